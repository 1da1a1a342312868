//! One SM's RT unit in the simulated GPU ([`RtPort`]): the hardware model — the RT unit
//! ([`vtq_hdl::rt_unit::RtUnit`], baseline and prefetch designs) or the treelet RT unit
//! ([`vtq_hdl::treelet_rt_unit::TreeletRtUnit`], the queues design) — stepped through its ports,
//! with what surrounds it: the memory access queue between it and the L1 (requests wait there
//! while the L1 stalls), the return path that feeds memory responses into the RT unit's response
//! FIFO (at most `resp_ports` per cycle and never more than `resp_free`), the memory contents it
//! reads and writes (node bytes from the BVH image, stack spills, ray records, the queue table's
//! spill FIFO; [`crate::model::gpu::ray_memory`]), the SM warps waiting for their rays, and the
//! statistics observers beside the blocks. It reads no register of any block: only the blocks'
//! outputs and their register-only output functions. The cycle of each kind of hardware is in
//! its own file: [`plain`] (baseline and prefetch) and [`treelet`] (queues).

pub mod waveform;

use std::collections::{BTreeMap, VecDeque};

use vtq_hdl::rt_unit::{
    ErrorRecord, MemRequest as HwRequest, MemResponse, RayRecord, RequestKind, RtCache, RtStats,
    RtUnit, RtUnitError, RtUnitParams, TraversalOrder, CHUNK_BYTES,
};
use vtq_hdl::treelet_rt_unit::{TreeletRtUnit, TreeletRtUnitCache, TreeletRtUnitParams};
use vtq_hdl::{Block, HwConfig};

use crate::model::bvh::layout::HEADER_ADDR;
use crate::model::bvh::{HwBvh, NodeKind};
use crate::model::geometry::Hit;
use crate::model::gpu::datapath::{node_entry, ray_words, BvhDatapath};
use crate::model::gpu::error::SimError;
use crate::model::gpu::prefetch::Prefetcher;
use crate::model::gpu::queued_stacks::QueuedStacks;
use crate::model::gpu::ray_memory::{RayStore, SpillFifo, SpillMemory};
use crate::model::gpu::rt_fault::RtFault;
use crate::model::gpu::warp_simt::WarpSimt;
use crate::model::memory::{AccessClass, AccessError, L1Port, MemRequest, Response};
use crate::model::workload::kind::TraceRay;

mod plain;
mod treelet;
pub mod warp_costs;

use plain::Plain;
use treelet::Treelet;
pub use treelet::{QueueObserver, QueueSetup};

/// Tag bit marking a ray-record load's response; below it, the ray id (bits 16 and up) and the
/// warp-buffer slot of the fill (bits 0-15).
const RAY_LOAD_TAG: u64 = 1 << 48;

/// A warp the RT unit finished: its SM warp slot and each lane's closest hit (`None` for a
/// miss), for the lanes that carried a ray.
#[derive(Debug, Clone, PartialEq)]
pub struct TracedWarp {
    /// SM warp id (stable while its CTA is suspended).
    pub warp: usize,
    /// Per lane: `Some(hit or miss)` for lanes that carried a ray.
    pub hits: Vec<Option<Option<Hit>>>,
}

/// What one cycle of an [`RtPort`] produced.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RtCycle {
    /// The warp accepted this cycle (its SM warp slot).
    pub accepted: Option<usize>,
    /// The warp completed this cycle.
    pub done: Option<TracedWarp>,
}

/// The error of an RT-unit error record of SM `sm`, with its ray's SM warp and lane where known
/// (`address_bits` sizes the stack spill area the message may name).
fn rt_error(
    sm: usize,
    record: ErrorRecord,
    owner: Option<(usize, u32)>,
    address_bits: u32,
) -> SimError {
    // Errors about responses name no ray.
    let owner = owner.filter(|_| {
        !matches!(
            record.kind,
            vtq_hdl::rt_unit::ErrorKind::FifoOverflow
                | vtq_hdl::rt_unit::ErrorKind::UnmatchedResponse
        )
    });
    SimError::RtUnit {
        sm,
        fault: Box::new(RtFault {
            record,
            owner,
            pixel: None,
            address_bits,
        }),
    }
}

/// Which hardware an [`RtPort`] steps.
#[derive(Debug, Clone)]
enum Hardware<'a> {
    Plain(Box<Plain<'a>>),
    Treelet(Box<Treelet<'a>>),
}

/// The RT unit of one SM with its memory queues.
#[derive(Debug)]
pub struct RtPort<'a> {
    hw: Hardware<'a>,
    bvh: &'a HwBvh,
    order: TraversalOrder,
    /// Memory access queue (requests not yet accepted by the L1), oldest first.
    requests: VecDeque<MemRequest>,
    /// First cycle the head of `requests` may be offered again after a stall.
    retry_at: u64,
    /// Load responses waiting to enter the response FIFO.
    responses: VecDeque<MemResponse>,
    /// The cycle the registers stand at (the next cycle to evaluate); cycles before it that
    /// were not stepped were idle and are caught up lazily with `skip`.
    at: u64,
    /// First cycle the hardware has work again with idle inputs: `at + idle_cycles`
    /// (saturating), recomputed after every step. Skipping idle cycles leaves it unchanged.
    wake: u64,
    /// The treelet prefetcher (prefetch mode; in queues mode it serves the controller's
    /// preloads).
    prefetcher: Option<Prefetcher<'a>>,
    /// Contents of this SM's stack spill area.
    spill: SpillMemory,
    /// `hw.address_bits`, for error messages.
    address_bits: u32,
    /// The RT unit's statistics, summed from its per-cycle counts.
    stats: RtStats,
    /// SIMT efficiency averaged per warp ([`WarpSimt`]).
    warp_simt: WarpSimt,
    /// Most requests queued at once.
    pub max_queue: u64,
    /// Rays issued.
    pub rays_issued: u64,
    /// Rays completed.
    pub rays_completed: u64,
    /// The waveform recorded over a window of cycles, if any (`vtq sim --vcd`).
    waveform: Option<Box<waveform::Waveform>>,
}

impl<'a> RtPort<'a> {
    /// The RT unit of one SM: `hw` sizes, `params` timing (with this SM's hit-record base and
    /// stack spill area), SM warps traversing in `order`; with `queues`, the treelet RT unit of
    /// the queues design.
    pub fn new(
        hw: &HwConfig,
        params: RtUnitParams,
        bvh: &'a HwBvh,
        order: TraversalOrder,
        queues: Option<QueueSetup>,
    ) -> Result<Self, RtUnitError> {
        let datapath = BvhDatapath::new(bvh);
        let (hardware, wake) = match queues {
            None => {
                let unit = RtUnit::new(hw.clone(), params, datapath)?;
                let regs = unit.reset();
                let cache = RtCache::of(&regs);
                let wake = unit.idle_cycles(&regs, &cache);
                let inputs = unit.idle_inputs();
                let plain = Plain {
                    slot_warp: vec![None; hw.warp_buffer_size as usize],
                    status: unit.status(&regs, &cache, false),
                    unit,
                    regs,
                    cache,
                    inputs,
                };
                (Hardware::Plain(Box::new(plain)), wake)
            }
            Some(setup) => {
                let params = TreeletRtUnitParams {
                    rt: params,
                    features: setup.features,
                    ray_base: setup.ray_base,
                };
                let unit = TreeletRtUnit::new(hw.clone(), params, datapath)?;
                let regs = unit.reset();
                let cache = TreeletRtUnitCache::of(&regs);
                let wake = unit.idle_cycles(&regs, &cache);
                let inputs = unit.idle_inputs();
                let outputs = unit.empty_outputs();
                let treelet = Treelet {
                    inputs,
                    outputs,
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
                };
                (Hardware::Treelet(Box::new(treelet)), wake)
            }
        };
        Ok(RtPort {
            hw: hardware,
            bvh,
            order,
            requests: VecDeque::new(),
            retry_at: 0,
            responses: VecDeque::new(),
            at: 0,
            wake,
            prefetcher: None,
            spill: SpillMemory::default(),
            address_bits: hw.address_bits,
            stats: RtStats::default(),
            warp_simt: WarpSimt::new(hw.warp_buffer_size as usize, hw.warp_size),
            max_queue: 0,
            rays_issued: 0,
            rays_completed: 0,
            waveform: None,
        })
    }

    /// The same port with a treelet prefetcher beside the RT unit (prefetch mode), or serving
    /// the treelet controller's preloads (queues mode).
    pub fn with_prefetcher(self, prefetcher: Prefetcher<'a>) -> Self {
        RtPort {
            prefetcher: Some(prefetcher),
            ..self
        }
    }

    /// What each kind of warp cost in each phase so far, if this port runs in queues mode.
    pub fn warp_costs(&self) -> Option<warp_costs::WarpCosts> {
        match &self.hw {
            Hardware::Treelet(t) => Some(t.observer.warp_costs(&self.stats)),
            Hardware::Plain(_) => None,
        }
    }

    /// The statistics observer of the treelet hardware, if this port runs in queues mode.
    pub fn queue_stats(&self) -> Option<&QueueObserver> {
        match &self.hw {
            Hardware::Treelet(t) => Some(&t.observer),
            Hardware::Plain(_) => None,
        }
    }

    /// Queues mode with `rt.queued_stack_traffic`: the queued-stack chunk stores and loads
    /// issued, (0, 0) otherwise.
    pub fn queued_stack_chunks(&self) -> (u64, u64) {
        match &self.hw {
            Hardware::Treelet(t) => t.stacks.as_ref().map_or((0, 0), |q| (q.stores, q.loads)),
            Hardware::Plain(_) => (0, 0),
        }
    }

    /// Queues mode: records the treelet tables' input ports of the next `cycles` cycles (call
    /// before the first step); returns false outside queues mode.
    pub fn record_tables(&mut self, cycles: usize) -> bool {
        match &mut self.hw {
            Hardware::Treelet(t) => {
                t.cache.record_tables(cycles, t.unit.params());
                true
            }
            Hardware::Plain(_) => false,
        }
    }

    /// The tables' inputs recorded so far ([`RtPort::record_tables`]).
    pub fn take_table_log(&mut self) -> Option<vtq_hdl::treelet_rt_unit::TableLog> {
        match &mut self.hw {
            Hardware::Treelet(t) => t.cache.take_table_log(),
            Hardware::Plain(_) => None,
        }
    }

    /// The treelet prefetcher, if this port has one.
    pub fn prefetcher(&self) -> Option<&Prefetcher<'a>> {
        self.prefetcher.as_ref()
    }

    /// Whether a warp can be offered this cycle (queues mode: a slot may be given to an SM warp
    /// and a warp's worth of ray ids is free; the controller may still reserve the slot).
    pub fn issue_ready(&self) -> bool {
        match &self.hw {
            Hardware::Plain(p) => p.unit.issue_ready(&p.regs),
            Hardware::Treelet(t) => t.unit.sm_ready(&t.regs, &t.cache),
        }
    }

    /// The RT unit's statistics.
    pub fn hw_stats(&self) -> &RtStats {
        &self.stats
    }

    /// RT-unit warp cycles and traversing lanes summed over them, through cycle `end - 1`
    /// (`end >= at`): the counters so far plus the idle cycles from `at` to `end` not caught up
    /// yet, which add each resident warp and its traversing lanes per cycle (as a skip would).
    pub fn warp_counters_until(&self, end: u64) -> (u64, u64) {
        let n = end.saturating_sub(self.at);
        // Resident warps and their traversing lanes.
        let tally = |slots: &mut dyn Iterator<Item = Option<u32>>| {
            slots
                .flatten()
                .fold((0u64, 0u64), |(w, l), lanes| (w + 1, l + u64::from(lanes)))
        };
        let (warps, lanes) = match &self.hw {
            _ if n == 0 => (0, 0),
            Hardware::Plain(p) => tally(&mut p.unit.slot_lanes(&p.regs, &p.cache)),
            Hardware::Treelet(t) => tally(&mut t.unit.slot_lanes(&t.regs, &t.cache)),
        };
        (
            self.stats.warp_cycles + n * warps,
            self.stats.active_thread_cycles + n * lanes,
        )
    }

    /// SIMT efficiency averaged per warp ([`WarpSimt`]).
    pub fn warp_simt(&self) -> &WarpSimt {
        &self.warp_simt
    }

    /// Follows the warp-buffer slots over the next `n` cycles, in the registers' current state
    /// (the start of the cycle `at`; before a step or a skip of those cycles).
    pub(super) fn observe_warps(&mut self, n: u64) {
        match &self.hw {
            Hardware::Plain(p) => self
                .warp_simt
                .observe(n, p.unit.slot_lanes(&p.regs, &p.cache)),
            Hardware::Treelet(t) => self
                .warp_simt
                .observe(n, t.unit.slot_lanes(&t.regs, &t.cache)),
        }
    }

    /// Rays traversing in the warp buffer.
    pub fn active_rays(&self) -> u64 {
        match &self.hw {
            Hardware::Plain(p) => p.unit.traversing_rays(&p.regs, &p.cache),
            Hardware::Treelet(t) => t.unit.traversing_rays(&t.regs, &t.cache),
        }
    }

    /// The warp-buffer entry of `rays` (one per lane, `None` for idle lanes; an occlusion ray
    /// carries the terminate-on-first-hit flag), ray ids from warp-buffer slot `slot`'s lanes;
    /// a ray that is not valid enters already finished (a miss, as in the functional tracer).
    fn warp_lanes(
        &self,
        slot: usize,
        rays: &[Option<TraceRay>],
        warp_size: usize,
    ) -> Vec<Option<RayRecord>> {
        let internal = self.bvh.params().internal_node_bytes();
        let root = node_entry(HEADER_ADDR, NodeKind::Header, internal);
        (0..warp_size)
            .map(|lane| {
                let TraceRay { ray, occlusion } = rays.get(lane).copied().flatten()?;
                let id = (slot * warp_size + lane) as u32;
                let words = ray_words(&ray);
                Some(if ray.is_valid() {
                    RayRecord {
                        occlusion,
                        ..RayRecord::new(id, words, root)
                    }
                } else {
                    RayRecord {
                        ray_id: id,
                        words,
                        occlusion,
                        ..RayRecord::default()
                    }
                })
            })
            .collect()
    }

    /// Moves SM `sm`'s responses due by `now` from memory to the RT unit's return queue (node
    /// chunks and stack fills) or, for ray-record loads, to the next step's inputs with the
    /// record from the store. CTA-state loads (ray virtualization) are the SM's: they go to
    /// `cta_state`.
    pub fn collect_responses(&mut self, now: u64, mem: &mut L1Port, cta_state: &mut Vec<Response>) {
        if let Hardware::Treelet(t) = &mut self.hw {
            while let Some(&(due, slot, ray)) = t.record_loads.front() {
                if due > now {
                    break;
                }
                t.record_loads.pop_front();
                t.record_arrived(slot, ray);
            }
        }
        for r in mem.pop_ready(now) {
            if r.store {
                continue;
            }
            match r.class {
                AccessClass::CtaState => cta_state.push(r),
                AccessClass::RayRecord => {
                    if let Hardware::Treelet(t) = &mut self.hw {
                        let slot = (r.tag & 0xFFFF) as u32;
                        let ray = ((r.tag & !RAY_LOAD_TAG) >> 16) as u32;
                        t.record_arrived(slot, ray);
                    }
                }
                AccessClass::RayStack => {
                    if let Hardware::Treelet(t) = &mut self.hw {
                        if let Some(load) = t.stacks.as_mut().and_then(|q| q.chunk_arrived(r.tag)) {
                            t.arrived.push(load);
                        }
                    }
                }
                AccessClass::Stack => self.responses.push_back(MemResponse {
                    address: r.addr,
                    tag: r.tag as u32,
                    data: self.spill.load(r.addr),
                }),
                AccessClass::Bvh | AccessClass::HitRecord => {
                    let mut data = [0u8; CHUNK_BYTES as usize];
                    data.copy_from_slice(self.bvh.bytes_at(r.addr as u32, CHUNK_BYTES));
                    self.responses.push_back(MemResponse {
                        address: r.addr,
                        tag: r.tag as u32,
                        data,
                    });
                }
            }
        }
    }

    /// Whether cycle `now` must be evaluated: a warp is offered (`offering`), responses or
    /// ray records are waiting, a finished SM warp is to return, or the hardware's idle cycles
    /// end by `now`.
    pub fn busy_at(&self, now: u64, offering: bool) -> bool {
        debug_assert_eq!(
            self.wake,
            self.at.saturating_add(self.idle_cycles()),
            "stale wake cycle"
        );
        offering
            || !self.responses.is_empty()
            || self.wake <= now
            || match &self.hw {
                Hardware::Plain(_) => false,
                Hardware::Treelet(t) => !t.completed.is_empty() || !t.arrived.is_empty(),
            }
    }

    /// The hardware's idle cycles from `at`.
    fn idle_cycles(&self) -> u64 {
        match &self.hw {
            Hardware::Plain(p) => p.unit.idle_cycles(&p.regs, &p.cache),
            Hardware::Treelet(t) => t.unit.idle_cycles(&t.regs, &t.cache),
        }
    }

    /// Catches the registers up to the start of cycle `now` over idle cycles (recording those
    /// in a waveform's window).
    pub fn catch_up(&mut self, now: u64) {
        if now <= self.at {
            return;
        }
        if self.waveform.is_some() {
            self.catch_up_recorded(now);
        } else {
            self.skip_to(now);
        }
    }

    /// Skips the registers to the start of cycle `now` (`now >= at`) over idle cycles.
    fn skip_to(&mut self, now: u64) {
        let n = now - self.at;
        if n == 0 {
            return;
        }
        self.observe_warps(n);
        match &mut self.hw {
            Hardware::Plain(p) => {
                let counts = p.unit.skip(&mut p.regs, &mut p.cache, n);
                self.stats.add(&counts);
            }
            Hardware::Treelet(t) => {
                // The controller is not evaluated in idle cycles: its mode holds throughout.
                let phase = treelet::phase_index(t.unit.mode(&t.regs));
                let kind = t.unit.warp_kind(&t.regs).unwrap_or(t.observer.cell.1);
                t.observer.enter_cell((phase, kind), &self.stats);
                let counts = t.unit.skip(&mut t.regs, &mut t.cache, n);
                self.stats.add(&counts.rt);
                t.observer.counts.add(&counts);
                t.observer.add_warp_cycles(phase, &counts.rt);
            }
        }
        self.at = now;
    }

    /// One cycle `now` of the RT unit (after catching up idle cycles): offers `warp` (SM warp
    /// slot and its lanes' rays) if given, feeds responses, and queues its memory requests.
    pub fn step(
        &mut self,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Result<RtCycle, SimError> {
        self.catch_up(now);
        self.observe_warps(1);
        self.at = now + 1;
        let cycle = if matches!(self.hw, Hardware::Plain(_)) {
            self.step_plain(now, sm, warp)?
        } else {
            self.step_treelet(now, sm, warp)?
        };
        self.wake = self.at.saturating_add(self.idle_cycles());
        self.max_queue = self.max_queue.max(self.requests.len() as u64);
        Ok(cycle)
    }

    /// Queues the RT unit's memory request `req` (a stack spill's data goes to the spill area).
    fn push_request(&mut self, req: &HwRequest) {
        let class = match req.kind {
            RequestKind::NodeLoad => AccessClass::Bvh,
            RequestKind::HitStore => AccessClass::HitRecord,
            RequestKind::StackSpill | RequestKind::StackFill => AccessClass::Stack,
        };
        if req.kind == RequestKind::StackSpill {
            self.spill.store(req.address, req.data);
        }
        if req.kind == RequestKind::NodeLoad {
            // The response copies these bytes tens to hundreds of cycles later: ask the host's
            // caches for them now (a hint only; it changes no result).
            self.bvh.prefetch_bytes(req.address);
        }
        self.requests.push_back(if req.is_store() {
            MemRequest::store(req.address, CHUNK_BYTES, class, req.tag as u64)
        } else {
            MemRequest::load(req.address, CHUNK_BYTES, class, req.tag as u64)
        });
    }

    /// Offers the head of the memory access queue to the SM's L1 in phase `phase` of cycle
    /// `now` (one request per cycle); returns whether one was accepted. With the queue empty
    /// (no demand request this cycle) the prefetcher, if any, may offer one prefetch instead
    /// (not counted as accepted).
    pub fn send(&mut self, now: u64, phase: u8, mem: &mut L1Port) -> Result<bool, SimError> {
        let Some(&req) = self.requests.front() else {
            if let Some(p) = self.prefetcher.as_mut() {
                p.issue(now, phase, mem)?;
            }
            return Ok(false);
        };
        if now < self.retry_at {
            return Ok(false);
        }
        match mem.access(now, phase, req) {
            Ok(acceptance) => {
                self.requests.pop_front();
                if let Hardware::Treelet(t) = &mut self.hw {
                    if req.class == AccessClass::Bvh && !req.store && !req.prefetch {
                        let (phase, kind) = t.observer.cell;
                        t.observer
                            .costs
                            .cell(phase, kind)
                            .count_bvh_access(&acceptance);
                    }
                }
                Ok(true)
            }
            Err(AccessError::Stall(s)) => {
                self.retry_at = s.retry_at.max(now + 1);
                Ok(false)
            }
            Err(e) => Err(SimError::Memory(e)),
        }
    }

    /// After the L1 port settled L2 results: makes a deferred stall's retry cycle real if that
    /// settle resolved it (here and in the prefetcher).
    pub fn settle_retries(&mut self, mem: &L1Port) {
        self.retry_at = mem.resolve_retry(self.retry_at);
        if let Some(p) = self.prefetcher.as_mut() {
            p.settle_retry(mem);
        }
    }

    /// The next cycle after `now` at which this port has work, assuming no new warp: a response
    /// or request to move, a queued prefetch, ray records or a finished SM warp to hand on, or
    /// the end of the hardware's idle cycles.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        let mut next = None::<u64>;
        let mut at = |c: u64| next = Some(next.map_or(c, |n| n.min(c)));
        if !self.responses.is_empty() {
            at(now + 1);
        }
        if !self.requests.is_empty() {
            at(self.retry_at.max(now + 1));
        }
        if self.wake != u64::MAX {
            at(self.wake.max(now + 1));
        }
        if let Some(c) = self.prefetcher.as_ref().and_then(|p| p.next_event(now)) {
            at(c);
        }
        if let Hardware::Treelet(t) = &self.hw {
            if !t.completed.is_empty() || !t.arrived.is_empty() {
                at(now + 1);
            }
            if let Some(&(due, ..)) = t.record_loads.front() {
                at(due.max(now + 1));
            }
        }
        next
    }

    /// A summary of the registers and queues, for the watchdog.
    pub fn debug_state(&self) -> String {
        let common = format!(
            "access queue {} (retry at {}), return queue {}, prefetches queued {}",
            self.requests.len(),
            self.retry_at,
            self.responses.len(),
            self.prefetcher.as_ref().map_or(0, Prefetcher::pending)
        );
        match &self.hw {
            Hardware::Plain(p) => format!(
                "{}; warps {:?}; {common}",
                p.unit.debug_state(&p.regs, &p.cache),
                p.slot_warp
            ),
            Hardware::Treelet(t) => format!(
                "{}; {common}; spill FIFO {}; SM warps waiting for rays {}, returning {}; ray \
                 records waiting for their stacks {}",
                t.unit.debug_state(&t.regs),
                t.spill_fifo.len(),
                t.pending.len(),
                t.completed.len(),
                t.stacks.as_ref().map_or(0, QueuedStacks::held)
            ),
        }
    }
}
