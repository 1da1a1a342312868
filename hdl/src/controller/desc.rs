//! The treelet controller's description: parameters, ports (from its port bundles), registers
//! (from [`super::regs`]), state machines and timing.

use super::{regs, ControllerFeatures, ControllerInputs, ControllerOutputs, ControllerWidths, Seq};
use crate::config::HwConfig;
use crate::describe::{block_params, BlockDesc, FsmDesc};
use crate::mode::Mode;

/// The controller's [`BlockDesc`].
pub(super) fn describe(
    cfg: &HwConfig,
    features: ControllerFeatures,
    w: &ControllerWidths,
) -> BlockDesc {
    let mut ports = ControllerInputs::ports(w);
    ports.extend(ControllerOutputs::ports(w));
    let registers = regs::table(w).descs();
    let n = w.resident_entries;
    BlockDesc {
        name: "treelet_controller".to_string(),
        doc: "Treelet controller (sections 4.2-4.5): switches the RT unit between the initial \
              ray-stationary phase, treelet-stationary processing of the largest treelet queues \
              (with preloading of the next treelet) and the final ray-stationary phase that \
              groups underpopulated queues into warps and repacks warps with few active rays; \
              drives one treelet-count-table and one treelet-queue-table op per cycle."
            .to_string(),
        params: block_params!(cfg;
            warp_size, max_rays, warp_buffer_size, max_resident_treelets, count_table_entries,
            queue_table_entries,
            treelet_addr_bits = w.treelet,
            ray_id_bits = w.ray,
            count_bits = w.count,
            lane_bits = w.lane,
            lane_count_bits = w.lanes,
            slot_bits = w.slot,
            divergence_threshold, underpopulation_threshold, repack_threshold,
            preload_threshold_warps,
            group_underpopulated = features.group_underpopulated,
            preload = features.preload,
        ),
        ports,
        registers,
        memories: vec![],
        fsms: vec![
            FsmDesc {
                name: "mode".to_string(),
                states: Mode::ALL.iter().map(|m| m.name().to_string()).collect(),
                width: Mode::BITS,
            },
            FsmDesc {
                name: "seq".to_string(),
                states: Seq::ALL.iter().map(|s| s.name().to_string()).collect(),
                width: Seq::BITS,
            },
        ],
        timing: vec![
            "At most one count-table op and one queue-table op per cycle, each driven only in a cycle whose ready input is high (both readies come from the tables' registers); all outputs are combinational from registers and this cycle's inputs.".to_string(),
            "restart in mode done selects the reset values of every register for this cycle's next-state logic (a new wave of rays starts in the initial phase).".to_string(),
            "Answers (qt_done with the popped entry, ct_evict_*) are the tables' outputs of the previous cycle; one pop / pop_any / refill is outstanding at a time (seq = pop_wait / refill_wait).".to_string(),
            "A pending count-table remove (prm_*) owns the count-table port first, issuing up to warp_size rays per cycle.".to_string(),
            "In seq = idle at most one action per cycle, by priority: refill a spilled ray, dispatch a treelet warp (pop), claim the largest queue (no table op; preload it if a treelet is already resident), start a grouped warp or a repack, enqueue one ray (insert plus count-table add).".to_string(),
            "Terminations of diverged initial-phase warps, warp-done bookkeeping, resident retirement and mode transitions happen every cycle in parallel with the sequencer.".to_string(),
            format!("The resident list ({n} entries) is searched in parallel: {n} comparators each on enq_treelet, ct_max_treelet and ct_evict_treelet, and a priority pick from res_head."),
            format!("A fill moves up to {} ray ids per cycle from the pop bus or the spare buffer through a lane shifter.", w.warp_size),
        ],
    }
}
