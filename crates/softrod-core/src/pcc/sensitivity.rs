//! Exact derivatives of the PCC model's predictions with respect to its visco-elastic
//! parameters (paper 003 Sec. V identified on the calibration engine): of equilibria by the
//! implicit function theorem, and of time series by forward sensitivities through the
//! implicit midpoint steps.
//!
//! The visco-elastic generalised force (`lagrangian`, paper 003 Sec. IV-B) is linear in the
//! parameters k_L, b_L, k_theta (a constant, or each stiffness of a k_theta(theta) table:
//! linear interpolation is linear in the table's values), b_theta, k_phi, b_phi, so its
//! parameter derivative at fixed (q, q_t) is the same force with one parameter set to 1 and
//! the others to 0.
//!
//! Statics: Q(x, theta) = 0 gives dx/dtheta = -Q_x^-1 Q_theta.
//! Dynamics: a step solves G(v_m) = R(x_0 + h/2 v_m, v_m, 2 (v_m - v_0)/h, p_m) = 0 (see
//! `integrate`) and sets x_1 = x_0 + h v_m, v_1 = 2 v_m - v_0. Differentiating,
//!   (R_x h/2 + R_v + R_a 2/h) S_m = -(R_x S_x0 - R_a 2/h S_v0 + R_theta),
//!   S_x1 = S_x0 + h S_m,  S_v1 = 2 S_m - S_v0,
//! whose matrix is the step's exact Newton matrix at the converged point. The step is first
//! taken by the simulator (unchanged), then the sensitivities follow along the stored
//! trajectory: R_x, R_v, R_a from three dual-number evaluations per step.
//!
//! The predicted points are the tip and markers on the chain (reference arc length s, the
//! fraction s / L0 along its link, plus an offset in the cross-section frame); their
//! derivatives are J_p dx/dtheta with J_p from one dual-number walk of the chain.

use super::integrate::{arr, eval_jac, solve_dense, statics_n, Dn, InitialState, StepOptions};
use super::jet::Grad;
use super::{BendStiffness, Link, PccModel, SegmentParams};
use crate::error::{Result, SoftrodError};

/// A parameter of the PCC model's visco-elastic law; it acts on every segment with chambers
/// (as the design's `[pcc]` values do).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PccParam {
    /// Longitudinal stiffness k_L, N/m.
    KL,
    /// Longitudinal damping b_L, N s/m.
    BL,
    /// Constant bending stiffness k_theta, N m/rad.
    KTheta,
    /// The j-th stiffness of the k_theta(theta) table, N m/rad.
    KThetaNode(usize),
    /// Bending damping b_theta, N m s/rad.
    BTheta,
    /// Extra stiffness towards d2, N m/rad.
    KPhi,
    /// Extra damping towards d2, N m s/rad.
    BPhi,
}

impl PccParam {
    /// "k_L", "b_L", "k_theta", "k_theta[j]", "b_theta", "k_phi", "b_phi".
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "k_L" => PccParam::KL,
            "b_L" => PccParam::BL,
            "k_theta" => PccParam::KTheta,
            "b_theta" => PccParam::BTheta,
            "k_phi" => PccParam::KPhi,
            "b_phi" => PccParam::BPhi,
            _ => {
                let j = name.strip_prefix("k_theta[")?.strip_suffix(']')?;
                PccParam::KThetaNode(j.trim().parse().ok()?)
            }
        })
    }

    pub fn name(&self) -> String {
        match self {
            PccParam::KL => "k_L".into(),
            PccParam::BL => "b_L".into(),
            PccParam::KTheta => "k_theta".into(),
            PccParam::KThetaNode(j) => format!("k_theta[{j}]"),
            PccParam::BTheta => "b_theta".into(),
            PccParam::KPhi => "k_phi".into(),
            PccParam::BPhi => "b_phi".into(),
        }
    }

    /// Its value in one segment's parameters (NaN where it does not exist).
    fn value(&self, p: &SegmentParams) -> f64 {
        match (self, &p.k_theta) {
            (PccParam::KL, _) => p.k_l,
            (PccParam::BL, _) => p.b_l,
            (PccParam::KTheta, BendStiffness::Constant(k)) => *k,
            (PccParam::KThetaNode(j), BendStiffness::Table(_, k)) => {
                k.get(*j).copied().unwrap_or(f64::NAN)
            }
            (PccParam::BTheta, _) => p.b_theta,
            (PccParam::KPhi, _) => p.k_phi,
            (PccParam::BPhi, _) => p.b_phi,
            _ => f64::NAN,
        }
    }
}

/// The segments the parameters act on: those with chambers, with their coordinate offset.
fn actuated(m: &PccModel) -> impl Iterator<Item = (&Link, usize, &SegmentParams)> {
    m.segments().filter(|(l, _, _)| !l.chambers.is_empty())
}

/// Check the parameters against the model: a segment with chambers exists, the law has the
/// parameter (a constant k_theta, or a table with that many entries), and every actuated
/// segment has the same value (one parameter, one value). Errors name `params[j]`.
pub fn validate_params(m: &PccModel, params: &[PccParam]) -> Result<()> {
    for (j, p) in params.iter().enumerate() {
        let field = format!("params[{j}] ({})", p.name());
        let mut first: Option<(String, f64, &SegmentParams)> = None;
        for (link, _, prm) in actuated(m) {
            let v = p.value(prm);
            if v.is_nan() {
                let rule = match (p, &prm.k_theta) {
                    (PccParam::KTheta, BendStiffness::Table(..)) => {
                        "the section's k_theta is a table: calibrate its entries k_theta[j]"
                            .to_string()
                    }
                    (PccParam::KThetaNode(_), BendStiffness::Constant(_)) => {
                        "the section's k_theta is a constant: calibrate k_theta".to_string()
                    }
                    (PccParam::KThetaNode(_), BendStiffness::Table(_, k)) => {
                        format!(
                            "the k_theta table has {} entries (0..{})",
                            k.len(),
                            k.len() - 1
                        )
                    }
                    _ => "the section has no such parameter".to_string(),
                };
                return Err(SoftrodError::invalid(field, &link.name, rule));
            }
            match &first {
                None => first = Some((link.name.clone(), v, prm)),
                Some((name, v0, p0)) => {
                    let same_table = match (p, &p0.k_theta, &prm.k_theta) {
                        (
                            PccParam::KThetaNode(_),
                            BendStiffness::Table(a0, _),
                            BendStiffness::Table(a, _),
                        ) => a0 == a,
                        _ => true,
                    };
                    if v != *v0 || !same_table {
                        return Err(SoftrodError::invalid(
                            field,
                            format!("{v} in section {}", link.name),
                            format!(
                                "one parameter needs one value: section {name} has {v0}; give the sections one [pcc] value"
                            ),
                        ));
                    }
                }
            }
        }
        let Some((_, v, _)) = first else {
            return Err(SoftrodError::invalid(
                field,
                "no section with chambers",
                "the PCC parameters act on the sections with chambers",
            ));
        };
        if !(v.is_finite() && v >= 0.0) {
            return Err(SoftrodError::invalid(
                field,
                v,
                "must be a finite number >= 0",
            ));
        }
    }
    Ok(())
}

/// The current value of a (validated) parameter.
pub fn param_value(m: &PccModel, p: PccParam) -> f64 {
    actuated(m)
        .map(|(_, _, prm)| p.value(prm))
        .next()
        .unwrap_or(f64::NAN)
}

/// d(viscoelastic force)/d theta of one parameter at (x, v): the force of the unit
/// parameter (the force is linear in the parameters), projected as `lagrangian` projects it.
fn d_viscoelastic<const N: usize>(
    m: &PccModel,
    x: &[f64; N],
    v: &[f64; N],
    p: PccParam,
) -> [f64; N] {
    let mut out = [0.0; N];
    for (link, o, prm) in actuated(m) {
        let y = m.expand(x, o);
        let yd = m.expand(v, o);
        let theta = y[1].hypot(y[2]);
        // d k_theta(theta) / d(parameter)
        let dk = match (p, &prm.k_theta) {
            (PccParam::KTheta, _) => 1.0,
            (PccParam::KThetaNode(j), BendStiffness::Table(a, _)) => hat(a, j, theta),
            _ => 0.0,
        };
        let mut ve = match p {
            PccParam::KL => [-(y[0] - link.length), 0.0, 0.0],
            PccParam::BL => [-yd[0], 0.0, 0.0],
            PccParam::KTheta | PccParam::KThetaNode(_) => [0.0, -y[1] * dk, -y[2] * dk],
            PccParam::BTheta => [0.0, -yd[1], -yd[2]],
            PccParam::KPhi => [0.0, 0.0, -y[2]],
            PccParam::BPhi => [0.0, 0.0, -yd[2]],
        };
        match m.plane {
            None => {
                for k in 0..3 {
                    out[o + k] += ve[k];
                }
            }
            Some((c, s)) => {
                ve[1] = ve[1] * c + ve[2] * s;
                out[o] += ve[0];
                out[o + 1] += ve[1];
            }
        }
    }
    out
}

/// Weight of table entry j in the piecewise-linear k_theta(theta) (constant beyond the ends,
/// as `BendStiffness::eval`).
fn hat(a: &[f64], j: usize, theta: f64) -> f64 {
    let n = a.len();
    if theta <= a[0] {
        return if j == 0 { 1.0 } else { 0.0 };
    }
    if theta >= a[n - 1] {
        return if j == n - 1 { 1.0 } else { 0.0 };
    }
    let i = a.partition_point(|&x| x <= theta) - 1;
    let t = (theta - a[i]) / (a[i + 1] - a[i]);
    if j == i {
        1.0 - t
    } else if j == i + 1 {
        t
    } else {
        0.0
    }
}

/// A point on the chain whose position is predicted: reference arc length s in [0, L] and an
/// offset in the cross-section frame (d1, d2, d3), m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PccMarker {
    pub s: f64,
    pub offset: [f64; 3],
}

/// A located marker: the link and the fraction along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PccMarkerAt {
    link: usize,
    sigma: f64,
    offset: [f64; 3],
}

/// Locate markers on the chain (a segment's material point at fraction sigma of its
/// reference length is at the same fraction of its arc). Errors name `markers[k]`.
pub fn locate_markers(m: &PccModel, markers: &[PccMarker]) -> Result<Vec<PccMarkerAt>> {
    let total = m.length();
    markers
        .iter()
        .enumerate()
        .map(|(k, mk)| {
            if !(mk.s.is_finite() && mk.s >= 0.0 && mk.s <= total * (1.0 + 1e-12)) {
                return Err(SoftrodError::invalid(
                    format!("markers[{k}].s"),
                    mk.s,
                    format!("a marker's arc length must lie in [0, L] = [0, {total}] m"),
                ));
            }
            if let Some(bad) = mk.offset.iter().find(|v| !v.is_finite()) {
                return Err(SoftrodError::invalid(
                    format!("markers[{k}].offset"),
                    bad,
                    "must be finite (m, cross-section frame)",
                ));
            }
            let mut start = 0.0;
            let last = m.links.len() - 1;
            for (li, l) in m.links.iter().enumerate() {
                if mk.s <= start + l.length || li == last {
                    let sigma = ((mk.s - start) / l.length).clamp(0.0, 1.0);
                    return Ok(PccMarkerAt {
                        link: li,
                        sigma,
                        offset: mk.offset,
                    });
                }
                start += l.length;
            }
            unreachable!("the last link takes every s <= L")
        })
        .collect()
}

/// The tip and the markers at x, with their Jacobians d point / dx (rows: x, y, z).
fn points<const N: usize>(
    m: &PccModel,
    x: &[f64; N],
    markers: &[PccMarkerAt],
) -> Vec<([f64; 3], [[f64; N]; 3])> {
    let xg: [Dn<N>; N] = std::array::from_fn(|i| Dn::<N>::variable(x[i], i));
    let split = |p: &[Dn<N>; 3]| -> ([f64; 3], [[f64; N]; 3]) {
        (p.map(|c| c.re), std::array::from_fn(|k| p[k].eps))
    };
    let mut out = Vec::with_capacity(1 + markers.len());
    let (tip, _) = m.walk(&xg, Some(&[]), |_, _| {});
    out.push(split(&tip));
    for mk in markers {
        let mut found: Option<[Dn<N>; 3]> = None;
        m.walk(&xg, Some(&[mk.sigma]), |site, (p, r)| {
            if let super::lagrangian::Site::Node { link, .. } = site {
                if link == mk.link {
                    let o = mk.offset;
                    found = Some(std::array::from_fn(|i| {
                        p[i] + r[i][0] * o[0] + r[i][1] * o[1] + r[i][2] * o[2]
                    }));
                }
            }
        });
        out.push(split(&found.expect("every link is walked")));
    }
    out
}

/// Predicted points (tip first, then the markers) and their parameter derivatives.
#[derive(Debug, Clone, PartialEq)]
pub struct PointSensitivity {
    pub points: Vec<[f64; 3]>,
    /// `d_points[i][j]`: d point_i / d theta_j.
    pub d_points: Vec<Vec<[f64; 3]>>,
}

fn project<const N: usize>(pts: &[([f64; 3], [[f64; N]; 3])], dx: &[[f64; N]]) -> PointSensitivity {
    PointSensitivity {
        points: pts.iter().map(|(p, _)| *p).collect(),
        d_points: pts
            .iter()
            .map(|(_, jp)| {
                dx.iter()
                    .map(|d| std::array::from_fn(|k| (0..N).map(|c| jp[k][c] * d[c]).sum()))
                    .collect()
            })
            .collect(),
    }
}

/// An equilibrium with its parameter derivatives.
#[derive(Debug, Clone, PartialEq)]
pub struct PccStaticSensitivity {
    /// Model coordinates (a warm start for the next solve).
    pub x: Vec<f64>,
    pub at: PointSensitivity,
}

fn singular() -> SoftrodError {
    SoftrodError::NotConverged {
        iterations: 0,
        residual: f64::NAN,
        load_factor: 1.0,
        reason: "the PCC Jacobian is singular here, so its parameter derivatives are undefined"
            .into(),
    }
}

/// dx/dtheta of the equilibrium x under pressures p.
fn static_dx<const N: usize>(
    m: &PccModel,
    x: &[f64; N],
    p: &[f64],
    params: &[PccParam],
) -> Result<Vec<[f64; N]>> {
    let (_, jac) = eval_jac(x, |z| m.static_forces(z, p).residual());
    let zero = [0.0; N];
    params
        .iter()
        .map(|&q| {
            // R = inertial - external - pressure - viscoelastic: R_theta = -d_ve, and
            // dx = -R_x^-1 R_theta.
            solve_dense(jac, d_viscoelastic(m, x, &zero, q)).ok_or_else(singular)
        })
        .collect()
}

fn statics_sensitivity_n<const N: usize>(
    m: &PccModel,
    p: &[f64],
    guess: &[f64],
    params: &[PccParam],
    markers: &[PccMarkerAt],
    opts: &StepOptions,
) -> Result<PccStaticSensitivity> {
    let s = statics_n::<N>(m, p, guess, opts)?;
    let x = arr::<N>(&s.x);
    let dx = static_dx(m, &x, p, params)?;
    Ok(PccStaticSensitivity {
        x: s.x,
        at: project(&points(m, &x, markers), &dx),
    })
}

/// A replayed time series with its parameter derivatives at the saved steps.
#[derive(Debug, Clone, PartialEq)]
pub struct PccRunSensitivity {
    pub time: Vec<f64>,
    pub at: Vec<PointSensitivity>,
}

/// R_x, R_v, R_a of the equations of motion at (x, v, a).
fn partials<const N: usize>(
    m: &PccModel,
    x: &[f64; N],
    v: &[f64; N],
    a: &[f64; N],
    p: &[f64],
) -> [[[f64; N]; N]; 3] {
    let lift = |z: &[f64; N], seeded: bool| -> [Dn<N>; N] {
        std::array::from_fn(|i| {
            if seeded {
                Dn::<N>::variable(z[i], i)
            } else {
                Grad::constant(z[i])
            }
        })
    };
    let jac = |k: usize| -> [[f64; N]; N] {
        let r = m
            .forces(&lift(x, k == 0), &lift(v, k == 1), &lift(a, k == 2), p)
            .residual();
        r.map(|c| c.eps)
    };
    [jac(0), jac(1), jac(2)]
}

fn mat_vec<const N: usize>(a: &[[f64; N]; N], x: &[f64; N]) -> [f64; N] {
    std::array::from_fn(|r| (0..N).map(|c| a[r][c] * x[c]).sum())
}

#[allow(clippy::too_many_arguments)]
fn run_sensitivity_n<const N: usize>(
    m: &PccModel,
    dt: f64,
    pressures: &[f64],
    initial: &InitialState,
    params: &[PccParam],
    markers: &[PccMarkerAt],
    save_every: usize,
    opts: &StepOptions,
) -> Result<PccRunSensitivity> {
    let tr = m.simulate(dt, pressures, initial, 1, opts)?;
    let nc = m.n_channels;
    let n_steps = tr.x.len() - 1;
    let zero = [0.0; N];
    // Sensitivities of x and v, one N-vector per parameter.
    let (mut sx, mut sv): (Vec<[f64; N]>, Vec<[f64; N]>) = match initial {
        InitialState::Rest => (
            static_dx(m, &arr::<N>(&tr.x[0]), &vec![0.0; nc], params)?,
            vec![zero; params.len()],
        ),
        InitialState::Static => (
            static_dx(m, &arr::<N>(&tr.x[0]), &tr.pressure[0], params)?,
            vec![zero; params.len()],
        ),
        InitialState::Given { .. } => (vec![zero; params.len()], vec![zero; params.len()]),
    };
    let mut out = PccRunSensitivity {
        time: vec![],
        at: vec![],
    };
    let mut save = |k: usize, sx: &[[f64; N]]| {
        out.time.push(tr.time[k]);
        out.at
            .push(project(&points(m, &arr::<N>(&tr.x[k]), markers), sx));
    };
    save(0, &sx);
    let h = dt;
    for k in 0..n_steps {
        let x0 = arr::<N>(&tr.x[k]);
        let v0 = arr::<N>(&tr.v[k]);
        let x1 = arr::<N>(&tr.x[k + 1]);
        let vm: [f64; N] = std::array::from_fn(|i| (x1[i] - x0[i]) / h);
        let xm: [f64; N] = std::array::from_fn(|i| x0[i] + 0.5 * h * vm[i]);
        let acc: [f64; N] = std::array::from_fn(|i| (vm[i] - v0[i]) * (2.0 / h));
        let pm: Vec<f64> = tr.pressure[k]
            .iter()
            .zip(&tr.pressure[k + 1])
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        let [gx, gv, ga] = partials(m, &xm, &vm, &acc, &pm);
        let jac: [[f64; N]; N] = std::array::from_fn(|r| {
            std::array::from_fn(|c| gx[r][c] * 0.5 * h + gv[r][c] + ga[r][c] * (2.0 / h))
        });
        for (j, &q) in params.iter().enumerate() {
            let dve = d_viscoelastic(m, &xm, &vm, q);
            let a1 = mat_vec(&gx, &sx[j]);
            let a2 = mat_vec(&ga, &sv[j]);
            // -(R_x S_x0 - 2/h R_a S_v0 + R_theta) with R_theta = -dve
            let rhs: [f64; N] = std::array::from_fn(|i| -(a1[i] - (2.0 / h) * a2[i] - dve[i]));
            let sm = solve_dense(jac, rhs).ok_or_else(singular)?;
            for i in 0..N {
                sx[j][i] += h * sm[i];
                sv[j][i] = 2.0 * sm[i] - sv[j][i];
            }
        }
        if (k + 1) % save_every == 0 || k + 1 == n_steps {
            save(k + 1, &sx);
        }
    }
    Ok(out)
}

impl PccModel {
    /// The equilibrium under pressures `p` (from `guess`, default the rest configuration)
    /// with the tip, the markers and their derivatives with respect to `params` (checked
    /// with [`validate_params`]; markers located by [`locate_markers`]).
    pub fn statics_sensitivity(
        &self,
        p: &[f64],
        guess: Option<&[f64]>,
        params: &[PccParam],
        markers: &[PccMarkerAt],
        opts: &StepOptions,
    ) -> Result<PccStaticSensitivity> {
        self.check_pressures(p)?;
        let rest = self.rest();
        let g = guess
            .filter(|g| g.len() == self.ndof && g.iter().all(|v| v.is_finite()))
            .unwrap_or(&rest);
        dispatch!(
            self.ndof,
            statics_sensitivity_n(self, p, g, params, markers, opts)
        )
    }

    /// [`PccModel::simulate`] of the commands `pressures` with the tip, the markers and their
    /// derivatives with respect to `params` at every `save_every`-th step (and the last).
    #[allow(clippy::too_many_arguments)]
    pub fn simulate_sensitivity(
        &self,
        dt: f64,
        pressures: &[f64],
        initial: &InitialState,
        params: &[PccParam],
        markers: &[PccMarkerAt],
        save_every: usize,
        opts: &StepOptions,
    ) -> Result<PccRunSensitivity> {
        if save_every == 0 {
            return Err(SoftrodError::invalid("save_every", 0, "must be >= 1"));
        }
        dispatch!(
            self.ndof,
            run_sensitivity_n(self, dt, pressures, initial, params, markers, save_every, opts)
        )
    }
}

/// Run `work` on `threads` workers (0: all cores).
pub(crate) fn in_pool<T: Send>(threads: usize, work: impl FnOnce() -> T + Send) -> Result<T> {
    if threads == 0 {
        return Ok(work());
    }
    if threads > crate::batch::MAX_THREADS {
        return Err(SoftrodError::invalid(
            "threads",
            threads,
            format!(
                "must be in 0..={} (0 = all cores)",
                crate::batch::MAX_THREADS
            ),
        ));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| {
            SoftrodError::invalid("threads", threads, format!("cannot build thread pool: {e}"))
        })?;
    Ok(pool.install(work))
}

/// Equilibria of many pressure rows (row-major, `n_channels` per row) in parallel, each from
/// its own warm start (`guesses`, `ndof` per row; NaN rows start at rest), with their
/// parameter derivatives. A row that fails gives its error; the others are unaffected.
pub fn statics_sensitivity_batch(
    m: &PccModel,
    pressures: &[f64],
    guesses: Option<&[f64]>,
    params: &[PccParam],
    markers: &[PccMarker],
    opts: &StepOptions,
    threads: usize,
) -> Result<Vec<Result<PccStaticSensitivity>>> {
    use rayon::prelude::*;
    validate_params(m, params)?;
    let located = locate_markers(m, markers)?;
    let nc = m.n_channels;
    if nc == 0 || pressures.len() % nc != 0 {
        return Err(SoftrodError::invalid(
            "pressures",
            format!("{} values", pressures.len()),
            format!("must be an (m, {nc}) array: one gauge pressure per channel per row"),
        ));
    }
    let rows = pressures.len() / nc;
    if let Some(g) = guesses {
        if g.len() != rows * m.ndof {
            return Err(SoftrodError::invalid(
                "guesses",
                format!("{} values", g.len()),
                format!("must be an ({rows}, {}) array", m.ndof),
            ));
        }
    }
    for r in 0..rows {
        m.check_pressures(&pressures[r * nc..(r + 1) * nc])
            .map_err(|e| match e {
                SoftrodError::InvalidParameter { field, value, rule } => {
                    SoftrodError::invalid(format!("row {r}: {field}"), value, rule)
                }
                other => other,
            })?;
    }
    in_pool(threads, || {
        (0..rows)
            .into_par_iter()
            .map(|r| {
                let guess = guesses.map(|g| &g[r * m.ndof..(r + 1) * m.ndof]);
                m.statics_sensitivity(
                    &pressures[r * nc..(r + 1) * nc],
                    guess,
                    params,
                    &located,
                    opts,
                )
            })
            .collect()
    })
}

/// One time series to replay: commands (row-major, (n_steps + 1) x n_channels, Pa) at every
/// step of `dt`, and the initial state.
#[derive(Debug, Clone, PartialEq)]
pub struct PccRun {
    pub dt: f64,
    pub pressures: Vec<f64>,
    pub initial: InitialState,
    pub save_every: usize,
}

/// Many time series replayed in parallel with their parameter derivatives.
pub fn simulate_sensitivity_batch(
    m: &PccModel,
    runs: &[PccRun],
    params: &[PccParam],
    markers: &[PccMarker],
    opts: &StepOptions,
    threads: usize,
) -> Result<Vec<Result<PccRunSensitivity>>> {
    use rayon::prelude::*;
    validate_params(m, params)?;
    let located = locate_markers(m, markers)?;
    in_pool(threads, || {
        runs.par_iter()
            .map(|run| {
                m.simulate_sensitivity(
                    run.dt,
                    &run.pressures,
                    &run.initial,
                    params,
                    &located,
                    run.save_every,
                    opts,
                )
            })
            .collect()
    })
}
