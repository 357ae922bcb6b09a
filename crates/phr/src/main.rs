//! `phr`: the command-line front end. Each subcommand wires library pieces together; the
//! work itself lives in `phr-bvh` and `phr-render`.

mod animate;
mod bench;
mod bench_build;
mod bench_cut_cost;
mod bench_device;
mod bench_frame;
mod bench_quality;
mod bench_rays;
mod bench_tune;
mod export_reference;
mod info;
mod progress;
mod render;
mod render_gpu;
mod scene_arg;
mod tune;
mod view;

use clap::{Parser, Subcommand};

use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "phr", version, about = "Progressive BVH refinement path tracer")]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Path trace a scene to an image.
    Render(render::RenderArgs),
    /// Print scene and BVH statistics.
    Info(info::InfoArgs),
    /// The thesis's evaluation on the scene suite: tables, CSV, JSON and plots in one folder.
    Bench(bench::BenchArgs),
    /// Benchmark BVH construction and ray tracing on the shared scenes.
    BenchBuild(bench_build::BenchBuildArgs),
    /// The thesis's frame on the suite, ours against Mitsuba 3 (llvm variant) in one run.
    BenchFrame(bench_frame::BenchFrameArgs),
    /// The thesis's frame on the CPU and on the GPU (build, upload, frame per device), in one run.
    BenchDevice(bench_device::BenchDeviceArgs),
    /// Image quality at equal time: RMSE of our estimators and Mitsuba 3's path tracer
    /// against converged references.
    BenchQuality(bench_quality::BenchQualityArgs),
    /// Write a scene in the reference renderer's format (JSON and PLY), for Mitsuba 3.
    ExportReference(export_reference::ExportReferenceArgs),
    /// Ray throughput: binary vs wide (SIMD) BVH traversal vs Embree, on the shared scenes.
    BenchRays(bench_rays::BenchRaysArgs),
    /// Correlation of PHR's build cost Σ|cut| with its build time over a sweep of α and δ.
    BenchCutCost(bench_cut_cost::BenchCutCostArgs),
    /// Choose PHR's α and δ for a scene, view and image size (grid or Bayesian optimisation).
    Tune(tune::TuneArgs),
    /// Bayesian optimisation against a dense grid, and frame times of the tuned builds.
    BenchTune(bench_tune::BenchTuneArgs),
    /// Animate a scene: move vertices, refit the LBVH, rebuild with PHR, render, every frame.
    Animate(animate::AnimateArgs),
    /// Interactive viewer: path tracing while you move, dynamic scenes, live statistics
    /// (`--headless` for the same frame loop without a window).
    View(view::ViewArgs),
}

/// Output into a closed pipe (`phr render … | head -1`) ends the process quietly, as it does
/// for other command-line tools, instead of panicking in `println!`: Rust ignores SIGPIPE,
/// this restores the default action, and unblocks the signal in case the parent blocked it
/// (a blocked SIGPIPE would leave the write failing with EPIPE all the same).
fn default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread starts; the signal set is
    // initialised by sigemptyset before use, and setting SIGPIPE's disposition to its
    // default and unblocking it have no other precondition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        libc::sigaddset(&mut set, libc::SIGPIPE);
        libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
    }
}

fn main() -> ExitCode {
    default_sigpipe();
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::FAILURE;
        }
    }
    let result = match cli.command {
        Some(Command::Render(args)) if args.device == render::Device::Gpu => render_gpu::run(&args),
        Some(Command::Render(args)) => render::run(&args),
        Some(Command::Info(args)) => info::run(&args),
        Some(Command::ExportReference(args)) => export_reference::run(&args),
        Some(Command::Bench(args)) => bench::run(&args),
        Some(Command::BenchBuild(args)) => bench_build::run(&args),
        Some(Command::BenchFrame(args)) => bench_frame::run(&args),
        Some(Command::BenchDevice(args)) => bench_device::run(&args),
        Some(Command::BenchQuality(args)) => bench_quality::run(&args),
        Some(Command::BenchRays(args)) => bench_rays::run(&args),
        Some(Command::BenchCutCost(args)) => bench_cut_cost::run(&args),
        Some(Command::Animate(args)) => animate::run(&args),
        Some(Command::View(args)) => view::run(&args),
        Some(Command::Tune(args)) => tune::run(&args),
        Some(Command::BenchTune(args)) => bench_tune::run(&args),
        None => {
            println!("No command given: rendering the built-in scene (run `phr --help` for more).");
            render::run(&render::RenderArgs::default())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
