//! Exact parameter derivatives of the PCC model (softrod_core::pcc::sensitivity) against
//! central finite differences of whole solves with the parameter changed in the design:
//! equilibria, and whole time series (step responses and free decays) through the implicit
//! midpoint steps; spatial, planar and two-segment chains, constant and tabulated k_theta;
//! markers on the chain; batches against single runs; parameter validation.

use crate::common;

use common::{chamber, design, direct_section, rigid_section, IDENTITY};
use softrod_core::pcc::sensitivity::{
    locate_markers, simulate_sensitivity_batch, statics_sensitivity_batch, validate_params,
    PccMarker, PccParam, PccRun,
};
use softrod_core::pcc::{InitialState, PccModel, PccSpec, PccTable, StepOptions};
use softrod_core::spec::DesignSpec;
use softrod_core::SoftrodError;

/// Newton tolerance of the finite-difference runs: far below what the differences resolve.
fn opts() -> StepOptions {
    StepOptions {
        tol: 1e-13,
        max_iter: 50,
    }
}

/// Relative parameter step of the central differences: truncation ~h^2 (1e-10 relative),
/// solve error 1e-13 / 1e-5 = 1e-8.
const H: f64 = 1e-5;
/// Agreement of exact and finite-difference derivatives relative to the largest entry of
/// the derivative (over the points and, for time series, the whole run). Measured: below
/// 1e-7; a missing term (the damping's velocity, the inertia of the step, the table's
/// interpolation weight) is off by percent.
const TOL: f64 = 1e-6;

fn spec(table: bool, planar: bool) -> PccSpec {
    PccSpec {
        k_l: Some(220.0),
        b_l: Some(6.0),
        k_theta: if table { None } else { Some(0.05) },
        k_theta_table: table.then(|| PccTable {
            angle: vec![0.0, 0.3, 0.8, 1.5],
            stiffness: vec![0.05, 0.045, 0.04, 0.042],
        }),
        b_theta: Some(4e-4),
        k_phi: Some(0.004),
        b_phi: Some(1e-4),
        plane: planar.then_some(0.4),
        ..Default::default()
    }
}

/// One 110 mm segment with three chambers and a rigid cap with a tip body, upright.
fn arm(table: bool, planar: bool) -> DesignSpec {
    let mut body = direct_section("body", 0.11, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.06, 16);
    body.chambers = vec![
        chamber(2.5e-3, 7e-3, 0.0, 0),
        chamber(2.5e-3, 7e-3, 120.0, 1),
        chamber(2.5e-3, 7e-3, 240.0, 2),
    ];
    let mut d = design(vec![body, rigid_section("cap", 0.01, 0.01)], IDENTITY, 9.81);
    d.tip.mass = 0.02;
    d.tip.com_offset = [0.002, 0.0, 0.005];
    d.pcc = Some(spec(table, planar));
    d
}

fn two_segments() -> DesignSpec {
    let mut a = direct_section("m1", 0.05, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.03, 16);
    a.chambers = vec![
        chamber(2.5e-3, 7e-3, 0.0, 0),
        chamber(2.5e-3, 7e-3, 180.0, 1),
    ];
    let mut b = direct_section("m2", 0.06, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.03, 16);
    b.chambers = vec![chamber(2.5e-3, 7e-3, 90.0, 2)];
    let mut d = design(
        vec![a, rigid_section("joint", 0.008, 0.005), b],
        IDENTITY,
        9.81,
    );
    d.tip.mass = 0.01;
    d.pcc = Some(spec(false, false));
    d
}

fn set(d: &DesignSpec, p: PccParam, v: f64) -> DesignSpec {
    let mut d = d.clone();
    let s = d.pcc.as_mut().unwrap();
    match p {
        PccParam::KL => s.k_l = Some(v),
        PccParam::BL => s.b_l = Some(v),
        PccParam::KTheta => s.k_theta = Some(v),
        PccParam::KThetaNode(j) => s.k_theta_table.as_mut().unwrap().stiffness[j] = v,
        PccParam::BTheta => s.b_theta = Some(v),
        PccParam::KPhi => s.k_phi = Some(v),
        PccParam::BPhi => s.b_phi = Some(v),
    }
    d
}

fn value(d: &DesignSpec, p: PccParam) -> f64 {
    let s = d.pcc.as_ref().unwrap();
    match p {
        PccParam::KL => s.k_l.unwrap(),
        PccParam::BL => s.b_l.unwrap(),
        PccParam::KTheta => s.k_theta.unwrap(),
        PccParam::KThetaNode(j) => s.k_theta_table.as_ref().unwrap().stiffness[j],
        PccParam::BTheta => s.b_theta.unwrap(),
        PccParam::KPhi => s.k_phi.unwrap(),
        PccParam::BPhi => s.b_phi.unwrap(),
    }
}

fn markers() -> Vec<PccMarker> {
    vec![
        PccMarker {
            s: 0.0,
            offset: [0.0; 3],
        },
        PccMarker {
            s: 0.04,
            offset: [0.01, 0.0, 0.0],
        },
        PccMarker {
            s: 0.11,
            offset: [0.0, -0.008, 0.002],
        },
        PccMarker {
            s: 0.115,
            offset: [0.0, 0.0, 0.0],
        },
    ]
}

/// Largest |exact - FD| over all entries relative to the largest |FD|.
fn worst(exact: &[[f64; 3]], fd: &[[f64; 3]]) -> f64 {
    let scale = fd.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    let err = exact
        .iter()
        .flatten()
        .zip(fd.iter().flatten())
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    err / scale.max(1e-300)
}

fn check_statics(d: &DesignSpec, pressures: &[f64], params: &[PccParam]) {
    let m = PccModel::new(d).unwrap();
    let mk = markers();
    let located = locate_markers(&m, &mk).unwrap();
    let at = |model: &PccModel| {
        model
            .statics_sensitivity(pressures, None, params, &located, &opts())
            .unwrap()
    };
    let base = at(&m);
    for (j, &p) in params.iter().enumerate() {
        if matches!(p, PccParam::BL | PccParam::BTheta | PccParam::BPhi) {
            // Damping does nothing at rest.
            assert!(base.at.d_points.iter().all(|d| d[j] == [0.0; 3]));
            continue;
        }
        let v0 = value(d, p);
        let step = H * v0;
        let plus = at(&PccModel::new(&set(d, p, v0 + step)).unwrap()).at.points;
        let minus = at(&PccModel::new(&set(d, p, v0 - step)).unwrap()).at.points;
        let fd: Vec<[f64; 3]> = plus
            .iter()
            .zip(&minus)
            .map(|(a, b)| std::array::from_fn(|k| (a[k] - b[k]) / (2.0 * step)))
            .collect();
        let exact: Vec<[f64; 3]> = base.at.d_points.iter().map(|d| d[j]).collect();
        let e = worst(&exact, &fd);
        println!("statics d/d {}: {e:.2e}", p.name());
        assert!(
            e < TOL,
            "statics d/d {}: {e:.2e}\n{exact:?}\n{fd:?}",
            p.name()
        );
    }
}

#[test]
fn statics_derivatives_match_finite_differences() {
    let all = [
        PccParam::KL,
        PccParam::KTheta,
        PccParam::KPhi,
        PccParam::BL,
        PccParam::BTheta,
    ];
    check_statics(&arm(false, false), &[40e3, 10e3, 0.0], &all);
    check_statics(&arm(false, true), &[30e3, 0.0, 5e3], &all);
    check_statics(
        &arm(true, false),
        &[60e3, 0.0, 0.0],
        &[
            PccParam::KL,
            PccParam::KThetaNode(1),
            PccParam::KThetaNode(2),
        ],
    );
    check_statics(
        &two_segments(),
        &[20e3, 0.0, 15e3],
        &[PccParam::KL, PccParam::KTheta],
    );
}

fn check_run(
    d: &DesignSpec,
    initial: InitialState,
    commands: &dyn Fn(f64) -> [f64; 3],
    params: &[PccParam],
) {
    let m = PccModel::new(d).unwrap();
    let dt = 1e-3;
    let n = 300; // 0.3 s: a step's rise and a decay's first swings
    let pressures: Vec<f64> = (0..=n).flat_map(|k| commands(k as f64 * dt)).collect();
    let mk = markers();
    let located = locate_markers(&m, &mk).unwrap();
    let run = |model: &PccModel| {
        model
            .simulate_sensitivity(dt, &pressures, &initial, params, &located, 10, &opts())
            .unwrap()
    };
    let base = run(&m);
    assert_eq!(base.time.len(), n / 10 + 1);
    for (j, &p) in params.iter().enumerate() {
        let v0 = value(d, p);
        let step = H * v0;
        let plus = run(&PccModel::new(&set(d, p, v0 + step)).unwrap());
        let minus = run(&PccModel::new(&set(d, p, v0 - step)).unwrap());
        let (mut exact, mut fd) = (vec![], vec![]);
        for k in 0..base.time.len() {
            for i in 0..base.at[k].points.len() {
                exact.push(base.at[k].d_points[i][j]);
                let (a, b) = (plus.at[k].points[i], minus.at[k].points[i]);
                fd.push(std::array::from_fn(|c| (a[c] - b[c]) / (2.0 * step)));
            }
        }
        let e = worst(&exact, &fd);
        println!("run d/d {}: {e:.2e}", p.name());
        assert!(e < TOL, "run d/d {}: {e:.2e}", p.name());
    }
}

#[test]
fn time_series_derivatives_match_finite_differences_of_whole_runs() {
    let all = [
        PccParam::KL,
        PccParam::BL,
        PccParam::KTheta,
        PccParam::BTheta,
        PccParam::KPhi,
        PccParam::BPhi,
    ];
    // A step on one side from rest (elongation and bending move together).
    let step = |t: f64| if t > 0.0 { [40e3, 15e3, 0.0] } else { [0.0; 3] };
    check_run(&arm(false, false), InitialState::Rest, &step, &all);
    // A free decay: released from the equilibrium under pressure.
    let release = |t: f64| if t > 0.0 { [0.0; 3] } else { [30e3, 0.0, 10e3] };
    check_run(&arm(false, false), InitialState::Static, &release, &all);
    check_run(&arm(false, true), InitialState::Static, &release, &all);
    check_run(
        &arm(true, false),
        InitialState::Static,
        &release,
        &[
            PccParam::KThetaNode(0),
            PccParam::KThetaNode(1),
            PccParam::BTheta,
        ],
    );
    let ramp = |t: f64| [20e3 * (t / 0.1).min(1.0), 0.0, 12e3];
    check_run(
        &two_segments(),
        InitialState::Rest,
        &ramp,
        &[PccParam::KL, PccParam::BTheta],
    );
}

#[test]
fn batches_equal_single_runs() {
    let d = arm(false, false);
    let m = PccModel::new(&d).unwrap();
    let params = [PccParam::KL, PccParam::KTheta, PccParam::BTheta];
    let mk = markers();
    let located = locate_markers(&m, &mk).unwrap();
    let rows: Vec<f64> = (0..5).flat_map(|k| [8e3 * k as f64, 3e3, 0.0]).collect();
    let batch = statics_sensitivity_batch(&m, &rows, None, &params, &mk, &opts(), 2).unwrap();
    for (r, row) in batch.iter().enumerate() {
        let single = m
            .statics_sensitivity(&rows[3 * r..3 * r + 3], None, &params, &located, &opts())
            .unwrap();
        assert_eq!(row.as_ref().unwrap(), &single);
    }
    let runs: Vec<PccRun> = (0..3)
        .map(|k| PccRun {
            dt: 1e-3,
            pressures: (0..=100)
                .flat_map(|_| [10e3 * (k + 1) as f64, 0.0, 0.0])
                .collect(),
            initial: InitialState::Rest,
            save_every: 5,
        })
        .collect();
    let out = simulate_sensitivity_batch(&m, &runs, &params, &mk, &opts(), 2).unwrap();
    for (run, got) in runs.iter().zip(&out) {
        let single = m
            .simulate_sensitivity(
                run.dt,
                &run.pressures,
                &run.initial,
                &params,
                &located,
                5,
                &opts(),
            )
            .unwrap();
        assert_eq!(got.as_ref().unwrap(), &single);
    }
}

#[test]
fn parameters_and_markers_are_validated() {
    let m = PccModel::new(&arm(false, false)).unwrap();
    let rule = |p: PccParam| match validate_params(&m, &[p]) {
        Err(SoftrodError::InvalidParameter { field, rule, .. }) => format!("{field} | {rule}"),
        other => panic!("expected an error, got {other:?}"),
    };
    assert!(rule(PccParam::KThetaNode(0)).contains("calibrate k_theta"));
    let t = PccModel::new(&arm(true, false)).unwrap();
    assert!(matches!(
        validate_params(&t, &[PccParam::KTheta]),
        Err(SoftrodError::InvalidParameter { rule, .. }) if rule.contains("k_theta[j]")
    ));
    assert!(matches!(
        validate_params(&t, &[PccParam::KThetaNode(9)]),
        Err(SoftrodError::InvalidParameter { rule, .. }) if rule.contains("4 entries")
    ));
    assert_eq!(PccParam::parse("k_theta[3]"), Some(PccParam::KThetaNode(3)));
    assert_eq!(PccParam::parse("k_theta[x]"), None);
    assert!(locate_markers(
        &m,
        &[PccMarker {
            s: 0.5,
            offset: [0.0; 3]
        }]
    )
    .is_err());
    assert!(locate_markers(
        &m,
        &[PccMarker {
            s: -0.1,
            offset: [0.0; 3]
        }]
    )
    .is_err());
}
