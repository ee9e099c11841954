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
        let mut config = surface
            .get_default_config(&gpu.adapter, width.max(1), height.max(1))
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
        Ok(Self { surface, config })
    }

    /// Follows a window resize; a zero side (minimised) keeps the old configuration.
    pub fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&gpu.device, &self.config);
    }

    /// The next texture to draw into; reconfigures the surface when it is lost or outdated.
    pub fn acquire(&mut self, gpu: &Gpu) -> Frame {
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => Frame::Ready(t),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                // draw this one, reconfigure for the next
                self.surface.configure(&gpu.device, &self.config);
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
