"""Shared pytest setup, and helpers the test modules import (``from conftest import ...``)."""

import copy
import os
import re

import pytest

# Tests never open windows: pick matplotlib's non-interactive backend before anything
# imports pyplot (the library itself never selects a backend).
os.environ.setdefault("MPLBACKEND", "Agg")

DELETE = object()  # an entry's value for with_entries: remove the entry


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
