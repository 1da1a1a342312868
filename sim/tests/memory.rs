//! Tests of the memory hierarchy through its public API: latencies, bandwidth, MSHRs, bypass,
//! prefetch, stores, replacement, and that skipping idle cycles changes nothing.

use std::collections::VecDeque;

use vtq_sim::model::memory::l1::RETRY_BASE;
use vtq_sim::model::memory::{
    Acceptance, AccessClass, AccessError, L1Port, MemConfig, MemConfigError, MemRequest, MemStats,
    MemorySystem, Response, SectorState, Source, StallReason,
};
use vtq_sim::model::splitmix::SplitMix64;

const LINE: u64 = 128;

fn system(cfg: &MemConfig, sms: usize) -> MemorySystem {
    MemorySystem::new(cfg, sms).unwrap()
}

fn load(addr: u64, tag: u64) -> MemRequest {
    MemRequest::load(addr, 4, AccessClass::Bvh, tag)
}

fn drain(mem: &mut MemorySystem, sm: usize, now: u64) -> Vec<Response> {
    mem.pop_ready(sm, now).collect()
}

#[test]
fn latencies_of_hit_l2_hit_and_dram_are_exact() {
    let cfg = MemConfig::default();
    let (l1, l2, dram) = (
        cfg.l1_latency as u64,
        cfg.l2_latency as u64,
        cfg.dram_latency as u64,
    );
    let mut mem = system(&cfg, 2);
    let a = mem.access(100, 0, load(0x1000, 1)).unwrap();
    assert_eq!(a.source, Source::Dram);
    assert_eq!(a.done, 100 + l1 + l2 + dram);
    assert_eq!(a.done, 100 + 480, "Table 1: 39 + 187 + 254");
    // Nothing before the completion cycle, then exactly this response.
    assert_eq!(mem.next_event(), Some(a.done));
    assert!(drain(&mut mem, 0, a.done - 1).is_empty());
    let got = drain(&mut mem, 0, a.done);
    assert_eq!(got.len(), 1);
    assert_eq!((got[0].tag, got[0].addr, got[0].cycle), (1, 0x1000, a.done));
    assert_eq!(mem.next_event(), None);

    let t = 2000;
    let hit = mem.access(t, 0, load(0x1008, 2)).unwrap();
    assert_eq!((hit.source, hit.done), (Source::L1Hit, t + l1));
    let l2_hit = mem.access(t, 1, load(0x1000, 3)).unwrap();
    assert_eq!((l2_hit.source, l2_hit.done), (Source::L2Hit, t + l1 + l2));
    let store = mem
        .access(
            t,
            1,
            MemRequest::store(0x9000, 32, AccessClass::HitRecord, 4),
        )
        .unwrap();
    assert_eq!((store.source, store.done), (Source::L2Write, t + l1 + l2));
    let acks = drain(&mut mem, 1, t + l1 + l2);
    assert_eq!(
        acks.iter().map(|r| (r.tag, r.store)).collect::<Vec<_>>(),
        vec![(3, false), (4, true)]
    );
}

#[test]
fn dram_bandwidth_queues_back_to_back_misses() {
    // One channel of 8 B/cycle: each 32 B sector holds it for 4 cycles.
    let cfg = MemConfig {
        dram_bytes_per_cycle: 8,
        dram_channels: 1,
        ..MemConfig::default()
    };
    let base = (cfg.l1_latency + cfg.l2_latency) as u64;
    let dram = cfg.dram_latency as u64;
    let mut mem = system(&cfg, 3);
    let mut done = Vec::new();
    for i in 0..9u64 {
        // Three SMs, distinct lines, all in cycle 50: the DRAM requests arrive together.
        let a = mem.access(50, (i % 3) as usize, load(i * LINE, i)).unwrap();
        assert_eq!(a.source, Source::Dram);
        done.push(a.done);
    }
    let expected: Vec<u64> = (0..9).map(|i| 50 + base + 4 * i + dram).collect();
    assert_eq!(done, expected);
    let s = mem.stats();
    assert_eq!(s.dram.reads, 9);
    assert_eq!(s.dram.read_bytes, 9 * 32);
    assert_eq!(s.dram.queue_cycles, (0..9).map(|i| 4 * i).sum::<u64>());
    // A miss after the queue drained is not delayed.
    let late = mem.access(1000, 0, load(100 * LINE, 99)).unwrap();
    assert_eq!(late.done, 1000 + base + dram);

    // 12 B/cycle: sector i starts floor(32 i / 12) cycles after the common arrival.
    let cfg = MemConfig {
        dram_bytes_per_cycle: 12,
        dram_channels: 1,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    for i in 0..6u64 {
        let a = mem.access(0, 0, load(i * LINE, i)).unwrap();
        assert_eq!(a.done, base + 32 * i / 12 + dram);
    }
}

#[test]
fn misses_to_an_outstanding_sector_merge_and_complete_together() {
    let cfg = MemConfig::default();
    let mut mem = system(&cfg, 2);
    let first = mem.access(0, 0, load(0x400, 10)).unwrap();
    let merged = mem.access(7, 0, load(0x404, 11)).unwrap();
    assert_eq!((merged.source, merged.done), (Source::L1Merge, first.done));
    // Another sector of the same line is a separate miss, read from DRAM.
    let other = mem.access(8, 0, load(0x420, 12)).unwrap();
    assert_eq!(other.source, Source::Dram);
    // Another SM missing the same sector merges with the L2 fill.
    let sm1 = mem.access(9, 1, load(0x400, 13)).unwrap();
    assert_eq!((sm1.source, sm1.done), (Source::L2Merge, first.done));
    let s = mem.stats().bvh;
    assert_eq!(
        (s.l1_loads, s.l1_misses, s.l1_merges, s.l1_hits),
        (4, 3, 1, 0)
    );
    assert_eq!((s.l2_accesses, s.l2_misses, s.l2_merges), (3, 2, 1));
    assert_eq!(mem.stats().dram.reads, 2);
    // Both responses of SM 0 for the first sector come in the same cycle, in acceptance order.
    let got = drain(&mut mem, 0, first.done);
    assert_eq!(got.iter().map(|r| r.tag).collect::<Vec<_>>(), vec![10, 11]);
    assert!(got.iter().all(|r| r.cycle == first.done));
}

#[test]
fn full_mshrs_stall_until_the_first_fill() {
    let cfg = MemConfig {
        l1_mshrs: 2,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    let a = mem.access(0, 0, load(0, 1)).unwrap();
    let b = mem.access(3, 0, load(LINE, 2)).unwrap();
    let e = mem.access(5, 0, load(2 * LINE, 3)).unwrap_err();
    let stall = e.stall().unwrap();
    assert_eq!(stall.reason, StallReason::MshrsFull);
    assert_eq!(stall.retry_at, a.done.min(b.done));
    assert!(e.to_string().contains("MSHR"), "{e}");
    // A merge needs no MSHR and is accepted while they are all busy.
    assert_eq!(
        mem.access(6, 0, load(4, 4)).unwrap().source,
        Source::L1Merge
    );
    // Still refused one cycle before the fill, accepted at it.
    assert!(mem
        .access(stall.retry_at - 1, 0, load(2 * LINE, 3))
        .is_err());
    let c = mem.access(stall.retry_at, 0, load(2 * LINE, 3)).unwrap();
    assert_eq!(c.source, Source::Dram);
    assert_eq!(mem.stats().mshr_stalls, 2);
    assert_eq!(
        mem.stats().bvh.l1_loads,
        4,
        "stalled attempts are not accesses"
    );
}

#[test]
fn a_set_whose_lines_are_all_being_filled_stalls() {
    // Two lines, fully associative, plenty of MSHRs.
    let cfg = MemConfig {
        l1_bytes: 256,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    let a = mem.access(0, 0, load(0, 1)).unwrap();
    mem.access(1, 0, load(LINE, 2)).unwrap();
    // Another sector of a line being filled is fine: no replacement needed. Line 0 is now
    // being filled until cycle a.done + 2 (its sector accepted at 2), line 1 until a.done + 1.
    mem.access(2, 0, load(32, 3)).unwrap();
    let stall = mem
        .access(2, 0, load(2 * LINE, 4))
        .unwrap_err()
        .stall()
        .unwrap();
    assert_eq!(stall.reason, StallReason::SetReserved);
    // Line 1 is free first.
    assert_eq!(stall.retry_at, a.done + 1);
    assert!(mem
        .access(stall.retry_at - 1, 0, load(2 * LINE, 4))
        .is_err());
    assert!(mem.access(stall.retry_at, 0, load(2 * LINE, 4)).is_ok());
    // Line 1 was the victim although line 0 is older: line 0 is still being filled.
    assert!(mem.l1_contains(0, 0));
    assert!(!mem.l1_contains(0, LINE));
    assert_eq!(mem.stats().set_stalls, 2);
}

#[test]
fn ray_record_loads_bypass_the_l1() {
    let cfg = MemConfig {
        l1_bytes: 256,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    mem.access(0, 0, load(0, 1)).unwrap();
    mem.access(0, 0, load(LINE, 2)).unwrap();
    let mut t = 1000;
    for i in 0..20u64 {
        let req = MemRequest::load(0x10_0000 + i * 32, 32, AccessClass::RayRecord, 100 + i)
            .bypassing_l1();
        let a = mem.access(t, 0, req).unwrap();
        assert_eq!(a.source, Source::Dram);
        t += 1;
    }
    for i in 0..20u64 {
        assert!(!mem.l1_contains(0, 0x10_0000 + i * 32));
        assert_ne!(
            mem.l2_sector(0x10_0000 + i * 32, u64::MAX),
            SectorState::Absent
        );
    }
    // The two BVH lines were not displaced.
    assert_eq!(mem.access(t, 0, load(0, 3)).unwrap().source, Source::L1Hit);
    assert_eq!(
        mem.access(t, 0, load(LINE, 4)).unwrap().source,
        Source::L1Hit
    );
    let rays = mem.stats().ray_record;
    assert_eq!(
        (rays.l1_bypasses, rays.l1_loads, rays.l2_accesses),
        (20, 0, 20)
    );
    // A second read of a ray record hits in the L2.
    let req = MemRequest::load(0x10_0000, 32, AccessClass::RayRecord, 200).bypassing_l1();
    let again = mem.access(t + 1000, 0, req).unwrap();
    assert_eq!(again.source, Source::L2Hit);
}

#[test]
fn prefetches_fill_the_l1_without_responses_and_count_their_use() {
    let cfg = MemConfig {
        l1_bytes: 256,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    let p = mem
        .access(0, 0, MemRequest::prefetch(0x40, AccessClass::Bvh))
        .unwrap();
    assert_eq!(p.source, Source::Dram);
    assert_eq!(mem.pending_responses(0), 0);
    assert_eq!(mem.next_event(), None, "a prefetch fill is not an event");
    assert!(mem.l1_contains(0, 0x40));
    assert_eq!(
        mem.l1_sector(0, 0x40, 0),
        Some(SectorState::Pending { ready_at: p.done })
    );
    // A second prefetch of the sector is dropped.
    let again = mem
        .access(1, 0, MemRequest::prefetch(0x44, AccessClass::Bvh))
        .unwrap();
    assert_eq!(again.source, Source::AlreadyInL1);
    // A demand load after the fill hits and uses the prefetch.
    let hit = mem.access(p.done, 0, load(0x48, 1)).unwrap();
    assert_eq!(hit.source, Source::L1Hit);
    // A late prefetch: the demand load merges with it and also counts as a use.
    let late = mem
        .access(p.done, 0, MemRequest::prefetch(0x80, AccessClass::Bvh))
        .unwrap();
    let merged = mem.access(p.done + 5, 0, load(0x80, 2)).unwrap();
    assert_eq!((merged.source, merged.done), (Source::L1Merge, late.done));
    // A prefetch evicted before use: two demand lines push the prefetched line 2 out.
    let t = late.done;
    mem.access(t, 0, MemRequest::prefetch(2 * LINE, AccessClass::Bvh))
        .unwrap();
    let x = mem.access(t + 1000, 0, load(3 * LINE, 3)).unwrap();
    mem.access(x.done, 0, load(4 * LINE, 4)).unwrap();
    assert!(!mem.l1_contains(0, 2 * LINE));
    let s = mem.stats();
    assert_eq!(s.prefetch.requests, 4);
    assert_eq!(s.prefetch.dropped, 1);
    assert_eq!(s.prefetch.issued, 3);
    assert_eq!(s.prefetch.used, 2);
    // Line 2 was unused; line 0 (sector 0x40) was evicted too, but it had been used.
    assert_eq!(s.prefetch.evicted_unused, 1);
    assert_eq!(s.bvh.l1_loads, 4, "prefetches are not demand loads");
    assert_eq!(s.bvh.l2_accesses, 5, "but they are L2 accesses");
}

#[test]
fn fully_associative_l1_replaces_least_recently_used() {
    let cfg = MemConfig::default();
    let lines = (cfg.l1_bytes / cfg.line_bytes) as u64;
    let mut mem = system(&cfg, 1);
    for i in 0..lines {
        // 10 cycles apart: about 48 misses in flight, fewer than the 64 MSHRs.
        mem.access(10 * i, 0, load(i * LINE, i)).unwrap();
    }
    let t = 10_000;
    // Use line 0 again: line 1 is now the least recently used.
    assert_eq!(mem.access(t, 0, load(0, 0)).unwrap().source, Source::L1Hit);
    mem.access(t + 1, 0, load(lines * LINE, 0)).unwrap();
    assert!(mem.l1_contains(0, 0));
    assert!(!mem.l1_contains(0, LINE));
    assert!(mem.l1_contains(0, 2 * LINE));
    mem.access(t + 2, 0, load((lines + 1) * LINE, 0)).unwrap();
    assert!(!mem.l1_contains(0, 2 * LINE));
    assert!(mem.l1_contains(0, 3 * LINE));
}

#[test]
fn sixteen_way_l2_replaces_least_recently_used_in_the_set() {
    let cfg = MemConfig::default();
    let sets = (cfg.l2_bytes / cfg.line_bytes / cfg.l2_ways) as u64;
    let mut mem = system(&cfg, 1);
    // Lines k * sets share L2 set 0. Bypass the L1 so only the L2 is exercised.
    let addr = |k: u64| k * sets * LINE;
    let ray = |k: u64, tag| MemRequest::load(addr(k), 32, AccessClass::Bvh, tag).bypassing_l1();
    for k in 0..16 {
        mem.access(k, 0, ray(k, k)).unwrap();
    }
    let t = 10_000;
    assert_eq!(mem.access(t, 0, ray(0, 0)).unwrap().source, Source::L2Hit);
    // A line of another set evicts nothing from set 0.
    mem.access(
        t,
        0,
        MemRequest::load(LINE, 32, AccessClass::Bvh, 0).bypassing_l1(),
    )
    .unwrap();
    mem.access(t + 1, 0, ray(16, 0)).unwrap();
    let present = |mem: &MemorySystem, k| mem.l2_sector(addr(k), u64::MAX) != SectorState::Absent;
    assert!(present(&mem, 0));
    assert!(!present(&mem, 1));
    assert!((2..=16).all(|k| present(&mem, k)));
}

#[test]
fn a_sector_miss_in_a_present_line_evicts_nothing() {
    // One line of L1: sectors of that line coexist, another line replaces all of them.
    let cfg = MemConfig {
        l1_bytes: 128,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    let a = mem.access(0, 0, load(0, 1)).unwrap();
    let b = mem.access(1, 0, load(96, 2)).unwrap();
    assert_eq!((a.source, b.source), (Source::Dram, Source::Dram));
    let t = b.done;
    assert_eq!(mem.access(t, 0, load(0, 3)).unwrap().source, Source::L1Hit);
    assert_eq!(mem.access(t, 0, load(96, 4)).unwrap().source, Source::L1Hit);
    // Sector 1 was never fetched: the line's tag is present but the sector misses down to DRAM.
    assert_eq!(mem.access(t, 0, load(32, 5)).unwrap().source, Source::Dram);
    let c = mem.access(t + 1000, 0, load(LINE, 6)).unwrap();
    assert_eq!(c.source, Source::Dram);
    assert!(!mem.l1_contains(0, 0) && !mem.l1_contains(0, 96));
    // The evicted line's sectors are still in the L2.
    assert_eq!(
        mem.access(c.done, 0, load(0, 7)).unwrap().source,
        Source::L2Hit
    );
}

#[test]
fn stores_write_through_the_l1_and_back_from_the_l2() {
    // L2 of 8 lines, fully associative.
    let cfg = MemConfig {
        l2_bytes: 1024,
        l2_ways: 0,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    let store = |addr, tag| MemRequest::store(addr, 32, AccessClass::HitRecord, tag);
    // Store miss: no L1 allocation; the L2 holds the sector, dirty, without a DRAM read.
    mem.access(0, 0, store(0x2000, 1)).unwrap();
    assert!(!mem.l1_contains(0, 0x2000));
    assert_eq!(
        mem.l2_sector(0x2000, cfg.l1_latency as u64),
        SectorState::Ready
    );
    assert_eq!(mem.stats().dram.reads, 0);
    // Store hit in the L1 keeps the sector.
    let l = mem.access(1, 0, load(0x3000, 2)).unwrap();
    mem.access(l.done, 0, store(0x3000, 3)).unwrap();
    assert!(mem.l1_contains(0, 0x3000));
    let hr = mem.stats().hit_record;
    assert_eq!(
        (hr.l1_stores, hr.l1_store_hits, hr.l2_misses, hr.l2_hits),
        (2, 1, 1, 1)
    );
    // Eight more lines through the L2 evict both dirty lines: two write-backs.
    let mut t = l.done + 1;
    for i in 0..8u64 {
        t = mem
            .access(t, 0, load(0x10_0000 + i * LINE, 10 + i))
            .unwrap()
            .done;
    }
    let d = mem.stats().dram;
    assert_eq!((d.writes, d.write_bytes), (2, 64));
    // Loads from the written line now come from DRAM.
    assert_eq!(
        mem.access(t, 0, load(0x2000, 30)).unwrap().source,
        Source::Dram
    );
}

#[test]
fn reserved_l2_ways_keep_ray_records_apart() {
    // One L2 set of 4 ways, one reserved for ray records.
    let cfg = MemConfig {
        l2_bytes: 512,
        l2_ways: 4,
        l2_ray_ways: 1,
        ..MemConfig::default()
    };
    let mut mem = system(&cfg, 1);
    let ray =
        |i: u64| MemRequest::load(0x8000 + i * LINE, 32, AccessClass::RayRecord, i).bypassing_l1();
    let bvh = |i: u64| MemRequest::load(i * LINE, 32, AccessClass::Bvh, i).bypassing_l1();
    let mut t = 0;
    for i in 0..3 {
        t = mem.access(t, 0, bvh(i)).unwrap().done;
    }
    for i in 0..10 {
        t = mem.access(t, 0, ray(i)).unwrap().done;
    }
    let l2 = |mem: &MemorySystem, a| mem.l2_sector(a, u64::MAX) != SectorState::Absent;
    assert!(
        (0..3).all(|i| l2(&mem, i * LINE)),
        "ray records evict only ray records"
    );
    assert_eq!((0..10).filter(|&i| l2(&mem, 0x8000 + i * LINE)).count(), 1);
    // BVH lines evict each other, not the ray record.
    t = mem.access(t, 0, bvh(3)).unwrap().done;
    mem.access(t, 0, bvh(4)).unwrap();
    assert!(l2(&mem, 0x8000 + 9 * LINE));
    assert!(!l2(&mem, 0));
}

#[test]
fn bad_requests_are_errors_and_change_nothing() {
    let cfg = MemConfig::default();
    let mut mem = system(&cfg, 2);
    mem.access(10, 0, load(0, 1)).unwrap();
    let before = mem.stats();
    let cases = [
        (10, 2, load(0, 2)),
        (10, 0, MemRequest::load(0, 0, AccessClass::Bvh, 2)),
        (10, 0, MemRequest::load(0, 33, AccessClass::Bvh, 2)),
        (10, 0, MemRequest::load(30, 4, AccessClass::Bvh, 2)),
        (
            10,
            0,
            MemRequest::prefetch(0, AccessClass::Bvh).bypassing_l1(),
        ),
        (9, 0, load(0, 2)),
        (u64::MAX, 0, load(0, 2)),
    ];
    let errors: Vec<AccessError> = cases
        .into_iter()
        .map(|(t, sm, req)| mem.access(t, sm, req).unwrap_err())
        .collect();
    assert!(matches!(
        errors[0],
        AccessError::NoSuchSm { sm: 2, num_sms: 2 }
    ));
    assert!(errors[1..4]
        .iter()
        .all(|e| matches!(e, AccessError::BadSize { .. })));
    assert!(matches!(errors[4], AccessError::BadPrefetch { .. }));
    assert!(matches!(
        errors[5],
        AccessError::TimeWentBackwards { now: 9, last: 10 }
    ));
    assert!(matches!(errors[6], AccessError::CycleOutOfRange { .. }));
    assert!(errors.iter().all(|e| e.stall().is_none()));
    assert_eq!(mem.stats(), before);
    assert_eq!(mem.pending_responses(0), 1);
    assert!(mem.pop_ready(5, u64::MAX).next().is_none());
}

#[test]
fn construction_rejects_bad_configs() {
    assert_eq!(
        MemorySystem::new(&MemConfig::default(), 0).unwrap_err(),
        MemConfigError::NoSms
    );
    let cfg = MemConfig {
        l2_ways: 5,
        ..MemConfig::default()
    };
    let e = MemorySystem::new(&cfg, 4).unwrap_err();
    assert!(e.to_string().contains("`l2_ways`"), "{e}");
}

#[test]
fn debug_state_lists_outstanding_work() {
    let mut mem = system(&MemConfig::default(), 2);
    mem.access(0, 1, load(0, 1)).unwrap();
    mem.access(0, 1, load(LINE, 2)).unwrap();
    let dump = mem.debug_state(5);
    assert!(dump.contains("SM 0: L1 0 lines, MSHRs 0/64"), "{dump}");
    assert!(dump.contains("SM 1: L1 2 lines, MSHRs 2/64"), "{dump}");
    assert!(dump.contains("2 responses queued"), "{dump}");
}

// ---- skipping idle cycles ----------------------------------------------------------------

/// A closed-loop requester of one SM: at most `WINDOW` outstanding responses, a random think
/// time after each issue or response, retry in the next cycle after a stall.
struct Requester {
    rng: SplitMix64,
    wake: Option<u64>,
    pending: Option<MemRequest>,
    outstanding: usize,
    issued: usize,
}

const WINDOW: usize = 6;
const BUDGET: usize = 250;

impl Requester {
    /// A response arrived at `now`: one fewer outstanding; wake after a think time if asleep.
    fn responded(&mut self, now: u64) {
        self.outstanding -= 1;
        if self.wake.is_none() && self.issued < BUDGET {
            self.wake = Some(now + 1 + self.rng.below_exact(6));
        }
    }

    /// The request to offer at `now`, if the requester is awake and has budget left (the
    /// stalled one again, else a new one tagged from `next_tag`).
    fn offer(&mut self, now: u64, next_tag: &mut u64) -> Option<MemRequest> {
        if !(self.wake.is_some_and(|w| w <= now) && self.issued < BUDGET) {
            return None;
        }
        let rng = &mut self.rng;
        Some(*self.pending.get_or_insert_with(|| {
            *next_tag += 1;
            random_request(rng, *next_tag)
        }))
    }

    /// `req` was accepted at `now`: think, unless the window of outstanding responses is full.
    fn accepted(&mut self, now: u64, req: &MemRequest) {
        self.pending = None;
        self.issued += 1;
        self.outstanding += usize::from(!req.prefetch);
        self.wake = (self.outstanding < WINDOW && self.issued < BUDGET)
            .then(|| now + 1 + self.rng.below_exact(6));
    }
}

/// One line of the run log.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Event {
    Accepted {
        now: u64,
        sm: usize,
        tag: u64,
        done: u64,
        source: Source,
    },
    Stalled {
        now: u64,
        sm: usize,
        reason: StallReason,
        retry_at: u64,
    },
    Delivered {
        now: u64,
        sm: usize,
        response: Response,
    },
}

/// A small hierarchy with little room, so hits, merges, stalls and DRAM queueing all occur.
fn stress_config() -> MemConfig {
    MemConfig {
        l1_bytes: 1024,
        l1_ways: 2,
        l1_latency: 3,
        l1_mshrs: 4,
        l2_bytes: 4096,
        l2_ways: 4,
        l2_latency: 10,
        l2_ray_ways: 1,
        dram_latency: 20,
        dram_bytes_per_cycle: 12,
        ..MemConfig::default()
    }
}

fn random_request(rng: &mut SplitMix64, tag: u64) -> MemRequest {
    let addr = rng.below_exact(40) * LINE + rng.below_exact(4) * 32 + 4 * rng.below_exact(4);
    let class = AccessClass::ALL[rng.below_exact(4) as usize];
    match rng.below_exact(10) {
        0 => MemRequest::store(addr, 8, class, tag),
        1 => MemRequest::load(addr, 16, AccessClass::RayRecord, tag).bypassing_l1(),
        2 => MemRequest::prefetch(addr, class),
        _ => MemRequest::load(addr, 4, class, tag),
    }
}

/// One requester per SM, seeded from `seed`, the first waking in cycle `sm`.
fn requesters(seed: u64, sms: usize) -> Vec<Requester> {
    (0..sms)
        .map(|sm| Requester {
            rng: SplitMix64::new(seed * 1000 + sm as u64 + 1),
            wake: Some(sm as u64),
            pending: None,
            outstanding: 0,
            issued: 0,
        })
        .collect()
}

/// Runs the requesters against the memory system, visiting every cycle (`jump == false`) or
/// only cycles where a response is due or a requester wakes (`jump == true`).
fn run(seed: u64, sms: usize, jump: bool) -> (Vec<Event>, MemStats) {
    let mut mem = system(&stress_config(), sms);
    let mut reqs = requesters(seed, sms);
    let mut log = Vec::new();
    let mut next_tag: Vec<u64> = (0..sms as u64).map(|sm| sm << 32).collect();
    let mut now = 0;
    loop {
        for (sm, r) in reqs.iter_mut().enumerate() {
            for response in mem.pop_ready(sm, now) {
                log.push(Event::Delivered { now, sm, response });
                r.responded(now);
            }
            if let Some(req) = r.offer(now, &mut next_tag[sm]) {
                match mem.access(now, sm, req) {
                    Ok(a) => {
                        log.push(Event::Accepted {
                            now,
                            sm,
                            tag: req.tag,
                            done: a.done,
                            source: a.source,
                        });
                        r.accepted(now, &req);
                    }
                    Err(e) => {
                        let stall = e.stall().expect("generated requests are valid");
                        log.push(Event::Stalled {
                            now,
                            sm,
                            reason: stall.reason,
                            retry_at: stall.retry_at,
                        });
                        r.wake = Some(now + 1);
                    }
                }
            }
        }
        let wakes = reqs
            .iter()
            .filter_map(|r| r.wake.filter(|_| r.issued < BUDGET));
        let next = wakes.chain(mem.next_event()).min();
        match next {
            None => break,
            Some(_) if !jump => now += 1,
            Some(t) => now = t.max(now + 1),
        }
        assert!(now < 1_000_000, "run did not finish");
    }
    (log, mem.stats())
}

/// [`run`] with the L1 ports on their own, each SM at its own cycle as the simulator's engine
/// runs them: an SM (picked at random) visits its next cycle if that is before its port's
/// horizon; at random moments, and whenever no SM may go on, the L2 applies in (cycle, phase,
/// SM, sequence) order every operation accepted before the cycle all SMs have reached, and
/// each port settles what it has results for.
fn run_lagged(seed: u64, sms: usize) -> (Vec<Event>, MemStats, usize) {
    let cfg = stress_config();
    let (mut ports, mut l2) = system(&cfg, sms).into_parts();
    let mut reqs = requesters(seed, sms);
    let mut rng = SplitMix64::new(0x5851_f42d_4c95_7f2d ^ seed);
    let mut log = Vec::new();
    // Log entries to complete when their operation settles: (entry, SM, operation, merge).
    let mut unsettled: Vec<(usize, usize, u64, bool)> = Vec::new();
    // Operations posted to the L2 and not yet applied: (SM, operation number, operation).
    let mut posted = VecDeque::new();
    let mut next_post = vec![0u64; sms];
    let mut deferred_retries = 0;
    let mut next_tag: Vec<u64> = (0..sms as u64).map(|sm| sm << 32).collect();
    let mut now = vec![0u64; sms];
    let done = |r: &Requester, p: &L1Port| {
        r.issued >= BUDGET && p.next_response().is_none() && p.ops().is_empty()
    };
    loop {
        let movable: Vec<usize> = (0..sms)
            .filter(|&sm| !done(&reqs[sm], &ports[sm]) && now[sm] < ports[sm].horizon())
            .collect();
        if movable.is_empty() || rng.below_exact(8) == 0 {
            // Every SM has posted its operations before the cycle all have reached.
            for (sm, port) in ports.iter().enumerate() {
                let first = port.first_op();
                for (k, op) in port.ops().iter().enumerate() {
                    let id = first + k as u64;
                    if id >= next_post[sm] {
                        posted.push_back((sm, id, *op));
                        next_post[sm] = id + 1;
                    }
                }
            }
            let reached = (0..sms)
                .map(|sm| {
                    if done(&reqs[sm], &ports[sm]) {
                        u64::MAX
                    } else {
                        now[sm]
                    }
                })
                .min()
                .unwrap_or(u64::MAX);
            let mut ready: Vec<(usize, u64, _)> = Vec::new();
            posted.retain(|&(sm, id, op)| {
                if op.cycle < reached {
                    ready.push((sm, id, op));
                    false
                } else {
                    true
                }
            });
            ready.sort_unstable_by_key(|(_, _, op)| op.key());
            for (sm, id, op) in ready {
                let result = l2.apply(&op);
                ports[sm].set_result(id, result);
            }
            unsettled.retain(|&(entry, sm, op, merge)| {
                let Some((done, source)) = ports[sm].result(op) else {
                    return true;
                };
                if let Event::Accepted {
                    done: d, source: s, ..
                } = &mut log[entry]
                {
                    *d = done;
                    *s = if merge { Source::L1Merge } else { source };
                }
                false
            });
            for port in &mut ports {
                port.settle();
            }
            for event in &mut log {
                if let Event::Stalled { sm, retry_at, .. } = event {
                    *retry_at = ports[*sm].resolve_retry(*retry_at);
                }
            }
            if movable.is_empty() {
                if (0..sms).all(|sm| done(&reqs[sm], &ports[sm])) {
                    break;
                }
                continue;
            }
        }
        let sm = movable[rng.below_exact(movable.len() as u64) as usize];
        let t = now[sm];
        let r = &mut reqs[sm];
        for response in ports[sm].pop_ready(t) {
            log.push(Event::Delivered {
                now: t,
                sm,
                response,
            });
            r.responded(t);
        }
        if let Some(req) = r.offer(t, &mut next_tag[sm]) {
            match ports[sm].access(t, 0, req) {
                Ok(a) => {
                    let (done, source) = match a {
                        Acceptance::Known(a) => (a.done, a.source),
                        Acceptance::Pending { op, merge } => {
                            unsettled.push((log.len(), sm, op, merge));
                            (0, Source::L2Write)
                        }
                    };
                    log.push(Event::Accepted {
                        now: t,
                        sm,
                        tag: req.tag,
                        done,
                        source,
                    });
                    r.accepted(t, &req);
                }
                Err(e) => {
                    let stall = e.stall().expect("generated requests are valid");
                    deferred_retries += usize::from(stall.retry_at >= RETRY_BASE);
                    log.push(Event::Stalled {
                        now: t,
                        sm,
                        reason: stall.reason,
                        retry_at: stall.retry_at,
                    });
                    r.wake = Some(t + 1);
                }
            }
        }
        now[sm] += 1;
        assert!(now[sm] < 1_000_000, "run did not finish");
    }
    let mut stats = l2.stats();
    for port in &ports {
        stats.add(port.stats());
    }
    (log, stats, deferred_retries)
}

/// Each SM's events in order.
fn per_sm(log: &[Event], sms: usize) -> Vec<Vec<Event>> {
    let mut out = vec![Vec::new(); sms];
    for e in log {
        let sm = match e {
            Event::Accepted { sm, .. }
            | Event::Stalled { sm, .. }
            | Event::Delivered { sm, .. } => *sm,
        };
        out[sm].push(e.clone());
    }
    out
}

/// Deferring every L2 operation until every SM has passed its cycle, with each SM at its own
/// cycle (up to one L2 round trip past its oldest unsettled operation) and results settled
/// whenever they arrive, gives exactly the accesses, stalls (with their retry cycles),
/// responses and counters of applying each operation as it is accepted.
#[test]
fn lagged_l1_ports_match_the_immediate_memory_system() {
    let mut deferred = 0;
    for seed in 0..12 {
        let (immediate, immediate_stats) = run(seed, 4, false);
        let (lagged, lagged_stats, retries) = run_lagged(seed, 4);
        assert_eq!(per_sm(&lagged, 4), per_sm(&immediate, 4), "seed {seed}");
        assert_eq!(lagged_stats, immediate_stats, "seed {seed}");
        assert!(immediate_stats.mshr_stalls + immediate_stats.set_stalls > 0);
        deferred += retries;
    }
    assert!(
        deferred > 0,
        "some stalls had to wait for a settle to know their retry cycle"
    );
}

#[test]
fn skipping_to_next_event_matches_stepping_every_cycle() {
    let mut prefetches_dropped = 0;
    for seed in 0..6 {
        let (step_log, step_stats) = run(seed, 4, false);
        let (jump_log, jump_stats) = run(seed, 4, true);
        assert_eq!(step_log, jump_log, "seed {seed}");
        assert_eq!(step_stats, jump_stats, "seed {seed}");

        // Every response came exactly at its completion cycle, each SM's in completion order
        // with ties in acceptance (= tag) order, and every non-prefetch access got one.
        let mut last: Vec<(u64, u64)> = vec![(0, 0); 4];
        let mut delivered = 0;
        for e in &step_log {
            if let Event::Delivered { now, sm, response } = e {
                assert_eq!(*now, response.cycle);
                assert!(
                    (response.cycle, response.tag) > last[*sm],
                    "seed {seed}: order"
                );
                last[*sm] = (response.cycle, response.tag);
                delivered += 1;
            }
        }
        let accepted = step_log
            .iter()
            .filter(
                |e| matches!(e, Event::Accepted { source, .. } if *source != Source::AlreadyInL1),
            )
            .count() as u64;
        let s = step_stats;
        assert_eq!(accepted, delivered + s.prefetch.issued);

        // The stream exercised every mechanism.
        let total = |f: fn(&vtq_sim::model::memory::ClassStats) -> u64| {
            AccessClass::ALL.iter().map(|&c| f(s.class(c))).sum::<u64>()
        };
        assert!(
            total(|c| c.l1_hits) > 0 && total(|c| c.l1_merges) > 0,
            "seed {seed}: {s:?}"
        );
        assert!(
            total(|c| c.l2_hits) > 0 && total(|c| c.l2_merges) > 0,
            "seed {seed}: {s:?}"
        );
        assert!(
            s.mshr_stalls > 0 && s.dram.queue_cycles > 0 && s.dram.writes > 0,
            "{s:?}"
        );
        assert!(s.prefetch.used > 0, "seed {seed}: {s:?}");
        prefetches_dropped += s.prefetch.dropped;
    }
    // A full prefetch queue drops a prefetch in some streams, not all (seed 2's never fills it).
    assert!(prefetches_dropped > 0);
}

#[test]
fn runs_are_deterministic() {
    let (log_a, stats_a) = run(42, 3, true);
    let (log_b, stats_b) = run(42, 3, true);
    assert_eq!(log_a, log_b);
    assert_eq!(
        serde_json::to_string(&stats_a).unwrap(),
        serde_json::to_string(&stats_b).unwrap()
    );
    let (log_c, _) = run(43, 3, true);
    assert_ne!(log_a, log_c, "different seeds give different streams");
}

/// Drains a queue of cycle-ordered requests with retries, for the retry_at check below.
fn issue_all(
    mem: &mut MemorySystem,
    mut queue: VecDeque<MemRequest>,
    use_retry_at: bool,
) -> Vec<(u64, u64)> {
    let mut now = 0;
    let mut accepted = Vec::new();
    while let Some(req) = queue.front().copied() {
        match mem.access(now, 0, req) {
            Ok(a) => {
                accepted.push((now, a.done));
                queue.pop_front();
                now += 1;
            }
            Err(e) => {
                let stall = e.stall().unwrap();
                now = if use_retry_at {
                    stall.retry_at
                } else {
                    now + 1
                };
            }
        }
    }
    accepted
}

#[test]
fn jumping_to_retry_at_accepts_at_the_same_cycles_as_retrying_every_cycle() {
    let cfg = stress_config();
    let requests: VecDeque<MemRequest> = (0..60u64)
        .map(|i| load((i * 7 % 23) * LINE + (i % 4) * 32, i))
        .collect();
    let mut every = system(&cfg, 1);
    let mut jumping = system(&cfg, 1);
    let a = issue_all(&mut every, requests.clone(), false);
    let b = issue_all(&mut jumping, requests, true);
    assert_eq!(a, b);
    assert!(
        every.stats().mshr_stalls + every.stats().set_stalls
            > jumping.stats().mshr_stalls + jumping.stats().set_stalls
    );
}
