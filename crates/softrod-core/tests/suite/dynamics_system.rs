//! Dynamics of a system of rods holding one rigid platform (docs/dynamics.md "Systems of
//! rods"): one rod on a massless platform against the single rod with the platform's
//! loads at its free tip, settling on `solve_system`'s equilibrium, the energy books of an
//! undamped run, a platform mass on three rods against the linear frequency from the
//! system's static stiffness, the step Jacobian, save/restore and refusals; a follower tip
//! load on a rod (against the free rod, at rest, the step Jacobian); a stiffness-mapped rod
//! (a constant map against the rod with its stiffness factors multiplied, refusals).

use crate::common;

use common::*;
use softrod_core::dynamics::system::{DynRod, SystemSimulator};
use softrod_core::dynamics::{DynOptions, Initial, Scheme, SigmaMap, Simulator};
use softrod_core::interp::GridPchip;
use softrod_core::ode::Loads;
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::{DesignSpec, Frame, MaterialSpec};
use softrod_core::statics::system::{solve_system, Platform, SystemRod};
use softrod_core::statics::SolverOptions;
use softrod_core::{Rod, SoftrodError};
use std::f64::consts::PI;

const E: f64 = 1.0e6;
const RHO: f64 = 1000.0;
const R: f64 = 0.008;
const L: f64 = 0.1;
/// The rods' bases: on a circle of this radius, m.
const RING: f64 = 0.03;

fn material() -> MaterialSpec {
    MaterialSpec {
        youngs_modulus: E,
        shear_modulus: E / 3.0,
        density: RHO,
    }
}

/// A vertical rod with one chamber (channel 0, towards +x of its base frame) based at
/// `base`, gravity g along -z, damping time `tau`.
fn rod_spec(base: [f64; 3], g: f64, tau: f64) -> DesignSpec {
    let sec = geometry_section(
        "rod",
        L,
        R,
        0.0,
        material(),
        vec![chamber(0.002, 0.004, 0.0, 0)],
        10,
    );
    let mut spec = design(vec![sec], IDENTITY, g);
    spec.mounting.base_position = base;
    spec.dynamics.damping_time = tau;
    spec
}

fn rod_mass() -> f64 {
    RHO * PI * R * R * L
}

/// `n` identical rods on the ring, each tip at its base's offset on the platform.
fn rods(n: usize, g: f64, tau: f64, pressures: &[f64]) -> Vec<DynRod> {
    (0..n)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / n as f64;
            let off = [RING * a.cos(), RING * a.sin(), 0.0];
            DynRod {
                rod: Rod::new(rod_spec(off, g, tau)).unwrap(),
                pressures: vec![pressures[i]],
                tensions: vec![],
                sigma_map: SigmaMap::None,
                attachment: off,
                attachment_rotation: IDENTITY,
            }
        })
        .collect()
}

fn platform(mass: f64, g: f64, force: [f64; 3], moment: [f64; 3]) -> Platform {
    Platform {
        position: [0.0, 0.0, L],
        rotation: IDENTITY,
        force,
        moment,
        mass,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -g],
    }
}

fn opts(dt: f64, alpha: f64) -> DynOptions {
    DynOptions {
        dt,
        alpha,
        ..DynOptions::default()
    }
}

/// The static platform position of a system (shooting statics).
fn static_position(rods: &[DynRod], p: &Platform) -> [f64; 3] {
    let sys: Vec<SystemRod> = rods
        .iter()
        .map(|r| SystemRod {
            rod: &r.rod,
            loads: loads(&r.pressures),
            attachment: r.attachment,
            attachment_rotation: r.attachment_rotation,
        })
        .collect();
    solve_system(&sys, p, None, &SolverOptions::default())
        .unwrap()
        .platform_position
}

fn commands(p: &[f64]) -> Vec<Vec<f64>> {
    p.iter().map(|x| vec![*x]).collect()
}

/// A one-rod system on a massless platform with no inertia loaded by `force`, `moment`,
/// and the same rod free with those loads at its tip (with a follower tip load of the
/// design, `spec.tip.frame = Body`: the platform unloaded and the free rod's tip carrying
/// the design's follower load), both started at `pressure` with Newton's tol = 1e-12 of
/// the scaled unknowns.
fn one_rod_and_free_rod(
    spec: DesignSpec,
    pressure: f64,
    force: [f64; 3],
    moment: [f64; 3],
) -> (SystemSimulator, Simulator) {
    let (tip_force, tip_moment) = if spec.tip.frame == Frame::Body {
        assert_eq!((force, moment), ([0.0; 3], [0.0; 3]), "one load at a time");
        (spec.tip.force, spec.tip.moment)
    } else {
        (force, moment)
    };
    let o = DynOptions {
        tol: 1e-12,
        ..opts(2e-3, -0.2)
    };
    let rod = Rod::new(spec).unwrap();
    let one = DynRod {
        rod: rod.clone(),
        pressures: vec![pressure],
        tensions: vec![],
        sigma_map: SigmaMap::None,
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    };
    let sys = SystemSimulator::new(
        vec![one],
        platform(0.0, 9.81, force, moment),
        [[0.0; 3]; 3],
        o,
    )
    .unwrap();
    let free = Simulator::with_inputs(
        rod,
        &[pressure],
        Initial::Static,
        o,
        SigmaMap::None,
        tip_force,
        tip_moment,
    )
    .unwrap();
    (sys, free)
}

#[test]
fn one_rod_on_a_massless_platform_is_the_free_rod_with_its_loads() {
    // A massless platform with no inertia transmits its loads to the tip: the free rod
    // with the platform's force and moment at its tip.
    let force = [0.02, -0.01, 0.0];
    let moment = [0.0, 0.0005, 0.0002];
    let spec = rod_spec([0.0; 3], 9.81, 0.005);
    let (mut sys, mut free) = one_rod_and_free_rod(spec, 0.0, force, moment);
    let mut worst: f64 = 0.0;
    for k in 0..40 {
        let p = if k < 20 { 30e3 } else { 10e3 };
        sys.step(&[vec![p]]).unwrap();
        free.step(&[p]).unwrap();
        let (pp, _) = sys.platform_pose();
        let a = free.tip().r;
        worst = worst.max(dist(&pp, &a));
        for (x, y) in sys.rods()[0].shape().iter().zip(free.shape()) {
            worst = worst.max(dist(x, y));
        }
    }
    eprintln!("one rod: largest difference from the free rod {worst:.3e} m");
    // Each step's Newton leaves errors ~1e-12 L in positions; 40 steps of them, carried
    // on through the histories (damped), stay below 1e-10 L.
    assert!(worst < 1e-10 * L, "{worst:e}");
}

/// A wall beside the rods' bend: a plane through x = -(R + 1 mm) facing +x, so that the
/// rod of `rod_spec` (bent towards -x by its chamber) presses on it from about 20 kPa on.
/// Penalty k = 1e5 N/m^2, tolerance 2 mm (docs/contact.md).
fn wall() -> softrod_core::spec::obstacle::ObstacleSpec {
    softrod_core::spec::obstacle::ObstacleSpec {
        point: Some([-(R + 0.001), 0.0, 0.0]),
        normal: Some([1.0, 0.0, 0.0]),
        ..obstacle(ObstacleKind::Plane, 1e5, 2e-3)
    }
}

#[test]
fn one_rod_by_a_wall_on_a_massless_platform_is_the_free_rod_by_the_wall() {
    // As the test above, with the rod pressed on a wall through the whole run (30 kPa,
    // then 40 kPa): the system's start and every step carry the rod's obstacles as the
    // free rod's do. Both Newtons converge to tol = 1e-12 of the scaled unknowns.
    let mut spec = rod_spec([0.0; 3], 9.81, 0.005);
    spec.obstacles = vec![wall()];
    let (mut sys, mut free) = one_rod_and_free_rod(spec, 30e3, [0.005, 0.0, 0.0], [0.0; 3]);
    // The wall holds the rod back: the free rod's contact force is far from zero.
    let contact = free.contact_state().expect("obstacles");
    assert!(contact.force[0] > 1e-3, "{:?}", contact.force);
    let mut worst = dist(&sys.platform_pose().0, &free.tip().r);
    for k in 0..40 {
        let p = if k < 10 { 30e3 } else { 40e3 };
        sys.step(&[vec![p]]).unwrap();
        free.step(&[p]).unwrap();
        let (pp, _) = sys.platform_pose();
        worst = worst.max(dist(&pp, &free.tip().r));
        for (x, y) in sys.rods()[0].shape().iter().zip(free.shape()) {
            worst = worst.max(dist(x, y));
        }
    }
    let contact = free.contact_state().expect("obstacles");
    eprintln!(
        "one rod by a wall: largest difference from the free rod {worst:.3e} m, contact force {:?} N",
        contact.force
    );
    // As above: Newton errors ~1e-12 L per step, carried through 40 damped steps.
    assert!(worst < 1e-10 * L, "{worst:e}");
    // The step's exact Jacobian (the penalty along the rod and the rounded end's term in
    // the tip reaction the platform feels) against central differences.
    assert!(contact.max_penetration > 0.0, "{contact:?}");
    let z = sys.unknowns();
    check_jacobian_at(
        "system step by a wall",
        &z,
        |x| sys.step_residual_and_jacobian(x).unwrap(),
        1e-6,
    );
}

/// Rod `spec` with a follower tip load (`[tip] frame = "body"`): a force along the tip's
/// d1 and d3 and a moment about its d2, in the tip frame (small against the rod's bending
/// scales EI / L^2 ~ 0.3 N and EI / L ~ 0.03 N m, yet bending it visibly).
fn with_follower(mut spec: DesignSpec) -> DesignSpec {
    spec.tip.frame = Frame::Body;
    spec.tip.force = [0.02, 0.0, -0.01];
    spec.tip.moment = [0.0, 0.0005, 0.0];
    spec
}

#[test]
fn one_rod_with_a_follower_tip_load_on_a_massless_platform_is_the_free_rod() {
    // A massless platform with no inertia and no load imposes nothing on the tip it holds:
    // the system's rod carries the design's follower tip load (R_tip f_b, R_tip m_b in
    // the platform's tip reaction) and moves as the free rod with the same follower load,
    // through a pressure step up and down that turns the tip (and the load with it).
    let spec = with_follower(rod_spec([0.0; 3], 9.81, 0.005));
    let (mut sys, mut free) = one_rod_and_free_rod(spec, 0.0, [0.0; 3], [0.0; 3]);
    // The same rod with the same load dead (world frame): what the system would do if
    // its rod's load did not turn with the tip.
    let mut dead_spec = with_follower(rod_spec([0.0; 3], 9.81, 0.005));
    dead_spec.tip.frame = Frame::World;
    let (f, m) = (dead_spec.tip.force, dead_spec.tip.moment);
    let (_, mut dead) = one_rod_and_free_rod(dead_spec, 0.0, f, m);
    let mut worst = dist(&sys.platform_pose().0, &free.tip().r);
    let mut apart = dist(&dead.tip().r, &free.tip().r);
    let start = free.tip().rot;
    let mut turned: f64 = 0.0;
    for k in 0..40 {
        let p = if k < 20 { 30e3 } else { 10e3 };
        sys.step(&[vec![p]]).unwrap();
        free.step(&[p]).unwrap();
        dead.step(&[p]).unwrap();
        let (pp, rp) = sys.platform_pose();
        let tip = free.tip();
        worst = worst.max(dist(&pp, &tip.r));
        apart = apart.max(dist(&dead.tip().r, &tip.r));
        for i in 0..3 {
            for j in 0..3 {
                // Rotation entries times L: the same units as the positions.
                worst = worst.max((rp[i][j] - tip.rot[i][j]).abs() * L);
                turned = turned.max((tip.rot[i][j] - start[i][j]).abs());
            }
        }
        for (x, y) in sys.rods()[0].shape().iter().zip(free.shape()) {
            worst = worst.max(dist(x, y));
        }
    }
    eprintln!(
        "one rod, follower tip load: largest difference from the free rod {worst:.3e} m, tip turned by {turned:.3e}, the dead load's tip {apart:.3e} m away"
    );
    // The tip turns (the load with it), and a dead load moves the tip elsewhere by far
    // more than the tolerance below: the comparison sees the load's rotation.
    assert!(turned > 0.02, "{turned:e}");
    assert!(apart > 1e-4 * L, "{apart:e}");
    // As the test with dead loads: Newton errors ~1e-12 L per step (both runs converge to
    // tol = 1e-12 of the scaled unknowns), carried through 40 damped steps, stay below
    // 1e-10 L.
    assert!(worst < 1e-10 * L, "{worst:e}");
}

#[test]
fn step_jacobian_with_a_follower_tip_load_against_central_differences() {
    // Rod 1's follower tip load reaches the platform's rows through its tip reaction, a
    // function of its tip node's rotation (R_tip f_b, R_tip m_b): the exact Jacobian
    // (those columns included) against central differences, with the platform's rotation
    // off the chart's origin and a massive platform with inertia, as
    // `step_jacobian_against_central_differences`.
    let mut rs = rods(2, 9.81, 0.01, &[10e3, 0.0]);
    rs[1].rod = Rod::new(with_follower(rs[1].rod.spec.clone())).unwrap();
    let (sys, z) = stepped_off_the_chart(rs);
    check_jacobian_at(
        "system step with a follower tip load",
        &z,
        |x| sys.step_residual_and_jacobian(x).unwrap(),
        1e-6,
    );
}

/// A system of `rs` on a 50 g platform with inertia and an offset centre of mass, after
/// three steps (30 and 10 kPa), and its unknowns with the platform's rotation moved off the
/// current one, so that the Cayley chart is not at its origin: where the step Jacobian's
/// tests check it.
fn stepped_off_the_chart(rs: Vec<DynRod>) -> (SystemSimulator, Vec<f64>) {
    let mut plat = platform(0.05, 9.81, [0.01, 0.0, 0.0], [0.0; 3]);
    plat.com_offset = [0.005, 0.0, 0.01];
    let inertia = [[2e-5, 1e-6, 0.0], [1e-6, 3e-5, 0.0], [0.0, 0.0, 4e-5]];
    let mut sys = SystemSimulator::new(rs, plat, inertia, opts(2e-3, -0.2)).unwrap();
    for _ in 0..3 {
        sys.step(&commands(&[30e3, 10e3])).unwrap();
    }
    let mut z = sys.unknowns();
    let n = z.len();
    z[n - 3] = 0.01;
    z[n - 2] = -0.02;
    z[n - 1] = 0.005;
    (sys, z)
}

#[test]
fn a_system_with_a_follower_tip_load_at_rest_stays_at_rest() {
    // Three damped rods on a 20 g platform with inertia under gravity, rod 1 with a
    // follower tip load: started at rest in its static equilibrium, held inputs keep it
    // there for 20 steps.
    let (n, g, tau) = (3, 9.81, 0.01);
    let plat = platform(0.02, g, [0.0; 3], [0.0; 3]);
    let inertia = [[2e-6, 0.0, 0.0], [0.0, 2e-6, 0.0], [0.0, 0.0, 4e-6]];
    let p = [20e3, 0.0, 10e3];
    let o = DynOptions {
        tol: 1e-14,
        ..opts(2e-3, -0.2)
    };
    let follower = || {
        let mut rs = rods(n, g, tau, &p);
        rs[1].rod = Rod::new(with_follower(rs[1].rod.spec.clone())).unwrap();
        rs
    };
    let mut sys = SystemSimulator::new(follower(), plat, inertia, o).unwrap();
    let (p0, r0) = sys.platform_pose();
    let shapes0: Vec<Vec<[f64; 3]>> = sys.rods().iter().map(|r| r.shape().to_vec()).collect();
    // The follower load acts: the start is not the unloaded system's ...
    let dead = SystemSimulator::new(rods(n, g, tau, &p), plat, inertia, o).unwrap();
    let moved = dist(&p0, &dead.platform_pose().0);
    // ... and it is solve_system's equilibrium under the same follower load, to the
    // difference of the two discretisations (shooting and collocation; < 1e-5 L, as in
    // the damped run's test).
    let statics: Vec<DynRod> = follower();
    let sys_rods: Vec<SystemRod> = statics
        .iter()
        .map(|r| SystemRod {
            rod: &r.rod,
            loads: Loads::from_design(&r.rod, r.pressures.clone()),
            attachment: r.attachment,
            attachment_rotation: r.attachment_rotation,
        })
        .collect();
    let shooting = solve_system(&sys_rods, &plat, None, &SolverOptions::default()).unwrap();
    let disc = dist(&p0, &shooting.platform_position);
    let steps = 20;
    let mut drift: f64 = 0.0;
    let mut speed: f64 = 0.0;
    for _ in 0..steps {
        sys.step(&commands(&p)).unwrap();
        let (pp, rp) = sys.platform_pose();
        drift = drift.max(dist(&pp, &p0));
        for i in 0..3 {
            for j in 0..3 {
                drift = drift.max((rp[i][j] - r0[i][j]).abs() * L);
            }
        }
        for (rod, s0) in sys.rods().iter().zip(&shapes0) {
            for (x, y) in rod.shape().iter().zip(s0) {
                drift = drift.max(dist(x, y));
            }
        }
        let (v, w) = sys.platform_velocity();
        speed = speed.max(norm(&v)).max(norm(&w) * L);
    }
    let bound = (1.0 + 2.0 * steps as f64) * o.tol * 2.0 * L;
    eprintln!(
        "follower at rest: drift {drift:.3e} m (bound {bound:.3e} m), speed {speed:.3e} m/s, \
         follower moved the start by {moved:.3e} m, shooting vs collocation {disc:.3e} m, \
         |balance| {:.3e} J",
        sys.energy_balance().abs()
    );
    assert!(moved > 1e-3 * L, "the follower load must act: {moved:e}");
    assert!(disc < 1e-5 * L, "{disc:e}");
    // Newton runs at tol = 1e-14 of the scaled unknowns, a hundred times double
    // precision's 1e-16: round-off level. The start solves the rest state's Newton to
    // min(tol, 1e-10) = tol (relative to max(1, |z|) <= 2, positions in units of L:
    // `newton_bound`), and the exact step from an exact rest state is that rest state
    // (zero velocities and history terms); so each step may add at most its own Newton
    // error (2 tol L; the damped scheme does not amplify a perturbation):
    // (tol + 2 tol steps) 2 L = 8.2e-14 m.
    assert!(drift <= bound, "{drift:e} vs {bound:e}");
    // Velocities are c0 (~1 / (0.6 dt) ~ 800 / s at alpha = -0.2) times those position
    // errors, at most: c0 bound <= 1e3 / s * bound.
    assert!(speed <= 1e3 * bound, "{speed:e}");
}

#[test]
fn damped_run_settles_on_the_static_equilibrium() {
    // Three rods, a 20 g platform, gravity; the pressure of rod 0 stepped from 0 to 40 kPa
    // at t = 0: the damped run ends at rest on solve_system's equilibrium under the new
    // pressures.
    let (n, g, tau) = (3, 9.81, 0.01);
    let plat = platform(0.02, g, [0.0; 3], [0.0; 3]);
    let p1 = [40e3, 0.0, 0.0];
    let o = opts(5e-3, -0.2);
    let mut sys = SystemSimulator::new(rods(n, g, tau, &[0.0; 3]), plat, [[0.0; 3]; 3], o).unwrap();
    let at_rest0 = static_position(&rods(n, g, tau, &[0.0; 3]), &plat);
    let target = static_position(&rods(n, g, tau, &p1), &plat);
    let moved = dist(&target, &at_rest0);
    // This discretisation's equilibrium under the new pressures: a run started there. It
    // differs from the shooting statics' by the two discretisations' errors.
    let rest1 = SystemSimulator::new(rods(n, g, tau, &p1), plat, [[0.0; 3]; 3], o).unwrap();
    let own = rest1.platform_pose().0;
    let disc = dist(&own, &target);
    for _ in 0..320 {
        sys.step(&commands(&p1)).unwrap();
    }
    let (end, _) = sys.platform_pose();
    let (v, w) = sys.platform_velocity();
    let off = dist(&end, &own);
    eprintln!(
        "settled: moved {moved:.3e} m, off its own equilibrium {off:.3e} m, discretisation {disc:.3e} m, |v| {:.2e} m/s, |w| {:.2e} rad/s",
        norm(&v),
        norm(&w)
    );
    assert!(
        moved > 1e-3 * L,
        "the pressure must move the platform: {moved:e}"
    );
    // Settled after 1.6 s (the slowest mode decays by ~e^-11 per second, measured): on
    // its own equilibrium to the Newton tolerance (1e-9 of L in positions) ...
    assert!(off <= 1e-9 * L, "{off:e}");
    assert!(norm(&v) < 1e-8, "still moving: {v:?}");
    // ... and so on solve_system's to the discretisations' difference.
    assert!(dist(&end, &target) <= disc + 1e-9 * L);
    assert!(disc < 1e-5 * L, "the grids' equilibria differ by {disc:e}");
    assert!(
        sys.energy_books().dissipated > 0.0,
        "the damped run dissipates"
    );
}

#[test]
fn undamped_energy_balance_with_a_massive_platform() {
    // A platform with mass, an offset centre of mass and a full inertia tensor on three
    // undamped rods, released at t = 0 from a static load (force and moment) under gravity
    // while rod 1's pressure steps up: the energy books (rods and platform, the
    // pressures' work) balance.
    let (n, g) = (3, 9.81);
    let mut plat = platform(0.05, g, [0.05, 0.02, 0.0], [0.0, 0.0, 0.002]);
    plat.com_offset = [0.01, -0.005, 0.008];
    let inertia = [[2e-5, 3e-6, 0.0], [3e-6, 3e-5, 1e-6], [0.0, 1e-6, 4e-5]];
    let mut sys =
        SystemSimulator::new(rods(n, g, 0.0, &[0.0; 3]), plat, inertia, opts(1e-3, -0.5)).unwrap();
    sys.set_platform_loads([0.0; 3], [0.0; 3]).unwrap();
    let p = [0.0, 30e3, 0.0];
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for _ in 0..200 {
        sys.step(&commands(&p)).unwrap();
        let b = sys.energy_books();
        worst = worst.max(sys.energy_balance().abs());
        scale = scale.max(b.kinetic);
    }
    let b = sys.energy_books();
    eprintln!(
        "undamped: |balance| <= {worst:.3e} J, max kinetic {scale:.3e} J, work in {:.3e} J, dissipated {:.3e}",
        b.work_in, b.dissipated
    );
    assert!(scale > 1e-5, "the platform must move: {scale:e}");
    assert_eq!(b.dissipated, 0.0);
    // The trapezoidal rule (alpha = -0.5) conserves the linearised rods' energy; the
    // platform's Cayley chart and the reactions' work along the pose path are second
    // order: errors ~(omega dt)^2 / 12 of the energy moved, with the platform's sway at
    // omega ~ sqrt(93 N/m / 0.05 kg) = 43 rad/s, omega dt = 0.043: 1.5e-4, within 1e-3.
    assert!(worst <= 1e-3 * scale, "{worst:e} vs {scale:e}");
}

#[test]
fn platform_mass_oscillates_at_the_static_stiffness_frequency() {
    // A 3 kg platform on three rods, no gravity, released from a small lateral force:
    // omega^2 = k / (m_p + m_eff), k the system's lateral stiffness (central difference of
    // solve_system's platform position in the force), m_eff the rods' participating mass
    // (Rayleigh, the clamped-guided beam's static shape: 13/35 of each rod's mass).
    let (n, mp) = (3, 3.0);
    let f0 = 0.02;
    let dyn_rods = rods(n, 0.0, 0.0, &[0.0; 3]);
    let xp = static_position(&dyn_rods, &platform(mp, 0.0, [f0, 0.0, 0.0], [0.0; 3]));
    let xm = static_position(&dyn_rods, &platform(mp, 0.0, [-f0, 0.0, 0.0], [0.0; 3]));
    let k = 2.0 * f0 / (xp[0] - xm[0]);
    let m_rods = n as f64 * rod_mass();
    let omega0 = (k / mp).sqrt();
    let omega = (k / (mp + 13.0 / 35.0 * m_rods)).sqrt();
    let dt = 2e-3;
    let mut sys = SystemSimulator::new(
        dyn_rods,
        platform(mp, 0.0, [f0, 0.0, 0.0], [0.0; 3]),
        [[0.0; 3]; 3],
        opts(dt, -0.45),
    )
    .unwrap();
    sys.set_platform_loads([0.0; 3], [0.0; 3]).unwrap();
    let x0 = (xp[0] + xm[0]) / 2.0;
    let mut last = sys.platform_pose().0[0] - x0;
    let mut crossings = vec![];
    let period = 2.0 * PI / omega;
    while sys.time() < 1.6 * period {
        sys.step(&commands(&[0.0; 3])).unwrap();
        let x = sys.platform_pose().0[0] - x0;
        if last * x < 0.0 {
            crossings.push(sys.time() - dt * x / (x - last));
        }
        last = x;
    }
    assert!(crossings.len() >= 3, "{crossings:?}");
    let measured = PI * (crossings.len() - 1) as f64 / (crossings.last().unwrap() - crossings[0]);
    let err = (measured - omega).abs() / omega;
    eprintln!(
        "oscillation: k = {k:.4} N/m, omega measured {measured:.5} rad/s, sqrt(k/m_p) {omega0:.5}, with the rods' mass {omega:.5}: {:.3e} off (neglecting it: {:.3e})",
        err,
        (measured - omega0).abs() / omega0
    );
    // The rods' mass shifts omega by ~13/70 m_rods / m_p = 0.37 %, neglected in
    // sqrt(k/m_p): that is the expected error of the massless estimate, and it must show.
    assert!(measured < omega0);
    // Left with the Rayleigh mass: its own error O((m_rods / m_p)^2) ~1e-5, BDF-alpha's
    // period error O((omega dt)^2) ~1e-4 at omega dt = 0.012, and the zero crossings'
    // linear interpolation (~(omega dt)^2 / 8 of a step): 1e-3.
    assert!(err < 1e-3, "{err:e}");
}

#[test]
fn step_jacobian_against_central_differences() {
    let (sys, z) = stepped_off_the_chart(rods(2, 9.81, 0.01, &[10e3, 0.0]));
    check_jacobian_at(
        "system step",
        &z,
        |x| sys.step_residual_and_jacobian(x).unwrap(),
        1e-6,
    );
    refused(sys.step_residual_and_jacobian(&z[1..]), "x");
}

#[test]
fn save_and_restore_continue_bit_for_bit() {
    let mut plat = platform(0.05, 9.81, [0.01, 0.0, 0.0], [0.0; 3]);
    plat.com_offset = [0.005, 0.0, 0.01];
    let inertia = [[2e-5, 0.0, 0.0], [0.0, 3e-5, 0.0], [0.0, 0.0, 4e-5]];
    let o = DynOptions {
        error_tol: Some(1e-6),
        ..opts(4e-3, -0.2)
    };
    let mut sys = SystemSimulator::new(rods(3, 9.81, 0.01, &[0.0; 3]), plat, inertia, o).unwrap();
    for _ in 0..4 {
        sys.step(&commands(&[20e3, 0.0, 5e3])).unwrap();
    }
    let saved = sys.save();
    let run = |s: &mut SystemSimulator| -> Vec<f64> {
        let mut out = vec![];
        for k in 0..5 {
            s.step(&commands(&[20e3, 10e3 * k as f64, 5e3])).unwrap();
            let (p, r) = s.platform_pose();
            out.extend_from_slice(&p);
            out.extend(r.iter().flatten());
            for rod in s.rods() {
                out.extend(rod.shape().iter().flatten());
            }
            out.push(s.energy_balance());
        }
        out
    };
    let a = run(&mut sys);
    let mut other = SystemSimulator::new(rods(3, 9.81, 0.01, &[0.0; 3]), plat, inertia, o).unwrap();
    other.restore(&saved).unwrap();
    let b = run(&mut other);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.to_bits(), y.to_bits());
    }
    assert_eq!(sys.stats, other.stats);
    // A state of another system is refused by name.
    let mut two = SystemSimulator::new(
        rods(2, 9.81, 0.01, &[0.0; 2]),
        platform(0.05, 9.81, [0.0; 3], [0.0; 3]),
        inertia,
        o,
    )
    .unwrap();
    refused(two.restore(&saved), "state");
    refused(two.restore(&saved[..10]), "state");
}

fn refused<T>(r: Result<T, SoftrodError>, field: &str) {
    match r {
        Err(SoftrodError::InvalidParameter { field: f, .. }) => {
            assert!(f.starts_with(field), "refused {f}, expected {field}")
        }
        Err(e) => panic!("expected a refusal of {field}, got {e}"),
        Ok(_) => panic!("expected a refusal of {field}"),
    }
}

#[test]
fn refusals_by_name() {
    let plat = platform(0.02, 9.81, [0.0; 3], [0.0; 3]);
    let z3 = [[0.0; 3]; 3];
    let o = opts(2e-3, -0.2);
    let new = |r: Vec<DynRod>, p: Platform, j: [[f64; 3]; 3], o: DynOptions| {
        SystemSimulator::new(r, p, j, o)
    };
    let midpoint = DynOptions {
        scheme: Scheme::Midpoint,
        ..o
    };
    refused(
        new(rods(2, 9.81, 0.0, &[0.0; 2]), plat, z3, midpoint),
        "scheme",
    );
    let mut rs = rods(2, 9.81, 0.0, &[0.0; 2]);
    rs[1].pressures = vec![0.0, 1.0];
    refused(new(rs, plat, z3, o), "rods[1].pressures");
    let mut rs = rods(2, 9.81, 0.0, &[0.0; 2]);
    rs[0].tensions = vec![1.0];
    refused(new(rs, plat, z3, o), "rods[0].tensions");
    let mut j = z3;
    j[0][1] = 1e-5;
    refused(
        new(rods(2, 9.81, 0.0, &[0.0; 2]), plat, j, o),
        "platform_inertia",
    );
    let j = [[1e-5, 0.0, 0.0], [0.0, -1e-5, 0.0], [0.0, 0.0, 1e-5]];
    refused(
        new(rods(2, 9.81, 0.0, &[0.0; 2]), plat, j, o),
        "platform_inertia",
    );
    let mut p = plat;
    p.mass = -1.0;
    refused(
        new(rods(2, 9.81, 0.0, &[0.0; 2]), p, z3, o),
        "platform.mass",
    );
    let mut sys = new(rods(2, 9.81, 0.0, &[0.0; 2]), plat, z3, o).unwrap();
    refused(sys.step(&commands(&[0.0])), "commands");
    refused(sys.step(&[vec![0.0], vec![0.0, 1.0]]), "commands[1]");
    refused(sys.step(&[vec![0.0], vec![f64::NAN]]), "commands[1]");
    refused(
        sys.set_platform_loads([f64::NAN, 0.0, 0.0], [0.0; 3]),
        "platform.force[0]",
    );
    refused(sys.set_tensions(5, &[]), "rod");
    refused(sys.set_tensions(0, &[1.0]), "rods[0].tensions");
    // Nothing changed: the run goes on.
    sys.step(&commands(&[0.0, 0.0])).unwrap();
}

#[test]
fn tendon_tensions_drive_a_system_and_their_work_is_booked() {
    // Two of paper 002's hanging tendon arms 60 mm apart holding a 20 g platform,
    // undamped; rod 0's tendon 0 pulls with 1 N from the first step on: the platform moves,
    // and the books (the tension's work in the rods' stored energy) balance.
    let arm = |x: f64| {
        let mut spec = tendon_arm(false, false, 8, 0.0);
        spec.mounting.base_position = [x, 0.0, 0.0];
        Rod::new(spec).unwrap()
    };
    let rods: Vec<DynRod> = [-0.03, 0.03]
        .into_iter()
        .map(|x| {
            let rod = arm(x);
            DynRod {
                pressures: vec![0.0; rod.n_channels],
                tensions: vec![0.0; rod.n_tendons],
                sigma_map: SigmaMap::None,
                attachment: [x, 0.0, 0.0],
                attachment_rotation: HANGING,
                rod,
            }
        })
        .collect();
    let length = rods[0].rod.length;
    let plat = Platform {
        position: [0.0, 0.0, -length],
        ..platform(0.02, 9.81, [0.0; 3], [0.0; 3])
    };
    let channels = rods[0].rod.n_channels;
    let mut sys = SystemSimulator::new(rods, plat, [[0.0; 3]; 3], opts(1e-3, -0.5)).unwrap();
    let start = sys.platform_pose().0;
    sys.set_tensions(0, &[1.0, 0.0]).unwrap();
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for _ in 0..60 {
        sys.step(&[vec![0.0; channels], vec![0.0; channels]])
            .unwrap();
        worst = worst.max(sys.energy_balance().abs());
        let b = sys.energy_books();
        scale = scale.max(b.kinetic + b.work_in.abs());
    }
    let moved = dist(&sys.platform_pose().0, &start);
    eprintln!("tendons: platform moved {moved:.3e} m, |balance| <= {worst:.3e} J of {scale:.3e} J");
    assert!(
        moved > 1e-4,
        "the tension must move the platform: {moved:e}"
    );
    assert_eq!(sys.rods()[0].tensions(), &[1.0, 0.0]);
    // The trapezoidal rule's second-order error, as in the undamped platform's test.
    assert!(worst <= 1e-3 * scale, "{worst:e} vs {scale:e}");
}

/// Platform position and rotation and every rod's centreline after each step of `run`
/// (m), and the counters at the end.
fn trajectory(
    sys: &mut SystemSimulator,
    steps: usize,
    forget: bool,
    pressure: impl Fn(usize) -> Vec<f64>,
) -> Vec<Vec<f64>> {
    (0..steps)
        .map(|k| {
            if forget {
                sys.forget_matrix();
            }
            sys.step(&commands(&pressure(k))).unwrap();
            let (p, r) = sys.platform_pose();
            let mut out = p.to_vec();
            out.extend(r.iter().flatten().map(|x| x * L));
            for rod in sys.rods() {
                out.extend(rod.shape().iter().flatten());
            }
            out
        })
        .collect()
}

/// The largest difference between two trajectories of [`trajectory`], m.
fn largest_difference(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max)
}

/// How far two runs of the same steps may part when each converges its steps' Newton
/// to `tol` (DynOptions::tol, relative to max(1, |z|) of the scaled unknowns, positions
/// in units of L): each step's solution is within ~tol max(1, |z|) L of the step's exact
/// discrete solution in either run (the convergence test bounds the correction, or the
/// error it leaves at the measured rate), so the two differ by at most twice that per
/// step; the damped scheme does not amplify a perturbation (it decays), so over `steps`
/// steps they part by at most 2 tol max(1, |z|) L steps. max(1, |z|) <= 2 here: node
/// positions within 1.1 L of the origin, quaternions <= 1, the rods' forces (< 1 N: the
/// platform's weight, the rods' own, 40 kPa on a chamber of 13 mm^2) below F_s (~8 N,
/// `collocation::force_scale`) and velocities far below L c0.
fn newton_bound(tol: f64, steps: usize) -> f64 {
    2.0 * tol * 2.0 * L * steps as f64
}

/// A smooth pressure ramp on rod 0 over `ramp` steps (half a cosine), then held.
fn ramp(k: usize, ramp: usize) -> Vec<f64> {
    let s = ((k + 1) as f64 / ramp as f64).min(1.0);
    vec![40e3 * 0.5 * (1.0 - (PI * s).cos()), 0.0, 10e3 * s]
}

#[test]
fn kept_matrix_gives_the_refactored_trajectory_and_is_reused() {
    // Three damped rods on a 20 g platform with inertia, a smooth pressure ramp: the run
    // that keeps its bordered Newton matrix across steps against one that factors afresh
    // at every step's start (`forget_matrix`, the system's behaviour before it kept it).
    let plat = platform(0.02, 9.81, [0.0; 3], [0.0; 3]);
    let inertia = [[2e-6, 0.0, 0.0], [0.0, 2e-6, 0.0], [0.0, 0.0, 4e-6]];
    let o = opts(2e-3, -0.2);
    let steps = 100;
    let new = || SystemSimulator::new(rods(3, 9.81, 0.02, &[0.0; 3]), plat, inertia, o).unwrap();
    let (mut kept, mut fresh) = (new(), new());
    let a = trajectory(&mut kept, steps, false, |k| ramp(k, 50));
    let b = trajectory(&mut fresh, steps, true, |k| ramp(k, 50));
    let diff = largest_difference(&a, &b);
    let moved = dist(
        &a[steps - 1][..3].try_into().unwrap(),
        &a[0][..3].try_into().unwrap(),
    );
    eprintln!(
        "kept {:?}\nfresh {:?}\nlargest difference {diff:.3e} m (bound {:.3e} m), moved {moved:.3e} m",
        kept.stats,
        fresh.stats,
        newton_bound(o.tol, steps)
    );
    assert!(
        moved > 1e-3 * L,
        "the ramp must move the platform: {moved:e}"
    );
    assert!(diff <= newton_bound(o.tol, steps), "{diff:e}");
    // The refactoring run factors at least once per step; the kept matrix serves many
    // steps of this smooth motion (a refresh only where it contracts by less than 1/4).
    assert!(fresh.stats.jacobians >= steps, "{:?}", fresh.stats);
    assert!(
        10 * kept.stats.jacobians <= steps,
        "the kept matrix is refactored {} times in {steps} steps",
        kept.stats.jacobians
    );
}

#[test]
fn restore_at_another_step_refactors_and_continues_right() {
    // A state saved from a run at dt = 2 ms restored into the same system at dt = 1 ms:
    // the kept matrix (recomputed on restore from what it was computed from) belongs to
    // another c0 (twice as small), so the first step refactors, and the run equals one
    // that refactors at every step's start to the Newton tolerance.
    let plat = platform(0.02, 9.81, [0.0; 3], [0.0; 3]);
    let inertia = [[2e-6, 0.0, 0.0], [0.0, 2e-6, 0.0], [0.0, 0.0, 4e-6]];
    let (o2, o1) = (opts(2e-3, -0.2), opts(1e-3, -0.2));
    let new = |o| SystemSimulator::new(rods(3, 9.81, 0.02, &[0.0; 3]), plat, inertia, o).unwrap();
    let mut first = new(o2);
    trajectory(&mut first, 30, false, |k| ramp(k, 50));
    let saved = first.save();
    let (mut kept, mut fresh) = (new(o1), new(o1));
    kept.restore(&saved).unwrap();
    fresh.restore(&saved).unwrap();
    let before = kept.stats.jacobians;
    kept.step(&commands(&ramp(30, 50))).unwrap();
    assert!(
        kept.stats.jacobians > before,
        "the first step at the new dt refactors: {:?}",
        kept.stats
    );
    fresh.forget_matrix();
    fresh.step(&commands(&ramp(30, 50))).unwrap();
    let steps = 40;
    let a = trajectory(&mut kept, steps, false, |k| ramp(k + 31, 50));
    let b = trajectory(&mut fresh, steps, true, |k| ramp(k + 31, 50));
    let diff = largest_difference(&a, &b);
    eprintln!(
        "kept {:?}\nfresh {:?}\nlargest difference {diff:.3e} m (bound {:.3e} m)",
        kept.stats,
        fresh.stats,
        newton_bound(o1.tol, steps + 1)
    );
    assert!(diff <= newton_bound(o1.tol, steps + 1), "{diff:e}");
    assert!(
        kept.stats.jacobians < fresh.stats.jacobians,
        "{:?}",
        kept.stats
    );
}

/// `rods(2, ..)` with rod 0's section stiffness-mapped (`law.stiffness_map`), with `map`.
fn mapped_rods(tau: f64, pressures: &[f64], map: SigmaMap) -> Vec<DynRod> {
    let mut rs = rods(2, 9.81, tau, pressures);
    let mut spec = rs[0].rod.spec.clone();
    spec.sections[0].law.stiffness_map = true;
    rs[0].rod = Rod::new(spec).unwrap();
    rs[0].sigma_map = map;
    rs
}

#[test]
fn a_constant_stiffness_map_is_the_rod_with_its_stiffness_factors_multiplied() {
    // sigma = (c, c, c) scales c_e EA and c_b EI of the mapped section (shear and torsion
    // stay): the same rod unmapped with c_e = c_b = c is an independent model of it, damped
    // (B = tau K follows the scaled K in both).
    let c = 1.4;
    let o = DynOptions {
        tol: 1e-12,
        ..opts(2e-3, -0.2)
    };
    let plat = platform(0.02, 9.81, [0.0; 3], [0.0; 3]);
    let z3 = [[0.0; 3]; 3];
    let mut mapped = SystemSimulator::new(
        mapped_rods(0.05, &[0.0; 2], SigmaMap::Constant([c; 3])),
        plat,
        z3,
        o,
    )
    .unwrap();
    let mut rs = rods(2, 9.81, 0.05, &[0.0; 2]);
    let mut spec = rs[0].rod.spec.clone();
    spec.sections[0].c_e = c;
    spec.sections[0].c_b = c;
    rs[0].rod = Rod::new(spec).unwrap();
    let mut scaled = SystemSimulator::new(rs, plat, z3, o).unwrap();
    let steps = 30;
    let pressure = |k: usize| vec![40e3 * ((k + 1) as f64 / 10.0).min(1.0), 0.0];
    let a = trajectory(&mut mapped, steps, false, pressure);
    let b = trajectory(&mut scaled, steps, false, pressure);
    let diff = largest_difference(&a, &b);
    let moved = (a[steps - 1][0] - a[0][0]).abs() + (a[steps - 1][1] - a[0][1]).abs();
    eprintln!("constant map against scaled factors: {diff:.3e} m (moved {moved:.3e} m)");
    // The two differ only in the rounding of c EA sigma against (c c_e) EA: within the
    // Newton tolerance's bound of two runs.
    assert!(diff <= newton_bound(o.tol, steps), "{diff:e}");
    // The ramp moves the platform (measured 1.1e-4 m), far beyond the bound.
    assert!(moved > 1e-5, "the ramp moves the platform: {moved:e} m");
    // sigma acts: sigma = 1 is another motion.
    let mut unit = SystemSimulator::new(
        mapped_rods(0.05, &[0.0; 2], SigmaMap::Constant([1.0; 3])),
        plat,
        z3,
        o,
    )
    .unwrap();
    let u = trajectory(&mut unit, steps, false, pressure);
    assert!(largest_difference(&a, &u) > 1e-5);
}

#[test]
fn stiffness_map_refusals_name_the_rod() {
    let plat = platform(0.02, 9.81, [0.0; 3], [0.0; 3]);
    let z3 = [[0.0; 3]; 3];
    let o = opts(2e-3, -0.2);
    // No map for a mapped section: never sigma = 1.
    refused(
        SystemSimulator::new(mapped_rods(0.0, &[0.0; 2], SigmaMap::None), plat, z3, o),
        "rods[0].sections[0].law.stiffness_map",
    );
    // A table over 0..30 kPa that refuses beyond it: at the start and at a step.
    let grid = || SigmaMap::Grid {
        grid: GridPchip::new(vec![vec![0.0, 30e3]], vec![1.0, 1.0, 1.0, 0.8, 0.9, 1.2], 3).unwrap(),
        clamp: false,
    };
    refused(
        SystemSimulator::new(mapped_rods(0.0, &[40e3, 0.0], grid()), plat, z3, o),
        "rods[0].pressures[0]",
    );
    let mut sys = SystemSimulator::new(mapped_rods(0.0, &[0.0; 2], grid()), plat, z3, o).unwrap();
    sys.step(&commands(&[20e3, 0.0])).unwrap();
    refused(sys.step(&commands(&[40e3, 0.0])), "rods[0].pressures[0]");
    // Nothing changed: the run goes on within the table.
    sys.step(&commands(&[25e3, 0.0])).unwrap();
    // Clamped, the same table holds sigma beyond it.
    let clamped = SigmaMap::Grid {
        grid: GridPchip::new(vec![vec![0.0, 30e3]], vec![1.0, 1.0, 1.0, 0.8, 0.9, 1.2], 3).unwrap(),
        clamp: true,
    };
    let mut sys =
        SystemSimulator::new(mapped_rods(0.0, &[40e3, 0.0], clamped), plat, z3, o).unwrap();
    sys.step(&commands(&[50e3, 0.0])).unwrap();
}
