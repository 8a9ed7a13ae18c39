mod common;
use common::*;
use softrod_core::statics::{solve, shape, SolverOptions};
use softrod_core::Rod;

#[test]
fn scratch() {
    let chs = vec![
        p002_chambers([90.0, 210.0, 330.0]),
        vec![chamber(P002_RP, P002_RHO, 0.0, 0), chamber(P002_RP, P002_RHO, 60.0, 1)],
    ];
    for (p, ch) in [(vec![60e3, 0.0, 0.0], 0), (vec![200e3, 0.0, 0.0], 0), (vec![30e3, 50e3], 1), (vec![400e3, 0.0, 0.0], 0)] {
        let mk = |steps| Rod::new(design(vec![geometry_section("body", P002_BODY, P002_RO, P002_RI, ECOFLEX, chs[ch].clone(), steps)], IDENTITY, 0.0)).unwrap();
        let refsh = shape(&mk(4096), &loads(&p), &solve(&mk(4096), &loads(&p), None, &SolverOptions::default()).unwrap());
        let kappa = norm(&refsh.u[0]);
        for steps in [16, 32, 64] {
            let rod = mk(steps);
            let sol = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
            let sh = shape(&rod, &loads(&p), &sol);
            let h = P002_BODY / steps as f64;
            let mut worst: f64 = 0.0;
            for i in 1..sh.s.len() {
                let a = sh.rotation[i]; let b = refsh.rotation[i * 4096 / steps];
                let e: f64 = (0..3).flat_map(|r| (0..3).map(move |c| (a[r][c]-b[r][c]).powi(2))).sum::<f64>().sqrt();
                worst = worst.max(e / (kappa * sh.s[i] * (kappa*h).powi(4)));
            }
            eprintln!("p {p:?} kL {:.3} steps {steps}: rot coeff {worst:.4}", kappa*P002_BODY);
        }
    }
}
