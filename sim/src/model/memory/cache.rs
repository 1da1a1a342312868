//! [`SectorCache`]: the tag store of one sectored cache (an L1 or the L2).
//!
//! Tags are kept per line, valid/dirty/prefetch bits and a fill cycle per sector, as in
//! GPGPU-Sim's sectored caches. The cache holds no data: it answers "is this sector here, and
//! from which cycle on" for the timing model in [`super::system`].
//!
//! - Sets are selected by `line % sets`; a fully associative cache has one set.
//! - Replacement is LRU: every [`touch`](SectorCache::touch) or
//!   [`install`](SectorCache::install) makes the line the most recently used of its set.
//!   Empty lines are used first, lowest way first.
//! - A line with a sector whose fill cycle is still in the future is *reserved* (being filled):
//!   it is never chosen as a victim, as in GPGPU-Sim. When every candidate line of a set is
//!   reserved, [`find_slot`](SectorCache::find_slot) reports the first cycle a line frees up.
//! - Lookups use an index from line address to slot; nothing iterates over it, so results do
//!   not depend on hash order. The index hashes with [`LineHasher`] (one multiply) instead of
//!   the DoS-resistant default, which dominated lookups in the cycle loop. Callers look a line
//!   up once ([`lookup`](SectorCache::lookup)) and then work on its [`Slot`].
//!
//! # Speed
//! Each set keeps its lines in a doubly linked recency list (least recently used first) and a
//! count of its empty ways, so choosing a victim in the 128-way L1 does not scan the set: a
//! full set walks the list from its least recently used end and stops at the first line in
//! the allowed ways that is not being filled, which is exactly the least recently used such
//! line. Only a set with an empty way (while the cache warms up) or one whose candidates are
//! all being filled (a stall) is scanned.

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

/// A line slot of a [`SectorCache`]: where a line is ([`SectorCache::lookup`]) or will go
/// ([`SectorCache::find_slot`]). Valid until the next [`install`](SectorCache::install) into
/// the same cache.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot(usize);

/// End of a recency list.
const NIL: u32 = u32::MAX;

/// Tag state of one line slot.
#[derive(Debug, Clone, Copy)]
struct LineState {
    /// Whether the slot holds a line.
    present: bool,
    /// Line address held.
    line: u64,
    /// Valid sectors (present or being filled).
    valid: u64,
    /// Dirty sectors.
    dirty: u64,
    /// Sectors filled by a prefetch and not yet used by a demand access.
    prefetched: u64,
    /// Latest fill cycle of its sectors: the line is reserved while this is in the future.
    pending_until: u64,
    /// Next less recently used line of the set, or [`NIL`] (only while present).
    older: u32,
    /// Next more recently used line of the set, or [`NIL`] (only while present).
    newer: u32,
}

impl Default for LineState {
    fn default() -> Self {
        LineState {
            present: false,
            line: 0,
            valid: 0,
            dirty: 0,
            prefetched: 0,
            pending_until: 0,
            older: NIL,
            newer: NIL,
        }
    }
}

/// Recency list and occupancy of one set.
#[derive(Debug, Clone, Copy)]
struct SetState {
    /// Least recently used line, or [`NIL`] when the set is empty.
    oldest: u32,
    /// Most recently used line, or [`NIL`] when the set is empty.
    newest: u32,
    /// Ways not holding a line.
    empty: u32,
}

/// Tag store of one sectored, set-associative (or fully associative) LRU cache.
#[derive(Debug, Clone)]
pub struct SectorCache {
    geometry: Geometry,
    /// `geometry.sectors_per_line()`, kept to spare a division per lookup.
    sectors: usize,
    /// `geometry.ways`, as an index.
    ways: usize,
    slots: Vec<LineState>,
    sets: Vec<SetState>,
    /// Fill cycle per sector, `slot * sectors_per_line + sector`.
    ready: Vec<u64>,
    index: HashMap<u64, usize, BuildHasherDefault<LineHasher>>,
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
        let set = SetState {
            oldest: NIL,
            newest: NIL,
            empty: geometry.ways,
        };
        SectorCache {
            geometry,
            sectors: geometry.sectors_per_line() as usize,
            ways: geometry.ways as usize,
            slots: vec![LineState::default(); lines],
            sets: vec![set; geometry.sets as usize],
            ready: vec![0; lines * geometry.sectors_per_line() as usize],
            index: HashMap::with_capacity_and_hasher(lines, BuildHasherDefault::default()),
        }
    }

    /// The cache's shape.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    fn set_of(&self, slot: usize) -> usize {
        slot / self.ways
    }

    /// The slot holding `line`, if present.
    #[inline]
    pub fn lookup(&self, line: u64) -> Option<Slot> {
        self.index.get(&line).map(|&s| Slot(s))
    }

    /// State of sector `sector` of line `line` at cycle `now`.
    pub fn state(&self, line: u64, sector: u32, now: u64) -> SectorState {
        match self.lookup(line) {
            Some(slot) => self.sector_state(slot, sector, now),
            None => SectorState::Absent,
        }
    }

    /// State at cycle `now` of sector `sector` of the line in `slot` (from
    /// [`lookup`](Self::lookup)).
    #[inline]
    pub fn sector_state(&self, slot: Slot, sector: u32, now: u64) -> SectorState {
        let Slot(s) = slot;
        if self.slots[s].valid & (1 << sector) == 0 {
            return SectorState::Absent;
        }
        let ready_at = self.ready[s * self.sectors + sector as usize];
        if ready_at > now {
            SectorState::Pending { ready_at }
        } else {
            SectorState::Ready
        }
    }

    /// Removes present slot `s` from its set's recency list.
    fn unlink(&mut self, s: usize) {
        let LineState { older, newer, .. } = self.slots[s];
        let set = self.set_of(s);
        match older {
            NIL => self.sets[set].oldest = newer,
            o => self.slots[o as usize].newer = newer,
        }
        match newer {
            NIL => self.sets[set].newest = older,
            n => self.slots[n as usize].older = older,
        }
    }

    /// Appends slot `s` to its set's recency list as the most recently used line.
    fn push_newest(&mut self, s: usize) {
        let set = self.set_of(s);
        let newest = self.sets[set].newest;
        self.slots[s].older = newest;
        self.slots[s].newer = NIL;
        match newest {
            NIL => self.sets[set].oldest = s as u32,
            n => self.slots[n as usize].newer = s as u32,
        }
        self.sets[set].newest = s as u32;
    }

    /// Makes the line in `slot` the most recently used line of its set.
    #[inline]
    pub fn touch(&mut self, slot: Slot) {
        let Slot(s) = slot;
        if self.slots[s].newer != NIL {
            self.unlink(s);
            self.push_newest(s);
        }
    }

    /// The slot `line` occupies, or the slot it would replace at cycle `now` choosing only
    /// among ways `ways` of its set: an empty way first, else the least recently used line
    /// that is not being filled. `Err(retry_at)` when every candidate is being filled;
    /// `retry_at` is the first cycle one of them is not. Changes nothing.
    pub fn find_slot(&self, line: u64, now: u64, ways: Range<u32>) -> Result<Slot, u64> {
        if let Some(slot) = self.lookup(line) {
            return Ok(slot);
        }
        let set = (line % u64::from(self.geometry.sets)) as usize;
        let base = set * self.ways;
        let candidates = (base + ways.start as usize)..(base + ways.end as usize);
        let set = self.sets[set];
        if set.empty > 0 {
            if let Some(s) = candidates.clone().find(|&s| !self.slots[s].present) {
                return Ok(Slot(s));
            }
        }
        // Least recently used first: the first allowed line not being filled is the victim.
        let mut s = set.oldest;
        while s != NIL {
            let state = &self.slots[s as usize];
            if candidates.contains(&(s as usize)) && state.pending_until <= now {
                return Ok(Slot(s as usize));
            }
            s = state.newer;
        }
        // Every candidate is present and being filled.
        Err(candidates
            .map(|s| self.slots[s].pending_until)
            .min()
            .unwrap_or(now + 1))
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
        let sectors = self.sectors;
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
                self.unlink(s);
            } else {
                let set = self.set_of(s);
                self.sets[set].empty -= 1;
            }
            self.index.insert(line, s);
            self.slots[s] = LineState {
                present: true,
                line,
                ..LineState::default()
            };
            self.ready[s * sectors..(s + 1) * sectors].fill(0);
            self.push_newest(s);
        } else {
            self.touch(slot);
        }
        let state = &mut self.slots[s];
        state.valid |= 1 << sector;
        state.pending_until = state.pending_until.max(ready_at);
        self.ready[s * sectors + sector as usize] = ready_at;
        evicted
    }

    /// Sets the fill cycle of sector `sector` of `line` to `ready_at` if it is `placeholder`
    /// (a fill installed before its cycle was known), and the line's reservation to the latest
    /// fill of its valid sectors. A line being filled is never evicted, so it is still there.
    pub fn settle_fill(&mut self, line: u64, sector: u32, placeholder: u64, ready_at: u64) {
        let Some(Slot(s)) = self.lookup(line) else {
            debug_assert!(false, "a line being filled was evicted");
            return;
        };
        let sectors = self.sectors;
        let ready = &mut self.ready[s * sectors..(s + 1) * sectors];
        if ready[sector as usize] == placeholder {
            ready[sector as usize] = ready_at;
        }
        let valid = self.slots[s].valid;
        self.slots[s].pending_until = (0..sectors)
            .filter(|&k| valid & (1 << k) != 0)
            .map(|k| ready[k])
            .max()
            .unwrap_or(0);
    }

    /// For each line of `line`'s set in the allowed `ways` (all present: called when
    /// [`find_slot`](Self::find_slot) found every candidate being filled), the fill cycles of
    /// its valid sectors: the line is free once all have passed.
    pub fn candidate_fills(&self, line: u64, ways: Range<u32>) -> Vec<Vec<u64>> {
        let set = (line % u64::from(self.geometry.sets)) as usize;
        let base = set * self.ways;
        ((base + ways.start as usize)..(base + ways.end as usize))
            .map(|s| {
                let valid = self.slots[s].valid;
                (0..self.sectors)
                    .filter(|&k| valid & (1 << k) != 0)
                    .map(|k| self.ready[s * self.sectors + k])
                    .collect()
            })
            .collect()
    }

    /// Marks sector `sector` of the line in `slot` dirty if it is valid.
    #[inline]
    pub fn mark_dirty(&mut self, slot: Slot, sector: u32) {
        let state = &mut self.slots[slot.0];
        state.dirty |= state.valid & (1 << sector);
    }

    /// Marks sector `sector` of the line in `slot` as filled by a prefetch if it is valid.
    #[inline]
    pub fn mark_prefetched(&mut self, slot: Slot, sector: u32) {
        let state = &mut self.slots[slot.0];
        state.prefetched |= state.valid & (1 << sector);
    }

    /// Clears the prefetch mark of sector `sector` of the line in `slot`; true when it was set
    /// (its first demand use).
    #[inline]
    pub fn take_prefetched(&mut self, slot: Slot, sector: u32) -> bool {
        let state = &mut self.slots[slot.0];
        let was = state.prefetched & (1 << sector) != 0;
        state.prefetched &= !(1 << sector);
        was
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
                (0..self.sectors)
                    .filter(move |&k| l.valid & (1 << k) != 0)
                    .map(move |k| self.ready[s * self.sectors + k])
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

    fn touch(c: &mut SectorCache, line: u64) {
        let slot = c.lookup(line).unwrap();
        c.touch(slot);
    }

    #[test]
    fn fully_associative_lru_evicts_least_recently_used() {
        let mut c = cache(4, 0);
        for line in [10, 20, 30, 40] {
            assert_eq!(fill(&mut c, line, 0), None);
        }
        touch(&mut c, 10);
        touch(&mut c, 30);
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
        touch(&mut c, 0);
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
        c.mark_dirty(s, 2);
        c.mark_prefetched(s, 0);
        c.mark_dirty(s, 3); // not valid: ignored
        let e = fill(&mut c, 2, 0).unwrap();
        assert_eq!((e.line, e.dirty, e.unused_prefetch), (1, 0b100, 0b1));
        let s = c.lookup(2).unwrap();
        c.mark_prefetched(s, 0);
        assert!(c.take_prefetched(s, 0));
        assert!(!c.take_prefetched(s, 0));
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

    /// The replacement rule written out directly: a use stamp per way and a scan of the set.
    struct Reference {
        ways: usize,
        sets: u64,
        /// Per way: (line, use stamp, pending until); `None` when empty.
        lines: Vec<Option<(u64, u64, u64)>>,
        clock: u64,
    }

    impl Reference {
        fn find_slot(&self, line: u64, now: u64, ways: Range<u32>) -> Result<usize, u64> {
            if let Some(s) = self
                .lines
                .iter()
                .position(|l| l.is_some_and(|l| l.0 == line))
            {
                return Ok(s);
            }
            let base = (line % self.sets) as usize * self.ways;
            let range = (base + ways.start as usize)..(base + ways.end as usize);
            if let Some(s) = range.clone().find(|&s| self.lines[s].is_none()) {
                return Ok(s);
            }
            let lines = || range.clone().map(|s| (s, self.lines[s].unwrap()));
            lines()
                .filter(|(_, l)| l.2 <= now)
                .min_by_key(|(_, l)| l.1)
                .map(|(s, _)| s)
                .ok_or_else(|| lines().map(|(_, l)| l.2).min().unwrap_or(now + 1))
        }

        fn install(&mut self, s: usize, line: u64, ready_at: u64) -> Option<u64> {
            self.clock += 1;
            let old = self.lines[s];
            let pending = match old {
                Some((l, _, p)) if l == line => p.max(ready_at),
                _ => ready_at,
            };
            self.lines[s] = Some((line, self.clock, pending));
            old.map(|o| o.0).filter(|&l| l != line)
        }

        fn touch(&mut self, line: u64) {
            self.clock += 1;
            if let Some(l) = self.lines.iter_mut().flatten().find(|l| l.0 == line) {
                l.1 = self.clock;
            }
        }
    }

    #[test]
    fn recency_lists_choose_the_same_victims_as_a_scan_of_use_stamps() {
        // Two shapes: fully associative, and 4 sets of 8 ways with a partition of the ways.
        for (lines, ways, split) in [(16u32, 0u32, 0u32), (32, 8, 3)] {
            let mut c = cache(lines, ways);
            let g = c.geometry();
            let mut r = Reference {
                ways: g.ways as usize,
                sets: u64::from(g.sets),
                lines: vec![None; lines as usize],
                clock: 0,
            };
            let mut seed = 0x2545_f491_4f6c_dd1du64;
            let mut next = |n: u64| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                seed % n
            };
            let mut now = 0;
            let (mut stalls, mut evictions) = (0, 0);
            for _ in 0..20_000 {
                now += next(3);
                let line = next(u64::from(lines) * 3);
                let range = match (split, next(2)) {
                    (0, _) => 0..g.ways,
                    (k, 0) => 0..k,
                    (k, _) => k..g.ways,
                };
                if next(4) == 0 {
                    if let Some(slot) = c.lookup(line) {
                        c.touch(slot);
                    }
                    r.touch(line);
                    continue;
                }
                let got = c.find_slot(line, now, range.clone());
                let want = r.find_slot(line, now, range);
                assert_eq!(got.map(|Slot(s)| s), want, "line {line} at {now}");
                if let Ok(slot) = got {
                    let ready_at = now + next(40);
                    let evicted = c.install(slot, line, next(4) as u32, ready_at);
                    assert_eq!(evicted.map(|e| e.line), r.install(slot.0, line, ready_at));
                    evictions += usize::from(evicted.is_some());
                } else {
                    stalls += 1;
                }
            }
            // Both paths of the victim search were exercised.
            assert!(
                stalls > 0 && evictions > 0,
                "{stalls} stalls, {evictions} evictions"
            );
        }
    }
}
