//! Forward sensitivities of a dynamic run with respect to design parameters: d x(t) / d
//! theta along the whole trajectory, for dynamic calibration with exact Jacobians (issue
//! 19; paper 000 Sec. III-D fits tau and A_eff to tip trajectories).
//!
//! Every step solves G(z_{n+1}; H_n, theta) = 0 for the collocation unknowns, with H_n the
//! history terms X_h = c1 X_n + c2 X_{n-1} + d1 X_t,n of every stage slot (BDF-alpha). By
//! the implicit function theorem
//!
//!   dz_{n+1}/dtheta = -G_z^-1 (d_theta G + G_H dH_n/dtheta),
//!
//! with G_z the exact Newton matrix at the converged z_{n+1} and the bracket one evaluation
//! of the residual in `Jet<N>` (N = the parameters of the chunk, at most CHUNK: a dual
//! number no wider than what it carries) with the section models built from dual
//! parameters (`SectionModel<Jet<N>>`) and dual histories carrying dH_n/dtheta. The step's
//! Newton keeps an older matrix M as long as it contracts; factoring G_z at every step
//! would cost several plain steps, so the linear equation is solved with M by iterative
//! refinement, dz += -M^-1 (d_theta G + G_z dz), whose bracket is again one exact dual
//! evaluation (at z_{n+1} + eps dz): it converges to the exact dz/dtheta as fast as Newton
//! did, and a parameter is done when its correction, or the error left after it (rate /
//! (1 - rate) of it, as Newton estimates), falls below 1e-9 of its derivative's size (it
//! starts from dz/dtheta extrapolated by the cubic through the last four steps).
//! Where M does not contract by 0.25 per correction (or none is kept) G_z is factored at
//! z_{n+1} and solved directly, and that exact matrix serves the next steps' refinements
//! in place of Newton's (which Newton keeps: tracking does not change the run). The dual
//! evaluation at the final iterate (the last residual, or where the last correction was
//! applied without a confirming one, the stage fields alone) gives the stage fields
//! X_{n+1} = fields(z_{n+1}) with their derivatives, so the new slot values (and X_t,n+1 =
//! c0 X_{n+1} + X_h) and the derivatives of the node positions, the tip's and the markers'
//! (`Simulator::set_markers`: the collocation's continuous extension, `collocation::
//! dense_point`, evaluated in the same dual numbers) follow without evaluating the rod
//! equations again. The start (at rest in equilibrium, c0 = 0) is differentiated the same way. No
//! finite differences; the errors are that of the converged Newton solution (tol)
//! propagated linearly and the refinement's 1e-9.
//!
//! What is supported: the BDF-alpha scheme with fixed steps (substeps where Newton fails
//! are fine: the step sizes do not depend on theta), the static start, every axial law
//! (linear, with or without stretch-dependent bending; Ogden and EA(F) tables, solved in
//! f64 and linearised by the implicit function theorem with dual coefficients and
//! histories, `collocation::ogden_strain` and `table_stretch`), tapered sections and
//! reference shapes tabulated along s (the dual section models are built per stage point
//! through `Coeffs::at`, as the step's own), follower (body-frame) tip and line loads
//! (they turn with the dual state in the residual), and tendons under tension (issue 17:
//! the tensions are inputs, not parameters; the parameters reach the implicit tendon law
//! through the section's law, whose dual evaluation at the converged strains is the
//! law's implicit-function-theorem step, `SectionModel::strains`). The parameters:
//! correction factors, E, Ogden's alpha, c_p, chamber offsets, area_scale, density, mass
//! and the damping time. Contact with obstacles and a held (pinned or clamped) tip too: the
//! step's unknowns then carry the node positions (`collocation::contact`) and the dual
//! residual is that of the same equations (`Problem::residual_with`); the held pose is an
//! input and carries no derivative. The penalty is C1 (docs/contact.md): its ramp's second
//! derivative jumps where a surface point touches down or lifts off (delta = 0) and at
//! delta = eps, so the step residual is C1 in (z, theta), the implicit function theorem
//! holds at every step and the sensitivities are the exact derivatives of the discrete
//! trajectory, continuous in theta; their own theta-derivative jumps where a change of theta
//! moves a stage point across a switch (a central difference across one errs by O(h) of
//! that jump, not O(h^2)). Regularised friction is smooth. Refused: the midpoint scheme,
//! adaptive steps, a straight start and the sigma factors.

use super::{section_inertia, Bdf, Candidate, Initial, Scheme, Simulator, Slot, FIELDS};
use crate::collocation::{Factorization, Problem, SectionModel, NF};
use crate::error::{Result, SoftrodError};
use crate::jet::Jet;
use crate::ode::Coeffs;
use crate::sensitivity::{check_params, section_value, seeded_in, Param, ParamKind, CHUNK};

/// The sensitivities carried through the time loop.
#[derive(Debug, Clone)]
pub(crate) struct Tracker {
    params: Vec<Param>,
    /// d slot / d theta_j: `slots[j][k]` for history slot k (2 per interval, then the tip).
    slots: Vec<Vec<Slot>>,
    /// d r_tip / d theta_j now (world, m per unit of the parameter).
    tip: Vec<[f64; 3]>,
    /// d r(node k) / d theta_j now: `shape[j][k]` (the nodes of `Simulator::shape`).
    shape: Vec<Vec<[f64; 3]>>,
    /// d marker_k / d theta_j now: `markers[j][k]` (`Simulator::set_markers`).
    markers: Vec<Vec<[f64; 3]>>,
    /// dz/dtheta_j (scaled unknowns) of the last DZ_KEPT steps, newest first: the
    /// refinement's start is their extrapolation (none before two steps).
    dz: Vec<Vec<Vec<f64>>>,
    /// max |dz/dtheta_j| (scaled unknowns) over the run so far, and at least
    /// SCALE_FLOOR / |theta_j|: the scale the refinement's tolerance is relative to.
    scale: Vec<f64>,
    /// The sensitivities' own Newton matrix and its c0: the exact one of the last step
    /// that needed it (see `advance_tracker`).
    own: Option<(Factorization, f64)>,
    /// The refinement's contraction rate per parameter with the matrix it last used
    /// (infinite: unknown), and that matrix's point and c0: similar steps contract at
    /// about the same rate with the same matrix (Newton's device, see `refine`).
    rate: Vec<f64>,
    rate_of: Option<(Vec<f64>, f64)>,
    /// The refinement's scratch (right sides, corrections), kept: a step allocates none.
    buf: Vec<f64>,
}

impl Tracker {
    /// Parameter j's node and marker position derivatives (dual direction q of `nodes_r`
    /// and `markers`).
    fn set_positions<const N: usize>(
        &mut self,
        j: usize,
        q: usize,
        nodes_r: &[[Jet<N>; 3]],
        markers: &[[Jet<N>; 3]],
    ) {
        let shape = &mut self.shape[j];
        shape.clear();
        shape.extend(nodes_r.iter().map(|r| r.map(|x| x.eps[q])));
        self.tip[j] = shape.last().copied().unwrap_or([0.0; 3]);
        let at = &mut self.markers[j];
        at.clear();
        at.extend(markers.iter().map(|r| r.map(|x| x.eps[q])));
    }
}

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
            "the Newton matrix is singular at the converged {what}, so its parameter derivatives are undefined"
        ),
    }
}

impl Simulator {
    /// Track d(state)/d(theta) from now on for `params` (checked against the rod; errors
    /// name `params[j]`). Call it before the first step of a run started at rest in
    /// equilibrium with the BDF-alpha scheme and fixed steps; afterwards
    /// [`Simulator::tip_sensitivity`] gives the tip position's derivatives after every
    /// step. A restored state tracks none.
    pub fn track_sensitivities(&mut self, params: &[Param]) -> Result<()> {
        let refuse =
            |field: &str, value: String, rule: &str| Err(SoftrodError::invalid(field, value, rule));
        if self.stats.internal_steps > 0 {
            return refuse(
                "track_sensitivities",
                format!("t = {} s", self.time),
                "start tracking before the first step (the start's derivatives come first)",
            );
        }
        if self.initial != Initial::Static {
            return refuse(
                "initial",
                "straight".into(),
                "parameter sensitivities need the start at rest in equilibrium ('static')",
            );
        }
        if self.opts.scheme != Scheme::BdfAlpha {
            return refuse(
                "scheme",
                self.opts.scheme.name().into(),
                "parameter sensitivities are implemented for 'bdf-alpha'",
            );
        }
        if let Some(e) = self.opts.error_tol {
            return refuse(
                "error_tol",
                format!("{e}"),
                "parameter sensitivities need fixed steps (adaptive step sizes depend on the parameters): give no error_tol",
            );
        }
        self.check_tracked(params)?;
        let n_slots = self.slots.len();
        let mut tr = Tracker {
            params: params.to_vec(),
            slots: vec![vec![ZERO_SLOT; n_slots]; params.len()],
            tip: vec![[0.0; 3]; params.len()],
            shape: vec![vec![]; params.len()],
            markers: vec![vec![]; params.len()],
            dz: vec![vec![]; params.len()],
            scale: params
                .iter()
                .map(|p| {
                    let value = match (p.kind, p.sections.first()) {
                        (ParamKind::DampingTime, _) => self.rod.spec.dynamics.damping_time,
                        (kind, Some(&i)) => section_value(&self.rod, i, kind),
                        (_, None) => f64::NAN,
                    };
                    let floor = SCALE_FLOOR / value.abs();
                    if floor.is_finite() {
                        floor
                    } else {
                        0.0
                    }
                })
                .collect(),
            own: None,
            rate: vec![f64::INFINITY; params.len()],
            rate_of: None,
            buf: vec![],
        };
        // The start: equilibrium at rest (c0 = 0, no history) under the first pressures.
        let models = self.models_at(&self.pressures, &self.tensions, &self.sigma, 0.0);
        let hist = vec![[0.0; FIELDS]; n_slots];
        let tip = self.tip_body(self.tip_force, self.tip_moment);
        let problem = Problem::new(&self.rod, &self.grid, &models, 0.0, &hist, tip)
            .with_contact()
            .with_end(super::end_target(&self.end));
        let z = super::to_scaled(&problem, &self.z);
        let fac = problem
            .factorize(&z)
            .ok_or_else(|| not_solvable("initial equilibrium"))?;
        for (c, chunk) in params.chunks(CHUNK).enumerate() {
            let j0 = CHUNK * c;
            let ok = match chunk.len() {
                1 => self.start_chunk::<1>(&mut tr, j0, chunk, &problem, &fac, &z),
                2 => self.start_chunk::<2>(&mut tr, j0, chunk, &problem, &fac, &z),
                3 => self.start_chunk::<3>(&mut tr, j0, chunk, &problem, &fac, &z),
                _ => self.start_chunk::<CHUNK>(&mut tr, j0, chunk, &problem, &fac, &z),
            };
            ok.ok_or_else(|| not_solvable("initial equilibrium"))?;
        }
        self.sens = Some(Box::new(tr));
        Ok(())
    }

    /// Check `params` as parameters of this rod's dynamics (errors name `params[j]`): the
    /// section parameters as the statics check them, sigma refused (the dynamics take it
    /// from the stiffness map), the damping time without sections and acting somewhere.
    pub(super) fn check_tracked(&self, params: &[Param]) -> Result<()> {
        let refuse =
            |field: &str, value: String, rule: &str| Err(SoftrodError::invalid(field, value, rule));
        let (statics_params, rest): (Vec<Param>, Vec<(usize, &Param)>) = {
            let mut st = vec![];
            let mut other = vec![];
            for (j, p) in params.iter().enumerate() {
                match p.kind {
                    ParamKind::DampingTime => other.push((j, p)),
                    _ => st.push(p.clone()),
                }
            }
            (st, other)
        };
        check_params(&self.rod, &statics_params).map_err(|e| renumber(e, params))?;
        for (j, p) in params.iter().enumerate() {
            if let ParamKind::StiffnessScale(_) = p.kind {
                return refuse(
                    &format!("params[{j}] ({})", p.kind.name()),
                    p.kind.name().into(),
                    "the dynamics take sigma from the stiffness map of the pressures: calibrate sigma in statics",
                );
            }
        }
        for (j, p) in rest {
            let field = format!("params[{j}] (damping_time)");
            if !p.sections.is_empty() {
                return refuse(
                    &field,
                    format!("sections {:?}", p.sections),
                    "the damping time is one value of [dynamics]: give no sections",
                );
            }
            let damped = self
                .rod
                .sections
                .iter()
                .enumerate()
                .any(|(i, s)| !s.rigid && section_inertia(&self.rod, i).damping.is_none());
            if !damped {
                return refuse(
                    &field,
                    "damping_time".into(),
                    "every elastic section gives its damping matrices, so tau acts nowhere",
                );
            }
        }
        Ok(())
    }

    /// d r_tip / d theta_j now (world, m per unit of parameter j, in SI), one per tracked
    /// parameter; None when no sensitivities are tracked.
    pub fn tip_sensitivity(&self) -> Option<&[[f64; 3]]> {
        self.sens.as_ref().map(|t| t.tip.as_slice())
    }

    /// d r / d theta_j at every node of [`Simulator::shape`] now (`[j][node]`, world, m
    /// per unit of parameter j): with a held tip, whose own position is prescribed, what a
    /// fit reads is the rest of the rod. None when no sensitivities are tracked.
    pub fn shape_sensitivity(&self) -> Option<&[Vec<[f64; 3]>]> {
        self.sens.as_ref().map(|t| t.shape.as_slice())
    }

    /// d marker_k / d theta_j of the markers of [`Simulator::set_markers`] now (`[j][k]`,
    /// world, m per unit of parameter j): the continuous extension's positions
    /// ([`Simulator::marker_positions`]) evaluated in dual numbers, exact for the
    /// discrete trajectory. None when no sensitivities are tracked.
    pub fn marker_sensitivity(&self) -> Option<&[Vec<[f64; 3]>]> {
        self.sens.as_ref().map(|t| t.markers.as_slice())
    }

    /// The parameters tracked.
    pub fn sensitivity_params(&self) -> Option<&[Param]> {
        self.sens.as_ref().map(|t| t.params.as_slice())
    }

    /// The start's derivatives of the parameters `chunk` (numbers j0..): `Jet<N>` with
    /// N = chunk.len() (a dual number no wider than the parameters it carries). None when
    /// the exact solve fails.
    fn start_chunk<const N: usize>(
        &self,
        tr: &mut Tracker,
        j0: usize,
        chunk: &[Param],
        problem: &Problem,
        fac: &Factorization,
        z: &[f64],
    ) -> Option<()> {
        let n_slots = self.slots.len();
        let models_d =
            self.dual_models::<N>(chunk, &self.pressures, &self.tensions, &self.sigma, 0.0);
        let hist_d = vec![[Jet::<N>::from(0.0); NF]; n_slots];
        let zd = solve_exact(problem, fac, &models_d, &hist_d, z, chunk.len())?;
        let (fields, _, nodes_r) = problem.fields_and_positions_with(&models_d, &hist_d, &zd);
        let markers = problem.points_with(&zd, &fields, &nodes_r, &self.markers);
        for q in 0..chunk.len() {
            let j = j0 + q;
            for (k, f) in fields.iter().enumerate() {
                let x: [f64; FIELDS] = std::array::from_fn(|a| f[a].eps[q]);
                // At rest: X_n = X_{n-1}, X_t = 0 (the tip slot stays zero, as the
                // state's).
                tr.slots[j][k] = Slot {
                    x1: x,
                    x2: x,
                    xt: [0.0; FIELDS],
                };
            }
            tr.set_positions(j, q, &nodes_r, &markers);
        }
        Some(())
    }

    /// Section models at `pressures`, tendon `tensions`, `sigma` and c0 with the parameters
    /// of `chunk` seeded as dual directions: the law through the knobs (`crate::sensitivity::seeded`), the
    /// inertia through the mass knob (rotary inertia given directly stays), the damping
    /// through tau.
    fn dual_models<const N: usize>(
        &self,
        chunk: &[Param],
        pressures: &[f64],
        tensions: &[f64],
        sigma: &[f64; 3],
        c0: f64,
    ) -> Vec<SectionModel<Jet<N>>> {
        debug_assert!(chunk.len() <= N);
        let dirs: Vec<(usize, &Param)> = chunk.iter().enumerate().collect();
        self.dual_models_in::<N>(&dirs, pressures, tensions, sigma, c0)
    }

    /// [`Simulator::dual_models`] with each parameter's dual direction given: `(q, param)`
    /// seeds `param` as direction q < N (a system's parameter that acts on some rods only
    /// leaves the others' models without it, `dynamics::system`).
    pub(super) fn dual_models_in<const N: usize>(
        &self,
        dirs: &[(usize, &Param)],
        pressures: &[f64],
        tensions: &[f64],
        sigma: &[f64; 3],
        c0: f64,
    ) -> Vec<SectionModel<Jet<N>>> {
        let (knobs, sigma_d) = seeded_in::<N>(&self.rod, sigma, dirs.iter().copied());
        let mut tau = Jet::<N>::from(self.rod.spec.dynamics.damping_time);
        for &(q, p) in dirs {
            if p.kind == ParamKind::DampingTime {
                tau.eps[q] = 1.0;
            }
        }
        let coeffs: Vec<Coeffs<Jet<N>>> = (0..self.rod.sections.len())
            .map(|i| {
                Coeffs::build_with(
                    &self.rod,
                    i,
                    pressures,
                    tensions,
                    &self.rod.gravity,
                    Jet::<N>::from(1.0),
                    &sigma_d,
                    &knobs[i],
                )
            })
            .collect();
        self.grid
            .build_models(&self.rod, &coeffs, |c, slot_k, slot| {
                let i = slot.section;
                let k = &knobs[i];
                let inr = &self.inertia[slot_k];
                let rho_j_given = self.rod.spec.sections[i].rotary_inertia.is_some();
                let rho_j = inr.rho_j.map(|x| {
                    if rho_j_given {
                        Jet::<N>::from(x)
                    } else {
                        k.mass_scale * x
                    }
                });
                SectionModel::new(
                    c,
                    self.rod.sections[i].rigid,
                    k.mass_scale * inr.rho_a,
                    rho_j,
                    inr.damping,
                    tau,
                    c0,
                )
            })
    }

    /// Carry the sensitivities over the accepted step `c` (before it is committed: the
    /// slots' sensitivities are still those of the step's start).
    pub(super) fn advance_sensitivity(&mut self, c: &Candidate) -> Result<()> {
        let Some(mut tr) = self.sens.take() else {
            return Ok(());
        };
        let out = self.advance_tracker(&mut tr, c);
        self.sens = Some(tr);
        self.stats.jacobians += out?;
        Ok(())
    }

    /// [`Simulator::advance_sensitivity`]; returns the Newton matrices factored.
    fn advance_tracker(&self, tr: &mut Tracker, c: &Candidate) -> Result<usize> {
        let tip = self.tip_body(self.tip_force, self.tip_moment);
        let problem = super::step_problem(
            &self.rod,
            &self.grid,
            self.scale_c0(),
            &c.models,
            c.bdf.c0,
            &c.hist,
            tip,
        )
        .with_end(super::end_target(&c.end));
        // The matrix Newton kept for this step (same c0), if any: the sensitivity equation
        // is solved with it by iterative refinement, else with the exact matrix factored
        // at the converged state.
        let own = tr.own.take().filter(|(_, c0)| *c0 == c.bdf.c0);
        let kept = match &own {
            Some((f, _)) => Some(f),
            None => self
                .cache
                .as_ref()
                .filter(|k| k.key.c0 == c.bdf.c0)
                .map(|k| &k.fac),
        };
        // The rates measured with another matrix say nothing about this one.
        let same = match (kept, &tr.rate_of) {
            (Some(f), Some((at, c0))) => *c0 == c.bdf.c0 && f.at == *at,
            _ => false,
        };
        if !same {
            tr.rate.fill(f64::INFINITY);
            tr.rate_of = kept.map(|f| (f.at.clone(), c.bdf.c0));
        }
        let mut exact: Option<Factorization> = None;
        let params = std::mem::take(&mut tr.params);
        let mut out = Ok(());
        for (ci, chunk) in params.chunks(CHUNK).enumerate() {
            let j0 = CHUNK * ci;
            let mut step = Step {
                problem: &problem,
                kept,
                exact: &mut exact,
            };
            // The dual number as wide as the chunk: every operation on it costs 1 + N
            // numbers (and N more per product), so two parameters in Jet<4> pay for four.
            out = match chunk.len() {
                1 => self.advance_chunk::<1>(tr, j0, chunk, c, &mut step),
                2 => self.advance_chunk::<2>(tr, j0, chunk, c, &mut step),
                3 => self.advance_chunk::<3>(tr, j0, chunk, c, &mut step),
                _ => self.advance_chunk::<CHUNK>(tr, j0, chunk, c, &mut step),
            };
            if out.is_err() {
                break;
            }
        }
        tr.params = params;
        let factored = usize::from(exact.is_some());
        // A matrix factored here is exact at this step's state: the next steps refine
        // with it (Newton keeps its own, so that tracking does not change the run).
        tr.own = match exact {
            Some(f) => Some((f, c.bdf.c0)),
            None => own,
        };
        out.map(|()| factored)
    }

    /// The sensitivities of the parameters `chunk` (numbers j0..) over the step `c`, in
    /// `Jet<N>` with N = chunk.len(): [`Simulator::advance_chunk_impl`] compiled for AVX2
    /// where the CPU has it (as the plain step's residual and solves,
    /// `banded::simd_dispatch`): the dual residual evaluations, the refinement's loops and
    /// the tracker's own are inlined into it. AVX2 without FMA changes no result: the
    /// same operations in the same order, only several lanes at once.
    #[inline(never)]
    fn advance_chunk<const N: usize>(
        &self,
        tr: &mut Tracker,
        j0: usize,
        chunk: &[Param],
        c: &Candidate,
        step: &mut Step,
    ) -> Result<()> {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2")]
            unsafe fn avx2<const N: usize>(
                this: &Simulator,
                tr: &mut Tracker,
                j0: usize,
                chunk: &[Param],
                c: &Candidate,
                step: &mut Step,
            ) -> Result<()> {
                this.advance_chunk_impl::<N>(tr, j0, chunk, c, step)
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above), the only
                // requirement of calling a function compiled for it.
                return unsafe { avx2::<N>(self, tr, j0, chunk, c, step) };
            }
        }
        self.advance_chunk_impl::<N>(tr, j0, chunk, c, step)
    }

    /// [`Simulator::advance_chunk`].
    #[inline(always)]
    fn advance_chunk_impl<const N: usize>(
        &self,
        tr: &mut Tracker,
        j0: usize,
        chunk: &[Param],
        c: &Candidate,
        step: &mut Step,
    ) -> Result<()> {
        let Bdf { c0, c1, c2, d1 } = c.bdf;
        let problem = step.problem;
        let n_slots = c.hist.len();
        let n_par = chunk.len();
        // The step's tensions are the new ones (BDF-alpha): `self.tensions` until it commits.
        let models_d = self.dual_models::<N>(chunk, &c.pressures, &self.tensions, &c.sigma, c0);
        // dH/dtheta = c1 dX_n + c2 dX_{n-1} + d1 dX_t,n.
        let hist_d: Vec<[Jet<N>; NF]> = (0..n_slots)
            .map(|k| {
                std::array::from_fn(|a| {
                    let mut h = Jet::<N>::from(c.hist[k][a]);
                    for q in 0..n_par {
                        let s = &tr.slots[j0 + q][k];
                        h.eps[q] = c1 * s.x1[a] + c2 * s.x2[a] + d1 * s.xt[a];
                    }
                    h
                })
            })
            .collect();
        let z = &c.z_scaled;
        // Start: dz/dtheta extrapolated from the last steps, by the cubic through the last
        // four (with equal steps the weights are 4, -6, 4, -1): on smooth motion the
        // refinement starts O(h^4) off instead of O(1). Linear extrapolation took 1.3x the
        // evaluations of the quadratic on the arm; the cubic saves another 10 % of the
        // residual evaluations and solves (benchmark arm, 20 s: 2.2 dual residual
        // evaluations per step against 2.5), so more steps end after one correction. It
        // amplifies the stored derivatives' errors (<= 1.33 REFINE_TOL of their size) by
        // at most 15, an error the refinement removes as any other. The steps are equal except
        // for halvings where Newton fails, where the start is only worse: the refinement
        // converges to the same derivative from any start.
        let mut start: Vec<Jet<N>> = z.iter().map(|&x| Jet::<N>::from(x)).collect();
        for q in 0..n_par {
            match tr.dz[j0 + q].as_slice() {
                [a, b, cc, d] => {
                    // 4 (a + c) - 6 b - d, in that order: the same numbers for any thread
                    // count (each run is sequential) and every platform.
                    for (k, x) in start.iter_mut().enumerate() {
                        x.eps[q] = 4.0 * (a[k] + cc[k]) - 6.0 * b[k] - d[k];
                    }
                }
                [a, b, cc] => {
                    for (k, x) in start.iter_mut().enumerate() {
                        x.eps[q] = 3.0 * (a[k] - b[k]) + cc[k];
                    }
                }
                [a, b] => {
                    for (x, (da, db)) in start.iter_mut().zip(a.iter().zip(b)) {
                        x.eps[q] = 2.0 * da - db;
                    }
                }
                _ => {}
            }
        }
        let scale: [f64; N] = std::array::from_fn(|q| tr.scale.get(j0 + q).copied().unwrap_or(0.0));
        let mut hint: [f64; N] =
            std::array::from_fn(|q| tr.rate.get(j0 + q).copied().unwrap_or(f64::INFINITY));
        // A match, not a closure: a closure would be compiled apart from this function, for
        // the baseline CPU (`Simulator::advance_chunk`).
        let refined = match step.kept {
            Some(f) => refine(
                problem,
                f,
                &models_d,
                &hist_d,
                start,
                n_par,
                &scale,
                &mut hint,
                &mut tr.buf,
            ),
            None => None,
        };
        tr.rate[j0..j0 + n_par].copy_from_slice(&hint[..n_par]);
        let (zd, fields) = match refined {
            Some(solved) => solved,
            None => {
                if step.exact.is_none() {
                    *step.exact = Some(problem.factorize(z).ok_or_else(|| {
                        not_solvable(&format!("step to t = {:.6} s", self.time + c.h))
                    })?);
                }
                let fac = step.exact.as_ref().expect("factored above");
                let zd = solve_exact(problem, fac, &models_d, &hist_d, z, n_par)
                    .ok_or_else(|| not_solvable("state"))?;
                let fields = problem.fields_with(&models_d, &hist_d, &zd);
                (zd, fields)
            }
        };
        let (tip_node, nodes_r) = problem.positions_of_fields(&zd, &fields);
        let markers = problem.points_with(&zd, &fields, &nodes_r, &self.markers);
        for q in 0..n_par {
            let j = j0 + q;
            let mut old = std::mem::take(&mut tr.dz[j]);
            let recycled = if old.len() == DZ_KEPT {
                old.pop()
            } else {
                None
            };
            let mut now = recycled.unwrap_or_else(|| vec![0.0; zd.len()]);
            for (x, d) in now.iter_mut().zip(&zd) {
                *x = d.eps[q];
            }
            tr.scale[j] = max_abs(&now, tr.scale[j], |x| *x);
            old.insert(0, now);
            tr.dz[j] = old;
            let slots = &mut tr.slots[j];
            for (k, slot) in slots.iter_mut().enumerate() {
                let x1: [f64; FIELDS] = if k < fields.len() {
                    std::array::from_fn(|a| fields[k][a].eps[q])
                } else {
                    // The tip slot: the tip node's q, w.
                    let mut x = [0.0; FIELDS];
                    for a in 6..12 {
                        x[a] = tip_node[a + 4].eps[q];
                    }
                    x
                };
                *slot = Slot {
                    xt: std::array::from_fn(|a| c0 * x1[a] + hist_d[k][a].eps[q]),
                    x2: slot.x1,
                    x1,
                };
            }
            tr.set_positions(j, q, &nodes_r, &markers);
        }
        Ok(())
    }
}

/// What the chunks of one step share: the step's problem, the matrix Newton kept and the
/// exact one once factored.
struct Step<'a, 'p> {
    problem: &'a Problem<'p>,
    kept: Option<&'a Factorization>,
    exact: &'a mut Option<Factorization>,
}

/// The smallest scale of a parameter's derivative, per unit of relative change of the
/// parameter: 1e-3 of the scaled unknowns' O(1) size for theta -> 2 theta. A derivative
/// smaller than that over the whole run so far (d/dtau is exactly zero while the arm rests
/// before the first input; round-off makes it ~1e-13) is resolved to REFINE_TOL of this
/// floor, 1e-12 per unit relative change, instead of to 1e-9 of its own round-off-sized
/// value, which took the refinement to its limit of evaluations at every resting step.
/// Derivatives that matter to a fit are far above it (the arm's are 0.1-1 per unit relative
/// change), where the tolerance stays relative to their own size.
const SCALE_FLOOR: f64 = 1e-3;

/// dz/dtheta of the last steps kept for the refinement's start.
const DZ_KEPT: usize = 4;

/// Refinement steps with a kept Newton matrix before the exact one is factored.
const MAX_REFINE: usize = 12;
/// The refinement falls back to the exact matrix (factored at the step's state, and kept
/// for the next steps' refinements) when a correction is not below this fraction of the
/// last one: Newton's own rule for keeping its matrix (`collocation::newton_with`). On the
/// arm (8 s of pulses, tau and area_scale) 0.5 took 4112 dual evaluations and 6
/// factorisations in 1600 steps, 0.25 3883 and 15, 0.1 3653 and 38, the factorisation
/// costing about ten evaluations.
const RATE_MAX: f64 = 0.25;
/// The refinement stops when every correction is below this fraction of the derivative it
/// corrects (scaled unknowns): as fine as the state itself is solved (Newton's tol of 1e-9
/// on the scaled unknowns), far below what a fit resolves.
const REFINE_TOL: f64 = 1e-9;

/// The chunk's unknowns with dz/dtheta in their dual parts, solved with the exact Newton
/// matrix `fac` at `z`: dz/dtheta = -G_z^-1 dG/dtheta (models and histories dual).
fn solve_exact<const N: usize>(
    problem: &Problem,
    fac: &Factorization,
    models: &[SectionModel<Jet<N>>],
    hist: &[[Jet<N>; NF]],
    z: &[f64],
    n_par: usize,
) -> Option<Vec<Jet<N>>> {
    let zc: Vec<Jet<N>> = z.iter().map(|&x| Jet::<N>::from(x)).collect();
    let r = problem.residual_with(models, hist, &zc);
    fac.implicit_step(z, &r, n_par)
}

/// The same with an approximate (kept) matrix M: iterative refinement
/// dz += -M^-1 (dG/dtheta + G_z dz), the bracket one dual evaluation of the residual at
/// z + eps dz (exact); it converges to the exact dz/dtheta as fast as Newton did with M.
/// A parameter's derivative is done when its correction falls below REFINE_TOL of its
/// size, the larger of max |dz/dtheta| now and `scale` (the largest it has been in the
/// run: where a derivative decays towards zero, e.g. d/dtau at rest, 1e-9 of its own
/// vanishing size would be below the round-off of the residual's terms, which are of the
/// derivative's usual size), or, as in Newton (`collocation::newton_with`), when the
/// error left after applying its correction, rate / (1 - rate) of the correction, is:
/// the rate is that of its last two corrections, or on the first correction `hint[q]`
/// (the rate of the last step's refinement with the same matrix), which the residual
/// must then confirm by falling at least as that rate says (by 10x the rate at worst,
/// and by half). Done parameters are not corrected further. Returns the final iterate
/// with the stage fields at it (their derivatives are the slots' new values): those of
/// the last residual when the last correction was below REFINE_TOL and is not applied,
/// else of one evaluation of the fields alone, which costs less than a residual and,
/// unlike the correction that would confirm convergence, no solve. The contraction rate
/// is held <= RATE_MAX = 0.25, so the returned error is at most 1.33 REFINE_TOL of the
/// size. Updates `hint` with the rates measured. None when it does not contract, or not
/// to REFINE_TOL within MAX_REFINE evaluations.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn refine<const N: usize>(
    problem: &Problem,
    fac: &Factorization,
    models: &[SectionModel<Jet<N>>],
    hist: &[[Jet<N>; NF]],
    start: Vec<Jet<N>>,
    n_par: usize,
    scale: &[f64; N],
    hint: &mut [f64; N],
    buf: &mut Vec<f64>,
) -> Option<(Vec<Jet<N>>, Vec<[Jet<N>; NF]>)> {
    let mut zd = start;
    let n = zd.len();
    // Right sides and corrections of up to two parameters (solved together), every
    // parameter's correction and the solver's scratch: all written before they are read.
    buf.resize(4 * n + n * n_par + 2 * fac.scratch_len(), 0.0);
    let (rhs, rest) = buf.split_at_mut(2 * n);
    let (out, rest) = rest.split_at_mut(2 * n);
    let (corr, scratch) = rest.split_at_mut(n * n_par);
    let mut last = [f64::INFINITY; N];
    let mut done = [false; N];
    let (mut r, mut fields) = problem.residual_and_fields_with(models, hist, &zd);
    for _ in 0..MAX_REFINE {
        // Every correction is computed from this residual before any is applied.
        let active: Vec<usize> = (0..n_par).filter(|&q| !done[q]).collect();
        for pair in active.chunks(2) {
            if let [a, b] = *pair {
                for (i, ri) in r.iter().enumerate() {
                    rhs[i] = ri.eps[a];
                    rhs[n + i] = ri.eps[b];
                }
                fac.solve2(rhs, out, scratch);
                corr[a * n..(a + 1) * n].copy_from_slice(&out[..n]);
                corr[b * n..(b + 1) * n].copy_from_slice(&out[n..]);
            } else {
                let a = pair[0];
                for (x, ri) in rhs[..n].iter_mut().zip(&r) {
                    *x = ri.eps[a];
                }
                fac.solve(&rhs[..n], &mut corr[a * n..(a + 1) * n], scratch);
            }
        }
        let mut apply = [false; N];
        // Settled after this correction, by the measured rate or by the hint.
        let mut settled = [false; N];
        let mut on_hint = [false; N];
        for &q in &active {
            let cq = &corr[q * n..(q + 1) * n];
            let step = max_abs(cq, 0.0, |x| *x);
            let size = max_abs(&zd, scale[q], |x| x.eps[q]);
            if step <= REFINE_TOL * size {
                done[q] = true;
                continue;
            }
            if !step.is_finite() || step > RATE_MAX * last[q] {
                return None; // not contracting: the exact matrix is needed
            }
            let measured = last[q].is_finite();
            let rate = if measured { step / last[q] } else { hint[q] };
            if measured {
                hint[q] = rate;
            }
            if rate <= RATE_MAX && step * rate / (1.0 - rate) <= REFINE_TOL * size {
                settled[q] = true;
                on_hint[q] = !measured;
            }
            last[q] = step;
            apply[q] = true;
        }
        if !apply.contains(&true) {
            return Some((zd, fields));
        }
        for q in (0..n_par).filter(|&q| apply[q]) {
            for (x, d) in zd.iter_mut().zip(&corr[q * n..(q + 1) * n]) {
                x.eps[q] += *d;
            }
        }
        let finished = (0..n_par).all(|q| done[q] || settled[q]);
        if finished && !on_hint.contains(&true) {
            let fields = problem.fields_with(models, hist, &zd);
            return Some((zd, fields));
        }
        let (r_new, f_new) = problem.residual_and_fields_with(models, hist, &zd);
        let confirmed = |q: usize| {
            let norm = |r: &[Jet<N>]| max_abs(r, 0.0, |x| x.eps[q]);
            norm(&r_new) <= norm(&r) * (10.0 * hint[q]).min(0.5)
        };
        if finished && (0..n_par).filter(|&q| on_hint[q]).all(confirmed) {
            return Some((zd, f_new));
        }
        // Not all settled, or the hint not confirmed: derivatives settled by their
        // measured rates are done; the others go on from the new residual.
        for q in 0..n_par {
            done[q] |= settled[q] && !on_hint[q];
        }
        r = r_new;
        fields = f_new;
    }
    None
}

/// max(start, max |f(x)| over `xs`), NaNs skipped (`f64::max`): the fold of `f64::max` from
/// `start`, in four running maxima (max is exact, so the order does not change the result)
/// instead of one chain whose every step waits for the last (the refinement takes several
/// per step over all unknowns).
#[inline(always)]
fn max_abs<T>(xs: &[T], start: f64, f: impl Fn(&T) -> f64) -> f64 {
    let mut acc = [start; 4];
    let mut quads = xs.chunks_exact(4);
    for c in &mut quads {
        for (a, x) in acc.iter_mut().zip(c) {
            *a = a.max(f(x).abs());
        }
    }
    for x in quads.remainder() {
        acc[0] = acc[0].max(f(x).abs());
    }
    acc[0].max(acc[1]).max(acc[2].max(acc[3]))
}

/// A section check's error with the index of the parameter in the full list.
fn renumber(e: SoftrodError, params: &[Param]) -> SoftrodError {
    // check_params numbered the parameters without the damping time; map back.
    let SoftrodError::InvalidParameter { field, value, rule } = e else {
        return e;
    };
    let statics: Vec<usize> = params
        .iter()
        .enumerate()
        .filter(|(_, p)| p.kind != ParamKind::DampingTime)
        .map(|(j, _)| j)
        .collect();
    let field = field
        .strip_prefix("params[")
        .and_then(|rest| rest.split_once(']'))
        .and_then(|(k, tail)| {
            let k: usize = k.parse().ok()?;
            Some(format!("params[{}]{tail}", statics.get(k)?))
        })
        .unwrap_or(field);
    SoftrodError::InvalidParameter { field, value, rule }
}
