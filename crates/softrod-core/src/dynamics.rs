//! Dynamics of the viscoelastic Cosserat rod (paper 000 eqs. 7-13; docs/model.md).
//!
//! Time: every time derivative X_t of X in {v, u, q, w} is replaced by an implicit formula
//! X_t = c0 X + X_h with X_h built from earlier steps (Till, Aloi, Rucker, "Real-time
//! dynamics of soft and continuum robots based on Cosserat rod models", IJRR 2019):
//! BDF-alpha (alpha in [-0.5, 0]; 0 is BDF2, -0.5 the trapezoidal rule) in a variable-step
//! form, so that a step can be subdivided or adapted, or the implicit midpoint rule, which
//! conserves the energy of the linear law exactly. Space: at every step the resulting
//! boundary-value problem in s is solved by Gauss collocation (`crate::collocation`),
//! whose conditioning does not depend on dt or the stiffness and whose semi-discrete
//! energy is conserved in the linear limit.
//!
//! Material law with Kelvin-Voigt damping (paper 000 eq. 8): R^T n_m = N(v) + B_se v_t,
//! R^T m_m = M(u, v) + B_bt u_t with N, M the section's static law (linear, Ogden, EA(F)
//! table, stretch-dependent bending, swelling, stiffness map) and B = tau K_0 (K_0 the
//! law's small-strain stiffness at the current pressure) or the section's given damping
//! diagonals: a linear viscous term that dissipates exactly v_t B v_t + u_t B u_t.
//!
//! After every step: finite values, rotations orthonormal, stretch v3 > 0 at every stage
//! point, and the energy balance E(t) - E(0) = W_in - D (kinetic + elastic + potential
//! energy, work of the inputs, Kelvin-Voigt dissipation) must not show growth beyond
//! `energy_tol` of the energy moved; a violation stops the run with an error naming the
//! time, the step and what to change.
//!
//! The tip may be held (`Simulator::with_constraint`, docs/dynamics.md "Held tip"): pinned
//! or clamped at a pose that the caller moves from output step to output step
//! (`set_tip_pose`); the step's collocation then carries the node positions and replaces
//! the tip's balance by the pose (`collocation::EndTarget`), the reaction is reported
//! (`tip_reaction`) and its work along the pose's path enters the energy books.
//!
//! Several rods whose tips hold one rigid platform move together in `system`
//! (`SystemSimulator`; docs/dynamics.md "Systems of rods"), built on the held tip's step.

use crate::collocation::{
    self, EndTarget, Evaluated, Factorization, Grid, GridPoint, NewtonOptions, NewtonStats,
    NewtonWork, Problem, SectionModel, TipBody, GAUSS_B, NF, NY,
};
use crate::error::{Result, SoftrodError};
use crate::interp::GridPchip;
use crate::law::ogden_energy;
use crate::marker::{check_markers, Marker};
use crate::ode::{Coeffs, Loads};
use crate::rod::Rod;
use crate::statics::constraint::{log_so3, slerp, tmatmul, TipConstraint, ROTATION_TOL};
use crate::statics::{self, SolverOptions};
use crate::validity;

pub mod sensitivity;
pub mod system;

/// v, u, q, w (body frame) at one stage point.
pub const FIELDS: usize = NF;

/// The time integrator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// BDF-alpha with the options' alpha: second order, damps unresolved modes for
    /// alpha > -0.5 (alpha = 0 is BDF2). alpha = -0.5 is the trapezoidal rule of paper
    /// 000: no numerical damping, conserves the linearised rod's energy, but large
    /// nonlinear motions can grow through unresolved modes (the energy check stops them).
    BdfAlpha,
    /// The implicit midpoint rule: the step's boundary-value problem is solved at
    /// t_n + h/2 with X_t = (X_{n+1} - X_n) / h, then X_{n+1} = 2 X_{n+1/2} - X_n and the
    /// shape at t_{n+1} is rebuilt from its strains. Second order, no numerical damping; for
    /// the linear law the stored and kinetic energies are quadratic in the integrated
    /// fields and the gyroscopic terms do no work, so the rule conserves the energy of
    /// undamped motions of any amplitude without gravity (with gravity to second order).
    Midpoint,
}

impl Scheme {
    pub fn name(&self) -> &'static str {
        match self {
            Scheme::BdfAlpha => "bdf-alpha",
            Scheme::Midpoint => "midpoint",
        }
    }
}

/// Settings of the time integrator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynOptions {
    /// Time step, s (with `error_tol`: the output interval and the largest step).
    pub dt: f64,
    pub scheme: Scheme,
    /// BDF-alpha parameter in [-0.5, 0] (`Scheme::BdfAlpha` only).
    pub alpha: f64,
    /// Tolerance on the scaled collocation residual at every step.
    pub tol: f64,
    /// Newton iterations per step.
    pub max_iter: usize,
    /// Adaptive time stepping: the largest estimated local error of any node position per
    /// step, m. None: steps of dt, subdivided only where Newton fails.
    pub error_tol: Option<f64>,
    /// Largest growth of the energy balance E - E(0) - W_in + D, relative to the energy
    /// moved so far, before the run is stopped (see `Simulator::energy_check`).
    pub energy_tol: f64,
}

impl Default for DynOptions {
    fn default() -> Self {
        DynOptions {
            dt: 2e-3,
            scheme: Scheme::BdfAlpha,
            alpha: -0.2,
            tol: 1e-9,
            max_iter: 25,
            error_tol: None,
            energy_tol: DEFAULT_ENERGY_TOL,
        }
    }
}

const SQRT3_6: f64 = 0.288_675_134_594_812_9; // sqrt(3) / 6, the Gauss tableau's

/// Default `energy_tol`: 2 % of the energy moved. The schemes' legitimate energy errors
/// are far smaller: none for the midpoint rule with the linear law and no dead loads
/// (exact conservation), numerical dissipation (a decrease, never flagged) for
/// BDF-alpha, and second-order errors of ~(omega dt)^2 / 12 of the nonlinear motion's
/// energy for resolved modes (omega dt <= 0.5: <= 2 %; measured: below 0.3 % in the
/// tests' large swings); an instability grows exponentially and crosses any such bound
/// within a few e-foldings.
pub const DEFAULT_ENERGY_TOL: f64 = 0.02;

/// How many times a step may be halved when Newton fails (2^6 substeps). Not more: as
/// h -> 0 the stiff solutions of a step's boundary-value problem (exp(s c0 / c)) make Gauss
/// collocation's amplification approach 1 for both growing and decaying ones, and its
/// Newton matrix grows singular; a failure that survives 64 substeps is not a step size
/// problem.
const MAX_HALVINGS: u32 = 6;
/// A kept Newton matrix serves a step whose c0 differs from its own by at most this
/// fraction (CVODE's rule for its iteration matrix, dgmax = 0.3): modified Newton still
/// contracts, and its rate test (`collocation::newton_with`) refreshes the matrix when it
/// does not. Adaptive steps change c0 at nearly every step; refactoring at each change
/// cost 0.25 ms per step on paper 000's arm, most of an adaptive run.
const REUSE_C0: f64 = 0.3;
/// An accepted adaptive step is not lengthened by less than this factor (Hairer and
/// Wanner's Radau5, quot2 = 1.2): a step kept equal keeps c0 and the Newton matrix.
const KEEP_STEP: f64 = 1.2;

/// Commanded pressures as a table of knots, so that steps inside an output interval
/// (substeps, adaptive steps) see the commands at their own end times: linear between the
/// knots, or held from each knot to the next (`step`); the end values hold outside.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandSchedule {
    times: Vec<f64>,
    values: Vec<Vec<f64>>,
    step: bool,
}

impl CommandSchedule {
    /// Knots `times` (finite, strictly increasing) with one row of `channels` pressures
    /// each (Pa; checked like commands).
    pub fn new(
        times: Vec<f64>,
        values: Vec<Vec<f64>>,
        step: bool,
        channels: usize,
    ) -> Result<Self> {
        if times.is_empty() || times.len() != values.len() {
            return Err(SoftrodError::invalid(
                "schedule",
                format!("{} times, {} rows", times.len(), values.len()),
                "needs one row of pressures per knot time, at least one",
            ));
        }
        for (k, t) in times.iter().enumerate() {
            if !t.is_finite() || (k > 0 && *t <= times[k - 1]) {
                return Err(SoftrodError::invalid(
                    format!("schedule.times[{k}]"),
                    t,
                    "knot times must be finite and strictly increasing",
                ));
            }
        }
        for (k, row) in values.iter().enumerate() {
            crate::spec::validate_pressures(row, channels)
                .map_err(|e| rename_pressure_error(e, &format!("schedule.values[{k}]")))?;
        }
        Ok(CommandSchedule {
            times,
            values,
            step,
        })
    }

    /// The commands at time t.
    pub fn at(&self, t: f64) -> Vec<f64> {
        let k = self.times.partition_point(|&x| x <= t);
        if k == 0 {
            return self.values[0].clone();
        }
        if k == self.times.len() || self.step {
            return self.values[k - 1].clone();
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let w = (t - t0) / (t1 - t0);
        self.values[k - 1]
            .iter()
            .zip(&self.values[k])
            .map(|(a, b)| a + w * (b - a))
            .collect()
    }

    /// The first knot strictly after t (where the commands change slope or jump).
    fn next_knot(&self, t: f64) -> Option<f64> {
        let k = self.times.partition_point(|&x| x <= t);
        self.times.get(k).copied()
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
        if let Some(e) = self.error_tol {
            if !(e.is_finite() && e > 0.0) {
                return Err(SoftrodError::invalid(
                    "error_tol",
                    e,
                    "must be a finite length > 0 m (the local error of the node positions per step)",
                ));
            }
        }
        if !(self.energy_tol.is_finite() && self.energy_tol > 0.0) {
            return Err(SoftrodError::invalid(
                "energy_tol",
                self.energy_tol,
                "must be a finite number > 0 (a fraction of the energy moved)",
            ));
        }
        Ok(())
    }

    fn alpha_eff(&self) -> f64 {
        match self.scheme {
            Scheme::BdfAlpha => self.alpha,
            Scheme::Midpoint => -0.5,
        }
    }
}

/// Coefficients of X_t(t_{n+1}) = c0 X_{n+1} + c1 X_n + c2 X_{n-1} + d1 X_t(t_n) for the
/// step h after a step h_prev: BDF-alpha (Till et al. 2019, eq. 7) in variable-step form,
/// (1 + alpha) X_t,n+1 - alpha X_t,n = BDF2(X) + alpha D(X) with the variable-step BDF2
/// and D the second divided difference times h; both sides are exact for quadratics, and
/// at alpha = -0.5 the X_{n-1} terms cancel to the trapezoidal rule.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bdf {
    c0: f64,
    c1: f64,
    c2: f64,
    d1: f64,
}

impl Bdf {
    fn new(alpha: f64, h: f64, h_prev: f64) -> Self {
        let w = h / h_prev;
        let s = h + h_prev;
        let (a0, a1, a2) = (
            (1.0 + 2.0 * w) / ((1.0 + w) * h),
            -(1.0 + w) / h,
            w * w / ((1.0 + w) * h),
        );
        let (e0, e1, e2) = (2.0 / s, -2.0 * (1.0 + w) / s, 2.0 * w / s);
        let k = 1.0 / (1.0 + alpha);
        if alpha == -0.5 {
            // The trapezoidal rule exactly (no round-off from the cancelling X_{n-1}).
            return Bdf {
                c0: 2.0 / h,
                c1: -2.0 / h,
                c2: 0.0,
                d1: -1.0,
            };
        }
        Bdf {
            c0: (a0 + alpha * e0) * k,
            c1: (a1 + alpha * e1) * k,
            c2: (a2 + alpha * e2) * k,
            d1: alpha * k,
        }
    }

    /// Local error of one step for X''' = 1, with exact history: the formula's defect on
    /// the cubic (t - t_{n+1})^3 / 6 divided by c0 (for error estimates).
    fn error_constant(&self, h: f64, h_prev: f64) -> f64 {
        let e = self.c1 * (-h.powi(3) / 6.0)
            + self.c2 * (-(h + h_prev).powi(3) / 6.0)
            + self.d1 * (h * h / 2.0);
        (e / self.c0).abs()
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

/// [`section_inertia`] at local arc length `s` of section `i`: a tapered section's line
/// mass (the quadratic of its area, `Section::line_mass_at`) and rotary inertia there
/// (rho A times the radii of gyration I/A of its cross-section at s, chambers and offsets
/// moved with the taper; a given rotary inertia stays). Uniform sections: their constants.
pub fn section_inertia_at(rod: &Rod, i: usize, s: f64) -> SectionInertia {
    let sec = &rod.sections[i];
    let spec = &rod.spec.sections[i];
    if !sec.tapered {
        return section_inertia(rod, i);
    }
    let t = s / sec.length;
    let rho_a = sec.line_mass_at(t);
    let rho_j = spec
        .rotary_inertia
        .unwrap_or_else(|| match &sec.law.geometry {
            Some(geo) => {
                let cs = crate::section::CrossSection::from_holes(
                    geo.outer_at(t),
                    geo.bore_radius,
                    sec.chambers.iter().map(|c| {
                        let (_, r, x) = c.at(t);
                        (r, x)
                    }),
                );
                let (a1, a2) = (cs.i11 / cs.area, cs.i22 / cs.area);
                [rho_a * a1, rho_a * a2, rho_a * (a1 + a2)]
            }
            None => section_inertia(rod, i)
                .rho_j
                .map(|j| j * rho_a / sec.line_mass),
        });
    SectionInertia {
        rho_a,
        rho_j,
        damping: spec.damping_se.zip(spec.damping_bt),
    }
}

/// The stiffness scale sigma(p) of mapped sections (paper 001 eq. 13) during a run,
/// evaluated in the core at the chamber pressures of every step.
#[derive(Debug, Clone, PartialEq)]
pub enum SigmaMap {
    /// The design has no mapped section.
    None,
    Constant([f64; 3]),
    /// Tensor-product PCHIP on a pressure grid (one axis per channel); outside the grid
    /// the pressure is clamped to it (`clamp`) or the step fails with an error.
    Grid {
        grid: GridPchip,
        clamp: bool,
    },
}

impl SigmaMap {
    fn eval(&self, p: &[f64]) -> Result<[f64; 3]> {
        match self {
            SigmaMap::None => Ok([1.0; 3]),
            SigmaMap::Constant(s) => Ok(*s),
            SigmaMap::Grid { grid, clamp } => {
                let axes = grid.axes();
                let mut at = p.to_vec();
                for (k, a) in axes.iter().enumerate() {
                    let (lo, hi) = (a[0], a[a.len() - 1]);
                    if at[k] < lo || at[k] > hi {
                        if *clamp {
                            at[k] = at[k].clamp(lo, hi);
                        } else {
                            return Err(SoftrodError::invalid(
                                format!("pressures[{k}]"),
                                at[k],
                                format!("lies outside the stiffness map's axis [{lo}, {hi}] Pa (use a map with outside='clamp' or a wider table)"),
                            ));
                        }
                    }
                }
                let mut out = [0.0; 3];
                grid.eval(&at, &mut out);
                Ok(out)
            }
        }
    }
}

/// The contact loads of a state with obstacles ([`Simulator::contact_state`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactState {
    /// Total contact force on the rod (normal and friction, rounded end included), N,
    /// world frame.
    pub force: [f64; 3],
    /// Penalty potential of the contacts, J (part of `Energy::potential`).
    pub potential: f64,
    /// Deepest penetration of the rod's surface into an obstacle, m (<= 0: no contact).
    pub max_penetration: f64,
}

/// Energies at one instant and the cumulative exchanges since t = 0, J.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// Kinetic energy of the rod and the tip body.
    pub kinetic: f64,
    /// Stored energy of the law at the current pressures: for the linear law
    /// (1/2)(v - v_p) K_se (v - v_p) + (1/2)(u - u_p) K_bt (u - u_p) about the
    /// pressure-shifted strains; for the others W(v, u) - P (v3 - 1) - M_p . u.
    pub elastic: f64,
    /// Potential of gravity and of the dead forces (line and tip), and the contacts'
    /// penalty potential.
    pub potential: f64,
    /// Work done on the rod since t = 0 by changing pressures, stiffness scale and dead
    /// loads, by dead moments, and by the non-potential part of stretch-dependent bending.
    pub work_in: f64,
    /// Kelvin-Voigt and friction dissipation since t = 0.
    pub dissipated: f64,
}

impl Energy {
    /// Mechanical energy: kinetic + elastic + potential.
    pub fn total(&self) -> f64 {
        self.kinetic + self.elastic + self.potential
    }
}

/// The energy books of a run: the balance E - E(0) - W_in + D is zero for the exact
/// motion; `scale` is the energy moved so far (the check's reference).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Books {
    now: Energy,
    e0: f64,
    elastic0: f64,
    potential0: f64,
    max_kinetic: f64,
    max_elastic: f64,
    max_potential: f64,
    moved_in: f64,
    /// Rates at the current time (for the trapezoidal quadrature in time): dissipation,
    /// power of dead moments, power of the non-potential law part.
    rates: [f64; 3],
}

impl Books {
    fn scale(&self) -> f64 {
        self.max_kinetic
            + self.max_elastic
            + self.max_potential
            + self.moved_in
            + self.now.dissipated
    }

    fn balance(&self) -> f64 {
        self.now.total() - self.e0 - self.now.work_in + self.now.dissipated
    }

    /// The books as numbers (saved states).
    fn numbers(&self) -> [f64; 15] {
        let b = self;
        [
            b.now.kinetic,
            b.now.elastic,
            b.now.potential,
            b.now.work_in,
            b.now.dissipated,
            b.e0,
            b.elastic0,
            b.potential0,
            b.max_kinetic,
            b.max_elastic,
            b.max_potential,
            b.moved_in,
            b.rates[0],
            b.rates[1],
            b.rates[2],
        ]
    }

    fn from_numbers(b: &[f64; 15]) -> Self {
        Books {
            now: Energy {
                kinetic: b[0],
                elastic: b[1],
                potential: b[2],
                work_in: b[3],
                dissipated: b[4],
            },
            e0: b[5],
            elastic0: b[6],
            potential0: b[7],
            max_kinetic: b[8],
            max_elastic: b[9],
            max_potential: b[10],
            moved_in: b[11],
            rates: [b[12], b[13], b[14]],
        }
    }
}

/// History of one stage slot: X_n, X_{n-1} and X_t(t_n).
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
    /// At rest in the straight shape (v = e3, u = 0) with no internal force, released at
    /// t = 0: only for a rod whose reference shape is straight.
    Straight,
    /// At rest in the reference shape with no internal force (the unloaded rod: for a
    /// straight reference, `Straight`), released at t = 0: a pre-bent finger let go.
    Reference,
}

impl Initial {
    /// Released from rest with no internal force (not in equilibrium under the loads).
    fn released(self) -> bool {
        matches!(self, Initial::Straight | Initial::Reference)
    }

    /// The name users give it.
    pub fn name(self) -> &'static str {
        match self {
            Initial::Static => "static",
            Initial::Straight => "straight",
            Initial::Reference => "reference",
        }
    }
}

/// Counters of a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DynStats {
    /// Calls of `step` (output steps).
    pub steps: usize,
    /// Time steps taken (more than `steps` where steps were subdivided or adapted).
    pub internal_steps: usize,
    /// Steps rejected (Newton failure, a penetration beyond an obstacle's tolerance or,
    /// adaptive, error above the tolerance).
    pub rejected: usize,
    pub newton_iterations: usize,
    pub jacobians: usize,
}

fn rename_pressure_error(e: SoftrodError, name: &str) -> SoftrodError {
    rename_field(e, "pressures", name)
}

/// An invalid-parameter error with `from` in its field name replaced by `to`.
fn rename_field(e: SoftrodError, from: &str, to: &str) -> SoftrodError {
    match e {
        SoftrodError::InvalidParameter { field, value, rule } => SoftrodError::InvalidParameter {
            field: field.replacen(from, to, 1),
            value,
            rule,
        },
        other => other,
    }
}

/// What a Newton factorization was computed from (so a restored state can recompute it
/// bit for bit): the scaled unknowns, pressures, sigma, c0 and histories of its problem.
#[derive(Debug, Clone, PartialEq)]
struct JacKey {
    at: Vec<f64>,
    pressures: Vec<f64>,
    tensions: Vec<f64>,
    sigma: [f64; 3],
    c0: f64,
    hist: Vec<[f64; FIELDS]>,
    /// The tip's pose (a clamped tip's rotation enters the Jacobian).
    end: TipConstraint,
}

#[derive(Debug, Clone)]
struct Cached {
    fac: Factorization,
    key: JacKey,
}

/// A running simulation: the rod, the time, the inputs, the collocation state and the
/// integrator's histories. Clone it to branch from its current state; `save`/`restore`
/// round-trip it exactly.
#[derive(Debug, Clone)]
pub struct Simulator {
    rod: Rod,
    grid: Grid,
    /// Inertia and damping per model slot of `grid` (`Grid::models`).
    inertia: Vec<SectionInertia>,
    sigma_map: SigmaMap,
    opts: DynOptions,
    time: f64,
    /// Length of the last time step taken and the next one proposed (adaptive).
    h_prev: f64,
    h_next: f64,
    /// Chamber pressures now, Pa (after the supply lag and rate limit).
    pressures: Vec<f64>,
    sigma: [f64; 3],
    /// Tip loads now, in the design's tip frame (world: dead loads; body: follower loads):
    /// the design's, until changed with `set_tip_loads`.
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    /// The tip loads of the last step taken.
    step_tip: ([f64; 3], [f64; 3]),
    /// Tendon tensions now, N (one per tendon channel): from the next step on.
    tensions: Vec<f64>,
    /// The tensions of the last step taken.
    step_tensions: Vec<f64>,
    /// Physical unknowns now and one step before (for the predictor).
    z: Vec<f64>,
    z_prev: Vec<f64>,
    z_prev2: Vec<f64>,
    slots: Vec<Slot>,
    /// Section models at the current pressures and sigma with the c0 `models_c0` (for the
    /// energy, and the next step's problem when its inputs and c0 are the same).
    models: Vec<SectionModel>,
    models_c0: f64,
    eval: Evaluated,
    /// (time, node positions) of the last three steps, newest first (error estimates).
    past: Vec<(f64, Vec<[f64; 3]>)>,
    books: Books,
    cache: Option<Cached>,
    /// Newton's contraction rate with the kept matrix at the last step.
    theta: f64,
    /// Newton's buffers (scratch: not part of the state).
    work: NewtonWork,
    /// Scales of the unknowns (fixed for the run: `Simulator::scale_c0`).
    scales: Vec<f64>,
    /// How the run started.
    initial: Initial,
    /// The 'static' start's stability verdict (the static solver's conjugate-point test of
    /// the equilibrium it started from; None for the 'straight' start or where not
    /// assessed): a fixed step may hold an unstable equilibrium, so the caller is told.
    start_stable: Option<bool>,
    /// Forward parameter sensitivities, when tracked (`sensitivity`).
    sens: Option<Box<sensitivity::Tracker>>,
    /// How the tip is held: the pose at the end of the next output step (set with
    /// `set_tip_pose`), and the pose now (that of the last step taken).
    end: TipConstraint,
    end_now: TipConstraint,
    /// The wrench the constraint applies to the tip now (world), N and N m.
    reaction: ([f64; 3], [f64; 3]),
    /// The body points read as markers (`set_markers`): grid point and offset.
    markers: Vec<(GridPoint, [f64; 3])>,
    pub stats: DynStats,
}

/// Check that every section's law has a dynamic counterpart and the map is given where
/// needed.
fn check_dynamic_laws(rod: &Rod, map: &SigmaMap) -> Result<()> {
    crate::scope::check_statics_only_with(rod, "the dynamics", true, true)?;
    for (i, s) in rod.sections.iter().enumerate() {
        if s.law.stiffness_map && matches!(map, SigmaMap::None) {
            return Err(SoftrodError::invalid(
                format!("sections[{i}].law.stiffness_map"),
                true,
                "a mapped section needs a stiffness map (sigma of the pressures) for dynamics: pass a constant or table StiffnessMap",
            ));
        }
    }
    Ok(())
}

/// The candidate result of one time step, committed only if it passes every check.
struct Candidate {
    h: f64,
    pressures: Vec<f64>,
    sigma: [f64; 3],
    z: Vec<f64>,
    slots: Vec<Slot>,
    models: Vec<SectionModel>,
    eval: Evaluated,
    books: Books,
    /// Estimated local error of the node positions, m (None without enough history).
    error: Option<f64>,
    /// The step's time formula, history terms and converged scaled unknowns (for the
    /// parameter sensitivities).
    bdf: Bdf,
    hist: Vec<[f64; FIELDS]>,
    z_scaled: Vec<f64>,
    /// The tip's pose at the step's end and the constraint's reaction there.
    end: TipConstraint,
    reaction: ([f64; 3], [f64; 3]),
}

/// A time step set up for its Newton solve ([`Simulator::prepare`]).
struct Prep {
    h: f64,
    t_new: f64,
    /// Pressures and sigma at the step's end.
    pressures: Vec<f64>,
    sigma: [f64; 3],
    midpoint: bool,
    bdf: Bdf,
    /// The inputs the step's boundary-value problem is solved with.
    solve_p: Vec<f64>,
    solve_sigma: [f64; 3],
    solve_t: Vec<f64>,
    tip: TipBody,
    models: Vec<SectionModel>,
    hist: Vec<[f64; FIELDS]>,
    /// The tip's pose at the step's end.
    end: TipConstraint,
    /// Predicted physical unknowns.
    guess: Vec<f64>,
}

impl Prep {
    /// The step's collocation problem.
    fn problem<'a>(&'a self, rod: &'a Rod, grid: &'a Grid, scale_c0: f64) -> Problem<'a> {
        step_problem(
            rod,
            grid,
            scale_c0,
            &self.models,
            self.bdf.c0,
            &self.hist,
            self.tip,
        )
        .with_end(end_target(&self.end))
    }

    /// The error of a step from `time` whose Newton solve failed.
    fn not_converged(&self, time: f64, iterations: usize, residual: f64) -> SoftrodError {
        SoftrodError::NotConverged {
            iterations,
            residual,
            load_factor: 1.0,
            reason: format!(
                "dynamic step from t = {time:.6} s to {:.6} s (h = {:.3e} s) did not converge",
                self.t_new, self.h
            ),
        }
    }
}

impl Simulator {
    /// Start a simulation of `rod` at t = 0 with chamber pressures `pressures` (Pa).
    pub fn new(rod: Rod, pressures: &[f64], initial: Initial, opts: DynOptions) -> Result<Self> {
        Self::with_map(rod, pressures, initial, opts, SigmaMap::None)
    }

    /// [`Simulator::new`] with a stiffness map for the mapped sections.
    pub fn with_map(
        rod: Rod,
        pressures: &[f64],
        initial: Initial,
        opts: DynOptions,
        sigma_map: SigmaMap,
    ) -> Result<Self> {
        let (f, m) = (rod.spec.tip.force, rod.spec.tip.moment);
        Self::with_inputs(rod, pressures, initial, opts, sigma_map, f, m)
    }

    /// [`Simulator::with_map`] with tip loads at t = 0 (in the design's tip frame; the
    /// starting static state balances them) other than the design's.
    pub fn with_inputs(
        rod: Rod,
        pressures: &[f64],
        initial: Initial,
        opts: DynOptions,
        sigma_map: SigmaMap,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
    ) -> Result<Self> {
        let tensions = vec![0.0; rod.n_tendons];
        Self::with_tensions(
            rod, pressures, &tensions, initial, opts, sigma_map, tip_force, tip_moment,
        )
    }

    /// [`Simulator::with_inputs`] with tendon tensions at t = 0 (N, one per tendon channel,
    /// each finite and >= 0; the starting static state balances them).
    #[allow(clippy::too_many_arguments)]
    pub fn with_tensions(
        rod: Rod,
        pressures: &[f64],
        tensions: &[f64],
        initial: Initial,
        opts: DynOptions,
        sigma_map: SigmaMap,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
    ) -> Result<Self> {
        let free = TipConstraint::Free;
        Self::with_constraint(
            rod, pressures, tensions, initial, opts, sigma_map, tip_force, tip_moment, free,
        )
    }

    /// [`Simulator::with_tensions`] with the tip held by `constraint` (docs/model.md, "End
    /// constraints"): pinned or clamped at the given pose at t = 0, moved from step to step
    /// with [`Simulator::set_tip_pose`]. A 'static' start is the constrained equilibrium
    /// (`statics::constraint::solve_constrained`); a 'straight' one needs the pose of the
    /// straight rod's tip. With obstacles the step carries both (`collocation::contact`).
    /// Not with the midpoint scheme (refused by name: docs/dynamics.md "Held tip").
    #[allow(clippy::too_many_arguments)]
    pub fn with_constraint(
        rod: Rod,
        pressures: &[f64],
        tensions: &[f64],
        initial: Initial,
        opts: DynOptions,
        sigma_map: SigmaMap,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
        constraint: TipConstraint,
    ) -> Result<Self> {
        check_end(&rod, &opts, initial, &constraint)?;
        for (name, v) in [("tip_force", &tip_force), ("tip_moment", &tip_moment)] {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(SoftrodError::invalid(
                    name,
                    format!("{v:?}"),
                    "must be finite",
                ));
            }
        }
        opts.validate()?;
        check_dynamic_laws(&rod, &sigma_map)?;
        rod.check_pressures(pressures)?;
        rod.check_tensions(tensions)?;
        if initial == Initial::Straight && !rod.is_straight() {
            return Err(SoftrodError::invalid(
                "initial",
                "straight",
                "the rod's reference shape is not straight, and held straight it carries an internal moment its free tip cannot (no state at rest): start 'reference' (at rest in the reference shape) or start 'static'",
            ));
        }
        if initial.released() {
            // The unloaded state with n = m = 0 is no state of a rod whose tendons pull
            // (their tension is part of n): start slack and pull from the first step on.
            if let Some(k) = tensions.iter().position(|t| *t != 0.0) {
                return Err(SoftrodError::invalid(
                    format!("tensions[{k}]"),
                    tensions[k],
                    format!("the '{}' start is at rest with slack tendons: give tension 0 at t = 0 (and the tension from the first step on) or start 'static'", initial.name()),
                ));
            }
        }
        let sigma = sigma_map.eval(pressures)?;
        rod.check_loads(pressures, &sigma)?;
        // Both starts begin at the unloaded rod (the 'straight' one is it, the 'static' one
        // follows the loads from it): an obstacle it already sinks into is refused by name.
        let at_rest = Loads {
            pressures: pressures.to_vec(),
            tensions: tensions.to_vec(),
            tip_force,
            tip_moment,
            tip_frame: rod.spec.tip.frame,
            stiffness_scale: sigma,
        };
        statics::contact::clear_at_rest(&rod, &at_rest)?;
        let grid = Grid::new(&rod);
        // Inertia per model slot of the grid (a tapered section's at each stage point).
        let inertia: Vec<SectionInertia> = grid
            .models
            .iter()
            .map(|m| section_inertia_at(&rod, m.section, m.s))
            .collect();
        let n_slots = 2 * grid.len() + 1;
        let zero = Slot {
            x1: [0.0; FIELDS],
            x2: [0.0; FIELDS],
            xt: [0.0; FIELDS],
        };
        let mut sim = Simulator {
            inertia,
            sigma_map,
            opts,
            time: 0.0,
            h_prev: opts.dt,
            h_next: opts.dt,
            pressures: pressures.to_vec(),
            sigma,
            tip_force,
            tip_moment,
            step_tip: (tip_force, tip_moment),
            tensions: tensions.to_vec(),
            step_tensions: tensions.to_vec(),
            z: vec![],
            z_prev: vec![],
            z_prev2: vec![],
            slots: vec![zero; n_slots],
            models: vec![],
            models_c0: 0.0,
            eval: Evaluated::default(),
            past: vec![],
            books: Books::default(),
            cache: None,
            theta: 1.0,
            work: NewtonWork::default(),
            scales: vec![],
            initial,
            start_stable: None,
            sens: None,
            end: constraint,
            end_now: constraint,
            reaction: ([0.0; 3], [0.0; 3]),
            markers: vec![],
            stats: DynStats::default(),
            grid,
            rod,
        };
        sim.start(initial)?;
        Ok(sim)
    }

    /// The c0 of a step of the nominal length dt after one of the same length: the
    /// velocity scale of the unknowns for the whole run (`collocation::point_scale`).
    /// Fixed, so that a Newton matrix stays valid in the same coordinates across steps of
    /// other lengths (adaptive steps, halvings); steps shorter than dt only tighten the
    /// velocity tolerance (an error dq moves the rod by dq / c0 in a step).
    fn scale_c0(&self) -> f64 {
        match self.opts.scheme {
            Scheme::Midpoint => 2.0 / self.opts.dt,
            Scheme::BdfAlpha => Bdf::new(self.opts.alpha_eff(), self.opts.dt, self.opts.dt).c0,
        }
    }

    /// Section models at `pressures`, tendon `tensions` and `sigma` for the integrator's c0.
    fn models_at(
        &self,
        pressures: &[f64],
        tensions: &[f64],
        sigma: &[f64; 3],
        c0: f64,
    ) -> Vec<SectionModel> {
        self.models_scaled(pressures, tensions, sigma, c0, 1.0)
    }

    /// [`Self::models_at`] with every load (pressure, tension, gravity, line loads) scaled
    /// by `factor` (0: the unloaded rod).
    fn models_scaled(
        &self,
        pressures: &[f64],
        tensions: &[f64],
        sigma: &[f64; 3],
        c0: f64,
        factor: f64,
    ) -> Vec<SectionModel> {
        let tau = self.rod.spec.dynamics.damping_time;
        let coeffs: Vec<Coeffs<f64>> = (0..self.rod.sections.len())
            .map(|i| {
                Coeffs::build(
                    &self.rod,
                    i,
                    pressures,
                    tensions,
                    &self.rod.gravity,
                    factor,
                    sigma,
                )
            })
            .collect();
        self.grid.build_models(&self.rod, &coeffs, |c, k, slot| {
            let inr = &self.inertia[k];
            SectionModel::new(
                c,
                self.rod.sections[slot.section].rigid,
                inr.rho_a,
                inr.rho_j,
                inr.damping,
                tau,
                c0,
            )
        })
    }

    /// The tip body with tip loads `force`, `moment` in the design's tip frame.
    fn tip_body(&self, force: [f64; 3], moment: [f64; 3]) -> TipBody {
        let t = &self.rod.spec.tip;
        let z = [0.0; 3];
        let body = self.follower_tip();
        TipBody {
            mass: t.mass,
            com: t.com_offset,
            inertia: t.inertia,
            force: if body { z } else { force },
            moment: if body { z } else { moment },
            force_body: if body { force } else { z },
            moment_body: if body { moment } else { z },
        }
    }

    /// The tip loads follow the tip (the design's `tip.frame = "body"`).
    fn follower_tip(&self) -> bool {
        self.rod.spec.tip.frame == crate::spec::Frame::Body
    }

    /// The rest problem of the unloaded rod (every load off: `models0` from
    /// `models_scaled` at factor 0, no gravity, no tip loads; frictionless contact as in
    /// the run), whose solution is the reference shape with no internal force.
    fn unloaded_problem<'a>(
        &'a self,
        models0: &'a [SectionModel],
        hist0: &'a [[f64; FIELDS]],
    ) -> Problem<'a> {
        let tip0 = TipBody {
            force: [0.0; 3],
            moment: [0.0; 3],
            force_body: [0.0; 3],
            moment_body: [0.0; 3],
            ..self.tip_body([0.0; 3], [0.0; 3])
        };
        let mut p0 = Problem::new(&self.rod, &self.grid, models0, 0.0, hist0, tip0).with_contact();
        p0.gravity = [0.0; 3];
        p0
    }

    fn start(&mut self, initial: Initial) -> Result<()> {
        let zero = [0.0; FIELDS];
        let hist0 = vec![zero; self.slots.len()];
        let models = self.models_at(&self.pressures, &self.tensions, &self.sigma, 0.0);
        let tip = self.tip_body(self.tip_force, self.tip_moment);
        let problem = Problem::new(&self.rod, &self.grid, &models, 0.0, &hist0, tip)
            .with_contact()
            .with_end(end_target(&self.end));
        let loads = Loads {
            pressures: self.pressures.clone(),
            tensions: self.tensions.clone(),
            tip_force: self.tip_force,
            tip_moment: self.tip_moment,
            tip_frame: self.rod.spec.tip.frame,
            stiffness_scale: self.sigma,
        };
        // At rest the regularised friction carries no force: the static start is the
        // frictionless equilibrium (`statics::contact::without_friction`).
        let smooth = statics::contact::without_friction(&self.rod);
        let rest_rod = smooth.as_ref().unwrap_or(&self.rod);
        let z_scaled = match initial {
            Initial::Static if problem.end.is_some() => {
                // The constrained equilibrium of this discretisation at rest (c0 = 0), from
                // the static solver's (shooting, the same constraint).
                let sol = statics::constraint::solve_constrained(
                    rest_rod,
                    &loads,
                    &self.end,
                    None,
                    &SolverOptions::default(),
                )
                .map_err(|e| e.map_message(|m| format!("the initial static state: {m}")))?;
                self.start_stable = sol.solution.stable;
                let z = static_guess(&problem, &sol.shape);
                let what = format!("with a {} tip", self.end.name());
                let (z, it) = refine_static(&problem, z, self.opts.tol, &what)?;
                self.stats.newton_iterations += it;
                z
            }
            Initial::Static if problem.contact.is_some() => {
                // Equilibrium in contact: this discretisation's static problem with the
                // contact loads (c0 = 0), from the static solver's (shooting, contact
                // too) shape.
                let solved = statics::solve(rest_rod, &loads, None, &SolverOptions::default()).ok();
                self.start_stable = solved.as_ref().and_then(|sol| sol.stable);
                let z = solved
                    .map(|sol| static_guess(&problem, &statics::shape(rest_rod, &loads, &sol)))
                    .unwrap_or_else(|| problem.straight_unknowns());
                let (z, it) = refine_static(&problem, z, self.opts.tol, "in contact")?;
                self.stats.newton_iterations += it;
                z
            }
            Initial::Static => {
                // Equilibrium of this discretisation at rest (c0 = 0, no history), from
                // the static solver's solution (which picks shooting or collocation).
                let guess = statics::solve(&self.rod, &loads, None, &SolverOptions::default())
                    .ok()
                    .map(|sol| static_guess(&problem, &statics::shape(&self.rod, &loads, &sol)));
                let opts = SolverOptions {
                    tol: self.opts.tol.min(1e-10),
                    ..SolverOptions::default()
                };
                let sol = crate::statics::collocation::solve_static(
                    &self.rod,
                    &loads,
                    guess.as_deref(),
                    &opts,
                )
                .map_err(|e| match e {
                    SoftrodError::NotConverged {
                        iterations,
                        residual,
                        load_factor,
                        reason,
                    } => SoftrodError::NotConverged {
                        iterations,
                        residual,
                        load_factor,
                        reason: format!("the initial static state did not solve: {reason}"),
                    },
                    other => other,
                })?;
                self.stats.newton_iterations += sol.iterations;
                self.start_stable = sol.stable;
                sol.z
            }
            Initial::Straight => {
                self.start_stable = None;
                problem.straight_unknowns()
            }
            Initial::Reference if self.rod.is_straight() => {
                self.start_stable = None;
                problem.straight_unknowns()
            }
            Initial::Reference => {
                // The unloaded rod in its reference shape, n = m = 0: this discretisation's
                // rest problem with every load off, whose kinematics Newton solves from the
                // straight rod (with m = 0, u = u*: Q' = Q u*/2 is linear in Q).
                self.start_stable = None;
                let models0 =
                    self.models_scaled(&self.pressures, &self.tensions, &self.sigma, 0.0, 0.0);
                let p0 = self.unloaded_problem(&models0, &hist0);
                let (z0, it) = refine_static(
                    &p0,
                    p0.straight_unknowns(),
                    self.opts.tol,
                    "in the reference shape",
                )?;
                let z = problem.rescale_from(&p0, &z0);
                drop(p0);
                self.stats.newton_iterations += it;
                z
            }
        };
        drop(problem);
        self.rest_at(&z_scaled, initial)
    }

    /// Set the state at t = 0 to rest at the scaled unknowns `z_scaled` of the rest
    /// problem (c0 = 0) under the current inputs and tip pose: the histories, reaction and
    /// energy books of a start `initial`.
    fn rest_at(&mut self, z_scaled: &[f64], initial: Initial) -> Result<()> {
        let zero = [0.0; FIELDS];
        let hist0 = vec![zero; self.slots.len()];
        let models = self.models_at(&self.pressures, &self.tensions, &self.sigma, 0.0);
        let tip = self.tip_body(self.tip_force, self.tip_moment);
        let problem = Problem::new(&self.rod, &self.grid, &models, 0.0, &hist0, tip)
            .with_contact()
            .with_end(end_target(&self.end));
        let eval = problem.evaluate(z_scaled);
        let straight = self.rod.is_straight();
        if initial.released() {
            // The fields at rest with no internal force: the straight ones, or those of the
            // unloaded rod's rest problem at the same state.
            let unloaded = (!straight).then(|| {
                let models0 =
                    self.models_scaled(&self.pressures, &self.tensions, &self.sigma, 0.0, 0.0);
                let p0 = self.unloaded_problem(&models0, &hist0);
                p0.evaluate(&p0.rescale_from(&problem, z_scaled)).fields
            });
            self.check_released(&eval, unloaded.as_deref(), initial)?;
        }
        self.z = to_physical(&problem, z_scaled);
        self.z_prev = self.z.clone();
        self.z_prev2 = self.z.clone();
        let n = self.slots.len();
        for (k, (slot, f)) in self.slots[..n - 1].iter_mut().zip(&eval.fields).enumerate() {
            let mut xt = zero;
            if initial.released() {
                // Released from rest in a state that is no equilibrium: the stage
                // accelerations at t = 0+ follow from n' + u x n = rho A q_t - R^T f (body
                // frame) with n = m = 0 along the rod: q_t = R^T f / (rho A); w_t = 0 and
                // the strain rates are zero. A consistent start keeps the schemes second
                // order.
                let m = &models[self.grid.intervals[k / 2].model[k % 2]];
                if m.rho_a > 0.0 {
                    // Dead line loads (and contact loads, at rest: no friction) turned
                    // into the base frame; follower ones are body loads already.
                    let mut f = m.f;
                    if let (Some(o), Some(c)) = (&self.rod.obstacles, &problem.contact) {
                        let fc = crate::contact::total_line_force(
                            o,
                            &eval.stage_r[k],
                            c.stage_radius[k],
                        );
                        f = std::array::from_fn(|a| f[a] + fc[a]);
                    }
                    let rot = if straight {
                        &self.rod.base_rotation
                    } else {
                        &eval.stage_rot[k]
                    };
                    let fb = mat_t_vec(rot, &f);
                    for a in 0..3 {
                        xt[6 + a] = (fb[a] + m.f_body[a]) / m.rho_a;
                    }
                }
            }
            *slot = Slot { x1: *f, x2: *f, xt };
        }
        if initial.released() && self.end == TipConstraint::Free {
            // (A held tip does not accelerate.)
            let tip_rot = if straight {
                self.rod.base_rotation
            } else {
                eval.nodes.last().map_or(self.rod.base_rotation, |y| {
                    crate::collocation::rotation(&y[..4])
                })
            };
            let gb = mat_t_vec(&tip_rot, &self.rod.gravity);
            self.slots[n - 1].xt[6..9].copy_from_slice(&gb);
        }
        self.reaction = problem.tip_reaction(z_scaled);
        drop(problem);
        self.check_state(&eval, &self.z.clone(), None)?;
        self.models = models;
        self.models_c0 = 0.0;
        self.eval = eval;
        self.past = vec![(0.0, self.eval.node_r.clone())];
        let e = self.energy_now(&self.models, &self.eval, self.tip_force);
        self.books = Books {
            now: e,
            e0: e.total(),
            elastic0: e.elastic,
            potential0: e.potential,
            max_kinetic: e.kinetic,
            ..Books::default()
        };
        self.books.rates = self.rates(&self.models, &self.eval, &self.slots, self.tip_moment);
        Ok(())
    }

    /// The 'straight' start is the rod at rest with no internal force (n = m = 0), with its
    /// nodes on the straight line: a state of the rod only where the law's strains at zero
    /// force are straight (v = e3, u = 0). A chamber pressure at t = 0 (its strains) or a
    /// reference shape (u*, v*) makes them curved or stretched: the fields would disagree
    /// with the straight nodes, and the first step would jump to the curved shape at no
    /// cost in energy (a teleport, not a motion). Refused, naming what to change.
    /// A start released from rest with no internal force (`initial`) must be a state of
    /// the rod: its fields under the inputs at t = 0 are those with n = m = 0 (straight, or
    /// `unloaded`: the unloaded rod's at the same state). A chamber pressure at t = 0 shifts
    /// them (the rest state would carry an internal force the free tip cannot), so it is
    /// refused by name; so is any other shift.
    fn check_released(
        &self,
        eval: &Evaluated,
        unloaded: Option<&[[f64; FIELDS]]>,
        initial: Initial,
    ) -> Result<()> {
        // Exactly the unloaded strains without shifts (0 times the compliance plus a zero
        // shift); 1e-12 of a strain is round-off of a shift that cancels.
        let bent = eval.fields.iter().enumerate().any(|(k, f)| {
            let r = unloaded.map_or([0.0, 0.0, 1.0, 0.0, 0.0, 0.0], |u| {
                std::array::from_fn(|a| u[k][a])
            });
            ((f[0] - r[0]).abs() + (f[1] - r[1]).abs() + (f[2] - r[2]).abs()) > 1e-12
                || ((f[3] - r[3]).abs() + (f[4] - r[4]).abs() + (f[5] - r[5]).abs())
                    * self.rod.length
                    > 1e-12
        });
        if !bent {
            return Ok(());
        }
        let name = initial.name();
        let why = format!("the '{name}' start is the rod at rest in its reference shape with no internal force, which is a state of the rod only without chamber pressure at t = 0");
        if let Some(k) = self.pressures.iter().position(|p| *p != 0.0) {
            return Err(SoftrodError::invalid(
                format!("pressures[{k}]"),
                self.pressures[k],
                format!("{why}: give pressure 0 at t = 0 (and the pressure from the first step on) or start 'static'"),
            ));
        }
        Err(SoftrodError::invalid(
            "initial",
            name,
            format!("{why}: the inputs at t = 0 shift the strains of zero force; start 'static'"),
        ))
    }

    /// Finite values, rotations and quaternion norms at the nodes, stretch at the stages;
    /// the penetration rule, with the motion since `from` (the last step's state; None at
    /// the start).
    fn check_state(&self, eval: &Evaluated, z: &[f64], from: Option<&Evaluated>) -> Result<()> {
        let t = self.time;
        let node = |j: usize| validity::Node {
            index: j,
            s: self.grid.node_s(j),
            section: self.grid.intervals[j.min(self.grid.len() - 1)].section,
        };
        if let Some(k) = z.iter().position(|x| !x.is_finite()) {
            // z holds the base unknowns, then 48 per interval (stages and end node).
            let j = if k < 6 { 0 } else { (k - 6) / 48 + 1 };
            validity::check_finite(node(j.min(self.grid.len())), &z[k..=k])
                .map_err(|e| e.at_time(t))?;
        }
        for (j, y) in eval.nodes.iter().enumerate() {
            let qn = y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3];
            // The quaternion norm is a quadratic invariant of Gauss collocation, so it
            // stays 1 to the Newton tolerance times the number of intervals (<= 1e-9 x
            // 400); 1e-6 flags a state the collocation equations do not hold for.
            if (qn - 1.0).abs().is_nan() || (qn - 1.0).abs() > 1e-6 {
                let n = node(j);
                return Err(SoftrodError::InvalidState {
                    rule: validity::Rule::Rotation,
                    node: Some(j),
                    s: n.s,
                    time: Some(t),
                    value: qn,
                    message: format!(
                        "the rotation quaternion's squared norm is {qn:.9} in sections[{}], not 1 to 1e-6: the collocation equations do not hold (tighten tol or shorten the step)",
                        n.section
                    ),
                });
            }
            validity::check_rotation(node(j), &collocation::rotation(&y[..4]))
                .map_err(|e| e.at_time(t))?;
        }
        // Strains live at the stage points: the same physical rules as statics' nodes
        // (stretch positive and below the tearing limit, no chamber collapsed).
        for (k, f) in eval.fields.iter().enumerate() {
            let j = k / 2;
            let sec = &self.rod.sections[self.grid.intervals[j].section];
            let (v, u) = ([f[0], f[1], f[2]], [f[3], f[4], f[5]]);
            // A tapered section's chambers sit where the taper has moved them at the stage.
            let tt = if sec.tapered {
                self.grid.intervals[j].stage_local(k % 2) / sec.length
            } else {
                0.0
            };
            let centroid = |c: &crate::rod::Chamber| c.at(tt).2;
            let fine = v[2] > 0.0
                && v[2] <= validity::MAX_STRETCH
                && sec
                    .chambers
                    .iter()
                    .all(|c| validity::fibre_stretch(&v, &u, centroid(c)) > 0.0);
            if fine {
                continue;
            }
            // Report the interval's start node and the stage's own arc length.
            let at = validity::Node {
                index: j,
                s: self.grid.stage_s(j, k % 2),
                section: self.grid.intervals[j].section,
            };
            validity::check_stretch(at, &v).map_err(|e| e.at_time(t))?;
            for (c, ch) in sec.chambers.iter().enumerate() {
                validity::check_chamber(at, c, &v, &u, centroid(ch)).map_err(|e| e.at_time(t))?;
            }
        }
        self.check_penetration(eval, from)
    }

    /// The penetration rule (`Rule::Penetration`) at every stage point and at the rounded
    /// end, and between the stage points (an obstacle smaller than an interval could lie
    /// there unfelt): the rod's surface sinks into no obstacle deeper than its tolerance. In the
    /// dynamics an impact sinks the rod deeper than its weight does: the error says so.
    fn check_penetration(&self, eval: &Evaluated, from: Option<&Evaluated>) -> Result<()> {
        let (Some(obstacles), Some(c)) = (&self.rod.obstacles, self.contact()) else {
            return Ok(());
        };
        let t = self.time;
        let dynamic = |e: SoftrodError| {
            e.at_time(t).map_message(|m| {
                format!(
                    "{m}; in motion an impact sinks it deeper than a resting load: a stiffer penalty, a larger tolerance or a shorter step (dt) that resolves the impact"
                )
            })
        };
        for (k, r) in eval.stage_r.iter().enumerate() {
            let j = k / 2;
            let at = validity::Node {
                index: j,
                s: self.grid.stage_s(j, k % 2),
                section: self.grid.intervals[j].section,
            };
            crate::contact::check_penetration(obstacles, at, r, c.stage_radius[k])
                .map_err(dynamic)?;
        }
        let n = self.grid.len();
        let at = validity::Node {
            index: n,
            s: self.grid.node_s(n),
            section: self.grid.intervals[n - 1].section,
        };
        let r = eval.node_r.last().expect("tip node");
        crate::contact::check_penetration(obstacles, at, r, c.tip_radius).map_err(dynamic)?;
        // Between the stage points, on the collocation's own centreline (the quadratic
        // through the nodes and stages of each interval: the continuous extension).
        let sigma = [0.0, collocation::GAUSS_C[0], collocation::GAUSS_C[1], 1.0];
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let sec = &self.rod.sections[iv.section];
            let rho = [
                sec.surface_radius(iv.s_local),
                sec.surface_radius(iv.s_local + iv.h),
            ];
            let points = [
                &eval.node_r[j],
                &eval.stage_r[2 * j],
                &eval.stage_r[2 * j + 1],
                &eval.node_r[j + 1],
            ];
            let piece = crate::contact::Piece::through(iv.s0, iv.h, sigma, points, rho);
            let at = validity::Node {
                index: j,
                s: iv.s0,
                section: iv.section,
            };
            crate::contact::check_between(obstacles, &piece, at).map_err(|e| e.at_time(t))?;
        }
        // Over the step: each stage point and the rounded end moved from where the last
        // step left it, along a path a step's length long that the penalty felt at its ends
        // only. A thin obstacle crossed within one step leaves both ends outside it; the
        // straight path between them (the motion to first order in dt) shows the crossing.
        let Some(from) = from.filter(|f| f.stage_r.len() == eval.stage_r.len()) else {
            return Ok(());
        };
        let last = (eval.node_r.last(), from.node_r.last());
        let tip = match last {
            (Some(b), Some(a)) => Some((a, b, c.tip_radius, n)),
            _ => None,
        };
        let stages = (0..eval.stage_r.len())
            .map(|k| (&from.stage_r[k], &eval.stage_r[k], c.stage_radius[k], k / 2));
        for (k, (a, b, rho, j)) in stages.chain(tip).enumerate() {
            let path = crate::contact::Piece {
                c: [*a, std::array::from_fn(|i| b[i] - a[i]), [0.0; 3], [0.0; 3]],
                s: if k < eval.stage_r.len() {
                    self.grid.stage_s(j, k % 2)
                } else {
                    self.grid.node_s(n)
                },
                h: 0.0,
                rho: [rho; 2],
            };
            if let Some((o, x, depth)) = crate::contact::deepest_between(obstacles, &path) {
                return Err(SoftrodError::InvalidState {
                    rule: validity::Rule::Penetration,
                    node: Some(j),
                    s: path.s,
                    time: Some(t),
                    value: depth,
                    message: format!(
                        "the rod's surface at s = {:.6} m passes {depth:.3e} m into obstacles[{o}] during the step to t = {t:.6} s (it moves {:.3e} m in one step, and the obstacle lies across that path {:.0} % of the way), deeper than its tolerance {:.3e} m: the step is too long to resolve this obstacle; use a shorter step (dt) or an adaptive one (error_tol)",
                        path.s,
                        (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f64>().sqrt(),
                        100.0 * x,
                        obstacles[o].tolerance
                    ),
                });
            }
        }
        Ok(())
    }

    /// The contact data of the rod on this run's grid (None without obstacles).
    fn contact(&self) -> Option<collocation::Contact> {
        collocation::Contact::of(&self.rod, &self.grid)
    }

    /// The contact loads of a state: the total contact force on the rod (N, world frame),
    /// the penalty potential (J) and the deepest
    /// penetration (m, <= 0: no contact), each a quadrature over the stage points (the
    /// collocation's own) plus the rounded end.
    fn contact_loads(&self, eval: &Evaluated) -> Option<ContactState> {
        let c = self.contact()?;
        let mut out = ContactState {
            force: [0.0; 3],
            potential: 0.0,
            max_penetration: f64::NEG_INFINITY,
        };
        let mut add =
            |r: &[f64; 3], rot: &[[f64; 3]; 3], q: &[f64], w: &[f64], rho: f64, wgt: f64| {
                let vel = mat_vec(rot, &[q[0], q[1], q[2]]);
                let omega = mat_vec(rot, &[w[0], w[1], w[2]]);
                let l = crate::contact::total_section_load(&c.obstacles, r, &vel, &omega, rho);
                for k in 0..3 {
                    out.force[k] += wgt * l.force[k];
                }
                for o in c.obstacles.iter() {
                    out.potential += wgt * o.potential(r, rho);
                    out.max_penetration = out.max_penetration.max(rho - o.distance(r).0);
                }
            };
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            for i in 0..2 {
                let k = 2 * j + i;
                let f = &eval.fields[k];
                add(
                    &eval.stage_r[k],
                    &eval.stage_rot[k],
                    &f[6..9],
                    &f[9..12],
                    c.stage_radius[k],
                    iv.h * GAUSS_B[i],
                );
            }
        }
        // The rounded end: the tip section's line load over the cap's length rho.
        let y = eval.nodes.last().expect("tip node");
        let rot = collocation::rotation(&y[..4]);
        let r = eval.node_r.last().expect("tip node");
        add(r, &rot, &y[10..13], &y[13..16], c.tip_radius, c.tip_radius);
        Some(out)
    }

    /// Friction's dissipation over a step of length h from `old` to `new`: minus the work
    /// of the new state's friction forces (those the implicit step applied) along the
    /// step's slip of each stage point and of the rounded end, -f_t . dr - h l_t . omega
    /// (l_t the friction's moment, so l_t . omega = f_t . (omega x arm)). Where friction
    /// holds the rod this is minus the work of what it holds (the same displacements as the
    /// potentials' change), so a sticking contact balances; the trapezoid of the end rates
    /// would not where the regularised law is stiff (v_reg / (mu g) << h).
    fn friction_work(&self, old: &Evaluated, new: &Evaluated, h: f64) -> f64 {
        let Some(c) = self.contact() else {
            return 0.0;
        };
        let mut out = 0.0;
        let mut add = |r0: &[f64; 3],
                       r: &[f64; 3],
                       rot: &[[f64; 3]; 3],
                       q: &[f64],
                       w: &[f64],
                       rho: f64,
                       wgt: f64| {
            let vel = mat_vec(rot, &[q[0], q[1], q[2]]);
            let omega = mat_vec(rot, &[w[0], w[1], w[2]]);
            let l = crate::contact::total_section_load(&c.obstacles, r, &vel, &omega, rho);
            out -= wgt
                * (0..3)
                    .map(|k| l.friction[k] * (r[k] - r0[k]) + h * l.moment[k] * omega[k])
                    .sum::<f64>();
        };
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            for i in 0..2 {
                let k = 2 * j + i;
                let f = &new.fields[k];
                add(
                    &old.stage_r[k],
                    &new.stage_r[k],
                    &new.stage_rot[k],
                    &f[6..9],
                    &f[9..12],
                    c.stage_radius[k],
                    iv.h * GAUSS_B[i],
                );
            }
        }
        let y = new.nodes.last().expect("tip node");
        let rot = collocation::rotation(&y[..4]);
        add(
            old.node_r.last().expect("tip node"),
            new.node_r.last().expect("tip node"),
            &rot,
            &y[10..13],
            &y[13..16],
            c.tip_radius,
            c.tip_radius,
        );
        out
    }

    /// The contact state now (None without obstacles): total contact force on the rod, N
    /// (world frame), and the deepest penetration of its surface, m (<= 0: no contact).
    pub fn contact_state(&self) -> Option<ContactState> {
        self.contact_loads(&self.eval)
    }

    /// Kinetic, elastic and potential energy of a state.
    fn energy_now(&self, models: &[SectionModel], eval: &Evaluated, force: [f64; 3]) -> Energy {
        let mut e = Energy::default();
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            for i in 0..2 {
                let m = &models[iv.model[i]];
                let k = 2 * j + i;
                let f = &eval.fields[k];
                let r = &eval.stage_r[k];
                let wgt = iv.h * GAUSS_B[i];
                let (q, w) = (&f[6..9], &f[9..12]);
                e.kinetic += wgt
                    * 0.5
                    * (m.rho_a * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
                        + (0..3).map(|a| m.rho_j[a] * w[a] * w[a]).sum::<f64>());
                e.potential -= wgt * (0..3).map(|a| m.f[a] * r[a]).sum::<f64>();
                if !m.rigid {
                    e.elastic += wgt * stored_density(m, f, iv.stage_local(i));
                }
            }
        }
        let t = &self.rod.spec.tip;
        let y = eval.nodes.last().expect("tip node");
        let rot = collocation::rotation(&y[..4]);
        let q = [y[10], y[11], y[12]];
        let w = [y[13], y[14], y[15]];
        let wxc = cross(&w, &t.com_offset);
        let vc: [f64; 3] = std::array::from_fn(|k| q[k] + wxc[k]);
        let cw = mat_vec(&rot, &t.com_offset);
        let r = eval.node_r.last().expect("tip node");
        let g = self.rod.gravity;
        e.kinetic += 0.5 * t.mass * (vc[0] * vc[0] + vc[1] * vc[1] + vc[2] * vc[2]);
        e.kinetic += 0.5 * (0..3).map(|k| t.inertia[k] * w[k] * w[k]).sum::<f64>();
        e.potential -= t.mass * (0..3).map(|k| g[k] * (r[k] + cw[k])).sum::<f64>();
        if !self.follower_tip() {
            // A dead tip force has a potential; a follower one does work (`rates`).
            e.potential -= (0..3).map(|k| force[k] * r[k]).sum::<f64>();
        }
        if let Some(c) = self.contact_loads(eval) {
            e.potential += c.potential;
        }
        e
    }

    /// Kelvin-Voigt dissipation over a step of length h from `old` to `new`: h (dX/h) B
    /// (dX/h) with dX the change of the stage strains, the midpoint rate of the
    /// trapezoidal rule, under which it is the exact energy loss of the linearised rod.
    fn dissipation(
        &self,
        models: &[SectionModel],
        old: &Evaluated,
        new: &Evaluated,
        h: f64,
    ) -> f64 {
        let mut out = 0.0;
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let m = &models[iv.model[0]];
            if m.rigid {
                continue;
            }
            for i in 0..2 {
                let m = &models[iv.model[i]];
                let k = 2 * j + i;
                let (a, b) = (&old.fields[k], &new.fields[k]);
                let dv: [f64; 3] = std::array::from_fn(|c| b[c] - a[c]);
                let du: [f64; 3] = std::array::from_fn(|c| b[3 + c] - a[3 + c]);
                let mut d = (0..3).map(|c| dv[c] * m.b_se[c] * dv[c]).sum::<f64>();
                for c in 0..3 {
                    for e in 0..3 {
                        d += du[c] * m.b_bt[c][e] * du[e];
                    }
                }
                out += iv.h * GAUSS_B[i] * d / h;
            }
        }
        out
    }

    /// Rates at one instant: Kelvin-Voigt dissipation, power of the loads without a
    /// potential (dead moments, line and tip; follower loads, line and tip, at the tip's
    /// loads now: F_b . q + M_b . w with q, w the body-frame velocities), power of the
    /// non-potential part of stretch-dependent bending.
    fn rates(
        &self,
        models: &[SectionModel],
        eval: &Evaluated,
        slots: &[Slot],
        moment: [f64; 3],
    ) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let m = &models[iv.model[0]];
            if m.rigid {
                continue;
            }
            for i in 0..2 {
                let m = &models[iv.model[i]];
                let k = 2 * j + i;
                let wgt = iv.h * GAUSS_B[i];
                let xt = &slots[k].xt;
                let f = &eval.fields[k];
                let (vt, ut) = (&xt[0..3], &xt[3..6]);
                let mut d = (0..3).map(|a| vt[a] * m.b_se[a] * vt[a]).sum::<f64>();
                for a in 0..3 {
                    for b in 0..3 {
                        d += ut[a] * m.b_bt[a][b] * ut[b];
                    }
                }
                out[0] += wgt * d;
                let ww = mat_vec(&eval.stage_rot[k], &[f[9], f[10], f[11]]);
                out[1] += wgt * (0..3).map(|a| m.l[a] * ww[a]).sum::<f64>();
                if m.follower {
                    out[1] += wgt
                        * (0..3)
                            .map(|a| m.f_body[a] * f[6 + a] + m.l_body[a] * f[9 + a])
                            .sum::<f64>();
                }
                if m.stretch_bending {
                    // The law's axial force lacks d/dv3 of (1/2) rho (u_b - u*_b) K_b
                    // (u_b - u*_b), rho = v3 - v3* + 1 (`elastic_density`).
                    let u = [f[3] - m.u_star[0], f[4] - m.u_star[1]];
                    let ub = 0.5
                        * (0..2)
                            .map(|a| (0..2).map(|b| u[a] * m.k_bt[a][b] * u[b]).sum::<f64>())
                            .sum::<f64>();
                    out[2] += wgt * ub * vt[2];
                }
            }
        }
        let y = eval.nodes.last().expect("tip node");
        if self.follower_tip() {
            let f = self.tip_force;
            out[1] += (0..3)
                .map(|k| f[k] * y[10 + k] + moment[k] * y[13 + k])
                .sum::<f64>();
        } else {
            let rot = collocation::rotation(&y[..4]);
            let ww = mat_vec(&rot, &[y[13], y[14], y[15]]);
            out[1] += (0..3).map(|k| moment[k] * ww[k]).sum::<f64>();
        }
        out
    }

    /// One time step with the commanded pressures `command` (Pa) held over it: dt, taken
    /// as one step, as substeps where Newton fails, or as error-controlled steps (adaptive).
    pub fn step(&mut self, command: &[f64]) -> Result<()> {
        self.step_with(command, None)
    }

    /// [`Simulator::step`] where the steps inside the interval (substeps, adaptive steps)
    /// take their commands from `schedule` at their own end times (the interval's end
    /// still takes `command`), and end on the schedule's knots.
    pub fn step_with(&mut self, command: &[f64], schedule: Option<&CommandSchedule>) -> Result<()> {
        crate::spec::validate_pressures(command, self.rod.n_channels)
            .map_err(|e| rename_pressure_error(e, "command"))?;
        drive(self, command, schedule)
    }

    /// Solve one time step of length h (not committed).
    fn attempt(&mut self, h: f64, command: &[f64]) -> Result<Candidate> {
        let prep = self.prepare(h, command)?;
        let problem = prep.problem(&self.rod, &self.grid, self.scale_c0());
        let mut z: Vec<f64> = prep
            .guess
            .iter()
            .zip(&self.scales)
            .map(|(a, b)| a / b)
            .collect();
        let old = self
            .cache
            .take()
            .filter(|c| (c.key.c0 / prep.bdf.c0 - 1.0).abs() <= REUSE_C0);
        let (mut cache, old_key) = match old {
            Some(c) => (Some(c.fac), Some(c.key)),
            None => (None, None),
        };
        let nopts = NewtonOptions {
            tol: self.opts.tol,
            max_iter: self.opts.max_iter,
        };
        let mut ns = NewtonStats::default();
        let result = collocation::newton_with(
            &problem,
            &mut z,
            &mut cache,
            &nopts,
            &mut ns,
            &mut self.theta,
            &mut self.work,
        );
        self.stats.newton_iterations += ns.iterations;
        self.stats.jacobians += ns.jacobians;
        // Keep the factorization, and what it was computed from, for the next step.
        self.cache = cache.map(|fac| {
            let key = match old_key {
                Some(k) if k.at == fac.at => k,
                _ => JacKey {
                    at: fac.at.clone(),
                    pressures: prep.solve_p.clone(),
                    tensions: prep.solve_t.clone(),
                    sigma: prep.solve_sigma,
                    c0: prep.bdf.c0,
                    hist: prep.hist.clone(),
                    end: prep.end,
                },
            };
            Cached { fac, key }
        });
        if let Err((it, res)) = result {
            return Err(prep.not_converged(self.time, it, res));
        }
        let fields = std::mem::take(&mut self.work.fields);
        let at_solution = self.work.fields_at_solution;
        let out = self.finish(prep, z, at_solution.then_some(&fields[..]));
        self.work.fields = fields;
        out
    }

    /// Everything of a step of length h before its Newton solve: the inputs advanced, the
    /// time formula, section models, history terms, the held tip's pose and the predictor
    /// (shared with the systems of rods, `system`).
    fn prepare(&mut self, h: f64, command: &[f64]) -> Result<Prep> {
        let t_new = self.time + h;
        let mut pressures = self.pressures.clone();
        self.rod
            .spec
            .dynamics
            .advance_supply(h, &mut pressures, command);
        let sigma = self.sigma_map.eval(&pressures)?;
        self.rod.check_loads(&pressures, &sigma)?;
        let midpoint = self.opts.scheme == Scheme::Midpoint;
        let bdf = if midpoint {
            // X_t(t_{n+1/2}) = (2 / h) (X_{n+1/2} - X_n).
            Bdf {
                c0: 2.0 / h,
                c1: -2.0 / h,
                c2: 0.0,
                d1: 0.0,
            }
        } else {
            Bdf::new(self.opts.alpha_eff(), h, self.h_prev)
        };
        // The step's boundary-value problem: at t_{n+1}, or at the midpoint with the
        // inputs halfway.
        let (solve_p, solve_sigma, tip) = if midpoint {
            let pm: Vec<f64> = self
                .pressures
                .iter()
                .zip(&pressures)
                .map(|(a, b)| 0.5 * (a + b))
                .collect();
            let sm = self.sigma_map.eval(&pm)?;
            let f: [f64; 3] =
                std::array::from_fn(|k| 0.5 * (self.step_tip.0[k] + self.tip_force[k]));
            let m: [f64; 3] =
                std::array::from_fn(|k| 0.5 * (self.step_tip.1[k] + self.tip_moment[k]));
            (pm, sm, self.tip_body(f, m))
        } else {
            (
                pressures.clone(),
                sigma,
                self.tip_body(self.tip_force, self.tip_moment),
            )
        };
        let solve_t = self.solve_tensions(midpoint);
        // Unchanged inputs and step: the models of the last step (the same numbers).
        let models = if self.models_c0 == bdf.c0
            && solve_p == self.pressures
            && solve_sigma == self.sigma
            && solve_t == self.step_tensions
        {
            self.models.clone()
        } else {
            self.models_at(&solve_p, &solve_t, &solve_sigma, bdf.c0)
        };
        let hist: Vec<[f64; FIELDS]> = self
            .slots
            .iter()
            .map(|s| {
                std::array::from_fn(|k| bdf.c1 * s.x1[k] + bdf.c2 * s.x2[k] + bdf.d1 * s.xt[k])
            })
            .collect();
        // The tip's pose at t_new: the set pose at the output step's end, interpolated
        // from the pose now (linear in position, geodesic in rotation) inside it.
        let t_end = (self.stats.steps + 1) as f64 * self.opts.dt;
        let end = interpolate_pose(&self.end_now, &self.end, h / (t_end - self.time));
        let problem = step_problem(
            &self.rod,
            &self.grid,
            self.scale_c0(),
            &models,
            bdf.c0,
            &hist,
            tip,
        )
        .with_end(end_target(&end));
        // Predictor. BDF-alpha damps the unresolved modes: linear extrapolation. The
        // trapezoidal and midpoint rules keep them, flipping sign every step
        // (amplification -> -1 for omega h >> 1): z_n + z_{n-1} - z_{n-2} extrapolates
        // linear trends and such alternating modes exactly (at equal steps).
        let ratio = h / self.h_prev;
        let alternating = self.opts.alpha_eff() == -0.5 && self.z_prev2.len() == self.z.len();
        let guess: Vec<f64> = if alternating {
            (0..self.z.len())
                .map(|k| self.z[k] + ratio * (self.z_prev[k] - self.z_prev2[k]))
                .collect()
        } else if self.past.len() >= 3 {
            // BDF-alpha: the quadratic through the last three states (at past[0..3]'s
            // times): the first correction shrinks from O(h^2) to O(h^3) on smooth motion,
            // so that one correction with the kept matrix usually ends the step.
            let ts = [t_new, self.past[0].0, self.past[1].0, self.past[2].0];
            let lag = |k: usize| -> f64 {
                let mut w = 1.0;
                for m in 1..4 {
                    if m != k {
                        w *= (ts[0] - ts[m]) / (ts[k] - ts[m]);
                    }
                }
                w
            };
            let w = [lag(1), lag(2), lag(3)];
            (0..self.z.len())
                .map(|k| w[0] * self.z[k] + w[1] * self.z_prev[k] + w[2] * self.z_prev2[k])
                .collect()
        } else {
            self.z
                .iter()
                .zip(&self.z_prev)
                .map(|(a, b)| a + ratio * (a - b))
                .collect()
        };
        if self.scales.len() != guess.len() {
            self.scales = unknown_scales(&problem, guess.len());
        }
        drop(problem);
        Ok(Prep {
            h,
            t_new,
            pressures,
            sigma,
            midpoint,
            bdf,
            solve_p,
            solve_sigma,
            solve_t,
            tip,
            models,
            hist,
            end,
            guess,
        })
    }

    /// The rest of a step once its Newton solve converged at scaled unknowns `z` (`fields`:
    /// the stage fields there, if known): the new state, its checks and energy books, and
    /// the local error estimate.
    fn finish(
        &mut self,
        prep: Prep,
        z: Vec<f64>,
        fields: Option<&[[f64; FIELDS]]>,
    ) -> Result<Candidate> {
        let Prep {
            h,
            t_new,
            pressures,
            sigma,
            midpoint,
            bdf,
            models,
            hist,
            end,
            ..
        } = prep;
        let problem = step_problem(
            &self.rod,
            &self.grid,
            self.scale_c0(),
            &models,
            bdf.c0,
            &hist,
            prep.tip,
        )
        .with_end(end_target(&end));
        let solved = match fields {
            Some(f) => problem.evaluate_with_fields(&z, f),
            None => problem.evaluate(&z),
        };
        if let (TipConstraint::Clamped { rotation, .. }, Some(y)) = (&end, solved.nodes.last()) {
            // e(R_c^T R(L)) vanishes at a half turn too: a step that lands there failed
            // (it is retried shorter, as a step whose Newton fails).
            let a = tmatmul(rotation, &collocation::rotation(&y[..4]));
            crate::statics::constraint::check_half_turn("tip_constraint.orientation", &a)?;
        }
        let reaction = problem.tip_reaction(&z);
        drop(problem);
        let zp: Vec<f64> = z.iter().zip(&self.scales).map(|(a, b)| a * b).collect();
        let (eval, models) = if midpoint {
            let models_new = if self.models_c0 == bdf.c0
                && pressures == self.pressures
                && sigma == self.sigma
                && self.tensions == self.step_tensions
            {
                self.models.clone()
            } else {
                self.models_at(&pressures, &self.tensions, &sigma, bdf.c0)
            };
            (self.midpoint_end(&solved), models_new)
        } else {
            (solved, models)
        };
        let saved_time = self.time;
        self.time = t_new;
        let checked = self.check_state(&eval, &zp, Some(&self.eval));
        self.time = saved_time;
        checked?;
        let n = self.slots.len();
        let mut slots = self.slots.clone();
        for (k, slot) in slots.iter_mut().enumerate() {
            let f = if k + 1 < n {
                eval.fields[k]
            } else {
                let y = eval.nodes.last().expect("tip node");
                let mut tf = [0.0; FIELDS];
                tf[6..12].copy_from_slice(&y[10..16]);
                tf
            };
            // X_t at the new time (BDF-alpha, trapezoidal) or over the step (midpoint).
            let xt: [f64; FIELDS] = if midpoint {
                std::array::from_fn(|a| (f[a] - slot.x1[a]) / h)
            } else {
                std::array::from_fn(|a| bdf.c0 * f[a] + hist[k][a])
            };
            *slot = Slot {
                x1: f,
                x2: slot.x1,
                xt,
            };
        }
        // Energy books.
        let mut books = self.books;
        let e = self.energy_now(&models, &eval, self.tip_force);
        // Work of changing pressures (and sigma): the stored energy's change at fixed
        // strains, at the old and new strains. A scheme that applies the new inputs over
        // the step (BDF-alpha solves (1 + alpha) f_{n+1} - alpha f_n = ...) does their
        // work at the configuration they first act on: for a linear law with a jump of the
        // inputs the discrete energy identity gives exactly weight 1 + alpha on the old
        // strains and -alpha on the new (the trapezoidal and midpoint rules: 1/2, 1/2);
        // second order for smooth changes. Of a changed dead tip force: -dF . r_tip alike.
        let w_new = if midpoint {
            0.5
        } else {
            -self.opts.alpha_eff()
        };
        // Unchanged models (same inputs and step): both differences are exactly zero (the
        // same sums in the same order as energy_now's), so skip their two passes.
        let pin = if models == self.models {
            0.0
        } else {
            w_new * (e.elastic - self.elastic_of(&self.models, &eval))
                + (1.0 - w_new) * (self.elastic_of(&models, &self.eval) - self.books.now.elastic)
        };
        let r0 = self.eval.node_r.last().expect("tip");
        let r1 = eval.node_r.last().expect("tip");
        // (A follower tip force has no potential: its work is in `rates`.)
        let follower = self.follower_tip();
        let df: [f64; 3] = std::array::from_fn(|k| {
            if follower {
                0.0
            } else {
                self.tip_force[k] - self.step_tip.0[k]
            }
        });
        let fin = -(0..3)
            .map(|k| df[k] * ((1.0 - w_new) * r0[k] + w_new * r1[k]))
            .sum::<f64>();
        let rates = self.rates(&models, &eval, &slots, self.tip_moment);
        let d = self.dissipation(&models, &self.eval, &eval, h);
        let win = 0.5 * h * (books.rates[1] + rates[1] + books.rates[2] + rates[2])
            + reaction_work(&self.end_now, &end, self.reaction, reaction, w_new);
        books.now = Energy {
            work_in: books.now.work_in + pin + fin + win,
            dissipated: books.now.dissipated + d + self.friction_work(&self.eval, &eval, h),
            ..e
        };
        books.rates = rates;
        books.moved_in += pin.abs() + fin.abs() + win.abs();
        books.max_kinetic = books.max_kinetic.max(e.kinetic);
        books.max_elastic = books.max_elastic.max((e.elastic - books.elastic0).abs());
        books.max_potential = books
            .max_potential
            .max((e.potential - books.potential0).abs());
        self.energy_check(&books, t_new, h)?;
        // Local error estimate of the node positions (adaptive stepping).
        let error = if self.past.len() >= 3 {
            let ts = [t_new, self.past[0].0, self.past[1].0, self.past[2].0];
            let cp = ((ts[0] - ts[1]) * (ts[0] - ts[2]) * (ts[0] - ts[3]) / 6.0).abs();
            let cs = if midpoint {
                h.powi(3) / 24.0 // the midpoint rule's local error constant
            } else {
                bdf.error_constant(h, self.h_prev)
            };
            let lag = |k: usize| -> f64 {
                let mut w = 1.0;
                for m in 1..4 {
                    if m != k {
                        w *= (ts[0] - ts[m]) / (ts[k] - ts[m]);
                    }
                }
                w
            };
            let w = [lag(1), lag(2), lag(3)];
            let mut worst: f64 = 0.0;
            for (j, r) in eval.node_r.iter().enumerate() {
                let pred: [f64; 3] = std::array::from_fn(|a| {
                    w[0] * self.past[0].1[j][a]
                        + w[1] * self.past[1].1[j][a]
                        + w[2] * self.past[2].1[j][a]
                });
                let d = ((r[0] - pred[0]).powi(2)
                    + (r[1] - pred[1]).powi(2)
                    + (r[2] - pred[2]).powi(2))
                .sqrt();
                worst = worst.max(d);
            }
            Some(cs / (cs + cp) * worst)
        } else {
            None
        };
        Ok(Candidate {
            h,
            pressures,
            sigma,
            z: zp,
            slots,
            models,
            eval,
            books,
            error,
            bdf,
            hist,
            z_scaled: z,
            end,
            reaction,
        })
    }

    /// The state at t_{n+1} of a midpoint step: stage fields X_{n+1} = 2 X_{n+1/2} - X_n,
    /// node forces, moments and velocities extrapolated alike, and the shape rebuilt from
    /// the new strains from the base by the same collocation (Q' = Q (0, u) / 2 is linear
    /// in Q for given u: an 8 x 8 solve per interval) and quadrature for r.
    fn midpoint_end(&self, mid: &Evaluated) -> Evaluated {
        let old = &self.eval;
        let twice = |m: &[f64], o: &[f64], k: usize| 2.0 * m[k] - o[k];
        let fields: Vec<[f64; FIELDS]> = mid
            .fields
            .iter()
            .zip(&old.fields)
            .map(|(m, o)| std::array::from_fn(|k| twice(m, o, k)))
            .collect();
        let node_at = |j: usize, q: [f64; 4]| -> [f64; NY] {
            std::array::from_fn(|k| {
                if k < 4 {
                    q[k]
                } else {
                    twice(&mid.nodes[j], &old.nodes[j], k)
                }
            })
        };
        let w = |u: &[f64]| -> nalgebra::Matrix4<f64> {
            nalgebra::Matrix4::new(
                0.0, -u[0], -u[1], -u[2], u[0], 0.0, u[2], -u[1], u[1], -u[2], 0.0, u[0], u[2],
                u[1], -u[0], 0.0,
            ) * 0.5
        };
        let n_int = self.grid.len();
        let mut out = Evaluated {
            nodes: Vec::with_capacity(n_int + 1),
            node_r: Vec::with_capacity(n_int + 1),
            fields: Vec::with_capacity(2 * n_int),
            stage_r: Vec::with_capacity(2 * n_int),
            stage_rot: Vec::with_capacity(2 * n_int),
            stage_q: Vec::with_capacity(2 * n_int),
        };
        let q0 = collocation::quaternion(&self.rod.base_rotation);
        let mut qj = nalgebra::Vector4::from_column_slice(&q0);
        let mut r = self.rod.base_position;
        out.nodes.push(node_at(0, q0));
        out.node_r.push(r);
        let a = [[0.25, 0.25 - SQRT3_6], [0.25 + SQRT3_6, 0.25]];
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let (f1, f2) = (&fields[2 * j], &fields[2 * j + 1]);
            let ws = [w(&f1[3..6]), w(&f2[3..6])];
            let mut m = nalgebra::SMatrix::<f64, 8, 8>::identity();
            for i in 0..2 {
                for k in 0..2 {
                    let blk = ws[k] * (-iv.h * a[i][k]);
                    for rr in 0..4 {
                        for cc in 0..4 {
                            m[(4 * i + rr, 4 * k + cc)] += blk[(rr, cc)];
                        }
                    }
                }
            }
            let rhs = nalgebra::SVector::<f64, 8>::from_fn(|k, _| qj[k % 4]);
            let qs = m
                .lu()
                .solve(&rhs)
                .unwrap_or_else(|| nalgebra::SVector::from_element(f64::NAN));
            let q1 = qs.fixed_rows::<4>(0).into_owned();
            let q2 = qs.fixed_rows::<4>(4).into_owned();
            let qn = qj + (ws[0] * q1 + ws[1] * q2) * (0.5 * iv.h);
            let rots = [
                collocation::rotation(q1.as_slice()),
                collocation::rotation(q2.as_slice()),
            ];
            let dr = [
                mat_vec(&rots[0], &[f1[0], f1[1], f1[2]]),
                mat_vec(&rots[1], &[f2[0], f2[1], f2[2]]),
            ];
            for i in 0..2 {
                out.stage_r.push(std::array::from_fn(|k| {
                    r[k] + iv.h * (a[i][0] * dr[0][k] + a[i][1] * dr[1][k])
                }));
                out.stage_rot.push(rots[i]);
            }
            out.stage_q.push([q1[0], q1[1], q1[2], q1[3]]);
            out.stage_q.push([q2[0], q2[1], q2[2], q2[3]]);
            r = std::array::from_fn(|k| r[k] + iv.h * 0.5 * (dr[0][k] + dr[1][k]));
            qj = qn;
            out.nodes.push(node_at(j + 1, [qn[0], qn[1], qn[2], qn[3]]));
            out.node_r.push(r);
        }
        out.fields = fields;
        out
    }

    /// The stored energy of a state under other section models (other pressures).
    fn elastic_of(&self, models: &[SectionModel], eval: &Evaluated) -> f64 {
        let mut e = 0.0;
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let m = &models[iv.model[0]];
            if m.rigid {
                continue;
            }
            for i in 0..2 {
                let m = &models[iv.model[i]];
                let f = &eval.fields[2 * j + i];
                e += iv.h * GAUSS_B[i] * stored_density(m, f, iv.stage_local(i));
            }
        }
        e
    }

    /// The energy check ([`check_energy`]) with the round-off floor 1e-10 F_s L
    /// (F_s = EI_min / L^2).
    fn energy_check(&self, books: &Books, t: f64, h: f64) -> Result<()> {
        let floor = 1e-10 * self.rod.force_scale * self.rod.length;
        check_energy(books, &self.opts, floor, t, h, self.stats.steps + 1)
    }

    fn commit(&mut self, c: Candidate) {
        self.past
            .insert(0, (self.time + c.h, c.eval.node_r.clone()));
        self.past.truncate(3);
        self.time += c.h;
        self.h_prev = c.h;
        self.pressures = c.pressures;
        self.sigma = c.sigma;
        self.z_prev2 = std::mem::replace(&mut self.z_prev, std::mem::replace(&mut self.z, c.z));
        self.slots = c.slots;
        self.models = c.models;
        self.models_c0 = c.bdf.c0;
        self.eval = c.eval;
        self.books = c.books;
        self.step_tip = (self.tip_force, self.tip_moment);
        self.step_tensions.clone_from(&self.tensions);
        self.end_now = c.end;
        self.reaction = c.reaction;
        self.stats.internal_steps += 1;
    }

    /// The 'static' start's stability verdict: Some(false) when the equilibrium the run
    /// started from is unstable (a small disturbance grows; a coarse step may still hold
    /// it), None for the 'straight' start or where the static solver did not assess it.
    pub fn start_stable(&self) -> Option<bool> {
        self.start_stable
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    /// The collocation problem of a step of length dt from the current state at the
    /// current pressures: its full residual at physical unknowns `z` (layout of
    /// `unknowns`) and the dense exact Jacobian with respect to z (for tests against
    /// finite differences).
    pub fn step_residual_and_jacobian(&self, z: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
        let bdf = Bdf::new(self.opts.alpha_eff(), self.opts.dt, self.h_prev);
        let models = self.models_at(&self.pressures, &self.tensions, &self.sigma, bdf.c0);
        let hist: Vec<[f64; FIELDS]> = self
            .slots
            .iter()
            .map(|s| {
                std::array::from_fn(|k| bdf.c1 * s.x1[k] + bdf.c2 * s.x2[k] + bdf.d1 * s.xt[k])
            })
            .collect();
        let tip = self.tip_body(self.tip_force, self.tip_moment);
        let p = step_problem(
            &self.rod,
            &self.grid,
            self.scale_c0(),
            &models,
            bdf.c0,
            &hist,
            tip,
        )
        .with_end(end_target(&self.end));
        let zs = to_scaled(&p, z);
        let n = zs.len();
        let mut r = vec![0.0; n];
        p.residual(&zs, &mut r, None);
        let jac = p.dense_jacobian(&zs);
        // Back to physical unknowns: dr/dz_phys = dr/dz_scaled / scale.
        let sc = unknown_scales(&p, n);
        let j: Vec<Vec<f64>> = jac
            .iter()
            .map(|row| row.iter().zip(&sc).map(|(a, s)| a / s).collect())
            .collect();
        (r, j)
    }

    /// The physical unknowns now (base force and moment, then per interval its two
    /// stages and its end node: quaternion, n, m, q, w).
    pub fn unknowns(&self) -> &[f64] {
        &self.z
    }

    /// Change the tendon tensions (N, one per tendon channel, each finite and >= 0) from
    /// the next step on; checked before anything changes.
    pub fn set_tensions(&mut self, tensions: &[f64]) -> Result<()> {
        self.rod.check_tensions(tensions)?;
        self.tensions = tensions.to_vec();
        Ok(())
    }

    /// Tendon tensions now (those of the next step), N.
    pub fn tensions(&self) -> &[f64] {
        &self.tensions
    }

    /// The tensions a step solves with: the new ones (BDF-alpha), or halfway between the
    /// last step's and the new ones (midpoint rule).
    fn solve_tensions(&self, midpoint: bool) -> Vec<f64> {
        if midpoint {
            self.step_tensions
                .iter()
                .zip(&self.tensions)
                .map(|(a, b)| 0.5 * (a + b))
                .collect()
        } else {
            self.tensions.clone()
        }
    }

    /// Change the tip force and moment (N and N m, in the design's tip frame: world for
    /// dead loads, body for follower loads) from the next step on.
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
    pub fn options(&self) -> &DynOptions {
        &self.opts
    }
    pub fn rod(&self) -> &Rod {
        &self.rod
    }
    pub fn grid(&self) -> &Grid {
        &self.grid
    }
    /// Chamber pressures now, Pa.
    pub fn pressures(&self) -> &[f64] {
        &self.pressures
    }
    /// The stiffness scale sigma now.
    pub fn sigma(&self) -> [f64; 3] {
        self.sigma
    }
    /// Tip force and moment now (in the design's tip frame).
    pub fn tip_loads(&self) -> ([f64; 3], [f64; 3]) {
        (self.tip_force, self.tip_moment)
    }
    /// Tip position (m), rotation and body-frame velocities (m/s, rad/s) now.
    pub fn tip(&self) -> TipState {
        let y = self.eval.nodes.last().expect("tip node");
        TipState {
            r: *self.eval.node_r.last().expect("tip node"),
            rot: collocation::rotation(&y[..4]),
            q: [y[10], y[11], y[12]],
            w: [y[13], y[14], y[15]],
        }
    }
    /// Tip velocity in the world frame, m/s.
    pub fn tip_velocity(&self) -> [f64; 3] {
        let t = self.tip();
        mat_vec(&t.rot, &t.q)
    }
    /// Base force and moment (world), N and N m.
    pub fn base_wrench(&self) -> ([f64; 3], [f64; 3]) {
        (
            [self.z[0], self.z[1], self.z[2]],
            [self.z[3], self.z[4], self.z[5]],
        )
    }
    /// Arc lengths of the nodes, m.
    pub fn node_s(&self) -> Vec<f64> {
        (0..=self.grid.len()).map(|j| self.grid.node_s(j)).collect()
    }
    /// Centreline at every node now (m, world).
    pub fn shape(&self) -> &[[f64; 3]] {
        &self.eval.node_r
    }
    /// Node states now: quaternion, n, m, q, w.
    pub fn nodes(&self) -> &[[f64; NY]] {
        &self.eval.nodes
    }
    /// Stage fields (v, u, q, w) now.
    pub fn fields(&self) -> &[[f64; FIELDS]] {
        &self.eval.fields
    }

    /// Read the body points `markers` (reference arc length s in [0, L], offset in the
    /// cross-section frame) from now on: [`Simulator::marker_positions`] gives their
    /// positions and, when sensitivities are tracked, [`Simulator::marker_sensitivity`]
    /// their derivatives. Checked as the statics' markers (errors name `markers[k]`);
    /// set them before [`Simulator::track_sensitivities`], whose start differentiates them.
    pub fn set_markers(&mut self, markers: &[Marker]) -> Result<()> {
        check_markers(&self.rod, markers)?;
        if self.sens.is_some() {
            return Err(SoftrodError::invalid(
                "markers",
                format!("{} markers", markers.len()),
                "set the markers before track_sensitivities (their derivatives start with the run's)",
            ));
        }
        self.markers = markers
            .iter()
            .map(|m| (self.grid.locate(m.s), m.offset))
            .collect();
        Ok(())
    }

    /// The positions (world, m) of the markers of [`Simulator::set_markers`] now: r(s) +
    /// R(s) o, at a node that node's own position and rotation (a marker at s = L with no
    /// offset is the tip), between nodes the collocation's continuous extension
    /// (`collocation::dense_point`), accurate to O(h^3) in the interval length h (the
    /// nodes' own error is O(h^4)).
    pub fn marker_positions(&self) -> Vec<[f64; 3]> {
        self.eval.points(&self.grid, &self.markers)
    }

    /// The number of markers read ([`Simulator::set_markers`]).
    pub fn marker_count(&self) -> usize {
        self.markers.len()
    }

    /// Energies now and the cumulative exchanges since t = 0, J.
    pub fn energy_books(&self) -> Energy {
        self.books.now
    }

    /// Total mechanical energy now, J (kinetic + elastic + potential).
    pub fn energy(&self) -> f64 {
        self.books.now.total()
    }

    /// The energy balance E - E(0) - W_in + D now (zero for the exact motion), J.
    pub fn energy_balance(&self) -> f64 {
        self.books.balance()
    }
}

/// The energy check: the balance E - E(0) - W_in + D may not exceed `energy_tol` of the
/// energy moved (max kinetic + max |change of elastic| + max |change of potential| +
/// work in + dissipated), plus the round-off `floor`, J; `step` names the output step.
fn check_energy(
    books: &Books,
    opts: &DynOptions,
    floor: f64,
    t: f64,
    h: f64,
    step: usize,
) -> Result<()> {
    let balance = books.balance();
    let scale = books.scale();
    if balance.is_finite() && balance <= opts.energy_tol * scale + floor {
        return Ok(());
    }
    let hint = match opts.scheme {
        Scheme::Midpoint => "the midpoint rule has no numerical damping, and unresolved modes can feed a large motion through the nonlinearity: use scheme 'bdf-alpha' (alpha -0.45 to 0), a smaller dt or adaptive stepping (error_tol)",
        Scheme::BdfAlpha if opts.alpha < -0.45 => "alpha = -0.5 (the trapezoidal rule) has no numerical damping, and unresolved modes can feed a large motion through the nonlinearity: use alpha -0.45 to 0, a smaller dt or adaptive stepping (error_tol)",
        Scheme::BdfAlpha => "use a smaller dt or adaptive stepping (error_tol), alpha closer to 0 (more numerical damping), or a tighter tol",
    };
    Err(SoftrodError::InvalidState {
        rule: validity::Rule::EnergyBalance,
        node: None,
        s: f64::NAN,
        time: Some(t),
        value: balance,
        message: format!(
            "the energy balance E - E(0) - W_in + D grew to {balance:.4e} J, {:.3} % of the {scale:.4e} J moved, beyond energy_tol = {} (step {}, time step {h:.3e} s): energy may not appear without input; the time integration is unstable or too coarse here: {hint}",
            100.0 * balance / scale.max(1e-300),
            opts.energy_tol,
            step
        ),
    })
}

/// What the step driver ([`drive`]) needs of a simulation: a single rod's or a system's.
trait Stepping {
    type Candidate;
    fn options(&self) -> DynOptions;
    fn clock(&self) -> f64;
    fn time_mut(&mut self) -> &mut f64;
    fn h_next(&mut self) -> &mut f64;
    fn counters(&mut self) -> &mut DynStats;
    /// Solve one time step of length h with commands `command` (not committed).
    fn attempt(&mut self, h: f64, command: &[f64]) -> Result<Self::Candidate>;
    /// Its estimated local error of the node positions, m.
    fn error(c: &Self::Candidate) -> Option<f64>;
    /// Commit an accepted step.
    fn accept(&mut self, c: Self::Candidate) -> Result<()>;
}

/// One output step of dt with the commands `command` held over it: taken as one step, as
/// substeps where Newton fails, or as error-controlled steps (adaptive); steps inside it
/// take their commands from `schedule` at their own end times and end on its knots.
fn drive<S: Stepping>(
    s: &mut S,
    command: &[f64],
    schedule: Option<&CommandSchedule>,
) -> Result<()> {
    let dt = s.options().dt;
    let t_end = (s.counters().steps + 1) as f64 * dt;
    let mut remaining = dt;
    let mut h = match s.options().error_tol {
        Some(_) => s.h_next().min(dt),
        None => dt,
    };
    let mut halvings = 0;
    while remaining > 0.0 {
        if s.options().error_tol.is_some() {
            // Adaptive: equal steps, none longer than h, to the next boundary (the
            // interval's end or a knot of the schedule inside it). A short last step
            // instead would change c0 twice, each time a new Newton matrix.
            let mut span = remaining;
            if let Some(knot) = schedule.and_then(|sch| sch.next_knot(s.clock())) {
                let k = knot - s.clock();
                if k > 1e-3 * h && k < remaining * (1.0 - 1e-9) {
                    span = k;
                }
            }
            h = span / (span / h * (1.0 - 1e-9)).ceil().max(1.0);
        } else if h >= remaining * (1.0 - 1e-9) || remaining - h < 1e-3 * h {
            h = remaining;
        }
        // Inside the interval: end on the schedule's next knot (a jump or a kink of the
        // commands) and take the commands there.
        let mut cmd = command.to_vec();
        if let Some(sch) = schedule {
            if h < remaining {
                if let Some(knot) = sch.next_knot(s.clock()) {
                    if knot < s.clock() + h && knot > s.clock() + 1e-3 * h {
                        h = knot - s.clock();
                    }
                }
                cmd = sch.at(s.clock() + h);
            }
        }
        match s.attempt(h, &cmd) {
            Ok(c) => {
                if let (Some(tol), Some(err)) = (s.options().error_tol, S::error(&c)) {
                    let factor = (0.9 * (tol / err.max(1e-300)).powf(1.0 / 3.0)).clamp(0.2, 2.0);
                    if err > tol && h > dt * 0.5f64.powi(20) {
                        s.counters().rejected += 1;
                        h *= factor.min(0.7);
                        continue;
                    }
                    *s.h_next() = if (1.0..=KEEP_STEP).contains(&factor) {
                        h
                    } else {
                        h * factor
                    };
                }
                s.accept(c)?;
                remaining -= h;
                if remaining <= 1e-12 * dt {
                    break;
                }
                if s.options().error_tol.is_some() {
                    h = s.h_next().min(dt);
                }
            }
            Err(SoftrodError::NotConverged {
                iterations,
                residual,
                reason,
                ..
            }) => {
                s.counters().rejected += 1;
                halvings += 1;
                if halvings > MAX_HALVINGS {
                    return Err(SoftrodError::NotConverged {
                            iterations,
                            residual,
                            load_factor: 1.0,
                            reason: format!(
                                "{reason}; also in steps down to {:.3e} s (dt / {}): check the inputs (a pressure or load far beyond the design's range?) or loosen tol",
                                dt / f64::from(1u32 << MAX_HALVINGS),
                                1u32 << MAX_HALVINGS
                            ),
                        });
                }
                h *= 0.5;
                *s.h_next() = h;
            }
            // A step whose rod went deeper into an obstacle than its tolerance, or jumped
            // through one, was too long for the contact (`Simulator::check_penetration`):
            // halved as a failed Newton solve is. An obstacle too thin for the intervals
            // stays refused in every substep; that error says so.
            Err(
                e @ SoftrodError::InvalidState {
                    rule: crate::error::Rule::Penetration,
                    ..
                },
            ) => {
                s.counters().rejected += 1;
                halvings += 1;
                if halvings > MAX_HALVINGS {
                    return Err(e.map_message(|m| {
                        format!(
                            "{m} (also in steps down to {:.3e} s, dt / {})",
                            dt / f64::from(1u32 << MAX_HALVINGS),
                            1u32 << MAX_HALVINGS
                        )
                    }));
                }
                h *= 0.5;
                *s.h_next() = h;
            }
            Err(e) => return Err(e),
        }
    }
    s.counters().steps += 1;
    // Steps times dt, not a running sum: no round-off drift of the clock.
    *s.time_mut() = t_end;
    Ok(())
}

impl Stepping for Simulator {
    type Candidate = Candidate;
    fn options(&self) -> DynOptions {
        self.opts
    }
    fn clock(&self) -> f64 {
        self.time
    }
    fn time_mut(&mut self) -> &mut f64 {
        &mut self.time
    }
    fn h_next(&mut self) -> &mut f64 {
        &mut self.h_next
    }
    fn counters(&mut self) -> &mut DynStats {
        &mut self.stats
    }
    fn attempt(&mut self, h: f64, command: &[f64]) -> Result<Candidate> {
        Simulator::attempt(self, h, command)
    }
    fn error(c: &Candidate) -> Option<f64> {
        c.error
    }
    fn accept(&mut self, c: Candidate) -> Result<()> {
        self.advance_sensitivity(&c)?;
        self.commit(c);
        Ok(())
    }
}

/// Layout version of [`Simulator::save`].
/// 4: the tip constraint (its pose next and now, the reaction, the kept matrix's pose).
/// 5: the stage quaternions (the continuous extension between the nodes reads them).
const STATE_VERSION: f64 = 5.0;
/// First number of a saved state ("softrod" in a number; guards against foreign arrays).
const STATE_MAGIC: f64 = 50_770_213.0;

/// Writes a state as a flat list of numbers (counts as exact integers).
struct Writer(Vec<f64>);

impl Writer {
    fn f(&mut self, x: f64) {
        self.0.push(x);
    }
    fn n(&mut self, k: usize) {
        self.0.push(k as f64);
    }
    fn all(&mut self, xs: &[f64]) {
        self.0.extend_from_slice(xs);
    }
    fn vec(&mut self, xs: &[f64]) {
        self.n(xs.len());
        self.all(xs);
    }
    fn arrays<const K: usize>(&mut self, xs: &[[f64; K]]) {
        self.n(xs.len());
        for x in xs {
            self.all(x);
        }
    }
}

/// Reads what [`Writer`] wrote, checking every count against what is left.
struct Reader<'a> {
    data: &'a [f64],
    pos: usize,
}

fn bad_state(rule: impl Into<String>) -> SoftrodError {
    SoftrodError::invalid("state", "(saved state)", rule)
}

impl Reader<'_> {
    fn f(&mut self) -> Result<f64> {
        let x = *self
            .data
            .get(self.pos)
            .ok_or_else(|| bad_state("is truncated: not a state saved by Simulator::save"))?;
        self.pos += 1;
        Ok(x)
    }
    fn n(&mut self) -> Result<usize> {
        let x = self.f()?;
        let left = (self.data.len() - self.pos) as f64;
        if !(x >= 0.0 && x.fract() == 0.0 && x <= left.max(64.0)) {
            return Err(bad_state(
                "holds an invalid count: not a state saved by Simulator::save",
            ));
        }
        Ok(x as usize)
    }
    fn take(&mut self, k: usize) -> Result<&[f64]> {
        if self.pos + k > self.data.len() {
            return Err(bad_state(
                "is truncated: not a state saved by Simulator::save",
            ));
        }
        let out = &self.data[self.pos..self.pos + k];
        self.pos += k;
        Ok(out)
    }
    fn fixed<const K: usize>(&mut self) -> Result<[f64; K]> {
        let t = self.take(K)?;
        Ok(std::array::from_fn(|i| t[i]))
    }
    fn vec(&mut self) -> Result<Vec<f64>> {
        let k = self.n()?;
        Ok(self.take(k)?.to_vec())
    }
    fn arrays<const K: usize>(&mut self) -> Result<Vec<[f64; K]>> {
        let k = self.n()?;
        let t = self.take(k * K)?;
        Ok(t.chunks_exact(K)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect())
    }
}

impl Simulator {
    /// The complete dynamic state as a flat list of numbers: time, inputs, collocation
    /// unknowns, histories, energy books, counters and what the kept Newton matrix was
    /// computed from. [`Simulator::restore`] continues from it bit for bit.
    pub fn save(&self) -> Vec<f64> {
        let mut w = Writer(Vec::new());
        w.f(STATE_MAGIC);
        w.f(STATE_VERSION);
        w.n(self.grid.len());
        w.n(self.rod.n_channels);
        w.f(self.time);
        w.f(self.h_prev);
        w.f(self.h_next);
        w.vec(&self.pressures);
        w.all(&self.sigma);
        w.all(&self.tip_force);
        w.all(&self.tip_moment);
        w.all(&self.step_tip.0);
        w.all(&self.step_tip.1);
        w.vec(&self.tensions);
        w.vec(&self.step_tensions);
        w.all(&pose_numbers(&self.end));
        w.all(&pose_numbers(&self.end_now));
        w.all(&self.reaction.0);
        w.all(&self.reaction.1);
        w.vec(&self.z);
        w.vec(&self.z_prev);
        w.vec(&self.z_prev2);
        w.n(self.slots.len());
        for sl in &self.slots {
            w.all(&sl.x1);
            w.all(&sl.x2);
            w.all(&sl.xt);
        }
        w.arrays(&self.eval.nodes);
        w.arrays(&self.eval.node_r);
        w.arrays(&self.eval.fields);
        w.arrays(&self.eval.stage_r);
        let rot: Vec<[f64; 9]> = self
            .eval
            .stage_rot
            .iter()
            .map(|r| std::array::from_fn(|k| r[k / 3][k % 3]))
            .collect();
        w.arrays(&rot);
        w.arrays(&self.eval.stage_q);
        w.n(self.past.len());
        for (t, r) in &self.past {
            w.f(*t);
            w.arrays(r);
        }
        w.all(&self.books.numbers());
        w.f(self.theta);
        let st = &self.stats;
        for c in [
            st.steps,
            st.internal_steps,
            st.rejected,
            st.newton_iterations,
            st.jacobians,
        ] {
            w.n(c);
        }
        match &self.cache {
            None => w.f(0.0),
            Some(c) => {
                w.f(1.0);
                w.vec(&c.key.at);
                w.vec(&c.key.pressures);
                w.vec(&c.key.tensions);
                w.all(&c.key.sigma);
                w.f(c.key.c0);
                w.arrays(&c.key.hist);
                w.all(&pose_numbers(&c.key.end));
            }
        }
        w.0
    }

    /// Continue from a state saved by [`Simulator::save`] of a simulation of the same rod
    /// (same intervals and channels). With the same options the run continues bit for bit
    /// as the one it was saved from; the kept Newton matrix is recomputed from what it was
    /// computed from.
    pub fn restore(&mut self, data: &[f64]) -> Result<()> {
        let mut r = Reader { data, pos: 0 };
        if r.f()? != STATE_MAGIC {
            return Err(bad_state("is not a state saved by Simulator::save"));
        }
        let version = r.f()?;
        if version != STATE_VERSION {
            return Err(bad_state(format!(
                "has layout version {version}; this softrod reads version {STATE_VERSION}"
            )));
        }
        let (n_int, nc) = (r.n()?, r.n()?);
        if n_int != self.grid.len() || nc != self.rod.n_channels {
            return Err(bad_state(format!(
                "was saved from a rod with {n_int} intervals and {nc} channels; this simulation has {} and {}",
                self.grid.len(),
                self.rod.n_channels
            )));
        }
        let mut next = self.clone();
        next.time = r.f()?;
        next.h_prev = r.f()?;
        next.h_next = r.f()?;
        next.pressures = r.vec()?;
        next.sigma = r.fixed()?;
        next.tip_force = r.fixed()?;
        next.tip_moment = r.fixed()?;
        next.step_tip = (r.fixed()?, r.fixed()?);
        next.tensions = r.vec()?;
        next.step_tensions = r.vec()?;
        let nt = self.rod.n_tendons;
        if next.tensions.len() != nt || next.step_tensions.len() != nt {
            return Err(bad_state(format!(
                "holds {} tendon tensions; this simulation's rod has {nt} tendon channels",
                next.tensions.len()
            )));
        }
        next.end = self.saved_pose(r.fixed()?)?;
        next.end_now = self.saved_pose(r.fixed()?)?;
        next.reaction = (r.fixed()?, r.fixed()?);
        next.z = r.vec()?;
        next.z_prev = r.vec()?;
        next.z_prev2 = r.vec()?;
        let n_slots = r.n()?;
        if n_slots != self.slots.len() || next.z.len() != self.z.len() {
            return Err(bad_state("does not match this simulation's discretisation"));
        }
        next.slots = (0..n_slots)
            .map(|_| -> Result<Slot> {
                Ok(Slot {
                    x1: r.fixed()?,
                    x2: r.fixed()?,
                    xt: r.fixed()?,
                })
            })
            .collect::<Result<_>>()?;
        next.eval = Evaluated {
            nodes: r.arrays()?,
            node_r: r.arrays()?,
            fields: r.arrays()?,
            stage_r: r.arrays()?,
            stage_rot: r
                .arrays::<9>()?
                .iter()
                .map(|a| std::array::from_fn(|i| std::array::from_fn(|j| a[3 * i + j])))
                .collect(),
            stage_q: r.arrays()?,
        };
        let n_past = r.n()?;
        next.past = (0..n_past)
            .map(|_| -> Result<(f64, Vec<[f64; 3]>)> { Ok((r.f()?, r.arrays()?)) })
            .collect::<Result<_>>()?;
        next.books = Books::from_numbers(&r.fixed()?);
        next.theta = r.f()?;
        next.stats = DynStats {
            steps: r.n()?,
            internal_steps: r.n()?,
            rejected: r.n()?,
            newton_iterations: r.n()?,
            jacobians: r.n()?,
        };
        next.cache = None;
        // The saved state holds no sensitivities: a restored run tracks none.
        next.sens = None;
        if r.f()? == 1.0 {
            let key = JacKey {
                at: r.vec()?,
                pressures: r.vec()?,
                tensions: r.vec()?,
                sigma: r.fixed()?,
                c0: r.f()?,
                hist: r.arrays()?,
                end: self.saved_pose(r.fixed()?)?,
            };
            if key.at.len() != self.z.len()
                || key.pressures.len() != nc
                || key.tensions.len() != self.rod.n_tendons
                || key.hist.len() != n_slots
            {
                return Err(bad_state("does not match this simulation's discretisation"));
            }
            let models = next.models_at(&key.pressures, &key.tensions, &key.sigma, key.c0);
            let tip = next.tip_body(next.tip_force, next.tip_moment);
            let p = step_problem(
                &next.rod,
                &next.grid,
                next.scale_c0(),
                &models,
                key.c0,
                &key.hist,
                tip,
            )
            .with_end(end_target(&key.end));
            if let Some(fac) = p.factorize(&key.at) {
                next.cache = Some(Cached { fac, key });
            }
        }
        if r.pos != data.len() {
            return Err(bad_state(
                "has trailing numbers: not a state saved by Simulator::save",
            ));
        }
        if next.eval.nodes.len() != n_int + 1
            || next.eval.fields.len() != 2 * n_int
            || next.eval.stage_rot.len() != 2 * n_int
            || next.eval.stage_q.len() != 2 * n_int
        {
            return Err(bad_state("does not match this simulation's discretisation"));
        }
        next.models = next.models_at(&next.pressures, &next.step_tensions, &next.sigma, 0.0);
        next.models_c0 = 0.0;
        *self = next;
        Ok(())
    }
}

impl Simulator {
    /// Move a held tip: its pose at the end of the next output step (the kind of the run's
    /// constraint, checked before anything changes); steps inside the output step
    /// (substeps, adaptive steps) take the pose interpolated from the pose now, linear in
    /// position and along the geodesic in rotation.
    pub fn set_tip_pose(&mut self, pose: TipConstraint) -> Result<()> {
        pose.validate()?;
        if pose.name() != self.end.name() {
            return Err(SoftrodError::invalid(
                "tip_constraint",
                pose.name(),
                format!(
                    "this run's tip is {}: give a {} pose (the kind of constraint is fixed for a run)",
                    self.end.name(),
                    self.end.name()
                ),
            ));
        }
        self.end = pose;
        Ok(())
    }

    /// How the tip is held now (its pose at the current time).
    pub fn tip_constraint(&self) -> TipConstraint {
        self.end_now
    }

    /// The force (N) and moment (N m) the constraint applies to the tip now, world frame:
    /// what is left of the free tip's balance n(L) = F + W, m(L) = M + ... (zero for a free
    /// tip; zero moment for a pinned one).
    pub fn tip_reaction(&self) -> ([f64; 3], [f64; 3]) {
        self.reaction
    }

    /// A pose read back from a saved state: of this run's kind.
    fn saved_pose(&self, x: [f64; 13]) -> Result<TipConstraint> {
        let position = [x[1], x[2], x[3]];
        let rotation = std::array::from_fn(|i| std::array::from_fn(|j| x[4 + 3 * i + j]));
        let pose = match x[0] {
            0.0 => TipConstraint::Free,
            1.0 => TipConstraint::Pinned { position },
            2.0 => TipConstraint::Clamped { position, rotation },
            _ => return Err(bad_state("holds an unknown tip constraint")),
        };
        if pose.name() != self.end.name() {
            return Err(bad_state(format!(
                "was saved from a run with a {} tip; this simulation's tip is {}",
                pose.name(),
                self.end.name()
            )));
        }
        Ok(pose)
    }
}

/// Refuse a tip constraint that the dynamics cannot carry, or a 'straight' start that does
/// not satisfy it (fields named).
fn check_end(rod: &Rod, opts: &DynOptions, initial: Initial, c: &TipConstraint) -> Result<()> {
    c.validate()?;
    if *c == TipConstraint::Free {
        return Ok(());
    }
    if opts.scheme == Scheme::Midpoint {
        // docs/dynamics.md "Held tip": the midpoint rule's energy identity needs the state
        // at t_{n+1} to be the linear extrapolation 2 X_{n+1/2} - X_n of the fields, and
        // the pose r(L) = r_c is nonlinear in them; the shape rebuilt from them misses the
        // pose by O(h^2) per step, and holding it there as well over-determines the step.
        return Err(SoftrodError::invalid(
            "scheme",
            opts.scheme.name(),
            format!("a {} tip is not carried by the midpoint rule: its energy conservation rests on extrapolating the fields linearly over a step, and the held pose is nonlinear in them (the rebuilt tip would miss the pose by O(dt^2) at every step); use 'bdf-alpha' (alpha = -0.5, the trapezoidal rule, has no numerical damping)", c.name()),
        ));
    }
    if initial == Initial::Reference && !rod.is_straight() {
        return Err(SoftrodError::invalid(
            "initial",
            "reference",
            format!("a {} tip on a rod with a curved reference shape starts 'static' (the 'reference' start is not carried with a held tip)", c.name()),
        ));
    }
    if initial.released() {
        // The straight rod at rest: tip at r_0 + L d3(0), frame R_0.
        let r0 = rod.base_position;
        let d3 = [
            rod.base_rotation[0][2],
            rod.base_rotation[1][2],
            rod.base_rotation[2][2],
        ];
        let tip: [f64; 3] = std::array::from_fn(|k| r0[k] + rod.length * d3[k]);
        let (TipConstraint::Pinned { position } | TipConstraint::Clamped { position, .. }) = c
        else {
            return Ok(());
        };
        // 1e-9 L: a position written out to 10 significant digits passes.
        let off = (0..3)
            .map(|k| (position[k] - tip[k]).abs())
            .fold(0.0, f64::max);
        if off > 1e-9 * rod.length {
            return Err(SoftrodError::invalid(
                "tip_constraint.position",
                format!("{position:?}"),
                format!("the 'straight' start is at rest in the straight shape, whose tip is at {tip:?} m ({off:.3e} m away): hold the tip there at t = 0 or start 'static'"),
            ));
        }
        if let TipConstraint::Clamped { rotation, .. } = c {
            let a = tmatmul(rotation, &rod.base_rotation);
            let off = (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| (a[i][j] - if i == j { 1.0 } else { 0.0 }).abs())
                .fold(0.0, f64::max);
            if off > ROTATION_TOL {
                return Err(SoftrodError::invalid(
                    "tip_constraint.orientation",
                    format!("{rotation:?}"),
                    "the 'straight' start is at rest in the straight shape, whose tip frame is the base's: clamp the tip in the base's orientation at t = 0 or start 'static'",
                ));
            }
        }
    }
    Ok(())
}

/// The collocation's target of a constrained tip (None: free).
fn end_target(c: &TipConstraint) -> Option<EndTarget> {
    match *c {
        TipConstraint::Free => None,
        TipConstraint::Pinned { position } => Some(EndTarget {
            position,
            rotation: None,
        }),
        TipConstraint::Clamped { position, rotation } => Some(EndTarget {
            position,
            rotation: Some(rotation),
        }),
    }
}

/// The pose a fraction `t` of the way from `a` to `b` (same kind): linear in position,
/// along the geodesic in rotation; `b` itself at t >= 1.
fn interpolate_pose(a: &TipConstraint, b: &TipConstraint, t: f64) -> TipConstraint {
    if t >= 1.0 || a == b {
        return *b;
    }
    let lerp = |p: &[f64; 3], q: &[f64; 3]| std::array::from_fn(|k| p[k] + t * (q[k] - p[k]));
    match (a, b) {
        (TipConstraint::Pinned { position: p }, TipConstraint::Pinned { position: q }) => {
            TipConstraint::Pinned {
                position: lerp(p, q),
            }
        }
        (
            TipConstraint::Clamped {
                position: p,
                rotation: ra,
            },
            TipConstraint::Clamped {
                position: q,
                rotation: rb,
            },
        ) => TipConstraint::Clamped {
            position: lerp(p, q),
            rotation: slerp(ra, rb, t),
        },
        _ => *b,
    }
}

/// The work of the constraint's reaction over a step from pose `a` (reaction `fa`) to `b`
/// (`fb`): the reaction the scheme applies over the step, (1 - w) F_a + w F_b with w = 1 +
/// alpha for BDF-alpha (its balance (1 + alpha) f_{n+1} - alpha f_n; the trapezoid at
/// alpha = -0.5), along the pose's path: F . (r_b - r_a) + M . theta with
/// theta = R_a log(R_a^T R_b) the step's rotation (world). Zero for a pose that does not
/// move (a fixed support does no work).
fn reaction_work(
    a: &TipConstraint,
    b: &TipConstraint,
    fa: ([f64; 3], [f64; 3]),
    fb: ([f64; 3], [f64; 3]),
    w_old: f64,
) -> f64 {
    if a == b {
        return 0.0;
    }
    let mix = |x: f64, y: f64| w_old * x + (1.0 - w_old) * y;
    let force = |p: &[f64; 3], q: &[f64; 3]| {
        (0..3)
            .map(|k| mix(fa.0[k], fb.0[k]) * (q[k] - p[k]))
            .sum::<f64>()
    };
    match (a, b) {
        (TipConstraint::Pinned { position: p }, TipConstraint::Pinned { position: q }) => {
            force(p, q)
        }
        (
            TipConstraint::Clamped {
                position: p,
                rotation: ra,
            },
            TipConstraint::Clamped {
                position: q,
                rotation: rb,
            },
        ) => {
            let theta = mat_vec(ra, &log_so3(&tmatmul(ra, rb)));
            force(p, q)
                + (0..3)
                    .map(|k| mix(fa.1[k], fb.1[k]) * theta[k])
                    .sum::<f64>()
        }
        _ => 0.0,
    }
}

/// A pose as 13 numbers for a saved state: kind (0 free, 1 pinned, 2 clamped), position,
/// rotation (row-major; zeros where absent).
fn pose_numbers(c: &TipConstraint) -> [f64; 13] {
    let mut x = [0.0; 13];
    match c {
        TipConstraint::Free => {}
        TipConstraint::Pinned { position } => {
            x[0] = 1.0;
            x[1..4].copy_from_slice(position);
        }
        TipConstraint::Clamped { position, rotation } => {
            x[0] = 2.0;
            x[1..4].copy_from_slice(position);
            for i in 0..3 {
                x[4 + 3 * i..7 + 3 * i].copy_from_slice(&rotation[i]);
            }
        }
    }
    x
}

/// Tip state of a simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipState {
    pub r: [f64; 3],
    pub rot: [[f64; 3]; 3],
    pub q: [f64; 3],
    pub w: [f64; 3],
}

/// The stored energy density at a stage with fields `f` (v, u first) at arc length `s`
/// from its section's start: the law's ([`elastic_density`]) plus the tendons' potential
/// sum tau_i (|q_i| - |q_i0|) (`crate::tendon::energy`), whose gradient is the tendons'
/// part of the total internal force and moment.
fn stored_density(m: &SectionModel, f: &[f64; FIELDS], s: f64) -> f64 {
    let e = elastic_density(m, &[f[0], f[1], f[2]], &[f[3], f[4], f[5]]);
    if m.tendons.is_empty() {
        return e;
    }
    let points: Vec<crate::tendon::TendonPoint> = m
        .tendons
        .iter()
        .map(|t| {
            let (r, dr) = t.route.at(s);
            crate::tendon::TendonPoint {
                tension: t.tension,
                r,
                dr,
            }
        })
        .collect();
    e + crate::tendon::energy(&[f[0], f[1], f[2], f[3], f[4], f[5]], &points)
}

/// The stored energy density of a section's law at strains (v, u), J/m, such that its
/// gradient is the total internal force and moment in the body frame (see `Energy`).
fn elastic_density(m: &SectionModel, v: &[f64; 3], u: &[f64; 3]) -> f64 {
    let p = m.p_force;
    // The nonlinear laws act on w = v - v* + e3 (`collocation::SectionModel::strains`).
    let w = [m.v_star[0], m.v_star[1], m.v_star[2] - 1.0];
    let w: [f64; 3] = std::array::from_fn(|k| v[k] - w[k]);
    let mut e = match &m.axial {
        collocation::Axial::Linear { .. } => (0..3)
            .map(|k| 0.5 * m.k_se[k] * (v[k] - m.v_p[k]).powi(2))
            .sum::<f64>(),
        collocation::Axial::Ogden { k_e, alpha, k_s } => {
            let lam = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
            ogden_energy(*k_e, *alpha, lam) + 0.5 * k_s * (w[0] * w[0] + w[1] * w[1])
                - p * (v[2] - 1.0)
        }
        collocation::Axial::Table { table, scale, .. } => {
            0.5 * (m.k_se[0] * w[0] * w[0] + m.k_se[1] * w[1] * w[1])
                + table_energy(table, *scale, w[2])
                - p * (v[2] - 1.0)
        }
    };
    if m.stretch_bending {
        // (1/2) (u - u*) K (u - u*) - M_p . u with the bending block times the stretch
        // relative to the reference, rho = v3 - v3* + 1 (M_p = K (u_p - u*), the pressure
        // moment): its u-gradient is the law's moment.
        let rho = v[2] + 1.0 - m.v_star[2];
        for a in 0..3 {
            let ka: f64 = (0..3).map(|b| m.k_bt[a][b] * m.u_star[b]).sum();
            for b in 0..3 {
                let s = if a < 2 && b < 2 { rho } else { 1.0 };
                e += 0.5 * (u[a] - m.u_star[a]) * s * m.k_bt[a][b] * (u[b] - m.u_star[b]);
            }
            e -= (m.g_bt[a] - ka) * u[a];
        }
        return e;
    }
    // Bending and torsion: (1/2) u K u - K u_p . u (the square completed for the linear law).
    for a in 0..3 {
        for b in 0..3 {
            e += 0.5 * u[a] * m.k_bt[a][b] * u[b];
        }
        e -= m.g_bt[a] * u[a];
    }
    if matches!(m.axial, collocation::Axial::Linear { .. }) {
        // Complete the square so that the linear law's energy is (1/2)(u - u_p) K (u - u_p).
        e += 0.5 * (0..3).map(|a| m.g_bt[a] * m.u_p[a]).sum::<f64>();
    }
    e
}

/// Energy of the EA(F) table law at stretch v3: W = F (v3 - 1) - int_0^F f / (s EA(f)) df
/// with F the elastic force at v3 (Newton on v3 = 1 + F / (s EA(F))), the integral by
/// 8-point Gauss-Legendre on each stretch of [0, F] between table knots (smooth there).
fn table_energy(table: &crate::law::AxialTable, s: f64, v3: f64) -> f64 {
    use crate::jet::Jet;
    let target = v3 - 1.0;
    let mut f = target * s * table.eval(0.0);
    for _ in 0..60 {
        let j = table.eval(Jet::<1>::variable(f, 0));
        let g = f / (s * j.re) - target;
        let dg = (j.re - f * j.eps[0]) / (s * j.re * j.re);
        let step = g / dg;
        f -= step;
        if step.abs() <= 1e-15 * (1.0 + f.abs()) {
            break;
        }
    }
    const X: [f64; 8] = [
        -0.960_289_856_497_536_3,
        -0.796_666_477_413_626_7,
        -0.525_532_409_916_329,
        -0.183_434_642_495_649_8,
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 8] = [
        0.101_228_536_290_376_3,
        0.222_381_034_453_374_5,
        0.313_706_645_877_887_3,
        0.362_683_783_378_362,
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let mut cuts = vec![0.0, f];
    for &k in table.knots() {
        if (k > 0.0 && k < f) || (k < 0.0 && k > f) {
            cuts.push(k);
        }
    }
    cuts.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
    let mut integral = 0.0;
    for w in cuts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
        for (x, wt) in X.iter().zip(&W) {
            let ff = mid + half * x;
            integral += half * wt * ff / (s * table.eval(ff));
        }
    }
    if f < 0.0 {
        // The cuts were sorted ascending: the integral from 0 to f < 0 is minus that.
        integral = -integral;
    }
    f * target - integral
}

/// An initial guess of the static collocation problem from a shooting solution: its node
/// states (the grids share their nodes), with quaternion signs kept continuous.
/// Newton on a discretisation's static problem (c0 = 0) from `z`, a shape of the static
/// solver: the exact rest state of a run (tolerance the run's, at most 1e-10). Returns it
/// and the iterations; `what` names the case in the error.
fn refine_static(
    problem: &Problem,
    mut z: Vec<f64>,
    tol: f64,
    what: &str,
) -> Result<(Vec<f64>, usize)> {
    let nopts = NewtonOptions {
        tol: tol.min(1e-10),
        max_iter: 100,
    };
    let mut ns = NewtonStats::default();
    collocation::newton(problem, &mut z, &mut None, &nopts, &mut ns).map_err(
        |(iterations, residual)| SoftrodError::NotConverged {
            iterations,
            residual,
            load_factor: 1.0,
            reason: format!("the initial static state {what} did not solve"),
        },
    )?;
    Ok((z, ns.iterations))
}

fn static_guess(p: &Problem, shape: &statics::Shape) -> Vec<f64> {
    let mut nodes: Vec<[f64; NY]> = Vec::with_capacity(shape.s.len());
    let mut last = p.base_q;
    for k in 0..shape.s.len() {
        let mut q = collocation::quaternion(&shape.rotation[k]);
        if (0..4).map(|a| q[a] * last[a]).sum::<f64>() < 0.0 {
            q = q.map(|x| -x);
        }
        last = q;
        let mut y = [0.0; NY];
        y[..4].copy_from_slice(&q);
        y[4..7].copy_from_slice(&shape.force[k]);
        y[7..10].copy_from_slice(&shape.moment[k]);
        nodes.push(y);
    }
    if nodes.len() != p.grid.len() + 1 {
        return p.straight_unknowns();
    }
    p.unknowns_from_nodes(&nodes)
}

/// The collocation problem of a time step with the run's fixed velocity scale, that of c0
/// `scale_c0` ([`Simulator::scale_c0`]).
fn step_problem<'p>(
    rod: &'p Rod,
    grid: &'p Grid,
    scale_c0: f64,
    models: &'p [SectionModel],
    c0: f64,
    hist: &'p [[f64; FIELDS]],
    tip: TipBody,
) -> Problem<'p> {
    let mut p = Problem::new(rod, grid, models, c0, hist, tip).with_contact();
    p.scale = collocation::point_scale(rod, scale_c0);
    p
}

/// Scale of every unknown of a problem (base unknowns, then point blocks).
fn unknown_scales(p: &Problem, n: usize) -> Vec<f64> {
    let mut s = vec![0.0; n];
    for k in 0..3 {
        s[k] = p.fs;
        s[3 + k] = p.ms;
    }
    // With contact the node positions follow (`collocation::Contact`), in units of L.
    let points = p.grid.unknowns().min(n);
    for (o, v) in s[..points].iter_mut().enumerate().skip(6) {
        *v = p.scale[(o - 6) % 16];
    }
    s[points..].fill(p.rod.length);
    s
}

fn to_scaled(p: &Problem, z: &[f64]) -> Vec<f64> {
    let s = unknown_scales(p, z.len());
    z.iter().zip(&s).map(|(a, b)| a / b).collect()
}

fn to_physical(p: &Problem, z: &[f64]) -> Vec<f64> {
    let s = unknown_scales(p, z.len());
    z.iter().zip(&s).map(|(a, b)| a * b).collect()
}

#[inline(always)]
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn mat_t_vec(r: &[[f64; 3]; 3], x: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| r[0][i] * x[0] + r[1][i] * x[1] + r[2][i] * x[2])
}

#[inline(always)]
fn mat_vec(r: &[[f64; 3]; 3], x: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The variable-step coefficients reduce to Till et al.'s constant-step ones, and are
    /// exact for quadratics at any step ratio.
    #[test]
    fn bdf_alpha_coefficients() {
        for alpha in [-0.4, -0.2, 0.0] {
            let dt = 0.01;
            let b = Bdf::new(alpha, dt, dt);
            assert!((b.c0 - (1.5 + alpha) / (dt * (1.0 + alpha))).abs() < 1e-10);
            assert!((b.c1 + 2.0 / dt).abs() < 1e-10);
            assert!((b.c2 - (0.5 + alpha) / (dt * (1.0 + alpha))).abs() < 1e-10);
            assert!((b.d1 - alpha / (1.0 + alpha)).abs() < 1e-14);
            for ratio in [0.5, 1.0, 1.7] {
                let (h, hp) = (dt, dt / ratio);
                let b = Bdf::new(alpha, h, hp);
                // y = t^2 + 3t, t_{n+1} = 0: y'(0) = 3 from y(0), y(-h), y(-h-hp), y'(-h).
                let y = |t: f64| t * t + 3.0 * t;
                let yt = |t: f64| 2.0 * t + 3.0;
                let got = b.c0 * y(0.0) + b.c1 * y(-h) + b.c2 * y(-h - hp) + b.d1 * yt(-h);
                assert!(
                    (got - 3.0).abs() < 1e-9,
                    "alpha {alpha}, ratio {ratio}: {got}"
                );
            }
        }
        let t = Bdf::new(-0.5, 0.01, 0.02);
        assert_eq!((t.c0, t.c1, t.c2, t.d1), (200.0, -200.0, 0.0, -1.0));
        // Error constants: trapezoidal 1/12, BDF2 2/9 (times h^3).
        let h = 0.01;
        assert!((Bdf::new(-0.5, h, h).error_constant(h, h) / h.powi(3) - 1.0 / 12.0).abs() < 1e-9);
        assert!((Bdf::new(0.0, h, h).error_constant(h, h) / h.powi(3) - 2.0 / 9.0).abs() < 1e-9);
    }
}
