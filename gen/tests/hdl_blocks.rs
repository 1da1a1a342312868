//! The skeleton generator on the real hardware blocks of `vtq-hdl`: every block's description
//! is valid and its skeleton lints clean and synthesizes without latches, at the paper's
//! configuration and a scaled one.

use std::path::PathBuf;
use vtq_gen::synth::{lint, synthesize};
use vtq_gen::tools::or_skip;
use vtq_gen::{emit_module, write_module, GenError};
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::rt_unit::{Hit, NodeDatapath, NodeEntry, RayWords, RtUnit, RtUnitParams, TestResult};
use vtq_hdl::{Block, BlockDesc, HwConfig};

/// An intersection datapath for describing the RT unit (the description does not depend on it).
struct NoHits;

impl NodeDatapath for NoHits {
    fn test(&self, _: &RayWords, _: Option<&Hit>, _: &NodeEntry, _: &[u8]) -> TestResult {
        TestResult::default()
    }
}

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
            let Some(report) = or_skip(lint(&files, &d.name, &dir)).unwrap() else {
                return;
            };
            assert!(report.is_clean(), "{} ({tag}):\n{report}", d.name);
            let Some(synth) = or_skip(synthesize(&files, &d.name, &dir)).unwrap() else {
                return;
            };
            assert_eq!(synth.latches, 0, "{} ({tag}): {synth:?}", d.name);
            assert!(synth.warnings.is_empty(), "{} ({tag}): {synth:?}", d.name);
        }
    }
}

fn rt_unit_desc(cfg: HwConfig) -> BlockDesc {
    RtUnit::new(cfg, RtUnitParams::default(), NoHits)
        .unwrap()
        .describe()
}

/// At the paper's configuration the RT unit's per-warp stack ports (32 lanes x 64 entries x 37
/// bits = 75776 bits) exceed the widest signal the generator (and Verilator) accepts, and the
/// error names the port; with 32-entry stacks (37888-bit ports) its skeleton lints clean and
/// synthesizes without latches.
#[test]
fn rt_unit_skeleton_lints_where_its_ports_fit() {
    match emit_module(&rt_unit_desc(HwConfig::default())) {
        Err(GenError::InvalidDesc { block, reason }) => {
            assert_eq!(block, "rt_unit");
            assert!(
                reason.contains("_stack") && reason.contains("75776"),
                "{reason}"
            );
        }
        other => panic!("expected the stack ports to be rejected as too wide: {other:?}"),
    }
    let cfg = HwConfig {
        stack_depth: 32,
        ..HwConfig::default()
    };
    let d = rt_unit_desc(cfg);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-gen-hdl-stack32-rt_unit");
    let files = [write_module(&dir, &d).unwrap()];
    let Some(report) = or_skip(lint(&files, &d.name, &dir)).unwrap() else {
        return;
    };
    assert!(report.is_clean(), "{}:\n{report}", d.name);
    let Some(synth) = or_skip(synthesize(&files, &d.name, &dir)).unwrap() else {
        return;
    };
    assert_eq!(synth.latches, 0, "{}: {synth:?}", d.name);
    assert!(synth.warnings.is_empty(), "{}: {synth:?}", d.name);
}
