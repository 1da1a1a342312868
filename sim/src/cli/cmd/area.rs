//! `vtq area`: storage sizes and area estimates of the treelet-queue structures (paper 6.5)
//! from the analytical model of docs/area.md, optionally (`--synth`) beside the synthesized logic
//! area of every block with complete RTL (Yosys, priced in NanGate45 NAND2 equivalents).

use anyhow::Context;
use clap::Args;
use serde::Serialize;
use vtq_gen::{area_report, logic_report, AreaParams, AreaReport, LogicReport};

use super::options::ConfigArgs;
use crate::experiment::reproduce::figures::Table;
use crate::model::config::SimConfig;

/// Options of `vtq area`.
#[derive(Debug, Args)]
pub struct AreaArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also synthesize every block with complete RTL (count table, queue table, controller)
    /// with Yosys and report cells, flip-flops, NAND2 equivalents and logic area at 45/22 nm.
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
    synthesis: Option<LogicReport>,
}

/// Synthesizes every block with complete RTL in a scratch directory.
fn synthesize_blocks(cfg: &SimConfig, model: &AreaReport) -> anyhow::Result<LogicReport> {
    let dir = std::env::temp_dir().join(format!("vtq-area-synth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let rt = super::cosim::rt_unit_params(cfg);
    let report = logic_report(
        &cfg.hw,
        cfg.hardware_controller_features(),
        &rt,
        model,
        &dir,
    );
    // Best effort: the reports are already in memory.
    let _ = std::fs::remove_dir_all(&dir);
    Ok(report?)
}

/// Run `vtq area`.
pub fn run(args: &AreaArgs) -> anyhow::Result<()> {
    let cfg = args.config.load_hardware()?;
    let model = area_report(&cfg.hw, &area_params(&cfg))?;
    let synthesis = if args.synth {
        Some(synthesize_blocks(&cfg, &model).context("yosys synthesis of the blocks' RTL")?)
    } else {
        None
    };
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&AreaJson { model, synthesis })?
        );
        return Ok(());
    }
    print!("{model}");
    if let Some(s) = &synthesis {
        println!();
        print!("{s}");
    }
    Ok(())
}

/// Section 6.5: the area report's structures as a table of `vtq reproduce`'s page.
pub fn area_table(report: &AreaReport) -> Table {
    let mut header = vec![
        "structure".to_string(),
        "where".into(),
        "entries".into(),
        "bits / entry".into(),
        "size".into(),
        "paper".into(),
    ];
    if let Some(s) = report.structures.first() {
        for a in &s.area {
            header.push(format!("SRAM {} nm (mm²)", a.feature_nm));
        }
    }
    Table {
        header,
        rows: report
            .structures
            .iter()
            .map(|s| {
                let mut row = vec![
                    s.name.clone(),
                    s.location.clone(),
                    s.entries.to_string(),
                    s.entry_bits.to_string(),
                    s.size.clone(),
                    s.paper.clone().unwrap_or_else(|| "-".into()),
                ];
                row.extend(s.area.iter().map(|a| format!("{:.4}", a.sram_mm2)));
                row
            })
            .collect(),
    }
}
