//! The RT unit's self-description (ports from its port bundles, registers, memories, lane state
//! machine, timing) and its registers' trace signals.

use super::bundles::{errors, LaneStatus, RtUnitRegs, TraversalOrder};
use super::node::{NodeEntry, NodeKind, MAX_NODE_CHUNKS, RAY_WORDS};
use super::ports::{RtUnitInputs, RtUnitStatus, Widths, DATA_BITS, HIT_BITS};
use super::RtUnitParams;
use crate::bits::{bits_for, clog2};
use crate::block::Signal;
use crate::config::HwConfig;
use crate::describe::{reg, BlockDesc, FsmDesc, MemDesc};

/// Builds the block description for `cfg` and `params`.
pub(super) fn describe(cfg: &HwConfig, params: &RtUnitParams, w: &Widths) -> BlockDesc {
    let n = cfg.warp_size;
    let entry = NodeEntry::bits(cfg.address_bits);
    let sp = bits_for(cfg.stack_depth as u64);
    let words = RAY_WORDS as u32 * 32;
    let delay = w.delay;
    let lanes = cfg.warp_buffer_size * n;

    // The cycle's ports, then the register-only status ports the treelet wiring reads.
    let mut ports = RtUnitInputs::block_ports(w);
    ports.extend(RtUnitStatus::ports(w));

    let registers = vec![
        reg(
            "slot_valid",
            1,
            cfg.warp_buffer_size,
            "warp-buffer slot holds a warp",
        ),
        reg(
            "slot_order",
            TraversalOrder::BITS,
            cfg.warp_buffer_size,
            "traversal order of the slot's warp",
        ),
        reg(
            "slot_held",
            1,
            cfg.warp_buffer_size,
            "the slot's warp is being repacked: it does not complete until the fill's last append",
        ),
        reg(
            "age_order",
            w.slot,
            cfg.warp_buffer_size,
            "valid slots, oldest first (scheduler and completion priority)",
        ),
        reg(
            "age_count",
            bits_for(cfg.warp_buffer_size as u64),
            1,
            "valid entries of age_order",
        ),
        reg(
            "split_valid",
            1,
            1,
            "chunks of the node being requested remain (highest scheduler priority)",
        ),
        reg("split_tag", w.tag, 1, "tag of the node being requested"),
        reg(
            "split_node",
            entry,
            1,
            "node being requested (address, kind, chunks - 1)",
        ),
        reg("split_chunk", 2, 1, "next chunk of the node to request"),
        reg(
            "fifo_head",
            clog2(params.resp_fifo_depth as u64),
            1,
            "response-FIFO read pointer",
        ),
        reg(
            "fifo_tail",
            clog2(params.resp_fifo_depth as u64),
            1,
            "response-FIFO write pointer",
        ),
        reg("fifo_count", w.fifo_count, 1, "response-FIFO occupancy"),
        reg("errors", errors::BITS, 1, "sticky error flags"),
        reg(
            "first_error",
            1 + 3 + w.slot + w.lane + w.ray_id + 128,
            1,
            "capture of the first error: valid, kind, slot, lane, ray id, value, limit",
        ),
        reg(
            "lane_status",
            2,
            lanes,
            "per lane: inactive / traversing / done / parked",
        ),
        reg("lane_ray_id", w.ray_id, lanes, "per lane: ray id"),
        reg(
            "lane_ray_words",
            words,
            lanes,
            "per lane: origin, direction, tmin, tmax (f32 bits)",
        ),
        reg("lane_hit_valid", 1, lanes, "per lane: a hit was found"),
        reg(
            "lane_hit",
            HIT_BITS,
            lanes,
            "per lane: closest hit t, hit id, two attributes",
        ),
        reg(
            "lane_cur_treelet",
            w.treelet,
            lanes,
            "per lane: the ray's current treelet",
        ),
        reg(
            "lane_cur_sp",
            sp,
            lanes,
            "per lane: current-treelet stack depth",
        ),
        reg(
            "lane_other_sp",
            sp,
            lanes,
            "per lane: other-treelet stack depth",
        ),
        reg(
            "lane_cur_spilled",
            w.spilled,
            lanes,
            "per lane: current-treelet stack chunks in the spill area",
        ),
        reg(
            "lane_other_spilled",
            w.spilled,
            lanes,
            "per lane: other-treelet stack chunks in the spill area",
        ),
        reg(
            "lane_filling",
            2,
            lanes,
            "per lane: stack fill in flight: 0 none, 1 current-treelet, 2 other-treelet",
        ),
        reg("lane_node_valid", 1, lanes, "per lane: a node is in flight"),
        reg(
            "lane_node",
            entry,
            lanes,
            "per lane: the node in flight (address, kind, chunks - 1)",
        ),
        reg(
            "lane_node_leader",
            w.lane,
            lanes,
            "per lane: lane whose request fetches the node (merging)",
        ),
        reg(
            "lane_chunks_returned",
            MAX_NODE_CHUNKS as u32,
            lanes,
            "per lane: chunks of the node returned",
        ),
        reg(
            "lane_delay",
            delay,
            lanes,
            "per lane: intersection-delay countdown",
        ),
        reg(
            "lane_store_pending",
            1,
            lanes,
            "per lane: hit-record store waiting",
        ),
    ];

    let stack = |name: &str, doc: &str| MemDesc {
        name: name.to_string(),
        depth: lanes * cfg.stack_depth,
        width: entry,
        read_ports: 1,
        write_ports: 1,
        read_latency: 0,
        fields: entry_fields(cfg.address_bits),
        doc: doc.to_string(),
    };
    let memories = vec![
        stack("cur_stack", "on-chip current-treelet stacks, stack_depth entries per lane, banked per lane; a test's children are written as one wide write; older entries spill to memory 4 per 32 B chunk"),
        stack("other_stack", "on-chip other-treelet stacks, stack_depth entries per lane, banked per lane; older entries spill to memory"),
        MemDesc {
            name: "node_buffer".into(),
            depth: lanes * MAX_NODE_CHUNKS as u32,
            width: DATA_BITS,
            read_ports: 1,
            write_ports: 1,
            read_latency: 0,
            fields: vec![("data".into(), DATA_BITS)],
            doc: "returned chunks of each lane's node in flight, read by the datapath as one node".into(),
        },
        MemDesc {
            name: "resp_fifo".into(),
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
    ];

    let l = &params.latencies;
    BlockDesc {
        name: "rt_unit".into(),
        doc: "RT unit control (paper section 2.2, Figure 3; section 4.2, Figure 8): warp buffer of \
              per-ray traversal state with current-treelet and other-treelet stacks, memory scheduler \
              issuing one 32 B request per cycle, response FIFO, intersection-delay countdown and warp \
              completion; reports treelet-boundary events to the treelet controller. The intersection \
              datapath is outside the block."
            .into(),
        params: vec![
            ("warp_size".into(), cfg.warp_size as u64),
            ("warp_buffer_size".into(), cfg.warp_buffer_size as u64),
            ("stack_depth".into(), cfg.stack_depth as u64),
            ("address_bits".into(), cfg.address_bits as u64),
            ("treelet_bytes".into(), cfg.treelet_bytes as u64),
            ("max_rays".into(), cfg.max_rays as u64),
            ("resp_fifo_depth".into(), params.resp_fifo_depth as u64),
            ("resp_ports".into(), params.resp_ports as u64),
            ("hit_record_base".into(), params.hit_record_base),
            ("max_children".into(), params.max_children as u64),
            ("stack_base".into(), super::spill_area(cfg, params).0),
            ("stack_spill_chunks".into(), params.stack_spill_chunks as u64),
        ],
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
            "requests for the same (address, size) by ready lanes of one warp in one cycle are merged; never across warps".into(),
            "a ray has one node in flight; its next fetch waits for every chunk and for its intersection delay to reach 0; all delays count down in parallel".into(),
            format!(
                "test latency (cycles): header {}, internal {}, instance leaf {}, primitive descriptor {}, triangle leaf {}, triangle hit {}, procedural {}; a node whose last chunk is popped in cycle t lets the ray request again in cycle t + latency + 1",
                l.header, l.internal, l.instance_leaf, l.primitive_descriptor, l.triangle_leaf, l.triangle_hit, l.procedural
            ),
            "response FIFO: written at the end of the cycle a response arrives, one entry popped per cycle (from the next cycle on)".into(),
            "a warp completes when every lane is inactive, done or parked with nothing in flight, no delay and no store pending, and it is not held by a repack; at most one per cycle (oldest first); an issued warp can request from the next cycle".into(),
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

/// The registers `r` as trace signals, for widths `w`.
pub(super) fn reg_signals(r: &RtUnitRegs, w: &Widths) -> Vec<Signal> {
    let mut v = Vec::new();
    for (s, slot) in r.slots.iter().enumerate() {
        v.push(Signal::new(format!("slot_valid_{s}"), 1, slot.valid as u64));
        v.push(Signal::new(
            format!("slot_order_{s}"),
            TraversalOrder::BITS,
            slot.order.code(),
        ));
        v.push(Signal::new(format!("slot_held_{s}"), 1, slot.held as u64));
    }
    for k in 0..r.slots.len() {
        v.push(Signal::new(
            format!("age_order_{k}"),
            w.slot,
            r.age.get(k).map_or(0, |&s| s as u64),
        ));
    }
    v.push(Signal::new(
        "age_count",
        bits_for(r.slots.len() as u64),
        r.age.len() as u64,
    ));
    let split = r.split.as_ref();
    v.extend([
        Signal::new("split_valid", 1, split.is_some() as u64),
        Signal::new("split_tag", w.tag, split.map_or(0, |s| s.tag as u64)),
        Signal::new(
            "split_node",
            NodeEntry::bits(w.address),
            split.map_or(0, |s| s.node.encode()),
        ),
        Signal::new("split_chunk", 2, split.map_or(0, |s| s.next_chunk as u64)),
        Signal::new("fifo_count", w.fifo_count, r.fifo.len() as u64),
        Signal::new("errors", errors::BITS, r.errors as u64),
    ]);
    for (s, slot) in r.slots.iter().enumerate() {
        for (l, lane) in slot.lanes.iter().enumerate() {
            v.push(Signal::new(
                format!("lane_status_{s}_{l}"),
                2,
                lane.status.code(),
            ));
            v.push(Signal::new(
                format!("lane_delay_{s}_{l}"),
                w.delay,
                lane.delay as u64,
            ));
        }
    }
    v
}
