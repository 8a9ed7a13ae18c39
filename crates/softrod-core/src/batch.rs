//! Many static solves in parallel (rayon). Every row is solved exactly as [`solve`] solves
//! it alone from the same start (cold, or the row's own warm start), so a batch row is
//! bitwise equal to the single solve, whatever the thread count or the order of the rows.
//! The same holds for a tip held by a constraint ([`solve_constrained_batch`]: every row is
//! one [`solve_constrained`], cold) and for a system of rods holding a platform
//! ([`solve_system_batch`]: every row is one [`solve_system`], cold) and for obstacles with
//! friction ([`solve_friction_batch`] and [`solve_held_friction_batch`]: every row is one
//! [`friction::solve`] or [`friction::solve_held`], its own load path from the unloaded
//! rod): no row starts from another row's solution. [`system_sensitivity_batch`] adds a
//! system's parameter derivatives to its rows (each row one [`solve_system`] from its own
//! warm start, if any).

use crate::error::{Result, SoftrodError};
use crate::marker::Marker;
use crate::ode::Loads;
use crate::rod::Rod;
use crate::sensitivity::system::{
    locate_system_markers, system_marker_positions, system_sensitivity, validate_system_params,
    SystemMarker, SystemParam, SystemSensitivity,
};
use crate::sensitivity::{
    constrained_pose_sensitivity, locate_markers, marker_positions, pose_sensitivity,
    validate_params, Param, TipSensitivity,
};
use crate::statics::constraint::{solve_constrained, ConstrainedSolution, TipConstraint};
use crate::statics::friction;
use crate::statics::system::{
    solve_system, solve_system_friction, Platform, SystemRod, SystemSolution,
};
use crate::statics::{n_unknowns, solve, Solution, SolverOptions};
use crate::validity::{self, Policy};

/// One row of a batch result. Failed rows are kept, with `converged = false` and NaNs.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchRow {
    pub converged: bool,
    pub tip_position: [f64; 3],
    pub tip_rotation: [[f64; 3]; 3],
    pub base_force: [f64; 3],
    pub base_moment: [f64; 3],
    pub iterations: usize,
    pub residual: f64,
    /// Scaled shooting unknowns (a warm start for a later solve of this row): 3, or 6 with
    /// follower loads.
    pub x: Vec<f64>,
    /// The equilibrium is stable (false on failed rows; None where not assessed: follower
    /// loads).
    pub stable: Option<bool>,
    /// The validity rule the row broke (a failed row under `Policy::Raise`, or a returned
    /// one under `Policy::Warn`), or the error that failed it (other than
    /// non-convergence), else empty.
    pub violation: String,
    /// Tip-pose (and marker) derivatives with respect to the parameters
    /// ([`sensitivity_batch`] only).
    pub sensitivity: Option<TipSensitivity>,
    /// Marker positions, world frame ([`sensitivity_batch`] with markers; NaN on failed
    /// rows).
    pub markers: Vec<[f64; 3]>,
    /// The wrench the tip constraint applies to the tip (world frame; N, N m): zero for a
    /// free tip, zero moment for a pinned one, NaN on failed rows.
    pub tip_reaction_force: [f64; 3],
    pub tip_reaction_moment: [f64; 3],
    /// Resultant contact force of each obstacle on the rod (normal and friction), N, world
    /// frame (`statics::contact::ContactReport::force`; [`solve_friction_batch`] only, NaN
    /// on failed rows; empty otherwise).
    pub contact_force: Vec<[f64; 3]>,
    /// The tangential (friction) part of `contact_force`, per obstacle, N
    /// (`ContactReport::friction`; as `contact_force`).
    pub friction_force: Vec<[f64; 3]>,
}

impl BatchRow {
    fn failed(unknowns: usize, iterations: usize, residual: f64) -> Self {
        BatchRow {
            stable: Some(false),
            violation: String::new(),
            converged: false,
            tip_position: [f64::NAN; 3],
            tip_rotation: [[f64::NAN; 3]; 3],
            base_force: [f64::NAN; 3],
            base_moment: [f64::NAN; 3],
            iterations,
            residual,
            x: vec![f64::NAN; unknowns],
            sensitivity: None,
            markers: vec![],
            tip_reaction_force: [f64::NAN; 3],
            tip_reaction_moment: [f64::NAN; 3],
            contact_force: vec![],
            friction_force: vec![],
        }
    }

    /// The row of a constrained (or system rod's) solution, with its tip reaction.
    fn held(c: &ConstrainedSolution) -> Self {
        BatchRow {
            tip_reaction_force: c.tip_reaction_force,
            tip_reaction_moment: c.tip_reaction_moment,
            ..BatchRow::solved(&c.solution)
        }
    }

    /// A failed row of an error: the iterations and residual of a non-convergence, else
    /// the error's message (the broken rule of an invalid state).
    fn of_error(unknowns: usize, e: &SoftrodError) -> Self {
        match e {
            SoftrodError::NotConverged {
                iterations,
                residual,
                ..
            } => BatchRow::failed(unknowns, *iterations, *residual),
            // A broken rule, or any other error: the row says why it failed.
            _ => BatchRow {
                violation: e.to_string(),
                ..BatchRow::failed(unknowns, 0, f64::NAN)
            },
        }
    }

    fn solved(sol: &Solution) -> Self {
        BatchRow {
            converged: true,
            tip_position: sol.tip.r,
            tip_rotation: sol.tip.rot,
            base_force: sol.base_force,
            base_moment: sol.base_moment,
            iterations: sol.iterations,
            residual: sol.residual,
            x: sol.x.clone(),
            stable: sol.stable,
            violation: sol
                .violations
                .first()
                .map(|e| e.to_string())
                .unwrap_or_default(),
            sensitivity: None,
            markers: vec![],
            tip_reaction_force: [0.0; 3],
            tip_reaction_moment: [0.0; 3],
            contact_force: vec![],
            friction_force: vec![],
        }
    }
}

/// The rows of a batch: pressures (row-major, `n_channels` per row), tensions
/// (`n_tendons` per row; none: slack), optional sigma (3 per row) and optional warm starts
/// (one per unknown per row), all checked up front. `template` holds the loads every row
/// shares (tip loads and their frame).
struct Rows<'a> {
    nc: usize,
    nt: usize,
    count: usize,
    unknowns: usize,
    pressures: &'a [f64],
    tensions: Option<&'a [f64]>,
    stiffness_scale: Option<&'a [f64]>,
    guesses: Option<&'a [f64]>,
    template: Loads,
}

/// A batch's inputs: the row arrays (row-major) and the tip loads every row shares.
#[derive(Debug, Clone, Copy)]
pub struct BatchInputs<'a> {
    /// (m, n_channels) gauge pressures, Pa.
    pub pressures: &'a [f64],
    /// (m, n_tendons) tendon tensions, N; None: slack tendons.
    pub tensions: Option<&'a [f64]>,
    /// (m, 3) stiffness scales sigma for mapped sections; None: ones.
    pub stiffness_scale: Option<&'a [f64]>,
    /// Tip force and moment of every row, in the design's tip frame.
    pub tip_force: [f64; 3],
    pub tip_moment: [f64; 3],
}

impl<'a> BatchInputs<'a> {
    /// Pressures only: slack tendons, the design's tip loads, unit stiffness scale.
    pub fn pressures(rod: &Rod, pressures: &'a [f64]) -> Self {
        BatchInputs {
            pressures,
            tensions: None,
            stiffness_scale: None,
            tip_force: rod.spec.tip.force,
            tip_moment: rod.spec.tip.moment,
        }
    }
}

impl<'a> Rows<'a> {
    fn new(
        rod: &Rod,
        opts: &SolverOptions,
        inputs: &BatchInputs<'a>,
        guesses: Option<&'a [f64]>,
    ) -> Result<Self> {
        // Only the frictional batch carries friction (obstacles with friction: refused
        // before any row here; each row of it follows its own load path).
        crate::statics::contact::frictionless(rod)?;
        Self::any_friction(rod, opts, inputs, guesses)
    }

    /// [`Rows::new`] without the frictionless rule ([`solve_friction_batch`]).
    fn any_friction(
        rod: &Rod,
        opts: &SolverOptions,
        inputs: &BatchInputs<'a>,
        guesses: Option<&'a [f64]>,
    ) -> Result<Self> {
        let (pressures, tensions, stiffness_scale) =
            (inputs.pressures, inputs.tensions, inputs.stiffness_scale);
        let nc = rod.n_channels;
        let nt = rod.n_tendons;
        let (count, width, what) = if nc > 0 {
            (
                pressures.len().checked_div(nc).unwrap_or(0),
                nc,
                "pressures",
            )
        } else {
            let t = tensions.unwrap_or(&[]);
            (t.len().checked_div(nt).unwrap_or(0), nt, "tensions")
        };
        let given = if nc > 0 {
            pressures.len()
        } else {
            tensions.map_or(0, <[f64]>::len)
        };
        if width == 0 || given % width != 0 {
            return Err(SoftrodError::invalid(
                what,
                format!("{given} values"),
                if nc > 0 {
                    format!("must be an (m, {nc}) array: one gauge pressure per channel per row")
                } else {
                    format!(
                        "the design has no pressure channels: give an (m, {nt}) array of tensions, one per tendon per row"
                    )
                },
            ));
        }
        if nc == 0 && !pressures.is_empty() {
            return Err(SoftrodError::invalid(
                "pressures",
                format!("{} values", pressures.len()),
                "the design has no pressure channels: give an (m, 0) array",
            ));
        }
        for (name, v) in [
            ("tip_force", &inputs.tip_force),
            ("tip_moment", &inputs.tip_moment),
        ] {
            finite3(name, v)?;
        }
        let template = Loads {
            pressures: vec![],
            tensions: vec![],
            tip_force: inputs.tip_force,
            tip_moment: inputs.tip_moment,
            tip_frame: rod.spec.tip.frame,
            stiffness_scale: [1.0; 3],
        };
        let unknowns = n_unknowns(rod, &template);
        if stiffness_scale.is_none() && count > 0 {
            // Every row's sigma of a mapped rod, never 1 by default.
            crate::statics::system::lone_sigma("stiffness_scale", rod, None)?;
        }
        for (name, v, k) in [
            ("stiffness_scale", stiffness_scale, 3),
            ("x0", guesses, unknowns),
            ("tensions", tensions, nt),
        ] {
            if let Some(s) = v {
                if s.len() != k * count {
                    return Err(SoftrodError::invalid(
                        name,
                        format!("{} values", s.len()),
                        format!("must be an ({count}, {k}) array: {k} values for every input row"),
                    ));
                }
            }
        }
        let rows = Rows {
            nc,
            nt,
            count,
            unknowns,
            pressures,
            tensions,
            stiffness_scale,
            guesses,
            template,
        };
        let range = rod
            .spec
            .operating_range
            .filter(|_| opts.on_invalid == Policy::Raise);
        for r in 0..count {
            rod.check_loads(rows.pressures(r), &rows.sigma(r))
                .and_then(|()| rod.check_tensions(&rows.tensions(r)))
                .and_then(|()| match range {
                    Some(range) => validity::check_operating_range(
                        rows.pressures(r),
                        &rows.tensions(r),
                        &range,
                    ),
                    None => Ok(()),
                })
                .map_err(|e| in_row(r, "", e))?;
        }
        Ok(rows)
    }

    fn pressures(&self, r: usize) -> &[f64] {
        &self.pressures[r * self.nc..(r + 1) * self.nc]
    }

    fn tensions(&self, r: usize) -> Vec<f64> {
        match self.tensions {
            Some(t) => t[r * self.nt..(r + 1) * self.nt].to_vec(),
            None => vec![0.0; self.nt],
        }
    }

    fn sigma(&self, r: usize) -> [f64; 3] {
        self.stiffness_scale
            .map_or([1.0; 3], |s| [s[3 * r], s[3 * r + 1], s[3 * r + 2]])
    }

    fn guess(&self, r: usize) -> Option<&[f64]> {
        let k = self.unknowns;
        self.guesses
            .map(|g| &g[k * r..k * (r + 1)])
            .filter(|g| g.iter().all(|v| v.is_finite()))
    }

    /// The loads of row r: its pressures, tensions and sigma over the shared template.
    fn loads(&self, r: usize) -> Loads {
        Loads {
            pressures: self.pressures(r).to_vec(),
            tensions: self.tensions(r),
            stiffness_scale: self.sigma(r),
            ..self.template.clone()
        }
    }

    /// Solve every row (from its own warm start, else cold), then apply `after` to each
    /// converged one, in parallel. Rows are independent: no row starts from another's
    /// solution, so the result does not depend on how rows are shared among threads.
    fn run(
        &self,
        rod: &Rod,
        opts: &SolverOptions,
        threads: usize,
        after: &(dyn Fn(&Loads, &Solution, &mut BatchRow) + Sync),
    ) -> Result<Vec<BatchRow>> {
        let n = self.unknowns;
        in_pool(threads, self.count, &|r| {
            let loads = self.loads(r);
            match solve(rod, &loads, self.guess(r), opts) {
                Ok(sol) => {
                    let mut row = BatchRow::solved(&sol);
                    after(&loads, &sol, &mut row);
                    row
                }
                Err(e) => BatchRow::of_error(n, &e),
            }
        })
    }
}

/// An input error of row r named as such ("row 3: pressures[1]", with `prefix` before the
/// field: "row 3: rods[1].pressures[0]").
fn in_row(r: usize, prefix: &str, e: SoftrodError) -> SoftrodError {
    match e {
        SoftrodError::InvalidParameter { field, value, rule } => SoftrodError::InvalidParameter {
            field: format!("row {r}: {prefix}{field}"),
            value,
            rule,
        },
        other => other.map_message(|message| {
            if prefix.is_empty() {
                format!("row {r}: {message}")
            } else {
                format!("row {r}: {}: {message}", prefix.trim_end_matches('.'))
            }
        }),
    }
}

fn finite3(field: &str, v: &[f64; 3]) -> Result<()> {
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(SoftrodError::invalid(
                format!("{field}[{i}]"),
                x,
                "must be a finite number",
            ));
        }
    }
    Ok(())
}

/// `one(r)` for every row r in 0..count on `threads` workers (0: rayon's global pool, all
/// cores), in row order. Each row is computed by itself, so the result does not depend on
/// the thread count.
fn in_pool<T: Send>(
    threads: usize,
    count: usize,
    one: &(dyn Fn(usize) -> T + Sync),
) -> Result<Vec<T>> {
    let work = || -> Vec<T> {
        use rayon::prelude::*;
        (0..count).into_par_iter().map(one).collect()
    };
    if threads == 0 {
        return Ok(work());
    }
    if threads > MAX_THREADS {
        return Err(SoftrodError::invalid(
            "threads",
            threads,
            format!("must be in 0..={MAX_THREADS} (0 = all cores)"),
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

/// Most worker threads a batch may ask for.
pub const MAX_THREADS: usize = 1024;

/// Solve for every row of the inputs (pressures and tensions, row-major). `threads = 0`
/// uses all cores.
pub fn solve_batch(
    rod: &Rod,
    inputs: &BatchInputs,
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    let rows = Rows::new(rod, opts, inputs, None)?;
    rows.run(rod, opts, threads, &|_, _, _| {})
}

/// [`solve_batch`] plus the positions of `markers` on every converged row and the exact
/// derivatives of its tip pose and marker positions with respect to `params` (see
/// [`crate::sensitivity`]; with no parameters, the positions only). `guesses`, when given,
/// holds a warm start x (one per unknown per row, e.g. the previous iteration's
/// `BatchRow::x`; NaN rows start cold). A row whose derivatives cannot be formed (a
/// singular shooting or collocation Jacobian: a limit point) is reported failed; failed
/// rows have NaN marker positions.
pub fn sensitivity_batch(
    rod: &Rod,
    inputs: &BatchInputs,
    guesses: Option<&[f64]>,
    params: &[Param],
    markers: &[Marker],
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    validate_params(rod, params)?;
    let located = locate_markers(rod, markers)?;
    let rows = Rows::new(rod, opts, inputs, guesses)?;
    let n = rows.unknowns;
    let mut out = rows.run(rod, opts, threads, &|loads, sol, row| {
        if params.is_empty() {
            row.markers = marker_positions(rod, loads, sol, &located);
            return;
        }
        match pose_sensitivity(rod, loads, sol, params, &located) {
            Ok(s) => {
                row.markers = marker_positions(rod, loads, sol, &located);
                row.sensitivity = Some(s);
            }
            Err(_) => *row = BatchRow::failed(n, sol.iterations, sol.residual),
        }
    })?;
    for row in out.iter_mut().filter(|r| !r.converged) {
        row.markers = vec![[f64::NAN; 3]; markers.len()];
    }
    Ok(out)
}

/// [`solve_batch`] with the tip held by `constraint` (docs/model.md, "End constraints"):
/// every row is solved exactly as [`solve_constrained`] solves it alone, cold (the free
/// equilibrium first, then the tip moved to the prescribed pose, else the loads ramped with
/// the pose), so a row is bitwise equal to the single solve whatever the thread count or the
/// grouping of rows. Every row has 6 unknowns (`x`) and its tip reaction; a pinned or
/// clamped tip's stability is assessed as in the single solve. A free `constraint` is
/// [`solve_batch`] (zero reactions). The constraint, the inputs and (with
/// `Policy::Raise`) the operating range are checked before any work.
pub fn solve_constrained_batch(
    rod: &Rod,
    inputs: &BatchInputs,
    constraint: &TipConstraint,
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    constraint.validate()?;
    if let TipConstraint::Free = constraint {
        return solve_batch(rod, inputs, opts, threads);
    }
    let mut rows = Rows::new(rod, opts, inputs, None)?;
    rows.unknowns = 6;
    let rows = &rows;
    in_pool(threads, rows.count, &|r| match solve_constrained(
        rod,
        &rows.loads(r),
        constraint,
        None,
        opts,
    ) {
        Ok(c) => BatchRow::held(&c),
        Err(e) => BatchRow::of_error(6, &e),
    })
}

/// [`solve_batch`] of a rod whose obstacles have friction (docs/contact.md, "Friction in
/// the statics"): every row follows its own load path from the unloaded rod to its inputs
/// in `steps` equal increments, exactly as [`friction::solve`] solves it alone (same
/// increments, same halvings; no history, no warm start: no row starts from another's
/// solution or state), so a row is bitwise equal to the single solve whatever the thread
/// count or the grouping of rows. Every row has 6 unknowns (`x`), `stable` None (friction
/// has no potential), and each obstacle's contact force and its friction part
/// (`contact_force`, `friction_force`, as `statics::contact::report` gives them). A row
/// that fails (an increment that does not converge even halved, an obstacle crossed, a
/// broken validity rule) is kept failed as in [`solve_batch`]. `steps`, the inputs and
/// (with `Policy::Raise`) the operating range are checked before any work; a design
/// without friction is refused (`solve_batch` solves it).
pub fn solve_friction_batch(
    rod: &Rod,
    inputs: &BatchInputs,
    steps: usize,
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    friction_rows(rod, inputs, steps, opts, threads, &|loads| {
        friction::solve(rod, loads, None, steps, opts).map(|sol| (BatchRow::solved(&sol), sol))
    })
}

/// [`solve_friction_batch`] with the tip held by `constraint` (pinned or clamped): every
/// row is one [`friction::solve_held`] from the unloaded rod, its held pose moved along
/// the row's path, bitwise the single held frictional solve; rows carry their tip
/// reactions as in [`solve_constrained_batch`] and each obstacle's contact and friction
/// force. A free `constraint` is [`solve_friction_batch`].
pub fn solve_held_friction_batch(
    rod: &Rod,
    inputs: &BatchInputs,
    constraint: &TipConstraint,
    steps: usize,
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    constraint.validate()?;
    if let TipConstraint::Free = constraint {
        return solve_friction_batch(rod, inputs, steps, opts, threads);
    }
    friction_rows(rod, inputs, steps, opts, threads, &|loads| {
        friction::solve_held(rod, loads, constraint, None, steps, opts)
            .map(|c| (BatchRow::held(&c), c.solution))
    })
}

/// The frictional batches' rows: inputs and `steps` checked before any work, then every
/// row solved by `solve_row` (one load path, cold) with the single solve's contact report
/// (`softrod.solve_statics`'s), failed rows kept as in [`solve_batch`].
fn friction_rows(
    rod: &Rod,
    inputs: &BatchInputs,
    steps: usize,
    opts: &SolverOptions,
    threads: usize,
    solve_row: &(dyn Fn(&Loads) -> Result<(BatchRow, Solution)> + Sync),
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    friction::check_steps(steps)?;
    if !friction::has_friction(rod) {
        return Err(SoftrodError::invalid(
            "obstacles",
            "no friction",
            "the frictional batch follows a load path per row for obstacles with friction > 0; this design has none (solve_batch solves it)",
        ));
    }
    let mut rows = Rows::any_friction(rod, opts, inputs, None)?;
    rows.unknowns = 6;
    let rows = &rows;
    let k = rod.spec.obstacles.len();
    in_pool(threads, rows.count, &|r| {
        let loads = rows.loads(r);
        let solved = solve_row(&loads).and_then(|(row, sol)| {
            let rep = crate::statics::contact::report(rod, &loads, &sol)?;
            Ok((row, rep))
        });
        match solved {
            Ok((row, rep)) => {
                // A frictional rod has obstacles, so its report is there.
                let (contact_force, friction_force) =
                    rep.map_or_else(Default::default, |c| (c.force, c.friction));
                BatchRow {
                    contact_force,
                    friction_force,
                    ..row
                }
            }
            Err(e) => BatchRow {
                contact_force: vec![[f64::NAN; 3]; k],
                friction_force: vec![[f64::NAN; 3]; k],
                ..BatchRow::of_error(6, &e)
            },
        }
    })
}

/// [`sensitivity_batch`] with the tip held by `constraint`: every row is solved exactly as
/// [`solve_constrained_batch`] solves it (one [`solve_constrained`], cold; or from the
/// row's own warm start in `guesses`, 6 per row, NaN rows cold, as a single
/// [`solve_constrained`] with that guess), so a row is bitwise equal to the single solve;
/// then the marker positions and the exact derivatives of the tip pose and the markers
/// with respect to `params` ([`constrained_pose_sensitivity`]). Rows carry their tip
/// reaction. A row whose derivatives cannot be formed (singular Jacobian) is reported
/// failed; failed rows have NaN marker positions. A free `constraint` is
/// [`sensitivity_batch`].
#[allow(clippy::too_many_arguments)]
pub fn constrained_sensitivity_batch(
    rod: &Rod,
    inputs: &BatchInputs,
    constraint: &TipConstraint,
    guesses: Option<&[f64]>,
    params: &[Param],
    markers: &[Marker],
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    constraint.validate()?;
    if let TipConstraint::Free = constraint {
        return sensitivity_batch(rod, inputs, guesses, params, markers, opts, threads);
    }
    validate_params(rod, params)?;
    let located = locate_markers(rod, markers)?;
    let mut rows = Rows::new(rod, opts, inputs, None)?;
    rows.unknowns = 6;
    if let Some(g) = guesses {
        if g.len() != 6 * rows.count {
            return Err(SoftrodError::invalid(
                "x0",
                format!("{} values", g.len()),
                format!(
                    "must be an ({}, 6) array: a held tip has 6 unknowns for every input row",
                    rows.count
                ),
            ));
        }
        rows.guesses = Some(g);
    }
    let rows = &rows;
    in_pool(threads, rows.count, &|r| {
        let loads = rows.loads(r);
        let c = match solve_constrained(rod, &loads, constraint, rows.guess(r), opts) {
            Ok(c) => c,
            Err(e) => {
                return BatchRow {
                    markers: vec![[f64::NAN; 3]; markers.len()],
                    ..BatchRow::of_error(6, &e)
                }
            }
        };
        let mut row = BatchRow::held(&c);
        row.markers = marker_positions(rod, &loads, &c.solution, &located);
        if params.is_empty() {
            return row;
        }
        match constrained_pose_sensitivity(rod, &loads, constraint, &c.solution, params, &located) {
            Ok(s) => row.sensitivity = Some(s),
            Err(_) => {
                row = BatchRow {
                    markers: vec![[f64::NAN; 3]; markers.len()],
                    ..BatchRow::failed(6, c.solution.iterations, c.solution.residual)
                }
            }
        }
        row
    })
}

/// One row of a system batch ([`solve_system_batch`]). Failed rows are kept, with
/// `converged = false` and NaNs.
#[derive(Debug, Clone, PartialEq)]
pub struct SystemBatchRow {
    pub converged: bool,
    /// Per rod: its tip pose, base wrench, 6 unknowns, the wrench the platform applies to
    /// its tip (`tip_reaction_*`), its obstacles' contact and friction forces
    /// (`contact_force`, `friction_force`: one per obstacle, NaN on a failed row, empty
    /// without obstacles) and the validity rule it broke under `Policy::Warn` (`stable`:
    /// the whole system's, as `stable` below).
    pub rods: Vec<BatchRow>,
    /// The system's equilibrium is stable (`SystemSolution::stable`); None where not
    /// assessed or the row failed.
    pub stable: Option<bool>,
    pub platform_position: [f64; 3],
    pub platform_rotation: [[f64; 3]; 3],
    /// The system's unknowns (6 per rod, then the platform's 6); a warm start.
    pub x: Vec<f64>,
    pub iterations: usize,
    pub residual: f64,
    pub load_steps: usize,
    /// Marker positions, world frame ([`system_sensitivity_batch`] only; NaN on failed
    /// rows).
    pub markers: Vec<[f64; 3]>,
    /// The platform pose's and the markers' derivatives with respect to the parameters
    /// ([`system_sensitivity_batch`] with parameters, converged rows only).
    pub sensitivity: Option<SystemSensitivity>,
    /// The first validity rule a rod broke (a failed row, or a returned one under
    /// `Policy::Warn`), "rods[i]: ..." where the rod is known, else empty.
    pub violation: String,
}

impl SystemBatchRow {
    fn solved(s: &SystemSolution) -> Self {
        let rods: Vec<BatchRow> = s.rods.iter().map(BatchRow::held).collect();
        let violation = rods
            .iter()
            .enumerate()
            .find(|(_, r)| !r.violation.is_empty())
            .map(|(i, r)| format!("rods[{i}]: {}", r.violation))
            .unwrap_or_default();
        SystemBatchRow {
            converged: true,
            rods,
            stable: s.stable,
            platform_position: s.platform_position,
            platform_rotation: s.platform_rotation,
            x: s.x.clone(),
            iterations: s.iterations,
            residual: s.residual,
            load_steps: s.load_steps,
            markers: vec![],
            sensitivity: None,
            violation,
        }
    }

    fn failed(n_rods: usize, e: &SoftrodError) -> Self {
        let first = BatchRow::of_error(6, e);
        let rod = || BatchRow {
            stable: None,
            ..BatchRow::failed(6, 0, f64::NAN)
        };
        SystemBatchRow {
            converged: false,
            rods: (0..n_rods).map(|_| rod()).collect(),
            stable: None,
            platform_position: [f64::NAN; 3],
            platform_rotation: [[f64::NAN; 3]; 3],
            x: vec![f64::NAN; 6 * n_rods + 6],
            iterations: first.iterations,
            residual: first.residual,
            load_steps: 0,
            markers: vec![],
            sensitivity: None,
            violation: first.violation,
        }
    }
}

/// The rows of a system batch: the inputs checked against the rods (their shapes, then
/// every row's loads against each rod's rules), and each row's rods with their loads.
struct SystemRows<'r, 'a> {
    rods: &'r [SystemRod<'a>],
    inputs: &'r SystemBatchInputs<'r>,
    /// Channels and tendon channels per rod, and their offsets in a row.
    nc: Vec<usize>,
    nt: Vec<usize>,
    oc: Vec<usize>,
    ot: Vec<usize>,
    count: usize,
}

impl<'r, 'a> SystemRows<'r, 'a> {
    fn new(
        rods: &'r [SystemRod<'a>],
        inputs: &'r SystemBatchInputs<'r>,
        frictional: bool,
        opts: &SolverOptions,
    ) -> Result<Self> {
        let nc: Vec<usize> = rods.iter().map(|r| r.rod.n_channels).collect();
        let nt: Vec<usize> = rods.iter().map(|r| r.rod.n_tendons).collect();
        let (wc, wt) = (nc.iter().sum::<usize>(), nt.iter().sum::<usize>());
        let given = inputs.pressures.len();
        let count = if wc > 0 {
            if given % wc != 0 {
                return Err(SoftrodError::invalid(
                    "pressures",
                    format!("{given} values"),
                    format!(
                        "must be an (m, {wc}) array: each row every rod's gauge pressures, rod \
                         after rod ({nc:?} channels)"
                    ),
                ));
            }
            given / wc
        } else {
            if given != 0 {
                return Err(SoftrodError::invalid(
                    "pressures",
                    format!("{given} values"),
                    "the system's rods have no pressure channels: give an (m, 0) array",
                ));
            }
            let t = inputs.tensions.map_or(0, <[f64]>::len);
            if wt == 0 || t % wt != 0 {
                return Err(SoftrodError::invalid(
                    "tensions",
                    format!("{t} values"),
                    format!(
                        "the system's rods have no pressure channels: give an (m, {wt}) array \
                         of tensions, rod after rod"
                    ),
                ));
            }
            t / wt
        };
        if let Some(t) = inputs.tensions {
            if t.len() != count * wt {
                return Err(SoftrodError::invalid(
                    "tensions",
                    format!("{} values", t.len()),
                    format!(
                        "must be an ({count}, {wt}) array: each row every rod's tendon tensions, \
                         rod after rod ({nt:?} tendon channels)"
                    ),
                ));
            }
        }
        let offsets = |w: &[usize]| -> Vec<usize> {
            w.iter()
                .scan(0, |acc, k| {
                    let o = *acc;
                    *acc += k;
                    Some(o)
                })
                .collect()
        };
        let n = rods.len();
        match inputs.stiffness_scale {
            Some(s) if s.len() != count * n * 3 => {
                return Err(SoftrodError::invalid(
                    "stiffness_scale",
                    format!("{} values", s.len()),
                    format!("must be an ({count}, {n}, 3) array: every row's sigma of every rod"),
                ));
            }
            Some(_) => {}
            None => {
                for (i, sr) in rods.iter().enumerate() {
                    crate::statics::system::rod_sigma(i, sr.rod, None)?;
                }
            }
        }
        let (oc, ot) = (offsets(&nc), offsets(&nt));
        let rows = SystemRows {
            rods,
            inputs,
            nc,
            nt,
            oc,
            ot,
            count,
        };
        let check = if frictional {
            crate::statics::check_inputs_any_friction
        } else {
            crate::statics::check_inputs
        };
        for r in 0..rows.count {
            for (i, sr) in rows.rods(r).iter().enumerate() {
                check(sr.rod, &sr.loads, opts).map_err(|e| in_row(r, &format!("rods[{i}]."), e))?;
            }
        }
        Ok(rows)
    }

    /// Row r's rods with their loads: the row's pressures, tensions and sigma.
    fn rods(&self, r: usize) -> Vec<SystemRod<'a>> {
        let (wc, wt) = (self.nc.iter().sum::<usize>(), self.nt.iter().sum::<usize>());
        self.rods
            .iter()
            .enumerate()
            .map(|(i, sr)| {
                let (oc, nc) = (self.oc[i], self.nc[i]);
                let p = &self.inputs.pressures[r * wc + oc..r * wc + oc + nc];
                let t = match self.inputs.tensions {
                    Some(t) => t[r * wt + self.ot[i]..r * wt + self.ot[i] + self.nt[i]].to_vec(),
                    None => vec![0.0; self.nt[i]],
                };
                let k = 3 * (r * self.rods.len() + i);
                let sigma = self
                    .inputs
                    .stiffness_scale
                    .map_or([1.0; 3], |s| [s[k], s[k + 1], s[k + 2]]);
                SystemRod {
                    loads: Loads {
                        pressures: p.to_vec(),
                        tensions: t,
                        stiffness_scale: sigma,
                        ..sr.loads.clone()
                    },
                    ..sr.clone()
                }
            })
            .collect()
    }
}

/// The per-row inputs of a system batch: every rod's pressures, then every rod's tensions,
/// each row the rods' values one after the other (row-major), and every rod's stiffness
/// scale.
#[derive(Debug, Clone, Copy)]
pub struct SystemBatchInputs<'a> {
    /// (m, sum of the rods' channels) gauge pressures, Pa: rod 0's channels, then rod 1's...
    pub pressures: &'a [f64],
    /// (m, sum of the rods' tendon channels) tensions, N; None: every tendon slack.
    pub tensions: Option<&'a [f64]>,
    /// (m, n_rods, 3) stiffness scaling factors sigma (paper 001, eq. 13) of every row and
    /// rod, each finite and > 0 (a rod without stiffness-mapped sections ignores its
    /// entries). None: 1, which only a system without mapped sections accepts (sigma is
    /// never assumed to be 1: a rod with a mapped section is refused).
    pub stiffness_scale: Option<&'a [f64]>,
}

impl<'a> SystemBatchInputs<'a> {
    /// Pressures only: slack tendons, no stiffness scale.
    pub fn pressures(pressures: &'a [f64]) -> Self {
        SystemBatchInputs {
            pressures,
            tensions: None,
            stiffness_scale: None,
        }
    }
}

/// Solve the system of `rods` holding `platform` for every row of `inputs` (each row one
/// equilibrium of the whole system; the rods' other loads and the platform's are shared):
/// every row is solved exactly as [`solve_system`] solves it alone, cold, so a row is
/// bitwise equal to the single solve whatever the thread count or the grouping of rows.
/// Where some rod's obstacle has friction, every row is one [`solve_system_friction`]
/// from the unloaded rods in `friction_steps` increments (its own load path; checked in
/// 1..=`friction::MAX_FRICTION_STEPS` then, unused otherwise).
/// Each row's rods take their sigma from `inputs.stiffness_scale` (a rod with a
/// stiffness-mapped section needs it). The system, the inputs and (with `Policy::Raise`)
/// the rods' operating ranges are checked before any work; an input error names the row
/// and the rod ("row 3: rods[1].pressures[0]", "row 2: rods[0].stiffness_scale[1]").
pub fn solve_system_batch(
    rods: &[SystemRod],
    platform: &Platform,
    inputs: &SystemBatchInputs,
    friction_steps: usize,
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<SystemBatchRow>> {
    opts.validate()?;
    crate::statics::system::validate(rods, platform)?;
    let frictional = rods.iter().any(|r| friction::has_friction(r.rod));
    if frictional {
        friction::check_steps(friction_steps)?;
    }
    let rows = SystemRows::new(rods, inputs, frictional, opts)?;
    let solve = |rods: &[SystemRod]| {
        if frictional {
            solve_system_friction(rods, platform, None, friction_steps, opts)
        } else {
            solve_system(rods, platform, None, opts)
        }
    };
    in_pool(threads, rows.count, &|r| {
        let row_rods = rows.rods(r);
        system_row(&row_rods, solve(&row_rods)).0
    })
}

/// A system batch row from one row's solve (`row_rods`: the rods with the row's loads):
/// the solution with each rod's contact report (`statics::contact::report`, as
/// `solve_system` gives it; NaN on a failed row), and the solution itself; or the failure.
fn system_row(
    row_rods: &[SystemRod],
    solved: Result<SystemSolution>,
) -> (SystemBatchRow, Option<SystemSolution>) {
    let reported = solved.and_then(|s| {
        let reports = row_rods
            .iter()
            .zip(&s.rods)
            .map(|(sr, c)| crate::statics::contact::report(sr.rod, &sr.loads, &c.solution))
            .collect::<Result<Vec<_>>>()?;
        Ok((s, reports))
    });
    let (mut row, reports, sol) = match reported {
        Ok((s, reports)) => (SystemBatchRow::solved(&s), Some(reports), Some(s)),
        Err(e) => (SystemBatchRow::failed(row_rods.len(), &e), None, None),
    };
    for (i, (b, sr)) in row.rods.iter_mut().zip(row_rods).enumerate() {
        let k = sr.rod.spec.obstacles.len();
        if k == 0 {
            continue;
        }
        match reports.as_ref().and_then(|r| r[i].as_ref()) {
            Some(rep) => {
                b.contact_force = rep.force.clone();
                b.friction_force = rep.friction.clone();
            }
            None => {
                b.contact_force = vec![[f64::NAN; 3]; k];
                b.friction_force = vec![[f64::NAN; 3]; k];
            }
        }
    }
    (row, sol)
}

/// [`solve_system_batch`] plus, on every converged row, the markers' positions and the
/// exact derivatives of the platform's pose and of the markers with respect to `params`
/// (`sensitivity::system`), for calibrating a system. Every row is solved exactly as
/// [`solve_system`] solves it alone from its warm start (`guesses`: an (m, 6n+6) array of
/// previous rows' `x`, a row with a NaN starting cold; None: every row cold), so a row is
/// bitwise the single solve. A system with friction is refused (its equilibria depend on
/// the load path). A row whose derivatives are undefined (a singular Jacobian) fails.
/// Markers are NaN on failed rows.
#[allow(clippy::too_many_arguments)]
pub fn system_sensitivity_batch(
    rods: &[SystemRod],
    platform: &Platform,
    inputs: &SystemBatchInputs,
    guesses: Option<&[f64]>,
    params: &[SystemParam],
    markers: &[SystemMarker],
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<SystemBatchRow>> {
    opts.validate()?;
    crate::statics::system::validate(rods, platform)?;
    if let Some(i) = rods.iter().position(|r| friction::has_friction(r.rod)) {
        return Err(SoftrodError::invalid(
            format!("rods[{i}]"),
            "an obstacle with friction > 0",
            "friction makes a system's equilibrium depend on its load path, so its parameter derivatives are not defined at one point: calibrate with frictionless obstacles",
        ));
    }
    validate_system_params(rods, params)?;
    let located = locate_system_markers(rods, markers)?;
    let rows = SystemRows::new(rods, inputs, false, opts)?;
    let dim = 6 * rods.len() + 6;
    if let Some(g) = guesses {
        if g.len() != rows.count * dim {
            return Err(SoftrodError::invalid(
                "x0",
                format!("{} values", g.len()),
                format!(
                    "must be an ({}, {dim}) array: a system's unknowns (6 per rod and the \
                     platform's 6) for every input row",
                    rows.count
                ),
            ));
        }
    }
    in_pool(threads, rows.count, &|r| {
        let row_rods = rows.rods(r);
        let guess = guesses
            .map(|g| &g[r * dim..(r + 1) * dim])
            .filter(|g| g.iter().all(|v| v.is_finite()));
        let (mut row, sol) = system_row(&row_rods, solve_system(&row_rods, platform, guess, opts));
        let lost = |n: usize| vec![[f64::NAN; 3]; n];
        let Some(sol) = sol else {
            row.markers = lost(markers.len());
            return row;
        };
        let derived = system_marker_positions(&row_rods, &sol, &located).and_then(|at| {
            let sens = if params.is_empty() {
                None
            } else {
                Some(system_sensitivity(
                    &row_rods, platform, &sol, params, &located,
                )?)
            };
            Ok((at, sens))
        });
        match derived {
            Ok((at, sens)) => {
                row.markers = at;
                row.sensitivity = sens;
            }
            Err(e) => {
                row = SystemBatchRow::failed(rods.len(), &e);
                row.markers = lost(markers.len());
            }
        }
        row
    })
}
