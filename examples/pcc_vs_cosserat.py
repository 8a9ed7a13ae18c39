"""PCC model (paper 003) vs Cosserat rod on the modified STIFF-FLOP arm.

Writes docs/figures/pcc_vs_cosserat.png (tip difference vs pressure: weightless, with
gravity, with gravity and a 10 g tip weight), docs/figures/pcc_dynamics_vs_cosserat.png
(the same three cases in motion: tip difference vs time under a 1 bar pulse on channels
5, 0, 1) and docs/figures/pcc_step_response.png (the PCC model's response to a 1 bar step on
channels 0, 2, 4 and on 5, 0, 1, as in paper 003 Figs. 8 and 9), and prints the numbers.
Channels are numbered from 0, as everywhere in softrod: paper 003's chambers 1 ... 6 are
channels 0 ... 5.

Run: python examples/pcc_vs_cosserat.py [output folder]
"""

import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import softrod  # noqa: E402
from softrod.pcc import run_pcc  # noqa: E402
from softrod.pcc.compare import (  # noqa: E402
    compare_pcc,
    compare_pcc_dynamics,
    plot_pcc_comparison,
    plot_pcc_dynamics_comparison,
    plot_pcc_step_response,
)

out_dir = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent.parent / "docs" / "figures"
)
design = softrod.load_design("stiff_flop_pcc")

t0 = time.perf_counter()
df = compare_pcc(design, [5, 0, 1], 1.5e5, steps=7)
rod = df[df["model"] == "cosserat"]  # one row per model: the error is on both
print(f"side by side: {len(rod)} levels x 2 models in {time.perf_counter() - t0:.2f} s")
columns = ["experiment", "level_kPa", "error_mm", "rel_error"]
print(rod[columns].to_string(index=False, float_format="%.4g"))
fig = plot_pcc_comparison(df, title="stiff_flop_pcc: PCC vs Cosserat rod, channels 5, 0, 1")
fig.savefig(out_dir / "pcc_vs_cosserat.png", dpi=120)
plt.close(fig)

zero, pulse = np.zeros(6), np.zeros(6)
pulse[[5, 0, 1]] = 1e5
schedule = softrod.PressureSchedule.steps([0.0, 0.1, 1.5], [zero, pulse, zero])
t0 = time.perf_counter()
dyn = compare_pcc_dynamics(design, schedule, 3.0, dt=2e-3)
print(f"dynamic side by side: 3 cases x 2 models, 3 s each, in {time.perf_counter() - t0:.2f} s")
rod = dyn[dyn["model"] == "cosserat"]
print(rod.groupby("experiment", sort=False)["error_mm"].max().to_string(float_format="%.3f mm"))
fig = plot_pcc_dynamics_comparison(
    dyn, title="stiff_flop_pcc: PCC vs Cosserat rod, 1 bar pulse on channels 5, 0, 1"
)
fig.savefig(out_dir / "pcc_dynamics_vs_cosserat.png", dpi=120)
plt.close(fig)

dt, n = 2e-3, 1500
runs = {}
for channels, label in (
    ([0, 2, 4], "1 bar step on channels 0, 2, 4 (elongation)"),
    ([5, 0, 1], "1 bar step on channels 5, 0, 1 (bending)"),
):
    p = np.zeros((n + 1, 6))
    p[int(0.2 / dt) :, channels] = 1e5
    t0 = time.perf_counter()
    runs[label] = run_pcc(design, dt, p, save_every=5)
    wall = time.perf_counter() - t0
    print(f"{label}: {n} steps of {dt * 1e3:.0f} ms in {wall:.3f} s")
fig = plot_pcc_step_response(runs, rest_length=design.length, title="stiff_flop_pcc: PCC model")
fig.savefig(out_dir / "pcc_step_response.png", dpi=120)
plt.close(fig)
names = "pcc_vs_cosserat.png, pcc_dynamics_vs_cosserat.png and pcc_step_response.png"
print(f"wrote {names} in {out_dir}")
