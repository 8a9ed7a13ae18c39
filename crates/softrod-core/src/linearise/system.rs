//! The linearised dynamics of a system of rods (a parallel continuum robot:
//! `crate::statics::system`) about a converged equilibrium: M q'' + D q' + K q = B u with q
//! the displacements and small rotations (world) of every rod's inner nodes, rod by rod,
//! then of the platform (its origin's displacement and its small rotation, dR_p = [psi]x
//! R_p), and u the inputs (`SystemInput`: rods' pressures, tensions and stiffness factors,
//! the platform's force and moment).
//!
//! The construction is the lone rod's (`crate::linearise`, a Ritz method with the static
//! deflection shapes) on the system's residual: K = C^-1 with C the flexibility, the
//! derivative of the coordinates' poses with respect to their conjugate loads (a point
//! force and moment at a rod's node, the force and moment on the platform), by the implicit
//! function theorem on the system residual with Newton's own Jacobian
//! (`crate::statics::tangent::system_tangent`). A point load at a node of rod i enters only
//! rod i's integration (one dual pass per node: its six rows and its wrench on the
//! platform); every rod's shape then follows from its own base unknowns' change, the
//! derivatives of its intervals with respect to its six base unknowns (one dual pass per
//! rod). M and D are the rods' Gram matrices in those shapes, plus the rigid bodies on the
//! platform: the platform (mass, centre of mass, inertia about it) and every rod's tip body,
//! whose tip is clamped to the platform. A rod's tip is no coordinate: it moves with the
//! platform.

use super::{
    choose_inner_nodes, interval_gram, load_pass, pose_derivative, rigid_block, tip_body_block,
    Interval, Meta,
};
use crate::error::{Result, SoftrodError};
use crate::jacobian::system::{check_system_inputs, input_residuals, SystemInput};
use crate::jet::Jet;
use crate::ode::State;
use crate::statics::system::{Level, Platform, SystemRod, SystemSolution};
use crate::statics::tangent::{singular_jacobian, solve_tangent, system_tangent};
use nalgebra::linalg::LU;
use nalgebra::{DMatrix, DVector, Dyn, Matrix3};

/// The linearised system of rods and platform (SI). q = (rod 0's nodes, rod 1's, ..., the
/// platform), 6 coordinates each.
#[derive(Debug, Clone, PartialEq)]
pub struct SystemLinear {
    /// Arc length of every rod's nodes, m (all inside the rod: its tip moves with the
    /// platform).
    pub nodes: Vec<Vec<f64>>,
    pub mass: DMatrix<f64>,
    pub damping: DMatrix<f64>,
    pub stiffness: DMatrix<f64>,
    /// One column per input, in the order given.
    pub input: DMatrix<f64>,
}

/// One rod's derivatives: its intervals (pose and strains at both ends and the midpoint) and
/// its nodes' poses, with respect to its six base unknowns.
struct RodShapes {
    meta: Vec<Meta>,
    /// [interval][end]: (6, 6) pose and strain derivatives per base unknown.
    pose_x: Vec<[DMatrix<f64>; 3]>,
    strain_x: Vec<[DMatrix<f64>; 3]>,
    /// Index of the interval that ends at each node.
    at_node: Vec<usize>,
    /// The tip's position and rotation.
    tip: ([f64; 3], [[f64; 3]; 3]),
}

type Dual = Jet<12>;

/// Pose (6) and strain (6) derivative matrices (6, k) of an interval end for directions
/// `dirs`.
fn end_derivatives(
    st: &State<Dual>,
    strain: &[Dual; 6],
    dirs: std::ops::Range<usize>,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let k = dirs.len();
    let mut p = DMatrix::zeros(6, k);
    let mut s = DMatrix::zeros(6, k);
    for (c, dir) in dirs.enumerate() {
        let pose = pose_derivative(st, dir);
        for r in 0..6 {
            p[(r, c)] = pose[r];
            s[(r, c)] = strain[r].eps[dir];
        }
    }
    (p, s)
}

fn ends(iv: &Interval<Dual>) -> [(&State<Dual>, &[Dual; 6]); 3] {
    [
        (&iv.start, &iv.strain_a),
        (&iv.mid, &iv.strain_m),
        (&iv.end, &iv.strain_b),
    ]
}

/// `e` of rod `i`: a field gets the prefix `rods[i].`.
fn on_rod(e: SoftrodError, i: usize) -> SoftrodError {
    match e {
        SoftrodError::InvalidParameter { field, value, rule } => SoftrodError::InvalidParameter {
            field: format!("rods[{i}].{field}"),
            value,
            rule,
        },
        other => other,
    }
}

/// Linearise the system `rods` holding `platform` at its converged frictionless equilibrium
/// `sol`, with `n_nodes` nodes inside every rod (`choose_inner_nodes`) and the platform's
/// inertia `platform_inertia` (kg m^2, about its centre of mass, platform frame); one input
/// column per entry of `inputs` (see the module docs).
pub fn linearise_system(
    rods: &[SystemRod],
    platform: &Platform,
    platform_inertia: &[[f64; 3]; 3],
    sol: &SystemSolution,
    n_nodes: usize,
    inputs: &[SystemInput],
) -> Result<SystemLinear> {
    check_system_inputs(rods, inputs)?;
    crate::dynamics::system::check_inertia(platform_inertia)?;
    let nodes: Vec<Vec<(usize, usize, f64)>> = rods
        .iter()
        .enumerate()
        .map(|(i, r)| choose_inner_nodes(r.rod, n_nodes).map_err(|e| on_rod(e, i)))
        .collect::<Result<_>>()?;
    let (level, x, lu) = system_tangent(
        rods,
        platform,
        sol,
        "and the stick/slip switch has no derivative: it has no linearisation",
    )?;
    let singular = || {
        singular_jacobian(
            sol.iterations,
            sol.residual,
            "the system's Jacobian",
            "linearisation",
        )
    };
    let n = rods.len();
    let dim = 6 * n + 6;
    let offsets: Vec<usize> = (0..n)
        .map(|i| 6 * nodes[..i].iter().map(Vec::len).sum::<usize>())
        .collect();
    let platform_at = 6 * nodes.iter().map(Vec::len).sum::<usize>();
    let nq = platform_at + 6;
    let (p0, r0) = level.platform(x);
    let pd = p0.map(Dual::from);
    let rd = r0.map(|row| row.map(Dual::from));

    // Every rod's interval derivatives with respect to its own base unknowns (one pass
    // without a point load).
    let shapes: Vec<RodShapes> = rods
        .iter()
        .enumerate()
        .map(|(i, sr)| {
            let (end, intervals) = load_pass::<12>(
                &level.problems[i],
                sr.rod,
                &x[6 * i..6 * i + 6],
                (usize::MAX, 0),
            );
            let mut pose_x = Vec::with_capacity(intervals.len());
            let mut strain_x = Vec::with_capacity(intervals.len());
            let mut meta = Vec::with_capacity(intervals.len());
            for iv in &intervals {
                let mut p: [DMatrix<f64>; 3] = std::array::from_fn(|_| DMatrix::zeros(6, 6));
                let mut s = p.clone();
                for (e, (st, sn)) in ends(iv).into_iter().enumerate() {
                    (p[e], s[e]) = end_derivatives(st, sn, 0..6);
                }
                pose_x.push(p);
                strain_x.push(s);
                let value = |st: &State<Dual>| st.rot.map(|r| r.map(|v| v.re));
                meta.push((
                    iv.section,
                    iv.a,
                    iv.b,
                    [value(&iv.start), value(&iv.mid), value(&iv.end)],
                ));
            }
            let at_node = nodes[i]
                .iter()
                .map(|&(_, _, s)| {
                    intervals
                        .iter()
                        .position(|iv| (iv.b - s).abs() <= 1e-12 * sr.rod.length)
                        .expect("every node ends an interval")
                })
                .collect();
            RodShapes {
                meta,
                pose_x,
                strain_x,
                at_node,
                tip: (end.r.map(|v| v.re), end.rot.map(|r| r.map(|v| v.re))),
            }
        })
        .collect();

    // Per load coordinate: the change of every unknown, dx (dim), and the loaded rod's own
    // partial derivatives (rod, [interval][end] pose and strain columns).
    let mut dxs = DMatrix::<f64>::zeros(dim, nq);
    type Partial = (usize, Vec<[(DMatrix<f64>, DMatrix<f64>); 3]>);
    let mut partials: Vec<Partial> = Vec::new();
    for (i, sr) in rods.iter().enumerate() {
        for (k, &(sec, step, _)) in nodes[i].iter().enumerate() {
            let (end, intervals) = load_pass::<12>(
                &level.problems[i],
                sr.rod,
                &x[6 * i..6 * i + 6],
                (sec, step),
            );
            let (rows, f, m) = level.rod_terms(i, &end, &pd, &rd);
            let balance = level.balance_rows(&f, &m);
            for j in 0..6 {
                let mut rhs = DVector::zeros(dim);
                for r in 0..6 {
                    rhs[6 * i + r] = -rows[r].eps[6 + j];
                    rhs[6 * n + r] = -balance[r].eps[6 + j];
                }
                let dx = solve_tangent(&lu, &rhs, singular)?;
                dxs.set_column(offsets[i] + 6 * k + j, &dx);
            }
            partials.push((
                i,
                intervals
                    .iter()
                    .map(|iv| ends(iv).map(|(st, sn)| end_derivatives(st, sn, 6..12)))
                    .collect(),
            ));
        }
    }
    for j in 0..6 {
        let unit = |c: usize| -> [f64; 3] { std::array::from_fn(|r| f64::from(r == c)) };
        let rows = if j < 3 {
            level.balance_rows(&unit(j), &[0.0; 3])
        } else {
            level.balance_rows(&[0.0; 3], &unit(j - 3))
        };
        let mut rhs = DVector::zeros(dim);
        for r in 0..6 {
            rhs[6 * n + r] = -rows[r];
        }
        let dx = solve_tangent(&lu, &rhs, singular)?;
        dxs.set_column(platform_at + j, &dx);
    }

    // Total derivatives: every rod's intervals (phi, psi: [interval][end] (6, nq)), the
    // flexibility C (node poses and the platform's pose, per load coordinate).
    let mut flex = DMatrix::<f64>::zeros(nq, nq);
    let mut gm = DMatrix::<f64>::zeros(nq, nq);
    let mut gd = DMatrix::<f64>::zeros(nq, nq);
    for (i, sr) in rods.iter().enumerate() {
        let sh = &shapes[i];
        let dx_i = dxs.rows(6 * i, 6).into_owned();
        let mut phi: Vec<[DMatrix<f64>; 3]> = Vec::with_capacity(sh.meta.len());
        let mut psi: Vec<[DMatrix<f64>; 3]> = Vec::with_capacity(sh.meta.len());
        for m in 0..sh.meta.len() {
            phi.push(std::array::from_fn(|e| &sh.pose_x[m][e] * &dx_i));
            psi.push(std::array::from_fn(|e| &sh.strain_x[m][e] * &dx_i));
        }
        // The point loads on this rod's own nodes add their partials.
        for (k, (_, own)) in partials.iter().filter(|(r, _)| *r == i).enumerate() {
            let col = offsets[i] + 6 * k;
            for (m, per_end) in own.iter().enumerate() {
                for (e, (p, s)) in per_end.iter().enumerate() {
                    let mut pc = phi[m][e].columns_mut(col, 6);
                    pc += p;
                    let mut sc = psi[m][e].columns_mut(col, 6);
                    sc += s;
                }
            }
        }
        for (k, &m) in sh.at_node.iter().enumerate() {
            flex.rows_mut(offsets[i] + 6 * k, 6).copy_from(&phi[m][2]);
        }
        let (a, d) = interval_gram(sr.rod, &level.problems[i], &sh.meta, &phi, &psi, nq);
        gm += a;
        gd += d;
    }
    for c in 0..nq {
        for r in 0..3 {
            flex[(platform_at + r, c)] = dxs[(6 * n + r, c)] * level.ls;
            flex[(platform_at + 3 + r, c)] = dxs[(6 * n + 3 + r, c)];
        }
    }
    let stiffness = flex.try_inverse().ok_or_else(singular)?;
    let kt = stiffness.transpose();
    let sym = |a: DMatrix<f64>| (&a + a.transpose()) * 0.5;
    let mut mass = sym(&kt * gm * &stiffness);
    let damping = sym(&kt * gd * &stiffness);
    // The rigid bodies on the platform, about its origin: the platform itself and every
    // rod's tip body (its tip is clamped to the platform).
    let rot = Matrix3::from_fn(|a, b| r0[a][b]);
    let com = rot * nalgebra::Vector3::from(platform.com_offset);
    let jw = rot * Matrix3::from_fn(|a, b| platform_inertia[a][b]) * rot.transpose();
    let mut bodies = rigid_block(platform.mass, &[com[0], com[1], com[2]], &jw);
    for (sr, sh) in rods.iter().zip(&shapes) {
        let lever = std::array::from_fn(|k| sh.tip.0[k] - p0[k]);
        bodies += tip_body_block(sr.rod, &sh.tip.1, lever);
    }
    let mut corner = mass.view_mut((platform_at, platform_at), (6, 6));
    corner += &bodies;

    let response = input_columns(
        rods, &level, x, &nodes, &shapes, &offsets, inputs, &lu, singular,
    )?;
    let mut input = &stiffness * response;
    // A platform load's generalised load is exactly its unit column (K dq/du gives it to
    // round-off).
    for (k, a) in inputs.iter().enumerate() {
        let row = match *a {
            SystemInput::PlatformForce(j) => platform_at + j,
            SystemInput::PlatformMoment(j) => platform_at + 3 + j,
            _ => continue,
        };
        input.column_mut(k).fill(0.0);
        input[(row, k)] = 1.0;
    }
    Ok(SystemLinear {
        nodes: nodes
            .iter()
            .map(|v| v.iter().map(|n| n.2).collect())
            .collect(),
        mass,
        damping,
        stiffness,
        input,
    })
}

/// The static response dq/du of the coordinates to each input (B = K dq/du: the input's
/// generalised load): the input's own change of its rod's node poses
/// (`jacobian::system::input_residuals`), plus every rod's shape change through its base
/// unknowns and the platform's pose, by the implicit function theorem.
#[allow(clippy::too_many_arguments)]
fn input_columns(
    rods: &[SystemRod],
    level: &Level,
    x: &[f64],
    nodes: &[Vec<(usize, usize, f64)>],
    shapes: &[RodShapes],
    offsets: &[usize],
    inputs: &[SystemInput],
    lu: &LU<f64, Dyn, Dyn>,
    singular: impl Fn() -> SoftrodError + Copy,
) -> Result<DMatrix<f64>> {
    let n = rods.len();
    let nq = offsets[n - 1] + 6 * nodes[n - 1].len() + 6;
    let (d_res, own) = input_residuals(rods, level, x, inputs, nodes);
    let mut dq = DMatrix::<f64>::zeros(nq, inputs.len());
    for (k, a) in inputs.iter().enumerate() {
        if let Some((i, _)) = a.on_rod() {
            for (m, p) in own[k].iter().enumerate() {
                for r in 0..6 {
                    dq[(offsets[i] + 6 * m + r, k)] = p[r];
                }
            }
        }
        let dx = solve_tangent(lu, &(-d_res.column(k).into_owned()), singular)?;
        for (i, sh) in shapes.iter().enumerate() {
            let dx_i = dx.rows(6 * i, 6);
            for (m, &iv) in sh.at_node.iter().enumerate() {
                let d = &sh.pose_x[iv][2] * dx_i;
                for r in 0..6 {
                    dq[(offsets[i] + 6 * m + r, k)] += d[r];
                }
            }
        }
        let o = nq - 6;
        for r in 0..3 {
            dq[(o + r, k)] = dx[6 * n + r] * level.ls;
            dq[(o + 3 + r, k)] = dx[6 * n + 3 + r];
        }
    }
    Ok(dq)
}
