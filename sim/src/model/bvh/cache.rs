//! On-disk cache of built BVHs, keyed by a blake3 hash of the scene geometry and the build
//! parameters, plus the byte serialization of [`HwBvh`].
//!
//! Serialized format (little-endian):
//! | offset | field |
//! |---|---|
//! | 0  | magic `VTQBVH\0\0` (8 bytes) |
//! | 8  | format version ([`FORMAT_VERSION`], u32) |
//! | 12 | width (u32) |
//! | 16 | treelet size in bytes (u32) |
//! | 20 | treelet formation (u32: 0 breadth first, 1 packed) |
//! | 24 | treelet count `n` (u32) |
//! | 28 | image length in bytes (u64) |
//! | 36 | used bytes of each treelet (`n` x u32) |
//! | 36+4n | the compact image |
//! | end-32 | blake3 hash of everything before it (32 bytes) |
//!
//! Loading verifies the length, magic, version and checksum, then re-validates every node of
//! the image, so a corrupt or truncated file is never trusted: it is rebuilt and replaced.

use std::path::{Path, PathBuf};

use super::{BvhError, BvhParams, HwBvh, TreeletFormation};
use crate::model::atomic_file::write_atomic;
use crate::model::scene::{hash_geometry, Scene};

/// Version of the serialized format and of the build algorithm; part of the cache key. Bump it
/// whenever the layout, the builder or its settings change (3: `obvhs` builds in parallel, whose
/// trees differ from its serial build's).
pub const FORMAT_VERSION: u32 = 3;

/// Bytes of the fixed part of a serialized BVH, before the treelet sizes.
const HEAD: usize = 36;

/// Magic bytes opening a serialized BVH.
const MAGIC: &[u8; 8] = b"VTQBVH\0\0";

/// File name extension of cache files.
const EXTENSION: &str = "vtqbvh";

/// How [`build_cached`] obtained its BVH.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Loaded from a valid cache file.
    Hit,
    /// Built (no cache file existed) and stored.
    Built,
    /// A cache file existed but was invalid (the reason); rebuilt and replaced.
    Rebuilt(String),
    /// Built, but the cache file could not be written (the reason).
    NotStored(String),
}

/// The cache key: blake3 over the format version, the build parameters and the scene geometry
/// ([`hash_geometry`]).
pub fn cache_key(scene: &Scene, params: &BvhParams) -> blake3::Hash {
    let mut h = blake3::Hasher::new();
    h.update(b"vtq-bvh-cache");
    h.update(&FORMAT_VERSION.to_le_bytes());
    h.update(&params.width.to_le_bytes());
    h.update(&params.treelet_bytes.to_le_bytes());
    h.update(&params.formation.code().to_le_bytes());
    hash_geometry(&mut h, scene);
    h.finalize()
}

/// The default cache folder: `$VTQ_CACHE_DIR`, else `$XDG_CACHE_HOME/vtq`, else
/// `$HOME/.cache/vtq`, else `<system temp dir>/vtq-cache`.
pub fn default_cache_dir() -> PathBuf {
    let var = |name: &str| {
        std::env::var_os(name)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = var("VTQ_CACHE_DIR") {
        return d;
    }
    if let Some(d) = var("XDG_CACHE_HOME").filter(|d| d.is_absolute()) {
        return d.join("vtq");
    }
    if let Some(d) = var("HOME") {
        return d.join(".cache").join("vtq");
    }
    std::env::temp_dir().join("vtq-cache")
}

/// Builds the BVH of `scene`, or loads it from the cache folder (`cache_dir`, else
/// [`default_cache_dir`]). Invalid cache files are rebuilt and replaced; files are written
/// atomically (temporary file + rename). Failing to write the cache is not an error (see
/// [`CacheOutcome::NotStored`]).
pub fn build_cached(
    scene: &Scene,
    params: &BvhParams,
    cache_dir: Option<&Path>,
) -> Result<(HwBvh, CacheOutcome), BvhError> {
    params.validate()?;
    let dir = cache_dir
        .map(Path::to_path_buf)
        .unwrap_or_else(default_cache_dir);
    let path = dir.join(format!("{}.{EXTENSION}", cache_key(scene, params).to_hex()));
    let mut stale = None;
    match std::fs::read(&path) {
        Ok(bytes) => match HwBvh::from_bytes(&bytes) {
            Ok(bvh) if bvh.params() == params => return Ok((bvh, CacheOutcome::Hit)),
            Ok(_) => stale = Some("parameters differ from the requested ones".to_string()),
            Err(e) => stale = Some(e.to_string()),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => stale = Some(format!("unreadable: {e}")),
    }
    let bvh = HwBvh::build(scene, params)?;
    let outcome = match write_atomic(&path, &bvh.to_bytes()) {
        Err(reason) => CacheOutcome::NotStored(reason),
        Ok(()) => match stale {
            Some(reason) => CacheOutcome::Rebuilt(reason),
            None => CacheOutcome::Built,
        },
    };
    Ok((bvh, outcome))
}

impl HwBvh {
    /// Serializes the BVH (format in the module documentation of `bvh::cache`).
    pub fn to_bytes(&self) -> Vec<u8> {
        let sizes = self.treelet_sizes();
        let image = self.image();
        let mut out = Vec::with_capacity(HEAD + 4 * sizes.len() + image.len() + 32);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&self.params().width.to_le_bytes());
        out.extend_from_slice(&self.params().treelet_bytes.to_le_bytes());
        out.extend_from_slice(&self.params().formation.code().to_le_bytes());
        out.extend_from_slice(&(sizes.len() as u32).to_le_bytes());
        out.extend_from_slice(&(image.len() as u64).to_le_bytes());
        for s in sizes {
            out.extend_from_slice(&s.to_le_bytes());
        }
        out.extend_from_slice(image);
        let sum = blake3::hash(&out);
        out.extend_from_slice(sum.as_bytes());
        out
    }

    /// Deserializes and fully validates a BVH written by [`HwBvh::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<HwBvh, BvhError> {
        let bad = |m: String| Err(BvhError::Corrupt(m));
        if bytes.len() < HEAD + 32 {
            return bad(format!(
                "{} bytes is too short for a serialized BVH",
                bytes.len()
            ));
        }
        if &bytes[..8] != MAGIC {
            return bad("bad magic (not a vtq BVH file)".into());
        }
        let (body, sum) = bytes.split_at(bytes.len() - 32);
        if blake3::hash(body).as_bytes() != sum {
            return bad("checksum mismatch (truncated or corrupted)".into());
        }
        let u32_at =
            |o: usize| u32::from_le_bytes([body[o], body[o + 1], body[o + 2], body[o + 3]]);
        let version = u32_at(8);
        if version != FORMAT_VERSION {
            return bad(format!(
                "format version {version}, expected {FORMAT_VERSION}"
            ));
        }
        let formation = TreeletFormation::from_code(u32_at(20)).ok_or_else(|| {
            BvhError::Corrupt(format!("unknown treelet formation {}", u32_at(20)))
        })?;
        let params = BvhParams {
            width: u32_at(12),
            treelet_bytes: u32_at(16),
            formation,
        };
        let count = u32_at(24) as u64;
        let mut len8 = [0u8; 8];
        len8.copy_from_slice(&body[28..HEAD]);
        let image_len = u64::from_le_bytes(len8);
        let expected = (HEAD as u64)
            .checked_add(4 * count)
            .and_then(|x| x.checked_add(image_len));
        if expected != Some(body.len() as u64) {
            return bad(format!(
                "length {} does not match {count} treelets and a {image_len}-byte image",
                body.len()
            ));
        }
        let sizes: Vec<u32> = (0..count as usize).map(|i| u32_at(HEAD + 4 * i)).collect();
        let image = body[HEAD + 4 * count as usize..].to_vec();
        if image.len() < 64 {
            return bad("image is shorter than the BVH header".into());
        }
        HwBvh::from_image(params, &sizes, image)
    }
}
