//! Which features of a design each model carries (docs/scope.md): the refusals that name
//! the field of a feature a model does not carry, shared by the solvers (statics, dynamics,
//! the Jacobians, the inverse, the linearisation, the PCC model), so that none of them has
//! to reach into another for them.

use crate::error::{Result, SoftrodError};
use crate::ode::Loads;
use crate::rod::Rod;

/// Refuse the statics-only features of a design (follower loads, reference shapes, tapered
/// sections, tendons): `model` (the linearisation, the PCC model) does not carry them yet.
pub(crate) fn check_statics_only(rod: &Rod, model: &str) -> Result<()> {
    if !rod.spec.obstacles.is_empty() {
        return Err(SoftrodError::invalid(
            "obstacles",
            "contact with obstacles",
            format!("is not supported by {model} yet; the Cosserat statics (solve_statics) and dynamics (simulate) support it"),
        ));
    }
    check_statics_only_with(rod, model, false, false)
}

/// [`check_statics_only`]; with `collocation` what the collocation discretisation carries
/// is accepted: tapered sections, and reference shapes (constant or tabulated along s;
/// the laws act on the strains relative to them, evaluated at every stage point:
/// `crate::collocation::Grid`); with `tendons_and_followers` tendons and
/// follower (body-frame) tip and line loads are accepted (`crate::collocation`).
pub(crate) fn check_statics_only_with(
    rod: &Rod,
    model: &str,
    collocation: bool,
    tendons_and_followers: bool,
) -> Result<()> {
    // Statics-only features of issue 17 (dynamics follows on the collocation engine).
    let statics_only = |field: String, what: &str| {
        SoftrodError::invalid(
            field,
            what,
            format!(
                "is not supported by {model} yet; the Cosserat statics (solve_statics) supports it"
            ),
        )
    };
    if rod.spec.tip.frame == crate::spec::Frame::Body && !tendons_and_followers {
        return Err(statics_only(
            "tip.frame".into(),
            "a follower (body-frame) tip load",
        ));
    }
    if let Some(k) = rod
        .spec
        .loads
        .iter()
        .position(|l| l.frame == crate::spec::Frame::Body)
        .filter(|_| !tendons_and_followers)
    {
        return Err(statics_only(
            format!("loads[{k}].frame"),
            "a follower line load",
        ));
    }
    for (i, s) in rod.sections.iter().enumerate() {
        if !s.reference.is_straight() && !collocation {
            return Err(statics_only(
                format!("sections[{i}].reference"),
                "a reference shape (precurvature or pre-strain)",
            ));
        }
        if s.tapered && !collocation {
            return Err(statics_only(
                format!("sections[{i}].outer_radius_end"),
                "a tapered section",
            ));
        }
        if !s.tendons.is_empty() && !tendons_and_followers {
            return Err(statics_only(format!("sections[{i}].tendons"), "tendons"));
        }
    }
    Ok(())
}

/// Refuse follower (body-frame) tip or line loads: `what` supports dead loads only (3
/// shooting unknowns, the base moment; with follower loads the base force is unknown too
/// and the loads are not conservative).
pub(crate) fn dead_loads_only(rod: &Rod, loads: &Loads, what: &str) -> Result<()> {
    refuse_obstacles(rod, what)?;
    if loads.has_follower(rod) {
        let (field, value) = if rod.spec.has_follower_line_loads() {
            let k = rod
                .spec
                .loads
                .iter()
                .position(|l| l.frame == crate::spec::Frame::Body)
                .unwrap_or(0);
            (format!("loads[{k}].frame"), "body")
        } else {
            ("tip.frame".to_string(), "body")
        };
        return Err(SoftrodError::invalid(
            field,
            value,
            format!("{what} supports dead (world-frame) loads only; follower loads are not supported there yet"),
        ));
    }
    Ok(())
}

/// Refuse a rod with obstacles in `what`, whose equations do not carry contact yet (its
/// penetration rule and contact report live in the statics, free or held tip).
pub(crate) fn refuse_obstacles(rod: &Rod, what: &str) -> Result<()> {
    if rod.obstacles.is_some() {
        return Err(SoftrodError::invalid(
            "obstacles",
            format!("{} obstacles", rod.spec.obstacles.len()),
            format!("{what} does not support contact yet; solve_statics (free, pinned or clamped tip) does"),
        ));
    }
    Ok(())
}
