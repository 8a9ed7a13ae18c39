"""Shared pytest setup, and helpers the test modules import (``from conftest import ...``)."""

import copy
import os
import re

import numpy as np
import pytest
from hypothesis import settings

# The test command (scripts/test.sh) runs the property tests on hypothesis's derandomized
# examples (`--hypothesis-profile=reproducible`), so a run on a fresh clone is reproducible;
# a plain `pytest` draws new random examples each time and keeps what fails in .hypothesis,
# which is how the property tests keep finding new defects.
settings.register_profile("reproducible", derandomize=True, database=None)

# Tests never open windows: pick matplotlib's non-interactive backend before anything
# imports pyplot (the library itself never selects a backend).
os.environ.setdefault("MPLBACKEND", "Agg")

DELETE = object()  # an entry's value for with_entries: remove the entry


def pytest_addoption(parser):
    parser.addoption(
        "--fuzz-long",
        action="store_true",
        default=False,
        help="run the fuzz suite (tests/test_fuzz.py) with many thousands of random cases "
        "instead of the few hundred fixed ones of the default run",
    )
    parser.addoption(
        "--long-calibration",
        action="store_true",
        default=False,
        help="run the 20-seed coverage test of the dynamic calibration's standard errors "
        "(tests/test_calibration_dynamic.py; about a minute) besides its quick 3-seed one",
    )


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """After a run of the fuzz suite: cases per target and outcome, and the defects."""
    runs = getattr(config, "_softrod_fuzz", [])
    if not runs:
        return
    from fuzzing import Stats

    total = Stats()
    for s in runs:
        for key, n in s.counts.items():
            total.counts[key] = total.counts.get(key, 0) + n
        total.defects += s.defects
    terminalreporter.section(f"softrod fuzz suite: {total.total} cases")
    terminalreporter.write_line(total.table())
    for target, _case, out in total.defects[:20]:
        terminalreporter.write_line(f"defect [{target}] {out.defect}: {out.detail[:300]}")


def with_entries(name: str, entries: dict) -> dict:
    """A copy of the document of the bundled design ``name`` with entries set by path
    (``"sections[1].law.alpha"``), or removed (value DELETE). Not validated, unlike
    ``Design.replace``: tests build bad documents on purpose and load them themselves."""
    from softrod import load_design  # after the backend is chosen above

    doc = copy.deepcopy(load_design(name).document)
    for path, value in entries.items():
        keys = [int(k) if k.isdigit() else k for k in re.findall(r"[^.\[\]]+", path)]
        target = doc
        for k in keys[:-1]:
            target = target[k]
        if value is DELETE:
            del target[keys[-1]]
        else:
            target[keys[-1]] = value
    return doc


@pytest.fixture
def run():
    """Invoke the CLI in-process: ``run("solve", design, "--pressure", "30kPa,0,0")``."""
    from click.testing import CliRunner
    from softrod.cli import main

    runner = CliRunner()

    def invoke(*args):
        return runner.invoke(main, [str(a) for a in args], catch_exceptions=False)

    return invoke


def assert_clean_error(result, code: int, *fragments: str):
    """A CLI failure: exit ``code`` and one ``error:`` line on stderr holding ``fragments``."""
    assert result.exit_code == code, result.output
    err = result.stderr
    assert err.startswith("error: "), err
    assert len(err.strip().splitlines()) == 1, err  # one line, never a traceback
    assert "Traceback" not in result.output
    for f in fragments:
        assert f in err, (f, err)


def ring_down_frequency(trajectory, t_start, axis=0):
    """Damped frequency (Hz) and decay rate (1/s) of the tip's motion along world ``axis``
    (0: x) after t_start, by a least-squares fit of a e^(-s t) cos(w t + phi) + c."""
    from scipy.optimize import curve_fit

    t, x = trajectory.time, trajectory.tip_position[:, axis]
    m = t > t_start
    xx = x[m] - x[m].mean()
    freqs = np.fft.rfftfreq(len(xx), t[1] - t[0])
    w0 = 2 * np.pi * freqs[np.argmax(np.abs(np.fft.rfft(xx)))]

    def model(t, a, s, w, ph, c):
        return a * np.exp(-s * t) * np.cos(w * t + ph) + c

    # Time from t_start: the amplitude is then that at t_start, whatever t_start is (a fit in
    # absolute time scales it by e^(s t_start) and overflows the exponential for late starts).
    p, _ = curve_fit(
        model, t[m] - t_start, x[m], p0=[2 * xx.std(), 1.0, w0, 0.0, x[m].mean()], maxfev=20000
    )
    return p[2] / (2 * np.pi), p[1]


@pytest.fixture(scope="module")
def finger():
    """The bundled finger pressed onto its table (tests/friction_designs.py)."""
    from friction_designs import FINGER
    from softrod import load_design

    return load_design(FINGER)


@pytest.fixture(scope="module")
def rough(finger):
    """The same finger on a table with Coulomb friction MU (tests/friction_designs.py)."""
    from friction_designs import MU

    return finger.replace({"obstacles[0].friction": MU})
