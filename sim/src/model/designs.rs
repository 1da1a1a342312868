//! The designs `vtq` knows by name: each a configuration file in `configs/` compiled into the
//! binary, so `vtq compare --designs`, `vtq accuracy --designs` and the other commands that take
//! a design work from any directory. A design is otherwise a configuration like any other: its
//! `[mode]` section picks the hardware beside each SM (`sim/src/model/config/mode.rs`), and any
//! configuration file can be named by path instead.
//!
//! To add a design: write its configuration file, add one [`BuiltIn`] line to [`BUILT_INS`]
//! (a test checks that every file of `configs/` has one), and document it (README's design
//! list, docs/config.md's `[mode]` table).

use std::borrow::Cow;
use std::path::Path;

use anyhow::{bail, Context};

use crate::model::config::SimConfig;

/// A design compiled into the binary: its name, the file it was read from (relative to the
/// workspace root), the file's text and a one-line description.
#[derive(Debug, Clone, Copy)]
pub struct BuiltIn {
    /// The name `--designs` takes.
    pub name: &'static str,
    /// Its configuration file, relative to the workspace root.
    pub path: &'static str,
    /// The file's text.
    pub toml: &'static str,
    /// What it is, in a line.
    pub summary: &'static str,
}

/// Every built-in design — every configuration file of `configs/` — the paper's three first, in
/// the default order of `--designs`, then VTQ with prefetching and the ablations.
pub const BUILT_INS: [BuiltIn; 10] = [
    BuiltIn {
        name: "baseline",
        path: "configs/baseline.toml",
        toml: include_str!("../../../configs/baseline.toml"),
        summary: "the baseline RT unit (paper section 5)",
    },
    BuiltIn {
        name: "prefetch",
        path: "configs/prefetch.toml",
        toml: include_str!("../../../configs/prefetch.toml"),
        summary: "treelet prefetching (Chou et al., MICRO 2023)",
    },
    BuiltIn {
        name: "vtq",
        path: "configs/vtq.toml",
        toml: include_str!("../../../configs/vtq.toml"),
        summary: "Virtualized Treelet Queues, the paper's full design",
    },
    BuiltIn {
        name: "vtq-prefetch",
        path: "configs/vtq-prefetch.toml",
        toml: include_str!("../../../configs/vtq-prefetch.toml"),
        summary: "VTQ with treelet prefetching in its ray-stationary phases",
    },
    BuiltIn {
        name: "vtq-prefetch-all",
        path: "configs/vtq-prefetch-all.toml",
        toml: include_str!("../../../configs/vtq-prefetch-all.toml"),
        summary: "VTQ with treelet prefetching in every phase",
    },
    BuiltIn {
        name: "queues-naive",
        path: "configs/queues-naive.toml",
        toml: include_str!("../../../configs/queues-naive.toml"),
        summary: "ablation: treelet queues without grouping or repacking (Figure 12)",
    },
    BuiltIn {
        name: "queues-grouping",
        path: "configs/queues-grouping.toml",
        toml: include_str!("../../../configs/queues-grouping.toml"),
        summary: "ablation: treelet queues with grouping, no repacking (Figures 12, 13)",
    },
    BuiltIn {
        name: "queues-repack16",
        path: "configs/queues-repack16.toml",
        toml: include_str!("../../../configs/queues-repack16.toml"),
        summary: "ablation: repacking warps below 16 active rays (Figure 13)",
    },
    BuiltIn {
        name: "queues-threshold0",
        path: "configs/queues-threshold0.toml",
        toml: include_str!("../../../configs/queues-threshold0.toml"),
        summary: "section 6.4: the queue threshold at zero, read literally",
    },
    BuiltIn {
        name: "queues-skip-treelet",
        path: "configs/queues-skip-treelet.toml",
        toml: include_str!("../../../configs/queues-skip-treelet.toml"),
        summary: "section 6.4: no treelet-stationary phase, the other reading",
    },
];

/// The built-in design called `name`.
pub fn find(name: &str) -> Option<&'static BuiltIn> {
    BUILT_INS.iter().find(|b| b.name == name)
}

impl BuiltIn {
    /// Its configuration with `overrides` applied, read as [`SimConfig::load`] reads its file.
    pub fn config(&self, overrides: &[String]) -> anyhow::Result<SimConfig> {
        Ok(SimConfig::load_str(
            Path::new(self.path),
            self.toml,
            overrides,
        )?)
    }
}

/// The text of the configuration file `path`: the file where there is one, else the built-in
/// design whose file it names (`configs/vtq.toml`) or whose name it is (`vtq`), so sweeps and
/// experiments that name the project's configuration files run from any directory (a cluster
/// node with only the binary). Anything else is an error naming the path.
pub fn config_text(path: &Path) -> anyhow::Result<Cow<'static, str>> {
    if path.exists() {
        return std::fs::read_to_string(path)
            .map(Cow::Owned)
            .with_context(|| format!("cannot read config file {}", path.display()));
    }
    BUILT_INS
        .iter()
        .find(|b| Path::new(b.path) == path || Path::new(b.name) == path)
        .map(|b| Cow::Borrowed(b.toml))
        .with_context(|| {
            format!(
                "cannot read config file {}: no such file, and not a built-in design's name or \
                 file (`vtq designs` lists them)",
                path.display()
            )
        })
}

/// One design to simulate: a built-in one or a configuration file.
#[derive(Debug, Clone)]
pub struct Design {
    /// Its name in tables and JSON (the built-in name, or the configuration file's stem).
    pub label: String,
    /// Where its configuration came from.
    pub source: String,
    /// The configuration, overrides applied.
    pub config: SimConfig,
}

/// Resolves one `--designs` entry: a built-in name, or else a configuration file path.
pub fn resolve(spec: &str, overrides: &[String]) -> anyhow::Result<Design> {
    let spec = spec.trim();
    let context = || format!("design '{spec}'");
    if let Some(built_in) = find(spec) {
        return Ok(Design {
            label: built_in.name.to_string(),
            source: format!("built-in {}", built_in.path),
            config: built_in.config(overrides).with_context(context)?,
        });
    }
    let path = Path::new(spec);
    let looks_like_path = spec.contains(['/', '\\']) || spec.ends_with(".toml");
    if spec.is_empty() || !(looks_like_path || path.is_file()) {
        let names: Vec<&str> = BUILT_INS.iter().map(|b| b.name).collect();
        bail!(
            "unknown design '{spec}': expected one of {} or the path of a configuration file",
            names.join(", ")
        );
    }
    let label = path
        .file_stem()
        .map_or_else(|| spec.to_string(), |s| s.to_string_lossy().into_owned());
    Ok(Design {
        label,
        source: spec.to_string(),
        config: SimConfig::load(Some(path), overrides).with_context(context)?,
    })
}

/// The names of the `.toml` files in `dir`, sorted (tests comparing a folder with the copies
/// compiled into the binary).
#[cfg(test)]
pub(crate) fn toml_files(dir: &Path) -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".toml"))
        .collect();
    files.sort();
    files
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_configs_equal_the_files() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        for b in &BUILT_INS {
            let on_disk = std::fs::read_to_string(root.join(b.path)).unwrap();
            assert_eq!(b.toml, on_disk, "{} is stale in the binary", b.path);
        }
        // Every configuration file is a built-in design, named after it.
        let files = toml_files(&root.join("configs"));
        let mut built_in: Vec<String> = BUILT_INS
            .iter()
            .map(|b| {
                assert_eq!(b.path, format!("configs/{}.toml", b.name));
                format!("{}.toml", b.name)
            })
            .collect();
        built_in.sort();
        assert_eq!(files, built_in);
    }

    #[test]
    fn config_text_reads_files_then_built_ins() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let file = root.join("configs/vtq.toml");
        assert_eq!(config_text(&file).unwrap(), find("vtq").unwrap().toml);
        // Relative to a directory without the project's files: the built-in, by file or name.
        let elsewhere = std::env::temp_dir().join("vtq-config-text-test-nothing-here");
        assert!(!elsewhere.exists());
        for p in ["configs/queues-naive.toml", "queues-naive"] {
            assert_eq!(
                config_text(Path::new(p)).unwrap(),
                find("queues-naive").unwrap().toml
            );
        }
        let err = config_text(&elsewhere.join("configs/vtq.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("cannot read config file") && err.contains("vtq designs"),
            "{err}"
        );
        assert!(config_text(Path::new("configs/fastest.toml")).is_err());
    }

    #[test]
    fn built_in_configs_load_as_their_files_do() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let sets = vec!["width=16".to_string(), "gpu.sms=2".to_string()];
        for b in &BUILT_INS {
            let from_file = SimConfig::load(Some(&root.join(b.path)), &sets).unwrap();
            assert_eq!(b.config(&sets).unwrap(), from_file, "{}", b.path);
        }
        // The built-ins differ from each other, so the file's keys were applied.
        let configs: Vec<SimConfig> = BUILT_INS.iter().map(|b| b.config(&[]).unwrap()).collect();
        for (i, a) in configs.iter().enumerate() {
            for b in &configs[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    #[test]
    fn unknown_design_names_the_choices() {
        let err = resolve("fastest", &[]).err().unwrap().to_string();
        assert!(err.contains("unknown design 'fastest'"), "{err}");
        assert!(
            err.contains("baseline, prefetch, vtq, vtq-prefetch, vtq-prefetch-all, queues-naive"),
            "{err}"
        );
    }
}
