//! The integrator's order of accuracy as a fitted slope, and rigid sections.

use crate::common;
use common::*;
use softrod_core::spec::{DesignSpec, TipSpec};
use softrod_core::statics::{shape, solve, Solution, SolverOptions};
use softrod_core::Rod;

/// Classical RK4 is fourth order: the fitted log-log slope of the error against the step
/// must lie in [4 - ORDER_SLACK, 4 + ORDER_SLACK]. Measured: 3.96 (cantilever: error ratios
/// per halving 24.7, 13.6, 13.5, 14.7, then 15.3 and 15.6 beyond 128 steps, tending to 16;
/// the error's z component changes sign between 16 and 32 steps) and 3.98 (SPA); 0.3 allows
/// such pre-asymptotic behaviour.
const ORDER_SLACK: f64 = 0.3;
const STEP_COUNTS: [usize; 5] = [8, 16, 32, 64, 128];
/// The reference: its own error is (128 / 1024)^4 = 2.4e-4 of the finest error above.
const REF_STEPS: usize = 1024;
/// Newton tolerance far below the smallest discretisation error (about 1e-10 L at 128
/// steps), so that the fit sees only the integrator.
const SOLVER_TOL: f64 = 1e-13;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: SOLVER_TOL,
        ..Default::default()
    }
}

/// Least-squares slope of log(err) against log(h) (h = 1 / steps).
fn fitted_order(errors: &[(usize, f64)]) -> f64 {
    let pts: Vec<(f64, f64)> = errors
        .iter()
        .map(|&(n, e)| ((1.0 / n as f64).ln(), e.ln()))
        .collect();
    let k = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / k,
        pts.iter().map(|p| p.1).sum::<f64>() / k,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

/// Tip errors (relative to L) against the REF_STEPS solution, for `make(steps)`.
fn tip_errors(
    make: impl Fn(usize) -> DesignSpec,
    p: &[f64],
    tip_force: [f64; 3],
) -> Vec<(usize, f64)> {
    let tip = |steps: usize| -> ([f64; 3], f64) {
        let rod = Rod::new(make(steps)).unwrap();
        let mut ld = loads(p);
        ld.tip_force = tip_force;
        (solve(&rod, &ld, None, &opts()).unwrap().tip.r, rod.length)
    };
    let (reference, l) = tip(REF_STEPS);
    STEP_COUNTS
        .iter()
        .map(|&n| (n, dist(&tip(n).0, &reference) / l))
        .collect()
}

fn assert_fourth_order(name: &str, errors: &[(usize, f64)]) {
    let slope = fitted_order(errors);
    assert!(
        (slope - 4.0).abs() <= ORDER_SLACK,
        "{name}: fitted order {slope:.3}, errors {errors:?}"
    );
    // and the error really falls monotonically
    for w in errors.windows(2) {
        assert!(
            w[1].1 < w[0].1,
            "{name}: error grew from {} to {} steps: {errors:?}",
            w[0].0,
            w[1].0
        );
    }
}

#[test]
fn rk4_is_fourth_order_on_a_large_deflection_cantilever() {
    // alpha = P L^2 / EI = 5: tip angle 1.2 rad, base curvature 5 / L.
    let (l, ei) = (0.2, 0.01);
    let make = |n| {
        design(
            vec![direct_section("beam", l, 1e3, 1e3, ei, ei, 0.0, n)],
            HORIZONTAL,
            0.0,
        )
    };
    let errors = tip_errors(make, &[], [0.0, 0.0, -5.0 * ei / (l * l)]);
    assert_fourth_order("cantilever alpha = 5", &errors);
}

#[test]
fn rk4_is_fourth_order_on_a_chambered_actuator_under_gravity() {
    // Paper 002's actuator mounted horizontally: gravity across the axis, two chambers
    // pressurised so the bend is spatial.
    let errors = tip_errors(
        |n| p002_actuator(HORIZONTAL, 9.81, n),
        &[50e3, 0.0, 20e3],
        [0.0; 3],
    );
    assert_fourth_order("SPA under gravity", &errors);
}

// ---- rigid sections ----

/// Round-off in carrying a pose through a rigid section (a few flops on numbers of order 1).
const RIGID_ROUNDOFF: f64 = 1e-15;
/// Two designs with the same elastic rod and equivalent tip loads, both converged to
/// SOLVER_TOL: their base wrench and shapes agree to the solver tolerance (the scaled
/// unknowns differ by ~SOLVER_TOL, which moves the tip by ~SOLVER_TOL L). Measured: tips
/// 1.2e-16 L apart, base moments identical, base forces 1e-15 of the weight.
const EQUIVALENT_TOL: f64 = 1e-11;

const L_E: f64 = 0.12;
const EI_E: f64 = 4e-3;
const M_E: f64 = 0.02;
const L_R: f64 = 0.03;
const M_R: f64 = 0.015;
const G: f64 = 9.81;

fn elastic() -> softrod_core::spec::SectionSpec {
    direct_section("elastic", L_E, 50.0, 30.0, EI_E, 3e-3, M_E, 32)
}

fn solved(spec: DesignSpec) -> (Rod, Solution) {
    let rod = Rod::new(spec).unwrap();
    let sol = solve(&rod, &loads(&[]), None, &opts()).unwrap();
    (rod, sol)
}

#[test]
fn rigid_tip_section_equals_tip_mass_at_its_centre() {
    // A: elastic rod + rigid section of mass M_R; B: the same elastic rod with a tip body
    // of mass M_R whose centre of mass sits L_R / 2 along d3.
    let (rod_a, a) = solved(design(
        vec![elastic(), rigid_section("plate", L_R, M_R)],
        HORIZONTAL,
        G,
    ));
    let mut spec_b = design(vec![elastic()], HORIZONTAL, G);
    spec_b.tip = TipSpec {
        mass: M_R,
        com_offset: [0.0, 0.0, L_R / 2.0],
        ..Default::default()
    };
    let (_, b) = solved(spec_b);
    let weight = (M_E + M_R) * G;
    // Base force = total weight, in both.
    for sol in [&a, &b] {
        assert!(
            dist(&sol.base_force, &[0.0, 0.0, -weight]) < EQUIVALENT_TOL * weight,
            "{:?}",
            sol.base_force
        );
    }
    // Same base moment (the rigid section's weight acts at its centre).
    let m_scale = weight * L_E;
    assert!(norm(&a.base_moment) > 0.3 * m_scale);
    assert!(
        dist(&a.base_moment, &b.base_moment) < EQUIVALENT_TOL * m_scale,
        "{:?} vs {:?}",
        a.base_moment,
        b.base_moment
    );
    // A's tip is B's tip carried L_R along B's tip tangent, with the same rotation.
    let t = column(&b.tip.rot, 2);
    let carried = [0, 1, 2].map(|k| b.tip.r[k] + L_R * t[k]);
    assert!(
        dist(&a.tip.r, &carried) < EQUIVALENT_TOL * L_E,
        "{:?} vs {carried:?}",
        a.tip.r
    );
    for k in 0..3 {
        assert!(dist(&a.tip.rot[k], &b.tip.rot[k]) < EQUIVALENT_TOL);
    }
    // and A's junction node is B's tip
    let sh = shape(&rod_a, &loads(&[]), &a);
    let j = sh.section.iter().rposition(|&s| s == 0).unwrap();
    assert!(dist(&sh.position[j], &b.tip.r) < EQUIVALENT_TOL * L_E);
}

#[test]
fn rigid_sections_carry_the_pose_straight() {
    // mount / elastic / connector / elastic / plate, horizontal under gravity
    let spec = design(
        vec![
            rigid_section("mount", 0.02, 0.05),
            direct_section("lower", 0.08, 50.0, 30.0, 5e-3, 3e-3, 0.015, 16),
            rigid_section("connector", 0.01, 0.008),
            direct_section("upper", 0.08, 50.0, 30.0, 5e-3, 3e-3, 0.015, 16),
            rigid_section("plate", 0.005, 0.004),
        ],
        HORIZONTAL,
        G,
    );
    let (rod, sol) = solved(spec.clone());
    let sh = shape(&rod, &loads(&[]), &sol);
    let mut bent = false;
    for i in 1..sh.s.len() {
        let sec = sh.section[i];
        if !rod.sections[sec].rigid {
            bent |= norm(&sh.u[i]) > 0.1;
            continue;
        }
        // one node per rigid section, at its end; the node before is its start
        assert!(
            i == 1 || sh.section[i - 1] == sec - 1,
            "a rigid section has exactly one step"
        );
        let len = rod.sections[sec].length;
        let t = column(&sh.rotation[i - 1], 2);
        let want = [0, 1, 2].map(|k| sh.position[i - 1][k] + len * t[k]);
        assert!(
            dist(&sh.position[i], &want) < RIGID_ROUNDOFF,
            "{}: not carried straight",
            rod.sections[sec].name
        );
        assert_eq!(
            sh.rotation[i],
            sh.rotation[i - 1],
            "{}: rotation changed",
            rod.sections[sec].name
        );
        assert_eq!(sh.u[i], [0.0; 3]);
        assert_eq!(sh.v[i], [0.0, 0.0, 1.0]);
    }
    assert!(bent, "the elastic sections should bend under gravity");
    // The base carries the whole weight.
    let weight = rod.mass() * G;
    assert!((rod.mass() - (0.05 + 0.015 + 0.008 + 0.015 + 0.004)).abs() < 1e-15);
    assert!(dist(&sol.base_force, &[0.0, 0.0, -weight]) < EQUIVALENT_TOL * weight);
    // The mount is at the base: the first elastic node is 2 cm straight out along +x.
    let first = sh.section.iter().position(|&s| s == 1).unwrap() - 1;
    assert!(dist(&sh.position[first], &[0.02, 0.0, 0.0]) < RIGID_ROUNDOFF);
    assert_eq!(sh.rotation[first], HORIZONTAL);
}
