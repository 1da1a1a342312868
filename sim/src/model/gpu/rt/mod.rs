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

use std::collections::VecDeque;

use vtq_hdl::rt_unit::{
    ErrorRecord, MemRequest as HwRequest, MemResponse, RayRecord, RequestKind, RtStats,
    RtUnitError, RtUnitParams, TraversalOrder, CHUNK_BYTES,
};
use vtq_hdl::HwConfig;

use crate::model::bvh::layout::HEADER_ADDR;
use crate::model::bvh::{HwBvh, NodeKind};
use crate::model::geometry::Hit;
use crate::model::gpu::datapath::{node_entry, ray_words, BvhDatapath};
use crate::model::gpu::error::SimError;
use crate::model::gpu::prefetch::Prefetcher;
use crate::model::gpu::ray_memory::SpillMemory;
use crate::model::gpu::rt_fault::RtFault;
use crate::model::gpu::warp_simt::WarpSimt;
use crate::model::memory::{AccessClass, AccessError, L1Port, MemRequest, Response};
use crate::model::workload::kind::TraceRay;

mod hardware;
mod plain;
mod treelet;
pub mod warp_costs;

use hardware::{Kind, RtHardware};
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

/// Resident warps and their traversing lanes, from the warp-buffer slots' lane counts (`None`:
/// a free slot).
fn tally(slots: impl Iterator<Item = Option<u32>>) -> (u64, u64) {
    slots
        .flatten()
        .fold((0, 0), |(w, l), lanes| (w + 1, l + u64::from(lanes)))
}

/// The RT unit of one SM with its memory queues: the design's RT hardware ([`RtHardware`]) in
/// its surroundings ([`Shell`]).
#[derive(Debug)]
pub struct RtPort<'a> {
    hw: Kind<'a>,
    shell: Shell<'a>,
}

/// What surrounds an SM's RT hardware, whatever its kind: the memory queues, the memory contents
/// it reads and writes, its statistics and the waveform.
#[derive(Debug)]
pub(super) struct Shell<'a> {
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
    max_queue: u64,
    /// Rays issued.
    rays_issued: u64,
    /// Rays completed.
    rays_completed: u64,
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
        // The design's kind of RT hardware: one implementation of [`RtHardware`] each.
        let kind = match queues {
            None => Kind::Plain(Box::new(Plain::new(hw, params, datapath)?)),
            Some(setup) => Kind::Treelet(Box::new(Treelet::new(hw, params, datapath, setup)?)),
        };
        let wake = kind.idle_cycles();
        Ok(RtPort {
            hw: kind,
            shell: Shell {
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
            },
        })
    }

    /// The same port with a treelet prefetcher beside the RT unit (prefetch mode), or serving
    /// the treelet controller's preloads (queues mode).
    pub fn with_prefetcher(mut self, prefetcher: Prefetcher<'a>) -> Self {
        self.shell.prefetcher = Some(prefetcher);
        self
    }

    /// What each kind of warp cost in each phase so far, if this port runs in queues mode.
    pub fn warp_costs(&self) -> Option<warp_costs::WarpCosts> {
        self.hw.warp_costs(&self.shell.stats)
    }

    /// The statistics observer of the treelet hardware, if this port runs in queues mode.
    pub fn queue_stats(&self) -> Option<&QueueObserver> {
        self.hw.queue_stats()
    }

    /// Queues mode with `rt.queued_stack_traffic`: the queued-stack chunk stores and loads
    /// issued, (0, 0) otherwise.
    pub fn queued_stack_chunks(&self) -> (u64, u64) {
        self.hw.queued_stack_chunks()
    }

    /// Queues mode: records the treelet tables' input ports of the next `cycles` cycles (call
    /// before the first step); returns false outside queues mode.
    pub fn record_tables(&mut self, cycles: usize) -> bool {
        self.hw.record_tables(cycles)
    }

    /// The tables' inputs recorded so far ([`RtPort::record_tables`]).
    pub fn take_table_log(&mut self) -> Option<vtq_hdl::treelet_rt_unit::TableLog> {
        self.hw.take_table_log()
    }

    /// Most requests queued at once.
    pub fn max_queue(&self) -> u64 {
        self.shell.max_queue
    }

    /// Rays issued.
    pub fn rays_issued(&self) -> u64 {
        self.shell.rays_issued
    }

    /// Rays completed.
    pub fn rays_completed(&self) -> u64 {
        self.shell.rays_completed
    }

    /// The treelet prefetcher, if this port has one.
    pub fn prefetcher(&self) -> Option<&Prefetcher<'a>> {
        self.shell.prefetcher.as_ref()
    }

    /// Whether a warp can be offered this cycle (queues mode: a slot may be given to an SM warp
    /// and a warp's worth of ray ids is free; the controller may still reserve the slot).
    pub fn issue_ready(&self) -> bool {
        self.hw.issue_ready()
    }

    /// The RT unit's statistics.
    pub fn hw_stats(&self) -> &RtStats {
        &self.shell.stats
    }

    /// RT-unit warp cycles and traversing lanes summed over them, through cycle `end - 1`
    /// (`end >= at`): the counters so far plus the idle cycles from `at` to `end` not caught up
    /// yet, which add each resident warp and its traversing lanes per cycle (as a skip would).
    pub fn warp_counters_until(&self, end: u64) -> (u64, u64) {
        let n = end.saturating_sub(self.shell.at);
        let (warps, lanes) = if n == 0 { (0, 0) } else { self.hw.resident() };
        (
            self.shell.stats.warp_cycles + n * warps,
            self.shell.stats.active_thread_cycles + n * lanes,
        )
    }

    /// SIMT efficiency averaged per warp ([`WarpSimt`]).
    pub fn warp_simt(&self) -> &WarpSimt {
        &self.shell.warp_simt
    }

    /// Follows the warp-buffer slots over the next `n` cycles, in the registers' current state
    /// (the start of the cycle `at`; before a step or a skip of those cycles).
    pub(super) fn observe_warps(&mut self, n: u64) {
        self.hw.observe_warps(&mut self.shell.warp_simt, n);
    }

    /// Rays traversing in the warp buffer.
    pub fn active_rays(&self) -> u64 {
        self.hw.traversing_rays()
    }

    /// Moves SM `sm`'s responses due by `now` from memory to the RT unit's return queue (node
    /// chunks and stack fills) or, for ray-record loads, to the next step's inputs with the
    /// record from the store. CTA-state loads (ray virtualization) are the SM's: they go to
    /// `cta_state`.
    pub fn collect_responses(&mut self, now: u64, mem: &mut L1Port, cta_state: &mut Vec<Response>) {
        self.hw.records_due(now);
        for r in mem.pop_ready(now) {
            if r.store {
                continue;
            }
            match r.class {
                AccessClass::CtaState => cta_state.push(r),
                AccessClass::RayRecord | AccessClass::RayStack => self.hw.ray_response(&r),
                AccessClass::Stack => self.shell.responses.push_back(MemResponse {
                    address: r.addr,
                    tag: r.tag as u32,
                    data: self.shell.spill.load(r.addr),
                }),
                AccessClass::Bvh | AccessClass::HitRecord => {
                    let mut data = [0u8; CHUNK_BYTES as usize];
                    data.copy_from_slice(self.shell.bvh.bytes_at(r.addr as u32, CHUNK_BYTES));
                    self.shell.responses.push_back(MemResponse {
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
            self.shell.wake,
            self.shell.at.saturating_add(self.idle_cycles()),
            "stale wake cycle"
        );
        offering || !self.shell.responses.is_empty() || self.shell.wake <= now || self.hw.has_work()
    }

    /// The hardware's idle cycles from `at`.
    fn idle_cycles(&self) -> u64 {
        self.hw.idle_cycles()
    }

    /// Catches the registers up to the start of cycle `now` over idle cycles (recording those
    /// in a waveform's window).
    pub fn catch_up(&mut self, now: u64) {
        if now <= self.shell.at {
            return;
        }
        if self.shell.waveform.is_some() {
            self.catch_up_recorded(now);
        } else {
            self.skip_to(now);
        }
    }

    /// Skips the registers to the start of cycle `now` (`now >= at`) over idle cycles.
    fn skip_to(&mut self, now: u64) {
        let n = now - self.shell.at;
        if n == 0 {
            return;
        }
        self.observe_warps(n);
        self.hw.skip(n, &mut self.shell.stats);
        self.shell.at = now;
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
        self.shell.at = now + 1;
        let cycle = self.hw.step(&mut self.shell, now, sm, warp)?;
        self.shell.wake = self.shell.at.saturating_add(self.idle_cycles());
        self.shell.max_queue = self.shell.max_queue.max(self.shell.requests.len() as u64);
        Ok(cycle)
    }

    /// Offers the head of the memory access queue to the SM's L1 in phase `phase` of cycle
    /// `now` (one request per cycle); returns whether one was accepted. With the queue empty
    /// (no demand request this cycle) the prefetcher, if any, may offer one prefetch instead
    /// (not counted as accepted).
    pub fn send(&mut self, now: u64, phase: u8, mem: &mut L1Port) -> Result<bool, SimError> {
        let Some(&req) = self.shell.requests.front() else {
            if let Some(p) = self.shell.prefetcher.as_mut() {
                p.issue(now, phase, mem)?;
            }
            return Ok(false);
        };
        if now < self.shell.retry_at {
            return Ok(false);
        }
        match mem.access(now, phase, req) {
            Ok(acceptance) => {
                self.shell.requests.pop_front();
                if req.class == AccessClass::Bvh && !req.store && !req.prefetch {
                    // Not stepped in cycle `now` (`at <= now`): an idle cycle, caught up later.
                    self.hw
                        .bvh_access_accepted(&acceptance, self.shell.at <= now);
                }
                Ok(true)
            }
            Err(AccessError::Stall(s)) => {
                self.shell.retry_at = s.retry_at.max(now + 1);
                Ok(false)
            }
            Err(e) => Err(SimError::Memory(e)),
        }
    }

    /// After the L1 port settled L2 results: makes a deferred stall's retry cycle real if that
    /// settle resolved it (here and in the prefetcher).
    pub fn settle_retries(&mut self, mem: &L1Port) {
        self.shell.retry_at = mem.resolve_retry(self.shell.retry_at);
        if let Some(p) = self.shell.prefetcher.as_mut() {
            p.settle_retry(mem);
        }
    }

    /// The next cycle after `now` at which this port has work, assuming no new warp: a response
    /// or request to move, a queued prefetch, ray records or a finished SM warp to hand on, or
    /// the end of the hardware's idle cycles.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        let mut next = None::<u64>;
        let mut at = |c: u64| next = Some(next.map_or(c, |n| n.min(c)));
        if !self.shell.responses.is_empty() {
            at(now + 1);
        }
        if !self.shell.requests.is_empty() {
            at(self.shell.retry_at.max(now + 1));
        }
        if self.shell.wake != u64::MAX {
            at(self.shell.wake.max(now + 1));
        }
        if let Some(c) = self
            .shell
            .prefetcher
            .as_ref()
            .and_then(|p| p.next_event(now))
        {
            at(c);
        }
        if let Some(c) = self.hw.next_event(now) {
            at(c);
        }
        next
    }

    /// A summary of the registers and queues, for the watchdog.
    pub fn debug_state(&self) -> String {
        let common = format!(
            "access queue {} (retry at {}), return queue {}, prefetches queued {}",
            self.shell.requests.len(),
            self.shell.retry_at,
            self.shell.responses.len(),
            self.shell
                .prefetcher
                .as_ref()
                .map_or(0, Prefetcher::pending)
        );
        self.hw.debug_state(&common)
    }
}

impl Shell<'_> {
    /// The warp-buffer entry of `rays` (one per lane, `None` for idle lanes; an occlusion ray
    /// carries the terminate-on-first-hit flag), ray ids from warp-buffer slot `slot`'s lanes;
    /// a ray that is not valid enters already finished (a miss, as in the functional tracer).
    pub(super) fn warp_lanes(
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

    /// Queues the RT unit's memory request `req` (a stack spill's data goes to the spill area).
    pub(super) fn push_request(&mut self, req: &HwRequest) {
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
}
