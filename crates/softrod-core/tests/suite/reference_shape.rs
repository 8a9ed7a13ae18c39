//! Reference shapes (precurvature u*, pre-strain v*): closed forms for unloaded rods (arc,
//! helix), every law acting on the strains relative to the reference, the spline table
//! against the constant reference and its fourth order, validity relative to the reference,
//! and exact Jacobians against finite differences.

use crate::common;
use common::*;
use softrod_core::ode::Loads;
use softrod_core::spec::{
    AxialSpec, LawSpec, PartitionSpec, ReferenceSpec, ReferenceTable, SectionSpec, SwellingSpec,
};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::validity::Policy;
use softrod_core::{Rod, SoftrodError};
use std::f64::consts::PI;

/// Bend radius of the arcs, m, and their length (a 45-degree arc).
const R: f64 = 0.1;
const ARC: f64 = PI / 4.0 * R;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

fn with_reference(mut sec: SectionSpec, u: [f64; 3], v: [f64; 3]) -> SectionSpec {
    sec.reference = ReferenceSpec {
        curvature: u,
        strain: v,
        table: None,
    };
    sec
}

/// r(s) of a rod with constant body-frame strains v = (0, 0, v3) and u from the base
/// (identity pose): R(s) = exp(s u^), r(s) = v3 int_0^s R e3 (Rodrigues, integrated).
fn helix(u: [f64; 3], v3: f64, s: f64) -> [f64; 3] {
    let w = norm(&u);
    let a = u.map(|x| x / w);
    let ae = a[2]; // a . e3
    let axe = [a[1], -a[0], 0.0]; // a x e3
    let (sn, cs) = (w * s).sin_cos();
    std::array::from_fn(|k| {
        let e = if k == 2 { 1.0 } else { 0.0 };
        v3 * (s * ae * a[k] + sn / w * (e - ae * a[k]) + (1.0 - cs) / w * axe[k])
    })
}

/// An unloaded precurved rod keeps its reference shape: u = u* exactly (the base wrench is
/// zero, so the law returns the reference strains at round-off) and the centreline is the
/// arc, or the helix, to 1e-12 of the radius. RK4 approximates exp(h u^) by its Taylor
/// polynomial of degree 4 (error (h |u|)^5 / 120 per step): 400 steps over 45 degrees make
/// that 2.6e-16 per step, 1e-13 in all.
#[test]
fn unloaded_precurved_rod_keeps_its_arc_and_helix() {
    for (u, v3) in [
        ([0.0, 1.0 / R, 0.0], 1.0),
        ([-1.0 / R, 0.0, 0.0], 1.0),
        ([3.0, -7.0, 4.0], 1.0),    // a helix
        ([0.0, 1.0 / R, 0.0], 1.2), // pre-stretched arc
    ] {
        let sec = with_reference(
            direct_section("arc", ARC, 50.0, 30.0, 0.02, 0.015, 0.0, 400),
            u,
            [0.0, 0.0, v3],
        );
        let rod = Rod::new(design(vec![sec], IDENTITY, 0.0)).unwrap();
        let ld = loads(&[]);
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        assert_eq!(sol.stable, Some(true));
        let sh = shape(&rod, &ld, &sol);
        for (k, s) in sh.s.iter().enumerate() {
            for i in 0..3 {
                assert!(
                    (sh.u[k][i] - u[i]).abs() < 1e-12 * norm(&u),
                    "u {:?}",
                    sh.u[k]
                );
            }
            assert!((sh.v[k][2] - v3).abs() < 1e-14);
            let want = helix(u, v3, *s);
            let err = dist(&sh.position[k], &want);
            assert!(err < 1e-12 * R, "u* {u:?}, s = {s}: {err:.2e}");
        }
    }
}

/// Every law acts on the strains relative to the reference, v - v* + e3 and u - u*: an
/// unloaded rod with a reference shape and any law keeps that shape (v = v*, u = u*).
#[test]
fn every_law_keeps_the_reference_shape_when_unloaded() {
    let u = [2.0, -5.0, 1.5];
    let v = [0.01, -0.02, 1.1];
    let geometric = || {
        with_reference(
            geometry_section(
                "body",
                0.1,
                0.02,
                0.0,
                ECOFLEX,
                p002_chambers([90.0, 210.0, 330.0]),
                24,
            ),
            u,
            v,
        )
    };
    let mut laws: Vec<(&str, SectionSpec)> = vec![("linear", geometric())];
    let mut s = geometric();
    s.law.axial = AxialSpec::Ogden { alpha: 8.89 };
    laws.push(("ogden", s));
    let mut s = geometric();
    s.law.axial = AxialSpec::Table {
        force: vec![-5.0, 0.0, 5.0],
        stiffness: vec![30.0, 25.0, 20.0],
    };
    laws.push(("table", s));
    let mut s = geometric();
    s.law.stretch_bending = true;
    s.law.swelling = Some(SwellingSpec {
        c_p: 0.1,
        p_ref: 1e5,
    });
    s.law.chamber_offset = [1e-4, -2e-4];
    laws.push(("stretch bending, swelling, offset", s));
    let mut s = geometric();
    s.law.stiffness_map = true;
    laws.push(("stiffness map", s));
    let mut s = direct_section("partition", 0.1, 0.0, 40.0, 0.0, 0.01, 0.01, 24);
    s.stiffness.ea = None;
    s.stiffness.ei1 = None;
    s.stiffness.ei2 = None;
    s.partition = Some(PartitionSpec {
        j: 3,
        e_i: 40.0,
        r_i: 0.008,
        e_ii: 0.0,
        r_ii: 0.0,
        e_iii: 20.0,
    });
    laws.push(("partition", with_reference(s, u, v)));
    for (name, sec) in laws {
        let rod = Rod::new(design(vec![sec], tilted(), 0.0)).unwrap();
        let np = rod.n_channels;
        let ld = Loads {
            stiffness_scale: [0.9, 1.1, 1.2],
            ..loads(&vec![0.0; np])
        };
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        let sh = shape(&rod, &ld, &sol);
        for k in 0..sh.s.len() {
            for i in 0..3 {
                assert!((sh.u[k][i] - u[i]).abs() < 1e-11, "{name}: u {:?}", sh.u[k]);
                assert!((sh.v[k][i] - v[i]).abs() < 1e-13, "{name}: v {:?}", sh.v[k]);
            }
        }
        assert_eq!(sol.stable, Some(true), "{name}");
    }
}

fn table(s: &[f64], u: impl Fn(f64) -> [f64; 3], v: impl Fn(f64) -> [f64; 3]) -> ReferenceSpec {
    ReferenceSpec {
        curvature: [0.0; 3],
        strain: [0.0, 0.0, 1.0],
        table: Some(ReferenceTable {
            s: s.to_vec(),
            curvature: s.iter().map(|&x| u(x)).collect(),
            strain: s.iter().map(|&x| v(x)).collect(),
        }),
    }
}

/// A rod loaded by gravity and a tip force, with the given reference, `steps` per section.
fn loaded(reference: ReferenceSpec, steps: usize) -> (Rod, Loads) {
    let mut sec = geometry_section("finger", ARC, 0.012, 0.0, DRAGON_SKIN, vec![], steps);
    sec.reference = reference;
    let rod = Rod::new(design(vec![sec], tilted(), 9.81)).unwrap();
    let mut ld = loads(&[]);
    ld.tip_force = [0.05, -0.02, 0.03];
    (rod, ld)
}

/// A table of constant values is the constant reference (the spline of constant data is
/// that constant up to round-off in its Hermite basis).
#[test]
fn constant_table_equals_constant_reference() {
    let u = [0.0, 1.0 / R, 0.5];
    let v = [0.0, 0.0, 1.05];
    let s = [0.0, 0.01, 0.04, 0.06, ARC];
    let (a, la) = loaded(
        ReferenceSpec {
            curvature: u,
            strain: v,
            table: None,
        },
        32,
    );
    let (b, lb) = loaded(table(&s, |_| u, |_| v), 32);
    let sa = solve(&a, &la, None, &opts()).unwrap();
    let sb = solve(&b, &lb, None, &opts()).unwrap();
    let err = dist(&sa.tip.r, &sb.tip.r);
    assert!(err < 1e-13 * ARC, "{err:.2e}");
}

/// The tabulated reference is interpolated by a C2 spline evaluated at the RK4 stages, so
/// the solution converges at fourth order in the steps: the differences between solutions
/// at n and 2n steps shrink 16-fold (fitted slope of log difference against log step in
/// [3.7, 4.3]; the error constants at 8-64 steps are in the asymptotic range). The table
/// is not a cubic, so its knots (inside steps) matter.
#[test]
fn tabulated_reference_converges_at_fourth_order() {
    let s: Vec<f64> = (0..=6).map(|k| ARC * k as f64 / 6.0).collect();
    let reference = table(
        &s,
        |x| {
            let q = x / ARC;
            [
                3.0 * (5.0 * q).sin(),
                1.0 / R * (1.0 + 0.5 * q * q),
                2.0 * q,
            ]
        },
        |x| [0.0, 0.01 * x / ARC, 1.0 + 0.05 * (3.0 * x / ARC).cos()],
    );
    let tip = |n: usize| {
        let (rod, ld) = loaded(reference.clone(), n);
        solve(&rod, &ld, None, &opts()).unwrap().tip.r
    };
    let ns = [6, 12, 24, 48, 96];
    let tips: Vec<[f64; 3]> = ns.iter().map(|&n| tip(n)).collect();
    let (mut xs, mut ys) = (vec![], vec![]);
    for k in 0..ns.len() - 1 {
        let d = dist(&tips[k], &tips[k + 1]);
        xs.push((ARC / ns[k] as f64).ln());
        ys.push(d.ln());
        eprintln!("n = {}: difference {d:.3e}", ns[k]);
    }
    let slope = fitted_slope(&xs, &ys);
    assert!((3.7..=4.3).contains(&slope), "order {slope:.3}");
}

/// Least-squares slope of y against x.
fn fitted_slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    sxy / sxx
}

/// Exact Jacobians with a reference shape: constant and tabulated, with chambers under
/// pressure, gravity on a tilted mounting and a tip body.
#[test]
fn jacobian_matches_finite_differences_with_reference_shapes() {
    let s: Vec<f64> = (0..=4).map(|k| P002_BODY * k as f64 / 4.0).collect();
    for (name, reference) in [
        (
            "constant",
            ReferenceSpec {
                curvature: [4.0, -9.0, 2.0],
                strain: [0.01, 0.0, 1.05],
                table: None,
            },
        ),
        (
            "table",
            table(
                &s,
                |x| [10.0 * x, -5.0 + 20.0 * x, 3.0],
                |x| [0.0, 0.02 * x, 1.0 + x],
            ),
        ),
    ] {
        let mut spec = p002_actuator(tilted(), 9.81, 12);
        spec.sections[1].reference = reference;
        spec.sections[1].law.stretch_bending = true;
        spec.tip.mass = 0.01;
        spec.tip.com_offset = [0.004, -0.002, 0.006];
        let rod = Rod::new(spec).unwrap();
        let ld = loads(&[30e3, 5e3, 12e3]);
        check_jacobian_against_fd(name, &rod, &ld, &opts(), 17);
    }
}

/// The fibre stretch is measured relative to the reference: a section bent to a radius of
/// 1.25 outer radii has fibres 0.2 and 1.8 times as long as its centreline, but unloaded
/// every fibre is at stretch 1 and the solution is valid; bent the other way by the
/// same load it is outside the range.
#[test]
fn validity_is_relative_to_the_reference_shape() {
    let ro = 0.01;
    let k = 0.8 / ro; // rho |u*| = 0.8
    let mut sec = geometry_section("hook", 0.02, ro, 0.0, DRAGON_SKIN, vec![], 64);
    sec.reference.curvature = [0.0, k, 0.0];
    let rod = Rod::new(design(vec![sec.clone()], IDENTITY, 0.0)).unwrap();
    let sol = solve(&rod, &loads(&[]), None, &opts()).unwrap();
    assert!(sol.violations.is_empty());
    // A tip moment that straightens the hook and bends it as far the other way: absolute
    // curvature -k, relative -2k: fibres at 1 -/+ 2 * 0.8 / (1 -/+ 0.8) -> far outside.
    let ei = DRAGON_SKIN.youngs_modulus * PI * ro.powi(4) / 4.0;
    let mut ld = loads(&[]);
    ld.tip_moment = [0.0, -2.0 * k * ei, 0.0];
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..opts()
    };
    let sol = solve(&rod, &ld, None, &warn).unwrap();
    assert!(!sol.violations.is_empty(), "reverse bend not flagged");
    // The reference itself may not fold the section: rho |u*| >= v3* is a design error.
    sec.reference.curvature = [0.0, 1.0 / ro, 0.0];
    match Rod::new(design(vec![sec], IDENTITY, 0.0)) {
        Err(SoftrodError::InvalidParameter { field, rule, .. }) => {
            assert_eq!(field, "sections[0].reference");
            assert!(rule.contains("folds"), "{rule}");
        }
        other => panic!("expected a design error, got {other:?}"),
    }
}

/// Bad reference tables are design errors naming the field.
#[test]
fn reference_tables_are_validated() {
    let sec = |t: ReferenceSpec| {
        let mut s = direct_section("s", 0.1, 10.0, 10.0, 0.01, 0.01, 0.01, 8);
        s.reference = t;
        Rod::new(design(vec![s], IDENTITY, 0.0))
    };
    let field = |r: softrod_core::Result<Rod>| match r {
        Err(SoftrodError::InvalidParameter { field, .. }) => field,
        other => panic!("expected a design error, got {other:?}"),
    };
    let ok = |s: &[f64]| table(s, |_| [0.0; 3], |_| [0.0, 0.0, 1.0]);
    assert!(sec(ok(&[0.0, 0.1])).is_ok());
    assert_eq!(
        field(sec(ok(&[0.0, 0.05]))),
        "sections[0].reference.table.s"
    );
    assert_eq!(
        field(sec(ok(&[0.0, 0.07, 0.05, 0.1]))),
        "sections[0].reference.table.s[2]"
    );
    assert_eq!(field(sec(ok(&[0.0]))), "sections[0].reference.table.s");
    let neg = table(&[0.0, 0.1], |_| [0.0; 3], |_| [0.0, 0.0, -1.0]);
    assert_eq!(field(sec(neg)), "sections[0].reference.table.strain[0][2]");
    let mut both = ok(&[0.0, 0.1]);
    both.curvature = [1.0, 0.0, 0.0];
    assert_eq!(field(sec(both)), "sections[0].reference.table");
    let nan = table(&[0.0, 0.1], |_| [f64::NAN, 0.0, 0.0], |_| [0.0, 0.0, 1.0]);
    assert_eq!(
        field(sec(nan)),
        "sections[0].reference.table.curvature[0][0]"
    );
    // a rigid section cannot have one
    let mut r = rigid_section("cap", 0.01, 0.001);
    r.reference.curvature = [1.0, 0.0, 0.0];
    assert_eq!(
        field(Rod::new(design(vec![r], IDENTITY, 0.0))),
        "sections[0].reference"
    );
    let _ = LawSpec::default();
}
