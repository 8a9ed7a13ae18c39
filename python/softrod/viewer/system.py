"""The interactive viewer of a system of rods holding one platform (a parallel continuum
robot, docs/model.md "Systems of rods"; docs/viewer.md "Systems of rods"): every rod's
tube, its mount and obstacles, and the platform, re-solved live (``solve_system``) as the
user moves each rod's pressure and tendon-tension sliders.

Every burst of slider moves is one ``solve_system`` call, warm-started from the
equilibrium on screen (with friction on some rod's obstacle: the load path continued from
it), and one redraw sent as one message batch (:class:`~softrod.viewer.served.Served`).
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import ConvergenceError, InputError, InvalidStateError, design_error
from ..statics import SolverOptions, _options, _pressures, _tensions
from ..system import System, SystemSolution, check_rods, load_system, solve_system
from . import geometry as geo
from .app import (
    CONTACT_COLOUR,
    OBSTACLE_COLOUR,
    Timing,
    _nice_ceiling,
    _positive,
    _range,
    default_pressure_max,
    default_tension_max,
    place_arrow,
)
from .served import Served, Tubes

#: Colour (RGB) of the platform.
PLATFORM_COLOUR = (235, 190, 60)


class SystemViewer(Served):
    """An interactive 3-D view of a :class:`~softrod.System` in the browser (start it with
    :func:`softrod.view_system`).

    Attributes for scripts and tests: :attr:`url`, :attr:`solution` (the
    :class:`~softrod.SystemSolution` on screen), :attr:`solves`, :attr:`timings`,
    :attr:`pressures` and :attr:`tensions` (the sliders' values per rod, SI).
    """

    def __init__(
        self,
        system,
        *,
        pressures=None,
        tensions=None,
        pressure_range=None,
        tension_max=None,
        options: SolverOptions | None = None,
        host: str = "127.0.0.1",
        port: int | None = None,
        environment_map: bool = True,
    ):
        self.system = system if isinstance(system, System) else load_system(system)
        sysm = self.system
        # Everything is checked here, as solve_system checks it, before the server starts.
        check_rods(sysm)
        self._options = None if options is None else _options(options)
        self.frictional = any(r.design.frictional_obstacle is not None for r in sysm.rods)
        designs = [r.design for r in sysm.rods]
        chambered = [d for d in designs if d.n_channels]
        tendoned = [d for d in designs if d.n_tendons]
        self.pressure_range = (
            (0.0, max((default_pressure_max(d) for d in chambered), default=100e3))
            if pressure_range is None
            else _range(pressure_range)
        )
        self.tension_max = (
            max((default_tension_max(d) for d in tendoned), default=10.0)
            if tension_max is None
            else _positive(tension_max, "tension_max")
        )
        p0 = self._per_rod(pressures, "pressures", _pressures, lambda d: [0.0] * d.n_channels)
        t0 = self._per_rod(tensions, "tensions", _tensions, lambda d: [0.0] * d.n_tendons)
        self._check_on_sliders(p0, t0)
        self.looks = [geo.section_looks(d) for d in designs]
        self.solution: SystemSolution | None = None
        self.solves = 0
        self.timings: list[Timing] = []
        self.error: str | None = None
        self._serve(host, port, environment_map)
        try:
            self._set_camera()
            self._build_scene()
            self._build_gui(p0, t0)
            self._request_solve()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ public API

    @property
    def name(self) -> str:
        return self.system.name

    @property
    def pressures(self) -> list[np.ndarray]:
        """Each rod's pressure sliders' values, Pa."""
        return [np.array([s.value * 1e3 for s in row]) for row in self._p_sliders]

    @property
    def tensions(self) -> list[np.ndarray]:
        """Each rod's tendon-tension sliders' values, N (0: slack)."""
        return [np.array([s.value for s in row]) for row in self._t_sliders]

    def set_inputs(self, pressures=None, tensions=None) -> SystemSolution | None:
        """Move the sliders from Python (one list per rod: Pa, N) and wait for the
        re-solve; returns the solution on screen."""
        p = None if pressures is None else self._per_rod(pressures, "pressures", _pressures)
        t = None if tensions is None else self._per_rod(tensions, "tensions", _tensions)
        self._check_on_sliders(p, t)
        self._quiet = True
        try:
            with self.server.atomic():
                for rows, values, scale in ((self._p_sliders, p, 1e3), (self._t_sliders, t, 1.0)):
                    if values is None:
                        continue
                    for sliders, row in zip(rows, values, strict=True):
                        for slider, x in zip(sliders, row, strict=True):
                            slider.value = x / scale
        finally:
            self._quiet = False
        self._request_solve()
        return self.solution

    def __repr__(self) -> str:
        return f"SystemViewer({self.system.name!r} at {self.url}, {self.solves} solves)"

    # ------------------------------------------------------------------ inputs

    def _per_rod(self, value, field: str, parse, default=None) -> list[list[float]]:
        """One list per rod, each checked as solve_system checks it (errors name the rod)."""
        rods = self.system.rods
        if value is None:
            return [default(r.design) for r in rods]
        if isinstance(value, np.ndarray):
            value = list(value)
        if not isinstance(value, (list, tuple)) or len(value) != len(rods):
            raise design_error(
                field, value, f"must be a list of {len(rods)} entries, one per rod", InputError
            )
        out = []
        for i, (rod, v) in enumerate(zip(rods, value, strict=True)):
            try:
                out.append(list(parse(rod.design, v)))
            except InputError as exc:
                raise design_error(
                    exc.field.replace(field, f"{field}[{i}]", 1), exc.value, exc.rule, InputError
                ) from None
        return out

    def _check_on_sliders(self, pressures, tensions) -> None:
        """Values within their sliders' ranges (None: not given), else an InputError naming
        the rod's entry and the range to widen."""
        lo, hi = self.pressure_range
        for rows, field, a, b, unit, widen in (
            (pressures, "pressures", lo, hi, "Pa", "pressure_range"),
            (tensions, "tensions", 0.0, self.tension_max, "N", "tension_max"),
        ):
            for i, row in enumerate([] if rows is None else rows):
                for k, x in enumerate(row):
                    if not a <= x <= b:
                        raise design_error(
                            f"{field}[{i}][{k}]",
                            float(x),
                            f"must be within its slider's range [{a:g}, {b:g}] {unit} (a "
                            f"slider cannot hold it): give a wider {widen}",
                            InputError,
                        )

    # ------------------------------------------------------------------ set-up

    def _size(self) -> float:
        """The scene's length scale: the rods' mean length."""
        return float(np.mean([r.design.length for r in self.system.rods]))

    def _set_camera(self) -> None:
        """Every new page starts looking at the middle between the bases and the platform,
        from the side and slightly from above, from far enough to see every rod."""
        bases = np.array([r.design.spec["mounting"]["base_position"] for r in self.system.rods])
        pf = np.asarray(self.system.platform.position, float)
        mid = 0.5 * (bases.mean(axis=0) + pf)
        reach = max(self._size(), float(np.ptp(np.vstack([bases, pf[None]]), axis=0).max()))
        cam = self.server.initial_camera
        cam.position = tuple(mid + reach * np.array([1.1, -1.5, 0.6]))
        cam.look_at = tuple(mid)
        cam.near = 1e-3 * reach

    def _build_scene(self) -> None:
        sc, L = self.server.scene, self._size()
        self._tubes = []
        drawn: list = []  # obstacles drawn once (rods of one system often share a table)
        self._contact_arrows: list[list] = []
        self._arrow_size = dict(shaft_radius=0.008 * L, head_radius=0.02 * L, head_length=0.04 * L)
        # Contact forces share one scale: the platform's weight (or 0.1 N) is 0.3 L.
        g = float(np.linalg.norm(self.system.rods[0].design.spec["mounting"]["gravity"]))
        self._force_scale = 0.3 * L / max(self.system.platform.mass * g, 0.1)
        for i, (rod, looks) in enumerate(zip(self.system.rods, self.looks, strict=True)):
            d = rod.design
            rmax = max(max(lk.radius, lk.radius_end or 0.0) for lk in looks)
            base = np.asarray(d.spec["mounting"]["base_position"], float)
            base_rot = np.asarray(d.spec["mounting"]["base_rotation"], float)
            sc.add_box(
                f"/mounts/{i}",
                dimensions=(3.0 * rmax, 3.0 * rmax, 0.15 * rmax),
                color=(200, 200, 200),
                position=base - base_rot[:, 2] * 0.075 * rmax,
                wxyz=geo.wxyz(base_rot),
            )
            self._tubes.append(Tubes(sc, looks, prefix=f"/rods/{i}"))
            mid = base + 0.5 * d.length * base_rot[:, 2]
            arrows = []
            for k, ob in enumerate(d.spec.get("obstacles", [])):
                if ob not in drawn:
                    drawn.append(ob)
                    for j, (solid, args) in enumerate(geo.obstacle_solids(ob, mid, d.length)):
                        name = f"/obstacles/{len(drawn) - 1}_{ob['kind']}/{j}"
                        look = dict(color=OBSTACLE_COLOUR, opacity=0.55, cast_shadow=False)
                        add = {
                            "box": sc.add_box,
                            "sphere": sc.add_icosphere,
                            "mesh": sc.add_mesh_simple,
                        }.get(solid, sc.add_cylinder)
                        add(name, receive_shadow=False, **look, **args)
                arrows.append(self._add_arrow(f"/loads/rod{i}_contact_{k}", CONTACT_COLOUR, False))
            self._contact_arrows.append(arrows)
        # The platform: a plate spanning its attachments, with its frame.
        att = np.array([np.asarray(r.attachment, float) for r in self.system.rods])
        span = float(np.ptp(att[:, :2], axis=0).max()) if len(att) > 1 else 0.0
        radius = max(lk.radius for looks in self.looks for lk in looks)
        width = span + 3.0 * radius
        self._platform = sc.add_box(
            "/platform/plate",
            dimensions=(width, width, 0.1 * radius + 0.02 * width),
            color=PLATFORM_COLOUR,
            opacity=0.8,
            cast_shadow=False,
            receive_shadow=False,
        )
        axes = 0.3 * width
        self._platform_frame = sc.add_frame(
            "/platform/frame", axes_length=axes, axes_radius=0.05 * axes, origin_radius=0.08 * axes
        )
        self._plate_centre = att.mean(axis=0)  # in the platform frame

    def _build_gui(self, p0, t0) -> None:
        gui, sysm = self.server.gui, self.system
        gui.add_markdown(
            f"**{sysm.name}**  \n{len(sysm.rods)} rods holding a "
            f"{sysm.platform.mass * 1e3:g} g platform"
        )
        lo, hi = self.pressure_range
        step = _nice_ceiling((hi - lo) / 1000.0)  # Pa
        self._p_sliders: list[list] = []
        self._t_sliders: list[list] = []
        for i, rod in enumerate(sysm.rods):
            d = rod.design
            ps, ts = [], []
            if d.n_channels:
                with gui.add_folder(f"rod {i} ({d.name}): pressures (kPa)"):
                    for k in range(d.n_channels):
                        s = gui.add_slider(
                            f"rod {i} channel {k}",
                            min=lo / 1e3,
                            max=hi / 1e3,
                            step=step / 1e3,
                            initial_value=float(p0[i][k]) / 1e3,
                        )
                        s.on_update(self._on_slider)
                        ps.append(s)
            if d.n_tendons:
                tm = self.tension_max
                with gui.add_folder(f"rod {i} ({d.name}): tendon tensions (N)"):
                    for k in range(d.n_tendons):
                        s = gui.add_slider(
                            f"rod {i} tendon {k}",
                            min=0.0,  # a tendon pulls or is slack
                            max=tm,
                            step=_nice_ceiling(tm / 1000.0),
                            initial_value=float(t0[i][k]),
                        )
                        s.on_update(self._on_slider)
                        ts.append(s)
            self._p_sliders.append(ps)
            self._t_sliders.append(ts)
        with gui.add_folder("Solver"):
            self._status = gui.add_markdown("starting...")
        shot = gui.add_button("Save screenshot (PNG)")
        shot.on_click(self._on_screenshot_button)
        self._shot_note = gui.add_markdown("")

    # ------------------------------------------------------------------ solve and draw

    def _solve_and_draw(self) -> None:
        if self._closed:
            return
        p = self.pressures
        t = self.tensions if any(r.design.n_tendons for r in self.system.rods) else None
        at, t0 = time.time(), time.perf_counter()
        shown = self.solution if self.solution is not None and self.solution.converged else None
        # The equilibrium on screen starts the solve: a warm start, or with friction the
        # load path continued from it (docs/contact.md, "Friction in the statics").
        start = {"history": shown} if self.frictional else {"initial": shown}
        try:
            sol = solve_system(
                self.system,
                [list(row) for row in p],
                tensions=None if t is None else [list(row) for row in t],
                options=self._options,
                on_unstable="ignore",  # the panel says whether it is stable
                **start,
            )
        except ConvergenceError as exc:
            sol = None
            what = "refused" if isinstance(exc, InvalidStateError) else "no convergence"
            self.error = f"{what} at these inputs: {exc} (the last converged shape stays drawn)"
        t1 = time.perf_counter()
        self.solves += 1
        if sol is not None:
            self.solution, self.error = sol, None
        with self.server.atomic():
            if sol is not None:
                for tubes, rod in zip(self._tubes, sol.rods, strict=True):
                    tubes.draw(rod.s, rod.position, rod.rotation, rod.section)
                rot = np.asarray(sol.platform_rotation)
                pos = np.asarray(sol.platform_position)
                q = tuple(geo.wxyz(rot))
                self._platform.position = tuple(pos + rot @ self._plate_centre)
                self._platform.wxyz = q
                self._platform_frame.position = tuple(pos)
                self._platform_frame.wxyz = q
                self._draw_contact(sol)
            self._status.content = self._status_text(sol, t1 - t0)
        self.server.flush()
        self.timings.append(Timing(t1 - t0, time.perf_counter() - t1, at))

    def _draw_contact(self, sol: SystemSolution) -> None:
        """Each rod's total contact force on each obstacle, drawn at the contact's centre."""
        for arrows, rod in zip(self._contact_arrows, sol.rods, strict=True):
            contact = rod.contact
            for k, handle in enumerate(arrows):
                total = None if contact is None else contact.total_force[k]
                on = None if contact is None else contact.obstacle == k
                if total is None or not np.linalg.norm(total) > 0 or not on.any():
                    handle.visible = False
                    continue
                at = contact.point[on].mean(axis=0)
                place_arrow(handle, at, total * self._force_scale)
                handle.visible = True

    def _status_text(self, sol: SystemSolution | None, solve_s: float) -> str:
        from ..system_plots import platform_tilt_deg

        lines = [f"solve {self.solves}: {solve_s * 1e3:.2f} ms"]
        if sol is None:
            return "  \n".join([*lines, "converged: **NO**", self.error or ""])
        pos = np.asarray(sol.platform_position) * 1e3
        lines += [
            "converged: **yes**",
            f"iterations: {sol.iterations} (load steps {sol.load_steps})",
            f"platform (mm): {pos[0]:.2f}, {pos[1]:.2f}, {pos[2]:.2f}",
            f"platform tilt: {float(platform_tilt_deg(sol.platform_rotation)):.2f} deg",
        ]
        if sol.stable is not None:
            lines.append(f"stable: **{'yes' if sol.stable else 'NO (unstable branch)'}**")
        for i, rod in enumerate(sol.rods):
            if rod.contact is not None:
                force = np.linalg.norm(rod.contact.total_force, axis=1).sum() * 1e3
                lines.append(f"rod {i} contact: {force:.1f} mN")
        return "  \n".join(lines)
