//! Forward parameter sensitivities of the dynamics (issue 19) against central finite
//! differences of whole tip trajectories, and the checks on what they support.

mod common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, Simulator};
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::spec::DesignSpec;
use softrod_core::{Rod, SoftrodError};

const BAR: f64 = 1e5;
const DT: f64 = 5e-3;
const STEPS: usize = 40;

/// Paper 000's arm (hanging, three PAMs, tau = 0.19 s) on 6 intervals: coarse, so the
/// test is quick; the sensitivities are exact for whatever discretisation runs.
fn pam_arm() -> DesignSpec {
    let mut sec = direct_section("arm", 0.22, 262.8, 87.6, 0.04466, 0.02977, 0.165, 6);
    sec.chambers = [0.0, 120.0, 240.0]
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let mut c = chamber(6.02e-3, 0.0175, *a, k);
            c.area = 113.88e-6;
            c
        })
        .collect();
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let mut spec = design(vec![sec], hanging, 9.81);
    spec.dynamics.damping_time = 0.19;
    spec
}

fn options() -> DynOptions {
    DynOptions {
        dt: DT,
        // Far below the default so that the finite differences are not noise: the
        // converged state's error ~ tol times the unknowns' scales.
        tol: 1e-11,
        ..DynOptions::default()
    }
}

/// Commands: a ramp to 2.5 bar on PAM 0 over 0.1 s, 1 bar on PAM 1 (from 0.5 bar and 0 at
/// the start, so the start's equilibrium depends on the area and the weight).
fn command(t: f64) -> Vec<f64> {
    vec![(0.5 + 2.0 * (t / 0.1).min(1.0)) * BAR, 1.0 * BAR, 0.0]
}

/// The tip after every step, and with `params` its derivatives.
fn run(spec: DesignSpec, params: &[Param]) -> (Vec<[f64; 3]>, Vec<Vec<[f64; 3]>>) {
    let rod = Rod::new(spec).unwrap();
    let mut sim = Simulator::new(rod, &command(0.0), Initial::Static, options()).unwrap();
    if !params.is_empty() {
        sim.track_sensitivities(params).unwrap();
    }
    let (mut tip, mut d) = (vec![], vec![]);
    for k in 1..=STEPS {
        sim.step(&command(k as f64 * DT)).unwrap();
        tip.push(sim.tip().r);
        if !params.is_empty() {
            d.push(sim.tip_sensitivity().unwrap().to_vec());
        }
    }
    (tip, d)
}

/// The design with parameter `kind` moved by `delta` (relative for the area factor).
fn moved(kind: ParamKind, delta: f64) -> DesignSpec {
    let mut spec = pam_arm();
    let sec = &mut spec.sections[0];
    match kind {
        ParamKind::DampingTime => spec.dynamics.damping_time += delta,
        ParamKind::AreaScale => sec.chambers.iter_mut().for_each(|c| c.area *= 1.0 + delta),
        ParamKind::Mass => *sec.mass.as_mut().unwrap() += delta,
        ParamKind::CorrectionFactor(2) => sec.c_b += delta,
        ParamKind::CorrectionFactor(1) => sec.c_e += delta,
        other => panic!("no finite difference for {other:?}"),
    }
    spec
}

#[test]
fn trajectory_sensitivities_match_central_differences() {
    let kinds = [
        (ParamKind::DampingTime, 0.19),
        (ParamKind::AreaScale, 1.0),
        (ParamKind::Mass, 0.165),
        (ParamKind::CorrectionFactor(2), 1.0),
        (ParamKind::CorrectionFactor(1), 1.0),
    ];
    // Five parameters: two dual chunks of four.
    let params: Vec<Param> = kinds
        .iter()
        .map(|(k, _)| Param {
            kind: *k,
            sections: if *k == ParamKind::DampingTime {
                vec![]
            } else {
                vec![0]
            },
        })
        .collect();
    let (tip0, exact) = run(pam_arm(), &params);
    let (plain, _) = run(pam_arm(), &[]);
    // Tracking does not change the run.
    assert_eq!(tip0, plain);
    for (j, (kind, value)) in kinds.iter().enumerate() {
        // Central differences with a relative step of 1e-4: truncation ~ (1e-4)^2 = 1e-8
        // of the derivative; the converged states' error (tol 1e-11 of the unknowns'
        // scales, ~1e-12 m at the tip) divided by the step (2e-4 of the value) adds
        // ~1e-8 m per unit. The tolerance, 1e-5 of the largest derivative plus 1e-7 m,
        // leaves two orders of magnitude above both.
        let h = 1e-4 * value;
        let (up, _) = run(moved(*kind, h), &[]);
        let (down, _) = run(moved(*kind, -h), &[]);
        // The area factor's derivative is per unit of the factor (1 = as designed).
        let scale = if *kind == ParamKind::AreaScale {
            1.0 / value
        } else {
            1.0
        };
        let largest = exact
            .iter()
            .flat_map(|d| d[j].iter().map(|x| x.abs()))
            .fold(0.0f64, f64::max);
        assert!(
            largest > 1e-4,
            "{kind:?}: the tip does not move ({largest})"
        );
        for (k, d) in exact.iter().enumerate() {
            for a in 0..3 {
                let fd = (up[k][a] - down[k][a]) / (2.0 * h) * scale;
                let err = (d[j][a] - fd).abs();
                assert!(
                    err <= 1e-5 * largest + 1e-7,
                    "{kind:?} step {k} axis {a}: exact {} fd {fd} (largest {largest})",
                    d[j][a]
                );
            }
        }
    }
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
    let mut sim = Simulator::new(rod(), &p0, Initial::Straight, options()).unwrap();
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
}
