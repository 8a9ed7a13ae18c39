//! Inverse statics of a long, soft arm that statics solves by collocation (single
//! shooting's growth exponent beyond the limit: docs/model.md, "Collocation"): every
//! iterate is a converged collocation equilibrium and its Jacobian comes from the
//! collocation equations. Round trips recover known pressures; warm starts follow a moving
//! target in few solves; an unreachable target ends at a point that no feasible move
//! improves (checked by whole solves); the answer is the forward solve's equilibrium.

// Index loops over channels read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;
use common::*;
use softrod_core::inverse::{solve_inverse, InverseOptions, InverseSolution};
use softrod_core::spec::{DesignSpec, MaterialSpec};
use softrod_core::statics::{solve, Solution, SolverOptions};
use softrod_core::validity::Policy;
use softrod_core::Rod;

/// Pressure range of every chamber, Pa: 20 kPa bends the arm by about a quarter turn.
const P_MAX: f64 = 20e3;

fn statics() -> SolverOptions {
    SolverOptions {
        // Clamped horizontally, the arm bends at the clamp beyond the default fibre-stretch
        // range (collocation.rs, `long_soft_rods_are_solved_by_collocation`).
        on_invalid: Policy::Warn,
        ..Default::default()
    }
}

fn options() -> InverseOptions {
    let mut opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    opts.statics = statics();
    opts
}

/// A 1 m soft arm (E = 100 kPa, r = 12.5 mm, 1000 kg/m^3) with three chambers 120 deg
/// apart, clamped horizontally under its own weight.
fn arm() -> Rod {
    let mat = MaterialSpec {
        youngs_modulus: 100e3,
        shear_modulus: 100e3 / 3.0,
        density: 1000.0,
    };
    let chambers = vec![
        chamber(2e-3, 5e-3, 0.0, 0),
        chamber(2e-3, 5e-3, 120.0, 1),
        chamber(2e-3, 5e-3, 240.0, 2),
    ];
    let sec = geometry_section("arm", 1.0, 0.0125, 0.0, mat, chambers, 32);
    let spec: DesignSpec = design(vec![sec], HORIZONTAL, 9.81);
    Rod::new(spec).unwrap()
}

fn forward(rod: &Rod, p: &[f64]) -> Solution {
    let sol = solve(rod, &loads(p), None, &statics()).unwrap();
    assert!(sol.collocation.is_some(), "routed to collocation");
    sol
}

/// The answer is an equilibrium of its pressures: the forward solve lands on the same
/// point. Both are collocation solves to the statics tolerance (1e-10 of the scaled
/// unknowns, of order 1), so their tips agree to about that times L.
fn check_answer(rod: &Rod, inv: &InverseSolution) {
    assert!(inv.solution.collocation.is_some());
    assert_eq!(inv.solution.stable, Some(true));
    let fwd = forward(rod, &inv.pressures);
    assert!(
        dist(&fwd.tip.r, &inv.point.r) <= 1e-9 * rod.length,
        "{:?} vs {:?}",
        fwd.tip.r,
        inv.point.r
    );
}

/// Random pressures inside the bounds, forward solve, invert the tip position from a cold
/// start: three chambers and a position target make the map injective here, so the
/// pressures come back to 1e-6 of the range (the tip to 1e-9 L, the inverse's tol is
/// 1e-10 L and the statics' 1e-10: a pressure error of 1e-6 moves the tip by about 1e-7 L,
/// 100x the tip tolerance, so the bound cannot pass by a loose tip).
#[test]
fn collocation_round_trip_recovers_pressures() {
    let rod = arm();
    let opts = options();
    let mut rng = Lcg(3);
    let mut worst_p: f64 = 0.0;
    for _ in 0..4 {
        let p: Vec<f64> = (0..3)
            .map(|_| (rng.uniform() + 1.0) * 0.4 * P_MAX + 0.1 * P_MAX)
            .collect();
        let fwd = forward(&rod, &p);
        let inv = solve_inverse(
            &rod,
            &loads(&[0.0; 3]),
            &tip_target(&rod, fwd.tip.r),
            &opts,
            None,
        )
        .unwrap_or_else(|e| panic!("p = {p:?}: {e}"));
        assert!(inv.reached, "p = {p:?}: distance {}", inv.distance);
        assert!(inv.distance <= 1e-9 * rod.length, "{}", inv.distance);
        for c in 0..3 {
            assert!((0.0..=P_MAX).contains(&inv.pressures[c]));
            worst_p = worst_p.max((inv.pressures[c] - p[c]).abs() / P_MAX);
        }
        check_answer(&rod, &inv);
        println!(
            "p = {p:?}: {} iterations, {} Jacobians",
            inv.iterations, inv.passes
        );
    }
    println!("worst pressure error {worst_p:.2e} of the range");
    assert!(worst_p <= 1e-6, "{worst_p}");
}

/// Warm starts along a path (0.3 mm steps on a 3 mm circle: the arm hangs under its weight,
/// whose tension lets the chambers move the tip sideways by about 4 mm only): each call starts from the
/// previous answer's equilibrium (its collocation unknowns) and reaches the target in a few
/// Newton steps of the joint problem, each one solve and one Jacobian.
#[test]
fn collocation_warm_start_follows_a_moving_target() {
    let rod = arm();
    let opts = options();
    let centre = forward(&rod, &[0.4 * P_MAX; 3]).tip.r;
    let radius = 0.003;
    let mut prev: Option<InverseSolution> = None;
    let mut passes = 0;
    let calls = 12;
    for k in 0..=calls {
        let a = k as f64 * 0.1; // 0.3 mm of arc per call
                                // The circle lies in the (y, z) plane.
        let goal = [
            centre[0],
            centre[1] + radius * a.cos(),
            centre[2] + radius * a.sin(),
        ];
        let start = prev.as_ref().map_or(vec![0.0; 3], |p| p.pressures.clone());
        let warm = prev.as_ref().map(|p| p.warm_start());
        let inv = solve_inverse(
            &rod,
            &loads(&start),
            &tip_target(&rod, goal),
            &opts,
            warm.as_ref(),
        )
        .unwrap_or_else(|e| panic!("call {k}: {e}"));
        assert!(
            inv.reached && inv.distance <= 1e-9 * rod.length,
            "call {k}: {} {:.3e} {:?} {:?} it {}",
            inv.reached,
            inv.distance,
            inv.pressures,
            inv.active,
            inv.iterations
        );
        if k > 0 {
            passes += inv.passes;
            assert!(inv.iterations <= 6, "call {k}: {}", inv.iterations);
        }
        prev = Some(inv);
    }
    let last = prev.unwrap();
    check_answer(&rod, &last);
    println!(
        "{:.1} Jacobians per warm call",
        passes as f64 / calls as f64
    );
    // Newton on the joint problem from 0.3 mm away: two or three steps.
    assert!(passes <= calls * 5, "{passes}");

    // The same target again from the answer: its own equilibrium, checked, not moved.
    let again = solve_inverse(
        &rod,
        &loads(&last.pressures),
        &tip_target(&rod, last.point.r),
        &opts,
        Some(&last.warm_start()),
    )
    .unwrap();
    assert!(again.reached);
    assert_eq!(again.pressures, last.pressures);
}

/// An unreachable target (far above the clamp): the answer is a closest feasible pose.
/// Checked by whole solves: no move of 1 % of the range along any channel (inside the box)
/// brings the tip closer, beyond the solves' own error.
#[test]
fn collocation_unreachable_target_is_locally_closest() {
    let rod = arm();
    let opts = options();
    let goal = [0.2, 0.0, 0.9];
    let inv = solve_inverse(
        &rod,
        &loads(&[0.0; 3]),
        &tip_target(&rod, goal),
        &opts,
        None,
    )
    .unwrap();
    assert!(!inv.reached);
    for p in &inv.pressures {
        assert!((0.0..=P_MAX).contains(p));
    }
    assert!((dist(&inv.point.r, &goal) - inv.distance).abs() < 1e-15);
    check_answer(&rod, &inv);
    for c in 0..3 {
        for sign in [-1.0, 1.0] {
            let mut p = inv.pressures.clone();
            p[c] = (p[c] + sign * 0.01 * P_MAX).clamp(0.0, P_MAX);
            if p[c] == inv.pressures[c] {
                continue; // at the bound: that move leaves the box
            }
            let d = dist(&forward(&rod, &p).tip.r, &goal);
            // A first-order stationary point: a 1 % move changes the distance by second
            // order only (about 1e-4 of the range's effect), never lowering it by more
            // than the solves' error (1e-9 L).
            assert!(
                d >= inv.distance - 1e-9,
                "channel {c} {sign}: {d} < {}",
                inv.distance
            );
        }
    }
}
