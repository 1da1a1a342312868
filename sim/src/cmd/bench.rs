//! `vtq bench`: time our BVH build and traversal against `obvhs`'s own compressed wide BVH
//! (CWBVH) traversal on the same scene and the same workload rays, single-threaded, and check
//! that both find the same closest hits.
//!
//! Both sides use the same leaf tests (our watertight ray/triangle and ray/sphere tests from
//! [`crate::intersect`]), so the comparison measures the acceleration structure and its
//! traversal, and disagreements can only come from ties between primitives at the same distance.

use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Args;
use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::BvhBuildParams;

use crate::bvh::build::{sphere_bounds, triangle_bounds};
use crate::bvh::HwBvh;
use crate::cmd::options::{load_scene, BvhArgs, ImageArgs};
use crate::geometry::{Hit, Ray};
use crate::intersect::{ray_sphere, ray_triangle, RayPrecomp};
use crate::scene::Scene;
use crate::traversal::{trace, Order};
use crate::workload::pathtracer::render;

/// Options of `vtq bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Scene: a built-in name, a folder under ../shared/scenes, a scene folder path or a `.obj`.
    #[arg(long)]
    pub scene: String,
    /// Use at most this many of the workload's rays (in pixel order) [default: all].
    #[arg(long)]
    pub rays: Option<usize>,
    /// Image size and path limits of the workload whose rays are timed.
    #[command(flatten)]
    pub image: ImageArgs,
    /// BVH parameters (the build is always timed, so the cache options are ignored).
    #[command(flatten)]
    pub bvh: BvhArgs,
}

/// `obvhs`'s CWBVH over the scene's primitives (triangles, then spheres, as global ids).
struct Reference<'a> {
    scene: &'a Scene,
    bvh: CwBvh,
}

impl Reference<'_> {
    /// Closest hit by `obvhs`'s CWBVH traversal, leaves tested with our intersection routines.
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let pre = RayPrecomp::new(ray);
        let oray = obvhs::ray::Ray::new(
            Vec3A::from(ray.origin),
            Vec3A::from(ray.dir),
            ray.tmin,
            ray.tmax,
        );
        let tris = self.scene.triangles.len();
        let mut best: Option<Hit> = None;
        let mut ray_hit = RayHit::none();
        self.bvh.ray_traverse(oray, &mut ray_hit, |r, id| {
            let prim = self.bvh.primitive_indices[id] as usize;
            let hit = if prim < tris {
                ray_triangle(&pre, self.scene.triangle(prim), r.tmin, r.tmax)
            } else {
                let s = &self.scene.spheres[prim - tris];
                ray_sphere(ray, s.center, s.radius, r.tmin, r.tmax).map(|t| (t, 0.0, 0.0))
            };
            match hit {
                // obvhs accepts a candidate only when it is strictly closer than the current tmax.
                Some((t, u, v)) if t < r.tmax => {
                    best = Some(Hit {
                        t,
                        prim: prim as u32,
                        u,
                        v,
                    });
                    t
                }
                _ => f32::INFINITY,
            }
        });
        best
    }
}

/// Rays per second, guarding against a zero duration.
fn rate(rays: usize, d: Duration) -> f64 {
    rays as f64 / d.as_secs_f64().max(1e-9)
}

/// Time `f` over every ray on the calling thread.
fn time_trace(rays: &[Ray], f: impl Fn(&Ray) -> Option<Hit>) -> (Vec<Option<Hit>>, Duration) {
    let start = Instant::now();
    let hits = rays.iter().map(f).collect();
    (hits, start.elapsed())
}

/// Run `vtq bench`.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let settings = args.image.settings()?;
    let scene = load_scene(&args.scene)?;

    let start = Instant::now();
    let bvh = HwBvh::build(&scene, &args.bvh.params())
        .with_context(|| format!("building the BVH of scene '{}'", scene.name))?;
    let ours_build = start.elapsed();
    let s = bvh.stats();
    println!(
        "ours:  built in {:.3} s: width {}, {} internal nodes + {} leaves, {} bytes, depth {}, \
         {} treelets",
        ours_build.as_secs_f64(),
        args.bvh.bvh_width,
        s.internal_nodes,
        s.leaves(),
        s.bvh_bytes,
        s.depth,
        s.treelets
    );

    let aabbs: Vec<Aabb> = (0..scene.triangles.len())
        .map(|i| triangle_bounds(scene.triangle(i)))
        .chain(
            scene
                .spheres
                .iter()
                .map(|s| sphere_bounds(s.center, s.radius)),
        )
        .map(|(lo, hi)| Aabb::new(lo.into(), hi.into()))
        .collect();
    let start = Instant::now();
    let mut core_build_time = Duration::ZERO;
    let reference = Reference {
        scene: &scene,
        bvh: build_cwbvh(&aabbs, BvhBuildParams::medium_build(), &mut core_build_time),
    };
    let obvhs_build = start.elapsed();
    println!(
        "obvhs: built in {:.3} s: CWBVH (8-wide, medium_build preset), {} nodes",
        obvhs_build.as_secs_f64(),
        reference.bvh.nodes.len()
    );

    let workload = render(&scene, &bvh, &settings, None)
        .with_context(|| format!("generating the workload rays of scene '{}'", scene.name))?;
    let mut rays = workload.rays;
    if let Some(n) = args.rays {
        rays.truncate(n);
    }
    println!(
        "rays:  {} from a {}x{} render ({} spp, {} bounces)",
        rays.len(),
        settings.width,
        settings.height,
        settings.spp,
        settings.bounces
    );
    if rays.is_empty() {
        anyhow::bail!("no rays to time (--rays 0)");
    }

    let (ours, ours_time) = time_trace(&rays, |r| trace(&bvh, r, Order::RayStationary));
    let (ours_treelet, treelet_time) = time_trace(&rays, |r| trace(&bvh, r, Order::Treelet));
    let (theirs, obvhs_time) = time_trace(&rays, |r| reference.closest_hit(r));

    let same = |a: &Option<Hit>, b: &Option<Hit>| match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => a.prim == b.prim && a.t.to_bits() == b.t.to_bits(),
        _ => false,
    };
    let same_t =
        |a: &Option<Hit>, b: &Option<Hit>| a.map(|h| h.t.to_bits()) == b.map(|h| h.t.to_bits());
    let agree = ours.iter().zip(&theirs).filter(|(a, b)| same(a, b)).count();
    let agree_t = ours
        .iter()
        .zip(&theirs)
        .filter(|(a, b)| same_t(a, b))
        .count();
    let orders_agree = ours
        .iter()
        .zip(&ours_treelet)
        .filter(|(a, b)| same(a, b))
        .count();
    let n = rays.len();
    let pct = |k: usize| 100.0 * k as f64 / n as f64;

    let (ours_rate, treelet_rate, obvhs_rate) = (
        rate(n, ours_time),
        rate(n, treelet_time),
        rate(n, obvhs_time),
    );
    println!("trace (single thread, {n} rays):");
    println!(
        "  ours, ray-stationary order: {:>12.0} rays/s ({:.3} s)",
        ours_rate,
        ours_time.as_secs_f64()
    );
    println!(
        "  ours, treelet order:        {:>12.0} rays/s ({:.3} s)",
        treelet_rate,
        treelet_time.as_secs_f64()
    );
    println!(
        "  obvhs CWBVH:                {:>12.0} rays/s ({:.3} s)",
        obvhs_rate,
        obvhs_time.as_secs_f64()
    );
    println!("  ratio ours/obvhs: {:.3}", ours_rate / obvhs_rate);
    println!(
        "agreement: same closest hit (prim and t) on {agree}/{n} rays ({:.3}%), same t on {agree_t} ({:.3}%); \
         ray vs treelet order agree on {orders_agree} ({:.3}%)",
        pct(agree),
        pct(agree_t),
        pct(orders_agree)
    );
    println!(
        "build: ours {:.3} s, obvhs {:.3} s",
        ours_build.as_secs_f64(),
        obvhs_build.as_secs_f64()
    );
    Ok(())
}
