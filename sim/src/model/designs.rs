//! The design registry: the designs `vtq` knows by name. A design is one folder of
//! `configs/designs/`, named after it, holding its configuration (`config.toml`) and its
//! documentation (`README.md`, first line `# NAME: SUMMARY`); `sim/build.rs` compiles every
//! folder into [`BUILT_INS`], so `vtq compare --designs`, `vtq accuracy --designs`, sweeps,
//! `vtq reproduce` and the other commands that take a design work from any directory. The
//! configuration's `[mode]` section picks the hardware beside each SM
//! (`sim/src/model/config/mode.rs`, the only place that matches on it); any configuration file
//! can be named by path instead.
//!
//! To add a design built from the hardware's switches: add its folder. Nothing else changes;
//! `vtq designs` lists it and every command takes its name.

use std::borrow::Cow;
use std::path::Path;

use anyhow::{bail, Context};

use crate::model::config::SimConfig;

/// A design compiled into the binary: its name, the file its configuration was read from
/// (relative to the workspace root), the file's text, its documentation and a one-line
/// description.
#[derive(Debug, Clone, Copy)]
pub struct BuiltIn {
    /// The name `--designs` takes.
    pub name: &'static str,
    /// Its configuration file, relative to the workspace root.
    pub path: &'static str,
    /// The file's text.
    pub toml: &'static str,
    /// Its documentation, `README.md` beside the configuration file.
    pub doc: &'static str,
    /// What it is, in a line (the documentation's first line after the name).
    pub summary: &'static str,
}

include!(concat!(env!("OUT_DIR"), "/designs.rs"));

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

/// The built-in design whose file (`configs/designs/vtq/config.toml`) `path` is.
fn file_of(path: &Path) -> Option<&'static BuiltIn> {
    BUILT_INS.iter().find(|b| Path::new(b.path) == path)
}

/// The text of the configuration `path` names: a built-in design's name (`vtq`) is that design,
/// as in `--designs` (a file of that name in the working directory is `./vtq`); otherwise the
/// file where there is one, else the built-in design whose file it names
/// (`configs/designs/vtq/config.toml`), so sweeps and experiments that name the project's
/// configuration files run from any directory (a cluster node with only the binary). Anything
/// else is an error naming the path.
pub fn config_text(path: &Path) -> anyhow::Result<Cow<'static, str>> {
    if let Some(b) = path.to_str().and_then(find) {
        return Ok(Cow::Borrowed(b.toml));
    }
    if path.exists() {
        return std::fs::read_to_string(path)
            .map(Cow::Owned)
            .with_context(|| format!("cannot read config file {}", path.display()));
    }
    file_of(path)
        .map(|b| Cow::Borrowed(b.toml))
        .with_context(|| {
            format!(
                "cannot read config file {}: no such file, and not a built-in design's name or \
                 file (`vtq designs` lists them)",
                path.display()
            )
        })
}

/// The defaults, then the configuration `path` names ([`config_text`]: the file, else the
/// built-in design it names; `None`: the defaults alone), then `overrides`, not validated.
pub fn load_unvalidated(path: Option<&Path>, overrides: &[String]) -> anyhow::Result<SimConfig> {
    Ok(match path {
        Some(path) => {
            let text = config_text(path)?;
            SimConfig::load_unvalidated(Some((path, &text)), overrides)?
        }
        None => SimConfig::load_unvalidated(None, overrides)?,
    })
}

/// [`load_unvalidated`], validated: what `--config NAME|FILE` with `--set` gives.
pub fn load(path: Option<&Path>, overrides: &[String]) -> anyhow::Result<SimConfig> {
    let cfg = load_unvalidated(path, overrides)?;
    cfg.validate()?;
    Ok(cfg)
}

/// The design folder's name when `path` is a design folder's configuration file
/// (`.../NAME/config.toml`), so tables and sweep points name it after its folder.
pub fn folder_name(path: &Path) -> Option<String> {
    (path.file_name()? == "config.toml")
        .then(|| path.parent()?.file_name())
        .flatten()
        .map(|d| d.to_string_lossy().into_owned())
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
    let label = folder_name(path)
        .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .unwrap_or_else(|| spec.to_string());
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
    fn every_design_folder_is_in_the_registry() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut folders: Vec<String> = std::fs::read_dir(root.join("configs/designs"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        folders.sort();
        let names: Vec<&str> = BUILT_INS.iter().map(|b| b.name).collect();
        assert_eq!(folders, names);
        for b in &BUILT_INS {
            assert_eq!(b.path, format!("configs/designs/{}/config.toml", b.name));
            let on_disk = std::fs::read_to_string(root.join(b.path)).unwrap();
            assert_eq!(b.toml, on_disk, "{} is stale in the binary", b.path);
            let doc = root.join(format!("configs/designs/{}/README.md", b.name));
            assert_eq!(b.doc, std::fs::read_to_string(doc).unwrap());
            assert!(b.doc.starts_with(&format!("# {}: {}\n", b.name, b.summary)));
        }
    }

    #[test]
    fn docs_config_lists_every_design() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let doc = std::fs::read_to_string(root.join("docs/config.md")).unwrap();
        let table = doc
            .split("## Shipped designs")
            .nth(1)
            .and_then(|s| s.split("\n## ").next())
            .expect("docs/config.md has a \"Shipped designs\" section");
        let rows: Vec<&str> = table
            .lines()
            .filter_map(|l| l.strip_prefix("| `")?.split('`').next())
            .collect();
        let mut rows = rows;
        rows.sort();
        let names: Vec<&str> = BUILT_INS.iter().map(|b| b.name).collect();
        assert_eq!(rows, names, "docs/config.md's table of designs");
    }

    #[test]
    fn config_text_reads_files_then_built_ins() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let file = root.join("configs/designs/vtq/config.toml");
        assert_eq!(config_text(&file).unwrap(), find("vtq").unwrap().toml);
        // Relative to a directory without the project's files: the built-in, by file or name.
        let elsewhere = std::env::temp_dir().join("vtq-config-text-test-nothing-here");
        assert!(!elsewhere.exists());
        for p in ["configs/designs/queues-naive/config.toml", "queues-naive"] {
            assert_eq!(
                config_text(Path::new(p)).unwrap(),
                find("queues-naive").unwrap().toml
            );
        }
        let err = config_text(&elsewhere.join("configs/designs/vtq/config.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("cannot read config file") && err.contains("vtq designs"),
            "{err}"
        );
        assert!(config_text(Path::new("configs/designs/fastest/config.toml")).is_err());
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
            err.contains("baseline, prefetch, queues-grouping, queues-naive, queues-repack16"),
            "{err}"
        );
    }
}
