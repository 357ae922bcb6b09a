//! Closest-hit queries for a batch of rays on the GPU (`shaders/hits.wgsl`): the traversal
//! alone, without shading, to check it against the CPU's and to time it.

use crate::device::{Binding, Gpu, GpuError};
use crate::scene::{GpuScene, Split, COMMON_WGSL};
use phr_bvh::Ray;

const HITS_WGSL: &str = include_str!("shaders/hits.wgsl");
/// Invocations per workgroup (`@workgroup_size` of the kernel), and workgroups per row of the
/// dispatch grid (`65535u` in the kernel).
const GROUP: u32 = 64;
const ROW: u32 = 65535;

/// A closest hit found on the GPU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    /// The primitive's number in the scene (triangles first, then spheres, then the
    /// triangles of the meshes placed many times, mesh after mesh, each mesh's once).
    pub prim: u32,
}

/// The kernel, made for a scene's layout and [`Split`].
pub struct HitQueries {
    pipeline: wgpu::ComputePipeline,
    split: Split,
    layout: wgpu::BindGroupLayout,
}

impl HitQueries {
    pub fn new(gpu: &Gpu, scene: &GpuScene) -> Self {
        let layout = gpu.layout("hit queries", &[Binding::Read, Binding::ReadWrite]);
        Self { pipeline: Self::kernel(gpu, scene, &layout), split: scene.split, layout }
    }

    fn kernel(gpu: &Gpu, scene: &GpuScene, layout: &wgpu::BindGroupLayout) -> wgpu::ComputePipeline {
        let source = format!("{COMMON_WGSL}\n{HITS_WGSL}");
        gpu.pipeline("hit queries", &source, "closest", &[&scene.layout, layout], &scene.split.constants())
    }

    /// The closest hit of each ray in `[tmin, tmax]` (an infinite `tmax`: without end).
    pub fn closest_hits(&self, gpu: &Gpu, scene: &GpuScene, rays: &[Ray]) -> Result<Vec<Option<GpuHit>>, GpuError> {
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let queries: Vec<[f32; 8]> = rays
            .iter()
            .map(|r| [r.origin.x, r.origin.y, r.origin.z, r.tmin, r.dir.x, r.dir.y, r.dir.z, r.tmax.min(f32::MAX)])
            .collect();
        let none = wgpu::BufferUsages::empty();
        let input = gpu.storage("query rays", bytemuck::cast_slice(&queries), none)?;
        let answers = gpu.storage("query answers", &vec![0u8; rays.len() * 16], wgpu::BufferUsages::COPY_SRC)?;
        let group = gpu.bind("hit queries", &self.layout, &[&input, &answers]);
        // A scene whose arrays moved to other bindings since (an update) needs its own kernel.
        let recompiled;
        let pipeline = if scene.split == self.split {
            &self.pipeline
        } else {
            recompiled = Self::kernel(gpu, scene, &self.layout);
            &recompiled
        };
        let groups = (rays.len() as u32).div_ceil(GROUP);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &scene.group, &[]);
            pass.set_bind_group(1, &group, &[]);
            pass.dispatch_workgroups(groups.min(ROW), groups.div_ceil(ROW), 1);
        }
        gpu.queue.submit([encoder.finish()]);
        let bytes = gpu.read(&answers, rays.len() as u64 * 16)?;
        Ok(bytemuck::pod_collect_to_vec::<u8, [u32; 4]>(&bytes)
            .into_iter()
            .map(|[t, u, v, prim]| {
                let [t, u, v] = [t, u, v].map(f32::from_bits);
                (prim != u32::MAX).then_some(GpuHit { t, u, v, prim })
            })
            .collect())
    }
}
