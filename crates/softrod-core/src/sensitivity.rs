//! Exact derivatives of the static tip pose with respect to design parameters, for
//! calibration (paper 002's fits, paper 001's per-sample stiffness identification).
//!
//! At a converged solution the shooting residual R(x, theta) vanishes (see `statics`). By
//! the implicit function theorem the unknowns move as dx/dtheta = -J^-1 d_theta R with
//! J = d_x R, and the tip pose y(x, theta) as dy/dtheta = d_theta y + d_x y dx/dtheta.
//! One integration in `Jet<3>` (state seeded in x) gives J and d_x y; one integration in
//! `Jet<CHUNK>` per CHUNK parameters, with the coefficients built from dual-valued
//! parameters (`Coeffs::build_with`), gives d_theta R and d_theta y. No finite differences.

use crate::error::{Result, SoftrodError};
use crate::jet::Jet;
use crate::ode::{integrate, Coeffs, Loads, SectionKnobs, State};
use crate::rod::{AxialLaw, Rod};
use crate::statics::{Problem, Solution};
use nalgebra::{DMatrix, DVector};

/// Parameters per dual integration.
const CHUNK: usize = 4;

/// What a calibration parameter is. All derivatives are with respect to the parameter's
/// value in SI, as written in a design file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamKind {
    /// Correction factors c_s, c_e, c_b, c_t of the listed sections (paper 002 eqs. 17-20).
    CorrectionFactor(usize),
    /// Young's modulus E in Pa of the listed sections' material; the shear modulus scales
    /// with it (Poisson's ratio held fixed).
    YoungsModulus,
    /// Ogden exponent alpha (paper 002 eq. 16).
    OgdenAlpha,
    /// Swelling coefficient c_p (paper 002 eq. 22).
    SwellingCp,
    /// Chamber offset along d1 (0) or d2 (1) in m (paper 002 eq. 21).
    ChamberOffset(usize),
    /// Factor on the listed sections' pressurised chamber areas (1 = as designed).
    AreaScale,
    /// Stiffness scaling factor sigma_ext (0), sigma_bend_1 (1), sigma_bend_2 (2) of the
    /// solve (paper 001 eq. 13), for the stiffness-mapped sections.
    StiffnessScale(usize),
}

impl ParamKind {
    /// Every kind with its name, as the Python layer spells them.
    pub const ALL: [(&'static str, ParamKind); 13] = [
        ("c_s", ParamKind::CorrectionFactor(0)),
        ("c_e", ParamKind::CorrectionFactor(1)),
        ("c_b", ParamKind::CorrectionFactor(2)),
        ("c_t", ParamKind::CorrectionFactor(3)),
        ("E", ParamKind::YoungsModulus),
        ("alpha", ParamKind::OgdenAlpha),
        ("c_p", ParamKind::SwellingCp),
        ("offset_1", ParamKind::ChamberOffset(0)),
        ("offset_2", ParamKind::ChamberOffset(1)),
        ("area_scale", ParamKind::AreaScale),
        ("sigma_ext", ParamKind::StiffnessScale(0)),
        ("sigma_bend_1", ParamKind::StiffnessScale(1)),
        ("sigma_bend_2", ParamKind::StiffnessScale(2)),
    ];

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
    }

    pub fn name(&self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, k)| k == self)
            .map(|(n, _)| *n)
            .unwrap_or("?")
    }
}

/// One calibration parameter: a kind and the sections it acts on (empty for the
/// stiffness scaling factors, which belong to the solve).
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub kind: ParamKind,
    pub sections: Vec<usize>,
}

impl Param {
    /// Its current value in `rod` and `loads` (the point the derivatives are taken at).
    pub fn value(&self, rod: &Rod, loads: &Loads) -> f64 {
        let Some(&i) = self.sections.first() else {
            return match self.kind {
                ParamKind::StiffnessScale(k) => loads.stiffness_scale[k],
                _ => f64::NAN,
            };
        };
        section_value(rod, i, self.kind)
    }
}

fn section_value(rod: &Rod, i: usize, kind: ParamKind) -> f64 {
    let s = &rod.sections[i];
    let knobs = SectionKnobs::of(s);
    match kind {
        ParamKind::CorrectionFactor(k) => knobs.factors[k],
        ParamKind::YoungsModulus => s
            .law
            .geometry
            .as_ref()
            .map_or(f64::NAN, |g| g.material.youngs_modulus),
        ParamKind::OgdenAlpha => knobs.alpha,
        ParamKind::SwellingCp => knobs.c_p,
        ParamKind::ChamberOffset(k) => rod.spec.sections[i].law.chamber_offset[k],
        ParamKind::AreaScale => 1.0,
        ParamKind::StiffnessScale(_) => f64::NAN,
    }
}

/// Check parameters against the rod: known sections, elastic, with the law the parameter
/// belongs to, one shared value per parameter. Errors name `params[j]`.
pub fn validate_params(rod: &Rod, params: &[Param]) -> Result<()> {
    for (j, p) in params.iter().enumerate() {
        let name = p.kind.name();
        let field = format!("params[{j}] ({name})");
        if let ParamKind::StiffnessScale(_) = p.kind {
            if !p.sections.is_empty() {
                return Err(SoftrodError::invalid(
                    field,
                    format!("sections {:?}", p.sections),
                    "stiffness scaling factors belong to the solve: give no sections",
                ));
            }
            if !rod.sections.iter().any(|s| s.law.stiffness_map) {
                return Err(SoftrodError::invalid(
                    field,
                    name,
                    "no section has law.stiffness_map = true, so sigma acts nowhere",
                ));
            }
            continue;
        }
        if p.sections.is_empty() {
            return Err(SoftrodError::invalid(
                field,
                "no sections",
                "name at least one section the parameter acts on",
            ));
        }
        for &i in &p.sections {
            let Some(s) = rod.sections.get(i) else {
                return Err(SoftrodError::invalid(
                    field,
                    format!("section {i}"),
                    format!("the design has {} sections", rod.sections.len()),
                ));
            };
            let what = format!("section {i} ({})", s.name);
            let law = &s.law;
            let missing = if s.rigid {
                Some("is rigid: it has no stiffness or chamber law")
            } else {
                match p.kind {
                    ParamKind::YoungsModulus if law.geometry.is_none() => {
                        Some("has no geometry and material, so E does not act on it")
                    }
                    ParamKind::OgdenAlpha if !matches!(law.axial, AxialLaw::Ogden { .. }) => {
                        Some("does not use axial = \"ogden\"")
                    }
                    ParamKind::SwellingCp if law.swelling.is_none() => {
                        Some("has no chamber swelling (c_p and p_ref)")
                    }
                    ParamKind::ChamberOffset(_) | ParamKind::AreaScale if s.chambers.is_empty() => {
                        Some("has no chambers")
                    }
                    _ => None,
                }
            };
            if let Some(rule) = missing {
                return Err(SoftrodError::invalid(field, what, rule));
            }
        }
        let v0 = section_value(rod, p.sections[0], p.kind);
        for &i in &p.sections[1..] {
            let v = section_value(rod, i, p.kind);
            if v != v0 {
                return Err(SoftrodError::invalid(
                    field,
                    format!("{v} in section {i} ({})", rod.sections[i].name),
                    format!(
                        "one parameter needs one value: section {} ({}) has {v0}; calibrate them as separate parameters",
                        p.sections[0], rod.sections[p.sections[0]].name
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Derivatives of the tip pose with respect to each parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct TipSensitivity {
    /// d r_tip / d theta_j (world frame), one per parameter.
    pub position: Vec<[f64; 3]>,
    /// d R_tip / d theta_j, one per parameter.
    pub rotation: Vec<[[f64; 3]; 3]>,
}

type Dual = Jet<CHUNK>;

/// Knobs and sigma of every section with the parameters of `chunk` seeded as dual
/// directions 0..chunk.len().
fn seeded(rod: &Rod, loads: &Loads, chunk: &[Param]) -> (Vec<SectionKnobs<Dual>>, [Dual; 3]) {
    let mut knobs: Vec<SectionKnobs<Dual>> = rod
        .sections
        .iter()
        .map(|s| SectionKnobs::of(s).lift())
        .collect();
    let mut sigma = loads.stiffness_scale.map(Dual::from);
    for (q, p) in chunk.iter().enumerate() {
        if let ParamKind::StiffnessScale(k) = p.kind {
            sigma[k].eps[q] = 1.0;
            continue;
        }
        for &i in &p.sections {
            let k = &mut knobs[i];
            match p.kind {
                ParamKind::CorrectionFactor(f) => k.factors[f].eps[q] = 1.0,
                // d(E/E0)/dE = 1/E0
                ParamKind::YoungsModulus => {
                    k.youngs_scale.eps[q] = 1.0 / section_value(rod, i, p.kind)
                }
                ParamKind::OgdenAlpha => k.alpha.eps[q] = 1.0,
                ParamKind::SwellingCp => k.c_p.eps[q] = 1.0,
                ParamKind::ChamberOffset(a) => k.offset[a].eps[q] = 1.0,
                ParamKind::AreaScale => k.area_scale.eps[q] = 1.0,
                ParamKind::StiffnessScale(_) => unreachable!("handled above"),
            }
        }
    }
    (knobs, sigma)
}

/// Tip-pose derivatives at the converged solution `sol` of `loads` (the parameters must
/// have been validated with [`validate_params`]).
pub fn tip_sensitivity(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    params: &[Param],
) -> Result<TipSensitivity> {
    if sol.x.len() == 6 {
        sensitivity_n::<6>(rod, loads, sol, params)
    } else {
        sensitivity_n::<3>(rod, loads, sol, params)
    }
}

fn sensitivity_n<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    params: &[Param],
) -> Result<TipSensitivity> {
    let p = Problem::new(rod, loads, 1.0);
    // J = d_x R and d_x y in one pass with x seeded.
    let xd: [Jet<N>; N] = std::array::from_fn(|i| Jet::variable(sol.x[i], i));
    let tip_x = integrate(rod, &p.coeffs, p.base_state(&xd), None);
    let r_x: [Jet<N>; N] = p.residual_of_tip(&tip_x);
    let jac = DMatrix::from_fn(N, N, |i, k| r_x[i].eps[k]);
    let lu = jac.lu();
    let mut out = TipSensitivity {
        position: Vec::with_capacity(params.len()),
        rotation: Vec::with_capacity(params.len()),
    };
    for chunk in params.chunks(CHUNK) {
        let (knobs, sigma) = seeded(rod, loads, chunk);
        let coeffs: Vec<Coeffs<Dual>> = (0..rod.sections.len())
            .map(|i| {
                Coeffs::build_with(
                    rod,
                    i,
                    &loads.pressures,
                    &loads.tensions,
                    &rod.gravity,
                    Dual::from(1.0),
                    &sigma,
                    &knobs[i],
                )
            })
            .collect();
        let x: Vec<Dual> = sol.x.iter().map(|v| Dual::from(*v)).collect();
        let tip: State<Dual> = integrate(rod, &coeffs, p.base_state(&x), None);
        let r_t: [Dual; N] = p.residual_of_tip(&tip);
        for q in 0..chunk.len() {
            let rhs = DVector::from_fn(N, |i, _| -r_t[i].eps[q]);
            let dx = lu
                .solve(&rhs)
                .filter(|d| d.iter().all(|v| v.is_finite()))
                .ok_or_else(|| SoftrodError::NotConverged {
                    iterations: sol.iterations,
                    residual: sol.residual,
                    load_factor: 1.0,
                    reason: "the shooting Jacobian is singular at this equilibrium, so its parameter derivatives are undefined".into(),
                })?;
            let total =
                |d: &Dual, dx_: &Jet<N>| d.eps[q] + (0..N).map(|k| dx_.eps[k] * dx[k]).sum::<f64>();
            out.position
                .push(std::array::from_fn(|i| total(&tip.r[i], &tip_x.r[i])));
            out.rotation.push(std::array::from_fn(|i| {
                std::array::from_fn(|j| total(&tip.rot[i][j], &tip_x.rot[i][j]))
            }));
        }
    }
    Ok(out)
}
