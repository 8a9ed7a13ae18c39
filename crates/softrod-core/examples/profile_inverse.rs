//! Time the pieces of a warm-started inverse solve (used while optimising;
//! `cargo run --release --example profile_inverse SPEC.json`).
use softrod_core::inverse::{solve_inverse, InverseOptions, InverseTarget};
use softrod_core::jacobian::{pass, Input, Probe};
use softrod_core::ode::Loads;
use softrod_core::statics::{residual, solve, SolverOptions};
use softrod_core::{DesignSpec, Rod};
use std::time::Instant;

/// Best of 5 rounds (the machine is shared: the minimum is the least disturbed round).
fn time<T>(n: usize, mut f: impl FnMut() -> T) -> f64 {
    (0..5)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..n / 5 {
                std::hint::black_box(f());
            }
            t.elapsed().as_secs_f64() / (n / 5) as f64 * 1e6
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: profile_inverse SPEC.json");
    let spec: DesignSpec = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let rod = Rod::new(spec).unwrap();
    let loads = |p: &[f64]| Loads {
        pressures: p.to_vec(),
        ..Loads::from_design(&rod, vec![])
    };
    let opts = SolverOptions::default();
    let p = [20e3, 40e3, 5e3];
    let sol = solve(&rod, &loads(&p), None, &opts).unwrap();
    let x3: [f64; 3] = std::array::from_fn(|i| sol.x[i]);
    let n = 2000;
    let probe = Probe::tip(&rod);
    let inputs: Vec<Input> = (0..3).map(Input::Pressure).collect();
    let f64_pass = time(n, || residual(&rod, &loads(&p), &sol.x));
    let warm = time(n, || solve(&rod, &loads(&p), Some(&sol.x), &opts).unwrap());
    let joint = time(n, || pass(&rod, &loads(&p), &x3, &inputs, &probe));
    let problem_new = time(n, || {
        softrod_core::statics::residual(&rod, &loads(&p), &sol.x)
    });
    let _ = problem_new;
    let check = time(n, || {
        softrod_core::statics::conclude_at(&rod, &loads(&p), x3, 0, &opts).unwrap()
    });
    let iopts = InverseOptions::new(vec![[0.0, 70e3]; 3]);
    let target = |r: [f64; 3]| InverseTarget {
        s: rod.length,
        position: r,
        orientation: None,
        position_weight: [1.0; 3],
        orientation_weight: 0.0,
    };
    let mut prev =
        solve_inverse(&rod, &loads(&[0.0; 3]), &target(sol.tip.r), &iopts, None).unwrap();
    let c = sol.tip.r;
    let mut k = 0usize;

    let inv = time(n, || {
        k += 1;
        let a = k as f64 * 0.05;
        let goal = [c[0] + 0.01 * (a.cos() - 1.0), c[1] + 0.01 * a.sin(), c[2]];
        prev = solve_inverse(
            &rod,
            &loads(&prev.pressures),
            &target(goal),
            &iopts,
            Some(&prev.warm_start()),
        )
        .unwrap();
    });
    let cold = time(200, || {
        solve_inverse(&rod, &loads(&[0.0; 3]), &target(sol.tip.r), &iopts, None).unwrap()
    });
    println!(
        "f64 pass {f64_pass:.2} us, warm statics {warm:.2} us, joint Jet<6> pass {joint:.2} us, conclusion (validity, stability) {check:.2} us, warm inverse {inv:.2} us ({} passes, {} iterations), cold inverse {cold:.1} us",
        prev.passes, prev.iterations
    );
}
