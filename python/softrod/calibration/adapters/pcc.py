"""Paper 003's PCC model on a dataset: equilibria (static experiments) and replayed time
series (dynamic experiments) in one problem, with exact derivatives with respect to the
visco-elastic parameters from the core (implicit function theorem for equilibria, forward
sensitivities through the implicit midpoint steps for time series; ``PccModel.
statics_sensitivity`` and ``runs_sensitivity``, parallel, GIL released).

A time series is replayed as the rod's are: the measured pressures joined linearly between
samples drive the model from rest in equilibrium under the experiment's first pressures,
with time step ``dt``; the model's positions are read at the sample times (linear in time
between steps when a sample falls between them)."""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ... import _core
from ... import _validate as V
from ..._validate import si_text
from ...design import Design
from ...errors import DesignError
from ..problem import ModelAdapter, Prediction
from .rod_dynamic import experiment_rows
from .rod_static import marker_sites

#: The parameters of the PCC model's visco-elastic law (paper 003 Sec. IV-B), with their
#: design keys in [pcc], their spec keys and units. ``k_theta[j]`` is the j-th stiffness of
#: a k_theta(theta) table.
PCC_KINDS = {
    "k_L": ("k_l", "N/m", "force_per_length"),
    "b_L": ("b_l", "N*s/m", "damping_linear"),
    "k_theta": ("k_theta", "N*m", "moment"),
    "b_theta": ("b_theta", "N*m*s", "damping_rotational"),
    "k_phi": ("k_phi", "N*m", "moment"),
    "b_phi": ("b_phi", "N*m*s", "damping_rotational"),
}
_NODE = re.compile(r"^k_theta\[\s*(\d+)\s*\]$")
#: Experiments that are time series by default (the names synthesize_pcc_experiments uses
#: for paper 003's step response and free decay, Sec. V-D and V-E).
DYNAMIC_EXPERIMENTS = ("step", "free_decay")


@dataclass(frozen=True)
class PccParameter:
    """A PCC parameter (paper 003 Sec. IV-B): k_L, b_L, k_theta or k_theta[j], b_theta,
    k_phi, b_phi. It acts on every section with chambers."""

    name: str
    kind: str
    node: int | None = None

    @property
    def unit(self) -> str:
        return PCC_KINDS[self.kind][1]

    positive = True


def parse_pcc_parameters(names) -> list[PccParameter]:
    if not names:
        raise V.fail("params", names, f"name at least one of {', '.join(PCC_KINDS)}")
    out = []
    for n in names:
        if not isinstance(n, str):
            raise V.fail("params", n, "each parameter must be a name such as 'k_L'")
        key = n.strip()
        node = _NODE.match(key)
        if node:
            out.append(PccParameter(key, "k_theta", int(node.group(1))))
        elif key in PCC_KINDS:
            out.append(PccParameter(key, key))
        else:
            raise V.fail(
                "params",
                n,
                f"unknown PCC parameter; known: {', '.join(PCC_KINDS)}, k_theta[j] (the j-th "
                "entry of a k_theta table)",
            )
    names = [p.name for p in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise V.fail("params", dup, "names a parameter twice")
    if any(p.node is not None for p in out) and "k_theta" in names:
        raise V.fail("params", names, "k_theta and k_theta[j] act on the same stiffness")
    return out


def _kinds(dataset, experiments, dynamic: bool) -> dict:
    """{experiment id: "static" | "dynamic"} of every experiment (None: the whole dataset)."""
    ids = dataset.experiments or (None,)
    if experiments is None:
        if dynamic:
            return dict.fromkeys(ids, "dynamic")
        return {e: ("dynamic" if e in DYNAMIC_EXPERIMENTS else "static") for e in ids}
    if not isinstance(experiments, Mapping):
        raise V.fail("experiments", experiments, "must map experiment ids to 'static' or 'dynamic'")
    if dataset.experiment is None:
        raise V.fail("experiments", dict(experiments), "the dataset has no experiment column")
    out = {}
    for e, kind in experiments.items():
        if not any(_same(e, k) for k in ids):
            raise V.fail(
                "experiments",
                e,
                f"unknown experiment id; the dataset has {', '.join(map(repr, ids))}",
            )
        if kind not in ("static", "dynamic"):
            raise V.fail(f"experiments[{e!r}]", kind, "must be 'static' or 'dynamic'")
        out[next(k for k in ids if _same(e, k))] = kind
    missing = [k for k in ids if k not in out]
    if missing:
        raise V.fail(
            "experiments",
            dict(experiments),
            f"say for every experiment whether it is 'static' or 'dynamic' (missing: "
            f"{', '.join(map(repr, missing))})",
        )
    return out


def _same(a, b) -> bool:
    if isinstance(a, (int, np.integer)) and isinstance(b, (int, np.integer)):
        return int(a) == int(b)
    return isinstance(a, str) and isinstance(b, str) and a == b


class PccAdapter(ModelAdapter):
    """Tip and marker positions of static rows and replayed time series of the PCC model."""

    model = "pcc"

    def __init__(self, design: Design, dataset, names, dynamic, experiments, dt, threads):
        from ...dynamics.simulate import _seconds
        from ...pcc.model import pcc_model

        super().__init__()
        labels = [] if dataset.mounting is None else sorted(set(dataset.mounting.tolist()))
        if len(labels) > 1:
            # Each row would be predicted in the design's own mounting: refused, not fitted
            # to a silent answer.
            raise V.fail(
                "dataset.mounting",
                labels,
                "model='pcc' fits rows of one mounting (the design's): fit each mounting "
                "separately, or fit the rod model, which solves every row in its mounting",
            )
        self.design = design
        self.params = parse_pcc_parameters(names)
        self.parameters = tuple(self.params)
        self.spec = copy.deepcopy(design.spec)
        self.spec.setdefault("pcc", {})
        pcc_model(design)  # the design must make a PCC model (errors name the field)
        self.initial = np.array([self._value(p) for p in self.params])
        for p, v in zip(self.params, self.initial, strict=True):
            if not v > 0:
                raise V.fail(
                    "params",
                    p.name,
                    f"{p.name} is {v:g} in design {design.name!r}: give a starting value > 0 "
                    "in [pcc] (the fit works on its logarithm)",
                )
        self.threads = threads
        self.dt = _seconds(dt, "dt")
        self.markers = marker_sites(dataset)
        self.pressures = np.ascontiguousarray(dataset.pressures, dtype=float)
        self.m = len(dataset)
        kinds = _kinds(dataset, experiments, dynamic)
        self.dynamic = any(k == "dynamic" for k in kinds.values())
        labels = dataset.experiment
        static = np.zeros(self.m, dtype=bool)
        self.runs: list[np.ndarray] = []
        if self.dynamic:
            if dataset.time is None:
                raise V.fail(
                    "dataset.time", None, "time series (dynamic experiments) need a time column"
                )
            all_runs = experiment_rows(dataset) if labels is not None else [np.arange(self.m)]
            ids = dataset.experiments or (None,)
            for e, rows in zip(ids, all_runs, strict=True):
                if kinds[e] == "dynamic":
                    self.runs.append(rows)
        for e, kind in kinds.items():
            if kind == "static":
                static |= np.ones(self.m, dtype=bool) if e is None else labels == e
        self.static_rows = np.flatnonzero(static)
        self.time = dataset.time
        self.x0 = np.full((self.m, 0), np.nan)
        # The core checks the parameters against the design once.
        self._model(self.initial).statics_sensitivity(
            np.zeros((0, design.n_channels)), [p.name for p in self.params]
        )

    def _value(self, p: PccParameter) -> float:
        from ...pcc.model import pcc_parameters

        chambered = {s["name"] for s in self.design.spec["sections"] if s.get("chambers")}
        seg = next((s for s in pcc_parameters(self.design) if s["name"] in chambered), None)
        if seg is None:
            raise V.fail("design.sections", "no chambers", "the PCC parameters act on chambers")
        value = seg[p.kind]
        if p.kind == "k_theta":
            table = isinstance(value, (tuple, list))
            if p.node is None and table:
                raise V.fail(
                    "params",
                    p.name,
                    "the design's k_theta is a table: calibrate its entries k_theta[j]",
                )
            if p.node is not None:
                if not table:
                    raise V.fail(
                        "params", p.name, "the design's k_theta is a constant: calibrate k_theta"
                    )
                stiff = value[1]
                if p.node >= len(stiff):
                    raise V.fail(
                        "params",
                        p.name,
                        f"the k_theta table has {len(stiff)} entries (0..{len(stiff) - 1})",
                    )
                return float(stiff[p.node])
        return float(value)

    def set_threads(self, threads: int) -> None:
        self.threads = threads

    def reset(self) -> None:
        self.evaluations = 0
        self.x0 = np.full((self.m, 0), np.nan)

    def _spec(self, theta) -> dict:
        spec = copy.deepcopy(self.spec)
        pcc = spec["pcc"]
        for p, v in zip(self.params, theta, strict=True):
            if p.node is not None:
                if "k_theta_table" not in pcc:
                    seg = self._table()
                    pcc["k_theta_table"] = {"angle": list(seg[0]), "stiffness": list(seg[1])}
                    pcc.pop("k_theta", None)
                pcc["k_theta_table"]["stiffness"][p.node] = float(v)
            else:
                key = PCC_KINDS[p.kind][0]
                if key == "k_theta":
                    pcc.pop("k_theta_table", None)
                pcc[key] = float(v)
        return spec

    def _table(self):
        from ...pcc.model import pcc_parameters

        chambered = {s["name"] for s in self.design.spec["sections"] if s.get("chambers")}
        seg = next(s for s in pcc_parameters(self.design) if s["name"] in chambered)
        return seg["k_theta"]

    def _model(self, theta) -> _core.PccModel:
        return _core.PccModel(json.dumps(self._spec(theta)))

    def predict(self, theta, rows, jacobian: bool) -> Prediction:
        n_par = len(self.params)
        out = Prediction.empty(self.m, n_par, len(self.markers), jacobian)
        self.evaluations += 1
        try:
            model = self._model(theta)
        except DesignError:
            return out
        names = [p.name for p in self.params]
        wanted = np.zeros(self.m, dtype=bool)
        wanted[rows] = True
        st = self.static_rows[wanted[self.static_rows]]
        if st.size:
            if self.x0.shape[1] != model.ndof:
                self.x0 = np.full((self.m, model.ndof), np.nan)
            res = model.statics_sensitivity(
                self.pressures[st],
                names,
                markers=self.markers,
                guesses=np.ascontiguousarray(self.x0[st]),
                threads=self.threads,
            )
            self._store(out, st, res["points"], res["d_points"], res["converged"], jacobian)
            good = st[res["converged"]]
            self.x0[good] = res["x"][res["converged"]]
        runs = [r for r in self.runs if wanted[r].any()]
        if runs:
            commands = [self._commands(r) for r in runs]
            results = model.runs_sensitivity(
                [(c, "static", _save_every(t, self.dt)) for c, t in commands],
                self.dt,
                names,
                markers=self.markers,
                threads=self.threads,
            )
            for r, (_, t), res in zip(runs, commands, results, strict=True):
                if res["error"]:
                    continue
                pts, dpts = _at_times(res["time"], res["points"], res["d_points"], t)
                self._store(out, r, pts, dpts, np.ones(r.size, dtype=bool), jacobian)
        return out

    def _commands(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(commands at every step of dt, sample times from the experiment's start)."""
        t = self.time[rows] - self.time[rows[0]]
        n = int(np.ceil(t[-1] / self.dt * (1.0 - 1e-12)))
        steps = np.minimum(np.arange(n + 1) * self.dt, t[-1])
        p = self.pressures[rows]
        commands = np.column_stack([np.interp(steps, t, p[:, k]) for k in range(p.shape[1])])
        return np.ascontiguousarray(commands), t

    def _store(self, out: Prediction, idx, points, d_points, ok, jacobian: bool) -> None:
        out.tip[idx] = points[:, 0]
        out.ok[idx] = ok
        if out.markers is not None:
            out.markers[idx] = points[:, 1:]
        if jacobian:
            out.d_tip[idx] = d_points[:, 0]
            if out.d_markers is not None:
                out.d_markers[idx] = d_points[:, 1:]

    def calibrated_design(self, theta) -> Design:
        changes = {}
        table = None
        for p, v in zip(self.params, theta, strict=True):
            if p.node is not None:
                if table is None:
                    angles, stiff = self._table()
                    table = [list(angles), list(stiff)]
                table[1][p.node] = float(v)
            else:
                changes[f"pcc.{p.kind}"] = f"{float(v)!r} {p.unit}"
        if table is not None:
            changes["pcc.k_theta"] = {
                "angle": [si_text(a, "angle") for a in table[0]],
                "stiffness": [si_text(k, "moment") for k in table[1]],
            }
        return self.design.replace(changes)

    def reference(self, calibrated: Design, theta) -> Prediction:
        """The unpressurised equilibrium's positions, for every row."""
        model = self._model(theta)
        res = model.statics_sensitivity(
            np.zeros((1, calibrated.n_channels)), [], markers=self.markers
        )
        out = Prediction.empty(self.m, 0, len(self.markers), False)
        out.tip[:] = res["points"][0, 0]
        if out.markers is not None:
            out.markers[:] = res["points"][0, 1:]
        out.ok[:] = bool(res["converged"][0])
        return out

    def base_frame(self):
        mount = self.design.spec["mounting"]
        return (
            np.asarray(mount["base_position"], dtype=float),
            np.asarray(mount["base_rotation"], dtype=float)[:, 2],
        )

    def __getstate__(self):
        from ...cluster import design_text

        state = dict(self.__dict__)
        state["design"] = design_text(self.design)
        return state

    def __setstate__(self, state):
        from ...cluster import design_from_text

        state["design"] = design_from_text(state["design"])
        self.__dict__.update(state)


def _save_every(t: np.ndarray, dt: float) -> int:
    """The largest step count k such that every sample time is a multiple of k dt (so the
    run keeps only those steps), 1 when some sample falls between steps."""
    steps = t / dt
    k = np.rint(steps)
    if np.any(np.abs(steps - k) > 1e-9 * np.maximum(1.0, steps)):
        return 1
    return max(int(np.gcd.reduce(k.astype(np.int64))), 1)


def _at_times(steps_t, points, d_points, t):
    """Points (and derivatives) at the sample times ``t`` by linear interpolation in time
    between the simulated steps (exact at samples that fall on steps)."""
    idx = np.clip(np.searchsorted(steps_t, t, side="right") - 1, 0, len(steps_t) - 2)
    span = steps_t[idx + 1] - steps_t[idx]
    w = np.clip((t - steps_t[idx]) / span, 0.0, 1.0)
    # A sample on a step (to round-off) is read at that step.
    w = np.where(np.isclose(w, 0.0, atol=1e-9), 0.0, w)
    w = np.where(np.isclose(w, 1.0, atol=1e-9), 1.0, w)
    pts = points[idx] * (1 - w)[:, None, None] + points[idx + 1] * w[:, None, None]
    dp = d_points[idx] * (1 - w)[:, None, None, None] + d_points[idx + 1] * w[:, None, None, None]
    return pts, dp
