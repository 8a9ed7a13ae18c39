//! Every class of bad input is rejected with an `InvalidParameter` naming the field, and a
//! solve that cannot converge says so instead of returning a shape.

use crate::common;
use common::*;
use softrod_core::spec::{DesignSpec, LineLoadSpec, MaterialSpec, StiffnessSpec};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

/// A valid design to break: paper 002's actuator, standing, under gravity, with a
/// direct-stiffness section at the end.
fn valid() -> DesignSpec {
    let mut spec = p002_actuator(IDENTITY, 9.81, 16);
    spec.sections.push(direct_section(
        "tail", 0.02, 50.0, 30.0, 1e-3, 1e-3, 0.01, 8,
    ));
    spec
}

fn field_of(r: softrod_core::Result<Rod>) -> String {
    match r {
        Err(SoftrodError::InvalidParameter { field, .. }) => field,
        Err(other) => panic!("expected InvalidParameter, got {other:?}"),
        Ok(_) => panic!("the design was accepted"),
    }
}

type Breaker = fn(&mut DesignSpec);

/// (what is wrong, how to break the valid design, the field the error must name)
const CASES: &[(&str, Breaker, &str)] = &[
    (
        "zero length",
        |d| d.sections[1].length = 0.0,
        "sections[1].length",
    ),
    (
        "negative length",
        |d| d.sections[0].length = -0.01,
        "sections[0].length",
    ),
    (
        "NaN length",
        |d| d.sections[2].length = f64::NAN,
        "sections[2].length",
    ),
    (
        "infinite length",
        |d| d.sections[1].length = f64::INFINITY,
        "sections[1].length",
    ),
    (
        "zero outer radius",
        |d| d.sections[0].outer_radius = Some(0.0),
        "sections[0].outer_radius",
    ),
    (
        "negative outer radius",
        |d| d.sections[1].outer_radius = Some(-0.02),
        "sections[1].outer_radius",
    ),
    (
        "bore equal to outer radius",
        |d| d.sections[0].bore_radius = P002_RO,
        "sections[0].bore_radius",
    ),
    (
        "bore beyond outer radius",
        |d| d.sections[2].bore_radius = 0.03,
        "sections[2].bore_radius",
    ),
    (
        "negative bore",
        |d| d.sections[2].bore_radius = -1e-3,
        "sections[2].bore_radius",
    ),
    (
        "chamber outside the section",
        |d| d.sections[1].chambers[2].distance = 17e-3,
        "sections[1].chambers[2].distance",
    ),
    (
        "chamber overlapping the bore",
        |d| d.sections[1].chambers[0].distance = 7e-3,
        "sections[1].chambers[0].distance",
    ),
    (
        "chambers overlapping each other",
        |d| d.sections[1].chambers[1].angle = 130f64.to_radians(),
        "sections[1].chambers[1].angle",
    ),
    (
        "zero chamber area",
        |d| d.sections[1].chambers[0].area = 0.0,
        "sections[1].chambers[0].area",
    ),
    (
        "negative chamber radius",
        |d| d.sections[1].chambers[1].radius = Some(-1e-3),
        "sections[1].chambers[1].radius",
    ),
    (
        "NaN chamber angle",
        |d| d.sections[1].chambers[1].angle = f64::NAN,
        "sections[1].chambers[1].angle",
    ),
    (
        "zero Young's modulus",
        |d| d.sections[1].material.as_mut().unwrap().youngs_modulus = 0.0,
        "sections[1].material.E",
    ),
    (
        "negative Young's modulus",
        |d| d.sections[0].material.as_mut().unwrap().youngs_modulus = -6e5,
        "sections[0].material.E",
    ),
    (
        "zero shear modulus",
        |d| d.sections[1].material.as_mut().unwrap().shear_modulus = 0.0,
        "sections[1].material.G",
    ),
    (
        // nu = E / (2G) - 1 = 0.6
        "Poisson ratio above 0.5",
        |d| {
            d.sections[1].material = Some(MaterialSpec {
                youngs_modulus: 80e3,
                shear_modulus: 25e3,
                density: 1070.0,
            })
        },
        "sections[1].material.poisson",
    ),
    (
        // nu = 3
        "Poisson ratio far above 0.5",
        |d| {
            d.sections[2].material = Some(MaterialSpec {
                youngs_modulus: 8e5,
                shear_modulus: 1e5,
                density: 1080.0,
            })
        },
        "sections[2].material.poisson",
    ),
    (
        "zero density",
        |d| d.sections[1].material.as_mut().unwrap().density = 0.0,
        "sections[1].material.density",
    ),
    (
        "negative EA",
        |d| d.sections[3].stiffness.ea = Some(-1.0),
        "sections[3].EA",
    ),
    (
        "NaN EI1",
        |d| d.sections[3].stiffness.ei1 = Some(f64::NAN),
        "sections[3].EI1",
    ),
    (
        "negative mass",
        |d| d.sections[3].mass = Some(-0.01),
        "sections[3].mass",
    ),
    (
        "zero correction factor c_b",
        |d| d.sections[1].c_b = 0.0,
        "sections[1].c_b",
    ),
    (
        "zero steps",
        |d| d.sections[1].steps = 0,
        "sections[1].steps",
    ),
    (
        "empty section name",
        |d| d.sections[2].name = " ".into(),
        "sections[2].name",
    ),
    (
        "duplicate section names",
        |d| d.sections[2].name = "cap_a".into(),
        "sections[2].name",
    ),
    ("no sections", |d| d.sections.clear(), "sections"),
    (
        "rigid section with chambers",
        |d| {
            let s = &mut d.sections[1];
            s.rigid = true;
            s.mass = Some(0.1);
        },
        "sections[1].chambers",
    ),
    (
        "elastic section with neither geometry nor all stiffnesses",
        |d| {
            d.sections[3].stiffness = StiffnessSpec {
                ea: Some(50.0),
                ga: Some(30.0),
                ei1: Some(1e-3),
                ..Default::default()
            }
        },
        "sections[3].outer_radius",
    ),
    (
        "section weight unknown",
        |d| d.sections[3].mass = None,
        "sections[3].mass",
    ),
    (
        "channel index 1e12 (would size a 1e12-entry table)",
        |d| d.sections[1].chambers[1].channel = 1_000_000_000_000,
        "sections[1].chambers[1].channel",
    ),
    (
        "channel index usize::MAX (channel + 1 overflows)",
        |d| d.sections[1].chambers[0].channel = usize::MAX,
        "sections[1].chambers[0].channel",
    ),
    (
        "channel index i64::MAX",
        |d| d.sections[1].chambers[2].channel = i64::MAX as usize,
        "sections[1].chambers[2].channel",
    ),
    (
        "too many chambers in a section",
        |d| {
            let c = d.sections[1].chambers[0];
            d.sections[1].chambers = vec![c; softrod_core::validity::MAX_CHAMBERS_PER_SECTION + 1];
        },
        "sections[1].chambers",
    ),
    (
        "too many steps in one section",
        |d| d.sections[0].steps = softrod_core::validity::MAX_STEPS_PER_SECTION + 1,
        "sections[0].steps",
    ),
    (
        "too many steps over the rod",
        |d| {
            for s in &mut d.sections {
                s.steps = softrod_core::validity::MAX_STEPS_PER_SECTION;
            }
            let extra = d.sections[3].clone();
            for k in 0..8 {
                let mut e = extra.clone();
                e.name = format!("extra{k}");
                d.sections.push(e);
            }
        },
        "sections.steps",
    ),
    (
        "too many sections",
        |d| {
            let s = d.sections[3].clone();
            d.sections = (0..=softrod_core::validity::MAX_SECTIONS)
                .map(|k| {
                    let mut e = s.clone();
                    e.name = format!("s{k}");
                    e
                })
                .collect();
        },
        "sections",
    ),
    (
        "operating range upside down",
        |d| {
            d.operating_range = Some(softrod_core::spec::OperatingRangeSpec {
                pressure: Some([7e4, 0.0]),
                tension: None,
            })
        },
        "operating_range.pressure",
    ),
    (
        "negative tension range",
        |d| {
            d.operating_range = Some(softrod_core::spec::OperatingRangeSpec {
                pressure: None,
                tension: Some([-1.0, 10.0]),
            })
        },
        "operating_range.tension",
    ),
    (
        "empty operating range",
        |d| {
            d.operating_range = Some(softrod_core::spec::OperatingRangeSpec {
                pressure: None,
                tension: None,
            })
        },
        "operating_range",
    ),
    (
        "non-contiguous channel indices",
        |d| d.sections[1].chambers[1].channel = 3,
        "chambers.channel",
    ),
    (
        "NaN tip force",
        |d| d.tip.force[1] = f64::NAN,
        "tip.force[1]",
    ),
    (
        "infinite tip moment",
        |d| d.tip.moment[0] = f64::NEG_INFINITY,
        "tip.moment[0]",
    ),
    ("negative tip mass", |d| d.tip.mass = -1e-3, "tip.mass"),
    (
        "NaN tip centre of mass",
        |d| d.tip.com_offset[2] = f64::NAN,
        "tip.com_offset[2]",
    ),
    (
        "infinite gravity",
        |d| d.mounting.gravity[2] = f64::INFINITY,
        "mounting.gravity[2]",
    ),
    (
        "NaN gravity",
        |d| d.mounting.gravity[0] = f64::NAN,
        "mounting.gravity[0]",
    ),
    (
        "NaN base position",
        |d| d.mounting.base_position[1] = f64::NAN,
        "mounting.base_position[1]",
    ),
    (
        "NaN in base rotation",
        |d| d.mounting.base_rotation[1][2] = f64::NAN,
        "mounting.base_rotation[1][2]",
    ),
    (
        "base rotation not orthonormal",
        |d| d.mounting.base_rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.001]],
        "mounting.base_rotation",
    ),
    (
        "base rotation with skewed columns",
        |d| d.mounting.base_rotation = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        "mounting.base_rotation",
    ),
    (
        "base rotation is a reflection",
        |d| d.mounting.base_rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
        "mounting.base_rotation",
    ),
    (
        "line load on a missing section",
        |d| {
            d.loads.push(LineLoadSpec {
                frame: Default::default(),
                section: 4,
                force_per_length: [0.0; 3],
                moment_per_length: [0.0; 3],
            })
        },
        "loads[0].section",
    ),
    (
        "NaN line load",
        |d| {
            d.loads.push(LineLoadSpec {
                frame: Default::default(),
                section: 0,
                force_per_length: [0.0, f64::NAN, 0.0],
                moment_per_length: [0.0; 3],
            })
        },
        "loads[0].force_per_length[1]",
    ),
];

#[test]
fn the_valid_design_is_accepted() {
    let rod = Rod::new(valid()).unwrap();
    assert_eq!(rod.n_channels, 3);
    // limits that must pass: Poisson ratio exactly 0.5 (Dragon Skin: E = 3 G), a chamber
    // tangent to the outer wall, a vacuum of exactly -1 atm
    assert_eq!(DRAGON_SKIN.youngs_modulus, 3.0 * DRAGON_SKIN.shear_modulus);
    let mut spec = valid();
    spec.sections[1].chambers[0].distance = P002_RO - P002_RP;
    Rod::new(spec).unwrap();
    solve(
        &rod,
        &loads(&[-101_325.0, 0.0, 0.0]),
        None,
        &SolverOptions::default(),
    )
    .unwrap();
}

#[test]
fn every_bad_design_names_its_field() {
    for (what, breaker, want) in CASES {
        let mut spec = valid();
        breaker(&mut spec);
        let got = field_of(Rod::new(spec));
        assert_eq!(&got, want, "{what}");
    }
}

#[test]
fn geometry_without_material_is_rejected() {
    // The rule covers "outer_radius and material"; the field named is the section's
    // outer_radius (the first of the pair), so only the section is pinned here.
    let mut spec = valid();
    spec.sections[2].material = None;
    spec.sections[2].mass = Some(0.01);
    let got = field_of(Rod::new(spec));
    assert!(got.starts_with("sections[2]."), "{got}");
}

#[test]
fn error_messages_state_value_and_rule() {
    let mut spec = valid();
    spec.sections[1].chambers[2].distance = 17e-3;
    let msg = Rod::new(spec).unwrap_err().to_string();
    assert!(
        msg.starts_with("sections[1].chambers[2].distance = 0.017: "),
        "{msg}"
    );
    assert!(msg.contains("outside the section"), "{msg}");
}

#[test]
fn bad_pressures_and_tip_loads_are_rejected_by_solve() {
    let rod = Rod::new(valid()).unwrap();
    let opts = SolverOptions::default();
    let field = |p: &[f64], f: [f64; 3]| -> String {
        let mut ld = loads(p);
        ld.tip_force = f;
        match solve(&rod, &ld, None, &opts) {
            Err(SoftrodError::InvalidParameter { field, .. }) => field,
            other => panic!("expected InvalidParameter, got {other:?}"),
        }
    };
    assert_eq!(field(&[0.0, 0.0], [0.0; 3]), "pressures");
    assert_eq!(field(&[0.0; 4], [0.0; 3]), "pressures");
    assert_eq!(field(&[], [0.0; 3]), "pressures");
    assert_eq!(field(&[0.0, -101_326.0, 0.0], [0.0; 3]), "pressures[1]");
    assert_eq!(field(&[0.0, 0.0, f64::NAN], [0.0; 3]), "pressures[2]");
    assert_eq!(field(&[f64::INFINITY, 0.0, 0.0], [0.0; 3]), "pressures[0]");
    assert_eq!(field(&[0.0; 3], [0.0, f64::NAN, 0.0]), "tip_force[1]");
    let mut ld = loads(&[0.0; 3]);
    ld.tip_moment = [f64::INFINITY, 0.0, 0.0];
    assert!(
        matches!(solve(&rod, &ld, None, &opts), Err(SoftrodError::InvalidParameter { field, .. }) if field == "tip_moment[0]")
    );
    // and invalid solver options
    for (o, f) in [
        (SolverOptions { tol: 0.0, ..opts }, "tol"),
        (
            SolverOptions {
                tol: f64::NAN,
                ..opts
            },
            "tol",
        ),
        (
            SolverOptions {
                max_iter: 0,
                ..opts
            },
            "max_iter",
        ),
        (
            SolverOptions {
                max_load_steps: 0,
                ..opts
            },
            "max_load_steps",
        ),
    ] {
        assert!(
            matches!(solve(&rod, &loads(&[0.0; 3]), None, &o), Err(SoftrodError::InvalidParameter { ref field, .. }) if field == f),
            "{f}"
        );
    }
}

#[test]
fn unknown_json_keys_are_rejected() {
    let json = serde_json::to_string(&valid()).unwrap();
    // (the clean string parses; it is not compared for equality: without serde_json's
    // `float_roundtrip` feature a float may come back 1 ulp off)
    Rod::new(serde_json::from_str::<DesignSpec>(&json).unwrap()).unwrap();
    // an extra key at the top, in a section, in a chamber, in the material
    let cases = [
        json.replacen(
            "\"name\":\"test\"",
            "\"name\":\"test\",\"colour\":\"red\"",
            1,
        ),
        json.replacen("\"rigid\":false", "\"rigid\":false,\"stifness\":1.0", 1),
        json.replacen("\"channel\":0", "\"channel\":0,\"chanel\":1", 1),
        json.replacen(
            "\"density\":1070.0",
            "\"density\":1070.0,\"poisson\":0.5",
            1,
        ),
    ];
    for (bad, key) in cases
        .iter()
        .zip(["colour", "stifness", "chanel", "poisson"])
    {
        assert_ne!(bad, &json, "the test failed to insert '{key}'");
        let e = serde_json::from_str::<DesignSpec>(bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("unknown field `{key}`")), "{key}: {e}");
    }
}

#[test]
fn non_convergence_is_an_error_not_a_shape() {
    // A large tip load (alpha = P L^2 / EI = 10) from the straight guess: two Newton
    // iterations cannot get there, and without continuation the solver must say so.
    let (l, ei) = (0.2, 0.01);
    let rod = Rod::new(design(
        vec![direct_section("beam", l, 1e3, 1e3, ei, ei, 0.0, 16)],
        HORIZONTAL,
        0.0,
    ))
    .unwrap();
    let mut ld = loads(&[]);
    ld.tip_force = [0.0, 0.0, -10.0 * ei / (l * l)];
    let strict = SolverOptions {
        continuation: false,
        max_iter: 2,
        ..Default::default()
    };
    match solve(&rod, &ld, None, &strict) {
        Err(SoftrodError::NotConverged {
            iterations,
            residual,
            load_factor,
            reason,
        }) => {
            assert!((1..=2).contains(&iterations), "iterations {iterations}");
            assert!(
                residual.is_finite() && residual > strict.tol,
                "residual {residual}"
            );
            assert_eq!(load_factor, 0.0);
            assert!(reason.contains("continuation is off"), "{reason}");
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    // With continuation but a single load level allowed it also fails, reporting the load
    // factor it reached.
    let one_level = SolverOptions {
        max_iter: 2,
        max_load_steps: 1,
        ..Default::default()
    };
    match solve(&rod, &ld, None, &one_level) {
        Err(SoftrodError::NotConverged {
            iterations,
            residual,
            load_factor,
            ..
        }) => {
            assert!(iterations >= 2 && residual.is_finite() && residual > 0.0);
            assert!(
                (0.0..1.0).contains(&load_factor),
                "load factor {load_factor}"
            );
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    // and the default options do converge
    assert!(solve(&rod, &ld, None, &SolverOptions::default()).is_ok());
}
