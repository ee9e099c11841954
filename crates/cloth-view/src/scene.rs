//! The scene the viewer shows: a scene file (a built-in one by name, or any TOML file), as
//! described in `docs/scenes.md`, built at a chosen resolution and integrator.

use cloth_core::glam::Vec3;
use cloth_core::scene::{self, ColliderKind, Scene, SubstepsDesc};
use cloth_core::{ClothError, Integrator, Simulation};

/// A scene to view: its name (a built-in name or the file path) and its description.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneKind {
    name: String,
    scene: Scene,
    /// Whether `--set` gave `camera…` (a built-in scene's hand-tuned framing then gives way).
    camera_set: bool,
    /// Whether `--set` gave the substeps (kept when the resolution or integrator changes).
    substeps_set: bool,
}

impl SceneKind {
    /// Loads a built-in scene by name, or a TOML scene file, with `--set` overrides.
    ///
    /// # Errors
    /// The scene error naming the file, line, column and key.
    pub fn load(name_or_path: &str, overrides: &[String]) -> Result<Self, ClothError> {
        let (scene, _) = scene::load(name_or_path, overrides)?;
        Ok(Self {
            name: name_or_path.to_string(),
            scene,
            camera_set: scene::overrides_set(overrides, "camera"),
            substeps_set: scene::overrides_set(overrides, "solver.substeps"),
        })
    }

    /// The built-in scene `name`.
    #[must_use]
    pub fn builtin(name: &str) -> Option<Self> {
        scene::builtin(name).map(|scene| Self {
            name: name.to_string(),
            scene,
            camera_set: false,
            substeps_set: false,
        })
    }

    /// The seed's drape, the default scene.
    #[must_use]
    pub fn drape() -> Self {
        Self::builtin("drape").expect("drape is built in")
    }

    /// Every built-in scene, in menu order.
    #[must_use]
    pub fn all() -> Vec<Self> {
        scene::BUILTIN
            .iter()
            .filter_map(|(name, _)| Self::builtin(name))
            .collect()
    }

    /// The name: a built-in scene's name or the file it came from.
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The scene description as loaded.
    #[must_use]
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The scene's own resolution, rows (the resolution slider's start).
    #[must_use]
    pub fn resolution(&self) -> usize {
        self.scene.cloth.resolution[0] as usize
    }

    /// The scene's own integrator.
    #[must_use]
    pub fn integrator(&self) -> Integrator {
        self.scene.integrator()
    }

    /// Height of a floor drawn for looks when the scene has no ground plane, m: half a metre
    /// below the lowest collider or cloth point.
    #[must_use]
    pub fn display_floor(&self) -> f32 {
        let s = &self.scene;
        if let Some(plane) = s.colliders.iter().find(|c| {
            c.kind == ColliderKind::Plane
                && c.normal
                    .is_some_and(|n| n[1] > 0.9 * Vec3::from(n).length())
        }) {
            return plane.point.map_or(0.0, |p| p[1]);
        }
        let cloth_low = s.cloth.origin[1] - 0.5 * s.cloth.size.map_or(1.0, |w| w[1].max(w[0]));
        let lowest = s
            .colliders
            .iter()
            .map(|c| match c.kind {
                ColliderKind::Sphere => c.center.map_or(0.0, |p| p[1]) - c.radius.unwrap_or(0.0),
                ColliderKind::Capsule => {
                    c.a.map_or(0.0, |p| p[1]).min(c.b.map_or(0.0, |p| p[1]))
                        - c.radius.unwrap_or(0.0)
                }
                ColliderKind::Box => {
                    let h = c.half_extents.map_or(0.0, |h| Vec3::from(h).length());
                    c.center.map_or(0.0, |p| p[1]) - h
                }
                ColliderKind::Mesh => {
                    let y = c.center.map_or(0.0, |p| p[1]);
                    c.mesh.as_ref().map_or(y, |m| {
                        let (lo, hi) = m.bounds();
                        y - lo.length().max(hi.length())
                    })
                }
                ColliderKind::Plane => 0.0,
            })
            .fold(cloth_low, f32::min);
        lowest - 0.5
    }

    /// Where the view starts: the camera and its vertical field of view (radians). The scene's
    /// `[camera]` (eye, target, `fov_degrees`); for the main built-in scenes (drape, hanging,
    /// peer-ball, flag) a hand-tuned framing at [`crate::FOVY`] instead, unless `--set camera…`
    /// changed their `[camera]`; a scene without one is looked at from 2.5 m, and so is the
    /// `[camera]`'s target when its eye is on it (closer than
    /// [`scene::MIN_CAMERA_DISTANCE`]: no direction to look in).
    #[must_use]
    pub fn start_view(&self) -> (crate::Camera, f32) {
        let tuned = match self.name.as_str() {
            // Hand-tuned framings of the main scenes (the reference image uses the drape's).
            "drape" => Some((Vec3::new(0.0, -0.05, 0.0), 1.9)),
            "hanging" => Some((Vec3::new(0.0, 0.95, 0.0), 2.4)),
            "peer-ball" => Some((Vec3::new(0.0, 0.0, 0.0), 2.4)),
            "flag" => Some((Vec3::new(0.75, 1.1, 0.0), 3.0)),
            _ => None,
        };
        match (tuned.filter(|_| !self.camera_set), &self.scene.camera) {
            (Some((target, distance)), _) => {
                (crate::Camera::looking_at(target, distance), crate::FOVY)
            }
            (None, Some(c)) => {
                let (eye, target) = (Vec3::from(c.eye), Vec3::from(c.target));
                let camera = if eye.distance(target) < scene::MIN_CAMERA_DISTANCE {
                    crate::Camera::looking_at(target, 2.5)
                } else {
                    crate::Camera::new(eye, target)
                };
                (camera, c.fov_degrees.to_radians())
            }
            (None, None) => (
                crate::Camera::looking_at(Vec3::from(self.scene.cloth.origin), 2.5),
                crate::FOVY,
            ),
        }
    }

    /// The scene as it will be built with `rows` rows (columns in proportion) and
    /// `integrator`. The file's own substeps are kept when neither changes; otherwise they
    /// are chosen again for the integrator ("auto").
    #[must_use]
    pub fn effective(&self, rows: usize, integrator: Integrator) -> Scene {
        let mut s = self.scene.clone();
        let [r0, c0] = s.cloth.resolution;
        let rows = u32::try_from(rows).unwrap_or(u32::MAX);
        if rows != r0 {
            let cols = (u64::from(rows) * u64::from(c0) + u64::from(r0) / 2) / u64::from(r0);
            s.cloth.resolution = [rows, u32::try_from(cols.max(2)).unwrap_or(u32::MAX)];
            if let Some(sp) = s.cloth.spacing {
                // keep the cloth's size
                let scale = (r0 - 1) as f32 / (rows.max(2) - 1) as f32;
                s.cloth.spacing = Some([sp[0] * scale, sp[1] * scale]);
            }
        }
        if integrator != s.integrator() || rows != r0 {
            s.solver.kind = integrator.name().into();
            if !self.substeps_set {
                s.solver.substeps = SubstepsDesc::default();
            }
        }
        s
    }

    /// Builds the scene with `rows` rows and `integrator` (see [`SceneKind::effective`]).
    ///
    /// # Errors
    /// The simulator's error for an invalid resolution or configuration.
    pub fn build(&self, rows: usize, integrator: Integrator) -> cloth_core::Result<Simulation> {
        let scene = self.effective(rows, integrator);
        scene.validate(self.name())?;
        scene.build()
    }
}

impl std::fmt::Display for SceneKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_scene_is_in_the_menu_and_builds_small() {
        let all = SceneKind::all();
        assert!(all.len() >= 10);
        for s in all {
            let mut sim = s.build(6, s.integrator()).expect("builds");
            sim.step().expect("steps");
        }
    }

    #[test]
    fn the_files_own_settings_are_kept_unless_changed() {
        let peer = SceneKind::builtin("peer-ball").expect("peer");
        let same = peer.effective(128, Integrator::SymplecticEuler);
        assert_eq!(same, *peer.scene());
        let other = peer.effective(32, Integrator::Xpbd);
        assert_eq!(other.cloth.resolution, [32, 32]);
        assert_eq!(other.solver.kind, "xpbd");
        // the cloth keeps its 1 m side
        let sp = other.cloth.spacing.expect("spacing");
        assert!((sp[0] * 31.0 - 0.0078125 * 127.0).abs() < 1e-6);
    }

    /// Substeps given with `--set` survive a new resolution or integrator (they were reset
    /// to "auto", so `cloth render drape --resolution 512 --set solver.substeps=8` ran
    /// another count); substeps from the file alone are still chosen again.
    #[test]
    fn substeps_given_on_the_command_line_are_kept() {
        let load = |set: &[&str]| {
            let set: Vec<String> = set.iter().map(|s| (*s).to_string()).collect();
            SceneKind::load("drape", &set).expect("drape loads")
        };
        for set in [
            &["solver.substeps=8"][..],
            &[r#"solver = { kind = "xpbd", substeps = 8 }"#],
        ] {
            let scene = load(set).effective(64, Integrator::Xpbd);
            assert_eq!(scene.solver.substeps, SubstepsDesc::Count(8), "{set:?}");
            assert_eq!(scene.cloth.resolution, [64, 64]);
        }
        let peer = SceneKind::load("peer-ball", &[]).expect("peer-ball loads");
        assert_eq!(peer.scene().solver.substeps, SubstepsDesc::Count(53));
        let other = peer.effective(32, Integrator::Xpbd);
        assert_eq!(other.solver.substeps, SubstepsDesc::default());
        let kind_only = load(&[r#"solver.kind="xpbd""#]).effective(64, Integrator::Xpbd);
        assert_eq!(kind_only.solver.substeps, SubstepsDesc::default());
    }

    /// The view starts where the scene's `[camera]` says (eye, target, field of view), except
    /// for the main built-in scenes' hand-tuned framings, which `--set camera…` overrides.
    #[test]
    fn the_start_view_follows_the_scenes_camera() {
        let close = |a: Vec3, b: Vec3| a.distance(b) < 1e-6;
        let drape = SceneKind::drape();
        let (cam, fovy) = drape.start_view();
        assert!(close(cam.target, Vec3::new(0.0, -0.05, 0.0)));
        assert!((cam.distance() - 1.9).abs() < 1e-5);
        assert!((fovy - crate::FOVY).abs() < 1e-7);

        let set = [
            "camera.eye=[0.25, 0.9, 0.35]".to_string(),
            "camera.fov_degrees=30.0".to_string(),
        ];
        let moved = SceneKind::load("drape", &set).expect("drape loads");
        let (cam, fovy) = moved.start_view();
        assert!(close(cam.eye, Vec3::new(0.25, 0.9, 0.35)));
        assert!(close(cam.target, Vec3::ZERO), "the file's target");
        assert!((fovy - 30f32.to_radians()).abs() < 1e-7);

        // A built-in scene without a tuned framing: its file's eye, target and 45°.
        let fold = SceneKind::builtin("fold").expect("fold");
        let c = fold.scene().camera.expect("fold has a [camera]");
        let (cam, fovy) = fold.start_view();
        assert!(close(cam.eye, Vec3::from(c.eye)) && close(cam.target, Vec3::from(c.target)));
        assert!((fovy - 45f32.to_radians()).abs() < 1e-7);
    }

    /// `--set camera.eye=[0,3,0] --set camera.target=[0,3,0]` (eye on the target) gave a NaN
    /// view matrix and a frame of background only: such a scene is now refused where it is
    /// read, naming `camera.target` (a scene edited in code that skips that check still gets
    /// the viewer's fallback, a view of the target from 2.5 m).
    #[test]
    fn a_camera_with_its_eye_on_the_target_is_refused() {
        let set = [
            "camera.eye=[0, 3, 0]".to_string(),
            "camera.target=[0, 3, 0]".to_string(),
        ];
        let Err(err) = SceneKind::load("drape", &set) else {
            panic!("a camera with its eye on its target was accepted");
        };
        assert!(err.to_string().contains("`camera.target`"), "{err}");
        // The fallback, for a scene edited in code.
        let mut drape = SceneKind::builtin("drape").expect("drape");
        drape.scene.camera = Some(scene::CameraDesc {
            eye: [0.0, 3.0, 0.0],
            target: [0.0, 3.0, 0.0],
            fov_degrees: 45.0,
        });
        drape.camera_set = true;
        let (cam, _) = drape.start_view();
        assert!(cam.target.distance(Vec3::new(0.0, 3.0, 0.0)) < 1e-6);
        assert!((cam.distance() - 2.5).abs() < 1e-5, "{}", cam.distance());
        assert!(cam.view().is_finite());
    }

    #[test]
    fn flag_is_pinned_on_the_left_and_flies_downwind() {
        let flag = SceneKind::builtin("flag").expect("flag");
        let mut sim = flag.build(10, Integrator::SymplecticEuler).unwrap();
        let (rows, cols) = sim.grid_size();
        assert_eq!((rows, cols), (10, 15));
        for r in 0..rows {
            assert!(sim.particles().is_pinned(r * cols));
            assert!(!sim.particles().is_pinned(r * cols + cols - 1));
        }
        let x0 = sim.particles().center_of_mass().x;
        for _ in 0..60 {
            sim.step().unwrap();
        }
        assert!(sim.particles().position.iter().all(|p| p.is_finite()));
        assert!(
            sim.particles().center_of_mass().x > x0 - 0.8,
            "flag blew upwind"
        );
    }

    #[test]
    fn bad_files_are_named() {
        let err = SceneKind::load("/no/such.toml", &[])
            .unwrap_err()
            .to_string();
        assert!(err.contains("/no/such.toml"), "{err}");
    }
}
