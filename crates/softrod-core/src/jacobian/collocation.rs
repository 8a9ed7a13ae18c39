//! [`super::point_jacobian`] of an equilibrium that collocation solved (a long, soft rod):
//! the implicit function theorem on its collocation equations
//! (`crate::statics::collocation::implicit`), the inputs seeded in the sections'
//! coefficients (pressures, tensions, stiffness factors) or in the tip's balance rows (the
//! tip force and moment). The point is read as the solution's values are: its node's state,
//! then the section's law over the partial step (`crate::sensitivity::advance_from_node`),
//! so the derivative is that of the value the solution reports.

use super::{dual_coeffs_from, small_rotation, Input, PointJacobian, Probe};
use crate::error::{Result, SoftrodError};
use crate::ode::{Loads, State};
use crate::rod::Rod;
use crate::sensitivity::advance_from_node;
use crate::statics::collocation::implicit::Implicit;
use crate::statics::Solution;

/// Inputs carried by one dual evaluation (more: several).
const DIRS: usize = 4;

/// The point Jacobian of the collocation solution `sol` of `loads`.
pub(crate) fn point_jacobian(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    inputs: &[Input],
    probe: &Probe,
) -> Result<PointJacobian> {
    point_state_jacobian(rod, loads, sol, inputs, probe).map(|(_, j)| j)
}

/// [`point_jacobian`] and the point's state (pose, internal force and moment).
pub(crate) fn point_state_jacobian(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    inputs: &[Input],
    probe: &Probe,
) -> Result<(State<f64>, PointJacobian)> {
    let imp = Implicit::of(rod, loads, sol)?;
    let mk = probe.on_centreline(rod);
    let (fs, ms, rows) = {
        let p = imp.problem();
        (p.fs, p.ms, p.tip_rows())
    };
    let mut out = PointJacobian {
        position: [0.0; 3],
        rotation: [[0.0; 3]; 3],
        d_position: Vec::with_capacity(inputs.len()),
        d_rotation: Vec::with_capacity(inputs.len()),
    };
    let mut state = None;
    // One evaluation even without inputs: it gives the point's value.
    let chunks: Vec<&[Input]> = if inputs.is_empty() {
        vec![&[]]
    } else {
        inputs.chunks(DIRS).collect()
    };
    for chunk in chunks {
        let coeffs = dual_coeffs_from::<DIRS>(rod, loads, chunk, 0);
        let tip: Vec<(usize, usize, f64)> = chunk
            .iter()
            .enumerate()
            .filter_map(|(q, a)| match a {
                // Tip rows: (n(L) - ... - F) / F_s, then (m(L) - ... - M) / M_s.
                Input::TipForce(j) => Some((rows + *j, q, -1.0 / fs)),
                Input::TipMoment(j) => Some((rows + 3 + *j, q, -1.0 / ms)),
                _ => None,
            })
            .collect();
        let d = imp.solve(&coeffs, &tip, chunk.len(), sol)?;
        let y = advance_from_node(rod, &coeffs, imp.node_state(&d, mk.node), &mk);
        state = Some(State {
            r: y.r.map(|v| v.re),
            rot: y.rot.map(|row| row.map(|v| v.re)),
            n: y.n.map(|v| v.re),
            m: y.m.map(|v| v.re),
            aux: y.aux.map(|v| v.re),
        });
        out.position = y.r.map(|v| v.re);
        out.rotation = y.rot.map(|row| row.map(|v| v.re));
        for q in 0..chunk.len() {
            out.d_position.push(y.r.map(|v| v.eps[q]));
            let d_rot = y.rot.map(|row| row.map(|v| v.eps[q]));
            out.d_rotation.push(small_rotation(&out.rotation, &d_rot));
        }
    }
    let state = state.ok_or_else(|| SoftrodError::Internal("no evaluation of the point".into()))?;
    Ok((state, out))
}
