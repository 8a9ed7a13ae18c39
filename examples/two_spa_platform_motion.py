"""Two-rod parallel mechanism in motion: the bundled system ``two_spa_platform`` (two of paper
001's hanging three-chamber actuators holding a 20 g platform), its left actuator's channel 0
stepped to 40 kPa at t = 20 ms. The rods are damped (Kelvin-Voigt, tau = 50 ms, paper 000's
law); the platform swings and settles on the static equilibrium of the same inputs.

Writes docs/figures/two_spa_platform_motion.png (platform position and tilt against time, the
static equilibrium dashed) and prints the settled pose beside the static one.

Run: python examples/two_spa_platform_motion.py [output folder]
"""

import dataclasses
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import softrod  # noqa: E402

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


def tilt_deg(rotation):
    return math.degrees(math.acos(np.clip(rotation[2, 2], -1.0, 1.0)))


t_ms = traj.time * 1e3
tilt = np.array([tilt_deg(r) for r in traj.platform_rotation])
fig, axes = plt.subplots(2, 1, figsize=(7.5, 5.6), sharex=True)
for k, (name, colour) in enumerate((("x", "tab:blue"), ("y", "tab:orange"), ("z", "tab:green"))):
    p = traj.platform_position[:, k] * 1e3
    axes[0].plot(t_ms, p - p[0], color=colour, label=f"{name} - {name}(0)")
    axes[0].axhline(static.platform_position[k] * 1e3 - p[0], color=colour, ls="--", lw=1)
axes[0].set_ylabel("platform displacement (mm)")
axes[0].legend(loc="center right", bbox_to_anchor=(1.0, 0.6), fontsize=8)
axes[1].plot(t_ms, tilt, color="tab:purple", label="simulated")
axes[1].axhline(
    tilt_deg(static.platform_rotation),
    color="tab:purple",
    ls="--",
    lw=1,
    label="static equilibrium",
)
axes[1].set_ylabel("platform tilt (deg)")
axes[1].set_xlabel("time (ms)")
axes[1].legend(loc="center right", fontsize=8)
for ax in axes:
    ax.grid(alpha=0.3)
fig.suptitle(f"two_spa_platform: left actuator's channel 0 stepped to {STEP_KPA:g} kPa")
fig.tight_layout()
out = out_dir / "two_spa_platform_motion.png"
fig.savefig(out, dpi=110)
end = np.round(traj.platform_position[-1] * 1e3, 3)
rest = np.round(static.platform_position * 1e3, 3)
print(f"settled platform at {end} mm, static {rest} mm")
print(f"tilt {tilt[-1]:.3f} deg, static {tilt_deg(static.platform_rotation):.3f} deg")
print(f"wrote {out}")
