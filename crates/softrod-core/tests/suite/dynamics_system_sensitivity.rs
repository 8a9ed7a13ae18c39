//! Forward parameter sensitivities of a system of rods in motion (docs/dynamics.md
//! "Systems of rods"): against central differences of whole system runs (E shared by both
//! rods, one rod's c_b and c_e, the platform's mass, the damping time shared by both rods),
//! a one-rod system on a massless platform against the lone free rod's sensitivities, the
//! start against the static system's derivatives, and the refusals.

use crate::common;

use common::*;
use softrod_core::dynamics::system::{DynRod, SystemSimulator};
use softrod_core::dynamics::{DynOptions, Initial, SigmaMap, Simulator};
use softrod_core::marker::Marker;
use softrod_core::sensitivity::system::{
    locate_system_markers, system_sensitivity, SystemMarker, SystemParam,
};
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::spec::{DesignSpec, MaterialSpec};
use softrod_core::statics::system::{solve_system, Platform, SystemRod};
use softrod_core::statics::SolverOptions;
use softrod_core::{Rod, SoftrodError};
use std::f64::consts::PI;

const L: f64 = 0.1;
const R: f64 = 0.008;
const RING: f64 = 0.03;
const DT: f64 = 5e-3;
const STEPS: usize = 24;

/// The values the derivatives are taken at.
#[derive(Debug, Clone, Copy)]
struct Values {
    e: f64,
    c_b0: f64,
    c_e1: f64,
    mass: f64,
    tau: f64,
}

const BASE: Values = Values {
    e: 1.0e6,
    c_b0: 1.0,
    c_e1: 1.0,
    mass: 0.04,
    tau: 0.02,
};

/// Rod i of two on the ring (one chamber, channel 0), with the values `v`, on 8
/// intervals.
fn rod_spec(i: usize, v: &Values) -> DesignSpec {
    rod_spec_on(i, v, 8)
}

/// [`rod_spec`] on `steps` intervals.
fn rod_spec_on(i: usize, v: &Values, steps: usize) -> DesignSpec {
    let material = MaterialSpec {
        youngs_modulus: v.e,
        shear_modulus: v.e / 3.0,
        density: 1000.0,
    };
    let mut sec = geometry_section(
        "rod",
        L,
        R,
        0.0,
        material,
        vec![chamber(0.002, 0.004, 90.0 * i as f64, 0)],
        steps,
    );
    if i == 0 {
        sec.c_b = v.c_b0;
    } else {
        sec.c_e = v.c_e1;
    }
    let mut spec = design(vec![sec], IDENTITY, 9.81);
    spec.mounting.base_position = attachment(i);
    spec.dynamics.damping_time = v.tau;
    spec
}

fn attachment(i: usize) -> [f64; 3] {
    let a = PI * i as f64;
    [RING * a.cos(), RING * a.sin(), 0.0]
}

/// Commands at t: rod 0 ramps from 10 kPa to 40 kPa over 0.06 s, rod 1 holds 15 kPa.
fn commands(t: f64) -> Vec<Vec<f64>> {
    vec![vec![10e3 + 30e3 * (t / 0.06).min(1.0)], vec![15e3]]
}

fn platform(mass: f64) -> Platform {
    Platform {
        position: [0.0, 0.0, L],
        rotation: IDENTITY,
        force: [0.0; 3],
        moment: [0.0; 3],
        mass,
        com_offset: [2e-3, -1e-3, 3e-3],
        gravity: [0.0, 0.0, -9.81],
    }
}

fn options() -> DynOptions {
    DynOptions {
        dt: DT,
        // Far below the default so that the finite differences are not noise (as the
        // lone rod's test, tests/suite/dynamics_sensitivity.rs): the converged states' error is
        // ~ tol of the unknowns' scales.
        tol: 1e-13,
        ..DynOptions::default()
    }
}

fn markers() -> Vec<SystemMarker> {
    vec![
        SystemMarker::Platform([0.01, 0.02, 0.005]),
        SystemMarker::Rod {
            rod: 0,
            marker: Marker {
                s: 0.055,
                offset: [0.004, 0.0, 0.001],
            },
        },
        SystemMarker::Rod {
            rod: 1,
            marker: Marker {
                s: 0.07,
                offset: [0.0, -0.003, 0.0],
            },
        },
    ]
}

fn system(v: &Values) -> SystemSimulator {
    system_on(v, 8)
}

/// [`system`] with its rods on `steps` intervals.
fn system_on(v: &Values, steps: usize) -> SystemSimulator {
    let rods = (0..2)
        .map(|i| {
            let c = commands(0.0);
            DynRod {
                rod: Rod::new(rod_spec_on(i, v, steps)).unwrap(),
                pressures: c[i].clone(),
                tensions: vec![],
                sigma_map: SigmaMap::None,
                attachment: attachment(i),
                attachment_rotation: IDENTITY,
            }
        })
        .collect();
    let inertia = [[2e-5, 0.0, 0.0], [0.0, 3e-5, 0.0], [0.0, 0.0, 4e-5]];
    SystemSimulator::new(rods, platform(v.mass), inertia, options()).unwrap()
}

/// Everything read after a step: platform position, rotation, markers (flattened).
fn outputs(s: &SystemSimulator) -> Vec<f64> {
    let (p, r) = s.platform_pose();
    let mut out = p.to_vec();
    out.extend(r.iter().flatten());
    out.extend(s.marker_positions().iter().flatten());
    out
}

/// The same outputs' derivatives (`[param][output]`).
fn derivatives(s: &SystemSimulator) -> Vec<Vec<f64>> {
    let dp = s.platform_position_sensitivity().unwrap();
    let dr = s.platform_rotation_sensitivity().unwrap();
    let dm = s.marker_sensitivity().unwrap();
    (0..dp.len())
        .map(|j| {
            let mut out = dp[j].to_vec();
            out.extend(dr[j].iter().flatten());
            out.extend(dm[j].iter().flatten());
            out
        })
        .collect()
}

/// Outputs after every step (and their derivatives where `params` is not empty).
fn run(v: &Values, params: &[SystemParam]) -> (Vec<Vec<f64>>, Vec<Vec<Vec<f64>>>) {
    let mut s = system(v);
    s.set_markers(&markers()).unwrap();
    if !params.is_empty() {
        s.track_sensitivities(params).unwrap();
    }
    let (mut out, mut d) = (vec![], vec![]);
    for k in 1..=STEPS {
        s.step(&commands(k as f64 * DT)).unwrap();
        out.push(outputs(&s));
        if !params.is_empty() {
            d.push(derivatives(&s));
        }
    }
    (out, d)
}

fn rods_param(kind: ParamKind, rods: &[usize]) -> SystemParam {
    let sections = if kind == ParamKind::DampingTime {
        vec![]
    } else {
        vec![0]
    };
    SystemParam::Rods(
        rods.iter()
            .map(|&i| {
                (
                    i,
                    Param {
                        kind,
                        sections: sections.clone(),
                    },
                )
            })
            .collect(),
    )
}

/// Parameter j of `params_of_test` moved by `h`.
fn moved(v: &Values, j: usize, h: f64) -> Values {
    let mut w = *v;
    match j {
        0 => w.e += h,
        1 => w.c_b0 += h,
        2 => w.mass += h,
        3 => w.tau += h,
        4 => w.c_e1 += h,
        _ => unreachable!(),
    }
    w
}

fn params_of_test() -> Vec<(SystemParam, f64)> {
    vec![
        (rods_param(ParamKind::YoungsModulus, &[0, 1]), BASE.e),
        (rods_param(ParamKind::CorrectionFactor(2), &[0]), BASE.c_b0),
        (SystemParam::PlatformMass, BASE.mass),
        (rods_param(ParamKind::DampingTime, &[0, 1]), BASE.tau),
        (rods_param(ParamKind::CorrectionFactor(1), &[1]), BASE.c_e1),
    ]
}

#[test]
fn system_trajectory_sensitivities_match_central_differences() {
    let params = params_of_test();
    let list: Vec<SystemParam> = params.iter().map(|(p, _)| p.clone()).collect();
    let (tracked, exact) = run(&BASE, &list);
    let (plain, _) = run(&BASE, &[]);
    // Tracking does not change the run.
    assert_eq!(tracked, plain);
    for (j, (p, value)) in params.iter().enumerate() {
        // Central differences with a relative step of 1e-4: truncation ~ (1e-4)^2 = 1e-8
        // of the derivative; the converged states' error (tol 1e-13 of the unknowns'
        // scales, ~1e-14 m here) divided by the step (2e-4 of the value) adds ~1e-10 m
        // per unit relative change. The bound, 1e-5 of the largest derivative plus 1e-7 m
        // per unit (per relative change for parameters of more than one unit), leaves
        // two orders of magnitude above both (the lone rod's test's bound and reasoning,
        // tests/suite/dynamics_sensitivity.rs).
        let h = 1e-4 * value;
        let (up, _) = run(&moved(&BASE, j, h), &[]);
        let (down, _) = run(&moved(&BASE, j, -h), &[]);
        let largest = exact
            .iter()
            .flat_map(|d| d[j].iter().map(|x| x.abs()))
            .fold(0.0f64, f64::max);
        let unit = value.abs().max(1.0);
        // A derivative that is zero tests nothing.
        assert!(
            largest * value.abs() > 1e-5,
            "{p:?}: the system does not move ({largest})"
        );
        let mut worst = 0.0f64;
        for (k, d) in exact.iter().enumerate() {
            for (a, dx) in d[j].iter().enumerate() {
                let fd = (up[k][a] - down[k][a]) / (2.0 * h);
                let err = (dx - fd).abs();
                worst = worst.max(err / largest);
                assert!(
                    err <= 1e-5 * largest + 1e-7 / unit,
                    "{p:?} step {k} output {a}: exact {dx} fd {fd} (largest {largest})"
                );
            }
        }
        eprintln!("{p:?}: largest {largest:.3e} per unit, worst error {worst:.1e} of it");
    }
}

/// One rod on a massless platform with no inertia is a free rod (the platform's balance
/// makes the tip reaction vanish): the system's derivatives of the platform (at the tip)
/// and of the rod's nodes equal the lone free rod's, computed by another path (its own
/// step matrix, no platform unknowns).
#[test]
fn one_rod_on_a_massless_platform_matches_the_free_rod() {
    let v = BASE;
    let spec = rod_spec(0, &v);
    let p0 = commands(0.0)[0].clone();
    let mut plat = platform(0.0);
    plat.com_offset = [0.0; 3];
    let rods = vec![DynRod {
        rod: Rod::new(spec.clone()).unwrap(),
        pressures: p0.clone(),
        tensions: vec![],
        sigma_map: SigmaMap::None,
        // The platform's origin at the tip: its position is the tip's.
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    }];
    plat.position = [attachment(0)[0], 0.0, L];
    let mut sys = SystemSimulator::new(rods, plat, [[0.0; 3]; 3], options()).unwrap();
    let mut lone =
        Simulator::new(Rod::new(spec).unwrap(), &p0, Initial::Static, options()).unwrap();
    let rod_params = [
        Param {
            kind: ParamKind::YoungsModulus,
            sections: vec![0],
        },
        Param {
            kind: ParamKind::CorrectionFactor(2),
            sections: vec![0],
        },
        Param {
            kind: ParamKind::DampingTime,
            sections: vec![],
        },
    ];
    let sys_params: Vec<SystemParam> = rod_params
        .iter()
        .map(|p| SystemParam::Rods(vec![(0, p.clone())]))
        .collect();
    sys.track_sensitivities(&sys_params).unwrap();
    lone.track_sensitivities(&rod_params).unwrap();
    let mut worst = 0.0f64;
    for k in 0..=STEPS {
        if k > 0 {
            let c = commands(k as f64 * DT);
            sys.step(&c[..1]).unwrap();
            lone.step(&c[0]).unwrap();
        }
        let dp = sys.platform_position_sensitivity().unwrap();
        let tip = lone.tip_sensitivity().unwrap();
        let shape_sys = sys.rod_shape_sensitivity(0).unwrap();
        let shape_lone = lone.shape_sensitivity().unwrap();
        for j in 0..rod_params.len() {
            let largest = shape_lone[j]
                .iter()
                .flatten()
                .fold(0.0f64, |m, x| m.max(x.abs()));
            let unit = if j == 0 { v.e } else { 1.0 };
            // The two solve the same discrete equations to Newton's tol (1e-13 of the
            // scaled unknowns). Both refine their derivatives with a kept Newton matrix
            // to 1.33e-9 of their size per step (REFINE_TOL with the contraction held
            // <= 1/4, `dynamics::sensitivity` and `dynamics::system`), an error the
            // histories carry on: at most 2 x STEPS x 1.33e-9 after STEPS steps, doubled
            // for the scaled unknowns' size against the positions', plus round-off of
            // the derivative's own terms (1e-12 m per unit relative change).
            let bound = 4.0 * 1.33e-9 * STEPS as f64 * largest + 1e-12 / unit;
            for (a, b) in shape_sys[j]
                .iter()
                .zip(&shape_lone[j])
                .chain([(&dp[j], &tip[j])])
            {
                for c in 0..3 {
                    let err = (a[c] - b[c]).abs();
                    worst = worst.max(err / largest.max(1e-300));
                    assert!(
                        err <= bound,
                        "step {k} param {j}: system {a:?} lone {b:?} (largest {largest})"
                    );
                }
            }
        }
    }
    eprintln!("one rod vs free rod: worst {worst:.1e} of the largest derivative");
}

/// The start's derivatives against the static system's (`system_sensitivity`, shooting)
/// on `steps` intervals: the largest difference relative to each parameter's largest
/// derivative, and the system with its sensitivities tracked.
fn start_against_statics(steps: usize, params: &[SystemParam]) -> (f64, SystemSimulator) {
    let v = BASE;
    let mut s = system_on(&v, steps);
    s.set_markers(&markers()).unwrap();
    s.track_sensitivities(params).unwrap();
    let start = derivatives(&s);
    let specs: Vec<Rod> = (0..2)
        .map(|i| Rod::new(rod_spec_on(i, &v, steps)).unwrap())
        .collect();
    let c = commands(0.0);
    let sys: Vec<SystemRod> = specs
        .iter()
        .enumerate()
        .map(|(i, rod)| SystemRod {
            rod,
            loads: loads(&c[i]),
            attachment: attachment(i),
            attachment_rotation: IDENTITY,
        })
        .collect();
    let plat = platform(v.mass);
    let sol = solve_system(&sys, &plat, None, &SolverOptions::default()).unwrap();
    let at = locate_system_markers(&sys, &markers()).unwrap();
    let st = system_sensitivity(&sys, &plat, &sol, params, &at).unwrap();
    let mut worst = 0.0f64;
    for (j, d) in start.iter().enumerate() {
        let mut stat = st.platform_position[j].to_vec();
        stat.extend(st.platform_rotation[j].iter().flatten());
        stat.extend(st.markers[j].iter().flatten());
        let largest = stat.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in d.iter().zip(&stat) {
            worst = worst.max((x - y).abs() / largest);
        }
    }
    (worst, s)
}

/// The start is the static equilibrium: its derivatives are the static system's
/// (`system_sensitivity`, shooting on another discretisation of the same rods), and a step
/// under constant inputs stays at rest with the same derivatives.
#[test]
fn the_start_is_the_static_systems_derivative() {
    let params: Vec<SystemParam> = params_of_test()
        .into_iter()
        .map(|(p, _)| p)
        .filter(|p| !matches!(p, SystemParam::Rods(e) if e[0].1.kind == ParamKind::DampingTime))
        .collect();
    // Collocation (Gauss, two stages) and shooting (RK4) are both fourth order: the
    // difference of their derivatives falls by 2^4 = 16 when the intervals halve. At
    // least 8 (third order) leaves room for the pre-asymptotic constants; a wrong
    // derivative (a missing term) would not fall at all.
    let (coarse, _) = start_against_statics(8, &params);
    let (fine, mut s) = start_against_statics(16, &params);
    eprintln!("start against statics: {coarse:.1e} (8 intervals), {fine:.1e} (16)");
    assert!(fine <= coarse / 8.0, "{coarse:.3e} -> {fine:.3e}");
    let start = derivatives(&s);
    // Constant inputs: the first step stays at rest, and so do the derivatives: the step's
    // are refined from the start's to 1.33e-9 of their size (the refinement's tolerance),
    // doubled for the scaled unknowns' size against the outputs'.
    s.step(&commands(0.0)).unwrap();
    let first = derivatives(&s);
    for (j, (a, b)) in first.iter().zip(&start).enumerate() {
        let largest = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!(
                (x - y).abs() <= 2.0 * 1.33e-9 * largest,
                "param {j}: after one step at rest {x}, at the start {y}"
            );
        }
    }
}

fn invalid_field(e: SoftrodError) -> String {
    match e {
        SoftrodError::InvalidParameter { field, .. } => field,
        other => panic!("not an invalid parameter: {other:?}"),
    }
}

#[test]
fn refusals_name_the_field() {
    let v = BASE;
    let e = rods_param(ParamKind::YoungsModulus, &[0, 1]);
    // A rod that does not exist, a rod twice, two kinds, two values.
    let mut s = system(&v);
    let bad = SystemParam::Rods(vec![(
        2,
        Param {
            kind: ParamKind::YoungsModulus,
            sections: vec![0],
        },
    )]);
    assert_eq!(
        invalid_field(s.track_sensitivities(&[e.clone(), bad]).unwrap_err()),
        "params[1].rods[0]"
    );
    let twice = rods_param(ParamKind::YoungsModulus, &[0, 0]);
    assert_eq!(
        invalid_field(s.track_sensitivities(&[twice]).unwrap_err()),
        "params[0].rods[1]"
    );
    let mixed = SystemParam::Rods(vec![
        (
            0,
            Param {
                kind: ParamKind::YoungsModulus,
                sections: vec![0],
            },
        ),
        (
            1,
            Param {
                kind: ParamKind::CorrectionFactor(2),
                sections: vec![0],
            },
        ),
    ]);
    assert_eq!(
        invalid_field(s.track_sensitivities(&[mixed]).unwrap_err()),
        "params[0].rods[1]"
    );
    let sigma = rods_param(ParamKind::StiffnessScale(0), &[0]);
    let f = invalid_field(s.track_sensitivities(&[sigma]).unwrap_err());
    assert!(
        f.starts_with("params[0]") && f.ends_with("of rods[0]"),
        "{f}"
    );
    // Two values of one parameter.
    let mut w = v;
    w.tau = 0.03;
    let rods: Vec<DynRod> = (0..2)
        .map(|i| DynRod {
            rod: Rod::new(rod_spec(i, if i == 0 { &v } else { &w })).unwrap(),
            pressures: commands(0.0)[i].clone(),
            tensions: vec![],
            sigma_map: SigmaMap::None,
            attachment: attachment(i),
            attachment_rotation: IDENTITY,
        })
        .collect();
    let mut two = SystemSimulator::new(rods, platform(v.mass), [[0.0; 3]; 3], options()).unwrap();
    let tau = rods_param(ParamKind::DampingTime, &[0, 1]);
    let f = invalid_field(two.track_sensitivities(&[tau]).unwrap_err());
    assert_eq!(f, "params[0] (damping_time) of rods[1]");
    // Adaptive steps.
    let rods: Vec<DynRod> = (0..2)
        .map(|i| DynRod {
            rod: Rod::new(rod_spec(i, &v)).unwrap(),
            pressures: commands(0.0)[i].clone(),
            tensions: vec![],
            sigma_map: SigmaMap::None,
            attachment: attachment(i),
            attachment_rotation: IDENTITY,
        })
        .collect();
    let adaptive = DynOptions {
        error_tol: Some(1e-4),
        ..options()
    };
    let mut a = SystemSimulator::new(rods, platform(v.mass), [[0.0; 3]; 3], adaptive).unwrap();
    assert_eq!(
        invalid_field(a.track_sensitivities(std::slice::from_ref(&e)).unwrap_err()),
        "error_tol"
    );
    // After the first step; markers after tracking.
    s.step(&commands(DT)).unwrap();
    assert_eq!(
        invalid_field(s.track_sensitivities(std::slice::from_ref(&e)).unwrap_err()),
        "track_sensitivities"
    );
    let mut t = system(&v);
    t.track_sensitivities(&[e]).unwrap();
    assert_eq!(
        invalid_field(t.set_markers(&markers()).unwrap_err()),
        "markers"
    );
    // A restored state tracks none.
    let saved = t.save();
    t.restore(&saved).unwrap();
    assert!(t.platform_position_sensitivity().is_none());
    // A marker on a rod that does not exist.
    let mut u = system(&v);
    let bad = [SystemMarker::Rod {
        rod: 5,
        marker: Marker {
            s: 0.01,
            offset: [0.0; 3],
        },
    }];
    assert_eq!(
        invalid_field(u.set_markers(&bad).unwrap_err()),
        "markers[0].rod"
    );
}
