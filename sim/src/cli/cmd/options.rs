//! Options and setup steps shared by the subcommands: image settings, BVH parameters and the
//! cache, loading a scene and building its BVH with a printed summary.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;

use crate::model::bvh::{build_cached, default_cache_dir, BvhParams, CacheOutcome, HwBvh};
use crate::model::config::{SimConfig, WorkloadKindName};
use crate::model::designs;
use crate::model::scene::load::{load_scene_with_report as load, LoadedScene};
use crate::model::scene::Scene;
use crate::model::workload::pathtracer::RenderSettings;

/// Image size and path-tracing limits (defaults: the paper's 256x256, 1 spp, 3 bounces).
#[derive(Debug, Clone, Args)]
pub struct ImageArgs {
    /// Image width in pixels.
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 256)]
    pub height: u32,
    /// Samples (paths) per pixel.
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    /// Maximum secondary rays per path (each path traces at most 1 + bounces rays).
    #[arg(long, default_value_t = 3)]
    pub bounces: u32,
    /// What each sample traces: `path` (the path tracer), `path-nee` (with shadow rays), `ao`
    /// (a primary ray, then --ao-rays occlusion rays per hit), `hybrid` (the path tracer's
    /// secondary rays only, primary hits given as by rasterization) or `rays` (--rays-file's);
    /// docs/workloads.md.
    #[arg(long, value_enum, hide_possible_values = true, default_value_t = WorkloadKindName::Path)]
    pub workload: WorkloadKindName,
    /// `--workload ao`: occlusion rays per primary hit (1..=64).
    #[arg(long, default_value_t = 4)]
    pub ao_rays: u32,
    /// `--workload ao`: their length as a fraction of the scene's bounding-box diagonal.
    #[arg(long, default_value_t = 0.05)]
    pub ao_radius: f64,
    /// `--workload rays`: the ray file (CSV as `vtq trace` reads, optionally with an
    /// `occlusion` column, or binary); the image is one row of one pixel per ray.
    #[arg(long)]
    pub rays_file: Option<String>,
}

impl ImageArgs {
    /// The render settings, checked.
    pub fn settings(&self) -> anyhow::Result<RenderSettings> {
        // The [workload] section's rules, through the same checks as a configuration's.
        let mut cfg = SimConfig::default();
        let w = &mut cfg.workload;
        (w.width, w.height, w.spp, w.bounces) = (self.width, self.height, self.spp, self.bounces);
        (w.kind, w.ao_rays, w.ao_radius) = (self.workload, self.ao_rays, self.ao_radius);
        w.rays_file = self.rays_file.clone().unwrap_or_default();
        w.read_rays()?;
        cfg.validate_workload()?;
        let settings = cfg.render_settings();
        settings.validate()?;
        Ok(settings)
    }
}

/// Hardware BVH parameters and the build cache.
#[derive(Debug, Clone, Args)]
pub struct BvhArgs {
    /// BVH width: children per internal node (2..=8).
    #[arg(long, default_value_t = 6)]
    pub bvh_width: u32,
    /// Maximum treelet size in bytes (a power of two; 8192 = half the simulated 16 KB L1).
    #[arg(long, default_value_t = 8192)]
    pub treelet_bytes: u32,
    /// The build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// Where built BVHs are cached (`--cache-dir`, `--no-cache`).
#[derive(Debug, Clone, Args)]
pub struct CacheArgs {
    /// Directory of cached BVH builds, keyed by scene geometry and BVH parameters
    /// [default: $VTQ_CACHE_DIR, else $XDG_CACHE_HOME/vtq, else ~/.cache/vtq].
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Always build the BVH; neither read nor write the cache.
    #[arg(long)]
    pub no_cache: bool,
}

impl BvhArgs {
    /// The build parameters.
    pub fn params(&self) -> BvhParams {
        BvhParams {
            width: self.bvh_width,
            treelet_bytes: self.treelet_bytes,
            ..BvhParams::default()
        }
    }
}

/// Load a scene by name or path and print a one-line summary, then the load report: one line
/// naming every statement read but not used with its count (`ignored: vt x12, l x3; in .mtl
/// files: map_Kd x4`), one counting triangles left out for non-finite vertices, and warnings
/// (missing libraries, undefined materials, a manifest count that differs) on stderr.
pub fn load_scene(spec: &str) -> anyhow::Result<Scene> {
    let start = Instant::now();
    let LoadedScene { scene, report } =
        load(spec).with_context(|| format!("loading scene '{spec}'"))?;
    println!(
        "scene {}: {} triangles, {} spheres, {} materials (loaded in {:.3} s)",
        scene.name,
        scene.triangles.len(),
        scene.spheres.len(),
        scene.materials.len(),
        start.elapsed().as_secs_f64()
    );
    for line in [
        report.ignored_line(),
        report.left_out_line(),
        report.camera_line(),
    ]
    .into_iter()
    .flatten()
    {
        println!("scene {}: {line}", scene.name);
    }
    for warning in report.warnings(scene.triangles.len()) {
        eprintln!("warning: scene {}: {warning}", scene.name);
    }
    Ok(scene)
}

/// Build the scene's hardware BVH (through the cache unless disabled) and print its summary:
/// nodes, bytes, treelets, fill ratio, depth, and the build or cache-load time.
pub fn build_bvh(scene: &Scene, params: &BvhParams, args: &CacheArgs) -> anyhow::Result<HwBvh> {
    let start = Instant::now();
    let context = || format!("building the BVH of scene '{}'", scene.name);
    let params = *params;
    let (bvh, how) = if args.no_cache {
        let bvh = HwBvh::build(scene, &params).with_context(context)?;
        (bvh, "built (cache disabled)".to_string())
    } else {
        let dir = args.cache_dir.clone().unwrap_or_else(default_cache_dir);
        let (bvh, outcome) = build_cached(scene, &params, Some(&dir)).with_context(context)?;
        let how = match outcome {
            CacheOutcome::Hit => format!("loaded from the cache in {}", dir.display()),
            CacheOutcome::Built => format!("built and cached in {}", dir.display()),
            CacheOutcome::Rebuilt(why) => {
                format!(
                    "rebuilt (cache file was invalid: {why}) and cached in {}",
                    dir.display()
                )
            }
            CacheOutcome::NotStored(why) => format!("built (not cached: {why})"),
        };
        (bvh, how)
    };
    let seconds = start.elapsed().as_secs_f64();
    let s = bvh.stats();
    println!(
        "bvh: width {}, {} internal nodes + {} leaves, {} bytes, depth {}; \
         {} treelets of <= {} bytes, fill {:.1}%",
        params.width,
        s.internal_nodes,
        s.leaves(),
        s.bvh_bytes,
        s.depth,
        s.treelets,
        params.treelet_bytes,
        100.0 * s.treelet_fill,
    );
    if s.excluded_prims > 0 {
        println!(
            "bvh: {} degenerate or non-finite primitives left out",
            s.excluded_prims
        );
    }
    println!("bvh: {how} in {seconds:.3} s");
    Ok(bvh)
}

/// The simulator configuration file and `--set` overrides (see docs/config.md).
#[derive(Debug, Clone, Args)]
pub struct ConfigArgs {
    /// Configuration: a built-in design's name (`vtq`; `vtq designs` lists them) or a TOML file
    /// (e.g. configs/designs/vtq/config.toml; a file of that path in the working directory
    /// is read before the built-in copy) [default: the paper's Table 1 baseline].
    #[arg(long, value_name = "NAME|FILE")]
    pub config: Option<PathBuf>,
    /// Override one parameter, e.g. `--set hw.max_rays=8192` or `--set width=64` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub overrides: Vec<String>,
}

impl ConfigArgs {
    /// Defaults, then the file (or built-in design), then the overrides, validated.
    pub fn load(&self) -> anyhow::Result<SimConfig> {
        designs::load(self.config.as_deref(), &self.overrides)
    }

    /// Defaults, then the file (or built-in design), then the overrides, with only the sections
    /// the hardware is generated from validated (`[hw]`, `[gpu]`, `[memory]`; see
    /// [`SimConfig::validate_hardware`]), for the commands that generate, co-simulate or size
    /// the hardware: table sizes can be explored without switching the simulated design to
    /// treelet queues.
    pub fn load_hardware(&self) -> anyhow::Result<SimConfig> {
        let cfg = designs::load_unvalidated(self.config.as_deref(), &self.overrides)?;
        cfg.validate_hardware()?;
        Ok(cfg)
    }
}

/// Simulates `cfg`'s workload on `scene` (cycle-exact) with `options` (threads, a waveform),
/// with a progress bar of finished pixels while stderr is a terminal.
pub fn simulate_with_progress(
    scene: &Scene,
    bvh: &HwBvh,
    cfg: &SimConfig,
    options: crate::model::gpu::SimOptions,
) -> anyhow::Result<crate::model::gpu::SimOutput> {
    use std::io::IsTerminal;
    let pixels = cfg.render_settings().pixels() as u64;
    let progress = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(pixels);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "sim {bar:40} {pos}/{len} pixels {elapsed} (eta {eta})",
            )
            .expect("the progress template is valid"),
        );
        bar
    });
    let out = crate::model::gpu::simulate(scene, bvh, cfg, options, progress.as_ref())
        .with_context(|| format!("simulating scene '{}'", scene.name))?;
    if let Some(bar) = &progress {
        bar.finish_and_clear();
    }
    Ok(out)
}

/// Parses a thread count of at least 1 (`--threads`).
pub fn parse_threads(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if (1..=1024).contains(&n) => Ok(n),
        _ => Err(format!("`{s}` is not a thread count (1..=1024)")),
    }
}

/// `--sample [POINT]`, shared by the commands that can run the sampled tier (`sim`, `compare`,
/// `sweep`, `reproduce`): a named point (`default`, `fast`), `FRACTION[xREPLICATES]` or
/// `config`; without a value `default` (docs/accuracy.md). `--help` lists the named points with
/// their measured speed and error.
#[derive(Debug, Clone, Default, Args)]
pub struct SampleArg {
    /// The sampled tier instead of full detail: a named point (`default`, `fast`),
    /// `FRACTION[xREPLICATES]` or `config`; without a value `default` (docs/accuracy.md).
    #[arg(
        id = "sample",
        long = "sample",
        value_name = "POINT",
        num_args = 0..=1,
        default_missing_value = crate::model::config::sample_points::DEFAULT_POINT,
        long_help = crate::model::config::sample_points::points_help()
    )]
    pub point: Option<String>,
}
