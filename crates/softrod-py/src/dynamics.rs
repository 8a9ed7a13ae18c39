//! Binding of the dynamic rod (`softrod_core::dynamics`): a stepper object that Python
//! drives in chunks (for progress bars), with the GIL released while it steps.

use crate::{array2, array3, to_py_err, Context};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::dynamics::{DynOptions, Initial, Simulator};
use softrod_core::{Rod, SoftrodError};

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
    tip_position: Vec<[f64; 3]>,
    tip_rotation: Vec<[[f64; 3]; 3]>,
    tip_velocity: Vec<[f64; 3]>,
    energy: Vec<f64>,
    shape_time: Vec<f64>,
    shape: Vec<[f64; 3]>,
}

impl Saved {
    fn push(&mut self, sim: &Simulator, energy: bool) {
        let tip = sim.tip();
        self.time.push(sim.time());
        self.pressure.extend_from_slice(sim.pressures());
        self.tip_position.push(tip.r);
        self.tip_rotation.push(tip.rot);
        self.tip_velocity.push(sim.tip_velocity());
        self.energy
            .push(if energy { sim.energy() } else { f64::NAN });
    }

    fn push_shape(&mut self, sim: &Simulator) {
        self.shape_time.push(sim.time());
        self.shape.extend_from_slice(sim.shape().1);
    }

    fn into_dict<'py>(
        self,
        py: Python<'py>,
        n_channels: usize,
        nodes: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let n = self.time.len();
        d.set_item("time", PyArray1::from_vec(py, self.time))?;
        d.set_item(
            "pressure",
            PyArray1::from_vec(py, self.pressure).reshape([n, n_channels])?,
        )?;
        d.set_item("tip_position", array2(py, &self.tip_position)?)?;
        d.set_item("tip_rotation", array3(py, &self.tip_rotation)?)?;
        d.set_item("tip_velocity", array2(py, &self.tip_velocity)?)?;
        d.set_item("energy", PyArray1::from_vec(py, self.energy))?;
        let k = self.shape_time.len();
        d.set_item("shape_time", PyArray1::from_vec(py, self.shape_time))?;
        let flat: Vec<f64> = self.shape.iter().flatten().copied().collect();
        d.set_item(
            "shape_position",
            PyArray1::from_vec(py, flat).reshape([k, nodes, 3])?,
        )?;
        Ok(d)
    }
}

#[pymethods]
impl PySimulator {
    /// Start at t = 0 from `initial` ("static": at rest in equilibrium under `pressures`;
    /// "straight": at rest in the straight reference shape) with chamber pressures (Pa).
    #[new]
    #[pyo3(signature = (spec_json, pressures, initial="static", dt=2e-3, alpha=-0.2, tol=1e-9, max_iter=25))]
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
    ) -> PyResult<Self> {
        let spec = crate::parse_spec(py, spec_json)?;
        let rod = Rod::new(spec).map_err(|e| to_py_err(py, e, Context::Design))?;
        let initial = match initial {
            "static" => Initial::Static,
            "straight" => Initial::Straight,
            other => {
                return Err(to_py_err(
                    py,
                    SoftrodError::invalid("initial", other, "must be 'static' or 'straight'"),
                    Context::Input,
                ))
            }
        };
        let opts = DynOptions {
            dt,
            alpha,
            tol,
            max_iter,
        };
        let sim = py
            .detach(|| Simulator::new(rod, &pressures, initial, opts))
            .map_err(|e| to_py_err(py, e, Context::Input))?;
        Ok(PySimulator { sim })
    }

    /// An independent copy of this simulation's current state.
    fn copy(&self) -> Self {
        PySimulator {
            sim: self.sim.clone(),
        }
    }

    /// Time now, s.
    #[getter]
    fn time(&self) -> f64 {
        self.sim.time()
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

    /// Steps taken, Newton iterations and exact Jacobians computed.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("steps", self.sim.stats.steps)?;
        d.set_item("newton_iterations", self.sim.stats.newton_iterations)?;
        d.set_item("jacobians", self.sim.stats.jacobians)?;
        Ok(d)
    }

    /// Dead tip force and moment (world, N and N m) from the next step on.
    fn set_tip_loads(&mut self, py: Python<'_>, force: [f64; 3], moment: [f64; 3]) -> PyResult<()> {
        self.sim
            .set_tip_loads(force, moment)
            .map_err(|e| to_py_err(py, e, Context::Input))
    }

    /// The state now: time, pressures, tip pose and velocity, energy, base wrench, shape.
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let mut saved = Saved::default();
        saved.push(&self.sim, true);
        saved.push_shape(&self.sim);
        let nodes = self.sim.shape().0.len();
        let d = saved.into_dict(py, self.sim.rod().n_channels, nodes)?;
        let (f, m) = self.sim.base_wrench();
        d.set_item("base_force", f.to_vec())?;
        d.set_item("base_moment", m.to_vec())?;
        d.set_item(
            "shape_s",
            PyArray1::from_vec(py, self.sim.shape().0.to_vec()),
        )?;
        Ok(d)
    }

    /// Take one step per row of `commands` (k, n_channels), Pa, the commanded pressures at
    /// each new step time. After step j the state is kept when `keep[j]` is 1 (tip) or 2
    /// (tip and shape). Returns the kept samples as arrays.
    #[pyo3(signature = (commands, keep, energy=true))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        commands: PyReadonlyArray2<'_, f64>,
        keep: PyReadonlyArray1<'_, u8>,
        energy: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
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
        let sim = &mut self.sim;
        let result = py.detach(|| -> Result<Saved, SoftrodError> {
            let mut saved = Saved::default();
            for (row, flag) in cmd.rows().into_iter().zip(keep.iter()) {
                let c: Vec<f64> = row.to_vec();
                sim.step(&c)?;
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
        let nodes = self.sim.shape().0.len();
        saved.into_dict(py, nc, nodes)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySimulator>()
}
