//! Binding of the dynamics of a system of rods and its platform
//! (`softrod_core::dynamics::system`): a stepper object that Python drives in chunks, with
//! the GIL released while it steps.

use crate::dynamics::{sigma_map, SigmaGrid};
use crate::ends::{platform_of, system_markers, system_params, PlatformEntry, SystemParamEntry};
use crate::{to_py_err, Context, PyRod};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::dynamics::system::{DynRod, SystemSimulator};
use softrod_core::dynamics::{DynOptions, Scheme, SigmaMap};
use softrod_core::SoftrodError;

/// A running simulation of a system (see `softrod.SystemSimulation`).
#[pyclass(name = "SystemSimulator", module = "softrod._core")]
pub struct PySystemSimulator {
    sim: SystemSimulator,
}

/// One rod: (rod, pressures, tensions, attachment offset, attachment rotation).
type DynRodEntry<'py> = (
    PyRef<'py, PyRod>,
    Vec<f64>,
    Vec<f64>,
    [f64; 3],
    [[f64; 3]; 3],
);

/// One rod's stiffness map: (`sigma_const`, `sigma_grid`) as `Simulator` takes them.
type SigmaEntry = (Option<[f64; 3]>, Option<SigmaGrid>);

/// The samples of a chunk of steps, as flat lists.
#[derive(Default)]
struct Samples {
    time: Vec<f64>,
    platform_position: Vec<f64>,
    platform_rotation: Vec<f64>,
    platform_velocity: Vec<f64>,
    platform_angular_velocity: Vec<f64>,
    tip_position: Vec<f64>,
    tip_reaction_force: Vec<f64>,
    tip_reaction_moment: Vec<f64>,
    /// Per rod: its node positions, sample after sample.
    shapes: Vec<Vec<f64>>,
    /// Per rod: its commanded chamber pressures (Pa) and tendon tensions (N), sample
    /// after sample (the inputs of the step that ended at the sample).
    pressures: Vec<Vec<f64>>,
    tensions: Vec<Vec<f64>>,
    /// Per rod with obstacles: the total contact force on it (N, world) and its deepest
    /// penetration (m, <= 0: none), sample after sample (empty for a rod without).
    contact_force: Vec<Vec<f64>>,
    penetration: Vec<Vec<f64>>,
    /// kinetic, elastic, potential, work in, dissipated, balance (J) per sample.
    energy: Vec<f64>,
    /// The markers' positions (K x 3 per sample) and, with sensitivities tracked, the
    /// derivatives of the platform's position (3 x P), rotation (3 x 3 x P) and the markers
    /// (K x 3 x P) per sample.
    marker_position: Vec<f64>,
    d_platform_position: Vec<f64>,
    d_platform_rotation: Vec<f64>,
    d_marker_position: Vec<f64>,
}

impl Samples {
    fn push(&mut self, sim: &SystemSimulator) {
        self.time.push(sim.time());
        let (p, r) = sim.platform_pose();
        let (v, w) = sim.platform_velocity();
        self.platform_position.extend_from_slice(&p);
        self.platform_rotation.extend(r.iter().flatten());
        self.platform_velocity.extend_from_slice(&v);
        self.platform_angular_velocity.extend_from_slice(&w);
        let n = sim.rods().len();
        for list in [
            &mut self.shapes,
            &mut self.pressures,
            &mut self.tensions,
            &mut self.contact_force,
            &mut self.penetration,
        ] {
            list.resize(n, vec![]);
        }
        for (k, rod) in sim.rods().iter().enumerate() {
            self.tip_position.extend_from_slice(&rod.tip().r);
            let (f, m) = rod.tip_reaction();
            self.tip_reaction_force.extend_from_slice(&f);
            self.tip_reaction_moment.extend_from_slice(&m);
            self.shapes[k].extend(rod.shape().iter().flatten());
            self.pressures[k].extend_from_slice(rod.pressures());
            self.tensions[k].extend_from_slice(rod.tensions());
            if let Some(c) = rod.contact_state() {
                self.contact_force[k].extend_from_slice(&c.force);
                self.penetration[k].push(c.max_penetration);
            }
        }
        for m in sim.marker_positions() {
            self.marker_position.extend_from_slice(&m);
        }
        if let (Some(dp), Some(dr), Some(dm)) = (
            sim.platform_position_sensitivity(),
            sim.platform_rotation_sensitivity(),
            sim.marker_sensitivity(),
        ) {
            for a in 0..3 {
                self.d_platform_position.extend(dp.iter().map(|d| d[a]));
            }
            for a in 0..3 {
                for c in 0..3 {
                    self.d_platform_rotation.extend(dr.iter().map(|d| d[a][c]));
                }
            }
            let k = dm.first().map_or(0, Vec::len);
            for m in 0..k {
                for a in 0..3 {
                    self.d_marker_position.extend(dm.iter().map(|d| d[m][a]));
                }
            }
        }
        let e = sim.energy_books();
        self.energy.extend_from_slice(&[
            e.kinetic,
            e.elastic,
            e.potential,
            e.work_in,
            e.dissipated,
            sim.energy_balance(),
        ]);
    }

    fn into_dict<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("time", self.time)?;
        d.set_item("platform_position", self.platform_position)?;
        d.set_item("platform_rotation", self.platform_rotation)?;
        d.set_item("platform_velocity", self.platform_velocity)?;
        d.set_item("platform_angular_velocity", self.platform_angular_velocity)?;
        d.set_item("tip_position", self.tip_position)?;
        d.set_item("tip_reaction_force", self.tip_reaction_force)?;
        d.set_item("tip_reaction_moment", self.tip_reaction_moment)?;
        d.set_item("shapes", self.shapes)?;
        d.set_item("pressures", self.pressures)?;
        d.set_item("tensions", self.tensions)?;
        d.set_item("contact_force", self.contact_force)?;
        d.set_item("penetration", self.penetration)?;
        d.set_item("energy", self.energy)?;
        d.set_item("marker_position", self.marker_position)?;
        d.set_item("d_platform_position", self.d_platform_position)?;
        d.set_item("d_platform_rotation", self.d_platform_rotation)?;
        d.set_item("d_marker_position", self.d_marker_position)?;
        Ok(d)
    }
}

#[pymethods]
impl PySystemSimulator {
    /// Start at rest in the system's static equilibrium (`SystemSimulator::new`).
    /// `sigma_maps`: per rod, the stiffness map of its mapped sections as
    /// (`sigma_const`, `sigma_grid`) of `Simulator` ((None, None): no map; None: no rod has
    /// one); sigma is evaluated in the core at every step's pressures.
    #[new]
    #[pyo3(signature = (rods, platform, inertia, dt, alpha, tol, max_iter, scheme, error_tol, energy_tol, sigma_maps=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        rods: Vec<DynRodEntry<'_>>,
        platform: PlatformEntry,
        inertia: [[f64; 3]; 3],
        dt: f64,
        alpha: f64,
        tol: f64,
        max_iter: usize,
        scheme: &str,
        error_tol: Option<f64>,
        energy_tol: f64,
        sigma_maps: Option<Vec<SigmaEntry>>,
    ) -> PyResult<Self> {
        crate::guarded(py, || {
            let scheme = match scheme {
                "bdf-alpha" => Scheme::BdfAlpha,
                "midpoint" => Scheme::Midpoint,
                other => {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid("scheme", other, "must be 'bdf-alpha' or 'midpoint'"),
                        Context::Input,
                    ))
                }
            };
            let opts = DynOptions {
                dt,
                scheme,
                alpha,
                tol,
                max_iter,
                error_tol,
                energy_tol,
            };
            let input = |e: SoftrodError| to_py_err(py, e, Context::Input);
            let maps: Vec<SigmaMap> = match sigma_maps {
                None => vec![SigmaMap::None; rods.len()],
                Some(m) if m.len() != rods.len() => {
                    return Err(input(SoftrodError::invalid(
                        "sigma_maps",
                        format!("{} entries", m.len()),
                        format!("one entry per rod: {} rods", rods.len()),
                    )))
                }
                Some(m) => m
                    .into_iter()
                    .enumerate()
                    .map(|(i, (c, g))| {
                        sigma_map(c, g).map_err(|e| {
                            input(match e {
                                SoftrodError::InvalidParameter { field, value, rule } => {
                                    SoftrodError::InvalidParameter {
                                        field: format!("sigma_maps[{i}].{field}"),
                                        value,
                                        rule,
                                    }
                                }
                                other => other,
                            })
                        })
                    })
                    .collect::<PyResult<_>>()?,
            };
            let rods: Vec<DynRod> = rods
                .iter()
                .zip(maps)
                .map(|((r, p, t, o, a), sigma_map)| DynRod {
                    rod: r.rod.clone(),
                    pressures: p.clone(),
                    tensions: t.clone(),
                    sigma_map,
                    attachment: *o,
                    attachment_rotation: *a,
                })
                .collect();
            let pf = platform_of(platform);
            let sim = py
                .detach(|| SystemSimulator::new(rods, pf, inertia, opts))
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            Ok(PySystemSimulator { sim })
        })
    }

    /// Time now, s.
    fn time(&self) -> f64 {
        self.sim.time()
    }

    /// Track the derivatives of the platform's pose and the markers with respect to
    /// `params` ((kind, [(rod, sections)]) entries, kinds as
    /// `softrod_core::sensitivity::ParamKind::ALL` or "platform_mass" with no rods) from
    /// now on (before the first step): `run` and `snapshot` then return
    /// "d_platform_position" (3 x P per sample), "d_platform_rotation" (3 x 3 x P) and
    /// "d_marker_position" (K x 3 x P). Errors name `params[j]`.
    fn track_sensitivities(
        &mut self,
        py: Python<'_>,
        params: Vec<SystemParamEntry>,
    ) -> PyResult<()> {
        crate::guarded(py, || {
            let params = system_params(params).map_err(|e| to_py_err(py, e, Context::Input))?;
            let sim = &mut self.sim;
            py.detach(|| sim.track_sensitivities(&params))
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// Read `markers` ((rod or None for the platform, s, offset) entries, m; a platform
    /// marker's s is 0) from now on (before `track_sensitivities`): "marker_position"
    /// (K x 3 per sample). Errors name `markers[k]`.
    fn set_markers(
        &mut self,
        py: Python<'_>,
        markers: Vec<(Option<usize>, f64, [f64; 3])>,
    ) -> PyResult<()> {
        crate::guarded(py, || {
            let markers = system_markers(markers).map_err(|e| to_py_err(py, e, Context::Input))?;
            self.sim
                .set_markers(&markers)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// The start's stability verdict (None: not assessed).
    #[getter]
    fn start_stable(&self) -> Option<bool> {
        self.sim.start_stable()
    }

    /// The state now as one sample (keys as `run`'s).
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let mut s = Samples::default();
            s.push(&self.sim);
            s.into_dict(py)
        })
    }

    /// Take one output step per entry of `commands` (per step, one list of pressures per
    /// rod, Pa), with `tensions` (per step, one list per rod, N) set before each step when
    /// given, and `platform_loads` (per step, force and moment) likewise; returns the
    /// samples after each step. Stops at the first error (raised; the steps before it are
    /// kept in the simulation).
    #[pyo3(signature = (commands, tensions=None, platform_loads=None))]
    #[allow(clippy::type_complexity)]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        commands: Vec<Vec<Vec<f64>>>,
        tensions: Option<Vec<Vec<Vec<f64>>>>,
        platform_loads: Option<Vec<([f64; 3], [f64; 3])>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        crate::guarded(py, || {
            let k = commands.len();
            for (name, n) in [
                ("tensions", tensions.as_ref().map(Vec::len)),
                ("platform_loads", platform_loads.as_ref().map(Vec::len)),
            ] {
                if let Some(n) = n.filter(|n| *n != k) {
                    return Err(to_py_err(
                        py,
                        SoftrodError::invalid(
                            name,
                            format!("{n} steps"),
                            format!("one entry per step: {k} steps"),
                        ),
                        Context::Input,
                    ));
                }
            }
            let sim = &mut self.sim;
            let out = py.detach(|| -> Result<Samples, SoftrodError> {
                let mut s = Samples::default();
                for (j, c) in commands.iter().enumerate() {
                    if let Some(t) = &tensions {
                        for (i, ti) in t[j].iter().enumerate() {
                            sim.set_tensions(i, ti)?;
                        }
                    }
                    if let Some(l) = &platform_loads {
                        sim.set_platform_loads(l[j].0, l[j].1)?;
                    }
                    sim.step(c)?;
                    s.push(sim);
                }
                Ok(s)
            });
            out.map_err(|e| to_py_err(py, e, Context::Input))?
                .into_dict(py)
        })
    }

    /// Change the platform's force (N, world) and moment (N m, world) from the next step.
    fn set_platform_loads(
        &mut self,
        py: Python<'_>,
        force: [f64; 3],
        moment: [f64; 3],
    ) -> PyResult<()> {
        crate::guarded(py, || {
            self.sim
                .set_platform_loads(force, moment)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// The platform's external force (N, world) and moment (N m, world) now.
    fn platform_loads(&self) -> ([f64; 3], [f64; 3]) {
        self.sim.platform_loads()
    }

    /// Counters of the run so far.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.sim.stats;
        let d = PyDict::new(py);
        d.set_item("steps", s.steps)?;
        d.set_item("internal_steps", s.internal_steps)?;
        d.set_item("rejected", s.rejected)?;
        d.set_item("newton_iterations", s.newton_iterations)?;
        d.set_item("jacobians", s.jacobians)?;
        Ok(d)
    }

    /// The complete state as numbers (see `SystemSimulator::save`).
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        crate::guarded(py, || Ok(PyArray1::from_vec(py, self.sim.save())))
    }

    /// Continue from a saved state (see `SystemSimulator::restore`).
    fn restore(&mut self, py: Python<'_>, state: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        crate::guarded(py, || {
            let data = state.as_array().to_vec();
            self.sim
                .restore(&data)
                .map_err(|e| to_py_err(py, e, Context::Input))
        })
    }

    /// An independent copy of this simulation's current state.
    fn copy(&self) -> Self {
        PySystemSimulator {
            sim: self.sim.clone(),
        }
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySystemSimulator>()
}
