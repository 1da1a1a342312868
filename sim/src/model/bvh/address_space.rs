//! Whether a BVH fits the 32-bit BVH address space: treelet `i` takes the `treelet_bytes` slot
//! at `i * treelet_bytes`, so at most `2^32 / treelet_bytes` treelets exist (524,288 of 8 KB:
//! the paper's 19-bit treelet ids, the width of the count and queue tables' tags).
//!
//! The exact treelet count is known only once the tree is built and partitioned, which for a
//! scene of tens of millions of triangles takes most of a minute. So before building a large
//! scene ([`PREFLIGHT_MIN_PRIMS`] primitives or more, and more primitives than slots),
//! [`preflight`] builds and partitions the tree of an evenly strided sample of about
//! [`SAMPLE_PRIMS`] primitives and scales its treelet count by the stride; an estimate more than [`MARGIN`] times the address space stops the
//! build there, saying it is an estimate and which settings fix it. Anything closer is built and
//! decided exactly by [`check`]. The estimate's measured error (docs/config.md, "Treelets and
//! the address space") is far inside the margin on every scene tried.

use super::build::build_wide_tree_every;
use super::treelet::{self, TreeletFormation};
use super::{BvhError, BvhParams};
use crate::model::scene::Scene;

/// Scenes with fewer primitives are built without an estimate (their build takes two or three
/// seconds at most, and the exact check follows it).
pub const PREFLIGHT_MIN_PRIMS: usize = 2_000_000;
/// Primitives in the estimate's sample (a stride of `prims / SAMPLE_PRIMS`, rounded up).
pub const SAMPLE_PRIMS: usize = 250_000;
/// How many times the address space the estimate must exceed to stop the build before it.
pub const MARGIN: f64 = 1.5;

/// Treelet slots the 32-bit address space holds at `params`' treelet size.
pub fn slots(params: &BvhParams) -> u64 {
    (1u64 << 32) / params.treelet_bytes as u64
}

/// The treelet count estimated from every `stride`-th primitive of `scene`: the sample's
/// treelets times the stride.
pub(crate) fn estimate(scene: &Scene, params: &BvhParams, stride: usize) -> Result<u64, BvhError> {
    let tree = build_wide_tree_every(scene, params, stride)?;
    let parts = treelet::partition(
        &tree,
        params.internal_node_bytes(),
        params.treelet_bytes,
        params.formation,
    );
    Ok(parts.len() as u64 * stride as u64)
}

/// Before building: refuses a scene whose estimated treelets exceed the address space by more
/// than [`MARGIN`]. Not estimated: scenes of fewer than [`PREFLIGHT_MIN_PRIMS`] primitives,
/// and scenes with no more primitives than slots (every treelet roots at the tree's root or at
/// an internal node's child group, so a tree has at most as many treelets as primitives).
pub(crate) fn preflight(scene: &Scene, params: &BvhParams) -> Result<(), BvhError> {
    let prims = scene.prim_count();
    if prims < PREFLIGHT_MIN_PRIMS || prims as u64 <= slots(params) {
        return Ok(());
    }
    let stride = prims.div_ceil(SAMPLE_PRIMS);
    verdict(estimate(scene, params, stride)?, stride, prims, params)
}

/// Refuses an estimate of `treelets` (from every `stride`-th of `prims` primitives) more than
/// [`MARGIN`] times the address space.
fn verdict(treelets: u64, stride: usize, prims: usize, params: &BvhParams) -> Result<(), BvhError> {
    if treelets as f64 > MARGIN * slots(params) as f64 {
        return Err(BvhError::TooLarge(unaddressable(
            &format!(
                "an estimated {treelets} treelets (estimated before building, from the tree of \
                 every {stride}th of the scene's {prims} primitives)"
            ),
            params,
        )));
    }
    Ok(())
}

/// After partitioning: refuses `treelets` treelets that the address space cannot hold.
pub(crate) fn check(treelets: usize, params: &BvhParams) -> Result<(), BvhError> {
    if treelets as u64 > slots(params) {
        return Err(BvhError::TooLarge(unaddressable(
            &format!("{treelets} treelets"),
            params,
        )));
    }
    Ok(())
}

/// Why `treelets` (a count, or an estimate of one) of `params` cannot be addressed, and which
/// settings fix it.
fn unaddressable(treelets: &str, params: &BvhParams) -> String {
    let tb = params.treelet_bytes as u64;
    let id_bits = 32 - tb.trailing_zeros();
    let mut fixes = Vec::new();
    if params.formation == TreeletFormation::BreadthFirst {
        fixes.push(
            "`--set bvh.treelet_formation=packed` packs the breadth-first formation's small \
             treelets into shared slots (the paper's section 6.5: treelets \"packed together in \
             memory\" so 19-bit treelet addresses suffice; same tables and widths, fewer and \
             fuller treelets)"
                .to_string(),
        );
    }
    fixes.push(format!(
        "`--treelet-bytes {}` doubles the slot (treelet ids of {} bits: one bit less in every \
         count- and queue-table tag, `vtq area --set hw.treelet_bytes={}` gives the tables' \
         storage and area; but treelets larger than half the 16 KB L1 the paper sizes them to)",
        2 * tb,
        id_bits - 1,
        2 * tb
    ));
    format!(
        "{treelets} of {tb} bytes exceed the 32-bit BVH address space, which holds {} treelet \
         slots ({id_bits}-bit treelet ids, the width of the treelet count and queue tables' \
         tags); {}",
        slots(params),
        fixes.join("; or ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unaddressable_bvh_names_the_settings_that_fix_it() {
        let bf = BvhParams {
            formation: TreeletFormation::BreadthFirst,
            ..BvhParams::default()
        };
        assert!(check(524_288, &bf).is_ok());
        let m = check(1_731_481, &bf).unwrap_err().to_string();
        assert!(m.contains("1731481 treelets of 8192 bytes"), "{m}");
        assert!(
            m.contains("524288 treelet slots (19-bit treelet ids"),
            "{m}"
        );
        assert!(m.contains("bvh.treelet_formation=packed"), "{m}");
        assert!(m.contains("--treelet-bytes 16384"), "{m}");
        assert!(m.contains("vtq area --set hw.treelet_bytes=16384"), "{m}");
        let packed = BvhParams {
            formation: TreeletFormation::Packed,
            ..BvhParams::default()
        };
        let m = check(600_000, &packed).unwrap_err().to_string();
        assert!(!m.contains("treelet_formation"), "already packed: {m}");
        assert!(m.contains("treelet ids of 18 bits"), "{m}");
    }

    #[test]
    fn a_far_unaddressable_estimate_stops_the_build_and_says_it_is_an_estimate() {
        let bf = BvhParams {
            formation: TreeletFormation::BreadthFirst,
            ..BvhParams::default()
        };
        // 1.5 x 524,288 slots is the line.
        assert!(verdict(786_432, 64, 16_000_000, &bf).is_ok());
        let m = verdict(1_700_000, 64, 16_000_000, &bf)
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("an estimated 1700000 treelets (estimated before building"),
            "{m}"
        );
        assert!(
            m.contains("every 64th of the scene's 16000000 primitives"),
            "{m}"
        );
        assert!(m.contains("bvh.treelet_formation=packed"), "{m}");
    }

    #[test]
    fn the_sampled_estimate_is_near_the_exact_count() {
        // A generated city of 200k triangles, a sample of every 8th: docs/config.md reports
        // the estimate's error on the shared scenes and the cities (packed within 2.5%,
        // breadth-first -22% to +2% at a million triangles and more).
        let scene = crate::model::scene::city::city(200_000);
        for (formation, tolerance) in [
            (TreeletFormation::Packed, 0.05),
            (TreeletFormation::BreadthFirst, 0.3),
        ] {
            let p = BvhParams {
                formation,
                ..BvhParams::default()
            };
            let exact = estimate(&scene, &p, 1).unwrap() as f64;
            let sampled = estimate(&scene, &p, 8).unwrap() as f64;
            let err = sampled / exact - 1.0;
            assert!(
                err.abs() <= tolerance,
                "{formation:?}: exact {exact}, sampled {sampled} ({err:+.3})"
            );
        }
    }
}
