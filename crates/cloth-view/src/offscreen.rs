//! Rendering without a window: one frame of a simulation into an RGBA image (PNG-ready).

use image::RgbaImage;

use crate::camera::{Camera, Projection};
use crate::gpu::Gpu;
use crate::renderer::{RenderOptions, Renderer, Targets};
use cloth_core::Simulation;

/// The colour format of offscreen images (8-bit sRGB, RGBA order).
pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// Draws frames of `width × height` offscreen with the viewer's renderer (MSAA 4× where the
/// adapter supports it) and reads them back.
#[derive(Debug)]
pub struct Offscreen {
    gpu: Gpu,
    renderer: Renderer,
    targets: Targets,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    /// Vertical field of view of the projection, radians.
    fovy: f32,
}

/// Bytes per row of a readback buffer for `width` pixels of 4 bytes (padded to 256).
#[must_use]
pub fn padded_row(width: u32) -> u32 {
    (4 * width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

/// A buffer to read back a `size` texture of 4-byte pixels into.
#[must_use]
pub fn readback_buffer(device: &wgpu::Device, size: [u32; 2]) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: u64::from(padded_row(size[0])) * u64::from(size[1].max(1)),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    })
}

/// Copies `texture` (4 bytes per pixel, COPY_SRC) into `readback` and returns its pixels,
/// tightly packed row by row. Waits for the GPU.
///
/// # Errors
/// When the GPU cannot be waited for or the buffer cannot be mapped.
pub fn read_texture(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    readback: &wgpu::Buffer,
    padded_row: u32,
) -> anyhow::Result<Vec<u8>> {
    let (w, h) = (texture.width(), texture.height());
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
    );
    gpu.queue.submit([encoder.finish()]);
    let slice = readback.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| anyhow::anyhow!("waiting for the GPU: {e}"))?;
    rx.recv()?
        .map_err(|e| anyhow::anyhow!("mapping the readback buffer: {e}"))?;
    let mut pixels = Vec::with_capacity((4 * w * h) as usize);
    {
        let data = slice
            .get_mapped_range()
            .map_err(|e| anyhow::anyhow!("reading the readback buffer: {e}"))?;
        for row in data.chunks(padded_row as usize).take(h as usize) {
            pixels.extend_from_slice(&row[..(4 * w) as usize]);
        }
    }
    readback.unmap();
    Ok(pixels)
}

impl Offscreen {
    /// An offscreen target of `size` pixels on `gpu`.
    #[must_use]
    pub fn new(gpu: Gpu, size: [u32; 2]) -> Self {
        let size = [size[0].max(1), size[1].max(1)];
        let samples = gpu.sample_count(FORMAT, 4);
        let renderer = Renderer::new(&gpu.device, FORMAT, samples);
        let targets = Targets::new(&gpu.device, FORMAT, size, samples);
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen"),
            size: wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let padded_row = padded_row(size[0]);
        let readback = readback_buffer(&gpu.device, size);
        Self {
            gpu,
            renderer,
            targets,
            texture,
            view,
            readback,
            padded_row,
            fovy: crate::FOVY,
        }
    }

    /// Image size in pixels.
    #[must_use]
    pub fn size(&self) -> [u32; 2] {
        self.targets.size
    }

    /// MSAA samples in use.
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.targets.samples
    }

    /// A projection matching this target's aspect ratio, at the field of view set by
    /// [`Offscreen::set_fovy`] ([`crate::FOVY`] until then).
    #[must_use]
    pub fn projection(&self) -> Projection {
        let [w, h] = self.size();
        Projection::new(w, h, self.fovy)
    }

    /// Sets the vertical field of view of the renders that follow, radians (e.g.
    /// the field of view of [`crate::SceneKind::start_view`]).
    pub fn set_fovy(&mut self, fovy: f32) {
        self.fovy = fovy;
    }

    /// Renders `sim` seen by `camera` and returns the image.
    ///
    /// # Errors
    /// When the frame cannot be read back.
    pub fn render(
        &mut self,
        sim: &Simulation,
        camera: &Camera,
        options: &RenderOptions,
    ) -> anyhow::Result<RgbaImage> {
        let projection = self.projection();
        let Gpu { device, queue, .. } = &self.gpu;
        self.renderer
            .prepare(device, queue, sim, camera, &projection, options);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("offscreen"),
        });
        self.renderer
            .render(&mut encoder, &self.targets, &self.view);
        queue.submit([encoder.finish()]);
        let [w, h] = self.size();
        let pixels = read_texture(&self.gpu, &self.texture, &self.readback, self.padded_row)?;
        RgbaImage::from_raw(w, h, pixels).ok_or_else(|| anyhow::anyhow!("short readback"))
    }
}
