//! `vtq trace`: trace the rays of a CSV file through a scene's hardware BVH and write the
//! closest hits as CSV.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, ValueEnum};
use rayon::prelude::*;

use crate::cli::cmd::options::{build_bvh, load_scene, BvhArgs};
use crate::model::geometry::Hit;
use crate::model::traversal::{trace, trace_occlusion, Order};
use crate::model::workload::rays_csv::{read_rays, write_hits};

/// Traversal order choice on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OrderArg {
    /// Depth-first, nearest child first, one ray at a time (ray stationary).
    Ray,
    /// Finish the current treelet before visiting nodes in other treelets.
    Treelet,
}

impl From<OrderArg> for Order {
    fn from(o: OrderArg) -> Order {
        match o {
            OrderArg::Ray => Order::RayStationary,
            OrderArg::Treelet => Order::Treelet,
        }
    }
}

/// Options of `vtq trace`.
#[derive(Debug, Args)]
pub struct TraceArgs {
    /// Scene: a built-in name, a folder under ../shared/scenes, a scene folder path or a `.obj`.
    #[arg(long)]
    pub scene: String,
    /// Input rays CSV with header `ox,oy,oz,dx,dy,dz,tmin,tmax` (`nan`/`inf` values allowed;
    /// such rays are reported as misses), optionally with a column `occlusion` (1: an occlusion
    /// ray, whose row is the first hit found, 0: a closest-hit ray).
    #[arg(long)]
    pub rays: PathBuf,
    /// Output hits CSV with header `ray,hit,t,prim,u,v` (one row per input ray; prim -1 on a miss).
    #[arg(long)]
    pub out: PathBuf,
    /// Traversal order (both find the same closest hits).
    #[arg(long, value_enum, default_value_t = OrderArg::Ray)]
    pub order: OrderArg,
    /// BVH build and cache options.
    #[command(flatten)]
    pub bvh: BvhArgs,
}

/// Run `vtq trace`.
pub fn run(args: &TraceArgs) -> anyhow::Result<()> {
    crate::cli::output::check_file(&args.out)?;
    let rays = read_rays(&args.rays).context("reading the rays")?;
    let scene = load_scene(&args.scene)?;
    let bvh = build_bvh(&scene, &args.bvh.params(), &args.bvh.cache)?;
    let order = Order::from(args.order);
    let hits: Vec<Option<Hit>> = rays
        .par_iter()
        .map(|r| match (r.ray.is_valid(), r.occlusion) {
            (false, _) => None,
            (true, false) => trace(&bvh, &r.ray, order),
            (true, true) => trace_occlusion(&bvh, &r.ray, order),
        })
        .collect();
    crate::cli::output::write_or_keep(&args.out, |p| write_hits(p, &hits))?;
    let invalid = rays.iter().filter(|r| !r.ray.is_valid()).count();
    let hit_count = hits.iter().filter(|h| h.is_some()).count();
    println!(
        "trace: {} rays, {} hits, {} misses ({} invalid rays reported as misses); wrote {}",
        rays.len(),
        hit_count,
        rays.len() - hit_count,
        invalid,
        args.out.display()
    );
    Ok(())
}
