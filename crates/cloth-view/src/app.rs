//! The window app: a winit [`ApplicationHandler`] that steps the simulation on a fixed-timestep
//! accumulator, turns input into camera motion, picking and panel actions, and draws with the
//! [`Renderer`] and egui.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use cloth_core::glam::{Vec2, Vec3};
use cloth_core::{Integrator, SimConfig, Simulation};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, ModifiersState, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::camera::{Camera, FlyController, OrbitController, Projection};
use crate::gpu::{Frame, Gpu, WindowSurface};
use crate::renderer::{RenderOptions, Renderer, Targets};
use crate::scene::SceneKind;
use crate::timestep::FixedStep;
use crate::ui::{Action, CameraMode, Panel, Status};

/// Steps allowed per frame before the simulation runs slower than real time.
pub const MAX_STEPS_PER_FRAME: u32 = 4;

/// What `cloth view` was asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewOptions {
    /// The scene.
    pub scene: SceneKind,
    /// Grid resolution.
    pub resolution: usize,
    /// The integrator.
    pub integrator: Integrator,
    /// Quit after this many frames.
    pub frames: Option<u64>,
    /// Initial window size, pixels.
    pub size: [u32; 2],
    /// Save the last frame (scene and panel) to this PNG before quitting (with `frames`).
    pub screenshot: Option<std::path::PathBuf>,
}

/// Opens the viewer window and runs until it is closed (or `options.frames` are drawn).
///
/// # Errors
/// When there is no display, no adapter, or the scene cannot be built.
pub fn run(options: ViewOptions) -> anyhow::Result<()> {
    let world = World::new(
        options.scene.clone(),
        options.resolution,
        options.integrator,
    )?;
    let event_loop = EventLoop::new().map_err(|e| anyhow!(no_window_message(&e, display_set())))?;
    if options.screenshot.is_some() && options.frames.is_none() {
        anyhow::bail!("a screenshot needs a frame count to take it at (--frames N)");
    }
    let mut app = App::new(options, world);
    if let Some(path) = std::env::var_os(LAYOUT_VAR).filter(|p| !p.is_empty()) {
        app.layout_file = Some(path.into());
        app.panel.layout = crate::ui::Layout::on();
    }
    event_loop.run_app(&mut app)?;
    if app.gfx.is_some() {
        eprintln!("cloth view: {}", app.summary());
    }
    match app.fatal {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The debugging hook's environment variable: `CLOTH_VIEW_LAYOUT=FILE cloth view` rewrites
/// `FILE` after every drawn frame with the viewer's state and where the panel's widgets are:
/// first the line the viewer prints on exit (`cloth view: ` and its summary), then one line
/// `x0 y0 x1 y1 LABEL` per labelled widget of the panel ([`crate::ui::Layout::widgets`]: the
/// part of it that takes the pointer, in window pixels with the origin at the top-left corner;
/// widgets scrolled out of view and a hidden panel's are left out). The file is written beside
/// it and renamed over it, so a reader never sees half of one; a failed write is said once and
/// turns the hook off. Scripts and the input tests (`tests/view_input.rs`) find and click the
/// panel's widgets with it. Unset or empty: nothing is recorded or written.
pub const LAYOUT_VAR: &str = "CLOTH_VIEW_LAYOUT";

/// Where to get a display: the end of every "no window" message.
const DISPLAY_HINT: &str = "set DISPLAY or WAYLAND_DISPLAY, or run under a virtual display \
with `xvfb-run -a cloth view` (apt-get install xvfb xauth); `cloth render` draws offscreen \
without one";

/// Whether the environment names a display to open a window on (`DISPLAY`, `WAYLAND_DISPLAY`
/// or `WAYLAND_SOCKET` set and not empty), as winit decides.
fn display_set() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// What to say when the event loop cannot be made: "no display" when none is set, else why
/// the display refused, without the source location winit puts in its OS errors.
fn no_window_message(error: &winit::error::EventLoopError, display_set: bool) -> String {
    if display_set {
        let why = error.to_string();
        format!(
            "cannot open a window on the display ({}); {DISPLAY_HINT}",
            without_location(&why)
        )
    } else {
        format!("no display: {DISPLAY_HINT}")
    }
}

/// `message` without the "os error at FILE.rs:LINE: " that winit's OS errors start with.
fn without_location(message: &str) -> &str {
    let Some(rest) = message.strip_prefix("os error at ") else {
        return message;
    };
    let mut search = 0;
    while let Some(at) = rest[search..].find(".rs:") {
        let after = &rest[search + at + ".rs:".len()..];
        let line = after.trim_start_matches(|c: char| c.is_ascii_digit());
        if line.len() < after.len()
            && let Some(why) = line.strip_prefix(": ")
        {
            return why;
        }
        search += at + 1;
    }
    message
}

/// The simulation and how it is being run.
#[derive(Debug)]
struct World {
    sim: Simulation,
    scene: SceneKind,
    resolution: usize,
    integrator: Integrator,
    stepper: FixedStep,
    paused: bool,
    message: Option<String>,
    sim_ms: f32,
    /// Simulated time of the last step whose linear solve stopped at its iteration cap
    /// (implicit Euler), for the status block ([`capped_recently`]).
    capped_at: Option<f64>,
}

impl World {
    fn new(scene: SceneKind, resolution: usize, integrator: Integrator) -> anyhow::Result<Self> {
        let sim = scene.build(resolution, integrator)?;
        let stepper = FixedStep::new(sim.config().dt, MAX_STEPS_PER_FRAME);
        Ok(Self {
            sim,
            scene,
            resolution,
            integrator,
            stepper,
            paused: false,
            message: None,
            sim_ms: 0.0,
            capped_at: None,
        })
    }

    /// Back to the initial state, keeping `config` if given.
    fn reset(&mut self, config: Option<SimConfig>) {
        match self.scene.build(self.resolution, self.integrator) {
            Ok(mut sim) => {
                self.message = None;
                // A kept configuration the rebuilt cloth refuses (the scene's own is used
                // instead) is said, not dropped.
                if let Some(c) = config
                    && let Err(e) = sim.set_config(c)
                {
                    self.message = Some(format!("kept the scene's settings: {e}"));
                }
                self.sim = sim;
                self.capped_at = None;
            }
            Err(e) => self.message = Some(e.to_string()),
        }
        self.stepper = FixedStep::new(self.sim.config().dt, MAX_STEPS_PER_FRAME);
    }

    /// One step, with the grabbed particle (if any) moved to its target. On instability the
    /// simulation keeps its last good state and the world pauses.
    fn step(&mut self, grab: Option<(usize, Vec3)>) -> bool {
        if let Some((i, target)) = grab {
            // A drag faster than the speed limit follows the cursor at that limit (the
            // library refuses a faster pin target).
            let reach = 0.99 * self.sim.pin_target_reach();
            let at = self.sim.particles().position[i];
            let _ = self
                .sim
                .set_pin_target(i, at + (target - at).clamp_length_max(reach));
        }
        match self.sim.step() {
            Ok(stats) => {
                if !stats.solver.converged {
                    self.capped_at = Some(stats.time);
                }
                true
            }
            Err(e) => {
                let msg = e.to_string();
                eprintln!("cloth: {msg}");
                self.message = Some(msg);
                self.paused = true;
                false
            }
        }
    }
}

/// What the mouse is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Drag {
    None,
    Orbit,
    Pan,
    Look,
    /// Holding particle `index` on the camera-facing plane through `plane`; `was_pinned`
    /// restores its pin on release.
    Grab {
        index: usize,
        plane: Vec3,
        target: Vec3,
        was_pinned: bool,
    },
}

/// The window, GPU and drawing state (exists between `resumed` and exit).
struct Gfx {
    window: Arc<Window>,
    gpu: Gpu,
    surface: WindowSurface,
    renderer: Renderer,
    targets: Targets,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
}

impl std::fmt::Debug for Gfx {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gfx")
            .field("adapter", &self.gpu.adapter_name())
            .field("size", &self.targets.size)
            .finish_non_exhaustive()
    }
}

/// The viewer application.
#[derive(Debug)]
struct App {
    options: ViewOptions,
    world: World,
    gfx: Option<Gfx>,
    camera: Camera,
    projection: Projection,
    orbit: OrbitController,
    fly: FlyController,
    mode: CameraMode,
    render: RenderOptions,
    panel: Panel,
    cursor: Vec2,
    modifiers: ModifiersState,
    drag: Drag,
    last_frame: Instant,
    fps: f32,
    frames: u64,
    /// Esc was pressed, at this frame count, with a screenshot to take: quit after the next
    /// drawn frame.
    quit_at: Option<u64>,
    /// The screenshot was written.
    shot_taken: bool,
    /// Particles grabbed with the mouse so far.
    grabs: u64,
    /// Where the [`LAYOUT_VAR`] hook writes (None: off).
    layout_file: Option<std::path::PathBuf>,
    fatal: Option<anyhow::Error>,
}

/// Frames drawn past the one a screenshot was due at before giving up on it (a window whose
/// surface gives no texture to draw into).
const SCREENSHOT_RETRIES: u64 = 120;

/// The pixel a grab follows for the cursor at `pos` in a `size` window: `pos` kept inside the
/// window. During a drag X reports the cursor outside the window too, and a window shrunk under
/// a held drag (to 1 × 1) put the cursor hundreds of window widths off its edge: the ray through
/// that pixel met the drag plane thousands of metres away, a paused drag moved the particle
/// there, and every later step failed with NaN positions until a reset.
fn grab_pixel(pos: Vec2, size: [u32; 2]) -> Vec2 {
    pos.clamp(Vec2::ZERO, Vec2::new(size[0] as f32, size[1] as f32))
}

/// Whether the viewer takes `key` before egui sees it: Tab shows and hides the panel, which egui
/// would otherwise use to move its keyboard focus through the panel's widgets (focusing the
/// "pause" button and so taking every later key: Space, R, W, K… did nothing).
fn viewer_key_first(key: PhysicalKey) -> bool {
    key == PhysicalKey::Code(KeyCode::Tab)
}

impl App {
    fn new(options: ViewOptions, world: World) -> Self {
        let scene = world.scene.clone();
        let (camera, fovy) = scene.start_view();
        Self {
            panel: Panel::new(scene.clone(), world.resolution, world.integrator),
            world,
            gfx: None,
            camera,
            projection: Projection::new(options.size[0], options.size[1], fovy),
            options,
            orbit: OrbitController::default(),
            fly: FlyController::default(),
            mode: CameraMode::Orbit,
            render: crate::default_options(&scene),
            cursor: Vec2::ZERO,
            modifiers: ModifiersState::empty(),
            drag: Drag::None,
            last_frame: Instant::now(),
            fps: 0.0,
            frames: 0,
            quit_at: None,
            shot_taken: false,
            grabs: 0,
            layout_file: None,
            fatal: None,
        }
    }

    fn init(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<Gfx> {
        let [w, h] = self.options.size;
        let attributes = Window::default_attributes()
            .with_title(format!("cloth — {}", self.world.scene))
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Arc::new(event_loop.create_window(attributes)?);
        let (gpu, surface) = Gpu::for_window(event_loop.owned_display_handle(), window.clone())?;
        let size = window.inner_size();
        let surface = WindowSurface::new(&gpu, surface, size.width, size.height)?;
        let format = surface.config.format;
        let samples = gpu.sample_count(format, 4);
        let renderer = Renderer::new(&gpu.device, format, samples);
        let targets = Targets::new(
            &gpu.device,
            format,
            [surface.config.width, surface.config.height],
            samples,
        );
        self.projection
            .resize(surface.config.width, surface.config.height);
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui_ctx.viewport_id(),
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
        eprintln!(
            "cloth view: {} on {}, {samples}x MSAA",
            self.world.scene,
            gpu.adapter_name()
        );
        Ok(Gfx {
            window,
            gpu,
            surface,
            renderer,
            targets,
            egui_ctx,
            egui_state,
            egui_renderer,
        })
    }

    /// The state at exit, one line: frames drawn, simulated time, pause, steps since the
    /// start or the last reset, camera, panel and display toggles, pins and the last message
    /// (for scripted runs and the input tests).
    fn summary(&self) -> String {
        let sim = &self.world.sim;
        let pinned = (0..sim.particles().len())
            .filter(|&i| sim.particles().is_pinned(i))
            .count();
        let on = |b: bool| if b { "on" } else { "off" };
        let mut line = format!(
            "{} frames, {} at t = {:.3} s{}, step {}, {} particles, {} (resolution {}), camera \
             {} at {:.3} m from its target (eye {:.3}), panel {}, wireframe {}, contacts {}, \
             {pinned} pinned, {} grabs, window {}x{}",
            self.frames,
            self.world.scene,
            sim.time(),
            if self.world.paused { " (paused)" } else { "" },
            sim.steps(),
            sim.particles().len(),
            self.world.integrator.name(),
            self.world.resolution,
            match self.mode {
                CameraMode::Orbit => "orbit",
                CameraMode::Fly => "fly",
            },
            self.camera.distance(),
            self.camera.eye,
            if self.panel.visible {
                "shown"
            } else {
                "hidden"
            },
            on(self.render.wireframe),
            on(self.render.contacts),
            self.grabs,
            self.window_size()[0],
            self.window_size()[1],
        );
        if let Some(m) = &self.world.message {
            line.push_str("; ");
            line.push_str(m);
        }
        line
    }

    fn grab_target(&self) -> Option<(usize, Vec3)> {
        match self.drag {
            Drag::Grab { index, target, .. } => Some((index, target)),
            _ => None,
        }
    }

    fn window_size(&self) -> [u32; 2] {
        self.gfx
            .as_ref()
            .map_or(self.options.size, |g| g.targets.size)
    }

    fn pick(&self) -> Option<(usize, f32)> {
        let ray = self
            .camera
            .ray_through(&self.projection, self.window_size(), self.cursor);
        ray.pick(
            &self.world.sim.particles().position,
            self.world.sim.topology().triangles(),
        )
    }

    fn reset_view(&mut self) {
        (self.camera, self.projection.fovy) = self.world.scene.start_view();
    }

    fn release_grab(&mut self) {
        if let Drag::Grab {
            index, was_pinned, ..
        } = self.drag
            && !was_pinned
        {
            let _ = self.world.sim.unpin(index);
        }
        self.drag = Drag::None;
    }

    fn on_mouse_button(&mut self, button: MouseButton, state: ElementState) {
        if state == ElementState::Released {
            self.release_grab();
            return;
        }
        let pin_click = self.modifiers.control_key() || self.modifiers.shift_key();
        self.drag = match (self.mode, button) {
            (_, MouseButton::Left) if pin_click => {
                if let Some((i, _)) = self.pick() {
                    let sim = &mut self.world.sim;
                    let _ = if sim.particles().is_pinned(i) {
                        sim.unpin(i)
                    } else {
                        sim.pin(i)
                    };
                }
                Drag::None
            }
            (CameraMode::Orbit, MouseButton::Left) => match self.pick() {
                Some((index, _)) => {
                    self.grabs += 1;
                    let was_pinned = self.world.sim.particles().is_pinned(index);
                    let _ = self.world.sim.pin(index);
                    let p = self.world.sim.particles().position[index];
                    Drag::Grab {
                        index,
                        plane: p,
                        target: p,
                        was_pinned,
                    }
                }
                None => Drag::Orbit,
            },
            (CameraMode::Orbit, _) => Drag::Pan,
            (CameraMode::Fly, _) => Drag::Look,
        };
    }

    fn on_cursor(&mut self, pos: Vec2) {
        let delta = pos - self.cursor;
        self.cursor = pos;
        let size = self.window_size();
        match self.drag {
            Drag::None => {}
            Drag::Orbit => self.orbit.rotate(&mut self.camera, delta.x, delta.y),
            Drag::Pan => {
                self.orbit.pan(
                    &mut self.camera,
                    &self.projection,
                    size[1],
                    delta.x,
                    delta.y,
                );
            }
            Drag::Look => self.fly.look(&mut self.camera, delta.x, delta.y),
            Drag::Grab {
                index,
                plane,
                was_pinned,
                ..
            } => {
                let ray = self
                    .camera
                    .ray_through(&self.projection, size, grab_pixel(pos, size));
                let normal = self.camera.forward();
                if let Some(t) = ray.hit_plane(plane, normal) {
                    let target = ray.at(t);
                    self.drag = Drag::Grab {
                        index,
                        plane,
                        target,
                        was_pinned,
                    };
                    if self.world.paused {
                        let _ = self.world.sim.set_position(index, target);
                    }
                }
            }
        }
    }

    fn on_key(&mut self, event_loop: &ActiveEventLoop, event: &KeyEvent) {
        let PhysicalKey::Code(code) = event.physical_key else {
            return;
        };
        let pressed = event.state == ElementState::Pressed;
        // held keys of the fly camera
        let keys = &mut self.fly.keys;
        match code {
            KeyCode::KeyW => keys.forward = pressed,
            KeyCode::KeyS => keys.back = pressed,
            KeyCode::KeyA => keys.left = pressed,
            KeyCode::KeyD => keys.right = pressed,
            KeyCode::KeyE | KeyCode::PageUp => keys.up = pressed,
            KeyCode::KeyQ | KeyCode::PageDown => keys.down = pressed,
            KeyCode::ShiftLeft | KeyCode::ShiftRight => keys.fast = pressed,
            _ => {}
        }
        if !pressed || event.repeat {
            return;
        }
        match code {
            KeyCode::Space => self.apply(Action::TogglePause),
            KeyCode::KeyN => self.apply(Action::Step),
            KeyCode::KeyR => self.apply(Action::Reset),
            KeyCode::KeyC => {
                self.mode = match self.mode {
                    CameraMode::Orbit => CameraMode::Fly,
                    CameraMode::Fly => CameraMode::Orbit,
                };
            }
            KeyCode::KeyW if self.mode == CameraMode::Orbit => {
                self.render.wireframe = !self.render.wireframe;
            }
            KeyCode::KeyK => self.render.contacts = !self.render.contacts,
            KeyCode::Home => self.apply(Action::ResetView),
            KeyCode::Escape if self.options.screenshot.is_some() && !self.shot_taken => {
                // the screenshot is of the last frame: draw one more
                self.quit_at.get_or_insert(self.frames);
            }
            KeyCode::Escape => event_loop.exit(),
            _ => {}
        }
    }

    fn apply(&mut self, action: Action) {
        let world = &mut self.world;
        match action {
            Action::TogglePause => {
                world.paused = !world.paused;
                world.stepper.reset();
            }
            Action::Step => {
                world.paused = true;
                let grab = self.grab_target();
                self.world.step(grab);
            }
            Action::Reset => {
                self.drag = Drag::None;
                let config = *world.sim.config();
                world.reset(Some(config));
            }
            Action::Rebuild {
                scene,
                resolution,
                integrator,
            } => {
                self.drag = Drag::None;
                let scene = *scene;
                let changed_scene = scene != world.scene;
                let (old_scene, old_res, old_int) =
                    (world.scene.clone(), world.resolution, world.integrator);
                world.scene = scene.clone();
                world.resolution = resolution;
                world.integrator = integrator;
                world.reset(None);
                if world.message.is_some() {
                    // keep running the old scene
                    world.scene = old_scene;
                    world.resolution = old_res;
                    world.integrator = old_int;
                } else if changed_scene {
                    self.render.floor = Some(scene.display_floor());
                    (self.camera, self.projection.fovy) = scene.start_view();
                    if let Some(g) = &self.gfx {
                        g.window.set_title(&format!("cloth — {scene}"));
                    }
                }
            }
            Action::Save(path) => {
                let saved = world
                    .scene
                    .effective(world.resolution, world.integrator)
                    .with_settings_of(&world.sim);
                world.message = Some(match std::fs::write(&path, saved.to_toml()) {
                    Ok(()) => format!("saved the scene to {}", path.display()),
                    Err(e) => format!("cannot save the scene to {}: {e}", path.display()),
                });
            }
            Action::Config(config) => match world.sim.set_config(config) {
                Ok(()) => {
                    world.stepper.set_dt(config.dt);
                    world.message = None;
                }
                Err(e) => world.message = Some(e.to_string()),
            },
            Action::Friction(friction) => {
                for i in 0..world.sim.colliders().len() {
                    let c = world.sim.colliders()[i].clone().with_friction(friction);
                    if let Err(e) = world.sim.set_collider(i, c) {
                        world.message = Some(e.to_string());
                    }
                }
            }
            Action::ResetView => self.reset_view(),
        }
    }

    fn status(&self, gpu: &Gpu) -> Status {
        let sim = &self.world.sim;
        let stats = sim.stats();
        Status {
            fps: self.fps,
            sim_ms: self.world.sim_ms,
            time: sim.time(),
            particles: sim.particles().len(),
            springs: sim.topology().springs().len(),
            energy: stats.total_energy(),
            max_strain: stats.max_strain.iter().copied().fold(0.0, f32::max),
            paused: self.world.paused,
            behind: self.world.stepper.behind(),
            solver_capped: capped_recently(self.world.capped_at, sim.time()),
            message: self.world.message.clone(),
            adapter: gpu.adapter_name(),
            friction: sim.colliders().first().map(|c| c.friction),
        }
    }

    /// One frame: step, update the camera, run the panel, draw.
    fn frame(&mut self, event_loop: &ActiveEventLoop) {
        let now = Instant::now();
        let elapsed = now - self.last_frame;
        self.last_frame = now;
        if elapsed > Duration::ZERO {
            let fps = 1.0 / elapsed.as_secs_f32();
            self.fps = if self.fps == 0.0 {
                fps
            } else {
                0.9 * self.fps + 0.1 * fps
            };
        }

        // simulation: whole fixed steps only
        if !self.world.paused {
            let n = self.world.stepper.steps(elapsed);
            let t0 = Instant::now();
            let grab = self.grab_target();
            let mut done = 0;
            for _ in 0..n {
                if !self.world.step(grab) {
                    break;
                }
                done += 1;
            }
            let ms = 1e3 * t0.elapsed().as_secs_f32();
            self.world.sim_ms = step_ms(self.world.sim_ms, ms, done);
        }
        if self.mode == CameraMode::Fly {
            self.fly
                .update(&mut self.camera, elapsed.as_secs_f32().min(0.1));
        }

        let Some(mut gfx) = self.gfx.take() else {
            return;
        };
        self.draw(&mut gfx);
        self.gfx = Some(gfx);

        self.frames += 1;
        self.write_layout();
        let due = self.quit_at.is_some() || self.options.frames.is_some_and(|n| self.frames >= n);
        if due && (self.options.screenshot.is_none() || self.shot_taken) {
            event_loop.exit();
        } else if due && self.frames >= self.shot_deadline() {
            self.fatal = Some(anyhow!(
                "no screenshot: the window gave no frame to draw into for {SCREENSHOT_RETRIES} \
                 frames"
            ));
            event_loop.exit();
        }
    }

    /// The [`LAYOUT_VAR`] hook, after each drawn frame (when on).
    fn write_layout(&mut self) {
        use std::fmt::Write as _;
        let (Some(path), Some(gfx)) = (&self.layout_file, &self.gfx) else {
            return;
        };
        let ppp = gfx.egui_ctx.pixels_per_point();
        let mut text = format!("cloth view: {}", self.summary());
        for (label, r) in self.panel.layout.widgets() {
            let _ = write!(
                text,
                "\n{:.1} {:.1} {:.1} {:.1} {label}",
                r.min.x * ppp,
                r.min.y * ppp,
                r.max.x * ppp,
                r.max.y * ppp
            );
        }
        text.push('\n');
        let mut tmp = path.clone().into_os_string();
        tmp.push(".tmp");
        if let Err(e) = std::fs::write(&tmp, text).and_then(|()| std::fs::rename(&tmp, path)) {
            eprintln!(
                "cloth view: cannot write the layout to {} ({LAYOUT_VAR}): {e}",
                path.display()
            );
            self.layout_file = None;
        }
    }

    /// The frame count past which a screenshot still not taken is given up.
    fn shot_deadline(&self) -> u64 {
        let due_at = self.quit_at.into_iter().chain(self.options.frames).min();
        due_at
            .unwrap_or(self.frames)
            .saturating_add(SCREENSHOT_RETRIES)
    }

    fn draw(&mut self, gfx: &mut Gfx) {
        // the panel
        let raw = gfx.egui_state.take_egui_input(&gfx.window);
        let status = self.status(&gfx.gpu);
        let config = *self.world.sim.config();
        let mut actions = Vec::new();
        let (panel, render, mode) = (&mut self.panel, &mut self.render, &mut self.mode);
        let mut full = gfx.egui_ctx.run_ui(raw, |ui| {
            actions = panel.show(ui, &config, render, mode, &status);
        });
        gfx.egui_state
            .handle_platform_output(&gfx.window, std::mem::take(&mut full.platform_output));
        for a in actions {
            self.apply(a);
        }
        // centre the scene in the part of the window the panel leaves free
        let panel_px = self.panel.width * full.pixels_per_point;
        self.projection.shift_x = panel_px / gfx.targets.size[0].max(1) as f32;

        let [w, h] = gfx.targets.size;
        let capture_due = self.options.screenshot.is_some()
            && !self.shot_taken
            && (self.quit_at.is_some()
                || self.options.frames.is_some_and(|n| self.frames + 1 >= n));
        let capture = capture_due.then(|| {
            let texture = gfx.gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("screenshot"),
                size: wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: gfx.surface.config.format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            (texture, view)
        });
        let frame = match gfx.surface.acquire(&gfx.gpu) {
            Frame::Ready(t) => Some(t),
            Frame::Skip => None,
        };
        let Gpu { device, queue, .. } = &gfx.gpu;
        // textures must be updated even when the frame is skipped
        for (id, deltas) in full.textures_delta.set.drain() {
            for delta in deltas {
                gfx.egui_renderer.update_texture(device, queue, id, &delta);
            }
        }
        let ppp = full.pixels_per_point;
        let jobs = gfx
            .egui_ctx
            .tessellate(std::mem::take(&mut full.shapes), ppp);
        if let Some(frame) = frame {
            let surface_view = frame
                .texture
                .create_view(&wgpu::TextureViewDescriptor::default());
            let view = capture.as_ref().map_or(&surface_view, |(_, v)| v);
            self.projection.resize(w, h);
            gfx.renderer.prepare(
                device,
                queue,
                &self.world.sim,
                &self.camera,
                &self.projection,
                &self.render,
            );
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
            gfx.renderer.render(&mut encoder, &gfx.targets, view);
            let screen = egui_wgpu::ScreenDescriptor {
                size_in_pixels: [w, h],
                pixels_per_point: ppp,
            };
            let extra =
                gfx.egui_renderer
                    .update_buffers(device, queue, &mut encoder, &jobs, &screen);
            {
                let mut pass = encoder
                    .begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("egui"),
                        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                            view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Load,
                                store: wgpu::StoreOp::Store,
                            },
                        })],
                        depth_stencil_attachment: None,
                        timestamp_writes: None,
                        occlusion_query_set: None,
                        multiview_mask: None,
                    })
                    .forget_lifetime();
                gfx.egui_renderer.render(&mut pass, &jobs, &screen);
            }
            queue.submit(extra.into_iter().chain([encoder.finish()]));
            if let (Some((texture, _)), Some(path)) = (&capture, &self.options.screenshot) {
                match save_screenshot(&gfx.gpu, texture, path) {
                    Ok(()) => self.shot_taken = true,
                    Err(e) => self.fatal = Some(e),
                }
            } else {
                gfx.window.pre_present_notify();
                queue.present(frame);
            }
        }
        for id in full.textures_delta.free.drain() {
            gfx.egui_renderer.free_texture(&id);
        }
    }
}

/// Reads back `texture` (the surface's format: RGBA or BGRA, 8 bits) and writes it as a PNG.
fn save_screenshot(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    path: &std::path::Path,
) -> anyhow::Result<()> {
    let size = [texture.width(), texture.height()];
    let readback = crate::offscreen::readback_buffer(&gpu.device, size);
    let mut pixels = crate::offscreen::read_texture(
        gpu,
        texture,
        &readback,
        crate::offscreen::padded_row(size[0]),
    )?;
    if matches!(
        texture.format(),
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    ) {
        for px in pixels.chunks_exact_mut(4) {
            px.swap(0, 2);
        }
    }
    let img = image::RgbaImage::from_raw(size[0], size[1], pixels)
        .ok_or_else(|| anyhow!("short screenshot readback"))?;
    img.save(path)
        .map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
    eprintln!("cloth view: wrote {}", path.display());
    Ok(())
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.init(event_loop) {
            Ok(gfx) => {
                gfx.window.request_redraw();
                self.gfx = Some(gfx);
                self.last_frame = Instant::now();
            }
            Err(e) => {
                self.fatal = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(gfx) = self.gfx.as_mut() else {
            return;
        };
        if let WindowEvent::KeyboardInput { event: key, .. } = &event
            && viewer_key_first(key.physical_key)
        {
            if key.state == ElementState::Pressed && !key.repeat {
                self.panel.visible = !self.panel.visible;
                if !self.panel.visible {
                    // the scene takes the whole window now, also for a click before the next
                    // frame is drawn
                    self.projection.shift_x = 0.0;
                }
                // a widget of the hidden panel keeps no keyboard focus
                gfx.egui_ctx.memory_mut(|m| {
                    if let Some(id) = m.focused() {
                        m.surrender_focus(id);
                    }
                });
            }
            return;
        }
        let response = gfx.egui_state.on_window_event(&gfx.window, &event);
        let egui_pointer = gfx.egui_ctx.egui_wants_pointer_input();
        let egui_keys = gfx.egui_ctx.egui_wants_keyboard_input();
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                // the size drawn at: a side past the device's limit is clamped
                let drawn = gfx.surface.resize(&gfx.gpu, size.width, size.height);
                if size.width > 0 && size.height > 0 && drawn != gfx.targets.size {
                    gfx.targets = Targets::new(
                        &gfx.gpu.device,
                        gfx.surface.config.format,
                        drawn,
                        gfx.renderer.samples(),
                    );
                    self.projection.resize(drawn[0], drawn[1]);
                }
                gfx.window.request_redraw();
            }
            WindowEvent::RedrawRequested => {
                let size = gfx.window.inner_size();
                if size.width == 0 || size.height == 0 {
                    // minimised: keep time from piling up, draw nothing
                    self.last_frame = Instant::now();
                    return;
                }
                self.frame(event_loop);
            }
            WindowEvent::ModifiersChanged(m) => self.modifiers = m.state(),
            WindowEvent::KeyboardInput { event, .. } if !response.consumed && !egui_keys => {
                self.on_key(event_loop, &event);
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.on_cursor(Vec2::new(position.x as f32, position.y as f32));
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let over_panel = response.consumed || egui_pointer;
                if state == ElementState::Released || !over_panel {
                    self.on_mouse_button(button, state);
                }
            }
            WindowEvent::MouseWheel { delta, .. } if !response.consumed => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.orbit.zoom(&mut self.camera, lines);
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(gfx) = &self.gfx {
            gfx.window.request_redraw();
        }
    }
}

/// Whether the status block says the linear solve was capped: a step capped within the last
/// [`CAPPED_HOLD`] of simulated time before `now` (`capped_at`: that step's time). Held, not
/// per step, so that a landing whose solves alternate between capped and converged does not
/// make the panel's lines jump every frame.
fn capped_recently(capped_at: Option<f64>, now: f64) -> bool {
    capped_at.is_some_and(|t| t <= now && now - t < CAPPED_HOLD)
}

/// How long (simulated seconds) the status block keeps saying a step's solve was capped.
const CAPPED_HOLD: f64 = 1.0;

/// The status line's simulation time: `elapsed_ms` spent on `steps` steps folded into the
/// smoothed `previous`, per step of the scene's dt (a "frame" as `cloth sim` counts and reports
/// them), not per drawn frame, which runs as many steps as are due: none (kept as it was) or
/// several (divided among them). The first sample is taken as it is.
fn step_ms(previous: f32, elapsed_ms: f32, steps: u32) -> f32 {
    if steps == 0 {
        return previous;
    }
    let ms = elapsed_ms / steps as f32;
    if previous == 0.0 {
        ms
    } else {
        0.9 * previous + 0.1 * ms
    }
}

#[cfg(test)]
mod tests {
    /// The status block says "capped" for [`super::CAPPED_HOLD`] of simulated time after a
    /// capped step and not before it, nor after a reset took the time back below it.
    #[test]
    fn a_capped_solve_is_said_for_a_second() {
        use super::capped_recently;
        assert!(!capped_recently(None, 3.0));
        assert!(capped_recently(Some(2.0), 2.0));
        assert!(capped_recently(Some(2.0), 2.9));
        assert!(!capped_recently(Some(2.0), 3.0));
        assert!(!capped_recently(Some(2.0), 1.5));
    }

    /// Without a display, `cloth view` said "no display to open a window on (os error at
    /// /root/.cargo/registry/src/…/winit-0.30.13/src/platform_impl/linux/mod.rs:765: …)": a
    /// build path. The message names only what to do.
    #[test]
    fn the_no_display_message_has_no_source_path() {
        let path = "/root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/\
                    winit-0.30.13/src/platform_impl/linux/mod.rs:765: ";
        let why = "neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set.";
        let raw = format!("os error at {path}{why}");
        assert_eq!(super::without_location(&raw), why);
        assert_eq!(super::without_location(why), why);
        assert_eq!(
            super::without_location("os error at odd"),
            "os error at odd"
        );
        let error = winit::error::EventLoopError::RecreationAttempt;
        let none = super::no_window_message(&error, false);
        assert!(
            none.starts_with("no display: set DISPLAY or WAYLAND_DISPLAY"),
            "{none}"
        );
        assert!(
            none.contains("xvfb-run") && none.contains("cloth render"),
            "{none}"
        );
        let refused = super::no_window_message(&error, true);
        assert!(
            refused.starts_with("cannot open a window on the display ("),
            "{refused}"
        );
        assert!(!refused.contains(".rs:"), "{refused}");
    }

    /// The status line's "sim ms/frame" is per simulation step (as `cloth sim` reports it):
    /// a drawn frame that ran four steps in 40 ms shows 10 ms, one that ran none keeps it.
    #[test]
    fn status_time_is_per_simulation_step() {
        let first = super::step_ms(0.0, 40.0, 4);
        assert_eq!(first, 10.0);
        assert_eq!(super::step_ms(first, 3.0, 0), first);
        let next = super::step_ms(first, 60.0, 3);
        assert!((next - (0.9 * 10.0 + 0.1 * 20.0)).abs() < 1e-6, "{next}");
    }

    /// Tab showed and hid the panel only when egui did not want it, and egui takes Tab to move
    /// its keyboard focus: Tab focused the panel's "pause" button instead, and every later key
    /// (Space, R, W, K…) went to egui. The viewer now takes Tab before egui sees it (the Xvfb
    /// test `tests/view_input.rs` drives this with real key events).
    #[test]
    fn tab_goes_to_the_viewer_before_egui() {
        use winit::keyboard::{KeyCode, PhysicalKey};
        assert!(super::viewer_key_first(PhysicalKey::Code(KeyCode::Tab)));
        for other in [
            KeyCode::Space,
            KeyCode::KeyW,
            KeyCode::Escape,
            KeyCode::KeyA,
        ] {
            assert!(
                !super::viewer_key_first(PhysicalKey::Code(other)),
                "{other:?}"
            );
        }
    }

    /// A grab follows the cursor only within the window: a cursor 300 px off a 1 × 1 window
    /// put the grabbed particle kilometres away (and the steps after it at NaN).
    #[test]
    fn a_grab_follows_the_cursor_within_the_window() {
        use cloth_core::glam::{Vec2, Vec3};
        let size = [1, 1];
        assert_eq!(super::grab_pixel(Vec2::new(300.0, 300.0), size), Vec2::ONE);
        assert_eq!(
            super::grab_pixel(Vec2::new(-5.0, 0.5), size),
            Vec2::new(0.0, 0.5)
        );
        let inside = Vec2::new(320.0, 35.0);
        assert_eq!(super::grab_pixel(inside, [640, 400]), inside);
        // the drag plane is met near the grabbed point for every pixel the grab can follow
        let (camera, fovy) = (crate::Camera::looking_at(Vec3::ZERO, 2.0), crate::FOVY);
        let projection = crate::Projection::new(1, 1, fovy);
        for pos in [Vec2::new(300.0, 300.0), Vec2::new(-4000.0, 9000.0)] {
            let ray = camera.ray_through(&projection, size, super::grab_pixel(pos, size));
            let t = ray.hit_plane(Vec3::ZERO, camera.forward()).expect("hit");
            assert!(ray.at(t).length() < 2.0, "{pos} -> {}", ray.at(t));
        }
    }

    /// The panel's rebuild switches scene and integrator at run time, here every built-in
    /// scene with every integrator, each while a particle of the previous cloth is held (an
    /// index that may not exist in the next one), then stepped with a grab, reset while
    /// grabbing, stepped again: no panic, the grab gone after each rebuild and reset, a finite
    /// state (a step may fail: forward Euler does, and the world pauses with a message).
    #[test]
    fn rebuilding_every_scene_and_integrator_while_grabbing() {
        use super::{Action, App, Drag, ViewOptions, World};
        use cloth_core::glam::Vec3;
        let scene = crate::scene::SceneKind::builtin("drape").expect("drape");
        let world = World::new(scene.clone(), 8, cloth_core::Integrator::Xpbd).expect("world");
        let options = ViewOptions {
            scene,
            resolution: 8,
            integrator: cloth_core::Integrator::Xpbd,
            frames: None,
            size: [64, 64],
            screenshot: None,
        };
        let mut app = App::new(options, world);
        let grab = |app: &mut App| {
            let index = app.world.sim.particles().len() - 1;
            let _ = app.world.sim.pin(index);
            let p = app.world.sim.particles().position[index];
            app.drag = Drag::Grab {
                index,
                plane: p,
                target: p + Vec3::new(0.05, 0.05, 0.0),
                was_pinned: false,
            };
        };
        for scene in crate::scene::SceneKind::all() {
            for integrator in cloth_core::Integrator::ALL {
                grab(&mut app);
                app.apply(Action::Rebuild {
                    scene: Box::new(scene.clone()),
                    resolution: 6,
                    integrator,
                });
                let name = format!("{} {}", scene.name(), integrator.name());
                assert_eq!(app.world.message, None, "{name}");
                assert_eq!(app.drag, Drag::None, "{name}");
                assert_eq!(app.world.integrator, integrator, "{name}");
                grab(&mut app);
                for _ in 0..3 {
                    let target = app.grab_target();
                    app.world.step(target);
                }
                app.apply(Action::Reset);
                assert_eq!(app.drag, Drag::None, "{name}");
                app.apply(Action::Step);
                let sim = &app.world.sim;
                assert!(
                    sim.particles().position.iter().all(|p| p.is_finite()),
                    "{name}"
                );
                assert!(sim.time().is_finite(), "{name}");
            }
        }
    }

    /// Reset keeps the running configuration; one the rebuilt cloth refuses (here a
    /// self-collision layer thicker than 16 grid spacings) is said in the status line and the
    /// scene's own configuration runs instead, and a good one clears the message.
    #[test]
    fn a_refused_configuration_on_reset_is_said() {
        let scene = crate::scene::SceneKind::builtin("sweep").expect("sweep");
        let mut world = super::World::new(scene, 32, cloth_core::Integrator::Xpbd).expect("world");
        let own = *world.sim.config();
        let mut thick = own;
        thick.self_collision = Some(cloth_core::SelfCollision {
            thickness: 1.0,
            ..cloth_core::SelfCollision::default()
        });
        world.reset(Some(thick));
        let message = world.message.clone().expect("a message");
        assert!(message.contains("kept the scene's settings"), "{message}");
        assert!(message.contains("self_collision.thickness"), "{message}");
        assert_eq!(*world.sim.config(), own);
        world.reset(Some(own));
        assert_eq!(world.message, None);
    }
}
