//! `vtq bench`: time our BVH build and traversal against `obvhs`'s own compressed wide BVH
//! (CWBVH) traversal on the same scene and the same workload rays, single-threaded, and check
//! that both find the same closest hits.
//!
//! Both sides use the same leaf tests (our watertight ray/triangle and ray/sphere tests from
//! [`crate::model::intersect`]), so the comparison measures the acceleration structure and its
//! traversal, and disagreements can only come from ties between primitives at the same distance.
//!
//! `vtq bench --sim` measures the cycle-exact simulator instead: in one run it path traces the
//! workload with the functional tracer on one thread (as `vtq render` does, ray tracing only),
//! simulates the same workload, and prints simulated rays/s and the slowdown (simulation wall
//! time over render wall time) against the project's targets.

use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Args;
use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::BvhBuildParams;

use crate::cli::cmd::options::{
    load_scene, parse_threads, simulate_with_progress, BvhArgs, ConfigArgs, ImageArgs,
};
use crate::model::bvh::build::{sphere_bounds, triangle_bounds};
use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::designs;
use crate::model::geometry::{Hit, Ray};
use crate::model::gpu::stats::comparable_json;
use crate::model::intersect::{ray_sphere, ray_triangle, RayPrecomp};
use crate::model::scene::Scene;
use crate::model::traversal::{trace, Order};
use crate::model::workload::pathtracer::{render, render_serial};

/// Options of `vtq bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Scene: a built-in name, a folder under ../shared/scenes, a scene folder path or a `.obj`.
    #[arg(long)]
    pub scene: String,
    /// Use at most this many of the workload's rays (in pixel order) [default: all].
    #[arg(long, conflicts_with = "sim")]
    pub rays: Option<usize>,
    /// Benchmark the cycle-exact simulator instead: time the functional path tracer on one
    /// thread and the simulation of the same workload, and print simulated rays/s and the
    /// slowdown against the targets.
    #[arg(long)]
    pub sim: bool,
    /// With --sim: the simulated GPU and design (`--config`, `--set` as in `vtq sim`). The
    /// workload and BVH come from the image and BVH options below; `--set` overrides them.
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Image size and path limits of the workload whose rays are timed.
    #[command(flatten)]
    pub image: ImageArgs,
    /// BVH parameters (the build is always timed, so the cache options are ignored).
    #[command(flatten)]
    pub bvh: BvhArgs,
    /// With --sim: thread counts to simulate with, in order, e.g. `1,2` (every count must give
    /// identical statistics; speeds are reported against the first).
    #[arg(long, value_delimiter = ',', default_value = "1", value_parser = parse_threads)]
    pub threads: Vec<usize>,
    /// With --sim: also run once on one thread with the work of every SM node (per stretch of
    /// cycles), memory partition and the coordinator timed, and print the parallelism report:
    /// where the time goes and the speedup the work-span bound (with bounded lag) predicts for
    /// 2 to 32 threads.
    #[arg(long, requires = "sim")]
    pub parallelism: bool,
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
    if args.sim {
        return run_sim(args);
    }
    if args.config.config.is_some() || !args.config.overrides.is_empty() {
        anyhow::bail!("--config and --set configure the simulator: use them with --sim");
    }
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

/// The simulator speed targets: at least this many simulated rays per second ...
const TARGET_RAYS_PER_SECOND: f64 = 100_000.0;

/// ... and at most this slowdown against the single-threaded functional path tracer.
const TARGET_SLOWDOWN: f64 = 10.0;

/// The simulator configuration of `bench --sim`: the file, then the bench's image and BVH
/// options as overrides, then `--set`. A workload or BVH key the file sets to another value
/// than those options is an error rather than silently replaced.
fn sim_config(args: &BenchArgs) -> anyhow::Result<SimConfig> {
    let flags = [
        ("workload.width", "--width", args.image.width),
        ("workload.height", "--height", args.image.height),
        ("workload.spp", "--spp", args.image.spp),
        ("workload.bounces", "--bounces", args.image.bounces),
        ("bvh.width", "--bvh-width", args.bvh.bvh_width),
        (
            "hw.treelet_bytes",
            "--treelet-bytes",
            args.bvh.treelet_bytes,
        ),
    ];
    let mut sets: Vec<String> = flags.iter().map(|(k, _, v)| format!("{k}={v}")).collect();
    let image = &args.image;
    sets.extend([
        format!("workload.kind={}", image.workload.name()),
        format!("workload.ao_rays={}", image.ao_rays),
        format!("workload.ao_radius={:?}", image.ao_radius),
    ]);
    if let Some(file) = &image.rays_file {
        sets.push(format!("workload.rays_file={file:?}"));
    }
    sets.extend(args.config.overrides.iter().cloned());
    let cfg = designs::load(args.config.config.as_deref(), &sets)?;
    if let Some(path) = &args.config.config {
        // What the file and --set give without the bench's options (as `vtq sim` would run).
        let as_sim = designs::load(Some(path), &args.config.overrides)?;
        let value = |c: &SimConfig, key: &str| match key {
            "workload.width" => c.workload.width,
            "workload.height" => c.workload.height,
            "workload.spp" => c.workload.spp,
            "workload.bounces" => c.workload.bounces,
            "bvh.width" => c.bvh.width,
            _ => c.hw.treelet_bytes,
        };
        let default = SimConfig::default();
        for (key, flag, _) in flags {
            let (theirs, ours) = (value(&as_sim, key), value(&cfg, key));
            if theirs != value(&default, key) && theirs != ours {
                anyhow::bail!(
                    "{} sets {key} = {theirs} but bench --sim uses {flag} {ours}: pass \
                     {flag} {theirs} (or --set {key}={theirs})",
                    path.display()
                );
            }
        }
    }
    Ok(cfg)
}

/// Pass or fail, for a target line.
fn verdict(ok: bool) -> &'static str {
    if ok {
        "pass"
    } else {
        "FAIL"
    }
}

/// Run `vtq bench --sim`.
fn run_sim(args: &BenchArgs) -> anyhow::Result<()> {
    let cfg = sim_config(args)?;
    let settings = cfg.render_settings();
    let scene = load_scene(&args.scene)?;
    let start = Instant::now();
    let bvh = HwBvh::build(&scene, &cfg.bvh_params())
        .with_context(|| format!("building the BVH of scene '{}'", scene.name))?;
    println!(
        "bvh:   built in {:.3} s ({} treelets); workload {}x{}, {} spp, {} bounces; mode {}",
        start.elapsed().as_secs_f64(),
        bvh.stats().treelets,
        settings.width,
        settings.height,
        settings.spp,
        settings.bounces,
        cfg.mode.kind
    );

    let functional = render_serial(&scene, &bvh, &settings, None)
        .with_context(|| format!("rendering scene '{}'", scene.name))?;
    let render_wall = functional.stats.wall_seconds;
    println!(
        "render wall: {render_wall:.4} s, {:.0} rays/s (functional path tracer, one thread, \
         ray tracing only)",
        rate(
            functional.stats.rays_traced as usize,
            Duration::from_secs_f64(render_wall)
        )
    );
    let mut runs = Vec::new();
    for &threads in &args.threads {
        let options = crate::model::gpu::SimOptions {
            threads,
            ..crate::model::gpu::SimOptions::default()
        };
        let out = simulate_with_progress(&scene, &bvh, &cfg, options)?;
        let s = &out.stats;
        if s.rays != functional.stats.rays_traced {
            anyhow::bail!(
                "the simulation traced {} rays but the functional render {}",
                s.rays,
                functional.stats.rays_traced
            );
        }
        let slowdown = s.sim_wall_seconds / render_wall.max(1e-9);
        let speedup =
            runs.first()
                .map_or(1.0, |(_, first): &(usize, crate::model::gpu::SimOutput)| {
                    first.stats.sim_wall_seconds / s.sim_wall_seconds.max(1e-9)
                });
        println!(
            "sim, {threads} thread(s): {:.4} s for {} cycles, {:.0} simulated rays/s, slowdown \
             {slowdown:.1}x (sim wall / render wall), {speedup:.2}x the first count",
            s.sim_wall_seconds, s.cycles, s.simulated_rays_per_second
        );
        if let Some((first_threads, first)) = runs.first() {
            if comparable_json(&first.stats) != comparable_json(s)
                || first.time_series != out.time_series
                || first.image != out.image
            {
                anyhow::bail!(
                    "{threads} threads gave different results from {first_threads} thread(s)"
                );
            }
        }
        runs.push((threads, out));
    }
    let (_, out) = runs.first().expect("at least one thread count");
    if args.parallelism {
        let options = crate::model::gpu::SimOptions {
            threads: 1,
            profile: true,
            ..crate::model::gpu::SimOptions::default()
        };
        let profiled = simulate_with_progress(&scene, &bvh, &cfg, options)?;
        if comparable_json(&profiled.stats) != comparable_json(&out.stats) {
            anyhow::bail!("the profiled run gave different statistics");
        }
        let profile = profiled
            .parallelism
            .context("the profiled run returned no parallelism report")?;
        print!("{}", profile.report());
    }
    let s = &out.stats;
    let slowdown = s.sim_wall_seconds / render_wall.max(1e-9);
    println!(
        "rays: {} (the functional render and the simulation agree{})",
        s.rays,
        if runs.len() > 1 {
            "; every thread count gave identical statistics, time series and image"
        } else {
            ""
        }
    );
    let bits = |img: &[glam::Vec3]| -> Vec<[u32; 3]> {
        img.iter().map(|c| c.to_array().map(f32::to_bits)).collect()
    };
    let identical = bits(&out.image) == bits(&functional.image);
    println!(
        "image: {}",
        if identical {
            "identical to the functional render"
        } else {
            "DIFFERENT from the functional render"
        }
    );
    println!(
        "target >= 100,000 simulated rays/s (first thread count): {}",
        verdict(s.simulated_rays_per_second >= TARGET_RAYS_PER_SECOND)
    );
    println!(
        "target slowdown < {TARGET_SLOWDOWN}x (first thread count): {}",
        verdict(slowdown < TARGET_SLOWDOWN)
    );
    if !identical {
        anyhow::bail!("the simulated image differs from the functional render's");
    }
    Ok(())
}
