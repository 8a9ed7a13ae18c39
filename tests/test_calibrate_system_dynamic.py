"""Dynamic calibration of a system of rods from time series (``calibrate_system(...,
dynamic=True)``, docs/calibration.md "Systems of rods"): the adapter's exact Jacobian
against central differences of whole replays, a noise-free round trip that recovers E and
the platform's mass from trajectories made by ``simulate_system``, and the refusals."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from adapter_checks import central_difference
from softrod import InputError
from softrod.calibration.system import (
    SystemDynamic,
    calibrate_system,
    calibrated_system,
    parse_system_parameters,
)
from softrod.datasets import Dataset

pytestmark = pytest.mark.filterwarnings("error")

SYSTEM = "two_spa_platform"
NAMES = ["E[ecoflex_00_50_table1]", "platform_mass"]
#: The truth of the round trip, relative to the bundled system's values.
SCALE = np.array([1.15, 1.25])
DT = 2e-3
#: Samples every two steps over 0.06 s per experiment.
SAMPLE = 2 * DT
DURATION = 0.06
#: Newton's tolerance of the replays and of the synthetic runs (scaled unknowns).
TOL = 1e-10
#: Noise-free data of the same discretisation: the residual vanishes at the truth up to the
#: runs' Newton error (1e-10 of the scaled unknowns, ~1e-11 m), ~1e-8 of the parameters at
#: these derivatives (~1e-3 m per unit relative change); 1e-6 leaves two digits for the
#: conditioning, as the static round trip's bound (tests/test_calibrate_system.py).
EXACT = 1e-6
MARKERS = [(-1, 0.0, [0.02, 0.0, 0.005]), (0, 0.06, [0.0211, 0.0, 0.0])]


@pytest.fixture(scope="module")
def system():
    return softrod.load_system(SYSTEM)


def _knots(seed: int) -> np.ndarray:
    """(samples, 6) pressures at the sample times: each rod's chambers ramping between
    random levels up to 30 kPa."""
    rng = np.random.default_rng(seed)
    n = int(round(DURATION / SAMPLE)) + 1
    levels = rng.uniform(0.0, 30e3, size=(3, 6))
    t = np.linspace(0.0, DURATION, n)
    return np.column_stack([np.interp(t, [0.0, DURATION / 2, DURATION], lv) for lv in levels.T])


def _series(system, seeds=(1, 2)) -> Dataset:
    """Experiments made by simulate_system on ``system`` (sampled every SAMPLE s), the
    pressures joined linearly between the samples as a replay joins them."""
    rows = {"p": [], "tip": [], "markers": [], "time": [], "experiment": []}
    for e, seed in enumerate(seeds):
        knots = _knots(seed)
        t = np.linspace(0.0, DURATION, len(knots))

        def command(at, knots=knots, t=t):
            p = [float(np.interp(at, t, knots[:, c])) for c in range(6)]
            return [p[:3], p[3:]]

        sim = softrod.SystemSimulation(system, command(0.0), dt=DT, tol=TOL, on_unstable="ignore")
        sim._sim.set_markers([(None if b < 0 else b, s, o) for b, s, o in MARKERS])
        start = sim._sim.snapshot()
        run = sim._run(DURATION, command, None, None, None)
        pos = np.vstack(
            [
                np.reshape(start["platform_position"], (1, 3)),
                np.reshape(run["platform_position"], (-1, 3)),
            ]
        )
        mk = np.vstack(
            [
                np.reshape(start["marker_position"], (1, -1)),
                np.reshape(run["marker_position"], (-1, len(MARKERS) * 3)),
            ]
        )
        every = int(round(SAMPLE / DT))
        pick = np.arange(0, len(pos), every)
        assert len(pick) == len(knots)
        rows["p"].append(knots)
        rows["tip"].append(pos[pick])
        rows["markers"].append(mk[pick].reshape(-1, len(MARKERS), 3))
        rows["time"].append(t + 10.0 * e)  # each experiment on its own clock
        rows["experiment"].append(np.full(len(t), e))
    return Dataset(
        pressures=np.vstack(rows["p"]),
        tip_position=np.vstack(rows["tip"]),
        markers=np.concatenate(rows["markers"]),
        marker_s=np.array([s for _, s, _ in MARKERS]),
        marker_offset=np.array([o for _, _, o in MARKERS]),
        marker_body=np.array([b for b, _, _ in MARKERS]),
        time=np.concatenate(rows["time"]),
        experiment=np.concatenate(rows["experiment"]),
    )


def _damped(system, tau: float = 0.02):
    """``system`` with its rods damped (the bundled system's are not)."""
    tau_p = parse_system_parameters(["damping_time"], system, dynamic=True)
    return calibrated_system(system, tau_p, [tau])


def test_dynamic_system_jacobian_matches_central_differences(system):
    """Every kind of column: a rod parameter on both rods, one on one rod, the platform's
    mass and the rods' damping time."""
    names = ["E", "rods[0].c_b", "platform_mass", "damping_time"]
    system = _damped(system)
    params = parse_system_parameters(names, system, dynamic=True)
    ds = _series(system, seeds=(3,))
    # Replays to 1e-13 (scaled): their error over the 2 h step (2e-5 of the value) stays
    # ~1e-8 of a column.
    adapter = SystemDynamic(system, ds, params, DT, 1e-13, 1)
    theta = np.array([p.value(system) for p in params]) * np.array([1.1, 0.95, 1.2, 1.1])
    rows = np.arange(len(ds))
    exact = adapter.predict(theta, rows, True)
    assert exact.ok.all()
    for quantity, d in (("tip", exact.d_tip), ("markers", exact.d_markers)):
        for j in range(len(params)):
            fd = central_difference(adapter, theta, rows, j, quantity)
            # Relative step 1e-5 (truncation ~1e-10 of the column), replay error over the
            # step ~1e-8: 1e-5 of the column's size is three digits above both; a missing
            # term (a rod's share, the platform's history) is off by percent.
            scale = np.abs(fd).max()
            assert scale > 0
            err = np.abs(d[..., j] - fd).max()
            assert err < 1e-5 * scale, f"{quantity} / {names[j]}: {err:.2e} of {scale:.2e}"


def test_noise_free_round_trip_recovers_e_and_the_platform_mass(system):
    params = parse_system_parameters(NAMES, system, dynamic=True)
    values = SCALE * np.array([p.value(system) for p in params])
    truth = calibrated_system(system, params, values)
    ds = _series(truth)
    res = calibrate_system(
        system, ds, NAMES, dynamic=True, dt=DT, options=softrod.SolverOptions(tol=TOL)
    )
    assert res.success
    np.testing.assert_allclose(res.values, values, rtol=EXACT)
    assert res.converged.all()
    assert np.abs(res.predicted - ds.tip_position).max() < 1e-9
    assert res.system.platform.mass == pytest.approx(values[1], rel=EXACT)


def test_refusals_name_the_field(system):
    ds = _series(system, seeds=(4,))
    static = Dataset(pressures=ds.pressures, tip_position=ds.tip_position)
    # The damping time is a parameter of time series only.
    with pytest.raises(InputError, match="params"):
        calibrate_system(system, static, ["damping_time"])
    # A damping time fitted on a log scale needs a start > 0.
    with pytest.raises(InputError, match="damping_time"):
        calibrate_system(system, ds, ["damping_time"], dynamic=True, dt=DT)
    # A time step without time series.
    with pytest.raises(InputError, match="dt"):
        calibrate_system(system, static, ["E"], dt=DT)
    # Time series need a time column.
    with pytest.raises(InputError, match="dataset.time"):
        calibrate_system(system, static, ["E"], dynamic=True, dt=DT)
    # Sigma factors are no system parameters.
    with pytest.raises(InputError, match="params"):
        calibrate_system(system, ds, ["sigma_ext"], dynamic=True, dt=DT)
    # A parameter its rods do not share a value of, named before any replay.
    params = parse_system_parameters(["rods[1].c_b"], system, dynamic=True)
    other = calibrated_system(system, params, [1.3])
    with pytest.raises(InputError, match=r"the rods differ \(rods\[0\] has 1, rods\[1\] has 1.3\)"):
        calibrate_system(other, ds, ["c_b"], dynamic=True, dt=DT)


def test_calibrate_system_command_replays_time_series(system, run, tmp_path):
    """``softrod calibrate-system --dynamic --dt``: the time series through a dataset file,
    the API's fit of the same file."""
    from softrod.datasets import write_dataset

    ds = _series(system, seeds=(5,))
    write_dataset(ds, tmp_path / "series.csv")
    result = run(
        "calibrate-system",
        SYSTEM,
        tmp_path / "series.csv",
        "--params",
        "E",
        "--dynamic",
        "--dt",
        "2 ms",
        "--json",
    )
    assert result.exit_code == 0, result.output
    import json

    fitted = json.loads(result.stdout)["parameters"][0]["value"]
    api = calibrate_system(system, tmp_path / "series.csv", ["E"], dynamic=True, dt=DT)
    assert fitted == api.values[0]


def test_tendon_driven_time_series_round_trip():
    """Tendon tensions as time inputs of a system's replay (two of Till's tendon robots side
    by side holding a 10 g platform, no pressure channels): the Jacobian against central
    differences, and a noise-free round trip recovers the bending factor and the damping
    time from the platform's trajectory made by simulate_system under the same tensions."""
    from softrod.system import Platform, SystemRod
    from softrod.system import System as Sys

    till = softrod.load_design("till_tendon_robot").replace({"sections[0].steps": 12})
    turn = np.asarray(till.spec["mounting"]["base_rotation"])
    rods = tuple(
        SystemRod(
            design=till.replace(
                {
                    "mounting.base_position": ["0 m", f"{y} m", "0 m"],
                    "dynamics.damping_time": "20 ms",
                }
            ),
            attachment=np.array([0.0, y, 0.0]),
            attachment_rotation=turn,
        )
        for y in (-0.05, 0.05)
    )
    pair = Sys("two_tills", rods, Platform(position=np.array([0.5, 0.0, 0.0]), mass=0.01))
    # The platform's mass would be all but a gauge of c_b here (|r| = 1.000: the tendons'
    # moment and the platform's weight both bend the rods against c_b EI); the damping time
    # is seen in how the platform lags the tensions.
    names = ["c_b", "damping_time"]
    params = parse_system_parameters(names, pair, dynamic=True)
    values = np.array([p.value(pair) for p in params]) * [1.2, 1.5]
    truth = calibrated_system(pair, params, values)
    n = 11
    t = np.linspace(0.0, 0.04, n)
    tensions = np.zeros((n, 8))
    tensions[:, 0] = np.linspace(0.0, 2.0, n)  # rod 0's tendon 0 pulled up
    tensions[:, 5] = np.linspace(1.0, 0.0, n)  # rod 1's tendon 1 let go

    def command(at):
        row = [float(np.interp(at, t, tensions[:, c])) for c in range(8)]
        return [row[:4], row[4:]]

    sim = softrod.SystemSimulation(truth, [[], []], tensions=command(0.0), dt=DT, tol=TOL)
    start = sim._sim.snapshot()
    run = sim._run(t[-1], [[], []], command, None, None)
    pos = np.vstack(
        [
            np.reshape(start["platform_position"], (1, 3)),
            np.reshape(run["platform_position"], (-1, 3)),
        ]
    )
    every = int(round((t[1] - t[0]) / DT))
    ds = Dataset(
        pressures=np.zeros((n, 0)),
        tensions=tensions,
        tip_position=pos[::every][:n],
        time=t,
        experiment=np.zeros(n, dtype=int),
    )
    adapter = SystemDynamic(pair, ds, params, DT, 1e-13, 1)
    theta = values * [0.9, 1.1]
    exact = adapter.predict(theta, np.arange(n), True)
    for j in range(len(params)):
        fd = central_difference(adapter, theta, np.arange(n), j, "tip")
        # As the pressure-driven check: 1e-5 of the column above the replays' error.
        assert np.abs(exact.d_tip[..., j] - fd).max() < 1e-5 * np.abs(fd).max()
    res = calibrate_system(
        pair, ds, names, dynamic=True, dt=DT, options=softrod.SolverOptions(tol=TOL)
    )
    np.testing.assert_allclose(res.values, values, rtol=EXACT)
