//! Binding of the tip end constraints (`softrod_core::statics::constraint`) and of systems
//! of rods sharing a platform (`softrod_core::statics::system`). No physics here.

use crate::{
    array2, array3, contact_dict, contact_forces, guarded, options, solution_dict, to_py_err,
    Context, PoseArrays, PyFrictionState, PyRod,
};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::batch::{
    solve_system_batch, system_sensitivity_batch, BatchRow, SystemBatchInputs, SystemBatchRow,
};
use softrod_core::jacobian::system::{system_jacobian, SystemInput};
use softrod_core::linearise::system::linearise_system;
use softrod_core::marker::Marker;
use softrod_core::ode::Loads;
use softrod_core::sensitivity::system::{SystemMarker, SystemParam};
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::statics::constraint::{ConstrainedSolution, TipConstraint};
use softrod_core::statics::friction;
use softrod_core::statics::system::{
    rod_sigma, solve_system, solve_system_friction, Platform, SystemFrictionPath, SystemRod,
};
use softrod_core::SoftrodError;
use std::sync::Arc;

/// The solution as `Rod.solve` gives it, with the tip reaction.
fn constrained_dict<'py>(py: Python<'py>, c: &ConstrainedSolution) -> PyResult<Bound<'py, PyDict>> {
    let d = solution_dict(py, &c.solution, &c.shape)?;
    d.set_item("tip_reaction_force", c.tip_reaction_force.to_vec())?;
    d.set_item("tip_reaction_moment", c.tip_reaction_moment.to_vec())?;
    Ok(d)
}

/// The core constraint of a kind name and its pose.
pub(crate) fn constraint(
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
/// With an obstacle's friction > 0 a held tip follows the frictional load path
/// (`statics::friction::solve_held`: the loads and the held pose in `friction_steps`
/// increments from the unloaded rod or from `history`, a `FrictionState` of this design
/// with the same kind of tip), and the dict has "friction_state".
#[pyfunction]
#[pyo3(signature = (rod, pressures, tip_force, tip_moment, kind, position=None, rotation=None, guess=None, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), stiffness_scale=None, on_invalid="raise", tensions=None, friction_steps=softrod_core::statics::friction::DEFAULT_FRICTION_STEPS, history=None))]
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
    stiffness_scale: Option<[f64; 3]>,
    on_invalid: &str,
    tensions: Option<Vec<f64>>,
    friction_steps: usize,
    history: Option<PyRef<'py, PyFrictionState>>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let c = constraint(py, kind, position, rotation)?;
        let opts = options(
            py,
            tol,
            max_iter,
            continuation,
            max_load_steps,
            stretch_range,
            on_invalid,
        )?;
        let input = crate::solve::One {
            pressures,
            tensions,
            tip_force,
            tip_moment,
            stiffness_scale,
            guess,
            friction_steps,
            history,
        };
        crate::solve::solve_one(py, &rod, c, input, &opts, true)
    })
}

/// `Rod.solve_batch` with the tip held by a constraint (`kind`, `position`, `rotation` as
/// in `solve_constrained_tip`): every row of the (m, channels) pressure array (and the
/// optional (m, tendon channels) tension array) solved in parallel, GIL released, each
/// exactly as `solve_constrained_tip` solves it alone. The dict of `Rod.solve_batch` ("x"
/// (m, 6)) plus "tip_reaction_force" and "tip_reaction_moment" (m, 3), NaN on failed rows.
/// With an obstacle's friction > 0 every row follows its own frictional load path in
/// `friction_steps` increments (`batch::solve_held_friction_batch`), and the dict adds
/// "contact_force" and "friction_force" (m, obstacles, 3).
#[pyfunction]
#[pyo3(signature = (rod, pressures, tip_force, tip_moment, kind, position=None, rotation=None, threads=0, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), stiffness_scale=None, on_invalid="raise", tensions=None, friction_steps=friction::DEFAULT_FRICTION_STEPS))]
#[allow(clippy::too_many_arguments)]
fn solve_constrained_tip_batch<'py>(
    py: Python<'py>,
    rod: PyRef<'py, PyRod>,
    pressures: PyReadonlyArray2<'py, f64>,
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    kind: &str,
    position: Option<[f64; 3]>,
    rotation: Option<[[f64; 3]; 3]>,
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
        let c = constraint(py, kind, position, rotation)?;
        let opts = options(
            py,
            tol,
            max_iter,
            continuation,
            max_load_steps,
            stretch_range,
            on_invalid,
        )?;
        let input = crate::solve::Rows {
            pressures,
            stiffness_scale,
            tensions,
            tip_force,
            tip_moment,
            friction_steps,
        };
        crate::solve::solve_rows(py, &rod, c, input, &opts, threads, true)
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

/// A system's frictional path at a converged equilibrium
/// (`softrod_core::statics::system::SystemFrictionPath`): every rod's loads and contact
/// memory, the attachments and the platform's load, for `solve_rod_system(history=...)` to
/// continue the path from. Opaque; it belongs to the system it was solved with.
#[pyclass(name = "SystemFrictionState", module = "softrod._core", frozen)]
pub(crate) struct PySystemFrictionState {
    path: Arc<SystemFrictionPath>,
}

#[pymethods]
impl PySystemFrictionState {
    /// Largest elastic tangential displacement stored in any rod's contact (m; 0: no
    /// tangential load held).
    #[getter]
    fn max_elastic_slip(&self) -> f64 {
        self.path.max_elastic_slip()
    }

    /// Every rod's pressures (Pa) at the path's end.
    #[getter]
    fn pressures(&self) -> Vec<Vec<f64>> {
        self.path
            .rods
            .iter()
            .map(|r| r.loads.pressures.clone())
            .collect()
    }

    /// Every rod's tendon tensions (N) at the path's end.
    #[getter]
    fn tensions(&self) -> Vec<Vec<f64>> {
        self.path
            .rods
            .iter()
            .map(|r| r.loads.tensions.clone())
            .collect()
    }

    /// The platform's force (N, world) at the path's end.
    #[getter]
    fn platform_force(&self) -> [f64; 3] {
        self.path.platform.force
    }

    /// The platform's moment (N m, about its origin, world) at the path's end.
    #[getter]
    fn platform_moment(&self) -> [f64; 3] {
        self.path.platform.moment
    }

    fn __repr__(&self) -> String {
        format!(
            "SystemFrictionState(rods={}, max_elastic_slip={:.3e} m)",
            self.path.rods.len(),
            self.path.max_elastic_slip()
        )
    }
}

/// Solve a system of rods whose tips hold one platform (GIL released). `rods`: entries
/// as `RodEntry`; `platform`: (position, rotation, force, moment, mass, com_offset,
/// gravity). Returns {"rods": [dicts as `Rod.solve_constrained`], "platform_position",
/// "platform_rotation", "x", "iterations", "residual", "load_steps", "stable" (None: not
/// assessed)}. With an obstacle's friction > 0 on some rod the system follows the
/// frictional load path (`statics::system::solve_system_friction`: `friction_steps`
/// increments from the unloaded rods, or from `history`, a `SystemFrictionState` of this
/// system; `guess` is refused), and the dict has "friction_state". `stiffness_scale`: per
/// rod, its sigma (3 factors > 0, paper 001 eq. 13) or None; None for all: no rod has one.
/// A rod with a stiffness-mapped section needs its sigma (`statics::system::rod_sigma`).
#[pyfunction]
#[pyo3(signature = (rods, platform, guess=None, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), on_invalid="raise", friction_steps=friction::DEFAULT_FRICTION_STEPS, history=None, stiffness_scale=None))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn solve_rod_system<'py>(
    py: Python<'py>,
    rods: Vec<RodEntry<'py>>,
    platform: PlatformEntry,
    guess: Option<Vec<f64>>,
    tol: f64,
    max_iter: usize,
    continuation: bool,
    max_load_steps: usize,
    stretch_range: (f64, f64),
    on_invalid: &str,
    friction_steps: usize,
    history: Option<PyRef<'py, PySystemFrictionState>>,
    stiffness_scale: Option<Vec<Option<[f64; 3]>>>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let input = |e: SoftrodError| to_py_err(py, e, Context::Input);
        let opts = options(
            py,
            tol,
            max_iter,
            continuation,
            max_load_steps,
            stretch_range,
            on_invalid,
        )?;
        let sigma = stiffness_scale.unwrap_or_else(|| vec![None; rods.len()]);
        if sigma.len() != rods.len() {
            return Err(input(SoftrodError::invalid(
                "stiffness_scale",
                format!("{} entries", sigma.len()),
                format!(
                    "must be a list of {} entries, one per rod: its sigma (3 factors) or None",
                    rods.len()
                ),
            )));
        }
        let system = system_rods(&rods, &sigma).map_err(input)?;
        let pf = platform_of(platform);
        let history = history.map(|h| h.path.clone());
        let frictional =
            softrod_core::statics::system::frictional(&system, history.is_some(), guess.is_some())
                .map_err(|e| to_py_err(py, e, Context::Input))?;
        let out = py
            .detach(|| {
                if frictional {
                    solve_system_friction(&system, &pf, history.as_deref(), friction_steps, &opts)
                } else {
                    solve_system(&system, &pf, guess.as_deref(), &opts)
                }
            })
            .map_err(|e| to_py_err(py, e, Context::Input))?;
        let d = PyDict::new(py);
        if let Some(path) = &out.friction {
            d.set_item(
                "friction_state",
                Py::new(py, PySystemFrictionState { path: path.clone() })?,
            )?;
        }
        let mut rods_out = Vec::with_capacity(out.rods.len());
        for (c, r) in out.rods.iter().zip(&system) {
            let rd = constrained_dict(py, c)?;
            // A rod of a frictional system: its path as a clamped rod's (held where the
            // platform holds it), for `Rod.solve_constrained(history=...)`.
            if let Some(path) = &c.solution.friction {
                rd.set_item(
                    "friction_state",
                    Py::new(py, PyFrictionState { path: path.clone() })?,
                )?;
            }
            // A rod with obstacles: its contact report, as `Rod.solve` gives it.
            let rep = softrod_core::statics::contact::report(r.rod, &r.loads, &c.solution)
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            if let Some(rep) = rep {
                rd.set_item("contact", contact_dict(py, &rep)?)?;
            }
            rods_out.push(rd);
        }
        d.set_item("rods", rods_out)?;
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
        d.set_item("stable", out.stable)?;
        Ok(d)
    })
}

/// The core's rods of a system from the binding's entries and each rod's sigma (None: no
/// mapped section).
fn system_rods<'a>(
    rods: &'a [RodEntry<'_>],
    sigma: &[Option<[f64; 3]>],
) -> Result<Vec<SystemRod<'a>>, SoftrodError> {
    rods.iter()
        .zip(sigma)
        .enumerate()
        .map(|(i, ((r, p, t, f, m, o, a), s))| {
            Ok(SystemRod {
                rod: &r.rod,
                loads: Loads {
                    pressures: p.clone(),
                    tensions: t.clone(),
                    tip_force: *f,
                    tip_moment: *m,
                    tip_frame: r.rod.spec.tip.frame,
                    stiffness_scale: rod_sigma(i, &r.rod, *s)?,
                },
                attachment: *o,
                attachment_rotation: *a,
            })
        })
        .collect()
}

/// Every rod's stiffness factors sigma (None: none given), one entry per rod.
fn rod_sigmas(
    given: Option<Vec<Option<[f64; 3]>>>,
    n: usize,
) -> Result<Vec<Option<[f64; 3]>>, SoftrodError> {
    let sigma = given.unwrap_or_else(|| vec![None; n]);
    if sigma.len() != n {
        return Err(SoftrodError::invalid(
            "stiffness_scale",
            format!("{} entries", sigma.len()),
            format!("must be a list of {n} entries, one per rod"),
        ));
    }
    Ok(sigma)
}

/// A system's inputs from (kind, rod, index): kind "pressure", "tension" or
/// "stiffness_scale" (of rod `rod`), or "platform_force", "platform_moment" (rod ignored).
fn system_inputs(inputs: &[(String, usize, usize)]) -> Result<Vec<SystemInput>, SoftrodError> {
    inputs
        .iter()
        .enumerate()
        .map(|(k, (kind, rod, index))| {
            let (rod, index) = (*rod, *index);
            Ok(match kind.as_str() {
                "pressure" => SystemInput::Pressure {
                    rod,
                    channel: index,
                },
                "tension" => SystemInput::Tension {
                    rod,
                    channel: index,
                },
                "stiffness_scale" => SystemInput::StiffnessScale { rod, factor: index },
                "platform_force" => SystemInput::PlatformForce(index),
                "platform_moment" => SystemInput::PlatformMoment(index),
                other => return Err(SoftrodError::invalid(
                    format!("inputs[{k}]"),
                    other,
                    "kinds: pressure, tension, stiffness_scale, platform_force, platform_moment",
                )),
            })
        })
        .collect()
}

/// The linearised dynamics of a frictionless system at the unknowns `x` (a converged
/// `solve_rod_system`'s "x", solved again from there) with `nodes` nodes inside every rod,
/// the platform's `platform_inertia` (kg m^2, about its centre of mass, platform frame) and
/// one input column per entry of `inputs` (as `system_jacobian_of` takes them). Returns
/// "mass", "damping", "stiffness", "input" (numpy) and "nodes" (one array per rod, m)
/// (`softrod_core::linearise::system`).
#[pyfunction]
#[pyo3(signature = (rods, platform, x, inputs, nodes, platform_inertia, stiffness_scale=None))]
#[allow(clippy::too_many_arguments)]
fn system_linearise_of<'py>(
    py: Python<'py>,
    rods: Vec<RodEntry<'py>>,
    platform: PlatformEntry,
    x: Vec<f64>,
    inputs: Vec<(String, usize, usize)>,
    nodes: usize,
    platform_inertia: [[f64; 3]; 3],
    stiffness_scale: Option<Vec<Option<[f64; 3]>>>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let input = |e: SoftrodError| to_py_err(py, e, Context::Input);
        let sigma = rod_sigmas(stiffness_scale, rods.len()).map_err(input)?;
        let inputs = system_inputs(&inputs).map_err(input)?;
        let system = system_rods(&rods, &sigma).map_err(input)?;
        let pf = platform_of(platform);
        let opts = options(py, 1e-10, 25, true, 200, (1.0 / 3.0, 3.0), "ignore")?;
        let lin = py
            .detach(|| {
                let sol = solve_system(&system, &pf, Some(&x), &opts)?;
                linearise_system(&system, &pf, &platform_inertia, &sol, nodes, &inputs)
            })
            .map_err(input)?;
        let d = PyDict::new(py);
        d.set_item("mass", crate::matrix(py, &lin.mass)?)?;
        d.set_item("damping", crate::matrix(py, &lin.damping)?)?;
        d.set_item("stiffness", crate::matrix(py, &lin.stiffness)?)?;
        d.set_item("input", crate::matrix(py, &lin.input)?)?;
        let per_rod: Vec<Bound<'py, PyArray1<f64>>> = lin
            .nodes
            .into_iter()
            .map(|v| PyArray1::from_vec(py, v))
            .collect();
        d.set_item("nodes", per_rod)?;
        Ok(d)
    })
}

/// The exact derivatives of a frictionless system's equilibrium at the unknowns `x` (a
/// converged `solve_rod_system`'s "x", solved again from there) with respect to `inputs`:
/// (kind, rod, index) with kind "pressure", "tension" or "stiffness_scale" (of rod `rod`)
/// or "platform_force", "platform_moment" (rod ignored). Returns "position" (3),
/// "rotation" (3, 3) of the platform, "pose" (6, K): its position (m) and small rotation
/// (rad, world) per unit of each input, and "base" (n, 6, K): every rod's base force (N)
/// and moment (N m) per unit (`softrod_core::jacobian::system`).
#[pyfunction]
#[pyo3(signature = (rods, platform, x, inputs, stiffness_scale=None))]
fn system_jacobian_of<'py>(
    py: Python<'py>,
    rods: Vec<RodEntry<'py>>,
    platform: PlatformEntry,
    x: Vec<f64>,
    inputs: Vec<(String, usize, usize)>,
    stiffness_scale: Option<Vec<Option<[f64; 3]>>>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let input = |e: SoftrodError| to_py_err(py, e, Context::Input);
        let sigma = rod_sigmas(stiffness_scale, rods.len()).map_err(input)?;
        let inputs = system_inputs(&inputs).map_err(input)?;
        let system = system_rods(&rods, &sigma).map_err(input)?;
        let pf = platform_of(platform);
        // The equilibrium the caller holds was checked when it was solved.
        let opts = options(py, 1e-10, 25, true, 200, (1.0 / 3.0, 3.0), "ignore")?;
        let jac = py
            .detach(|| {
                let sol = solve_system(&system, &pf, Some(&x), &opts)?;
                system_jacobian(&system, &pf, &sol, &inputs)
            })
            .map_err(input)?;
        let k = inputs.len();
        let n = rods.len();
        let pose: Vec<f64> = (0..6)
            .flat_map(|r| {
                jac.d_position
                    .iter()
                    .zip(&jac.d_rotation)
                    .map(move |(p, w)| if r < 3 { p[r] } else { w[r - 3] })
            })
            .collect();
        let mut base = vec![0.0; n * 6 * k];
        for (c, (f, m)) in jac.d_base_force.iter().zip(&jac.d_base_moment).enumerate() {
            for i in 0..n {
                for r in 0..3 {
                    base[(i * 6 + r) * k + c] = f[i][r];
                    base[(i * 6 + 3 + r) * k + c] = m[i][r];
                }
            }
        }
        let d = PyDict::new(py);
        d.set_item("position", jac.position.to_vec())?;
        d.set_item("rotation", jac.rotation.map(|r| r.to_vec()).to_vec())?;
        d.set_item("pose", PyArray1::from_vec(py, pose).reshape([6, k])?)?;
        d.set_item("base", PyArray1::from_vec(py, base).reshape([n, 6, k])?)?;
        Ok(d)
    })
}

/// One rod of a system batch: (rod, tip force, tip moment, attachment offset, attachment
/// rotation); its pressures and tensions come from the rows.
type BatchRodEntry<'py> = (
    PyRef<'py, PyRod>,
    [f64; 3],
    [f64; 3],
    [f64; 3],
    [[f64; 3]; 3],
);

/// A system's platform: (position, rotation, force, moment, mass, com_offset, gravity).
pub(crate) type PlatformEntry = (
    [f64; 3],
    [[f64; 3]; 3],
    [f64; 3],
    [f64; 3],
    f64,
    [f64; 3],
    [f64; 3],
);

pub(crate) fn platform_of(p: PlatformEntry) -> Platform {
    let (position, rotation, force, moment, mass, com_offset, gravity) = p;
    Platform {
        position,
        rotation,
        force,
        moment,
        mass,
        com_offset,
        gravity,
    }
}

/// `solve_rod_system` for every row (GIL released, rows in parallel, each exactly as
/// `solve_rod_system` solves it alone): `pressures` (m, sum of the rods' channels), each row
/// rod 0's pressures, then rod 1's...; `tensions` likewise (None: slack). Returns
/// "converged", "iterations", "residual", "load_steps" (m,), "x" (m, 6 n + 6),
/// "platform_position" (m, 3), "platform_rotation" (m, 3, 3), per rod "tip_position",
/// "base_force", "base_moment", "tip_reaction_force", "tip_reaction_moment" (m, n, 3),
/// "tip_rotation" (m, n, 3, 3), "stable" and "assessed" (m,) bool, "violation" (m
/// strings), and "contact": per rod, None or (a rod with obstacles) {"contact_force",
/// "friction_force"} (m, obstacles, 3). NaN on failed rows. With friction on some rod's
/// obstacle every row is its own load path (`friction_steps` increments).
/// `stiffness_scale`: (m, n, 3) every row's sigma of every rod (paper 001 eq. 13); None:
/// no rod has a stiffness-mapped section (`batch::SystemBatchInputs`).
#[pyfunction]
#[pyo3(signature = (rods, platform, pressures, tensions=None, threads=0, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), on_invalid="raise", friction_steps=friction::DEFAULT_FRICTION_STEPS, stiffness_scale=None))]
#[allow(clippy::too_many_arguments)]
fn solve_rod_system_batch<'py>(
    py: Python<'py>,
    rods: Vec<BatchRodEntry<'py>>,
    platform: PlatformEntry,
    pressures: PyReadonlyArray2<'py, f64>,
    tensions: Option<PyReadonlyArray2<'py, f64>>,
    threads: usize,
    tol: f64,
    max_iter: usize,
    continuation: bool,
    max_load_steps: usize,
    stretch_range: (f64, f64),
    on_invalid: &str,
    friction_steps: usize,
    stiffness_scale: Option<PyReadonlyArray3<'py, f64>>,
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
        let system = batch_rods(&rods);
        let pf = platform_of(platform);
        let flat: Vec<f64> = pressures.as_array().iter().copied().collect();
        let tens: Option<Vec<f64>> = tensions.map(|s| s.as_array().iter().copied().collect());
        let sigma = sigma_rows(py, stiffness_scale, rods.len())?;
        let out = py
            .detach(|| {
                let inputs = SystemBatchInputs {
                    pressures: &flat,
                    tensions: tens.as_deref(),
                    stiffness_scale: sigma.as_deref(),
                };
                solve_system_batch(&system, &pf, &inputs, friction_steps, &opts, threads)
            })
            .map_err(|e| to_py_err(py, e, Context::Input))?;
        system_rows_dict(py, &system, &out)
    })
}

/// A system batch's (m, n, 3) sigma array as owned row-major data (copied before the GIL
/// is released), its rod and component axes checked (the core checks the rows).
fn sigma_rows(
    py: Python<'_>,
    sigma: Option<PyReadonlyArray3<'_, f64>>,
    n: usize,
) -> PyResult<Option<Vec<f64>>> {
    let Some(s) = sigma else { return Ok(None) };
    let shape = s.shape();
    if shape[1] != n || shape[2] != 3 {
        return Err(to_py_err(
            py,
            SoftrodError::invalid(
                "stiffness_scale",
                format!("shape {shape:?}"),
                format!("must be an (m, {n}, 3) array: every row's sigma of every rod"),
            ),
            Context::Input,
        ));
    }
    Ok(Some(s.as_array().iter().copied().collect()))
}

/// The arrays of a system batch's rows (`solve_rod_system_batch`'s dict).
fn system_rows_dict<'py>(
    py: Python<'py>,
    system: &[SystemRod],
    out: &[SystemBatchRow],
) -> PyResult<Bound<'py, PyDict>> {
    let m = out.len();
    let n = system.len();
    let d = PyDict::new(py);
    d.set_item(
        "converged",
        PyArray1::from_vec(py, out.iter().map(|r| r.converged).collect()),
    )?;
    d.set_item(
        "iterations",
        PyArray1::from_vec(py, out.iter().map(|r| r.iterations as i64).collect()),
    )?;
    d.set_item(
        "residual",
        PyArray1::from_vec(py, out.iter().map(|r| r.residual).collect()),
    )?;
    d.set_item(
        "load_steps",
        PyArray1::from_vec(py, out.iter().map(|r| r.load_steps as i64).collect()),
    )?;
    // "stable" is false where stability was not assessed: see "assessed".
    d.set_item(
        "stable",
        PyArray1::from_vec(py, out.iter().map(|r| r.stable == Some(true)).collect()),
    )?;
    d.set_item(
        "assessed",
        PyArray1::from_vec(py, out.iter().map(|r| r.stable.is_some()).collect()),
    )?;
    let x: Vec<f64> = out.iter().flat_map(|r| r.x.iter().copied()).collect();
    d.set_item("x", PyArray1::from_vec(py, x).reshape([m, 6 * n + 6])?)?;
    let pp: Vec<[f64; 3]> = out.iter().map(|r| r.platform_position).collect();
    let pr: Vec<[[f64; 3]; 3]> = out.iter().map(|r| r.platform_rotation).collect();
    d.set_item("platform_position", array2(py, &pp)?)?;
    d.set_item("platform_rotation", array3(py, &pr)?)?;
    let per_rod = |get: &dyn Fn(&BatchRow) -> [f64; 3]| -> Vec<f64> {
        out.iter()
            .flat_map(|r| r.rods.iter().flat_map(get))
            .collect()
    };
    for (name, get) in [
        (
            "tip_position",
            &(|r: &BatchRow| r.tip_position) as &dyn Fn(&BatchRow) -> [f64; 3],
        ),
        ("base_force", &|r: &BatchRow| r.base_force),
        ("base_moment", &|r: &BatchRow| r.base_moment),
        ("tip_reaction_force", &|r: &BatchRow| r.tip_reaction_force),
        ("tip_reaction_moment", &|r: &BatchRow| r.tip_reaction_moment),
    ] {
        d.set_item(
            name,
            PyArray1::from_vec(py, per_rod(get)).reshape([m, n, 3])?,
        )?;
    }
    let rot: Vec<f64> = out
        .iter()
        .flat_map(|r| {
            r.rods
                .iter()
                .flat_map(|k| k.tip_rotation.into_iter().flatten())
        })
        .collect();
    d.set_item(
        "tip_rotation",
        PyArray1::from_vec(py, rot).reshape([m, n, 3, 3])?,
    )?;
    d.set_item(
        "violation",
        out.iter().map(|r| r.violation.as_str()).collect::<Vec<_>>(),
    )?;
    // Per rod with obstacles, its contact and friction forces (m, obstacles, 3); None
    // for a rod without any.
    let mut contact = Vec::with_capacity(n);
    for (i, sr) in system.iter().enumerate() {
        let k = sr.rod.spec.obstacles.len();
        if k == 0 {
            contact.push(None);
            continue;
        }
        let rows: Vec<BatchRow> = out.iter().map(|r| r.rods[i].clone()).collect();
        let rd = PyDict::new(py);
        contact_forces(py, &rd, &rows, k)?;
        contact.push(Some(rd));
    }
    d.set_item("contact", contact)?;
    Ok(d)
}

/// The rods of a system batch: each with its tip loads and attachment; the rows give the
/// pressures, tensions and sigma.
fn batch_rods<'a>(rods: &'a [BatchRodEntry<'_>]) -> Vec<SystemRod<'a>> {
    rods.iter()
        .map(|(r, f, m, o, a)| SystemRod {
            rod: &r.rod,
            loads: Loads {
                pressures: vec![],
                tensions: vec![],
                tip_force: *f,
                tip_moment: *m,
                tip_frame: r.rod.spec.tip.frame,
                stiffness_scale: [1.0; 3],
            },
            attachment: *o,
            attachment_rotation: *a,
        })
        .collect()
}

/// A system parameter: (kind, [(rod, sections)]), kinds as `ParamKind::ALL` names, or
/// ("platform_mass", []).
pub(crate) type SystemParamEntry = (String, Vec<(usize, Vec<usize>)>);

/// `solve_rod_system_batch` (frictionless systems) plus the markers and the exact
/// derivatives of the platform pose and the markers with respect to `params`
/// (`softrod_core::batch::system_sensitivity_batch`; GIL released). `markers`: (rod, s,
/// offset) with rod None for a point fixed to the platform (offset in the platform frame;
/// s must be 0) or a rod's index (s its reference arc length, offset in its cross-section
/// frame); m. `x0`: optional (m, 6 n + 6) warm starts (a previous call's "x"; NaN rows
/// start cold). `stiffness_scale` as in `solve_rod_system_batch`. Adds "marker_position"
/// (m, K, 3), "d_platform_position" (m, 3, P), "d_platform_rotation" (m, 3, 3, P) and
/// "d_marker_position" (m, K, 3, P), NaN on failed rows.
#[pyfunction]
#[pyo3(signature = (rods, platform, pressures, params, tensions=None, markers=vec![], x0=None, threads=0, tol=1e-10, max_iter=25, continuation=true, max_load_steps=200, stretch_range=(1.0 / 3.0, 3.0), on_invalid="ignore", stiffness_scale=None))]
#[allow(clippy::too_many_arguments)]
fn rod_system_sensitivity_batch<'py>(
    py: Python<'py>,
    rods: Vec<BatchRodEntry<'py>>,
    platform: PlatformEntry,
    pressures: PyReadonlyArray2<'py, f64>,
    params: Vec<SystemParamEntry>,
    tensions: Option<PyReadonlyArray2<'py, f64>>,
    markers: Vec<(Option<usize>, f64, [f64; 3])>,
    x0: Option<PyReadonlyArray2<'py, f64>>,
    threads: usize,
    tol: f64,
    max_iter: usize,
    continuation: bool,
    max_load_steps: usize,
    stretch_range: (f64, f64),
    on_invalid: &str,
    stiffness_scale: Option<PyReadonlyArray3<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let input = |e: SoftrodError| to_py_err(py, e, Context::Input);
        let opts = options(
            py,
            tol,
            max_iter,
            continuation,
            max_load_steps,
            stretch_range,
            on_invalid,
        )?;
        let system = batch_rods(&rods);
        let params = system_params(params).map_err(input)?;
        let markers = system_markers(markers).map_err(input)?;
        let pf = platform_of(platform);
        let flat: Vec<f64> = pressures.as_array().iter().copied().collect();
        let tens: Option<Vec<f64>> = tensions.map(|s| s.as_array().iter().copied().collect());
        let guesses: Option<Vec<f64>> = x0.map(|s| s.as_array().iter().copied().collect());
        let sigma = sigma_rows(py, stiffness_scale, rods.len())?;
        let out = py
            .detach(|| {
                let inputs = SystemBatchInputs {
                    pressures: &flat,
                    tensions: tens.as_deref(),
                    stiffness_scale: sigma.as_deref(),
                };
                system_sensitivity_batch(
                    &system,
                    &pf,
                    &inputs,
                    guesses.as_deref(),
                    &params,
                    &markers,
                    &opts,
                    threads,
                )
            })
            .map_err(input)?;
        let d = system_rows_dict(py, &system, &out)?;
        let mut arrays = PoseArrays::new(out.len(), params.len(), markers.len());
        for (r, row) in out.iter().enumerate() {
            arrays.markers(r, &row.markers);
            if let Some(sens) = &row.sensitivity {
                arrays.derivatives(
                    r,
                    &sens.platform_position,
                    &sens.platform_rotation,
                    &sens.markers,
                );
            }
        }
        arrays.into_dict(py, &d, "d_platform_position", "d_platform_rotation")?;
        Ok(d)
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(solve_constrained_tip_batch, m)?)?;
    m.add_function(wrap_pyfunction!(solve_rod_system_batch, m)?)?;
    m.add_function(wrap_pyfunction!(rod_system_sensitivity_batch, m)?)?;
    m.add_function(wrap_pyfunction!(solve_constrained_tip, m)?)?;
    m.add_function(wrap_pyfunction!(solve_rod_system, m)?)?;
    m.add_function(wrap_pyfunction!(system_jacobian_of, m)?)?;
    m.add_function(wrap_pyfunction!(system_linearise_of, m)?)?;
    m.add_class::<PySystemFrictionState>()?;
    Ok(())
}

/// A system's parameters from (kind, [(rod, sections)]) entries ("platform_mass" with no
/// rods); errors name `params[j]`.
pub(crate) fn system_params(
    params: Vec<SystemParamEntry>,
) -> Result<Vec<SystemParam>, SoftrodError> {
    params
        .into_iter()
        .enumerate()
        .map(|(j, (name, entries))| {
            if name == "platform_mass" {
                return if entries.is_empty() {
                    Ok(SystemParam::PlatformMass)
                } else {
                    Err(SoftrodError::invalid(
                        format!("params[{j}]"),
                        format!("{} rods", entries.len()),
                        "the platform's mass acts on no rod: give no rods",
                    ))
                };
            }
            let Some(kind) = ParamKind::from_name(&name) else {
                return Err(SoftrodError::invalid(
                    format!("params[{j}]"),
                    &name,
                    format!(
                        "unknown parameter kind; known: platform_mass, {}",
                        ParamKind::ALL.map(|(n, _)| n).join(", ")
                    ),
                ));
            };
            Ok(SystemParam::Rods(
                entries
                    .into_iter()
                    .map(|(rod, sections)| (rod, Param { kind, sections }))
                    .collect(),
            ))
        })
        .collect()
}

/// A system's markers from (rod, or None for the platform; s; offset) entries; errors
/// name `markers[k]`.
pub(crate) fn system_markers(
    markers: Vec<(Option<usize>, f64, [f64; 3])>,
) -> Result<Vec<SystemMarker>, SoftrodError> {
    markers
        .into_iter()
        .enumerate()
        .map(|(k, (rod, s, offset))| match rod {
            None if s != 0.0 => Err(SoftrodError::invalid(
                format!("markers[{k}].s"),
                s,
                "a marker fixed to the platform has no arc length: give 0",
            )),
            None => Ok(SystemMarker::Platform(offset)),
            Some(rod) => Ok(SystemMarker::Rod {
                rod,
                marker: Marker { s, offset },
            }),
        })
        .collect()
}
