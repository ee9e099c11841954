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
    /// Implicit Euler's linear solve stopped at its iteration cap before its tolerance in a
    /// step within the last simulated second (such a step is taken, less accurately than the
    /// tolerance asks).
    pub solver_capped: bool,
    /// The last instability or parameter error.
    pub message: Option<String>,
    /// The graphics adapter.
    pub adapter: String,
    /// Current friction of the colliders (None: no colliders).
    pub friction: Option<Friction>,
}

/// Where the panel's labelled widgets were drawn in the last frame, for the viewer's
/// debugging hook [`CLOTH_VIEW_LAYOUT`](crate::app::LAYOUT_VAR) (the input tests click them):
/// off by default, and then nothing is recorded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Layout(Option<Vec<(String, egui::Rect)>>);

impl Layout {
    /// A layout that records the widgets of every frame the panel is drawn in.
    #[must_use]
    pub fn on() -> Self {
        Self(Some(Vec::new()))
    }

    /// The last frame's labelled widgets (buttons, checkboxes, sliders, combo boxes, camera
    /// choices and section headers) in the order drawn, each with the part of it that takes the
    /// pointer, points; a widget scrolled out of view is left out. Empty when off or when the
    /// panel is hidden.
    #[must_use]
    pub fn widgets(&self) -> &[(String, egui::Rect)] {
        self.0.as_deref().unwrap_or_default()
    }

    fn clear(&mut self) {
        if let Some(widgets) = &mut self.0 {
            widgets.clear();
        }
    }

    /// Records `response` under `label` (when on) and passes it on.
    fn note(&mut self, label: &str, response: egui::Response) -> egui::Response {
        if let Some(widgets) = &mut self.0
            && response.interact_rect.is_positive()
        {
            widgets.push((label.to_owned(), response.interact_rect));
        }
        response
    }

    fn button(&mut self, ui: &mut egui::Ui, label: &str) -> egui::Response {
        self.note(label, ui.button(label))
    }

    fn checkbox(&mut self, ui: &mut egui::Ui, value: &mut bool, label: &str) {
        self.note(label, ui.checkbox(value, label));
    }

    fn slider(&mut self, ui: &mut egui::Ui, label: &str, slider: egui::Slider<'_>) {
        self.note(label, ui.add(slider.text(label)));
    }
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
    /// Where its widgets were drawn (recorded only when turned on).
    pub layout: Layout,
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
            layout: Layout::default(),
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
        self.layout.clear();
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
        let layout = &mut self.layout;
        ui.horizontal(|ui| {
            if layout
                .button(ui, if status.paused { "run" } else { "pause" })
                .clicked()
            {
                actions.push(Action::TogglePause);
            }
            if layout.button(ui, "step").clicked() {
                actions.push(Action::Step);
            }
            if layout.button(ui, "reset").clicked() {
                actions.push(Action::Reset);
            }
        });
        ui.separator();

        let scene = ui.collapsing("scene", |ui| {
            let combo = egui::ComboBox::from_label("scene")
                .selected_text(self.scene.name())
                .show_ui(ui, |ui| {
                    for s in SceneKind::all() {
                        let label = s.name().to_string();
                        ui.selectable_value(&mut self.scene, s, label);
                    }
                });
            layout.note("scene", combo.response);
            let combo = egui::ComboBox::from_label("integrator")
                .selected_text(self.integrator.name())
                .show_ui(ui, |ui| {
                    for i in Integrator::ALL {
                        ui.selectable_value(&mut self.integrator, i, i.name());
                    }
                });
            layout.note("integrator", combo.response);
            layout.slider(
                ui,
                "resolution",
                egui::Slider::new(&mut self.resolution, 4..=160),
            );
            if layout.button(ui, "rebuild").clicked() {
                actions.push(Action::Rebuild {
                    scene: Box::new(self.scene.clone()),
                    resolution: self.resolution,
                    integrator: self.integrator,
                });
            }
        });
        layout.note(
            "scene",
            scene
                .header_response
                .on_hover_text("scene, integrator and resolution take effect on rebuild"),
        );
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.save_path);
            if layout
                .button(ui, "save scene")
                .on_hover_text(
                    "write the current settings as a scene file (`cloth view FILE` opens it)",
                )
                .clicked()
            {
                actions.push(Action::Save(self.save_path.clone().into()));
            }
        });

        let mut cfg = *config;
        let time = ui.collapsing("time", |ui| {
            layout.slider(
                ui,
                "dt [s]",
                egui::Slider::new(&mut cfg.dt, 1.0 / 480.0..=1.0 / 20.0).logarithmic(true),
            );
            layout.slider(
                ui,
                "substeps",
                egui::Slider::new(&mut cfg.substeps, 1..=4000).logarithmic(true),
            );
            ui.label(format!("h = {:.2e} s", cfg.substep_dt()));
        });
        layout.note("time", time.header_response);
        let material = ui.collapsing("material", |ui| {
            let mut structural = cfg.material.warp;
            spring_sliders(layout, ui, "structural", &mut structural, 5000.0);
            if structural != cfg.material.warp {
                cfg.material.warp = structural;
                cfg.material.weft = structural;
            }
            spring_sliders(layout, ui, "shear", &mut cfg.material.shear, 2000.0);
            spring_sliders(layout, ui, "bend", &mut cfg.material.bend, 500.0);
            layout.slider(
                ui,
                "global damping [N·s/m]",
                egui::Slider::new(&mut cfg.damping, 0.0..=0.1).logarithmic(true),
            );
        });
        layout.note("material", material.header_response);
        let forces = ui.collapsing("forces", |ui| {
            layout.slider(
                ui,
                "gravity y [m/s²]",
                egui::Slider::new(&mut cfg.gravity.y, -30.0..=0.0),
            );
            let speed = Vec3::new(cfg.air.wind.x, 0.0, cfg.air.wind.z).length();
            let mut strength = cfg.air.wind.length();
            let mut heading = if speed > 0.0 {
                cfg.air.wind.z.atan2(cfg.air.wind.x).to_degrees()
            } else {
                0.0
            };
            let before = (strength, heading);
            layout.slider(
                ui,
                "wind [m/s]",
                egui::Slider::new(&mut strength, 0.0..=20.0),
            );
            layout.slider(
                ui,
                "wind heading [°]",
                egui::Slider::new(&mut heading, -180.0..=180.0),
            );
            if (strength, heading) != before {
                let h = heading.to_radians();
                cfg.air.wind = Vec3::new(h.cos(), 0.0, h.sin()) * strength;
            }
            let mut gusts = cfg.air.gust.is_some();
            layout.checkbox(ui, &mut gusts, "gusts");
            if gusts != cfg.air.gust.is_some() {
                cfg.air.gust = gusts.then(Gust::default);
            }
            layout.slider(
                ui,
                "air density [kg/m³]",
                egui::Slider::new(&mut cfg.air.density, 0.0..=3.0),
            );
            layout.checkbox(ui, &mut cfg.forces.air, "air drag and lift");
        });
        layout.note("forces", forces.header_response);
        if cfg != *config {
            actions.push(Action::Config(cfg));
        }
        if let Some(friction) = status.friction {
            let header = ui.collapsing("friction", |ui| {
                let mut f = friction;
                layout.slider(
                    ui,
                    "μ static",
                    egui::Slider::new(&mut f.static_coefficient, 0.0..=1.5),
                );
                layout.slider(
                    ui,
                    "μ kinetic",
                    egui::Slider::new(&mut f.kinetic_coefficient, 0.0..=1.5),
                );
                f.kinetic_coefficient = f.kinetic_coefficient.min(f.static_coefficient);
                if f != friction {
                    actions.push(Action::Friction(f));
                }
            });
            layout.note("friction", header.header_response);
        }
        let display = ui.collapsing("display", |ui| {
            layout.checkbox(ui, &mut options.surface, "surface");
            layout.checkbox(ui, &mut options.wireframe, "wireframe (W)");
            layout.checkbox(ui, &mut options.springs, "springs by class");
            layout.checkbox(ui, &mut options.pattern, "fabric pattern");
            layout.checkbox(ui, &mut options.pins, "pin markers");
            layout.checkbox(ui, &mut options.contacts, "contacts (K)");
            ui.horizontal(|ui| {
                ui.label("camera (C):");
                layout.note(
                    "orbit",
                    ui.selectable_value(mode, CameraMode::Orbit, "orbit"),
                );
                layout.note("fly", ui.selectable_value(mode, CameraMode::Fly, "fly"));
            });
            if layout.button(ui, "reset view (Home)").clicked() {
                actions.push(Action::ResetView);
            }
        });
        layout.note("display", display.header_response);
        ui.separator();
        ui.small(
            "drag cloth: grab · drag: orbit · right/middle drag: pan · wheel: zoom · \
             ctrl/shift-click: pin · space pause · N step · R reset · C camera · W wireframe · K contacts · \
             Home view · Tab panel",
        );
    }
}

fn spring_sliders(
    layout: &mut Layout,
    ui: &mut egui::Ui,
    name: &str,
    p: &mut SpringParams,
    max_k: f32,
) {
    layout.slider(
        ui,
        &format!("{name} k [N/m]"),
        egui::Slider::new(&mut p.stiffness, 0.0..=max_k).logarithmic(true),
    );
    layout.slider(
        ui,
        &format!("{name} c [N·s/m]"),
        egui::Slider::new(&mut p.damping, 0.0..=1.0).logarithmic(true),
    );
}

/// What the status block says while the linear solve stops at its cap ([`Status::solver_capped`]).
pub const CAPPED_TEXT: &str =
    "CG stopped at its iteration cap: step approximate (more substeps or a higher cap)";

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
    if s.solver_capped {
        ui.colored_label(egui::Color32::from_rgb(255, 200, 90), CAPPED_TEXT);
    }
    if let Some(msg) = &s.message {
        ui.colored_label(egui::Color32::from_rgb(255, 120, 90), msg);
    }
    ui.small(&s.adapter);
}

#[cfg(test)]
mod tests {
    use super::{CameraMode, Layout, Panel, Status};
    use crate::renderer::RenderOptions;

    /// Draws `panel` twice (egui sizes its widgets in the first pass) in a 640 × 600 screen.
    fn draw(panel: &mut Panel) {
        let _ = draw_with(panel, &Status::default());
    }

    /// [`draw`] with `status`; returns the text of the last pass's text shapes.
    fn draw_with(panel: &mut Panel, status: &Status) -> Vec<String> {
        let ctx = egui::Context::default();
        let config = cloth_core::SimConfig::default();
        let mut options = RenderOptions::default();
        let mut mode = CameraMode::Orbit;
        let mut texts = Vec::new();
        let raw = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(640.0, 600.0),
            )),
            ..egui::RawInput::default()
        };
        for _ in 0..2 {
            let mut output = ctx.run_ui(raw.clone(), |ui| {
                let _ = panel.show(ui, &config, &mut options, &mut mode, status);
            });
            // No renderer takes the font atlas here: epaint's debug builds panic on dropping
            // texture updates nobody applied.
            output.textures_delta.clear();
            texts = output
                .shapes
                .iter()
                .filter_map(|c| match &c.shape {
                    egui::Shape::Text(t) => Some(t.galley.text().to_owned()),
                    _ => None,
                })
                .collect();
        }
        texts
    }

    /// The status block says when the last step's linear solve stopped at its iteration cap
    /// (implicit Euler's CG), and says nothing of it otherwise.
    #[test]
    fn the_status_block_says_when_the_solve_was_capped() {
        let scene = crate::scene::SceneKind::builtin("drape").expect("drape");
        let mut panel = Panel::new(scene, 16, cloth_core::Integrator::ImplicitEuler);
        let capped = Status {
            solver_capped: true,
            ..Status::default()
        };
        let said = |texts: &[String]| texts.iter().any(|t| t == super::CAPPED_TEXT);
        let texts = draw_with(&mut panel, &capped);
        assert!(said(&texts), "{texts:?}");
        let texts = draw_with(&mut panel, &Status::default());
        assert!(!said(&texts), "{texts:?}");
        assert!(texts.iter().any(|t| t.contains("fps")), "{texts:?}");
    }

    /// The `CLOTH_VIEW_LAYOUT` hook's record: off, nothing; on, the panel's labelled widgets
    /// (the run/pause row, the section headers) once each a frame, inside the screen, the
    /// buttons of one row side by side; nothing while the panel is hidden.
    #[test]
    fn the_layout_records_the_widgets_only_when_on() {
        let scene = crate::scene::SceneKind::builtin("drape").expect("drape");
        let mut panel = Panel::new(scene, 16, cloth_core::Integrator::Xpbd);
        draw(&mut panel);
        assert!(panel.layout.widgets().is_empty());

        panel.layout = Layout::on();
        draw(&mut panel);
        let widgets = panel.layout.widgets();
        let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(640.0, 600.0));
        let find = |label: &str| {
            let found: Vec<_> = widgets.iter().filter(|(l, _)| l == label).collect();
            assert_eq!(found.len(), 1, "{label}: {widgets:?}");
            found[0].1
        };
        for label in ["pause", "step", "reset", "save scene", "time", "display"] {
            let r = find(label);
            assert!(r.is_positive() && screen.contains_rect(r), "{label}: {r:?}");
        }
        let (pause, step) = (find("pause"), find("step"));
        assert!(pause.max.x <= step.min.x && pause.center().y == step.center().y);
        // a closed section's widgets are not drawn
        assert!(widgets.iter().all(|(l, _)| l != "wireframe (W)"));

        panel.visible = false;
        draw(&mut panel);
        assert!(panel.layout.widgets().is_empty());
    }
}
