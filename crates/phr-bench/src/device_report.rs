//! The CPU-versus-GPU benchmark's results (`phr bench-device`): per scene and resolution, the
//! build (on the CPU, for both), the upload to the GPU, and the thesis's frame on each device,
//! as CSV, JSON and a Markdown table. The GPU's measuring lives with the command, behind its
//! cargo feature; these rows know only the numbers.

use crate::frame::FrameTiming;
use crate::frame_report::write_report_files;
use anyhow::Result;
use std::fmt::Write as _;
use std::path::Path;

/// The GPU's side of a row, or why it did not run.
#[derive(Clone, Debug, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GpuRun {
    Ran {
        /// Laying out and uploading nodes, primitives and materials, waiting for the GPU (ms).
        upload_ms: f64,
        /// Bytes uploaded.
        bytes: u64,
        frame: FrameTiming,
    },
    Skipped(String),
}

/// One scene at one resolution on both devices.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceRow {
    pub scene: String,
    pub triangles: usize,
    pub res: u32,
    pub builder: String,
    /// The build on the CPU (both devices trace its tree; the CPU's collapse to its wide tree
    /// included).
    pub build_ms: f64,
    pub cpu: FrameTiming,
    pub gpu: GpuRun,
}

impl DeviceRow {
    /// The CPU's median frame time over the GPU's: above 1 the GPU is faster.
    pub fn gpu_speedup(&self) -> Option<f64> {
        match &self.gpu {
            GpuRun::Ran { frame, .. } => Some(self.cpu.ms.median / frame.ms.median),
            GpuRun::Skipped(_) => None,
        }
    }
}

/// What the run was: its command, the CPU's threads and the GPU adapter (or why none).
pub struct DeviceRunInfo<'a> {
    pub command: &'a str,
    pub threads: usize,
    pub adapter: &'a str,
    /// The adapter is a software rasteriser on the same CPU (lavapipe).
    pub software: bool,
}

/// Writes `device.csv`, `device.json` and `device.md` to `dir`.
pub fn write_device_report(dir: &Path, info: &DeviceRunInfo, rows: &[DeviceRow]) -> Result<()> {
    write_report_files(
        dir,
        &[
            ("device.csv", csv(rows)),
            ("device.json", serde_json::to_string_pretty(rows)?),
            ("device.md", markdown(info, rows)),
        ],
    )
}

fn csv(rows: &[DeviceRow]) -> String {
    let mut s = String::from(
        "scene,triangles,res,builder,build_ms,cpu_ms_median,cpu_ms_min,cpu_rays_per_frame,cpu_mrays_per_s,upload_ms,upload_mib,gpu_ms_median,gpu_ms_min,gpu_rays_per_frame,gpu_mrays_per_s,cpu_over_gpu\n",
    );
    for r in rows {
        let mut cells = vec![r.scene.clone(), r.triangles.to_string(), r.res.to_string(), r.builder.clone()];
        cells.push(format!("{:.3}", r.build_ms));
        cells.extend([r.cpu.ms.median, r.cpu.ms.min, r.cpu.rays, r.cpu.mrays_per_s()].map(|x| format!("{x:.3}")));
        match &r.gpu {
            GpuRun::Ran { upload_ms, bytes, frame } => cells.extend(
                [
                    *upload_ms,
                    *bytes as f64 / (1 << 20) as f64,
                    frame.ms.median,
                    frame.ms.min,
                    frame.rays,
                    frame.mrays_per_s(),
                ]
                .map(|x| format!("{x:.3}")),
            ),
            GpuRun::Skipped(_) => cells.extend(std::iter::repeat_n(String::new(), 6)),
        }
        cells.push(r.gpu_speedup().map(|x| format!("{x:.3}")).unwrap_or_default());
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

/// The Markdown report: the table, then why the GPU was skipped, if it was.
pub fn markdown(info: &DeviceRunInfo, rows: &[DeviceRow]) -> String {
    let mut s = String::from("# The thesis's frame on the CPU and on the GPU\n\n");
    let _ = writeln!(
        s,
        "Command: `{}` (release build). CPU: {} thread(s). GPU: {}.\n",
        info.command, info.threads, info.adapter
    );
    if info.software {
        s.push_str(
            "**The GPU column ran on a software Vulkan driver (Mesa's lavapipe) on the same CPU cores**: it \
             measures the kernels' code compiled for the CPU, not a GPU. Run the same command on a machine \
             with a GPU for the comparison the thesis asked for.\n\n",
        );
    }
    s.push_str(
        "One frame: first view, 1 sample per pixel, at most 6 segments, white sky, every surface diffuse 0.7 \
         (the thesis's setting), the same estimator and the same random numbers on both devices. Build: the \
         tree both devices trace, built once on the CPU. Upload: laying out and uploading the tree, \
         primitives and materials. Frame: median [min] wall-clock ms after warm-up frames; on the GPU each \
         frame is submitted and waited for, as an interactive loop must. CPU/GPU: median over median, above \
         1 the GPU is faster.\n\n",
    );
    s.push_str(
        "| scene | triangles | res | build ms | CPU ms | CPU Mrays/s | upload ms | GPU ms | GPU Mrays/s | CPU/GPU |\n",
    );
    s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let (upload, gpu_ms, gpu_rays) = match &r.gpu {
            GpuRun::Ran { upload_ms, frame, .. } => (
                format!("{upload_ms:.1}"),
                format!("{:.1} [{:.1}]", frame.ms.median, frame.ms.min),
                format!("{:.2}", frame.mrays_per_s()),
            ),
            GpuRun::Skipped(_) => ("–".into(), "skipped".into(), "–".into()),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {}² | {:.1} | {:.1} [{:.1}] | {:.2} | {upload} | {gpu_ms} | {gpu_rays} | {} |",
            r.scene,
            r.triangles,
            r.res,
            r.build_ms,
            r.cpu.ms.median,
            r.cpu.ms.min,
            r.cpu.mrays_per_s(),
            r.gpu_speedup().map(|x| format!("{x:.2}")).unwrap_or_else(|| "–".into())
        );
    }
    if let Some(why) = rows.iter().find_map(|r| match &r.gpu {
        GpuRun::Skipped(why) => Some(why),
        GpuRun::Ran { .. } => None,
    }) {
        let _ = writeln!(s, "\nThe GPU was skipped: {why}");
    }
    s
}
