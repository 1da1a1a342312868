//! The energy model's inputs ([`EnergyEvents`], [`TimeInputs`]) derived from a run's statistics
//! JSON (docs/stats.md): the counters `vtq sim` already writes, read back through a view of the
//! keys the model needs, so stored statistics of earlier runs are evaluated the same way.
//! docs/energy.md, "Events", gives every rule below.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::model::config::SimConfig;

/// Memory events of one group of access classes, each a count of 32 B accesses.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MemoryEvents {
    /// L1 reads that hit or merged with a fill (prefetches that found their sector included).
    pub l1_read_hits: f64,
    /// L1 reads that missed (prefetches that fetched their sector included).
    pub l1_read_misses: f64,
    /// L1 stores that hit.
    pub l1_write_hits: f64,
    /// L1 stores that missed (write-through, no write-allocate).
    pub l1_write_misses: f64,
    /// L2 reads that hit or merged.
    pub l2_read_hits: f64,
    /// L2 reads that missed (each read DRAM).
    pub l2_read_misses: f64,
    /// L2 writes that hit or merged.
    pub l2_write_hits: f64,
    /// L2 writes that missed (allocated without reading).
    pub l2_write_misses: f64,
    /// 32 B flits between the L1s and the L2: one per L2 access.
    pub flits: f64,
    /// DRAM reads per 32 B.
    pub dram_reads: f64,
    /// DRAM writes per 32 B.
    pub dram_writes: f64,
}

/// Every event the model charges energy for.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EnergyEvents {
    /// Memory events of every access class but CTA state.
    pub memory: MemoryEvents,
    /// Memory events of CTA-state saves and restores (ray virtualization, class `cta_state`).
    pub cta_state: MemoryEvents,
    /// Ray-box tests: internal-node tests times `bvh.width` (every child box tested).
    pub box_tests: f64,
    /// Ray-triangle and ray-sphere tests (triangle-leaf and procedural-leaf tests).
    pub triangle_tests: f64,
    /// Treelet count table searches by treelet id.
    pub count_table_searches: f64,
    /// Treelet count table entry writes.
    pub count_table_writes: f64,
    /// Treelet count table entry reads of the scans for the largest queue.
    pub count_table_reads: f64,
    /// Treelet queue table entry reads.
    pub queue_table_reads: f64,
    /// Treelet queue table entry writes.
    pub queue_table_writes: f64,
}

/// What the time-proportional terms need of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TimeInputs {
    /// Seconds of the frame: cycles / `energy.clock_mhz`.
    pub seconds: f64,
    /// SMs of the GPU (`gpu.sms`).
    pub sms: f64,
    /// Fraction of SM-cycles in which an SM held work: the sum over SMs of the cycles before it
    /// held no CTA for good (`sm_finish_cycles`) over SMs x cycles.
    pub active_sm_fraction: f64,
}

/// One access class's counters (`memory.CLASS` in the statistics).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(default)]
struct ClassView {
    l1_hits: u64,
    l1_merges: u64,
    l1_misses: u64,
    l1_stores: u64,
    l1_store_hits: u64,
    l1_bypasses: u64,
    l2_accesses: u64,
    l2_hits: u64,
    l2_merges: u64,
    l2_misses: u64,
    dram_reads: u64,
}

/// `memory.prefetch`.
#[derive(Debug, Clone, Copy, Default, Deserialize)]
struct PrefetchView {
    dropped: u64,
    issued: u64,
}

/// `memory.dram`.
#[derive(Debug, Clone, Copy, Default, Deserialize)]
struct DramView {
    read_bytes: u64,
    write_bytes: u64,
}

/// `memory`: classes added after a run was stored read as zeros (they had no traffic then).
#[derive(Debug, Clone, Copy, Deserialize)]
struct MemView {
    bvh: ClassView,
    #[serde(default)]
    ray_record: ClassView,
    #[serde(default)]
    cta_state: ClassView,
    #[serde(default)]
    hit_record: ClassView,
    #[serde(default)]
    stack: ClassView,
    #[serde(default)]
    ray_stack: ClassView,
    prefetch: PrefetchView,
    dram: DramView,
}

/// `rt`: node tests by kind name.
#[derive(Debug, Clone, Deserialize)]
struct RtView {
    tests: BTreeMap<String, u64>,
}

/// `queues`: the treelet hardware's counters (zeros outside `queues` mode).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(default)]
struct QueuesView {
    enqueued_rays: u64,
    claims: u64,
    preloads: u64,
    treelet_warps: u64,
    grouped_warps: u64,
    repacks: u64,
    refills: u64,
    ray_stores: u64,
    stack_stores: u64,
}

/// The keys of the statistics JSON the model reads.
#[derive(Debug, Clone, Deserialize)]
pub(super) struct StatsView {
    /// `cycles`.
    pub cycles: u64,
    /// `rays`.
    pub rays: u64,
    sm_finish_cycles: Vec<u64>,
    cta_suspends: u64,
    cta_resumes: u64,
    rt: RtView,
    #[serde(default)]
    queues: QueuesView,
    memory: MemView,
}

impl StatsView {
    /// The view of statistics JSON `stats`, or the deserializer's reason it lacks a key.
    pub fn of(stats: &serde_json::Value) -> Result<StatsView, String> {
        StatsView::deserialize(stats).map_err(|e| e.to_string())
    }

    /// The time-proportional terms' inputs under `cfg` (its SMs and clock).
    pub fn time(&self, cfg: &SimConfig) -> TimeInputs {
        let sms = cfg.gpu.sms as f64;
        let busy: u64 = self
            .sm_finish_cycles
            .iter()
            .map(|&c| c.min(self.cycles))
            .sum();
        let sm_cycles = sms * self.cycles as f64;
        TimeInputs {
            seconds: self.cycles as f64 / (cfg.energy.clock_mhz as f64 * 1e6),
            sms,
            active_sm_fraction: if sm_cycles > 0.0 {
                (busy as f64 / sm_cycles).min(1.0)
            } else {
                0.0
            },
        }
    }

    /// The events of the run under `cfg` (its BVH width, sector size and count-table size).
    pub fn events(&self, cfg: &SimConfig) -> EnergyEvents {
        let m = &self.memory;
        let q = &self.queues;
        let per_32 = cfg.memory.sector_bytes as f64 / 32.0;
        // Stores among each class's L1 bypasses (docs/energy.md, "Events").
        let cta_stores = if self.cta_suspends + self.cta_resumes == 0 {
            0.0
        } else {
            m.cta_state.l1_bypasses as f64 * self.cta_suspends as f64
                / (self.cta_suspends + self.cta_resumes) as f64
        };
        let others = [
            (m.bvh, 0.0),
            (m.ray_record, q.ray_stores as f64),
            (m.hit_record, 0.0),
            (m.stack, 0.0),
            (m.ray_stack, q.stack_stores as f64),
        ];
        let mut memory = MemoryEvents::default();
        for (class, bypass_stores) in others {
            add_class(&mut memory, &class, bypass_stores, per_32);
        }
        memory.l1_read_hits += m.prefetch.dropped as f64;
        memory.l1_read_misses += m.prefetch.issued as f64;
        let mut cta_state = MemoryEvents::default();
        add_class(&mut cta_state, &m.cta_state, cta_stores, per_32);
        // DRAM writes are write-backs of any class; CTA state's share is its share of the L2
        // writes (an estimate: the counters do not split write-backs by class).
        let writes = m.dram.write_bytes as f64 / 32.0;
        let l2_writes = memory.l2_write_hits + memory.l2_write_misses;
        let cta_writes = cta_state.l2_write_hits + cta_state.l2_write_misses;
        let cta_share = if l2_writes + cta_writes > 0.0 {
            cta_writes / (l2_writes + cta_writes)
        } else {
            0.0
        };
        cta_state.dram_writes = writes * cta_share;
        memory.dram_writes = writes - cta_state.dram_writes;
        // DRAM reads: every class's own, the rest (none today) with the others.
        memory.dram_reads = m.dram.read_bytes as f64 / 32.0 - cta_state.dram_reads;
        let tests = |kind: &str| self.rt.tests.get(kind).copied().unwrap_or(0) as f64;
        let lookups = (q.enqueued_rays + q.treelet_warps + q.grouped_warps + q.repacks) as f64;
        EnergyEvents {
            memory,
            cta_state,
            box_tests: tests("internal") * cfg.bvh.width as f64,
            triangle_tests: tests("triangle_leaf") + tests("procedural"),
            count_table_searches: lookups,
            count_table_writes: lookups,
            count_table_reads: (q.claims + q.preloads) as f64 * cfg.hw.count_table_entries as f64,
            queue_table_reads: lookups + q.refills as f64,
            queue_table_writes: lookups + q.refills as f64,
        }
    }
}

/// Adds the L1 and L2 events of one class's counters, of which `bypass_stores` of its L1
/// bypasses were stores, and its DRAM reads (`per_32`: 32 B units per sector).
fn add_class(e: &mut MemoryEvents, c: &ClassView, bypass_stores: f64, per_32: f64) {
    e.l1_read_hits += (c.l1_hits + c.l1_merges) as f64;
    e.l1_read_misses += c.l1_misses as f64;
    e.l1_write_hits += c.l1_store_hits as f64;
    e.l1_write_misses += c.l1_stores.saturating_sub(c.l1_store_hits) as f64;
    // Stores reaching the L2: the L1's write-through stores and the bypassing stores. A read
    // miss reads DRAM (`dram_reads`), a store miss does not; the class's other misses and hits
    // are its writes'.
    let writes = c.l1_stores as f64 + bypass_stores;
    let write_misses = c.l2_misses.saturating_sub(c.dram_reads) as f64;
    let write_hits = (writes - write_misses).max(0.0);
    e.l2_read_hits += ((c.l2_hits + c.l2_merges) as f64 - write_hits).max(0.0);
    e.l2_read_misses += c.dram_reads as f64;
    e.l2_write_hits += write_hits;
    e.l2_write_misses += write_misses;
    e.flits += c.l2_accesses as f64;
    e.dram_reads += c.dram_reads as f64 * per_32;
}
