//! The pinhole camera of RTIOW and of the reference scenes (`shared/reference/README.md`):
//! position, look-at point, up vector and full vertical field of view; pixel `(x, y)` from the
//! top left, a box filter over each pixel's square.

use glam::Vec3;
use phr_bvh::Ray;

/// A camera as a scene file describes it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Full vertical field of view in degrees.
    pub vfov_degrees: f32,
}

impl Default for CameraDesc {
    fn default() -> Self {
        Self { position: Vec3::new(0.0, 0.0, 1.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov_degrees: 60.0 }
    }
}

impl From<&crate::load::SourceCamera> for CameraDesc {
    fn from(c: &crate::load::SourceCamera) -> Self {
        Self { position: c.position, look_at: c.look_at, up: c.up, vfov_degrees: c.vfov_degrees }
    }
}

/// A camera ready to generate rays for an image of a given size.
#[derive(Clone, Debug)]
pub struct Camera {
    origin: Vec3,
    forward: Vec3,
    /// `right` scaled by `a · tan(vfov / 2)`.
    horizontal: Vec3,
    /// `up'` scaled by `tan(vfov / 2)`.
    vertical: Vec3,
    inv_width: f32,
    inv_height: f32,
    /// For [`Camera::project`] (once per pixel and frame in the temporal filter): half the
    /// image size in pixels over `|horizontal|²` and `|vertical|²`, and half the image size.
    project_scale: [f32; 2],
    half_size: [f32; 2],
}

impl Camera {
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Self {
        let forward = (desc.look_at - desc.position).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(desc.up).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let half_height = (desc.vfov_degrees.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        let (horizontal, vertical) = (right * (aspect * half_height), up * half_height);
        Self {
            origin: desc.position,
            forward,
            horizontal,
            vertical,
            inv_width: 1.0 / width as f32,
            inv_height: 1.0 / height as f32,
            project_scale: [
                0.5 * width as f32 / horizontal.length_squared(),
                0.5 * height as f32 / vertical.length_squared(),
            ],
            half_size: [0.5 * width as f32, 0.5 * height as f32],
        }
    }

    /// The ray through image point `(x, y)` in pixels (continuous; `x` from the left, `y` from
    /// the top). The direction is normalised.
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let sx = 2.0 * x * self.inv_width - 1.0;
        let sy = 2.0 * y * self.inv_height - 1.0;
        let dir = self.forward + sx * self.horizontal - sy * self.vertical;
        Ray::new(self.origin, dir.normalize())
    }
}

/// A camera's rays in closed form, for tracers that generate them elsewhere (the GPU's
/// kernel): the ray through image point `(x, y)` leaves `origin` along
/// `forward + sx · horizontal − sy · vertical`, normalised, with `sx = 2x / width − 1` and
/// `sy = 2y / height − 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraBasis {
    pub origin: Vec3,
    pub forward: Vec3,
    pub horizontal: Vec3,
    pub vertical: Vec3,
}

impl Camera {
    /// What [`Camera::ray`] computes its rays from.
    pub fn basis(&self) -> CameraBasis {
        CameraBasis { origin: self.origin, forward: self.forward, horizontal: self.horizontal, vertical: self.vertical }
    }

    /// Where `point` appears in the image: continuous pixel coordinates as [`Camera::ray`]
    /// takes them (`None` behind the camera). The inverse of `ray`.
    pub fn project(&self, point: Vec3) -> Option<(f32, f32)> {
        let d = point - self.origin;
        let depth = d.dot(self.forward);
        // Also NaN.
        if depth.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        // d / depth = forward + sx·horizontal − sy·vertical, the three orthogonal, and the
        // pixel is ((sx + 1)·width / 2, (sy + 1)·height / 2): one division.
        let inv_depth = 1.0 / depth;
        let [scale_x, scale_y] = self.project_scale;
        let x = d.dot(self.horizontal) * inv_depth * scale_x + self.half_size[0];
        let y = -d.dot(self.vertical) * inv_depth * scale_y + self.half_size[1];
        Some((x, y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_ray() {
        let desc = CameraDesc {
            position: Vec3::new(1.0, 2.0, 3.0),
            look_at: Vec3::new(-2.0, 0.5, -1.0),
            up: Vec3::new(0.1, 1.0, 0.0),
            vfov_degrees: 55.0,
        };
        let cam = Camera::new(&desc, 320, 200);
        for (x, y) in [(0.0, 0.0), (160.0, 100.0), (319.5, 12.25), (-30.0, 250.0)] {
            let ray = cam.ray(x, y);
            let (px, py) = cam.project(ray.origin + 7.0 * ray.dir).expect("in front");
            assert!((px - x).abs() < 1e-3 && (py - y).abs() < 1e-3, "({x}, {y}) came back as ({px}, {py})");
        }
        assert_eq!(cam.project(desc.position - (desc.look_at - desc.position)), None, "behind");
    }

    #[test]
    fn orientation_matches_the_reference_convention() {
        // "A camera at z = 3.9 looking towards -z with up +y sees +x on the right."
        let desc = CameraDesc {
            position: Vec3::new(0.0, 1.0, 3.9),
            look_at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            vfov_degrees: 40.0,
        };
        let cam = Camera::new(&desc, 200, 100);
        let centre = cam.ray(100.0, 50.0);
        assert!((centre.dir - Vec3::NEG_Z).length() < 1e-6);
        assert!(cam.ray(199.0, 50.0).dir.x > 0.0, "right edge looks towards +x");
        assert!(cam.ray(100.0, 0.0).dir.y > 0.0, "top row looks up");
        let top = cam.ray(100.0, 0.0).dir;
        let angle = top.y.atan2(-top.z).to_degrees();
        assert!((angle - 20.0).abs() < 1e-3, "half the vertical fov: {angle}");
    }
}
