"""A picture of the lever arm for ``render_mode="rgb_array"`` (NumPy only, no window).

The pivot sits in the middle; the arm (dark grey, with the two masses of the
paper's Fig. 1) points along θ measured from the horizontal, positive
counter-clockwise; the reference θd is a thin vermilion line; a bar at the bottom
shows the torque u as a fraction of ±torque_limit (blue: positive).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["draw_arm"]

SIZE = 320
_BG = np.array([255, 255, 255], dtype=np.uint8)
_ARM = np.array([60, 60, 60], dtype=np.uint8)
_MASS = np.array([0, 114, 178], dtype=np.uint8)
_REF = np.array([213, 94, 0], dtype=np.uint8)
_BAR = np.array([0, 114, 178], dtype=np.uint8)
_GRID = np.array([225, 225, 225], dtype=np.uint8)

_YY, _XX = np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)


def _segment(img: np.ndarray, p: tuple[float, float], q: tuple[float, float], width: float,
             color: np.ndarray) -> None:
    (x0, y0), (x1, y1) = p, q
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy or 1.0
    s = np.clip(((_XX - x0) * dx + (_YY - y0) * dy) / length2, 0.0, 1.0)
    d2 = (_XX - x0 - s * dx) ** 2 + (_YY - y0 - s * dy) ** 2
    img[d2 <= (width / 2.0) ** 2] = color


def _disc(img: np.ndarray, c: tuple[float, float], r: float, color: np.ndarray) -> None:
    img[(_XX - c[0]) ** 2 + (_YY - c[1]) ** 2 <= r * r] = color


def draw_arm(theta: float, theta_ref: float, u_fraction: float) -> np.ndarray:
    """RGB image (SIZE × SIZE × 3, uint8) of the arm at θ [rad] with reference θd [rad].

    ``u_fraction`` is u / torque_limit, clipped to [−1, 1].
    """
    img = np.empty((SIZE, SIZE, 3), dtype=np.uint8)
    img[:] = _BG
    cx, cy = SIZE / 2.0, SIZE / 2.0 - 10.0
    reach = 0.4 * SIZE
    _segment(img, (cx - reach, cy), (cx + reach, cy), 1.0, _GRID)
    _segment(img, (cx, cy - reach), (cx, cy + reach), 1.0, _GRID)

    def tip(angle: float, r: float) -> tuple[float, float]:
        return cx + r * math.cos(angle), cy - r * math.sin(angle)

    if math.isfinite(theta):
        _segment(img, tip(theta + math.pi, reach * 0.93), tip(theta, reach), 9.0, _ARM)
        _disc(img, tip(theta, reach), 13.0, _MASS)
        _disc(img, tip(theta + math.pi, reach * 0.93), 14.0, _MASS)
    if math.isfinite(theta_ref):  # drawn over the arm, so it shows while tracking well
        _segment(img, tip(theta_ref + math.pi, reach * 1.08), tip(theta_ref, reach * 1.08), 2.0,
                 _REF)
    _disc(img, (cx, cy), 6.0, _BG)
    frac = max(-1.0, min(1.0, u_fraction)) if math.isfinite(u_fraction) else 0.0
    y = SIZE - 14.0
    _segment(img, (cx - reach, y), (cx + reach, y), 1.0, _GRID)
    if frac != 0.0:
        _segment(img, (cx, y), (cx + frac * reach, y), 8.0, _BAR if frac > 0 else _REF)
    return img
