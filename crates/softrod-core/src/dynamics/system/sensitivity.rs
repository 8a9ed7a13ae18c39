//! Forward parameter sensitivities of a system of rods in motion (rods whose tips hold one
//! rigid platform, `dynamics::system`): d(platform pose)/dtheta and d(marker)/dtheta after
//! every step, for calibrating a parallel continuum robot from time series.
//!
//! Every step solves the coupled equations G(x_{n+1}; H_n, theta) = 0 for x = (every rod's
//! step unknowns z_i, the platform's 6 xi), with H_n the history terms of every rod's stage
//! slots (BDF-alpha) and of the platform (its position, velocity and angular velocity, and
//! the Cayley chart's phi with the chart's base R_n). By the implicit function theorem
//!
//!   dx_{n+1}/dtheta = -G_x^-1 (d_theta G + G_H dH_n/dtheta),
//!
//! with G_x the system's exact step Jacobian (the bordered matrix of `Coupled::factor`,
//! solved by the Schur complement on the platform's 6 unknowns with each rod's banded
//! factorization: `Bordered::correction`) at the converged x_{n+1}, and the bracket one
//! evaluation in `Jet<N>` (N = the parameters of the chunk, at most CHUNK) of
//! - every rod's step residual with dual section models (the rod's parameters seeded,
//!   `Simulator::dual_models_in`, the damping time included) and dual histories, its held
//!   tip's rows with the held pose p + R o_i, R A_i dual: R = cay(phi) R_n, whose base R_n
//!   (the platform's rotation at t_n) carries its derivative from the last step;
//! - the platform's rigid-body rows (`rows_of`) with the dual mass (`SystemParam::
//!   PlatformMass`), dual step terms (`terms_of` of the platform's motion at t_n and
//!   t_{n-1} with their derivatives) and the rods' dual tip reactions (the tip slot's
//!   history carries derivatives, `Problem::tip_reaction_with`).
//!
//! Factoring G_x at every step would cost more than the step itself (Newton keeps its
//! matrix over many steps), so the linear equation is solved as the lone rod's is, by
//! iterative refinement with a kept matrix M (the exact one of an earlier step, else the
//! one Newton kept for this step): dx += -M^-1 (d_theta G + G_x dx), whose bracket is
//! again one exact dual evaluation (at x_{n+1} + eps dx), from the last step's dx. It
//! converges to the exact dx/dtheta as fast as Newton did with M; a parameter is done when
//! its correction, or the error left after it at the measured contraction rate, is below
//! 1e-9 of its derivative's size. Where M does not contract by 1/4 per correction (or none
//! is kept, as at the start) the exact G_x is factored at the converged state and solved
//! once, and it serves the next steps' refinements (Newton keeps its own, so tracking does
//! not change the run). The dual evaluation at the final x_{n+1} + eps dx/dtheta then gives
//! every rod's stage fields (its slots' new derivatives, as the lone rod's,
//! `dynamics::sensitivity`), node and marker positions, and the platform's pose and motion
//! (`kin_of`), whose derivatives are the next step's history. The start (at rest in
//! equilibrium: c0 = 0, no history, the chart based at the rest rotation) is
//! differentiated with the exact matrix, on the collocation grids the run starts from (the static system's derivatives,
//! `sensitivity::system`, to the difference of the two discretisations). No finite
//! differences; the errors are that of the converged Newton solutions (tol) propagated
//! linearly and the refinement's 1e-9.
//!
//! Supported: what the lone rod supports (`dynamics::sensitivity`: BDF-alpha with fixed
//! steps, section parameters, the damping time) on any rod, one value shared by several
//! rods (`SystemParam::Rods`), and the platform's mass. Refused: adaptive steps (the step
//! sizes would depend on theta), tracking after the first step; the platform's inertia,
//! centre of mass and attachments are not parameters.

use super::{
    held_rows, kin_of, rotate, rows_of, terms_of, Bordered, Coupled, PlatformEq, StepTerms,
    SystemCandidate, SystemSimulator,
};
use crate::collocation::{Problem, SectionModel, NF};
use crate::dynamics::{end_target, step_problem, to_scaled, Bdf, Slot, FIELDS};
use crate::error::{Result, SoftrodError};
use crate::jet::Jet;
use crate::marker::check_markers;
use crate::sensitivity::system::{check_system_params, SystemMarker, SystemParam};
use crate::sensitivity::{section_value, Param, ParamKind, CHUNK};

/// The sensitivities carried through a system's time loop.
#[derive(Debug, Clone)]
pub(in crate::dynamics) struct SysTracker {
    params: Vec<SystemParam>,
    /// Per rod: the parameters acting on it (number j, the rod's own parameter).
    on_rod: Vec<Vec<(usize, Param)>>,
    /// d slot / d theta_j per rod: `slots[i][j][k]` (history slot k of rod i).
    slots: Vec<Vec<Vec<Slot>>>,
    /// d(platform motion)/d theta_j now and one step before (`Motion::numbers` layout:
    /// p, R row by row, V, W, A, W_t).
    now: Vec<[f64; 24]>,
    prev: Vec<[f64; 24]>,
    /// d r(node) / d theta_j of rod i now: `shape[i][j][node]`.
    shape: Vec<Vec<Vec<[f64; 3]>>>,
    /// d marker / d theta_j of rod i's markers now: `rod_markers[i][j][k]`.
    rod_markers: Vec<Vec<Vec<[f64; 3]>>>,
    /// dx/dtheta_j of the last step (scaled unknowns: every rod's, the platform's 6): the
    /// refinement's start.
    last: Vec<Option<Derivative>>,
    /// The largest |dx/dtheta_j| (scaled) so far: the refinement's tolerance is relative
    /// to it.
    scale: Vec<f64>,
    /// The exact matrix factored at an earlier step and its c0: the next steps refine with
    /// it (Newton keeps its own, so that tracking does not change the run).
    own: Option<(Bordered, f64)>,
}

/// dx/dtheta of one parameter (scaled unknowns): every rod's, then the platform's 6.
type Derivative = (Vec<Vec<f64>>, [f64; 6]);

const ZERO_SLOT: Slot = Slot {
    x1: [0.0; FIELDS],
    x2: [0.0; FIELDS],
    xt: [0.0; FIELDS],
};

fn not_solvable(what: &str) -> SoftrodError {
    SoftrodError::NotConverged {
        iterations: 0,
        residual: f64::NAN,
        load_factor: 1.0,
        reason: format!(
            "the system's Newton matrix is singular at the converged {what}, so its parameter derivatives are undefined"
        ),
    }
}

/// One solve of the sensitivities: the coupled equations at their converged state (the
/// problems' tips placed at `xi`), the exact matrix there, and what the dual evaluation
/// needs besides the tracker.
struct At<'a, 'p> {
    coupled: &'a Coupled<'p>,
    /// The matrix the linear equation is solved with: the exact one at the converged
    /// state (`refine` false: one solve), or one kept from earlier (`refine` true: the
    /// iterative refinement, module docs).
    matrix: &'a Bordered,
    refine: bool,
    zs: &'a [Vec<f64>],
    xi: &'a [f64; 6],
    /// The step's time formula; None at rest (c0 = 0, no history).
    bdf: Option<Bdf>,
    /// Per rod: pressures, tensions and sigma of its models.
    inputs: &'a [(&'a [f64], &'a [f64], [f64; 3])],
}

/// What one solve needs besides the matrix (`SystemSimulator::run_chunks`).
struct Solve<'a, 'p> {
    coupled: &'a mut Coupled<'p>,
    zs: &'a [Vec<f64>],
    xi: &'a [f64; 6],
    bdf: Option<Bdf>,
    inputs: Vec<(&'a [f64], &'a [f64], [f64; 3])>,
    /// A matrix kept from earlier steps (None: factor the exact one).
    kept: Option<&'a Bordered>,
    /// What the solve is of, for the error of a singular matrix.
    what: String,
}

/// Refinement steps with a kept matrix before the exact one is factored.
const MAX_REFINE: usize = 12;
/// The refinement falls back to the exact matrix when a correction is not below this
/// fraction of the last one (Newton's rule for keeping its matrix, as the lone rod's
/// sensitivities, `dynamics::sensitivity`).
const RATE_MAX: f64 = 0.25;
/// The refinement stops when a correction, or the error it leaves at the measured
/// contraction rate (rate / (1 - rate) of it), is below this fraction of the derivative's
/// size (scaled unknowns; the largest the derivative has been in the run): as fine as the
/// state itself is solved, the lone rod's REFINE_TOL.
const REFINE_TOL: f64 = 1e-9;

impl SystemSimulator {
    /// Track d(state)/d(theta) from now on for `params` (checked against the rods and the
    /// platform; errors name `params[j]`). Call it before the first step of a run with
    /// fixed steps (no `error_tol`); afterwards [`SystemSimulator::platform_position_sensitivity`]
    /// and [`SystemSimulator::marker_sensitivity`] give the derivatives after every step.
    /// The start (at rest in equilibrium) is differentiated here. A restored state tracks
    /// none.
    pub fn track_sensitivities(&mut self, params: &[SystemParam]) -> Result<()> {
        if self.stats.internal_steps > 0 {
            return Err(SoftrodError::invalid(
                "track_sensitivities",
                format!("t = {} s", self.time),
                "start tracking before the first step (the start's derivatives come first)",
            ));
        }
        if let Some(e) = self.opts.error_tol {
            return Err(SoftrodError::invalid(
                "error_tol",
                format!("{e}"),
                "parameter sensitivities need fixed steps (adaptive step sizes depend on the parameters): give no error_tol",
            ));
        }
        let on_rod = self.check_params(params)?;
        let n = self.rods.len();
        let np = params.len();
        let mut tr = SysTracker {
            params: params.to_vec(),
            on_rod,
            slots: self
                .rods
                .iter()
                .map(|r| vec![vec![ZERO_SLOT; r.slots.len()]; np])
                .collect(),
            now: vec![[0.0; 24]; np],
            prev: vec![[0.0; 24]; np],
            shape: vec![vec![vec![]; np]; n],
            rod_markers: vec![vec![vec![]; np]; n],
            last: vec![None; np],
            scale: vec![0.0; np],
            own: None,
        };
        // The rest state's equations (as `SystemSimulator::new` solved them), the chart
        // based at the rest rotation (phi = 0 there).
        let models: Vec<Vec<SectionModel>> = self
            .rods
            .iter()
            .map(|s| s.models_at(&s.pressures, &s.tensions, &s.sigma, 0.0))
            .collect();
        let hist: Vec<Vec<[f64; FIELDS]>> = self
            .rods
            .iter()
            .map(|s| vec![[0.0; FIELDS]; s.slots.len()])
            .collect();
        let problems: Vec<Problem> = self
            .rods
            .iter()
            .zip(&models)
            .zip(&hist)
            .map(|((s, m), h)| {
                Problem::new(
                    &s.rod,
                    &s.grid,
                    m,
                    0.0,
                    h,
                    s.tip_body(s.tip_force, s.tip_moment),
                )
                .with_contact()
                .with_end(end_target(&s.end))
            })
            .collect();
        let zs: Vec<Vec<f64>> = problems
            .iter()
            .zip(&self.rods)
            .map(|(p, s)| to_scaled(p, &s.z))
            .collect();
        let xi: [f64; 6] = std::array::from_fn(|k| {
            if k < 3 {
                self.now.p[k] / self.body.ls
            } else {
                0.0
            }
        });
        let mut coupled = Coupled {
            problems,
            eq: PlatformEq::rest(&self.body, self.now.rot),
        };
        let solve = Solve {
            coupled: &mut coupled,
            zs: &zs,
            xi: &xi,
            bdf: None,
            inputs: self
                .rods
                .iter()
                .map(|s| (s.pressures.as_slice(), s.tensions.as_slice(), s.sigma))
                .collect(),
            kept: None,
            what: "initial equilibrium".into(),
        };
        self.run_chunks(&mut tr, solve)?;
        self.sens = Some(Box::new(tr));
        Ok(())
    }

    /// Check the parameters against the system: every rod entry names a known rod once,
    /// one kind and one value per parameter, each checked as the lone rod's dynamic
    /// parameter is (`Simulator::check_tracked`). Returns, per rod, the parameters acting
    /// on it.
    fn check_params(&self, params: &[SystemParam]) -> Result<Vec<Vec<(usize, Param)>>> {
        check_system_params(
            self.rods.len(),
            params,
            |i, p| self.rods[i].check_tracked(std::slice::from_ref(p)),
            |i, p| {
                let sim = &self.rods[i];
                match (p.kind, p.sections.first()) {
                    (ParamKind::DampingTime, _) => sim.rod.spec.dynamics.damping_time,
                    (kind, Some(&s)) => section_value(&sim.rod, s, kind),
                    (_, None) => f64::NAN,
                }
            },
        )?;
        let mut on_rod = vec![vec![]; self.rods.len()];
        for (j, p) in params.iter().enumerate() {
            if let SystemParam::Rods(entries) = p {
                for (i, param) in entries {
                    on_rod[*i].push((j, param.clone()));
                }
            }
        }
        Ok(on_rod)
    }

    /// d p / d theta_j of the platform's position now (world, m per unit of parameter j),
    /// one per tracked parameter; None when no sensitivities are tracked.
    pub fn platform_position_sensitivity(&self) -> Option<Vec<[f64; 3]>> {
        let tr = self.sens.as_ref()?;
        Some(tr.now.iter().map(|d| [d[0], d[1], d[2]]).collect())
    }

    /// d R / d theta_j of the platform's rotation now (per unit of parameter j), one per
    /// tracked parameter; None when no sensitivities are tracked.
    pub fn platform_rotation_sensitivity(&self) -> Option<Vec<[[f64; 3]; 3]>> {
        let tr = self.sens.as_ref()?;
        Some(
            tr.now
                .iter()
                .map(|d| std::array::from_fn(|i| std::array::from_fn(|c| d[3 + 3 * i + c])))
                .collect(),
        )
    }

    /// d r / d theta_j at every node of rod `rod`'s shape now (`[j][node]`, world, m per
    /// unit of parameter j); None when no sensitivities are tracked or no such rod.
    pub fn rod_shape_sensitivity(&self, rod: usize) -> Option<&[Vec<[f64; 3]>]> {
        self.sens
            .as_ref()
            .and_then(|t| t.shape.get(rod))
            .map(|s| s.as_slice())
    }

    /// The parameters tracked.
    pub fn sensitivity_params(&self) -> Option<&[SystemParam]> {
        self.sens.as_ref().map(|t| t.params.as_slice())
    }

    /// Read `markers` from now on: points fixed to the platform (offset in its frame, m)
    /// or on a rod (`Marker` of that rod: arc length and offset in the cross-section
    /// frame). Set them before [`SystemSimulator::track_sensitivities`]. Errors name
    /// `markers[k]`.
    pub fn set_markers(&mut self, markers: &[SystemMarker]) -> Result<()> {
        if self.sens.is_some() {
            return Err(SoftrodError::invalid(
                "markers",
                format!("{} markers", markers.len()),
                "set the markers before track_sensitivities (their derivatives start with the run's)",
            ));
        }
        let mut per_rod = vec![vec![]; self.rods.len()];
        for (k, m) in markers.iter().enumerate() {
            match *m {
                SystemMarker::Platform(o) => {
                    if let Some(c) = o.iter().position(|v| !v.is_finite()) {
                        return Err(SoftrodError::invalid(
                            format!("markers[{k}].offset[{c}]"),
                            o[c],
                            "must be a finite number (m, platform frame)",
                        ));
                    }
                }
                SystemMarker::Rod { rod, marker } => {
                    let Some(sim) = self.rods.get(rod) else {
                        return Err(SoftrodError::invalid(
                            format!("markers[{k}].rod"),
                            rod,
                            format!("the system has {} rods", self.rods.len()),
                        ));
                    };
                    check_markers(&sim.rod, &[marker]).map_err(|err| match err {
                        SoftrodError::InvalidParameter { field, value, rule } => {
                            SoftrodError::InvalidParameter {
                                field: field.replacen("markers[0]", &format!("markers[{k}]"), 1),
                                value,
                                rule: format!("{rule} (on rods[{rod}])"),
                            }
                        }
                        other => other,
                    })?;
                    per_rod[rod].push(marker);
                }
            }
        }
        for (sim, ms) in self.rods.iter_mut().zip(&per_rod) {
            sim.set_markers(ms)?;
        }
        self.markers = markers.to_vec();
        Ok(())
    }

    /// The positions (world, m) of the markers of [`SystemSimulator::set_markers`] now.
    pub fn marker_positions(&self) -> Vec<[f64; 3]> {
        let on_rods: Vec<Vec<[f64; 3]>> = self.rods.iter().map(|r| r.marker_positions()).collect();
        self.read_markers(
            |o| {
                let arm = rotate(&self.now.rot, o);
                std::array::from_fn(|c| self.now.p[c] + arm[c])
            },
            |rod, k| on_rods[rod][k],
        )
    }

    /// d marker_k / d theta_j (`[j][k]`, world, m per unit of parameter j) of the markers
    /// of [`SystemSimulator::set_markers`] now; None when no sensitivities are tracked.
    pub fn marker_sensitivity(&self) -> Option<Vec<Vec<[f64; 3]>>> {
        let tr = self.sens.as_ref()?;
        Some(
            (0..tr.params.len())
                .map(|j| {
                    let d = &tr.now[j];
                    let dp = [d[0], d[1], d[2]];
                    let dr: [[f64; 3]; 3] =
                        std::array::from_fn(|i| std::array::from_fn(|c| d[3 + 3 * i + c]));
                    self.read_markers(
                        |o| {
                            let arm = rotate(&dr, o);
                            std::array::from_fn(|c| dp[c] + arm[c])
                        },
                        |rod, k| tr.rod_markers[rod][j][k],
                    )
                })
                .collect(),
        )
    }

    /// The markers in order: platform ones from `platform(offset)`, rod ones from
    /// `rod(rod, its index among that rod's markers)`.
    fn read_markers(
        &self,
        platform: impl Fn(&[f64; 3]) -> [f64; 3],
        rod: impl Fn(usize, usize) -> [f64; 3],
    ) -> Vec<[f64; 3]> {
        let mut count = vec![0; self.rods.len()];
        self.markers
            .iter()
            .map(|m| match m {
                SystemMarker::Platform(o) => platform(o),
                SystemMarker::Rod { rod: i, .. } => {
                    count[*i] += 1;
                    rod(*i, count[*i] - 1)
                }
            })
            .collect()
    }

    /// Carry the sensitivities over the accepted step `c` (before it is committed: the
    /// slots' and the platform's sensitivities are still those of the step's start).
    pub(super) fn advance_sensitivity(&mut self, c: &SystemCandidate) -> Result<()> {
        let Some(mut tr) = self.sens.take() else {
            return Ok(());
        };
        let out = self.advance_tracker(&mut tr, c);
        self.sens = Some(tr);
        self.stats.jacobians += out?;
        Ok(())
    }

    /// [`SystemSimulator::advance_sensitivity`]; returns the matrices factored (0 or 1).
    fn advance_tracker(&self, tr: &mut SysTracker, c: &SystemCandidate) -> Result<usize> {
        let problems: Vec<Problem> = self
            .rods
            .iter()
            .zip(&c.rods)
            .map(|(r, rc)| {
                step_problem(
                    &r.rod,
                    &r.grid,
                    r.scale_c0(),
                    &rc.models,
                    rc.bdf.c0,
                    &rc.hist,
                    r.tip_body(r.tip_force, r.tip_moment),
                )
                .with_end(end_target(&rc.end))
            })
            .collect();
        let mut coupled = Coupled {
            problems,
            eq: PlatformEq {
                body: &self.body,
                t: c.terms,
            },
        };
        let zs: Vec<Vec<f64>> = c.rods.iter().map(|rc| rc.z_scaled.clone()).collect();
        let c0 = c.terms.c0;
        // The matrix to refine with: the exact one of an earlier step with this c0, else
        // the one Newton kept for this step.
        let own = tr.own.take().filter(|(_, k)| *k == c0);
        let kept = match &own {
            Some((m, _)) => Some(m),
            None => self
                .kept
                .as_ref()
                .filter(|k| k.key.platform.c0 == c0)
                .map(|k| &k.matrix),
        };
        let solve = Solve {
            coupled: &mut coupled,
            zs: &zs,
            xi: &c.xi,
            bdf: Some(c.rods[0].bdf),
            inputs: self
                .rods
                .iter()
                .zip(&c.rods)
                .map(|(r, rc)| (rc.pressures.as_slice(), r.tensions.as_slice(), rc.sigma))
                .collect(),
            kept,
            what: format!("step to t = {:.6} s", self.time + c.h),
        };
        let exact = self.run_chunks(tr, solve)?;
        let factored = usize::from(exact.is_some());
        tr.own = match exact {
            Some(m) => Some((m, c0)),
            None => own,
        };
        Ok(factored)
    }

    /// Every chunk of parameters through one solve: refined with the kept matrix where one
    /// is given and contracts, else with the exact matrix, factored at the converged state
    /// once (and returned).
    fn run_chunks(&self, tr: &mut SysTracker, solve: Solve) -> Result<Option<Bordered>> {
        let Solve {
            coupled,
            zs,
            xi,
            bdf,
            inputs,
            kept,
            what,
        } = solve;
        let np = tr.params.len();
        let mut exact: Option<Bordered> = None;
        for j0 in (0..np).step_by(CHUNK) {
            let n_par = (np - j0).min(CHUNK);
            // The dual number as wide as the chunk (as the lone rod's).
            let dispatch = |tr: &mut SysTracker, at: &At| match n_par {
                1 => self.chunk::<1>(tr, j0, at),
                2 => self.chunk::<2>(tr, j0, at),
                3 => self.chunk::<3>(tr, j0, at),
                _ => self.chunk::<CHUNK>(tr, j0, at),
            };
            let mut solved = false;
            if let (None, Some(m)) = (&exact, kept) {
                let at = At {
                    coupled: &*coupled,
                    matrix: m,
                    refine: true,
                    zs,
                    xi,
                    bdf,
                    inputs: &inputs,
                };
                solved = dispatch(tr, &at)?;
            }
            if !solved {
                if exact.is_none() {
                    exact = Some(coupled.factor(zs, xi).ok_or_else(|| not_solvable(&what))?);
                }
                let at = At {
                    coupled: &*coupled,
                    matrix: exact.as_ref().expect("factored above"),
                    refine: false,
                    zs,
                    xi,
                    bdf,
                    inputs: &inputs,
                };
                dispatch(tr, &at)?;
            }
        }
        Ok(exact)
    }

    /// The derivatives of the parameters j0..j0 + N over the solve `at` (module docs).
    /// Ok(false), the tracker untouched, where the refinement with a kept matrix does not
    /// contract (the exact matrix is needed).
    fn chunk<const N: usize>(&self, tr: &mut SysTracker, j0: usize, at: &At) -> Result<bool> {
        let n_par = N.min(tr.params.len() - j0);
        let coupled = at.coupled;
        let body = coupled.eq.body;
        // Per rod: dual models (its parameters of the chunk seeded) and dual histories.
        let mut models_d: Vec<Vec<SectionModel<Jet<N>>>> = Vec::with_capacity(self.rods.len());
        let mut hist_d: Vec<Vec<[Jet<N>; NF]>> = Vec::with_capacity(self.rods.len());
        for (i, (r, p)) in self.rods.iter().zip(&coupled.problems).enumerate() {
            let dirs: Vec<(usize, &Param)> = tr.on_rod[i]
                .iter()
                .filter(|(j, _)| (j0..j0 + n_par).contains(j))
                .map(|(j, param)| (j - j0, param))
                .collect();
            let (pressures, tensions, sigma) = at.inputs[i];
            models_d.push(r.dual_models_in::<N>(&dirs, pressures, tensions, &sigma, p.c0));
            hist_d.push(
                p.hist
                    .iter()
                    .enumerate()
                    .map(|(k, h)| {
                        std::array::from_fn(|a| {
                            let mut x = Jet::<N>::from(h[a]);
                            if let Some(Bdf { c1, c2, d1, .. }) = at.bdf {
                                // dH/dtheta = c1 dX_n + c2 dX_{n-1} + d1 dX_t,n.
                                for q in 0..n_par {
                                    let s = &tr.slots[i][j0 + q][k];
                                    x.eps[q] = c1 * s.x1[a] + c2 * s.x2[a] + d1 * s.xt[a];
                                }
                            }
                            x
                        })
                    })
                    .collect(),
            );
        }
        // The platform's dual step terms and mass.
        let terms_d: StepTerms<Jet<N>> = match at.bdf {
            None => coupled.eq.t.lift(),
            Some(bdf) => {
                let dual = |x: &[f64; 24], d: &[[f64; 24]]| -> [Jet<N>; 24] {
                    std::array::from_fn(|k| {
                        let mut v = Jet::<N>::from(x[k]);
                        for q in 0..n_par {
                            v.eps[q] = d[j0 + q][k];
                        }
                        v
                    })
                };
                let now = dual(&self.now.numbers(), &tr.now);
                let prev = dual(&self.prev.numbers(), &tr.prev);
                let mut t = terms_of(&bdf, &now, &prev);
                // The values where the derivatives are taken: the step's own terms.
                let f = coupled.eq.t;
                for k in 0..3 {
                    t.hp[k].re = f.hp[k];
                    t.hphi[k].re = f.hphi[k];
                    t.hv[k].re = f.hv[k];
                    t.hw[k].re = f.hw[k];
                    for c in 0..3 {
                        t.r_n[k][c].re = f.r_n[k][c];
                    }
                }
                t
            }
        };
        let mut mass = Jet::<N>::from(body.mass);
        for q in 0..n_par {
            if tr.params[j0 + q] == SystemParam::PlatformMass {
                mass.eps[q] = 1.0;
            }
        }
        // dx/dtheta = -G_x^-1 (d_theta G + G_H dH/dtheta): with the exact G_x one solve
        // from dx = 0; with a kept matrix M, dx += -M^-1 (d_theta G + G_x dx) from the last
        // step's dx, the bracket one exact dual evaluation at x + eps dx.
        let mut zd: Vec<Vec<Jet<N>>> = at
            .zs
            .iter()
            .map(|z| z.iter().map(|&x| Jet::<N>::from(x)).collect())
            .collect();
        let mut xid: [Jet<N>; 6] = at.xi.map(Jet::<N>::from);
        if at.refine {
            for q in 0..n_par {
                if let Some((dzs, dxi)) = &tr.last[j0 + q] {
                    for (zi, dz) in zd.iter_mut().zip(dzs) {
                        for (x, d) in zi.iter_mut().zip(dz) {
                            x.eps[q] = *d;
                        }
                    }
                    for k in 0..6 {
                        xid[k].eps[q] = dxi[k];
                    }
                }
            }
        }
        let size_of = |zd: &[Vec<Jet<N>>], xid: &[Jet<N>; 6], q: usize| {
            let mut m = xid.iter().fold(0.0f64, |m, x| m.max(x.eps[q].abs()));
            for z in zd {
                m = z.iter().fold(m, |m, x| m.max(x.eps[q].abs()));
            }
            m
        };
        let mut last = [f64::INFINITY; N];
        let mut done = [false; N];
        for _ in 0..if at.refine { MAX_REFINE } else { 1 } {
            let (rs_d, g_d) = dual_residual(
                coupled, &models_d, &hist_d, &terms_d, mass, at.zs, &zd, &xid,
            );
            for q in 0..n_par {
                if done[q] {
                    continue;
                }
                let rs: Vec<Vec<f64>> = rs_d
                    .iter()
                    .map(|r| r.iter().map(|x| x.eps[q]).collect())
                    .collect();
                let g: [f64; 6] = std::array::from_fn(|k| g_d[k].eps[q]);
                let (dzs, dxi) = at
                    .matrix
                    .correction(&rs, &g)
                    .ok_or_else(|| not_solvable("state"))?;
                let mut step = dxi.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                for (zi, dz) in zd.iter_mut().zip(&dzs) {
                    for (x, d) in zi.iter_mut().zip(dz) {
                        x.eps[q] += *d;
                        step = step.max(d.abs());
                    }
                }
                for k in 0..6 {
                    xid[k].eps[q] += dxi[k];
                }
                if !at.refine {
                    done[q] = true;
                    continue;
                }
                if !step.is_finite() || step > RATE_MAX * last[q] {
                    return Ok(false); // not contracting: the exact matrix is needed
                }
                let size = size_of(&zd, &xid, q).max(tr.scale[j0 + q]);
                // The error left after this correction at the measured rate (none
                // measured on the first correction).
                let left = if last[q].is_finite() {
                    let rate = step / last[q];
                    step * rate / (1.0 - rate)
                } else {
                    f64::INFINITY
                };
                if step <= REFINE_TOL * size || left <= REFINE_TOL * size {
                    done[q] = true;
                }
                last[q] = step;
            }
            if done[..n_par].iter().all(|d| *d) {
                break;
            }
        }
        if !done[..n_par].iter().all(|d| *d) {
            return Ok(false);
        }
        for q in 0..n_par {
            let j = j0 + q;
            tr.scale[j] = tr.scale[j].max(size_of(&zd, &xid, q));
            tr.last[j] = Some((
                zd.iter()
                    .map(|z| z.iter().map(|x| x.eps[q]).collect())
                    .collect(),
                std::array::from_fn(|k| xid[k].eps[q]),
            ));
        }
        // The new state's derivatives: the platform's motion, every rod's slots, nodes
        // and markers.
        let k = kin_of(body.ls, &terms_d, &xid);
        let mut numbers = [Jet::<N>::from(0.0); 24];
        numbers[..3].copy_from_slice(&k.p);
        for i in 0..3 {
            numbers[3 + 3 * i..6 + 3 * i].copy_from_slice(&k.rot[i]);
        }
        for (m, v) in [k.v, k.w, k.a, k.wt].iter().enumerate() {
            numbers[12 + 3 * m..15 + 3 * m].copy_from_slice(v);
        }
        for q in 0..n_par {
            let j = j0 + q;
            let d: [f64; 24] = std::array::from_fn(|a| numbers[a].eps[q]);
            tr.prev[j] = if at.bdf.is_some() { tr.now[j] } else { d };
            tr.now[j] = d;
        }
        for (i, ((p, r), z)) in coupled.problems.iter().zip(&self.rods).zip(&zd).enumerate() {
            let fields = p.fields_with(&models_d[i], &hist_d[i], z);
            let (tip_node, nodes_r) = p.positions_of_fields(z, &fields);
            let markers = p.points_with(z, &fields, &nodes_r, &r.markers);
            let c0 = p.c0;
            for q in 0..n_par {
                let j = j0 + q;
                for (kk, slot) in tr.slots[i][j].iter_mut().enumerate() {
                    if at.bdf.is_none() {
                        // At rest: X_n = X_{n-1}, X_t = 0 (the tip slot stays zero, as
                        // the state's).
                        if kk < fields.len() {
                            let x: [f64; FIELDS] = std::array::from_fn(|a| fields[kk][a].eps[q]);
                            *slot = Slot {
                                x1: x,
                                x2: x,
                                xt: [0.0; FIELDS],
                            };
                        }
                        continue;
                    }
                    let x1: [f64; FIELDS] = if kk < fields.len() {
                        std::array::from_fn(|a| fields[kk][a].eps[q])
                    } else {
                        // The tip slot: the tip node's q, w.
                        let mut x = [0.0; FIELDS];
                        for a in 6..12 {
                            x[a] = tip_node[a + 4].eps[q];
                        }
                        x
                    };
                    *slot = Slot {
                        xt: std::array::from_fn(|a| c0 * x1[a] + hist_d[i][kk][a].eps[q]),
                        x2: slot.x1,
                        x1,
                    };
                }
                tr.shape[i][j] = nodes_r.iter().map(|v| v.map(|x| x.eps[q])).collect();
                tr.rod_markers[i][j] = markers.iter().map(|v| v.map(|x| x.eps[q])).collect();
            }
        }
        Ok(true)
    }
}

/// The step's residual in `Jet<N>` at the dual unknowns (`zd`, `xid`; their f64 parts the
/// converged `zs` and xi): every rod's residual with its dual models and histories, its
/// held rows with the dual held pose added (the residual's own read the f64 pose: the two
/// dual parts add up to the rows' full linearisation), its dual tip reaction; the
/// platform's rows with the dual mass and step terms.
#[allow(clippy::too_many_arguments)]
fn dual_residual<const N: usize>(
    coupled: &Coupled,
    models_d: &[Vec<SectionModel<Jet<N>>>],
    hist_d: &[Vec<[Jet<N>; NF]>],
    terms_d: &StepTerms<Jet<N>>,
    mass: Jet<N>,
    zs: &[Vec<f64>],
    zd: &[Vec<Jet<N>>],
    xid: &[Jet<N>; 6],
) -> (Vec<Vec<Jet<N>>>, [Jet<N>; 6]) {
    let body = coupled.eq.body;
    let pose = kin_of(body.ls, terms_d, xid);
    let mut rs_d = Vec::with_capacity(zd.len());
    let mut reactions = Vec::with_capacity(zd.len());
    for (i, (p, z)) in coupled.problems.iter().zip(zd).enumerate() {
        let mut r = p.residual_with(&models_d[i], &hist_d[i], z);
        let (rt, rot) = p.tip_pose(&zs[i]);
        let held = held_rows(&pose, &body.attach[i], &rt, &rot, 1.0 / p.rod.length);
        let row0 = p.tip_rows();
        for (k, h) in held.iter().enumerate() {
            for q in 0..N {
                r[row0 + k].eps[q] += h.eps[q];
            }
        }
        reactions.push(p.tip_reaction_with(&hist_d[i], z));
        rs_d.push(r);
    }
    let g_d = rows_of(body, mass, terms_d, xid, &reactions);
    (rs_d, g_d)
}
