//! Binding of the PCC model (softrod_core::pcc): type conversion and error mapping only.

use super::{array2, array3, to_py_err, Context};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::pcc::sensitivity::{
    simulate_sensitivity_batch, statics_sensitivity_batch, PccMarker, PccParam, PccRun,
    PointSensitivity,
};
use softrod_core::pcc::{BendStiffness, InitialState, PccModel, StepOptions};
use softrod_core::SoftrodError;

/// The compiled PCC model of a design (immutable).
#[pyclass(name = "PccModel", module = "softrod._core", frozen)]
struct PyPcc {
    model: PccModel,
}

fn matrix<'py>(py: Python<'py>, rows: &[Vec<f64>], width: usize) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([rows.len(), width])?
        .into_any())
}

/// Parameter names -> core parameters (errors name `params[j]`).
fn pcc_params(py: Python<'_>, names: &[String]) -> PyResult<Vec<PccParam>> {
    names
        .iter()
        .enumerate()
        .map(|(j, n)| {
            PccParam::parse(n).ok_or_else(|| {
                to_py_err(
                    py,
                    SoftrodError::invalid(
                        format!("params[{j}]"),
                        n,
                        "unknown PCC parameter; known: k_L, b_L, k_theta, k_theta[j], b_theta, k_phi, b_phi",
                    ),
                    Context::Input,
                )
            })
        })
        .collect()
}

fn pcc_markers(markers: Vec<(f64, [f64; 3])>) -> Vec<PccMarker> {
    markers
        .into_iter()
        .map(|(s, offset)| PccMarker { s, offset })
        .collect()
}

/// (points (n, K, 3), d_points (n, K, 3, P)) of several point sets, NaN for missing ones.
fn point_arrays<'py>(
    py: Python<'py>,
    sets: &[Option<&PointSensitivity>],
    n_points: usize,
    n_par: usize,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let n = sets.len();
    let mut pts = vec![f64::NAN; n * n_points * 3];
    let mut dp = vec![f64::NAN; n * n_points * 3 * n_par];
    for (r, set) in sets.iter().enumerate() {
        let Some(set) = set else { continue };
        for (i, (p, d)) in set.points.iter().zip(&set.d_points).enumerate() {
            for k in 0..3 {
                pts[(r * n_points + i) * 3 + k] = p[k];
                for j in 0..n_par {
                    dp[((r * n_points + i) * 3 + k) * n_par + j] = d[j][k];
                }
            }
        }
    }
    Ok((
        PyArray1::from_vec(py, pts)
            .reshape([n, n_points, 3])?
            .into_any(),
        PyArray1::from_vec(py, dp)
            .reshape([n, n_points, 3, n_par])?
            .into_any(),
    ))
}

impl PyPcc {
    fn paper_rows(&self, x: &[Vec<f64>], v: &[Vec<f64>]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        x.iter()
            .zip(v)
            .map(|(a, b)| self.model.to_paper(a, b))
            .unzip()
    }
}

#[pymethods]
impl PyPcc {
    /// Build from the JSON text of a `DesignSpec` (SI units).
    #[new]
    fn new(py: Python<'_>, spec_json: &str) -> PyResult<Self> {
        crate::guarded(py, || {
            let spec = crate::parse_spec(py, spec_json)?;
            let model = PccModel::new(&spec).map_err(|e| to_py_err(py, e, Context::Design))?;
            Ok(PyPcc { model })
        })
    }

    #[getter]
    fn n_channels(&self) -> usize {
        self.model.n_channels
    }

    #[getter]
    fn ndof(&self) -> usize {
        self.model.ndof
    }

    #[getter]
    fn n_segments(&self) -> usize {
        self.model.n_segments()
    }

    #[getter]
    fn planar(&self) -> bool {
        self.model.plane.is_some()
    }

    /// Reference length of the chain, m.
    #[getter]
    fn length(&self) -> f64 {
        self.model.length()
    }

    /// Per-segment parameters (SI) as dicts.
    fn segments<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        crate::guarded(py, || {
            self.model
                .segments()
                .map(|(l, _, p)| {
                    let d = PyDict::new(py);
                    d.set_item("name", &l.name)?;
                    d.set_item("length", l.length)?;
                    d.set_item("mass", l.line_mass * l.length)?;
                    d.set_item("k_L", p.k_l)?;
                    d.set_item("b_L", p.b_l)?;
                    match &p.k_theta {
                        BendStiffness::Constant(k) => d.set_item("k_theta", *k)?,
                        BendStiffness::Table(a, k) => {
                            d.set_item("k_theta", (a.clone(), k.clone()))?
                        }
                    }
                    d.set_item("b_theta", p.b_theta)?;
                    d.set_item("k_phi", p.k_phi)?;
                    d.set_item("b_phi", p.b_phi)?;
                    Ok(d)
                })
                .collect()
        })
    }

    /// Model coordinates (x, v) from paper coordinates (q, q_dot) = (L, theta, phi) per segment.
    fn to_model(
        &self,
        py: Python<'_>,
        q: Vec<f64>,
        q_dot: Vec<f64>,
    ) -> PyResult<(Vec<f64>, Vec<f64>)> {
        crate::guarded(py, || {
            self.model
                .from_paper(&q, &q_dot)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Static equilibrium: dict with x, q, iterations, residual, tip pose.
    #[pyo3(signature = (pressures, guess=None, tol=1e-11, max_iter=30))]
    fn statics<'py>(
        &self,
        py: Python<'py>,
        pressures: Vec<f64>,
        guess: Option<Vec<f64>>,
        tol: f64,
        max_iter: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let opts = StepOptions { tol, max_iter };
            let m = &self.model;
            let s = py
                .detach(|| m.solve_statics(&pressures, guess.as_deref(), &opts))
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            let zero = vec![0.0; s.x.len()];
            let (q, _) = m.to_paper(&s.x, &zero);
            let (p, r) = m.tip_pose(&s.x);
            let d = PyDict::new(py);
            d.set_item("x", s.x.clone())?;
            d.set_item("q", q)?;
            d.set_item("iterations", s.iterations)?;
            d.set_item("residual", s.residual)?;
            d.set_item("tip_position", p.to_vec())?;
            d.set_item(
                "tip_rotation",
                r.iter().map(|x| x.to_vec()).collect::<Vec<_>>(),
            )?;
            Ok(d)
        })
    }

    /// Equilibria of the rows of `pressures` (m, n_channels) with the derivatives of the tip
    /// and the markers ((s, offset) pairs) with respect to `params` (names), in parallel
    /// with the GIL released. `guesses`: optional (m, ndof) warm starts (NaN rows start at
    /// rest). Returns a dict: x (m, ndof), converged (m,), errors (m, message or ""),
    /// points (m, 1 + K, 3) (tip first), d_points (m, 1 + K, 3, P); NaN on failed rows.
    #[pyo3(signature = (pressures, params, markers=vec![], guesses=None, threads=0, tol=1e-11, max_iter=30))]
    #[allow(clippy::too_many_arguments)]
    fn statics_sensitivity<'py>(
        &self,
        py: Python<'py>,
        pressures: PyReadonlyArray2<'_, f64>,
        params: Vec<String>,
        markers: Vec<(f64, [f64; 3])>,
        guesses: Option<PyReadonlyArray2<'_, f64>>,
        threads: usize,
        tol: f64,
        max_iter: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let m = &self.model;
            let params = pcc_params(py, &params)?;
            let markers = pcc_markers(markers);
            let flat: Vec<f64> = pressures.as_array().iter().copied().collect();
            let rows = pressures.as_array().nrows();
            let guesses: Option<Vec<f64>> = guesses.map(|g| g.as_array().iter().copied().collect());
            let opts = StepOptions { tol, max_iter };
            let out = py
                .detach(|| {
                    statics_sensitivity_batch(
                        m,
                        &flat,
                        guesses.as_deref(),
                        &params,
                        &markers,
                        &opts,
                        threads,
                    )
                })
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            let d = PyDict::new(py);
            let mut x = vec![f64::NAN; rows * m.ndof];
            for (r, row) in out.iter().enumerate() {
                if let Ok(s) = row {
                    x[r * m.ndof..(r + 1) * m.ndof].copy_from_slice(&s.x);
                }
            }
            let sets: Vec<Option<&PointSensitivity>> =
                out.iter().map(|r| r.as_ref().ok().map(|s| &s.at)).collect();
            let (pts, dp) = point_arrays(py, &sets, 1 + markers.len(), params.len())?;
            d.set_item("x", PyArray1::from_vec(py, x).reshape([rows, m.ndof])?)?;
            d.set_item(
                "converged",
                out.iter().map(|r| r.is_ok()).collect::<Vec<_>>(),
            )?;
            d.set_item(
                "errors",
                out.iter()
                    .map(|r| r.as_ref().err().map(|e| e.to_string()).unwrap_or_default())
                    .collect::<Vec<_>>(),
            )?;
            d.set_item("points", pts)?;
            d.set_item("d_points", dp)?;
            Ok(d)
        })
    }

    /// Replay time series with the derivatives of the tip and the markers with respect to
    /// `params`, in parallel with the GIL released. `runs`: (commands (n_steps + 1,
    /// n_channels) Pa at every step of `dt`, initial "rest" or "static", save_every). Returns
    /// one dict per run: time (n,), points (n, 1 + K, 3), d_points (n, 1 + K, 3, P), error
    /// ("" when it ran).
    #[pyo3(signature = (runs, dt, params, markers=vec![], threads=0, tol=1e-11, max_iter=30))]
    #[allow(clippy::too_many_arguments)]
    fn runs_sensitivity<'py>(
        &self,
        py: Python<'py>,
        runs: Vec<(PyReadonlyArray2<'py, f64>, String, usize)>,
        dt: f64,
        params: Vec<String>,
        markers: Vec<(f64, [f64; 3])>,
        threads: usize,
        tol: f64,
        max_iter: usize,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        crate::guarded(py, || {
            let m = &self.model;
            let params = pcc_params(py, &params)?;
            let markers = pcc_markers(markers);
            let mut core_runs = Vec::with_capacity(runs.len());
            for (k, (p, initial, save_every)) in runs.iter().enumerate() {
                let arr = p.as_array();
                if arr.shape()[1] != m.n_channels {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            format!("runs[{k}].pressures"),
                            format!("{} columns", arr.shape()[1]),
                            format!("the design has {} pressure channels", m.n_channels),
                        ),
                        Context::Input,
                    ));
                }
                let initial = match initial.as_str() {
                    "rest" => InitialState::Rest,
                    "static" => InitialState::Static,
                    other => {
                        return Err(to_py_err(
                            py,
                            SoftrodError::invalid(
                                format!("runs[{k}].initial"),
                                other,
                                "must be 'rest' or 'static'",
                            ),
                            Context::Input,
                        ))
                    }
                };
                core_runs.push(PccRun {
                    dt,
                    pressures: arr.iter().copied().collect(),
                    initial,
                    save_every: *save_every,
                });
            }
            let opts = StepOptions { tol, max_iter };
            let out = py
                .detach(|| {
                    simulate_sensitivity_batch(m, &core_runs, &params, &markers, &opts, threads)
                })
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            out.iter()
                .map(|run| {
                    let d = PyDict::new(py);
                    match run {
                        Ok(r) => {
                            let sets: Vec<Option<&PointSensitivity>> =
                                r.at.iter().map(Some).collect();
                            let (pts, dp) =
                                point_arrays(py, &sets, 1 + markers.len(), params.len())?;
                            d.set_item("time", PyArray1::from_vec(py, r.time.clone()))?;
                            d.set_item("points", pts)?;
                            d.set_item("d_points", dp)?;
                            d.set_item("error", "")?;
                        }
                        Err(e) => d.set_item("error", e.to_string())?,
                    }
                    Ok(d)
                })
                .collect()
        })
    }

    /// Shape at model coordinates x: (s, position (p, 3), rotation (p, 3, 3)).
    fn shape<'py>(
        &self,
        py: Python<'py>,
        x: Vec<f64>,
        per_section: usize,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        crate::guarded(py, || {
            let (s, p, r) = self
                .model
                .shape(&x, per_section)
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            Ok((
                PyArray1::from_vec(py, s).into_any(),
                array2(py, &p)?,
                array3(py, &r)?,
            ))
        })
    }

    /// Shapes at many model coordinates (rows of x): (s (p,), positions (k, p, 3)).
    fn shapes<'py>(
        &self,
        py: Python<'py>,
        xs: PyReadonlyArray2<'_, f64>,
        per_section: usize,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        crate::guarded(py, || {
            let xs = xs.as_array();
            let mut s_out = vec![];
            let mut flat = vec![];
            for row in xs.rows() {
                let x: Vec<f64> = row.iter().copied().collect();
                let (s, p, _) = self
                    .model
                    .shape(&x, per_section)
                    .map_err(|e| to_py_err(py, e, Context::Input))?;
                flat.extend(p.iter().flatten().copied());
                s_out = s;
            }
            let n_pts = s_out.len();
            let pos = PyArray1::from_vec(py, flat).reshape([xs.nrows(), n_pts, 3])?;
            Ok((PyArray1::from_vec(py, s_out).into_any(), pos.into_any()))
        })
    }

    /// Energies (kinetic, gravity, elastic, pressure) at model coordinates (x, v), J.
    fn energy(
        &self,
        py: Python<'_>,
        x: Vec<f64>,
        v: Vec<f64>,
        pressures: Vec<f64>,
    ) -> PyResult<(f64, f64, f64, f64)> {
        crate::guarded(py, || {
            let e = self
                .model
                .energy(&x, &v, &pressures)
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            Ok((e.kinetic, e.gravity, e.elastic, e.pressure))
        })
    }

    /// Mass matrix at model coordinates x.
    fn mass_matrix(&self, py: Python<'_>, x: Vec<f64>) -> PyResult<Vec<Vec<f64>>> {
        crate::guarded(py, || {
            self.model
                .mass_matrix(&x)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Simulate: pressures (n_steps + 1, n_channels) Pa at every step time; initial is
    /// "rest", "static" or "given" (with q0, q_dot0 in paper coordinates).
    #[pyo3(signature = (dt, pressures, initial="rest", q0=None, q_dot0=None, save_every=1, tol=1e-11, max_iter=30))]
    #[allow(clippy::too_many_arguments)]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        dt: f64,
        pressures: PyReadonlyArray2<'_, f64>,
        initial: &str,
        q0: Option<Vec<f64>>,
        q_dot0: Option<Vec<f64>>,
        save_every: usize,
        tol: f64,
        max_iter: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let m = &self.model;
            let arr = pressures.as_array();
            let nc = m.n_channels;
            if arr.shape()[1] != nc {
                return Err(to_py_err(
                    py,
                    SoftrodError::invalid(
                        "pressures",
                        format!("{} columns", arr.shape()[1]),
                        format!(
                            "the design has {nc} pressure channels: one column per channel (Pa)"
                        ),
                    ),
                    Context::Input,
                ));
            }
            let flat: Vec<f64> = arr.iter().copied().collect();
            let init = match initial {
                "rest" => InitialState::Rest,
                "static" => InitialState::Static,
                "given" => {
                    let (q, qd) = (q0.unwrap_or_default(), q_dot0.unwrap_or_default());
                    let (x, v) = m
                        .from_paper(&q, &qd)
                        .map_err(|e| to_py_err(py, e, Context::Input))?;
                    InitialState::Given { x, v }
                }
                // Model coordinates as returned in "x"/"x_dot" (continuing a run without the
                // loss of the bending direction that paper coordinates have at theta = 0).
                "model" => InitialState::Given {
                    x: q0.unwrap_or_default(),
                    v: q_dot0.unwrap_or_default(),
                },
                other => {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            "initial",
                            other,
                            "must be 'rest', 'static' or a pair (q, q_dot)",
                        ),
                        Context::Input,
                    ))
                }
            };
            let opts = StepOptions { tol, max_iter };
            let tr = py
                .detach(|| m.simulate(dt, &flat, &init, save_every, &opts))
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            let (q, qd) = self.paper_rows(&tr.x, &tr.v);
            let n = 3 * m.n_segments();
            let d = PyDict::new(py);
            d.set_item("time", PyArray1::from_vec(py, tr.time.clone()))?;
            d.set_item("q", matrix(py, &q, n)?)?;
            d.set_item("q_dot", matrix(py, &qd, n)?)?;
            d.set_item("x", matrix(py, &tr.x, m.ndof)?)?;
            d.set_item("x_dot", matrix(py, &tr.v, m.ndof)?)?;
            d.set_item("tip_position", array2(py, &tr.tip_position)?)?;
            d.set_item("tip_rotation", array3(py, &tr.tip_rotation)?)?;
            d.set_item("tip_velocity", array2(py, &tr.tip_velocity)?)?;
            d.set_item("pressure", matrix(py, &tr.pressure, nc)?)?;
            d.set_item("energy", PyArray1::from_vec(py, tr.energy.clone()))?;
            d.set_item("newton_iterations", tr.newton_iterations)?;
            d.set_item("jacobian_evaluations", tr.jacobian_evaluations)?;
            Ok(d)
        })
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPcc>()
}
