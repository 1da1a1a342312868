//! [`ResultStore`]: a results folder holding one JSON file per run, `DIR/runs/<key>.json`,
//! named by the run's [`RunKey`] and written atomically (temporary file + rename), so a killed
//! sweep leaves only whole files and a rerun skips every run already recorded.
//!
//! [`ResultStore::run_or_load`] is the one call a command needs to get a (scene,
//! configuration) point's statistics: the stored record if there is one, else a fresh
//! simulation, stored before it is returned.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use super::key::{RunKey, Tier, RESULT_FORMAT};
use super::prepared::{BvhBuilder, PreparedScene};
use super::record::{RunRecord, RunStatus};
use crate::model::atomic_file::write_atomic;
use crate::model::config::SimConfig;

/// The folder of result files inside a results folder.
pub const RUNS_DIR: &str = "runs";

/// Extension of result files.
const EXTENSION: &str = "json";

/// Whether a stored failed run counts as done.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reuse {
    /// Reuse every stored record, failed ones included (a failure is deterministic).
    Recorded,
    /// Reuse successful records; run failed points again.
    RetryFailed,
}

impl Reuse {
    /// Whether `record` needs no new run.
    pub fn is_done(self, record: &RunRecord) -> bool {
        record.status == RunStatus::Ok || self == Reuse::Recorded
    }
}

/// Where a [`ResultStore::run_or_load`] record came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fetched {
    /// Read from the store.
    Stored,
    /// Simulated now (and stored).
    Ran,
}

/// A results folder.
#[derive(Debug, Clone)]
pub struct ResultStore {
    dir: PathBuf,
}

impl ResultStore {
    /// The store in `dir` (created when the first result is saved).
    pub fn new(dir: impl Into<PathBuf>) -> ResultStore {
        ResultStore { dir: dir.into() }
    }

    /// The results folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The folder of result files.
    pub fn runs_dir(&self) -> PathBuf {
        self.dir.join(RUNS_DIR)
    }

    /// The result file of `key`.
    pub fn path(&self, key: &RunKey) -> PathBuf {
        self.runs_dir().join(format!("{}.{EXTENSION}", key.hex()))
    }

    /// The stored record of `key`: `None` when there is none; an error naming the file when
    /// it cannot be read or is not a result file of this format for this key.
    pub fn load(&self, key: &RunKey) -> anyhow::Result<Option<RunRecord>> {
        let path = self.path(key);
        match std::fs::read_to_string(&path) {
            Ok(text) => read_record(&path, &text, Some(&key.hex())).map(Some),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
        }
    }

    /// Stores `record` (atomically) under its key.
    pub fn save(&self, record: &RunRecord) -> anyhow::Result<()> {
        let path = self.runs_dir().join(format!("{}.{EXTENSION}", record.key));
        let text = serde_json::to_string_pretty(record).context("serializing the result record")?;
        write_atomic(&path, (text + "\n").as_bytes()).map_err(anyhow::Error::msg)
    }

    /// Every stored record, in key order. Files that are not result files (temporary files of a
    /// write in progress or killed, other names) are ignored; a result file that cannot be read
    /// is an error naming it.
    pub fn records(&self) -> anyhow::Result<Vec<RunRecord>> {
        let dir = self.runs_dir();
        let entries = match std::fs::read_dir(&dir) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                bail!(
                    "{} holds no results ({} is missing)",
                    self.dir.display(),
                    dir.display()
                )
            }
            Err(e) => return Err(e).with_context(|| format!("cannot list {}", dir.display())),
        };
        let mut records = Vec::new();
        for entry in entries {
            let path = entry
                .with_context(|| format!("cannot list {}", dir.display()))?
                .path();
            let Some(stem) = result_stem(&path) else {
                continue;
            };
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            records.push(read_record(&path, &text, Some(stem))?);
        }
        records.sort_by(|a, b| a.key.cmp(&b.key));
        Ok(records)
    }

    /// The record of simulating `config` on `scene` in a tier: the stored one if it is done (see
    /// [`Reuse`]), else a new run (BVH from `build`), stored before it is returned. A stored
    /// file that cannot be read is replaced by a new run.
    pub fn run_or_load(
        &self,
        scene: &PreparedScene,
        (config, tier): (&SimConfig, Tier),
        reuse: Reuse,
        build: &BvhBuilder,
    ) -> anyhow::Result<(RunRecord, Fetched)> {
        let key = RunKey::for_tier(&scene.hash, config, tier)?;
        if let Ok(Some(record)) = self.load(&key) {
            if reuse.is_done(&record) {
                return Ok((record, Fetched::Stored));
            }
        }
        let record = scene.simulate(config, tier, build)?;
        self.save(&record)?;
        Ok((record, Fetched::Ran))
    }
}

/// The key of a result file's path (`<64 hex digits>.json`), `None` for any other file.
fn result_stem(path: &Path) -> Option<&str> {
    if path.extension()? != EXTENSION {
        return None;
    }
    let stem = path.file_stem()?.to_str()?;
    (stem.len() == 64 && stem.bytes().all(|b| b.is_ascii_hexdigit())).then_some(stem)
}

/// Parses a result file and checks its format and key.
fn read_record(path: &Path, text: &str, key: Option<&str>) -> anyhow::Result<RunRecord> {
    let record: RunRecord = serde_json::from_str(text)
        .with_context(|| format!("{} is not a result file", path.display()))?;
    if record.format != RESULT_FORMAT {
        bail!(
            "{}: result format {}, this vtq reads {RESULT_FORMAT}",
            path.display(),
            record.format
        );
    }
    if let Some(key) = key.filter(|k| *k != record.key) {
        bail!(
            "{}: holds the result of key {}, not {key}",
            path.display(),
            record.key
        );
    }
    if (record.status == RunStatus::Ok) != record.result.is_some() {
        bail!(
            "{}: status {} does not match its contents",
            path.display(),
            record.status.name()
        );
    }
    Ok(record)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::sweep::prepared::cached_builder;
    use crate::model::scene::builtin::cornell;

    fn temp_store(test: &str) -> ResultStore {
        let dir = std::env::temp_dir().join(format!("vtq-store-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        ResultStore::new(dir)
    }

    fn tiny(sets: &[&str]) -> SimConfig {
        let mut all = vec!["width=8", "height=8", "bounces=1", "gpu.sms=2"];
        all.extend_from_slice(sets);
        let all: Vec<String> = all.into_iter().map(String::from).collect();
        SimConfig::load_unvalidated(None, &all).unwrap()
    }

    #[test]
    fn run_or_load_runs_once_then_loads() {
        let store = temp_store("once");
        let scene = PreparedScene::new("cornell", cornell());
        let build = cached_builder(None);
        let cfg = tiny(&[]);
        let (first, how) = store
            .run_or_load(&scene, (&cfg, Tier::Full), Reuse::Recorded, &build)
            .unwrap();
        assert_eq!(how, Fetched::Ran);
        assert_eq!(first.status, RunStatus::Ok);
        assert!(first.stats().unwrap()["cycles"].as_u64().unwrap() > 0);
        let (second, how) = store
            .run_or_load(&scene, (&cfg, Tier::Full), Reuse::Recorded, &build)
            .unwrap();
        assert_eq!(how, Fetched::Stored);
        assert_eq!(second, first);
        assert_eq!(store.records().unwrap(), vec![first.clone()]);
        // A corrupt file is not trusted: load names it, run_or_load replaces it.
        let key = RunKey::new(&scene.hash, &cfg).unwrap();
        std::fs::write(store.path(&key), "{ half a file").unwrap();
        let err = format!("{:#}", store.load(&key).unwrap_err());
        assert!(
            err.contains(&key.hex()) && err.contains("not a result file"),
            "{err}"
        );
        assert!(store.records().is_err());
        let (third, how) = store
            .run_or_load(&scene, (&cfg, Tier::Full), Reuse::Recorded, &build)
            .unwrap();
        assert_eq!(how, Fetched::Ran);
        assert_eq!(
            third.comparable_stats(),
            first.comparable_stats(),
            "deterministic"
        );
        assert_eq!(
            third.result.unwrap().time_series,
            first.result.unwrap().time_series
        );
        let _ = std::fs::remove_dir_all(store.dir());
    }

    #[test]
    fn failures_are_recorded_and_retried_only_on_request() {
        let store = temp_store("fail");
        let scene = PreparedScene::new("cornell", cornell());
        let build = cached_builder(None);
        let cfg = tiny(&["hw.repack_threshold=99"]);
        let (rec, how) = store
            .run_or_load(&scene, (&cfg, Tier::Full), Reuse::Recorded, &build)
            .unwrap();
        assert_eq!((rec.status, how), (RunStatus::Failed, Fetched::Ran));
        let error = rec.error.as_deref().unwrap();
        assert!(error.contains("repack_threshold"), "{error}");
        let (_, how) = store
            .run_or_load(&scene, (&cfg, Tier::Full), Reuse::Recorded, &build)
            .unwrap();
        assert_eq!(how, Fetched::Stored);
        let (_, how) = store
            .run_or_load(&scene, (&cfg, Tier::Full), Reuse::RetryFailed, &build)
            .unwrap();
        assert_eq!(how, Fetched::Ran);
        // Temporary files and other names are not results.
        std::fs::write(
            store.runs_dir().join(format!("{}.json.tmp.1.0", rec.key)),
            "x",
        )
        .unwrap();
        std::fs::write(store.runs_dir().join("notes.json"), "x").unwrap();
        assert_eq!(store.records().unwrap().len(), 1);
        let _ = std::fs::remove_dir_all(store.dir());
    }
}
