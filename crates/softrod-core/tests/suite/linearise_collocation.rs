//! The linearisation of equilibria that statics solved by collocation (long, soft rods:
//! `crate::linearise::collocation`): a heavy hanging beam's bending frequencies against an
//! independent solver of the Euler-Bernoulli equation with the weight's tension, and K^-1 B
//! against the point Jacobian of the same equilibrium.

use crate::common;
use common::*;
use softrod_core::jacobian::{point_jacobian, Input, Probe};
use softrod_core::linearise::linearise;
use softrod_core::statics::{solve, Solution, SolverOptions};
use softrod_core::Rod;

const HANGING: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
const L: f64 = 1.0;
/// Line mass (kg/m) and bending stiffness (N m^2): single shooting's growth exponent
/// int_0^L sqrt(w (L - s) / EI) ds = (2/3) sqrt(w L^3 / EI) is 14.8 (> 12), so statics
/// solves it by collocation.
const RHO_A: f64 = 0.1;
const EI: f64 = 2e-3;
const G: f64 = 9.81;

/// The beam: EA = GA = 1e8 N (its stretch under its weight, 1e-8, shifts no frequency
/// measurably), a rotary inertia of 1e-9 kg m (Rayleigh's correction, rho I w^2 against
/// rho A, is below 1e-7 for these modes), hanging from a clamp.
fn beam(steps: usize) -> Rod {
    let mut sec = direct_section("beam", L, 1e8, 1e8, EI, EI, RHO_A * L, steps);
    sec.rotary_inertia = Some([1e-9, 1e-9, 2e-9]);
    Rod::new(design(vec![sec], HANGING, G)).unwrap()
}

fn solved(rod: &Rod) -> Solution {
    let opts = SolverOptions {
        tol: 1e-12,
        ..Default::default()
    };
    let sol = solve(rod, &loads(&[]), None, &opts).unwrap();
    assert!(sol.collocation.is_some(), "routed to collocation");
    sol
}

/// The determinant of the free-end conditions of EI w'''' - (T w')' = rho A w^2 w with
/// T(s) = rho A g (L - s), clamped at s = 0: (w, w', w'', Q = EI w''' - T w') integrated by
/// RK4 (4000 steps) from the two base states (w'', Q) = (1, 0), (0, 1); zero at a natural
/// frequency. (Shooting this linear equation loses about e^14.8 ~ 3e6 of the 16 digits,
/// which leaves 1e-10 of a frequency.)
fn hanging_determinant(om: f64) -> f64 {
    let w = RHO_A * G;
    let f = |s: f64, z: [f64; 4]| -> [f64; 4] {
        let t = w * (L - s);
        [z[1], z[2], (z[3] + t * z[1]) / EI, RHO_A * om * om * z[0]]
    };
    let n = 4000;
    let h = L / n as f64;
    let run = |mut z: [f64; 4]| {
        for k in 0..n {
            let s = k as f64 * h;
            let k1 = f(s, z);
            let k2 = f(s + 0.5 * h, std::array::from_fn(|j| z[j] + 0.5 * h * k1[j]));
            let k3 = f(s + 0.5 * h, std::array::from_fn(|j| z[j] + 0.5 * h * k2[j]));
            let k4 = f(s + h, std::array::from_fn(|j| z[j] + h * k3[j]));
            for j in 0..4 {
                z[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        z
    };
    let a = run([0.0, 0.0, 1.0, 0.0]);
    let b = run([0.0, 0.0, 0.0, 1.0]);
    a[2] * b[3] - a[3] * b[2]
}

/// The lowest `count` natural frequencies (rad/s) of the hanging beam: a scan for sign
/// changes of the determinant, then bisection.
fn hanging_frequencies(count: usize) -> Vec<f64> {
    let mut out = Vec::new();
    let (mut lo, mut d_lo) = (0.1, hanging_determinant(0.1));
    while out.len() < count {
        let hi = lo + 0.05;
        let d_hi = hanging_determinant(hi);
        if d_lo.signum() != d_hi.signum() {
            let (mut a, mut b, mut da) = (lo, hi, d_lo);
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                let dm = hanging_determinant(m);
                if dm.signum() == da.signum() {
                    (a, da) = (m, dm);
                } else {
                    b = m;
                }
            }
            out.push(0.5 * (a + b));
        }
        (lo, d_lo) = (hi, d_hi);
    }
    out
}

/// Before, refused (`solution`: solved by collocation). The lowest three bending
/// frequencies, each a degenerate pair (the two planes), against the independent solver:
/// the Ritz construction with the rod's static deflection shapes converges as n^-4 in the
/// nodes (measured, printed: 2.2e-3, 1.5e-4, 9.9e-6 at 8, 16, 32 nodes, falling by 14x and
/// 15x; fourth order is 16x, so each halving must gain at least 12x), and the collocation
/// grid's own error (64 intervals, O(h^4) ~ 1e-7) is far below. At 32 nodes within 2e-5.
#[test]
fn hanging_beam_frequencies_from_a_collocation_solution() {
    let rod = beam(64);
    let sol = solved(&rod);
    let want = hanging_frequencies(3);
    println!("hanging beam: Euler-Bernoulli {want:?} rad/s");
    let mut errors = Vec::new();
    for nodes in [8, 16, 32] {
        let sys = linearise(&rod, &loads(&[]), &sol, nodes).unwrap();
        let got = frequencies(&sys.mass, &sys.stiffness);
        let worst = (0..3)
            .flat_map(|k| [got[2 * k], got[2 * k + 1]].map(|g| (g - want[k]).abs() / want[k]))
            .fold(0.0_f64, f64::max);
        println!(
            "{nodes} nodes: {:?}: worst relative error {worst:.2e}",
            &got[..6]
        );
        errors.push(worst);
    }
    assert!(errors[2] < 2e-5, "32 nodes: {:.2e}", errors[2]);
    assert!(
        errors[1] < errors[0] / 12.0 && errors[2] < errors[1] / 12.0,
        "convergence {errors:?}"
    );
}

/// K^-1 B against the point Jacobian of the same collocation equilibrium (the tip load
/// columns; both from the collocation equations, so to the round-off of inverting the
/// flexibility), on the hanging beam pushed sideways by a tip force.
#[test]
fn collocation_linearisation_matches_the_point_jacobian() {
    let rod = beam(48);
    let ld = softrod_core::ode::Loads {
        tip_force: [0.05, -0.02, 0.0],
        tip_moment: [0.0, 0.01, 0.0],
        ..loads(&[])
    };
    let opts = SolverOptions {
        tol: 1e-12,
        ..Default::default()
    };
    let sol = solve(&rod, &ld, None, &opts).unwrap();
    assert!(sol.collocation.is_some(), "routed to collocation");
    let sys = linearise(&rod, &ld, &sol, 12).unwrap();
    let inputs: Vec<Input> = (0..3)
        .map(Input::TipForce)
        .chain((0..3).map(Input::TipMoment))
        .collect();
    let jac = point_jacobian(&rod, &ld, &sol, &inputs, &Probe::tip(&rod)).unwrap();
    assert_tip_response("collocation beam", &sys, &jac);
}
