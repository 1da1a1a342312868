//! `vtq reproduce`: the paper's experiment matrix run through the result store, and its figures
//! (docs/reproducing.md).
//!
//! The experiments are the sweep files of `configs/experiments/` that `docs/fidelity.md` defines
//! ([`FIGURE_EXPERIMENTS`]): one definition per experiment, shared by `vtq sweep --spec`, the
//! fidelity study and this command. Their points run into a [`ResultStore`], so a reproduction
//! that is interrupted resumes, and a point any sweep already ran is not run again. The figures
//! ([`figures`]) and the section 6.5 tables ([`tables`]) read the stored statistics through
//! [`Results`], which names each scene by its own name ([`scene_labels`]), and are written as
//! SVG and PNG with the paper's published values drawn beside vtq's, on an HTML page and its
//! Markdown twin ([`page`]). Figure 17 and section 6.6's energy table ([`energy`]) evaluate the
//! energy model on the stored runs of Figures 10 and 16. [`matrix`] says what a reproduction
//! runs and draws.

pub mod beyond;
pub mod cause_g;
pub mod energy;
pub mod figures;
pub mod matrix;
pub mod page;
pub mod tables;

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_json::Value as Json;

use crate::estimate::sample::stored::{stored_estimate, stored_speedup};
use crate::estimate::sample::Estimate;
use crate::experiment::sweep::spec::apply_sample;
use crate::experiment::sweep::{PreparedScene, ResultStore, RunKey, RunStatus, SweepSpec};
use crate::model::config::SimConfig;

/// The experiment files (stems in `configs/experiments/`) the figures are computed from.
pub const FIGURE_EXPERIMENTS: [&str; 9] = [
    "fig01-baseline",
    "fig10-speedup",
    "fig11-treelet-stationary",
    "fig12-grouping",
    "fig13-repack",
    "fig14-15-phases",
    "fig16-virtualization",
    "sec65-queues",
    "ext-vtq-prefetch",
];

/// The experiment files of docs/fidelity.md's cause G that `vtq reproduce` also runs and draws
/// ([`cause_g`]): the factorial over VTQ's mechanisms and the map of when the
/// treelet-stationary phase pays. (`dev-treelet-map-size` and `dev-treelet-readings` are sweeps
/// of their own: city:32M alone takes 9.4 GB.)
pub const CAUSE_G_EXPERIMENTS: [&str; 2] = ["dev-mechanisms", "dev-treelet-map"];

/// The experiment files of docs/fidelity.md's "Beyond the paper" sections that `vtq reproduce`
/// runs on scenes of their own (their figures are in [`beyond`]): the paper's predictions about
/// samples per pixel and bounces.
pub const BEYOND_EXPERIMENTS: [&str; 1] = ["ext-workload-predictions"];

/// The experiment files of `configs/experiments/`, compiled in as (stem, text), so `vtq
/// reproduce` and `vtq sweep --spec` run from any directory (a cluster node with only the binary).
pub const EXPERIMENT_FILES: [(&str, &str); 24] = [
    (
        "dev-frame-size",
        include_str!("../../../../configs/experiments/dev-frame-size.toml"),
    ),
    (
        "dev-mechanisms",
        include_str!("../../../../configs/experiments/dev-mechanisms.toml"),
    ),
    (
        "dev-memory",
        include_str!("../../../../configs/experiments/dev-memory.toml"),
    ),
    (
        "dev-queued-stacks",
        include_str!("../../../../configs/experiments/dev-queued-stacks.toml"),
    ),
    (
        "dev-scene-size",
        include_str!("../../../../configs/experiments/dev-scene-size.toml"),
    ),
    (
        "dev-shader-timing",
        include_str!("../../../../configs/experiments/dev-shader-timing.toml"),
    ),
    (
        "dev-treelet-formation",
        include_str!("../../../../configs/experiments/dev-treelet-formation.toml"),
    ),
    (
        "dev-treelet-map",
        include_str!("../../../../configs/experiments/dev-treelet-map.toml"),
    ),
    (
        "dev-treelet-map-size",
        include_str!("../../../../configs/experiments/dev-treelet-map-size.toml"),
    ),
    (
        "dev-treelet-readings",
        include_str!("../../../../configs/experiments/dev-treelet-readings.toml"),
    ),
    (
        "dev-virtualization-baseline",
        include_str!("../../../../configs/experiments/dev-virtualization-baseline.toml"),
    ),
    (
        "dev-virtualization-vtq",
        include_str!("../../../../configs/experiments/dev-virtualization-vtq.toml"),
    ),
    (
        "ext-vtq-prefetch",
        include_str!("../../../../configs/experiments/ext-vtq-prefetch.toml"),
    ),
    (
        "ext-workload-predictions",
        include_str!("../../../../configs/experiments/ext-workload-predictions.toml"),
    ),
    (
        "fig01-baseline",
        include_str!("../../../../configs/experiments/fig01-baseline.toml"),
    ),
    (
        "fig05-max-rays",
        include_str!("../../../../configs/experiments/fig05-max-rays.toml"),
    ),
    (
        "fig10-speedup",
        include_str!("../../../../configs/experiments/fig10-speedup.toml"),
    ),
    (
        "fig11-treelet-stationary",
        include_str!("../../../../configs/experiments/fig11-treelet-stationary.toml"),
    ),
    (
        "fig12-grouping",
        include_str!("../../../../configs/experiments/fig12-grouping.toml"),
    ),
    (
        "fig13-repack",
        include_str!("../../../../configs/experiments/fig13-repack.toml"),
    ),
    (
        "fig14-15-phases",
        include_str!("../../../../configs/experiments/fig14-15-phases.toml"),
    ),
    (
        "fig16-virtualization",
        include_str!("../../../../configs/experiments/fig16-virtualization.toml"),
    ),
    (
        "sec64-threshold0",
        include_str!("../../../../configs/experiments/sec64-threshold0.toml"),
    ),
    (
        "sec65-queues",
        include_str!("../../../../configs/experiments/sec65-queues.toml"),
    ),
];

/// The built-in experiment file `path` names: by its stem (`fig10-speedup`) or its file in the
/// project (`configs/experiments/fig10-speedup.toml`).
pub fn built_in_experiment(path: &Path) -> Option<(&'static str, &'static str)> {
    EXPERIMENT_FILES.iter().copied().find(|(name, _)| {
        Path::new(name) == path
            || Path::new("configs/experiments").join(format!("{name}.toml")) == path
    })
}

/// Whether `scene` is a built-in (generated) scene rather than a scene folder: built-ins are
/// drawn for reference but left out of the means, as in docs/fidelity.md.
pub fn is_builtin(scene: &str) -> bool {
    let lower = scene.to_ascii_lowercase();
    lower == "wknd" || lower == "cornell" || lower.starts_with("city")
}

/// The names the figures and tables give `scenes`: each scene's own name (a scene folder's
/// `name` in its scene.toml, else the folder's name; a built-in's name; an `.obj` file's stem),
/// never the path it was given by. Scenes that share a name are numbered (`LANDS-1`,
/// `LANDS-2`).
pub fn scene_labels(scenes: &[PreparedScene]) -> Vec<String> {
    let names: Vec<&str> = scenes.iter().map(|s| s.scene.name.as_str()).collect();
    unique_labels(&names)
}

/// `names`, those that occur more than once numbered in order (`A-1`, `A-2`).
fn unique_labels(names: &[&str]) -> Vec<String> {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    names
        .iter()
        .map(|&name| {
            if names.iter().filter(|&&n| n == name).count() < 2 {
                return name.to_string();
            }
            let k = seen.entry(name).or_default();
            *k += 1;
            format!("{name}-{k}")
        })
        .collect()
}

/// `label` as a file name: letters, digits, `-` and `_` kept, everything else (a path's
/// slashes, a `city:4M`'s colon, spaces) turned into `_`.
pub fn file_safe(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Where the experiment files come from: a folder (`--experiments`, or `configs/experiments`
/// under the working directory), whose configuration paths are relative to the project root
/// above it, or the files compiled into the binary ([`EXPERIMENT_FILES`]), whose configuration
/// paths name the built-in designs ([`crate::model::designs::config_text`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Experiments {
    /// A folder of experiment files (`<root>/configs/experiments`).
    Folder(PathBuf),
    /// The files compiled into the binary.
    BuiltIn,
}

impl Experiments {
    /// `configs/experiments` under the working directory where there is one (a project
    /// checkout, whose edits then count), else the built-in files.
    pub fn default_source() -> Self {
        let here = PathBuf::from("configs/experiments");
        if here.is_dir() {
            Experiments::Folder(here)
        } else {
            Experiments::BuiltIn
        }
    }

    /// Checks that every experiment file the figures need is there.
    pub fn check(&self) -> anyhow::Result<()> {
        let Experiments::Folder(dir) = self else {
            return Ok(());
        };
        for name in FIGURE_EXPERIMENTS {
            let path = dir.join(format!("{name}.toml"));
            if !path.is_file() {
                anyhow::bail!(
                    "experiment file {} is missing (--experiments names the folder of the \
                     paper's experiment files, configs/experiments in the project; without it \
                     and outside a checkout vtq uses its built-in copies)",
                    path.display()
                );
            }
        }
        Ok(())
    }

    /// The folder the experiment files' configuration paths (`configs/...`) are relative to:
    /// a folder's project root (`<root>` of `<root>/configs/experiments`); for the built-in
    /// files none (the paths stay as given).
    pub fn root(&self) -> PathBuf {
        match self {
            Experiments::Folder(dir) => dir
                .parent()
                .and_then(Path::parent)
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
            Experiments::BuiltIn => PathBuf::new(),
        }
    }

    /// What they are, for the page: the folder, or that they are the built-in copies.
    pub fn describe(&self) -> String {
        match self {
            Experiments::Folder(dir) => format!("`{}`", dir.display()),
            Experiments::BuiltIn => "vtq's built-in copy of `configs/experiments`".into(),
        }
    }

    /// One experiment's sweep file, its configuration paths resolved against [`Self::root`]
    /// and its scenes replaced by the command line's when given.
    pub fn load(&self, name: &str, scenes: &[String]) -> anyhow::Result<SweepSpec> {
        let mut spec = match self {
            Experiments::Folder(dir) => SweepSpec::from_file(&dir.join(format!("{name}.toml")))?,
            Experiments::BuiltIn => {
                let (_, text) = EXPERIMENT_FILES
                    .iter()
                    .find(|(n, _)| *n == name)
                    .ok_or_else(|| anyhow::anyhow!("no built-in experiment file {name}"))?;
                SweepSpec::from_toml(text)
                    .map_err(|e| e.context(format!("built-in experiment file {name}")))?
            }
        };
        let root = self.root();
        for config in &mut spec.configs {
            if config.is_relative() {
                *config = root.join(&*config);
            }
        }
        if !scenes.is_empty() {
            spec.scenes = scenes.to_vec();
        }
        Ok(spec)
    }
}

/// The stored statistics of the experiments' runs, looked up by scene, base configuration and
/// overrides (each lookup hashes the configuration into its [`RunKey`], so any run of the same
/// configuration is found, whichever sweep stored it).
pub struct Results<'a> {
    store: &'a ResultStore,
    scenes: &'a [PreparedScene],
    root: PathBuf,
    /// Overrides of every run (`vtq reproduce --set`).
    sets: Vec<String>,
    /// The sampled tier's point every run used (`vtq reproduce --sample`), `None` for full
    /// detail.
    sample: Option<String>,
    /// Statistics looked up so far, by scene, configuration file and overrides.
    loaded: RefCell<HashMap<String, Option<Json>>>,
}

impl<'a> Results<'a> {
    /// Results in `store` of runs on `scenes`, with configuration files relative to `root`.
    pub fn new(store: &'a ResultStore, scenes: &'a [PreparedScene], root: PathBuf) -> Self {
        Results {
            store,
            scenes,
            root,
            sets: Vec::new(),
            sample: None,
            loaded: RefCell::new(HashMap::new()),
        }
    }

    /// The same results, with `sets` (`key=value`) applied to every lookup before its own.
    pub fn with_sets(mut self, sets: &[String]) -> Self {
        self.sets = sets.to_vec();
        self
    }

    /// The same results, looked up as the sampled tier's estimates at sample point `sample`
    /// (`None`: full detail's).
    pub fn with_sample(mut self, sample: Option<&str>) -> Self {
        self.sample = sample.map(str::to_string);
        self
    }

    /// Whether the results are the sampled tier's estimates.
    pub fn sampled(&self) -> bool {
        self.sample.is_some()
    }

    /// Statistic `name` (one of [`crate::estimate::sample::stored::ESTIMATED`], or any exact
    /// statistic by JSON pointer `/name`) of `scene` under `base` and `sets`, as an estimate:
    /// a sampled run's with its 95% interval, a full-detail run's exact value (no interval).
    pub fn estimate(&self, scene: &str, base: &str, sets: &[&str], name: &str) -> Option<Estimate> {
        let stats = self.stats(scene, base, sets)?;
        stored_estimate(&stats, name).or_else(|| {
            Some(Estimate {
                value: stats.pointer(&format!("/{name}"))?.as_f64()?,
                half_width: None,
            })
        })
    }

    /// The speedup (baseline cycles over cycles) of `design` with `sets` over `baseline` on
    /// `scene`: exact from full-detail runs, an estimate with its 95% interval from sampled
    /// ones (paired per replicate, [`stored_speedup`]).
    pub fn speedup(
        &self,
        scene: &str,
        baseline: (&str, &[&str]),
        design: (&str, &[&str]),
    ) -> Option<Estimate> {
        let base = self.stats(scene, baseline.0, baseline.1)?;
        let d = self.stats(scene, design.0, design.1)?;
        if self.sampled() {
            return stored_speedup(&base, &d);
        }
        let cycles = |s: &Json| s.pointer("/cycles").and_then(Json::as_f64);
        Some(Estimate {
            value: cycles(&base)? / cycles(&d)?,
            half_width: None,
        })
    }

    /// The scenes as given (what [`Results::stats`] looks up), in order.
    pub fn scenes(&self) -> Vec<&str> {
        self.scenes.iter().map(|s| s.spec.as_str()).collect()
    }

    /// The scenes' names for figures and tables, in the order of [`Results::scenes`]
    /// ([`scene_labels`]).
    pub fn labels(&self) -> Vec<String> {
        scene_labels(self.scenes)
    }

    /// The statistics of `scene` simulated with the configuration file `base` (relative to the
    /// project root, e.g. `configs/designs/vtq/config.toml`) and the overrides `sets`
    /// (`key=value`), or `None` when that run is not stored or failed.
    pub fn stats(&self, scene: &str, base: &str, sets: &[&str]) -> Option<Json> {
        // Figures ask for the same runs again and again: cached by the question.
        let question = format!("{scene}\n{base}\n{}", sets.join("\n"));
        if let Some(found) = self.loaded.borrow().get(&question) {
            return found.clone();
        }
        let found = self.lookup(scene, base, sets);
        self.loaded.borrow_mut().insert(question, found.clone());
        found
    }

    /// [`Results::stats`] without the cache: the configuration loaded, hashed with the scene
    /// into its key and the stored run read.
    fn lookup(&self, scene: &str, base: &str, sets: &[&str]) -> Option<Json> {
        let prepared = self.scenes.iter().find(|s| s.spec == scene)?;
        let path = self.root.join(base);
        let text = crate::model::designs::config_text(&path).ok()?;
        let sets: Vec<String> = self
            .sets
            .iter()
            .cloned()
            .chain(sets.iter().map(|s| s.to_string()))
            .collect();
        let mut config = SimConfig::load_unvalidated(Some((path.as_path(), &*text)), &sets).ok()?;
        let tier = apply_sample(&mut config, self.sample.as_deref()).ok()?;
        let key = RunKey::for_tier(&prepared.hash, &config, tier).ok()?;
        self.store
            .load(&key)
            .ok()
            .flatten()
            .filter(|r| r.status == RunStatus::Ok)
            .and_then(|r| r.stats().cloned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_experiment_files_equal_the_project_s() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/experiments");
        let files = crate::model::designs::toml_files(&dir);
        let mut built_in: Vec<String> = EXPERIMENT_FILES
            .iter()
            .map(|(name, text)| {
                let on_disk = std::fs::read_to_string(dir.join(format!("{name}.toml"))).unwrap();
                assert_eq!(*text, on_disk, "{name} is stale in the binary");
                format!("{name}.toml")
            })
            .collect();
        built_in.sort();
        assert_eq!(files, built_in);
        // Found by stem or by the project's path; the built-in copies load as the folder's do.
        let fig10 = "configs/experiments/fig10-speedup.toml";
        assert_eq!(
            built_in_experiment(Path::new("fig10-speedup")).unwrap().0,
            "fig10-speedup"
        );
        assert_eq!(
            built_in_experiment(Path::new(fig10)).unwrap().0,
            "fig10-speedup"
        );
        assert!(built_in_experiment(Path::new("fig99")).is_none());
        for name in FIGURE_EXPERIMENTS {
            let folder = Experiments::Folder(dir.clone()).load(name, &[]).unwrap();
            let mut built = Experiments::BuiltIn.load(name, &[]).unwrap();
            // The folder's configuration paths are joined to its project root.
            let root = Experiments::Folder(dir.clone()).root();
            for c in &mut built.configs {
                *c = root.join(&*c);
            }
            assert_eq!(folder, built, "{name}");
        }
    }

    #[test]
    fn scenes_are_named_by_their_own_names_and_files_never_by_paths() {
        assert_eq!(
            unique_labels(&["LANDS", "wknd", "LANDS", "SHIP"]),
            ["LANDS-1", "wknd", "LANDS-2", "SHIP"]
        );
        for name in ["city:4M", "/work/shared/scenes/lands", "a b/c\\d", "LANDS"] {
            let file = file_safe(name);
            assert!(
                !file.contains('/') && !file.contains('\\') && !file.contains(':'),
                "{file}"
            );
        }
        assert_eq!(file_safe("city:4M"), "city_4M");
        assert_eq!(file_safe("../scenes/lands"), "___scenes_lands");
    }
}
