"""Two-rod parallel mechanism: two hanging three-chamber actuators (paper 001's SPA) clamped
to one 20 g platform (python/softrod/designs/systems/two_spa_platform.toml).

Pressurising the left actuator's chamber on +d2 (channel 0) lengthens and bends it; the
platform tilts and swings, and the unpressurised right actuator is dragged along. Writes
docs/figures/two_spa_platform.png (side views, x-z and y-z, of the shapes at 0, 20, 40 and
60 kPa) and prints the platform pose and the rods' tip reactions.

Run: python examples/two_spa_platform.py [output folder]
"""

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
system = softrod.load_system("two_spa_platform")
fig, axes = plt.subplots(1, 2, figsize=(9, 5.2), sharey=True)
colours = plt.cm.viridis(np.linspace(0.0, 0.85, 4))
previous = None
for kpa, colour in zip((0, 20, 40, 60), colours, strict=True):
    sol = softrod.solve_system(system, [[kpa * 1e3, 0.0, 0.0], [0.0, 0.0, 0.0]], initial=previous)
    previous = sol
    p = sol.platform_position
    tilt = math.degrees(math.acos(np.clip(sol.platform_rotation[2, 2], -1.0, 1.0)))
    print(
        f"{kpa:3d} kPa: platform at {np.round(p * 1e3, 2)} mm, tilted {tilt:.2f} deg; "
        f"tip reactions {[np.round(r.tip_reaction_force, 4).tolist() for r in sol.rods]} N"
    )
    for ax, (a, b) in zip(axes, ((0, 2), (1, 2)), strict=True):
        for r in sol.rods:
            ax.plot(r.position[:, a] * 1e3, r.position[:, b] * 1e3, color=colour, lw=2)
        # The platform: the segment between the two attachments.
        ends = np.array([r.tip_position for r in sol.rods]) * 1e3
        ax.plot(
            ends[:, a],
            ends[:, b],
            color=colour,
            lw=5,
            solid_capstyle="butt",
            label=f"{kpa} kPa (tilt {tilt:.1f} deg)",
        )
for ax, name in zip(axes, ("x", "y"), strict=True):
    ax.plot([-45, 45], [0, 0], color="black", lw=3)
    ax.set_xlabel(f"{name} (mm)")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
axes[0].set_ylabel("z (mm)")
axes[0].set_title("front view (x-z)")
axes[1].set_title("side view (y-z)")
axes[0].legend(loc="center", fontsize=8)
fig.suptitle("Two SPAs holding a 20 g platform: left actuator, channel 0 pressurised")
fig.tight_layout()
out = out_dir / "two_spa_platform.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
