//! [`SectorCache`]: the tag store of one sectored cache (an L1 or the L2).
//!
//! Tags are kept per line, valid/dirty/prefetch bits and a fill cycle per sector, as in
//! GPGPU-Sim's sectored caches. The cache holds no data: it answers "is this sector here, and
//! from which cycle on" for the timing model in [`super::system`].
//!
//! - Sets are selected by `line % sets`; a fully associative cache has one set.
//! - Replacement is LRU over a per-cache use counter (every [`touch`](SectorCache::touch) or
//!   [`install`](SectorCache::install) makes the line most recently used), so ties cannot
//!   occur. Empty lines are used first, lowest way first.
//! - A line with a sector whose fill cycle is still in the future is *reserved* (being filled):
//!   it is never chosen as a victim, as in GPGPU-Sim. When every candidate line of a set is
//!   reserved, [`find_slot`](SectorCache::find_slot) reports the first cycle a line frees up.
//! - Lookups use an index from line address to slot; nothing iterates over it, so results do
//!   not depend on hash order. The index hashes with [`LineHasher`] (one multiply) instead of
//!   the DoS-resistant default, which dominated lookups in the cycle loop.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::Range;

use super::config::Geometry;

/// Where one sector stands at a given cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SectorState {
    /// Neither present nor being filled.
    Absent,
    /// Allocated and being filled; the data is there from `ready_at` on.
    Pending {
        /// Fill cycle.
        ready_at: u64,
    },
    /// Present.
    Ready,
}

/// A line removed to make room for another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EvictedLine {
    /// Line address (byte address / line size) of the removed line.
    pub line: u64,
    /// Mask of its valid sectors that were dirty (need a write-back).
    pub dirty: u64,
    /// Mask of its sectors filled by a prefetch and never used by a demand access.
    pub unused_prefetch: u64,
}

/// A line slot chosen by [`SectorCache::find_slot`] for [`SectorCache::install`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot(usize);

/// Tag state of one line slot.
#[derive(Debug, Clone, Copy, Default)]
struct LineState {
    /// Whether the slot holds a line.
    present: bool,
    /// Line address held.
    line: u64,
    /// Use stamp for LRU (larger = more recent).
    lru: u64,
    /// Valid sectors (present or being filled).
    valid: u64,
    /// Dirty sectors.
    dirty: u64,
    /// Sectors filled by a prefetch and not yet used by a demand access.
    prefetched: u64,
    /// Latest fill cycle of its sectors: the line is reserved while this is in the future.
    pending_until: u64,
}

/// Tag store of one sectored, set-associative (or fully associative) LRU cache.
#[derive(Debug, Clone)]
pub struct SectorCache {
    geometry: Geometry,
    slots: Vec<LineState>,
    /// Fill cycle per sector, `slot * sectors_per_line + sector`.
    ready: Vec<u64>,
    index: HashMap<u64, usize, BuildHasherDefault<LineHasher>>,
    clock: u64,
}

/// Hasher of the line-address index: Fibonacci hashing of the 64-bit key (line addresses are
/// trusted simulator values, so no DoS resistance is needed).
#[derive(Debug, Clone, Copy, Default)]
pub struct LineHasher(u64);

impl Hasher for LineHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

impl SectorCache {
    /// An empty cache of the given shape.
    pub fn new(geometry: Geometry) -> Self {
        let lines = geometry.lines() as usize;
        SectorCache {
            geometry,
            slots: vec![LineState::default(); lines],
            ready: vec![0; lines * geometry.sectors_per_line() as usize],
            index: HashMap::with_capacity_and_hasher(lines, BuildHasherDefault::default()),
            clock: 0,
        }
    }

    /// The cache's shape.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    fn sectors(&self) -> usize {
        self.geometry.sectors_per_line() as usize
    }

    /// State of sector `sector` of line `line` at cycle `now`.
    pub fn state(&self, line: u64, sector: u32, now: u64) -> SectorState {
        let Some(&slot) = self.index.get(&line) else {
            return SectorState::Absent;
        };
        if self.slots[slot].valid & (1 << sector) == 0 {
            return SectorState::Absent;
        }
        let ready_at = self.ready[slot * self.sectors() + sector as usize];
        if ready_at > now {
            SectorState::Pending { ready_at }
        } else {
            SectorState::Ready
        }
    }

    /// Makes `line` the most recently used line of its set (no effect when absent).
    pub fn touch(&mut self, line: u64) {
        if let Some(&slot) = self.index.get(&line) {
            self.clock += 1;
            self.slots[slot].lru = self.clock;
        }
    }

    /// The slot `line` occupies, or the slot it would replace at cycle `now` choosing only
    /// among ways `ways` of its set: an empty way first, else the least recently used line
    /// that is not being filled. `Err(retry_at)` when every candidate is being filled;
    /// `retry_at` is the first cycle one of them is not. Changes nothing.
    pub fn find_slot(&self, line: u64, now: u64, ways: Range<u32>) -> Result<Slot, u64> {
        if let Some(&slot) = self.index.get(&line) {
            return Ok(Slot(slot));
        }
        let base = (line % u64::from(self.geometry.sets)) as usize * self.geometry.ways as usize;
        let candidates = (base + ways.start as usize)..(base + ways.end as usize);
        // One pass: the first empty way wins outright; otherwise the least recently used line
        // not being filled (stamps are unique), else the earliest end of a fill.
        let mut victim: Option<(u64, usize)> = None;
        let mut retry: Option<u64> = None;
        for s in candidates {
            let state = &self.slots[s];
            if !state.present {
                return Ok(Slot(s));
            }
            if state.pending_until <= now {
                if victim.is_none_or(|(lru, _)| state.lru < lru) {
                    victim = Some((state.lru, s));
                }
            } else {
                retry = Some(retry.map_or(state.pending_until, |r| r.min(state.pending_until)));
            }
        }
        victim.map(|(_, s)| Slot(s)).ok_or(retry.unwrap_or(now + 1))
    }

    /// Puts sector `sector` of `line` into `slot` (from [`find_slot`](Self::find_slot) for the
    /// same line), valid from `ready_at` on, and makes the line most recently used. Returns
    /// the line the slot held before, if it was another one.
    pub fn install(
        &mut self,
        slot: Slot,
        line: u64,
        sector: u32,
        ready_at: u64,
    ) -> Option<EvictedLine> {
        let Slot(s) = slot;
        let sectors = self.sectors();
        let old = self.slots[s];
        let mut evicted = None;
        if !old.present || old.line != line {
            if old.present {
                self.index.remove(&old.line);
                evicted = Some(EvictedLine {
                    line: old.line,
                    dirty: old.dirty & old.valid,
                    unused_prefetch: old.prefetched & old.valid,
                });
            }
            self.index.insert(line, s);
            self.slots[s] = LineState {
                present: true,
                line,
                ..LineState::default()
            };
            self.ready[s * sectors..(s + 1) * sectors].fill(0);
        }
        self.clock += 1;
        let state = &mut self.slots[s];
        state.lru = self.clock;
        state.valid |= 1 << sector;
        state.pending_until = state.pending_until.max(ready_at);
        self.ready[s * sectors + sector as usize] = ready_at;
        evicted
    }

    fn bits(&mut self, line: u64) -> Option<&mut LineState> {
        let slot = *self.index.get(&line)?;
        Some(&mut self.slots[slot])
    }

    /// Marks a valid sector dirty (no effect when absent).
    pub fn mark_dirty(&mut self, line: u64, sector: u32) {
        if let Some(state) = self.bits(line) {
            state.dirty |= state.valid & (1 << sector);
        }
    }

    /// Marks a valid sector as filled by a prefetch (no effect when absent).
    pub fn mark_prefetched(&mut self, line: u64, sector: u32) {
        if let Some(state) = self.bits(line) {
            state.prefetched |= state.valid & (1 << sector);
        }
    }

    /// Clears a sector's prefetch mark; true when it was set (its first demand use).
    pub fn take_prefetched(&mut self, line: u64, sector: u32) -> bool {
        match self.bits(line) {
            Some(state) if state.prefetched & (1 << sector) != 0 => {
                state.prefetched &= !(1 << sector);
                true
            }
            _ => false,
        }
    }

    /// Number of lines held.
    pub fn lines_present(&self) -> usize {
        self.index.len()
    }

    /// Number of sectors being filled at cycle `now`, and the earliest fill cycle among them.
    pub fn pending_sectors(&self, now: u64) -> (usize, Option<u64>) {
        let pending = self
            .slots
            .iter()
            .enumerate()
            .filter(|(_, l)| l.present && l.pending_until > now)
            .flat_map(|(s, l)| {
                (0..self.sectors())
                    .filter(move |&k| l.valid & (1 << k) != 0)
                    .map(move |k| self.ready[s * self.sectors() + k])
            })
            .filter(|&r| r > now);
        pending.fold((0, None), |(n, min), r| {
            (n + 1, Some(min.map_or(r, |m: u64| m.min(r))))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cache of `lines` 128 B lines of 4 sectors, `ways` per set (0 = fully associative).
    fn cache(lines: u32, ways: u32) -> SectorCache {
        SectorCache::new(Geometry::new(lines * 128, ways, 128, 32))
    }

    /// Brings sector 0 of `line` in at cycle `now`, ready immediately.
    fn fill(c: &mut SectorCache, line: u64, now: u64) -> Option<EvictedLine> {
        let ways = 0..c.geometry().ways;
        let slot = c.find_slot(line, now, ways).unwrap();
        c.install(slot, line, 0, now)
    }

    fn present(c: &SectorCache, line: u64) -> bool {
        c.state(line, 0, u64::MAX) != SectorState::Absent
    }

    #[test]
    fn fully_associative_lru_evicts_least_recently_used() {
        let mut c = cache(4, 0);
        for line in [10, 20, 30, 40] {
            assert_eq!(fill(&mut c, line, 0), None);
        }
        c.touch(10);
        c.touch(30);
        // LRU order now: 20, 40, 10, 30.
        assert_eq!(fill(&mut c, 50, 0).map(|e| e.line), Some(20));
        assert_eq!(fill(&mut c, 60, 0).map(|e| e.line), Some(40));
        assert_eq!(fill(&mut c, 70, 0).map(|e| e.line), Some(10));
        assert!(present(&c, 30) && present(&c, 50) && present(&c, 60) && present(&c, 70));
        assert_eq!(c.lines_present(), 4);
    }

    #[test]
    fn sixteen_way_lru_stays_within_a_set() {
        // 64 lines, 16 ways: 4 sets; lines 0, 4, 8, ... map to set 0.
        let mut c = cache(64, 16);
        for k in 0..16 {
            fill(&mut c, 4 * k, 0);
        }
        // Other sets do not disturb set 0.
        for line in [1, 2, 3, 5] {
            assert_eq!(fill(&mut c, line, 0), None);
        }
        c.touch(0);
        assert_eq!(fill(&mut c, 64, 0).map(|e| e.line), Some(4));
        assert_eq!(fill(&mut c, 68, 0).map(|e| e.line), Some(8));
        assert!(present(&c, 0) && present(&c, 1));
    }

    #[test]
    fn sectors_share_a_tag() {
        let mut c = cache(2, 0);
        fill(&mut c, 1, 0);
        assert_eq!(c.state(1, 1, 0), SectorState::Absent);
        let slot = c.find_slot(1, 0, 0..2).unwrap();
        // A sector miss in a present line evicts nothing.
        assert_eq!(c.install(slot, 1, 1, 5), None);
        assert_eq!(c.state(1, 1, 4), SectorState::Pending { ready_at: 5 });
        assert_eq!(c.state(1, 1, 5), SectorState::Ready);
        assert_eq!(c.state(1, 0, 0), SectorState::Ready);
        assert_eq!(c.lines_present(), 1);
    }

    #[test]
    fn lines_being_filled_are_not_victims() {
        let mut c = cache(2, 0);
        let s = c.find_slot(1, 0, 0..2).unwrap();
        c.install(s, 1, 0, 100);
        let s = c.find_slot(2, 0, 0..2).unwrap();
        c.install(s, 2, 3, 80);
        assert_eq!(c.find_slot(3, 50, 0..2), Err(80));
        // At 80 line 2 is filled; line 1 (older) is still being filled, so 2 is the victim.
        let s = c.find_slot(3, 80, 0..2).unwrap();
        assert_eq!(c.install(s, 3, 0, 90).map(|e| e.line), Some(2));
        assert_eq!(c.pending_sectors(85), (2, Some(90)));
    }

    #[test]
    fn evictions_report_dirty_and_unused_prefetch_sectors() {
        let mut c = cache(1, 0);
        fill(&mut c, 1, 0);
        let s = c.find_slot(1, 0, 0..1).unwrap();
        c.install(s, 1, 2, 0);
        c.mark_dirty(1, 2);
        c.mark_prefetched(1, 0);
        c.mark_dirty(1, 3); // not valid: ignored
        let e = fill(&mut c, 2, 0).unwrap();
        assert_eq!((e.line, e.dirty, e.unused_prefetch), (1, 0b100, 0b1));
        c.mark_prefetched(2, 0);
        assert!(c.take_prefetched(2, 0));
        assert!(!c.take_prefetched(2, 0));
        assert_eq!(fill(&mut c, 3, 0).unwrap().unused_prefetch, 0);
    }

    #[test]
    fn way_ranges_partition_a_set() {
        // One set of 4 ways: ways 0..1 for one class, 1..4 for the others.
        let mut c = cache(4, 4);
        let s = c.find_slot(100, 0, 0..1).unwrap();
        c.install(s, 100, 0, 0);
        for line in [1, 2, 3, 4, 5] {
            let s = c.find_slot(line, 0, 1..4).unwrap();
            c.install(s, line, 0, 0);
        }
        assert!(present(&c, 100));
        let s = c.find_slot(101, 0, 0..1).unwrap();
        assert_eq!(c.install(s, 101, 0, 0).map(|e| e.line), Some(100));
        // A present line is found whatever the range.
        assert!(c.find_slot(5, 0, 0..1).is_ok());
    }
}
