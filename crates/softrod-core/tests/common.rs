//! Shared builders for the core's integration tests.
#![allow(dead_code)]

use softrod_core::ode::Loads;
use softrod_core::spec::{ChamberSpec, DesignSpec, MountingSpec, SectionSpec, StiffnessSpec, TipSpec};

pub const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
/// Horizontal mounting: d3 = +x_world, d1 = +z_world, d2 = d3 x d1 = -y_world.
pub const HORIZONTAL: [[f64; 3]; 3] = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]];

/// A uniform elastic section with stiffnesses given directly.
pub fn direct_section(name: &str, length: f64, ea: f64, ga: f64, ei: f64, gj: f64, mass: f64, steps: usize) -> SectionSpec {
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
        stiffness: StiffnessSpec { ea: Some(ea), ga: Some(ga), ei1: Some(ei), ei2: Some(ei), gj: Some(gj) },
        chambers: vec![],
        steps,
    }
}

pub fn design(sections: Vec<SectionSpec>, rotation: [[f64; 3]; 3], g: f64) -> DesignSpec {
    DesignSpec {
        name: "test".into(),
        mounting: MountingSpec { base_position: [0.0; 3], base_rotation: rotation, gravity: [0.0, 0.0, -g] },
        sections,
        tip: TipSpec::default(),
        loads: vec![],
    }
}

pub fn loads(p: &[f64]) -> Loads {
    Loads { pressures: p.to_vec(), tip_force: [0.0; 3], tip_moment: [0.0; 3] }
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

/// Read a validation CSV from ../shared/validation (comment lines start with '#').
pub fn validation_table(name: &str) -> Vec<Vec<f64>> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/validation").join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .skip(1) // header
        .map(|l| l.split(',').map(|v| v.trim().parse::<f64>().unwrap()).collect())
        .collect()
}
