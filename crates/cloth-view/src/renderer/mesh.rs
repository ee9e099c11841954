//! CPU-side geometry, rebuilt by `prepare`: the cloth's vertices with per-vertex normals from
//! the current positions, collider and ground meshes, and line lists.

use bytemuck::{Pod, Zeroable};
use cloth_core::glam::{Quat, Vec3};
use cloth_core::{Collider, Shape, SpringKind};

/// Material ids of [`MeshVertex::material`] (the `material` switch of `mesh.wgsl`).
pub mod material {
    /// The cloth: double-sided, patterned.
    pub const CLOTH: u32 = 0;
    /// A collider sphere.
    pub const SPHERE: u32 = 1;
    /// The ground.
    pub const GROUND: u32 = 2;
}

/// A vertex of a lit surface (`mesh.wgsl`'s `VertexIn`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MeshVertex {
    /// Position, m.
    pub position: [f32; 3],
    /// Unit normal.
    pub normal: [f32; 3],
    /// Texture coordinates (pattern space).
    pub uv: [f32; 2],
    /// One of [`material`].
    pub material: u32,
}

impl MeshVertex {
    /// The vertex buffer layout matching `mesh.wgsl`.
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: size_of::<Self>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Uint32],
    };
}

/// A vertex of a coloured line (`lines.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LineVertex {
    /// Position, m.
    pub position: [f32; 3],
    /// Colour, linear RGB.
    pub color: [f32; 3],
}

impl LineVertex {
    /// The vertex buffer layout matching `lines.wgsl`.
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: size_of::<Self>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
    };
}

pub use cloth_core::topology::vertex_normals;

/// Appends the cloth's vertices (a `rows × cols` grid) to `out`, UVs running 0..1 across it.
pub fn cloth_vertices(
    positions: &[Vec3],
    normals: &[Vec3],
    (rows, cols): (usize, usize),
    out: &mut Vec<MeshVertex>,
) {
    let du = 1.0 / (cols.max(2) - 1) as f32;
    let dv = 1.0 / (rows.max(2) - 1) as f32;
    out.extend(
        positions
            .iter()
            .zip(normals)
            .enumerate()
            .map(|(i, (p, n))| {
                let (r, c) = (i / cols.max(1), i % cols.max(1));
                MeshVertex {
                    position: p.to_array(),
                    normal: n.to_array(),
                    uv: [c as f32 * du, r as f32 * dv],
                    material: material::CLOTH,
                }
            }),
    );
}

/// Appends a UV sphere to `vertices`/`indices`.
pub fn sphere(center: Vec3, radius: f32, vertices: &mut Vec<MeshVertex>, indices: &mut Vec<u32>) {
    const STACKS: u32 = 24;
    const SLICES: u32 = 48;
    let base = vertices.len() as u32;
    for i in 0..=STACKS {
        let theta = std::f32::consts::PI * i as f32 / STACKS as f32;
        for j in 0..=SLICES {
            let phi = std::f32::consts::TAU * j as f32 / SLICES as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            vertices.push(MeshVertex {
                position: (center + n * radius).to_array(),
                normal: n.to_array(),
                uv: [j as f32 / SLICES as f32, i as f32 / STACKS as f32],
                material: material::SPHERE,
            });
        }
    }
    let row = SLICES + 1;
    for i in 0..STACKS {
        for j in 0..SLICES {
            let a = base + i * row + j;
            let b = a + row;
            // counter-clockwise seen from outside
            indices.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
}

/// Appends a capsule around the segment `a`–`b`: two hemispheres joined by a cylinder.
pub fn capsule(
    a: Vec3,
    b: Vec3,
    radius: f32,
    vertices: &mut Vec<MeshVertex>,
    indices: &mut Vec<u32>,
) {
    const STACKS: u32 = 24; // even: the equator ring is emitted twice, once per cap
    const SLICES: u32 = 48;
    let axis = (b - a).normalize_or(Vec3::Y);
    let t1 = axis.any_orthonormal_vector();
    let t2 = t1.cross(axis);
    let base = vertices.len() as u32;
    let rings: Vec<(u32, Vec3)> = (0..=STACKS / 2)
        .map(|i| (i, b))
        .chain((STACKS / 2..=STACKS).map(|i| (i, a)))
        .collect();
    for &(i, centre) in &rings {
        let theta = std::f32::consts::PI * i as f32 / STACKS as f32;
        for j in 0..=SLICES {
            let phi = std::f32::consts::TAU * j as f32 / SLICES as f32;
            let n = t1 * (theta.sin() * phi.cos())
                + axis * theta.cos()
                + t2 * (theta.sin() * phi.sin());
            vertices.push(MeshVertex {
                position: (centre + n * radius).to_array(),
                normal: n.to_array(),
                uv: [j as f32 / SLICES as f32, i as f32 / STACKS as f32],
                material: material::SPHERE,
            });
        }
    }
    let row = SLICES + 1;
    for r in 0..rings.len() as u32 - 1 {
        for j in 0..SLICES {
            let p = base + r * row + j;
            let q = p + row;
            indices.extend_from_slice(&[p, p + 1, q, p + 1, q + 1, q]);
        }
    }
}

/// Appends an oriented box.
pub fn cuboid(
    center: Vec3,
    half: Vec3,
    rotation: Quat,
    vertices: &mut Vec<MeshVertex>,
    indices: &mut Vec<u32>,
) {
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n_local = Vec3::ZERO;
            n_local[axis] = sign;
            let (u_axis, v_axis) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = vertices.len() as u32;
            let n = rotation * n_local;
            for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut local = n_local * half;
                local[u_axis] = su * half[u_axis];
                local[v_axis] = sv * half[v_axis];
                let p = center + rotation * local;
                vertices.push(MeshVertex {
                    position: p.to_array(),
                    normal: n.to_array(),
                    uv: [0.5 * (su + 1.0), 0.5 * (sv + 1.0)],
                    material: material::SPHERE,
                });
            }
            let p0 = Vec3::from(vertices[base as usize].position);
            let p1 = Vec3::from(vertices[base as usize + 1].position);
            let p2 = Vec3::from(vertices[base as usize + 2].position);
            if (p1 - p0).cross(p2 - p0).dot(n) > 0.0 {
                indices.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
            } else {
                indices.extend_from_slice(&[base, base + 2, base + 1, base, base + 3, base + 2]);
            }
        }
    }
}

/// Appends a square of side `2 * half` in the plane through `point` with `normal`, centred at
/// the point of the plane closest to `around`. UVs are world metres along the plane.
pub fn ground(
    point: Vec3,
    normal: Vec3,
    around: Vec3,
    half: f32,
    vertices: &mut Vec<MeshVertex>,
    indices: &mut Vec<u32>,
) {
    let n = normal.normalize_or(Vec3::Y);
    let centre = around - (around - point).dot(n) * n;
    let (t, b) = n.any_orthonormal_pair();
    let base = vertices.len() as u32;
    for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let p = centre + t * (su * half) + b * (sv * half);
        vertices.push(MeshVertex {
            position: p.to_array(),
            normal: n.to_array(),
            uv: [p.dot(t), p.dot(b)],
            material: material::GROUND,
        });
    }
    // wind so that the front face is the one the normal points to
    let (p0, p1, p2) = (
        Vec3::from(vertices[base as usize].position),
        Vec3::from(vertices[base as usize + 1].position),
        Vec3::from(vertices[base as usize + 2].position),
    );
    if (p1 - p0).cross(p2 - p0).dot(n) > 0.0 {
        indices.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    } else {
        indices.extend_from_slice(&[base, base + 2, base + 1, base, base + 3, base + 2]);
    }
}

/// Appends a triangle-mesh collider at its pose, flat shaded (three vertices per triangle
/// with the face normal, so hard edges stay sharp).
pub fn triangle_mesh(
    mesh: &cloth_core::collide::TriMesh,
    position: Vec3,
    rotation: Quat,
    vertices: &mut Vec<MeshVertex>,
    indices: &mut Vec<u32>,
) {
    for (tri, n) in mesh.triangles().iter().zip(mesh.face_normals()) {
        let base = vertices.len() as u32;
        let n = rotation * *n;
        for (k, &i) in tri.iter().enumerate() {
            let p = position + rotation * mesh.vertices()[i as usize];
            vertices.push(MeshVertex {
                position: p.to_array(),
                normal: n.to_array(),
                uv: [(k == 1) as u32 as f32, (k == 2) as u32 as f32],
                material: material::SPHERE,
            });
        }
        indices.extend_from_slice(&[base, base + 1, base + 2]);
    }
}

/// Appends the colliders' meshes; the planes become squares around `around`.
pub fn colliders(
    colliders: &[Collider],
    around: Vec3,
    vertices: &mut Vec<MeshVertex>,
    indices: &mut Vec<u32>,
) {
    for c in colliders {
        match c.shape {
            Shape::Mesh {
                ref mesh,
                position,
                rotation,
            } => triangle_mesh(mesh, position, rotation, vertices, indices),
            Shape::Sphere { center, radius } => sphere(center, radius, vertices, indices),
            Shape::Plane { point, normal } => {
                ground(point, normal, around, 12.0, vertices, indices);
            }
            Shape::Capsule { a, b, radius } => capsule(a, b, radius, vertices, indices),
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => cuboid(center, half_extents, rotation, vertices, indices),
        }
    }
}

/// The unique edges of `triangles`, each as `(low, high)`, sorted.
#[must_use]
pub fn unique_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// The colour of springs of one kind in the springs view (linear RGB).
#[must_use]
pub fn spring_color(kind: SpringKind) -> [f32; 3] {
    match kind {
        SpringKind::Warp => [0.9, 0.35, 0.1],
        SpringKind::Weft => [0.95, 0.65, 0.1],
        SpringKind::Shear => [0.2, 0.8, 0.3],
        SpringKind::Bend => [0.25, 0.45, 1.0],
    }
}

/// Appends the segment from `a` to `b`.
pub fn segment(a: Vec3, b: Vec3, color: [f32; 3], out: &mut Vec<LineVertex>) {
    out.push(LineVertex {
        position: a.to_array(),
        color,
    });
    out.push(LineVertex {
        position: b.to_array(),
        color,
    });
}

/// Appends a small three-axis cross at `p`.
pub fn cross(p: Vec3, size: f32, color: [f32; 3], out: &mut Vec<LineVertex>) {
    for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
        out.push(LineVertex {
            position: (p - axis * size).to_array(),
            color,
        });
        out.push(LineVertex {
            position: (p + axis * size).to_array(),
            color,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_grid_normals_point_along_the_winding() {
        let positions = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
        ];
        // counter-clockwise seen from +Y
        let triangles = [[0, 2, 1], [1, 2, 3]];
        let mut normals = Vec::new();
        vertex_normals(&positions, &triangles, &mut normals);
        for n in normals {
            assert!((n - Vec3::Y).length() < 1e-6, "{n}");
        }
    }

    #[test]
    fn normals_follow_a_fold() {
        // two triangles folded along the x axis like a roof
        let positions = [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let triangles = [[0, 1, 2], [1, 3, 2]];
        let mut normals = Vec::new();
        vertex_normals(&positions, &triangles, &mut normals);
        // the ridge vertex's normal is the average: straight up (or down), length 1
        assert!((normals[1].length() - 1.0).abs() < 1e-6);
        assert!(normals[1].z.abs() < 1e-6);
    }

    #[test]
    fn sphere_normals_point_out_and_triangles_wind_outwards() {
        let (mut v, mut i) = (Vec::new(), Vec::new());
        sphere(Vec3::new(1.0, 2.0, 3.0), 0.5, &mut v, &mut i);
        for t in i.chunks(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|k| Vec3::from(v[k as usize].position));
            let n = (b - a).cross(c - a);
            if n.length() > 1e-6 {
                assert!(n.dot((a + b + c) / 3.0 - Vec3::new(1.0, 2.0, 3.0)) > 0.0);
            }
        }
    }

    #[test]
    fn edges_of_two_triangles() {
        assert_eq!(unique_edges(&[[0, 1, 2], [1, 3, 2]]).len(), 5);
    }

    #[test]
    fn vertex_sizes_match_the_layouts() {
        assert_eq!(size_of::<MeshVertex>(), 36);
        assert_eq!(size_of::<LineVertex>(), 24);
    }
}
