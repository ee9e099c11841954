#!/usr/bin/env python3
"""Fuzzes the `cloth` command with hostile input and reports every run that panics, exits
with a status other than 0 (ok), 2 (bad input) or 3 (unstable), hangs, prints a non-finite
number as a result, or writes a report that is not JSON or holds NaN (docs/performance.md,
thirty-second round). Not part of the build: Python 3 only, no packages.

Modes (each run is one `cloth` invocation with a random case, reproducible by --seed):
  set         random `--set` overrides of every scene key, at and past their ranges, on every
              built-in scene and the shipped scene files; `cloth check` and short `cloth sim`
              runs with random threads, exports, reports and checkpoints
  scene       the shipped scene files with lines deleted, duplicated or corrupted
  checkpoint  a checkpoint with values replaced, arrays cut, the text truncated, then --resume
  obj         scenes/mesh.toml with its OBJ mesh corrupted

usage: scripts/fuzz-cli.py MODE [--runs N] [--seed S] [--bin target/release/cloth]
Prints the failing commands (inputs kept in a temporary folder) and `bad K` at the end;
exits 1 if K > 0.
"""
import argparse, copy, glob, json, os, random, re, shutil, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["drape", "hanging", "flag", "peer-ball", "xpbd-drape", "table", "sweep", "euler-sheet",
          "verlet-swing", "implicit-drape", "xpbd-curtain"] + sorted(
              glob.glob(os.path.join(ROOT, "scenes", "*.toml")))


def run(cmd, tmp, report=None):
    """One invocation; the reason it is bad, or None."""
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return "timeout (120 s)"
    out = p.stdout + p.stderr
    if p.returncode not in (0, 2, 3):
        return f"exit status {p.returncode}"
    if "panicked" in out:
        return "panic"
    # Non-finite numbers are allowed only in the description of an instability.
    if re.search(r"\bNaN\b|\binf\b", p.stdout, re.I) and "unstable" not in p.stdout:
        return "non-finite number printed"
    if report and p.returncode == 0 and os.path.exists(report):
        text = open(report).read()
        os.remove(report)
        try:
            json.loads(text)
        except ValueError as e:
            return f"report is not JSON: {e}"
        if re.search(r"\bNaN\b|Infinity", text):
            return "non-finite number in the report"
    return None


def value():
    """A plausible value two times in three (so that many cases reach the simulator), a
    hostile one otherwise."""
    if random.random() < 2 / 3:
        return random.choice(["0.01", "0.05", "0.3", "1", "10", "400"])
    return random.choice(["0", "1", "-1", "0.3", "1e-9", "1e9", "nan", "inf", "-inf", "1e30",
                          "-1e-30", "2", "[]", "\"x\"", "true"])


def vec3():
    return "[" + ",".join(value() for _ in range(3)) + "]"


def collider():
    parts = [f'type="{random.choice(["sphere", "plane", "capsule", "box", "mesh", "cone"])}"']
    for key, make in [("center", vec3), ("radius", value), ("point", vec3), ("normal", vec3),
                      ("a", vec3), ("b", vec3), ("half_extents", vec3), ("rotation", vec3),
                      ("angular_velocity", vec3), ("velocity", vec3), ("thickness", value),
                      ("file", lambda: random.choice(['"meshes/table.obj"', '"nope.obj"',
                                                      '"/dev/null"']))]:
        if random.random() < 0.35:
            parts.append(f"{key}={make()}")
    if random.random() < 0.3:
        parts.append(f"friction={{static={value()},kinetic={value()}}}")
    return "{" + ",".join(parts) + "}"


KEYS = {
    "cloth.resolution": lambda: random.choice(["[0,0]", "[1,5]", "[2,2]", "[3,2]", "[2,3]",
                                               "[7,3]", "[64,2]", "[2,64]", "[16,16]", "[2.5,3]",
                                               "[4,4,4]", "[100000,100000]"]),
    "cloth.size": lambda: f"[{value()},{value()}]",
    "cloth.spacing": lambda: f"[{value()},{value()}]",
    "cloth.origin": vec3, "cloth.rotation": vec3, "cloth.velocity": vec3,
    "cloth.density": value, "cloth.mass_per_particle": value,
    "cloth.orientation": lambda: random.choice(['"vertical"', '"horizontal"', '"diagonal"']),
    "cloth.pins": lambda: random.choice(['{corners=["top-left"]}', '{edges=["top","left"]}',
                                         '{indices=[0,1,2,3]}', '{indices=[100000]}',
                                         '{edges=["middle"]}']),
    "material.warp": lambda: f"{{stiffness={value()},damping={value()}}}",
    "material.shear": lambda: f"{{stiffness={value()},damping={value()}}}",
    "material.bend": lambda: f"{{stiffness={value()},damping={value()}}}",
    "forces.gravity": vec3, "forces.damping": value,
    "forces.air": lambda: (f"{{density={value()},drag={value()},lift={value()},wind={vec3()},"
                           f"gust={{amplitude={value()},frequency={value()}}}}}"),
    "forces.enabled": lambda: "{" + ",".join(
        f"{k}={random.choice(['true', 'false'])}"
        for k in ["gravity", "springs", "dashpots", "damping", "air"]) + "}",
    "colliders": lambda: "[" + ",".join(collider() for _ in range(random.randint(0, 3))) + "]",
    "solver.kind": lambda: random.choice(["xpbd", "implicit-euler", "verlet", "symplectic-euler",
                                          "forward-euler", "bogus"]),
    "solver.substeps": lambda: random.choice(["0", "1", "2", "20", "1000000", "\"auto\"", "2.5"]),
    "solver.dt": lambda: random.choice(["0.001", "0.0166", "0.1", "10", value()]),
    "solver.strain_limit": value,
    "solver.self_collision": lambda: f"{{thickness={value()},friction={value()}}}",
    "solver.implicit": lambda: (f"{{tolerance={value()},"
                                f"max_iterations={random.choice(['0', '1', '1000000'])}}}"),
    "solver.xpbd": lambda: "{" + ",".join(random.sample(
        [f"iterations={random.randint(0, 4)}", "tethers=true", f"tether_slack={value()}",
         f"hierarchy_levels={random.randint(0, 20)}", f"hierarchy_slack={value()}",
         f"structural_limit={value()}", "chains=true",
         f"chain_iterations={random.randint(0, 20)}", f"chain_rounds={random.randint(0, 20)}",
         "shear_chains=true"], random.randint(1, 4))) + "}",
    "solver.limits": lambda: f"{{max_stretch_ratio={value()},max_speed={value()}}}",
    "duration": value,
    "camera": lambda: f"{{eye={vec3()},target={vec3()},fov_degrees={value()}}}",
}


def case_set(binary, tmp):
    sets = []
    for _ in range(random.randint(1, 2)):
        key = random.choice(list(KEYS))
        sets += ["--set", f"{key}={KEYS[key]()}"]
    scene = random.choice(SCENES)
    if random.random() < 0.3:
        return [binary, "check", scene] + sets, None
    cmd = [binary, "sim", scene, "--frames", str(random.choice([1, 3, 10])),
           "--threads", random.choice(["1", "2"])] + sets
    if random.random() < 0.5:
        cmd += ["--resolution", str(random.choice([2, 3, 8, 16]))]
    if random.random() < 0.3:
        cmd += ["--out", os.path.join(tmp, "out"), "--format",
                random.choice(["obj", "glb", "obj,glb"])]
    elif random.random() < 0.2:
        cmd += ["--checkpoint-every", "1", "--out", os.path.join(tmp, "ck")]
    report = None
    if random.random() < 0.3:
        report = os.path.join(tmp, "report.json")
        cmd += ["--report", report]
    return cmd, report


def mutate_lines(lines, tokens, inserts):
    for _ in range(random.randint(1, 4)):
        if not lines:
            break
        i = random.randrange(len(lines))
        r = random.random()
        if r < 0.2:
            del lines[i]
        elif r < 0.35:
            lines.insert(i, random.choice(inserts or lines))
        elif "=" in lines[i] or " " in lines[i]:
            sep = "=" if "=" in lines[i] else " "
            key, rest = lines[i].split(sep, 1)
            nums = list(re.finditer(r"-?[0-9.]+(e-?[0-9]+)?", rest))
            if nums and random.random() < 0.7:
                m = random.choice(nums)
                rest = rest[:m.start()] + random.choice(tokens) + rest[m.end():]
            else:
                rest = " " + random.choice(tokens)
            lines[i] = key + sep + rest
        else:
            j = random.randrange(len(lines[i]) + 1)
            lines[i] = lines[i][:j] + random.choice("[]{}\"=#\\") + lines[i][j:]
    return lines


def case_scene(binary, tmp):
    src = open(random.choice(glob.glob(os.path.join(ROOT, "scenes", "*.toml")))).read()
    lines = mutate_lines(src.split("\n"), ["0", "-0.0", "1e39", "nan", "inf", "-1", "[]", "[1]",
                                           "{}", "\"\"", "true", "[0,0,0]", "1e-45",
                                           "18446744073709551616", "[[1]]"], [])
    path = os.path.join(tmp, "scenes", "s.toml")
    open(path, "w").write("\n".join(lines))
    if random.random() < 0.5:
        return [binary, "check", path], None
    return [binary, "sim", path, "--frames", "2", "--resolution", "6"], None


def case_checkpoint(binary, tmp, base):
    d = copy.deepcopy(base)

    def paths(o, p=()):
        if isinstance(o, dict):
            for k, v in o.items():
                yield from paths(v, p + (k,))
        elif isinstance(o, list):
            for i, v in enumerate(o[:6]):
                yield from paths(v, p + (i,))
            if o:
                yield p
        else:
            yield p

    all_paths = list(paths(d))
    for _ in range(random.randint(1, 3)):
        p = random.choice(all_paths)
        try:
            o = d
            for k in p[:-1]:
                o = o[k]
            if not p:
                continue
            r = random.random()
            if r < 0.15 and isinstance(o[p[-1]], list):
                o[p[-1]] = o[p[-1]][:-1]
            elif r < 0.25 and isinstance(o, list):
                del o[p[-1]]
            else:
                o[p[-1]] = random.choice([None, -1, 0, 1e40, -1e40, "x", [], {}, [1, 2], 1.5,
                                          2 ** 40, True, "NaN"])
        except (TypeError, KeyError, IndexError):
            pass
    text = json.dumps(d)
    if random.random() < 0.2:
        text = text[:random.randint(0, len(text))]
    if random.random() < 0.5:
        text = text.replace('"NaN"', "NaN")
    path = os.path.join(tmp, "checkpoint-in.json")
    open(path, "w").write(text)
    report = os.path.join(tmp, "report.json")
    return [binary, "sim", "drape", "--resolution", "8", "--frames", "6", "--resume", path,
            "--report", report, "--out", os.path.join(tmp, "resumed")], report


def case_obj(binary, tmp, obj_lines):
    lines = mutate_lines(list(obj_lines), ["nan", "inf", "-inf", "1e39", "0", "-1", "999999",
                                           "1/2/3", "a", "//", "4294967297"],
                         ["f 1 1 1", "f 1 2", "f 1 2 3 4 5 6", "v 1 2", "v", "f -1 -2 -3",
                          "f 0 1 2", "mtllib nope.mtl"])
    if random.random() < 0.05:
        lines = []
    open(os.path.join(tmp, "scenes", "meshes", "table.obj"), "w").write("\n".join(lines))
    path = os.path.join(tmp, "scenes", "mesh.toml")
    if random.random() < 0.5:
        return [binary, "check", path], None
    return [binary, "sim", path, "--frames", "2", "--resolution", "6"], None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=["set", "scene", "checkpoint", "obj"])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "cloth"))
    a = ap.parse_args()
    random.seed(a.seed)
    tmp = tempfile.mkdtemp(prefix="cloth-fuzz-")
    os.makedirs(os.path.join(tmp, "scenes", "meshes"))
    shutil.copy(os.path.join(ROOT, "scenes", "mesh.toml"), os.path.join(tmp, "scenes"))
    obj_lines = open(os.path.join(ROOT, "scenes", "meshes", "table.obj")).read().split("\n")
    base = None
    if a.mode == "checkpoint":
        subprocess.run([a.bin, "sim", "drape", "--resolution", "8", "--frames", "4",
                        "--checkpoint-every", "2", "--out", os.path.join(tmp, "ck0")],
                       check=True, capture_output=True)
        base = json.load(open(os.path.join(tmp, "ck0", "checkpoint.json")))
    bad = 0
    for i in range(a.runs):
        if a.mode == "set":
            cmd, report = case_set(a.bin, tmp)
        elif a.mode == "scene":
            cmd, report = case_scene(a.bin, tmp)
        elif a.mode == "checkpoint":
            cmd, report = case_checkpoint(a.bin, tmp, base)
        else:
            cmd, report = case_obj(a.bin, tmp, obj_lines)
        why = run(cmd, tmp, report)
        if why:
            bad += 1
            keep = os.path.join(tmp, f"case-{i}")
            os.makedirs(keep)
            for f in ["scenes/s.toml", "checkpoint-in.json", "scenes/meshes/table.obj"]:
                if os.path.exists(os.path.join(tmp, f)):
                    shutil.copy(os.path.join(tmp, f), keep)
            print(f"{why}: {' '.join(cmd)}  (inputs in {keep})", flush=True)
    print(f"bad {bad} of {a.runs} ({a.mode}, seed {a.seed})")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
