//! Markers on a moving rod (`Simulator::set_markers`, `marker_positions`): at a node the
//! node itself, between nodes the collocation's continuous extension, whose order on an
//! exact arc is measured here; their parameter derivatives are checked against central
//! differences in tests/suite/dynamics_sensitivity.rs.

use crate::common;

use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, Simulator};
use softrod_core::marker::Marker;
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::{Rod, SoftrodError};
use std::f64::consts::PI;

const L: f64 = 0.2;
const EI: f64 = 0.01;
/// A quarter circle: u1 = kappa = M / EI with kappa L = pi / 2.
const KAPPA: f64 = PI / 2.0 / L;

/// A straight rod (no gravity) under a pure tip moment M about d1, at rest in its static
/// equilibrium on `steps` intervals: the exact shape is the arc of curvature KAPPA in the
/// y-z plane (tests/suite/exact.rs), which every step keeps.
fn arc(steps: usize) -> Simulator {
    arc_with(steps, Scheme::BdfAlpha)
}

fn arc_with(steps: usize, scheme: Scheme) -> Simulator {
    let mut spec = design(
        vec![direct_section("rod", L, 1e3, 1e3, EI, 0.02, 0.02, steps)],
        IDENTITY,
        0.0,
    );
    spec.tip.moment = [KAPPA * EI, 0.0, 0.0];
    let opts = DynOptions {
        dt: 1e-3,
        // Newton's tolerance far below the discretisation error of the finest grid
        // (~1e-8 m), so that the measured errors are the extension's.
        tol: 1e-13,
        scheme,
        ..DynOptions::default()
    };
    Simulator::new(Rod::new(spec).unwrap(), &[], Initial::Static, opts).unwrap()
}

/// The exact point at s with offset o (d1, d2, d3): r = (0, -(1 - cos ks)/k, sin ks / k),
/// d1 = x, d2 = (0, cos ks, sin ks), d3 = (0, -sin ks, cos ks).
fn exact(s: f64, o: [f64; 3]) -> [f64; 3] {
    let (c, sn) = ((KAPPA * s).cos(), (KAPPA * s).sin());
    [
        o[0],
        -(1.0 - c) / KAPPA + o[1] * c - o[2] * sn,
        sn / KAPPA + o[1] * sn + o[2] * c,
    ]
}

#[test]
fn markers_at_nodes_are_the_nodes_and_at_the_end_the_tip() {
    for scheme in [Scheme::BdfAlpha, Scheme::Midpoint] {
        markers_at_nodes_with(scheme);
    }
}

fn markers_at_nodes_with(scheme: Scheme) {
    let mut sim = arc_with(6, scheme);
    let s = sim.node_s();
    let markers: Vec<Marker> = s
        .iter()
        .map(|&s| Marker {
            s,
            offset: [0.0; 3],
        })
        .collect();
    sim.set_markers(&markers).unwrap();
    for _ in 0..3 {
        sim.step(&[]).unwrap();
        // Bit for bit: the node's own position (r + R 0 adds exact zeros).
        assert_eq!(sim.marker_positions(), sim.shape().to_vec());
        let mut tip = Marker {
            s: L,
            offset: [0.0; 3],
        };
        let mut one = sim.clone();
        one.set_markers(&[tip]).unwrap();
        assert_eq!(one.marker_positions(), vec![sim.tip().r]);
        // An offset at the tip: r + R o with the tip's rotation.
        tip.offset = [0.003, -0.002, 0.001];
        one.set_markers(&[tip]).unwrap();
        let t = sim.tip();
        let want: [f64; 3] = std::array::from_fn(|i| {
            t.r[i] + t.rot[i][0] * 0.003 - t.rot[i][1] * 0.002 + t.rot[i][2] * 0.001
        });
        assert_eq!(one.marker_positions(), vec![want]);
    }
}

/// Interior markers on the exact arc converge at third order: the extension's error is
/// C h^3 theta (2 theta - 1) (theta - 1) / 6 inside an interval (collocation::
/// dense_weights), so the markers sit where theta stays 1/3 or 2/3 as the grid is refined
/// by 4 (s = L/6, L/3, 2L/3 on 2, 8, 32 intervals), and the slope is fitted over the
/// three grids.
#[test]
fn interior_markers_converge_at_third_order_on_an_exact_arc() {
    let sites = [
        (L / 6.0, [0.0, 0.0, 0.0]),
        (L / 3.0, [0.0, 0.01, 0.0]),
        (2.0 * L / 3.0, [0.004, -0.006, 0.002]),
    ];
    let markers: Vec<Marker> = sites
        .iter()
        .map(|&(s, offset)| Marker { s, offset })
        .collect();
    let grids = [2usize, 8, 32];
    let mut errors = vec![];
    for &n in &grids {
        let mut sim = arc(n);
        sim.set_markers(&markers).unwrap();
        sim.step(&[]).unwrap();
        let got = sim.marker_positions();
        let worst = sites
            .iter()
            .zip(&got)
            .map(|(&(s, o), p)| dist(p, &exact(s, o)))
            .fold(0.0f64, f64::max);
        errors.push(worst);
    }
    // Least-squares slope of log(error) against log(h) over the three grids.
    let x: Vec<f64> = grids.iter().map(|&n| (L / n as f64).ln()).collect();
    let y: Vec<f64> = errors.iter().map(|e| e.ln()).collect();
    let (mx, my) = (x.iter().sum::<f64>() / 3.0, y.iter().sum::<f64>() / 3.0);
    let slope = x
        .iter()
        .zip(&y)
        .map(|(a, b)| (a - mx) * (b - my))
        .sum::<f64>()
        / x.iter().map(|a| (a - mx).powi(2)).sum::<f64>();
    eprintln!("marker errors {errors:?} on {grids:?} intervals: order {slope:.3}");
    // Third order: a slope within 0.15 of 3 (second or fourth order would be 1 away).
    assert!(
        (slope - 3.0).abs() < 0.15,
        "order {slope}, errors {errors:?}"
    );
    // And small: the coarsest grid (2 intervals on a quarter circle) is within 1 % of L.
    assert!(errors[0] < 1e-2 * L, "{errors:?}");
}

/// The saved state holds the stage quaternions the extension reads: a restored run reads
/// the same markers bit for bit (midpoint scheme: its end state's stages are rebuilt from
/// the strains, not the step's unknowns).
#[test]
fn restored_state_reads_the_same_markers() {
    let markers = [
        Marker {
            s: 0.07,
            offset: [0.0, 0.004, 0.0],
        },
        Marker {
            s: 0.13,
            offset: [0.002, 0.0, -0.001],
        },
    ];
    for scheme in [Scheme::BdfAlpha, Scheme::Midpoint] {
        let mut a = arc_with(4, scheme);
        a.set_markers(&markers).unwrap();
        a.step(&[]).unwrap();
        let mut b = arc_with(4, scheme);
        b.set_markers(&markers).unwrap();
        b.restore(&a.save()).unwrap();
        assert_eq!(a.marker_positions(), b.marker_positions(), "{scheme:?}");
    }
}

#[test]
fn bad_markers_are_refused_by_name() {
    let mut sim = arc(4);
    let refused = |sim: &mut Simulator, m: Marker, field: &str| match sim.set_markers(&[
        Marker {
            s: 0.1,
            offset: [0.0; 3],
        },
        m,
    ]) {
        Err(SoftrodError::InvalidParameter { field: f, .. }) => assert_eq!(f, field),
        other => panic!("{field}: expected a refusal, got {other:?}"),
    };
    let ok = [0.0; 3];
    refused(
        &mut sim,
        Marker {
            s: 1.1 * L,
            offset: ok,
        },
        "markers[1].s",
    );
    refused(
        &mut sim,
        Marker {
            s: -1e-3,
            offset: ok,
        },
        "markers[1].s",
    );
    refused(
        &mut sim,
        Marker {
            s: f64::NAN,
            offset: ok,
        },
        "markers[1].s",
    );
    let nan = [0.0, f64::INFINITY, 0.0];
    refused(
        &mut sim,
        Marker {
            s: 0.1,
            offset: nan,
        },
        "markers[1].offset",
    );
    // Set after tracking started: its start's derivatives would be missing.
    let tau = Param {
        kind: ParamKind::CorrectionFactor(2),
        sections: vec![0],
    };
    sim.track_sensitivities(&[tau]).unwrap();
    refused(&mut sim, Marker { s: 0.1, offset: ok }, "markers");
}
