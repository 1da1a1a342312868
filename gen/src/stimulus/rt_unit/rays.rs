//! The rays the RT unit's environment issues: fresh from a root, with a previous hit, already
//! finished or in the middle of a traversal with stack chunks spilled to memory, the warps
//! they fill, and throwaway warps for faults.

use super::{Env, QUIET_CYCLES};
use vtq_hdl::bounded::BoundedVec;
use vtq_hdl::rt_unit::{
    pack_spill_chunk, spill_area, Hit, IssueTarget, NodeEntry, RayRecord, RayWords, StackSel,
    TraversalOrder, WarpIssue, CHUNK_BYTES, STACK_ENTRIES_PER_CHUNK,
};

impl Env {
    /// A random node of the tree (`leaf`: one without children).
    pub(super) fn node(&mut self, leaf: bool) -> NodeEntry {
        let v = if leaf {
            &self.tree.leaves
        } else {
            &self.tree.nodes
        };
        v[self.rng.below(v.len() as u64) as usize]
    }

    /// An on-chip stack of `k` random leaves, with a random node on top unless `leaves`.
    pub(super) fn stack(&mut self, k: usize, leaves: bool) -> BoundedVec<NodeEntry> {
        let nodes: Vec<NodeEntry> = (0..k).map(|j| self.node(leaves || j + 1 < k)).collect();
        BoundedVec::with(k.max(self.depth), nodes).unwrap_or_default()
    }

    /// A ray with id `id`: mostly fresh at a random root; sometimes with a previous hit,
    /// already finished, or in the middle of a traversal (a few nodes on both stacks, up to
    /// half the spill area of each spilled). Its spilled chunks are not stored yet
    /// ([`Env::store_spills`]). The ray class 7 (bad children) only after the quiet start.
    pub(super) fn ray(&mut self, id: u32) -> RayRecord {
        let mut words: RayWords = std::array::from_fn(|_| self.rng.below(1 << 32) as u32);
        if self.cycle >= QUIET_CYCLES && self.rng.chance(12) {
            words[0] |= 7;
        } else if words[0] & 7 == 7 {
            words[0] ^= 1;
        }
        let root = self.idx(self.tree.roots.len());
        let mut ray = RayRecord::new(id, words, self.tree.roots[root]);
        // One ray in four is an occlusion ray (from its words: the stream of draws is kept).
        ray.occlusion = words[1] & 3 == 0;
        match self.rng.below(50) {
            0 => ray.other_stack = BoundedVec::new(self.depth),
            1..=10 => {
                let node = self.node(false);
                ray.current_treelet = self.block.treelet_of(node.address);
                let spare = self.chunks as u64 / 2;
                if spare > 0 && self.rng.chance(50) {
                    ray.current_spilled = self.rng.below(spare + 1) as u32;
                    ray.other_spilled = self.rng.below(spare + 1) as u32;
                }
                let leaves = ray.current_spilled + ray.other_spilled > 0;
                let most = self.record.min(3) + 1;
                let (a, b) = (self.idx(most), self.idx(most));
                ray.current_stack = self.stack(a, leaves);
                ray.other_stack = self.stack(b, leaves);
            }
            _ => {}
        }
        if self.rng.chance(10) {
            let mut w = || self.rng.below(1 << 32) as u32;
            let (t, hit_id, attribs) = (w(), w(), [w(), w()]);
            ray.hit = Some(Hit { t, hit_id, attribs });
        }
        ray
    }

    /// Stores the chunks `ray` has spilled, 1–4 leaves each, where the RT unit reads them.
    pub(super) fn store_spills(&mut self, ray: &RayRecord) {
        let base = spill_area(self.block.config(), self.block.params()).0;
        for stack in [StackSel::Current, StackSel::Other] {
            for k in 0..ray.spilled(stack) as u64 {
                let n = 1 + self.idx(STACK_ENTRIES_PER_CHUNK.min(self.depth));
                let entries: Vec<NodeEntry> = (0..n).map(|_| self.node(true)).collect();
                let area = ray.ray_id as u64 * 2 + stack.code();
                let address = base + (area * self.chunks as u64 + k) * CHUNK_BYTES as u64;
                self.mem.insert(address, pack_spill_chunk(&entries));
            }
        }
    }

    /// A new ray with a free id, its spilled chunks stored.
    pub(super) fn new_ray(&mut self) -> Option<RayRecord> {
        let i = (!self.free_ids.is_empty()).then(|| self.idx(self.free_ids.len()))?;
        let id = self.free_ids.swap_remove(i);
        let ray = self.ray(id);
        self.store_spills(&ray);
        Some(ray)
    }

    /// Lanes `lanes` of a warp of order `order` filled: with parked rays from the pool
    /// (two-stack orders only) or new rays (none when no id is free).
    pub(super) fn fill(
        &mut self,
        order: TraversalOrder,
        lanes: Vec<usize>,
    ) -> Vec<Option<RayRecord>> {
        let mut out = vec![None; self.ws];
        for l in lanes {
            out[l] = if order.two_stack() && !self.pool.is_empty() && self.rng.chance(60) {
                let i = self.idx(self.pool.len());
                Some(self.pool.swap_remove(i))
            } else {
                self.new_ray()
            };
        }
        out
    }

    /// A warp of random rays with any ids, for a fault (never loaded).
    pub(super) fn throwaway(&mut self, target: IssueTarget) -> WarpIssue {
        let lanes = (0..self.ws)
            .map(|_| {
                let id = self.rng.below(self.rays as u64) as u32;
                self.rng.chance(60).then(|| self.ray(id))
            })
            .collect();
        let order = TraversalOrder::ALL[self.idx(3)];
        WarpIssue {
            order,
            lanes,
            target,
            written: 0,
        }
    }
}
