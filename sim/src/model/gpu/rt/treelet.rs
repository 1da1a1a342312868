//! The treelet RT unit's cycle in an [`RtPort`] (queues mode): SM warps offered on its ports
//! and their rays' hits collected per SM warp, memory requests and ray records, the ray-record
//! store and the spill FIFO, preloads handed to the preloader, the treelet prefetcher watching
//! the rays (`mode.treelet_prefetch`), and the statistics observer.

use std::collections::{BTreeMap, VecDeque};

use vtq_hdl::mode::Mode;
use vtq_hdl::rt_unit::{RayRecord, RtStats, RtUnitError, RtUnitParams, CHUNK_BYTES};
use vtq_hdl::treelet_rt_unit::{
    RayLoad, TableLog, TreeletCounts, TreeletRequest, TreeletRtUnit, TreeletRtUnitCache,
    TreeletRtUnitInputs, TreeletRtUnitOutputs, TreeletRtUnitParams, TreeletRtUnitRegs,
    TreeletRtUnitStatus, WarpKind,
};
use vtq_hdl::{Block, Cached, HwConfig, Moore, Skip, Taps};

use super::hardware::RtHardware;
use super::warp_costs::WarpCosts;
use super::waveform::Waveform;
use super::{rt_error, tally, RtCycle, Shell, TracedWarp, RAY_LOAD_TAG};
use crate::model::config::TreeletPrefetch;
use crate::model::geometry::Hit;
use crate::model::gpu::datapath::{hit_from_hw, BvhDatapath};
use crate::model::gpu::error::SimError;
use crate::model::gpu::queued_stacks::QueuedStacks;
use crate::model::gpu::ray_memory::{RayStore, SpillFifo};
use crate::model::gpu::stats::WarpLanes;
use crate::model::gpu::warp_simt::WarpSimt;
use crate::model::memory::{Acceptance, AccessClass, MemRequest, Response};
use crate::model::workload::kind::TraceRay;

/// The statistics observer beside one SM's treelet RT unit: its summed events, its tests per
/// traversal phase and the largest number of queues.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QueueObserver {
    /// The treelet RT unit's events, summed (the RT unit's part is also in [`RtPort::hw_stats`]).
    pub counts: TreeletCounts,
    /// Intersection tests per phase (the controller's mode after the cycle of the test):
    /// initial, treelet stationary, final ray stationary.
    pub tests: [u64; 3],
    /// RT-unit warp cycles and what their lanes held, per phase (the controller's mode during
    /// the cycle, the mode its cycle counters use), in the order of `tests`.
    pub lanes: [WarpLanes; 3],
    /// Most treelet queues tracked by the count table at once.
    pub max_queues: u64,
    /// Most of them holding at least `hw.underpopulation_threshold` rays at once.
    pub max_queues_above_threshold: u64,
    /// What each kind of warp cost in each phase ([`WarpCosts`]), up to when `cell` was
    /// entered.
    pub costs: WarpCosts,
    /// The (phase index, warp kind) the last stepped or skipped cycle counted in: where BVH
    /// loads the L1 accepts in stepped cycles are attributed, and the RT unit's counters since
    /// `cell_since`.
    pub cell: (usize, WarpKind),
    /// The port's RT-unit counters when `cell` was entered: what was counted since belongs to
    /// it (taken by difference when the cell changes, so a cycle costs a comparison).
    pub cell_since: RtStats,
}

impl QueueObserver {
    /// Enters cell `cell` (phase index, warp kind) for the cycles counted from now, `total`
    /// being the port's RT-unit counters so far: the counters since the current cell was
    /// entered go to it.
    pub(super) fn enter_cell(&mut self, cell: (usize, WarpKind), total: &RtStats) {
        if cell != self.cell {
            let mut since = *total;
            since.sub(&self.cell_since);
            self.costs.cell(self.cell.0, self.cell.1).rt.add(&since);
            self.cell_since = *total;
            self.cell = cell;
        }
    }

    /// The warp costs so far, the current cell's counters since it was entered included
    /// (`total`: the port's RT-unit counters).
    pub(super) fn warp_costs(&self, total: &RtStats) -> WarpCosts {
        let mut costs = self.costs;
        let mut since = *total;
        since.sub(&self.cell_since);
        costs.cell(self.cell.0, self.cell.1).rt.add(&since);
        costs
    }

    /// Counts the events of a stepped or skipped stretch of cycles (`counts`, the RT unit's
    /// part also into the port's `stats`), its warp cycles and lanes in phase `phase` (an index
    /// of [`phase_index`]): the one place a stretch is counted.
    pub(super) fn count(&mut self, phase: usize, counts: &TreeletCounts, stats: &mut RtStats) {
        stats.add(&counts.rt);
        self.counts.add(counts);
        self.lanes[phase].add(&WarpLanes::of(&counts.rt));
    }
}

/// The index of the controller's mode `mode` in [`QueueObserver`]'s per-phase counters: initial
/// (and done, a drained controller), treelet stationary, final ray stationary.
pub(super) fn phase_index(mode: Mode) -> usize {
    match mode {
        Mode::Initial | Mode::Done => 0,
        Mode::TreeletStationary => 1,
        Mode::FinalRayStationary => 2,
    }
}

/// The queues design's treelet hardware for [`RtPort::new`]: the controller's feature switches
/// and where this SM's ray records start.
#[derive(Debug, Clone, Copy)]
pub struct QueueSetup {
    /// The controller's feature switches.
    pub features: vtq_hdl::controller::ControllerFeatures,
    /// Byte address of this SM's ray id 0's 32 B ray record.
    pub ray_base: u64,
    /// Where queued rays' stacks go, when they move through memory
    /// (`rt.queued_stack_traffic`): the address of this SM's area ([`QueuedStacks`]).
    pub stack_base: Option<u64>,
    /// In which phases the port's treelet prefetcher watches the rays (`mode.treelet_prefetch`).
    pub prefetch: TreeletPrefetch,
    /// Ray records held on chip (`rt.ray_record_latency`): the cycles a record load takes;
    /// `None`: records go through memory.
    pub record_latency: Option<u32>,
}

/// Queues mode: an SM warp whose rays are spread over the RT unit and the treelet queues.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PendingWarp {
    /// Per lane that carried a ray: `Some(closest hit)` (`Some(None)`, a miss, until the ray
    /// finishes); `None` for idle lanes.
    hits: Vec<Option<Option<Hit>>>,
    /// Rays still out.
    left: u32,
}

/// The treelet RT unit with its registers, cache and surroundings.
#[derive(Debug, Clone)]
pub(super) struct Treelet<'a> {
    pub(super) unit: TreeletRtUnit<BvhDatapath<'a>>,
    pub(super) regs: TreeletRtUnitRegs,
    pub(super) cache: TreeletRtUnitCache,
    /// Records of rays waiting in the treelet queues.
    pub(super) store: RayStore,
    /// The queue table's spill FIFO.
    pub(super) spill_fifo: SpillFifo,
    /// Ray records that arrived, oldest first, for the next steps (at most `record_ports` a
    /// step: the SM's response queue in front of the wiring's record ports).
    pub(super) arrived: Vec<RayLoad>,
    /// The input bundle, reused every step.
    pub(super) inputs: TreeletRtUnitInputs,
    /// The output bundle, reused every step.
    pub(super) outputs: TreeletRtUnitOutputs,
    /// SM warp and lane of each ray id in use.
    pub(super) owners: Vec<Option<(usize, u32)>>,
    /// SM warps with rays still traversing, by warp id.
    pub(super) pending: BTreeMap<usize, PendingWarp>,
    /// SM warps whose rays have all finished, returned one per cycle.
    pub(super) completed: VecDeque<TracedWarp>,
    /// A ray-record response the store could not answer (reported at the next step).
    pub(super) fault: Option<String>,
    /// The traffic of queued rays' stacks (`rt.queued_stack_traffic`; `None`: free).
    pub(super) stacks: Option<QueuedStacks>,
    /// The statistics observer.
    pub(super) observer: QueueObserver,
    /// In which phases the prefetcher watches the rays.
    pub(super) prefetch: TreeletPrefetch,
    /// Per ray id, the cycle it was last parked in the queues (for the queue wait of
    /// [`WarpCosts`]).
    pub(super) parked_at: Vec<u64>,
    /// Ray records held on chip (`rt.ray_record_latency`): the cycles a record load takes.
    pub(super) record_latency: Option<u32>,
    /// On-chip record loads in flight, in request order: (cycle due, slot, ray id).
    pub(super) record_loads: VecDeque<(u64, u32, u32)>,
}

impl<'a> Treelet<'a> {
    /// The (phase index, warp kind) cell of an idle cycle: the controller's mode, which holds
    /// in idle cycles (it is not evaluated), and the kind of warp resident, else the last kind
    /// seen.
    #[inline]
    fn idle_cell(&self) -> (usize, WarpKind) {
        let status = self.unit.status(&self.regs, &self.cache, false);
        let kind = status.warp_kind.unwrap_or(self.observer.cell.1);
        (phase_index(status.mode), kind)
    }

    /// The treelet RT unit of `hw`, `params` and `setup` after reset, with its surroundings
    /// empty.
    pub(super) fn new(
        hw: &HwConfig,
        params: RtUnitParams,
        datapath: BvhDatapath<'a>,
        setup: QueueSetup,
    ) -> Result<Self, RtUnitError> {
        let params = TreeletRtUnitParams {
            rt: params,
            features: setup.features,
            ray_base: setup.ray_base,
        };
        let unit = TreeletRtUnit::new(hw.clone(), params, datapath)?;
        let regs = unit.reset();
        let cache = unit.cache(&regs);
        Ok(Treelet {
            inputs: unit.idle_inputs(),
            outputs: unit.empty_outputs(),
            unit,
            regs,
            cache,
            store: RayStore::new(hw.max_rays),
            spill_fifo: SpillFifo::default(),
            arrived: Vec::new(),
            owners: vec![None; hw.max_rays as usize],
            pending: BTreeMap::new(),
            completed: VecDeque::new(),
            fault: None,
            stacks: setup
                .stack_base
                .map(|base| QueuedStacks::new(base, hw.max_rays, hw.stack_depth)),
            observer: QueueObserver::default(),
            prefetch: setup.prefetch,
            parked_at: vec![0; hw.max_rays as usize],
            record_latency: setup.record_latency,
            record_loads: VecDeque::new(),
        })
    }

    /// The record of ray `ray`, loaded for the fill in slot `slot`, arrived: taken from the
    /// store and handed to the next step (after its stack chunks, when they move through
    /// memory).
    pub(super) fn record_arrived(&mut self, slot: u32, ray: u32) {
        match self.store.take(ray) {
            Some(record) => {
                let load = RayLoad { slot, ray, record };
                let ready = match self.stacks.as_mut() {
                    Some(q) => q.record_arrived(load),
                    None => Some(load),
                };
                self.arrived.extend(ready);
            }
            None => {
                self.fault.get_or_insert(format!(
                    "the record of ray {ray} was loaded but the store holds none"
                ));
            }
        }
    }
}

impl<'a> RtHardware<'a> for Treelet<'a> {
    fn issue_ready(&self) -> bool {
        self.unit.status(&self.regs, &self.cache, true).sm_ready
    }

    fn observe_warps(&self, simt: &mut WarpSimt, n: u64) {
        simt.observe(n, self.unit.slot_lanes(&self.regs, &self.cache));
    }

    fn resident(&self) -> (u64, u64) {
        tally(self.unit.slot_lanes(&self.regs, &self.cache))
    }

    fn traversing_rays(&self) -> u64 {
        self.unit.traversing_rays(&self.regs, &self.cache)
    }

    fn idle_cycles(&self) -> u64 {
        self.unit.idle_cycles(&self.regs, &self.cache)
    }

    fn skip(&mut self, n: u64, stats: &mut RtStats) {
        let (phase, kind) = self.idle_cell();
        self.observer.enter_cell((phase, kind), stats);
        let counts = self.unit.skip(&mut self.regs, &mut self.cache, n);
        self.observer.count(phase, &counts, stats);
    }

    fn idle_step(&mut self, stats: &mut RtStats, w: &mut Waveform, c: u64) {
        let inputs = TreeletRtUnitInputs {
            spill_head: self.spill_fifo.head(),
            ..self.unit.idle_inputs()
        };
        self.cache.probe(true);
        let phase = phase_index(self.unit.status(&self.regs, &self.cache, false).mode);
        let out = self
            .unit
            .step_cached(&mut self.regs, &mut self.cache, &inputs);
        let probe = self.cache.take_probe();
        self.cache.probe(false);
        debug_assert!(
            out.requests.is_empty()
                && out.finished.is_empty()
                && out.parked.is_empty()
                && out.spill_push.is_none()
                && !out.spill_pop
                && out.preload.is_none()
                && out.sm_accepted.is_none(),
            "an idle cycle did something (cycle {c})"
        );
        self.observer.count(phase, &out.counts, stats);
        w.record_treelet(&inputs, &out, probe);
    }

    fn debug_state(&self, common: &str) -> String {
        format!(
            "{}; {common}; spill FIFO {}; SM warps waiting for rays {}, returning {}; ray \
             records waiting for their stacks {}",
            self.unit.debug_state(&self.regs),
            self.spill_fifo.len(),
            self.pending.len(),
            self.completed.len(),
            self.stacks.as_ref().map_or(0, QueuedStacks::held)
        )
    }

    fn records_due(&mut self, now: u64) {
        while let Some(&(due, slot, ray)) = self.record_loads.front() {
            if due > now {
                break;
            }
            self.record_loads.pop_front();
            self.record_arrived(slot, ray);
        }
    }

    fn ray_response(&mut self, r: &Response) {
        match r.class {
            AccessClass::RayRecord => {
                let slot = (r.tag & 0xFFFF) as u32;
                let ray = ((r.tag & !RAY_LOAD_TAG) >> 16) as u32;
                self.record_arrived(slot, ray);
            }
            AccessClass::RayStack => {
                if let Some(load) = self.stacks.as_mut().and_then(|q| q.chunk_arrived(r.tag)) {
                    self.arrived.push(load);
                }
            }
            _ => {}
        }
    }

    fn has_work(&self) -> bool {
        !self.completed.is_empty() || !self.arrived.is_empty()
    }

    fn next_event(&self, now: u64) -> Option<u64> {
        let soon = self.has_work().then_some(now + 1);
        let record = self.record_loads.front().map(|&(due, ..)| due.max(now + 1));
        soon.into_iter().chain(record).min()
    }

    fn bvh_access_accepted(&mut self, acceptance: &Acceptance, idle: bool) {
        // In an idle cycle not stepped yet the cell is the one its skip will enter, as a
        // lockstep run's step of it would.
        let (phase, kind) = if idle {
            self.idle_cell()
        } else {
            self.observer.cell
        };
        self.observer
            .costs
            .cell(phase, kind)
            .count_bvh_access(acceptance);
    }

    fn warp_costs(&self, stats: &RtStats) -> Option<WarpCosts> {
        Some(self.observer.warp_costs(stats))
    }

    fn queue_stats(&self) -> Option<&QueueObserver> {
        Some(&self.observer)
    }

    fn queued_stack_chunks(&self) -> (u64, u64) {
        self.stacks.as_ref().map_or((0, 0), |q| (q.stores, q.loads))
    }

    fn record_tables(&mut self, cycles: usize) -> bool {
        self.cache.record_tables(cycles, self.unit.params());
        true
    }

    fn take_table_log(&mut self) -> Option<TableLog> {
        self.cache.take_table_log()
    }

    /// A cycle `now` of the treelet RT unit (out of line: the plain RT unit's step stays small
    /// enough to inline into the node's visit).
    #[inline(never)]
    fn step(
        &mut self,
        shell: &mut Shell<'a>,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Result<RtCycle, SimError> {
        let mut cycle = RtCycle::default();
        let record = shell.recording(now);
        let lanes = warp.map(|(_, rays)| {
            let warp_size = self.unit.config().warp_size as usize;
            shell.warp_lanes(0, rays, warp_size)
        });
        if let Some(reason) = self.fault.take() {
            return Err(SimError::Queues { sm, reason });
        }
        // The register-only outputs before the cycle and after it.
        let before = self.unit.status(&self.regs, &self.cache, false);
        self.feed_inputs(shell, lanes, before.resp_free);
        if record {
            self.cache.probe(true);
        }
        let during = phase_index(before.mode);
        self.unit.step_cached_into(
            &mut self.regs,
            &mut self.cache,
            &self.inputs,
            &mut self.outputs,
        );
        let after = self.unit.status(&self.regs, &self.cache, false);
        let kind = before
            .warp_kind
            .or(after.warp_kind)
            .unwrap_or(self.observer.cell.1);
        self.observer.enter_cell((during, kind), &shell.stats);
        if let (true, Some(w)) = (record, shell.waveform.as_mut()) {
            w.record_treelet(&self.inputs, &self.outputs, self.cache.take_probe());
            self.cache.probe(false);
        }
        self.observe_outputs(during, &after, &mut shell.stats);
        self.check_outputs(sm, shell.address_bits)?;
        if let Some(idx) = self.accept_warp(shell, during, warp) {
            cycle.accepted = Some(idx);
        }
        self.park_rays(shell, now);
        self.feed_prefetcher(shell, after.mode);
        self.finish_rays(shell, sm)?;
        cycle.done = self.completed.pop_front();
        self.queue_requests(shell, now, during);
        Ok(cycle)
    }
}

/// The pieces of [`Treelet`]'s cycle ([`RtHardware::step`]), in the order the step runs them.
impl<'a> Treelet<'a> {
    /// Fills the reused input bundle for this cycle: the SM warp offered (`lanes`), the
    /// responses the RT unit's free ports take from the shell's queue, this cycle's ray records
    /// and the spill FIFO's head.
    #[inline]
    fn feed_inputs(
        &mut self,
        shell: &mut Shell<'a>,
        lanes: Option<Vec<Option<RayRecord>>>,
        resp_free: u32,
    ) {
        let rt = self.unit.rt_unit();
        let ports = resp_free.min(rt.params().resp_ports);
        let n = (ports as usize).min(shell.responses.len());
        // The input bundle is reused every cycle, so feeding it does not allocate.
        let inputs = &mut self.inputs;
        inputs.sm_warp = lanes;
        inputs.responses.clear();
        inputs.responses.extend(shell.responses.drain(..n));
        // At most one record per record port a cycle, all for one slot (the RT unit writes
        // one slot's lanes a cycle): the oldest records of the oldest one's slot. The rest wait
        // in the response queue.
        inputs.ray_records.clear();
        let ports = self.unit.config().record_ports() as usize;
        let slot = self.arrived.first().map(|r| r.slot);
        let mut taken = 0;
        inputs.ray_records.extend(self.arrived.extract_if(.., |r| {
            let take = Some(r.slot) == slot && taken < ports;
            taken += usize::from(take);
            take
        }));
        inputs.spill_head = self.spill_fifo.head();
    }

    /// Counts the cycle's events in phase `during` (the RT unit's part also into `stats`), its
    /// tests in the phase after it, and the largest numbers of queues.
    #[inline]
    fn observe_outputs(&mut self, during: usize, after: &TreeletRtUnitStatus, stats: &mut RtStats) {
        let out = &self.outputs;
        let obs = &mut self.observer;
        obs.count(during, &out.counts, stats);
        obs.tests[phase_index(after.mode)] += out.counts.rt.total_tests();
        obs.max_queues = obs.max_queues.max(after.queues as u64);
        obs.max_queues_above_threshold = obs
            .max_queues_above_threshold
            .max(after.queues_above_threshold as u64);
    }

    /// The RT unit's first error (naming the ray's SM warp and lane) or the treelet hardware's
    /// fault of this cycle, as the run's error (`address_bits`: `hw.address_bits`).
    #[inline]
    fn check_outputs(&self, sm: usize, address_bits: u32) -> Result<(), SimError> {
        let out = &self.outputs;
        if let Some(record) = out.first_error {
            let owner = self.owners.get(record.ray_id as usize).copied().flatten();
            return Err(rt_error(sm, record, owner, address_bits));
        }
        if let Some(fault) = &out.fault {
            return Err(SimError::Queues {
                sm,
                reason: fault.to_string(),
            });
        }
        Ok(())
    }

    /// The offered SM warp `warp`, if the RT unit accepted it this cycle: its rays' ids are
    /// owned by its lanes and it waits for them (returned at once if it carries none); its
    /// index, else `None`. `during`: the phase index of the cycle.
    #[inline]
    fn accept_warp(
        &mut self,
        shell: &mut Shell<'a>,
        during: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Option<usize> {
        let (Some(ids), Some((idx, rays))) = (&self.outputs.sm_accepted, warp) else {
            return None;
        };
        let active = ids.iter().flatten().count();
        shell.rays_issued += active as u64;
        self.observer.costs.cell(during, WarpKind::Sm).rays_in += active as u64;
        for (lane, id) in ids.iter().enumerate() {
            if let Some(id) = id {
                self.owners[*id as usize] = Some((idx, lane as u32));
            }
        }
        let hits = (0..ids.len())
            .map(|l| rays.get(l).copied().flatten().map(|_| None))
            .collect::<Vec<_>>();
        if active == 0 {
            self.completed.push_back(TracedWarp { warp: idx, hits });
        } else {
            let left = active as u32;
            self.pending.insert(idx, PendingWarp { hits, left });
        }
        Some(idx)
    }

    /// Stores the records of the rays parked this cycle (`now`), with their stacks' traffic,
    /// and applies the cycle's spill-FIFO push and pop.
    #[inline]
    fn park_rays(&mut self, shell: &mut Shell<'a>, now: u64) {
        let out = &self.outputs;
        for r in out.parked.iter().map(|p| &p.record) {
            if let Some(at) = self.parked_at.get_mut(r.ray_id as usize) {
                *at = now;
            }
            if let Some(q) = self.stacks.as_mut() {
                shell.requests.extend(q.park(r));
            }
            self.store.park(r.clone());
        }
        if let Some(entry) = out.spill_push {
            self.spill_fifo.push(entry);
        }
        if out.spill_pop {
            self.spill_fifo.pop();
        }
    }

    /// Hands the shell's treelet prefetcher (if any) this cycle's preload and, in a watched
    /// phase, the rays' next addresses.
    #[inline]
    fn feed_prefetcher(&self, shell: &mut Shell<'a>, mode: Mode) {
        if let Some(p) = shell.prefetcher.as_mut() {
            if let Some(treelet) = self.outputs.preload {
                p.queue_treelet(treelet);
            }
            // Every stepped cycle of a watched phase: observing unchanged rays again changes
            // nothing (the prefetcher's rule), so skipped idle cycles need no observation.
            if self.prefetch.watches(mode) {
                p.observe(self.unit.next_addresses(&self.regs, &self.cache));
            }
        }
    }

    /// Hands the rays finished this cycle their hits in their SM warps' lanes; a warp whose
    /// last ray finished is completed. An error for a ray no SM warp waits for.
    #[inline]
    fn finish_rays(&mut self, shell: &mut Shell<'a>, sm: usize) -> Result<(), SimError> {
        for f in &self.outputs.finished {
            let Some((warp, lane)) = self.owners.get_mut(f.ray as usize).and_then(Option::take)
            else {
                return Err(SimError::Queues {
                    sm,
                    reason: format!("ray {} finished but no SM warp waits for it", f.ray),
                });
            };
            let Some(PendingWarp { hits, left }) = self.pending.get_mut(&warp) else {
                return Err(SimError::Queues {
                    sm,
                    reason: format!("a ray of SM warp {warp} finished twice"),
                });
            };
            if let Some(h) = hits.get_mut(lane as usize) {
                *h = Some(f.hit.as_ref().map(hit_from_hw));
            }
            *left -= 1;
            shell.rays_completed += 1;
            if *left == 0 {
                let done = self.pending.remove(&warp).expect("present");
                self.completed.push_back(TracedWarp {
                    warp,
                    hits: done.hits,
                });
            }
        }
        Ok(())
    }

    /// Counts the cycle's ray loads into the warp costs (phase index `during`, their queue
    /// wait up to `now`), then queues the cycle's memory requests on the shell: ray-record loads
    /// and stores (or on-chip record loads due after `rt.ray_record_latency`), queued rays'
    /// stack chunks and the RT unit's own requests.
    #[inline]
    fn queue_requests(&mut self, shell: &mut Shell<'a>, now: u64, during: usize) {
        // Taken out while the requests are queued (queueing borrows the port), put back after.
        let mut stacks = self.stacks.take();
        let requests = std::mem::take(&mut self.outputs.requests);
        for r in &requests {
            if let TreeletRequest::RayLoad { slot, ray, .. } = *r {
                let kind = self
                    .unit
                    .fill_kind(&self.regs, slot)
                    .unwrap_or(WarpKind::Grouped);
                let parked = self.parked_at.get(ray as usize).copied().unwrap_or(now);
                let cell = self.observer.costs.cell(during, kind);
                cell.rays_in += 1;
                cell.ray_loads += 1;
                cell.queue_wait_cycles += now.saturating_sub(parked);
            }
        }
        let onchip = self.record_latency;
        let mut record_loads = Vec::new();
        for r in &requests {
            match *r {
                TreeletRequest::RayLoad { slot, ray, .. } if onchip.is_some() => {
                    let due = now + u64::from(onchip.unwrap_or(0));
                    record_loads.push((due, slot, ray));
                    if let Some(q) = stacks.as_mut() {
                        shell.requests.extend(q.load(ray));
                    }
                }
                TreeletRequest::RayLoad { slot, ray, address } => {
                    shell.requests.push_back(
                        MemRequest::load(
                            address,
                            CHUNK_BYTES,
                            AccessClass::RayRecord,
                            RAY_LOAD_TAG | (ray as u64) << 16 | slot as u64,
                        )
                        .bypassing_l1(),
                    );
                    if let Some(q) = stacks.as_mut() {
                        shell.requests.extend(q.load(ray));
                    }
                }
                TreeletRequest::RayStore { .. } if onchip.is_some() => {}
                TreeletRequest::RayStore { address, .. } => shell.requests.push_back(
                    MemRequest::store(address, CHUNK_BYTES, AccessClass::RayRecord, 0)
                        .bypassing_l1(),
                ),
                TreeletRequest::Rt(req) => shell.push_request(&req),
            }
        }
        self.record_loads.extend(record_loads);
        self.stacks = stacks;
        self.outputs.requests = requests;
    }
}
