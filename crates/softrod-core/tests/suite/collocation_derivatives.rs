//! Exact derivatives of equilibria that statics solved by collocation (long, soft rods:
//! `crate::statics::collocation::derivatives`, the implicit function theorem on the
//! collocation equations) against central finite differences of full solves: the point
//! Jacobian with respect to pressures, tip loads and stiffness factors, at the tip and
//! between nodes; the parameter sensitivities of the tip pose and of markers; the batch
//! against single solves. The linearisation still refuses such solutions.

use crate::common;
use common::*;
use softrod_core::batch::{sensitivity_batch, BatchInputs};
use softrod_core::jacobian::{point_jacobian, Input, Probe};
use softrod_core::marker::Marker;
use softrod_core::ode::Loads;
use softrod_core::sensitivity::{
    locate_markers, marker_positions, pose_sensitivity, validate_params, Param, ParamKind,
};
use softrod_core::spec::{DesignSpec, MaterialSpec};
use softrod_core::statics::{solve, Solution, SolverOptions};
use softrod_core::validity::Policy;
use softrod_core::Rod;

/// Newton tolerance of the finite-difference solves (scaled unknowns): the solution error
/// divided by the step below stays near 1e-8 of a derivative.
const SOLVER_TOL: f64 = 1e-13;
/// Relative step of the central differences: truncation h^2 |y'''| / 6 ~ 1e-10 relative
/// for these smooth laws, solve error / h ~ 1e-8 relative.
const H: f64 = 1e-5;
/// Column-wise agreement relative to the column's norm: 100x above the differences' own
/// error (above; measured, printed: at most 2.2e-8); a missing term (a load's share of the tip balance, the quadrature of the
/// centreline, the partial step between nodes) is off by percent.
const COLUMN_TOL: f64 = 1e-6;
/// Arm length, m, and collocation intervals.
const L: f64 = 1.0;
const STEPS: usize = 32;

fn opts() -> SolverOptions {
    SolverOptions {
        tol: SOLVER_TOL,
        // Clamped horizontally, the arm bends at the clamp beyond the default fibre-stretch
        // range (collocation.rs, `long_soft_rods_are_solved_by_collocation`).
        on_invalid: Policy::Warn,
        ..Default::default()
    }
}

/// A 1 m soft arm (E = 100 kPa, r = 12.5 mm) with one chamber, clamped horizontally under
/// its own weight: single shooting's growth exponent is beyond the limit, so statics
/// solves it by collocation.
fn arm() -> DesignSpec {
    let mat = MaterialSpec {
        youngs_modulus: 100e3,
        shear_modulus: 100e3 / 3.0,
        density: 1000.0,
    };
    let sec = geometry_section(
        "arm",
        L,
        0.0125,
        0.0,
        mat,
        vec![chamber(2e-3, 5e-3, 30.0, 0)],
        STEPS,
    );
    design(vec![sec], HORIZONTAL, 9.81)
}

fn base_loads() -> Loads {
    Loads {
        tip_force: [0.02, -0.05, 0.01],
        tip_moment: [0.0, 1e-3, 0.0],
        ..loads(&[10e3])
    }
}

fn solved(rod: &Rod, ld: &Loads) -> Solution {
    let sol = solve(rod, ld, None, &opts()).unwrap();
    assert!(sol.collocation.is_some(), "routed to collocation");
    sol
}

/// Positions of the markers (world, m) of the arm solved under `ld`.
fn markers_at(spec: &DesignSpec, ld: &Loads, markers: &[Marker]) -> Vec<[f64; 3]> {
    let rod = Rod::new(spec.clone()).unwrap();
    let sol = solved(&rod, ld);
    marker_positions(&rod, ld, &sol, &locate_markers(&rod, markers).unwrap())
}

/// Relative error of an exact column against a finite-difference one (norms).
fn column_error(exact: &[f64], fd: &[f64]) -> f64 {
    let n = fd.iter().map(|x| x * x).sum::<f64>().sqrt();
    let e = exact
        .iter()
        .zip(fd)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    e / n
}

/// Three markers read the pose at `s`: the centreline point and two points offset along
/// the section's first two axes (d = 10 mm), whose differences are d R e_1 and d R e_2.
const D: f64 = 0.01;
fn pose_markers(s: f64) -> [Marker; 3] {
    [
        Marker {
            s,
            offset: [0.0; 3],
        },
        Marker {
            s,
            offset: [D, 0.0, 0.0],
        },
        Marker {
            s,
            offset: [0.0, D, 0.0],
        },
    ]
}

#[test]
fn collocation_point_jacobian_matches_finite_differences() {
    let spec = arm();
    let rod = Rod::new(spec.clone()).unwrap();
    let ld = base_loads();
    let sol = solved(&rod, &ld);
    let inputs = [
        Input::Pressure(0),
        Input::TipForce(0),
        Input::TipForce(1),
        Input::TipForce(2),
        Input::TipMoment(0),
        Input::TipMoment(1),
    ];
    let h = L / STEPS as f64;
    // At the tip, at a node, and between nodes (the partial step from the node).
    for s in [L, 0.5 * L, 0.5 * L + 0.3 * h] {
        let jac = point_jacobian(&rod, &ld, &sol, &inputs, &Probe::at(&rod, s).unwrap()).unwrap();
        let marks = pose_markers(s);
        let here = markers_at(&spec, &ld, &marks);
        // The value is the solution's own point there.
        assert!(dist(&jac.position, &here[0]) < 1e-14, "s = {s}: value");
        for (k, a) in inputs.iter().enumerate() {
            let (step, at): (f64, Box<dyn Fn(f64) -> Loads>) = match *a {
                Input::Pressure(c) => (
                    H * ld.pressures[c],
                    Box::new(move |d| {
                        let mut l = base_loads();
                        l.pressures[c] += d;
                        l
                    }),
                ),
                Input::TipForce(j) => (
                    1e-5,
                    Box::new(move |d| {
                        let mut l = base_loads();
                        l.tip_force[j] += d;
                        l
                    }),
                ),
                Input::TipMoment(j) => (
                    1e-7,
                    Box::new(move |d| {
                        let mut l = base_loads();
                        l.tip_moment[j] += d;
                        l
                    }),
                ),
                Input::StiffnessScale(_) | Input::Tension(_) => unreachable!(),
            };
            let (p, m) = (
                markers_at(&spec, &at(step), &marks),
                markers_at(&spec, &at(-step), &marks),
            );
            let fd = |i: usize, c: usize| (p[i][c] - m[i][c]) / (2.0 * step);
            let fd_r: Vec<f64> = (0..3).map(|c| fd(0, c)).collect();
            let e_r = column_error(&jac.d_position[k], &fd_r);
            // d(R e_a) = w x (R e_a): the small rotation's effect on the two axes.
            let axis =
                |i: usize| -> [f64; 3] { std::array::from_fn(|c| (here[i][c] - here[0][c]) / D) };
            let w = jac.d_rotation[k];
            let exact_axes: Vec<f64> = [axis(1), axis(2)]
                .iter()
                .flat_map(|e| {
                    [
                        w[1] * e[2] - w[2] * e[1],
                        w[2] * e[0] - w[0] * e[2],
                        w[0] * e[1] - w[1] * e[0],
                    ]
                })
                .collect();
            let fd_axes: Vec<f64> = [1, 2]
                .iter()
                .flat_map(|&i| (0..3).map(move |c| (fd(i, c) - fd(0, c)) / D))
                .collect();
            let e_w = column_error(&exact_axes, &fd_axes);
            println!("s = {s}: d/d {a:?}: position {e_r:.2e}, rotation {e_w:.2e}");
            assert!(e_r < COLUMN_TOL, "s = {s}, {a:?}: position {e_r:.2e}");
            assert!(e_w < COLUMN_TOL, "s = {s}, {a:?}: rotation {e_w:.2e}");
        }
    }
}

/// Every parameter's exact derivative of the tip pose and of three markers (at a node,
/// between nodes, at the tip; offset in the cross-section) against central differences.
fn check_sensitivities(name: &str, spec: DesignSpec, ld: Loads, names: &[&str]) {
    let rod = Rod::new(spec.clone()).unwrap();
    let sol = solved(&rod, &ld);
    let params: Vec<Param> = names.iter().map(|n| param(n, &[0])).collect();
    validate_params(&rod, &params).unwrap();
    let h = L / rod.sections[0].steps as f64;
    let marks: Vec<Marker> = [0.25 * L, 0.5 * L + 0.3 * h, L]
        .iter()
        .map(|&s| Marker {
            s,
            offset: [0.01, -0.005, 0.0],
        })
        .collect();
    let located = locate_markers(&rod, &marks).unwrap();
    let sens = pose_sensitivity(&rod, &ld, &sol, &params, &located).unwrap();
    for (j, p) in params.iter().enumerate() {
        let v0 = p.value(&rod, &ld);
        let step = H * v0.abs();
        let at = |v: f64| {
            let (mut s, mut l) = (spec.clone(), ld.clone());
            if let ParamKind::AreaScale = p.kind {
                set_param(&mut s, &mut l, p, v / v0); // factor on the design's areas
            } else {
                set_param(&mut s, &mut l, p, v);
            }
            let r = Rod::new(s).unwrap();
            let sol = solved(&r, &l);
            let marks = marker_positions(&r, &l, &sol, &locate_markers(&r, &marks).unwrap());
            (sol.tip, marks)
        };
        let ((tp, mp), (tm, mm)) = (at(v0 + step), at(v0 - step));
        let fd_r: Vec<f64> = (0..3).map(|i| (tp.r[i] - tm.r[i]) / (2.0 * step)).collect();
        let fd_q: Vec<f64> = (0..9)
            .map(|k| (tp.rot[k / 3][k % 3] - tm.rot[k / 3][k % 3]) / (2.0 * step))
            .collect();
        let ex_q: Vec<f64> = (0..9).map(|k| sens.rotation[j][k / 3][k % 3]).collect();
        let mut cols = vec![
            ("tip position", sens.position[j].to_vec(), fd_r),
            ("tip rotation", ex_q, fd_q),
        ];
        for (k, (a, b)) in mp.iter().zip(&mm).enumerate() {
            let fd: Vec<f64> = (0..3).map(|i| (a[i] - b[i]) / (2.0 * step)).collect();
            cols.push((
                ["marker 0", "marker 1", "marker 2"][k],
                sens.markers[j][k].to_vec(),
                fd,
            ));
        }
        for (what, ex, fd) in cols {
            let e = column_error(&ex, &fd);
            println!("{name}: d {what} / d {}: rel. error {e:.2e}", p.kind.name());
            assert!(
                e < COLUMN_TOL,
                "{name}: d {what} / d {}: {ex:?} vs {fd:?} ({e:.2e})",
                p.kind.name()
            );
        }
    }
    // The marker at the tip moves with the tip's pose: d(r + R o) = dr + dR o.
    let o = marks[2].offset;
    for j in 0..params.len() {
        let dr = &sens.rotation[j];
        let want: [f64; 3] = std::array::from_fn(|i| {
            sens.position[j][i] + (0..3).map(|c| dr[i][c] * o[c]).sum::<f64>()
        });
        assert!(
            dist(&sens.markers[j][2], &want) <= 1e-12 * dist(&want, &[0.0; 3]),
            "{name}, param {j}: tip marker {:?} vs tip pose {want:?}",
            sens.markers[j][2]
        );
    }
}

#[test]
fn collocation_sensitivities_match_finite_differences() {
    check_sensitivities(
        "chambered arm",
        arm(),
        base_loads(),
        &["E", "density", "area_scale", "c_b", "c_e"],
    );
}

/// The same on a section whose models vary along s (one per stage point), hanging
/// (`common::long_tapered_tabulated_arm`).
#[test]
fn collocation_sensitivities_of_a_tapered_tabulated_arm() {
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    check_sensitivities(
        "tapered arm",
        design(vec![long_tapered_tabulated_arm()], hanging, 9.81),
        loads(&[30e3, 0.0, 0.0]),
        &["mass", "c_e", "c_b", "area_scale"],
    );
}

/// A batch of collocation rows: every row's derivatives equal the single solve's (the same
/// cold solve and factorisation: equal to round-off), where before the batch was refused.
#[test]
fn collocation_batch_equals_single_solves() {
    let rod = Rod::new(arm()).unwrap();
    let params = [param("E", &[0]), param("density", &[0])];
    let marks = [Marker {
        s: 0.6 * L,
        offset: [0.0, 0.01, 0.0],
    }];
    let pressures = [0.0, 5e3, 20e3];
    let batch = BatchInputs {
        pressures: &pressures,
        tensions: None,
        stiffness_scale: None,
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
    };
    let rows = sensitivity_batch(&rod, &batch, None, &params, &marks, &opts(), 2).unwrap();
    let located = locate_markers(&rod, &marks).unwrap();
    for (row, &p) in rows.iter().zip(&pressures) {
        assert!(row.converged, "{p} Pa");
        let ld = loads(&[p]);
        let sol = solved(&rod, &ld);
        let single = pose_sensitivity(&rod, &ld, &sol, &params, &located).unwrap();
        let got = row.sensitivity.as_ref().unwrap();
        for j in 0..params.len() {
            let scale = dist(&single.position[j], &[0.0; 3]);
            assert!(
                dist(&got.position[j], &single.position[j]) <= 1e-9 * scale,
                "{p} Pa, param {j}: {:?} vs {:?}",
                got.position[j],
                single.position[j]
            );
            assert!(dist(&got.markers[j][0], &single.markers[j][0]) <= 1e-9 * scale);
        }
    }
}
