"""The docs run: every example in README.md and docs/*.md is executed, and shown output is real.

Conventions of the Markdown files (docs/writing-docs.md says the same):

- Every ```python block of a file runs, in order, in one namespace per file, in a fresh
  temporary working directory (so files a block writes are there for the next block).
- A fence tagged ``text`` or untagged right after a ```python block (only blank lines between)
  is that block's **output**: it must equal what the block prints (stdout), after removing
  trailing spaces and blank lines at both ends. ``...`` in the shown output matches any text
  (doctest's ELLIPSIS), for values that change from run to run (timings, temporary paths,
  round-off below the shown digits).
- ```console blocks hold ``$ softrod ...`` commands (or ``$ python examples/<name>.py``, the
  repository's examples, run in a subprocess), each followed by its output (compared the
  same way; no output shown means only the exit code is checked). A command must exit with 0,
  or with N when it ends in ``# exit N`` (an error shown on purpose). ```bash blocks: every line
  that starts with ``softrod`` is run and must exit 0. Commands run in-process through click's
  CliRunner, in the same working directory as the file's Python blocks.
- ``<!-- not-run: REASON -->`` on the line before a fence skips it; the reason is required
  (external data, a placeholder path, a signature listing, minutes of rendering).
- ``<!-- file: NAME -->`` before a fence writes its text to NAME in the working directory
  (sample input files shown in the docs).

Each file has a budget of CPU seconds, so the whole run stays near a minute on two cores.
"""

from __future__ import annotations

import contextlib
import doctest
import io
import os
import re
import shlex
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

# CPU budget per file (s). It catches an example that grew into a benchmark, not a slower or
# busier machine, so it sits at about three times the measured cost (see the report of
# `pytest tests/test_docs.py --durations=0`).
# CPU seconds (this process's threads and its example subprocesses), not wall time: a
# wall-clock budget failed at load 8. CPU seconds still vary between machines: the CI
# machine (2 cores, the Rust tests running beside pytest, a checked core) measured 1.6 times
# what a quiet developer machine does (calibration.md: 21.7 against 13.5 CPU s).
DEFAULT_BUDGET_S = 20.0
BUDGET_S = {
    "README.md": 40.0,
    "calibration.md": 40.0,
    "calibration-per-sample.md": 45.0,
    "dynamics.md": 40.0,
}


def _cpu_seconds() -> float:
    import resource

    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>`{3,}|~{3,})\s*(?P<lang>[\w+-]*)")
MARKER = re.compile(r"^<!--\s*(?P<kind>not-run|file)\s*:\s*(?P<arg>.*?)\s*-->\s*$")
OUTPUT_LANGS = ("", "text")
SHELL_LANGS = ("bash", "sh", "shell")


@dataclass
class Block:
    lang: str
    text: str
    line: int  # 1-based line of the opening fence
    marker: tuple[str, str] | None = None
    output: Block | None = None
    is_output: bool = False
    extra: dict = field(default_factory=dict)


def parse(path: Path) -> list[Block]:
    """The fenced blocks of a Markdown file, with their markers and output blocks."""
    lines = path.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    marker = None
    previous: Block | None = None  # the last block, while only blank lines follow it
    i = 0
    while i < len(lines):
        line = lines[i]
        m = FENCE.match(line)
        if not m:
            if line.strip():
                mk = MARKER.match(line.strip())
                marker = (mk["kind"], mk["arg"]) if mk else None
                previous = None
            i += 1
            continue
        fence, lang = m["fence"], m["lang"].lower()
        body = []
        j = i + 1
        while j < len(lines):
            close = lines[j].strip()
            if close.startswith(fence[0] * len(fence)) and not close.strip(fence[0]):
                break
            body.append(lines[j])
            j += 1
        else:
            raise AssertionError(f"{path.name}:{i + 1}: fence never closed")
        block = Block(lang, "\n".join(body) + "\n", i + 1, marker)
        if (
            previous is not None
            and previous.lang == "python"
            and previous.output is None
            and marker is None
            and lang in OUTPUT_LANGS
        ):
            previous.output = block
            block.is_output = True
            previous = None
        else:
            previous = block
        blocks.append(block)
        marker = None
        i = j + 1
    return blocks


def normalise(text: str) -> str:
    return "\n".join(line.rstrip() for line in text.strip("\n").splitlines()).strip("\n")


def check_output(where: str, got: str, want: str) -> None:
    got_n, want_n = normalise(got), normalise(want)
    checker = doctest.OutputChecker()
    if checker.check_output(want_n + "\n", got_n + "\n", doctest.ELLIPSIS):
        return
    import difflib

    diff = "\n".join(
        difflib.unified_diff(
            want_n.splitlines(), got_n.splitlines(), "shown in the docs", "real output", lineterm=""
        )
    )
    raise AssertionError(f"{where}: the shown output is not the real output:\n{diff}")


def console_commands(block: Block) -> list[tuple[str, str]]:
    """(command, shown output) for each ``$ `` line of a console block."""
    items: list[tuple[str, list[str]]] = []
    lines = block.text.splitlines()
    k = 0
    while k < len(lines):
        line = lines[k]
        if line.startswith("$ "):
            command = line[2:]
            while command.endswith("\\") and k + 1 < len(lines):
                k += 1
                command = command[:-1] + " " + lines[k].strip()
            items.append((command, []))
        elif items:
            items[-1][1].append(line)
        elif line.strip():
            raise AssertionError(f"line {block.line + 1 + k}: output before any '$ ' command")
        k += 1
    return [(c, "\n".join(out)) for c, out in items]


def shell_commands(block: Block) -> list[str]:
    """The ``softrod`` command lines of a bash block (continuations joined)."""
    out, current = [], None
    for line in block.text.splitlines():
        if current is not None:
            current += " " + line.strip()
        elif line.startswith("softrod "):
            current = line
        else:
            continue
        if current.endswith("\\"):
            current = current[:-1]
        else:
            out.append(current)
            current = None
    return out


def run_example(where: str, command: str, want: str | None) -> None:
    """``python examples/<name>.py ...``: the repository's example script, in a subprocess."""
    import subprocess
    import sys

    args = shlex.split(command, comments=True)
    script = ROOT / args[1]
    assert script.is_file() and script.parent == ROOT / "examples", f"{where}: {command!r}"
    proc = subprocess.run(
        [sys.executable, str(script), *args[2:]], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, f"{where}: {command!r} exited {proc.returncode}:\n{proc.stderr}"
    if want is not None and want.strip():
        check_output(f"{where}: {command!r}", proc.stdout + proc.stderr, want)


def run_cli(where: str, command: str, want: str | None) -> None:
    from click.testing import CliRunner
    from softrod.cli import main

    if command.startswith("python examples/"):
        return run_example(where, command, want)
    exit_code = re.search(r"#\s*exit\s+(\d+)\s*$", command)
    expected = int(exit_code[1]) if exit_code else 0
    args = shlex.split(command, comments=True)
    assert args and args[0] == "softrod", f"{where}: only softrod commands run here: {command!r}"
    result = CliRunner().invoke(main, args[1:], catch_exceptions=True)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"{where}: {command!r} raised") from result.exception
    assert result.exit_code == expected, (
        f"{where}: {command!r} exited {result.exit_code}, not {expected}:\n{result.output}"
    )
    if want is not None and want.strip():
        check_output(f"{where}: {command!r}", result.output, want)


def run_python(where: str, block: Block, namespace: dict) -> None:
    buf = io.StringIO()
    code = compile(block.text, where, "exec")
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(buf):
        warnings.simplefilter("always")
        exec(code, namespace)
    # softrod's own warnings (CalibrationWarning, ...) are part of what a block shows a user;
    # anything else (a deprecation in numpy, pandas, matplotlib) means the example is stale.
    foreign = [w for w in caught if not w.category.__module__.startswith("softrod")]
    assert not foreign, f"{where}: warnings from outside softrod: " + "; ".join(
        f"{w.category.__name__}: {w.message}" for w in foreign
    )
    if block.output is not None:
        check_output(where, buf.getvalue(), block.output.text)


def fresh_display_options() -> None:
    """Each page starts from numpy's and pandas' default print options: a page that sets
    them (pd.set_option("display.precision", 4)) must not change what the next one shows."""
    import numpy as np
    import pandas as pd

    np.set_printoptions(**NUMPY_PRINT_DEFAULTS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # options pandas has deprecated warn on reset
        pd.reset_option("all")


def _numpy_print_defaults() -> dict:
    import numpy as np

    return dict(np.get_printoptions())


NUMPY_PRINT_DEFAULTS = _numpy_print_defaults()


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_examples_run_and_show_real_output(doc, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "100")  # rich tables: the width the shown output has
    fresh_display_options()
    namespace: dict = {"__name__": "__docs__"}
    start = _cpu_seconds()
    try:
        for block in parse(doc):
            where = f"{doc.name}:{block.line}"
            kind, arg = block.marker or ("", "")
            if kind == "not-run":
                assert len(arg.split()) >= 2, f"{where}: say why the block does not run"
                continue
            if kind == "file":
                (tmp_path / arg).write_text(block.text, encoding="utf-8")
                continue
            if block.is_output:
                continue
            if block.lang == "python":
                run_python(where, block, namespace)
            elif block.lang == "console":
                for command, shown in console_commands(block):
                    run_cli(where, command, shown)
            elif block.lang in SHELL_LANGS:
                for command in shell_commands(block):
                    run_cli(where, command, None)
            elif block.lang == "" and re.search(r"^(\$ )?softrod ", block.text, re.M):
                raise AssertionError(
                    f"{where}: an untagged block with softrod commands: tag it console "
                    "($ prompts and output), bash (commands only) or text (a synopsis)"
                )
    finally:
        plt.close("all")
    elapsed = _cpu_seconds() - start
    budget = BUDGET_S.get(doc.name, DEFAULT_BUDGET_S)
    assert elapsed < budget, (
        f"{doc.name}: the examples took {elapsed:.1f} CPU s (budget {budget} CPU s)"
    )


# --------------------------------------------------------------------------- the parser itself


def test_parser_pairs_output_and_markers(tmp_path):
    md = tmp_path / "x.md"
    md.write_text(
        "text\n\n```python\nprint(1)\n```\n\n```\n1\n```\n\n"
        "<!-- not-run: needs the lab's data -->\n```python\nboom()\n```\n"
        "```text\nshown output of the skipped block: not compared\n```\n"
        "<!-- file: a.csv -->\n```text\nx\n```\n",
        encoding="utf-8",
    )
    blocks = parse(md)
    assert [b.lang for b in blocks] == ["python", "", "python", "text", "text"]
    assert blocks[0].output is blocks[1] and blocks[1].is_output
    assert blocks[2].marker == ("not-run", "needs the lab's data")
    # the block right after a python block is its output, whether or not that one runs
    assert blocks[2].output is blocks[3]
    assert blocks[4].marker == ("file", "a.csv") and not blocks[4].is_output


def test_output_check_uses_ellipsis_and_reports_a_diff():
    check_output("x", "took 0.83 s\nresult 1\n", "took ... s\nresult 1")
    with pytest.raises(AssertionError, match="shown in the docs"):
        check_output("x", "result 2\n", "result 1")


def test_console_and_shell_commands_are_parsed():
    block = Block("console", "$ softrod a \\\n   --b 1\nout 1\nout 2\n$ softrod c\n", 1)
    assert console_commands(block) == [("softrod a  --b 1", "out 1\nout 2"), ("softrod c", "")]
    bash = Block("bash", "pip install x\nsoftrod d --e \\\n  f\nsoftrod g\n", 1)
    assert shell_commands(bash) == ["softrod d --e  f", "softrod g"]


def test_every_doc_is_listed():
    assert ROOT / "README.md" in DOCS and len(DOCS) > 5
    assert all(p.exists() for p in DOCS)
    assert os.sep not in "".join(BUDGET_S)  # budgets are keyed by file name
