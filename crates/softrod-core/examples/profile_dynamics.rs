//! Time a dynamics run (used while optimising; `cargo run --release --example
//! profile_dynamics -- SPEC.json [dt] [t_end] [alpha] [pulses|release]`): the paper 000 square
//! pulses (zero for 1 s, then 0.9 ... 3.6 bar, 5 s on each channel in turn with 5 s rests)
//! or, with `release`, a rod released at rest in its straight shape with no input. Prints the
//! wall time, the counters and the tip at the end (to compare runs bit for bit). With the
//! environment variable `SENS=tau,area_scale` (names of `ParamKind::ALL`) the run tracks
//! the forward sensitivities of those parameters (sections: all elastic ones) and prints
//! the tip's derivatives at the end too.
use softrod_core::dynamics::{DynOptions, Initial, Simulator};
use softrod_core::sensitivity::{Param, ParamKind};
use softrod_core::{DesignSpec, Rod};
use std::time::Instant;

fn command(t: f64, n: usize) -> Vec<f64> {
    let mut p = vec![0.0; n];
    if t < 1.0 || n == 0 {
        return p;
    }
    let k = ((t - 1.0) / 10.0).floor() as usize;
    let within = (t - 1.0) - 10.0 * k as f64;
    if k < 4 * n && within < 5.0 {
        p[k % n] = [0.9e5, 1.8e5, 2.7e5, 3.6e5][k / n];
    }
    p
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .expect("usage: profile_dynamics SPEC.json [dt] [t_end] [alpha] [pulses|release]");
    let arg = |i: usize, d: f64| args.get(i).map(|s| s.parse().unwrap()).unwrap_or(d);
    let (dt, t_end, alpha) = (arg(2, 5e-3), arg(3, 116.0), arg(4, -0.2));
    let release = args.get(5).map(|s| s == "release").unwrap_or(false);
    let spec: DesignSpec = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let rod = Rod::new(spec).unwrap();
    let nch = rod.n_channels;
    // ERR=TOL: adaptive steps with that error tolerance (m); dt is then the longest step.
    let opts = DynOptions {
        dt,
        alpha,
        error_tol: std::env::var("ERR").ok().map(|s| s.parse().unwrap()),
        ..Default::default()
    };
    let initial = if release {
        Initial::Straight
    } else {
        Initial::Static
    };
    // CMDS=FILE: the commands of every step from a text file (one row of pressures in Pa
    // per step, the first row the start's).
    let table: Option<Vec<Vec<f64>>> = std::env::var("CMDS").ok().map(|p| {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
            .collect()
    });
    let t0 = Instant::now();
    let sections: Vec<usize> = (0..rod.sections.len())
        .filter(|&i| !rod.sections[i].rigid)
        .collect();
    let p0 = table.as_ref().map_or(vec![0.0; nch], |t| t[0].clone());
    let mut sim = Simulator::new(rod, &p0, initial, opts).unwrap();
    if let Ok(names) = std::env::var("SENS") {
        let params: Vec<Param> = names
            .split(',')
            .map(|n| {
                let kind = ParamKind::from_name(n).expect("a parameter name of ParamKind::ALL");
                Param {
                    kind,
                    sections: if kind == ParamKind::DampingTime {
                        vec![]
                    } else {
                        sections.clone()
                    },
                }
            })
            .collect();
        sim.track_sensitivities(&params).unwrap();
    }
    let n = table
        .as_ref()
        .map_or((t_end / dt).round() as usize, |t| t.len() - 1);
    let mut dout = std::env::var("DOUT")
        .ok()
        .map(|p| std::io::BufWriter::new(std::fs::File::create(p).unwrap()));
    for k in 0..n {
        let c = if let Some(t) = &table {
            t[k + 1].clone()
        } else if release {
            vec![0.0; nch]
        } else {
            command((k + 1) as f64 * dt, nch)
        };
        sim.step(&c).unwrap();
        if let (Some(d), Some(f)) = (sim.tip_sensitivity(), dout.as_mut()) {
            use std::io::Write;
            writeln!(f, "{:?}", d).unwrap();
        }
    }
    let wall = t0.elapsed();
    println!("wall {:.3} s, {:?}", wall.as_secs_f64(), sim.stats);
    println!("tip {:?} energy {:e}", sim.tip().r, sim.energy());
    if let Some(d) = sim.tip_sensitivity() {
        println!("d tip {d:?}");
    }
}
