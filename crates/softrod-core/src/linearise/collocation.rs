//! The linearisation's static responses ([`Responses`]) of an equilibrium that collocation
//! solved (a long, soft rod whose single shooting is ill-conditioned: docs/model.md,
//! "Collocation"), from the collocation equations themselves rather than shooting passes
//! (which would leave such an equilibrium): the implicit function theorem on G(z, a) = 0
//! (`crate::statics::collocation::implicit`) with a point force and moment at a node as
//! the directions a. A point load at interior node j is a jump of the internal force and
//! moment there (n(s_j+) = n(s_j-) - F, m likewise), so it enters the equations of the
//! interval that starts at j, whose start value becomes Y_j - (0, F, M): d G / d F is
//! +1 per unit in the scaled n rows of its two stage equations and its node equation. At
//! the tip it enters the tip's balance (-1/F_s, -1/M_s), as a tip load does. Each interval
//! then records what the shooting pass records ([`Interval`]): its start (right limit,
//! after the jump), its midpoint (half a step of the section's law from the start, as
//! markers are read) and its end (left limit), with their strains.

use super::{strain6, Interval, Layout, Responses};
use crate::collocation::{IM, IN};
use crate::error::Result;
use crate::jacobian::{dual_coeffs_from, pose_derivative};
use crate::jet::Jet;
use crate::ode::{advance, resolve_stretch, Loads, NodeAt};
use crate::rod::Rod;
use crate::statics::collocation::implicit::Implicit;
use crate::statics::{Problem, Solution};
use nalgebra::DMatrix;

/// Directions of one node's load: force x, y, z, then moment x, y, z.
type Load = Jet<6>;

/// The index of integration node (section, step) among the grid's nodes (0: the base).
fn grid_node(rod: &Rod, section: usize, step: usize) -> usize {
    rod.sections[..section]
        .iter()
        .map(|s| s.steps)
        .sum::<usize>()
        + step
}

/// [`Responses`] of the collocation solution `sol` with nodes `nodes` (a free tip under
/// dead loads: the only equilibria collocation solves).
pub(super) fn responses(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
) -> Result<Responses> {
    let imp = Implicit::of(rod, loads, sol)?;
    let p = imp.problem();
    let n_int = imp.grid.len();
    let nq = layout.size;
    // The sections' coefficients: f64 for the laws read at the recorded points, lifted to
    // dual numbers (no direction seeded) for the equations.
    let coeffs = Problem::new(rod, loads, 1.0).coeffs;
    let lifted = dual_coeffs_from::<6>(rod, loads, &[], 0);
    let mut flex = DMatrix::<f64>::zeros(nq, nq);
    let mut meta = Vec::new();
    let (mut phi, mut psi) = super::zero_fields(n_int, nq);
    // The first interval of each section (a node's step within its section).
    let first: Vec<usize> = (0..rod.sections.len())
        .map(|i| grid_node(rod, i, 0))
        .collect();
    for (k, &(sec, step, _)) in nodes.iter().enumerate() {
        let at = grid_node(rod, sec, step);
        let terms: Vec<(usize, usize, f64)> = if at == n_int {
            (0..3)
                .flat_map(|c| {
                    [
                        (p.tip_rows() + c, c, -1.0 / p.fs),
                        (p.tip_rows() + 3 + c, 3 + c, -1.0 / p.ms),
                    ]
                })
                .collect()
        } else {
            // The interval starting at the node: its two stage equations and its node
            // equation (48 scaled rows per interval, 16 each).
            (0..3)
                .flat_map(|block| {
                    (0..3).flat_map(move |c| {
                        let o = 48 * at + 16 * block;
                        [
                            (o + IN + c, c, 1.0 / p.scale[IN + c]),
                            (o + IM + c, 3 + c, 1.0 / p.scale[IM + c]),
                        ]
                    })
                })
                .collect()
        };
        let d = imp.solve::<6>(&lifted, &terms, 6, sol)?;
        let mut intervals: Vec<Interval<Load>> = Vec::with_capacity(n_int);
        for (j, iv) in imp.grid.intervals.iter().enumerate() {
            let i = iv.section;
            let section = &rod.sections[i];
            let c = &coeffs[i];
            let (a, b) = (imp.grid.node_s(j), imp.grid.node_s(j + 1));
            let local = |s: f64| s - section.s_start;
            let mut start = imp.node_state(&d, j);
            if j == at {
                for r in 0..3 {
                    start.n[r].eps[r] -= 1.0;
                    start.m[r].eps[3 + r] -= 1.0;
                }
            }
            resolve_stretch(&mut start, c);
            let node = NodeAt {
                section: i,
                step: j - first[i],
                s: a,
            };
            let mid = advance(rod, &coeffs, node, &start, 0.5 * iv.h);
            let mut end = imp.node_state(&d, j + 1);
            resolve_stretch(&mut end, c);
            intervals.push(Interval {
                section: i,
                a,
                b,
                strain_a: strain6(section, &start, c, local(a)),
                strain_m: strain6(section, &mid, c, local(a) + 0.5 * iv.h),
                strain_b: strain6(section, &end, c, local(b)),
                start,
                mid,
                end,
            });
        }
        if k == 0 {
            meta = intervals.iter().map(Interval::meta).collect();
        }
        for (m, iv) in intervals.iter().enumerate() {
            for (e, (st, sn)) in iv.ends().iter().enumerate() {
                let dpose: [[f64; 6]; 6] = std::array::from_fn(|dir| pose_derivative(st, dir));
                let dstrain: [[f64; 6]; 6] =
                    std::array::from_fn(|dir| std::array::from_fn(|r| sn[r].eps[dir]));
                super::record(layout, k, &dpose, &dstrain, &mut phi[m][e], &mut psi[m][e]);
            }
        }
        super::fill_flexibility(rod, nodes, layout, k, &meta, &phi, &mut flex);
    }
    let dq = input_response(rod, loads, sol, &imp, nodes, layout)?;
    Ok(Responses {
        flex,
        meta,
        phi,
        psi,
        dq,
    })
}

/// The coordinates' derivatives with respect to the pressures, tensions and factors sigma
/// (`super::Inputs`): the implicit function theorem with those inputs seeded in the
/// coefficients; the node poses (no point load acts) read from the dual unknowns.
fn input_response(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    imp: &Implicit,
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
) -> Result<DMatrix<f64>> {
    let inputs = super::Inputs::of(rod);
    let mut dq = DMatrix::<f64>::zeros(layout.size, inputs.len());
    for chunk in (0..inputs.len()).collect::<Vec<_>>().chunks(6) {
        let seeded: Vec<_> = chunk.iter().map(|&u| inputs.input(u)).collect();
        let coeffs = dual_coeffs_from::<6>(rod, loads, &seeded, 0);
        let d = imp.solve::<6>(&coeffs, &[], chunk.len(), sol)?;
        for (a, &(sec, step, _)) in nodes.iter().enumerate() {
            let st = imp.node_state(&d, grid_node(rod, sec, step));
            for (q, &c) in chunk.iter().enumerate() {
                let pose = pose_derivative(&st, q);
                for (_, r, row) in layout.coordinates().filter(|x| x.0 == a) {
                    dq[(row, c)] = pose[r];
                }
            }
        }
    }
    Ok(dq)
}
