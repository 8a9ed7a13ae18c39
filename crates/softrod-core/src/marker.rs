//! Motion-capture markers: points on the body given by their reference arc length and an
//! offset in the cross-section frame (paper 000 Sec. III-D records such markers). Shared by
//! the statics' sensitivities (`crate::sensitivity`, which locates them on the shooting
//! grid) and the dynamics (`crate::dynamics`, `crate::collocation`, which read them on the
//! collocation's intervals).

use crate::error::{Result, SoftrodError};
use crate::rod::Rod;

/// A point on the body whose position is measured (a motion-capture marker): reference arc
/// length `s` in [0, L] and an offset in the cross-section frame (d1, d2, d3) at s, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    pub s: f64,
    pub offset: [f64; 3],
}

/// A marker closer than this fraction of a step to a node is read at that node (so a
/// marker at s = L is read exactly at the tip).
pub(crate) const NODE_SNAP: f64 = 1e-9;

/// Check the markers against the rod: an arc length in [0, L] and a finite offset. Errors
/// name `markers[k]`.
pub fn check_markers(rod: &Rod, markers: &[Marker]) -> Result<()> {
    for (k, mk) in markers.iter().enumerate() {
        if !(mk.s.is_finite() && mk.s >= 0.0 && mk.s <= rod.length * (1.0 + 1e-12)) {
            return Err(SoftrodError::invalid(
                format!("markers[{k}].s"),
                mk.s,
                format!(
                    "a marker's arc length must lie in [0, L] = [0, {}] m",
                    rod.length
                ),
            ));
        }
        if let Some(bad) = mk.offset.iter().find(|v| !v.is_finite()) {
            return Err(SoftrodError::invalid(
                format!("markers[{k}].offset"),
                bad,
                "must be finite (m, cross-section frame)",
            ));
        }
    }
    Ok(())
}
