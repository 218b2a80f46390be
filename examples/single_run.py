"""One closed-loop run on the digital twin: metrics, time series and a figure.

Run:  python examples/single_run.py [OUTPUT_DIR]
"""

import sys
from pathlib import Path

import esoarm

out = Path(sys.argv[1] if len(sys.argv) > 1 else "example-output")
out.mkdir(parents=True, exist_ok=True)

# test-1 of the paper (rest-to-rest moves) with a faster observer
scn = esoarm.load_scenario("test-1", {"observer.eps": 0.05})
result = esoarm.simulate(scn)

print(f"{scn.name}, eps = {scn.observer.eps} s, {scn.observer.discretization} ESO")
print(f"  RMS tracking error {result.rms_error:.4f} rad")
print(f"  RMS control        {result.rms_u:.4f} N·m")
print(f"  max |error|        {result.max_abs_error:.4f} rad")

result.to_csv(out / "single_run.csv")  # t,theta,theta_ref,error,u,z1,z2,z3,f_true
result.plot(out / "single_run.png")  # .pdf or .svg work too
print(f"wrote {out / 'single_run.csv'} and {out / 'single_run.png'}")
