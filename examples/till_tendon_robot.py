"""Tendon-driven continuum robot: the statics example of Till, Aloi and Rucker (IJRR 2019) as
the bundled design ``till_tendon_robot`` (a 0.5 m spring-steel rod, four tendons 15.06 mm
off the axis, held horizontally under gravity; docs/designs.md).

Pulls tendon 0 (the lower side) from 0 to 15 N, the example's load, and tendons 0 and 1
together; prints the tip per tension and writes docs/figures/till_tendon_robot.png (side view
x-z and top view x-y of the shapes, the tendon paths drawn for the example's 15 N).

Run: python examples/till_tendon_robot.py [output folder]
"""

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
design = softrod.load_design("till_tendon_robot")
cases = [([t, 0, 0, 0], f"tendon 0: {t} N") for t in (0, 5, 10, 15)]
cases.append(([10, 10, 0, 0], "tendons 0 and 1: 10 N each"))
fig, (side, top) = plt.subplots(1, 2, figsize=(11, 3.6))
colours = list(plt.cm.viridis(np.linspace(0.0, 0.8, 4))) + ["tab:red"]
print("tensions (N)          tip x, y, z (mm)          stable")
for (tensions, label), colour in zip(cases, colours, strict=True):
    sol = softrod.solve_statics(design, [], tensions=tensions)
    tip = ", ".join(f"{round(v, 1) + 0.0:6.1f}" for v in sol.tip_position * 1e3)  # no -0.0
    print(f"{str(tensions):<21} {tip:<25} {sol.stable}")
    r = sol.position * 1e3
    side.plot(r[:, 0], r[:, 2], color=colour, lw=2, label=label)
    top.plot(r[:, 0], r[:, 1], color=colour, lw=2, label=label)
    if tensions == [15, 0, 0, 0]:
        # The example's load: draw the four tendon paths p_i = r + R r_i.
        for k in range(4):
            angle = k * np.pi / 2
            offset = 15.06 * np.array([np.cos(angle), np.sin(angle), 0.0])
            path = r + np.einsum("nij,j->ni", sol.rotation, offset)
            side.plot(path[:, 0], path[:, 2], color=colour, lw=0.7, ls="--")
for ax, (name, vertical) in zip((side, top), (("side view", "z"), ("top view", "y")), strict=True):
    ax.axvline(0.0, color="black", lw=3)  # the wall the base is clamped to
    ax.set_xlabel("x (mm)")
    ax.set_ylabel(f"{vertical} (mm)")
    ax.set_title(name)
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
side.legend(loc="lower left", fontsize=8)
fig.suptitle("Till's tendon robot (0.5 m steel rod, horizontal): dashed, the tendons at 15 N")
fig.tight_layout()
out = out_dir / "till_tendon_robot.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
