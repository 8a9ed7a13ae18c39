//! Inverse statics with tendon tensions as inputs (crate::inverse, crate::jacobian): the
//! exact tension Jacobian against finite differences (also at a slack tendon, where it is
//! one-sided), round trips that recover known tensions, slack respected for a target that
//! would need a tendon to push, a hybrid rod with chambers and tendons, and the input rules.

// Index loops over inputs read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;
use common::*;
use softrod_core::inverse::{solve_inverse, InverseOptions};
use softrod_core::jacobian::{point_jacobian, Input, Probe};
use softrod_core::ode::Loads;
use softrod_core::spec::{DesignSpec, TendonSpec};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

/// The horizontal base of Till, Aloi and Rucker's tendon robot (d3 along world x, d1 down).
const TILL_BASE: [[f64; 3]; 3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]];
/// Tension range of the tests, N.
const T_MAX: f64 = 20.0;

fn tendon(channel: usize, angle_deg: f64) -> TendonSpec {
    TendonSpec {
        channel,
        distance: 0.01506,
        angle: angle_deg.to_radians(),
        distance_end: None,
        angle_end: None,
    }
}

/// The 0.5 m steel backbone of Till, Aloi and Rucker (IJRR 2019) with tendons at the given
/// angles, under gravity.
fn till(angles: &[f64]) -> Rod {
    let mut sec = direct_section(
        "backbone", 0.5, 628318.5, 251327.4, 0.1570796, 0.1256637, 0.012566, 40,
    );
    sec.outer_radius = Some(0.016);
    sec.tendons = angles
        .iter()
        .enumerate()
        .map(|(c, a)| tendon(c, *a))
        .collect();
    Rod::new(design(vec![sec], TILL_BASE, 9.81)).unwrap()
}

fn tensions(t: &[f64]) -> Loads {
    Loads {
        tensions: t.to_vec(),
        ..loads(&[])
    }
}

fn tight() -> SolverOptions {
    SolverOptions {
        tol: 1e-13,
        ..Default::default()
    }
}

/// d(tip)/d(tension) from the dual pass against differences of whole solves: central
/// differences (step 1e-3 N) at a pulled tendon; at a slack one (tension 0, where a tendon
/// cannot be pushed) the second-order one-sided difference (-3 f(0) + 4 f(h) - f(2h)) / 2h.
/// Both err by ~h^2 |y'''| (1e-6 relative for bending that is smooth on the scale of
/// 1 N) plus the solves' noise 1e-13 / h; 1e-5 of the column keeps both well below.
#[test]
fn tension_jacobian_matches_finite_differences() {
    let rod = till(&[0.0, 90.0, 180.0, 270.0]);
    let base = tensions(&[6.0, 0.0, 2.5, 0.0]);
    let sol = solve(&rod, &base, None, &tight()).unwrap();
    let inputs: Vec<Input> = (0..4).map(Input::Tension).collect();
    for probe in [Probe::tip(&rod), Probe::at(&rod, 0.2).unwrap()] {
        let jac = point_jacobian(&rod, &base, &sol, &inputs, &probe).unwrap();
        let at = |k: usize, d: f64| {
            let mut l = base.clone();
            l.tensions[k] += d;
            let s = solve(&rod, &l, Some(&sol.x), &tight()).unwrap();
            point_jacobian(&rod, &l, &s, &[], &probe).unwrap().position
        };
        let h = 1e-3;
        for k in 0..4 {
            let fd: [f64; 3] = if base.tensions[k] > 0.0 {
                let (p, m) = (at(k, h), at(k, -h));
                std::array::from_fn(|i| (p[i] - m[i]) / (2.0 * h))
            } else {
                let (f0, f1, f2) = (at(k, 0.0), at(k, h), at(k, 2.0 * h));
                std::array::from_fn(|i| (-3.0 * f0[i] + 4.0 * f1[i] - f2[i]) / (2.0 * h))
            };
            let err = dist(&fd, &jac.d_position[k]) / norm(&fd);
            println!("s = {}, tendon {k}: {err:.2e}", probe.s);
            assert!(norm(&fd) > 1e-6, "tendon {k} should move the point");
            assert!(err < 1e-5, "s = {}, tendon {k}: {err:.2e}", probe.s);
        }
    }
}

/// Two tendons 90 degrees apart and a position target made by a forward solve: three task
/// components, two inputs, consistent, so the tensions come back (to 1e-6 of the range:
/// the tip is reached to tol = 1e-10 L and the map's sensitivity is ~1e-3 L per N) and the
/// tip to 1e-9 L.
#[test]
fn round_trip_recovers_tensions() {
    let rod = till(&[0.0, 90.0]);
    let opts = InverseOptions::new(vec![[0.0, T_MAX]; 2]);
    let mut rng = Lcg(5);
    for _ in 0..12 {
        let t: Vec<f64> = (0..2)
            .map(|_| (rng.uniform() + 1.0) * 0.5 * T_MAX)
            .collect();
        let fwd = solve(&rod, &tensions(&t), None, &SolverOptions::default()).unwrap();
        let inv = solve_inverse(
            &rod,
            &tensions(&[0.0; 2]),
            &tip_target(&rod, fwd.tip.r),
            &opts,
            None,
        )
        .unwrap_or_else(|e| panic!("t = {t:?}: {e}"));
        assert!(inv.reached, "t = {t:?}: distance {}", inv.distance);
        assert!(inv.pressures.is_empty());
        for k in 0..2 {
            assert!(
                (inv.tensions[k] - t[k]).abs() < 1e-6 * T_MAX,
                "{:?} vs {t:?}",
                inv.tensions
            );
        }
        assert!(dist(&inv.solution.tip.r, &fwd.tip.r) < 1e-9 * rod.length);
        assert_eq!(inv.solution.stable, Some(true));
    }
}

/// Four tendons (redundant: four inputs for three position components): the least-tension
/// answer reaches the target, and of each opposed pair at most one pulls (pulling both only
/// compresses the rod, which the regularisation avoids; the compression this costs is
/// 1e-5 of the length per 20 N, far below what the bending needs).
#[test]
fn redundant_tendons_reach_with_least_tension() {
    let rod = till(&[0.0, 90.0, 180.0, 270.0]);
    let opts = InverseOptions::new(vec![[0.0, T_MAX]; 4]);
    let t = [9.0, 0.0, 0.0, 4.0];
    let fwd = solve(&rod, &tensions(&t), None, &SolverOptions::default()).unwrap();
    let inv = solve_inverse(
        &rod,
        &tensions(&[0.0; 4]),
        &tip_target(&rod, fwd.tip.r),
        &opts,
        None,
    )
    .unwrap();
    assert!(inv.reached, "distance {}", inv.distance);
    println!("tensions {:?}, active {:?}", inv.tensions, inv.active);
    for (a, b) in [(0, 2), (1, 3)] {
        assert!(
            inv.tensions[a].min(inv.tensions[b]) < 1e-3 * T_MAX,
            "opposed tendons {a} and {b} both pull: {:?}",
            inv.tensions
        );
    }
    assert!(inv.tensions.iter().all(|v| (0.0..=T_MAX).contains(v)));
}

/// A target that only a pushing tendon could reach (the mirror image of what pulling the
/// one tendon gives, across the rod's unloaded plane): the tendon stays slack (tension 0,
/// at its lower bound), the target is not reached, and the distance left is that of the
/// slack rod's tip.
#[test]
fn slack_tendon_is_respected() {
    let rod = till(&[90.0]);
    let opts = InverseOptions::new(vec![[0.0, T_MAX]]);
    let slack = solve(&rod, &tensions(&[0.0]), None, &tight()).unwrap();
    let pulled = solve(&rod, &tensions(&[10.0]), None, &tight()).unwrap();
    // Tendon at 90 deg from d1 bends the rod sideways (world y); mirror that across y = 0.
    let mut goal = pulled.tip.r;
    goal[1] = -goal[1];
    assert!(
        goal[1].abs() > 0.01,
        "the tendon should bend sideways: {goal:?}"
    );
    let inv = solve_inverse(
        &rod,
        &tensions(&[5.0]),
        &tip_target(&rod, goal),
        &opts,
        None,
    )
    .unwrap();
    assert!(!inv.reached);
    assert_eq!(inv.tensions, vec![0.0]);
    assert_eq!(inv.active, vec![-1]);
    let d = dist(&slack.tip.r, &goal);
    assert!(
        (inv.distance - d).abs() < 1e-9 * rod.length,
        "{} vs {d}",
        inv.distance
    );
}

/// Paper 002's actuator with a tendon beside its chambers: the inputs are the three
/// pressures then the tension; a forward solve's tip with pressures and a tension is
/// reached, with every input inside its bounds.
#[test]
fn hybrid_pressures_and_tension() {
    let mut spec: DesignSpec = p002_actuator(tilted(), 9.81, 12);
    // The tendon runs from the base through the cap into the body, where it ends.
    for sec in &mut spec.sections[..2] {
        sec.tendons = vec![TendonSpec {
            distance: 0.006,
            ..tendon(0, 60.0)
        }];
    }
    let rod = Rod::new(spec).unwrap();
    let mut bounds = vec![[0.0, 70e3]; 3];
    bounds.push([0.0, 2.0]);
    let opts = InverseOptions::new(bounds);
    let fwd_loads = Loads {
        tensions: vec![1.2],
        ..loads(&[20e3, 5e3, 40e3])
    };
    let fwd = solve(&rod, &fwd_loads, None, &SolverOptions::default()).unwrap();
    let start = Loads {
        tensions: vec![0.0],
        ..loads(&[0.0; 3])
    };
    let inv = solve_inverse(&rod, &start, &tip_target(&rod, fwd.tip.r), &opts, None).unwrap();
    assert!(inv.reached, "distance {}", inv.distance);
    assert_eq!(inv.pressures.len(), 3);
    assert_eq!(inv.tensions.len(), 1);
    assert_eq!(inv.active.len(), 4);
    assert!((0.0..=2.0).contains(&inv.tensions[0]));
    assert!(inv.pressures.iter().all(|p| (0.0..=70e3).contains(p)));
}

/// Input rules: a negative lower tension bound and a wrong count are refused by name.
#[test]
fn tension_bounds_rules() {
    let rod = till(&[0.0, 90.0]);
    let t = tip_target(&rod, [0.5, 0.0, 0.0]);
    let bad = InverseOptions::new(vec![[0.0, T_MAX], [-1.0, T_MAX]]);
    match solve_inverse(&rod, &tensions(&[0.0; 2]), &t, &bad, None) {
        Err(SoftrodError::InvalidParameter { field, .. }) => {
            assert_eq!(field, "tension_bounds[1][0]")
        }
        other => panic!("{other:?}"),
    }
    let short = InverseOptions::new(vec![[0.0, T_MAX]]);
    match solve_inverse(&rod, &tensions(&[0.0; 2]), &t, &short, None) {
        Err(SoftrodError::InvalidParameter { field, .. }) => assert_eq!(field, "bounds"),
        other => panic!("{other:?}"),
    }
    let none = Rod::new(design(
        vec![direct_section(
            "plain", 0.2, 500.0, 300.0, 0.02, 0.01, 0.01, 10,
        )],
        TILL_BASE,
        9.81,
    ))
    .unwrap();
    let err = solve_inverse(
        &none,
        &loads(&[]),
        &tip_target(&none, [0.2, 0.0, 0.0]),
        &InverseOptions::new(vec![]),
        None,
    )
    .unwrap_err();
    assert!(
        err.to_string()
            .contains("neither pressure channels nor tendons"),
        "{err}"
    );
}

/// An absurdly wide range (1e300 N) would overflow the scaled derivatives: refused by name
/// rather than answered with the start as the "closest pose".
#[test]
fn absurd_range_is_refused() {
    let rod = till(&[0.0, 90.0]);
    let opts = InverseOptions::new(vec![[0.0, T_MAX], [0.0, 1e300]]);
    let t = tip_target(&rod, [0.45, 0.05, 0.0]);
    match solve_inverse(&rod, &tensions(&[0.0; 2]), &t, &opts, None) {
        Err(SoftrodError::InvalidParameter { field, .. }) => assert_eq!(field, "tension_bounds[1]"),
        other => panic!("{other:?}"),
    }
}

/// A target far out of reach (inside the arc the robot cannot bend back to): the distance has
/// a flat valley along the opposed tendons' common pull, which only compresses the steel
/// backbone. The inverse stops at the closest pose (first-order stationary in the box)
/// within the default 100 iterations, instead of raising at max_iter (found by
/// tests/test_control_tendons.py's hypothesis test).
#[test]
fn flat_valley_of_an_unreachable_target_stops() {
    let rod = till(&[0.0, 90.0, 180.0, 270.0]);
    for hi in [2.0, 6.0] {
        let opts = InverseOptions::new(vec![[0.0, hi]; 4]);
        let t = tip_target(&rod, [0.171_809_581_362_631_97, 0.003_906_25, 0.0]);
        let inv = solve_inverse(&rod, &tensions(&[0.0; 4]), &t, &opts, None)
            .unwrap_or_else(|e| panic!("hi = {hi}: {e}"));
        println!(
            "hi {hi}: {:?}, distance {}, {} iterations",
            inv.tensions, inv.distance, inv.iterations
        );
        assert!(!inv.reached);
        assert!(inv.iterations < opts.max_iter);
        assert!(inv.tensions.iter().all(|v| (0.0..=hi).contains(v)));
    }
}

/// Tip of a forward solve at tensions t, tight (scaled residual 1e-13).
fn tip_at(rod: &Rod, t: &[f64]) -> [f64; 3] {
    solve(rod, &tensions(t), None, &tight()).unwrap().tip.r
}

/// Independent first-order check of an inverse answer t in the box [0, hi]^n: the gradient
/// g of 1/2 |e|^2 (e = (tip - goal) / L) in fractions of the range from central differences
/// of whole solves (second-order one-sided ones, inwards, next to a bound), and its
/// Frank-Wolfe gap sum_c max(g_c z_c, -g_c (1 - z_c), 0): the most the linearised cost can
/// fall anywhere in the box. Returns (gap, |J|_F |e|).
fn box_gap(rod: &Rod, goal: &[f64; 3], t: &[f64], hi: f64) -> (f64, f64) {
    let l = rod.length;
    let e_at = |tt: &[f64]| -> [f64; 3] {
        let r = tip_at(rod, tt);
        std::array::from_fn(|i| (r[i] - goal[i]) / l)
    };
    let e0 = e_at(t);
    let h = 1e-3 * hi;
    let (mut gap, mut jf2) = (0.0, 0.0);
    for c in 0..t.len() {
        let at = |d: f64| {
            let mut tt = t.to_vec();
            tt[c] += d;
            e_at(&tt)
        };
        // d e / d z (z = t / hi): per full range.
        let col: [f64; 3] = if t[c] - 2.0 * h < 0.0 {
            let (f1, f2) = (at(h), at(2.0 * h));
            std::array::from_fn(|i| (-3.0 * e0[i] + 4.0 * f1[i] - f2[i]) / (2.0 * h) * hi)
        } else if t[c] + 2.0 * h > hi {
            let (f1, f2) = (at(-h), at(-2.0 * h));
            std::array::from_fn(|i| (3.0 * e0[i] - 4.0 * f1[i] + f2[i]) / (2.0 * h) * hi)
        } else {
            let (p, m) = (at(h), at(-h));
            std::array::from_fn(|i| (p[i] - m[i]) / (2.0 * h) * hi)
        };
        let g: f64 = (0..3).map(|i| e0[i] * col[i]).sum();
        let z = t[c] / hi;
        gap += (g * z).max(-g * (1.0 - z)).max(0.0);
        jf2 += col.iter().map(|v| v * v).sum::<f64>();
    }
    (gap, jf2.sqrt() * norm(&e0))
}

/// Far out of reach (a point on the robot's axis 0.14 m from the base of the 0.5 m rod):
/// the closest pose pulls three tendons to their bound, shortening the steel backbone by
/// micrometres, and balances the fourth. The distance is nearly constant along the tip's
/// arc there (the target sits near its centre of curvature): a large-residual valley where
/// Gauss-Newton crawled (246 to 252 iterations, past the default 100). Now a few
/// iterations reach a pose that is stationary by a check independent of the solver: the
/// box gap of a central-difference gradient of whole solves is below 1e-6 |J|_F |e|. The
/// check's error: truncation h^2/3 |e'''| <= 3.3e-7 |J_c| per column at h = 1e-3 of the
/// range (the map is smooth on the range's scale), summed over 4 columns
/// (sum |J_c| <= 2 |J|_F): 7e-7 |J|_F |e|; the solves' noise, 1e-13 L / h = 1e-10 L per
/// column, is far below. The same check at an answer moved by 5 % of the range along the
/// valley fails (so it can fail).
#[test]
fn far_unreachable_target_converges_to_a_stationary_pose() {
    let rod = till(&[0.0, 90.0, 180.0, 270.0]);
    let goal = [0.140625, 0.0, 0.0];
    for hi in [4.0, 5.0, 20.0] {
        let opts = InverseOptions::new(vec![[0.0, hi]; 4]);
        let inv = solve_inverse(
            &rod,
            &tensions(&[0.0; 4]),
            &tip_target(&rod, goal),
            &opts,
            None,
        )
        .unwrap_or_else(|e| panic!("hi = {hi}: {e}"));
        let (gap, scale) = box_gap(&rod, &goal, &inv.tensions, hi);
        let mut moved = inv.tensions.clone();
        moved[0] -= 0.05 * hi;
        let (gap_moved, _) = box_gap(&rod, &goal, &moved, hi);
        println!(
            "hi {hi}: {:?}, distance {}, {} iterations, {} passes; gap {gap:.2e} of {scale:.2e} (moved: {gap_moved:.2e})",
            inv.tensions, inv.distance, inv.iterations, inv.passes
        );
        assert!(!inv.reached);
        assert!(inv.iterations <= 25, "{} iterations", inv.iterations);
        assert!(inv.tensions.iter().all(|v| (0.0..=hi).contains(v)));
        assert!(
            gap <= 1e-6 * scale,
            "hi = {hi}: gap {gap:.2e} of {scale:.2e}"
        );
        assert!(
            gap_moved > 1e-6 * scale,
            "hi = {hi}: moved gap {gap_moved:.2e}"
        );
    }
}
