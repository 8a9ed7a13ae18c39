"""Two-rod parallel mechanism: two hanging three-chamber actuators (paper 001's SPA) clamped
to one 20 g platform (python/softrod/designs/systems/two_spa_platform.toml).

Pressurising the left actuator's chamber on +d2 (channel 0) lengthens and bends it; the
platform tilts and swings, and the unpressurised right actuator is dragged along. Writes
docs/figures/two_spa_platform.png (``softrod.system_plots.plot_system``: front and side views,
x-z and y-z, of the shapes at 0, 20, 40 and 60 kPa) and prints the platform pose and the rods'
tip reactions.

Run: python examples/two_spa_platform.py [output folder]
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import softrod  # noqa: E402
from softrod.system_plots import platform_tilt_deg, plot_system  # noqa: E402

out_dir = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent.parent / "docs" / "figures"
)
system = softrod.load_system("two_spa_platform")
solutions, labels = [], []
previous = None
for kpa in (0, 20, 40, 60):
    sol = softrod.solve_system(system, [[kpa * 1e3, 0.0, 0.0], [0.0, 0.0, 0.0]], initial=previous)
    previous = sol
    p = sol.platform_position
    tilt = float(platform_tilt_deg(sol.platform_rotation))
    print(
        f"{kpa:3d} kPa: platform at {np.round(p * 1e3, 2)} mm, tilted {tilt:.2f} deg; "
        f"tip reactions {[np.round(r.tip_reaction_force, 4).tolist() for r in sol.rods]} N"
    )
    solutions.append(sol)
    labels.append(f"left actuator, channel 0 at {kpa} kPa (tilt {tilt:.1f} deg)")
out = out_dir / "two_spa_platform.png"
fig = plot_system(
    solutions,
    out,
    labels=labels,
    title="Two SPAs holding a 20 g platform: left actuator, channel 0 pressurised",
)
plt.close(fig)
print(f"wrote {out}")
