//! Queues mode with `rt.queued_stack_traffic`: the traffic of the traversal stacks of rays
//! waiting in treelet queues ([`QueuedStacks`]).
//!
//! The paper costs a queued ray as its 32 B ray record (origin, direction, tmin, tmax: section
//! 6.5); the stack that says where its traversal resumes is not mentioned. By default it travels
//! with the record for free. With the switch, the stack lives in memory while the ray waits:
//! parking a ray stores the 32 B chunks holding its on-chip stack entries (four entries per
//! chunk, the current-treelet and other-treelet stacks each rounded up to whole chunks; entries
//! already spilled are in memory and move nothing), and forming a warp loads them back beside
//! the ray record, the ray joining the warp only when its record and every chunk have returned.
//! The accesses are of class [`AccessClass::RayStack`] and bypass the L1, like ray records
//! (paper section 4.2: ray data must not evict treelet data). Each ray id has its own area of
//! `2 x ceil(hw.stack_depth / 4)` chunks.

use std::collections::BTreeMap;

use vtq_hdl::rt_unit::{RayRecord, CHUNK_BYTES, STACK_ENTRIES_PER_CHUNK};
use vtq_hdl::treelet_rt_unit::RayLoad;

use crate::model::memory::{AccessClass, MemRequest};

/// Tag bit of a queued-stack load; below it, the ray id.
const STACK_LOAD_TAG: u64 = 1 << 49;

/// One SM's queued-stack traffic: chunks per parked ray, loads outstanding, records held back.
#[derive(Debug, Clone)]
pub struct QueuedStacks {
    /// Address of ray id 0's area.
    base: u64,
    /// Chunks of one ray's area.
    area_chunks: u64,
    /// Chunks each ray stored when it was parked.
    parked: Vec<u32>,
    /// Chunk loads not yet returned, per ray.
    waiting: Vec<u32>,
    /// Ray records that returned before their stack chunks, by ray id.
    held: BTreeMap<u32, RayLoad>,
    /// Chunk stores queued.
    pub stores: u64,
    /// Chunk loads queued.
    pub loads: u64,
}

impl QueuedStacks {
    /// The area of `max_rays` ray ids at `base`, each for two stacks of `stack_depth` on-chip
    /// entries.
    pub fn new(base: u64, max_rays: u32, stack_depth: u32) -> Self {
        QueuedStacks {
            base,
            area_chunks: Self::chunks_per_ray(stack_depth),
            parked: vec![0; max_rays as usize],
            waiting: vec![0; max_rays as usize],
            held: BTreeMap::new(),
            stores: 0,
            loads: 0,
        }
    }

    /// Chunks of one ray's area: two stacks of `stack_depth` entries.
    pub fn chunks_per_ray(stack_depth: u32) -> u64 {
        2 * (stack_depth as u64).div_ceil(STACK_ENTRIES_PER_CHUNK as u64)
    }

    /// Bytes of the area of `max_rays` ray ids.
    pub fn area_bytes(max_rays: u32, stack_depth: u32) -> u64 {
        max_rays as u64 * Self::chunks_per_ray(stack_depth) * CHUNK_BYTES as u64
    }

    /// The address of chunk `k` of ray `ray`'s area.
    fn address(&self, ray: u32, k: u64) -> u64 {
        self.base + (ray as u64 * self.area_chunks + k) * CHUNK_BYTES as u64
    }

    /// Ray `record` was parked in a treelet queue: the stores of its on-chip stack entries.
    pub fn park(&mut self, record: &RayRecord) -> Vec<MemRequest> {
        let per = STACK_ENTRIES_PER_CHUNK;
        let chunks =
            record.current_stack.len().div_ceil(per) + record.other_stack.len().div_ceil(per);
        if let Some(p) = self.parked.get_mut(record.ray_id as usize) {
            *p = chunks as u32;
        }
        self.stores += chunks as u64;
        (0..chunks as u64)
            .map(|k| {
                MemRequest::store(
                    self.address(record.ray_id, k),
                    CHUNK_BYTES,
                    AccessClass::RayStack,
                    0,
                )
                .bypassing_l1()
            })
            .collect()
    }

    /// Ray `ray`'s record is being loaded for a warp: the loads of its parked stack chunks.
    pub fn load(&mut self, ray: u32) -> Vec<MemRequest> {
        let chunks = self.parked.get(ray as usize).copied().unwrap_or(0);
        if let Some(w) = self.waiting.get_mut(ray as usize) {
            *w += chunks;
        }
        self.loads += chunks as u64;
        (0..chunks as u64)
            .map(|k| {
                MemRequest::load(
                    self.address(ray, k),
                    CHUNK_BYTES,
                    AccessClass::RayStack,
                    STACK_LOAD_TAG | ray as u64,
                )
                .bypassing_l1()
            })
            .collect()
    }

    /// A ray record returned: the ray may join its warp (`Some`) unless stack chunks are still
    /// on their way, in which case it is held until they are.
    pub fn record_arrived(&mut self, load: RayLoad) -> Option<RayLoad> {
        if self.waiting.get(load.ray as usize).copied().unwrap_or(0) > 0 {
            self.held.insert(load.ray, load);
            None
        } else {
            Some(load)
        }
    }

    /// A stack chunk load with tag `tag` returned: the ray whose record was held for it, if this
    /// was its last chunk.
    pub fn chunk_arrived(&mut self, tag: u64) -> Option<RayLoad> {
        let ray = (tag & !STACK_LOAD_TAG) as u32;
        let w = self.waiting.get_mut(ray as usize)?;
        *w = w.saturating_sub(1);
        if *w == 0 {
            self.held.remove(&ray)
        } else {
            None
        }
    }

    /// Ray records held for their stack chunks.
    pub fn held(&self) -> usize {
        self.held.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vtq_hdl::bounded::BoundedVec;
    use vtq_hdl::rt_unit::NodeEntry;

    fn record(ray: u32, current: usize, other: usize) -> RayRecord {
        RayRecord {
            ray_id: ray,
            current_stack: BoundedVec::with(32, vec![NodeEntry::default(); current]).unwrap(),
            other_stack: BoundedVec::with(32, vec![NodeEntry::default(); other]).unwrap(),
            ..RayRecord::default()
        }
    }

    #[test]
    fn parking_stores_each_stack_in_whole_chunks_and_loading_brings_them_back() {
        let mut q = QueuedStacks::new(1 << 20, 8, 32);
        assert_eq!(QueuedStacks::chunks_per_ray(32), 16);
        // 0 current entries, 5 other entries: 2 chunks.
        let stores = q.park(&record(3, 0, 5));
        assert_eq!(stores.len(), 2);
        assert!(stores
            .iter()
            .all(|r| r.store && r.bypass_l1 && r.class == AccessClass::RayStack));
        assert_eq!(stores[0].addr, (1 << 20) + 3 * 16 * 32);
        assert_eq!(stores[1].addr, stores[0].addr + 32);
        // 1 + 4 entries: 2 chunks.
        assert_eq!(q.park(&record(4, 1, 4)).len(), 2);
        // No entries: nothing.
        assert!(q.park(&record(5, 0, 0)).is_empty());
        let loads = q.load(3);
        assert_eq!(loads.len(), 2);
        assert!(loads.iter().all(|r| !r.store && r.bypass_l1));
        let ray = RayLoad {
            slot: 0,
            ray: 3,
            record: record(3, 0, 5),
        };
        // The record first: held until both chunks are back.
        assert!(q.record_arrived(ray.clone()).is_none());
        assert_eq!(q.held(), 1);
        assert!(q.chunk_arrived(loads[0].tag).is_none());
        assert_eq!(q.chunk_arrived(loads[1].tag), Some(ray.clone()));
        assert_eq!(q.held(), 0);
        // Chunks first: the record passes at once.
        let loads = q.load(3);
        for l in &loads {
            assert!(q.chunk_arrived(l.tag).is_none());
        }
        assert_eq!(q.record_arrived(ray.clone()), Some(ray));
        // A ray without parked chunks passes at once.
        assert!(q.load(5).is_empty());
    }
}
