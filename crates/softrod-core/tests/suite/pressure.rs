//! Closed forms for chambered sections (docs/model.md; paper 002, eqs. 6-7, 21 and
//! Table III): with no gravity and no tip load the total internal force and moment vanish,
//! so the strains are the pressure shifts alone,
//!   u = K_bt^-1 sum_k p_k A_k (y_k, -x_k, 0),   v = (0, 0, 1 + sum_k p_k A_k / (c_e E A_m)),
//! and a section with constant u and v is a circular arc.

use crate::common;
use common::*;
use nalgebra::{Matrix3, Vector3};
use softrod_core::section::CrossSection;
use softrod_core::spec::{ChamberSpec, SectionSpec};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::Rod;
use std::f64::consts::PI;

/// Strains are compared relative to their own size: they are formed by a handful of
/// products and sums of quantities known to ~1e-16, and K_bt is well conditioned here
/// (eigenvalues within a factor 2), so 1e-10 is round-off with a wide margin.
const STRAIN_TOL: f64 = 1e-10;
/// Section properties computed two ways (section.rs and the hand formulas here) agree to
/// round-off: the terms differ by up to 1e4 in size (r_o^4 vs r_i^4), so 1e-12 relative.
const GEOMETRY_TOL: f64 = 1e-12;
/// RK4's error on a circular arc of curvature kappa, step h, length L: measured
/// |r - r_arc| = C (kappa h)^4 L at the tip (the worst node) with C = 0.0088 for kappa L
/// up to 0.7, 0.0099 at kappa L = 2 and 0.0114 at kappa L = 4, for 16, 32 and 64 steps
/// (the error drops by exactly 16 per doubling). The bound takes C = 0.02.
const RK4_ARC_COEFF: f64 = 0.02;
/// RK4's rotation error after arc length s (Frobenius norm): each step misses the
/// exponential's (kappa h)^5 / 5! term, i.e. |R - R_arc| = (sqrt 2 / 120) kappa s (kappa h)^4
/// = 0.0118 kappa s (kappa h)^4, measured 0.0118 for every case and step count here.
/// The bound takes 0.02.
const RK4_ROT_COEFF: f64 = 0.02;
/// Round-off floor for positions relative to L (and for rotation matrix entries).
const ROUNDOFF: f64 = 1e-14;

/// "No bending": residual lateral motion under symmetric pressure is round-off only
/// (the chamber angles 90/210/330 deg are not exact in binary).
const SYMMETRY_TOL: f64 = 1e-12;
/// Total force and moment where none is applied: exactly zero, since the solver starts
/// from (and accepts) the straight guess x = 0; allow round-off of the pressure terms.
const ZERO_WRENCH_TOL: f64 = 1e-14;
/// Default RK4 steps per section (SectionSpec's serde default).
const STEPS: usize = 16;

/// Position tolerance relative to L for an arc of curvature `kappa` integrated with step `h`.
fn arc_tol(kappa: f64, h: f64) -> f64 {
    RK4_ARC_COEFF * (kappa * h).powi(4) + ROUNDOFF
}

/// Rotation tolerance after arc length `s` of such an arc.
fn rot_tol(kappa: f64, h: f64, s: f64) -> f64 {
    RK4_ROT_COEFF * kappa * s * (kappa * h).powi(4) + ROUNDOFF
}

/// Hand formulas of paper 002, Table III (with its typos corrected, see section.rs):
/// returns (A_m, I_11 = int y^2, I_22 = int x^2, I_12 = sum_k x_k y_k A_k).
fn table_iii(ro: f64, ri: f64, chambers: &[ChamberSpec]) -> (f64, f64, f64, f64) {
    let mut a = PI * (ro * ro - ri * ri);
    let mut i11 = PI / 4.0 * (ro.powi(4) - ri.powi(4));
    let mut i22 = i11;
    let mut i12 = 0.0;
    for c in chambers {
        let rp = c.radius.unwrap();
        let ap = PI * rp * rp;
        let (x, y) = (c.distance * c.angle.cos(), c.distance * c.angle.sin());
        a -= ap;
        i11 -= PI / 4.0 * rp.powi(4) + y * y * ap;
        i22 -= PI / 4.0 * rp.powi(4) + x * x * ap;
        i12 += x * y * ap;
    }
    (a, i11, i22, i12)
}

/// K_bt (c_b = c_t = 1) from the hand formulas.
fn k_bt_hand(sec: &SectionSpec) -> Matrix3<f64> {
    let m = sec.material.unwrap();
    let (_, i11, i22, i12) = table_iii(sec.outer_radius.unwrap(), sec.bore_radius, &sec.chambers);
    let e = m.youngs_modulus;
    Matrix3::new(
        e * i11,
        e * i12,
        0.0,
        e * i12,
        e * i22,
        0.0,
        0.0,
        0.0,
        m.shear_modulus * (i11 + i22),
    )
}

/// Pressure moment sum_k p_k A_k (y_k, -x_k, 0) and force sum_k p_k A_k.
fn pressure_load(sec: &SectionSpec, p: &[f64]) -> (Vector3<f64>, f64) {
    let mut m = Vector3::zeros();
    let mut f = 0.0;
    for c in &sec.chambers {
        let pa = p[c.channel] * c.area;
        m += pa * Vector3::new(c.distance * c.angle.sin(), -c.distance * c.angle.cos(), 0.0);
        f += pa;
    }
    (m, f)
}

/// The strains a pressurised section must have: (u, v3).
fn expected_strains(sec: &SectionSpec, p: &[f64]) -> (Vector3<f64>, f64) {
    let (mp, f) = pressure_load(sec, p);
    let u = k_bt_hand(sec).try_inverse().unwrap() * mp;
    let m = sec.material.unwrap();
    let (am, ..) = table_iii(sec.outer_radius.unwrap(), sec.bore_radius, &sec.chambers);
    (u, 1.0 + f / (sec.c_e * m.youngs_modulus * am))
}

/// Pose after arc length s of constant body strains u (u3 = 0) and v = v3 e3 from `r0`, `rot0`:
/// R = R0 exp(s u^), r = r0 + R0 v3 (e3 sin(ks)/k + (a x e3)(1 - cos ks)/k), a = u/k.
fn arc(
    r0: Vector3<f64>,
    rot0: Matrix3<f64>,
    u: Vector3<f64>,
    v3: f64,
    s: f64,
) -> (Vector3<f64>, Matrix3<f64>) {
    let k = u.norm();
    let a = u / k;
    let e3 = Vector3::z();
    let local = v3 * (e3 * (k * s).sin() / k + a.cross(&e3) * (1.0 - (k * s).cos()) / k);
    let ahat = a.cross_matrix();
    let rot = Matrix3::identity() + ahat * (k * s).sin() + ahat * ahat * (1.0 - (k * s).cos());
    (r0 + rot0 * local, rot0 * rot)
}

fn mat(r: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| r[i][j])
}

fn vec3(a: &[f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

#[test]
fn paper_002_cross_section_matches_table_iii() {
    let sec = p002_body(STEPS);
    let cs = CrossSection::from_spec(&sec, P002_RO);
    // A_m = pi (r_o^2 - r_i^2 - 3 r_p^2)
    let am = PI * (P002_RO.powi(2) - P002_RI.powi(2) - 3.0 * P002_RP.powi(2));
    // Three chambers 120 deg apart: sum of rho_perp^2 over the chambers is 3/2 rho_p^2 about
    // either axis, so I_11 = I_22 = pi/4 (r_o^4 - r_i^4) - 3 pi/4 r_p^4 - 3/2 rho_p^2 A_p.
    let ap = PI * P002_RP.powi(2);
    let i = PI / 4.0 * (P002_RO.powi(4) - P002_RI.powi(4))
        - 3.0 * PI / 4.0 * P002_RP.powi(4)
        - 1.5 * P002_RHO.powi(2) * ap;
    assert!(
        (cs.area - am).abs() < GEOMETRY_TOL * am,
        "A_m {} vs {am}",
        cs.area
    );
    assert!(
        (cs.i11 - i).abs() < GEOMETRY_TOL * i,
        "I_11 {} vs {i}",
        cs.i11
    );
    assert!(
        (cs.i22 - i).abs() < GEOMETRY_TOL * i,
        "I_22 {} vs {i}",
        cs.i22
    );
    assert!(
        cs.i12.abs() < GEOMETRY_TOL * i,
        "I_12 {} should vanish",
        cs.i12
    );
    // The numbers themselves (mm^2, mm^4), as a regression anchor: pi * 357.2325 mm^2 and
    // 135 964.55 mm^4, to the digits given.
    assert!(
        (cs.area * 1e6 - 1122.2790).abs() < 1e-4,
        "A_m = {} mm^2",
        cs.area * 1e6
    );
    assert!(
        (cs.i11 * 1e12 - 135_964.55).abs() < 1e-2,
        "I = {} mm^4",
        cs.i11 * 1e12
    );
    // and the compiled stiffnesses: EA, GA, EI, GJ = G (I_11 + I_22)
    let rod = Rod::new(design(vec![sec], IDENTITY, 0.0)).unwrap();
    let s = &rod.sections[0];
    let (e, g) = (ECOFLEX.youngs_modulus, ECOFLEX.shear_modulus);
    let checks = [
        (s.k_se[2], e * am),
        (s.k_se[0], g * am),
        (s.k_se[1], g * am),
        (s.k_bt[0][0], e * i),
        (s.k_bt[1][1], e * i),
        (s.k_bt[2][2], g * 2.0 * i),
    ];
    for (k, (got, want)) in checks.iter().enumerate() {
        assert!(
            (got - want).abs() < GEOMETRY_TOL * want,
            "stiffness {k}: {got} vs {want}"
        );
    }
    assert!(s.k_bt[0][1].abs() < GEOMETRY_TOL * e * i && s.k_bt[1][0] == s.k_bt[0][1]);
    // weight from the density
    assert!((s.line_mass - ECOFLEX.density * am).abs() < GEOMETRY_TOL * s.line_mass);
}

/// Compare the shape's strains with the closed form and its positions with the arc.
fn check_single_section_arc(sec: &SectionSpec, p: &[f64]) {
    let rod = Rod::new(design(vec![sec.clone()], IDENTITY, 0.0)).unwrap();
    let ld = loads(p);
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let sh = shape(&rod, &ld, &sol);
    let (u, v3) = expected_strains(sec, p);
    assert_eq!(sh.s.len(), sec.steps + 1);
    for (i, s) in sh.s.iter().enumerate() {
        let du = (vec3(&sh.u[i]) - u).norm();
        assert!(
            du <= STRAIN_TOL * u.norm(),
            "p = {p:?}, s = {s}: u = {:?}, want {u}",
            sh.u[i]
        );
        let v = sh.v[i];
        assert!(v[0].abs() <= STRAIN_TOL * (v3 - 1.0) && v[1].abs() <= STRAIN_TOL * (v3 - 1.0));
        assert!(
            (v[2] - v3).abs() <= STRAIN_TOL * (v3 - 1.0),
            "s = {s}: v3 = {} want {v3}",
            v[2]
        );
    }
    let h = sec.length / sec.steps as f64;
    let tol = arc_tol(u.norm(), h);
    for (i, s) in sh.s.iter().enumerate() {
        let (r, rot) = arc(Vector3::zeros(), Matrix3::identity(), u, v3, *s);
        let e = (vec3(&sh.position[i]) - r).norm() / sec.length;
        assert!(
            e < tol,
            "p = {p:?}, s = {s}: position off the arc by {e:.2e} L, bound {tol:.2e}"
        );
        let e = (mat(&sh.rotation[i]) - rot).norm();
        let rtol = rot_tol(u.norm(), h, *s);
        assert!(
            e < rtol,
            "p = {p:?}, s = {s}: rotation off the arc by {e:.2e}, bound {rtol:.2e}"
        );
    }
}

#[test]
fn pressurised_chamber_gives_constant_curvature_and_stretch() {
    let sec = p002_body(STEPS);
    // one chamber (on +d2): the rod bends away from it, towards -d2 = -y_world
    let p = [60e3, 0.0, 0.0];
    check_single_section_arc(&sec, &p);
    let (u, _) = expected_strains(&sec, &p);
    assert!(
        u[0] > 0.0 && u[1].abs() < STRAIN_TOL * u[0] && u[2] == 0.0,
        "u = {u}"
    );
    let rod = Rod::new(design(vec![sec.clone()], IDENTITY, 0.0)).unwrap();
    let tip = solve(&rod, &loads(&p), None, &SolverOptions::default())
        .unwrap()
        .tip
        .r;
    assert!(
        tip[1] < -0.1 * sec.length && tip[0].abs() < SYMMETRY_TOL * sec.length,
        "tip {tip:?}"
    );
    // two chambers at different pressures: a bend in a general direction, still an arc;
    // and a strong bend (kappa L = 2 rad)
    check_single_section_arc(&sec, &[0.0, 45e3, 20e3]);
    let (u, _) = expected_strains(&sec, &[200e3, 0.0, 0.0]);
    assert!(u.norm() * sec.length > 2.0);
    check_single_section_arc(&sec, &[200e3, 0.0, 0.0]);
}

#[test]
fn equal_pressures_in_symmetric_chambers_only_extend() {
    let sec = p002_body(STEPS);
    let rod = Rod::new(design(vec![sec.clone()], IDENTITY, 0.0)).unwrap();
    let p = 50e3;
    let sol = solve(&rod, &loads(&[p; 3]), None, &SolverOptions::default()).unwrap();
    let (am, ..) = table_iii(P002_RO, P002_RI, &sec.chambers);
    let stretch = 1.0 + 3.0 * p * PI * P002_RP.powi(2) / (ECOFLEX.youngs_modulus * am);
    let r = sol.tip.r;
    assert!(
        r[0].abs() < SYMMETRY_TOL * sec.length && r[1].abs() < SYMMETRY_TOL * sec.length,
        "tip {r:?}"
    );
    assert!(
        (r[2] - stretch * sec.length).abs() < SYMMETRY_TOL * sec.length,
        "tip z {} vs {}",
        r[2],
        stretch * sec.length
    );
    assert!((mat(&sol.tip.rot) - Matrix3::identity()).norm() < SYMMETRY_TOL);
}

#[test]
fn offset_chambers_couple_the_bending_axes() {
    // Two chambers at 0 and 60 deg (centres 12 mm apart, 10.3 mm needed): I_11 != I_22
    // and a product of area sum_k x_k y_k A_k != 0.
    let chambers = vec![
        chamber(P002_RP, P002_RHO, 0.0, 0),
        chamber(P002_RP, P002_RHO, 60.0, 1),
    ];
    let sec = geometry_section(
        "body", P002_BODY, P002_RO, P002_RI, ECOFLEX, chambers, STEPS,
    );
    let rod = Rod::new(design(vec![sec.clone()], IDENTITY, 0.0)).unwrap();
    let k = rod.sections[0].k_bt;
    let e = ECOFLEX.youngs_modulus;
    let sum_xya: f64 = sec
        .chambers
        .iter()
        .map(|c| {
            let [x, y] = c.centroid();
            x * y * c.area
        })
        .sum();
    assert!(sum_xya > 0.0);
    assert!(
        (k[0][1] - e * sum_xya).abs() < GEOMETRY_TOL * e * sum_xya,
        "K_12 = {} vs {}",
        k[0][1],
        e * sum_xya
    );
    assert_eq!(k[1][0], k[0][1]);
    let hand = k_bt_hand(&sec);
    for i in 0..3 {
        for j in 0..3 {
            assert!(
                (k[i][j] - hand[(i, j)]).abs() < GEOMETRY_TOL * hand.norm(),
                "K_bt[{i}][{j}]"
            );
        }
    }
    for p in [[50e3, 0.0], [0.0, 50e3], [30e3, 50e3]] {
        check_single_section_arc(&sec, &p);
        // The coupling matters: dropping K_12 would turn the curvature by a visible amount.
        let (mp, _) = pressure_load(&sec, &p);
        let (u, _) = expected_strains(&sec, &p);
        let mut diag = hand;
        diag[(0, 1)] = 0.0;
        diag[(1, 0)] = 0.0;
        let u_uncoupled = diag.try_inverse().unwrap() * mp;
        assert!(
            (u - u_uncoupled).norm() > 0.01 * u.norm(),
            "p = {p:?}: coupling has no effect?"
        );
    }
}

#[test]
fn chamber_offset_bends_under_equal_pressures() {
    // Paper 002, eq. 21: all three chambers displaced by rho_off. Equal pressures p then
    // give the moment 3 p A_p (off_y, -off_x, 0) and the coupled K_bt turns its curvature.
    let off = [0.8e-3, -0.5e-3];
    let chambers: Vec<ChamberSpec> = [90.0f64, 210.0, 330.0]
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let a = a.to_radians();
            let (x, y) = (P002_RHO * a.cos() + off[0], P002_RHO * a.sin() + off[1]);
            let mut c = chamber(P002_RP, x.hypot(y), 0.0, k);
            c.angle = y.atan2(x);
            c
        })
        .collect();
    let sec = geometry_section(
        "body", P002_BODY, P002_RO, P002_RI, ECOFLEX, chambers, STEPS,
    );
    let p = 40e3;
    let (mp, _) = pressure_load(&sec, &[p; 3]);
    let ap = PI * P002_RP.powi(2);
    let want = Vector3::new(3.0 * p * ap * off[1], -3.0 * p * ap * off[0], 0.0);
    assert!(
        (mp - want).norm() < GEOMETRY_TOL * want.norm(),
        "M_p = {mp} vs {want}"
    );
    assert!(
        Rod::new(design(vec![sec.clone()], IDENTITY, 0.0))
            .unwrap()
            .sections[0]
            .k_bt[0][1]
            != 0.0
    );
    check_single_section_arc(&sec, &[p; 3]);
}

#[test]
fn caps_stay_straight_and_body_bends_in_three_section_actuator() {
    let spec = p002_actuator(IDENTITY, 0.0, STEPS);
    let rod = Rod::new(spec.clone()).unwrap();
    let p = [0.0, 55e3, 10e3];
    let ld = loads(&p);
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let sh = shape(&rod, &ld, &sol);
    let body = &spec.sections[1];
    let (u, v3) = expected_strains(body, &p);
    let (mp, _) = pressure_load(body, &p);
    let scale = mp.norm();
    for i in 0..sh.s.len() {
        let (sec, s) = (sh.section[i], sh.s[i]);
        // Total force and moment: the pressure is internal, so nothing is transmitted,
        // on either side of each junction.
        assert!(
            norm(&sh.force[i]) <= ZERO_WRENCH_TOL * scale / P002_RHO,
            "s = {s}: n = {:?}",
            sh.force[i]
        );
        assert!(
            norm(&sh.moment[i]) <= ZERO_WRENCH_TOL * scale,
            "s = {s}: m = {:?}",
            sh.moment[i]
        );
        if sec == 1 {
            assert!(
                (vec3(&sh.u[i]) - u).norm() <= STRAIN_TOL * u.norm(),
                "body s = {s}: u = {:?}",
                sh.u[i]
            );
            assert!((sh.v[i][2] - v3).abs() <= STRAIN_TOL * (v3 - 1.0));
            // the material moment K_bt u carries the pressure moment: M_p = K_bt u
            let km = k_bt_hand(body) * vec3(&sh.u[i]);
            assert!((km - mp).norm() <= STRAIN_TOL * scale);
        } else {
            // no chambers, no wrench: the caps stay straight and unstretched
            let du = norm(&sh.u[i]);
            let dv = dist(&sh.v[i], &[0.0, 0.0, 1.0]);
            assert!(
                du <= STRAIN_TOL * u.norm(),
                "cap s = {s} must stay straight: u = {:?}",
                sh.u[i]
            );
            assert!(
                dv <= STRAIN_TOL * (v3 - 1.0),
                "cap s = {s} must not stretch: v = {:?}",
                sh.v[i]
            );
        }
    }
    // Pose: straight cap, arc, straight cap along the body's end tangent.
    let r1 = Vector3::new(0.0, 0.0, P002_CAP_A);
    let (r2, rot2) = arc(r1, Matrix3::identity(), u, v3, P002_BODY);
    let tip = r2 + rot2.column(2) * P002_CAP_C;
    // The caps are exact (v = e3, u = 0 integrate exactly); the body's RK4 errors in
    // position and rotation carry through the distal cap (lever d^c on the rotation error).
    let h = P002_BODY / STEPS as f64;
    let rtol = rot_tol(u.norm(), h, P002_BODY);
    let tol = arc_tol(u.norm(), h) * P002_BODY + rtol * P002_CAP_C;
    assert!(
        (vec3(&sol.tip.r) - tip).norm() < tol,
        "tip {:?} vs {tip}",
        sol.tip.r
    );
    assert!((mat(&sol.tip.rot) - rot2).norm() < rtol);
    // the cap nodes themselves
    for i in 0..sh.s.len() {
        let want = match sh.section[i] {
            0 => Vector3::new(0.0, 0.0, sh.s[i]),
            2 => r2 + rot2.column(2) * (sh.s[i] - P002_CAP_A - P002_BODY),
            _ => continue,
        };
        assert!(
            (vec3(&sh.position[i]) - want).norm() < tol,
            "s = {}",
            sh.s[i]
        );
    }
}

/// With gravity across the axis, the total force at every node is the weight of everything
/// beyond it (n' = -f integrates exactly), continuous across the junctions, and the base
/// moment balances the weight's moment about the base.
#[test]
fn three_section_actuator_balances_its_weight() {
    let g = 9.81;
    // 64 steps per section so that the Simpson quadrature below is accurate (at 16 steps
    // its O(h^4) error is 1.3e-7 of the moment: the rod droops to kappa ~ 10/m)
    const BALANCE_STEPS: usize = 64;
    let spec = p002_actuator(HORIZONTAL, g, BALANCE_STEPS);
    let rod = Rod::new(spec.clone()).unwrap();
    let ld = loads(&[20e3, 0.0, 40e3]);
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let sh = shape(&rod, &ld, &sol);
    let weight = rod.mass() * g;
    // Newton stops at a scaled residual <= 1e-10 (relative to F_s = EI/L^2, about 0.6 N
    // here, the weight being 1.5 N): the tip force is zero to ~1e-10 N.
    const FORCE_TOL: f64 = 1e-9;
    let mass_beyond = |s: f64| -> f64 {
        rod.sections
            .iter()
            .map(|sec| sec.line_mass * ((sec.s_start + sec.length) - s.max(sec.s_start)).max(0.0))
            .sum()
    };
    for i in 0..sh.s.len() {
        let want = [0.0, 0.0, -g * mass_beyond(sh.s[i])];
        assert!(
            dist(&sh.force[i], &want) < FORCE_TOL * weight,
            "s = {}: n = {:?} want {want:?}",
            sh.s[i],
            sh.force[i]
        );
    }
    // Base moment = int (r - r0) x f ds (m' = -r' x n, n(L) = m(L) = 0, r0 = 0), by
    // composite Simpson over each section's nodes (64 steps, even). Measured: Simpson's
    // error is 1.3e-7 of the moment at 16 steps, so 5e-10 at 64.
    const MOMENT_QUADRATURE_TOL: f64 = 5e-9;
    let mut total = Vector3::zeros();
    let mut start = 0;
    for (k, sec) in rod.sections.iter().enumerate() {
        let idx: Vec<usize> = std::iter::once(start)
            .chain((0..sh.s.len()).filter(|&i| sh.section[i] == k && i > 0))
            .collect();
        let h = sec.length / sec.steps as f64;
        let f = Vector3::new(0.0, 0.0, -g * sec.line_mass);
        for (j, &i) in idx.iter().enumerate() {
            let w = if j == 0 || j == idx.len() - 1 {
                1.0
            } else if j % 2 == 1 {
                4.0
            } else {
                2.0
            };
            total += vec3(&sh.position[i]).cross(&f) * (w * h / 3.0);
        }
        start = *idx.last().unwrap();
    }
    let base = vec3(&sol.base_moment);
    assert!(base.norm() > 0.01 * weight * spec.length());
    assert!(
        (base - total).norm() < MOMENT_QUADRATURE_TOL * base.norm(),
        "base moment {base} vs int r x f {total}"
    );
}
