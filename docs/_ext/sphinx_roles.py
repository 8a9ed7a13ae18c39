"""Griffe extension for the API reference: Sphinx roles in softrod's docstrings as code spans.

The docstrings use Sphinx's inline roles (``:func:`load_design```,
``:class:`~softrod.StaticSolution```); mkdocstrings renders Markdown, where they would show
as raw text. Each role becomes a code span with the name as Sphinx would print it (``~``
keeps the last component).
"""

from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|attr|data|exc|obj|const):`(~?)([^`]+)`")


def _plain(match: re.Match) -> str:
    name = match[2].split(".")[-1] if match[1] else match[2]
    return f"`{name}`"


class SphinxRoles(griffe.Extension):
    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(_plain, obj.docstring.value)
