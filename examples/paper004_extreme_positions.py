"""Paper 004, Sec. 4.1: tip of the modular two-module actuator at its seven extreme positions.

The paper validates its partition model (Table 1, eqs. 29-31; E = 200 N) at the "extreme
positions" of the pressure grid 0-95 kPa (Sec. 3.2), with and without a 1 N weight at the
free end (Figs. 7 and 8, Table 3):

- positions 1, 3, 5: one chamber at the maximum pressure, the others at 0;
- positions 2, 4, 6: two chambers at the maximum, the third at 0;
- position 7: all three chambers at the maximum.

Which chambers belong to which position number is only drawn in Fig. 7, which is not in the
text. Assumed here: the numbers go once around the x-y plane, alternating single and double
chambers, as the split into odd (one chamber) and even (two chambers) numbers suggests:
1 = chamber 1, 2 = chambers 1+2, 3 = chamber 2, 4 = chambers 2+3, 5 = chamber 3,
6 = chambers 3+1, 7 = all. Chamber k is pressure channel k-1 at angle (k-1) 120 deg from d1
(design file modular_two_module.toml).

Coordinates are the paper's: z along the unloaded centreline from the clamp towards the free
end, x and y in the clamp plane (here along the base directors d1, d2; the paper does not
give the orientation of its x axis relative to the chambers). Lateral = sqrt(x^2 + y^2).
Run: python examples/paper004_extreme_positions.py
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import softrod
from softrod.compare import clamp_frame

P_MAX = 95e3  # Pa, the top of the pressure grid of Sec. 3.2 (0 to 95 kPa in 23.75 kPa steps)
# Position number -> chambers (1-based) at P_MAX; see the module docstring for the assumption.
POSITIONS = {1: (1,), 2: (1, 2), 3: (2,), 4: (2, 3), 5: (3,), 6: (3, 1), 7: (1, 2, 3)}
DESIGNS = {"no load": "paper004", "1 N at the tip": "paper004_1N_tip"}


def extreme_positions() -> pd.DataFrame:
    """One row per load case and position, tip coordinates in mm (clamp frame)."""
    pressures = np.zeros((len(POSITIONS), 3))
    for row, chambers in enumerate(POSITIONS.values()):
        pressures[row, [c - 1 for c in chambers]] = P_MAX
    rows = []
    for load, name in DESIGNS.items():
        design = softrod.load_design(name)
        out = softrod.solve_statics_batch(design, pressures)
        tip_mm = clamp_frame(design, out.tip_position) * 1e3
        for row, (pos, chambers) in enumerate(POSITIONS.items()):
            x, y, z = tip_mm[row]
            rows.append(
                {
                    "load": load,
                    "position": pos,
                    "chambers": "+".join(str(c) for c in chambers),
                    # the paper's chambers 1, 2, 3 are softrod's channels 0, 1, 2
                    "p0_kPa": pressures[row, 0] / 1e3,
                    "p1_kPa": pressures[row, 1] / 1e3,
                    "p2_kPa": pressures[row, 2] / 1e3,
                    "x_mm": x,
                    "y_mm": y,
                    "z_mm": z,
                    "lateral_mm": float(np.hypot(x, y)),
                    "converged": bool(out.converged[row]),
                }
            )
    return pd.DataFrame(rows)


def main() -> None:
    df = extreme_positions()
    for load, name in DESIGNS.items():
        design = softrod.load_design(name)
        rest = clamp_frame(design, softrod.solve_statics(design, [0, 0, 0]).tip_position) * 1e3
        print(
            f"{name} ({load}): rod length {design.length * 1e3:.1f} mm, "
            f"unpressurised tip z = {rest[2]:.2f} mm"
        )
        table = df[df["load"] == load].drop(columns="load")
        # round first, then + 0.0 turns the -0.0 of tiny negative values into 0.0
        print(table.to_string(index=False, float_format=lambda v: f"{round(v, 2) + 0.0:.2f}"))
        print()


if __name__ == "__main__":
    main()
