//! Binding of the tip end constraints (`softrod_core::statics::constraint`) and of systems
//! of rods sharing a platform (`softrod_core::statics::system`). No physics here.

use crate::{guarded, options, solution_dict, to_py_err, Context, PyRod};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::ode::Loads;
use softrod_core::statics::constraint::{solve_constrained, ConstrainedSolution, TipConstraint};
use softrod_core::statics::system::{solve_system, Platform, SystemRod};
use softrod_core::SoftrodError;

/// The solution as `Rod.solve` gives it, with the tip reaction.
fn constrained_dict<'py>(py: Python<'py>, c: &ConstrainedSolution) -> PyResult<Bound<'py, PyDict>> {
    let d = solution_dict(py, &c.solution, &c.shape)?;
    d.set_item("tip_reaction_force", c.tip_reaction_force.to_vec())?;
    d.set_item("tip_reaction_moment", c.tip_reaction_moment.to_vec())?;
    Ok(d)
}

/// The core constraint of a kind name and its pose.
fn constraint(
    py: Python<'_>,
    kind: &str,
    position: Option<[f64; 3]>,
    rotation: Option<[[f64; 3]; 3]>,
) -> PyResult<TipConstraint> {
    let missing = |what: &str| {
        to_py_err(
            py,
            SoftrodError::invalid(
                format!("tip_constraint.{what}"),
                "(missing)",
                format!("a {kind} tip needs its {what}"),
            ),
            Context::Input,
        )
    };
    Ok(match kind {
        "free" => TipConstraint::Free,
        "pinned" => TipConstraint::Pinned {
            position: position.ok_or_else(|| missing("position"))?,
        },
        "clamped" => TipConstraint::Clamped {
            position: position.ok_or_else(|| missing("position"))?,
            rotation: rotation.ok_or_else(|| missing("orientation"))?,
        },
        other => {
            return Err(to_py_err(
                py,
                SoftrodError::invalid(
                    "tip_constraint.type",
                    other,
                    "must be 'free', 'pinned' or 'clamped'",
                ),
                Context::Input,
            ))
        }
    })
}

/// Solve one static equilibrium with the tip held by a constraint: `kind` "free",
/// "pinned" (needs `position`, world, m) or "clamped" (and `rotation`, row-major, the
/// tip frame's columns in the world). The dict of `solve` plus "tip_reaction_force"
/// and "tip_reaction_moment" (the wrench the constraint applies to the tip, world).
#[pyfunction]
#[pyo3(signature = (rod, pressures, tip_force, tip_moment, kind, position=None, rotation=None, guess=None, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), stiffness_scale=[1.0, 1.0, 1.0], on_invalid="raise", tensions=None))]
#[allow(clippy::too_many_arguments)]
fn solve_constrained_tip<'py>(
    py: Python<'py>,
    rod: PyRef<'py, PyRod>,
    pressures: Vec<f64>,
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    kind: &str,
    position: Option<[f64; 3]>,
    rotation: Option<[[f64; 3]; 3]>,
    guess: Option<Vec<f64>>,
    tol: f64,
    max_iter: usize,
    continuation: bool,
    max_load_steps: usize,
    stretch_range: (f64, f64),
    stiffness_scale: [f64; 3],
    on_invalid: &str,
    tensions: Option<Vec<f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let c = constraint(py, kind, position, rotation)?;
        let loads = Loads {
            pressures,
            tensions: tensions.unwrap_or_default(),
            tip_force,
            tip_moment,
            tip_frame: rod.rod.spec.tip.frame,
            stiffness_scale,
        };
        let opts = options(
            py,
            tol,
            max_iter,
            continuation,
            max_load_steps,
            stretch_range,
            on_invalid,
        )?;
        let rod = &rod.rod;
        let out = py
            .detach(|| solve_constrained(rod, &loads, &c, guess.as_deref(), &opts))
            .map_err(|e| to_py_err(py, e, Context::Input))?;
        constrained_dict(py, &out)
    })
}

/// One rod of a system: (rod, pressures, tensions, tip force, tip moment, attachment
/// offset, attachment rotation).
type RodEntry<'py> = (
    PyRef<'py, PyRod>,
    Vec<f64>,
    Vec<f64>,
    [f64; 3],
    [f64; 3],
    [f64; 3],
    [[f64; 3]; 3],
);

/// Solve a system of rods whose tips hold one platform (GIL released). `rods`: entries
/// as `RodEntry`; `platform`: (position, rotation, force, moment, mass, com_offset,
/// gravity). Returns {"rods": [dicts as `Rod.solve_constrained`], "platform_position",
/// "platform_rotation", "x", "iterations", "residual", "load_steps"}.
#[pyfunction]
#[pyo3(signature = (rods, platform, guess=None, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), on_invalid="raise"))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn solve_rod_system<'py>(
    py: Python<'py>,
    rods: Vec<RodEntry<'py>>,
    platform: (
        [f64; 3],
        [[f64; 3]; 3],
        [f64; 3],
        [f64; 3],
        f64,
        [f64; 3],
        [f64; 3],
    ),
    guess: Option<Vec<f64>>,
    tol: f64,
    max_iter: usize,
    continuation: bool,
    max_load_steps: usize,
    stretch_range: (f64, f64),
    on_invalid: &str,
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
        let system: Vec<SystemRod> = rods
            .iter()
            .map(|(r, p, t, f, m, o, a)| SystemRod {
                rod: &r.rod,
                loads: Loads {
                    pressures: p.clone(),
                    tensions: t.clone(),
                    tip_force: *f,
                    tip_moment: *m,
                    tip_frame: r.rod.spec.tip.frame,
                    stiffness_scale: [1.0; 3],
                },
                attachment: *o,
                attachment_rotation: *a,
            })
            .collect();
        let (position, rotation, force, moment, mass, com_offset, gravity) = platform;
        let pf = Platform {
            position,
            rotation,
            force,
            moment,
            mass,
            com_offset,
            gravity,
        };
        let out = py
            .detach(|| solve_system(&system, &pf, guess.as_deref(), &opts))
            .map_err(|e| to_py_err(py, e, Context::Input))?;
        let d = PyDict::new(py);
        d.set_item(
            "rods",
            out.rods
                .iter()
                .map(|c| constrained_dict(py, c))
                .collect::<PyResult<Vec<_>>>()?,
        )?;
        d.set_item("platform_position", out.platform_position.to_vec())?;
        d.set_item(
            "platform_rotation",
            out.platform_rotation
                .iter()
                .map(|r| r.to_vec())
                .collect::<Vec<_>>(),
        )?;
        d.set_item("x", out.x)?;
        d.set_item("iterations", out.iterations)?;
        d.set_item("residual", out.residual)?;
        d.set_item("load_steps", out.load_steps)?;
        Ok(d)
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(solve_constrained_tip, m)?)?;
    m.add_function(wrap_pyfunction!(solve_rod_system, m)?)?;
    Ok(())
}
