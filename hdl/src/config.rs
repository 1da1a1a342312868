//! The hardware configuration: sizes and thresholds of the treelet-queue RT unit, and every bit
//! width derived from them. Defaults are the paper's (Table 1 and section 6.5).

use crate::bits::clog2;
use serde::{Deserialize, Serialize};

/// A configuration value is out of range or inconsistent with another.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid hardware configuration: {key} = {value}: {reason}")]
pub struct ConfigError {
    /// The offending key.
    pub key: &'static str,
    /// Its value.
    pub value: u64,
    /// Why it is rejected.
    pub reason: String,
}

/// Sizes and thresholds of the treelet-queue hardware (one RT unit).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HwConfig {
    /// Maximum rays in flight per SM (ray virtualization); sets ray-id and count widths.
    pub max_rays: u32,
    /// Threads per warp; also rays per treelet-queue entry.
    pub warp_size: u32,
    /// Width of a byte address into BVH memory.
    pub address_bits: u32,
    /// Maximum treelet size in bytes (a power of two; half the L1 in the paper).
    pub treelet_bytes: u32,
    /// Entries in the treelet count table.
    pub count_table_entries: u32,
    /// Entries in the treelet queue table.
    pub queue_table_entries: u32,
    /// A treelet queue with fewer rays than this is underpopulated.
    pub underpopulation_threshold: u32,
    /// A warp with fewer active rays than this is repacked (0 disables repacking).
    pub repack_threshold: u32,
    /// Treelets that may be resident (processed or preloaded) at once.
    pub max_resident_treelets: u32,
    /// In the initial phase a warp is sent to the treelet queues once its active rays need more
    /// than this many distinct treelets next.
    pub divergence_threshold: u32,
    /// Preload the next treelet when the current queue holds fewer than this many warps of rays.
    pub preload_threshold_warps: u32,
    /// Warps the RT unit's warp buffer holds.
    pub warp_buffer_size: u32,
    /// On-chip entries of each per-ray traversal stack (current-treelet and other-treelet
    /// stacks); older entries spill to memory in 32 B chunks and are filled back on demand, so
    /// a stack never overflows (see the RT unit's "Stack spilling").
    ///
    /// The default, 32, is the short stack of the GPGPU-Sim ray-tracing model that Vulkan-Sim's
    /// RT unit grew from (`MAX_TRAVERSAL_STACK_SIZE 32`, "short stack", in its
    /// `ray_trace_function.h`); AMD's RDNA 3 keeps its per-lane BVH stack in LDS with 8 to 64
    /// entries (`DS_BVH_STACK_RTN`), and Intel's Xe ray-tracing unit uses a short stack backed
    /// by memory. At least the BVH width (a node's children must fit).
    pub stack_depth: u32,
    /// On-chip entries per stack that a ray record carries into and out of the RT unit. A parked
    /// ray spills its other stack to memory down to this many entries before its warp
    /// completes (the current stack is empty at a boundary), and its spilled entries come back
    /// through the ordinary stack fills after it is issued again.
    ///
    /// The default, 4, is one 32 B spill chunk of 64-bit entries: the memory width a record
    /// moves at. 1 keeps only the next node; `stack_depth` is the record carrying the whole
    /// on-chip stacks to the queues and back for free (vtq before 2026-12-03, and what the
    /// paper's costs imply: its ray record is 32 B, section 6.5). 1..=stack_depth.
    pub record_stack_entries: u32,
    /// Bytes of ray records the fills take from memory per cycle: the wiring's record write
    /// ports, one per 32 B record (a record's stacks, when `rt.queued_stack_traffic` moves them
    /// through memory, arrive before it on requests of their own). The records of a cycle are
    /// one slot's: they are written into that slot's RT-unit lanes. Records that return
    /// faster, or for another slot, wait in the SM's response queue.
    ///
    /// The default, 32, is one 32 B record a cycle: GPGPU-Sim's interconnect moves one flit a
    /// cycle per port, 32 B by default (`-icnt_flit_size`, `gpu-sim.cc`; Accel-Sim's Volta and
    /// Turing configurations use 40 B, which still carries one record). A multiple of 32, at
    /// most a warp of records.
    pub record_bytes_per_cycle: u32,
}

impl Default for HwConfig {
    fn default() -> Self {
        HwConfig {
            max_rays: 4096,
            warp_size: 32,
            address_bits: 32,
            treelet_bytes: 8192,
            count_table_entries: 600,
            queue_table_entries: 128,
            underpopulation_threshold: 128,
            repack_threshold: 22,
            max_resident_treelets: 2,
            divergence_threshold: 4,
            preload_threshold_warps: 2,
            warp_buffer_size: 1,
            stack_depth: 32,
            record_stack_entries: 4,
            record_bytes_per_cycle: 32,
        }
    }
}

fn err(key: &'static str, value: u32, reason: impl Into<String>) -> ConfigError {
    ConfigError {
        key,
        value: value as u64,
        reason: reason.into(),
    }
}

impl HwConfig {
    /// Checks every value's range and the relations between them.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let pow2 = |key, v: u32| {
            if v.is_power_of_two() {
                Ok(())
            } else {
                Err(err(key, v, "must be a power of two"))
            }
        };
        pow2("max_rays", self.max_rays)?;
        pow2("warp_size", self.warp_size)?;
        pow2("treelet_bytes", self.treelet_bytes)?;
        if !(2..=1 << 20).contains(&self.max_rays) {
            return Err(err("max_rays", self.max_rays, "must be 2..=1048576"));
        }
        if !(2..=64).contains(&self.warp_size) {
            return Err(err("warp_size", self.warp_size, "must be 2..=64"));
        }
        if self.max_rays < self.warp_size {
            return Err(err("max_rays", self.max_rays, "must be at least warp_size"));
        }
        if !(16..=48).contains(&self.address_bits) {
            return Err(err("address_bits", self.address_bits, "must be 16..=48"));
        }
        if self.treelet_bytes < 64 || clog2(self.treelet_bytes as u64) >= self.address_bits {
            return Err(err(
                "treelet_bytes",
                self.treelet_bytes,
                "must be at least 64 and smaller than the address space",
            ));
        }
        if !(2..=65536).contains(&self.count_table_entries) {
            return Err(err(
                "count_table_entries",
                self.count_table_entries,
                "must be 2..=65536",
            ));
        }
        if !(2..=65536).contains(&self.queue_table_entries) {
            return Err(err(
                "queue_table_entries",
                self.queue_table_entries,
                "must be 2..=65536",
            ));
        }
        if self.underpopulation_threshold > self.max_rays {
            return Err(err(
                "underpopulation_threshold",
                self.underpopulation_threshold,
                "must not exceed max_rays",
            ));
        }
        if self.repack_threshold > self.warp_size {
            return Err(err(
                "repack_threshold",
                self.repack_threshold,
                format!("must not exceed warp_size ({})", self.warp_size),
            ));
        }
        if self.max_resident_treelets == 0 || self.max_resident_treelets > 16 {
            return Err(err(
                "max_resident_treelets",
                self.max_resident_treelets,
                "must be 1..=16",
            ));
        }
        if self.divergence_threshold == 0 || self.divergence_threshold > self.warp_size {
            return Err(err(
                "divergence_threshold",
                self.divergence_threshold,
                "must be 1..=warp_size",
            ));
        }
        if self.warp_buffer_size == 0 || self.warp_buffer_size > 64 {
            return Err(err(
                "warp_buffer_size",
                self.warp_buffer_size,
                "must be 1..=64",
            ));
        }
        if !(2..=1024).contains(&self.stack_depth) {
            return Err(err(
                "stack_depth",
                self.stack_depth,
                "must be 2..=1024 (and at least the BVH width)",
            ));
        }
        if self.record_stack_entries == 0 || self.record_stack_entries > self.stack_depth {
            return Err(err(
                "record_stack_entries",
                self.record_stack_entries,
                format!("must be 1..={} (stack_depth)", self.stack_depth),
            ));
        }
        let most = 32 * self.warp_size;
        if self.record_bytes_per_cycle == 0
            || !self.record_bytes_per_cycle.is_multiple_of(32)
            || self.record_bytes_per_cycle > most
        {
            return Err(err(
                "record_bytes_per_cycle",
                self.record_bytes_per_cycle,
                format!("must be a multiple of 32 (bytes of a ray record), 32..={most} (a warp of records)"),
            ));
        }
        Ok(())
    }

    /// Ray records the fills take from memory per cycle (`record_bytes_per_cycle / 32`): the
    /// wiring's record write ports.
    pub fn record_ports(&self) -> u32 {
        self.record_bytes_per_cycle / 32
    }

    /// Bits of a ray id: log2(max rays in flight) (12 for 4096).
    pub fn ray_id_bits(&self) -> u32 {
        clog2(self.max_rays as u64)
    }

    /// Bits of a treelet address: the address bits above the treelet offset (19 for 32-bit
    /// addresses and 8 KB treelets). Treelets sit in treelet-sized slots, so the low bits are 0.
    pub fn treelet_addr_bits(&self) -> u32 {
        self.address_bits - clog2(self.treelet_bytes as u64)
    }

    /// Bits of a per-treelet ray count (12 for 4096 rays). A valid count is 1..=max_rays and is
    /// stored as count - 1, so log2(max_rays) bits suffice, as in the paper.
    pub fn count_bits(&self) -> u32 {
        clog2(self.max_rays as u64)
    }

    /// Bits of a treelet-queue-entry fill count (rays held 1..=warp_size, stored as count - 1).
    pub fn entry_count_bits(&self) -> u32 {
        clog2(self.warp_size as u64)
    }

    /// Bits of a treelet-queue-table index / chain link.
    pub fn queue_index_bits(&self) -> u32 {
        clog2(self.queue_table_entries as u64)
    }

    /// Bits of a treelet-count-table index.
    pub fn count_index_bits(&self) -> u32 {
        clog2(self.count_table_entries as u64)
    }

    /// Bits of a lane index within a warp (5 for 32).
    pub fn lane_bits(&self) -> u32 {
        clog2(self.warp_size as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_widths() {
        let c = HwConfig::default();
        c.validate().unwrap();
        assert_eq!(c.treelet_addr_bits(), 19);
        assert_eq!(c.ray_id_bits(), 12);
        assert_eq!(c.count_bits(), 12);
        assert_eq!(c.queue_index_bits(), 7);
        assert_eq!(c.count_index_bits(), 10);
    }

    #[test]
    fn widths_follow_config() {
        let c = HwConfig {
            max_rays: 8192,
            treelet_bytes: 32768,
            queue_table_entries: 256,
            ..HwConfig::default()
        };
        assert_eq!(c.ray_id_bits(), 13);
        assert_eq!(c.count_bits(), 13);
        assert_eq!(c.treelet_addr_bits(), 17);
        assert_eq!(c.queue_index_bits(), 8);
    }

    #[test]
    fn rejects_out_of_range() {
        let bad = HwConfig {
            repack_threshold: 33,
            ..HwConfig::default()
        };
        let e = bad.validate().unwrap_err();
        assert_eq!(e.key, "repack_threshold");
        let bad = HwConfig {
            max_rays: 3000,
            ..HwConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().key, "max_rays");
    }
}
