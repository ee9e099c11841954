//! The renderer: [`Renderer::prepare`] turns a simulation's state into GPU buffers (uploads
//! only), [`Renderer::paint`] records the draws into a render pass. The same renderer draws
//! into the window and offscreen.
//!
//! What it draws: the cloth as a triangle mesh with per-vertex normals recomputed on the CPU
//! every frame, double-sided (the back uses the flipped normal and its own colour) with a
//! fabric pattern; the sphere colliders and the ground, lit the same way (Blinn-Phong, one
//! directional light from above-front); optionally the wireframe and the springs by class as
//! lines; markers on pinned particles. Depth-tested, MSAA when the target has samples.

pub mod mesh;

use bytemuck::{Pod, Zeroable};
use cloth_core::glam::{Mat4, Vec3};
use cloth_core::{Shape, Simulation, SpringKind};

use crate::camera::{Camera, Projection};
use mesh::{LineVertex, MeshVertex};

/// Depth buffer format.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The background colour as 8-bit sRGB: what an empty pixel holds after rendering into an sRGB
/// target.
pub const BACKGROUND_SRGB8: [u8; 3] = [40, 46, 58];

/// Converts an 8-bit sRGB channel to linear.
#[must_use]
pub fn srgb_to_linear(c: u8) -> f32 {
    let c = f32::from(c) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The background colour, linear (what the pass clears to).
#[must_use]
pub fn background_linear() -> [f32; 3] {
    BACKGROUND_SRGB8.map(srgb_to_linear)
}

/// Colour of collider contacts (linear RGB).
const CONTACT_COLLIDER: [f32; 3] = [0.1, 0.85, 0.95];
/// Colour of cloth–cloth contacts (linear RGB).
const CONTACT_CLOTH: [f32; 3] = [0.95, 0.2, 0.85];

/// What to draw besides the cloth, and how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Draw the cloth's triangle edges.
    pub wireframe: bool,
    /// Draw the springs, coloured by class (structural warp/weft orange, shear green, bend blue).
    pub springs: bool,
    /// Draw the cloth's surface.
    pub surface: bool,
    /// Mark pinned particles with small crosses.
    pub pins: bool,
    /// Draw the contacts: a short cyan line along the collider's normal at each particle
    /// touching a collider, and a magenta line between particles touching each other.
    pub contacts: bool,
    /// The fabric pattern on the cloth.
    pub pattern: bool,
    /// Height of a ground drawn for looks when the scene has no plane collider, m.
    pub floor: Option<f32>,
    /// Colour of the cloth's front (linear RGB).
    pub front_color: [f32; 3],
    /// Colour of the cloth's back (linear RGB).
    pub back_color: [f32; 3],
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            wireframe: false,
            springs: false,
            surface: true,
            pins: true,
            contacts: false,
            pattern: true,
            floor: None,
            front_color: [0.50, 0.07, 0.06],
            back_color: [0.80, 0.55, 0.16],
        }
    }
}

/// The uniforms shared by every pipeline (`struct Globals` in `shaders/*.wgsl`). Every field
/// is a 16-byte column or vector, so the Rust and WGSL layouts are the same (160 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// Projection × view.
    pub view_proj: [[f32; 4]; 4],
    /// xyz: eye position, m.
    pub eye: [f32; 4],
    /// xyz: unit vector towards the light.
    pub light_dir: [f32; 4],
    /// rgb: light colour; w: ambient strength.
    pub light_color: [f32; 4],
    /// rgb: cloth front colour; w: pattern squares across the cloth.
    pub cloth_front: [f32; 4],
    /// rgb: cloth back colour; w: 1 = pattern on.
    pub cloth_back: [f32; 4],
    /// rgb: background (fog) colour, linear; w: distance where fog starts, m.
    pub background: [f32; 4],
    /// xyz: centre of the sphere shadowing the ground; w: radius (0 = none).
    pub shadow_sphere: [f32; 4],
}

impl Globals {
    /// The uniforms for `camera`, `projection` and `options`; `shadow` is the sphere that
    /// shadows the ground, if any.
    #[must_use]
    pub fn new(
        camera: &Camera,
        projection: &Projection,
        options: &RenderOptions,
        shadow: Option<(Vec3, f32)>,
    ) -> Self {
        let vp: Mat4 = camera.view_proj(projection);
        let bg = background_linear();
        let (sc, sr) = shadow.unwrap_or((Vec3::ZERO, 0.0));
        Self {
            view_proj: vp.to_cols_array_2d(),
            eye: camera.eye.extend(1.0).to_array(),
            light_dir: light_direction().extend(0.0).to_array(),
            light_color: [1.0, 0.97, 0.92, 0.16],
            cloth_front: [
                options.front_color[0],
                options.front_color[1],
                options.front_color[2],
                8.0,
            ],
            cloth_back: [
                options.back_color[0],
                options.back_color[1],
                options.back_color[2],
                if options.pattern { 1.0 } else { 0.0 },
            ],
            background: [bg[0], bg[1], bg[2], 4.0 + 0.5 * camera.distance()],
            shadow_sphere: [sc.x, sc.y, sc.z, sr],
        }
    }
}

/// Unit vector towards the light: above, in front (+z) and to the left.
#[must_use]
pub fn light_direction() -> Vec3 {
    Vec3::new(-0.45, 1.0, 0.55).normalize()
}

/// A growable GPU buffer.
#[derive(Debug)]
struct DynBuffer {
    buffer: wgpu::Buffer,
    usage: wgpu::BufferUsages,
    label: &'static str,
    len: u32,
}

impl DynBuffer {
    fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages) -> Self {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        Self {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 256,
                usage,
                mapped_at_creation: false,
            }),
            usage,
            label,
            len: 0,
        }
    }

    /// Uploads `data` (growing the buffer if needed); `len` is the element count to draw.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, data: &[u8], len: usize) {
        let size = (data.len() as u64).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        if size > self.buffer.size() {
            self.buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: size.next_power_of_two(),
                usage: self.usage,
                mapped_at_creation: false,
            });
        }
        if !data.is_empty() {
            let mut padded;
            let bytes = if data.len() as u64 == size {
                data
            } else {
                padded = data.to_vec();
                padded.resize(size as usize, 0);
                &padded
            };
            queue.write_buffer(&self.buffer, 0, bytes);
        }
        self.len = len as u32;
    }
}

/// Colour and depth targets for one size and sample count; resolve into the final view.
#[derive(Debug)]
pub struct Targets {
    /// Multisampled colour (None when `samples == 1`: draw straight into the output).
    msaa: Option<wgpu::TextureView>,
    depth: wgpu::TextureView,
    /// Size in pixels.
    pub size: [u32; 2],
    /// MSAA samples.
    pub samples: u32,
}

impl Targets {
    /// Targets of `size` (sides clamped to ≥ 1) for colour `format` with `samples` samples.
    #[must_use]
    pub fn new(
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        size: [u32; 2],
        samples: u32,
    ) -> Self {
        let size = [size[0].max(1), size[1].max(1)];
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let make = |label, format, samples| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: extent,
                    mip_level_count: 1,
                    sample_count: samples,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        Self {
            msaa: (samples > 1).then(|| make("msaa colour", format, samples)),
            depth: make("depth", DEPTH_FORMAT, samples),
            size,
            samples,
        }
    }
}

/// Draws a [`Simulation`]: see the module docs.
#[derive(Debug)]
pub struct Renderer {
    mesh_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    globals: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    cloth_vertices: DynBuffer,
    cloth_indices: DynBuffer,
    /// (particles, triangles) of the uploaded cloth indices.
    cloth_key: (usize, usize),
    scene_vertices: DynBuffer,
    scene_indices: DynBuffer,
    lines: DynBuffer,
    edges: Vec<[u32; 2]>,
    // CPU scratch, kept between frames
    normals: Vec<Vec3>,
    mesh_scratch: Vec<MeshVertex>,
    index_scratch: Vec<u32>,
    line_scratch: Vec<LineVertex>,
    contact_scratch: Vec<cloth_core::Contact>,
    draw_surface: bool,
    color_format: wgpu::TextureFormat,
    samples: u32,
}

impl Renderer {
    /// A renderer drawing into `color_format` targets with `samples` MSAA samples.
    #[must_use]
    pub fn new(device: &wgpu::Device, color_format: wgpu::TextureFormat, samples: u32) -> Self {
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals"),
            size: size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("globals layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: wgpu::BufferSize::new(size_of::<Globals>() as u64),
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("cloth-view"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |label, source: &str, vertex: wgpu::VertexBufferLayout<'_>, topology| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    buffers: &[Some(vertex)],
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    front_face: wgpu::FrontFace::Ccw,
                    // the cloth is double-sided
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::LessEqual),
                    stencil: wgpu::StencilState::default(),
                    bias: wgpu::DepthBiasState::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: samples,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: color_format,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let mesh_pipeline = pipeline(
            "mesh",
            MESH_WGSL,
            MeshVertex::LAYOUT,
            wgpu::PrimitiveTopology::TriangleList,
        );
        let line_pipeline = pipeline(
            "lines",
            LINES_WGSL,
            LineVertex::LAYOUT,
            wgpu::PrimitiveTopology::LineList,
        );
        let vb = wgpu::BufferUsages::VERTEX;
        let ib = wgpu::BufferUsages::INDEX;
        Self {
            mesh_pipeline,
            line_pipeline,
            globals,
            bind_group,
            cloth_vertices: DynBuffer::new(device, "cloth vertices", vb),
            cloth_indices: DynBuffer::new(device, "cloth indices", ib),
            cloth_key: (usize::MAX, usize::MAX),
            scene_vertices: DynBuffer::new(device, "scene vertices", vb),
            scene_indices: DynBuffer::new(device, "scene indices", ib),
            lines: DynBuffer::new(device, "lines", vb),
            edges: Vec::new(),
            normals: Vec::new(),
            mesh_scratch: Vec::new(),
            index_scratch: Vec::new(),
            line_scratch: Vec::new(),
            contact_scratch: Vec::new(),
            draw_surface: true,
            color_format,
            samples,
        }
    }

    /// The colour format this renderer draws into.
    #[must_use]
    pub fn color_format(&self) -> wgpu::TextureFormat {
        self.color_format
    }

    /// MSAA samples of the targets it draws into.
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Uploads everything one frame of `sim` needs: uniforms, the cloth's vertices (normals
    /// recomputed from the positions), colliders, ground and lines.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        sim: &Simulation,
        camera: &Camera,
        projection: &Projection,
        options: &RenderOptions,
    ) {
        let positions = &sim.particles().position;
        let triangles = sim.topology().triangles();
        let shadow = sim.colliders().iter().find_map(|c| match c.shape {
            Shape::Sphere { center, radius } => Some((center, radius)),
            _ => None,
        });
        let globals = Globals::new(camera, projection, options, shadow);
        queue.write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));

        // cloth: indices only when the topology changes, vertices every frame
        let key = (positions.len(), triangles.len());
        if key != self.cloth_key {
            let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
            self.cloth_indices
                .upload(device, queue, bytemuck::cast_slice(&flat), flat.len());
            self.edges = mesh::unique_edges(triangles);
            self.cloth_key = key;
        }
        mesh::vertex_normals(positions, triangles, &mut self.normals);
        self.mesh_scratch.clear();
        mesh::cloth_vertices(
            positions,
            &self.normals,
            sim.grid_size(),
            &mut self.mesh_scratch,
        );
        self.cloth_vertices.upload(
            device,
            queue,
            bytemuck::cast_slice(&self.mesh_scratch),
            self.mesh_scratch.len(),
        );
        self.draw_surface = options.surface;

        // colliders and ground
        self.mesh_scratch.clear();
        self.index_scratch.clear();
        let around = camera.target;
        mesh::colliders(
            sim.colliders(),
            around,
            &mut self.mesh_scratch,
            &mut self.index_scratch,
        );
        let has_plane = sim
            .colliders()
            .iter()
            .any(|c| matches!(c.shape, Shape::Plane { .. }));
        if let (false, Some(y)) = (has_plane, options.floor) {
            mesh::ground(
                Vec3::new(0.0, y, 0.0),
                Vec3::Y,
                around,
                12.0,
                &mut self.mesh_scratch,
                &mut self.index_scratch,
            );
        }
        self.scene_vertices.upload(
            device,
            queue,
            bytemuck::cast_slice(&self.mesh_scratch),
            self.mesh_scratch.len(),
        );
        self.scene_indices.upload(
            device,
            queue,
            bytemuck::cast_slice(&self.index_scratch),
            self.index_scratch.len(),
        );

        // lines
        self.line_scratch.clear();
        let line = |out: &mut Vec<LineVertex>, a: u32, b: u32, color: [f32; 3]| {
            mesh::segment(positions[a as usize], positions[b as usize], color, out);
        };
        // Marker sizes follow the grid spacing.
        let spacing = positions
            .first()
            .zip(positions.get(1))
            .map_or(0.02, |(a, b)| a.distance(*b));
        if options.wireframe {
            let color = if options.surface {
                [0.05, 0.05, 0.06]
            } else {
                [0.85, 0.85, 0.9]
            };
            for &[a, b] in &self.edges {
                line(&mut self.line_scratch, a, b, color);
            }
        }
        if options.springs {
            for kind in SpringKind::ALL {
                let color = mesh::spring_color(kind);
                for s in sim.topology().springs_of(kind) {
                    line(&mut self.line_scratch, s.a, s.b, color);
                }
            }
        }
        if options.pins {
            let size = (0.35 * spacing).clamp(0.004, 0.03);
            for (i, p) in positions.iter().enumerate() {
                if sim.particles().is_pinned(i) {
                    mesh::cross(*p, size, [1.0, 0.85, 0.1], &mut self.line_scratch);
                }
            }
        }
        if options.contacts {
            self.contact_scratch.clear();
            sim.contacts(&mut self.contact_scratch);
            let length = (1.5 * spacing).clamp(0.01, 0.05);
            for c in &self.contact_scratch {
                let p = positions[c.particle as usize];
                match c.with {
                    cloth_core::ContactWith::Collider(_) => {
                        mesh::segment(
                            p,
                            p + length * c.normal,
                            CONTACT_COLLIDER,
                            &mut self.line_scratch,
                        );
                    }
                    cloth_core::ContactWith::Cloth(other) => {
                        // Each pair is listed from both ends: draw it once.
                        if c.particle < other {
                            line(&mut self.line_scratch, c.particle, other, CONTACT_CLOTH);
                        }
                    }
                }
            }
        }
        self.lines.upload(
            device,
            queue,
            bytemuck::cast_slice(&self.line_scratch),
            self.line_scratch.len(),
        );
    }

    /// Records the draws of the last [`prepare`](Self::prepare) into `pass`.
    pub fn paint(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&self.mesh_pipeline);
        if self.scene_indices.len > 0 {
            pass.set_vertex_buffer(0, self.scene_vertices.buffer.slice(..));
            pass.set_index_buffer(
                self.scene_indices.buffer.slice(..),
                wgpu::IndexFormat::Uint32,
            );
            pass.draw_indexed(0..self.scene_indices.len, 0, 0..1);
        }
        if self.draw_surface && self.cloth_indices.len > 0 {
            pass.set_vertex_buffer(0, self.cloth_vertices.buffer.slice(..));
            pass.set_index_buffer(
                self.cloth_indices.buffer.slice(..),
                wgpu::IndexFormat::Uint32,
            );
            pass.draw_indexed(0..self.cloth_indices.len, 0, 0..1);
        }
        if self.lines.len > 0 {
            pass.set_pipeline(&self.line_pipeline);
            pass.set_vertex_buffer(0, self.lines.buffer.slice(..));
            pass.draw(0..self.lines.len, 0..1);
        }
    }

    /// Begins a render pass that clears `targets` to the background and resolves into
    /// `output` (an image of `targets.size` in this renderer's format), paints into it and
    /// ends it.
    pub fn render(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        output: &wgpu::TextureView,
    ) {
        let bg = background_linear();
        let clear = wgpu::Color {
            r: f64::from(bg[0]),
            g: f64::from(bg[1]),
            b: f64::from(bg[2]),
            a: 1.0,
        };
        let (view, resolve_target) = match &targets.msaa {
            Some(msaa) => (msaa, Some(output)),
            None => (output, None),
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: if resolve_target.is_some() {
                        wgpu::StoreOp::Discard
                    } else {
                        wgpu::StoreOp::Store
                    },
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        self.paint(&mut pass);
    }
}

/// The lit-surface shader.
pub const MESH_WGSL: &str = include_str!("../shaders/mesh.wgsl");
/// The line shader.
pub const LINES_WGSL: &str = include_str!("../shaders/lines.wgsl");

#[cfg(test)]
mod tests {
    use super::*;

    /// Size and alignment of a struct named `name` in `source` as naga lays it out for a
    /// uniform buffer.
    fn wgsl_struct_layout(source: &str, name: &str) -> (u32, u32) {
        let module = naga::front::wgsl::parse_str(source).expect("valid WGSL");
        let mut layouter = naga::proc::Layouter::default();
        layouter
            .update(module.to_ctx())
            .expect("layout of the module's types");
        let (handle, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .expect("the struct is in the shader");
        let layout = layouter[handle];
        (layout.size, layout.alignment.round_up(1))
    }

    #[test]
    fn globals_match_the_wgsl_struct_in_every_shader() {
        assert_eq!(size_of::<Globals>() % 16, 0);
        for source in [MESH_WGSL, LINES_WGSL] {
            let (size, align) = wgsl_struct_layout(source, "Globals");
            assert_eq!(size as usize, size_of::<Globals>());
            assert_eq!(align, 16);
            assert!(align_of::<Globals>() <= 16);
        }
    }

    #[test]
    fn vertex_structs_match_the_wgsl_inputs() {
        let (size, _) = wgsl_struct_layout(MESH_WGSL, "VertexIn");
        // WGSL pads vec3 to 16 in structs; the vertex buffer is tightly packed instead, so
        // compare the attribute offsets of the layout against the Rust fields instead.
        assert!(size >= 36);
        let attrs = MeshVertex::LAYOUT.attributes;
        assert_eq!(
            attrs[1].offset as usize,
            std::mem::offset_of!(MeshVertex, normal)
        );
        assert_eq!(
            attrs[2].offset as usize,
            std::mem::offset_of!(MeshVertex, uv)
        );
        assert_eq!(
            attrs[3].offset as usize,
            std::mem::offset_of!(MeshVertex, material)
        );
        let attrs = LineVertex::LAYOUT.attributes;
        assert_eq!(
            attrs[1].offset as usize,
            std::mem::offset_of!(LineVertex, color)
        );
    }

    #[test]
    fn background_round_trips_through_srgb() {
        let lin = background_linear();
        for (l, s) in lin.iter().zip(BACKGROUND_SRGB8) {
            let back = if *l <= 0.003_130_8 {
                l * 12.92
            } else {
                1.055 * l.powf(1.0 / 2.4) - 0.055
            };
            assert_eq!((back * 255.0).round() as u8, s);
        }
    }
}
