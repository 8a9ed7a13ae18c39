//! The static Cosserat rod ODE (docs/model.md; paper 001 eqs. 1-4 with the pressure
//! moved into the constitutive law as in paper 002 eqs. 6-7) and its fixed-step RK4
//! integration from base to tip.
//!
//! State y = (r, R, n, m): centreline, rotation [d1 d2 d3] (row-major), total internal
//! force and moment in the world frame. Strains from the linear law with pressure:
//!   v = K_se^-1 (R^T n + P e3) + v*,            P = sum_k p_k A_k,
//!   u = K_bt^-1 (R^T m + sum_k p_k A_k (y_k, -x_k, 0)) + u*,
//! since n_m = n - n_p with n_p = -P d3 and m_m = m - m_p with
//! m_p = -sum_k rho_k x (p_k A_k d3). Then r' = R v, R' = R u^, n' = -f, m' = -r' x n - l,
//! with f and l the world-frame line loads plus the body-frame (follower) ones turned by R.
//! v*, u* are the section's reference strains (precurvature, pre-strain; `crate::reference`);
//! tendons add their tensions to n and m (`crate::tendon`).
//!
//! A uniform section has constant coefficients ([`Coeffs`]); a tapered section or one with
//! a tabulated reference shape has coefficients that depend on s, evaluated at every RK4
//! stage ([`Local`], built by the same code for both).
//!
//! Everything is generic over the scalar `D` of the state (f64, or dual numbers for exact
//! Jacobians) and the scalar `C` of the coefficients (f64, or dual numbers when derivatives
//! with respect to pressures or parameters are wanted).

use crate::contact::{total_line_force, total_stick_load, Obstacle, StickPoint};
use crate::jet::{Coeff, RodScalar, StateScalar};
use crate::law::{ogden_from_stretch, ogden_initial_stretch, AxialTable};
use crate::rod::{inverse3, stiffness_matrices, swelling_factors_with, AxialLaw, Rod, Section};
use crate::section::CrossSection;
use crate::spec::Frame;
use crate::tendon::{Route, TendonPoint};
use std::sync::Arc;

/// Rod state at one arc length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State<D> {
    pub r: [D; 3],
    pub rot: [[D; 3]; 3],
    pub n: [D; 3],
    pub m: [D; 3],
    /// Carried law states: (lambda, lambda^alpha) in an Ogden section, unused elsewhere.
    pub aux: [D; 2],
}

/// Axial law of one solve (stiffnesses after swelling and the stiffness map).
#[derive(Debug, Clone, PartialEq)]
pub enum AxialCoeffs<C> {
    /// v = C_se n_m + e3 (folded into c_se and v_shift).
    Linear,
    /// Paper 002 eq. 16 with k_e = c_e EA (N), exponent alpha, shear stiffness k_s (N).
    /// The stretch is carried in `State::aux` (see `crate::law`).
    Ogden { k_e: C, alpha: C, k_s: C },
    /// v3 = 1 + F / (scale EA(F)); shear linear through c_se.
    Table { table: Arc<AxialTable>, scale: C },
}

/// Per-solve coefficients of one section: compliances, strain shifts from pressure, loads.
/// The law's fields are the section's values at its start (all along for a uniform section;
/// a varying one recomputes them at every stage from `inputs`, see [`Coeffs::local_at`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Coeffs<C> {
    pub c_se: [C; 3],
    pub c_bt: [[C; 3]; 3],
    /// v* plus the pressure shift K_se^-1 P e3 (body frame).
    pub v_shift: [C; 3],
    /// u* plus the pressure shift K_bt^-1 M_p (body frame).
    pub u_shift: [C; 3],
    /// Line force f (world), N/m: weight plus user loads.
    pub f: [C; 3],
    /// Line moment l (world), N m/m.
    pub l: [C; 3],
    /// Pressure force P = sum_k p_k A_k, N (n_m = n + P d3).
    pub p_force: C,
    pub axial: AxialCoeffs<C>,
    /// Bending stiffness times the local stretch v3 (paper 004 eq. 29).
    pub stretch_bending: bool,
    /// Reference strains v*, u* (body frame) at the section's start.
    pub v_star: [f64; 3],
    pub u_star: [f64; 3],
    /// Stiffnesses K_se (diagonal) and K_bt at the section's start.
    pub k_se: [C; 3],
    pub k_bt: [[C; 3]; 3],
    /// Follower line force and moment (body frame), N/m and N m/m.
    pub f_body: [C; 3],
    pub l_body: [C; 3],
    /// Some follower line load is not zero.
    pub follower: bool,
    /// The section's tendons under tension in this solve.
    pub tendons: Vec<TendonCoeff<C>>,
    /// Radius that scales curvatures to strains in the tendon law's convergence test: the
    /// section's outermost fibre radius (1 % of its length without one), m.
    pub tendon_radius: f64,
    /// What a varying section needs to rebuild its law at any s; None if uniform.
    pub inputs: Option<Box<LawInputs<C>>>,
    /// The rod's obstacles (`crate::contact`): a line load that depends on the position.
    /// Not scaled by the load factor (contact is a constraint, not a load).
    pub obstacles: Option<Arc<[Obstacle]>>,
    /// The frictional statics' contact points of this section from the last converged
    /// increment, one per RK4 stage (4 per step; `crate::statics::friction`): with them
    /// the contact load carries elastic-slip friction. None: frictionless.
    pub friction: Option<Arc<[StickPoint]>>,
}

/// A tendon of a section in one solve: its tension (scaled by the load factor) and routing.
#[derive(Debug, Clone, PartialEq)]
pub struct TendonCoeff<C> {
    pub tension: C,
    pub route: Route,
}

/// The law of a section at one arc length: what the right-hand side reads. For a uniform
/// section it is copied once from [`Coeffs`]; a varying one builds it at every stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Local<C> {
    pub c_se: [C; 3],
    pub c_bt: [[C; 3]; 3],
    pub v_shift: [C; 3],
    pub u_shift: [C; 3],
    pub v_star: [f64; 3],
    pub u_star: [f64; 3],
    pub f: [C; 3],
    pub p_force: C,
    /// Stiffnesses K_se (diagonal) and K_bt: the inverses of c_se and c_bt (the Ogden law
    /// takes k_e = K_se[2] and k_s = K_se[0]).
    pub k_se: [C; 3],
    pub k_bt: [[C; 3]; 3],
}

/// The per-solve inputs of a varying section's law (the parameters, pressures and loads
/// of [`Coeffs::build_with`]), kept to rebuild [`Local`] at any arc length.
#[derive(Debug, Clone, PartialEq)]
pub struct LawInputs<C> {
    knobs: SectionKnobs<C>,
    /// Swelling factor of every chamber.
    swell: Vec<C>,
    /// factor * p_k * area_scale * swell^2 for every chamber (times its area at s: the
    /// pressure force p_k A_k).
    pressure: Vec<C>,
    sigma: [C; 3],
    /// factor * g (world), m/s^2, and factor * user line force, N/m.
    gravity: [C; 3],
    line_force: [C; 3],
}

/// The per-solve loads, SI. The solver scales all of them (and gravity) by a load factor
/// during continuation. `tip_force` and `tip_moment` are the tip loads of this solve, in
/// `tip_frame` (world: dead loads; body: follower loads): [`Loads::from_design`] takes them
/// from the design's `[tip]`; set them to override it. Gravity, line loads and the tip body
/// always come from the design.
#[derive(Debug, Clone, PartialEq)]
pub struct Loads {
    /// Gauge pressure per channel, Pa.
    pub pressures: Vec<f64>,
    /// Tension per tendon channel, N (>= 0).
    pub tensions: Vec<f64>,
    pub tip_force: [f64; 3],
    pub tip_moment: [f64; 3],
    pub tip_frame: Frame,
    /// Stiffness scaling sigma = (sigma_ext, sigma_bend_1, sigma_bend_2) of this solve for
    /// the sections with `law.stiffness_map` (paper 001 eq. 13); not ramped by continuation.
    pub stiffness_scale: [f64; 3],
}

impl Loads {
    /// The design's own tip loads with the given pressures and slack tendons.
    pub fn from_design(rod: &Rod, pressures: Vec<f64>) -> Self {
        Loads {
            pressures,
            tensions: vec![0.0; rod.n_tendons],
            tip_force: rod.spec.tip.force,
            tip_moment: rod.spec.tip.moment,
            tip_frame: rod.spec.tip.frame,
            stiffness_scale: [1.0; 3],
        }
    }

    /// Some load of this solve follows the body (a follower tip load or line load that is
    /// not zero): the base force is then unknown and the loads are not conservative.
    pub fn has_follower(&self, rod: &Rod) -> bool {
        let tip = self.tip_frame == Frame::Body
            && (self.tip_force.iter().any(|x| *x != 0.0)
                || self.tip_moment.iter().any(|x| *x != 0.0));
        tip || rod.spec.has_follower_line_loads()
    }

    /// The base force is unknown (6 shooting unknowns): a follower load, or obstacles,
    /// whose contact forces depend on the shape.
    pub fn base_force_unknown(&self, rod: &Rod) -> bool {
        self.has_follower(rod) || rod.obstacles.is_some()
    }

    /// Tensions of this solve (slack where the caller gave none).
    pub fn tension(&self, channel: usize) -> f64 {
        self.tensions.get(channel).copied().unwrap_or(0.0)
    }
}

#[inline(always)]
fn cross<D: RodScalar>(a: &[D; 3], b: &[D; 3]) -> [D; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The values of a section's calibration parameters, in any scalar: f64 for a solve, dual
/// numbers for the parameter derivatives of `crate::sensitivity`. `SectionKnobs::of` gives
/// the compiled design's values, with which `Coeffs::build_with` equals `Coeffs::build`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionKnobs<S> {
    /// Correction factors c_s, c_e, c_b, c_t (paper 002 eqs. 17, 19, 20).
    pub factors: [S; 4],
    /// Young's and shear modulus of the geometric stiffnesses relative to the material's.
    pub youngs_scale: S,
    /// Ogden exponent (paper 002 eq. 16); unused in other sections.
    pub alpha: S,
    /// Shift of every chamber centroid (d1, d2) in m on top of the design's (eq. 21).
    pub offset: [S; 2],
    /// Swelling coefficient (eq. 22); unused without swelling.
    pub c_p: S,
    /// Factor on every chamber's pressurised area (an effective area, as A_eff of paper 000).
    pub area_scale: S,
    /// Factor on the section's mass per length (its weight here; its inertia in dynamics).
    pub mass_scale: S,
}

impl SectionKnobs<f64> {
    /// The compiled values of section `s`.
    pub fn of(s: &Section) -> Self {
        SectionKnobs {
            factors: s.law.factors,
            youngs_scale: 1.0,
            alpha: match s.law.axial {
                AxialLaw::Ogden { alpha } => alpha,
                _ => 1.0,
            },
            offset: [0.0; 2],
            c_p: s.law.swelling.map_or(0.0, |sw| sw.c_p),
            area_scale: 1.0,
            mass_scale: 1.0,
        }
    }

    /// The same values in scalar `S` (no derivatives).
    pub fn lift<S: RodScalar>(&self) -> SectionKnobs<S> {
        SectionKnobs {
            factors: self.factors.map(S::from),
            youngs_scale: S::from(self.youngs_scale),
            alpha: S::from(self.alpha),
            offset: self.offset.map(S::from),
            c_p: S::from(self.c_p),
            area_scale: S::from(self.area_scale),
            mass_scale: S::from(self.mass_scale),
        }
    }
}

impl Coeffs<f64> {
    /// Coefficients of section `i` under `pressures`, `tensions` and gravity `g`, all
    /// scaled by the load factor, with the stiffness scale `sigma` (used where the section
    /// is mapped).
    pub fn build(
        rod: &Rod,
        i: usize,
        pressures: &[f64],
        tensions: &[f64],
        g: &[f64; 3],
        factor: f64,
        sigma: &[f64; 3],
    ) -> Self {
        let knobs = SectionKnobs::of(&rod.sections[i]);
        Self::build_with(rod, i, pressures, tensions, g, factor, sigma, &knobs)
    }
}

impl<C: RodScalar> Coeffs<C> {
    /// [`Coeffs::build`] with the section's parameters given as `knobs`, in any scalar;
    /// the load factor may be a dual number too (the load derivative of
    /// `crate::statics`' continuation predictor), and the pressures f64 or the coefficients'
    /// scalar (dual pressures give the exact pressure derivatives of `crate::jacobian`).
    #[allow(clippy::too_many_arguments)]
    pub fn build_with<P: Copy>(
        rod: &Rod,
        i: usize,
        pressures: &[P],
        tensions: &[f64],
        g: &[f64; 3],
        factor: C,
        sigma: &[C; 3],
        knobs: &SectionKnobs<C>,
    ) -> Self
    where
        C: From<P>,
    {
        let s = &rod.sections[i];
        let law = &s.law;
        let swell = swelling_factors_with(rod, i, pressures, factor, knobs.c_p);
        let pressure: Vec<C> = s
            .chambers
            .iter()
            .zip(&swell)
            .map(|(c, w)| *w * *w * knobs.area_scale * (factor * C::from(pressures[c.channel])))
            .collect();
        let inputs = LawInputs {
            knobs: *knobs,
            swell,
            pressure,
            sigma: *sigma,
            gravity: g.map(|x| factor * x),
            line_force: s.line_force.map(|x| factor * x),
        };
        let loc = local_law(s, &inputs, 0.0);
        let axial = match &law.axial {
            AxialLaw::Linear => AxialCoeffs::Linear,
            AxialLaw::Ogden { .. } => AxialCoeffs::Ogden {
                k_e: loc.k_se[2],
                alpha: knobs.alpha,
                k_s: loc.k_se[0],
            },
            AxialLaw::Table(table) => AxialCoeffs::Table {
                table: table.clone(),
                scale: if law.stiffness_map {
                    knobs.factors[1] * sigma[0]
                } else {
                    knobs.factors[1]
                },
            },
        };
        let tendons = s
            .tendons
            .iter()
            .filter(|r| tensions.get(r.channel).is_some_and(|t| *t != 0.0))
            .map(|r| TendonCoeff {
                tension: factor * tensions[r.channel],
                route: *r,
            })
            .collect();
        Coeffs {
            c_se: loc.c_se,
            c_bt: loc.c_bt,
            v_shift: loc.v_shift,
            u_shift: loc.u_shift,
            f: loc.f,
            l: s.line_moment.map(|x| factor * x),
            p_force: loc.p_force,
            axial,
            stretch_bending: law.stretch_bending,
            v_star: loc.v_star,
            u_star: loc.u_star,
            k_se: loc.k_se,
            k_bt: loc.k_bt,
            f_body: s.line_force_body.map(|x| factor * x),
            l_body: s.line_moment_body.map(|x| factor * x),
            follower: s
                .line_force_body
                .iter()
                .chain(&s.line_moment_body)
                .any(|x| *x != 0.0),
            tendons,
            tendon_radius: if s.fibre_radius > 0.0 {
                s.fibre_radius
            } else {
                1e-2 * s.length
            },
            inputs: s.is_varying().then(|| Box::new(inputs)),
            obstacles: rod.obstacles.clone(),
            friction: None,
        }
    }

    /// The law at the section's start (a uniform section's law all along).
    pub fn local(&self) -> Local<C> {
        Local {
            c_se: self.c_se,
            c_bt: self.c_bt,
            v_shift: self.v_shift,
            u_shift: self.u_shift,
            v_star: self.v_star,
            u_star: self.u_star,
            f: self.f,
            p_force: self.p_force,
            k_se: self.k_se,
            k_bt: self.k_bt,
        }
    }

    /// The coefficients of section `sec` as they hold at local arc length `s`: a varying
    /// section's law, pressure force and moment, reference strains and line force there
    /// ([`Coeffs::local_at`]; the Ogden law's k_e and k_s with them), the others as they
    /// are. A uniform section's are borrowed. The result is uniform (no `inputs`): what a
    /// collocation stage at `s` reads (`crate::collocation::Grid::build_models`).
    pub fn at(&self, sec: &Section, s: f64) -> std::borrow::Cow<'_, Coeffs<C>> {
        use std::borrow::Cow;
        let Some(inp) = &self.inputs else {
            return Cow::Borrowed(self);
        };
        let loc = local_law(sec, inp, s);
        let axial = match &self.axial {
            AxialCoeffs::Ogden { alpha, .. } => AxialCoeffs::Ogden {
                k_e: loc.k_se[2],
                alpha: *alpha,
                k_s: loc.k_se[0],
            },
            other => other.clone(),
        };
        Cow::Owned(Coeffs {
            c_se: loc.c_se,
            c_bt: loc.c_bt,
            v_shift: loc.v_shift,
            u_shift: loc.u_shift,
            f: loc.f,
            l: self.l,
            p_force: loc.p_force,
            axial,
            stretch_bending: self.stretch_bending,
            v_star: loc.v_star,
            u_star: loc.u_star,
            k_se: loc.k_se,
            k_bt: loc.k_bt,
            f_body: self.f_body,
            l_body: self.l_body,
            follower: self.follower,
            tendons: self.tendons.clone(),
            tendon_radius: self.tendon_radius,
            inputs: None,
            obstacles: self.obstacles.clone(),
            friction: self.friction.clone(),
        })
    }

    /// The law of section `sec` at local arc length `s` (from its start).
    #[inline]
    pub fn local_at(&self, sec: &Section, s: f64) -> Local<C> {
        match &self.inputs {
            Some(inp) => local_law(sec, inp, s),
            None => self.local(),
        }
    }
}

/// The law of a section at local arc length `s`: stiffness of its cross-section there
/// (swollen chambers remove more material: A_m and I of paper 002 eq. 22; a tapered
/// section's outer radius and chambers move linearly in s), the compliances, the pressure
/// force and moment, the reference strains and the line force (weight on the referential
/// area A_m,0: paper 002 eq. 27).
fn local_law<C: RodScalar>(sec: &Section, inp: &LawInputs<C>, s: f64) -> Local<C> {
    let law = &sec.law;
    let zero = C::from(0.0);
    let t = if sec.tapered { s / sec.length } else { 0.0 };
    let knobs = &inp.knobs;
    let centroid = |x: [f64; 2]| [knobs.offset[0] + x[0], knobs.offset[1] + x[1]];
    let (mut k_se, mut k_bt) = match &law.geometry {
        Some(geo) => {
            let cs = CrossSection::from_holes(
                geo.outer_at(t),
                geo.bore_radius,
                sec.chambers.iter().zip(&inp.swell).map(|(c, w)| {
                    let (_, r, x) = c.at(t);
                    (*w * r, centroid(x))
                }),
            );
            let e = knobs.youngs_scale * geo.material.youngs_modulus;
            let g = knobs.youngs_scale * geo.material.shear_modulus;
            stiffness_matrices(&law.given, Some((&cs, e, g)), knobs.factors)
        }
        None => stiffness_matrices(&law.given, None, knobs.factors),
    };
    if law.stiffness_map {
        let [se, s1, s2] = inp.sigma;
        k_se[2] = k_se[2] * se;
        k_bt[0][0] = k_bt[0][0] * s1;
        k_bt[1][1] = k_bt[1][1] * s2;
        // The coupling scales with the geometric mean, which keeps K_bt positive definite.
        let c = (s1 * s2).sqrt();
        k_bt[0][1] = k_bt[0][1] * c;
        k_bt[1][0] = k_bt[1][0] * c;
    }
    let (c_se, c_bt) = if sec.rigid {
        ([zero; 3], [[zero; 3]; 3])
    } else {
        (
            k_se.map(|k| k.recip()),
            inverse3(&k_bt).unwrap_or([[C::from(f64::NAN); 3]; 3]),
        )
    };
    let mut force = zero; // sum p_k A_k
    let mut mp = [zero; 3]; // sum p_k A_k (y_k, -x_k, 0)
    for (c, p) in sec.chambers.iter().zip(&inp.pressure) {
        let (area, _, x) = c.at(t);
        let x = centroid(x);
        let pa = *p * area;
        force += pa;
        mp[0] += pa * x[1];
        mp[1] -= pa * x[0];
    }
    let (v_star, u_star) = sec.reference.at(s);
    let u_shift: [C; 3] = std::array::from_fn(|a| {
        c_bt[a][0] * mp[0] + c_bt[a][1] * mp[1] + c_bt[a][2] * mp[2] + u_star[a]
    });
    let mass = sec.line_mass_at(t);
    Local {
        c_se,
        c_bt,
        v_shift: [
            zero + v_star[0],
            zero + v_star[1],
            c_se[2] * force + v_star[2],
        ],
        u_shift,
        v_star,
        u_star,
        f: std::array::from_fn(|k| {
            inp.gravity[k] * (inp.knobs.mass_scale * mass) + inp.line_force[k]
        }),
        p_force: force,
        k_se,
        k_bt,
    }
}

impl<D: RodScalar> State<D> {
    /// self = base + h k, entry by entry (the arithmetic of `axpy`, in place).
    #[inline(always)]
    fn set_axpy(&mut self, base: &State<D>, h: f64, k: &State<D>) {
        for i in 0..3 {
            self.r[i] = base.r[i] + k.r[i] * h;
            self.n[i] = base.n[i] + k.n[i] * h;
            self.m[i] = base.m[i] + k.m[i] * h;
            for j in 0..3 {
                self.rot[i][j] = base.rot[i][j] + k.rot[i][j] * h;
            }
        }
        self.aux[0] = base.aux[0] + k.aux[0] * h;
        self.aux[1] = base.aux[1] + k.aux[1] * h;
    }

    /// Director d_j (column j of R).
    #[inline(always)]
    pub fn director(&self, j: usize) -> [D; 3] {
        [self.rot[0][j], self.rot[1][j], self.rot[2][j]]
    }

    /// Value part (drops derivatives).
    pub fn re(&self) -> State<f64> {
        State {
            r: self.r.map(|x| x.value()),
            rot: self.rot.map(|row| row.map(|x| x.value())),
            n: self.n.map(|x| x.value()),
            m: self.m.map(|x| x.value()),
            aux: self.aux.map(|x| x.value()),
        }
    }
}

/// Body-frame strains (v, u) from the state through section `sec`'s law at local arc
/// length `s` (pressure, reference strains and tendons included).
pub fn strains<C: Coeff, D: StateScalar<C>>(
    sec: &Section,
    y: &State<D>,
    c: &Coeffs<C>,
    s: f64,
) -> ([D; 3], [D; 3]) {
    let loc = c.local_at(sec, s);
    let (v, u, _) = law_strains(y, c, &loc, sec, s, &mut Scratch::default());
    (v, u)
}

/// [`strains`] with the tendon law started from `scratch` (e.g. [`LawMemory::seeded`]).
pub(crate) fn strains_with<C: Coeff, D: StateScalar<C>>(
    sec: &Section,
    y: &State<D>,
    c: &Coeffs<C>,
    s: f64,
    scratch: &mut Scratch,
) -> ([D; 3], [D; 3]) {
    let loc = c.local_at(sec, s);
    let (v, u, _) = law_strains(y, c, &loc, sec, s, scratch);
    (v, u)
}

/// What the tendon law keeps from one evaluation to the next along a section: the last
/// strains (Newton's starting point at the next stage) and buffers; in a [`LawMemory`],
/// also every stage's solution of the last pass through the section.
#[derive(Default)]
pub(crate) struct Scratch {
    hint: Option<[f64; 6]>,
    /// The strains without tendons, w_free, at the stage that left `hint`.
    hint_free: [f64; 6],
    /// The last factorised J_K (linear law): Newton's matrix for the next stage.
    factor: Option<crate::tendon::Ldl6>,
    /// The tendons' load T = (F_t, M_t) at the last point where the linear law evaluated
    /// the tangents (within a round-off-sized step of `hint`).
    load: Option<[f64; 6]>,
    /// `hint` and `load` were solved at the arc length of the next evaluation (a seeded
    /// scratch), so the load is valid there for any route.
    here: bool,
    points: Vec<TendonPoint>,
    tangents: Vec<([f64; 3], f64)>,
    /// Keep every stage's solution in `memo` (a [`LawMemory`]'s section).
    remember: bool,
    /// Stages (law evaluations) of the section in this pass so far.
    stage: usize,
    /// The last pass's solution at each stage.
    memo: Vec<Memo>,
    /// Newton steps of the linear tendon law taken with this scratch (its cost counter).
    pub(crate) newton_steps: usize,
}

/// One stage's solution of the linear tendon law: strains, the strains without tendons
/// there, and the tendons' load with it (see `Scratch::load`).
#[derive(Clone, Copy)]
struct Memo {
    w: [f64; 6],
    free: [f64; 6],
    load: Option<[f64; 6]>,
}

/// The tendon law's solutions at every stage of the last integration, section by section,
/// kept for the next integration of the same problem (the shooting solver's passes at
/// successive Newton iterates, and its final pass at the solution): each stage starts
/// Newton from the closer of the last pass's solution there and the last stage's.
#[derive(Default)]
pub(crate) struct LawMemory {
    sections: Vec<Scratch>,
}

impl LawMemory {
    /// Newton steps the linear tendon law took in all passes so far.
    pub(crate) fn newton_steps(&self) -> usize {
        self.sections.iter().map(|s| s.newton_steps).sum()
    }

    /// Evaluations of the linear tendon law in the last pass.
    pub(crate) fn evaluations(&self) -> usize {
        self.sections.iter().map(|s| s.stage).sum()
    }

    /// A scratch that starts the tendon law from the last pass's solution at stage `stage`
    /// of section `section` (and its Newton matrix there), for a state at or near that
    /// stage's; a plain cold start where there is none.
    pub(crate) fn seeded(&self, section: usize, stage: usize) -> Scratch {
        let Some(sc) = self.sections.get(section) else {
            return Scratch::default();
        };
        let Some(m) = sc.memo.get(stage) else {
            return Scratch::default();
        };
        Scratch {
            hint: Some(m.w),
            hint_free: m.free,
            load: m.load,
            here: true,
            factor: sc.factor,
            ..Scratch::default()
        }
    }

    /// The section's scratch, made ready for a new pass (stage count and the last stage's
    /// hint reset; the memo and Newton's matrix kept).
    fn pass(&mut self, section: usize) -> &mut Scratch {
        while self.sections.len() <= section {
            self.sections.push(Scratch {
                remember: true,
                ..Scratch::default()
            });
        }
        let sc = &mut self.sections[section];
        sc.stage = 0;
        sc.hint = None;
        sc.load = None;
        sc
    }
}

impl<C: RodScalar> Local<C> {
    /// The values (derivatives dropped).
    fn value(&self) -> Local<f64> {
        Local {
            c_se: self.c_se.map(|x| x.value()),
            c_bt: self.c_bt.map(|r| r.map(|x| x.value())),
            v_shift: self.v_shift.map(|x| x.value()),
            u_shift: self.u_shift.map(|x| x.value()),
            v_star: self.v_star,
            u_star: self.u_star,
            f: self.f.map(|x| x.value()),
            p_force: self.p_force.value(),
            k_se: self.k_se.map(|x| x.value()),
            k_bt: self.k_bt.map(|r| r.map(|x| x.value())),
        }
    }

    fn straight(&self) -> bool {
        self.v_star == [0.0, 0.0, 1.0] && self.u_star == [0.0; 3]
    }
}

/// The linear law (with stretch-dependent bending when `sb`): strains from the body-frame
/// force `nm` and moment `mm` (the state's, less the tendons' when there are any).
#[inline(always)]
fn linear_strains<C: Coeff, D: StateScalar<C>>(
    loc: &Local<C>,
    sb: bool,
    nm: &[D; 3],
    mm: &[D; 3],
) -> ([D; 3], [D; 3]) {
    let v = [
        nm[0] * loc.c_se[0] + loc.v_shift[0],
        nm[1] * loc.c_se[1] + loc.v_shift[1],
        nm[2] * loc.c_se[2] + loc.v_shift[2],
    ];
    let u = bending(loc, sb, &v, mm);
    (v, u)
}

/// u from the body-frame moment `mm` (the law acts on u - u*); with stretch-dependent
/// bending (paper 004 eq. 29, K_bend(v3) = v3 K_bend with the stretch relative to the
/// reference, v3 - v3* + 1) the bending curvatures divide by that stretch; K_bt is block
/// diagonal, so torsion is unaffected.
#[inline(always)]
fn bending<C: Coeff, D: StateScalar<C>>(
    loc: &Local<C>,
    sb: bool,
    v: &[D; 3],
    mm: &[D; 3],
) -> [D; 3] {
    let mut u = [mm[0]; 3];
    for i in 0..3 {
        u[i] = mm[0] * loc.c_bt[i][0]
            + mm[1] * loc.c_bt[i][1]
            + mm[2] * loc.c_bt[i][2]
            + loc.u_shift[i];
    }
    if sb {
        if loc.straight() {
            let r = v[2].recip();
            u[0] = u[0] * r;
            u[1] = u[1] * r;
        } else {
            let r = (v[2] + (1.0 - loc.v_star[2])).recip();
            for k in 0..2 {
                u[k] = (u[k] - loc.u_star[k]) * r + loc.u_star[k];
            }
        }
    }
    u
}

/// Strains, and for an Ogden section the rate of the carried stretch lambda (else zero).
#[inline(always)]
fn law_strains<C: Coeff, D: StateScalar<C>>(
    y: &State<D>,
    c: &Coeffs<C>,
    loc: &Local<C>,
    sec: &Section,
    s: f64,
    scratch: &mut Scratch,
) -> ([D; 3], [D; 3], D) {
    let rt = |w: &[D; 3]| -> [D; 3] {
        let mut o = [w[0] * y.rot[0][0] + w[1] * y.rot[1][0] + w[2] * y.rot[2][0]; 3];
        o[1] = w[0] * y.rot[0][1] + w[1] * y.rot[1][1] + w[2] * y.rot[2][1];
        o[2] = w[0] * y.rot[0][2] + w[1] * y.rot[1][2] + w[2] * y.rot[2][2];
        o
    };
    let nb = rt(&y.n);
    let mb = rt(&y.m);
    let zero = D::from(0.0);
    if !c.tendons.is_empty() {
        let (v, u) = tendon_strains(&nb, &mb, c, loc, sec, s, scratch);
        return (v, u, zero);
    }
    let mut grad = None;
    // The laws act on the strain relative to the reference, v - v* + e3 (docs/laws.md).
    let v = match &c.axial {
        AxialCoeffs::Linear => [
            nb[0] * loc.c_se[0] + loc.v_shift[0],
            nb[1] * loc.c_se[1] + loc.v_shift[1],
            nb[2] * loc.c_se[2] + loc.v_shift[2],
        ],
        // Material force n_m = n + P d3 (the pressure part of the total force removed).
        AxialCoeffs::Ogden { alpha, .. } => {
            let nm = [nb[0], nb[1], nb[2] + loc.p_force];
            let (v, g) =
                ogden_from_stretch(loc.k_se[2], *alpha, loc.k_se[0], y.aux[0], y.aux[1], &nm);
            grad = Some(g);
            let w = loc.v_star;
            [v[0] + w[0], v[1] + w[1], v[2] + (w[2] - 1.0)]
        }
        AxialCoeffs::Table { table, scale } => {
            let f = nb[2] + loc.p_force;
            let ea = table.eval(f) * *scale;
            [
                nb[0] * loc.c_se[0] + loc.v_shift[0],
                nb[1] * loc.c_se[1] + loc.v_shift[1],
                f * ea.recip() + loc.v_star[2],
            ]
        }
    };
    let u = bending(loc, c.stretch_bending, &v, &mb);
    let dlam = match grad {
        // d n_m/ds in the body frame = R^T n' - u x (R^T n) = -R^T f - f_body - u x n_b.
        Some(g) => {
            let f = [zero + loc.f[0], zero + loc.f[1], zero + loc.f[2]];
            let fb = rt(&f);
            let uxn = cross(&u, &nb);
            let mut d = zero;
            for k in 0..3 {
                d += g[k] * (-fb[k] - uxn[k] + neg(c.f_body[k]));
            }
            d
        }
        None => zero,
    };
    (v, u, dlam)
}

/// Strains of a section with tendons under tension (see `crate::tendon`).
#[inline]
fn tendon_strains<C: Coeff, D: StateScalar<C>>(
    nb: &[D; 3],
    mb: &[D; 3],
    c: &Coeffs<C>,
    loc: &Local<C>,
    sec: &Section,
    s: f64,
    scratch: &mut Scratch,
) -> ([D; 3], [D; 3]) {
    if c.stretch_bending {
        general_tendon_strains(nb, mb, c, loc, sec, s, scratch)
    } else {
        linear_tendon_strains(nb, mb, c, loc, sec, s, scratch)
    }
}

/// Newton's tolerance on the strain change (u scaled by the outermost fibre's radius, a
/// strain): a few hundred ulps of a stretch near 1.
const TENDON_TOL: f64 = 1e-13;

/// Scaled size of a strain change: u times `rho` is a strain.
#[inline]
fn strain_size(d: &[f64; 6], rho: f64) -> f64 {
    let mut m: f64 = 0.0;
    for k in 0..6 {
        let x = if k < 3 { d[k] } else { rho * d[k] };
        m = if x.is_nan() { f64::NAN } else { m.max(x.abs()) };
    }
    m
}

/// The tendon law with the linear law (any stiffness, reference strains, pressure):
/// G(w) = K (w - w_free) + T(w) = 0 with w_free = S(nb, mb) the strains without tendons
/// and T = sum tau B^T t(w): the gradient of a strictly convex potential, whose Hessian
/// J_K = K + sum (tau / |q|) B^T (I - t t^T) B is symmetric positive definite (LDL^T).
/// Newton in f64 from the last stage's strains, or from the last pass's at this stage when
/// the scratch belongs to a [`LawMemory`] and those are closer, keeping J_K from stage to
/// stage (a chord method, refreshed when it contracts poorly); for dual scalars, J_K at the
/// solution and one linearised step: w_D = w* - J_K^-1 G_D(w*) (the implicit function
/// theorem).
fn linear_tendon_strains<C: Coeff, D: StateScalar<C>>(
    nb: &[D; 3],
    mb: &[D; 3],
    c: &Coeffs<C>,
    loc: &Local<C>,
    sec: &Section,
    s: f64,
    scratch: &mut Scratch,
) -> ([D; 3], [D; 3]) {
    use crate::tendon::{load, stiffness_with_tendons, tangent, Ldl6};
    let lf = loc.value();
    let nbf = nb.map(|x| x.value());
    let mbf = mb.map(|x| x.value());
    scratch.points.clear();
    for t in &c.tendons {
        let (r, dr) = t.route.at(s);
        scratch.points.push(TendonPoint {
            tension: t.tension.value(),
            r,
            dr,
        });
    }
    let points = &scratch.points;
    let tangents = &mut scratch.tangents;
    let (vf, uf) = linear_strains(&lf, false, &nbf, &mbf);
    let wfree = [vf[0], vf[1], vf[2], uf[0], uf[1], uf[2]];
    let rho = if sec.fibre_radius > 0.0 {
        sec.fibre_radius
    } else {
        1e-2 * sec.length
    };
    // G(w) = K (w - w_free) + T for a given tendon load T.
    let gradient = |w: &[f64; 6], t: &[f64; 6]| -> [f64; 6] {
        let d: [f64; 6] = std::array::from_fn(|k| w[k] - wfree[k]);
        let mut g = [0.0; 6];
        for a in 0..3 {
            g[a] = lf.k_se[a] * d[a] + t[a];
            g[3 + a] =
                lf.k_bt[a][0] * d[3] + lf.k_bt[a][1] * d[4] + lf.k_bt[a][2] * d[5] + t[3 + a];
        }
        g
    };
    // G(w) = K (w - w_free) + T(w) and T(w), with the tangents at w left in `tangents`.
    let residual = |w: &[f64; 6], tangents: &mut Vec<([f64; 3], f64)>| {
        tangents.clear();
        tangents.extend(points.iter().map(|p| tangent(w, p)));
        let t = load(tangents, points);
        (gradient(w, &t), t)
    };
    let build = |tangents: &Vec<([f64; 3], f64)>| {
        Ldl6::new(&stiffness_with_tendons(
            &lf.k_se, &lf.k_bt, tangents, points,
        ))
    };
    let plain = std::any::TypeId::of::<D>() == std::any::TypeId::of::<f64>();
    // The last pass's solution at this stage, if kept: a start closer than the last
    // stage's once the shooting iterates settle. Of the two, the one whose strains without
    // tendons are closer to this stage's: w* = w_free - C T(w*), and T changes with w* only
    // through the tendons' tangents, so w* moves about as w_free does.
    let stage = scratch.stage;
    scratch.stage += 1;
    let memo = scratch
        .memo
        .get(stage)
        .copied()
        .filter(|_| scratch.remember);
    let gap = |a: &[f64; 6]| strain_size(&std::array::from_fn(|k| a[k] - wfree[k]), rho);
    let (hint, hint_load, here) = match (memo, scratch.hint) {
        (Some(m), Some(_)) if gap(&m.free) <= gap(&scratch.hint_free) => (Some(m.w), m.load, true),
        (Some(m), None) => (Some(m.w), m.load, true),
        _ => (scratch.hint, scratch.load, scratch.here),
    };
    scratch.here = false;
    // The start: the chosen hint, else straight tendons (t = e3: w = w_free - C T(e3),
    // which is exact for straight tendons without shear or twist).
    let mut w = match hint {
        Some(w) => w,
        None => {
            tangents.clear();
            tangents.extend(points.iter().map(|_| ([0.0, 0.0, 1.0], 1.0)));
            let t = load(tangents, points);
            let nm = [nbf[0] - t[0], nbf[1] - t[1], nbf[2] - t[2]];
            let mm = [mbf[0] - t[3], mbf[1] - t[4], mbf[2] - t[5]];
            let (v, u) = linear_strains(&lf, false, &nm, &mm);
            [v[0], v[1], v[2], u[0], u[1], u[2]]
        }
    };
    // Newton's matrix is kept in place (no copies of its 42 numbers per evaluation).
    let factor = &mut scratch.factor;
    let mut refresh = factor.is_none();
    // The first residual at the hint's strains w* without new tangents: the tendons' load
    // there is the hint's when it was solved at this arc length (the last pass's solution
    // at this stage), or with straight routes anywhere (the tangents depend on w alone),
    // so G(w*) = K (w* - w_free) + T(w*) costs no square roots. T was evaluated one
    // converged Newton step before w*, so this residual is off by a round-off-sized
    // amount; every later step (and so the convergence test) uses the exact residual.
    let fixed = c.tendons.iter().all(|t| t.route.is_fixed());
    let mut known_load = match (hint, hint_load) {
        (Some(_), Some(t)) if (fixed || here) && !refresh => Some(t),
        _ => None,
    };
    let mut last_load = None;
    let mut prev = f64::INFINITY;
    let mut converged = false;
    for _ in 0..60 {
        let g = match known_load.take() {
            Some(t) => gradient(&w, &t),
            None => {
                let (g, t) = residual(&w, tangents);
                last_load = Some(t);
                g
            }
        };
        if refresh {
            *factor = build(tangents);
            refresh = false;
        }
        let Some(f) = factor.as_ref() else { break };
        let d = f.solve(&g);
        scratch.newton_steps += 1;
        let dn = strain_size(&d, rho);
        if !dn.is_finite() {
            break;
        }
        for k in 0..6 {
            w[k] -= d[k];
        }
        // Converged when the step, or (a contracting iteration) the next one, is below the
        // tolerance: the error after this step is about rate * dn.
        if dn <= TENDON_TOL || (prev.is_finite() && dn * dn <= TENDON_TOL * prev) {
            converged = true;
            break;
        }
        if dn > 0.25 * prev {
            refresh = true; // poor contraction: Newton's matrix at the new point
        }
        prev = dn;
    }
    if !converged {
        scratch.hint = None;
        scratch.factor = None;
        scratch.load = None;
        scratch.memo.truncate(stage);
        let nan = D::from(f64::NAN);
        return ([nan; 3], [nan; 3]);
    }
    scratch.hint = Some(w);
    scratch.hint_free = wfree;
    scratch.load = last_load;
    if plain {
        remember(scratch, stage);
        return (
            [w[0], w[1], w[2]].map(D::from),
            [w[3], w[4], w[5]].map(D::from),
        );
    }
    // Exact first derivatives: J_K at the solution, then w_D = w* - J_K^-1 G_D(w*) with
    // G_D = K_C (w* - S_C(nb_D, mb_D) ...) written as K_C (w* - shift_C) + T_C - (nb, mb)_D
    // (the same G: K (w - w_free) = K (w - shift) - (nb, mb)).
    let (_, t_star) = residual(&w, tangents);
    scratch.load = Some(t_star);
    let Some(f) = build(tangents) else {
        scratch.factor = None;
        scratch.load = None;
        scratch.memo.truncate(stage);
        let nan = D::from(f64::NAN);
        return ([nan; 3], [nan; 3]);
    };
    scratch.factor = Some(f);
    let zero = D::from(0.0);
    let mut t = [zero; 6];
    for (tc, (p, (tv, _))) in c.tendons.iter().zip(points.iter().zip(tangents.iter())) {
        let (x, y) = (p.r[0], p.r[1]);
        let tau = zero + tc.tension;
        t[0] += tau * tv[0];
        t[1] += tau * tv[1];
        t[2] += tau * tv[2];
        t[3] += tau * (y * tv[2]);
        t[4] -= tau * (x * tv[2]);
        t[5] += tau * (x * tv[1] - y * tv[0]);
    }
    let shift = [
        loc.v_shift[0],
        loc.v_shift[1],
        loc.v_shift[2],
        loc.u_shift[0],
        loc.u_shift[1],
        loc.u_shift[2],
    ];
    let dw: [C; 6] = std::array::from_fn(|k| -shift[k] + w[k]);
    let mut g = [zero; 6];
    for a in 0..3 {
        g[a] = t[a] - nb[a] + loc.k_se[a] * dw[a];
        g[3 + a] = t[3 + a] - mb[a]
            + (loc.k_bt[a][0] * dw[3] + loc.k_bt[a][1] * dw[4] + loc.k_bt[a][2] * dw[5]);
    }
    let d = f.solve(&g);
    remember(scratch, stage);
    let out: [D; 6] = std::array::from_fn(|k| -d[k] + w[k]);
    ([out[0], out[1], out[2]], [out[3], out[4], out[5]])
}

/// Keep the solution the scratch holds (hint, its w_free and load) as stage `stage`'s memo.
#[inline]
fn remember(scratch: &mut Scratch, stage: usize) {
    if !scratch.remember {
        return;
    }
    let Some(w) = scratch.hint else { return };
    let m = Memo {
        w,
        free: scratch.hint_free,
        load: scratch.load,
    };
    if stage < scratch.memo.len() {
        scratch.memo[stage] = m;
    } else if stage == scratch.memo.len() {
        scratch.memo.push(m);
    }
}

/// Strains of a section with tendons and stretch-dependent bending (a law that is not the
/// gradient of a quadratic): Newton's method in f64 on w = S(nb - F_t(w), mb - M_t(w)) from
/// the last stage's strains (general LU), then one linearised step in the state's scalar
/// for exact first derivatives.
fn general_tendon_strains<C: Coeff, D: StateScalar<C>>(
    nb: &[D; 3],
    mb: &[D; 3],
    c: &Coeffs<C>,
    loc: &Local<C>,
    sec: &Section,
    s: f64,
    scratch: &mut Scratch,
) -> ([D; 3], [D; 3]) {
    use crate::tendon::{implicit_step, load_with, solve_implicit};
    let sb = c.stretch_bending;
    let lf = loc.value();
    let nbf = nb.map(|x| x.value());
    let mbf = mb.map(|x| x.value());
    scratch.points.clear();
    for t in &c.tendons {
        let (r, dr) = t.route.at(s);
        scratch.points.push(TendonPoint {
            tension: t.tension.value(),
            r,
            dr,
        });
    }
    let points = &scratch.points;
    let tangents = &mut scratch.tangents;
    let law = |ft: &[f64; 6]| -> [f64; 6] {
        let nm = [nbf[0] - ft[0], nbf[1] - ft[1], nbf[2] - ft[2]];
        let mm = [mbf[0] - ft[3], mbf[1] - ft[4], mbf[2] - ft[5]];
        let (v, u) = linear_strains(&lf, sb, &nm, &mm);
        [v[0], v[1], v[2], u[0], u[1], u[2]]
    };
    // Scaled size of a strain change: u times the outermost fibre's radius is a strain.
    let rho = if sec.fibre_radius > 0.0 {
        sec.fibre_radius
    } else {
        1e-2 * sec.length
    };
    let plain = std::any::TypeId::of::<D>() == std::any::TypeId::of::<f64>();
    // Newton from the last strains of this section, else straight tendons (t = e3).
    let solved = solve_implicit(
        points,
        tangents,
        scratch.hint,
        rho,
        plain,
        law,
        |ft: &[f64; 6]| law_jacobian(&lf, sb, &nbf, &mbf, ft),
    );
    let nan = D::from(f64::NAN);
    let Some((ws, jac)) = solved else {
        scratch.hint = None;
        return ([nan; 3], [nan; 3]);
    };
    scratch.hint = Some(ws);
    if plain {
        return (
            [ws[0], ws[1], ws[2]].map(D::from),
            [ws[3], ws[4], ws[5]].map(D::from),
        );
    }
    // Exact first derivatives (implicit function theorem): w_D = w* - J^-1 R_D(w*), with
    // R_D(w) = w - S_D(nb - F_t, mb - M_t) in the state's and coefficients' scalars at the
    // tangents of w* (their dependence on w is in J).
    let zero = D::from(0.0);
    let ft: [D; 6] = load_with(c.tendons.iter().map(|tc| zero + tc.tension), points, &ws);
    let nm = [nb[0] - ft[0], nb[1] - ft[1], nb[2] - ft[2]];
    let mm = [mb[0] - ft[3], mb[1] - ft[4], mb[2] - ft[5]];
    let (v, u) = linear_strains(loc, sb, &nm, &mm);
    match implicit_step(&ws, &jac, &[v[0], v[1], v[2], u[0], u[1], u[2]]) {
        Some(out) => ([out[0], out[1], out[2]], [out[3], out[4], out[5]]),
        None => ([nan; 3], [nan; 3]),
    }
}

/// S' = d(v, u)/d(n_m, m_m) of the linear law (with stretch-dependent bending) at the
/// body-frame force and moment nb - F_t, mb - M_t.
fn law_jacobian(
    loc: &Local<f64>,
    sb: bool,
    nb: &[f64; 3],
    mb: &[f64; 3],
    ft: &[f64; 6],
) -> crate::tendon::Mat6 {
    let mut j = crate::tendon::Mat6::zeros();
    for k in 0..3 {
        j[(k, k)] = loc.c_se[k];
        for l in 0..3 {
            j[(3 + k, 3 + l)] = loc.c_bt[k][l];
        }
    }
    if sb {
        let mm = [mb[0] - ft[3], mb[1] - ft[4], mb[2] - ft[5]];
        let v3 = (nb[2] - ft[2]) * loc.c_se[2] + loc.v_shift[2];
        let st = v3 + (1.0 - loc.v_star[2]);
        for k in 0..2 {
            let raw = mm[0] * loc.c_bt[k][0]
                + mm[1] * loc.c_bt[k][1]
                + mm[2] * loc.c_bt[k][2]
                + loc.u_shift[k]
                - loc.u_star[k];
            for l in 0..3 {
                j[(3 + k, 3 + l)] = loc.c_bt[k][l] / st;
            }
            j[(3 + k, 2)] = -raw / (st * st) * loc.c_se[2];
        }
    }
    j
}

/// dy/ds for an elastic section at local arc length `s` with the law `loc` there.
#[inline(always)]
fn rhs<C: Coeff, D: StateScalar<C>>(
    y: &State<D>,
    c: &Coeffs<C>,
    loc: &Local<C>,
    sec: &Section,
    s: f64,
    stage: usize,
    scratch: &mut Scratch,
) -> State<D> {
    let (v, u, dlam) = law_strains(y, c, loc, sec, s, scratch);
    let rot = &y.rot;
    let mut dr = [v[0]; 3];
    for i in 0..3 {
        dr[i] = rot[i][0] * v[0] + rot[i][1] * v[1] + rot[i][2] * v[2];
    }
    // R u^ column by column: [u3 d2 - u2 d3, u1 d3 - u3 d1, u2 d1 - u1 d2].
    let mut drot = *rot;
    for i in 0..3 {
        let (a, b, e) = (rot[i][0], rot[i][1], rot[i][2]);
        drot[i][0] = b * u[2] - e * u[1];
        drot[i][1] = e * u[0] - a * u[2];
        drot[i][2] = a * u[1] - b * u[0];
    }
    let zero = D::from(0.0);
    let mut dn = [
        zero + neg(loc.f[0]),
        zero + neg(loc.f[1]),
        zero + neg(loc.f[2]),
    ];
    let rxn = cross(&dr, &y.n);
    let mut dm = [
        -rxn[0] + neg(c.l[0]),
        -rxn[1] + neg(c.l[1]),
        -rxn[2] + neg(c.l[2]),
    ];
    if c.follower {
        // Follower line loads: R f_body, R l_body.
        for i in 0..3 {
            for k in 0..3 {
                dn[i] -= rot[i][k] * c.f_body[k];
                dm[i] -= rot[i][k] * c.l_body[k];
            }
        }
    }
    if let Some(obstacles) = &c.obstacles {
        match c.friction.as_deref().and_then(|f| f.get(stage)) {
            // Elastic-slip friction of the frictional statics: the contact point's load
            // from its state of the last increment, with the friction's moment about the
            // centreline (`crate::contact::Obstacle::stick_load`).
            Some(old) => {
                let g = total_stick_load(obstacles, &y.r, &y.rot, sec.surface_radius(s), 1.0, old);
                for i in 0..3 {
                    dn[i] -= g.force[i];
                    dm[i] -= g.moment[i];
                }
            }
            None => {
                // Contact: a line load that depends on the position (normal, through the
                // centreline: no moment; `crate::contact`).
                let fc = total_line_force(obstacles, &y.r, sec.surface_radius(s));
                for i in 0..3 {
                    dn[i] -= fc[i];
                }
            }
        }
    }
    // d(lambda^alpha)/ds = alpha lambda^alpha / lambda * d lambda/ds (Ogden sections).
    let dla = match &c.axial {
        AxialCoeffs::Ogden { alpha, .. } => dlam * y.aux[1] * y.aux[0].recip() * *alpha,
        _ => zero,
    };
    State {
        r: dr,
        rot: drot,
        n: dn,
        m: dm,
        aux: [dlam, dla],
    }
}

#[inline(always)]
fn neg<C: Coeff>(x: C) -> C {
    -x
}

/// One classical RK4 step of length h from local arc length s0, with the law at the
/// step's start, middle and end (`locs`; all the same in a uniform section).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn rk4_step<C: Coeff, D: StateScalar<C>>(
    y: &mut State<D>,
    c: &Coeffs<C>,
    locs: [&Local<C>; 3],
    sec: &Section,
    s0: f64,
    h: f64,
    step: usize,
    scratch: &mut Scratch,
) {
    let at = 4 * step;
    // One stage buffer, overwritten in place (State<Jet<N>> is hundreds of bytes: fresh
    // temporaries per stage cost measurable copies in the dual passes).
    let mut stage = *y;
    let k1 = rhs(&*y, c, locs[0], sec, s0, at, scratch);
    stage.set_axpy(y, 0.5 * h, &k1);
    let k2 = rhs(&stage, c, locs[1], sec, s0 + 0.5 * h, at + 1, scratch);
    stage.set_axpy(y, 0.5 * h, &k2);
    let k3 = rhs(&stage, c, locs[1], sec, s0 + 0.5 * h, at + 2, scratch);
    stage.set_axpy(y, h, &k3);
    let k4 = rhs(&stage, c, locs[2], sec, s0 + h, at + 3, scratch);
    // Each entry of y is updated from its own old value only, so y is overwritten in place.
    let out = y;
    let w = h / 6.0;
    // (R is re-projected onto SO(3) below.)
    for i in 0..3 {
        out.r[i] += (k1.r[i] + (k2.r[i] + k3.r[i]) * 2.0 + k4.r[i]) * w;
        out.n[i] += (k1.n[i] + (k2.n[i] + k3.n[i]) * 2.0 + k4.n[i]) * w;
        out.m[i] += (k1.m[i] + (k2.m[i] + k3.m[i]) * 2.0 + k4.m[i]) * w;
        for j in 0..3 {
            out.rot[i][j] +=
                (k1.rot[i][j] + (k2.rot[i][j] + k3.rot[i][j]) * 2.0 + k4.rot[i][j]) * w;
        }
    }
    for i in 0..2 {
        out.aux[i] += (k1.aux[i] + (k2.aux[i] + k3.aux[i]) * 2.0 + k4.aux[i]) * w;
    }
    out.rot = reproject(&out.rot);
}

/// One Newton-Schulz step R <- R (3I - R^T R) / 2 back towards SO(3). RK4 on the nine
/// entries of R leaves R^T R - I at the size of the step's truncation error, O(h^5); one
/// step squares that, so rotations stay orthonormal to round-off, and positions, forces
/// and the exact Jacobian (this is generic code) all see the same R.
#[inline(always)]
pub(crate) fn reproject<D: RodScalar>(r: &[[D; 3]; 3]) -> [[D; 3]; 3] {
    let s: [[D; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| r[0][i] * r[0][j] + r[1][i] * r[1][j] + r[2][i] * r[2][j])
    });
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let t = |k: usize| if k == j { -s[k][j] + 3.0 } else { -s[k][j] };
            (r[i][0] * t(0) + r[i][1] * t(1) + r[i][2] * t(2)) * 0.5
        })
    })
}

/// Exact transfer through a rigid section of length L with constant line loads:
/// v = e3, u = 0, so r' = d3 is constant and n, m integrate in closed form (R is constant,
/// so follower line loads are constant in the world frame too).
fn rigid_step<C: Coeff, D: StateScalar<C>>(y: &State<D>, c: &Coeffs<C>, len: f64) -> State<D> {
    let t = y.director(2);
    let mut out = *y;
    let zero = D::from(0.0);
    let mut f = [zero + c.f[0], zero + c.f[1], zero + c.f[2]];
    let mut l = [zero + c.l[0], zero + c.l[1], zero + c.l[2]];
    if c.follower {
        for i in 0..3 {
            for k in 0..3 {
                f[i] += y.rot[i][k] * c.f_body[k];
                l[i] += y.rot[i][k] * c.l_body[k];
            }
        }
    }
    let txn = cross(&t, &y.n);
    let txf = cross(&t, &f);
    for i in 0..3 {
        out.r[i] += t[i] * len;
        out.n[i] -= f[i] * len;
        // m(L) = m0 - L t x n0 + (L^2/2) t x f - L l
        out.m[i] = out.m[i] - txn[i] * len + txf[i] * (0.5 * len * len) - l[i] * len;
    }
    out
}

/// (lambda, lambda^alpha) at the start of an Ogden section: the law solved for the material
/// force there (see `crate::law`).
fn initial_stretch<C: Coeff, D: StateScalar<C>>(
    y: &State<D>,
    p_force: C,
    k_e: C,
    alpha: C,
    k_s: C,
) -> [D; 2] {
    let d = |j: usize| y.director(j);
    let dot = |a: &[D; 3], b: &[D; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let nm = [
        dot(&d(0), &y.n),
        dot(&d(1), &y.n),
        dot(&d(2), &y.n) + p_force,
    ];
    ogden_initial_stretch(k_e, alpha, k_s, &nm)
}

/// A node visited by the integrator: section index, arc length, state.
pub type Visitor<'a, D> = &'a mut dyn FnMut(usize, f64, &State<D>);

/// Integrate from the base state through all sections; `visit` sees every node
/// (the base, then the end of every step).
pub fn integrate<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    visit: Option<Visitor<'_, D>>,
) -> State<D> {
    integrate_in(rod, coeffs, y0, visit, None)
}

/// [`integrate`] with the tendon law's solutions kept in `memory` from one call to the next
/// (successive integrations of one problem: same rod and coefficient values).
pub(crate) fn integrate_remembering<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    visit: Option<Visitor<'_, D>>,
    memory: &mut LawMemory,
) -> State<D> {
    integrate_in(rod, coeffs, y0, visit, Some(memory))
}

fn integrate_in<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    mut visit: Option<Visitor<'_, D>>,
    memory: Option<&mut LawMemory>,
) -> State<D> {
    match visit.as_mut() {
        None => integrate_hooked(rod, coeffs, y0, &mut |_, _| false, memory),
        Some(v) => integrate_hooked(
            rod,
            coeffs,
            y0,
            &mut |node: NodeAt, y: &mut State<D>| {
                // The base node is visited once the first section's carried stretch is set,
                // so that its strains come from that section's law like every other node's;
                // a later section's start is the previous section's end, already visited.
                if node.step > 0 || node.section == 0 {
                    v(node.section, node.s, y);
                }
                false
            },
            memory,
        ),
    }
}

/// A node visited by [`integrate_with`]: section index, steps done in that section (0 at the
/// section's start) and arc length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeAt {
    pub section: usize,
    pub step: usize,
    pub s: f64,
}

/// [`integrate`] with a hook that sees every node (every section's start, then the end of
/// every step) and may change the state there, e.g. to apply a point load as a jump of n
/// and m. When the hook returns true the state was changed, and an Ogden section's carried
/// stretch is solved again from the new force. A hook that changes nothing reproduces
/// [`integrate`] exactly.
pub fn integrate_with<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    at_node: &mut dyn FnMut(NodeAt, &mut State<D>) -> bool,
) -> State<D> {
    integrate_hooked(rod, coeffs, y0, at_node, None)
}

fn integrate_hooked<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    y0: State<D>,
    at_node: &mut dyn FnMut(NodeAt, &mut State<D>) -> bool,
    mut memory: Option<&mut LawMemory>,
) -> State<D> {
    let mut y = y0;
    let mut own;
    for (i, (sec, c)) in rod.sections.iter().zip(coeffs).enumerate() {
        resolve_stretch(&mut y, c);
        let node = NodeAt {
            section: i,
            step: 0,
            s: sec.s_start,
        };
        if at_node(node, &mut y) {
            resolve_stretch(&mut y, c);
        }
        let h = sec.length / sec.steps as f64;
        let scratch = match memory.as_deref_mut() {
            Some(m) => m.pass(i),
            None => {
                own = Scratch::default();
                &mut own
            }
        };
        let uniform = c.local();
        let varying = c.inputs.is_some();
        let mut start = if varying {
            c.local_at(sec, 0.0)
        } else {
            uniform
        };
        for k in 0..sec.steps {
            let s0 = h * k as f64;
            if sec.rigid {
                y = rigid_step(&y, c, sec.length);
            } else if varying {
                let mid = c.local_at(sec, s0 + 0.5 * h);
                // The last step ends exactly at the section's length.
                let end_s = if k + 1 == sec.steps {
                    sec.length
                } else {
                    s0 + h
                };
                let end = c.local_at(sec, end_s);
                rk4_step(&mut y, c, [&start, &mid, &end], sec, s0, h, k, scratch);
                start = end;
            } else {
                rk4_step(&mut y, c, [&uniform; 3], sec, s0, h, k, scratch);
            }
            let node = NodeAt {
                section: i,
                step: k + 1,
                s: sec.s_start + h * (k + 1) as f64,
            };
            if at_node(node, &mut y) {
                resolve_stretch(&mut y, c);
            }
        }
    }
    y
}

/// In an Ogden section, set the carried stretch (lambda, lambda^alpha) by solving the law
/// for the state's force (as at a section start); nothing in other sections.
pub fn resolve_stretch<C: Coeff, D: StateScalar<C>>(y: &mut State<D>, c: &Coeffs<C>) {
    if let AxialCoeffs::Ogden { k_e, alpha, k_s } = &c.axial {
        y.aux = initial_stretch(y, c.p_force, *k_e, *alpha, *k_s);
    }
}

/// The state a distance `h` (0 <= h <= one step) further along the rod from `y` at `node`:
/// one RK4 step of length h (with the law at the step's start, middle and end in a varying
/// section; the exact rigid transfer in a rigid section). Used to read the state at an arc
/// length between two nodes.
pub fn advance<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    node: NodeAt,
    y: &State<D>,
    h: f64,
) -> State<D> {
    let sec = &rod.sections[node.section];
    let c = &coeffs[node.section];
    if h == 0.0 {
        *y
    } else if sec.rigid {
        rigid_step(y, c, h)
    } else {
        let s0 = (node.s - sec.s_start).max(0.0);
        let locs = [
            c.local_at(sec, s0),
            c.local_at(sec, s0 + 0.5 * h),
            c.local_at(sec, (s0 + h).min(sec.length)),
        ];
        let mut scratch = Scratch::default();
        let mut out = *y;
        rk4_step(
            &mut out,
            c,
            [&locs[0], &locs[1], &locs[2]],
            sec,
            s0,
            h,
            // Not a step of the grid: no stage of the frictional statics (which the
            // point readers that call this refuse).
            usize::MAX / 8,
            &mut scratch,
        );
        out
    }
}

/// The quadrature the integrator applies to a line load over one RK4 step of an elastic
/// section from the node state `y` at `node` (not the section's end): `g` sees the four
/// stage states, their local arc lengths and their weights h/6, h/3, h/3, h/6. The sum of
/// weight * load(stage) is exactly what the step added to n (e.g. the contact resultant of
/// `crate::statics::contact`); rigid sections and a section's end node see nothing.
pub fn step_quadrature(
    rod: &Rod,
    coeffs: &[Coeffs<f64>],
    node: NodeAt,
    y: &State<f64>,
    g: &mut dyn FnMut(&State<f64>, f64, f64),
) {
    let sec = &rod.sections[node.section];
    let c = &coeffs[node.section];
    if sec.rigid || node.step >= sec.steps {
        return;
    }
    let h = sec.length / sec.steps as f64;
    let s0 = h * node.step as f64;
    let end_s = if node.step + 1 == sec.steps {
        sec.length
    } else {
        s0 + h
    };
    let locs = if c.inputs.is_some() {
        [
            c.local_at(sec, s0),
            c.local_at(sec, s0 + 0.5 * h),
            c.local_at(sec, end_s),
        ]
    } else {
        [c.local(); 3]
    };
    let mut scratch = Scratch::default();
    // The stages of `rk4_step`, with the same arithmetic.
    let mut stage = *y;
    let at = 4 * node.step;
    g(y, s0, h / 6.0);
    let k1 = rhs(y, c, &locs[0], sec, s0, at, &mut scratch);
    stage.set_axpy(y, 0.5 * h, &k1);
    g(&stage, s0 + 0.5 * h, h / 3.0);
    let k2 = rhs(&stage, c, &locs[1], sec, s0 + 0.5 * h, at + 1, &mut scratch);
    stage.set_axpy(y, 0.5 * h, &k2);
    g(&stage, s0 + 0.5 * h, h / 3.0);
    let k3 = rhs(&stage, c, &locs[1], sec, s0 + 0.5 * h, at + 2, &mut scratch);
    stage.set_axpy(y, h, &k3);
    g(&stage, s0 + h, h / 6.0);
}
