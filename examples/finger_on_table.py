"""The pre-curved finger pressed onto a table (design ``prebent_finger_on_table``,
docs/contact.md): shapes at several pressures (side view) and the contact force against the
chamber pressure.

Writes docs/figures/contact_finger.png and prints the contact force per pressure.

Run: python examples/finger_on_table.py [output folder]
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
design = softrod.load_design("prebent_finger_on_table")
free = design.with_obstacles([])
table_z = design.spec["obstacles"][0]["point"][2]
radius = design.spec["sections"][0]["outer_radius"]

pressures_kpa = np.linspace(0.0, 50.0, 26)
force, free_drop = [], []
for p in pressures_kpa:
    sol = softrod.solve_statics(design, [p * 1e3])
    force.append(sol.contact.total[2])
    # How far the free finger's surface would reach below the table.
    tip_free = softrod.solve_statics(free, [p * 1e3]).tip_position
    free_drop.append((table_z - (tip_free[2] - radius)) * 1e3)
force = np.array(force)
print("pressure_kPa  contact_force_mN  free_finger_below_table_mm")
for p, f, d in zip(pressures_kpa[::5], force[::5], free_drop[::5], strict=True):
    print(f"{p:12.0f}  {f * 1e3:16.2f}  {d:26.2f}")

fig, (ax_shape, ax_force) = plt.subplots(
    1, 2, figsize=(10, 4.6), constrained_layout=True, gridspec_kw={"width_ratios": [1.1, 1.0]}
)
colours = plt.cm.viridis(np.linspace(0.0, 0.9, 4))
for p, c in zip((0.0, 20.0, 35.0, 50.0), colours, strict=True):
    sol = softrod.solve_statics(design, [p * 1e3])
    x, z = sol.position[:, 0] * 1e3, sol.position[:, 2] * 1e3
    ax_shape.plot(x, z, color=c, lw=0.8, ls="--")
    # The finger's outline: the centreline -/+ its outer radius along d1 (the bending plane).
    d1 = sol.rotation[:, :, 0]
    for side in (-1.0, 1.0):
        edge = sol.position + side * radius * d1
        ax_shape.plot(
            edge[:, 0] * 1e3, edge[:, 2] * 1e3, color=c, label=f"{p:.0f} kPa" if side > 0 else None
        )
    # The rounded end (a hemisphere of the outer radius about the tip), which meets the table.
    t3 = sol.rotation[-1][:, 2]
    t1 = d1[-1]
    ang = np.linspace(-np.pi / 2, np.pi / 2, 40)
    cap = sol.position[-1] + radius * (np.outer(np.cos(ang), t3) + np.outer(np.sin(ang), t1))
    ax_shape.plot(cap[:, 0] * 1e3, cap[:, 2] * 1e3, color=c)
    touching = sol.contact.in_contact
    if touching.any():
        pts = sol.contact.point[touching] * 1e3
        ax_shape.plot(pts[:, 0], pts[:, 2], "o", color=c, ms=4)
ax_shape.axhline(table_z * 1e3, color="0.3", lw=2)
ax_shape.text(40.0, table_z * 1e3 - 5.0, "table", color="0.3")
ax_shape.set_xlabel("x (mm)")
ax_shape.set_ylabel("z (mm)")
ax_shape.set_title("Finger hanging above the table (side view)")
ax_shape.set_aspect("equal")
ax_shape.set_xlim(-15.0, 70.0)
ax_shape.set_ylim(table_z * 1e3 - 8.0, 10.0)
ax_shape.legend(loc="upper right", fontsize=8, title="outline; dots: contact", title_fontsize=8)

ax_force.plot(pressures_kpa, force * 1e3, "o-", ms=3)
ax_force.set_xlabel("chamber pressure (kPa)")
ax_force.set_ylabel("contact force on the table (mN)")
ax_force.set_title("Contact force vs pressure")
ax_force.grid(alpha=0.3)

out_dir.mkdir(parents=True, exist_ok=True)
fig.savefig(out_dir / "contact_finger.png", dpi=120)
print(f"wrote {out_dir / 'contact_finger.png'}")
