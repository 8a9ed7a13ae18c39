//! Tendons and follower loads in dynamics (issue 17): the collocation dynamics carries the
//! implicit tendon law of the statics (Rucker and Webster 2011; `crate::tendon`) with
//! Kelvin-Voigt damping, and follower (body-frame) tip and line loads. A damped run under
//! constant tensions (or follower loads) settles on the static equilibrium of the same
//! discretisation (collocation statics) to 1e-9 L; the exact Jacobian of a step matches
//! finite differences; the energy balance E - E(0) = W_in - D holds with the tendons'
//! potential and the work of changing tensions, and with the work of follower loads; bad
//! tensions are refused with the field named.

use crate::common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, SigmaMap, Simulator};
use softrod_core::ode::Loads;
use softrod_core::statics::collocation::solve_static;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

const LENGTH: f64 = 0.134;
const P: [f64; 3] = [20e3, 0.0, 10e3];
const T: [f64; 2] = [4.0, 1.5];

fn cases() -> [(&'static str, bool, bool); 3] {
    [
        ("straight", false, false),
        ("helical", true, false),
        ("helical, stretch bending", true, true),
    ]
}

fn tensioned(p: &[f64], t: &[f64]) -> Loads {
    Loads {
        tensions: t.to_vec(),
        ..loads(p)
    }
}

fn tight() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

fn start(rod: &Rod, p: &[f64], t: &[f64], opts: DynOptions) -> Simulator {
    let (f, m) = (rod.spec.tip.force, rod.spec.tip.moment);
    Simulator::with_tensions(
        rod.clone(),
        p,
        t,
        Initial::Static,
        opts,
        SigmaMap::None,
        f,
        m,
    )
    .unwrap()
}

/// From rest, slack, to tensions T (and pressures P) held for 3 s with tau = 0.05 s: as
/// tests/suite/dynamics_laws.rs, the run settles on collocation statics with the same tensions to
/// 1e-9 L, and on the shooting statics to the two discretisations' difference.
#[test]
fn damped_tendon_runs_settle_on_statics() {
    for (name, helical, sb) in cases() {
        let rod = Rod::new(tendon_arm(helical, sb, 8, 0.05)).unwrap();
        let opts = DynOptions {
            dt: 5e-3,
            tol: 1e-12,
            ..Default::default()
        };
        let mut sim = start(&rod, &[0.0; 3], &[0.0; 2], opts);
        let begin = sim.tip().r;
        sim.set_tensions(&T).unwrap();
        for _ in 0..600 {
            sim.step(&P).unwrap();
        }
        let ld = tensioned(&P, &T);
        check_settled(name, &sim, &rod, &ld, begin, 2e-3);
    }
}

/// A damped run that has settled under the loads `ld`: it moved more than `min_move` from
/// `begin`, lies on collocation statics to 1e-9 L (the same discretisation at rest) and on
/// shooting statics to 2e-5 L (RK4 and collocation differ by their O(h^4) errors at 8 steps
/// per section: largest for the helical route, 5e-6 L).
fn check_settled(
    name: &str,
    sim: &Simulator,
    rod: &Rod,
    ld: &Loads,
    begin: [f64; 3],
    min_move: f64,
) {
    let st = solve_static(rod, ld, None, &tight()).unwrap();
    let shot = solve(rod, ld, None, &tight()).unwrap();
    let d = dist(&sim.tip().r, st.evaluated.node_r.last().unwrap());
    let ds = dist(&sim.tip().r, &shot.tip.r);
    let moved = dist(&sim.tip().r, &begin);
    eprintln!(
        "{name}: moved {moved:.4e} m; off collocation statics {d:.3e} m, off shooting {ds:.3e} m; balance {:.2e} J, work in {:.2e} J",
        sim.energy_balance(),
        sim.energy_books().work_in
    );
    assert!(moved > min_move, "{name}: the inputs move the tip");
    assert!(d < 1e-9 * LENGTH, "{name}: {d}");
    assert!(ds < 2e-5 * LENGTH, "{name}: {ds}");
}

#[test]
fn step_jacobian_with_tendons_matches_finite_differences() {
    for (name, helical, sb) in cases() {
        let rod = Rod::new(tendon_arm(helical, sb, 2, 0.05)).unwrap();
        let mut sim = start(&rod, &[0.0; 3], &[0.0; 2], DynOptions::default());
        sim.set_tensions(&T).unwrap();
        for _ in 0..10 {
            sim.step(&P).unwrap();
        }
        check_step_jacobian(name, &sim);
    }
}

/// Undamped and lightly damped runs driven by the tendons: a jump of the tensions, a ramp
/// and a release. The energy balance counts the tendons' potential sum tau (|q| - |q0|) and
/// the work of changing tensions: with the midpoint rule (no numerical damping) |E - E(0) -
/// W_in + D| stays within 1 % of the energy moved at every step (measured 0.1 %) and the
/// swing under constant tensions keeps its energy to 1 %; BDF-alpha may only lose energy
/// (its numerical damping of the modes the jump excites), never gain more than 1 %.
#[test]
fn tendon_runs_keep_their_energy_balance() {
    for (scheme, alpha, tau) in [
        (Scheme::Midpoint, -0.2, 0.0),
        (Scheme::BdfAlpha, -0.2, 0.0),
        (Scheme::BdfAlpha, -0.45, 0.005),
    ] {
        let rod = Rod::new(tendon_arm(true, false, 4, tau)).unwrap();
        let opts = DynOptions {
            dt: 2e-3,
            scheme,
            alpha,
            ..Default::default()
        };
        let mut sim = start(&rod, &[0.0; 3], &[0.0; 2], opts);
        let mut worst: f64 = 0.0;
        let mut moved: f64 = 0.0;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..400 {
            let t = (k + 1) as f64 * 2e-3;
            // Jump to T at once, ramp tendon 1 up over 0.2-0.4 s, hold, release at 0.6 s.
            let t1 = if t < 0.2 {
                T[1]
            } else {
                T[1] * (1.0 + 2.0 * ((t - 0.2) / 0.2).min(1.0))
            };
            let tens = if t < 0.6 { [T[0], t1] } else { [0.0, 0.0] };
            sim.set_tensions(&tens).unwrap();
            sim.step(&[0.0; 3]).unwrap();
            let b = sim.energy_books();
            moved = moved.max(b.work_in.abs() + b.dissipated + b.kinetic);
            // Growth is what the check forbids; BDF-alpha's numerical damping (a loss) is
            // not, so only the midpoint rule is held to |balance|.
            let b = sim.energy_balance();
            worst = worst.max(if scheme == Scheme::Midpoint {
                b.abs()
            } else {
                b
            });
            if (0.45..0.6).contains(&t) {
                lo = lo.min(sim.energy());
                hi = hi.max(sim.energy());
            }
        }
        let b = sim.energy_books();
        eprintln!(
            "{}, alpha {alpha}, tau {tau}: worst |balance| {worst:.3e} J of {moved:.3e} J moved; work in {:.3e} J, dissipated {:.3e} J; constant-tension energy range {:.3e} J",
            scheme.name(),
            b.work_in,
            b.dissipated,
            hi - lo
        );
        assert!(b.work_in.abs() > 1e-4, "the tensions do work");
        assert!(worst <= 1e-2 * moved, "balance {worst} of {moved}");
        if scheme == Scheme::Midpoint {
            assert!(hi - lo <= 1e-2 * moved, "{lo}..{hi}");
        }
    }
}

#[test]
fn bad_tensions_are_refused_with_the_field_named() {
    let rod = Rod::new(tendon_arm(false, false, 2, 0.05)).unwrap();
    let mut sim = start(&rod, &[0.0; 3], &[0.0; 2], DynOptions::default());
    for (t, field) in [
        (vec![1.0, -0.5], "tensions[1]"),
        (vec![f64::NAN, 0.0], "tensions[0]"),
        (vec![1.0], "tensions"),
    ] {
        let err = sim.set_tensions(&t).unwrap_err().to_string();
        assert!(err.contains(field), "{err}");
    }
    assert_eq!(sim.tensions(), &[0.0, 0.0]);
    let (f, m) = (rod.spec.tip.force, rod.spec.tip.moment);
    let err = Simulator::with_tensions(
        rod,
        &[0.0; 3],
        &[0.5, f64::INFINITY],
        Initial::Static,
        DynOptions::default(),
        SigmaMap::None,
        f,
        m,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("tensions[1]"), "{err}");
    // The straight start is at rest with slack tendons.
    let rod = Rod::new(tendon_arm(false, false, 2, 0.05)).unwrap();
    let err = Simulator::with_tensions(
        rod.clone(),
        &[0.0; 3],
        &[0.0, 0.5],
        Initial::Straight,
        DynOptions::default(),
        SigmaMap::None,
        f,
        m,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("tensions[1]") && err.contains("straight"),
        "{err}"
    );
    let mut sim = Simulator::with_tensions(
        rod,
        &[0.0; 3],
        &[0.0, 0.0],
        Initial::Straight,
        DynOptions::default(),
        SigmaMap::None,
        f,
        m,
    )
    .unwrap();
    sim.set_tensions(&[0.0, 0.5]).unwrap();
    sim.step(&[0.0; 3]).unwrap();
}

#[test]
fn restored_tendon_run_continues_bit_for_bit() {
    let rod = Rod::new(tendon_arm(true, false, 4, 0.05)).unwrap();
    let mut sim = start(&rod, &[0.0; 3], &T, DynOptions::default());
    sim.set_tensions(&[2.0, 0.1]).unwrap();
    for _ in 0..5 {
        sim.step(&P).unwrap();
    }
    let saved = sim.save();
    let mut other = start(&rod, &[0.0; 3], &[0.0; 2], DynOptions::default());
    other.restore(&saved).unwrap();
    assert_eq!(other.tensions(), sim.tensions());
    for _ in 0..5 {
        sim.step(&P).unwrap();
        other.step(&P).unwrap();
    }
    assert_eq!(sim.unknowns(), other.unknowns());
}

/// A damped run from rest in equilibrium under the follower loads at 0 kPa, driven to P,
/// settles on
/// collocation statics with the same follower loads (1e-9 L) and on the shooting statics
/// (to the discretisations' difference).
#[test]
fn damped_follower_runs_settle_on_statics() {
    for (name, spec) in follower_cases(8) {
        let rod = Rod::new(spec).unwrap();
        let opts = DynOptions {
            dt: 5e-3,
            tol: 1e-12,
            ..Default::default()
        };
        let (f, m) = (rod.spec.tip.force, rod.spec.tip.moment);
        let mut sim = start(&rod, &[0.0; 3], &[], opts);
        let begin = sim.tip().r;
        let ld = Loads {
            tip_force: f,
            tip_moment: m,
            tip_frame: rod.spec.tip.frame,
            ..loads(&P)
        };
        for _ in 0..600 {
            sim.step(&P).unwrap();
        }
        check_settled(name, &sim, &rod, &ld, begin, 1e-3);
    }
}

#[test]
fn step_jacobian_with_follower_loads_matches_finite_differences() {
    for (name, mut spec) in follower_cases(8) {
        for s in &mut spec.sections {
            s.steps = 2;
        }
        let rod = Rod::new(spec).unwrap();
        let mut sim = start(&rod, &[0.0; 3], &[], DynOptions::default());
        for _ in 0..10 {
            sim.step(&P).unwrap();
        }
        check_step_jacobian(name, &sim);
    }
}

/// Follower loads are not conservative: their power F_b . q + M_b . w (tip) and
/// f_b . q + l_b . w (line) is integrated into W_in (trapezoidal rule in time). Lightly
/// damped runs driven from rest keep the balance: the midpoint rule to 1 % of the energy
/// moved (measured 4e-5), BDF-alpha without growth beyond 1 % (it only loses energy).
#[test]
fn follower_runs_keep_their_energy_balance() {
    for (name, spec) in follower_cases(8) {
        let mut spec = spec;
        spec.dynamics.damping_time = 0.002;
        for s in &mut spec.sections {
            s.steps = 4;
        }
        let rod = Rod::new(spec).unwrap();
        for (scheme, alpha) in [(Scheme::Midpoint, -0.2), (Scheme::BdfAlpha, -0.3)] {
            let opts = DynOptions {
                dt: 2e-3,
                scheme,
                alpha,
                ..Default::default()
            };
            let mut sim = start(&rod, &[0.0; 3], &[], opts);
            let mut worst: f64 = 0.0;
            let mut moved: f64 = 0.0;
            for _ in 0..300 {
                sim.step(&P).unwrap();
                let b = sim.energy_books();
                moved = moved.max(b.work_in.abs() + b.dissipated + b.kinetic);
                let e = sim.energy_balance();
                worst = worst.max(if scheme == Scheme::Midpoint {
                    e.abs()
                } else {
                    e
                });
            }
            eprintln!(
                "{name}, {}: worst balance {worst:.3e} J of {moved:.3e} J moved, final {:.3e} J, work in {:.3e} J",
                scheme.name(),
                sim.energy_balance(),
                sim.energy_books().work_in
            );
            assert!(worst <= 1e-2 * moved, "{name}: {worst} of {moved}");
        }
    }
}
