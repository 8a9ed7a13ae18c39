//! The static Cosserat rod ODE (docs/model.md; paper 001 eqs. 1-4 with the pressure
//! moved into the constitutive law as in paper 002 eqs. 6-7) and its fixed-step RK4
//! integration from base to tip.
//!
//! State y = (r, R, n, m): centreline, rotation [d1 d2 d3] (row-major), total internal
//! force and moment in the world frame. Strains from the linear law with pressure:
//!   v = K_se^-1 (R^T n + P e3) + v*,            P = sum_k p_k A_k,
//!   u = K_bt^-1 (R^T m + sum_k p_k A_k (y_k, -x_k, 0)) + u*,
//! since n_m = n - n_p with n_p = -P d3 and m_m = m - m_p with
//! m_p = -sum_k rho_k x (p_k A_k d3). Then r' = R v, R' = R u^, n' = -f, m' = -r' x n - l.
//!
//! Everything is generic over the scalar `D` of the state (f64, or dual numbers for exact
//! Jacobians) and the scalar `C` of the coefficients (f64, or dual numbers when derivatives
//! with respect to pressures or parameters are wanted).

use crate::jet::{Coeff, RodScalar, StateScalar};
use crate::law::{ogden_from_stretch, ogden_initial_stretch, AxialTable};
use crate::rod::{inverse3, stiffness_matrices, swelling_factors_with, AxialLaw, Rod, Section};
use crate::section::CrossSection;
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
}

/// The per-solve loads, SI, world frame. The solver scales all of them (and gravity) by a
/// load factor during continuation. `tip_force` and `tip_moment` are the dead tip loads of
/// this solve: [`Loads::from_design`] takes them from the design's `[tip]`; set them to
/// override it. Gravity, line loads and the tip body always come from the design.
#[derive(Debug, Clone, PartialEq)]
pub struct Loads {
    /// Gauge pressure per channel, Pa.
    pub pressures: Vec<f64>,
    pub tip_force: [f64; 3],
    pub tip_moment: [f64; 3],
    /// Stiffness scaling sigma = (sigma_ext, sigma_bend_1, sigma_bend_2) of this solve for
    /// the sections with `law.stiffness_map` (paper 001 eq. 13); not ramped by continuation.
    pub stiffness_scale: [f64; 3],
}

impl Loads {
    /// The design's own tip loads with the given pressures.
    pub fn from_design(rod: &Rod, pressures: Vec<f64>) -> Self {
        Loads {
            pressures,
            tip_force: rod.spec.tip.force,
            tip_moment: rod.spec.tip.moment,
            stiffness_scale: [1.0; 3],
        }
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
    /// Coefficients of section `i` under `pressures` and gravity `g`, both scaled by the
    /// load factor, with the stiffness scale `sigma` (used where the section is mapped).
    pub fn build(
        rod: &Rod,
        i: usize,
        pressures: &[f64],
        g: &[f64; 3],
        factor: f64,
        sigma: &[f64; 3],
    ) -> Self {
        let knobs = SectionKnobs::of(&rod.sections[i]);
        Self::build_with(rod, i, pressures, g, factor, sigma, &knobs)
    }
}

impl<C: RodScalar> Coeffs<C> {
    /// [`Coeffs::build`] with the section's parameters given as `knobs`, in any scalar;
    /// the load factor may be a dual number too (the load derivative of
    /// `crate::statics`' continuation predictor), and the pressures f64 or the coefficients'
    /// scalar (dual pressures give the exact pressure derivatives of `crate::jacobian`).
    pub fn build_with<P: Copy>(
        rod: &Rod,
        i: usize,
        pressures: &[P],
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
        let zero = C::from(0.0);
        let swell = swelling_factors_with(rod, i, pressures, factor, knobs.c_p);
        let centroids: Vec<[C; 2]> = s
            .chambers
            .iter()
            .map(|c| {
                [
                    knobs.offset[0] + c.centroid[0],
                    knobs.offset[1] + c.centroid[1],
                ]
            })
            .collect();
        // Stiffness at this pressure (swollen chambers remove more material: A_m and I of
        // eq. 22) and these parameters, from the same formulas as the compiled rod.
        let (mut k_se, mut k_bt) = match &law.geometry {
            Some(geo) => {
                let cs = CrossSection::from_holes(
                    geo.outer_radius,
                    geo.bore_radius,
                    s.chambers
                        .iter()
                        .zip(&swell)
                        .zip(&centroids)
                        .map(|((c, w), x)| (*w * c.hole_radius, *x)),
                );
                let e = knobs.youngs_scale * geo.material.youngs_modulus;
                let g = knobs.youngs_scale * geo.material.shear_modulus;
                stiffness_matrices(&law.given, Some((&cs, e, g)), knobs.factors)
            }
            None => stiffness_matrices(&law.given, None, knobs.factors),
        };
        if law.stiffness_map {
            let [se, s1, s2] = *sigma;
            k_se[2] = k_se[2] * se;
            k_bt[0][0] = k_bt[0][0] * s1;
            k_bt[1][1] = k_bt[1][1] * s2;
            // The coupling scales with the geometric mean, which keeps K_bt positive definite.
            let c = (s1 * s2).sqrt();
            k_bt[0][1] = k_bt[0][1] * c;
            k_bt[1][0] = k_bt[1][0] * c;
        }
        let (c_se, c_bt) = if s.rigid {
            ([zero; 3], [[zero; 3]; 3])
        } else {
            (
                k_se.map(|k| k.recip()),
                inverse3(&k_bt).unwrap_or([[C::from(f64::NAN); 3]; 3]),
            )
        };
        let mut force = zero; // sum p_k A_k
        let mut mp = [zero; 3]; // sum p_k A_k (y_k, -x_k, 0)
        for ((c, w), x) in s.chambers.iter().zip(&swell).zip(&centroids) {
            let pa = *w * *w * knobs.area_scale * (factor * C::from(pressures[c.channel]) * c.area);
            force += pa;
            mp[0] += pa * x[1];
            mp[1] -= pa * x[0];
        }
        let u_shift: [C; 3] =
            std::array::from_fn(|a| c_bt[a][0] * mp[0] + c_bt[a][1] * mp[1] + c_bt[a][2] * mp[2]);
        let f = std::array::from_fn(|k| {
            factor * (knobs.mass_scale * (s.line_mass * g[k]) + s.line_force[k])
        });
        let l = std::array::from_fn(|k| factor * s.line_moment[k]);
        let axial = match &law.axial {
            AxialLaw::Linear => AxialCoeffs::Linear,
            AxialLaw::Ogden { .. } => AxialCoeffs::Ogden {
                k_e: k_se[2],
                alpha: knobs.alpha,
                k_s: k_se[0],
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
        Coeffs {
            c_se,
            c_bt,
            v_shift: [zero, zero, c_se[2] * force + 1.0],
            u_shift,
            f,
            l,
            p_force: force,
            axial,
            stretch_bending: law.stretch_bending,
        }
    }
}

impl<D: RodScalar> State<D> {
    #[inline(always)]
    fn axpy(&self, h: f64, k: &State<D>) -> State<D> {
        let mut y = *self;
        for i in 0..3 {
            y.r[i] += k.r[i] * h;
            y.n[i] += k.n[i] * h;
            y.m[i] += k.m[i] * h;
            for j in 0..3 {
                y.rot[i][j] += k.rot[i][j] * h;
            }
        }
        y.aux[0] += k.aux[0] * h;
        y.aux[1] += k.aux[1] * h;
        y
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

/// Body-frame strains (v, u) from the state through the section's law with pressure.
#[inline(always)]
pub fn strains<C: Coeff, D: StateScalar<C>>(y: &State<D>, c: &Coeffs<C>) -> ([D; 3], [D; 3]) {
    let (v, u, _) = law_strains(y, c);
    (v, u)
}

/// Strains, and for an Ogden section the rate of the carried stretch lambda (else zero).
#[inline(always)]
fn law_strains<C: Coeff, D: StateScalar<C>>(y: &State<D>, c: &Coeffs<C>) -> ([D; 3], [D; 3], D) {
    let rt = |w: &[D; 3]| -> [D; 3] {
        let mut o = [w[0] * y.rot[0][0] + w[1] * y.rot[1][0] + w[2] * y.rot[2][0]; 3];
        o[1] = w[0] * y.rot[0][1] + w[1] * y.rot[1][1] + w[2] * y.rot[2][1];
        o[2] = w[0] * y.rot[0][2] + w[1] * y.rot[1][2] + w[2] * y.rot[2][2];
        o
    };
    let nb = rt(&y.n);
    let mb = rt(&y.m);
    let mut grad = None;
    let v = match &c.axial {
        AxialCoeffs::Linear => [
            nb[0] * c.c_se[0] + c.v_shift[0],
            nb[1] * c.c_se[1] + c.v_shift[1],
            nb[2] * c.c_se[2] + c.v_shift[2],
        ],
        // Material force n_m = n + P d3 (the pressure part of the total force removed).
        AxialCoeffs::Ogden { k_e, alpha, k_s } => {
            let nm = [nb[0], nb[1], nb[2] + c.p_force];
            let (v, g) = ogden_from_stretch(*k_e, *alpha, *k_s, y.aux[0], y.aux[1], &nm);
            grad = Some(g);
            v
        }
        AxialCoeffs::Table { table, scale } => {
            let f = nb[2] + c.p_force;
            let ea = table.eval(f) * *scale;
            [
                nb[0] * c.c_se[0] + c.v_shift[0],
                nb[1] * c.c_se[1] + c.v_shift[1],
                f * ea.recip() + 1.0,
            ]
        }
    };
    let mut u = [mb[0]; 3];
    for i in 0..3 {
        u[i] = mb[0] * c.c_bt[i][0] + mb[1] * c.c_bt[i][1] + mb[2] * c.c_bt[i][2] + c.u_shift[i];
    }
    if c.stretch_bending {
        // K_bend(v3) = v3 K_bend (paper 004 eq. 29 with L_c/L_c0 = v3): bending curvatures
        // divide by v3; K_bt is block diagonal, so torsion is unaffected.
        let r = v[2].recip();
        u[0] = u[0] * r;
        u[1] = u[1] * r;
    }
    let zero = D::from(0.0);
    let dlam = match grad {
        // d n_m/ds in the body frame = R^T n' - u x (R^T n) = -R^T f - u x n_b.
        Some(g) => {
            let f = [zero + c.f[0], zero + c.f[1], zero + c.f[2]];
            let fb = rt(&f);
            let uxn = cross(&u, &nb);
            g[0] * (-fb[0] - uxn[0]) + g[1] * (-fb[1] - uxn[1]) + g[2] * (-fb[2] - uxn[2])
        }
        None => zero,
    };
    (v, u, dlam)
}

/// dy/ds for an elastic section.
#[inline(always)]
fn rhs<C: Coeff, D: StateScalar<C>>(y: &State<D>, c: &Coeffs<C>) -> State<D> {
    let (v, u, dlam) = law_strains(y, c);
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
    let dn = [zero + neg(c.f[0]), zero + neg(c.f[1]), zero + neg(c.f[2])];
    let rxn = cross(&dr, &y.n);
    let dm = [
        -rxn[0] + neg(c.l[0]),
        -rxn[1] + neg(c.l[1]),
        -rxn[2] + neg(c.l[2]),
    ];
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

/// One classical RK4 step of length h.
#[inline(always)]
pub(crate) fn rk4_step<C: Coeff, D: StateScalar<C>>(
    y: &State<D>,
    c: &Coeffs<C>,
    h: f64,
) -> State<D> {
    let k1 = rhs(y, c);
    let k2 = rhs(&y.axpy(0.5 * h, &k1), c);
    let k3 = rhs(&y.axpy(0.5 * h, &k2), c);
    let k4 = rhs(&y.axpy(h, &k3), c);
    let mut out = *y;
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
    out
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
/// v = e3, u = 0, so r' = d3 is constant and n, m integrate in closed form.
pub(crate) fn rigid_step<C: Coeff, D: StateScalar<C>>(
    y: &State<D>,
    c: &Coeffs<C>,
    len: f64,
) -> State<D> {
    let t = y.director(2);
    let mut out = *y;
    let zero = D::from(0.0);
    let f = [zero + c.f[0], zero + c.f[1], zero + c.f[2]];
    let txn = cross(&t, &y.n);
    let txf = cross(&t, &f);
    for i in 0..3 {
        out.r[i] += t[i] * len;
        out.n[i] -= f[i] * len;
        // m(L) = m0 - L t x n0 + (L^2/2) t x f - L l
        out.m[i] =
            out.m[i] - txn[i] * len + txf[i] * (0.5 * len * len) + (zero + neg(c.l[i])) * len;
    }
    out
}

/// (lambda, lambda^alpha) at the start of an Ogden section: the law solved for the material
/// force there (see `crate::law`).
pub(crate) fn initial_stretch<C: Coeff, D: StateScalar<C>>(
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
    mut visit: Option<Visitor<'_, D>>,
) -> State<D> {
    let mut y = y0;
    for (i, (sec, c)) in rod.sections.iter().zip(coeffs).enumerate() {
        if let AxialCoeffs::Ogden { k_e, alpha, k_s } = &c.axial {
            y.aux = initial_stretch(&y, c.p_force, *k_e, *alpha, *k_s);
        }
        if i == 0 {
            // The base node is visited once the first section's carried stretch is set,
            // so that its strains come from that section's law like every other node's.
            if let Some(v) = visit.as_mut() {
                v(0, 0.0, &y);
            }
        }
        let h = sec.length / sec.steps as f64;
        for k in 0..sec.steps {
            y = if sec.rigid {
                rigid_step(&y, c, sec.length)
            } else {
                rk4_step(&y, c, h)
            };
            if let Some(v) = visit.as_mut() {
                v(i, sec.s_start + h * (k + 1) as f64, &y);
            }
        }
    }
    y
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
    let mut y = y0;
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
        for k in 0..sec.steps {
            y = if sec.rigid {
                rigid_step(&y, c, sec.length)
            } else {
                rk4_step(&y, c, h)
            };
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

/// The state a distance `h` (0 <= h <= one step) further along section `i` from `y`: one
/// RK4 step of length h (the exact rigid transfer in a rigid section). Used to read the
/// state at an arc length between two nodes.
pub fn advance<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[Coeffs<C>],
    i: usize,
    y: &State<D>,
    h: f64,
) -> State<D> {
    if h == 0.0 {
        *y
    } else if rod.sections[i].rigid {
        rigid_step(y, &coeffs[i], h)
    } else {
        rk4_step(y, &coeffs[i], h)
    }
}
