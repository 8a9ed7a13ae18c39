//! Exact first derivatives of a system's equilibrium (rods whose tips hold one platform, a
//! parallel continuum robot: `crate::statics::system`) with respect to its inputs: each
//! rod's chamber pressures and tendon tensions (and, for a stiffness-mapped rod, its
//! factors sigma, which the caller composes with its map's d sigma / d p), and the force and
//! moment applied to the platform. The outputs are the platform's pose and every rod's base
//! wrench: the actuation Jacobian that resolved-rate control of the platform needs, the
//! platform's compliance (its pose per unit of platform load), and what force sensing from
//! the loads measured at the rods' bases needs (Black, Till & Rucker, "Parallel continuum
//! robots: modeling, analysis, and actuation-based force sensing", IEEE T-RO 2018, doi
//! 10.1109/TRO.2017.2753829, Sec. V).
//!
//! The implicit function theorem on the system's residual R(x, a) = 0 (6 unknowns per rod,
//! then the platform's 6), as `crate::sensitivity::system` does for model parameters:
//! dx/da = -J^-1 d_a R with J the exact Jacobian Newton uses (`Level::jacobian`). A rod's
//! pressures and tensions enter its coefficients, so d_a R costs one dual integration of that
//! rod per chunk of its inputs (its six rows and its wrench on the platform, at the fixed
//! platform pose); the platform's load enters the platform's balance rows linearly. The
//! platform moves by dp = L_s dx_p and the small rotation psi = dx_psi (world frame, dR_p =
//! [psi]x R_p); rod i's base wrench (n_i(0), m_i(0)) is its scaled unknowns times its force
//! and moment scales.
//!
//! A frictional equilibrium is refused: it depends on its load path, and the return map's
//! stick/slip switch has no derivative there.

use super::{dual_coeffs_from, pose_derivative, Input};
use crate::error::{Result, SoftrodError};
use crate::jet::Jet;
use crate::ode::{integrate_with, NodeAt, State};
use crate::statics::system::{Level, Platform, SystemRod, SystemSolution};
use crate::statics::tangent::{singular_jacobian, solve_tangent, system_tangent};
use nalgebra::DMatrix;

/// An input of a system a derivative is taken with respect to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SystemInput {
    /// Gauge pressure of a channel of a rod, Pa.
    Pressure { rod: usize, channel: usize },
    /// Tension of a tendon channel of a rod, N.
    Tension { rod: usize, channel: usize },
    /// A factor of a stiffness-mapped rod's sigma (0: extension, 1, 2: bending about d1,
    /// d2), 1.
    StiffnessScale { rod: usize, factor: usize },
    /// Component of the external force on the platform (world), N.
    PlatformForce(usize),
    /// Component of the external moment on the platform (about its origin, world), N m.
    PlatformMoment(usize),
}

impl SystemInput {
    /// The rod this input acts on and its input in that rod's terms (None: the platform).
    pub(crate) fn on_rod(&self) -> Option<(usize, Input)> {
        match *self {
            SystemInput::Pressure { rod, channel } => Some((rod, Input::Pressure(channel))),
            SystemInput::Tension { rod, channel } => Some((rod, Input::Tension(channel))),
            SystemInput::StiffnessScale { rod, factor } => {
                Some((rod, Input::StiffnessScale(factor)))
            }
            SystemInput::PlatformForce(_) | SystemInput::PlatformMoment(_) => None,
        }
    }
}

/// Derivatives of a system's equilibrium, one entry per input.
#[derive(Debug, Clone, PartialEq)]
pub struct SystemJacobian {
    /// The platform's pose at the equilibrium (world).
    pub position: [f64; 3],
    pub rotation: [[f64; 3]; 3],
    /// d p / d a_k (world), m per unit of the input.
    pub d_position: Vec<[f64; 3]>,
    /// The platform's small rotation d psi / d a_k (world, dR_p = [d psi]x R_p).
    pub d_rotation: Vec<[f64; 3]>,
    /// d n_i(0) / d a_k, the base force of rod i (world, N per unit): `d_base_force[k][i]`.
    pub d_base_force: Vec<Vec<[f64; 3]>>,
    /// d m_i(0) / d a_k, the base moment of rod i (world, N m per unit).
    pub d_base_moment: Vec<Vec<[f64; 3]>>,
}

/// Inputs per dual integration of a rod.
const CHUNK: usize = 6;

/// Check the inputs against the system: rods, channels and components that exist. Errors
/// name `inputs[k]`.
pub fn check_system_inputs(rods: &[SystemRod], inputs: &[SystemInput]) -> Result<()> {
    for (k, a) in inputs.iter().enumerate() {
        let rule = match *a {
            SystemInput::PlatformForce(j) | SystemInput::PlatformMoment(j) => {
                (j >= 3).then(|| "a platform load has components 0..3".to_string())
            }
            _ => {
                let (i, input) = a.on_rod().expect("a rod's input");
                match rods.get(i) {
                    None => Some(format!("the system has {} rods", rods.len())),
                    Some(r) => super::check_inputs(r.rod, &[input]).err().map(|_| {
                        format!(
                            "rod {i} has pressure channels 0..{}, tendon channels 0..{} \
                                 and stiffness factors 0..3",
                            r.rod.n_channels, r.rod.n_tendons
                        )
                    }),
                }
            }
        };
        if let Some(rule) = rule {
            return Err(SoftrodError::invalid(
                format!("inputs[{k}]"),
                format!("{a:?}"),
                rule,
            ));
        }
    }
    Ok(())
}

/// The exact derivatives of the platform's pose and of every rod's base wrench with respect
/// to `inputs` at the converged frictionless system `sol` of `rods` and `platform`.
pub fn system_jacobian(
    rods: &[SystemRod],
    platform: &Platform,
    sol: &SystemSolution,
    inputs: &[SystemInput],
) -> Result<SystemJacobian> {
    check_system_inputs(rods, inputs)?;
    let (level, x, lu) = system_tangent(
        rods,
        platform,
        sol,
        "and the stick/slip switch has no derivative: its Jacobian is not defined (obstacles without friction have one)",
    )?;
    let n = rods.len();
    let (p0, r0) = level.platform(x);
    let no_nodes = vec![vec![]; n];
    let (d_res, _) = input_residuals(rods, &level, x, inputs, &no_nodes);
    let mut out = SystemJacobian {
        position: p0,
        rotation: r0,
        d_position: Vec::with_capacity(inputs.len()),
        d_rotation: Vec::with_capacity(inputs.len()),
        d_base_force: Vec::with_capacity(inputs.len()),
        d_base_moment: Vec::with_capacity(inputs.len()),
    };
    for column in d_res.column_iter() {
        let rhs = -column.into_owned();
        let dx = solve_tangent(&lu, &rhs, || {
            singular_jacobian(
                sol.iterations,
                sol.residual,
                "the system's Jacobian",
                "derivatives",
            )
        })?;
        out.d_position
            .push(std::array::from_fn(|c| dx[6 * n + c] * level.ls));
        out.d_rotation
            .push(std::array::from_fn(|c| dx[6 * n + 3 + c]));
        // The scales of `Problem::base_state`: x_i = (n_i(0) / F_s, m_i(0) / (F_s L)).
        let fs = |i: usize| rods[i].rod.force_scale;
        let ms = |i: usize| rods[i].rod.force_scale * rods[i].rod.length;
        out.d_base_force.push(
            (0..n)
                .map(|i| std::array::from_fn(|c| dx[6 * i + c] * fs(i)))
                .collect(),
        );
        out.d_base_moment.push(
            (0..n)
                .map(|i| std::array::from_fn(|c| dx[6 * i + 3 + c] * ms(i)))
                .collect(),
        );
    }
    Ok(out)
}

/// What each input changes at fixed unknowns: its column of d_a R (the system residual,
/// `dim` rows), and for a rod's input the pose derivatives (dr, dtheta) of that rod's states
/// at its nodes `nodes[i]` (section, step, s) in that order (empty for a platform load). A
/// rod's pressures and tensions enter its coefficients: one dual integration of that rod
/// per chunk of its inputs (its six rows and its wrench on the platform, at the fixed
/// platform pose); the platform's load enters the balance rows linearly.
#[allow(clippy::type_complexity)]
pub(crate) fn input_residuals(
    rods: &[SystemRod],
    level: &Level,
    x: &[f64],
    inputs: &[SystemInput],
    nodes: &[Vec<(usize, usize, f64)>],
) -> (DMatrix<f64>, Vec<Vec<[f64; 6]>>) {
    let n = rods.len();
    let (p0, r0) = level.platform(x);
    let mut d_res = DMatrix::<f64>::zeros(6 * n + 6, inputs.len());
    let mut at_nodes: Vec<Vec<[f64; 6]>> = vec![vec![]; inputs.len()];
    for (k, a) in inputs.iter().enumerate() {
        let unit = |j: usize| -> [f64; 3] { std::array::from_fn(|c| f64::from(c == j)) };
        let rows = match *a {
            SystemInput::PlatformForce(j) => level.balance_rows(&unit(j), &[0.0; 3]),
            SystemInput::PlatformMoment(j) => level.balance_rows(&[0.0; 3], &unit(j)),
            _ => continue,
        };
        for r in 0..6 {
            d_res[(6 * n + r, k)] = rows[r];
        }
    }
    let pd = p0.map(Jet::<CHUNK>::from);
    let rd = r0.map(|row| row.map(Jet::<CHUNK>::from));
    for (i, sr) in rods.iter().enumerate() {
        let mine: Vec<(usize, Input)> = inputs
            .iter()
            .enumerate()
            .filter_map(|(k, a)| match a.on_rod() {
                Some((r, input)) if r == i => Some((k, input)),
                _ => None,
            })
            .collect();
        let pr = &level.problems[i];
        for chunk in mine.chunks(CHUNK) {
            let chunk_inputs: Vec<Input> = chunk.iter().map(|(_, a)| *a).collect();
            let coeffs = dual_coeffs_from::<CHUNK>(sr.rod, &sr.loads, &chunk_inputs, 0);
            let xi: Vec<Jet<CHUNK>> = x[6 * i..6 * i + 6].iter().map(|v| Jet::from(*v)).collect();
            let mut states: Vec<State<Jet<CHUNK>>> = Vec::with_capacity(nodes[i].len());
            let tip = integrate_with(
                sr.rod,
                &coeffs,
                pr.base_state(&xi),
                &mut |node: NodeAt, y| {
                    if node.step > 0
                        && nodes[i]
                            .iter()
                            .any(|nd| (nd.0, nd.1) == (node.section, node.step))
                    {
                        states.push(*y);
                    }
                    false
                },
            );
            let (rows, f, m) = level.rod_terms(i, &tip, &pd, &rd);
            let balance = level.balance_rows(&f, &m);
            for (q, (k, _)) in chunk.iter().enumerate() {
                for r in 0..6 {
                    d_res[(6 * i + r, *k)] = rows[r].eps[q];
                    d_res[(6 * n + r, *k)] = balance[r].eps[q];
                }
                at_nodes[*k] = states.iter().map(|st| pose_derivative(st, q)).collect();
            }
        }
    }
    (d_res, at_nodes)
}
