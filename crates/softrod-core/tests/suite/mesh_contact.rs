//! Triangle-mesh obstacles in the statics and dynamics (docs/contact.md, "Triangle
//! meshes"): a plane given as two triangles is the plane obstacle to round-off, a rod
//! pressed onto an icosphere converges to the sphere obstacle's answer as the mesh is
//! refined, the contact forces balance the load, and a rod dropped onto a mesh table settles
//! on the static equilibrium.

// Index loops over 3-vectors read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Simulator};
use softrod_core::mesh::{cuboid, icosphere};
use softrod_core::spec::obstacle::{ObstacleKind, ObstacleSpec};
use softrod_core::spec::DesignSpec;
use softrod_core::statics::contact::report;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

const G: f64 = 9.81;

fn mesh_obstacle(
    (vertices, faces): (Vec<[f64; 3]>, Vec<[usize; 3]>),
    k: f64,
    tolerance: f64,
) -> ObstacleSpec {
    ObstacleSpec {
        vertices: Some(vertices),
        faces: Some(faces),
        ..obstacle(ObstacleKind::Mesh, k, tolerance)
    }
}

/// The square [-2, 2]^2 at height z as two triangles, normal +z.
fn patch(z: f64) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    (
        vec![
            [-2.0, -2.0, z],
            [2.0, -2.0, z],
            [2.0, 2.0, z],
            [-2.0, 2.0, z],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
}

/// A 1 m horizontal cantilever (EI = 10 N m^2, q = 1 N/m) clamped c above a plane, as in
/// tests/suite/contact.rs, with the plane as `table`.
fn cantilever_over(table: ObstacleSpec) -> DesignSpec {
    let sec = direct_section("beam", 1.0, 1e8, 1e8, 10.0, 10.0, 1.0 / G, 400);
    let mut d = design(vec![sec], HORIZONTAL, G);
    d.obstacles = vec![table];
    d
}

/// On a patch the nearest feature of every point above the interior is a face (or the
/// diagonal edge, whose distance is the same plane distance), so the mesh's d and normal
/// are the plane's: the same equilibrium to round-off (1e-12 of the forces' scale).
#[test]
fn a_two_triangle_plane_is_the_plane() {
    let c = 0.5f64.powi(4) / 720.0;
    let (k, tol) = (1e6, 5e-5);
    let mut plane = obstacle(ObstacleKind::Plane, k, tol);
    plane.point = Some([0.0, 0.0, -c]);
    plane.normal = Some([0.0, 0.0, 1.0]);
    plane.smoothing = Some(2e-7);
    let mut mesh = mesh_obstacle(patch(-c), k, tol);
    mesh.smoothing = Some(2e-7);
    let l = loads(&[]);
    let opts = SolverOptions::default();
    let mut answers = vec![];
    for ob in [plane, mesh] {
        let rod = Rod::new(cantilever_over(ob)).unwrap();
        let sol = solve(&rod, &l, None, &opts).expect("the plane and the patch both solve");
        let rep = report(&rod, &l, &sol).unwrap().unwrap();
        // Global balance: n(0) = weight + contact, to the solver's tolerance.
        let total = rep.force[0][2];
        assert!((sol.base_force[2] - (total - 1.0)).abs() < 1e-9);
        assert!(rep.max_penetration > 0.0 && rep.max_penetration <= tol);
        answers.push((sol.base_force, sol.base_moment, sol.tip.r, total));
    }
    let (a, b) = (&answers[0], &answers[1]);
    for i in 0..3 {
        assert!(
            (a.0[i] - b.0[i]).abs() <= 1e-12,
            "force {:?} {:?}",
            a.0,
            b.0
        );
        assert!(
            (a.1[i] - b.1[i]).abs() <= 1e-12,
            "moment {:?} {:?}",
            a.1,
            b.1
        );
        assert!((a.2[i] - b.2[i]).abs() <= 1e-12, "tip {:?} {:?}", a.2, b.2);
    }
    assert!((a.3 - b.3).abs() <= 1e-12);
}

/// A 0.5 m cantilever (EI = 1 N m^2, weightless) pushed down at its tip by 0.1 N onto a
/// ball of radius 50 mm whose top lies 2 mm below the tip (tests/suite/contact.rs), the ball as a
/// sphere obstacle or an icosphere of 20 * 4^level triangles. The icosphere lies between the
/// sphere and the ball of its smallest face distance r_in, so its distance differs from the
/// sphere's by at most delta = R - r_in (0 to delta): the tip's support moves by at most
/// delta, which changes the reaction by at most 3 EI delta / L^3 (the cantilever's tip
/// stiffness); the facets' normals tilt the force by at most the angle e / R of an edge,
/// which changes its vertical part by a factor cos(e / R) (second order). The reaction
/// converges to the sphere's; every answer balances the load to 1e-9 and stays within the
/// tolerance.
#[test]
fn an_icosphere_converges_to_the_sphere() {
    let (l_rod, r_s, d0, p) = (0.5, 0.05, 2e-3, 0.1);
    let (k, tol) = (1e7, 1e-4);
    let center = [l_rod, 0.0, -(d0 + r_s)];
    let spec = |ob: ObstacleSpec| {
        let sec = direct_section("beam", l_rod, 1e8, 1e8, 1.0, 1.0, 0.0, 200);
        let mut d = design(vec![sec], HORIZONTAL, 0.0);
        d.tip.force = [0.0, 0.0, -p];
        d.obstacles = vec![ob];
        d
    };
    let solve_with = |ob: ObstacleSpec| {
        let rod = Rod::new(spec(ob)).unwrap();
        let l = softrod_core::ode::Loads {
            tip_force: rod.spec.tip.force,
            ..loads(&[])
        };
        let sol = solve(&rod, &l, None, &SolverOptions::default()).unwrap();
        let rep = report(&rod, &l, &sol).unwrap().unwrap();
        let f = rep.force[0];
        for i in 0..3 {
            let want = rod.spec.tip.force[i] + f[i];
            assert!((sol.base_force[i] - want).abs() < 1e-9 * p);
        }
        assert!(rep.max_penetration > 0.0 && rep.max_penetration <= tol);
        (f[2], sol.tip.r)
    };
    let mut ball = obstacle(ObstacleKind::Sphere, k, tol);
    ball.center = Some(center);
    ball.radius = Some(r_s);
    let (exact, tip) = solve_with(ball);
    let mut last = f64::INFINITY;
    for level in 2..=5 {
        let (v, f) = icosphere(center, r_s, level);
        let m = softrod_core::mesh::TriMesh::new("obstacles[0]", &v, &f).unwrap();
        let r_in = f
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let a = m.vertices[t[0]];
                let n = m.face_normals[i];
                (0..3).map(|j| (center[j] - a[j]) * n[j]).sum::<f64>().abs()
            })
            .fold(f64::INFINITY, f64::min);
        let delta = r_s - r_in;
        let edge = f
            .iter()
            .flat_map(|t| (0..3).map(move |j| (t[j], t[(j + 1) % 3])))
            .map(|(a, b)| {
                (0..3)
                    .map(|j| (v[a][j] - v[b][j]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        let (rz, tip_m) = solve_with(mesh_obstacle((v, f), k, tol));
        let err = (rz - exact).abs();
        let bound = 3.0 * delta / l_rod.powi(3) + exact * (1.0 - (edge / r_s).cos());
        let dtip = (0..3)
            .map(|j| (tip_m[j] - tip[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        eprintln!("level {level}: R {rz:.6e} sphere {exact:.6e} err {err:.2e} bound {bound:.2e} delta {delta:.2e} tip off {dtip:.2e}");
        assert!(err <= bound, "level {level}: {err} > {bound}");
        // The tip follows its support: it moves by at most delta (plus the penalty's
        // change of sinking with the reaction, err / k per length: negligible).
        assert!(
            dtip <= 1.1 * delta,
            "level {level}: tip off by {dtip}, delta {delta}"
        );
        // Measured: the error halves with the edge (first order, from the facets'
        // tilt at the contact point): it falls at every level.
        assert!(err < last, "level {level}: {err} after {last}");
        last = err;
    }
    // Level 5 (20480 triangles, edges of 1.7 mm on a 50 mm ball): within 1e-4 of the
    // sphere's reaction (measured 5.5e-5).
    assert!(last < 1e-4 * exact, "{last}");
}

/// A cantilever (0.2 m, EI = 0.01 N m^2, 0.1 kg/m) released straight 10 mm above a table
/// given as a closed box mesh (its top 10 mm below the base), with Kelvin-Voigt damping
/// tau = 0.05 s, falls, lands and settles: after 2 s (the slowest mode's envelope is down
/// to 1e-17, tests/suite/dynamics_contact.rs) it lies on the static equilibrium of the same
/// discretisation to 1e-9 L, and the clamp and the table carry the weight to 1e-9 W.
#[test]
fn dropped_rod_settles_on_a_mesh_table() {
    let (length, mass, ei) = (0.2, 0.02, 0.01);
    let sec = direct_section("beam", length, 1e4, 1e4, ei, ei, mass, 10);
    let mut d = design(vec![sec], HORIZONTAL, G);
    d.obstacles = vec![mesh_obstacle(
        cuboid([-0.5, -0.3, -0.05], [0.5, 0.3, -0.01]),
        1e4,
        3e-3,
    )];
    d.dynamics.damping_time = 0.05;
    let rod = Rod::new(d).unwrap();
    let opts = DynOptions {
        dt: 2e-3,
        tol: 1e-12,
        ..Default::default()
    };
    let mut sim = Simulator::new(rod.clone(), &[], Initial::Straight, opts).unwrap();
    let mut touched = false;
    for _ in 0..1000 {
        sim.step(&[]).unwrap();
        touched |= sim.contact_state().unwrap().max_penetration > 0.0;
    }
    assert!(touched, "the rod reaches the table");
    let rest = Simulator::new(rod, &[], Initial::Static, opts).unwrap();
    let (a, b) = (sim.tip().r, rest.tip().r);
    let off = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
    let c = sim.contact_state().unwrap();
    let (n0, _) = sim.base_wrench();
    let w = mass * G;
    eprintln!(
        "tip {a:?}, static {b:?}, off {off:.2e}; contact {:?}",
        c.force
    );
    assert!(a[2] < -0.009, "the tip rests on the table");
    assert!(off < 1e-9 * length, "{off}");
    assert!((n0[2] - (c.force[2] - w)).abs() < 1e-9 * w);
    assert!(c.force[2] > 0.1 * w);
}

/// The statics' refusals reach a mesh: an unloaded rod through the mesh is refused before
/// any solve, naming the obstacle; a rod that would sink deeper than the tolerance is an
/// error, not a shape.
#[test]
fn mesh_refusals() {
    // The box around the clamp: the unloaded rod starts inside it.
    let inside = mesh_obstacle(cuboid([-0.1, -0.1, -0.1], [0.3, 0.1, 0.1]), 1e6, 1e-4);
    let rod = Rod::new(cantilever_over(inside)).unwrap();
    let err = solve(&rod, &loads(&[]), None, &SolverOptions::default()).unwrap_err();
    assert!(format!("{err}").contains("obstacles[0]"), "{err}");
    // A bad mesh is refused when the rod is built, naming the entry.
    let mut bad = mesh_obstacle(patch(-0.1), 1e6, 1e-4);
    bad.faces = Some(vec![[0, 1, 2], [0, 1, 3]]);
    let err = Rod::new(cantilever_over(bad)).unwrap_err();
    assert!(format!("{err}").contains("obstacles[0].faces[1]"), "{err}");
    let mut other = obstacle(ObstacleKind::Sphere, 1e6, 1e-4);
    other.center = Some([0.0; 3]);
    other.radius = Some(0.1);
    other.faces = Some(vec![[0, 1, 2]]);
    let err = Rod::new(cantilever_over(other)).unwrap_err();
    assert!(format!("{err}").contains("obstacles[0].faces"), "{err}");
}

/// A cantilever along the crease of a V-groove (slopes of 0.2 across y, the crease along x
/// 0.5 mm below the clamp), in its bisecting plane y = 0: the nearest point per cross-section
/// jumps from one slope to the other across that plane, so the exact distance gives no
/// equilibrium there; blended over the smoothing length (docs/contact.md, "Triangle
/// meshes") the rod settles into the groove on both slopes: it converges, stays in the plane
/// y = 0 by symmetry, balances its weight to 1e-9 and sinks no deeper than the tolerance.
#[test]
fn a_rod_along_a_v_groove_settles_in_it() {
    let v = vec![
        [-1.0, -1.0, 0.2 - 5e-4],
        [-1.0, 0.0, -5e-4],
        [-1.0, 1.0, 0.2 - 5e-4],
        [2.0, -1.0, 0.2 - 5e-4],
        [2.0, 0.0, -5e-4],
        [2.0, 1.0, 0.2 - 5e-4],
    ];
    // Counter-clockwise seen from above (normals up, into the groove's open side).
    let f = vec![[0, 3, 4], [0, 4, 1], [1, 4, 5], [1, 5, 2]];
    let (k, tol) = (1e6, 5e-5);
    let mut groove = mesh_obstacle((v, f), k, tol);
    groove.smoothing = Some(2e-6);
    let rod = Rod::new(cantilever_over(groove)).unwrap();
    let l = loads(&[]);
    let sol = solve(&rod, &l, None, &SolverOptions::default()).unwrap();
    let rep = report(&rod, &l, &sol).unwrap().unwrap();
    let f = rep.force[0];
    eprintln!("groove: contact {f:?} N, tip {:?}", sol.tip.r);
    assert!((sol.base_force[2] - (f[2] - 1.0)).abs() < 1e-9);
    assert!(f[2] > 0.1, "the groove carries part of the weight");
    assert!(f[1].abs() < 1e-9 && sol.tip.r[1].abs() < 1e-9);
    assert!(rep.max_penetration > 0.0 && rep.max_penetration <= tol);
}
