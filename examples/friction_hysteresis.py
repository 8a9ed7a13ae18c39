"""Friction hysteresis of the pre-curved finger pressed onto a rough table (design
``prebent_finger_on_table`` with Coulomb friction mu = 0.2 on the table, docs/contact.md
"Friction in the statics"): the chamber pressure goes up from 0 to 50 kPa and back down in
steps of 2.5 kPa, each level's load path continued from the last (``history=``). The
table's tangential (friction) force on the finger, its normal force and the tip's
horizontal position trace loops: on the way up the tip slides outwards and the table holds
it back; on the way down it first sticks (the friction unloads and reverses), then slides
back in with the table holding it out; the frictionless finger has one curve.

Writes friction_hysteresis.png into the output folder (its argument; default docs/figures)
and prints both branches.

Run: python examples/friction_hysteresis.py [output folder]
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
smooth = softrod.load_design("prebent_finger_on_table")
rough = smooth.replace({"obstacles[0].friction": 0.2})

up = np.linspace(0.0, 50.0, 21)
levels = np.concatenate([up, up[-2::-1]])  # 0 -> 50 -> 0 kPa
friction, normal, tip_x, previous = [], [], [], None
for p in levels:
    sol = softrod.solve_statics(rough, [p * 1e3], history=previous)
    friction.append(sol.contact.friction_force[0][0])
    normal.append(sol.contact.total_force[0][2])
    tip_x.append(sol.tip_position[0])
    previous = sol
friction, normal, tip_x = (np.array(v) * 1e3 for v in (friction, normal, tip_x))
plain = [softrod.solve_statics(smooth, [p * 1e3]) for p in up]
plain_n = np.array([s.contact.total_force[0][2] for s in plain]) * 1e3
plain_x = np.array([s.tip_position[0] for s in plain]) * 1e3

n = len(up)
print("pressure_kPa  friction_up_mN  friction_down_mN  tip_x_up_mm  tip_x_down_mm  tip_x_mu0_mm")
for k in range(0, n, 4):
    down = 2 * (n - 1) - k
    print(
        f"{up[k]:12.0f}  {friction[k]:14.2f}  {friction[down]:16.2f}  "
        f"{tip_x[k]:11.3f}  {tip_x[down]:13.3f}  {plain_x[k]:12.3f}"
    )

fig, (ax_f, ax_n, ax_x) = plt.subplots(1, 3, figsize=(13, 4.0), constrained_layout=True)
for ax, values, mu0, label in (
    (ax_f, friction, np.zeros(n), "friction force on the finger, x (mN)"),
    (ax_n, normal, plain_n, "normal force on the finger, z (mN)"),
    (ax_x, tip_x, plain_x, "tip position x (mm)"),
):
    ax.plot(up, values[:n], "o-", ms=3, color="tab:red", label="pressure rising")
    ax.plot(up[::-1], values[n - 1 :], "s-", ms=3, color="tab:blue", label="pressure falling")
    ax.plot(up, mu0, "--", color="0.4", label="frictionless")
    ax.set_xlabel("chamber pressure (kPa)")
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)
ax_f.set_title("Friction (mu = 0.2)")
ax_n.set_title("Normal force")
ax_x.set_title("Tip position")
ax_f.legend(loc="lower left", fontsize=8)

out_dir.mkdir(parents=True, exist_ok=True)
fig.savefig(out_dir / "friction_hysteresis.png", dpi=120)
print(f"wrote {out_dir / 'friction_hysteresis.png'}")
