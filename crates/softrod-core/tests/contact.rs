//! Contact with rigid obstacles (docs/contact.md): a cantilever resting on a plane against
//! the beam on a rigid support, a rod pressed onto a sphere, the penetration rule, global
//! equilibrium, the exact shooting Jacobian, and bad obstacle input.

mod common;

use common::{design, direct_section, loads, HORIZONTAL, IDENTITY};
use softrod_core::error::{Rule, SoftrodError};
use softrod_core::spec::obstacle::{ObstacleKind, ObstacleSpec};
use softrod_core::statics::contact::report;
use softrod_core::statics::{residual, residual_and_jacobian, solve, SolverOptions};
use softrod_core::{DesignSpec, Rod};

fn obstacle(kind: ObstacleKind, stiffness: f64, tolerance: f64) -> ObstacleSpec {
    ObstacleSpec {
        kind,
        point: None,
        normal: None,
        center: None,
        axis: None,
        start: None,
        end: None,
        radius: None,
        stiffness,
        tolerance,
        smoothing: None,
        friction: 0.0,
    }
}

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
    let mut plane = obstacle(ObstacleKind::Plane, k, 1e-3);
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
    for k in [1e6, 1.6e7] {
        let rod = Rod::new(cantilever_over_plane(c, k, 400)).unwrap();
        let l = loads(&[]);
        let sol = solve(&rod, &l, None, &SolverOptions::default()).unwrap();
        let rep = report(&rod, &l, &sol).unwrap();
        // The penalty is a Winkler foundation of modulus k: near the first contact the
        // beam's deflection decays over 1/beta = (4 EI / k)^(1/4), which smears the point
        // reaction over that length and moves the clamp's reactions by O(1/(beta a)).
        let ell = (4.0 * EI / k).powf(0.25);
        let ef = (sol.base_force[2] - f0).abs() / f0;
        let em = (sol.base_moment[1].abs() - m0).abs() / m0;
        println!("k {k:e}: 1/beta a {:.3e} force err {ef:.3e} moment err {em:.3e}", ell / a);
        // First order in 1/(beta a) with a constant of order one.
        assert!(ef < 2.0 * ell / a && em < 4.0 * ell / a, "k {k}: {ef} {em}");
        errors.push((ell, ef, em));
        // Where the beam lies flat the support carries its weight: q per length.
        let flat = rep.nodes.len() * 9 / 10;
        let fz = rep.nodes[flat].force[2];
        assert!((fz - Q).abs() < 1e-6, "line force {fz}");
        // Force balance: clamp + contact = weight, to the solver's tolerance.
        let total: f64 = rep.force.iter().map(|f| f[2]).sum();
        assert!((sol.base_force[2] + total - Q).abs() < 1e-9 * Q);
    }
    // The error falls like 1/(beta a) ~ k^(-1/4): 16x stiffer halves it (order 1 +- 0.3).
    let order_f = (errors[0].1 / errors[1].1).ln() / (errors[0].0 / errors[1].0).ln();
    let order_m = (errors[0].2 / errors[1].2).ln() / (errors[0].0 / errors[1].0).ln();
    assert!((order_f - 1.0).abs() < 0.3 && (order_m - 1.0).abs() < 0.3, "orders {order_f} {order_m}");
}
