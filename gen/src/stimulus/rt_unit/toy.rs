//! The toy node format of the RT unit's co-simulation: its intersection datapath
//! ([`ToyDatapath`], specified byte for byte so that a Verilog twin can be written from it,
//! `vtq_gen::rtl::toy_datapath_verilog`), node images, and the toy BVH the environment builds.

use super::super::Rng;
use crate::error::GenError;
use std::collections::HashMap;
use vtq_hdl::rt_unit::{
    spill_area, Hit, NodeDatapath, NodeEntry, NodeKind, RayWords, RtUnitParams, TestResult,
    CHUNK_BYTES,
};
use vtq_hdl::HwConfig;

/// The last byte of every well-formed toy node.
pub const TOY_MAGIC: u8 = 0xA5;

/// A toy intersection datapath reading nodes of this format (`n` = `node.bytes()`): byte 0
/// the child count, byte 1 the hit flag (nonzero: the node reports a hit), bytes 2..4 the top
/// 16 bits of the hit's t (little endian), from byte 4 the child records of 8 bytes each
/// (address u32 little endian, kind code, chunks as stored, ray mask, unused byte), and
/// [`TOY_MAGIC`] as byte `n - 1`.
///
/// A test of a node whose data is not `n` bytes or does not end with the magic byte finds
/// nothing. Otherwise the first `min(count, (n - 5) / 8)` records are read in order, and a
/// child is kept when its mask has bit `ray[0] & 7` set (the ray's class) and its kind code is
/// below 6: `NodeEntry { address, kind: NodeKind::ALL[code], chunks }`, unchecked, so the RT
/// unit sees bad children. With the hit flag the node reports `Hit { t: top << 16, hit_id:
/// node address, attribs: [ray[0], node address ^ 0x5555_5555] }`. The closest hit so far is
/// ignored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ToyDatapath;

impl NodeDatapath for ToyDatapath {
    fn test(
        &self,
        ray: &RayWords,
        _best: Option<&Hit>,
        node: &NodeEntry,
        data: &[u8],
    ) -> TestResult {
        let n = node.bytes() as usize;
        if n == 0 || data.len() != n || data[n - 1] != TOY_MAGIC {
            return TestResult::default();
        }
        let select = 1u8 << (ray[0] & 7);
        let cap = (n - 5) / 8;
        let children = data[4..]
            .chunks_exact(8)
            .take((data[0] as usize).min(cap))
            .filter(|c| c[6] & select != 0 && c[4] < 6)
            .map(|c| NodeEntry {
                address: u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u64,
                kind: NodeKind::ALL[c[4] as usize],
                chunks: c[5],
            })
            .collect();
        let hit = (data[1] != 0).then(|| Hit {
            t: (u16::from_le_bytes([data[2], data[3]]) as u32) << 16,
            hit_id: node.address as u32,
            attribs: [ray[0], node.address as u32 ^ 0x5555_5555],
        });
        TestResult { children, hit }
    }
}

/// One child record of a toy node ([`toy_node_bytes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ToyChild {
    /// Byte address of the child.
    pub address: u32,
    /// Kind code: the index in [`NodeKind::ALL`]; 6 and 7 make the datapath skip the record.
    pub kind: u8,
    /// Size in 32 B chunks, as stored (the RT unit rejects 0 and above 4).
    pub chunks: u8,
    /// The ray classes (`ray[0] & 7`) that visit the child, one bit each.
    pub mask: u8,
}

/// The bytes of a toy node of `chunks` chunks (1..=4) in [`ToyDatapath`]'s format: child count
/// `children.len()`, the records that fit (at most `(32 chunks - 5) / 8`, so a count above that
/// is cut by the datapath), the hit flag with t's top 16 bits when `hit_t` is given, and
/// [`TOY_MAGIC`] last.
pub fn toy_node_bytes(chunks: u8, hit_t: Option<u16>, children: &[ToyChild]) -> Vec<u8> {
    let n = chunks as usize * CHUNK_BYTES as usize;
    let mut b = vec![0u8; n];
    b[0] = children.len() as u8;
    if let Some(t) = hit_t {
        b[1] = 1;
        b[2..4].copy_from_slice(&t.to_le_bytes());
    }
    for (rec, c) in b[4..n - 1].chunks_exact_mut(8).zip(children) {
        rec[..4].copy_from_slice(&c.address.to_le_bytes());
        rec[4] = c.kind;
        rec[5] = c.chunks;
        rec[6] = c.mask;
    }
    b[n - 1] = TOY_MAGIC;
    b
}

/// The memory: node chunks and spilled stack chunks by address.
pub(super) type Memory = HashMap<u64, [u8; 32]>;

/// The toy BVH: node references in address order, those without children, and the roots.
pub(super) struct Tree {
    pub(super) nodes: Vec<NodeEntry>,
    pub(super) leaves: Vec<NodeEntry>,
    pub(super) roots: Vec<NodeEntry>,
}

/// Kind codes of nodes without children (mostly triangle leaves) and with (mostly internal).
const KINDS: [[u8; 8]; 2] = [[4, 4, 4, 4, 5, 3, 2, 0], [1, 1, 1, 1, 1, 1, 2, 0]];

/// Builds the toy BVH into `mem` between the hit records and the spill area: 40–120 nodes in
/// trees of at most 4 levels (a fifth of the inner nodes with `max_children` children every
/// ray visits, the others 1–3 children each visited by half the ray classes), laid out in
/// preorder (so a first child often shares its
/// parent's treelet; children lie at higher addresses). A few nodes hold bad child records,
/// records of kind 6 or 7, or more children than `max_children`, 2% a wrong magic byte, 30% a
/// hit; the bad and surplus records are visited by the ray class 7 only.
pub(super) fn build_tree(
    rng: &mut Rng,
    cfg: &HwConfig,
    params: &RtUnitParams,
    mem: &mut Memory,
) -> Result<Tree, GenError> {
    let lo = (params.hit_record_base + cfg.max_rays as u64 * 32 + 31) & !31;
    let hi = spill_area(cfg, params).0.min(1 << 32);
    let n = (40 + rng.below(81)).min(hi.saturating_sub(lo) / 224) as usize;
    if n < 8 {
        return Err(GenError::Cosim {
            block: "rt_unit".into(),
            reason: format!("no room for a toy BVH between {lo:#x} and {hi:#x}"),
        });
    }
    // The structure, breadth first: parentless nodes are roots.
    let mc = params.max_children as usize;
    let (mut kids, mut level, mut root) = (vec![Vec::new(); n], vec![0; n], vec![true; n]);
    let mut wide = vec![false; n];
    let mut next = (n / 16).max(2);
    for i in 0..n {
        next = next.max(i + 1);
        if level[i] < 3 && next < n && !rng.chance(15) {
            // A fifth of the nodes are wide: max_children children every ray visits, so
            // stacks grow past their window (the RTL's SRAM ring) and up to a spill.
            wide[i] = rng.chance(20);
            let k = if wide[i] {
                mc
            } else {
                1 + rng.below(3) as usize
            };
            let k = k.min(n - next).min(mc);
            kids[i] = (next..next + k).collect();
            for c in next..next + k {
                (level[c], root[c]) = (level[i] + 1, false);
            }
            next += k;
        }
    }
    let mut order = Vec::with_capacity(n);
    for r in (0..n).filter(|&i| root[i]) {
        let mut stack = vec![r];
        while let Some(x) = stack.pop() {
            order.push(x);
            stack.extend(kids[x].iter().rev());
        }
    }
    let mut pos = vec![0; n];
    for (p, &x) in order.iter().enumerate() {
        pos[x] = p;
    }
    // In preorder: surplus and bad records, size (room for every record), kind, address.
    let (mut nodes, mut extra, mut cur) = (Vec::with_capacity(n), Vec::with_capacity(n), lo);
    for &x in &order {
        let surplus = (!kids[x].is_empty() && mc < 15 && rng.chance(3)) as usize;
        let surplus = surplus * (mc + 1 - kids[x].len());
        let bad = usize::from(rng.chance(8)) + usize::from(rng.chance(4));
        let records = kids[x].len() + surplus + bad;
        let need = (1..=4).find(|&c| (32 * c - 5) / 8 >= records).unwrap_or(4);
        let chunks = need.max(1 + rng.below(4) as usize) as u8;
        let code = KINDS[usize::from(!kids[x].is_empty())][rng.below(8) as usize];
        let kind = NodeKind::ALL[code as usize];
        if rng.chance(30) {
            cur += 32 * (1 + rng.below(3));
        }
        nodes.push(NodeEntry {
            address: cur,
            kind,
            chunks,
        });
        extra.push((surplus, bad));
        cur += chunks as u64 * 32;
    }
    let top = 1u64 << cfg.address_bits;
    let mut ts: Vec<u16> = Vec::new();
    for (p, (&x, &node)) in order.iter().zip(&nodes).enumerate() {
        let record = |e: &NodeEntry, mask| {
            let (address, kind, chunks) = (e.address as u32, e.kind.code() as u8, e.chunks);
            ToyChild {
                address,
                kind,
                chunks,
                mask,
            }
        };
        let mut recs: Vec<ToyChild> = kids[x]
            .iter()
            .map(|&c| {
                let mask = if wide[x] { 0xFF } else { rng.below(256) as u8 };
                record(&nodes[pos[c]], mask)
            })
            .collect();
        let cap = (node.bytes() as usize - 5) / 8;
        let (surplus, bad) = extra[p];
        if surplus > 0 && p + 1 < n {
            // For the class 7 every record is kept: the test returns too many children.
            recs.iter_mut().for_each(|r| r.mask |= 0x80);
            for _ in 0..surplus.min(cap - recs.len()) {
                let other = nodes[p + 1 + rng.below((n - p - 1) as u64) as usize];
                recs.push(record(&other, 0x80));
            }
        }
        for _ in 0..bad.min(cap - recs.len()) {
            let mut r = record(&node, 0x80);
            match rng.below(6) {
                0 => r.chunks = 0,
                1 => r.chunks = 5,
                2 if cfg.address_bits < 32 => r.address = (top + 32 * rng.below(8)) as u32,
                3 if cfg.address_bits <= 32 => (r.address, r.chunks) = ((top - 32) as u32, 2),
                4 => (r.kind, r.mask) = (6 + rng.below(2) as u8, 0xFF),
                _ => r.address += 16,
            }
            recs.insert(rng.below(recs.len() as u64 + 1) as usize, r);
        }
        let hit = rng.chance(30).then(|| match rng.below(10) {
            0..=2 => [0x0000, 0x8000, 0x7FC0, 0x7F80, 0xBF80][rng.below(5) as usize],
            3..=4 if !ts.is_empty() => ts[rng.below(ts.len() as u64) as usize],
            _ => rng.below(1 << 16) as u16,
        });
        ts.extend(hit);
        let mut bytes = toy_node_bytes(node.chunks, hit, &recs);
        if rng.chance(2) {
            bytes[node.bytes() as usize - 1] = !TOY_MAGIC;
        }
        for (k, chunk) in bytes.chunks_exact(32).enumerate() {
            let chunk = chunk.try_into().unwrap_or([0; 32]);
            mem.insert(node.address + 32 * k as u64, chunk);
        }
    }
    let pick = |keep: &dyn Fn(usize) -> bool| -> Vec<NodeEntry> {
        (0..n).filter(|&x| keep(x)).map(|x| nodes[pos[x]]).collect()
    };
    Ok(Tree {
        leaves: pick(&|x| kids[x].is_empty()),
        roots: pick(&|x| root[x]),
        nodes,
    })
}
