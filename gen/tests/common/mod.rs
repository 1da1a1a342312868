//! Shared by the RTL tests (each test crate uses a part of it).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::time::Instant;
use vtq_gen::cosim::{run_cosim, CosimOptions, CosimResult, Simulator, Trace};
use vtq_gen::synth::{lint, synthesize, SynthReport};
use vtq_gen::tools::or_skip;
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

/// Co-simulates `trace` against `files` under `sim` in `work_dir`, prints the result and how
/// long it took (after `tag`) and asserts every cycle of the trace was compared; `None` when
/// the simulator is not installed (outside CI: the test skips).
pub fn cosim_timed(
    trace: &Trace,
    files: &[PathBuf],
    sim: Simulator,
    work_dir: PathBuf,
    tag: &str,
) -> Option<CosimResult> {
    let opts = CosimOptions {
        simulator: sim,
        ..CosimOptions::icarus(work_dir)
    };
    let start = Instant::now();
    let result = or_skip(run_cosim(trace, files, &opts)).unwrap()?;
    eprintln!("{tag}: {result}  ({:.1} s)", start.elapsed().as_secs_f64());
    assert_eq!(result.cycles, trace.cycles() as u64, "{tag}");
    Some(result)
}

/// Asserts `verilator --lint-only -Wall` finds nothing in `files` (top `module`, working in
/// `dir`), the failure naming `what`; false when Verilator is not installed (outside CI: the
/// test skips).
pub fn lints_clean(files: &[PathBuf], module: &str, dir: &Path, what: &str) -> bool {
    let Some(report) = or_skip(lint(files, module, dir)).unwrap() else {
        return false;
    };
    assert!(report.is_clean(), "{what}:\n{report}");
    true
}

/// Yosys' generic synthesis of `files` (top `module`, working in `dir`), asserting it infers
/// no latches and warns of nothing (failures name `what`); `None` when Yosys is not installed
/// (outside CI: the test skips).
pub fn synthesizes_without_latches(
    files: &[PathBuf],
    module: &str,
    dir: &Path,
    what: &str,
) -> Option<SynthReport> {
    let r = or_skip(synthesize(files, module, dir)).unwrap()?;
    assert_eq!(r.latches, 0, "{what}: {r:?}");
    assert!(r.warnings.is_empty(), "{what}: {r:?}");
    Some(r)
}

/// Writes `text`, the RTL of `module` at the small configuration, into `dir` and synthesizes
/// it ([`synthesizes_without_latches`]), asserting no undriven wires either; prints its cells
/// and flip-flops. `None` when Yosys is not installed (outside CI: the test skips).
pub fn synthesize_small(dir: &Path, module: &str, text: &str) -> Option<SynthReport> {
    let file = write_verilog(dir, module, text);
    let r = synthesizes_without_latches(&[file], module, dir, module)?;
    eprintln!(
        "{module} (small): {} cells, {} flip-flops",
        r.cells, r.flip_flops
    );
    assert!(r.undriven.is_empty(), "{module}: {:?}", r.undriven);
    Some(r)
}
