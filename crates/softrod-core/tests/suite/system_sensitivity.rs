//! Exact parameter derivatives of a system's equilibrium (`sensitivity::system`): the
//! platform's pose and markers on the platform and on the rods against central finite
//! differences of full system solves with the parameter changed in the designs; a one-rod
//! system against the lone free rod's derivatives (an independent code path); the batch
//! against single solves; refusals by name. And the derivatives with respect to the
//! system's inputs (`jacobian::system`): the platform's pose and the rods' base wrenches
//! against central differences and a one-rod system against the lone rod's tip Jacobian.

use crate::common;
use common::*;
use softrod_core::batch::{system_sensitivity_batch, SystemBatchInputs};
use softrod_core::jacobian::system::{system_jacobian, SystemInput};
use softrod_core::jacobian::{point_jacobian, Input, Probe};
use softrod_core::marker::Marker;
use softrod_core::ode::Loads;
use softrod_core::sensitivity::system::{
    locate_system_markers, system_marker_positions, system_sensitivity, validate_system_params,
    SystemMarker, SystemParam,
};
use softrod_core::sensitivity::{tip_sensitivity, Param, ParamKind};
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::DesignSpec;
use softrod_core::statics::system::{solve_system, Platform, SystemRod, SystemSolution};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

/// Newton tolerance of the finite-difference solves: the solution error (~1e-13 of the
/// scaled unknowns) over the step below stays near 1e-8 of a derivative.
const SOLVER_TOL: f64 = 1e-13;
/// Relative parameter step of the central differences (truncation ~1e-10 relative for
/// these smooth laws; solve error / step ~1e-8 relative).
const H: f64 = 1e-5;
/// Column-wise agreement relative to the column's norm, as for the lone rod
/// (tests/suite/sensitivity.rs): a derivative missing a term (the platform's weight, a rod's
/// share of the balance, the marker's own d_theta) is off by percent or more.
const COLUMN_TOL: f64 = 1e-6;
/// Plus an absolute allowance for nearly zero columns: two solves agree to ~1e-14 m,
/// divided by the 2 h step.
const NOISE: f64 = 1e-14;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: SOLVER_TOL,
        ..Default::default()
    }
}

const HANGING: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
/// Half the distance between the two bases and between the two attachments, m.
const GAP: f64 = 0.02;

/// Paper 002's actuator hanging at x = `x`.
fn hanging_at(x: f64) -> DesignSpec {
    let mut d = p002_actuator(HANGING, 9.81, 10);
    d.mounting.base_position = [x, 0.0, 0.0];
    d
}

/// A platform hung from two of paper 002's actuators, 5 g with its centre of mass off its
/// origin, under a small side force.
fn platform() -> Platform {
    Platform {
        position: [0.0, 0.0, -0.134],
        rotation: HANGING,
        force: [4e-3, -2e-3, 0.0],
        moment: [0.0; 3],
        mass: 5e-3,
        com_offset: [3e-3, 1e-3, 2e-3],
        gravity: [0.0, 0.0, -9.81],
    }
}

fn rods<'a>(r0: &'a Rod, r1: &'a Rod, loads: [&Loads; 2]) -> Vec<SystemRod<'a>> {
    vec![
        SystemRod {
            rod: r0,
            loads: loads[0].clone(),
            attachment: [-GAP, 0.0, 0.0],
            attachment_rotation: IDENTITY,
        },
        SystemRod {
            rod: r1,
            loads: loads[1].clone(),
            attachment: [GAP, 0.0, 0.0],
            attachment_rotation: IDENTITY,
        },
    ]
}

fn markers() -> Vec<SystemMarker> {
    vec![
        SystemMarker::Platform([5e-3, 3e-3, 2e-3]),
        SystemMarker::Rod {
            rod: 0,
            marker: Marker {
                s: 0.06,
                offset: [12e-3, 0.0, 0.0],
            },
        },
        SystemMarker::Rod {
            rod: 1,
            marker: Marker {
                s: 0.134,
                offset: [0.0, 5e-3, 1e-3],
            },
        },
    ]
}

/// Everything a finite difference reads of a solved system: the platform position, its
/// rotation and the markers, flattened.
fn outputs(sol: &SystemSolution, rods: &[SystemRod], mk: &[SystemMarker]) -> Vec<f64> {
    let at = locate_system_markers(rods, mk).unwrap();
    let mut out = sol.platform_position.to_vec();
    out.extend(sol.platform_rotation.iter().flatten());
    for m in system_marker_positions(rods, sol, &at).unwrap() {
        out.extend(m);
    }
    out
}

/// Change system parameter `p` to `v` in the two designs (or the platform).
fn changed(
    specs: &mut [DesignSpec; 2],
    lds: &mut [Loads; 2],
    pf: &mut Platform,
    p: &SystemParam,
    v: f64,
) {
    match p {
        SystemParam::PlatformMass => pf.mass = v,
        SystemParam::Rods(entries) => {
            for (i, param) in entries {
                set_param(&mut specs[*i], &mut lds[*i], param, v);
            }
        }
    }
}

#[test]
fn system_derivatives_match_central_differences() {
    let specs = [hanging_at(-GAP), hanging_at(GAP)];
    let lds = [loads(&[20e3, 0.0, 0.0]), loads(&[0.0, 15e3, 5e3])];
    let (r0, r1) = (
        Rod::new(specs[0].clone()).unwrap(),
        Rod::new(specs[1].clone()).unwrap(),
    );
    let pf = platform();
    let system = rods(&r0, &r1, [&lds[0], &lds[1]]);
    let params = vec![
        // The body's Young's modulus, shared by both rods.
        SystemParam::Rods(vec![(0, param("E", &[1])), (1, param("E", &[1]))]),
        SystemParam::Rods(vec![(1, param("c_b", &[1]))]),
        SystemParam::PlatformMass,
        SystemParam::Rods(vec![
            (0, param("density", &[0, 2])),
            (1, param("density", &[0, 2])),
        ]),
        SystemParam::Rods(vec![(0, param("offset_1", &[1]))]),
        SystemParam::Rods(vec![(0, param("c_e", &[1])), (1, param("c_e", &[1]))]),
    ];
    validate_system_params(&system, &params).unwrap();
    let mk = markers();
    let at = locate_system_markers(&system, &mk).unwrap();
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let sens = system_sensitivity(&system, &pf, &sol, &params, &at).unwrap();
    let value = |p: &SystemParam| match p {
        SystemParam::PlatformMass => pf.mass,
        SystemParam::Rods(e) => e[0].1.value(system[e[0].0].rod, &system[e[0].0].loads),
    };
    let mut worst: f64 = 0.0;
    for (j, p) in params.iter().enumerate() {
        let v0 = value(p);
        let step = match p {
            SystemParam::Rods(e) if matches!(e[0].1.kind, ParamKind::ChamberOffset(_)) => 1e-8,
            _ => H * v0.abs(),
        };
        let at_value = |v: f64| {
            let (mut s, mut l, mut f) = (specs.clone(), lds.clone(), pf);
            changed(&mut s, &mut l, &mut f, p, v);
            let (a, b) = (
                Rod::new(s[0].clone()).unwrap(),
                Rod::new(s[1].clone()).unwrap(),
            );
            let sys = rods(&a, &b, [&l[0], &l[1]]);
            let out = solve_system(&sys, &f, Some(&sol.x), &opts()).unwrap();
            outputs(&out, &sys, &mk)
        };
        let (hi, lo) = (at_value(v0 + step), at_value(v0 - step));
        let fd: Vec<f64> = hi
            .iter()
            .zip(&lo)
            .map(|(a, b)| (a - b) / (2.0 * step))
            .collect();
        let mut exact = sens.platform_position[j].to_vec();
        exact.extend(sens.platform_rotation[j].iter().flatten());
        for m in &sens.markers[j] {
            exact.extend(m);
        }
        for (what, range) in [
            ("platform position", 0..3),
            ("platform rotation", 3..12),
            ("platform marker", 12..15),
            ("rod 0 marker", 15..18),
            ("rod 1 marker", 18..21),
        ] {
            let (f, e) = (&fd[range.clone()], &exact[range]);
            let n = f.iter().map(|x| x * x).sum::<f64>().sqrt();
            let err = f
                .iter()
                .zip(e)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
                / (n + NOISE / (COLUMN_TOL * step));
            println!("d {what} / d params[{j}]: |fd| {n:.3e}, rel. error {err:.2e}");
            worst = worst.max(err);
        }
    }
    assert!(
        worst < COLUMN_TOL,
        "worst relative column error {worst:.2e}"
    );
}

/// A one-rod system whose platform is massless and sits on the tip is the lone free rod
/// with the platform's load as its tip load: its platform derivatives are the free rod's
/// tip derivatives (`sensitivity::tip_sensitivity`, another residual and Jacobian).
#[test]
fn one_rod_system_derivatives_equal_the_free_rods() {
    let spec = hanging_at(0.0);
    let rod = Rod::new(spec).unwrap();
    let force = [3e-3, 1e-3, -5e-3];
    let mut free_loads = loads(&[18e3, 4e3, 0.0]);
    free_loads.tip_force = force;
    let free = solve(&rod, &free_loads, None, &opts()).unwrap();
    let params = [
        param("E", &[1]),
        param("c_b", &[1]),
        param("density", &[0, 2]),
    ];
    let lone = tip_sensitivity(&rod, &free_loads, &free, &params).unwrap();

    let pf = Platform {
        position: free.tip.r,
        rotation: free.tip.rot,
        force,
        moment: [0.0; 3],
        mass: 0.0,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -9.81],
    };
    let system = vec![SystemRod {
        rod: &rod,
        loads: loads(&[18e3, 4e3, 0.0]),
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    }];
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let sys_params: Vec<SystemParam> = params
        .iter()
        .map(|p| SystemParam::Rods(vec![(0, p.clone())]))
        .collect();
    let sens = system_sensitivity(&system, &pf, &sol, &sys_params, &[]).unwrap();
    for j in 0..params.len() {
        let scale = lone.position[j].iter().map(|v| v * v).sum::<f64>().sqrt();
        for i in 0..3 {
            // Both are exact derivatives of the same equilibrium, each solved to 1e-13 of
            // its scaled unknowns: they agree to round-off amplified by the conditioning of
            // two different Jacobians, far below 1e-9 of the column.
            let d = (sens.platform_position[j][i] - lone.position[j][i]).abs();
            assert!(
                d < 1e-9 * scale,
                "params[{j}] position[{i}]: {d:.2e} of {scale:.2e}"
            );
            for k in 0..3 {
                let d = (sens.platform_rotation[j][i][k] - lone.rotation[j][i][k]).abs();
                assert!(
                    d < 1e-9 * scale / rod.length,
                    "params[{j}] rotation[{i}][{k}]: {d:.2e}"
                );
            }
        }
    }
}

#[test]
fn system_batch_rows_are_the_single_solves() {
    let specs = [hanging_at(-GAP), hanging_at(GAP)];
    let (r0, r1) = (
        Rod::new(specs[0].clone()).unwrap(),
        Rod::new(specs[1].clone()).unwrap(),
    );
    let pf = platform();
    let base = loads(&[0.0; 3]);
    let system = rods(&r0, &r1, [&base, &base]);
    let pressures: Vec<f64> = vec![
        10e3, 0.0, 0.0, 0.0, 5e3, 0.0, //
        0.0, 20e3, 0.0, 8e3, 0.0, 0.0, //
        15e3, 15e3, 0.0, 0.0, 0.0, 12e3,
    ];
    let inputs = SystemBatchInputs {
        pressures: &pressures,
        tensions: None,
        stiffness_scale: None,
    };
    let params = vec![
        SystemParam::Rods(vec![(0, param("E", &[1])), (1, param("E", &[1]))]),
        SystemParam::PlatformMass,
    ];
    let mk = markers();
    let at = locate_system_markers(&system, &mk).unwrap();
    for threads in [1, 2] {
        let rows =
            system_sensitivity_batch(&system, &pf, &inputs, None, &params, &mk, &opts(), threads)
                .unwrap();
        // Warm starts from the first pass reproduce the warm single solves.
        let x0: Vec<f64> = rows.iter().flat_map(|r| r.x.clone()).collect();
        let warm = system_sensitivity_batch(
            &system,
            &pf,
            &inputs,
            Some(&x0),
            &params,
            &mk,
            &opts(),
            threads,
        )
        .unwrap();
        for (r, (row, wrow)) in rows.iter().zip(&warm).enumerate() {
            let one = |guess: Option<&[f64]>| {
                let l0 = loads(&pressures[6 * r..6 * r + 3]);
                let l1 = loads(&pressures[6 * r + 3..6 * r + 6]);
                let sys = rods(&r0, &r1, [&l0, &l1]);
                let sol = solve_system(&sys, &pf, guess, &opts()).unwrap();
                let sens = system_sensitivity(&sys, &pf, &sol, &params, &at).unwrap();
                let pos = system_marker_positions(&sys, &sol, &at).unwrap();
                (sol, sens, pos)
            };
            for (got, guess) in [(row, None), (wrow, Some(&x0[r * 18..(r + 1) * 18]))] {
                let (sol, sens, pos) = one(guess);
                assert!(got.converged);
                assert_eq!(got.x, sol.x, "row {r}: bitwise the single solve");
                assert_eq!(got.platform_position, sol.platform_position);
                assert_eq!(got.markers, pos);
                assert_eq!(got.sensitivity.as_ref(), Some(&sens));
            }
        }
    }
}

#[test]
fn bad_system_parameters_and_markers_are_refused_by_name() {
    let specs = [hanging_at(-GAP), hanging_at(GAP)];
    let (r0, r1) = (
        Rod::new(specs[0].clone()).unwrap(),
        Rod::new(specs[1].clone()).unwrap(),
    );
    let base = loads(&[0.0; 3]);
    let system = rods(&r0, &r1, [&base, &base]);
    let field = |e: SoftrodError| match e {
        SoftrodError::InvalidParameter { field, .. } => field,
        other => panic!("{other:?}"),
    };
    let refused =
        |params: Vec<SystemParam>| field(validate_system_params(&system, &params).unwrap_err());
    assert_eq!(refused(vec![SystemParam::Rods(vec![])]), "params[0]");
    assert_eq!(
        refused(vec![
            SystemParam::PlatformMass,
            SystemParam::Rods(vec![(2, param("E", &[1]))])
        ]),
        "params[1].rods[0]"
    );
    assert_eq!(
        refused(vec![SystemParam::Rods(vec![
            (0, param("E", &[1])),
            (0, param("E", &[0]))
        ])]),
        "params[0].rods[1]"
    );
    assert_eq!(
        refused(vec![SystemParam::Rods(vec![
            (0, param("E", &[1])),
            (1, param("c_b", &[1]))
        ])]),
        "params[0].rods[1]"
    );
    // Ecoflex body and Dragon Skin cap: two values.
    assert_eq!(
        refused(vec![SystemParam::Rods(vec![
            (0, param("E", &[1])),
            (1, param("E", &[0]))
        ])]),
        "params[0] (E) of rods[1]"
    );
    assert_eq!(
        refused(vec![SystemParam::Rods(vec![(
            1,
            Param {
                kind: ParamKind::DampingTime,
                sections: vec![]
            }
        )])]),
        "params[0] (damping_time) of rods[1]"
    );
    let located = |mk: Vec<SystemMarker>| field(locate_system_markers(&system, &mk).unwrap_err());
    assert_eq!(
        located(vec![SystemMarker::Platform([f64::NAN, 0.0, 0.0])]),
        "markers[0].offset"
    );
    let on = |rod, s| SystemMarker::Rod {
        rod,
        marker: Marker {
            s,
            offset: [0.0; 3],
        },
    };
    assert_eq!(located(vec![on(0, 0.05), on(3, 0.05)]), "markers[1].rod");
    assert!(located(vec![on(0, 0.05), on(1, 0.5)]).starts_with("markers[1]"));

    // Friction: refused before any solve, naming the rod.
    let mut rough = hanging_at(GAP);
    let mut table = obstacle(ObstacleKind::Plane, 1e4, 1e-4);
    table.point = Some([0.0, 0.0, -0.2]);
    table.normal = Some([0.0, 0.0, 1.0]);
    table.friction = 0.3;
    rough.obstacles = vec![table];
    let rr = Rod::new(rough).unwrap();
    let sys = rods(&r0, &rr, [&base, &base]);
    let p = [0.0; 6];
    let inputs = SystemBatchInputs {
        pressures: &p,
        tensions: None,
        stiffness_scale: None,
    };
    let e = system_sensitivity_batch(
        &sys,
        &platform(),
        &inputs,
        None,
        &[SystemParam::PlatformMass],
        &[],
        &opts(),
        1,
    )
    .unwrap_err();
    assert_eq!(field(e), "rods[1]");
}

/// What a finite difference of the input Jacobian reads of a solved system: the platform
/// position and rotation (9, flattened) and every rod's base force and moment.
fn pose_and_base(sol: &SystemSolution) -> Vec<f64> {
    let mut out = sol.platform_position.to_vec();
    out.extend(sol.platform_rotation.iter().flatten());
    for r in &sol.rods {
        out.extend(r.solution.base_force);
        out.extend(r.solution.base_moment);
    }
    out
}

/// `jacobian::system::system_jacobian`: the platform's pose and the rods' base wrenches
/// against central differences of whole system solves, for pressures on either rod and the
/// platform's force and moment.
#[test]
fn system_input_jacobian_matches_central_differences() {
    let specs = [hanging_at(-GAP), hanging_at(GAP)];
    let lds = [loads(&[20e3, 0.0, 0.0]), loads(&[0.0, 15e3, 5e3])];
    let (r0, r1) = (
        Rod::new(specs[0].clone()).unwrap(),
        Rod::new(specs[1].clone()).unwrap(),
    );
    let pf = platform();
    let system = rods(&r0, &r1, [&lds[0], &lds[1]]);
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let inputs = [
        SystemInput::Pressure { rod: 0, channel: 1 },
        SystemInput::Pressure { rod: 1, channel: 0 },
        SystemInput::Pressure { rod: 1, channel: 2 },
        SystemInput::PlatformForce(0),
        SystemInput::PlatformForce(2),
        SystemInput::PlatformMoment(1),
    ];
    let jac = system_jacobian(&system, &pf, &sol, &inputs).unwrap();
    let r0t = sol.platform_rotation;
    let mut worst: f64 = 0.0;
    for (k, a) in inputs.iter().enumerate() {
        // Steps: 1 Pa (pressures of ~1e4 Pa), 1e-4 N and 1e-6 N m (loads of ~1e-2 N and
        // its moments): truncation ~(h / scale)^2, far below COLUMN_TOL; the solves' error
        // over 2h stays near 1e-8 of a column.
        let step = match a {
            SystemInput::PlatformForce(_) => 1e-4,
            SystemInput::PlatformMoment(_) => 1e-6,
            _ => 1.0,
        };
        let at = |h: f64| {
            let (mut l, mut f) = (lds.clone(), pf);
            match *a {
                SystemInput::Pressure { rod, channel } => l[rod].pressures[channel] += h,
                SystemInput::PlatformForce(j) => f.force[j] += h,
                SystemInput::PlatformMoment(j) => f.moment[j] += h,
                _ => unreachable!("not among the inputs"),
            }
            let sys = rods(&r0, &r1, [&l[0], &l[1]]);
            pose_and_base(&solve_system(&sys, &f, Some(&sol.x), &opts()).unwrap())
        };
        let (hi, lo) = (at(step), at(-step));
        let fd: Vec<f64> = hi
            .iter()
            .zip(&lo)
            .map(|(a, b)| (a - b) / (2.0 * step))
            .collect();
        // dR R^T from the rotation's difference: its skew part is [d psi]x.
        let dr: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| fd[3 + 3 * i + j]));
        let w = softrod_core::jacobian::small_rotation(&r0t, &dr);
        let mut checks: Vec<(&str, Vec<f64>, Vec<f64>)> = vec![
            (
                "platform position",
                fd[0..3].to_vec(),
                jac.d_position[k].to_vec(),
            ),
            ("platform rotation", w.to_vec(), jac.d_rotation[k].to_vec()),
        ];
        for i in 0..2 {
            let at = 12 + 6 * i;
            checks.push((
                "base force",
                fd[at..at + 3].to_vec(),
                jac.d_base_force[k][i].to_vec(),
            ));
            checks.push((
                "base moment",
                fd[at + 3..at + 6].to_vec(),
                jac.d_base_moment[k][i].to_vec(),
            ));
        }
        for (what, f, e) in checks {
            let n = f.iter().map(|x| x * x).sum::<f64>().sqrt();
            let err = f
                .iter()
                .zip(&e)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
                / (n + NOISE / (COLUMN_TOL * step));
            println!("d {what} / d {a:?}: |fd| {n:.3e}, rel. error {err:.2e}");
            worst = worst.max(err);
        }
    }
    assert!(
        worst < COLUMN_TOL,
        "worst relative column error {worst:.2e}"
    );
}

/// A one-rod system whose massless platform sits on the tip is the lone free rod with the
/// platform's load as its tip load: the platform's derivatives with respect to the
/// pressures and the platform force are the free rod's tip Jacobian
/// (`jacobian::point_jacobian`, another residual and another code path).
#[test]
fn one_rod_system_input_jacobian_equals_the_free_rods() {
    let rod = Rod::new(hanging_at(0.0)).unwrap();
    let force = [3e-3, 1e-3, -5e-3];
    let mut free_loads = loads(&[18e3, 4e3, 0.0]);
    free_loads.tip_force = force;
    let free = solve(&rod, &free_loads, None, &opts()).unwrap();
    let lone_inputs = [
        Input::Pressure(0),
        Input::Pressure(1),
        Input::TipForce(0),
        Input::TipForce(2),
    ];
    let lone = point_jacobian(&rod, &free_loads, &free, &lone_inputs, &Probe::tip(&rod)).unwrap();
    let pf = Platform {
        position: free.tip.r,
        rotation: free.tip.rot,
        force,
        moment: [0.0; 3],
        mass: 0.0,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -9.81],
    };
    let system = vec![SystemRod {
        rod: &rod,
        loads: loads(&[18e3, 4e3, 0.0]),
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    }];
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    let inputs = [
        SystemInput::Pressure { rod: 0, channel: 0 },
        SystemInput::Pressure { rod: 0, channel: 1 },
        SystemInput::PlatformForce(0),
        SystemInput::PlatformForce(2),
    ];
    let jac = system_jacobian(&system, &pf, &sol, &inputs).unwrap();
    for k in 0..inputs.len() {
        // Two exact derivatives of the same equilibrium (each solved to 1e-13): they agree
        // to the solves' error relative to the column, far below 1e-8.
        let scale = norm(&lone.d_position[k]).max(1e-12);
        assert!(
            dist(&jac.d_position[k], &lone.d_position[k]) < 1e-8 * scale,
            "{k}: position"
        );
        let wscale = norm(&lone.d_rotation[k]).max(1e-12);
        assert!(
            dist(&jac.d_rotation[k], &lone.d_rotation[k]) < 1e-8 * wscale,
            "{k}: rotation"
        );
    }
}

#[test]
fn system_input_jacobian_refuses_unknown_inputs_by_name() {
    let spec = hanging_at(0.0);
    let rod = Rod::new(spec).unwrap();
    let system = vec![SystemRod {
        rod: &rod,
        loads: loads(&[0.0; 3]),
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    }];
    let mut pf = platform();
    pf.position = [0.0, 0.0, -0.134];
    pf.force = [0.0; 3];
    let sol = solve_system(&system, &pf, None, &opts()).unwrap();
    for (bad, rule) in [
        (
            SystemInput::Pressure { rod: 1, channel: 0 },
            "the system has 1 rods",
        ),
        (
            SystemInput::Pressure { rod: 0, channel: 3 },
            "pressure channels 0..3",
        ),
        (
            SystemInput::Tension { rod: 0, channel: 0 },
            "tendon channels 0..0",
        ),
        (
            SystemInput::StiffnessScale { rod: 0, factor: 3 },
            "stiffness factors 0..3",
        ),
        (SystemInput::PlatformMoment(3), "components 0..3"),
    ] {
        let inputs = [SystemInput::PlatformForce(0), bad];
        match system_jacobian(&system, &pf, &sol, &inputs) {
            Err(SoftrodError::InvalidParameter { field, rule: r, .. }) => {
                assert_eq!(field, "inputs[1]");
                assert!(r.contains(rule), "{r}");
            }
            other => panic!("{bad:?}: {other:?}"),
        }
    }
}
