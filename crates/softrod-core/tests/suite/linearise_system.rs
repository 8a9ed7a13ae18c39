//! The linearised dynamics of a system of rods (`linearise::system`): a one-rod system
//! equals the lone free rod's linearisation with the platform as its tip body (another
//! residual, another code path); two straight rods holding a heavy platform against the
//! closed forms of a bar and of a cantilever with a tip mass, with their convergence
//! orders; K^-1 B against the system's input Jacobian at the platform; refusals by name.

use crate::common;
use common::*;
use nalgebra::DMatrix;
use softrod_core::jacobian::system::{system_jacobian, SystemInput};
use softrod_core::linearise::linearise;
use softrod_core::linearise::system::linearise_system;
use softrod_core::ode::Loads;
use softrod_core::spec::{DesignSpec, Frame, LineLoadSpec};
use softrod_core::statics::system::{solve_system, Platform, SystemRod};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-13,
        ..Default::default()
    }
}

const HANGING: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];

/// Paper 002's actuator hanging at x = `x`.
fn hanging_at(x: f64) -> DesignSpec {
    let mut d = p002_actuator(HANGING, 9.81, 12);
    d.mounting.base_position = [x, 0.0, 0.0];
    d
}

/// max |S (a - b) S| with S = diag(a)^-1/2: the difference relative to the diagonal scales
/// (coordinates in m and rad differ by orders of magnitude).
fn scaled_difference(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    let s: Vec<f64> = (0..a.nrows()).map(|i| a[(i, i)].abs().sqrt()).collect();
    let mut worst: f64 = 0.0;
    for i in 0..a.nrows() {
        for j in 0..a.ncols() {
            worst = worst.max((a[(i, j)] - b[(i, j)]).abs() / (s[i] * s[j]));
        }
    }
    worst
}

/// A one-rod system whose platform sits at the free rod's tip (attachment at its origin,
/// frames aligned) and carries what the lone rod's tip body carries: the same equilibrium,
/// the same coordinates (the lone rod's n nodes are the system's n - 1 inner nodes and the
/// platform), so the same M, D, K and B, from the system residual instead of the free tip's.
#[test]
fn one_rod_system_equals_the_lone_rod() {
    let (mass, com, inertia) = (5e-3, [3e-3, 1e-3, 2e-3], [2e-7, 3e-7, 1e-7]);
    let mut lone_spec = hanging_at(0.0);
    lone_spec.dynamics.damping_time = 0.01;
    lone_spec.tip.mass = mass;
    lone_spec.tip.com_offset = com;
    lone_spec.tip.inertia = inertia;
    let lone_rod = Rod::new(lone_spec.clone()).unwrap();
    let mut bare = lone_spec;
    bare.tip.mass = 0.0;
    bare.tip.com_offset = [0.0; 3];
    bare.tip.inertia = [0.0; 3];
    let rod = Rod::new(bare).unwrap();
    let p = [18e3, 4e3, 0.0];
    let free = solve(&lone_rod, &loads(&p), None, &opts()).unwrap();
    let n = 6;
    let lone = linearise(&lone_rod, &loads(&p), &free, n).unwrap();
    let pf = Platform {
        position: free.tip.r,
        rotation: free.tip.rot,
        force: [0.0; 3],
        moment: [0.0; 3],
        mass,
        com_offset: com,
        gravity: [0.0, 0.0, -9.81],
    };
    let system = vec![SystemRod {
        rod: &rod,
        loads: loads(&p),
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    }];
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let j = [
        [inertia[0], 0.0, 0.0],
        [0.0, inertia[1], 0.0],
        [0.0, 0.0, inertia[2]],
    ];
    let mut inputs: Vec<SystemInput> = (0..3)
        .map(|c| SystemInput::Pressure { rod: 0, channel: c })
        .collect();
    inputs.extend((0..3).map(SystemInput::PlatformForce));
    inputs.extend((0..3).map(SystemInput::PlatformMoment));
    let lin = linearise_system(&system, &pf, &j, &sol, n - 1, &inputs).unwrap();
    assert_eq!(lin.nodes[0].len(), n - 1);
    for (a, b) in lin.nodes[0].iter().zip(&lone.nodes) {
        assert!((a - b).abs() < 1e-12);
    }
    // Two exact linearisations of one equilibrium (each solved to 1e-13), through a 36 x 36
    // inverse: K and D agree to ~1e-9 of the diagonal scales, and so do the mass's Gram
    // matrices in load coordinates, C^T M C (C = K^-1), which both sides integrate.
    for (what, a, b) in [
        ("stiffness", &lin.stiffness, &lone.stiffness),
        ("damping", &lin.damping, &lone.damping),
    ] {
        let d = scaled_difference(b, a);
        assert!(d < 1e-9, "{what}: {d:.2e}");
    }
    let cs = lin.stiffness.clone().try_inverse().unwrap();
    let cl = lone.stiffness.clone().try_inverse().unwrap();
    let gram_s = cs.transpose() * &lin.mass * &cs;
    let gram_l = cl.transpose() * &lone.mass * &cl;
    let d = scaled_difference(&gram_l, &gram_s);
    assert!(d < 1e-9, "mass in load coordinates: {d:.2e}");
    // M = K^T G K itself cancels: its diagonal is up to ~1e9 times smaller than
    // (|K|^T |G| |K|)_ii here, so its round-off is that factor times a few ulps (measured
    // 1.4e-7 of the diagonal scales). Bound: 16 ulps of the uncancelled products.
    let k = lone.stiffness.abs();
    let uncancelled = k.transpose() * gram_l.abs() * &k;
    let factor = (0..k.nrows())
        .map(|i| uncancelled[(i, i)] / lone.mass[(i, i)])
        .fold(0.0f64, f64::max);
    let d = scaled_difference(&lone.mass, &lin.mass);
    assert!(
        d < 16.0 * f64::EPSILON * factor,
        "mass: {d:.2e}, factor {factor:.2e}"
    );
    // B: the same columns (pressures, then the tip's force and moment = the platform's).
    let resp_s = lin.stiffness.clone().try_inverse().unwrap() * &lin.input;
    let resp_l = lone.stiffness.clone().try_inverse().unwrap() * &lone.input;
    for c in 0..9 {
        let scale = resp_l.column(c).norm();
        let err = (resp_s.column(c) - resp_l.column(c)).norm();
        assert!(err < 1e-7 * scale, "input {c}: {err:.2e} of {scale:.2e}");
    }
    let wl = frequencies(&lone.mass, &lone.stiffness);
    let ws = frequencies(&lin.mass, &lin.stiffness);
    // The lowest twelve modes (bending, torsion): the mass's round-off above reaches the
    // stiffest axial and shear modes (6 kHz here) at ~1e-7, the low ones far less.
    assert_eq!(wl.len(), ws.len());
    for (a, b) in wl.iter().zip(&ws).take(12) {
        assert!((a / b - 1.0).abs() < 1e-8, "{a} vs {b}");
    }
}

const L: f64 = 0.5;
const EI: f64 = 0.02;
const EA: f64 = 400.0;
const MASS: f64 = 0.1; // kg over L
const GAP: f64 = 0.02;

/// Two straight, nearly shear-rigid rods along z (bases at x = -GAP and +GAP, no gravity)
/// holding a point platform of mass `mp` at their tips, `nodes` inner nodes each.
fn two_rod_platform(nodes: usize, mp: f64) -> Vec<f64> {
    let spec = |x: f64| {
        let mut s = direct_section("rod", L, EA, 1e10, EI, 0.015, MASS, 64);
        s.rotary_inertia = Some([1e-9, 1e-9, 2e-6]);
        let mut d = design(vec![s], IDENTITY, 0.0);
        d.mounting.base_position = [x, 0.0, 0.0];
        d
    };
    let (r0, r1) = (Rod::new(spec(-GAP)).unwrap(), Rod::new(spec(GAP)).unwrap());
    let pf = Platform {
        position: [0.0, 0.0, L],
        rotation: IDENTITY,
        force: [0.0; 3],
        moment: [0.0; 3],
        mass: mp,
        com_offset: [0.0; 3],
        gravity: [0.0; 3],
    };
    let rod = |r, x: f64| SystemRod {
        rod: r,
        loads: loads(&[]),
        attachment: [x, 0.0, 0.0],
        attachment_rotation: IDENTITY,
    };
    let system = vec![rod(&r0, -GAP), rod(&r1, GAP)];
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let lin = linearise_system(&system, &pf, &[[0.0; 3]; 3], &sol, nodes, &[]).unwrap();
    assert_eq!(lin.mass.nrows(), 12 * nodes + 6);
    let asym = (&lin.mass - lin.mass.transpose()).amax() / lin.mass.amax();
    assert!(asym < 1e-10, "{asym}");
    assert!(lin.mass.clone().cholesky().is_some());
    frequencies(&lin.mass, &lin.stiffness)
}

/// Root of `f` in [a, b] by bisection (f changes sign there).
fn bisect(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if (f(a) < 0.0) == (f(m) < 0.0) {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// The platform (as heavy as both rods) bouncing along the rods: each rod a bar fixed at
/// its base carrying half the platform, (w L / c) tan(w L / c) = m_rod / (m_p / 2); swaying
/// across the rods' plane (y): the platform has no rotary inertia, so it puts no moment on
/// the tips, and each rod is a cantilever with a tip mass m_p / 2,
/// 1 + cos b cosh b + mu b (cos b sinh b - sin b cosh b) = 0, mu = m_p / 2 / m_rod
/// (Euler-Bernoulli). Extension converges as n^-2 (linear static shapes), bending as n^-4.
#[test]
fn two_rod_platform_frequencies_match_closed_forms() {
    let mp = 2.0 * MASS;
    let mu = 0.5 * mp / MASS;
    let c = (EA / (MASS / L)).sqrt();
    let beta_axial = bisect(|b| b * b.tan() - 1.0 / mu, 0.1, 1.5);
    let axial = beta_axial * c / L;
    let lam = bisect(
        |b| 1.0 + b.cos() * b.cosh() + mu * b * (b.cos() * b.sinh() - b.sin() * b.cosh()),
        0.5,
        1.8,
    );
    let sway = lam * lam * (EI / (MASS / L * L.powi(4))).sqrt();
    let near = |w: &[f64], target: f64| {
        w.iter()
            .map(|x| (x / target - 1.0).abs())
            .fold(f64::INFINITY, f64::min)
    };
    let mut errors = Vec::new();
    for nodes in [3, 7, 15] {
        let w = two_rod_platform(nodes, mp);
        let e = [near(&w, axial), near(&w, sway)];
        println!("{nodes} nodes: axial {:.2e}, sway {:.2e}", e[0], e[1]);
        errors.push(e);
    }
    let order = |k: usize, a: usize| (errors[a][k] / errors[a + 1][k]).log2();
    for a in 0..2 {
        assert!((order(0, a) - 2.0).abs() < 0.25, "axial {errors:?}");
        assert!(order(1, a) > 3.5, "sway {errors:?}");
    }
    // At 15 nodes (h = L / 16) within the linear elements' leading term (k h)^2 / 24 with
    // k = beta / L (the tip mass's share of the energy only lowers it), and the sway within
    // the cubic elements' (lambda h / L)^4 / 1440, each half as much again for the next
    // order.
    let h = L / 16.0;
    assert!(
        errors[2][0] < 1.5 * (beta_axial * h / L).powi(2) / 24.0,
        "{errors:?}"
    );
    assert!(
        errors[2][1] < 1.5 * (lam * h / L).powi(4) / 1440.0,
        "{errors:?}"
    );
}

/// A platform hung from two of paper 002's actuators (pressurised, its centre of mass off
/// its origin, a side force): the platform's rows of K^-1 B are the system's input Jacobian
/// (`jacobian::system`, the same implicit differentiation without the node loads). The same
/// with a follower line load on the first rod's body (every rod's base force is a system
/// unknown anyway; the load turns with the rod, so K is not symmetric).
#[test]
fn static_response_is_the_system_jacobian() {
    let mut follower = hanging_at(-0.02);
    follower.loads = vec![LineLoadSpec {
        section: 1,
        force_per_length: [0.2, 0.0, -0.1],
        moment_per_length: [0.0, 0.0, 5e-3],
        frame: Frame::Body,
    }];
    let asym = |k: DMatrix<f64>| (&k - k.transpose()).amax() / k.amax();
    let dead = asym(static_response_of(hanging_at(-0.02)));
    let turning = asym(static_response_of(follower));
    // The dead loads' K is symmetric but for the world-frame small rotations' terms of the
    // prestress moments (a dead moment has no potential in them); the follower load adds
    // its own non-symmetric part (measured 2e-7 against 1e-9 of max |K|).
    println!("K - K^T: dead {dead:.1e}, follower {turning:.1e} of max |K|");
    assert!(turning > 10.0 * dead, "{dead:.1e} {turning:.1e}");
}

/// The system's K, after checking its static response.
fn static_response_of(first: DesignSpec) -> DMatrix<f64> {
    let (r0, r1) = (
        Rod::new(first).unwrap(),
        Rod::new(hanging_at(0.02)).unwrap(),
    );
    let pf = Platform {
        position: [0.0, 0.0, -0.134],
        rotation: HANGING,
        force: [4e-3, -2e-3, 0.0],
        moment: [0.0; 3],
        mass: 5e-3,
        com_offset: [3e-3, 1e-3, 2e-3],
        gravity: [0.0, 0.0, -9.81],
    };
    let ld: [Loads; 2] = [loads(&[18e3, 4e3, 0.0]), loads(&[0.0, 12e3, 6e3])];
    let system: Vec<SystemRod> = [(&r0, -0.02), (&r1, 0.02)]
        .iter()
        .zip(&ld)
        .map(|(&(r, x), l)| SystemRod {
            rod: r,
            loads: l.clone(),
            attachment: [x, 0.0, 0.0],
            attachment_rotation: IDENTITY,
        })
        .collect();
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let mut inputs: Vec<SystemInput> = Vec::new();
    for rod in 0..2 {
        inputs.extend((0..3).map(|channel| SystemInput::Pressure { rod, channel }));
    }
    inputs.push(SystemInput::PlatformForce(1));
    inputs.push(SystemInput::PlatformMoment(2));
    let j = [[1e-7, 0.0, 0.0], [0.0, 2e-7, 0.0], [0.0, 0.0, 3e-7]];
    let lin = linearise_system(&system, &pf, &j, &sol, 4, &inputs).unwrap();
    let jac = system_jacobian(&system, &pf, &sol, &inputs).unwrap();
    let resp = lin.stiffness.clone().try_inverse().unwrap() * &lin.input;
    let o = resp.nrows() - 6;
    for (k, (dp, dw)) in jac.d_position.iter().zip(&jac.d_rotation).enumerate() {
        let want = [dp[0], dp[1], dp[2], dw[0], dw[1], dw[2]];
        let scale = want.iter().map(|v| v * v).sum::<f64>().sqrt();
        let err = (0..6)
            .map(|r| (resp[(o + r, k)] - want[r]).powi(2))
            .sum::<f64>()
            .sqrt();
        // The same implicit differentiation by another pass; a 54 x 54 inverse.
        assert!(err < 1e-8 * scale, "input {k}: {err:.2e} of {scale:.2e}");
    }
    assert!(lin.mass.clone().cholesky().is_some());
    assert!(frequencies(&lin.mass, &lin.stiffness)[0] > 0.0);
    // Refusals by name: the inertia, the node count, an input.
    let bad = |r: softrod_core::Result<_>, field: &str| match r {
        Err(SoftrodError::InvalidParameter { field: f, .. }) => assert_eq!(f, field),
        other => panic!("{field}: {other:?}"),
    };
    let mut asym = j;
    asym[0][1] = 1e-7;
    bad(
        linearise_system(&system, &pf, &asym, &sol, 4, &inputs),
        "platform_inertia[0][1]",
    );
    bad(
        linearise_system(&system, &pf, &j, &sol, 1000, &inputs),
        "rods[0].nodes",
    );
    bad(
        linearise_system(
            &system,
            &pf,
            &j,
            &sol,
            4,
            &[SystemInput::Pressure { rod: 2, channel: 0 }],
        ),
        "inputs[0]",
    );
    lin.stiffness
}

/// The same rod carrying the body itself on a massless platform whose origin lies 1 cm off
/// the tip (the attachment offset): other coordinates for the platform (its origin, not the
/// tip), the rod's tip body about a lever, the same motion, so the same frequencies.
#[test]
fn a_rod_tip_body_rides_on_the_platform() {
    let mut spec = hanging_at(0.0);
    spec.tip.mass = 5e-3;
    spec.tip.com_offset = [3e-3, 1e-3, 2e-3];
    spec.tip.inertia = [2e-7, 3e-7, 1e-7];
    let rod = Rod::new(spec).unwrap();
    let p = [18e3, 4e3, 0.0];
    let free = solve(&rod, &loads(&p), None, &opts()).unwrap();
    let lone = linearise(&rod, &loads(&p), &free, 6).unwrap();
    // The platform frame is the tip's; its origin at -o from the tip in that frame.
    let o = [0.01, 0.0, 0.0];
    let origin: [f64; 3] = std::array::from_fn(|i| {
        free.tip.r[i] - (0..3).map(|k| free.tip.rot[i][k] * o[k]).sum::<f64>()
    });
    let pf = Platform {
        position: origin,
        rotation: free.tip.rot,
        force: [0.0; 3],
        moment: [0.0; 3],
        mass: 0.0,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -9.81],
    };
    let system = vec![SystemRod {
        rod: &rod,
        loads: loads(&p),
        attachment: o,
        attachment_rotation: IDENTITY,
    }];
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let lin = linearise_system(&system, &pf, &[[0.0; 3]; 3], &sol, 5, &[]).unwrap();
    let (wl, ws) = (
        frequencies(&lone.mass, &lone.stiffness),
        frequencies(&lin.mass, &lin.stiffness),
    );
    // As in `one_rod_system_equals_the_lone_rod`: the lowest twelve modes to 1e-8.
    for (a, b) in wl.iter().zip(&ws).take(12) {
        assert!((a / b - 1.0).abs() < 1e-8, "{a} vs {b}");
    }
}
