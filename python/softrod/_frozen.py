"""Read-only nested dicts and lists: a design's SI ``spec`` (softrod.Design.spec).

The spec is what the compiled core rod was built from; editing it in place would leave the
two telling different stories (Python readers of the spec would see the edit, the solver
would not). So it is handed out frozen: still a ``dict`` and ``list`` to read, compare,
iterate and ``json.dumps``, but every in-place change raises a TypeError that says to use
``Design.replace``. ``copy.deepcopy`` gives plain, editable dicts and lists.
"""

from __future__ import annotations

import copy
from typing import Any, NoReturn

_RULE = (
    "a design's spec is read-only (the compiled model was built from it): use "
    "Design.replace({...}) for a changed copy, or copy.deepcopy(design.spec) for an editable dict"
)


def _refuse(*_args: Any, **_kwargs: Any) -> NoReturn:
    raise TypeError(_RULE)


class FrozenDict(dict):
    """A dict that refuses every in-place change."""

    __slots__ = ()
    __setitem__ = __delitem__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse
    __ior__ = _refuse

    def __reduce__(self):
        # Pickle through the constructor (dict's C init does not call __setitem__).
        return (FrozenDict, (dict(self),))

    def __deepcopy__(self, memo: dict) -> dict:
        return {k: copy.deepcopy(v, memo) for k, v in self.items()}

    def __copy__(self) -> FrozenDict:
        return self


class FrozenList(list):
    """A list that refuses every in-place change."""

    __slots__ = ()
    __setitem__ = __delitem__ = _refuse
    append = extend = insert = pop = remove = clear = sort = reverse = _refuse
    __iadd__ = __imul__ = _refuse

    def __reduce__(self):
        return (FrozenList, (list(self),))

    def __deepcopy__(self, memo: dict) -> list:
        return [copy.deepcopy(v, memo) for v in self]

    def __copy__(self) -> FrozenList:
        return self


_PLAIN = frozenset({int, float, str, bool, type(None)})


def freeze(obj: Any) -> Any:
    """``obj`` with every nested dict and list frozen (tuples stay tuples, of frozen
    items)."""
    if isinstance(obj, FrozenDict | FrozenList):
        return obj
    if isinstance(obj, dict):
        return FrozenDict({k: freeze(v) for k, v in obj.items()})
    if isinstance(obj, list):
        # Lists of plain numbers (a mesh's thousands of vertex rows) in one go.
        if all(type(v) in _PLAIN for v in obj):
            return FrozenList(obj)
        return FrozenList([freeze(v) for v in obj])
    if isinstance(obj, tuple):
        return tuple(freeze(v) for v in obj)
    return obj


def thaw(obj: Any) -> Any:
    """A plain, editable deep copy of document data (dicts, lists, tuples of plain scalars,
    frozen or not): what ``copy.deepcopy`` gives, without its memo, so a document with an
    inline mesh (thousands of numbers) copies in milliseconds. Anything else is deep-copied."""
    t = type(obj)
    if t in _PLAIN:
        return obj
    if isinstance(obj, dict):
        return {k: thaw(v) for k, v in obj.items()}
    if isinstance(obj, list):
        if all(type(v) in _PLAIN for v in obj):
            return list(obj)
        return [thaw(v) for v in obj]
    if t is tuple:
        return tuple(thaw(v) for v in obj)
    return copy.deepcopy(obj)
