//! The progressive path tracer on the GPU: one dispatch per frame, one invocation per pixel
//! (`shaders/path.wgsl`), sums of the samples and of their squares kept on the GPU until the
//! caller reads them back as a [`Film`].

use crate::device::{Binding, Gpu, GpuError};
use crate::scene::{GpuScene, Split, COMMON_WGSL};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use phr_render::camera::Camera;
use phr_render::film::Film;
use phr_render::scene::Background;

const PATH_WGSL: &str = include_str!("shaders/path.wgsl");
const LIGHTS_WGSL: &str = include_str!("shaders/lights.wgsl");
const ENVIRONMENT_WGSL: &str = include_str!("shaders/environment.wgsl");
/// The kernel's workgroup is 8 × 8 pixels.
const GROUP: u32 = 8;

/// `Frame` in `shaders/path.wgsl`.
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
#[repr(C)]
struct FrameUniform {
    width: u32,
    height: u32,
    number: u32,
    max_depth: u32,
    seed: [u32; 2],
    background: u32,
    light_sampling: u32,
    sky_probability: f32,
    light_count: u32,
    environment: [u32; 2],
    rotation: [f32; 2],
    inv_size: [f32; 2],
    origin: [f32; 4],
    forward: [f32; 4],
    horizontal: [f32; 4],
    vertical: [f32; 4],
    sky_a: [f32; 4],
    sky_b: [f32; 4],
}

fn lanes(v: Vec3) -> [f32; 4] {
    [v.x, v.y, v.z, 0.0]
}

/// The GPU's renderer of one view of a [`GpuScene`], at one size, depth and seed.
pub struct GpuTracer {
    gpu: Gpu,
    pipeline: wgpu::ComputePipeline,
    /// The scene's split the kernel was compiled for, and the frame's bindings' layout (to
    /// compile it again when a moved scene's arrays take other bindings).
    split: Split,
    layout: wgpu::BindGroupLayout,
    group: wgpu::BindGroup,
    frame: wgpu::Buffer,
    sum: wgpu::Buffer,
    sum_sq: wgpu::Buffer,
    rays: wgpu::Buffer,
    uniform: FrameUniform,
    pub width: u32,
    pub height: u32,
    /// Frames accumulated since the last [`GpuTracer::clear`].
    samples: u32,
}

impl GpuTracer {
    /// The renderer of `scene` seen by `camera` (made for `width × height`), paths of at most
    /// `max_depth` segments, random numbers of `seed` (the CPU's for the same seed); with light
    /// sampling if `scene` was uploaded with a light set.
    pub fn new(
        gpu: &Gpu,
        scene: &GpuScene,
        camera: &Camera,
        width: u32,
        height: u32,
        max_depth: u32,
        seed: u64,
    ) -> Result<Self, GpuError> {
        let max_groups = gpu.device.limits().max_compute_workgroups_per_dimension;
        if width == 0 || height == 0 || width.div_ceil(GROUP).max(height.div_ceil(GROUP)) > max_groups {
            return Err(GpuError::TooLarge(format!(
                "an image of {width} × {height} pixels (the adapter dispatches at most {} pixels a side)",
                u64::from(max_groups) * u64::from(GROUP)
            )));
        }
        let (kind, sky_a, sky_b) = match scene.background {
            Background::Constant(c) => (0, c, c),
            Background::Gradient { bottom, top } => (1, bottom, top),
            // Its texels, tables, size and rotation are the scene's (`environment.wgsl`).
            Background::Environment(_) => (2, Vec3::ZERO, Vec3::ZERO),
        };
        let (sky_probability, light_count) = scene.lights.unwrap_or((0.0, 0));
        let (environment, rotation) = scene.environment.unwrap_or_default();
        let uniform = FrameUniform {
            width,
            height,
            number: 0,
            max_depth,
            seed: [seed as u32, (seed >> 32) as u32],
            background: kind,
            light_sampling: u32::from(scene.lights.is_some()),
            sky_probability,
            light_count,
            environment,
            rotation,
            inv_size: [1.0 / width as f32, 1.0 / height as f32],
            origin: [0.0; 4],
            forward: [0.0; 4],
            horizontal: [0.0; 4],
            vertical: [0.0; 4],
            sky_a: lanes(sky_a),
            sky_b: lanes(sky_b),
        };
        let device = &gpu.device;
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let zeros = vec![0u8; width as usize * height as usize * 16];
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let sum = gpu.storage("sum", &zeros, copy)?;
        let sum_sq = gpu.storage("sum of squares", &zeros, copy)?;
        let rays = gpu.storage("rays", &[0; 8], copy)?;
        let layout =
            gpu.layout("path tracer", &[Binding::Uniform, Binding::ReadWrite, Binding::ReadWrite, Binding::ReadWrite]);
        let group = gpu.bind("path tracer", &layout, &[&frame, &sum, &sum_sq, &rays]);
        let pipeline = Self::kernel(gpu, scene, &layout);
        let mut tracer = Self {
            gpu: gpu.clone(),
            pipeline,
            split: scene.split,
            layout,
            group,
            frame,
            sum,
            sum_sq,
            rays,
            uniform,
            width,
            height,
            samples: 0,
        };
        tracer.set_camera(camera);
        Ok(tracer)
    }

    /// The path tracer's kernel, compiled for `scene`'s [`Split`].
    fn kernel(gpu: &Gpu, scene: &GpuScene, layout: &wgpu::BindGroupLayout) -> wgpu::ComputePipeline {
        let source = format!("{COMMON_WGSL}\n{PATH_WGSL}\n{LIGHTS_WGSL}\n{ENVIRONMENT_WGSL}");
        gpu.pipeline("path tracer", &source, "render", &[&scene.layout, layout], &scene.split.constants())
    }

    /// Moves the camera (made for the tracer's size); the frames after see the new view. The
    /// accumulated samples stay: [`GpuTracer::clear`] them.
    pub fn set_camera(&mut self, camera: &Camera) {
        let basis = camera.basis();
        self.uniform.origin = lanes(basis.origin);
        self.uniform.forward = lanes(basis.forward);
        self.uniform.horizontal = lanes(basis.horizontal);
        self.uniform.vertical = lanes(basis.vertical);
    }

    /// Submits frames `frames` of `scene` (the one the tracer was made for, or that scene
    /// moved: [`GpuScene::update`]), one sample per pixel each (frame `k` gives every pixel the
    /// sample the CPU's frame `k` gives it, up to rounding), and returns without waiting.
    pub fn render(&mut self, scene: &GpuScene, frames: std::ops::Range<u32>) {
        if scene.split != self.split {
            self.pipeline = Self::kernel(&self.gpu, scene, &self.layout);
            self.split = scene.split;
        }
        if let Some((sky, emitters)) = scene.lights {
            (self.uniform.sky_probability, self.uniform.light_count) = (sky, emitters);
        }
        for k in frames {
            self.uniform.number = k;
            // Takes effect before the next submission: each frame sees its own number.
            self.gpu.queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&self.uniform));
            let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &scene.group, &[]);
                pass.set_bind_group(1, &self.group, &[]);
                pass.dispatch_workgroups(self.width.div_ceil(GROUP), self.height.div_ceil(GROUP), 1);
            }
            self.gpu.queue.submit([encoder.finish()]);
            self.samples += 1;
        }
    }

    /// Frames accumulated since the last [`GpuTracer::clear`].
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The sums of the accumulated samples (`vec4<f32>` per pixel, row-major from the top
    /// left), which the display kernel reads.
    pub(crate) fn sums(&self) -> &wgpu::Buffer {
        &self.sum
    }

    /// Waits for the submitted frames.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.gpu.wait()
    }

    /// Discards the accumulated samples (the view changed).
    pub fn clear(&mut self) {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        for b in [&self.sum, &self.sum_sq, &self.rays] {
            encoder.clear_buffer(b, 0, None);
        }
        self.gpu.queue.submit([encoder.finish()]);
        self.samples = 0;
    }

    /// What has accumulated, read back (waits for the submitted frames).
    pub fn film(&self) -> Result<Film, GpuError> {
        let mut film = Film::new(self.width, self.height);
        film.add_sums(&self.read_sums(&self.sum)?, &self.read_sums(&self.sum_sq)?, self.samples);
        Ok(film)
    }

    /// Adds what has accumulated to `film` and starts the GPU's sums again (waits for the
    /// submitted frames). The GPU sums in single precision; moving its sums into the film's
    /// double-precision ones every few frames keeps the variance of long renders exact. The
    /// ray count goes on.
    pub fn drain_into(&mut self, film: &mut Film) -> Result<(), GpuError> {
        film.add_sums(&self.read_sums(&self.sum)?, &self.read_sums(&self.sum_sq)?, self.samples);
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.sum, 0, None);
        encoder.clear_buffer(&self.sum_sq, 0, None);
        self.gpu.queue.submit([encoder.finish()]);
        self.samples = 0;
        Ok(())
    }

    /// The mean of what has accumulated, read back (waits for the submitted frames): after one
    /// frame, its samples.
    pub fn mean(&self) -> Result<Vec<Vec3>, GpuError> {
        let n = f64::from(self.samples.max(1));
        Ok(self
            .read_sums(&self.sum)?
            .into_iter()
            .map(|[r, g, b]| Vec3::new((r / n) as f32, (g / n) as f32, (b / n) as f32))
            .collect())
    }

    fn read_sums(&self, buffer: &wgpu::Buffer) -> Result<Vec<[f64; 3]>, GpuError> {
        let bytes = self.gpu.read(buffer, u64::from(self.width) * u64::from(self.height) * 16)?;
        Ok(bytemuck::pod_collect_to_vec::<u8, [f32; 4]>(&bytes)
            .into_iter()
            .map(|[r, g, b, _]| [f64::from(r), f64::from(g), f64::from(b)])
            .collect())
    }

    /// Rays traced since the last [`GpuTracer::clear`] (waits for the submitted frames).
    pub fn rays(&self) -> Result<u64, GpuError> {
        let count = bytemuck::pod_collect_to_vec::<u8, u32>(&self.gpu.read(&self.rays, 8)?);
        Ok(u64::from(count[0]) | (u64::from(count[1]) << 32))
    }
}
