"""The interactive viewer: a viser server that draws a design's static shape and re-solves it
live as the user moves the pressure, tendon-tension and tip-force sliders (docs/viewer.md).

Every slider move is one ``solve_statics`` call (the Rust shooting solve, warm-started from
the shape on screen) and one redraw: the tube of every section, the tip frame, the load
arrows, the contact forces on the design's obstacles, the chamber cross-section and the
solver's state, sent to the browser as one message batch. Moves that arrive while a solve
runs are merged: the next solve takes the sliders' latest values, so a fast drag never
queues stale work.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from .. import _validate as V
from ..catalog import load_design
from ..design import Design
from ..errors import ConvergenceError, InputError, InvalidStateError, design_error
from ..solution import StaticSolution
from ..statics import (
    SolverOptions,
    _options,
    _pressures,
    _stiffness_map,
    _tensions,
    _vec3,
    solve_statics,
)
from . import geometry as geo
from .served import Served, Tubes

#: Colours (RGB) of the arrows and markers.
GRAVITY_COLOUR = (60, 110, 220)
FORCE_COLOUR = (220, 40, 40)
WEIGHT_COLOUR = (150, 60, 200)
MEASURED_COLOUR = (30, 160, 60)
PREDICTED_COLOUR = (230, 120, 20)
OBSTACLE_COLOUR = (170, 170, 160)
CONTACT_COLOUR = (20, 170, 170)


def place_arrow(handle, at, vector) -> None:
    """Draw an arrow of ``vector`` from ``at`` by posing the two bones of its skinned mesh
    (geometry.arrow_mesh): the start's and the end's, both turned from z to the vector. A
    node's or bone's pose reaches the screen in the animation frame that receives it, new
    vertex arrays or arrow points one frame later (docs/viewer.md, "Responsiveness"), so an
    arrow follows the rod, and changes its length, as fast as the tube."""
    v = np.asarray(vector, dtype=float)
    q = geo.wxyz(geo.frame_along(v)) if np.linalg.norm(v) > 0 else np.array([1.0, 0, 0, 0])
    start, (b0, b1) = np.asarray(at, dtype=float), handle.bones
    b0.wxyz, b1.wxyz = q, q
    b0.position, b1.position = start, start + v


@dataclass(frozen=True)
class Timing:
    """One re-solve and redraw, measured on the server (s): the solve in Rust, building and
    queueing the scene update, and the two together; ``at`` is when it started (time.time(),
    to line it up with the browser's clock in latency measurements)."""

    solve_s: float
    draw_s: float
    at: float = 0.0

    @property
    def total_s(self) -> float:
        return self.solve_s + self.draw_s


def _nice_ceiling(x: float) -> float:
    """The smallest of 1, 1.5, 2, 3, 5, 7 times a power of ten that is >= x."""
    if not (math.isfinite(x) and x > 0):
        return 1.0
    e = 10.0 ** math.floor(math.log10(x))
    return next(m * e for m in (1.0, 1.5, 2.0, 3.0, 5.0, 7.0, 10.0) if m * e >= x * (1 - 1e-12))


def default_pressure_max(design: Design) -> float:
    """Default top of the pressure sliders (Pa): the design's ``[operating_range] pressure``
    top when it has one (solves beyond it are refused), else the pressure at which one
    channel's chambers alone bend the softest chambered section by about half a turn,
    p = pi EI / (A d L) (the pressure moment p A d over the bending stiffness EI gives the
    curvature; a bend angle of pi over the section length L), rounded up to a round number
    (1, 1.5, 2, 3, 5 or 7 times a power of ten)."""
    rng = design.spec.get("operating_range", {}).get("pressure")
    if rng is not None and rng[1] > 0:
        return float(rng[1])
    best = math.inf
    for sec, spec in zip(design.sections(), design.spec["sections"], strict=True):
        if spec["rigid"] or not spec["chambers"]:
            continue
        ei = min(float(sec["k_bt"][0][0]), float(sec["k_bt"][1][1]))
        per_channel: dict[int, float] = {}
        for ch in spec["chambers"]:
            per_channel[ch["channel"]] = per_channel.get(ch["channel"], 0.0) + (
                ch["area"] * ch["distance"]
            )
        ad = max(per_channel.values())
        if ad > 0:
            best = min(best, math.pi * ei / (ad * spec["length"]))
    return _nice_ceiling(best) if math.isfinite(best) else 100e3


def default_tension_max(design: Design) -> float:
    """Default top of the tension sliders (N): the design's ``[operating_range] tension``
    top when it has one, else the tension at which one tendon alone bends the softest
    tendon-carrying section by about half a turn, T = pi EI / (d L) (the tendon's moment T d
    over EI gives the curvature, as the chambers' p A d does), rounded up like the
    pressure range."""
    rng = design.spec.get("operating_range", {}).get("tension")
    if rng is not None:
        return float(rng[1])
    best = math.inf
    for sec, spec in zip(design.sections(), design.spec["sections"], strict=True):
        if spec["rigid"] or not spec.get("tendons"):
            continue
        ei = min(float(sec["k_bt"][0][0]), float(sec["k_bt"][1][1]))
        d = max(max(t["distance"], t.get("distance_end", 0.0)) for t in spec["tendons"])
        if d > 0:
            best = min(best, math.pi * ei / (d * spec["length"]))
    return _nice_ceiling(best) if math.isfinite(best) else 10.0


def default_force_max(design: Design) -> float:
    """Default range of the tip-force sliders (N, +-): the tip force that deflects the rod,
    taken as a uniform cantilever with the smallest bending stiffness of its elastic sections,
    by half its length (F L^3 / (3 EI) = L / 2), rounded up like the pressure range."""
    eis = [
        min(float(sec["k_bt"][0][0]), float(sec["k_bt"][1][1]))
        for sec, spec in zip(design.sections(), design.spec["sections"], strict=True)
        if not spec["rigid"]
    ]
    if not eis:
        return 1.0
    return _nice_ceiling(1.5 * min(eis) / design.length**2)


class Viewer(Served):
    """An interactive 3-D view of ``design`` in the browser (start it with :func:`view`).

    Attributes for scripts and tests: :attr:`url`, :attr:`solution` (the shape on screen),
    :attr:`solves` (re-solves so far), :attr:`timings` (one :class:`Timing` per re-solve),
    :attr:`pressures`, :attr:`tensions` and :attr:`tip_force` (the sliders' values, SI).
    """

    def __init__(
        self,
        design,
        *,
        pressures=None,
        pressure_range=None,
        force_max=None,
        tensions=None,
        tension_max=None,
        trajectory=None,
        calibration=None,
        dataset=None,
        stiffness_map=None,
        options: SolverOptions | None = None,
        host: str = "127.0.0.1",
        port: int | None = None,
        environment_map: bool = True,
    ):
        self.design = load_design(design)
        d = self.design
        # Every value is checked here, as solve_statics checks it, before the server starts:
        # a bad one is named at once, never at the first solve with a server left running.
        self._options = None if options is None else _options(options)
        #: An obstacle with friction: every solve continues the load path from the shape shown.
        self.frictional = d.frictional_obstacle is not None
        _stiffness_map(d, stiffness_map)
        self._stiffness_map = stiffness_map
        self.looks = geo.section_looks(d)
        nc = d.n_channels
        if pressure_range is None:
            self.pressure_range = (0.0, default_pressure_max(d))
        else:
            self.pressure_range = _range(pressure_range)
        self.force_max = default_force_max(d) if force_max is None else _positive(force_max)
        p0 = np.zeros(nc) if pressures is None else np.array(_pressures(d, pressures))
        nt = d.n_tendons
        self.tension_max = (
            default_tension_max(d) if tension_max is None else _positive(tension_max, "tension_max")
        )
        t0 = np.zeros(nt) if tensions is None else np.array(_tensions(d, tensions))
        # A slider cannot show a value beyond its ends (viser would clip it silently).
        self._check_on_sliders(p0, t0, None)
        f0 = np.asarray(d.spec["tip"]["force"], float)
        if not np.all(np.abs(f0) <= self.force_max):
            raise design_error(
                "force_max",
                self.force_max,
                f"the design's [tip] force {f0.tolist()} N is beyond the tip-force sliders' "
                "range +-force_max: give a larger force_max",
                InputError,
            )
        self.trajectory = _trajectory(d, trajectory)
        shown = _measured_predicted(d, calibration, dataset)
        self.calibration = None if shown is None else shown[:3]
        self._sample_tensions = None if shown is None else shown[3]

        self.solution: StaticSolution | None = None
        self.solves = 0
        self.timings: list[Timing] = []
        self.error: str | None = None
        self._playing = threading.Event()
        self._serve(host, port, environment_map)
        try:
            self._set_camera()
            self._build_scene()
            self._build_gui(p0, t0)
            self._request_solve()
        except BaseException:
            # An error while the scene is built or in the first solve (a refused or
            # unconverged one is shown on the panel, not raised) leaves no server running.
            self.close()
            raise

    # ------------------------------------------------------------------ public API

    @property
    def pressures(self) -> np.ndarray:
        """The pressure sliders' values, Pa (one per channel)."""
        return np.array([s.value * 1e3 for s in self._p_sliders])

    @property
    def tensions(self) -> np.ndarray:
        """The tendon-tension sliders' values, N (one per tendon channel; 0: slack)."""
        return np.array([s.value for s in self._t_sliders])

    @property
    def tip_force(self) -> np.ndarray:
        """The tip-force sliders' values, N (in the design's tip frame: world, or the tip's
        body frame for a follower load)."""
        return np.array([s.value for s in self._f_sliders])

    def set_inputs(self, pressures=None, tip_force=None, tensions=None) -> StaticSolution | None:
        """Move the sliders from Python (Pa, N, N) and wait for the re-solve; returns the
        solution on screen."""
        # Checked as solve_statics checks them (units, counts, finite, tensions >= 0), all
        # before any slider moves.
        d = self.design
        p = None if pressures is None else _pressures(d, pressures)
        t = None if tensions is None else _tensions(d, tensions)
        f = None if tip_force is None else _vec3(tip_force, "force", "tip_force", None)
        self._check_on_sliders(p, t, f)
        self._quiet = True
        try:
            with self.server.atomic():
                for sliders, values, scale in (
                    (self._p_sliders, p, 1e3),
                    (self._t_sliders, t, 1.0),
                    (self._f_sliders, f, 1.0),
                ):
                    if values is not None:
                        for slider, x in zip(sliders, values, strict=True):
                            slider.value = x / scale
        finally:
            self._quiet = False
        self._request_solve()
        return self.solution

    def _check_on_sliders(self, pressures, tensions, tip_force) -> None:
        """Values within their sliders' ranges (None: not given), else an InputError naming
        the entry and the range to widen."""
        lo, hi = self.pressure_range
        for values, field, a, b, unit, widen in (
            (pressures, "pressures", lo, hi, "Pa", "pressure_range"),
            (tensions, "tensions", 0.0, self.tension_max, "N", "tension_max"),
            (tip_force, "tip_force", -self.force_max, self.force_max, "N", "force_max"),
        ):
            for k, x in enumerate([] if values is None else values):
                if not a <= x <= b:
                    raise design_error(
                        f"{field}[{k}]",
                        float(x),
                        f"must be within its slider's range [{a:g}, {b:g}] {unit} (a slider "
                        f"cannot hold it): give a wider {widen}",
                        InputError,
                    )

    @property
    def name(self) -> str:
        return self.design.name

    def _on_close(self) -> None:
        self._playing.clear()

    def __repr__(self) -> str:
        return f"Viewer({self.design.name!r} at {self.url}, {self.solves} solves)"

    # ------------------------------------------------------------------ set-up

    def _build_scene(self) -> None:
        d, sc = self.design, self.server.scene
        L = d.length
        rmax = max(max(lk.radius, lk.radius_end or 0.0) for lk in self.looks)
        self._scale = L
        base = np.asarray(d.spec["mounting"]["base_position"], float)
        base_rot = np.asarray(d.spec["mounting"]["base_rotation"], float)
        # The mount: a plate across the base, in the base's cross-section plane.
        sc.add_box(
            "/mount",
            dimensions=(3.0 * rmax, 3.0 * rmax, 0.15 * rmax),
            color=(200, 200, 200),
            position=base - base_rot[:, 2] * 0.075 * rmax,
            wxyz=geo.wxyz(base_rot),
        )
        # One skinned tube per section, made at its first draw (its bones: the section's
        # nodes; see Tubes.draw).
        self._tubes = Tubes(sc, self.looks)
        # Axes that reach out of the tube (the frame sits on the centreline).
        axes = max(0.15 * L, 1.8 * self.looks[-1].radius)
        self._tip_frame = sc.add_frame(
            "/tip_frame", axes_length=axes, axes_radius=0.06 * axes, origin_radius=0.1 * axes
        )
        g = float(np.linalg.norm(d.spec["mounting"]["gravity"]))
        side = base + np.array([2.0 * rmax, 0.0, 0.0])
        self._gravity = sc.add_arrows(
            "/loads/gravity",
            points=geo.arrow(side, [0.0, 0.0, -0.25 * L]),
            colors=GRAVITY_COLOUR,
            shaft_radius=0.01 * L,
            head_radius=0.025 * L,
            head_length=0.05 * L,
            visible=g > 0,
        )
        sc.add_label("/loads/gravity/label", f"g {g:.2f} m/s²", position=side, visible=g > 0)
        # Forces share one scale: the slider range (or the largest constant load) is 0.3 L.
        tip = d.spec["tip"]
        self._weight_n = tip["mass"] * g
        line_loads = [
            np.asarray(ld["force_per_length"]) * d.spec["sections"][ld["section"]]["length"]
            for ld in d.spec["loads"]
        ]
        f_ref = max(
            [self.force_max, self._weight_n] + [float(np.linalg.norm(f)) for f in line_loads]
        )
        self._force_scale = 0.3 * L / f_ref
        self._arrow_size = dict(shaft_radius=0.008 * L, head_radius=0.02 * L, head_length=0.04 * L)
        self._force_arrow = self._add_arrow("/loads/tip_force", FORCE_COLOUR)
        self._weight_arrow = self._add_arrow(
            "/loads/tip_weight", WEIGHT_COLOUR, visible=self._weight_n > 0
        )
        self._line_loads = []
        for k, (ld, f) in enumerate(zip(d.spec["loads"], line_loads, strict=True)):
            lk = self.looks[ld["section"]]
            self._line_loads.append(
                (
                    0.5 * (lk.s0 + lk.s1),
                    f,
                    self._add_arrow(f"/loads/line_{k}", WEIGHT_COLOUR),
                )
            )
        # The obstacles (docs/contact.md), translucent so the rod shows through where it
        # presses in, and one arrow per obstacle for the contact force on the rod.
        mid = base + 0.5 * L * base_rot[:, 2]
        self._contact_arrows = []
        for k, ob in enumerate(d.spec.get("obstacles", [])):
            for j, (solid, args) in enumerate(geo.obstacle_solids(ob, mid, L)):
                name = f"/obstacles/{k}_{ob['kind']}/{j}"
                look = dict(color=OBSTACLE_COLOUR, opacity=0.55, cast_shadow=False)
                if solid == "box":
                    sc.add_box(name, receive_shadow=False, **look, **args)
                elif solid == "sphere":
                    sc.add_icosphere(name, receive_shadow=False, **look, **args)
                elif solid == "mesh":
                    sc.add_mesh_simple(name, receive_shadow=False, side="double", **look, **args)
                else:
                    sc.add_cylinder(name, receive_shadow=False, **look, **args)
            self._contact_arrows.append(
                self._add_arrow(f"/loads/contact_{k}", CONTACT_COLOUR, visible=False)
            )
        if self.calibration is not None:
            measured, predicted, _ = self.calibration
            ok = np.isfinite(predicted).all(axis=1)
            pt = 0.012 * L
            sc.add_point_cloud(
                "/calibration/measured",
                points=measured.astype(np.float32),
                colors=MEASURED_COLOUR,
                point_size=pt,
                point_shape="circle",
            )
            sc.add_point_cloud(
                "/calibration/predicted",
                points=predicted[ok].astype(np.float32),
                colors=PREDICTED_COLOUR,
                point_size=pt,
                point_shape="circle",
            )
            sc.add_line_segments(
                "/calibration/errors",
                points=np.stack([measured[ok], predicted[ok]], axis=1).astype(np.float32),
                colors=(120, 120, 120),
            )
            self._sample_marker = sc.add_icosphere(
                "/calibration/sample", radius=0.02 * L, color=MEASURED_COLOUR, visible=False
            )

    def _build_gui(self, p0: np.ndarray, t0: np.ndarray) -> None:
        gui, d = self.server.gui, self.design
        inputs = [f"{d.n_channels} channel(s)"] if d.n_channels else []
        inputs += [f"{d.n_tendons} tendon(s)"] if d.n_tendons else []
        gui.add_markdown(f"**{d.name}**  \n{d.length * 1e3:.0f} mm, {', '.join(inputs)}")
        lo, hi = self.pressure_range
        step = _nice_ceiling((hi - lo) / 1000.0) / 1e3
        self._p_sliders = []
        # A design without chambers (tendons only) gets no empty pressure folder.
        folder = gui.add_folder("Pressures (kPa)") if d.n_channels else contextlib.nullcontext()
        with folder:
            for k in range(d.n_channels):
                s = gui.add_slider(
                    f"channel {k}",
                    min=lo / 1e3,
                    max=hi / 1e3,
                    step=step,
                    initial_value=float(np.clip(p0[k], lo, hi)) / 1e3,
                )
                s.on_update(self._on_slider)
                self._p_sliders.append(s)
        self._t_sliders = []
        if d.n_tendons:
            tm = self.tension_max
            with gui.add_folder("Tendon tensions (N)"):
                for k in range(d.n_tendons):
                    s = gui.add_slider(
                        f"tendon {k}",
                        min=0.0,  # a tendon pulls or is slack (docs/scope.md)
                        max=tm,
                        step=_nice_ceiling(tm / 1000.0),
                        initial_value=float(np.clip(t0[k], 0.0, tm)),
                    )
                    s.on_update(self._on_slider)
                    self._t_sliders.append(s)
        self._f_sliders = []
        f0 = np.asarray(d.spec["tip"]["force"], float)
        fm = self.force_max
        frame = "tip frame" if d.spec["tip"].get("frame") == "body" else "world"
        with gui.add_folder(f"Tip force (N, {frame})", expand_by_default=False):
            for k, axis in enumerate("xyz"):
                s = gui.add_slider(
                    f"F{axis}",
                    min=-fm,
                    max=fm,
                    step=fm / 500.0,
                    initial_value=float(np.clip(f0[k], -fm, fm)),
                )
                s.on_update(self._on_slider)
                self._f_sliders.append(s)
        with gui.add_folder("Solver"):
            self._status = gui.add_markdown("starting...")
        chambered = [
            (k, sec)
            for k, sec in enumerate(d.spec["sections"])
            if sec["chambers"] or sec.get("tendons")
        ]
        self._sections_html = []
        if chambered:
            with gui.add_folder("Cross-section (from the tip)"):
                for k, sec in chambered:
                    self._sections_html.append(
                        (sec, self.looks[k].radius, gui.add_html(""), sec["name"])
                    )
        with gui.add_folder("Sections", expand_by_default=False):
            rows = ["| section | kind | outer radius |", "|---|---|---|"]
            for lk in self.looks:
                note = "" if lk.radius_from_design else " (drawn; not in the design)"
                r = f"{lk.radius * 1e3:.1f}"
                if lk.radius_end is not None:
                    r += f" to {lk.radius_end * 1e3:.1f}"
                rows.append(f"| {lk.name} | {lk.kind} | {r} mm{note} |")
            self._sections_note = gui.add_markdown("\n".join(rows))
        if self.trajectory is not None:
            self._build_trajectory_gui()
        if self.calibration is not None:
            self._build_calibration_gui()
        shot = gui.add_button("Save screenshot (PNG)")
        shot.on_click(self._on_screenshot_button)
        self._shot_note = gui.add_markdown("")

    def _build_trajectory_gui(self) -> None:
        gui, tr = self.server.gui, self.trajectory
        with gui.add_folder("Trajectory"):
            self._t_slider = gui.add_slider(
                "sample", min=0, max=len(tr) - 1, step=1, initial_value=0
            )
            self._t_note = gui.add_markdown("")
            self._play = gui.add_checkbox("play", initial_value=False)
            self._speed = gui.add_slider("speed", min=0.1, max=4.0, step=0.1, initial_value=1.0)
        self._t_slider.on_update(lambda _e: self._show_trajectory(int(self._t_slider.value)))
        self._play.on_update(lambda _e: self._toggle_play())

    def _build_calibration_gui(self) -> None:
        gui = self.server.gui
        measured, predicted, _ = self.calibration
        err = np.linalg.norm(predicted - measured, axis=1) * 1e3
        ok = np.isfinite(err)
        with gui.add_folder("Calibration"):
            gui.add_markdown(
                f"{len(measured)} samples: measured (green) vs predicted (orange)  \n"
                f"tip error mean {np.mean(err[ok]):.2f} mm, max {np.max(err[ok]):.2f} mm"
                if ok.any()
                else f"{len(measured)} samples; no prediction converged"
            )
            self._sample = gui.add_slider(
                "sample", min=0, max=len(measured) - 1, step=1, initial_value=0
            )
            go = gui.add_button("Solve at this sample's pressures")
        go.on_click(lambda _e: self._show_sample(int(self._sample.value)))

    def _set_camera(self) -> None:
        """Every new page starts looking at the rod's middle from the side, slightly from
        above, from far enough to see it whole."""
        d = self.design
        base = np.asarray(d.spec["mounting"]["base_position"], float)
        axis = np.asarray(d.spec["mounting"]["base_rotation"], float)[:, 2]
        mid = base + 0.5 * d.length * axis
        cam = self.server.initial_camera
        cam.position = tuple(mid + d.length * np.array([1.1, -1.5, 0.6]))  # first: it moves look_at
        cam.look_at = tuple(mid)
        cam.near = 1e-3 * d.length

    # ------------------------------------------------------------------ solve and draw

    def _solve_and_draw(self) -> None:
        if self._closed:
            return
        p, f = self.pressures, self.tip_force
        tensions = self.tensions if self.design.n_tendons else None
        at = time.time()
        t0 = time.perf_counter()
        shown = self.solution if self.solution is not None and self.solution.converged else None
        # The shape on screen starts the solve: a warm start, or with friction (docs/contact.md,
        # "Friction in the statics") the load path continued from it, so a slider move loads
        # or unloads the rod from where it stands, with what its contacts hold.
        start = {"history" if self.frictional else "initial": shown}
        try:
            sol = solve_statics(
                self.design,
                p,
                tensions=tensions,
                tip_force=f,
                options=self._options,
                stiffness_map=self._stiffness_map,
                **start,
            )
        except ConvergenceError as exc:
            # Not converged, or refused by a validity rule (InvalidStateError: beyond the
            # operating range, ...): the panel says which and why; the last converged shape
            # stays drawn.
            sol = None
            what = "refused" if isinstance(exc, InvalidStateError) else "no convergence"
            reason = f"{what} at these inputs: {exc}"
        t1 = time.perf_counter()
        self.solves += 1
        if sol is not None:
            self.solution = sol
            self.error = None
        else:
            self.error = f"{reason} (the last converged shape stays drawn)"
        with self.server.atomic():
            if sol is not None:
                self._tubes.draw(sol.s, sol.position, sol.rotation, sol.section)
                self._draw_tip(sol.position[-1], sol.rotation[-1], f)
                self._draw_line_loads(sol.s, sol.position)
                self._draw_contact(sol)
            self._draw_sections(p, tensions)
            self._status.content = self._status_text(sol, t1 - t0)
        self.server.flush()  # send now, not at the end of viser's 1/60 s batching window
        self.timings.append(Timing(t1 - t0, time.perf_counter() - t1, at))

    def _draw_tip(self, tip, rot, force) -> None:
        self._tip_frame.position = tuple(tip)
        self._tip_frame.wxyz = tuple(geo.wxyz(rot))
        fvec = np.asarray(force, float) * self._force_scale
        place_arrow(self._force_arrow, tip, fvec)
        self._force_arrow.visible = bool(np.linalg.norm(force) > 0)
        if self._weight_n > 0:
            place_arrow(self._weight_arrow, tip, [0.0, 0.0, -self._weight_n * self._force_scale])

    def _draw_line_loads(self, s, position) -> None:
        for s_mid, f, handle in self._line_loads:
            at = np.array([np.interp(s_mid, s, position[:, i]) for i in range(3)])
            place_arrow(handle, at, f * self._force_scale)

    def _draw_contact(self, sol: StaticSolution) -> None:
        """Each obstacle's total contact force on the rod, drawn from the contact's centre
        on the obstacle's surface: the contact points weighted by the force they carry (line
        force times the node's share of the length, and the rounded end's point force)."""
        contact = sol.contact
        if contact is None:
            return
        share = np.gradient(sol.s)  # m of rod per node
        for k, handle in enumerate(self._contact_arrows):
            total = contact.total_force[k]
            on = contact.obstacle == k
            w = np.where(on, np.linalg.norm(contact.force, axis=1) * share, 0.0)
            w_end = float(np.linalg.norm(contact.end_force[k]))
            if not np.linalg.norm(total) > 0 or w.sum() + w_end <= 0:
                handle.visible = False
                continue
            # The rounded end presses at its node's surface point on this obstacle.
            end = contact.point[-1] if contact.obstacle[-1] == k else sol.position[-1]
            at = (w @ contact.point + w_end * end) / (w.sum() + w_end)
            place_arrow(handle, at, total * self._force_scale)
            handle.visible = True

    def _draw_sections(self, pressures, tensions=None) -> None:
        hi = self.pressure_range[1]
        for sec, radius, handle, _name in self._sections_html:
            handle.content = geo.cross_section_svg(
                sec, pressures, hi, radius, tensions=tensions, t_max=self.tension_max
            )

    def _status_text(self, sol: StaticSolution | None, solve_s: float) -> str:
        lines = [f"solve {self.solves}: {solve_s * 1e3:.2f} ms"]
        if sol is not None:
            tip = sol.tip_position * 1e3
            lines += [
                "converged: **yes**",
                f"iterations: {sol.iterations} (load steps {sol.load_steps})",
                f"residual: {sol.residual:.1e}",
                f"tip (mm): {tip[0]:.2f}, {tip[1]:.2f}, {tip[2]:.2f}",
            ]
            stable = getattr(sol, "stable", None)
            if stable is not None:
                lines.append(f"stable: **{'yes' if stable else 'NO (unstable branch)'}**")
            if sol.tip_constraint != "free":
                r = sol.tip_reaction_force * 1e3
                lines.append(
                    f"tip {sol.tip_constraint}: reaction (mN) {r[0]:.1f}, {r[1]:.1f}, {r[2]:.1f}"
                )
            if sol.contact is not None:
                for k, force in enumerate(sol.contact.total_force):
                    kind = self.design.spec["obstacles"][k]["kind"]
                    lines.append(f"contact with {kind} {k}: {np.linalg.norm(force) * 1e3:.1f} mN")
                depth = max(sol.contact.max_penetration, 0.0) * 1e3
                lines.append(f"deepest penetration: {depth:.3f} mm")
                if self.frictional:
                    ft = np.linalg.norm(sol.contact.friction_force, axis=1).max() * 1e3
                    lines.append(f"friction: {ft:.1f} mN (loaded from the shape shown)")
        else:
            lines += ["converged: **NO**", self.error or ""]
        return "  \n".join(lines)

    # ------------------------------------------------------------------ playback, samples

    def _show_trajectory(self, i: int) -> None:
        tr, d = self.trajectory, self.design
        i = int(np.clip(i, 0, len(tr) - 1))
        t = tr.time[i]
        note = f"t = {t:.3f} s of {tr.time[-1]:.3f} s; pressures (kPa): " + ", ".join(
            f"{p / 1e3:.1f}" for p in tr.pressure[i]
        )
        with self.server.atomic():
            if tr.shape_time is not None and tr.shape_time.size:
                j = int(np.searchsorted(tr.shape_time, t, side="right")) - 1
                j = max(j, 0)
                pos = tr.shape_position[j]
                rot = geo.transport_frames(pos, np.asarray(d.spec["mounting"]["base_rotation"]))
                sec = geo.section_of_arclength(self.looks, tr.shape_s)
                self._tubes.draw(tr.shape_s, pos, rot, sec)
                note += f"  \nshape at t = {tr.shape_time[j]:.3f} s"
            else:
                note += "  \n(the trajectory stores no shapes: tip only)"
            self._draw_tip(tr.tip_position[i], tr.tip_rotation[i], np.zeros(3))
            self._draw_sections(tr.pressure[i], tr.tension[i] if tr.n_tendons else None)
            self._t_note.content = note

    def _toggle_play(self) -> None:
        if self._play.value and not self._playing.is_set():
            self._playing.set()
            threading.Thread(target=self._play_loop, daemon=True).start()
        elif not self._play.value:
            self._playing.clear()

    def _play_loop(self) -> None:
        tr = self.trajectory
        wall0 = time.perf_counter()
        t_start = tr.time[int(self._t_slider.value)]
        if int(self._t_slider.value) >= len(tr) - 1:
            t_start = tr.time[0]
        while self._playing.is_set() and not self._closed:
            t = t_start + (time.perf_counter() - wall0) * float(self._speed.value)
            i = int(np.searchsorted(tr.time, t, side="right")) - 1
            if i >= len(tr) - 1:
                self._t_slider.value = len(tr) - 1
                break
            self._t_slider.value = max(i, 0)
            time.sleep(1 / 30)
        self._playing.clear()
        self._play.value = False

    def _show_sample(self, k: int) -> None:
        measured, _, pressures = self.calibration
        self._sample_marker.position = tuple(measured[k])
        self._sample_marker.visible = True
        tensions = None if self._sample_tensions is None else self._sample_tensions[k]
        self.set_inputs(pressures=pressures[k], tensions=tensions)


def _range(value) -> tuple[float, float]:
    """(low, high) gauge pressures: numbers in Pa or strings with units, finite, low < high."""
    if isinstance(value, np.ndarray):
        value = value.tolist() if value.ndim == 1 else value
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise design_error(
            "pressure_range", value, "must be (low, high) gauge pressures in Pa", InputError
        )
    lo, hi = (V.quantity(v, "pressure", f"pressure_range[{i}]") for i, v in enumerate(value))
    if not lo < hi:
        raise design_error("pressure_range", value, "must be finite with low < high", InputError)
    return lo, hi


def _positive(value, field: str = "force_max") -> float:
    """A positive force: a number in N or a string with units (not a bool)."""
    x = V.quantity(value, "force", field)
    if not x > 0:
        raise design_error(field, value, "must be a positive force in N", InputError)
    return x


def _measured_predicted(design: Design, calibration, dataset):
    """(measured, predicted, pressures, tensions): tip positions (m, 3), pressures (m, c)
    and tendon tensions (m, k; None: slack) of a calibration result, or of a dataset
    against ``design`` (one batch solve), or None."""
    if calibration is not None and dataset is not None:
        raise design_error(
            "dataset", "given", "give calibration= or dataset=, not both", InputError
        )
    if calibration is not None:
        for attr in ("dataset", "predicted"):
            if not hasattr(calibration, attr):
                raise design_error(
                    "calibration",
                    type(calibration).__name__,
                    "must be a softrod.CalibrationResult (from softrod.calibrate)",
                    InputError,
                )
        tensions = getattr(calibration.dataset, "tensions", None)
        return (
            np.asarray(calibration.dataset.tip_position, float),
            np.asarray(calibration.predicted, float),
            np.asarray(calibration.dataset.pressures, float),
            None if tensions is None else np.asarray(tensions, float),
        )
    if dataset is None:
        return None
    from ..datasets import Dataset, load_dataset
    from ..statics import solve_statics_batch

    if not isinstance(dataset, Dataset):
        dataset = load_dataset(dataset, design=design)
    if dataset.mounting is not None and len(set(dataset.mounting.tolist())) > 1:
        raise design_error(
            "dataset",
            "several mountings",
            "one mounting per view: pass a CalibrationResult (calibration=) instead, which "
            "carries predictions for every mounting",
            InputError,
        )
    out = solve_statics_batch(design, dataset.pressures, tensions=dataset.tensions)
    return (
        np.asarray(dataset.tip_position, float),
        out.tip_position,
        np.asarray(dataset.pressures, float),
        None if dataset.tensions is None else np.asarray(dataset.tensions, float),
    )


def _trajectory(design: Design, trajectory):
    """A Trajectory (or the path of one) whose channels match ``design``, or None."""
    if trajectory is None:
        return None
    from ..dynamics import Trajectory

    if not isinstance(trajectory, Trajectory):
        trajectory = Trajectory.load(trajectory)
    if trajectory.n_channels != design.n_channels:
        raise design_error(
            "trajectory",
            f"{trajectory.n_channels} channels",
            f"design {design.name!r} has {design.n_channels}",
            InputError,
        )
    return trajectory
