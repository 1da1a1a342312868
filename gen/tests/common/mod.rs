//! Shared by the RTL tests (each test crate uses a part of it).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use vtq_hdl::HwConfig;

/// Writes `text` as `<dir>/<module>.v`.
pub fn write_verilog(dir: &Path, module: &str, text: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{module}.v"));
    std::fs::write(&path, text).unwrap();
    path
}

/// The small configuration of the controller's RTL tests: 4-lane warps, 64 rays, a 4-entry count
/// table (it evicts) and a 6-entry queue table (it spills), 3 warp-buffer slots and 3 resident
/// entries (neither a power of two: the slot range checks and the resident list's wrap are
/// exercised); every block synthesizes in a few seconds.
pub fn small() -> HwConfig {
    HwConfig {
        count_table_entries: 4,
        queue_table_entries: 6,
        max_rays: 64,
        warp_size: 4,
        underpopulation_threshold: 5,
        repack_threshold: 3,
        divergence_threshold: 1,
        max_resident_treelets: 3,
        warp_buffer_size: 3,
        preload_threshold_warps: 1,
        ..HwConfig::default()
    }
}
