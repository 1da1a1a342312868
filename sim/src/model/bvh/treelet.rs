//! Treelets: the BVH split into subtrees of at most `treelet_bytes` bytes (paper sections 2.3,
//! 4.2 and 6.5; formation as in the treelet-prefetching code).
//!
//! Formation is a greedy breadth-first fill from the root, by bytes. The unit of placement is a
//! *child group* (all children of one internal node, stored contiguously); the first unit is
//! the BVH header plus the root node. Units are taken from the front of a FIFO frontier; placing
//! a unit appends the child groups of its internal nodes to the frontier. When the unit at the
//! front does not fit in the remaining space, the treelet is closed and every unit still in the
//! frontier becomes the root of a pending treelet (FIFO order).
//!
//! That rule ([`TreeletFormation::BreadthFirst`], the treelet-prefetching code's) leaves most
//! slots nearly empty: the frontier of a closed treelet is wide, and the subtrees near the leaves
//! that its units root are small (the shared scenes' treelets are 6-11% full).
//! [`TreeletFormation::Packed`] forms the same treelets, then packs consecutive ones (in
//! formation order, so siblings share a slot) into one slot while their bytes fit (next fit).
//! A slot then holds several subtrees, and a ray may enter it more than once: subtrees of one
//! slot can hang below different slots, and a ray that finished the slot through one subtree
//! meets another one later (the treelet order finishes the nodes of a slot it knows of, not those
//! it has yet to reach). Each subtree is still entered at most once per ray, at its root (tested
//! in `sim/tests/bvh_props.rs`); with breadth-first formation a slot is one subtree, so it is
//! entered at most once.
//!
//! Treelet `i` occupies the `treelet_bytes`-aligned slot starting at address
//! `i * treelet_bytes`, so a node's treelet is `addr / treelet_bytes` (the paper's 19-bit
//! treelet addresses for 8 KB treelets and 32-bit addresses). Only the used bytes of each slot
//! are stored.

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

use super::build::{WideNode, WideTree};
use super::{HEADER_BYTES, LEAF_BYTES};

/// How the BVH is partitioned into treelets (`bvh.treelet_formation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TreeletFormation {
    /// Greedy breadth-first fill, every unit left in the frontier of a closed treelet rooting a
    /// treelet of its own (the treelet-prefetching code of Chou et al., MICRO 2023, which the
    /// paper used), one slot each: slots 6-12% full, too many of them to address a scene of
    /// the paper's largest size.
    BreadthFirst,
    /// The breadth-first treelets, consecutive ones packed into one slot while they fit (next
    /// fit in formation order): fuller treelets, fewer of them. The default: the paper's
    /// section 6.5 packs treelets "together in memory as suggested by Chou et al." so that
    /// 19-bit treelet addresses cover its gigabyte BVHs.
    #[default]
    Packed,
}

impl TreeletFormation {
    /// The name used in configuration files.
    pub fn name(self) -> &'static str {
        match self {
            TreeletFormation::BreadthFirst => "breadth_first",
            TreeletFormation::Packed => "packed",
        }
    }

    /// Its code in the BVH cache file and key.
    pub fn code(self) -> u32 {
        match self {
            TreeletFormation::BreadthFirst => 0,
            TreeletFormation::Packed => 1,
        }
    }

    /// The formation with cache code `code`.
    pub fn from_code(code: u32) -> Option<TreeletFormation> {
        match code {
            0 => Some(TreeletFormation::BreadthFirst),
            1 => Some(TreeletFormation::Packed),
            _ => None,
        }
    }
}

/// One treelet of a laid-out BVH.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct TreeletInfo {
    /// First byte address of the treelet's slot (`index * treelet_bytes`).
    pub base: u32,
    /// Bytes used (sum of the sizes of its nodes); at most `treelet_bytes`.
    pub bytes: u32,
    /// Number of nodes (the header counts as a node of treelet 0).
    pub nodes: u32,
    /// Address of the treelet's root unit: the first node placed in it (equals `base`).
    pub root: u32,
}

/// A unit of placement: the header with the root node, or the child group of an internal node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Unit {
    /// The 64 B BVH header followed by the root internal node (just the header when empty).
    Root,
    /// The children of the internal node with this index in [`WideTree::nodes`].
    Children(u32),
}

/// Byte size of one node of the tree.
pub(crate) fn node_size(node: &WideNode, internal_bytes: u32) -> u32 {
    match node {
        WideNode::Internal { .. } => internal_bytes,
        WideNode::Triangle { .. } | WideNode::Sphere { .. } => LEAF_BYTES,
    }
}

/// The internal nodes whose child groups follow once `unit` is placed.
fn internal_nodes_of(tree: &WideTree, unit: Unit) -> Vec<u32> {
    match unit {
        Unit::Root if tree.nodes.is_empty() => Vec::new(),
        Unit::Root => vec![0],
        Unit::Children(n) => match &tree.nodes[n as usize] {
            WideNode::Internal { children, .. } => children
                .iter()
                .copied()
                .filter(|&c| matches!(tree.nodes[c as usize], WideNode::Internal { .. }))
                .collect(),
            _ => Vec::new(),
        },
    }
}

/// Byte size of a unit.
pub(crate) fn unit_size(tree: &WideTree, unit: Unit, internal_bytes: u32) -> u32 {
    match unit {
        Unit::Root if tree.nodes.is_empty() => HEADER_BYTES,
        Unit::Root => HEADER_BYTES + internal_bytes,
        Unit::Children(n) => match &tree.nodes[n as usize] {
            WideNode::Internal { children, .. } => children
                .iter()
                .map(|&c| node_size(&tree.nodes[c as usize], internal_bytes))
                .sum(),
            _ => 0,
        },
    }
}

/// Partitions the tree into treelets of at most `max_bytes` bytes by `formation`: the units of
/// each treelet in placement order. Every unit must fit in an empty treelet (guaranteed by
/// [`crate::model::bvh::BvhParams::validate`]).
pub(crate) fn partition(
    tree: &WideTree,
    internal_bytes: u32,
    max_bytes: u32,
    formation: TreeletFormation,
) -> Vec<Vec<Unit>> {
    let treelets = breadth_first(tree, internal_bytes, max_bytes);
    match formation {
        TreeletFormation::BreadthFirst => treelets,
        TreeletFormation::Packed => pack(tree, internal_bytes, max_bytes, treelets),
    }
}

/// Packs consecutive treelets into one slot while their bytes fit (next fit).
fn pack(
    tree: &WideTree,
    internal_bytes: u32,
    max_bytes: u32,
    treelets: Vec<Vec<Unit>>,
) -> Vec<Vec<Unit>> {
    let mut slots: Vec<Vec<Unit>> = Vec::new();
    let mut used = 0u32;
    for units in treelets {
        let bytes: u32 = units
            .iter()
            .map(|&u| unit_size(tree, u, internal_bytes))
            .sum();
        match slots.last_mut() {
            Some(slot) if used + bytes <= max_bytes => {
                slot.extend(units);
                used += bytes;
            }
            _ => {
                slots.push(units);
                used = bytes;
            }
        }
    }
    slots
}

/// The greedy breadth-first treelets (module documentation).
fn breadth_first(tree: &WideTree, internal_bytes: u32, max_bytes: u32) -> Vec<Vec<Unit>> {
    let mut treelets = Vec::new();
    let mut pending: VecDeque<Unit> = VecDeque::from([Unit::Root]);
    while let Some(root) = pending.pop_front() {
        let mut frontier: VecDeque<Unit> = VecDeque::from([root]);
        let mut used = 0u32;
        let mut units = Vec::new();
        while let Some(&unit) = frontier.front() {
            let size = unit_size(tree, unit, internal_bytes);
            if used + size > max_bytes && !units.is_empty() {
                break;
            }
            frontier.pop_front();
            used += size;
            units.push(unit);
            frontier.extend(
                internal_nodes_of(tree, unit)
                    .into_iter()
                    .map(Unit::Children),
            );
        }
        pending.extend(frontier);
        treelets.push(units);
    }
    treelets
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::bvh::build::build_wide_tree;
    use crate::model::bvh::BvhParams;
    use crate::model::scene::{Camera, Material, Scene};
    use glam::Vec3;

    /// A row of `n` small separated triangles.
    fn row(n: u32) -> Scene {
        let mut positions = Vec::new();
        for i in 0..n {
            let x = i as f32 * 2.0;
            positions.extend([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
            ]);
        }
        Scene {
            name: "row".into(),
            positions,
            triangles: (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
            tri_material: vec![0; n as usize],
            spheres: Vec::new(),
            materials: vec![Material::DEFAULT],
            camera: Camera {
                eye: Vec3::Z,
                look_at: Vec3::ZERO,
                up: Vec3::Y,
                fov_y_deg: 45.0,
            },
            sky: false,
        }
    }

    /// The 4-wide tree of [`row`]`(200)` with 512 B treelets, which the partition tests cut.
    fn row_tree() -> WideTree {
        let params = BvhParams {
            width: 4,
            treelet_bytes: 512,
            ..BvhParams::default()
        };
        build_wide_tree(&row(200), &params).expect("tree")
    }

    #[test]
    fn units_fill_greedily_and_each_placed_once() {
        let tree = row_tree();
        let parts = partition(&tree, 64, 512, TreeletFormation::BreadthFirst);
        let mut seen = std::collections::BTreeSet::new();
        for (i, units) in parts.iter().enumerate() {
            let bytes: u32 = units.iter().map(|&u| unit_size(&tree, u, 64)).sum();
            assert!(bytes <= 512 && !units.is_empty());
            for &u in units {
                assert!(seen.insert(format!("{u:?}")), "unit {u:?} placed twice");
            }
            if i == 0 {
                assert_eq!(units[0], Unit::Root);
            }
        }
        let internal = tree
            .nodes
            .iter()
            .filter(|n| matches!(n, WideNode::Internal { .. }))
            .count();
        // The root unit plus one child group per internal node.
        assert_eq!(seen.len(), internal + 1);
        // The first treelet is filled until the next unit (at most 4 x 64 B) does not fit.
        let first: u32 = parts[0].iter().map(|&u| unit_size(&tree, u, 64)).sum();
        assert!(
            parts.len() > 1 && first + 4 * 64 > 512,
            "first treelet {first} B"
        );
    }

    #[test]
    fn packing_merges_consecutive_treelets_in_order_and_fills_slots() {
        let tree = row_tree();
        let size = |units: &[Unit]| -> u32 { units.iter().map(|&u| unit_size(&tree, u, 64)).sum() };
        let bf = partition(&tree, 64, 512, TreeletFormation::BreadthFirst);
        let packed = partition(&tree, 64, 512, TreeletFormation::Packed);
        // The same units in the same order, fewer slots, none over the size.
        let flat = |p: &[Vec<Unit>]| p.concat();
        assert_eq!(flat(&bf), flat(&packed));
        assert!(packed.len() < bf.len(), "{} vs {}", packed.len(), bf.len());
        assert!(packed.iter().all(|s| size(s) <= 512));
        // Next fit: a slot is closed only when the next breadth-first treelet does not fit.
        let mut k = 0;
        for (i, slot) in packed.iter().enumerate() {
            let mut n = 0;
            while n < slot.len() {
                n += bf[k].len();
                k += 1;
            }
            assert_eq!(n, slot.len(), "slot {i} holds whole treelets");
            if let Some(next) = bf.get(k) {
                assert!(
                    size(slot) + size(next) > 512,
                    "slot {i} could take the next treelet"
                );
            }
        }
        assert_eq!(k, bf.len());
    }

    #[test]
    fn empty_tree_is_one_header_treelet() {
        let tree = build_wide_tree(&row(0), &BvhParams::default()).expect("tree");
        for f in [TreeletFormation::BreadthFirst, TreeletFormation::Packed] {
            assert_eq!(partition(&tree, 64, 8192, f), vec![vec![Unit::Root]]);
        }
        assert_eq!(unit_size(&tree, Unit::Root, 64), 64);
    }
}
