//! Tendons (Rucker and Webster 2011, frictionless, tension the same all along): the
//! constant-curvature arc of a straight tendon, termination inside the rod, exact
//! Jacobians, load tangents and parameter sensitivities against finite differences, batch
//! rows against single solves, and the input rules (slack, counts).

use crate::common;
use common::*;
use softrod_core::batch::{sensitivity_batch, solve_batch, BatchInputs};
use softrod_core::ode::Loads;
use softrod_core::sensitivity::{tip_sensitivity, Param, ParamKind};
use softrod_core::spec::{DesignSpec, SectionSpec, TendonSpec};
use softrod_core::statics::{
    load_tangent, residual, residual_passes, shape, solve, solve_with_shape, SolverOptions,
};
use softrod_core::{Rod, SoftrodError};

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

fn tendon(channel: usize, distance: f64, angle_deg: f64) -> TendonSpec {
    TendonSpec {
        channel,
        distance,
        angle: angle_deg.to_radians(),
        distance_end: None,
        angle_end: None,
    }
}

fn with_tendons(mut sec: SectionSpec, tendons: Vec<TendonSpec>) -> SectionSpec {
    sec.tendons = tendons;
    sec
}

fn tensioned(p: &[f64], t: &[f64]) -> Loads {
    Loads {
        tensions: t.to_vec(),
        ..loads(p)
    }
}

/// A straight tendon at offset d pulling with T bends a free rod into an arc of constant
/// curvature T d / EI (about the axis normal to the offset) and shortens it by T / EA:
/// without external loads n = m = 0 along the rod, the tendon's tangent is d3 exactly, and
/// the law gives u = K_bt^-1 (T r x e3) and v3 = 1 - T / EA. Checked at every node to 1e-10
/// relative, for offsets along d1 and d2 and on a rod with unequal EI.
#[test]
fn straight_tendon_gives_the_constant_curvature_arc() {
    let (l, ea, ga, gj) = (0.2, 500.0, 300.0, 0.01);
    let (d, t) = (0.012, 1.7);
    for (angle, ei1, ei2) in [(0.0, 0.02, 0.02), (90.0, 0.02, 0.02), (0.0, 0.015, 0.03)] {
        let mut sec = direct_section("rod", l, ea, ga, ei1, gj, 0.0, 20);
        sec.stiffness.ei2 = Some(ei2);
        let rod = Rod::new(design(
            vec![with_tendons(sec, vec![tendon(0, d, angle)])],
            IDENTITY,
            0.0,
        ))
        .unwrap();
        let ld = tensioned(&[], &[t]);
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        assert_eq!(sol.stable, Some(true));
        let sh = shape(&rod, &ld, &sol);
        // r x e3 = (y, -x, 0): the tendon moment on the material is -T r x e3.
        let (x, y) = (d * angle.to_radians().cos(), d * angle.to_radians().sin());
        let want_u = [-t * y / ei1, t * x / ei2, 0.0];
        let kappa = t * d / if angle == 0.0 { ei2 } else { ei1 };
        assert!((norm(&want_u) - kappa).abs() < 1e-15 * kappa);
        for k in 0..sh.s.len() {
            for i in 0..3 {
                assert!(
                    (sh.u[k][i] - want_u[i]).abs() <= 1e-10 * kappa,
                    "u {:?} vs {want_u:?}",
                    sh.u[k]
                );
            }
            assert!((sh.v[k][2] - (1.0 - t / ea)).abs() < 1e-14);
            assert!(sh.v[k][0].abs() < 1e-15 && sh.v[k][1].abs() < 1e-15);
        }
        // The base takes no load: tendon and rod are one free body.
        assert!(norm(&sol.base_force) < 1e-15 && norm(&sol.base_moment) < 1e-12 * t * d);
    }
}

/// A tendon attached at the end of the first of two sections bends only that section; the
/// second stays straight (n and m are continuous at the termination and vanish), and the
/// tendon's point load there is what removes its tension from the cut.
#[test]
fn tendon_terminated_inside_the_rod_bends_only_its_sections() {
    let (t, d, ei) = (0.8, 0.01, 0.02);
    let a = with_tendons(
        direct_section("a", 0.1, 500.0, 300.0, ei, 0.01, 0.0, 16),
        vec![tendon(0, d, 0.0)],
    );
    let b = direct_section("b", 0.1, 500.0, 300.0, ei, 0.01, 0.0, 16);
    let rod = Rod::new(design(vec![a, b], IDENTITY, 0.0)).unwrap();
    let ld = tensioned(&[], &[t]);
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let sh = shape(&rod, &ld, &sol);
    for k in 0..sh.s.len() {
        let want = if sh.s[k] < 0.1 - 1e-12 {
            t * d / ei
        } else {
            0.0
        };
        // (the node at the junction belongs to the first section)
        let want = if sh.section[k] == 0 { t * d / ei } else { want };
        assert!(
            (sh.u[k][1] - want).abs() < 1e-10 * t * d / ei,
            "s = {}",
            sh.s[k]
        );
    }
}

/// A soft arm: paper 002's actuator (Ecoflex body, three chambers) with tendons, on a
/// tilted mounting under gravity with a tip body; `helical` routes one tendon along a
/// helix (angle turning by 300 degrees and distance shrinking along the body).
fn tendon_arm(helical: bool, stretch_bending: bool) -> DesignSpec {
    let mut spec = two_tendons(p002_actuator(tilted(), 9.81, 12), helical, stretch_bending);
    spec.tip.mass = 0.01;
    spec.tip.com_offset = [0.004, -0.002, 0.006];
    spec
}

/// Exact Jacobians of the shooting residual with tendons (straight and helical routing,
/// tendons ending in different sections, chambers under pressure, stretch-dependent
/// bending) against central differences.
#[test]
fn jacobian_matches_finite_differences_with_tendons() {
    for (name, helical, sb) in [
        ("straight", false, false),
        ("helical", true, false),
        ("helical, stretch bending", true, true),
    ] {
        let rod = Rod::new(tendon_arm(helical, sb)).unwrap();
        let ld = tensioned(&[20e3, 0.0, 10e3], &[1.5, 0.6]);
        check_jacobian_against_fd(name, &rod, &ld, &opts(), 5);
    }
}

/// The tendon law starts each evaluation from the last one's strains and Newton matrix
/// (and, with straight routes, from the last tendon load, saving the first tangents):
/// integrating a section in one warm chain (`integrate_with`) and re-stepping each step
/// alone from the same node (`advance`: its first stage solved cold) give the same nodes to
/// round-off. Every law solve stops within about 1e-13 of a strain of its root, and a step
/// of length h moves r, R, n, m by h times those strains (times n for m), so 1e-12 of each
/// quantity's scale bounds what two correct solves can differ by; a stale start accepted
/// as converged would show as a difference at the size of a stage's strain change (1e-5).
#[test]
fn warm_started_tendon_law_matches_cold_solves() {
    use softrod_core::ode::{advance, integrate_with, Coeffs, NodeAt, State};
    for helical in [false, true] {
        let rod = Rod::new(tendon_arm(helical, false)).unwrap();
        let ld = tensioned(&[20e3, 0.0, 10e3], &[1.5, 0.6]);
        let coeffs: Vec<Coeffs<f64>> = (0..rod.sections.len())
            .map(|i| {
                Coeffs::build(
                    &rod,
                    i,
                    &ld.pressures,
                    &ld.tensions,
                    &rod.gravity,
                    1.0,
                    &[1.0; 3],
                )
            })
            .collect();
        // A base state with force and moment of the size the arm carries.
        let y0 = State {
            r: [0.0; 3],
            rot: rod.base_rotation,
            n: [0.3, -0.2, 0.8],
            m: [0.01, -0.02, 0.004],
            aux: [0.0; 2],
        };
        let mut nodes: Vec<(NodeAt, State<f64>)> = Vec::new();
        integrate_with(&rod, &coeffs, y0, &mut |node, y| {
            nodes.push((node, *y));
            false
        });
        let mut checked = 0;
        for pair in nodes.windows(2) {
            let ((a, ya), (b, yb)) = (&pair[0], &pair[1]);
            if a.section != b.section || b.step != a.step + 1 {
                continue;
            }
            let y = advance(&rod, &coeffs, *a, ya, b.s - a.s);
            let scale = |x: &[f64]| x.iter().fold(1e-3_f64, |m, v| m.max(v.abs()));
            let worst = |p: &[f64], q: &[f64]| {
                p.iter()
                    .zip(q)
                    .fold(0.0_f64, |m, (u, v)| m.max((u - v).abs()))
                    / scale(q)
            };
            let rot = |s: &State<f64>| s.rot.concat();
            let err = worst(&y.r, &yb.r)
                .max(worst(&rot(&y), &rot(yb)))
                .max(worst(&y.n, &yb.n))
                .max(worst(&y.m, &yb.m));
            assert!(
                err <= 1e-12,
                "helical {helical}: node {b:?} differs by {err:e} of its scale"
            );
            checked += 1;
        }
        assert!(checked >= 20, "only {checked} steps compared");
    }
}

/// The shooting solver's passes start the tendon law at every stage from the last pass's
/// solution there when that is closer than the last stage's (`residual_passes`: one
/// problem's f64 passes in order). Along iterates closing in on the solution, as Newton's
/// do, every pass's residual equals a fresh pass's (no memory) at the same unknowns: each
/// stage's law stops within about 1e-13 of a strain (u times the fibre radius) of its root,
/// and an error d in a strain bends the rod's remaining length L by about L d / rho,
/// moving the moment arms of the loads in the scaled residual (moments over F_s L) by
/// about (L / rho) d, 10 d here; with some 100 stages' errors adding up that is 1e-10. A
/// stale start accepted as converged would show at the size of the change from one pass
/// to the next (1e-4 for the 1e-2 step). Passing the same unknowns again (the solver's
/// final pass at its last iterate) the start at each stage is its root to the law's
/// tolerance, so most evaluations take one Newton step (the rest a second, where the
/// start's error from the last pass's tolerance is about the tolerance itself): at most
/// 1.75 steps per evaluation on average, where a fresh pass from the last stage's strains
/// takes over 2 (its first step is as large as the change from one stage to the next,
/// and a second cannot show convergence below 1e-13), so the count fails without the memory.
/// The solver's final pass checks every node with the law started from that pass's own
/// solution there: its strains equal `shape`'s cold solves at the same solution to 1e-11
/// (v, and u times the fibre radius: the law's 1e-13 at each node plus the two passes'
/// states differing by the stages' law errors carried along, the 1e-10 above); a stale
/// start accepted would be off by a stage's strain change, 1e-4.
#[test]
fn tendon_law_memory_across_passes_matches_fresh_passes() {
    for helical in [false, true] {
        let rod = Rod::new(tendon_arm(helical, false)).unwrap();
        let ld = tensioned(&[20e3, 0.0, 10e3], &[1.5, 0.6]);
        let (sol, seeded) = solve_with_shape(&rod, &ld, None, &opts()).unwrap();
        let cold = shape(&rod, &ld, &sol);
        assert_eq!(seeded.v.len(), cold.v.len());
        for k in 0..cold.v.len() {
            let rho = rod.sections[cold.section[k]].fibre_radius;
            for a in 0..3 {
                let dv = (seeded.v[k][a] - cold.v[k][a]).abs();
                let du = rho * (seeded.u[k][a] - cold.u[k][a]).abs();
                assert!(
                    dv.max(du) <= 1e-11,
                    "helical {helical}: node {k} strains differ by {dv:e}, {du:e}"
                );
            }
        }
        let xs: Vec<Vec<f64>> = [1e-2, -3e-4, 1e-7, 0.0, 0.0]
            .iter()
            .map(|e| {
                sol.x
                    .iter()
                    .enumerate()
                    .map(|(i, v)| v + e * (1.0 + 0.5 * i as f64))
                    .collect()
            })
            .collect();
        let passes = residual_passes(&rod, &ld, &xs).unwrap();
        for (k, (x, (r, _, _))) in xs.iter().zip(&passes).enumerate() {
            let fresh = residual(&rod, &ld, x).unwrap();
            let diff = r
                .iter()
                .zip(&fresh)
                .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                diff <= 1e-10,
                "helical {helical}: pass {k} differs from a fresh pass by {diff:e}"
            );
        }
        let (_, evals, again) = passes[4];
        assert!(
            evals >= 20,
            "helical {helical}: only {evals} law evaluations"
        );
        let fresh = residual_passes(&rod, &ld, &xs[4..5]).unwrap()[0].2;
        eprintln!(
            "helical {helical}: {evals} evaluations; Newton steps per pass {:?}, fresh {fresh}",
            passes.iter().map(|p| p.2).collect::<Vec<_>>()
        );
        assert!(
            4 * again <= 7 * evals && fresh > 2 * evals,
            "helical {helical}: {again} Newton steps again, {fresh} fresh, {evals} evaluations"
        );
    }
}

/// The continuation tangent dx/dlambda with tendon tensions ramped with the other loads,
/// against central differences of solutions at lambda -/+ eps.
#[test]
fn load_tangent_with_tendons_matches_finite_differences() {
    let spec = tendon_arm(true, false);
    let base = |g: f64| {
        let mut s = spec.clone();
        s.mounting.gravity = [0.0, 0.0, -g];
        s.tip.mass = 0.0;
        Rod::new(s).unwrap()
    };
    let rod = base(9.81);
    let ld = tensioned(&[15e3, 5e3, 0.0], &[1.2, 0.4]);
    let tight = SolverOptions {
        tol: 1e-14,
        ..Default::default()
    };
    let scaled = |lam: f64| -> Vec<f64> {
        let rod = base(9.81 * lam);
        let mut l = ld.clone();
        l.pressures = ld.pressures.iter().map(|p| p * lam).collect();
        l.tensions = ld.tensions.iter().map(|t| t * lam).collect();
        solve(&rod, &l, None, &tight).unwrap().x
    };
    let lam = 0.7;
    let x = scaled(lam);
    let (t, _, stable) = load_tangent(&rod, &ld, lam, &x).unwrap().unwrap();
    assert_eq!(stable, Some(true));
    let eps = 1e-5;
    let (xp, xm) = (scaled(lam + eps), scaled(lam - eps));
    for i in 0..3 {
        let fd = (xp[i] - xm[i]) / (2.0 * eps);
        // central differences: truncation ~eps^2 |x'''| ~1e-10, round-off ~1e-14 / eps
        assert!(
            (t[i] - fd).abs() < 1e-7 * (1.0 + fd.abs()),
            "component {i}: exact {} vs finite differences {fd}",
            t[i]
        );
    }
}

/// Parameter derivatives of the tip pose with tendons against central differences.
#[test]
fn sensitivities_with_tendons_match_finite_differences() {
    let spec = tendon_arm(true, false);
    let rod = Rod::new(spec.clone()).unwrap();
    let ld = tensioned(&[10e3, 25e3, 0.0], &[1.0, 0.5]);
    let params = [
        Param {
            kind: ParamKind::CorrectionFactor(2),
            sections: vec![1],
        },
        Param {
            kind: ParamKind::YoungsModulus,
            sections: vec![1],
        },
        Param {
            kind: ParamKind::AreaScale,
            sections: vec![1],
        },
    ];
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let exact = tip_sensitivity(&rod, &ld, &sol, &params).unwrap();
    let tip_with = |f: &dyn Fn(&mut DesignSpec, &mut Loads)| {
        let mut s = spec.clone();
        let mut l = ld.clone();
        f(&mut s, &mut l);
        solve(&Rod::new(s).unwrap(), &l, Some(&sol.x), &opts())
            .unwrap()
            .tip
            .r
    };
    let h_cb = 1e-6;
    let h_e = 1e-6 * ECOFLEX.youngs_modulus;
    // (parameter index, finite-difference step, how the step changes the design)
    type Perturb = Box<dyn Fn(&mut DesignSpec, &mut Loads, f64)>;
    let cases: [(usize, f64, Perturb); 2] = [
        (0, h_cb, Box::new(|s, _, h| s.sections[1].c_b += h)),
        (
            1,
            h_e,
            Box::new(|s, _, h| {
                let m = s.sections[1].material.as_mut().unwrap();
                let nu = m.youngs_modulus / (2.0 * m.shear_modulus) - 1.0;
                m.youngs_modulus += h;
                m.shear_modulus = m.youngs_modulus / (2.0 * (1.0 + nu));
            }),
        ),
    ];
    for (j, h, apply) in cases.iter() {
        let rp = tip_with(&|s, l| apply(s, l, *h));
        let rm = tip_with(&|s, l| apply(s, l, -*h));
        let fd: [f64; 3] = std::array::from_fn(|i| (rp[i] - rm[i]) / (2.0 * h));
        let ex = exact.position[*j];
        let err = dist(&ex, &fd) / norm(&fd).max(1e-12);
        assert!(
            err < 1e-6,
            "param {j}: exact {ex:?} vs FD {fd:?} ({err:.2e})"
        );
    }
}

/// Batch rows with per-row tensions equal single solves bitwise; batch sensitivities too.
#[test]
fn batch_with_tensions_equals_single_solves() {
    let rod = Rod::new(tendon_arm(true, false)).unwrap();
    let mut p = vec![];
    let mut t = vec![];
    for k in 0..6 {
        p.extend([5e3 * k as f64, 0.0, 2e3]);
        t.extend([0.4 * k as f64, 1.0 - 0.1 * k as f64]);
    }
    let inputs = BatchInputs {
        pressures: &p,
        tensions: Some(&t),
        stiffness_scale: None,
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
    };
    let rows = solve_batch(&rod, &inputs, &opts(), 2).unwrap();
    let params = [Param {
        kind: ParamKind::CorrectionFactor(2),
        sections: vec![1],
    }];
    let sens = sensitivity_batch(&rod, &inputs, None, &params, &[], &opts(), 2).unwrap();
    for (r, row) in rows.iter().enumerate() {
        let ld = tensioned(&p[3 * r..3 * r + 3], &t[2 * r..2 * r + 2]);
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        assert!(row.converged);
        assert_eq!(row.tip_position, sol.tip.r, "row {r}");
        assert_eq!(row.x, sol.x);
        let single = tip_sensitivity(&rod, &ld, &sol, &params).unwrap();
        assert_eq!(
            sens[r].sensitivity.as_ref().unwrap().position,
            single.position
        );
    }
}

/// A slack tendon (tension 0) is no tendon at all: the solution equals the rod without it,
/// bitwise.
#[test]
fn slack_tendon_is_no_tendon() {
    let with = Rod::new(tendon_arm(true, false)).unwrap();
    let mut spec = tendon_arm(true, false);
    for s in &mut spec.sections {
        s.tendons.clear();
    }
    let without = Rod::new(spec).unwrap();
    let p = [20e3, 0.0, 10e3];
    let a = solve(&with, &tensioned(&p, &[0.0, 0.0]), None, &opts()).unwrap();
    let b = solve(&without, &loads(&p), None, &opts()).unwrap();
    assert_eq!(a.tip.r, b.tip.r);
    assert_eq!(a.x, b.x);
}

fn field_of<T: std::fmt::Debug>(r: softrod_core::Result<T>) -> String {
    match r {
        Err(SoftrodError::InvalidParameter { field, .. }) => field,
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

/// Tensions are inputs: one per tendon channel, finite, >= 0 (a tendon cannot push).
/// Routes: every elastic section from the base to a tendon's end lists it; channels are
/// contiguous; a tendon lies inside the section.
#[test]
fn tensions_and_routes_are_validated() {
    let rod = Rod::new(tendon_arm(false, false)).unwrap();
    let p = [0.0; 3];
    for (t, field) in [
        (vec![1.0, -0.1], "tensions[1]"),
        (vec![f64::NAN, 0.0], "tensions[0]"),
        (vec![1.0], "tensions"),
        (vec![1.0, 1.0, 1.0], "tensions"),
    ] {
        assert_eq!(
            field_of(solve(&rod, &tensioned(&p, &t), None, &opts())),
            field
        );
    }
    let bad_row = [1.0, 0.5, 2.0, -3.0];
    let inputs = BatchInputs {
        pressures: &[0.0; 6],
        tensions: Some(&bad_row),
        stiffness_scale: None,
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
    };
    assert_eq!(
        field_of(solve_batch(&rod, &inputs, &opts(), 1)),
        "row 1: tensions[1]"
    );
    // a tendon that skips the cap
    let mut spec = tendon_arm(false, false);
    spec.sections[0].tendons.retain(|t| t.channel != 1);
    assert_eq!(field_of(Rod::new(spec)), "sections[0].tendons");
    // a gap in the channels
    let mut spec = tendon_arm(false, false);
    for s in &mut spec.sections {
        for t in &mut s.tendons {
            if t.channel == 1 {
                t.channel = 2;
            }
        }
    }
    assert_eq!(field_of(Rod::new(spec)), "tendons.channel");
    // outside the section
    let mut spec = tendon_arm(false, false);
    spec.sections[1].tendons[0].distance_end = Some(0.03);
    assert_eq!(
        field_of(Rod::new(spec)),
        "sections[1].tendons[0].distance_end"
    );
    // one tendon twice in a section
    let mut spec = tendon_arm(false, false);
    spec.sections[2].tendons.push(tendon(1, 0.01, 0.0));
    assert_eq!(field_of(Rod::new(spec)), "sections[2].tendons[1].channel");
    // tendons with a nonlinear axial law are refused
    let mut spec = tendon_arm(false, false);
    spec.sections[1].law.axial = softrod_core::spec::AxialSpec::Ogden { alpha: 2.0 };
    assert_eq!(field_of(Rod::new(spec)), "sections[1].tendons");
}
