//! The static solves of one rod, free or held (`Rod.solve`, `Rod.solve_batch`,
//! `solve_constrained_tip`, `solve_constrained_tip_batch`): one body each for a single
//! equilibrium and for a batch, the tip's constraint an argument. No physics here.

use crate::{
    array2, contact_dict, contact_forces, rows_dict, solution_dict, to_py_err, Context,
    PyFrictionState, PyRod,
};
use numpy::PyReadonlyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::batch::{
    solve_constrained_batch, solve_held_friction_batch, BatchInputs, BatchRow,
};
use softrod_core::ode::Loads;
use softrod_core::statics::constraint::{solve_constrained, ConstrainedSolution, TipConstraint};
use softrod_core::statics::{friction, SolverOptions};

/// The inputs of one equilibrium (SI; tip loads in the design's tip frame).
pub(crate) struct One<'py> {
    pub pressures: Vec<f64>,
    pub tensions: Option<Vec<f64>>,
    pub tip_force: [f64; 3],
    pub tip_moment: [f64; 3],
    /// sigma of the mapped sections; None: ones, refused for a design with one.
    pub stiffness_scale: Option<[f64; 3]>,
    pub guess: Option<Vec<f64>>,
    pub friction_steps: usize,
    pub history: Option<PyRef<'py, PyFrictionState>>,
}

/// One equilibrium with the tip `held` (free, pinned or clamped): the dict of `Rod.solve`
/// ("contact" with obstacles, "friction_state" on a frictional path), plus the tip's
/// reaction ("tip_reaction_force", "tip_reaction_moment") where `with_reaction`.
pub(crate) fn solve_one<'py>(
    py: Python<'py>,
    rod: &PyRod,
    held: TipConstraint,
    input: One<'py>,
    opts: &SolverOptions,
    with_reaction: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let rod = &rod.rod;
    let frictional = friction::has_friction(rod);
    friction::check_history_wanted(rod, input.history.is_some())
        .map_err(|e| to_py_err(py, e, Context::Input))?;
    let history = input.history.map(|h| h.path.clone());
    let sigma =
        softrod_core::statics::system::lone_sigma("stiffness_scale", rod, input.stiffness_scale)
            .map_err(|e| to_py_err(py, e, Context::Input))?;
    let loads = Loads {
        pressures: input.pressures,
        tensions: input.tensions.unwrap_or_default(),
        tip_force: input.tip_force,
        tip_moment: input.tip_moment,
        tip_frame: rod.spec.tip.frame,
        stiffness_scale: sigma,
    };
    let (steps, guess) = (input.friction_steps, input.guess);
    let (out, contact) = py
        .detach(|| {
            let out = match (frictional, held) {
                (true, TipConstraint::Free) => {
                    let (solution, shape) =
                        friction::solve_with_shape(rod, &loads, history.as_deref(), steps, opts)?;
                    ConstrainedSolution {
                        solution,
                        shape,
                        tip_reaction_force: [0.0; 3],
                        tip_reaction_moment: [0.0; 3],
                    }
                }
                (true, _) => {
                    friction::solve_held(rod, &loads, &held, history.as_deref(), steps, opts)?
                }
                (false, _) => solve_constrained(rod, &loads, &held, guess.as_deref(), opts)?,
            };
            let contact = softrod_core::statics::contact::report(rod, &loads, &out.solution)?;
            Ok((out, contact))
        })
        .map_err(|e| to_py_err(py, e, Context::Input))?;
    let d = solution_dict(py, &out.solution, &out.shape)?;
    if with_reaction {
        d.set_item("tip_reaction_force", out.tip_reaction_force.to_vec())?;
        d.set_item("tip_reaction_moment", out.tip_reaction_moment.to_vec())?;
    }
    if let Some(rep) = &contact {
        d.set_item("contact", contact_dict(py, rep)?)?;
    }
    if let Some(path) = &out.solution.friction {
        d.set_item(
            "friction_state",
            Py::new(py, PyFrictionState { path: path.clone() })?,
        )?;
    }
    Ok(d)
}

/// The inputs of a batch: (m, channels) pressures, optional (m, 3) stiffness scales and
/// (m, tendon channels) tensions.
pub(crate) struct Rows<'py> {
    pub pressures: PyReadonlyArray2<'py, f64>,
    pub stiffness_scale: Option<PyReadonlyArray2<'py, f64>>,
    pub tensions: Option<PyReadonlyArray2<'py, f64>>,
    pub tip_force: [f64; 3],
    pub tip_moment: [f64; 3],
    pub friction_steps: usize,
}

/// Every row solved in parallel (GIL released), each as [`solve_one`] solves it alone:
/// the dict of `Rod.solve_batch` ("contact_force" and "friction_force" on frictional
/// paths), plus the reactions (m, 3) where `with_reaction`.
pub(crate) fn solve_rows<'py>(
    py: Python<'py>,
    rod: &PyRod,
    held: TipConstraint,
    input: Rows<'py>,
    opts: &SolverOptions,
    threads: usize,
    with_reaction: bool,
) -> PyResult<Bound<'py, PyDict>> {
    rod.check_columns(py, &input.pressures)?;
    // Copy into owned Rust data before releasing the GIL.
    let owned =
        |a: &PyReadonlyArray2<'py, f64>| -> Vec<f64> { a.as_array().iter().copied().collect() };
    let flat = owned(&input.pressures);
    let sigma = input.stiffness_scale.as_ref().map(owned);
    let tens = input.tensions.as_ref().map(owned);
    let (tip_force, tip_moment, steps) = (input.tip_force, input.tip_moment, input.friction_steps);
    let rod = &rod.rod;
    let frictional = friction::has_friction(rod);
    let rows = py
        .detach(|| {
            let inputs = BatchInputs {
                pressures: &flat,
                tensions: tens.as_deref(),
                stiffness_scale: sigma.as_deref(),
                tip_force,
                tip_moment,
            };
            // Both hand a free tip to the free batches (`batch::solve_batch`,
            // `batch::solve_friction_batch`).
            if frictional {
                solve_held_friction_batch(rod, &inputs, &held, steps, opts, threads)
            } else {
                solve_constrained_batch(rod, &inputs, &held, opts, threads)
            }
        })
        .map_err(|e| to_py_err(py, e, Context::Input))?;
    let d = rows_dict(py, &rows)?;
    if with_reaction {
        reactions(py, &d, &rows)?;
    }
    if frictional {
        contact_forces(py, &d, &rows, rod.spec.obstacles.len())?;
    }
    Ok(d)
}

/// The tip reactions of batch rows as (m, 3) arrays.
pub(crate) fn reactions(py: Python<'_>, d: &Bound<'_, PyDict>, rows: &[BatchRow]) -> PyResult<()> {
    let f: Vec<[f64; 3]> = rows.iter().map(|r| r.tip_reaction_force).collect();
    let m: Vec<[f64; 3]> = rows.iter().map(|r| r.tip_reaction_moment).collect();
    d.set_item("tip_reaction_force", array2(py, &f)?)?;
    d.set_item("tip_reaction_moment", array2(py, &m)?)?;
    Ok(())
}
