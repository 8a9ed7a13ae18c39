//! A held tip (pinned or clamped) together with obstacles in dynamics (docs/dynamics.md
//! "Held tip", docs/contact.md "Dynamics"): a beam held at both ends sags onto a plane. A
//! damped run settles on the static equilibrium of the same problem; an undamped
//! frictionless run keeps its energy books (penalty potential included); the step
//! Jacobian with both matches central differences.

use crate::common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, SigmaMap, Simulator};
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::{DesignSpec, MaterialSpec};
use softrod_core::statics::constraint::{solve_constrained, TipConstraint};
use softrod_core::statics::SolverOptions;
use softrod_core::Rod;
use std::f64::consts::PI;

const L: f64 = 0.5;
const R: f64 = 0.005;
const E: f64 = 1e6;
const RHO: f64 = 1000.0;
/// Gravity across the beam: q L^4 / (384 EI) = 4 mm of sag clamped-clamped without the
/// plane (8 mm clamped-pinned), twice the plane's distance below the surface.
const G: f64 = 0.15;
/// The plane's height: 2 mm below the straight beam's surface.
const PLANE: f64 = -(R + 2e-3);

/// The beam's first clamped-clamped bending frequency (Euler-Bernoulli), rad/s.
fn omega1() -> f64 {
    let ei = E * PI * R.powi(4) / 4.0;
    let rho_a = RHO * PI * R * R;
    4.730_040_744_862f64.powi(2) / (L * L) * (ei / rho_a).sqrt()
}

/// The beam along +x over the plane, penalty 50 N/m^2 (the weight's 12 mN/m sinks it by
/// q / k = 0.24 mm where it lies on the plane; tolerance 3 mm), `friction`, damping `tau`.
fn beam_over_plane(steps: usize, tau: f64, friction: f64) -> DesignSpec {
    let material = MaterialSpec {
        youngs_modulus: E,
        shear_modulus: E / 3.0,
        density: RHO,
    };
    let sec = geometry_section("beam", L, R, 0.0, material, vec![], steps);
    let mut spec = design(vec![sec], HORIZONTAL, G);
    spec.dynamics.damping_time = tau;
    let mut plane = obstacle(ObstacleKind::Plane, 50.0, 3e-3);
    plane.point = Some([0.0, 0.0, PLANE]);
    plane.normal = Some([0.0, 0.0, 1.0]);
    plane.friction = friction;
    spec.obstacles = vec![plane];
    spec
}

fn held(kind: &str) -> TipConstraint {
    let position = [L, 0.0, 0.0];
    match kind {
        "pinned" => TipConstraint::Pinned { position },
        _ => TipConstraint::Clamped {
            position,
            rotation: HORIZONTAL,
        },
    }
}

fn sim(spec: DesignSpec, initial: Initial, opts: DynOptions, c: TipConstraint) -> Simulator {
    Simulator::with_constraint(
        Rod::new(spec).unwrap(),
        &[],
        &[],
        initial,
        opts,
        SigmaMap::None,
        [0.0; 3],
        [0.0; 3],
        c,
    )
    .unwrap()
}

/// Released straight (at rest, 2 mm above the plane) with Kelvin-Voigt damping tau = 0.5 /
/// omega1 (the first mode's damping ratio 0.25; the modes in contact, stiffer, are damped
/// more), the beam sags onto the plane and settles after 60 periods of the first mode
/// (envelope exp(-0.25 * 2 pi * 60) ~ 1e-41) on the static equilibrium of the same
/// discretisation (the run's 'static' start, from the shooting statics with the same
/// constraint and plane) to the Newton tolerance: 1e-12 of the scaled residual, ~1e-12 L
/// in position, times 100 for the banded system's condition with contact. At rest the
/// base, the tip reaction and the plane carry the weight: n(0) = F_r + F_contact + W to
/// 1e-9 W. The shooting statics and the collocation converge to each other as the grids
/// refine.
#[test]
fn damped_held_runs_in_contact_settle_on_the_static_equilibrium() {
    for kind in ["pinned", "clamped"] {
        let mut off_shooting = vec![];
        let mut deflection = 0.0;
        for steps in [8, 32] {
            let om = omega1();
            let spec = beam_over_plane(steps, 0.5 / om, 0.0);
            let opts = DynOptions {
                dt: 0.1 / om,
                tol: 1e-12,
                ..Default::default()
            };
            let rest = sim(spec.clone(), Initial::Static, opts, held(kind));
            let mut s = sim(spec.clone(), Initial::Straight, opts, held(kind));
            let mut deepest = f64::NEG_INFINITY;
            for _ in 0..(60.0 * 2.0 * PI / 0.1) as usize {
                s.step(&[]).unwrap();
                deepest = deepest.max(s.contact_state().unwrap().max_penetration);
            }
            assert!(
                deepest > 0.0 && deepest <= 3e-3,
                "{kind}: deepest {deepest}"
            );
            let worst = s
                .shape()
                .iter()
                .zip(rest.shape())
                .map(|(a, b)| dist(a, b))
                .fold(0.0, f64::max);
            let c = s.contact_state().unwrap();
            let (n0, _) = s.base_wrench();
            let (fr, _) = s.tip_reaction();
            let w = RHO * PI * R * R * L * G;
            let balance = (0..3)
                .map(|k| {
                    let weight = if k == 2 { -w } else { 0.0 };
                    (n0[k] - (fr[k] + c.force[k] + weight)).abs()
                })
                .fold(0.0, f64::max);
            // The shooting statics of the same problem, at the collocation's mid-span node.
            let rod = Rod::new(spec).unwrap();
            let shot = solve_constrained(
                &rod,
                &loads(&[]),
                &held(kind),
                None,
                &SolverOptions {
                    tol: 1e-12,
                    ..Default::default()
                },
            )
            .unwrap();
            let mid = shot.shape.s.len() / 2;
            assert!((shot.shape.s[mid] - 0.5 * L).abs() < 1e-12);
            let ds = dist(&s.shape()[steps / 2], &shot.shape.position[mid]);
            eprintln!(
                "{kind} {steps}: settled within {worst:.2e} m of the static start; mid-span {:.4e} m, {ds:.2e} m off shooting; contact {:.4e} N of the weight {w:.4e} N, balance {balance:.1e} N; deepest {deepest:.2e} m",
                s.shape()[steps / 2][2],
                c.force[2]
            );
            assert!(worst < 1e-10 * L, "{kind} {steps}: {worst:e}");
            assert!(
                c.force[2] > 0.1 * w,
                "{kind}: the plane carries part of the weight"
            );
            assert!(balance < 1e-9 * w, "{kind}: {balance:e}");
            assert_eq!(shot.solution.stable, Some(true), "{kind}");
            off_shooting.push(ds);
            deflection = s.shape()[steps / 2][2].abs();
        }
        // Converging, at first order at least: the ramp's kinks at the contact zone's
        // edges fall between nodes (measured: 3.3e-7 m to 6.6e-8 m from 8 to 32 intervals,
        // pinned); at 32 intervals within 1e-4 of the mid-span deflection.
        assert!(
            off_shooting[1] < off_shooting[0] / 4.0 && off_shooting[1] < 1e-4 * deflection,
            "{kind}: {off_shooting:?}"
        );
    }
}

/// On a plane with Coulomb friction the held beam's static start is the frictionless one
/// (the regularised friction carries no force at rest; the start once refused to run,
/// its frictionless statics seeing the friction): bitwise the same shape, and then the
/// friction acts as the beam moves (the tip pose is moved along the plane over 20 steps,
/// dragging the beam over it).
#[test]
fn held_run_on_a_frictional_plane_starts_from_the_frictionless_rest() {
    let om = omega1();
    let opts = DynOptions {
        dt: 0.1 / om,
        ..Default::default()
    };
    let mut runs: Vec<Simulator> = [0.5, 0.0]
        .iter()
        .map(|mu| {
            sim(
                beam_over_plane(16, 0.5 / om, *mu),
                Initial::Static,
                opts,
                held("pinned"),
            )
        })
        .collect();
    assert_eq!(runs[0].shape(), runs[1].shape());
    for s in &mut runs {
        for k in 1..=20 {
            s.set_tip_pose(TipConstraint::Pinned {
                position: [L, 1e-3 * k as f64, 0.0],
            })
            .unwrap();
            s.step(&[]).unwrap();
        }
    }
    let (rough, smooth) = (runs[0].shape(), runs[1].shape());
    let mid = rough.len() / 2;
    // The friction holds the middle back against the drag.
    eprintln!(
        "mid-span y: rough {:.4e} m, smooth {:.4e} m",
        rough[mid][1], smooth[mid][1]
    );
    assert!(rough[mid][1] < smooth[mid][1]);
}

/// Undamped and frictionless (the trapezoidal rule, alpha = -0.5: no numerical damping),
/// the clamped beam released straight falls onto the plane and swings on it. The energy
/// books (kinetic, elastic, gravity, penalty potential; no work: the held pose is fixed)
/// balance up to the scheme's second-order error: halving the step quarters the balance
/// (ratio >= 3 accepted: 4 less higher-order terms), and at 200 steps per period of the
/// first mode it stays below 1 % of the energy moved (the contact's (omega_c dt)^2 / 12
/// per unit of the energy it holds).
#[test]
fn undamped_held_run_in_contact_keeps_its_energy() {
    let run = |n: usize| -> (f64, f64) {
        let period = 2.0 * PI / omega1();
        let opts = DynOptions {
            dt: period / n as f64,
            alpha: -0.5,
            tol: 1e-12,
            ..Default::default()
        };
        let mut s = sim(
            beam_over_plane(8, 0.0, 0.0),
            Initial::Straight,
            opts,
            held("clamped"),
        );
        let (mut worst, mut penalty): (f64, f64) = (0.0, 0.0);
        let mut moved: f64 = 0.0;
        for _ in 0..2 * n {
            s.step(&[]).unwrap();
            let b = s.energy_books();
            assert_eq!(b.work_in, 0.0);
            moved = moved.max(b.kinetic + b.elastic);
            worst = worst.max(s.energy_balance().abs());
            penalty = penalty.max(s.contact_state().unwrap().potential);
        }
        assert!(penalty > 0.0, "the beam reaches the plane");
        (worst, moved)
    };
    let (b1, _) = run(100);
    let (b2, moved) = run(200);
    eprintln!(
        "held in contact, undamped: balance {b1:.3e} J at 100 steps per period, {b2:.3e} J at 200 (ratio {:.2}), energy moved {moved:.3e} J",
        b1 / b2
    );
    assert!(b1 / b2 > 3.0, "{b1:e} {b2:e}");
    assert!(b2 < 1e-2 * moved, "{b2:e} of {moved:e}");
}

/// The exact Jacobian of a step with a held tip and an obstacle with friction (the beam's
/// surface radius 5 mm: friction has a moment about the centreline), in motion on the
/// plane, against central differences (`check_step_jacobian_with`) with steps of 1e-5:
/// the held tip's test in dynamics_ends.rs takes 1e-4 (its node positions' rows round off
/// at 1e-6), but here a difference that straddles the ramp's switch (its curvature jumps
/// from 0 to k / eps) errs by O(h) of the jump (measured 2.3e-6 of the row's scale at 1e-4,
/// above the check's 1e-6).
#[test]
fn step_jacobian_with_a_held_tip_and_contact_matches_central_differences() {
    for kind in ["pinned", "clamped"] {
        let om = omega1();
        let opts = DynOptions {
            dt: 0.1 / om,
            ..Default::default()
        };
        let mut s = sim(
            beam_over_plane(3, 0.5 / om, 0.4),
            Initial::Straight,
            opts,
            held(kind),
        );
        // The first step after 10 that ends in contact (the beam bounces on the plane).
        for k in 0.. {
            s.step(&[]).unwrap();
            let touching = s.contact_state().unwrap().max_penetration > 0.0;
            if k >= 10 && touching {
                break;
            }
            assert!(k < 200, "{kind}: never in contact");
        }
        check_step_jacobian_with(kind, &s, 1e-5);
    }
}
