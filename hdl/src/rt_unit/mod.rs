//! The RT unit's control (paper section 2.2, Figure 3; section 4.2, Figure 8): the warp buffer
//! with per-ray traversal state, the memory scheduler, the response FIFO and warp completion.
//!
//! The intersection datapath is not part of this block: it is a pure function supplied as the
//! type parameter `D: NodeDatapath` at construction, called when the last chunk of a node has
//! arrived; its result (children to push, a candidate hit, kept only when its `(t, hit id)` is
//! lexicographically smaller than the lane's hit so far, so ties go to the smaller primitive id
//! whatever the visiting order) is written back at once and the lane's
//! intersection-delay counter is loaded with the test's latency ([`Latencies`]), which holds the
//! lane's next fetch back. Node bytes reach the block only through the response input port, so
//! [`Block::eval`] stays a pure function of registers and inputs.
//!
//! # One cycle
//! The stages run in this order on the next cycle's copy of the registers, so a later stage
//! sees an earlier one's writes. The issue takes a slot free at the start of the cycle and the
//! FIFO accepts responses up to its free entries at the start of the cycle; the treelet
//! controller's commands (stop, repack, after stage 7's issue) act on the lanes as this cycle's
//! completion and delivery leave them (a warp that completed is not repacked; a lane whose node
//! arrived and emptied its current stack parks at a stop) — combinational paths an RTL of the
//! block must have too:
//! 1. statistics: every valid warp adds one warp cycle and its traversing lanes;
//! 2. completion: the oldest warp whose lanes are all inactive/done/parked with no node in
//!    flight, no delay and no store pending leaves (at most one per cycle);
//! 3. memory scheduler, at most one 32 B request: the next chunk of the node being requested,
//!    else a pending hit-record store (oldest warp, lowest lane), else the next node of the
//!    lowest ready lane of the oldest warp with a ready lane, merged with every ready lane of
//!    that warp whose next node has the same address and size (never across warps);
//! 4. every intersection delay above 0 counts down by one;
//! 5. the head of the response FIFO is popped and delivered to the lanes waiting for it; a
//!    lane whose node is complete runs its test (delay := latency);
//! 6. this cycle's responses enter the FIFO (registered: popped from the next cycle on);
//! 7. an issued warp is written into the lowest slot that was free at the start of the cycle.
//!
//! So a node whose last chunk is popped in cycle `t` with test latency `L` lets the ray request
//! its next node in cycle `t + L + 1` at the earliest.
//!
//! # Stack spilling
//! Each lane's stacks hold at most `stack_depth` entries on chip; older entries live in the
//! ray's spill area in memory (`stack_spill_chunks` 32 B chunks per stack at
//! `stack_base + ((ray_id * 2 + stack) * stack_spill_chunks + k) * 32`, four entries per chunk,
//! bottom first). Before a ray fetches its next node it makes sure that, once that node is
//! popped, every stack that may receive the node's children has room for `max_children` more:
//! otherwise its request this cycle is a *spill*, a 32 B store of up to four of that stack's
//! oldest on-chip entries (never the entry about to be popped). When the stack to pop from is
//! empty on chip but has chunks in memory, the request is a *fill*: a 32 B load of the most
//! recently spilled chunk, whose entries become the on-chip stack when the response is popped.
//! So the on-chip stacks never overflow, and a ray's stack can grow as deep as its spill area.
//! Spills and fills compete with node fetches as the lane's one request; they are not merged.
//! A ray whose current stack is empty and whose other stack's top is in memory reports its
//! treelet boundary when the fill brings that top back.
//!
//! # Traversal order
//! The two-stack treelet order (the treelet-prefetching code of Chou et al., MICRO 2023): a
//! child in the ray's current treelet
//! (address >> log2(treelet_bytes)) goes on the current stack, any other child on the
//! other-treelet stack; children are pushed so that the first in visit order is on top. When the
//! current stack is empty the top of the other stack is popped and its treelet becomes the
//! current treelet. A test that empties the current stack while the other stack is not empty is
//! a treelet boundary: a [`BoundaryEvent`] reports the treelet needed next, and under
//! [`TraversalOrder::TreeletStop`] the ray stops ([`RayOutcome::AtBoundary`]). The single-stack
//! [`TraversalOrder::RayStationary`] order pushes every child on the current stack.
//!
//! # Definition and fast path
//! [`Block::eval`] is the definition: a pure function of the registers and inputs. It builds
//! the lane summaries of an [`RtCache`] (bit masks of each slot's lane predicates, a pure
//! function of the registers) and runs the cycle on a copy of the registers.
//! [`Cached::step_cached`] runs the same cycle in place with a cache kept up to date across
//! cycles by its owner (the simulator), so that completion, scheduling, the delay countdown,
//! response delivery, [`Skip::idle_cycles`] and [`RtUnit::slot_summary`] touch only the
//! lanes concerned; debug builds check the cache against the registers at every cached step
//! and tests check the fast path against `eval`.
//!
//! # Statistics
//! The block has no statistics registers: each cycle's increments leave on
//! [`RtUnitOutputs::counts`] ([`Skip::skip`] returns those of skipped idle cycles) and the
//! observer beside it sums them ([`RtStats::add`]).
//!
//! # Files
//! `ports` (the port bundles, declared once, and their widths), `bundles` (the registers and the
//! records that enter and leave the warp buffer), `node` (node references and the datapath
//! interface), `desc` (the description and the registers, declared once with their trace
//! signals); the cycle: `cycle` (the stages in order, issue, stop, repack, completion),
//! `scheduler` (the memory scheduler), `responses` (response delivery and the intersection
//! test), `status` (the register-only status ports and summaries); this file: parameters,
//! checks of issued warps and nodes, idle skipping, and the [`Block`] implementation.

mod bundles;
mod cycle;
mod desc;
mod event_ports;
mod node;
mod ports;
mod responses;
mod scheduler;
mod stack_layout;
mod status;

use bundles::{bits, LaneMasks};
pub use bundles::{
    errors, occupied, BoundaryEvent, ErrorKind, ErrorRecord, InFlight, IssueTarget, Lane,
    LaneStatus, LaneWrite, MemRequest, MemResponse, RayOutcome, RayRecord, RequestKind, RtCache,
    RtStats, RtUnitRegs, SlotSummary, Split, StackSel, TraversalOrder, WarpDone, WarpIssue,
    WarpSlot,
};
pub use event_ports::{RtCountPorts, RtCountWidths, RtErrorPorts, RtErrorWidths};
pub use node::{
    pack_spill_chunk, unpack_spill_chunk, Hit, Latencies, NoDatapath, NodeDatapath, NodeEntry,
    NodeKind, RayWords, TestResult, CHUNK_BYTES, CHUNK_MASK, MAX_NODE_CHUNKS, RAY_WORDS,
    STACK_ENTRIES_PER_CHUNK, TMAX_WORD, TMIN_WORD,
};
pub(crate) use ports::{data_word, ray_state, ray_state_words, HIT_BITS};
pub use ports::{RtUnitInputs, RtUnitOutputs, RtUnitStatus, SlotStatus, StatusSelect, Widths};
pub use stack_layout::StackLayout;

use crate::bits::{bits_for, clog2};
use crate::block::{Block, Cached, Signal, Skip};
use crate::bounded::{BoundedDeque, BoundedVec};
use crate::config::{ConfigError, HwConfig};
use crate::describe::BlockDesc;
use serde::{Deserialize, Serialize};

/// Bad configuration, parameter, node or issued warp for the RT unit.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RtUnitError {
    /// The hardware configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A parameter of [`RtUnitParams`] is out of range.
    #[error("invalid RT unit parameter {name} = {value}: {reason}")]
    BadParam {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: u64,
        /// Why it is rejected.
        reason: String,
    },
    /// A node reference cannot be held by the hardware.
    #[error("invalid node at address {address:#x}: {reason}")]
    BadNode {
        /// The node's address.
        address: u64,
        /// What is wrong with it.
        reason: String,
    },
    /// An issued warp cannot be loaded into the warp buffer.
    #[error("invalid warp issue (lane {lane}): {reason}")]
    BadIssue {
        /// Offending lane (0 when the whole warp is malformed).
        lane: u32,
        /// What is wrong.
        reason: String,
    },
}

/// Parameters of the RT unit that are not in [`HwConfig`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RtUnitParams {
    /// Intersection latencies per node kind.
    pub latencies: Latencies,
    /// Entries of the response FIFO.
    pub resp_fifo_depth: u32,
    /// Responses memory may deliver per cycle (L1 hit return and miss fill).
    pub resp_ports: u32,
    /// Byte address of ray 0's 32 B hit record; ray `r`'s is at `hit_record_base + 32 r`.
    pub hit_record_base: u64,
    /// Most children a node test returns (the BVH width): the stack room kept free before a
    /// fetch. At most `stack_depth`.
    pub max_children: u32,
    /// Byte address of the stack spill area (32 B aligned): `stack_spill_chunks` chunks per
    /// stack of each of `max_rays` rays. `None`: the area ends at the top of the address space
    /// ([`spill_area`] gives the resolved range).
    pub stack_base: Option<u64>,
    /// 32 B chunks of spilled entries each stack of each ray may hold in memory (at least 1).
    pub stack_spill_chunks: u32,
}

impl Default for RtUnitParams {
    fn default() -> Self {
        RtUnitParams {
            latencies: Latencies::default(),
            resp_fifo_depth: 8,
            resp_ports: 2,
            hit_record_base: 0,
            max_children: 8,
            stack_base: None,
            stack_spill_chunks: 16,
        }
    }
}

/// Checks `cfg` and `params` and derives the bundle widths from them.
fn checked_widths(cfg: &HwConfig, params: &RtUnitParams) -> Result<Widths, RtUnitError> {
    cfg.validate()?;
    params.latencies.validate()?;
    let bad = |name, value: u64, reason: &str| RtUnitError::BadParam {
        name,
        value,
        reason: reason.to_string(),
    };
    if !(1..=1024).contains(&params.resp_fifo_depth) {
        return Err(bad(
            "resp_fifo_depth",
            params.resp_fifo_depth as u64,
            "must be 1..=1024",
        ));
    }
    if !(1..=8).contains(&params.resp_ports) {
        return Err(bad("resp_ports", params.resp_ports as u64, "must be 1..=8"));
    }
    let records_end = params.hit_record_base + cfg.max_rays as u64 * CHUNK_BYTES as u64;
    if params.hit_record_base & CHUNK_MASK != 0 || records_end > 1 << cfg.address_bits {
        return Err(bad(
            "hit_record_base",
            params.hit_record_base,
            "must be 32 B aligned with max_rays hit records inside the address space",
        ));
    }
    if !(1..=64).contains(&params.max_children) || params.max_children > cfg.stack_depth {
        return Err(bad(
            "max_children",
            params.max_children as u64,
            &format!(
                "must be 1..=64 and at most stack_depth ({}): a stack must hold one node's children",
                cfg.stack_depth
            ),
        ));
    }
    if !(1..=1 << 24).contains(&params.stack_spill_chunks) {
        return Err(bad(
            "stack_spill_chunks",
            params.stack_spill_chunks as u64,
            "must be 1..=16777216",
        ));
    }
    let (stack_base, spill_end) = spill_area(cfg, params);
    let spill_bytes = spill_end.wrapping_sub(stack_base);
    let overlaps_records = stack_base < records_end && params.hit_record_base < spill_end;
    if stack_base & CHUNK_MASK != 0
        || spill_end > 1 << cfg.address_bits
        || spill_end < stack_base
        || overlaps_records
    {
        return Err(bad(
            "stack_base",
            stack_base,
            &format!(
                "must be 32 B aligned with the {spill_bytes}-byte stack spill area inside the \
                 address space and apart from the hit records"
            ),
        ));
    }
    let slot = clog2(cfg.warp_buffer_size as u64);
    let lane = cfg.lane_bits();
    Ok(Widths {
        warp_size: cfg.warp_size,
        slots: cfg.warp_buffer_size,
        resp_ports: params.resp_ports,
        ray_id: cfg.ray_id_bits(),
        address: cfg.address_bits,
        treelet: cfg.treelet_addr_bits(),
        lane,
        slot,
        tag: slot + lane,
        fifo_count: bits_for(params.resp_fifo_depth as u64),
        delay: bits_for(params.latencies.max() as u64),
        spilled: bits_for(params.stack_spill_chunks as u64),
        stack_depth: cfg.stack_depth,
        stack_pointer: bits_for(cfg.stack_depth as u64),
        record_stack: cfg.record_stack_entries,
        record_pointer: bits_for(cfg.record_stack_entries as u64),
    })
}

/// The byte range `[start, end)` of the stack spill area for `cfg` and `params`: `max_rays` x 2
/// stacks x `stack_spill_chunks` chunks of 32 B from `stack_base`, or ending at the top of the
/// address space when `stack_base` is `None`. Saturating: [`RtUnit::new`] rejects an area that
/// does not fit.
pub fn spill_area(cfg: &HwConfig, params: &RtUnitParams) -> (u64, u64) {
    let bytes = (cfg.max_rays as u64 * 2)
        .saturating_mul(params.stack_spill_chunks as u64)
        .saturating_mul(CHUNK_BYTES as u64);
    let top = 1u64 << cfg.address_bits.min(63);
    let start = params.stack_base.unwrap_or(top.saturating_sub(bytes));
    (start, start.saturating_add(bytes))
}

/// A ready lane's request this cycle (see the module documentation, "Stack spilling").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LaneAction {
    /// Fetch this node (popping it).
    Fetch(NodeEntry),
    /// Store this many of the stack's oldest on-chip entries to its spill area.
    Spill(StackSel, usize),
    /// Load the stack's most recently spilled chunk back.
    Fill(StackSel),
}

/// Sets `kind`'s flag in `flags` and captures `record` if it is the first error.
fn raise(flags: &mut u8, first: &mut Option<ErrorRecord>, record: ErrorRecord) {
    *flags |= record.kind.flag();
    first.get_or_insert(record);
}

/// An error record of `kind` with no location.
fn record(kind: ErrorKind, value: u64, limit: u64) -> ErrorRecord {
    ErrorRecord {
        kind,
        slot: 0,
        lane: 0,
        ray_id: 0,
        value,
        limit,
    }
}

/// The RT unit control block, generic over the intersection datapath `D`.
#[derive(Debug, Clone)]
pub struct RtUnit<D> {
    cfg: HwConfig,
    params: RtUnitParams,
    datapath: D,
    widths: Widths,
    treelet_shift: u32,
    /// The stack spill area, `[start, end)` ([`spill_area`]).
    spill: (u64, u64),
}

impl<D: NodeDatapath> RtUnit<D> {
    /// An RT unit for `cfg` and `params` testing nodes with `datapath`; checks both.
    pub fn new(cfg: HwConfig, params: RtUnitParams, datapath: D) -> Result<Self, RtUnitError> {
        let widths = checked_widths(&cfg, &params)?;
        let treelet_shift = clog2(cfg.treelet_bytes as u64);
        let spill = spill_area(&cfg, &params);
        Ok(RtUnit {
            cfg,
            params,
            datapath,
            widths,
            treelet_shift,
            spill,
        })
    }

    /// The hardware configuration.
    pub fn config(&self) -> &HwConfig {
        &self.cfg
    }

    /// The RT-unit parameters.
    pub fn params(&self) -> &RtUnitParams {
        &self.params
    }

    /// Field widths of the bundles.
    pub fn widths(&self) -> Widths {
        self.widths
    }

    /// The summary of slot `slot` for the treelet controller's reports (`None` for an empty or
    /// nonexistent slot); the distinct next treelets are counted only with `distinct` (0
    /// otherwise), as only initial-phase divergence reports need them.
    pub fn slot_summary(
        &self,
        regs: &RtUnitRegs,
        cache: &RtCache,
        slot: u32,
        distinct: bool,
    ) -> Option<SlotSummary> {
        let s = regs.slots.get(slot as usize).filter(|s| s.valid)?;
        let m = &cache.masks[slot as usize];
        let not_quiet = m.busy();
        let mut found = 0;
        if distinct {
            // At most warp_size distinct treelets: a fixed bank, searched linearly (filled only
            // when asked for: clearing it costs more than the rest of the summary).
            let mut treelets = [0u64; 64];
            for l in bits(m.traversing) {
                if let Some(n) = s.lanes[l].ray.next_node() {
                    let t = self.treelet_of(n.address);
                    if !treelets[..found].contains(&t) && found < treelets.len() {
                        treelets[found] = t;
                        found += 1;
                    }
                }
            }
        }
        Some(SlotSummary {
            traversing: m.traversing.count_ones(),
            busy: crate::warp_repacking::kept_lanes(m.traversing, m.parked, m.done, not_quiet)
                .count_ones(),
            distinct_next_treelets: found as u32,
            quiescent: not_quiet == 0,
        })
    }

    /// Entries of its other stack a parked lane keeps on chip (`hw.record_stack_entries`).
    pub(crate) fn keep(&self) -> usize {
        self.cfg.record_stack_entries as usize
    }

    /// Treelet of a byte address (address >> log2(treelet_bytes)).
    pub fn treelet_of(&self, address: u64) -> u64 {
        address >> self.treelet_shift
    }

    /// The `resp_free` output for these registers (free response-FIFO entries).
    pub(crate) fn resp_free(&self, regs: &RtUnitRegs) -> u32 {
        self.params.resp_fifo_depth - regs.fifo.len() as u32
    }

    /// Checks that the hardware can hold `node`: 1..=4 chunks, 32 B aligned, inside the
    /// address space.
    pub fn check_node(&self, node: &NodeEntry) -> Result<(), RtUnitError> {
        let bad = |reason: String| RtUnitError::BadNode {
            address: node.address,
            reason,
        };
        if node.chunks == 0 || node.chunks as usize > MAX_NODE_CHUNKS {
            return Err(bad(format!("{} chunks is not 1..=4", node.chunks)));
        }
        if node.address & CHUNK_MASK != 0 {
            return Err(bad("address is not 32 B aligned".into()));
        }
        if node.address + node.bytes() as u64 > 1 << self.cfg.address_bits {
            return Err(bad(format!(
                "node ends beyond the {}-bit address space",
                self.cfg.address_bits
            )));
        }
        Ok(())
    }

    /// Checks that `issue` fits the warp buffer: `warp_size` lanes, ray ids below `max_rays`,
    /// treelet numbers in range, stacks no deeper than a record carries
    /// (`record_stack_entries`), valid nodes.
    pub fn check_issue(&self, issue: &WarpIssue) -> Result<(), RtUnitError> {
        let bad = |lane: usize, reason: String| RtUnitError::BadIssue {
            lane: lane as u32,
            reason,
        };
        if issue.lanes.len() != self.cfg.warp_size as usize {
            return Err(bad(
                0,
                format!(
                    "{} lanes, expected warp_size = {}",
                    issue.lanes.len(),
                    self.cfg.warp_size
                ),
            ));
        }
        self.check_lanes(issue.lanes.iter().map(Option::as_ref))
    }

    /// Checks the records on the issue bus, lane by lane (`None`: the lane carries none): ray
    /// ids below `max_rays`, treelet numbers in range, stacks no deeper than a record carries,
    /// valid nodes. The error names the lowest bad lane.
    pub fn check_lanes<'a>(
        &self,
        lanes: impl Iterator<Item = Option<&'a RayRecord>>,
    ) -> Result<(), RtUnitError> {
        let bad = |lane: usize, reason: String| RtUnitError::BadIssue {
            lane: lane as u32,
            reason,
        };
        for (i, ray) in lanes.enumerate() {
            let Some(ray) = ray else { continue };
            if ray.ray_id >= self.cfg.max_rays {
                return Err(bad(
                    i,
                    format!("ray id {} >= max_rays {}", ray.ray_id, self.cfg.max_rays),
                ));
            }
            if ray.current_treelet >> self.widths.treelet != 0 {
                return Err(bad(
                    i,
                    format!(
                        "treelet {} does not fit in {} bits",
                        ray.current_treelet, self.widths.treelet
                    ),
                ));
            }
            for s in [StackSel::Current, StackSel::Other] {
                if ray.spilled(s) > self.params.stack_spill_chunks {
                    return Err(bad(
                        i,
                        format!(
                            "{} stack has {} chunks spilled, stack_spill_chunks is {}",
                            s.name(),
                            ray.spilled(s),
                            self.params.stack_spill_chunks
                        ),
                    ));
                }
            }
            for (name, stack) in [("current", &ray.current_stack), ("other", &ray.other_stack)] {
                if stack.len() > self.keep() {
                    return Err(bad(
                        i,
                        format!(
                            "{name} stack holds {} entries, a record carries at most \
                             record_stack_entries = {}",
                            stack.len(),
                            self.cfg.record_stack_entries
                        ),
                    ));
                }
                for node in stack {
                    self.check_node(node).map_err(|e| bad(i, e.to_string()))?;
                }
            }
        }
        Ok(())
    }
}

/// The lane masks of each slot ([`RtCache`]).
impl<D: NodeDatapath> Cached for RtUnit<D> {
    type Cache = RtCache;

    /// The simulation cache of `regs` ([`RtCache::of`] with this unit's configuration).
    fn cache(&self, regs: &RtUnitRegs) -> RtCache {
        RtCache::of(regs, self.keep())
    }

    /// One cycle in place with `cache` kept up to date (the simulator's fast path): the same
    /// outputs and next registers as [`Block::eval`], without copying the warp buffer. `cache`
    /// must be the cache of `regs` ([`RtCache::of`]; debug builds check it).
    fn step_cached(
        &self,
        regs: &mut RtUnitRegs,
        cache: &mut RtCache,
        inputs: &RtUnitInputs,
    ) -> RtUnitOutputs {
        debug_assert!(
            cache.consistent(regs),
            "stale RT-unit cache: it must follow every change of the registers"
        );
        self.update(regs, cache, inputs)
    }
}

/// Delays counting down: the cycles until the first delayed lane's test, while nothing else
/// has work.
impl<D: NodeDatapath> Skip for RtUnit<D> {
    type Counts = RtStats;

    /// Cycles from now in which the unit, given idle inputs (no issue, no responses), does
    /// nothing visible outside its statistics and delay counters: no request, no completion,
    /// no response pop, no test. `u64::MAX` when it waits only for responses (or is empty).
    /// Lets a simulator skip those cycles with [`Skip::skip`].
    fn idle_cycles(&self, regs: &RtUnitRegs, cache: &RtCache) -> u64 {
        if !regs.fifo.is_empty() || regs.split.is_some() {
            return 0;
        }
        let mut idle = u64::MAX;
        for &s in &regs.age {
            let slot = &regs.slots[s as usize];
            let m = &cache.masks[s as usize];
            if (!slot.held && m.busy() == 0) || m.store | m.ready() != 0 {
                return 0;
            }
            for l in bits(m.delayed) {
                idle = idle.min(slot.lanes[l].delay as u64);
            }
        }
        idle
    }

    /// Advances the registers (and their cache) by `n` cycles with idle inputs, exactly as
    /// `n` cached steps would, provided `n <= idle_cycles`: the delays count down by `n`.
    /// Returns the statistics increments of those cycles (`n` warp cycles per resident warp
    /// and its traversing lanes). Panics in debug builds when `n` exceeds
    /// [`Skip::idle_cycles`].
    fn skip(&self, regs: &mut RtUnitRegs, cache: &mut RtCache, n: u64) -> RtStats {
        debug_assert!(
            n <= self.idle_cycles(regs, cache),
            "skip beyond the idle cycles"
        );
        let mut counts = RtStats::default();
        if n == 0 {
            return counts;
        }
        for (slot, m) in regs.slots.iter_mut().zip(&mut cache.masks) {
            if !slot.valid {
                continue;
            }
            counts.warp_cycles += n;
            counts.active_thread_cycles += n * u64::from(m.traversing.count_ones());
            counts.waiting_lane_cycles += n * u64::from((m.traversing & m.in_flight).count_ones());
            counts.done_lane_cycles += n * u64::from(m.done.count_ones());
            counts.parked_lane_cycles += n * u64::from(m.parked.count_ones());
            for l in bits(m.delayed) {
                let lane = &mut slot.lanes[l];
                lane.delay = (lane.delay as u64).saturating_sub(n) as u32;
                if lane.delay == 0 {
                    m.delayed &= !(1 << l);
                }
            }
        }
        counts
    }
}

/// Per slot its traversing lanes, and every traversing ray's next node address.
impl<D: NodeDatapath> crate::block::Taps for RtUnit<D> {
    /// Per warp-buffer slot, the rays traversing in it (`None` for a slot holding no warp): a
    /// register-only output, for observers that follow each warp (e.g. SIMT efficiency averaged
    /// per warp).
    fn slot_lanes<'a>(
        &self,
        regs: &'a RtUnitRegs,
        cache: &'a RtCache,
    ) -> impl Iterator<Item = Option<u32>> + 'a {
        regs.slots
            .iter()
            .zip(&cache.masks)
            .map(|(s, m)| s.valid.then(|| m.traversing.count_ones()))
    }

    /// The address of the next node of every traversing ray whose next node is on chip, slot by
    /// slot and lane by lane (the per-lane next-access wires a treelet prefetcher taps).
    fn next_addresses<'r>(
        &self,
        regs: &'r RtUnitRegs,
        cache: &'r RtCache,
    ) -> impl Iterator<Item = u64> + 'r {
        regs.slots
            .iter()
            .zip(&cache.masks)
            .filter(|(slot, _)| slot.valid)
            .flat_map(|(slot, m)| {
                bits(m.traversing).filter_map(|l| slot.lanes[l].ray.next_node().map(|n| n.address))
            })
    }
}

impl<D: NodeDatapath> Block for RtUnit<D> {
    type Inputs = RtUnitInputs;
    type Outputs = RtUnitOutputs;
    type Regs = RtUnitRegs;

    fn reset(&self) -> RtUnitRegs {
        let lanes = vec![Lane::default(); self.cfg.warp_size as usize];
        let slot = WarpSlot {
            valid: false,
            held: false,
            order: TraversalOrder::RayStationary,
            lanes: lanes.into_boxed_slice(),
        };
        RtUnitRegs {
            slots: vec![slot; self.cfg.warp_buffer_size as usize].into_boxed_slice(),
            age: BoundedVec::new(self.cfg.warp_buffer_size as usize),
            fifo: BoundedDeque::new(self.params.resp_fifo_depth as usize),
            split: None,
            errors: 0,
            first_error: None,
        }
    }

    /// Nothing issued, no responses, no command.
    fn idle_inputs(&self) -> RtUnitInputs {
        RtUnitInputs {
            widths: self.widths,
            issue: None,
            write: None,
            responses: Vec::new(),
            stop: None,
            repack: None,
        }
    }

    /// The definition: the cycle's seven stages ([`RtUnit::update`]) on a copy of the
    /// registers in `next`, with their freshly built cache. The stages run in order on that
    /// copy, each seeing the earlier ones' writes (the module documentation's "One cycle" says
    /// where that matters); their types do not separate start-of-cycle from next values.
    fn next_into(
        &self,
        regs: &RtUnitRegs,
        inputs: &RtUnitInputs,
        next: &mut RtUnitRegs,
    ) -> RtUnitOutputs {
        next.clone_from(regs);
        let mut cache = self.cache(regs);
        self.update(next, &mut cache, inputs)
    }

    fn reg_signals(&self, regs: &RtUnitRegs) -> Vec<Signal> {
        desc::registers(&self.cfg, &self.params, &self.widths).signals(regs)
    }

    fn describe(&self) -> BlockDesc {
        desc::describe(&self.cfg, &self.params, &self.widths)
    }

    fn debug_state(&self, regs: &RtUnitRegs) -> String {
        self.summary(regs, &self.cache(regs))
    }
}
