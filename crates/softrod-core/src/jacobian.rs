//! Exact first derivatives of a static equilibrium with respect to the chamber pressures,
//! the dead tip loads and the shooting unknowns, at any point of the rod: the building block
//! of inverse statics (`crate::inverse`), tip Jacobians and linearisations
//! (`crate::linearise`).
//!
//! One integration in `Jet<N>` carries N directions: the three scaled shooting unknowns x
//! (the base moment, see `crate::statics`) and up to N - 3 inputs (a pressure, a component of
//! the tip force or moment). Pressures enter through the coefficients (chamber forces and
//! moments, and with swelling the stiffnesses, paper 002 eq. 22), so the coefficients are
//! built from dual pressures (`Coeffs::build_with`); the tip force enters the known base
//! force n(0) and the tip moment the residual. A mapped design's stiffness factors sigma
//! enter the coefficients too (`Input::StiffnessScale`): sigma depends on the pressures
//! through the map, whose derivative the caller composes with these columns. The pass returns the shooting residual
//! g(x, a) and the state at a probe point with their partial derivatives; by the implicit
//! function theorem on g = 0, dx/da = -g_x^-1 g_a and every output y moves as
//! dy/da = y_a + y_x dx/da. No finite differences.
//!
//! [`point_jacobian6`] does the same with six unknowns (the base force and moment) and the
//! residual of a held tip, or of a free tip under follower loads or on obstacles; the tip
//! loads then enter the tip's balance as dual directions, and a held tip's reaction is one
//! more output.
//!
//! [`system`] differentiates a system of rods holding one platform with respect to its
//! inputs.

pub(crate) mod collocation;
pub mod system;

use crate::error::{Result, SoftrodError};
use crate::jet::{Coeff, Jet, StateScalar};
use crate::ode::{
    advance, integrate_with, Coeffs, Loads, NodeAt, SectionKnobs, State, TendonCoeff,
};
use crate::rod::Rod;
use crate::sensitivity::MarkerAt;
use crate::statics::constraint::{reaction_under, tip_residual_under, TipConstraint};
use crate::statics::tangent::singular_jacobian;
use crate::statics::{Problem, Solution};
use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3, Vector6};

/// An input a derivative is taken with respect to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Gauge pressure of a channel, Pa.
    Pressure(usize),
    /// Component of the dead tip force (world frame), N.
    TipForce(usize),
    /// Component of the dead tip moment (world frame), N m.
    TipMoment(usize),
    /// Tension of a tendon channel, N.
    Tension(usize),
    /// A factor of the stiffness scaling sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) of
    /// the mapped sections (docs/stiffness-map.md), 1: with the map's derivative d sigma /
    /// d p, the pressures' total derivative on a mapped design.
    StiffnessScale(usize),
}

/// Where the state is read: at a node, or a partial step after it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// Arc length, m.
    pub s: f64,
    section: usize,
    step: usize,
    offset: f64,
}

impl Probe {
    /// The point at arc length `s` in [0, L]. A point within 1e-9 of a step from a node is
    /// that node (so the tip is read exactly as the solver integrates it).
    pub fn at(rod: &Rod, s: f64) -> Result<Self> {
        if !(s.is_finite() && (0.0..=rod.length * (1.0 + 1e-12)).contains(&s)) {
            return Err(SoftrodError::invalid(
                "point",
                s,
                format!("the arc length must lie in [0, L] = [0, {}] m", rod.length),
            ));
        }
        let last = rod.sections.len() - 1;
        let i = rod
            .sections
            .iter()
            .position(|sec| s < sec.s_start + sec.length)
            .unwrap_or(last);
        let sec = &rod.sections[i];
        let h = sec.length / sec.steps as f64;
        let t = ((s - sec.s_start) / h).max(0.0);
        let mut step = (t.floor() as usize).min(sec.steps);
        let mut offset = (s - sec.s_start - h * step as f64).max(0.0);
        if offset >= h * (1.0 - 1e-9) {
            step = (step + 1).min(sec.steps);
            offset = 0.0;
        } else if offset <= h * 1e-9 {
            offset = 0.0;
        }
        Ok(Probe {
            s,
            section: i,
            step,
            offset,
        })
    }

    /// The probe as a marker on the centreline: a collocation solution's state there is
    /// read from its node (`crate::sensitivity::advance_from_node`).
    pub(crate) fn on_centreline(&self, rod: &Rod) -> MarkerAt {
        let sec = &rod.sections[self.section];
        MarkerAt {
            node: rod.sections[..self.section]
                .iter()
                .map(|s| s.steps)
                .sum::<usize>()
                + self.step,
            section: self.section,
            step: self.step,
            s_node: sec.s_start + self.step as f64 * sec.length / sec.steps as f64,
            h: self.offset,
            section_start: self.step == 0,
            offset: [0.0; 3],
        }
    }

    /// The tip.
    pub fn tip(rod: &Rod) -> Self {
        let i = rod.sections.len() - 1;
        Probe {
            s: rod.length,
            section: i,
            step: rod.sections[i].steps,
            offset: 0.0,
        }
    }
}

/// One pass: the residual and the probe's state, each with its partial derivatives in the
/// pass's directions (x first, then the inputs).
#[derive(Debug, Clone, PartialEq)]
pub struct Pass {
    /// Arc length of the probe, m.
    pub s: f64,
    /// Scaled shooting residual g (3).
    pub g: [f64; 3],
    /// d g / d x.
    pub g_x: Matrix3<f64>,
    /// d g / d input, one column per input.
    pub g_a: Vec<[f64; 3]>,
    /// Position (3) then rotation (9, row-major) at the probe.
    pub y: [f64; 12],
    /// d y / d x.
    pub y_x: [[f64; 3]; 12],
    /// d y / d input, one column per input.
    pub y_a: Vec<[f64; 12]>,
}

/// Pressures, knobs and sigma of the coefficients in `Jet<N>`, the listed pressures and
/// tensions seeded as directions `3 + k`.
pub(crate) fn dual_coeffs<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    inputs: &[Input],
) -> Vec<Coeffs<Jet<N>>> {
    dual_coeffs_from::<N>(rod, loads, inputs, 3)
}

/// [`dual_coeffs`] with the inputs seeded as directions `first + k` (after `first` shooting
/// unknowns: 3, or 6 with the base force among them).
pub(crate) fn dual_coeffs_from<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    inputs: &[Input],
    first: usize,
) -> Vec<Coeffs<Jet<N>>> {
    let mut p: Vec<Jet<N>> = loads.pressures.iter().map(|&v| Jet::from(v)).collect();
    for (k, a) in inputs.iter().enumerate() {
        if let Input::Pressure(c) = a {
            p[*c].eps[first + k] = 1.0;
        }
    }
    let mut sigma = loads.stiffness_scale.map(Jet::<N>::from);
    for (k, a) in inputs.iter().enumerate() {
        if let Input::StiffnessScale(j) = a {
            sigma[*j].eps[first + k] = 1.0;
        }
    }
    (0..rod.sections.len())
        .map(|i| {
            let knobs = SectionKnobs::of(&rod.sections[i]).lift();
            let mut coeffs = Coeffs::build_with(
                rod,
                i,
                &p,
                &loads.tensions,
                &rod.gravity,
                Jet::from(1.0),
                &sigma,
                &knobs,
            );
            seed_tensions(rod, i, loads, inputs, first, &mut coeffs);
            coeffs
        })
        .collect()
}

/// Seed the tension inputs among `inputs` in section `i`'s tendon coefficients. A slack
/// tendon (tension 0) is left out of the coefficients (it carries no load), but its
/// tension's derivative is not zero (pulling it bends the rod): it is added with value 0,
/// where the law's tangent is still defined (the tendon's length is positive).
fn seed_tensions<const N: usize>(
    rod: &Rod,
    i: usize,
    loads: &Loads,
    inputs: &[Input],
    first: usize,
    coeffs: &mut Coeffs<Jet<N>>,
) {
    for (k, a) in inputs.iter().enumerate() {
        let Input::Tension(t) = a else { continue };
        for route in rod.sections[i].tendons.iter().filter(|r| r.channel == *t) {
            match coeffs.tendons.iter_mut().find(|c| c.route == *route) {
                Some(c) => c.tension.eps[first + k] = 1.0,
                None => {
                    let mut tension = Jet::from(loads.tensions[*t]);
                    tension.eps[first + k] = 1.0;
                    coeffs.tendons.push(TendonCoeff {
                        tension,
                        route: *route,
                    });
                }
            }
        }
    }
}

fn flatten<D: Copy>(st: &State<D>) -> [D; 12] {
    let r = &st.rot;
    [
        st.r[0], st.r[1], st.r[2], r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0],
        r[2][1], r[2][2],
    ]
}

/// The pass in `Jet<N>` for at most N - 3 inputs.
fn pass_n<const N: usize>(
    problem: &Problem,
    rod: &Rod,
    loads: &Loads,
    x: &[f64; 3],
    inputs: &[Input],
    probe: &Probe,
) -> Pass {
    debug_assert!(inputs.len() + 3 <= N);
    let coeffs = dual_coeffs::<N>(rod, loads, inputs);
    let xd: [Jet<N>; 3] = std::array::from_fn(|i| Jet::variable(x[i], i));
    let mut y0 = problem.base_state(&xd);
    for (k, a) in inputs.iter().enumerate() {
        if let Input::TipForce(j) = a {
            // n(0) = F_tip + tip weight + int f: d n(0) / d F_tip = I.
            y0.n[*j].eps[3 + k] = 1.0;
        }
    }
    let (tip, point) = integrate_to(rod, &coeffs, y0, probe);
    let mut g = problem.residual_of_tip(&tip);
    let ms = rod.force_scale * rod.length;
    for (k, a) in inputs.iter().enumerate() {
        if let Input::TipMoment(j) = a {
            // g = (m(L) - c x W - M_tip) / M_s
            g[*j].eps[3 + k] -= 1.0 / ms;
        }
    }
    let y = flatten(&point);
    Pass {
        s: probe.s,
        g: g.map(|v| v.re),
        g_x: Matrix3::from_fn(|i, j| g[i].eps[j]),
        g_a: (0..inputs.len())
            .map(|k| std::array::from_fn(|i| g[i].eps[3 + k]))
            .collect(),
        y: y.map(|v| v.re),
        y_x: std::array::from_fn(|i| std::array::from_fn(|j| y[i].eps[j])),
        y_a: (0..inputs.len())
            .map(|k| std::array::from_fn(|i| y[i].eps[3 + k]))
            .collect(),
    }
}

/// Inputs per pass beyond x: passes with more directions are split into chunks.
const CHUNK: usize = 6;

/// The residual and the probe's state at (x, loads) with their partial derivatives with
/// respect to x and `inputs`. Inputs are checked by the caller (channels in range).
pub fn pass(rod: &Rod, loads: &Loads, x: &[f64; 3], inputs: &[Input], probe: &Probe) -> Pass {
    let problem = Problem::new(rod, loads, 1.0);
    pass_with(&problem, rod, loads, x, inputs, probe)
}

/// [`pass`] on an already built problem (its loads must be `loads`).
pub(crate) fn pass_with(
    problem: &Problem,
    rod: &Rod,
    loads: &Loads,
    x: &[f64; 3],
    inputs: &[Input],
    probe: &Probe,
) -> Pass {
    let run = |chunk: &[Input]| -> Pass {
        match chunk.len() {
            0 => pass_n::<3>(problem, rod, loads, x, chunk, probe),
            1 => pass_n::<4>(problem, rod, loads, x, chunk, probe),
            2 => pass_n::<5>(problem, rod, loads, x, chunk, probe),
            3 => pass_n::<6>(problem, rod, loads, x, chunk, probe),
            4 => pass_n::<7>(problem, rod, loads, x, chunk, probe),
            5 => pass_n::<8>(problem, rod, loads, x, chunk, probe),
            _ => pass_n::<9>(problem, rod, loads, x, chunk, probe),
        }
    };
    let mut chunks = inputs.chunks(CHUNK);
    let mut out = run(chunks.next().unwrap_or(&[]));
    for chunk in chunks {
        let more = run(chunk);
        out.g_a.extend(more.g_a);
        out.y_a.extend(more.y_a);
    }
    out
}

/// The value part only (residual and probe state), at f64 cost.
pub(crate) fn value_with(
    problem: &Problem,
    rod: &Rod,
    x: &[f64; 3],
    probe: &Probe,
) -> ([f64; 3], State<f64>, State<f64>) {
    let (tip, point) = integrate_to(rod, &problem.coeffs, problem.base_state(x), probe);
    (problem.residual_of_tip(&tip), point, tip)
}

/// Integrate from `y0` to the tip, reading the state at `probe` on the way: (tip, state at
/// the probe).
fn integrate_to<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    probe: &Probe,
) -> (State<D>, State<D>) {
    let mut point = None;
    let tip = integrate_with(rod, coeffs, y0, &mut |node: NodeAt, y| {
        if point.is_none() && node.section == probe.section && node.step == probe.step {
            point = Some(advance(rod, coeffs, node, y, probe.offset));
        }
        false
    });
    (tip, point.unwrap_or(tip))
}

/// Total derivatives of the probe's position and rotation with respect to each input at a
/// converged equilibrium, by the implicit function theorem.
#[derive(Debug, Clone, PartialEq)]
pub struct PointJacobian {
    pub position: [f64; 3],
    pub rotation: [[f64; 3]; 3],
    /// d r / d a_k (world frame), one per input.
    pub d_position: Vec<[f64; 3]>,
    /// The small rotation d theta / d a_k (world frame, d R = [d theta]x R), one per input.
    pub d_rotation: Vec<[f64; 3]>,
}

/// The three shooting unknowns of a solution with dead loads.
pub(crate) fn unknowns3(sol: &Solution) -> Result<[f64; 3]> {
    shooting_derivable(sol)?;
    <[f64; 3]>::try_from(sol.x.as_slice()).map_err(|_| {
        SoftrodError::invalid(
            "solution",
            format!("{} shooting unknowns", sol.x.len()),
            "a solution with dead loads (3 shooting unknowns) is needed here",
        )
    })
}

/// Shooting passes from the solution's unknowns x would leave an equilibrium that
/// collocation solved (single shooting cannot resolve such a rod: docs/model.md,
/// "Collocation"): its readers differentiate the collocation equations instead
/// ([`collocation`], `crate::sensitivity::collocation`, `crate::linearise::collocation`, the
/// inverse's collocation iterates), so reaching a shooting pass with one is a defect.
pub(crate) fn shooting_derivable(sol: &Solution) -> Result<()> {
    if sol.collocation.is_some() {
        return Err(SoftrodError::Internal(
            "a shooting pass from an equilibrium that collocation solved".into(),
        ));
    }
    Ok(())
}

/// Error for a singular shooting Jacobian (the equilibrium is at a limit point).
pub(crate) fn singular(sol: &Solution) -> SoftrodError {
    singular_jacobian(
        sol.iterations,
        sol.residual,
        "the shooting Jacobian",
        "derivatives",
    )
}

/// Pose (dr, dtheta) derivative of a state with respect to the directions, given the
/// rotation's value: dtheta from [dtheta]x = dR R^T.
pub(crate) fn pose_derivative<const N: usize>(y: &State<Jet<N>>, dir: usize) -> [f64; 6] {
    let rot: [[f64; 3]; 3] = y.rot.map(|r| r.map(|v| v.re));
    let d_rot: [[f64; 3]; 3] = y.rot.map(|r| r.map(|v| v.eps[dir]));
    let w = small_rotation(&rot, &d_rot);
    [
        y.r[0].eps[dir],
        y.r[1].eps[dir],
        y.r[2].eps[dir],
        w[0],
        w[1],
        w[2],
    ]
}

/// The small rotation w (world) with d R = [w]x R, from d R and R: [w]x = dR R^T.
pub fn small_rotation(rot: &[[f64; 3]; 3], d_rot: &[[f64; 3]; 3]) -> [f64; 3] {
    let w = |i: usize, j: usize| -> f64 { (0..3).map(|k| d_rot[i][k] * rot[j][k]).sum() };
    // vee of the skew part (dR R^T is skew to first order; averaging removes round-off).
    [
        0.5 * (w(2, 1) - w(1, 2)),
        0.5 * (w(0, 2) - w(2, 0)),
        0.5 * (w(1, 0) - w(0, 1)),
    ]
}

/// Total derivatives of the probe's values (12 per input) and of x (3 per input).
pub type TotalDerivatives = (Vec<[f64; 12]>, Vec<[f64; 3]>);

/// Reduce a pass to total derivatives: dy/da = y_a - y_x g_x^-1 g_a. Also returns dx/da.
pub fn total_derivatives(p: &Pass) -> Option<TotalDerivatives> {
    let lu = p.g_x.lu();
    let mut dy = Vec::with_capacity(p.g_a.len());
    let mut dxs = Vec::with_capacity(p.g_a.len());
    for (ga, ya) in p.g_a.iter().zip(&p.y_a) {
        let dx = lu
            .solve(&-Vector3::from_column_slice(ga))
            .filter(|d| d.iter().all(|v| v.is_finite()))?;
        dy.push(std::array::from_fn(|i| {
            ya[i] + (0..3).map(|j| p.y_x[i][j] * dx[j]).sum::<f64>()
        }));
        dxs.push([dx[0], dx[1], dx[2]]);
    }
    Some((dy, dxs))
}

/// The exact Jacobian of the pose at `probe` with respect to `inputs` at the converged
/// solution `sol` of `loads`.
pub fn point_jacobian(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    inputs: &[Input],
    probe: &Probe,
) -> Result<PointJacobian> {
    check_inputs(rod, inputs)?;
    crate::scope::dead_loads_only(rod, loads, "the point Jacobian")?;
    if sol.collocation.is_some() {
        // Implicit differentiation of the collocation equations: a shooting pass from x
        // would leave this equilibrium.
        return collocation::point_jacobian(rod, loads, sol, inputs, probe);
    }
    let x = unknowns3(sol)?;
    let p = pass(rod, loads, &x, inputs, probe);
    let (dy, _) = total_derivatives(&p).ok_or_else(|| singular(sol))?;
    let rot: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| p.y[3 + 3 * i + j]));
    Ok(PointJacobian {
        position: [p.y[0], p.y[1], p.y[2]],
        rotation: rot,
        d_position: dy.iter().map(|d| [d[0], d[1], d[2]]).collect(),
        d_rotation: dy
            .iter()
            .map(|d| {
                let dr = std::array::from_fn(|i| std::array::from_fn(|j| d[3 + 3 * i + j]));
                small_rotation(&rot, &dr)
            })
            .collect(),
    })
}

/// Inputs name existing channels and components.
pub fn check_inputs(rod: &Rod, inputs: &[Input]) -> Result<()> {
    for (k, a) in inputs.iter().enumerate() {
        let bad = match a {
            Input::Pressure(c) => *c >= rod.n_channels,
            Input::Tension(t) => *t >= rod.n_tendons,
            Input::TipForce(j) | Input::TipMoment(j) | Input::StiffnessScale(j) => *j >= 3,
        };
        if bad {
            return Err(SoftrodError::invalid(
                format!("inputs[{k}]"),
                format!("{a:?}"),
                format!(
                    "pressure channels are 0..{}, tendon channels 0..{}, load and stiffness scale components 0..3",
                    rod.n_channels, rod.n_tendons
                ),
            ));
        }
    }
    Ok(())
}

/// The Jacobian as a dense (6, inputs) matrix: rows position (3) then small rotation (3).
pub fn as_matrix(j: &PointJacobian) -> DMatrix<f64> {
    DMatrix::from_fn(6, j.d_position.len(), |i, k| {
        if i < 3 {
            j.d_position[k][i]
        } else {
            j.d_rotation[k][i - 3]
        }
    })
}

/// The point Jacobian of an equilibrium with six shooting unknowns (the base force and
/// moment, scaled): a tip held by `constraint` (pinned or clamped, the converged solution of
/// `crate::statics::constraint::solve_constrained`), or a free tip under follower loads or
/// pressed on obstacles (frictionless), where n(0) is unknown too. The same implicit
/// differentiation as [`point_jacobian`] with that tip's residual
/// (`constraint::tip_residual_under`): the pressures and tensions enter through the
/// coefficients, the tip force and moment through the tip's balance (the free tip's six
/// rows; a pinned tip's moment rows; a clamped tip's residual has none, so its shape does
/// not depend on them). For a held tip, also the derivatives of the reaction the
/// constraint applies to the tip (world frame; zero moment when pinned).
pub fn point_jacobian6(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    sol: &Solution,
    inputs: &[Input],
    probe: &Probe,
) -> Result<HeldJacobian> {
    check_inputs(rod, inputs)?;
    let x: [f64; 6] = <[f64; 6]>::try_from(sol.x.as_slice()).map_err(|_| {
        SoftrodError::invalid(
            "solution",
            format!("{} shooting unknowns", sol.x.len()),
            "six shooting unknowns (base force and moment) are needed here: a held tip's \
             equilibrium, or a free tip's under follower loads or with obstacles",
        )
    })?;
    let problem = Problem::new(rod, loads, 1.0);
    let held = !matches!(constraint, TipConstraint::Free);
    let run = |chunk: &[Input]| -> Pass6 {
        match chunk.len() {
            0 => pass6::<6>(&problem, rod, loads, constraint, &x, chunk, probe),
            1 => pass6::<7>(&problem, rod, loads, constraint, &x, chunk, probe),
            2 => pass6::<8>(&problem, rod, loads, constraint, &x, chunk, probe),
            _ => pass6::<9>(&problem, rod, loads, constraint, &x, chunk, probe),
        }
    };
    let mut chunks = inputs.chunks(3);
    let mut p = run(chunks.next().unwrap_or(&[]));
    for chunk in chunks {
        let more = run(chunk);
        p.g_a.extend(more.g_a);
        p.y_a.extend(more.y_a);
        p.q_a.extend(more.q_a);
    }
    let lu = p.g_x.lu();
    let rot: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| p.y[3 + 3 * i + j]));
    let pinned = matches!(constraint, TipConstraint::Pinned { .. });
    let mut out = HeldJacobian {
        point: PointJacobian {
            position: [p.y[0], p.y[1], p.y[2]],
            rotation: rot,
            d_position: Vec::with_capacity(inputs.len()),
            d_rotation: Vec::with_capacity(inputs.len()),
        },
        reaction_force: vec![],
        reaction_moment: vec![],
    };
    for ((ga, ya), qa) in p.g_a.iter().zip(&p.y_a).zip(&p.q_a) {
        let dx = lu
            .solve(&-Vector6::from_column_slice(ga))
            .filter(|d| d.iter().all(|v| v.is_finite()))
            .ok_or_else(|| singular(sol))?;
        let dy: [f64; 12] =
            std::array::from_fn(|i| ya[i] + (0..6).map(|j| p.y_x[i][j] * dx[j]).sum::<f64>());
        out.point.d_position.push([dy[0], dy[1], dy[2]]);
        let dr = std::array::from_fn(|i| std::array::from_fn(|j| dy[3 + 3 * i + j]));
        out.point.d_rotation.push(small_rotation(&rot, &dr));
        if held {
            let dq: [f64; 6] =
                std::array::from_fn(|i| qa[i] + (0..6).map(|j| p.q_x[i][j] * dx[j]).sum::<f64>());
            out.reaction_force.push([dq[0], dq[1], dq[2]]);
            // A pin carries no moment: its moment balance is a residual row (zero).
            out.reaction_moment.push(if pinned {
                [0.0; 3]
            } else {
                [dq[3], dq[4], dq[5]]
            });
        }
    }
    Ok(out)
}

/// [`point_jacobian6`]'s result: the point's derivatives, and for a held tip those of its
/// reaction, one per input (empty for a free tip).
#[derive(Debug, Clone, PartialEq)]
pub struct HeldJacobian {
    pub point: PointJacobian,
    /// d F_r / d a_k (world frame), N per unit of the input.
    pub reaction_force: Vec<[f64; 3]>,
    /// d M_r / d a_k (world frame), N m per unit of the input; zero for a pinned tip.
    pub reaction_moment: Vec<[f64; 3]>,
}

/// One pass of [`point_jacobian6`]: the residual's, the probe's and the reaction's partial
/// derivatives in the six unknowns and the chunk's inputs.
struct Pass6 {
    g_x: Matrix6<f64>,
    g_a: Vec<[f64; 6]>,
    /// Position (3) then rotation (9, row-major) at the probe.
    y: [f64; 12],
    y_x: [[f64; 6]; 12],
    y_a: Vec<[f64; 12]>,
    /// The tip's reaction (force, moment), whose value is not needed.
    q_x: [[f64; 6]; 6],
    q_a: Vec<[f64; 6]>,
}

/// The pass in `Jet<N>` for at most N - 6 inputs.
fn pass6<const N: usize>(
    problem: &Problem,
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    x: &[f64; 6],
    inputs: &[Input],
    probe: &Probe,
) -> Pass6 {
    debug_assert!(inputs.len() + 6 <= N);
    let coeffs = dual_coeffs_from::<N>(rod, loads, inputs, 6);
    let xd: [Jet<N>; 6] = std::array::from_fn(|i| Jet::variable(x[i], i));
    // n(0) is an unknown: the tip loads enter through the tip's balance only.
    let mut f_tip = loads.tip_force.map(Jet::<N>::from);
    let mut m_tip = loads.tip_moment.map(Jet::<N>::from);
    for (k, a) in inputs.iter().enumerate() {
        match a {
            Input::TipForce(j) => f_tip[*j].eps[6 + k] = 1.0,
            Input::TipMoment(j) => m_tip[*j].eps[6 + k] = 1.0,
            _ => {}
        }
    }
    let (tip, point) = integrate_to(rod, &coeffs, problem.base_state(&xd), probe);
    let g = tip_residual_under(problem, constraint, &tip, &f_tip, &m_tip);
    let (qf, qm) = reaction_under(problem, &tip, &f_tip, &m_tip);
    let q = [qf[0], qf[1], qf[2], qm[0], qm[1], qm[2]];
    let y = flatten(&point);
    Pass6 {
        g_x: Matrix6::from_fn(|i, j| g[i].eps[j]),
        g_a: (0..inputs.len())
            .map(|k| std::array::from_fn(|i| g[i].eps[6 + k]))
            .collect(),
        y: y.map(|v| v.re),
        y_x: std::array::from_fn(|i| std::array::from_fn(|j| y[i].eps[j])),
        y_a: (0..inputs.len())
            .map(|k| std::array::from_fn(|i| y[i].eps[6 + k]))
            .collect(),
        q_x: std::array::from_fn(|i| std::array::from_fn(|j| q[i].eps[j])),
        q_a: (0..inputs.len())
            .map(|k| std::array::from_fn(|i| q[i].eps[6 + k]))
            .collect(),
    }
}
