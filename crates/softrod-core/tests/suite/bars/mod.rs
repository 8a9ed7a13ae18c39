//! The frictional bars of the friction tests (tests/suite/friction.rs, tests/suite/friction_system.rs):
//! a 1 m bar lying on a frictional bed under its weight, and a round bar on a plane.

// Each test crate uses a part of these.
#![allow(dead_code)]

use crate::common::{design, direct_section, geometry_section, loads, obstacle, HORIZONTAL};
use softrod_core::ode::Loads;
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::MaterialSpec;
use softrod_core::{DesignSpec, Rod};

pub const G: f64 = 9.81;
pub const L: f64 = 1.0;
/// Line weight q, N/m.
pub const Q: f64 = 1.0;
/// Axial stiffness EA, N.
pub const EA: f64 = 100.0;
/// Penalty stiffness k = k_t, N/m^2. Single shooting needs the stuck zone's decay length
/// sqrt(EA / k_t) = 0.1 m and the bed's Winkler length (4 EI / k)^(1/4) = 0.14 m to be
/// a good fraction of L (the shooting ODE grows like exp(L / length): docs/contact.md,
/// "Which solver").
pub const K: f64 = 1e4;
pub const STEPS: usize = 200;

/// Smoothing length of the bed's ramp, m: a tenth of the sinking q / k, so the bed is
/// linear where the bar lies on it.
pub const EPS: f64 = 1e-5;
/// Where the bar lies under its weight: its axis sinks q / k + eps / 2 into the bed.
pub const SINK: f64 = Q / K + 0.5 * EPS;

/// A 1 m bar (EA = GA = 100 N, EI = 1 N m^2, q = 1 N/m; stiffnesses given directly, so
/// its surface radius is 0), clamped horizontally with its axis at the depth where it
/// lies on a plane with friction `mu` under its weight: straight, the bed carrying q all
/// along and the clamp none of the weight (with the clamp at the bed's surface it would
/// carry a share over the Winkler length, which the closed forms leave out).
pub fn bar_on_bed(mu: f64) -> DesignSpec {
    let sec = direct_section("bar", L, EA, EA, 1.0, 1.0, Q / G, STEPS);
    let mut d = design(vec![sec], HORIZONTAL, G);
    let mut plane = obstacle(ObstacleKind::Plane, K, 1e-3);
    plane.point = Some([0.0, 0.0, SINK]);
    plane.normal = Some([0.0, 0.0, 1.0]);
    plane.smoothing = Some(EPS);
    plane.friction = mu;
    d.obstacles = vec![plane];
    d
}

pub fn pulled(f: f64) -> Loads {
    let mut l = loads(&[]);
    l.tip_force = [f, 0.0, 0.0];
    l
}

/// A round bar (surface radius 5 mm, so the friction has a moment and the contact points
/// roll with the sections) of 0.2 m, clamped horizontally on a plane with mu = 0.4.
pub fn round_bar() -> Rod {
    let material = MaterialSpec {
        youngs_modulus: 1e6,
        shear_modulus: 1e6 / 3.0,
        density: 1300.0,
    };
    let r0 = 5e-3;
    let sec = geometry_section("bar", 0.2, r0, 0.0, material, vec![], 40);
    let mut d = design(vec![sec], HORIZONTAL, G);
    let mut plane = obstacle(ObstacleKind::Plane, K, 1e-3);
    plane.point = Some([0.0, 0.0, -r0]);
    plane.normal = Some([0.0, 0.0, 1.0]);
    plane.friction = 0.4;
    d.obstacles = vec![plane];
    Rod::new(d).unwrap()
}

/// Step of the central differences of [`worst_central_difference_error`].
pub const FD_H: f64 = 1e-7;

/// The largest error of the Jacobian `jac` (rows of `n` columns) against central
/// differences, each entry relative to its row's largest (at least 1): column k is
/// (residual(k, FD_H) - residual(k, -FD_H)) / (2 FD_H), with `residual(k, s)` the residual
/// at the unknowns stepped by s along k as the solver steps them. The differences err by
/// h^2 |r'''| / 6 plus round-off ~1e-16 |r| / h, both below 1e-6 of a row's scale at
/// h = 1e-7: the bound the friction tests assert.
pub fn worst_central_difference_error(
    jac: &[Vec<f64>],
    n: usize,
    residual: impl Fn(usize, f64) -> Vec<f64>,
) -> f64 {
    let mut worst: f64 = 0.0;
    for k in 0..n {
        let (ra, rb) = (residual(k, FD_H), residual(k, -FD_H));
        for (i, row) in jac.iter().enumerate() {
            let fd = (ra[i] - rb[i]) / (2.0 * FD_H);
            let scale = row.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            worst = worst.max((fd - row[k]).abs() / scale);
        }
    }
    worst
}
