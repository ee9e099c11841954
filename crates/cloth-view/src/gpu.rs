//! The GPU: instance, adapter, device and queue, and the window surface (configure, resize,
//! lost/outdated frames).

use std::fmt;
use std::sync::Arc;

use winit::window::Window;

/// The apt line that installs software rendering and a virtual display on Debian.
pub const APT_HINT: &str = "apt-get install -y --no-install-recommends mesa-vulkan-drivers \
libvulkan1 libegl1 libegl-mesa0 libgl1-mesa-dri xvfb xauth libxcursor1 libxi6 libxkbcommon-x11-0";

/// Why the GPU could not be set up.
#[derive(Debug)]
pub enum GpuError {
    /// No adapter (no GPU and no software renderer).
    NoAdapter(String),
    /// The adapter refused to create a device.
    NoDevice(String),
    /// The window's surface could not be created.
    Surface(String),
}

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoAdapter(why) => write!(
                f,
                "no usable graphics adapter ({why}); on a machine without a GPU install Mesa's \
                 software renderer: {APT_HINT}"
            ),
            Self::NoDevice(why) => write!(f, "the graphics adapter refused a device: {why}"),
            Self::Surface(why) => write!(f, "cannot draw into the window: {why}"),
        }
    }
}

impl std::error::Error for GpuError {}

/// Instance, adapter, device and queue.
#[derive(Debug, Clone)]
pub struct Gpu {
    /// The wgpu instance.
    pub instance: wgpu::Instance,
    /// The adapter in use.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
}

impl Gpu {
    /// A GPU for rendering without a window (backends from `WGPU_BACKEND`, default all).
    ///
    /// # Errors
    /// [`GpuError::NoAdapter`] when there is no adapter at all.
    pub fn headless() -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        pollster::block_on(Self::with_instance(instance, None))
    }

    /// A GPU able to draw into `window`, and the window's surface.
    ///
    /// # Errors
    /// When there is no adapter compatible with the window or the surface cannot be made.
    pub fn for_window(
        display: winit::event_loop::OwnedDisplayHandle,
        window: Arc<Window>,
    ) -> Result<(Self, wgpu::Surface<'static>), GpuError> {
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(display)),
        );
        let surface = instance
            .create_surface(window)
            .map_err(|e| GpuError::Surface(e.to_string()))?;
        let gpu = pollster::block_on(Self::with_instance(instance, Some(&surface)))?;
        Ok((gpu, surface))
    }

    async fn with_instance(
        instance: wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Self, GpuError> {
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::from_env().unwrap_or_default(),
                force_fallback_adapter: false,
                compatible_surface: surface,
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("cloth-view device"),
                required_limits: wgpu::Limits::downlevel_webgl2_defaults()
                    .using_resolution(adapter.limits()),
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::NoDevice(e.to_string()))?;
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
        })
    }

    /// The largest MSAA sample count up to `want` that `format` supports here (1 if none).
    #[must_use]
    pub fn sample_count(&self, format: wgpu::TextureFormat, want: u32) -> u32 {
        let flags = self.adapter.get_texture_format_features(format).flags;
        let depth = self
            .adapter
            .get_texture_format_features(crate::renderer::DEPTH_FORMAT)
            .flags;
        [want, 8, 4, 2]
            .into_iter()
            .filter(|&n| n <= want && n > 1)
            .find(|&n| flags.sample_count_supported(n) && depth.sample_count_supported(n))
            .unwrap_or(1)
    }

    /// A one-line description of the adapter.
    #[must_use]
    pub fn adapter_name(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
    }
}

/// A window's surface and its configuration.
#[derive(Debug)]
pub struct WindowSurface {
    /// The surface.
    pub surface: wgpu::Surface<'static>,
    /// Its configuration (size, format, present mode).
    pub config: wgpu::SurfaceConfiguration,
    /// The longest side the device can draw (`max_texture_dimension_2d`): a larger window is
    /// drawn at most this large.
    max_side: u32,
    /// The last texture was suboptimal: configure again before taking the next one.
    stale: bool,
    /// The window is larger than the surface ([`surface_size`] clamped it): its textures stay
    /// suboptimal however often the surface is configured.
    clamped: bool,
}

/// Most pixels a window is drawn at (4096 × 4096): its multisampled colour and depth targets
/// take 32 bytes a pixel at 4× MSAA, half a GiB at this size.
pub const MAX_PIXELS: u64 = 4096 * 4096;

/// The surface size for a `width × height` window on a device whose textures are at most
/// `max_side` pixels a side: each side clamped to `1 ..= max_side`, then both scaled down
/// alike to at most [`MAX_PIXELS`]. A window can be made larger than any texture (e.g. 20000 ×
/// 20000 pixels on X11): configuring a surface that large is a validation error and allocating
/// its targets runs out of memory, both of which wgpu raises as panics. Such a window shows the
/// smaller image stretched or cropped, as the platform presents it.
#[must_use]
pub fn surface_size(width: u32, height: u32, max_side: u32) -> [u32; 2] {
    let max_side = max_side.max(1);
    let [w, h] = [width.clamp(1, max_side), height.clamp(1, max_side)];
    let pixels = u64::from(w) * u64::from(h);
    if pixels <= MAX_PIXELS {
        return [w, h];
    }
    let scale = (MAX_PIXELS as f64 / pixels as f64).sqrt();
    let side = |s: u32| ((f64::from(s) * scale).floor() as u32).max(1);
    [side(w), side(h)]
}

/// What [`WindowSurface::acquire`] got.
#[derive(Debug)]
pub enum Frame {
    /// A texture to draw into; present it with `queue.present`.
    Ready(wgpu::SurfaceTexture),
    /// Nothing to draw this time (minimised, occluded, timeout, reconfigured): try next frame.
    Skip,
}

impl WindowSurface {
    /// Configures `surface` for a `width × height` window (sRGB format if offered).
    ///
    /// # Errors
    /// When the surface is not supported by the adapter.
    pub fn new(
        gpu: &Gpu,
        surface: wgpu::Surface<'static>,
        width: u32,
        height: u32,
    ) -> Result<Self, GpuError> {
        let max_side = gpu.device.limits().max_texture_dimension_2d;
        let drawn = surface_size(width, height, max_side);
        let clamped = drawn != [width.max(1), height.max(1)];
        let mut config = surface
            .get_default_config(&gpu.adapter, drawn[0], drawn[1])
            .ok_or_else(|| GpuError::Surface("the adapter cannot present to it".into()))?;
        let caps = surface.get_capabilities(&gpu.adapter);
        if let Some(srgb) = caps
            .formats
            .iter()
            .copied()
            .find(wgpu::TextureFormat::is_srgb)
        {
            config.format = srgb;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&gpu.device, &config);
        Ok(Self {
            surface,
            config,
            max_side,
            stale: false,
            clamped,
        })
    }

    /// Follows a window resize; a zero side (minimised) keeps the old configuration, a side
    /// longer than the device can draw is clamped ([`surface_size`]). Returns the size drawn
    /// at, `[config.width, config.height]`.
    pub fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) -> [u32; 2] {
        if width > 0 && height > 0 {
            let drawn = surface_size(width, height, self.max_side);
            self.clamped = drawn != [width, height];
            [self.config.width, self.config.height] = drawn;
            self.surface.configure(&gpu.device, &self.config);
            self.stale = false;
        }
        [self.config.width, self.config.height]
    }

    /// The next texture to draw into; reconfigures the surface when it is lost or outdated.
    pub fn acquire(&mut self, gpu: &Gpu) -> Frame {
        if std::mem::take(&mut self.stale) {
            self.surface.configure(&gpu.device, &self.config);
        }
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => Frame::Ready(t),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                // Draw this one and reconfigure before the next: configuring while `t` is
                // alive is a validation error (a panic), which a resize could trigger. A
                // clamped surface is suboptimal by design: configuring it again every frame
                // would change nothing.
                self.stale = !self.clamped;
                Frame::Ready(t)
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&gpu.device, &self.config);
                Frame::Skip
            }
            _ => Frame::Skip,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{MAX_PIXELS, surface_size};

    /// A window resized to 20000 × 20000 pixels (xdotool windowsize under Xvfb) panicked in
    /// `Surface::configure` (larger than the 16384-pixel texture limit), and clamped to that
    /// limit it panicked allocating 8 GiB of multisampled targets. The size drawn at keeps
    /// within both, keeps the aspect when it scales, and leaves ordinary sizes alone.
    #[test]
    fn a_huge_window_is_drawn_at_a_size_the_device_can_hold() {
        assert_eq!(surface_size(640, 400, 16384), [640, 400]);
        assert_eq!(surface_size(1, 1, 16384), [1, 1]);
        assert_eq!(surface_size(0, 7, 16384), [1, 7]);
        assert_eq!(surface_size(4096, 4096, 16384), [4096, 4096]);
        for (w, h) in [
            (20000, 20000),
            (32767, 1),
            (16384, 16384),
            (8192, 8192),
            (30000, 500),
        ] {
            let [sw, sh] = surface_size(w, h, 16384);
            assert!(sw <= 16384 && sh <= 16384, "{w}x{h} -> {sw}x{sh}");
            assert!(
                u64::from(sw) * u64::from(sh) <= MAX_PIXELS,
                "{w}x{h} -> {sw}x{sh}"
            );
            assert!(sw >= 1 && sh >= 1);
        }
        let [sw, sh] = surface_size(8000, 4000, 16384);
        assert!(
            (f64::from(sw) / f64::from(sh) - 2.0).abs() < 1e-3,
            "{sw}x{sh}"
        );
        assert_eq!(surface_size(5000, 100, 2048), [2048, 100]);
    }
}
