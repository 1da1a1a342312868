//! The skeleton generator on the real hardware blocks of `vtq-hdl`: every block's description
//! is valid and its skeleton lints clean and synthesizes without latches, at the paper's
//! configuration and a scaled one.

mod common;

use common::{lints_clean, synthesizes_without_latches};
use std::path::PathBuf;
use vtq_gen::compose::composite_modules;
use vtq_gen::rtl::{
    instances, rt_unit_verilog, rtl_modules, toy_datapath_verilog, treelet_wiring_verilog,
};
use vtq_gen::verilog::MAX_WIDTH;
use vtq_gen::{emit_module, write_module};
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::rt_unit::{NoDatapath as NoHits, NodeEntry, RtUnit, RtUnitParams};
use vtq_hdl::treelet_rt_unit::{TreeletRtUnit, TreeletRtUnitParams};
use vtq_hdl::{Block, BlockDesc, HwConfig};

fn descs(cfg: &HwConfig) -> Vec<BlockDesc> {
    vec![
        CountTable::new(cfg).unwrap().describe(),
        QueueTable::new(cfg).unwrap().describe(),
        TreeletController::new(cfg.clone(), ControllerFeatures::default())
            .unwrap()
            .describe(),
    ]
}

fn scaled() -> HwConfig {
    HwConfig {
        max_rays: 8192,
        treelet_bytes: 32768,
        queue_table_entries: 256,
        ..HwConfig::default()
    }
}

#[test]
fn every_block_description_emits() {
    for cfg in [HwConfig::default(), scaled()] {
        for d in descs(&cfg) {
            let text = emit_module(&d).unwrap_or_else(|e| panic!("{e}"));
            assert!(text.contains(&format!("module {} (", d.name)));
            for p in &d.ports {
                assert!(text.contains(&p.name), "{}: port {}", d.name, p.name);
            }
        }
    }
}

#[test]
fn every_block_skeleton_lints_and_synthesizes() {
    for (tag, cfg) in [("paper", HwConfig::default()), ("scaled", scaled())] {
        for d in descs(&cfg) {
            let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
                .join(format!("vtq-gen-hdl-{tag}-{}", d.name));
            let file = write_module(&dir, &d).unwrap();
            let files = [file];
            let what = format!("{} ({tag})", d.name);
            if !lints_clean(&files, &d.name, &dir, &what)
                || synthesizes_without_latches(&files, &d.name, &dir, &what).is_none()
            {
                return;
            }
        }
    }
}

fn rt_unit_desc(cfg: HwConfig) -> BlockDesc {
    RtUnit::new(cfg, RtUnitParams::default(), NoHits)
        .unwrap()
        .describe()
}

/// The RT unit's per-warp stack ports are warp_size lanes x record_stack_entries entries x
/// 37-bit entries. With records carrying whole 128-entry on-chip stacks (the default is 4
/// entries of 32) that is 32 x 128 x 37 = 151,552 bits, wider than the 65,536 bits IEEE
/// 1364-2005 guarantees
/// but within `MAX_WIDTH`: its skeleton emits with every port at full width, lints clean with
/// `verilator -Wall` and synthesizes with Yosys without latches or warnings.
#[test]
fn rt_unit_skeleton_lints_and_synthesizes_at_the_paper_config() {
    let cfg = HwConfig {
        stack_depth: 128,
        record_stack_entries: 128,
        ..HwConfig::default()
    };
    let d = rt_unit_desc(cfg.clone());
    assert_eq!(d.name, "rt_unit");
    let stack = d
        .ports
        .iter()
        .find(|p| p.name.ends_with("_stack"))
        .expect("the RT unit has stack ports");
    let entry = NodeEntry::bits(cfg.address_bits);
    assert_eq!(entry, 37, "address, kind and chunk count of a stack entry");
    let width = cfg.warp_size * cfg.record_stack_entries * entry;
    assert_eq!(stack.width, width, "{}", stack.name);
    assert!(stack.width > 1 << 16 && stack.width <= MAX_WIDTH);
    let text = emit_module(&d).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        text.contains(&format!("[{}:0]", width - 1)),
        "the stack ports keep their width"
    );
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-gen-hdl-paper-rt_unit");
    let files = [write_module(&dir, &d).unwrap()];
    if lints_clean(&files, &d.name, &dir, &d.name) {
        synthesizes_without_latches(&files, &d.name, &dir, &d.name);
    }
}

/// The composed treelet RT unit's top module instantiates the tables', the controller's and the
/// RT unit's complete RTL (the RT unit with the toy datapath) and its wiring module's,
/// connected port by port; all of it lints clean under `verilator --lint-only -Wall`.
#[test]
fn the_composed_treelet_rt_unit_lints_clean() {
    let cfg = HwConfig::default();
    let params = TreeletRtUnitParams {
        rt: RtUnitParams::default(),
        features: ControllerFeatures::FULL,
        ray_base: 0,
    };
    let unit = TreeletRtUnit::new(cfg.clone(), params, NoHits).unwrap();
    let children = instances(&unit);
    let mut modules = rtl_modules(&cfg, ControllerFeatures::FULL).unwrap();
    for c in children.iter().filter(|c| c.name == "rt") {
        let rtl = rt_unit_verilog(&cfg, &RtUnitParams::default()).unwrap();
        modules.push((c.desc.name.clone(), rtl));
        modules.push(("rt_datapath".into(), toy_datapath_verilog(cfg.address_bits)));
    }
    let wiring = treelet_wiring_verilog(&unit).unwrap();
    assert!(
        !wiring.contains("Skeleton body"),
        "the wiring is complete RTL"
    );
    // The record crossbars gate each input with a conditional, not with a replicated select
    // bit, which Verilator builds one bit at a time (docs/hardware.md, "The wiring on its own").
    assert!(wiring.contains("(sel[i] ? in[i*W +: W] : {W{1'b0}})"));
    assert!(
        !wiring.contains("{W{sel"),
        "a replicated select bit in the crossbar"
    );
    let top = composite_modules(&unit.describe(), &children, wiring).unwrap();
    let top_text = &top[0].1;
    for c in &children {
        assert!(
            top_text.contains(&format!("{} {} (", c.desc.name, c.name)),
            "the top instantiates {}",
            c.name
        );
    }
    // What the wiring reads of the RT unit are its status ports, wired like any other port.
    let wiring_text = &top[1].1;
    for port in [
        "status_valid",
        "status_held",
        "status_quiescent",
        "status_order",
        "status_traversing",
        "status_busy",
        "status_distinct",
        "status_inactive",
    ] {
        assert!(
            top_text.contains(&format!(".{port}(rt_{port})")),
            "the top connects the RT unit's {port}"
        );
        assert!(
            wiring_text.contains(&format!("rt_{port},")),
            "the wiring takes the RT unit's {port}"
        );
    }
    modules.extend(top);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-gen-composed");
    std::fs::create_dir_all(&dir).unwrap();
    let files: Vec<PathBuf> = modules
        .iter()
        .map(|(name, text)| {
            let path = dir.join(format!("{name}.v"));
            std::fs::write(&path, text).unwrap();
            path
        })
        .collect();
    lints_clean(&files, "treelet_rt_unit", &dir, "treelet_rt_unit");
}
