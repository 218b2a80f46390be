"""The look shared by every figure: palettes, line styles, and saving (PNG, PDF, SVG)."""

from __future__ import annotations

import io
from pathlib import Path

from matplotlib.figure import Figure

from esoarm._io import atomic_path

__all__ = ["DISCRETIZATION_STYLE", "FIGURE_FORMATS", "NO_ESTIMATION_COLOR", "REF_STYLE",
           "TRUE_STYLE", "eps_color", "figure_bytes", "finish_figure", "save_figure"]

#: File formats :func:`save_figure` writes, by suffix.
FIGURE_FORMATS: tuple[str, ...] = ("png", "pdf", "svg")

# Okabe & Ito (2008) colour-blind-safe palette.
_EPS_COLORS = {0.05: "#D55E00", 0.09: "#0072B2", 0.2: "#009E73"}
_OTHER = ["#CC79A7", "#E69F00", "#56B4E9", "#7f7f7f", "#F0E442", "#000000"]
#: Colour of the run without perturbation estimation (Fig. 7 baseline).
NO_ESTIMATION_COLOR = "#E69F00"
REF_STYLE = {"color": "black", "linestyle": "--", "linewidth": 1.3, "label": "reference θd",
             "zorder": 5}
TRUE_STYLE = {"color": "0.25", "linewidth": 0.9}
#: Line style per ESO discretization (figures comparing discretizations).
DISCRETIZATION_STYLE: dict[str, dict[str, object]] = {
    "euler": {"color": "#000000", "marker": "o", "linestyle": "-",
              "label": "euler (paper)"},
    "zoh": {"color": "#CC79A7", "marker": "s", "linestyle": "--",
            "label": "zoh (exact, predictive)"},
    "current": {"color": "#56B4E9", "marker": "^", "linestyle": ":",
                "label": "current (exact, uses y_k)"},
}
_DPI = 130


def eps_color(eps: float) -> str:
    """The colour used for ε in every figure (fixed for the paper's 0.05, 0.09, 0.2 s)."""
    for key, color in _EPS_COLORS.items():
        if abs(key - eps) < 1e-12:
            return color
    return _OTHER[int(round(eps * 1e4)) % len(_OTHER)]


def check_suffix(path: Path) -> str:
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FIGURE_FORMATS:
        raise ValueError(
            f"figure file '{path}': the name must end in "
            f"{', '.join('.' + f for f in FIGURE_FORMATS)}"
        )
    return fmt


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save as PNG (default), PDF or SVG, chosen by the file suffix.

    The file appears only once complete (written beside it, then renamed).

    Raises
    ------
    ValueError
        The suffix is not .png, .pdf or .svg.
    """
    path = Path(path)
    fmt = check_suffix(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=_DPI, bbox_inches="tight",
                    metadata={"Software": "esoarm"} if fmt == "png" else None)
    return path


def figure_bytes(fig: Figure, fmt: str = "png", dpi: int = _DPI) -> bytes:
    """The figure encoded as PNG or SVG bytes (for embedding in a report)."""
    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"fmt must be one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def finish_figure(fig: Figure, path: str | Path | None) -> Figure:
    """Save ``fig`` to ``path`` when one is given (see :func:`save_figure`); return it."""
    if path is not None:
        save_figure(fig, path)
    return fig
