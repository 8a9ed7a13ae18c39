//! Contact with rigid obstacles in dynamics (issue 17, item 5; docs/contact.md,
//! "Dynamics"): a cantilever dropped onto a plane comes to rest on the static contact
//! solution; an undamped bounce keeps its energy (penalty potential included) under the
//! midpoint rule; a rod on an inclined plane sticks below the friction angle and slides
//! with the Coulomb acceleration above it; the step Jacobian with contact and friction
//! matches finite differences; hostile obstacle values are refused by name.

use crate::common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, Simulator};
use softrod_core::spec::obstacle::{ObstacleKind, ObstacleSpec};
use softrod_core::spec::DesignSpec;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

const G: f64 = 9.81;
const LENGTH: f64 = 0.2;
/// Line mass 0.1 kg/m; EI = 0.01 N m^2: free of the plane the tip sags w L^4 / (8 EI) =
/// 20 mm under its weight.
const MASS: f64 = 0.02;
const EI: f64 = 0.01;

fn plane(z: f64, stiffness: f64, tolerance: f64) -> ObstacleSpec {
    ObstacleSpec {
        point: Some([0.0, 0.0, z]),
        normal: Some([0.0, 0.0, 1.0]),
        ..obstacle(ObstacleKind::Plane, stiffness, tolerance)
    }
}

/// A horizontal cantilever (d3 = +x) over a plane 10 mm below its base: under its weight
/// it lies on the plane over its outer part. Penalty k = 1e4 N/m^2: the weight 0.98 N/m
/// sinks it by q / k + eps / 2 = 0.25 mm at rest; the tolerance of 3 mm leaves room for the
/// impact of a fall from 10 mm (the tip lands at ~0.4 m/s and sinks by ~v sqrt(rho A / k)
/// = 1.3 mm).
fn cantilever_over_plane(steps: usize, tau: f64) -> DesignSpec {
    let sec = direct_section("beam", LENGTH, 1e4, 1e4, EI, EI, MASS, steps);
    let mut d = design(vec![sec], HORIZONTAL, G);
    d.obstacles = vec![plane(-0.01, 1e4, 3e-3)];
    d.dynamics.damping_time = tau;
    d
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Released straight 10 mm above the plane with Kelvin-Voigt damping tau = 0.05 s, the
/// rod falls, lands and comes to rest. After 2 s (the slowest mode's envelope,
/// exp(-tau omega1^2 t / 2) with omega1 = 3.52 sqrt(EI / (m L^4)) = 28 rad/s, is down to
/// 1e-17) it lies on the static contact solution of the same discretisation (the
/// dynamics' own start in equilibrium) to 1e-9 L, and on the shooting statics with the
/// same obstacle to the two discretisations' difference (at 10 and 40 intervals); its surface never sank deeper
/// than the tolerance (the run checks it every step: a deeper one is an error); at rest
/// the clamp and the contact carry the weight: n(0) = F_contact + W to 1e-9 W.
#[test]
fn dropped_rod_settles_on_static_contact() {
    let mut off_shooting = vec![];
    for steps in [10, 40] {
        let rod = Rod::new(cantilever_over_plane(steps, 0.05)).unwrap();
        let opts = DynOptions {
            dt: 2e-3,
            tol: 1e-12,
            ..Default::default()
        };
        let mut sim = Simulator::new(rod.clone(), &[], Initial::Straight, opts).unwrap();
        let mut deepest: f64 = f64::NEG_INFINITY;
        let mut touched = false;
        for _ in 0..1000 {
            sim.step(&[]).unwrap();
            let c = sim.contact_state().unwrap();
            deepest = deepest.max(c.max_penetration);
            touched |= c.max_penetration > 0.0;
        }
        assert!(touched, "the rod reaches the plane");
        assert!(deepest <= 3e-3, "penetration {deepest}");
        let rest = Simulator::new(rod.clone(), &[], Initial::Static, opts).unwrap();
        let shot = solve(
            &rod,
            &loads(&[]),
            None,
            &SolverOptions {
                tol: 1e-12,
                ..Default::default()
            },
        )
        .unwrap();
        let d = dist(&sim.tip().r, &rest.tip().r);
        let ds = dist(&sim.tip().r, &shot.tip.r);
        let c = sim.contact_state().unwrap();
        let (n0, _) = sim.base_wrench();
        let w = MASS * G;
        let balance = (n0[2] - (c.force[2] - w)).abs();
        eprintln!(
        "tip {:?}; off static collocation {d:.3e} m, off shooting {ds:.3e} m; contact {:?} N, n(0) {:?} N, balance {balance:.2e} N; deepest {deepest:.3e} m",
        sim.tip().r,
        c.force,
        n0
    );
        assert!(sim.tip().r[2] < -0.009, "the tip rests on the plane");
        assert!(d < 1e-9 * LENGTH, "{d}");
        off_shooting.push(ds);
        assert!(balance < 1e-9 * w, "{balance}");
        assert!(c.force[2] > 0.1 * w, "the plane carries part of the weight");
    }
    // Collocation (Gauss, fourth order where the load is smooth) and RK4 shooting differ by
    // their discretisation errors, which the penalty's C1 ramp at the contact's edge and its
    // end at the tip cut to lower order: both converge, at least third order from 10 to 40
    // intervals (measured 3.5: 9.8e-5 m to 7.3e-7 m), to 1e-5 L at 40.
    eprintln!("off shooting statics at 10 and 40 intervals: {off_shooting:?} m");
    assert!(off_shooting[1] < off_shooting[0] / 64.0, "{off_shooting:?}");
    assert!(off_shooting[1] < 1e-5 * LENGTH, "{off_shooting:?}");
}

/// Undamped, the cantilever released above the plane lands and bounces. The midpoint rule
/// conserves the energy of the linear law exactly; the penalty is nonlinear (a C1 ramp),
/// so the balance E - E(0) - W_in + D (E with the penalty potential) errs by the scheme's
/// second-order error on the contact mode, ~(omega_c dt)^2 / 12 of the energy it holds with
/// omega_c = sqrt(k / (rho A)) = 316 rad/s: 2e-3 at dt = 5e-4 s. It must stay below 1 % of
/// the energy moved at every step, and the bounce must exchange energy with the plane.
#[test]
fn undamped_bounce_keeps_its_energy() {
    let rod = Rod::new(cantilever_over_plane(8, 0.0)).unwrap();
    let opts = DynOptions {
        dt: 5e-4,
        tol: 1e-12,
        scheme: Scheme::Midpoint,
        ..Default::default()
    };
    let mut sim = Simulator::new(rod, &[], Initial::Straight, opts).unwrap();
    let mut worst: f64 = 0.0;
    let mut most_penalty: f64 = 0.0;
    for _ in 0..600 {
        sim.step(&[]).unwrap();
        let b = sim.energy_books();
        let moved = b.kinetic.abs() + b.elastic.abs() + b.potential.abs();
        worst = worst.max(sim.energy_balance().abs() / moved.max(1e-300));
        most_penalty = most_penalty.max(sim.contact_state().unwrap().potential);
    }
    eprintln!("bounce: worst balance {worst:.3e} of the energy moved; largest penalty potential {most_penalty:.3e} J");
    assert!(most_penalty > 0.0, "the rod bounces on the plane");
    assert!(worst < 1e-2, "{worst}");
}

/// The cantilever of `cantilever_over_plane` (no plane) over a pin across its path: a
/// capsule along y of radius 2 mm at x = 150 mm, its top 3 mm below the rod (which would
/// sag about 12 mm there without it), with Kelvin-Voigt damping tau = 0.02 s. Penalty
/// k = 1e6 N/m^2, tolerance 1 mm: a pin stops only a short piece of the rod, which the rest
/// of the falling rod drives into it, so the landing sinks it several times deeper than the
/// rod's line-contact estimate v sqrt(rho A / k) = 0.1 mm (0.54 mm at the deepest stage
/// point, measured).
fn cantilever_over_pin(steps: usize) -> DesignSpec {
    let mut d = cantilever_over_plane(steps, 0.02);
    d.obstacles = vec![ObstacleSpec {
        start: Some([0.15, -0.01, -5e-3]),
        end: Some([0.15, 0.01, -5e-3]),
        radius: Some(2e-3),
        ..obstacle(ObstacleKind::Capsule, 1e6, 1e-3)
    }];
    d
}

/// The penalty acts at the collocation points. (1) With 20 mm intervals the 4 mm pin lies
/// between the stage points of the interval from 140 to 160 mm (5.8 mm from it), so
/// released straight the rod would fall through it unhindered: the first step that leaves
/// the rod more than the tolerance inside the pin (steps of 0.5 ms move it about 0.2 mm,
/// so one does) is refused in every substep, saying the intervals are too long. (2) With
/// 2 mm intervals and 1 ms steps the pin catches the rod, which comes to rest on it. (3)
/// With 2 mm intervals and 20 ms steps the rod moves several mm per step: the steps that
/// jump into or through the pin are halved until the contact is resolved, and the run
/// comes to the same rest on the pin.
#[test]
fn a_thin_obstacle_is_resolved_or_refused_never_passed_through() {
    let run = |steps: usize, dt: f64, n: usize| {
        let rod = Rod::new(cantilever_over_pin(steps)).unwrap();
        let opts = DynOptions {
            dt,
            tol: 1e-12,
            ..Default::default()
        };
        let mut sim = Simulator::new(rod, &[], Initial::Straight, opts).unwrap();
        let mut deepest: f64 = 0.0;
        for _ in 0..n {
            sim.step(&[])?;
            deepest = deepest.max(sim.contact_state().unwrap().max_penetration);
        }
        Ok::<_, softrod_core::error::SoftrodError>((sim, deepest))
    };
    match run(10, 5e-4, 600) {
        Err(softrod_core::error::SoftrodError::InvalidState {
            rule, s, message, ..
        }) => {
            assert_eq!(rule, softrod_core::error::Rule::Penetration, "{message}");
            assert!((s - 0.15).abs() < 0.011, "{s}: {message}");
            assert!(
                message.contains("obstacles[0]") && message.contains("steps"),
                "{message}"
            );
        }
        Err(e) => panic!("expected a penetration error, got {e}"),
        Ok((sim, _)) => panic!("passed through the pin, tip at {:?}", sim.tip().r),
    }
    // Every step checks the rule, so a run shows the pin never went deeper than the
    // tolerance; the deepest stage point is reported.
    let (fine, deepest) = run(100, 1e-3, 1000).unwrap();
    let (coarse, _) = run(100, 2e-2, 50).unwrap();
    eprintln!("rod on a pin: deepest stage point {deepest:.3e} m");
    let (c, cc) = (
        fine.contact_state().unwrap(),
        coarse.contact_state().unwrap(),
    );
    assert!(
        deepest > 0.0 && c.force[2] > 0.0,
        "the pin holds the rod up: {:?}",
        c.force
    );
    assert!(
        coarse.stats.rejected > 0,
        "the coarse steps were halved at the pin"
    );
    // Nearly at rest after 1 s (tau = 0.02 s damps the first mode, 28 rad/s, by
    // exp(-tau omega^2 t / 2) = 4e-4): both runs on the same equilibrium (a step's rest
    // state does not depend on dt), to the damped remainder of the motion.
    eprintln!("pin force: fine {:?}, coarse {:?}", c.force, cc.force);
    assert!(
        (c.force[2] - cc.force[2]).abs() < 1e-2 * c.force[2].abs(),
        "{:?} {:?}",
        c.force,
        cc.force
    );
}

/// A rod lying on a plane with gravity tilted by theta (the plane inclined): base clamped
/// up-slope, d3 down-slope. The plane sits so that the rod starts sunk by its static depth
/// (no normal transient). Axially soft (EA = 0.4 N, wave speed c = 2 m/s): the base's pull
/// reaches the tip after L / c = 0.1 s, so until then the tip moves as a free rigid body
/// on the incline.
fn rod_on_incline(theta: f64, mu: f64, slip: f64) -> (DesignSpec, f64) {
    let (k, tol) = (1e4, 1e-3);
    let eps = 0.1 * tol;
    let sec = direct_section("rod", LENGTH, 0.4, 1e4, EI, EI, MASS, 10);
    let mut d = design(vec![sec], HORIZONTAL, G);
    d.mounting.gravity = [G * theta.sin(), 0.0, -G * theta.cos()];
    let q = MASS / LENGTH * G * theta.cos();
    let sink = q / k + 0.5 * eps;
    let mut p = plane(sink, k, tol);
    p.friction = mu;
    p.slip_velocity = Some(slip);
    d.obstacles = vec![p];
    (d, sink)
}

/// tan(theta) > mu: the tip slides with the rigid body's acceleration g (sin theta -
/// mu cos theta) until the base's pull arrives. Its displacement at t = 0.06 s (before
/// L / c = 0.1 s) is a t^2 / 2 up to the regularisation: friction falls short of mu |f_n|
/// by mu |f_n| (1 - v / sqrt(v^2 + v_reg^2)), whose integral over the motion adds
/// ~mu g cos(theta) v_reg / a to the velocity, v_reg t mu g cos(theta) / a to the
/// displacement: 1e-6 m here (2.4e-4 of a t^2 / 2); and to the implicit scheme's
/// spreading of the base's pull ahead of the axial wave front (an implicit step couples
/// the whole rod), the larger part (measured 1.9e-3 of a t^2 / 2 at alpha = -0.2; BDF2's
/// heavier damping spreads it to 1.6e-2). Bound: 0.5 % of a t^2 / 2.
/// tan(theta) < mu: the rod sticks; it creeps at most at the regularised law's speed
/// v_reg r / sqrt(1 - r^2), r = tan(theta) / mu (where friction alone holds the weight),
/// so the tip moves by less than that speed times the time, and by nearly as much.
#[test]
fn rod_on_incline_sticks_or_slides_as_coulomb_says() {
    let theta = 30f64.to_radians();
    let slip = 1e-4;
    let opts = DynOptions {
        dt: 1e-3,
        tol: 1e-12,
        ..Default::default()
    };
    // Sliding: mu = 0.3 < tan(30 deg) = 0.577.
    let mu = 0.3;
    let (d, _) = rod_on_incline(theta, mu, slip);
    let mut sim = Simulator::new(Rod::new(d).unwrap(), &[], Initial::Straight, opts).unwrap();
    let x0 = sim.tip().r[0];
    let t = 0.06;
    for _ in 0..60 {
        sim.step(&[]).unwrap();
    }
    let a = G * (theta.sin() - mu * theta.cos());
    let moved = sim.tip().r[0] - x0;
    let expect = 0.5 * a * t * t;
    eprintln!(
        "slide: tip moved {moved:.6e} m, rigid body {expect:.6e} m ({:.2e} relative)",
        (moved - expect) / expect
    );
    assert!(
        (moved - expect).abs() < 5e-3 * expect,
        "{moved} vs {expect}"
    );
    // Sticking: mu = 0.8 > tan(30 deg). The regularised law is stiff where it holds: its
    // time constant v_reg / (mu g cos theta) = 1.5e-5 s is far below the step, so the
    // scheme must damp such modes within a step: BDF-alpha with alpha = 0 (BDF2,
    // L-stable). With less damping the start rings about the creep speed, and the energy
    // check sees the ringing (docs/contact.md).
    let opts = DynOptions { alpha: 0.0, ..opts };
    let mu = 0.8;
    let (d, _) = rod_on_incline(theta, mu, slip);
    let mut sim = Simulator::new(Rod::new(d).unwrap(), &[], Initial::Straight, opts).unwrap();
    let r0 = sim.tip().r;
    let steps = 200;
    for _ in 0..steps {
        sim.step(&[]).unwrap();
    }
    let r = theta.tan() / mu;
    let creep = slip * r / (1.0 - r * r).sqrt() * steps as f64 * opts.dt;
    let moved = dist(&sim.tip().r, &r0);
    eprintln!("stick: tip moved {moved:.3e} m, creep bound {creep:.3e} m");
    // Friction alone holds the weight (the base's axial pull over a 2e-5 m creep is
    // EA 1e-4 = 4e-5 N against 0.1 N): the rod creeps at the regularised speed, from
    // rest, so it moves by just under the bound (measured 0.998 of it).
    assert!(moved < creep && moved > 0.9 * creep, "{moved} vs {creep}");
    // Friction dissipates: the books count it, and the balance holds.
    assert!(sim.energy_books().dissipated >= 0.0);
}

/// The exact Jacobian of a step with contact (a sphere and a plane, the rod's surface
/// radius 5 mm, so friction has a moment about the centreline) matches central
/// differences (`check_step_jacobian`), mid-bounce (t = 0.08 s, the tip rebounding at
/// 5 cm/s). Axially soft (EA = GA = 100 N): with EA = 1e4 N the rod's velocity rows hold
/// terms ~1/EA whose central differences fall to round-off below the check's 1e-6, with
/// or without obstacles.
#[test]
fn step_jacobian_with_contact_and_friction_matches_finite_differences() {
    let mut d = cantilever_over_plane(3, 0.01);
    d.sections[0].outer_radius = Some(0.005);
    d.sections[0].stiffness.ea = Some(100.0);
    d.sections[0].stiffness.ga = Some(100.0);
    d.obstacles[0].friction = 0.4;
    d.obstacles[0].slip_velocity = Some(1e-2);
    let mut sphere = plane(0.0, 2e4, 2e-3);
    sphere.kind = ObstacleKind::Sphere;
    sphere.point = None;
    sphere.normal = None;
    sphere.center = Some([0.12, 0.0, -0.06]);
    sphere.radius = Some(0.05);
    sphere.friction = 0.3;
    d.obstacles.push(sphere);
    let rod = Rod::new(d).unwrap();
    let opts = DynOptions {
        dt: 2e-3,
        ..Default::default()
    };
    let mut sim = Simulator::new(rod, &[], Initial::Straight, opts).unwrap();
    for _ in 0..40 {
        sim.step(&[]).unwrap();
    }
    let c = sim.contact_state().unwrap();
    assert!(sim.tip_velocity()[2].abs() > 0.01, "in motion");
    assert!(c.max_penetration > 0.0, "in contact: {c:?}");
    check_step_jacobian("contact", &sim);
}

type Mutate = Box<dyn Fn(&mut ObstacleSpec)>;

/// Hostile obstacle values are refused by name.
#[test]
fn bad_obstacles_are_refused_by_name() {
    let cases: Vec<(&str, Mutate)> = vec![
        ("obstacles[0].friction", Box::new(|o| o.friction = -0.1)),
        ("obstacles[0].friction", Box::new(|o| o.friction = f64::NAN)),
        (
            "obstacles[0].slip_velocity",
            Box::new(|o| o.slip_velocity = Some(0.0)),
        ),
        (
            "obstacles[0].slip_velocity",
            Box::new(|o| o.slip_velocity = Some(f64::INFINITY)),
        ),
        (
            "obstacles[0].stiffness",
            Box::new(|o| o.stiffness = f64::NAN),
        ),
    ];
    for (field, bad) in cases {
        let mut d = cantilever_over_plane(4, 0.05);
        bad(&mut d.obstacles[0]);
        let Err(err) = Rod::new(d) else {
            panic!("{field}: accepted")
        };
        let err = err.to_string();
        assert!(err.contains(field), "{field}: {err}");
    }
}
