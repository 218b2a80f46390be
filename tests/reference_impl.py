"""An independent, deliberately plain implementation of the sampled-data loop (test-only).

Written from docs/semantics.md (the sampled-data loop, the scenario format), not
from the esoarm sources: it imports
nothing from ``esoarm`` and takes the scenario as the plain nested dict of
``Scenario.to_dict()`` (the keys of the scenario format).  Differences from the package
engine, on purpose:

* the observer is state-space with NumPy matrices; Φ and Γ come from
  ``scipy.linalg.expm`` of the augmented matrix [[A, B], [0, 0]] (not a closed
  form), and the discrete gains from matching characteristic-polynomial
  coefficients (affine in L), not from Ackermann's formula;
* the rig state is a NumPy vector (θ, θ̇, τ) integrated with its own RK4;
* the reference trajectories and the FLC are typed again from docs/semantics.md.

It is the second engine of ``tests/engines/test_simulation.py``: both must agree to
round-off (the sampled-data loop: relative 1e-9 on RMS values).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

C_ROW = np.array([[1.0, 0.0, 0.0]])


def _charpoly3(m: np.ndarray) -> np.ndarray:
    """Coefficients (c2, c1, c0) of det(zI − m) = z³ + c2 z² + c1 z + c0."""
    tr = np.trace(m)
    return np.array([-tr, 0.5 * (tr * tr - np.trace(m @ m)), -np.linalg.det(m)])


def place_triple(phi: np.ndarray, c_row: np.ndarray, shift: float) -> np.ndarray:
    """L (column) with det(zI − (Φ − L c_row)) = (z − p)³, p = 1 + ``shift``.

    Works on Φ − I and the shifted pole p − 1 (given directly, e.g. from
    ``math.expm1``) so that no O(1) terms cancel.  The characteristic
    polynomial of a rank-one update is affine in L, so three unit
    perturbations give the linear map exactly.
    """
    m = phi - np.eye(3)
    target = np.array([-3.0 * shift, 3.0 * shift**2, -(shift**3)])
    base = _charpoly3(m)
    cols = []
    for i in range(3):
        e = np.zeros((3, 1))
        e[i, 0] = 1.0
        cols.append(_charpoly3(m - e @ c_row) - base)
    jac = np.column_stack(cols)
    return np.linalg.solve(jac, target - base).reshape(3, 1)


def observer_matrices(eps: float, ts: float, b0: float, disc: str):
    """(Φ, Γ, L, β) for a discretization; Φ, Γ of the exact ZOH model except Euler."""
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    b = np.array([[0.0], [b0], [0.0]])
    beta = np.array([[3.0 / eps], [3.0 / eps**2], [1.0 / eps**3]])
    if disc == "euler":
        return np.eye(3) + ts * a, ts * b, ts * beta, beta
    aug = np.zeros((4, 4))
    aug[:3, :3] = a
    aug[:3, 3:] = b
    big = expm(aug * ts)
    phi, gamma = big[:3, :3], big[:3, 3:]
    shift = math.expm1(-ts / eps)  # pole e^{−Ts/ε} minus 1
    if disc == "zoh":
        gain = place_triple(phi, C_ROW, shift)
    elif disc == "current":
        gain = place_triple(phi, C_ROW @ phi, shift)
    else:
        raise ValueError(disc)
    return phi, gamma, gain, beta


def reference(ref: dict, t: float) -> tuple[float, float, float]:
    """θd, θ̇d, θ̈d at time t (reference kinds of the scenario format)."""
    if ref["kind"] == "multisine":
        phases = ref.get("phases") or [0.0] * len(ref["amplitudes"])
        p = ref.get("offset", 0.0)
        v = acc = 0.0
        for amp, w, ph in zip(ref["amplitudes"], ref["frequencies"], phases, strict=True):
            p += amp * math.sin(w * t + ph)
            v += amp * w * math.cos(w * t + ph)
            acc += -amp * w * w * math.sin(w * t + ph)
        return p, v, acc
    # rest-to-rest quintic moves, held between them
    p, v, acc = ref["start"], 0.0, 0.0
    prev = ref["start"]
    for t0, dur, target in ref["moves"]:
        if t >= t0 + dur:
            p, v, acc = target, 0.0, 0.0
        elif t >= t0:
            s = (t - t0) / dur
            d = target - prev
            p = prev + d * (10 * s**3 - 15 * s**4 + 6 * s**5)
            v = d * (30 * s**2 - 60 * s**3 + 30 * s**4) / dur
            acc = d * (60 * s - 180 * s**2 + 120 * s**3) / dur**2
        prev = target
    return p, v, acc


def run(scn: dict) -> dict[str, np.ndarray]:
    """Simulate one scenario dict; returns the logged series and the metrics."""
    plant, rig, sensor = scn["plant"], scn["rig"], scn["sensor"]
    act, obs, ctl = scn["actuator"], scn["observer"], scn["controller"]
    i0 = plant["inertia"]
    b0 = 1.0 / i0
    gc = (plant["m1"] * plant["l1"] - plant["m2"] * plant["l2"]) * plant["g"]
    inertia = rig["inertia_scale"] * i0
    fc, vs, visc = rig["coulomb_friction"], rig["friction_velocity"], rig["viscous_friction"]
    fst, vst = rig.get("stiction", 0.0), rig.get("stribeck_velocity", 0.1)
    d_amp, d_freq = rig["disturbance"]["amplitude"], rig["disturbance"]["frequency"]
    lag = act["lag"]
    ts = 1.0 / sensor["rate_hz"]
    h = rig["step"]
    nsub = int(round(ts / h))
    n = int(round(scn["duration"] * sensor["rate_hz"]))
    sigma = sensor["noise_deg"] * math.pi / 180.0
    q = sensor["resolution_deg"] * math.pi / 180.0
    noise = (np.random.default_rng(sensor["seed"]).standard_normal(n)
             if sensor["noise_deg"] > 0 else np.zeros(n))

    def quant(x: float) -> float:
        return q * math.floor(x / q + 0.5) if q > 0 else x

    def accel(x: np.ndarray, u_app: float, t: float) -> float:
        torque = x[2] if lag > 0 else u_app
        fric = fc * math.tanh(x[1] / vs) + visc * x[1]
        if fst:  # Stribeck peak above Coulomb
            fric += fst * math.exp(-((x[1] / vst) ** 2)) * math.tanh(x[1] / vs)
        return (torque - gc * math.cos(x[0]) - fric) / inertia + d_amp * math.sin(d_freq * t)

    def deriv(x: np.ndarray, u_app: float, t: float) -> np.ndarray:
        dtau = (u_app - x[2]) / lag if lag > 0 else 0.0
        return np.array([x[1], accel(x, u_app, t), dtau])

    phi, gamma, gain, beta = observer_matrices(obs["eps"], ts, b0, obs["discretization"])
    a_cont = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    b_cont = np.array([[0.0], [b0], [0.0]])
    disc = obs["discretization"]
    k1, k2, limit = ctl["k1"], ctl["k2"], act["torque_limit"]

    x = np.array([rig["theta0"], 0.0, 0.0])
    z = np.array([[quant(rig["theta0"] + sigma * noise[0])], [0.0], [0.0]])
    commands: list[float] = []
    out = {key: np.zeros(n) for key in ("t", "theta", "theta_ref", "error", "u", "f_true")}
    out["z"] = np.zeros((n, 3))
    for k in range(n):
        t = k * ts
        y = quant(x[0] + sigma * noise[k])
        r, dr, ddr = reference(scn["reference"], t)
        innovation = y - z[0, 0]
        zhat = z + gain * innovation if disc == "current" else z.copy()
        alpha = ddr - k1 * (zhat[1, 0] - dr) - k2 * (zhat[0, 0] - r)
        if ctl["compensation"] == "eso":
            beta_hat = zhat[2, 0]
        else:
            beta_hat = -gc * math.cos(zhat[0, 0]) / i0
        u = min(max(i0 * (alpha - beta_hat), -limit), limit)
        commands.append(u)
        delay = act["delay_samples"]
        u_app = commands[k - delay] if k >= delay else 0.0
        out["t"][k] = t
        out["theta"][k] = x[0]
        out["theta_ref"][k] = r
        out["error"][k] = x[0] - r
        out["u"][k] = u
        out["z"][k] = zhat[:, 0]
        out["f_true"][k] = accel(x, u_app, t) - b0 * u
        # observer update
        if disc == "euler":
            z = z + ts * (a_cont @ z + b_cont * u + beta * innovation)
        elif disc == "zoh":
            z = phi @ z + gamma * u + gain * innovation
        else:
            z = phi @ zhat + gamma * u
        # rig over [t_k, t_k+1) with RK4 at step h
        for j in range(nsub):
            tj = t + j * h
            s1 = deriv(x, u_app, tj)
            s2 = deriv(x + 0.5 * h * s1, u_app, tj + 0.5 * h)
            s3 = deriv(x + 0.5 * h * s2, u_app, tj + 0.5 * h)
            s4 = deriv(x + h * s3, u_app, tj + h)
            x = x + (h / 6.0) * (s1 + 2.0 * s2 + 2.0 * s3 + s4)
    out["rms_error"] = np.sqrt(np.mean(out["error"] ** 2))
    out["rms_u"] = np.sqrt(np.mean(out["u"] ** 2))
    out["max_abs_error"] = np.max(np.abs(out["error"]))
    return out
