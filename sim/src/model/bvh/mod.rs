//! The hardware BVH: built with `obvhs`, collapsed to the configured width and laid out in a
//! byte-addressed memory image in the Intel/Vulkan-Sim style (see `layout`), partitioned into
//! treelets (see [`treelet`]) and cached on disk (see `cache`).

pub mod address_space;
pub mod build;
pub mod cache;
mod image;
pub mod layout;
pub mod params;
pub mod treelet;

/// Size of the BVH header.
pub const HEADER_BYTES: u32 = 64;
/// Size of a triangle or procedural leaf.
pub const LEAF_BYTES: u32 = 64;

pub use build::{sphere_bounds, sphere_is_usable, triangle_bounds, triangle_is_usable};
pub use cache::{build_cached, default_cache_dir, CacheOutcome};
pub use layout::{BvhStats, HwBvh, NodeInfo, NodeKind};
pub use params::{BvhParams, WIDTH_RANGE};
pub use treelet::TreeletFormation;

/// Why a BVH could not be built, loaded or cached.
#[derive(Debug, thiserror::Error)]
pub enum BvhError {
    /// Out-of-range build parameters.
    #[error("invalid BVH parameters: {0}")]
    Params(String),
    /// Scene geometry the hardware format cannot represent.
    #[error("unsupported scene geometry: {0}")]
    Geometry(String),
    /// The BVH does not fit the 32-bit address space.
    #[error("BVH too large: {0}")]
    TooLarge(String),
    /// A serialized BVH (cache file) is malformed.
    #[error("malformed serialized BVH: {0}")]
    Corrupt(String),
    /// A cache directory or file could not be read or written.
    #[error("BVH cache {path}: {reason}")]
    Io {
        /// The file or folder.
        path: String,
        /// What went wrong.
        reason: String,
    },
}
