//! `vtq designs`: the design registry ([`crate::model::designs`]) as a reader wants it when
//! choosing what to compare — each design's name, file and summary, the hardware it puts beside
//! every SM's RT unit, and the configuration keys in which it differs from the baseline. Files
//! given with `--design` are listed the same way, so a design of one's own can be checked
//! against the built-in ones before a long run.

use anyhow::Context;
use clap::Args;
use toml::Value;

use crate::experiment::sweep::collect::flat_config;
use crate::model::config::SimConfig;
use crate::model::designs::{self, Design};

/// Options of `vtq designs`.
#[derive(Debug, Args)]
pub struct DesignsArgs {
    /// Designs to list: built-in names or configuration files (repeatable, or comma-separated)
    /// [default: every built-in design].
    #[arg(long = "design", value_name = "NAME|FILE", value_delimiter = ',')]
    pub designs: Vec<String>,
    /// Override one configuration key in every design (and in the baseline they are compared
    /// with), e.g. `--set hw.max_rays=8192` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Also print each built-in design's documentation (the `README.md` of its folder).
    #[arg(long)]
    pub doc: bool,
}

/// One design's entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Its name (the built-in name, or the file's stem).
    pub label: String,
    /// Where it came from.
    pub source: String,
    /// The built-in design's one-line summary (empty for a file).
    pub summary: String,
    /// The built-in design's documentation (`None` for a file).
    pub doc: Option<&'static str>,
    /// The RT unit and the design's units beside it in every SM
    /// ([`crate::model::config::ModeConfig::units`]).
    pub units: Vec<&'static str>,
    /// Configuration keys whose value differs from the baseline's: `(key, value)`.
    pub differs: Vec<(String, String)>,
}

/// The flat `(key, value)` list of a configuration.
fn flat(cfg: &SimConfig) -> anyhow::Result<Vec<(String, Value)>> {
    flat_config(&cfg.to_toml()?)
}

/// The entry of `design`, compared with the flat baseline configuration `baseline`.
pub fn entry(design: &Design, baseline: &[(String, Value)]) -> anyhow::Result<Entry> {
    let built_in = designs::find(&design.label).filter(|b| design.source.ends_with(b.path));
    let summary = built_in.map_or(String::new(), |b| b.summary.to_string());
    let differs = flat(&design.config)?
        .into_iter()
        .filter(|(k, v)| baseline.iter().find(|(b, _)| b == k).map(|(_, w)| w) != Some(v))
        .map(|(k, v)| (k, v.to_string()))
        .collect();
    Ok(Entry {
        label: design.label.clone(),
        source: design.source.clone(),
        summary,
        doc: built_in.map(|b| b.doc),
        units: std::iter::once("rt_unit")
            .chain(design.config.mode.units())
            .collect(),
        differs,
    })
}

/// The listing as text: a block of lines per design, with its documentation indented after it
/// when `doc` is set.
pub fn listing(entries: &[Entry], doc: bool) -> String {
    let mut out = String::new();
    for e in entries {
        let title = if e.summary.is_empty() {
            String::new()
        } else {
            format!(": {}", e.summary)
        };
        out.push_str(&format!("{}{title}\n", e.label));
        out.push_str(&format!("  from: {}\n", e.source));
        out.push_str(&format!("  beside each SM: {}\n", e.units.join(", ")));
        let differs = if e.differs.is_empty() {
            "nothing".to_string()
        } else {
            e.differs
                .iter()
                .map(|(k, v)| format!("{k} = {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out.push_str(&format!("  differs from the baseline in: {differs}\n"));
        if doc {
            let text = e
                .doc
                .unwrap_or("(no documentation: a configuration file, not a built-in design)");
            out.push('\n');
            for line in text.lines() {
                out.push_str(format!("    {line}").trim_end());
                out.push('\n');
            }
            out.push('\n');
        }
    }
    out
}

/// Run `vtq designs`.
pub fn run(args: &DesignsArgs) -> anyhow::Result<()> {
    let names: Vec<String> = if args.designs.is_empty() {
        designs::BUILT_INS
            .iter()
            .map(|b| b.name.to_string())
            .collect()
    } else {
        args.designs.clone()
    };
    let baseline = designs::find("baseline")
        .context("the registry has no baseline design")?
        .config(&args.set)?;
    let baseline = flat(&baseline)?;
    let mut entries = Vec::new();
    for name in &names {
        let design = designs::resolve(name, &args.set)?;
        entries.push(entry(&design, &baseline)?);
    }
    print!("{}", listing(&entries, args.doc));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries() -> Vec<Entry> {
        let baseline = flat(&designs::find("baseline").unwrap().config(&[]).unwrap()).unwrap();
        designs::BUILT_INS
            .iter()
            .map(|b| entry(&designs::resolve(b.name, &[]).unwrap(), &baseline).unwrap())
            .collect()
    }

    #[test]
    fn the_baseline_differs_in_nothing_and_vtq_in_its_mode() {
        let e = entries();
        let by = |n: &str| e.iter().find(|x| x.label == n).unwrap().clone();
        assert!(by("baseline").differs.is_empty());
        assert!(by("baseline").units.contains(&"rt_unit"));
        let vtq = by("vtq");
        assert!(
            vtq.differs
                .iter()
                .any(|(k, v)| k == "mode.kind" && v == "\"queues\""),
            "{:?}",
            vtq.differs
        );
        assert!(vtq.units.contains(&"treelet_controller"), "{:?}", vtq.units);
        assert!(by("prefetch").units.contains(&"prefetcher"));
        // Every built-in design but the baseline differs from it, and each names its summary.
        for x in &e {
            assert_eq!(x.differs.is_empty(), x.label == "baseline", "{}", x.label);
            assert!(!x.summary.is_empty(), "{}", x.label);
        }
    }

    #[test]
    fn an_override_given_to_every_design_is_no_difference() {
        let sets = vec!["hw.max_rays=8192".to_string()];
        let baseline = flat(&designs::find("baseline").unwrap().config(&sets).unwrap()).unwrap();
        let vtq = entry(&designs::resolve("vtq", &sets).unwrap(), &baseline).unwrap();
        assert!(!vtq.differs.iter().any(|(k, _)| k == "hw.max_rays"));
        let text = listing(std::slice::from_ref(&vtq), false);
        assert!(text.starts_with("vtq: "), "{text}");
        assert!(text.contains("differs from the baseline in: "), "{text}");
        // With its documentation: the folder's README, indented, after the block.
        let with_doc = listing(&[vtq], true);
        assert!(with_doc.starts_with(&text), "{with_doc}");
        assert!(
            with_doc.contains("\n    # vtq: Virtualized Treelet Queues"),
            "{with_doc}"
        );
        assert!(
            with_doc.contains("    - Configuration: [`config.toml`]"),
            "{with_doc}"
        );
    }
}
