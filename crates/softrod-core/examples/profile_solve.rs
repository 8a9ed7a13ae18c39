//! Time the pieces of one static solve (used while optimising; `cargo run --release --example
//! profile_solve -- SPEC.json [TENSION_N [COLD_SOLVES]]`; with COLD_SOLVES it only runs that many
//! cold solves, for `valgrind --tool=callgrind`).
use softrod_core::ode::Loads;
use softrod_core::statics::{residual, residual_and_jacobian, solve, SolverOptions};
use softrod_core::{DesignSpec, Rod};
use std::time::Instant;

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: profile_solve SPEC.json");
    let spec: DesignSpec = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let rod = Rod::new(spec).unwrap();
    let mut loads = Loads::from_design(&rod, [70e3, 35e3, 0.0][..rod.n_channels.min(3)].to_vec());
    // Optional second argument: the same tension on every tendon, N.
    if let Some(t) = std::env::args().nth(2) {
        let t: f64 = t.parse().expect("tension in N");
        loads.tensions = vec![t; rod.n_tendons];
    }
    let opts = SolverOptions::default();
    let sol = solve(&rod, &loads, None, &opts).unwrap();
    // Optional third argument: only that many cold solves (for callgrind's counts).
    if let Some(k) = std::env::args().nth(3) {
        let k: usize = k.parse().expect("number of cold solves");
        for _ in 0..k {
            std::hint::black_box(solve(&rod, &loads, None, &opts).unwrap());
        }
        println!("{k} cold solves, {} iterations each", sol.iterations);
        return;
    }
    let n = 2000;
    let t = Instant::now();
    for _ in 0..n {
        let _ = std::hint::black_box(residual(&rod, &loads, &sol.x));
    }
    let f64_pass = t.elapsed().as_secs_f64() / n as f64;
    let t = Instant::now();
    for _ in 0..n {
        let _ = std::hint::black_box(residual_and_jacobian(&rod, &loads, &sol.x));
    }
    let dual_pass = t.elapsed().as_secs_f64() / n as f64;
    let t = Instant::now();
    let mut it = 0;
    for _ in 0..n {
        it = std::hint::black_box(solve(&rod, &loads, None, &opts).unwrap()).iterations;
    }
    let cold = t.elapsed().as_secs_f64() / n as f64;
    println!(
        "f64 pass {:.2} us, dual pass {:.2} us, cold solve {:.2} us ({it} iterations, {} load levels, stable {:?})",
        f64_pass * 1e6,
        dual_pass * 1e6,
        cold * 1e6,
        sol.load_steps,
        sol.stable
    );
}
