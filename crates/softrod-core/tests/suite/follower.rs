//! Follower loads (tip force and moment and line loads in the body frame): the 6-unknown
//! shooting they need, the end moment that rolls a rod into a circle, the follower force
//! against the dead force it ends up as, exact Jacobians and sensitivities, batches, and
//! stability reported as not assessed. (The follower-force cantilever against the elastica
//! solved by scipy's BVP solver is in tests/test_scope.py.)

use crate::common;
use common::*;
use softrod_core::batch::{sensitivity_batch, solve_batch, BatchInputs};
use softrod_core::ode::Loads;
use softrod_core::sensitivity::{tip_sensitivity, Param, ParamKind};
use softrod_core::spec::{DesignSpec, Frame, LineLoadSpec, TendonSpec};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::Rod;
use std::f64::consts::PI;

const L: f64 = 1.0;
const EI: f64 = 1.0;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

/// An extensible, shearable rod far stiffer in extension and shear than in bending, along
/// +z, no gravity.
fn column(steps: usize) -> DesignSpec {
    design(
        vec![direct_section("rod", L, 1e8, 1e8, EI, 2.0 * EI, 0.0, steps)],
        IDENTITY,
        0.0,
    )
}

fn follower_tip(spec: &DesignSpec, force: [f64; 3], moment: [f64; 3]) -> (Rod, Loads) {
    let mut spec = spec.clone();
    spec.tip.frame = Frame::Body;
    spec.tip.force = force;
    spec.tip.moment = moment;
    let rod = Rod::new(spec).unwrap();
    let ld = Loads::from_design(&rod, vec![]);
    (rod, ld)
}

/// A follower end moment M about d2 bends the rod with the constant curvature M / EI: at
/// M = 2 pi EI / L the rod rolls into a full circle and its tip returns to the base with the
/// base's orientation. The curvature holds at every node to round-off (m is constant in the
/// body frame of a planar rod); positions within the RK4 error of the rotation, which
/// converges at fourth order (checked from 100 to 400 steps). Also tilted about d1 + d2:
/// the same circle in another plane.
#[test]
fn follower_end_moment_rolls_the_rod_into_a_circle() {
    let m = 2.0 * PI * EI / L;
    let mut errs = vec![];
    for steps in [100, 200, 400] {
        let (rod, ld) = follower_tip(&column(steps), [0.0; 3], [0.0, m, 0.0]);
        let sol = solve(&rod, &ld, None, &opts()).unwrap();
        assert_eq!(sol.x.len(), 6);
        assert_eq!(
            sol.stable, None,
            "follower loads: stability is not assessed"
        );
        let sh = shape(&rod, &ld, &sol);
        for u in &sh.u {
            assert!((u[1] - m / EI).abs() < 1e-12 * m && u[0].abs() < 1e-12 && u[2].abs() < 1e-12);
        }
        for (k, s) in sh.s.iter().enumerate() {
            let want = [(1.0 - (s * m).cos()) / m, 0.0, (s * m).sin() / m];
            assert!(dist(&sh.position[k], &want) < 1e-6 * L);
        }
        errs.push(norm(&sol.tip.r));
        // rotation back to the identity
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((sol.tip.rot[i][j] - want).abs() < 1e-6);
            }
        }
    }
    eprintln!("circle closure: {errs:?}");
    for k in 0..2 {
        let ratio = errs[k] / errs[k + 1];
        assert!((13.0..19.0).contains(&ratio), "order: ratio {ratio}");
    }
    let c = m / 2f64.sqrt();
    let (rod, ld) = follower_tip(&column(400), [0.0; 3], [c, c, 0.0]);
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    assert!(norm(&sol.tip.r) < 1e-8 * L, "tip {:?}", sol.tip.r);
}

/// Under a follower tip force the internal force is constant along the rod and equal to the
/// force's final direction: the equilibrium is also the equilibrium under the dead force
/// R(L) F_body. Solving that dead problem from scratch (3 unknowns) gives the same shape.
#[test]
fn follower_force_equilibrium_is_the_dead_force_equilibrium_of_its_final_direction() {
    let spec = column(64);
    let f_body = [2.5, -0.8, 0.3];
    let (rod, ld) = follower_tip(&spec, f_body, [0.0; 3]);
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let f_world: [f64; 3] =
        std::array::from_fn(|i| (0..3).map(|k| sol.tip.rot[i][k] * f_body[k]).sum::<f64>());
    // the follower force turned with the rod: it is not the dead force F_body
    assert!(dist(&f_world, &f_body) > 0.5);
    let dead = Rod::new(spec).unwrap();
    let mut ld2 = loads(&[]);
    ld2.tip_force = f_world;
    let dead_sol = solve(&dead, &ld2, None, &opts()).unwrap();
    assert_eq!(dead_sol.x.len(), 3);
    let err = dist(&sol.tip.r, &dead_sol.tip.r);
    assert!(err < 1e-10 * L, "{err:.2e}");
    assert!(dist(&sol.base_force, &f_world) < 1e-10);
}

/// A design whose loads all follow the body: a follower tip force and moment, follower line
/// loads on two sections and a dead one, tendons, chambers, gravity on a tilted mounting.
fn follower_arm() -> DesignSpec {
    let mut spec = p002_actuator(tilted(), 9.81, 12);
    spec.tip.frame = Frame::Body;
    spec.tip.force = [0.03, -0.02, -0.01];
    spec.tip.moment = [0.0, 4e-4, 1e-4];
    spec.tip.mass = 0.01;
    spec.tip.com_offset = [0.004, -0.002, 0.006];
    spec.loads = vec![
        LineLoadSpec {
            section: 1,
            frame: Frame::Body,
            force_per_length: [0.2, 0.1, -0.05],
            moment_per_length: [0.0, 0.002, 0.001],
        },
        LineLoadSpec {
            section: 2,
            frame: Frame::Body,
            force_per_length: [-0.1, 0.0, 0.0],
            moment_per_length: [0.0; 3],
        },
        LineLoadSpec {
            section: 1,
            frame: Frame::World,
            force_per_length: [0.0, 0.05, 0.0],
            moment_per_length: [0.0; 3],
        },
    ];
    let t = TendonSpec {
        channel: 0,
        distance: 0.017,
        angle: 0.3,
        distance_end: None,
        angle_end: Some(2.0),
    };
    spec.sections[0].tendons = vec![TendonSpec {
        angle_end: None,
        ..t
    }];
    spec.sections[1].tendons = vec![t];
    spec
}

/// Exact Jacobians of the 6-unknown residual (tip force and moment balance) against
/// central differences, with every kind of follower load, on their own and with tendons.
#[test]
fn jacobian_matches_finite_differences_with_follower_loads() {
    let rod = Rod::new(follower_arm()).unwrap();
    let mut ld = Loads::from_design(&rod, vec![25e3, 0.0, 10e3]);
    check_jacobian_against_fd("follower", &rod, &ld, &opts(), 3);
    ld.tensions = vec![1.2];
    check_jacobian_against_fd("follower + tendon", &rod, &ld, &opts(), 4);
    // a follower line load alone (tip loads dead) also needs the 6 unknowns
    let mut spec = follower_arm();
    spec.tip.frame = Frame::World;
    let rod = Rod::new(spec).unwrap();
    let ld = Loads::from_design(&rod, vec![25e3, 0.0, 10e3]);
    assert_eq!(solve(&rod, &ld, None, &opts()).unwrap().x.len(), 6);
    check_jacobian_against_fd("follower line loads", &rod, &ld, &opts(), 9);
}

/// Parameter derivatives of the tip pose under follower loads (6 unknowns) against central
/// differences; batch rows and batch sensitivities equal single solves.
#[test]
fn sensitivities_and_batches_with_follower_loads() {
    let spec = follower_arm();
    let rod = Rod::new(spec.clone()).unwrap();
    let mut ld = Loads::from_design(&rod, vec![10e3, 20e3, 0.0]);
    ld.tensions = vec![0.5];
    let params = [Param {
        kind: ParamKind::CorrectionFactor(2),
        sections: vec![1],
    }];
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    let exact = tip_sensitivity(&rod, &ld, &sol, &params).unwrap().position[0];
    let tip = |h: f64| {
        let mut s = spec.clone();
        s.sections[1].c_b += h;
        solve(&Rod::new(s).unwrap(), &ld, Some(&sol.x), &opts())
            .unwrap()
            .tip
            .r
    };
    let h = 1e-6;
    let (rp, rm) = (tip(h), tip(-h));
    let fd: [f64; 3] = std::array::from_fn(|i| (rp[i] - rm[i]) / (2.0 * h));
    assert!(dist(&exact, &fd) < 1e-6 * norm(&fd), "{exact:?} vs {fd:?}");

    let p: Vec<f64> = (0..4).flat_map(|k| [5e3 * k as f64, 1e4, 0.0]).collect();
    let t: Vec<f64> = (0..4).map(|k| 0.3 * k as f64).collect();
    let inputs = BatchInputs {
        pressures: &p,
        tensions: Some(&t),
        stiffness_scale: None,
        tip_force: spec.tip.force,
        tip_moment: spec.tip.moment,
    };
    let rows = solve_batch(&rod, &inputs, &opts(), 2).unwrap();
    let sens = sensitivity_batch(&rod, &inputs, None, &params, &[], &opts(), 2).unwrap();
    for (r, row) in rows.iter().enumerate() {
        let mut l = Loads::from_design(&rod, p[3 * r..3 * r + 3].to_vec());
        l.tensions = vec![t[r]];
        let single = solve(&rod, &l, None, &opts()).unwrap();
        assert_eq!(row.tip_position, single.tip.r);
        assert_eq!(row.x.len(), 6);
        assert_eq!(row.x, single.x);
        assert_eq!(row.stable, None);
        let s = tip_sensitivity(&rod, &l, &single, &params).unwrap();
        assert_eq!(sens[r].sensitivity.as_ref().unwrap().position, s.position);
    }
}

/// A zero follower load is no follower load: the fast 3-unknown path, whose stability is
/// assessed.
#[test]
fn zero_follower_loads_keep_the_three_unknown_path() {
    let (rod, ld) = follower_tip(&column(32), [0.0; 3], [0.0; 3]);
    let mut ld = ld;
    ld.tip_force = [0.0; 3];
    let sol = solve(&rod, &ld, None, &opts()).unwrap();
    assert_eq!(sol.x.len(), 3);
    assert_eq!(sol.stable, Some(true));
}
