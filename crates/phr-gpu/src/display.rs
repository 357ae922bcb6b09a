//! The film the GPU keeps, shown where it is: a kernel (`shaders/display.wgsl`) writes the
//! mean of the accumulated sums, sRGB-encoded as the CPU's viewer encodes it, into an 8-bit
//! texture of the device, which a window drawing with the same device shows ([`Shown`]).
//! Nothing is read back for it.

use crate::device::Gpu;
use crate::device::GpuError;
use bytemuck::{Pod, Zeroable};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

const DISPLAY_WGSL: &str = include_str!("shaders/display.wgsl");
/// The kernel's workgroup is 8 × 8 pixels.
const GROUP: u32 = 8;

/// `Display` in `shaders/display.wgsl`.
#[derive(Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct DisplayUniform {
    width: u32,
    height: u32,
    samples: u32,
    unused: u32,
}

/// The image a window shows, as the GPU last wrote it.
#[derive(Clone)]
pub struct ShownImage {
    /// A view of the texture: 8-bit RGBA holding sRGB-encoded values (`Rgba8Unorm`, as egui's
    /// own textures), row 0 at the top.
    pub view: wgpu::TextureView,
    pub width: u32,
    pub height: u32,
    /// Changes when the texture is another one (the image changed size): a window that
    /// registered the view registers the new one.
    pub texture_number: u64,
}

/// The displayed image, shared between the [`crate::GpuFrames`] that write it and the window
/// that draws it; empty until a frame has been kept on the device. It is written only while
/// someone watches it ([`Shown::watch`]).
#[derive(Clone, Default)]
pub struct Shown {
    image: Arc<Mutex<Option<ShownImage>>>,
    watchers: Arc<AtomicUsize>,
}

impl Shown {
    /// Watches the image (a window drawing it): written after every kept frame while any
    /// [`Watching`] lives.
    pub fn watch(&self) -> Watching {
        self.watchers.fetch_add(1, Ordering::Relaxed);
        Watching(self.clone())
    }

    pub(crate) fn set(&self, image: ShownImage) {
        *self.image.lock().unwrap_or_else(|e| e.into_inner()) = Some(image);
    }

    pub(crate) fn watched(&self) -> bool {
        self.watchers.load(Ordering::Relaxed) > 0
    }
}

/// A watcher of a [`Shown`] image.
pub struct Watching(Shown);

impl Watching {
    /// The image as last written, `None` before the first kept frame.
    pub fn get(&self) -> Option<ShownImage> {
        self.0.image.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl Drop for Watching {
    fn drop(&mut self) {
        self.0.watchers.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The display kernel bound to one film's sums and one texture of the film's size.
pub(crate) struct Display {
    pipeline: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    texture_number: u64,
    pub width: u32,
    pub height: u32,
}

impl Display {
    /// The display of the film whose sums are `sum` (`width × height` of `vec4<f32>`), into a
    /// new texture, number `texture_number`.
    pub fn new(gpu: &Gpu, sum: &wgpu::Buffer, width: u32, height: u32, texture_number: u64) -> Self {
        let device = &gpu.device;
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("displayed image"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            // The encoded values, as egui keeps its own images (and storage textures have no
            // sRGB formats).
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("display"),
            size: size_of::<DisplayUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("display"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: compute,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: compute,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: compute,
                    ty: wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: wgpu::TextureFormat::Rgba8Unorm,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    count: None,
                },
            ],
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("display"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: sum.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&view) },
            ],
        });
        let pipeline = gpu.pipeline("display", DISPLAY_WGSL, "show", &[&layout], &[]);
        Self { pipeline, group, uniform, texture, view, texture_number, width, height }
    }

    /// The texture, for [`Shown`].
    pub fn image(&self) -> ShownImage {
        ShownImage {
            view: self.view.clone(),
            width: self.width,
            height: self.height,
            texture_number: self.texture_number,
        }
    }

    /// Writes the mean of `samples` frames' sums into the texture (submitted, not waited for).
    pub fn write(&self, gpu: &Gpu, samples: u32) {
        let uniform = DisplayUniform { width: self.width, height: self.height, samples, unused: 0 };
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            pass.dispatch_workgroups(self.width.div_ceil(GROUP), self.height.div_ceil(GROUP), 1);
        }
        gpu.queue.submit([encoder.finish()]);
    }

    /// The texture's pixels, read back (8-bit RGBA, row-major from the top left): for tests.
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<u8>, GpuError> {
        let row = self.width * 4;
        let padded = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("displayed image"),
            size: u64::from(padded) * u64::from(self.height),
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
        );
        gpu.queue.submit([encoder.finish()]);
        let bytes = gpu.read(&buffer, u64::from(padded) * u64::from(self.height))?;
        Ok(bytes.chunks(padded as usize).flat_map(|r| r[..row as usize].iter().copied()).collect())
    }
}
