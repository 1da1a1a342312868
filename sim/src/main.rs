//! `vtq`: list scenes, render the LumiBench path-tracing workload, trace ray files, benchmark
//! the traversal against `obvhs`, and generate Verilog and area reports for the hardware.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use vtq_sim::cmd::{area, bench, render, scenes, sim, trace, verilog};

/// Virtualized Treelet Queues: scenes, the path-traced workload and the functional ray tracer.
#[derive(Debug, Parser)]
#[command(name = "vtq", version, about, long_about = None)]
struct Cli {
    /// What to do.
    #[command(subcommand)]
    command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
enum Command {
    /// List the built-in scenes and the scene folders of ../shared/scenes with their sizes.
    Scenes(scenes::ScenesArgs),
    /// Path trace a scene (LumiBench workload) and write a PNG.
    Render(render::RenderArgs),
    /// Trace the rays of a CSV file through a scene and write the closest hits as CSV.
    Trace(trace::TraceArgs),
    /// Time our BVH build and traversal against obvhs on the workload's rays.
    Bench(bench::BenchArgs),
    /// Simulate the workload on the cycle-exact GPU model and write its statistics.
    Sim(sim::SimArgs),
    /// Write Verilog for the hardware blocks at the configured sizes.
    Verilog(verilog::VerilogArgs),
    /// Storage sizes and area estimates of the treelet-queue tables (paper 6.5).
    Area(area::AreaArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Scenes(args) => scenes::run(args),
        Command::Render(args) => render::run(args),
        Command::Trace(args) => trace::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Sim(args) => sim::run(args),
        Command::Verilog(args) => verilog::run(args),
        Command::Area(args) => area::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // `{:#}` joins the context chain with ": "; causes that span several lines (e.g.
            // parser messages with a source excerpt) are folded onto the one line.
            let message = format!("{e:#}");
            let one_line: Vec<&str> = message
                .lines()
                .map(str::trim)
                .filter(|l| !l.is_empty())
                .collect();
            eprintln!("error: {}", one_line.join(" "));
            ExitCode::FAILURE
        }
    }
}
