"""``softrod.trajectory_sensitivities``: the exact forward sensitivities of a rod's motion
(tip and markers) with respect to named model parameters, against central differences of
whole ``simulate`` runs (docs/dynamics.md, "Parameter sensitivities of the motion"; the
core's own checks are crates/softrod-core/tests/suite/dynamics_sensitivity.rs), the run itself
against ``simulate``'s, and the refusals by name."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from softrod import InputError
from softrod.calibration.params import design_changes, parse_parameters

pytestmark = pytest.mark.filterwarnings("error")

DESIGN = "spa_three_chamber_130mm"
DT = 2e-3
T_END = 0.03  # s: 15 steps
#: Newton to 1e-12 in every run, so that the differences see the parameters and not the
#: solver's stopping point.
TOL = 1e-12
#: Central differences with a relative step H: truncation ~H^2 = 1e-8 of a derivative;
#: each run's Newton error (~TOL L ~ 1e-13 m) over the step 2 H theta, relative to the
#: largest derivative times theta (millimetres of tip motion here), ~1e-7; 1e-6 of the
#: largest derivative bounds both with a margin.
H = 1e-4
RTOL = 1e-6
PARAMS = ["c_b[body]", "damping_time"]
MARKERS = ["65 mm", ("100 mm", ["12 mm", "0 mm"])]


def ramp(t):
    """Channel 0 ramped to 30 kPa in 10 ms, channel 2 held at 10 kPa."""
    return [min(t / 0.01, 1.0) * 30e3, 0.0, 10e3]


@pytest.fixture(scope="module")
def design():
    # A damping time of its own (the bundled one is part of what is differentiated).
    return softrod.load_design(DESIGN).replace({"dynamics.damping_time": "20 ms"})


def test_derivatives_match_central_differences_of_simulate(design):
    out = softrod.trajectory_sensitivities(
        design, ramp, T_END, PARAMS, markers=MARKERS, dt=DT, tol=TOL
    )
    k = round(T_END / DT) + 1
    assert out["params"] == tuple(PARAMS) and out["units"] == ("1", "s")
    assert out["time"].shape == (k,) and out["tip_position"].shape == (k, 3)
    assert out["d_tip_position"].shape == (k, 3, 2)
    assert out["d_marker_position"].shape == (k, 2, 3, 2)
    params = parse_parameters(PARAMS, design)
    theta = np.array([p.value(design) for p in params])
    for j, p in enumerate(params):
        moved = []
        for sign in (1.0, -1.0):
            values = theta.copy()
            values[j] *= 1.0 + sign * H
            d = design.replace(design_changes(params, values, design))
            tr = softrod.simulate(d, ramp, T_END, dt=DT, tol=TOL, markers=MARKERS, progress=False)
            moved.append((tr.tip_position, tr.marker_position))
        step = 2.0 * H * theta[j]
        fd_tip = (moved[0][0] - moved[1][0]) / step
        fd_markers = (moved[0][1] - moved[1][1]) / step
        for exact, fd in (
            (out["d_tip_position"][..., j], fd_tip),
            (out["d_marker_position"][..., j], fd_markers),
        ):
            scale = np.abs(fd).max()
            assert scale > 0, p.name  # the parameter moves the rod
            assert np.abs(exact - fd).max() <= RTOL * scale, (p.name, np.abs(exact - fd).max())


def test_the_run_is_simulates(design):
    """Tracking the derivatives does not change the run: bit for bit simulate's tip and
    markers at every step (same start, steps and Newton settings)."""
    out = softrod.trajectory_sensitivities(design, ramp, T_END, PARAMS, markers=MARKERS, dt=DT)
    tr = softrod.simulate(design, ramp, T_END, dt=DT, markers=MARKERS, progress=False)
    np.testing.assert_array_equal(out["time"], tr.time)
    np.testing.assert_array_equal(out["tip_position"], tr.tip_position)
    np.testing.assert_array_equal(out["marker_position"], tr.marker_position)
    plain = softrod.trajectory_sensitivities(design, ramp, T_END, [], dt=DT)
    assert plain["params"] == () and "d_tip_position" not in plain
    np.testing.assert_array_equal(plain["tip_position"], tr.tip_position)


def test_tensions_drive_a_tendon_finger():
    """Tendon tensions are inputs of the run (held or a function of t), not parameters."""
    till = softrod.load_design("till_tendon_robot")  # no chambers: no pressure schedule
    out = softrod.trajectory_sensitivities(
        till, None, 0.01, "c_b", tensions=lambda t: [min(t / 0.005, 1.0) * 5.0, 0, 0, 0], dt=DT
    )
    assert out["d_tip_position"].shape == (6, 3, 1)
    assert np.abs(out["tip_position"][-1] - out["tip_position"][0]).max() > 1e-4


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"params": ["registration_angle"]}, "params"),
        ({"params": ["no_such_kind"]}, "params"),
        ({"params": "c_b[no_such_section]"}, "params"),
        ({"params": ""}, "params"),  # no names: the empty list runs without derivatives
        ({"markers": ["1 m"]}, "markers"),
        ({"tensions": [1.0]}, "tensions"),  # no tendons
        ({"dt": "0 s"}, "dt"),
        ({"t_end": -1.0}, "t_end"),
    ],
)
def test_bad_input_is_refused_by_name(design, kwargs, field):
    args = {"params": PARAMS, "t_end": T_END, **kwargs}
    with pytest.raises(InputError) as e:
        softrod.trajectory_sensitivities(
            design,
            ramp,
            args.pop("t_end"),
            args.pop("params"),
            dt=args.pop("dt", DT),
            **args,
        )
    assert e.value.field.startswith(field), e.value.field


def test_progress_reports_the_simulated_time(design):
    """Long runs show progress as simulate's do: a callable gets (t_done, t_end, wall_s)
    after each chunk of steps, t_done rising to t_end."""
    seen = []
    softrod.trajectory_sensitivities(
        design, ramp, T_END, PARAMS, dt=DT, progress=lambda done, total, wall: seen.append(done)
    )
    assert seen and np.all(np.diff(seen) > 0)
    assert seen[-1] == pytest.approx(T_END, rel=1e-12)


def test_progress_of_a_run_longer_than_t_end_rises_to_its_length(design):
    """t_end = 4 ms at dt = 5 ms is one whole step: the run (and its reports) end at 5 ms,
    never past the total they report (found by the long fuzz run: (5 ms, 4 ms) before)."""
    seen = []
    out = softrod.trajectory_sensitivities(
        design,
        [30e3, 0.0, 0.0],
        "4 ms",
        ["c_b"],
        dt="5 ms",
        progress=lambda done, total, wall: seen.append((done, total)),
    )
    assert out["time"][-1] == pytest.approx(5e-3, rel=1e-12)
    assert seen == [pytest.approx((5e-3, 5e-3), rel=1e-12)]
    reports = []
    softrod.simulate(
        design, [30e3, 0.0, 0.0], "4 ms", dt="5 ms", progress=lambda d, t, w: reports.append((d, t))
    )
    assert reports == [pytest.approx((5e-3, 5e-3), rel=1e-12)]
