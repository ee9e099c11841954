//! `cloth`: runs a built-in scene headless and prints what happens.
//!
//! (The viewer and scene files come later; for now this is the quick way to see the
//! simulator work.)

use std::process::ExitCode;
use std::time::Instant;

use cloth_core::{ClothError, Integrator, Simulation, SpringClass, presets};

const USAGE: &str = "usage: cloth [sim] [drape|hanging|peer-ball] [--frames N] [--resolution N] \
[--integrator forward-euler|symplectic-euler|verlet]";

struct Args {
    scene: String,
    frames: u64,
    resolution: usize,
    integrator: Integrator,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        scene: "drape".into(),
        frames: 120,
        resolution: 48,
        integrator: Integrator::SymplecticEuler,
    };
    let mut it = std::env::args().skip(1).peekable();
    if it.peek().map(String::as_str) == Some("sim") {
        it.next();
    }
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("`{name}` needs a value"));
        match arg.as_str() {
            "-h" | "--help" => return Err(String::new()),
            "--frames" => {
                let v = value("--frames")?;
                args.frames = v.parse().ok().filter(|&f| f >= 1).ok_or_else(|| {
                    format!("invalid `--frames` = {v:?}: allowed an integer >= 1")
                })?;
            }
            "--resolution" => {
                let v = value("--resolution")?;
                args.resolution = v
                    .parse()
                    .ok()
                    .filter(|r| (2..=4096).contains(r))
                    .ok_or_else(|| {
                        format!("invalid `--resolution` = {v:?}: allowed an integer in 2 ..= 4096")
                    })?;
            }
            "--integrator" => {
                let v = value("--integrator")?;
                args.integrator = Integrator::ALL
                    .into_iter()
                    .find(|i| i.name() == v)
                    .ok_or_else(|| {
                        format!(
                            "invalid `--integrator` = {v:?}: allowed forward-euler, symplectic-euler, verlet"
                        )
                    })?;
            }
            s if !s.starts_with('-') => args.scene = s.to_string(),
            s => return Err(format!("unknown option `{s}`")),
        }
    }
    Ok(args)
}

fn build(args: &Args) -> Result<Simulation, String> {
    let sim = match args.scene.as_str() {
        "drape" => presets::drape(args.resolution, args.integrator),
        "hanging" => presets::hanging(args.resolution, args.integrator),
        "peer-ball" => presets::peer_ball(args.resolution),
        other => {
            return Err(format!(
                "unknown scene `{other}`: allowed drape, hanging, peer-ball"
            ));
        }
    };
    sim.map_err(|e| e.to_string())
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(msg) => {
            if msg.is_empty() {
                println!("{USAGE}");
                return ExitCode::SUCCESS;
            }
            eprintln!("error: {msg}\n{USAGE}");
            return ExitCode::from(2);
        }
    };
    let mut sim = match build(&args) {
        Ok(s) => s,
        Err(msg) => {
            eprintln!("error: {msg}");
            return ExitCode::from(2);
        }
    };
    let (rows, cols) = sim.grid_size();
    let cfg = *sim.config();
    println!(
        "scene {} {}x{} particles={} springs={} integrator={} dt={:.5} s substeps={}",
        args.scene,
        rows,
        cols,
        sim.particles().len(),
        sim.topology().springs().len(),
        cfg.integrator.name(),
        cfg.dt,
        cfg.substeps
    );
    println!(
        "{:>6} {:>8} {:>12} {:>12} {:>10} {:>10} {:>10} {:>9} {:>8}",
        "frame",
        "t [s]",
        "E_total [J]",
        "E_kin [J]",
        "strain_st",
        "strain_sh",
        "strain_bd",
        "pen [m]",
        "contacts"
    );
    let start = Instant::now();
    let mut stepping = 0.0f64;
    for frame in 1..=args.frames {
        let t0 = Instant::now();
        let result = sim.step();
        stepping += t0.elapsed().as_secs_f64();
        match result {
            Ok(s) => {
                if frame % 10 == 0 || frame == args.frames {
                    println!(
                        "{:>6} {:>8.3} {:>12.5e} {:>12.5e} {:>10.4} {:>10.4} {:>10.4} {:>9.2e} {:>8}",
                        frame,
                        s.time,
                        s.total_energy(),
                        s.kinetic_energy,
                        s.strain(SpringClass::Structural),
                        s.strain(SpringClass::Shear),
                        s.strain(SpringClass::Bend),
                        s.max_penetration,
                        s.contacts
                    );
                }
            }
            Err(e @ ClothError::Unstable { .. }) => {
                eprintln!("error: {e}");
                return ExitCode::from(3);
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    let n = sim.particles().len() as f64;
    let substeps = f64::from(cfg.substeps) * args.frames as f64;
    println!(
        "done: {} frames in {:.3} s wall ({:.3} s stepping), {:.2} ms/frame, {:.3e} particle-substeps/s",
        args.frames,
        start.elapsed().as_secs_f64(),
        stepping,
        1e3 * stepping / args.frames as f64,
        n * substeps / stepping
    );
    ExitCode::SUCCESS
}
