//! The RT unit's intersection datapath over the hardware BVH ([`BvhDatapath`]): decodes the node
//! bytes that reached the RT unit with the BVH layout decoders and runs the same box, triangle
//! and sphere tests as the functional tracer ([`crate::model::traversal`]), so every ray's closest hit
//! equals [`crate::model::traversal::trace`]'s.
//!
//! Box culling uses [`BoxTester`] (same slab test, slack and closest-first child order).
//! Primitives are tested against the ray's original `[tmin, tmax]` and reported when not beyond
//! the closest hit so far; the RT unit keeps a candidate only if its `(t, primitive id)` is
//! lexicographically smaller, which is [`trace`](crate::model::traversal::trace)'s tie rule.

use glam::Vec3;
use vtq_hdl::rt_unit::{
    Hit as HwHit, NodeDatapath, NodeEntry, NodeKind as HwKind, RayWords, TestResult, CHUNK_BYTES,
    TMAX_WORD, TMIN_WORD,
};

use crate::model::bvh::layout::{
    decode_sphere, decode_triangle, Header, InternalView, HEADER_BYTES,
};
use crate::model::bvh::{HwBvh, NodeKind};
use crate::model::geometry::{Hit, Ray};
use crate::model::intersect::{ray_sphere, ray_triangle, RayPrecomp};
use crate::model::traversal::BoxTester;

/// The ray words of a ray: origin, direction, tmin, tmax as f32 bits.
pub fn ray_words(ray: &Ray) -> RayWords {
    ray.bits()
}

/// The ray held in ray words (inverse of [`ray_words`]).
pub fn words_ray(w: &RayWords) -> Ray {
    let f = |i: usize| f32::from_bits(w[i]);
    Ray {
        origin: Vec3::new(f(0), f(1), f(2)),
        dir: Vec3::new(f(3), f(4), f(5)),
        tmin: f(TMIN_WORD),
        tmax: f(TMAX_WORD),
    }
}

/// The simulator's hit from the RT unit's hit record (t, primitive id, barycentrics).
pub fn hit_from_hw(h: &HwHit) -> Hit {
    Hit {
        t: f32::from_bits(h.t),
        prim: h.hit_id,
        u: f32::from_bits(h.attribs[0]),
        v: f32::from_bits(h.attribs[1]),
    }
}

/// The RT unit's hit record of a simulator hit (inverse of [`hit_from_hw`]).
fn hit_to_hw(h: Hit) -> HwHit {
    HwHit {
        t: h.t.to_bits(),
        hit_id: h.prim,
        attribs: [h.u.to_bits(), h.v.to_bits()],
    }
}

/// The RT unit's node reference for a node of the BVH image (address, kind, size in chunks).
pub fn node_entry(addr: u32, kind: NodeKind, internal_bytes: u32) -> NodeEntry {
    let (kind, bytes) = match kind {
        NodeKind::Header => (HwKind::Header, HEADER_BYTES),
        NodeKind::Internal => (HwKind::Internal, internal_bytes),
        NodeKind::TriangleLeaf => (HwKind::TriangleLeaf, crate::model::bvh::layout::LEAF_BYTES),
        NodeKind::ProceduralLeaf => (HwKind::Procedural, crate::model::bvh::layout::LEAF_BYTES),
    };
    NodeEntry {
        address: addr as u64,
        kind,
        chunks: (bytes / CHUNK_BYTES) as u8,
    }
}

/// The intersection datapath of the RT unit over one hardware BVH.
#[derive(Debug, Clone, Copy)]
pub struct BvhDatapath<'a> {
    bvh: &'a HwBvh,
}

impl<'a> BvhDatapath<'a> {
    /// The datapath testing rays against `bvh`.
    pub fn new(bvh: &'a HwBvh) -> Self {
        BvhDatapath { bvh }
    }

    /// The node reference of a child the tests decided to visit.
    fn entry(&self, addr: u32, kind: NodeKind) -> NodeEntry {
        node_entry(addr, kind, self.bvh.params().internal_node_bytes())
    }
}

impl NodeDatapath for BvhDatapath<'_> {
    fn test(
        &self,
        words: &RayWords,
        best: Option<&HwHit>,
        node: &NodeEntry,
        data: &[u8],
    ) -> TestResult {
        let ray = words_ray(words);
        let mut result = TestResult::default();
        if !ray.is_valid() {
            return result;
        }
        let best_t = best.map(|b| f32::from_bits(b.t));
        let not_beyond_best = |t: f32| best_t.is_none_or(|b| t <= b);
        match node.kind {
            HwKind::Header => {
                let root = Header::decode(data).root;
                if root != 0 {
                    result.children.push(self.entry(root, NodeKind::Internal));
                }
            }
            HwKind::Internal => {
                if let Some(view) = InternalView::new(data) {
                    // Allocates only when some child is kept, exactly as many as are kept.
                    let (kept, _) = BoxTester::new(self.bvh.header(), &ray).children(
                        &view,
                        node.address as u32,
                        best_t,
                    );
                    result.children.extend(kept.map(|(a, k)| self.entry(a, k)));
                }
            }
            HwKind::TriangleLeaf => {
                let (v, prim) = decode_triangle(data);
                let pre = RayPrecomp::new(&ray);
                if let Some((t, u, w)) = ray_triangle(&pre, v, ray.tmin, ray.tmax) {
                    if not_beyond_best(t) {
                        result.hit = Some(hit_to_hw(Hit { t, prim, u, v: w }));
                    }
                }
            }
            HwKind::Procedural => {
                let (c, r, prim) = decode_sphere(data);
                if let Some(t) = ray_sphere(&ray, c, r, ray.tmin, ray.tmax) {
                    if not_beyond_best(t) {
                        result.hit = Some(hit_to_hw(Hit {
                            t,
                            prim,
                            u: 0.0,
                            v: 0.0,
                        }));
                    }
                }
            }
            // The hardware BVH has no instances or separate primitive descriptors.
            HwKind::InstanceLeaf | HwKind::PrimitiveDescriptor => {}
        }
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_words_round_trip() {
        let ray = Ray {
            origin: Vec3::new(1.0, -2.5, 3.25),
            dir: Vec3::new(-0.0, 0.5, 1e-30),
            tmin: 0.001,
            tmax: 10000.0,
        };
        assert_eq!(words_ray(&ray_words(&ray)), ray);
    }

    #[test]
    fn hits_round_trip_through_hit_records() {
        let h = Hit {
            t: 2.5,
            prim: 7,
            u: 0.25,
            v: 0.5,
        };
        assert_eq!(hit_from_hw(&hit_to_hw(h)), h);
    }
}
