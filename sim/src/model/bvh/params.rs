//! The hardware BVH's build parameters ([`BvhParams`]: width, treelet size, treelet formation),
//! part of the BVH cache's key, and their checks.

use super::treelet::TreeletFormation;
use super::BvhError;

/// Smallest and largest supported BVH width.
pub const WIDTH_RANGE: std::ops::RangeInclusive<u32> = 2..=8;

/// Build parameters of the hardware BVH (part of the cache key).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BvhParams {
    /// Children per internal node, 2..=8 (default 6). Widths up to 6 use 64 B internal nodes,
    /// 7 and 8 use 128 B internal nodes.
    pub width: u32,
    /// Maximum treelet size in bytes: a power of two, at least one full child group
    /// (`width` x internal node size) and at least 128 (default 8192, half the L1).
    pub treelet_bytes: u32,
    /// How the BVH is partitioned into treelets (default: the breadth-first treelets packed
    /// into shared slots, as the paper's section 6.5 packs them).
    pub formation: TreeletFormation,
}

impl Default for BvhParams {
    fn default() -> Self {
        BvhParams {
            width: 6,
            treelet_bytes: 8192,
            formation: TreeletFormation::Packed,
        }
    }
}

impl BvhParams {
    /// Largest accepted treelet size (1 GiB).
    pub const MAX_TREELET_BYTES: u32 = 1 << 30;

    /// Bytes of one internal node at this width (64 for widths up to 6, else 128).
    pub fn internal_node_bytes(&self) -> u32 {
        if self.width <= 6 {
            64
        } else {
            128
        }
    }

    /// Checks the parameters, naming the offending one.
    pub fn validate(&self) -> Result<(), BvhError> {
        if !WIDTH_RANGE.contains(&self.width) {
            return Err(BvhError::Params(format!(
                "BVH width {} is out of range (must be 2..=8)",
                self.width
            )));
        }
        let tb = self.treelet_bytes;
        if !tb.is_power_of_two() {
            return Err(BvhError::Params(format!(
                "treelet size {tb} bytes is not a power of two"
            )));
        }
        let min = (self.width * self.internal_node_bytes()).max(128);
        if tb < min {
            return Err(BvhError::Params(format!(
                "treelet size {tb} bytes is smaller than one child group of a {}-wide BVH \
                 ({min} bytes)",
                self.width
            )));
        }
        if tb > Self::MAX_TREELET_BYTES {
            return Err(BvhError::Params(format!(
                "treelet size {tb} bytes exceeds the maximum of {} bytes",
                Self::MAX_TREELET_BYTES
            )));
        }
        Ok(())
    }
}
