//! Shared builders for the core's integration tests.
#![allow(dead_code)]

use softrod_core::ode::Loads;
use softrod_core::spec::{
    ChamberSpec, DesignSpec, LawSpec, MaterialSpec, MountingSpec, SectionSpec, StiffnessSpec,
    TipSpec,
};

pub const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
/// Horizontal mounting: d3 = +x_world, d1 = +z_world, d2 = d3 x d1 = -y_world.
pub const HORIZONTAL: [[f64; 3]; 3] = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]];

/// A uniform elastic section with stiffnesses given directly.
#[allow(clippy::too_many_arguments)] // mirrors the section's own fields
pub fn direct_section(
    name: &str,
    length: f64,
    ea: f64,
    ga: f64,
    ei: f64,
    gj: f64,
    mass: f64,
    steps: usize,
) -> SectionSpec {
    SectionSpec {
        name: name.into(),
        length,
        rigid: false,
        outer_radius: None,
        bore_radius: 0.0,
        material: None,
        mass: Some(mass),
        c_s: 1.0,
        c_e: 1.0,
        c_b: 1.0,
        c_t: 1.0,
        stiffness: StiffnessSpec {
            ea: Some(ea),
            ga: Some(ga),
            ei1: Some(ei),
            ei2: Some(ei),
            gj: Some(gj),
        },
        chambers: vec![],
        steps,
        law: LawSpec::default(),
        partition: None,
    }
}

pub fn design(sections: Vec<SectionSpec>, rotation: [[f64; 3]; 3], g: f64) -> DesignSpec {
    DesignSpec {
        name: "test".into(),
        mounting: MountingSpec {
            base_position: [0.0; 3],
            base_rotation: rotation,
            gravity: [0.0, 0.0, -g],
        },
        sections,
        tip: TipSpec::default(),
        loads: vec![],
    }
}

pub fn loads(p: &[f64]) -> Loads {
    Loads {
        pressures: p.to_vec(),
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
        stiffness_scale: [1.0; 3],
    }
}

pub fn chamber(radius: f64, distance: f64, angle_deg: f64, channel: usize) -> ChamberSpec {
    ChamberSpec {
        area: std::f64::consts::PI * radius * radius,
        radius: Some(radius),
        distance,
        angle: angle_deg.to_radians(),
        channel,
    }
}

/// Read a validation CSV from tests/data (a copy of the project's shared validation set, so
/// the tests run from a fresh clone; comment lines start with '#').
pub fn validation_table(name: &str) -> Vec<Vec<f64>> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .skip(1) // header
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse::<f64>().unwrap())
                .collect()
        })
        .collect()
}

/// Ecoflex 00-50 (paper 002, Table II): E = 0.08 MPa, G = 0.027 MPa, 1070 kg/m^3.
pub const ECOFLEX: MaterialSpec = MaterialSpec {
    youngs_modulus: 80e3,
    shear_modulus: 27e3,
    density: 1070.0,
};
/// Dragon Skin 30 (paper 002, Table II): E = 0.6 MPa, G = 0.2 MPa, 1080 kg/m^3.
pub const DRAGON_SKIN: MaterialSpec = MaterialSpec {
    youngs_modulus: 600e3,
    shear_modulus: 200e3,
    density: 1080.0,
};

/// Paper 002, Table I: outer radius, bore radius, chamber radius, chamber centroid distance,
/// cap lengths d^a, d^c and body length l, all in m.
pub const P002_RO: f64 = 21.1e-3;
pub const P002_RI: f64 = 2.9e-3;
pub const P002_RP: f64 = 5.15e-3;
pub const P002_RHO: f64 = 12e-3;
pub const P002_CAP_A: f64 = 14e-3;
pub const P002_CAP_C: f64 = 10e-3;
pub const P002_BODY: f64 = 110e-3;

/// A section whose stiffness and weight follow from geometry and material.
pub fn geometry_section(
    name: &str,
    length: f64,
    outer_radius: f64,
    bore_radius: f64,
    material: MaterialSpec,
    chambers: Vec<ChamberSpec>,
    steps: usize,
) -> SectionSpec {
    SectionSpec {
        name: name.into(),
        length,
        rigid: false,
        outer_radius: Some(outer_radius),
        bore_radius,
        material: Some(material),
        mass: None,
        c_s: 1.0,
        c_e: 1.0,
        c_b: 1.0,
        c_t: 1.0,
        stiffness: StiffnessSpec::default(),
        chambers,
        steps,
        law: LawSpec::default(),
        partition: None,
    }
}

/// A rigid section that only carries its mass.
pub fn rigid_section(name: &str, length: f64, mass: f64) -> SectionSpec {
    SectionSpec {
        name: name.into(),
        length,
        rigid: true,
        outer_radius: None,
        bore_radius: 0.0,
        material: None,
        mass: Some(mass),
        c_s: 1.0,
        c_e: 1.0,
        c_b: 1.0,
        c_t: 1.0,
        stiffness: StiffnessSpec::default(),
        chambers: vec![],
        steps: 1,
        law: LawSpec::default(),
        partition: None,
    }
}

/// Paper 002's three chambers (r_p at rho_p) at the given angles in degrees, channels 0, 1, 2.
pub fn p002_chambers(angles_deg: [f64; 3]) -> Vec<ChamberSpec> {
    angles_deg
        .iter()
        .enumerate()
        .map(|(k, &a)| chamber(P002_RP, P002_RHO, a, k))
        .collect()
}

/// Paper 002's actuator: Dragon Skin cap (d^a) / Ecoflex body with three chambers at 90, 210
/// and 330 deg / Dragon Skin cap (d^c), `steps` RK4 steps in each section.
pub fn p002_actuator(rotation: [[f64; 3]; 3], g: f64, steps: usize) -> DesignSpec {
    design(
        vec![
            geometry_section(
                "cap_a",
                P002_CAP_A,
                P002_RO,
                P002_RI,
                DRAGON_SKIN,
                vec![],
                steps,
            ),
            geometry_section(
                "body",
                P002_BODY,
                P002_RO,
                P002_RI,
                ECOFLEX,
                p002_chambers([90.0, 210.0, 330.0]),
                steps,
            ),
            geometry_section(
                "cap_c",
                P002_CAP_C,
                P002_RO,
                P002_RI,
                DRAGON_SKIN,
                vec![],
                steps,
            ),
        ],
        rotation,
        g,
    )
}

/// Column j of a row-major rotation matrix (director d_{j+1} in world coordinates).
pub fn column(rot: &[[f64; 3]; 3], j: usize) -> [f64; 3] {
    [rot[0][j], rot[1][j], rot[2][j]]
}

pub fn norm(a: &[f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

pub fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    norm(&[a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// Deterministic "random-ish" numbers in [-1, 1) (64-bit LCG, Knuth's MMIX constants), so
/// that the tests are reproducible without a dev-dependency.
pub struct Lcg(pub u64);

impl Lcg {
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}
