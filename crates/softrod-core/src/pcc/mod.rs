//! Piecewise-constant-curvature (PCC) Lagrangian model of paper 003 ("Dynamic modelling and
//! visco-elastic parameter identification of a fibre-reinforced soft fluidic elastomer
//! manipulator"), built from the same `DesignSpec` as the Cosserat rod.
//!
//! Every deformable section of the design is one constant-curvature segment with
//! configuration (L, theta, phi) (paper eqs. 1-4); rigid sections are straight rigid links.
//! Internally the segment is described by the regular bending vector
//! (L, theta_x, theta_y) = (L, theta cos phi, theta sin phi) (see `kinematics`), so that the
//! dynamics stay regular at theta = 0; a planar model (paper eq. 12) keeps (L, theta) with
//! the bending plane fixed at angle `plane`.
//!
//! - Mass matrix, Coriolis and gravity terms come from one Lagrangian: the mass of the
//!   sections is integrated along the arc (Gauss-Legendre), with the rotary inertia of the
//!   cross-sections, plus the tip body (`lagrangian`). `mass_model = "tip"` lumps all mass at
//!   the tip without rotary inertia, as paper 003 eq. 6 does.
//! - Chamber pressures do the virtual work p_k A_k delta l_k, l_k the chamber length
//!   (`pressure_force = "chamber"`, consistent with the rod's constitutive pressure law), or
//!   act as tip follower forces at the chamber centroids as in paper eqs. 9-13
//!   (`pressure_force = "tip_force"`).
//! - Visco-elastic forces k_L d + b_L d_t, k_theta(theta) theta + b_theta theta_t (paper Sec.
//!   IV-B), and an anisotropy k_phi, b_phi for bending towards d2 (see `PccSpec`).
//!
//! `integrate` steps the equations with the implicit midpoint rule (Newton, exact Jacobian
//! from dual numbers) and solves the statics.

/// Call `$f::<N>(...)` with the const N of a model's number of coordinates.
macro_rules! dispatch {
    ($n:expr, $f:ident ( $($arg:expr),* )) => {
        match $n {
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            6 => $f::<6>($($arg),*),
            8 => $f::<8>($($arg),*),
            9 => $f::<9>($($arg),*),
            10 => $f::<10>($($arg),*),
            12 => $f::<12>($($arg),*),
            14 => $f::<14>($($arg),*),
            15 => $f::<15>($($arg),*),
            n => Err(SoftrodError::invalid(
                "sections",
                n,
                "the PCC model supports at most 5 deformable sections (7 when planar)",
            )),
        }
    };
}

pub mod integrate;
pub mod jet;
pub mod kinematics;
pub mod lagrangian;
pub mod sensitivity;

use crate::error::{Result, SoftrodError};
use crate::rod::Rod;
use crate::spec::pcc::check;
use crate::spec::{DesignSpec, TipSpec};

pub use crate::spec::pcc::{MassModel, PccSpec, PccTable, PressureModel};
pub use integrate::{InitialState, PccStatic, PccTrajectory, StepOptions};

/// k_theta: constant or piecewise linear in theta.
#[derive(Debug, Clone, PartialEq)]
pub enum BendStiffness {
    Constant(f64),
    Table(Vec<f64>, Vec<f64>),
}

impl BendStiffness {
    /// k_theta(theta) and its derivative.
    pub fn eval(&self, theta: f64) -> (f64, f64) {
        match self {
            BendStiffness::Constant(k) => (*k, 0.0),
            BendStiffness::Table(a, k) => {
                let n = a.len();
                if theta <= a[0] {
                    return (k[0], 0.0);
                }
                if theta >= a[n - 1] {
                    return (k[n - 1], 0.0);
                }
                let i = a.partition_point(|&x| x <= theta) - 1;
                let s = (k[i + 1] - k[i]) / (a[i + 1] - a[i]);
                (k[i] + s * (theta - a[i]), s)
            }
        }
    }

    /// Elastic energy int_0^theta k(t) t dt (exact for the piecewise linear table).
    pub fn energy(&self, theta: f64) -> f64 {
        match self {
            BendStiffness::Constant(k) => 0.5 * k * theta * theta,
            BendStiffness::Table(a, _) => {
                // int t k(t) dt over [lo, hi] where k is linear: Simpson is exact (cubic).
                let piece = |lo: f64, hi: f64| {
                    let m = 0.5 * (lo + hi);
                    let f = |t: f64| t * self.eval(t).0;
                    (hi - lo) / 6.0 * (f(lo) + 4.0 * f(m) + f(hi))
                };
                let mut knots = vec![0.0];
                knots.extend(a.iter().copied().filter(|&x| x > 0.0 && x < theta));
                knots.push(theta);
                knots.windows(2).map(|w| piece(w[0], w[1])).sum()
            }
        }
    }
}

/// Visco-elastic parameters of one segment.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentParams {
    pub k_l: f64,
    pub b_l: f64,
    pub k_theta: BendStiffness,
    pub b_theta: f64,
    pub k_phi: f64,
    pub b_phi: f64,
}

/// A chamber as the PCC model sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PccChamber {
    pub area: f64,
    /// Centroid in the section frame (d1, d2), m.
    pub centroid: [f64; 2],
    pub channel: usize,
}

#[derive(Debug, Clone, PartialEq)]
pub enum LinkKind {
    /// Straight and rigid.
    Rigid,
    /// Constant curvature; its coordinates start at `offset` in the model's vector.
    Segment {
        offset: usize,
        params: SegmentParams,
    },
}

/// One section of the chain.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub name: String,
    pub kind: LinkKind,
    /// Reference length L0, m.
    pub length: f64,
    /// Mass per reference length, kg/m (0 under `MassModel::Tip`).
    pub line_mass: f64,
    /// Rotary inertia per reference length about (d1, d2, d3), kg m.
    pub rotary: [f64; 3],
    /// Dead line loads, world frame: force N/m and moment N m/m.
    pub line_force: [f64; 3],
    pub line_moment: [f64; 3],
    pub chambers: Vec<PccChamber>,
}

/// The compiled PCC model of a design (immutable).
#[derive(Debug, Clone, PartialEq)]
pub struct PccModel {
    pub links: Vec<Link>,
    /// Number of generalised coordinates: 3 per segment (2 if planar).
    pub ndof: usize,
    /// Planar model: (cos, sin) of the bending plane angle.
    pub plane: Option<(f64, f64)>,
    pub base_position: [f64; 3],
    /// Rows of [d1 d2 d3] at the base.
    pub base_rotation: [[f64; 3]; 3],
    pub gravity: [f64; 3],
    /// Tip body (with the rod's mass added under `MassModel::Tip`) and dead tip loads.
    pub tip: TipSpec,
    pub n_channels: usize,
    pub pressure_model: PressureModel,
    /// Gauss-Legendre nodes and weights on [0, 1].
    pub nodes: Vec<(f64, f64)>,
    /// The pressure supply (lag and rate limit) of the design's `[dynamics]` table, shared
    /// with the rod's dynamics so that both models see the same chamber pressures.
    pub supply: crate::spec::DynamicsSpec,
}

/// Supported numbers of coordinates (up to 5 spatial or 7 planar segments).
pub const SUPPORTED_DOF: [usize; 10] = [2, 3, 4, 6, 8, 9, 10, 12, 14, 15];

/// Gauss-Legendre nodes and weights on [0, 1] (Newton on P_n, Golub-Welsch-free).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 - x), 0.5 * w));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

impl PccModel {
    /// Validate the design and compile its PCC model.
    pub fn new(spec: &DesignSpec) -> Result<Self> {
        let rod = Rod::new(spec.clone())?;
        crate::scope::check_statics_only(&rod, "the PCC model")?;
        if let Some(k) = crate::statics::system::mapped_section(&rod) {
            // sigma(p) scales the Cosserat section's stiffness (paper 001); the PCC model has
            // its own (k_L, k_theta, k_phi), so a mapped design would silently lose its map.
            return Err(SoftrodError::invalid(
                format!("sections[{k}].law.stiffness_map"),
                true,
                "a stiffness-mapped section (sigma(p) scales the rod model's section \
                 stiffness) is not carried by the PCC model, which has its own stiffness \
                 parameters (k_L, k_theta, k_phi): solve the rod model, or a design without \
                 mapped sections",
            ));
        }
        let pspec = spec.pcc.clone().unwrap_or_default();
        pspec.validate()?;
        let tau = spec.dynamics.damping_time;
        let planar = pspec.plane.map(|a| (a.cos(), a.sin()));
        let per = if planar.is_some() { 2 } else { 3 };
        let mut links = Vec::new();
        let mut ndof = 0;
        let mut rod_mass = 0.0;
        for (sec, s) in rod.sections.iter().zip(&spec.sections) {
            let chambers: Vec<PccChamber> = sec
                .chambers
                .iter()
                .map(|c| PccChamber {
                    area: c.area,
                    centroid: c.centroid,
                    channel: c.channel,
                })
                .collect();
            let kind = if sec.rigid {
                LinkKind::Rigid
            } else {
                let l0 = sec.length;
                // Arc of constant curvature u = theta / L0 (per reference length, as in
                // the rod): bending energy 1/2 L0 u^T K_bt u = 1/2 (EI/L0) theta^2.
                let k_l_rod = sec.k_se[2] / l0;
                let k_t_rod = sec.k_bt[1][1] / l0;
                let k_p_rod = (sec.k_bt[0][0] - sec.k_bt[1][1]) / l0;
                let given = if chambers.is_empty() {
                    PccSpec::default()
                } else {
                    pspec.clone()
                };
                let k_l = given.k_l.unwrap_or(k_l_rod);
                let k_theta = match (&given.k_theta, &given.k_theta_table) {
                    (Some(k), _) => BendStiffness::Constant(*k),
                    (None, Some(t)) => BendStiffness::Table(t.angle.clone(), t.stiffness.clone()),
                    (None, None) => BendStiffness::Constant(k_t_rod),
                };
                let k0 = k_theta.eval(0.0).0;
                let k_phi = given.k_phi.unwrap_or(
                    if given.k_theta.is_some() || given.k_theta_table.is_some() {
                        0.0
                    } else {
                        k_p_rod
                    },
                );
                if k0 + k_phi <= 0.0 {
                    return Err(SoftrodError::invalid(
                        "pcc.k_phi",
                        k_phi,
                        format!("k_theta + k_phi must be > 0 (k_theta(0) = {k0})"),
                    ));
                }
                let params = SegmentParams {
                    k_l,
                    b_l: given.b_l.unwrap_or(tau * k_l),
                    b_theta: given.b_theta.unwrap_or(tau * k0),
                    k_phi,
                    b_phi: given.b_phi.unwrap_or(tau * k_phi.max(0.0)),
                    k_theta,
                };
                let kind = LinkKind::Segment {
                    offset: ndof,
                    params,
                };
                ndof += per;
                kind
            };
            // Rotary inertia per length: given, or that of the annulus (outer radius, bore)
            // carrying the section's line mass (chambers ignored).
            let rotary = match (s.rotary_inertia, s.outer_radius) {
                (Some(j), _) => j,
                (None, Some(ro)) => {
                    let r2 = ro * ro + s.bore_radius * s.bore_radius;
                    let i = sec.line_mass * r2 / 4.0;
                    [i, i, 2.0 * i]
                }
                (None, None) => [0.0; 3],
            };
            rod_mass += sec.line_mass * sec.length;
            links.push(Link {
                name: sec.name.clone(),
                kind,
                length: sec.length,
                line_mass: sec.line_mass,
                rotary,
                line_force: sec.line_force,
                line_moment: sec.line_moment,
                chambers,
            });
        }
        if ndof == 0 {
            return Err(SoftrodError::invalid(
                "sections",
                "all rigid",
                "the PCC model needs at least one deformable section",
            ));
        }
        if !SUPPORTED_DOF.contains(&ndof) {
            return Err(SoftrodError::invalid(
                "sections",
                format!("{} deformable sections", ndof / per),
                "the PCC model supports at most 5 deformable sections (7 when planar)",
            ));
        }
        let mut tip = spec.tip;
        if pspec.mass_model == MassModel::Tip {
            // Paper 003 eq. 6: point mass m at the tip, no rotary inertia.
            for l in &mut links {
                l.line_mass = 0.0;
                l.rotary = [0.0; 3];
            }
            let m_tip = tip.mass;
            let m = m_tip + rod_mass;
            for k in 0..3 {
                tip.com_offset[k] *= if m > 0.0 { m_tip / m } else { 0.0 };
            }
            tip.mass = m;
            tip.inertia = [0.0; 3];
        }
        Ok(PccModel {
            links,
            ndof,
            plane: planar,
            base_position: spec.mounting.base_position,
            base_rotation: spec.mounting.base_rotation,
            gravity: spec.mounting.gravity,
            tip,
            n_channels: rod.n_channels,
            pressure_model: pspec.pressure_force,
            nodes: gauss_legendre(pspec.quadrature),
            supply: spec.dynamics,
        })
    }

    /// Coordinates per segment (3, or 2 when planar).
    pub fn per_segment(&self) -> usize {
        if self.plane.is_some() {
            2
        } else {
            3
        }
    }

    pub fn n_segments(&self) -> usize {
        self.ndof / self.per_segment()
    }

    /// Reference length of the whole chain, m.
    pub fn length(&self) -> f64 {
        self.links.iter().map(|l| l.length).sum()
    }

    /// The rest configuration: every segment straight at its reference length.
    pub fn rest(&self) -> Vec<f64> {
        let mut x = vec![0.0; self.ndof];
        for l in &self.links {
            if let LinkKind::Segment { offset, .. } = l.kind {
                x[offset] = l.length;
            }
        }
        x
    }

    /// The segment parameters in order.
    pub fn segments(&self) -> impl Iterator<Item = (&Link, usize, &SegmentParams)> {
        self.links.iter().filter_map(|l| match &l.kind {
            LinkKind::Segment { offset, params } => Some((l, *offset, params)),
            LinkKind::Rigid => None,
        })
    }

    /// Model coordinates -> (L, theta_x, theta_y) of the segment at `offset`.
    pub fn expand<S: kinematics::Real>(&self, x: &[S], offset: usize) -> [S; 3] {
        match self.plane {
            None => [x[offset], x[offset + 1], x[offset + 2]],
            Some((c, s)) => [x[offset], x[offset + 1] * c, x[offset + 1] * s],
        }
    }

    /// Paper 003's (L, theta, phi) per segment from the model coordinates (and rates).
    /// Planar models keep the signed theta and phi = plane angle.
    pub fn to_paper(&self, x: &[f64], v: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut q = Vec::with_capacity(3 * self.n_segments());
        let mut qd = Vec::with_capacity(3 * self.n_segments());
        for (_, o, _) in self.segments() {
            match self.plane {
                Some((c, s)) => {
                    let phi = s.atan2(c);
                    q.extend([x[o], x[o + 1], phi]);
                    qd.extend([v[o], v[o + 1], 0.0]);
                }
                None => {
                    let y = [x[o], x[o + 1], x[o + 2]];
                    let yd = [v[o], v[o + 1], v[o + 2]];
                    q.extend(kinematics::to_paper(&y));
                    qd.extend(kinematics::rates_to_paper(&y, &yd));
                }
            }
        }
        (q, qd)
    }

    /// Model coordinates and rates from paper 003's (L, theta, phi) per segment.
    pub fn from_paper(&self, q: &[f64], qd: &[f64]) -> Result<(Vec<f64>, Vec<f64>)> {
        let n = 3 * self.n_segments();
        if q.len() != n || qd.len() != n {
            return Err(SoftrodError::invalid(
                "initial",
                format!("q with {} and q_dot with {} values", q.len(), qd.len()),
                format!("give (L, theta, phi) and their rates for each of the {} segments: {n} values each", self.n_segments()),
            ));
        }
        for (i, z) in q.iter().chain(qd).enumerate() {
            check(
                &format!("initial[{i}]"),
                *z,
                true,
                "must be a finite number",
            )?;
        }
        let mut x = vec![0.0; self.ndof];
        let mut v = vec![0.0; self.ndof];
        for (k, (_, o, _)) in self.segments().enumerate() {
            let qs = [q[3 * k], q[3 * k + 1], q[3 * k + 2]];
            let qds = [qd[3 * k], qd[3 * k + 1], qd[3 * k + 2]];
            if qs[0] <= 0.0 {
                return Err(SoftrodError::invalid(
                    format!("initial.q[{}]", 3 * k),
                    qs[0],
                    "segment length L must be > 0",
                ));
            }
            match self.plane {
                Some((c, s)) => {
                    // Signed theta in the plane: project the bending vector on it.
                    let (y, yd) = kinematics::from_paper(&qs, &qds);
                    x[o] = y[0];
                    x[o + 1] = y[1] * c + y[2] * s;
                    v[o] = yd[0];
                    v[o + 1] = yd[1] * c + yd[2] * s;
                }
                None => {
                    let (y, yd) = kinematics::from_paper(&qs, &qds);
                    x[o..o + 3].copy_from_slice(&y);
                    v[o..o + 3].copy_from_slice(&yd);
                }
            }
        }
        Ok((x, v))
    }

    /// Check a pressure vector (length, finite, above vacuum).
    pub fn check_pressures(&self, p: &[f64]) -> Result<()> {
        crate::spec::validate_pressures(p, self.n_channels)
    }
}
