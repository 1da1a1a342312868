//! The BVH reads of the SMs a scale model leaves out (the sampled tier's ghost reads,
//! `sample.ghost_l2_footprint`, docs/accuracy.md): the recorded streams split by memory
//! partition into runs of reads of one line, built once and shared by every replicate that
//! leaves out the same SMs; each partition of the model's L2 replays its share as it runs
//! ([`super::L2Side::ghosts`]).

use super::config::MemConfig;
use super::partitions::PartitionMap;

/// Bytes of a sector address in a ghost stream (stream entries are byte address / 32, the
/// functional profile's BVH sectors).
pub const GHOST_SECTOR_BYTES: u64 = 32;

/// Reads of one line in a row of a ghost stream, applied together.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct GhostRun {
    /// Its sectors of the L2's size, one bit each.
    pub sectors: u64,
    /// The line (byte address / line bytes).
    pub line: u32,
    /// Reads it stands for.
    pub reads: u32,
}

/// The left-out SMs' BVH reads for one L2 and how many follow each BVH read of the simulated
/// SMs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GhostReads {
    /// The partitions the reads are split by.
    map: PartitionMap,
    /// Per partition, per stream with reads there, its runs in order.
    parts: Vec<Vec<Vec<GhostRun>>>,
    /// Ghost reads after each demand BVH read of a simulated SM.
    per_read: u32,
}

impl GhostReads {
    /// The streams `streams` (`streams[g]`: left-out SM `g`'s sector reads at the L2, byte
    /// address / 32, in order) split for the L2 of `cfg` (validated), `per_read` of them to
    /// follow each demand BVH read of a simulated SM.
    pub fn new(cfg: &MemConfig, streams: &[Vec<u32>], per_read: u32) -> Self {
        let map = PartitionMap::new(cfg);
        let line_bytes = u64::from(cfg.line_bytes);
        let sector_bytes = u64::from(cfg.sector_bytes);
        let mut parts: Vec<Vec<Vec<GhostRun>>> =
            vec![vec![Vec::new(); streams.len()]; map.partitions()];
        for (g, stream) in streams.iter().enumerate() {
            for &s in stream {
                let addr = u64::from(s) * GHOST_SECTOR_BYTES;
                let line = addr / line_bytes;
                let sector = 1u64 << ((addr % line_bytes) / sector_bytes);
                let runs = &mut parts[map.partition(line)][g];
                match runs.last_mut() {
                    Some(run) if u64::from(run.line) == line => {
                        run.sectors |= sector;
                        run.reads += 1;
                    }
                    // Stream entries are 32-bit sector addresses, so their lines fit 32 bits.
                    _ => runs.push(GhostRun {
                        sectors: sector,
                        line: line as u32,
                        reads: 1,
                    }),
                }
            }
        }
        for part in &mut parts {
            part.retain(|runs| !runs.is_empty());
        }
        GhostReads {
            map,
            parts,
            per_read,
        }
    }

    /// The partitions the reads are split by.
    pub(super) fn map(&self) -> PartitionMap {
        self.map
    }

    /// Partition `p`'s streams (empty: none reads there).
    pub(super) fn part(&self, p: usize) -> &[Vec<GhostRun>] {
        self.parts.get(p).map_or(&[], Vec::as_slice)
    }

    /// Ghost reads after each demand BVH read of a simulated SM.
    pub(super) fn per_read(&self) -> u32 {
        self.per_read
    }
}
