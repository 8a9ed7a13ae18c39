"""Typing: the package ships py.typed and a stub of its compiled module that matches the
module, and every function and method of the public API (softrod.__all__) is annotated."""

from __future__ import annotations

import importlib.util
import inspect
import subprocess
import sys
from pathlib import Path

import pytest
import softrod

PACKAGE = Path(softrod.__file__).parent


def test_package_is_marked_typed_and_ships_the_core_stub():
    assert (PACKAGE / "py.typed").is_file()
    assert (PACKAGE / "_core.pyi").is_file()


def _public_callables():
    """(qualified name, function) of every public function and method of softrod.__all__."""
    for name in softrod.__all__:
        obj = getattr(softrod, name)
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj) and not issubclass(obj, (BaseException, Warning)):
            for attr, value in vars(obj).items():
                if attr.startswith("_") and attr not in ("__init__", "__call__"):
                    continue
                if isinstance(value, (staticmethod, classmethod)):
                    value = value.__func__
                elif isinstance(value, property):
                    value = value.fget
                if inspect.isfunction(value):
                    yield f"{name}.{attr}", value


def test_public_api_is_annotated():
    bare = {}
    for qualname, fn in _public_callables():
        sig = inspect.signature(fn)
        missing = [
            p.name
            for p in sig.parameters.values()
            if p.name not in ("self", "cls") and p.annotation is inspect.Parameter.empty
        ]
        if fn.__name__ != "__init__" and sig.return_annotation is inspect.Signature.empty:
            missing.append("return")
        if missing:
            bare[qualname] = missing
    assert not bare, "annotate these parameters (and returns) of the public API: " + "; ".join(
        f"{k}: {', '.join(v)}" for k, v in bare.items()
    )


@pytest.mark.skipif(
    importlib.util.find_spec("mypy") is None,
    reason="mypy is not installed (pip install -e '.[docs]'): the stub is not checked",
)
def test_core_stub_matches_the_compiled_module(tmp_path):
    # stubtest imports softrod._core and compares every name, signature, default and property
    # of the stub with it. The stub names no numpy types, which keeps this to seconds.
    proc = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "softrod._core"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
