//! [`L1Port`]: one SM's side of the memory hierarchy — its L1, its MSHRs and its undelivered
//! responses — which decides everything about an access that the L1 alone decides and sends
//! the rest to the shared L2 as an [`L2Op`].
//!
//! # Deferred L2 results
//! An access that needs the L2 (an L1 miss, an L1-bypassing load, a store) cannot complete
//! before `l1_latency + l2_latency` cycles after its acceptance (the *L2 round trip*), so
//! nothing the SM does in the meantime depends on its L2 result. The port therefore records the
//! operation ([`L1Port::ops`]) and gives the access a placeholder completion cycle
//! ([`PENDING_BASE`] + the operation's number, counted over the whole run) that compares later
//! than every real cycle; the caller applies the operations to the
//! [`L2Side`](super::l2::L2Side) in [`L2Op::key`] order (merged over all SMs), hands the results
//! back ([`L1Port::set_result`]) and calls [`L1Port::settle`], which replaces the placeholders
//! of the oldest operations that have their results by the real cycles and queues their
//! responses. The port may run up to one L2 round trip past its oldest unsettled acceptance
//! ([`L1Port::horizon`]): before that cycle a placeholder is always later than the cycle being
//! simulated, and so is the real cycle it stands for, so every decision it takes part in (a
//! sector being filled, a line reserved, an MSHR busy) is the same whether the operation is
//! settled or not — settling early (as soon as results arrive) or late gives the same results.
//! The one value that may be needed earlier, the retry cycle of a stall when the earliest known
//! fill is past the horizon, is itself a placeholder ([`RETRY_BASE`] + the stall's number)
//! resolved by the settle that makes it certain ([`L1Port::resolve_retry`]). Settling after
//! every access gives the plain, immediate model ([`super::MemorySystem`]).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::cache::{SectorCache, SectorState};
use super::config::MemConfig;
use super::l2::L2Op;
use super::request::{
    Accepted, AccessError, MemRequest, Response, Source, Stall, StallReason, MAX_CYCLE,
};
use super::responses::ResponseQueue;
use super::stats::MemStats;

/// Placeholder completion cycles start here: operation number `k` (counted over the run)
/// completes at `PENDING_BASE + k` until settled. Above every real cycle ([`MAX_CYCLE`]).
pub const PENDING_BASE: u64 = 1 << 62;

/// Placeholder retry cycles start here: deferred stall number `j` (counted over the run) may
/// retry at `RETRY_BASE + j` until resolved ([`L1Port::resolve_retry`]). Above every real
/// cycle, below [`PENDING_BASE`].
pub const RETRY_BASE: u64 = 1 << 61;

/// What the L1 port made of an accepted access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Acceptance {
    /// Decided by the L1 alone: completion cycle and source are final.
    Known(Accepted),
    /// Its completion depends on unsettled L2 operation `op` (its own, or the fill it merged
    /// with, `merge`).
    Pending {
        /// Number of the operation ([`L1Port::first_op`] numbers [`L1Port::ops`]' first).
        op: u64,
        /// The access merged with that operation's L1 fill (source [`Source::L1Merge`]).
        merge: bool,
    },
}

/// What settling an L2 operation does on the L1 side.
#[derive(Debug, Clone, Copy)]
struct Reply {
    /// An L1 miss: its sector's fill cycle and its MSHR wait for the result.
    fill: bool,
    /// The response to queue (its cycle is the result's), with its acceptance number.
    respond: Option<(u64, Response)>,
}

/// One SM's L1, MSHRs and response queue, with its unsettled L2 operations.
#[derive(Debug, Clone)]
pub struct L1Port {
    sm: u32,
    l1: SectorCache,
    /// Fill cycles of the outstanding L1 misses (one MSHR each), earliest first; entries at
    /// or before the current cycle are free.
    mshrs: BinaryHeap<Reverse<u64>>,
    responses: ResponseQueue,
    /// Completion cycle of the next response (`u64::MAX` when none).
    due: u64,
    /// Acceptance counter: breaks completion-cycle ties between this SM's responses.
    seq: u64,
    /// Cycle of the latest access.
    last_now: u64,
    /// The L2 round trip: an operation's result is never earlier than this after its
    /// acceptance.
    round_trip: u64,
    /// Number of the first unsettled operation (`ops[0]`).
    first: u64,
    /// Unsettled L2 operations, in acceptance order.
    ops: Vec<L2Op>,
    /// What each operation does when settled.
    replies: Vec<Reply>,
    /// Each operation's result, once applied.
    results: Vec<Option<(u64, Source)>>,
    /// Merges with unsettled fills: (operation number, acceptance number, response).
    waiting: Vec<(u64, u64, Response)>,
    /// Unresolved deferred stalls: for each, its number and the candidates' fill cycles (a
    /// candidate is free once all its values have passed; the retry cycle is the earliest
    /// candidate).
    stalls: Vec<(u64, Vec<Vec<u64>>)>,
    /// Deferred stalls so far.
    stalls_made: u64,
    /// The deferred stalls resolved by the last settle: (number, retry cycle).
    retries: Vec<(u64, u64)>,
    l1_latency: u64,
    l1_ways: u32,
    l1_mshrs: usize,
    sector_bytes: u32,
    line_shift: u32,
    sector_shift: u32,
    stats: MemStats,
}

impl L1Port {
    /// SM `sm`'s port with an empty L1 (`cfg` already validated).
    pub fn new(cfg: &MemConfig, sm: u32) -> Self {
        L1Port {
            sm,
            l1: SectorCache::new(cfg.l1_geometry()),
            mshrs: BinaryHeap::with_capacity(cfg.l1_mshrs as usize),
            responses: ResponseQueue::new(),
            due: u64::MAX,
            seq: 0,
            last_now: 0,
            round_trip: Self::round_trip(cfg),
            first: 0,
            ops: Vec::new(),
            replies: Vec::new(),
            results: Vec::new(),
            waiting: Vec::new(),
            stalls: Vec::new(),
            stalls_made: 0,
            retries: Vec::new(),
            l1_latency: u64::from(cfg.l1_latency),
            l1_ways: cfg.l1_geometry().ways,
            l1_mshrs: cfg.l1_mshrs as usize,
            sector_bytes: cfg.sector_bytes,
            line_shift: cfg.line_bytes.trailing_zeros(),
            sector_shift: cfg.sector_bytes.trailing_zeros(),
            stats: MemStats::default(),
        }
    }

    /// The L2 round trip in cycles: an L2 result is never needed sooner than this after its
    /// access was accepted.
    pub fn round_trip(cfg: &MemConfig) -> u64 {
        (u64::from(cfg.l1_latency) + u64::from(cfg.l2_latency)).max(1)
    }

    /// The first cycle this port may not simulate before its oldest unsettled operation is
    /// settled (one round trip after that operation's acceptance; `u64::MAX` with none): every
    /// placeholder, and the real cycle it stands for, is at or after it.
    pub fn horizon(&self) -> u64 {
        self.ops
            .first()
            .map_or(u64::MAX, |op| op.cycle.saturating_add(self.round_trip))
    }

    /// This SM's L1 counters (and prefetch counters); the L2 and DRAM ones are the L2's.
    pub fn stats(&self) -> &MemStats {
        &self.stats
    }

    /// Line address and sector index of a byte address.
    fn locate(&self, addr: u64) -> (u64, u32) {
        let line = addr >> self.line_shift;
        let offset = addr & ((1 << self.line_shift) - 1);
        (line, (offset >> self.sector_shift) as u32)
    }

    /// Rejects malformed requests and out-of-order cycles.
    fn check(&self, now: u64, req: &MemRequest) -> Result<(), AccessError> {
        let sector_bytes = self.sector_bytes;
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

    /// Offers `req` at cycle `now`, in phase `phase` of the cycle (cycles must not decrease
    /// from call to call). `Err(AccessError::Stall)` means retry later (only the stall counters
    /// changed); other errors are bad requests.
    pub fn access(
        &mut self,
        now: u64,
        phase: u8,
        req: MemRequest,
    ) -> Result<Acceptance, AccessError> {
        self.check(now, &req)?;
        self.last_now = now;
        let (line, sector) = self.locate(req.addr);
        if req.store {
            if !req.bypass_l1 {
                let slot = self.l1.lookup(line);
                let hit = slot
                    .is_some_and(|s| self.l1.sector_state(s, sector, now) == SectorState::Ready);
                if let (true, Some(slot)) = (hit, slot) {
                    self.l1.touch(slot);
                }
                let class = self.stats.class_mut(req.class);
                class.l1_stores += 1;
                class.l1_store_hits += u64::from(hit);
            } else {
                self.stats.class_mut(req.class).l1_bypasses += 1;
            }
            let respond = Some(self.deferred_response(&req));
            let op = self.push_op(now, phase, line, sector, &req, false, respond);
            return Ok(Acceptance::Pending { op, merge: false });
        }
        if req.bypass_l1 {
            self.stats.class_mut(req.class).l1_bypasses += 1;
            let respond = Some(self.deferred_response(&req));
            let op = self.push_op(now, phase, line, sector, &req, false, respond);
            return Ok(Acceptance::Pending { op, merge: false });
        }
        let slot = self.l1.lookup(line);
        let state = slot.map_or(SectorState::Absent, |s| {
            self.l1.sector_state(s, sector, now)
        });
        if req.prefetch && state != SectorState::Absent {
            self.stats.prefetch.requests += 1;
            self.stats.prefetch.dropped += 1;
            return Ok(Acceptance::Known(Accepted {
                done: now,
                source: Source::AlreadyInL1,
            }));
        }
        let (done, source, slot) = match (state, slot) {
            (SectorState::Ready, Some(slot)) => (now + self.l1_latency, Source::L1Hit, slot),
            (SectorState::Pending { ready_at }, Some(slot)) => (ready_at, Source::L1Merge, slot),
            _ => return self.miss(now, phase, req, line, sector),
        };
        self.l1.touch(slot);
        let used = self.l1.take_prefetched(slot, sector);
        self.stats.prefetch.used += u64::from(used);
        let class = self.stats.class_mut(req.class);
        class.l1_loads += 1;
        match source {
            Source::L1Hit => class.l1_hits += 1,
            _ => class.l1_merges += 1,
        }
        if done >= PENDING_BASE {
            let op = done - PENDING_BASE;
            let (seq, response) = self.deferred_response(&req);
            self.waiting.push((op, seq, response));
            return Ok(Acceptance::Pending { op, merge: true });
        }
        self.respond(&req, done, source);
        Ok(Acceptance::Known(Accepted { done, source }))
    }

    /// A demand load or prefetch whose sector is absent from the L1: allocate an MSHR and a
    /// line (or stall), then read through the L2.
    fn miss(
        &mut self,
        now: u64,
        phase: u8,
        req: MemRequest,
        line: u64,
        sector: u32,
    ) -> Result<Acceptance, AccessError> {
        while self.mshrs.peek().is_some_and(|&Reverse(fill)| fill <= now) {
            self.mshrs.pop();
        }
        if self.mshrs.len() >= self.l1_mshrs {
            self.stats.mshr_stalls += 1;
            let earliest = self.mshrs.peek().map_or(now + 1, |&Reverse(fill)| fill);
            let retry_at = if self.exact(earliest) {
                earliest
            } else {
                let fills = self.mshrs.iter().map(|&Reverse(f)| vec![f]).collect();
                self.defer(earliest, fills)
            };
            return Err(AccessError::Stall(Stall {
                reason: StallReason::MshrsFull,
                retry_at,
            }));
        }
        let slot = match self.l1.find_slot(line, now, 0..self.l1_ways) {
            Ok(slot) => slot,
            Err(earliest) => {
                self.stats.set_stalls += 1;
                let retry_at = if self.exact(earliest) {
                    earliest
                } else {
                    let fills = self.l1.candidate_fills(line, 0..self.l1_ways);
                    self.defer(earliest, fills)
                };
                return Err(AccessError::Stall(Stall {
                    reason: StallReason::SetReserved,
                    retry_at,
                }));
            }
        };
        let pending = PENDING_BASE + self.first + self.ops.len() as u64;
        if let Some(evicted) = self.l1.install(slot, line, sector, pending) {
            self.stats.prefetch.evicted_unused += u64::from(evicted.unused_prefetch.count_ones());
        }
        self.mshrs.push(Reverse(pending));
        let respond = if req.prefetch {
            self.l1.mark_prefetched(slot, sector);
            self.stats.prefetch.requests += 1;
            self.stats.prefetch.issued += 1;
            None
        } else {
            let class = self.stats.class_mut(req.class);
            class.l1_loads += 1;
            class.l1_misses += 1;
            Some(self.deferred_response(&req))
        };
        let op = self.push_op(now, phase, line, sector, &req, true, respond);
        Ok(Acceptance::Pending { op, merge: false })
    }

    /// Whether `earliest`, the earliest candidate fill of a stall (placeholders compare later
    /// than real cycles), is its exact retry cycle for sure: a real cycle no later than the
    /// horizon, before which no pending fill completes.
    fn exact(&self, earliest: u64) -> bool {
        earliest < PENDING_BASE && earliest <= self.horizon()
    }

    /// The retry cycle of a stall whose candidates' fill cycles are `fills` and whose earliest
    /// candidate fill is `earliest`: `earliest` when no fill is pending, otherwise a deferred
    /// retry resolved by a later settle.
    fn defer(&mut self, earliest: u64, fills: Vec<Vec<u64>>) -> u64 {
        if fills.iter().flatten().all(|&f| f < PENDING_BASE) {
            return earliest;
        }
        let j = self.stalls_made;
        self.stalls_made += 1;
        self.stalls.push((j, fills));
        RETRY_BASE + j
    }

    /// Records an L2 operation and what settling it does; returns its number.
    #[allow(clippy::too_many_arguments)]
    fn push_op(
        &mut self,
        now: u64,
        phase: u8,
        line: u64,
        sector: u32,
        req: &MemRequest,
        fill: bool,
        respond: Option<(u64, Response)>,
    ) -> u64 {
        let k = self.first + self.ops.len() as u64;
        self.ops.push(L2Op {
            cycle: now,
            phase,
            sm: self.sm,
            seq: k,
            line,
            sector,
            class: req.class,
            write: req.store,
            prefetch: req.prefetch,
        });
        self.replies.push(Reply { fill, respond });
        self.results.push(None);
        k
    }

    /// The response to `req`, numbered now, its cycle to be filled in when settled.
    fn deferred_response(&mut self, req: &MemRequest) -> (u64, Response) {
        let seq = self.seq;
        self.seq += 1;
        (
            seq,
            Response {
                tag: req.tag,
                addr: req.addr,
                class: req.class,
                store: req.store,
                cycle: 0,
            },
        )
    }

    /// Queues the response to `req`, served from `source`, for cycle `done`.
    fn respond(&mut self, req: &MemRequest, done: u64, source: Source) {
        let (seq, mut response) = self.deferred_response(req);
        response.cycle = done;
        self.responses.push(seq, source, response);
        self.due = self.due.min(done);
    }

    /// Whether a stall waits for a settle to know its retry cycle (which may be any fill
    /// cycle past the horizon).
    pub fn has_deferred_stall(&self) -> bool {
        !self.stalls.is_empty()
    }

    /// The unsettled L2 operations, in acceptance order (to be applied in [`L2Op::key`] order
    /// over all SMs); the first is number [`first_op`](Self::first_op).
    pub fn ops(&self) -> &[L2Op] {
        &self.ops
    }

    /// The number of the first unsettled operation (every earlier one is settled).
    pub fn first_op(&self) -> u64 {
        self.first
    }

    /// Records the result of unsettled operation number `op` ([`super::l2::L2Side::apply`]).
    pub fn set_result(&mut self, op: u64, result: (u64, Source)) {
        self.results[(op - self.first) as usize] = Some(result);
    }

    /// The result of unsettled operation number `op`, once set.
    pub fn result(&self, op: u64) -> Option<(u64, Source)> {
        let k = op.checked_sub(self.first)?;
        self.results.get(k as usize).copied().flatten()
    }

    /// A value that may be a placeholder of one of the first `n` unsettled operations (all
    /// with results), made real; any other value unchanged.
    fn real(&self, value: u64, n: usize) -> u64 {
        match value.checked_sub(PENDING_BASE + self.first) {
            Some(k) if (k as usize) < n => {
                self.results[k as usize]
                    .expect("settled operations have their results")
                    .0
            }
            _ => value,
        }
    }

    /// Settles the oldest unsettled operations that have their results (all of them once every
    /// result is set), replacing their placeholders by the real cycles: fills the L1 sectors
    /// and MSHRs, queues the responses (in acceptance order among equal cycles) and resolves
    /// the deferred stalls whose retry cycle is now certain ([`resolve_retry`](Self::resolve_retry)
    /// gives them until the next settle). Returns how many it settled.
    pub fn settle(&mut self) -> usize {
        self.retries.clear();
        let n = self.results.iter().take_while(|r| r.is_some()).count();
        if n == 0 && self.stalls.is_empty() {
            return 0;
        }
        for k in 0..n {
            let (done, source) = self.results[k].expect("counted above");
            let reply = self.replies[k];
            let op = &self.ops[k];
            if reply.fill {
                let placeholder = PENDING_BASE + self.first + k as u64;
                self.l1.settle_fill(op.line, op.sector, placeholder, done);
            }
            if let Some((seq, mut response)) = reply.respond {
                response.cycle = done;
                self.responses.push(seq, source, response);
                self.due = self.due.min(done);
            }
        }
        let settled = PENDING_BASE + self.first..PENDING_BASE + self.first + n as u64;
        if self.mshrs.iter().any(|Reverse(f)| settled.contains(f)) {
            let fills: Vec<Reverse<u64>> = self
                .mshrs
                .iter()
                .map(|&Reverse(f)| Reverse(self.real(f, n)))
                .collect();
            self.mshrs = fills.into();
        }
        let mut waiting = std::mem::take(&mut self.waiting);
        waiting.retain(|&(op, seq, mut response)| {
            if !settled.contains(&(PENDING_BASE + op)) {
                return true;
            }
            response.cycle = self.real(PENDING_BASE + op, n);
            self.responses.push(seq, Source::L1Merge, response);
            self.due = self.due.min(response.cycle);
            false
        });
        self.waiting = waiting;
        let mut stalls = std::mem::take(&mut self.stalls);
        for (_, candidates) in &mut stalls {
            for f in candidates.iter_mut().flatten() {
                *f = self.real(*f, n);
            }
        }
        self.ops.drain(..n);
        self.replies.drain(..n);
        self.results.drain(..n);
        self.first += n as u64;
        // A candidate with a pending fill frees at or after the horizon; one whose fills are
        // all real frees when the last of them has passed.
        let horizon = self.horizon();
        stalls.retain(|(j, candidates)| {
            let known = candidates
                .iter()
                .filter(|fills| fills.iter().all(|&f| f < PENDING_BASE))
                .map(|fills| fills.iter().copied().max().unwrap_or(0))
                .min();
            let all_known = candidates
                .iter()
                .all(|fills| fills.iter().all(|&f| f < PENDING_BASE));
            match known {
                Some(retry) if all_known || retry <= horizon => {
                    self.retries.push((*j, retry));
                    false
                }
                _ => true,
            }
        });
        self.stalls = stalls;
        n
    }

    /// A retry cycle from a stall: a deferred one ([`RETRY_BASE`] + j) resolved by the last
    /// settle made real; any other value unchanged.
    pub fn resolve_retry(&self, retry_at: u64) -> u64 {
        if (RETRY_BASE..PENDING_BASE).contains(&retry_at) {
            let j = retry_at - RETRY_BASE;
            self.retries
                .iter()
                .find(|&&(k, _)| k == j)
                .map_or(retry_at, |&(_, r)| r)
        } else {
            retry_at
        }
    }

    /// Removes and yields the responses due at or before `now`, in completion-cycle order, ties
    /// in acceptance order. Responses the caller does not consume stay queued.
    pub fn pop_ready(&mut self, now: u64) -> impl Iterator<Item = Response> + '_ {
        std::iter::from_fn(move || {
            if self.due > now {
                return None;
            }
            let response = self.responses.pop_due(now);
            self.due = self.responses.earliest().unwrap_or(u64::MAX);
            response
        })
    }

    /// Completion cycle of the next queued response, if any (responses of unsettled
    /// operations are not queued yet).
    pub fn next_response(&self) -> Option<u64> {
        (self.due != u64::MAX).then_some(self.due)
    }

    /// Responses queued.
    pub fn pending_responses(&self) -> usize {
        self.responses.len()
    }

    /// State at cycle `now` of the L1 sector holding `addr`.
    pub fn l1_sector(&self, addr: u64, now: u64) -> SectorState {
        let (line, sector) = self.locate(addr);
        self.l1.state(line, sector, now)
    }

    /// Whether the L1 holds or is filling the sector of `addr` (a prefetcher can skip it).
    pub fn l1_contains(&self, addr: u64) -> bool {
        self.l1_sector(addr, 0) != SectorState::Absent
    }

    /// A one-line summary at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let busy: Vec<u64> = self
            .mshrs
            .iter()
            .map(|&Reverse(f)| f)
            .filter(|&f| f > now)
            .collect();
        format!(
            "SM {}: L1 {} lines, MSHRs {}/{} busy (first fill {:?}), {} responses queued (next \
             {:?}), {} accesses accepted",
            self.sm,
            self.l1.lines_present(),
            busy.len(),
            self.l1_mshrs,
            busy.iter().min(),
            self.responses.len(),
            self.responses.peek(),
            self.seq
        )
    }
}
