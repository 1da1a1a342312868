//! One SM's RT unit in the simulated GPU ([`RtPort`]): the hardware model
//! [`vtq_hdl::rt_unit::RtUnit`] with its registers, the memory access queue between its memory
//! scheduler and the L1 (requests wait there while the L1 stalls), and the return path that
//! feeds memory responses into the response FIFO (at most `resp_ports` per cycle and never more
//! than `resp_free`). Node data comes from the BVH image; hit-record stores go to memory;
//! traversal-stack spills are stored in this SM's stack spill area ([`SpillMemory`]) and
//! stack fills read them back.

use std::collections::{BTreeMap, HashMap, VecDeque};

use vtq_hdl::rt_unit::{
    ErrorKind, ErrorRecord, MemResponse, RayRecord, RequestKind, RtCache, RtStats, RtUnit,
    RtUnitError, RtUnitInputs, RtUnitOutputs, RtUnitParams, RtUnitRegs, TraversalOrder, WarpIssue,
    CHUNK_BYTES,
};
use vtq_hdl::{Block, HwConfig};

use crate::bvh::layout::HEADER_ADDR;
use crate::bvh::{HwBvh, NodeKind};
use crate::geometry::{Hit, Ray};
use crate::gpu::datapath::{hit_from_hw, node_entry, ray_words, BvhDatapath};
use crate::gpu::prefetch::Prefetcher;
use crate::gpu::treelet_queues::{FinishedRay, TreeletQueues};
use crate::gpu::SimError;
use crate::memory::{AccessClass, AccessError, MemRequest, MemorySystem, Response};

/// A warp the RT unit finished: its SM warp slot and each lane's closest hit (`None` for a
/// miss), for the lanes that carried a ray.
#[derive(Debug, Clone, PartialEq)]
pub struct TracedWarp {
    /// SM warp id (stable while its CTA is suspended).
    pub warp: usize,
    /// Per lane: `Some(hit or miss)` for lanes that carried a ray.
    pub hits: Vec<Option<Option<Hit>>>,
}

/// The contents of one SM's stack spill area: what the RT unit's spill stores wrote, by
/// address, read back by its fills (memory contents, not timing: timing is the memory
/// system's, through the `Stack` access class).
#[derive(Debug, Clone, Default)]
pub struct SpillMemory {
    chunks: HashMap<u64, [u8; CHUNK_BYTES as usize]>,
}

impl SpillMemory {
    /// Writes the 32 B chunk at `address`.
    fn store(&mut self, address: u64, data: [u8; CHUNK_BYTES as usize]) {
        self.chunks.insert(address, data);
    }

    /// The 32 B chunk at `address` (zeros where nothing was stored: the RT unit then reports
    /// an unmatched response).
    fn load(&self, address: u64) -> [u8; CHUNK_BYTES as usize] {
        self.chunks.get(&address).copied().unwrap_or_default()
    }
}

/// An error the RT unit raised, with where its ray came from, so the message can name the SM
/// warp, lane and pixel rather than a flag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtFault {
    /// The RT unit's first-error capture.
    pub record: ErrorRecord,
    /// SM warp (virtual id) and lane of the ray concerned, when known.
    pub owner: Option<(usize, u32)>,
    /// Pixel `(x, y)` of that ray's thread, when known (filled in by the engine).
    pub pixel: Option<(u32, u32)>,
    /// `hw.address_bits`, which sizes the stack spill area.
    pub address_bits: u32,
}

impl std::fmt::Display for RtFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = &self.record;
        write!(f, "{}", r.kind.describe())?;
        let ray = match (self.owner, self.pixel) {
            (Some((w, l)), Some((x, y))) => {
                format!("ray {} (SM warp {w}, lane {l}, pixel ({x}, {y}))", r.ray_id)
            }
            (Some((w, l)), None) => format!("ray {} (SM warp {w}, lane {l})", r.ray_id),
            _ => format!("ray {}", r.ray_id),
        };
        let at = format!("warp-buffer slot {}, lane {}", r.slot, r.lane);
        match r.kind {
            ErrorKind::SpillAreaFull => write!(
                f,
                ": {ray} in {at} needs {} spilled 32 B chunks of one stack, but its spill area \
                 holds {} (the area is sized from the free address space: raise \
                 hw.address_bits, now {})",
                r.value, r.limit, self.address_bits
            ),
            ErrorKind::BadChild if r.limit == 0 => write!(
                f,
                ": {ray} in {at}: a child at address {:#x} is misaligned, of a bad size or \
                 outside the address space",
                r.value
            ),
            ErrorKind::BadChild => write!(
                f,
                ": {ray} in {at}: {} children, the stack room per node (max_children = \
                 bvh.width) is {}",
                r.value, r.limit
            ),
            ErrorKind::FifoOverflow => write!(
                f,
                ": {} responses offered in one cycle, at most {} accepted (a simulator bug)",
                r.value, r.limit
            ),
            ErrorKind::UnmatchedResponse => write!(
                f,
                ": the response for address {:#x} (tag: {at}) (a simulator bug)",
                r.value
            ),
            ErrorKind::IssueWhileFull | ErrorKind::BadIssue | ErrorKind::BadCommand => write!(
                f,
                ": {ray}, {at}, value {}, limit {} (a simulator bug)",
                r.value, r.limit
            ),
        }
    }
}

/// Queues mode: an SM warp whose rays are spread over the RT unit and the treelet queues.
#[derive(Debug, Clone, PartialEq)]
struct PendingWarp {
    /// Per lane that carried a ray: `Some(closest hit)` (`Some(None)`, a miss, until the ray
    /// finishes); `None` for idle lanes.
    hits: Vec<Option<Option<Hit>>>,
    /// Rays still out.
    left: u32,
}

/// What one cycle of an [`RtPort`] produced.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RtCycle {
    /// The warp accepted this cycle (its SM warp slot).
    pub accepted: Option<usize>,
    /// The warp completed this cycle.
    pub done: Option<TracedWarp>,
    /// Whether the memory scheduler issued a request.
    pub requested: bool,
}

/// The RT unit of one SM with its memory queues.
#[derive(Debug, Clone)]
pub struct RtPort<'a> {
    unit: RtUnit<BvhDatapath<'a>>,
    regs: RtUnitRegs,
    /// The RT unit's simulation cache (lane summaries of `regs`).
    cache: RtCache,
    /// The RT unit's statistics, summed from its per-cycle counts.
    stats: RtStats,
    bvh: &'a HwBvh,
    order: TraversalOrder,
    /// SM warp slot held by each warp-buffer slot.
    slot_warp: Vec<Option<usize>>,
    /// Memory access queue (requests not yet accepted by the L1), oldest first.
    requests: VecDeque<MemRequest>,
    /// First cycle the head of `requests` may be offered again after a stall.
    retry_at: u64,
    /// Load responses waiting to enter the response FIFO.
    responses: VecDeque<MemResponse>,
    /// The RT unit's input bundle, reused every step so feeding responses does not allocate.
    inputs: RtUnitInputs,
    /// The cycle the registers stand at (the next cycle to evaluate); cycles before it that
    /// were not stepped were idle and are caught up lazily with [`RtUnit::skip`].
    at: u64,
    /// First cycle the RT unit has work again with idle inputs: `at + idle_cycles` (saturating),
    /// recomputed after every step. Skipping idle cycles leaves it unchanged (each skipped
    /// cycle advances `at` and lowers `idle_cycles` by one), so it is computed once per step
    /// instead of once per query.
    wake: u64,
    /// The treelet prefetcher (prefetch mode; in queues mode it serves the controller's
    /// preloads).
    prefetcher: Option<Prefetcher<'a>>,
    /// The treelet controller and tables (queues mode only).
    queues: Option<TreeletQueues>,
    /// Queues mode: SM warps with rays still traversing, by warp id.
    pending: BTreeMap<usize, PendingWarp>,
    /// Queues mode: SM warps whose rays have all finished, returned one per cycle.
    completed: VecDeque<TracedWarp>,
    /// Contents of this SM's stack spill area.
    spill: SpillMemory,
    /// `hw.address_bits`, for error messages.
    address_bits: u32,
    /// Most requests queued at once.
    pub max_queue: u64,
    /// Rays issued.
    pub rays_issued: u64,
    /// Rays completed.
    pub rays_completed: u64,
}

impl<'a> RtPort<'a> {
    /// The RT unit of one SM: `hw` sizes, `params` timing (with this SM's hit-record base),
    /// warps traversing in `order`.
    pub fn new(
        hw: &HwConfig,
        params: RtUnitParams,
        bvh: &'a HwBvh,
        order: TraversalOrder,
    ) -> Result<Self, RtUnitError> {
        let unit = RtUnit::new(hw.clone(), params, BvhDatapath::new(bvh))?;
        let regs = unit.reset();
        let cache = RtCache::of(&regs);
        let wake = unit.idle_cycles(&regs, &cache);
        let inputs = unit.idle_inputs();
        Ok(RtPort {
            slot_warp: vec![None; hw.warp_buffer_size as usize],
            unit,
            regs,
            cache,
            stats: RtStats::default(),
            bvh,
            order,
            requests: VecDeque::new(),
            retry_at: 0,
            responses: VecDeque::new(),
            inputs,
            at: 0,
            wake,
            prefetcher: None,
            queues: None,
            pending: BTreeMap::new(),
            completed: VecDeque::new(),
            spill: SpillMemory::default(),
            address_bits: hw.address_bits,
            max_queue: 0,
            rays_issued: 0,
            rays_completed: 0,
        })
    }

    /// The same port with a treelet prefetcher beside the RT unit.
    pub fn with_prefetcher(self, prefetcher: Prefetcher<'a>) -> Self {
        RtPort {
            prefetcher: Some(prefetcher),
            ..self
        }
    }

    /// The same port in queues mode: `queues` decides which rays the RT unit traverses; a
    /// prefetcher (if any) preloads the treelets it names.
    pub fn with_queues(self, queues: TreeletQueues) -> Self {
        RtPort {
            queues: Some(queues),
            ..self
        }
    }

    /// The treelet controller and tables, if this port runs in queues mode.
    pub fn queues(&self) -> Option<&TreeletQueues> {
        self.queues.as_ref()
    }

    /// The treelet prefetcher, if this port has one.
    pub fn prefetcher(&self) -> Option<&Prefetcher<'a>> {
        self.prefetcher.as_ref()
    }

    /// Whether a warp can be issued this cycle (queues mode: a slot may be given to an SM warp
    /// and a warp's worth of ray ids is free; the controller may still reserve the slot).
    pub fn issue_ready(&self) -> bool {
        match &self.queues {
            Some(q) => q.sm_may_issue(&self.regs),
            None => self.unit.issue_ready(&self.regs),
        }
    }

    /// The hardware statistics registers.
    pub fn hw_stats(&self) -> &RtStats {
        &self.stats
    }

    /// Rays traversing in the warp buffer.
    pub fn active_rays(&self) -> u64 {
        self.regs
            .slots
            .iter()
            .filter(|s| s.valid)
            .flat_map(|s| s.lanes.iter())
            .filter(|l| l.status == vtq_hdl::rt_unit::LaneStatus::Traversing)
            .count() as u64
    }

    /// The warp-buffer entry of `rays` (one per lane, `None` for idle lanes) of SM warp `warp`;
    /// a ray that is not valid enters already finished (a miss, as in the functional tracer).
    fn warp_issue(&self, slot: usize, rays: &[Option<Ray>]) -> WarpIssue {
        let warp_size = self.unit.config().warp_size as usize;
        let internal = self.bvh.params().internal_node_bytes();
        let root = node_entry(HEADER_ADDR, NodeKind::Header, internal);
        let lanes = (0..warp_size)
            .map(|lane| {
                let ray = rays.get(lane).copied().flatten()?;
                let id = (slot * warp_size + lane) as u32;
                let words = ray_words(&ray);
                Some(if ray.is_valid() {
                    RayRecord::new(id, words, root)
                } else {
                    RayRecord {
                        ray_id: id,
                        words,
                        ..RayRecord::default()
                    }
                })
            })
            .collect();
        WarpIssue {
            order: self.order,
            lanes,
            ..WarpIssue::default()
        }
    }

    /// Moves SM `sm`'s load responses due by `now` from memory to the return queue. CTA-state
    /// loads (ray virtualization) are the SM's, not the RT unit's: they go to `cta_state`.
    pub fn collect_responses(
        &mut self,
        now: u64,
        sm: usize,
        mem: &mut MemorySystem,
        cta_state: &mut Vec<Response>,
    ) {
        for r in mem.pop_ready(sm, now) {
            if r.store {
                continue;
            }
            if r.class == AccessClass::CtaState {
                cta_state.push(r);
                continue;
            }
            if r.class == AccessClass::RayRecord {
                if let Some(q) = self.queues.as_mut() {
                    q.ray_loaded(r.tag);
                }
                continue;
            }
            let data = if r.class == AccessClass::Stack {
                self.spill.load(r.addr)
            } else {
                let mut data = [0u8; CHUNK_BYTES as usize];
                data.copy_from_slice(self.bvh.bytes_at(r.addr as u32, CHUNK_BYTES));
                data
            };
            self.responses.push_back(MemResponse {
                address: r.addr,
                tag: r.tag as u32,
                data,
            });
        }
    }

    /// Whether cycle `now` must be evaluated: a warp is offered (`offering`), responses are
    /// waiting, or the RT unit's idle cycles end by `now`.
    pub fn busy_at(&self, now: u64, offering: bool) -> bool {
        debug_assert_eq!(
            self.wake,
            self.at
                .saturating_add(self.unit.idle_cycles(&self.regs, &self.cache)),
            "stale wake cycle"
        );
        offering
            || !self.responses.is_empty()
            || self.wake <= now
            || !self.completed.is_empty()
            || self
                .queues
                .as_ref()
                .is_some_and(|q| q.busy() || q.wake() <= now)
    }

    /// Catches the registers up to the start of cycle `now` over idle cycles.
    pub fn catch_up(&mut self, now: u64) {
        if now > self.at {
            let counts = self
                .unit
                .skip(&mut self.regs, &mut self.cache, now - self.at);
            self.stats.add(&counts);
            if let Some(q) = self.queues.as_mut() {
                q.skip(now - self.at);
            }
            self.at = now;
        }
    }

    /// One cycle `now` of the RT unit (after catching up idle cycles): issues `warp` (SM warp
    /// slot and its lanes' rays) if given and a slot is free, feeds responses, and queues its
    /// memory request.
    pub fn step(
        &mut self,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<Ray>])>,
    ) -> Result<RtCycle, SimError> {
        self.catch_up(now);
        self.at = now + 1;
        self.inputs.issue = None;
        self.inputs.stop = None;
        self.inputs.repack = None;
        self.inputs.responses.clear();
        let mut cycle = RtCycle::default();
        if self.queues.is_some() {
            cycle.accepted = self.queue_commands(sm, warp)?;
        } else if let Some((idx, rays)) = warp {
            if let Some(slot) = self.regs.slots.iter().position(|s| !s.valid) {
                let issue = self.warp_issue(slot, rays);
                self.unit
                    .check_issue(&issue)
                    .map_err(|e| SimError::Rt { sm, source: e })?;
                self.rays_issued += issue.lanes.iter().flatten().count() as u64;
                self.slot_warp[slot] = Some(idx);
                self.inputs.issue = Some(issue);
                cycle.accepted = Some(idx);
            }
        }
        let ports = self
            .unit
            .resp_free(&self.regs)
            .min(self.unit.params().resp_ports);
        let n = (ports as usize).min(self.responses.len());
        self.inputs.responses.extend(self.responses.drain(..n));
        let out = self
            .unit
            .step_cached(&mut self.regs, &mut self.cache, &self.inputs);
        self.stats.add(&out.counts);
        self.wake = self
            .at
            .saturating_add(self.unit.idle_cycles(&self.regs, &self.cache));
        if let (Some(p), None) = (self.prefetcher.as_mut(), &self.queues) {
            p.observe(self.unit.next_addresses(&self.regs, &self.cache));
        }
        if let Some(record) = out.first_error {
            return Err(SimError::RtUnit {
                sm,
                fault: Box::new(self.fault(record)),
            });
        }
        if let Some(req) = out.request {
            let class = match req.kind {
                RequestKind::NodeLoad => AccessClass::Bvh,
                RequestKind::HitStore => AccessClass::HitRecord,
                RequestKind::StackSpill | RequestKind::StackFill => AccessClass::Stack,
            };
            if req.kind == RequestKind::StackSpill {
                self.spill.store(req.address, req.data);
            }
            let r = if req.is_store() {
                MemRequest::store(req.address, CHUNK_BYTES, class, req.tag as u64)
            } else {
                MemRequest::load(req.address, CHUNK_BYTES, class, req.tag as u64)
            };
            self.requests.push_back(r);
            self.max_queue = self.max_queue.max(self.requests.len() as u64);
            cycle.requested = true;
        }
        if self.queues.is_some() {
            self.queue_results(sm, &out)?;
            cycle.done = self.completed.pop_front();
        } else if let Some(done) = out.done {
            let warp =
                self.slot_warp[done.slot as usize]
                    .take()
                    .ok_or_else(|| SimError::Queues {
                        sm,
                        reason: format!(
                            "warp-buffer slot {} completed a warp it never got",
                            done.slot
                        ),
                    })?;
            let hits: Vec<Option<Option<Hit>>> = done
                .lanes
                .iter()
                .map(|l| l.as_ref().map(|(rec, _)| rec.hit.as_ref().map(hit_from_hw)))
                .collect();
            self.rays_completed += hits.iter().flatten().count() as u64;
            cycle.done = Some(TracedWarp { warp, hits });
        }
        Ok(cycle)
    }

    /// The fault of an RT-unit error `record`, with the SM warp and lane of its ray where
    /// known (the pixel is the engine's to add).
    fn fault(&self, record: ErrorRecord) -> RtFault {
        let owner = match &self.queues {
            Some(q) => q.owner(record.ray_id),
            None => self
                .slot_warp
                .get(record.slot as usize)
                .copied()
                .flatten()
                .map(|w| (w, record.lane)),
        };
        let owner = owner.filter(|_| {
            !matches!(
                record.kind,
                ErrorKind::FifoOverflow | ErrorKind::UnmatchedResponse
            )
        });
        RtFault {
            record,
            owner,
            pixel: None,
            address_bits: self.address_bits,
        }
    }

    /// Queues mode, before the RT unit steps: runs the treelet controller and tables, turns their
    /// commands into the RT unit's inputs and admits SM warp `warp` if it may enter; returns
    /// the admitted warp.
    fn queue_commands(
        &mut self,
        sm: usize,
        warp: Option<(usize, &[Option<Ray>])>,
    ) -> Result<Option<usize>, SimError> {
        let q = self.queues.as_mut().expect("queues mode");
        let cmd = q.before_step(
            &self.unit,
            (&self.regs, &self.cache, &self.stats),
            warp.is_some(),
            &mut self.requests,
        );
        self.inputs.stop = cmd.stop;
        self.inputs.repack = cmd.repack;
        if let (Some(t), Some(p)) = (cmd.preload, self.prefetcher.as_mut()) {
            p.queue_treelet(t);
        }
        let mut accepted = None;
        let issue = match (cmd.issue, cmd.sm_slot, warp) {
            (Some(issue), _, _) => Some(issue),
            (None, Some(slot), Some((idx, rays))) => {
                let lanes = self.warp_issue(0, rays).lanes;
                let active = lanes.iter().flatten().count();
                let q = self.queues.as_mut().expect("queues mode");
                let issue = q.admit(idx, slot, lanes, &mut self.requests);
                if issue.is_some() {
                    accepted = Some(idx);
                    self.rays_issued += active as u64;
                    let lanes = self.unit.config().warp_size as usize;
                    let hits = (0..lanes)
                        .map(|l| rays.get(l).copied().flatten().map(|_| None))
                        .collect::<Vec<_>>();
                    if active == 0 {
                        self.completed.push_back(TracedWarp { warp: idx, hits });
                    } else {
                        let left = active as u32;
                        self.pending.insert(idx, PendingWarp { hits, left });
                    }
                }
                issue
            }
            _ => None,
        };
        if let Some(issue) = &issue {
            self.unit
                .check_issue(issue)
                .map_err(|e| SimError::Rt { sm, source: e })?;
        }
        self.inputs.issue = issue;
        self.max_queue = self.max_queue.max(self.requests.len() as u64);
        Ok(accepted)
    }

    /// Queues mode, after the RT unit stepped: hands finished rays back to their SM warps
    /// (a warp whose last ray finished joins `completed`).
    fn queue_results(&mut self, sm: usize, out: &RtUnitOutputs) -> Result<(), SimError> {
        let q = self.queues.as_mut().expect("queues mode");
        let mut finished: Vec<FinishedRay> = Vec::new();
        q.after_step(
            &self.unit,
            (&self.regs, &self.cache),
            out,
            self.at,
            &mut finished,
        );
        if let Some(reason) = q.fault() {
            return Err(SimError::Queues {
                sm,
                reason: reason.to_string(),
            });
        }
        for f in finished {
            let Some(PendingWarp { hits, left }) = self.pending.get_mut(&f.warp) else {
                return Err(SimError::Queues {
                    sm,
                    reason: format!("a ray of SM warp {} finished twice", f.warp),
                });
            };
            if let Some(h) = hits.get_mut(f.lane as usize) {
                *h = Some(f.hit);
            }
            *left -= 1;
            self.rays_completed += 1;
            if *left == 0 {
                let done = self.pending.remove(&f.warp).expect("present");
                self.completed.push_back(TracedWarp {
                    warp: f.warp,
                    hits: done.hits,
                });
            }
        }
        Ok(())
    }

    /// Offers the head of the memory access queue to the L1 (one request per cycle); returns
    /// whether one was accepted. With the queue empty (no demand request this cycle) the
    /// prefetcher, if any, may offer one prefetch instead (not counted as accepted).
    pub fn send(&mut self, now: u64, sm: usize, mem: &mut MemorySystem) -> Result<bool, SimError> {
        let Some(&req) = self.requests.front() else {
            if let Some(p) = self.prefetcher.as_mut() {
                p.issue(now, sm, mem)?;
            }
            return Ok(false);
        };
        if now < self.retry_at {
            return Ok(false);
        }
        match mem.access(now, sm, req) {
            Ok(_) => {
                self.requests.pop_front();
                Ok(true)
            }
            Err(AccessError::Stall(s)) => {
                self.retry_at = s.retry_at.max(now + 1);
                Ok(false)
            }
            Err(e) => Err(SimError::Memory(e)),
        }
    }

    /// The next cycle after `now` at which this port has work, assuming no new warp: a response
    /// or request to move, a queued prefetch, or the end of the RT unit's idle cycles.
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
        if let Some(q) = &self.queues {
            if q.busy() || !self.completed.is_empty() {
                at(now + 1);
            } else if q.wake() != u64::MAX {
                at(q.wake().max(now + 1));
            }
        }
        next
    }

    /// Queues mode: attributes the last intersection tests to their phase (call at the end).
    pub fn finish(&mut self) {
        if let Some(q) = self.queues.as_mut() {
            q.finish(&self.stats);
        }
    }

    /// A summary of the registers and queues, for the watchdog.
    pub fn debug_state(&self) -> String {
        let r = &self.regs;
        let lanes: Vec<String> = r
            .slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.valid)
            .map(|(i, s)| {
                let count = |st| s.lanes.iter().filter(|l| l.status == st).count();
                use vtq_hdl::rt_unit::LaneStatus::*;
                format!(
                    "slot {i} (warp {:?}): {} traversing, {} done, {} in flight, {} delayed, {} stores pending",
                    self.slot_warp[i],
                    count(Traversing),
                    count(Done),
                    s.lanes.iter().filter(|l| l.in_flight.is_some()).count(),
                    s.lanes.iter().filter(|l| l.delay > 0).count(),
                    s.lanes.iter().filter(|l| l.store_pending).count()
                )
            })
            .collect();
        format!(
            "RT unit: fifo {}, split {:?}, errors {:#x}, idle for {}; {}; access queue {} (retry at {}), return queue {}, prefetches queued {}",
            r.fifo.len(),
            r.split,
            r.errors,
            self.unit.idle_cycles(r, &self.cache),
            if lanes.is_empty() { "no warps".to_string() } else { lanes.join("; ") },
            self.requests.len(),
            self.retry_at,
            self.responses.len(),
            self.prefetcher.as_ref().map_or(0, Prefetcher::pending)
        ) + &self.queues.as_ref().map_or(String::new(), |q| {
            format!(
                "\n  {}; SM warps waiting for rays {}, returning {}",
                q.debug_state(),
                self.pending.len(),
                self.completed.len()
            )
        })
    }
}
