//! The RT unit's self-description (ports, registers, memories, lane state machine, timing) and
//! the flattening of its bundles into trace signals.

use super::bundles::{
    errors, IssueTarget, LaneStatus, MemRequest, MemResponse, RequestKind, RtStats, RtUnitInputs,
    RtUnitOutputs, RtUnitRegs, TraversalOrder, Widths,
};
use super::node::{NodeEntry, NodeKind, CHUNK_BYTES, MAX_NODE_CHUNKS, RAY_WORDS};
use super::RtUnitParams;
use crate::bits::{bits_for, clog2};
use crate::block::{Signal, Signals};
use crate::config::HwConfig;
use crate::describe::{port, reg, BlockDesc, Dir, FsmDesc, MemDesc};

/// Bits of a memory data chunk (32 B).
const DATA_BITS: u32 = CHUNK_BYTES * 8;
/// Bits of a hit: t, hit id and two attribute words.
const HIT_BITS: u32 = 4 * 32;
/// Bits of a request's size field (bytes, always 32).
const SIZE_BITS: u32 = 6;

/// Builds the block description for `cfg` and `params`.
pub(super) fn describe(cfg: &HwConfig, params: &RtUnitParams, w: &Widths) -> BlockDesc {
    let n = cfg.warp_size;
    let entry = NodeEntry::bits(cfg.address_bits);
    let sp = bits_for(cfg.stack_depth as u64);
    let words = RAY_WORDS as u32 * 32;
    let delay = w.delay;
    let lanes = cfg.warp_buffer_size * n;

    let mut ports = vec![
        port("issue_valid", Dir::In, 1, "a warp is issued to the warp buffer this cycle"),
        port("issue_ready", Dir::Out, 1, "a warp-buffer slot is free (registers only)"),
        port("issue_order", Dir::In, TraversalOrder::BITS, "traversal order: 0 ray-stationary single stack, 1 treelet two-stack continuing across boundaries, 2 treelet two-stack stopping at a boundary"),
        port("issue_target", Dir::In, IssueTarget::BITS, "0 a new warp in the lowest free slot, 1 a new warp in issue_slot (reserved by the treelet controller), 2 append the active lanes into inactive lanes of held slot issue_slot (repack fill)"),
        port("issue_slot", Dir::In, w.slot, "slot of issue_target 1 and 2"),
        port("issue_last", Dir::In, 1, "with issue_target 2: the repack fill is complete, release the hold"),
        port("stop_valid", Dir::In, 1, "treelet controller terminate: stop_slot's rays stop at their next treelet boundary (order becomes treelet-stop)"),
        port("stop_slot", Dir::In, w.slot, "the terminated slot"),
        port("repack_valid", Dir::In, 1, "treelet controller repack: release repack_slot's finished lanes and hold the slot until a fill with issue_last"),
        port("repack_slot", Dir::In, w.slot, "the repacked slot"),
    ];
    ports.extend(ray_state_ports("issue", Dir::In, cfg, w));
    ports.extend([
        port(
            "req_valid",
            Dir::Out,
            1,
            "a 32 B memory request is issued (at most one per cycle)",
        ),
        port(
            "req_address",
            Dir::Out,
            cfg.address_bits,
            "byte address of the request (32 B aligned)",
        ),
        port(
            "req_size",
            Dir::Out,
            SIZE_BITS,
            "request size in bytes (always 32; a 64 B node takes two requests)",
        ),
        port(
            "req_kind",
            Dir::Out,
            RequestKind::BITS,
            "0 node-chunk load, 1 hit-record store (no response), 2 stack spill store (no response), 3 stack fill load",
        ),
        port(
            "req_tag",
            Dir::Out,
            w.tag,
            "requesting slot and lane (slot << lane_bits | lane), returned with the response",
        ),
        port(
            "req_data",
            Dir::Out,
            DATA_BITS,
            "store data: hit record (t, hit id, two attributes, ray id) or up to four spilled stack entries (64-bit slots, valid bit 63, bottom first)",
        ),
        port(
            "resp_free",
            Dir::Out,
            w.fifo_count,
            "free response-FIFO entries (registers only); memory delivers no more than this",
        ),
    ]);
    for k in 0..params.resp_ports {
        ports.extend([
            port(
                &format!("resp{k}_valid"),
                Dir::In,
                1,
                "a 32 B chunk returns from memory on this response port",
            ),
            port(
                &format!("resp{k}_address"),
                Dir::In,
                cfg.address_bits,
                "byte address of the returned chunk",
            ),
            port(
                &format!("resp{k}_tag"),
                Dir::In,
                w.tag,
                "tag of the request the chunk answers",
            ),
            port(
                &format!("resp{k}_data"),
                Dir::In,
                DATA_BITS,
                "the chunk's 256 bits",
            ),
        ]);
    }
    ports.extend([
        port(
            "done_valid",
            Dir::Out,
            1,
            "a warp completes this cycle (at most one)",
        ),
        port(
            "done_slot",
            Dir::Out,
            w.slot,
            "warp-buffer slot of the completed warp",
        ),
        port(
            "done_parked",
            Dir::Out,
            n,
            "per lane: the ray stopped at a treelet boundary rather than finishing",
        ),
    ]);
    ports.extend(ray_state_ports("done", Dir::Out, cfg, w));
    ports.extend([
        port("boundary_valid", Dir::Out, n, "per lane: the ray reached a treelet boundary this cycle"),
        port("boundary_slot", Dir::Out, w.slot, "slot of the rays reaching a boundary (the slot whose response was popped)"),
        port("boundary_ray_id", Dir::Out, n * w.ray_id, "per lane: ray id"),
        port("boundary_treelet", Dir::Out, n * w.treelet, "per lane: treelet the ray needs next"),
        port("released_valid", Dir::Out, 1, "a repack released finished lanes this cycle (their hit records are already stored)"),
        port("released_slot", Dir::Out, w.slot, "slot of the released lanes"),
        port("released_mask", Dir::Out, n, "per lane: released"),
        port("errors", Dir::Out, errors::BITS, "sticky protocol errors: issue while full, bad issue, FIFO overflow, unmatched response, stack spill area full, bad child, bad controller command"),
        port("error_valid", Dir::Out, 1, "an error was captured (first error, sticky)"),
        port("error_kind", Dir::Out, 3, "first error: bit index of its flag in errors"),
        port("error_slot", Dir::Out, w.slot, "first error: warp-buffer slot"),
        port("error_lane", Dir::Out, w.lane, "first error: lane"),
        port("error_ray_id", Dir::Out, w.ray_id, "first error: ray id"),
        port("error_value", Dir::Out, 64, "first error: the value needed or seen"),
        port("error_limit", Dir::Out, 64, "first error: the limit it broke"),
    ]);

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
    ports.extend(count_ports(w));

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

/// Ports carrying every lane's ray state (ray load at issue, ray write-back at completion).
fn ray_state_ports(
    prefix: &str,
    dir: Dir,
    cfg: &HwConfig,
    w: &Widths,
) -> Vec<crate::describe::PortDesc> {
    let n = cfg.warp_size;
    let entry = NodeEntry::bits(cfg.address_bits);
    let sp = bits_for(cfg.stack_depth as u64);
    let p = |name: &str, width: u32, doc: &str| port(&format!("{prefix}_{name}"), dir, width, doc);
    vec![
        p("active", n, "per lane: the lane holds a ray"),
        p("ray_id", n * w.ray_id, "per lane: ray id"),
        p("ray_words", n * RAY_WORDS as u32 * 32, "per lane: origin, direction, tmin, tmax (f32 bits)"),
        p("hit_valid", n, "per lane: the ray has a hit"),
        p("hit", n * HIT_BITS, "per lane: closest hit t, hit id, two attributes"),
        p("cur_treelet", n * w.treelet, "per lane: current treelet"),
        p("cur_sp", n * sp, "per lane: current-treelet stack depth"),
        p("other_sp", n * sp, "per lane: other-treelet stack depth"),
        p("cur_spilled", n * w.spilled, "per lane: current-treelet stack chunks in the spill area"),
        p("other_spilled", n * w.spilled, "per lane: other-treelet stack chunks in the spill area"),
        p("cur_stack", n * cfg.stack_depth * entry, "per lane: current-treelet stack entries, bottom first (parallel load of the ray state)"),
        p("other_stack", n * cfg.stack_depth * entry, "per lane: other-treelet stack entries, bottom first"),
    ]
}

/// Fields of a stack entry, most significant first.
fn entry_fields(address_bits: u32) -> Vec<(String, u32)> {
    vec![
        ("address".into(), address_bits),
        ("kind".into(), NodeKind::BITS),
        ("chunks_minus_1".into(), 2),
    ]
}

/// The four 64-bit words of a 32 B chunk, lowest bytes first.
fn data_words(data: &[u8; CHUNK_BYTES as usize]) -> [u64; 4] {
    let mut out = [0u64; 4];
    for (o, b) in out.iter_mut().zip(data.chunks_exact(8)) {
        let mut bytes = [0u8; 8];
        bytes.copy_from_slice(b);
        *o = u64::from_le_bytes(bytes);
    }
    out
}

fn push_data(v: &mut Vec<Signal>, name: &str, data: Option<&[u8; CHUNK_BYTES as usize]>) {
    let words = data.map(data_words).unwrap_or_default();
    for (k, word) in words.into_iter().enumerate() {
        v.push(Signal::new(format!("{name}_{k}"), 64, word));
    }
}

fn mask(bits: impl Iterator<Item = bool>) -> u64 {
    bits.enumerate().fold(0, |m, (i, b)| m | ((b as u64) << i))
}

impl Signals for RtUnitInputs {
    fn signals(&self) -> Vec<Signal> {
        let w = &self.widths;
        let lanes = self.issue.as_ref().map(|i| &i.lanes[..]).unwrap_or(&[]);
        let lane = |i: usize| lanes.get(i).and_then(|l| l.as_ref());
        let mut v = vec![
            Signal::new("issue_valid", 1, self.issue.is_some() as u64),
            Signal::new(
                "issue_order",
                TraversalOrder::BITS,
                self.issue.as_ref().map_or(0, |i| i.order.code()),
            ),
            Signal::new(
                "issue_target",
                IssueTarget::BITS,
                self.issue.as_ref().map_or(0, |i| i.target.code()),
            ),
            Signal::new(
                "issue_slot",
                w.slot,
                self.issue.as_ref().map_or(0, |i| i.target.slot() as u64),
            ),
            Signal::new(
                "issue_last",
                1,
                self.issue
                    .as_ref()
                    .is_some_and(|i| matches!(i.target, IssueTarget::Append { last: true, .. }))
                    as u64,
            ),
            Signal::new("stop_valid", 1, self.stop.is_some() as u64),
            Signal::new("stop_slot", w.slot, self.stop.unwrap_or(0) as u64),
            Signal::new("repack_valid", 1, self.repack.is_some() as u64),
            Signal::new("repack_slot", w.slot, self.repack.unwrap_or(0) as u64),
            Signal::new(
                "issue_active",
                w.warp_size,
                mask((0..w.warp_size as usize).map(|i| lane(i).is_some())),
            ),
        ];
        for i in 0..w.warp_size as usize {
            v.push(Signal::new(
                format!("issue_ray_id_{i}"),
                w.ray_id,
                lane(i).map_or(0, |r| r.ray_id as u64),
            ));
        }
        for k in 0..w.resp_ports as usize {
            let r: Option<&MemResponse> = self.responses.get(k);
            v.push(Signal::new(format!("resp{k}_valid"), 1, r.is_some() as u64));
            v.push(Signal::new(
                format!("resp{k}_address"),
                w.address,
                r.map_or(0, |r| r.address),
            ));
            v.push(Signal::new(
                format!("resp{k}_tag"),
                w.tag,
                r.map_or(0, |r| r.tag as u64),
            ));
            push_data(&mut v, &format!("resp{k}_data"), r.map(|r| &r.data));
        }
        v
    }
}

impl Signals for RtUnitOutputs {
    fn signals(&self) -> Vec<Signal> {
        let w = &self.widths;
        let n = w.warp_size as usize;
        let req: Option<&MemRequest> = self.request.as_ref();
        let mut v = vec![
            Signal::new("issue_ready", 1, self.issue_ready as u64),
            Signal::new("resp_free", w.fifo_count, self.resp_free as u64),
            Signal::new("req_valid", 1, req.is_some() as u64),
            Signal::new("req_address", w.address, req.map_or(0, |r| r.address)),
            Signal::new("req_size", SIZE_BITS, req.map_or(0, |_| CHUNK_BYTES as u64)),
            Signal::new(
                "req_kind",
                RequestKind::BITS,
                req.map_or(0, |r| r.kind.code()),
            ),
            Signal::new("req_tag", w.tag, req.map_or(0, |r| r.tag as u64)),
        ];
        push_data(
            &mut v,
            "req_data",
            req.filter(|r| r.is_store()).map(|r| &r.data),
        );
        let done_lanes = self.done.as_ref().map(|d| &d.lanes[..]).unwrap_or(&[]);
        let done_lane = |i: usize| done_lanes.get(i).and_then(|l| l.as_ref());
        v.push(Signal::new("done_valid", 1, self.done.is_some() as u64));
        v.push(Signal::new(
            "done_slot",
            w.slot,
            self.done.as_ref().map_or(0, |d| d.slot as u64),
        ));
        v.push(Signal::new(
            "done_active",
            w.warp_size,
            mask((0..n).map(|i| done_lane(i).is_some())),
        ));
        v.push(Signal::new(
            "done_parked",
            w.warp_size,
            mask((0..n).map(|i| {
                done_lane(i).is_some_and(|(_, o)| *o != super::bundles::RayOutcome::Finished)
            })),
        ));
        for i in 0..n {
            v.push(Signal::new(
                format!("done_ray_id_{i}"),
                w.ray_id,
                done_lane(i).map_or(0, |(r, _)| r.ray_id as u64),
            ));
        }
        let event = |i: usize| self.boundary.iter().find(|e| e.lane as usize == i);
        v.push(Signal::new(
            "boundary_valid",
            w.warp_size,
            mask((0..n).map(|i| event(i).is_some())),
        ));
        v.push(Signal::new(
            "boundary_slot",
            w.slot,
            self.boundary.first().map_or(0, |e| e.slot as u64),
        ));
        for i in 0..n {
            v.push(Signal::new(
                format!("boundary_ray_id_{i}"),
                w.ray_id,
                event(i).map_or(0, |e| e.ray_id as u64),
            ));
        }
        for i in 0..n {
            v.push(Signal::new(
                format!("boundary_treelet_{i}"),
                w.treelet,
                event(i).map_or(0, |e| e.treelet),
            ));
        }
        let released = self.released.as_ref();
        v.push(Signal::new("released_valid", 1, released.is_some() as u64));
        v.push(Signal::new(
            "released_slot",
            w.slot,
            released.map_or(0, |d| d.slot as u64),
        ));
        v.push(Signal::new(
            "released_mask",
            w.warp_size,
            mask(
                (0..n)
                    .map(|i| released.is_some_and(|d| d.lanes.get(i).is_some_and(Option::is_some))),
            ),
        ));
        v.push(Signal::new("errors", errors::BITS, self.errors as u64));
        let e = self.first_error.as_ref();
        v.extend([
            Signal::new("error_valid", 1, e.is_some() as u64),
            Signal::new("error_kind", 3, e.map_or(0, |e| e.kind.code())),
            Signal::new("error_slot", w.slot, e.map_or(0, |e| e.slot as u64)),
            Signal::new("error_lane", w.lane, e.map_or(0, |e| e.lane as u64)),
            Signal::new("error_ray_id", w.ray_id, e.map_or(0, |e| e.ray_id as u64)),
            Signal::new("error_value", 64, e.map_or(0, |e| e.value)),
            Signal::new("error_limit", 64, e.map_or(0, |e| e.limit)),
        ]);
        for (name, width, value, _) in counts(w, &self.counts) {
            v.push(Signal::new(name, width, value));
        }
        v
    }
}

impl Signals for RtUnitRegs {
    fn signals(&self) -> Vec<Signal> {
        let w = &self.widths;
        let mut v = Vec::new();
        for (s, slot) in self.slots.iter().enumerate() {
            v.push(Signal::new(format!("slot_valid_{s}"), 1, slot.valid as u64));
            v.push(Signal::new(
                format!("slot_order_{s}"),
                TraversalOrder::BITS,
                slot.order.code(),
            ));
            v.push(Signal::new(format!("slot_held_{s}"), 1, slot.held as u64));
        }
        for k in 0..self.slots.len() {
            v.push(Signal::new(
                format!("age_order_{k}"),
                w.slot,
                self.age.get(k).map_or(0, |&s| s as u64),
            ));
        }
        v.push(Signal::new(
            "age_count",
            bits_for(self.slots.len() as u64),
            self.age.len() as u64,
        ));
        let split = self.split.as_ref();
        v.extend([
            Signal::new("split_valid", 1, split.is_some() as u64),
            Signal::new("split_tag", w.tag, split.map_or(0, |s| s.tag as u64)),
            Signal::new(
                "split_node",
                NodeEntry::bits(w.address),
                split.map_or(0, |s| s.node.encode()),
            ),
            Signal::new("split_chunk", 2, split.map_or(0, |s| s.next_chunk as u64)),
            Signal::new("fifo_count", w.fifo_count, self.fifo.len() as u64),
            Signal::new("errors", errors::BITS, self.errors as u64),
        ]);
        for (s, slot) in self.slots.iter().enumerate() {
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
}

/// The statistics-event output ports: this cycle's increments of the counters an observer
/// beside the block keeps ([`RtStats`]), each with the name, width and value of its signal.
fn counts(w: &Widths, c: &RtStats) -> Vec<(&'static str, u32, u64, &'static str)> {
    let lanes = bits_for(w.warp_size as u64);
    let all_lanes = bits_for(w.warp_size as u64 * w.slots as u64);
    vec![
        (
            "count_warps",
            bits_for(w.slots as u64),
            c.warp_cycles,
            "valid warps this cycle (warp cycles)",
        ),
        (
            "count_active",
            all_lanes,
            c.active_thread_cycles,
            "traversing lanes of the valid warps this cycle (active-thread cycles)",
        ),
        (
            "count_request",
            1,
            c.requests,
            "a node-chunk load was requested",
        ),
        (
            "count_store",
            1,
            c.stores,
            "a hit-record store was requested",
        ),
        (
            "count_spill",
            1,
            c.stack_spills,
            "a stack spill was requested",
        ),
        ("count_fill", 1, c.stack_fills, "a stack fill was requested"),
        (
            "count_merged",
            lanes,
            c.merged,
            "lanes served by the leader's request (merged)",
        ),
        (
            "count_tests_header",
            lanes,
            c.tests[0],
            "header tests completed",
        ),
        (
            "count_tests_internal",
            lanes,
            c.tests[1],
            "internal-node tests completed",
        ),
        (
            "count_tests_instance_leaf",
            lanes,
            c.tests[2],
            "instance-leaf tests completed",
        ),
        (
            "count_tests_primitive_descriptor",
            lanes,
            c.tests[3],
            "primitive-descriptor tests completed",
        ),
        (
            "count_tests_triangle_leaf",
            lanes,
            c.tests[4],
            "triangle-leaf tests completed",
        ),
        (
            "count_tests_procedural",
            lanes,
            c.tests[5],
            "procedural tests completed",
        ),
        (
            "count_hits",
            lanes,
            c.hits,
            "triangle tests that produced a new closest hit",
        ),
        ("count_warp_done", 1, c.warps_done, "a warp completed"),
    ]
}

/// The statistics-event ports of [`counts`] as port descriptions.
fn count_ports(w: &Widths) -> Vec<crate::describe::PortDesc> {
    counts(w, &RtStats::default())
        .into_iter()
        .map(|(name, width, _, doc)| port(name, Dir::Out, width, doc))
        .collect()
}
