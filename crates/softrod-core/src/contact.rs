//! Contact with rigid obstacles by a smoothed penalty (docs/contact.md).
//!
//! Each obstacle has a signed distance d(r) from its surface (positive outside) and an
//! outward unit normal nu(r) at the nearest surface point. The rod's surface at arc length s
//! is a tube of outer radius rho(s) about the centreline r(s), so it penetrates the obstacle
//! by delta = rho - d(r). The obstacle pushes it back with a force per unit reference length
//!   f_c = k ramp_eps(delta) nu,
//!   ramp_eps(delta) = 0 (delta <= 0),  delta^2 / (2 eps) (0 < delta < eps),
//!                     delta - eps/2 (delta >= eps),
//! a C1 ramp (Newton's matrix is continuous) that is exactly zero off contact: k is the
//! penalty stiffness (N/m^2) and eps the smoothing length. f_c = -grad Phi with the potential
//! Phi(r) = k R_eps(rho - d(r)), R_eps' = ramp_eps, so the law is conservative. A rod
//! pressed with a line load q sinks by delta = q / k + eps / 2 (for q >= k eps / 2): the
//! penalty's compliance, which the design's `tolerance` bounds (`Rule::Penetration`).
//! The normal force acts through the centreline (the surface point is r - rho nu), so it
//! carries no moment about it. This is the distance-based penalty of Wriggers,
//! "Computational Contact Mechanics" (Springer, 2006, DOI 10.1007/978-3-540-32609-0), on a
//! Cosserat rod as in Till, Aloi and Rucker, IJRR 2019.
//!
//! Everything here is generic over the scalar (f64, or dual numbers: the derivatives of the
//! load with respect to the rod's position are exact).

use crate::error::{Result, Rule, SoftrodError};
use crate::jet::RodScalar;
use crate::mesh::TriMesh;
use crate::spec::obstacle::{ObstacleKind, ObstacleSpec};
use std::sync::Arc;

/// A compiled obstacle's surface (directions normalised).
#[derive(Debug, Clone, PartialEq)]
pub enum Surface {
    Plane {
        point: [f64; 3],
        normal: [f64; 3],
    },
    Sphere {
        center: [f64; 3],
        radius: f64,
    },
    Cylinder {
        point: [f64; 3],
        axis: [f64; 3],
        radius: f64,
    },
    Capsule {
        start: [f64; 3],
        end: [f64; 3],
        radius: f64,
    },
    /// A rigid triangle mesh with its hierarchy (`crate::mesh`), shared by the copies of
    /// a rod.
    Mesh(Arc<TriMesh>),
}

/// A compiled obstacle with its penalty law.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    pub surface: Surface,
    /// Penalty stiffness k, N/m^2.
    pub stiffness: f64,
    /// Smoothing length eps, m.
    pub smoothing: f64,
    /// Largest penetration a solution may have, m.
    pub tolerance: f64,
    /// Coulomb friction coefficient mu (dynamics only).
    pub friction: f64,
    /// Regularisation velocity of the friction law, m/s.
    pub slip_velocity: f64,
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / n)
}

impl Obstacle {
    /// Compile the validated spec of obstacle `k` (a mesh's topology is checked here: its
    /// errors name `obstacles[k]`).
    pub fn new(o: &ObstacleSpec, k: usize) -> Result<Self> {
        let z = [0.0; 3];
        let radius = o.radius.unwrap_or(0.0);
        let surface = match o.kind {
            ObstacleKind::Plane => Surface::Plane {
                point: o.point.unwrap_or(z),
                normal: unit(o.normal.unwrap_or([0.0, 0.0, 1.0])),
            },
            ObstacleKind::Sphere => Surface::Sphere {
                center: o.center.unwrap_or(z),
                radius,
            },
            ObstacleKind::Cylinder => Surface::Cylinder {
                point: o.point.unwrap_or(z),
                axis: unit(o.axis.unwrap_or([0.0, 0.0, 1.0])),
                radius,
            },
            ObstacleKind::Capsule => Surface::Capsule {
                start: o.start.unwrap_or(z),
                end: o.end.unwrap_or(z),
                radius,
            },
            ObstacleKind::Mesh => Surface::Mesh(Arc::new(TriMesh::new(
                &format!("obstacles[{k}]"),
                o.vertices.as_deref().unwrap_or(&[]),
                o.faces.as_deref().unwrap_or(&[]),
            )?)),
        };
        Ok(Obstacle {
            surface,
            stiffness: o.stiffness,
            smoothing: o.smoothing_length(),
            tolerance: o.tolerance,
            friction: o.friction,
            slip_velocity: o.slip_velocity(),
        })
    }

    /// Signed distance d of point r from the surface (positive outside) and the outward
    /// unit normal at the nearest surface point.
    #[inline]
    pub fn distance<D: RodScalar>(&self, r: &[D; 3]) -> (D, [D; 3]) {
        match &self.surface {
            &Surface::Plane { point, normal } => {
                let mut d = D::from(0.0);
                for k in 0..3 {
                    d += (r[k] - point[k]) * normal[k];
                }
                (d, normal.map(D::from))
            }
            &Surface::Sphere { center, radius } => {
                radial(std::array::from_fn(|k| r[k] - center[k]), radius)
            }
            &Surface::Cylinder {
                point,
                axis,
                radius,
            } => {
                let w: [D; 3] = std::array::from_fn(|k| r[k] - point[k]);
                let mut along = D::from(0.0);
                for k in 0..3 {
                    along += w[k] * axis[k];
                }
                radial(std::array::from_fn(|k| w[k] - along * axis[k]), radius)
            }
            &Surface::Capsule { start, end, radius } => {
                let ab: [f64; 3] = std::array::from_fn(|k| end[k] - start[k]);
                let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
                let mut t = D::from(0.0);
                for k in 0..3 {
                    t += (r[k] - start[k]) * (ab[k] / len2);
                }
                // The nearest point of the segment: an end cap (t clamped: a sphere there)
                // or the side (a cylinder); d is C1 across, since the pieces share their
                // nearest point and normal at t = 0 and t = 1.
                let t = if t.value() <= 0.0 {
                    D::from(0.0)
                } else if t.value() >= 1.0 {
                    D::from(1.0)
                } else {
                    t
                };
                radial(
                    std::array::from_fn(|k| r[k] - (t * ab[k] + start[k])),
                    radius,
                )
            }
            Surface::Mesh(mesh) => mesh.distance(r, self.smoothing),
        }
    }

    /// Whether a cross-section of outer radius `rho` at r is certainly off this obstacle
    /// without computing its distance (a point far outside a closed mesh's box: one box
    /// test instead of a hierarchy query). The penalty is exactly zero there, so skipping
    /// it changes nothing.
    #[inline]
    fn surely_clear<D: RodScalar>(&self, r: &[D; 3], rho: f64) -> bool {
        match &self.surface {
            Surface::Mesh(m) => m.surely_outside_by(&r.map(|x| x.value()), rho),
            _ => false,
        }
    }

    /// Contact force per unit reference length on a rod cross-section of outer radius `rho`
    /// whose centreline is at r (world frame, N/m).
    #[inline]
    pub fn line_force<D: RodScalar>(&self, r: &[D; 3], rho: f64) -> [D; 3] {
        if self.surely_clear(r, rho) {
            return [D::from(0.0); 3];
        }
        let (d, nu) = self.distance(r);
        let Some(p) = self.penalty(-d + rho) else {
            return [D::from(0.0); 3];
        };
        nu.map(|n| n * p)
    }

    /// The normal penalty per unit length k ramp_eps(delta) at the penetration `delta`
    /// (module docs); None off contact, where the force is exactly zero.
    #[inline]
    fn penalty<D: RodScalar>(&self, delta: D) -> Option<D> {
        let eps = self.smoothing;
        if delta.value() <= 0.0 {
            None
        } else if delta.value() < eps {
            Some(delta * delta * (0.5 * self.stiffness / eps))
        } else {
            Some((delta - 0.5 * eps) * self.stiffness)
        }
    }

    /// The penalty potential Phi = k R_eps(delta) of a cross-section of outer radius `rho`
    /// at r, J/m: R_eps(delta) = delta^3 / (6 eps) below eps, delta^2 / 2 - eps delta / 2 +
    /// eps^2 / 6 beyond (R_eps' = ramp_eps, so f_c = -grad Phi).
    pub fn potential(&self, r: &[f64; 3], rho: f64) -> f64 {
        let (d, _) = self.distance(r);
        let delta = rho - d;
        let eps = self.smoothing;
        let k = self.stiffness;
        if delta <= 0.0 {
            0.0
        } else if delta < eps {
            k * delta * delta * delta / (6.0 * eps)
        } else {
            k * (0.5 * delta * delta - 0.5 * eps * delta + eps * eps / 6.0)
        }
    }

    /// The contact load on a cross-section of outer radius `rho` whose centreline is at r
    /// and moves with velocity `vel` while the section turns at `omega` (world frame): the
    /// normal penalty force f_n = k ramp_eps(delta) nu and the regularised Coulomb
    /// friction at the contact point r - rho nu,
    ///   v_s = vel + omega x (-rho nu),  v_t = v_s - (v_s . nu) nu,
    ///   f_t = -mu |f_n| v_t / sqrt(|v_t|^2 + v_reg^2),
    /// a smooth saturation that reaches the Coulomb bound mu |f_n| for |v_t| >> v_reg
    /// (docs/contact.md, "Dynamics"). Force per unit length (normal and friction), the
    /// friction's moment about the centreline (-rho nu) x f_t, and the friction force f_t.
    #[inline]
    pub fn section_load<D: RodScalar>(
        &self,
        r: &[D; 3],
        vel: &[D; 3],
        omega: &[D; 3],
        rho: f64,
    ) -> SectionLoad<D> {
        let mut out = SectionLoad::zero();
        if self.surely_clear(r, rho) {
            return out;
        }
        let (d, nu) = self.distance(r);
        let Some(p) = self.penalty(-d + rho) else {
            return out;
        };
        out.force = nu.map(|n| n * p);
        if self.friction > 0.0 {
            let arm = nu.map(|n| n * -rho);
            let oxa = cross(omega, &arm);
            let vs: [D; 3] = std::array::from_fn(|k| vel[k] + oxa[k]);
            let vn = vs[0] * nu[0] + vs[1] * nu[1] + vs[2] * nu[2];
            let vt: [D; 3] = std::array::from_fn(|k| vs[k] - vn * nu[k]);
            let v2 = vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2];
            let g = (v2 + self.slip_velocity * self.slip_velocity)
                .sqrt()
                .recip();
            let ft: [D; 3] = std::array::from_fn(|k| vt[k] * g * p * -self.friction);
            let m = cross(&arm, &ft);
            for k in 0..3 {
                out.force[k] += ft[k];
            }
            out.moment = m;
            out.friction = ft;
        }
        out
    }
}

/// What one contact point of the frictional statics remembers from the last converged
/// load increment (docs/contact.md, "Friction in the statics"): the section's centreline
/// position and rotation there (so the material surface point r + R b, b fixed in the
/// body, is tracked through the rod's rotation: rolling is not slip) and, per obstacle, the
/// elastic tangential displacement e of the penalty's tangential spring (m).
#[derive(Debug, Clone, PartialEq)]
pub struct StickPoint {
    pub r: [f64; 3],
    pub rot: [[f64; 3]; 3],
    /// One per obstacle (zero off contact).
    pub e: Vec<[f64; 3]>,
}

/// The frictional contact load of the statics on one point ([`Obstacle::stick_load`]):
/// the total force (normal and tangential), the friction's moment about the centreline,
/// the tangential part, and the elastic tangential displacement after the return map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StickLoad<D> {
    pub force: [D; 3],
    pub moment: [D; 3],
    pub friction: [D; 3],
    pub e: [D; 3],
}

impl<D: RodScalar> StickLoad<D> {
    /// No load and nothing stored (off contact).
    pub fn zero() -> Self {
        let zero = D::from(0.0);
        StickLoad {
            force: [zero; 3],
            moment: [zero; 3],
            friction: [zero; 3],
            e: [zero; 3],
        }
    }
}

impl Obstacle {
    /// The statics' contact load with elastic-slip Coulomb friction on a cross-section of
    /// outer radius `rho` at centreline r with rotation `rot` (body to world, row-major),
    /// given the point's state `old` of the last converged increment (`k`: this
    /// obstacle's index in it). `scale` turns the line law into the load: 1 for a line load
    /// (N/m), rho for the rounded end (a point force, N: the penalty over the cap's
    /// length, as `end_force`). With the contact offset a = -rho nu (the surface point of
    /// the section that touches) and b = R^T a fixed in the body, the slip of that
    /// material point over the increment is
    ///   ds = (r + R b) - (r_old + R_old b) = r - r_old + a - R_old R^T a,
    /// and the return map (Wriggers, "Computational Contact Mechanics", Springer 2006,
    /// DOI 10.1007/978-3-540-32609-0, Sec. 5.2 on the elastic-slip friction law) is
    ///   e_tr = P_t (e_old + ds),  f_tr = -k_t e_tr,  P_t = I - nu nu^T,
    ///   stick (|f_tr| <= mu |f_n|):  f_t = f_tr,                   e = e_tr,
    ///   slip:                        f_t = mu |f_n| f_tr / |f_tr|,  e = -f_t / k_t,
    /// with k_t = k scale (the normal penalty stiffness). The moment about the centreline
    /// is a x f_t. A point that lands on the obstacle during the increment is anchored
    /// where its material point was at the increment's start (its flight before touching
    /// counts as slip: first order in the increment, as the rest of the path; so the path
    /// lands in increments no longer than the default path's, `statics::friction::follow`).
    /// Continuous in the state, with a kink at the stick/slip switch (Newton
    /// is semi-smooth there); generic over the scalar, so the shooting Jacobian is exact
    /// on either side.
    #[inline]
    pub fn stick_load<D: RodScalar>(
        &self,
        r: &[D; 3],
        rot: &[[D; 3]; 3],
        rho: f64,
        scale: f64,
        old: &StickPoint,
        k: usize,
    ) -> StickLoad<D> {
        let mut out = StickLoad::zero();
        if self.surely_clear(r, rho) {
            return out;
        }
        let (d, nu) = self.distance(r);
        let Some(p) = self.penalty(-d + rho).map(|p| p * scale) else {
            return out;
        };
        out.force = nu.map(|n| n * p);
        if self.friction == 0.0 {
            return out;
        }
        let e_old = &old.e[k];
        let kt = self.stiffness * scale;
        let a = nu.map(|n| n * -rho);
        // b = R^T a (body frame), then R_old b.
        let b: [D; 3] =
            std::array::from_fn(|j| rot[0][j] * a[0] + rot[1][j] * a[1] + rot[2][j] * a[2]);
        let a_old: [D; 3] = std::array::from_fn(|i| {
            b[0] * old.rot[i][0] + b[1] * old.rot[i][1] + b[2] * old.rot[i][2]
        });
        let trial: [D; 3] = std::array::from_fn(|i| r[i] - old.r[i] + a[i] - a_old[i] + e_old[i]);
        let tn = trial[0] * nu[0] + trial[1] * nu[1] + trial[2] * nu[2];
        let et: [D; 3] = std::array::from_fn(|i| trial[i] - tn * nu[i]);
        let n2 = et[0] * et[0] + et[1] * et[1] + et[2] * et[2];
        let cap = p * self.friction;
        let (ft, e) = if n2.value() * kt * kt <= cap.value() * cap.value() {
            (et.map(|x| x * -kt), et)
        } else {
            // |f_tr| > mu |f_n| >= 0, so |e_tr| > 0.
            let shrink = cap * (n2.sqrt() * kt).recip();
            (et.map(|x| x * shrink * -kt), et.map(|x| x * shrink))
        };
        let m = cross(&a, &ft);
        for k in 0..3 {
            out.force[k] += ft[k];
        }
        out.moment = m;
        out.friction = ft;
        out.e = e;
        out
    }
}

/// The sum of all obstacles' [`Obstacle::stick_load`] at a point with state `old`.
#[inline]
pub fn total_stick_load<D: RodScalar>(
    obstacles: &[Obstacle],
    r: &[D; 3],
    rot: &[[D; 3]; 3],
    rho: f64,
    scale: f64,
    old: &StickPoint,
) -> StickLoad<D> {
    let mut out = StickLoad::zero();
    for (k, o) in obstacles.iter().enumerate() {
        let g = o.stick_load(r, rot, rho, scale, old, k);
        for i in 0..3 {
            out.force[i] += g.force[i];
            out.moment[i] += g.moment[i];
            out.friction[i] += g.friction[i];
        }
    }
    out
}

/// A contact load on a cross-section ([`Obstacle::section_load`]): force (N/m) and moment
/// about the centreline (N m/m), world frame, and the friction part of the force (N/m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionLoad<D> {
    pub force: [D; 3],
    pub moment: [D; 3],
    pub friction: [D; 3],
}

impl<D: RodScalar> SectionLoad<D> {
    /// No load (off contact).
    pub fn zero() -> Self {
        let zero = D::from(0.0);
        SectionLoad {
            force: [zero; 3],
            moment: [zero; 3],
            friction: [zero; 3],
        }
    }
}

/// The sum of all obstacles' [`Obstacle::section_load`].
#[inline]
pub fn total_section_load<D: RodScalar>(
    obstacles: &[Obstacle],
    r: &[D; 3],
    vel: &[D; 3],
    omega: &[D; 3],
    rho: f64,
) -> SectionLoad<D> {
    let mut out = SectionLoad::zero();
    for o in obstacles {
        let g = o.section_load(r, vel, omega, rho);
        for k in 0..3 {
            out.force[k] += g.force[k];
            out.moment[k] += g.moment[k];
            out.friction[k] += g.friction[k];
        }
    }
    out
}

#[inline]
fn cross<D: RodScalar>(a: &[D; 3], b: &[D; 3]) -> [D; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Distance and outward normal for a surface at distance `radius` from a point or an axis,
/// given w: the point's offset from the nearest point of that centre. At w = 0 (the rod's
/// centreline on the centre itself, far beyond any tolerance) the normal is +z: the
/// penetration check reports that state.
#[inline]
fn radial<D: RodScalar>(w: [D; 3], radius: f64) -> (D, [D; 3]) {
    let n2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if n2.value() <= 0.0 || !n2.value().is_finite() {
        let zero = D::from(0.0);
        return (zero - radius, [zero, zero, zero + 1.0]);
    }
    let n = n2.sqrt();
    let inv = n.recip();
    (n - radius, w.map(|x| x * inv))
}

/// Sum of the contact forces per unit length of all obstacles at r (N/m, world frame).
#[inline]
pub fn total_line_force<D: RodScalar>(obstacles: &[Obstacle], r: &[D; 3], rho: f64) -> [D; 3] {
    let mut f = [D::from(0.0); 3];
    for o in obstacles {
        let g = o.line_force(r, rho);
        for k in 0..3 {
            f[k] += g[k];
        }
    }
    f
}

/// What a solution reports at one node: the penetration-closest obstacle and the contact
/// state there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeContact {
    /// Index of the obstacle nearest to the rod's surface.
    pub obstacle: usize,
    /// Gap between the rod's surface and that obstacle, m (negative: penetration).
    pub gap: f64,
    /// The nearest point of that obstacle's surface (the contact point when in contact), m.
    pub point: [f64; 3],
    /// Sum of all obstacles' contact forces per unit length, N/m (world frame).
    pub force: [f64; 3],
}

/// The contact state of a node with centreline at r and surface radius rho.
pub fn node_contact(obstacles: &[Obstacle], r: &[f64; 3], rho: f64) -> Option<NodeContact> {
    let mut best: Option<NodeContact> = None;
    for (k, o) in obstacles.iter().enumerate() {
        let (d, nu) = o.distance(r);
        let gap = d - rho;
        if best.is_none_or(|b| gap < b.gap) {
            best = Some(NodeContact {
                obstacle: k,
                gap,
                point: std::array::from_fn(|i| r[i] - d * nu[i]),
                force: [0.0; 3],
            });
        }
    }
    best.map(|mut b| {
        b.force = total_line_force(obstacles, r, rho);
        b
    })
}

/// The penetration rule at a node: the rod's surface (radius `rho` about the centreline
/// r) may sink into no obstacle deeper than that obstacle's tolerance.
pub fn check_penetration(
    obstacles: &[Obstacle],
    node: crate::validity::Node,
    r: &[f64; 3],
    rho: f64,
) -> Result<()> {
    for (k, o) in obstacles.iter().enumerate() {
        let (d, _) = o.distance(r);
        let depth = rho - d;
        if depth > o.tolerance || depth.is_nan() {
            return Err(SoftrodError::InvalidState {
                rule: Rule::Penetration,
                node: Some(node.index),
                s: node.s,
                time: None,
                value: depth,
                message: format!(
                    "the rod sinks {depth:.3e} m into obstacles[{k}], deeper than its tolerance {:.3e} m (the penalty's compliance: a line load q sinks it by q / k + eps / 2 with k = {:.3e} N/m^2; raise the stiffness or the tolerance)",
                    o.tolerance, o.stiffness
                ),
            });
        }
    }
    Ok(())
}

/// A piece of the centreline between two points where the solver feels the obstacles (its
/// integration or collocation points), as a cubic in sigma in [0, 1]:
/// r(sigma) = c[0] + c[1] sigma + c[2] sigma^2 + c[3] sigma^3, from arc length `s` over the
/// length `h`, with the surface radius linear from `rho[0]` to `rho[1]` (exact for a
/// tapered section). The penalty acts only at those points, so an obstacle smaller than
/// the spacing can lie between two of them unfelt, with the rod passing through it:
/// [`check_between`] finds that.
#[derive(Debug, Clone, Copy)]
pub struct Piece {
    pub c: [[f64; 3]; 4],
    pub s: f64,
    pub h: f64,
    pub rho: [f64; 2],
}

impl Piece {
    /// The cubic Hermite piece through positions `ra`, `rb` with derivatives d r / d s
    /// `da`, `db` (fourth-order accurate in h where the centreline is smooth).
    pub fn hermite(
        s: f64,
        h: f64,
        ra: &[f64; 3],
        da: &[f64; 3],
        rb: &[f64; 3],
        db: &[f64; 3],
        rho: [f64; 2],
    ) -> Self {
        let c = [
            *ra,
            std::array::from_fn(|i| h * da[i]),
            std::array::from_fn(|i| 3.0 * (rb[i] - ra[i]) - h * (2.0 * da[i] + db[i])),
            std::array::from_fn(|i| 2.0 * (ra[i] - rb[i]) + h * (da[i] + db[i])),
        ];
        Piece { c, s, h, rho }
    }

    /// The cubic through four points `r` at the parameters `sigma` (distinct, in [0, 1]),
    /// by Lagrange interpolation written in monomials.
    pub fn through(s: f64, h: f64, sigma: [f64; 4], r: [&[f64; 3]; 4], rho: [f64; 2]) -> Self {
        let mut c = [[0.0; 3]; 4];
        for k in 0..4 {
            // l_k(x) = prod_{j != k} (x - sigma_j) / (sigma_k - sigma_j), expanded.
            let mut poly = [1.0, 0.0, 0.0, 0.0];
            let mut denom = 1.0;
            for j in (0..4).filter(|&j| j != k) {
                let mut next = [0.0; 4];
                for d in 0..3 {
                    next[d + 1] += poly[d];
                    next[d] -= sigma[j] * poly[d];
                }
                poly = next;
                denom *= sigma[k] - sigma[j];
            }
            for d in 0..4 {
                for i in 0..3 {
                    c[d][i] += r[k][i] * poly[d] / denom;
                }
            }
        }
        Piece { c, s, h, rho }
    }

    fn at(&self, x: f64) -> [f64; 3] {
        std::array::from_fn(|i| {
            self.c[0][i] + x * (self.c[1][i] + x * (self.c[2][i] + x * self.c[3][i]))
        })
    }

    /// A bound on |d r / d sigma| over [0, 1]: |c1| + 2 |c2| + 3 |c3|.
    fn speed_bound(&self) -> f64 {
        let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        norm(&self.c[1]) + 2.0 * norm(&self.c[2]) + 3.0 * norm(&self.c[3])
    }
}

/// A node of a static solution for [`check_after`]: where it is, the centreline's
/// derivative d r / d s = R v there, and the surface radius.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    node: crate::validity::Node,
    r: [f64; 3],
    dr: [f64; 3],
    rho: f64,
}

impl Sample {
    /// The sample of a node with centreline r, rotation `rot` (body to world) and body
    /// strain v.
    pub fn of(
        node: crate::validity::Node,
        r: &[f64; 3],
        rot: &[[f64; 3]; 3],
        v: &[f64; 3],
        rho: f64,
    ) -> Self {
        let dr = std::array::from_fn(|i| rot[i][0] * v[0] + rot[i][1] * v[1] + rot[i][2] * v[2]);
        Sample {
            node,
            r: *r,
            dr,
            rho,
        }
    }
}

/// [`check_between`] on the cubic Hermite piece between consecutive nodes `a` and `b` of a
/// static solution (the nodes are RK4 step ends; nothing to check where they coincide, at a
/// section boundary).
pub fn check_after(obstacles: &[Obstacle], a: &Sample, b: &Sample) -> Result<()> {
    let h = b.node.s - a.node.s;
    if h <= 0.0 {
        return Ok(());
    }
    let piece = Piece::hermite(a.node.s, h, &a.r, &a.dr, &b.r, &b.dr, [a.rho, b.rho]);
    check_between(obstacles, &piece, a.node)
}

/// The penetration rule between two points where the solver feels the obstacles (which
/// [`check_penetration`] checks), along `piece`: the first obstacle found that the rod's
/// surface sinks into deeper than its tolerance, as (obstacle, sigma, depth), or None. The
/// gap g(sigma) = d(r(sigma)) - rho(sigma) changes by at most Lip = |dr/dsigma| +
/// |rho1 - rho0| per unit sigma (d is 1-Lipschitz), so on a stretch [a, b] with end gaps
/// ga, gb its minimum is at least (ga + gb) / 2 - Lip (b - a) / 2: stretches that cannot
/// reach below -tolerance are done, the others are halved, down to a resolution where the
/// bound is within 5 % of the tolerance (so a point found deeper is at least that deep on
/// the piece, and one accepted at most 5 % deeper than allowed). To a plane the gap is a
/// cubic in sigma, minimised exactly.
pub fn deepest_between(obstacles: &[Obstacle], piece: &Piece) -> Option<(usize, f64, f64)> {
    deepest_beyond(obstacles, piece, |k| obstacles[k].tolerance)
}

/// [`deepest_between`] with the depth allowed in obstacle k given by `limit(k)` (m) in
/// place of its tolerance.
pub fn deepest_beyond(
    obstacles: &[Obstacle],
    piece: &Piece,
    limit: impl Fn(usize) -> f64,
) -> Option<(usize, f64, f64)> {
    let lip = piece.speed_bound() + (piece.rho[1] - piece.rho[0]).abs();
    let rho = |x: f64| piece.rho[0] + x * (piece.rho[1] - piece.rho[0]);
    for (k, o) in obstacles.iter().enumerate() {
        let tol = limit(k);
        let gap = |x: f64| o.distance(&piece.at(x)).0 - rho(x);
        let too_deep = |depth: f64| depth > tol || depth.is_nan();
        if let Surface::Plane { normal, .. } = &o.surface {
            // The zeros of the gap's derivative a1 + 2 a2 x + 3 a3 x^2 and the ends.
            let dot = |v: &[f64; 3]| v[0] * normal[0] + v[1] * normal[1] + v[2] * normal[2];
            let (a1, a2, a3) = (
                dot(&piece.c[1]) - (piece.rho[1] - piece.rho[0]),
                dot(&piece.c[2]),
                dot(&piece.c[3]),
            );
            let mut deepest = (f64::NEG_INFINITY, 0.0);
            for x in [0.0, 1.0].into_iter().chain(stationary(a1, a2, a3)) {
                let depth = -gap(x);
                if depth > deepest.0 || depth.is_nan() {
                    deepest = (depth, x);
                }
            }
            if too_deep(deepest.0) {
                return Some((k, deepest.1, deepest.0));
            }
            continue;
        }
        let resolution = 0.1 * tol;
        let mut stack = vec![(0.0, 1.0, gap(0.0), gap(1.0))];
        // Each halving shrinks Lip (b - a) by 2: at most log2(Lip / resolution) levels.
        while let Some((a, b, ga, gb)) = stack.pop() {
            if too_deep(-ga.min(gb)) {
                let x = if ga <= gb { a } else { b };
                return Some((k, x, -ga.min(gb)));
            }
            if 0.5 * (ga + gb) - 0.5 * lip * (b - a) >= -tol || lip * (b - a) <= resolution {
                continue;
            }
            let m = 0.5 * (a + b);
            let gm = gap(m);
            stack.push((a, m, ga, gm));
            stack.push((m, b, gm, gb));
        }
    }
    None
}

/// [`deepest_between`] as the penetration rule along the centreline between two points
/// where the solver feels the obstacles: an error that names the obstacle, the depth, the
/// spacing and the fix (shorter steps along the rod). `node` is the piece's first point.
pub fn check_between(
    obstacles: &[Obstacle],
    piece: &Piece,
    node: crate::validity::Node,
) -> Result<()> {
    let Some((k, x, depth)) = deepest_between(obstacles, piece) else {
        return Ok(());
    };
    let o = &obstacles[k];
    Err(SoftrodError::InvalidState {
        rule: Rule::Penetration,
        node: Some(node.index),
        s: piece.s + x * piece.h,
        time: None,
        value: depth,
        message: format!(
            "the rod passes {depth:.3e} m into obstacles[{k}] between the points where the solver feels the obstacles (s = {:.6} to {:.6} m), deeper than its tolerance {:.3e} m: the obstacle is too small for that spacing and its contact is not resolved; use shorter steps there (the section's `steps` or numerics.steps_per_section) so that several points fall inside the contact",
            piece.s,
            piece.s + piece.h,
            o.tolerance
        ),
    })
}

/// The zeros in (0, 1) of a1 + 2 a2 x + 3 a3 x^2.
fn stationary(a1: f64, a2: f64, a3: f64) -> impl Iterator<Item = f64> {
    let (a, b, c) = (3.0 * a3, 2.0 * a2, a1);
    let roots: [f64; 2] = if a.abs() <= 1e-14 * (b.abs() + c.abs()) {
        [if b != 0.0 { -c / b } else { f64::NAN }, f64::NAN]
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            [f64::NAN; 2]
        } else {
            // The stable pair of roots: q = -(b + sign(b) sqrt(disc)) / 2.
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            [q / a, if q != 0.0 { c / q } else { f64::NAN }]
        }
    };
    roots.into_iter().filter(|x| *x > 0.0 && *x < 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jet::Jet;

    fn spec(kind: ObstacleKind) -> ObstacleSpec {
        ObstacleSpec {
            kind,
            point: None,
            normal: None,
            center: None,
            axis: None,
            start: None,
            end: None,
            radius: None,
            vertices: None,
            faces: None,
            stiffness: 1e4,
            tolerance: 1e-3,
            smoothing: Some(1e-4),
            friction: 0.0,
            slip_velocity: None,
        }
    }

    fn shapes() -> Vec<Obstacle> {
        let mut out = vec![];
        let mut s = spec(ObstacleKind::Plane);
        s.point = Some([0.1, -0.2, 0.05]);
        s.normal = Some([0.3, -0.4, 1.2]);
        out.push(Obstacle::new(&s, 0).unwrap());
        let mut s = spec(ObstacleKind::Sphere);
        s.center = Some([0.02, 0.01, -0.03]);
        s.radius = Some(0.04);
        out.push(Obstacle::new(&s, 0).unwrap());
        let mut s = spec(ObstacleKind::Cylinder);
        s.point = Some([0.0, 0.01, 0.0]);
        s.axis = Some([1.0, 2.0, -0.5]);
        s.radius = Some(0.03);
        out.push(Obstacle::new(&s, 0).unwrap());
        let mut s = spec(ObstacleKind::Capsule);
        s.start = Some([-0.02, 0.0, 0.0]);
        s.end = Some([0.03, 0.02, -0.01]);
        s.radius = Some(0.025);
        out.push(Obstacle::new(&s, 0).unwrap());
        out
    }

    /// Closed forms of the distance: a point 5 mm above a plane through the origin with
    /// normal z, a point on a sphere's radius, a point beside a cylinder's axis and beyond
    /// a capsule's end cap.
    #[test]
    fn distances_match_closed_forms() {
        let mut s = spec(ObstacleKind::Plane);
        s.point = Some([0.0; 3]);
        s.normal = Some([0.0, 0.0, 2.0]);
        let (d, n) = Obstacle::new(&s, 0)
            .unwrap()
            .distance::<f64>(&[0.3, -0.1, 0.005]);
        assert!((d - 0.005).abs() < 1e-15 && n == [0.0, 0.0, 1.0]);
        let mut s = spec(ObstacleKind::Sphere);
        s.center = Some([1.0, 0.0, 0.0]);
        s.radius = Some(0.5);
        let (d, n) = Obstacle::new(&s, 0)
            .unwrap()
            .distance::<f64>(&[1.0, 0.0, 0.8]);
        assert!((d - 0.3).abs() < 1e-15 && (n[2] - 1.0).abs() < 1e-15);
        let mut s = spec(ObstacleKind::Cylinder);
        s.point = Some([0.0; 3]);
        s.axis = Some([0.0, 0.0, 1.0]);
        s.radius = Some(0.1);
        let (d, _) = Obstacle::new(&s, 0)
            .unwrap()
            .distance::<f64>(&[0.3, 0.4, 7.0]);
        assert!((d - 0.4).abs() < 1e-15);
        let mut s = spec(ObstacleKind::Capsule);
        s.start = Some([0.0; 3]);
        s.end = Some([1.0, 0.0, 0.0]);
        s.radius = Some(0.1);
        let o = Obstacle::new(&s, 0).unwrap();
        let (d, _) = o.distance::<f64>(&[1.3, 0.4, 0.0]);
        assert!((d - 0.4).abs() < 1e-15);
        let (d, _) = o.distance::<f64>(&[0.5, 0.0, -0.3]);
        assert!((d - 0.2).abs() < 1e-15);
    }

    /// The dual-number derivative of the contact force equals central differences at
    /// points in the ramp's smooth part (quadratic and linear branches) for every shape.
    #[test]
    fn force_derivative_matches_finite_differences() {
        for o in shapes() {
            // Points near each surface at penetrations inside and beyond eps.
            for (k, depth) in [(0usize, 3e-5), (1, 4e-4), (2, 2e-3)] {
                let probe = [0.011 * k as f64, -0.007, 0.004 + 0.001 * k as f64];
                let (d, nu) = o.distance(&probe);
                let rho = 0.005;
                let r: [f64; 3] = std::array::from_fn(|i| probe[i] - (d - rho + depth) * nu[i]);
                let rj: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(r[i], i));
                let f = o.line_force(&rj, rho);
                assert!(f.iter().any(|x| x.re != 0.0));
                for j in 0..3 {
                    let h = 1e-7;
                    let mut a = r;
                    let mut b = r;
                    a[j] += h;
                    b[j] -= h;
                    let (fa, fb) = (o.line_force(&a, rho), o.line_force(&b, rho));
                    for i in 0..3 {
                        let fd = (fa[i] - fb[i]) / (2.0 * h);
                        // Central differences err by h^2 f''' / 6 plus round-off
                        // ~1e-16 |f| / h; both are below 1e-6 of k here.
                        assert!(
                            (fd - f[i].eps[j]).abs() <= 1e-6 * o.stiffness,
                            "{:?} d f{i}/d r{j}: dual {} fd {fd}",
                            o.surface,
                            f[i].eps[j]
                        );
                    }
                }
            }
        }
    }

    /// The ramp is C1: value and slope continuous at delta = 0 and delta = eps; a rod
    /// pressed by q sinks by q / k + eps / 2.
    #[test]
    fn ramp_is_c1_and_sinks_by_the_compliance() {
        let mut s = spec(ObstacleKind::Plane);
        s.point = Some([0.0; 3]);
        s.normal = Some([0.0, 0.0, 1.0]);
        let o = Obstacle::new(&s, 0).unwrap();
        let f = |z: f64| o.line_force(&[0.0, 0.0, z], 0.0)[2];
        let eps = o.smoothing;
        let tiny = 1e-12;
        for z in [0.0, -eps] {
            assert!((f(z - tiny) - f(z + tiny)).abs() < 1e-6);
            let slope = |z: f64| (f(z + 1e-9) - f(z - 1e-9)) / 2e-9;
            assert!((slope(z - 1e-8) - slope(z + 1e-8)).abs() < 1e-2 * o.stiffness);
        }
        assert_eq!(f(1e-9), 0.0);
        let q = 3.0;
        let sink = q / o.stiffness + 0.5 * eps;
        assert!((f(-sink) - q).abs() < 1e-12);
    }
}
