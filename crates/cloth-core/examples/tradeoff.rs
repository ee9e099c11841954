//! The integrators' trade-off on the drape scene (`presets::drape`), printed as the
//! Markdown table of the README:
//! - the largest stable step: the fewest substeps per 1/60 s frame (from 1, 2, 3, 4, 6, 8,
//!   12, … ) at which 1 s of draping runs without an `Unstable` report;
//! - the cost of a 1/60 s frame at the fewest substeps that keep the largest structural
//!   strain under 10 % once draped (the last 0.5 s of a 1.5 s run), that strain, and the
//!   largest stretch of the shear diagonals over the same window (a drape whose cells
//!   collapsed in shear, a "fishnet", meets the structural figure with its diagonals
//!   stretched by tens of percent).
//!
//! Every integrator runs with its default settings, and XPBD once more with its warp and weft
//! solved chain by chain (`xpbd.chains`, two Newton iterations per chain solve).
//!
//! usage: `cargo run --release -p cloth-core --example tradeoff -- [SIZES…]` (default 64 128)

use std::time::Instant;

use cloth_core::{Integrator, Simulation, SpringClass, presets};

const CANDIDATES: [u32; 22] = [
    1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 160, 192, 256, 320, 384, 512, 768, 1024,
];

struct Run {
    stable: bool,
    strain: f32,
    shear: f32,
    ms_per_frame: f64,
}

fn run(n: usize, (integrator, chains): (Integrator, bool), substeps: u32, frames: u32) -> Run {
    let mut sim: Simulation = presets::drape(n, integrator).expect("drape");
    let mut config = *sim.config();
    config.substeps = substeps;
    if chains {
        config.xpbd.chains = true;
        config.xpbd.chain_iterations = 2;
    }
    sim.set_config(config).expect("config");
    let mut strain = 0.0f32;
    let mut shear = 0.0f32;
    let mut stepping = 0.0;
    for frame in 0..frames {
        let t = Instant::now();
        let result = sim.step();
        stepping += t.elapsed().as_secs_f64();
        match result {
            Ok(s) if frame >= frames / 3 * 2 => {
                strain = strain.max(s.strain(SpringClass::Structural));
                shear = shear.max(s.strain(SpringClass::Shear));
            }
            Ok(_) => {}
            Err(_) => {
                return Run {
                    stable: false,
                    strain: f32::INFINITY,
                    shear: f32::INFINITY,
                    ms_per_frame: f64::NAN,
                };
            }
        }
    }
    Run {
        stable: true,
        strain,
        shear,
        ms_per_frame: 1e3 * stepping / f64::from(frames),
    }
}

fn main() {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![64, 128]
    } else {
        sizes
    };
    println!(
        "| drape | integrator | largest stable step | substeps for strain < 10 % | ms per 1/60 s frame | structural strain | shear strain |"
    );
    println!("|---|---|---|---|---|---|---|");
    for n in sizes {
        let setups = Integrator::ALL
            .into_iter()
            .map(|i| (i, false))
            .chain([(Integrator::Xpbd, true)]);
        for setup in setups {
            let stable = CANDIDATES
                .iter()
                .copied()
                .find(|&s| run(n, setup, s, 60).stable);
            let stable_txt = stable.map_or("none tried".to_string(), |s| {
                let plural = if s == 1 { "" } else { "s" };
                format!("1/{} s ({s} substep{plural})", 60 * s)
            });
            let start = stable.unwrap_or(1);
            let good = CANDIDATES
                .iter()
                .copied()
                .filter(|&s| s >= start)
                .map(|s| (s, run(n, setup, s, 90)))
                .find(|(_, r)| r.stable && r.strain < 0.1);
            let (sub, ms, strain, shear) = match good {
                Some((s, r)) => (
                    s.to_string(),
                    format!("{:.1}", r.ms_per_frame),
                    format!("{:.1} %", 100.0 * r.strain),
                    format!("{:.1} %", 100.0 * r.shear),
                ),
                None => ("none ≤ 1024".into(), "–".into(), "–".into(), "–".into()),
            };
            let name = match setup {
                (i, false) => i.name().to_string(),
                (i, true) => format!("{} + chains", i.name()),
            };
            println!("| {n}² | {name} | {stable_txt} | {sub} | {ms} | {strain} | {shear} |");
        }
    }
}
