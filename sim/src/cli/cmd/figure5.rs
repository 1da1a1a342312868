//! `vtq figure5`: the paper's Figure 5 analytical model (treelet reuse against concurrent rays,
//! [`crate::estimate::figure5`]) for one scene, from the functional traces of the workload's rays.

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::Args;
use serde::Serialize;

use crate::cli::cmd::options::{build_bvh, load_scene, CacheArgs, ConfigArgs};
use crate::estimate::figure5::{model, Figure5Row};
use crate::model::workload::pathtracer::render;

/// Batch sizes of concurrent rays modelled by default: one warp, one SM's CTA slots (1024), the
/// paper's 4096 rays per SM, and the whole GPU's 16 x 4096.
const DEFAULT_RAYS: &str = "32,128,512,1024,2048,4096,8192,16384,65536";

/// Options of `vtq figure5`.
#[derive(Debug, Args)]
pub struct Figure5Args {
    /// Scene: a built-in name, a folder under ../shared/scenes, a scene folder path or a `.obj`
    /// file (see `vtq scenes`).
    #[arg(long)]
    pub scene: String,
    /// Batch sizes (concurrent rays), comma-separated.
    #[arg(long, default_value = DEFAULT_RAYS, value_delimiter = ',')]
    pub rays: Vec<u64>,
    /// The workload (`[workload]`), the BVH (`[bvh]`, `hw.treelet_bytes`) and the CTA shape
    /// (`gpu.threads_per_cta`) come from this configuration.
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Also write the table as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The BVH build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// The JSON written by `--json`.
#[derive(Debug, Serialize)]
struct Output<'a> {
    scene: &'a str,
    rays: u64,
    treelets: u32,
    treelet_fill: f64,
    rows: &'a [Figure5Row],
}

/// Run `vtq figure5`.
pub fn run(args: &Figure5Args) -> anyhow::Result<()> {
    if let Some(bad) = args.rays.iter().find(|&&r| r == 0) {
        bail!("--rays: a batch of {bad} rays; every batch size must be at least 1");
    }
    if let Some(path) = &args.json {
        crate::cli::output::check_file(path)?;
    }
    let cfg = args.config.load()?;
    let scene = load_scene(&args.scene)?;
    let bvh = build_bvh(&scene, &cfg.bvh_params(), &args.cache)?;
    let settings = cfg.render_settings();
    let rendered = render(&scene, &bvh, &settings, None)
        .with_context(|| format!("rendering scene '{}'", scene.name))?;
    let rows = model(&bvh, &rendered, cfg.gpu.threads_per_cta, &args.rays);
    let stats = bvh.stats();
    println!(
        "figure5 {}: {} rays, {} treelets of {} B ({:.1}% full); cycles in units of the memory \
         latency",
        scene.name,
        rendered.rays.len(),
        stats.treelets,
        bvh.params().treelet_bytes,
        100.0 * stats.treelet_fill
    );
    println!(
        "{:>16} {:>9} {:>14} {:>14} {:>14} {:>8} {:>13}",
        "concurrent rays",
        "batches",
        "baseline",
        "treelet nodes",
        "treelets",
        "speedup",
        "full treelets"
    );
    for r in &rows {
        println!(
            "{:>16} {:>9} {:>14} {:>14} {:>14} {:>8.2} {:>13.2}",
            r.concurrent_rays,
            r.batches,
            r.baseline_fetches,
            r.treelet_fetches,
            r.unique_treelets,
            r.speedup,
            r.speedup_full_treelets
        );
    }
    if let Some(path) = &args.json {
        let out = Output {
            scene: &scene.name,
            rays: rendered.rays.len() as u64,
            treelets: stats.treelets,
            treelet_fill: stats.treelet_fill,
            rows: &rows,
        };
        let json = serde_json::to_string_pretty(&out).context("serializing the table")?;
        let text = json + "\n";
        crate::cli::output::write_or_keep(path, |p| std::fs::write(p, &text))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
