//! Exact derivatives of the static tip pose, and of marker points anywhere on the body,
//! with respect to design parameters, for calibration (paper 002's fits, paper 001's
//! per-sample stiffness identification, motion-capture markers as paper 000 Sec. III-D
//! records them).
//!
//! At a converged solution the shooting residual R(x, theta) vanishes (see `statics`). By
//! the implicit function theorem the unknowns move as dx/dtheta = -J^-1 d_theta R with
//! J = d_x R, and any output y(x, theta) (the tip pose, a marker's position) as
//! dy/dtheta = d_theta y + d_x y dx/dtheta. One integration in `Jet<3>` (state seeded in x)
//! gives J and d_x y; one integration in `Jet<CHUNK>` per CHUNK parameters, with the
//! coefficients built from dual-valued parameters (`Coeffs::build_with`), gives d_theta R
//! and d_theta y. No finite differences.
//!
//! A tip held by a constraint (pinned or clamped, `crate::statics::constraint`) has its
//! own residual (`constraint::held_residual`, 6 unknowns): [`constrained_pose_sensitivity`]
//! runs the same two passes with it (`Jet<6>` for J), so calibration works for held tips
//! too; the held tip's position (clamped: and rotation) then has zero total derivative.
//! The held tip's reaction (`constraint::reaction`, what is left of the tip wrench
//! balance) is one more output y of the same passes: its derivatives cost no extra
//! integration, and a free tip (no reaction) skips them.
//!
//! A system of rods holding a platform has the same derivatives of its platform pose and
//! of markers on the platform and the rods (`system`).
//!
//! A marker sits at reference arc length s with an offset o in the cross-section frame:
//! its position is r(s) + R(s) o. The state at s is read during the same integration: the
//! node before s, then one partial RK4 step (the exact transfer in a rigid section) of the
//! remaining length, so the integration itself, and the tip, are unchanged.

use crate::error::{Result, SoftrodError};
use crate::jet::{Coeff, Jet, RodScalar, StateScalar};
use crate::marker::{check_markers, Marker, NODE_SNAP};
use crate::ode::{advance, integrate, resolve_stretch, Coeffs, Loads, NodeAt, SectionKnobs, State};
use crate::rod::{AxialLaw, Rod};
use crate::statics::constraint::{reaction, tip_residual, TipConstraint};
use crate::statics::tangent::{singular_jacobian, solve_tangent};
use crate::statics::{Problem, Shape, Solution};
use nalgebra::{DMatrix, DVector};

mod collocation;
pub mod system;

/// Parameters per dual integration.
pub(crate) const CHUNK: usize = 4;

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
    /// Mass density in kg/m^3 of the listed sections' material (their weight; their
    /// inertia in dynamics); for sections whose mass comes from the material.
    Density,
    /// Mass in kg of each listed section, for sections whose mass is given directly.
    Mass,
    /// Kelvin-Voigt damping time tau in s of `[dynamics]` (B = tau K, paper 000 eq. 8):
    /// dynamics only (`crate::dynamics::sensitivity`); no sections.
    DampingTime,
}

impl ParamKind {
    /// Every kind with its name, as the Python layer spells them.
    pub const ALL: [(&'static str, ParamKind); 16] = [
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
        ("density", ParamKind::Density),
        ("mass", ParamKind::Mass),
        ("damping_time", ParamKind::DampingTime),
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
                ParamKind::DampingTime => rod.spec.dynamics.damping_time,
                _ => f64::NAN,
            };
        };
        section_value(rod, i, self.kind)
    }
}

pub(crate) fn section_value(rod: &Rod, i: usize, kind: ParamKind) -> f64 {
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
        ParamKind::StiffnessScale(_) | ParamKind::DampingTime => f64::NAN,
        ParamKind::Density => rod.spec.sections[i]
            .material
            .map_or(f64::NAN, |m| m.density),
        ParamKind::Mass => s.line_mass * s.length,
    }
}

/// Check parameters of the static sensitivities against the rod ([`check_params`]; with
/// obstacles too: the contact penalty is a line load of the shooting ODE and the rounded
/// end's force a term of the tip balance, both carried by the dual passes like any load).
/// Errors name `params[j]`.
pub fn validate_params(rod: &Rod, params: &[Param]) -> Result<()> {
    check_params(rod, params)
}

/// Check parameters against the rod: known sections, elastic, with the law the parameter
/// belongs to, one shared value per parameter (the dynamic sensitivities carry contact:
/// `crate::dynamics::sensitivity`). Errors name `params[j]`.
pub(crate) fn check_params(rod: &Rod, params: &[Param]) -> Result<()> {
    for (j, p) in params.iter().enumerate() {
        let name = p.kind.name();
        let field = format!("params[{j}] ({name})");
        if p.kind == ParamKind::DampingTime {
            return Err(SoftrodError::invalid(
                field,
                name,
                "the damping time acts in dynamics only (calibrate it with a dynamic fit)",
            ));
        }
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
                    ParamKind::Density
                        if rod.spec.sections[i].mass.is_some()
                            || rod.spec.sections[i].material.is_none() =>
                    {
                        Some("has its mass given directly, not from a material density: calibrate its mass")
                    }
                    ParamKind::Mass if rod.spec.sections[i].mass.is_none() => {
                        Some("has its mass from the material density: calibrate the density")
                    }
                    _ => None,
                }
            };
            if let Some(rule) = missing {
                return Err(SoftrodError::invalid(field, what, rule));
            }
        }
        let v0 = section_value(rod, p.sections[0], p.kind);
        if matches!(p.kind, ParamKind::Density | ParamKind::Mass) && (v0.is_nan() || v0 <= 0.0) {
            return Err(SoftrodError::invalid(
                field,
                v0,
                "the mass the derivative scales must be > 0",
            ));
        }
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

/// Where a marker is read during the integration: after visit `node` (the base is visit 0,
/// then the end of every step), a partial step of length `h` in `section` (none when the
/// marker sits on that node), from the section's start when `section_start` (an Ogden
/// section's carried stretch is set there first).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerAt {
    /// The integration node at or before the marker (0: the base).
    pub(crate) node: usize,
    pub(crate) section: usize,
    /// Steps done in `section` at the node, and the node's arc length.
    pub(crate) step: usize,
    pub(crate) s_node: f64,
    /// The distance from the node (0: at the node).
    pub(crate) h: f64,
    pub(crate) section_start: bool,
    /// In the cross-section frame, m.
    pub(crate) offset: [f64; 3],
}

impl MarkerAt {
    /// The tip: the last node, no offset.
    pub(crate) fn tip(rod: &Rod) -> Self {
        let last = rod.sections.len() - 1;
        let sec = &rod.sections[last];
        MarkerAt {
            node: rod.sections.iter().map(|s| s.steps).sum(),
            section: last,
            step: sec.steps,
            s_node: rod.length,
            h: 0.0,
            section_start: false,
            offset: [0.0; 3],
        }
    }
}

/// Check the markers against the rod and locate them on its integration grid. Errors name
/// `markers[k]`.
pub fn locate_markers(rod: &Rod, markers: &[Marker]) -> Result<Vec<MarkerAt>> {
    check_markers(rod, markers)?;
    let mut out = Vec::with_capacity(markers.len());
    for mk in markers {
        let mut node = 0;
        let mut at = None;
        for (i, sec) in rod.sections.iter().enumerate() {
            let h = sec.length / sec.steps as f64;
            let local = mk.s - sec.s_start;
            let last = i + 1 == rod.sections.len();
            if local <= sec.length || last {
                let k_step = ((local / h).floor() as usize).min(sec.steps - 1);
                let rest = (local - k_step as f64 * h).clamp(0.0, h);
                at = Some(if rest <= NODE_SNAP * h {
                    MarkerAt {
                        node: node + k_step,
                        section: i,
                        step: k_step,
                        s_node: sec.s_start + k_step as f64 * h,
                        h: 0.0,
                        section_start: false,
                        offset: mk.offset,
                    }
                } else if rest >= (1.0 - NODE_SNAP) * h {
                    MarkerAt {
                        node: node + k_step + 1,
                        section: i,
                        step: k_step + 1,
                        s_node: sec.s_start + (k_step + 1) as f64 * h,
                        h: 0.0,
                        section_start: false,
                        offset: mk.offset,
                    }
                } else {
                    MarkerAt {
                        node: node + k_step,
                        section: i,
                        step: k_step,
                        s_node: sec.s_start + k_step as f64 * h,
                        h: rest,
                        section_start: k_step == 0,
                        offset: mk.offset,
                    }
                });
                break;
            }
            node += sec.steps;
        }
        out.push(at.expect("the last section takes every s <= L"));
    }
    Ok(out)
}

/// Integrate like [`integrate`] and return the tip state and the state at every marker.
pub(crate) fn integrate_markers<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    markers: &[MarkerAt],
) -> (State<D>, Vec<State<D>>) {
    let mut states: Vec<Option<State<D>>> = vec![None; markers.len()];
    let mut node = 0;
    let mut visit = |_: usize, _: f64, y: &State<D>| {
        for (mk, out) in markers.iter().zip(states.iter_mut()) {
            if mk.node != node {
                continue;
            }
            if mk.h == 0.0 {
                *out = Some(*y);
                continue;
            }
            let mut start = *y;
            if mk.section_start {
                // The previous section's end: this section's carried stretch first.
                resolve_stretch(&mut start, &coeffs[mk.section]);
            }
            let node = NodeAt {
                section: mk.section,
                step: mk.step,
                s: mk.s_node,
            };
            *out = Some(advance(rod, coeffs, node, &start, mk.h));
        }
        node += 1;
    };
    let tip = integrate(rod, coeffs, y0, Some(&mut visit));
    let states = states
        .into_iter()
        .map(|s| s.expect("every marker lies on the integration grid"))
        .collect();
    (tip, states)
}

/// r(s) + R(s) o.
pub(crate) fn marker_position<D: RodScalar>(y: &State<D>, offset: &[f64; 3]) -> [D; 3] {
    std::array::from_fn(|i| {
        y.r[i] + y.rot[i][0] * offset[0] + y.rot[i][1] * offset[1] + y.rot[i][2] * offset[2]
    })
}

/// Positions of the markers of a converged solution (world frame, m).
pub fn marker_positions(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    markers: &[MarkerAt],
) -> Vec<[f64; 3]> {
    if markers.is_empty() {
        return vec![];
    }
    let p = Problem::new(rod, loads, 1.0);
    if let Some(c) = &sol.collocation {
        // Solved by collocation: shooting from x would leave the equilibrium; each marker
        // is read from its node's state, over at most one step.
        return markers
            .iter()
            .map(|mk| marker_position(&from_node(rod, &p.coeffs, &c.shape, mk), &mk.offset))
            .collect();
    }
    let (_, states) = integrate_markers(rod, &p.coeffs, p.base_state(&sol.x), markers);
    states
        .iter()
        .zip(markers)
        .map(|(y, mk)| marker_position(y, &mk.offset))
        .collect()
}

/// The state at marker `mk` of a collocation solution's `shape`: its node's state (force,
/// moment, pose), advanced over the marker's partial step with the section's law.
fn from_node(rod: &Rod, coeffs: &[Coeffs<f64>], shape: &Shape, mk: &MarkerAt) -> State<f64> {
    let j = mk.node;
    let y = State {
        r: shape.position[j],
        rot: shape.rotation[j],
        n: shape.force[j],
        m: shape.moment[j],
        aux: [1.0, 1.0],
    };
    advance_from_node(rod, coeffs, y, mk)
}

/// The state at marker `mk` from the state `y` at its node (in any scalar: the exact
/// derivatives of a collocation solution read their markers the same way,
/// `crate::sensitivity::collocation`): `y` itself at a node, else advanced over
/// the marker's partial step with the section's law.
pub(crate) fn advance_from_node<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    mut y: State<D>,
    mk: &MarkerAt,
) -> State<D> {
    if mk.h == 0.0 {
        return y;
    }
    // The carried stretch of the marker's section at that node.
    resolve_stretch(&mut y, &coeffs[mk.section]);
    let node = NodeAt {
        section: mk.section,
        step: mk.step,
        s: mk.s_node,
    };
    advance(rod, coeffs, node, &y, mk.h)
}

/// Derivatives of the tip pose and of the marker positions with respect to each parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct TipSensitivity {
    /// d r_tip / d theta_j (world frame), one per parameter.
    pub position: Vec<[f64; 3]>,
    /// d R_tip / d theta_j, one per parameter.
    pub rotation: Vec<[[f64; 3]; 3]>,
    /// d marker_k / d theta_j (world frame): `markers[j][k]`.
    pub markers: Vec<Vec<[f64; 3]>>,
    /// d F_r / d theta_j and d M_r / d theta_j of the held tip's reaction (world frame, the
    /// wrench the constraint applies to the tip, as `ConstrainedSolution` reports it; N
    /// and N m per unit of the parameter), one per parameter; zero moment for a pinned
    /// tip. Empty for a free tip (it has no reaction).
    pub reaction_force: Vec<[f64; 3]>,
    pub reaction_moment: Vec<[f64; 3]>,
}

pub(crate) type Dual = Jet<CHUNK>;

/// Knobs and sigma of every section with the parameters of `chunk` seeded as dual
/// directions 0..chunk.len() (the damping time is no knob: the dynamics seed it), in
/// `Jet<N>` with N >= chunk.len() (the dynamics size N to the chunk).
pub(crate) fn seeded<const N: usize>(
    rod: &Rod,
    stiffness_scale: &[f64; 3],
    chunk: &[Param],
) -> (Vec<SectionKnobs<Jet<N>>>, [Jet<N>; 3]) {
    debug_assert!(chunk.len() <= N);
    seeded_in(rod, stiffness_scale, chunk.iter().enumerate())
}

/// The sections' coefficients under `loads` with the parameters of `chunk` seeded as dual
/// directions 0..chunk.len() ([`seeded`]), and the knobs they were built from.
#[allow(clippy::type_complexity)]
pub(crate) fn seeded_coeffs<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    chunk: &[Param],
) -> (Vec<Coeffs<Jet<N>>>, Vec<SectionKnobs<Jet<N>>>) {
    let (knobs, sigma) = seeded::<N>(rod, &loads.stiffness_scale, chunk);
    let coeffs = (0..rod.sections.len())
        .map(|i| {
            Coeffs::build_with(
                rod,
                i,
                &loads.pressures,
                &loads.tensions,
                &rod.gravity,
                Jet::<N>::from(1.0),
                &sigma,
                &knobs[i],
            )
        })
        .collect();
    (coeffs, knobs)
}

/// [`seeded`] with each parameter's dual direction given: `(q, param)` seeds `param` as
/// direction q < N (a system's parameter that acts on some rods only skips the others).
pub(crate) fn seeded_in<'p, const N: usize>(
    rod: &Rod,
    stiffness_scale: &[f64; 3],
    directions: impl IntoIterator<Item = (usize, &'p Param)>,
) -> (Vec<SectionKnobs<Jet<N>>>, [Jet<N>; 3]) {
    let mut knobs: Vec<SectionKnobs<Jet<N>>> = rod
        .sections
        .iter()
        .map(|s| SectionKnobs::of(s).lift())
        .collect();
    let mut sigma = stiffness_scale.map(Jet::<N>::from);
    for (q, p) in directions {
        match p.kind {
            ParamKind::StiffnessScale(k) => {
                sigma[k].eps[q] = 1.0;
                continue;
            }
            ParamKind::DampingTime => continue,
            _ => {}
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
                // d(rho/rho0)/d rho = 1/rho0, d(m/m0)/dm = 1/m0
                ParamKind::Density | ParamKind::Mass => {
                    k.mass_scale.eps[q] = 1.0 / section_value(rod, i, p.kind)
                }
                ParamKind::StiffnessScale(_) | ParamKind::DampingTime => {
                    unreachable!("handled above")
                }
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
    pose_sensitivity(rod, loads, sol, params, &[])
}

/// Derivatives of the tip pose and of the markers (located by [`locate_markers`]) at the
/// converged solution `sol` of `loads` (the parameters must have been validated with
/// [`validate_params`]).
pub fn pose_sensitivity(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    params: &[Param],
    markers: &[MarkerAt],
) -> Result<TipSensitivity> {
    if sol.x.len() == 6 {
        sensitivity_n::<6>(rod, loads, &TipConstraint::Free, sol, params, markers)
    } else {
        sensitivity_n::<3>(rod, loads, &TipConstraint::Free, sol, params, markers)
    }
}

/// [`pose_sensitivity`] of an equilibrium whose tip is held by `constraint` (the converged
/// solution of [`crate::statics::constraint::solve_constrained`], 6 unknowns): the same
/// implicit differentiation with the held tip's residual (pinned: the tip position and the
/// tip moment balance; clamped: the tip position and orientation). The held tip's position
/// (and, clamped, its rotation) then has zero derivative up to round-off, since the
/// residual fixes it. A free `constraint` is [`pose_sensitivity`]. The constraint must have
/// been validated (`TipConstraint::validate`), the parameters with [`validate_params`].
pub fn constrained_pose_sensitivity(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    sol: &Solution,
    params: &[Param],
    markers: &[MarkerAt],
) -> Result<TipSensitivity> {
    if let TipConstraint::Free = constraint {
        return pose_sensitivity(rod, loads, sol, params, markers);
    }
    if sol.x.len() != 6 {
        return Err(SoftrodError::invalid(
            "solution.x",
            format!("{} values", sol.x.len()),
            "a held tip's equilibrium has 6 shooting unknowns (base force and moment): \
             pass the solution of solve_constrained",
        ));
    }
    sensitivity_n::<6>(rod, loads, constraint, sol, params, markers)
}

/// The implicit-function-theorem derivatives for the shooting residual of `constraint`
/// (`crate::statics::constraint::tip_residual`: the free tip's wrench balance, or a held
/// tip's residual) with N unknowns.
fn sensitivity_n<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    sol: &Solution,
    params: &[Param],
    markers: &[MarkerAt],
) -> Result<TipSensitivity> {
    if sol.collocation.is_some() {
        // Implicit differentiation of the collocation equations: a shooting pass from x
        // would leave this equilibrium (only a free tip's equilibrium is solved so).
        if let TipConstraint::Free = constraint {
            return collocation::pose_sensitivity(rod, loads, sol, params, markers);
        }
        return Err(SoftrodError::invalid(
            "solution",
            "solved by collocation (a free tip)",
            "a held tip's derivatives need the held equilibrium: pass the solution of \
             solve_constrained",
        ));
    }
    let p = Problem::new(rod, loads, 1.0);
    // J = d_x R and d_x y in one pass with x seeded.
    let xd: [Jet<N>; N] = std::array::from_fn(|i| Jet::variable(sol.x[i], i));
    let (tip_x, marks_x) = integrate_markers(rod, &p.coeffs, p.base_state(&xd), markers);
    let r_x: [Jet<N>; N] = tip_residual(&p, constraint, &tip_x);
    let jac = DMatrix::from_fn(N, N, |i, k| r_x[i].eps[k]);
    let lu = jac.lu();
    let mut out = TipSensitivity {
        position: Vec::with_capacity(params.len()),
        rotation: Vec::with_capacity(params.len()),
        markers: Vec::with_capacity(params.len()),
        reaction_force: vec![],
        reaction_moment: vec![],
    };
    // A held tip's reaction (a pin carries no moment: its moment balance is a residual row).
    let pinned = matches!(constraint, TipConstraint::Pinned { .. });
    let held = !matches!(constraint, TipConstraint::Free);
    let reaction_x = held.then(|| reaction(&p, &tip_x));
    let pos_x: Vec<[Jet<N>; 3]> = marks_x
        .iter()
        .zip(markers)
        .map(|(y, mk)| marker_position(y, &mk.offset))
        .collect();
    for chunk in params.chunks(CHUNK) {
        let (coeffs, knobs) = seeded_coeffs::<CHUNK>(rod, loads, chunk);
        let x: Vec<Dual> = sol.x.iter().map(|v| Dual::from(*v)).collect();
        let mut base = p.base_state(&x);
        // The base force carries the rod's whole weight (n(0) = F_tip + m_t g + int f ds):
        // a mass parameter moves it by its sections' weight per unit of mass_scale. With 6
        // unknowns (n(0) among them) this is a change of variables only: J dx/dtheta
        // absorbs it and the total derivatives do not depend on it.
        for (sec, k) in rod.sections.iter().zip(&knobs) {
            for c in 0..3 {
                base.n[c] += (k.mass_scale - 1.0) * (sec.line_mass * rod.gravity[c] * sec.length);
            }
        }
        let (tip, marks) = integrate_markers(rod, &coeffs, base, markers);
        let r_t: [Dual; N] = tip_residual(&p, constraint, &tip);
        let reaction_t = held.then(|| reaction(&p, &tip));
        let pos_t: Vec<[Dual; 3]> = marks
            .iter()
            .zip(markers)
            .map(|(y, mk)| marker_position(y, &mk.offset))
            .collect();
        for q in 0..chunk.len() {
            let rhs = DVector::from_fn(N, |i, _| -r_t[i].eps[q]);
            let dx = solve_tangent(&lu, &rhs, || {
                singular_jacobian(
                    sol.iterations,
                    sol.residual,
                    "the shooting Jacobian",
                    "parameter derivatives",
                )
            })?;
            let total =
                |d: &Dual, dx_: &Jet<N>| d.eps[q] + (0..N).map(|k| dx_.eps[k] * dx[k]).sum::<f64>();
            out.position
                .push(std::array::from_fn(|i| total(&tip.r[i], &tip_x.r[i])));
            out.rotation.push(std::array::from_fn(|i| {
                std::array::from_fn(|j| total(&tip.rot[i][j], &tip_x.rot[i][j]))
            }));
            out.markers.push(
                pos_t
                    .iter()
                    .zip(&pos_x)
                    .map(|(pt, px)| std::array::from_fn(|i| total(&pt[i], &px[i])))
                    .collect(),
            );
            if let (Some((ft, mt)), Some((fx, mx))) = (&reaction_t, &reaction_x) {
                out.reaction_force
                    .push(std::array::from_fn(|i| total(&ft[i], &fx[i])));
                out.reaction_moment.push(if pinned {
                    [0.0; 3]
                } else {
                    std::array::from_fn(|i| total(&mt[i], &mx[i]))
                });
            }
        }
    }
    Ok(out)
}
