//! Exact parameter derivatives of a system's static equilibrium (rods whose tips hold one
//! platform, `crate::statics::system`): the platform's pose and marker points on the
//! platform or on any rod, for calibrating parallel continuum robots from what a
//! motion-capture system sees.
//!
//! The implicit differentiation of the lone rod (`crate::sensitivity`) on the system's
//! residual: at the converged unknowns x (6 per rod, then the platform's 6) R(x, theta)
//! vanishes, so dx/dtheta = -J^-1 d_theta R with J the exact Jacobian Newton uses
//! (`Level::jacobian`). d_theta R costs one dual integration per rod that a chunk of
//! CHUNK parameters acts on (its coefficients built from dual-valued knobs, as for a lone
//! rod), its tip rows and its share of the platform balance formed from the dual tip at
//! the fixed platform pose; the platform's mass enters the balance through its weight.
//! Outputs: the platform position p and rotation R_p (dR_p = [dpsi]x R_p, psi the
//! Jacobian's own rotation increment of the platform), a platform marker p + R_p o, and a
//! rod marker r_i(s) + R_i(s) o (its d_x from one `Jet<6>` integration of rod i).
//!
//! A frictional equilibrium is refused: it depends on its load path, not on the point
//! alone, so the implicit function theorem at that point does not give its derivatives.

use super::{
    check_params, integrate_markers, locate_markers, marker_position, seeded_in, Dual, MarkerAt,
    Param, CHUNK,
};
use crate::error::{Result, SoftrodError};
use crate::jet::Jet;
use crate::marker::Marker;
use crate::ode::Coeffs;
use crate::statics::system::{Platform, SystemRod, SystemSolution};
use crate::statics::tangent::{singular_jacobian, solve_tangent, system_tangent, system_unknowns};
use crate::statics::Problem;
use nalgebra::DVector;

/// One calibration parameter of a system.
#[derive(Debug, Clone, PartialEq)]
pub enum SystemParam {
    /// One value acting on several rods: each entry is a rod's index and the parameter in
    /// that rod's design (the same kind in every entry; the sections are the rod's own).
    Rods(Vec<(usize, Param)>),
    /// The platform's mass, kg.
    PlatformMass,
}

/// A marker of a system: a point fixed to the platform (offset in the platform frame, m)
/// or a point on a rod (`crate::marker::Marker` of rod `rod`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SystemMarker {
    Platform([f64; 3]),
    Rod { rod: usize, marker: Marker },
}

/// A [`SystemMarker`] located on its rod's integration grid ([`locate_system_markers`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SystemMarkerAt {
    Platform([f64; 3]),
    Rod(usize, MarkerAt),
}

/// Derivatives of the platform's pose and of the markers with respect to each parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct SystemSensitivity {
    /// d p / d theta_j (world frame), one per parameter.
    pub platform_position: Vec<[f64; 3]>,
    /// d R_p / d theta_j, one per parameter.
    pub platform_rotation: Vec<[[f64; 3]; 3]>,
    /// d marker_k / d theta_j (world frame): `markers[j][k]`.
    pub markers: Vec<Vec<[f64; 3]>>,
}

/// Check a system's parameters: every rod entry known and checked as the lone rod's
/// parameter is (`check_params`), one kind and one value per parameter, no rod twice.
/// Errors name `params[j]` (and the rod).
pub fn validate_system_params(rods: &[SystemRod], params: &[SystemParam]) -> Result<()> {
    check_system_params(
        rods.len(),
        params,
        |i, p| check_params(rods[i].rod, std::slice::from_ref(p)),
        |i, p| p.value(rods[i].rod, &rods[i].loads),
    )
}

/// The rules every system's parameters follow, in statics and in motion: each rod entry
/// names one of the `n_rods` rods once, one kind and (`value`) one value per parameter, and
/// each entry passes `check` (its rod's own rules: the statics' or the dynamics'). Errors
/// name `params[j]` and the rod.
pub(crate) fn check_system_params(
    n_rods: usize,
    params: &[SystemParam],
    check: impl Fn(usize, &Param) -> Result<()>,
    value: impl Fn(usize, &Param) -> f64,
) -> Result<()> {
    for (j, p) in params.iter().enumerate() {
        let SystemParam::Rods(entries) = p else {
            continue;
        };
        let field = format!("params[{j}]");
        let Some((_, first)) = entries.first() else {
            return Err(SoftrodError::invalid(
                field,
                "no rods",
                "name at least one rod the parameter acts on",
            ));
        };
        let mut seen: Option<(usize, f64)> = None;
        for (e, (i, param)) in entries.iter().enumerate() {
            if *i >= n_rods {
                return Err(SoftrodError::invalid(
                    format!("{field}.rods[{e}]"),
                    format!("rod {i}"),
                    format!("the system has {n_rods} rods"),
                ));
            }
            if entries[..e].iter().any(|(k, _)| k == i) {
                return Err(SoftrodError::invalid(
                    format!("{field}.rods[{e}]"),
                    format!("rod {i}"),
                    "names a rod twice: list each rod once with all its sections",
                ));
            }
            if param.kind != first.kind {
                return Err(SoftrodError::invalid(
                    format!("{field}.rods[{e}]"),
                    param.kind.name(),
                    format!(
                        "one parameter has one kind: the first entry is {}",
                        first.kind.name()
                    ),
                ));
            }
            let named = format!("{field} ({}) of rods[{i}]", param.kind.name());
            check(*i, param).map_err(|err| match err {
                SoftrodError::InvalidParameter { value, rule, .. } => {
                    SoftrodError::InvalidParameter {
                        field: named.clone(),
                        value,
                        rule,
                    }
                }
                other => other,
            })?;
            let v = value(*i, param);
            match seen {
                None => seen = Some((*i, v)),
                Some((k, v0)) if v != v0 => {
                    return Err(SoftrodError::invalid(
                        named,
                        v,
                        format!(
                            "one parameter needs one value: rods[{k}] has {v0}; calibrate them as separate parameters"
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// Check the markers against the system (rods known, each rod marker on its rod, offsets
/// finite) and locate them. Errors name `markers[k]`.
pub fn locate_system_markers(
    rods: &[SystemRod],
    markers: &[SystemMarker],
) -> Result<Vec<SystemMarkerAt>> {
    markers
        .iter()
        .enumerate()
        .map(|(k, mk)| match *mk {
            SystemMarker::Platform(o) => {
                if o.iter().all(|v| v.is_finite()) {
                    Ok(SystemMarkerAt::Platform(o))
                } else {
                    Err(SoftrodError::invalid(
                        format!("markers[{k}].offset"),
                        format!("{o:?}"),
                        "must be finite (m, platform frame)",
                    ))
                }
            }
            SystemMarker::Rod { rod, marker } => {
                let Some(sr) = rods.get(rod) else {
                    return Err(SoftrodError::invalid(
                        format!("markers[{k}].rod"),
                        rod,
                        format!("the system has {} rods", rods.len()),
                    ));
                };
                let at = locate_markers(sr.rod, &[marker]).map_err(|err| match err {
                    SoftrodError::InvalidParameter { field, value, rule } => {
                        SoftrodError::InvalidParameter {
                            field: field.replacen("markers[0]", &format!("markers[{k}]"), 1),
                            value,
                            rule: format!("{rule} (on rods[{rod}])"),
                        }
                    }
                    other => other,
                })?;
                Ok(SystemMarkerAt::Rod(rod, at[0]))
            }
        })
        .collect()
}

/// The rods' markers of `markers`, rod by rod: (index in `markers`, its place).
fn rod_markers(n: usize, markers: &[SystemMarkerAt]) -> Vec<(Vec<usize>, Vec<MarkerAt>)> {
    let mut out = vec![(vec![], vec![]); n];
    for (k, mk) in markers.iter().enumerate() {
        if let SystemMarkerAt::Rod(i, at) = mk {
            out[*i].0.push(k);
            out[*i].1.push(*at);
        }
    }
    out
}

/// Positions of the markers of a converged system (world frame, m).
pub fn system_marker_positions(
    rods: &[SystemRod],
    sol: &SystemSolution,
    markers: &[SystemMarkerAt],
) -> Result<Vec<[f64; 3]>> {
    let x = system_unknowns(rods, sol)?;
    let (p, rp) = (sol.platform_position, sol.platform_rotation);
    let mut out = vec![[f64::NAN; 3]; markers.len()];
    for (k, mk) in markers.iter().enumerate() {
        if let SystemMarkerAt::Platform(o) = mk {
            out[k] = std::array::from_fn(|i| p[i] + (0..3).map(|c| rp[i][c] * o[c]).sum::<f64>());
        }
    }
    for (i, (idx, at)) in rod_markers(rods.len(), markers).iter().enumerate() {
        if idx.is_empty() {
            continue;
        }
        let sr = &rods[i];
        let pr = Problem::new(sr.rod, &sr.loads, 1.0);
        let (_, states) =
            integrate_markers(sr.rod, &pr.coeffs, pr.base_state(&x[6 * i..6 * i + 6]), at);
        for ((k, y), a) in idx.iter().zip(&states).zip(at) {
            out[*k] = marker_position(y, &a.offset);
        }
    }
    Ok(out)
}

/// Derivatives of the platform's pose and of the markers (located by
/// [`locate_system_markers`]) at the converged frictionless system `sol` (the parameters
/// must have been validated with [`validate_system_params`]).
pub fn system_sensitivity(
    rods: &[SystemRod],
    platform: &Platform,
    sol: &SystemSolution,
    params: &[SystemParam],
    markers: &[SystemMarkerAt],
) -> Result<SystemSensitivity> {
    let (level, x, lu) = system_tangent(
        rods,
        platform,
        sol,
        "not on the parameters at one point: its derivatives are not defined here (calibrate on frictionless obstacles)",
    )?;
    let n = rods.len();
    let dim = 6 * n + 6;
    let (p0, r0) = level.platform(x);
    let per_rod = rod_markers(n, markers);
    // d_x of each rod marker: rod i integrated with its own unknowns seeded.
    let marks_x: Vec<Vec<[Jet<6>; 3]>> = per_rod
        .iter()
        .enumerate()
        .map(|(i, (idx, at))| {
            if idx.is_empty() {
                return vec![];
            }
            let pr = &level.problems[i];
            let xd: [Jet<6>; 6] = std::array::from_fn(|j| Jet::variable(x[6 * i + j], j));
            let (_, states) = integrate_markers(rods[i].rod, &pr.coeffs, pr.base_state(&xd), at);
            states
                .iter()
                .zip(at)
                .map(|(y, a)| marker_position(y, &a.offset))
                .collect()
        })
        .collect();
    let mut out = SystemSensitivity {
        platform_position: Vec::with_capacity(params.len()),
        platform_rotation: Vec::with_capacity(params.len()),
        markers: Vec::with_capacity(params.len()),
    };
    let pd = p0.map(Dual::from);
    let rd = r0.map(|row| row.map(Dual::from));
    for chunk in params.chunks(CHUNK) {
        let mut dres = vec![Dual::from(0.0); dim];
        // The platform's weight, its mass seeded where it is a parameter.
        let mut mass = Dual::from(platform.mass);
        for (q, p) in chunk.iter().enumerate() {
            if let SystemParam::PlatformMass = p {
                mass.eps[q] = 1.0;
            }
        }
        let (mut f, mut m) = level.platform_terms_weighing(&rd, platform.gravity.map(|g| mass * g));
        // Per rod: d_theta of its markers (None: no parameter of the chunk acts on it).
        let mut marks_t: Vec<Option<Vec<[Dual; 3]>>> = vec![None; n];
        for (i, sr) in rods.iter().enumerate() {
            let dirs: Vec<(usize, &Param)> = chunk
                .iter()
                .enumerate()
                .filter_map(|(q, p)| match p {
                    SystemParam::Rods(e) => e.iter().find(|(r, _)| *r == i).map(|(_, p)| (q, p)),
                    SystemParam::PlatformMass => None,
                })
                .collect();
            if dirs.is_empty() {
                continue; // its rows and its wrench on the platform do not move
            }
            let (knobs, sigma) = seeded_in::<CHUNK>(sr.rod, &sr.loads.stiffness_scale, dirs);
            let coeffs: Vec<Coeffs<Dual>> = (0..sr.rod.sections.len())
                .map(|s| {
                    Coeffs::build_with(
                        sr.rod,
                        s,
                        &sr.loads.pressures,
                        &sr.loads.tensions,
                        &sr.rod.gravity,
                        Dual::from(1.0),
                        &sigma,
                        &knobs[s],
                    )
                })
                .collect();
            let pr = &level.problems[i];
            let xi: Vec<Dual> = x[6 * i..6 * i + 6].iter().map(|v| Dual::from(*v)).collect();
            // With 6 unknowns the base force is an unknown itself: no weight to carry.
            let (tip, states) =
                integrate_markers(sr.rod, &coeffs, pr.base_state(&xi), &per_rod[i].1);
            let (rows, fi, mi) = level.rod_terms(i, &tip, &pd, &rd);
            dres[6 * i..6 * i + 6].copy_from_slice(&rows);
            for k in 0..3 {
                f[k] += fi[k];
                m[k] += mi[k];
            }
            marks_t[i] = Some(
                states
                    .iter()
                    .zip(&per_rod[i].1)
                    .map(|(y, a)| marker_position(y, &a.offset))
                    .collect(),
            );
        }
        dres[6 * n..].copy_from_slice(&level.balance_rows(&f, &m));
        for q in 0..chunk.len() {
            let rhs = DVector::from_fn(dim, |i, _| -dres[i].eps[q]);
            let dx = solve_tangent(&lu, &rhs, || {
                singular_jacobian(
                    sol.iterations,
                    sol.residual,
                    "the system's Jacobian",
                    "parameter derivatives",
                )
            })?;
            let dp: [f64; 3] = std::array::from_fn(|k| dx[6 * n + k] * level.ls);
            let psi = [dx[6 * n + 3], dx[6 * n + 4], dx[6 * n + 5]];
            let spin = |v: &[f64; 3]| -> [f64; 3] {
                [
                    psi[1] * v[2] - psi[2] * v[1],
                    psi[2] * v[0] - psi[0] * v[2],
                    psi[0] * v[1] - psi[1] * v[0],
                ]
            };
            out.platform_position.push(dp);
            // dR_p = [psi]x R_p, column by column.
            let cols: [[f64; 3]; 3] =
                std::array::from_fn(|c| spin(&[r0[0][c], r0[1][c], r0[2][c]]));
            out.platform_rotation
                .push(std::array::from_fn(|i| std::array::from_fn(|c| cols[c][i])));
            let mut dm = vec![[0.0; 3]; markers.len()];
            for (k, mk) in markers.iter().enumerate() {
                if let SystemMarkerAt::Platform(o) = mk {
                    let arm: [f64; 3] =
                        std::array::from_fn(|i| (0..3).map(|c| r0[i][c] * o[c]).sum());
                    let turn = spin(&arm);
                    dm[k] = std::array::from_fn(|i| dp[i] + turn[i]);
                }
            }
            for (i, (idx, _)) in per_rod.iter().enumerate() {
                for (slot, k) in idx.iter().enumerate() {
                    let px = &marks_x[i][slot];
                    dm[*k] = std::array::from_fn(|c| {
                        let direct = marks_t[i].as_ref().map_or(0.0, |t| t[slot][c].eps[q]);
                        direct + (0..6).map(|j| px[c].eps[j] * dx[6 * i + j]).sum::<f64>()
                    });
                }
            }
            out.markers.push(dm);
        }
    }
    Ok(out)
}
