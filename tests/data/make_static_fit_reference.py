"""Write static_fit_reference.json: values, standard errors and costs of static fits as
softrod.calibrate made them BEFORE the calibration engine (commit 443ade3, the switchboard
of calibration/fit.py). tests/test_calibration_engine.py checks that the engine gives the
same numbers to 1e-9 (issue 19). Kept so that the cases can be read; running it again on a
later softrod writes that softrod's numbers, which is not the reference.

    python tests/data/make_static_fit_reference.py
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from static_fit_cases import CASES, run_case  # noqa: E402


def main() -> None:
    out = {}
    for name in CASES:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = run_case(name)
        out[name] = {
            "names": list(res.names),
            "values": np.asarray(res.values).tolist(),
            "std_errors": np.asarray(res.std_errors).tolist(),
            "cost_m2": float(res.cost_m2),
            "evaluations": int(res.evaluations),
            "correlation": np.asarray(res.correlation).tolist(),
        }
        print(name, out[name]["values"], out[name]["std_errors"])
    (HERE / "static_fit_reference.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
