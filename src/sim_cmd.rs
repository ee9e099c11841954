//! `cloth sim`, `cloth scenes` and `cloth check`: scenes run headless, listed and validated.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crate::out::{out, outln};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use cloth_core::diagnostics::{explicit_stability_limit_of, stable_substep_text, substeps_text};
use cloth_core::scene::{self, BUILTIN, Scene};
use cloth_core::{ClothError, SimConfig, SimState, Simulation, SpringClass, StepStats};
use serde::{Deserialize, Serialize};

use crate::export::{GlbFrames, grid_uvs, obj, write_atomic};

/// Exit status for bad input (arguments, scene files).
pub const EXIT_BAD_INPUT: u8 = 2;
/// Exit status of a run that became unstable.
pub const EXIT_UNSTABLE: u8 = 3;
/// Exit status of a run interrupted by Ctrl-C.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Mesh formats of `--format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// An OBJ file per exported frame, `frame_0001.obj`, …
    Obj,
    /// One animated glTF binary, `cloth.glb`.
    Glb,
}

/// Arguments of `cloth sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// A built-in scene (see `cloth scenes`) or a TOML scene file [default: drape].
    #[arg(value_name = "SCENE")]
    pub scene: Option<String>,
    /// Frames to run (steps of the scene's dt). Default: the scene's duration.
    #[arg(long, value_name = "N", conflicts_with = "seconds", value_parser = parse_positive_u64)]
    pub frames: Option<u64>,
    /// Simulated seconds to run, instead of --frames.
    #[arg(long, value_name = "S", value_parser = parse_seconds)]
    pub seconds: Option<f64>,
    /// Folder for mesh frames (created if missing; checked before simulating).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Mesh formats to write into --out: obj, glb, or both (`obj,glb`).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "obj",
        requires = "out"
    )]
    pub format: Vec<Format>,
    /// Export frames K, 2K, 3K, … and always the run's last frame (`frame_NNNN.obj`, NNNN
    /// the frame number: the state after NNNN steps of dt, at t = NNNN·dt).
    #[arg(long, value_name = "K", default_value = "1", value_parser = parse_positive_u64)]
    pub every: u64,
    /// Write a JSON run report to FILE.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Worker threads, 1 ..= 256 (default: the logical CPUs this process may use, at most
    /// 256). Results are bit-identical for every count: the explicit integrators' grid fast
    /// path cuts the rows into one band per thread and sums every force in a fixed order;
    /// XPBD's grid path projects colours of disjoint springs; implicit Euler splits its
    /// passes into fixed tasks and adds their partial sums in task order (recorded in the
    /// report, with the kernel that ran).
    #[arg(long, value_name = "N", default_value_t = default_threads(), value_parser = parse_threads)]
    pub threads: usize,
    /// The grid paths' kernel: reference, portable, avx2 or avx512 (default: the widest this
    /// CPU runs). For the explicit integrators and implicit Euler all give the same bits; for
    /// XPBD the grid kernels give the same bits and `reference` runs XPBD's storage-order
    /// sweeps.
    #[arg(long, value_name = "NAME", value_parser = parse_kernel)]
    pub kernel: Option<cloth_core::simd::Kernel>,
    #[arg(
        long = "set",
        value_name = "KEY=VALUE",
        help = "Override a scene key, in TOML syntax: --set cloth.resolution=[64,64] \
                --set solver.kind=xpbd (a bare word is a string) (repeatable)"
    )]
    pub set: Vec<String>,
    #[command(flatten)]
    pub shorthands: Shorthands,
    /// Save a checkpoint every N frames (into --out, or the current folder), atomically.
    #[arg(long, value_name = "N", value_parser = parse_positive_u64)]
    pub checkpoint_every: Option<u64>,
    /// Continue a run from a checkpoint file to the same result it would have had. The
    /// checkpoint carries its scene: SCENE, --set, --resolution and --integrator may repeat
    /// the original command line, and anything that changes the scene is refused. --frames
    /// and --seconds count from the start of the run.
    #[arg(long, value_name = "CHECKPOINT")]
    pub resume: Option<PathBuf>,
    /// Run even if the memory estimate exceeds the memory available (or the environment's
    /// CLOTH_MEMORY_LIMIT, a size such as 4GiB).
    #[arg(long)]
    pub force: bool,
    /// Print the diagnostics table every N frames (0: only the summary).
    #[arg(long, value_name = "N", default_value = "10")]
    pub table_every: u64,
}

/// Arguments of `cloth scenes`.
#[derive(Debug, Args)]
pub struct ScenesArgs {
    /// Print the TOML of this built-in scene, to start a scene file from.
    #[arg(long, value_name = "NAME")]
    pub print: Option<String>,
}

/// Arguments of `cloth check`.
#[derive(Debug, Args)]
pub struct CheckArgs {
    /// A built-in scene or a TOML scene file.
    #[arg(value_name = "SCENE")]
    pub scene: String,
    /// Overrides, as for `cloth sim`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    #[command(flatten)]
    pub shorthands: Shorthands,
    /// Check the scene even if its memory estimate exceeds the memory available or
    /// CLOTH_MEMORY_LIMIT (as `cloth sim --force`; checking builds the cloth, which takes that
    /// memory).
    #[arg(long)]
    pub force: bool,
}

/// The shorthands `cloth sim` and `cloth check` take for two overrides.
#[derive(Args, Debug, Clone)]
pub struct Shorthands {
    #[arg(
        long,
        value_name = "N",
        value_parser = parse_resolution,
        help = "Shorthand for --set cloth.resolution=[N,N]"
    )]
    pub resolution: Option<usize>,
    /// Shorthand for --set solver.kind="NAME".
    #[arg(long, value_name = "NAME", value_parser = parse_integrator)]
    pub integrator: Option<cloth_core::Integrator>,
}

impl Shorthands {
    /// `set` followed by the overrides these shorthands stand for.
    fn overrides(&self, set: &[String]) -> Vec<String> {
        let mut overrides = set.to_vec();
        if let Some(n) = self.resolution {
            overrides.push(format!("cloth.resolution=[{n},{n}]"));
        }
        if let Some(integrator) = self.integrator {
            overrides.push(format!("solver.kind=\"{}\"", integrator.name()));
        }
        overrides
    }
}

/// A count in 1 ..= 2⁶⁴ − 1 (a larger number does not fit the counter: it is refused with
/// the bound, not taken as "not an integer").
pub(crate) fn parse_positive_u64(s: &str) -> Result<u64, String> {
    s.parse()
        .ok()
        .filter(|&f| f >= 1)
        .ok_or_else(|| format!("allowed an integer in 1 ..= {}", u64::MAX))
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0 && *v <= f64::from(scene::MAX_DURATION))
        .ok_or_else(|| {
            format!(
                "allowed a number of seconds in (0, {:e}] (a scene's `duration` has the same \
                 bound)",
                scene::MAX_DURATION
            )
        })
}

fn parse_kernel(s: &str) -> Result<cloth_core::simd::Kernel, String> {
    use cloth_core::simd::Kernel;
    let k = Kernel::ALL
        .into_iter()
        .find(|k| k.name() == s)
        .ok_or_else(|| "allowed: reference, portable, avx2, avx512".to_string())?;
    if k.is_available() {
        Ok(k)
    } else {
        Err(format!("this CPU cannot run the {s} kernel"))
    }
}

/// The logical CPUs this process may use (its affinity mask or cgroup quota, as `std` reads
/// them; 1 if unknown): the report's `host.logical_cpus`.
fn logical_cpus() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
}

/// `--threads` when not given: [`logical_cpus`], at most 256.
fn default_threads() -> usize {
    logical_cpus().min(256)
}

fn parse_threads(s: &str) -> Result<usize, String> {
    s.parse()
        .ok()
        .filter(|t| (1..=256).contains(t))
        .ok_or_else(|| "allowed an integer in 1 ..= 256".into())
}

/// A grid side: 2 ..= 8192 particles.
pub(crate) fn parse_resolution(s: &str) -> Result<usize, String> {
    s.parse()
        .ok()
        .filter(|r| (2..=8192).contains(r))
        .ok_or_else(|| "allowed an integer in 2 ..= 8192".into())
}

/// An integrator by name.
pub(crate) fn parse_integrator(s: &str) -> Result<cloth_core::Integrator, String> {
    cloth_core::Integrator::from_name(s).ok_or_else(|| {
        let names: Vec<_> = cloth_core::Integrator::ALL
            .iter()
            .map(|i| i.name())
            .collect();
        format!("allowed {}", names.join(", "))
    })
}

/// `cloth scenes`.
pub fn scenes(args: &ScenesArgs) -> ExitCode {
    match &args.print {
        Some(name) => match scene::builtin_source(name) {
            Some(src) => {
                out!("{src}");
                ExitCode::SUCCESS
            }
            None => {
                let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
                eprintln!(
                    "error: unknown scene `{name}`: allowed {}",
                    names.join(", ")
                );
                ExitCode::from(EXIT_BAD_INPUT)
            }
        },
        None => {
            for (name, _) in BUILTIN {
                let s = scene::builtin(name).expect("built-in scenes are valid");
                outln!("{name:<16} {}", s.description);
            }
            ExitCode::SUCCESS
        }
    }
}

/// Bytes of memory available, from /proc/meminfo (Linux); `None` elsewhere.
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb.saturating_mul(1024))
}

/// The environment variable that caps the memory `cloth sim`, `check`, `render` and `view`
/// plan for (below what /proc/meminfo says is available), e.g. `CLOTH_MEMORY_LIMIT=4GiB` on a
/// shared machine.
pub const MEMORY_LIMIT_VAR: &str = "CLOTH_MEMORY_LIMIT";

/// A size in bytes: a whole number, optionally followed by `KiB`, `MiB` or `GiB`
/// (`512MiB`, `4GiB`, `1048576`). `None` for anything else, zero, or 2⁶⁴ bytes or more.
fn parse_size(text: &str) -> Option<u64> {
    let t = text.trim();
    let (digits, unit) = match t.find(|c: char| !c.is_ascii_digit()) {
        Some(i) => t.split_at(i),
        None => (t, ""),
    };
    let scale: u64 = match unit.trim() {
        "" => 1,
        "KiB" => 1 << 10,
        "MiB" => 1 << 20,
        "GiB" => 1 << 30,
        _ => return None,
    };
    let n: u64 = digits.parse().ok()?;
    n.checked_mul(scale).filter(|&b| b > 0)
}

/// The memory a scene may use: the smaller of /proc/meminfo's `MemAvailable` and
/// [`MEMORY_LIMIT_VAR`], with the limit's source for messages (`None` when neither is known).
fn memory_budget() -> Result<Option<(u64, &'static str)>, String> {
    let limit = match std::env::var_os(MEMORY_LIMIT_VAR) {
        // Unset, or set empty (`CLOTH_MEMORY_LIMIT= cloth sim ...`): no limit.
        None => None,
        Some(v) if v.is_empty() => None,
        Some(v) => Some(v.to_str().and_then(parse_size).ok_or_else(|| {
            format!(
                "{MEMORY_LIMIT_VAR}={}: expected a size in bytes > 0, as a whole number \
                 optionally followed by KiB, MiB or GiB (e.g. 4GiB)",
                v.to_string_lossy()
            )
        })?),
    };
    Ok(match (available_memory(), limit) {
        (Some(avail), Some(lim)) if lim < avail => Some((lim, MEMORY_LIMIT_VAR)),
        (Some(avail), _) => Some((avail, "available")),
        (None, Some(lim)) => Some((lim, MEMORY_LIMIT_VAR)),
        (None, None) => None,
    })
}

fn summary(scene: &Scene) -> String {
    let (particles, springs) = scene.counts();
    let mem = scene.memory_estimate();
    format!(
        "scene {} {}x{} particles={} springs={} integrator={} memory≈{:.1} MiB",
        scene.name,
        scene.cloth.resolution[0],
        scene.cloth.resolution[1],
        particles,
        springs,
        scene.integrator().name(),
        mem as f64 / (1024.0 * 1024.0)
    )
}

/// A size in bytes as three significant digits of the largest binary unit it fills
/// ("36.0 GiB", "144 MiB", "1.17 MiB", "512 B"): a scene's need and the bound it exceeds
/// never print as the same figure unless they are within 1 % of each other.
fn size_text(bytes: u64) -> String {
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit < 3 {
        value /= 1024.0;
        unit += 1;
    }
    let name = ["B", "KiB", "MiB", "GiB"][unit];
    if unit == 0 {
        format!("{bytes} B")
    } else if value < 10.0 {
        format!("{value:.2} {name}")
    } else if value < 100.0 {
        format!("{value:.1} {name}")
    } else {
        format!("{value:.0} {name}")
    }
}

/// Refuses a scene whose memory estimate exceeds the memory available or
/// [`MEMORY_LIMIT_VAR`], unless `force` (`cloth sim`, `check`, `render` and `view` call it
/// before building, which would take the memory): the error is the message to print. A
/// malformed limit is refused even with `force`; a scene fits when neither bound is known.
pub fn memory_gate(scene: &Scene, force: bool) -> Result<(), String> {
    let (particles, _) = scene.counts();
    let mem = scene.memory_estimate();
    let Some((budget, source)) = memory_budget()? else {
        return Ok(());
    };
    if force || mem <= budget {
        return Ok(());
    }
    Err({
        let what = if source == MEMORY_LIMIT_VAR {
            format!("the {} {MEMORY_LIMIT_VAR} allows", size_text(budget))
        } else {
            format!("the {} available", size_text(budget))
        };
        format!(
            "this scene needs about {} ({particles} particles), more than {what}; \
             lower cloth.resolution or pass --force",
            size_text(mem)
        )
    })
}

/// `cloth check`.
pub fn check(args: &CheckArgs) -> ExitCode {
    let overrides = args.shorthands.overrides(&args.set);
    let scene = match scene::load(&args.scene, &overrides) {
        Ok((s, _)) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    if let Err(refusal) = memory_gate(&scene, args.force) {
        eprintln!("error: {refusal}");
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let sim = match scene.build() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {}: {e}", args.scene);
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    let cfg = sim.config();
    let limit = explicit_stability_limit_of(cfg, sim.topology(), sim.particles());
    outln!("{}", summary(&scene));
    // The estimate underflows f32 (zero) for an absurd stiffness or a feather-light cloth.
    let stable = stable_substep_text(limit);
    let needed_text = if limit > 0.0 {
        substeps_text(f64::from(cfg.dt) / f64::from(limit))
    } else {
        "more than 1e38".to_string()
    };
    outln!(
        "dt={} s substeps={} (substep {:.3e} s); estimated stable substep for the explicit integrators: {stable} ({needed_text} substeps per step)",
        cfg.dt,
        cfg.substeps,
        cfg.substep_dt(),
    );
    // An explicit integrator far over its stability bound will blow up: say so before a
    // run. The bound is a sufficient one (Gershgorin's), up to about 1.5× below the true
    // limit on a grid (peer-ball runs at 1.44× it), so only twice over it is flagged.
    let ratio = f64::from(cfg.substep_dt()) / f64::from(limit);
    let over = cfg.integrator.is_explicit() && ratio > 2.0;
    if over {
        let ratio_text = if ratio < 1e6 {
            format!("{ratio:.1}× the estimated stable {stable}")
        } else if ratio.is_finite() {
            format!("{ratio:.1e}× the estimated stable {stable}")
        } else {
            format!("far over the estimated stable substep ({stable})")
        };
        eprintln!(
            "warning: {} will likely go unstable: its substep {:.3e} s is {ratio_text}; raise \
             `solver.substeps` to {needed_text} (at most {} are allowed), lower the stiffness \
             or the damping, or use xpbd or implicit-euler",
            cfg.integrator.name(),
            cfg.substep_dt(),
            cloth_core::config::MAX_SUBSTEPS
        );
    }
    outln!(
        "colliders={} duration={} s: {}",
        sim.colliders().len(),
        scene.duration,
        if over { "ok, with a warning" } else { "ok" }
    );
    ExitCode::SUCCESS
}

/// One frame of the report.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct FrameRecord {
    frame: u64,
    time: f64,
    kinetic_energy: f64,
    potential_energy: f64,
    spring_energy: f64,
    max_strain: Strain,
    max_penetration: f32,
    contacts: u32,
    #[serde(default)]
    ccd_corrections: u32,
    /// Intersecting triangle pairs (exact count); only with self-collision on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    self_intersections: Option<u32>,
    /// Smallest particle–non-neighbour-triangle distance within the self-collision
    /// thickness, m (null: none that close); only with self-collision on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    min_self_distance: Option<Option<f32>>,
    solver_iterations: u32,
    solver_residual: f32,
    solver_converged: bool,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Strain {
    structural: f32,
    shear: f32,
    bend: f32,
}

impl FrameRecord {
    fn new(frame: u64, s: &StepStats) -> Self {
        Self {
            frame,
            time: s.time,
            kinetic_energy: s.kinetic_energy,
            potential_energy: s.gravitational_energy,
            spring_energy: s.spring_energy,
            max_strain: Strain {
                structural: s.strain(SpringClass::Structural),
                shear: s.strain(SpringClass::Shear),
                bend: s.strain(SpringClass::Bend),
            },
            max_penetration: s.max_penetration,
            contacts: s.contacts,
            ccd_corrections: s.ccd_corrections,
            self_intersections: None,
            min_self_distance: None,
            solver_iterations: s.solver.iterations,
            solver_residual: s.solver.residual,
            solver_converged: s.solver.converged,
        }
    }
}

/// A checkpoint: the resolved scene, the state and what the run has produced so far.
#[derive(Debug, Serialize, Deserialize)]
struct Checkpoint {
    format: String,
    scene_toml: String,
    frames_done: u64,
    sim_wall_seconds: f64,
    state: SimState,
    records: Vec<FrameRecord>,
    glb: GlbFrames,
}

const CHECKPOINT_FORMAT: &str = "cloth-checkpoint-1";

/// How a run ended.
enum Status {
    Ok,
    /// `step`: the failed step's index from the start of the run (0-based: the frames done
    /// before it); it failed computing frame `step + 1`, from the state at `time`.
    Unstable {
        step: u64,
        time: f64,
        reason: String,
    },
    Interrupted,
}

/// `cloth sim`.
pub fn sim(args: &SimArgs) -> ExitCode {
    match run(args) {
        Ok(code) => code,
        Err(e) => {
            let bad_input = e.downcast_ref::<BadInput>().is_some();
            eprintln!("error: {e:#}");
            ExitCode::from(if bad_input { EXIT_BAD_INPUT } else { 1 })
        }
    }
}

/// An error in what the user gave (exit status 2).
#[derive(Debug)]
struct BadInput(String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

fn bad(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(BadInput(msg.into()))
}

fn check_writable_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        bad(format!(
            "the output folder {} cannot be created: {e}",
            dir.display()
        ))
    })?;
    let probe = dir.join(".cloth-write-test");
    std::fs::write(&probe, b"ok").map_err(|e| {
        bad(format!(
            "the output folder {} is not writable: {e}",
            dir.display()
        ))
    })?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

pub(crate) fn check_writable_file(path: &Path, what: &str) -> Result<()> {
    // A device or a FIFO is written in place (its folder need not take new files), a link's
    // target replaced (its folder must take them).
    let (target, special) = crate::export::write_target(path);
    if special {
        return Ok(());
    }
    let path = target.as_path();
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(bad(format!(
            "the {what} folder {} does not exist",
            dir.display()
        )));
    }
    if path.is_dir() {
        return Err(bad(format!(
            "the {what} {} is a folder: allowed a file name (a file there is replaced)",
            path.display()
        )));
    }
    let probe = dir.join(".cloth-write-test");
    std::fs::write(&probe, b"ok").map_err(|e| {
        bad(format!(
            "the {what} {} cannot be written: {e}",
            path.display()
        ))
    })?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

/// Refuses a run whose `--out` folder holds a folder where the run writes a file (`wanted`
/// says which names it writes): its write would fail after the work is done.
fn check_no_folder_in_the_way(dir: &Path, wanted: impl Fn(&str) -> bool) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| {
        bad(format!(
            "the output folder {} cannot be read: {e}",
            dir.display()
        ))
    })?;
    for entry in entries.flatten() {
        let name = entry.file_name();
        if let Some(name) = name.to_str()
            && wanted(name)
            && entry.path().is_dir()
        {
            return Err(bad(format!(
                "--out: {} is a folder, where this run would write a file; remove or rename it",
                entry.path().display()
            )));
        }
    }
    Ok(())
}

/// The OBJ file of frame `n`: `frame_0001.obj`, … (more digits past 9999).
fn obj_name(n: u64) -> String {
    format!("frame_{n:04}.obj")
}

/// The frames `cloth sim` exports into `--out`: OBJ files written as they come, glb frames
/// collected for one file at the end.
struct Export {
    /// `--out`; `None`: nothing is exported.
    dir: Option<PathBuf>,
    /// `--format` has `obj` (used only with `dir`).
    obj: bool,
    /// `--format` has `glb` (used only with `dir`).
    glb_wanted: bool,
    uvs: Vec<[f32; 2]>,
    normals: Vec<cloth_core::glam::Vec3>,
    /// The glb's frames so far (from the checkpoint when resumed).
    glb: GlbFrames,
    /// The frame exported last, so that none is exported twice.
    last: Option<u64>,
}

impl Export {
    /// Exports `sim`'s state as frame `frame` at time `time`, unless it was already.
    fn frame(&mut self, sim: &Simulation, frame: u64, time: f64) -> Result<()> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        if self.last == Some(frame) {
            return Ok(());
        }
        self.last = Some(frame);
        let pos = &sim.particles().position;
        if self.obj {
            sim.topology().vertex_normals(pos, &mut self.normals);
            let text = obj(
                pos,
                &self.normals,
                &self.uvs,
                sim.topology(),
                &format!("cloth frame {frame}, t = {time:.6} s"),
            );
            write_atomic(&dir.join(obj_name(frame)), text.as_bytes())?;
        }
        if self.glb_wanted {
            self.glb.push(time as f32, pos);
        }
        Ok(())
    }

    /// Writes the glb of the frames collected, if any.
    fn finish(&self, sim: &Simulation) -> Result<()> {
        if let Some(dir) = &self.dir
            && self.glb_wanted
            && !self.glb.positions.is_empty()
        {
            let bytes = self.glb.to_glb(sim.topology(), &self.uvs)?;
            write_atomic(&dir.join("cloth.glb"), &bytes)?;
        }
        Ok(())
    }
}

/// Runs the simulation on a pool of `--threads` worker threads.
fn run(args: &SimArgs) -> Result<ExitCode> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build()
        .context("starting the worker threads")?;
    pool.install(|| {
        // The kernel choice is per thread: made on the pool's thread that steps.
        cloth_core::simd::set_kernel(args.kernel)?;
        run_on_pool(args)
    })
}

/// The scene `cloth sim` runs: the SCENE argument, or the drape.
fn scene_name(args: &SimArgs) -> &str {
    args.scene.as_deref().unwrap_or("drape")
}

fn run_on_pool(args: &SimArgs) -> Result<ExitCode> {
    // 1. The scene: from a checkpoint, or from the file/built-in with overrides.
    let overrides = args.shorthands.overrides(&args.set);
    let checkpoint: Option<Checkpoint> = match &args.resume {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| {
                bad(format!(
                    "cannot read the checkpoint {}: {e}",
                    path.display()
                ))
            })?;
            let cp: Checkpoint = serde_json::from_str(&text)
                .map_err(|e| bad(format!("{} is not a cloth checkpoint: {e}", path.display())))?;
            if cp.format != CHECKPOINT_FORMAT {
                return Err(bad(format!(
                    "{} is a checkpoint of format {:?}; this cloth reads {CHECKPOINT_FORMAT:?}",
                    path.display(),
                    cp.format
                )));
            }
            Some(cp)
        }
        None => None,
    };
    let scene = match &checkpoint {
        Some(cp) => {
            let saved =
                Scene::from_toml(&cp.scene_toml, "checkpoint").map_err(|e| bad(e.to_string()))?;
            // The command line may repeat the original run's scene and overrides, but not
            // change them: a checkpoint continues its own scene, nothing is silently dropped.
            if args.scene.is_some() || !overrides.is_empty() {
                let given = match &args.scene {
                    Some(name) => scene::load(name, &overrides).map(|(s, _)| s),
                    None => {
                        Scene::from_toml_with_overrides(&cp.scene_toml, "checkpoint", &overrides)
                    }
                }
                .map_err(|e| bad(e.to_string()))?;
                if given.to_toml() != saved.to_toml() {
                    return Err(bad(format!(
                        "--resume continues the checkpoint's own scene (`{}`), and the scene \
                         given by SCENE, --set, --resolution or --integrator differs from it; \
                         drop them to continue, or start a new run without --resume",
                        saved.name
                    )));
                }
            }
            saved
        }
        None => {
            scene::load(scene_name(args), &overrides)
                .map_err(|e| bad(e.to_string()))?
                .0
        }
    };
    let (particles, springs) = scene.counts();
    memory_gate(&scene, args.force).map_err(bad)?;
    // 2. Outputs are checked before simulating.
    if let Some(dir) = &args.out {
        check_writable_dir(dir)?;
    }
    if let Some(report) = &args.report {
        check_writable_file(report, "report")?;
    }
    let checkpoint_path = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("."))
        .join("checkpoint.json");

    let mut sim = scene
        .build()
        .map_err(|e| bad(format!("{}: {e}", scene_name(args))))?;
    let cfg = *sim.config();
    let frames_total = match (args.frames, args.seconds) {
        (Some(f), _) => f,
        (None, Some(s)) => (s / f64::from(cfg.dt)).ceil() as u64,
        (None, None) => (f64::from(scene.duration) / f64::from(cfg.dt)).ceil() as u64,
    }
    .max(1);
    let (mut records, mut glb, mut frame, mut stepping) =
        (Vec::new(), GlbFrames::default(), 0u64, 0.0f64);
    if let Some(cp) = checkpoint {
        if cp.frames_done >= frames_total {
            return Err(bad(format!(
                "the checkpoint is at frame {} already, and this run asks for {frames_total} \
                 frames in all (--frames and --seconds count from the start of the run): \
                 nothing is left to run; ask for more than {} frames",
                cp.frames_done, cp.frames_done
            )));
        }
        sim.restore(&cp.state)
            .map_err(|e| bad(format!("checkpoint: {e}")))?;
        records = cp.records;
        glb = cp.glb;
        frame = cp.frames_done;
        stepping = cp.sim_wall_seconds;
    }
    let (rows, cols) = sim.grid_size();
    let mut export = Export {
        dir: args.out.clone(),
        obj: args.format.contains(&Format::Obj),
        glb_wanted: args.format.contains(&Format::Glb),
        uvs: grid_uvs(rows, cols),
        normals: Vec::new(),
        glb,
        // A resumed run's checkpoint frame was exported by the run that saved it if it was
        // one of the K-th (a checkpoint is never saved at the last frame).
        last: (frame > 0 && frame.is_multiple_of(args.every)).then_some(frame),
    };
    // A folder where the run would write a file would fail it at the end: refused now.
    let exported = |n: u64| {
        n > frame && n <= frames_total && (n.is_multiple_of(args.every) || n == frames_total)
    };
    if let Some(dir) = &args.out {
        check_no_folder_in_the_way(dir, |name| {
            (export.glb_wanted && name == "cloth.glb")
                || (export.obj
                    && name
                        .strip_prefix("frame_")
                        .and_then(|n| n.strip_suffix(".obj"))
                        .and_then(|n| n.parse::<u64>().ok())
                        .is_some_and(|n| exported(n) && name == obj_name(n)))
        })?;
    }
    if args.checkpoint_every.is_some() && checkpoint_path.is_dir() {
        return Err(bad(format!(
            "--checkpoint-every: {} is a folder, where the checkpoint would be written",
            checkpoint_path.display()
        )));
    }

    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
    }
    outln!(
        "{} dt={} s substeps={}",
        summary(&scene),
        cfg.dt,
        cfg.substeps
    );
    if args.table_every > 0 {
        outln!(
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
    }
    let progress = if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new(frames_total);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} frames  {msg}")
                .expect("valid template"),
        );
        bar.set_position(frame);
        Some(bar)
    } else {
        None
    };

    let mut status = Status::Ok;
    let mut max_self_intersections = records
        .iter()
        .filter_map(|r| r.self_intersections)
        .max()
        .unwrap_or(0);
    let wall_start = Instant::now();
    // Wall time of each frame's step (this run's frames only), for the median-frame figure.
    let mut frame_wall = Vec::new();
    while frame < frames_total {
        if interrupted.load(Ordering::SeqCst) {
            status = Status::Interrupted;
            break;
        }
        let t0 = Instant::now();
        let result = sim.step();
        let wall = t0.elapsed().as_secs_f64();
        let stats = match result {
            Ok(s) => {
                // The frames done only: a failed step is undone, so it is no work done.
                stepping += wall;
                frame_wall.push(wall);
                s
            }
            Err(ClothError::Unstable {
                step,
                time,
                reason,
                hint,
                particle,
            }) => {
                status = Status::Unstable {
                    step,
                    time,
                    reason: format!("particle {particle}: {reason}; likely cause: {hint}"),
                };
                break;
            }
            Err(e) => return Err(e.into()),
        };
        frame += 1;
        let mut record = FrameRecord::new(frame, &stats);
        if cfg.self_collision.is_some() {
            // Outside the stepping time: a diagnostic of the frame, not part of the step.
            let contact = sim.self_contact(None)?;
            record.self_intersections = Some(contact.self_intersections);
            record.min_self_distance = Some(
                contact
                    .min_distance
                    .is_finite()
                    .then_some(contact.min_distance),
            );
            max_self_intersections = max_self_intersections.max(contact.self_intersections);
        }
        records.push(record);
        if args.table_every > 0 && (frame % args.table_every == 0 || frame == frames_total) {
            let line = format!(
                "{:>6} {:>8.3} {:>12.5e} {:>12.5e} {:>10.4} {:>10.4} {:>10.4} {:>9.2e} {:>8}",
                frame,
                stats.time,
                stats.total_energy(),
                stats.kinetic_energy,
                stats.strain(SpringClass::Structural),
                stats.strain(SpringClass::Shear),
                stats.strain(SpringClass::Bend),
                stats.max_penetration,
                stats.contacts
            );
            match &progress {
                Some(bar) => bar.println(line),
                None => outln!("{line}"),
            }
        }
        // (The last frame is exported after the loop, however the run ends.)
        if frame.is_multiple_of(args.every) {
            export.frame(&sim, frame, stats.time)?;
        }
        if let Some(every) = args.checkpoint_every
            && frame % every == 0
            && frame < frames_total
        {
            let cp = Checkpoint {
                format: CHECKPOINT_FORMAT.into(),
                scene_toml: scene.to_toml(),
                frames_done: frame,
                sim_wall_seconds: stepping,
                state: sim.state(),
                records: records.clone(),
                glb: export.glb.clone(),
            };
            write_atomic(&checkpoint_path, &serde_json::to_vec(&cp)?)?;
        }
        if let Some(bar) = &progress {
            bar.set_position(frame);
            let simulated = stats.time;
            let speed = simulated / wall_start.elapsed().as_secs_f64().max(1e-9);
            bar.set_message(format!("t = {simulated:.2} s, {speed:.2}× real time"));
        }
    }
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    // A run that stopped early (unstable: the state is the last good frame's; interrupted)
    // exports its last frame too.
    if frame > 0 {
        export.frame(&sim, frame, sim.time())?;
    }
    export.finish(&sim)?;

    let kernel = cloth_core::simd::kernel_for(&sim);
    let substeps_done = records.len() as f64 * f64::from(cfg.substeps);
    // `None` (null in the report, "n/a" in the summary) when no frame was done: no figure
    // is made up for work that did not happen.
    let throughput = (!records.is_empty() && stepping > 0.0)
        .then(|| particles as f64 * substeps_done / stepping);
    // Throughput of the median frame of this run: robust against the odd slow frame on a
    // busy machine (the figure the peer benchmark scripts quote too).
    frame_wall.sort_by(f64::total_cmp);
    let median_frame = frame_wall
        .get(frame_wall.len() / 2)
        .copied()
        .filter(|&t| t > 0.0);
    let median_throughput = median_frame.map(|t| particles as f64 * f64::from(cfg.substeps) / t);
    let (status_json, code, status_line) = match &status {
        Status::Ok => (serde_json::json!("ok"), ExitCode::SUCCESS, "ok".to_string()),
        Status::Unstable { step, time, reason } => (
            serde_json::json!({ "unstable": {
                "step": step,
                "frame": step.saturating_add(1),
                "time": time,
                "reason": reason
            } }),
            ExitCode::from(EXIT_UNSTABLE),
            format!(
                "unstable in frame {} (step index {step}, from t = {time:.6} s): {reason}",
                step.saturating_add(1)
            ),
        ),
        Status::Interrupted => (
            serde_json::json!("interrupted"),
            ExitCode::from(EXIT_INTERRUPTED),
            "interrupted".to_string(),
        ),
    };
    // Structural and shear strain of the final state: median, 99th and 99.9th percentiles,
    // maximum; `None` for a class the cloth has no spring of. (The shear diagonals show a
    // cloth whose cells collapsed in shear, a "fishnet", which the structural strain alone
    // does not.)
    let quantiles = |class| {
        cloth_core::diagnostics::strain_quantiles(
            sim.topology(),
            &sim.particles().position,
            class,
            &[0.5, 0.99, 0.999, 1.0],
        )
    };
    let strains = [
        ("structural", quantiles(SpringClass::Structural)),
        ("shear", quantiles(SpringClass::Shear)),
    ];
    let json = |q: &Option<Vec<f32>>| {
        q.as_ref()
            .map(|q| serde_json::json!({ "p50": q[0], "p99": q[1], "p99_9": q[2], "max": q[3] }))
    };
    let capped = CappedSolves::of(&records);
    if let Some(path) = &args.report {
        let report = serde_json::json!({
            "format": "cloth-report-1",
            "scene": scene.to_toml(),
            "versions": { "cloth": env!("CARGO_PKG_VERSION") },
            "host": host(),
            "threads": args.threads,
            "kernel": kernel.name(),
            "particles": particles,
            "springs": springs,
            "integrator": cfg.integrator.name(),
            "dt": cfg.dt,
            "substeps": cfg.substeps,
            "frames": records,
            "sim_wall_seconds": stepping,
            "particle_substeps_per_second": throughput,
            "median_frame_ms": median_frame.map(|t| 1e3 * t),
            "median_frame_particle_substeps_per_second": median_throughput,
            "status": status_json,
            "solver_unconverged_frames": capped.as_ref().map_or(0, |c| c.frames),
            "final_structural_strain": json(&strains[0].1),
            "final_shear_strain": json(&strains[1].1),
        });
        write_atomic(path, &serde_json::to_vec_pretty(&report)?)
            .with_context(|| format!("writing the report {}", path.display()))?;
    }
    let figure = |x: Option<f64>, text: &dyn Fn(f64) -> String| x.map_or("n/a".into(), text);
    outln!(
        "done: {} frames, status {status_line}, {:.3} s stepping, {} ms/frame, {} particle-substeps/s (median frame {}; {} thread{}, kernel {})",
        records.len(),
        stepping,
        figure(
            (!records.is_empty()).then(|| 1e3 * stepping / records.len() as f64),
            &|x| format!("{x:.2}")
        ),
        figure(throughput, &|x| format!("{x:.3e}")),
        figure(median_throughput, &|x| format!("{x:.3e}")),
        args.threads,
        if args.threads == 1 { "" } else { "s" },
        kernel.name()
    );
    for (name, q) in &strains {
        if let Some(q) = q {
            outln!(
                "{name} strain at the end: median {:.3}%, p99 {:.3}%, p99.9 {:.3}%, max {:.3}%",
                100.0 * q[0],
                100.0 * q[1],
                100.0 * q[2],
                100.0 * q[3]
            );
        }
    }
    if cfg.self_collision.is_some() {
        outln!(
            "self-contact: at most {max_self_intersections} intersecting triangle pairs in a frame"
        );
    }
    if let Some(capped) = &capped {
        eprintln!("{}", capped.warning(records.len(), &cfg));
    }
    if let Status::Unstable { .. } = status {
        eprintln!("error: the simulation became unstable: {status_line}");
    }
    Ok(code)
}

/// The frames of a run in which implicit Euler's linear solve stopped at its iteration cap
/// before reaching its tolerance (`frames[].solver_converged` false). Those steps were taken,
/// but less accurately than the tolerance asks (at one substep per frame the CG reaches its
/// cap of 200 while the `drape` lands, and the landing's strain peaks higher than with the
/// solve converged), so the report counts them and the run warns.
struct CappedSolves {
    /// How many frames.
    frames: usize,
    /// The first of them.
    first: u64,
    /// The largest final residual among them.
    residual: f32,
}

impl CappedSolves {
    /// `None` when every frame's solve converged.
    fn of(records: &[FrameRecord]) -> Option<Self> {
        let mut capped = records.iter().filter(|r| !r.solver_converged);
        let first = capped.next()?;
        let mut out = Self {
            frames: 1,
            first: first.frame,
            residual: first.solver_residual,
        };
        for r in capped {
            out.frames += 1;
            out.residual = out.residual.max(r.solver_residual);
        }
        Some(out)
    }

    /// The warning: the cap, how many of the run's `total` frames, the first, the largest
    /// residual and what to raise.
    fn warning(&self, total: usize, cfg: &SimConfig) -> String {
        format!(
            "warning: implicit Euler's linear solve stopped at its cap of {} CG iterations \
             before its tolerance {:e} in {} of {total} frames (the first: frame {}; largest \
             residual {:.2e}): those steps are approximate; raise \
             solver.implicit.max_iterations (1 ..= 4294967295) or solver.substeps",
            cfg.implicit.max_iterations,
            cfg.implicit.tolerance,
            self.frames,
            self.first,
            self.residual,
        )
    }
}

/// The machine a run's timings come from: the CPU's model name (from `/proc/cpuinfo`; `null`
/// where the system has none) and the logical CPUs the process may use. Timings differ by 2×
/// between hosts of the same core count, so a report says which one it was measured on.
fn host() -> serde_json::Value {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find_map(|line| line.strip_prefix("model name")?.split_once(':'))
                .map(|(_, name)| name.trim().to_owned())
        });
    serde_json::json!({ "cpu": cpu, "logical_cpus": logical_cpus() })
}
