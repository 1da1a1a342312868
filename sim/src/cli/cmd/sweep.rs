//! `vtq sweep`: run a grid or list of configurations over scenes into a results folder (one
//! result file per run, keyed by content, so a rerun resumes), as local parallel runs, one
//! shard of them, or a Slurm job array; and `vtq sweep --collect`, the tidy CSV table of the
//! results. See docs/sweeps.md.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

use super::options::{CacheArgs, SampleArg};
use super::runner::{listed, prepare_scenes, scene_of, Runner};
use crate::cli::output::{check_dir, check_file_or_dirs};
use crate::experiment::reproduce::built_in_experiment;
use crate::experiment::sweep::collect::{table, Row};
use crate::experiment::sweep::key::VTQ_VERSION;
use crate::experiment::sweep::slurm::{SlurmJob, TABLE_FILE};
use crate::experiment::sweep::{Point, ResultStore, Reuse};
use crate::experiment::sweep::{Shard, SweepSpec};

/// Options of `vtq sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Sweep file (TOML: scenes, configs, set, [grid], [[points]]; docs/sweeps.md), or the name
    /// of one of the project's experiment files (`fig10-speedup`; a built-in copy where
    /// `configs/experiments/` is not here). The options below add to it.
    #[arg(long, value_name = "FILE")]
    pub spec: Option<PathBuf>,
    /// Scene: a built-in name (`wknd`, `cornell`, `city:N`), a folder under ../shared/scenes,
    /// a scene folder path or a `.obj` file (repeatable).
    #[arg(long = "scene", value_name = "SCENE")]
    pub scenes: Vec<String>,
    /// Base configuration file (TOML, docs/config.md), or a built-in design's name (`vtq
    /// designs`); repeatable: every point runs on each [default: the baseline GPU].
    #[arg(long = "config", value_name = "FILE")]
    pub configs: Vec<PathBuf>,
    /// Override one configuration key in every point, e.g. `--set width=64` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Sweep one key over values, e.g. `--grid hw.repack_threshold=16,22,28` (repeatable: the
    /// points are every combination).
    #[arg(long = "grid", value_name = "KEY=V1,V2,...")]
    pub grids: Vec<String>,
    /// The sampled tier instead of full detail (`--sample [POINT]`).
    #[command(flatten)]
    pub sample: SampleArg,
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
            Some(path) => match built_in_experiment(path) {
                Some((name, text)) if !path.exists() => SweepSpec::from_toml(text)
                    .with_context(|| format!("built-in experiment file {name}"))?,
                _ => SweepSpec::from_file(path)?,
            },
            None => SweepSpec::default(),
        };
        spec.scenes.extend(self.scenes.iter().cloned());
        spec.configs.extend(self.configs.iter().cloned());
        spec.set.extend(self.set.iter().cloned());
        for grid in &self.grids {
            spec.add_grid_arg(grid)?;
        }
        if let Some(sample) = &self.sample.point {
            spec.sample = Some(sample.clone());
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
            || self.sample.point.is_some()
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
    let cfgs = selected.iter().map(|p| &p.config);
    for note in crate::model::config::sample_points::notes_of_all(spec.sample.as_deref(), cfgs) {
        println!("note: {note}");
    }
    let failed = runner.run(&selected, &scenes, total, &slice)?;
    if !failed.is_empty() {
        bail!(
            "{} of {} points failed ({}); their errors are in their result files and in the \
             table of `vtq sweep --collect`; --retry-failed runs them again",
            failed.len(),
            selected.len(),
            listed(&failed)
        );
    }
    Ok(())
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
    // The jobs read the sweep from a file; its configuration paths must not depend on where
    // (a built-in design's name or file, not a file here, stays as given: every node has it).
    spec.configs = spec
        .configs
        .iter()
        .map(|p| {
            if p.exists() {
                absolute(p)
            } else {
                Ok(p.clone())
            }
        })
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
            let key = point
                .key(&scene.hash)
                .with_context(|| format!("sweep point {}", point.label))?;
            rows.push(match store.load(&key)? {
                Some(record) => Row::from_record(&record)?,
                None => Row::missing(
                    &scene.scene.name,
                    VTQ_VERSION,
                    (&point.config.to_toml()?, point.tier),
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
