//! The exact (dual-number) Jacobian of the shooting residual against central finite
//! differences of the plain residual, at points that are not the solution.

use crate::common;
use common::*;
use softrod_core::ode::Loads;
use softrod_core::spec::{DesignSpec, LineLoadSpec, TipSpec};
use softrod_core::statics::SolverOptions;
use softrod_core::Rod;

/// The shared check (tests/suite/common.rs) at the default solver options.
fn check_against_fd(name: &str, rod: &Rod, ld: &Loads) {
    check_jacobian_against_fd(name, rod, ld, &SolverOptions::default(), 0x5EED_0F50_F70D);
}

#[test]
fn jacobian_matches_fd_for_pressurised_spa_with_tip_body() {
    // Paper 002's actuator, horizontal (gravity across the axis), three pressures and its
    // marker plate: 17.25 g with the centre of mass at (9.3, 2.9, -1.1) mm in the tip frame,
    // so the residual's moment part depends on the tip rotation.
    let mut spec: DesignSpec = p002_actuator(HORIZONTAL, 9.81, 16);
    spec.tip = TipSpec {
        mass: 17.25e-3,
        com_offset: [9.3e-3, 2.9e-3, -1.1e-3],
        ..Default::default()
    };
    let rod = Rod::new(spec).unwrap();
    check_against_fd("SPA", &rod, &loads(&[30e3, 10e3, 50e3]));
    // and tilted, with a tip force and moment on top
    let mut spec = p002_actuator(tilted(), 9.81, 16);
    spec.tip = TipSpec {
        mass: 17.25e-3,
        com_offset: [9.3e-3, 2.9e-3, -1.1e-3],
        ..Default::default()
    };
    let rod = Rod::new(spec).unwrap();
    let mut ld = loads(&[60e3, 0.0, 25e3]);
    ld.tip_force = [0.05, -0.1, 0.02];
    ld.tip_moment = [0.002, 0.001, -0.003];
    check_against_fd("SPA tilted", &rod, &ld);
}

#[test]
fn jacobian_matches_fd_with_rigid_section_and_line_loads() {
    let mut spec = design(
        vec![
            direct_section("lower", 0.1, 40.0, 25.0, 4e-3, 2e-3, 0.02, 16),
            rigid_section("connector", 0.015, 0.01),
            direct_section("upper", 0.08, 40.0, 25.0, 3e-3, 1.5e-3, 0.015, 16),
        ],
        tilted(),
        9.81,
    );
    spec.loads = vec![
        LineLoadSpec {
            frame: Default::default(),
            section: 0,
            force_per_length: [0.3, -0.2, 0.1],
            moment_per_length: [0.01, 0.0, -0.02],
        },
        LineLoadSpec {
            frame: Default::default(),
            section: 1,
            force_per_length: [0.0, 0.5, 0.0],
            moment_per_length: [0.0, 0.03, 0.0],
        },
        LineLoadSpec {
            frame: Default::default(),
            section: 2,
            force_per_length: [-0.1, 0.0, 0.2],
            moment_per_length: [0.0; 3],
        },
    ];
    spec.tip = TipSpec {
        mass: 0.005,
        com_offset: [0.01, 0.0, 0.005],
        ..Default::default()
    };
    let rod = Rod::new(spec).unwrap();
    let mut ld = loads(&[]);
    ld.tip_force = [0.02, 0.0, -0.01];
    ld.tip_moment = [0.0, 0.001, 0.0];
    check_against_fd("rigid + line loads", &rod, &ld);
}
