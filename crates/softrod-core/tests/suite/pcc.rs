//! The PCC model of paper 003: series forms, consistency of mass matrix, Coriolis and
//! gravity terms (against finite differences of the model's own energy and mass matrix, and
//! against paper 003's planar matrices of eq. 12), energy conservation, the linear elongation
//! response and the time-step convergence order.

// Index loops over coordinates read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::{chamber, design, direct_section, rigid_section, IDENTITY};
use num_dual::{Dual2_64, DualNum};
use softrod_core::pcc::kinematics::{
    cosc_closed, cosc_t, segment_pose, sinc_closed, sinc_t, SERIES_SWITCH,
};
use softrod_core::pcc::{InitialState, MassModel, PccModel, PccSpec, PressureModel, StepOptions};
use softrod_core::spec::DesignSpec;

/// The closed forms lose digits to cancellation as t -> 0: the k-th t-derivative of
/// (1 - cos x)/x^2 carries a round-off of about eps / t^(k+1). The series is the accurate
/// side; the tolerance is 10 eps / t^(k+1) + 1e-14.
fn series_tol(t: f64, k: i32) -> f64 {
    10.0 * f64::EPSILON / t.powi(k + 1) + 1e-14
}

#[test]
fn series_match_closed_forms_and_derivatives() {
    // Values, first and second t-derivatives on both sides of the switch.
    for &t in &[1e-2, 0.1, 0.2, SERIES_SWITCH * 0.999, 0.3, 1.0, 4.0] {
        let x = Dual2_64::from_re(t).derivative();
        for (a, b) in [(sinc_t(x), sinc_closed(x)), (cosc_t(x), cosc_closed(x))] {
            for (k, (u, w)) in [(a.re, b.re), (a.v1, b.v1), (a.v2, b.v2)]
                .into_iter()
                .enumerate()
            {
                assert!(
                    (u - w).abs() <= series_tol(t, k as i32) * (1.0 + w.abs()),
                    "t = {t}, derivative {k}: series {u} vs closed {w}"
                );
            }
        }
    }
    // At theta = 0 the series give the limits exactly and finite derivatives
    // (Taylor coefficients 1, -1/6, 2/120 and 1/2, -1/24, 2/720).
    let z = Dual2_64::from_re(0.0).derivative();
    let (f1, f2) = (sinc_t(z), cosc_t(z));
    assert_eq!((f1.re, f1.v1, f1.v2), (1.0, -1.0 / 6.0, 2.0 / 120.0));
    assert_eq!((f2.re, f2.v1, f2.v2), (0.5, -1.0 / 24.0, 2.0 / 720.0));
    // The closed forms are NaN there: the reason for the series.
    assert!(sinc_closed(0.0f64).is_nan());
}

/// Paper 003 eq. 1 (closed form in (L, theta, phi)).
fn paper_eq1(l: f64, th: f64, ph: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    let (s, c) = th.sin_cos();
    let (sp, cp) = ph.sin_cos();
    (
        [l * cp * (1.0 - c) / th, l * sp * (1.0 - c) / th, l * s / th],
        [
            [cp * cp * (c - 1.0) + 1.0, sp * cp * (c - 1.0), cp * s],
            [sp * cp * (c - 1.0), cp * cp * (1.0 - c) + c, sp * s],
            [-cp * s, -sp * s, c],
        ],
    )
}

#[test]
fn kinematics_match_paper_eq1() {
    const TOL: f64 = 1e-14; // round-off of O(1) trigonometric expressions
    for &(th, ph) in &[(0.3, 0.2), (1.2, -2.0), (2.4, 3.0), (0.01, 1.0)] {
        let l = 0.11;
        let (p, r) = segment_pose(&[l, th * ph.cos(), th * ph.sin()], 1.0);
        let (pw, rw) = paper_eq1(l, th, ph);
        for i in 0..3 {
            assert!((p[i] - pw[i]).abs() < TOL * l, "{th} {ph}: p[{i}]");
            for j in 0..3 {
                assert!((r[i][j] - rw[i][j]).abs() < TOL, "{th} {ph}: R[{i}][{j}]");
            }
        }
    }
    // Straight at theta = 0, with no NaN.
    let (p, r) = segment_pose(&[0.1, 0.0, 0.0], 1.0);
    assert_eq!(p, [0.0, 0.0, 0.1]);
    assert_eq!(r, IDENTITY);
}

/// One 110 mm segment with three chambers (paper 003 Fig. 2), optional rigid cap and tip
/// body; gravity along -z of the base, i.e. the arm stands upright (paper eq. 7).
fn arm(g: f64, spec: PccSpec, cap: bool, tip_mass: f64) -> DesignSpec {
    let mut body = direct_section("body", 0.11, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.06, 16);
    body.chambers = vec![
        chamber(2.5e-3, 7e-3, 0.0, 0),
        chamber(2.5e-3, 7e-3, 120.0, 1),
        chamber(2.5e-3, 7e-3, 240.0, 2),
    ];
    let mut sections = vec![body];
    if cap {
        sections.push(rigid_section("cap", 0.01, 0.01));
    }
    let mut d = design(sections, IDENTITY, g);
    d.tip.mass = tip_mass;
    d.tip.com_offset = [0.002, 0.0, 0.005];
    d.tip.inertia = [2e-6, 3e-6, 1e-6];
    d.pcc = Some(spec);
    d
}

fn two_segments(g: f64) -> DesignSpec {
    let mut a = direct_section("m1", 0.05, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.03, 16);
    a.chambers = vec![
        chamber(2.5e-3, 7e-3, 0.0, 0),
        chamber(2.5e-3, 7e-3, 180.0, 1),
    ];
    let mut b = direct_section("m2", 0.06, 20.0, 9.0, 5.0e-3, 4.4e-3, 0.03, 16);
    b.chambers = vec![chamber(2.5e-3, 7e-3, 90.0, 2)];
    let mut d = design(
        vec![a, rigid_section("joint", 0.008, 0.005), b],
        IDENTITY,
        g,
    );
    d.tip.mass = 0.01;
    d
}

/// Central differences of a function of x.
fn fd(x: &[f64], h: f64, f: impl Fn(&[f64]) -> Vec<f64>) -> Vec<Vec<f64>> {
    (0..x.len())
        .map(|k| {
            let mut xp = x.to_vec();
            let mut xm = x.to_vec();
            xp[k] += h;
            xm[k] -= h;
            let (a, b) = (f(&xp), f(&xm));
            a.iter().zip(&b).map(|(u, w)| (u - w) / (2.0 * h)).collect()
        })
        .collect()
}

/// Central differences with h = 1e-6 on O(1) quantities: truncation h^2 ~ 1e-12, round-off
/// 1e-16/1e-6 = 1e-10; 1e-7 relative leaves a wide margin yet catches any wrong term.
const FD_TOL: f64 = 1e-7;

fn close(a: f64, b: f64, scale: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * scale
}

/// M a + C v (Lagrange's equations, computed through dual numbers) against M from the same
/// mass points and the Christoffel symbols of finite differences of M; gravity against
/// -dV/dq by finite differences of the energy; pressure force against -d(-p A l)/dq.
fn check_consistency(d: &DesignSpec, x: &[f64], v: &[f64], a: &[f64]) {
    let m = PccModel::new(d).unwrap();
    let n = m.ndof;
    let p: Vec<f64> = (0..m.n_channels).map(|k| 2e4 * (k as f64 + 1.0)).collect();
    let mm = m.mass_matrix(x).unwrap();
    let scale = mm.iter().flatten().fold(0.0f64, |s, z| s.max(z.abs()));
    // Symmetric positive definite (Cholesky succeeds).
    let mut l = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..=i {
            assert!(close(mm[i][j], mm[j][i], scale, 1e-14));
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                assert!(mm[i][i] - s > 0.0, "M not positive definite");
                l[i][j] = (mm[i][i] - s).sqrt();
            } else {
                l[i][j] = (mm[i][j] - s) / l[j][j];
            }
        }
    }
    let dm = fd(x, 1e-6, |z| m.mass_matrix(z).unwrap().concat());
    let zero = vec![0.0; n];
    let t = m.force_terms(x, v, a, &p).unwrap();
    for i in 0..n {
        let mut want = 0.0;
        for j in 0..n {
            want += mm[i][j] * a[j];
            for k in 0..n {
                // c_i = sum_jk (dM_ij/dq_k - 1/2 dM_jk/dq_i) v_j v_k
                want += (dm[k][i * n + j] - 0.5 * dm[i][j * n + k]) * v[j] * v[k];
            }
        }
        let sc = scale
            * (1.0
                + a.iter()
                    .chain(v)
                    .fold(0.0f64, |s, z| s.max(z.abs()))
                    .powi(2));
        assert!(
            close(t[0][i], want, sc, FD_TOL),
            "inertial[{i}] = {} vs M a + C v = {want}",
            t[0][i]
        );
    }
    let dv = fd(x, 1e-6, |z| {
        let e = m.energy(z, &zero, &p).unwrap();
        vec![e.gravity, e.elastic, e.pressure]
    });
    let t0 = m.force_terms(x, &zero, &zero, &p).unwrap();
    for i in 0..n {
        let g = t0[1][i];
        let gs = 1.0 + g.abs();
        assert!(
            close(g, -dv[i][0], gs, FD_TOL),
            "gravity[{i}] {g} vs {}",
            -dv[i][0]
        );
        let e = t0[3][i];
        assert!(close(e, -dv[i][1], 1.0 + e.abs(), FD_TOL), "elastic[{i}]");
        let q = t0[2][i];
        assert!(close(q, -dv[i][2], 1.0 + q.abs(), FD_TOL), "pressure[{i}]");
    }
}

#[test]
fn mass_coriolis_gravity_consistent_spatial() {
    let d = arm(9.81, PccSpec::default(), true, 0.02);
    check_consistency(&d, &[0.12, 0.7, -0.4], &[0.3, -2.0, 1.5], &[1.0, 3.0, -2.0]);
    // Near and at theta = 0 (series branch), where (L, theta, phi) would be singular.
    check_consistency(&d, &[0.11, 1e-3, 2e-3], &[0.1, 1.0, -1.0], &[0.5, 0.0, 1.0]);
    check_consistency(&d, &[0.11, 0.0, 0.0], &[0.1, 1.0, -1.0], &[0.5, 0.0, 1.0]);
}

#[test]
fn mass_coriolis_gravity_consistent_chain_and_planar() {
    let d = two_segments(9.81);
    check_consistency(
        &d,
        &[0.052, 0.5, 0.2, 0.061, -0.3, 0.9],
        &[0.1, 1.0, -2.0, -0.2, 0.5, 1.0],
        &[0.3, -1.0, 2.0, 1.0, 0.0, -1.0],
    );
    let spec = PccSpec {
        plane: Some(0.4),
        ..Default::default()
    };
    let d = arm(9.81, spec, false, 0.01);
    check_consistency(&d, &[0.115, 1.1], &[0.2, -1.5], &[1.0, 2.0]);
}

/// Paper 003's series A..H of eq. 8, literally, to 30 terms.
fn paper_series(th: f64) -> [f64; 6] {
    let f = |n: i64| -> f64 { (1..=n).map(|k| k as f64).product() };
    let pw = |e: i64| th.powi(e as i32);
    let sg = |n: i64| if n % 2 == 0 { 1.0 } else { -1.0 };
    let (mut a, mut b, mut c, mut d, mut e, mut h) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for n in 0..30i64 {
        b += sg(n) * pw(2 * n) / f(2 * n + 1);
        if n >= 1 {
            a += sg(n + 1) * pw(2 * n - 1) / f(2 * n);
            c += sg(n + 1) * pw(2 * n - 2) / ((2 * n) as f64 * f(2 * n - 2));
            d += sg(n) * pw(2 * n - 1) / ((2 * n + 1) as f64 * f(2 * n - 1));
            h += sg(n) * pw(2 * n - 2) / ((2 * n + 1) as f64 * f(2 * n - 2));
        }
        if n >= 2 {
            e += sg(n + 1) * pw(2 * n - 3) / ((2 * n) as f64 * f(2 * n - 3));
        }
    }
    [a, b, c, d, e, h]
}

/// Paper 003 eq. 12 (planar, point mass m at the tip, eq. 6), term by term against the
/// model with `mass_model = "tip"`. The paper's matrices hold after three corrections
/// derived in docs/pcc.md: nu_L = A E + B H (printed A E - B H), nu_theta = C E + D H
/// (printed C Q + D H), and gravity terms g B and g D in rows scaled like the inertia rows
/// (printed -g B / 2 and -g L D / 2).
#[test]
fn planar_tip_mass_matches_corrected_paper_eq12() {
    const TOL: f64 = 1e-12; // closed-form expressions of O(1), 30-term series
    let (m, g) = (0.05, 9.81);
    let spec = PccSpec {
        plane: Some(0.0),
        mass_model: MassModel::Tip,
        ..Default::default()
    };
    let mut d = arm(g, spec, false, 0.0);
    d.sections[0].mass = Some(m);
    d.tip = Default::default();
    let model = PccModel::new(&d).unwrap();
    for &(l, th, ld, thd) in &[
        (0.11, 0.8, 0.05, 1.3),
        (0.12, 0.05, -0.1, 2.0),
        (0.1, 2.0, 0.0, -1.0),
    ] {
        let [a, b, c, dd, e, h] = paper_series(th);
        let x = [l, th];
        let mm = model.mass_matrix(&x).unwrap();
        // Rows of eq. 12: L row as printed, theta row divided by L.
        assert!(close(mm[0][0] / m, a * a + b * b, 1.0, TOL));
        assert!(close(mm[0][1] / m, l * (a * c + b * dd), l, TOL));
        assert!(close(mm[1][0] / (m * l), a * c + b * dd, 1.0, TOL));
        assert!(close(mm[1][1] / (m * l), l * (c * c + dd * dd), l, TOL));
        let p = [0.0; 3];
        let t = model.force_terms(&x, &[ld, thd], &[0.0, 0.0], &p).unwrap();
        let cor_l = 2.0 * (a * c + b * dd) * ld * thd + l * (a * e + b * h) * thd * thd;
        let cor_t = 2.0 * (c * c + dd * dd) * ld * thd + l * (c * e + dd * h) * thd * thd;
        assert!(
            close(t[0][0] / m, cor_l, 1.0, TOL),
            "{} vs {cor_l}",
            t[0][0] / m
        );
        assert!(close(t[0][1] / (m * l), cor_t, 1.0, TOL));
        // The printed nu_L = A E - B H differs (unless B H = 0): a sign typo.
        assert!(
            (t[0][0] / m - (2.0 * (a * c + b * dd) * ld * thd + l * (a * e - b * h) * thd * thd))
                .abs()
                > 1e-3
        );
        // Gravity (U = m g L B, eq. 7): generalised force -dU/dq.
        assert!(close(-t[1][0] / m, g * b, g, TOL));
        assert!(close(-t[1][1] / (m * l), g * dd, g, TOL));
    }
}

/// Paper 003 eq. 11 / Table I: the follower-force pressure model, three chambers at
/// r_c, 0/120/240 deg, gives Q1 = B sum F, Q2 = sum (-r_c cos(phi - phi_k) + L N) F_k,
/// Q3 = sum r_c sin(phi - phi_k) sin(theta) F_k in (L, theta, phi); the chamber model gives
/// Q_L = sum F, Q_theta = -sum r_c cos(phi - phi_k) F_k, Q_phi = theta sum r_c sin(..) F_k.
#[test]
fn pressure_forces_match_paper_eq11_and_chamber_work() {
    const TOL: f64 = 1e-12;
    let rc = 7e-3;
    let area = std::f64::consts::PI * 2.5e-3f64.powi(2);
    let p = [3e4, 1e4, 5e4];
    for model_kind in [PressureModel::TipForce, PressureModel::Chamber] {
        let spec = PccSpec {
            pressure_force: model_kind,
            ..Default::default()
        };
        let model = PccModel::new(&arm(0.0, spec, false, 0.0)).unwrap();
        for &(l, th, ph) in &[(0.11, 0.9, 0.4), (0.12, 2.0, -1.0)] {
            let x = [l, th * f64::cos(ph), th * f64::sin(ph)];
            let q = model.force_terms(&x, &[0.0; 3], &[0.0; 3], &p).unwrap()[2].clone();
            // Map to (L, theta, phi): Q_theta = Q . dx/dtheta, Q_phi = Q . dx/dphi.
            let qt = q[1] * ph.cos() + q[2] * ph.sin();
            let qp = th * (-q[1] * ph.sin() + q[2] * ph.cos());
            let nn = (th - th.sin()) / (th * th);
            let (mut w1, mut w2, mut w3) = (0.0, 0.0, 0.0);
            for (k, ang) in [0.0f64, 120.0, 240.0].iter().enumerate() {
                let f = p[k] * area;
                let dphi = ph - ang.to_radians();
                match model_kind {
                    PressureModel::TipForce => {
                        w1 += th.sin() / th * f;
                        w2 += (-rc * dphi.cos() + l * nn) * f;
                        w3 += rc * dphi.sin() * th.sin() * f;
                    }
                    PressureModel::Chamber => {
                        w1 += f;
                        w2 += -rc * dphi.cos() * f;
                        w3 += rc * dphi.sin() * th * f;
                    }
                }
            }
            assert!(
                close(q[0], w1, 1.0, TOL),
                "{model_kind:?} Q1 {} vs {w1}",
                q[0]
            );
            assert!(close(qt, w2, 1.0, TOL), "{model_kind:?} Q2 {qt} vs {w2}");
            assert!(close(qp, w3, 1.0, TOL), "{model_kind:?} Q3 {qp} vs {w3}");
        }
    }
}

fn undamped(d: &mut DesignSpec) {
    let p = d.pcc.get_or_insert_with(Default::default);
    p.b_l = Some(0.0);
    p.b_theta = Some(0.0);
    p.b_phi = Some(0.0);
}

/// Largest |E(t) - E(0)| over a free motion without damping or input.
fn energy_drift(d: &DesignSpec, x0: &[f64], v0: &[f64], t_end: f64, dt: f64) -> (f64, f64) {
    let m = PccModel::new(d).unwrap();
    let n = (t_end / dt).round() as usize;
    let pressures = vec![0.0; (n + 1) * m.n_channels];
    let init = InitialState::Given {
        x: x0.to_vec(),
        v: v0.to_vec(),
    };
    let tr = m
        .simulate(dt, &pressures, &init, 1, &StepOptions::default())
        .unwrap();
    let e0 = tr.energy[0];
    let drift = tr.energy.iter().fold(0.0f64, |s, e| s.max((e - e0).abs()));
    // Energy scale: the largest kinetic energy reached (= exchange between forms).
    let range = tr.energy.len();
    let ke = (0..range)
        .map(|k| {
            m.energy(&tr.x[k], &tr.v[k], &[0.0; 3][..m.n_channels])
                .unwrap()
                .kinetic
        })
        .fold(0.0f64, f64::max);
    (drift, ke)
}

#[test]
fn energy_conserved_to_integrator_accuracy() {
    // Spatial arm with distributed mass, rigid cap, tip body and gravity, started with a
    // bend and a swirl; no damping, no input.
    let mut d = arm(9.81, PccSpec::default(), true, 0.02);
    undamped(&mut d);
    let x0 = [0.115, 0.6, -0.3];
    let v0 = [0.05, -3.0, 4.0];
    let (e1, ke) = energy_drift(&d, &x0, &v0, 0.2, 2e-3);
    let (e2, _) = energy_drift(&d, &x0, &v0, 0.2, 1e-3);
    // Second-order rule: halving dt divides the energy error by ~4 (>= 3 allows for the
    // pre-asymptotic range), and at dt = 1 ms it is under 0.1 % of the largest kinetic energy.
    eprintln!("spatial: drift {e1:.3e} -> {e2:.3e} J, kinetic {ke:.3e} J");
    assert!(e1 / e2 > 3.0, "order: drift {e1:.3e} -> {e2:.3e}");
    assert!(e2 < 1e-3 * ke, "drift {e2:.3e} J vs kinetic {ke:.3e} J");
    // A two-segment chain too.
    let mut d = two_segments(9.81);
    undamped(&mut d);
    let x0 = [0.05, 0.3, 0.1, 0.06, -0.2, 0.4];
    let v0 = [0.0, 2.0, 0.0, 0.0, 0.0, -2.0];
    let (e1, ke) = energy_drift(&d, &x0, &v0, 0.1, 2e-3);
    let (e2, _) = energy_drift(&d, &x0, &v0, 0.1, 1e-3);
    eprintln!("chain: drift {e1:.3e} -> {e2:.3e} J, kinetic {ke:.3e} J");
    assert!(e1 / e2 > 3.0, "chain order: drift {e1:.3e} -> {e2:.3e}");
    assert!(
        e2 < 1e-3 * ke,
        "chain drift {e2:.3e} J vs kinetic {ke:.3e} J"
    );
}

/// Equal pressure on the three chambers without gravity: pure elongation obeying
/// m_eff d_tt + b_L d_t + k_L d = F, F = 3 p A, m_eff = m_rod/3 + m_tip (the rod's material
/// point at fraction sigma moves with sigma L_t, so T = 1/2 (m_rod/3) L_t^2).
#[test]
fn linear_elongation_is_second_order_system() {
    let (k, b, m_rod, m_tip) = (246.0, 2.0, 0.06, 0.02);
    let spec = PccSpec {
        k_l: Some(k),
        b_l: Some(b),
        k_theta: Some(0.06),
        b_theta: Some(0.02),
        ..Default::default()
    };
    let mut d = arm(0.0, spec, false, m_tip);
    d.tip.com_offset = [0.0; 3];
    d.sections[0].mass = Some(m_rod);
    let model = PccModel::new(&d).unwrap();
    let area = std::f64::consts::PI * 2.5e-3f64.powi(2);
    let p = 5e4;
    let f = 3.0 * p * area;
    let me = m_rod / 3.0 + m_tip;
    let wn = (k / me).sqrt();
    let zeta = b / (2.0 * (k * me).sqrt());
    assert!(zeta < 1.0); // under-damped: frequency and decay both tested
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let exact = |t: f64| {
        f / k * (1.0 - (-zeta * wn * t).exp() * ((wd * t).cos() + zeta * wn / wd * (wd * t).sin()))
    };
    let dt = 2e-4;
    let n = 2000;
    // Step at t = 0+: the first step sees the midpoint pressure p/2, so start with p on.
    let pressures = vec![p; (n + 1) * 3];
    let tr = model
        .simulate(
            dt,
            &pressures,
            &InitialState::Rest,
            1,
            &StepOptions::default(),
        )
        .unwrap();
    let amp = f / k;
    let mut err = 0.0f64;
    for (t, x) in tr.time.iter().zip(&tr.x) {
        err = err.max((x[0] - 0.11 - exact(*t)).abs());
        assert!(x[1].abs() < 1e-12 && x[2].abs() < 1e-12, "no bending");
    }
    // Implicit midpoint phase error ~ (wn dt)^2 / 12 per radian: wn dt = 0.014 here, over
    // ~6 periods (40 rad) that is ~7e-4 rad, i.e. < 1e-3 of the amplitude.
    assert!(
        err < 1e-3 * amp,
        "max error {err:.3e} m vs amplitude {amp:.3e} m"
    );
}

#[test]
fn statics_balance_and_bad_input() {
    let d = arm(9.81, PccSpec::default(), true, 0.02);
    let m = PccModel::new(&d).unwrap();
    let p = [6e4, 0.0, 0.0];
    let s = m.solve_statics(&p, None, &StepOptions::default()).unwrap();
    let t = m.force_terms(&s.x, &[0.0; 3], &[0.0; 3], &p).unwrap();
    for i in 0..3 {
        let r = t[1][i] + t[2][i] + t[3][i];
        assert!(r.abs() < 1e-9, "residual {r}");
    }
    // The arm bends away from the pressurised chamber at angle 0: theta_x < 0.
    assert!(s.x[1] < -0.1 && s.x[2].abs() < 1e-9, "{:?}", s.x);
    assert!(m
        .solve_statics(&[1.0, f64::NAN, 0.0], None, &StepOptions::default())
        .is_err());
    assert!(m
        .solve_statics(&[1.0], None, &StepOptions::default())
        .is_err());
    let bad = PccSpec {
        k_l: Some(-1.0),
        ..Default::default()
    };
    let err = PccModel::new(&arm(0.0, bad, false, 0.0)).unwrap_err();
    assert!(err.to_string().contains("pcc.k_L"), "{err}");
    let pr = vec![0.0; 3 * 3];
    assert!(m
        .simulate(0.0, &pr, &InitialState::Rest, 1, &StepOptions::default())
        .is_err());
    assert!(m
        .simulate(
            1e-3,
            &pr[..7],
            &InitialState::Rest,
            1,
            &StepOptions::default()
        )
        .is_err());
}
