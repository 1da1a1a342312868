//! Closest-hit traversal of the hardware BVH, decoding nodes from the memory image, in two
//! orders that give bit-identical hits:
//!
//! - [`Order::RayStationary`]: one stack, children visited closest-first (the baseline RT unit).
//! - [`Order::Treelet`]: the treelet traversal order of Chou et al. (MICRO 2023). A hit child
//!   goes on the current-treelet stack if it lies in the ray's current treelet, otherwise at the
//!   back of the other-treelet FIFO. When the current stack empties, the entry at the front of the
//!   FIFO (the oldest) is fetched next; visiting it makes its treelet current, and every other
//!   FIFO entry of that treelet moves onto the current stack at the same time, so a treelet
//!   that is one subtree (breadth-first formation) is entered at most once per ray; a packed
//!   slot, which holds several, at most once per subtree (`crate::model::bvh::treelet`).
//!
//! The stepwise API ([`TraversalState`]) keeps one node in flight per ray, as the cycle-level
//! simulator needs: [`TraversalState::next_fetch`] names the node (address, size, kind,
//! treelet) and [`TraversalState::visit`] tests it. Every traversal starts by fetching the 64 B
//! BVH header.
//!
//! Closest hit = smallest `t`, ties broken by the smaller global primitive id. Primitives are
//! always tested against the ray's full `[tmin, tmax]` interval and compared with that rule, so
//! the result cannot depend on visiting order. Box culling against the best hit so far keeps a
//! small slack ([`CULL_SLACK`]) so that rounding in the box and primitive distances can never
//! cull a box holding a primitive whose computed `t` ties with or beats the best one.

use std::cell::RefCell;
use std::collections::VecDeque;

use crate::model::bvh::layout::{decode_sphere, decode_triangle, Header, InternalView, LEAF_BYTES};
use crate::model::bvh::HwBvh;
pub use crate::model::bvh::NodeKind;
use crate::model::geometry::{Hit, Ray};
use crate::model::intersect::{gamma, ray_sphere, ray_triangle, RayPrecomp};

/// Relative slack of box culling: a box is culled only when its entry distance exceeds the
/// bound by more than `CULL_SLACK * (S + |bound|)`, where `S` bounds the ray-parameter distance
/// of any scene point from the ray origin (so it covers the absolute rounding error of
/// primitive distances, which scales with vertex distances, not with `t`).
pub const CULL_SLACK: f32 = 1.0 / 16384.0;

/// Far-distance padding of [`intersect::ray_box`](crate::model::intersect::ray_box): `1 + 2 gamma(3)`.
const FAR_PAD: f32 = 1.0 + 2.0 * gamma(3);

/// Per-ray data of [`slab_test_8`]: origin, reciprocal direction and which plane is near.
#[derive(Debug, Clone, Copy)]
struct Slab {
    origin: [f32; 3],
    inv: [f32; 3],
    /// Per axis: whether the direction's reciprocal is negative (the hi plane is near).
    neg: [bool; 3],
}

impl Slab {
    fn new(ray: &Ray) -> Slab {
        let inv = ray.dir.recip().to_array();
        Slab {
            origin: ray.origin.to_array(),
            inv,
            neg: inv.map(f32::is_sign_negative),
        }
    }
}

/// [`ray_box`](crate::model::intersect::ray_box) for eight boxes at once, written without early exits
/// so it vectorizes. It performs the same operations in the same order for every box, so each
/// lane's result (hit flag and entry distance) is identical to `ray_box` for a valid ray (a
/// unit test checks this): after a lane's interval empties, further slabs can only shrink it.
#[inline(always)]
fn slab_test_8(
    slab: &Slab,
    lo: &[[f32; 8]; 3],
    hi: &[[f32; 8]; 3],
    tmin: f32,
    tmax: f32,
) -> ([f32; 8], [bool; 8]) {
    let mut t0 = [tmin; 8];
    let mut t1 = [tmax; 8];
    for a in 0..3 {
        let (near, far) = if slab.neg[a] {
            (&hi[a], &lo[a])
        } else {
            (&lo[a], &hi[a])
        };
        let (o, inv) = (slab.origin[a], slab.inv[a]);
        for i in 0..8 {
            let tn = (near[i] - o) * inv;
            let tf = (far[i] - o) * inv * FAR_PAD;
            if tn > t0[i] {
                t0[i] = tn;
            }
            if tf < t1[i] {
                t1[i] = tf;
            }
        }
    }
    let mut hit = [false; 8];
    for i in 0..8 {
        hit[i] = t0[i] <= t1[i];
    }
    (t0, hit)
}

/// Child visiting policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Order {
    /// One stack, closest child first.
    RayStationary,
    /// Two stacks: current treelet first, other treelets in FIFO order.
    Treelet,
    /// The simulated RT unit's order (`TraversalOrder::TreeletContinue` of `vtq-hdl`): two
    /// LIFO stacks, a node's hit children pushed closest on top onto the current-treelet stack
    /// or the other-treelet stack by their treelet; when the current stack is empty the top of
    /// the other becomes the next node and its treelet the current one. Stack entries carry no
    /// distance, so nothing is culled when popped (the box tests of the popped node's children
    /// use the best hit). Visits exactly the nodes the RT unit fetches, in its order.
    Hardware,
}

/// One node fetch of a ray.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fetch {
    /// Byte address of the node.
    pub addr: u32,
    /// Node size in bytes.
    pub bytes: u32,
    /// What the node is.
    pub kind: NodeKind,
    /// Treelet holding the node.
    pub treelet: u32,
}

/// The work one [`TraversalState::visit`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VisitOutcome {
    /// Ray/box tests (one per child of an internal node).
    pub box_tests: u32,
    /// Ray/triangle tests.
    pub triangle_tests: u32,
    /// Ray/sphere tests.
    pub sphere_tests: u32,
    /// Whether the visit recorded a new closest hit.
    pub hit_recorded: bool,
}

/// A pending node: address, kind and the ray's entry distance into its box (for culling).
#[derive(Debug, Clone, Copy)]
struct Entry {
    addr: u32,
    kind: NodeKind,
    t: f32,
}

/// Reusable stack storage of one traversal.
#[derive(Debug, Default)]
struct Stacks {
    /// The stack (ray-stationary) or current-treelet stack (treelet and hardware orders).
    stack: Vec<Entry>,
    /// The other-treelet FIFO (treelet order only).
    other: VecDeque<Entry>,
    /// The other-treelet stack (hardware order only).
    other_stack: Vec<Entry>,
}

/// The traversal of one ray, advanced one node at a time.
#[derive(Debug)]
pub struct TraversalState {
    ray: Ray,
    pre: RayPrecomp,
    slab: Slab,
    order: Order,
    /// An occlusion ray: the traversal ends at the first hit it records.
    occlusion: bool,
    /// The node to fetch and visit next (`None` when done).
    next: Option<Entry>,
    stacks: Stacks,
    /// Treelet of the last visited node / the ray's current treelet (`None` when done).
    current: Option<u32>,
    best: Option<Hit>,
    /// Absolute part of the culling slack for this ray.
    slack_base: f32,
    /// Lower end of the box-test interval.
    lo_bound: f32,
    /// Upper end of the box-test interval (best hit or tmax, plus slack).
    cull_bound: f32,
    /// log2(treelet_bytes).
    shift: u32,
    /// Internal node size.
    internal_bytes: u32,
}

thread_local! {
    /// Stack storage reused by [`trace`] and [`trace_with_fetches`] on this thread.
    static SCRATCH: RefCell<Stacks> = RefCell::new(Stacks::default());
}

/// Pads a finite bound outward by the culling slack.
#[inline(always)]
fn pad(x: f32, slack_base: f32, up: bool) -> f32 {
    if !x.is_finite() {
        return x;
    }
    let s = slack_base + CULL_SLACK * x.abs();
    if up {
        x + s
    } else {
        x - s
    }
}

/// Bound on `|p - origin|_max / |dir|_max` over the scene box: how far (in units of `t`) any
/// primitive coordinate can be from the ray origin.
fn scene_scale(header: &Header, ray: &Ray) -> f32 {
    let far = (header.lo - ray.origin)
        .abs()
        .max((header.hi - ray.origin).abs())
        .max_element();
    far / ray.dir.abs().max_element()
}

/// Absolute part of the culling slack of a valid ray: [`CULL_SLACK`] times the scene scale
/// (infinite when that is NaN, so nothing is culled).
fn slack_base_of(header: &Header, ray: &Ray) -> f32 {
    let base = CULL_SLACK * scene_scale(header, ray);
    if base.is_nan() {
        f32::INFINITY
    } else {
        base
    }
}

/// The children of an internal node that a ray's box tests keep, closest first (equal entry
/// distances keep slot order), and the number of box tests made.
#[inline(always)]
fn hit_children(
    slab: &Slab,
    view: &InternalView,
    addr: u32,
    lo_bound: f32,
    cull_bound: f32,
) -> ([Entry; 8], usize, u32) {
    let count = view.child_count();
    let mut hits = [Entry {
        addr: 0,
        kind: NodeKind::Internal,
        t: 0.0,
    }; 8];
    let mut n = 0usize;
    let mut caddr = view.child_base(addr);
    let mut tests = 0;
    let mut lo = [[0f32; 8]; 3];
    let mut hi = [[0f32; 8]; 3];
    view.decode_boxes(&mut lo, &mut hi);
    let (t_near, hit) = slab_test_8(slab, &lo, &hi, lo_bound, cull_bound);
    for i in 0..count {
        let Some(kind) = view.child_kind(i) else {
            continue;
        };
        tests += 1;
        if hit[i] {
            let t = t_near[i];
            // Insertion sort by entry distance; equal distances keep slot order.
            let mut j = n;
            while j > 0 && hits[j - 1].t > t {
                hits[j] = hits[j - 1];
                j -= 1;
            }
            hits[j] = Entry {
                addr: caddr,
                kind,
                t,
            };
            n += 1;
        }
        caddr = caddr.wrapping_add(view.child_size(kind));
    }
    (hits, n, tests)
}

/// The box tests of one ray outside a [`TraversalState`], for a datapath that sees one node at a
/// time (the cycle-level RT unit): the same slab test, slack and child order as [`trace`], so
/// culling is as conservative and closest hits are identical.
#[derive(Debug, Clone, Copy)]
pub struct BoxTester {
    slab: Slab,
    slack_base: f32,
    lo_bound: f32,
    tmax: f32,
}

impl BoxTester {
    /// The box tester of a valid ray (see [`Ray::is_valid`]) in the BVH with header `header`.
    pub fn new(header: &Header, ray: &Ray) -> Self {
        let slack_base = slack_base_of(header, ray);
        BoxTester {
            slab: Slab::new(ray),
            slack_base,
            lo_bound: pad(ray.tmin, slack_base, false),
            tmax: ray.tmax,
        }
    }

    /// Tests the children of the internal node `view` at `addr` against the ray, culling against
    /// the closest hit distance so far (`best_t`) as [`trace`] does; returns the kept children
    /// (address and kind) closest first and the number of box tests.
    pub fn children(
        &self,
        view: &InternalView,
        addr: u32,
        best_t: Option<f32>,
    ) -> (impl ExactSizeIterator<Item = (u32, NodeKind)>, u32) {
        let bound = best_t.map_or(self.tmax, |t| t.min(self.tmax));
        let cull_bound = pad(bound, self.slack_base, true);
        let (hits, n, tests) = hit_children(&self.slab, view, addr, self.lo_bound, cull_bound);
        (hits.into_iter().take(n).map(|e| (e.addr, e.kind)), tests)
    }
}

impl TraversalState {
    /// Starts the traversal of `ray`. An invalid ray ([`Ray::is_valid`] false) is already
    /// done: a miss with no fetches.
    pub fn new(bvh: &HwBvh, ray: &Ray, order: Order) -> Self {
        Self::with_stacks(bvh, ray, order, false, Stacks::default())
    }

    /// Starts the traversal of `ray` as an occlusion ray (the RT unit's terminate-on-first-hit
    /// flag): it ends at the first hit it records, which is then [`hit`](Self::hit). Whether it
    /// hits is whether the closest-hit traversal hits; which hit it reports depends on the
    /// order.
    pub fn occlusion(bvh: &HwBvh, ray: &Ray, order: Order) -> Self {
        Self::with_stacks(bvh, ray, order, true, Stacks::default())
    }

    fn with_stacks(
        bvh: &HwBvh,
        ray: &Ray,
        order: Order,
        occlusion: bool,
        mut stacks: Stacks,
    ) -> Self {
        stacks.stack.clear();
        stacks.other.clear();
        stacks.other_stack.clear();
        let valid = ray.is_valid();
        let slack_base = if valid {
            slack_base_of(bvh.header(), ray)
        } else {
            0.0
        };
        TraversalState {
            ray: *ray,
            pre: RayPrecomp::new(ray),
            slab: Slab::new(ray),
            order,
            occlusion,
            next: valid.then_some(Entry {
                addr: crate::model::bvh::layout::HEADER_ADDR,
                kind: NodeKind::Header,
                t: ray.tmin,
            }),
            stacks,
            current: valid.then_some(0),
            best: None,
            slack_base,
            lo_bound: pad(ray.tmin, slack_base, false),
            cull_bound: pad(ray.tmax, slack_base, true),
            shift: bvh.params().treelet_bytes.trailing_zeros(),
            internal_bytes: bvh.params().internal_node_bytes(),
        }
    }

    /// Size of a node of the given kind.
    #[inline(always)]
    fn size_of(&self, kind: NodeKind) -> u32 {
        match kind {
            NodeKind::Internal => self.internal_bytes,
            _ => LEAF_BYTES,
        }
    }

    /// The node this ray needs next; `None` when done.
    #[inline]
    pub fn next_fetch(&self) -> Option<Fetch> {
        self.next.map(|e| Fetch {
            addr: e.addr,
            bytes: self.size_of(e.kind),
            kind: e.kind,
            treelet: e.addr >> self.shift,
        })
    }

    /// Whether the traversal has finished.
    pub fn is_done(&self) -> bool {
        self.next.is_none()
    }

    /// The closest hit found so far (the final hit once done).
    pub fn hit(&self) -> Option<Hit> {
        self.best
    }

    /// The ray's current treelet: the treelet of the node visited last (treelet 0 before the
    /// first visit); `None` when done.
    pub fn current_treelet(&self) -> Option<u32> {
        if self.is_done() {
            None
        } else {
            self.current
        }
    }

    /// Treelet of the next fetch; `None` when done.
    pub fn next_treelet(&self) -> Option<u32> {
        self.next.map(|e| e.addr >> self.shift)
    }

    /// Whether the next fetch leaves the current treelet (never true when done).
    pub fn at_treelet_boundary(&self) -> bool {
        match (self.next_treelet(), self.current) {
            (Some(n), Some(c)) => n != c,
            _ => false,
        }
    }

    /// Whether a primitive hit `(t, prim)` beats the best hit so far.
    #[inline(always)]
    fn better(&self, t: f32, prim: u32) -> bool {
        match self.best {
            None => true,
            Some(b) => t < b.t || (t == b.t && prim < b.prim),
        }
    }

    /// Records a new closest hit and tightens the culling bound.
    #[inline(always)]
    fn record(&mut self, hit: Hit) {
        self.best = Some(hit);
        self.cull_bound = pad(hit.t.min(self.ray.tmax), self.slack_base, true);
    }

    /// Tests the node named by [`next_fetch`](Self::next_fetch) (decoding its bytes), updates
    /// the stacks and the best hit, and picks the next node. A no-op when done.
    pub fn visit(&mut self, bvh: &HwBvh) -> VisitOutcome {
        let mut out = VisitOutcome::default();
        let Some(e) = self.next.take() else {
            return out;
        };
        let treelet = e.addr >> self.shift;
        if self.current != Some(treelet) {
            self.current = Some(treelet);
            if self.order == Order::Treelet {
                self.enter_treelet(treelet);
            }
        }
        let bytes = bvh.bytes_at(e.addr, self.size_of(e.kind));
        match e.kind {
            NodeKind::Header => {
                let root = Header::decode(bytes).root;
                if root != 0 {
                    let entry = Entry {
                        addr: root,
                        kind: NodeKind::Internal,
                        t: self.lo_bound,
                    };
                    if self.order == Order::Hardware && Some(root >> self.shift) != self.current {
                        self.stacks.other_stack.push(entry);
                    } else {
                        self.stacks.stack.push(entry);
                    }
                }
            }
            NodeKind::Internal => {
                if let Some(view) = InternalView::new(bytes) {
                    out.box_tests = self.visit_internal(&view, e.addr);
                }
            }
            NodeKind::TriangleLeaf => {
                out.triangle_tests = 1;
                let (v, prim) = decode_triangle(bytes);
                if let Some((t, u, w)) = ray_triangle(&self.pre, v, self.ray.tmin, self.ray.tmax) {
                    if self.better(t, prim) {
                        self.record(Hit { t, prim, u, v: w });
                        out.hit_recorded = true;
                    }
                }
            }
            NodeKind::ProceduralLeaf => {
                out.sphere_tests = 1;
                let (c, r, prim) = decode_sphere(bytes);
                if let Some(t) = ray_sphere(&self.ray, c, r, self.ray.tmin, self.ray.tmax) {
                    if self.better(t, prim) {
                        self.record(Hit {
                            t,
                            prim,
                            u: 0.0,
                            v: 0.0,
                        });
                        out.hit_recorded = true;
                    }
                }
            }
        }
        if self.occlusion && out.hit_recorded {
            // An occlusion ray's first hit ends its traversal.
            self.next = None;
            self.current = None;
            return out;
        }
        self.advance();
        out
    }

    /// Tests the children of an internal node and pushes the hit ones; returns the box tests.
    #[inline(always)]
    fn visit_internal(&mut self, view: &InternalView, addr: u32) -> u32 {
        let (hits, n, tests) = hit_children(&self.slab, view, addr, self.lo_bound, self.cull_bound);
        let hits = &hits[..n];
        match self.order {
            Order::RayStationary => {
                self.stacks.stack.extend(hits.iter().rev());
            }
            Order::Treelet => {
                let cur = self.current;
                let shift = self.shift;
                self.stacks
                    .stack
                    .extend(hits.iter().rev().filter(|h| Some(h.addr >> shift) == cur));
                self.stacks
                    .other
                    .extend(hits.iter().filter(|h| Some(h.addr >> shift) != cur));
            }
            Order::Hardware => {
                let (cur, shift) = (self.current, self.shift);
                for h in hits.iter().rev() {
                    if Some(h.addr >> shift) == cur {
                        self.stacks.stack.push(*h);
                    } else {
                        self.stacks.other_stack.push(*h);
                    }
                }
            }
        }
        tests
    }

    /// Treelet order: entering `treelet` moves its pending FIFO entries onto the current
    /// stack (oldest on top) and drops culled entries.
    fn enter_treelet(&mut self, treelet: u32) {
        let shift = self.shift;
        let bound = self.cull_bound;
        let other = &mut self.stacks.other;
        if other.is_empty() {
            return;
        }
        let first_new = self.stacks.stack.len();
        other.retain(|e| {
            if e.t > bound {
                return false;
            }
            if e.addr >> shift == treelet {
                self.stacks.stack.push(*e);
                return false;
            }
            true
        });
        self.stacks.stack[first_new..].reverse();
    }

    /// Picks the next node to visit: the top of the current stack, else the front of the
    /// other-treelet FIFO, skipping entries the best hit has culled.
    #[inline(always)]
    fn advance(&mut self) {
        if self.order == Order::Hardware {
            // No culling on pop: the RT unit's stack entries carry no distance.
            self.next = self
                .stacks
                .stack
                .pop()
                .or_else(|| self.stacks.other_stack.pop());
            if self.next.is_none() {
                self.current = None;
            }
            return;
        }
        while let Some(e) = self.stacks.stack.pop() {
            if e.t <= self.cull_bound {
                self.next = Some(e);
                return;
            }
        }
        while let Some(e) = self.stacks.other.pop_front() {
            if e.t <= self.cull_bound {
                self.next = Some(e);
                return;
            }
        }
        self.current = None;
    }

    /// Runs to completion (recording fetches if asked), returning the stacks for reuse.
    fn finish(
        mut self,
        bvh: &HwBvh,
        mut fetches: Option<&mut Vec<Fetch>>,
    ) -> (Option<Hit>, Stacks) {
        while let Some(e) = self.next {
            if let Some(f) = fetches.as_deref_mut() {
                f.push(Fetch {
                    addr: e.addr,
                    bytes: self.size_of(e.kind),
                    kind: e.kind,
                    treelet: e.addr >> self.shift,
                });
            }
            self.visit(bvh);
        }
        (self.best, self.stacks)
    }
}

/// Runs a traversal (an occlusion ray's if `occlusion`) on this thread's reusable stacks.
fn run(
    bvh: &HwBvh,
    ray: &Ray,
    order: Order,
    occlusion: bool,
    fetches: Option<&mut Vec<Fetch>>,
) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let stacks = SCRATCH.with(|s| std::mem::take(&mut *s.borrow_mut()));
    let state = TraversalState::with_stacks(bvh, ray, order, occlusion, stacks);
    let (hit, stacks) = state.finish(bvh, fetches);
    SCRATCH.with(|s| *s.borrow_mut() = stacks);
    hit
}

/// The closest hit of `ray` (`None` for a miss or an invalid ray).
pub fn trace(bvh: &HwBvh, ray: &Ray, order: Order) -> Option<Hit> {
    run(bvh, ray, order, false, None)
}

/// The first hit an occlusion ray `ray` records in `order` (`None` for a miss or an invalid
/// ray): some hit exactly when [`trace`] finds one ([`TraversalState::occlusion`]).
pub fn trace_occlusion(bvh: &HwBvh, ray: &Ray, order: Order) -> Option<Hit> {
    run(bvh, ray, order, true, None)
}

/// [`trace_occlusion`], also appending every node fetch in order (header first) to `fetches`.
pub fn trace_occlusion_with_fetches(
    bvh: &HwBvh,
    ray: &Ray,
    order: Order,
    fetches: &mut Vec<Fetch>,
) -> Option<Hit> {
    run(bvh, ray, order, true, Some(fetches))
}

/// [`trace`], also appending every node fetch in order (header first) to `fetches`.
pub fn trace_with_fetches(
    bvh: &HwBvh,
    ray: &Ray,
    order: Order,
    fetches: &mut Vec<Fetch>,
) -> Option<Hit> {
    run(bvh, ray, order, false, Some(fetches))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::intersect::ray_box;
    use glam::Vec3;
    use proptest::prelude::*;

    /// Coordinates that include zeros, so origins on slab planes and zero direction components
    /// (infinite reciprocals, `0 * inf`) occur often.
    fn coord() -> impl Strategy<Value = f32> {
        prop_oneof![Just(0.0f32), Just(1.0f32), Just(-1.0f32), -4.0f32..4.0]
    }

    fn vec3() -> impl Strategy<Value = Vec3> {
        (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]

        /// The batched slab test gives exactly `ray_box`'s answer in every lane.
        #[test]
        fn slab_test_8_matches_ray_box(
            origin in vec3(),
            dir in vec3(),
            boxes in prop::collection::vec((vec3(), vec3()), 8),
            tmin in prop_oneof![Just(0.0f32), Just(f32::NEG_INFINITY), -2.0f32..2.0],
            len in prop_oneof![Just(f32::INFINITY), 0.0f32..8.0],
        ) {
            let ray = Ray { origin, dir, tmin, tmax: tmin + len };
            prop_assume!(ray.is_valid());
            let pre = RayPrecomp::new(&ray);
            let mut lo = [[0f32; 8]; 3];
            let mut hi = [[0f32; 8]; 3];
            for (i, (a, b)) in boxes.iter().enumerate() {
                for axis in 0..3 {
                    // Some boxes are inverted (empty) on purpose.
                    lo[axis][i] = a[axis];
                    hi[axis][i] = b[axis];
                }
            }
            let (t, hit) = slab_test_8(&Slab::new(&ray), &lo, &hi, ray.tmin, ray.tmax);
            for (i, (a, b)) in boxes.iter().enumerate() {
                let expected = ray_box(&pre, *a, *b, ray.tmin, ray.tmax);
                prop_assert_eq!(hit[i].then_some(t[i]), expected, "lane {}", i);
            }
        }
    }
}
