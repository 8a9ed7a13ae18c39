//! Statics by collocation (`crate::collocation`): the solver for rods whose single
//! shooting is ill-conditioned (long, soft, many-section rods), chosen automatically by
//! `crate::statics` (docs/model.md, "Collocation").

use crate::collocation::{
    force_scale, mat_t_vec, newton, rotation, Evaluated, Grid, NewtonOptions, NewtonStats, Problem,
    SectionModel, TipBody, IM, IN, IQ, NF, NY,
};
use crate::error::{Result, SoftrodError};
use crate::jet::{Coeff, Jet};
use crate::ode::Coeffs;
use crate::rod::Rod;
use crate::statics::{rotation_variations, Jacobi, SolverOptions, MIN_STABLE_STEP};
use nalgebra::{Matrix3, SMatrix};

pub mod implicit;

/// A static equilibrium solved by collocation.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticSolution {
    /// Scaled unknowns (a warm start for a later solve).
    pub z: Vec<f64>,
    pub residual: f64,
    pub iterations: usize,
    pub load_steps: usize,
    pub evaluated: Evaluated,
    /// The conjugate-point test on the collocation solution ([`stability`]): None only
    /// where the Jacobi fields could not be carried (a singular stage matrix).
    pub stable: Option<bool>,
}

/// Section models of a static solve at load factor `factor` (pressures and gravity scaled
/// by it, as in the shooting solver's continuation).
/// One model per slot of `grid` (`Grid::models`).
pub fn static_models(
    rod: &Rod,
    grid: &Grid,
    loads: &crate::ode::Loads,
    factor: f64,
) -> Vec<SectionModel> {
    let coeffs: Vec<Coeffs<f64>> = (0..rod.sections.len())
        .map(|i| static_coeffs(rod, i, loads, factor))
        .collect();
    models_of(rod, grid, &coeffs)
}

/// Static section models (no inertia, no damping, c0 = 0) from the sections' coefficients,
/// in any coefficient scalar (dual ones for [`derivatives`]).
fn models_of<C: Coeff>(rod: &Rod, grid: &Grid, coeffs: &[Coeffs<C>]) -> Vec<SectionModel<C>> {
    let zero = C::from(0.0);
    grid.build_models(rod, coeffs, |c, _, slot| {
        SectionModel::new(
            c,
            rod.sections[slot.section].rigid,
            zero,
            [zero; 3],
            None,
            zero,
            0.0,
        )
    })
}

fn static_coeffs(rod: &Rod, i: usize, loads: &crate::ode::Loads, factor: f64) -> Coeffs<f64> {
    Coeffs::build(
        rod,
        i,
        &loads.pressures,
        &loads.tensions,
        &rod.gravity,
        factor,
        &loads.stiffness_scale,
    )
}

fn static_tip(rod: &Rod, loads: &crate::ode::Loads, factor: f64) -> TipBody {
    let t = &rod.spec.tip;
    let force = loads.tip_force.map(|f| f * factor);
    let moment = loads.tip_moment.map(|m| m * factor);
    let z = [0.0; 3];
    let body = loads.tip_frame == crate::spec::Frame::Body;
    TipBody {
        mass: t.mass,
        com: t.com_offset,
        inertia: [0.0; 3],
        force: if body { z } else { force },
        moment: if body { z } else { moment },
        force_body: if body { force } else { z },
        moment_body: if body { moment } else { z },
    }
}

/// The equilibrium at the unknowns `z` as they are (a converged solution's, which its
/// holder passes back to take its derivatives): evaluated with its stability and its
/// largest scaled residual, without moving z, so that everything read from it is that
/// solution's own value (a Newton step would move it within the tolerance). z must be
/// converged by the solver's own test: the Newton correction at z within `tol` of its size.
/// None when it is not, or does not fit the rod's grid, or is not finite (the caller then
/// solves from it).
pub fn at_unknowns(
    rod: &Rod,
    loads: &crate::ode::Loads,
    z: &[f64],
    tol: f64,
) -> Option<StaticSolution> {
    let grid = Grid::new(rod);
    if z.len() != grid.unknowns() || !z.iter().all(|v| v.is_finite()) {
        return None;
    }
    let hist = vec![[0.0; NF]; 2 * grid.len() + 1];
    let models = static_models(rod, &grid, loads, 1.0);
    let mut p = Problem::new(rod, &grid, &models, 0.0, &hist, static_tip(rod, loads, 1.0));
    p.gravity = rod.gravity;
    let mut r = vec![0.0; z.len()];
    p.residual(z, &mut r, None);
    let fac = p.factorize(z)?;
    let mut dz = vec![0.0; z.len()];
    let mut scratch = vec![0.0; fac.scratch_len()];
    fac.solve(&r, &mut dz, &mut scratch);
    let norm = crate::collocation::inf_norm(&dz);
    let converged = norm <= tol * crate::collocation::inf_norm(z).max(1.0); // false for NaN
    if !converged {
        return None;
    }
    Some(StaticSolution {
        evaluated: p.evaluate(z),
        stable: stability(&p, z),
        z: z.to_vec(),
        residual: crate::collocation::inf_norm(&r),
        iterations: 0,
        load_steps: 0,
    })
}

/// Static equilibrium by collocation (the dt -> infinity limit of the dynamic
/// discretisation): Newton from `guess` (scaled unknowns of an earlier solution, or None
/// for the straight rod), then, if that fails, load continuation from the unloaded
/// straight rod with a secant predictor, as the shooting solver does. The solution
/// carries the conjugate-point test ([`stability`]). As on the shooting solver's natural
/// path, continuation also runs when Newton from the straight rod (no guess) lands on an
/// unstable equilibrium, a level that leaves the stable path is cut down to
/// `MIN_STABLE_STEP` (shorter, the path itself loses stability and is followed), and an
/// unstable equilibrium is returned only when no stable one was reached.
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
    let full_models = static_models(rod, &grid, loads, 1.0);
    let full = at(rod, &grid, &hist, loads, 1.0, &full_models);
    let warm = guess.filter(|g| g.len() == grid.unknowns() && g.iter().all(|x| x.is_finite()));
    let mut z = match warm {
        Some(g) => g.to_vec(),
        None => full.straight_unknowns(),
    };
    let mut cache = None;
    let first = newton(&full, &mut z, &mut cache, &nopts, &mut stats);
    // An equilibrium at full load off the stable path, kept in case no stable one is
    // reached (as the shooting solver's natural path does).
    let mut unstable_end: Option<StaticSolution> = None;
    let mut last_res = match first {
        Ok(res) => {
            let sol = StaticSolution {
                evaluated: full.evaluate(&z),
                stable: stability(&full, &z),
                z,
                residual: res,
                iterations: stats.iterations,
                load_steps: 1,
            };
            // A caller's warm start picked its branch (dynamics starts from the static
            // solver's equilibrium): its solution is returned with its verdict.
            if sol.stable != Some(false) || !opts.continuation || warm.is_some() {
                return Ok(sol);
            }
            let res = sol.residual;
            unstable_end = Some(sol);
            res
        }
        Err((_, res)) => res,
    };
    if !opts.continuation {
        return Err(SoftrodError::NotConverged {
            iterations: stats.iterations,
            residual: last_res,
            load_factor: 0.0,
            reason: "collocation Newton failed from the initial guess and continuation is off"
                .into(),
        });
    }
    let give_up = |unstable_end: Option<StaticSolution>, e: SoftrodError| match unstable_end {
        Some(sol) => Ok(sol),
        None => Err(e),
    };
    let mut lam = 0.0;
    let mut z = full.straight_unknowns();
    let mut prev: Option<(f64, Vec<f64>)> = None;
    let mut dlam: f64 = 0.25;
    let mut levels = 0;
    // The unloaded rod in its reference shape is the energy's minimum: the path starts
    // stable, and a level that loses stability is cut (down to `MIN_STABLE_STEP`) as on
    // the shooting solver's natural path, so the path does not jump to another branch.
    let mut stable = Some(true);
    while lam < 1.0 {
        if levels >= opts.max_load_steps {
            return give_up(
                unstable_end,
                SoftrodError::NotConverged {
                    iterations: stats.iterations,
                    residual: last_res,
                    load_factor: lam,
                    reason: format!(
                        "collocation load continuation used all {} load steps",
                        opts.max_load_steps
                    ),
                },
            );
        }
        levels += 1;
        let target = (lam + dlam).min(1.0);
        let h = target - lam;
        let models = static_models(rod, &grid, loads, target);
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
                let st = stability(&p, &trial);
                if stable == Some(true) && st == Some(false) && h > MIN_STABLE_STEP {
                    if target >= 1.0 {
                        unstable_end = Some(StaticSolution {
                            evaluated: p.evaluate(&trial),
                            z: trial,
                            residual: res,
                            iterations: stats.iterations,
                            load_steps: levels,
                            stable: st,
                        });
                    }
                    dlam = 0.5 * h;
                    continue;
                }
                prev = Some((lam, std::mem::replace(&mut z, trial)));
                lam = target;
                stable = st;
                if lam >= 1.0 {
                    let sol = StaticSolution {
                        evaluated: p.evaluate(&z),
                        z,
                        residual: res,
                        iterations: stats.iterations,
                        load_steps: levels,
                        stable: st,
                    };
                    return Ok(match unstable_end {
                        Some(u) if st == Some(false) && u.stable != Some(false) => u,
                        _ => sol,
                    });
                }
                dlam = (dlam * 1.5).min(0.5);
            }
            Err((_, res)) => {
                last_res = res;
                dlam *= 0.5;
                if dlam < 1e-5 {
                    return give_up(
                        unstable_end,
                        SoftrodError::NotConverged {
                            iterations: stats.iterations,
                            residual: last_res,
                            load_factor: lam,
                            reason: "collocation load step fell below 1e-5 (the load may exceed a limit point such as buckling)".into(),
                        },
                    );
                }
            }
        }
    }
    unreachable!("the continuation loop returns at load factor 1")
}

/// The conjugate-point test of the shooting solver (`super::Jacobi`; docs/model.md,
/// "Validity and stability") on a collocation solution `z` of `p`, with dead loads.
///
/// The three Jacobi fields that start at the clamp (d theta(0) = 0, dn = 0, dm(0) = e_j
/// in scaled units) are carried along the rod by the linearised collocation equations,
/// interval by interval (`Problem::transfer`: exact stage Jacobians, one 32 x 32 LU per
/// interval): they are the derivatives of the discrete solution with respect to the base
/// moment, the collocation counterpart of the shooting test's dual numbers. Integrated
/// as they are, they grow like the shooting sensitivity (the reason for collocation), so
/// after every interval the three fields are replaced by an orthonormal basis of their
/// span (Gram-Schmidt: F = B R, R upper triangular with a positive diagonal). That is a
/// change of basis of the same space of fields, Theta -> Theta C with C invertible, under
/// which both halves of the test are invariant:
/// - a crossing between nodes k and k+1 is read from the eigenvalues of
///   Theta_k+1^-1 Theta_k, and with both matrices taken in the basis of node k (the
///   propagated fields, before their orthonormalisation) the matrix is similar to the
///   unnormalised one;
/// - the tip form sym(Theta(L)^T J) is congruent to sym((Theta(L) C)^T (J C)), so its
///   definiteness is the same when J is taken in the same basis: J = D B_N, D the tip
///   moment residual's derivative with respect to the tip node's unknowns.
///
/// det R > 0 keeps the sign of det Theta, which marks the first elastic step. Cost:
/// two 16-direction dual evaluations of the ODE and one 32 x 32 LU per interval, about
/// one Newton factorisation. None if a stage matrix is singular or the fields stop being
/// finite (not assessed).
pub fn stability(p: &Problem, z: &[f64]) -> Option<bool> {
    let mut b = SMatrix::<f64, NY, 3>::zeros();
    for k in 0..3 {
        b[(IM + k, k)] = 1.0;
    }
    let mut jacobi = Jacobi::default();
    for j in 0..p.grid.len() {
        let f = p.transfer(z, j, &b)?;
        let y = p.node(z, j + 1);
        let q: [Jet<3>; 4] = std::array::from_fn(|k| Jet {
            re: y[IQ + k],
            eps: [f[(IQ + k, 0)], f[(IQ + k, 1)], f[(IQ + k, 2)]],
        });
        jacobi.visit_theta(rotation_variations(&rotation(&q)));
        let (basis, r) = orthonormalise(&f)?;
        jacobi.theta *= r.try_inverse()?;
        b = basis;
    }
    let d = p.tip_jacobian(z);
    let jac: Matrix3<f64> = d.fixed_rows::<3>(3) * b;
    jac.iter()
        .all(|v| v.is_finite())
        .then(|| jacobi.stable(&jac))
}

/// Gram-Schmidt with re-orthogonalisation ("twice is enough"): F = B R with B's columns
/// orthonormal and R upper triangular with a positive diagonal. None if the columns are
/// (numerically) dependent or not finite.
fn orthonormalise(f: &SMatrix<f64, NY, 3>) -> Option<(SMatrix<f64, NY, 3>, Matrix3<f64>)> {
    let mut b = *f;
    let mut r = Matrix3::zeros();
    for c in 0..3 {
        let norm0 = f.column(c).norm();
        for _ in 0..2 {
            for k in 0..c {
                let d = b.column(k).dot(&b.column(c));
                r[(k, c)] += d;
                let bk = b.column(k).into_owned();
                b.column_mut(c).axpy(-d, &bk, 1.0);
            }
        }
        let n = b.column(c).norm();
        if !(n.is_finite() && n > 1e-14 * norm0) {
            return None;
        }
        r[(c, c)] = n;
        b.column_mut(c).unscale_mut(n);
    }
    Some((b, r))
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
        let coeffs: Vec<Coeffs<f64>> = (0..rod.sections.len())
            .map(|i| static_coeffs(rod, i, loads, 1.0))
            .collect();
        let zero = [0.0; NF];
        self.evaluated
            .nodes
            .iter()
            .enumerate()
            .map(|(j, y)| {
                // Node j >= 1 ends interval j - 1 (its section's law, at its local end).
                let (sec, s) = if j == 0 {
                    (0, 0.0)
                } else {
                    let iv = &grid.intervals[j - 1];
                    (iv.section, iv.s_local + iv.h)
                };
                let rot = rotation(&y[IQ..IQ + 4]);
                let nb = mat_t_vec(&rot, &[y[IN], y[IN + 1], y[IN + 2]]);
                let mb = mat_t_vec(&rot, &[y[IM], y[IM + 1], y[IM + 2]]);
                // The law at the node's own arc length (a varying section's there).
                let c = coeffs[sec].at(&rod.sections[sec], s);
                let model =
                    SectionModel::new(&c, rod.sections[sec].rigid, 0.0, [0.0; 3], None, 0.0, 0.0);
                model.strains(&nb, &mb, &zero, 0.0, s)
            })
            .collect()
    }
}
