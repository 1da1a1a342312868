//! What the RT unit's control knows about BVH nodes: node references as held on the traversal
//! stacks, the intersection latency of each node kind, and the interface to the (external,
//! combinational) intersection datapath that decides which children a ray visits.

use super::RtUnitError;
use serde::{Deserialize, Serialize};

/// Bytes of one memory request and of one response chunk (the RT unit's access granularity).
pub const CHUNK_BYTES: u32 = 32;

/// Mask of the byte-offset bits within a chunk (an address is chunk aligned when these are 0).
pub const CHUNK_MASK: u64 = CHUNK_BYTES as u64 - 1;

/// Largest node the RT unit fetches, in 32 B chunks (a 128 B instance leaf, Vulkan-Sim layout).
pub const MAX_NODE_CHUNKS: usize = 4;

/// Stack entries in one 32 B spill chunk: four 64-bit slots, bottom entry first (see
/// [`pack_spill_chunk`]).
pub const STACK_ENTRIES_PER_CHUNK: usize = 4;

/// 32-bit words of a ray record: origin xyz, direction xyz, tmin, tmax (32 B, paper section 6.5).
pub const RAY_WORDS: usize = 8;

/// Index of the tmin word in [`RayWords`].
pub const TMIN_WORD: usize = 6;

/// Index of the tmax word in [`RayWords`] (a hit lowers it).
pub const TMAX_WORD: usize = 7;

/// A ray's geometry as raw 32-bit words (f32 bit patterns), in the order of [`RAY_WORDS`].
pub type RayWords = [u32; RAY_WORDS];

/// The kind of a BVH node, as encoded by its parent (Intel/Vulkan-Sim layout); it selects the
/// intersection test and its latency.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default, Serialize, Deserialize,
)]
pub enum NodeKind {
    /// BVH header (top of an acceleration structure).
    Header,
    /// Internal node: a box test of its children.
    #[default]
    Internal,
    /// Instance leaf: transforms the ray into a bottom-level structure.
    InstanceLeaf,
    /// Primitive-leaf descriptor.
    PrimitiveDescriptor,
    /// Triangle (quad) leaf: a ray/triangle test.
    TriangleLeaf,
    /// Procedural leaf: a ray/procedural-primitive test.
    Procedural,
}

impl NodeKind {
    /// Every kind, in encoding order (kind `k` is encoded as its index here).
    pub const ALL: [NodeKind; 6] = [
        NodeKind::Header,
        NodeKind::Internal,
        NodeKind::InstanceLeaf,
        NodeKind::PrimitiveDescriptor,
        NodeKind::TriangleLeaf,
        NodeKind::Procedural,
    ];

    /// Bits of the kind field of a stack entry.
    pub const BITS: u32 = 3;

    /// The kind's encoding (its index in [`NodeKind::ALL`]).
    pub fn code(self) -> u64 {
        NodeKind::ALL.iter().position(|&k| k == self).unwrap_or(0) as u64
    }

    /// snake_case name, used for statistics and signal names.
    pub fn name(self) -> &'static str {
        match self {
            NodeKind::Header => "header",
            NodeKind::Internal => "internal",
            NodeKind::InstanceLeaf => "instance_leaf",
            NodeKind::PrimitiveDescriptor => "primitive_descriptor",
            NodeKind::TriangleLeaf => "triangle_leaf",
            NodeKind::Procedural => "procedural",
        }
    }
}

/// A reference to a node to visit: what a traversal-stack entry and the node in flight hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct NodeEntry {
    /// Byte address of the node (32 B aligned).
    pub address: u64,
    /// Kind of the node (decides the test and its latency).
    pub kind: NodeKind,
    /// Size in 32 B chunks, 1..=[`MAX_NODE_CHUNKS`] (a 64 B node is 2 chunks).
    pub chunks: u8,
}

impl NodeEntry {
    /// A node of `bytes` bytes (32, 64, 96 or 128) at a 32 B aligned `address`.
    pub fn new(address: u64, kind: NodeKind, bytes: u32) -> Result<Self, RtUnitError> {
        let chunks = bytes / CHUNK_BYTES;
        if bytes & (CHUNK_BYTES - 1) != 0 || chunks == 0 || chunks as usize > MAX_NODE_CHUNKS {
            return Err(RtUnitError::BadNode {
                address,
                reason: format!("size {bytes} B is not 32, 64, 96 or 128"),
            });
        }
        if address & CHUNK_MASK != 0 {
            return Err(RtUnitError::BadNode {
                address,
                reason: "address is not 32 B aligned".into(),
            });
        }
        Ok(NodeEntry {
            address,
            kind,
            chunks: chunks as u8,
        })
    }

    /// Size of the node in bytes.
    pub fn bytes(&self) -> u32 {
        self.chunks as u32 * CHUNK_BYTES
    }

    /// Bits of a stack entry for `address_bits`-bit addresses: address, kind, chunks - 1.
    pub fn bits(address_bits: u32) -> u32 {
        address_bits + NodeKind::BITS + 2
    }

    /// The entry packed as stored in a stack: `{address, kind, chunks - 1}`, address in the high bits.
    pub fn encode(&self) -> u64 {
        (self.address << (NodeKind::BITS + 2))
            | (self.kind.code() << 2)
            | (self.chunks.saturating_sub(1) as u64 & 3)
    }

    /// The entry as a 64-bit slot of a spill chunk: a valid bit (bit 63) over [`encode`]
    /// (an empty slot is all zeros).
    ///
    /// [`encode`]: NodeEntry::encode
    pub fn spill_word(&self) -> u64 {
        1 << 63 | self.encode()
    }

    /// The entry of a spill-chunk slot, `None` for an empty slot or an undefined kind code.
    pub fn from_spill_word(word: u64) -> Option<NodeEntry> {
        if word >> 63 == 0 {
            return None;
        }
        let fields = word & !(1 << 63);
        let kind = *NodeKind::ALL.get(((fields >> 2) & 7) as usize)?;
        Some(NodeEntry {
            address: fields >> (NodeKind::BITS + 2),
            kind,
            chunks: (fields & 3) as u8 + 1,
        })
    }
}

/// Packs up to [`STACK_ENTRIES_PER_CHUNK`] stack entries (bottom first) into a 32 B spill
/// chunk: little-endian 64-bit slots ([`NodeEntry::spill_word`]), unused slots zero.
pub fn pack_spill_chunk(entries: &[NodeEntry]) -> [u8; CHUNK_BYTES as usize] {
    debug_assert!(entries.len() <= STACK_ENTRIES_PER_CHUNK);
    let mut data = [0u8; CHUNK_BYTES as usize];
    for (slot, e) in data.chunks_exact_mut(8).zip(entries) {
        slot.copy_from_slice(&e.spill_word().to_le_bytes());
    }
    data
}

/// The stack entries of a 32 B spill chunk, bottom first, up to the first empty slot.
pub fn unpack_spill_chunk(data: &[u8; CHUNK_BYTES as usize]) -> Vec<NodeEntry> {
    data.chunks_exact(8)
        .map_while(|slot| {
            let mut bytes = [0u8; 8];
            bytes.copy_from_slice(slot);
            NodeEntry::from_spill_word(u64::from_le_bytes(bytes))
        })
        .collect()
}

/// Intersection-test latencies in cycles per node kind, from Vulkan-Sim's RT-unit model (the
/// public Vulkan-Sim treelet-prefetching configuration): header 2, internal 4, instance leaf 4,
/// primitive-leaf descriptor 2, triangle (quad) leaf 4, triangle hit 4, procedural 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Latencies {
    /// BVH header.
    pub header: u32,
    /// Internal node (box tests of all children in parallel).
    pub internal: u32,
    /// Instance leaf.
    pub instance_leaf: u32,
    /// Primitive-leaf descriptor.
    pub primitive_descriptor: u32,
    /// Triangle leaf whose triangle is missed.
    pub triangle_leaf: u32,
    /// Triangle leaf whose triangle is hit (replaces `triangle_leaf`; the hit also writes a 32 B
    /// hit record).
    pub triangle_hit: u32,
    /// Procedural leaf.
    pub procedural: u32,
}

impl Default for Latencies {
    fn default() -> Self {
        Latencies {
            header: 2,
            internal: 4,
            instance_leaf: 4,
            primitive_descriptor: 2,
            triangle_leaf: 4,
            triangle_hit: 4,
            procedural: 4,
        }
    }
}

impl Latencies {
    /// Latency of a test of a `kind` node; `hit` selects the triangle-hit latency for a
    /// triangle leaf whose test reported a hit.
    pub fn of(&self, kind: NodeKind, hit: bool) -> u32 {
        match kind {
            NodeKind::Header => self.header,
            NodeKind::Internal => self.internal,
            NodeKind::InstanceLeaf => self.instance_leaf,
            NodeKind::PrimitiveDescriptor => self.primitive_descriptor,
            NodeKind::TriangleLeaf if hit => self.triangle_hit,
            NodeKind::TriangleLeaf => self.triangle_leaf,
            NodeKind::Procedural => self.procedural,
        }
    }

    /// The largest latency (sets the width of the intersection-delay counters).
    pub fn max(&self) -> u32 {
        self.all().into_iter().map(|(_, v)| v).max().unwrap_or(0)
    }

    /// Every latency with its name.
    fn all(&self) -> [(&'static str, u32); 7] {
        [
            ("header", self.header),
            ("internal", self.internal),
            ("instance_leaf", self.instance_leaf),
            ("primitive_descriptor", self.primitive_descriptor),
            ("triangle_leaf", self.triangle_leaf),
            ("triangle_hit", self.triangle_hit),
            ("procedural", self.procedural),
        ]
    }

    /// Every latency must be 1..=255 cycles.
    pub fn validate(&self) -> Result<(), RtUnitError> {
        for (name, v) in self.all() {
            if !(1..=255).contains(&v) {
                return Err(RtUnitError::BadParam {
                    name: "latencies",
                    value: v as u64,
                    reason: format!("{name} latency must be 1..=255 cycles"),
                });
            }
        }
        Ok(())
    }
}

/// A closest-hit update reported by a leaf test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Hit {
    /// Hit distance (f32 bit pattern). The ray's words keep their original tmax; the closest
    /// hit so far is passed back to the datapath for culling.
    pub t: u32,
    /// Identifier of the primitive hit (written to the hit record).
    pub hit_id: u32,
    /// Two attribute words of the hit record (e.g. barycentrics u, v as f32 bits).
    pub attribs: [u32; 2],
}

impl Hit {
    /// Pushes the 128 bits a hit takes on the ports onto `p`, lowest first: t, the hit id and
    /// the two attributes (zeros for `None`).
    pub fn pack(hit: Option<&Hit>, p: &mut crate::bits::BitPacker) {
        let h = hit.copied().unwrap_or_default();
        for v in [h.t, h.hit_id, h.attribs[0], h.attribs[1]] {
            p.push(v as u64, 32);
        }
    }
}

/// What one node test decided for one ray.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct TestResult {
    /// Children to visit, in visit order (the first is visited first).
    pub children: Vec<NodeEntry>,
    /// A candidate hit, if the node is a leaf the ray hits within its `[tmin, tmax]` and not
    /// beyond the closest hit so far; the RT unit keeps it only if `(t, hit_id)` is
    /// lexicographically smaller than that hit's (smallest `t`, ties to the smaller id).
    pub hit: Option<Hit>,
}

/// The RT unit's intersection datapath (box, triangle, procedural tests), supplied by the
/// block's user: the simulator plugs in the real BVH decoder, tests plug in a toy tree.
///
/// It models combinational logic whose result is ready after the latency of
/// [`Latencies::of`]; it must be a pure function of its arguments (no interior mutability), so
/// that [`crate::Block::eval`] stays pure and deterministic.
pub trait NodeDatapath {
    /// Tests the ray `ray` (its original words) against `node`, whose `node.bytes()` bytes
    /// (all chunks, in address order) are `data`; `best` is the ray's closest hit so far (box
    /// tests cull against it).
    fn test(&self, ray: &RayWords, best: Option<&Hit>, node: &NodeEntry, data: &[u8])
        -> TestResult;
}

/// A datapath that visits nothing and hits nothing: for building blocks only to describe them
/// (the datapath is outside the RT unit and not part of its description).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NoDatapath;

impl NodeDatapath for NoDatapath {
    fn test(&self, _: &RayWords, _: Option<&Hit>, _: &NodeEntry, _: &[u8]) -> TestResult {
        TestResult::default()
    }
}

impl<T: NodeDatapath + ?Sized> NodeDatapath for &T {
    fn test(
        &self,
        ray: &RayWords,
        best: Option<&Hit>,
        node: &NodeEntry,
        data: &[u8],
    ) -> TestResult {
        (**self).test(ray, best, node, data)
    }
}

impl Hit {
    /// Whether this hit beats `other`: smaller `t` (as f32), ties broken by the smaller hit id.
    pub fn closer_than(&self, other: &Hit) -> bool {
        let (a, b) = (f32::from_bits(self.t), f32::from_bits(other.t));
        a < b || (a == b && self.hit_id < other.hit_id)
    }
}
