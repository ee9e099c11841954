//! Cameras: where the eye is ([`Camera`]), how it projects ([`Projection`]), how input moves it
//! ([`OrbitController`], [`FlyController`]), and picking ([`Ray`]).
//!
//! Conventions: right-handed, Y up, wgpu's clip space (depth 0 at the near plane, 1 at the far
//! plane), pixels with the origin at the top-left corner and y down.

use cloth_core::glam::camera::rh::{proj::directx, view};
use cloth_core::glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

/// Below this sine of the angle between the view direction and [`Camera::up`], the two count
/// as parallel and [`Camera::view_up`] falls back to another up direction (0.057°).
pub const PARALLEL_SINE: f32 = 1e-3;

/// An eye looking at a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position, m.
    pub eye: Vec3,
    /// The point looked at, m.
    pub target: Vec3,
    /// The up direction (need not be orthogonal to the view direction).
    pub up: Vec3,
}

impl Camera {
    /// A camera at `eye` looking at `target`, with +Y up.
    #[must_use]
    pub fn new(eye: Vec3, target: Vec3) -> Self {
        Self {
            eye,
            target,
            up: Vec3::Y,
        }
    }

    /// A camera looking at `target` from `distance` away, from the front-right and above.
    #[must_use]
    pub fn looking_at(target: Vec3, distance: f32) -> Self {
        let dir = Vec3::new(0.6, 0.5, 1.0).normalize();
        Self::new(target + dir * distance, target)
    }

    /// The world-to-view matrix, built from [`forward`](Self::forward) and
    /// [`view_up`](Self::view_up): finite for every camera with a finite eye and target, also
    /// one looking straight along `up` or with the eye on the target.
    #[must_use]
    pub fn view(&self) -> Mat4 {
        view::look_to_mat4(self.eye, self.forward(), self.view_up())
    }

    /// Unit vector from the eye towards the target (−Z when the eye is on the target).
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye).normalize_or(Vec3::NEG_Z)
    }

    /// The unit up direction the view is built with: [`up`](Self::up), unless the view looks
    /// along it (within [`PARALLEL_SINE`]), where it gives no orientation. Then the top of the
    /// image points the way a camera facing −Z shows it when tilted to straight down or
    /// straight up (with `up` = +Y: −Z looking down, +Z looking up), which is also how the
    /// view looks just before the pole when the eye comes to it from the +Z side.
    #[must_use]
    pub fn view_up(&self) -> Vec3 {
        let up = self.up.normalize_or(Vec3::Y);
        let f = self.forward();
        if f.cross(up).length_squared() > PARALLEL_SINE * PARALLEL_SINE {
            return up;
        }
        // +Z made orthogonal to `up` (any orthogonal vector if `up` is along Z)
        let side = (Vec3::Z - up * up.z).normalize_or(up.any_orthonormal_vector());
        side * f.dot(up).signum()
    }

    /// Unit vector to the right of the view.
    #[must_use]
    pub fn right(&self) -> Vec3 {
        self.forward().cross(self.view_up()).normalize_or(Vec3::X)
    }

    /// The direction the camera faces, level (orthogonal to +Y, unit): the view direction
    /// levelled, or, looking straight down or up, the direction the top (looking down) or the
    /// bottom (looking up) of the image points to. The controllers turn from it.
    #[must_use]
    fn heading(&self) -> Vec3 {
        let f = self.forward();
        let level = Vec3::new(f.x, 0.0, f.z);
        if level.length_squared() > PARALLEL_SINE * PARALLEL_SINE {
            return level.normalize();
        }
        let u = self.view_up() * -f.y.signum();
        Vec3::new(u.x, 0.0, u.z).normalize_or(Vec3::NEG_Z)
    }

    /// Distance from the eye to the target, m.
    #[must_use]
    pub fn distance(&self) -> f32 {
        self.eye.distance(self.target)
    }

    /// Projection × view.
    #[must_use]
    pub fn view_proj(&self, projection: &Projection) -> Mat4 {
        projection.matrix() * self.view()
    }

    /// The pixel (origin top-left, y down) where `point` appears in a `size` image, if it is in
    /// front of the camera.
    #[must_use]
    pub fn project(&self, projection: &Projection, size: [u32; 2], point: Vec3) -> Option<Vec2> {
        let clip = self.view_proj(projection) * point.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.xyz() / clip.w;
        Some(Vec2::new(
            (ndc.x * 0.5 + 0.5) * size[0] as f32,
            (0.5 - ndc.y * 0.5) * size[1] as f32,
        ))
    }

    /// The ray from the eye through `pixel` (origin top-left, y down) of a `size` image.
    #[must_use]
    pub fn ray_through(&self, projection: &Projection, size: [u32; 2], pixel: Vec2) -> Ray {
        let inv = self.view_proj(projection).inverse();
        let ndc = Vec2::new(
            2.0 * pixel.x / size[0].max(1) as f32 - 1.0,
            1.0 - 2.0 * pixel.y / size[1].max(1) as f32,
        );
        let near = inv.project_point3(ndc.extend(0.0));
        let far = inv.project_point3(ndc.extend(1.0));
        Ray {
            origin: near,
            dir: (far - near).normalize_or(self.forward()),
        }
    }
}

/// A perspective projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Vertical field of view, radians.
    pub fovy: f32,
    /// Width / height.
    pub aspect: f32,
    /// Near plane distance, m.
    pub near: f32,
    /// Far plane distance, m.
    pub far: f32,
    /// Horizontal lens shift in NDC units: the view's centre appears at NDC x = `shift_x`
    /// (e.g. to centre the scene in the part of a window a side panel leaves free). Default 0.
    pub shift_x: f32,
}

impl Projection {
    /// A projection for a `width × height` image with a vertical field of view `fovy` (radians).
    #[must_use]
    pub fn new(width: u32, height: u32, fovy: f32) -> Self {
        let mut p = Self {
            fovy,
            aspect: 1.0,
            near: 0.02,
            far: 100.0,
            shift_x: 0.0,
        };
        p.resize(width, height);
        p
    }

    /// Follows a new image size; a zero side (a minimised window) counts as 1 pixel.
    pub fn resize(&mut self, width: u32, height: u32) {
        self.aspect = width.max(1) as f32 / height.max(1) as f32;
    }

    /// The projection matrix (right-handed, depth 0..1), lens shift included.
    #[must_use]
    pub fn matrix(&self) -> Mat4 {
        // WebGPU: depth 0..1, y up in NDC
        Mat4::from_translation(Vec3::new(self.shift_x, 0.0, 0.0))
            * directx::perspective(self.fovy, self.aspect, self.near, self.far)
    }
}

/// A half-line from `origin` along the unit vector `dir`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start, m.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

impl Ray {
    /// The point at parameter `t` (m along the ray).
    #[must_use]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// Distance along the ray to triangle `(a, b, c)` (either side), if hit (Möller–Trumbore).
    #[must_use]
    pub fn hit_triangle(&self, a: Vec3, b: Vec3, c: Vec3) -> Option<f32> {
        let e1 = b - a;
        let e2 = c - a;
        let p = self.dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let s = self.origin - a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(e1);
        let v = self.dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(q) * inv;
        (t > 0.0).then_some(t)
    }

    /// Where the ray meets the plane through `point` with normal `normal`, if in front.
    #[must_use]
    pub fn hit_plane(&self, point: Vec3, normal: Vec3) -> Option<f32> {
        let denom = self.dir.dot(normal);
        if denom.abs() < 1e-9 {
            return None;
        }
        let t = (point - self.origin).dot(normal) / denom;
        (t > 0.0).then_some(t)
    }

    /// The particle under the ray: the vertex of the nearest hit triangle closest to the hit
    /// point. Returns `(particle, distance along the ray)`.
    #[must_use]
    pub fn pick(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> Option<(usize, f32)> {
        let mut best: Option<(f32, [u32; 3])> = None;
        for tri in triangles {
            let [a, b, c] = tri.map(|i| positions[i as usize]);
            if let Some(t) = self.hit_triangle(a, b, c)
                && best.is_none_or(|(bt, _)| t < bt)
            {
                best = Some((t, *tri));
            }
        }
        let (t, tri) = best?;
        let hit = self.at(t);
        let i = tri.into_iter().min_by(|&i, &j| {
            let di = positions[i as usize].distance_squared(hit);
            let dj = positions[j as usize].distance_squared(hit);
            di.total_cmp(&dj)
        })?;
        Some((i as usize, t))
    }
}

/// Orbits the camera around its target: drag to rotate, wheel to zoom, drag with another button
/// to pan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitController {
    /// Radians per pixel of drag.
    pub rotate_speed: f32,
    /// Fraction of the distance per wheel line.
    pub zoom_speed: f32,
    /// Closest allowed distance to the target, m.
    pub min_distance: f32,
    /// Farthest allowed distance, m.
    pub max_distance: f32,
}

impl Default for OrbitController {
    fn default() -> Self {
        Self {
            rotate_speed: 0.008,
            zoom_speed: 0.1,
            min_distance: 0.1,
            max_distance: 50.0,
        }
    }
}

impl OrbitController {
    /// Rotates the eye about the target by a drag of `(dx, dy)` pixels, keeping the distance:
    /// horizontal drags turn about +Y, vertical drags tilt (clamped short of the poles).
    pub fn rotate(&self, camera: &mut Camera, dx: f32, dy: f32) {
        let offset = camera.eye - camera.target;
        let r = offset.length();
        if r <= 0.0 {
            return;
        }
        // the eye's side of the target: behind the camera's heading (also looking straight
        // down or up, where the offset has no level part to take it from)
        let back = -camera.heading();
        let mut yaw = back.x.atan2(back.z);
        let mut pitch = (offset.y / r).clamp(-1.0, 1.0).asin();
        yaw -= dx * self.rotate_speed;
        let limit = 89f32.to_radians();
        pitch = (pitch + dy * self.rotate_speed).clamp(-limit, limit);
        let dir = Vec3::new(
            pitch.cos() * yaw.sin(),
            pitch.sin(),
            pitch.cos() * yaw.cos(),
        );
        camera.eye = camera.target + dir * r;
        camera.up = Vec3::Y;
    }

    /// Moves the eye towards the target by `lines` wheel lines (negative: away).
    pub fn zoom(&self, camera: &mut Camera, lines: f32) {
        let r = camera.distance();
        let new_r =
            (r * (1.0 - self.zoom_speed).powf(lines)).clamp(self.min_distance, self.max_distance);
        camera.eye = camera.target - camera.forward() * new_r;
    }

    /// Slides eye and target together by a drag of `(dx, dy)` pixels in a window of height
    /// `height` pixels with `projection`: the point under the cursor follows it at the target's
    /// depth.
    pub fn pan(&self, camera: &mut Camera, projection: &Projection, height: u32, dx: f32, dy: f32) {
        let per_pixel =
            2.0 * camera.distance() * (0.5 * projection.fovy).tan() / height.max(1) as f32;
        let right = camera.right();
        let up = right.cross(camera.forward());
        let by = (-dx * right + dy * up) * per_pixel;
        camera.eye += by;
        camera.target += by;
    }
}

/// Which movement keys of the fly camera are held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FlyKeys {
    /// Forward (W).
    pub forward: bool,
    /// Backward (S).
    pub back: bool,
    /// Left (A).
    pub left: bool,
    /// Right (D).
    pub right: bool,
    /// Up (E or Page Up).
    pub up: bool,
    /// Down (Q or Page Down).
    pub down: bool,
    /// Faster (Shift).
    pub fast: bool,
}

/// A first-person camera: WASD moves along the view, Q/E down/up, Shift faster, the mouse
/// looks around.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlyController {
    /// Speed, m/s.
    pub speed: f32,
    /// Speed multiplier with the fast key.
    pub fast_factor: f32,
    /// Radians per pixel of mouse motion.
    pub look_speed: f32,
    /// Keys held.
    pub keys: FlyKeys,
}

impl Default for FlyController {
    fn default() -> Self {
        Self {
            speed: 1.0,
            fast_factor: 4.0,
            look_speed: 0.004,
            keys: FlyKeys::default(),
        }
    }
}

impl FlyController {
    /// Moves the camera for `dt` seconds of the keys held. Eye and target move together.
    pub fn update(&self, camera: &mut Camera, dt: f32) {
        let k = self.keys;
        let axis = |pos: bool, neg: bool| f32::from(u8::from(pos)) - f32::from(u8::from(neg));
        let forward = camera.forward();
        let right = camera.right();
        let dir = forward * axis(k.forward, k.back)
            + right * axis(k.right, k.left)
            + Vec3::Y * axis(k.up, k.down);
        if dir == Vec3::ZERO {
            return;
        }
        let speed = if k.fast {
            self.speed * self.fast_factor
        } else {
            self.speed
        };
        let by = dir.normalize() * speed * dt;
        camera.eye += by;
        camera.target += by;
    }

    /// Turns the view direction by a mouse motion of `(dx, dy)` pixels, keeping the eye and the
    /// eye–target distance.
    pub fn look(&self, camera: &mut Camera, dx: f32, dy: f32) {
        let r = camera.distance().max(1e-3);
        let f = camera.forward();
        let heading = camera.heading();
        let mut yaw = heading.x.atan2(heading.z);
        let limit = 89f32.to_radians();
        let mut pitch = f.y.clamp(-1.0, 1.0).asin();
        yaw -= dx * self.look_speed;
        pitch = (pitch - dy * self.look_speed).clamp(-limit, limit);
        let dir = Vec3::new(
            pitch.cos() * yaw.sin(),
            pitch.sin(),
            pitch.cos() * yaw.cos(),
        );
        camera.target = camera.eye + dir * r;
        camera.up = Vec3::Y;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (Camera, Projection) {
        (
            Camera::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 0.5, 0.0)),
            Projection::new(320, 240, 45f32.to_radians()),
        )
    }

    #[test]
    fn view_projection_maps_the_target_to_the_ndc_centre() {
        let (cam, proj) = setup();
        let clip = cam.view_proj(&proj) * cam.target.extend(1.0);
        let ndc = clip.xyz() / clip.w;
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5, "{ndc}");
        assert!((0.0..1.0).contains(&ndc.z), "{ndc}");
        let px = cam.project(&proj, [320, 240], cam.target).unwrap();
        assert!((px - Vec2::new(160.0, 120.0)).length() < 1e-3, "{px}");
    }

    /// Where `point` lands in normalised device coordinates.
    fn ndc(cam: &Camera, proj: &Projection, point: Vec3) -> Vec3 {
        let clip = cam.view_proj(proj) * point.extend(1.0);
        clip.xyz() / clip.w
    }

    /// A camera straight above or below its target (view direction along `up`) built its view
    /// from a degenerate basis: a NaN matrix, and `cloth render … --set
    /// 'camera.eye=[0,3,0]' --set 'camera.target=[0,0,0]'` drew only the background.
    #[test]
    fn a_camera_straight_above_or_below_the_target_has_a_finite_view() {
        let proj = Projection::new(320, 240, 45f32.to_radians());
        let target = Vec3::new(0.2, 0.5, -0.1);
        // (eye offset, where a point 0.1 m towards −Z of the target appears: the image's top
        // points to −Z looking down, to +Z looking up, as the limit of a camera tilted to the
        // pole from the +Z side)
        for (offset, minus_z_up) in [(Vec3::Y * 3.0, true), (Vec3::NEG_Y * 2.0, false)] {
            let cam = Camera::new(target + offset, target);
            let view = cam.view();
            assert!(view.is_finite(), "{offset}: {view}");
            let c = ndc(&cam, &proj, target);
            assert!(c.x.abs() < 1e-5 && c.y.abs() < 1e-5, "{offset}: {c}");
            assert!((0.0..1.0).contains(&c.z), "{offset}: {c}");
            let px = cam.project(&proj, [320, 240], target).unwrap();
            assert!((px - Vec2::new(160.0, 120.0)).length() < 1e-3, "{px}");
            let towards = ndc(&cam, &proj, target + Vec3::NEG_Z * 0.1);
            assert!(towards.x.abs() < 1e-5, "{offset}: {towards}");
            assert_eq!(towards.y > 0.0, minus_z_up, "{offset}: {towards}");
            // the same orientation as a camera a hair short of the pole on the +Z side
            let near = Camera::new(target + offset + Vec3::Z * 0.01, target);
            let near_towards = ndc(&near, &proj, target + Vec3::NEG_Z * 0.1);
            assert!(
                (near_towards.y - towards.y).abs() < 0.05,
                "{near_towards} vs {towards}"
            );
            let right = cam.right();
            assert!(right.is_finite() && (right.length() - 1.0).abs() < 1e-5);
            assert!(right.dot(cam.forward()).abs() < 1e-6);
        }
    }

    /// An eye on the target (no direction to look in) still gives a finite view matrix.
    #[test]
    fn a_camera_with_its_eye_on_the_target_has_a_finite_view() {
        let cam = Camera::new(Vec3::ONE, Vec3::ONE);
        assert!(cam.view().is_finite());
        assert_eq!(cam.forward(), Vec3::NEG_Z);
        assert!(cam.view_proj(&Projection::new(320, 240, 1.0)).is_finite());
    }

    /// From straight above, the controllers turn the view without flipping the image: a
    /// small drag keeps a point towards −Z at the top of the image.
    #[test]
    fn the_controllers_turn_smoothly_away_from_straight_down() {
        let proj = Projection::new(320, 240, 45f32.to_radians());
        let target = Vec3::ZERO;
        let probe = Vec3::NEG_Z * 0.1;
        for negative_zero in [false, true] {
            // -0.0 - 0.0 = -0.0: the offset's atan2 read such an eye as the −Z side
            let z = if negative_zero { -0.0 } else { 0.0 };
            let straight = Camera::new(Vec3::new(z, 3.0, z), target);
            let before = ndc(&straight, &proj, probe);
            let mut orbit = straight;
            OrbitController::default().rotate(&mut orbit, 0.0, -2.0);
            let mut fly = straight;
            FlyController::default().look(&mut fly, 0.0, 1.0);
            for (name, cam) in [("orbit", orbit), ("fly", fly)] {
                assert!(cam.view().is_finite(), "{name}");
                let after = ndc(&cam, &proj, probe);
                assert!(
                    after.y > 0.0 && before.y > 0.0,
                    "{name}: {before} → {after}"
                );
            }
        }
    }

    #[test]
    fn orbit_keeps_the_distance_to_the_target() {
        let (mut cam, _) = setup();
        let r = cam.distance();
        let orbit = OrbitController::default();
        for (dx, dy) in [(30.0, 0.0), (0.0, 25.0), (-200.0, 400.0), (5.0, -1000.0)] {
            orbit.rotate(&mut cam, dx, dy);
            assert!(
                (cam.distance() - r).abs() < 1e-4,
                "{} vs {r}",
                cam.distance()
            );
            assert_eq!(cam.target, Vec3::new(0.0, 0.5, 0.0));
        }
        orbit.zoom(&mut cam, 2.0);
        assert!(cam.distance() < r);
    }

    #[test]
    fn pan_moves_eye_and_target_together() {
        let (mut cam, proj) = setup();
        let before = cam.eye - cam.target;
        OrbitController::default().pan(&mut cam, &proj, 240, 10.0, -7.0);
        assert!(((cam.eye - cam.target) - before).length() < 1e-5);
        assert_ne!(cam.target, Vec3::new(0.0, 0.5, 0.0));
    }

    #[test]
    fn fly_moves_along_the_view_direction() {
        let (mut cam, _) = setup();
        let f = cam.forward();
        let eye = cam.eye;
        let mut fly = FlyController::default();
        fly.keys.forward = true;
        fly.update(&mut cam, 0.5);
        let moved = cam.eye - eye;
        assert!((moved - f * 0.5).length() < 1e-5, "{moved} vs {f}");
        fly.keys.fast = true;
        let eye = cam.eye;
        fly.update(&mut cam, 0.5);
        assert!((cam.eye.distance(eye) - 2.0).abs() < 1e-4);
    }

    #[test]
    fn fly_look_keeps_the_eye() {
        let (mut cam, _) = setup();
        let eye = cam.eye;
        let fly = FlyController::default();
        fly.look(&mut cam, 50.0, 20.0);
        assert_eq!(cam.eye, eye);
    }

    #[test]
    fn lens_shift_moves_the_target_and_picking_follows() {
        let (cam, mut proj) = setup();
        proj.shift_x = 0.25;
        let px = cam.project(&proj, [320, 240], cam.target).unwrap();
        assert!((px - Vec2::new(200.0, 120.0)).length() < 1e-3, "{px}");
        let ray = cam.ray_through(&proj, [320, 240], px);
        let closest = ray.at((cam.target - ray.origin).dot(ray.dir));
        assert!(closest.distance(cam.target) < 1e-4);
    }

    #[test]
    fn projection_survives_a_minimised_window() {
        let mut p = Projection::new(800, 600, 1.0);
        p.resize(0, 0);
        assert!(p.matrix().is_finite());
    }

    #[test]
    fn a_ray_through_a_known_pixel_hits_a_known_particle() {
        let (cam, proj) = setup();
        // a 3 × 3 grid in the plane y = 0.5, centred on the target
        let mut positions = Vec::new();
        for r in 0..3 {
            for c in 0..3 {
                positions.push(Vec3::new(c as f32 * 0.2 - 0.2, 0.5, r as f32 * 0.2 - 0.2));
            }
        }
        let mut triangles = Vec::new();
        for r in 0..2u32 {
            for c in 0..2u32 {
                let i = r * 3 + c;
                triangles.push([i, i + 3, i + 1]);
                triangles.push([i + 1, i + 3, i + 4]);
            }
        }
        for want in [4usize, 0, 8, 5] {
            // a point a little off the particle (towards the grid's centre) still picks it
            let near = positions[want].lerp(positions[4], 0.2) + Vec3::new(0.01, 0.0, -0.01);
            let px = cam.project(&proj, [320, 240], near).unwrap();
            let ray = cam.ray_through(&proj, [320, 240], px);
            let (got, t) = ray
                .pick(&positions, &triangles)
                .expect("the ray hits the grid");
            assert_eq!(got, want);
            assert!((ray.at(t) - positions[want]).length() < 0.1);
        }
        let away = cam.ray_through(&proj, [320, 240], Vec2::new(2.0, 2.0));
        assert!(away.pick(&positions, &triangles).is_none());
    }
}
