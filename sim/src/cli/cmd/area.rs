//! `vtq area`: storage sizes and area estimates of the treelet-queue structures (paper 6.5)
//! from the analytical model of docs/area.md, optionally beside Yosys synthesis of the tables.

use anyhow::Context;
use clap::Args;
use serde::Serialize;
use vtq_gen::{area_report, AreaParams, AreaReport, SynthReport};

use super::options::ConfigArgs;
use crate::model::config::SimConfig;

/// Options of `vtq area`.
#[derive(Debug, Args)]
pub struct AreaArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also synthesize the generated RTL of the two tables with Yosys (generic `synth`) and
    /// report cell and flip-flop counts.
    #[arg(long)]
    pub synth: bool,
}

/// The area-model parameters the simulator configuration determines (CTA shape, saved state).
pub fn area_params(cfg: &SimConfig) -> AreaParams {
    AreaParams {
        threads_per_cta: cfg.gpu.threads_per_cta,
        regs_per_thread: cfg.gpu.raygen_regs_per_thread,
        simt_stack_depth: cfg.gpu.simt_stack_entries,
        ..AreaParams::default()
    }
}

/// The JSON document of `vtq area --json`.
#[derive(Debug, Serialize)]
struct AreaJson {
    model: AreaReport,
    synthesis: Vec<SynthReport>,
}

/// Synthesizes the two tables' RTL in a scratch directory.
fn synthesize_tables(cfg: &SimConfig) -> anyhow::Result<Vec<SynthReport>> {
    let dir = std::env::temp_dir().join(format!("vtq-area-synth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut reports = Vec::new();
    for (name, text) in vtq_gen::rtl::table_modules(&cfg.hw)? {
        let path = dir.join(format!("{name}.v"));
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        reports.push(vtq_gen::synthesize(&[path], &name, &dir)?);
    }
    // Best effort: the reports are already in memory.
    let _ = std::fs::remove_dir_all(&dir);
    Ok(reports)
}

/// Run `vtq area`.
pub fn run(args: &AreaArgs) -> anyhow::Result<()> {
    let cfg = args.config.load_hardware()?;
    let model = area_report(&cfg.hw, &area_params(&cfg))?;
    let synthesis = if args.synth {
        synthesize_tables(&cfg).context("yosys synthesis of the table RTL")?
    } else {
        Vec::new()
    };
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&AreaJson { model, synthesis })?
        );
        return Ok(());
    }
    print!("{model}");
    for s in &synthesis {
        println!(
            "yosys {}: {} cells, {} flip-flops, {} latches, {} memory bits{}",
            s.top,
            s.cells,
            s.flip_flops,
            s.latches,
            s.memory_bits,
            if s.is_clean() { "" } else { " (warnings)" }
        );
    }
    Ok(())
}
