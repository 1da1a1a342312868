//! A sweep's definition ([`SweepSpec`]): scenes, base configuration files, overrides applied to
//! every point, a grid of values (cartesian product) and explicit points; read from a sweep
//! file (TOML) and the command line, written back as TOML for cluster jobs, and expanded into
//! the ordered, duplicate-free list of [`Point`]s that shards partition.
//!
//! A sweep file:
//! ```toml
//! scenes = ["wknd", "cornell"]           # as `vtq sim --scene` takes them
//! configs = ["configs/designs/vtq/config.toml"]         # base configurations; none: the defaults
//! set = ["width=64", "height=64"]        # overrides of every point, as `--set`
//! [grid]                                 # every combination of these values
//! "hw.repack_threshold" = [16, 22, 28]
//! "hw.underpopulation_threshold" = [64, 128]
//! [[points]]                             # and these points (each a set of overrides)
//! "hw.repack_threshold" = 0
//! "mode.grouping" = false
//! ```
//! A top-level `sample = "default"` (or `--sample`) runs every point in the sampled tier at
//! that sample point: estimates with intervals, stored apart from full detail's results.
//! Paths (scenes and configurations) are relative to the working directory, as on the command
//! line; a configuration that is not a file there may name a built-in design, by name (`vtq`)
//! or by its file in the project (`configs/designs/vtq/config.toml`), so a sweep of the
//! project's designs runs from any directory ([`crate::model::designs::config_text`]).

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use serde::Deserialize;
use toml::{Table, Value};

use super::key::{RunKey, Tier};
use crate::model::config::{parse_override_value, ConfigError, SimConfig};

/// The sweep file as written (keys of `grid` and `points` may be dotted TOML keys or quoted
/// `"section.key"` strings; both mean the same).
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct SweepFile {
    scenes: Vec<String>,
    configs: Vec<PathBuf>,
    set: Vec<String>,
    grid: Table,
    points: Vec<Table>,
    sample: Option<String>,
}

/// One swept key and its values, in the given order.
#[derive(Debug, Clone, PartialEq)]
pub struct GridAxis {
    /// The dotted configuration key (`hw.repack_threshold`, or a bare workload key).
    pub key: String,
    /// Its values.
    pub values: Vec<Value>,
}

/// A sweep: every scene x every base configuration x every assignment (the grid's combinations,
/// then the explicit points).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepSpec {
    /// Scenes, as `vtq sim --scene` takes them.
    pub scenes: Vec<String>,
    /// Base configuration files; empty: the defaults (the paper's baseline GPU).
    pub configs: Vec<PathBuf>,
    /// Overrides applied to every point before its assignment (`key=value`, as `--set`).
    pub set: Vec<String>,
    /// The grid, sorted by key (so the point order does not depend on how it was written).
    pub grid: Vec<GridAxis>,
    /// Explicit points: each a list of (dotted key, value) overrides.
    pub points: Vec<Vec<(String, Value)>>,
    /// Run every point in the sampled tier at this sample point (`--sample`: a named point,
    /// `FRACTIONxREPLICATES` or `config`; docs/accuracy.md) instead of full detail.
    pub sample: Option<String>,
}

/// One run of a sweep: a scene and an effective configuration.
#[derive(Debug, Clone)]
pub struct Point {
    /// Position in the sweep's point list (shards partition by it).
    pub index: usize,
    /// The scene, as given.
    pub scene: String,
    /// The base configuration file (`None`: the defaults).
    pub base: Option<PathBuf>,
    /// The point's own overrides (a grid combination or an explicit point).
    pub assignment: Vec<(String, Value)>,
    /// The effective configuration: defaults, base file, the sweep's `set`, the assignment. Not
    /// validated: an out-of-range point is recorded as a failed run.
    pub config: SimConfig,
    /// A short description for messages: scene, base file (when several), assignment.
    pub label: String,
    /// The tier it runs in (sampled with the sweep's `sample`, its settings in
    /// `config.sample`).
    pub tier: Tier,
}

/// Applies a sample point `sample` (`--sample`: a named point, `FRACTIONxREPLICATES` or
/// `config`) to `config`'s `[sample]` section and gives the tier a run of it is: sampled with a
/// point, full detail without (`config` unchanged).
pub fn apply_sample(config: &mut SimConfig, sample: Option<&str>) -> Result<Tier, String> {
    match sample {
        Some(spec) => {
            config.sample.apply_spec(spec)?;
            Ok(Tier::Sampled)
        }
        None => Ok(Tier::Full),
    }
}

impl Point {
    /// The key of this point's result on the scene whose content hash is `scene_hash`.
    pub fn key(&self, scene_hash: &blake3::Hash) -> Result<RunKey, ConfigError> {
        RunKey::for_tier(scene_hash, &self.config, self.tier)
    }
}

/// Every leaf of `table` (nested tables flattened) as `(dotted key, value)`, in table order.
pub fn leaves(table: &Table) -> Vec<(String, Value)> {
    fn walk(table: &Table, prefix: &str, out: &mut Vec<(String, Value)>) {
        for (k, v) in table {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                Value::Table(sub) => walk(sub, &key, out),
                _ => out.push((key, v.clone())),
            }
        }
    }
    let mut out = Vec::new();
    walk(table, "", &mut out);
    out
}

/// Flattened, sorted entries of `table`, with an error for a key given twice (once dotted, once
/// quoted).
fn flat_entries(table: &Table, what: &str) -> anyhow::Result<Vec<(String, Value)>> {
    let mut out = leaves(table);
    out.sort_by(|a, b| a.0.cmp(&b.0));
    if let Some(w) = out.windows(2).find(|w| w[0].0 == w[1].0) {
        bail!("{what}: key `{}` is given twice", w[0].0);
    }
    Ok(out)
}

/// The `key=value` override text of a TOML value (strings quoted, so it reads back unchanged).
pub fn override_text(key: &str, value: &Value) -> String {
    format!("{key}={value}")
}

/// A value as a table cell or label: strings without quotes, everything else as TOML.
pub fn value_text(value: &Value) -> String {
    match value {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

impl SweepSpec {
    /// Reads a sweep file. Errors name the file (and the line, for TOML syntax).
    pub fn from_file(path: &Path) -> anyhow::Result<SweepSpec> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read sweep file {}", path.display()))?;
        SweepSpec::from_toml(&text).with_context(|| format!("sweep file {}", path.display()))
    }

    /// Reads a sweep file's text.
    pub fn from_toml(text: &str) -> anyhow::Result<SweepSpec> {
        let file: SweepFile = toml::from_str(text)
            .map_err(|e| anyhow::anyhow!("not a valid sweep file: {}", e.to_string().trim_end()))?;
        let mut spec = SweepSpec {
            scenes: file.scenes,
            configs: file.configs,
            set: file.set,
            sample: file.sample,
            ..SweepSpec::default()
        };
        for (key, value) in flat_entries(&file.grid, "[grid]")? {
            let Value::Array(values) = value else {
                bail!("[grid] `{key}` = {value}: expected an array of values, e.g. [16, 22]");
            };
            spec.add_axis(key, values)?;
        }
        for (i, table) in file.points.iter().enumerate() {
            let entries = flat_entries(table, &format!("[[points]] #{}", i + 1))?;
            if entries.is_empty() {
                bail!("[[points]] #{} is empty", i + 1);
            }
            spec.points.push(entries);
        }
        Ok(spec)
    }

    /// Adds a `--grid key=v1,v2,...` axis (values as `--set` takes them: TOML, or a bare word
    /// as a string; a comma inside brackets or quotes belongs to its value, so
    /// `sample.cluster=1,[1,2]` is two values).
    pub fn add_grid_arg(&mut self, arg: &str) -> anyhow::Result<()> {
        let context = || format!("--grid `{arg}`");
        let (key, list) = arg
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("expected key=v1,v2,..., e.g. hw.max_rays=2048,4096"))
            .with_context(context)?;
        let values = split_values(list)
            .into_iter()
            .map(|raw| parse_override_value(raw).map_err(anyhow::Error::msg))
            .collect::<anyhow::Result<Vec<Value>>>()
            .with_context(context)?;
        self.add_axis(key.trim().to_string(), values)
            .with_context(context)
    }

    /// Adds a grid axis, keeping the axes sorted by key.
    fn add_axis(&mut self, key: String, values: Vec<Value>) -> anyhow::Result<()> {
        if key.is_empty() {
            bail!("the grid key is empty");
        }
        if values.is_empty() {
            bail!("grid key `{key}` has no values");
        }
        if self.grid.iter().any(|a| a.key == key) {
            bail!("grid key `{key}` is given twice");
        }
        let at = self.grid.partition_point(|a| a.key < key);
        self.grid.insert(at, GridAxis { key, values });
        Ok(())
    }

    /// The sweep as a sweep file (reads back to an equal spec).
    pub fn to_toml(&self) -> anyhow::Result<String> {
        let strings = |v: Vec<String>| Value::Array(v.into_iter().map(Value::String).collect());
        let mut doc = Table::new();
        doc.insert("scenes".into(), strings(self.scenes.clone()));
        let configs = self.configs.iter().map(|p| p.display().to_string());
        doc.insert("configs".into(), strings(configs.collect()));
        doc.insert("set".into(), strings(self.set.clone()));
        let grid: Table = self
            .grid
            .iter()
            .map(|a| (a.key.clone(), Value::Array(a.values.clone())))
            .collect();
        doc.insert("grid".into(), Value::Table(grid));
        let points = self
            .points
            .iter()
            .map(|p| Value::Table(p.iter().cloned().collect()))
            .collect();
        doc.insert("points".into(), Value::Array(points));
        if let Some(sample) = &self.sample {
            doc.insert("sample".into(), Value::String(sample.clone()));
        }
        toml::to_string(&doc).context("writing the sweep file")
    }

    /// The assignments: every grid combination (the last key varying fastest), then the
    /// explicit points; one empty assignment when there are neither.
    fn assignments(&self) -> Vec<Vec<(String, Value)>> {
        let mut combos: Vec<Vec<(String, Value)>> = vec![Vec::new()];
        if self.grid.is_empty() && !self.points.is_empty() {
            combos.clear();
        }
        for axis in &self.grid {
            combos = combos
                .into_iter()
                .flat_map(|c| {
                    axis.values.iter().map(move |v| {
                        let mut next = c.clone();
                        next.push((axis.key.clone(), v.clone()));
                        next
                    })
                })
                .collect();
        }
        combos.extend(self.points.iter().cloned());
        combos
    }

    /// The sweep's points in order: scenes, then base configurations, then assignments; a
    /// point equal to an earlier one (same scene, same effective configuration) is dropped. A
    /// configuration that cannot be read (missing file, unknown key, value of the wrong type) is
    /// an error naming the point; one that reads but fails validation is a point (recorded as a
    /// failed run when it runs).
    pub fn points(&self) -> anyhow::Result<Vec<Point>> {
        if self.scenes.is_empty() {
            bail!("the sweep has no scenes: give --scene or `scenes` in the sweep file");
        }
        let mut bases: Vec<(Option<PathBuf>, Option<String>)> = Vec::new();
        for path in &self.configs {
            let text = crate::model::designs::config_text(path)?;
            bases.push((Some(path.clone()), Some(text.into_owned())));
        }
        if bases.is_empty() {
            bases.push((None, None));
        }
        let assignments = self.assignments();
        let mut seen = HashSet::new();
        let mut points = Vec::new();
        for scene in &self.scenes {
            for (base, text) in &bases {
                for assignment in &assignments {
                    let mut label = scene.clone();
                    if let (Some(path), true) = (base, bases.len() > 1) {
                        let name = crate::model::designs::folder_name(path).unwrap_or_else(|| {
                            let name = path.file_name().unwrap_or(path.as_os_str());
                            name.to_string_lossy().into_owned()
                        });
                        let _ = write!(label, " {name}");
                    }
                    for (k, v) in assignment {
                        let _ = write!(label, " {k}={}", value_text(v));
                    }
                    let mut overrides = self.set.clone();
                    overrides.extend(assignment.iter().map(|(k, v)| override_text(k, v)));
                    let file = base.as_deref().zip(text.as_deref());
                    let mut config = SimConfig::load_unvalidated(file, &overrides)
                        .with_context(|| format!("sweep point {label}"))?;
                    let tier = apply_sample(&mut config, self.sample.as_deref())
                        .map_err(anyhow::Error::msg)?;
                    let canonical = config
                        .to_toml()
                        .with_context(|| format!("sweep point {label}"))?;
                    if !seen.insert((scene.clone(), canonical)) {
                        continue;
                    }
                    points.push(Point {
                        index: points.len(),
                        scene: scene.clone(),
                        base: base.clone(),
                        assignment: assignment.clone(),
                        config,
                        label,
                        tier,
                    });
                }
            }
        }
        Ok(points)
    }
}

/// The `I/N` of `--shard`: the I-th (from 0) of N slices of a sweep's points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which slice, `0..count`.
    pub index: usize,
    /// How many slices.
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Shard, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("`{s}`: expected I/N, e.g. 0/4"))?;
        let parse = |t: &str, what: &str| {
            t.trim()
                .parse::<usize>()
                .map_err(|e| format!("`{s}`: {what} `{t}`: {e}"))
        };
        let (index, count) = (parse(i, "slice")?, parse(n, "count")?);
        if count == 0 || index >= count {
            return Err(format!("`{s}`: need 0 <= I < N"));
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// Whether point `index` of the sweep belongs to this slice (round robin, so every slice
    /// gets a share of every scene).
    pub fn contains(&self, index: usize) -> bool {
        index % self.count == self.index
    }
}

/// `list` cut at its commas outside brackets, braces and quotes (a TOML array or string keeps
/// its commas).
fn split_values(list: &str) -> Vec<&str> {
    let (mut parts, mut depth, mut quote, mut start) = (Vec::new(), 0i32, None, 0);
    for (i, c) in list.char_indices() {
        match (quote, c) {
            (Some(q), _) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth <= 0 => {
                parts.push(&list[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&list[start..]);
    parts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> SweepSpec {
        SweepSpec::from_toml(text).unwrap()
    }

    #[test]
    fn grid_is_a_sorted_product_then_points() {
        let mut s = spec(
            "scenes = ['cornell', 'wknd']\nset = ['width=16']\n\
             [[points]]\nmode.kind = 'queues'\n",
        );
        s.add_grid_arg("hw.repack_threshold=16,22").unwrap();
        s.add_grid_arg("gpu.sms=2,4,8").unwrap();
        assert_eq!(s.grid[0].key, "gpu.sms");
        let points = s.points().unwrap();
        assert_eq!(points.len(), 2 * (3 * 2 + 1));
        assert_eq!(points[0].label, "cornell gpu.sms=2 hw.repack_threshold=16");
        assert_eq!(points[1].label, "cornell gpu.sms=2 hw.repack_threshold=22");
        assert_eq!(points[6].label, "cornell mode.kind=queues");
        assert_eq!(points[7].label, "wknd gpu.sms=2 hw.repack_threshold=16");
        assert_eq!(points[1].config.hw.repack_threshold, 22);
        assert_eq!(points[1].config.workload.width, 16);
        assert!(points.iter().enumerate().all(|(i, p)| p.index == i));
    }

    #[test]
    fn grid_values_keep_their_own_commas() {
        assert_eq!(split_values("1,[1, 2],'a,b'"), ["1", "[1, 2]", "'a,b'"]);
        let mut s = spec("scenes = ['wknd']");
        s.add_grid_arg("sample.cluster=1,[1,2]").unwrap();
        let points = s.points().unwrap();
        assert_eq!(points.len(), 2);
        assert_eq!(points[1].config.sample.cluster.for_replicate(1), 2);
    }

    #[test]
    fn duplicate_points_are_dropped() {
        let mut s = spec("scenes = ['wknd']");
        s.add_grid_arg("width=256,256,64").unwrap();
        let points = s.points().unwrap();
        assert_eq!(points.len(), 2);
    }

    #[test]
    fn round_trips_through_toml() {
        let mut s = spec(
            "scenes = ['wknd']\nconfigs = []\nset = ['height=8']\n\
             [grid]\nmode.kind = ['baseline', 'queues']\n\"hw.max_rays\" = [1024]\n\
             [[points]]\n\"mode.prefetch_threshold\" = 0.5\n",
        );
        s.add_grid_arg("bounces=0,1").unwrap();
        let back = SweepSpec::from_toml(&s.to_toml().unwrap()).unwrap();
        assert_eq!(back, s);
    }

    #[test]
    fn bad_definitions_are_named() {
        let e = SweepSpec::from_toml("scenes = ['wknd']\n[grid]\nwidth = 16\n").unwrap_err();
        assert!(format!("{e:#}").contains("expected an array"), "{e:#}");
        let e = SweepSpec::from_toml("scene = ['wknd']").unwrap_err();
        assert!(format!("{e:#}").contains("unknown field `scene`"), "{e:#}");
        let e = SweepSpec::from_toml("scenes = ['wknd']\n[grid]\nwidth = []\n").unwrap_err();
        assert!(format!("{e:#}").contains("has no values"), "{e:#}");
        let mut s = spec("scenes = ['wknd']");
        s.add_grid_arg("hw.no_such_key=1,2").unwrap();
        let e = format!("{:#}", s.points().unwrap_err());
        assert!(e.contains("sweep point wknd hw.no_such_key=1"), "{e}");
        assert!(e.contains("unknown key `hw.no_such_key`"), "{e}");
        let e = format!("{:#}", spec("").points().unwrap_err());
        assert!(e.contains("no scenes"), "{e}");
        let e = spec("scenes=['wknd']\nconfigs=['/no/such.toml']")
            .points()
            .unwrap_err();
        assert!(format!("{e:#}").contains("/no/such.toml"), "{e:#}");
        assert!(s.add_grid_arg("gpu.sms").is_err());
        assert!(s.add_grid_arg("gpu.sms=1,,2").is_err());
    }

    #[test]
    fn out_of_range_values_are_points_not_errors() {
        let vtq = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/designs/vtq/config.toml"
        );
        let mut s = spec(&format!("scenes = ['wknd']\nconfigs = ['{vtq}']"));
        s.add_grid_arg("hw.repack_threshold=16,99").unwrap();
        let points = s.points().unwrap();
        assert_eq!(points.len(), 2);
        assert!(points[0].config.validate().is_ok());
        assert!(points[1].config.validate().is_err());
    }

    #[test]
    fn shards_partition_the_points() {
        assert!("3/3".parse::<Shard>().is_err());
        assert!("0/0".parse::<Shard>().is_err());
        assert!("x/2".parse::<Shard>().is_err());
        let shards: Vec<Shard> = (0..3).map(|i| format!("{i}/3").parse().unwrap()).collect();
        for index in 0..10 {
            assert_eq!(shards.iter().filter(|s| s.contains(index)).count(), 1);
        }
        assert_eq!(shards[1].to_string(), "1/3");
    }
}
