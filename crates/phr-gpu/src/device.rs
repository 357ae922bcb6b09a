//! Finding a GPU (or lavapipe) and the few buffer chores every kernel shares.

use wgpu::util::DeviceExt;

/// Why the GPU tracer cannot run.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found (tried Vulkan, Metal and DX12: {0}). Install your GPU's driver, or \
         Mesa's software Vulkan driver lavapipe (Debian and Ubuntu: `apt-get install \
         mesa-vulkan-drivers libvulkan1`)"
    )]
    NoAdapter(String),
    #[error("the GPU adapter {adapter} refused a device: {reason}")]
    Device { adapter: String, reason: String },
    #[error("the GPU tracer does not handle this scene yet: {0}")]
    Unsupported(String),
    #[error("the scene does not fit the GPU: {0}")]
    TooLarge(String),
    #[error("the GPU failed: {0}")]
    Failed(String),
}

/// Storage buffers the path tracer's kernel binds: the scene's seventeen (its nodes and its
/// primitives over four bindings each, and the parts' instances) and the frame's three.
const STORAGE_BUFFERS: u32 = 20;

/// A device and its queue (a clone is another handle on the same device).
#[derive(Clone)]
pub struct Gpu {
    /// The instance and adapter the device came from (a window drawing with this device
    /// makes its surface from them).
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// The largest storage buffer one binding may see.
    pub max_binding: u64,
    /// The first error the device reported outside any call's result (validation, out of
    /// memory, device lost): [`Gpu::wait`] returns it, instead of wgpu's default of panicking.
    failure: std::sync::Arc<std::sync::Mutex<Option<String>>>,
}

/// The smallest storage buffer made: one element of the largest array element the kernels
/// read, a wide BVH node (`GpuNode`).
const MIN_STORAGE: usize = 256;

impl Gpu {
    /// The most capable adapter there is (a discrete GPU over an integrated one over a software
    /// one); `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` choose another, as in every wgpu program.
    pub fn new() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        };
        let adapter = match std::env::var("WGPU_ADAPTER_NAME") {
            Ok(name) => {
                let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
                let wanted = name.to_lowercase();
                adapters.into_iter().find(|a| a.get_info().name.to_lowercase().contains(&wanted)).ok_or_else(|| {
                    GpuError::NoAdapter(format!("no adapter's name contains WGPU_ADAPTER_NAME={name}"))
                })?
            }
            Err(_) => pollster::block_on(instance.request_adapter(&options))
                .map_err(|e| GpuError::NoAdapter(e.to_string()))?,
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
            return Err(GpuError::Device {
                adapter: info.name,
                reason: format!(
                    "the path tracer binds {STORAGE_BUFFERS} storage buffers, the adapter allows {}",
                    limits.max_storage_buffers_per_shader_stage
                ),
            });
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("phr"),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device { adapter: info.name.clone(), reason: e.to_string() })?;
        let max_binding = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let failure = std::sync::Arc::new(std::sync::Mutex::new(None));
        let record = |failure: &std::sync::Arc<std::sync::Mutex<Option<String>>>| {
            let failure = failure.clone();
            move |what: String| {
                let mut first = failure.lock().unwrap_or_else(|e| e.into_inner());
                first.get_or_insert(what);
            }
        };
        let on_error = record(&failure);
        device.on_uncaptured_error(std::sync::Arc::new(move |e: wgpu::Error| on_error(e.to_string())));
        let on_lost = record(&failure);
        device.set_device_lost_callback(move |reason, message| on_lost(format!("device lost ({reason:?}): {message}")));
        Ok(Self { instance, adapter, device, queue, info, max_binding, failure })
    }

    /// "NAME (BACKEND, TYPE)", for reports.
    pub fn describe(&self) -> String {
        format!("{} ({:?}, {:?})", self.info.name, self.info.backend, self.info.device_type)
    }

    /// Whether the adapter is a software rasteriser (lavapipe, WARP, SwiftShader): its timings
    /// are the CPU's, not a GPU's.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// A storage buffer holding `data` (zeros after it up to [`MIN_STORAGE`] bytes: a binding
    /// must hold one element of its array at least), refused if one binding cannot see it all.
    pub(crate) fn storage(
        &self,
        label: &str,
        data: &[u8],
        usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        if data.len() as u64 > self.max_binding {
            return Err(GpuError::TooLarge(format!(
                "{label} takes {} MiB, more than the {} MiB one storage binding of {} may hold",
                data.len() >> 20,
                self.max_binding >> 20,
                self.info.name
            )));
        }
        let mut padded;
        let contents = if data.len() < MIN_STORAGE {
            padded = data.to_vec();
            padded.resize(MIN_STORAGE, 0);
            &padded[..]
        } else {
            data
        };
        Ok(self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage: wgpu::BufferUsages::STORAGE | usage,
        }))
    }

    /// Copies `bytes` bytes of `buffer` back to the CPU, waiting for the queue.
    pub(crate) fn read(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>, GpuError> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let (sender, receiver) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |result| {
            let _ = sender.send(result);
        });
        self.wait()?;
        receiver
            .recv()
            .map_err(|e| GpuError::Failed(e.to_string()))?
            .map_err(|e| GpuError::Failed(format!("reading a buffer back: {e}")))?;
        let data = staging.get_mapped_range(..).map_err(|e| GpuError::Failed(e.to_string()))?.to_vec();
        staging.unmap();
        Ok(data)
    }

    /// Waits until the GPU has done everything submitted; fails if the device reported an
    /// error since it was made.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| GpuError::Failed(e.to_string()))?;
        match self.failure.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
            Some(what) => Err(GpuError::Failed(what.clone())),
            None => Ok(()),
        }
    }

    /// Elements of type `T` one storage binding holds: how the nodes and the primitives are
    /// cut across bindings (the kernels' `nodes_per_binding` and `prims_per_binding`).
    pub(crate) fn per_binding<T>(&self) -> usize {
        (self.max_binding / std::mem::size_of::<T>() as u64).min(u64::from(u32::MAX)) as usize
    }

    /// A compute pipeline running `entry` of the WGSL `source` with these bind group layouts
    /// and values of its pipeline constants (a scene's `Split`).
    pub(crate) fn pipeline(
        &self,
        label: &str,
        source: &str,
        entry: &str,
        layouts: &[&wgpu::BindGroupLayout],
        constants: &[(&str, f64)],
    ) -> wgpu::ComputePipeline {
        let module = self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let layouts: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(|&l| Some(l)).collect();
        let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &layouts,
            immediate_size: 0,
        });
        self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
            cache: None,
        })
    }

    /// A bind group layout of buffers seen by compute kernels, binding `i` of kind `kinds[i]`.
    pub(crate) fn layout(&self, label: &str, kinds: &[Binding]) -> wgpu::BindGroupLayout {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = kinds
            .iter()
            .enumerate()
            .map(|(i, kind)| wgpu::BindGroupLayoutEntry {
                binding: i as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: match kind {
                        Binding::Uniform => wgpu::BufferBindingType::Uniform,
                        Binding::Read => wgpu::BufferBindingType::Storage { read_only: true },
                        Binding::ReadWrite => wgpu::BufferBindingType::Storage { read_only: false },
                    },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            })
            .collect();
        self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
    }

    /// A bind group of `layout` binding `buffers` in order.
    pub(crate) fn bind(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
    }
}

/// How a kernel sees a buffer.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Binding {
    Uniform,
    Read,
    ReadWrite,
}
