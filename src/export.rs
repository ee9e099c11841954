//! Mesh export: OBJ frames and an animated glTF binary, written atomically.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use cloth_core::Topology;
use cloth_core::glam::Vec3;

/// Where a write to `path` lands: the path itself, or a symbolic link's target (the link is
/// kept: the file it points to is replaced); and whether that is a file that is not a regular
/// file (a device such as `/dev/stdout` or `/dev/null`, a FIFO), which is written in place:
/// renaming over it would replace the device with a regular file.
pub fn write_target(path: &Path) -> (PathBuf, bool) {
    let target = match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
        }
        _ => path.to_path_buf(),
    };
    let special = fs::metadata(&target).is_ok_and(|m| !m.is_file() && !m.is_dir());
    (target, special)
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, flushed and
/// synced, then renamed over `path`. A run that is killed leaves either the old file or the
/// whole new one, never a truncated file. When the write or the rename fails, the temporary
/// file is removed: a failed write leaves `path` as it was and nothing beside it.
///
/// A symbolic link is followed (its target is replaced, the link kept), and a file that is
/// not a regular file (`/dev/stdout`, a FIFO) is written in place ([`write_target`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let (path, special) = write_target(path);
    let path = path.as_path();
    if special {
        return fs::OpenOptions::new()
            .write(true)
            .open(path)
            .and_then(|mut f| f.write_all(bytes).and_then(|()| f.flush()))
            .with_context(|| format!("cannot write {}", path.display()));
    }
    let tmp = temporary_path(path);
    let mut file =
        fs::File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    let written = file
        .write_all(bytes)
        .and_then(|()| file.sync_all())
        .with_context(|| format!("cannot write {}", tmp.display()));
    drop(file);
    let result = written.and_then(|()| {
        fs::rename(&tmp, path)
            .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))
    });
    if result.is_err() {
        // The file was created above, so it is ours to remove.
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// The temporary file [`write_atomic`] writes `path` through: `.NAME.tmp` in its folder.
fn temporary_path(path: &Path) -> PathBuf {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    dir.join(format!(".{name}.tmp"))
}

/// Texture coordinates of a `rows × cols` grid: u along the columns, v along the rows, in
/// [0, 1].
pub fn grid_uvs(rows: usize, cols: usize) -> Vec<[f32; 2]> {
    let mut uv = Vec::with_capacity(rows * cols);
    for r in 0..rows {
        for c in 0..cols {
            uv.push([c as f32 / (cols - 1) as f32, r as f32 / (rows - 1) as f32]);
        }
    }
    uv
}

/// The cloth as Wavefront OBJ text: positions, normals, UVs and triangles.
pub fn obj(
    positions: &[Vec3],
    normals: &[Vec3],
    uvs: &[[f32; 2]],
    topology: &Topology,
    comment: &str,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(positions.len() * 96 + topology.triangles().len() * 40);
    let _ = writeln!(s, "# {comment}");
    let _ = writeln!(s, "o cloth");
    for p in positions {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for n in normals {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    for t in uvs {
        let _ = writeln!(s, "vt {} {}", t[0], t[1]);
    }
    for tri in topology.triangles() {
        let [a, b, c] = tri.map(|i| i + 1);
        let _ = writeln!(s, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
    }
    s
}

/// Collects frames for one animated glTF binary: the first frame is the base mesh, every frame
/// a morph target (its displacement from the base), played by a STEP weights animation.
#[derive(Debug, Default, Clone, serde::Serialize, serde::Deserialize)]
pub struct GlbFrames {
    /// Time of each frame, s.
    pub times: Vec<f32>,
    /// Positions of each frame.
    pub positions: Vec<Vec<[f32; 3]>>,
}

impl GlbFrames {
    /// Adds a frame at time `t`.
    pub fn push(&mut self, t: f32, positions: &[Vec3]) {
        self.times.push(t);
        self.positions
            .push(positions.iter().map(|p| p.to_array()).collect());
    }

    /// The glTF binary (`.glb`) of the collected frames.
    pub fn to_glb(&self, topology: &Topology, uvs: &[[f32; 2]]) -> Result<Vec<u8>> {
        use serde_json::json;
        let frames = self.positions.len();
        anyhow::ensure!(frames > 0, "no frames to write");
        let n = self.positions[0].len();
        let base: Vec<Vec3> = self.positions[0].iter().map(|p| Vec3::from(*p)).collect();
        let mut normals = Vec::new();
        topology.vertex_normals(&base, &mut normals);

        let mut bin: Vec<u8> = Vec::new();
        let mut views = Vec::new();
        let mut accessors = Vec::new();
        let mut push_view = |bin: &mut Vec<u8>, bytes: &[u8], target: Option<u32>| -> usize {
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            let offset = bin.len();
            bin.extend_from_slice(bytes);
            let mut view = json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() });
            if let Some(t) = target {
                view["target"] = json!(t);
            }
            views.push(view);
            views.len() - 1
        };
        let f32_bytes = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
        let bounds = |pts: &[[f32; 3]]| {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in pts {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            (lo, hi)
        };

        // Base attributes.
        let flat: Vec<f32> = self.positions[0].iter().flatten().copied().collect();
        let (lo, hi) = bounds(&self.positions[0]);
        let v = push_view(&mut bin, &f32_bytes(&flat), Some(34962));
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}));
        let flat: Vec<f32> = normals.iter().flat_map(|n| n.to_array()).collect();
        let v = push_view(&mut bin, &f32_bytes(&flat), Some(34962));
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3"}));
        let flat: Vec<f32> = uvs.iter().flatten().copied().collect();
        let v = push_view(&mut bin, &f32_bytes(&flat), Some(34962));
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC2"}));
        let idx: Vec<u8> = topology
            .triangles()
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let v = push_view(&mut bin, &idx, Some(34963));
        accessors.push(json!({"bufferView": v, "componentType": 5125, "count": topology.triangles().len() * 3, "type": "SCALAR"}));

        // One morph target per frame: displacement from the base.
        let mut targets = Vec::with_capacity(frames);
        for frame in &self.positions {
            let d: Vec<[f32; 3]> = frame
                .iter()
                .zip(&self.positions[0])
                .map(|(p, b)| [p[0] - b[0], p[1] - b[1], p[2] - b[2]])
                .collect();
            let (lo, hi) = bounds(&d);
            let flat: Vec<f32> = d.iter().flatten().copied().collect();
            let v = push_view(&mut bin, &f32_bytes(&flat), Some(34962));
            accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}));
            targets.push(json!({ "POSITION": accessors.len() - 1 }));
        }

        // Animation: at frame k's time, weight k is 1 and all others 0 (STEP).
        let (t0, t1) = (self.times[0], *self.times.last().unwrap_or(&0.0));
        let v = push_view(&mut bin, &f32_bytes(&self.times), None);
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": frames, "type": "SCALAR", "min": [t0], "max": [t1]}));
        let time_acc = accessors.len() - 1;
        let mut weights = vec![0.0f32; frames * frames];
        for k in 0..frames {
            weights[k * frames + k] = 1.0;
        }
        let v = push_view(&mut bin, &f32_bytes(&weights), None);
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": frames * frames, "type": "SCALAR"}));
        let weight_acc = accessors.len() - 1;
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }

        let mut initial = vec![0.0f32; frames];
        initial[0] = 1.0;
        let doc = json!({
            "asset": { "version": "2.0", "generator": concat!("cloth ", env!("CARGO_PKG_VERSION")) },
            "scene": 0,
            "scenes": [{ "nodes": [0] }],
            "nodes": [{ "mesh": 0, "name": "cloth" }],
            "materials": [{ "name": "cloth", "doubleSided": true,
                "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.3, 0.25, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8 } }],
            "meshes": [{ "name": "cloth", "weights": initial, "primitives": [{
                "attributes": { "POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2 },
                "indices": 3, "material": 0, "mode": 4, "targets": targets }] }],
            "animations": [{ "name": "simulation",
                "samplers": [{ "input": time_acc, "output": weight_acc, "interpolation": "STEP" }],
                "channels": [{ "sampler": 0, "target": { "node": 0, "path": "weights" } }] }],
            "buffers": [{ "byteLength": bin.len() }],
            "bufferViews": views,
            "accessors": accessors,
        });
        let mut json_bytes = serde_json::to_vec(&doc)?;
        while !json_bytes.len().is_multiple_of(4) {
            json_bytes.push(b' ');
        }
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: (12 + 8 + json_bytes.len() + 8 + bin.len()) as u32,
            },
            json: std::borrow::Cow::Owned(json_bytes),
            bin: Some(std::borrow::Cow::Owned(bin)),
        };
        Ok(glb.to_vec()?)
    }
}
