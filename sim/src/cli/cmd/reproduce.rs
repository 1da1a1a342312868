//! `vtq reproduce --out DIR`: runs the paper's experiment matrix (the experiment files of
//! `configs/experiments/` that docs/fidelity.md defines) over the scenes given through the
//! result store, then draws the paper's figures with its published values beside vtq's and
//! writes `DIR/index.html` and `DIR/index.md` (docs/reproducing.md).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use vtq_gen::area_report;

use super::area::{area_params, area_table};
use super::options::{build_bvh, CacheArgs, SampleArg};
use super::runner::{listed, prepare_scenes, Runner};
use crate::cli::output::check_dir;
use crate::estimate::figure5::{model, Figure5Row};
use crate::experiment::reproduce::energy;
use crate::experiment::reproduce::figures;
use crate::experiment::reproduce::matrix;
use crate::experiment::reproduce::page::Page;
use crate::experiment::reproduce::tables;
use crate::experiment::reproduce::{scene_labels, Experiments, Results};
use crate::experiment::sweep::{Point, PreparedScene, ResultStore, Reuse};
use crate::model::bvh::BvhParams;
use crate::model::config::SimConfig;
use crate::model::designs;
use crate::model::scene::Scene;
use crate::model::workload::pathtracer::render;

/// Options of `vtq reproduce`.
#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// Output folder: index.html, index.md, figures/ (SVG and PNG), tables/ (CSV).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Scene (repeatable) [default: the experiment files' scenes: every shared scene and wknd].
    #[arg(long = "scene", value_name = "SCENE")]
    pub scenes: Vec<String>,
    /// Results folder (one result file per run, shared with `vtq sweep --results`)
    /// [default: OUT/results].
    #[arg(long, value_name = "DIR")]
    pub results: Option<PathBuf>,
    /// The folder of the paper's experiment files [default: configs/experiments here, else
    /// vtq's built-in copies].
    #[arg(long, value_name = "DIR")]
    pub experiments: Option<PathBuf>,
    /// Override one configuration key in every run, e.g. `--set width=64` (repeatable; the
    /// page says so).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Runs at once, one thread each [default: the available cores].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub jobs: Option<u32>,
    /// Run points whose stored result is a failure again.
    #[arg(long)]
    pub retry_failed: bool,
    /// The sampled tier instead of full detail (`--sample [POINT]`).
    #[command(flatten)]
    pub sample: SampleArg,
    /// The BVH build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// Run `vtq reproduce`.
pub fn run(args: &ReproduceArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    check_dir(&args.out)?;
    if let Some(results) = &args.results {
        check_dir(results)?;
    }
    let experiments = args
        .experiments
        .clone()
        .map_or_else(Experiments::default_source, Experiments::Folder);
    experiments.check()?;
    let root = experiments.root();

    // Every experiment's points, each distinct run once.
    let sample = args.sample.point.as_deref();
    let (points, paper_points) = matrix::points(&experiments, &args.scenes, &args.set, sample)?;
    let scenes = prepare_scenes(&points)?;
    let paper_scenes = matrix::prepare_count(&scenes, &points[..paper_points]);
    let results_dir = args
        .results
        .clone()
        .unwrap_or_else(|| args.out.join("results"));
    let store = ResultStore::new(&results_dir);
    let runner = Runner {
        name: "reproduce",
        store: &store,
        reuse: if args.retry_failed {
            Reuse::RetryFailed
        } else {
            Reuse::Recorded
        },
        jobs: args.jobs,
        cache: &args.cache,
    };
    let selected: Vec<&Point> = points.iter().collect();
    let failed = runner.run(&selected, &scenes, points.len(), "")?;
    let cfgs = points.iter().map(|p| &p.config);
    for note in crate::model::config::sample_points::notes_of_all(sample, cfgs) {
        println!("note: {note}");
    }

    // The figures, from the stored runs (with --set, looked up with the same overrides).
    let figures_dir = args.out.join("figures");
    std::fs::create_dir_all(&figures_dir)
        .with_context(|| format!("creating {}", figures_dir.display()))?;
    let results = Results::new(&store, &scenes[..paper_scenes], root.clone())
        .with_sets(&args.set)
        .with_sample(sample);
    let all_results = Results::new(&store, &scenes, root.clone())
        .with_sets(&args.set)
        .with_sample(sample);
    let out = args.out.as_path();
    // A figure that cannot be drawn leaves a note on the page instead of stopping the others
    // (the runs are stored: a rerun draws it without running them again).
    let mut undrawn: Vec<String> = Vec::new();
    let mut figures = matrix::draw_figures((&results, &all_results), out, sample, &mut undrawn);
    let vtq_path = root.join("configs/designs/vtq/config.toml");
    let vtq = designs::load(Some(&vtq_path), &args.set)?;
    let fig5 = figure5_rows(&scenes[..paper_scenes], &vtq, &args.cache)
        .and_then(|rows| figures::figure5(&rows, out));
    figures.insert(0, matrix::or_note("fig05", "Figure 5", fig5, &mut undrawn));
    let area = area_report(&vtq.hw, &area_params(&vtq))?;
    let page = Page {
        title: "vtq: the paper's figures reproduced".into(),
        intro: intro(
            args,
            &experiments,
            &results_dir,
            &scenes,
            points.len(),
            &failed,
            start.elapsed().as_secs_f64(),
        ),
        figures,
        tables: vec![
            (
                "Section 6.5: treelet queues at once".into(),
                "The most treelet queues the count table tracked at once in VTQ and the most \
                 holding at least the underpopulation threshold (127) rays; a full table (600 \
                 entries) evicts its smallest queue. The paper: at most 549 and 13."
                    .into(),
                tables::section65(&results),
            ),
            (
                "Section 6.6: ray virtualization's share of the energy".into(),
                "CTA-state traffic's share of VTQ's energy under each coefficient set \
                 (docs/energy.md; an estimate), and the share of VTQ's energy saved when its \
                 state moves for free (Figure 16's run, time included). The paper: \
                 virtualization is 11% of the design's energy."
                    .into(),
                energy::section66(&results),
            ),
            (
                "Section 6.5: storage and area of the tables".into(),
                "The analytical area model of docs/area.md (`vtq area`) at the VTQ \
                 configuration: the paper gives 2.2 KB for the count table, 6.29 KB for the \
                 queue table and 128 KB of ray records."
                    .into(),
                area_table(&area),
            ),
        ],
    };
    page.write(out)?;
    println!(
        "reproduce: {} runs ({} failed), {} figures; wrote {} and {} in {:.1} s",
        points.len(),
        failed.len(),
        page.figures.len(),
        out.join("index.html").display(),
        out.join("index.md").display(),
        start.elapsed().as_secs_f64()
    );
    let mut problems = Vec::new();
    if !undrawn.is_empty() {
        problems.push(format!(
            "{} figure(s) not drawn ({}); the results are stored in {}: a rerun draws them \
             without running again",
            undrawn.len(),
            undrawn.join("; "),
            results_dir.display()
        ));
    }
    if !failed.is_empty() {
        problems.push(format!(
            "{} runs failed ({}); the figures leave them out (shown as `-`); their errors are in \
             their result files (`vtq sweep --collect` tables them); --retry-failed runs them \
             again",
            failed.len(),
            listed(&failed)
        ));
    }
    if !problems.is_empty() {
        anyhow::bail!("{}", problems.join("; "));
    }
    Ok(())
}

/// Batch sizes of the Figure 5 model: one warp up to the whole GPU's 16 x 4096 rays.
const FIGURE5_RAYS: [u64; 9] = [32, 128, 512, 1024, 2048, 4096, 8192, 16384, 65536];

/// The Figure 5 model's rows of every scene (by its name, [`scene_labels`]), from its
/// functional render under `cfg`.
fn figure5_rows(
    scenes: &[PreparedScene],
    cfg: &SimConfig,
    cache: &CacheArgs,
) -> anyhow::Result<Vec<(String, Vec<Figure5Row>)>> {
    let build = |scene: &Scene, params: &BvhParams| build_bvh(scene, params, cache);
    scenes
        .iter()
        .zip(scene_labels(scenes))
        .map(|(s, name)| {
            let bvh = s.bvh(&cfg.bvh_params(), &build)?;
            let rendered = render(&s.scene, bvh.as_ref(), &cfg.render_settings(), None)
                .with_context(|| format!("rendering scene '{}' for Figure 5", s.spec))?;
            let rows = model(&bvh, &rendered, cfg.gpu.threads_per_cta, &FIGURE5_RAYS);
            Ok((name, rows))
        })
        .collect()
}

/// The page's opening paragraphs: what was run, how, and how to rerun it.
fn intro(
    args: &ReproduceArgs,
    experiments: &Experiments,
    results: &Path,
    scenes: &[PreparedScene],
    runs: usize,
    failed: &[String],
    seconds: f64,
) -> Vec<String> {
    // Each scene by its name, with what it was given as where that differs.
    let names: Vec<String> = scenes
        .iter()
        .zip(scene_labels(scenes))
        .map(|(s, name)| {
            if name.eq_ignore_ascii_case(&s.spec) {
                name
            } else {
                format!("{name} (`{}`)", s.spec)
            }
        })
        .collect();
    let mut intro = vec![
        format!(
            "The figures of Chou & Aamodt, Virtualized Treelet Queues (ASPLOS 2025), measured by \
             vtq {} on {} ({} distinct runs of the experiment files in {}; docs/fidelity.md \
             explains every deviation). Dashed lines are the paper's published values where it \
             gives numbers (the paper simulated all of LumiBench in Vulkan-Sim; the shared scenes \
             are smaller subsets). Means leave the built-in scenes out.",
            crate::experiment::sweep::key::VTQ_VERSION,
            names.join(", "),
            runs,
            experiments.describe()
        ),
        format!(
            "Rerun: `vtq reproduce --out {}{}` (results are stored in `{}`, so a rerun only \
             draws, and an interrupted one resumes). This page took {seconds:.0} s including the \
             runs that were not stored yet.",
            args.out.display(),
            args.scenes
                .iter()
                .map(|s| format!(" --scene {s}"))
                .chain(args.set.iter().map(|s| format!(" --set {s}")))
                .chain(args.sample.point.iter().map(|p| format!(" --sample {p}")))
                .collect::<String>(),
            results.display()
        ),
    ];
    if let Some(point) = &args.sample.point {
        intro.push(format!(
            "Estimates, not full detail: every run was simulated by the sampled tier at \
             sample point `{point}` (docs/accuracy.md gives its measured speed and error): each \
             value is an estimate, drawn with its 95% interval as an error bar and given with \
             it in brackets in the tables (speedups paired per replicate; means and stacked \
             shares without one). Figures of statistics the tier does not estimate are left \
             out and say so; the section 6.5 and 6.6 tables need full detail's counts and show \
             `-`. Full detail: the same command without --sample."
        ));
    }
    if !args.set.is_empty() {
        intro.push(format!(
            "Every run has these overrides: {}.",
            args.set
                .iter()
                .map(|s| format!("`{s}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if !failed.is_empty() {
        intro.push(format!(
            "{} failed runs, left out of the figures (their errors are in their result files): \
             {}.",
            failed.len(),
            listed(failed)
        ));
    }
    intro
}
