//! The exact (dual-number) Jacobian of the shooting residual against central finite
//! differences of the plain residual, at points that are not the solution.

mod common;
use common::*;
use nalgebra::{Rotation3, Unit, Vector3};
use softrod_core::ode::Loads;
use softrod_core::spec::{DesignSpec, LineLoadSpec, TipSpec};
use softrod_core::statics::{residual, residual_and_jacobian, solve, SolverOptions};
use softrod_core::Rod;

/// Finite-difference step, relative to max(1, |x_j|) (the unknowns are scaled to be of
/// order 1). Central differences err by h^2 |r'''| / 6 (truncation, ~1e-12 here) plus
/// eps |r| / h (round-off, ~2e-16 * 10 / 1e-6 = 2e-9 for residuals up to 10): h = 1e-6
/// is close to the optimum eps^(1/3) and keeps both far below FD_TOL.
const FD_STEP: f64 = 1e-6;
/// Column-wise agreement, relative to the larger of the column's norm and 1e-3 (a column
/// of an O(1)-scaled Jacobian can be near zero only by accident). Measured: at most
/// 1.2e-9 over all points and designs below (printed with --nocapture), so 1e-7 leaves
/// an 80x margin for round-off while still catching a missing derivative term: e.g. the
/// tip body's lever R(L) c, whose derivative is ~1e-2 of a column for paper 002's marker.
const FD_TOL: f64 = 1e-7;
/// The dual-number residual and the f64 residual run the same arithmetic on the value
/// parts; allow a few ulps of the residual's size.
const SAME_RESIDUAL_TOL: f64 = 1e-13;
/// Points: the solution plus a perturbation of this size in each scaled unknown, and
/// points with each unknown drawn uniformly from [-RANDOM_BOX, RANDOM_BOX] (forces up to
/// F_s = EI/L^2, moments up to F_s L: the rod bends by up to a radian, far from
/// equilibrium).
const PERTURBATION: f64 = 0.3;
const RANDOM_BOX: f64 = 1.0;

fn check_against_fd(name: &str, rod: &Rod, ld: &Loads) {
    let sol = solve(rod, ld, None, &SolverOptions::default()).unwrap();
    let mut rng = Lcg(0x5EED_0F50_F70D);
    // (written for any number of shooting unknowns: the solver's x is a fixed-size array)
    let mut points = Vec::new();
    for k in 0..8 {
        let mut x = sol.x;
        for v in x.iter_mut() {
            *v = if k < 4 {
                *v + PERTURBATION * rng.uniform()
            } else {
                RANDOM_BOX * rng.uniform()
            };
        }
        points.push(x);
    }
    let n = sol.x.len();
    let mut worst: f64 = 0.0;
    for x in &points {
        let (r, jac) = residual_and_jacobian(rod, ld, x);
        let r_plain = residual(rod, ld, x);
        let rnorm = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(rnorm > 1e-3, "{name}: x = {x:?} should not be a solution");
        for (i, (a, b)) in r.iter().zip(&r_plain).enumerate() {
            assert!(
                (a - b).abs() <= SAME_RESIDUAL_TOL * rnorm.max(1.0),
                "{name}: residual[{i}] {a} vs {b}"
            );
        }
        for j in 0..n {
            let h = FD_STEP * x[j].abs().max(1.0);
            let (mut xp, mut xm) = (*x, *x);
            xp[j] += h;
            xm[j] -= h;
            let (rp, rm) = (residual(rod, ld, &xp), residual(rod, ld, &xm));
            let fd: Vec<f64> = rp
                .iter()
                .zip(&rm)
                .map(|(a, b)| (a - b) / (xp[j] - xm[j]))
                .collect();
            let col: Vec<f64> = jac.iter().map(|row| row[j]).collect();
            let scale = col.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-3);
            let err = col
                .iter()
                .zip(&fd)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
                / scale;
            worst = worst.max(err);
            assert!(
                err < FD_TOL,
                "{name}: x = {x:?}, column {j}: AD {col:?} vs FD {fd:?} (rel. error {err:.2e})"
            );
        }
    }
    eprintln!("{name}: worst relative column error {worst:.2e}");
}

/// A base rotation with no axis along the world axes, so no entry is structurally zero.
fn tilted() -> [[f64; 3]; 3] {
    let r = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)), 1.1);
    std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]))
}

#[test]
fn jacobian_matches_fd_for_pressurised_spa_with_tip_body() {
    // Paper 002's actuator, horizontal (gravity across the axis), three pressures and its
    // marker plate: 17.25 g with the centre of mass at (9.3, 2.9, -1.1) mm in the tip frame,
    // so the residual's moment part depends on the tip rotation.
    let mut spec: DesignSpec = p002_actuator(HORIZONTAL, 9.81, 16);
    spec.tip = TipSpec {
        mass: 17.25e-3,
        com_offset: [9.3e-3, 2.9e-3, -1.1e-3],
        ..Default::default()
    };
    let rod = Rod::new(spec).unwrap();
    check_against_fd("SPA", &rod, &loads(&[30e3, 10e3, 50e3]));
    // and tilted, with a tip force and moment on top
    let mut spec = p002_actuator(tilted(), 9.81, 16);
    spec.tip = TipSpec {
        mass: 17.25e-3,
        com_offset: [9.3e-3, 2.9e-3, -1.1e-3],
        ..Default::default()
    };
    let rod = Rod::new(spec).unwrap();
    let mut ld = loads(&[60e3, 0.0, 25e3]);
    ld.tip_force = [0.05, -0.1, 0.02];
    ld.tip_moment = [0.002, 0.001, -0.003];
    check_against_fd("SPA tilted", &rod, &ld);
}

#[test]
fn jacobian_matches_fd_with_rigid_section_and_line_loads() {
    let mut spec = design(
        vec![
            direct_section("lower", 0.1, 40.0, 25.0, 4e-3, 2e-3, 0.02, 16),
            rigid_section("connector", 0.015, 0.01),
            direct_section("upper", 0.08, 40.0, 25.0, 3e-3, 1.5e-3, 0.015, 16),
        ],
        tilted(),
        9.81,
    );
    spec.loads = vec![
        LineLoadSpec {
            section: 0,
            force_per_length: [0.3, -0.2, 0.1],
            moment_per_length: [0.01, 0.0, -0.02],
        },
        LineLoadSpec {
            section: 1,
            force_per_length: [0.0, 0.5, 0.0],
            moment_per_length: [0.0, 0.03, 0.0],
        },
        LineLoadSpec {
            section: 2,
            force_per_length: [-0.1, 0.0, 0.2],
            moment_per_length: [0.0; 3],
        },
    ];
    spec.tip = TipSpec {
        mass: 0.005,
        com_offset: [0.01, 0.0, 0.005],
        ..Default::default()
    };
    let rod = Rod::new(spec).unwrap();
    let mut ld = loads(&[]);
    ld.tip_force = [0.02, 0.0, -0.01];
    ld.tip_moment = [0.0, 0.001, 0.0];
    check_against_fd("rigid + line loads", &rod, &ld);
}
