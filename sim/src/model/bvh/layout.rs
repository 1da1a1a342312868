//! The hardware BVH memory image (Intel / Vulkan-Sim style), its decoders and [`HwBvh`].
//!
//! All values are little-endian; every node is 64-byte aligned; addresses are 32-bit byte
//! addresses. Treelet `i` occupies the slot `[i * treelet_bytes, (i + 1) * treelet_bytes)`
//! (see [`super::treelet`]); the image stores only the used bytes of each slot.
//!
//! **Header** (64 B, address 0):
//! | offset | field |
//! |---|---|
//! | 0  | root node address (u32; 0 = empty BVH, no primitives) |
//! | 4  | internal node count (u32) |
//! | 8  | triangle leaf count (u32) |
//! | 12 | procedural leaf count (u32) |
//! | 16 | treelet count (u32) |
//! | 20 | treelet size in bytes (u32) |
//! | 24 | width (u8); 25: internal node size in 64 B units (u8); 26..28 zero |
//! | 28 | scene bounds lo (3 x f32); 40: scene bounds hi (3 x f32) (zeros when empty) |
//! | 52 | primitives excluded from the tree (u32); 56..64 zero |
//!
//! **Internal node** (64 B with S = 6 child slots for widths 2..=6; 128 B with S = 8 slots
//! for widths 7 and 8, because 8 children need 20 + 8 + 48 = 76 bytes):
//! | offset | field |
//! |---|---|
//! | 0  | origin (3 x f32) = lower corner of the node's exact box |
//! | 12 | child base: offset of the first child from this node, in 64 B units (u32) |
//! | 16 | per-axis exponents e_x, e_y, e_z (3 x i8, in -126..=127) |
//! | 19 | child count (u8, 1..=width) |
//! | 20 | child type per slot (S x u8: 0 empty, 1 internal, 2 triangle leaf, 3 procedural leaf) |
//! | 20+S | quantized boxes, 6 arrays of S x u8: lo_x, hi_x, lo_y, hi_y, lo_z, hi_z |
//! | 20+7S | zero padding to 64 / 128 B |
//!
//! Children are stored contiguously from the child base in slot order; child `j` is at
//! `base + sum of the sizes of children 0..j` (internal nodes `S == 6 ? 64 : 128` B, leaves
//! 64 B). Child box plane on axis `a`: `origin[a] + (q as f32) * 2^e[a]` in f32 arithmetic
//! ([`dequantize`]); lo planes are rounded down and hi planes up so the decoded box contains
//! the child's exact box.
//!
//! **Triangle leaf** (64 B): 0: v0, 12: v1, 24: v2 (3 x f32 each); 36: global primitive id
//! (u32); 40..64 zero.
//!
//! **Procedural leaf** (64 B): 0: sphere centre (3 x f32); 12: radius (f32); 16: global
//! primitive id (u32); 20..64 zero.

use glam::Vec3;

use super::address_space;
use super::build::{build_wide_tree, WideNode, WideTree};
use super::treelet::{self, TreeletInfo, Unit};
use super::{BvhError, BvhParams};
pub use super::{HEADER_BYTES, LEAF_BYTES};
use crate::model::scene::Scene;

/// Address of the BVH header.
pub const HEADER_ADDR: u32 = 0;

/// Child type byte of an empty slot.
pub(super) const TYPE_EMPTY: u8 = 0;
/// Child type byte of an internal node.
const TYPE_INTERNAL: u8 = 1;
/// Child type byte of a triangle leaf.
const TYPE_TRIANGLE: u8 = 2;
/// Child type byte of a procedural leaf.
const TYPE_PROCEDURAL: u8 = 3;

/// What a node of the memory image is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum NodeKind {
    /// The 64 B BVH header at address 0.
    Header,
    /// An internal node with quantized child boxes.
    Internal,
    /// A leaf holding one triangle.
    TriangleLeaf,
    /// A leaf holding one procedural sphere.
    ProceduralLeaf,
}

impl NodeKind {
    /// Decodes a child type byte (`None` for empty slots and unknown values).
    pub(super) fn from_type_byte(b: u8) -> Option<NodeKind> {
        match b {
            TYPE_INTERNAL => Some(NodeKind::Internal),
            TYPE_TRIANGLE => Some(NodeKind::TriangleLeaf),
            TYPE_PROCEDURAL => Some(NodeKind::ProceduralLeaf),
            _ => None,
        }
    }
}

/// One node of the image, as listed by [`HwBvh::nodes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeInfo {
    /// Byte address.
    pub addr: u32,
    /// Size in bytes.
    pub bytes: u32,
    /// What the node is.
    pub kind: NodeKind,
    /// Treelet holding the node (`addr / treelet_bytes`).
    pub treelet: u32,
    /// Depth: 0 for the header and the root, 1 for the root's children, and so on.
    pub depth: u32,
}

/// Per-scene BVH statistics.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BvhStats {
    /// Internal nodes.
    pub internal_nodes: u32,
    /// Triangle leaves.
    pub triangle_leaves: u32,
    /// Procedural (sphere) leaves.
    pub procedural_leaves: u32,
    /// Bytes of all nodes including the header.
    pub bvh_bytes: u64,
    /// Number of treelets.
    pub treelets: u32,
    /// Bytes used / (treelets x treelet size).
    pub treelet_fill: f64,
    /// Levels of nodes below the header: 1 for a root with only leaf children.
    pub depth: u32,
    /// Primitives left out of the tree (degenerate or non-finite triangles, invalid spheres).
    pub excluded_prims: u32,
}

impl BvhStats {
    /// All leaves.
    pub fn leaves(&self) -> u32 {
        self.triangle_leaves + self.procedural_leaves
    }
}

/// Reads a little-endian u32 at `off`.
#[inline(always)]
pub(super) fn rd_u32(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

/// Reads a little-endian f32 at `off`.
#[inline(always)]
fn rd_f32(b: &[u8], off: usize) -> f32 {
    f32::from_bits(rd_u32(b, off))
}

/// Reads three f32 at `off`.
#[inline(always)]
fn rd_vec3(b: &[u8], off: usize) -> Vec3 {
    Vec3::new(rd_f32(b, off), rd_f32(b, off + 4), rd_f32(b, off + 8))
}

/// Writes three f32 at `off`.
fn wr_vec3(b: &mut [u8], off: usize, v: Vec3) {
    for (i, x) in v.to_array().into_iter().enumerate() {
        b[off + 4 * i..off + 4 * i + 4].copy_from_slice(&x.to_le_bytes());
    }
}

/// Writes a u32 at `off`.
fn wr_u32(b: &mut [u8], off: usize, v: u32) {
    b[off..off + 4].copy_from_slice(&v.to_le_bytes());
}

/// The scale `2^e` of a stored exponent (clamped to the normal range -126..=127).
#[inline(always)]
pub fn exp_scale(e: i8) -> f32 {
    f32::from_bits((((e as i32) + 127).clamp(1, 254) as u32) << 23)
}

/// Decodes one quantized plane exactly as traversal does: `origin + q * scale` in f32.
#[inline(always)]
pub fn dequantize(origin: f32, scale: f32, q: u8) -> f32 {
    origin + (q as f32) * scale
}

/// Smallest exponent whose 255 steps from `lo` reach `hi` after f32 rounding.
fn choose_exponent(lo: f32, hi: f32) -> i8 {
    let extent = hi as f64 - lo as f64;
    let mut e: i32 = if extent > 0.0 {
        ((extent / 255.0).log2().ceil() as i32 - 1).max(-126)
    } else {
        -126
    };
    while e < 127 && dequantize(lo, exp_scale(e as i8), 255) < hi {
        e += 1;
    }
    e as i8
}

/// Quantizes a child interval `[clo, chi]` on one axis, rounding outward and verified against
/// [`dequantize`]: the decoded interval contains `[clo, chi]` and is the tightest such.
fn quantize_interval(origin: f32, scale: f32, clo: f32, chi: f32) -> (u8, u8) {
    let est = |x: f32| ((x as f64 - origin as f64) / scale as f64).clamp(0.0, 255.0);
    let mut ql = est(clo).floor() as u8;
    while ql > 0 && dequantize(origin, scale, ql) > clo {
        ql -= 1;
    }
    while ql < 255 && dequantize(origin, scale, ql + 1) <= clo {
        ql += 1;
    }
    let mut qh = est(chi).ceil() as u8;
    while qh < 255 && dequantize(origin, scale, qh) < chi {
        qh += 1;
    }
    while qh > 0 && dequantize(origin, scale, qh - 1) >= chi {
        qh -= 1;
    }
    // When steps are below the f32 resolution at `origin`, ql can pass qh; then both decode to
    // the same value (clo == chi) and qh alone describes the interval.
    (ql.min(qh), qh)
}

/// A decoded internal node (borrowing its bytes); this is the decoder traversal uses.
#[derive(Debug, Clone, Copy)]
pub struct InternalView<'a> {
    bytes: &'a [u8],
    pub(super) slots: usize,
    origin: Vec3,
    scale: Vec3,
}

impl<'a> InternalView<'a> {
    /// Views the bytes of an internal node (64 B: 6 slots, 128 B: 8 slots; else `None`).
    #[inline(always)]
    pub fn new(bytes: &'a [u8]) -> Option<Self> {
        let slots = match bytes.len() {
            64 => 6,
            128 => 8,
            _ => return None,
        };
        let origin = rd_vec3(bytes, 0);
        let scale = Vec3::new(
            exp_scale(bytes[16] as i8),
            exp_scale(bytes[17] as i8),
            exp_scale(bytes[18] as i8),
        );
        Some(InternalView {
            bytes,
            slots,
            origin,
            scale,
        })
    }

    /// Number of children.
    #[inline(always)]
    pub fn child_count(&self) -> usize {
        (self.bytes[19] as usize).min(self.slots)
    }

    /// Kind of child `i` (`None` for an empty or unknown slot).
    #[inline(always)]
    pub fn child_kind(&self, i: usize) -> Option<NodeKind> {
        NodeKind::from_type_byte(self.bytes[20 + i])
    }

    /// Address of the first child, given this node's address.
    #[inline(always)]
    pub fn child_base(&self, node_addr: u32) -> u32 {
        node_addr.wrapping_add(rd_u32(self.bytes, 12).wrapping_mul(64))
    }

    /// Size of one child of the given kind.
    #[inline(always)]
    pub fn child_size(&self, kind: NodeKind) -> u32 {
        match kind {
            NodeKind::Internal => self.bytes.len() as u32,
            _ => LEAF_BYTES,
        }
    }

    /// Decodes the boxes of all slots at once (`lo[axis][slot]`, `hi[axis][slot]`) with the
    /// same arithmetic as [`child_box`](Self::child_box); slots past the node's slot count are
    /// left untouched.
    #[inline(always)]
    pub fn decode_boxes(&self, lo: &mut [[f32; 8]; 3], hi: &mut [[f32; 8]; 3]) {
        let s = self.slots;
        let q = &self.bytes[20 + s..20 + 7 * s];
        let origin = self.origin.to_array();
        let scale = self.scale.to_array();
        for a in 0..3 {
            let (ql, qh) = (
                &q[2 * a * s..(2 * a + 1) * s],
                &q[(2 * a + 1) * s..(2 * a + 2) * s],
            );
            for i in 0..s {
                lo[a][i] = dequantize(origin[a], scale[a], ql[i]);
                hi[a][i] = dequantize(origin[a], scale[a], qh[i]);
            }
        }
    }

    /// Decoded (conservative) box of child `i`.
    #[inline(always)]
    pub fn child_box(&self, i: usize) -> (Vec3, Vec3) {
        let s = self.slots;
        let q = |a: usize, hi: usize| self.bytes[20 + s + (2 * a + hi) * s + i];
        let lo = Vec3::new(
            dequantize(self.origin.x, self.scale.x, q(0, 0)),
            dequantize(self.origin.y, self.scale.y, q(1, 0)),
            dequantize(self.origin.z, self.scale.z, q(2, 0)),
        );
        let hi = Vec3::new(
            dequantize(self.origin.x, self.scale.x, q(0, 1)),
            dequantize(self.origin.y, self.scale.y, q(1, 1)),
            dequantize(self.origin.z, self.scale.z, q(2, 1)),
        );
        (lo, hi)
    }
}

/// Decodes a triangle leaf: vertices and global primitive id.
#[inline(always)]
pub fn decode_triangle(bytes: &[u8]) -> ([Vec3; 3], u32) {
    (
        [rd_vec3(bytes, 0), rd_vec3(bytes, 12), rd_vec3(bytes, 24)],
        rd_u32(bytes, 36),
    )
}

/// Decodes a procedural leaf: sphere centre, radius and global primitive id.
#[inline(always)]
pub fn decode_sphere(bytes: &[u8]) -> (Vec3, f32, u32) {
    (rd_vec3(bytes, 0), rd_f32(bytes, 12), rd_u32(bytes, 16))
}

/// The decoded BVH header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// Root node address (0 when the BVH is empty).
    pub root: u32,
    /// Internal node count.
    pub internal_nodes: u32,
    /// Triangle leaf count.
    pub triangle_leaves: u32,
    /// Procedural leaf count.
    pub procedural_leaves: u32,
    /// Treelet count.
    pub treelets: u32,
    /// Treelet size in bytes.
    pub treelet_bytes: u32,
    /// Width.
    pub width: u8,
    /// Internal node size in 64 B units.
    pub internal_units: u8,
    /// Scene bounds, lower corner.
    pub lo: Vec3,
    /// Scene bounds, upper corner.
    pub hi: Vec3,
    /// Primitives left out of the tree.
    pub excluded: u32,
}

impl Header {
    /// Decodes the 64 header bytes.
    pub fn decode(b: &[u8]) -> Header {
        Header {
            root: rd_u32(b, 0),
            internal_nodes: rd_u32(b, 4),
            triangle_leaves: rd_u32(b, 8),
            procedural_leaves: rd_u32(b, 12),
            treelets: rd_u32(b, 16),
            treelet_bytes: rd_u32(b, 20),
            width: b[24],
            internal_units: b[25],
            lo: rd_vec3(b, 28),
            hi: rd_vec3(b, 40),
            excluded: rd_u32(b, 52),
        }
    }

    /// Encodes into 64 bytes.
    fn encode(&self) -> [u8; 64] {
        let mut b = [0u8; 64];
        wr_u32(&mut b, 0, self.root);
        wr_u32(&mut b, 4, self.internal_nodes);
        wr_u32(&mut b, 8, self.triangle_leaves);
        wr_u32(&mut b, 12, self.procedural_leaves);
        wr_u32(&mut b, 16, self.treelets);
        wr_u32(&mut b, 20, self.treelet_bytes);
        b[24] = self.width;
        b[25] = self.internal_units;
        wr_vec3(&mut b, 28, self.lo);
        wr_vec3(&mut b, 40, self.hi);
        wr_u32(&mut b, 52, self.excluded);
        b
    }
}

/// The hardware BVH: a byte-addressed memory image partitioned into treelets.
#[derive(Debug, Clone)]
pub struct HwBvh {
    pub(super) params: BvhParams,
    /// log2(treelet_bytes).
    pub(super) shift: u32,
    /// Used bytes of every treelet, concatenated.
    pub(super) image: Vec<u8>,
    /// Offset in `image` of each treelet's first byte.
    pub(super) slot_offset: Vec<usize>,
    pub(super) treelets: Vec<TreeletInfo>,
    pub(super) nodes: Vec<NodeInfo>,
    pub(super) header: Header,
    pub(super) stats: BvhStats,
}

impl HwBvh {
    /// Builds the BVH of a scene (obvhs binary build, collapse, layout, treelets).
    pub fn build(scene: &Scene, params: &BvhParams) -> Result<HwBvh, BvhError> {
        address_space::preflight(scene, params)?;
        let tree = build_wide_tree(scene, params)?;
        let (treelet_sizes, image) = lay_out(&tree, params)?;
        HwBvh::from_image(*params, &treelet_sizes, image)
    }

    /// The build parameters.
    pub fn params(&self) -> &BvhParams {
        &self.params
    }

    /// Per-scene statistics.
    pub fn stats(&self) -> BvhStats {
        self.stats
    }

    /// The decoded header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Address of the root internal node (0, the header's address, when the BVH is empty).
    pub fn root(&self) -> u32 {
        self.header.root
    }

    /// Whether the BVH holds procedural (sphere) leaves.
    pub fn has_procedural(&self) -> bool {
        self.header.procedural_leaves > 0
    }

    /// Treelet holding an address (`addr / treelet_bytes`).
    #[inline(always)]
    pub fn treelet_of(&self, addr: u32) -> u32 {
        addr >> self.shift
    }

    /// The treelets in address order.
    pub fn treelets(&self) -> &[TreeletInfo] {
        &self.treelets
    }

    /// Every node (header included) in address order.
    pub fn nodes(&self) -> &[NodeInfo] {
        &self.nodes
    }

    /// The node starting at `addr`, if any.
    pub fn node(&self, addr: u32) -> Option<NodeInfo> {
        self.nodes
            .binary_search_by_key(&addr, |n| n.addr)
            .ok()
            .map(|i| self.nodes[i])
    }

    /// The bytes of the node starting at `addr` (`None` if no node starts there).
    pub fn node_bytes(&self, addr: u32) -> Option<&[u8]> {
        self.node(addr).map(|n| self.bytes_at(addr, n.bytes))
    }

    /// `len` bytes at a validated node address (traversal's fast path).
    #[inline(always)]
    pub(crate) fn bytes_at(&self, addr: u32, len: u32) -> &[u8] {
        let t = (addr >> self.shift) as usize;
        let off = self.slot_offset[t] + (addr & (self.params.treelet_bytes - 1)) as usize;
        &self.image[off..off + len as usize]
    }

    /// Asks the host's caches for the image bytes at BVH address `addr` ahead of their use, so
    /// copying a node's bytes into a memory response later does not wait for host memory. A
    /// hint without effect on results; an address outside the image is ignored.
    pub(crate) fn prefetch_bytes(&self, addr: u64) {
        let t = (addr >> self.shift) as usize;
        let Some(&base) = self.slot_offset.get(t) else {
            return;
        };
        let off = base + (addr & (self.params.treelet_bytes as u64 - 1)) as usize;
        if let Some(byte) = self.image.get(off) {
            // SAFETY: a prefetch reads nothing the program sees and cannot fault; SSE, which it
            // needs, is part of every x86_64 target. The pointer is into the image anyway.
            #[cfg(target_arch = "x86_64")]
            unsafe {
                std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                    (byte as *const u8).cast::<i8>(),
                );
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = byte;
        }
    }

    /// Used bytes of each treelet, in order (for serialization).
    pub(crate) fn treelet_sizes(&self) -> Vec<u32> {
        self.treelets.iter().map(|t| t.bytes).collect()
    }

    /// The compact image (used bytes of every treelet, concatenated).
    pub(crate) fn image(&self) -> &[u8] {
        &self.image
    }
}

/// Child type byte of a tree node.
fn type_byte(node: &WideNode) -> u8 {
    match node {
        WideNode::Internal { .. } => TYPE_INTERNAL,
        WideNode::Triangle { .. } => TYPE_TRIANGLE,
        WideNode::Sphere { .. } => TYPE_PROCEDURAL,
    }
}

/// Encodes an internal node whose children start at `child_base`.
fn encode_internal(
    tree: &WideTree,
    (lo, hi, children): (Vec3, Vec3, &[u32]),
    addr: u32,
    child_base: u32,
    ib: u32,
) -> Vec<u8> {
    let slots = if ib == 64 { 6 } else { 8 };
    let mut b = vec![0u8; ib as usize];
    wr_vec3(&mut b, 0, lo);
    wr_u32(&mut b, 12, (child_base - addr) / 64);
    let mut scale = [0f32; 3];
    for a in 0..3 {
        let e = choose_exponent(lo[a], hi[a]);
        b[16 + a] = e as u8;
        scale[a] = exp_scale(e);
    }
    b[19] = children.len() as u8;
    for (i, &c) in children.iter().enumerate() {
        let child = &tree.nodes[c as usize];
        b[20 + i] = type_byte(child);
        let (clo, chi) = child.bounds();
        for a in 0..3 {
            let (ql, qh) = quantize_interval(lo[a], scale[a], clo[a], chi[a]);
            b[20 + slots + 2 * a * slots + i] = ql;
            b[20 + slots + (2 * a + 1) * slots + i] = qh;
        }
    }
    b
}

/// Encodes a triangle leaf.
fn encode_triangle(verts: &[Vec3; 3], prim: u32) -> Vec<u8> {
    let mut b = vec![0u8; LEAF_BYTES as usize];
    for (i, v) in verts.iter().enumerate() {
        wr_vec3(&mut b, 12 * i, *v);
    }
    wr_u32(&mut b, 36, prim);
    b
}

/// Encodes a procedural (sphere) leaf.
fn encode_sphere(center: Vec3, radius: f32, prim: u32) -> Vec<u8> {
    let mut b = vec![0u8; LEAF_BYTES as usize];
    wr_vec3(&mut b, 0, center);
    b[12..16].copy_from_slice(&radius.to_le_bytes());
    wr_u32(&mut b, 16, prim);
    b
}

/// Places the tree's nodes into treelets and encodes the compact image.
/// Returns the used bytes of each treelet and the image.
fn lay_out(tree: &WideTree, params: &BvhParams) -> Result<(Vec<u32>, Vec<u8>), BvhError> {
    let ib = params.internal_node_bytes();
    let tb = params.treelet_bytes;
    let parts = treelet::partition(tree, ib, tb, params.formation);
    address_space::check(parts.len(), params)?;
    // Addresses: node index -> address; child group of node -> address of its first child.
    let mut addr = vec![0u32; tree.nodes.len()];
    let mut group_addr = vec![0u32; tree.nodes.len()];
    let mut sizes = Vec::with_capacity(parts.len());
    for (t, units) in parts.iter().enumerate() {
        let base = (t as u64 * tb as u64) as u32;
        let mut cur = base;
        for &u in units {
            match u {
                Unit::Root => {
                    cur += HEADER_BYTES;
                    if !tree.nodes.is_empty() {
                        addr[0] = cur;
                        cur += ib;
                    }
                }
                Unit::Children(n) => {
                    group_addr[n as usize] = cur;
                    if let WideNode::Internal { children, .. } = &tree.nodes[n as usize] {
                        for &c in children {
                            addr[c as usize] = cur;
                            cur += treelet::node_size(&tree.nodes[c as usize], ib);
                        }
                    }
                }
            }
        }
        sizes.push(cur - base);
    }
    let count = |f: fn(&WideNode) -> bool| tree.nodes.iter().filter(|n| f(n)).count() as u32;
    let (lo, hi) = tree
        .nodes
        .first()
        .map(|n| n.bounds())
        .unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let header = Header {
        root: if tree.nodes.is_empty() { 0 } else { addr[0] },
        internal_nodes: count(|n| matches!(n, WideNode::Internal { .. })),
        triangle_leaves: count(|n| matches!(n, WideNode::Triangle { .. })),
        procedural_leaves: count(|n| matches!(n, WideNode::Sphere { .. })),
        treelets: parts.len() as u32,
        treelet_bytes: tb,
        width: params.width as u8,
        internal_units: (ib / 64) as u8,
        lo,
        hi,
        excluded: tree.excluded,
    };
    let mut image = Vec::with_capacity(sizes.iter().map(|&s| s as usize).sum());
    for units in &parts {
        for &u in units {
            let put = |image: &mut Vec<u8>, n: usize| {
                let node = &tree.nodes[n];
                let bytes = match node {
                    WideNode::Internal { lo, hi, children } => {
                        encode_internal(tree, (*lo, *hi, children), addr[n], group_addr[n], ib)
                    }
                    WideNode::Triangle { prim, verts } => encode_triangle(verts, *prim),
                    WideNode::Sphere {
                        prim,
                        center,
                        radius,
                    } => encode_sphere(*center, *radius, *prim),
                };
                image.extend_from_slice(&bytes);
            };
            match u {
                Unit::Root => {
                    image.extend_from_slice(&header.encode());
                    if !tree.nodes.is_empty() {
                        put(&mut image, 0);
                    }
                }
                Unit::Children(n) => {
                    if let WideNode::Internal { children, .. } = &tree.nodes[n as usize] {
                        for &c in children {
                            put(&mut image, c as usize);
                        }
                    }
                }
            }
        }
    }
    Ok((sizes, image))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Encodes one axis the way internal nodes do and checks the decoded interval.
    fn check_axis(lo: f32, hi: f32, clo: f32, chi: f32) -> Result<(), TestCaseError> {
        let e = choose_exponent(lo, hi);
        prop_assert!((-126..=127).contains(&(e as i32)));
        let scale = exp_scale(e);
        prop_assert!(dequantize(lo, scale, 255) >= hi);
        let (ql, qh) = quantize_interval(lo, scale, clo, chi);
        prop_assert!(ql <= qh);
        prop_assert!(dequantize(lo, scale, ql) <= clo, "lo plane above the child");
        prop_assert!(dequantize(lo, scale, qh) >= chi, "hi plane below the child");
        // Tightest: a plane is exact, or one step inward would no longer contain the child.
        let (dl, dh) = (dequantize(lo, scale, ql), dequantize(lo, scale, qh));
        prop_assert!(dl == clo || dequantize(lo, scale, ql + 1) > clo);
        prop_assert!(dh == chi || dequantize(lo, scale, qh - 1) < chi);
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Containment across magnitudes from 1e-30 to 1e18 and arbitrary child placement.
        #[test]
        fn quantization_is_conservative_and_tight(
            center_exp in -30i32..18,
            extent_exp in -30i32..18,
            center_mant in -1.0f32..1.0,
            a in 0.0f32..=1.0,
            b in 0.0f32..=1.0,
        ) {
            let c = center_mant * 10f32.powi(center_exp);
            let ext = 10f32.powi(extent_exp);
            let (lo, hi) = (c - ext, c + ext);
            prop_assert!(lo <= hi && lo.is_finite() && hi.is_finite());
            let span = hi - lo;
            let x = (lo + a.min(b) * span).clamp(lo, hi);
            let y = (lo + a.max(b) * span).clamp(lo, hi);
            check_axis(lo, hi, x, y)?;
            check_axis(lo, hi, lo, hi)?;
            check_axis(lo, hi, hi, hi)?;
        }
    }

    #[test]
    fn flat_axis_uses_zero_steps() {
        let (ql, qh) = quantize_interval(3.5, exp_scale(choose_exponent(3.5, 3.5)), 3.5, 3.5);
        assert_eq!((ql, qh), (0, 0));
    }

    #[test]
    fn exponent_scale_is_a_power_of_two() {
        assert_eq!(exp_scale(0), 1.0);
        assert_eq!(exp_scale(-3), 0.125);
        assert_eq!(exp_scale(10), 1024.0);
        assert_eq!(exp_scale(i8::MIN), exp_scale(-126));
    }
}
