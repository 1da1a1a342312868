//! [`MemStats`]: counters of the memory system, by access class.

use serde::Serialize;

use super::request::AccessClass;

vtq_hdl::counters! {
    /// Counters for one [`AccessClass`].
    ///
    /// L1 load counters count demand loads only (not prefetches, not L1 bypasses):
    /// `l1_loads = l1_hits + l1_merges + l1_misses`. L2 counters count every request that reached
    /// the L2 (L1 misses, prefetches that missed the L1, bypasses and stores):
    /// `l2_accesses = l2_hits + l2_merges + l2_misses`.
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
    pub struct ClassStats {
        /// Demand loads looked up in the L1.
        pub l1_loads: u64,
        /// ... that found their sector present.
        pub l1_hits: u64,
        /// ... that found their sector being filled and merged with that miss (MSHR hit).
        pub l1_merges: u64,
        /// ... that allocated an MSHR and went to the L2.
        pub l1_misses: u64,
        /// Stores looked up in the L1 (write-through, no write-allocate).
        pub l1_stores: u64,
        /// ... that found their sector present (updated in place).
        pub l1_store_hits: u64,
        /// Loads and stores that bypassed the L1.
        pub l1_bypasses: u64,
        /// Requests that reached the L2.
        pub l2_accesses: u64,
        /// ... that found their sector present.
        pub l2_hits: u64,
        /// ... that found their sector being filled from DRAM and merged with it.
        pub l2_merges: u64,
        /// ... that missed (loads read DRAM; stores allocate without reading).
        pub l2_misses: u64,
        /// Sector reads from DRAM caused by this class.
        pub dram_reads: u64,
        /// Cycles those reads waited for their DRAM channel (queueing behind earlier transfers).
        pub dram_queue_cycles: u64,
    }
}

vtq_hdl::counters! {
    /// L1 prefetch counters (all classes).
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
    pub struct PrefetchStats {
        /// Prefetches accepted.
        pub requests: u64,
        /// ... dropped because the sector was already in or being filled into the L1.
        pub dropped: u64,
        /// ... that allocated an MSHR and went to the L2.
        pub issued: u64,
        /// Prefetched sectors later used by a demand load (hit, or merge with a late prefetch).
        pub used: u64,
        /// Prefetched sectors evicted from the L1 before any demand use.
        pub evicted_unused: u64,
    }
}

vtq_hdl::counters! {
    /// DRAM counters (all classes).
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
    pub struct DramStats {
        /// Sector reads.
        pub reads: u64,
        /// Sector writes (L2 write-backs and stores that could not allocate in the L2).
        pub writes: u64,
        /// Bytes read.
        pub read_bytes: u64,
        /// Bytes written.
        pub write_bytes: u64,
        /// Sum over transfers of the cycles spent waiting for the channel.
        pub queue_cycles: u64,
        /// ... over writes only (the reads' are in each class's `dram_queue_cycles`).
        pub write_queue_cycles: u64,
    }
}

vtq_hdl::counters! {
    /// Every counter of a [`MemorySystem`](super::MemorySystem).
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
    pub struct MemStats {
        /// BVH node traffic.
        pub bvh: ClassStats,
        /// Ray-record traffic.
        pub ray_record: ClassStats,
        /// CTA save/restore traffic.
        pub cta_state: ClassStats,
        /// Hit-record traffic.
        pub hit_record: ClassStats,
        /// Traversal-stack spill and fill traffic.
        pub stack: ClassStats,
        /// Traffic of the stacks of rays waiting in treelet queues (`rt.queued_stack_traffic`).
        pub ray_stack: ClassStats,
        /// L1 prefetches.
        pub prefetch: PrefetchStats,
        /// DRAM traffic.
        pub dram: DramStats,
        /// Accesses refused because every MSHR of the SM was busy (each retry counts).
        pub mshr_stalls: u64,
        /// Accesses refused because every replaceable L1 line was being filled.
        pub set_stalls: u64,
        /// L2 misses that could not allocate because every replaceable L2 line was being filled
        /// (served without caching in the L2).
        pub l2_no_allocate: u64,
    }
}

impl MemStats {
    /// Counters of one class.
    pub fn class(&self, class: AccessClass) -> &ClassStats {
        match class {
            AccessClass::Bvh => &self.bvh,
            AccessClass::RayRecord => &self.ray_record,
            AccessClass::CtaState => &self.cta_state,
            AccessClass::HitRecord => &self.hit_record,
            AccessClass::Stack => &self.stack,
            AccessClass::RayStack => &self.ray_stack,
        }
    }

    /// Mutable counters of one class.
    pub(crate) fn class_mut(&mut self, class: AccessClass) -> &mut ClassStats {
        match class {
            AccessClass::Bvh => &mut self.bvh,
            AccessClass::RayRecord => &mut self.ray_record,
            AccessClass::CtaState => &mut self.cta_state,
            AccessClass::HitRecord => &mut self.hit_record,
            AccessClass::Stack => &mut self.stack,
            AccessClass::RayStack => &mut self.ray_stack,
        }
    }
}
