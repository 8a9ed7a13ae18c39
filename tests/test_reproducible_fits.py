"""Fits are reproducible: the same data and seed give the same numbers, bit for bit, whatever
the caller's BLAS thread settings (issue 15, item 1).

softrod runs BLAS on one thread inside its fits (softrod._threads): the matrices are small, so
threads only add synchronisation (fit_stiffness_map took 87.5 s with the default threads and
2.3 s with one on a busy 2-core machine), and with one thread every product is summed in one
fixed order. These tests set the caller's BLAS threads to 1 and to 2 around the same fit and
compare the results exactly: equality of doubles, no tolerance.
"""

import subprocess
import sys

import numpy as np
import pytest
import softrod
from softrod import fit_stiffness_map, identify_stiffness
from softrod._threads import FIT_BLAS_THREADS, fit_blas_threads
from threadpoolctl import threadpool_info, threadpool_limits

SPA = "spa_three_chamber_130mm"


def _blas_threads() -> list[int]:
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


@pytest.fixture(scope="module")
def ident():
    """Per-sample factors of the bundled synthetic example's first 72 samples."""
    data = softrod.load_dataset("spa130_synthetic").subset(np.arange(72))
    return identify_stiffness(SPA, data)


def _fit(ident, blas_threads: int):
    # Small networks keep the test quick; the threads act on every network size the same way.
    with threadpool_limits(limits=blas_threads, user_api="blas"):
        return fit_stiffness_map(ident, hidden=(12, 10), seed=7)


def test_fit_blas_threads_limits_and_restores():
    import scipy.linalg  # noqa: F401 - every BLAS loaded, so "before" sees them all

    if not _blas_threads():
        pytest.skip("no BLAS library found by threadpoolctl")
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with fit_blas_threads():
            assert set(_blas_threads()) == {FIT_BLAS_THREADS}
        assert _blas_threads() == before  # the caller's setting comes back


def test_blas_loaded_late_is_limited_too():
    """In a fresh interpreter (scipy not imported yet, as in a script that calls a fit first):
    the BLAS that scipy and scikit-learn bring is limited as well."""
    code = (
        "import sys\n"
        "from softrod._threads import fit_blas_threads\n"
        "from threadpoolctl import threadpool_info\n"
        "assert 'scipy' not in sys.modules\n"
        "with fit_blas_threads():\n"
        "    import sklearn.neural_network\n"
        "    pools = threadpool_info()\n"
        "    print(sorted({p['num_threads'] for p in pools if p['user_api'] == 'blas'}))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() in (f"[{FIT_BLAS_THREADS}]", "[]")


@pytest.mark.filterwarnings("ignore:the network for:RuntimeWarning")  # 20 iterations only
def test_fit_stiffness_map_runs_blas_on_one_thread(ident, monkeypatch):
    """The networks train under the limit (recorded from inside a network's fit)."""
    import softrod.calibration.hybrid as hybrid

    if not _blas_threads():
        pytest.skip("no BLAS library found by threadpoolctl")
    seen = []
    make = hybrid._network

    def recording(*args):
        net = make(*args)
        fit = net.fit

        def fit_and_record(x, y):
            seen.append(_blas_threads())
            return fit(x, y)

        net.fit = fit_and_record
        return net

    monkeypatch.setattr(hybrid, "_network", recording)
    with threadpool_limits(limits=2, user_api="blas"):
        fit_stiffness_map(ident, hidden=(4,), max_iter=20, seed=0)
    assert len(seen) == 3 and all(set(s) == {FIT_BLAS_THREADS} for s in seen)


def test_fit_stiffness_map_is_the_same_under_any_blas_threads(ident):
    one, two = _fit(ident, 1), _fit(ident, 2)
    for a, b in zip(one.networks(), two.networks(), strict=True):
        for wa, wb in zip(a["weights"] + a["biases"], b["weights"] + b["biases"], strict=True):
            np.testing.assert_array_equal(wa, wb)
    p = ident.dataset.pressures
    np.testing.assert_array_equal(one.predict(p), two.predict(p))
    # Same seed, same split and same training table.
    np.testing.assert_array_equal(one.test_rows, two.test_rows)
    assert one.training.equals(two.training)


def test_another_seed_gives_other_networks(ident):
    a = fit_stiffness_map(ident, hidden=(12, 10), seed=7)
    b = fit_stiffness_map(ident, hidden=(12, 10), seed=8)
    assert not np.array_equal(a.networks()[0]["weights"][0], b.networks()[0]["weights"][0])


def test_calibrate_is_the_same_under_any_blas_threads():
    data = softrod.load_dataset("paper002_m3_synthetic").subset(np.arange(0, 240, 8))
    fits = []
    for blas in (1, 2):
        with threadpool_limits(limits=blas, user_api="blas"):
            fits.append(softrod.calibrate("paper002_M3_vertical", data, ["c_b", "c_e"], threads=1))
    a, b = fits
    np.testing.assert_array_equal(a.values, b.values)
    np.testing.assert_array_equal(a.std_errors, b.std_errors)
    np.testing.assert_array_equal(a.predicted, b.predicted)
