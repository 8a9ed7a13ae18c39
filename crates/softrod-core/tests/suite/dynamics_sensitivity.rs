//! Forward parameter sensitivities of the dynamics (issue 19) against central finite
//! differences of whole tip trajectories, and the checks on what they support.

use crate::common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, SigmaMap, Simulator};
use softrod_core::marker::Marker;
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::{AxialSpec, DesignSpec, MaterialSpec};
use softrod_core::statics::constraint::TipConstraint;
use softrod_core::{Rod, SoftrodError};

const BAR: f64 = 1e5;
const DT: f64 = 5e-3;
const STEPS: usize = 40;

/// Paper 000's arm (hanging, three PAMs, tau = 0.19 s) on 6 intervals: coarse, so the
/// test is quick; the sensitivities are exact for whatever discretisation runs.
fn pam_arm() -> DesignSpec {
    let sec = pam_arm_section(0.22, 0.165, 6);
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let mut spec = design(vec![sec], hanging, 9.81);
    spec.dynamics.damping_time = 0.19;
    spec
}

fn options() -> DynOptions {
    DynOptions {
        dt: DT,
        // Far below the default so that the finite differences are not noise: the
        // converged state's error ~ tol times the unknowns' scales. 1e-11 left a clamped
        // tip's position (an unknown of the held step) 1e-11 m off its pose, 3e-7 m per
        // unit in a difference quotient over 3.8e-5 s of tau: the size of the bound below.
        tol: 1e-13,
        ..DynOptions::default()
    }
}

/// Commands: a ramp to 2.5 bar on PAM 0 over 0.1 s, 1 bar on PAM 1 (from 0.5 bar and 0 at
/// the start, so the start's equilibrium depends on the area and the weight).
fn command(t: f64) -> Vec<f64> {
    vec![(0.5 + 2.0 * (t / 0.1).min(1.0)) * BAR, 1.0 * BAR, 0.0]
}

/// Paper 002's actuator's commands: 10 kPa on chamber 0 at the start (the start depends
/// on the law), ramped to 40 kPa over 0.1 s, with 15 kPa on chamber 2.
fn p002_command(t: f64) -> Vec<f64> {
    vec![10e3 + 30e3 * (t / 0.1).min(1.0), 0.0, 15e3]
}

/// A run's inputs as functions of t (s): chamber pressures (Pa), tendon tensions (N) and
/// the tip's pose (free, or pinned or clamped where the pose says); and the markers read
/// (their positions and derivatives follow the nodes' in `run`).
struct Inputs {
    pressures: fn(f64) -> Vec<f64>,
    tensions: fn(f64) -> Vec<f64>,
    held: fn(f64) -> TipConstraint,
    markers: &'static [Marker],
}

/// No markers: the nodes only.
const NO_MARKERS: &[Marker] = &[];

fn slack(_: f64) -> Vec<f64> {
    vec![]
}

fn free(_: f64) -> TipConstraint {
    TipConstraint::Free
}

const PAM: Inputs = Inputs {
    pressures: command,
    tensions: slack,
    held: free,
    markers: ARM_MARKERS,
};

const P002: Inputs = Inputs {
    pressures: p002_command,
    tensions: slack,
    held: free,
    markers: NO_MARKERS,
};

/// The node positions after every step followed by the markers' (`[step][point]`), with
/// `params` their derivatives (`[step][param][point]`), and the shallowest of the steps' deepest penetrations into an
/// obstacle (m; -inf without obstacles: > 0 means in contact at every step).
type Run = (Vec<Vec<[f64; 3]>>, Vec<Vec<Vec<[f64; 3]>>>, f64);

fn run(spec: DesignSpec, params: &[Param], inputs: &Inputs) -> Run {
    let rod = Rod::new(spec).unwrap();
    let (f, m) = (rod.spec.tip.force, rod.spec.tip.moment);
    let mut sim = Simulator::with_constraint(
        rod,
        &(inputs.pressures)(0.0),
        &(inputs.tensions)(0.0),
        Initial::Static,
        options(),
        SigmaMap::None,
        f,
        m,
        (inputs.held)(0.0),
    )
    .unwrap();
    sim.set_markers(inputs.markers).unwrap();
    if !params.is_empty() {
        sim.track_sensitivities(params).unwrap();
    }
    let (mut shape, mut d) = (vec![], vec![]);
    let mut touching = f64::INFINITY;
    for k in 1..=STEPS {
        let t = k as f64 * DT;
        let tensions = (inputs.tensions)(t);
        if !tensions.is_empty() {
            sim.set_tensions(&tensions).unwrap();
        }
        sim.set_tip_pose((inputs.held)(t)).unwrap();
        sim.step(&(inputs.pressures)(t)).unwrap();
        let nodes = sim.shape().len();
        shape.push([sim.shape(), &sim.marker_positions()].concat());
        let deepest = sim
            .contact_state()
            .map_or(f64::NEG_INFINITY, |c| c.max_penetration);
        touching = touching.min(deepest);
        if !params.is_empty() {
            let (nodes_d, markers_d) = (
                sim.shape_sensitivity().unwrap(),
                sim.marker_sensitivity().unwrap(),
            );
            let both = nodes_d.iter().zip(markers_d);
            d.push(both.map(|(a, b)| [&a[..], b].concat()).collect::<Vec<_>>());
            // The tip's derivatives are the last node's, and those of a marker on the tip
            // with no offset.
            let tip = sim.tip_sensitivity().unwrap();
            let on_tip = inputs
                .markers
                .iter()
                .position(|m| m.s == 0.22 && m.offset == [0.0; 3]);
            for (j, s) in d.last().unwrap().iter().enumerate() {
                assert_eq!(s[nodes - 1], tip[j]);
                if let Some(k) = on_tip {
                    assert_eq!(s[nodes + k], tip[j]);
                }
            }
        }
    }
    (shape, d, touching)
}

/// `spec` with parameter `p` moved by `delta` (relative for the area factor; E moves G with
/// it, as the core's E does: a fixed Poisson ratio).
fn moved(mut spec: DesignSpec, p: &Param, delta: f64) -> DesignSpec {
    if p.kind == ParamKind::DampingTime {
        spec.dynamics.damping_time += delta;
        return spec;
    }
    for &i in &p.sections {
        let sec = &mut spec.sections[i];
        match p.kind {
            ParamKind::AreaScale => sec.chambers.iter_mut().for_each(|c| c.area *= 1.0 + delta),
            ParamKind::Mass => *sec.mass.as_mut().unwrap() += delta,
            ParamKind::CorrectionFactor(k) => {
                *[&mut sec.c_s, &mut sec.c_e, &mut sec.c_b, &mut sec.c_t][k] += delta
            }
            ParamKind::YoungsModulus => {
                let m = sec.material.as_mut().unwrap();
                let f = 1.0 + delta / m.youngs_modulus;
                m.youngs_modulus *= f;
                m.shear_modulus *= f;
            }
            ParamKind::Density => sec.material.as_mut().unwrap().density += delta,
            ParamKind::OgdenAlpha => match &mut sec.law.axial {
                AxialSpec::Ogden { alpha } => *alpha += delta,
                other => panic!("alpha of {other:?}"),
            },
            other => panic!("no finite difference for {other:?}"),
        }
    }
    spec
}

/// A parameter of `sections` (none for the damping time).
fn param(kind: ParamKind, sections: &[usize]) -> Param {
    Param {
        kind,
        sections: sections.to_vec(),
    }
}

/// The tracked tip derivatives of `params` (each with its value, the finite difference's
/// scale) on `spec` against central differences of whole trajectories.
fn check_against_central_differences(
    name: &str,
    spec: &DesignSpec,
    params: &[(Param, f64)],
    inputs: &Inputs,
) {
    let list: Vec<Param> = params.iter().map(|(p, _)| p.clone()).collect();
    let (shape0, exact, _) = run(spec.clone(), &list, inputs);
    let (plain, _, _) = run(spec.clone(), &[], inputs);
    // Tracking does not change the run.
    assert_eq!(shape0, plain, "{name}");
    for (j, (p, value)) in params.iter().enumerate() {
        // Central differences with a relative step of 1e-4: truncation ~ (1e-4)^2 = 1e-8
        // of the derivative; the converged states' error (tol 1e-13 of the unknowns'
        // scales, ~1e-13 m at the tip) divided by the step (2e-4 of the value) adds
        // ~1e-9 m per unit. The tolerance, 1e-5 of the largest derivative plus 1e-7 m
        // per `unit`, leaves two orders of magnitude above both. Markers are points of
        // the same state (the continuous extension, smooth in it), with the same errors.
        let h = 1e-4 * value;
        let (up, _, _) = run(moved(spec.clone(), p, h), &[], inputs);
        let (down, _, _) = run(moved(spec.clone(), p, -h), &[], inputs);
        // The area factor's derivative is per unit of the factor (1 = as designed).
        let scale = if p.kind == ParamKind::AreaScale {
            1.0 / value
        } else {
            1.0
        };
        let largest = exact
            .iter()
            .flat_map(|d| d[j].iter().flatten().map(|x| x.abs()))
            .fold(0.0f64, f64::max);
        // Per unit of the parameter, or per relative change for parameters of more than
        // one unit (E in Pa, density in kg/m^3, whose per-unit derivatives are tiny).
        let unit = value.abs().max(1.0);
        // A derivative that is zero tests nothing.
        assert!(
            largest * unit > 1e-4,
            "{name} {:?}: the rod does not move ({largest})",
            p.kind
        );
        let mut worst = 0.0f64;
        for (k, d) in exact.iter().enumerate() {
            for (node, dr) in d[j].iter().enumerate() {
                for a in 0..3 {
                    let fd = (up[k][node][a] - down[k][node][a]) / (2.0 * h) * scale;
                    let err = (dr[a] - fd).abs();
                    worst = worst.max(err / largest);
                    assert!(
                        err <= 1e-5 * largest + 1e-7 / unit,
                        "{name} {:?} step {k} node {node} axis {a}: exact {} fd {fd} (largest {largest})",
                        p.kind,
                        dr[a]
                    );
                }
            }
        }
        eprintln!(
            "{name} {:?}: largest |d r| {largest:.3e} per unit, worst error {worst:.1e} of it",
            p.kind
        );
    }
}

/// Markers on the arm (6 intervals of 36.7 mm): inside intervals with offsets in the
/// cross-section (read by the continuous extension, which the dual evaluation
/// differentiates), on a node (s = 2 L / 3) and at the tip.
const ARM_MARKERS: &[Marker] = &[
    Marker {
        s: 0.1,
        offset: [0.012, -0.004, 0.002],
    },
    Marker {
        s: 0.22 * 2.0 / 3.0,
        offset: [0.0, 0.01, 0.0],
    },
    Marker {
        s: 0.205,
        offset: [-0.006, 0.0, 0.0],
    },
    Marker {
        s: 0.22,
        offset: [0.0; 3],
    },
];

#[test]
fn trajectory_sensitivities_match_central_differences() {
    // Five parameters: two dual chunks of four.
    let params = [
        (param(ParamKind::DampingTime, &[]), 0.19),
        (param(ParamKind::AreaScale, &[0]), 1.0),
        (param(ParamKind::Mass, &[0]), 0.165),
        (param(ParamKind::CorrectionFactor(2), &[0]), 1.0),
        (param(ParamKind::CorrectionFactor(1), &[0]), 1.0),
    ];
    check_against_central_differences("PAM arm", &pam_arm(), &params, &PAM);
}

/// The material parameters of paper 002's body (section 1), its bending factor and tau.
fn body_params() -> Vec<(Param, f64)> {
    vec![
        (param(ParamKind::DampingTime, &[]), 0.05),
        (
            param(ParamKind::YoungsModulus, &[1]),
            ECOFLEX.youngs_modulus,
        ),
        (param(ParamKind::Density, &[1]), ECOFLEX.density),
        (param(ParamKind::CorrectionFactor(2), &[1]), 1.31),
    ]
}

/// Follower (body-frame) tip force and moment, and a follower line load (issue 17): the
/// load turns with the rod, so it enters the step's residual through the state's rotation,
/// which the dual evaluation differentiates with the rest.
#[test]
fn follower_load_sensitivities_match_central_differences() {
    for (name, spec) in follower_cases(2) {
        check_against_central_differences(name, &spec, &body_params(), &P002);
    }
}

/// A tapered body and a reference shape tabulated along s: every stage point has its own
/// section model (`Coeffs::at`), built from the dual parameters the same way.
#[test]
fn tapered_and_tabulated_sensitivities_match_central_differences() {
    check_against_central_differences("tapered", &tapered(2, 0.05), &body_params(), &P002);
    let mut arm = tabulated_arm(false);
    arm.sections[0].steps = 4;
    let params = [
        (param(ParamKind::DampingTime, &[]), 0.19),
        (param(ParamKind::Mass, &[0]), 0.165),
        (param(ParamKind::CorrectionFactor(2), &[0]), 1.0),
    ];
    check_against_central_differences("tabulated reference", &arm, &params, &PAM);
}

/// Tendon tensions: 1 N and 0.5 N at the start (the start's equilibrium holds them),
/// ramped to 4 N and 1.5 N over 0.1 s; no pressure.
fn tendon_tensions(t: f64) -> Vec<f64> {
    let r = (t / 0.1).min(1.0);
    vec![1.0 + 3.0 * r, 0.5 + r]
}

fn no_pressure(_: f64) -> Vec<f64> {
    vec![0.0; 3]
}

/// Tendons (the implicit tendon law of Rucker and Webster 2011): the parameters enter the
/// law through the section's stiffness; its parameter derivative follows by the implicit
/// function theorem on the converged strains (`SectionModel::strains`). Helical and
/// straight routes, with the linear law and with paper 004's stretch-dependent bending.
#[test]
fn tendon_sensitivities_match_central_differences() {
    let inputs = Inputs {
        pressures: no_pressure,
        tensions: tendon_tensions,
        held: free,
        markers: NO_MARKERS,
    };
    for (helical, sb) in [(false, false), (true, true)] {
        let spec = tendon_arm(helical, sb, 2, 0.05);
        let name = format!("tendons (helical {helical}, stretch bending {sb})");
        check_against_central_differences(&name, &spec, &body_params(), &inputs);
    }
}

/// The nonlinear axial laws: Ogden with swelling and a chamber offset (paper 002's M3) and
/// an EA(F) table. Each is solved in f64 and linearised by the implicit function theorem,
/// in the state and, with dual coefficients, in the parameters and the histories
/// (`collocation::ogden_strain`, `table_stretch`).
#[test]
fn nonlinear_axial_law_sensitivities_match_central_differences() {
    let mut ogden = body_params();
    ogden[3] = (param(ParamKind::OgdenAlpha, &[1]), 8.89);
    ogden.push((param(ParamKind::CorrectionFactor(1), &[1]), 1.0));
    check_against_central_differences("Ogden (M3)", &actuator(ogden_m3_law(), 2), &ogden, &P002);
    let mut table = body_params();
    table.push((param(ParamKind::CorrectionFactor(1), &[1]), 1.0));
    check_against_central_differences("EA(F) table", &actuator(ea_table_law(), 2), &table, &P002);
}

/// Paper 000's arm with its tip held: pinned where the straight arm's tip is (the PAMs'
/// moment bends the rod between its ends while the tip stays put: its derivatives are
/// zero, the shape's are what is checked), or clamped in the base's orientation and moved
/// sideways by 20 mm over the run (a uniform moment alone would go into the clamps).
fn clamped_arm_tip(t: f64) -> TipConstraint {
    let s = (t / (STEPS as f64 * DT)).min(1.0);
    TipConstraint::Clamped {
        position: [0.02 * s * s * (3.0 - 2.0 * s), 0.0, -0.22],
        rotation: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
    }
}

/// Clamped 20 mm aside of the straight tip in the base's orientation and held there: the
/// arm starts S-shaped, and the PAMs' stretch changes that shape (markers move) while the
/// tip stays put.
fn clamped_aside_tip(_: f64) -> TipConstraint {
    TipConstraint::Clamped {
        position: [0.02, 0.0, -0.22],
        rotation: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
    }
}

fn pinned_arm_tip(_: f64) -> TipConstraint {
    TipConstraint::Pinned {
        position: [0.0, 0.0, -0.22],
    }
}

#[test]
fn held_tip_sensitivities_match_central_differences() {
    let params = [
        (param(ParamKind::DampingTime, &[]), 0.19),
        (param(ParamKind::AreaScale, &[0]), 1.0),
        (param(ParamKind::Mass, &[0]), 0.165),
        (param(ParamKind::CorrectionFactor(2), &[0]), 1.0),
    ];
    for (name, held) in [
        ("clamped arm", clamped_arm_tip as fn(f64) -> TipConstraint),
        ("clamped aside", clamped_aside_tip),
        ("pinned arm", pinned_arm_tip),
    ] {
        let inputs = Inputs {
            pressures: command,
            tensions: slack,
            held,
            markers: ARM_MARKERS,
        };
        if name == "clamped aside" {
            // The tip (the last node, and the marker on it) stays; the other markers move.
            let (points, _, _) = run(pam_arm(), &[], &inputs);
            let (first, last) = (&points[0], &points[STEPS - 1]);
            let nodes = first.len() - ARM_MARKERS.len();
            // The held pose holds to Newton's tolerance (1e-13 of the unknowns' scales, the
            // length for positions: 1e-19 m measured); the markers move (by 0.3 mm or more
            // in the 0.2 s run, the one 15 mm from the clamp least).
            let tip_moved = dist(&first[nodes - 1], &last[nodes - 1]);
            assert!(tip_moved < 1e-13, "{name}: the tip moved {tip_moved}");
            let moved = (nodes..nodes + 3).map(|k| dist(&first[k], &last[k]));
            let least = moved.fold(f64::INFINITY, f64::min);
            eprintln!("{name}: tip moved {tip_moved:.1e} m, the markers at least {least:.1e} m");
            assert!(least > 1e-4, "{name}: the markers moved only {least} m");
        }
        check_against_central_differences(name, &pam_arm(), &params, &inputs);
    }
}

/// A horizontal beam (0.5 m, radius 5 mm, E 1 MPa) clamped at the base, its tip pinned at
/// the base's height and pressed down 1 mm over the run, over a plane 2 mm below its
/// surface: gravity (0.15 m/s^2) sags it onto the plane (it would sag 4 mm without it), so
/// it lies on the plane over its middle at every step while the pinned tip moves.
fn beam_on_plane() -> DesignSpec {
    let material = MaterialSpec {
        youngs_modulus: 1e6,
        shear_modulus: 1e6 / 3.0,
        density: 1000.0,
    };
    let sec = geometry_section("beam", 0.5, 0.005, 0.0, material, vec![], 6);
    let mut spec = design(vec![sec], HORIZONTAL, 0.15);
    spec.dynamics.damping_time = 0.05;
    let mut plane = obstacle(ObstacleKind::Plane, 50.0, 3e-3);
    plane.point = Some([0.0, 0.0, -0.007]);
    plane.normal = Some([0.0, 0.0, 1.0]);
    spec.obstacles = vec![plane];
    spec
}

fn pressed_tip(t: f64) -> TipConstraint {
    let s = (t / (STEPS as f64 * DT)).min(1.0);
    TipConstraint::Pinned {
        position: [0.5, 0.0, -1e-3 * s * s * (3.0 - 2.0 * s)],
    }
}

fn no_channels(_: f64) -> Vec<f64> {
    vec![]
}

/// A held tip with an obstacle in contact over the whole run: the penalty's C1 ramp
/// (docs/contact.md) keeps the trajectory differentiable, and the sensitivities carry the
/// node positions of the contact equations.
#[test]
fn contact_sensitivities_match_central_differences() {
    let inputs = Inputs {
        pressures: no_channels,
        tensions: slack,
        held: pressed_tip,
        markers: NO_MARKERS,
    };
    let (_, _, touching) = run(beam_on_plane(), &[], &inputs);
    assert!(touching > 0.0, "in contact at every step: {touching}");
    let params = [
        (param(ParamKind::DampingTime, &[]), 0.05),
        (param(ParamKind::YoungsModulus, &[0]), 1e6),
        (param(ParamKind::Density, &[0]), 1000.0),
        (param(ParamKind::CorrectionFactor(2), &[0]), 1.0),
    ];
    check_against_central_differences("beam on a plane", &beam_on_plane(), &params, &inputs);
}

#[test]
fn unsupported_settings_are_refused_with_the_rule() {
    let tau = [Param {
        kind: ParamKind::DampingTime,
        sections: vec![],
    }];
    let refused = |sim: &mut Simulator, params: &[Param], field: &str| match sim
        .track_sensitivities(params)
    {
        Err(SoftrodError::InvalidParameter { field: f, .. }) => {
            assert!(f.starts_with(field), "{f} is not {field}")
        }
        other => panic!("{field}: expected a refusal, got {other:?}"),
    };
    let rod = || Rod::new(pam_arm()).unwrap();
    let p0 = command(0.0);
    let midpoint = DynOptions {
        scheme: Scheme::Midpoint,
        ..options()
    };
    let mut sim = Simulator::new(rod(), &p0, Initial::Static, midpoint).unwrap();
    refused(&mut sim, &tau, "scheme");
    let adaptive = DynOptions {
        error_tol: Some(1e-4),
        ..options()
    };
    let mut sim = Simulator::new(rod(), &p0, Initial::Static, adaptive).unwrap();
    refused(&mut sim, &tau, "error_tol");
    // (The straight start is at rest without pressure.)
    let mut sim = Simulator::new(rod(), &[0.0; 3], Initial::Straight, options()).unwrap();
    refused(&mut sim, &tau, "initial");
    let mut sim = Simulator::new(rod(), &p0, Initial::Static, options()).unwrap();
    sim.step(&p0).unwrap();
    refused(&mut sim, &tau, "track_sensitivities");
    let mut sim = Simulator::new(rod(), &p0, Initial::Static, options()).unwrap();
    // E needs a material: this arm gives its stiffnesses directly (params[1] is E).
    let with_e = [
        tau[0].clone(),
        Param {
            kind: ParamKind::YoungsModulus,
            sections: vec![0],
        },
    ];
    refused(&mut sim, &with_e, "params[1] (E)");
    let sigma = [Param {
        kind: ParamKind::StiffnessScale(0),
        sections: vec![],
    }];
    refused(&mut sim, &sigma, "params[0]");
    // Ogden's alpha is a dynamic parameter of Ogden sections only (this arm is linear).
    refused(&mut sim, &[param(ParamKind::OgdenAlpha, &[0])], "params[0]");
}

/// A dynamic calibration round trip on a held tip: the PAM arm pinned at its straight tip
/// position, whose own position does not move, is fitted by Gauss-Newton on its node
/// positions along the run (`Simulator::shape_sensitivity`) from tau and the area factor
/// 20 % and 10 % off to a synthetic run of the true values: six Gauss-Newton steps (the
/// misfit is zero at the truth, so they converge quadratically) land on them to the
/// replays' convergence.
#[test]
fn held_tip_calibration_round_trip_recovers_tau_and_area() {
    let inputs = Inputs {
        pressures: command,
        tensions: slack,
        held: pinned_arm_tip,
        markers: NO_MARKERS,
    };
    let tau = param(ParamKind::DampingTime, &[]);
    let area = param(ParamKind::AreaScale, &[0]);
    // The design with tau and the area factor a (relative to paper 000's areas).
    let at = |theta: [f64; 2]| {
        let spec = moved(pam_arm(), &tau, theta[0] - 0.19);
        moved(spec, &area, theta[1] - 1.0)
    };
    let truth = [0.16, 1.15];
    let (target, _, _) = run(at(truth), &[], &inputs);
    let mut theta = [truth[0] * 1.2, truth[1] * 0.9];
    for _ in 0..6 {
        let (shape, d, _) = run(at(theta), &[tau.clone(), area.clone()], &inputs);
        // Normal equations of the node positions' misfit; the area derivative is per unit
        // of the factor on the design's (already scaled) areas: d/da = d/dfactor / a.
        let (mut jtj, mut jtr) = ([[0.0; 2]; 2], [0.0; 2]);
        for (k, nodes) in shape.iter().enumerate() {
            for (n, r) in nodes.iter().enumerate() {
                for a in 0..3 {
                    let res = r[a] - target[k][n][a];
                    let g = [d[k][0][n][a], d[k][1][n][a] / theta[1]];
                    for i in 0..2 {
                        jtr[i] += g[i] * res;
                        for j in 0..2 {
                            jtj[i][j] += g[i] * g[j];
                        }
                    }
                }
            }
        }
        let det = jtj[0][0] * jtj[1][1] - jtj[0][1] * jtj[1][0];
        theta[0] -= (jtj[1][1] * jtr[0] - jtj[0][1] * jtr[1]) / det;
        theta[1] -= (jtj[0][0] * jtr[1] - jtj[1][0] * jtr[0]) / det;
    }
    eprintln!(
        "held-tip fit: tau {:.9} (truth {}), area {:.9} (truth {})",
        theta[0], truth[0], theta[1], truth[1]
    );
    // The replays converge to 1e-13 of the unknowns' scales: the misfit's minimum lies
    // that close to the truth, far inside 1e-6.
    for i in 0..2 {
        assert!(
            ((theta[i] - truth[i]) / truth[i]).abs() < 1e-6,
            "{theta:?} vs {truth:?}"
        );
    }
}
