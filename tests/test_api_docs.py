"""The API reference (docs/api.md, built with mkdocs + mkdocstrings) covers the public API."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest
import softrod

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api.md"


def public_names() -> list[str]:
    return [n for n in softrod.__all__ if not n.startswith("_")]


def test_every_public_name_has_an_entry():
    documented = set(re.findall(r"^::: softrod\.(\w+)", API.read_text(encoding="utf-8"), re.M))
    missing = [n for n in public_names() if n not in documented]
    assert not missing, f"add '::: softrod.NAME' entries to docs/api.md for {missing}"
    unknown = sorted(documented - set(public_names()))
    assert not unknown, f"docs/api.md documents names that softrod.__all__ lacks: {unknown}"


def test_every_public_object_has_a_docstring():
    bare = [n for n in public_names() if not (getattr(softrod, n).__doc__ or "").strip()]
    assert not bare, f"public objects without a docstring: {bare}"


@pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None
    or importlib.util.find_spec("mkdocstrings_handlers") is None,
    reason="the docs extra is not installed (pip install -e '.[docs]'): the site is not built",
)
def test_site_builds_strictly_and_shows_every_public_name(tmp_path):
    site = tmp_path / "site"
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    # --strict turns every warning (a broken link or anchor, a page missing from the nav, an
    # object mkdocstrings cannot find or render) into a failure.
    assert proc.returncode == 0, proc.stdout + proc.stderr
    page = (site / "api" / "index.html").read_text(encoding="utf-8")
    for name in public_names():
        assert f'id="softrod.{name}"' in page, name
    assert ":func:" not in page and ":class:" not in page  # Sphinx roles became code spans
    # The linearisations' first-order form and poles live on their shared base class.
    for cls in ("LinearSystem", "SystemLinearSystem"):
        for method in ("state_space", "poles", "modes"):
            assert f'id="softrod.{cls}.{method}"' in page, (cls, method)
