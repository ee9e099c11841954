//! `cloth`: run, render and view the cloth simulator's built-in scenes.
//!
//! - `cloth sim SCENE`: headless run printing a diagnostics table;
//! - `cloth render SCENE --png FILE`: steps the scene and renders its last frame offscreen;
//! - `cloth view [SCENE]`: the interactive viewer (plain `cloth` is `cloth view drape`).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

mod export;
mod out;
mod sim_cmd;
use cloth_core::{Integrator, Simulation};
use cloth_view::SceneKind;

/// The help's text after the options: the built-in scenes (their names read from the scenes
/// the binary embeds, so the list is never stale), examples, the viewer's controls and the
/// exit statuses.
fn after_help() -> String {
    let mut scenes = String::new();
    let mut line = String::from(" ");
    for (i, (name, _)) in cloth_core::scene::BUILTIN.iter().enumerate() {
        let sep = if i + 1 < cloth_core::scene::BUILTIN.len() {
            ","
        } else {
            ""
        };
        if line.len() + 1 + name.len() + sep.len() > 90 {
            scenes.push_str(&line);
            scenes.push('\n');
            line = String::from(" ");
        }
        line.push(' ');
        line.push_str(name);
        line.push_str(sep);
    }
    scenes.push_str(&line);
    format!(
        "Built-in scenes (`cloth scenes` describes each; drape is the default; any TOML scene \
         file works too):\n{scenes}\n\n{AFTER_SCENES}"
    )
}

const AFTER_SCENES: &str = "\
Examples:
  cloth                                   open the viewer on the drape
  cloth sim drape --frames 300            run headless, print energies and strains
  cloth render drape --frames 90 --png drape.png --size 800x600
  cloth view flag --resolution 32
  cloth view my.toml                      open a scene file (the panel saves one)
  cloth sim my.toml --out frames --format obj,glb --report run.json

Viewer controls: left-drag on the cloth grabs it, elsewhere orbits; right/middle-drag pans;
wheel zooms; Ctrl/Shift-click pins or unpins; Space pause, N single step, R reset,
C orbit/fly camera (fly: WASD, Q/E down/up, Shift faster, right-drag looks), W wireframe,
K contacts, Home reset view, Tab hide/show the panel, Esc quit (after taking --screenshot). On
quitting, the viewer prints one line of its state to standard error; CLOTH_VIEW_LAYOUT=FILE
makes it write that line and where the panel's widgets are to FILE after every frame (for
scripts that click the panel; see crates/cloth-view/README.md).

Without a GPU, rendering needs Mesa's software renderer and, for the window, a display (or
`xvfb-run -a cloth view`).

Exit status: 0 ok; 1 a failure while working (no adapter, no display, a write of frames, report,
checkpoint, image or standard output that fails during or after the run); 2 bad input
(arguments, scene files, and output paths found unwritable before any work is done: a folder
that cannot be created, a missing folder, a folder where a file goes); 3 the simulation went
unstable; 130 interrupted (Ctrl-C).";

/// Real-time cloth simulation: run, render or view a built-in scene.
#[derive(Debug, Parser)]
#[command(name = "cloth", version, about, after_help = after_help())]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a scene headless: diagnostics table, mesh export, JSON report, checkpoints.
    Sim(sim_cmd::SimArgs),
    /// List the built-in scenes, or print one's TOML (--print NAME).
    Scenes(sim_cmd::ScenesArgs),
    /// Validate a scene and print its summary without running it.
    Check(sim_cmd::CheckArgs),
    /// Step a scene, then render its last frame offscreen (no window) into a PNG.
    Render {
        #[command(flatten)]
        scene: SceneArgs,
        /// Frames to step before rendering.
        #[arg(long, value_name = "N", default_value = "120", value_parser = sim_cmd::parse_positive_u64)]
        frames: u64,
        /// The PNG file to write (its name ends in .png; its folder must exist).
        #[arg(long, value_name = "FILE", value_parser = parse_png)]
        png: PathBuf,
        /// Image size.
        #[arg(long, value_name = "WxH", default_value = "800x600", value_parser = parse_size)]
        size: [u32; 2],
        /// Draw the triangle edges too.
        #[arg(long)]
        wireframe: bool,
        /// Draw the springs, coloured by class (structural orange, shear green, bend blue).
        #[arg(long)]
        springs: bool,
        /// Draw the contacts (cyan: particle–collider normals; magenta: cloth–cloth pairs).
        #[arg(long)]
        contacts: bool,
    },
    /// Open the interactive viewer.
    View {
        #[command(flatten)]
        scene: SceneArgs,
        /// Quit by itself after this many frames (for scripted runs and tests).
        #[arg(long, value_name = "N", value_parser = sim_cmd::parse_positive_u64)]
        frames: Option<u64>,
        /// Initial window size.
        #[arg(long, value_name = "WxH", default_value = "1280x800", value_parser = parse_size)]
        size: [u32; 2],
        /// Save the last frame, panel included, to this PNG: frame N of --frames (needed), or the
        /// frame Esc quits at if earlier (the name ends in .png and its folder must exist).
        #[arg(long, value_name = "FILE", requires = "frames", value_parser = parse_png)]
        screenshot: Option<PathBuf>,
    },
}

#[derive(Debug, Args)]
struct SceneArgs {
    /// A built-in scene (`cloth scenes` lists them) or a TOML scene file.
    #[arg(value_name = "SCENE", default_value = "drape")]
    scene: String,
    /// Particles along the cloth's rows (columns in proportion). Default: the scene's. Another
    /// resolution (or integrator) chooses the substeps again, unless --set gives them.
    #[arg(long, value_name = "N", value_parser = sim_cmd::parse_resolution)]
    resolution: Option<usize>,
    /// The time integrator. Default: the scene's.
    #[arg(long, value_name = "NAME", value_parser = sim_cmd::parse_integrator)]
    integrator: Option<Integrator>,
    #[arg(
        long = "set",
        value_name = "KEY=VALUE",
        help = "Override a scene key in TOML syntax, e.g. --set forces.air.wind=[3,0,0] (repeatable)"
    )]
    set: Vec<String>,
    /// Build the scene even if its memory estimate exceeds the memory available (or the
    /// environment's CLOTH_MEMORY_LIMIT, a size such as 4GiB).
    #[arg(long)]
    force: bool,
}

/// A loaded scene with the resolution and integrator to build it with.
struct Chosen {
    scene: SceneKind,
    resolution: usize,
    integrator: Integrator,
}

impl SceneArgs {
    fn load(&self) -> Result<Chosen, ExitCode> {
        let scene = SceneKind::load(&self.scene, &self.set).map_err(|e| {
            eprintln!("error: {e}");
            ExitCode::from(2)
        })?;
        let chosen = Chosen {
            resolution: self.resolution.unwrap_or_else(|| scene.resolution()),
            integrator: self.integrator.unwrap_or_else(|| scene.integrator()),
            scene,
        };
        let effective = chosen.scene.effective(chosen.resolution, chosen.integrator);
        sim_cmd::memory_gate(&effective, self.force).map_err(|refusal| {
            eprintln!("error: {refusal}");
            ExitCode::from(2)
        })?;
        Ok(chosen)
    }
}

fn parse_png(s: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match path.extension() {
        Some(ext) if ext.eq_ignore_ascii_case("png") => Ok(path),
        _ => Err("allowed a file name ending in .png (the image is written as PNG)".into()),
    }
}

fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let err = || "allowed WIDTHxHEIGHT with sides in 1 ..= 8192, e.g. 800x600".to_string();
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let side = |v: &str| v.parse::<u32>().ok().filter(|v| (1..=8192).contains(v));
    Ok([side(w).ok_or_else(err)?, side(h).ok_or_else(err)?])
}

fn main() -> ExitCode {
    let code = run(Cli::parse());
    // A closed pipe (`cloth scenes | head`) is not an error; any other failed write is.
    match out::status() {
        Some(e) => {
            eprintln!("error: cannot write to standard output: {e}");
            ExitCode::FAILURE
        }
        None => code,
    }
}

fn run(cli: Cli) -> ExitCode {
    let command = cli.command.unwrap_or(Command::View {
        scene: SceneArgs {
            scene: "drape".into(),
            resolution: None,
            integrator: None,
            set: Vec::new(),
            force: false,
        },
        frames: None,
        size: [1280, 800],
        screenshot: None,
    });
    match command {
        Command::Sim(args) => sim_cmd::sim(&args),
        Command::Scenes(args) => sim_cmd::scenes(&args),
        Command::Check(args) => sim_cmd::check(&args),
        Command::Render {
            scene,
            frames,
            png,
            size,
            wireframe,
            springs,
            contacts,
        } => {
            let chosen = match scene.load() {
                Ok(c) => c,
                Err(code) => return code,
            };
            let mut options = cloth_view::default_options(&chosen.scene);
            options.wireframe = wireframe;
            options.springs = springs;
            options.contacts = contacts;
            render(&chosen, frames, &png, size, &options)
        }
        Command::View {
            scene,
            frames,
            size,
            screenshot,
        } => {
            let chosen = match scene.load() {
                Ok(c) => c,
                Err(code) => return code,
            };
            if let Some(path) = &screenshot
                && let Err(code) = writable(path, "screenshot")
            {
                return code;
            }
            let options = cloth_view::app::ViewOptions {
                scene: chosen.scene,
                resolution: chosen.resolution,
                integrator: chosen.integrator,
                frames,
                size,
                screenshot,
            };
            match cloth_view::app::run(options) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}

/// Whether the image file `path` can be written, checked before any work: else the error
/// is printed and the exit status is 2 (bad input).
fn writable(path: &std::path::Path, what: &str) -> Result<(), ExitCode> {
    sim_cmd::check_writable_file(path, what).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

fn build(args: &Chosen) -> Result<Simulation, ExitCode> {
    args.scene
        .build(args.resolution, args.integrator)
        .map_err(|e| {
            eprintln!("error: {e}");
            ExitCode::from(2)
        })
}

fn render(
    args: &Chosen,
    frames: u64,
    png: &std::path::Path,
    size: [u32; 2],
    options: &cloth_view::RenderOptions,
) -> ExitCode {
    let mut sim = match build(args) {
        Ok(s) => s,
        Err(code) => return code,
    };
    // Checked before stepping and rendering: a bad path costs nothing.
    if let Err(code) = writable(png, "PNG") {
        return code;
    }
    for _ in 0..frames {
        if let Err(e) = sim.step() {
            eprintln!("error: {e}");
            return ExitCode::from(3);
        }
    }
    let gpu = match cloth_view::Gpu::headless() {
        Ok(g) => g,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let adapter = gpu.adapter_name();
    let mut offscreen = cloth_view::Offscreen::new(gpu, size);
    let (camera, fovy) = args.scene.start_view();
    offscreen.set_fovy(fovy);
    let result = offscreen
        .render(&sim, &camera, options)
        .and_then(|img| img.save(png).map_err(anyhow::Error::from));
    match result {
        Ok(()) => {
            out::outln!(
                "wrote {} ({}x{}, {} after {frames} frames, t = {:.3} s; {}x MSAA on {adapter})",
                png.display(),
                size[0],
                size[1],
                args.scene,
                sim.time(),
                offscreen.samples()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: cannot write {}: {e:#}", png.display());
            ExitCode::FAILURE
        }
    }
}
