//! `cloth sim`, `cloth scenes` and `cloth check` end to end: built-in scenes run headless,
//! exports parse back with independent parsers (tobj, gltf), the report has its documented
//! fields, a resumed run ends bit-identical to an uninterrupted one, and every kind of bad input
//! exits with status 2 and one message naming the file, line, column and key.

use std::path::Path;
use std::process::Command;

fn cloth(args: &[&str]) -> (i32, String, String) {
    cloth_env(args, &[])
}

/// `cloth` with environment variables set (e.g. `CLOTH_MEMORY_LIMIT`).
fn cloth_env(args: &[&str], vars: &[(&str, &str)]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args(args)
        .envs(vars.iter().copied())
        .output()
        .expect("run cloth");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A fresh directory for one test's files, removed when the returned guard drops.
fn tmp(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("cloth-sim-test-{name}-"))
        .tempdir()
        .expect("temp dir")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn report(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).expect("report")).expect("report is JSON")
}

/// The first mesh of an OBJ file, parsed by tobj (polygons kept; `single_index`: one index
/// per vertex, positions and texture coordinates aligned).
fn obj_mesh(path: &Path, single_index: bool) -> tobj::Mesh {
    let (mut models, _) = tobj::load_obj(
        path,
        &tobj::LoadOptions {
            single_index,
            triangulate: false,
            ..Default::default()
        },
    )
    .expect("tobj parses it");
    models.swap_remove(0).mesh
}

/// Every built-in scene runs headless for 2 s of simulated time with status "ok".
#[test]
fn every_builtin_scene_runs_ok() {
    let (code, list, _) = cloth(&["scenes"]);
    assert_eq!(code, 0);
    let names: Vec<&str> = list
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert!(names.len() >= 9, "{list}");
    for name in ["drape", "hanging", "flag", "peer-ball", "table"] {
        assert!(names.contains(&name), "{name} missing from {list}");
    }
    let guard = tmp("builtin");
    let dir = guard.path();
    for name in names {
        let rep = dir.join(format!("{name}.json"));
        let (code, out, err) = cloth(&[
            "sim",
            name,
            "--seconds",
            "2",
            "--table-every",
            "0",
            "--report",
            s(&rep),
        ]);
        assert_eq!(code, 0, "{name}: {out}\n{err}");
        let r = report(&rep);
        assert_eq!(r["status"], "ok", "{name}");
        let (_, toml, _) = cloth(&["scenes", "--print", name]);
        assert!(toml.contains("[cloth]"), "{name}");
    }
}

/// OBJ frames parse with `tobj` and glb with `gltf` (an importer that validates the file):
/// vertex and face counts match the cloth, normals are unit length, the animation has one
/// morph target per exported frame.
#[test]
fn exports_parse_with_independent_parsers() {
    let guard = tmp("export");
    let dir = guard.path();
    let out = dir.join("out");
    let (code, _, err) = cloth(&[
        "sim",
        "drape",
        "--frames",
        "12",
        "--resolution",
        "10",
        "--out",
        s(&out),
        "--format",
        "obj,glb",
        "--every",
        "4",
    ]);
    assert_eq!(code, 0, "{err}");
    let mut objs: Vec<_> = std::fs::read_dir(&out)
        .expect("out")
        .filter_map(|e| e.ok().map(|e| e.file_name().into_string().expect("name")))
        .filter(|n| n.ends_with(".obj"))
        .collect();
    objs.sort();
    assert_eq!(objs, ["frame_0004.obj", "frame_0008.obj", "frame_0012.obj"]);
    let frame = &obj_mesh(&out.join("frame_0012.obj"), false);
    assert_eq!(frame.positions.len(), 100 * 3);
    assert_eq!(frame.normals.len(), 100 * 3);
    assert_eq!(frame.texcoords.len(), 100 * 2);
    assert_eq!(frame.indices.len(), 2 * 9 * 9 * 3);
    for n in frame.normals.chunks(3) {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "normal length {len}");
    }
    assert!(!out.read_dir().expect("out").any(|e| {
        e.expect("entry")
            .file_name()
            .to_string_lossy()
            .ends_with(".tmp")
    }));

    let (doc, buffers, _) = gltf::import(out.join("cloth.glb")).expect("gltf imports it");
    let mesh = doc.meshes().next().expect("a mesh");
    let prim = mesh.primitives().next().expect("a primitive");
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    assert_eq!(reader.read_positions().expect("positions").count(), 100);
    assert_eq!(
        reader.read_indices().expect("indices").into_u32().count(),
        2 * 9 * 9 * 3
    );
    assert_eq!(prim.morph_targets().count(), 3);
    let anim = doc.animations().next().expect("an animation");
    assert_eq!(anim.channels().count(), 1);
    // The last target moves the base mesh to the last OBJ frame (compared as sorted vertex
    // sets: tobj may renumber vertices).
    let base: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
    let last = reader
        .read_morph_targets()
        .last()
        .expect("targets")
        .0
        .expect("positions");
    let mut moved: Vec<[f32; 3]> = base
        .iter()
        .zip(last)
        .map(|(b, d)| [b[0] + d[0], b[1] + d[1], b[2] + d[2]])
        .collect();
    let mut obj: Vec<[f32; 3]> = frame
        .positions
        .chunks(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    let key = |a: &[f32; 3], b: &[f32; 3]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    };
    moved.sort_by(key);
    obj.sort_by(key);
    for (m, o) in moved.iter().zip(&obj) {
        for k in 0..3 {
            assert!((m[k] - o[k]).abs() < 1e-5, "{m:?} != {o:?}");
        }
    }
}

/// Without `--threads` a run uses the logical CPUs the process may use (at most 256), and its
/// results are the bits of a one-thread run: the same positions in the last OBJ frame, byte
/// for byte (the run report's `threads` says which count ran).
#[test]
fn the_default_thread_count_is_the_machines_and_changes_no_bit() {
    let guard = tmp("default-threads");
    let dir = guard.path();
    let expected = std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .min(256);
    let mut frames = Vec::new();
    for threads in [None, Some("1")] {
        let out = dir.join(threads.unwrap_or("default"));
        let rep = out.join("r.json");
        let mut args = vec![
            "sim",
            "peer-ball",
            "--frames",
            "3",
            "--resolution",
            "40",
            "--out",
            s(&out),
            "--report",
            s(&rep),
        ];
        if let Some(t) = threads {
            args.extend(["--threads", t]);
        }
        let (code, _, err) = cloth(&args);
        assert_eq!(code, 0, "{err}");
        let r = report(&rep);
        let ran = threads.map_or(expected, |t| t.parse().expect("a count"));
        assert_eq!(r["threads"], ran);
        frames.push(std::fs::read(out.join("frame_0003.obj")).expect("last frame"));
    }
    assert!(
        frames[0] == frames[1],
        "the default run differs from one thread's"
    );
}

/// The report holds its documented fields (docs/scenes.md, "Run report").
#[test]
fn report_has_its_documented_fields() {
    let guard = tmp("report");
    let dir = guard.path();
    let rep = dir.join("r.json");
    let (code, _, err) = cloth(&[
        "sim",
        "drape",
        "--frames",
        "5",
        "--resolution",
        "8",
        "--integrator",
        "implicit-euler",
        "--report",
        s(&rep),
        "--threads",
        "2",
    ]);
    assert_eq!(code, 0, "{err}");
    let r = report(&rep);
    for key in [
        "scene",
        "versions",
        "host",
        "threads",
        "particles",
        "springs",
        "integrator",
        "dt",
        "substeps",
        "frames",
        "sim_wall_seconds",
        "particle_substeps_per_second",
        "median_frame_ms",
        "median_frame_particle_substeps_per_second",
        "kernel",
        "final_structural_strain",
        "final_shear_strain",
        "solver_unconverged_frames",
        "status",
    ] {
        assert!(!r[key].is_null(), "missing {key}");
    }
    assert_eq!(r["threads"], 2);
    assert_eq!(r["particles"], 64);
    assert_eq!(r["integrator"], "implicit-euler");
    // The host: the CPU's model as `/proc/cpuinfo` names it (x86 Linux, as in CI), `null`
    // where no such line exists (other systems, ARM Linux); at least one logical CPU.
    let named = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("model name"))?;
            Some(line[line.find(':')? + 1..].trim().to_owned())
        });
    match named {
        Some(name) => {
            assert!(!name.is_empty(), "an empty model name in /proc/cpuinfo");
            assert_eq!(r["host"]["cpu"], name.as_str());
        }
        None => assert!(r["host"]["cpu"].is_null(), "host.cpu: {}", r["host"]["cpu"]),
    }
    assert!(r["host"]["logical_cpus"].as_u64().is_some_and(|n| n >= 1));
    let frames = r["frames"].as_array().expect("frames");
    assert_eq!(frames.len(), 5);
    for key in [
        "frame",
        "time",
        "kinetic_energy",
        "potential_energy",
        "spring_energy",
        "max_strain",
        "max_penetration",
        "contacts",
        "solver_iterations",
        "solver_residual",
        "solver_converged",
    ] {
        assert!(!frames[4][key].is_null(), "missing frames[].{key}");
    }
    assert!(frames[4]["solver_iterations"].as_u64().expect("iterations") >= 1);
    assert!(
        r["scene"]
            .as_str()
            .expect("scene")
            .contains("kind = \"implicit-euler\"")
    );
}

/// A run in which implicit Euler's CG stops at its iteration cap says so: with a cap of 2
/// iterations the 24² drape's solves in contact do not reach the tolerance, and the run (exit
/// 0: the steps are taken) warns on standard error with the cap, the count of such frames, the
/// first one and the key to raise; the report's `solver_unconverged_frames` is that count, the
/// number of `frames[]` whose `solver_converged` is false. With the default cap (200) every
/// solve converges: no warning, and 0.
#[test]
fn a_capped_linear_solve_is_reported() {
    let guard = tmp("capped");
    let rep = guard.path().join("r.json");
    let run = |cap: &str| {
        let (code, out, err) = cloth(&[
            "sim",
            "drape",
            "--frames",
            "40",
            "--resolution",
            "24",
            "--integrator",
            "implicit-euler",
            "--set",
            &format!("solver.implicit.max_iterations={cap}"),
            "--report",
            s(&rep),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(out.contains("status ok"), "{out}");
        let r = report(&rep);
        let frames = r["frames"].as_array().expect("frames").clone();
        let capped = frames
            .iter()
            .filter(|f| f["solver_converged"] == false)
            .count();
        let first = frames
            .iter()
            .find(|f| f["solver_converged"] == false)
            .map(|f| f["frame"].as_u64().expect("frame"));
        assert_eq!(r["solver_unconverged_frames"], capped as u64);
        (err, capped, first)
    };
    let (err, capped, first) = run("2");
    let first = first.expect("a capped frame");
    assert!(capped > 0 && capped <= 40);
    for needle in [
        "warning: implicit Euler's linear solve stopped at its cap of 2 CG iterations".to_owned(),
        format!("in {capped} of 40 frames (the first: frame {first};"),
        "raise solver.implicit.max_iterations".to_owned(),
    ] {
        assert!(err.contains(&needle), "{needle:?} not in {err}");
    }
    let (err, capped, _) = run("200");
    assert_eq!(capped, 0);
    assert!(!err.contains("warning"), "{err}");
}

/// The report's `final_structural_strain` and `final_shear_strain` are the strains of the last
/// frame: recomputed here from the exported OBJ (parsed by tobj; each vertex placed on the grid
/// by its texture coordinate) against the scene's rest spacing, the nearest-rank median, p99,
/// p99.9 and maximum agree within 10⁻⁴ (the OBJ's 9 significant digits, over a 0.13 m
/// spacing). The drape's diagonals stretch more than its warp and weft (they take the
/// wrapping of the ball), which the structural figures alone would not show.
#[test]
fn final_strains_match_the_exported_frame() {
    let guard = tmp("strain");
    let dir = guard.path();
    let (out, rep) = (dir.join("out"), dir.join("r.json"));
    let (code, stdout, err) = cloth(&[
        "sim",
        "drape",
        "--frames",
        "60",
        "--resolution",
        "10",
        "--out",
        s(&out),
        "--every",
        "60",
        "--report",
        s(&rep),
        "--table-every",
        "0",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        stdout.contains("shear strain at the end: median"),
        "{stdout}"
    );
    let mesh = &obj_mesh(&out.join("frame_0060.obj"), true);
    let n = 10;
    let mut grid = vec![[f64::NAN; 3]; n * n];
    for (p, uv) in mesh.positions.chunks(3).zip(mesh.texcoords.chunks(2)) {
        let (c, r) = (uv[0] as f64 * 9.0, uv[1] as f64 * 9.0);
        assert!(
            (c - c.round()).abs() < 1e-3 && (r - r.round()).abs() < 1e-3,
            "{uv:?}"
        );
        grid[r.round() as usize * n + c.round() as usize] = [p[0], p[1], p[2]].map(f64::from);
    }
    let spacing = 1.2 / 9.0;
    let strain = |a: usize, b: usize, rest: f64| {
        let d: f64 = (0..3).map(|k| (grid[a][k] - grid[b][k]).powi(2)).sum();
        (d.sqrt() - rest) / rest
    };
    let (mut structural, mut shear) = (Vec::new(), Vec::new());
    for r in 0..n {
        for c in 0..n {
            let i = r * n + c;
            if r + 1 < n {
                structural.push(strain(i, i + n, spacing));
            }
            if c + 1 < n {
                structural.push(strain(i, i + 1, spacing));
            }
            if r + 1 < n && c + 1 < n {
                shear.push(strain(i, i + n + 1, spacing * 2f64.sqrt()));
                shear.push(strain(i + 1, i + n, spacing * 2f64.sqrt()));
            }
        }
    }
    let r = report(&rep);
    for (key, mut strains) in [
        ("final_structural_strain", structural),
        ("final_shear_strain", shear),
    ] {
        strains.sort_by(f64::total_cmp);
        for (q, field) in [(0.5, "p50"), (0.99, "p99"), (0.999, "p99_9"), (1.0, "max")] {
            let rank = ((q * strains.len() as f64).ceil() as usize).clamp(1, strains.len());
            let want = strains[rank - 1];
            let got = r[key][field].as_f64().expect("a number");
            assert!((got - want).abs() < 1e-4, "{key}.{field}: {got} vs {want}");
        }
    }
    let max = |key: &str| r[key]["max"].as_f64().expect("max");
    assert!(max("final_shear_strain") > max("final_structural_strain"));
}

/// A run resumed from a checkpoint ends bit-identical to the same run uninterrupted, and the
/// thread count does not change a bit either.
#[test]
fn resume_and_threads_give_identical_bits() {
    let guard = tmp("resume");
    let dir = guard.path();
    let (a, b, c) = (dir.join("a"), dir.join("b"), dir.join("c"));
    let base = [
        "sim",
        "flag",
        "--resolution",
        "10",
        "--table-every",
        "0",
        "--format",
        "obj",
        "--every",
        "30",
    ];
    let run = |out: &Path, extra: &[&str]| {
        let mut args: Vec<&str> = base.to_vec();
        args.extend_from_slice(&["--out", s(out)]);
        args.extend_from_slice(extra);
        let (code, o, e) = cloth(&args);
        assert_eq!(code, 0, "{o}\n{e}");
    };
    run(&a, &["--frames", "60"]);
    // "Killed" after frame 40 with a checkpoint at frame 20 (runs only write checkpoints before
    // their last frame), then resumed to 60.
    run(&b, &["--frames", "40", "--checkpoint-every", "20"]);
    let cp = b.join("checkpoint.json");
    assert!(cp.exists());
    // The checkpoint carries its scene: changing it on resume is refused, not ignored; and
    // a run that is already as long as asked has nothing left to do.
    for extra in [
        &["--set", "cloth.resolution=[8,8]"][..],
        &["--resolution", "8"],
        &["--integrator", "xpbd"],
        &["hanging"],
        &["flag", "--set", "forces.damping=0.5"],
    ] {
        let mut args = vec!["sim", "--frames", "60", "--resume", s(&cp)];
        args.extend_from_slice(extra);
        bad(
            &args,
            &["--resume continues the checkpoint's own scene (`flag`)"],
        );
    }
    bad(
        &["sim", "--frames", "20", "--resume", s(&cp)],
        &["at frame 20 already", "ask for more than 20 frames"],
    );
    run(&b, &["--frames", "60", "--resume", s(&cp)]);
    run(&c, &["--frames", "60", "--threads", "2"]);
    let last = |d: &Path| std::fs::read(d.join("frame_0060.obj")).expect("frame 60");
    assert_eq!(last(&a), last(&b), "resumed run differs");
    assert_eq!(last(&a), last(&c), "two threads differ from one");
}

/// An unstable run stops, exits 3, writes the frames before the failure and a report with
/// status "unstable" naming the step (0-based: the frames done before it) and the frame that
/// failed (numbered from 1, as the table and `frames[].frame`); the summary line says both,
/// unambiguously (it used to say "3 frames, status unstable at step 3" for the 4th frame).
#[test]
fn unstable_runs_exit_3_with_report() {
    let guard = tmp("unstable");
    let dir = guard.path();
    let rep = dir.join("r.json");
    let out = dir.join("out");
    let (code, stdout, err) = cloth(&[
        "sim",
        "drape",
        "--resolution",
        "16",
        "--frames",
        "50",
        "--set",
        "solver.substeps=1",
        "--report",
        s(&rep),
        "--out",
        s(&out),
    ]);
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("unstable"), "{err}");
    let r = report(&rep);
    let step = r["status"]["unstable"]["step"]
        .as_u64()
        .expect("unstable step");
    let frames = r["frames"].as_array().expect("frames");
    assert_eq!(frames.len() as u64, step);
    assert_eq!(
        r["status"]["unstable"]["frame"].as_u64(),
        Some(step + 1),
        "{r}"
    );
    let time = r["status"]["unstable"]["time"].as_f64().expect("time");
    let last_time = frames
        .last()
        .map_or(0.0, |f| f["time"].as_f64().expect("time"));
    assert_eq!(time, last_time, "{r}");
    assert!(
        stdout.contains(&format!(
            "done: {step} frames, status unstable in frame {} (step index {step}, from t = {time:.6} s): particle",
            step + 1
        )),
        "{stdout}"
    );
    assert!(
        err.contains(&format!("unstable in frame {}", step + 1)),
        "{err}"
    );
    // (This drape at one substep fails after a few good frames, so a frame was exported.)
    assert!(step > 0, "the drape failed at its first frame: {r}");
    assert!(out.join(format!("frame_{step:04}.obj")).exists());

    // With --every past the failure, the last frame done is exported all the same.
    let sparse = dir.join("sparse");
    let (code, _, err) = cloth(&[
        "sim",
        "drape",
        "--resolution",
        "16",
        "--frames",
        "50",
        "--set",
        "solver.substeps=1",
        "--every",
        "1000",
        "--out",
        s(&sparse),
    ]);
    assert_eq!(code, 3, "{err}");
    assert!(sparse.join(format!("frame_{step:04}.obj")).exists());

    // Unstable at its very first frame (a cloth thrown at 999 m/s into the ball): no frame
    // was done, so no throughput is made up: null in the report, "n/a" in the summary.
    let (code, out, err) = cloth(&[
        "sim",
        "drape",
        "--resolution",
        "16",
        "--frames",
        "5",
        "--set",
        "cloth.velocity=[999,0,0]",
        "--report",
        s(&rep),
    ]);
    assert_eq!(code, 3, "{err}");
    let r = report(&rep);
    assert_eq!(r["status"]["unstable"]["step"], 0, "{r}");
    for key in [
        "particle_substeps_per_second",
        "median_frame_ms",
        "median_frame_particle_substeps_per_second",
    ] {
        assert!(r[key].is_null(), "{key}: {}", r[key]);
    }
    assert!(
        out.contains("n/a particle-substeps/s (median frame n/a;"),
        "{out}"
    );
}

fn bad(args: &[&str], needles: &[&str]) {
    let (code, out, err) = cloth(args);
    assert_eq!(code, 2, "{args:?}: {out}{err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert_eq!(
        err.trim().lines().count(),
        1,
        "{args:?}: one message expected: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in {err}");
    }
}

/// Bad input of every kind: exit status 2, one message naming file:line:column, the key and
/// what is allowed; never a panic.
#[test]
fn bad_input_is_named_precisely() {
    let guard = tmp("bad");
    let dir = guard.path();
    let write = |name: &str, text: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, text).expect("write");
        p
    };
    let good = "[cloth]\nresolution = [8, 8]\nsize = [1.0, 1.0]\n";
    let syntax = write("syntax.toml", b"[cloth]\nresolution = [8, 8\n");
    bad(&["sim", s(&syntax)], &["syntax.toml:2:", "unclosed array"]);
    let unknown = write("unknown.toml", good.replace("size", "sizee").as_bytes());
    bad(
        &["sim", s(&unknown)],
        &["unknown.toml:3:1", "did you mean `size`?"],
    );
    let wrong_type = write("type.toml", good.replace("[8, 8]", "\"big\"").as_bytes());
    bad(&["sim", s(&wrong_type)], &["type.toml:2:"]);
    let range = write("range.toml", format!("{good}density = -1.0\n").as_bytes());
    bad(
        &["sim", s(&range)],
        &["range.toml:4:11", "cloth.density", "> 0"],
    );
    let nan = write("nan.toml", format!("{good}[solver]\ndt = nan\n").as_bytes());
    bad(&["sim", s(&nan)], &["nan.toml:5:6", "solver.dt"]);
    let friction = write("friction.toml", format!("{good}[[colliders]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nfriction = {{ static = -0.5 }}\n").as_bytes());
    bad(
        &["sim", s(&friction)],
        &["friction.toml:8:", "colliders[0].friction.static", ">= 0"],
    );
    let pins = write(
        "pins.toml",
        format!("{good}pins = {{ indices = [3, 99] }}\n").as_bytes(),
    );
    bad(
        &["sim", s(&pins)],
        &["pins.toml:4:", "cloth.pins.indices", "0 ..= 63"],
    );
    let zero = write("zero.toml", good.replace("[8, 8]", "[0, 8]").as_bytes());
    bad(
        &["sim", s(&zero)],
        &["zero.toml:2:", "cloth.resolution", "2 ..= 8192"],
    );
    let empty = write("empty.toml", b"");
    bad(&["sim", s(&empty)], &["empty.toml", "empty"]);
    let binary = write("binary.toml", &[0x7f, b'E', b'L', b'F', 0, 1, 2, 0xff]);
    bad(&["sim", s(&binary)], &["binary.toml", "binary"]);
    bad(
        &["sim", s(&dir.join("missing.toml"))],
        &["missing.toml", "cannot read"],
    );
    let file_as_dir = write("not-a-dir", b"x");
    bad(
        &[
            "sim",
            "drape",
            "--frames",
            "1",
            "--out",
            s(&file_as_dir.join("sub")),
        ],
        &["output folder"],
    );
    bad(
        &["sim", "drape", "--set", "solver.kind=\"rk4\""],
        &["--set", "solver.kind", "xpbd"],
    );
    bad(&["check", s(&range)], &["cloth.density"]);
    bad(
        &["scenes", "--print", "nope"],
        &["unknown scene `nope`", "drape"],
    );
}

#[test]
fn check_summarises_without_running() {
    let (code, out, err) = cloth(&["check", "peer-ball"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("particles=16384"), "{out}");
    assert!(out.contains("memory"), "{out}");
    assert!(out.contains("estimated stable substep"), "{out}");
    // peer-ball runs at 1.44× the (sufficient, Gershgorin) bound: no warning.
    assert!(!err.contains("warning"), "{err}");
    assert!(out.trim_end().ends_with(": ok"), "{out}");
}

/// `cloth check` warns (on stderr, exit status 0) when an explicit integrator's substep is
/// more than twice the estimated stable one, with the substeps it needs; the same scene
/// with xpbd, stable at any step, gets no warning.
#[test]
fn check_warns_of_an_explicit_step_past_its_stability_bound() {
    let (code, out, err) = cloth(&["check", "drape", "--set", "solver.substeps=2"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("warning: symplectic-euler will likely go unstable"),
        "{err}"
    );
    assert!(err.contains("raise `solver.substeps` to 92"), "{err}");
    assert!(out.contains("ok, with a warning"), "{out}");
    let (code, out, err) = cloth(&[
        "check",
        "drape",
        "--set",
        "solver.substeps=2",
        "--integrator",
        "xpbd",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("warning"), "{err}");
    assert!(out.trim_end().ends_with(": ok"), "{out}");
    // A stable substep that underflows f32 (10³⁰ N/m on a 10⁻³⁰ kg/m² cloth) is said as
    // such, never as 0 s or "inf" substeps.
    let (code, out, err) = cloth(&[
        "check",
        "drape",
        "--set",
        "cloth.density=1e-30",
        "--set",
        "material.warp={stiffness=1e30,damping=0}",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("below 1.2e-38 s (more than 1e38 substeps"),
        "{out}"
    );
    assert!(
        err.contains("far over the estimated stable substep"),
        "{err}"
    );
    for text in [&out, &err] {
        assert!(!text.contains("inf") && !text.contains("NaN"), "{text}");
    }
}

/// Ctrl-C (SIGINT) stops a run between frames: exit status 130 and a report with status
/// "interrupted" holding the frames done so far.
#[cfg(unix)]
#[test]
fn interrupted_runs_write_their_report() {
    let guard = tmp("interrupt");
    let dir = guard.path();
    let rep = dir.join("r.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args([
            "sim",
            "peer-ball",
            "--frames",
            "100000",
            "--table-every",
            "0",
            "--report",
            s(&rep),
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    // The summary line is printed once the Ctrl-C handler is installed: wait for it, then let
    // the run simulate a little.
    let mut stdout = std::io::BufReader::new(child.stdout.take().expect("stdout"));
    let mut first = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut first).expect("summary line");
    assert!(first.starts_with("scene peer-ball"), "{first}");
    std::thread::sleep(std::time::Duration::from_millis(1000));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let status = child.wait().expect("wait");
    assert_eq!(status.code(), Some(130));
    let r = report(&rep);
    assert_eq!(r["status"], "interrupted");
    assert!(!r["frames"].as_array().expect("frames").is_empty());
}

/// The names in `dir` that end in `.tmp`: what a failed atomic write would leave behind.
fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("dir")
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

/// An output path that cannot be written, found before the run (a `--report` that names a
/// folder, a folder inside `--out` where the run writes a file, a folder that cannot be
/// created, a missing report folder), is bad input: exit status 2, one message naming it,
/// nothing simulated and no temporary file left. (A report path that was a folder used to
/// fail only after the run, exit status 1, leaving `.NAME.tmp` behind.)
#[test]
fn output_paths_that_cannot_be_written_are_refused_before_the_run() {
    let guard = tmp("out-paths");
    let dir = guard.path();
    let folder = dir.join("somedir");
    std::fs::create_dir(&folder).expect("mkdir");
    let (code, out, err) = cloth(&["sim", "drape", "--frames", "2", "--report", s(&folder)]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains(&format!("the report {} is a folder", s(&folder))),
        "{err}"
    );
    assert!(!out.contains("done:"), "the run should not start: {out}");
    assert!(temporaries(dir).is_empty(), "{:?}", temporaries(dir));

    // Folders where `--out` files go: the glb, an exported frame, the checkpoint.
    for (name, extra) in [
        ("cloth.glb", &["--format", "glb"][..]),
        ("frame_0004.obj", &["--format", "obj", "--every", "2"][..]),
        // not exported with --every 3 and 5 frames (3 and the last, 5, are): no refusal
        ("frame_0004.obj", &["--format", "obj", "--every", "3"][..]),
        ("checkpoint.json", &["--checkpoint-every", "2"][..]),
    ] {
        let out_dir = dir.join(format!("out-{}", extra.join("")));
        std::fs::create_dir_all(out_dir.join(name)).expect("mkdir");
        let mut args = vec!["sim", "drape", "--resolution", "6", "--frames", "5"];
        args.extend_from_slice(&["--out", s(&out_dir)]);
        args.extend_from_slice(extra);
        let (code, _, err) = cloth(&args);
        if extra.contains(&"3") {
            assert_eq!(code, 0, "{args:?}: {err}");
            assert!(out_dir.join("frame_0003.obj").exists());
            assert!(out_dir.join("frame_0005.obj").exists());
            continue;
        }
        bad(&args, &[&format!("{} is a folder", s(&out_dir.join(name)))]);
        assert!(temporaries(&out_dir).is_empty(), "{args:?}");
    }

    // A folder that cannot be created and a missing report folder: exit status 2 too, as
    // the README and `cloth --help` say.
    bad(
        &["sim", "drape", "--frames", "1", "--out", "/dev/null/x"],
        &["the output folder /dev/null/x cannot be created"],
    );
    bad(
        &[
            "sim",
            "drape",
            "--frames",
            "1",
            "--report",
            s(&dir.join("nonexistent/r.json")),
        ],
        &["report folder", "does not exist"],
    );
}

/// A write that fails during or after the run exits with status 1 and removes its temporary
/// file (it used to stay, `.r.json.tmp` beside the report). The folder in the way is made
/// once the run has started (after the checks before it): the run prints more table lines
/// than a pipe holds before it writes the file, so it waits for this test to read them, and
/// the folder is there by then.
#[test]
fn a_failed_write_during_the_run_exits_1_and_leaves_no_temporary_file() {
    use std::io::{BufRead, Read};
    let guard = tmp("failed-write");
    let dir = guard.path();
    for (name, extra) in [
        ("r.json", &["--report"][..]),
        ("out/frame_2000.obj", &["--every", "1000", "--out"][..]),
        (
            "out/cloth.glb",
            &["--every", "1000", "--format", "glb", "--out"][..],
        ),
        (
            "out/checkpoint.json",
            &["--every", "1000", "--checkpoint-every", "1999", "--out"][..],
        ),
    ] {
        let target = dir.join(name);
        let _ = std::fs::remove_dir_all(&target);
        let out_dir = dir.join("out");
        let last = if extra.contains(&"--report") {
            s(&target)
        } else {
            s(&out_dir)
        };
        let mut args = vec![
            "sim",
            "hanging",
            "--resolution",
            "4",
            "--frames",
            "2000",
            "--table-every",
            "1",
            "--threads",
            "1",
        ];
        args.extend_from_slice(extra);
        args.push(last);
        let mut child = Command::new(env!("CARGO_BIN_EXE_cloth"))
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("spawn");
        let mut stdout = std::io::BufReader::new(child.stdout.take().expect("stdout"));
        let mut first = String::new();
        stdout.read_line(&mut first).expect("summary line");
        assert!(first.starts_with("scene hanging"), "{first}");
        std::fs::create_dir_all(&target).expect("mkdir");
        let mut rest = String::new();
        stdout.read_to_string(&mut rest).expect("stdout");
        assert!(
            rest.len() > 1 << 17,
            "the run must outlast the pipe: {}",
            rest.len()
        );
        let mut err = String::new();
        child
            .stderr
            .take()
            .expect("stderr")
            .read_to_string(&mut err)
            .expect("stderr");
        let status = child.wait().expect("wait");
        assert_eq!(status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("cannot rename"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let folder = target.parent().expect("parent");
        assert!(
            temporaries(folder).is_empty(),
            "{args:?}: {:?}",
            temporaries(folder)
        );
        std::fs::remove_dir_all(&target).expect("rmdir");
    }
}

/// `--every K` exports frames K, 2K, … and always the run's last frame: K past the frame
/// count still exports the last frame (it used to export nothing and say nothing), and the
/// files are named by frame number.
#[test]
fn every_exports_the_last_frame_too() {
    let guard = tmp("every");
    let dir = guard.path();
    let objs = |out: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(out)
            .expect("out")
            .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
            .filter(|n| n.ends_with(".obj"))
            .collect();
        names.sort();
        names
    };
    for (frames, every, want) in [
        ("3", "5", &["frame_0003.obj"][..]),
        (
            "10",
            "4",
            &["frame_0004.obj", "frame_0008.obj", "frame_0010.obj"][..],
        ),
        ("4", "2", &["frame_0002.obj", "frame_0004.obj"][..]),
    ] {
        let out = dir.join(format!("f{frames}e{every}"));
        let (code, _, err) = cloth(&[
            "sim",
            "drape",
            "--resolution",
            "6",
            "--frames",
            frames,
            "--every",
            every,
            "--out",
            s(&out),
            "--format",
            "obj,glb",
        ]);
        assert_eq!(code, 0, "{err}");
        assert_eq!(objs(&out), want, "--frames {frames} --every {every}");
        let (doc, _, _) = gltf::import(out.join("cloth.glb")).expect("gltf imports it");
        let prim = doc
            .meshes()
            .next()
            .and_then(|m| m.primitives().next())
            .expect("a primitive");
        assert_eq!(prim.morph_targets().count(), want.len());
    }
}

/// `cloth check` refuses a scene too big for the memory available as `cloth sim` does, with
/// the same figures (it used to say "ok" for a scene `sim` refuses). The bound is set with
/// `CLOTH_MEMORY_LIMIT` so that the test does not depend on the host's memory: at the largest
/// resolution, 8192², the estimate is 36 GiB, over the 8 GiB limit; at 512² it is about
/// 144 MiB, over a 64 MiB limit (also for `cloth render` and `cloth view`), and `--force`
/// checks it.
#[test]
fn every_command_refuses_a_scene_too_big_for_memory() {
    let needs = |err: &str| {
        err.split("needs about ")
            .nth(1)
            .and_then(|r| r.split(')').next())
            .map(str::to_owned)
            .unwrap_or_else(|| panic!("no estimate in {err}"))
    };
    let limit = [("CLOTH_MEMORY_LIMIT", "8GiB")];
    let sim = ["sim", "drape", "--resolution", "8192", "--frames", "1"];
    let (code, out, sim_err) = cloth_env(&sim, &limit);
    assert_eq!(code, 2, "{out}{sim_err}");
    let (code, out, check_err) = cloth_env(&["check", "drape", "--resolution", "8192"], &limit);
    assert_eq!(code, 2, "{out}{check_err}");
    assert!(!out.contains("ok"), "{out}");
    assert_eq!(needs(&check_err), needs(&sim_err));
    assert_eq!(needs(&check_err), "36.0 GiB (67108864 particles");
    // Whichever is smaller binds: the limit, or the memory available on a small host.
    for err in [&sim_err, &check_err] {
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains("--force"), "{err}");
        assert!(
            err.contains("the 8.00 GiB CLOTH_MEMORY_LIMIT allows") || err.contains("GiB available"),
            "{err}"
        );
    }
    let small = [("CLOTH_MEMORY_LIMIT", "64MiB")];
    let (code, out, err) = cloth_env(&["check", "drape", "--resolution", "512"], &small);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("(262144 particles), more than the 64.0 MiB CLOTH_MEMORY_LIMIT allows"),
        "{err}"
    );
    let (code, out, err) = cloth_env(
        &["check", "drape", "--resolution", "512", "--force"],
        &small,
    );
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("particles=262144"), "{out}");
    // `cloth render` and `cloth view` refuse it too, before building (so before any adapter
    // or display is needed).
    let png = std::env::temp_dir().join("cloth-memory-refusal.png");
    let png = s(&png);
    for cmd in [
        &["render", "drape", "--resolution", "512", "--png", png][..],
        &["view", "drape", "--resolution", "512", "--frames", "1"][..],
    ] {
        let (code, out, err) = cloth_env(cmd, &small);
        assert_eq!(code, 2, "{cmd:?}: {out}{err}");
        assert!(
            err.contains("more than the 64.0 MiB CLOTH_MEMORY_LIMIT allows")
                && err.contains("--force"),
            "{cmd:?}: {err}"
        );
    }
    // Three significant digits: the need and the bound never print as the same figure (the
    // 48² drape needs about 1.2 MiB; it used to read "needs about 1 MiB, more than the 1 MiB").
    let (code, out, err) = cloth_env(&["check", "drape"], &[("CLOTH_MEMORY_LIMIT", "1MiB")]);
    assert_eq!(code, 2, "{out}{err}");
    let need = err
        .split("needs about ")
        .nth(1)
        .and_then(|r| r.split(" (").next())
        .unwrap_or_else(|| panic!("{err}"));
    assert!(need.ends_with(" MiB") && need != "1.00 MiB", "{err}");
    assert!(
        err.contains("more than the 1.00 MiB CLOTH_MEMORY_LIMIT allows"),
        "{err}"
    );
    // A malformed limit is bad input, named, even with --force.
    for bad_limit in ["4GB", "0", "1.5GiB", "-1", " ", "99999999999GiB"] {
        for force in [false, true] {
            let mut args = vec!["check", "drape", "--resolution", "8"];
            if force {
                args.push("--force");
            }
            let (code, out, err) = cloth_env(&args, &[("CLOTH_MEMORY_LIMIT", bad_limit)]);
            assert_eq!(code, 2, "{bad_limit:?}: {out}{err}");
            assert!(
                err.contains(&format!("CLOTH_MEMORY_LIMIT={bad_limit}:")) && err.contains("GiB"),
                "{bad_limit:?}: {err}"
            );
        }
    }
}

/// A report written through a symbolic link replaces the file the link points to and keeps
/// the link; a report written to a FIFO (or a device such as `/dev/stdout`) is written into
/// it, and the FIFO stays a FIFO: renaming a temporary file over it, as a regular file is
/// replaced, used to turn it (and, as root, `/dev/full`) into a regular file.
#[test]
fn reports_follow_links_and_write_into_fifos() {
    use std::os::unix::fs::FileTypeExt;
    let guard = tmp("special-report");
    let dir = guard.path();
    let real = dir.join("real.json");
    std::fs::write(&real, b"old").expect("write");
    let link = dir.join("link.json");
    std::os::unix::fs::symlink(&real, &link).expect("symlink");
    let (code, out, err) = cloth(&["sim", "drape", "--frames", "2", "--report", s(&link)]);
    assert_eq!(code, 0, "{out}{err}");
    let meta = std::fs::symlink_metadata(&link).expect("link");
    assert!(meta.file_type().is_symlink(), "the link was replaced");
    let frames = |r: &serde_json::Value| r["frames"].as_array().map(Vec::len);
    assert_eq!(frames(&report(&real)), Some(2));

    let fifo = dir.join("report.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
    assert!(made.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).expect("read the fifo"))
    };
    let (code, out, err) = cloth(&["sim", "drape", "--frames", "2", "--report", s(&fifo)]);
    assert_eq!(code, 0, "{out}{err}");
    // Checked before joining: had the FIFO been replaced, its reader would wait for ever.
    let kind = std::fs::symlink_metadata(&fifo).expect("fifo").file_type();
    assert!(kind.is_fifo(), "the FIFO was replaced: {kind:?}");
    let bytes = reader.join().expect("reader");
    let json: serde_json::Value = serde_json::from_slice(&bytes).expect("the report, as JSON");
    assert_eq!(frames(&json), Some(2));
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .expect("dir")
        .flatten()
        .map(|e| e.file_name())
        .filter(|n| n.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
