//! Shared builders for the core's integration tests.
#![allow(dead_code)]

use nalgebra::{Rotation3, Unit, Vector3};
use softrod_core::inverse::InverseTarget;
use softrod_core::ode::Loads;
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::spec::obstacle::{ObstacleKind, ObstacleSpec};
use softrod_core::spec::{
    AxialSpec, ChamberSpec, DesignSpec, Frame, LawSpec, LineLoadSpec, MaterialSpec, MountingSpec,
    ReferenceSpec, ReferenceTable, SectionSpec, StiffnessSpec, SwellingSpec, TendonSpec, TipSpec,
};
use softrod_core::statics::{residual, residual_and_jacobian, solve, SolverOptions};
use softrod_core::Rod;

pub const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
/// Horizontal mounting: d3 = +x_world, d1 = +z_world, d2 = d3 x d1 = -y_world.
pub const HORIZONTAL: [[f64; 3]; 3] = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]];

/// A linear-law section with unit correction factors, no chambers and nothing set; the
/// builders below fill in what distinguishes them.
fn base_section(name: &str, length: f64, steps: usize) -> SectionSpec {
    SectionSpec {
        name: name.into(),
        length,
        rigid: false,
        outer_radius: None,
        bore_radius: 0.0,
        material: None,
        mass: None,
        c_s: 1.0,
        c_e: 1.0,
        c_b: 1.0,
        c_t: 1.0,
        stiffness: StiffnessSpec::default(),
        chambers: vec![],
        steps,
        law: LawSpec::default(),
        partition: None,
        rotary_inertia: None,
        damping_se: None,
        damping_bt: None,
        reference: Default::default(),
        outer_radius_end: None,
        tendons: vec![],
    }
}

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
        mass: Some(mass),
        stiffness: StiffnessSpec {
            ea: Some(ea),
            ga: Some(ga),
            ei1: Some(ei),
            ei2: Some(ei),
            gj: Some(gj),
        },
        ..base_section(name, length, steps)
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
        dynamics: Default::default(),
        pcc: None,
        operating_range: None,
        obstacles: vec![],
    }
}

pub fn loads(p: &[f64]) -> Loads {
    Loads {
        pressures: p.to_vec(),
        tensions: vec![],
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
        tip_frame: Default::default(),
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
        distance_end: None,
        radius_end: None,
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
        outer_radius: Some(outer_radius),
        bore_radius,
        material: Some(material),
        chambers,
        ..base_section(name, length, steps)
    }
}

/// A rigid section that only carries its mass.
pub fn rigid_section(name: &str, length: f64, mass: f64) -> SectionSpec {
    SectionSpec {
        rigid: true,
        mass: Some(mass),
        ..base_section(name, length, 1)
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

/// Paper 002's body section alone: Ecoflex with three chambers at 90, 210 and 330 deg.
pub fn p002_body(steps: usize) -> SectionSpec {
    geometry_section(
        "body",
        P002_BODY,
        P002_RO,
        P002_RI,
        ECOFLEX,
        p002_chambers([90.0, 210.0, 330.0]),
        steps,
    )
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
            p002_body(steps),
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

/// A base rotation with no axis along the world axes, so no entry is structurally zero.
pub fn tilted() -> [[f64; 3]; 3] {
    let r = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)), 1.1);
    std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]))
}

// Exact (dual-number) Jacobians of the shooting residual against central finite differences
// of the plain residual (tests/suite/jacobian.rs: the linear law; tests/suite/laws.rs: every law).

/// Finite-difference step, relative to max(1, |x_j|) (the unknowns are scaled to be of
/// order 1). Central differences err by h^2 |r'''| / 6 (truncation, ~1e-12 here) plus
/// eps |r| / h (round-off, ~2e-16 * 10 / 1e-6 = 2e-9 for residuals up to 10): h = 1e-6
/// is close to the optimum eps^(1/3) and keeps both far below FD_TOL.
pub const FD_STEP: f64 = 1e-6;
/// Column-wise agreement, relative to the larger of the column's norm and 1e-3 (a column
/// of an O(1)-scaled Jacobian can be near zero only by accident). Measured: at most
/// 1.2e-9 over all points and designs of tests/suite/jacobian.rs (printed with --nocapture;
/// tests/suite/laws.rs prints its own), so 1e-7 leaves an 80x margin for round-off while still
/// catching a missing derivative term: e.g. the tip body's lever R(L) c, whose derivative
/// is ~1e-2 of a column for paper 002's marker, or a law's (the carried stretch's initial
/// value, d(EA)/dF of the table, the v3 in stretch-dependent bending).
pub const FD_TOL: f64 = 1e-7;
/// The dual-number residual and the f64 residual run the same arithmetic on the value
/// parts; allow a few ulps of the residual's size.
pub const SAME_RESIDUAL_TOL: f64 = 1e-13;
/// With tendons under tension the law is implicit (src/tendon.rs): both passes solve it by
/// Newton's method to its tolerance (1e-13 on the strains) along different iterations (the
/// f64 pass reuses a factorised matrix from stage to stage, the dual pass ends with one
/// exact step at the solution), so each stage's strains agree to that tolerance, not to
/// the ulp. Summed over the stages (4 per step, a few hundred in these designs) that is
/// ~1e-11 of the residual; 1e-10 is still 1000x below FD_TOL.
pub const SAME_RESIDUAL_TOL_IMPLICIT: f64 = 1e-10;
/// Points: the solution plus a perturbation of this size in each scaled unknown, and
/// points with each unknown drawn uniformly from [-RANDOM_BOX, RANDOM_BOX] (forces up to
/// F_s = EI/L^2, moments up to F_s L: the rod bends by up to a radian, far from
/// equilibrium).
pub const PERTURBATION: f64 = 0.3;
pub const RANDOM_BOX: f64 = 1.0;

/// Check `residual_and_jacobian` against central differences of `residual` at 8 points that
/// are not the solution (solved with `opts`): 4 near it (perturbed by up to PERTURBATION),
/// 4 drawn from the RANDOM_BOX, from `Lcg(seed)`. The two residuals must agree to
/// SAME_RESIDUAL_TOL and every Jacobian column to FD_TOL; prints the worst column error.
pub fn check_jacobian_against_fd(
    name: &str,
    rod: &Rod,
    ld: &Loads,
    opts: &SolverOptions,
    seed: u64,
) {
    let sol = solve(rod, ld, None, opts).unwrap();
    let n = sol.x.len();
    let implicit = rod.n_tendons > 0 && ld.tensions.iter().any(|t| *t > 0.0);
    let same_tol = if implicit {
        SAME_RESIDUAL_TOL_IMPLICIT
    } else {
        SAME_RESIDUAL_TOL
    };
    let mut rng = Lcg(seed);
    let mut worst: f64 = 0.0;
    let vnorm = |a: &[f64]| a.iter().map(|v| v * v).sum::<f64>().sqrt();
    for k in 0..8 {
        let x: Vec<f64> = (0..n)
            .map(|i| {
                if k < 4 {
                    sol.x[i] + PERTURBATION * rng.uniform()
                } else {
                    RANDOM_BOX * rng.uniform()
                }
            })
            .collect();
        let (r, jac) = residual_and_jacobian(rod, ld, &x).unwrap();
        let r_plain = residual(rod, ld, &x).unwrap();
        let rnorm = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(rnorm > 1e-3, "{name}: x = {x:?} should not be a solution");
        for (i, (a, b)) in r.iter().zip(&r_plain).enumerate() {
            assert!(
                (a - b).abs() <= same_tol * rnorm.max(1.0),
                "{name}: residual[{i}] {a} vs {b}"
            );
        }
        for j in 0..n {
            let h = FD_STEP * x[j].abs().max(1.0);
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[j] += h;
            xm[j] -= h;
            let (rp, rm) = (
                residual(rod, ld, &xp).unwrap(),
                residual(rod, ld, &xm).unwrap(),
            );
            let fd: Vec<f64> = (0..n).map(|i| (rp[i] - rm[i]) / (xp[j] - xm[j])).collect();
            let col: Vec<f64> = (0..n).map(|i| jac[i][j]).collect();
            let scale = vnorm(&col).max(1e-3);
            let diff: Vec<f64> = col.iter().zip(&fd).map(|(a, b)| a - b).collect();
            let err = vnorm(&diff) / scale;
            worst = worst.max(err);
            assert!(
                err < FD_TOL,
                "{name}: x = {x:?}, column {j}: AD {col:?} vs FD {fd:?} (rel. error {err:.2e})"
            );
        }
    }
    eprintln!("{name}: worst relative column error {worst:.2e}");
}

/// The full collocation residual of a simulator's next step (every node and stage unknown)
/// at a point off the solution against central differences: each entry of the exact
/// Jacobian within 1e-6 of its row's scale (truncation ~h^2, round-off ~1e-16 / h relative to
/// that scale at h = 1e-6 of each unknown).
pub fn check_step_jacobian(name: &str, sim: &softrod_core::dynamics::Simulator) {
    check_step_jacobian_with(name, sim, 1e-6);
}

/// [`check_step_jacobian`] with central differences of relative step `rel` (truncation
/// ~rel^2, round-off ~1e-16 / rel: the 1e-6 bound holds for rel in [1e-7, 1e-4]).
pub fn check_step_jacobian_with(name: &str, sim: &softrod_core::dynamics::Simulator, rel: f64) {
    let z: Vec<f64> = sim
        .unknowns()
        .iter()
        .enumerate()
        .map(|(k, v)| v * 1.01 + 1e-3 * ((k % 7) as f64 - 3.0) * v.abs().max(1e-3))
        .collect();
    check_jacobian_at(name, &z, |x| sim.step_residual_and_jacobian(x), rel);
}

/// The dense Jacobian `eval(z).1` against central differences of `eval(z).0` at `z`, entry
/// by entry relative to the row's largest |J_ik z_k| (steps of relative size `rel`, as
/// [`check_step_jacobian_with`]).
pub fn check_jacobian_at(
    name: &str,
    z: &[f64],
    eval: impl Fn(&[f64]) -> (Vec<f64>, Vec<Vec<f64>>),
    rel: f64,
) {
    let (_, jac) = eval(z);
    let n = z.len();
    let mut worst: f64 = 0.0;
    for j in 0..n {
        let h = rel * z[j].abs().max(1e-3);
        let (mut zp, mut zm) = (z.to_vec(), z.to_vec());
        zp[j] += h;
        zm[j] -= h;
        let (rp, _) = eval(&zp);
        let (rm, _) = eval(&zm);
        for i in 0..n {
            let fd = (rp[i] - rm[i]) / (zp[j] - zm[j]);
            let scale = (0..n)
                .map(|k| (jac[i][k] * z[k].abs().max(1e-3)).abs())
                .fold(0.0, f64::max);
            let err = (fd - jac[i][j]).abs() * z[j].abs().max(1e-3) / scale.max(1e-300);
            worst = worst.max(err);
            assert!(
                err <= 1e-6,
                "{name}: J[{i}][{j}] = {} vs FD {fd}",
                jac[i][j]
            );
        }
    }
    eprintln!("{name}: worst relative Jacobian error {worst:.2e} over {n} unknowns");
}

/// An inverse-statics target: the tip at `position`, every component weighted 1, no
/// orientation.
pub fn tip_target(rod: &Rod, position: [f64; 3]) -> InverseTarget {
    InverseTarget {
        s: rod.length,
        position,
        orientation: None,
        position_weight: [1.0; 3],
        orientation_weight: 0.0,
    }
}

/// A frictionless obstacle of `kind` with its penalty, every geometric key unset (the
/// caller fills in the ones its kind needs).
pub fn obstacle(kind: ObstacleKind, stiffness: f64, tolerance: f64) -> ObstacleSpec {
    ObstacleSpec {
        kind,
        point: None,
        normal: None,
        center: None,
        axis: None,
        start: None,
        end: None,
        radius: None,
        vertices: None,
        faces: None,
        stiffness,
        tolerance,
        smoothing: None,
        friction: 0.0,
        slip_velocity: None,
    }
}

/// designs/prebent_finger_on_table.toml built here: an 80 mm Dragon Skin 20 finger
/// (E = 337.8 kPa, Poisson 0.5) moulded on a 100 mm arc towards d1, a chamber and a
/// tendon on the inside of the bend, hanging above a plane 82 mm below its base with
/// friction `mu`. Pressure opens the finger and presses its tip onto the table.
pub fn finger(mu: f64) -> DesignSpec {
    let ds20 = MaterialSpec {
        youngs_modulus: 337.8e3,
        shear_modulus: 337.8e3 / 3.0,
        density: 1080.0,
    };
    let mut sec = geometry_section(
        "finger",
        0.08,
        8e-3,
        0.0,
        ds20,
        vec![chamber(2e-3, 3.5e-3, 0.0, 0)],
        40,
    );
    sec.reference = ReferenceSpec {
        curvature: [0.0, 1.0 / 0.1, 0.0],
        ..Default::default()
    };
    sec.tendons = vec![tendon(0, 6.5e-3, 0.0)];
    let mut d = design(vec![sec], HANGING, 9.81);
    let mut table = obstacle(ObstacleKind::Plane, 1e7, 2e-4);
    table.point = Some([0.0, 0.0, -0.082]);
    table.normal = Some([0.0, 0.0, 1.0]);
    table.friction = mu;
    d.obstacles = vec![table];
    d
}

/// Hanging mounting: d3 = -z_world (gravity along the arm).
pub const HANGING: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];

/// A straight tendon of `channel` at `distance` (m) from the axis, at `angle_deg`.
pub fn tendon(channel: usize, distance: f64, angle_deg: f64) -> TendonSpec {
    TendonSpec {
        channel,
        distance,
        angle: angle_deg.to_radians(),
        distance_end: None,
        angle_end: None,
    }
}

/// Paper 002's actuator `spec` with two tendons: tendon 0 in the base cap and the body
/// (helical there when `helical`: angle turning by 300 degrees, distance shrinking), tendon
/// 1 through all three sections; `stretch_bending` sets the body's law to paper 004's (the
/// tendon law's general, non-quadratic branch).
pub fn two_tendons(mut spec: DesignSpec, helical: bool, stretch_bending: bool) -> DesignSpec {
    let mut spiral = tendon(0, 0.017, 30.0);
    if helical {
        spiral.angle_end = Some(330f64.to_radians());
        spiral.distance_end = Some(0.014);
    }
    spec.sections[0].tendons = vec![tendon(0, 0.017, 30.0), tendon(1, 0.016, 150.0)];
    spec.sections[1].tendons = vec![spiral, tendon(1, 0.016, 150.0)];
    spec.sections[2].tendons = vec![tendon(1, 0.016, 150.0)];
    spec.sections[1].law.stretch_bending = stretch_bending;
    spec
}

/// The hanging actuator with `two_tendons` (as tests/suite/tendons.rs' arm), c_b 1.31 on the body,
/// damping time `tau`.
pub fn tendon_arm(helical: bool, stretch_bending: bool, steps: usize, tau: f64) -> DesignSpec {
    let mut spec = two_tendons(
        p002_actuator(HANGING, 9.81, steps),
        helical,
        stretch_bending,
    );
    spec.sections[1].c_b = 1.31;
    spec.dynamics.damping_time = tau;
    spec
}

/// Paper 002's hanging actuator with its body tapered: outer radius 20 % smaller at the
/// body's end, chambers closer to the axis and narrower there.
pub fn tapered(steps: usize, tau: f64) -> DesignSpec {
    let mut d = p002_actuator(HANGING, 9.81, steps);
    let body = &mut d.sections[1];
    body.outer_radius_end = Some(0.8 * P002_RO);
    for ch in &mut body.chambers {
        ch.distance_end = Some(0.85 * ch.distance);
        ch.radius_end = Some(0.8 * ch.radius.unwrap_or(P002_RP));
    }
    d.sections[2].outer_radius = Some(0.8 * P002_RO);
    d.dynamics.damping_time = tau;
    d
}

/// Paper 000's arm body: `length`, `mass` (kg), three extending PAMs at 0, 120 and 240 deg
/// (effective area 113.88 mm^2 at 17.5 mm), the stiffnesses of designs/pam_arm_220mm.toml.
pub fn pam_arm_section(length: f64, mass: f64, steps: usize) -> SectionSpec {
    let mut sec = direct_section("arm", length, 262.8, 87.6, 0.04466, 0.02977, mass, steps);
    sec.chambers = [0.0, 120.0, 240.0]
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let mut c = chamber(6.02e-3, 0.0175, *a, k);
            c.area = 113.88e-6;
            c
        })
        .collect();
    sec
}

/// Paper 000's 1 m arm made heavier (2 kg: single shooting's growth exponent
/// int sqrt(|n| / EI) ds is ~14, beyond 12, so statics solves it by collocation), 40 steps,
/// its chambers moving inwards along it (a taper of the chamber distances to 12.5 mm) and a
/// tabulated precurvature growing to 1 1/m: a section whose models vary per stage point.
pub fn long_tapered_tabulated_arm() -> SectionSpec {
    let mut sec = pam_arm_section(1.0, 2.0, 40);
    for c in &mut sec.chambers {
        c.distance_end = Some(0.0125);
    }
    sec.reference = ReferenceSpec {
        table: Some(ReferenceTable {
            s: vec![0.0, 0.5, 1.0],
            curvature: vec![[0.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0]],
            strain: vec![[0.0, 0.0, 1.0]; 3],
        }),
        ..Default::default()
    };
    sec
}

/// Paper 000's arm (tests/suite/dynamics_scope.rs, tests/suite/dynamics_sensitivity.rs) moulded curved: the reference curvature and
/// stretch given by a table along s, a helix (constant values, `helix`) or an arc whose
/// curvature grows along the arm.
pub fn tabulated_arm(helix: bool) -> DesignSpec {
    let mut sec = pam_arm_section(0.22, 0.165, 16);
    let s = vec![0.0, 0.07, 0.15, 0.22];
    let curvature = if helix {
        vec![[0.0, 3.0, 0.5]; 4]
    } else {
        vec![
            [0.0, 1.0, 0.0],
            [0.0, 2.0, 0.2],
            [0.5, 3.5, 0.3],
            [0.0, 4.0, 0.0],
        ]
    };
    let strain = if helix {
        vec![[0.0, 0.0, 1.02]; 4]
    } else {
        vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.01, 1.02],
            [0.0, 0.0, 1.03],
            [0.0, 0.0, 1.0],
        ]
    };
    sec.reference = ReferenceSpec {
        table: Some(ReferenceTable {
            s,
            curvature,
            strain,
        }),
        ..Default::default()
    };
    let mut spec = design(vec![sec], HANGING, 9.81);
    spec.dynamics.damping_time = 0.19;
    spec
}

/// A soft cantilever along the horizontal under gravity (paper 002's actuator, damped).
pub fn horizontal_actuator(steps: usize, tau: f64) -> DesignSpec {
    let mut spec = p002_actuator(HORIZONTAL, 9.81, steps);
    spec.sections[1].c_b = 1.31;
    spec.dynamics.damping_time = tau;
    spec
}

/// The damped horizontal actuator (`steps` per section) with follower (body-frame) tip
/// loads, and with a follower line load on its body.
pub fn follower_cases(steps: usize) -> Vec<(&'static str, DesignSpec)> {
    let mut tip = horizontal_actuator(steps, 0.05);
    tip.tip.frame = Frame::Body;
    tip.tip.force = [0.05, -0.03, -0.02];
    tip.tip.moment = [0.0, 2e-3, 1e-3];
    let mut line = horizontal_actuator(steps, 0.05);
    line.loads = vec![LineLoadSpec {
        section: 1,
        force_per_length: [0.4, 0.0, -0.2],
        moment_per_length: [0.0, 0.0, 0.01],
        frame: Frame::Body,
    }];
    vec![
        ("follower tip force and moment", tip),
        ("follower line load", line),
    ]
}

/// Paper 002's hanging actuator with the body's law `law` (c_b = 1.31, tau = 0.05 s).
pub fn actuator(law: LawSpec, steps: usize) -> DesignSpec {
    let mut d = p002_actuator(HANGING, 9.81, steps);
    d.sections[1].law = law;
    d.sections[1].c_b = 1.31;
    d.dynamics.damping_time = 0.05;
    d
}

/// Paper 002's model M3 on the body: Ogden (alpha = 8.89) with swelling and a chamber
/// offset.
pub fn ogden_m3_law() -> LawSpec {
    LawSpec {
        axial: AxialSpec::Ogden { alpha: 8.89 },
        chamber_offset: [0.89e-3, 0.98e-3],
        swelling: Some(SwellingSpec {
            c_p: 0.48,
            p_ref: 0.8e5,
        }),
        ..Default::default()
    }
}

/// An EA(F) table softening under tension (N against N).
pub fn ea_table_law() -> LawSpec {
    LawSpec {
        axial: AxialSpec::Table {
            force: vec![-5.0, 0.0, 5.0, 20.0],
            stiffness: vec![110.0, 100.0, 80.0, 65.0],
        },
        ..Default::default()
    }
}

/// The tip conditions of [`timoshenko_first_frequency`]: indices into (w, psi, M, V) that
/// vanish at s = L. Free: M = V = 0.
pub const TIMOSHENKO_FREE: [usize; 2] = [2, 3];
/// Pinned: w = M = 0.
pub const TIMOSHENKO_PINNED: [usize; 2] = [0, 2];
/// Clamped: w = psi = 0.
pub const TIMOSHENKO_CLAMPED: [usize; 2] = [0, 1];

/// First natural frequency (rad/s) of a uniform linear Timoshenko beam of length `l`
/// clamped at s = 0 (shear coefficient 1, the Cosserat rod's c_s = 1, with rotary inertia),
/// `k` = [EI, GA, rho A, rho I], with the tip conditions `tip`
/// ([`TIMOSHENKO_FREE`], ...): shooting its ODE in s with RK4 (4000 steps) from the two
/// base states (M, V) = (1, 0), (0, 1) and bisecting on the determinant of the tip
/// conditions, in a bracket about the Euler-Bernoulli frequency of `beta1_l`:
///   w' = psi + V/(GA),  psi' = M/EI,  M' = -V - rho I om^2 psi,  V' = -rho A om^2 w.
pub fn timoshenko_first_frequency(l: f64, k: [f64; 4], beta1_l: f64, tip: [usize; 2]) -> f64 {
    let [ei, _, ra, _] = k;
    let det = |om: f64| timoshenko_determinant(l, k, om, tip);
    let eb = beta1_l.powi(2) * (ei / (ra * l.powi(4))).sqrt();
    let (mut lo, mut hi) = (0.9 * eb, 1.01 * eb);
    assert!(det(lo) * det(hi) < 0.0, "bracket the first root");
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if det(lo) * det(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The determinant of the tip conditions `tip` of the Timoshenko beam of
/// [`timoshenko_first_frequency`] (`k` = [EI, GA, rho A, rho I]) at the frequency `om`
/// (rad/s): zero at a natural frequency. RK4 with 4000 steps from the two base states
/// (M, V) = (1, 0), (0, 1).
pub fn timoshenko_determinant(l: f64, k: [f64; 4], om: f64, tip: [usize; 2]) -> f64 {
    let [ei, ga, ra, ri] = k;
    let f = |z: [f64; 4]| -> [f64; 4] {
        [
            z[1] + z[3] / ga,
            z[2] / ei,
            -z[3] - ri * om * om * z[1],
            -ra * om * om * z[0],
        ]
    };
    let n = 4000;
    let h = l / n as f64;
    let run = |mut z: [f64; 4]| {
        for _ in 0..n {
            let k1 = f(z);
            let k2 = f(std::array::from_fn(|j| z[j] + 0.5 * h * k1[j]));
            let k3 = f(std::array::from_fn(|j| z[j] + 0.5 * h * k2[j]));
            let k4 = f(std::array::from_fn(|j| z[j] + h * k3[j]));
            for j in 0..4 {
                z[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        z
    };
    let za = run([0.0, 0.0, 1.0, 0.0]);
    let zb = run([0.0, 0.0, 0.0, 1.0]);
    za[tip[0]] * zb[tip[1]] - za[tip[1]] * zb[tip[0]]
}

/// Set a parameter's value in the design (or the loads, for sigma).
pub fn set_param(spec: &mut DesignSpec, ld: &mut Loads, p: &Param, v: f64) {
    if let ParamKind::StiffnessScale(k) = p.kind {
        ld.stiffness_scale[k] = v;
        return;
    }
    for &i in &p.sections {
        let s = &mut spec.sections[i];
        match p.kind {
            ParamKind::CorrectionFactor(0) => s.c_s = v,
            ParamKind::CorrectionFactor(1) => s.c_e = v,
            ParamKind::CorrectionFactor(2) => s.c_b = v,
            ParamKind::CorrectionFactor(_) => s.c_t = v,
            ParamKind::YoungsModulus => {
                let m = s.material.as_mut().unwrap();
                m.shear_modulus *= v / m.youngs_modulus; // Poisson's ratio held fixed
                m.youngs_modulus = v;
            }
            ParamKind::OgdenAlpha => s.law.axial = AxialSpec::Ogden { alpha: v },
            ParamKind::SwellingCp => s.law.swelling.as_mut().unwrap().c_p = v,
            ParamKind::ChamberOffset(a) => s.law.chamber_offset[a] = v,
            // relative to the design's areas: v is the factor on the current areas
            ParamKind::AreaScale => s.chambers.iter_mut().for_each(|c| c.area *= v),
            ParamKind::Density => s.material.as_mut().unwrap().density = v,
            ParamKind::Mass => s.mass = Some(v),
            // Neither belongs to the statics (sigma is handled above; validate_params
            // refuses the damping time).
            ParamKind::StiffnessScale(_) | ParamKind::DampingTime => unreachable!(),
        }
    }
}

pub fn param(name: &str, sections: &[usize]) -> Param {
    Param {
        kind: ParamKind::from_name(name).unwrap(),
        sections: sections.to_vec(),
    }
}

/// Undamped frequencies (rad/s), ascending: eigenvalues of M^-1 K.
pub fn frequencies(m: &nalgebra::DMatrix<f64>, k: &nalgebra::DMatrix<f64>) -> Vec<f64> {
    let a = m.clone().try_inverse().unwrap() * k;
    let mut w: Vec<f64> = a
        .complex_eigenvalues()
        .iter()
        .map(|l| l.re.max(0.0).sqrt())
        .collect();
    w.sort_by(|a, b| a.partial_cmp(b).unwrap());
    w
}

/// The tip rows of K^-1 B of a free tip's linearisation against the point Jacobian `jac` of
/// the same equilibrium, column by column (the first jac.d_position.len() inputs of B): both
/// come from the same dual passes, so they agree to the round-off of inverting the dense
/// flexibility (1e-8 of the column).
pub fn assert_tip_response(
    what: &str,
    sys: &softrod_core::linearise::LinearSystem,
    jac: &softrod_core::jacobian::PointJacobian,
) {
    let response = sys.stiffness.clone().try_inverse().unwrap() * &sys.input;
    let nq = sys.mass.nrows();
    for (k, (dp, dw)) in jac.d_position.iter().zip(&jac.d_rotation).enumerate() {
        let col = [*dp, *dw].concat();
        let scale = col.iter().map(|v| v * v).sum::<f64>().sqrt();
        let err = (0..6)
            .map(|r| (response[(nq - 6 + r, k)] - col[r]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            err <= 1e-8 * scale,
            "{what}, input {k}: {err:.2e} of {scale:.2e}"
        );
    }
}
