//! Statics by collocation (`crate::collocation`): the solver for rods whose single
//! shooting is ill-conditioned (long, soft, many-section rods), chosen automatically by
//! `crate::statics` (docs/model.md, "Collocation").

use crate::collocation::{
    force_scale, mat_t_vec, newton, rotation, Evaluated, Grid, NewtonOptions, NewtonStats, Problem,
    SectionModel, TipBody, IM, IN, IQ, NF,
};
use crate::error::{Result, SoftrodError};
use crate::ode::Coeffs;
use crate::rod::Rod;
use crate::statics::SolverOptions;

/// A static equilibrium solved by collocation.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticSolution {
    /// Scaled unknowns (a warm start for a later solve).
    pub z: Vec<f64>,
    pub residual: f64,
    pub iterations: usize,
    pub load_steps: usize,
    pub evaluated: Evaluated,
}

/// Section models of a static solve at load factor `factor` (pressures and gravity scaled
/// by it, as in the shooting solver's continuation).
pub fn static_models(rod: &Rod, loads: &crate::ode::Loads, factor: f64) -> Vec<SectionModel> {
    (0..rod.sections.len())
        .map(|i| {
            let c = Coeffs::build(
                rod,
                i,
                &loads.pressures,
                &loads.tensions,
                &rod.gravity,
                factor,
                &loads.stiffness_scale,
            );
            SectionModel::new(&c, rod.sections[i].rigid, 0.0, [0.0; 3], None, 0.0, 0.0)
        })
        .collect()
}

fn static_tip(rod: &Rod, loads: &crate::ode::Loads, factor: f64) -> TipBody {
    let t = &rod.spec.tip;
    TipBody {
        mass: t.mass,
        com: t.com_offset,
        inertia: [0.0; 3],
        force: loads.tip_force.map(|f| f * factor),
        moment: loads.tip_moment.map(|m| m * factor),
    }
}

/// Static equilibrium by collocation (the dt -> infinity limit of the dynamic
/// discretisation): Newton from `guess` (scaled unknowns of an earlier solution, or None
/// for the straight rod), then, if that fails, load continuation from the unloaded
/// straight rod with a secant predictor, as the shooting solver does.
pub fn solve_static(
    rod: &Rod,
    loads: &crate::ode::Loads,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
) -> Result<StaticSolution> {
    let grid = Grid::new(rod);
    let hist = vec![[0.0; NF]; 2 * grid.len() + 1];
    let nopts = NewtonOptions {
        tol: opts.tol,
        max_iter: opts.max_iter,
    };
    let mut stats = NewtonStats::default();
    fn at<'a>(
        rod: &'a Rod,
        grid: &'a Grid,
        hist: &'a [[f64; NF]],
        loads: &crate::ode::Loads,
        factor: f64,
        models: &'a [SectionModel],
    ) -> Problem<'a> {
        let mut p = Problem::new(rod, grid, models, 0.0, hist, static_tip(rod, loads, factor));
        p.gravity = rod.gravity.map(|g| g * factor);
        p
    }
    let full_models = static_models(rod, loads, 1.0);
    let full = at(rod, &grid, &hist, loads, 1.0, &full_models);
    let mut z = match guess {
        Some(g) if g.len() == grid.unknowns() && g.iter().all(|x| x.is_finite()) => g.to_vec(),
        _ => full.straight_unknowns(),
    };
    let mut cache = None;
    let first = newton(&full, &mut z, &mut cache, &nopts, &mut stats);
    if let Ok(res) = first {
        return Ok(StaticSolution {
            evaluated: full.evaluate(&z),
            z,
            residual: res,
            iterations: stats.iterations,
            load_steps: 1,
        });
    }
    let (_, mut last_res) = first.unwrap_err();
    if !opts.continuation {
        return Err(SoftrodError::NotConverged {
            iterations: stats.iterations,
            residual: last_res,
            load_factor: 0.0,
            reason: "collocation Newton failed from the initial guess and continuation is off"
                .into(),
        });
    }
    let mut lam = 0.0;
    let mut z = full.straight_unknowns();
    let mut prev: Option<(f64, Vec<f64>)> = None;
    let mut dlam: f64 = 0.25;
    let mut levels = 0;
    while lam < 1.0 {
        if levels >= opts.max_load_steps {
            return Err(SoftrodError::NotConverged {
                iterations: stats.iterations,
                residual: last_res,
                load_factor: lam,
                reason: format!(
                    "collocation load continuation used all {} load steps",
                    opts.max_load_steps
                ),
            });
        }
        levels += 1;
        let target = (lam + dlam).min(1.0);
        let models = static_models(rod, loads, target);
        let p = at(rod, &grid, &hist, loads, target, &models);
        let mut trial: Vec<f64> = match &prev {
            Some((lp, zp)) if lam > *lp => z
                .iter()
                .zip(zp)
                .map(|(a, b)| a + (a - b) * (target - lam) / (lam - lp))
                .collect(),
            _ => z.clone(),
        };
        let mut cache = None;
        match newton(&p, &mut trial, &mut cache, &nopts, &mut stats) {
            Ok(res) => {
                last_res = res;
                prev = Some((lam, std::mem::replace(&mut z, trial)));
                lam = target;
                if lam >= 1.0 {
                    return Ok(StaticSolution {
                        evaluated: p.evaluate(&z),
                        z,
                        residual: res,
                        iterations: stats.iterations,
                        load_steps: levels,
                    });
                }
                dlam = (dlam * 1.5).min(0.5);
            }
            Err((_, res)) => {
                last_res = res;
                dlam *= 0.5;
                if dlam < 1e-5 {
                    return Err(SoftrodError::NotConverged {
                        iterations: stats.iterations,
                        residual: last_res,
                        load_factor: lam,
                        reason: "collocation load step fell below 1e-5 (the load may exceed a limit point such as buckling)".into(),
                    });
                }
            }
        }
    }
    unreachable!("the continuation loop returns at load factor 1")
}

/// Base force and moment (world) of a solution, N and N m.
pub fn base_wrench(rod: &Rod, z: &[f64]) -> ([f64; 3], [f64; 3]) {
    let fs = force_scale(rod);
    let ms = fs * rod.length;
    (
        [z[0] * fs, z[1] * fs, z[2] * fs],
        [z[3] * ms, z[4] * ms, z[5] * ms],
    )
}

/// The growth exponent of single shooting's sensitivity in statics, int_0^L sqrt(|n| / EI)
/// ds: under an axial force n the bending perturbations grow (tension) or oscillate
/// (compression) with wavenumber sqrt(|n| / EI), so the tip responds to the base unknowns
/// by up to exp(this). n(s) = F_tip + m_t g + int_s^L f ds is exact in statics (dead
/// loads), so this is known before any solve. Rigid sections add nothing.
pub fn shooting_growth(rod: &Rod, loads: &crate::ode::Loads) -> f64 {
    let g = rod.gravity;
    let mt = rod.spec.tip.mass;
    let mut n: [f64; 3] = std::array::from_fn(|k| loads.tip_force[k] + mt * g[k]);
    let mut kappa = 0.0;
    // From the tip to the base, 8 midpoint samples per section.
    for sec in rod.sections.iter().rev() {
        let f: [f64; 3] = std::array::from_fn(|k| sec.line_mass * g[k] + sec.line_force[k]);
        let ei = sec.k_bt[0][0].min(sec.k_bt[1][1]);
        let h = sec.length / 8.0;
        for _ in 0..8 {
            let mid: [f64; 3] = std::array::from_fn(|k| n[k] + 0.5 * h * f[k]);
            if !sec.rigid && ei > 0.0 {
                let nn = (mid[0] * mid[0] + mid[1] * mid[1] + mid[2] * mid[2]).sqrt();
                kappa += h * (nn / ei).sqrt();
            }
            for k in 0..3 {
                n[k] += h * f[k];
            }
        }
    }
    kappa
}

/// Beyond this growth exponent (e^12 ~ 1.6e5: Newton's steps from a poor guess lose about
/// 5 of 16 digits, and continuation wanders between equilibria) statics uses collocation.
pub const SHOOTING_GROWTH_LIMIT: f64 = 12.0;

/// Whether statics should solve `rod` under `loads` by collocation rather than single
/// shooting (see [`shooting_growth`]).
pub fn shooting_ill_conditioned(rod: &Rod, loads: &crate::ode::Loads) -> bool {
    shooting_growth(rod, loads) > SHOOTING_GROWTH_LIMIT
}

impl StaticSolution {
    /// Strains (v, u) at every node of a static solution (the law at rest: c0 = 0).
    pub fn node_strains(&self, rod: &Rod, loads: &crate::ode::Loads) -> Vec<([f64; 3], [f64; 3])> {
        let grid = Grid::new(rod);
        let models = static_models(rod, loads, 1.0);
        let zero = [0.0; NF];
        self.evaluated
            .nodes
            .iter()
            .enumerate()
            .map(|(j, y)| {
                let sec = if j == 0 {
                    0
                } else {
                    grid.intervals[j - 1].section
                };
                let rot = rotation(&y[IQ..IQ + 4]);
                let nb = mat_t_vec(&rot, &[y[IN], y[IN + 1], y[IN + 2]]);
                let mb = mat_t_vec(&rot, &[y[IM], y[IM + 1], y[IM + 2]]);
                models[sec].strains(&nb, &mb, &zero, 0.0)
            })
            .collect()
    }
}
