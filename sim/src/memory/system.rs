//! [`MemorySystem`]: per-SM L1s, the shared L2 and DRAM, with completion cycles fixed at
//! acceptance (the timing rules are in the [module documentation](super)).

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fmt::Write as _;
use std::ops::Range;

use super::cache::{EvictedLine, SectorCache, SectorState};
use super::config::{MemConfig, MemConfigError};
use super::dram::DramChannel;
use super::request::{
    Accepted, AccessClass, AccessError, MemRequest, Response, Source, Stall, StallReason, MAX_CYCLE,
};
use super::responses::ResponseQueue;
use super::stats::MemStats;

/// Per-SM state: the SM's L1, its outstanding misses and its undelivered responses.
#[derive(Debug, Clone)]
struct SmPort {
    l1: SectorCache,
    /// Fill cycles of the outstanding L1 misses (one MSHR each), earliest first; entries at
    /// or before the current cycle are free.
    mshrs: BinaryHeap<Reverse<u64>>,
    responses: ResponseQueue,
}

/// The memory hierarchy of the simulated GPU: one L1 per SM, a shared L2 and one DRAM channel.
///
/// Every accepted access gets its completion cycle when it is accepted, so the memory system
/// has no per-cycle work: an engine calls [`access`](Self::access) in non-decreasing cycle
/// order, delivers responses with [`pop_ready`](Self::pop_ready), and may jump straight to
/// [`next_event`](Self::next_event) when nothing else happens in between.
#[derive(Debug, Clone)]
pub struct MemorySystem {
    cfg: MemConfig,
    sms: Vec<SmPort>,
    /// Per SM: completion cycle of its next response (`u64::MAX` when none), kept beside the
    /// ports so [`next_event`](Self::next_event) scans one small array.
    due: Vec<u64>,
    l2: SectorCache,
    dram: DramChannel,
    /// Lines per L1 set.
    l1_set_ways: u32,
    /// Lines per L2 set.
    l2_set_ways: u32,
    /// log2 of the line size (validated to be a power of two).
    line_shift: u32,
    /// log2 of the sector size (validated to be a power of two).
    sector_shift: u32,
    /// Acceptance counter: breaks completion-cycle ties.
    seq: u64,
    /// Cycle of the latest access.
    last_now: u64,
    stats: MemStats,
}

impl MemorySystem {
    /// An empty memory system for `num_sms` SMs; fails on an invalid configuration or 0 SMs.
    pub fn new(cfg: &MemConfig, num_sms: usize) -> Result<Self, MemConfigError> {
        cfg.validate()?;
        if num_sms == 0 {
            return Err(MemConfigError::NoSms);
        }
        let port = SmPort {
            l1: SectorCache::new(cfg.l1_geometry()),
            mshrs: BinaryHeap::with_capacity(cfg.l1_mshrs as usize),
            responses: ResponseQueue::new(),
        };
        Ok(MemorySystem {
            cfg: cfg.clone(),
            sms: vec![port; num_sms],
            due: vec![u64::MAX; num_sms],
            l2: SectorCache::new(cfg.l2_geometry()),
            dram: DramChannel::new(cfg.dram_latency, cfg.dram_bytes_per_cycle),
            l1_set_ways: cfg.l1_geometry().ways,
            l2_set_ways: cfg.l2_geometry().ways,
            line_shift: cfg.line_bytes.trailing_zeros(),
            sector_shift: cfg.sector_bytes.trailing_zeros(),
            seq: 0,
            last_now: 0,
            stats: MemStats::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MemConfig {
        &self.cfg
    }

    /// Number of SMs (L1s).
    pub fn num_sms(&self) -> usize {
        self.sms.len()
    }

    /// Counters so far.
    pub fn stats(&self) -> MemStats {
        self.stats
    }

    fn l1_latency(&self) -> u64 {
        u64::from(self.cfg.l1_latency)
    }

    fn l2_latency(&self) -> u64 {
        u64::from(self.cfg.l2_latency)
    }

    /// Line address and sector index of a byte address.
    fn locate(&self, addr: u64) -> (u64, u32) {
        let line = addr >> self.line_shift;
        let offset = addr & ((1 << self.line_shift) - 1);
        (line, (offset >> self.sector_shift) as u32)
    }

    /// Offers one request from SM `sm` at cycle `now` (cycles must not decrease from call to
    /// call). On success the access's completion cycle is fixed and, unless it is a
    /// prefetch, a [`Response`] is delivered at that cycle. `Err(AccessError::Stall)` means
    /// retry later (nothing changed but the stall counters); other errors are bad requests.
    pub fn access(
        &mut self,
        now: u64,
        sm: usize,
        req: MemRequest,
    ) -> Result<Accepted, AccessError> {
        self.check(now, sm, &req)?;
        self.last_now = now;
        let (line, sector) = self.locate(req.addr);
        let at_l2 = now + self.l1_latency();
        if req.store {
            if !req.bypass_l1 {
                let l1 = &mut self.sms[sm].l1;
                let slot = l1.lookup(line);
                let hit =
                    slot.is_some_and(|s| l1.sector_state(s, sector, now) == SectorState::Ready);
                if let (true, Some(slot)) = (hit, slot) {
                    l1.touch(slot);
                }
                let class = self.stats.class_mut(req.class);
                class.l1_stores += 1;
                class.l1_store_hits += u64::from(hit);
            } else {
                self.stats.class_mut(req.class).l1_bypasses += 1;
            }
            self.l2_write(at_l2, line, sector, req.class);
            let done = at_l2 + self.l2_latency();
            self.respond(sm, &req, done, Source::L2Write);
            return Ok(Accepted {
                done,
                source: Source::L2Write,
            });
        }
        if req.bypass_l1 {
            self.stats.class_mut(req.class).l1_bypasses += 1;
            let (done, source) = self.l2_read(at_l2, line, sector, req.class);
            self.respond(sm, &req, done, source);
            return Ok(Accepted { done, source });
        }
        let l1 = &self.sms[sm].l1;
        let slot = l1.lookup(line);
        let state = slot.map_or(SectorState::Absent, |s| l1.sector_state(s, sector, now));
        if req.prefetch && state != SectorState::Absent {
            self.stats.prefetch.requests += 1;
            self.stats.prefetch.dropped += 1;
            return Ok(Accepted {
                done: now,
                source: Source::AlreadyInL1,
            });
        }
        let (done, source, slot) = match (state, slot) {
            (SectorState::Ready, Some(slot)) => (now + self.l1_latency(), Source::L1Hit, slot),
            (SectorState::Pending { ready_at }, Some(slot)) => (ready_at, Source::L1Merge, slot),
            _ => return self.l1_miss(now, sm, req, line, sector),
        };
        let port = &mut self.sms[sm];
        port.l1.touch(slot);
        let used = port.l1.take_prefetched(slot, sector);
        self.stats.prefetch.used += u64::from(used);
        let class = self.stats.class_mut(req.class);
        class.l1_loads += 1;
        match source {
            Source::L1Hit => class.l1_hits += 1,
            _ => class.l1_merges += 1,
        }
        self.respond(sm, &req, done, source);
        Ok(Accepted { done, source })
    }

    /// Rejects malformed requests and out-of-order cycles.
    fn check(&self, now: u64, sm: usize, req: &MemRequest) -> Result<(), AccessError> {
        if sm >= self.sms.len() {
            return Err(AccessError::NoSuchSm {
                sm,
                num_sms: self.sms.len(),
            });
        }
        let sector_bytes = self.cfg.sector_bytes;
        let offset = req.addr & ((1 << self.sector_shift) - 1);
        if req.bytes == 0 || offset + u64::from(req.bytes) > u64::from(sector_bytes) {
            return Err(AccessError::BadSize {
                addr: req.addr,
                bytes: req.bytes,
                sector_bytes,
            });
        }
        if req.prefetch && (req.store || req.bypass_l1) {
            return Err(AccessError::BadPrefetch { addr: req.addr });
        }
        if now > MAX_CYCLE {
            return Err(AccessError::CycleOutOfRange { now });
        }
        if now < self.last_now {
            return Err(AccessError::TimeWentBackwards {
                now,
                last: self.last_now,
            });
        }
        Ok(())
    }

    /// A demand load or prefetch whose sector is absent from the L1: allocate an MSHR and a
    /// line (or stall), then read through the L2.
    fn l1_miss(
        &mut self,
        now: u64,
        sm: usize,
        req: MemRequest,
        line: u64,
        sector: u32,
    ) -> Result<Accepted, AccessError> {
        let ways = self.l1_set_ways;
        let port = &mut self.sms[sm];
        while port.mshrs.peek().is_some_and(|&Reverse(fill)| fill <= now) {
            port.mshrs.pop();
        }
        if port.mshrs.len() >= self.cfg.l1_mshrs as usize {
            self.stats.mshr_stalls += 1;
            let retry_at = port.mshrs.peek().map_or(now + 1, |&Reverse(fill)| fill);
            return Err(AccessError::Stall(Stall {
                reason: StallReason::MshrsFull,
                retry_at,
            }));
        }
        let slot = match port.l1.find_slot(line, now, 0..ways) {
            Ok(slot) => slot,
            Err(retry_at) => {
                self.stats.set_stalls += 1;
                return Err(AccessError::Stall(Stall {
                    reason: StallReason::SetReserved,
                    retry_at,
                }));
            }
        };
        let (done, source) = self.l2_read(now + self.l1_latency(), line, sector, req.class);
        let port = &mut self.sms[sm];
        if let Some(evicted) = port.l1.install(slot, line, sector, done) {
            self.stats.prefetch.evicted_unused += u64::from(evicted.unused_prefetch.count_ones());
        }
        port.mshrs.push(Reverse(done));
        if req.prefetch {
            port.l1.mark_prefetched(slot, sector);
            self.stats.prefetch.requests += 1;
            self.stats.prefetch.issued += 1;
        } else {
            let class = self.stats.class_mut(req.class);
            class.l1_loads += 1;
            class.l1_misses += 1;
            self.respond(sm, &req, done, source);
        }
        Ok(Accepted { done, source })
    }

    /// Ways of an L2 set that `class` may allocate into.
    fn l2_ways(&self, class: AccessClass) -> Range<u32> {
        let ways = self.l2_set_ways;
        match (self.cfg.l2_ray_ways, class) {
            (0, _) => 0..ways,
            (ray, AccessClass::RayRecord) => 0..ray,
            (ray, _) => ray..ways,
        }
    }

    /// A read reaching the L2 at cycle `at`: returns its completion cycle and source.
    fn l2_read(&mut self, at: u64, line: u64, sector: u32, class: AccessClass) -> (u64, Source) {
        let hit_done = at + self.l2_latency();
        let slot = self.l2.lookup(line);
        let state = slot.map_or(SectorState::Absent, |s| self.l2.sector_state(s, sector, at));
        let stats = self.stats.class_mut(class);
        stats.l2_accesses += 1;
        match (state, slot) {
            (SectorState::Ready, Some(slot)) => {
                stats.l2_hits += 1;
                self.l2.touch(slot);
                (hit_done, Source::L2Hit)
            }
            (SectorState::Pending { ready_at }, Some(slot)) => {
                stats.l2_merges += 1;
                self.l2.touch(slot);
                (ready_at.max(hit_done), Source::L2Merge)
            }
            _ => {
                stats.l2_misses += 1;
                stats.dram_reads += 1;
                let grant = self.dram.schedule(hit_done, self.cfg.sector_bytes);
                let dram = &mut self.stats.dram;
                dram.reads += 1;
                dram.read_bytes += u64::from(self.cfg.sector_bytes);
                dram.queue_cycles += grant.start - hit_done;
                match self.l2.find_slot(line, at, self.l2_ways(class)) {
                    Ok(slot) => {
                        let evicted = self.l2.install(slot, line, sector, grant.done);
                        self.write_back(hit_done, evicted);
                    }
                    Err(_) => self.stats.l2_no_allocate += 1,
                }
                (grant.done, Source::Dram)
            }
        }
    }

    /// A store reaching the L2 at cycle `at` (write-back, write-allocate without a fetch).
    fn l2_write(&mut self, at: u64, line: u64, sector: u32, class: AccessClass) {
        let leave = at + self.l2_latency();
        let slot = self.l2.lookup(line);
        let state = slot.map_or(SectorState::Absent, |s| self.l2.sector_state(s, sector, at));
        let stats = self.stats.class_mut(class);
        stats.l2_accesses += 1;
        let slot = match (state, slot) {
            (SectorState::Ready, Some(slot)) => {
                stats.l2_hits += 1;
                Some(slot)
            }
            (SectorState::Pending { .. }, Some(slot)) => {
                stats.l2_merges += 1;
                Some(slot)
            }
            _ => {
                stats.l2_misses += 1;
                match self.l2.find_slot(line, at, self.l2_ways(class)) {
                    Ok(slot) => {
                        let evicted = self.l2.install(slot, line, sector, at);
                        self.write_back(leave, evicted);
                        Some(slot)
                    }
                    Err(_) => {
                        self.stats.l2_no_allocate += 1;
                        self.dram_write(leave);
                        None
                    }
                }
            }
        };
        // Without an L2 line (not allocated) there is nothing to update.
        if let Some(slot) = slot {
            self.l2.touch(slot);
            self.l2.mark_dirty(slot, sector);
        }
    }

    /// Writes the dirty sectors of an evicted L2 line to DRAM, leaving the L2 at `leave`.
    fn write_back(&mut self, leave: u64, evicted: Option<EvictedLine>) {
        if let Some(evicted) = evicted {
            for _ in 0..evicted.dirty.count_ones() {
                self.dram_write(leave);
            }
        }
    }

    /// One sector write to DRAM arriving at `arrival` (takes bandwidth; nobody waits for it).
    fn dram_write(&mut self, arrival: u64) {
        let grant = self.dram.schedule(arrival, self.cfg.sector_bytes);
        let dram = &mut self.stats.dram;
        dram.writes += 1;
        dram.write_bytes += u64::from(self.cfg.sector_bytes);
        dram.queue_cycles += grant.start - arrival;
    }

    /// Queues the response to `req`, served from `source`, for cycle `done`.
    fn respond(&mut self, sm: usize, req: &MemRequest, done: u64, source: Source) {
        let seq = self.seq;
        self.seq += 1;
        let response = Response {
            tag: req.tag,
            addr: req.addr,
            class: req.class,
            store: req.store,
            cycle: done,
        };
        self.sms[sm].responses.push(seq, source, response);
        self.due[sm] = self.due[sm].min(done);
    }

    /// Removes and yields SM `sm`'s responses due at or before `now`, in completion-cycle
    /// order, ties in acceptance order (empty for an SM that does not exist). Responses the
    /// caller does not consume stay queued.
    pub fn pop_ready(&mut self, sm: usize, now: u64) -> impl Iterator<Item = Response> + '_ {
        let mut queue = self.sms.get_mut(sm).map(|port| &mut port.responses);
        let mut due = self.due.get_mut(sm);
        std::iter::from_fn(move || {
            let due = due.as_mut()?;
            if **due > now {
                return None;
            }
            let queue = queue.as_mut()?;
            let response = queue.pop_due(now);
            **due = queue.earliest().unwrap_or(u64::MAX);
            response
        })
    }

    /// Earliest cycle at which some SM has a response due, if any is queued. Fills without a
    /// response (prefetches) are not events: their effect is already in the cache state.
    pub fn next_event(&self) -> Option<u64> {
        self.due.iter().copied().min().filter(|&c| c != u64::MAX)
    }

    /// Completion cycle of SM `sm`'s next response, if one is queued (`None` also for an SM
    /// that does not exist). Only SM `sm`'s own accesses change it, so an engine can keep
    /// per-SM wake times.
    pub fn next_response(&self, sm: usize) -> Option<u64> {
        self.due.get(sm).copied().filter(|&c| c != u64::MAX)
    }

    /// Responses queued for SM `sm` (0 for an SM that does not exist).
    pub fn pending_responses(&self, sm: usize) -> usize {
        self.sms.get(sm).map_or(0, |port| port.responses.len())
    }

    /// State at cycle `now` of the L1 sector holding `addr` in SM `sm` (`None` when the SM
    /// does not exist).
    pub fn l1_sector(&self, sm: usize, addr: u64, now: u64) -> Option<SectorState> {
        let (line, sector) = self.locate(addr);
        self.sms
            .get(sm)
            .map(|port| port.l1.state(line, sector, now))
    }

    /// Whether SM `sm`'s L1 holds or is filling the sector of `addr` (false for an SM that
    /// does not exist). A prefetcher can skip such sectors.
    pub fn l1_contains(&self, sm: usize, addr: u64) -> bool {
        self.l1_sector(sm, addr, 0)
            .is_some_and(|state| state != SectorState::Absent)
    }

    /// State at cycle `now` (in L2 time, i.e. the cycle a request reaches the L2) of the L2
    /// sector holding `addr`.
    pub fn l2_sector(&self, addr: u64, now: u64) -> SectorState {
        let (line, sector) = self.locate(addr);
        self.l2.state(line, sector, now)
    }

    /// A human-readable dump of the outstanding work at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let mut out = String::new();
        let (l2_pending, l2_next) = self.l2.pending_sectors(now);
        let _ = writeln!(
            out,
            "memory at cycle {now} (last access at {}): {} accesses accepted, next event {:?}",
            self.last_now,
            self.seq,
            self.next_event()
        );
        let _ = writeln!(
            out,
            "  L2: {} lines, {l2_pending} sectors being filled (first fill {l2_next:?}); DRAM free from cycle {}",
            self.l2.lines_present(),
            self.dram.next_free_cycle()
        );
        for (sm, port) in self.sms.iter().enumerate() {
            let busy: Vec<u64> = port
                .mshrs
                .iter()
                .map(|&Reverse(f)| f)
                .filter(|&f| f > now)
                .collect();
            let next = port.responses.peek();
            let _ = writeln!(
                out,
                "  SM {sm}: L1 {} lines, MSHRs {}/{} busy (first fill {:?}), {} responses queued (next {:?})",
                port.l1.lines_present(),
                busy.len(),
                self.cfg.l1_mshrs,
                busy.iter().min(),
                port.responses.len(),
                next
            );
        }
        out
    }
}
