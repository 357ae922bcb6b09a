//! What moves, as plain data: procedural [`Motion`]s a scene file attaches to an object
//! (`"animate"`: a rotation about a pivot, a sinusoidal back-and-forth, a travelling wave) and
//! glTF node animations ([`NodeAnimation`]: keyframed translation, rotation and scale through
//! the node hierarchy), each evaluated at a time. Loaders and the scene model fill these in;
//! [`crate::animation::Animator`] applies them to a scene's geometry. Nothing here knows about
//! scenes or geometry, so the loaders and the scene model depend on it and not on the
//! animator.

use glam::{Affine3A, Mat4, Quat, Vec3};
use rayon::prelude::*;

/// A procedural motion of an object's vertices (or a sphere's centre); `t` is in seconds.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// Turns about `axis` through `pivot`.
    Rotate { axis: Vec3, pivot: Vec3, degrees_per_second: f32 },
    /// Moves by `amplitude · sin(2π t / period)`: a bob or a swing.
    Oscillate { amplitude: Vec3, period: f32 },
    /// Displaces each vertex along `displacement` (a unit vector) by
    /// `amplitude · sin(2π (p·direction / wavelength − t / period))`: a travelling wave.
    Wave { amplitude: f32, wavelength: f32, period: f32, direction: Vec3, displacement: Vec3 },
}

impl Motion {
    #[inline]
    pub fn apply(&self, p: Vec3, t: f32) -> Vec3 {
        use std::f32::consts::TAU;
        match *self {
            Motion::Rotate { axis, pivot, degrees_per_second } => {
                pivot + Quat::from_axis_angle(axis, (degrees_per_second * t).to_radians()) * (p - pivot)
            }
            Motion::Oscillate { amplitude, period } => p + amplitude * (TAU * t / period).sin(),
            Motion::Wave { amplitude, wavelength, period, direction, displacement } => {
                let phase = TAU * (p.dot(direction) / wavelength - t / period);
                p + displacement * (amplitude * phase.sin())
            }
        }
    }

    /// Applies `motions` in order.
    pub fn apply_all(motions: &[Motion], p: Vec3, t: f32) -> Vec3 {
        motions.iter().fold(p, |p, m| m.apply(p, t))
    }

    /// For a wave, the sine and cosine of each point's spatial phase `2π p·direction /
    /// wavelength`, which do not change with time: [`WaveAt::apply`] then poses a point with
    /// two multiplications instead of a sine (the 871k-triangle dragon's 437k vertices took
    /// 3 ms a frame of sines on 2 threads). `None` for the other motions.
    pub fn rest_phases(&self, points: &[Vec3]) -> Option<Vec<[f32; 2]>> {
        use std::f32::consts::TAU;
        let Motion::Wave { wavelength, direction, .. } = *self else { return None };
        Some(
            points
                .par_iter()
                .map(|p| {
                    let (sin, cos) = (TAU * p.dot(direction) / wavelength).sin_cos();
                    [sin, cos]
                })
                .collect(),
        )
    }

    /// A wave at time `t`, to apply to points whose [`Motion::rest_phases`] are known; `None`
    /// for the other motions.
    pub fn wave_at(&self, t: f32) -> Option<WaveAt> {
        use std::f32::consts::TAU;
        let Motion::Wave { amplitude, period, displacement, .. } = *self else { return None };
        let (sin, cos) = (TAU * t / period).sin_cos();
        Some(WaveAt { offset: displacement * amplitude, sin, cos })
    }

    /// The motion at time `t` as one affine map of space, if it is one (rotations and
    /// oscillations are; a wave deforms).
    pub fn affine(&self, t: f32) -> Option<Affine3A> {
        use std::f32::consts::TAU;
        match *self {
            Motion::Rotate { axis, pivot, degrees_per_second } => {
                let q = Quat::from_axis_angle(axis, (degrees_per_second * t).to_radians());
                Some(Affine3A::from_rotation_translation(q, pivot - q * pivot))
            }
            Motion::Oscillate { amplitude, period } => {
                Some(Affine3A::from_translation(amplitude * (TAU * t / period).sin()))
            }
            Motion::Wave { .. } => None,
        }
    }

    /// [`Motion::apply_all`] as one affine map, if every motion is one.
    pub fn affine_all(motions: &[Motion], t: f32) -> Option<Affine3A> {
        motions.iter().try_fold(Affine3A::IDENTITY, |m, motion| Some(motion.affine(t)? * m))
    }

    /// The motions of a copy placed by `to_world`: the same motions in the world, each
    /// rotation about its pivot as the copy places it (so every copy turns about its own
    /// centre, or its own point of the pivot given).
    pub fn placed_by(motions: &[Motion], to_world: Affine3A) -> Vec<Motion> {
        motions
            .iter()
            .map(|m| match m {
                &Motion::Rotate { axis, pivot, degrees_per_second } => {
                    Motion::Rotate { axis, pivot: to_world.transform_point3(pivot), degrees_per_second }
                }
                other => other.clone(),
            })
            .collect()
    }
}

/// A travelling wave at one time ([`Motion::wave_at`]): the sine of a point's phase
/// `a − b` (`a` its spatial phase, `b = 2π t / period`) is `sin a cos b − cos a sin b`.
#[derive(Clone, Copy, Debug)]
pub struct WaveAt {
    /// `amplitude · displacement`.
    offset: Vec3,
    /// Of `b`.
    sin: f32,
    cos: f32,
}

impl WaveAt {
    /// [`Motion::apply`] of the wave to `p`, whose spatial phase's sine and cosine are `phase`.
    #[inline]
    pub fn apply(&self, p: Vec3, [sin_a, cos_a]: [f32; 2]) -> Vec3 {
        p + self.offset * (sin_a * self.cos - cos_a * self.sin)
    }
}

/// How keyframes are interpolated (glTF `sampler.interpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    /// Values come in triples (in-tangent, value, out-tangent).
    CubicSpline,
}

/// Keyframes of one node property.
#[derive(Clone, Debug)]
pub struct Track<T> {
    pub times: Vec<f32>,
    pub values: Vec<T>,
    pub interpolation: Interpolation,
}

/// What a track's values can do: blend linearly, and be combined for cubic Hermite splines.
pub trait Keyframe: Copy {
    fn lerp_to(self, other: Self, s: f32) -> Self;
    fn hermite(p0: Self, m0: Self, p1: Self, m1: Self, s: f32, dt: f32) -> Self;
}

impl Keyframe for Vec3 {
    fn lerp_to(self, other: Self, s: f32) -> Self {
        self.lerp(other, s)
    }
    fn hermite(p0: Self, m0: Self, p1: Self, m1: Self, s: f32, dt: f32) -> Self {
        let (s2, s3) = (s * s, s * s * s);
        p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
            + m0 * (dt * (s3 - 2.0 * s2 + s))
            + p1 * (-2.0 * s3 + 3.0 * s2)
            + m1 * (dt * (s3 - s2))
    }
}

impl Keyframe for Quat {
    fn lerp_to(self, other: Self, s: f32) -> Self {
        self.slerp(other, s)
    }
    fn hermite(p0: Self, m0: Self, p1: Self, m1: Self, s: f32, dt: f32) -> Self {
        let v = |q: Quat| glam::Vec4::from(q);
        let (s2, s3) = (s * s, s * s * s);
        let r = v(p0) * (2.0 * s3 - 3.0 * s2 + 1.0)
            + v(m0) * (dt * (s3 - 2.0 * s2 + s))
            + v(p1) * (-2.0 * s3 + 3.0 * s2)
            + v(m1) * (dt * (s3 - s2));
        Quat::from_vec4(r).normalize()
    }
}

impl<T: Keyframe> Track<T> {
    /// The value at time `t` (clamped to the first and last keyframe).
    pub fn sample(&self, t: f32) -> T {
        let n = self.times.len();
        let value = |k: usize| match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * k + 1],
            _ => self.values[k],
        };
        if n == 1 || t <= self.times[0] {
            return value(0);
        }
        if t >= self.times[n - 1] {
            return value(n - 1);
        }
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let dt = self.times[k + 1] - self.times[k];
        let s = if dt > 0.0 { (t - self.times[k]) / dt } else { 0.0 };
        match self.interpolation {
            Interpolation::Step => value(k),
            Interpolation::Linear => value(k).lerp_to(value(k + 1), s),
            Interpolation::CubicSpline => {
                let out_tangent = self.values[3 * k + 2];
                let in_tangent = self.values[3 * (k + 1)];
                T::hermite(value(k), out_tangent, value(k + 1), in_tangent, s, dt)
            }
        }
    }
}

/// A glTF node: its rest transform, its parent, and the tracks that animate it.
#[derive(Clone, Debug)]
pub struct AnimatedNode {
    pub parent: Option<usize>,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    pub translation_track: Option<Track<Vec3>>,
    pub rotation_track: Option<Track<Quat>>,
    pub scale_track: Option<Track<Vec3>>,
}

impl AnimatedNode {
    fn local(&self, t: f32) -> Mat4 {
        let translation = self.translation_track.as_ref().map_or(self.translation, |k| k.sample(t));
        let rotation = self.rotation_track.as_ref().map_or(self.rotation, |k| k.sample(t).normalize());
        let scale = self.scale_track.as_ref().map_or(self.scale, |k| k.sample(t));
        Mat4::from_scale_rotation_translation(scale, rotation, translation)
    }

    fn is_animated(&self) -> bool {
        self.translation_track.is_some() || self.rotation_track.is_some() || self.scale_track.is_some()
    }
}

/// Vertices (a contiguous range of a mesh's positions) placed by one glTF node.
#[derive(Clone, Debug)]
pub struct AnimatedPart {
    pub node: usize,
    pub first_vertex: usize,
    /// The vertices in the node's own space.
    pub local: Vec<Vec3>,
}

/// The animations of a glTF file, all played together and looped over `duration` seconds.
#[derive(Clone, Debug, Default)]
pub struct NodeAnimation {
    pub nodes: Vec<AnimatedNode>,
    /// Only the parts under an animated node.
    pub parts: Vec<AnimatedPart>,
    pub duration: f32,
    /// Applied after the node hierarchy (the scene file's `transform` of the glTF object).
    pub outer: Mat4,
}

impl NodeAnimation {
    /// World matrix of `node` at time `t`.
    fn world(&self, node: usize, t: f32) -> Mat4 {
        self.chain(node, |n| n.local(t))
    }

    /// `outer` times the product of `local` over `node` and its ancestors, walking up the
    /// parent chain (bounded, in case a malformed file has a cycle).
    fn chain(&self, node: usize, local: impl Fn(&AnimatedNode) -> Mat4) -> Mat4 {
        let mut m = local(&self.nodes[node]);
        let mut parent = self.nodes[node].parent;
        let mut guard = 0;
        while let Some(p) = parent {
            m = local(&self.nodes[p]) * m;
            parent = self.nodes[p].parent;
            guard += 1;
            if guard > self.nodes.len() {
                break;
            }
        }
        self.outer * m
    }

    /// Whether any node of a part's chain moves.
    pub fn moves(&self, node: usize) -> bool {
        let mut current = Some(node);
        let mut guard = 0;
        while let Some(n) = current {
            if self.nodes[n].is_animated() {
                return true;
            }
            current = self.nodes[n].parent;
            guard += 1;
            if guard > self.nodes.len() {
                return false;
            }
        }
        false
    }

    /// The animation's own time at scene time `t`: looped over its duration.
    fn looped(&self, t: f32) -> f32 {
        if self.duration > 0.0 {
            t.rem_euclid(self.duration)
        } else {
            0.0
        }
    }

    /// World matrix of `node` at scene time `t` (looped).
    pub fn world_at(&self, node: usize, t: f32) -> Mat4 {
        self.world(node, self.looped(t))
    }

    /// World matrix of `node` in the rest pose the loader placed the vertices in: every node's
    /// own translation, rotation and scale, without the tracks.
    pub fn rest_world(&self, node: usize) -> Mat4 {
        self.chain(node, |n| Mat4::from_scale_rotation_translation(n.scale, n.rotation, n.translation))
    }

    /// Writes the posed vertices of every part at time `t` (looped) into `positions`.
    pub fn pose(&self, positions: &mut [Vec3], t: f32) {
        let t = self.looped(t);
        for part in &self.parts {
            let m = self.world(part.node, t);
            let out = &mut positions[part.first_vertex..part.first_vertex + part.local.len()];
            out.par_iter_mut().zip(&part.local).for_each(|(p, &l)| *p = m.transform_point3(l));
        }
    }
}

/// What moves an object.
#[derive(Clone, Debug)]
pub enum Animation {
    Procedural(Vec<Motion>),
    Nodes(Box<NodeAnimation>),
}

/// An animation attached to mesh `index` or sphere `index` of a scene.
#[derive(Clone, Debug)]
pub struct ObjectAnimation {
    pub target: AnimationTarget,
    pub animation: Animation,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnimationTarget {
    Mesh(usize),
    Sphere(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motions_move_as_documented() {
        let rotate = Motion::Rotate { axis: Vec3::Y, pivot: Vec3::new(1.0, 0.0, 0.0), degrees_per_second: 90.0 };
        let p = rotate.apply(Vec3::new(2.0, 0.0, 0.0), 1.0);
        assert!((p - Vec3::new(1.0, 0.0, -1.0)).length() < 1e-5, "{p}");
        let bob = Motion::Oscillate { amplitude: Vec3::Y, period: 4.0 };
        assert!((bob.apply(Vec3::ZERO, 1.0) - Vec3::Y).length() < 1e-6);
        assert!(bob.apply(Vec3::ZERO, 2.0).length() < 1e-5);
        let wave =
            Motion::Wave { amplitude: 0.5, wavelength: 2.0, period: 1.0, direction: Vec3::X, displacement: Vec3::Y };
        // A quarter wavelength along x is the crest at t = 0; the shape changes with x.
        assert!((wave.apply(Vec3::new(0.5, 0.0, 0.0), 0.0).y - 0.5).abs() < 1e-5);
        assert!(wave.apply(Vec3::ZERO, 0.0).y.abs() < 1e-5);
    }

    #[test]
    fn rigid_motions_are_one_affine_map() {
        let motions = [
            Motion::Rotate {
                axis: Vec3::new(0.3, 1.0, 0.2).normalize(),
                pivot: Vec3::new(1.0, -2.0, 0.5),
                degrees_per_second: 40.0,
            },
            Motion::Oscillate { amplitude: Vec3::new(0.0, 0.7, -0.2), period: 2.5 },
            Motion::Rotate { axis: Vec3::X, pivot: Vec3::ZERO, degrees_per_second: -75.0 },
        ];
        for t in [0.0, 0.4, 1.7, 9.0] {
            let m = Motion::affine_all(&motions, t).expect("rotations and oscillations are rigid");
            for p in [Vec3::ZERO, Vec3::new(3.0, -1.0, 2.0), Vec3::new(-0.5, 4.0, 1.0)] {
                let (got, want) = (m.transform_point3(p), Motion::apply_all(&motions, p, t));
                assert!((got - want).length() < 1e-4, "t = {t}, p = {p}: {got} vs {want}");
            }
        }
        let wave =
            Motion::Wave { amplitude: 0.5, wavelength: 2.0, period: 1.0, direction: Vec3::X, displacement: Vec3::Y };
        assert!(Motion::affine_all(&[motions[1].clone(), wave], 1.0).is_none());
    }

    #[test]
    fn a_wave_from_rest_phases_moves_points_as_applied() {
        let wave = Motion::Wave {
            amplitude: 0.3,
            wavelength: 0.7,
            period: 1.3,
            direction: Vec3::new(0.8, 0.1, -0.6).normalize(),
            displacement: Vec3::new(0.0, 1.0, 0.2).normalize(),
        };
        let points: Vec<Vec3> =
            (0..200).map(|k| Vec3::new(k as f32 * 0.037 - 3.0, (k % 7) as f32 * 0.4, (k % 13) as f32 * -0.3)).collect();
        let phases = wave.rest_phases(&points).expect("a wave");
        for t in [0.0, 0.21, 1.0, 7.9] {
            let at = wave.wave_at(t).expect("a wave");
            for (&p, &phase) in points.iter().zip(&phases) {
                let (got, want) = (at.apply(p, phase), wave.apply(p, t));
                assert!((got - want).length() < 1e-5, "t = {t}, p = {p}: {got} vs {want}");
            }
        }
        let bob = Motion::Oscillate { amplitude: Vec3::Y, period: 4.0 };
        assert!(bob.rest_phases(&points).is_none() && bob.wave_at(1.0).is_none());
    }

    #[test]
    fn tracks_interpolate_and_clamp() {
        let track = Track {
            times: vec![0.0, 1.0, 3.0],
            values: vec![Vec3::ZERO, Vec3::X, Vec3::new(3.0, 0.0, 0.0)],
            interpolation: Interpolation::Linear,
        };
        assert_eq!(track.sample(-1.0), Vec3::ZERO);
        assert!((track.sample(0.5) - Vec3::new(0.5, 0.0, 0.0)).length() < 1e-6);
        assert!((track.sample(2.0) - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6);
        assert_eq!(track.sample(9.0), Vec3::new(3.0, 0.0, 0.0));
        let step = Track { interpolation: Interpolation::Step, ..track.clone() };
        assert_eq!(step.sample(0.99), Vec3::ZERO);
        // A cubic spline with zero tangents passes through its keys and stays between them.
        let cubic = Track {
            times: vec![0.0, 1.0],
            values: vec![Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::X, Vec3::ZERO],
            interpolation: Interpolation::CubicSpline,
        };
        assert!((cubic.sample(0.5).x - 0.5).abs() < 1e-6);
        assert_eq!(cubic.sample(1.0), Vec3::X);
        let spin = Track {
            times: vec![0.0, 1.0],
            values: vec![Quat::IDENTITY, Quat::from_rotation_y(std::f32::consts::FRAC_PI_2)],
            interpolation: Interpolation::Linear,
        };
        let half = spin.sample(0.5) * Vec3::X;
        let expected = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4) * Vec3::X;
        assert!((half - expected).length() < 1e-5);
    }

    #[test]
    fn node_hierarchy_composes_parent_motion() {
        let node = |parent, translation, track| AnimatedNode {
            parent,
            translation,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
            translation_track: track,
            rotation_track: None,
            scale_track: None,
        };
        let slide = Track {
            times: vec![0.0, 2.0],
            values: vec![Vec3::ZERO, Vec3::new(0.0, 2.0, 0.0)],
            interpolation: Interpolation::Linear,
        };
        let animation = NodeAnimation {
            nodes: vec![node(None, Vec3::ZERO, Some(slide)), node(Some(0), Vec3::X, None)],
            parts: vec![AnimatedPart { node: 1, first_vertex: 1, local: vec![Vec3::Z] }],
            duration: 2.0,
            outer: Mat4::from_translation(Vec3::new(0.0, 0.0, 10.0)),
        };
        assert!(animation.moves(1));
        let mut positions = vec![Vec3::splat(-7.0); 2];
        animation.pose(&mut positions, 1.0);
        assert_eq!(positions[0], Vec3::splat(-7.0), "vertices outside parts stay");
        assert!((positions[1] - Vec3::new(1.0, 1.0, 11.0)).length() < 1e-5, "{}", positions[1]);
        // Looped: t = 3 is t = 1.
        animation.pose(&mut positions, 3.0);
        assert!((positions[1] - Vec3::new(1.0, 1.0, 11.0)).length() < 1e-5);
    }
}
