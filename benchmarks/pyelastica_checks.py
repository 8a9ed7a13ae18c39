"""Why PyElastica 1.0 and softrod differ on the issue-14 cantilever (a script, not a test).

    python benchmarks/pyelastica_checks.py   # ~3 min, writes results/pyelastica_checks.json

Needs PyElastica 1.0 (benchmark only; without it the script says so and exits). The rod, the
setup and the law variants are those of bench_dynamics.py (section 3) and pyelastica_laws.py.
Rest states are reached with PyElastica's AnalyticalLinearDamper (uniform_damping_constant
DAMPING 1/s) over T_REST s of simulated time, dt 25 us; softrod's are ``solve_statics``.

1. **Clamp.** At 1 % of g (sag 7.4 mm, the laws agree to first order), PyElastica's rest tip
   with n elements against softrod's statics of the rod (80 intervals) of length L and of
   length L - dx/2 (dx = L/n). OneEndFixedBC fixes the first node and the first element's
   directors, i.e. holds the rotation over the first element: if that is all, PyElastica at n
   elements matches softrod's rod shortened by dx/2, and its error against length L falls as
   1/n (first order).
2. **Static sag at full g** (the laws differ only through the dilatation, here at most
   ~2 %): PyElastica with softrod's law and as shipped, 80 and 160 elements, against
   softrod's statics (length L and L - dx/2).
3. **Rest-state stability.** 80 elements, full g, the same weak damping, 16 s: PyElastica as
   shipped, with softrod's law, and with each of its dilatation factors alone. A law whose
   couple depends on the stretch while the force does not depend on the curvature (m = B
   kappa / e^3, n = S sigma / e) is not the gradient of a stored energy: the stiffness is not
   symmetric and a rest state can lose stability by flutter, however small the step.
"""

from __future__ import annotations

import os

for _var in ("RAYON_NUM_THREADS", "NUMBA_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ[_var] = "1"

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import softrod  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_dynamics as bd  # noqa: E402
from common import bench_main, machine, result_header  # noqa: E402

DAMPING = 8.0  # 1/s
T_REST = 8.0
DT = 2.5e-5
T_FLUTTER = 16.0


def sr_static_tip(g: float, length: float) -> np.ndarray:
    return np.asarray(softrod.solve_statics(bd.cantilever(80, g, length)).tip_position)


def pe_rest(n: int, law: str, g: float, damping: float = DAMPING, t_end: float = T_REST):
    r = bd.pe_cantilever(n, DT, t_end, law=law, g=g, damping=damping)
    tips = r["tips"]
    return {
        "tip_m": tips[-1].tolist(),
        "moved_last_0.1s_m": float(np.abs(tips[-1] - tips[-101]).max()),
        "blew_up_at_s": r["blew_up_at_s"],
        "dilatation_range": r["dilatation_range"],
    }


def run(quick: bool) -> dict:
    t_start = time.perf_counter()
    info = machine()
    info["pyelastica"] = bd._pe_version()
    out: dict = {**result_header("pyelastica_checks", quick, info)}
    if bd.ea is None:
        print(f"PyElastica not importable ({bd.ELASTICA_ERROR}): nothing to check")
        return {**out, "skipped": bd.ELASTICA_ERROR, "wall_time_s": 0.0}
    elems = [20, 40] if quick else [20, 40, 80, 160]

    print(f"[1] clamp: 1 % of g, rest tips ({DAMPING:g}/s damping, {T_REST:g} s)")
    g1 = 0.01 * bd.G_ACC
    sr_l = sr_static_tip(g1, bd.L)
    rows = []
    for n in elems:
        rest = pe_rest(n, "pyelastica", g1)
        sr_short = sr_static_tip(g1, bd.L - bd.L / n / 2)
        tip = np.array(rest["tip_m"])
        row = {
            "n_elem": n,
            **rest,
            "z_minus_softrod_L_mm": float(tip[2] - sr_l[2]) * 1e3,
            "z_minus_softrod_L_minus_half_dx_mm": float(tip[2] - sr_short[2]) * 1e3,
        }
        rows.append(row)
        print(
            f"    {n} elements: tip z {tip[2] * 1e3:.4f} mm; - softrod(L) "
            f"{row['z_minus_softrod_L_mm']:+.4f} mm; - softrod(L - dx/2) "
            f"{row['z_minus_softrod_L_minus_half_dx_mm']:+.4f} mm"
        )
    out["clamp"] = {"gravity_m_s2": g1, "softrod_tip_L_m": sr_l.tolist(), "runs": rows}

    print(f"[2] static sag at full g ({DAMPING:g}/s damping; 50/s where {DAMPING:g}/s flutters)")
    sr_full = sr_static_tip(bd.G_ACC, bd.L)
    rows = []
    for n, law, damping in [
        (80, "softrod", DAMPING),
        (80, "pyelastica", DAMPING),
        (160, "softrod", DAMPING),
        (160, "pyelastica", 50.0),
    ][: 2 if quick else None]:
        rest = pe_rest(n, law, bd.G_ACC, damping)
        sr_short = sr_static_tip(bd.G_ACC, bd.L - bd.L / n / 2)
        tip = np.array(rest["tip_m"])
        row = {
            "n_elem": n,
            "law": law,
            "damping": damping,
            **rest,
            "minus_softrod_L_mm": ((tip - sr_full) * 1e3).tolist(),
            "minus_softrod_L_minus_half_dx_mm": ((tip - sr_short) * 1e3).tolist(),
        }
        rows.append(row)
        print(
            f"    {n} elements, {law} law: tip {np.round(tip * 1e3, 3).tolist()} mm (moved "
            f"{rest['moved_last_0.1s_m'] * 1e3:.1e} mm in the last 0.1 s); - softrod(L) "
            f"{np.round(row['minus_softrod_L_mm'], 3).tolist()} mm"
        )
    out["static_full_g"] = {"softrod_tip_L_m": sr_full.tolist(), "runs": rows}

    t_fl = 2.0 if quick else T_FLUTTER
    print(f"[3] rest-state stability: 80 elements, full g, {DAMPING:g}/s, {t_fl:g} s")
    rows = []
    variants = ["pyelastica", "softrod", "force/e only", "couple/e^3 only", "inertia/e only"]
    for law in variants[:2] if quick else variants:
        rest = pe_rest(80, law, bd.G_ACC, DAMPING, t_fl)
        rows.append({"law": law, **rest})
        print(
            f"    {law}: "
            + (
                f"blew up at {rest['blew_up_at_s']:.2f} s"
                if rest["blew_up_at_s"] is not None
                else f"at rest (moved {rest['moved_last_0.1s_m'] * 1e3:.1e} mm in the last 0.1 s)"
            )
        )
    out["rest_stability"] = {"n_elem": 80, "damping": DAMPING, "t_end_s": t_fl, "runs": rows}
    out["wall_time_s"] = time.perf_counter() - t_start
    return out


def main(argv=None) -> int:
    return bench_main(argv, __doc__, "pyelastica_checks", lambda args: run(args.quick))


if __name__ == "__main__":
    sys.exit(main())
