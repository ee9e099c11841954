//! The egui side panel: scene and integrator, time step, material, forces, friction,
//! resolution, display toggles, and a status block. It only reads the simulation's state and
//! returns [`Action`]s; the app applies them.

use cloth_core::glam::Vec3;
use cloth_core::{Friction, Gust, Integrator, SimConfig, SpringParams};

use crate::renderer::RenderOptions;
use crate::scene::SceneKind;

/// Which camera controller is active.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CameraMode {
    /// Orbit around a target.
    #[default]
    Orbit,
    /// Fly through the scene.
    Fly,
}

/// What the panel asks the app to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Build a new simulation.
    Rebuild {
        /// The scene.
        scene: Box<SceneKind>,
        /// Grid resolution.
        resolution: usize,
        /// The integrator.
        integrator: Integrator,
    },
    /// Write the current settings as a scene file that reproduces them.
    Save(std::path::PathBuf),
    /// Replace the simulation's parameters.
    Config(SimConfig),
    /// Set every collider's friction.
    Friction(Friction),
    /// Reset the scene to its initial state (keeping edited parameters).
    Reset,
    /// Pause or resume.
    TogglePause,
    /// Advance exactly one step.
    Step,
    /// Put the camera back where it started.
    ResetView,
}

/// Numbers the status block shows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Status {
    /// Frames per second (smoothed).
    pub fps: f32,
    /// Wall time of one simulation step of the scene's dt (a frame as `cloth sim` counts and
    /// reports them; a drawn frame runs as many steps as are due), ms (smoothed).
    pub sim_ms: f32,
    /// Simulated time, s.
    pub time: f64,
    /// Particles.
    pub particles: usize,
    /// Springs.
    pub springs: usize,
    /// Total energy, J.
    pub energy: f64,
    /// Largest strain over all spring classes.
    pub max_strain: f32,
    /// Paused.
    pub paused: bool,
    /// The simulation runs slower than real time.
    pub behind: bool,
    /// The last instability or parameter error.
    pub message: Option<String>,
    /// The graphics adapter.
    pub adapter: String,
    /// Current friction of the colliders (None: no colliders).
    pub friction: Option<Friction>,
}

/// The panel's own state: choices that take effect on "rebuild".
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Scene to build.
    pub scene: SceneKind,
    /// Resolution to build.
    pub resolution: usize,
    /// Integrator to build with.
    pub integrator: Integrator,
    /// Where "save scene" writes.
    pub save_path: String,
    /// Whether the panel is shown.
    pub visible: bool,
    /// Width the panel took in the last frame, points (0 when hidden).
    pub width: f32,
}

impl Panel {
    /// A panel whose choices start as the running simulation's.
    #[must_use]
    pub fn new(scene: SceneKind, resolution: usize, integrator: Integrator) -> Self {
        Self {
            scene,
            resolution,
            integrator,
            save_path: "my-scene.toml".into(),
            visible: true,
            width: 0.0,
        }
    }

    /// Draws the panel into `ui` and returns what the user asked for.
    pub fn show(
        &mut self,
        ui: &mut egui::Ui,
        config: &SimConfig,
        options: &mut RenderOptions,
        mode: &mut CameraMode,
        status: &Status,
    ) -> Vec<Action> {
        let mut actions = Vec::new();
        if !self.visible {
            self.width = 0.0;
            return actions;
        }
        let response = egui::Panel::left("cloth-panel")
            .default_size(270.0)
            .resizable(true)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    self.contents(ui, config, options, mode, status, &mut actions);
                });
            });
        self.width = response.response.rect.width();
        actions
    }

    fn contents(
        &mut self,
        ui: &mut egui::Ui,
        config: &SimConfig,
        options: &mut RenderOptions,
        mode: &mut CameraMode,
        status: &Status,
        actions: &mut Vec<Action>,
    ) {
        ui.heading("cloth");
        status_block(ui, status);
        ui.horizontal(|ui| {
            if ui
                .button(if status.paused { "run" } else { "pause" })
                .clicked()
            {
                actions.push(Action::TogglePause);
            }
            if ui.button("step").clicked() {
                actions.push(Action::Step);
            }
            if ui.button("reset").clicked() {
                actions.push(Action::Reset);
            }
        });
        ui.separator();

        ui.collapsing("scene", |ui| {
            egui::ComboBox::from_label("scene")
                .selected_text(self.scene.name())
                .show_ui(ui, |ui| {
                    for s in SceneKind::all() {
                        let label = s.name().to_string();
                        ui.selectable_value(&mut self.scene, s, label);
                    }
                });
            egui::ComboBox::from_label("integrator")
                .selected_text(self.integrator.name())
                .show_ui(ui, |ui| {
                    for i in Integrator::ALL {
                        ui.selectable_value(&mut self.integrator, i, i.name());
                    }
                });
            ui.add(egui::Slider::new(&mut self.resolution, 4..=160).text("resolution"));
            if ui.button("rebuild").clicked() {
                actions.push(Action::Rebuild {
                    scene: Box::new(self.scene.clone()),
                    resolution: self.resolution,
                    integrator: self.integrator,
                });
            }
        })
        .header_response
        .on_hover_text("scene, integrator and resolution take effect on rebuild");
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.save_path);
            if ui
                .button("save scene")
                .on_hover_text(
                    "write the current settings as a scene file (`cloth view FILE` opens it)",
                )
                .clicked()
            {
                actions.push(Action::Save(self.save_path.clone().into()));
            }
        });

        let mut cfg = *config;
        ui.collapsing("time", |ui| {
            ui.add(
                egui::Slider::new(&mut cfg.dt, 1.0 / 480.0..=1.0 / 20.0)
                    .logarithmic(true)
                    .text("dt [s]"),
            );
            ui.add(
                egui::Slider::new(&mut cfg.substeps, 1..=4000)
                    .logarithmic(true)
                    .text("substeps"),
            );
            ui.label(format!("h = {:.2e} s", cfg.substep_dt()));
        });
        ui.collapsing("material", |ui| {
            let mut structural = cfg.material.warp;
            spring_sliders(ui, "structural", &mut structural, 5000.0);
            if structural != cfg.material.warp {
                cfg.material.warp = structural;
                cfg.material.weft = structural;
            }
            spring_sliders(ui, "shear", &mut cfg.material.shear, 2000.0);
            spring_sliders(ui, "bend", &mut cfg.material.bend, 500.0);
            ui.add(
                egui::Slider::new(&mut cfg.damping, 0.0..=0.1)
                    .logarithmic(true)
                    .text("global damping [N·s/m]"),
            );
        });
        ui.collapsing("forces", |ui| {
            ui.add(egui::Slider::new(&mut cfg.gravity.y, -30.0..=0.0).text("gravity y [m/s²]"));
            let speed = Vec3::new(cfg.air.wind.x, 0.0, cfg.air.wind.z).length();
            let mut strength = cfg.air.wind.length();
            let mut heading = if speed > 0.0 {
                cfg.air.wind.z.atan2(cfg.air.wind.x).to_degrees()
            } else {
                0.0
            };
            let before = (strength, heading);
            ui.add(egui::Slider::new(&mut strength, 0.0..=20.0).text("wind [m/s]"));
            ui.add(egui::Slider::new(&mut heading, -180.0..=180.0).text("wind heading [°]"));
            if (strength, heading) != before {
                let h = heading.to_radians();
                cfg.air.wind = Vec3::new(h.cos(), 0.0, h.sin()) * strength;
            }
            let mut gusts = cfg.air.gust.is_some();
            ui.checkbox(&mut gusts, "gusts");
            if gusts != cfg.air.gust.is_some() {
                cfg.air.gust = gusts.then(Gust::default);
            }
            ui.add(egui::Slider::new(&mut cfg.air.density, 0.0..=3.0).text("air density [kg/m³]"));
            ui.checkbox(&mut cfg.forces.air, "air drag and lift");
        });
        if cfg != *config {
            actions.push(Action::Config(cfg));
        }
        if let Some(friction) = status.friction {
            ui.collapsing("friction", |ui| {
                let mut f = friction;
                ui.add(egui::Slider::new(&mut f.static_coefficient, 0.0..=1.5).text("μ static"));
                ui.add(egui::Slider::new(&mut f.kinetic_coefficient, 0.0..=1.5).text("μ kinetic"));
                f.kinetic_coefficient = f.kinetic_coefficient.min(f.static_coefficient);
                if f != friction {
                    actions.push(Action::Friction(f));
                }
            });
        }
        ui.collapsing("display", |ui| {
            ui.checkbox(&mut options.surface, "surface");
            ui.checkbox(&mut options.wireframe, "wireframe (W)");
            ui.checkbox(&mut options.springs, "springs by class");
            ui.checkbox(&mut options.pattern, "fabric pattern");
            ui.checkbox(&mut options.pins, "pin markers");
            ui.checkbox(&mut options.contacts, "contacts (K)");
            ui.horizontal(|ui| {
                ui.label("camera (C):");
                ui.selectable_value(mode, CameraMode::Orbit, "orbit");
                ui.selectable_value(mode, CameraMode::Fly, "fly");
            });
            if ui.button("reset view (Home)").clicked() {
                actions.push(Action::ResetView);
            }
        });
        ui.separator();
        ui.small(
            "drag cloth: grab · drag: orbit · right/middle drag: pan · wheel: zoom · \
             ctrl/shift-click: pin · space pause · N step · R reset · C camera · W wireframe · K contacts · \
             Home view · Tab panel",
        );
    }
}

fn spring_sliders(ui: &mut egui::Ui, name: &str, p: &mut SpringParams, max_k: f32) {
    ui.add(
        egui::Slider::new(&mut p.stiffness, 0.0..=max_k)
            .logarithmic(true)
            .text(format!("{name} k [N/m]")),
    );
    ui.add(
        egui::Slider::new(&mut p.damping, 0.0..=1.0)
            .logarithmic(true)
            .text(format!("{name} c [N·s/m]")),
    );
}

fn status_block(ui: &mut egui::Ui, s: &Status) {
    ui.monospace(format!(
        "{:.1} fps, sim {:.1} ms/frame\nt = {:.3} s{}\n{} particles, {} springs\nE = {:+.4e} J\nmax strain {:.4}",
        s.fps,
        s.sim_ms,
        s.time,
        if s.paused {
            " (paused)"
        } else if s.behind {
            " (slow-motion)"
        } else {
            ""
        },
        s.particles,
        s.springs,
        s.energy,
        s.max_strain,
    ));
    if let Some(msg) = &s.message {
        ui.colored_label(egui::Color32::from_rgb(255, 120, 90), msg);
    }
    ui.small(&s.adapter);
}
