//! Binding of the control tools of the core (`softrod_core::{inverse, jacobian, linearise}`):
//! type conversion and error mapping only.

use crate::{guarded, matrix, options, to_py_err, Context, PyRod};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use softrod_core::inverse::{solve_inverse, InverseOptions, InverseTarget, WarmStart};
use softrod_core::jacobian::{point_jacobian, point_jacobian6, HeldJacobian, Input, Probe};
use softrod_core::linearise::{linearise, linearise_held};
use softrod_core::ode::Loads;
use softrod_core::sensitivity::{constrained_pose_sensitivity, validate_params, Param, ParamKind};
use softrod_core::statics;
use softrod_core::statics::constraint::{solve_constrained, TipConstraint};
use softrod_core::{Rod, SoftrodError};
use std::sync::Mutex;

/// An inverse problem of one design with fixed bounds, weights, point and tip loads, solved
/// for a target at a time (GIL released). See `softrod.InverseProblem`.
#[pyclass(name = "InverseSolver", module = "softrod._core", frozen)]
pub struct PyInverse {
    rod: Rod,
    opts: InverseOptions,
    s: f64,
    position_weight: [f64; 3],
    orientation_weight: f64,
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    /// The last answer's warm start: a call that starts from that answer (same pressures
    /// and unknowns) reuses its equilibrium and linearisation.
    last: Mutex<Option<WarmStart>>,
}

#[pymethods]
impl PyInverse {
    #[new]
    #[pyo3(signature = (rod, bounds, reference, s, position_weight, orientation_weight, tip_force, tip_moment, regularisation=1e-6, tol=1e-10, max_iter=100, statics_tol=1e-10, statics_max_iter=25, on_invalid="raise", stretch_range=(1.0 / 3.0, 3.0)))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        rod: PyRef<'_, PyRod>,
        bounds: Vec<[f64; 2]>,
        reference: Vec<f64>,
        s: f64,
        position_weight: [f64; 3],
        orientation_weight: f64,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
        regularisation: f64,
        tol: f64,
        max_iter: usize,
        statics_tol: f64,
        statics_max_iter: usize,
        on_invalid: &str,
        stretch_range: (f64, f64),
    ) -> PyResult<Self> {
        guarded(py, || {
            let statics = options(
                py,
                statics_tol,
                statics_max_iter,
                true,
                200,
                stretch_range,
                on_invalid,
            )?;
            let opts = InverseOptions {
                bounds,
                reference,
                regularisation,
                tol,
                max_iter,
                statics,
            };
            let rod = rod.rod.clone();
            Probe::at(&rod, s).map_err(|e| to_py_err(py, e, Context::Input))?;
            Ok(PyInverse {
                rod,
                opts,
                s,
                position_weight,
                orientation_weight,
                tip_force,
                tip_moment,
                last: Mutex::new(None),
            })
        })
    }

    /// Solve for `position` (m) and optionally `orientation` from the start `pressures`
    /// (Pa) and `tensions` (N) and, for a warm start, its shooting unknowns `x` (and `z`,
    /// the collocation unknowns of a start that collocation solved, when the start is not
    /// this solver's last answer). `reference` replaces the regularisation's centre for
    /// this call. Returns a dict (SI).
    #[pyo3(signature = (position, pressures, tensions, orientation=None, x=None, reference=None, z=None))]
    #[allow(clippy::too_many_arguments)]
    fn solve<'py>(
        &self,
        py: Python<'py>,
        position: [f64; 3],
        pressures: Vec<f64>,
        tensions: Vec<f64>,
        orientation: Option<[[f64; 3]; 3]>,
        x: Option<[f64; 3]>,
        reference: Option<Vec<f64>>,
        z: Option<Vec<f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(py, || {
            let target = InverseTarget {
                s: self.s,
                position,
                orientation,
                position_weight: self.position_weight,
                orientation_weight: self.orientation_weight,
            };
            let loads = Loads {
                pressures,
                tip_force: self.tip_force,
                tip_moment: self.tip_moment,
                stiffness_scale: [1.0; 3],
                tensions,
                tip_frame: self.rod.spec.tip.frame,
            };
            let custom;
            let opts = match reference {
                Some(r) => {
                    custom = InverseOptions {
                        reference: r,
                        ..self.opts.clone()
                    };
                    &custom
                }
                None => &self.opts,
            };
            let rod = &self.rod;
            let last = self.last.lock().ok().and_then(|g| g.clone());
            let out = py
                .detach(|| {
                    let warm = match x {
                        None => None,
                        Some(x) => Some(match last {
                            Some(w) if w.x == x => w,
                            other => WarmStart {
                                x,
                                // A start that collocation solved: its equilibrium from its z
                                // (a cold start if z is not converged there).
                                solution: match &z {
                                    Some(z) => {
                                        WarmStart::collocation_start(rod, &loads, z, &opts.statics)?
                                    }
                                    None => None,
                                },
                                equilibrium: None,
                                linearisation: other.and_then(|w| w.linearisation),
                            },
                        }),
                    };
                    solve_inverse(rod, &loads, &target, opts, warm.as_ref())
                })
                .map_err(|e| to_py_err(py, e, Context::Input))?;
            if let Ok(mut g) = self.last.lock() {
                *g = Some(out.warm_start());
            }
            let d = PyDict::new(py);
            d.set_item("pressures", out.pressures)?;
            d.set_item("tensions", out.tensions)?;
            d.set_item("x", out.solution.x.to_vec())?;
            d.set_item(
                "collocation_unknowns",
                crate::collocation_unknowns(py, &out.solution),
            )?;
            d.set_item("point_position", out.point.r.to_vec())?;
            d.set_item("point_rotation", out.point.rot.map(|r| r.to_vec()).to_vec())?;
            d.set_item("tip_position", out.solution.tip.r.to_vec())?;
            d.set_item(
                "tip_rotation",
                out.solution.tip.rot.map(|r| r.to_vec()).to_vec(),
            )?;
            d.set_item("base_force", out.solution.base_force.to_vec())?;
            d.set_item("base_moment", out.solution.base_moment.to_vec())?;
            d.set_item("residual", out.solution.residual)?;
            d.set_item("reached", out.reached)?;
            d.set_item("distance", out.distance)?;
            d.set_item("angle", out.angle)?;
            d.set_item("cost", out.cost)?;
            d.set_item(
                "active",
                out.active.iter().map(|&a| a as i64).collect::<Vec<_>>(),
            )?;
            d.set_item("iterations", out.iterations)?;
            d.set_item("passes", out.passes)?;
            d.set_item("stable", out.solution.stable)?;
            d.set_item(
                "violations",
                out.solution
                    .violations
                    .iter()
                    .map(|v| v.to_string())
                    .collect::<Vec<_>>(),
            )?;
            Ok(d)
        })
    }
}

fn parse_params(py: Python<'_>, params: Vec<(String, Vec<usize>)>) -> PyResult<Vec<Param>> {
    params
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
                        "unknown parameter; known: {}",
                        ParamKind::ALL.map(|(n, _)| n).join(", ")
                    ),
                ),
                Context::Input,
            )),
        })
        .collect()
}

/// The exact Jacobian of the pose at arc length `s` of the equilibrium under `pressures`
/// and tip loads (warm start `x`): (6, k) arrays, rows position then small rotation, for
/// the pressures, tip force, tip moment and (at the tip only) the named parameters, at the
/// given tendon `tensions` (N; None: slack). `tip_kind` "pinned" (with `tip_position`) or
/// "clamped" (and `tip_rotation`) for an equilibrium whose tip is held (`x` then has 6
/// values), which adds "reaction": the same blocks for the reaction wrench the constraint
/// applies to the tip (rows force, N, then moment, N m; world frame). A design with a
/// stiffness-mapped section adds "stiffness_scale": the partial derivatives with respect to
/// the three factors sigma at fixed pressures (the pressures' blocks are partial too: the
/// caller adds the map's part, d/dsigma times d sigma / d p).
#[pyfunction]
#[pyo3(signature = (rod, pressures, tip_force, tip_moment, stiffness_scale, x, s, params, tensions=None, tip_kind="free", tip_position=None, tip_rotation=None))]
#[allow(clippy::too_many_arguments)]
pub fn point_jacobian_of<'py>(
    py: Python<'py>,
    rod: PyRef<'_, PyRod>,
    pressures: Vec<f64>,
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    stiffness_scale: [f64; 3],
    x: Vec<f64>,
    s: f64,
    params: Vec<(String, Vec<usize>)>,
    tensions: Option<Vec<f64>>,
    tip_kind: &str,
    tip_position: Option<[f64; 3]>,
    tip_rotation: Option<[[f64; 3]; 3]>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let params = parse_params(py, params)?;
        let held = crate::ends::constraint(py, tip_kind, tip_position, tip_rotation)?;
        let rod = &rod.rod;
        // The equilibrium the caller holds was checked when it was solved.
        let checked = options(py, 1e-10, 25, true, 200, (1.0 / 3.0, 3.0), "ignore")?;
        let loads = Loads {
            pressures,
            tip_force,
            tip_moment,
            stiffness_scale,
            tensions: tensions.unwrap_or_default(),
            tip_frame: rod.spec.tip.frame,
        };
        let nc = rod.n_channels;
        let mapped = softrod_core::statics::system::mapped_section(rod).is_some();
        let result = py.detach(|| -> softrod_core::Result<_> {
            validate_params(rod, &params)?;
            let probe = Probe::at(rod, s)?;
            let free = matches!(held, TipConstraint::Free);
            let sol = if free {
                statics::solution_at(rod, &loads, &x, &checked)?
            } else {
                solve_constrained(rod, &loads, &held, Some(&x), &checked)?.solution
            };
            let mut inputs: Vec<Input> = (0..nc).map(Input::Pressure).collect();
            inputs.extend((0..3).map(Input::TipForce));
            inputs.extend((0..3).map(Input::TipMoment));
            inputs.extend((0..rod.n_tendons).map(Input::Tension));
            if mapped {
                inputs.extend((0..3).map(Input::StiffnessScale));
            }
            // Six unknowns (a held tip, or the base force unknown under follower loads or
            // with obstacles): the implicit differentiation of that residual.
            let jac = if free && sol.x.len() == 3 {
                HeldJacobian {
                    point: point_jacobian(rod, &loads, &sol, &inputs, &probe)?,
                    reaction_force: vec![],
                    reaction_moment: vec![],
                }
            } else {
                point_jacobian6(rod, &loads, &held, &sol, &inputs, &probe)?
            };
            let sens = if params.is_empty() {
                None
            } else {
                if (s - rod.length).abs() > 1e-12 * rod.length {
                    return Err(SoftrodError::invalid(
                        "params",
                        format!("{} parameters", params.len()),
                        "parameter derivatives are available at the tip only",
                    ));
                }
                Some(constrained_pose_sensitivity(
                    rod,
                    &loads,
                    &held,
                    &sol,
                    &params,
                    &[],
                )?)
            };
            Ok((jac, sens))
        });
        let (jac, sens) = result.map_err(|e| to_py_err(py, e, Context::Input))?;
        let point = &jac.point;
        let block = |rows: &dyn Fn(usize) -> [f64; 6], from: usize, count: usize| {
            nalgebra::DMatrix::from_fn(6, count, |i, k| rows(from + k)[i])
        };
        let pose = |k: usize| -> [f64; 6] {
            let (p, r) = (point.d_position[k], point.d_rotation[k]);
            [p[0], p[1], p[2], r[0], r[1], r[2]]
        };
        let d = PyDict::new(py);
        d.set_item("position", point.position.to_vec())?;
        d.set_item("rotation", point.rotation.map(|r| r.to_vec()).to_vec())?;
        d.set_item("pressures", matrix(py, &block(&pose, 0, nc))?)?;
        d.set_item("tip_force", matrix(py, &block(&pose, nc, 3))?)?;
        d.set_item("tip_moment", matrix(py, &block(&pose, nc + 3, 3))?)?;
        d.set_item(
            "tensions",
            matrix(py, &block(&pose, nc + 6, rod.n_tendons))?,
        )?;
        let sigma_at = nc + 6 + rod.n_tendons;
        if mapped {
            d.set_item("stiffness_scale", matrix(py, &block(&pose, sigma_at, 3))?)?;
        }
        let held_tip = !jac.reaction_force.is_empty();
        let reaction = PyDict::new(py);
        if held_tip {
            let wrench = |k: usize| -> [f64; 6] {
                let (f, m) = (jac.reaction_force[k], jac.reaction_moment[k]);
                [f[0], f[1], f[2], m[0], m[1], m[2]]
            };
            reaction.set_item("pressures", matrix(py, &block(&wrench, 0, nc))?)?;
            reaction.set_item("tip_force", matrix(py, &block(&wrench, nc, 3))?)?;
            reaction.set_item("tip_moment", matrix(py, &block(&wrench, nc + 3, 3))?)?;
            reaction.set_item(
                "tensions",
                matrix(py, &block(&wrench, nc + 6, rod.n_tendons))?,
            )?;
            if mapped {
                reaction.set_item("stiffness_scale", matrix(py, &block(&wrench, sigma_at, 3))?)?;
            }
        }
        if let Some(sens) = sens {
            let pose = |k: usize| -> [f64; 6] {
                let p = sens.position[k];
                let r = softrod_core::jacobian::small_rotation(&point.rotation, &sens.rotation[k]);
                [p[0], p[1], p[2], r[0], r[1], r[2]]
            };
            let count = sens.position.len();
            d.set_item("params", matrix(py, &block(&pose, 0, count))?)?;
            if held_tip {
                let wrench = |k: usize| -> [f64; 6] {
                    let (f, m) = (sens.reaction_force[k], sens.reaction_moment[k]);
                    [f[0], f[1], f[2], m[0], m[1], m[2]]
                };
                reaction.set_item("params", matrix(py, &block(&wrench, 0, count))?)?;
            }
        }
        if held_tip {
            d.set_item("reaction", reaction)?;
        }
        Ok(d)
    })
}

/// The linearised dynamics at the equilibrium under `pressures` and tip loads (warm start
/// `x`) with `nodes` nodes: dict of mass, damping, stiffness, input (numpy) and nodes (m).
/// `tip_kind` "clamped" or "pinned" (with `tip_position`, and `tip_rotation` for a clamp)
/// linearises the equilibrium with the tip held there (`linearise::linearise_held`: a
/// clamped tip is no coordinate, a pinned one keeps its rotation). `stiffness_scale`: sigma
/// of a stiffness-mapped design (required there; its input has three more columns, d / d
/// sigma).
#[pyfunction]
#[pyo3(signature = (rod, pressures, tip_force, tip_moment, x, nodes, tensions=None, tip_kind="free", tip_position=None, tip_rotation=None, stiffness_scale=None))]
#[allow(clippy::too_many_arguments)]
pub fn linearise_at<'py>(
    py: Python<'py>,
    rod: PyRef<'_, PyRod>,
    pressures: Vec<f64>,
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    x: Option<Vec<f64>>,
    nodes: usize,
    tensions: Option<Vec<f64>>,
    tip_kind: &str,
    tip_position: Option<[f64; 3]>,
    tip_rotation: Option<[[f64; 3]; 3]>,
    stiffness_scale: Option<[f64; 3]>,
) -> PyResult<Bound<'py, PyDict>> {
    guarded(py, || {
        let held = crate::ends::constraint(py, tip_kind, tip_position, tip_rotation)?;
        let rod = &rod.rod;
        let checked = options(py, 1e-10, 25, true, 200, (1.0 / 3.0, 3.0), "ignore")?;
        let sigma =
            softrod_core::statics::system::lone_sigma("stiffness_scale", rod, stiffness_scale)
                .map_err(|e| to_py_err(py, e, Context::Input))?;
        let loads = Loads {
            pressures,
            tip_force,
            tip_moment,
            stiffness_scale: sigma,
            tensions: tensions.unwrap_or_else(|| vec![0.0; rod.n_tendons]),
            tip_frame: rod.spec.tip.frame,
        };
        let result = py.detach(|| -> softrod_core::Result<_> {
            rod.check_tensions(&loads.tensions)?;
            if let TipConstraint::Free = held {
                let sol = match x.as_deref() {
                    Some(x) => statics::solution_at(rod, &loads, x, &checked)?,
                    None => statics::solve(rod, &loads, None, &checked)?,
                };
                let sys = linearise(rod, &loads, &sol, nodes)?;
                return Ok((sol, sys));
            }
            let sol = solve_constrained(rod, &loads, &held, x.as_deref(), &checked)?.solution;
            let sys = linearise_held(rod, &loads, &held, &sol, nodes)?;
            Ok((sol, sys))
        });
        let (sol, sys) = result.map_err(|e| to_py_err(py, e, Context::Input))?;
        let d = PyDict::new(py);
        d.set_item("mass", matrix(py, &sys.mass)?)?;
        d.set_item("damping", matrix(py, &sys.damping)?)?;
        d.set_item("stiffness", matrix(py, &sys.stiffness)?)?;
        d.set_item("input", matrix(py, &sys.input)?)?;
        d.set_item("nodes", PyArray1::from_vec(py, sys.nodes))?;
        d.set_item("x", sol.x.to_vec())?;
        Ok(d)
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyInverse>()?;
    m.add_function(wrap_pyfunction!(point_jacobian_of, m)?)?;
    m.add_function(wrap_pyfunction!(linearise_at, m)?)?;
    Ok(())
}
