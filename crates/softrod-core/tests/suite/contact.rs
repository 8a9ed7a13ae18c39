//! Contact with rigid obstacles (docs/contact.md): a cantilever resting on a plane against
//! the beam on a rigid support, a rod pressed onto a sphere, the penetration rule, global
//! equilibrium, the exact shooting Jacobian, and bad obstacle input.

// Index loops over 3-vectors read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::{design, direct_section, loads, obstacle, HORIZONTAL};
use softrod_core::error::{Rule, SoftrodError};
use softrod_core::spec::obstacle::{ObstacleKind, ObstacleSpec};
use softrod_core::statics::constraint::{
    constraint_residual_and_jacobian, solve_constrained, TipConstraint,
};
use softrod_core::statics::contact::report;
use softrod_core::statics::system::{solve_system, Platform, SystemRod};
use softrod_core::statics::{residual, residual_and_jacobian, solve, SolverOptions};
use softrod_core::{DesignSpec, Rod};

/// Nearly inextensible and unshearable (EA = GA = 1e8 N), so the Euler-Bernoulli beam is
/// the right comparison.
const EI: f64 = 10.0;
const Q: f64 = 1.0; // weight per length, N/m
const G: f64 = 9.81;

/// A 1 m horizontal cantilever under its weight q = 1 N/m, clamped at height c above a
/// plane (the rod's centreline touches: stiffnesses given directly, surface radius 0).
fn cantilever_over_plane(c: f64, k: f64, steps: usize) -> DesignSpec {
    let sec = direct_section("beam", 1.0, 1e8, 1e8, EI, EI, Q / G, steps);
    let mut d = design(vec![sec], HORIZONTAL, G);
    // Tolerance 60 % of c; the ramp's smoothing a fifth of the sinking q / k, so that the
    // support is linear with stiffness k where the beam lies on it (delta = q/k + eps/2).
    let mut plane = obstacle(ObstacleKind::Plane, k, 5e-5);
    plane.smoothing = Some(0.2 * Q / k);
    plane.point = Some([0.0, 0.0, -c]);
    plane.normal = Some([0.0, 0.0, 1.0]);
    d.obstacles = vec![plane];
    d
}

/// The beam on a rigid support (Euler-Bernoulli, small deflection): clamped at x = 0 a
/// height c above the support, uniform load q. It lies flat on the support from x = a on,
/// where EI w = -q x^4/24 + A x^3 + B x^2 meets w = -c with w' = w'' = 0:
/// A = q a / (9 EI), B = -q a^2 / (12 EI), a = (72 EI c / q)^(1/4). The support carries a
/// point force q a / 3 at x = a and q per length beyond; the clamp carries 2 q a / 3 and
/// the moment q a^2 / 6.
fn rigid_support(c: f64) -> (f64, f64, f64) {
    let a = (72.0 * EI * c / Q).powf(0.25);
    (a, 2.0 * Q * a / 3.0, Q * a * a / 6.0)
}

#[test]
fn cantilever_on_plane_matches_beam_on_rigid_support() {
    // c puts the first contact at a = 0.5 m; w' <= c / a ~ 2e-4, so the small-deflection
    // theory errs by ~1e-8 relative: what is left is the penalty's compliance.
    let c = Q * 0.5f64.powi(4) / (72.0 * EI);
    let (a, f0, m0) = rigid_support(c);
    let mut errors = vec![];
    for k in [1e5, 1e6] {
        let rod = Rod::new(cantilever_over_plane(c, k, 400)).unwrap();
        let l = loads(&[]);
        let sol = solve(&rod, &l, None, &SolverOptions::default()).unwrap();
        // A beam lying on a support under its weight is stable (the assessment of the
        // six-unknown contact solve, docs/contact.md "Stability").
        assert_eq!(sol.stable, Some(true), "k {k}");
        let rep = report(&rod, &l, &sol).unwrap().unwrap();
        // The penalty is a Winkler foundation of modulus k: near the first contact the
        // beam's deflection decays over 1/beta = (4 EI / k)^(1/4), which smears the point
        // reaction over that length and moves the clamp's reactions by O(1/(beta a)).
        let ell = (4.0 * EI / k).powf(0.25);
        let ef = (-sol.base_force[2] - f0).abs() / f0;
        let em = (sol.base_moment[1].abs() - m0).abs() / m0;
        println!(
            "k {k:e}: 1/beta a {:.3e} force err {ef:.3e} moment err {em:.3e}",
            ell / a
        );
        // Measured: second order or better in 1/(beta a) (the smeared reaction keeps its
        // resultant and nearly its moment), with a constant below one.
        let bound = (ell / a).powi(2);
        assert!(ef < bound && em < bound, "k {k}: {ef} {em} > {bound}");
        errors.push((ell, ef, em));
        // The first contact lies within two decay lengths 1/beta of a (the Winkler
        // foundation lets the beam sink before a and smears the point force over ~1/beta).
        let first = rep.nodes.iter().position(|n| n.gap < 0.0).unwrap();
        let s_first = first as f64 / 400.0;
        println!("first contact at {s_first}, a = {a}");
        assert!(
            (s_first - a).abs() < 2.0 * ell,
            "first contact {s_first}, a {a}"
        );
        // Force balance: n(0) = weight + contact, to the solver's tolerance.
        let total: f64 = rep.force.iter().map(|f| f[2]).sum();
        assert!((sol.base_force[2] - (total - Q)).abs() < 1e-9 * Q);
    }
    // The error falls at least like (1/beta)^2 ~ k^(-1/2) as the penalty stiffens: it
    // converges to the rigid support (measured orders: 5.1 for the force, 4.0 for the
    // moment, from k = 1e5 to 1e6).
    let order_f = (errors[0].1 / errors[1].1).ln() / (errors[0].0 / errors[1].0).ln();
    let order_m = (errors[0].2 / errors[1].2).ln() / (errors[0].0 / errors[1].0).ln();
    assert!(order_f > 2.0 && order_m > 2.0, "orders {order_f} {order_m}");
}

/// A 1.5 m horizontal beam under its weight q = 1 N/m, clamped at the base and held at the
/// tip (pinned or clamped) at the base's height, a height c above a plane. Axially soft
/// (EA = 1e4 N): between two held ends the sag stretches the beam by ~int w'^2 / 2 ~ 1e-8,
/// and with EA = 1e8 N that tension (~1 N) would stiffen the beam by N a^2 / EI ~ 3 %;
/// with 1e4 N by 3e-6.
fn held_beam_over_plane(c: f64, k: f64, steps: usize) -> DesignSpec {
    let mut d = cantilever_over_plane(c, k, steps);
    d.sections[0] = direct_section("beam", 1.5, 1e4, 1e8, EI, EI, 1.5 * Q / G, steps);
    d
}

/// The end of a lifted span of the beam on a rigid support (`rigid_support`), held pinned
/// a height c above it: EI w = q x^4 / 24 + A x^3 from the touch-down point, with w'' = 0
/// at the pin (no moment) instead of w' = 0: a = (24 EI c / q)^(1/4); the pin carries
/// q a / 2, the touch-down point q a / 2.
fn pinned_span(c: f64) -> (f64, f64) {
    let a = (24.0 * EI * c / Q).powf(0.25);
    (a, Q * a / 2.0)
}

/// A beam held at both ends (the base clamped, the tip pinned or clamped) lies on a plane
/// between two lifted spans. The flat part carries no moment and no shear, so each span is
/// the beam on a rigid support on its own: the base's and a clamped tip's as the
/// cantilever's (`rigid_support`), a pinned tip's as `pinned_span`. The tip reaction, the
/// base wrench and the contact report balance the weight to the solver's tolerance; no node
/// sinks beyond the tolerance; the equilibrium is assessed stable; the constrained
/// Jacobian with contact is exact.
#[test]
fn held_beam_on_plane_matches_beam_on_rigid_support() {
    let c = Q * 0.5f64.powi(4) / (72.0 * EI); // the base's span a = 0.5 m
    let (a, f0, m0) = rigid_support(c);
    let (a_pin, f_pin) = pinned_span(c);
    for kind in ["clamped", "pinned"] {
        let mut errors = vec![];
        for k in [1e5, 1e6] {
            let rod = Rod::new(held_beam_over_plane(c, k, 600)).unwrap();
            let l = loads(&[]);
            let tip = [1.5, 0.0, 0.0];
            let held = match kind {
                "clamped" => TipConstraint::Clamped {
                    position: tip,
                    rotation: HORIZONTAL,
                },
                _ => TipConstraint::Pinned { position: tip },
            };
            let sol = solve_constrained(&rod, &l, &held, None, &SolverOptions::default())
                .unwrap_or_else(|e| panic!("{kind} k {k}: {e}"));
            // A beam lying on a support under its weight, both ends held: stable (the
            // conjugate-point test with the penalty in the Jacobi fields).
            assert_eq!(sol.solution.stable, Some(true), "{kind} k {k}");
            let rep = report(&rod, &l, &sol.solution).unwrap().unwrap();
            assert!(
                rep.max_penetration <= 5e-5,
                "{kind}: {}",
                rep.max_penetration
            );
            // Global balance: n(0) = tip reaction + contact + weight (world z down), to
            // the solver's tolerance (1e-10 of the force scale EI / L^2 ~ 4 N).
            for i in 0..3 {
                let contact: f64 = rep.force.iter().map(|f| f[i]).sum();
                let weight = if i == 2 { -Q * 1.5 } else { 0.0 };
                let want = sol.tip_reaction_force[i] + contact + weight;
                assert!(
                    (sol.solution.base_force[i] - want).abs() < 1e-9 * Q,
                    "{kind} {i}: n(0) {} want {want}",
                    sol.solution.base_force[i]
                );
            }
            let ell = (4.0 * EI / k).powf(0.25);
            let eb = (-sol.solution.base_force[2] - f0).abs() / f0;
            let em = (sol.solution.base_moment[1].abs() - m0).abs() / m0;
            let (et, span) = if kind == "clamped" {
                let ef = (sol.tip_reaction_force[2] - f0).abs() / f0;
                let emt = (sol.tip_reaction_moment[1].abs() - m0).abs() / m0;
                (ef.max(emt), a)
            } else {
                assert_eq!(sol.tip_reaction_moment, [0.0; 3]);
                ((sol.tip_reaction_force[2] - f_pin).abs() / f_pin, a_pin)
            };
            println!(
                "{kind} k {k:e}: base force {eb:.3e} moment {em:.3e}, tip {et:.3e} (1/beta a {:.3e})",
                ell / span
            );
            // As the cantilever's (`cantilever_on_plane_matches_beam_on_rigid_support`):
            // the Winkler foundation smears the touch-down point force over 1/beta,
            // which moves the reactions by O((1/(beta a))^2).
            let bound = |span: f64| (ell / span).powi(2);
            assert!(
                eb < bound(a) && em < bound(a),
                "{kind} k {k}: base {eb} {em}"
            );
            assert!(et < bound(span), "{kind} k {k}: tip {et}");
            errors.push((ell, eb.max(em), et));
            if k == 1e5 {
                // The exact Jacobian of the constrained residual with contact, against
                // central differences at the solution (nodes in the penalty's linear and
                // smoothing zones), at the softer penalty: shooting across the stiffer one
                // amplifies the residual's curvature so much that the differences stop
                // converging before round-off takes over. Here their error falls as h^2
                // (measured worst entry, of the largest: 2e-4 at h = 1e-7, 4e-8 at 1e-8
                // clamped; 5e-3, 4e-5 pinned) to 3e-9 at h = 1e-9; bound 1e-6 of it.
                let x = &sol.solution.x;
                let (_, jac) = constraint_residual_and_jacobian(&rod, &l, &held, x).unwrap();
                let scale = jac.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                let h = 1e-9;
                for j in 0..6 {
                    let at = |d: f64| {
                        let mut y = x.clone();
                        y[j] += d;
                        constraint_residual_and_jacobian(&rod, &l, &held, &y)
                            .unwrap()
                            .0
                    };
                    let (up, down) = (at(h), at(-h));
                    for i in 0..6 {
                        let fd = (up[i] - down[i]) / (2.0 * h);
                        assert!(
                            (fd - jac[i][j]).abs() <= 1e-6 * scale,
                            "{kind} J[{i}][{j}] = {} fd {fd}",
                            jac[i][j]
                        );
                    }
                }
            }
        }
        // The errors fall as the penalty stiffens (towards the rigid support).
        assert!(
            errors[1].1 < errors[0].1 && errors[1].2 < errors[0].2,
            "{kind}: {errors:?}"
        );
    }
}

/// A 0.5 m horizontal cantilever (EI = 1 N m^2, weightless) pushed down at its tip by P,
/// with a sphere of radius 50 mm whose top lies d0 below the tip: the beam is clamped-free
/// until the tip touches, then the sphere takes R = P - 3 EI d0 / L^3 at the tip (small
/// deflection: the sphere falls away from the rod everywhere else).
fn cantilever_over_sphere(k: f64, tolerance: f64) -> (DesignSpec, [f64; 3], f64) {
    let (l, r_s, d0, p) = (0.5, 0.05, 2e-3, 0.1);
    let sec = direct_section("beam", l, 1e8, 1e8, 1.0, 1.0, 0.0, 200);
    let mut d = design(vec![sec], HORIZONTAL, 0.0);
    d.tip.force = [0.0, 0.0, -p];
    let center = [l, 0.0, -(d0 + r_s)];
    let mut ball = obstacle(ObstacleKind::Sphere, k, tolerance);
    ball.center = Some(center);
    ball.radius = Some(r_s);
    d.obstacles = vec![ball];
    (d, center, p - 3.0 * d0 / l.powi(3))
}

fn tip_loads(rod: &Rod) -> softrod_core::ode::Loads {
    softrod_core::ode::Loads {
        tip_force: rod.spec.tip.force,
        ..loads(&[])
    }
}

#[test]
fn rod_pressed_onto_a_sphere() {
    let (spec, center, r_exact) = cantilever_over_sphere(1e7, 1e-4);
    let rod = Rod::new(spec).unwrap();
    let l = tip_loads(&rod);
    let sol = solve(&rod, &l, None, &SolverOptions::default()).unwrap();
    assert_eq!(
        sol.stable,
        Some(true),
        "a beam pressed onto a ball is stable"
    );
    let rep = report(&rod, &l, &sol).unwrap().unwrap();
    let f = rep.force[0];
    // The penalty spreads the tip reaction over the last ~(EI/k)^(1/4) = 18 mm, which
    // moves its point of action inwards by a fraction of that: R errs by O(3 ell / (2 L))
    // relative (the tip deflection's lever); small-deflection theory adds
    // (P L^2 / EI)^2 ~ 6e-4.
    let ell = (1.0f64 / 1e7).powf(0.25);
    println!("R {} exact {r_exact} ell {ell}", f[2]);
    assert!(
        (f[2] - r_exact).abs() < 1.5 * ell / 0.5 * r_exact,
        "R {}",
        f[2]
    );
    // Global equilibrium: n(0) = F_tip + contact, to the solver's tolerance (1e-10 of
    // the force scale EI / L^2 = 4 N).
    for i in 0..3 {
        let want = rod.spec.tip.force[i] + f[i];
        assert!(
            (sol.base_force[i] - want).abs() < 1e-9,
            "{i}: {} {want}",
            sol.base_force[i]
        );
    }
    // Every contact force points along the sphere's radius, so about the base the contact
    // moment is (c - r0) x F: exact up to round-off.
    let c = center;
    let m = [
        c[1] * f[2] - c[2] * f[1],
        c[2] * f[0] - c[0] * f[2],
        c[0] * f[1] - c[1] * f[0],
    ];
    for i in 0..3 {
        assert!(
            (rep.moment[0][i] - m[i]).abs() < 1e-12,
            "{:?} {m:?}",
            rep.moment[0]
        );
    }
    // No penetration beyond the tolerance, and the contact is near the tip.
    assert!(rep.max_penetration > 0.0 && rep.max_penetration <= 1e-4);
    let first = rep.nodes.iter().position(|n| n.gap < 0.0).unwrap();
    assert!(first as f64 / 200.0 * 0.5 > 0.5 - 3.0 * ell);
    // Contact points lie on the sphere.
    for n in rep.nodes.iter().filter(|n| n.gap < 0.0) {
        let d: f64 = (0..3)
            .map(|i| (n.point[i] - c[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!((d - 0.05).abs() < 1e-12);
    }
    // The report checks what it is given: loads of another rod (a pressure it has no
    // channel for) or unknowns that are no shooting solution's are refused, not a panic.
    let mut wrong = l.clone();
    wrong.pressures = vec![1e3];
    let err = report(&rod, &wrong, &sol).unwrap_err();
    assert!(format!("{err}").contains("pressures"), "{err}");
    let mut short = sol.clone();
    short.x.truncate(2);
    let err = report(&rod, &l, &short).unwrap_err();
    assert!(format!("{err}").contains("solution.x"), "{err}");
}

#[test]
fn penetration_beyond_tolerance_is_an_error() {
    // The same press with a soft penalty (k = 1e4 N/m^2): the tip sinks far beyond 10 um.
    let (spec, _, _) = cantilever_over_sphere(1e4, 1e-5);
    let rod = Rod::new(spec).unwrap();
    match solve(&rod, &tip_loads(&rod), None, &SolverOptions::default()) {
        Err(SoftrodError::InvalidState { rule, value, .. }) => {
            assert_eq!(rule, Rule::Penetration);
            assert!(value > 1e-5);
        }
        other => panic!("expected a penetration error, got {other:?}"),
    }
}

#[test]
fn an_obstacle_through_the_unloaded_rod_is_refused_by_name() {
    // The 1 m horizontal beam with a plane 0.1 mm above its centreline (the unloaded rod
    // sinks 0.1 mm into the half-space below it, tolerance 50 um) and with a ball around its
    // middle: no load path starts there. Before any solve, every entry refuses it naming
    // the obstacle and the unloaded rod (it was a singular Jacobian or a failed load step).
    let mut through_plane = cantilever_over_plane(-1e-4, 1e6, 20);
    through_plane.obstacles[0].point = Some([0.0, 0.0, 1e-4]);
    let (mut through_ball, _, _) = cantilever_over_sphere(1e6, 1e-3);
    through_ball.obstacles[0].center = Some([0.5 * through_ball.sections[0].length, 0.0, 0.0]);
    // The deepest node is named: the plane is 0.1 mm into every node (the first, s = 0, is
    // reported), the rod passes through the ball's centre at s = 0.25 m (a node of 200 steps
    // over 0.5 m), 50 mm deep.
    let deepest = [
        "up to 1.000e-4 m into it (at s = 0.000000 m)",
        "up to 5.000e-2 m into it (at s = 0.250000 m)",
    ];
    for (spec, deepest) in [through_plane, through_ball].into_iter().zip(deepest) {
        let rod = Rod::new(spec).unwrap();
        let loads = tip_loads(&rod);
        let held = TipConstraint::Pinned {
            position: [1.0, 0.0, 0.0],
        };
        let results = [
            solve(&rod, &loads, None, &SolverOptions::default()).map(|_| ()),
            solve_constrained(&rod, &loads, &held, None, &SolverOptions::default()).map(|_| ()),
        ];
        for result in results {
            match result {
                Err(SoftrodError::InvalidParameter { field, rule, .. }) => {
                    assert_eq!(field, "obstacles[0]");
                    assert!(rule.contains("the unloaded rod"), "{rule}");
                    assert!(rule.contains(deepest), "{rule}");
                }
                other => panic!("expected an error naming obstacles[0], got {other:?}"),
            }
        }
    }
    // A plane tilted so that it cuts into the outer half of the unloaded beam, 0.2 mm deep
    // at the tip (four times the tolerance): the reported depth is the reference shape's
    // own (the unloaded integration used to carry the penalty, which bent the beam up out
    // of the plane and reported it shallower than it is).
    let mut tilted = cantilever_over_plane(0.0, 1e6, 20);
    tilted.obstacles[0].point = Some([0.5, 0.0, 0.0]);
    tilted.obstacles[0].normal = Some([-2e-4, 0.0, 0.5]);
    let rod = Rod::new(tilted).unwrap();
    match softrod_core::statics::contact::clear_at_rest(&rod, &tip_loads(&rod)) {
        Err(SoftrodError::InvalidParameter { rule, .. }) => {
            // Depth at the tip: 0.5 m x 2e-4 / sqrt(0.5^2 + 2e-4^2) = 2.000e-4 m.
            assert!(
                rule.contains("up to 2.000e-4 m into it (at s = 1.000000 m)"),
                "{rule}"
            );
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    // Touching within the tolerance is a start like any other.
    let mut touching = cantilever_over_plane(-1e-5, 1e6, 20);
    touching.obstacles[0].point = Some([0.0, 0.0, 1e-5]);
    let rod = Rod::new(touching).unwrap();
    assert!(softrod_core::statics::contact::clear_at_rest(&rod, &tip_loads(&rod)).is_ok());
}

/// A 0.2 m horizontal cantilever along +x (EI = 1e-3 N m^2) in `steps` RK4 steps, sagging
/// under a weight of 0.026 N/m by about 2 mm at x = 105 mm (small deflection: w = q x^2
/// (6 L^2 - 4 L x + x^2) / (24 EI)) onto a ball (or a pin across it: a capsule along y) of
/// radius 2 mm whose top is 1 mm below the clamp's height there (the rod's surface radius
/// is 0: stiffnesses given directly).
fn rod_over_small_ball(steps: usize, kind: ObstacleKind) -> DesignSpec {
    let sec = direct_section("rod", 0.2, 1e3, 5e2, 1e-3, 1e-3, 0.026 * 0.2 / G, steps);
    let mut d = design(vec![sec], HORIZONTAL, G);
    let mut ball = obstacle(kind, 1e6, 2e-4);
    match kind {
        ObstacleKind::Sphere => ball.center = Some([0.105, 0.0, -3e-3]),
        _ => {
            ball.start = Some([0.105, -0.01, -3e-3]);
            ball.end = Some([0.105, 0.01, -3e-3]);
        }
    }
    ball.radius = Some(2e-3);
    d.obstacles = vec![ball];
    d
}

/// The penalty acts at the integration points only. With steps of 20 mm the 4 mm ball at
/// x = 105 mm falls between the points of the step from 100 to 120 mm (its stages at 100,
/// 110 and 120 mm are more than 5 mm from its centre), so no point feels it and the rod
/// sags into it unhindered, about 1 mm deep: that shape is refused, naming the obstacle,
/// the place and the fix. With 2 mm steps the contact is resolved: the rod rests on the
/// ball and the rule holds everywhere.
#[test]
fn an_obstacle_between_integration_points_is_an_error_not_a_pass_through() {
    for kind in [ObstacleKind::Sphere, ObstacleKind::Capsule] {
        let rod = Rod::new(rod_over_small_ball(10, kind)).unwrap();
        match solve(&rod, &loads(&[]), None, &SolverOptions::default()) {
            Err(SoftrodError::InvalidState {
                rule,
                value,
                s,
                message,
                ..
            }) => {
                assert_eq!(rule, Rule::Penetration);
                // The search stops at a point deeper than the tolerance (0.2 mm) and at
                // most as deep as the unhindered sag reaches (about 1 mm).
                assert!(value > 2e-4 && value < 1.5e-3, "{value}");
                assert!((s - 0.105).abs() < 2e-3, "{s}");
                assert!(
                    message.contains("obstacles[0]") && message.contains("steps"),
                    "{message}"
                );
            }
            other => panic!("{kind:?}: expected a penetration error, got {other:?}"),
        }
        let rod = Rod::new(rod_over_small_ball(100, kind)).unwrap();
        let sol = solve(&rod, &loads(&[]), None, &SolverOptions::default()).unwrap();
        let rep = report(&rod, &loads(&[]), &sol).unwrap().unwrap();
        // The ball's contact is narrower than a step: the nodes may clear it while the
        // integration points between them carry it, so the report's node gaps only bound it.
        assert!(rep.max_penetration <= 2e-4);
        // It carries part of the rod's weight (0.0052 N in all).
        assert!(
            rep.force[0][2] > 0.0 && rep.force[0][2] < 0.0052,
            "{:?}",
            rep.force[0]
        );
    }
}

/// A soft cantilever (EI = 0.01 N m^2, 0.2 m, 20 g) over a pin across its path: a capsule
/// along y of radius 2 mm at x = 150 mm whose top is 3 mm below the clamp's height. Without
/// the pin the rod sags 13 mm there, wholly below it, and that free shape touches nothing:
/// it is an equilibrium of the model, but one the rod cannot reach from its unloaded shape
/// without passing through the pin. The solve returns the rod resting on the pin (found by
/// the load path from the unloaded rod, each level's nodes checked for crossings), in 2 mm
/// steps (the contact resolved).
#[test]
fn a_rod_sagging_onto_a_pin_rests_on_it_not_below_it() {
    let sec = direct_section("rod", 0.2, 1e3, 5e2, 1e-2, 1e-2, 0.02, 100);
    let mut d = design(vec![sec], HORIZONTAL, G);
    let mut pin = obstacle(ObstacleKind::Capsule, 1e6, 1e-3);
    pin.start = Some([0.15, -0.01, -5e-3]);
    pin.end = Some([0.15, 0.01, -5e-3]);
    pin.radius = Some(2e-3);
    let free_rod = Rod::new(d.clone()).unwrap();
    d.obstacles = vec![pin];
    let free = solve(&free_rod, &loads(&[]), None, &SolverOptions::default()).unwrap();
    let rod = Rod::new(d).unwrap();
    let sol = solve(&rod, &loads(&[]), None, &SolverOptions::default()).unwrap();
    let rep = report(&rod, &loads(&[]), &sol).unwrap().unwrap();
    // The pin carries part of the weight (0.196 N in all) and the rod lies on top of it:
    // its node at x = 150 mm no lower than the pin's top less the tolerance.
    assert!(
        rep.force[0][2] > 0.0 && rep.force[0][2] < 0.196,
        "{:?}",
        rep.force[0]
    );
    let shape = softrod_core::statics::shape(&rod, &loads(&[]), &sol);
    let k = (0..shape.s.len())
        .min_by(|&a, &b| {
            (shape.s[a] - 0.15)
                .abs()
                .total_cmp(&(shape.s[b] - 0.15).abs())
        })
        .unwrap();
    let r = shape.position[k];
    assert!(r[2] > -3e-3 - 1e-3, "rests on the pin: {r:?}");
    // Without the pin the same rod hangs below where the pin is.
    let fs = softrod_core::statics::shape(&free_rod, &loads(&[]), &free);
    assert!(fs.position[k][2] < -7e-3, "{:?}", fs.position[k]);
    // That free shape touches nothing, so it is an equilibrium of the rod with the pin
    // too, to the tolerance: the cold start's first test accepts it, and only the crossing
    // check sends the solve along the load path above (`contact::crossing`).
    let scale = rod.force_scale;
    let x6: Vec<f64> = (free.base_force.iter().map(|n| n / scale))
        .chain(free.base_moment.iter().map(|m| m / (scale * rod.length)))
        .collect();
    let xmax = x6.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    let r = residual(&rod, &loads(&[]), &x6).unwrap();
    let tol = SolverOptions::default().tol;
    assert!(r.iter().all(|v| v.abs() <= tol * xmax), "{r:?}");
    // Without continuation only the cold start is tried: its equilibrium below the pin is
    // refused, never returned.
    let once = SolverOptions {
        continuation: false,
        ..SolverOptions::default()
    };
    match solve(&rod, &loads(&[]), None, &once) {
        Err(SoftrodError::NotConverged { reason, .. }) => {
            assert!(reason.contains("beyond obstacles[0]"), "{reason}")
        }
        other => panic!("expected the crossing to be refused, got {other:?}"),
    }
}

/// The top of the pin of `rod_over_pin`, 3 mm below the rod's base, and its axis (m).
const PIN_TOP: f64 = -3e-3;
const PIN_AXIS: f64 = PIN_TOP - 2e-3;

/// A soft rod (0.2 m, EI = `ei`, 20 g) mounted horizontally along +x at (0, `y`, 0), in
/// 2 mm steps, with (`pin`) or without a pin across its path: a capsule along y of radius
/// 2 mm at x = 100 mm whose top is at `PIN_TOP` (k = 1e6 N/m^2, tolerance 1 mm).
fn rod_over_pin(ei: f64, y: f64, pin: bool) -> Rod {
    let sec = direct_section("rod", 0.2, 1e3, 5e2, ei, ei, 0.02, 100);
    let mut d = design(vec![sec], HORIZONTAL, G);
    d.mounting.base_position = [0.0, y, 0.0];
    if pin {
        let mut o = obstacle(ObstacleKind::Capsule, 1e6, 1e-3);
        o.start = Some([0.1, y - 0.01, PIN_AXIS]);
        o.end = Some([0.1, y + 0.01, PIN_AXIS]);
        o.radius = Some(2e-3);
        d.obstacles = vec![o];
    }
    Rod::new(d).unwrap()
}

/// The height of the node of `shape` nearest x = 0.1 m (over the pin).
fn height_over_pin(shape: &softrod_core::statics::Shape) -> f64 {
    let k = (0..shape.s.len())
        .min_by(|&a, &b| {
            (shape.position[a][0] - 0.1)
                .abs()
                .total_cmp(&(shape.position[b][0] - 0.1).abs())
        })
        .unwrap();
    shape.position[k][2]
}

/// The soft rod of `rod_over_pin` (EI = 3e-3 N m^2) clamped at its base and held at its tip
/// (clamped level, or pinned) 20 mm below the base at x = 0.2 m. Without the pin it passes
/// wholly below the pin at x = 0.1 m, touching nothing: an equilibrium of the model with
/// the pin too, but one the rod cannot reach from its unloaded shape without passing
/// through the pin. The solve returns the rod resting on the pin, from a cold start and
/// from a warm start at that shape; without continuation the warm start's equilibrium
/// beyond the pin is refused, never returned. A softer rod (EI = 1e-3 N m^2) clamped level
/// 10 mm below the base rests on the pin from a cold start too, where the solve's first
/// path (from the free rod lying on the pin, the tip moved to its pose) lands against the
/// pin's underside unless its levels are checked.
#[test]
fn a_held_rod_sagging_onto_a_pin_rests_on_it_not_below_it() {
    let soft = rod_over_pin(1e-3, 0.0, true);
    let clamp = TipConstraint::Clamped {
        position: [0.2, 0.0, -0.01],
        rotation: HORIZONTAL,
    };
    let sol =
        solve_constrained(&soft, &loads(&[]), &clamp, None, &SolverOptions::default()).unwrap();
    let z = height_over_pin(&sol.shape);
    assert!(z > PIN_AXIS, "soft rod: below the pin at z = {z}");
    let (free_rod, rod) = (
        rod_over_pin(3e-3, 0.0, false),
        rod_over_pin(3e-3, 0.0, true),
    );
    let l = loads(&[]);
    let opts = SolverOptions::default();
    let once = SolverOptions {
        continuation: false,
        ..opts
    };
    let tip = [0.2, 0.0, -0.02];
    for held in [
        TipConstraint::Clamped {
            position: tip,
            rotation: HORIZONTAL,
        },
        TipConstraint::Pinned { position: tip },
    ] {
        let free = solve_constrained(&free_rod, &l, &held, None, &opts).unwrap();
        // Below the pin's bottom (its axis less its radius).
        assert!(height_over_pin(&free.shape) < PIN_AXIS - 2e-3, "{held:?}");
        for guess in [None, Some(&free.solution.x[..])] {
            let sol = solve_constrained(&rod, &l, &held, guess, &opts)
                .unwrap_or_else(|e| panic!("{held:?} guess {}: {e}", guess.is_some()));
            // On top of the pin: above its axis, which parts its two sides (resting on it
            // the rod sinks at most the tolerance, 1 mm, into its 2 mm radius), and the
            // pin carries part of the weight.
            let z = height_over_pin(&sol.shape);
            assert!(
                z > PIN_AXIS,
                "{held:?} guess {}: below the pin at z = {z}",
                guess.is_some()
            );
            let rep = report(&rod, &l, &sol.solution).unwrap().unwrap();
            assert!(rep.force[0][2] > 0.0, "{held:?}: {:?}", rep.force[0]);
        }
        match solve_constrained(&rod, &l, &held, Some(&free.solution.x), &once) {
            Err(SoftrodError::NotConverged { reason, .. }) => {
                assert!(reason.contains("beyond obstacles[0]"), "{reason}")
            }
            Ok(sol) => panic!(
                "{held:?}: expected the crossing to be refused, got z = {}",
                height_over_pin(&sol.shape)
            ),
            Err(e) => panic!("{held:?}: expected the crossing to be refused, got {e}"),
        }
    }
}

/// Two soft rods of `rod_over_pin` (EI = 3e-3 N m^2) side by side, 40 mm apart, carry a
/// massless platform at their tips (each tip clamped to it where it is unloaded), with the
/// pin under one of them (rods[1]). Under their weight the rods sag 23 mm at x = 0.1 m
/// without the pin, wholly below where it is; the system's equilibrium found from the
/// unloaded rods has that rod resting on the pin, the other sagging freely. Without
/// continuation the equilibrium below the pin is refused, naming the rod and the obstacle.
#[test]
fn a_system_rod_sagging_onto_a_pin_rests_on_it_not_below_it() {
    let other = rod_over_pin(3e-3, -0.02, false);
    let (free_rod, rod) = (
        rod_over_pin(3e-3, 0.02, false),
        rod_over_pin(3e-3, 0.02, true),
    );
    // The platform frame is the rods' base frame (HORIZONTAL: y_platform = -y_world) at
    // the unloaded tips' midpoint, so the attachments are where the unloaded tips are.
    fn system<'a>(other: &'a Rod, second: &'a Rod) -> Vec<SystemRod<'a>> {
        let at = |rod, y: f64| SystemRod {
            rod,
            loads: loads(&[]),
            attachment: [0.0, -y, 0.0],
            attachment_rotation: common::IDENTITY,
        };
        vec![at(other, -0.02), at(second, 0.02)]
    }
    let platform = Platform {
        position: [0.2, 0.0, 0.0],
        rotation: HORIZONTAL,
        force: [0.0; 3],
        moment: [0.0; 3],
        mass: 0.0,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -G],
    };
    let opts = SolverOptions::default();
    let free = solve_system(&system(&other, &free_rod), &platform, None, &opts).unwrap();
    assert!(height_over_pin(&free.rods[1].shape) < PIN_AXIS - 2e-3);
    let rods = system(&other, &rod);
    let sys = solve_system(&rods, &platform, None, &opts).unwrap();
    // On top of the pin (above its axis, as for the held rod above), the pin carrying part
    // of its weight; the rod without the pin hangs lower.
    let z = height_over_pin(&sys.rods[1].shape);
    assert!(z > PIN_AXIS, "below the pin at z = {z}");
    let rep = report(&rod, &loads(&[]), &sys.rods[1].solution)
        .unwrap()
        .unwrap();
    assert!(rep.force[0][2] > 0.0, "{:?}", rep.force[0]);
    assert!(height_over_pin(&sys.rods[0].shape) < z);
    let once = SolverOptions {
        continuation: false,
        ..opts
    };
    match solve_system(&rods, &platform, None, &once) {
        Err(SoftrodError::NotConverged { reason, .. }) => {
            assert!(reason.contains("beyond rods[1].obstacles[0]"), "{reason}")
        }
        Ok(sys) => panic!(
            "expected the crossing to be refused, got z = {}",
            height_over_pin(&sys.rods[1].shape)
        ),
        Err(e) => panic!("expected the crossing to be refused, got {e}"),
    }
}

#[test]
fn contact_jacobian_is_exact() {
    // The shooting Jacobian (dual numbers through the contact law) against central
    // differences at the converged solution of the sphere press, and at a point off it.
    let (spec, _, _) = cantilever_over_sphere(1e6, 1e-3);
    let rod = Rod::new(spec).unwrap();
    let l = tip_loads(&rod);
    let sol = solve(&rod, &l, None, &SolverOptions::default()).unwrap();
    assert_eq!(sol.x.len(), 6);
    for shift in [0.0, 1e-3] {
        let x: Vec<f64> = sol.x.iter().map(|v| v + shift).collect();
        let (_, jac) = residual_and_jacobian(&rod, &l, &x).unwrap();
        let scale = jac.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
        for j in 0..6 {
            let h = 1e-6;
            let mut a = x.clone();
            let mut b = x.clone();
            a[j] += h;
            b[j] -= h;
            let (ra, rb) = (
                residual(&rod, &l, &a).unwrap(),
                residual(&rod, &l, &b).unwrap(),
            );
            for i in 0..6 {
                let fd = (ra[i] - rb[i]) / (2.0 * h);
                // Central differences err by h^2 R'''/6 (the ramp's curvature k / eps
                // enters only where a stage lies in the smoothing zone) plus round-off
                // 1e-16 |R| / h: 1e-5 of the largest entry bounds both here.
                assert!(
                    (fd - jac[i][j]).abs() <= 1e-5 * scale,
                    "shift {shift} J[{i}][{j}] = {} vs fd {fd}",
                    jac[i][j]
                );
            }
        }
    }
}

fn rejects(spec: DesignSpec, field: &str, rule_part: &str) {
    match Rod::new(spec) {
        Err(SoftrodError::InvalidParameter { field: f, rule, .. }) => {
            assert_eq!(f, field, "rule: {rule}");
            assert!(rule.contains(rule_part), "{rule}");
        }
        other => panic!("expected an error on {field}, got {other:?}"),
    }
}

#[test]
fn bad_obstacles_are_refused_with_field_and_rule() {
    let (good, _, _) = cantilever_over_sphere(1e6, 1e-3);
    let with = |f: &dyn Fn(&mut ObstacleSpec)| {
        let mut d = good.clone();
        f(&mut d.obstacles[0]);
        d
    };
    rejects(
        with(&|o| o.radius = Some(-0.01)),
        "obstacles[0].radius",
        "> 0",
    );
    rejects(
        with(&|o| o.radius = None),
        "obstacles[0].radius",
        "required",
    );
    rejects(
        with(&|o| o.stiffness = f64::NAN),
        "obstacles[0].stiffness",
        "finite",
    );
    rejects(
        with(&|o| o.tolerance = 0.0),
        "obstacles[0].tolerance",
        "> 0",
    );
    rejects(
        with(&|o| o.center = Some([0.0, f64::INFINITY, 0.0])),
        "obstacles[0].center[1]",
        "finite",
    );
    rejects(
        with(&|o| o.normal = Some([0.0, 0.0, 1.0])),
        "obstacles[0].normal",
        "sphere obstacle has no normal",
    );
    rejects(
        with(&|o| o.smoothing = Some(1.0)),
        "obstacles[0].smoothing",
        "at most the tolerance",
    );
    rejects(
        with(&|o| o.friction = -0.1),
        "obstacles[0].friction",
        ">= 0",
    );
    let mut plane = obstacle(ObstacleKind::Plane, 1e6, 1e-3);
    plane.point = Some([0.0; 3]);
    plane.normal = Some([0.0; 3]);
    let mut d = good.clone();
    d.obstacles = vec![plane];
    rejects(d, "obstacles[0].normal", "non-zero direction");
    let mut cap = obstacle(ObstacleKind::Capsule, 1e6, 1e-3);
    cap.start = Some([0.0; 3]);
    cap.end = Some([0.0; 3]);
    cap.radius = Some(0.1);
    let mut d = good.clone();
    d.obstacles = vec![cap];
    rejects(d, "obstacles[0].end", "must differ from start");
    // Friction: statics::solve refuses it and says why (the frictional load path is
    // statics::friction::solve, tests/suite/friction.rs).
    let rod = Rod::new(with(&|o| o.friction = 0.3)).unwrap();
    match solve(&rod, &loads(&[]), None, &SolverOptions::default()) {
        Err(SoftrodError::InvalidParameter { field, rule, .. }) => {
            assert_eq!(field, "obstacles[0].friction");
            assert!(rule.contains("loading path"));
        }
        other => panic!("{other:?}"),
    }
    // Models without contact refuse obstacles instead of ignoring them (the dynamics and
    // the linearisation carry contact: tests/suite/dynamics_contact.rs, linearise_loads.rs).
    match softrod_core::pcc::PccModel::new(&good) {
        Err(SoftrodError::InvalidParameter { field, .. }) => assert_eq!(field, "obstacles"),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("the PCC model accepted obstacles"),
    }
}

/// Inf-norm of the inverse of the shooting Jacobian at `x` (6 unknowns).
fn inverse_jacobian_norm(rod: &Rod, l: &softrod_core::ode::Loads, x: &[f64]) -> f64 {
    let (_, j) = residual_and_jacobian(rod, l, x).unwrap();
    let inv = nalgebra::Matrix6::from_fn(|i, k| j[i][k])
        .try_inverse()
        .unwrap();
    inv.row_iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// The cold solve of the finger on its table (`common::finger`) against the full contact
/// solve: the same loads with an unusable guess (not finite), which the solve ignores and
/// so follows the natural path from the unloaded rod in all six unknowns, without the
/// obstacle-free start. Both answers are equilibria to the solver's tolerance (the scaled
/// residual at most tol max(1, |x|)), so they differ by at most |J^-1| times the sum of
/// those residuals, to first order (the second order, |dx|^2, is far below): the bound
/// asserted. The stability verdict and the report's forces are the same.
fn assert_same_as_full_solve(rod: &Rod, l: &softrod_core::ode::Loads, what: &str) -> f64 {
    let opts = SolverOptions::default();
    let cold = solve(rod, l, None, &opts).unwrap();
    let full = solve(rod, l, Some(&[f64::NAN; 6]), &opts).unwrap();
    let xmax = cold.x.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    let bound = inverse_jacobian_norm(rod, l, &cold.x) * 2.0 * opts.tol * xmax;
    let dx = cold
        .x
        .iter()
        .zip(&full.x)
        .fold(0.0f64, |a, (u, v)| a.max((u - v).abs()));
    assert!(dx <= bound, "{what}: |dx| = {dx:e} > {bound:e}");
    for sol in [&cold, &full] {
        let r = residual(rod, l, &sol.x).unwrap();
        assert!(
            r.iter().all(|v| v.abs() <= opts.tol * xmax),
            "{what}: {r:?}"
        );
    }
    assert_eq!(cold.stable, Some(true), "{what}");
    assert_eq!(cold.stable, full.stable, "{what}");
    assert_eq!(cold.violations, full.violations, "{what}");
    let (a, b) = (
        report(rod, l, &cold).unwrap().unwrap(),
        report(rod, l, &full).unwrap().unwrap(),
    );
    let force = a.force[0][2];
    assert!(
        (force - b.force[0][2]).abs() <= 1e-6 * force.abs().max(1e-9),
        "{what}"
    );
    assert!(
        (a.max_penetration - b.max_penetration).abs() < 1e-9,
        "{what}"
    );
    force
}

/// Off the table (0 and 10 kPa: the finger's free equilibrium touches nothing, the penalty
/// adds exactly zero) a cold solve concludes from the equilibrium without the table after
/// one residual test: one Newton iteration, one load level, every contact force zero, the
/// penetration the (negative) gap; it is the full contact solve's answer and the answer of
/// Newton warm-started there. Touching it lightly (11 kPa: the free equilibrium sinks into
/// the table by less than its tolerance, so only the residual refuses it) or pressed on it
/// (30 kPa), Newton solves the contact from there, to the full solve's answer as before.
#[test]
fn a_cold_solve_that_touches_nothing_concludes_from_the_free_equilibrium() {
    let rod = Rod::new(common::finger(0.0)).unwrap();
    let opts = SolverOptions::default();
    for p in [0.0, 10e3] {
        let mut l = loads(&[p]);
        l.tensions = vec![0.0];
        let what = format!("{p} Pa");
        assert_eq!(assert_same_as_full_solve(&rod, &l, &what), 0.0, "{what}");
        let cold = solve(&rod, &l, None, &opts).unwrap();
        assert_eq!((cold.iterations, cold.load_steps), (1, 1), "{what}");
        let rep = report(&rod, &l, &cold).unwrap().unwrap();
        assert!(rep.force[0].iter().chain(&rep.end[0]).all(|f| *f == 0.0));
        assert!(rep.nodes.iter().all(|n| n.force == [0.0; 3]), "{what}");
        let gap = rep
            .nodes
            .iter()
            .map(|n| n.gap)
            .fold(f64::INFINITY, f64::min);
        assert!(gap > 0.0 && rep.max_penetration == -gap, "{what}");
        // Warm-started at the answer, Newton stops at its first test after its dual pass:
        // the same x, bit for bit, and the same verdict.
        let warm = solve(&rod, &l, Some(&cold.x), &opts).unwrap();
        assert_eq!(warm.x, cold.x, "{what}");
        assert_eq!((warm.iterations, warm.stable), (1, cold.stable), "{what}");
    }
    for p in [11e3, 30e3] {
        let mut l = loads(&[p]);
        l.tensions = vec![0.0];
        let what = format!("{p} Pa");
        assert!(assert_same_as_full_solve(&rod, &l, &what) > 0.0, "{what}");
        assert!(
            solve(&rod, &l, None, &opts).unwrap().iterations > 1,
            "{what}"
        );
    }
}
