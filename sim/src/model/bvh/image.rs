//! A BVH's compact image read back (from the BVH cache, and after every build): the treelet
//! table and every node reachable from the root checked, so that traversal of the result can
//! never index out of range, and the node and treelet tables rebuilt.

use super::layout::{
    rd_u32, BvhStats, Header, HwBvh, InternalView, NodeInfo, NodeKind, HEADER_ADDR, TYPE_EMPTY,
};
use super::treelet::TreeletInfo;
use super::{BvhError, BvhParams, HEADER_BYTES, LEAF_BYTES};

impl HwBvh {
    /// Rebuilds the tables of a BVH from its compact image, validating every node so that
    /// traversal of the result can never index out of range.
    pub(crate) fn from_image(
        params: BvhParams,
        treelet_sizes: &[u32],
        image: Vec<u8>,
    ) -> Result<HwBvh, BvhError> {
        params.validate()?;
        let bad = |m: String| Err(BvhError::Corrupt(m));
        let tb = params.treelet_bytes;
        let total: u64 = treelet_sizes.iter().map(|&s| s as u64).sum();
        if total != image.len() as u64 {
            return bad(format!(
                "treelet sizes add to {total} bytes but the image has {}",
                image.len()
            ));
        }
        if treelet_sizes.is_empty() {
            return bad("the treelet table is empty".into());
        }
        if treelet_sizes.len() as u64 * tb as u64 > 1u64 << 32 {
            return bad(format!(
                "{} treelets of {tb} bytes do not fit a 32-bit address space",
                treelet_sizes.len()
            ));
        }
        if let Some(s) = treelet_sizes
            .iter()
            .find(|&&s| s > tb || s % 64 != 0 || s == 0)
        {
            return bad(format!(
                "a treelet holds {s} bytes (max {tb}, multiple of 64)"
            ));
        }
        let mut slot_offset = Vec::with_capacity(treelet_sizes.len());
        let mut acc = 0usize;
        for &s in treelet_sizes {
            slot_offset.push(acc);
            acc += s as usize;
        }
        if image.len() < HEADER_BYTES as usize {
            return bad("image is shorter than the BVH header".into());
        }
        let header = Header::decode(&image[0..64]);
        let ib = params.internal_node_bytes();
        if header.treelets as usize != treelet_sizes.len()
            || header.treelet_bytes != tb
            || header.width as u32 != params.width
            || header.internal_units as u32 * 64 != ib
        {
            return bad("header does not match the parameters or treelet table".into());
        }
        let shift = tb.trailing_zeros();
        let check = ImageCheck {
            tb,
            shift,
            ib,
            width: params.width,
            sizes: treelet_sizes,
            slot_offset: &slot_offset,
            image: &image,
        };
        let mut nodes = vec![NodeInfo {
            addr: HEADER_ADDR,
            bytes: HEADER_BYTES,
            kind: NodeKind::Header,
            treelet: 0,
            depth: 0,
        }];
        let ((n_int, n_tri, n_proc), max_depth) = if header.root != 0 {
            check.walk(header.root, &mut nodes)?
        } else {
            ((0, 0, 0), 0)
        };
        nodes.sort_by_key(|n| n.addr);
        // Nodes must tile the used bytes of every treelet exactly, without overlap.
        let mut used = vec![0u64; treelet_sizes.len()];
        for w in nodes.windows(2) {
            if w[0].addr as u64 + w[0].bytes as u64 > w[1].addr as u64 {
                return bad(format!(
                    "nodes {:#x} and {:#x} overlap",
                    w[0].addr, w[1].addr
                ));
            }
        }
        for n in &nodes {
            used[n.treelet as usize] += n.bytes as u64;
        }
        if used.iter().zip(treelet_sizes).any(|(&u, &s)| u != s as u64) {
            return bad(
                "treelet contents are not exactly the nodes reachable from the root".into(),
            );
        }
        if (n_int, n_tri, n_proc)
            != (
                header.internal_nodes,
                header.triangle_leaves,
                header.procedural_leaves,
            )
        {
            return bad("header node counts do not match the tree".into());
        }
        let mut treelets: Vec<TreeletInfo> = treelet_sizes
            .iter()
            .enumerate()
            .map(|(i, &s)| TreeletInfo {
                base: (i as u64 * tb as u64) as u32,
                bytes: s,
                nodes: 0,
                root: (i as u64 * tb as u64) as u32,
            })
            .collect();
        for n in &nodes {
            treelets[n.treelet as usize].nodes += 1;
        }
        let bvh_bytes = image.len() as u64;
        let stats = BvhStats {
            internal_nodes: n_int,
            triangle_leaves: n_tri,
            procedural_leaves: n_proc,
            bvh_bytes,
            treelets: treelets.len() as u32,
            treelet_fill: bvh_bytes as f64 / (treelets.len() as f64 * tb as f64),
            depth: max_depth,
            excluded_prims: header.excluded,
        };
        Ok(HwBvh {
            params,
            shift,
            image,
            slot_offset,
            treelets,
            nodes,
            header,
            stats,
        })
    }
}

/// What [`HwBvh::from_image`] checks a node against: the treelet table and the image.
struct ImageCheck<'a> {
    /// Treelet size in bytes (a power of two).
    tb: u32,
    /// log2 of `tb`.
    shift: u32,
    /// Bytes of an internal node.
    ib: u32,
    /// The BVH's width.
    width: u32,
    /// Used bytes of each treelet.
    sizes: &'a [u32],
    /// Where each treelet starts in the image.
    slot_offset: &'a [usize],
    /// The compact image.
    image: &'a [u8],
}

impl ImageCheck<'_> {
    /// Whether `len` bytes at `addr` lie inside the used bytes of one treelet (64-aligned).
    fn in_range(&self, addr: u32, len: u32) -> bool {
        let t = (addr >> self.shift) as usize;
        let off = (addr & (self.tb - 1)) as u64;
        addr.is_multiple_of(64) && t < self.sizes.len() && off + len as u64 <= self.sizes[t] as u64
    }

    /// Walks the tree from `root`, checking every internal node and child, and appends every
    /// reachable node to `nodes`; returns the (internal, triangle, procedural) node counts and
    /// the tree's depth.
    fn walk(
        &self,
        root: u32,
        nodes: &mut Vec<NodeInfo>,
    ) -> Result<((u32, u32, u32), u32), BvhError> {
        let bad = |m: String| Err(BvhError::Corrupt(m));
        let (mut n_int, mut n_tri, mut n_proc) = (0u32, 0u32, 0u32);
        let mut max_depth = 0u32;
        if !self.in_range(root, self.ib) {
            return bad(format!("root address {root:#x} is outside the image"));
        }
        let mut stack = vec![(root, NodeKind::Internal, 0u32)];
        let max_nodes = self.image.len() / 64;
        while let Some((addr, kind, depth)) = stack.pop() {
            if nodes.len() >= max_nodes {
                return bad("more nodes are reachable than the image can hold".into());
            }
            let size = if kind == NodeKind::Internal {
                self.ib
            } else {
                LEAF_BYTES
            };
            nodes.push(NodeInfo {
                addr,
                bytes: size,
                kind,
                treelet: addr >> self.shift,
                depth,
            });
            max_depth = max_depth.max(depth + 1);
            match kind {
                NodeKind::Internal => n_int += 1,
                NodeKind::TriangleLeaf => n_tri += 1,
                _ => n_proc += 1,
            }
            if kind != NodeKind::Internal {
                continue;
            }
            let off =
                self.slot_offset[(addr >> self.shift) as usize] + (addr & (self.tb - 1)) as usize;
            let node = &self.image[off..off + self.ib as usize];
            let Some(view) = InternalView::new(node) else {
                return bad(format!("internal node {addr:#x} has a bad size"));
            };
            let count = node[19] as u32;
            if count == 0 || count > self.width {
                return bad(format!("internal node {addr:#x} has {count} children"));
            }
            if node[16..19].iter().any(|&e| (e as i8) < -126) {
                return bad(format!(
                    "internal node {addr:#x} has an exponent below -126"
                ));
            }
            let child_off = rd_u32(node, 12) as u64 * 64;
            if child_off == 0 || addr as u64 + child_off >= 1u64 << 32 {
                return bad(format!("internal node {addr:#x} has a bad child offset"));
            }
            let base = view.child_base(addr);
            let mut caddr = base as u64;
            let slots = view.slots;
            for i in 0..slots {
                let t = node[20 + i];
                if (i as u32) < count {
                    let Some(k) = NodeKind::from_type_byte(t) else {
                        return bad(format!("internal node {addr:#x} child {i} has type {t}"));
                    };
                    let csize = view.child_size(k);
                    if caddr + csize as u64 > 1u64 << 32
                        || !self.in_range(caddr as u32, csize)
                        || (caddr as u32) >> self.shift != base >> self.shift
                    {
                        return bad(format!(
                        "internal node {addr:#x} child {i} at {caddr:#x} is outside its group's treelet"
                    ));
                    }
                    stack.push((caddr as u32, k, depth + 1));
                    caddr += csize as u64;
                } else if t != TYPE_EMPTY {
                    return bad(format!(
                        "internal node {addr:#x} empty slot {i} has type {t}"
                    ));
                }
            }
        }
        Ok(((n_int, n_tri, n_proc), max_depth))
    }
}
