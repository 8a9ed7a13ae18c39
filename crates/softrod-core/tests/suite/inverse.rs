//! Inverse statics (crate::inverse): round trips that recover known pressures, bounds,
//! unreachable targets, redundant channels and warm starts; the exact pressure and tip-load
//! Jacobians (crate::jacobian) against finite differences of whole solves.

// Index loops over channels read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;
use common::*;
use softrod_core::inverse::{solve_inverse, InverseOptions};
use softrod_core::jacobian::{point_jacobian, Input, Probe};
use softrod_core::ode::Loads;
use softrod_core::spec::Frame;
use softrod_core::spec::{AxialSpec, DesignSpec, SwellingSpec};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

const HANGING: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
/// Paper 001's pressure range, Pa.
const P_MAX: f64 = 70e3;

fn actuator() -> Rod {
    Rod::new(p002_actuator(HANGING, 9.81, 16)).unwrap()
}

/// Paper 002's M3 law (Ogden, swelling, chamber offset) on the same actuator.
fn m3() -> DesignSpec {
    let mut d = p002_actuator(HANGING, 9.81, 12);
    d.sections[1].c_e = 2.82;
    d.sections[1].law = ogden_m3_law();
    d.tip.mass = 6e-3;
    d.tip.com_offset = [1e-3, 0.0, 4e-3];
    d
}

/// The round trip: random pressures inside the bounds, forward solve, invert the tip
/// position from a cold start. The map is injective (three chambers, position target), so
/// the pressures come back to 1e-6 of the range, and the tip to 1e-9 L.
#[test]
fn round_trip_recovers_pressures() {
    let rod = actuator();
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    let mut rng = Lcg(11);
    let mut worst_p: f64 = 0.0;
    let mut worst_tip: f64 = 0.0;
    let mut iters = 0;
    for _ in 0..200 {
        let p: Vec<f64> = (0..3)
            .map(|_| (rng.uniform() + 1.0) * 0.5 * P_MAX)
            .collect();
        let fwd = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
        let inv = solve_inverse(
            &rod,
            &loads(&[0.0; 3]),
            &tip_target(&rod, fwd.tip.r),
            &opts,
            None,
        )
        .unwrap_or_else(|e| panic!("p = {p:?}: {e}"));
        assert!(inv.reached, "p = {p:?}: distance {}", inv.distance);
        assert_eq!(inv.solution.stable, Some(true));
        for c in 0..3 {
            assert!((0.0..=P_MAX).contains(&inv.pressures[c]));
            worst_p = worst_p.max((inv.pressures[c] - p[c]).abs() / P_MAX);
        }
        worst_tip = worst_tip.max(inv.distance / rod.length);
        iters += inv.iterations;
    }
    println!("worst pressure error {worst_p:.2e} of the range, tip {worst_tip:.2e} L, {iters} iterations");
    assert!(worst_p <= 1e-6, "{worst_p}");
    assert!(worst_tip <= 1e-9, "{worst_tip}");
}

/// The other laws on the same actuator: EA(F) table (paper 004), bending stiffness that
/// grows with the stretch (paper 004 eq. 29), swelling chambers (paper 002 eq. 22).
fn other_laws() -> Vec<(&'static str, DesignSpec)> {
    let mut table = p002_actuator(HANGING, 9.81, 12);
    table.sections[1].law.axial = AxialSpec::Table {
        force: vec![-2.0, 0.0, 2.0, 6.0],
        stiffness: vec![40.0, 36.0, 30.0, 26.0],
    };
    let mut stretch = p002_actuator(HANGING, 9.81, 12);
    stretch.sections[1].law.stretch_bending = true;
    let mut swelling = p002_actuator(HANGING, 9.81, 12);
    swelling.sections[1].law.swelling = Some(SwellingSpec {
        c_p: 0.3,
        p_ref: 0.8e5,
    });
    vec![
        ("table", table),
        ("stretch_bending", stretch),
        ("swelling", swelling),
        ("m3", m3()),
    ]
}

/// Every law: round trips from cold starts recover the pressures.
#[test]
fn round_trip_for_every_law() {
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    let mut rng = Lcg(5);
    for (name, spec) in other_laws() {
        let rod = Rod::new(spec).unwrap();
        for _ in 0..10 {
            let p: Vec<f64> = (0..3)
                .map(|_| (rng.uniform() + 1.0) * 0.5 * P_MAX)
                .collect();
            let fwd = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
            let inv = solve_inverse(
                &rod,
                &loads(&[0.0; 3]),
                &tip_target(&rod, fwd.tip.r),
                &opts,
                None,
            )
            .unwrap_or_else(|e| panic!("{name}, p = {p:?}: {e}"));
            assert!(inv.reached, "{name}: {}", inv.distance);
            for c in 0..3 {
                assert!(
                    (inv.pressures[c] - p[c]).abs() <= 1e-6 * P_MAX,
                    "{name}: {:?} vs {p:?}",
                    inv.pressures
                );
            }
        }
    }
}

/// Warm starts along a path: each call starts from the previous answer and needs few passes.
#[test]
fn warm_start_follows_a_moving_target() {
    let rod = actuator();
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    // A 10 mm circle around the tip at 35 kPa in every chamber: inside the workspace.
    let fwd = solve(&rod, &loads(&[35e3; 3]), None, &SolverOptions::default()).unwrap();
    let t = fwd.tip.r;
    let start = [t[0] + 10e-3, t[1], t[2]];
    let mut prev = solve_inverse(
        &rod,
        &loads(&[0.0; 3]),
        &tip_target(&rod, start),
        &opts,
        None,
    )
    .unwrap();
    let mut passes = 0;
    for k in 1..=40 {
        let a = k as f64 * 0.5e-3 / 10e-3; // 0.5 mm per call on a 10 mm circle
        let goal = [t[0] + 10e-3 * a.cos(), t[1] + 10e-3 * a.sin(), t[2]];
        let inv = solve_inverse(
            &rod,
            &loads(&prev.pressures),
            &tip_target(&rod, goal),
            &opts,
            Some(&prev.warm_start()),
        )
        .unwrap();
        assert!(
            inv.reached && inv.distance <= 1e-9 * rod.length,
            "call {k}: {} {:.3e} it {} {:?} {:?}",
            inv.reached,
            inv.distance,
            inv.iterations,
            inv.pressures,
            inv.active
        );
        passes += inv.passes;
        prev = inv;
    }
    println!("{} dual passes per warm call", passes as f64 / 40.0);
    assert!(passes <= 40 * 4, "{passes}");
}

/// An unreachable target: the closest pose has a bound active, the flag is down, the
/// distance is the one left, and the bounds hold.
#[test]
fn unreachable_target_gives_closest_pose_on_the_boundary() {
    let rod = actuator();
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    // Far out to the side at the base's height: no pressure in 0-70 kPa bends this far.
    let goal = [0.3, 0.1, 0.0];
    let inv = solve_inverse(
        &rod,
        &loads(&[0.0; 3]),
        &tip_target(&rod, goal),
        &opts,
        None,
    )
    .unwrap();
    assert!(!inv.reached);
    assert!(inv.active.iter().any(|a| *a != 0), "{:?}", inv.active);
    for p in &inv.pressures {
        assert!((0.0..=P_MAX).contains(p));
    }
    let d = dist(&inv.point.r, &goal);
    assert!((d - inv.distance).abs() < 1e-15);
    // No corner of the box is closer (a coarse check; the sweep test in Python is finer).
    for corner in 0..8 {
        let p: Vec<f64> = (0..3)
            .map(|c| if corner >> c & 1 == 1 { P_MAX } else { 0.0 })
            .collect();
        let tip = solve(&rod, &loads(&p), None, &SolverOptions::default())
            .unwrap()
            .tip
            .r;
        // Two equilibria converged to the statics tolerance agree to ~1e-10 L.
        assert!(
            dist(&tip, &goal) >= inv.distance - 1e-9 * rod.length,
            "corner {p:?}: {} vs {} at {:?} it {}",
            dist(&tip, &goal),
            inv.distance,
            inv.pressures,
            inv.iterations
        );
    }
}

/// Two stacked modules with three channels each, position target: six channels for three
/// task dimensions. The answer reaches the target and is the least-pressure one: the
/// gradient of |p|^2 has no component along the free directions that keep the tip.
#[test]
fn redundant_channels_take_least_pressure() {
    let mut d = p002_actuator(HANGING, 9.81, 8);
    let mut body2 = p002_body(8);
    for (k, c) in body2.chambers.iter_mut().enumerate() {
        c.channel = 3 + k;
    }
    body2.name = "body2".into();
    d.sections.insert(2, body2);
    let rod = Rod::new(d).unwrap();
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 6]);
    let fwd = solve(
        &rod,
        &loads(&[20e3, 5e3, 0.0, 25e3, 0.0, 10e3]),
        None,
        &SolverOptions::default(),
    )
    .unwrap();
    let inv = solve_inverse(
        &rod,
        &loads(&[0.0; 6]),
        &tip_target(&rod, fwd.tip.r),
        &opts,
        None,
    )
    .unwrap();
    assert!(inv.reached, "{}", inv.distance);
    // Free channels and the tip Jacobian there.
    let free: Vec<usize> = (0..6).filter(|&c| inv.active[c] == 0).collect();
    let ld = loads(&inv.pressures);
    let inputs: Vec<Input> = free.iter().map(|&c| Input::Pressure(c)).collect();
    let jac = point_jacobian(&rod, &ld, &inv.solution, &inputs, &Probe::tip(&rod)).unwrap();
    let j = nalgebra::DMatrix::from_fn(3, free.len(), |r, k| jac.d_position[k][r]);
    // Projector onto the null space of J (tip kept), applied to the gradient p.
    let pinv = j.clone().pseudo_inverse(1e-14).unwrap();
    let n = nalgebra::DMatrix::identity(free.len(), free.len()) - &pinv * &j;
    let grad = nalgebra::DVector::from_fn(free.len(), |k, _| inv.pressures[free[k]] / P_MAX);
    let along = (&n * &grad).norm() / grad.norm();
    println!("active {:?}, null-space gradient {along:.2e}", inv.active);
    // The regularised phase converges to the point where the gradient of the task balances
    // eps = 1e-6 times that of |p|^2, and the polish moves by O(eps): the null-space
    // gradient is O(eps) relative (measured 9e-7).
    assert!(along < 10.0 * opts.regularisation, "{along}");
    // Less pressure than the one that made the target.
    let sq = |p: &[f64]| p.iter().map(|v| v * v).sum::<f64>();
    assert!(sq(&inv.pressures) <= sq(&[20e3, 5e3, 0.0, 25e3, 0.0, 10e3]));
}

/// Orientation target: reach a pose (position and rotation) of a forward solve.
#[test]
fn position_and_orientation_target() {
    let rod = Rod::new(m3()).unwrap();
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    let p = [40e3, 12e3, 3e3];
    let fwd = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
    let mut t = tip_target(&rod, fwd.tip.r);
    t.orientation = Some(fwd.tip.rot);
    t.orientation_weight = 1.0;
    let inv = solve_inverse(&rod, &loads(&[0.0; 3]), &t, &opts, None).unwrap();
    assert!(inv.reached, "{} {}", inv.distance, inv.angle);
    for c in 0..3 {
        assert!((inv.pressures[c] - p[c]).abs() < 1e-6 * P_MAX);
    }
    assert!(inv.angle < 1e-9);
}

/// A point along the rod: the end of the body section.
#[test]
fn point_along_the_rod() {
    let rod = actuator();
    let opts = InverseOptions::new(vec![[0.0, P_MAX]; 3]);
    let p = [10e3, 50e3, 20e3];
    let s = P002_CAP_A + P002_BODY * 0.5; // mid-body, between nodes? (12 steps over 110 mm)
    let fwd = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
    // The point's position from the exact Jacobian machinery (the same probe).
    let probe = Probe::at(&rod, s).unwrap();
    let at = point_jacobian(&rod, &loads(&p), &fwd, &[], &probe).unwrap();
    let mut t = tip_target(&rod, at.position);
    t.s = s;
    let inv = solve_inverse(&rod, &loads(&[0.0; 3]), &t, &opts, None).unwrap();
    assert!(inv.reached);
    for c in 0..3 {
        assert!(
            (inv.pressures[c] - p[c]).abs() < 1e-6 * P_MAX,
            "{:?}",
            inv.pressures
        );
    }
}

/// Exact d tip / d (pressures, tip force, tip moment) against central differences of whole
/// solves, for the linear law and paper 002's M3 law, at the tip and mid-body; the linear
/// law's actuator also stiffness-mapped (sigma away from 1), with d / d sigma.
#[test]
fn pressure_and_load_jacobians_match_finite_differences() {
    let tight = SolverOptions {
        tol: 1e-13,
        ..Default::default()
    };
    let mut mapped = p002_actuator(tilted(), 9.81, 12);
    for sec in &mut mapped.sections {
        sec.law.stiffness_map = true;
    }
    let specs = [
        (p002_actuator(tilted(), 9.81, 12), [1.0; 3]),
        (mapped, [0.9, 1.2, 0.8]),
    ]
    .into_iter()
    .chain(other_laws().into_iter().map(|(_, s)| (s, [1.0; 3])));
    for (spec, sigma) in specs {
        let rod = Rod::new(spec).unwrap();
        let base = Loads {
            pressures: vec![35e3, 12e3, 50e3],
            tip_force: [0.02, -0.01, 0.03],
            tip_moment: [1e-3, 2e-3, -1e-3],
            stiffness_scale: sigma,
            tensions: vec![],
            tip_frame: Frame::World,
        };
        let sol = solve(&rod, &base, None, &tight).unwrap();
        let mut inputs = vec![
            Input::Pressure(0),
            Input::Pressure(1),
            Input::Pressure(2),
            Input::TipForce(0),
            Input::TipForce(1),
            Input::TipForce(2),
            Input::TipMoment(0),
            Input::TipMoment(1),
            Input::TipMoment(2),
        ];
        if sigma != [1.0; 3] {
            inputs.extend((0..3).map(Input::StiffnessScale));
        }
        for probe in [Probe::tip(&rod), Probe::at(&rod, 0.07).unwrap()] {
            let jac = point_jacobian(&rod, &base, &sol, &inputs, &probe).unwrap();
            for (k, a) in inputs.iter().enumerate() {
                // Steps: 1 Pa, 1e-4 N, 1e-5 N m, 1e-4 of sigma (an O(1) factor): truncation
                // ~h^2 y''' relative 1e-8, solve noise 1e-13 / h ~ 1e-9 of a column.
                type Setter = Box<dyn Fn(&mut Loads, f64)>;
                let (h, set): (f64, Setter) = match *a {
                    Input::Pressure(c) => {
                        (1.0, Box::new(move |l: &mut Loads, d| l.pressures[c] += d))
                    }
                    Input::TipForce(j) => {
                        (1e-4, Box::new(move |l: &mut Loads, d| l.tip_force[j] += d))
                    }
                    Input::TipMoment(j) => {
                        (1e-5, Box::new(move |l: &mut Loads, d| l.tip_moment[j] += d))
                    }
                    Input::StiffnessScale(j) => (
                        1e-4,
                        Box::new(move |l: &mut Loads, d| l.stiffness_scale[j] += d),
                    ),
                    Input::Tension(_) => unreachable!("no tendons on this rod"),
                };
                let eval = |d: f64| {
                    let mut l = base.clone();
                    set(&mut l, d);
                    let s = solve(&rod, &l, Some(&sol.x), &tight).unwrap();
                    point_jacobian(&rod, &l, &s, &[], &probe).unwrap()
                };
                let (plus, minus) = (eval(h), eval(-h));
                let fd: [f64; 3] =
                    std::array::from_fn(|i| (plus.position[i] - minus.position[i]) / (2.0 * h));
                let scale = norm(&fd).max(1e-12);
                let err = dist(&fd, &jac.d_position[k]) / scale;
                // rotation: dR R^T from the difference of rotations
                let dr: [[f64; 3]; 3] = std::array::from_fn(|i| {
                    std::array::from_fn(|j| {
                        (plus.rotation[i][j] - minus.rotation[i][j]) / (2.0 * h)
                    })
                });
                let w = softrod_core::jacobian::small_rotation(&at_value(&jac), &dr);
                let werr = dist(&w, &jac.d_rotation[k]) / norm(&w).max(1e-12);
                assert!(
                    err < 1e-6 && werr < 1e-6,
                    "{a:?} at s = {}: {err:.2e} {werr:.2e}",
                    probe.s
                );
            }
        }
    }
}

fn at_value(j: &softrod_core::jacobian::PointJacobian) -> [[f64; 3]; 3] {
    j.rotation
}
