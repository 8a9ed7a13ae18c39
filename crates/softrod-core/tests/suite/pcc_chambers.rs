//! Chamber layouts of the PCC model (paper 003 Secs. III-IV): three chambers, six chambers and
//! three chamber pairs (two chambers on one pressure channel).
//!
//! - Generalised pressure forces against the paper's closed forms: eq. 11 for three forces
//!   at 0/120/240 deg (with the sign of its Q3 corrected, see docs/pcc.md), eq. 11 applied
//!   twice for six chambers, eq. 11 with the pair's resultant for three pairs, and eq. 13
//!   (planar) for two opposite forces or two opposite pairs; for the `tip_force` model
//!   (paper) and the `chamber` model (virtual work p A delta l).
//! - Weightless statics against their closed forms: elongation sum(F)/k_L and
//!   theta = M/k_theta exactly for the chamber model; L = L0 + B(theta) sum(F)/k_L and
//!   k_theta theta = M + L N(theta) sum(F) for the tip-force model; bending towards the
//!   direction opposite the chambers' resultant sum(F_k c_k) in both.
//! - A three-channel pair design and the six-channel design with the pair pressures
//!   duplicated give the same statics and dynamics.
//! - Symmetry: six equal pressures give pure elongation; turning the pressure pattern by
//!   60 deg turns the bending plane by 60 deg (statics and dynamics).
//!
//! Derivation (docs/pcc.md, "Pressure"): a chamber k with centroid c_k = r_k (cos phi_k,
//! sin phi_k) and force F_k = p_k A_k. Tip follower force F_k d3 at p_tip + R c_k:
//!   Q_L = d3 . dp/dL F = B F,  Q_theta = (-r_k cos(phi - phi_k) + L N) F,
//!   Q_phi = r_k sin(phi - phi_k) sin(theta) F,
//! with B = sin(theta)/theta, N = (theta - sin theta)/theta^2 (d3 . dp/dtheta = L N,
//! d3 . dp/dphi = 0, and d3 . dR/dq c = (omega_q x c)_3 with the body angular velocities
//! omega_theta = (-sin phi, cos phi, 0), omega_phi = (-cos phi sin theta, -sin phi sin theta,
//! cos theta - 1)). Chamber work F_k l_k, l_k = L - r_k theta cos(phi - phi_k):
//!   Q_L = F, Q_theta = -r_k cos(phi - phi_k) F, Q_phi = r_k theta sin(phi - phi_k) F.
//! Two equal forces at angles a and a + 60 deg and radius r act like one force 2F at
//! a + 30 deg and radius r cos(30 deg): the forces are linear in c_k (Table I).

// Index loops over coordinates read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::{chamber, design, direct_section, IDENTITY};
use softrod_core::pcc::{InitialState, PccModel, PccSpec, PressureModel, StepOptions};
use softrod_core::spec::DesignSpec;
use std::f64::consts::PI;

/// Chamber geometry of the bundled `stiff_flop_pcc` arm: radius 4 mm at 9 mm.
const RC: f64 = 9e-3;
const CHAMBER_RADIUS: f64 = 4e-3;
const L0: f64 = 0.11;
const K_L: f64 = 246.0;
const K_THETA: f64 = 0.06;
const SIX: [usize; 6] = [0, 1, 2, 3, 4, 5];
const PAIRS: [usize; 6] = [0, 0, 1, 1, 2, 2];

fn area() -> f64 {
    PI * CHAMBER_RADIUS * CHAMBER_RADIUS
}

/// Generalised forces against closed forms: both are a few dozen flops on O(1) numbers
/// (the core's through dual numbers of the rotation, the closed form directly), so they
/// agree to ~1e-15 of the component's scale; 1e-12 leaves a margin while a wrong sign or
/// factor of any one chamber's term is off by > 1e-3.
const Q_TOL: f64 = 1e-12;
/// Statics against closed forms: Newton stops when its last update is below 1e-11 of the
/// coordinate scale (L0, 1 rad) and converges quadratically, so the solution is exact to
/// round-off; 1e-10 (relative to L0 or 1 rad) is 10x Newton's own tolerance.
const STATICS_TOL: f64 = 1e-10;
/// Two designs that should be the same model: the core evaluates the same sums; 1e-13 of
/// the coordinate scale allows for a different summation order of the chamber terms only.
const SAME_TOL: f64 = 1e-13;
/// Symmetries: the chamber angles k 60 deg are rounded (cos 60 deg = 0.5000000000000001),
/// so a pattern turned by 60 deg is the same model to ~1e-16 relative, and six equal
/// pressures leave a resultant of ~1e-17 N m instead of 0. Static Newton (fresh Jacobian,
/// quadratic) carries that to ~1e-14, and so does a run under equal pressures (theta is
/// forced only by that round-off); 1e-12 rad is the brief's bound for "exactly".
const SYM_TOL: f64 = 1e-12;
/// A turned pattern over 300 time steps: the two runs take different Newton paths (the
/// Newton matrix is reused while it contracts), and each step stops once its update is
/// below the default tolerance 1e-11 of the scale, leaving a few 1e-12 per step that the
/// damped arm does not amplify (measured 7e-12 rad after 300 steps); 1e-10 is 10x Newton's
/// tolerance.
const DYN_SYM_TOL: f64 = 1e-10;

/// The six-chamber arm of paper 003 (bundled `stiff_flop_pcc`: 110 mm, 59 g, chambers 4 mm
/// at 9 mm, 0/60/.../300 deg) with chamber k on channel `channels[k]`.
fn arm6(channels: [usize; 6], model: PressureModel, g: f64, k_theta: f64) -> DesignSpec {
    let mut body = direct_section("arm", L0, 27.06, 9.02, 0.0066, 0.0044, 0.059, 16);
    body.outer_radius = Some(16e-3);
    body.chambers = (0..6)
        .map(|k| chamber(CHAMBER_RADIUS, RC, 60.0 * k as f64, channels[k]))
        .collect();
    let mut d = design(vec![body], IDENTITY, g);
    d.pcc = Some(PccSpec {
        k_l: Some(K_L),
        b_l: Some(119.0),
        k_theta: Some(k_theta),
        b_theta: Some(0.02),
        k_phi: Some(0.0),
        b_phi: Some(0.0),
        pressure_force: model,
        ..Default::default()
    });
    d
}

/// The same arm with three chambers at 0/120/240 deg (paper eq. 9: three forces).
fn arm3(model: PressureModel) -> DesignSpec {
    let mut d = arm6(SIX, model, 0.0, K_THETA);
    d.sections[0].chambers = (0..3)
        .map(|k| chamber(CHAMBER_RADIUS, RC, 120.0 * k as f64, k))
        .collect();
    d
}

fn planar(mut d: DesignSpec, plane_deg: f64) -> DesignSpec {
    d.pcc.as_mut().unwrap().plane = Some(plane_deg.to_radians());
    d
}

/// Paper 003's B = sin(theta)/theta and N = (theta - sin theta)/theta^2 from their printed
/// series (Sec. IV-A and IV-B), 30 terms: converged to round-off for |theta| <= pi.
fn b_n(th: f64) -> (f64, f64) {
    let (mut b, mut n, mut term) = (0.0, 0.0, 1.0); // term = (-1)^k th^(2k) / (2k+1)!
    for k in 0..30 {
        b += term;
        // th^(2k+1)/(2k+3)! = term * th / ((2k+2)(2k+3))
        n += term * th / ((2 * k + 2) as f64 * (2 * k + 3) as f64);
        term *= -th * th / ((2 * k + 2) as f64 * (2 * k + 3) as f64);
    }
    (b, n)
}

/// Paper 003 eq. 11, literally: three tip forces F at r_c and 0/120/240 deg, in (L, theta,
/// phi). `printed_q3`: the printed Q3, with +r_c/2 sin(phi) sin(theta) in the F_B2 and F_B3
/// terms; otherwise the corrected -r_c/2 (Table I and the derivation). `chamber`: the
/// chamber-work analogue (B -> 1, L N -> 0, sin(theta) -> theta).
fn eq11(
    l: f64,
    th: f64,
    ph: f64,
    rc: f64,
    f: [f64; 3],
    printed_q3: bool,
    chamber: bool,
) -> [f64; 3] {
    let (b, n) = b_n(th);
    let (b, ln, st) = if chamber {
        (1.0, 0.0, th)
    } else {
        (b, l * n, th.sin())
    };
    let (sp, cp) = ph.sin_cos();
    let s3 = 3f64.sqrt() / 2.0;
    let half = if printed_q3 { 0.5 } else { -0.5 };
    [
        b * (f[0] + f[1] + f[2]),
        (-cp * rc + ln) * f[0]
            + (rc / 2.0 * cp - s3 * rc * sp + ln) * f[1]
            + (rc / 2.0 * cp + s3 * rc * sp + ln) * f[2],
        rc * sp * st * f[0]
            + (half * rc * sp * st - s3 * rc * cp * st) * f[1]
            + (half * rc * sp * st + s3 * rc * cp * st) * f[2],
    ]
}

/// Paper 003 eq. 13 (planar): forces F1 at +r_c and F2 at -r_c in the bending plane.
fn eq13(l: f64, th: f64, rc: f64, f: [f64; 2], chamber: bool) -> [f64; 2] {
    let (b, n) = b_n(th);
    let (b, ln) = if chamber { (1.0, 0.0) } else { (b, l * n) };
    [b * (f[0] + f[1]), (-rc + ln) * f[0] + (rc + ln) * f[1]]
}

/// The model's pressure forces at (L, theta, phi), in paper coordinates:
/// Q_theta = Q . dx/dtheta, Q_phi = Q . dx/dphi with x = (L, theta cos phi, theta sin phi).
fn pressure_q(m: &PccModel, l: f64, th: f64, ph: f64, p: &[f64]) -> [f64; 3] {
    let (sp, cp) = ph.sin_cos();
    let x = [l, th * cp, th * sp];
    let q = m.force_terms(&x, &[0.0; 3], &[0.0; 3], p).unwrap()[2].clone();
    [q[0], q[1] * cp + q[2] * sp, th * (-q[1] * sp + q[2] * cp)]
}

/// Configurations (L, theta, phi): small theta (series branch of the kinematics, < 0.5
/// rad), moderate and large bending, all four quadrants of phi.
const CONFIGS: [(f64, f64, f64); 5] = [
    (0.11, 1e-3, 1.0),
    (0.115, 0.3, 2.9),
    (0.12, 0.9, 0.4),
    (0.13, 2.3, -2.0),
    (0.14, 1.6, -0.7),
];

fn assert_q(got: &[f64], want: &[f64], scale: &[f64], what: &str) {
    for i in 0..got.len() {
        assert!(
            (got[i] - want[i]).abs() <= Q_TOL * scale[i],
            "{what}: Q[{i}] = {} vs closed form {} (scale {})",
            got[i],
            want[i],
            scale[i]
        );
    }
}

/// Scales of (Q_L, Q_theta, Q_phi): total force, N; force times (r_c + L), N m; force
/// times r_c, N m.
fn scales(ftot: f64, l: f64) -> [f64; 3] {
    [ftot, ftot * (RC + l), ftot * RC]
}

#[test]
fn three_chambers_match_paper_eq11_with_corrected_q3() {
    let p = [3e4, 1e4, 5e4];
    let f = p.map(|pk| pk * area());
    let ftot: f64 = f.iter().sum();
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        let chamber = model == PressureModel::Chamber;
        let m = PccModel::new(&arm3(model)).unwrap();
        for &(l, th, ph) in &CONFIGS {
            let q = pressure_q(&m, l, th, ph, &p);
            let want = eq11(l, th, ph, RC, f, false, chamber);
            assert_q(&q, &want, &scales(ftot, l), &format!("{model:?} {th} {ph}"));
            // The printed Q3 (+r_c/2 sin(phi) sin(theta) for F_B2, F_B3) is not the
            // derivative of the virtual work: it differs by r_c sin(phi) sin(theta) (F2 + F3).
            let printed = eq11(l, th, ph, RC, f, true, chamber);
            let gap = RC * ph.sin() * if chamber { th } else { th.sin() } * (f[1] + f[2]);
            assert!(((printed[2] - q[2]) - gap).abs() <= Q_TOL * ftot * RC);
            if th > 0.1 {
                assert!((printed[2] - q[2]).abs() > 1e-3 * ftot * RC * th.sin().abs());
            }
        }
        // Equal forces: by symmetry Q_theta = 3 L N F (tip force) or 0 (chamber) and
        // Q_phi = 0; the printed Q3 would give 2 r_c sin(phi) sin(theta) F.
        let pe = [4e4; 3];
        let (l, th, ph) = (0.12, 0.9, 0.4);
        let q = pressure_q(&m, l, th, ph, &pe);
        let fe = 4e4 * area();
        let (_, n) = b_n(th);
        let qt = if chamber { 0.0 } else { 3.0 * l * n * fe };
        assert_q(
            &q[1..],
            &[qt, 0.0],
            &scales(3.0 * fe, l)[1..],
            &format!("{model:?} equal"),
        );
    }
}

#[test]
fn six_chambers_are_eq11_twice() {
    // Chambers 1, 3, 5 at 0/120/240 deg and 2, 4, 6 at 60/180/300 deg: the second triple
    // is eq. 11 at phi - 60 deg.
    let p = [3e4, 1e4, 5e4, 0.0, 2e4, 7e4];
    let f = p.map(|pk| pk * area());
    let ftot: f64 = f.iter().sum();
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        let chamber = model == PressureModel::Chamber;
        let m = PccModel::new(&arm6(SIX, model, 0.0, K_THETA)).unwrap();
        for &(l, th, ph) in &CONFIGS {
            let q = pressure_q(&m, l, th, ph, &p);
            let odd = eq11(l, th, ph, RC, [f[0], f[2], f[4]], false, chamber);
            let even = eq11(l, th, ph - PI / 3.0, RC, [f[1], f[3], f[5]], false, chamber);
            let want: Vec<f64> = (0..3).map(|i| odd[i] + even[i]).collect();
            assert_q(&q, &want, &scales(ftot, l), &format!("{model:?} {th} {ph}"));
        }
    }
}

#[test]
fn three_pairs_are_eq11_with_the_pair_resultant() {
    // Pair i (chambers at 120 i and 120 i + 60 deg, one channel) = one force 2 P_i A at
    // 120 i + 30 deg and radius r_c cos(30 deg): eq. 11 at phi - 30 deg. This is paper
    // 003's own reading: the original STIFF-FLOP connects its six chambers into three pairs
    // (Sec. II) and eq. 9 sums three forces.
    let p = [3e4, 1e4, 5e4];
    let f = p.map(|pk| 2.0 * pk * area());
    let ftot: f64 = f.iter().sum();
    let r_pair = RC * (PI / 6.0).cos();
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        let chamber = model == PressureModel::Chamber;
        let m = PccModel::new(&arm6(PAIRS, model, 0.0, K_THETA)).unwrap();
        assert_eq!(m.n_channels, 3);
        for &(l, th, ph) in &CONFIGS {
            let q = pressure_q(&m, l, th, ph, &p);
            let want = eq11(l, th, ph - PI / 6.0, r_pair, f, false, chamber);
            assert_q(&q, &want, &scales(ftot, l), &format!("{model:?} {th} {ph}"));
        }
    }
}

#[test]
fn opposite_chambers_and_opposite_pairs_match_paper_eq13() {
    // Planar model (paper eq. 12/13), signed theta in the plane.
    let a = area();
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        let chamber = model == PressureModel::Chamber;
        // Two opposite chambers (0 and 180 deg) in the plane at 0 deg: eq. 13 as printed.
        let m = PccModel::new(&planar(arm6(SIX, model, 0.0, K_THETA), 0.0)).unwrap();
        // Two opposite pairs (chambers 1+2 and 4+5) in the plane at 30 deg: eq. 13 with
        // F = 2 P A and r_c cos(30 deg) (paper Fig. 2b, case II).
        let mp = PccModel::new(&planar(arm6(SIX, model, 0.0, K_THETA), 30.0)).unwrap();
        for &(l, th) in &[(0.11, 1e-3), (0.12, 0.4), (0.13, -1.1), (0.125, 2.5)] {
            let (p1, p2) = (6e4, 2e4);
            let q = m
                .force_terms(
                    &[l, th],
                    &[0.0; 2],
                    &[0.0; 2],
                    &[p1, 0.0, 0.0, p2, 0.0, 0.0],
                )
                .unwrap()[2]
                .clone();
            let want = eq13(l, th, RC, [p1 * a, p2 * a], chamber);
            let sc = [(p1 + p2) * a, (p1 + p2) * a * (RC + l)];
            assert_q(&q, &want, &sc, &format!("{model:?} opposite chambers {th}"));
            let q = mp
                .force_terms(&[l, th], &[0.0; 2], &[0.0; 2], &[p1, p1, 0.0, p2, p2, 0.0])
                .unwrap()[2]
                .clone();
            let f = [2.0 * p1 * a, 2.0 * p2 * a];
            let want = eq13(l, th, RC * (PI / 6.0).cos(), f, chamber);
            let sc = [f[0] + f[1], (f[0] + f[1]) * (RC + l)];
            assert_q(&q, &want, &sc, &format!("{model:?} opposite pairs {th}"));
        }
        // The spatial model in that plane gives the same Q_L, Q_theta, and Q_phi = 0.
        let ms = PccModel::new(&arm6(SIX, model, 0.0, K_THETA)).unwrap();
        let (l, th) = (0.12, 0.7);
        let p = [6e4, 6e4, 0.0, 2e4, 2e4, 0.0];
        let q = pressure_q(&ms, l, th, PI / 6.0, &p);
        let f = [12e4 * a, 4e4 * a];
        let want = eq13(l, th, RC * (PI / 6.0).cos(), f, chamber);
        assert_q(
            &q,
            &[want[0], want[1], 0.0],
            &scales(f[0] + f[1], l),
            &format!("{model:?} spatial"),
        );
    }
}

/// Weightless statics of the six-chamber arm; returns (L, theta, phi).
fn statics(d: &DesignSpec, p: &[f64]) -> [f64; 3] {
    let m = PccModel::new(d).unwrap();
    let s = m.solve_statics(p, None, &StepOptions::default()).unwrap();
    let th = s.x[1].hypot(s.x[2]);
    [s.x[0], th, s.x[2].atan2(s.x[1])]
}

/// Resultant b = sum F_k c_k of the chambers (N m) in the section frame.
fn resultant(channels: [usize; 6], p: &[f64]) -> ([f64; 2], f64) {
    let mut b = [0.0; 2];
    let mut ftot = 0.0;
    for k in 0..6 {
        let f = p[channels[k]] * area();
        let ang = (60.0 * k as f64).to_radians();
        b[0] += f * RC * ang.cos();
        b[1] += f * RC * ang.sin();
        ftot += f;
    }
    (b, ftot)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    d.min(2.0 * PI - d)
}

#[test]
fn weightless_statics_chamber_model_closed_forms() {
    // Chamber work is linear in (L, theta_x, theta_y) and so is the elastic force: the
    // equilibrium is exact at any bending, L = L0 + sum F / k_L, theta = M / k_theta with
    // M = |sum F_k c_k|, towards phi = angle of -sum F_k c_k (away from the chambers).
    let pa = 1e5 * area();
    let cases: [([usize; 6], Vec<f64>, f64, f64); 6] = [
        // one chamber at 0 deg: M = p A r, bends to 180 deg
        (SIX, vec![1e5, 0.0, 0.0, 0.0, 0.0, 0.0], pa * RC, 180.0),
        // the pair at 0/60 deg: M = 2 p A r cos 30, bends to 210 deg (-150)
        (
            PAIRS,
            vec![1e5, 0.0, 0.0],
            2.0 * pa * RC * (PI / 6.0).cos(),
            -150.0,
        ),
        // three adjacent chambers at 300/0/60 deg (paper Sec. V-C): M = 2 p A r
        (
            SIX,
            vec![1e5, 1e5, 0.0, 0.0, 0.0, 1e5],
            2.0 * pa * RC,
            180.0,
        ),
        // two pairs (0/60 and 120/180): M = 2 p A r cos 30 * 2 cos 60, towards 270 deg
        (
            PAIRS,
            vec![1e5, 1e5, 0.0],
            2.0 * pa * RC * (PI / 6.0).cos(),
            -90.0,
        ),
        // 1.5 bar on three adjacent chambers: 130 deg of bending, still exact
        (
            SIX,
            vec![1.5e5, 1.5e5, 0.0, 0.0, 0.0, 1.5e5],
            3.0 * pa * RC,
            180.0,
        ),
        // mixed pressures: against the resultant computed here
        (SIX, vec![3e4, 1e4, 5e4, 0.0, 2e4, 7e4], f64::NAN, f64::NAN),
    ];
    for (channels, p, moment, phi_deg) in cases {
        let d = arm6(channels, PressureModel::Chamber, 0.0, K_THETA);
        let [l, th, ph] = statics(&d, &p);
        let (b, ftot) = resultant(channels, &p);
        let m_res = b[0].hypot(b[1]);
        if moment.is_finite() {
            assert!((m_res - moment).abs() < 1e-15, "{m_res} vs {moment}");
            assert!(angle_diff((-b[1]).atan2(-b[0]), phi_deg.to_radians()) < 1e-14);
        }
        assert!(
            (l - L0 - ftot / K_L).abs() < STATICS_TOL * L0,
            "{p:?}: L {l}"
        );
        assert!(
            (th - m_res / K_THETA).abs() < STATICS_TOL,
            "{p:?}: theta {th}"
        );
        assert!(
            angle_diff(ph, (-b[1]).atan2(-b[0])) < STATICS_TOL,
            "{p:?}: phi {ph}"
        );
    }
}

/// Root of k theta = M + (L0 + B(theta) F / k_L) N(theta) F on (0, pi] by bisection (the
/// tip-force model's weightless equilibrium, bending plane opposite the resultant).
fn tip_force_theta(k_theta: f64, moment: f64, ftot: f64) -> f64 {
    let g = |th: f64| {
        let (b, n) = b_n(th);
        k_theta * th - moment - (L0 + b * ftot / K_L) * n * ftot
    };
    let (mut lo, mut hi) = (0.0, PI);
    assert!(g(lo) <= 0.0 && g(hi) > 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn weightless_statics_tip_force_model_closed_forms() {
    // Tip follower forces: Q_L = B sum F, Q_theta = -M cos(phi - beta) + L N sum F, Q_phi =
    // M sin(phi - beta) sin(theta) (beta = angle of sum F_k c_k). Equilibrium: phi = beta + pi,
    // L = L0 + B sum F / k_L, k_theta theta = M + L N sum F. theta = M / k_theta holds only
    // when sum F = 0; the L N sum F term (~ L theta sum F / 6) is a negative stiffness, so
    // k_theta = 0.3 N m/rad here keeps the equilibrium unique and stable (with the arm's
    // 0.06 a pair above ~0.3 bar has no stable straight-ish equilibrium).
    let kt = 0.3;
    let cases: [([usize; 6], Vec<f64>); 4] = [
        (SIX, vec![1e5, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (PAIRS, vec![5e4, 0.0, 0.0]),
        (PAIRS, vec![5e4, 2e4, 0.0]),
        (SIX, vec![3e4, 1e4, 5e4, 0.0, 2e4, 7e4]),
    ];
    for (channels, p) in cases {
        let d = arm6(channels, PressureModel::TipForce, 0.0, kt);
        let [l, th, ph] = statics(&d, &p);
        let (b, ftot) = resultant(channels, &p);
        let m_res = b[0].hypot(b[1]);
        let want = tip_force_theta(kt, m_res, ftot);
        let (bb, _) = b_n(want);
        assert!(
            (th - want).abs() < STATICS_TOL,
            "{p:?}: theta {th} vs {want}"
        );
        assert!(
            (l - L0 - bb * ftot / K_L).abs() < STATICS_TOL * L0,
            "{p:?}: L {l}"
        );
        assert!(
            angle_diff(ph, (-b[1]).atan2(-b[0])) < STATICS_TOL,
            "{p:?}: phi {ph}"
        );
        // ... and it bends further than M / k_theta (the follower forces' lever).
        assert!(th > m_res / kt * 1.01, "{p:?}");
    }
    // Antagonistic pressures, sum F = 0 (0.5 bar against -0.5 bar, opposite chambers; eq.
    // 13 with F2 = -F1): Q_L = 0, Q_theta = -2 r F exactly, so L = L0 and theta = 2 r F /
    // k_theta in both models, at the arm's own k_theta.
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        let d = arm6(SIX, model, 0.0, K_THETA);
        let [l, th, ph] = statics(&d, &[5e4, 0.0, 0.0, -5e4, 0.0, 0.0]);
        assert!((l - L0).abs() < STATICS_TOL * L0, "{model:?}: L {l}");
        let want = 2.0 * RC * 5e4 * area() / K_THETA;
        assert!((th - want).abs() < STATICS_TOL, "{model:?}: {th} vs {want}");
        assert!(angle_diff(ph, PI) < STATICS_TOL, "{model:?}: phi {ph}");
    }
}

/// Pressures of `rows` time steps: a ramp and a sine per channel (Pa).
fn inputs(n_channels: usize, rows: usize, dt: f64, amp: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(rows * n_channels);
    for k in 0..rows {
        let t = k as f64 * dt;
        for c in 0..n_channels {
            let w = 2.0 * PI * (1.0 + c as f64);
            out.push(amp[c] * (t / (t + 0.05)) * (1.0 + 0.3 * (w * t).sin()));
        }
    }
    out
}

fn simulate(d: &DesignSpec, p: &[f64], dt: f64) -> softrod_core::pcc::PccTrajectory {
    PccModel::new(d)
        .unwrap()
        .simulate(dt, p, &InitialState::Rest, 1, &StepOptions::default())
        .unwrap()
}

#[test]
fn pair_design_equals_six_channels_with_duplicated_pressures() {
    // Gravity on (upright arm) and a tip body, both pressure models: statics at several
    // pressures and 0.3 s of dynamics under varying pressures.
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        let mut pair = arm6(PAIRS, model, 9.81, K_THETA);
        pair.tip.mass = 0.01;
        pair.tip.com_offset = [0.0, 0.0, 0.005];
        let mut six = pair.clone();
        for (k, c) in six.sections[0].chambers.iter_mut().enumerate() {
            c.channel = SIX[k];
        }
        let mp = PccModel::new(&pair).unwrap();
        let ms = PccModel::new(&six).unwrap();
        assert_eq!((mp.n_channels, ms.n_channels), (3, 6));
        let dup = |p: &[f64]| -> Vec<f64> { PAIRS.iter().map(|&c| p[c]).collect() };
        // tip_force on the soft arm: low pressures (see the test above).
        let level = if model == PressureModel::TipForce {
            0.15e5
        } else {
            1e5
        };
        for p in [[1.0, 0.0, 0.0], [1.0, 0.5, 0.0], [0.2, 0.7, 1.0]] {
            let p = p.map(|z| z * level);
            let a = mp.solve_statics(&p, None, &StepOptions::default()).unwrap();
            let b = ms
                .solve_statics(&dup(&p), None, &StepOptions::default())
                .unwrap();
            for i in 0..3 {
                let sc = if i == 0 { L0 } else { 1.0 };
                assert!((a.x[i] - b.x[i]).abs() <= SAME_TOL * sc, "{model:?} {p:?}");
            }
            assert!(a.x[1].hypot(a.x[2]) > 0.05, "{model:?} {p:?}: bends");
        }
        let dt = 1e-3;
        let rows = 301;
        let amp = [level, 0.6 * level, 0.3 * level];
        let p3 = inputs(3, rows, dt, &amp);
        let p6: Vec<f64> = p3.chunks(3).flat_map(dup).collect();
        let (ta, tb) = (simulate(&pair, &p3, dt), simulate(&six, &p6, dt));
        assert_eq!(ta.x.len(), rows);
        for k in 0..rows {
            for i in 0..3 {
                let sc = if i == 0 { L0 } else { 1.0 };
                assert!(
                    (ta.x[k][i] - tb.x[k][i]).abs() <= SAME_TOL * sc,
                    "{model:?} step {k} x[{i}]"
                );
                // rates: scale / (0.1 s), the arm's slowest time constants
                assert!(
                    (ta.v[k][i] - tb.v[k][i]).abs() <= SAME_TOL * sc * 10.0,
                    "{model:?} step {k} v[{i}]"
                );
            }
        }
        assert!(ta.x[rows - 1][1].hypot(ta.x[rows - 1][2]) > 0.05);
    }
}

/// Rotate a bending vector by `deg`.
fn rot(x: &[f64], deg: f64) -> [f64; 2] {
    let (s, c) = deg.to_radians().sin_cos();
    [c * x[1] - s * x[2], s * x[1] + c * x[2]]
}

#[test]
fn six_equal_pressures_elongate_only_and_patterns_rotate_by_60_deg() {
    for model in [PressureModel::TipForce, PressureModel::Chamber] {
        // Upright with gravity: gravity along the axis keeps the symmetry.
        let m = PccModel::new(&arm6(SIX, model, 9.81, K_THETA)).unwrap();
        let mw = PccModel::new(&arm6(SIX, model, 0.0, K_THETA)).unwrap();
        for p in [2e4, 1e5] {
            let s = m
                .solve_statics(&[p; 6], None, &StepOptions::default())
                .unwrap();
            assert!(s.x[1].hypot(s.x[2]) <= SYM_TOL, "{model:?} {p}: {:?}", s.x);
            // Weightless: theta = 0 exactly, so L = L0 + 6 p A / k_L in both models (B(0) = 1).
            let s = mw
                .solve_statics(&[p; 6], None, &StepOptions::default())
                .unwrap();
            assert!(s.x[1].hypot(s.x[2]) <= SYM_TOL);
            let want = L0 + 6.0 * p * area() / K_L;
            assert!(
                (s.x[0] - want).abs() <= STATICS_TOL * L0,
                "{model:?}: {}",
                s.x[0]
            );
        }
        // A pattern and its turns by 60 and 120 deg (channel k -> k + j).
        let level = if model == PressureModel::TipForce {
            0.2
        } else {
            1.0
        };
        let base = [0.9e5, 0.4e5, 0.0, 0.1e5, 0.0, 0.3e5].map(|z| z * level);
        let s0 = m
            .solve_statics(&base, None, &StepOptions::default())
            .unwrap();
        assert!(s0.x[1].hypot(s0.x[2]) > 0.05, "{model:?}: bends");
        for j in 1..3 {
            let turned: Vec<f64> = (0..6).map(|k| base[(k + 6 - j) % 6]).collect();
            let s = m
                .solve_statics(&turned, None, &StepOptions::default())
                .unwrap();
            let want = rot(&s0.x, 60.0 * j as f64);
            assert!((s.x[0] - s0.x[0]).abs() <= SYM_TOL * L0, "{model:?} L");
            assert!(
                (s.x[1] - want[0]).abs() <= SYM_TOL && (s.x[2] - want[1]).abs() <= SYM_TOL,
                "{model:?} turned {j}: {:?} vs {want:?}",
                &s.x[1..]
            );
        }
        // Dynamics: equal time-varying pressures never bend the arm; a turned pattern turns
        // the whole trajectory.
        let dt = 1e-3;
        let rows = 301;
        let amp: Vec<f64> = base.to_vec();
        let p = inputs(6, rows, dt, &amp);
        let eq: Vec<f64> = p.chunks(6).flat_map(|r| [r[0]; 6]).collect();
        let d = arm6(SIX, model, 9.81, K_THETA);
        let te = simulate(&d, &eq, dt);
        for x in &te.x {
            assert!(x[1].hypot(x[2]) <= SYM_TOL, "{model:?}: {x:?}");
        }
        let t0 = simulate(&d, &p, dt);
        let turned: Vec<f64> = p
            .chunks(6)
            .flat_map(|r| (0..6).map(move |k| r[(k + 5) % 6]))
            .collect();
        let t1 = simulate(&d, &turned, dt);
        for (a, b) in t0.x.iter().zip(&t1.x) {
            let want = rot(a, 60.0);
            assert!((a[0] - b[0]).abs() <= DYN_SYM_TOL * L0, "{model:?} L");
            assert!(
                (b[1] - want[0]).abs() <= DYN_SYM_TOL && (b[2] - want[1]).abs() <= DYN_SYM_TOL,
                "{model:?}: {:?} vs {want:?}",
                &b[1..]
            );
        }
        assert!(
            t0.x[rows - 1][1].hypot(t0.x[rows - 1][2]) > 0.02,
            "{model:?}"
        );
    }
}
