"""The hybrid model of paper 001 (Sec. III-C, eqs. 23-25, Table II; Sec. V-B/C, Fig. 7).

The stiffness factors identified per sample (:func:`~softrod.calibration.per_sample.
identify_stiffness`) are learned as functions of the chamber pressures, one neural network
per factor: sigma_ext = f_ext(p), sigma_bend_x = f_x(p), sigma_bend_y = f_y(p). The Cosserat
model with these learned factors is the hybrid model.

Networks (Table II): inputs the c chamber pressures, two hidden layers of 45 and 50 tanh
neurons, one linear output. Paper 001 trains them with Levenberg-Marquardt and Bayesian
regularisation (MATLAB); scikit-learn has neither, so each network here is an
``MLPRegressor`` trained with L-BFGS and an L2 weight penalty ``alpha`` (the regularisation
the Bayesian scheme sets automatically is fixed by hand), with standardised inputs and a
standardised log sigma as target: sigma = exp(net(p)) is positive everywhere (a tanh network
is bounded, so it is finite too), which :class:`~softrod.StiffnessMap` requires.

The samples are split 80/20 (Sec. V-B) once, over all samples. Each network trains on the
training samples at which its factor was identified; the test samples are held out from the
networks and from the constant-stiffness fit. :func:`compare_hybrid` evaluates the models
on all test samples, including those where the identification found no factor (Sec. V-C).
"""

from __future__ import annotations

import json
import logging
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .. import _validate as V
from .._threads import one_blas_thread
from ..catalog import load_design
from ..constraints import require_free_tip
from ..datasets import Dataset
from ..errors import InputError, design_error
from ..statics import SolverOptions, solve_statics_batch
from ..stiffness_map import SIGMA_NAMES, StiffnessMap
from .fit import calibrate
from .metrics import tip_error_table
from .per_sample import (
    StiffnessIdentification,
    _check_dataset,
    _readonly,
    stiffness_mapped_design,
)

if TYPE_CHECKING:
    from .._types import ArrayLike, DesignLike, PathLike, Progress
    from ..design import Design

__all__ = ["HybridStiffnessModel", "compare_hybrid", "fit_stiffness_map"]

logger = logging.getLogger(__name__)

# A network needs at least this many identified training samples of its factor: below it a
# 3-45-50-1 network (about 2,600 weights) is not even constrained in shape by the data.
MIN_TRAINING_SAMPLES = 10
# Largest networks accepted: far above paper 001's 45-50 (a few layers of thousands of neurons
# train for hours), small enough that a typo (10**9 neurons) is refused, not allocated.
MAX_LAYERS = 16
MAX_NEURONS = 10_000
# Default L2 penalty of the networks (scikit-learn's alpha, on standardised data; scikit-learn
# divides it by the number of samples, so it weakens as the data grow). Chosen on synthetic
# data (216-9261 samples, 0.1-0.3 mm noise): alpha <= 0.3 fits the noise of the identified
# factors (test RMSE 2-10x the training RMSE, thousands of L-BFGS iterations), 1-3 follow the
# true sigma(p) to within a few 1e-3.
DEFAULT_ALPHA = 1.0
# L-BFGS iterations per network. A network that stops here is reported (``converged`` in
# the training table) and a RuntimeWarning names it.
DEFAULT_MAX_ITER = 3000
# calibrate()'s names of the three factors: the constant-stiffness fit of compare_hybrid.
_CONSTANT_PARAMS = ("sigma_ext", "sigma_bend_1", "sigma_bend_2")


def _network(hidden, activation, alpha, max_iter, seed):
    """One factor's regressor: standardised pressures -> MLP -> standardised log sigma."""
    from sklearn.compose import TransformedTargetRegressor
    from sklearn.neural_network import MLPRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import FunctionTransformer, StandardScaler

    net = MLPRegressor(
        hidden_layer_sizes=hidden,
        activation=activation,
        solver="lbfgs",
        alpha=alpha,
        max_iter=max_iter,
        random_state=seed,
    )
    return TransformedTargetRegressor(
        regressor=make_pipeline(StandardScaler(), net),
        transformer=make_pipeline(
            FunctionTransformer(np.log, inverse_func=np.exp, validate=False), StandardScaler()
        ),
    )


class _SavedNetwork:
    """A network read from a file: ``predict(P)`` (pressures in Pa) with numpy, as the
    scikit-learn model it was saved from."""

    def __init__(self, arrays: dict):
        self.arrays = arrays

    def predict(self, pressures) -> np.ndarray:
        from ..stiffness_map import _forward

        return _forward(self.arrays, np.asarray(pressures, dtype=float))


def _arrays(net) -> dict:
    """A fitted network's numbers (scikit-learn objects -> arrays, see
    :meth:`StiffnessMap.from_networks`)."""
    if isinstance(net, _SavedNetwork):
        return net.arrays
    scaler, mlp = net.regressor_[0], net.regressor_[-1]
    target = net.transformer_[-1]
    if mlp.out_activation_ != "identity":  # pragma: no cover - MLPRegressor's output is linear
        raise design_error("nets", mlp.out_activation_, "the output layer must be linear")
    return {
        "input_mean": np.asarray(scaler.mean_, dtype=float),
        "input_scale": np.asarray(scaler.scale_, dtype=float),
        "weights": [np.asarray(w, dtype=float) for w in mlp.coefs_],
        "biases": [np.asarray(b, dtype=float) for b in mlp.intercepts_],
        "activation": mlp.activation,
        "target_mean": float(target.mean_[0]),
        "target_scale": float(target.scale_[0]),
    }


@dataclass(frozen=True, eq=False)
class HybridStiffnessModel:
    """Three trained networks sigma_k(p) (paper 001 eqs. 23-25) and how they were trained.

    nets: the fitted regressors (sigma_ext, sigma_bend_x, sigma_bend_y), each mapping
        pressures in Pa (m, c) to sigma_k (m,).
    identification: the :class:`StiffnessIdentification` they learned from (None for a model
        read with :meth:`load`: the file keeps the networks, not the data).
    train_rows, test_rows: sample indices of the 80/20 split (over all samples).
    training: per factor: samples used (identified ones), train/test RMSE of sigma (and of
        log sigma), L-BFGS iterations and whether it converged.
    settings: hidden layers, activation, alpha, test fraction, seed, max_iter.
    saved: for a loaded model, the design and sections the file records.

    :meth:`save` writes the networks as arrays in a versioned JSON file (no pickle), which is
    also a stiffness map file: ``StiffnessMap.load(path)``, or ``[stiffness_map] file = ...``
    in a design.
    """

    nets: tuple
    identification: StiffnessIdentification | None
    train_rows: np.ndarray
    test_rows: np.ndarray
    training: pd.DataFrame
    settings: dict = field(default_factory=dict)
    wall_time_s: float = float("nan")
    saved: dict = field(default_factory=dict, repr=False)

    def __repr__(self) -> str:
        test = ", ".join(
            f"{r.factor} {r.rmse_test:.3g}" for r in self.training.itertuples(index=False)
        )
        return (
            f"HybridStiffnessModel({len(self.nets)} nets {self.settings.get('hidden')}, "
            f"design {self.design.name!r}; test RMSE of sigma: {test})"
        )

    @property
    def design(self) -> Design:
        """The design with the mapped sections (as identified)."""
        if self.identification is None:
            return self.saved["design"]
        return self.identification.design

    @property
    def sections(self) -> tuple[str, ...]:
        """The sections sigma scales."""
        if self.identification is None:
            return tuple(self.saved["sections"])
        return tuple(self.identification.sections)

    @property
    def n_channels(self) -> int:
        if self.identification is None:
            return self.design.n_channels
        return self.identification.dataset.n_channels

    def predict(self, pressures: ArrayLike) -> np.ndarray:
        """sigma (m, 3) at gauge pressures (m, c) in Pa; every entry finite and > 0."""
        p = V.real_array(pressures, "pressures", what="gauge pressures (Pa)")
        if p.ndim != 2 or p.shape[1] != self.n_channels:
            raise design_error(
                "pressures",
                f"shape {p.shape}",
                f"must be an (m, {self.n_channels}) array of gauge pressures (Pa)",
                InputError,
            )
        if p.shape[0] == 0:
            return np.empty((0, 3))
        return np.column_stack([np.asarray(net.predict(p)).reshape(-1) for net in self.nets])

    def networks(self) -> list[dict]:
        """The three networks as arrays (see :meth:`StiffnessMap.from_networks`)."""
        return [_arrays(net) for net in self.nets]

    @property
    def stiffness_map(self) -> StiffnessMap:
        """The networks as a :class:`~softrod.StiffnessMap` (pressures in Pa), for
        ``solve_statics(self.design, p, stiffness_map=...)``. It evaluates the networks'
        arrays with numpy (the same operations as scikit-learn) and can be saved."""
        return StiffnessMap.from_networks(self.networks())

    def save(self, path: PathLike) -> Path:
        """Write the model as JSON (whole or not at all): the stiffness map of
        :meth:`StiffnessMap.save` (format "softrod.stiffness_map", kind "mlp", versioned)
        plus a ``hybrid`` block with the settings, the training table, the split, the design
        and its mapped sections. No pickle: the file holds numbers and text only, and
        :meth:`load` reads it back without scikit-learn. Returns the path."""
        from ..io import metadata_json
        from ..schema import provenance
        from ..stiffness_map import _write_json

        doc = self.stiffness_map._document()
        design = self.design
        doc["hybrid"] = {
            "design": _design_document(design),
            "sections": list(self.sections),
            "settings": {
                k: list(v) if isinstance(v, tuple) else v for k, v in self.settings.items()
            },
            "training": _records(self.training),
            "train_rows": self.train_rows.tolist(),
            "test_rows": self.test_rows.tolist(),
            "wall_time_s": self.wall_time_s,
        }
        ident = self.identification
        meta = provenance("softrod.fit_stiffness_map", design)
        if ident is not None:
            source = ident.dataset.source
            meta["dataset"] = None if source is None else source.name
            meta["synthetic"] = ident.dataset.synthetic
        elif "metadata" in self.saved:
            meta = dict(self.saved["metadata"])
        doc["metadata"] = json.loads(metadata_json(meta))
        return _write_json(doc, path)

    @classmethod
    def load(cls, path: PathLike) -> HybridStiffnessModel:
        """Read a model written by :meth:`save`. Its networks predict with numpy; it has no
        ``identification`` (``compare_hybrid`` needs the fitted model)."""
        from ..design import read_design
        from ..stiffness_map import read_map_document

        doc = read_map_document(path)
        hybrid = doc.get("hybrid")
        if doc.get("kind") != "mlp" or not isinstance(hybrid, dict):
            raise design_error(
                "path",
                str(path),
                "is a stiffness map but not a hybrid model (load it with StiffnessMap.load)",
                InputError,
            )
        smap = StiffnessMap.from_networks(doc["networks"])
        design = read_design(hybrid["design"])
        settings = dict(hybrid.get("settings", {}))
        if "hidden" in settings:
            settings["hidden"] = tuple(settings["hidden"])
        return cls(
            nets=tuple(_SavedNetwork(net) for net in smap._data["networks"]),
            identification=None,
            train_rows=_readonly(np.asarray(hybrid.get("train_rows", []), dtype=np.int64)),
            test_rows=_readonly(np.asarray(hybrid.get("test_rows", []), dtype=np.int64)),
            training=pd.DataFrame(hybrid.get("training", [])).fillna(np.nan),
            settings=settings,
            wall_time_s=float(hybrid.get("wall_time_s", float("nan"))),
            saved={
                "design": design,
                "sections": list(hybrid.get("sections", [])),
                "metadata": doc.get("metadata", {}),
                "source": str(path),
            },
        )


def _records(frame: pd.DataFrame) -> list[dict]:
    """A table as JSON records, every number exact (NaN as null)."""
    out = []
    for row in frame.to_dict(orient="records"):
        clean = {}
        for key, value in row.items():
            if isinstance(value, np.generic):
                value = value.item()
            clean[key] = None if isinstance(value, float) and np.isnan(value) else value
        out.append(clean)
    return out


def _design_document(design) -> dict:
    """A design's document with units on every value, as JSON values; a mesh obstacle's
    file by its absolute path (the model file may be read from another folder)."""
    from ..design import _plain, _with_units

    doc = json.loads(json.dumps(_with_units(_plain(design.document))))
    for k, file in design.mesh_sources:
        doc["obstacles"][k]["file"] = str(file)
    return doc


def _split(m: int, test_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    order = np.random.default_rng(seed).permutation(m)
    n_test = int(round(test_fraction * m))
    return np.sort(order[n_test:]), np.sort(order[:n_test])


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2))) if a.size else float("nan")


@one_blas_thread
def fit_stiffness_map(
    identification: StiffnessIdentification,
    *,
    hidden: Sequence[int] = (45, 50),
    activation: str = "tanh",
    alpha: float = DEFAULT_ALPHA,
    test_fraction: float = 0.2,
    seed: int = 0,
    max_iter: int = DEFAULT_MAX_ITER,
    progress: Progress = None,
) -> HybridStiffnessModel:
    """Train one network per factor on the identified samples (paper 001 Sec. III-C, V-B).

    hidden: neurons per hidden layer (Table II: 45, 50); activation: "tanh" (Table II),
    "relu" or "logistic". alpha: L2 weight penalty (scikit-learn's; stands in for the
    Bayesian regularisation of Table II). test_fraction: share of all samples held out
    (Table II: 20 %). seed: the split and the networks' initial weights. max_iter: L-BFGS
    iterations per network. progress: see :mod:`softrod.progress`; a callable gets
    ``progress(networks_done, 3)``.

    Reproducible: the same identification and seed give the same networks, bit for bit,
    whatever the BLAS thread settings (the fit runs BLAS on one thread, :mod:`softrod._threads`).

    Raises :class:`~softrod.errors.InputError` when a factor has fewer than
    :data:`MIN_TRAINING_SAMPLES` identified training samples.
    """
    t0 = time.perf_counter()
    if not isinstance(identification, StiffnessIdentification):
        raise design_error(
            "identification",
            type(identification).__name__,
            "must be the result of identify_stiffness",
            InputError,
        )
    if not isinstance(hidden, (list, tuple)) or not 1 <= len(hidden) <= MAX_LAYERS:
        raise design_error(
            "hidden",
            hidden,
            f"must be a list of 1 to {MAX_LAYERS} neuron counts, one per hidden layer",
            InputError,
        )
    hidden = tuple(
        V.integer(h, f"hidden[{i}]", minimum=1, maximum=MAX_NEURONS) for i, h in enumerate(hidden)
    )
    if not (isinstance(activation, str) and activation in ("tanh", "relu", "logistic")):
        raise design_error(
            "activation",
            activation,
            "must be 'tanh' (paper 001), 'relu' or 'logistic'",
            InputError,
        )
    alpha = V.real(alpha, "alpha", minimum=0.0)
    if isinstance(test_fraction, bool) or not (
        isinstance(test_fraction, (int, float)) and 0 <= test_fraction < 1
    ):
        raise design_error("test_fraction", test_fraction, "must lie in [0, 1)", InputError)
    # scikit-learn's random_state is a 32-bit seed; network k is seeded with seed + k.
    seed = V.integer(seed, "seed", minimum=0, maximum=2**32 - 1 - len(SIGMA_NAMES))
    max_iter = V.integer(max_iter, "max_iter", minimum=1)

    from ..progress import check_progress, reporter

    check_progress(progress)
    ident = identification
    p = np.asarray(ident.dataset.pressures, dtype=float)
    train_rows, test_rows = _split(len(ident), float(test_fraction), int(seed))
    with reporter(
        progress, "fit_stiffness_map", 3, lambda done, total: (done, f"{done}/{total} networks")
    ) as report:
        nets, rows = _train(
            ident, p, train_rows, test_rows, hidden, activation, alpha, max_iter, seed, report
        )
    return HybridStiffnessModel(
        nets=tuple(nets),
        identification=ident,
        train_rows=_readonly(train_rows),
        test_rows=_readonly(test_rows),
        training=pd.DataFrame(rows),
        settings={
            "hidden": hidden,
            "activation": activation,
            "alpha": float(alpha),
            "test_fraction": float(test_fraction),
            "seed": int(seed),
            "max_iter": int(max_iter),
            "target": "standardised log sigma",
            "solver": "lbfgs",
        },
        wall_time_s=time.perf_counter() - t0,
    )


def _train(ident, p, train_rows, test_rows, hidden, activation, alpha, max_iter, seed, report):
    """The three networks and their training table (fit_stiffness_map's loop)."""
    from sklearn.exceptions import ConvergenceWarning

    nets, rows = [], []
    for k, name in enumerate(SIGMA_NAMES):
        ok = ident.identifiable[:, k]
        tr = train_rows[ok[train_rows]]
        te = test_rows[ok[test_rows]]
        if tr.size < MIN_TRAINING_SAMPLES:
            raise design_error(
                f"identification.{name}",
                f"{tr.size} identified training samples",
                f"a network needs at least {MIN_TRAINING_SAMPLES}: identify more samples or "
                "lower min_sensitivity",
                InputError,
            )
        net = _network(hidden, activation, float(alpha), int(max_iter), int(seed) + k)
        # lbfgs reports hitting max_iter as a ConvergenceWarning: record it for this net.
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            net.fit(p[tr], ident.sigma[tr, k])
        stopped = [w for w in caught if issubclass(w.category, ConvergenceWarning)]
        for w in caught:
            if not issubclass(w.category, ConvergenceWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        mlp = net.regressor_[-1]
        if stopped:
            warnings.warn(
                f"the network for {name} stopped after max_iter = {max_iter} L-BFGS "
                "iterations without converging; its RMSE is in the training table (raise "
                "max_iter or alpha)",
                RuntimeWarning,
                stacklevel=4,  # the caller of fit_stiffness_map (via the BLAS-thread wrapper)
            )
        fit_tr, fit_te = net.predict(p[tr]), net.predict(p[te]) if te.size else np.empty(0)
        s_tr, s_te = ident.sigma[tr, k], ident.sigma[te, k]
        rows.append(
            {
                "factor": name,
                "n_train": int(tr.size),
                "n_test": int(te.size),
                "rmse_train": _rmse(fit_tr, s_tr),
                "rmse_test": _rmse(fit_te, s_te),
                "rmse_log_train": _rmse(np.log(fit_tr), np.log(s_tr)),
                "rmse_log_test": _rmse(np.log(fit_te), np.log(s_te)),
                "iterations": int(mlp.n_iter_),
                "converged": not stopped,
            }
        )
        nets.append(net)
        logger.info(
            "fit_stiffness_map: network %s, %d iterations, test RMSE %.3g",
            name,
            int(mlp.n_iter_),
            rows[-1]["rmse_test"],
        )
        if report is not None:
            report(k + 1, 3)
    return nets, rows


def _rows(rows, hybrid: HybridStiffnessModel, dataset: Dataset) -> np.ndarray:
    ident = hybrid.identification.dataset
    if rows is None:
        same = len(dataset) == len(ident) and np.array_equal(dataset.pressures, ident.pressures)
        return hybrid.test_rows if same else np.arange(len(dataset))
    idx = np.asarray(rows)
    if idx.dtype == bool and idx.shape == (len(dataset),):
        return np.flatnonzero(idx)
    if idx.ndim != 1 or not np.issubdtype(idx.dtype, np.integer) or idx.size == 0:
        raise design_error(
            "rows",
            rows,
            "must be a boolean mask or a non-empty list of sample indices",
            InputError,
        )
    if idx.min() < 0 or idx.max() >= len(dataset):
        raise design_error(
            "rows",
            f"{idx.min()}..{idx.max()}",
            f"indices must lie in [0, {len(dataset)})",
            InputError,
        )
    return idx


def compare_hybrid(
    design: DesignLike,
    dataset: Dataset,
    hybrid: HybridStiffnessModel,
    *,
    rows: ArrayLike | None = None,
    literature: ArrayLike | None = None,
    constant: str | ArrayLike | None = "fit",
    options: SolverOptions | None = None,
    threads: int = 0,
) -> pd.DataFrame:
    """Tip errors of the hybrid model against the literature model and a constant-stiffness
    fit (paper 001 Sec. V-C, Fig. 7), one :func:`~softrod.calibration.metrics.tip_error_table`
    per model stacked in one DataFrame with a leading ``model`` column.

    design: the design (the hybrid's sections get the stiffness map). dataset: the samples.
    rows: the samples to compare (mask or indices); default the hybrid's held-out test rows
        when ``dataset`` is the identified one, else all rows. Samples where the
        identification found no factor are included; the ``set`` column splits them into
        "identified" (all three factors) and "not identified", then "all".
    literature: the literature model: None for sigma = 1 on ``design`` (its data-sheet
        stiffness), or another design (or name) solved as it is.
    constant: "fit" (default): one sigma fitted to the tip positions of the hybrid's training
        rows (all of them, identified or not); a (3,) sigma; or None to leave it out.

    Errors are measured minus predicted, as in Fig. 7; radial and height are about the
    design's undeformed axis through its base. Failed solves are counted, never dropped.
    """
    require_free_tip(load_design(design), "compare_hybrid")
    if not isinstance(hybrid, HybridStiffnessModel):
        raise design_error(
            "hybrid",
            type(hybrid).__name__,
            "must be the result of fit_stiffness_map",
            InputError,
        )
    if hybrid.identification is None:
        raise design_error(
            "hybrid",
            repr(hybrid),
            "was read from a file and has no identification (its training data and split): "
            "compare the model fitted by fit_stiffness_map",
            InputError,
        )
    mapped, _ = stiffness_mapped_design(design, hybrid.identification.sections)
    rough = mapped.frictional_obstacle
    if rough is not None and isinstance(constant, str) and constant == "fit":
        # The constant-stiffness fit is a calibration, whose solves are frictionless: said
        # here, before the hybrid's and the literature's frictional batches run.
        raise design_error(
            f"obstacles[{rough}].friction",
            mapped.spec["obstacles"][rough]["friction"],
            "constant='fit' calibrates one sigma, and calibration is frictionless (a "
            "frictional equilibrium depends on its load path; docs/contact.md, 'Friction in "
            "the statics'): pass constant=None or a (3,) sigma, or set friction = 0",
            InputError,
        )
    dataset = _check_dataset(dataset, mapped)
    idx = _rows(rows, hybrid, dataset)
    p = np.asarray(dataset.pressures, dtype=float)[idx]
    measured = np.asarray(dataset.require_tip("compare_hybrid"), dtype=float)[idx]
    kwargs = {"options": options, "threads": threads}

    def solve(model_design, smap):
        return solve_statics_batch(model_design, p, stiffness_map=smap, **kwargs).tip_position

    models = [("hybrid", solve(mapped, hybrid.stiffness_map))]
    ones = StiffnessMap.constant((1.0, 1.0, 1.0), mapped.n_channels)
    if literature is None:
        models.append(("literature (sigma = 1)", solve(mapped, ones)))
    else:
        lit = load_design(literature)
        models.append((f"literature ({lit.name})", solve(lit, None)))
    if isinstance(constant, str) and constant == "fit":
        # The global calibration with the three factors: one sigma for all training rows.
        train = hybrid.identification.dataset.subset(hybrid.train_rows)
        fit = calibrate(mapped, train, list(_CONSTANT_PARAMS), **kwargs)
        sigma = fit.stiffness_scale
        label = f"constant sigma fit ({', '.join(f'{s:.3g}' for s in sigma)})"
        models.append((label, solve(mapped, fit.stiffness_map)))
    elif constant is not None:
        smap = StiffnessMap.constant(constant, mapped.n_channels)
        sigma = smap(np.zeros((1, mapped.n_channels)))[0]
        label = f"constant sigma ({', '.join(f'{s:.3g}' for s in sigma)})"
        models.append((label, solve(mapped, smap)))

    ident = hybrid.identification
    same = len(dataset) == len(ident) and np.array_equal(dataset.pressures, ident.dataset.pressures)
    labels = None
    if same:
        found = ident.identifiable[idx].all(axis=1)
        labels = np.where(found, "identified", "not identified").astype(object)
    mount = mapped.spec["mounting"]
    tables = []
    for name, predicted in models:
        table = tip_error_table(
            measured,
            predicted,
            length=mapped.length,
            base_position=mount["base_position"],
            axis=np.asarray(mount["base_rotation"])[:, 2],
            labels=labels,
        )
        table.insert(0, "model", name)
        tables.append(table)
    return pd.concat(tables, ignore_index=True)
