"""Calibrate a parallel mechanism (the bundled system ``two_spa_platform``: two hanging
three-chamber actuators holding a 20 g platform) from what a motion-capture system sees:
the platform's origin, two markers on the platform and one marker on each actuator
(docs/calibration.md "Systems of rods").

The "measurements" are synthetic: the system with the body's Young's modulus 15 % stiffer,
rod 1's extension factor 0.9 and a 25 g platform, 0.1 mm of noise. The fit starts from the
bundled values and recovers the three, with standard errors; the figure shows the
platform's measured positions against the model before and after calibration, and each
row's error.

Writes calibrate_two_spa_platform.png into the output folder (its argument; default
docs/figures) and prints the fitted values.

Run: python examples/calibrate_two_spa_platform.py [output folder]
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import softrod  # noqa: E402
from softrod.calibration.system import (  # noqa: E402
    calibrated_system,
    parse_system_parameters,
)

out_dir = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent.parent / "docs" / "figures"
)
system = softrod.load_system("two_spa_platform")
names = ["E[ecoflex_00_50_table1]", "rods[1].c_e", "platform_mass"]
params = parse_system_parameters(names, system)
bundled = np.array([p.value(system) for p in params])
truth = calibrated_system(system, params, bundled * [1.15, 0.9, 1.25])

# 30 equilibria: each chamber of each actuator off or at 5-30 kPa.
rng = np.random.default_rng(4)
pressures = rng.uniform(5e3, 30e3, size=(30, 2, 3)) * (rng.random((30, 2, 3)) < 0.5)
markers = [
    ("platform", ["20 mm", "0 mm", "5 mm"]),
    ("platform", ["-20 mm", "10 mm", "0 mm"]),
    ("rod0", "60 mm", ["21.1 mm", "0 mm"]),  # on the outer surface, d1 side
    ("rod1", "90 mm", ["0 mm", "21.1 mm"]),
]
data = softrod.synthesize_system_dataset(truth, pressures, markers=markers, noise_mm=0.1, seed=7)

fit = softrod.calibrate_system(system, data, names, progress=False)
truths = bundled * [1.15, 0.9, 1.25]
print("parameter                unit     initial      fitted   std_error       truth")
for p, v0, v, sd, t in zip(params, fit.initial, fit.values, fit.std_errors, truths, strict=True):
    print(f"{p.name:24s} {p.unit:4s} {v0:11.4g} {v:11.4g} {sd:11.2g} {t:11.4g}")
rms = fit.error_table.set_index("quantity")["rms_error_mm"]
print(f"RMS error after calibration: platform {rms['platform']:.3f} mm, ", end="")
print(f"markers {rms['markers']:.3f} mm")

# The bundled system's prediction (no fit) for the "before" picture.
initial = softrod.solve_system_batch(system, pressures, on_unstable="ignore").platform_position
out_dir.mkdir(parents=True, exist_ok=True)
fit.plot(out_dir / "calibrate_two_spa_platform.png", initial=initial)
print(f"wrote {out_dir / 'calibrate_two_spa_platform.png'}")
