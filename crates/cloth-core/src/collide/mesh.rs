//! Static triangle meshes as colliders: a bounding-volume hierarchy for closest-point queries
//! and angle-weighted pseudo-normals for the inside/outside sign (Bærentzen & Aanæs 2005).
//!
//! A [`TriMesh`] is built once (from vertex and index arrays, or from an OBJ file) and shared
//! by [`Shape::Mesh`](super::Shape::Mesh) through an `Arc`; the shape carries the mesh's pose,
//! so a mesh collider can move and turn kinematically like the other shapes. Queries do not
//! allocate.

use glam::Vec3;

use crate::error::{ClothError, Result};

/// Largest number of triangles in a BVH leaf.
const LEAF_SIZE: usize = 4;
/// Depth of the traversal stack; the median split keeps the tree at most
/// ⌈log2(triangles / LEAF_SIZE)⌉ + 1 deep, so 64 covers any mesh that fits in memory.
const STACK: usize = 64;

/// One node of the hierarchy: an axis-aligned box and either two children or a leaf range.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Node {
    min: Vec3,
    max: Vec3,
    /// Leaf: first index into `order`; inner node: index of the first child (the second
    /// child follows it).
    first: u32,
    /// Leaf: number of triangles (`> 0`); inner node: 0.
    count: u32,
}

impl Node {
    /// Squared distance from `p` to the box (0 inside).
    #[inline]
    fn distance_squared(&self, p: Vec3) -> f32 {
        let d = (self.min - p).max(p - self.max).max(Vec3::ZERO);
        d.length_squared()
    }
}

/// Which feature of a triangle holds the closest point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Feature {
    Face,
    /// Edge from corner `k` to corner `(k + 1) % 3`.
    Edge(usize),
    Vertex(usize),
}

/// A closed (or open) triangle mesh with a BVH, in its own coordinates.
///
/// The signed distance is negative inside a closed, consistently oriented mesh
/// (counter-clockwise triangles seen from outside). For an open mesh the sign follows the
/// side of the nearest feature's pseudo-normal.
#[derive(Debug, Clone)]
pub struct TriMesh {
    vertices: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    face_normals: Vec<Vec3>,
    /// Angle-weighted pseudo-normal of each vertex.
    vertex_normals: Vec<Vec3>,
    /// Pseudo-normal of each triangle's three edges (mean of the adjacent faces' normals).
    edge_normals: Vec<[Vec3; 3]>,
    nodes: Vec<Node>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
}

impl PartialEq for TriMesh {
    fn eq(&self, other: &Self) -> bool {
        self.vertices == other.vertices && self.triangles == other.triangles
    }
}

impl TriMesh {
    /// A mesh from vertex positions (m) and triangles (indices into `vertices`,
    /// counter-clockwise seen from outside).
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] naming the offending entry when there are no
    /// triangles, a vertex is not finite or farther than
    /// [`MAX_COLLIDER_EXTENT`](super::MAX_COLLIDER_EXTENT) from the origin along an axis, an
    /// index is out of range or a triangle has zero area.
    pub fn new(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self> {
        if triangles.is_empty() {
            return Err(ClothError::invalid(
                "mesh.triangles",
                0,
                "at least one triangle",
            ));
        }
        for (i, v) in vertices.iter().enumerate() {
            super::range::point(v.to_array()).map_err(|allowed| {
                ClothError::invalid(format!("mesh.vertices[{i}]"), *v, allowed)
            })?;
        }
        let n = vertices.len();
        let mut face_normals = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(ClothError::invalid(
                    format!("mesh.triangles[{t}]"),
                    bad,
                    format!("vertex indices 0 ..< {n}"),
                ));
            }
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            let cross = (b - a).cross(c - a);
            let len = cross.length();
            if len.is_nan() || len <= 1e-12 {
                return Err(ClothError::invalid(
                    format!("mesh.triangles[{t}]"),
                    format!("{tri:?}"),
                    "a triangle of non-zero area",
                ));
            }
            face_normals.push(cross / len);
        }

        // Angle-weighted vertex pseudo-normals.
        let mut vertex_normals = vec![Vec3::ZERO; n];
        for (tri, &nrm) in triangles.iter().zip(&face_normals) {
            for k in 0..3 {
                let p = vertices[tri[k] as usize];
                let e1 = (vertices[tri[(k + 1) % 3] as usize] - p).normalize();
                let e2 = (vertices[tri[(k + 2) % 3] as usize] - p).normalize();
                let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                vertex_normals[tri[k] as usize] += angle * nrm;
            }
        }
        for v in &mut vertex_normals {
            *v = v.normalize_or_zero();
        }

        // Edge pseudo-normals: sort the half-edges by their undirected key and sum the face
        // normals of each group.
        let mut half: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (i, j) = (tri[k], tri[(k + 1) % 3]);
                half.push((i.min(j), i.max(j), t as u32, k as u8));
            }
        }
        half.sort_unstable();
        let mut edge_normals = vec![[Vec3::ZERO; 3]; triangles.len()];
        let mut start = 0;
        while start < half.len() {
            let key = (half[start].0, half[start].1);
            let mut end = start;
            let mut sum = Vec3::ZERO;
            while end < half.len() && (half[end].0, half[end].1) == key {
                sum += face_normals[half[end].2 as usize];
                end += 1;
            }
            let nrm = sum.normalize_or_zero();
            for h in &half[start..end] {
                edge_normals[h.2 as usize][h.3 as usize] = if nrm == Vec3::ZERO {
                    face_normals[h.2 as usize]
                } else {
                    nrm
                };
            }
            start = end;
        }

        let mut mesh = Self {
            vertices,
            triangles,
            face_normals,
            vertex_normals,
            edge_normals,
            nodes: Vec::new(),
            order: Vec::new(),
        };
        mesh.build_bvh();
        Ok(mesh)
    }

    /// Reads a mesh from Wavefront OBJ text (every object and group, triangulated; materials
    /// ignored). `name` is used in error messages.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] when the text is not a valid OBJ or the mesh is
    /// invalid (see [`new`](Self::new)).
    pub fn from_obj_str(text: &str, name: &str) -> Result<Self> {
        let mut reader = std::io::BufReader::new(text.as_bytes());
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| ClothError::invalid(name, format!("{e}"), "a valid Wavefront OBJ file"))?;
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for model in &models {
            let base = vertices.len() as u32;
            let m = &model.mesh;
            vertices.extend(
                m.positions
                    .chunks_exact(3)
                    .map(|p| Vec3::new(p[0], p[1], p[2])),
            );
            triangles.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|t| [base + t[0], base + t[1], base + t[2]]),
            );
        }
        Self::new(vertices, triangles).map_err(|e| match e {
            ClothError::InvalidArgument {
                name: field,
                value,
                allowed,
            } => ClothError::InvalidArgument {
                name: format!("{name}: {field}"),
                value,
                allowed,
            },
            other => other,
        })
    }

    /// Reads a mesh from an OBJ file.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] naming the path when it cannot be read or parsed.
    pub fn from_obj(path: impl AsRef<std::path::Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| {
            ClothError::invalid(
                path.display().to_string(),
                format!("{e}"),
                "a readable OBJ file",
            )
        })?;
        Self::from_obj_str(&text, &path.display().to_string())
    }

    /// Vertex positions, m (mesh coordinates).
    #[must_use]
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// Triangles, counter-clockwise seen from outside.
    #[must_use]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Unit normal of each triangle.
    #[must_use]
    pub fn face_normals(&self) -> &[Vec3] {
        &self.face_normals
    }

    /// The bounding box `(min, max)` of the mesh.
    #[must_use]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.nodes[0].min, self.nodes[0].max)
    }

    fn build_bvh(&mut self) {
        let centroids: Vec<Vec3> = self
            .triangles
            .iter()
            .map(|t| t.iter().map(|&i| self.vertices[i as usize]).sum::<Vec3>() / 3.0)
            .collect();
        self.order = (0..self.triangles.len() as u32).collect();
        self.nodes = vec![Node {
            min: Vec3::ZERO,
            max: Vec3::ZERO,
            first: 0,
            count: 0,
        }];
        // (node, start, end) ranges of `order` still to split.
        let mut todo = vec![(0usize, 0usize, self.order.len())];
        while let Some((node, start, end)) = todo.pop() {
            let (mut min, mut max) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
            let (mut cmin, mut cmax) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
            for &t in &self.order[start..end] {
                for &i in &self.triangles[t as usize] {
                    let v = self.vertices[i as usize];
                    min = min.min(v);
                    max = max.max(v);
                }
                cmin = cmin.min(centroids[t as usize]);
                cmax = cmax.max(centroids[t as usize]);
            }
            self.nodes[node].min = min;
            self.nodes[node].max = max;
            if end - start <= LEAF_SIZE {
                self.nodes[node].first = start as u32;
                self.nodes[node].count = (end - start) as u32;
                continue;
            }
            let ext = cmax - cmin;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = (start + end) / 2;
            self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
                centroids[a as usize][axis]
                    .total_cmp(&centroids[b as usize][axis])
                    .then(a.cmp(&b))
            });
            let child = self.nodes.len();
            let empty = Node {
                min: Vec3::ZERO,
                max: Vec3::ZERO,
                first: 0,
                count: 0,
            };
            self.nodes.push(empty);
            self.nodes.push(empty);
            self.nodes[node].first = child as u32;
            self.nodes[node].count = 0;
            todo.push((child, start, mid));
            todo.push((child + 1, mid, end));
        }
    }

    /// Signed distance from `p` (mesh coordinates) to the surface and the outward direction
    /// at the closest point, looking only within `max_distance`: when no surface point is
    /// that close, returns `(max_distance, Vec3::ZERO)` (treated as "far outside"). Points
    /// deeper inside than `max_distance` are therefore not seen; contact queries pass the
    /// contact thickness plus the substep's travel.
    #[must_use]
    pub fn distance_within(&self, p: Vec3, max_distance: f32) -> (f32, Vec3) {
        let mut best = max_distance * max_distance;
        let mut found: Option<(usize, Vec3, Feature)> = None;
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = self.nodes[stack[top] as usize];
            if node.distance_squared(p) > best {
                continue;
            }
            if node.count > 0 {
                let first = node.first as usize;
                for &t in &self.order[first..first + node.count as usize] {
                    let [a, b, c] = self.triangles[t as usize].map(|i| self.vertices[i as usize]);
                    let (q, feature) = closest_on_triangle(p, a, b, c);
                    let d = (p - q).length_squared();
                    if d < best || (d == best && found.is_none()) {
                        best = d;
                        found = Some((t as usize, q, feature));
                    }
                }
            } else if top + 2 <= STACK {
                // Visit the nearer child first (pushed last).
                let (l, r) = (node.first, node.first + 1);
                let dl = self.nodes[l as usize].distance_squared(p);
                let dr = self.nodes[r as usize].distance_squared(p);
                let (near, far) = if dl <= dr { (l, r) } else { (r, l) };
                stack[top] = far;
                stack[top + 1] = near;
                top += 2;
            }
        }
        let Some((t, q, feature)) = found else {
            return (max_distance, Vec3::ZERO);
        };
        let pseudo = match feature {
            Feature::Face => self.face_normals[t],
            Feature::Edge(k) => self.edge_normals[t][k],
            Feature::Vertex(k) => self.vertex_normals[self.triangles[t][k] as usize],
        };
        let d = p - q;
        let len = d.length();
        let sign = if d.dot(pseudo) < 0.0 { -1.0 } else { 1.0 };
        let nrm = if len > 1e-9 { sign * d / len } else { pseudo };
        (sign * len, nrm)
    }

    /// Signed distance from `p` (mesh coordinates) to the surface and the outward direction
    /// at the closest point.
    #[must_use]
    pub fn distance(&self, p: Vec3) -> (f32, Vec3) {
        self.distance_within(p, f32::MAX.sqrt())
    }
}

/// The closest point to `p` on triangle `abc` and the feature holding it (Ericson,
/// Real-Time Collision Detection, §5.1.5).
fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Feature) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + v * ab, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + w * ac, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + w * (c - b), Feature::Edge(1));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Feature::Face)
}

/// Closest point on triangle `abc` to `p` (for self-collision diagnostics).
#[must_use]
#[allow(dead_code)] // not called yet (kept for the collision work in progress)
pub(crate) fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    closest_on_triangle(p, a, b, c).0
}

/// A closed box mesh (12 triangles, outward counter-clockwise), for tests and examples.
#[must_use]
pub fn box_mesh(center: Vec3, half_extents: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut v = Vec::with_capacity(8);
    for i in 0..8 {
        let s = Vec3::new(
            if i & 1 == 0 { -1.0 } else { 1.0 },
            if i & 2 == 0 { -1.0 } else { 1.0 },
            if i & 4 == 0 { -1.0 } else { 1.0 },
        );
        v.push(center + s * half_extents);
    }
    let quads = [
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
    ];
    let mut t = Vec::with_capacity(12);
    for q in quads {
        t.push([q[0], q[1], q[2]]);
        t.push([q[0], q[2], q[3]]);
    }
    (v, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mesh_distance_matches_the_analytic_box() {
        let (v, t) = box_mesh(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.5, 0.25, 0.4));
        let mesh = TriMesh::new(v, t).unwrap();
        let shape = super::super::Shape::Box {
            center: Vec3::new(0.1, 0.2, 0.3),
            half_extents: Vec3::new(0.5, 0.25, 0.4),
            rotation: glam::Quat::IDENTITY,
        };
        // A deterministic cloud of points inside and outside.
        let mut s = 12345u32;
        let mut rnd = || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let p = Vec3::new(rnd(), rnd(), rnd()) * 1.2;
            let (dm, _) = mesh.distance(p);
            let (db, _) = shape.distance(p);
            assert!((dm - db).abs() < 1e-5, "{p}: mesh {dm} box {db}");
        }
    }
}

/// The serialised form of a mesh: its vertices and triangles (the BVH is rebuilt on load).
#[cfg(feature = "scene")]
#[derive(serde::Serialize, serde::Deserialize)]
struct TriMeshData {
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

#[cfg(feature = "scene")]
impl serde::Serialize for TriMesh {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        TriMeshData {
            vertices: self.vertices.iter().map(|v| v.to_array()).collect(),
            triangles: self.triangles.clone(),
        }
        .serialize(s)
    }
}

#[cfg(feature = "scene")]
impl<'de> serde::Deserialize<'de> for TriMesh {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let data = TriMeshData::deserialize(d)?;
        TriMesh::new(
            data.vertices.into_iter().map(Vec3::from).collect(),
            data.triangles,
        )
        .map_err(serde::de::Error::custom)
    }
}
