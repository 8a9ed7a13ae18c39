//! Tapered sections (outer radius, chamber distances and radii, tendon offsets linear in
//! s): the small-deflection cone cantilever against its closed form, the exact weight of a
//! frustum, a "taper" of zero equal to the uniform section, exact Jacobians, and the
//! geometry rules checked along the section.

use crate::common;
use common::*;
use softrod_core::ode::Loads;
use softrod_core::spec::{DesignSpec, SectionSpec, TendonSpec};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};
use std::f64::consts::PI;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-13,
        ..Default::default()
    }
}

fn cone(r0: f64, r1: f64, length: f64, steps: usize) -> SectionSpec {
    let mut s = geometry_section("cone", length, r0, 0.0, DRAGON_SKIN, vec![], steps);
    s.outer_radius_end = Some(r1);
    s
}

/// Tip deflection of a solid conical cantilever (radius a at the clamp, c at the tip,
/// R(s) = a - b s) under a small transverse tip load P, by the unit-load method:
///   bending  P int_0^L (L - s)^2 / (E I(s)) ds, I = pi R^4 / 4,
///          = 4 P / (pi E b^3) [ -1/a + c/a^2 - c^2/(3 a^3) + 1/(3 c) ],
///   shear    P int_0^L ds / (G A(s)) = P / (pi G b) (1/c - 1/a)
/// (the rod's shear stiffness is G A with c_s = 1, as softrod's law).
fn cone_deflection(p: f64, a: f64, c: f64, l: f64, e: f64, g: f64) -> f64 {
    let b = (a - c) / l;
    let bend = 4.0 * p / (PI * e * b.powi(3))
        * (-1.0 / a + c / (a * a) - c * c / (3.0 * a.powi(3)) + 1.0 / (3.0 * c));
    let shear = p / (PI * g * b) * (1.0 / c - 1.0 / a);
    bend + shear
}

/// A cone of radius 10 mm tapering to 3 mm over 150 mm, deflected by 1e-5 of its length
/// (geometric nonlinearity: relative O(1e-10)). softrod's deflection converges to the
/// closed form at fourth order (I varies 120-fold along the cone, so RK4's constant is
/// large: 2e-6 at 32 steps): the error shrinks 16-fold per halving of the step (ratios in
/// [13, 19]) down to below 1e-9 at 256 steps. A section that kept its start radius would
/// be off by a factor of ~20.
#[test]
fn small_deflection_of_a_cone_matches_the_closed_form() {
    let (a, c, l) = (0.010, 0.003, 0.15);
    let (e, g) = (DRAGON_SKIN.youngs_modulus, DRAGON_SKIN.shear_modulus);
    let want_unit = cone_deflection(1.0, a, c, l, e, g);
    let p = 1e-5 * l / want_unit;
    let want = p * want_unit;
    let errs: Vec<f64> = [32, 64, 128, 256]
        .iter()
        .map(|&n| {
            let rod = Rod::new(design(vec![cone(a, c, l, n)], IDENTITY, 0.0)).unwrap();
            let mut ld = loads(&[]);
            ld.tip_force = [p, 0.0, 0.0];
            let got = solve(&rod, &ld, None, &opts()).unwrap().tip.r[0];
            (got - want).abs() / want
        })
        .collect();
    eprintln!("relative errors at 32, 64, 128, 256 steps: {errs:?}");
    for k in 0..3 {
        let ratio = errs[k] / errs[k + 1];
        assert!((13.0..19.0).contains(&ratio), "convergence ratio {ratio}");
    }
    assert!(errs[3] < 1e-9);
}

/// The weight of a tapered section is the frustum's, exactly (its area is a quadratic in s
/// and Simpson's rule integrates it exactly); the base force under gravity is that weight.
#[test]
fn tapered_weight_is_the_frustums() {
    let (a, c, l) = (0.012, 0.004, 0.2);
    let rod = Rod::new(design(vec![cone(a, c, l, 10)], IDENTITY, 9.81)).unwrap();
    let volume = PI * l * (a * a + a * c + c * c) / 3.0;
    let mass = DRAGON_SKIN.density * volume;
    assert!((rod.mass() - mass).abs() < 1e-14 * mass);
    let sol = solve(&rod, &loads(&[]), None, &opts()).unwrap();
    assert!((sol.base_force[2] + mass * 9.81).abs() < 1e-13 * mass * 9.81);
}

/// End values equal to the start values take the varying path (coefficients rebuilt at
/// every stage) and give the uniform section's solution bitwise.
#[test]
fn zero_taper_equals_the_uniform_section() {
    let mut uniform = p002_actuator(tilted(), 9.81, 12);
    uniform.sections[1].tendons = vec![];
    let mut tapered = uniform.clone();
    let body = &mut tapered.sections[1];
    body.outer_radius_end = body.outer_radius;
    for ch in &mut body.chambers {
        ch.distance_end = Some(ch.distance);
        ch.radius_end = ch.radius;
    }
    let ld = loads(&[30e3, 0.0, 12e3]);
    let a = solve(&Rod::new(uniform).unwrap(), &ld, None, &opts()).unwrap();
    let b = solve(&Rod::new(tapered).unwrap(), &ld, None, &opts()).unwrap();
    assert_eq!(a.tip.r, b.tip.r);
    assert_eq!(a.x, b.x);
}

/// A tapered pneumatic tentacle: outer radius, chamber distances and radii, and a tendon's
/// offset all shrink along the body.
fn tentacle() -> DesignSpec {
    let mut spec = p002_actuator(tilted(), 9.81, 16);
    let body = &mut spec.sections[1];
    body.outer_radius_end = Some(0.012);
    for ch in &mut body.chambers {
        ch.distance_end = Some(0.0075);
        ch.radius_end = Some(0.0028);
    }
    let t = |end: Option<f64>| TendonSpec {
        channel: 0,
        distance: 0.018,
        angle: 0.5,
        distance_end: end,
        angle_end: None,
    };
    body.tendons = vec![t(Some(0.010))];
    spec.sections[0].tendons = vec![t(None)];
    spec.sections[2].outer_radius = Some(0.012);
    spec.tip.mass = 0.01;
    spec.tip.com_offset = [0.004, -0.002, 0.006];
    spec
}

/// Exact Jacobians of the tapered tentacle (pressures, tendon, gravity) against central
/// differences; its curvature follows the shrinking cross-section (the chambers' pressure
/// moment shrinks with their distance and area, the stiffness faster, with r^4).
#[test]
fn tapered_tentacle_jacobian_matches_finite_differences() {
    let rod = Rod::new(tentacle()).unwrap();
    let ld = Loads {
        tensions: vec![0.8],
        ..loads(&[25e3, 0.0, 0.0])
    };
    check_jacobian_against_fd("tentacle", &rod, &ld, &opts(), 11);
    // pressure alone bends the thin end more than the thick one
    let ld = Loads {
        tensions: vec![0.0],
        ..loads(&[25e3, 0.0, 0.0])
    };
    let mut spec = tentacle();
    spec.mounting.gravity = [0.0; 3];
    spec.tip.mass = 0.0;
    let rod = Rod::new(spec).unwrap();
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let sh = shape(&rod, &ld, &sol);
    let body: Vec<usize> = (0..sh.s.len()).filter(|&k| sh.section[k] == 1).collect();
    let curvature = |k: usize| sh.u[k][0].hypot(sh.u[k][1]);
    assert!(curvature(body[body.len() - 1]) > 1.5 * curvature(body[0]));
}

fn field_of(r: softrod_core::Result<Rod>) -> String {
    match r {
        Err(SoftrodError::InvalidParameter { field, .. }) => field,
        other => panic!("expected a design error, got {other:?}"),
    }
}

/// The geometry rules hold along the whole section: a chamber inside at the start can
/// leave the section at the end, or cut another chamber in between.
#[test]
fn tapered_geometry_is_checked_along_the_section() {
    let mut spec = tentacle();
    spec.sections[1].outer_radius_end = Some(0.009);
    assert_eq!(
        field_of(Rod::new(spec)),
        "sections[1].chambers[0].distance_end"
    );
    // two chambers on crossing paths: apart at both ends, overlapping in the middle
    let mut spec = p002_actuator(IDENTITY, 0.0, 8);
    let body = &mut spec.sections[1];
    body.chambers = vec![chamber(0.002, 0.012, 0.0, 0), chamber(0.002, 0.005, 0.0, 1)];
    body.chambers[0].distance_end = Some(0.005);
    body.chambers[1].distance_end = Some(0.016);
    body.bore_radius = 0.0;
    assert_eq!(field_of(Rod::new(spec)), "sections[1].chambers[1].angle");
    // a taper needs the geometry: directly given stiffness cannot follow it
    let mut s = direct_section("s", 0.1, 10.0, 10.0, 0.01, 0.01, 0.01, 8);
    s.outer_radius_end = Some(0.01);
    assert_eq!(
        field_of(Rod::new(design(vec![s], IDENTITY, 0.0))),
        "sections[0].outer_radius_end"
    );
    // nor can a given mass
    let mut s = cone(0.01, 0.005, 0.1, 8);
    s.mass = Some(0.01);
    assert_eq!(
        field_of(Rod::new(design(vec![s], IDENTITY, 0.0))),
        "sections[0].mass"
    );
}
