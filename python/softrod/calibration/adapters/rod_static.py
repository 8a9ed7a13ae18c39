"""Cosserat-rod equilibria on a dataset: the tip and the markers of every row, with their
exact parameter derivatives (dual numbers through the shooting solve and the implicit
function theorem, ``Rod.sensitivity_batch``; every evaluation is one parallel batch over
the requested rows, GIL released). A design whose ``[tip]`` pins or clamps the tip is
solved and differentiated with the tip held (the held residual's sensitivities), and the
wrench its constraint applies to the tip (the blocked force) is predicted with its exact
derivatives too."""

from __future__ import annotations

import numpy as np

from ... import _validate as V
from ...constraints import held_kwargs
from ...design import Design
from ...errors import DesignError
from ...statics import _options
from ..params import SIGMA_KINDS, Parameter, design_changes
from ..problem import ModelAdapter, Prediction

#: Mounting labels a dataset may carry per row (paper 002 fits vertical and horizontal
#: experiments together).
ORIENTATIONS = ("hanging", "upright", "horizontal")


def mounting_groups(design: Design, dataset) -> list[tuple[dict, np.ndarray]]:
    """(document changes for the mounting, row indices) per mounting label."""
    m = len(dataset)
    if dataset.mounting is None:
        return [({}, np.arange(m))]
    labels = list(dict.fromkeys(dataset.mounting.tolist()))
    if len(labels) == 1:  # one mounting: the design is mounted as the data were
        return [({}, np.arange(m))]
    if design.tip_constraint is not None:
        raise V.fail(
            "dataset.mounting",
            labels,
            f"the design's [tip] constraint ({design.tip_constraint.kind}) holds the tip at "
            "one world pose, which another mounting of the base would not share: fit each "
            "mounting separately, with its own held pose",
        )
    out = []
    for label in labels:
        if label not in ORIENTATIONS:
            raise V.fail(
                "dataset.mounting",
                label,
                f"with several mountings each must be one of {', '.join(ORIENTATIONS)}",
            )
        if "base_rotation" in design.document.get("mounting", {}):
            raise V.fail(
                "design.mounting.base_rotation",
                "given",
                "mounting labels set the orientation; use mounting.orientation instead",
            )
        out.append(({"mounting.orientation": label}, np.flatnonzero(dataset.mounting == label)))
    return out


def marker_sites(dataset) -> list[tuple[float, list[float]]]:
    """The core's (s, offset) of every marker of ``dataset`` (empty without markers)."""
    if dataset.markers is None:
        return []
    return [
        (float(s), [float(v) for v in o])
        for s, o in zip(dataset.marker_s, dataset.marker_offset, strict=True)
    ]


class RodStatic(ModelAdapter):
    """Tip and marker positions of the dataset's equilibria (and a held tip's reaction) and
    their parameter derivatives."""

    model = "cosserat"
    dynamic = False

    def __init__(self, design: Design, dataset, params: list[Parameter], options, threads: int):
        super().__init__()
        self.design = design
        self.params = list(params)
        self.parameters = tuple(params)
        self.initial = np.array([p.value(design) for p in params])
        self.groups = mounting_groups(design, dataset)
        self.p = np.ascontiguousarray(dataset.pressures, dtype=float)
        # Tendon tensions of each sample (N), None: every tendon slack.
        self.t = None if dataset.tensions is None else np.asarray(dataset.tensions, dtype=float)
        self.options = options
        self.opts = _options(options).as_kwargs()
        self.threads = threads
        self.markers = marker_sites(dataset)
        self.m = len(dataset)
        # A held tip ([tip] constraint, pinned or clamped): every solve and derivative is the
        # held equilibrium's (``Rod.sensitivity_batch(..., tip_kind=...)``).
        self.held = held_kwargs(design.tip_constraint)
        # Warm starts: the shooting unknowns of each row's last solve (NaN: cold), sized by
        # the first solve's: 3 (base moment) or 6 (base force too: obstacles, followers).
        self.x0: np.ndarray | None = None
        self.sigma_index = {
            j: SIGMA_KINDS.index(p.kind) for j, p in enumerate(params) if p.kind in SIGMA_KINDS
        }

    # --- pickling for Dask workers: the design travels as TOML text -------------------------

    def __getstate__(self):
        from ...cluster import design_text

        state = dict(self.__dict__)
        state["design"] = design_text(self.design)
        return state

    def __setstate__(self, state):
        from ...cluster import design_from_text

        state["design"] = design_from_text(state["design"])
        self.__dict__.update(state)

    def set_threads(self, threads: int) -> None:
        self.threads = threads

    def reset(self) -> None:
        self.evaluations = 0
        self.x0 = None

    # ------------------------------------------------------------------------------------------

    def designs(self, theta) -> list[Design]:
        changes = design_changes(self.params, theta, self.design)
        return [self.design.replace({**changes, **g}) for g, _ in self.groups]

    def sigma(self, theta, idx: np.ndarray) -> np.ndarray | None:
        """sigma of the rows ``idx``: the fitted constant one, the design's stiffness map
        (``[stiffness_map] file``), or None (no mapped sections)."""
        if not self.sigma_index:
            smap = self.design.stiffness_map
            return None if smap is None else np.ascontiguousarray(smap(self.p[idx]))
        s = np.ones(3)
        for j, k in self.sigma_index.items():
            s[k] = theta[j]
        return np.tile(s, (idx.size, 1))

    def predict(self, theta, rows, jacobian: bool) -> Prediction:
        m, n_par = len(self.p), len(self.params)
        out = Prediction.empty(m, n_par, len(self.markers), jacobian, bool(self.held))
        self.evaluations += 1
        try:
            designs = self.designs(theta)
        except DesignError:
            # A trial point outside what a design allows (e.g. a stiffness that is no longer
            # positive definite): every sample fails, so the optimiser steps back.
            return out
        for d, (_, idx) in zip(designs, self.groups, strict=True):
            idx = idx[np.isin(idx, rows)]
            if idx.size == 0:
                continue
            tip_f = d.spec["tip"]["force"]
            tip_m = d.spec["tip"]["moment"]
            kw = dict(stiffness_scale=self.sigma(theta, idx), threads=self.threads, **self.opts)
            if self.t is not None:
                kw["tensions"] = np.ascontiguousarray(self.t[idx])
            if jacobian or self.markers or self.held:
                res = d._rod.sensitivity_batch(
                    self.p[idx],
                    tip_f,
                    tip_m,
                    [p.core() for p in self.params] if jacobian else [],
                    x0=None if self.x0 is None else np.ascontiguousarray(self.x0[idx]),
                    markers=self.markers,
                    **kw,
                    **self.held,
                )
            else:
                res = d._rod.solve_batch(self.p[idx], tip_f, tip_m, **kw)
            if jacobian:
                derivatives = ["d_tip_position", "d_marker_position"]
                if self.held:
                    derivatives += ["d_tip_reaction_force", "d_tip_reaction_moment"]
                for j, p in enumerate(self.params):
                    if p.kind == "area_scale":
                        # The core differentiates by a factor on the current areas, which
                        # are theta_j times the design's: d/d theta_j = (1/theta_j) d/dk.
                        for key in derivatives:
                            res[key][..., j] /= theta[j]
                out.d_tip[idx] = res["d_tip_position"]
                if out.d_markers is not None:
                    out.d_markers[idx] = res["d_marker_position"]
                if self.held:
                    out.d_reaction[idx] = res["d_tip_reaction_force"]
                    out.d_reaction_moment[idx] = res["d_tip_reaction_moment"]
            out.tip[idx] = res["tip_position"]
            if out.markers is not None:
                out.markers[idx] = res["marker_position"]
            if self.held:
                out.reaction[idx] = res["tip_reaction_force"]
                out.reaction_moment[idx] = res["tip_reaction_moment"]
            out.ok[idx] = res["converged"]
            if self.x0 is None:
                self.x0 = np.full((self.m, res["x"].shape[1]), np.nan)
            good = idx[res["converged"]]
            self.x0[good] = res["x"][res["converged"]]
        return out

    def calibrated_design(self, theta) -> Design:
        return self.design.replace(design_changes(self.params, theta, self.design))

    def final_prediction(self, calibrated: Design, theta, rows) -> Prediction:
        """The positions with the calibrated design itself (only the per-solve sigma factors
        remain parameters), so that the written design reproduces them."""
        sigma = [p for p in self.params if p.kind in SIGMA_KINDS]
        clone = object.__new__(RodStatic)
        clone.__dict__.update(self.__dict__)
        clone.design = calibrated
        clone.params = sigma
        clone.parameters = tuple(sigma)
        clone.sigma_index = {j: SIGMA_KINDS.index(p.kind) for j, p in enumerate(sigma)}
        clone.x0 = None
        values = np.array([theta[self.params.index(p)] for p in sigma])
        return clone.predict(values, rows, False)

    def reference(self, design: Design, theta) -> Prediction:
        """The model's unpressurised tip (and markers) of every row's mounting, with the
        fitted constant sigma where sigma factors are parameters (the calibrated design
        maps its sections but carries no map)."""
        out = Prediction.empty(len(self.p), 0, len(self.markers), False)
        sigma = self.sigma(theta, np.arange(1))[0] if self.sigma_index else None
        for changes, idx in self.groups:
            d = design.replace(changes) if changes else design
            rest = rest_prediction(d, self.markers, 1, self.options, sigma=sigma)
            out.tip[idx] = rest.tip[0]
            if out.markers is not None:
                out.markers[idx] = rest.markers[0]
            out.ok[idx] = rest.ok[0]
        return out

    def base_frame(self):
        if len(self.groups) > 1:
            return None
        mount = self.design.spec["mounting"]
        return (
            np.asarray(mount["base_position"], dtype=float),
            np.asarray(mount["base_rotation"], dtype=float)[:, 2],
        )


def rest_prediction(
    design: Design, markers, m: int, options=None, sigma: np.ndarray | None = None
) -> Prediction:
    """The unpressurised equilibrium's tip and markers (the core's (s, offset) pairs) of
    ``design`` (its tip loads and constraint, slack tendons, and ``sigma`` (3,) or else its
    stiffness map at zero pressure), repeated for ``m`` rows."""
    out = Prediction.empty(m, 0, len(markers), False)
    zero = np.zeros((1, design.n_channels))
    smap = design.stiffness_map
    if sigma is None and smap is not None:
        sigma = smap(zero)[0]
    res = design._rod.sensitivity_batch(
        zero,
        design.spec["tip"]["force"],
        design.spec["tip"]["moment"],
        [],
        stiffness_scale=None if sigma is None else np.ascontiguousarray([sigma], dtype=float),
        markers=markers,
        # Slack tendons (zero tension), given explicitly: a rod without chambers counts
        # its batch rows by its tension rows.
        tensions=np.zeros((1, design.n_tendons)) if design.n_tendons else None,
        **_options(options).as_kwargs(),
        **held_kwargs(design.tip_constraint),
    )
    out.tip[:] = res["tip_position"][0]
    if out.markers is not None:
        out.markers[:] = res["marker_position"][0]
    out.ok[:] = bool(res["converged"][0])
    return out
