//! Dynamics of the viscoelastic Cosserat rod (paper 000 eqs. 7-13; docs/model.md),
//! integrated in time with BDF-alpha and solved in space by shooting at every step (Till,
//! Aloi, Rucker, "Real-time dynamics of soft and continuum robots based on Cosserat rod
//! models", IJRR 2019).
//!
//! State along s: y = (r, R, n, m, q, w) with n, m the total internal force and moment
//! (world frame) and q, w the linear and angular velocity in the body frame. Every time
//! derivative X_t of X in {v, u, q, w} is replaced by the BDF-alpha formula
//!   X_t(t_i) = c0 X_i + X_h,   X_h = c1 X_{i-1} + c2 X_{i-2} + d1 X_t(t_{i-1}),
//! which turns the PDEs into an ODE in s at each step:
//!   material law with Kelvin-Voigt damping (paper 000 eq. 8) and pressure (docs/model.md):
//!     R^T n + P e3 = K_se (v - v*) + B_se v_t  =>  v = (K_se + c0 B_se)^-1 (R^T n + K_se v_p - B_se v_h)
//!     R^T m + M_p  = K_bt (u - u*) + B_bt u_t  =>  u = (K_bt + c0 B_bt)^-1 (R^T m + K_bt u_p - B_bt u_h)
//!   (v_p = v* + K_se^-1 P e3 and u_p = u* + K_bt^-1 M_p are the static law's shifted strains),
//!   r' = R v,  R' = R u^,
//!   q' = v_t + w x v - u x q,  w' = u_t + w x u          (compatibility, paper 000 eq. 13),
//!   n' = rho A R (q_t + w x q) - f,                      (linear momentum, eq. 7)
//!   m' = R (rho J w_t + w x rho J w) - r' x n - l        (angular momentum, eq. 7).
//! The base is clamped (q = w = 0); the six unknowns n(0), m(0) are found by Newton with the
//! exact Jacobian (dual numbers) so that the tip balances the tip body's inertia and the
//! dead tip loads. RK4 in s evaluates each step's right-hand side at four stages; each stage
//! keeps its own history slot, so the space discretisation is the static solver's.
//!
//! alpha = -0.5 is the trapezoidal rule of paper 000 (no numerical damping); alpha = 0 is
//! BDF2; the default -0.2 damps unresolved high-frequency modes a little and is second order.

use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};
use crate::ode::{reproject, Coeff, Coeffs, Loads, StateScalar};
use crate::rod::{inverse3, AxialLaw, Rod};
use crate::spec::DynamicsSpec;
use crate::statics::{self, SolverOptions};
use nalgebra::{SMatrix, SVector};

/// v, u, q, w (body frame) at one stage point.
pub const FIELDS: usize = 12;

type Mat6 = SMatrix<f64, 6, 6>;
type Vec6 = SVector<f64, 6>;

/// Settings of the time integrator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynOptions {
    /// Time step, s.
    pub dt: f64,
    /// BDF-alpha parameter in [-0.5, 0]: -0.5 trapezoidal, 0 BDF2.
    pub alpha: f64,
    /// Tolerance on the scaled shooting residual at every step.
    pub tol: f64,
    /// Newton iterations per step.
    pub max_iter: usize,
}

impl Default for DynOptions {
    fn default() -> Self {
        DynOptions {
            dt: 2e-3,
            alpha: -0.2,
            tol: 1e-9,
            max_iter: 25,
        }
    }
}

impl DynOptions {
    pub fn validate(&self) -> Result<()> {
        if !(self.dt.is_finite() && self.dt > 0.0 && self.dt <= 1.0) {
            return Err(SoftrodError::invalid("dt", self.dt, "must be in (0, 1] s"));
        }
        if !(self.alpha.is_finite() && (-0.5..=0.0).contains(&self.alpha)) {
            return Err(SoftrodError::invalid(
                "alpha",
                self.alpha,
                "the BDF-alpha parameter must lie in [-0.5, 0] (-0.5 trapezoidal, 0 BDF2)",
            ));
        }
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol < 1.0) {
            return Err(SoftrodError::invalid("tol", self.tol, "must be in (0, 1)"));
        }
        if self.max_iter == 0 {
            return Err(SoftrodError::invalid("max_iter", 0, "must be >= 1"));
        }
        Ok(())
    }
}

/// BDF-alpha coefficients (Till et al. 2019, eq. 7).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bdf {
    c0: f64,
    c1: f64,
    c2: f64,
    d1: f64,
}

impl Bdf {
    fn new(dt: f64, alpha: f64) -> Self {
        Bdf {
            c0: (1.5 + alpha) / (dt * (1.0 + alpha)),
            c1: -2.0 / dt,
            c2: (0.5 + alpha) / (dt * (1.0 + alpha)),
            d1: alpha / (1.0 + alpha),
        }
    }
}

/// Inertia and damping of one section, compiled once per rod.
#[derive(Debug, Clone, PartialEq)]
pub struct SectionInertia {
    /// rho A, kg/m.
    pub rho_a: f64,
    /// Mass moments of inertia per length (rho I_11, rho I_22, rho J), kg m.
    pub rho_j: [f64; 3],
    /// Given damping matrices (diagonals of B_se, B_bt), else B = tau K.
    pub damping: Option<([f64; 3], [f64; 3])>,
}

/// Rotary inertia per unit length of section `i`: given, else rho A times the squared radii
/// of gyration I/A of its material area, else (stiffnesses given directly) rho A EI/EA, the
/// same ratio for a homogeneous material. Rigid parts without geometry get none.
pub fn section_inertia(rod: &Rod, i: usize) -> SectionInertia {
    let spec = &rod.spec.sections[i];
    let sec = &rod.sections[i];
    let rho_a = sec.line_mass;
    let rho_j = spec.rotary_inertia.unwrap_or_else(|| {
        if let Some(ro) = spec.outer_radius {
            let cs = crate::section::CrossSection::from_spec(spec, ro);
            let (a1, a2) = (cs.i11 / cs.area, cs.i22 / cs.area);
            [rho_a * a1, rho_a * a2, rho_a * (a1 + a2)]
        } else if !sec.rigid {
            let st = spec.given_stiffness();
            match (st.ea, st.ei1, st.ei2) {
                (Some(ea), Some(e1), Some(e2)) => {
                    [rho_a * e1 / ea, rho_a * e2 / ea, rho_a * (e1 + e2) / ea]
                }
                _ => [0.0; 3],
            }
        } else {
            [0.0; 3]
        }
    });
    SectionInertia {
        rho_a,
        rho_j,
        damping: spec.damping_se.zip(spec.damping_bt),
    }
}

/// Per-step coefficients of one section (scalar C: f64, or dual numbers for derivatives).
#[derive(Debug, Clone, PartialEq)]
pub struct DynCoeffs<C> {
    rigid: bool,
    /// (K_se + c0 B_se)^-1 (diagonal).
    a_se: [C; 3],
    /// K_se v_p.
    g_se: [C; 3],
    b_se: [C; 3],
    /// (K_bt + c0 B_bt)^-1.
    a_bt: [[C; 3]; 3],
    /// K_bt u_p.
    g_bt: [C; 3],
    b_bt: [[C; 3]; 3],
    k_se: [C; 3],
    k_bt: [[C; 3]; 3],
    v_p: [C; 3],
    u_p: [C; 3],
    rho_a: f64,
    rho_j: [f64; 3],
    /// Line force and moment (world), weight included.
    f: [C; 3],
    l: [C; 3],
    c0: f64,
}

impl<C: Coeff> DynCoeffs<C> {
    /// From the static law's coefficients `c` (which carry the pressure), the damping time
    /// `tau` and the BDF factor c0.
    fn build(c: &Coeffs<C>, inertia: &SectionInertia, rigid: bool, tau: C, c0: f64) -> Self {
        let zero = C::from(0.0);
        let z3 = [zero; 3];
        let z33 = [[zero; 3]; 3];
        let mut out = DynCoeffs {
            rigid,
            a_se: z3,
            g_se: z3,
            b_se: z3,
            a_bt: z33,
            g_bt: z3,
            b_bt: z33,
            k_se: z3,
            k_bt: z33,
            v_p: c.v_shift,
            u_p: c.u_shift,
            rho_a: inertia.rho_a,
            rho_j: inertia.rho_j,
            f: c.f,
            l: c.l,
            c0,
        };
        if rigid {
            return out;
        }
        let k_se = c.c_se.map(|x| x.recip());
        let k_bt = inverse3(&c.c_bt).unwrap_or([[C::from(f64::NAN); 3]; 3]);
        let (b_se, b_bt) = match inertia.damping {
            Some((se, bt)) => (
                se.map(C::from),
                std::array::from_fn(|i| {
                    std::array::from_fn(|j| C::from(if i == j { bt[i] } else { 0.0 }))
                }),
            ),
            None => (k_se.map(|k| k * tau), k_bt.map(|row| row.map(|k| k * tau))),
        };
        out.a_se = std::array::from_fn(|k| (k_se[k] + b_se[k] * c0).recip());
        let eff: [[C; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| k_bt[i][j] + b_bt[i][j] * c0));
        out.a_bt = inverse3(&eff).unwrap_or([[C::from(f64::NAN); 3]; 3]);
        out.g_se = std::array::from_fn(|k| k_se[k] * c.v_shift[k]);
        out.g_bt = std::array::from_fn(|i| {
            k_bt[i][0] * c.u_shift[0] + k_bt[i][1] * c.u_shift[1] + k_bt[i][2] * c.u_shift[2]
        });
        out.b_se = b_se;
        out.b_bt = b_bt;
        out.k_se = k_se;
        out.k_bt = k_bt;
        out
    }
}

/// Rod state at one arc length during a time step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynState<D> {
    pub r: [D; 3],
    pub rot: [[D; 3]; 3],
    pub n: [D; 3],
    pub m: [D; 3],
    /// Linear velocity, body frame, m/s.
    pub q: [D; 3],
    /// Angular velocity, body frame, rad/s.
    pub w: [D; 3],
}

impl<D: RodScalar> DynState<D> {
    #[inline(always)]
    fn axpy(&self, h: f64, k: &DynState<D>) -> Self {
        let mut y = *self;
        for i in 0..3 {
            y.r[i] += k.r[i] * h;
            y.n[i] += k.n[i] * h;
            y.m[i] += k.m[i] * h;
            y.q[i] += k.q[i] * h;
            y.w[i] += k.w[i] * h;
            for j in 0..3 {
                y.rot[i][j] += k.rot[i][j] * h;
            }
        }
        y
    }

    pub fn re(&self) -> DynState<f64> {
        DynState {
            r: self.r.map(|x| x.value()),
            rot: self.rot.map(|row| row.map(|x| x.value())),
            n: self.n.map(|x| x.value()),
            m: self.m.map(|x| x.value()),
            q: self.q.map(|x| x.value()),
            w: self.w.map(|x| x.value()),
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

#[inline(always)]
fn rot_mul<D: RodScalar>(rot: &[[D; 3]; 3], x: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| rot[i][0] * x[0] + rot[i][1] * x[1] + rot[i][2] * x[2])
}

#[inline(always)]
fn rot_t_mul<D: RodScalar>(rot: &[[D; 3]; 3], x: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| rot[0][i] * x[0] + rot[1][i] * x[1] + rot[2][i] * x[2])
}

/// dy/ds and the stage's fields (v, u, q, w), given the history terms `h` of this stage.
#[inline(always)]
fn rhs<C: Coeff, D: StateScalar<C>>(
    y: &DynState<D>,
    c: &DynCoeffs<C>,
    h: &[C; FIELDS],
) -> (DynState<D>, [D; FIELDS]) {
    let zero = D::from(0.0);
    let c0 = c.c0;
    let (v, u, vt, ut) = if c.rigid {
        let v = [zero, zero, D::from(1.0)];
        (v, [zero; 3], [zero; 3], [zero; 3])
    } else {
        let nb = rot_t_mul(&y.rot, &y.n);
        let mb = rot_t_mul(&y.rot, &y.m);
        let v: [D; 3] =
            std::array::from_fn(|k| (nb[k] + (c.g_se[k] - c.b_se[k] * h[k])) * c.a_se[k]);
        let t: [C; 3] = std::array::from_fn(|i| {
            c.g_bt[i] - (c.b_bt[i][0] * h[3] + c.b_bt[i][1] * h[4] + c.b_bt[i][2] * h[5])
        });
        let tm: [D; 3] = std::array::from_fn(|k| mb[k] + t[k]);
        let u: [D; 3] = std::array::from_fn(|i| {
            tm[0] * c.a_bt[i][0] + tm[1] * c.a_bt[i][1] + tm[2] * c.a_bt[i][2]
        });
        let vt: [D; 3] = std::array::from_fn(|k| v[k] * c0 + h[k]);
        let ut: [D; 3] = std::array::from_fn(|k| u[k] * c0 + h[3 + k]);
        (v, u, vt, ut)
    };
    let qt: [D; 3] = std::array::from_fn(|k| y.q[k] * c0 + h[6 + k]);
    let wt: [D; 3] = std::array::from_fn(|k| y.w[k] * c0 + h[9 + k]);
    let dr = rot_mul(&y.rot, &v);
    let rot = &y.rot;
    let mut drot = *rot;
    for i in 0..3 {
        let (a, b, e) = (rot[i][0], rot[i][1], rot[i][2]);
        drot[i][0] = b * u[2] - e * u[1];
        drot[i][1] = e * u[0] - a * u[2];
        drot[i][2] = a * u[1] - b * u[0];
    }
    let wxv = cross(&y.w, &v);
    let uxq = cross(&u, &y.q);
    let wxu = cross(&y.w, &u);
    let dq: [D; 3] = std::array::from_fn(|k| vt[k] + wxv[k] - uxq[k]);
    let dw: [D; 3] = std::array::from_fn(|k| ut[k] + wxu[k]);
    let wxq = cross(&y.w, &y.q);
    let acc: [D; 3] = std::array::from_fn(|k| (wxq[k] + qt[k]) * c.rho_a);
    let acc_w = rot_mul(&y.rot, &acc);
    let dn: [D; 3] = std::array::from_fn(|k| acc_w[k] + (-c.f[k]));
    let jw: [D; 3] = std::array::from_fn(|k| y.w[k] * c.rho_j[k]);
    let wxjw = cross(&y.w, &jw);
    let ang: [D; 3] = std::array::from_fn(|k| wt[k] * c.rho_j[k] + wxjw[k]);
    let ang_w = rot_mul(&y.rot, &ang);
    let rxn = cross(&dr, &y.n);
    let dm: [D; 3] = std::array::from_fn(|k| ang_w[k] - rxn[k] + (-c.l[k]));
    let fields = [
        v[0], v[1], v[2], u[0], u[1], u[2], y.q[0], y.q[1], y.q[2], y.w[0], y.w[1], y.w[2],
    ];
    (
        DynState {
            r: dr,
            rot: drot,
            n: dn,
            m: dm,
            q: dq,
            w: dw,
        },
        fields,
    )
}

/// What a sweep keeps: per stage slot the fields and the position (for histories and the
/// energy), and the centreline at every node (for shapes).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Record {
    pub fields: Vec<[f64; FIELDS]>,
    pub position: Vec<[f64; 3]>,
    pub nodes: Vec<[f64; 3]>,
    pub node_s: Vec<f64>,
}

impl Record {
    fn clear(&mut self) {
        self.fields.clear();
        self.position.clear();
        self.nodes.clear();
        self.node_s.clear();
    }
}

/// Integrate base to tip through every section with RK4, each stage using its own history
/// slot of `hist`; returns the tip state.
fn sweep<C: Coeff, D: StateScalar<C>>(
    rod: &Rod,
    coeffs: &[DynCoeffs<C>],
    hist: &[[C; FIELDS]],
    y0: DynState<D>,
    mut rec: Option<&mut Record>,
) -> DynState<D> {
    let mut y = y0;
    let mut slot = 0;
    if let Some(r) = rec.as_mut() {
        r.clear();
        r.nodes.push(y.r.map(|x| x.value()));
        r.node_s.push(0.0);
    }
    for (sec, c) in rod.sections.iter().zip(coeffs) {
        // A rigid part is one RK4 step: along it the integrands are polynomials in s of
        // degree <= 3 (q is linear), which RK4 integrates exactly.
        let h = sec.length / sec.steps as f64;
        for k in 0..sec.steps {
            let (k1, f1) = rhs(&y, c, &hist[slot]);
            let y2 = y.axpy(0.5 * h, &k1);
            let (k2, f2) = rhs(&y2, c, &hist[slot + 1]);
            let y3 = y.axpy(0.5 * h, &k2);
            let (k3, f3) = rhs(&y3, c, &hist[slot + 2]);
            let y4 = y.axpy(h, &k3);
            let (k4, f4) = rhs(&y4, c, &hist[slot + 3]);
            if let Some(r) = rec.as_mut() {
                for (f, ys) in [(f1, &y), (f2, &y2), (f3, &y3), (f4, &y4)] {
                    r.fields.push(f.map(|x| x.value()));
                    r.position.push(ys.r.map(|x| x.value()));
                }
            }
            slot += 4;
            let w = h / 6.0;
            let mut out = y;
            for i in 0..3 {
                out.r[i] += (k1.r[i] + (k2.r[i] + k3.r[i]) * 2.0 + k4.r[i]) * w;
                out.n[i] += (k1.n[i] + (k2.n[i] + k3.n[i]) * 2.0 + k4.n[i]) * w;
                out.m[i] += (k1.m[i] + (k2.m[i] + k3.m[i]) * 2.0 + k4.m[i]) * w;
                out.q[i] += (k1.q[i] + (k2.q[i] + k3.q[i]) * 2.0 + k4.q[i]) * w;
                out.w[i] += (k1.w[i] + (k2.w[i] + k3.w[i]) * 2.0 + k4.w[i]) * w;
                for j in 0..3 {
                    out.rot[i][j] +=
                        (k1.rot[i][j] + (k2.rot[i][j] + k3.rot[i][j]) * 2.0 + k4.rot[i][j]) * w;
                }
            }
            out.rot = reproject(&out.rot);
            y = out;
            if let Some(r) = rec.as_mut() {
                r.nodes.push(y.r.map(|x| x.value()));
                r.node_s.push(sec.s_start + h * (k + 1) as f64);
            }
        }
    }
    y
}

/// Rigid tip body and dead tip loads.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TipBody {
    mass: f64,
    com: [f64; 3],
    inertia: [f64; 3],
    force: [f64; 3],
    moment: [f64; 3],
}

/// Everything one time step's shooting problem needs besides the histories.
struct StepProblem<'a> {
    rod: &'a Rod,
    coeffs: Vec<DynCoeffs<f64>>,
    tip: TipBody,
    gravity: [f64; 3],
    c0: f64,
    fs: f64,
    ms: f64,
}

impl StepProblem<'_> {
    fn base<D: RodScalar>(&self, x: &[D; 6]) -> DynState<D> {
        let c = |v: f64| D::from(v);
        DynState {
            r: self.rod.base_position.map(c),
            rot: self.rod.base_rotation.map(|row| row.map(c)),
            n: [x[0] * self.fs, x[1] * self.fs, x[2] * self.fs],
            m: [x[3] * self.ms, x[4] * self.ms, x[5] * self.ms],
            q: [c(0.0); 3],
            w: [c(0.0); 3],
        }
    }

    /// Tip balance: n(L) = F + m_t (g - a_c), m(L) = M + c_w x m_t (g - a_c) - R (J w_t +
    /// w x J w), with a_c the acceleration of the tip body's centre of mass; scaled.
    fn residual<D: RodScalar>(&self, y: &DynState<D>, th: &[f64; FIELDS]) -> [D; 6] {
        let t = &self.tip;
        let c0 = self.c0;
        let qt: [D; 3] = std::array::from_fn(|k| y.q[k] * c0 + th[6 + k]);
        let wt: [D; 3] = std::array::from_fn(|k| y.w[k] * c0 + th[9 + k]);
        let com = t.com.map(D::from);
        let wxq = cross(&y.w, &y.q);
        let wtxc = cross(&wt, &com);
        let wxc = cross(&y.w, &com);
        let wxwxc = cross(&y.w, &wxc);
        let ab: [D; 3] = std::array::from_fn(|k| qt[k] + wxq[k] + wtxc[k] + wxwxc[k]);
        let a = rot_mul(&y.rot, &ab);
        let body: [D; 3] = std::array::from_fn(|k| (-a[k] + self.gravity[k]) * t.mass);
        let cw = rot_mul(&y.rot, &com);
        let cxb = cross(&cw, &body);
        let jw: [D; 3] = std::array::from_fn(|k| y.w[k] * t.inertia[k]);
        let wxjw = cross(&y.w, &jw);
        let torque: [D; 3] = std::array::from_fn(|k| wt[k] * t.inertia[k] + wxjw[k]);
        let torque_w = rot_mul(&y.rot, &torque);
        std::array::from_fn(|k| {
            if k < 3 {
                (y.n[k] - body[k] - t.force[k]) * (1.0 / self.fs)
            } else {
                let j = k - 3;
                (y.m[j] - cxb[j] + torque_w[j] - t.moment[j]) * (1.0 / self.ms)
            }
        })
    }

    fn eval(
        &self,
        hist: &[[f64; FIELDS]],
        x: &[f64; 6],
        rec: Option<&mut Record>,
    ) -> ([f64; 6], DynState<f64>) {
        let tip = sweep(self.rod, &self.coeffs, hist, self.base(x), rec);
        (self.residual(&tip, hist.last().expect("tip slot")), tip)
    }

    fn jacobian(&self, hist: &[[f64; FIELDS]], x: &[f64; 6]) -> Mat6 {
        let xd: [Jet<6>; 6] = std::array::from_fn(|i| Jet::variable(x[i], i));
        let tip = sweep(self.rod, &self.coeffs, hist, self.base(&xd), None);
        let r = self.residual(&tip, hist.last().expect("tip slot"));
        Mat6::from_fn(|i, j| r[i].eps[j])
    }
}

/// The shooting problem of one step at chamber pressures `pressures` with BDF factor c0.
fn step_problem<'a>(
    rod: &'a Rod,
    inertia: &[SectionInertia],
    pressures: &[f64],
    c0: f64,
) -> StepProblem<'a> {
    let sigma = [1.0; 3];
    let coeffs = (0..rod.sections.len())
        .map(|i| {
            let c = Coeffs::build(rod, i, pressures, &[], &rod.gravity, 1.0, &sigma);
            DynCoeffs::build(
                &c,
                &inertia[i],
                rod.sections[i].rigid,
                rod.spec.dynamics.damping_time,
                c0,
            )
        })
        .collect();
    let t = &rod.spec.tip;
    StepProblem {
        rod,
        coeffs,
        tip: TipBody {
            mass: t.mass,
            com: t.com_offset,
            inertia: t.inertia,
            force: t.force,
            moment: t.moment,
        },
        gravity: rod.gravity,
        c0,
        fs: rod.force_scale,
        ms: rod.force_scale * rod.length,
    }
}

/// The record of the straight reference shape at rest: v = e3, u = 0, q = w = 0.
fn straight_record(rod: &Rod) -> Record {
    let mut rec = Record::default();
    let base = rod.base_position;
    let t: [f64; 3] = std::array::from_fn(|k| rod.base_rotation[k][2]);
    let at = |s: f64| -> [f64; 3] { std::array::from_fn(|k| base[k] + t[k] * s) };
    let mut f = [0.0; FIELDS];
    f[2] = 1.0;
    rec.nodes.push(at(0.0));
    rec.node_s.push(0.0);
    for sec in &rod.sections {
        let h = sec.length / sec.steps as f64;
        for k in 0..sec.steps {
            let s0 = sec.s_start + h * k as f64;
            for ds in [0.0, 0.5 * h, 0.5 * h, h] {
                rec.fields.push(f);
                rec.position.push(at(s0 + ds));
            }
            rec.nodes.push(at(s0 + h));
            rec.node_s.push(s0 + h);
        }
    }
    rec
}

fn inf_norm(r: &[f64]) -> f64 {
    r.iter().fold(
        0.0,
        |a: f64, x| if x.is_nan() { f64::NAN } else { a.max(x.abs()) },
    )
}

/// History of one stage slot: X_{i-1}, X_{i-2} and X_t(t_{i-1}).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Slot {
    x1: [f64; FIELDS],
    x2: [f64; FIELDS],
    xt: [f64; FIELDS],
}

/// How a simulation starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Initial {
    /// At rest in static equilibrium under the first pressures (and gravity, tip loads).
    Static,
    /// At rest in the straight reference shape (v = e3, u = 0), released at t = 0.
    Straight,
}

/// Counters of a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DynStats {
    pub steps: usize,
    pub newton_iterations: usize,
    pub jacobians: usize,
}

/// Advance chamber pressures by one step of dt towards the commands: a first-order lag with
/// time constant T (exact for a command held over the step), then the rate limit (paper 000
/// Sec. III-A). The PCC model uses the same supply, so both models see the same pressures.
pub fn advance_supply(dy: &DynamicsSpec, dt: f64, pressures: &mut [f64], command: &[f64]) {
    for (p, &c) in pressures.iter_mut().zip(command) {
        let target = if dy.pressure_time_constant > 0.0 {
            c + (*p - c) * (-dt / dy.pressure_time_constant).exp()
        } else {
            c
        };
        let step = match dy.pressure_rate_limit {
            Some(rate) => (target - *p).clamp(-rate * dt, rate * dt),
            None => target - *p,
        };
        *p += step;
    }
}

/// A running simulation: the rod, the time, the chamber pressures and the histories.
/// Clone it to branch a simulation from its current state.
#[derive(Debug, Clone)]
pub struct Simulator {
    rod: Rod,
    inertia: Vec<SectionInertia>,
    opts: DynOptions,
    bdf: Bdf,
    time: f64,
    /// Chamber pressures now, Pa (after the supply lag and rate limit).
    pressures: Vec<f64>,
    x: [f64; 6],
    x_prev: [f64; 6],
    slots: Vec<Slot>,
    jac: Option<nalgebra::LU<f64, nalgebra::Const<6>, nalgebra::Const<6>>>,
    record: Record,
    tip: DynState<f64>,
    coeffs: Vec<DynCoeffs<f64>>,
    /// Dead tip loads now (world): the design's, until changed with `set_tip_loads`.
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    /// The tip loads of the last step taken (the start of a ramp).
    step_tip: ([f64; 3], [f64; 3]),
    pub stats: DynStats,
}

/// Refuse the statics-only features of a design (follower loads, reference shapes, tapered
/// sections, tendons): `model` (the dynamics, its linearisation, the PCC model) does not
/// carry them yet.
pub(crate) fn check_statics_only(rod: &Rod, model: &str) -> Result<()> {
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
    if rod.spec.tip.frame == crate::spec::Frame::Body {
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
    {
        return Err(statics_only(
            format!("loads[{k}].frame"),
            "a follower line load",
        ));
    }
    for (i, s) in rod.sections.iter().enumerate() {
        if !s.reference.is_straight() {
            return Err(statics_only(
                format!("sections[{i}].reference"),
                "a reference shape (precurvature or pre-strain)",
            ));
        }
        if s.tapered {
            return Err(statics_only(
                format!("sections[{i}].outer_radius_end"),
                "a tapered section",
            ));
        }
        if !s.tendons.is_empty() {
            return Err(statics_only(format!("sections[{i}].tendons"), "tendons"));
        }
    }
    Ok(())
}

/// Check that every section's law has a dynamic counterpart here.
fn check_dynamic_laws(rod: &Rod) -> Result<()> {
    check_statics_only(rod, "the dynamics")?;
    for (i, s) in rod.sections.iter().enumerate() {
        let what = if !matches!(s.law.axial, AxialLaw::Linear) {
            Some("a nonlinear axial law (ogden/table)")
        } else if s.law.stretch_bending {
            Some("stretch-dependent bending (partition / stretch_bending)")
        } else if s.law.stiffness_map {
            Some("a pressure-dependent stiffness map")
        } else {
            None
        };
        if let Some(what) = what {
            return Err(SoftrodError::invalid(
                format!("sections[{i}].law"),
                what,
                "dynamics supports the linear law (with chamber swelling and correction factors); use solve_statics for this section's law",
            ));
        }
    }
    Ok(())
}

impl Simulator {
    /// Start a simulation of `rod` at t = 0 with chamber pressures `pressures` (Pa).
    pub fn new(rod: Rod, pressures: &[f64], initial: Initial, opts: DynOptions) -> Result<Self> {
        opts.validate()?;
        check_dynamic_laws(&rod)?;
        rod.check_loads(pressures, &[1.0; 3])?;
        let inertia: Vec<SectionInertia> = (0..rod.sections.len())
            .map(|i| section_inertia(&rod, i))
            .collect();
        let n_slots: usize = rod.sections.iter().map(|s| 4 * s.steps).sum::<usize>() + 1;
        let mut sim = Simulator {
            inertia,
            opts,
            bdf: Bdf::new(opts.dt, opts.alpha),
            time: 0.0,
            pressures: pressures.to_vec(),
            x: [0.0; 6],
            x_prev: [0.0; 6],
            slots: vec![
                Slot {
                    x1: [0.0; FIELDS],
                    x2: [0.0; FIELDS],
                    xt: [0.0; FIELDS],
                };
                n_slots
            ],
            jac: None,
            record: Record::default(),
            tip: DynState {
                r: [0.0; 3],
                rot: [[0.0; 3]; 3],
                n: [0.0; 3],
                m: [0.0; 3],
                q: [0.0; 3],
                w: [0.0; 3],
            },
            coeffs: vec![],
            tip_force: rod.spec.tip.force,
            tip_moment: rod.spec.tip.moment,
            step_tip: (rod.spec.tip.force, rod.spec.tip.moment),
            stats: DynStats::default(),
            rod,
        };
        sim.start(initial)?;
        Ok(sim)
    }

    fn start(&mut self, initial: Initial) -> Result<()> {
        let zero = [0.0; FIELDS];
        match initial {
            Initial::Static => {
                // The static solver (with continuation) gives the base wrench. One shooting
                // solve of the dynamic equations at rest (c0 = 0, no history) then fills
                // every stage slot consistently.
                let loads = Loads::from_design(&self.rod, self.pressures.clone());
                let sol = statics::solve(&self.rod, &loads, None, &SolverOptions::default())?;
                let p = step_problem(&self.rod, &self.inertia, &self.pressures, 0.0);
                let x0: [f64; 6] = std::array::from_fn(|k| {
                    if k < 3 {
                        sol.base_force[k] / p.fs
                    } else {
                        sol.base_moment[k - 3] / p.ms
                    }
                });
                let hist = vec![zero; self.slots.len()];
                let mut rec = Record::default();
                let (x, tip, _) =
                    newton(&p, &hist, x0, None, &self.opts, &mut rec, &mut self.stats).map_err(
                        |(it, res)| SoftrodError::NotConverged {
                            iterations: it,
                            residual: res,
                            load_factor: 1.0,
                            reason:
                                "the initial static state did not solve as a dynamic state at rest"
                                    .into(),
                        },
                    )?;
                self.x = x;
                self.x_prev = x;
                self.tip = tip;
                let n = self.slots.len();
                for (slot, f) in self.slots[..n - 1].iter_mut().zip(&rec.fields) {
                    *slot = Slot {
                        x1: *f,
                        x2: *f,
                        xt: zero,
                    };
                }
                self.record = rec;
            }
            Initial::Straight => {
                let rec = straight_record(&self.rod);
                let n = self.slots.len();
                for (slot, f) in self.slots[..n - 1].iter_mut().zip(&rec.fields) {
                    *slot = Slot {
                        x1: *f,
                        x2: *f,
                        xt: zero,
                    };
                }
                let end = *rec.nodes.last().expect("at least the base node");
                self.tip = DynState {
                    r: end,
                    rot: self.rod.base_rotation,
                    n: [0.0; 3],
                    m: [0.0; 3],
                    q: [0.0; 3],
                    w: [0.0; 3],
                };
                self.record = rec;
                self.x = [0.0; 6];
                self.x_prev = self.x;
            }
        }
        self.coeffs = step_problem(&self.rod, &self.inertia, &self.pressures, self.bdf.c0).coeffs;
        Ok(())
    }

    /// Advance the chamber pressures by one step towards the commands.
    fn advance_pressures(&mut self, command: &[f64]) {
        advance_supply(
            &self.rod.spec.dynamics,
            self.opts.dt,
            &mut self.pressures,
            command,
        );
    }

    /// One time step with the commanded pressures `command` (Pa) at the new time.
    pub fn step(&mut self, command: &[f64]) -> Result<()> {
        crate::spec::validate_pressures(command, self.rod.n_channels)
            .map_err(|e| rename_pressure_error(e, "command"))?;
        let saved = self.pressures.clone();
        self.advance_pressures(command);
        if let Err(e) = self.rod.check_loads(&self.pressures, &[1.0; 3]) {
            self.pressures = saved;
            return Err(e);
        }
        let bdf = self.bdf;
        let hist: Vec<[f64; FIELDS]> = self
            .slots
            .iter()
            .map(|s| {
                std::array::from_fn(|k| bdf.c1 * s.x1[k] + bdf.c2 * s.x2[k] + bdf.d1 * s.xt[k])
            })
            .collect();
        // Linear extrapolation of the unknowns from the last two steps.
        let guess: [f64; 6] = std::array::from_fn(|k| 2.0 * self.x[k] - self.x_prev[k]);
        let mut rec = std::mem::take(&mut self.record);
        let level = Level {
            rod: &self.rod,
            inertia: &self.inertia,
            c0: bdf.c0,
            hist: &hist,
            opts: &self.opts,
            from: (&saved, self.step_tip),
            to: (&self.pressures, (self.tip_force, self.tip_moment)),
        };
        let mut result = level.solve(1.0, guess, self.jac.take(), &mut rec, &mut self.stats);
        if result.is_err() {
            // A sudden change of the inputs (a pressure step) can put the new state out of
            // Newton's reach: ramp the step's inputs from the last step's values to the new
            // ones (the equations at ramp 1 are the step's own).
            result = level.ramp(self.x, &mut rec, &mut self.stats);
        }
        let (x, tip, lu) = match result {
            Ok(v) => v,
            Err((it, res)) => {
                self.pressures = saved;
                self.record = rec;
                return Err(SoftrodError::NotConverged {
                    iterations: it,
                    residual: res,
                    load_factor: 1.0,
                    reason: format!(
                        "dynamic step from t = {:.6} s to {:.6} s did not converge (dt = {} s), also with the step's inputs ramped; a larger dt, more damping or fewer steps per section improves the shooting problem's conditioning",
                        self.time,
                        self.time + self.opts.dt,
                        self.opts.dt
                    ),
                });
            }
        };
        self.step_tip = (self.tip_force, self.tip_moment);
        self.coeffs = step_problem(&self.rod, &self.inertia, &self.pressures, bdf.c0).coeffs;
        // Shift the histories: X_t(t_i) = c0 X_i + X_h.
        for ((slot, f), h) in self.slots.iter_mut().zip(&rec.fields).zip(&hist) {
            let xt: [f64; FIELDS] = std::array::from_fn(|k| bdf.c0 * f[k] + h[k]);
            *slot = Slot {
                x1: *f,
                x2: slot.x1,
                xt,
            };
        }
        let tip_slot = self.slots.len() - 1;
        let th = &hist[tip_slot];
        let mut tf = [0.0; FIELDS];
        tf[6..9].copy_from_slice(&tip.q);
        tf[9..12].copy_from_slice(&tip.w);
        let xt: [f64; FIELDS] = std::array::from_fn(|k| bdf.c0 * tf[k] + th[k]);
        let old = self.slots[tip_slot].x1;
        self.slots[tip_slot] = Slot {
            x1: tf,
            x2: old,
            xt,
        };
        self.record = rec;
        self.x_prev = self.x;
        self.x = x;
        self.tip = tip;
        self.jac = lu;
        self.stats.steps += 1;
        // Steps times dt, not a running sum: no round-off drift of the clock.
        self.time = self.stats.steps as f64 * self.opts.dt;
        Ok(())
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    /// The next step's scaled shooting residual and its exact Jacobian at unknowns `x`, at
    /// the current pressures (for tests against finite differences).
    pub fn step_residual_and_jacobian(&self, x: &[f64; 6]) -> ([f64; 6], [[f64; 6]; 6]) {
        let bdf = self.bdf;
        let hist: Vec<[f64; FIELDS]> = self
            .slots
            .iter()
            .map(|s| {
                std::array::from_fn(|k| bdf.c1 * s.x1[k] + bdf.c2 * s.x2[k] + bdf.d1 * s.xt[k])
            })
            .collect();
        let mut p = step_problem(&self.rod, &self.inertia, &self.pressures, bdf.c0);
        p.tip.force = self.tip_force;
        p.tip.moment = self.tip_moment;
        let (r, _) = p.eval(&hist, x, None);
        let j = p.jacobian(&hist, x);
        (
            r,
            std::array::from_fn(|i| std::array::from_fn(|k| j[(i, k)])),
        )
    }

    /// The scaled shooting unknowns of the last step (n(0)/F_s, m(0)/(F_s L)).
    pub fn unknowns(&self) -> [f64; 6] {
        self.x
    }
    /// Change the dead tip force and moment (world, N and N m) from the next step on.
    pub fn set_tip_loads(&mut self, force: [f64; 3], moment: [f64; 3]) -> Result<()> {
        for (name, v) in [("tip_force", &force), ("tip_moment", &moment)] {
            for (i, x) in v.iter().enumerate() {
                if !x.is_finite() {
                    return Err(SoftrodError::invalid(
                        format!("{name}[{i}]"),
                        x,
                        "must be a finite number",
                    ));
                }
            }
        }
        self.tip_force = force;
        self.tip_moment = moment;
        Ok(())
    }
    pub fn dt(&self) -> f64 {
        self.opts.dt
    }
    pub fn rod(&self) -> &Rod {
        &self.rod
    }
    /// Chamber pressures now, Pa.
    pub fn pressures(&self) -> &[f64] {
        &self.pressures
    }
    /// State at the tip now.
    pub fn tip(&self) -> &DynState<f64> {
        &self.tip
    }
    /// Tip velocity in the world frame, m/s.
    pub fn tip_velocity(&self) -> [f64; 3] {
        rot_mul(&self.tip.rot, &self.tip.q)
    }
    /// Base force and moment (world), N and N m.
    pub fn base_wrench(&self) -> ([f64; 3], [f64; 3]) {
        let fs = self.rod.force_scale;
        let ms = fs * self.rod.length;
        (
            [self.x[0] * fs, self.x[1] * fs, self.x[2] * fs],
            [self.x[3] * ms, self.x[4] * ms, self.x[5] * ms],
        )
    }
    /// Centreline at every node now: arc lengths (m) and positions (m, world).
    pub fn shape(&self) -> (&[f64], &[[f64; 3]]) {
        (&self.record.node_s, &self.record.nodes)
    }

    /// Total mechanical energy now, J: kinetic (translation and rotation), elastic about the
    /// pressure-shifted stress-free strains, gravitational, the tip body's kinetic and
    /// potential energy and the potential -F.r_tip of a dead tip force. With constant
    /// pressures and loads it can only decrease (Kelvin-Voigt damping dissipates). Each
    /// section is integrated with the RK4 weights over its stage points.
    pub fn energy(&self) -> f64 {
        let g = self.rod.gravity;
        let mut e = 0.0;
        let mut slot = 0;
        for (sec, c) in self.rod.sections.iter().zip(&self.coeffs) {
            let h = sec.length / sec.steps as f64;
            for _ in 0..sec.steps {
                for (j, w) in [1.0, 2.0, 2.0, 1.0].iter().enumerate() {
                    let f = &self.record.fields[slot + j];
                    let r = &self.record.position[slot + j];
                    let (v, u, q, om) = (&f[0..3], &f[3..6], &f[6..9], &f[9..12]);
                    let mut d = 0.5 * c.rho_a * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
                    d += 0.5 * (0..3).map(|k| c.rho_j[k] * om[k] * om[k]).sum::<f64>();
                    d -= c.rho_a * (g[0] * r[0] + g[1] * r[1] + g[2] * r[2]);
                    if !c.rigid {
                        let dv: [f64; 3] = std::array::from_fn(|k| v[k] - c.v_p[k]);
                        let du: [f64; 3] = std::array::from_fn(|k| u[k] - c.u_p[k]);
                        d += 0.5 * (0..3).map(|k| c.k_se[k] * dv[k] * dv[k]).sum::<f64>();
                        for a in 0..3 {
                            for b in 0..3 {
                                d += 0.5 * du[a] * c.k_bt[a][b] * du[b];
                            }
                        }
                    }
                    e += w * h / 6.0 * d;
                }
                slot += 4;
            }
        }
        let t = &self.rod.spec.tip;
        let y = &self.tip;
        let wxc = cross(&y.w, &t.com_offset);
        let vc: [f64; 3] = std::array::from_fn(|k| y.q[k] + wxc[k]);
        let cw = rot_mul(&y.rot, &t.com_offset);
        e += 0.5 * t.mass * (vc[0] * vc[0] + vc[1] * vc[1] + vc[2] * vc[2]);
        e += 0.5 * (0..3).map(|k| t.inertia[k] * y.w[k] * y.w[k]).sum::<f64>();
        e -= t.mass * (0..3).map(|k| g[k] * (y.r[k] + cw[k])).sum::<f64>();
        e -= (0..3).map(|k| self.tip_force[k] * y.r[k]).sum::<f64>();
        e
    }
}

fn rename_pressure_error(e: SoftrodError, name: &str) -> SoftrodError {
    match e {
        SoftrodError::InvalidParameter { field, value, rule } => SoftrodError::InvalidParameter {
            field: field.replacen("pressures", name, 1),
            value,
            rule,
        },
        other => other,
    }
}

type Lu6 = nalgebra::LU<f64, nalgebra::Const<6>, nalgebra::Const<6>>;
type Solved = std::result::Result<([f64; 6], DynState<f64>, Option<Lu6>), (usize, f64)>;

/// One time step's equations with its inputs (pressures, tip loads) a fraction `lam` of
/// the way from the last step's values to the new ones.
struct Level<'a> {
    rod: &'a Rod,
    inertia: &'a [SectionInertia],
    c0: f64,
    hist: &'a [[f64; FIELDS]],
    opts: &'a DynOptions,
    from: (&'a [f64], ([f64; 3], [f64; 3])),
    to: (&'a [f64], ([f64; 3], [f64; 3])),
}

impl Level<'_> {
    fn solve(
        &self,
        lam: f64,
        x0: [f64; 6],
        jac: Option<Lu6>,
        rec: &mut Record,
        stats: &mut DynStats,
    ) -> Solved {
        let mix = |a: f64, b: f64| a + lam * (b - a);
        let p: Vec<f64> = self
            .from
            .0
            .iter()
            .zip(self.to.0)
            .map(|(a, b)| mix(*a, *b))
            .collect();
        let mut sp = step_problem(self.rod, self.inertia, &p, self.c0);
        let ((f0, m0), (f1, m1)) = (self.from.1, self.to.1);
        sp.tip.force = std::array::from_fn(|k| mix(f0[k], f1[k]));
        sp.tip.moment = std::array::from_fn(|k| mix(m0[k], m1[k]));
        newton(&sp, self.hist, x0, jac, self.opts, rec, stats)
    }

    /// Continuation in the ramp parameter from 0 (solved from the last step's unknowns)
    /// to 1, halving the increment on failure down to 1/1024.
    fn ramp(&self, x_last: [f64; 6], rec: &mut Record, stats: &mut DynStats) -> Solved {
        let (mut x, _, _) = self.solve(0.0, x_last, None, rec, stats)?;
        let (mut lam, mut dlam): (f64, f64) = (0.0, 0.25);
        loop {
            let target = (lam + dlam).min(1.0);
            match self.solve(target, x, None, rec, stats) {
                Ok(done) if target >= 1.0 => return Ok(done),
                Ok((xn, _, _)) => {
                    x = xn;
                    lam = target;
                    dlam = (dlam * 1.5).min(0.5);
                }
                Err(e) => {
                    dlam *= 0.5;
                    if dlam < 1.0 / 1024.0 {
                        return Err(e);
                    }
                }
            }
        }
    }
}

/// Newton on the six base unknowns from `x0`. A Jacobian from the previous step is reused
/// while it contracts the residual by at least `REUSE_CONTRACTION` per iteration (the
/// exact one is recomputed otherwise). The record holds the last (accepted) evaluation.
fn newton(
    p: &StepProblem,
    hist: &[[f64; FIELDS]],
    x0: [f64; 6],
    jac: Option<Lu6>,
    opts: &DynOptions,
    rec: &mut Record,
    stats: &mut DynStats,
) -> Solved {
    const REUSE_CONTRACTION: f64 = 0.2;
    let mut x = x0;
    let (mut r, mut tip) = p.eval(hist, &x, Some(rec));
    let mut norm = inf_norm(&r);
    let mut lu = jac;
    let mut fresh = false;
    for it in 0..opts.max_iter {
        stats.newton_iterations += 1;
        let scale = inf_norm(&x).max(1.0);
        if norm <= opts.tol * scale {
            return Ok((x, tip, lu));
        }
        if !norm.is_finite() && fresh {
            return Err((it + 1, norm));
        }
        if lu.is_none() {
            lu = Some(p.jacobian(hist, &x).lu());
            stats.jacobians += 1;
            fresh = true;
        }
        let rv = Vec6::from_column_slice(&r);
        let step = lu
            .as_ref()
            .and_then(|l| l.solve(&(-rv)))
            .filter(|d| d.iter().all(|v| v.is_finite()));
        let Some(step) = step else {
            if fresh {
                return Err((it + 1, norm));
            }
            lu = None;
            continue;
        };
        let mut alpha = 1.0;
        let mut accepted = false;
        while alpha >= 1.0 / 256.0 {
            let xt: [f64; 6] = std::array::from_fn(|i| x[i] + alpha * step[i]);
            let (rt, tipt) = p.eval(hist, &xt, Some(rec));
            let nt = inf_norm(&rt);
            if nt.is_finite() && nt < (1.0 - 1e-4 * alpha) * norm {
                let contraction = nt / norm;
                x = xt;
                r = rt;
                tip = tipt;
                norm = nt;
                accepted = true;
                if contraction > REUSE_CONTRACTION {
                    lu = None; // refresh next iteration
                }
                fresh = false;
                break;
            }
            if !fresh {
                break; // a stale Jacobian: refresh and retry the full step
            }
            alpha *= 0.5;
        }
        if !accepted {
            if fresh {
                // Converged to round-off already?
                if norm <= 100.0 * opts.tol * scale {
                    // The record must hold x's evaluation (the trials overwrote it).
                    let (_, t) = p.eval(hist, &x, Some(rec));
                    return Ok((x, t, lu));
                }
                return Err((it + 1, norm));
            }
            lu = None;
            // Re-evaluate at x so the record matches it.
            let (rr, t) = p.eval(hist, &x, Some(rec));
            r = rr;
            tip = t;
        }
    }
    if norm <= opts.tol * inf_norm(&x).max(1.0) {
        Ok((x, tip, lu))
    } else {
        Err((opts.max_iter, norm))
    }
}
