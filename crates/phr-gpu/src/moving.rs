//! A moving scene on the GPU, uploaded part by part: what [`crate::GpuFrames`] writes when
//! the pipeline's scene changed. A rigid motion changes only the instances (of parts and of
//! copies of meshes placed many times), the top-level tree over them and the emitters
//! (sampled in the world), so only those are written; a deforming part whose tree
//! was refitted or rebuilt is written into its own slot ([`TreeSlot`]), the other parts'
//! trees and records stay as they are. The whole scene is laid out again only when there are
//! other parts (another number of them, instances or not, other copied meshes), the emitters
//! are other primitives, or a part outgrew its slot, and then with room to grow for every
//! part seen changing.

use crate::device::{Gpu, GpuError};
use crate::scene::{is_instanced, top_records, Emitters, GpuScene, Packed, TreeSlot};
use phr_render::frame_tracer::FrameJob;

/// What is on the GPU of a pipeline's moving scene.
pub(crate) struct Uploaded {
    /// Each part's [`phr_render::geometry::Geometry::part_generation`] as uploaded, and where
    /// its tree lies.
    parts: Vec<(u64, TreeSlot)>,
    /// Whether the parts are traced through their instances.
    instanced: bool,
    /// [`Packed::emitter_of`] of the records uploaded.
    emitter_of: Vec<u32>,
    /// [`Packed::mesh_roots`] and [`Packed::top`] as uploaded.
    mesh_roots: Vec<u32>,
    top: Option<TreeSlot>,
    /// The parts seen changing since the first upload: laid out with room to grow.
    changing: Vec<bool>,
}

impl Uploaded {
    /// What `packed` (laid out for `job`'s geometry) put on the GPU.
    pub(crate) fn new(job: &FrameJob, packed: &Packed, changing: Vec<bool>) -> Self {
        let g = job.geometry;
        Self {
            parts: (0..g.part_count()).map(|k| (g.part_generation(k), packed.slots[k])).collect(),
            instanced: is_instanced(g),
            emitter_of: packed.emitter_of.clone(),
            mesh_roots: packed.mesh_roots.clone(),
            top: packed.top,
            changing,
        }
    }

    /// Brings `scene` (uploaded for an earlier version of `job`'s scene, with the same light
    /// sampling) to `job`'s: in place where the parts are the same ones and fit their slots,
    /// else by laying out the moving geometry again ([`GpuScene::bytes`] says how much was
    /// written). Does not wait for the GPU.
    pub(crate) fn update(&mut self, gpu: &Gpu, scene: &mut GpuScene, job: &FrameJob) -> Result<(), GpuError> {
        let g = job.geometry;
        let same_parts = g.part_count() == self.parts.len()
            && is_instanced(g) == self.instanced
            && g.copied_mesh_count() == self.mesh_roots.len();
        if same_parts {
            for (k, changing) in self.changing.iter_mut().enumerate() {
                *changing |= g.part_generation(k) != self.parts[k].0;
            }
            if self.write_in_place(gpu, scene, job)? {
                return Ok(());
            }
        } else {
            // Other parts: none is known to change.
            self.changing = vec![false; g.part_count()];
        }
        let packed = Packed::moved_parts(job.scene, g, job.lights, |k| self.changing[k])?;
        scene.update(gpu, &packed)?;
        let changing = std::mem::take(&mut self.changing);
        *self = Self::new(job, &packed, changing);
        Ok(())
    }

    /// Writes the changed parts' trees into their slots, the instances and the emitters;
    /// false (nothing written) where that cannot be done: a part outgrew its slot, or the
    /// emitters are other primitives than the records say.
    fn write_in_place(&mut self, gpu: &Gpu, scene: &mut GpuScene, job: &FrameJob) -> Result<bool, GpuError> {
        let g = job.geometry;
        let emitters = Emitters::new(g, job.lights);
        if emitters.of_prim != self.emitter_of {
            return Ok(false);
        }
        let mut trees = Vec::new();
        for (k, &(generation, slot)) in self.parts.iter().enumerate() {
            if g.part_generation(k) == generation {
                continue;
            }
            match Packed::part_records(job.scene, g, k, slot, &self.emitter_of)? {
                Some(records) => trees.push((k, records)),
                None => return Ok(false),
            }
        }
        let slots: Vec<TreeSlot> = self.parts.iter().map(|&(_, slot)| slot).collect();
        let instances = Packed::instance_records(g, &slots, &self.mesh_roots)?;
        // The top level over the instances where they are now, in its slot.
        let mut top = None;
        if let Some(slot) = self.top {
            let nodes = top_records(&instances, slot.first_node)?;
            if nodes.len() > slot.node_room as usize {
                return Ok(false);
            }
            top = Some((slot, Packed { nodes, ..Packed::default() }));
        }
        let Some(mut bytes) = scene.write_placement(gpu, &instances, &emitters) else {
            return Ok(false);
        };
        if let Some((slot, nodes)) = top {
            bytes += scene.write_part(gpu, slot, &nodes);
        }
        for (k, part) in trees {
            bytes += scene.write_part(gpu, slots[k], &part);
            self.parts[k].0 = g.part_generation(k);
        }
        scene.bytes = bytes;
        Ok(true)
    }
}
