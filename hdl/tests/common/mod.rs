//! Shared by the RT unit's and the treelet RT unit's tests: a toy node format with its
//! intersection datapath, and a BVH memory of such nodes.

// Each test binary compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use std::collections::BTreeMap;
use vtq_hdl::bits::fits;
use vtq_hdl::rt_unit::{Hit, NodeDatapath, NodeEntry, NodeKind, RayWords, TestResult};
use vtq_hdl::Signal;

/// Last byte of every toy node; a node assembled from wrong or missing chunks lacks it.
pub const MAGIC: u8 = 0xA5;
/// Child mask selecting every ray.
pub const ALL: u8 = 0xFF;

/// Toy node format: byte 0 child count, byte 1 hit flag, children from byte 4 as 8 bytes each
/// (address u32 LE, kind code, size in chunks, lane mask, 0), last byte [`MAGIC`]. A child is
/// visited by a ray when bit `ray[0]` of its mask is set; a hit reports t = 0.5 and the node's
/// address as hit id.
#[derive(Debug)]
pub struct ToyDatapath;

impl NodeDatapath for ToyDatapath {
    fn test(
        &self,
        ray: &RayWords,
        _best: Option<&Hit>,
        node: &NodeEntry,
        data: &[u8],
    ) -> TestResult {
        if data.len() != node.bytes() as usize || data.last() != Some(&MAGIC) {
            return TestResult::default();
        }
        let select = 1u8 << (ray[0] & 7);
        let children = (0..data[0] as usize)
            .map(|i| &data[4 + 8 * i..12 + 8 * i])
            .filter(|c| c[6] & select != 0)
            .map(|c| NodeEntry {
                address: u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u64,
                kind: NodeKind::ALL[c[4] as usize],
                chunks: c[5],
            })
            .collect();
        let hit = (data[1] != 0).then(|| Hit {
            t: 0.5f32.to_bits(),
            hit_id: node.address as u32,
            attribs: [1, 2],
        });
        TestResult { children, hit }
    }
}

/// A node reference (panics on a bad one: test trees are made by hand).
pub fn node(address: u64, kind: NodeKind, bytes: u32) -> NodeEntry {
    NodeEntry::new(address, kind, bytes).unwrap()
}

/// BVH memory of toy nodes, by 32 B chunk address.
#[derive(Default, Clone)]
pub struct Tree {
    /// The chunks.
    pub chunks: BTreeMap<u64, [u8; 32]>,
}

impl Tree {
    /// Stores node `n` with its hit flag and `(child, ray mask)` children.
    pub fn add(&mut self, n: NodeEntry, hit: bool, children: &[(NodeEntry, u8)]) -> &mut Self {
        let mut bytes = vec![0u8; n.bytes() as usize];
        bytes[0] = children.len() as u8;
        bytes[1] = hit as u8;
        for (i, (c, mask)) in children.iter().enumerate() {
            let at = 4 + 8 * i;
            bytes[at..at + 4].copy_from_slice(&(c.address as u32).to_le_bytes());
            bytes[at + 4] = c.kind.code() as u8;
            bytes[at + 5] = c.chunks;
            bytes[at + 6] = *mask;
        }
        *bytes.last_mut().unwrap() = MAGIC;
        for (k, chunk) in bytes.chunks_exact(32).enumerate() {
            self.chunks
                .insert(n.address + 32 * k as u64, chunk.try_into().unwrap());
        }
        self
    }
}

/// Ray words selecting child-mask bit `select`.
pub fn words(select: u32) -> RayWords {
    let mut w = [0u32; 8];
    w[0] = select;
    w[7] = 1000f32.to_bits();
    w
}

/// Asserts every one of `signals` fits its width; a failure names the signal after `when`.
pub fn assert_signals_fit<'a>(signals: impl IntoIterator<Item = &'a Signal>, when: &str) {
    for s in signals {
        assert!(
            fits(s.value, s.width),
            "{when}{} = {:#x} does not fit {} bits",
            s.name,
            s.value,
            s.width
        );
    }
}
