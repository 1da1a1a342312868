//! [`L2Side`]: the part of the memory hierarchy every SM shares — the L2 and the DRAM — and
//! [`L2Op`], an access on its way there from an SM's L1 port ([`super::l1::L1Port`]).
//!
//! # Memory partitions
//! As in GPGPU-Sim (and so Vulkan-Sim), the L2 is sliced by address across memory partitions,
//! one per DRAM channel: every L2 set lies in exactly one channel's address range when the
//! channel interleaving (`dram_interleave_bytes` chunks, consecutive chunks in consecutive
//! channels) repeats within the set index, i.e. when the L2's sets are a multiple of
//! `dram_channels x dram_interleave_bytes / line_bytes` and the channel count is a power of two.
//! Then a set's lines, its replacement state and its channel's queue belong to one
//! [`L2Partition`], and partitions share no state: applying each partition's operations in key
//! order on its own (on any thread) gives exactly what applying all of them in key order gives
//! (tested against the unified model, [`L2Side::unified`]). Otherwise (one channel, the default
//! before partitions; a channel count that is not a power of two; or an L2 too small to hold a
//! set per channel) the whole L2 and its DRAM are one partition.
//!
//! Every request reaches the L2 `l1_latency` cycles after its L1 port accepted it, so requests
//! reach the L2 (and DRAM) in acceptance order: acceptance cycle first, then the phase of the
//! cycle in which the SM offered it (the RT unit's port before the CTA-state port), then the SM
//! index, then the SM's own acceptance order. [`L2Side::apply`] must be called in exactly that
//! order; [`L2Op::key`] is that order, so a simulator may let SMs run ahead independently and
//! apply their L2 operations later, merged by key, with results identical to applying each
//! one at acceptance.

use std::ops::Range;
use std::sync::Arc;

use super::cache::{EvictedLine, SectorCache, SectorState};
use super::config::MemConfig;
use super::dram::Dram;
use super::ghosts::GhostReads;
use super::partitions::PartitionMap;
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
    /// A prefetch (the treelet prefetcher's or the treelet controller's preload) rather than
    /// a demand access.
    pub prefetch: bool,
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

/// Lines between mirror `j` and `j + 1` of a line (beyond [`MIRROR_SHIFT`]): about the L2's
/// sets over `l2_private_mirrors`, a whole number of channel interleavings so that a mirror
/// stays in its line's partition. The copies of one private access fall in different sets,
/// as the private data of different SMs does, rather than filling one set at once.
fn mirror_spread(cfg: &MemConfig) -> u64 {
    let sets = u64::from(cfg.l2_geometry().sets);
    let period = u64::from((cfg.dram_interleave_bytes / cfg.line_bytes).max(1))
        * u64::from(cfg.dram_channels.max(1));
    let step = (sets / u64::from(cfg.l2_private_mirrors.max(1))).max(1);
    step.div_ceil(period) * period
}

/// The L2 and DRAM of the GPU: its memory partitions and how addresses map to them.
#[derive(Debug, Clone)]
pub struct L2Side {
    map: PartitionMap,
    parts: Vec<L2Partition>,
}

impl L2Side {
    /// An empty L2 and idle DRAM (`cfg` already validated), in partitions where the
    /// configuration allows ([`PartitionMap::new`]).
    pub fn new(cfg: &MemConfig) -> Self {
        Self::with_map(cfg, PartitionMap::new(cfg))
    }

    /// The same L2 and DRAM as one partition (the reference the partitions are tested against).
    pub fn unified(cfg: &MemConfig) -> Self {
        Self::with_map(cfg, PartitionMap::unified())
    }

    fn with_map(cfg: &MemConfig, map: PartitionMap) -> Self {
        L2Side {
            map,
            parts: (0..map.partitions())
                .map(|i| L2Partition::new(cfg, map, i))
                .collect(),
        }
    }

    /// Applies `op` (in key order over all operations; see [`L2Partition::apply`]).
    pub fn apply(&mut self, op: &L2Op) -> (u64, Source) {
        let p = self.map.partition(op.line);
        self.parts[p].apply(op)
    }

    /// Makes the BVH sectors at byte addresses `addresses` present (ready at cycle 0) in an
    /// L2 that has served nothing yet, in order (the last the most recently used), where the
    /// BVH may allocate; moves no data and counts nothing (the sampled tier's warm start,
    /// `sample.warm_l2`).
    pub fn warm(&mut self, addresses: &[u64]) {
        for &addr in addresses {
            let line = addr / self.parts[0].line_bytes;
            let p = self.map.partition(line);
            self.parts[p].warm(line, addr);
        }
    }

    /// Sets the BVH reads of the SMs a scale model leaves out (the sampled tier's
    /// `sample.ghost_l2_footprint`; [`GhostReads`], built for this L2's configuration): after
    /// each demand BVH read of a simulated SM (not its prefetches: the streams are the
    /// left-out SMs' demand reads, which keep pace with its own), its partition applies the next
    /// [`GhostReads::per_read`] reads of its share of the streams (the streams in turn, each
    /// from where it stopped, from its start again when it runs out; reads of one line in a
    /// row together). They take room in the L2 and refresh lines as mirrored accesses do: no
    /// DRAM traffic, counted nowhere.
    pub fn ghosts(&mut self, reads: &Arc<GhostReads>) {
        assert_eq!(reads.map(), self.map, "ghost reads split for another L2");
        for part in &mut self.parts {
            let streams = reads.part(part.index).len();
            part.ghosts = (streams > 0).then(|| Arc::clone(reads));
            part.ghost_cursors = vec![0; streams];
            part.ghost_turn = 0;
            part.ghost_ahead = 0;
        }
    }

    /// The L2 and DRAM counters of all partitions (the L1 counters are the ports').
    pub fn stats(&self) -> MemStats {
        total_stats(self.parts.iter())
    }

    /// State at L2 cycle `at` of sector `sector` of line `line`.
    pub fn sector(&self, line: u64, sector: u32, at: u64) -> SectorState {
        self.parts[self.map.partition(line)].sector(line, sector, at)
    }

    /// A one-line summary at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        summary(self.parts.iter(), now)
    }

    /// The address map and the partitions, to apply each partition's operations on its own.
    pub fn into_partitions(self) -> (PartitionMap, Vec<L2Partition>) {
        (self.map, self.parts)
    }
}

/// The L2 and DRAM counters of `parts` added up.
pub fn total_stats<'p>(parts: impl Iterator<Item = &'p L2Partition>) -> MemStats {
    let mut stats = MemStats::default();
    for part in parts {
        stats.add(&part.stats);
    }
    stats
}

/// A one-line summary of `parts` at cycle `now`, for a deadlock watchdog.
pub fn summary<'p>(parts: impl Iterator<Item = &'p L2Partition>, now: u64) -> String {
    let (mut lines, mut pending, mut first, mut applied, mut free) = (0, 0, None, 0, 0);
    for p in parts {
        let (n, next) = p.l2.pending_sectors(now);
        lines += p.l2.lines_present();
        pending += n;
        first = match (first, next) {
            (Some(a), Some(b)) => Some(std::cmp::min(a, b)),
            (a, b) => a.or(b),
        };
        applied += p.applied;
        free = free.max(p.dram.next_free_cycle());
    }
    format!(
        "L2: {lines} lines, {pending} sectors being filled (first fill {first:?}), {applied} \
         accesses applied; DRAM free from cycle {free}"
    )
}

/// One memory partition: its part of the L2's sets and its DRAM channel(s), with counters.
#[derive(Debug, Clone)]
pub struct L2Partition {
    /// Its index (its DRAM channel with several partitions).
    index: usize,
    map: PartitionMap,
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
    /// Lines between consecutive mirrors of a line beyond [`MIRROR_SHIFT`]: spreads its copies
    /// over the L2's sets.
    mirror_spread: u64,
    /// Operations applied.
    applied: u64,
    stats: MemStats,
    /// The left-out SMs' BVH reads, where some fall in this partition ([`L2Side::ghosts`]).
    ghosts: Option<Arc<GhostReads>>,
    /// Next read of each ghost stream.
    ghost_cursors: Vec<usize>,
    /// The ghost stream whose turn it is.
    ghost_turn: usize,
    /// Ghost reads applied beyond those owed (a run is applied whole).
    ghost_ahead: u32,
}

impl L2Partition {
    /// One empty partition of `map` (`cfg` already validated): `1 / partitions` of the L2's
    /// sets and, with several partitions, one DRAM channel with its share of the bandwidth.
    fn new(cfg: &MemConfig, map: PartitionMap, index: usize) -> Self {
        let n = map.partitions() as u32;
        let mut geometry = cfg.l2_geometry();
        geometry.sets /= n;
        // One partition keeps every channel; partition k of `n` is channel k, with
        // `[num, den x n]` of the bandwidth, as `Dram::new` gives each channel.
        let [num, den] = cfg.dram_share;
        let channels = if n == 1 { cfg.dram_channels } else { 1 };
        let dram = Dram::new(
            cfg.dram_latency,
            cfg.dram_bytes_per_cycle,
            [num, den.max(1) * n],
            channels,
            cfg.dram_interleave_bytes,
        );
        L2Partition {
            index,
            map,
            l2: SectorCache::new(geometry),
            dram,
            set_ways: cfg.l2_geometry().ways,
            ray_ways: cfg.l2_ray_ways,
            l1_latency: u64::from(cfg.l1_latency),
            l2_latency: u64::from(cfg.l2_latency),
            line_bytes: u64::from(cfg.line_bytes),
            sector_bytes: cfg.sector_bytes,
            mirrors: cfg.l2_private_mirrors.max(1),
            mirror_spread: mirror_spread(cfg),
            applied: 0,
            stats: MemStats::default(),
            ghosts: None,
            ghost_cursors: Vec::new(),
            ghost_turn: 0,
            ghost_ahead: 0,
        }
    }

    /// Applies `op`, an operation on a line of this partition, which reaches the L2 at
    /// `op.cycle + l1_latency`; returns its completion cycle and where it was served (a write:
    /// acknowledged by the L2, `Source::L2Write`). Operations must come in key order.
    pub fn apply(&mut self, op: &L2Op) -> (u64, Source) {
        debug_assert_eq!(
            self.map.partition(op.line),
            self.index,
            "line of another partition"
        );
        self.applied += 1;
        let at = op.cycle + self.l1_latency;
        let line = self.map.local(op.line);
        let result = if op.write {
            self.write(at, line, op.sector, op.class);
            (at + self.l2_latency, Source::L2Write)
        } else {
            self.read(at, line, op.sector, op.class)
        };
        if op.class != AccessClass::Bvh {
            for j in 1..self.mirrors {
                let j = u64::from(j);
                // Mirrors keep the partition bits of `op.line`, in sets spread over the L2.
                self.mirror(
                    at,
                    self.map
                        .local(op.line + (j << MIRROR_SHIFT) + j * self.mirror_spread),
                    1 << op.sector,
                    op.class,
                );
            }
        } else if !op.write && !op.prefetch && self.ghosts.is_some() {
            self.ghost_reads(at);
        }
        result
    }

    /// The next [`GhostReads::per_read`] reads of this partition's ghost streams, reaching the
    /// L2 at `at`: whole runs, the streams in turn; reads applied beyond those owed count
    /// towards the next.
    fn ghost_reads(&mut self, at: u64) {
        // Taken out while the runs are applied (no reference count touched on this hot path).
        let Some(reads) = self.ghosts.take() else {
            return;
        };
        let streams = reads.part(self.index);
        let mut owed = reads.per_read();
        let ahead = owed.min(self.ghost_ahead);
        owed -= ahead;
        self.ghost_ahead -= ahead;
        while owed > 0 {
            let g = self.ghost_turn;
            self.ghost_turn = (g + 1) % streams.len();
            let stream = &streams[g];
            let run = stream[self.ghost_cursors[g]];
            self.ghost_cursors[g] = (self.ghost_cursors[g] + 1) % stream.len();
            let line = self.map.local(u64::from(run.line));
            self.mirror(at, line, run.sectors, AccessClass::Bvh);
            self.ghost_ahead += run.reads.saturating_sub(owed);
            owed = owed.saturating_sub(run.reads);
        }
        self.ghosts = Some(reads);
    }

    /// [`L2Side::warm`] for the sector of byte address `addr` on `line`, a line of this
    /// partition.
    fn warm(&mut self, line: u64, addr: u64) {
        let sector = ((addr % self.line_bytes) / u64::from(self.sector_bytes)) as u32;
        let local = self.map.local(line);
        match self.l2.lookup(local) {
            Some(slot) if self.l2.sector_state(slot, sector, 0) != SectorState::Absent => {
                self.l2.touch(slot);
            }
            Some(slot) => {
                self.l2.install(slot, local, sector, 0);
            }
            None => {
                // Nothing is dirty before the run: an evicted line needs no write-back.
                if let Ok(slot) = self.l2.find_slot(local, 0, self.ways(AccessClass::Bvh)) {
                    self.l2.install(slot, local, sector, 0);
                }
            }
        }
    }

    /// A mirrored copy of an access to the sectors `sectors` (a bit mask) of `line` reaching
    /// the L2 at `at` (a private access's mirror, or a run of ghost reads; one lookup for all
    /// the sectors): it takes room in the L2 like the access (as if filled from DRAM) but moves
    /// no DRAM data, counts nowhere, and its line leaves without a write-back. A real line it
    /// evicts is written back as usual.
    fn mirror(&mut self, at: u64, line: u64, mut sectors: u64, class: AccessClass) {
        let slot = match self.l2.lookup(line) {
            Some(slot) => slot,
            None => {
                let Ok(slot) = self.l2.find_slot(line, at, self.ways(class)) else {
                    return;
                };
                let first = sectors.trailing_zeros();
                sectors &= sectors - 1;
                // Mirrored lines are never dirty: only an evicted real line is written back.
                let evicted = self.l2.install(slot, line, first, at);
                self.write_back(at + self.l2_latency, evicted);
                slot
            }
        };
        while sectors != 0 {
            let sector = sectors.trailing_zeros();
            sectors &= sectors - 1;
            if self.l2.sector_state(slot, sector, at) == SectorState::Absent {
                self.l2.install(slot, line, sector, at);
            } else {
                self.l2.touch(slot);
            }
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

    /// State at L2 cycle `at` of sector `sector` of line `line` (a line of this partition).
    pub fn sector(&self, line: u64, sector: u32, at: u64) -> SectorState {
        self.l2.state(self.map.local(line), sector, at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A configuration with `channels` DRAM channels and a small L2 whose sets repeat the
    /// channel interleaving (16 sets of 4 ways: 2 chunks of 2 lines per set stride).
    fn small(channels: u32) -> MemConfig {
        MemConfig {
            l2_bytes: 16 * 4 * 128,
            l2_ways: 4,
            dram_channels: channels,
            dram_bytes_per_cycle: 40,
            ..MemConfig::default()
        }
    }

    #[test]
    fn partitions_follow_the_channels_where_every_set_lies_in_one() {
        let cfg = MemConfig {
            dram_channels: 16,
            ..MemConfig::default()
        };
        cfg.validate().unwrap();
        let map = PartitionMap::new(&cfg);
        assert_eq!(map.partitions(), 16);
        // 256 B chunks: lines 2k and 2k + 1 share a channel, consecutive chunks the next one.
        assert_eq!(map.partition(0), 0);
        assert_eq!(map.partition(1), 0);
        assert_eq!(map.partition(2), 1);
        assert_eq!(map.partition(31), 15);
        assert_eq!(map.partition(32), 0);
        // One channel, a channel count that is no power of two, an L2 too small for a set per
        // channel: one partition.
        for channels in [1, 12] {
            let c = MemConfig {
                dram_channels: channels,
                ..MemConfig::default()
            };
            assert_eq!(PartitionMap::new(&c).partitions(), 1, "{channels} channels");
        }
        assert_eq!(PartitionMap::new(&small(16)).partitions(), 1);
        assert_eq!(PartitionMap::new(&small(8)).partitions(), 8);
        assert_eq!(L2Side::new(&cfg).into_partitions().1.len(), 16);
    }

    /// A warmed sector is present from cycle 0: the first read hits the L2; its line's other
    /// sectors, and lines not warmed, miss; warming moves no data and counts nothing.
    #[test]
    fn warmed_sectors_hit_from_the_start() {
        for channels in [1, 8] {
            let cfg = small(channels);
            let mut l2 = L2Side::new(&cfg);
            let line_bytes = u64::from(cfg.line_bytes);
            // Line 5's sector 1 and line 9's sector 0.
            l2.warm(&[5 * line_bytes + 32, 9 * line_bytes]);
            assert_eq!(l2.stats(), MemStats::default());
            let read = |line: u64, sector: u32, seq: u64| L2Op {
                cycle: 10,
                phase: 0,
                sm: 0,
                seq,
                line,
                sector,
                class: AccessClass::Bvh,
                write: false,
                prefetch: false,
            };
            let hit = 10 + u64::from(cfg.l1_latency) + u64::from(cfg.l2_latency);
            assert_eq!(l2.apply(&read(5, 1, 0)), (hit, Source::L2Hit));
            assert_eq!(l2.apply(&read(9, 0, 1)), (hit, Source::L2Hit));
            assert_eq!(l2.apply(&read(5, 0, 2)).1, Source::Dram);
            assert_eq!(l2.apply(&read(7, 1, 3)).1, Source::Dram);
            let bvh = l2.stats().bvh;
            assert_eq!((bvh.l2_hits, bvh.l2_misses, bvh.dram_reads), (2, 2, 2));
        }
        // Five lines of one 4-way set (16 sets), in order: the first leaves for the fifth.
        let cfg = small(1);
        let mut l2 = L2Side::new(&cfg);
        let lines = [0u64, 16, 32, 48, 64];
        l2.warm(&lines.map(|l| l * u64::from(cfg.line_bytes)));
        let present: Vec<bool> = lines
            .iter()
            .map(|&l| l2.sector(l, 0, 0) != SectorState::Absent)
            .collect();
        assert_eq!(present, [false, true, true, true, true]);
    }

    /// Ghost reads follow each BVH read of the simulated SMs (not writes, not other classes),
    /// streams in turn, from where each stopped and round again; they bring lines a later read
    /// hits and evict lines, but count nowhere and move no DRAM data.
    #[test]
    fn ghost_reads_follow_bvh_reads_and_count_nowhere() {
        for channels in [1, 8] {
            let cfg = small(channels);
            let per_line = u64::from(cfg.line_bytes / cfg.sector_bytes);
            let sector = |line: u64, s: u64| (line * per_line + s) as u32;
            let mut l2 = L2Side::new(&cfg);
            // Two streams: line 5 then line 9 (sector 0); line 40 (sector 2).
            let streams = [vec![sector(5, 0), sector(9, 0)], vec![sector(40, 2)]];
            l2.ghosts(&Arc::new(GhostReads::new(&cfg, &streams, 1)));
            let op = |line: u64, sector: u32, seq: u64, class: AccessClass, write: bool| L2Op {
                cycle: 10 * seq,
                phase: 0,
                sm: 0,
                seq,
                line,
                sector,
                class,
                write,
                prefetch: false,
            };
            let read = |line, s, seq| op(line, s, seq, AccessClass::Bvh, false);
            // A write, a ray-record read and a BVH prefetch bring nothing: the left-out SMs'
            // reads keep pace with the simulated SM's demand reads.
            l2.apply(&op(100, 0, 0, AccessClass::Bvh, true));
            l2.apply(&op(101, 0, 1, AccessClass::RayRecord, false));
            l2.apply(&L2Op {
                phase: 1,
                prefetch: true,
                ..read(102, 0, 1)
            });
            let present = |l2: &L2Side, line, s| l2.sector(line, s, 1_000) != SectorState::Absent;
            assert!(!present(&l2, 5, 0));
            assert!(!present(&l2, 40, 2));
            // In partitions, a stream's reads go with its lines' partition: one channel only.
            if channels == 1 {
                assert_eq!(l2.apply(&read(7, 0, 2)).1, Source::Dram);
                assert!(present(&l2, 5, 0), "stream 0's first read");
                assert!(!present(&l2, 40, 2));
                assert_eq!(l2.apply(&read(7, 1, 3)).1, Source::Dram);
                assert!(present(&l2, 40, 2), "stream 1's turn");
                assert!(!present(&l2, 5, 1), "a ghost read brings its sector only");
                assert_eq!(l2.apply(&read(5, 0, 4)).1, Source::L2Hit);
                assert_eq!(l2.apply(&read(40, 2, 5)).1, Source::L2Hit);
                assert!(present(&l2, 9, 0), "stream 0 went on where it stopped");
                let bvh = l2.stats().bvh;
                assert_eq!((bvh.l2_accesses, bvh.l2_hits, bvh.dram_reads), (6, 2, 3));
                // DRAM read the three BVH misses and the ray record, nothing for the ghosts.
                assert_eq!(l2.stats().dram.reads, 4);
            } else {
                // Line 5's partition has stream 0's line 5 alone: each read there brings it.
                let p5 = l2.map.partition(5);
                let other = (0..64)
                    .find(|&l| l != 5 && l2.map.partition(l) == p5)
                    .unwrap();
                assert_eq!(l2.apply(&read(other, 0, 2)).1, Source::Dram);
                assert!(present(&l2, 5, 0));
                assert_eq!(l2.apply(&read(5, 0, 3)).1, Source::L2Hit);
            }
        }
        // Ghost reads evict: line 0 of a 4-way set (16 sets) leaves for four ghost lines of its
        // set, read after a read of line 1 (another set).
        let cfg = small(1);
        let per_line = u64::from(cfg.line_bytes / cfg.sector_bytes);
        let mut l2 = L2Side::new(&cfg);
        l2.warm(&[0]);
        let set0 = [16u64, 32, 48, 64].map(|l| (l * per_line) as u32).to_vec();
        l2.ghosts(&Arc::new(GhostReads::new(&cfg, &[set0], 4)));
        assert_ne!(l2.sector(0, 0, 0), SectorState::Absent);
        let read = L2Op {
            cycle: 0,
            phase: 0,
            sm: 0,
            seq: 0,
            line: 1,
            sector: 0,
            class: AccessClass::Bvh,
            write: false,
            prefetch: false,
        };
        l2.apply(&read);
        assert_eq!(
            l2.sector(0, 0, 1_000),
            SectorState::Absent,
            "evicted by ghosts"
        );
        assert!([16u64, 32, 48, 64]
            .iter()
            .all(|&l| l2.sector(l, 0, 1_000) != SectorState::Absent));
    }

    /// Reads of one line in a row are applied together and count as the reads they are: with
    /// one ghost read per BVH read, the run of line 5's two sectors is applied at the first,
    /// nothing at the second (it was read ahead), line 9 at the third.
    #[test]
    fn a_ghost_run_counts_its_reads() {
        let cfg = small(1);
        let per_line = u64::from(cfg.line_bytes / cfg.sector_bytes);
        let sector = |line: u64, s: u64| (line * per_line + s) as u32;
        let mut l2 = L2Side::new(&cfg);
        let stream = vec![sector(5, 0), sector(5, 1), sector(9, 0)];
        l2.ghosts(&Arc::new(GhostReads::new(&cfg, &[stream], 1)));
        let read = |seq: u64| L2Op {
            cycle: 10 * seq,
            phase: 0,
            sm: 0,
            seq,
            line: 100 + seq,
            sector: 0,
            class: AccessClass::Bvh,
            write: false,
            prefetch: false,
        };
        let present = |l2: &L2Side, line, s| l2.sector(line, s, 1_000) != SectorState::Absent;
        l2.apply(&read(0));
        assert!(present(&l2, 5, 0) && present(&l2, 5, 1) && !present(&l2, 9, 0));
        l2.apply(&read(1));
        assert!(!present(&l2, 9, 0), "the run stood for two reads");
        l2.apply(&read(2));
        assert!(present(&l2, 9, 0));
    }

    /// The mirrors of a private access fall in sets of their own, as different SMs' private
    /// data does, instead of filling its set: four copies of a ray-record read in a 4-way set
    /// would evict the BVH line there; spread over four sets they leave it.
    #[test]
    fn mirrors_spread_over_the_sets() {
        let cfg = MemConfig {
            l2_private_mirrors: 4,
            ..small(1)
        };
        cfg.validate().unwrap();
        let mut l2 = L2Side::new(&cfg);
        l2.warm(&[0]);
        l2.apply(&L2Op {
            cycle: 0,
            phase: 0,
            sm: 0,
            seq: 0,
            line: 16,
            sector: 0,
            class: AccessClass::RayRecord,
            write: false,
            prefetch: false,
        });
        assert_ne!(l2.sector(0, 0, 1_000), SectorState::Absent, "line 0 stays");
        // 16 sets over 4 mirrors: a mirror every 4 sets.
        let spread = mirror_spread(&cfg);
        assert_eq!(spread, 4);
        let sets: Vec<u64> = (0..4u64)
            .map(|j| {
                let line = 16 + (j << MIRROR_SHIFT) + j * spread;
                assert_ne!(l2.sector(line, 0, 1_000), SectorState::Absent, "mirror {j}");
                line % 16
            })
            .collect();
        assert_eq!(sets, [0, 4, 8, 12]);
    }

    /// Operations in key order from (cycle step, line, sector, class, write) draws.
    fn ops(draws: &[(u64, u64, u32, usize, bool)]) -> Vec<L2Op> {
        let mut cycle = 0;
        draws
            .iter()
            .enumerate()
            .map(|(seq, &(step, line, sector, class, write))| {
                cycle += step;
                L2Op {
                    cycle,
                    phase: 0,
                    sm: 0,
                    seq: seq as u64,
                    line,
                    sector,
                    class: AccessClass::ALL[class],
                    write,
                    prefetch: false,
                }
            })
            .collect()
    }

    proptest! {
        /// Applying each partition's operations on its own gives the unified L2's results and
        /// counters, with ray ways, mirrors and a scale model's DRAM share.
        #[test]
        fn partitions_equal_the_unified_l2(
            draws in prop::collection::vec(
                (0u64..6, 0u64..512, 0u32..4, 0usize..6, any::<bool>()), 1..400),
            channels in prop::sample::select(vec![2u32, 4, 8]),
            ray_ways in 0u32..3,
            mirrors in 1u32..4,
        ) {
            let cfg = MemConfig {
                l2_ray_ways: ray_ways,
                l2_private_mirrors: mirrors,
                dram_share: [1, 2],
                ..small(channels)
            };
            cfg.validate().unwrap();
            let mut parts = L2Side::new(&cfg);
            prop_assert_eq!(parts.map.partitions(), channels as usize);
            let mut unified = L2Side::unified(&cfg);
            for op in ops(&draws) {
                prop_assert_eq!(parts.apply(&op), unified.apply(&op), "{:?}", op);
                for sector in 0..4 {
                    let at = op.cycle + 100;
                    prop_assert_eq!(
                        parts.sector(op.line, sector, at),
                        unified.sector(op.line, sector, at)
                    );
                }
            }
            prop_assert_eq!(parts.stats(), unified.stats());
        }
    }
}
