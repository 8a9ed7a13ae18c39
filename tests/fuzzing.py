"""The fuzz harness: hostile cases run in worker subprocesses with a time and a memory limit,
and every outcome classified (docs/errors.md, "The fuzz suite").

A case is ``(target, payload)``: the name of a function below (``TARGETS``) and plain data
(documents, arrays, argument lists, file bytes) that it feeds to softrod. A worker runs it
and reports one of

- ``ok``: accepted, and the result passed its validity checks (finite, rotations
  orthonormal, stretch > 0, exit code 0, ...);
- ``error``: a clean softrod error (DesignError/InputError naming field and rule,
  ConvergenceError, or a CLI exit 2/3 with one ``error:`` line);
- ``defect``: anything else, with its class (``raw exception``, ``invalid result``,
  ``unclear error``, ``internal error``, ``numpy warning``), or, seen from the parent, a
  ``crash`` (the worker died: abort, signal, out of memory) or a ``timeout``.

Run as ``python fuzzing.py --worker`` it is a worker: length-prefixed pickles in on stdin,
out on stdout. :class:`Pool` starts and restarts the workers.
"""

from __future__ import annotations

import contextlib
import copy
import math
import os
import pickle
import select
import struct
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# Limits of one case. The memory limit is on the worker's address space (RLIMIT_AS): a case
# that tries to allocate gigabytes fails there (MemoryError or an abort), which is a defect.
CASE_TIMEOUT_S = 20.0
MEMORY_LIMIT_BYTES = 3 * 2**30
ROTATION_TOLERANCE = 1e-6  # |R^T R - I| at a node (the core's rule, docs/model.md)
MAX_MESSAGE = 2000  # characters of an error message; longer ones are a defect (unreadable)
DEFAULT_OPTIONS = "<default solver options>"  # a case's options: softrod's defaults

DEFECT_CLASSES = (
    "crash",
    "timeout",
    "raw exception",
    "internal error",
    "invalid result",
    "unclear error",
    "numpy warning",
)


@dataclass
class Outcome:
    kind: str  # "ok", "error" or "defect"
    defect: str = ""  # the defect class (DEFECT_CLASSES)
    detail: str = ""
    seconds: float = 0.0


@dataclass
class Stats:
    """Counts of outcomes per target, and the defects seen (case and outcome)."""

    counts: dict = field(default_factory=dict)
    defects: list = field(default_factory=list)

    def add(self, target: str, case, outcome: Outcome) -> None:
        key = (target, outcome.kind if outcome.kind != "defect" else outcome.defect)
        self.counts[key] = self.counts.get(key, 0) + 1
        if outcome.kind == "defect":
            self.defects.append((target, case, outcome))

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def table(self) -> str:
        targets = sorted({t for t, _ in self.counts})
        kinds = ["ok", "error", *DEFECT_CLASSES]
        rows = [f"{'target':<14}" + "".join(f"{k:>15}" for k in kinds)]
        for t in targets:
            rows.append(f"{t:<14}" + "".join(f"{self.counts.get((t, k), 0):>15}" for k in kinds))
        return "\n".join(rows)


# --- the parent side -----------------------------------------------------------------------------


def _send(stream, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(struct.pack("<Q", len(data)) + data)
    stream.flush()


class _Worker:
    def __init__(self):
        self.log = tempfile.TemporaryFile()
        env = dict(os.environ)
        env.update(
            OMP_NUM_THREADS="1",
            OPENBLAS_NUM_THREADS="1",
            MKL_NUM_THREADS="1",
            MALLOC_ARENA_MAX="2",
            MPLBACKEND="Agg",
            RAYON_NUM_THREADS="2",
        )
        self.proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "--worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
            env=env,
        )
        self.buffer = b""

    def send(self, case) -> None:
        _send(self.proc.stdin, case)

    def receive(self, timeout: float):
        """The worker's answer, or None if it died or timed out (then it is killed)."""
        deadline = time.monotonic() + timeout
        fd = self.proc.stdout.fileno()
        while True:
            if len(self.buffer) >= 8:
                (n,) = struct.unpack("<Q", self.buffer[:8])
                if len(self.buffer) >= 8 + n:
                    data, self.buffer = self.buffer[8 : 8 + n], self.buffer[8 + n :]
                    return pickle.loads(data)
            left = deadline - time.monotonic()
            if left <= 0:
                self.kill()
                return None
            ready, _, _ = select.select([fd], [], [], left)
            if ready:
                chunk = os.read(fd, 1 << 20)
                if not chunk:  # the worker died
                    self.proc.wait()
                    return None
                self.buffer += chunk

    def stderr_tail(self) -> str:
        with contextlib.suppress(OSError):
            self.log.seek(0, os.SEEK_END)
            size = self.log.tell()
            self.log.seek(max(0, size - 1500))
            return self.log.read().decode("utf-8", "replace").strip()
        return ""

    def kill(self) -> None:
        with contextlib.suppress(OSError):
            self.proc.kill()
        self.proc.wait()

    def close(self) -> None:
        with contextlib.suppress(OSError, BrokenPipeError):
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.kill()
        with contextlib.suppress(OSError):
            self.proc.stdout.close()
        self.log.close()


class Pool:
    """``n`` worker subprocesses; :meth:`run` spreads cases over them and classifies a dead
    or stuck worker's case as a crash or a timeout (and starts a new worker)."""

    def __init__(self, n: int = 2, timeout: float = CASE_TIMEOUT_S):
        self.n = n
        self.timeout = timeout
        self.workers: list[_Worker] = []

    def __enter__(self) -> Pool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        for w in self.workers:
            w.close()
        self.workers = []

    def _worker(self, i: int) -> _Worker:
        while len(self.workers) <= i:
            self.workers.append(_Worker())
        return self.workers[i]

    def run(self, cases: list[tuple[str, object]]) -> list[Outcome]:
        outcomes: list[Outcome | None] = [None] * len(cases)
        queue = list(range(len(cases)))
        busy: dict[int, tuple[int, float]] = {}  # worker -> (case index, start time)
        while queue or busy:
            for i in range(self.n):
                if i not in busy and queue:
                    k = queue.pop(0)
                    try:
                        self._worker(i).send(cases[k])
                    except OSError:  # it died between cases: start another
                        self.workers[i].close()
                        self.workers[i] = _Worker()
                        self.workers[i].send(cases[k])
                    busy[i] = (k, time.monotonic())
            fds = {self.workers[i].proc.stdout.fileno(): i for i in busy}
            ready, _, _ = select.select(list(fds), [], [], 0.05)
            for fd in ready:
                i = fds[fd]
                k, start = busy[i]
                w = self.workers[i]
                answer = w.receive(max(0.1, self.timeout - (time.monotonic() - start)))
                if answer is None:
                    code = w.proc.returncode
                    outcomes[k] = Outcome(
                        "defect",
                        "crash",
                        f"the worker died (exit code {code}): {w.stderr_tail()[-600:]}",
                        time.monotonic() - start,
                    )
                    self._replace(i)
                else:
                    outcomes[k] = answer
                del busy[i]
            for i in list(busy):
                k, start = busy[i]
                if time.monotonic() - start > self.timeout:
                    outcomes[k] = Outcome(
                        "defect", "timeout", f"no answer within {self.timeout:g} s", self.timeout
                    )
                    self._replace(i)
                    del busy[i]
        return outcomes  # type: ignore[return-value]

    def _replace(self, i: int) -> None:
        self.workers[i].kill()
        self.workers[i].close()
        self.workers[i] = _Worker()


# --- the worker side -----------------------------------------------------------------------------


def _check_solution(sol) -> str:
    """'' if a StaticSolution that says converged is valid, else what is wrong."""

    if not sol.converged:
        return "a solution returned with converged = False by a call that should raise"
    for name in ("position", "rotation", "v", "u"):
        a = np.asarray(getattr(sol, name))
        if not np.all(np.isfinite(a)):
            return f"{name} is not finite"
    r = np.asarray(sol.rotation)
    err = np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max()
    if err > ROTATION_TOLERANCE or np.linalg.det(r).min() <= 0:
        return f"rotation not orthonormal: max |R^T R - I| = {err:.3g}"
    v3 = np.asarray(sol.v)[:, 2]
    if v3.min() <= 0:
        return f"stretch v3 = {v3.min():.3g} <= 0"
    if sol.contact is not None:
        deepest = _deepest_allowed(sol.design)
        if not sol.contact.max_penetration <= deepest:
            return (
                f"penetration {sol.contact.max_penetration:.3g} m beyond the obstacles' "
                f"tolerance {deepest:.3g} m"
            )
    return ""


def _deepest_allowed(design) -> float:
    """The largest penetration tolerance of the design's obstacles, m (docs/contact.md: a
    result never goes deeper than its obstacle's tolerance; the largest bounds every
    node's, whichever obstacle it touches)."""
    return max(float(o["tolerance"]) for o in design.spec["obstacles"])


def _check_batch(out, m: int) -> str:

    if out.tip_position.shape != (m, 3) or out.converged.shape != (m,):
        return f"batch result has the wrong shape for {m} rows"
    ok = np.asarray(out.converged, dtype=bool)
    if not np.all(np.isfinite(out.tip_position[ok])):
        return "a converged row is not finite"
    held = getattr(out, "tip_reaction_force", None)
    if held is not None and not np.all(np.isfinite(np.asarray(held)[ok])):
        return "a converged row's tip reaction is not finite"
    r = out.tip_rotation[ok]
    if r.size:
        err = np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max()
        if err > ROTATION_TOLERANCE:
            return f"tip rotation not orthonormal: max |R^T R - I| = {err:.3g}"
    return ""


def _check_trajectory(traj, design=None) -> str:

    for name in ("time", "tip_position", "tip_rotation", "pressure"):
        a = np.asarray(getattr(traj, name))
        if not np.all(np.isfinite(a)):
            return f"trajectory {name} is not finite"
    r = np.asarray(traj.tip_rotation)
    err = np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max()
    if err > ROTATION_TOLERANCE:
        return f"tip rotation not orthonormal: max |R^T R - I| = {err:.3g}"
    if traj.penetration is not None and design is not None:
        deepest = _deepest_allowed(design)
        if not np.all(np.asarray(traj.penetration) <= deepest):
            return (
                f"penetration {np.max(traj.penetration):.3g} m beyond the tolerance {deepest:.3g} m"
            )
    return ""


_QUICK = None


def _options():
    """Solver options that keep a hostile case short (clean ConvergenceError otherwise)."""
    global _QUICK
    if _QUICK is None:
        from softrod import SolverOptions

        _QUICK = SolverOptions(max_iter=12, max_load_steps=8)
    return _QUICK


def target_design(doc) -> str:
    """Load a design document; if it loads, solve it at zero pressure and at 50 kPa on the
    first channel."""
    import softrod

    d = softrod.load_design(doc)
    for p in (0.0, 5e4):
        pressures = [p] + [0.0] * (d.n_channels - 1) if d.n_channels else []
        try:
            sol = softrod.solve_statics(d, pressures, options=_options())
        except softrod.ConvergenceError:
            continue
        problem = _check_solution(sol)
        if problem:
            return problem
    return ""


def target_design_file(data: bytes) -> str:
    """Load a design file with these bytes."""
    import softrod

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.toml"
        path.write_bytes(data)
        softrod.load_design(path)
    return ""


def target_statics(payload) -> str:
    """solve_statics(design, pressures, **kwargs) on a bundled design."""
    import softrod

    kwargs = dict(payload.get("kwargs", {}))
    kwargs.setdefault("options", _options())
    if kwargs["options"] == DEFAULT_OPTIONS:
        del kwargs["options"]
    design = softrod.load_design(payload["design"])
    if payload.get("changes"):
        design = design.replace(payload["changes"])
    sol = softrod.solve_statics(design, payload["pressures"], **kwargs)
    if kwargs.get("check", True) is False and not sol.converged:
        return ""
    return _check_solution(sol)


def target_batch(payload) -> str:
    import softrod

    kwargs = dict(payload.get("kwargs", {}))
    kwargs.setdefault("options", _options())
    out = softrod.solve_statics_batch(payload["design"], payload["pressures"], **kwargs)
    return _check_batch(out, len(np.asarray(out.pressures)))


def target_simulate(payload) -> str:
    import softrod

    design = softrod.load_design(payload["design"])
    traj = softrod.simulate(
        design, payload["schedule"], payload["t_end"], **payload.get("kwargs", {})
    )
    return _check_trajectory(traj, design)


def target_markers(payload) -> str:
    """Markers on the moving 130 mm SPA, free or with its tip pinned, through
    ``simulate(markers=)``, ``Simulation(markers=)`` or ``Simulation.set_markers``: an
    accepted set is recorded at every sample, finite, its sites in [0, L], and a bare
    marker at s = L is the tip bit for bit."""
    import softrod

    design = softrod.load_design("spa_three_chamber_130mm")
    kwargs = {"dt": "5 ms"}
    if payload["held"]:
        kwargs["tip_constraint"] = {"type": "pinned", "position": ["3 mm", "0 mm", "-127 mm"]}
    how, markers = payload["how"], payload["markers"]
    if how == "simulate":
        traj = softrod.simulate(design, [0.0] * 3, "10 ms", markers=markers, **kwargs)
    else:
        sim = softrod.Simulation(design, markers=markers if how == "Simulation" else None, **kwargs)
        if how == "set_markers":
            sim.set_markers(markers)
        traj = sim.run([0.0] * 3, "10 ms")
    problem = _check_trajectory(traj)
    if problem or markers is None:
        return problem or ("" if traj.marker_position is None else "markers=None recorded some")
    pos, s, offset = traj.marker_position, traj.marker_s, traj.marker_offset
    if pos is None or pos.shape != (len(traj), s.size, 3) or offset.shape != (s.size, 3):
        return f"accepted markers not recorded as (n, K, 3): {None if pos is None else pos.shape}"
    if not (np.isfinite(pos).all() and np.isfinite(offset).all()):
        return "marker positions or offsets not finite"
    if not ((s >= 0) & (s <= design.length * (1 + 1e-12))).all():
        return f"a marker's arc length outside [0, L]: {s.tolist()}"
    at_tip = (s == design.length) & (offset == 0).all(axis=1)
    if not all(np.array_equal(pos[:, k], traj.tip_position) for k in np.flatnonzero(at_tip)):
        return "a bare marker at s = L is not the tip"
    return ""


def target_schedule(payload) -> str:
    """A PressureSchedule constructor with these arguments, then a sample."""
    from softrod import PressureSchedule

    make = getattr(PressureSchedule, payload["constructor"])
    s = make(*payload.get("args", ()), **payload.get("kwargs", {}))
    s.sample(payload.get("times", [0.0, 0.5, 1.0]))
    return ""


def target_dataset_file(payload) -> str:
    """Read these bytes as a dataset (CSV/Parquet), a schedule and a stiffness map."""
    import softrod
    from softrod import PressureSchedule, StiffnessMap

    suffix = payload.get("suffix", ".csv")
    reader = payload.get("reader", "dataset")
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"fuzz{suffix}"
        path.write_bytes(payload["data"])
        if reader == "dataset":
            softrod.load_dataset(path, extra=payload.get("extra", "error"))
        elif reader == "schedule":
            PressureSchedule.from_file(path, extra=payload.get("extra", "error"))
        else:
            StiffnessMap.from_csv(path)
    return ""


def target_dataset_frame(payload) -> str:
    import softrod

    ds = softrod.load_dataset(payload["frame"], **payload.get("kwargs", {}))

    if not (np.all(np.isfinite(ds.pressures)) and np.all(np.isfinite(ds.tip_position))):
        return "a dataset with non-finite values was accepted"
    # A reaction component may be NaN (not measured), never infinite.
    for reaction in (ds.tip_reaction_force, ds.tip_reaction_moment):
        if reaction is not None and np.isinf(reaction).any():
            return "a dataset with an infinite reaction was accepted"
    return ""


def target_stiffness_map(payload) -> str:
    from softrod import StiffnessMap

    m = StiffnessMap.from_table(payload["axes"], payload["sigma"], **payload.get("kwargs", {}))
    m(payload.get("pressures", [[0.0] * m.n_channels]))
    return ""


def target_quantity(payload) -> str:
    """A quantity string of a kind (the unit grammar alone)."""
    from softrod._validate import quantity

    quantity(payload["value"], payload["kind"], "x", bare=payload.get("bare", "error"))
    return ""


def target_replace(payload) -> str:
    """Design.replace(changes) on a bundled design, then a solve at zero pressure."""
    import softrod

    d = softrod.load_design(payload["design"]).replace(payload["changes"])
    sol = softrod.solve_statics(d, [0.0] * d.n_channels, options=_options())
    return _check_solution(sol)


def target_fit(payload) -> str:
    """calibrate / identify_stiffness on a few rows of a bundled example dataset, with
    hostile arguments."""
    import softrod
    from softrod.datasets import example_dataset_path

    data = softrod.load_dataset(example_dataset_path(payload["dataset"]))
    data = data.subset(np.arange(min(len(data), payload.get("rows", 6))))
    kwargs = dict(payload.get("kwargs", {}))
    if payload["function"] == "calibrate":
        kwargs.setdefault("max_evaluations", 3)
        softrod.calibrate(payload["design"], data, payload["params"], **kwargs)
    else:
        softrod.identify_stiffness(payload["design"], data, **kwargs)
    return ""


def target_system_fit(payload) -> str:
    """synthesize_system_dataset and calibrate_system on the bundled two-rod platform with
    hostile markers, rows and arguments."""
    import softrod

    system = softrod.load_system("two_spa_platform")
    ds = softrod.synthesize_system_dataset(system, payload["pressures"], **payload.get("synth", {}))
    if not np.isfinite(ds.pressures).all():
        return "a system dataset with non-finite pressures was made"
    if ds.markers is not None and not np.isfinite(ds.markers).all():
        return "a converged system dataset has non-finite markers"
    if payload.get("fit"):
        kwargs = dict(payload.get("kwargs", {}))
        kwargs.setdefault("max_evaluations", 3)
        res = softrod.calibrate_system(system, ds, payload["params"], progress=False, **kwargs)
        if not np.isfinite(res.values).all():
            return "calibrate_system returned non-finite values"
    return ""


def target_trajectory_file(data: bytes) -> str:
    """Trajectory.load of these bytes as .npz and as .parquet."""
    import softrod

    suffix = ".npz" if data[:2] == b"PK" else ".parquet"  # a zip archive, or not
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"t{suffix}"
        path.write_bytes(data)
        softrod.Trajectory.load(path)
    return ""


def target_api(payload) -> str:
    """Any public function by name with these arguments (calibrate, synthesize_dataset,
    identify_stiffness, Design.replace, Simulation, ...)."""
    import softrod

    fn = softrod
    for part in payload["function"].split("."):
        fn = getattr(fn, part)
    fn(*payload.get("args", ()), **payload.get("kwargs", {}))
    return ""


def _finite_arrays(out: dict, what: str) -> str:
    """'' if every array in ``out`` is finite, else the first that is not."""
    for key, value in out.items():
        a = np.asarray(value)
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            return f"{what}[{key!r}] is not finite"
    return ""


def target_sensitivities(payload) -> str:
    """trajectory_sensitivities or system_trajectory_sensitivities with these arguments:
    every returned array finite, one derivative per named parameter at every sample."""
    import softrod

    fn = getattr(softrod, payload["function"])
    reports: list = []
    progress = {
        # A callback of the right arity records the reports; one of the wrong arity must be
        # refused by name before the run.
        "three": lambda done, total, wall: reports.append((done, total)),
        "one": lambda done: None,
        "none": None,
        "false": False,
    }[payload["progress"]]
    out = fn(*payload["args"], **payload["kwargs"], progress=progress)
    if payload["progress"] == "one":
        return "a progress callback of one argument was accepted"
    done = [r[0] for r in reports]
    # The reports rise to t_end (the last within round-off of the steps' sum).
    if reports and not (np.all(np.diff(done) > 0) and math.isclose(*reports[-1], rel_tol=1e-9)):
        return f"the progress reports {reports} do not rise to t_end"
    problem = _finite_arrays(out, payload["function"])
    if problem:
        return problem
    n, k = len(out["time"]), len(out["params"])
    for key, value in out.items():
        if key.startswith("d_") and (value.shape[0] != n or value.shape[-1] != k):
            return f"{key} has shape {value.shape} for {n} samples and {k} parameters"
    if not np.all(np.diff(out["time"]) > 0):
        return "the samples' times do not increase"
    return ""


def target_control(payload) -> str:
    """The control entry points (solve_inverse, InverseProblem.solve, linearise,
    TargetPath, TrackingController) with these arguments: a reached inverse solution is a
    valid static equilibrium, a linearisation's matrices are finite."""
    import softrod

    function = payload["function"]
    args, kwargs = payload["args"], payload["kwargs"]
    if function == "InverseProblem.solve":
        problem = softrod.InverseProblem(*args, **kwargs)
        out = problem.solve(*payload["solve_args"], **payload["solve_kwargs"])
    else:
        out = getattr(softrod, function)(*args, **kwargs)
    if isinstance(out, softrod.InverseSolution):
        return _check_solution(out.statics()) if out.reached else ""
    if isinstance(out, softrod.LinearSystem):
        for name in ("mass", "stiffness", "damping", "input"):
            if not np.all(np.isfinite(np.asarray(getattr(out, name)))):
                return f"the linearisation's {name} matrix is not finite"
    return ""


# --- methods of the public classes -----------------------------------------------------------

SPA = "spa_three_chamber_130mm"
TWO = "two_spa_platform"
_OBJECTS: dict = {}


def _spa_data(rows: int):
    import softrod

    return softrod.load_dataset("spa130_synthetic").subset(range(rows))


def _build(kind: str):
    """One small instance of a public class (a few seconds at most), built once per worker."""
    import softrod

    p = [2e4, 0.0, 0.0]
    two = [[1e4, 0.0, 0.0], [0.0, 0.0, 0.0]]
    if kind == "StaticSolution":
        return softrod.solve_statics(SPA, p)
    if kind == "BatchSolution":
        return softrod.solve_statics_batch(SPA, [[0.0] * 3, p])
    if kind == "LinearSystem":
        return softrod.linearise(SPA, p, nodes=3)
    if kind == "Trajectory":
        return softrod.simulate(SPA, p, "4 ms", dt="2 ms", markers=[(0.065, [0, 0, 0])])
    if kind == "InverseSolution":
        return softrod.solve_inverse(SPA, softrod.solve_statics(SPA, p).tip_position)
    if kind == "InverseProblem":
        return softrod.InverseProblem(SPA)
    if kind == "Design":
        return softrod.load_design(SPA)
    if kind == "SystemSolution":
        return softrod.solve_system(TWO, two)
    if kind == "SystemBatchSolution":
        return softrod.solve_system_batch(TWO, [two])
    if kind == "SystemTrajectory":
        return softrod.simulate_system(TWO, two, "4 ms", dt="2 ms")
    if kind == "CalibrationResult":
        return softrod.calibrate(SPA, _spa_data(6), "c_b", progress=False)
    if kind == "StiffnessMap":
        return softrod.StiffnessMap.from_table([[0, 1e4]] * 3, np.ones((2, 2, 2, 3)))
    if kind == "Dataset":
        return _spa_data(6)
    if kind == "PressureSchedule":
        return softrod.PressureSchedule.piecewise_linear([0.0, 0.01], [[0.0] * 3, p])
    if kind == "Simulation":
        return softrod.Simulation(SPA, p, dt="2 ms")
    if kind == "SystemSimulation":
        return softrod.SystemSimulation(TWO, two, dt="2 ms")
    if kind == "TrackingController":
        path = softrod.TargetPath([0.0, 0.01], [softrod.solve_statics(SPA, p).tip_position] * 2)
        return softrod.TrackingController(SPA, path, rate=200.0)
    if kind == "Workspace":
        return softrod.workspace(SPA, samples=3)
    if kind == "StiffnessIdentification":
        return softrod.identify_stiffness(SPA, _spa_data(4))
    if kind == "HybridStiffnessModel":
        ident = softrod.identify_stiffness(SPA, _spa_data(60))
        return softrod.fit_stiffness_map(ident, hidden=(4,), max_iter=200, progress=False)
    if kind == "SystemCalibrationResult":
        system = softrod.load_system(TWO)
        data = softrod.synthesize_system_dataset(system, [two, [[0.0] * 3, [2e4, 0.0, 0.0]]])
        return softrod.calibrate_system(system, data, ["platform_mass"], progress=False)
    raise KeyError(kind)


def _instance(kind: str):
    if kind not in _OBJECTS:
        _OBJECTS[kind] = _build(kind)
    obj = _OBJECTS[kind]
    # A case may move a simulation on: each starts from the same state.
    return obj.copy() if hasattr(obj, "copy") and kind.endswith("Simulation") else obj


def target_method(payload) -> str:
    """A public method of a public class (``kind``) with hostile values for ``params`` (the
    method's other required arguments hostile too, the optional ones at their defaults),
    in an empty folder (a method that writes writes there)."""
    import inspect

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import softrod

    kind, name = payload["kind"], payload["method"]
    cls = getattr(softrod, kind)
    static = isinstance(inspect.getattr_static(cls, name), (staticmethod, classmethod))
    target = getattr(cls if static else _instance(kind), name)
    kwargs = dict(payload["kwargs"])
    if "hostile" in payload:
        # One hostile argument, the other required ones valid where a value is known.
        for p in inspect.signature(target).parameters.values():
            if p.default is p.empty and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
                value = _valid_argument(kind, name, p.name)
                kwargs[p.name] = payload["fallback"] if value is None else value
        kwargs[payload["hostile"]] = payload["value"]
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        os.chdir(folder)
        try:
            target(**kwargs)
        finally:
            os.chdir(cwd)
            plt.close("all")
    return ""


def _valid_argument(kind: str, method: str, param: str):
    """A valid value of a method's required argument (None where none is known)."""
    suffix = {
        "save": ".json" if kind in ("StiffnessMap", "HybridStiffnessModel") else ".npz",
        "to_toml": ".toml",
        "toml_text": ".toml",
        "write": ".csv",
        "write_report": ".html",
    }.get(method, ".png" if method.startswith("plot") else None)
    if kind == "Design" and method == "save":
        suffix = ".toml"
    values = {
        "times": lambda: [0.0, 0.002],
        "t": lambda: 0.001,
        "point": lambda: [0.01, 0.0, -0.125],
        "pressures": lambda: [[0.0, 0.0, 0.0], [1e4, 0.0, 0.0]],
        "pressure_schedule": lambda: [1e4, 0.0, 0.0],
        "duration": lambda: "4 ms",
        "command": lambda: [1e4, 0.0, 0.0],
        "target": lambda: [0.01, 0.0, -0.125],
        "rows": lambda: [0, 1],
        "count": lambda: 1,
        "omega": lambda: 10.0,
        "changes": lambda: {},
        "obstacles": lambda: [],
        "n": lambda: 3,
        "trajectory": lambda: _instance("Trajectory"),
        "state": lambda: _instance(kind).save() if hasattr(_instance(kind), "save") else None,
        "path": lambda: None if suffix is None else f"out{suffix}",
    }
    make = values.get(param)
    return None if make is None else make()


def _valid(function: str, param: str):
    """A valid value of a public function's required argument, so that a case can make one
    other argument hostile (None where there is none: that argument is hostile too)."""

    system = function.startswith(("solve_system", "simulate_system", "system_", "calibrate_sys"))
    system = system or function.endswith("system_dataset") or function == "view_system"
    two = [[1e4, 0.0, 0.0], [0.0, 0.0, 0.0]]
    values = {
        "design": lambda: SPA,
        "system": lambda: TWO,
        "source": lambda: TWO if function == "load_system" else "spa130_synthetic",
        "pressures": lambda: (
            two
            if system
            else [[0.0, 0.0, 0.0], [2e4, 0.0, 0.0]]
            if "batch" in function or "dataset" in function
            else [2e4, 0.0, 0.0]
        ),
        "pressure_schedule": lambda: [2e4, 0.0, 0.0],
        "t_end": lambda: "4 ms",
        "params": lambda: "c_b",
        "dataset": lambda: _spa_data(4),
        "identification": lambda: _instance("StiffnessIdentification"),
        "hybrid": lambda: _instance("HybridStiffnessModel"),
        "target": lambda: [0.01, 0.0, -0.125],
        "controller": lambda: _hold_controller,
        "rate": lambda: 200.0,
        "solutions": lambda: _instance("SystemSolution"),
        "trajectory": lambda: _instance("SystemTrajectory"),
        "path": lambda: "out.stl" if function == "write_stl" else "out.csv",
        "vertices": lambda: [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        "faces": lambda: [[0, 1, 2]],
    }
    make = values.get(param)
    return None if make is None else make()


def _hold_controller(measurement):
    return [0.0, 0.0, 0.0]


def target_function(payload) -> str:
    """A public function with one hostile argument (``hostile``: its name and value) and
    valid values for its other required arguments, in an empty folder; a solution it
    returns must be valid."""
    import inspect

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import softrod

    name = payload["function"]
    fn = getattr(softrod, name)
    kwargs = {}
    for p in inspect.signature(fn).parameters.values():
        if p.default is p.empty and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            value = _valid(name, p.name)
            kwargs[p.name] = payload["fallback"] if value is None else value
    kwargs[payload["hostile"]] = payload["value"]
    if "progress" in inspect.signature(fn).parameters and payload["hostile"] != "progress":
        kwargs.setdefault("progress", False)
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        os.chdir(folder)
        try:
            out = fn(**kwargs)
        finally:
            os.chdir(cwd)
            plt.close("all")
    if isinstance(out, softrod.StaticSolution):
        return _check_solution(out)
    return ""


# --- friction (docs/contact.md, "Friction in the statics") --------------------------------------

FINGER = "prebent_finger_on_table"  # the bundled finger on its table (1 channel, 1 tendon)
_FRICTION_CACHE: dict = {}


def friction_design(payload):
    """The design of a friction case: the finger (or ``payload["design"]``), its obstacle 0's
    friction set to ``payload["friction"]`` through ``Design.replace`` or in the document
    (``payload["how"]``); "spa_wall" is the SPA beside its rough wall
    (tests/friction_designs.py), for compare_models."""
    import softrod

    name = payload.get("design", FINGER)
    if name == "spa_wall":
        from friction_designs import spa_beside_rough_wall

        base = spa_beside_rough_wall()
    else:
        base = softrod.load_design(name)
    if "friction" not in payload:
        return base
    mu = payload["friction"]
    if payload.get("how") == "document":
        doc = copy.deepcopy(base.document)
        doc["obstacles"][0]["friction"] = mu
        return softrod.load_design(doc)
    return base.replace({"obstacles[0].friction": mu})


def _quick_friction(steps=8):
    from softrod import SolverOptions

    return SolverOptions(max_iter=12, max_load_steps=8, friction_steps=steps)


HISTORY_KINDS = (
    "@frictionless",
    "@rough",
    "@other",
    "@held",
    "@failed",
    "@state",
    "@batch",
    "@spa",
)


def friction_history(kind, design):
    """What a case passes as ``history=``: a name of HISTORY_KINDS is a solution made here (of
    this design, of another, frictionless, held, failed, its raw friction state, a batch);
    anything else is passed as it is."""
    import softrod

    if not (isinstance(kind, str) and kind in HISTORY_KINDS):
        return kind
    finger = softrod.load_design(FINGER)
    pin = {"type": "pinned", "position": ["27 mm", "0 mm", "-74 mm"]}  # near its rest tip
    makers = {
        "@frictionless": lambda: softrod.solve_statics(finger, [20e3], tensions=[0.0]),
        "@rough": lambda: softrod.solve_statics(design, [20e3], options=_quick_friction()),
        "@other": lambda: softrod.solve_statics(
            finger.replace({"obstacles[0].friction": 0.3}), [20e3], options=_quick_friction()
        ),
        "@held": lambda: softrod.solve_statics(
            design, [20e3], tip_constraint=pin, options=_quick_friction()
        ),
        "@failed": lambda: softrod.solve_statics(
            design,
            [20e3],
            options=softrod.SolverOptions(max_iter=1, continuation=False, friction_steps=1),
            check=False,
        ),
        "@state": lambda: (
            softrod.solve_statics(design, [20e3], options=_quick_friction()).friction_state
        ),
        "@batch": lambda: softrod.solve_statics_batch(design, [[20e3]], options=_quick_friction()),
        "@spa": lambda: softrod.solve_statics("spa_three_chamber_130mm", [0.0, 0.0, 0.0]),
    }
    key = (kind, repr(design.document))
    if key not in _FRICTION_CACHE:
        _FRICTION_CACHE.clear()  # one design's histories at a time: the worker stays small
        _FRICTION_CACHE[key] = makers[kind]()
    return _FRICTION_CACHE[key]


def _check_friction(sol) -> str:
    """A converged frictional solution carries its path's state and finite contact forces."""
    problem = _check_solution(sol)
    if problem:
        return problem
    if sol.friction_state is None:
        return "a frictional solve returned no friction_state"
    if sol.contact is None or not np.all(np.isfinite(sol.contact.friction_force)):
        return "a frictional solve's friction force is missing or not finite"
    return ""


def target_friction(payload) -> str:
    """A design with Coulomb friction (hostile friction values), solved by ``call``: "solve"
    (solve_statics with hostile history, friction_steps, tip_constraint), "batch"
    (solve_statics_batch), "workspace" (softrod.workspace) or "compare"
    (softrod.compare_models of the SPA beside its rough wall)."""
    import softrod

    design = friction_design(payload)
    if "options" in payload:  # a hostile value in place of SolverOptions
        options = payload["options"]
    else:
        options = _quick_friction(payload.get("friction_steps", 8))
    kwargs = dict(payload.get("kwargs", {}))
    call = payload["call"]
    if call == "solve":
        kwargs["history"] = friction_history(kwargs.get("history"), design)
        sol = softrod.solve_statics(design, payload["pressures"], options=options, **kwargs)
        if kwargs.get("check", True) is False and not sol.converged:
            return ""
        if sol.friction_state is None and not any(
            float(o.get("friction", 0.0)) > 0 for o in design.spec["obstacles"]
        ):
            return _check_solution(sol)  # friction 0: the frictionless solve
        return _check_friction(sol)
    if call == "batch":
        out = softrod.solve_statics_batch(design, payload["pressures"], options=options, **kwargs)
        problem = _check_batch(out, len(np.asarray(out.pressures)))
        ok = np.asarray(out.converged, dtype=bool)
        if not problem and out.friction_force is not None:
            if not np.all(np.isfinite(out.friction_force[ok])):
                return "a converged row's friction force is not finite"
        return problem
    if call == "workspace":
        ws = softrod.workspace(design, options=options, **kwargs)
        if not np.all(np.isfinite(ws.tip_position[ws.converged])):
            return "a converged workspace sample is not finite"
        return ""
    if call == "compare":
        table = softrod.compare_models({"rough": {"vertical": design}}, options=options, **kwargs)
        ok = table["converged"].to_numpy(dtype=bool)
        if not np.all(np.isfinite(table.loc[ok, ["tip_x_mm", "tip_y_mm", "tip_z_mm"]])):
            return "a converged compare row is not finite"
        return ""
    raise ValueError(f"unknown friction call {call!r}")


def target_viewer(payload) -> str:
    """softrod.view (headless: the server alone, no browser) of a design with hostile
    start values and slider ranges, then set_inputs with hostile values; the shape shown
    must be valid."""
    import softrod

    design = friction_design(payload) if "friction" in payload else payload["design"]
    v = softrod.view(design, environment_map=False, **payload.get("kwargs", {}))
    try:
        for move in payload.get("moves", []):
            v.set_inputs(**move)
        sol = v.solution
        if sol is not None and sol.converged:
            return _check_solution(sol)
        return ""
    finally:
        v.close()


def target_cli(args) -> str:
    """``softrod ARGS`` in a fresh folder; a clean failure is exit 2 or 3 with one
    ``error:`` line on stderr (exit 1 is an internal error: a defect)."""
    from click.testing import CliRunner
    from softrod.cli import main

    runner = CliRunner()
    with runner.isolated_filesystem():
        for name, data in getattr(args, "files", {}).items():
            Path(name).write_bytes(data)
        result = runner.invoke(main, list(args), catch_exceptions=True)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    err = result.stderr.strip()
    if result.exit_code == 0:
        return ""
    if "Traceback" in result.output or "Traceback" in err:
        raise _Defect("raw exception", f"traceback on exit {result.exit_code}: {err[-400:]}")
    if result.exit_code == 1:
        raise _Defect("internal error", err[-400:])
    if result.exit_code not in (2, 3) or not err.startswith("error: ") or "\n" in err:
        raise _Defect("unclear error", f"exit {result.exit_code}: {err[-400:]!r}")
    raise _CleanExit(err)


class CliArgs(list):
    """CLI arguments plus files to create in the run's folder (name -> bytes)."""

    def __init__(self, args, files=None):
        super().__init__(args)
        self.files = dict(files or {})


class _Defect(Exception):
    def __init__(self, kind: str, detail: str):
        super().__init__(detail)
        self.kind = kind


class _CleanExit(Exception):
    pass


TARGETS = {
    name[len("target_") :]: fn for name, fn in dict(globals()).items() if name.startswith("target_")
}


def classify(target: str, payload) -> Outcome:
    """Run one case here and classify what happened (the worker's side)."""
    from softrod.errors import ConvergenceError, DesignError, SoftrodError

    internal = getattr(__import__("softrod.errors", fromlist=["x"]), "InternalError", ())
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            problem = TARGETS[target](payload)
            out = Outcome("defect", "invalid result", problem) if problem else Outcome("ok")
        except _CleanExit as exc:
            out = Outcome("error", detail=str(exc)[:300])
        except _Defect as exc:
            out = Outcome("defect", exc.kind, str(exc))
        except MemoryError:
            out = Outcome("defect", "crash", "MemoryError")
        except BaseException as exc:  # noqa: BLE001 - everything is classified
            if internal and isinstance(exc, internal):
                out = Outcome("defect", "internal error", str(exc)[:600])
            elif isinstance(exc, SoftrodError):
                out = _clean(exc, DesignError, ConvergenceError)
            elif isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            else:
                frames = traceback.extract_tb(exc.__traceback__)
                inside = [f for f in frames if "softrod" in f.filename] or frames
                last = inside[-1]
                where = f"{Path(last.filename).name}:{last.lineno} in {last.name}"
                out = Outcome(
                    "defect", "raw exception", f"{type(exc).__name__} at {where}: {str(exc)[:400]}"
                )
    if out.kind != "defect":
        for w in caught:
            # numpy's own files too: the worker's calls all start in softrod, so an overflow
            # inside np.linalg.norm on a user's value is softrod's defect as well
            if issubclass(w.category, (RuntimeWarning,)) and _ours_or_numpy(str(w.filename)):
                out = Outcome("defect", "numpy warning", f"{w.message} ({w.filename}:{w.lineno})")
                break
    out.seconds = time.perf_counter() - start
    return out


def _ours_or_numpy(filename: str) -> bool:
    return any(part in filename for part in ("softrod", "numpy", "scipy", "pandas"))


def _clean(exc, design_error, convergence_error) -> Outcome:
    """A softrod error is clean if it says where and why (a DesignError's field and rule,
    a message that is short and not the core's raw JSON complaint)."""
    text = str(exc)
    if len(text) > MAX_MESSAGE:
        return Outcome("defect", "unclear error", f"message of {len(text)} characters")
    if isinstance(exc, design_error):
        said = isinstance(exc.field, str) and exc.field and isinstance(exc.rule, str)
        if not (said and exc.rule):
            return Outcome("defect", "unclear error", f"no field or rule: {text[:300]}")
        if "(JSON)" in text or "line 1 column" in text:
            return Outcome("defect", "unclear error", f"no field path: {text[:300]}")
    return Outcome("error", detail=f"{type(exc).__name__}: {text[:300]}")


def _worker() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))
    proto_out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # anything printed goes to the log, never into the protocol
    sys.stdout = sys.stderr
    proto_in = os.fdopen(os.dup(0), "rb")
    import softrod  # noqa: F401 - imported once, before the first case
    from softrod._validate import registry

    registry()
    while True:
        head = proto_in.read(8)
        if len(head) < 8:
            return
        (n,) = struct.unpack("<Q", head)
        target, payload = pickle.loads(proto_in.read(n))
        _send(proto_out, classify(target, payload))


if __name__ == "__main__" and "--worker" in sys.argv:
    # Run as the module `fuzzing` so that what it pickles (Outcome) unpickles in the parent.
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import fuzzing

    fuzzing._worker()
