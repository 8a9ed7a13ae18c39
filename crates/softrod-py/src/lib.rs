//! Thin PyO3 binding of softrod-core, built by maturin as `softrod._core`.
//! It converts types, maps errors to the exception classes of `softrod.errors`, and
//! releases the GIL for long calls. No physics lives here.

use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::batch::{constrained_sensitivity_batch, BatchInputs, BatchRow};
use softrod_core::interp::GridPchip;
use softrod_core::marker::Marker;
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::statics::constraint::TipConstraint;
use softrod_core::statics::{self, SolverOptions};
use softrod_core::validity::{Policy, StrainLimits};
use softrod_core::{DesignSpec, Rod, SoftrodError};

mod control;
mod dynamics;
mod ends;
mod pcc;
mod solve;
mod system_dynamics;

/// Which exception class a core `InvalidParameter` becomes.
#[derive(Clone, Copy)]
enum Context {
    Design,
    Input,
}

fn to_py_err(py: Python<'_>, err: SoftrodError, ctx: Context) -> PyErr {
    let build = || -> PyResult<PyErr> {
        let errors = py.import("softrod.errors")?;
        let msg = err.to_string();
        Ok(match err {
            SoftrodError::InvalidParameter { field, value, rule } => {
                let cls = errors.getattr(match ctx {
                    Context::Design => "DesignError",
                    Context::Input => "InputError",
                })?;
                PyErr::from_value(cls.call1((msg, field, value, rule))?)
            }
            SoftrodError::NotConverged {
                iterations,
                residual,
                load_factor,
                reason,
            } => {
                let cls = errors.getattr("ConvergenceError")?;
                PyErr::from_value(cls.call1((msg, iterations, residual, load_factor, reason))?)
            }
            SoftrodError::InvalidState {
                rule,
                node,
                s,
                time,
                value,
                ..
            } => {
                let cls = errors.getattr("InvalidStateError")?;
                PyErr::from_value(cls.call1((msg, rule.name(), node, s, value, time))?)
            }
            SoftrodError::Internal(_) => {
                PyErr::from_value(errors.getattr("InternalError")?.call1((msg,))?)
            }
        })
    };
    build().unwrap_or_else(|e| e)
}

/// A validated, compiled design (immutable).
#[pyclass(name = "Rod", module = "softrod._core", frozen)]
pub(crate) struct PyRod {
    pub(crate) rod: Rod,
}

/// Where a frictional static solve's load path stands (`statics::friction::FrictionPath`):
/// its loads and every contact point's friction memory, for `Rod.solve(history=...)` to
/// continue the path from. Opaque; it belongs to the design it was solved with.
#[pyclass(name = "FrictionState", module = "softrod._core", frozen)]
pub(crate) struct PyFrictionState {
    pub(crate) path: std::sync::Arc<statics::friction::FrictionPath>,
}

#[pymethods]
impl PyFrictionState {
    /// Largest elastic tangential displacement stored in a contact (m; 0: no tangential
    /// load held).
    #[getter]
    fn max_elastic_slip(&self) -> f64 {
        self.path.max_elastic_slip()
    }

    /// The pressures (Pa) of the path's end.
    #[getter]
    fn pressures(&self) -> Vec<f64> {
        self.path.loads.pressures.clone()
    }

    /// The tip force (N, the design's tip frame) of the path's end.
    #[getter]
    fn tip_force(&self) -> [f64; 3] {
        self.path.loads.tip_force
    }

    /// The tip moment (N m) of the path's end.
    #[getter]
    fn tip_moment(&self) -> [f64; 3] {
        self.path.loads.tip_moment
    }

    /// The tendon tensions (N) of the path's end.
    #[getter]
    fn tensions(&self) -> Vec<f64> {
        self.path.loads.tensions.clone()
    }

    /// How the tip was held on the path: "free", "pinned" or "clamped" (a further path
    /// continues with the same).
    #[getter]
    fn tip_constraint(&self) -> &'static str {
        self.path.held.name()
    }

    fn __repr__(&self) -> String {
        format!(
            "FrictionState(pressures={:?}, max_elastic_slip={:.3e} m)",
            self.path.loads.pressures,
            self.path.max_elastic_slip()
        )
    }
}

/// The solver options of a call; `on_invalid` is "raise", "warn" or "ignore".
fn options(
    py: Python<'_>,
    tol: f64,
    max_iter: usize,
    continuation: bool,
    max_load_steps: usize,
    stretch_range: (f64, f64),
    on_invalid: &str,
) -> PyResult<SolverOptions> {
    let on_invalid = Policy::from_name(on_invalid).ok_or_else(|| {
        to_py_err(
            py,
            SoftrodError::invalid(
                "on_invalid",
                on_invalid,
                "must be 'raise', 'warn' or 'ignore'",
            ),
            Context::Input,
        )
    })?;
    Ok(SolverOptions {
        tol,
        max_iter,
        continuation,
        max_load_steps,
        strain_limits: StrainLimits {
            stretch_min: stretch_range.0,
            stretch_max: stretch_range.1,
        },
        on_invalid,
    })
}

/// Run a binding entry so that a panic inside the core (a bug: the core reports every
/// expected failure as a `SoftrodError`) becomes `softrod.InternalError`, never a
/// `pyo3_runtime.PanicException` that `except Exception` would miss.
pub(crate) fn guarded<T>(py: Python<'_>, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".into());
        Err(to_py_err(py, SoftrodError::Internal(what), Context::Input))
    })
}

/// The `DesignSpec` of a design's JSON text (SI units), as written by the Python package.
/// A type or value error names the field path (`sections[1].chambers[0].channel`).
fn parse_spec(py: Python<'_>, spec_json: &str) -> PyResult<DesignSpec> {
    let de = &mut serde_json::Deserializer::from_str(spec_json);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let field = if path.is_empty() || path == "." {
            "design".to_string()
        } else {
            path
        };
        let inner = e.inner();
        // serde_json's message without its position in the JSON text (which the user never
        // wrote); the offending value is the first `quoted` part, when there is one.
        let text = inner.to_string();
        let rule = match text.rfind(" at line ") {
            Some(k) if inner.line() > 0 => text[..k].to_string(),
            _ => text.clone(),
        };
        let value = rule
            .split('`')
            .nth(1)
            .map(str::to_string)
            .unwrap_or_else(|| "(invalid)".into());
        to_py_err(
            py,
            SoftrodError::invalid(field, value, rule),
            Context::Design,
        )
    })
}

/// A matrix as a (rows, columns) numpy array.
pub(crate) fn matrix<'py>(
    py: Python<'py>,
    m: &nalgebra::DMatrix<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    // nalgebra is column-major; numpy wants rows.
    let (r, c) = m.shape();
    let flat: Vec<f64> = (0..r)
        .flat_map(|i| (0..c).map(move |j| m[(i, j)]))
        .collect();
    Ok(PyArray1::from_vec(py, flat).reshape([r, c])?.into_any())
}

pub(crate) fn array2<'py>(py: Python<'py>, rows: &[[f64; 3]]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([rows.len(), 3])?
        .into_any())
}

/// The contact report of a static solution as numpy arrays (SI).
pub(crate) fn contact_dict<'py>(
    py: Python<'py>,
    rep: &statics::contact::ContactReport,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let forces: Vec<[f64; 3]> = rep.nodes.iter().map(|n| n.force).collect();
    let points: Vec<[f64; 3]> = rep.nodes.iter().map(|n| n.point).collect();
    d.set_item("force", array2(py, &forces)?)?;
    d.set_item("point", array2(py, &points)?)?;
    d.set_item(
        "gap",
        PyArray1::from_vec(py, rep.nodes.iter().map(|n| n.gap).collect()),
    )?;
    d.set_item(
        "obstacle",
        PyArray1::from_vec(py, rep.nodes.iter().map(|n| n.obstacle as i64).collect()),
    )?;
    d.set_item("total_force", array2(py, &rep.force)?)?;
    d.set_item("total_moment", array2(py, &rep.moment)?)?;
    d.set_item("end_force", array2(py, &rep.end)?)?;
    d.set_item("friction_force", array2(py, &rep.friction)?)?;
    d.set_item("max_penetration", rep.max_penetration)?;
    Ok(d)
}

/// A static solution's shape (arrays over the nodes) and numbers as a dict: the keys of
/// `Rod.solve`, shared by every entry that returns one solution.
fn solution_dict<'py>(
    py: Python<'py>,
    sol: &statics::Solution,
    sh: &statics::Shape,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("s", PyArray1::from_vec(py, sh.s.clone()))?;
    d.set_item(
        "section",
        PyArray1::from_vec(py, sh.section.iter().map(|&i| i as i64).collect()),
    )?;
    d.set_item("position", array2(py, &sh.position)?)?;
    d.set_item("rotation", array3(py, &sh.rotation)?)?;
    d.set_item("force", array2(py, &sh.force)?)?;
    d.set_item("moment", array2(py, &sh.moment)?)?;
    d.set_item("v", array2(py, &sh.v)?)?;
    d.set_item("u", array2(py, &sh.u)?)?;
    d.set_item("x", sol.x.to_vec())?;
    // A collocation solution's unknowns z: the warm start that re-solving it for its
    // derivatives needs (its `x`, the base moment, does not determine them).
    d.set_item("collocation_unknowns", collocation_unknowns(py, sol))?;
    d.set_item("iterations", sol.iterations)?;
    d.set_item("residual", sol.residual)?;
    d.set_item("load_steps", sol.load_steps)?;
    d.set_item("stable", sol.stable)?;
    d.set_item(
        "violations",
        sol.violations
            .iter()
            .map(|e| e.to_string())
            .collect::<Vec<_>>(),
    )?;
    Ok(d)
}

/// The collocation unknowns z of a solution that collocation solved, else None.
pub(crate) fn collocation_unknowns<'py>(
    py: Python<'py>,
    sol: &statics::Solution,
) -> Option<Bound<'py, PyArray1<f64>>> {
    sol.collocation
        .as_ref()
        .map(|c| PyArray1::from_slice(py, &c.z))
}

pub(crate) fn array3<'py>(py: Python<'py>, mats: &[[[f64; 3]; 3]]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = mats.iter().flatten().flatten().copied().collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([mats.len(), 3, 3])?
        .into_any())
}

#[pymethods]
impl PyRod {
    /// Build from the JSON text of a `DesignSpec` (SI units).
    #[new]
    fn new(py: Python<'_>, spec_json: &str) -> PyResult<Self> {
        guarded(py, || {
            let spec = parse_spec(py, spec_json)?;
            let rod = Rod::new(spec).map_err(|e| to_py_err(py, e, Context::Design))?;
            Ok(PyRod { rod })
        })
    }

    #[getter]
    fn n_channels(&self) -> usize {
        self.rod.n_channels
    }

    /// Number of tendon tension channels.
    #[getter]
    fn n_tendons(&self) -> usize {
        self.rod.n_tendons
    }

    /// Total reference length, m.
    #[getter]
    fn length(&self) -> f64 {
        self.rod.length
    }

    /// Mass of the rod without the tip body, kg.
    #[getter]
    fn mass(&self) -> f64 {
        self.rod.mass()
    }

    /// Per-section compiled properties (SI) as a list of dicts.
    fn sections<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.rod
            .sections
            .iter()
            .map(|s| {
                let d = PyDict::new(py);
                d.set_item("name", &s.name)?;
                d.set_item("length", s.length)?;
                d.set_item("s_start", s.s_start)?;
                d.set_item("steps", s.steps)?;
                d.set_item("rigid", s.rigid)?;
                d.set_item("k_se", s.k_se.to_vec())?;
                d.set_item(
                    "k_bt",
                    s.k_bt.iter().map(|r| r.to_vec()).collect::<Vec<_>>(),
                )?;
                d.set_item("line_mass", s.line_mass)?;
                d.set_item(
                    "chambers",
                    s.chambers
                        .iter()
                        .map(|c| (c.area, c.centroid[0], c.centroid[1], c.channel))
                        .collect::<Vec<_>>(),
                )?;
                Ok(d)
            })
            .collect()
    }

    /// Solve one static equilibrium; returns a dict of numpy arrays (SI), the stability
    /// flag "stable" (None where not assessed: follower loads, friction) and the
    /// validity-range violations "violations" (with on_invalid="warn"). `tensions`: one
    /// per tendon channel, N (None: slack); the tip loads act in the design's tip frame.
    /// With an obstacle's friction > 0 the solve follows the frictional load path
    /// (`statics::friction`) in `friction_steps` increments from the unloaded rod or from
    /// `history` (a `FrictionState` of this design), and the dict has "friction_state".
    /// `stiffness_scale`: sigma of the mapped sections (None: a design without one).
    #[pyo3(signature = (pressures, tip_force, tip_moment, guess=None, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), stiffness_scale=None, on_invalid="raise", tensions=None, friction_steps=statics::friction::DEFAULT_FRICTION_STEPS, history=None))]
    #[allow(clippy::too_many_arguments)]
    fn solve<'py>(
        &self,
        py: Python<'py>,
        pressures: Vec<f64>,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
        guess: Option<Vec<f64>>,
        tol: f64,
        max_iter: usize,
        continuation: bool,
        max_load_steps: usize,
        stretch_range: (f64, f64),
        stiffness_scale: Option<[f64; 3]>,
        on_invalid: &str,
        tensions: Option<Vec<f64>>,
        friction_steps: usize,
        history: Option<PyRef<'py, PyFrictionState>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(py, || {
            let opts = options(
                py,
                tol,
                max_iter,
                continuation,
                max_load_steps,
                stretch_range,
                on_invalid,
            )?;
            let input = solve::One {
                pressures,
                tensions,
                tip_force,
                tip_moment,
                stiffness_scale,
                guess,
                friction_steps,
                history,
            };
            solve::solve_one(py, self, TipConstraint::Free, input, &opts, false)
        })
    }

    /// Solve every row of an (m, channels) pressure array in parallel (GIL released), with
    /// an optional (m, tendon channels) tension array (N; None: slack). With an obstacle's
    /// friction > 0 every row follows its own frictional load path from the unloaded rod
    /// in `friction_steps` increments (`batch::solve_friction_batch`, as `solve` does for
    /// one row), and the dict adds "contact_force" and "friction_force" (m, obstacles, 3).
    #[pyo3(signature = (pressures, tip_force, tip_moment, threads=0, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), stiffness_scale=None, on_invalid="raise", tensions=None, friction_steps=statics::friction::DEFAULT_FRICTION_STEPS))]
    #[allow(clippy::too_many_arguments)]
    fn solve_batch<'py>(
        &self,
        py: Python<'py>,
        pressures: PyReadonlyArray2<'py, f64>,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
        threads: usize,
        tol: f64,
        max_iter: usize,
        continuation: bool,
        max_load_steps: usize,
        stretch_range: (f64, f64),
        stiffness_scale: Option<PyReadonlyArray2<'py, f64>>,
        on_invalid: &str,
        tensions: Option<PyReadonlyArray2<'py, f64>>,
        friction_steps: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(py, || {
            let opts = options(
                py,
                tol,
                max_iter,
                continuation,
                max_load_steps,
                stretch_range,
                on_invalid,
            )?;
            let input = solve::Rows {
                pressures,
                stiffness_scale,
                tensions,
                tip_force,
                tip_moment,
                friction_steps,
            };
            solve::solve_rows(py, self, TipConstraint::Free, input, &opts, threads, false)
        })
    }

    /// `solve_batch` plus the exact derivatives of every converged tip pose with respect to
    /// calibration parameters (GIL released). `params`: a list of (kind, sections) pairs,
    /// kinds as in `softrod_core::sensitivity::ParamKind::ALL`. `x0`: optional (m, 3) warm
    /// starts (a previous call's "x"; NaN rows start cold). `markers`: (s, offset) pairs,
    /// points on the body (reference arc length in m, offset (d1, d2, d3) in m). Adds "x"
    /// (m, n), "d_tip_position" (m, 3, P), "d_tip_rotation" (m, 3, 3, P), "marker_position"
    /// (m, K, 3) and "d_marker_position" (m, K, 3, P), NaN on failed rows. `tip_kind`
    /// "pinned" (with `tip_position`) or "clamped" (and `tip_rotation`) holds the tip as
    /// `solve_constrained_tip_batch` does (rows solved as it solves them; `x0` then (m, 6))
    /// and adds "tip_reaction_force" and "tip_reaction_moment" (m, 3) with their exact
    /// derivatives "d_tip_reaction_force" and "d_tip_reaction_moment" (m, 3, P), NaN on
    /// failed rows.
    #[pyo3(signature = (pressures, tip_force, tip_moment, params, stiffness_scale=None, x0=None, threads=0, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), on_invalid="ignore", tensions=None, markers=vec![], tip_kind="free", tip_position=None, tip_rotation=None))]
    #[allow(clippy::too_many_arguments)]
    fn sensitivity_batch<'py>(
        &self,
        py: Python<'py>,
        pressures: PyReadonlyArray2<'py, f64>,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
        params: Vec<(String, Vec<usize>)>,
        stiffness_scale: Option<PyReadonlyArray2<'py, f64>>,
        x0: Option<PyReadonlyArray2<'py, f64>>,
        threads: usize,
        tol: f64,
        max_iter: usize,
        continuation: bool,
        max_load_steps: usize,
        stretch_range: (f64, f64),
        on_invalid: &str,
        tensions: Option<PyReadonlyArray2<'py, f64>>,
        markers: Vec<(f64, [f64; 3])>,
        tip_kind: &str,
        tip_position: Option<[f64; 3]>,
        tip_rotation: Option<[[f64; 3]; 3]>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(py, || {
            self.check_columns(py, &pressures)?;
            let held = ends::constraint(py, tip_kind, tip_position, tip_rotation)?;
            let tens: Option<Vec<f64>> = tensions.map(|s| s.as_array().iter().copied().collect());
            let markers: Vec<Marker> = markers
                .into_iter()
                .map(|(s, offset)| Marker { s, offset })
                .collect();
            let params: Vec<Param> = params
                .into_iter()
                .enumerate()
                .map(|(j, (name, sections))| match ParamKind::from_name(&name) {
                    Some(kind) => Ok(Param { kind, sections }),
                    None => Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            format!("params[{j}]"),
                            &name,
                            format!(
                                "unknown parameter kind; known: {}",
                                ParamKind::ALL.map(|(n, _)| n).join(", ")
                            ),
                        ),
                        Context::Input,
                    )),
                })
                .collect::<PyResult<_>>()?;
            let flat: Vec<f64> = pressures.as_array().iter().copied().collect();
            let sigma: Option<Vec<f64>> =
                stiffness_scale.map(|s| s.as_array().iter().copied().collect());
            let guesses: Option<Vec<f64>> = x0.map(|s| s.as_array().iter().copied().collect());
            let opts = options(
                py,
                tol,
                max_iter,
                continuation,
                max_load_steps,
                stretch_range,
                on_invalid,
            )?;
            let rod = &self.rod;
            let rows = py
                .detach(|| {
                    let inputs = BatchInputs {
                        pressures: &flat,
                        tensions: tens.as_deref(),
                        stiffness_scale: sigma.as_deref(),
                        tip_force,
                        tip_moment,
                    };
                    constrained_sensitivity_batch(
                        rod,
                        &inputs,
                        &held,
                        guesses.as_deref(),
                        &params,
                        &markers,
                        &opts,
                        threads,
                    )
                })
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            let d = rows_dict(py, &rows)?;
            let (np, m) = (params.len(), rows.len());
            if held != TipConstraint::Free {
                solve::reactions(py, &d, &rows)?;
                let (mut df, mut dmo) = (vec![f64::NAN; m * 3 * np], vec![f64::NAN; m * 3 * np]);
                for (r, row) in rows.iter().enumerate() {
                    let Some(sens) = &row.sensitivity else {
                        continue;
                    };
                    for j in 0..np {
                        for i in 0..3 {
                            df[(r * 3 + i) * np + j] = sens.reaction_force[j][i];
                            dmo[(r * 3 + i) * np + j] = sens.reaction_moment[j][i];
                        }
                    }
                }
                d.set_item(
                    "d_tip_reaction_force",
                    PyArray1::from_vec(py, df).reshape([m, 3, np])?,
                )?;
                d.set_item(
                    "d_tip_reaction_moment",
                    PyArray1::from_vec(py, dmo).reshape([m, 3, np])?,
                )?;
            }
            let mut arrays = PoseArrays::new(m, np, markers.len());
            for (r, row) in rows.iter().enumerate() {
                arrays.markers(r, &row.markers);
                if let Some(sens) = &row.sensitivity {
                    arrays.derivatives(r, &sens.position, &sens.rotation, &sens.markers);
                }
            }
            arrays.into_dict(py, &d, "d_tip_position", "d_tip_rotation")?;
            Ok(d)
        })
    }
}

impl PyRod {
    pub(crate) fn check_columns(
        &self,
        py: Python<'_>,
        pressures: &PyReadonlyArray2<'_, f64>,
    ) -> PyResult<()> {
        let shape = pressures.as_array().shape().to_vec();
        if shape[1] != self.rod.n_channels {
            return Err(to_py_err(
                py,
                SoftrodError::invalid(
                    "pressures",
                    format!("shape {shape:?}"),
                    format!(
                        "must have {} columns, one per pressure channel",
                        self.rod.n_channels
                    ),
                ),
                Context::Input,
            ));
        }
        Ok(())
    }
}

/// The per-row arrays of a pose's parameter derivatives (a tip's or a platform's) and of the
/// markers: positions (m, K, 3), their derivatives (m, K, 3, P), the pose's (m, 3, P) and
/// (m, 3, 3, P); NaN on rows without them.
pub(crate) struct PoseArrays {
    m: usize,
    np: usize,
    nk: usize,
    marker: Vec<f64>,
    d_marker: Vec<f64>,
    d_position: Vec<f64>,
    d_rotation: Vec<f64>,
}

impl PoseArrays {
    pub(crate) fn new(m: usize, np: usize, nk: usize) -> Self {
        PoseArrays {
            m,
            np,
            nk,
            marker: vec![f64::NAN; m * nk * 3],
            d_marker: vec![f64::NAN; m * nk * 3 * np],
            d_position: vec![f64::NAN; m * 3 * np],
            d_rotation: vec![f64::NAN; m * 9 * np],
        }
    }

    /// Row r's marker positions.
    pub(crate) fn markers(&mut self, r: usize, at: &[[f64; 3]]) {
        for (k, pos) in at.iter().enumerate() {
            let i = (r * self.nk + k) * 3;
            self.marker[i..i + 3].copy_from_slice(pos);
        }
    }

    /// Row r's derivatives, one entry per parameter (`markers[j][k]`).
    pub(crate) fn derivatives(
        &mut self,
        r: usize,
        position: &[[f64; 3]],
        rotation: &[[[f64; 3]; 3]],
        markers: &[Vec<[f64; 3]>],
    ) {
        let (np, nk) = (self.np, self.nk);
        for j in 0..np {
            for i in 0..3 {
                self.d_position[(r * 3 + i) * np + j] = position[j][i];
                for (c, v) in rotation[j][i].iter().enumerate() {
                    self.d_rotation[((r * 3 + i) * 3 + c) * np + j] = *v;
                }
            }
            for (k, m) in markers[j][..nk].iter().enumerate() {
                for (i, v) in m.iter().enumerate() {
                    self.d_marker[((r * nk + k) * 3 + i) * np + j] = *v;
                }
            }
        }
    }

    /// Into `d`: "marker_position", "d_marker_position" and the pose's two under the given
    /// names.
    pub(crate) fn into_dict(
        self,
        py: Python<'_>,
        d: &Bound<'_, PyDict>,
        position: &str,
        rotation: &str,
    ) -> PyResult<()> {
        let (m, np, nk) = (self.m, self.np, self.nk);
        d.set_item(
            "marker_position",
            PyArray1::from_vec(py, self.marker).reshape([m, nk, 3])?,
        )?;
        d.set_item(
            "d_marker_position",
            PyArray1::from_vec(py, self.d_marker).reshape([m, nk, 3, np])?,
        )?;
        d.set_item(
            position,
            PyArray1::from_vec(py, self.d_position).reshape([m, 3, np])?,
        )?;
        d.set_item(
            rotation,
            PyArray1::from_vec(py, self.d_rotation).reshape([m, 3, 3, np])?,
        )?;
        Ok(())
    }
}

/// The per-row arrays of a batch result.
pub(crate) fn rows_dict<'py>(py: Python<'py>, rows: &[BatchRow]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let tp: Vec<[f64; 3]> = rows.iter().map(|r| r.tip_position).collect();
    let tr: Vec<[[f64; 3]; 3]> = rows.iter().map(|r| r.tip_rotation).collect();
    let bf: Vec<[f64; 3]> = rows.iter().map(|r| r.base_force).collect();
    let bm: Vec<[f64; 3]> = rows.iter().map(|r| r.base_moment).collect();
    d.set_item("tip_position", array2(py, &tp)?)?;
    d.set_item("tip_rotation", array3(py, &tr)?)?;
    d.set_item("base_force", array2(py, &bf)?)?;
    d.set_item("base_moment", array2(py, &bm)?)?;
    d.set_item(
        "converged",
        PyArray1::from_vec(py, rows.iter().map(|r| r.converged).collect()),
    )?;
    d.set_item(
        "iterations",
        PyArray1::from_vec(py, rows.iter().map(|r| r.iterations as i64).collect()),
    )?;
    d.set_item(
        "residual",
        PyArray1::from_vec(py, rows.iter().map(|r| r.residual).collect()),
    )?;
    // Shooting unknowns (m, 3), or (m, 6) with follower loads (every row has as many).
    let width = rows.first().map_or(3, |r| r.x.len());
    let x: Vec<f64> = rows.iter().flat_map(|r| r.x.iter().copied()).collect();
    d.set_item("x", PyArray1::from_vec(py, x).reshape([rows.len(), width])?)?;
    // "stable" is false where stability was not assessed (follower loads): see "assessed".
    d.set_item(
        "stable",
        PyArray1::from_vec(py, rows.iter().map(|r| r.stable == Some(true)).collect()),
    )?;
    d.set_item(
        "assessed",
        PyArray1::from_vec(py, rows.iter().map(|r| r.stable.is_some()).collect()),
    )?;
    d.set_item(
        "violation",
        rows.iter()
            .map(|r| r.violation.as_str())
            .collect::<Vec<_>>(),
    )?;
    Ok(d)
}

/// A frictional batch's "contact_force" and "friction_force": per row, per obstacle, a
/// force, (m, obstacles, 3).
pub(crate) fn contact_forces(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    rows: &[BatchRow],
    obstacles: usize,
) -> PyResult<()> {
    let stack = |of: &dyn Fn(&BatchRow) -> &[[f64; 3]]| {
        let flat: Vec<f64> = rows
            .iter()
            .flat_map(|r| of(r).as_flattened())
            .copied()
            .collect();
        PyArray1::from_vec(py, flat).reshape([rows.len(), obstacles, 3])
    };
    d.set_item("contact_force", stack(&|r| &r.contact_force)?)?;
    d.set_item("friction_force", stack(&|r| &r.friction_force)?)?;
    Ok(())
}

/// Tensor-product PCHIP on a regular grid (the interpolation of table stiffness maps).
#[pyclass(name = "GridPchip", frozen)]
struct PyGridPchip {
    grid: GridPchip,
}

#[pymethods]
impl PyGridPchip {
    /// axes: one increasing axis per dimension; values: flat row-major (last axis fastest),
    /// `width` values per grid point.
    #[new]
    fn new(py: Python<'_>, axes: Vec<Vec<f64>>, values: Vec<f64>, width: usize) -> PyResult<Self> {
        guarded(py, || {
            let grid = GridPchip::new(axes, values, width)
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            Ok(PyGridPchip { grid })
        })
    }

    /// Interpolate at every row of an (m, dims) array of points inside the grid.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guarded(py, || {
            let rows = self.rows(py, &points)?;
            let grid = &self.grid;
            let width = grid.width();
            let out: Vec<Vec<f64>> = py.detach(|| {
                rows.iter()
                    .map(|p| {
                        let mut o = vec![0.0; width];
                        grid.eval(p, &mut o);
                        o
                    })
                    .collect()
            });
            Ok(PyArray2::from_vec2(py, &out)?)
        })
    }

    /// The derivatives of the interpolant at every row of an (m, dims) array of points
    /// inside the grid: (m, width, dims), d value / d coordinate
    /// (`GridPchip::gradient`).
    fn gradient<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        guarded(py, || {
            let rows = self.rows(py, &points)?;
            let grid = &self.grid;
            let (width, dims) = (grid.width(), grid.dims());
            let out: Vec<Vec<Vec<f64>>> = py.detach(|| {
                rows.iter()
                    .map(|p| {
                        let mut o = vec![vec![0.0; dims]; width];
                        grid.gradient(p, &mut o);
                        o
                    })
                    .collect()
            });
            Ok(PyArray3::from_vec3(py, &out)?)
        })
    }
}

impl PyGridPchip {
    /// The rows of an (m, dims) array of points, its column count checked.
    fn rows(&self, py: Python<'_>, points: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Vec<f64>>> {
        let pts = points.as_array();
        let dims = self.grid.dims();
        if pts.shape()[1] != dims {
            return Err(to_py_err(
                py,
                SoftrodError::invalid(
                    "points",
                    format!("shape {:?}", pts.shape()),
                    format!("must have {dims} columns"),
                ),
                Context::Input,
            ));
        }
        Ok(pts.rows().into_iter().map(|r| r.to_vec()).collect())
    }
}

/// Panics inside `guarded`: the tests' proof that a panic in the core reaches Python as
/// `softrod.InternalError` (no other use).
#[pyfunction]
fn _panic_inside_guard(py: Python<'_>) -> PyResult<()> {
    guarded(py, || panic!("deliberate panic from _panic_inside_guard"))
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRod>()?;
    m.add_class::<PyFrictionState>()?;
    m.add_class::<PyGridPchip>()?;
    m.add_function(wrap_pyfunction!(_panic_inside_guard, m)?)?;
    control::register(m)?;
    dynamics::register(m)?;
    ends::register(m)?;
    pcc::register(m)?;
    system_dynamics::register(m)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // Whether this build checks debug assertions and integer overflow (the test command's
    // `checked` profile, or a debug build): benchmarks record it and warn, as such a build is
    // slower than the release build.
    m.add("_debug_assertions", cfg!(debug_assertions))?;
    Ok(())
}
