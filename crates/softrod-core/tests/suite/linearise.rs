//! The linearised dynamics (crate::linearise): natural frequencies of a straight cantilever
//! against the closed forms (bending, axial, torsion), convergence with the number of nodes,
//! the static consistency of K and B with the exact Jacobians, M symmetric positive
//! definite, D = tau K for an unstressed rod; the same for a clamped tip (clamped-clamped
//! beam and bar frequencies, the held equilibrium's Jacobians) and a pinned one
//! (clamped-pinned beam, fixed-fixed bar, torsion free at the pin; the tip body's inertia
//! about the pin).

use crate::common;
use common::*;
use softrod_core::jacobian::{point_jacobian, point_jacobian6, Input, Probe};
use softrod_core::linearise::{linearise, linearise_held};
use softrod_core::ode::Loads;
use softrod_core::spec::DesignSpec;
use softrod_core::spec::Frame;
use softrod_core::statics::constraint::{solve_constrained, TipConstraint};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

const L: f64 = 0.5;
const EI: f64 = 0.02;
const EA: f64 = 400.0;
const GA: f64 = 1e6; // nearly shear-rigid: the Euler-Bernoulli limit
const GJ: f64 = 0.015;
const MASS: f64 = 0.1; // kg over L
const ROT: [f64; 3] = [1e-9, 1e-9, 2e-6]; // rho I tiny (no rotary inertia in bending), rho J for torsion

fn cantilever(steps: usize, g: f64) -> DesignSpec {
    let mut s = direct_section("rod", L, EA, GA, EI, GJ, MASS, steps);
    s.rotary_inertia = Some(ROT);
    design(vec![s], IDENTITY, g)
}

/// Relative errors of the first two bending frequencies (modes in pairs: EI1 = EI2, so
/// w[0], w[1] the first and w[2], w[3] the second) and of the frequencies nearest the axial
/// and torsional ones, printed with the node count.
fn mode_errors(nodes: usize, w: &[f64], bending: [f64; 2], axial: f64, torsion: f64) -> [f64; 4] {
    let pair = |k: usize| {
        (w[2 * k] / bending[k] - 1.0)
            .abs()
            .max((w[2 * k + 1] / bending[k] - 1.0).abs())
    };
    let find = |target: f64| {
        w.iter()
            .map(|x| (x / target - 1.0).abs())
            .fold(f64::INFINITY, f64::min)
    };
    let e = [pair(0), pair(1), find(axial), find(torsion)];
    println!(
        "{nodes} nodes: bending 1 {:.2e}, bending 2 {:.2e}, axial {:.2e}, torsion {:.2e}",
        e[0], e[1], e[2], e[3]
    );
    e
}

/// Straight cantilever without gravity: bending (two equal families), axial and torsional
/// frequencies against the closed forms of the Euler-Bernoulli beam and the bar.
#[test]
fn cantilever_frequencies_match_closed_forms() {
    let rod = Rod::new(cantilever(64, 0.0)).unwrap();
    let ld = loads(&[]);
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let rho_a = MASS / L;
    let beam = |beta_l: f64| beta_l * beta_l * (EI / (rho_a * L.powi(4))).sqrt();
    let axial = std::f64::consts::FRAC_PI_2 * (EA / (rho_a * L * L)).sqrt();
    let torsion = std::f64::consts::FRAC_PI_2 * (GJ / (ROT[2] * L * L)).sqrt();
    let mut errors = Vec::new();
    for nodes in [4, 8, 16] {
        let sys = linearise(&rod, &ld, &sol, nodes).unwrap();
        let w = frequencies(&sys.mass, &sys.stiffness);
        let want = [beam(1.875_104_068_711_961), beam(4.694_091_132_974_175)];
        errors.push(mode_errors(nodes, &w, want, axial, torsion));
    }
    // Between the nodes the rod takes its static shapes under node loads: cubic in bending
    // (Hermite-like, frequencies converge as n^-4) and linear in extension and torsion (n^-2).
    let order = |k: usize, a: usize| (errors[a][k] / errors[a + 1][k]).log2();
    for a in 0..2 {
        assert!(
            order(0, a) > 3.5 && order(1, a) > 3.5,
            "bending order {a}: {errors:?}"
        );
        assert!((order(2, a) - 2.0).abs() < 0.2 && (order(3, a) - 2.0).abs() < 0.2);
    }
    // At 16 nodes: bending to 1e-5 (the RK4 error of K and the Simpson quadrature of M on 64
    // steps are both far below), extension and torsion to 5e-4 (linear shapes).
    assert!(errors[2][0] < 1e-5 && errors[2][1] < 1e-5, "{errors:?}");
    assert!(errors[2][2] < 5e-4 && errors[2][3] < 5e-4, "{errors:?}");
}

/// K^-1 reproduces the exact static responses: the tip rows of K^-1 B are the Jacobian of
/// the tip pose with respect to pressures and tip loads (crate::jacobian).
#[test]
fn static_response_of_the_linear_system_is_exact() {
    let rod = Rod::new(p002_actuator(tilted(), 9.81, 12)).unwrap();
    let ld = Loads {
        pressures: vec![35e3, 12e3, 50e3],
        tip_force: [0.02, -0.01, 0.03],
        tip_moment: [0.0; 3],
        stiffness_scale: [1.0; 3],
        tensions: vec![],
        tip_frame: Frame::World,
    };
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let sys = linearise(&rod, &ld, &sol, 9).unwrap();
    let inputs = [
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
    let jac = point_jacobian(&rod, &ld, &sol, &inputs, &Probe::tip(&rod)).unwrap();
    assert_tip_response("actuator", &sys, &jac);
    // M symmetric positive definite.
    let asym = (&sys.mass - sys.mass.transpose()).amax() / sys.mass.amax();
    assert!(asym < 1e-10, "{asym}");
    assert!(sys.mass.clone().cholesky().is_some());
}

/// A tendon's input column (after the pressures and tip loads): its static response is the
/// exact tension derivative of the equilibrium, at a pulled and at a slack tendon.
#[test]
fn static_response_of_tension_columns_is_exact() {
    let mut spec = p002_actuator(tilted(), 9.81, 12);
    for sec in &mut spec.sections[..2] {
        sec.tendons = vec![
            softrod_core::spec::TendonSpec {
                channel: 0,
                distance: 0.006,
                angle: 1.0,
                distance_end: None,
                angle_end: None,
            },
            softrod_core::spec::TendonSpec {
                channel: 1,
                distance: 0.006,
                angle: 3.0,
                distance_end: None,
                angle_end: None,
            },
        ];
    }
    let rod = Rod::new(spec).unwrap();
    let ld = Loads {
        tensions: vec![1.5, 0.0],
        ..loads(&[35e3, 12e3, 50e3])
    };
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let sys = linearise(&rod, &ld, &sol, 9).unwrap();
    assert_eq!(sys.input.ncols(), 3 + 6 + 2);
    let response = sys.stiffness.clone().try_inverse().unwrap() * &sys.input;
    let inputs = [Input::Tension(0), Input::Tension(1)];
    let jac = point_jacobian(&rod, &ld, &sol, &inputs, &Probe::tip(&rod)).unwrap();
    let nq = sys.mass.nrows();
    for k in 0..2 {
        let col = [jac.d_position[k], jac.d_rotation[k]].concat();
        let scale = col.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(scale > 0.0);
        let err = (0..6)
            .map(|r| (response[(nq - 6 + r, 9 + k)] - col[r]).powi(2))
            .sum::<f64>()
            .sqrt();
        // Both from the same dual passes; an inverse of a 54 x 54 flexibility: round-off.
        assert!(err <= 1e-8 * scale, "tendon {k}: {err:.2e} of {scale:.2e}");
    }
}

/// Kelvin-Voigt damping B = tau K on an unstressed straight rod: D = tau K (the material
/// stiffness is all of K there), up to the quadrature of D.
#[test]
fn damping_is_tau_times_stiffness_without_prestress() {
    let mut spec = cantilever(64, 0.0);
    spec.dynamics.damping_time = 0.01;
    let rod = Rod::new(spec).unwrap();
    let ld = loads(&[]);
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let sys = linearise(&rod, &ld, &sol, 8).unwrap();
    // Compare in the modal coordinates of the lowest modes (the well-resolved ones).
    let tk = &sys.stiffness * 0.01;
    let w = frequencies(&sys.mass, &sys.stiffness);
    let a = sys.mass.clone().try_inverse().unwrap() * &sys.damping;
    let b = sys.mass.clone().try_inverse().unwrap() * &tk;
    let ea = a.complex_eigenvalues();
    let eb = b.complex_eigenvalues();
    let mut ra: Vec<f64> = ea.iter().map(|c| c.re).collect();
    let mut rb: Vec<f64> = eb.iter().map(|c| c.re).collect();
    ra.sort_by(|x, y| x.partial_cmp(y).unwrap());
    rb.sort_by(|x, y| x.partial_cmp(y).unwrap());
    for i in 0..6 {
        let rel = (ra[i] / rb[i] - 1.0).abs();
        // Simpson's rule on both D and K's own shapes: agreement to ~1e-6 (measured).
        assert!(
            rel < 1e-4,
            "mode {i}: {} vs {} ({rel:.2e}), w {}",
            ra[i],
            rb[i],
            w[i]
        );
    }
}

/// The cantilever of `cantilever_frequencies_match_closed_forms` clamped at its tip too
/// (where the unloaded rod's tip is, so the clamp carries no prestress): bending, axial and
/// torsional frequencies of the clamped-clamped beam and bar against their closed forms,
/// and the same convergence orders. The tip is no coordinate; the nodes sit between the
/// clamps (`choose_inner_nodes`).
#[test]
fn clamped_clamped_frequencies_match_closed_forms() {
    let rod = Rod::new(cantilever(64, 0.0)).unwrap();
    let ld = loads(&[]);
    let free = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let clamp = TipConstraint::Clamped {
        position: free.tip.r,
        rotation: free.tip.rot,
    };
    let sol = solve_constrained(&rod, &ld, &clamp, None, &SolverOptions::default())
        .unwrap()
        .solution;
    let rho_a = MASS / L;
    let beam = |beta_l: f64| beta_l * beta_l * (EI / (rho_a * L.powi(4))).sqrt();
    let axial = std::f64::consts::PI * (EA / (rho_a * L * L)).sqrt();
    let torsion = std::f64::consts::PI * (GJ / (ROT[2] * L * L)).sqrt();
    let mut errors = Vec::new();
    // 3, 7 and 15 inner nodes: spacings of 16, 8 and 4 steps.
    for nodes in [3, 7, 15] {
        let sys = linearise_held(&rod, &ld, &clamp, &sol, nodes).unwrap();
        assert_eq!(sys.mass.nrows(), 6 * nodes);
        assert!(sys.nodes.iter().all(|s| *s > 0.0 && *s < L));
        let w = frequencies(&sys.mass, &sys.stiffness);
        let want = [beam(4.730_040_744_862_704), beam(7.853_204_624_095_838)];
        errors.push(mode_errors(nodes, &w, want, axial, torsion));
        // A tip load goes whole into the clamp: its input columns are zero.
        assert!((0..6).all(|j| sys.input.column(j).amax() == 0.0));
    }
    // Cubic static shapes in bending (n^-4), linear in extension and torsion (n^-2), as for
    // the cantilever.
    let order = |k: usize, a: usize| (errors[a][k] / errors[a + 1][k]).log2();
    for a in 0..2 {
        assert!(
            order(0, a) > 3.5 && order(1, a) > 3.5,
            "bending order {a}: {errors:?}"
        );
        assert!(
            (order(2, a) - 2.0).abs() < 0.2 && (order(3, a) - 2.0).abs() < 0.2,
            "{errors:?}"
        );
    }
    // At 15 nodes (16 intervals of h = L / 16) the size of the errors too: the static shapes
    // are the finite elements' own (cubic Hermite in bending, linear in extension and
    // torsion, with consistent masses), whose frequencies lie above the exact ones by
    // (beta h)^4 / 1440 and (k h)^2 / 24 (k = pi / L) to leading order. Half as much again
    // for the next order; the RK4 error of K and Simpson's rule for M on 64 steps are far
    // below.
    let h = L / 16.0;
    for (k, beta_l) in [(0, 4.730_040_744_862_704), (1, 7.853_204_624_095_838)] {
        let fe = (beta_l * h / L).powi(4) / 1440.0;
        assert!(
            errors[2][k] < 1.5 * fe,
            "bending {k}: {:.2e} vs {fe:.2e}",
            errors[2][k]
        );
    }
    let fe = (std::f64::consts::PI * h / L).powi(2) / 24.0;
    assert!(
        errors[2][2] < 1.5 * fe && errors[2][3] < 1.5 * fe,
        "{errors:?} vs {fe:.2e}"
    );
}

/// K^-1 B of a clamped SPA under pressure and gravity: every node's rows are the exact
/// pressure Jacobian of the held equilibrium at that node (`jacobian::point_jacobian6`),
/// so the stiffness and the input columns carry the clamp's prestress.
#[test]
fn static_response_of_the_clamped_linear_system_is_exact() {
    let rod = Rod::new(p002_actuator(tilted(), 9.81, 12)).unwrap();
    let ld = Loads {
        pressures: vec![35e3, 12e3, 50e3],
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
        stiffness_scale: [1.0; 3],
        tensions: vec![],
        tip_frame: Frame::World,
    };
    let free = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    // Held 6 mm aside of where it would be: the clamp carries load.
    let clamp = TipConstraint::Clamped {
        position: [free.tip.r[0] + 6e-3, free.tip.r[1], free.tip.r[2]],
        rotation: free.tip.rot,
    };
    let sol = solve_constrained(&rod, &ld, &clamp, None, &SolverOptions::default())
        .unwrap()
        .solution;
    let sys = linearise_held(&rod, &ld, &clamp, &sol, 5).unwrap();
    let response = sys.stiffness.clone().try_inverse().unwrap() * &sys.input;
    let inputs = [Input::Pressure(0), Input::Pressure(1), Input::Pressure(2)];
    for (a, s) in sys.nodes.iter().enumerate() {
        let jac = point_jacobian6(
            &rod,
            &ld,
            &clamp,
            &sol,
            &inputs,
            &Probe::at(&rod, *s).unwrap(),
        )
        .unwrap()
        .point;
        for (k, _) in inputs.iter().enumerate() {
            let col = [jac.d_position[k], jac.d_rotation[k]].concat();
            let scale = col.iter().map(|v| v * v).sum::<f64>().sqrt();
            let err = (0..6)
                .map(|r| (response[(6 * a + r, k)] - col[r]).powi(2))
                .sum::<f64>()
                .sqrt();
            // The same implicit differentiation by another pass; a 30 x 30 inverse.
            assert!(
                err <= 1e-8 * scale,
                "node {a}, input {k}: {err:.2e} of {scale:.2e}"
            );
        }
    }
    let asym = (&sys.mass - sys.mass.transpose()).amax() / sys.mass.amax();
    assert!(asym < 1e-10, "{asym}");
    assert!(sys.mass.clone().cholesky().is_some());
    // A free tip is refused by name (it is `linearise`'s).
    match linearise_held(&rod, &ld, &TipConstraint::Free, &sol, 5) {
        Err(softrod_core::SoftrodError::InvalidParameter { field, .. }) => {
            assert_eq!(field, "tip_constraint")
        }
        other => panic!("{other:?}"),
    }
}

const CLAMPED_PINNED: [f64; 2] = [3.926_602_312_047_919, 7.068_582_745_628_732];

/// The cantilever of `cantilever_frequencies_match_closed_forms` pinned at its tip (where
/// the unloaded rod's tip is): the clamped-pinned beam (tan beta L = tanh beta L), the bar
/// fixed at both ends in extension (pi), and torsion free at the pin (pi / 2), with the
/// cantilever's convergence orders. The nodes are spread as for a free tip, the tip last,
/// and the tip keeps its three small rotations only.
#[test]
fn clamped_pinned_frequencies_match_closed_forms() {
    let rod = Rod::new(cantilever(64, 0.0)).unwrap();
    let ld = loads(&[]);
    let free = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let pin = TipConstraint::Pinned {
        position: free.tip.r,
    };
    let sol = solve_constrained(&rod, &ld, &pin, None, &SolverOptions::default())
        .unwrap()
        .solution;
    let rho_a = MASS / L;
    let beam = |beta_l: f64| beta_l * beta_l * (EI / (rho_a * L.powi(4))).sqrt();
    let axial = std::f64::consts::PI * (EA / (rho_a * L * L)).sqrt();
    let torsion = std::f64::consts::FRAC_PI_2 * (GJ / (ROT[2] * L * L)).sqrt();
    let mut errors = Vec::new();
    for nodes in [4, 8, 16] {
        let sys = linearise_held(&rod, &ld, &pin, &sol, nodes).unwrap();
        assert_eq!(sys.mass.nrows(), 6 * nodes - 3);
        assert!((sys.nodes[nodes - 1] - L).abs() < 1e-12);
        let w = frequencies(&sys.mass, &sys.stiffness);
        let want = CLAMPED_PINNED.map(beam);
        errors.push(mode_errors(nodes, &w, want, axial, torsion));
        // A tip force goes into the pin (zero columns); a tip moment is a unit load on the
        // tip's rotations.
        assert!((0..3).all(|j| sys.input.column(j).amax() == 0.0));
        for j in 0..3 {
            let col = sys.input.column(3 + j);
            assert_eq!(col[6 * nodes - 6 + j], 1.0);
            assert_eq!(col.amax(), 1.0);
        }
    }
    let order = |k: usize, a: usize| (errors[a][k] / errors[a + 1][k]).log2();
    for a in 0..2 {
        assert!(
            order(0, a) > 3.5 && order(1, a) > 3.5,
            "bending order {a}: {errors:?}"
        );
        assert!(
            (order(2, a) - 2.0).abs() < 0.2 && (order(3, a) - 2.0).abs() < 0.2,
            "{errors:?}"
        );
    }
    // At 16 nodes (h = L / 16) within 1.5 times the finite elements' leading terms, as for the
    // clamped tip: (beta h)^4 / 1440 in bending, (k h)^2 / 24 in extension (k = pi / L) and
    // torsion (k = pi / 2L).
    let h = L / 16.0;
    for (k, beta_l) in CLAMPED_PINNED.iter().enumerate() {
        let fe = (beta_l * h / L).powi(4) / 1440.0;
        assert!(
            errors[2][k] < 1.5 * fe,
            "bending {k}: {:.2e} vs {fe:.2e}",
            errors[2][k]
        );
    }
    let fe = |k: f64| (k * h).powi(2) / 24.0;
    let pi = std::f64::consts::PI;
    assert!(errors[2][2] < 1.5 * fe(pi / L), "{errors:?}");
    assert!(errors[2][3] < 1.5 * fe(pi / (2.0 * L)), "{errors:?}");
}

/// K^-1 B of a pinned SPA under pressure and gravity, with a heavy tip body off the axis
/// (its weight's moment arm is part of K): every node's rows are the exact pressure and
/// tip-moment Jacobian of the held equilibrium there (at the tip its rotation rows).
#[test]
fn static_response_of_the_pinned_linear_system_is_exact() {
    let mut spec = p002_actuator(tilted(), 9.81, 12);
    spec.tip.mass = 0.01;
    spec.tip.com_offset = [0.004, -0.002, 0.01];
    let rod = Rod::new(spec).unwrap();
    let ld = loads(&[35e3, 12e3, 50e3]);
    let free = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let pin = TipConstraint::Pinned {
        position: [free.tip.r[0] + 6e-3, free.tip.r[1], free.tip.r[2]],
    };
    let sol = solve_constrained(&rod, &ld, &pin, None, &SolverOptions::default())
        .unwrap()
        .solution;
    let n = 5;
    let sys = linearise_held(&rod, &ld, &pin, &sol, n).unwrap();
    let response = sys.stiffness.clone().try_inverse().unwrap() * &sys.input;
    let inputs = [
        Input::Pressure(0),
        Input::Pressure(1),
        Input::Pressure(2),
        Input::TipMoment(0),
        Input::TipMoment(1),
        Input::TipMoment(2),
    ];
    let columns = [0, 1, 2, 6, 7, 8];
    for (a, s) in sys.nodes.iter().enumerate() {
        let probe = Probe::at(&rod, *s).unwrap();
        let jac = point_jacobian6(&rod, &ld, &pin, &sol, &inputs, &probe)
            .unwrap()
            .point;
        // The tip's rows are its rotation; an inner node's are its pose.
        let (rows, first) = if a + 1 == n {
            (3..6, 6 * a)
        } else {
            (0..6, 6 * a)
        };
        for (k, &c) in columns.iter().enumerate() {
            let col = [jac.d_position[k], jac.d_rotation[k]].concat();
            let scale = col.iter().map(|v| v * v).sum::<f64>().sqrt();
            let err = rows
                .clone()
                .enumerate()
                .map(|(i, r)| (response[(first + i, c)] - col[r]).powi(2))
                .sum::<f64>()
                .sqrt();
            // The same implicit differentiation by another pass; a 27 x 27 inverse.
            assert!(
                err <= 1e-8 * scale,
                "node {a}, input {k}: {err:.2e} of {scale:.2e}"
            );
        }
    }
    let asym = (&sys.mass - sys.mass.transpose()).amax() / sys.mass.amax();
    assert!(asym < 1e-10, "{asym}");
    assert!(sys.mass.clone().cholesky().is_some());
}

/// Without gravity a tip body does not change the equilibrium, so it changes only the mass
/// matrix: on a pinned tip by its inertia about the pin, J_c + m (|c|^2 I - c c^T) by the
/// parallel-axis theorem (the straight rod's tip frame is the world's), at the tip's rows.
#[test]
fn pinned_tip_body_adds_its_inertia_about_the_pin() {
    let mass_with = |body: bool| {
        let mut spec = cantilever(32, 0.0);
        if body {
            spec.tip.mass = 0.05;
            spec.tip.com_offset = [0.01, -0.02, 0.03];
            spec.tip.inertia = [2e-5, 3e-5, 4e-5];
        }
        let rod = Rod::new(spec).unwrap();
        let ld = loads(&[]);
        let free = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
        let pin = TipConstraint::Pinned {
            position: free.tip.r,
        };
        let sol = solve_constrained(&rod, &ld, &pin, None, &SolverOptions::default())
            .unwrap()
            .solution;
        linearise_held(&rod, &ld, &pin, &sol, 4).unwrap().mass
    };
    let diff = mass_with(true) - mass_with(false);
    let (m, c, j) = (0.05, [0.01, -0.02, 0.03], [2e-5, 3e-5, 4e-5]);
    let c2: f64 = c.iter().map(|v| v * v).sum();
    let o = diff.nrows() - 3;
    for a in 0..diff.nrows() {
        for b in 0..diff.ncols() {
            let want = if a >= o && b >= o {
                let (i, k) = (a - o, b - o);
                let delta = if i == k { 1.0 } else { 0.0 };
                j[i] * delta + m * (c2 * delta - c[i] * c[k])
            } else {
                0.0
            };
            // The rest of M is the same computation twice (bitwise but for the symmetrising).
            assert!(
                (diff[(a, b)] - want).abs() < 1e-15,
                "({a}, {b}): {} vs {want}",
                diff[(a, b)]
            );
        }
    }
}
