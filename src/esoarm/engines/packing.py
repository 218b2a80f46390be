"""Scenarios packed into arrays for the compiled kernels (exact and fast engines).

Kept apart from the kernels so that the fast engine packs its runs without
importing numba (~0.2 s of start-up).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from esoarm.engines.metrics import NoiseCache
from esoarm.engines.simulation import prepare
from esoarm.plants.noise import noise_model
from esoarm.scenario import Scenario

# point-parameter columns
_SIGMA, _Q, _H, _TS = range(4)
_N, _NSUB, _DELAY, _REFIDX, _NJ, _NZ, _NC = range(7)

#: Widths of the plant, observer, controller and actuator vectors in the kernels
#: (zero-padded; a kind needs its vector to fit).
VECTOR_WIDTH = (16, 32, 16, 16)



@dataclass
class _Pack:
    """Arrays for the kernels: P points, R runs (run -> point, run -> noise row)."""

    run_point: np.ndarray
    run_noise: np.ndarray
    fpar: np.ndarray
    ipar: np.ndarray
    x0: np.ndarray
    b0: np.ndarray
    pp: np.ndarray
    op: np.ndarray
    cp: np.ndarray
    ap: np.ndarray
    refs: np.ndarray
    noises: np.ndarray

    @property
    def wide(self) -> bool:
        """A vector is longer than :data:`VECTOR_WIDTH`: the kernels take them as arrays."""
        return any(a.shape[1] > w for a, w in zip((self.pp, self.op, self.cp, self.ap),
                                                   VECTOR_WIDTH, strict=True))

    def args(self) -> tuple[np.ndarray, ...]:
        return (self.run_point, self.run_noise, self.fpar, self.ipar, self.x0, self.b0, self.pp,
                self.op, self.cp, self.ap, self.refs, self.noises)


def _stack(rows: list[np.ndarray], width: int | None = None) -> np.ndarray:
    """Rows of different lengths as one zero-padded 2-D array, at least ``width`` wide.

    Wider than ``width`` if a row is longer (a URDF arm's vectors carry its models):
    the batch engine then runs the point with its vectors as arrays (:attr:`_Pack.wide`).
    """
    longest = max((len(r) for r in rows), default=1)
    out = np.zeros((len(rows), max(width or 0, longest, 1)))
    for i, row in enumerate(rows):
        out[i, : len(row)] = row
    return out


def _pack(points: Sequence[Scenario], runs: Sequence[tuple[int, int]],
          noise_cache: NoiseCache | None = None) -> _Pack:
    """Pack ``points`` and ``runs`` = [(point index, seed), ...] for the kernels."""
    noise_cache = noise_cache or NoiseCache()
    p = len(points)
    fpar = np.empty((p, 4))
    ipar = np.empty((p, 7), dtype=np.int64)
    x0, b0, pp, op, cp, ap = [], [], [], [], [], []
    ref_keys: dict[str, int] = {}
    ref_list: list[np.ndarray] = []
    for i, scn in enumerate(points):
        inp = prepare(scn, draw_noise=False)  # noise is drawn once per seed (NoiseCache)
        fpar[i] = (inp.sigma, inp.q, inp.h, inp.ts)
        ipar[i, :3] = (len(inp.t), inp.nsub, inp.delay)
        ipar[i, 4:] = (inp.plant.n_joints, inp.observer.n_state, inp.controller.n_state)
        x0.append(inp.plant.x0)
        b0.append(inp.plant.b0)
        pp.append(inp.plant.vector)
        op.append(inp.observer.vector)
        cp.append(inp.controller.vector)
        ap.append(inp.actuator)
        ref_key = f"{scn.sample_time!r}/{scn.n_samples}/{scn.reference.model_dump_json()}"
        if ref_key not in ref_keys:
            ref_keys[ref_key] = len(ref_list)
            ref_list.append(inp.refs)
        ipar[i, _REFIDX] = ref_keys[ref_key]
    nmax = int(ipar[:, _N].max()) if p else 1
    nref = max((r.shape[0] for r in ref_list), default=3)
    refs = np.zeros((len(ref_list), nref, nmax))
    for i, ref in enumerate(ref_list):
        refs[i, : ref.shape[0], : ref.shape[1]] = ref
    noise_rows: dict[tuple[Any, ...], int] = {}
    noise_list: list[np.ndarray] = []
    run_point = np.empty(len(runs), dtype=np.int64)
    run_noise = np.empty(len(runs), dtype=np.int64)
    for r, (pi, seed) in enumerate(runs):
        scn = points[pi]
        length = scn.n_samples * int(ipar[pi, _NJ])
        key, seq = noise_cache.get(seed, length, scn.sensor.noise_deg, noise_model(scn),
                                   int(ipar[pi, _NJ]))
        if key not in noise_rows:
            noise_rows[key] = len(noise_list)
            noise_list.append(seq)
        run_point[r] = pi
        run_noise[r] = noise_rows[key]
    noises = _stack(noise_list) if noise_list else np.zeros((1, nmax))
    wp, wo, wc, wa = VECTOR_WIDTH
    return _Pack(run_point, run_noise, fpar, ipar, _stack(x0), _stack(b0), _stack(pp, wp),
                 _stack(op, wo), _stack(cp, wc), _stack(ap, wa), refs, noises)
