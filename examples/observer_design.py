"""Observer design at 50 Hz: gains and poles of the three discretizations, Theorem 1.

Also steps the stateful ExtendedStateObserver on a synthetic measurement: the arm
at rest under a constant unknown acceleration of 2 rad/s², which the third state
z3 must find.

Run:  python examples/observer_design.py
"""

import numpy as np

from esoarm.observers.linear import ExtendedStateObserver, design_observer
from esoarm.observers.stability import analyze_observer, theorem1_bound

ts = 1.0 / 50.0  # s, the paper's encoder rate
b0 = 1.0 / 0.0225  # 1/(kg·m²), 1/I0 of Table I

print(f"Ts = {ts} s")
print(f"{'eps [s]':>8} {'disc':>8} {'pole':>8} {'|pole|':>7} {'damping':>8} stable  gains")
for eps in (0.015, 0.05, 0.09, 0.2):
    for disc in ("euler", "zoh", "current"):
        a = analyze_observer(eps, ts, disc)
        gains = ", ".join(f"{g:.4g}" for g in a.gains)
        print(f"{eps:8g} {disc:>8} {a.poles[0]:8.4f} {a.spectral_radius:7.4f} {a.damping:8.3f}"
              f" {a.stable!s:>6}  ({gains})")

# Theorem 1: steady-state bound for |ḟ| ≤ 1 rad/s³
for eps in (0.05, 0.09, 0.2):
    b = theorem1_bound(eps, 1.0)
    print(f"eps = {eps:g} s: |θ−z1| ≤ {b[0]:.2e} rad, |θ̇−z2| ≤ {b[1]:.2e} rad/s, "
          f"|f−z3| ≤ {b[2]:.2e} rad/s² per rad/s³ of |ḟ|")

# A constant unknown acceleration f = 2 rad/s² and no control: θ(t) = f t² / 2.
f = 2.0
eso = ExtendedStateObserver(design_observer(0.09, ts, b0, "current"), y0=0.0)
for k in range(100):  # 2 s
    t = k * ts
    z1, z2, z3 = eso.estimate(0.5 * f * t * t)
    eso.update(0.0)
print(f"after 2 s: z3 = {z3:.4f} rad/s² (true {f}), z2 = {z2:.4f} rad/s (true {f * t:.4f})")
assert abs(z3 - f) < 1e-3 and np.isfinite(z2)
