//! [`L2Side`]: the part of the memory hierarchy every SM shares — the L2 and the DRAM channel —
//! and [`L2Op`], an access on its way there from an SM's L1 port ([`super::l1::L1Port`]).
//!
//! Every request reaches the L2 `l1_latency` cycles after its L1 port accepted it, so requests
//! reach the L2 (and DRAM) in acceptance order: acceptance cycle first, then the phase of the
//! cycle in which the SM offered it (the RT unit's port before the CTA-state port), then the SM
//! index, then the SM's own acceptance order. [`L2Side::apply`] must be called in exactly that
//! order; [`L2Op::key`] is that order, so a simulator may let SMs run ahead independently and
//! apply their L2 operations later, merged by key, with results identical to applying each
//! one at acceptance.

use std::ops::Range;

use super::cache::{EvictedLine, SectorCache, SectorState};
use super::config::MemConfig;
use super::dram::Dram;
use super::request::{AccessClass, Source};
use super::stats::MemStats;

/// An access of one SM on its way to the L2: a read (L1 miss, L1-bypassing load or prefetch
/// fill) or a write (every store goes through to the L2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct L2Op {
    /// Cycle the SM's L1 port accepted it (it reaches the L2 `l1_latency` later).
    pub cycle: u64,
    /// Phase of that cycle in which it was offered (RT unit 0, CTA-state port 1).
    pub phase: u8,
    /// The SM.
    pub sm: u32,
    /// The SM's acceptance counter.
    pub seq: u64,
    /// Line address.
    pub line: u64,
    /// Sector within the line.
    pub sector: u32,
    /// Traffic class.
    pub class: AccessClass,
    /// A store (write-back, write-allocate) rather than a read.
    pub write: bool,
}

impl L2Op {
    /// The order in which operations reach the L2.
    pub fn key(&self) -> (u64, u8, u32, u64) {
        (self.cycle, self.phase, self.sm, self.seq)
    }
}

/// Mirrored lines are at `line + (j << MIRROR_SHIFT)` for mirror `j` (line addresses of real
/// data stay far below: 2^40 lines is 2^47 bytes).
const MIRROR_SHIFT: u32 = 40;

/// The L2 and DRAM with their counters.
#[derive(Debug, Clone)]
pub struct L2Side {
    l2: SectorCache,
    dram: Dram,
    /// Lines per L2 set.
    set_ways: u32,
    /// Ways reserved for ray records (`l2_ray_ways`; 0: none).
    ray_ways: u32,
    l1_latency: u64,
    l2_latency: u64,
    line_bytes: u64,
    sector_bytes: u32,
    /// Copies of each private access the L2 takes in (`l2_private_mirrors`).
    mirrors: u32,
    /// Operations applied.
    applied: u64,
    stats: MemStats,
}

impl L2Side {
    /// An empty L2 and an idle DRAM channel (`cfg` already validated).
    pub fn new(cfg: &MemConfig) -> Self {
        L2Side {
            l2: SectorCache::new(cfg.l2_geometry()),
            dram: Dram::new(
                cfg.dram_latency,
                cfg.dram_bytes_per_cycle,
                cfg.dram_share,
                cfg.dram_channels,
                cfg.dram_interleave_bytes,
            ),
            set_ways: cfg.l2_geometry().ways,
            ray_ways: cfg.l2_ray_ways,
            l1_latency: u64::from(cfg.l1_latency),
            l2_latency: u64::from(cfg.l2_latency),
            line_bytes: u64::from(cfg.line_bytes),
            sector_bytes: cfg.sector_bytes,
            mirrors: cfg.l2_private_mirrors.max(1),
            applied: 0,
            stats: MemStats::default(),
        }
    }

    /// The L2 and DRAM counters (the L1 counters are the ports').
    pub fn stats(&self) -> &MemStats {
        &self.stats
    }

    /// Applies `op`, which reaches the L2 at `op.cycle + l1_latency`; returns its completion
    /// cycle and where it was served (a write: acknowledged by the L2, `Source::L2Write`).
    pub fn apply(&mut self, op: &L2Op) -> (u64, Source) {
        self.applied += 1;
        let at = op.cycle + self.l1_latency;
        let result = if op.write {
            self.write(at, op.line, op.sector, op.class);
            (at + self.l2_latency, Source::L2Write)
        } else {
            self.read(at, op.line, op.sector, op.class)
        };
        if op.class != AccessClass::Bvh {
            for j in 1..self.mirrors {
                self.mirror(
                    at,
                    op.line + (u64::from(j) << MIRROR_SHIFT),
                    op.sector,
                    op.class,
                );
            }
        }
        result
    }

    /// A mirrored copy of a private access reaching the L2 at `at`: it takes room in the L2 like
    /// the access (as if filled from DRAM) but moves no DRAM data, counts nowhere, and its line
    /// leaves without a write-back. A real line it evicts is written back as usual.
    fn mirror(&mut self, at: u64, line: u64, sector: u32, class: AccessClass) {
        if let Some(slot) = self.l2.lookup(line) {
            if self.l2.sector_state(slot, sector, at) == SectorState::Absent {
                self.l2.install(slot, line, sector, at);
            } else {
                self.l2.touch(slot);
            }
            return;
        }
        if let Ok(slot) = self.l2.find_slot(line, at, self.ways(class)) {
            // Mirrored lines are never dirty: only an evicted real line is written back.
            let evicted = self.l2.install(slot, line, sector, at);
            self.write_back(at + self.l2_latency, evicted);
        }
    }

    /// Ways of an L2 set that `class` may allocate into.
    fn ways(&self, class: AccessClass) -> Range<u32> {
        match (self.ray_ways, class) {
            (0, _) => 0..self.set_ways,
            (ray, AccessClass::RayRecord) => 0..ray,
            (ray, _) => ray..self.set_ways,
        }
    }

    /// A read reaching the L2 at cycle `at`: returns its completion cycle and source.
    fn read(&mut self, at: u64, line: u64, sector: u32, class: AccessClass) -> (u64, Source) {
        let hit_done = at + self.l2_latency;
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
                let grant = self
                    .dram
                    .schedule(hit_done, line * self.line_bytes, self.sector_bytes);
                stats.dram_queue_cycles += grant.start - hit_done;
                let dram = &mut self.stats.dram;
                dram.reads += 1;
                dram.read_bytes += u64::from(self.sector_bytes);
                dram.queue_cycles += grant.start - hit_done;
                match self.l2.find_slot(line, at, self.ways(class)) {
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
    fn write(&mut self, at: u64, line: u64, sector: u32, class: AccessClass) {
        let leave = at + self.l2_latency;
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
                match self.l2.find_slot(line, at, self.ways(class)) {
                    Ok(slot) => {
                        let evicted = self.l2.install(slot, line, sector, at);
                        self.write_back(leave, evicted);
                        Some(slot)
                    }
                    Err(_) => {
                        self.stats.l2_no_allocate += 1;
                        self.dram_write(leave, line);
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
                self.dram_write(leave, evicted.line);
            }
        }
    }

    /// One sector write of line `line` to DRAM arriving at `arrival` (takes bandwidth; nobody
    /// waits for it).
    fn dram_write(&mut self, arrival: u64, line: u64) {
        let grant = self
            .dram
            .schedule(arrival, line * self.line_bytes, self.sector_bytes);
        let dram = &mut self.stats.dram;
        dram.writes += 1;
        dram.write_bytes += u64::from(self.sector_bytes);
        dram.queue_cycles += grant.start - arrival;
        dram.write_queue_cycles += grant.start - arrival;
    }

    /// State at L2 cycle `at` of sector `sector` of line `line`.
    pub fn sector(&self, line: u64, sector: u32, at: u64) -> SectorState {
        self.l2.state(line, sector, at)
    }

    /// A one-line summary at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let (pending, next) = self.l2.pending_sectors(now);
        format!(
            "L2: {} lines, {pending} sectors being filled (first fill {next:?}), {} accesses \
             applied; DRAM free from cycle {}",
            self.l2.lines_present(),
            self.applied,
            self.dram.next_free_cycle()
        )
    }
}
