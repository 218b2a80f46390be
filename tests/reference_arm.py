"""A plain-Python, Pinocchio-only closed loop for a URDF arm (test and benchmark reference).

The computed-torque loop a Pinocchio user would write by hand, with one ESO
per joint: it imports nothing from ``esoarm``.  Differences from the package
on purpose:

* the twin's derivative is q̈ = M⁻¹(τ − F − n) with M from CRBA and n from
  RNEA (the package uses one ABA call per stage, on a model whose gravity is
  divided by the inertia scale); ``dynamics = "aba"`` (inertia scale 1 only)
  uses ``pinocchio.aba`` instead, as a Pinocchio user would (the benchmark's
  baseline);
* the observers are NumPy state-space matrices (Euler: z⁺ = z + Ts (A z + B v + L (y − z1)));
* RK4, friction, disturbance, noise and quantization are typed again, all in NumPy.

It is the second engine of ``tests/plants/test_arms.py`` and the "plain Python"
baseline of ``benchmarks/bench_arms.py``.  Revolute/prismatic joints only
(no continuous joint), Euler observers, no lag or delay.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin


def run_plain(p: dict) -> dict[str, np.ndarray]:
    """One run; ``p`` holds plain values (keys as used below, SI units, angles in rad).

    ``reference`` is the tuple (q_ref, v_ref, a_ref) of (N, n) arrays.  Returns
    (N, n) arrays ``theta``, ``error``, ``u``, ``z3``.
    """
    nominal = pin.buildModelFromUrdf(p["urdf"])
    nominal.gravity.linear = np.array([0.0, 0.0, -p["g"]])
    true = pin.buildModelFromUrdf(p["urdf"])
    true.gravity.linear = np.array([0.0, 0.0, -p["g"]])
    if p["payload_mass"] > 0:
        last = true.njoints - 1
        true.inertias[last] = true.inertias[last] + pin.Inertia(
            p["payload_mass"], np.array(p["payload_offset"], dtype=float), np.zeros((3, 3)))
    dn, dt = nominal.createData(), true.createData()
    n = nominal.nv
    s = p["inertia_scale"]
    fc, vs, b = (np.broadcast_to(np.asarray(p[k], dtype=float), (n,))
                 for k in ("coulomb", "vs", "viscous"))
    da, dw = (np.broadcast_to(np.asarray(p[k], dtype=float), (n,)) for k in ("d_amp", "d_freq"))

    use_aba = p.get("dynamics", "crba") == "aba" and s == 1.0

    def accel(q, v, tau, t):
        if use_aba:  # what a Pinocchio user writes: forward dynamics by ABA
            friction = fc * np.tanh(v / vs) + b * v
            return pin.aba(true, dt, q, v, tau - friction) + da * np.sin(dw * t)
        m = pin.crba(true, dt, q)
        m = np.triu(m) + np.triu(m, 1).T
        nle = pin.rnea(true, dt, q, v, np.zeros(n))
        grav = pin.rnea(true, dt, q, np.zeros(n), np.zeros(n))
        friction = fc * np.tanh(v / vs) + b * v
        # s (M q̈ + C q̇) + g = τ − F
        return np.linalg.solve(s * m, tau - friction - s * (nle - grav) - grav) + da * np.sin(
            dw * t)

    ts = 1.0 / p["rate_hz"]
    h = p["step"]
    nsub = int(round(ts / h))
    n_samples = int(round(p["duration"] * p["rate_hz"]))
    sigma, quant = math.radians(p["noise_deg"]), math.radians(p["resolution_deg"])
    noise = (np.random.default_rng(p["seed"]).standard_normal((n_samples, n))
             if p["noise_deg"] > 0 else np.zeros((n_samples, n)))
    eps = np.broadcast_to(np.asarray(p["eps"], dtype=float), (n,))
    k1 = np.broadcast_to(np.asarray(p["k1"], dtype=float), (n,))
    k2 = np.broadcast_to(np.asarray(p["k2"], dtype=float), (n,))
    limit = np.broadcast_to(np.asarray(p["torque_limit"], dtype=float), (n,))
    q_ref, v_ref, a_ref = p["reference"]

    def measure(x, nk):
        y = x + sigma * nk
        return quant * np.floor(y / quant + 0.5) if quant > 0 else y

    q = np.zeros(n)
    v = np.zeros(n)
    z = np.zeros((n, 3))
    z[:, 0] = measure(q, noise[0])
    beta = np.column_stack([3 / eps, 3 / eps**2, 1 / eps**3])
    out = {key: np.zeros((n_samples, n)) for key in ("theta", "error", "u", "z3")}
    for k in range(n_samples):
        tk = k * ts
        y = measure(q, noise[k])
        alpha = a_ref[k] - k1 * (z[:, 1] - v_ref[k]) - k2 * (z[:, 0] - q_ref[k])
        mh = pin.crba(nominal, dn, z[:, 0])
        mh = np.triu(mh) + np.triu(mh, 1).T
        if p["compensation"] == "model":
            tau = mh @ alpha + pin.rnea(nominal, dn, z[:, 0], z[:, 1], np.zeros(n))
        else:
            tau = mh @ (alpha - z[:, 2])
        u = np.clip(tau, -limit, limit)
        out["theta"][k], out["error"][k], out["u"][k] = q, q - q_ref[k], u
        out["z3"][k] = z[:, 2]
        vin = np.linalg.solve(mh, u)
        e = y - z[:, 0]
        z = z + ts * np.column_stack([z[:, 1] + beta[:, 0] * e,
                                      z[:, 2] + vin + beta[:, 1] * e, beta[:, 2] * e])
        for j in range(nsub):
            t = tk + j * h
            a1 = accel(q, v, u, t)
            a2 = accel(q + h / 2 * v, v + h / 2 * a1, u, t + h / 2)
            a3 = accel(q + h / 2 * (v + h / 2 * a1), v + h / 2 * a2, u, t + h / 2)
            a4 = accel(q + h * (v + h / 2 * a2), v + h * a3, u, t + h)
            q, v = (q + h / 6 * (v + 2 * (v + h / 2 * a1) + 2 * (v + h / 2 * a2) + v + h * a3),
                    v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4))
    return out
