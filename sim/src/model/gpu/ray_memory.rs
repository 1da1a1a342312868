//! What the treelet hardware keeps in memory, as memory contents (the timing of every access is
//! the memory system's): the RT units' traversal-stack spill areas ([`SpillMemory`]), the ray-record
//! store of rays waiting in treelet queues ([`RayStore`]) and the queue table's spill FIFO
//! ([`SpillFifo`]).

use std::collections::{HashMap, VecDeque};

use vtq_hdl::rt_unit::{RayRecord, CHUNK_BYTES};

/// The contents of one SM's stack spill area: what the RT unit's spill stores wrote, by
/// address, read back by its fills (memory contents, not timing: timing is the memory
/// system's, through the `Stack` access class).
#[derive(Debug, Clone, Default)]
pub struct SpillMemory {
    chunks: HashMap<u64, [u8; CHUNK_BYTES as usize]>,
}

impl SpillMemory {
    /// Writes the 32 B chunk at `address`.
    pub fn store(&mut self, address: u64, data: [u8; CHUNK_BYTES as usize]) {
        self.chunks.insert(address, data);
    }

    /// The 32 B chunk at `address` (zeros where nothing was stored: the RT unit then reports
    /// an unmatched response).
    pub fn load(&self, address: u64) -> [u8; CHUNK_BYTES as usize] {
        self.chunks.get(&address).copied().unwrap_or_default()
    }
}

/// The ray records of one SM's rays stopped at a treelet boundary, by ray id, from the moment
/// the treelet RT unit parks them until a fill loads them back (their 32 B records are written
/// when the rays enter; the traversal stacks travel with them).
#[derive(Debug, Clone, Default)]
pub struct RayStore {
    records: Vec<Option<RayRecord>>,
}

impl RayStore {
    /// A store for `max_rays` ray ids.
    pub fn new(max_rays: u32) -> Self {
        RayStore {
            records: vec![None; max_rays as usize],
        }
    }

    /// Keeps `record` under its ray id.
    pub fn park(&mut self, record: RayRecord) {
        if let Some(slot) = self.records.get_mut(record.ray_id as usize) {
            *slot = Some(record);
        }
    }

    /// Takes ray `ray`'s record (`None` when none is kept).
    pub fn take(&mut self, ray: u32) -> Option<RayRecord> {
        self.records.get_mut(ray as usize)?.take()
    }
}

/// The queue table's spill FIFO in memory: `(treelet, ray)` of every spilled queue entry,
/// oldest first, until the table refills it (its traffic is not modelled).
#[derive(Debug, Clone, Default)]
pub struct SpillFifo {
    entries: VecDeque<(u64, u32)>,
}

impl SpillFifo {
    /// The oldest entry.
    pub fn head(&self) -> Option<(u64, u32)> {
        self.entries.front().copied()
    }

    /// Appends a spilled entry.
    pub fn push(&mut self, entry: (u64, u32)) {
        self.entries.push_back(entry);
    }

    /// Removes the oldest entry.
    pub fn pop(&mut self) {
        self.entries.pop_front();
    }

    /// Entries waiting.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether nothing waits.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}
