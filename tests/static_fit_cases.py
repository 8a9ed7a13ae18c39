"""Static calibration cases shared by tests/test_calibration_engine.py and
tests/data/make_static_fit_reference.py (the numbers softrod gave before the engine)."""

from __future__ import annotations

import numpy as np
import softrod
from softrod.calibration.params import design_changes, parse_parameters

FAST = {"numerics": {"step_length": "13 mm"}}


def _m3():
    return softrod.load_design("paper002_M3_vertical").replace(FAST)


def _pressures(n: int, top: float = 50e3):
    ramp = top * np.arange(1, n + 1) / n
    rows, exp = [], []
    for e, pattern in enumerate(([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.4, 0])):
        rows.append(np.outer(ramp, pattern))
        exp += [e] * n
    return np.vstack(rows), np.array(exp)


def _made(design, truth: dict):
    params = parse_parameters(list(truth), design)
    return design.replace(design_changes(params, list(truth.values()), design))


def _data(design, n, noise_mm, seed):
    p, exp = _pressures(n)
    return softrod.synthesize_dataset(design, p, noise_mm=noise_mm, seed=seed, experiment=exp)


def run_case(name: str):
    m3 = _m3()
    if name == "lm_five_parameters_split":
        truth = {"c_b": 1.45, "c_e": 2.6, "alpha": 7.0, "offset_1": 0.5e-3, "offset_2": 1.2e-3}
        data = _data(_made(m3, truth), 6, 0.2, 1)
        return softrod.calibrate(m3, data, list(truth), split="experiment", test=3)
    if name == "lm_E_cp_offset":
        truth = {"E[ecoflex_00_50_table2]": 90e3, "c_p": 0.3, "offset_2": 0.8e-3}
        data = _data(_made(m3, truth), 4, 0.1, 2)
        return softrod.calibrate(m3, data, list(truth))
    if name == "trf_bounded":
        truth = {"c_b": 1.2, "offset_1": 0.4e-3}
        data = _data(_made(m3, truth), 4, 0.2, 3)
        return softrod.calibrate(
            m3, data, list(truth), bounds={"c_b": (0.5, 3.0), "offset_1": ("-2 mm", "2 mm")}
        )
    if name == "nelder_mead":
        data = _data(_made(m3, {"c_b": 1.2}), 4, 0.1, 4)
        return softrod.calibrate(m3, data, ["c_b", "c_e"], method="nelder-mead")
    if name == "sigma":
        mapped = m3.replace(
            {"sections[1].law": {**m3.document["sections"][1]["law"], "stiffness_map": True}}
        )
        p, exp = _pressures(3)
        smap = softrod.StiffnessMap.constant([0.8, 1.3, 0.9], 3)
        sol = softrod.solve_statics_batch(mapped, p, stiffness_map=smap)
        rng = np.random.default_rng(5)
        data = softrod.Dataset(
            pressures=p,
            tip_position=sol.tip_position + rng.normal(0, 1e-4, (len(p), 3)),
            experiment=exp,
        )
        return softrod.calibrate(m3, data, ["sigma_ext", "sigma_bend_1", "sigma_bend_2"])
    if name == "restarts":
        data = _data(_made(m3, {"c_b": 1.3}), 3, 0.1, 6)
        return softrod.calibrate(m3, data, ["c_b"], restarts=2, seed=1)
    raise KeyError(name)


CASES = (
    "lm_five_parameters_split",
    "lm_E_cp_offset",
    "trf_bounded",
    "nelder_mead",
    "sigma",
    "restarts",
)
