//! Collocation statics (crate::collocation): fourth order, against single shooting, the
//! elastica, and on the long soft rods where single shooting fails.

use crate::common;

use common::*;
use softrod_core::spec::MaterialSpec;
use softrod_core::statics::collocation::{shooting_growth, solve_static, SHOOTING_GROWTH_LIMIT};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::validity::{Policy, Rule};
use softrod_core::{Rod, SoftrodError};

fn pam_arm(steps: usize) -> Rod {
    pam_arm_of(0.22, 0.165, steps)
}

/// Paper 000's arm of a length and mass (designs/pam_arm_220mm.toml, pam_arm_1m.toml).
fn pam_arm_of(length: f64, mass: f64, steps: usize) -> Rod {
    let sec = pam_arm_section(length, mass, steps);
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    Rod::new(design(vec![sec], hanging, 9.81)).unwrap()
}

fn tight() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

#[test]
fn collocation_and_shooting_converge_together_at_fourth_order() {
    // Paper 000's arm bent by 1.5 and 0.6 bar: the two discretisations differ by their
    // O(h^4) errors, so the difference must fall 16x per halving of h (orders in
    // [3.5, 4.5]); at 32 steps it is below 1e-7 L (measured 2.8e-8 L).
    let p = [150e3, 0.0, 60e3];
    let diffs: Vec<f64> = [8, 16, 32]
        .iter()
        .map(|&steps| {
            let rod = pam_arm(steps);
            let a = solve(&rod, &loads(&p), None, &tight()).unwrap();
            let b = solve_static(&rod, &loads(&p), None, &tight()).unwrap();
            dist(&a.tip.r, b.evaluated.node_r.last().unwrap())
        })
        .collect();
    let orders = [(diffs[0] / diffs[1]).log2(), (diffs[1] / diffs[2]).log2()];
    eprintln!("tip differences {diffs:?} m, orders {orders:?}");
    for q in orders {
        assert!(q > 3.5 && q < 4.5, "order {q}");
    }
    assert!(diffs[2] < 1e-7 * 0.22);
}

#[test]
fn collocation_matches_the_elastica() {
    // The tip-load table (elliptic integrals) with EA = GA = 1e8 EI/L^2 (tests/suite/published.rs
    // explains why that leaves < 1e-7 L), 64 intervals: Gauss collocation errs by ~(h/L)^4
    // alpha^2 / 4320 ~ 1e-11 here.
    let table = validation_table("cantilever_tip_load.csv");
    let k = 1e8;
    let rod = Rod::new(design(
        vec![direct_section("beam", 1.0, k, k, 1.0, 1.0, 0.0, 64)],
        HORIZONTAL,
        0.0,
    ))
    .unwrap();
    for row in &table {
        let mut ld = loads(&[]);
        ld.tip_force = [0.0, 0.0, -row[0]];
        let sol = solve_static(&rod, &ld, None, &tight()).unwrap();
        let tip = sol.evaluated.node_r.last().unwrap();
        let (x, d) = (tip[0], -tip[2]);
        eprintln!(
            "alpha {}: deflection {d:.10} vs {:.10}, shortening {:.10} vs {:.10}",
            row[0],
            row[1],
            1.0 - x,
            row[2]
        );
        assert!((d - row[1]).abs() < 1e-6 && (1.0 - x - row[2]).abs() < 1e-6);
    }
}

fn soft_rod(length: f64, rotation: [[f64; 3]; 3], steps: usize) -> Rod {
    let mat = MaterialSpec {
        youngs_modulus: 100e3,
        shear_modulus: 100e3 / 3.0,
        density: 1000.0,
    };
    let sec = geometry_section("rod", length, 0.0125, 0.0, mat, vec![], steps);
    Rod::new(design(vec![sec], rotation, 9.81)).unwrap()
}

#[test]
fn long_soft_rods_are_solved_by_collocation() {
    // A soft rod (E = 100 kPa, r = 12.5 mm) clamped horizontally under its own weight.
    // At 0.22 m single shooting is well conditioned (growth exp(3.4)) and keeps solving
    // it. At 1 m the growth is exp(33): shooting's continuation returned a coiled
    // equilibrium (tip 0.23 m below the base, behind it) and at 2 m it failed; statics now
    // routes both to collocation, which finds the hanging shape. Its accuracy: the same
    // solve with twice the intervals moves the tip by 15/16 of the 32-interval error
    // (fourth order): below 1e-3 L (measured 2e-4 L at 1 m).
    let short = soft_rod(0.22, HORIZONTAL, 16);
    assert!(shooting_growth(&short, &loads(&[])) < SHOOTING_GROWTH_LIMIT);
    assert!(solve(&short, &loads(&[]), None, &SolverOptions::default())
        .unwrap()
        .collocation
        .is_none());
    // Hanging from a horizontal clamp, these rods bend at the clamp far beyond the model's
    // default fibre-stretch range (stretch 0.16 at 1 m against [1/3, 3]): collocation
    // solutions pass the same validity rules as shooting ones, so the default policy
    // refuses them and `Policy::Warn` returns them with the violation listed.
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..SolverOptions::default()
    };
    for length in [1.0, 2.0] {
        let rod = soft_rod(length, HORIZONTAL, 32);
        let growth = shooting_growth(&rod, &loads(&[]));
        match solve(&rod, &loads(&[]), None, &SolverOptions::default()) {
            Err(SoftrodError::InvalidState {
                rule: Rule::StrainRange,
                ..
            }) => {}
            other => panic!("expected the strain-range error, got {other:?}"),
        }
        let sol = solve(&rod, &loads(&[]), None, &warn).unwrap();
        assert!(sol.collocation.is_some(), "routed to collocation");
        assert!(
            matches!(
                sol.violations.as_slice(),
                [SoftrodError::InvalidState {
                    rule: Rule::StrainRange,
                    ..
                }]
            ),
            "{:?}",
            sol.violations
        );
        let fine = solve(&soft_rod(length, HORIZONTAL, 64), &loads(&[]), None, &warn).unwrap();
        let sh = shape(&rod, &loads(&[]), &sol);
        eprintln!(
            "L = {length} m: growth exp({growth:.1}); tip {:?}, 64 intervals {:?}; {} Newton iterations, {} load levels",
            sol.tip.r, fine.tip.r, sol.iterations, sol.load_steps
        );
        assert!(growth > SHOOTING_GROWTH_LIMIT);
        // It hangs: the tip below the base by more than 0.9 L, in front of it.
        assert!(sol.tip.r[2] < -0.9 * length && sol.tip.r[0] > 0.0);
        assert!(dist(&sol.tip.r, &fine.tip.r) < 1e-3 * length);
        // The shape comes from the solve itself (shooting from x would diverge).
        assert_eq!(sh.position.last().unwrap(), &sol.tip.r);
        assert_eq!(sh.s.len(), 33);
    }
}

// ---- Stability of collocation solutions (the conjugate-point test carried by the
// linearised collocation equations in a re-orthonormalised basis; docs/model.md,
// "Collocation" and "Validity and stability").

/// An upright column (L = 1 m, EI = 1 N m^2, GJ = 2 EI, extension and shear 1e10 EI/L^2 as
/// in tests/suite/stability.rs), clamped at the base.
fn upright_column(steps: usize, line_mass: f64, g: f64) -> Rod {
    let k = 1e10;
    Rod::new(design(
        vec![direct_section(
            "column", 1.0, k, k, 1.0, 2.0, line_mass, steps,
        )],
        IDENTITY,
        g,
    ))
    .unwrap()
}

/// Euler's load of the clamped-free column, pi^2 EI / (4 L^2).
const P_CR: f64 = std::f64::consts::PI * std::f64::consts::PI / 4.0;

fn tip_force(f: [f64; 3]) -> softrod_core::ode::Loads {
    let mut ld = loads(&[]);
    ld.tip_force = f;
    ld
}

/// Every case where both solvers run: single shooting's verdict (`solve`, which shoots
/// these well-conditioned rods) and the collocation test's (`solve_static`, collocation
/// forced) agree. Cases: the straight column on both sides of Euler's load (0.5 to 5
/// P_cr: at 5 P_cr only the conjugate point flags it, kL = 3.51 > pi), the heavy column on
/// both sides of Greenhill's load, the column bent past buckling by a lateral force (the
/// stable buckled branch), paper 000's arm at pressures over its range and the 0.22 m soft
/// cantilever under its own weight.
#[test]
fn collocation_stability_agrees_with_shooting() {
    let opts = tight();
    let mut cases: Vec<(String, Rod, softrod_core::ode::Loads, Option<bool>)> = vec![];
    for (ratio, want) in [
        (0.5, true),
        (0.97, true),
        (1.03, false),
        (1.5, false),
        (2.0, false),
        (5.0, false),
    ] {
        cases.push((
            format!("column at {ratio} P_cr"),
            upright_column(100, 0.0, 0.0),
            tip_force([0.0, 0.0, -ratio * P_CR]),
            Some(want),
        ));
    }
    // Greenhill's self-weight load (q L^3 / EI)_cr = 7.8373.
    for (ratio, want) in [(0.97, true), (1.03, false)] {
        let q = ratio * 7.8373;
        cases.push((
            format!("heavy column at {ratio} q_cr"),
            upright_column(100, q / 9.81, 9.81),
            loads(&[]),
            Some(want),
        ));
    }
    cases.push((
        "column at 2 P_cr bent by 2e-3 P_cr".into(),
        upright_column(100, 0.0, 0.0),
        tip_force([2e-3 * P_CR, 0.0, -2.0 * P_CR]),
        Some(true),
    ));
    for p in [
        [0.0; 3],
        [150e3, 0.0, 60e3],
        [400e3, 0.0, 0.0],
        [0.0, 300e3, 300e3],
    ] {
        cases.push((
            format!("paper 000's arm at {p:?} Pa"),
            pam_arm(16),
            loads(&p),
            Some(true),
        ));
    }
    // designs/pam_arm_1m.toml (40 steps): stable up to its critical pressure on one
    // channel, 2.0159 bar (`collocation_stability_changes_at_the_critical_pressure`), then
    // curled past it on the unstable planar branch.
    for (p, want) in [(1e5, true), (2e5, true), (2.2e5, false), (2.5e5, false)] {
        cases.push((
            format!("pam_arm_1m at {p} Pa on channel 0"),
            pam_arm_of(1.0, 0.75, 40),
            loads(&[p, 0.0, 0.0]),
            Some(want),
        ));
    }
    // A rigid mount before the upright arm (Theta = 0 there: the test starts at the first
    // elastic step) and a tip body 20 mm above the tip (its weight's moment enters the
    // tip form). 0.3 kg (2.9 N) exceeds the arm's buckling load (about 2.3 N from Euler's
    // P_cr with EI = 0.04466 N m^2 over 0.22 m, less with its own weight): on the axis
    // the arm stays straight, unstable; 10 mm off the axis it bends over, stable, as
    // with 0.05 kg.
    for (mass, offset, want) in [(0.05, 0.01, true), (0.3, 0.01, true), (0.3, 0.0, false)] {
        let mut spec = design(
            vec![
                rigid_section("mount", 0.03, 0.02),
                direct_section("arm", 0.22, 262.8, 87.6, 0.04466, 0.02977, 0.165, 16),
            ],
            IDENTITY,
            9.81,
        );
        spec.tip.mass = mass;
        spec.tip.com_offset = [offset, 0.0, 0.02];
        cases.push((
            format!("upright arm on a rigid mount, {mass} kg tip body {offset} m off the axis"),
            Rod::new(spec).unwrap(),
            loads(&[]),
            Some(want),
        ));
    }
    cases.push((
        "0.22 m soft cantilever under gravity".into(),
        soft_rod(0.22, HORIZONTAL, 16),
        loads(&[]),
        Some(true),
    ));
    for (name, rod, ld, want) in &cases {
        // (pam_arm_1m beyond 2 bar is outside its design's strain range; the verdict is
        // what is compared.)
        let opts = SolverOptions {
            on_invalid: Policy::Warn,
            ..opts
        };
        let shot = solve(rod, ld, None, &opts).unwrap();
        assert!(shot.collocation.is_none(), "{name}: shot");
        let col = solve_static(rod, ld, None, &opts).unwrap();
        let tip = col.evaluated.node_r.last().unwrap();
        eprintln!(
            "{name}: shooting {:?}, collocation {:?}; tips {:?} / {:?}",
            shot.stable, col.stable, shot.tip.r, tip
        );
        // The same equilibrium: the two discretisations differ by their O(h^4) errors (up to
        // 2e-5 L for the arm curled by 4 bar at 16 steps; docs/model.md quotes 1.2e-5 L at
        // 3.6 bar), another branch lies 1e-2 L or more away.
        assert!(
            dist(&shot.tip.r, tip) < 1e-4 * rod.length,
            "{name}: same branch"
        );
        assert_eq!(shot.stable, *want, "{name}: shooting");
        assert_eq!(col.stable, *want, "{name}: collocation");
    }
}

/// Close to Euler's load on both sides. The collocation column's critical load differs
/// from P_cr by the discretisation's error: Gauss-Legendre (2 stages) errs in the
/// buckling wavenumber by about (k h)^4 / 4320 relative, with k h = (pi/2)/100 here, i.e.
/// 1.4e-11; the tolerance 1e-12 of the solve leaves the base moment of the straight branch
/// at round-off. So a margin of 1e-4 P_cr on either side is 7 orders above what could
/// blur the verdict, and the test must resolve it.
#[test]
fn collocation_stability_changes_at_the_euler_load() {
    let rod = upright_column(100, 0.0, 0.0);
    for (ratio, want) in [(1.0 - 1e-4, true), (1.0 + 1e-4, false)] {
        let ld = tip_force([0.0, 0.0, -ratio * P_CR]);
        let col = solve_static(&rod, &ld, None, &tight()).unwrap();
        let shot = solve(&rod, &ld, None, &tight()).unwrap();
        eprintln!(
            "{ratio} P_cr: collocation {:?}, shooting {:?}",
            col.stable, shot.stable
        );
        assert_eq!(col.stable, Some(want), "collocation at {ratio} P_cr");
        assert_eq!(shot.stable, Some(want), "shooting at {ratio} P_cr");
    }
}

/// The statics entry point routes a long soft column to collocation and reports its
/// stability. An upright soft column (E = 100 kPa, r = 12.5 mm, 1 m) under its own weight
/// is at q L^3 / EI = 2510, 320 times Greenhill's load: the straight column is an
/// equilibrium, unstable, and the solve says so (shooting's growth exponent there is 33,
/// beyond `SHOOTING_GROWTH_LIMIT`). Hanging from a horizontal clamp (1 m and 2 m, where
/// shooting failed before collocation) and hanging down, the same rods are stable.
#[test]
fn collocation_statics_report_stability() {
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..SolverOptions::default()
    };
    let upright = soft_rod(1.0, IDENTITY, 32);
    assert!(shooting_growth(&upright, &loads(&[])) > SHOOTING_GROWTH_LIMIT);
    let sol = solve(&upright, &loads(&[]), None, &warn).unwrap();
    eprintln!(
        "upright soft column: tip {:?}, stable {:?}",
        sol.tip.r, sol.stable
    );
    assert!(sol.collocation.is_some(), "routed to collocation");
    assert_eq!(sol.stable, Some(false));
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    for (length, rot) in [(1.0, HORIZONTAL), (2.0, HORIZONTAL), (1.0, hanging)] {
        let rod = soft_rod(length, rot, 32);
        let sol = solve(&rod, &loads(&[]), None, &warn).unwrap();
        eprintln!(
            "soft rod {length} m: tip {:?}, stable {:?}",
            sol.tip.r, sol.stable
        );
        assert!(sol.collocation.is_some(), "routed to collocation");
        assert_eq!(sol.stable, Some(true));
    }
}

/// The test's cost against the solve's: both timed on the 1 m soft cantilever (32
/// intervals) and paper 000's arm (16 and 64 intervals). The test is about one Newton
/// factorisation (two dual evaluations and a 32 x 32 LU per interval), and a solve takes
/// several: the bound (the test cheaper than the rest of the solve) is loose enough for a
/// shared machine (measured 0.05 to 0.4).
#[test]
fn collocation_stability_costs_less_than_the_solve() {
    use softrod_core::collocation::{Grid, Problem};
    use softrod_core::statics::collocation::{stability, static_models};
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..SolverOptions::default()
    };
    for (name, rod, ld) in [
        (
            "1 m soft cantilever",
            soft_rod(1.0, HORIZONTAL, 32),
            loads(&[]),
        ),
        ("arm, 16 steps", pam_arm(16), loads(&[150e3, 0.0, 60e3])),
        ("arm, 64 steps", pam_arm(64), loads(&[150e3, 0.0, 60e3])),
    ] {
        // Fastest of several runs of each: the machine is shared (tests run in parallel),
        // and the minimum is the time without interference.
        let reps = 9;
        let mut t_solve = f64::INFINITY;
        let mut sol = None;
        for _ in 0..reps {
            let t0 = std::time::Instant::now();
            sol = Some(solve_static(&rod, &ld, None, &warn).unwrap());
            t_solve = t_solve.min(t0.elapsed().as_secs_f64());
        }
        let sol = sol.unwrap();
        let grid = Grid::new(&rod);
        let models = static_models(&rod, &grid, &ld, 1.0);
        let hist = vec![[0.0; softrod_core::collocation::NF]; 2 * grid.len() + 1];
        let p = Problem::new(&rod, &grid, &models, 0.0, &hist, static_tip(&rod, &ld));
        let mut t_test = f64::INFINITY;
        let mut st = None;
        for _ in 0..reps {
            let t1 = std::time::Instant::now();
            st = stability(&p, &sol.z);
            t_test = t_test.min(t1.elapsed().as_secs_f64());
        }
        // The solve ran the test once (Newton converged at the first level).
        assert_eq!(sol.load_steps, 1);
        let t_newton = t_solve - t_test;
        eprintln!(
            "{name}: solve {:.1} us ({} iterations), of which the stability test {:.1} us ({:.2} of the rest)",
            t_solve * 1e6,
            sol.iterations,
            t_test * 1e6,
            t_test / t_newton
        );
        assert_eq!(st, sol.stable);
        assert!(t_test < t_newton, "{name}");
    }
}

/// The tip body of a static collocation problem under dead tip loads `ld`.
fn static_tip(rod: &Rod, ld: &softrod_core::ode::Loads) -> softrod_core::collocation::TipBody {
    softrod_core::collocation::TipBody {
        mass: rod.spec.tip.mass,
        com: rod.spec.tip.com_offset,
        inertia: [0.0; 3],
        force: ld.tip_force,
        moment: ld.tip_moment,
        force_body: [0.0; 3],
        moment_body: [0.0; 3],
    }
}

/// pam_arm_1m near its critical pressure on one channel, on both sides. Bisection on each
/// solver's verdict (40 steps, 30 halvings) puts it at 201594.355 Pa for shooting and
/// 201594.559 Pa for collocation: the two discretisations' O(h^4) errors move it by 1.0e-6
/// relative. 1e-3 relative on either side (1000 times that) must give the same verdict
/// from both solvers.
#[test]
fn collocation_stability_changes_at_the_critical_pressure() {
    const P_C: f64 = 201_594.4;
    let rod = pam_arm_of(1.0, 0.75, 40);
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..tight()
    };
    for (ratio, want) in [(1.0 - 1e-3, true), (1.0 + 1e-3, false)] {
        let ld = loads(&[ratio * P_C, 0.0, 0.0]);
        let col = solve_static(&rod, &ld, None, &warn).unwrap();
        let shot = solve(&rod, &ld, None, &warn).unwrap();
        eprintln!(
            "{ratio} p_c: collocation {:?} ({} levels), shooting {:?} ({} levels)",
            col.stable, col.load_steps, shot.stable, shot.load_steps
        );
        assert_eq!(col.stable, Some(want), "collocation at {ratio} p_c");
        assert_eq!(shot.stable, Some(want), "shooting at {ratio} p_c");
    }
}

/// `Factorization::solve2` (the dynamic sensitivities' two right sides, each block's
/// matrices read once for both) gives the numbers of two `solve`s, bit for bit.
#[test]
fn two_right_sides_solve_as_two_solves() {
    use softrod_core::collocation::{Grid, Problem};
    use softrod_core::statics::collocation::static_models;
    let rod = pam_arm(16);
    let ld = loads(&[150e3, 0.0, 60e3]);
    let sol = solve_static(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let grid = Grid::new(&rod);
    let models = static_models(&rod, &grid, &ld, 1.0);
    let hist = vec![[0.0; softrod_core::collocation::NF]; 2 * grid.len() + 1];
    let p = Problem::new(&rod, &grid, &models, 0.0, &hist, static_tip(&rod, &ld));
    let fac = p.factorize(&sol.z).unwrap();
    let n = sol.z.len();
    let r: Vec<f64> = (0..2 * n)
        .map(|k| ((k * 7919) % 1013) as f64 / 1013.0 - 0.5)
        .collect();
    let mut both = vec![0.0; 2 * n];
    let mut scratch = vec![0.0; 2 * fac.scratch_len()];
    fac.solve2(&r, &mut both, &mut scratch);
    for c in 0..2 {
        let mut one = vec![0.0; n];
        fac.solve(&r[c * n..(c + 1) * n], &mut one, &mut scratch);
        for (i, x) in one.iter().enumerate() {
            assert_eq!(
                x.to_bits(),
                both[c * n + i].to_bits(),
                "side {c}, unknown {i}"
            );
        }
    }
}

/// Markers on a collocation solution are read from its nodes' states (within the
/// discretisation's error of a finer solve's nodes; before, they were shot from the base
/// unknowns and landed anywhere). (Its derivatives and the inverse differentiate the
/// collocation equations: collocation_derivatives.rs, linearise_collocation.rs,
/// inverse_collocation.rs.)
#[test]
fn collocation_solutions_give_markers() {
    use softrod_core::marker::Marker;
    use softrod_core::sensitivity::{locate_markers, marker_positions};

    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..SolverOptions::default()
    };
    let length = 1.0;
    let (coarse, fine) = (
        soft_rod(length, HORIZONTAL, 32),
        soft_rod(length, HORIZONTAL, 64),
    );
    let ld = loads(&[]);
    let sol = solve(&coarse, &ld, None, &warn).unwrap();
    let reference = solve(&fine, &ld, None, &warn).unwrap();
    assert!(sol.collocation.is_some() && reference.collocation.is_some());
    // At the coarse grid's nodes and halfway between them (the fine grid's nodes), with an
    // offset in the cross-section.
    let offset = [0.01, -0.005, 0.0];
    let h = length / 32.0;
    let ss: Vec<f64> = [0.25, 0.5, 0.5 + 0.5 * h, 1.0 - 0.5 * h, 1.0]
        .iter()
        .map(|x| x * length)
        .collect();
    let markers: Vec<Marker> = ss.iter().map(|&s| Marker { s, offset }).collect();
    let got = marker_positions(
        &coarse,
        &ld,
        &sol,
        &locate_markers(&coarse, &markers).unwrap(),
    );
    let want = marker_positions(
        &fine,
        &ld,
        &reference,
        &locate_markers(&fine, &markers).unwrap(),
    );
    let sh = shape(&coarse, &ld, &sol);
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        // Both grids' errors are O(h^4): the tip differs by below 1e-3 L
        // (long_soft_rods_are_solved_by_collocation); every marker within the same.
        assert!(dist(g, w) < 1e-3 * length, "marker {k}: {g:?} vs {w:?}");
    }
    // A marker at a node is that node's pose exactly.
    let j = 16; // s = 0.5 L
    let at: [f64; 3] = std::array::from_fn(|i| {
        sh.position[j][i]
            + (0..3)
                .map(|c| sh.rotation[j][i][c] * offset[c])
                .sum::<f64>()
    });
    assert_eq!(got[1], at);
}

/// The equilibrium a caller holds, from its unknowns (`statics::solution_at`, which the
/// binding uses before taking a solution's derivatives): a collocation solution's own z is
/// taken as it is (no Newton step: the tip is the solution's, bit for bit); a z that is not
/// converged by the solver's own test (the Newton correction there beyond tol) is solved
/// from instead, and lands on the equilibrium (within the tolerance), not on the z given.
#[test]
fn solution_at_takes_a_converged_collocation_solution_as_it_is() {
    use softrod_core::statics::solution_at;

    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..SolverOptions::default()
    };
    let rod = soft_rod(1.0, HORIZONTAL, 32);
    let ld = loads(&[]);
    let sol = solve(&rod, &ld, None, &warn).unwrap();
    let z = sol.collocation.as_ref().unwrap().z.clone();
    let again = solution_at(&rod, &ld, &z, &warn).unwrap();
    assert_eq!(again.tip.r, sol.tip.r);
    assert_eq!(again.tip.rot, sol.tip.rot);
    assert_eq!(again.iterations, 0);
    assert_eq!(again.collocation.as_ref().unwrap().z, z);
    assert_eq!(again.stable, sol.stable);

    // A moved z (1e-6 on every unknown: 1e4 times the tolerance) is not an equilibrium.
    let moved: Vec<f64> = z.iter().map(|v| v + 1e-6).collect();
    let fixed = solution_at(&rod, &ld, &moved, &warn).unwrap();
    assert!(fixed.iterations > 0);
    // Both solves converge to 1e-10 of the (order-one) scaled unknowns: the tips agree to a
    // few 1e-10 L.
    assert!(dist(&fixed.tip.r, &sol.tip.r) < 1e-9, "{:?}", fixed.tip.r);
}
