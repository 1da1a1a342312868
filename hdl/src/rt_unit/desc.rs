//! The RT unit's self-description (ports from its port bundles, registers, memories, lane state
//! machine, timing), its registers declared once with their trace signals ([`registers`]).

use super::bundles::{errors, LaneStatus, RtUnitRegs, TraversalOrder};
use super::node::{NodeEntry, NodeKind, MAX_NODE_CHUNKS, RAY_WORDS};
use super::ports::{RtUnitInputs, RtUnitStatus, Widths, DATA_BITS, HIT_BITS};
use super::{RtUnitParams, StackLayout};
use crate::bits::{bits_for, clog2};
use crate::config::HwConfig;
use crate::describe::{block_params, BlockDesc, FsmDesc, MemDesc};
use crate::registers::RegTable;

/// Builds the block description for `cfg` and `params`.
pub(super) fn describe(cfg: &HwConfig, params: &RtUnitParams, w: &Widths) -> BlockDesc {
    let lanes = cfg.warp_buffer_size * cfg.warp_size;
    let entry = NodeEntry::bits(cfg.address_bits);

    // The cycle's ports, then the register-only status ports the treelet wiring reads.
    let mut ports = RtUnitInputs::block_ports(w);
    ports.extend(RtUnitStatus::ports(w));

    let registers = registers(cfg, params, w).descs();

    // Each lane's stacks: the bottom window and the top in registers (below), the rest in a
    // ring of SRAM banks (`StackLayout`).
    let layout = StackLayout::new(cfg, params);
    let stack = |name: &str, which: &str| MemDesc {
        name: name.to_string(),
        banks: lanes * layout.banks,
        depth: layout.bank_words,
        width: entry,
        read_ports: 1,
        write_ports: 1,
        read_latency: 1,
        fields: entry_fields(cfg.address_bits),
        doc: format!(
            "the {which} stacks' entries above each lane's window of {}: a ring of {} banks of \
             {} words per lane, one read and one write port each; a test's children are \
             written in one cycle, each to its own bank; a pop reads the new top and a spill \
             the entries sliding into the window, for the next cycle",
            layout.window, layout.banks, layout.bank_words
        ),
    };
    let mut memories = Vec::new();
    if layout.banks > 0 {
        memories.push(stack("cur_stack", "current-treelet"));
        memories.push(stack("other_stack", "other-treelet"));
    }
    memories.extend([
        MemDesc {
            name: "node_buffer".into(),
            banks: MAX_NODE_CHUNKS as u32,
            depth: lanes,
            width: DATA_BITS,
            read_ports: 1,
            write_ports: 1,
            read_latency: 1,
            fields: vec![("data".into(), DATA_BITS)],
            doc: "returned chunks of the nodes in flight, bank c holding chunk c, one word per \
                  slot and leader lane (the lanes a fetch merged share its chunks); a popped \
                  chunk is written, and every bank reads the next response's leader one cycle \
                  ahead, so a node's earlier chunks reach the datapath with its last"
                .into(),
        },
        MemDesc {
            name: "resp_fifo".into(),
            banks: 1,
            depth: params.resp_fifo_depth,
            width: cfg.address_bits + w.tag + DATA_BITS,
            read_ports: 1,
            write_ports: params.resp_ports,
            read_latency: 0,
            fields: vec![
                ("address".into(), cfg.address_bits),
                ("tag".into(), w.tag),
                ("data".into(), DATA_BITS),
            ],
            doc: "responses from memory, popped one per cycle".into(),
        },
    ]);

    let l = &params.latencies;
    BlockDesc {
        name: "rt_unit".into(),
        doc: "RT unit control (paper section 2.2, Figure 3; section 4.2, Figure 8): warp buffer of \
              per-ray traversal state with current-treelet and other-treelet stacks, memory scheduler \
              issuing one 32 B request per cycle, response FIFO, intersection-delay countdown and warp \
              completion; reports treelet-boundary events to the treelet controller. The intersection \
              datapath is outside the block."
            .into(),
        params: block_params!(cfg;
            warp_size, warp_buffer_size, stack_depth, record_stack_entries, address_bits,
            treelet_bytes, max_rays,
            resp_fifo_depth = params.resp_fifo_depth,
            resp_ports = params.resp_ports,
            hit_record_base = params.hit_record_base,
            max_children = params.max_children,
            stack_base = super::spill_area(cfg, params).0,
            stack_spill_chunks = params.stack_spill_chunks,
            stack_window = layout.window,
            stack_banks = layout.banks,
            stack_bank_words = layout.bank_words,
        ),
        ports,
        registers,
        memories,
        fsms: vec![FsmDesc {
            name: "lane_status".into(),
            states: LaneStatus::NAMES.iter().map(|s| s.to_string()).collect(),
            width: 2,
        }],
        timing: vec![
            "memory scheduler: at most one 32 B request per cycle; priority: remaining chunks of the node being requested, then a hit-record store (oldest warp, lowest lane), then the request of the lowest ready lane of the oldest warp with a ready lane: a stack spill, a stack fill or its next node".into(),
            "stack spilling: before a fetch, every stack that may receive the node's children must have max_children free entries after the pop, else the lane's request is a 32 B store of up to four of that stack's oldest on-chip entries (never the one about to be popped) to the ray's spill area (stack_base + ((ray_id * 2 + stack) * stack_spill_chunks + k) * 32); a stack empty on chip with chunks in memory is refilled by a 32 B load of its last spilled chunk (the lane waits for it); the on-chip stacks never overflow".into(),
            "parked rays: a parked lane with more than record_stack_entries entries of its other stack on chip is ready and busy; its request is a spill of up to four of that stack's oldest entries (never the newest record_stack_entries), so a completed warp's records carry at most record_stack_entries on-chip entries per stack; an issued record carries no more".into(),
            "requests for the same (address, size) by ready lanes of one warp in one cycle are merged; never across warps".into(),
            "a ray has one node in flight; its next fetch waits for every chunk and for its intersection delay to reach 0; all delays count down in parallel".into(),
            format!(
                "test latency (cycles): header {}, internal {}, instance leaf {}, primitive descriptor {}, triangle leaf {}, triangle hit {}, procedural {}; a node whose last chunk is popped in cycle t lets the ray request again in cycle t + latency + 1",
                l.header, l.internal, l.instance_leaf, l.primitive_descriptor, l.triangle_leaf, l.triangle_hit, l.procedural
            ),
            "response FIFO: written at the end of the cycle a response arrives, one entry popped per cycle (from the next cycle on)".into(),
            "a warp completes when every lane is inactive, done or parked (at most record_stack_entries entries of the other stack on chip) with nothing in flight, no delay and no store pending, and it is not held by a repack; at most one per cycle (oldest first); an issued warp can request from the next cycle".into(),
            "treelet controller commands (issue into a reserved slot, append, stop, repack) take effect at the end of the cycle after the warp issue; a repack releases the lanes that are done and quiescent after this cycle's completion, response delivery and issue".into(),
        ],
    }
}

/// Fields of a stack entry, most significant first.
fn entry_fields(address_bits: u32) -> Vec<(String, u32)> {
    vec![
        ("address".into(), address_bits),
        ("kind".into(), NodeKind::BITS),
        ("chunks_minus_1".into(), 2),
    ]
}

/// The RT unit's registers for `cfg`, `params` and widths `w`: their descriptions and trace
/// signals, declared once. Per-slot state is traced per slot (`<name>_<slot>`), per-lane state
/// per slot and lane (`<name>_<slot>_<lane>`); ray records, hits, stack pointers and the other
/// per-lane registers are described but not traced, and the response FIFO's pointers are
/// described only (the model keeps the FIFO as a queue; its occupancy is traced).
pub(super) fn registers(
    cfg: &HwConfig,
    params: &RtUnitParams,
    w: &Widths,
) -> RegTable<'static, RtUnitRegs> {
    let mut t = RegTable::new();
    slot_and_scheduler_registers(&mut t, cfg, params, w);
    lane_registers(&mut t, cfg, w);
    stack_window_registers(&mut t, cfg, params);
    t
}

/// The per-slot, scheduler, response-FIFO, node-buffer and error registers, appended to `t` in
/// their description order (the first group of [`registers`]).
fn slot_and_scheduler_registers(
    t: &mut RegTable<'static, RtUnitRegs>,
    cfg: &HwConfig,
    params: &RtUnitParams,
    w: &Widths,
) {
    let entry = NodeEntry::bits(cfg.address_bits);
    let lanes = cfg.warp_buffer_size * cfg.warp_size;
    t.bank(
        "slot_valid",
        1,
        cfg.warp_buffer_size,
        "warp-buffer slot holds a warp",
        |r: &RtUnitRegs, s| r.slots[s].valid as u64,
    )
    .bank(
        "slot_order",
        TraversalOrder::BITS,
        cfg.warp_buffer_size,
        "traversal order of the slot's warp",
        |r, s| r.slots[s].order.code(),
    )
    .bank(
        "slot_held",
        1,
        cfg.warp_buffer_size,
        "the slot's warp is being repacked: it does not complete until the fill's last append",
        |r, s| r.slots[s].held as u64,
    )
    .bank(
        "age_order",
        w.slot,
        cfg.warp_buffer_size,
        "valid slots, oldest first (scheduler and completion priority)",
        |r, k| r.age.get(k).map_or(0, |&s| s as u64),
    )
    .one(
        "age_count",
        bits_for(cfg.warp_buffer_size as u64),
        "valid entries of age_order",
        |r| r.age.len() as u64,
    )
    .one(
        "split_valid",
        1,
        "chunks of the node being requested remain (highest scheduler priority)",
        |r| r.split.is_some() as u64,
    )
    .one("split_tag", w.tag, "tag of the node being requested", |r| {
        r.split.as_ref().map_or(0, |s| s.tag as u64)
    })
    .one(
        "split_node",
        entry,
        "node being requested (address, kind, chunks - 1)",
        |r| r.split.as_ref().map_or(0, |s| s.node.encode()),
    )
    .one("split_chunk", 2, "next chunk of the node to request", |r| {
        r.split.as_ref().map_or(0, |s| s.next_chunk as u64)
    })
    .untraced(
        "fifo_head",
        clog2(params.resp_fifo_depth as u64),
        1,
        "response-FIFO read pointer",
    )
    .untraced(
        "fifo_tail",
        clog2(params.resp_fifo_depth as u64),
        1,
        "response-FIFO write pointer",
    )
    .one("fifo_count", w.fifo_count, "response-FIFO occupancy", |r| {
        r.fifo.len() as u64
    })
    .untraced(
        "node_write_valid",
        1,
        1,
        "the node buffer was written last cycle (its read that cycle missed the write)",
    )
    .untraced(
        "node_write_chunk",
        2,
        1,
        "the node buffer's bank written last cycle",
    )
    .untraced(
        "node_write_index",
        clog2(lanes as u64).max(1),
        1,
        "the node buffer's word written last cycle (slot * warp size + leader lane)",
    )
    .untraced(
        "node_write_data",
        DATA_BITS,
        1,
        "the chunk written last cycle, forwarded to this cycle's read",
    )
    .one("errors", errors::BITS, "sticky error flags", |r| {
        r.errors as u64
    })
    .untraced(
        "first_error",
        1 + 3 + w.slot + w.lane + w.ray_id + 128,
        1,
        "capture of the first error: valid, kind, slot, lane, ray id, value, limit",
    );
}

/// The per-lane registers (status, ray record, hit, stack pointers, node in flight, delay,
/// store and write flags), appended to `t` in their description order (the second group of
/// [`registers`]).
fn lane_registers(t: &mut RegTable<'static, RtUnitRegs>, cfg: &HwConfig, w: &Widths) {
    let n = cfg.warp_size;
    let entry = NodeEntry::bits(cfg.address_bits);
    let sp = bits_for(cfg.stack_depth as u64);
    let words = RAY_WORDS as u32 * 32;
    let delay = w.delay;
    let lanes = cfg.warp_buffer_size * n;
    t.grid(
        "lane_status",
        2,
        (cfg.warp_buffer_size, n),
        "per lane: inactive / traversing / done / parked",
        |r, s, l| r.slots[s].lanes[l].status.code(),
    )
    .untraced("lane_ray_id", w.ray_id, lanes, "per lane: ray id")
    .untraced(
        "lane_ray_words",
        words,
        lanes,
        "per lane: origin, direction, tmin, tmax (f32 bits)",
    )
    .untraced(
        "lane_occlusion",
        1,
        lanes,
        "per lane: an occlusion ray (traversal ends at its first accepted hit)",
    )
    .untraced("lane_hit_valid", 1, lanes, "per lane: a hit was found")
    .untraced(
        "lane_hit",
        HIT_BITS,
        lanes,
        "per lane: closest hit t, hit id, two attributes",
    )
    .untraced(
        "lane_cur_treelet",
        w.treelet,
        lanes,
        "per lane: the ray's current treelet",
    )
    .untraced(
        "lane_cur_sp",
        sp,
        lanes,
        "per lane: current-treelet stack depth",
    )
    .untraced(
        "lane_other_sp",
        sp,
        lanes,
        "per lane: other-treelet stack depth",
    )
    .untraced(
        "lane_cur_spilled",
        w.spilled,
        lanes,
        "per lane: current-treelet stack chunks in the spill area",
    )
    .untraced(
        "lane_other_spilled",
        w.spilled,
        lanes,
        "per lane: other-treelet stack chunks in the spill area",
    )
    .untraced(
        "lane_filling",
        2,
        lanes,
        "per lane: stack fill in flight: 0 none, 1 current-treelet, 2 other-treelet",
    )
    .untraced("lane_node_valid", 1, lanes, "per lane: a node is in flight")
    .untraced(
        "lane_node",
        entry,
        lanes,
        "per lane: the node in flight (address, kind, chunks - 1)",
    )
    .untraced(
        "lane_node_leader",
        w.lane,
        lanes,
        "per lane: lane whose request fetches the node (merging)",
    )
    .untraced(
        "lane_chunks_returned",
        MAX_NODE_CHUNKS as u32,
        lanes,
        "per lane: chunks of the node returned",
    )
    .grid(
        "lane_delay",
        delay,
        (cfg.warp_buffer_size, n),
        "per lane: intersection-delay countdown",
        |r, s, l| r.slots[s].lanes[l].delay as u64,
    )
    .untraced(
        "lane_store_pending",
        1,
        lanes,
        "per lane: hit-record store waiting",
    )
    .grid(
        "lane_written",
        1,
        (cfg.warp_buffer_size, n),
        "per lane: holds a ray record written ahead of its warp's issue (inactive until issued)",
        |r, s, l| r.slots[s].lanes[l].written as u64,
    );
}

/// Each lane's stack registers (bottom window, top copy, ring base, pending SRAM read) for the
/// current-treelet then the other-treelet stack, appended to `t` (the last group of
/// [`registers`]).
fn stack_window_registers(
    t: &mut RegTable<'static, RtUnitRegs>,
    cfg: &HwConfig,
    params: &RtUnitParams,
) {
    let entry = NodeEntry::bits(cfg.address_bits);
    let lanes = cfg.warp_buffer_size * cfg.warp_size;
    let layout = StackLayout::new(cfg, params);
    for (stack, which) in [("cur", "current-treelet"), ("other", "other-treelet")] {
        t.untraced(
            &format!("lane_{stack}_window"),
            layout.window * entry,
            lanes,
            &format!(
                "per lane: the {which} stack's bottom {} entries, bottom first",
                layout.window
            ),
        )
        .untraced(
            &format!("lane_{stack}_top"),
            entry,
            lanes,
            &format!(
                "per lane: a copy of the {which} stack's top entry while it lies in the SRAM ring"
            ),
        )
        .untraced(
            &format!("lane_{stack}_base"),
            layout.position_bits(),
            lanes,
            &format!(
                "per lane: the ring position of the {which} stack's entry {} (the first above \
                 the window)",
                layout.window
            ),
        )
        .untraced(
            &format!("lane_{stack}_pending"),
            layout.window + 1,
            lanes,
            &format!(
                "per lane: the {which} stack's window entries (low bits) and top (high bit) \
                 that this cycle's SRAM read data replaces"
            ),
        );
    }
}
