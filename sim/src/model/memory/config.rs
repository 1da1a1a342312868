//! [`MemConfig`]: sizes, latencies and bandwidth of the memory hierarchy, and its validation.

use serde::{Deserialize, Serialize};

/// Largest cache accepted by [`MemConfig::validate`] (128 MiB), so a typo cannot allocate
/// gigabytes of tag state.
pub const MAX_CACHE_BYTES: u32 = 128 << 20;
/// Largest latency (cycles) accepted by [`MemConfig::validate`]; keeps cycle sums far from
/// overflow.
pub const MAX_LATENCY: u32 = 1 << 20;
/// Largest number of sectors per line (valid, dirty and prefetch bits are kept in a `u64`).
pub const MAX_SECTORS_PER_LINE: u32 = 64;
/// Largest number of L1 MSHRs accepted by [`MemConfig::validate`].
pub const MAX_MSHRS: u32 = 1 << 16;

/// Largest `l2_private_mirrors`.
pub const MAX_MIRRORS: u32 = 1024;
/// Largest DRAM bandwidth (bytes per core cycle) accepted by [`MemConfig::validate`].
pub const MAX_DRAM_BYTES_PER_CYCLE: u32 = 1 << 20;
/// Largest number of DRAM channels accepted by [`MemConfig::validate`].
pub const MAX_DRAM_CHANNELS: u32 = 1024;
/// Largest DRAM interleaving granularity (bytes) accepted by [`MemConfig::validate`].
pub const MAX_DRAM_INTERLEAVE: u32 = 1 << 30;

/// The memory hierarchy of the simulated GPU: one L1 per SM, a unified L2 (in memory partitions),
/// `dram_channels` DRAM channels.
///
/// Defaults are the paper's Table 1 (Vulkan-Sim / Accel-Sim RTX 3070-like configuration); the
/// fields the table does not give are documented where they are chosen. All latencies are in
/// core cycles (1365 MHz). Unknown keys are rejected when deserializing; missing keys take
/// their default.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MemConfig {
    /// L1 data cache bytes per SM (Table 1: 16 KB).
    pub l1_bytes: u32,
    /// L1 associativity in lines per set; 0 = fully associative (Table 1).
    pub l1_ways: u32,
    /// L1 hit latency in cycles (Table 1: 39). Every request, including L1 bypasses and stores,
    /// pays it once for the trip through the SM's load/store pipeline.
    pub l1_latency: u32,
    /// Outstanding L1 sector misses per SM (MSHR entries). Not in Table 1; the default 64 is
    /// Vulkan-Sim's limit on the RT unit's outstanding memory requests (`-gpgpu_rt_max_mshr 64`
    /// in its public RTX 2060 configuration), the main client of this L1. Merges into an
    /// outstanding miss take no entry and are not limited (GPGPU-Sim limits them to 8 per
    /// entry; the RT unit already merges identical requests within a warp).
    pub l1_mshrs: u32,
    /// Unified L2 bytes shared by all SMs (Table 1: 128 KB).
    pub l2_bytes: u32,
    /// L2 associativity in lines per set; 0 = fully associative (Table 1: 16).
    pub l2_ways: u32,
    /// L2 latency in cycles, added to `l1_latency` for an L2 hit (Table 1: 187).
    pub l2_latency: u32,
    /// Ways of every L2 set reserved for [`RayRecord`](super::AccessClass::RayRecord) data
    /// (paper 4.2 and 5: "ray data ... resides in a reserved portion of the L2"). Ray records
    /// allocate only into ways `0..l2_ray_ways`, everything else only into the remaining ways;
    /// lookups search the whole set. The paper does not give the size; the default 0 disables
    /// the partition (all classes share the L2), which is the Table 1 baseline.
    pub l2_ray_ways: u32,
    /// Copies of every per-SM (private) L2 access — ray records, CTA state, stack spills, hit
    /// records; not BVH nodes, which all SMs share — that the L2 also takes in, at mirrored
    /// addresses that no real access uses, each copy in another set (as different SMs' private
    /// data lies), without DRAM traffic or statistics (default 1: the access alone). The
    /// sampled tier's scale models of `k` of `sms` SMs set it to `sms / k`, so the private data
    /// of the SMs not simulated takes its room in the L2 as the simulated SMs' does
    /// (docs/accuracy.md).
    pub l2_private_mirrors: u32,
    /// DRAM access latency in cycles after the request leaves the L2 (254 in the public
    /// RTX 3070 configuration that supplied the 39/187 figures).
    pub dram_latency: u32,
    /// DRAM bandwidth in bytes per core cycle. Default 328: the RTX 3070's GDDR6 (256-bit,
    /// 3500 MHz memory clock as in Table 1, 14 Gb/s per pin = 448 GB/s) divided by the
    /// 1365 MHz core clock: 448e9 / 1.365e9 = 328.2, rounded down.
    pub dram_bytes_per_cycle: u32,
    /// The share of that bandwidth this GPU gets, `[numerator, denominator]` (default
    /// `[1, 1]`: all of it). The sampled tier's scale models, which simulate `k` of the GPU's
    /// SMs, give them `[k, sms]` of the channel (docs/accuracy.md); bandwidth is then exactly
    /// `dram_bytes_per_cycle * numerator / denominator` bytes per cycle.
    pub dram_share: [u32; 2],
    /// DRAM channels sharing `dram_bytes_per_cycle` equally, each first come first served, and
    /// with them the memory partitions the L2 is sliced into ([`super::l2::PartitionMap`]).
    /// Default 16: Vulkan-Sim's RTX 3070 configuration, which supplied the paper's latencies
    /// (`-gpgpu_n_mem 16`; each channel's FR-FCFS scheduling over 16 banks is not modelled).
    /// 1 is the single first-come-first-served channel of vtq before memory partitions.
    pub dram_channels: u32,
    /// Bytes of consecutive addresses in one channel before the next channel's (a power of two,
    /// at least `line_bytes`, so a line lives in one channel); used when `dram_channels > 1`.
    /// Default 256: Vulkan-Sim's RTX 3070 address mapping (`dramid@8`); consecutive chunks go
    /// to consecutive channels (its IPOLY index hashing is not modelled).
    pub dram_interleave_bytes: u32,
    /// Sector size in bytes: the unit of valid bits, fills and DRAM transfers (32).
    pub sector_bytes: u32,
    /// Line size in bytes: the unit of tags and replacement (128), as in GPGPU-Sim/Accel-Sim.
    pub line_bytes: u32,
}

impl Default for MemConfig {
    fn default() -> Self {
        MemConfig {
            l1_bytes: 16 * 1024,
            l1_ways: 0,
            l1_latency: 39,
            l1_mshrs: 64,
            l2_bytes: 128 * 1024,
            l2_ways: 16,
            l2_latency: 187,
            l2_ray_ways: 0,
            l2_private_mirrors: 1,
            dram_latency: 254,
            dram_bytes_per_cycle: 328,
            dram_share: [1, 1],
            dram_channels: 16,
            dram_interleave_bytes: 256,
            sector_bytes: 32,
            line_bytes: 128,
        }
    }
}

/// Why a [`MemConfig`] (or the SM count given with it) was rejected; each names the key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MemConfigError {
    /// A key that must be positive is 0.
    #[error("memory config `{key}` must be greater than 0")]
    Zero {
        /// The offending key.
        key: &'static str,
    },
    /// A size that must be a power of two is not.
    #[error("memory config `{key}` = {value} must be a power of two")]
    NotPowerOfTwo {
        /// The offending key.
        key: &'static str,
        /// Its value.
        value: u32,
    },
    /// A value is above the supported maximum.
    #[error("memory config `{key}` = {value} is above the supported maximum {max}")]
    TooLarge {
        /// The offending key.
        key: &'static str,
        /// Its value.
        value: u32,
        /// The largest accepted value.
        max: u32,
    },
    /// `sector_bytes` is larger than `line_bytes`, or a line has too many sectors.
    #[error(
        "memory config `sector_bytes` = {sector} must be at most `line_bytes` = {line} and a line \
         may hold at most {max_sectors} sectors"
    )]
    SectorVsLine {
        /// `sector_bytes`.
        sector: u32,
        /// `line_bytes`.
        line: u32,
        /// [`MAX_SECTORS_PER_LINE`].
        max_sectors: u32,
    },
    /// A cache is smaller than one line.
    #[error("memory config `{key}` = {bytes} is smaller than one line (`line_bytes` = {line})")]
    SmallerThanLine {
        /// The offending key.
        key: &'static str,
        /// Its value.
        bytes: u32,
        /// `line_bytes`.
        line: u32,
    },
    /// The associativity does not divide the cache's line count.
    #[error("memory config `{key}` = {ways} must divide the cache's {lines} lines (0 = fully associative)")]
    WaysDoNotDivide {
        /// The offending key.
        key: &'static str,
        /// Its value.
        ways: u32,
        /// Lines in that cache.
        lines: u32,
    },
    /// The ray-record partition leaves no L2 way for other data.
    #[error(
        "memory config `l2_ray_ways` = {ray_ways} must be less than the {ways} lines of an L2 set"
    )]
    RayWays {
        /// `l2_ray_ways`.
        ray_ways: u32,
        /// Lines per L2 set.
        ways: u32,
    },
    /// `dram_share` is not a fraction in (0, 1].
    #[error(
        "memory config `dram_share` = [{num}, {den}] must be [numerator, denominator] with \
         0 < numerator <= denominator"
    )]
    DramShare {
        /// Numerator.
        num: u32,
        /// Denominator.
        den: u32,
    },
    /// A memory system needs at least one SM.
    #[error("a memory system needs at least one SM (got 0)")]
    NoSms,
}

impl MemConfig {
    /// Checks every key; the first problem found is returned, naming its key.
    pub fn validate(&self) -> Result<(), MemConfigError> {
        for (key, value) in [
            ("l1_bytes", self.l1_bytes),
            ("l2_bytes", self.l2_bytes),
            ("l2_private_mirrors", self.l2_private_mirrors),
            ("l1_latency", self.l1_latency),
            ("l2_latency", self.l2_latency),
            ("dram_latency", self.dram_latency),
            ("l1_mshrs", self.l1_mshrs),
            ("dram_bytes_per_cycle", self.dram_bytes_per_cycle),
            ("dram_channels", self.dram_channels),
            ("dram_interleave_bytes", self.dram_interleave_bytes),
            ("sector_bytes", self.sector_bytes),
            ("line_bytes", self.line_bytes),
        ] {
            if value == 0 {
                return Err(MemConfigError::Zero { key });
            }
        }
        for (key, value, max) in [
            ("l1_bytes", self.l1_bytes, MAX_CACHE_BYTES),
            ("l2_bytes", self.l2_bytes, MAX_CACHE_BYTES),
            ("l1_latency", self.l1_latency, MAX_LATENCY),
            ("l2_latency", self.l2_latency, MAX_LATENCY),
            ("dram_latency", self.dram_latency, MAX_LATENCY),
            ("l1_mshrs", self.l1_mshrs, MAX_MSHRS),
            ("l2_private_mirrors", self.l2_private_mirrors, MAX_MIRRORS),
            (
                "dram_bytes_per_cycle",
                self.dram_bytes_per_cycle,
                MAX_DRAM_BYTES_PER_CYCLE,
            ),
            ("dram_channels", self.dram_channels, MAX_DRAM_CHANNELS),
            (
                "dram_interleave_bytes",
                self.dram_interleave_bytes,
                MAX_DRAM_INTERLEAVE,
            ),
        ] {
            if value > max {
                return Err(MemConfigError::TooLarge { key, value, max });
            }
        }
        for (key, value) in [
            ("l1_bytes", self.l1_bytes),
            ("l2_bytes", self.l2_bytes),
            ("sector_bytes", self.sector_bytes),
            ("line_bytes", self.line_bytes),
            ("dram_interleave_bytes", self.dram_interleave_bytes),
        ] {
            if !value.is_power_of_two() {
                return Err(MemConfigError::NotPowerOfTwo { key, value });
            }
        }
        if self.sector_bytes > self.line_bytes
            || self.line_bytes / self.sector_bytes > MAX_SECTORS_PER_LINE
        {
            return Err(MemConfigError::SectorVsLine {
                sector: self.sector_bytes,
                line: self.line_bytes,
                max_sectors: MAX_SECTORS_PER_LINE,
            });
        }
        for (bytes_key, bytes, ways_key, ways) in [
            ("l1_bytes", self.l1_bytes, "l1_ways", self.l1_ways),
            ("l2_bytes", self.l2_bytes, "l2_ways", self.l2_ways),
        ] {
            if bytes < self.line_bytes {
                return Err(MemConfigError::SmallerThanLine {
                    key: bytes_key,
                    bytes,
                    line: self.line_bytes,
                });
            }
            let lines = bytes / self.line_bytes;
            if ways > lines || (ways != 0 && !lines.is_multiple_of(ways)) {
                return Err(MemConfigError::WaysDoNotDivide {
                    key: ways_key,
                    ways,
                    lines,
                });
            }
        }
        let [num, den] = self.dram_share;
        if num == 0 || num > den {
            return Err(MemConfigError::DramShare { num, den });
        }
        if self.dram_interleave_bytes < self.line_bytes {
            return Err(MemConfigError::SmallerThanLine {
                key: "dram_interleave_bytes",
                bytes: self.dram_interleave_bytes,
                line: self.line_bytes,
            });
        }
        let l2_set_ways = self.l2_geometry().ways;
        if self.l2_ray_ways >= l2_set_ways {
            return Err(MemConfigError::RayWays {
                ray_ways: self.l2_ray_ways,
                ways: l2_set_ways,
            });
        }
        Ok(())
    }

    /// Shape of one L1 (call after [`validate`](Self::validate)).
    pub fn l1_geometry(&self) -> Geometry {
        Geometry::new(
            self.l1_bytes,
            self.l1_ways,
            self.line_bytes,
            self.sector_bytes,
        )
    }

    /// Shape of the L2 (call after [`validate`](Self::validate)).
    pub fn l2_geometry(&self) -> Geometry {
        Geometry::new(
            self.l2_bytes,
            self.l2_ways,
            self.line_bytes,
            self.sector_bytes,
        )
    }
}

/// Shape of one sectored cache: sets x ways lines of `line_bytes`, each split in sectors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Geometry {
    /// Number of sets (1 when fully associative).
    pub sets: u32,
    /// Lines per set.
    pub ways: u32,
    /// Bytes per line (tag granularity).
    pub line_bytes: u32,
    /// Bytes per sector (valid-bit and fill granularity).
    pub sector_bytes: u32,
}

impl Geometry {
    /// Shape of a cache of `bytes` with `ways` lines per set (0 = fully associative). The
    /// arguments must have passed [`MemConfig::validate`].
    pub fn new(bytes: u32, ways: u32, line_bytes: u32, sector_bytes: u32) -> Self {
        let lines = bytes / line_bytes;
        let ways = if ways == 0 { lines } else { ways };
        Geometry {
            sets: lines / ways,
            ways,
            line_bytes,
            sector_bytes,
        }
    }

    /// Total lines.
    pub fn lines(&self) -> u32 {
        self.sets * self.ways
    }

    /// Sectors per line.
    pub fn sectors_per_line(&self) -> u32 {
        self.line_bytes / self.sector_bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_table_1() {
        let c = MemConfig::default();
        c.validate().unwrap();
        assert_eq!((c.l1_bytes, c.l1_ways, c.l1_latency), (16384, 0, 39));
        assert_eq!((c.l2_bytes, c.l2_ways, c.l2_latency), (131072, 16, 187));
        assert_eq!(c.dram_latency, 254);
        // 448 GB/s at 1365 MHz, rounded down.
        assert_eq!(
            c.dram_bytes_per_cycle as u64,
            448_000_000_000u64 / 1_365_000_000
        );
        let l1 = c.l1_geometry();
        assert_eq!((l1.sets, l1.ways, l1.sectors_per_line()), (1, 128, 4));
        let l2 = c.l2_geometry();
        assert_eq!((l2.sets, l2.ways), (64, 16));
    }

    fn err(f: impl FnOnce(&mut MemConfig)) -> MemConfigError {
        let mut c = MemConfig::default();
        f(&mut c);
        c.validate().unwrap_err()
    }

    #[test]
    fn every_bad_key_is_named() {
        let cases: Vec<(MemConfigError, &str)> = vec![
            (err(|c| c.l1_bytes = 0), "`l1_bytes`"),
            (err(|c| c.l2_latency = 0), "`l2_latency`"),
            (err(|c| c.l1_mshrs = 0), "`l1_mshrs`"),
            (
                err(|c| c.dram_bytes_per_cycle = 0),
                "`dram_bytes_per_cycle`",
            ),
            (err(|c| c.l2_bytes = 100_000), "`l2_bytes`"),
            (err(|c| c.line_bytes = 96), "`line_bytes`"),
            (err(|c| c.sector_bytes = 256), "`sector_bytes`"),
            (err(|c| c.sector_bytes = 1), "`sector_bytes`"),
            (err(|c| c.l1_bytes = 64), "`l1_bytes`"),
            (err(|c| c.l1_ways = 3), "`l1_ways`"),
            (err(|c| c.l2_ways = 2048), "`l2_ways`"),
            (err(|c| c.l2_ray_ways = 16), "`l2_ray_ways`"),
            (err(|c| c.dram_latency = MAX_LATENCY + 1), "`dram_latency`"),
            (err(|c| c.l2_bytes = 1 << 30), "`l2_bytes`"),
            (err(|c| c.dram_channels = 0), "`dram_channels`"),
            (err(|c| c.dram_channels = 2000), "`dram_channels`"),
            (
                err(|c| c.dram_interleave_bytes = 300),
                "`dram_interleave_bytes`",
            ),
            (
                err(|c| c.dram_interleave_bytes = 64),
                "`dram_interleave_bytes`",
            ),
        ];
        for (e, key) in cases {
            assert!(e.to_string().contains(key), "{e} should name {key}");
        }
        assert_eq!(
            err(|c| c.l1_ways = 3),
            MemConfigError::WaysDoNotDivide {
                key: "l1_ways",
                ways: 3,
                lines: 128
            }
        );
    }

    #[test]
    fn toml_rejects_unknown_keys_and_fills_defaults() {
        let c: MemConfig = toml::from_str("l2_ways = 8\nl1_mshrs = 8").unwrap();
        assert_eq!(c.l2_ways, 8);
        assert_eq!(c.l1_mshrs, 8);
        assert_eq!(c.l1_bytes, MemConfig::default().l1_bytes);
        let e = toml::from_str::<MemConfig>("l3_bytes = 4").unwrap_err();
        assert!(e.to_string().contains("l3_bytes"), "{e}");
        let round: MemConfig =
            toml::from_str(&toml::to_string(&MemConfig::default()).unwrap()).unwrap();
        assert_eq!(round, MemConfig::default());
    }
}
