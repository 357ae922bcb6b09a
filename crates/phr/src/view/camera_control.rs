//! Camera navigation for the viewer: orbit about a target (drag), look around in place (right
//! drag), dolly (wheel), fly (WASD, Q/E down/up, Shift faster). The camera is kept as a
//! position, a yaw and pitch about the scene's up vector, and a distance to the orbit target,
//! so every gesture is a small change of one of them.

use glam::Vec3;
use phr_render::camera::CameraDesc;

#[derive(Clone, Debug)]
pub struct CameraControl {
    position: Vec3,
    yaw: f32,
    pitch: f32,
    distance: f32,
    vfov: f32,
    up: Vec3,
    /// Two unit vectors completing `up` to an orthonormal basis; yaw is measured in their plane.
    basis: (Vec3, Vec3),
    /// World units per second when flying (scaled with the scene).
    pub speed: f32,
}

/// Radians per pixel of mouse drag.
const ROTATE_PER_PIXEL: f32 = 0.005;
const MAX_PITCH: f32 = 1.55;

impl CameraControl {
    /// Takes over a camera; `scene_size` (the scene's diagonal) sets the flying speed.
    pub fn new(desc: &CameraDesc, scene_size: f32) -> Self {
        let up = desc.up.normalize_or(Vec3::Y);
        let e1 = up.any_orthonormal_vector();
        let e2 = up.cross(e1);
        let mut c = Self {
            position: desc.position,
            yaw: 0.0,
            pitch: 0.0,
            distance: 1.0,
            vfov: desc.vfov_degrees,
            up,
            basis: (e1, e2),
            speed: 0.25 * scene_size.max(1e-3),
        };
        c.look_at(desc.position, desc.look_at);
        c
    }

    fn look_at(&mut self, position: Vec3, target: Vec3) {
        let offset = target - position;
        self.position = position;
        self.distance = offset.length().max(1e-4);
        let f = offset / self.distance;
        let (e1, e2) = self.basis;
        self.pitch = f.dot(self.up).clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH);
        self.yaw = f.dot(e2).atan2(f.dot(e1));
    }

    pub fn forward(&self) -> Vec3 {
        let (e1, e2) = self.basis;
        let horizontal = e1 * self.yaw.cos() + e2 * self.yaw.sin();
        horizontal * self.pitch.cos() + self.up * self.pitch.sin()
    }

    fn right(&self) -> Vec3 {
        self.forward().cross(self.up).normalize_or(self.basis.0)
    }

    pub fn target(&self) -> Vec3 {
        self.position + self.forward() * self.distance
    }

    pub fn desc(&self) -> CameraDesc {
        CameraDesc { position: self.position, look_at: self.target(), up: self.up, vfov_degrees: self.vfov }
    }

    /// Turns the camera about its target by a mouse drag of `(dx, dy)` pixels.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        let target = self.target();
        self.rotate(dx, dy);
        self.position = target - self.forward() * self.distance;
    }

    /// Turns the camera in place (the target moves).
    pub fn look(&mut self, dx: f32, dy: f32) {
        self.rotate(dx, dy);
    }

    fn rotate(&mut self, dx: f32, dy: f32) {
        // Dragging right turns the view to the right: yaw grows towards `right`.
        let (e1, e2) = self.basis;
        let sign = if e1.cross(e2).dot(self.up) >= 0.0 { -1.0 } else { 1.0 };
        self.yaw += sign * dx * ROTATE_PER_PIXEL;
        self.pitch = (self.pitch - dy * ROTATE_PER_PIXEL).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Moves towards (positive `steps`) or away from the target, by 10 % of the distance a step.
    pub fn dolly(&mut self, steps: f32) {
        let target = self.target();
        self.distance = (self.distance * 0.9f32.powf(steps)).max(1e-4);
        self.position = target - self.forward() * self.distance;
    }

    /// Flies by `dt` seconds along `(right, up, forward)` in `[-1, 1]` each.
    pub fn fly(&mut self, direction: Vec3, dt: f32, fast: bool) {
        let speed = self.speed * if fast { 4.0 } else { 1.0 };
        let step = self.right() * direction.x + self.up * direction.y + self.forward() * direction.z;
        self.position += step * (speed * dt);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc() -> CameraDesc {
        CameraDesc {
            position: Vec3::new(0.0, 1.0, 5.0),
            look_at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            vfov_degrees: 40.0,
        }
    }

    #[test]
    fn round_trips_the_scene_camera() {
        let c = CameraControl::new(&desc(), 10.0);
        let d = c.desc();
        assert!((d.position - desc().position).length() < 1e-5);
        assert!((d.look_at - desc().look_at).length() < 1e-4, "{:?}", d.look_at);
    }

    #[test]
    fn orbit_keeps_the_target_and_distance() {
        let mut c = CameraControl::new(&desc(), 10.0);
        c.orbit(120.0, -40.0);
        let d = c.desc();
        assert!((d.look_at - desc().look_at).length() < 1e-4);
        assert!(((d.position - d.look_at).length() - 5.0).abs() < 1e-4);
        assert!((d.position - desc().position).length() > 0.5, "the camera moved");
        // Dragging right moves the view to the right: the camera swings to the left (-x).
        assert!(d.position.x < 0.0, "{:?}", d.position);
    }

    #[test]
    fn fly_and_dolly_move_along_the_view() {
        let mut c = CameraControl::new(&desc(), 4.0);
        c.fly(Vec3::Z, 1.0, false);
        assert!((c.desc().position - Vec3::new(0.0, 1.0, 4.0)).length() < 1e-4);
        c.fly(Vec3::X, 1.0, true);
        assert!((c.desc().position - Vec3::new(4.0, 1.0, 4.0)).length() < 1e-4, "right is +x, shift is 4x");
        let mut c = CameraControl::new(&desc(), 4.0);
        c.dolly(1.0);
        assert!((c.desc().position.z - 4.5).abs() < 1e-4);
    }
}
