//! `vtq fuzz`: feed mutated and random inputs to every parser of user input and report cases,
//! panics, hangs and the slowest case per parser (`docs/fuzzing.md`).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::Args;

use crate::cli::fuzz::{fuzz_parser, replay, FuzzOptions, Parser, ParserReport};

/// Options of `vtq fuzz`.
#[derive(Debug, Args)]
pub struct FuzzArgs {
    /// Parser to fuzz: obj, mtl, gltf, ply, scene-toml, config, set, rays-csv, ray-file, bvh-cache or
    /// all.
    #[arg(long, default_value = "all")]
    pub parser: String,
    /// Cases per parser.
    #[arg(long, default_value_t = 10_000)]
    pub cases: u64,
    /// Seed of the case generator (the same seed gives the same inputs).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Time bound of one case in milliseconds; a case still running then is a hang.
    #[arg(long, default_value_t = 2000)]
    pub timeout_ms: u64,
    /// Folder where inputs that panic or hang are saved (created on the first one).
    #[arg(long, default_value = "vtq-fuzz-failures")]
    pub save_dir: PathBuf,
    /// Stop a parser after this many hangs.
    #[arg(long, default_value_t = 3)]
    pub max_hangs: u64,
    /// Run this one saved input through --parser (one parser, not all) and say how it ended.
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,
}

/// The parsers `name` selects.
fn parsers(name: &str) -> anyhow::Result<Vec<Parser>> {
    if name == "all" {
        return Ok(Parser::ALL.to_vec());
    }
    match Parser::from_name(name) {
        Some(p) => Ok(vec![p]),
        None => bail!(
            "unknown parser '{name}': expected all or one of {}",
            Parser::ALL.map(Parser::name).join(", ")
        ),
    }
}

/// The table of reports, one parser per line after a header.
pub fn table(reports: &[ParserReport]) -> String {
    let mut out = format!(
        "{:<10}  {:>9}  {:>9}  {:>9}  {:>6}  {:>5}  {:>20}  {:>8}  {}\n",
        "parser",
        "cases",
        "accepted",
        "rejected",
        "panics",
        "hangs",
        "slowest (case)",
        "wall s",
        "inputs digest"
    );
    for r in reports {
        let slowest = format!(
            "{:.3} ms (#{})",
            r.slowest.1.as_secs_f64() * 1000.0,
            r.slowest.0
        );
        out.push_str(&format!(
            "{:<10}  {:>9}  {:>9}  {:>9}  {:>6}  {:>5}  {:>20}  {:>8.2}  {}\n",
            r.parser.name(),
            r.cases,
            r.accepted,
            r.rejected,
            r.panics.len(),
            r.hangs.len(),
            slowest,
            r.wall.as_secs_f64(),
            r.digest
        ));
    }
    out
}

/// Run `vtq fuzz`.
pub fn run(args: &FuzzArgs) -> anyhow::Result<()> {
    let timeout = Duration::from_millis(args.timeout_ms.max(1));
    let selected = parsers(&args.parser)?;
    if let Some(file) = &args.replay {
        let [parser] = selected[..] else {
            bail!("--replay needs one --parser (obj, mtl, ...), not all");
        };
        let how =
            replay(parser, file, timeout).with_context(|| format!("reading {}", file.display()))?;
        println!("{} on {}: {how}", parser.name(), file.display());
        if how.starts_with("PANIC") || how.starts_with("HANG") {
            bail!("the input still fails");
        }
        return Ok(());
    }
    // Inputs that fail are saved there: checked before fuzzing (created on the first one).
    crate::cli::output::check_dir(&args.save_dir)?;
    let options = FuzzOptions {
        cases: args.cases,
        seed: args.seed,
        timeout,
        save_dir: Some(args.save_dir.clone()),
        max_hangs: args.max_hangs.max(1),
    };
    println!(
        "fuzz: {} case(s) per parser, seed {}, time bound {} ms per case",
        args.cases, args.seed, args.timeout_ms
    );
    let mut reports = Vec::new();
    for parser in selected {
        let report = fuzz_parser(parser, &options);
        for f in report.panics.iter().chain(&report.hangs) {
            let saved = f.saved.as_ref().map_or_else(
                || "not saved".into(),
                |p| format!("saved as {}", p.display()),
            );
            let message: String = f.message.replace('\n', " ").chars().take(300).collect();
            println!("{} case {}: {message} ({saved})", parser.name(), f.case);
        }
        reports.push(report);
    }
    print!("{}", table(&reports));
    let panics: usize = reports.iter().map(|r| r.panics.len()).sum();
    let hangs: usize = reports.iter().map(|r| r.hangs.len()).sum();
    if panics + hangs > 0 {
        bail!(
            "{panics} panic(s) and {hangs} hang(s); reproduce one with \
             `vtq fuzz --parser P --replay FILE`"
        );
    }
    Ok(())
}
