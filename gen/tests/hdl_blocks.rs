//! The skeleton generator on the real hardware blocks of `vtq-hdl`: every block's description
//! is valid and its skeleton lints clean and synthesizes without latches, at the paper's
//! configuration and a scaled one.

use std::path::PathBuf;
use vtq_gen::synth::{lint, synthesize};
use vtq_gen::tools::or_skip;
use vtq_gen::{emit_module, write_module};
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
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
