//! [`super::pose_sensitivity`] of an equilibrium that collocation solved (a long, soft rod):
//! the implicit function theorem on its collocation equations
//! (`crate::statics::collocation::implicit`), the parameters seeded in the sections'
//! coefficients ([`super::seeded_coeffs`]). The tip and the markers are read as the
//! solution's values are: their node's state, then the section's law over the partial step
//! ([`super::advance_from_node`]), so each derivative is that of the value reported.

use super::{advance_from_node, marker_position, seeded_coeffs, MarkerAt, Param, TipSensitivity};
use crate::error::Result;
use crate::jet::Jet;
use crate::ode::Loads;
use crate::rod::Rod;
use crate::statics::collocation::implicit::Implicit;
use crate::statics::Solution;

/// Parameters carried by one dual evaluation (more: several).
const DIRS: usize = 4;
type Dual = Jet<DIRS>;

/// The tip pose's and the markers' derivatives with respect to the (validated) parameters
/// at the collocation solution `sol` of `loads`.
pub(crate) fn pose_sensitivity(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    params: &[Param],
    markers: &[MarkerAt],
) -> Result<TipSensitivity> {
    let imp = Implicit::of(rod, loads, sol)?;
    let tip = MarkerAt::tip(rod);
    let mut out = TipSensitivity {
        position: Vec::with_capacity(params.len()),
        rotation: Vec::with_capacity(params.len()),
        markers: Vec::with_capacity(params.len()),
        reaction_force: vec![],
        reaction_moment: vec![],
    };
    for chunk in params.chunks(DIRS) {
        let (coeffs, _) = seeded_coeffs::<DIRS>(rod, loads, chunk);
        let d = imp.solve(&coeffs, &[], chunk.len(), sol)?;
        let y = advance_from_node(rod, &coeffs, imp.node_state(&d, tip.node), &tip);
        let marks: Vec<[Dual; 3]> = markers
            .iter()
            .map(|mk| {
                let y = advance_from_node(rod, &coeffs, imp.node_state(&d, mk.node), mk);
                marker_position(&y, &mk.offset)
            })
            .collect();
        for q in 0..chunk.len() {
            out.position.push(y.r.map(|v| v.eps[q]));
            out.rotation.push(y.rot.map(|row| row.map(|v| v.eps[q])));
            out.markers
                .push(marks.iter().map(|m| m.map(|v| v.eps[q])).collect());
        }
    }
    Ok(out)
}
