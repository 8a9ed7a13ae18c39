//! Binding of the dynamic rod (`softrod_core::dynamics`): a stepper object that Python
//! drives in chunks (for progress bars), with the GIL released while it steps.

use crate::{array2, array3, to_py_err, Context};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::dynamics::{CommandSchedule, DynOptions, Initial, Scheme, SigmaMap, Simulator};
use softrod_core::interp::GridPchip;
use softrod_core::marker::Marker;
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::statics::constraint::TipConstraint;
use softrod_core::{Rod, SoftrodError};

/// The binding's stiffness map of a rod's mapped sections: `sigma_const` (sigma for every
/// pressure) or `sigma_grid` = (axes, values, clamp), a PCHIP table over the channels'
/// pressures (values row-major, 3 per grid point); neither: no map.
pub(crate) type SigmaGrid = (Vec<Vec<f64>>, Vec<f64>, bool);

pub(crate) fn sigma_map(
    sigma_const: Option<[f64; 3]>,
    sigma_grid: Option<SigmaGrid>,
) -> Result<SigmaMap, SoftrodError> {
    Ok(match (sigma_const, sigma_grid) {
        (Some(s), _) => SigmaMap::Constant(s),
        (None, Some((axes, values, clamp))) => SigmaMap::Grid {
            grid: GridPchip::new(axes, values, 3)?,
            clamp,
        },
        (None, None) => SigmaMap::None,
    })
}

/// A running simulation of a design (see `softrod.dynamics`).
#[pyclass(name = "Simulator", module = "softrod._core")]
pub struct PySimulator {
    sim: Simulator,
}

/// What a chunk of steps keeps.
#[derive(Default)]
struct Saved {
    time: Vec<f64>,
    pressure: Vec<f64>,
    /// Tendon tensions (N) per sample: those held over the step that ended there.
    tension: Vec<f64>,
    tip_position: Vec<[f64; 3]>,
    tip_rotation: Vec<[[f64; 3]; 3]>,
    tip_velocity: Vec<[f64; 3]>,
    /// The wrench a pinned or clamped tip's constraint applies (world, N and N m).
    tip_reaction_force: Vec<[f64; 3]>,
    tip_reaction_moment: Vec<[f64; 3]>,
    energy: Vec<f64>,
    /// kinetic, elastic, potential, work in, dissipated (J) per sample.
    books: Vec<[f64; 5]>,
    /// Total contact force (N, world frame) and deepest penetration (m, <= 0: none) per
    /// sample, for a rod with obstacles.
    contact_force: Vec<[f64; 3]>,
    penetration: Vec<f64>,
    shape_time: Vec<f64>,
    shape: Vec<[f64; 3]>,
    /// d tip / d theta per sample (3 x P, row-major) when sensitivities are tracked.
    d_tip: Vec<f64>,
    n_par: usize,
    /// The markers' positions per sample (`set_markers`; K per sample) and, when
    /// sensitivities are tracked, their derivatives (K x 3 x P, row-major).
    markers: Vec<[f64; 3]>,
    d_markers: Vec<f64>,
    n_markers: usize,
}

impl Saved {
    fn push(&mut self, sim: &Simulator, energy: bool) {
        let tip = sim.tip();
        self.time.push(sim.time());
        self.pressure.extend_from_slice(sim.pressures());
        self.tension.extend_from_slice(sim.tensions());
        self.tip_position.push(tip.r);
        self.tip_rotation.push(tip.rot);
        self.tip_velocity.push(sim.tip_velocity());
        let (rf, rm) = sim.tip_reaction();
        self.tip_reaction_force.push(rf);
        self.tip_reaction_moment.push(rm);
        let b = sim.energy_books();
        self.energy.push(if energy { b.total() } else { f64::NAN });
        self.books.push(if energy {
            [b.kinetic, b.elastic, b.potential, b.work_in, b.dissipated]
        } else {
            [f64::NAN; 5]
        });
        if let Some(c) = sim.contact_state() {
            self.contact_force.push(c.force);
            self.penetration.push(c.max_penetration);
        }
        if let Some(d) = sim.tip_sensitivity() {
            self.n_par = d.len();
            for a in 0..3 {
                self.d_tip.extend(d.iter().map(|dj| dj[a]));
            }
        }
        if self.n_markers > 0 {
            self.markers.extend(sim.marker_positions());
            if let Some(d) = sim.marker_sensitivity() {
                for k in 0..self.n_markers {
                    for a in 0..3 {
                        self.d_markers.extend(d.iter().map(|dj| dj[k][a]));
                    }
                }
            }
        }
    }

    fn push_shape(&mut self, sim: &Simulator) {
        self.shape_time.push(sim.time());
        self.shape.extend_from_slice(sim.shape());
    }

    fn into_dict<'py>(
        self,
        py: Python<'py>,
        n_channels: usize,
        n_tendons: usize,
        nodes: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let n = self.time.len();
        d.set_item("time", PyArray1::from_vec(py, self.time))?;
        d.set_item(
            "pressure",
            PyArray1::from_vec(py, self.pressure).reshape([n, n_channels])?,
        )?;
        d.set_item(
            "tension",
            PyArray1::from_vec(py, self.tension).reshape([n, n_tendons])?,
        )?;
        d.set_item("tip_position", array2(py, &self.tip_position)?)?;
        d.set_item("tip_rotation", array3(py, &self.tip_rotation)?)?;
        d.set_item("tip_velocity", array2(py, &self.tip_velocity)?)?;
        d.set_item("tip_reaction_force", array2(py, &self.tip_reaction_force)?)?;
        d.set_item(
            "tip_reaction_moment",
            array2(py, &self.tip_reaction_moment)?,
        )?;
        d.set_item("energy", PyArray1::from_vec(py, self.energy))?;
        for (k, name) in ["kinetic", "elastic", "potential", "work_in", "dissipated"]
            .iter()
            .enumerate()
        {
            let col: Vec<f64> = self.books.iter().map(|b| b[k]).collect();
            d.set_item(*name, PyArray1::from_vec(py, col))?;
        }
        if !self.penetration.is_empty() {
            d.set_item("contact_force", array2(py, &self.contact_force)?)?;
            d.set_item("penetration", PyArray1::from_vec(py, self.penetration))?;
        }
        let k = self.shape_time.len();
        d.set_item("shape_time", PyArray1::from_vec(py, self.shape_time))?;
        let flat: Vec<f64> = self.shape.iter().flatten().copied().collect();
        d.set_item(
            "shape_position",
            PyArray1::from_vec(py, flat).reshape([k, nodes, 3])?,
        )?;
        if self.n_par > 0 {
            d.set_item(
                "d_tip_position",
                PyArray1::from_vec(py, self.d_tip).reshape([n, 3, self.n_par])?,
            )?;
        }
        let k = self.n_markers;
        if k > 0 {
            let flat: Vec<f64> = self.markers.iter().flatten().copied().collect();
            d.set_item(
                "marker_position",
                PyArray1::from_vec(py, flat).reshape([n, k, 3])?,
            )?;
            if self.n_par > 0 {
                d.set_item(
                    "d_marker_position",
                    PyArray1::from_vec(py, self.d_markers).reshape([n, k, 3, self.n_par])?,
                )?;
            }
        }
        Ok(d)
    }
}

#[pymethods]
impl PySimulator {
    /// Start at t = 0 from `initial` ("static": at rest in equilibrium under `pressures`;
    /// "straight": at rest in the straight shape; "reference": at rest in the reference
    /// shape, the two released at t = 0 with no internal force) with chamber pressures (Pa).
    /// `scheme`: "bdf-alpha" or "midpoint"; `error_tol` (m): adaptive steps; `sigma_const`
    /// or `sigma_grid` = (axes, values, clamp): the stiffness map of mapped sections;
    /// `tip_force`, `tip_moment`: tip loads at t = 0 in the design's tip frame; `tensions`:
    /// tendon tensions at t = 0 (N, one per tendon channel; None: slack); `tip_kind`
    /// ("free", "pinned", "clamped") with `tip_position` (m, world) and `tip_rotation`
    /// (row-major): how the tip is held at t = 0.
    #[new]
    #[pyo3(signature = (spec_json, pressures, initial="static", dt=2e-3, alpha=-0.2, tol=1e-9, max_iter=25, scheme="bdf-alpha", error_tol=None, energy_tol=softrod_core::dynamics::DEFAULT_ENERGY_TOL, sigma_const=None, sigma_grid=None, tip_force=None, tip_moment=None, tensions=None, tip_kind="free", tip_position=None, tip_rotation=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        spec_json: &str,
        pressures: Vec<f64>,
        initial: &str,
        dt: f64,
        alpha: f64,
        tol: f64,
        max_iter: usize,
        scheme: &str,
        error_tol: Option<f64>,
        energy_tol: f64,
        sigma_const: Option<[f64; 3]>,
        sigma_grid: Option<SigmaGrid>,
        tip_force: Option<[f64; 3]>,
        tip_moment: Option<[f64; 3]>,
        tensions: Option<Vec<f64>>,
        tip_kind: &str,
        tip_position: Option<[f64; 3]>,
        tip_rotation: Option<[[f64; 3]; 3]>,
    ) -> PyResult<Self> {
        crate::guarded(py, || {
            let spec = crate::parse_spec(py, spec_json)?;
            let rod = Rod::new(spec).map_err(|e| to_py_err(py, e, Context::Design))?;
            let input = |e: SoftrodError| to_py_err(py, e, Context::Input);
            let initial = match initial {
                "static" => Initial::Static,
                "straight" => Initial::Straight,
                "reference" => Initial::Reference,
                other => {
                    return Err(input(SoftrodError::invalid(
                        "initial",
                        other,
                        "must be 'static', 'straight' or 'reference'",
                    )))
                }
            };
            let scheme = match scheme {
                "bdf-alpha" => Scheme::BdfAlpha,
                "midpoint" => Scheme::Midpoint,
                other => {
                    return Err(input(SoftrodError::invalid(
                        "scheme",
                        other,
                        "must be 'bdf-alpha' or 'midpoint'",
                    )))
                }
            };
            let map = sigma_map(sigma_const, sigma_grid).map_err(input)?;
            let opts = DynOptions {
                dt,
                scheme,
                alpha,
                tol,
                max_iter,
                error_tol,
                energy_tol,
            };
            let tf = tip_force.unwrap_or(rod.spec.tip.force);
            let tm = tip_moment.unwrap_or(rod.spec.tip.moment);
            let tensions = tensions.unwrap_or_else(|| vec![0.0; rod.n_tendons]);
            let held = crate::ends::constraint(py, tip_kind, tip_position, tip_rotation)?;
            let sim = py
                .detach(|| {
                    Simulator::with_constraint(
                        rod, &pressures, &tensions, initial, opts, map, tf, tm, held,
                    )
                })
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            Ok(PySimulator { sim })
        })
    }

    /// The complete state as numbers (see `Simulator::save`).
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        crate::guarded(py, || Ok(PyArray1::from_vec(py, self.sim.save())))
    }

    /// Continue from a saved state (see `Simulator::restore`).
    fn restore(&mut self, py: Python<'_>, state: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        crate::guarded(py, || {
            let data = state.as_array().to_vec();
            self.sim
                .restore(&data)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// An independent copy of this simulation's current state.
    fn copy(&self, py: Python<'_>) -> PyResult<Self> {
        crate::guarded(py, || {
            Ok(PySimulator {
                sim: self.sim.clone(),
            })
        })
    }

    /// Track the tip's derivatives with respect to `params` ((kind, sections) pairs, kinds
    /// as in `softrod_core::sensitivity::ParamKind::ALL`) from now on (before the first
    /// step); `run` then returns them as `d_tip_position` (k, 3, P).
    fn track_sensitivities(
        &mut self,
        py: Python<'_>,
        params: Vec<(String, Vec<usize>)>,
    ) -> PyResult<()> {
        crate::guarded(py, || {
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
            let sim = &mut self.sim;
            py.detach(|| sim.track_sensitivities(&params))
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Read the markers `markers` ((s, offset) pairs: reference arc length in [0, L], m,
    /// and offset in the cross-section frame, m) from now on (before
    /// `track_sensitivities`): `run` and `snapshot` then return their positions as
    /// `marker_position` (k, K, 3) and, with sensitivities, `d_marker_position`
    /// (k, K, 3, P). Errors name `markers[k]`.
    fn set_markers(&mut self, py: Python<'_>, markers: Vec<(f64, [f64; 3])>) -> PyResult<()> {
        crate::guarded(py, || {
            let markers: Vec<Marker> = markers
                .into_iter()
                .map(|(s, offset)| Marker { s, offset })
                .collect();
            self.sim
                .set_markers(&markers)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Time now, s.
    #[getter]
    fn time(&self) -> f64 {
        self.sim.time()
    }

    /// The 'static' start's stability verdict (None: not assessed or a 'straight' start).
    #[getter]
    fn start_stable(&self) -> Option<bool> {
        self.sim.start_stable()
    }

    /// Time step, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.sim.dt()
    }

    #[getter]
    fn n_channels(&self) -> usize {
        self.sim.rod().n_channels
    }

    /// Chamber pressures now, Pa.
    #[getter]
    fn pressures(&self) -> Vec<f64> {
        self.sim.pressures().to_vec()
    }

    /// Tendon tensions now (those of the next step), N.
    #[getter]
    fn tensions(&self) -> Vec<f64> {
        self.sim.tensions().to_vec()
    }

    /// Tendon tensions (N, one per tendon channel, each >= 0) from the next step on.
    fn set_tensions(&mut self, py: Python<'_>, tensions: Vec<f64>) -> PyResult<()> {
        crate::guarded(py, || {
            self.sim
                .set_tensions(&tensions)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Steps taken, Newton iterations and exact Jacobians computed.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let d = PyDict::new(py);
            let st = &self.sim.stats;
            d.set_item("steps", st.steps)?;
            d.set_item("internal_steps", st.internal_steps)?;
            d.set_item("rejected_steps", st.rejected)?;
            d.set_item("newton_iterations", st.newton_iterations)?;
            d.set_item("jacobians", st.jacobians)?;
            Ok(d)
        })
    }

    /// Tip force and moment (N and N m, in the design's tip frame: world for dead loads,
    /// body for follower loads) from the next step on.
    fn set_tip_loads(&mut self, py: Python<'_>, force: [f64; 3], moment: [f64; 3]) -> PyResult<()> {
        crate::guarded(py, || {
            self.sim
                .set_tip_loads(force, moment)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Move a held tip: its pose (`kind` the run's, `position` m, `rotation` row-major) at
    /// the end of the next step.
    #[pyo3(signature = (kind, position=None, rotation=None))]
    fn set_tip_pose(
        &mut self,
        py: Python<'_>,
        kind: &str,
        position: Option<[f64; 3]>,
        rotation: Option<[[f64; 3]; 3]>,
    ) -> PyResult<()> {
        crate::guarded(py, || {
            let pose = crate::ends::constraint(py, kind, position, rotation)?;
            self.sim
                .set_tip_pose(pose)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// The state now: time, pressures, tip pose and velocity, energy, base wrench, shape.
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let mut saved = Saved {
                n_markers: self.sim.marker_count(),
                ..Saved::default()
            };
            saved.push(&self.sim, true);
            saved.push_shape(&self.sim);
            let nodes = self.sim.shape().len();
            let rod = self.sim.rod();
            let d = saved.into_dict(py, rod.n_channels, rod.n_tendons, nodes)?;
            let (f, m) = self.sim.base_wrench();
            d.set_item("base_force", f.to_vec())?;
            d.set_item("base_moment", m.to_vec())?;
            d.set_item("shape_s", PyArray1::from_vec(py, self.sim.node_s()))?;
            let (tf, tm) = self.sim.tip_loads();
            d.set_item("tip_force", tf.to_vec())?;
            d.set_item("tip_moment", tm.to_vec())?;
            d.set_item("tensions", self.sim.tensions().to_vec())?;
            d.set_item("energy_balance", self.sim.energy_balance())?;
            let (kind, position, rotation) = match self.sim.tip_constraint() {
                TipConstraint::Free => ("free", [0.0; 3], [[0.0; 3]; 3]),
                TipConstraint::Pinned { position } => ("pinned", position, [[0.0; 3]; 3]),
                TipConstraint::Clamped { position, rotation } => ("clamped", position, rotation),
            };
            d.set_item("tip_kind", kind)?;
            d.set_item("tip_pose_position", position.to_vec())?;
            d.set_item("tip_pose_rotation", rotation.map(|r| r.to_vec()).to_vec())?;
            Ok(d)
        })
    }

    /// Take one step per row of `commands` (k, n_channels), Pa, the commanded pressures at
    /// each new step time, with the tip loads of `tip_loads` (k, 6: force N, moment N m, in
    /// the design's tip frame) and the tendon tensions of `tensions` (k, tendon channels,
    /// N) when given, held over each step, and a held tip's poses of `tip_poses` (k, 12:
    /// position m, rotation row-major, the run's kind) at each new step time. After step j
    /// the state is kept when `keep[j]` is
    /// 1 (tip) or 2 (tip and shape). Returns the kept samples as arrays.
    /// `schedule` = (knot times, knot rows, step kind): the commands of steps inside an
    /// interval (substeps, adaptive steps) come from it at their own times.
    #[pyo3(signature = (commands, keep, energy=true, tip_loads=None, schedule=None, tensions=None, tip_poses=None))]
    #[allow(clippy::too_many_arguments)]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        commands: PyReadonlyArray2<'_, f64>,
        keep: PyReadonlyArray1<'_, u8>,
        energy: bool,
        tip_loads: Option<PyReadonlyArray2<'_, f64>>,
        schedule: Option<(Vec<f64>, Vec<Vec<f64>>, bool)>,
        tensions: Option<PyReadonlyArray2<'_, f64>>,
        tip_poses: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let nc = self.sim.rod().n_channels;
            let cmd = commands.as_array().to_owned();
            let shape = cmd.shape().to_vec();
            if shape[1] != nc {
                return Err(to_py_err(
                    py,
                    SoftrodError::invalid(
                        "commands",
                        format!("{} columns", shape[1]),
                        format!("the design has {nc} pressure channels"),
                    ),
                    Context::Input,
                ));
            }
            let keep = keep.as_array().to_owned();
            if keep.len() != shape[0] {
                return Err(to_py_err(
                    py,
                    SoftrodError::invalid(
                        "keep",
                        format!("{} flags", keep.len()),
                        format!("needs one flag per command row ({})", shape[0]),
                    ),
                    Context::Input,
                ));
            }
            let table = match schedule {
                Some((t, v, step)) => Some(
                    CommandSchedule::new(t, v, step, nc)
                        .map_err(|e| to_py_err(py, e, Context::Input))?,
                ),
                None => None,
            };
            let loads = tip_loads.map(|a| a.as_array().to_owned());
            if let Some(l) = &loads {
                if l.shape() != [shape[0], 6] {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            "tip_loads",
                            format!("shape {:?}", l.shape()),
                            format!("must be ({}, 6): force and moment per step", shape[0]),
                        ),
                        Context::Input,
                    ));
                }
            }
            let poses = tip_poses.map(|a| a.as_array().to_owned());
            let held = self.sim.tip_constraint();
            let mut pose_rows = Vec::new();
            if let Some(p) = &poses {
                if p.shape() != [shape[0], 12] {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            "tip_poses",
                            format!("shape {:?}", p.shape()),
                            format!(
                                "must be ({}, 12): position and rotation (row-major) per step",
                                shape[0]
                            ),
                        ),
                        Context::Input,
                    ));
                }
                // Every pose checked before any step (a bad one is refused before work).
                for (j, row) in p.rows().into_iter().enumerate() {
                    let position = [row[0], row[1], row[2]];
                    let rotation =
                        std::array::from_fn(|i| std::array::from_fn(|k| row[3 + 3 * i + k]));
                    let pose = match held {
                        TipConstraint::Free => TipConstraint::Free,
                        TipConstraint::Pinned { .. } => TipConstraint::Pinned { position },
                        TipConstraint::Clamped { .. } => {
                            TipConstraint::Clamped { position, rotation }
                        }
                    };
                    pose.validate().map_err(|e| {
                        let e = match e {
                            SoftrodError::InvalidParameter { field, value, rule } => {
                                SoftrodError::InvalidParameter {
                                    field: field.replacen(
                                        "tip_constraint",
                                        &format!("tip_poses[{j}]"),
                                        1,
                                    ),
                                    value,
                                    rule,
                                }
                            }
                            other => other,
                        };
                        to_py_err(py, e, Context::Input)
                    })?;
                    pose_rows.push(pose);
                }
            }
            let tens = tensions.map(|a| a.as_array().to_owned());
            let nt = self.sim.rod().n_tendons;
            if let Some(t) = &tens {
                if t.shape() != [shape[0], nt] {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            "tensions",
                            format!("shape {:?}", t.shape()),
                            format!(
                                "must be ({}, {nt}): one tension (N) per tendon channel per step",
                                shape[0]
                            ),
                        ),
                        Context::Input,
                    ));
                }
                // Every row checked before any step (a bad value is refused before work).
                for (j, row) in t.rows().into_iter().enumerate() {
                    softrod_core::spec::validate_tensions(&row.to_vec(), nt).map_err(|e| {
                        let e = match e {
                            SoftrodError::InvalidParameter { field, value, rule } => {
                                SoftrodError::InvalidParameter {
                                    // Row j: "tensions[j][k]".
                                    field: field.replacen("tensions", &format!("tensions[{j}]"), 1),
                                    value,
                                    rule,
                                }
                            }
                            other => other,
                        };
                        to_py_err(py, e, Context::Input)
                    })?;
                }
            }
            let sim = &mut self.sim;
            let result = py.detach(|| -> Result<Saved, SoftrodError> {
                let mut saved = Saved {
                    n_markers: sim.marker_count(),
                    ..Saved::default()
                };
                for (j, (row, flag)) in cmd.rows().into_iter().zip(keep.iter()).enumerate() {
                    if let Some(t) = &tens {
                        sim.set_tensions(&t.row(j).to_vec())?;
                    }
                    if let Some(p) = pose_rows.get(j) {
                        sim.set_tip_pose(*p)?;
                    }
                    if let Some(l) = &loads {
                        sim.set_tip_loads(
                            [l[[j, 0]], l[[j, 1]], l[[j, 2]]],
                            [l[[j, 3]], l[[j, 4]], l[[j, 5]]],
                        )?;
                    }
                    let c: Vec<f64> = row.to_vec();
                    sim.step_with(&c, table.as_ref())?;
                    if *flag >= 1 {
                        saved.push(sim, energy);
                    }
                    if *flag >= 2 {
                        saved.push_shape(sim);
                    }
                }
                Ok(saved)
            });
            let saved = result.map_err(|e| to_py_err(py, e, Context::Input))?;
            let nodes = self.sim.shape().len();
            saved.into_dict(py, nc, self.sim.rod().n_tendons, nodes)
        })
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySimulator>()
}
