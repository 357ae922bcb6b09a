//! `phr`: the command-line front end. Each subcommand wires library pieces together; the
//! work itself lives in `phr-bvh` and `phr-render`.

mod bench_build;
mod info;
mod render;
mod scene_arg;

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
    /// Benchmark BVH construction and ray tracing on the shared scenes.
    BenchBuild(bench_build::BenchBuildArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::FAILURE;
        }
    }
    let result = match cli.command {
        Some(Command::Render(args)) => render::run(&args),
        Some(Command::Info(args)) => info::run(&args),
        Some(Command::BenchBuild(args)) => bench_build::run(&args),
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
