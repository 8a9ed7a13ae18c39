//! Lagrangian dynamics of the PCC chain (paper 003 eqs. 5-13), derived once from the
//! kinematics so that mass matrix, Coriolis and gravity terms are consistent.
//!
//! Kinetic energy T = sum over mass points of 1/2 m |p_t|^2 + 1/2 Omega^T I Omega, with the
//! mass points at the Gauss-Legendre nodes of each section (paper eq. 6 is the special case
//! of one point mass at the tip, `MassModel::Tip`). For a particle, Lagrange's equations
//! (eq. 5) give the generalised inertial force J^T p_tt, J = dp/dq, which equals
//! M(q) q_tt + C(q, q_t) q_t with the Christoffel form of C; for a rotating cross-section
//! J_Omega^T (I Omega_t + Omega x I Omega). p_tt and Omega_t come from one evaluation of the
//! kinematics in second-order dual numbers along t -> q + q_t t + q_tt t^2/2, and J from a
//! vector dual over q nested inside, so no Christoffel symbol is written by hand.

use super::kinematics::{segment_pose, Pose, Real};
use super::{LinkKind, PccModel, PressureModel};
use num_dual::{Dual2, DualSVec};

/// Scalar for one evaluation: time derivatives (Dual2) of values with their gradient in q.
pub type K<D, const N: usize> = Dual2<DualSVec<D, N>>;

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

/// Value, q-gradient component, rate and acceleration of a K scalar.
fn val<D: Real, const N: usize>(k: &K<D, N>) -> D {
    k.re.re
}
fn grad<D: Real, const N: usize>(k: &K<D, N>, i: usize) -> D {
    k.re.eps.0.as_ref().map_or(D::from(0.0), |e| e[i])
}
fn rate<D: Real, const N: usize>(k: &K<D, N>) -> D {
    k.v1.re
}
fn accel<D: Real, const N: usize>(k: &K<D, N>) -> D {
    k.v2.re
}

fn map3<A: Copy, B>(a: &[A; 3], f: impl Fn(&A) -> B) -> [B; 3] {
    std::array::from_fn(|i| f(&a[i]))
}
fn map33<A: Copy, B>(a: &[[A; 3]; 3], f: impl Fn(&A) -> B) -> [[B; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| f(&a[i][j])))
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
        let mut pos: [S; 3] = std::array::from_fn(|k| S::from(self.base_position[k]));
        let mut rot: [[S; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| S::from(self.base_rotation[i][j])));
        let eye: [[S; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| S::from(if i == j { 1.0 } else { 0.0 }))
        });
        for (li, link) in self.links.iter().enumerate() {
            let y = match link.kind {
                LinkKind::Segment { offset, .. } => Some(self.expand(x, offset)),
                LinkKind::Rigid => None,
            };
            let local = |sigma: f64| -> Pose<S> {
                match &y {
                    Some(y) => segment_pose(y, sigma),
                    None => (
                        [S::from(0.0), S::from(0.0), S::from(sigma * link.length)],
                        eye,
                    ),
                }
            };
            let world = |(p, r): Pose<S>| -> Pose<S> {
                if li == 0 {
                    // The base frame is constant: products with plain numbers are several
                    // times cheaper than with the nested duals (most chains are one link).
                    let (b, q) = (&self.base_position, &self.base_rotation);
                    let d: [S; 3] =
                        std::array::from_fn(|i| p[0] * q[i][0] + p[1] * q[i][1] + p[2] * q[i][2]);
                    let rr = std::array::from_fn(|i| {
                        std::array::from_fn(|j| {
                            r[0][j] * q[i][0] + r[1][j] * q[i][1] + r[2][j] * q[i][2]
                        })
                    });
                    return (std::array::from_fn(|k| d[k] + b[k]), rr);
                }
                let d = mv(&rot, &p);
                (std::array::from_fn(|k| pos[k] + d[k]), mm(&rot, &r))
            };
            match sigmas {
                None => {
                    for &(sg, w) in &self.nodes {
                        let site = Site::Node {
                            link: li,
                            weight: w * link.length,
                        };
                        f(site, &world(local(sg)));
                    }
                }
                Some(list) => {
                    for &sg in list {
                        f(
                            Site::Node {
                                link: li,
                                weight: sg,
                            },
                            &world(local(sg)),
                        );
                    }
                }
            }
            let end = world(local(1.0));
            f(Site::LinkTip { link: li }, &end);
            (pos, rot) = end;
        }
        (pos, rot)
    }

    fn lift<D: Real, const N: usize>(x: &[D; N], v: &[D; N], a: &[D; N]) -> [K<D, N>; N] {
        std::array::from_fn(|i| {
            Dual2::new(
                DualSVec::from_re(x[i]).derivative(i),
                DualSVec::from_re(v[i]),
                DualSVec::from_re(a[i]),
            )
        })
    }

    /// Add a rigid body (mass point with rotary inertia, and dead loads) to the forces.
    #[allow(clippy::too_many_arguments)]
    fn add_body<D: Real, const N: usize>(
        &self,
        out: &mut Forces<D, N>,
        pose: &Pose<K<D, N>>,
        mass: f64,
        inertia: [f64; 3],
        force: [f64; 3],
        moment: [f64; 3],
    ) {
        let (p, r) = pose;
        let load: [D; 3] = std::array::from_fn(|k| D::from(mass * self.gravity[k] + force[k]));
        let pdd = map3(p, accel);
        for i in 0..N {
            let ji = map3(p, |k| grad(k, i));
            out.inertial[i] += dot(&ji, &pdd) * mass;
            out.external[i] += dot(&ji, &load);
        }
        let spin = inertia.iter().any(|&x| x != 0.0);
        let torque = moment.iter().any(|&x| x != 0.0);
        if !(spin || torque) {
            return;
        }
        let r0 = map33(r, val);
        let rd = map33(r, rate);
        let rdd = map33(r, accel);
        // Body angular velocity and acceleration: hat(Omega) = R^T R_t, hat(Omega_t) =
        // skew(R^T R_tt) (R^T R_tt = hat(Omega_t) + hat(Omega)^2, the latter symmetric).
        let w = vee_atb(&r0, &rd);
        let wd = vee_atb(&r0, &rdd);
        let iw: [D; 3] = std::array::from_fn(|k| w[k] * inertia[k]);
        let wxiw = cross(&w, &iw);
        let tau: [D; 3] = std::array::from_fn(|k| wd[k] * inertia[k] + wxiw[k]);
        let mom: [D; 3] = std::array::from_fn(|k| D::from(moment[k]));
        for i in 0..N {
            let dri = map33(r, |k| grad(k, i));
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
        let zero = [D::from(0.0); N];
        let mut out = Forces {
            inertial: zero,
            external: zero,
            pressure: zero,
            viscoelastic: zero,
        };
        let xk = Self::lift(x, v, a);
        let tip = self.walk(&xk, None, |site, pose| match site {
            Site::Node { link, weight } => {
                let l = &self.links[link];
                let m = l.line_mass * weight;
                let i = l.rotary.map(|j| j * weight);
                let f = l.line_force.map(|j| j * weight);
                let mo = l.line_moment.map(|j| j * weight);
                self.add_body(&mut out, pose, m, i, f, mo);
            }
            Site::LinkTip { link } => {
                if self.pressure_model != PressureModel::TipForce {
                    return;
                }
                // Paper 003 eq. 9: follower force p A d3 at the chamber centroid of the
                // segment's end, virtual work p A d3 . d r_k/dq.
                let (pk, rk) = pose;
                let d3: [D; 3] = std::array::from_fn(|k| val(&rk[k][2]));
                for c in &self.links[link].chambers {
                    let fa = p[c.channel] * c.area;
                    for i in 0..N {
                        let dr: [D; 3] = std::array::from_fn(|k| {
                            grad(&pk[k], i)
                                + grad(&rk[k][0], i) * c.centroid[0]
                                + grad(&rk[k][1], i) * c.centroid[1]
                        });
                        out.pressure[i] += dot(&d3, &dr) * fa;
                    }
                }
            }
        });
        // Tip body at its centre of mass; dead tip force at the tip.
        let (pt, rt) = &tip;
        let c = self.tip.com_offset;
        let pc: [K<D, N>; 3] =
            std::array::from_fn(|k| pt[k] + rt[k][0] * c[0] + rt[k][1] * c[1] + rt[k][2] * c[2]);
        self.add_body(
            &mut out,
            &(pc, *rt),
            self.tip.mass,
            self.tip.inertia,
            [0.0; 3],
            self.tip.moment,
        );
        self.add_body(&mut out, &tip, 0.0, [0.0; 3], self.tip.force, [0.0; 3]);

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
        out
    }

    /// Mass matrix M(q) (N x N, row-major), from the same mass points.
    pub fn mass_matrix_n<const N: usize>(&self, x: &[f64; N]) -> [[f64; N]; N] {
        let zero = [0.0; N];
        let xk = Self::lift(x, &zero, &zero);
        let mut m = [[0.0; N]; N];
        let mut body = |pose: &Pose<K<f64, N>>, mass: f64, inertia: [f64; 3]| {
            let (p, r) = pose;
            let r0 = map33(r, val);
            let j: Vec<[f64; 3]> = (0..N).map(|i| map3(p, |k| grad(k, i))).collect();
            let jw: Vec<[f64; 3]> = (0..N)
                .map(|i| vee_atb(&r0, &map33(r, |k| grad(k, i))))
                .collect();
            for a in 0..N {
                for b in 0..N {
                    m[a][b] += mass * dot(&j[a], &j[b])
                        + (0..3)
                            .map(|k| jw[a][k] * inertia[k] * jw[b][k])
                            .sum::<f64>();
                }
            }
        };
        let tip = self.walk(&xk, None, |site, pose| {
            if let Site::Node { link, weight } = site {
                let l = &self.links[link];
                body(pose, l.line_mass * weight, l.rotary.map(|j| j * weight));
            }
        });
        let (pt, rt) = &tip;
        let c = self.tip.com_offset;
        let pc: [K<f64, N>; 3] =
            std::array::from_fn(|k| pt[k] + rt[k][0] * c[0] + rt[k][1] * c[1] + rt[k][2] * c[2]);
        body(&(pc, *rt), self.tip.mass, self.tip.inertia);
        m
    }

    /// Energies at (x, v) under constant pressures p.
    pub fn energy_n<const N: usize>(&self, x: &[f64; N], v: &[f64; N], p: &[f64]) -> Energy {
        let zero = [0.0; N];
        let xk = Self::lift(x, v, &zero);
        let mut e = Energy {
            kinetic: 0.0,
            gravity: 0.0,
            elastic: 0.0,
            pressure: 0.0,
        };
        let g = self.gravity;
        let mut body = |pose: &Pose<K<f64, N>>, mass: f64, inertia: [f64; 3]| {
            let (p, r) = pose;
            let pd = map3(p, rate);
            let w = vee_atb(&map33(r, val), &map33(r, rate));
            e.kinetic += 0.5 * mass * dot(&pd, &pd)
                + 0.5 * (0..3).map(|k| inertia[k] * w[k] * w[k]).sum::<f64>();
            e.gravity -= mass * dot(&map3(p, val), &g);
        };
        let tip = self.walk(&xk, None, |site, pose| {
            if let Site::Node { link, weight } = site {
                let l = &self.links[link];
                body(pose, l.line_mass * weight, l.rotary.map(|j| j * weight));
            }
        });
        let (pt, rt) = &tip;
        let c = self.tip.com_offset;
        let pc: [K<f64, N>; 3] =
            std::array::from_fn(|k| pt[k] + rt[k][0] * c[0] + rt[k][1] * c[1] + rt[k][2] * c[2]);
        body(&(pc, *rt), self.tip.mass, self.tip.inertia);
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
        e
    }
}
