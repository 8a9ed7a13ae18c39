"""Two pre-curved fingers whose tips hold one clip, pressed onto their table (the bundled
system ``two_fingers_on_table``, docs/contact.md "Friction in the statics", "Systems of
rods"), with a frictionless table and with Coulomb friction mu = 0.5 on it: the clip's
position, each finger's normal and friction force against the pressure, and front and side
views of both systems at 50 kPa.

Writes two_fingers_on_table.png into the output folder (its argument; default
docs/figures) and prints the table.

Run: python examples/two_fingers_on_table.py [output folder]
"""

import dataclasses
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import softrod  # noqa: E402
from softrod.system_plots import plot_system  # noqa: E402

out_dir = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent.parent / "docs" / "figures"
)
smooth = softrod.load_system("two_fingers_on_table")
# The same system with friction on every finger's table: a rod's design replaced.
rough = dataclasses.replace(
    smooth,
    rods=tuple(
        dataclasses.replace(r, design=r.design.replace({"obstacles[0].friction": 0.5}))
        for r in smooth.rods
    ),
)

print("pressure_kPa  clip_x_mm  clip_x_mu_mm  normal_mN  normal_mu_mN  friction_mu_mN")
last = {}
for p in (10.0, 20.0, 35.0, 50.0):
    both = [[p * 1e3], [p * 1e3]]
    a = softrod.solve_system(smooth, both)
    b = softrod.solve_system(rough, both)  # a load path from the unloaded fingers
    ca, cb = a.rods[0].contact, b.rods[0].contact
    print(
        f"{p:12.0f}  {a.platform_position[0] * 1e3:9.3f}  {b.platform_position[0] * 1e3:12.3f}  "
        f"{ca.total_force[0][2] * 1e3:9.2f}  {cb.total_force[0][2] * 1e3:12.2f}  "
        f"{cb.friction_force[0][0] * 1e3:14.2f}"
    )
    last = {"frictionless table": a, "table with mu = 0.5": b}

out_dir.mkdir(parents=True, exist_ok=True)
labels = [f"{name}, 50 kPa per finger" for name in last]
plot_system(
    list(last.values()),
    out_dir / "two_fingers_on_table.png",
    labels=labels,
    title="two_fingers_on_table: the clip pressed onto the table",
)
print(f"wrote {out_dir / 'two_fingers_on_table.png'}")
