"""Two-rod parallel mechanism in motion: the bundled system ``two_spa_platform`` (two of paper
001's hanging three-chamber actuators holding a 20 g platform), its left actuator's channel 0
stepped to 40 kPa at t = 20 ms. The rods are damped (Kelvin-Voigt, tau = 50 ms, paper 000's
law); the platform swings and settles on the static equilibrium of the same inputs.

Writes docs/figures/two_spa_platform_motion.png (``SystemTrajectory.plot``: the platform's
displacement and tilt and the pressures against time, the static equilibrium dashed) and prints
the settled pose beside the static one.

Run: python examples/two_spa_platform_motion.py [output folder]
"""

import dataclasses
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import softrod  # noqa: E402
from softrod.system_plots import platform_tilt_deg  # noqa: E402

out_dir = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent.parent / "docs" / "figures"
)
bundled = softrod.load_system("two_spa_platform")
damped = [
    dataclasses.replace(r, design=r.design.replace({"dynamics.damping_time": "50 ms"}))
    for r in bundled.rods
]
system = dataclasses.replace(bundled, rods=damped)
STEP_KPA, T_STEP = 40.0, 0.02


def pressures(t):
    p = STEP_KPA * 1e3 if t >= T_STEP else 0.0
    return [[p, 0.0, 0.0], [0.0, 0.0, 0.0]]


traj = softrod.simulate_system(system, pressures, 1.0, dt=2e-3)
static = softrod.solve_system(system, pressures(1.0))


tilt = platform_tilt_deg(traj.platform_rotation)
out = out_dir / "two_spa_platform_motion.png"
fig = traj.plot(
    out,
    reference=static,
    title=f"two_spa_platform: left actuator's channel 0 stepped to {STEP_KPA:g} kPa",
)
plt.close(fig)
end = np.round(traj.platform_position[-1] * 1e3, 3)
rest = np.round(static.platform_position * 1e3, 3)
print(f"settled platform at {end} mm, static {rest} mm")
print(f"tilt {tilt[-1]:.3f} deg, static {platform_tilt_deg(static.platform_rotation):.3f} deg")
print(f"wrote {out}")
