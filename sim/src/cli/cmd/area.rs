//! `vtq area`: storage sizes and area estimates of the treelet-queue structures (paper 6.5)
//! from the analytical model of docs/area.md, optionally (`--synth`) beside the synthesized logic
//! area of every block with complete RTL (Yosys, priced in NanGate45 NAND2 equivalents).

use anyhow::Context;
use clap::Args;
use serde::Serialize;
use vtq_gen::logic_report::logic_report_with;
use vtq_gen::{area_report, AreaParams, AreaReport, LogicReport};

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
    /// Also synthesize every block with complete RTL (count table, queue table, controller,
    /// the composed block's wiring, the RT unit's control) with Yosys and report per block
    /// cells, flip-flops, NAND2 equivalents, memory macros and area at 45/22 nm, the datapath,
    /// the whole RT unit and the overheads over it and over an SM.
    #[arg(long)]
    pub synth: bool,
    /// With --synth: synthesize in DIR and keep it: the Verilog, Yosys' statistics and a
    /// cache of each block's synthesis, so a later run with the same RTL, script and Yosys
    /// reuses them (default: a scratch directory removed afterwards).
    #[arg(long, value_name = "DIR", requires = "synth")]
    pub work_dir: Option<std::path::PathBuf>,
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

/// Synthesizes every block with complete RTL in `work_dir` (kept), or in a scratch directory.
fn synthesize_blocks(
    cfg: &SimConfig,
    model: &AreaReport,
    work_dir: Option<&std::path::Path>,
) -> anyhow::Result<LogicReport> {
    let dir = work_dir
        .map(std::path::Path::to_path_buf)
        .unwrap_or_else(|| {
            std::env::temp_dir().join(format!("vtq-area-synth-{}", std::process::id()))
        });
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let rt = super::cosim::rt_unit_params(cfg);
    eprintln!(
        "synthesizing 5 blocks with Yosys in {} (at the defaults about 8-12 minutes and 4 GB on 2 cores)",
        dir.display()
    );
    let report = logic_report_with(
        &cfg.hw,
        cfg.hardware_controller_features(),
        &rt,
        model,
        &dir,
        &|top, s| {
            let how = if s.reused { "reused" } else { "synthesized" };
            eprintln!("  {top}: {how} ({:.1} s of Yosys)", s.seconds);
        },
    );
    if work_dir.is_none() {
        // Best effort: the reports are already in memory.
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(report?)
}

/// Run `vtq area`.
pub fn run(args: &AreaArgs) -> anyhow::Result<()> {
    let cfg = args.config.load_hardware()?;
    let model = area_report(&cfg.hw, &area_params(&cfg))?;
    let synthesis = if args.synth {
        Some(
            synthesize_blocks(&cfg, &model, args.work_dir.as_deref())
                .context("yosys synthesis of the blocks' RTL")?,
        )
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
