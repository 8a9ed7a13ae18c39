//! Exact parameter derivatives of the tip pose and of marker points anywhere on the body
//! (crate::sensitivity) against central finite differences of full solves with the
//! parameter changed in the design, for every parameter kind and law; marker positions
//! against the solved shape; the batch against single solves; parameter validation.

use crate::common;
use common::*;
use softrod_core::batch::{constrained_sensitivity_batch, sensitivity_batch, BatchInputs};
use softrod_core::marker::Marker;
use softrod_core::ode::Loads;
use softrod_core::sensitivity::{
    constrained_pose_sensitivity, locate_markers, marker_positions, pose_sensitivity,
    tip_sensitivity, validate_params, Param, ParamKind,
};
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::{AxialSpec, DesignSpec};
use softrod_core::statics::constraint::{exp_so3, solve_constrained, TipConstraint};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

/// Newton tolerance for the finite-difference solves: the solution error (~1e-13 of the
/// scaled unknowns) divided by the step below stays near 1e-8 of a derivative.
const SOLVER_TOL: f64 = 1e-13;
/// Relative parameter step of the central differences: truncation h^2 |y'''|/6 ~ 1e-10
/// relative for these smooth laws, solve error / h ~ 1e-8 relative.
const H: f64 = 1e-5;
/// Column-wise agreement relative to the column's norm. Measured (printed): at most 2e-7
/// (the Ogden alpha's rotation column), most below 1e-8; a derivative missing one term
/// (e.g. swelling's change of I, lambda^alpha's dependence on alpha, the offset's moment
/// arm) is off by percent.
const COLUMN_TOL: f64 = 1e-6;
/// Plus an absolute allowance for the finite differences' own noise on columns that are
/// nearly zero (c_t barely moves the tip): two solves agree to ~1e-14 m, divided by 2 h.
const TIP_NOISE: f64 = 1e-14;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: SOLVER_TOL,
        ..Default::default()
    }
}

const HANGING: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];

/// Paper 002's M3 body (Ogden, offset, swelling) in the p002 actuator, c_b 1.31 on the body
/// only so that a shared c_b of both caps is a different parameter.
fn m3(rotation: [[f64; 3]; 3]) -> DesignSpec {
    let mut d = p002_actuator(rotation, 9.81, 12);
    d.sections[1].c_b = 1.31;
    d.sections[1].c_e = 2.82;
    d.sections[1].law = ogden_m3_law();
    d.tip.mass = 6e-3;
    d.tip.com_offset = [1e-3, 0.0, 4e-3];
    d
}

/// Compare every parameter's exact derivative of the tip position and rotation with
/// central differences; returns the worst relative column error.
fn check(name: &str, spec: DesignSpec, ld: Loads, params: &[Param]) -> f64 {
    let rod = Rod::new(spec.clone()).unwrap();
    validate_params(&rod, params).unwrap();
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let sens = tip_sensitivity(&rod, &ld, &sol, params).unwrap();
    let mut worst: f64 = 0.0;
    for (j, p) in params.iter().enumerate() {
        let v0 = p.value(&rod, &ld);
        // Offsets are absolute lengths (possibly 0): step in m.
        let step = match p.kind {
            ParamKind::ChamberOffset(_) => 1e-8,
            _ => H * v0.abs(),
        };
        let at = |v: f64| {
            let (mut s, mut l) = (spec.clone(), ld.clone());
            if let ParamKind::AreaScale = p.kind {
                set_param(&mut s, &mut l, p, v / v0); // factor on the design's areas
            } else {
                set_param(&mut s, &mut l, p, v);
            }
            let r = Rod::new(s).unwrap();
            solve(&r, &l, Some(&sol.x), &opts()).unwrap().tip
        };
        let (tp, tm) = (at(v0 + step), at(v0 - step));
        let fd_r: Vec<f64> = (0..3).map(|i| (tp.r[i] - tm.r[i]) / (2.0 * step)).collect();
        let fd_q: Vec<f64> = (0..9)
            .map(|k| (tp.rot[k / 3][k % 3] - tm.rot[k / 3][k % 3]) / (2.0 * step))
            .collect();
        let ex_r = sens.position[j].to_vec();
        let ex_q: Vec<f64> = (0..9).map(|k| sens.rotation[j][k / 3][k % 3]).collect();
        for (what, fd, ex) in [("position", fd_r, ex_r), ("rotation", fd_q, ex_q)] {
            let n = fd.iter().map(|x| x * x).sum::<f64>().sqrt();
            let e = fd
                .iter()
                .zip(&ex)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
                / (n + TIP_NOISE / (COLUMN_TOL * step));
            println!(
                "{name}: d tip {what} / d {} : rel. error {e:.2e}",
                p.kind.name()
            );
            assert!(
                e < COLUMN_TOL,
                "{name}: d tip {what}/d {}: exact {ex:?} vs FD {fd:?} (rel. error {e:.2e})",
                p.kind.name()
            );
            worst = worst.max(e);
        }
    }
    worst
}

#[test]
fn every_parameter_of_the_m3_law_matches_finite_differences() {
    let ld = Loads {
        pressures: vec![30e3, 12e3, 0.0],
        ..loads(&[0.0; 3])
    };
    let params = [
        param("c_b", &[1]),
        param("c_e", &[1]),
        param("alpha", &[1]),
        param("c_p", &[1]),
        param("offset_1", &[1]),
        param("offset_2", &[1]),
        param("E", &[1]),
        param("area_scale", &[1]),
        param("c_s", &[1]),
        param("c_t", &[1]),
        param("c_b", &[0, 2]), // both caps share c_b = 1
        param("E", &[0, 2]),   // both caps are Dragon Skin
        param("density", &[1]),
        param("density", &[0, 2]),
    ];
    for (name, rotation) in [("hanging", HANGING), ("tilted", tilted())] {
        check(name, m3(rotation), ld.clone(), &params);
    }
}

#[test]
fn stiffness_scaling_factors_match_finite_differences() {
    let mut spec = p002_actuator(HORIZONTAL, 9.81, 12);
    spec.sections[1].law.stiffness_map = true;
    let ld = Loads {
        pressures: vec![40e3, 0.0, 25e3],
        stiffness_scale: [0.8, 1.2, 0.7],
        ..loads(&[0.0; 3])
    };
    let params = [
        param("sigma_ext", &[]),
        param("sigma_bend_1", &[]),
        param("sigma_bend_2", &[]),
        param("c_b", &[1]),
    ];
    check("sigma", spec, ld, &params);
}

#[test]
fn table_law_and_linear_law_parameters_match_finite_differences() {
    let mut spec = p002_actuator(tilted(), 9.81, 12);
    spec.sections[1].law.axial = AxialSpec::Table {
        force: vec![0.0, 5.0, 20.0],
        stiffness: vec![90.0, 70.0, 60.0],
    };
    spec.sections[1].law.stiffness_map = true;
    let ld = Loads {
        pressures: vec![20e3, 35e3, 5e3],
        stiffness_scale: [1.1, 1.0, 0.9],
        ..loads(&[0.0; 3])
    };
    let params = [
        param("c_e", &[1]),
        param("sigma_ext", &[]),
        param("E", &[1]),
        param("area_scale", &[1]),
    ];
    check("table", spec, ld, &params);
}

#[test]
fn batch_sensitivities_equal_single_ones() {
    let spec = m3(HANGING);
    let rod = Rod::new(spec).unwrap();
    let params = [
        param("c_b", &[1]),
        param("alpha", &[1]),
        param("c_p", &[1]),
        param("offset_2", &[1]),
        param("c_e", &[1]),
    ];
    let mut pressures = vec![];
    for k in 0..6 {
        pressures.extend([5e3 * k as f64, 3e3, 20e3 - 3e3 * k as f64]);
    }
    let rows = sensitivity_batch(
        &rod,
        &BatchInputs::pressures(&rod, &pressures),
        None,
        &params,
        &[],
        &opts(),
        2,
    )
    .unwrap();
    for (r, row) in rows.iter().enumerate() {
        let ld = loads(&pressures[3 * r..3 * r + 3]);
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        let single = tip_sensitivity(&rod, &ld, &sol, &params).unwrap();
        let batch = row.sensitivity.as_ref().unwrap();
        // Warm and cold solves reach the same equilibrium to the solver tolerance; the
        // derivatives then agree to about the same relative size.
        for j in 0..params.len() {
            let n = norm(&single.position[j]).max(1e-12);
            let d = dist(&single.position[j], &batch.position[j]);
            assert!(d <= 1e-8 * n, "row {r} param {j}: {d:e} vs {n:e}");
        }
    }
}

#[test]
fn parameters_are_validated_against_the_design() {
    let rod = Rod::new(m3(HANGING)).unwrap();
    let err = |p: Param| match validate_params(&rod, &[p]) {
        Err(SoftrodError::InvalidParameter { field, value, rule }) => {
            format!("{field} | {value} | {rule}")
        }
        other => panic!("expected an error, got {other:?}"),
    };
    assert!(err(param("alpha", &[0])).contains("ogden"));
    assert!(err(param("c_p", &[0])).contains("swelling"));
    assert!(err(param("c_b", &[7])).contains("3 sections"));
    assert!(err(param("c_b", &[])).contains("at least one section"));
    assert!(err(param("sigma_ext", &[])).contains("stiffness_map"));
    assert!(err(param("offset_1", &[0])).contains("no chambers"));
    // c_b is 1 in the caps and 1.31 in the body: one parameter cannot have both values.
    let e = err(param("c_b", &[0, 1]));
    assert!(e.contains("one value") && e.contains("1.31"), "{e}");
    let mut rigid = m3(HANGING);
    rigid.sections[2] = rigid_section("cap_c", 0.01, 0.005);
    let rod = Rod::new(rigid).unwrap();
    assert!(matches!(
        validate_params(&rod, &[param("c_e", &[2])]),
        Err(SoftrodError::InvalidParameter { rule, .. }) if rule.contains("rigid")
    ));
}

/// Markers at the base, inside a step of the cap, at the junction cap/body, inside a step
/// of the Ogden body (its first step, where the carried stretch starts), on a node of the
/// body, at the junction body/cap and at the tip, with offsets in the cross-section frame.
fn markers(spec: &DesignSpec) -> Vec<Marker> {
    let (a, b) = (spec.sections[0].length, spec.sections[1].length);
    let h = b / spec.sections[1].steps as f64;
    [
        (0.0, [0.0, 0.0, 0.0]),
        (0.37 * a, [3e-3, -2e-3, 0.0]),
        (a, [0.0, 12e-3, 0.0]),
        (a + 0.4 * h, [-5e-3, 0.0, 1e-3]),
        (a + 3.0 * h, [0.0, 0.0, 0.0]),
        (a + 0.55 * b, [15e-3, 2e-3, -1e-3]),
        (a + b, [1e-3, 1e-3, 0.0]),
        (
            spec.sections.iter().map(|s| s.length).sum::<f64>(),
            [0.0, 0.0, 5e-3],
        ),
    ]
    .into_iter()
    .map(|(s, offset)| Marker { s, offset })
    .collect()
}

#[test]
fn markers_on_nodes_equal_the_solved_shape_and_the_tip() {
    let spec = m3(tilted());
    let rod = Rod::new(spec.clone()).unwrap();
    let ld = Loads {
        pressures: vec![30e3, 12e3, 0.0],
        ..loads(&[0.0; 3])
    };
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let sh = shape(&rod, &ld, &sol);
    // Every node, with no offset: the shape's positions; the last one is the tip, bitwise
    // (the same state, read at the node).
    let on_nodes: Vec<Marker> =
        sh.s.iter()
            .map(|&s| Marker {
                s,
                offset: [0.0; 3],
            })
            .collect();
    let located = locate_markers(&rod, &on_nodes).unwrap();
    let got = marker_positions(&rod, &ld, &sol, &located);
    for (k, (p, q)) in got.iter().zip(&sh.position).enumerate() {
        assert!(dist(p, q) <= 1e-15, "node {k}: {p:?} vs {q:?}");
    }
    assert_eq!(got.last().unwrap(), &sol.tip.r);
    // An offset along d3 at the tip is the tip plus that length along the tip tangent.
    let tip = Marker {
        s: rod.length,
        offset: [0.0, 0.0, 0.01],
    };
    let p = marker_positions(&rod, &ld, &sol, &locate_markers(&rod, &[tip]).unwrap())[0];
    let d3 = column(&sol.tip.rot, 2);
    for i in 0..3 {
        assert!((p[i] - sol.tip.r[i] - 0.01 * d3[i]).abs() < 1e-15);
    }
}

#[test]
fn markers_between_nodes_converge_at_fourth_order() {
    // A marker between nodes is read by a partial RK4 step: as the steps shrink its
    // position approaches the exact one at the integrator's order (h^4), like the nodes.
    let ld = Loads {
        pressures: vec![40e3, 0.0, 10e3],
        ..loads(&[0.0; 3])
    };
    let at = |steps: usize| {
        let spec = p002_actuator(HANGING, 9.81, steps);
        let s = spec.sections[0].length + 0.613 * spec.sections[1].length;
        let rod = Rod::new(spec).unwrap();
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        let mk = Marker {
            s,
            offset: [4e-3, -3e-3, 0.0],
        };
        marker_positions(&rod, &ld, &sol, &locate_markers(&rod, &[mk]).unwrap())[0]
    };
    let reference = at(256);
    let errors: Vec<f64> = [8, 16, 32]
        .iter()
        .map(|&n| dist(&at(n), &reference))
        .collect();
    let order = |a: f64, b: f64| (a / b).log2();
    println!("marker errors {errors:?}");
    // Fourth order: the error ratio per halving is 16 (slopes within [3.5, 4.5] measured
    // 3.9-4.0; the reference's own error is 256^-4 relative, far below).
    assert!(order(errors[0], errors[1]) > 3.5 && order(errors[1], errors[2]) > 3.5);
}

/// Central differences of marker positions with respect to `p` (step: 1e-8 m for an
/// offset, else H of its value), `solved(spec, loads)` giving the markers of the design and
/// loads with the parameter changed; returns the difference quotient per marker and the
/// step.
fn fd_markers(
    spec: &DesignSpec,
    ld: &Loads,
    rod: &Rod,
    p: &Param,
    solved: impl Fn(&DesignSpec, &Loads) -> Vec<[f64; 3]>,
) -> (Vec<[f64; 3]>, f64) {
    let v0 = p.value(rod, ld);
    let step = match p.kind {
        ParamKind::ChamberOffset(_) => 1e-8,
        _ => H * v0.abs(),
    };
    let at = |v: f64| {
        let (mut s, mut l) = (spec.clone(), ld.clone());
        // The area factor is relative to the design's areas.
        let v = if let ParamKind::AreaScale = p.kind {
            v / v0
        } else {
            v
        };
        set_param(&mut s, &mut l, p, v);
        solved(&s, &l)
    };
    let (plus, minus) = (at(v0 + step), at(v0 - step));
    let fd = plus
        .iter()
        .zip(&minus)
        .map(|(a, b)| std::array::from_fn(|i| (a[i] - b[i]) / (2.0 * step)))
        .collect();
    (fd, step)
}

/// Relative error of an exact marker derivative against its central difference, with the
/// absolute allowance for nearly-zero columns (TIP_NOISE).
fn marker_error(fd: &[f64; 3], exact: &[f64; 3], step: f64) -> f64 {
    dist(fd, exact) / (norm(fd) + TIP_NOISE / (COLUMN_TOL * step))
}

/// Compare the exact derivatives of every marker (and of the tip) with central differences
/// of full solves; the base marker (markers()[0]) must not move.
fn check_markers(spec: &DesignSpec, ld: &Loads, params: &[Param]) {
    let rod = Rod::new(spec.clone()).unwrap();
    let mks = markers(spec);
    let located = locate_markers(&rod, &mks).unwrap();
    let sol = solve(&rod, ld, None, &opts()).unwrap();
    let sens = pose_sensitivity(&rod, ld, &sol, params, &located).unwrap();
    // The tip derivative is the same with or without markers.
    let tip_only = tip_sensitivity(&rod, ld, &sol, params).unwrap();
    assert_eq!(sens.position, tip_only.position);
    for (j, p) in params.iter().enumerate() {
        let (fd, step) = fd_markers(spec, ld, &rod, p, |s, l| {
            let r = Rod::new(s.clone()).unwrap();
            let sol = solve(&r, l, Some(&sol.x), &opts()).unwrap();
            marker_positions(&r, l, &sol, &locate_markers(&r, &mks).unwrap())
        });
        for (k, fd) in fd.iter().enumerate() {
            let ex = sens.markers[j][k];
            let e = marker_error(fd, &ex, step);
            println!("marker {k} d/d {}: rel. error {e:.2e}", p.kind.name());
            assert!(
                e < COLUMN_TOL,
                "marker {k} d/d {}: exact {ex:?} vs FD {fd:?} ({e:.2e})",
                p.kind.name()
            );
        }
        // The base marker does not move with any parameter.
        assert_eq!(sens.markers[j][0], [0.0; 3]);
    }
}

#[test]
fn marker_derivatives_match_finite_differences() {
    let spec = m3(tilted());
    let ld = Loads {
        pressures: vec![25e3, 5e3, 15e3],
        ..loads(&[0.0; 3])
    };
    let params = [
        param("c_b", &[1]),
        param("alpha", &[1]),
        param("c_p", &[1]),
        param("offset_1", &[1]),
        param("E", &[0, 2]),
        param("area_scale", &[1]),
        param("density", &[1]),
    ];
    check_markers(&spec, &ld, &params);
}

#[test]
fn derivatives_with_an_obstacle_match_finite_differences() {
    // The hanging M3 actuator bends sideways under channel 0 and presses on a wall whose
    // face is half its free lateral tip deflection away from its surface: the contact
    // penalty (a line load of the shooting ODE, docs/contact.md) and the rounded end's
    // force enter the dual passes like any load, so the derivatives carry them. The
    // penalty is C1 (its curvature jumps where a point touches down or reaches the ramp's
    // end), so central differences are O(h^2) accurate unless a step moves an RK4 stage
    // point across a switch; the same tolerance as without contact holds (and would not if
    // the contact term were missing: the wall changes the tip's derivatives by tens of
    // percent, asserted below).
    let mut spec = m3(HANGING);
    let ld = Loads {
        pressures: vec![30e3, 0.0, 0.0],
        ..loads(&[0.0; 3])
    };
    let free = solve(&Rod::new(spec.clone()).unwrap(), &ld, None, &opts()).unwrap();
    let side = [free.tip.r[0], free.tip.r[1], 0.0];
    let reach = norm(&side);
    assert!(reach > 5e-3, "the free tip moves {reach} m sideways");
    let dir = side.map(|v| v / reach);
    let mut wall = obstacle(ObstacleKind::Plane, 1e5, 1e-3);
    wall.point = Some(dir.map(|v| (P002_RO + 0.5 * reach) * v));
    wall.normal = Some(dir.map(|v| -v));
    spec.obstacles = vec![wall];
    // The wall really holds the rod: its tip stops short of the free one by millimetres.
    let rod = Rod::new(spec.clone()).unwrap();
    let held = solve(&rod, &ld, None, &opts()).unwrap();
    let gap = reach - (held.tip.r[0] * dir[0] + held.tip.r[1] * dir[1]);
    assert!(gap > 2e-3, "the wall moved the tip by {gap} m only");
    let params = [
        param("c_b", &[1]),
        param("alpha", &[1]),
        param("E", &[0, 2]),
        param("area_scale", &[1]),
        param("density", &[1]),
    ];
    check_markers(&spec, &ld, &params);
    // Not vacuous: the wall changes the tip's bending derivative by far more than the
    // tolerance (measured: tens of percent).
    let free_rod = Rod::new(m3(HANGING)).unwrap();
    let without = tip_sensitivity(&free_rod, &ld, &free, &params[..1]).unwrap();
    let with = tip_sensitivity(&rod, &ld, &held, &params[..1]).unwrap();
    let change = dist(&with.position[0], &without.position[0]) / norm(&without.position[0]);
    println!("the wall changes d tip / d c_b by {change:.2e} relative");
    assert!(
        change > 0.1,
        "the wall changed d tip / d c_b by {change:.2e} only"
    );
}

#[test]
fn section_mass_matches_finite_differences_and_batch_markers_equal_single() {
    // A section with its mass given (a rigid-free direct section) takes "mass"; its weight
    // moves the base force, so the derivative needs n(0)'s share too.
    let mut spec = p002_actuator(HORIZONTAL, 9.81, 12);
    spec.sections[1].mass = Some(0.08);
    let ld = Loads {
        pressures: vec![20e3, 0.0, 30e3],
        ..loads(&[0.0; 3])
    };
    check(
        "mass",
        spec.clone(),
        ld,
        &[param("mass", &[1]), param("c_b", &[1])],
    );
    let rod = Rod::new(spec.clone()).unwrap();
    let mks = markers(&spec);
    let mut pressures = vec![];
    for k in 0..4 {
        pressures.extend([8e3 * k as f64, 2e3, 15e3]);
    }
    for params in [vec![], vec![param("mass", &[1])]] {
        let rows = sensitivity_batch(
            &rod,
            &BatchInputs::pressures(&rod, &pressures),
            None,
            &params,
            &mks,
            &opts(),
            2,
        )
        .unwrap();
        for (r, row) in rows.iter().enumerate() {
            let ld = loads(&pressures[3 * r..3 * r + 3]);
            let sol = solve(&rod, &ld, None, &opts()).unwrap();
            let single = marker_positions(&rod, &ld, &sol, &locate_markers(&rod, &mks).unwrap());
            for (a, b) in row.markers.iter().zip(&single) {
                assert!(dist(a, b) <= 1e-12, "row {r}: {a:?} vs {b:?}");
            }
            assert_eq!(row.sensitivity.is_some(), !params.is_empty());
        }
    }
}

#[test]
fn markers_and_mass_parameters_are_validated() {
    let spec = m3(HANGING);
    let rod = Rod::new(spec).unwrap();
    let bad = |mk: Marker| match locate_markers(&rod, &[mk]) {
        Err(SoftrodError::InvalidParameter { field, rule, .. }) => format!("{field} | {rule}"),
        other => panic!("expected an error, got {other:?}"),
    };
    assert!(bad(Marker {
        s: -1e-3,
        offset: [0.0; 3]
    })
    .contains("markers[0].s"));
    assert!(bad(Marker {
        s: 1.0,
        offset: [0.0; 3]
    })
    .contains("[0, L]"));
    assert!(bad(Marker {
        s: f64::NAN,
        offset: [0.0; 3]
    })
    .contains("markers[0].s"));
    assert!(bad(Marker {
        s: 0.05,
        offset: [0.0, f64::INFINITY, 0.0]
    })
    .contains("offset"));
    let err = |p: Param| match validate_params(&rod, &[p]) {
        Err(SoftrodError::InvalidParameter { rule, .. }) => rule,
        other => panic!("expected an error, got {other:?}"),
    };
    assert!(err(param("mass", &[1])).contains("calibrate the density"));
    let mut given = m3(HANGING);
    given.sections[1].mass = Some(0.1);
    let rod = Rod::new(given).unwrap();
    assert!(validate_params(&rod, &[param("density", &[1])]).is_err());
}

// ---- a tip held by a constraint (pinned or clamped) ----

/// The held tips of the tests: the M3 actuator (tilted, gravity, Ogden body) under three
/// channels, its tip pinned 8 mm off the free equilibrium's tip, or clamped there with the
/// free tip's orientation turned by 0.15 rad (so both constraints carry a real reaction).
fn held_tips(spec: &DesignSpec, ld: &Loads) -> [TipConstraint; 2] {
    let rod = Rod::new(spec.clone()).unwrap();
    let free = solve(&rod, ld, None, &opts()).unwrap();
    let position = [
        free.tip.r[0] + 6e-3,
        free.tip.r[1] - 4e-3,
        free.tip.r[2] + 3e-3,
    ];
    let turn = exp_so3(&[0.1, -0.05, 0.1]);
    let rotation: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| (0..3).map(|k| free.tip.rot[i][k] * turn[k][j]).sum())
    });
    [
        TipConstraint::Pinned { position },
        TipConstraint::Clamped { position, rotation },
    ]
}

/// Like [`check_markers`] for a held tip: every marker's exact derivative against central
/// differences of full `solve_constrained` solves (warm-started at the unperturbed
/// solution, so both stay on its branch), with the same step and tolerance (same
/// derivation: the held solve converges to the same SOLVER_TOL); the base marker does not
/// move; the held tip point does not move (`HELD_ROUNDOFF`), nor, when clamped, its
/// rotation. Returns the worst relative marker error.
fn check_held_markers(spec: &DesignSpec, ld: &Loads, c: &TipConstraint, params: &[Param]) -> f64 {
    let rod = Rod::new(spec.clone()).unwrap();
    let mut mks = markers(spec);
    // The tip point itself, no offset (markers() has one at the tip with an axial offset,
    // which turns with a pinned tip).
    mks.push(Marker {
        s: rod.length,
        offset: [0.0; 3],
    });
    let held = mks.len() - 1;
    let located = locate_markers(&rod, &mks).unwrap();
    let sol = solve_constrained(&rod, ld, c, None, &opts()).unwrap();
    // Not vacuous: the constraint holds the tip with a real force.
    let reaction = norm(&sol.tip_reaction_force);
    assert!(
        reaction > 1e-2 * rod.force_scale,
        "{c:?}: reaction {reaction} N"
    );
    let sens = constrained_pose_sensitivity(&rod, ld, c, &sol.solution, params, &located).unwrap();
    let mut worst: f64 = 0.0;
    for (j, p) in params.iter().enumerate() {
        let (fd, step) = fd_markers(spec, ld, &rod, p, |s, l| {
            let r = Rod::new(s.clone()).unwrap();
            let h = solve_constrained(&r, l, c, Some(&sol.solution.x), &opts()).unwrap();
            marker_positions(&r, l, &h.solution, &locate_markers(&r, &mks).unwrap())
        });
        let mut largest: f64 = 0.0;
        for (k, fd) in fd.iter().enumerate() {
            let ex = sens.markers[j][k];
            largest = largest.max(norm(&ex));
            if k == held {
                continue;
            }
            let e = marker_error(fd, &ex, step);
            worst = worst.max(e);
            println!(
                "{} marker {k} d/d {}: rel. error {e:.2e}",
                c.name(),
                p.kind.name()
            );
            assert!(
                e < COLUMN_TOL,
                "{} marker {k} d/d {}: exact {ex:?} vs FD {fd:?} ({e:.2e})",
                c.name(),
                p.kind.name()
            );
        }
        assert_eq!(sens.markers[j][0], [0.0; 3]);
        // The held point: (r(L) - r_c)/L is a residual row, so J dx/dtheta = -d_theta R
        // cancels its partial derivative up to the linear solve's round-off.
        let moved = norm(&sens.markers[j][held]).max(norm(&sens.position[j]));
        println!(
            "{} held tip d/d {}: {moved:.2e} (largest marker {largest:.2e})",
            c.name(),
            p.kind.name()
        );
        assert!(
            moved <= HELD_ROUNDOFF * largest,
            "{}: the held tip moves with {}: {moved:.2e} vs {largest:.2e}",
            c.name(),
            p.kind.name()
        );
        if let TipConstraint::Clamped { .. } = c {
            let turned = sens.rotation[j]
                .iter()
                .flatten()
                .fold(0.0_f64, |a, v| a.max(v.abs()));
            assert!(
                turned * rod.length <= HELD_ROUNDOFF * largest,
                "clamped: the tip turns with {}: {turned:.2e}",
                p.kind.name()
            );
        }
    }
    worst
}

/// The held tip's derivative is round-off of the 6x6 linear solve: about eps cond(J)
/// relative to the partial derivatives it cancels (measured |d tip| / |largest marker
/// derivative|, printed: at most 2e-14 for both constraints and every parameter), so 1e-9
/// leaves a margin of 1e4 for worse-conditioned equilibria; a missing or wrong term of the
/// held residual would move the tip by O(1) of that scale.
const HELD_ROUNDOFF: f64 = 1e-9;

#[test]
fn held_tip_marker_derivatives_match_finite_differences() {
    let spec = m3(tilted());
    let ld = Loads {
        pressures: vec![25e3, 5e3, 15e3],
        ..loads(&[0.0; 3])
    };
    let params = [
        param("c_b", &[1]),
        param("alpha", &[1]),
        param("E", &[0, 2]),
        param("area_scale", &[1]),
        param("density", &[1]),
    ];
    for c in held_tips(&spec, &ld) {
        let worst = check_held_markers(&spec, &ld, &c, &params);
        println!("{}: worst relative marker error {worst:.2e}", c.name());
    }
}

#[test]
fn held_tip_derivatives_differ_from_the_free_tip_and_batch_equals_single() {
    let spec = m3(tilted());
    let rod = Rod::new(spec.clone()).unwrap();
    let ld = Loads {
        pressures: vec![25e3, 5e3, 15e3],
        ..loads(&[0.0; 3])
    };
    let params = [param("E", &[0, 2]), param("area_scale", &[1])];
    let mks = markers(&spec);
    let located = locate_markers(&rod, &mks).unwrap();
    let free = solve(&rod, &ld, None, &opts()).unwrap();
    let free_sens = pose_sensitivity(&rod, &ld, &free, &params, &located).unwrap();
    let mut pressures = vec![];
    for k in 0..3 {
        pressures.extend([25e3 - 5e3 * k as f64, 5e3, 15e3]);
    }
    for c in held_tips(&spec, &ld) {
        // Holding the tip changes a mid-body marker's derivatives by O(1) (not vacuous).
        let sol = solve_constrained(&rod, &ld, &c, None, &opts()).unwrap();
        let s =
            constrained_pose_sensitivity(&rod, &ld, &c, &sol.solution, &params, &located).unwrap();
        let k = 5;
        let change =
            dist(&s.markers[0][k], &free_sens.markers[0][k]) / norm(&free_sens.markers[0][k]);
        println!(
            "{}: holding the tip changes d marker {k} / d E by {change:.2e}",
            c.name()
        );
        assert!(change > 0.1, "{}: changed by {change:.2e} only", c.name());
        // The batch: every row bitwise equal to the single solve and its sensitivities.
        let rows = constrained_sensitivity_batch(
            &rod,
            &BatchInputs::pressures(&rod, &pressures),
            &c,
            None,
            &params,
            &mks,
            &opts(),
            2,
        )
        .unwrap();
        assert_eq!(rows.len(), 3);
        for (r, row) in rows.iter().enumerate() {
            let l = loads(&pressures[3 * r..3 * r + 3]);
            let single = solve_constrained(&rod, &l, &c, None, &opts()).unwrap();
            assert!(row.converged, "row {r}");
            assert_eq!(row.x, single.solution.x, "row {r}");
            assert_eq!(row.tip_reaction_force, single.tip_reaction_force);
            assert_eq!(
                row.markers,
                marker_positions(&rod, &l, &single.solution, &located)
            );
            let ss =
                constrained_pose_sensitivity(&rod, &l, &c, &single.solution, &params, &located)
                    .unwrap();
            assert_eq!(row.sensitivity.as_ref(), Some(&ss), "row {r}");
        }
        // A warm start of the wrong size is refused naming x0.
        match constrained_sensitivity_batch(
            &rod,
            &BatchInputs::pressures(&rod, &pressures),
            &c,
            Some(&[0.0; 9]),
            &params,
            &mks,
            &opts(),
            1,
        ) {
            Err(SoftrodError::InvalidParameter { field, .. }) => assert_eq!(field, "x0"),
            other => panic!("expected an error, got {other:?}"),
        }
    }
    // A free solution (3 unknowns) is refused for a held tip, naming the field.
    match constrained_pose_sensitivity(&rod, &ld, &held_tips(&spec, &ld)[0], &free, &params, &[]) {
        Err(SoftrodError::InvalidParameter { field, .. }) => assert_eq!(field, "solution.x"),
        other => panic!("expected an error, got {other:?}"),
    }
}

/// The held tip's reaction (force and moment, world frame) against central differences of
/// full `solve_constrained` solves (warm-started at the unperturbed solution), for E, the
/// area factor, the body's given mass, c_b and alpha. The reaction is compared in lengths,
/// F L / F_s and M / F_s, so that `marker_error`'s allowance for nearly-zero columns
/// (TIP_NOISE, 1e-14 m) is the solve's own noise, ~1e-13 F_s for this 0.1 m rod; the
/// tolerance is COLUMN_TOL for the same reason as the markers': the solves converge to
/// SOLVER_TOL (round-off ~1e-13 / H = 1e-8 relative) and the step H gives truncation
/// ~H^2 = 1e-10 relative. Measured (printed): at most 2.2e-8 (clamped, mass and c_b) and
/// 5.1e-9 (pinned); a derivative without the shooting unknowns' share (d_x F dx/dtheta)
/// would be off by O(1). A pinned tip's moment and its derivative are zero.
#[test]
fn held_tip_reaction_derivatives_match_finite_differences() {
    let mut spec = m3(tilted());
    // The body's mass given directly, so that "mass" acts (the held tip carries part of its
    // weight).
    spec.sections[1].mass = Some(0.08);
    let rod = Rod::new(spec.clone()).unwrap();
    let ld = Loads {
        pressures: vec![25e3, 5e3, 15e3],
        ..loads(&[0.0; 3])
    };
    let params = [
        param("E", &[0, 2]),
        param("area_scale", &[1]),
        param("mass", &[1]),
        param("c_b", &[1]),
        param("alpha", &[1]),
    ];
    validate_params(&rod, &params).unwrap();
    let to_length = |w: &([f64; 3], [f64; 3])| -> Vec<[f64; 3]> {
        vec![
            w.0.map(|f| f * rod.length / rod.force_scale),
            w.1.map(|m| m / rod.force_scale),
        ]
    };
    for c in held_tips(&spec, &ld) {
        let sol = solve_constrained(&rod, &ld, &c, None, &opts()).unwrap();
        let sens =
            constrained_pose_sensitivity(&rod, &ld, &c, &sol.solution, &params, &[]).unwrap();
        assert_eq!(sens.reaction_force.len(), params.len());
        assert_eq!(sens.reaction_moment.len(), params.len());
        let mut worst: f64 = 0.0;
        for (j, p) in params.iter().enumerate() {
            let (fd, step) = fd_markers(&spec, &ld, &rod, p, |s, l| {
                let r = Rod::new(s.clone()).unwrap();
                let h = solve_constrained(&r, l, &c, Some(&sol.solution.x), &opts()).unwrap();
                to_length(&(h.tip_reaction_force, h.tip_reaction_moment))
            });
            let exact = to_length(&(sens.reaction_force[j], sens.reaction_moment[j]));
            // Not vacuous: every parameter moves the reaction force, by more than 1e-3 F_s
            // per relative change of the parameter (theta dF/dtheta, in lengths).
            let v0 = p.value(&rod, &ld).abs();
            assert!(
                v0 * norm(&exact[0]) > 1e-3 * rod.length,
                "{}: {exact:?}",
                p.kind.name()
            );
            for (what, fd, ex) in [("force", &fd[0], &exact[0]), ("moment", &fd[1], &exact[1])] {
                let e = marker_error(fd, ex, step);
                worst = worst.max(e);
                println!(
                    "{} d reaction {what} / d {}: rel. error {e:.2e}",
                    c.name(),
                    p.kind.name()
                );
                assert!(
                    e < COLUMN_TOL,
                    "{} d reaction {what} / d {}: exact {ex:?} vs FD {fd:?} ({e:.2e})",
                    c.name(),
                    p.kind.name()
                );
            }
            if let TipConstraint::Pinned { .. } = c {
                assert_eq!(sens.reaction_moment[j], [0.0; 3]);
            } else {
                // Not vacuous: the clamp's moment moves too.
                assert!(
                    v0 * norm(&exact[1]) > 1e-4 * rod.length,
                    "{}: {exact:?}",
                    p.kind.name()
                );
            }
        }
        println!("{}: worst relative reaction error {worst:.2e}", c.name());
    }
    // A free tip has no reaction: no derivatives.
    let free = solve(&rod, &ld, None, &opts()).unwrap();
    let s = pose_sensitivity(&rod, &ld, &free, &params, &[]).unwrap();
    assert!(s.reaction_force.is_empty() && s.reaction_moment.is_empty());
}
