"""Interactive 3-D viewer in the browser (docs/viewer.md), built on viser.

``softrod.view(design)`` starts a local web server and returns a :class:`Viewer`; open its
``url`` (a notebook shows the page inline). viser is an optional dependency, imported only
when a viewer starts: ``pip install 'softrod[viewer]'``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from .._types import ArrayLike, DesignLike, Quantity
    from .app import Viewer
    from .system import SystemViewer

__all__ = ["SystemViewer", "Viewer", "view", "view_system"]


def view(
    design: DesignLike,
    *,
    pressures: ArrayLike | None = None,
    pressure_range: tuple[Quantity, Quantity] | None = None,
    tensions: ArrayLike | None = None,
    tension_max: Quantity | None = None,
    force_max: Quantity | None = None,
    trajectory: Any = None,
    calibration: Any = None,
    dataset: Any = None,
    stiffness_map: Any = None,
    options: Any = None,
    host: str = "127.0.0.1",
    port: int | None = None,
    environment_map: bool = True,
) -> Viewer:
    """Serve an interactive view of ``design`` in the browser and return the
    :class:`Viewer` (the server runs in background threads until ``viewer.close()``).

    design: a design (path, bundled name, preset or :class:`~softrod.Design`).
    pressures: initial gauge pressures (Pa, one per channel; default 0).
    pressure_range: (low, high) of the pressure sliders in Pa; default 0 to the pressure that
        bends the softest chambered section by about half a turn (docs/viewer.md).
    tensions: initial tendon tensions (N, one per tendon channel, >= 0; default 0: slack).
    tension_max: top of the tension sliders (N); default: the design's
        ``[operating_range] tension`` top, else the tension that bends the softest tendon
        section by about half a turn (docs/viewer.md).
    force_max: range (N, +-) of the tip-force sliders (in the design's tip frame: world, or
        the tip's frame for a follower load); default: the force that deflects the rod by
        about half its length.
    trajectory: a :class:`~softrod.Trajectory` (or its file) to play back with a time slider.
    calibration: a :class:`~softrod.CalibrationResult`: its measured and predicted tips are
        drawn; or dataset: a :class:`~softrod.Dataset` (or its file) whose measured tips are
        drawn against ``design``'s predictions.
    stiffness_map, options: as in :func:`softrod.solve_statics`.
    host, port: where to listen (default: this machine only, a free port).
    environment_map: viser's image-based lighting (turn off for software rendering, where
        the first frame takes seconds).
    """
    Viewer = _viewer_class(".app", "Viewer")  # noqa: N806 (a class)
    return Viewer(
        design,
        pressures=pressures,
        pressure_range=pressure_range,
        tensions=tensions,
        tension_max=tension_max,
        force_max=force_max,
        trajectory=trajectory,
        calibration=calibration,
        dataset=dataset,
        stiffness_map=stiffness_map,
        options=options,
        host=host,
        port=port,
        environment_map=environment_map,
    )


def _viewer_class(module: str, name: str):
    """The viewer class, or the InputError that names the missing extra."""
    import importlib

    try:
        return getattr(importlib.import_module(module, __name__), name)
    except ModuleNotFoundError as exc:  # pragma: no cover (viser missing)
        if exc.name and exc.name.split(".")[0] == "viser":
            from ..errors import InputError

            raise InputError(
                "softrod.view needs the viewer extra: pip install 'softrod[viewer]' (viser)",
                "viser",
                None,
                "not installed",
            ) from None
        raise


def view_system(
    system: Any,
    *,
    pressures: Any = None,
    tensions: Any = None,
    pressure_range: tuple[Quantity, Quantity] | None = None,
    tension_max: Quantity | None = None,
    options: Any = None,
    host: str = "127.0.0.1",
    port: int | None = None,
    environment_map: bool = True,
) -> SystemViewer:
    """Serve an interactive view of a system of rods holding one platform
    (:class:`~softrod.System`, a system file or a bundled system name) and return the
    :class:`SystemViewer` (docs/viewer.md, "Systems of rods").

    pressures, tensions: each rod's initial inputs, one list per rod (Pa, N; default 0).
    pressure_range: (low, high) of every pressure slider in Pa (default: 0 to the largest of
        the rods' defaults, as :func:`view` chooses them). tension_max: top of the tension
        sliders (N). options: as in :func:`softrod.solve_system`. host, port,
        environment_map: as in :func:`view`.
    """
    cls = _viewer_class(".system", "SystemViewer")
    return cls(
        system,
        pressures=pressures,
        tensions=tensions,
        pressure_range=pressure_range,
        tension_max=tension_max,
        options=options,
        host=host,
        port=port,
        environment_map=environment_map,
    )


def __getattr__(name):
    if name == "Viewer":
        return _viewer_class(".app", "Viewer")
    if name == "SystemViewer":
        return _viewer_class(".system", "SystemViewer")
    raise AttributeError(name)
