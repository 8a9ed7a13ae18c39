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

/// Pressure range of every chamber, Pa.
const P_MAX: f64 = 20e3;

/// The recovered pressures against the true ones. How closely a reached target pins them
/// differs by direction (an equal change of the three pressures only stretches the arm, EA
/// = 1e4 N: nanometres per pascal; their differences bend it), so the bound comes from the
/// linearised map at the true solution: with J the Jacobian of the weighted task rows (the
/// position in L, and with `pose` the small rotation in rad) and every row within tol =
/// 1e-10 of its target, |J e| <= sqrt(rows) tol and |e| <= sqrt(rows) tol / sigma_min(J);
/// 10 times that leaves a margin. (The target's being reached is judged on the solved
/// point itself; this checks that the answer is the one set of pressures that reaches it.)
fn check_pressures(name: &str, rod: &Rod, s: f64, pose: bool, p: &[f64], got: &[f64]) {
    use softrod_core::jacobian::{point_jacobian, Input, Probe};

    let inputs: Vec<Input> = (0..3).map(Input::Pressure).collect();
    let jac = point_jacobian(
        rod,
        &loads(p),
        &forward(rod, p),
        &inputs,
        &Probe::at(rod, s).unwrap(),
    )
    .unwrap();
    let rows = if pose { 6 } else { 3 };
    let j = nalgebra::DMatrix::from_fn(rows, 3, |r, c| {
        if r < 3 {
            jac.d_position[c][r] / rod.length
        } else {
            jac.d_rotation[c][r - 3]
        }
    });
    let sigma_min = j.singular_values().min();
    let bound = 10.0 * (rows as f64).sqrt() * 1e-10 / sigma_min;
    let e: f64 = (0..3).map(|c| (got[c] - p[c]).powi(2)).sum::<f64>().sqrt();
    println!("{name}: pressure error {e:.2e} Pa, bound {bound:.2e} Pa");
    assert!(e <= bound, "{name}: {got:?} vs {p:?} (bound {bound} Pa)");
}

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
/// pressures come back (`check_pressures`) and the tip to 1e-9 L (the inverse's tol is
/// 1e-10 L, the statics' 1e-10).
#[test]
fn collocation_round_trip_recovers_pressures() {
    let rod = arm();
    let opts = options();
    let mut rng = Lcg(3);
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
        }
        check_pressures("round trip", &rod, rod.length, false, &p, &inv.pressures);
        check_answer(&rod, &inv);
        println!(
            "p = {p:?}: {} iterations, {} Jacobians",
            inv.iterations, inv.passes
        );
    }
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

/// Orientation targets and points between nodes exercise the rest of the collocation
/// linearisation: the rotation rows (dR = [d theta]x R from the implicit function
/// theorem's small rotations) and the partial step from a node. A pose at mid-length
/// (s = 0.51 m, between the nodes at 0.5 and 0.53125 m) from a forward solve: the whole
/// pose (position and orientation: six rows, three chambers, consistent) and the position
/// alone bring the pressures back (`check_pressures`) from a cold start. (The
/// orientation alone would not fix them: the chambers turn the section about
/// two axes only, and an equal change of the three pressures stretches the arm without
/// turning it, so the regularisation picks among the answers.)
#[test]
fn collocation_inverse_reaches_orientations_and_points_between_nodes() {
    use softrod_core::inverse::InverseTarget;
    use softrod_core::jacobian::{point_jacobian, Probe};

    let rod = arm();
    let opts = options();
    let p = [0.7 * P_MAX, 0.2 * P_MAX, 0.45 * P_MAX];
    let fwd = forward(&rod, &p);
    let s = 0.51;
    // The pose there, as the solution reports it (the Jacobian's value part).
    let at = point_jacobian(&rod, &loads(&p), &fwd, &[], &Probe::at(&rod, s).unwrap()).unwrap();
    let targets = [
        (
            "pose",
            InverseTarget {
                s,
                position: at.position,
                orientation: Some(at.rotation),
                position_weight: [1.0; 3],
                orientation_weight: 1.0,
            },
        ),
        (
            "position at s",
            InverseTarget {
                s,
                position: at.position,
                orientation: None,
                position_weight: [1.0; 3],
                orientation_weight: 0.0,
            },
        ),
    ];
    for (name, target) in targets {
        let inv = solve_inverse(&rod, &loads(&[0.0; 3]), &target, &opts, None)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(inv.reached, "{name}: {} {}", inv.distance, inv.angle);
        if target.orientation.is_some() {
            assert!(inv.angle <= 1e-9, "{name}: {}", inv.angle);
        }
        check_pressures(
            name,
            &rod,
            s,
            target.orientation.is_some(),
            &p,
            &inv.pressures,
        );
        // Newton on the joint problem from the best start candidate: a few iterations. A
        // wrong rotation or point derivative would stall it (linear convergence at best).
        assert!(inv.iterations <= 8, "{name}: {} iterations", inv.iterations);
    }
}

/// A warm start from a static solution (not an answer of the inverse): its collocation
/// unknowns give the start's equilibrium as it is (no iteration: the same z), and the
/// inverse from there reaches a nearby target in a few iterations without the cold start's
/// candidates. A rod that shooting solves, or a z of another grid, gives no such start.
#[test]
fn collocation_warm_start_from_a_static_solution() {
    use softrod_core::inverse::WarmStart;

    let rod = arm();
    let opts = options();
    let p0 = [0.3 * P_MAX, 0.5 * P_MAX, 0.2 * P_MAX];
    let start = forward(&rod, &p0);
    let z = &start.collocation.as_ref().unwrap().z;
    let sol = WarmStart::collocation_start(&rod, &loads(&p0), z, &opts.statics)
        .unwrap()
        .expect("a collocation rod's start");
    assert_eq!(sol.iterations, 0);
    assert_eq!(&sol.collocation.as_ref().unwrap().z, z);
    assert_eq!(sol.tip.r, start.tip.r);
    assert!(
        WarmStart::collocation_start(&rod, &loads(&p0), &z[1..], &opts.statics)
            .unwrap()
            .is_none()
    );
    let short = Rod::new(p002_actuator(HORIZONTAL, 9.81, 16)).unwrap();
    assert!(
        WarmStart::collocation_start(&short, &loads(&[0.0; 3]), z, &opts.statics)
            .unwrap()
            .is_none()
    );

    let p = [0.32 * P_MAX, 0.48 * P_MAX, 0.22 * P_MAX];
    let goal = forward(&rod, &p).tip.r;
    let warm = WarmStart {
        x: std::array::from_fn(|i| start.x[i]),
        solution: Some(sol),
        equilibrium: None,
        linearisation: None,
    };
    let inv = solve_inverse(
        &rod,
        &loads(&p0),
        &tip_target(&rod, goal),
        &opts,
        Some(&warm),
    )
    .unwrap();
    assert!(inv.reached, "{}", inv.distance);
    assert!(inv.iterations <= 4, "{}", inv.iterations);
    check_pressures(
        "from a static solution",
        &rod,
        rod.length,
        false,
        &p,
        &inv.pressures,
    );
}
