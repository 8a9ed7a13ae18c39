//! Many static solves in parallel (rayon), warm-starting each solve from its neighbour.

use crate::error::{Result, SoftrodError};
use crate::ode::Loads;
use crate::rod::Rod;
use crate::sensitivity::{tip_sensitivity, validate_params, Param, TipSensitivity};
use crate::statics::{solve, Solution, SolverOptions};

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
    /// Tip-pose derivatives with respect to the parameters ([`sensitivity_batch`] only).
    pub sensitivity: Option<TipSensitivity>,
}

impl BatchRow {
    fn failed(iterations: usize, residual: f64) -> Self {
        BatchRow {
            converged: false,
            tip_position: [f64::NAN; 3],
            tip_rotation: [[f64::NAN; 3]; 3],
            base_force: [f64::NAN; 3],
            base_moment: [f64::NAN; 3],
            iterations,
            residual,
            x: [f64::NAN; 3],
            sensitivity: None,
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
            sensitivity: None,
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
        for r in 0..count {
            rod.check_loads(rows.pressures(r), &rows.sigma(r))
                .map_err(|e| match e {
                    SoftrodError::InvalidParameter { field, value, rule } => {
                        SoftrodError::InvalidParameter {
                            field: format!("row {r}: {field}"),
                            value,
                            rule,
                        }
                    }
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

    /// Solve every row, then apply `after` to each converged one, in parallel. Rows are
    /// split into contiguous chunks; inside a chunk a row without its own warm start
    /// starts from the previous row's solution, so ordered sweeps (grids, ramps) converge
    /// in few iterations.
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
            let n_threads = rayon::current_num_threads().max(1);
            // Enough chunks to balance load, few enough that warm starts dominate.
            let chunk = self.count.div_ceil(8 * n_threads).max(1);
            let mut out = vec![BatchRow::failed(0, f64::NAN); self.count];
            out.par_chunks_mut(chunk)
                .enumerate()
                .for_each(|(ci, slot)| {
                    let mut previous: Option<[f64; 3]> = None;
                    for (k, row) in slot.iter_mut().enumerate() {
                        let r = ci * chunk + k;
                        let loads = Loads {
                            pressures: self.pressures(r).to_vec(),
                            tip_force,
                            tip_moment,
                            stiffness_scale: self.sigma(r),
                        };
                        let guess = self.guess(r).or(previous);
                        let mut attempt = solve(rod, &loads, guess.as_ref(), opts);
                        if attempt.is_err() && guess.is_some() {
                            attempt = solve(rod, &loads, None, opts); // cold retry
                        }
                        *row = match attempt {
                            Ok(sol) => {
                                previous = Some(sol.x);
                                let mut row = BatchRow::solved(&sol);
                                after(&loads, &sol, &mut row);
                                row
                            }
                            Err(SoftrodError::NotConverged {
                                iterations,
                                residual,
                                ..
                            }) => BatchRow::failed(iterations, residual),
                            Err(_) => BatchRow::failed(0, f64::NAN),
                        };
                    }
                });
            out
        };
        if threads == 0 {
            Ok(work())
        } else {
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
    let rows = Rows::new(rod, pressures, stiffness_scale, None)?;
    rows.run(rod, tip_force, tip_moment, opts, threads, &|_, _, _| {})
}

/// [`solve_batch`] plus the exact derivatives of every converged tip pose with respect to
/// `params` (see [`crate::sensitivity`]). `guesses`, when given, holds a warm start x
/// (3 per row, e.g. the previous iteration's `BatchRow::x`; NaN rows start cold). A row
/// whose derivatives cannot be formed (singular shooting Jacobian) is reported failed.
#[allow(clippy::too_many_arguments)]
pub fn sensitivity_batch(
    rod: &Rod,
    pressures: &[f64],
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    stiffness_scale: Option<&[f64]>,
    guesses: Option<&[f64]>,
    params: &[Param],
    opts: &SolverOptions,
    threads: usize,
) -> Result<Vec<BatchRow>> {
    opts.validate()?;
    validate_params(rod, params)?;
    let rows = Rows::new(rod, pressures, stiffness_scale, guesses)?;
    rows.run(
        rod,
        tip_force,
        tip_moment,
        opts,
        threads,
        &|loads, sol, row| match tip_sensitivity(rod, loads, sol, params) {
            Ok(s) => row.sensitivity = Some(s),
            Err(_) => *row = BatchRow::failed(sol.iterations, sol.residual),
        },
    )
}
