//! Many static solves in parallel (rayon). Every row is solved exactly as [`solve`] solves
//! it alone from the same start (cold, or the row's own warm start), so a batch row is
//! bitwise equal to the single solve, whatever the thread count or the order of the rows.

use crate::error::{Result, SoftrodError};
use crate::ode::Loads;
use crate::rod::Rod;
use crate::sensitivity::{
    locate_markers, marker_positions, pose_sensitivity, validate_params, Marker, Param,
    TipSensitivity,
};
use crate::statics::{solve, Solution, SolverOptions};
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
    /// Scaled shooting unknowns (a warm start for a later solve of this row).
    pub x: [f64; 3],
    /// The equilibrium is stable (false on failed rows).
    pub stable: bool,
    /// The validity rule the row broke (a failed row under `Policy::Raise`, or a returned
    /// one under `Policy::Warn`), else empty.
    pub violation: String,
    /// Tip-pose (and marker) derivatives with respect to the parameters
    /// ([`sensitivity_batch`] only).
    pub sensitivity: Option<TipSensitivity>,
    /// Marker positions, world frame ([`sensitivity_batch`] with markers; NaN on failed
    /// rows).
    pub markers: Vec<[f64; 3]>,
}

impl BatchRow {
    fn failed(iterations: usize, residual: f64) -> Self {
        BatchRow {
            stable: false,
            violation: String::new(),
            converged: false,
            tip_position: [f64::NAN; 3],
            tip_rotation: [[f64::NAN; 3]; 3],
            base_force: [f64::NAN; 3],
            base_moment: [f64::NAN; 3],
            iterations,
            residual,
            x: [f64::NAN; 3],
            sensitivity: None,
            markers: vec![],
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
            x: sol.x,
            stable: sol.stable,
            violation: sol
                .violations
                .first()
                .map(|e| e.to_string())
                .unwrap_or_default(),
            sensitivity: None,
            markers: vec![],
        }
    }
}

/// The rows of a batch: pressures (row-major, `n_channels` per row), optional sigma
/// (3 per row) and optional warm starts (3 per row), all checked up front.
struct Rows<'a> {
    nc: usize,
    count: usize,
    pressures: &'a [f64],
    stiffness_scale: Option<&'a [f64]>,
    guesses: Option<&'a [f64]>,
}

impl<'a> Rows<'a> {
    fn new(
        rod: &Rod,
        opts: &SolverOptions,
        pressures: &'a [f64],
        stiffness_scale: Option<&'a [f64]>,
        guesses: Option<&'a [f64]>,
    ) -> Result<Self> {
        let nc = rod.n_channels;
        let count = pressures.len().checked_div(nc).unwrap_or(0);
        if nc == 0 || pressures.len() % nc != 0 {
            return Err(SoftrodError::invalid(
                "pressures",
                format!("{} values", pressures.len()),
                format!("must be an (m, {nc}) array: one gauge pressure per channel per row"),
            ));
        }
        for (name, v) in [("stiffness_scale", stiffness_scale), ("x0", guesses)] {
            if let Some(s) = v {
                if s.len() != 3 * count {
                    return Err(SoftrodError::invalid(
                        name,
                        format!("{} values", s.len()),
                        format!("must be an ({count}, 3) array: 3 values for every pressure row"),
                    ));
                }
            }
        }
        let rows = Rows {
            nc,
            count,
            pressures,
            stiffness_scale,
            guesses,
        };
        let range = rod
            .spec
            .operating_range
            .filter(|_| opts.on_invalid == Policy::Raise);
        for r in 0..count {
            rod.check_loads(rows.pressures(r), &rows.sigma(r))
                .and_then(|()| match range {
                    Some(range) => {
                        validity::check_operating_range(rows.pressures(r), range.pressure)
                    }
                    None => Ok(()),
                })
                .map_err(|e| match e {
                    SoftrodError::InvalidParameter { field, value, rule } => {
                        SoftrodError::InvalidParameter {
                            field: format!("row {r}: {field}"),
                            value,
                            rule,
                        }
                    }
                    SoftrodError::InvalidState {
                        rule,
                        node,
                        s,
                        time,
                        value,
                        message,
                    } => SoftrodError::InvalidState {
                        rule,
                        node,
                        s,
                        time,
                        value,
                        message: format!("row {r}: {message}"),
                    },
                    other => other,
                })?;
        }
        Ok(rows)
    }

    fn pressures(&self, r: usize) -> &[f64] {
        &self.pressures[r * self.nc..(r + 1) * self.nc]
    }

    fn sigma(&self, r: usize) -> [f64; 3] {
        self.stiffness_scale
            .map_or([1.0; 3], |s| [s[3 * r], s[3 * r + 1], s[3 * r + 2]])
    }

    fn guess(&self, r: usize) -> Option<[f64; 3]> {
        self.guesses
            .map(|g| [g[3 * r], g[3 * r + 1], g[3 * r + 2]])
            .filter(|g| g.iter().all(|v| v.is_finite()))
    }

    /// Solve every row (from its own warm start, else cold), then apply `after` to each
    /// converged one, in parallel. Rows are independent: no row starts from another's
    /// solution, so the result does not depend on how rows are shared among threads.
    fn run(
        &self,
        rod: &Rod,
        tip_force: [f64; 3],
        tip_moment: [f64; 3],
        opts: &SolverOptions,
        threads: usize,
        after: &(dyn Fn(&Loads, &Solution, &mut BatchRow) + Sync),
    ) -> Result<Vec<BatchRow>> {
        let work = || -> Vec<BatchRow> {
            use rayon::prelude::*;
            (0..self.count)
                .into_par_iter()
                .map(|r| {
                    let loads = Loads {
                        pressures: self.pressures(r).to_vec(),
                        tip_force,
                        tip_moment,
                        stiffness_scale: self.sigma(r),
                    };
                    match solve(rod, &loads, self.guess(r).as_ref(), opts) {
                        Ok(sol) => {
                            let mut row = BatchRow::solved(&sol);
                            after(&loads, &sol, &mut row);
                            row
                        }
                        Err(SoftrodError::NotConverged {
                            iterations,
                            residual,
                            ..
                        }) => BatchRow::failed(iterations, residual),
                        Err(e @ SoftrodError::InvalidState { .. }) => BatchRow {
                            violation: e.to_string(),
                            ..BatchRow::failed(0, f64::NAN)
                        },
                        Err(_) => BatchRow::failed(0, f64::NAN),
                    }
                })
                .collect()
        };
        if threads == 0 {
            Ok(work())
        } else {
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
                    SoftrodError::invalid(
                        "threads",
                        threads,
                        format!("cannot build thread pool: {e}"),
                    )
                })?;
            Ok(pool.install(work))
        }
    }
}

/// Most worker threads a batch may ask for.
pub const MAX_THREADS: usize = 1024;

/// Solve for every row of `pressures` (row-major, `n_channels` per row). `threads = 0`
/// uses all cores. `stiffness_scale`, when given, holds sigma (3 per row, row-major) for
/// the sections with a stiffness map.
pub fn solve_batch(
    rod: &Rod,
    pressures: &[f64],
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    stiffness_scale: Option<&[f64]>,
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    let rows = Rows::new(rod, opts, pressures, stiffness_scale, None)?;
    rows.run(rod, tip_force, tip_moment, opts, threads, &|_, _, _| {})
}

/// [`solve_batch`] plus the positions of `markers` on every converged row and the exact
/// derivatives of its tip pose and marker positions with respect to `params` (see
/// [`crate::sensitivity`]; with no parameters, the positions only). `guesses`, when given,
/// holds a warm start x (3 per row, e.g. the previous iteration's `BatchRow::x`; NaN rows
/// start cold). A row whose derivatives cannot be formed (singular shooting Jacobian) is
/// reported failed; failed rows have NaN marker positions.
#[allow(clippy::too_many_arguments)]
pub fn sensitivity_batch(
    rod: &Rod,
    pressures: &[f64],
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    stiffness_scale: Option<&[f64]>,
    guesses: Option<&[f64]>,
    params: &[Param],
    markers: &[Marker],
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    validate_params(rod, params)?;
    let located = locate_markers(rod, markers)?;
    let rows = Rows::new(rod, opts, pressures, stiffness_scale, guesses)?;
    let mut out = rows.run(
        rod,
        tip_force,
        tip_moment,
        opts,
        threads,
        &|loads, sol, row| {
            if params.is_empty() {
                row.markers = marker_positions(rod, loads, sol, &located);
                return;
            }
            match pose_sensitivity(rod, loads, sol, params, &located) {
                Ok(s) => {
                    row.markers = marker_positions(rod, loads, sol, &located);
                    row.sensitivity = Some(s);
                }
                Err(_) => *row = BatchRow::failed(sol.iterations, sol.residual),
            }
        },
    )?;
    for row in out.iter_mut().filter(|r| !r.converged) {
        row.markers = vec![[f64::NAN; 3]; markers.len()];
    }
    Ok(out)
}
