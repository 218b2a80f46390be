"""A UR5 from the `example-robot-data` package (optional): write a scenario for it and run it.

    pip install example-robot-data        # not needed by esoarm or its tests
    python examples/arm_ur5.py [OUT_DIR]

Writes OUT_DIR/ur5.toml pointing at the package's UR5 URDF (its meshes are not
needed for the dynamics), with a 1 kg payload the controller does not know, a
500 Hz loop and the joints moved through 15 % of their range, then simulates
it with the ESO and without estimation.  For a Panda use
`panda_description/urdf/panda.urdf` (nine joints: seven plus two fingers) with
``payload_mass = 0``: the payload sits on the last link in URDF order, a finger.
Without example-robot-data installed it says so and stops.
"""

import sys
from importlib import metadata
from pathlib import Path

import esoarm


def robots_dir() -> Path | None:
    """The URDF folder of example-robot-data, if installed."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return path if path.is_dir() else None


out = Path(sys.argv[1] if len(sys.argv) > 1 else "example-output")
robots = robots_dir()
if robots is None:
    print("example-robot-data is not installed (pip install example-robot-data); nothing to do")
    sys.exit(0)
out.mkdir(parents=True, exist_ok=True)
scenario = out / "ur5.toml"
scenario.write_text(f'''name = "ur5"
duration = 6.0

[plant]
kind = "urdf"
file = "{robots / 'ur_description' / 'urdf' / 'ur5_robot.urdf'}"
payload_mass = 1.0
payload_offset = [0.0, 0.0, 0.05]

[sensor]
rate_hz = 500.0

[observer]
eps = 0.01

[controller]
kind = "computed-torque"
k1 = 40.0
k2 = 400.0

[actuator]
torque_limit = 150.0

[reference]
kind = "range"
fraction = 0.15
moves = [[0.5, 2.0, 1.0], [3.5, 2.0, -1.0]]
''', encoding="utf-8")
for compensation in ("eso", "model"):
    run = esoarm.simulate(scenario, {"controller.compensation": compensation})
    per_joint = ", ".join(f"{j.rms_error:.4f}" for j in run.per_joint)
    print(f"{compensation:6s} RMS error {run.rms_error:.4f} rad; per joint [rad]: {per_joint}")
print(f"scenario: {scenario}")
