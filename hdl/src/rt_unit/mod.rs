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
//! All decisions use the register values at the start of the cycle:
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
//! # Traversal order
//! The two-stack treelet order (FACTS.md "Treelets"): a child in the ray's current treelet
//! (address >> log2(treelet_bytes)) goes on the current stack, any other child on the
//! other-treelet stack; children are pushed so that the first in visit order is on top. When the
//! current stack is empty the top of the other stack is popped and its treelet becomes the
//! current treelet. A test that empties the current stack while the other stack is not empty is
//! a treelet boundary: a [`BoundaryEvent`] reports the treelet needed next, and under
//! [`TraversalOrder::TreeletStop`] the ray stops ([`RayOutcome::AtBoundary`]). The single-stack
//! [`TraversalOrder::RayStationary`] order pushes every child on the current stack.
//!
//! # Lane summaries (simulation cache)
//! Each slot carries bit masks of its lanes' predicates (traversing, done, parked, store
//! pending, delay above 0, node in flight, next node present) and each in-flight lane's leader.
//! They are not registers: they are a pure function of the lanes, updated wherever a lane is
//! written, so that completion, scheduling, the delay countdown, response delivery,
//! [`RtUnit::idle_cycles`] and [`RtUnit::slot_summary`] touch only the lanes concerned instead
//! of scanning all of them. Code that writes lane registers directly must call
//! [`RtUnitRegs::refresh_summaries`] afterwards; debug builds check the summaries at the start
//! of every cycle.
//!
//! # Signals
//! Per-lane fields of a bus port appear in traces as `<port>_<lane>`, the 256-bit data buses as
//! `<port>_<k>` 64-bit words (`k` = 0 for the lowest bytes). Ray words and stack contents are
//! bulk data and are not traced.

mod bundles;
mod desc;
mod node;

use bundles::{bits, LaneMasks};
pub use bundles::{
    errors, BoundaryEvent, InFlight, IssueTarget, Lane, LaneStatus, MemRequest, MemResponse,
    RayOutcome, RayRecord, RtStats, RtUnitInputs, RtUnitOutputs, RtUnitRegs, SlotSummary, Split,
    TraversalOrder, WarpDone, WarpIssue, WarpSlot, Widths,
};
pub use node::{
    Hit, Latencies, NodeDatapath, NodeEntry, NodeKind, RayWords, TestResult, CHUNK_BYTES,
    CHUNK_MASK, MAX_NODE_CHUNKS, RAY_WORDS, TMAX_WORD, TMIN_WORD,
};

use crate::bits::{bits_for, clog2};
use crate::block::Block;
use crate::config::{ConfigError, HwConfig};
use crate::describe::BlockDesc;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

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
}

impl Default for RtUnitParams {
    fn default() -> Self {
        RtUnitParams {
            latencies: Latencies::default(),
            resp_fifo_depth: 8,
            resp_ports: 2,
            hit_record_base: 0,
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
    })
}

/// The RT unit's self-description for `cfg` and `params` (what `describe()` returns), without a
/// datapath: for the Verilog and area generators.
pub fn describe_rt_unit(cfg: &HwConfig, params: &RtUnitParams) -> Result<BlockDesc, RtUnitError> {
    Ok(desc::describe(cfg, params, &checked_widths(cfg, params)?))
}

/// The RT unit control block, generic over the intersection datapath `D`.
#[derive(Debug, Clone)]
pub struct RtUnit<D> {
    cfg: HwConfig,
    params: RtUnitParams,
    datapath: D,
    widths: Widths,
    treelet_shift: u32,
}

impl<D: NodeDatapath> RtUnit<D> {
    /// An RT unit for `cfg` and `params` testing nodes with `datapath`; checks both.
    pub fn new(cfg: HwConfig, params: RtUnitParams, datapath: D) -> Result<Self, RtUnitError> {
        let widths = checked_widths(&cfg, &params)?;
        let treelet_shift = clog2(cfg.treelet_bytes as u64);
        Ok(RtUnit {
            cfg,
            params,
            datapath,
            widths,
            treelet_shift,
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

    /// Inputs with nothing issued and no responses.
    pub fn idle_inputs(&self) -> RtUnitInputs {
        RtUnitInputs {
            widths: self.widths,
            issue: None,
            responses: Vec::new(),
            stop: None,
            repack: None,
        }
    }

    /// The summary of slot `slot` for the treelet controller's reports (`None` for an empty or
    /// nonexistent slot); the distinct next treelets are counted only with `distinct` (0
    /// otherwise), as only initial-phase divergence reports need them.
    pub fn slot_summary(
        &self,
        regs: &RtUnitRegs,
        slot: u32,
        distinct: bool,
    ) -> Option<SlotSummary> {
        let s = regs.slots.get(slot as usize).filter(|s| s.valid)?;
        let m = &s.masks;
        let not_quiet = m.busy();
        // At most warp_size distinct treelets: a fixed bank, searched linearly.
        let mut treelets = [0u64; 64];
        let mut found = 0;
        if distinct {
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
            // Traversing, parked, or done with something outstanding.
            busy: (m.traversing | m.parked | (m.done & not_quiet)).count_ones(),
            distinct_next_treelets: found as u32,
            quiescent: not_quiet == 0,
        })
    }

    /// Treelet of a byte address (address >> log2(treelet_bytes)).
    pub fn treelet_of(&self, address: u64) -> u64 {
        address >> self.treelet_shift
    }

    /// The `issue_ready` output for these registers (a slot is free).
    pub fn issue_ready(&self, regs: &RtUnitRegs) -> bool {
        regs.slots.iter().any(|s| !s.valid)
    }

    /// The `resp_free` output for these registers (free response-FIFO entries).
    pub fn resp_free(&self, regs: &RtUnitRegs) -> u32 {
        self.params.resp_fifo_depth - regs.fifo.len() as u32
    }

    /// Cycles from now in which the unit, given idle inputs (no issue, no responses), does
    /// nothing visible outside its statistics and delay counters: no request, no completion,
    /// no response pop, no test. `u64::MAX` when it waits only for responses (or is empty).
    /// Lets a simulator skip those cycles with [`skip`](Self::skip).
    pub fn idle_cycles(&self, regs: &RtUnitRegs) -> u64 {
        if !regs.fifo.is_empty() || regs.split.is_some() {
            return 0;
        }
        let mut idle = u64::MAX;
        for &s in &regs.age {
            let slot = &regs.slots[s as usize];
            let m = &slot.masks;
            if (!slot.held && m.busy() == 0) || m.store | m.ready() != 0 {
                return 0;
            }
            for l in bits(m.delayed) {
                idle = idle.min(slot.lanes[l].delay as u64);
            }
        }
        idle
    }

    /// Advances the registers by `n` cycles with idle inputs, exactly as `n` calls of
    /// [`Block::step`] would, provided `n <= idle_cycles(regs)`: the statistics count `n` warp
    /// cycles per resident warp and the delays count down by `n`. Panics in debug builds when
    /// `n` exceeds [`idle_cycles`](Self::idle_cycles).
    pub fn skip(&self, regs: &mut RtUnitRegs, n: u64) {
        debug_assert!(n <= self.idle_cycles(regs), "skip beyond the idle cycles");
        if n == 0 {
            return;
        }
        for slot in regs.slots.iter_mut().filter(|s| s.valid) {
            regs.stats.warp_cycles += n;
            regs.stats.active_thread_cycles += n * u64::from(slot.masks.traversing.count_ones());
            for l in bits(slot.masks.delayed) {
                let lane = &mut slot.lanes[l];
                lane.delay = (lane.delay as u64).saturating_sub(n) as u32;
                if lane.delay == 0 {
                    slot.masks.delayed &= !(1 << l);
                }
            }
        }
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
    /// treelet numbers in range, stacks no deeper than `stack_depth`, valid nodes.
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
        for (i, ray) in issue.lanes.iter().enumerate() {
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
            for (name, stack) in [("current", &ray.current_stack), ("other", &ray.other_stack)] {
                if stack.len() > self.cfg.stack_depth as usize {
                    return Err(bad(
                        i,
                        format!(
                            "{name} stack holds {} entries, stack_depth is {}",
                            stack.len(),
                            self.cfg.stack_depth
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

    /// The whole cycle, in place; `eval` runs it on a copy of the registers.
    fn update(&self, r: &mut RtUnitRegs, inp: &RtUnitInputs) -> RtUnitOutputs {
        debug_assert!(
            r.summaries_consistent(),
            "lane summaries out of date: call RtUnitRegs::refresh_summaries after writing lanes"
        );
        let free_mask = r
            .slots
            .iter()
            .enumerate()
            .fold(0u64, |m, (i, s)| m | (u64::from(!s.valid) << i));
        let free_slot = (free_mask != 0).then(|| free_mask.trailing_zeros() as usize);
        let issue_ready = free_slot.is_some();
        let resp_free = self.resp_free(r);

        // 1. Statistics.
        for slot in r.slots.iter().filter(|s| s.valid) {
            r.stats.warp_cycles += 1;
            r.stats.active_thread_cycles += u64::from(slot.masks.traversing.count_ones());
        }

        // 2. Completion, 3. memory scheduler, 4. delay countdown.
        let done = self.complete(r);
        let request = self.schedule(r);
        for slot in &mut r.slots {
            for l in bits(slot.masks.delayed) {
                let lane = &mut slot.lanes[l];
                lane.delay -= 1;
                if lane.delay == 0 {
                    slot.masks.delayed &= !(1 << l);
                }
            }
        }

        // 5. Response pop, 6. response push.
        let mut boundary = Vec::new();
        if let Some(resp) = r.fifo.pop_front() {
            self.deliver(r, &resp, &mut boundary);
        }
        for (k, resp) in inp.responses.iter().enumerate() {
            if k < self.params.resp_ports as usize
                && r.fifo.len() < self.params.resp_fifo_depth as usize
            {
                r.fifo.push_back(*resp);
            } else {
                r.errors |= errors::FIFO_OVERFLOW;
            }
        }

        // 7. Warp issue, then the treelet controller's commands.
        if let Some(issue) = &inp.issue {
            self.issue(r, free_mask, issue);
        }
        if let Some(s) = inp.stop {
            self.stop(r, s);
        }
        let released = inp.repack.and_then(|s| self.repack(r, s));

        RtUnitOutputs {
            widths: self.widths,
            issue_ready,
            resp_free,
            request,
            done,
            boundary,
            released,
            errors: r.errors,
        }
    }

    /// Step 7: loads an issued warp into a slot that was free at the start of the cycle (bit
    /// `s` of `free_mask`) or appends a repack fill to a held slot.
    fn issue(&self, r: &mut RtUnitRegs, free_mask: u64, issue: &WarpIssue) {
        let free_slot = (free_mask != 0).then(|| free_mask.trailing_zeros() as usize);
        if self.check_issue(issue).is_err() {
            r.errors |= errors::BAD_ISSUE;
            return;
        }
        match issue.target {
            IssueTarget::AnyFree => match free_slot {
                None => r.errors |= errors::ISSUE_WHILE_FULL,
                Some(s) => self.load(r, s, issue),
            },
            IssueTarget::Slot(s) if s < 64 && free_mask >> s & 1 == 1 => {
                self.load(r, s as usize, issue)
            }
            IssueTarget::Slot(_) => r.errors |= errors::BAD_COMMAND,
            IssueTarget::Append { slot: s, last } => {
                let ok =
                    r.slots.get(s as usize).is_some_and(|slot| {
                        slot.valid
                            && slot.held
                            && slot.lanes.iter().zip(&issue.lanes).all(|(lane, ray)| {
                                ray.is_none() || lane.status == LaneStatus::Inactive
                            })
                    });
                if !ok {
                    r.errors |= errors::BAD_COMMAND;
                    return;
                }
                let slot = &mut r.slots[s as usize];
                for (lane, ray) in slot.lanes.iter_mut().zip(&issue.lanes) {
                    if let Some(ray) = ray {
                        *lane = Self::lane_for(ray);
                    }
                }
                slot.masks = LaneMasks::of(&slot.lanes);
                if last {
                    slot.held = false;
                }
            }
        }
    }

    /// Terminates slot `s`'s warp into the treelet queues: treelet-stop order from now on, and
    /// rays already between treelets park at once.
    fn stop(&self, r: &mut RtUnitRegs, s: u32) {
        let Some(slot) = r.slots.get_mut(s as usize).filter(|slot| slot.valid) else {
            r.errors |= errors::BAD_COMMAND;
            return;
        };
        slot.order = TraversalOrder::TreeletStop;
        for (l, lane) in slot.lanes.iter_mut().enumerate() {
            if lane.status == LaneStatus::Traversing
                && lane.in_flight.is_none()
                && lane.ray.current_stack.is_empty()
                && !lane.ray.other_stack.is_empty()
            {
                lane.status = LaneStatus::Parked;
                slot.masks.set(l, lane);
            }
        }
    }

    /// Repacks slot `s`: releases its finished, quiescent lanes and holds the slot. A slot
    /// that completed this cycle is left alone (nothing to repack).
    fn repack(&self, r: &mut RtUnitRegs, s: u32) -> Option<WarpDone> {
        let slot = r.slots.get_mut(s as usize).filter(|slot| slot.valid)?;
        slot.held = true;
        let lanes = slot
            .lanes
            .iter_mut()
            .map(|lane| {
                (lane.status == LaneStatus::Done && lane.quiescent()).then(|| {
                    lane.status = LaneStatus::Inactive;
                    (std::mem::take(&mut lane.ray), RayOutcome::Finished)
                })
            })
            .collect();
        slot.masks = LaneMasks::of(&slot.lanes);
        Some(WarpDone { slot: s, lanes })
    }

    /// A fresh lane holding `ray` (already finished rays enter done).
    fn lane_for(ray: &RayRecord) -> Lane {
        Lane {
            status: if ray.finished() {
                LaneStatus::Done
            } else {
                LaneStatus::Traversing
            },
            ray: ray.clone(),
            ..Lane::default()
        }
    }

    /// Removes and reports the oldest warp with nothing outstanding.
    fn complete(&self, r: &mut RtUnitRegs) -> Option<WarpDone> {
        let pos = r.age.iter().position(|&s| {
            let slot = &r.slots[s as usize];
            !slot.held && slot.masks.busy() == 0
        })?;
        let s = r.age.remove(pos);
        let slot = &mut r.slots[s as usize];
        slot.valid = false;
        r.stats.warps_done += 1;
        let lanes = slot
            .lanes
            .iter_mut()
            .map(|lane| {
                let outcome = match lane.status {
                    LaneStatus::Inactive | LaneStatus::Traversing => return None,
                    LaneStatus::Done => RayOutcome::Finished,
                    LaneStatus::Parked => RayOutcome::AtBoundary {
                        treelet: self.treelet_of(lane.ray.next_node()?.address),
                    },
                };
                lane.status = LaneStatus::Inactive;
                Some((std::mem::take(&mut lane.ray), outcome))
            })
            .collect();
        slot.masks = LaneMasks::of(&slot.lanes);
        Some(WarpDone { slot: s, lanes })
    }

    /// Picks this cycle's memory request and updates the lanes it serves.
    fn schedule(&self, r: &mut RtUnitRegs) -> Option<MemRequest> {
        let lane_bits = self.widths.lane;
        if let Some(split) = r.split.take() {
            let chunk = split.next_chunk;
            if chunk + 1 < split.node.chunks {
                r.split = Some(Split {
                    next_chunk: chunk + 1,
                    ..split
                });
            }
            r.stats.requests += 1;
            return Some(load_request(&split.node, chunk, split.tag));
        }
        for &s in &r.age {
            let slot = &mut r.slots[s as usize];
            if slot.masks.store != 0 {
                let l = slot.masks.store.trailing_zeros() as usize;
                let lane = &mut slot.lanes[l];
                lane.store_pending = false;
                slot.masks.set(l, lane);
                r.stats.stores += 1;
                return Some(self.store_request(&lane.ray, s << lane_bits | l as u32));
            }
        }
        for &s in &r.age {
            let slot = &mut r.slots[s as usize];
            // Serving a lane changes only that lane, so the ready set of the scan is the one at
            // its start.
            let ready = slot.masks.ready();
            if ready == 0 {
                continue;
            }
            let leader = ready.trailing_zeros() as usize;
            let Some(node) = slot.lanes[leader].ray.next_node() else {
                continue;
            };
            let same = |n: NodeEntry| n.address == node.address && n.chunks == node.chunks;
            let mut served = 0;
            for l in bits(ready) {
                let lane = &mut slot.lanes[l];
                if lane.ray.next_node().is_some_and(same) {
                    self.pop_next(&mut lane.ray);
                    lane.in_flight = Some(InFlight {
                        node,
                        leader: leader as u32,
                        returned: 0,
                    });
                    slot.masks.set(l, lane);
                    served += 1;
                }
            }
            r.stats.merged += served - 1;
            let tag = s << lane_bits | leader as u32;
            if node.chunks > 1 {
                r.split = Some(Split {
                    tag,
                    node,
                    next_chunk: 1,
                });
            }
            r.stats.requests += 1;
            return Some(load_request(&node, 0, tag));
        }
        None
    }

    /// The 32 B hit-record store of a ray: t, hit id, two attribute words, ray id, zeros.
    fn store_request(&self, ray: &RayRecord, tag: u32) -> MemRequest {
        let hit = ray.hit.unwrap_or_default();
        let words = [
            hit.t,
            hit.hit_id,
            hit.attribs[0],
            hit.attribs[1],
            ray.ray_id,
            0,
            0,
            0,
        ];
        let mut data = [0u8; CHUNK_BYTES as usize];
        for (bytes, w) in data.chunks_exact_mut(4).zip(words) {
            bytes.copy_from_slice(&w.to_le_bytes());
        }
        MemRequest {
            address: self.params.hit_record_base + ray.ray_id as u64 * CHUNK_BYTES as u64,
            is_store: true,
            tag,
            data,
        }
    }

    /// Pops the ray's next node, switching treelets when the current stack is empty.
    fn pop_next(&self, ray: &mut RayRecord) {
        if ray.current_stack.pop().is_none() {
            if let Some(node) = ray.other_stack.pop() {
                ray.current_treelet = self.treelet_of(node.address);
            }
        }
    }

    /// Delivers a popped response to the lanes waiting for it and runs completed tests.
    fn deliver(&self, r: &mut RtUnitRegs, resp: &MemResponse, boundary: &mut Vec<BoundaryEvent>) {
        let s = resp.tag >> self.widths.lane;
        let leader = resp.tag & ((1 << self.widths.lane) - 1);
        let Some(slot) = r.slots.get_mut(s as usize).filter(|slot| slot.valid) else {
            r.errors |= errors::UNMATCHED_RESPONSE;
            return;
        };
        let order = slot.order;
        let mut matched = false;
        // Only lanes whose cached leader matches can match (the full check follows).
        let group = bits(slot.masks.in_flight)
            .filter(|&l| slot.masks.leader[l] == leader as u8)
            .fold(0u64, |m, l| m | 1 << l);
        for l in bits(group) {
            let lane = &mut slot.lanes[l];
            let Some(f) = lane.in_flight.as_mut() else {
                continue;
            };
            let offset = resp.address.wrapping_sub(f.node.address);
            let chunk = offset / CHUNK_BYTES as u64;
            if f.leader != leader
                || resp.address < f.node.address
                || offset & CHUNK_MASK != 0
                || chunk >= f.node.chunks as u64
                || f.returned & (1 << chunk) != 0
            {
                continue;
            }
            matched = true;
            f.returned |= 1 << chunk;
            lane.chunks[chunk as usize] = resp.data;
            if f.returned == (1u8 << f.node.chunks) - 1 {
                let node = f.node;
                lane.in_flight = None;
                let event = self.test(lane, &node, order, &mut r.stats, &mut r.errors);
                slot.masks.set(l, lane);
                if let Some(treelet) = event {
                    boundary.push(BoundaryEvent {
                        slot: s,
                        lane: l as u32,
                        ray_id: lane.ray.ray_id,
                        treelet,
                    });
                }
            }
        }
        if !matched {
            r.errors |= errors::UNMATCHED_RESPONSE;
        }
    }

    /// Runs the datapath on a complete node and writes the result back; returns the treelet
    /// needed next when the ray reached a treelet boundary.
    fn test(
        &self,
        lane: &mut Lane,
        node: &NodeEntry,
        order: TraversalOrder,
        stats: &mut RtStats,
        errs: &mut u8,
    ) -> Option<u64> {
        let data = &lane.chunks.as_flattened()[..node.bytes() as usize];
        let result = self
            .datapath
            .test(&lane.ray.words, lane.ray.hit.as_ref(), node, data);
        stats.tests[node.kind.code() as usize] += 1;
        let best = lane.ray.hit;
        let accepted = result
            .hit
            .filter(|h| best.is_none_or(|b| h.closer_than(&b)));
        if let Some(hit) = accepted {
            lane.ray.hit = Some(hit);
            lane.store_pending = true;
            if node.kind == NodeKind::TriangleLeaf {
                stats.hits += 1;
            }
        }
        lane.delay = self.params.latencies.of(node.kind, accepted.is_some());
        let ray = &mut lane.ray;
        for child in result.children.iter().rev() {
            if self.check_node(child).is_err() {
                *errs |= errors::BAD_CHILD;
                continue;
            }
            let current =
                !order.two_stack() || self.treelet_of(child.address) == ray.current_treelet;
            let stack = if current {
                &mut ray.current_stack
            } else {
                &mut ray.other_stack
            };
            if stack.len() < self.cfg.stack_depth as usize {
                stack.push(*child);
            } else {
                *errs |= errors::STACK_OVERFLOW;
            }
        }
        if ray.finished() {
            lane.status = LaneStatus::Done;
            return None;
        }
        if !order.two_stack() || !ray.current_stack.is_empty() {
            return None;
        }
        if order == TraversalOrder::TreeletStop {
            lane.status = LaneStatus::Parked;
        }
        ray.other_stack.last().map(|n| self.treelet_of(n.address))
    }

    /// Writes an issued warp into slot `s`.
    fn load(&self, r: &mut RtUnitRegs, s: usize, issue: &WarpIssue) {
        let slot = &mut r.slots[s];
        slot.valid = true;
        slot.held = false;
        slot.order = issue.order;
        for (lane, ray) in slot.lanes.iter_mut().zip(&issue.lanes) {
            *lane = ray.as_ref().map_or_else(Lane::default, Self::lane_for);
        }
        slot.masks = LaneMasks::of(&slot.lanes);
        r.age.push(s as u32);
    }
}

/// The load request for chunk `chunk` of `node`.
fn load_request(node: &NodeEntry, chunk: u8, tag: u32) -> MemRequest {
    MemRequest {
        address: node.address + chunk as u64 * CHUNK_BYTES as u64,
        is_store: false,
        tag,
        data: [0; CHUNK_BYTES as usize],
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
            masks: LaneMasks::of(&lanes),
            lanes,
        };
        RtUnitRegs {
            widths: self.widths,
            slots: vec![slot; self.cfg.warp_buffer_size as usize],
            age: Vec::new(),
            fifo: VecDeque::with_capacity(self.params.resp_fifo_depth as usize),
            split: None,
            errors: 0,
            stats: RtStats::default(),
        }
    }

    fn eval(&self, regs: &RtUnitRegs, inputs: &RtUnitInputs) -> (RtUnitOutputs, RtUnitRegs) {
        let mut next = regs.clone();
        let out = self.update(&mut next, inputs);
        (out, next)
    }

    /// In place: the same update as `eval` without copying the warp buffer.
    fn step(&self, regs: &mut RtUnitRegs, inputs: &RtUnitInputs) -> RtUnitOutputs {
        self.update(regs, inputs)
    }

    fn describe(&self) -> BlockDesc {
        desc::describe(&self.cfg, &self.params, &self.widths)
    }
}
