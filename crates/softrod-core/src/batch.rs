//! Many static solves in parallel (rayon), warm-starting each solve from its neighbour.

use crate::error::{Result, SoftrodError};
use crate::ode::Loads;
use crate::rod::Rod;
use crate::statics::{solve, SolverOptions};

/// One row of a batch result. Failed rows are kept, with `converged = false` and NaNs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatchRow {
    pub converged: bool,
    pub tip_position: [f64; 3],
    pub tip_rotation: [[f64; 3]; 3],
    pub base_force: [f64; 3],
    pub base_moment: [f64; 3],
    pub iterations: usize,
    pub residual: f64,
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
        }
    }
}

/// Solve for every row of `pressures` (row-major, `n_channels` per row). Rows are split
/// into contiguous chunks; inside a chunk each solve starts from the previous row's
/// solution, so ordered sweeps (grids, ramps) converge in few iterations. `threads = 0`
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
    let nc = rod.n_channels;
    let rows = pressures.len().checked_div(nc).unwrap_or(0);
    if nc == 0 || pressures.len() % nc != 0 {
        return Err(SoftrodError::invalid(
            "pressures",
            format!("{} values", pressures.len()),
            format!("must be an (m, {nc}) array: one gauge pressure per channel per row"),
        ));
    }
    if let Some(s) = stiffness_scale {
        if s.len() != 3 * rows {
            return Err(SoftrodError::invalid(
                "stiffness_scale",
                format!("{} values", s.len()),
                format!("must be an ({rows}, 3) array: sigma for every pressure row"),
            ));
        }
    }
    let sigma = |r: usize| -> [f64; 3] {
        match stiffness_scale {
            Some(s) => [s[3 * r], s[3 * r + 1], s[3 * r + 2]],
            None => [1.0; 3],
        }
    };
    for r in 0..rows {
        rod.check_loads(&pressures[r * nc..(r + 1) * nc], &sigma(r))
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
    let run = || -> Vec<BatchRow> {
        use rayon::prelude::*;
        let n_threads = rayon::current_num_threads().max(1);
        // Enough chunks to balance load, few enough that warm starts dominate.
        let chunk = rows.div_ceil(8 * n_threads).max(1);
        let mut out = vec![BatchRow::failed(0, f64::NAN); rows];
        out.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(ci, slot)| {
                let mut guess: Option<[f64; 3]> = None;
                for (k, row) in slot.iter_mut().enumerate() {
                    let r = ci * chunk + k;
                    let loads = Loads {
                        pressures: pressures[r * nc..(r + 1) * nc].to_vec(),
                        tip_force,
                        tip_moment,
                        stiffness_scale: sigma(r),
                    };
                    let mut attempt = solve(rod, &loads, guess.as_ref(), opts);
                    if attempt.is_err() && guess.is_some() {
                        attempt = solve(rod, &loads, None, opts); // cold retry
                    }
                    *row = match attempt {
                        Ok(sol) => {
                            guess = Some(sol.x);
                            BatchRow {
                                converged: true,
                                tip_position: sol.tip.r,
                                tip_rotation: sol.tip.rot,
                                base_force: sol.base_force,
                                base_moment: sol.base_moment,
                                iterations: sol.iterations,
                                residual: sol.residual,
                            }
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
        Ok(run())
    } else {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| {
                SoftrodError::invalid("threads", threads, format!("cannot build thread pool: {e}"))
            })?;
        Ok(pool.install(run))
    }
}
