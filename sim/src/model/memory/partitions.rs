//! How line addresses map to the memory partitions (one per DRAM channel where every L2 set
//! lies in one channel; see [`super::l2`]) and to line numbers inside a partition's cache.

use super::config::MemConfig;

/// How line addresses map to memory partitions and to line numbers inside their partition's
/// cache (a partition's cache has `1 / partitions` of the sets).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PartitionMap {
    /// log2 of the partitions (a power of two).
    bits: u32,
    /// log2 of the lines of one interleaving chunk.
    chunk_bits: u32,
}

impl PartitionMap {
    /// The map of `cfg` (validated): one partition per DRAM channel where each L2 set lies in
    /// one channel, else one partition.
    pub fn new(cfg: &MemConfig) -> Self {
        let channels = cfg.dram_channels.max(1);
        let chunk_lines = (cfg.dram_interleave_bytes / cfg.line_bytes).max(1);
        let sets = cfg.l2_geometry().sets;
        let fits = channels > 1
            && channels.is_power_of_two()
            && chunk_lines.is_power_of_two()
            && sets.is_power_of_two()
            && u64::from(sets) % (u64::from(channels) * u64::from(chunk_lines)) == 0;
        if fits {
            PartitionMap {
                bits: channels.trailing_zeros(),
                chunk_bits: chunk_lines.trailing_zeros(),
            }
        } else {
            PartitionMap::unified()
        }
    }

    /// One partition holding everything.
    pub fn unified() -> Self {
        PartitionMap {
            bits: 0,
            chunk_bits: 0,
        }
    }

    /// Number of partitions.
    pub fn partitions(&self) -> usize {
        1 << self.bits
    }

    /// The partition of line `line` (its DRAM channel).
    pub fn partition(&self, line: u64) -> usize {
        ((line >> self.chunk_bits) & ((1 << self.bits) - 1)) as usize
    }

    /// The line number of `line` inside its partition: the partition bits taken out, so the
    /// partition's cache of `1 / partitions` of the sets puts it in the set and order it has in
    /// the whole L2.
    pub(super) fn local(&self, line: u64) -> u64 {
        let low = line & ((1 << self.chunk_bits) - 1);
        ((line >> (self.chunk_bits + self.bits)) << self.chunk_bits) | low
    }
}
