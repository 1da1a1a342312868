//! `vtq`: list scenes, render the LumiBench path-tracing workload, trace ray files, benchmark
//! the traversal against `obvhs`, simulate and compare designs on the cycle-exact GPU model,
//! generate Verilog and area reports for the hardware, co-simulate the tables' RTL against
//! the Rust blocks, and fuzz the parsers of user input.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use vtq_sim::cli::cmd::{
    accuracy, area, bench, compare, cosim, designs, energy, figure5, fuzz, render, reproduce,
    scenes, sim, sweep, trace, verilog,
};

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
    /// Path trace a scene (LumiBench workload, or another with --workload) and write a PNG.
    Render(render::RenderArgs),
    /// Trace the rays of a CSV file through a scene and write the closest hits as CSV.
    Trace(trace::TraceArgs),
    /// Time our BVH build and traversal against obvhs on the workload's rays.
    Bench(bench::BenchArgs),
    /// Simulate the workload on the cycle-exact GPU model and write its statistics.
    Sim(sim::SimArgs),
    /// List the designs vtq knows by name (or the given configuration files): what each puts
    /// beside every SM's RT unit and the keys in which it differs from the baseline.
    Designs(designs::DesignsArgs),
    /// Simulate one scene on several designs (baseline, prefetch, vtq, or configuration files)
    /// and print cycles, speedups, miss rates, SIMT efficiency and the phase split side by side.
    Compare(compare::CompareArgs),
    /// The energy model on stored statistics, no rerun: each run under every coefficient set,
    /// relative to the first, and with --vary each coefficient halved and doubled.
    Energy(energy::EnergyArgs),
    /// Run a grid or list of configurations over scenes into a results folder (one file per
    /// run, so a rerun resumes), locally, as one shard or as a Slurm job array; or collect the
    /// results into one CSV table (--collect).
    Sweep(sweep::SweepArgs),
    /// Run time against error: full detail and the sampled tier at several settings on each
    /// scene and design, with a CSV and a plot (docs/accuracy.md).
    Accuracy(accuracy::AccuracyArgs),
    /// The paper's Figure 5 analytical model: potential treelet speedup against concurrent rays,
    /// from the functional node-fetch traces of the workload's rays.
    Figure5(figure5::Figure5Args),
    /// The paper's figures: run its experiment matrix (configs/experiments, shared with
    /// docs/fidelity.md) over the scenes through the result store and write DIR/index.html and
    /// index.md with the figures as SVG and PNG beside the paper's published values.
    Reproduce(reproduce::ReproduceArgs),
    /// Write Verilog for the hardware blocks at the configured sizes (checks only the [hw],
    /// [gpu] and [memory] sections, so table sizes can be set in any mode).
    Verilog(verilog::VerilogArgs),
    /// Storage sizes and area estimates of the treelet-queue tables (paper 6.5; checks only the
    /// [hw], [gpu] and [memory] sections, so table sizes can be set in any mode).
    Area(area::AreaArgs),
    /// Co-simulate the count and queue tables' RTL against the Rust blocks on random stimulus
    /// (checks only the [hw], [gpu] and [memory] sections).
    Cosim(cosim::CosimArgs),
    /// Fuzz the parsers of user input (OBJ, MTL, scene.toml, configuration, --set, rays CSV,
    /// BVH cache files) with mutated and random inputs; report panics, hangs and the slowest case.
    Fuzz(fuzz::FuzzArgs),
}

/// Lets a closed output pipe (`vtq area --json | head`) end the process quietly, as for other
/// command-line tools, instead of making `println!` panic.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called once at start-up before any thread exists; SIG_DFL is a valid disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    restore_default_sigpipe();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Scenes(args) => scenes::run(args),
        Command::Render(args) => render::run(args),
        Command::Trace(args) => trace::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Sim(args) => sim::run(args),
        Command::Designs(args) => designs::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Energy(args) => energy::run(args),
        Command::Sweep(args) => sweep::run(args),
        Command::Accuracy(args) => accuracy::run(args),
        Command::Figure5(args) => figure5::run(args),
        Command::Reproduce(args) => reproduce::run(args),
        Command::Verilog(args) => verilog::run(args),
        Command::Area(args) => area::run(args),
        Command::Cosim(args) => cosim::run(args),
        Command::Fuzz(args) => fuzz::run(args),
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
