//! Coulomb friction in the statics (docs/contact.md, "Friction in the statics"): a bar
//! pulled along a frictional bed against the rigid-plastic and elastic-slip closed forms,
//! path dependence (loading then unloading), global balance, mu = 0 against the
//! frictionless solve, and hostile input; the same for a held (pinned or clamped) tip,
//! whose pose moves along the path, against the free tip's path.

// Index loops over 3-vectors read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::bars;
use crate::common;

use bars::{bar_on_bed, pulled, round_bar, worst_central_difference_error, EA, G, K, L, STEPS};
use softrod_core::ode::Loads;
use softrod_core::statics::constraint::{solve_constrained, ConstrainedSolution, TipConstraint};
use softrod_core::statics::contact::report;
use softrod_core::statics::friction::{self, FrictionPath};
use softrod_core::statics::{shape, Shape, Solution, SolverOptions};
use softrod_core::Rod;

/// EA (N) and q (N/m) of the compiled bar.
fn ea_q(rod: &Rod) -> (f64, f64) {
    let s = &rod.sections[0];
    (s.k_se[2], s.line_mass * G)
}

/// The elastic-slip bar (k_t = K): stuck near the base, where EA u'' = k_t u and
/// u = A sinh(s / ell), ell = sqrt(EA / k_t), and sliding from s = a on, where the
/// friction is mu q: N(s) = F - mu q (L - s). At a the spring reaches its cap,
/// k_t u(a) = mu q, and N is continuous: F - mu q (L - a) = mu q ell coth(a / ell).
/// Returns (a, ell, N(s), tip displacement u(L) = mu q / k_t + (F d - mu q d^2 / 2) / EA,
/// d = L - a). For F < mu q L.
fn elastic_slip(f: f64, mu: f64, ea: f64, q: f64) -> (f64, f64, impl Fn(f64) -> f64, f64) {
    let ell = (ea / K).sqrt();
    let g = |a: f64| f - mu * q * (L - a) - mu * q * ell / (a / ell).tanh();
    // g rises with a (d/da: mu q (1 + 1/sinh^2)); bisection on [ell/100, L].
    let (mut lo, mut hi) = (ell * 1e-2, L);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if g(m) < 0.0 {
            lo = m
        } else {
            hi = m
        }
    }
    let a = 0.5 * (lo + hi);
    let amp = mu * q * ell / (a / ell).sinh();
    let n = move |s: f64| {
        if s < a {
            amp * (s / ell).cosh()
        } else {
            f - mu * q * (L - s)
        }
    };
    let d = L - a;
    let tip = mu * q / K + (f * d - 0.5 * mu * q * d * d) / ea;
    (a, ell, n, tip)
}

fn solve(rod: &Rod, l: &Loads, history: Option<&FrictionPath>, steps: usize) -> Solution {
    friction::solve(rod, l, history, steps, &SolverOptions::default()).unwrap()
}

/// Largest |n_x(s) - N(s)| over the nodes.
fn axial_error(rod: &Rod, l: &Loads, sol: &Solution, n: &dyn Fn(f64) -> f64) -> f64 {
    axial_error_of(&shape(rod, l, sol), n)
}

/// Largest |n_x(s) - N(s)| over the nodes of a shape.
fn axial_error_of(sh: &Shape, n: &dyn Fn(f64) -> f64) -> f64 {
    sh.s.iter()
        .zip(&sh.force)
        .map(|(s, f)| (f[0] - n(*s)).abs())
        .fold(0.0, f64::max)
}

/// The jump J of the friction load's slope at the stick/slip boundary s = a: in the stuck
/// zone f' = k_t u' = k_t N(a) / EA, beyond it f' = 0. RK4 integrates N' = friction with
/// its stage points; a step that contains the kink errs by at most J h^2 (a quadrature
/// exact for linear loads, applied to a load whose slope jumps by J within the step of
/// length h), and the steps elsewhere by O(h^4) of a smooth load.
fn kink_error(n_at_a: f64, h: f64) -> f64 {
    K * n_at_a / EA * h * h
}

#[test]
fn bar_pulled_on_a_frictional_bed_matches_the_closed_forms() {
    let mu = 0.5;
    let rod = Rod::new(bar_on_bed(mu)).unwrap();
    let (ea, q) = ea_q(&rod);
    let h = L / STEPS as f64;
    // The bar laid on the bed under its weight (it lies straight where it was: nothing is
    // stored in the contacts), then pulled, the path continued from the laid bar.
    let laid = solve(&rod, &pulled(0.0), None, 4);
    let history = laid.friction.as_deref().unwrap();
    assert!(history.max_elastic_slip() < 1e-12 * L);
    for (f, steps) in [(0.3, 4), (0.3, 1), (0.7, 4)] {
        let l = pulled(f);
        let sol = solve(&rod, &l, Some(history), steps);
        assert_eq!(sol.stable, None, "friction has no potential: not assessed");
        let tip = sol.tip.r[0] - L;
        let base = sol.base_force[0];
        let (a, ell, n, u) = elastic_slip(f, mu, ea, q);
        let tol_n = kink_error(n(a), h);
        let e_n = axial_error(&rod, &l, &sol, &n);
        // The rigid-plastic limit: N = max(0, F - mu q (L - s)), sliding from s0 on; the
        // elastic slip moves the start of the sliding zone from s0 to a, and N differs
        // from the limit only on [s0, a], by at most mu q (a - s0) (|N'| <= mu q there).
        let s0 = (L - f / (mu * q)).max(0.0);
        let rigid = |s: f64| (f - mu * q * (L - s)).max(0.0);
        let e_rigid = axial_error(&rod, &l, &sol, &rigid);
        let tol_rigid = mu * q * (a - s0) + tol_n;
        // Tip: u(L) = int N / EA ds, so it errs by at most L tol_n / EA. Against the
        // rigid-plastic F^2 / (2 EA mu q) (F < mu q L) the elastic slip adds
        // mu q / k_t (1 - coth^2(a / ell) / 2), at most mu q / k_t in size.
        let tip_rigid = if f < mu * q * L {
            f * f / (2.0 * ea * mu * q)
        } else {
            // All slides: N = F - mu q (L - s) from the base.
            (f * L - 0.5 * mu * q * L * L) / ea
        };
        println!(
            "F {f} steps {steps}: a {a:.4} ell {ell:.3}: |N - N_elastic| {e_n:.2e} (tol {tol_n:.2e}), |N - N_rigid| {e_rigid:.2e} (tol {tol_rigid:.2e}); base {base:.6e} (elastic {:.6e}, rigid {:.6e}); tip {tip:.6e} (elastic {u:.6e}, rigid {tip_rigid:.6e})",
            n(0.0),
            (f - mu * q * L).max(0.0)
        );
        assert!(e_n <= tol_n, "N against the elastic-slip bar");
        assert!((base - n(0.0)).abs() <= tol_n, "base reaction");
        assert!((tip - u).abs() <= L * tol_n / ea, "tip displacement");
        assert!(e_rigid <= tol_rigid, "N against the rigid-plastic limit");
        assert!((base - (f - mu * q * L).max(0.0)).abs() <= tol_rigid);
        assert!((tip - tip_rigid).abs() <= mu * q / K + L * tol_n / ea);
    }
}

/// Global balance with friction: the base force n(0) equals the tip load, the weight
/// and every obstacle's contact force (normal and friction, `report`) to the solver's
/// tolerance (1e-10 of the force scale); and the report's friction is the tangential part.
#[test]
fn frictional_contact_balances_the_base_reaction() {
    let rod = Rod::new(bar_on_bed(0.5)).unwrap();
    let (_, q) = ea_q(&rod);
    let laid = solve(&rod, &pulled(0.0), None, 4);
    for f in [0.3, 0.7] {
        let l = pulled(f);
        let sol = solve(&rod, &l, laid.friction.as_deref(), 4);
        let rep = report(&rod, &l, &sol).unwrap().unwrap();
        let scale = rod.force_scale.max(f);
        for i in 0..3 {
            let weight = if i == 2 { -q * L } else { 0.0 };
            let want = l.tip_force[i] + weight + rep.force[0][i];
            let err = (sol.base_force[i] - want).abs();
            println!(
                "F {f} [{i}]: n(0) {:.6e} balance error {err:.2e}",
                sol.base_force[i]
            );
            assert!(err <= 1e-9 * scale, "component {i}: {err:e}");
        }
        // The bed pulls back along -x: the friction is the report's x force.
        assert!(rep.friction[0][0] < 0.0);
        assert!((rep.friction[0][0] - rep.force[0][0]).abs() <= 1e-12 * scale);
    }
}

/// Path dependence: pulled to F, then released to 0 from there (the friction state
/// carried by `history`), the bar keeps a tension locked in by the friction and does
/// not return; without friction it returns to where it lay.
#[test]
fn released_bar_keeps_a_locked_in_tension_unless_frictionless() {
    let f = 0.3;
    for mu in [0.5, 0.0] {
        let rod = Rod::new(bar_on_bed(mu)).unwrap();
        let (ea, q) = ea_q(&rod);
        let laid = solve(&rod, &pulled(0.0), None, 4);
        let pulled_sol = solve(&rod, &pulled(f), laid.friction.as_deref(), 4);
        let released = solve(&rod, &pulled(0.0), pulled_sol.friction.as_deref(), 4);
        let sh = shape(&rod, &pulled(0.0), &released);
        let locked = sh
            .force
            .iter()
            .map(|n| n[0])
            .fold(f64::NEG_INFINITY, f64::max);
        let tip = released.tip.r[0] - L;
        println!("mu {mu}: locked-in tension {locked:.4e} N, tip {tip:.4e} m");
        if mu > 0.0 {
            // Rigid-plastic unloading: the tip's end slides back over F / (2 mu q) with the
            // friction reversed, leaving N = mu q (L - s) there and the loaded N before
            // it: a peak F / 2, and a tip displaced by the locked strain,
            // int N / EA = F^2 / (4 EA mu q). The elastic slip changes N by at most
            // mu q ell (each zone boundary moves by about ell = sqrt(EA / k_t)).
            let ell = (ea / K).sqrt();
            assert!((locked - 0.5 * f).abs() <= mu * q * ell, "{locked}");
            let tip_rigid = f * f / (4.0 * ea * mu * q);
            assert!((tip - tip_rigid).abs() <= 2.0 * mu * q * ell * ell / ea + mu * q / K);
        } else {
            // Frictionless: elastic, back to the laid bar to the solver's tolerance.
            assert!(
                locked.abs() <= 1e-9 && tip.abs() <= 1e-9 * L,
                "{locked} {tip}"
            );
        }
    }
}

/// mu = 0 on the frictional path is the frictionless solve: the same equilibrium (to the
/// solver's tolerance, which Newton's last quadratic step leaves far behind: measured
/// ~1e-16), and the frictionless statics refuses friction > 0 by name.
#[test]
fn zero_friction_on_the_frictional_path_is_the_frictionless_solve() {
    let rod = Rod::new(bar_on_bed(0.0)).unwrap();
    let mut l = pulled(0.3);
    // A load with a lateral and vertical part too, so that the bar bends on the bed.
    l.tip_force = [0.3, 0.05, -0.2];
    let opts = SolverOptions::default();
    let plain = softrod_core::statics::solve(&rod, &l, None, &opts).unwrap();
    for steps in [1, 7] {
        let fr = friction::solve(&rod, &l, None, steps, &opts).unwrap();
        let dr = (0..3)
            .map(|i| (fr.tip.r[i] - plain.tip.r[i]).abs())
            .fold(0.0, f64::max);
        let dn = (0..3)
            .map(|i| (fr.base_force[i] - plain.base_force[i]).abs())
            .fold(0.0, f64::max);
        println!("steps {steps}: tip {dr:.2e} m, base force {dn:.2e} N");
        assert!(dr <= 1e-12 * L && dn <= 1e-12 * rod.force_scale);
    }
    let rough = Rod::new(bar_on_bed(0.5)).unwrap();
    let err = softrod_core::statics::solve(&rough, &l, None, &opts).unwrap_err();
    assert!(err.to_string().contains("obstacles[0].friction"), "{err}");
}

/// Hostile input: increments out of range, and a history of another design or other
/// obstacles, are refused by name before any work.
#[test]
fn frictional_solve_refuses_bad_input_by_name() {
    let rod = Rod::new(bar_on_bed(0.5)).unwrap();
    let opts = SolverOptions::default();
    let l = pulled(0.3);
    for steps in [0, friction::MAX_FRICTION_STEPS + 1] {
        let err = friction::solve(&rod, &l, None, steps, &opts).unwrap_err();
        assert!(err.to_string().contains("friction_steps"), "{err}");
    }
    let laid = solve(&rod, &pulled(0.0), None, 2);
    let history = laid.friction.as_deref().unwrap();
    // Other obstacles (friction changed), another design (renamed).
    let other_bed = Rod::new(bar_on_bed(0.6)).unwrap();
    let err = friction::solve(&other_bed, &l, Some(history), 2, &opts).unwrap_err();
    assert!(
        err.to_string().contains("history") && err.to_string().contains("obstacles"),
        "{err}"
    );
    let mut spec = bar_on_bed(0.5);
    spec.name = "stiffer".into();
    let other = Rod::new(spec).unwrap();
    let err = friction::solve(&other, &l, Some(history), 2, &opts).unwrap_err();
    assert!(
        err.to_string().contains("history") && err.to_string().contains("another design"),
        "{err}"
    );
    // A path must change loads, not the material.
    let mut scaled = l.clone();
    scaled.stiffness_scale = [2.0, 1.0, 1.0];
    let err = friction::solve(&rod, &scaled, Some(history), 2, &opts).unwrap_err();
    assert!(err.to_string().contains("history"), "{err}");
}

/// The shooting Jacobian with friction is exact: a round bar (surface radius 5 mm, so the
/// friction has a moment and the contact points roll with the sections) laid on a
/// frictional plane, then pulled along and across its axis: the residual's dual-number
/// derivatives at a trial point of the pulling increment against central differences.
/// The laid bar's sliding points store e on the Coulomb cone (|k_t e| = mu |f_n|), where
/// the law has its kink: at the laid shape itself central differences straddle it and
/// average the two sides (an error of 2e-2 of a row's scale, whatever h). So the point
/// is moved off it (the unknowns changed by 1 %: every contact point's trial state
/// strictly in stick or in slip).
#[test]
fn frictional_shooting_jacobian_matches_central_differences() {
    let rod = round_bar();
    let laid = solve(&rod, &pulled(0.0), None, 2);
    let history = laid.friction.as_deref().unwrap();
    let mut l = pulled(0.02);
    l.tip_force[1] = 0.01;
    let x: [f64; 6] = std::array::from_fn(|i| history.x[i] * 1.01 + 1e-4);
    let (_, jac) = friction::residual_and_jacobian(&rod, &l, history, &x);
    let worst = worst_central_difference_error(&rows(&jac), 6, |k, s| {
        let mut a = x;
        a[k] += s;
        friction::residual_and_jacobian(&rod, &l, history, &a)
            .0
            .to_vec()
    });
    // Bound: bars::worst_central_difference_error says why.
    println!("worst Jacobian error {worst:.2e} of a row's scale");
    assert!(worst < 1e-6, "{worst:e}");
}

// ---- a held (pinned or clamped) tip ----

fn held(
    rod: &Rod,
    l: &Loads,
    c: &TipConstraint,
    history: Option<&FrictionPath>,
    steps: usize,
) -> ConstrainedSolution {
    friction::solve_held(rod, l, c, history, steps, &SolverOptions::default()).unwrap()
}

/// A pinned (`clamped` false) or clamped tip at the pose (r, rot).
fn hold(clamped: bool, r: [f64; 3], rot: [[f64; 3]; 3]) -> TipConstraint {
    if clamped {
        TipConstraint::Clamped {
            position: r,
            rotation: rot,
        }
    } else {
        TipConstraint::Pinned { position: r }
    }
}

fn max_diff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).abs()))
        .fold(0.0, f64::max)
}

/// The bar laid on its bed with the tip held where the free laid bar's tip is (from the
/// unloaded rod, gravity ramped in 4 increments), for a held path to continue from.
fn laid_held(rod: &Rod, clamped: bool) -> (Solution, ConstrainedSolution) {
    let free_laid = solve(rod, &pulled(0.0), None, 4);
    let c = hold(clamped, free_laid.tip.r, free_laid.tip.rot);
    let laid = held(rod, &pulled(0.0), &c, None, 4);
    (free_laid, laid)
}

/// Consistency with the free tip: the laid bar pulled by F = 0.3 N in one increment ends
/// at the tip pose P; the same bar laid with its tip held and moved to P in one increment
/// (the same friction state at the start, the same pose at the end) is the same
/// equilibrium, with the tip reaction the pull F. In 4 increments the held path (the pose
/// moved in equal steps, not the force) is still a monotonic pull, and matches the
/// elastic-slip closed form with F = the reaction.
#[test]
fn held_tip_on_a_frictional_bed_matches_the_free_tip_and_the_closed_form() {
    let mu = 0.5;
    let f = 0.3;
    let rod = Rod::new(bar_on_bed(mu)).unwrap();
    let (ea, q) = ea_q(&rod);
    let h = L / STEPS as f64;
    let l0 = pulled(0.0);
    let tol = SolverOptions::default().tol;
    for clamped in [false, true] {
        let (free_laid, laid) = laid_held(&rod, clamped);
        // The held laid bar is the free one: nothing to react (to the solves' tolerance,
        // 1e-10 of the force scale F_s = 1 N; the bar's axial stiffness EA/L = 100 N/m
        // turns the position residual 1e-10 L into 1e-8 N).
        let r0 = laid.tip_reaction_force;
        println!("clamped {clamped}: laid reaction {r0:?}");
        assert!(r0.iter().all(|v| v.abs() <= 2.0 * tol * EA), "{r0:?}");
        assert!(laid.solution.stable.is_none(), "friction: not assessed");
        let free = solve(&rod, &pulled(f), free_laid.friction.as_deref(), 1);
        let target = hold(clamped, free.tip.r, free.tip.rot);
        let one = held(&rod, &l0, &target, laid.solution.friction.as_deref(), 1);
        // Both solves end within tol (scaled residual) of the exact equilibrium: the free
        // one's force balance to tol F_s, the held one's position to tol L, which the
        // bar's tip stiffness (at most EA / (L - a), the sliding length L - a of the
        // closed form) turns into a force; 4 times that sum bounds the reaction's error
        // (the two laid states differ by as much again).
        let (a, _, _, _) = elastic_slip(f, mu, ea, q);
        let tol_f = 4.0 * (tol * rod.force_scale + ea / (L - a) * tol * L);
        let rf = one.tip_reaction_force;
        let e_f = (rf[0] - f).abs().max(rf[1].abs()).max(rf[2].abs());
        let e_m = one
            .tip_reaction_moment
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let free_shape = shape(&rod, &pulled(f), &free);
        let e_r = max_diff(&one.shape.position, &free_shape.position);
        let e_n = max_diff(&one.shape.force, &free_shape.force);
        let fr_free = report(&rod, &pulled(f), &free).unwrap().unwrap().friction[0];
        let fr_held = report(&rod, &l0, &one.solution).unwrap().unwrap().friction[0];
        let e_t = max_diff(&[fr_free], &[fr_held]);
        println!(
            "clamped {clamped}: reaction {rf:?} (F {f}; error {e_f:.2e}, tol {tol_f:.2e}), moment {e_m:.2e}; shape {e_r:.2e} m, n {e_n:.2e} N, friction {e_t:.2e} N"
        );
        assert!(e_f <= tol_f, "reaction {rf:?}");
        // A moment error tol_f L from the same bound (the clamp's moment balances the
        // force's arm); the pin carries none.
        assert!(e_m <= tol_f * L);
        // The internal force and the friction (the bed's load integrated) are forces like
        // the reaction; positions move by force / (EA / L).
        assert!(e_n <= tol_f && e_t <= tol_f);
        assert!(e_r <= tol_f * L / ea + 4.0 * tol * L);
        // Four increments of the pose: the closed form with F = the reaction.
        let four = held(&rod, &l0, &target, laid.solution.friction.as_deref(), 4);
        let fr = four.tip_reaction_force[0];
        let (a4, _, n, u) = elastic_slip(fr, mu, ea, q);
        let tol_n = kink_error(n(a4), h);
        let e_n4 = axial_error_of(&four.shape, &n);
        let tip = free.tip.r[0] - L;
        println!(
            "clamped {clamped}, 4 increments: reaction {fr:.6e}, |N - N_elastic| {e_n4:.2e} (tol {tol_n:.2e}); tip {tip:.6e} (elastic {u:.6e})"
        );
        assert!(e_n4 <= tol_n, "N against the elastic-slip bar");
        assert!((tip - u).abs() <= L * tol_n / ea, "tip displacement");
        assert!((four.solution.base_force[0] - n(0.0)).abs() <= tol_n);
    }
}

/// Global balance with a held tip and friction: the base wrench (n(0), m(0)) equals the
/// tip reaction, the weight and every obstacle's contact wrench (normal and friction,
/// `report`) to the solver's tolerance. The clamp moved sideways too, so the bar bends on
/// the bed and the friction has a lateral part and a moment.
#[test]
fn held_frictional_contact_balances_the_base_wrench() {
    let rod = Rod::new(bar_on_bed(0.5)).unwrap();
    let (_, q) = ea_q(&rod);
    let l0 = pulled(0.0);
    for clamped in [false, true] {
        let (free_laid, laid) = laid_held(&rod, clamped);
        let r = free_laid.tip.r;
        let c = hold(clamped, [r[0] + 2e-3, r[1] + 0.05, r[2]], free_laid.tip.rot);
        let sol = held(&rod, &l0, &c, laid.solution.friction.as_deref(), 8);
        let rep = report(&rod, &l0, &sol.solution).unwrap().unwrap();
        let (fr, mr) = (sol.tip_reaction_force, sol.tip_reaction_moment);
        let tip = sol.solution.tip.r;
        // The weight's moment about the base: int (r(s) - r(0)) x (0, 0, -q) ds by
        // Simpson's rule over the nodes (uniform steps h, an even number of them): exact
        // for r cubic in s; the bar's bending within a step leaves h^4 |r''''| L q / 180,
        // far below the tolerance.
        let sh = &sol.shape;
        let n = sh.s.len() - 1;
        assert_eq!(n % 2, 0);
        let h = L / n as f64;
        let mut wm = [0.0; 3];
        for (k, p) in sh.position.iter().enumerate() {
            let w = if k == 0 || k == n {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            } * h
                / 3.0;
            // (p x (0, 0, -q))
            wm[0] += w * (-q * p[1]);
            wm[1] += w * (q * p[0]);
        }
        let txf = [
            tip[1] * fr[2] - tip[2] * fr[1],
            tip[2] * fr[0] - tip[0] * fr[2],
            tip[0] * fr[1] - tip[1] * fr[0],
        ];
        let scale = rod.force_scale;
        for i in 0..3 {
            let weight = if i == 2 { -q * L } else { 0.0 };
            let ef = (sol.solution.base_force[i] - (fr[i] + weight + rep.force[0][i])).abs();
            let em =
                (sol.solution.base_moment[i] - (txf[i] + mr[i] + wm[i] + rep.moment[0][i])).abs();
            println!(
                "clamped {clamped} [{i}]: n(0) {:.6e} error {ef:.2e}; m(0) {:.6e} error {em:.2e}; friction {:.4e}",
                sol.solution.base_force[i], sol.solution.base_moment[i], rep.friction[0][i]
            );
            // The residual 1e-10 of F_s, and of F_s L for moments, each; 1e-9 leaves a
            // factor 10 for the reaction's round-off sum.
            assert!(ef <= 1e-9 * scale, "force {i}: {ef:e}");
            assert!(em <= 1e-9 * scale * L, "moment {i}: {em:e}");
        }
        // The bed resists the sideways move: friction along -y.
        assert!(rep.friction[0][1] < 0.0);
    }
}

/// mu = 0 on the frictional held path is the frictionless held solve (the constrained
/// solver's own path): the same equilibrium to the solvers' tolerance.
#[test]
fn zero_friction_on_the_held_frictional_path_is_the_frictionless_held_solve() {
    let rod = Rod::new(bar_on_bed(0.0)).unwrap();
    let l0 = pulled(0.0);
    let opts = SolverOptions::default();
    let tilt = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]];
    // The clamp turned 0.2 rad about z from HORIZONTAL (its columns rotated).
    let (c, s) = (0.2f64.cos(), 0.2f64.sin());
    let rz = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    let rot: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| (0..3).map(|k| rz[i][k] * tilt[k][j]).sum())
    });
    for clamped in [false, true] {
        let con = hold(clamped, [L + 2e-3, 0.05, 0.0], rot);
        let plain = solve_constrained(&rod, &l0, &con, None, &opts).unwrap();
        for steps in [1, 7] {
            let fr = held(&rod, &l0, &con, None, steps);
            let d_f = max_diff(&[fr.tip_reaction_force], &[plain.tip_reaction_force]);
            let d_m = max_diff(&[fr.tip_reaction_moment], &[plain.tip_reaction_moment]);
            let d_r = max_diff(&fr.shape.position, &plain.shape.position);
            println!("clamped {clamped}, steps {steps}: reaction {d_f:.2e} N, {d_m:.2e} N m, shape {d_r:.2e} m");
            // Both end within tol = 1e-10 (scaled) of the equilibrium; the held residual's
            // position rows become forces through the bed's and the bar's stiffness
            // (EA / L = 100 N/m axially, less in bending): 1e-10 L x 100 N/m = 1e-8 N, x 10
            // for the two solves and the Jacobian's conditioning.
            assert!(d_f <= 1e-7 && d_m <= 1e-7 * L, "{d_f:e} {d_m:e}");
            assert!(d_r <= 1e-9 * L);
            assert!(fr.solution.stable.is_none() && plain.solution.stable.is_some());
        }
    }
}

/// Path dependence with a held tip: the laid bar's clamp pulled out by the closed form's
/// tip displacement under F, then moved back (`history`) to where it lay, leaves a
/// locked-in compressive reaction (the tip's zone slid back, the base's stays stretched);
/// without friction the bar returns to rest and nothing is locked in. The free tip's path
/// through the same friction states (pulled by F, released to the held reaction) returns
/// its tip to where it lay.
#[test]
fn held_tip_moved_back_keeps_a_locked_in_reaction_unless_frictionless() {
    let f = 0.3;
    let l0 = pulled(0.0);
    for mu in [0.5, 0.0] {
        let rod = Rod::new(bar_on_bed(mu)).unwrap();
        let (ea, q) = ea_q(&rod);
        let (free_laid, laid) = laid_held(&rod, true);
        let free = solve(&rod, &pulled(f), free_laid.friction.as_deref(), 1);
        let rest = hold(true, free_laid.tip.r, free_laid.tip.rot);
        let out = hold(true, free.tip.r, free.tip.rot);
        let pulled_h = held(&rod, &l0, &out, laid.solution.friction.as_deref(), 1);
        let back = held(&rod, &l0, &rest, pulled_h.solution.friction.as_deref(), 1);
        let locked = back.tip_reaction_force[0];
        // The free tip released to the held reaction, through the same states.
        let released = solve(&rod, &pulled(locked), free.friction.as_deref(), 1);
        let dx = (released.tip.r[0] - free_laid.tip.r[0]).abs();
        println!("mu {mu}: locked-in reaction {locked:.4e} N; free tip released to it: {dx:.2e} m from rest");
        // The two paths are the same equations within the solves' tolerance (the held
        // reaction's error tol (F_s + EA) turns into a tip error of that over EA / L).
        assert!(dx <= 4.0 * SolverOptions::default().tol * L * (1.0 + rod.force_scale / EA) * 10.0);
        if mu > 0.0 {
            // Rigid-plastic (derived in docs/contact.md): the tip's zone of length c slides
            // back with the friction reversed, N = F' + mu q y there (y from the tip), the
            // loaded N = F - mu q y beyond; the tip back at rest needs int N ds = 0, so
            // c = F / (sqrt(2) mu q) and the reaction F' = (1 - sqrt 2) F. The elastic
            // slip moves the zone boundaries by about ell = sqrt(EA / k_t), changing N
            // near them, and the reaction that zeroes int N ds, by about mu q ell (as the
            // free tip's locked-in tension above).
            let ell = (ea / K).sqrt();
            let rigid = (1.0 - 2f64.sqrt()) * f;
            assert!(
                locked < 0.0 && (locked - rigid).abs() <= mu * q * ell,
                "{locked}"
            );
        } else {
            // Elastic: back at rest, no reaction (the clamp's position residual 1e-10 L
            // through EA / L).
            assert!(locked.abs() <= 1e-10 * L * EA * 10.0, "{locked}");
        }
    }
}

/// The held frictional residual's exact Jacobian (the constrained solver's dual-number
/// pass sees the friction loads) against central differences, for a pinned and a clamped
/// round bar moved off its laid pose (as `frictional_shooting_jacobian_matches_central_
/// differences`, the unknowns 1 % off the laid ones so every point is strictly in stick
/// or in slip).
#[test]
fn held_frictional_jacobian_matches_central_differences() {
    let rod = round_bar();
    for clamped in [false, true] {
        let free_laid = solve(&rod, &pulled(0.0), None, 2);
        let r = free_laid.tip.r;
        let rest = hold(clamped, r, free_laid.tip.rot);
        let laid = held(&rod, &pulled(0.0), &rest, None, 2);
        let history = laid.solution.friction.as_deref().unwrap();
        let c = hold(clamped, [r[0] + 1e-3, r[1] + 2e-3, r[2]], free_laid.tip.rot);
        let l = pulled(0.0);
        let x: [f64; 6] = std::array::from_fn(|i| history.x[i] * 1.01 + 1e-4);
        let (_, jac) = friction::held_residual_and_jacobian(&rod, &l, &c, history, &x).unwrap();
        let worst = worst_central_difference_error(&rows(&jac), 6, |k, s| {
            let mut a = x;
            a[k] += s;
            let (r, _) = friction::held_residual_and_jacobian(&rod, &l, &c, history, &a).unwrap();
            r.to_vec()
        });
        // Bound: bars::worst_central_difference_error says why.
        println!("clamped {clamped}: worst Jacobian error {worst:.2e} of a row's scale");
        assert!(worst < 1e-6, "{worst:e}");
    }
}

/// Hostile input for a held tip: a history of another end condition (free for held, held
/// for free, pinned for clamped), a free "held" tip, a rotation that is not one, and bad
/// increments are refused by name; the frictionless constrained solve still refuses
/// friction, naming the obstacle's friction and where friction is carried.
#[test]
fn held_frictional_solve_refuses_bad_input_by_name() {
    let rod = Rod::new(bar_on_bed(0.5)).unwrap();
    let opts = SolverOptions::default();
    let l0 = pulled(0.0);
    let (free_laid, pinned_laid) = laid_held(&rod, false);
    let r = free_laid.tip.r;
    let clamp = hold(true, r, free_laid.tip.rot);
    let pin = hold(false, r, free_laid.tip.rot);
    let msg = |e: softrod_core::SoftrodError| e.to_string();
    let e = msg(
        friction::solve_held(&rod, &l0, &clamp, free_laid.friction.as_deref(), 2, &opts)
            .unwrap_err(),
    );
    assert!(
        e.contains("history") && e.contains("free tip") && e.contains("clamped"),
        "{e}"
    );
    let e = msg(friction::solve(
        &rod,
        &l0,
        pinned_laid.solution.friction.as_deref(),
        2,
        &opts,
    )
    .unwrap_err());
    assert!(e.contains("history") && e.contains("pinned tip"), "{e}");
    let e = msg(friction::solve_held(
        &rod,
        &l0,
        &clamp,
        pinned_laid.solution.friction.as_deref(),
        2,
        &opts,
    )
    .unwrap_err());
    assert!(
        e.contains("history") && e.contains("pinned tip") && e.contains("clamped"),
        "{e}"
    );
    let e = msg(friction::solve_held(&rod, &l0, &TipConstraint::Free, None, 2, &opts).unwrap_err());
    assert!(
        e.contains("constraint") && e.contains("pinned or clamped"),
        "{e}"
    );
    let bad = hold(true, r, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]);
    let e = msg(friction::solve_held(&rod, &l0, &bad, None, 2, &opts).unwrap_err());
    assert!(e.contains("tip_constraint.orientation"), "{e}");
    let nan = hold(false, [f64::NAN, 0.0, 0.0], free_laid.tip.rot);
    let e = msg(friction::solve_held(&rod, &l0, &nan, None, 2, &opts).unwrap_err());
    assert!(e.contains("tip_constraint.position[0]"), "{e}");
    for steps in [0, friction::MAX_FRICTION_STEPS + 1] {
        let e = msg(friction::solve_held(&rod, &l0, &pin, None, steps, &opts).unwrap_err());
        assert!(e.contains("friction_steps"), "{e}");
    }
    let e = msg(solve_constrained(&rod, &l0, &pin, None, &opts).unwrap_err());
    assert!(e.contains("obstacles[0].friction"), "{e}");
}

/// Jumping over a path's contact-free stretch (`friction::follow`) leaves the answer as
/// solving every increment gives it: the round bar, weightless, held 3 mm above its
/// frictional plane and pushed down and sideways at the tip, lands on the plane about half
/// way along the path; before that nothing touches, nothing is stored, and the equilibria do not depend
/// on the path. Both paths meet the contact in the same increments, each solved to the
/// tolerance tol (relative to L and the force scale), so they agree to steps * tol; the
/// jumps take fewer increments. A load that never brings the bar down is the
/// frictionless equilibrium, reached in a few jumps.
#[test]
fn contact_free_stretches_are_jumped_without_changing_the_answer() {
    // Weightless (its weight alone would lay the soft bar on the plane): only the tip load
    // (1 mN down: 5.4 mm of deflection at the tip without the plane) brings it down.
    let mut spec = round_bar().spec;
    spec.obstacles[0].point = Some([0.0, 0.0, -8e-3]);
    spec.mounting.gravity = [0.0; 3];
    let rod = Rod::new(spec).unwrap();
    let opts = SolverOptions::default();
    let steps = 80;
    let bound = steps as f64 * opts.tol;
    let mut l = pulled(0.0);
    l.tip_force = [0.0, 3e-4, -1e-3];
    let jumped = friction::solve(&rod, &l, None, steps, &opts).unwrap();
    let every = friction::solve_every_increment(&rod, &l, None, steps, &opts).unwrap();
    let (a, b) = (
        report(&rod, &l, &jumped).unwrap().unwrap(),
        report(&rod, &l, &every).unwrap().unwrap(),
    );
    let dr = (0..3)
        .map(|k| (jumped.tip.r[k] - every.tip.r[k]).abs())
        .fold(0.0, f64::max);
    let df = (0..3)
        .map(|k| (a.force[0][k] - b.force[0][k]).abs())
        .fold(0.0, f64::max);
    println!(
        "touching: tip {dr:.2e} m, contact force {df:.2e} N apart; friction {:?} N; increments {} against {}",
        a.friction[0], jumped.load_steps, every.load_steps
    );
    assert!(
        a.force[0][2] > 0.0 && a.friction[0][1].abs() > 0.0,
        "{:?}",
        a.force[0]
    );
    assert!(dr <= bound * rod.length, "{dr:e}");
    assert!(df <= bound * rod.force_scale, "{df:e}");
    assert!(jumped.load_steps < every.load_steps);
    // Never touching: the frictionless equilibrium, in a handful of increments.
    l.tip_force = [0.0, 3e-4, -2e-4];
    let free = friction::solve(&rod, &l, None, steps, &opts).unwrap();
    let mut smooth_spec = rod.spec.clone();
    smooth_spec.obstacles[0].friction = 0.0;
    let plain =
        softrod_core::statics::solve(&Rod::new(smooth_spec).unwrap(), &l, None, &opts).unwrap();
    let dr = (0..3)
        .map(|k| (free.tip.r[k] - plain.tip.r[k]).abs())
        .fold(0.0, f64::max);
    println!(
        "clear: tip {dr:.2e} m from the frictionless solve, {} increments",
        free.load_steps
    );
    assert!(dr <= bound * rod.length, "{dr:e}");
    assert!(free.load_steps <= 10, "{}", free.load_steps);
}

/// A 6x6 Jacobian as rows (for `bars::worst_central_difference_error`).
fn rows(jac: &[[f64; 6]; 6]) -> Vec<Vec<f64>> {
    jac.iter().map(|r| r.to_vec()).collect()
}

/// Regression: the finger of designs/prebent_finger_on_table.toml pressed onto the table
/// with mu = 0.5 at 25 kPa. Requested in 3 increments, the path lands on the table at 2/3
/// with the tip barely in the penalty's smoothing zone (0.4 um deep, where the normal
/// force is quadratic in the depth and the friction at its slip cap), and Newton reaches
/// the next equilibrium only in sub-increments of about 1.6e-4 of the path: finer than
/// 1/1024 of a third (3.3e-4), where the halving used to stop, so the solve failed while 2,
/// 4, 5, 6 and 80 increments solved it (those too halve to 1e-3 .. 1.6e-4 of the path
/// there). The finest sub-increment no longer depends on how coarse the request is.
/// Every coarse request (1 to 8 increments) now reaches the equilibrium: the tip pressed
/// on the table with friction, and the base force balancing the weight and the contact
/// force to the solver's tolerance (as `frictional_contact_balances_the_base_reaction`).
/// And they land as the default path does: one or two increments carried the tip from the
/// air onto the table in one increment, whose net travel (the tip swings back, -x, before
/// it lands, and is pushed out, +x, once pressed) counted as slip, so the friction pointed
/// the wrong way (+8.4 mN against -23.7 mN on fine paths). A landing increment is now no
/// longer than the default's: every request's friction has the fine path's sign and is
/// within 5 % of it (the default's own first-order error is about 1 %, and a coarse request
/// goes on in longer increments after the landing, each first order: measured 0.1-1.7 %).
#[test]
fn coarse_frictional_paths_halve_as_finely_as_the_default_one() {
    let rod = Rod::new(common::finger(0.5)).unwrap();
    let mut l = common::loads(&[25e3]);
    l.tensions = vec![0.0];
    let opts = SolverOptions::default();
    let weight = rod.mass() * 9.81; // common::finger hangs under g = 9.81 m/s^2 along -z
    let fine = friction::solve(&rod, &l, None, 320, &opts).unwrap();
    let fine_ft = report(&rod, &l, &fine).unwrap().unwrap().friction[0][0];
    assert!(fine_ft < -1e-3, "{fine_ft}");
    for steps in 1..=8 {
        let sol = friction::solve(&rod, &l, None, steps, &opts)
            .unwrap_or_else(|e| panic!("{steps} increments: {e}"));
        let rep = report(&rod, &l, &sol).unwrap().unwrap();
        let (f, ft) = (rep.force[0], rep.friction[0]);
        println!(
            "{steps} increments: tip x {:.6e} m, contact force {f:?} N, friction {ft:?} N, {} increments solved",
            sol.tip.r[0], sol.load_steps
        );
        // The table pushes up and its friction acts along it (0.1 mN: far above the
        // solver's resolution of forces of tens of mN, far below the friction here).
        assert!(f[2] > 1e-3 && ft[0].abs() > 1e-4, "{steps}: {f:?} {ft:?}");
        assert!(
            ft[0] < 0.0 && (ft[0] - fine_ft).abs() <= 0.05 * fine_ft.abs(),
            "{steps} increments: friction {} N, fine path {fine_ft} N",
            ft[0]
        );
        let scale = rod.force_scale;
        for i in 0..3 {
            let w = if i == 2 { -weight } else { 0.0 };
            let err = (sol.base_force[i] - (w + f[i])).abs();
            assert!(
                err <= 1e-9 * scale,
                "{steps} increments, component {i}: {err:e}"
            );
        }
    }
}
