//! The compiled rod: a validated design turned into per-section stiffness, compliance,
//! weight and chamber data (all SI), ready for the integrator.

use crate::error::{Result, SoftrodError};
use crate::jet::RodScalar;
use crate::law::AxialTable;
use crate::reference::Reference;
use crate::section::CrossSection;
use crate::spec::{
    validate_pressures, validate_tensions, AxialSpec, DesignSpec, Frame, MaterialSpec, SectionSpec,
    StiffnessSpec, SwellingSpec, GEOMETRY_SLACK,
};
use crate::tendon::Route;
use std::sync::Arc;

/// A chamber as the constitutive law sees it: pressurised area, hole radius and centroid
/// (d1, d2, including the section's chamber offset), at the section's start; in a tapered
/// section the centroid and the radius move linearly to their end values and the area
/// follows the radius squared.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chamber {
    pub area: f64,
    pub hole_radius: f64,
    pub centroid: [f64; 2],
    pub channel: usize,
    pub centroid_end: [f64; 2],
    pub hole_radius_end: f64,
}

impl Chamber {
    /// (area, hole radius, centroid) at the relative position t in [0, 1] along the section.
    #[inline]
    pub fn at(&self, t: f64) -> (f64, f64, [f64; 2]) {
        if t == 0.0 {
            return (self.area, self.hole_radius, self.centroid);
        }
        let r = self.hole_radius + t * (self.hole_radius_end - self.hole_radius);
        let c = [
            self.centroid[0] + t * (self.centroid_end[0] - self.centroid[0]),
            self.centroid[1] + t * (self.centroid_end[1] - self.centroid[1]),
        ];
        let q = r / self.hole_radius;
        (self.area * q * q, r, c)
    }
}

/// Axial law of a compiled section (see `crate::law`).
#[derive(Debug, Clone, PartialEq)]
pub enum AxialLaw {
    Linear,
    Ogden { alpha: f64 },
    Table(Arc<AxialTable>),
}

/// What a section needs to recompute its stiffness when its chambers swell
/// (paper 002 eq. 22 changes A_m and I, hence eqs. 17, 19, 20).
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    pub outer_radius: f64,
    /// Outer radius at the section's end (equal to `outer_radius` unless tapered).
    pub outer_radius_end: f64,
    pub bore_radius: f64,
    pub material: MaterialSpec,
}

impl Geometry {
    /// Outer radius at the relative position t in [0, 1] along the section.
    #[inline]
    pub fn outer_at(&self, t: f64) -> f64 {
        if t == 0.0 {
            self.outer_radius
        } else {
            self.outer_radius + t * (self.outer_radius_end - self.outer_radius)
        }
    }
}

/// The constitutive refinements of a compiled section.
#[derive(Debug, Clone, PartialEq)]
pub struct SectionLaw {
    pub axial: AxialLaw,
    /// Bending stiffness times the local stretch v3 (paper 004 eq. 29).
    pub stretch_bending: bool,
    /// EA, EI_1, EI_2 scaled by the per-solve factors sigma (paper 001 eq. 13).
    pub stiffness_map: bool,
    pub swelling: Option<SwellingSpec>,
    /// Geometry and the directly given stiffnesses, for swelling.
    pub geometry: Option<Geometry>,
    pub given: StiffnessSpec,
    /// Correction factors c_s, c_e, c_b, c_t.
    pub factors: [f64; 4],
}

impl SectionLaw {
    pub fn is_linear(&self) -> bool {
        matches!(self.axial, AxialLaw::Linear)
            && !self.stretch_bending
            && !self.stiffness_map
            && self.swelling.is_none()
    }
}

/// K_se diagonal and K_bt of a section from directly given stiffnesses, or else from the
/// cross-section and the material's (E, G), times the correction factors (paper 002 eqs.
/// 17, 19, 20). Generic over the scalar so that parameter derivatives pass through it.
pub fn stiffness_matrices<S: RodScalar>(
    given: &StiffnessSpec,
    geo: Option<(&CrossSection<S>, S, S)>,
    [c_s, c_e, c_b, c_t]: [S; 4],
) -> ([S; 3], [[S; 3]; 3]) {
    let from = |given: Option<f64>, f: &dyn Fn(&CrossSection<S>, S, S) -> S| -> S {
        match (given, geo) {
            (Some(k), _) => S::from(k),
            (None, Some((c, e, g))) => f(c, e, g),
            (None, None) => S::from(f64::NAN), // unreachable for validated elastic sections
        }
    };
    let ea = from(given.ea, &|c, e, _| e * c.area);
    let ga = from(given.ga, &|c, _, g| g * c.area);
    let ei1 = from(given.ei1, &|c, e, _| e * c.i11);
    let ei2 = from(given.ei2, &|c, e, _| e * c.i22);
    // The coupling term comes from the geometry only (direct stiffnesses describe
    // principal axes); zero when the section has no geometry.
    let ei12 = match geo {
        Some((c, e, _)) if given.ei1.is_none() && given.ei2.is_none() => e * c.i12,
        _ => S::from(0.0),
    };
    let gj = from(given.gj, &|c, _, g| g * c.polar());
    let zero = S::from(0.0);
    (
        [c_s * ga, c_s * ga, c_e * ea],
        [
            [c_b * ei1, c_b * ei12, zero],
            [c_b * ei12, c_b * ei2, zero],
            [zero, zero, c_t * gj],
        ],
    )
}

fn compile_law(s: &SectionSpec) -> SectionLaw {
    SectionLaw {
        axial: match &s.law.axial {
            AxialSpec::Linear => AxialLaw::Linear,
            AxialSpec::Ogden { alpha } => AxialLaw::Ogden { alpha: *alpha },
            AxialSpec::Table { force, stiffness } => {
                AxialLaw::Table(Arc::new(AxialTable::new(force, stiffness)))
            }
        },
        stretch_bending: s.stretch_bending(),
        stiffness_map: s.law.stiffness_map,
        swelling: s.law.swelling,
        geometry: match (s.outer_radius, s.material) {
            (Some(outer_radius), Some(material)) => Some(Geometry {
                outer_radius,
                outer_radius_end: s.outer_radius_end.unwrap_or(outer_radius),
                bore_radius: s.bore_radius,
                material,
            }),
            _ => None,
        },
        given: s.given_stiffness(),
        factors: [s.c_s, s.c_e, s.c_b, s.c_t],
    }
}

/// One compiled section.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    pub name: String,
    pub length: f64,
    pub steps: usize,
    pub rigid: bool,
    /// Diagonal of K_se = diag(c_s GA, c_s GA, c_e EA), N.
    pub k_se: [f64; 3],
    /// K_bt = [[c_b EI_11, c_b EI_12, 0], [c_b EI_12, c_b EI_22, 0], [0, 0, c_t GJ]], N m^2.
    pub k_bt: [[f64; 3]; 3],
    /// Inverse of K_se (diagonal), 1/N.
    pub c_se: [f64; 3],
    /// Inverse of K_bt, 1/(N m^2).
    pub c_bt: [[f64; 3]; 3],
    /// Mass per unit reference length, kg/m (the mean over the section if it is tapered).
    pub line_mass: f64,
    /// Line mass at the section's start, middle and end (a quadratic in s: the area of a
    /// tapered section), kg/m; all equal `line_mass` in a uniform section.
    pub line_mass_profile: [f64; 3],
    /// User line loads on this section (world frame): force N/m and moment N m/m.
    pub line_force: [f64; 3],
    pub line_moment: [f64; 3],
    /// Follower line loads (body frame): force N/m and moment N m/m.
    pub line_force_body: [f64; 3],
    pub line_moment_body: [f64; 3],
    pub chambers: Vec<Chamber>,
    /// Arc length at the start of the section, m.
    pub s_start: f64,
    pub law: SectionLaw,
    /// Reference strains v*(s), u*(s).
    pub reference: Reference,
    /// Tendons routed through this section (a tendon listed here ends at this section's end
    /// if no later section lists it).
    pub tendons: Vec<Route>,
    /// The cross-section changes along s (taper, chamber end values).
    pub tapered: bool,
    /// Radius of the outermost material fibre (validity rule of the fibre stretch): the
    /// largest outer radius, else (stiffnesses given directly) the outer edge of the farthest
    /// chamber or tendon, else 0 (only the centreline is checked).
    pub fibre_radius: f64,
}

impl Section {
    /// Line mass at the relative position t in [0, 1], kg/m.
    #[inline]
    pub fn line_mass_at(&self, t: f64) -> f64 {
        if !self.tapered {
            return self.line_mass;
        }
        let [a, m, b] = self.line_mass_profile;
        if a == m && m == b {
            return a;
        }
        // The quadratic through (0, a), (1/2, m), (1, b).
        a + t * (4.0 * m - 3.0 * a - b) + t * t * (2.0 * (a + b) - 4.0 * m)
    }

    /// Radius of the surface that touches obstacles (`crate::contact`) at local arc length
    /// `s`: the outer radius (a tapered section's at s), else (stiffnesses given directly)
    /// the outermost fibre's radius, which may be 0 (the centreline touches).
    #[inline]
    pub fn surface_radius(&self, s: f64) -> f64 {
        match &self.law.geometry {
            Some(g) => g.outer_at(if self.tapered { s / self.length } else { 0.0 }),
            None => self.fibre_radius,
        }
    }

    /// The section's properties change along s (taper or a reference table).
    pub fn is_varying(&self) -> bool {
        self.tapered || self.reference.is_varying()
    }
}

/// A validated, compiled design. Immutable: solves never change it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rod {
    pub spec: DesignSpec,
    pub sections: Vec<Section>,
    pub n_channels: usize,
    /// Number of tendon (tension) channels.
    pub n_tendons: usize,
    pub length: f64,
    pub base_position: [f64; 3],
    /// Base rotation R0, row-major (columns are d1, d2, d3 in world coordinates).
    pub base_rotation: [[f64; 3]; 3],
    pub gravity: [f64; 3],
    /// Force scale for the shooting unknowns and residual: a bending stiffness over L^2, N.
    pub force_scale: f64,
    /// Rigid obstacles (`crate::contact`); None without any.
    pub obstacles: Option<std::sync::Arc<[crate::contact::Obstacle]>>,
}

/// Inverse of a 3x3 matrix with positive determinant, else None.
pub fn inverse3<S: RodScalar>(m: &[[S; 3]; 3]) -> Option<[[S; 3]; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let d = det.value();
    if !(d.is_finite() && d > 0.0) {
        return None;
    }
    let inv_det = det.recip();
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let (a, b) = ((j + 1) % 3, (j + 2) % 3);
            let (c, e) = ((i + 1) % 3, (i + 2) % 3);
            (m[a][c] * m[b][e] - m[a][e] * m[b][c]) * inv_det
        })
    }))
}

impl Rod {
    /// Validate and compile a design.
    pub fn new(spec: DesignSpec) -> Result<Self> {
        spec.validate()?;
        let mut sections = Vec::with_capacity(spec.sections.len());
        let mut s_start = 0.0;
        for (i, s) in spec.sections.iter().enumerate() {
            let chambers: Vec<Chamber> = s
                .chambers
                .iter()
                .enumerate()
                .map(|(k, c)| {
                    let ([_, d1], [r0, r1]) = s.chamber_ends(k);
                    let o = s.law.chamber_offset;
                    Chamber {
                        area: c.area,
                        hole_radius: r0,
                        centroid: s.chamber_centroid(k),
                        channel: c.channel,
                        centroid_end: [o[0] + d1 * c.angle.cos(), o[1] + d1 * c.angle.sin()],
                        hole_radius_end: r1,
                    }
                })
                .collect();
            let tapered = s.is_tapered();
            let outer_end = s.outer_radius.map(|ro| s.outer_radius_end.unwrap_or(ro));
            // The material cross-section at the relative position t along the section.
            let cs_at = |t: f64| {
                s.outer_radius.zip(outer_end).map(|(r0, r1)| {
                    CrossSection::from_holes(
                        r0 + t * (r1 - r0),
                        s.bore_radius,
                        chambers.iter().map(|c| {
                            let (_, r, x) = c.at(t);
                            (r, x)
                        }),
                    )
                })
            };
            // Every point the integrator evaluates: the RK4 stages of every step.
            let stages: Vec<f64> = if tapered || s.reference.table.is_some() {
                (0..=2 * s.steps)
                    .map(|k| k as f64 / (2 * s.steps) as f64)
                    .collect()
            } else {
                vec![0.0]
            };
            for &t in &stages {
                if let Some(cs) = cs_at(t) {
                    if cs.area <= 0.0 || cs.i11 <= 0.0 || cs.i22 <= 0.0 {
                        return Err(SoftrodError::invalid(
                            format!("sections[{i}].chambers"),
                            format!("A_m = {:.4e} m^2", cs.area),
                            if t == 0.0 {
                                "bore and chambers leave no positive material area / second moment"
                                    .to_string()
                            } else {
                                format!("bore and chambers leave no positive material area / second moment at {:.4} of the section's length", t)
                            },
                        ));
                    }
                }
            }
            let cs = cs_at(0.0);
            let law = compile_law(s);
            let (k_se, k_bt) = stiffness_matrices(
                &law.given,
                cs.as_ref()
                    .zip(s.material.as_ref())
                    .map(|(c, m)| (c, m.youngs_modulus, m.shear_modulus)),
                law.factors,
            );
            let (c_se, c_bt) = if s.rigid {
                ([0.0; 3], [[0.0; 3]; 3])
            } else {
                let c_bt = inverse3(&k_bt).ok_or_else(|| {
                    SoftrodError::invalid(
                        format!("sections[{i}]"),
                        format!("K_bt = {k_bt:?}"),
                        "bending/torsion stiffness matrix must be positive definite",
                    )
                })?;
                ([1.0 / k_se[0], 1.0 / k_se[1], 1.0 / k_se[2]], c_bt)
            };
            // Gravity acts on the referential area A_m,0 (paper 002 eq. 27): no swelling.
            // A tapered section's area is a quadratic in s: Simpson's rule is exact.
            let mass_at = |t: f64| match (s.mass, cs_at(t), &s.material) {
                (Some(m), _, _) => m / s.length,
                (None, Some(c), Some(m)) => m.density * c.area,
                _ => f64::NAN, // unreachable for validated sections
            };
            let line_mass_profile = if tapered {
                [mass_at(0.0), mass_at(0.5), mass_at(1.0)]
            } else {
                [mass_at(0.0); 3]
            };
            let [ma, mm, mb] = line_mass_profile;
            let line_mass = if tapered && !(ma == mm && mm == mb) {
                (ma + 4.0 * mm + mb) / 6.0
            } else {
                ma
            };
            let mut line_force = [0.0; 3];
            let mut line_moment = [0.0; 3];
            let mut line_force_body = [0.0; 3];
            let mut line_moment_body = [0.0; 3];
            for l in spec.loads.iter().filter(|l| l.section == i) {
                let (f, m) = match l.frame {
                    Frame::World => (&mut line_force, &mut line_moment),
                    Frame::Body => (&mut line_force_body, &mut line_moment_body),
                };
                for k in 0..3 {
                    f[k] += l.force_per_length[k];
                    m[k] += l.moment_per_length[k];
                }
            }
            let tendons: Vec<Route> = s.tendons.iter().map(|t| Route::new(t, s.length)).collect();
            let reference = Reference::new(&s.reference);
            let fibre_radius = match (s.outer_radius, outer_end) {
                (Some(r0), Some(r1)) => r0.max(r1),
                _ => chambers
                    .iter()
                    .map(|c| {
                        (c.centroid[0].hypot(c.centroid[1]) + c.hole_radius)
                            .max(c.centroid_end[0].hypot(c.centroid_end[1]) + c.hole_radius_end)
                    })
                    .chain(tendons.iter().map(|t| t.max_distance()))
                    .fold(0.0, f64::max),
            };
            // The reference length of every fibre is positive: v3* - rho |u*_perp| > 0 at
            // the outermost fibre (else the stress-free shape folds through itself).
            if !reference.is_straight() {
                let refs: Vec<f64> = if reference.is_varying() {
                    stages.clone()
                } else {
                    vec![0.0]
                };
                for t in refs {
                    let (v, u) = reference.at(t * s.length);
                    let rho = match (s.outer_radius, outer_end) {
                        (Some(r0), Some(r1)) => r0 + t * (r1 - r0),
                        _ => fibre_radius,
                    };
                    let fibre = v[2] - rho * u[0].hypot(u[1]);
                    if fibre.is_nan() || fibre <= 0.0 {
                        return Err(SoftrodError::invalid(
                            format!("sections[{i}].reference"),
                            format!("u* = {u:?} 1/m, v* = {v:?} at s = {:.6e} m", t * s.length),
                            format!(
                                "the precurvature folds the section through itself: the fibre at radius {rho:.4e} m would have reference stretch v3* - rho |(u1*, u2*)| = {fibre:.4} <= 0 (bend radius smaller than the section)"
                            ),
                        ));
                    }
                }
            }
            sections.push(Section {
                name: s.name.clone(),
                length: s.length,
                steps: if s.rigid { 1 } else { s.steps },
                rigid: s.rigid,
                k_se,
                k_bt,
                c_se,
                c_bt,
                line_mass,
                line_mass_profile,
                line_force,
                line_moment,
                line_force_body,
                line_moment_body,
                chambers,
                s_start,
                law,
                reference,
                tendons,
                tapered,
                fibre_radius,
            });
            s_start += s.length;
        }
        let length = spec.length();
        // Force scale: the softest bending stiffness over L^2 (deflects the tip by ~L).
        // (A tapered section's smallest EI is at one of its ends: I grows like r^4.)
        let ei_min = sections
            .iter()
            .filter(|s| !s.rigid)
            .map(|s| {
                let ei = s.k_bt[0][0].min(s.k_bt[1][1]);
                match &s.law.geometry {
                    Some(g) if s.tapered => {
                        let q = (g.outer_radius_end / g.outer_radius).powi(4);
                        ei.min(ei * q)
                    }
                    _ => ei,
                }
            })
            .fold(f64::INFINITY, f64::min);
        let force_scale = if ei_min.is_finite() {
            ei_min / (length * length)
        } else {
            1.0
        };
        Ok(Rod {
            n_channels: spec.n_channels(),
            n_tendons: spec.n_tendons(),
            length,
            base_position: spec.mounting.base_position,
            base_rotation: spec.mounting.base_rotation,
            gravity: spec.mounting.gravity,
            force_scale,
            sections,
            obstacles: if spec.obstacles.is_empty() {
                None
            } else {
                Some(
                    spec.obstacles
                        .iter()
                        .enumerate()
                        .map(|(k, o)| crate::contact::Obstacle::new(o, k))
                        .collect::<Result<_>>()?,
                )
            },
            spec,
        })
    }

    /// Total mass of the rod (without the tip body), kg.
    pub fn mass(&self) -> f64 {
        self.sections.iter().map(|s| s.line_mass * s.length).sum()
    }

    /// Whether every section's reference shape is straight (no precurvature, no pre-strain):
    /// the unloaded rod is the straight line.
    pub fn is_straight(&self) -> bool {
        self.sections.iter().all(|s| s.reference.is_straight())
    }

    pub fn check_pressures(&self, pressures: &[f64]) -> Result<()> {
        validate_pressures(pressures, self.n_channels)
    }

    /// Check a solve's tendon tensions: one per tendon channel, finite, >= 0.
    pub fn check_tensions(&self, tensions: &[f64]) -> Result<()> {
        validate_tensions(tensions, self.n_tendons)
    }

    /// Check a solve's pressures and stiffness scale against the design: the pressures
    /// (see `validate_pressures`), sigma finite and > 0, and swollen chambers (paper 002
    /// eq. 22) with a positive radius that leave material in the section. Radii are
    /// linear in the load factor, so checking the full load covers the ramp.
    pub fn check_loads(&self, pressures: &[f64], sigma: &[f64; 3]) -> Result<()> {
        self.check_pressures(pressures)?;
        for (k, s) in sigma.iter().enumerate() {
            if !(s.is_finite() && *s > 0.0) {
                return Err(SoftrodError::invalid(
                    format!("stiffness_scale[{k}]"),
                    s,
                    "stiffness scaling factors must be finite and > 0",
                ));
            }
        }
        for (i, s) in self.sections.iter().enumerate() {
            let Some(sw) = s.law.swelling else { continue };
            let w = swelling_factors(self, i, pressures, 1.0);
            for (k, (c, f)) in s.chambers.iter().zip(&w).enumerate() {
                if f.is_nan() || *f <= 0.0 {
                    return Err(SoftrodError::invalid(
                        format!("pressures[{}]", c.channel),
                        pressures[c.channel],
                        format!(
                            "shrinks sections[{i}].chambers[{k}] to radius factor 1 + c_p p / p_ref = {f:.4} <= 0 (c_p = {}, p_ref = {} Pa)",
                            sw.c_p, sw.p_ref
                        ),
                    ));
                }
            }
            let Some(geo) = &s.law.geometry else { continue };
            // Swollen chambers must stay inside the wall, off the bore and apart: eq. 22 is a
            // heuristic with no such limit, and overlapping holes would be subtracted twice
            // from A_m and I. A tapered section is checked at its ends and middle.
            let ts: &[f64] = if s.tapered { &[0.0, 0.5, 1.0] } else { &[0.0] };
            for &t in ts {
                let at: Vec<(f64, [f64; 2])> = s
                    .chambers
                    .iter()
                    .zip(&w)
                    .map(|(c, f)| {
                        let (_, r, x) = c.at(t);
                        (r * f, x)
                    })
                    .collect();
                let outer = geo.outer_at(t);
                for (k, &(r, cen)) in at.iter().enumerate() {
                    let f = w[k];
                    let dist = cen[0].hypot(cen[1]);
                    // The same slack as the design's own containment checks, so that a
                    // chamber the design accepts (e.g. tangent to the wall) passes at p = 0.
                    let clash = if dist + r > outer * (1.0 + GEOMETRY_SLACK) {
                        Some("breaks through the outer wall".to_string())
                    } else if geo.bore_radius > 0.0
                        && dist - r < geo.bore_radius * (1.0 - GEOMETRY_SLACK)
                    {
                        Some("reaches the bore".to_string())
                    } else {
                        at.iter()
                            .take(k)
                            .position(|(ro, o)| {
                                let d = (cen[0] - o[0]).hypot(cen[1] - o[1]);
                                d < (r + ro) * (1.0 - GEOMETRY_SLACK)
                            })
                            .map(|j| format!("overlaps chambers[{j}]"))
                    };
                    if let Some(what) = clash {
                        return Err(SoftrodError::invalid(
                            "pressures",
                            format!("{pressures:?}"),
                            format!(
                                "swell sections[{i}].chambers[{k}] to radius {r:.4e} m (factor 1 + c_p p / p_ref = {f:.4}), which {what}; lower c_p or the pressure"
                            ),
                        ));
                    }
                }
                let cs = CrossSection::from_holes(outer, geo.bore_radius, at.iter().copied());
                let (_, k_bt) = stiffness_matrices(
                    &s.law.given,
                    Some((&cs, geo.material.youngs_modulus, geo.material.shear_modulus)),
                    s.law.factors,
                );
                if !(cs.area > 0.0 && inverse3(&k_bt).is_some()) {
                    return Err(SoftrodError::invalid(
                        "pressures",
                        format!("{pressures:?}"),
                        format!(
                            "swells the chambers of sections[{i}] until no material is left (A_m = {:.3e} m^2); lower c_p or the pressure",
                            cs.area
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Factor by which chamber radii grow at the (scaled) pressures: 1 + c_p p / p_ref
/// (paper 002 eq. 22), one per chamber of section `i`, with the section's own c_p.
pub fn swelling_factors(rod: &Rod, i: usize, pressures: &[f64], factor: f64) -> Vec<f64> {
    let c_p = rod.sections[i].law.swelling.map_or(0.0, |sw| sw.c_p);
    swelling_factors_with(rod, i, pressures, factor, c_p)
}

pub(crate) fn swelling_factors_with<S, P: Copy>(
    rod: &Rod,
    i: usize,
    pressures: &[P],
    factor: S,
    c_p: S,
) -> Vec<S>
where
    S: RodScalar + From<P>,
{
    let s = &rod.sections[i];
    s.chambers
        .iter()
        .map(|c| match s.law.swelling {
            Some(sw) => c_p * (factor * S::from(pressures[c.channel]) / sw.p_ref) + 1.0,
            None => S::from(1.0),
        })
        .collect()
}
