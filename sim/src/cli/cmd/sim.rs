//! `vtq sim`: simulate the path-traced workload on the cycle-exact GPU model and write its
//! statistics (JSON), time series (CSV beside the JSON) and, if asked, the image.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;

use crate::cli::cmd::options::{
    build_bvh, load_scene, parse_threads, simulate_with_progress, CacheArgs, SampleArg,
};
use crate::cli::image::write_png;
use crate::cli::output::{check_file, write_or_keep, Failures};
use crate::cli::time_series::write_time_series;
use crate::estimate::sample::{simulate_sampled, Profile};
use crate::model::config::sample_points;
use crate::model::config::{Cluster, SimConfig};
use crate::model::gpu::rt::waveform::parse_cycles;
use crate::model::gpu::sm::CtaSpan;
use crate::model::gpu::{SimOptions, VcdWindow};

/// Options of `vtq sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// Scene: a built-in name (`wknd`, `cornell`, `city:N` e.g. `city:250k`), a folder under
    /// ../shared/scenes, a scene folder path or a `.obj` file (see `vtq scenes`).
    #[arg(long)]
    pub scene: String,
    /// Configuration: a built-in design's name (`vtq`; `vtq designs` lists them) or a TOML file
    /// (docs/config.md) [default: the baseline GPU].
    #[arg(long, value_name = "NAME|FILE")]
    pub config: Option<PathBuf>,
    /// Override one configuration key, e.g. `--set gpu.sms=4` or `--set width=64` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Statistics output (JSON); the time series goes beside it as `<stem>.timeseries.csv`.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the simulated image (PNG).
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Also write when each CTA ran (CSV `cta,sm,start,end`: the cycles from its warps' first
    /// trace to its retirement), for studying load balance over the SMs (docs/stats.md).
    #[arg(long, value_name = "FILE", conflicts_with = "sample")]
    pub ctas: Option<PathBuf>,
    /// Step every cycle instead of skipping idle ones (verification; same results).
    #[arg(long)]
    pub lockstep: bool,
    /// Threads simulating the SMs (results are identical for every count); with --sample,
    /// replicates simulated at once.
    #[arg(long, default_value_t = 1, value_parser = parse_threads)]
    pub threads: usize,
    /// The sampled tier instead of full detail (`--sample [POINT]`).
    #[command(flatten)]
    pub sample: SampleArg,
    /// Also write a waveform (VCD, for GTKWave) of the RT unit hardware of SM --vcd-sm over
    /// the cycles --vcd-cycles: each block's ports and registers, every cycle (docs/hardware.md).
    /// The statistics do not change.
    #[arg(long, value_name = "FILE", requires = "vcd_cycles")]
    pub vcd: Option<PathBuf>,
    /// The SM whose RT unit --vcd records [default: 0].
    #[arg(long, value_name = "K", requires = "vcd")]
    pub vcd_sm: Option<usize>,
    /// The cycles --vcd records: `A..B`, B exclusive (at most 1,000,000 cycles), inside the run.
    #[arg(long, value_name = "A..B", requires = "vcd", value_parser = parse_cycles)]
    pub vcd_cycles: Option<Range<u64>>,
    /// The BVH build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// Where the time series of a statistics file goes: `<stem>.timeseries.csv` beside it.
pub fn time_series_path(out: &Path) -> PathBuf {
    out.with_extension("timeseries.csv")
}

/// Run `vtq sim`.
pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    let mut cfg = crate::model::designs::load(args.config.as_deref(), &args.set)?;
    if args.lockstep {
        cfg.sim.lockstep = true;
    }
    let vcd = match (&args.vcd, &args.vcd_cycles) {
        (Some(path), Some(cycles)) => Some(VcdWindow {
            path: path.clone(),
            sm: args.vcd_sm.unwrap_or(0),
            cycles: cycles.clone(),
        }),
        _ => None,
    };
    if vcd.is_some() && args.sample.point.is_some() {
        anyhow::bail!("--vcd records a full-detail run: it cannot be combined with --sample");
    }
    check_outputs(args)?;
    let scene = load_scene(&args.scene)?;
    if let Some(spec) = &args.sample.point {
        cfg.sample.apply_spec(spec).map_err(anyhow::Error::msg)?;
        cfg.sample.validate(&cfg)?;
        let bvh = build_bvh(&scene, &cfg.bvh_params(), &args.cache)?;
        return run_sampled(args, &scene, &bvh, &cfg);
    }
    let bvh = build_bvh(&scene, &cfg.bvh_params(), &args.cache)?;
    let options = SimOptions {
        threads: args.threads,
        vcd,
        ..SimOptions::default()
    };
    let out = simulate_with_progress(&scene, &bvh, &cfg, options)?;
    let s = &out.stats;
    let json = serde_json::to_string_pretty(s).context("serializing the statistics")? + "\n";
    // Every output is attempted; one that cannot be written is kept in a fallback file.
    let mut failures = Failures::default();
    failures.note(write_json(&args.out, &json));
    let csv = time_series_path(&args.out);
    failures.note(write_or_keep(&csv, |p| {
        write_time_series(p, &out.time_series)
    }));
    println!(
        "sim: {} cycles, {} rays, SIMT efficiency {:.3}, BVH L1 miss rate {:.3}; {:.2} s wall, \
         {:.0} simulated rays/s",
        s.cycles,
        s.rays,
        s.simt_efficiency,
        s.bvh_l1_miss_rate,
        s.sim_wall_seconds,
        s.simulated_rays_per_second
    );
    let e = &s.energy;
    println!(
        "energy ({}): {:.4} mJ/frame, {:.2} W, {:.2} nJ/ray, {:.0}% time-proportional, {:.1}% \
         virtualization (docs/energy.md)",
        e.coefficients,
        e.total_mj,
        e.average_power_w,
        e.nj_per_ray,
        100.0 * e.time_share,
        100.0 * e.virtualization_share
    );
    if failures.is_empty() {
        println!("wrote {} and {}", args.out.display(), csv.display());
    }
    if let Some(w) = &out.waveform {
        println!(
            "wrote {} (the RT unit of SM {} over cycles {}..{}; {} of them idle, stepped only \
             for the waveform)",
            w.path.display(),
            w.sm,
            w.cycles.start,
            w.cycles.end,
            w.idle_steps
        );
    }
    if let Some(path) = &args.ctas {
        let written = failures.note(write_or_keep(path, |p| {
            std::fs::write(p, cta_csv(&out.cta_spans))
        }));
        if written {
            println!("wrote {}", path.display());
        }
    }
    if let Some(path) = &args.image {
        let written = failures.note(write_or_keep(path, |p| {
            write_png(p, cfg.workload.width, cfg.workload.height, &out.image).map(|_| ())
        }));
        if written {
            println!("wrote {}", path.display());
        }
    }
    failures.finish()
}

/// Checks before the work that every file the run writes can be created (the statistics, the
/// time series of a full-detail run, the image, the waveform), so that a bad path fails at once.
fn check_outputs(args: &SimArgs) -> anyhow::Result<()> {
    check_file(&args.out)?;
    if args.sample.point.is_none() {
        check_file(&time_series_path(&args.out))?;
    }
    for path in args.image.iter().chain(&args.vcd).chain(&args.ctas) {
        check_file(path)?;
    }
    Ok(())
}

/// The CTA spans of a run, per SM, as CSV (`cta,sm,start,end`), in CTA order.
fn cta_csv(spans: &[Vec<CtaSpan>]) -> String {
    let mut rows: Vec<(usize, &CtaSpan)> = spans
        .iter()
        .enumerate()
        .flat_map(|(sm, v)| v.iter().map(move |s| (sm, s)))
        .collect();
    rows.sort_by_key(|(_, s)| s.cta);
    let mut out = String::from("cta,sm,start,end\n");
    for (sm, s) in rows {
        out += &format!("{},{},{},{}\n", s.cta, sm, s.start, s.end);
    }
    out
}

/// Writes the JSON text `json` to `path`, or keeps it in a fallback file the error names.
fn write_json(path: &Path, json: &str) -> anyhow::Result<()> {
    write_or_keep(path, |p| std::fs::write(p, json))
}

/// `vtq sim --sample`: the sampled tier's estimates, written as JSON (docs/accuracy.md).
fn run_sampled(
    args: &SimArgs,
    scene: &crate::model::scene::Scene,
    bvh: &crate::model::bvh::HwBvh,
    cfg: &SimConfig,
) -> anyhow::Result<()> {
    let profile = Profile::new(scene, bvh, cfg)
        .with_context(|| format!("profiling scene '{}'", scene.name))?;
    let s = simulate_sampled(scene, bvh, cfg, &profile, args.threads)
        .with_context(|| format!("simulating scene '{}' (sampled)", scene.name))?;
    let json = serde_json::to_string_pretty(&s).context("serializing the estimates")?;
    write_json(&args.out, &(json + "\n"))?;
    let how = match s.method {
        crate::estimate::sample::Method::Strata => format!(
            "{} replicates of {} SM(s) on 1/{:.0} of the frame{}, 95% intervals{}",
            s.replicates,
            s.scale_sms,
            1.0 / s.fraction,
            match &s.cluster {
                Cluster::Each(1) => String::new(),
                c => format!(" in units of {c} neighbouring CTAs"),
            },
            if s.stripes_dynamic {
                "; stratified because the stripes' scale model found the CTA dispatch not static"
            } else {
                ""
            }
        ),
        crate::estimate::sample::Method::Stripes => {
            let stripes: Vec<Vec<u32>> =
                s.replicate_runs.iter().map(|r| r.stripes.clone()).collect();
            format!(
                "the stripes ranked slowest, {stripes:?}, on scale models of {} SM(s); \
                 cycles within the validated bound",
                s.scale_sms
            )
        }
    };
    let rays = if s.rays_estimated {
        format!(
            "about {} rays (profiled from 1 warp in {} of the frame's)",
            s.rays, cfg.sample.profile_stride
        )
    } else {
        format!("{} rays", s.rays)
    };
    println!(
        "sim (sampled: {how}): cycles {}, {rays}, SIMT efficiency {}, BVH L1 miss rate {}; \
         {:.2} s wall ({:.2} s profile)",
        s.cycles.display(0),
        s.simt_efficiency.display(3),
        s.bvh_l1_miss_rate.display(3),
        s.profile_seconds + s.sim_seconds,
        s.profile_seconds
    );
    if s.method == crate::estimate::sample::Method::Stripes {
        println!("note: {}", crate::estimate::sample::STRIPE_NOTE);
    } else if s.every_cta_resident {
        println!("caution: {}", crate::estimate::sample::STRIPE_CAUTION);
    }
    for note in sample_points::notes(args.sample.point.as_deref(), cfg) {
        println!("note: {note}");
    }
    println!("wrote {}", args.out.display());
    Ok(())
}
