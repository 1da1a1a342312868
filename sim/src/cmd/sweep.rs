//! `vtq sweep`: run a grid or list of configurations over scenes into a results folder (one
//! result file per run, keyed by content, so a rerun resumes), as local parallel runs, one
//! shard of them, or a Slurm job array; and `vtq sweep --collect`, the tidy CSV table of the
//! results. See docs/sweeps.md.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

use crate::bvh::{BvhParams, HwBvh};
use crate::cmd::options::{build_bvh, load_scene, CacheArgs};
use crate::output::{check_dir, check_file_or_dirs};
use crate::scene::Scene;
use crate::sweep::collect::{table, Row};
use crate::sweep::key::VTQ_VERSION;
use crate::sweep::run::{run_tasks, Task};
use crate::sweep::slurm::{SlurmJob, TABLE_FILE};
use crate::sweep::{Point, PreparedScene, ResultStore, Reuse, RunKey, RunRecord, RunStatus};
use crate::sweep::{Shard, SweepSpec};

/// Options of `vtq sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Sweep file (TOML: scenes, configs, set, [grid], [[points]]; docs/sweeps.md). The
    /// options below add to it.
    #[arg(long, value_name = "FILE")]
    pub spec: Option<PathBuf>,
    /// Scene: a built-in name (`wknd`, `cornell`, `city:N`), a folder under ../shared/scenes,
    /// a scene folder path or a `.obj` file (repeatable).
    #[arg(long = "scene", value_name = "SCENE")]
    pub scenes: Vec<String>,
    /// Base configuration file (TOML, docs/config.md; repeatable: every point runs on each)
    /// [default: the baseline GPU].
    #[arg(long = "config", value_name = "FILE")]
    pub configs: Vec<PathBuf>,
    /// Override one configuration key in every point, e.g. `--set width=64` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Sweep one key over values, e.g. `--grid hw.repack_threshold=16,22,28` (repeatable: the
    /// points are every combination).
    #[arg(long = "grid", value_name = "KEY=V1,V2,...")]
    pub grids: Vec<String>,
    /// Results folder: one result file per run in DIR/runs, reused by every later sweep.
    #[arg(long, value_name = "DIR")]
    pub results: Option<PathBuf>,
    /// Runs at once, one thread each [default: the available cores].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub jobs: Option<u32>,
    /// Run points whose stored result is a failure again (by default a failure is final).
    #[arg(long)]
    pub retry_failed: bool,
    /// Run only the I-th (from 0) of N slices of the points (round robin), e.g. `--shard 2/8`.
    #[arg(long, value_name = "I/N", conflicts_with = "slurm")]
    pub shard: Option<Shard>,
    /// Write a Slurm job-array script (and beside it its collect job's script and the sweep
    /// file) instead of running.
    #[arg(long, value_name = "SCRIPT")]
    pub slurm: Option<PathBuf>,
    /// Array tasks of the Slurm job [default: one per point].
    #[arg(long, requires = "slurm", value_parser = clap::value_parser!(u32).range(1..))]
    pub shards: Option<u32>,
    /// Submit the Slurm job array and the collect job that runs after it (`sbatch`).
    #[arg(long, requires = "slurm")]
    pub submit: bool,
    /// An extra `#SBATCH` option of the Slurm jobs, e.g. `--sbatch-arg=--partition=short`
    /// (repeatable).
    #[arg(
        long = "sbatch-arg",
        value_name = "OPTION",
        requires = "slurm",
        allow_hyphen_values = true
    )]
    pub sbatch_args: Vec<String>,
    /// Collect the results in DIR into one CSV table (of the sweep given, if one is: its
    /// points without a result show as `missing`; else of every stored run).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["results", "shard", "slurm", "jobs", "retry_failed"])]
    pub collect: Option<PathBuf>,
    /// Where `--collect` writes the table [default: DIR/table.csv].
    #[arg(long, value_name = "FILE", requires = "collect")]
    pub out: Option<PathBuf>,
    /// The BVH build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

impl SweepArgs {
    /// The sweep file (if any) with the command line's scenes, configurations, overrides and
    /// grids added.
    fn spec(&self) -> anyhow::Result<SweepSpec> {
        let mut spec = match &self.spec {
            Some(path) => SweepSpec::from_file(path)?,
            None => SweepSpec::default(),
        };
        spec.scenes.extend(self.scenes.iter().cloned());
        spec.configs.extend(self.configs.iter().cloned());
        spec.set.extend(self.set.iter().cloned());
        for grid in &self.grids {
            spec.add_grid_arg(grid)?;
        }
        Ok(spec)
    }

    /// Whether a sweep is defined (or begun) on the command line or by a file.
    fn has_sweep(&self) -> bool {
        self.spec.is_some()
            || !self.scenes.is_empty()
            || !self.configs.is_empty()
            || !self.set.is_empty()
            || !self.grids.is_empty()
    }
}

/// Run `vtq sweep`.
pub fn run(args: &SweepArgs) -> anyhow::Result<()> {
    if let Some(dir) = &args.collect {
        check_file_or_dirs(&args.out.clone().unwrap_or_else(|| dir.join(TABLE_FILE)))?;
        return collect(args, dir);
    }
    let spec = args.spec()?;
    let Some(results) = &args.results else {
        bail!("--results DIR is required: the folder that holds one result file per run");
    };
    // The outputs are checked before any scene is loaded or run.
    check_dir(results)?;
    if let Some(script) = &args.slurm {
        check_file_or_dirs(script)?;
    }
    match &args.slurm {
        Some(script) => slurm(args, spec, results, script),
        None => sweep(args, &spec, results),
    }
}

/// Loads each distinct scene of `points` (printing a summary line each), in order.
pub(crate) fn prepare_scenes<'a>(
    points: impl IntoIterator<Item = &'a Point>,
) -> anyhow::Result<Vec<PreparedScene>> {
    let mut scenes: Vec<PreparedScene> = Vec::new();
    for point in points {
        if !scenes.iter().any(|s| s.spec == point.scene) {
            scenes.push(PreparedScene::new(&point.scene, load_scene(&point.scene)?));
        }
    }
    Ok(scenes)
}

/// The prepared scene of `point`.
pub(crate) fn scene_of<'a>(scenes: &'a [PreparedScene], point: &Point) -> &'a PreparedScene {
    scenes
        .iter()
        .find(|s| s.spec == point.scene)
        .expect("every point's scene was prepared")
}

/// One line about a finished run.
fn describe(record: &RunRecord) -> String {
    match (record.status, record.stats()) {
        (RunStatus::Ok, Some(s)) => format!(
            "ok: {} cycles, SIMT efficiency {:.3}, BVH L1 miss rate {:.3} ({:.2} s)",
            s["cycles"],
            s["simt_efficiency"].as_f64().unwrap_or(f64::NAN),
            s["bvh_l1_miss_rate"].as_f64().unwrap_or(f64::NAN),
            record.wall_seconds
        ),
        _ => format!(
            "FAILED: {}",
            record.error.as_deref().unwrap_or("no error recorded")
        ),
    }
}

/// Runs the sweep (or its shard) locally.
fn sweep(args: &SweepArgs, spec: &SweepSpec, results: &Path) -> anyhow::Result<()> {
    let points = spec.points()?;
    let total = points.len();
    let selected: Vec<&Point> = points
        .iter()
        .filter(|p| args.shard.is_none_or(|s| s.contains(p.index)))
        .collect();
    let scenes = prepare_scenes(selected.iter().copied())?;
    let store = ResultStore::new(results);
    let reuse = if args.retry_failed {
        Reuse::RetryFailed
    } else {
        Reuse::Recorded
    };
    let slice = match args.shard {
        Some(shard) => format!(", shard {shard}: {} of them", selected.len()),
        None => String::new(),
    };
    let runner = Runner {
        name: "sweep",
        store: &store,
        reuse,
        jobs: args.jobs,
        cache: &args.cache,
    };
    let failed = runner.run(&selected, &scenes, total, &slice)?;
    if !failed.is_empty() {
        bail!(
            "{} of {} points failed ({}); their errors are in their result files and in the \
             table of `vtq sweep --collect`; --retry-failed runs them again",
            failed.len(),
            selected.len(),
            failed.join("; ")
        );
    }
    Ok(())
}

/// Runs points into a result store, skipping those already done, with a progress bar on a
/// terminal and one line per finished run (shared by `vtq sweep` and `vtq reproduce`).
pub(crate) struct Runner<'a> {
    /// The command, prefixing every line.
    pub name: &'a str,
    /// Where results are stored and found.
    pub store: &'a ResultStore,
    /// Which stored results count as done.
    pub reuse: Reuse,
    /// Runs at once [default: the available cores].
    pub jobs: Option<u32>,
    /// The BVH build cache.
    pub cache: &'a CacheArgs,
}

impl Runner<'_> {
    /// Runs every point of `selected` (whose scenes are in `scenes`) that has no result in the
    /// store yet; `total` and `slice` describe the selection in the summary line. Returns the
    /// labels of the points whose run failed (now or earlier).
    pub fn run(
        &self,
        selected: &[&Point],
        scenes: &[PreparedScene],
        total: usize,
        slice: &str,
    ) -> anyhow::Result<Vec<String>> {
        let (name, store) = (self.name, self.store);
        // Which points are done: a result file with an ok run (or a failed one, unless retried).
        let mut pending: Vec<&Point> = Vec::new();
        let (mut done, mut failed_before) = (0usize, Vec::new());
        for &point in selected {
            let key = RunKey::new(&scene_of(scenes, point).hash, &point.config)
                .with_context(|| format!("{name} point {}", point.label))?;
            match store.load(&key) {
                Ok(Some(record)) if self.reuse.is_done(&record) => match record.status {
                    RunStatus::Ok => done += 1,
                    RunStatus::Failed => failed_before.push(point.label.clone()),
                },
                Ok(_) => pending.push(point),
                Err(e) => {
                    eprintln!("{name}: warning: {e:#}; running {} again", point.label);
                    pending.push(point);
                }
            }
        }
        let jobs = match self.jobs {
            Some(n) => n as usize,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        let at_a_time = match pending.len() {
            0 => String::new(),
            n => format!(", {} at a time", jobs.min(n)),
        };
        println!(
            "{name}: {total} point{}{slice}; {done} already done, {} failed earlier (skipped; \
             --retry-failed runs them again), {} to run{at_a_time}; results in {}",
            if total == 1 { "" } else { "s" },
            failed_before.len(),
            pending.len(),
            store.runs_dir().display()
        );

        // Build (or load) the BVHs first, so their summaries do not cut through the progress.
        let build = |scene: &Scene, params: &BvhParams| -> anyhow::Result<HwBvh> {
            build_bvh(scene, params, self.cache)
        };
        for point in &pending {
            let scene = scene_of(scenes, point);
            let params = point.config.bvh_params();
            if point.config.validate().is_ok() && !scene.has_bvh(&params) {
                if let Err(e) = scene.bvh(&params, &build) {
                    eprintln!("{name}: {e:#} (its points are recorded as failed)");
                }
            }
        }

        let tasks: Vec<Task> = pending
            .iter()
            .map(|p| Task {
                scene: scene_of(scenes, p),
                config: &p.config,
            })
            .collect();
        let bar = (std::io::stderr().is_terminal() && !tasks.is_empty()).then(|| {
            let bar = indicatif::ProgressBar::new(tasks.len() as u64);
            let template =
                format!("{name} {{bar:40}} {{pos}}/{{len}} runs {{elapsed}} (eta {{eta}}) {{msg}}");
            bar.set_style(
                indicatif::ProgressStyle::with_template(&template)
                    .expect("the progress template is valid"),
            );
            bar
        });
        let (mut ran, mut failed_now) = (0usize, Vec::new());
        let outcome = run_tasks(store, &tasks, jobs, &build, |i, record| {
            ran += 1;
            if record.status == RunStatus::Failed {
                failed_now.push(pending[i].label.clone());
            }
            let line = format!(
                "{name}: [{ran}/{}] {}: {}",
                tasks.len(),
                pending[i].label,
                describe(record)
            );
            match &bar {
                Some(bar) => {
                    bar.println(line);
                    bar.set_message(format!("last: {}", pending[i].label));
                    bar.inc(1);
                }
                None => println!("{line}"),
            }
        });
        if let Some(bar) = &bar {
            bar.finish_and_clear();
        }
        outcome?;
        println!(
            "{name}: ran {ran} ({} ok, {} failed), skipped {} ({done} done, {} failed earlier); \
             results in {}",
            ran - failed_now.len(),
            failed_now.len(),
            done + failed_before.len(),
            failed_before.len(),
            store.runs_dir().display()
        );
        Ok(failed_before.into_iter().chain(failed_now).collect())
    }
}

/// Writes (and with `--submit` submits) the Slurm jobs of the sweep.
fn slurm(
    args: &SweepArgs,
    mut spec: SweepSpec,
    results: &Path,
    script: &Path,
) -> anyhow::Result<()> {
    if script.extension().is_some_and(|e| e == "toml") {
        bail!(
            "--slurm {}: the script must not be a .toml file (the sweep file goes beside it)",
            script.display()
        );
    }
    let absolute = |p: &Path| {
        std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
    };
    // The jobs read the sweep from a file; its configuration paths must not depend on where.
    spec.configs = spec
        .configs
        .iter()
        .map(|p| absolute(p))
        .collect::<anyhow::Result<_>>()?;
    let points = spec.points()?;
    prepare_scenes(&points)?;
    let shards = args
        .shards
        .map_or(points.len(), |n| n as usize)
        .clamp(1, points.len().max(1));
    let script = absolute(script)?;
    let (collect_script, spec_file) = SlurmJob::companions(&script);
    let mut vtq_args = Vec::new();
    if args.retry_failed {
        vtq_args.push("--retry-failed".to_string());
    }
    if args.cache.no_cache {
        vtq_args.push("--no-cache".to_string());
    } else if let Some(dir) = &args.cache.cache_dir {
        vtq_args.extend([
            "--cache-dir".to_string(),
            absolute(dir)?.display().to_string(),
        ]);
    }
    let job = SlurmJob {
        script,
        collect_script,
        spec_file,
        results: absolute(results)?,
        shards,
        vtq: std::env::current_exe().context("cannot find the vtq executable")?,
        workdir: std::env::current_dir().context("cannot read the working directory")?,
        vtq_args,
        sbatch_args: args.sbatch_args.clone(),
    };
    job.write(&spec)?;
    println!(
        "sweep: {} points in {shards} array tasks; wrote {} (the job array), {} (its collect \
         job) and {} (the sweep)",
        points.len(),
        job.script.display(),
        job.collect_script.display(),
        job.spec_file.display()
    );
    if !args.submit {
        println!(
            "sweep: submit with `sbatch {}`, then `sbatch --dependency=afterany:<job id> {}` \
             (or add --submit)",
            job.script.display(),
            job.collect_script.display()
        );
        return Ok(());
    }
    let (array, collect) = job.submit()?;
    println!(
        "sweep: submitted job array {array} ({shards} tasks) and collect job {collect} (runs \
         after it); the table goes to {}",
        job.results.join(TABLE_FILE).display()
    );
    Ok(())
}

/// `vtq sweep --collect DIR`: the table of the sweep given (its points, `missing` where no
/// result exists) or of every stored run.
fn collect(args: &SweepArgs, dir: &Path) -> anyhow::Result<()> {
    let store = ResultStore::new(dir);
    let rows = if args.has_sweep() {
        let points = args.spec()?.points()?;
        let scenes = prepare_scenes(&points)?;
        let mut rows = Vec::with_capacity(points.len());
        for point in &points {
            let scene = scene_of(&scenes, point);
            let key = RunKey::new(&scene.hash, &point.config)
                .with_context(|| format!("sweep point {}", point.label))?;
            rows.push(match store.load(&key)? {
                Some(record) => Row::from_record(&record)?,
                None => Row::missing(
                    &scene.scene.name,
                    VTQ_VERSION,
                    &point.config.to_toml()?,
                    &key.hex(),
                )?,
            });
        }
        rows
    } else {
        store
            .records()?
            .iter()
            .map(Row::from_record)
            .collect::<anyhow::Result<_>>()?
    };
    let table = table(rows);
    let out = args.out.clone().unwrap_or_else(|| dir.join(TABLE_FILE));
    table
        .write_csv(&out)
        .with_context(|| format!("writing {}", out.display()))?;
    println!(
        "collect: {} runs ({}), {} columns; wrote {}",
        table.rows.len(),
        table.status_summary(),
        table.header.len(),
        out.display()
    );
    Ok(())
}
