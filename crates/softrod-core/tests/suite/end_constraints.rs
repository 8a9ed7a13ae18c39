//! End constraints (pinned and clamped tips) and systems of rods sharing a platform:
//! the clamped-clamped beam against the linear Timoshenko solution, the Euler loads of the
//! clamped-pinned and clamped-clamped columns where the constraint Jacobian turns singular,
//! exact Jacobians against finite differences, reactions that balance the applied loads,
//! round trips through the free solve, a one-rod system equal to the free rod, and bad
//! inputs. (Large loads and a two-rod mechanism against scipy's BVP solver are in
//! tests/test_end_constraints.py.)

#![allow(clippy::needless_range_loop)]

use crate::common;
use common::*;
use softrod_core::ode::Loads;
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::spec::{Frame, LineLoadSpec};
use softrod_core::statics::constraint::{
    constraint_residual_and_jacobian, exp_so3, log_so3, solve_constrained, TipConstraint,
};
use softrod_core::statics::system::{
    solve_system, system_residual_and_jacobian, system_retract, Platform, SystemRod, SystemSolution,
};
use softrod_core::statics::{solve_with_shape, SolverOptions};
use softrod_core::{Rod, SoftrodError};

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

fn no_loads() -> Loads {
    loads(&[])
}

/// A horizontal beam (along +x) of three sections, the middle one [L/2 - eps, L/2 + eps]
/// carrying a line load q (world -z): a mid-span load spread over 2 eps.
fn patch_beam(l: f64, eps: f64, ea: f64, ga: f64, ei: f64, q: f64, steps: usize) -> Rod {
    let sec = |name: &str, len: f64| direct_section(name, len, ea, ga, ei, 2.0 * ei, 0.0, steps);
    let mut spec = design(
        vec![
            sec("left", l / 2.0 - eps),
            sec("patch", 2.0 * eps),
            sec("right", l / 2.0 - eps),
        ],
        HORIZONTAL,
        0.0,
    );
    spec.loads = vec![LineLoadSpec {
        section: 1,
        frame: Frame::World,
        force_per_length: [0.0, 0.0, -q],
        moment_per_length: [0.0; 3],
    }];
    Rod::new(spec).unwrap()
}

#[test]
fn clamped_clamped_beam_matches_the_linear_solution_under_a_small_mid_span_load() {
    let (l, eps, ei, ea, ga) = (1.0, 0.05, 1.0, 1e4, 1e4);
    let q = 1e-4; // total load P = 2 eps q = 1e-5 N: mid-span deflection ~ 5e-8 L
    let rod = patch_beam(l, eps, ea, ga, ei, q, 64);
    let clamp = TipConstraint::Clamped {
        position: [l, 0.0, 0.0],
        rotation: HORIZONTAL,
    };
    let sol = solve_constrained(&rod, &no_loads(), &clamp, None, &opts()).unwrap();
    // Linear clamped-clamped Timoshenko beam. Bending: w_b = int q G(L/2, a) da with the
    // influence function G(L/2, a) = a^2 (3L - 4a) / (48 EI) for a <= L/2 (symmetric),
    // so w_b = 2 q [L a^3 - a^4]_{L/2 - eps}^{L/2} / (48 EI). Shear (the section rotation
    // is clamped, so the redundant moments are Euler-Bernoulli's): w_s = int_0^{L/2} V /
    // GA = (P/2)(L/2 - eps/2) / GA.
    let a1 = l / 2.0 - eps;
    let a2 = l / 2.0;
    let prim = |a: f64| l * a.powi(3) - a.powi(4);
    let w_b = 2.0 * q * (prim(a2) - prim(a1)) / (48.0 * ei);
    let p = 2.0 * eps * q;
    let w_s = 0.5 * p * (l / 2.0 - eps / 2.0) / ga;
    let mid = sol
        .shape
        .s
        .iter()
        .position(|&s| (s - l / 2.0).abs() < 1e-12)
        .unwrap();
    let w = -sol.shape.position[mid][2];
    // Tolerance: the neglected terms are the membrane tension of the axially held beam,
    // relative size ~ (EA / EI) w^2 ~ 1e4 * (5e-8)^2 ~ 3e-11, the rotation's geometric
    // terms ~ (w / L)^2, and RK4's O(h^4) error on the quartic deflection (~1e-9 at 64
    // steps); the solver's tolerance (1e-12 L on the tip position) is ~2e-5 of w. 1e-4
    // relative leaves room for that and would catch a missing shear term (1.2e-3 of w).
    let reference = w_b + w_s;
    assert!(
        ((w - reference) / reference).abs() < 1e-4,
        "w = {w:e}, linear {reference:e} (bending {w_b:e}, shear {w_s:e})"
    );
    // Symmetry: equal vertical reactions P/2, equal and opposite end moments
    // (magnitude from the same influence integrals: M = int q a b^2 / L^2 da).
    assert!((sol.tip_reaction_force[2] - p / 2.0).abs() < 1e-9 * p);
    // The clamp applies -n(0) to the rod.
    assert!((-sol.solution.base_force[2] - p / 2.0).abs() < 1e-9 * p);
    // A lightly loaded beam held at both ends is stable.
    assert_eq!(sol.solution.stable, Some(true));
}

/// The constraint's reactions and the base wrench balance the applied loads: force
/// exactly (n' = -f is integrated exactly by RK4 for a constant f), and the moment about
/// the base exactly when the loads are point loads (n is constant, and r(L) - r(0) uses
/// the same RK4 weights as m(L) - m(0)).
#[test]
fn reactions_balance_the_applied_loads() {
    let spec = design(
        vec![direct_section("rod", 0.5, 1e3, 1e3, 0.02, 0.04, 0.0, 40)],
        tilted(),
        0.0,
    );
    let rod = Rod::new(spec).unwrap();
    let mut ld = no_loads();
    ld.tip_force = [0.06, -0.04, 0.02];
    ld.tip_moment = [0.002, 0.004, -0.006];
    let free = solve_with_shape(&rod, &ld, None, &opts()).unwrap().0;
    let r_tip = free.tip.r;
    for c in [
        TipConstraint::Pinned {
            position: [r_tip[0] + 0.02, r_tip[1] - 0.01, r_tip[2]],
        },
        TipConstraint::Clamped {
            position: [r_tip[0], r_tip[1] + 0.01, r_tip[2] - 0.02],
            rotation: matmul(&exp_so3(&[0.2, -0.1, 0.3]), &free.tip.rot),
        },
    ] {
        let sol = solve_constrained(&rod, &ld, &c, None, &opts())
            .unwrap_or_else(|e| panic!("{}: {e:?}", c.name()));
        let (f_r, m_r) = (sol.tip_reaction_force, sol.tip_reaction_moment);
        let n0 = sol.solution.base_force;
        let m0 = sol.solution.base_moment;
        let tip = sol.solution.tip.r;
        let r0 = rod.base_position;
        let scale_f = norm(&ld.tip_force) + norm(&f_r);
        let scale_m = scale_f * rod.length + norm(&ld.tip_moment) + norm(&m_r);
        for k in 0..3 {
            // The clamp applies -n(0) and -m(0) to the rod.
            let f = -n0[k] + ld.tip_force[k] + f_r[k];
            assert!(
                f.abs() < 1e-9 * scale_f,
                "{}: force balance {k}: {f:e}",
                c.name()
            );
        }
        let arm: [f64; 3] = std::array::from_fn(|k| tip[k] - r0[k]);
        let tot: [f64; 3] = std::array::from_fn(|k| ld.tip_force[k] + f_r[k]);
        let cx = cross(&arm, &tot);
        for k in 0..3 {
            let m = -m0[k] + cx[k] + ld.tip_moment[k] + m_r[k];
            assert!(
                m.abs() < 1e-9 * scale_m,
                "{}: moment balance {k}: {m:e}",
                c.name()
            );
        }
        if let TipConstraint::Pinned { .. } = c {
            assert_eq!(m_r, [0.0; 3]);
            // The moment balance at the pin is a residual row: m(L) = M_tip.
            let ml = sol.shape.moment.last().unwrap();
            for k in 0..3 {
                assert!((ml[k] - ld.tip_moment[k]).abs() < 1e-9 * scale_m);
            }
        } else {
            let e = log_so3(&tmatmul(
                &match c {
                    TipConstraint::Clamped { rotation, .. } => rotation,
                    _ => unreachable!(),
                },
                &sol.solution.tip.rot,
            ));
            assert!(norm(&e) < 1e-10, "orientation error {e:?}");
        }
        let pos = match c {
            TipConstraint::Pinned { position } | TipConstraint::Clamped { position, .. } => {
                position
            }
            TipConstraint::Free => unreachable!(),
        };
        assert!(dist(&pos, &tip) < 1e-10 * rod.length);
    }
}

/// Clamping the tip where the free solve put it gives back the free solve: zero reaction,
/// the same base wrench.
#[test]
fn clamping_the_free_solution_tip_recovers_it() {
    let rod = Rod::new(p002_actuator(HORIZONTAL, 9.81, 40)).unwrap();
    let ld = loads(&[30e3, 0.0, 0.0]);
    let (free, _) = solve_with_shape(&rod, &ld, None, &opts()).unwrap();
    for c in [
        TipConstraint::Clamped {
            position: free.tip.r,
            rotation: free.tip.rot,
        },
        TipConstraint::Pinned {
            position: free.tip.r,
        },
    ] {
        let sol = solve_constrained(&rod, &ld, &c, None, &opts()).unwrap();
        let fs = rod.force_scale;
        assert!(
            norm(&sol.tip_reaction_force) < 1e-8 * fs,
            "{:?}",
            sol.tip_reaction_force
        );
        assert!(norm(&sol.tip_reaction_moment) < 1e-8 * fs * rod.length);
        for k in 0..3 {
            assert!(
                (sol.solution.base_moment[k] - free.base_moment[k]).abs() < 1e-8 * fs * rod.length
            );
            assert!((sol.solution.base_force[k] - free.base_force[k]).abs() < 1e-8 * fs);
        }
    }
}

fn fd_check(
    name: &str,
    f: impl Fn(&[f64]) -> (Vec<f64>, Vec<Vec<f64>>),
    x: &[f64],
    step: impl Fn(&[f64], usize, f64) -> Vec<f64>,
) {
    let (_, jac) = f(x);
    let h = 1e-6;
    for j in 0..x.len() {
        let (rp, _) = f(&step(x, j, h));
        let (rm, _) = f(&step(x, j, -h));
        for i in 0..x.len() {
            let fd = (rp[i] - rm[i]) / (2.0 * h);
            // Central differences: O(h^2) truncation plus ~1e-16 / h round-off on O(1)
            // residuals; 1e-6 absolute on entries of size O(1).
            assert!(
                (fd - jac[i][j]).abs() < 1e-6 * (1.0 + jac[i][j].abs()),
                "{name}: J[{i}][{j}] = {} vs finite difference {fd}",
                jac[i][j]
            );
        }
    }
}

#[test]
fn constraint_jacobians_match_finite_differences() {
    let rod = Rod::new(p002_actuator(tilted(), 9.81, 20)).unwrap();
    let mut ld = loads(&[20e3, 5e3, 0.0]);
    ld.tip_force = [0.1, 0.0, -0.2];
    let free = solve_with_shape(&rod, &ld, None, &opts()).unwrap().0;
    let x = [0.3, -0.2, 0.1, 0.05, -0.1, 0.2];
    for c in [
        TipConstraint::Pinned {
            position: free.tip.r,
        },
        TipConstraint::Clamped {
            position: free.tip.r,
            rotation: free.tip.rot,
        },
    ] {
        fd_check(
            c.name(),
            |x| constraint_residual_and_jacobian(&rod, &ld, &c, x).unwrap(),
            &x,
            |x, j, h| {
                let mut y = x.to_vec();
                y[j] += h;
                y
            },
        );
    }
}

/// A column along +z with EI_1 != EI_2 (so each buckling load is a simple root), axially
/// and in shear far stiffer than in bending.
fn column(ei1: f64, ei2: f64) -> Rod {
    let mut sec = direct_section("rod", 1.0, 1e7, 1e7, ei1, ei1 + ei2, 0.0, 100);
    sec.stiffness.ei2 = Some(ei2);
    Rod::new(design(vec![sec], IDENTITY, 0.0)).unwrap()
}

/// det of the constraint Jacobian at the straight column compressed by P: it vanishes at
/// the Euler load of the end conditions (a conjugate point at the tip).
fn det_at(rod: &Rod, c: &TipConstraint, p: f64) -> f64 {
    let x = [0.0, 0.0, -p / rod.force_scale, 0.0, 0.0, 0.0];
    let (_, j) = constraint_residual_and_jacobian(rod, &no_loads(), c, &x).unwrap();
    nalgebra::Matrix6::from_fn(|a, b| j[a][b]).determinant()
}

#[test]
fn constraint_jacobian_turns_singular_at_the_euler_loads() {
    let (ei1, ei2) = (1.0, 3.0);
    let rod = column(ei1, ei2);
    let pinned = TipConstraint::Pinned {
        position: [0.0, 0.0, 1.0],
    };
    let clamped = TipConstraint::Clamped {
        position: [0.0, 0.0, 1.0],
        rotation: IDENTITY,
    };
    // Clamped-pinned: tan(kL) = kL, kL = 4.493409457909064; clamped-clamped: kL = 2 pi
    // (the symmetric mode). With EA = GA = 1e7 the shear and extension corrections are
    // ~P/GA ~ 1e-5 relative; the bracket of +-0.1 % is far outside them and the
    // neighbouring roots (EI_2 ones are 3x higher).
    for (name, c, kl) in [
        ("clamped-pinned", pinned, 4.493409457909064_f64),
        ("clamped-clamped", clamped, 2.0 * std::f64::consts::PI),
    ] {
        let pe = kl * kl * ei1;
        let below = det_at(&rod, &c, 0.999 * pe);
        let above = det_at(&rod, &c, 1.001 * pe);
        let far = det_at(&rod, &c, 0.5 * pe);
        assert!(
            below * above < 0.0,
            "{name}: det {below:e} at 0.999 P_E, {above:e} at 1.001 P_E"
        );
        assert!(far * below > 0.0, "{name}: a root below 0.5..0.999 P_E");
    }
}

/// The tip pose of the straight column (along +z, length 1) compressed by P: the linear law
/// gives the stretch v3 = 1 - P/EA, so the tip sits at z = L (1 - P/EA).
fn compressed(rod: &Rod, ea: f64, p: f64, clamped: bool) -> TipConstraint {
    let position = [0.0, 0.0, rod.length * (1.0 - p / ea)];
    if clamped {
        TipConstraint::Clamped {
            position,
            rotation: IDENTITY,
        }
    } else {
        TipConstraint::Pinned { position }
    }
}

/// A straight column held at both ends: stable below the Euler load of its end
/// conditions, unstable above it. The Euler loads P_E = (kL)^2 EI_1 / L^2 (the weaker plane)
/// come from EI w'''' + P w'' = 0 with w(0) = w'(0) = 0 and, at L, w = w' = 0
/// (clamped-clamped: the symmetric mode, kL = 2 pi) or w = w'' = 0 (clamped-pinned:
/// tan kL = kL, kL = 4.4934). The prescribed tip z = L (1 - P/EA) sets P; the straight column
/// is an equilibrium at any P, and the path to it stays straight by symmetry. EA = GA =
/// 1e7 EI / L^2 moves the thresholds by ~P/GA ~ 1e-5, far inside 0.95..1.05.
/// - Clamped-clamped: only conjugate points decide (no tip form): the first, at k s = 2 pi,
///   lies inside (0, L] exactly when P > P_E.
/// - Clamped-pinned: below kL = 2 pi there is no conjugate point, and the tip form (the
///   pin's rotational stiffness, EI k (sin kL - kL cos kL) / (2 - 2 cos kL - kL sin kL) on
///   the straight column) changes sign at tan kL = kL; at kL = 6.5 (beyond 2 pi) it is
///   positive again (numerator -6.1, denominator -1.35), and only the conjugate point at
///   k s = 2 pi flags the column.
///
/// A round column (EI_1 = EI_2) buckles in both planes at once: a double conjugate point,
/// or a tip form with a double negative eigenvalue, neither of which changes a det's sign.
#[test]
fn straight_columns_held_at_both_ends_change_stability_at_their_euler_loads() {
    let ea = 1e7;
    for (ei1, ei2) in [(1.0, 3.0), (1.0, 1.0)] {
        let rod = column(ei1, ei2);
        let cc = (2.0 * std::f64::consts::PI).powi(2) * ei1;
        let cp = 4.493409457909064_f64.powi(2) * ei1;
        let cases = [
            ("clamped-clamped", true, cc, 0.8, true),
            ("clamped-clamped", true, cc, 0.95, true),
            ("clamped-clamped", true, cc, 1.05, false),
            ("clamped-clamped", true, cc, 1.5, false),
            ("clamped-pinned", false, cp, 0.8, true),
            ("clamped-pinned", false, cp, 0.95, true),
            ("clamped-pinned", false, cp, 1.05, false),
            ("clamped-pinned", false, cp, 1.5, false),
            // kL = 6.5 > 2 pi: the conjugate point alone.
            ("clamped-pinned", false, 6.5_f64.powi(2) * ei1, 1.0, false),
        ];
        for (name, clamped, pe, ratio, want) in cases {
            let c = compressed(&rod, ea, ratio * pe, clamped);
            let sol = solve_constrained(&rod, &no_loads(), &c, None, &opts())
                .unwrap_or_else(|e| panic!("{name} at {ratio} P_E: {e:?}"));
            // Straight, and carrying P.
            let tip = sol.solution.tip.r;
            assert!(
                tip[0].abs() < 1e-9 && tip[1].abs() < 1e-9,
                "{name}: {tip:?}"
            );
            let p = -sol.solution.base_force[2];
            assert!(
                (p - ratio * pe).abs() < 1e-6 * pe,
                "{name}: P = {p}, want {}",
                ratio * pe
            );
            assert_eq!(
                sol.solution.stable,
                Some(want),
                "{name}, EI = ({ei1}, {ei2}), {ratio} P_E"
            );
        }
    }
}

/// A softer column (EA = GA = 2000 EI / L^2: the clamped-clamped Euler shortening P_E / EA
/// is 2 %) shortened by 1.5 P_E / EA. Perfect, it stays straight under 1.5 P_E and is
/// unstable; with a small lateral line load (q L^3 / EI_2 = 1e-2, in the plane of the weaker
/// bending stiffness EI_2 = EI) the path bends it, and the
/// buckled column carries about the Euler load (the post-buckled elastica's force rises with
/// the square of the amplitude, ~1 % here; shear lowers the critical load by P/GA ~ 2 %),
/// far below the straight column's 1.5 P_E. The side it bends to is the path's (the tip
/// moves from where the load put the free tip), here against the load.
/// - EI_1 = 3 EI_2 (bending about d1, out of the plane of the load, three times stiffer):
///   the buckled column is stable.
/// - A round column (EI_1 = EI_2): turning the buckled shape about the chord (r -> Q r,
///   R -> Q R Q^T with Q a rotation about the axis through both ends) keeps both ends' poses
///   and, the section being round, every strain's energy: without the load it is a neutral
///   mode. The load makes it stable if the column bows with the load, unstable if against it
///   (turning towards the load lowers the potential by q int x ds (1 - cos phi)). This is a
///   spatial instability of a planar shape, which a planar test would miss.
#[test]
fn buckled_columns_held_at_both_ends_are_stable() {
    let (ea, ei) = (2e3, 1.0);
    for (clamped, ei1) in [(true, 3.0), (false, 3.0), (true, 1.0), (false, 1.0)] {
        let name = if clamped {
            "clamped-clamped"
        } else {
            "clamped-pinned"
        };
        let pe = if clamped {
            (2.0 * std::f64::consts::PI).powi(2) * ei
        } else {
            4.493409457909064_f64.powi(2) * ei
        };
        let sec = |q: f64| {
            let mut section = direct_section("rod", 1.0, ea, ea, ei, 2.0 * ei, 0.0, 100);
            section.stiffness.ei1 = Some(ei1 * ei);
            let mut spec = design(vec![section], IDENTITY, 0.0);
            spec.loads = vec![LineLoadSpec {
                section: 0,
                frame: Frame::World,
                force_per_length: [q, 0.0, 0.0],
                moment_per_length: [0.0; 3],
            }];
            Rod::new(spec).unwrap()
        };
        let perfect = sec(0.0);
        let c = compressed(&perfect, ea, 1.5 * pe, clamped);
        let straight = solve_constrained(&perfect, &no_loads(), &c, None, &opts()).unwrap();
        assert!(straight.solution.tip.r[0].abs() < 1e-9);
        assert_eq!(straight.solution.stable, Some(false), "{name}: straight");
        let rod = sec(1e-2 * ei);
        let bent = solve_constrained(&rod, &no_loads(), &c, None, &opts())
            .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        let x: Vec<f64> = bent.shape.position.iter().map(|r| r[0]).collect();
        let sway = x.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
        let with_load = x.iter().sum::<f64>() > 0.0;
        let p = -bent.solution.base_force[2];
        assert!(sway > 0.03, "{name}: not buckled (sway {sway})");
        assert!((p / pe - 1.0).abs() < 0.05, "{name}: P = {} P_E", p / pe);
        let want = ei1 > 1.0 || with_load;
        assert_eq!(
            bent.solution.stable,
            Some(want),
            "{name}, EI_1 = {ei1}, with the load: {with_load}"
        );
    }
}

/// A clamped tip moved sideways by 0.3 L (the rod bends into an S) or pinned there (a C),
/// the chord as long as the rod, so the rod is stretched (EA = GA = 1000 EI / L^2): the axial force
/// at the base is a tension, and the equilibrium is stable. With a follower tip moment a
/// pin's equilibrium is not assessed; a clamp takes any tip load into its reaction, so it
/// still is.
#[test]
fn rods_bent_by_a_displaced_tip_are_stable() {
    let rod = Rod::new(design(
        vec![direct_section("rod", 1.0, 1e3, 1e3, 1.0, 2.0, 0.0, 100)],
        IDENTITY,
        0.0,
    ))
    .unwrap();
    let tip = [0.3, 0.0, (1.0_f64 - 0.09).sqrt()];
    let clamp = TipConstraint::Clamped {
        position: tip,
        rotation: IDENTITY,
    };
    let pin = TipConstraint::Pinned { position: tip };
    for c in [clamp, pin] {
        let sol = solve_constrained(&rod, &no_loads(), &c, None, &opts())
            .unwrap_or_else(|e| panic!("{}: {e:?}", c.name()));
        let n0 = sol.solution.base_force;
        let t0 = sol.shape.rotation[0];
        // n(0) . d3(0) > 0: tension (d3 = third column of the row-major rotation).
        let axial: f64 = (0..3).map(|k| n0[k] * t0[k][2]).sum();
        assert!(axial > 0.0, "{}: axial force {axial}", c.name());
        assert_eq!(sol.solution.stable, Some(true), "{}", c.name());
    }
    let mut follower = no_loads();
    follower.tip_frame = Frame::Body;
    follower.tip_moment = [0.0, 0.1, 0.0];
    let sol = solve_constrained(&rod, &follower, &pin, None, &opts()).unwrap();
    assert_eq!(sol.solution.stable, None);
    let sol = solve_constrained(&rod, &follower, &clamp, None, &opts()).unwrap();
    assert_eq!(sol.solution.stable, Some(true));
}

fn two_rod_system(rod: &Rod, gap: f64) -> Vec<SystemRod<'_>> {
    vec![
        SystemRod {
            rod,
            loads: no_loads(),
            attachment: [-gap, 0.0, 0.0],
            attachment_rotation: IDENTITY,
        },
        SystemRod {
            rod,
            loads: no_loads(),
            attachment: [gap, 0.0, 0.0],
            attachment_rotation: IDENTITY,
        },
    ]
}

fn platform(position: [f64; 3], force: [f64; 3], moment: [f64; 3]) -> Platform {
    Platform {
        position,
        rotation: IDENTITY,
        force,
        moment,
        mass: 0.0,
        com_offset: [0.0; 3],
        gravity: [0.0; 3],
    }
}

/// A one-rod system whose platform sits on the tip is the free rod with the platform's
/// load as its tip load.
/// `rod` alone under `ld`, its tip clamped at the platform's origin in the platform's frame.
fn one_rod_system(rod: &Rod, ld: &Loads, platform: Platform) -> SystemSolution {
    let rods = vec![SystemRod {
        rod,
        loads: ld.clone(),
        attachment: [0.0; 3],
        attachment_rotation: IDENTITY,
    }];
    solve_system(&rods, &platform, None, &opts()).unwrap()
}

#[test]
fn one_rod_system_equals_the_free_rod() {
    let rod = Rod::new(p002_actuator(IDENTITY, 9.81, 40)).unwrap();
    let mut ld = loads(&[25e3, 0.0, 10e3]);
    let force = [0.3, -0.1, -0.2];
    let moment = [0.002, 0.004, -0.001];
    let sys = one_rod_system(&rod, &ld, platform([0.0, 0.0, rod.length], force, moment));
    ld.tip_force = force;
    ld.tip_moment = moment;
    let (free, _) = solve_with_shape(&rod, &ld, None, &opts()).unwrap();
    let got = &sys.rods[0].solution;
    assert!(dist(&got.tip.r, &free.tip.r) < 1e-9 * rod.length);
    assert!(dist(&sys.platform_position, &free.tip.r) < 1e-9 * rod.length);
    for i in 0..3 {
        assert!(dist(&sys.platform_rotation[i], &free.tip.rot[i]) < 1e-9);
    }
    // The platform applies (F, M) to the tip: the reaction equals the load.
    for k in 0..3 {
        assert!((sys.rods[0].tip_reaction_force[k] - force[k]).abs() < 1e-9);
        assert!((sys.rods[0].tip_reaction_moment[k] - moment[k]).abs() < 1e-9);
    }
}

/// A rod's obstacles go with it into a system: one rod by a wall holding a massless,
/// unloaded platform is the free rod by the same wall (the contact forces, the shape and a
/// zero reaction), and the tip is held back by the wall.
#[test]
fn one_rod_system_by_a_wall_equals_the_free_rod_by_the_wall() {
    let mut spec = p002_actuator(IDENTITY, 9.81, 40);
    let ld = loads(&[25e3, 0.0, 0.0]);
    let free = solve_with_shape(&Rod::new(spec.clone()).unwrap(), &ld, None, &opts())
        .unwrap()
        .0;
    let side = [free.tip.r[0], free.tip.r[1], 0.0];
    let reach = norm(&side);
    let dir = side.map(|v| v / reach);
    let mut wall = obstacle(ObstacleKind::Plane, 1e5, 1e-3);
    wall.point = Some(dir.map(|v| (P002_RO + 0.5 * reach) * v));
    wall.normal = Some(dir.map(|v| -v));
    spec.obstacles = vec![wall];
    let rod = Rod::new(spec).unwrap();
    let (by_wall, _) = solve_with_shape(&rod, &ld, None, &opts()).unwrap();
    let held_back = reach - (by_wall.tip.r[0] * dir[0] + by_wall.tip.r[1] * dir[1]);
    assert!(
        held_back > 2e-3,
        "the wall held the tip back by {held_back:e} m only"
    );
    let sys = one_rod_system(&rod, &ld, platform(by_wall.tip.r, [0.0; 3], [0.0; 3]));
    let got = &sys.rods[0];
    // Both solves converge to 1e-10 of the scaled residual (opts): the same equilibrium to
    // 1e-9 of the length, and a reaction of round-off against the rod's weight.
    assert!(dist(&got.solution.tip.r, &by_wall.tip.r) < 1e-9 * rod.length);
    assert!(norm(&got.tip_reaction_force) < 1e-9);
    assert!(norm(&got.tip_reaction_moment) < 1e-9 * rod.length);
    for k in 0..3 {
        assert!((got.solution.base_force[k] - by_wall.base_force[k]).abs() < 1e-9);
    }
}

/// Two equal rods side by side, the platform pushed sideways and twisted: the platform
/// balance holds to 1e-9 of the load, and the symmetric load (straight down) is shared
/// equally.
#[test]
fn two_rod_platform_balances_its_load() {
    let spec = design(
        vec![direct_section("rod", 0.3, 2e3, 2e3, 0.05, 0.1, 0.0, 40)],
        IDENTITY,
        0.0,
    );
    let rod = Rod::new(spec.clone()).unwrap();
    let mut right = spec;
    right.mounting.base_position = [0.08, 0.0, 0.0];
    let rod_r = Rod::new(right).unwrap();
    let mut rods = two_rod_system(&rod, 0.04);
    rods[1].rod = &rod_r;
    let force = [0.4, 0.2, -0.5];
    let moment = [0.01, -0.02, 0.03];
    let pf = platform([0.04, 0.0, 0.3], force, moment);
    let sys = solve_system(&rods, &pf, None, &opts()).unwrap();
    let p = sys.platform_position;
    let mut f = force;
    let mut m = moment;
    for r in &sys.rods {
        let lever: [f64; 3] = std::array::from_fn(|k| r.solution.tip.r[k] - p[k]);
        let c = cross(&lever, &r.tip_reaction_force);
        for k in 0..3 {
            f[k] -= r.tip_reaction_force[k];
            m[k] -= r.tip_reaction_moment[k] + c[k];
        }
    }
    assert!(norm(&f) < 1e-9 * norm(&force), "force balance {f:?}");
    assert!(
        norm(&m) < 1e-9 * (norm(&moment) + 0.3 * norm(&force)),
        "moment balance {m:?}"
    );
    // Attachments hold.
    for (r, s) in sys.rods.iter().zip(&rods) {
        let want: [f64; 3] = std::array::from_fn(|k| {
            p[k] + (0..3)
                .map(|j| sys.platform_rotation[k][j] * s.attachment[j])
                .sum::<f64>()
        });
        assert!(dist(&want, &r.solution.tip.r) < 1e-10);
    }
    // Symmetric load: equal shares.
    let sym = solve_system(
        &rods,
        &platform([0.04, 0.0, 0.3], [0.0, 0.0, -0.5], [0.0; 3]),
        None,
        &opts(),
    )
    .unwrap();
    let (a, b) = (
        &sym.rods[0].tip_reaction_force,
        &sym.rods[1].tip_reaction_force,
    );
    assert!(
        (a[2] - b[2]).abs() < 1e-9 && (a[2] + 0.25).abs() < 1e-9,
        "{a:?} {b:?}"
    );
    assert!((a[0] + b[0]).abs() < 1e-9);
}

#[test]
fn system_jacobian_matches_finite_differences() {
    let spec = design(
        vec![direct_section("rod", 0.3, 2e3, 2e3, 0.05, 0.1, 0.001, 20)],
        IDENTITY,
        9.81,
    );
    let rod = Rod::new(spec.clone()).unwrap();
    let mut right = spec;
    right.mounting.base_position = [0.08, 0.0, 0.0];
    let rod_r = Rod::new(right).unwrap();
    let mut rods = two_rod_system(&rod, 0.04);
    rods[1].rod = &rod_r;
    rods[1].attachment_rotation = exp_so3(&[0.1, 0.2, -0.1]);
    let mut pf = platform([0.04, 0.0, 0.3], [0.2, 0.1, -0.3], [0.01, 0.0, 0.02]);
    pf.mass = 0.05;
    pf.com_offset = [0.01, 0.02, 0.03];
    pf.gravity = [0.0, 0.0, -9.81];
    let mut x: Vec<f64> = (0..18).map(|i| 0.1 * ((i * 7 % 5) as f64 - 2.0)).collect();
    x[12..15].copy_from_slice(&[0.12, 0.01, 0.95]);
    x[15..18].copy_from_slice(&[0.1, -0.2, 0.3]);
    fd_check(
        "system",
        |x| system_residual_and_jacobian(&rods, &pf, x).unwrap(),
        &x,
        |x, j, h| {
            let mut d = vec![0.0; x.len()];
            d[j] = h;
            system_retract(2, x, &d)
        },
    );
}

#[test]
fn bad_constraints_are_refused_naming_the_field() {
    let rod = column(1.0, 1.0);
    let mut skewed = IDENTITY;
    skewed[0][1] = 0.1;
    let cases = [
        (
            TipConstraint::Clamped {
                position: [0.0, 0.0, 1.0],
                rotation: skewed,
            },
            "tip_constraint.orientation",
        ),
        (
            TipConstraint::Clamped {
                position: [0.0, 0.0, 1.0],
                rotation: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            },
            "tip_constraint.orientation",
        ),
        (
            TipConstraint::Pinned {
                position: [0.0, f64::NAN, 1.0],
            },
            "tip_constraint.position[1]",
        ),
    ];
    for (c, field) in cases {
        match solve_constrained(&rod, &no_loads(), &c, None, &opts()) {
            Err(SoftrodError::InvalidParameter { field: f, rule, .. }) => {
                assert_eq!(f, field, "{rule}")
            }
            other => panic!("{field}: expected InvalidParameter, got {other:?}"),
        }
    }
    let none: Vec<SystemRod> = vec![];
    match solve_system(
        &none,
        &platform([0.0; 3], [0.0; 3], [0.0; 3]),
        None,
        &opts(),
    ) {
        Err(SoftrodError::InvalidParameter { field, .. }) => assert_eq!(field, "rods"),
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
    // A pose the rod cannot reach (stretch 4, beyond the validity range) is a convergence error, not a
    // shape.
    let far = TipConstraint::Pinned {
        position: [0.0, 0.0, 4.0],
    };
    let loose = SolverOptions {
        max_load_steps: 30,
        ..opts()
    };
    assert!(matches!(
        solve_constrained(&rod, &no_loads(), &far, None, &loose),
        Err(SoftrodError::NotConverged { .. }) | Err(SoftrodError::InvalidState { .. })
    ));
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn matmul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn tmatmul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[k][i] * b[k][j]).sum()))
}

/// `column` (EI_1 = 1 < EI_2 = 3, EA = GA = 1e7 N, L = 1 m) with its base at `base`.
fn column_at(base: [f64; 3]) -> Rod {
    let mut spec = column(1.0, 3.0).spec.clone();
    spec.mounting.base_position = base;
    Rod::new(spec).unwrap()
}

/// The system's stability is assessed (docs/model.md "Systems of rods"): a one-rod system
/// whose platform sits on the tip and carries a compressive load P is the free column under
/// that tip load, whose verdict (the free tip's own test, 3 unknowns) it must repeat: just
/// below and above the Euler load pi^2 EI_1 / (4 L^2) (the platform's tip form), and at
/// 5 times it (kL = 3.5: past the free tip's conjugate point at kL = pi, which the
/// platform's form must flag by itself since the rod held at both ends has no conjugate
/// point before kL = 2 pi).
#[test]
fn one_rod_system_has_the_free_columns_stability() {
    let rod = column_at([0.0; 3]);
    let pe = std::f64::consts::PI.powi(2) / 4.0;
    for (ratio, want) in [(0.9, true), (1.1, false), (5.0, false)] {
        let f = [0.0, 0.0, -ratio * pe];
        let rods = vec![SystemRod {
            rod: &rod,
            loads: no_loads(),
            attachment: [0.0; 3],
            attachment_rotation: IDENTITY,
        }];
        let sys = solve_system(
            &rods,
            &platform([0.0, 0.0, 1.0], f, [0.0; 3]),
            None,
            &opts(),
        )
        .unwrap_or_else(|e| panic!("{ratio} P_E: {e}"));
        let mut ld = no_loads();
        ld.tip_force = f;
        let (free, _) = solve_with_shape(&rod, &ld, None, &opts()).unwrap();
        assert_eq!(free.stable, Some(want), "free column at {ratio} P_E");
        assert_eq!(sys.stable, Some(want), "one-rod system at {ratio} P_E");
        assert_eq!(sys.rods[0].solution.stable, sys.stable);
        assert!(dist(&sys.platform_position, &free.tip.r) < 1e-9, "straight");
    }
}

/// Three equal columns at the corners of a triangle (circumradius 0.1 m) hold a platform
/// loaded by W straight down. The rods' axial stiffness keeps the platform from tilting
/// (EA a^2 / L = 1e5 N m against the rods' bending, ~EI / L = 1 N m), so it sways as a
/// guided column: each rod is clamped at its base and at a tip that translates but does not
/// turn, whose Euler load is pi^2 EI_1 / L^2 (the weaker plane; kL = pi). The platform
/// sways at W = 3 pi^2 EI_1 / L^2, twelve times the load that buckles the same rods with free
/// tips, and its yaw stays stiff there (3 GJ / L = 12 N m of twist). Two rods on a line
/// instead let the platform roll about that line: in the plane across it each rod is a free
/// cantilever again (pi^2 EI_1 / (4 L^2) each, the rods' d1 axis along the line). The
/// thresholds move by ~P / GA ~ 3e-6 and by the tilt's compliance ~1e-5: far inside the
/// +-3 % brackets.
#[test]
fn platform_systems_buckle_at_their_euler_loads() {
    let pi2 = std::f64::consts::PI.powi(2);
    let corners: Vec<[f64; 3]> = (0..3)
        .map(|k| {
            let a = 2.0 * std::f64::consts::PI * k as f64 / 3.0;
            [0.1 * a.cos(), 0.1 * a.sin(), 0.0]
        })
        .collect();
    let line: Vec<[f64; 3]> = vec![[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]];
    for (name, bases, w_cr) in [
        ("triangle", corners, 3.0 * pi2),
        ("line", line, 2.0 * pi2 / 4.0),
    ] {
        let rods_of: Vec<Rod> = bases.iter().map(|b| column_at(*b)).collect();
        let rods: Vec<SystemRod> = rods_of
            .iter()
            .zip(&bases)
            .map(|(rod, b)| SystemRod {
                rod,
                loads: no_loads(),
                attachment: [b[0], b[1], 0.0],
                attachment_rotation: IDENTITY,
            })
            .collect();
        for (ratio, want) in [(0.97, true), (1.03, false)] {
            let pf = platform([0.0, 0.0, 1.0], [0.0, 0.0, -ratio * w_cr], [0.0; 3]);
            let sys = solve_system(&rods, &pf, None, &opts())
                .unwrap_or_else(|e| panic!("{name} at {ratio} W_cr: {e}"));
            assert_eq!(sys.stable, Some(want), "{name} at {ratio} W_cr");
            for r in &sys.rods {
                let t = r.solution.tip.r;
                assert!(t[0].hypot(t[1]) < 0.1 + 1e-9, "{name}: straight {t:?}");
            }
        }
    }
}

/// The held tip's point Jacobian (`jacobian::point_jacobian6`) against central differences
/// of whole held solves: the pose at mid-length and the reaction, for a pressure and a tip
/// moment, pinned and clamped; the held tip's own position does not move.
#[test]
fn held_point_jacobian_matches_central_differences_of_held_solves() {
    use softrod_core::jacobian::{point_jacobian6, Input, Probe};
    let rod = Rod::new(p002_actuator(tilted(), 9.81, 20)).unwrap();
    let ld = loads(&[30e3, 5e3, 0.0]);
    let free = solve_with_shape(&rod, &ld, None, &opts()).unwrap().0;
    let aside = [free.tip.r[0] + 0.008, free.tip.r[1], free.tip.r[2] - 0.004];
    let tip = Probe::tip(&rod);
    let inputs = [Input::Pressure(0), Input::TipMoment(1)];
    // Steps: 50 Pa and 1e-4 N m, central differences of solves to tol 1e-12: truncation
    // O(h^2) ~ 1e-9 relative, round-off ~1e-12 * scale / h; 1e-5 relative, plus an absolute
    // floor for entries that vanish.
    let steps = [50.0, 1e-4];
    for c in [
        TipConstraint::Pinned { position: aside },
        TipConstraint::Clamped {
            position: aside,
            rotation: free.tip.rot,
        },
    ] {
        let sol = solve_constrained(&rod, &ld, &c, None, &opts()).unwrap();
        // A node near mid-length (the shapes report nodes).
        let s_mid = sol.shape.s[sol.shape.s.len() / 2];
        let mid = Probe::at(&rod, s_mid).unwrap();
        let jac = point_jacobian6(&rod, &ld, &c, &sol.solution, &inputs, &mid).unwrap();
        let at_tip = point_jacobian6(&rod, &ld, &c, &sol.solution, &inputs, &tip).unwrap();
        let solve = |k: usize, h: f64| {
            let mut l = ld.clone();
            match inputs[k] {
                Input::Pressure(j) => l.pressures[j] += h,
                Input::TipMoment(j) => l.tip_moment[j] += h,
                _ => unreachable!(),
            }
            solve_constrained(&rod, &l, &c, Some(&sol.solution.x), &opts()).unwrap()
        };
        for k in 0..inputs.len() {
            let h = steps[k];
            let (hi, lo) = (solve(k, h), solve(k, -h));
            // The position at that node.
            let node = |s: &softrod_core::statics::constraint::ConstrainedSolution| {
                let i = s
                    .shape
                    .s
                    .iter()
                    .position(|&x| x == s_mid)
                    .expect("the same nodes");
                s.shape.position[i]
            };
            let (ph, pl) = (node(&hi), node(&lo));
            for i in 0..3 {
                let fd = (ph[i] - pl[i]) / (2.0 * h);
                let d = jac.point.d_position[k][i];
                assert!(
                    (fd - d).abs() < 1e-5 * d.abs() + 1e-12 / h.min(1.0),
                    "{}: d r_mid[{i}] / d input {k}: {d} vs {fd}",
                    c.name()
                );
                let fd_f = (hi.tip_reaction_force[i] - lo.tip_reaction_force[i]) / (2.0 * h);
                let d_f = jac.reaction_force[k][i];
                assert!(
                    (fd_f - d_f).abs() < 1e-5 * d_f.abs() + 1e-9,
                    "{}: d F_r[{i}] / d input {k}: {d_f} vs {fd_f}",
                    c.name()
                );
                let fd_m = (hi.tip_reaction_moment[i] - lo.tip_reaction_moment[i]) / (2.0 * h);
                let d_m = jac.reaction_moment[k][i];
                assert!(
                    (fd_m - d_m).abs() < 1e-5 * d_m.abs() + 1e-9,
                    "{}: d M_r[{i}] / d input {k}: {d_m} vs {fd_m}",
                    c.name()
                );
                // The held tip stays where it is held.
                assert!(at_tip.point.d_position[k][i].abs() < 1e-12 / h.min(1.0));
            }
        }
        // Not zeros by construction: the pressure moves the mid-length and the reaction.
        assert!(jac.point.d_position[0].iter().any(|v| v.abs() > 1e-8));
        assert!(jac.reaction_force[0].iter().any(|v| v.abs() > 1e-7));
    }
}
