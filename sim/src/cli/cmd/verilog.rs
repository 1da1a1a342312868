//! `vtq verilog`: Verilog-2005 for every hardware block at the configured sizes — complete RTL
//! for the treelet count table, the treelet queue table, the treelet controller (with the
//! configuration's design features when it is a queues design, the full design otherwise) and
//! the RT unit's control (with `rt_datapath`, the toy node format's datapath standing in for the
//! box/triangle datapath), and the composed treelet RT unit: a top module instantiating the four
//! with its wiring module.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use vtq_gen::compose::composite_modules;
use vtq_gen::rtl::{rt_unit_verilog, toy_datapath_verilog};
use vtq_hdl::rt_unit::NoDatapath;
use vtq_hdl::treelet_rt_unit::{TreeletRtUnit, TreeletRtUnitParams};
use vtq_hdl::Block;

use super::options::ConfigArgs;
use crate::model::config::SimConfig;

/// Options of `vtq verilog`.
#[derive(Debug, Args)]
pub struct VerilogArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Directory to write one `<module>.v` per block into (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// Every block's module as (module name, Verilog text): the tables, the controller and the RT
/// unit (full RTL) with the RT unit's stand-in datapath, then the composed treelet RT unit's top
/// and wiring modules.
pub fn modules(cfg: &SimConfig) -> anyhow::Result<Vec<(String, String)>> {
    let features = cfg.hardware_controller_features();
    let mut out = vtq_gen::rtl::rtl_modules(&cfg.hw, features)?;
    let rt_params = super::cosim::rt_unit_params(cfg);
    let params = TreeletRtUnitParams {
        rt: rt_params.clone(),
        features,
        ray_base: 0,
    };
    let unit = TreeletRtUnit::new(cfg.hw.clone(), params, NoDatapath)?;
    let children = vtq_gen::rtl::instances(&unit);
    out.push((
        children[0].desc.name.clone(),
        rt_unit_verilog(&cfg.hw, &rt_params)?,
    ));
    out.push((
        "rt_datapath".to_string(),
        toy_datapath_verilog(cfg.hw.address_bits),
    ));
    let wiring = vtq_gen::rtl::treelet_wiring_verilog(&unit)?;
    out.extend(composite_modules(&unit.describe(), &children, wiring)?);
    Ok(out)
}

/// Run `vtq verilog`.
pub fn run(args: &VerilogArgs) -> anyhow::Result<()> {
    let cfg = args.config.load_hardware()?;
    crate::cli::output::check_dir(&args.out)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for (name, text) in modules(&cfg)? {
        let path = args.out.join(format!("{name}.v"));
        std::fs::write(&path, &text).with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {} ({} lines)", path.display(), text.lines().count());
    }
    Ok(())
}
