"""Progress and speed where people wait (issue 15, item 5): a fast start-up (lazy imports),
``python -m softrod``, --quiet/--verbose and the "softrod" logger, progress reporting in the
long API calls, and animations with a frame budget."""

import logging
import subprocess
import sys

import numpy as np
import pytest
import softrod
from PIL import Image
from softrod import InputError
from softrod.dynamics import animation_plan
from softrod.progress import check_progress, reporter

HEAVY = ("numpy", "pandas", "scipy", "pyarrow", "matplotlib", "pint", "sklearn")
SPA = "spa_three_chamber_130mm"


def _python(code: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, **kw
    )


# --------------------------------------------------------------------------- start-up


def test_help_imports_no_heavy_library():
    """`softrod --help` and every command's --help: click and softrod's light modules only
    (not a timing test: what is imported decides the time)."""
    commands = [[], *[[name] for name in ("solve", "sweep", "calibrate", "simulate", "identify")]]
    commands += [["compare"], ["compare-pcc"], ["pcc-identify"], ["calibrate-axial"], ["demo"]]
    commands += [["view"], ["designs"]]
    code = (
        "import sys\n"
        "from softrod.cli import main\n"
        f"for args in {commands!r}:\n"
        "    try:\n"
        "        main([*args, '--help'], prog_name='softrod')\n"
        "    except SystemExit as exc:\n"
        "        assert exc.code == 0, (args, exc.code)\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    out = _python(code).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_import_softrod_is_lazy():
    out = _python(
        "import sys, softrod\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
        "softrod.load_design\n"  # the first use imports what it needs
        "print('numpy' in sys.modules)\n"
    ).stdout.split()
    assert out == ["[]", "True"]


def test_public_names_resolve():
    for name in softrod.__all__:
        assert getattr(softrod, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        softrod.nope  # noqa: B018
    assert "solve_statics" in dir(softrod)


def test_python_dash_m_softrod():
    for module in ("softrod", "softrod.cli"):
        res = subprocess.run(
            [sys.executable, "-m", module, "--version"], capture_output=True, text=True
        )
        assert res.returncode == 0 and res.stdout.strip() == f"softrod {softrod.__version__}"


# --------------------------------------------------------------------------- quiet / verbose


def test_quiet_leaves_out_notes_and_verbose_logs(run, tmp_path):
    out = tmp_path / "s.csv"
    args = ["sweep", SPA, "--grid", "0:20kPa:2", "--out", out]
    normal = run(*args)
    assert f"wrote {out}" in normal.stdout and normal.stderr == ""
    quiet = run("--quiet", *args)
    assert quiet.exit_code == 0 and "wrote" not in quiet.stdout
    assert "8 rows" in quiet.stdout  # the result stays
    loud = run("-vv", *args)
    assert loud.exit_code == 0 and f"softrod.io: wrote {out}" in loud.stderr
    # The command's log handler is gone when it ends: the library is quiet again.
    assert logging.getLogger("softrod").level == logging.NOTSET
    handlers = logging.getLogger("softrod").handlers
    assert all(isinstance(h, logging.NullHandler) for h in handlers)
    res = run("-q", "-v", "designs")
    assert res.exit_code == 2 and "not both" in res.output


def test_verbose_shows_the_steps_of_a_fit(run):
    res = run("-v", "calibrate", SPA, "spa130_synthetic", "--params", "c_b", "--json")
    assert res.exit_code == 0, res.output
    logged = "softrod.calibration.fit: calibrate spa_three_chamber_130mm (cosserat): c_b on 216"
    assert logged in res.stderr
    # --json keeps stdout pure JSON whatever the log level.
    import json

    assert set(json.loads(res.stdout)) == {"model", "dynamic", "parameters", "errors", "warnings"}


def test_library_logger_is_quiet_by_default(caplog):
    assert any(isinstance(h, logging.NullHandler) for h in logging.getLogger("softrod").handlers)
    with caplog.at_level(logging.INFO, logger="softrod"):
        softrod.simulate("pam_arm_220mm", [0.0, 0.0, 0.0], 0.01, dt=0.005, progress=False)
    assert any("simulate pam_arm_220mm: 2 steps" in r.getMessage() for r in caplog.records)


# --------------------------------------------------------------------------- progress


def test_progress_argument_is_checked():
    for ok in (None, True, False, print):
        assert check_progress(ok) is ok
    with pytest.raises(InputError, match="progress = 'str'"):
        check_progress("yes")
    with pytest.raises(InputError, match="progress"):
        softrod.simulate("pam_arm_220mm", [0.0, 0.0, 0.0], 0.01, progress=1)


def test_a_progress_callback_that_cannot_take_the_reports_is_refused_before_the_run():
    # simulate reports (t_done, t_end, wall_s): a one-argument callback would fail with a
    # TypeError at the first report, after the work; it is refused by name before.
    calls = []
    with pytest.raises(InputError, match="3 positional arguments") as err:
        softrod.simulate("pam_arm_220mm", [0.0] * 3, 0.01, progress=lambda t: calls.append(t))
    assert err.value.field == "progress" and not calls
    # Defaults and *args take the three arguments: accepted.
    for ok in (lambda a, b=0, c=0, d=0: calls.append(a), lambda *a: calls.append(a[0])):
        softrod.simulate("pam_arm_220mm", [0.0] * 3, 0.01, dt=0.005, progress=ok)
    assert len(calls) >= 2


def test_default_progress_is_off_in_scripts_and_on_by_request(monkeypatch, capsys):
    monkeypatch.delenv("SOFTROD_PROGRESS", raising=False)
    with reporter(None, "x", 1.0, lambda d: (d, "")) as report:
        assert report is None  # pytest is not an interactive session
    with reporter(False, "x", 1.0, lambda d: (d, "")) as report:
        assert report is None
    monkeypatch.setenv("SOFTROD_PROGRESS", "1")
    with reporter(None, "x", 1.0, lambda d: (d, "")) as report:
        assert callable(report)
        report(1.0)
    monkeypatch.setenv("SOFTROD_PROGRESS", "0")
    with reporter(True, "x", 1.0, lambda d: (d, "")) as report:
        assert callable(report)  # True wins over the environment


def test_long_calls_report_to_a_callable(tmp_path):
    seen = {"simulate": [], "fit": [], "animate": []}
    traj = softrod.simulate(
        "pam_arm_220mm",
        [0.0, 0.0, 0.0],
        0.05,
        dt=0.005,
        shapes=0.01,
        progress=lambda done, total, wall: seen["simulate"].append((done, total)),
    )
    assert seen["simulate"][-1] == pytest.approx((0.05, 0.05))
    traj.animate(
        tmp_path / "a.gif",
        dpi=20,
        figsize=(2, 2),
        progress=lambda done, total: seen["animate"].append((done, total)),
    )
    n = seen["animate"][-1][1]
    assert seen["animate"] == [(k, n) for k in range(1, n + 1)]
    data = softrod.load_dataset("spa130_synthetic").subset(np.arange(72))
    ident = softrod.identify_stiffness(SPA, data)
    softrod.fit_stiffness_map(
        ident, hidden=(6,), seed=0, progress=lambda done, total: seen["fit"].append(done)
    )
    assert seen["fit"] == [1, 2, 3]


# --------------------------------------------------------------------------- animations


def test_animation_plan_gives_a_watchable_clip():
    long = animation_plan(116.0)  # paper 000's square pulses
    assert long.n_frames <= 300 and 14.0 <= long.clip_s <= 16.0
    assert long.speed == pytest.approx(116.0 / 15.0)
    short = animation_plan(3.0)  # real time, 20 fps
    assert (short.speed, short.fps, short.n_frames) == (1.0, 20.0, 61)
    fast = animation_plan(116.0, speed=4.0)  # 29 s of clip: fewer frames per second
    assert fast.n_frames <= 300 and fast.fps < 20 and fast.clip_s == pytest.approx(29.0, rel=0.01)
    free = animation_plan(116.0, speed=1.0, max_frames=None)
    assert free.n_frames == 2321 and free.fps == 20
    for bad in ({"fps": 0}, {"speed": -1.0}, {"max_frames": 1}):
        with pytest.raises(InputError):
            animation_plan(10.0, **bad)


def test_gif_has_the_planned_frames(tmp_path):
    traj = softrod.simulate("pam_arm_220mm", [0.0, 0.0, 0.0], 0.5, dt=0.01, shapes=0.01)
    plan = animation_plan(0.5, max_frames=8)  # 8 frames at 14 fps instead of 11 at 20
    path = traj.animate(tmp_path / "a.gif", max_frames=8, dpi=20, figsize=(2, 2))
    with Image.open(path) as img:
        # Identical consecutive frames may be merged by the GIF writer: at most the plan.
        assert 2 <= img.n_frames <= plan.n_frames == 8
        # GIF stores frame times in units of 10 ms.
        assert abs(img.info["duration"] - 1000 / plan.fps) <= 10
