//! BVH construction: a binary BVH from `obvhs` (PLOC + reinsertion, one primitive per leaf)
//! collapsed to the configured width. The result is a [`WideTree`] with exact (unquantized)
//! bounds; [`super::layout`] turns it into the hardware memory image.

use glam::Vec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};

use super::{BvhError, BvhParams};
use crate::model::scene::{Scene, Sphere};

/// Largest accepted magnitude of a vertex coordinate or sphere extent. Larger values would make
/// box surface areas overflow `f32` inside the builder; scenes beyond it are rejected.
pub const MAX_COORD: f32 = 1.0e18;

/// A node of the collapsed tree, before layout.
#[derive(Debug, Clone)]
pub(crate) enum WideNode {
    /// Internal node with 1..=width children (indices into [`WideTree::nodes`]).
    Internal {
        /// Exact bounds (union of the children's bounds).
        lo: Vec3,
        /// Exact bounds, upper corner.
        hi: Vec3,
        /// Children in slot order.
        children: Vec<u32>,
    },
    /// One triangle.
    Triangle {
        /// Global primitive id.
        prim: u32,
        /// Vertices.
        verts: [Vec3; 3],
    },
    /// One procedural sphere.
    Sphere {
        /// Global primitive id.
        prim: u32,
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
}

impl WideNode {
    /// Exact bounds of the node (leaf bounds from the geometry, spheres rounded outward).
    pub(crate) fn bounds(&self) -> (Vec3, Vec3) {
        match self {
            WideNode::Internal { lo, hi, .. } => (*lo, *hi),
            WideNode::Triangle { verts, .. } => triangle_bounds(*verts),
            WideNode::Sphere { center, radius, .. } => sphere_bounds(*center, *radius),
        }
    }
}

/// The collapsed tree: node 0 is the root (always internal) unless the tree is empty.
#[derive(Debug, Clone)]
pub(crate) struct WideTree {
    /// Nodes; parents precede their children.
    pub(crate) nodes: Vec<WideNode>,
    /// Primitives left out of the tree (degenerate or non-finite triangles, invalid spheres).
    pub(crate) excluded: u32,
}

/// Exact bounds of a triangle.
pub fn triangle_bounds(v: [Vec3; 3]) -> (Vec3, Vec3) {
    (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]))
}

/// Bounds of a sphere, rounded outward by one ulp so they contain the true sphere.
pub fn sphere_bounds(center: Vec3, radius: f32) -> (Vec3, Vec3) {
    let lo = (center - Vec3::splat(radius)).to_array().map(next_down);
    let hi = (center + Vec3::splat(radius)).to_array().map(next_up);
    (Vec3::from_array(lo), Vec3::from_array(hi))
}

/// The next representable `f32` above `x` (finite inputs).
pub(crate) fn next_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f32::from_bits(1);
    }
    let b = x.to_bits();
    f32::from_bits(if x > 0.0 { b + 1 } else { b - 1 })
}

/// The next representable `f32` below `x` (finite inputs).
pub(crate) fn next_down(x: f32) -> f32 {
    -next_up(-x)
}

/// Whether a triangle can ever be hit and so belongs in the BVH: finite vertices and a non-zero
/// area (cross product of its edges, computed in f64, not exactly zero). Excluded triangles are
/// never reported as hits by any traversal; brute-force references must apply the same filter.
pub fn triangle_is_usable(v: [Vec3; 3]) -> bool {
    if !(v[0].is_finite() && v[1].is_finite() && v[2].is_finite()) {
        return false;
    }
    let a = v[0].as_dvec3();
    let e1 = v[1].as_dvec3() - a;
    let e2 = v[2].as_dvec3() - a;
    e1.cross(e2) != glam::DVec3::ZERO
}

/// Whether a sphere belongs in the BVH: finite centre and a finite radius > 0.
pub fn sphere_is_usable(s: &Sphere) -> bool {
    s.center.is_finite() && s.radius.is_finite() && s.radius > 0.0
}

/// Bounds check against [`MAX_COORD`].
fn check_range(kind: &str, id: usize, lo: Vec3, hi: Vec3) -> Result<(), BvhError> {
    let m = lo.abs().max(hi.abs()).max_element();
    if m > MAX_COORD {
        return Err(BvhError::Geometry(format!(
            "{kind} {id} reaches coordinate magnitude {m:e}, beyond the supported {MAX_COORD:e}"
        )));
    }
    Ok(())
}

/// Builds the collapsed `width`-wide tree over the scene's usable primitives.
pub(crate) fn build_wide_tree(scene: &Scene, params: &BvhParams) -> Result<WideTree, BvhError> {
    build_wide_tree_every(scene, params, 1)
}

/// Builds the collapsed tree over every `stride`-th primitive (triangles, then spheres, by
/// index): `stride = 1` is the scene's tree; a larger stride a sample of it, for estimating
/// the full tree's treelets before building it ([`super::layout::preflight`]).
pub(crate) fn build_wide_tree_every(
    scene: &Scene,
    params: &BvhParams,
    stride: usize,
) -> Result<WideTree, BvhError> {
    params.validate()?;
    let stride = stride.max(1);
    let ntri = scene.triangles.len();
    let total = scene.prim_count();
    if total > u32::MAX as usize / 2 {
        return Err(BvhError::Geometry(format!(
            "{total} primitives exceed the supported maximum of {}",
            u32::MAX / 2
        )));
    }
    let mut leaves: Vec<WideNode> = Vec::with_capacity(total.div_ceil(stride));
    let mut examined = 0usize;
    for (i, tri) in scene.triangles.iter().enumerate().step_by(stride) {
        examined += 1;
        if let Some(&bad) = tri.iter().find(|&&p| p as usize >= scene.positions.len()) {
            return Err(BvhError::Geometry(format!(
                "triangle {i} references vertex {bad}, but the scene has {} positions",
                scene.positions.len()
            )));
        }
        let verts = scene.triangle(i);
        if !triangle_is_usable(verts) {
            continue;
        }
        let (lo, hi) = triangle_bounds(verts);
        check_range("triangle", i, lo, hi)?;
        leaves.push(WideNode::Triangle {
            prim: i as u32,
            verts,
        });
    }
    // The spheres continue the triangles' primitive numbering in the sample.
    let first_sphere = (stride - ntri % stride) % stride;
    for (i, s) in scene
        .spheres
        .iter()
        .enumerate()
        .skip(first_sphere)
        .step_by(stride)
    {
        examined += 1;
        if !sphere_is_usable(s) {
            continue;
        }
        let (lo, hi) = sphere_bounds(s.center, s.radius);
        check_range("sphere", i, lo, hi)?;
        leaves.push(WideNode::Sphere {
            prim: (ntri + i) as u32,
            center: s.center,
            radius: s.radius,
        });
    }
    let excluded = (examined - leaves.len()) as u32;
    if leaves.is_empty() {
        return Ok(WideTree {
            nodes: Vec::new(),
            excluded,
        });
    }

    let aabbs: Vec<Aabb> = leaves
        .iter()
        .map(|l| {
            let (lo, hi) = l.bounds();
            Aabb::new(lo.into(), hi.into())
        })
        .collect();
    let indices: Vec<u32> = (0..leaves.len() as u32).collect();
    let mut bvh2 = PlocBuilder::with_capacity(aabbs.len()).build(
        PlocSearchDistance::Medium,
        &aabbs,
        indices,
        SortPrecision::U64,
        3,
    );
    ReinsertionOptimizer::default().run(&mut bvh2, 0.05, None);

    let mut tree = collapse(&bvh2, &leaves, params.width as usize);
    tree.excluded = excluded;
    Ok(tree)
}

/// Collapses the binary tree: each wide node starts with its binary node's two children and
/// repeatedly opens the internal child with the largest surface area until it has `width`
/// children or only leaves remain.
fn collapse(bvh2: &Bvh2, leaves: &[WideNode], width: usize) -> WideTree {
    let leaf_index =
        |n: &obvhs::bvh2::node::Bvh2Node| bvh2.primitive_indices[n.first_index as usize];
    let mut nodes: Vec<WideNode> = Vec::with_capacity(leaves.len() * 2);
    // Work list of (binary node, wide node to fill).
    let mut work: Vec<(u32, u32)> = Vec::new();
    nodes.push(WideNode::Internal {
        lo: Vec3::ZERO,
        hi: Vec3::ZERO,
        children: Vec::new(),
    });
    if bvh2.nodes[0].is_leaf() {
        let leaf = leaves[leaf_index(&bvh2.nodes[0]) as usize].clone();
        nodes.push(leaf);
        if let WideNode::Internal { children, .. } = &mut nodes[0] {
            children.push(1);
        }
    } else {
        work.push((0, 0));
    }
    while let Some((b, w)) = work.pop() {
        let first = bvh2.nodes[b as usize].first_index;
        let mut group: Vec<u32> = vec![first, first + 1];
        while group.len() < width {
            let mut best: Option<(usize, f32)> = None;
            for (i, &c) in group.iter().enumerate() {
                let n = &bvh2.nodes[c as usize];
                if n.is_leaf() {
                    continue;
                }
                let area = n.aabb().half_area();
                if best.is_none_or(|(_, a)| area > a) {
                    best = Some((i, area));
                }
            }
            let Some((i, _)) = best else { break };
            let f = bvh2.nodes[group[i] as usize].first_index;
            group[i] = f;
            group.insert(i + 1, f + 1);
        }
        let mut children = Vec::with_capacity(group.len());
        for c in group {
            let n = &bvh2.nodes[c as usize];
            let idx = nodes.len() as u32;
            if n.is_leaf() {
                nodes.push(leaves[leaf_index(n) as usize].clone());
            } else {
                nodes.push(WideNode::Internal {
                    lo: Vec3::ZERO,
                    hi: Vec3::ZERO,
                    children: Vec::new(),
                });
                work.push((c, idx));
            }
            children.push(idx);
        }
        if let WideNode::Internal { children: slot, .. } = &mut nodes[w as usize] {
            *slot = children;
        }
    }
    // Exact bounds bottom-up: children always have larger indices than their parent.
    for i in (0..nodes.len()).rev() {
        if let WideNode::Internal { children, .. } = &nodes[i] {
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for &c in children {
                let (clo, chi) = nodes[c as usize].bounds();
                lo = lo.min(clo);
                hi = hi.max(chi);
            }
            if let WideNode::Internal { lo: l, hi: h, .. } = &mut nodes[i] {
                *l = lo;
                *h = hi;
            }
        }
    }
    WideTree { nodes, excluded: 0 }
}
