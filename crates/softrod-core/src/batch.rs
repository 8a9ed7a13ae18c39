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
        let template = Loads {
            pressures: vec![],
            tensions: vec![],
            tip_force: inputs.tip_force,
            tip_moment: inputs.tip_moment,
            tip_frame: rod.spec.tip.frame,
            stiffness_scale: [1.0; 3],
        };
        let unknowns = n_unknowns(rod, &template);
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
        let work = || -> Vec<BatchRow> {
            use rayon::prelude::*;
            (0..self.count)
                .into_par_iter()
                .map(|r| {
                    let loads = Loads {
                        pressures: self.pressures(r).to_vec(),
                        tensions: self.tensions(r),
                        stiffness_scale: self.sigma(r),
                        ..self.template.clone()
                    };
                    match solve(rod, &loads, self.guess(r), opts) {
                        Ok(sol) => {
                            let mut row = BatchRow::solved(&sol);
                            after(&loads, &sol, &mut row);
                            row
                        }
                        Err(SoftrodError::NotConverged {
                            iterations,
                            residual,
                            ..
                        }) => BatchRow::failed(n, iterations, residual),
                        Err(e @ SoftrodError::InvalidState { .. }) => BatchRow {
                            violation: e.to_string(),
                            ..BatchRow::failed(n, 0, f64::NAN)
                        },
                        Err(_) => BatchRow::failed(n, 0, f64::NAN),
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
/// `BatchRow::x`; NaN rows start cold). A row whose derivatives cannot be formed (singular
/// shooting Jacobian) is reported failed; failed rows have NaN marker positions.
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
