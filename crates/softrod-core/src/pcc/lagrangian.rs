//! Lagrangian dynamics of the PCC chain (paper 003 eqs. 5-13), derived once from the
//! kinematics so that mass matrix, Coriolis and gravity terms are consistent.
//!
//! Kinetic energy T = sum over mass points of 1/2 m |p_t|^2 + 1/2 Omega^T I Omega, with the
//! mass points at the Gauss-Legendre nodes of each section (paper eq. 6 is the special case
//! of one point mass at the tip, `MassModel::Tip`). For a particle, Lagrange's equations
//! (eq. 5) give the generalised inertial force J^T p_tt, J = dp/dq, which equals
//! M(q) q_tt + C(q, q_t) q_t with the Christoffel form of C; for a rotating cross-section
//! J_Omega^T (I Omega_t + Omega x I Omega). p_tt, Omega_t and J come from one evaluation of
//! the kinematics in the scalar `Jet` (value, gradient in q, and first and second derivatives
//! along t -> q + q_t t + q_tt t^2/2), so no Christoffel symbol is written by hand.
//! Statics (v = a = 0) runs the same code with `Grad` (value and gradient only), which skips
//! the inertial terms and the rotations at the mass points where nothing needs them.

use super::jet::{Grad, Jet};
use super::kinematics::{segment_pose, segment_position, Pose, Real};
use super::{LinkKind, PccModel, PressureModel};

/// What a visited pose is.
#[derive(Clone, Copy, Debug)]
pub enum Site {
    /// A quadrature node of link `link`, standing for `weight` m of reference length (or,
    /// when sampling, the fraction sigma along the link).
    Node { link: usize, weight: f64 },
    /// The end of link `link`.
    LinkTip { link: usize },
}

fn mv<S: Real>(r: &[[S; 3]; 3], p: &[S; 3]) -> [S; 3] {
    std::array::from_fn(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2])
}

fn mm<S: Real>(a: &[[S; 3]; 3], b: &[[S; 3]; 3]) -> [[S; 3]; 3] {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// vee of the skew part of A^T B.
fn vee_atb<S: Real>(a: &[[S; 3]; 3], b: &[[S; 3]; 3]) -> [S; 3] {
    let c = |i: usize, j: usize| a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j];
    [
        (c(2, 1) - c(1, 2)) * 0.5,
        (c(0, 2) - c(2, 0)) * 0.5,
        (c(1, 0) - c(0, 1)) * 0.5,
    ]
}

type Rot<S> = [[S; 3]; 3];

/// R^T p.
fn mtv<S: Real>(r: &[[S; 3]; 3], p: &[S; 3]) -> [S; 3] {
    std::array::from_fn(|i| r[0][i] * p[0] + r[1][i] * p[1] + r[2][i] * p[2])
}

/// The frame at the start of a link: constant, or a function of the coordinates before.
enum Frame<L> {
    Const([f64; 3], [[f64; 3]; 3]),
    Var([L; 3], [[L; 3]; 3]),
}

fn dot<S: Real>(a: &[S; 3], b: &[S; 3]) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross<S: Real>(a: &[S; 3], b: &[S; 3]) -> [S; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn map3<A: Copy, B>(a: &[A; 3], f: impl Fn(&A) -> B) -> [B; 3] {
    std::array::from_fn(|i| f(&a[i]))
}
fn map33<A: Copy, B>(a: &[[A; 3]; 3], f: impl Fn(&A) -> B) -> [[B; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| f(&a[i][j])))
}

/// A scalar lifted from the coordinates q (with values in D): its value, its gradient in q
/// (J = dp/dq for a position) and, when `DYNAMIC`, its rate and acceleration along
/// t -> q + q_t t + q_tt t^2/2.
pub trait Lifted<D: Real, const N: usize>: Real {
    /// Whether the scalar carries time derivatives (inertial forces).
    const DYNAMIC: bool;
    /// The same kind of scalar over the 3 coordinates of one segment.
    type Local: Lifted<D, 3>;
    /// A local scalar whose variables 0..count are the coordinates offset..offset + count.
    fn embed(local: &Self::Local, offset: usize, count: usize) -> Self;
    /// The coordinates as variables (q_t and q_tt are ignored by static scalars).
    fn lift(x: &[D; N], v: &[D; N], a: &[D; N]) -> [Self; N];
    fn val(&self) -> D;
    fn grad(&self, i: usize) -> D;
    fn rate(&self) -> D;
    fn accel(&self) -> D;
}

impl<D: Real, const N: usize> Lifted<D, N> for Jet<D, N> {
    const DYNAMIC: bool = true;
    type Local = Jet<D, 3>;
    #[inline]
    fn embed(l: &Jet<D, 3>, offset: usize, count: usize) -> Self {
        let mut j = Jet::constant(l.re);
        j.grad[offset..offset + count].copy_from_slice(&l.grad[..count]);
        j.d1 = l.d1;
        j.d2 = l.d2;
        j
    }
    #[inline]
    fn lift(x: &[D; N], v: &[D; N], a: &[D; N]) -> [Self; N] {
        std::array::from_fn(|i| Jet::variable(x[i], v[i], a[i], i))
    }
    #[inline]
    fn val(&self) -> D {
        self.re
    }
    #[inline]
    fn grad(&self, i: usize) -> D {
        self.grad[i]
    }
    #[inline]
    fn rate(&self) -> D {
        self.d1
    }
    #[inline]
    fn accel(&self) -> D {
        self.d2
    }
}

/// Statics: value and gradient only (v = a = 0).
impl<D: Real, const N: usize> Lifted<D, N> for Grad<D, N> {
    const DYNAMIC: bool = false;
    type Local = Grad<D, 3>;
    #[inline]
    fn embed(l: &Grad<D, 3>, offset: usize, count: usize) -> Self {
        let mut g = Grad::constant(l.re);
        g.eps[offset..offset + count].copy_from_slice(&l.eps[..count]);
        g
    }
    #[inline]
    fn lift(x: &[D; N], _v: &[D; N], _a: &[D; N]) -> [Self; N] {
        std::array::from_fn(|i| Grad::variable(x[i], i))
    }
    #[inline]
    fn val(&self) -> D {
        self.re
    }
    #[inline]
    fn grad(&self, i: usize) -> D {
        self.eps[i]
    }
    #[inline]
    fn rate(&self) -> D {
        D::from(0.0)
    }
    #[inline]
    fn accel(&self) -> D {
        D::from(0.0)
    }
}

/// Generalised forces at (q, q_t, q_tt) with pressures p, each an N-vector.
#[derive(Debug, Clone, Copy)]
pub struct Forces<D, const N: usize> {
    /// M(q) q_tt + C(q, q_t) q_t.
    pub inertial: [D; N],
    /// Gravity, tip and line loads: -dV_g/dq + J^T F.
    pub external: [D; N],
    /// Chamber pressures.
    pub pressure: [D; N],
    /// -(k q + b q_t) terms.
    pub viscoelastic: [D; N],
}

impl<D: Real, const N: usize> Forces<D, N> {
    /// Equations of motion M q_tt + C q_t - Q = 0.
    pub fn residual(&self) -> [D; N] {
        std::array::from_fn(|i| {
            self.inertial[i] - self.external[i] - self.pressure[i] - self.viscoelastic[i]
        })
    }
}

/// Kinetic, gravitational and elastic energy (J) and the work potential of constant
/// pressures, -sum p A l (chamber model only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Energy {
    pub kinetic: f64,
    pub gravity: f64,
    pub elastic: f64,
    pub pressure: f64,
}

impl PccModel {
    /// Walk the chain from the base: call `f` at each link's quadrature nodes (or at the
    /// fractions `sigmas`) and at each link's end; returns the pose of the chain's tip.
    pub fn walk<S: Real>(
        &self,
        x: &[S],
        sigmas: Option<&[f64]>,
        mut f: impl FnMut(Site, &Pose<S>),
    ) -> Pose<S> {
        self.walk_parts(
            x,
            sigmas,
            |_| true,
            |site, p, r| f(site, &(*p, *r.expect("rotations requested"))),
        )
    }

    /// `walk` computing the rotation at the nodes of link `li` only where `node_rot(li)`
    /// (`f` gets None otherwise; link ends always have it). A node's position costs about
    /// half its pose, and statics needs positions only.
    pub(crate) fn walk_parts<S: Real>(
        &self,
        x: &[S],
        sigmas: Option<&[f64]>,
        node_rot: impl Fn(usize) -> bool,
        mut f: impl FnMut(Site, &[S; 3], Option<&[[S; 3]; 3]>),
    ) -> Pose<S> {
        let mut pos: [S; 3] = std::array::from_fn(|k| S::from(self.base_position[k]));
        let mut rot: [[S; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| S::from(self.base_rotation[i][j])));
        let eye: [[S; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| S::from(if i == j { 1.0 } else { 0.0 }))
        });
        let (b, q) = (&self.base_position, &self.base_rotation);
        for (li, link) in self.links.iter().enumerate() {
            let y = match link.kind {
                LinkKind::Segment { offset, .. } => Some(self.expand(x, offset)),
                LinkKind::Rigid => None,
            };
            let local_p = |sigma: f64| -> [S; 3] {
                match &y {
                    Some(y) => segment_position(y, sigma),
                    None => [S::from(0.0), S::from(0.0), S::from(sigma * link.length)],
                }
            };
            let local = |sigma: f64| -> Pose<S> {
                match &y {
                    Some(y) => segment_pose(y, sigma),
                    None => (local_p(sigma), eye),
                }
            };
            // The base frame is constant: for the first link, products with plain numbers
            // are several times cheaper than with the duals (most chains are one link).
            let world_p = |p: [S; 3]| -> [S; 3] {
                if li == 0 {
                    std::array::from_fn(|i| p[0] * q[i][0] + p[1] * q[i][1] + p[2] * q[i][2] + b[i])
                } else {
                    let d = mv(&rot, &p);
                    std::array::from_fn(|k| pos[k] + d[k])
                }
            };
            let world_r = |r: [[S; 3]; 3]| -> [[S; 3]; 3] {
                if li == 0 {
                    std::array::from_fn(|i| {
                        std::array::from_fn(|j| {
                            r[0][j] * q[i][0] + r[1][j] * q[i][1] + r[2][j] * q[i][2]
                        })
                    })
                } else {
                    mm(&rot, &r)
                }
            };
            let with_rot = node_rot(li);
            let mut node = |site: Site, sg: f64| {
                if with_rot {
                    let (p, r) = local(sg);
                    f(site, &world_p(p), Some(&world_r(r)));
                } else {
                    f(site, &world_p(local_p(sg)), None);
                }
            };
            match sigmas {
                None => {
                    for &(sg, w) in &self.nodes {
                        let site = Site::Node {
                            link: li,
                            weight: w * link.length,
                        };
                        node(site, sg);
                    }
                }
                Some(list) => {
                    for &sg in list {
                        node(
                            Site::Node {
                                link: li,
                                weight: sg,
                            },
                            sg,
                        );
                    }
                }
            }
            let (pe, re) = local(1.0);
            let end = (world_p(pe), world_r(re));
            f(Site::LinkTip { link: li }, &end.0, Some(&end.1));
            (pos, rot) = end;
        }
        (pos, rot)
    }

    /// Add a rigid body (mass point with rotary inertia, and dead loads) to the forces.
    #[allow(clippy::too_many_arguments)]
    fn add_body<D: Real, L: Lifted<D, N>, const N: usize>(
        &self,
        out: &mut Forces<D, N>,
        p: &[L; 3],
        r: Option<&[[L; 3]; 3]>,
        mass: f64,
        inertia: [f64; 3],
        force: [f64; 3],
        moment: [f64; 3],
    ) {
        let load: [D; 3] = std::array::from_fn(|k| D::from(mass * self.gravity[k] + force[k]));
        let inertial = L::DYNAMIC && mass != 0.0;
        let pdd = map3(p, L::accel);
        for i in 0..N {
            let ji = map3(p, |k| k.grad(i));
            if inertial {
                out.inertial[i] += dot(&ji, &pdd) * mass;
            }
            out.external[i] += dot(&ji, &load);
        }
        let spin = L::DYNAMIC && inertia.iter().any(|&x| x != 0.0);
        let torque = moment.iter().any(|&x| x != 0.0);
        if !(spin || torque) {
            return;
        }
        let r = r.expect("rotation computed where there is rotary inertia or a moment");
        let r0 = map33(r, L::val);
        // Body angular velocity and acceleration: hat(Omega) = R^T R_t, hat(Omega_t) =
        // skew(R^T R_tt) (R^T R_tt = hat(Omega_t) + hat(Omega)^2, the latter symmetric).
        let tau: [D; 3] = if spin {
            let w = vee_atb(&r0, &map33(r, L::rate));
            let wd = vee_atb(&r0, &map33(r, L::accel));
            let iw: [D; 3] = std::array::from_fn(|k| w[k] * inertia[k]);
            let wxiw = cross(&w, &iw);
            std::array::from_fn(|k| wd[k] * inertia[k] + wxiw[k])
        } else {
            [D::from(0.0); 3]
        };
        let mom: [D; 3] = std::array::from_fn(|k| D::from(moment[k]));
        for i in 0..N {
            let dri = map33(r, |k| k.grad(i));
            let jw = vee_atb(&r0, &dri);
            if spin {
                out.inertial[i] += dot(&jw, &tau);
            }
            if torque {
                // A world moment M does virtual work M . (R delta_theta_body).
                out.external[i] += dot(&mv(&r0, &jw), &mom);
            }
        }
    }

    /// All generalised forces at (x, v, a) under pressures `p` (Pa, one per channel).
    pub fn forces<D: Real, const N: usize>(
        &self,
        x: &[D; N],
        v: &[D; N],
        a: &[D; N],
        p: &[f64],
    ) -> Forces<D, N> {
        self.forces_split::<D, Jet<D, N>, N>(x, v, a, p)
    }

    /// The generalised forces of statics (v = a = 0, so no inertial term) at x: the same
    /// code as `forces` with a scalar that carries the gradient in q only (no time
    /// derivatives), so `static_forces(x) == forces(x, 0, 0)` up to round-off.
    pub fn static_forces<D: Real, const N: usize>(&self, x: &[D; N], p: &[f64]) -> Forces<D, N> {
        let zero = [D::from(0.0); N];
        self.forces_split::<D, Grad<D, N>, N>(x, &zero, &zero, p)
    }

    /// Reference evaluation of `forces`: every mass point in world coordinates, with the
    /// gradient over all N coordinates (the direct form of the Lagrangian; its cost per
    /// mass point grows with N). `forces` gives the same numbers to round-off; the tests
    /// compare the two.
    pub fn forces_direct<D: Real, const N: usize>(
        &self,
        x: &[D; N],
        v: &[D; N],
        a: &[D; N],
        p: &[f64],
    ) -> Forces<D, N> {
        let zero = [D::from(0.0); N];
        let mut out = Forces {
            inertial: zero,
            external: zero,
            pressure: zero,
            viscoelastic: zero,
        };
        let xk = <Jet<D, N> as Lifted<D, N>>::lift(x, v, a);
        let tip = self.walk_parts(
            &xk,
            None,
            |_| true,
            |site, pk, rk| match site {
                Site::Node { link, weight } => {
                    let l = &self.links[link];
                    let m = l.line_mass * weight;
                    let i = l.rotary.map(|j| j * weight);
                    let f = l.line_force.map(|j| j * weight);
                    let mo = l.line_moment.map(|j| j * weight);
                    self.add_body(&mut out, pk, rk, m, i, f, mo);
                }
                Site::LinkTip { link } => {
                    self.add_tip_pressure(&mut out, link, pk, rk.expect("link ends"), p);
                }
            },
        );
        self.add_tip_body(&mut out, &tip);
        self.add_segment_forces(&mut out, x, v, p);
        out
    }

    /// Paper 003 eq. 9 (`pressure_force = "tip_force"`): follower force p A d3 at the chamber
    /// centroid of the segment's end, virtual work p A d3 . d r_k/dq.
    fn add_tip_pressure<D: Real, L: Lifted<D, N>, const N: usize>(
        &self,
        out: &mut Forces<D, N>,
        link: usize,
        pk: &[L; 3],
        rk: &[[L; 3]; 3],
        p: &[f64],
    ) {
        if self.pressure_model != PressureModel::TipForce {
            return;
        }
        let d3: [D; 3] = std::array::from_fn(|k| rk[k][2].val());
        for c in &self.links[link].chambers {
            let fa = p[c.channel] * c.area;
            for i in 0..N {
                let dr: [D; 3] = std::array::from_fn(|k| {
                    pk[k].grad(i)
                        + rk[k][0].grad(i) * c.centroid[0]
                        + rk[k][1].grad(i) * c.centroid[1]
                });
                out.pressure[i] += dot(&d3, &dr) * fa;
            }
        }
    }

    /// Tip body at its centre of mass; dead tip force and moment at the tip.
    fn add_tip_body<D: Real, L: Lifted<D, N>, const N: usize>(
        &self,
        out: &mut Forces<D, N>,
        tip: &Pose<L>,
    ) {
        let (pt, rt) = tip;
        let c = self.tip.com_offset;
        let pc: [L; 3] =
            std::array::from_fn(|k| pt[k] + rt[k][0] * c[0] + rt[k][1] * c[1] + rt[k][2] * c[2]);
        self.add_body(
            out,
            &pc,
            Some(rt),
            self.tip.mass,
            self.tip.inertia,
            [0.0; 3],
            self.tip.moment,
        );
        self.add_body(out, pt, Some(rt), 0.0, [0.0; 3], self.tip.force, [0.0; 3]);
    }

    /// Chamber pressures (`pressure_force = "chamber"`) and visco-elastic forces, segment by
    /// segment (no kinematics needed).
    fn add_segment_forces<D: Real, const N: usize>(
        &self,
        out: &mut Forces<D, N>,
        x: &[D; N],
        v: &[D; N],
        p: &[f64],
    ) {
        for (link, o, prm) in self.segments() {
            let y = self.expand(x, o);
            let yd = self.expand(v, o);
            let mut q = [D::from(0.0); 3];
            if self.pressure_model == PressureModel::Chamber {
                // Chamber length l = L - (c_x theta_x + c_y theta_y): the fibre at c lies
                // on the inside of the bend when c points along the bending direction.
                for c in &link.chambers {
                    let fa = p[c.channel] * c.area;
                    q[0] += D::from(fa);
                    q[1] -= D::from(fa * c.centroid[0]);
                    q[2] -= D::from(fa * c.centroid[1]);
                }
            }
            let theta_re = y[1].re().hypot(y[2].re());
            let (k0, dk) = prm.k_theta.eval(theta_re);
            // k_theta(theta) to first order around the current value (exact value and first
            // derivative, which is all the Newton Jacobian needs).
            let kt = if theta_re > 0.0 && dk != 0.0 {
                ((y[1] * y[1] + y[2] * y[2]).sqrt() - theta_re) * dk + k0
            } else {
                D::from(k0)
            };
            let mut ve = [
                -((y[0] - link.length) * prm.k_l + yd[0] * prm.b_l),
                -(y[1] * kt + yd[1] * prm.b_theta),
                -(y[2] * kt + y[2] * prm.k_phi + yd[2] * (prm.b_theta + prm.b_phi)),
            ];
            match self.plane {
                None => {
                    for k in 0..3 {
                        out.pressure[o + k] += q[k];
                        out.viscoelastic[o + k] += ve[k];
                    }
                }
                Some((c, s)) => {
                    out.pressure[o] += q[0];
                    out.pressure[o + 1] += q[1] * c + q[2] * s;
                    ve[1] = ve[1] * c + ve[2] * s;
                    out.viscoelastic[o] += ve[0];
                    out.viscoelastic[o + 1] += ve[1];
                }
            }
        }
    }

    /// The forces link by link, each link's mass points in the link's own frame.
    ///
    /// A point of link k is p = P + R s, with (P, R) the frame at the link's start (a
    /// function of the coordinates before it) and (s, R_l) its pose in that frame (a function
    /// of the link's own 2-3 coordinates only). So the points are evaluated in a scalar over
    /// the link's own coordinates (`Lifted::Local`, whose cost does not grow with the chain),
    /// and what they do to the earlier coordinates i is summed per link and projected once:
    ///   sum_n (dp_n/dq_i) . f_n = dP/dq_i . sum_n f_n + <dR/dq_i, sum_n f_n s_n^T>,
    ///   sum_n J_Omega,n,i . tau_n = J_Omega,frame,i . sum_n R_l,n tau_n,
    /// with f_n = m p_tt (inertial) or the load (external); for the own coordinates j,
    /// dp_n/dy_j = R ds_n/dy_j. p_tt = P_tt + R_tt s + 2 R_t s_t + R s_tt, and the body
    /// angular velocity of a point's section is R_l^T Omega_frame + omega_l. Only the frame
    /// at each link's end is composed in the full scalar L. With a constant frame (the first
    /// link, or after rigid links only) there are no earlier coordinates and the frame
    /// products are plain numbers.
    fn forces_split<D: Real, L: Lifted<D, N>, const N: usize>(
        &self,
        x: &[D; N],
        v: &[D; N],
        a: &[D; N],
        p: &[f64],
    ) -> Forces<D, N> {
        let zero = [D::from(0.0); N];
        let mut out = Forces {
            inertial: zero,
            external: zero,
            pressure: zero,
            viscoelastic: zero,
        };
        let z = D::from(0.0);
        let per = self.per_segment();
        let dynamic = L::DYNAMIC;
        // The frame at the start of the link: constant (plain numbers) or in L.
        let mut frame: Frame<L> = Frame::Const(self.base_position, self.base_rotation);
        let mut before = 0;
        for (li, link) in self.links.iter().enumerate() {
            let own = match link.kind {
                LinkKind::Segment { offset, .. } => {
                    let pick = |u: &[D; N]| -> [D; 3] {
                        std::array::from_fn(|j| if j < per { u[offset + j] } else { z })
                    };
                    let yl = L::Local::lift(&pick(x), &pick(v), &pick(a));
                    Some((offset, self.expand(&yl, 0)))
                }
                LinkKind::Rigid => None,
            };
            let nown = if own.is_some() { per } else { 0 };
            let o = own.as_ref().map_or(before, |(o, _)| *o);
            // Frame values, rates and accelerations (D).
            let (rv, var) = match &frame {
                Frame::Const(_, r) => (map33(r, |&e| D::from(e)), None),
                Frame::Var(pf, rf) => (map33(rf, L::val), Some((pf, rf))),
            };
            let moving = dynamic && var.is_some();
            let (pdd, rd, rdd) = match (moving, var) {
                (true, Some((pf, rf))) => {
                    (map3(pf, L::accel), map33(rf, L::rate), map33(rf, L::accel))
                }
                _ => ([z; 3], [[z; 3]; 3], [[z; 3]; 3]),
            };
            let (wf, wfd) = if moving {
                (vee_atb(&rv, &rd), vee_atb(&rv, &rdd))
            } else {
                ([z; 3], [z; 3])
            };
            let spin = dynamic && link.rotary.iter().any(|&j| j != 0.0);
            let torque = link.line_moment.iter().any(|&j| j != 0.0);
            let with_rot = spin || torque;
            let inertial = dynamic && link.line_mass != 0.0;
            // Sums for the earlier coordinates: inertial and external f_n and f_n s_n^T,
            // rotary torques R_l tau and world moments.
            let (mut fi, mut gi, mut fe, mut ge) = ([z; 3], [[z; 3]; 3], [z; 3], [[z; 3]; 3]);
            let (mut tq, mut mt) = ([z; 3], [z; 3]);
            let eye = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
            for &(sg, w) in &self.nodes {
                let wl = w * link.length;
                let m = link.line_mass * wl;
                let load: [D; 3] =
                    std::array::from_fn(|k| D::from(m * self.gravity[k] + link.line_force[k] * wl));
                let (s, rl): ([L::Local; 3], Option<Rot<L::Local>>) = match &own {
                    Some((_, y)) if with_rot => {
                        let (s, r) = segment_pose(y, sg);
                        (s, Some(r))
                    }
                    Some((_, y)) => (segment_position(y, sg), None),
                    None => (
                        [
                            L::Local::from(0.0),
                            L::Local::from(0.0),
                            L::Local::from(sg * link.length),
                        ],
                        with_rot.then(|| {
                            std::array::from_fn(|i| {
                                std::array::from_fn(|j| L::Local::from(eye(i, j)))
                            })
                        }),
                    ),
                };
                let sv = map3(&s, L::Local::val);
                // World acceleration of the point.
                let acc: [D; 3] = if inertial {
                    let sdd = map3(&s, L::Local::accel);
                    let mut acc = mv(&rv, &sdd);
                    if moving {
                        let sd = map3(&s, L::Local::rate);
                        let a1 = mv(&rdd, &sv);
                        let a2 = mv(&rd, &sd);
                        for k in 0..3 {
                            acc[k] += pdd[k] + a1[k] + a2[k] * 2.0;
                        }
                    }
                    acc
                } else {
                    [z; 3]
                };
                if own.is_some() {
                    let a_loc = mtv(&rv, &acc);
                    let l_loc = mtv(&rv, &load);
                    for j in 0..nown {
                        let ds = map3(&s, |k| k.grad(j));
                        if inertial {
                            out.inertial[o + j] += dot(&ds, &a_loc) * m;
                        }
                        out.external[o + j] += dot(&ds, &l_loc);
                    }
                }
                if var.is_some() {
                    for k in 0..3 {
                        if inertial {
                            fi[k] += acc[k] * m;
                            for b in 0..3 {
                                gi[k][b] += acc[k] * sv[b] * m;
                            }
                        }
                        fe[k] += load[k];
                        for b in 0..3 {
                            ge[k][b] += load[k] * sv[b];
                        }
                    }
                }
                if let Some(rl) = &rl {
                    let rlv = map33(rl, L::Local::val);
                    let jw: [[D; 3]; 3] = std::array::from_fn(|j| {
                        if j < nown {
                            vee_atb(&rlv, &map33(rl, |k| k.grad(j)))
                        } else {
                            [z; 3]
                        }
                    });
                    if spin {
                        let inertia = link.rotary.map(|j| j * wl);
                        let wl_ = vee_atb(&rlv, &map33(rl, L::Local::rate));
                        let wdl = vee_atb(&rlv, &map33(rl, L::Local::accel));
                        let (om, omd) = if moving {
                            let wa = mtv(&rlv, &wf);
                            let wb = mtv(&rlv, &wfd);
                            let c = cross(&wl_, &wa);
                            (
                                std::array::from_fn(|k| wa[k] + wl_[k]),
                                std::array::from_fn(|k| wb[k] - c[k] + wdl[k]),
                            )
                        } else {
                            (wl_, wdl)
                        };
                        let iw: [D; 3] = std::array::from_fn(|k| om[k] * inertia[k]);
                        let wxiw = cross(&om, &iw);
                        let tau: [D; 3] = std::array::from_fn(|k| omd[k] * inertia[k] + wxiw[k]);
                        for j in 0..nown {
                            out.inertial[o + j] += dot(&jw[j], &tau);
                        }
                        if var.is_some() {
                            let t = mv(&rlv, &tau);
                            for k in 0..3 {
                                tq[k] += t[k];
                            }
                        }
                    }
                    if torque {
                        // A world moment M does virtual work M . (R_n delta_theta_body).
                        let mw: [D; 3] = std::array::from_fn(|k| D::from(link.line_moment[k] * wl));
                        let mloc = mtv(&rlv, &mtv(&rv, &mw));
                        for j in 0..nown {
                            out.external[o + j] += dot(&jw[j], &mloc);
                        }
                        for k in 0..3 {
                            mt[k] += mw[k];
                        }
                    }
                }
            }
            // Project the link's sums on the earlier coordinates.
            if let Some((pf, rf)) = var {
                let mt_loc = mtv(&rv, &mt);
                for i in 0..before {
                    let dp = map3(pf, |k| k.grad(i));
                    let dr = map33(rf, |k| k.grad(i));
                    let jwf = vee_atb(&rv, &dr);
                    let mut e = dot(&dp, &fe) + dot(&jwf, &mt_loc);
                    for k in 0..3 {
                        e += dot(&dr[k], &ge[k]);
                    }
                    out.external[i] += e;
                    if dynamic {
                        let mut f = dot(&dp, &fi) + dot(&jwf, &tq);
                        for k in 0..3 {
                            f += dot(&dr[k], &gi[k]);
                        }
                        out.inertial[i] += f;
                    }
                }
            }
            // The link's end, in the full scalar: the next link's frame.
            let (se, re): Pose<L::Local> = match &own {
                Some((_, y)) => segment_pose(y, 1.0),
                None => (
                    [
                        L::Local::from(0.0),
                        L::Local::from(0.0),
                        L::Local::from(link.length),
                    ],
                    std::array::from_fn(|i| std::array::from_fn(|j| L::Local::from(eye(i, j)))),
                ),
            };
            let se: [L; 3] = map3(&se, |e| L::embed(e, o, nown));
            let re: [[L; 3]; 3] = map33(&re, |e| L::embed(e, o, nown));
            let end: Pose<L> = match &frame {
                Frame::Const(b, q) => (
                    std::array::from_fn(|i| {
                        se[0] * q[i][0] + se[1] * q[i][1] + se[2] * q[i][2] + b[i]
                    }),
                    std::array::from_fn(|i| {
                        std::array::from_fn(|j| {
                            re[0][j] * q[i][0] + re[1][j] * q[i][1] + re[2][j] * q[i][2]
                        })
                    }),
                ),
                Frame::Var(pf, rf) => {
                    let d = mv(rf, &se);
                    (std::array::from_fn(|k| pf[k] + d[k]), mm(rf, &re))
                }
            };
            self.add_tip_pressure(&mut out, li, &end.0, &end.1, p);
            frame = match (&frame, own.is_some()) {
                // Still constant after a rigid link.
                (Frame::Const(..), false) => {
                    Frame::Const(map3(&end.0, |e| e.re()), map33(&end.1, |e| e.re()))
                }
                _ => Frame::Var(end.0, end.1),
            };
            before += nown;
        }
        let tip: Pose<L> = match frame {
            Frame::Const(b, q) => (b.map(L::from), q.map(|r| r.map(L::from))),
            Frame::Var(pf, rf) => (pf, rf),
        };
        self.add_tip_body(&mut out, &tip);
        self.add_segment_forces(&mut out, x, v, p);
        out
    }

    /// Mass matrix M(q) (N x N, row-major), from the same mass points.
    pub fn mass_matrix_n<const N: usize>(&self, x: &[f64; N]) -> [[f64; N]; N] {
        let zero = [0.0; N];
        let xk = <Grad<f64, N> as Lifted<f64, N>>::lift(x, &zero, &zero);
        let mut m = [[0.0; N]; N];
        let mut body =
            |p: &[Grad<f64, N>; 3], r: &[[Grad<f64, N>; 3]; 3], mass: f64, inertia: [f64; 3]| {
                let r0 = map33(r, |k| k.re);
                let j: [[f64; 3]; N] = std::array::from_fn(|i| map3(p, |k| k.eps[i]));
                let jw: [[f64; 3]; N] =
                    std::array::from_fn(|i| vee_atb(&r0, &map33(r, |k| k.eps[i])));
                for a in 0..N {
                    for b in 0..N {
                        m[a][b] += mass * dot(&j[a], &j[b])
                            + (0..3)
                                .map(|k| jw[a][k] * inertia[k] * jw[b][k])
                                .sum::<f64>();
                    }
                }
            };
        let tip = self.walk(&xk, None, |site, (p, r)| {
            if let Site::Node { link, weight } = site {
                let l = &self.links[link];
                body(p, r, l.line_mass * weight, l.rotary.map(|j| j * weight));
            }
        });
        let (pt, rt) = &tip;
        let c = self.tip.com_offset;
        let pc: [Grad<f64, N>; 3] =
            std::array::from_fn(|k| pt[k] + rt[k][0] * c[0] + rt[k][1] * c[1] + rt[k][2] * c[2]);
        body(&pc, rt, self.tip.mass, self.tip.inertia);
        m
    }

    /// Energies at (x, v) under constant pressures p.
    pub fn energy_n<const N: usize>(&self, x: &[f64; N], v: &[f64; N], p: &[f64]) -> Energy {
        self.observe(x, v, p).0
    }

    /// Energies, tip pose and tip velocity at (x, v), from one walk with the derivative
    /// along v (a dual number in one direction).
    pub(crate) fn observe(&self, x: &[f64], v: &[f64], p: &[f64]) -> (Energy, Pose<f64>, [f64; 3]) {
        let xk: Vec<Grad<f64, 1>> = x
            .iter()
            .zip(v)
            .map(|(&a, &b)| Grad { re: a, eps: [b] })
            .collect();
        let mut e = Energy {
            kinetic: 0.0,
            gravity: 0.0,
            elastic: 0.0,
            pressure: 0.0,
        };
        let g = self.gravity;
        let mut body =
            |p: &[Grad<f64, 1>; 3], r: &[[Grad<f64, 1>; 3]; 3], mass: f64, inertia: [f64; 3]| {
                let pd = map3(p, |k| k.eps[0]);
                let w = vee_atb(&map33(r, |k| k.re), &map33(r, |k| k.eps[0]));
                e.kinetic += 0.5 * mass * dot(&pd, &pd)
                    + 0.5 * (0..3).map(|k| inertia[k] * w[k] * w[k]).sum::<f64>();
                e.gravity -= mass * dot(&map3(p, |k| k.re), &g);
            };
        let tip = self.walk(&xk, None, |site, (p, r)| {
            if let Site::Node { link, weight } = site {
                let l = &self.links[link];
                body(p, r, l.line_mass * weight, l.rotary.map(|j| j * weight));
            }
        });
        let (pt, rt) = &tip;
        let c = self.tip.com_offset;
        let pc: [Grad<f64, 1>; 3] =
            std::array::from_fn(|k| pt[k] + rt[k][0] * c[0] + rt[k][1] * c[1] + rt[k][2] * c[2]);
        body(&pc, rt, self.tip.mass, self.tip.inertia);
        for (link, o, prm) in self.segments() {
            let y = self.expand(x, o);
            let d = y[0] - link.length;
            let theta = y[1].hypot(y[2]);
            e.elastic +=
                0.5 * prm.k_l * d * d + prm.k_theta.energy(theta) + 0.5 * prm.k_phi * y[2] * y[2];
            if self.pressure_model == PressureModel::Chamber {
                for c in &link.chambers {
                    let l = y[0] - c.centroid[0] * y[1] - c.centroid[1] * y[2];
                    e.pressure -= p[c.channel] * c.area * l;
                }
            }
        }
        let pose = (map3(pt, |k| k.re), map33(rt, |k| k.re));
        (e, pose, map3(pt, |k| k.eps[0]))
    }
}
