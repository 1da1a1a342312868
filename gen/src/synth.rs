//! Yosys generic synthesis and Verilator lint of generated Verilog, as structured results.
//!
//! [`synthesize`] runs `read_verilog; synth -flatten -top X; check; stat -json` and reports the
//! cell counts by type, the flip-flop and latch bit counts and every warning (undriven wires
//! among them). [`synthesize_logic`] runs the quicker script of the logic-area report
//! ([`LOGIC_SCRIPT`]): latency-1 memories (SRAM arrays) stay memories instead of becoming
//! flip-flops, and the gate-level `opt` passes ABC makes redundant are left out. [`lint`] runs `verilator --lint-only -Wall` and reports each message with its
//! code and location. A missing tool is [`GenError::ToolMissing`].

use crate::error::GenError;
use crate::tools::run;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What Yosys made of a design.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SynthReport {
    /// Top module.
    pub top: String,
    /// Cells after generic synthesis (one cell per bit for gates and flip-flops).
    pub cells: u64,
    /// Cells by Yosys cell type (`$_AND_`, `$_SDFFE_PP0P_`, ...).
    pub cells_by_type: BTreeMap<String, u64>,
    /// Flip-flop bits (cells whose type is a `DFF` variant).
    pub flip_flops: u64,
    /// Latch bits (`$_DLATCH*`, `$_SR_*`, `$dlatch`, `$sr` cells); a clean design has none.
    pub latches: u64,
    /// Memory bits Yosys kept as memories (not mapped to flip-flops).
    pub memory_bits: u64,
    /// Memory cells (`$mem`, `$mem_v2`) left unmapped: each is an SRAM array whose area the
    /// storage model gives, not logic ([`synthesize_logic`] keeps them).
    pub memory_cells: u64,
    /// Every distinct warning Yosys printed, in order.
    pub warnings: Vec<String>,
    /// The warnings that name a wire without a driver.
    pub undriven: Vec<String>,
}

impl SynthReport {
    /// No latches and no warnings.
    pub fn is_clean(&self) -> bool {
        self.latches == 0 && self.warnings.is_empty()
    }
}

/// One Verilator message.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LintMessage {
    /// `Warning` or `Error`.
    pub severity: String,
    /// Warning code (`UNUSEDSIGNAL`, `WIDTHTRUNC`, ...), empty for plain errors.
    pub code: String,
    /// `file:line:col`, when given.
    pub location: String,
    /// The message text.
    pub message: String,
}

/// Verilator's verdict on a design.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LintReport {
    /// Top module.
    pub top: String,
    /// Every warning and error, in order.
    pub messages: Vec<LintMessage>,
}

impl LintReport {
    /// No warnings and no errors.
    pub fn is_clean(&self) -> bool {
        self.messages.is_empty()
    }
}

impl std::fmt::Display for LintReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.messages.is_empty() {
            return writeln!(f, "verilator lint of {}: clean", self.top);
        }
        for m in &self.messages {
            writeln!(
                f,
                "%{}{}: {} {}",
                m.severity,
                if m.code.is_empty() {
                    String::new()
                } else {
                    format!("-{}", m.code)
                },
                m.location,
                m.message
            )?;
        }
        Ok(())
    }
}

/// Absolute versions of `files`, so tools can run in another directory.
fn absolute(files: &[PathBuf]) -> Result<Vec<String>, GenError> {
    files
        .iter()
        .map(|f| {
            std::fs::canonicalize(f)
                .map(|p| p.display().to_string())
                .map_err(|e| GenError::io(format!("finding Verilog source {}", f.display()), e))
        })
        .collect()
}

/// Synthesizes `files` with top module `top` using Yosys' generic `synth`, working in
/// `work_dir` (which must exist; the statistics file is written there).
pub fn synthesize(files: &[PathBuf], top: &str, work_dir: &Path) -> Result<SynthReport, GenError> {
    run_yosys(
        files,
        top,
        work_dir,
        &format!("synth -flatten -top {top}"),
        "",
    )
}

/// The Yosys script of [`synthesize_logic`] after `read_verilog`, with `{top}` for the top
/// module: `synth`'s coarse stage (`-run begin:fine`: `proc`, `flatten`, `opt`, `fsm`,
/// `wreduce`, `alumacc`, `share`, `memory -nomap`), then `synth`'s fine stage without
/// `memory_map` (memories stay `$mem_v2` cells) and without the gate-level `opt -full` and
/// `opt -fast` passes (`opt_clean` instead; ABC optimizes the gates): on the paper's 600-entry
/// count table this halves Yosys' time for cell counts within 1% of `synth`'s.
pub const LOGIC_SCRIPT: &str =
    "synth -flatten -top {top} -run begin:fine; opt -fast -full; techmap; opt_clean; abc -fast; \
     opt_clean; hierarchy -check";

/// Synthesizes `files` with top module `top` for the logic-area report ([`LOGIC_SCRIPT`]):
/// latency-1 memories are kept as `$mem_v2` cells ([`SynthReport::memory_cells`]), everything
/// else is mapped to Yosys' internal gates and flip-flops.
pub fn synthesize_logic(
    files: &[PathBuf],
    top: &str,
    work_dir: &Path,
) -> Result<SynthReport, GenError> {
    run_yosys(
        files,
        top,
        work_dir,
        &LOGIC_SCRIPT.replace("{top}", top),
        "",
    )
}

/// The Yosys script of [`synthesize_logic_hierarchy`]: [`LOGIC_SCRIPT`] keeping the hierarchy
/// (each module synthesized once, however many instances it has) and without `share`'s
/// SAT-based resource sharing (on the RT unit's lanes it ran for minutes and merges little).
pub const HIERARCHY_LOGIC_SCRIPT: &str =
    "synth -top {top} -noshare -run begin:fine; opt -fast -full; techmap; opt_clean; \
     abc -fast; opt_clean; hierarchy -check";

/// [`synthesize_logic`] for a design built of many instances of a few modules (the RT unit's
/// lanes): [`HIERARCHY_LOGIC_SCRIPT`], the statistics of the whole hierarchy under `top`
/// (every instance counted). Black-box modules stay cells of their own type.
pub fn synthesize_logic_hierarchy(
    files: &[PathBuf],
    top: &str,
    work_dir: &Path,
) -> Result<SynthReport, GenError> {
    let script = HIERARCHY_LOGIC_SCRIPT.replace("{top}", top);
    run_yosys(files, top, work_dir, &script, &format!(" -top {top}"))
}

/// Runs `read_verilog FILES; SCRIPT; check; stat -json STAT_ARGS` and reads the statistics.
fn run_yosys(
    files: &[PathBuf],
    top: &str,
    work_dir: &Path,
    synth: &str,
    stat_args: &str,
) -> Result<SynthReport, GenError> {
    let sources = absolute(files)?;
    let stat_file = format!("{top}_stat.json");
    let script = format!(
        "read_verilog {}; {synth}; check; tee -q -o {stat_file} stat -json{stat_args}",
        sources
            .iter()
            .map(|s| format!("\"{s}\""))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let (out, _) = run("yosys", &["-p", &script], work_dir, false)?;
    let stat_path = work_dir.join(&stat_file);
    let stat = std::fs::read_to_string(&stat_path)
        .map_err(|e| GenError::io(format!("reading {}", stat_path.display()), e))?;
    let mut report = parse_stat(&stat, top)?;
    let mut warnings: Vec<String> = Vec::new();
    for line in out.stdout.lines().chain(out.stderr.lines()) {
        if let Some(w) = line.trim().strip_prefix("Warning:") {
            let w = w.trim().to_string();
            if !warnings.contains(&w) {
                warnings.push(w);
            }
        }
    }
    report.undriven = warnings
        .iter()
        .filter(|w| w.contains("no driver") || w.contains("undriven"))
        .cloned()
        .collect();
    report.warnings = warnings;
    Ok(report)
}

/// Reads Yosys' `stat -json` output.
fn parse_stat(json: &str, top: &str) -> Result<SynthReport, GenError> {
    let bad = |reason: String| GenError::Parse {
        tool: "yosys".to_string(),
        reason,
    };
    // Yosys 0.23 prints a line of its text hierarchy into the JSON of a design three modules
    // deep (`       rt_unit_stack_bank            8`); such lines are not JSON and are dropped.
    let json: String = json
        .lines()
        .filter(|l| {
            let t = l.trim_start();
            t.is_empty() || t.starts_with(['"', '{', '}', '[', ']'])
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let v: serde_json::Value =
        serde_json::from_str(&json).map_err(|e| bad(format!("stat -json is not JSON: {e}")))?;
    let design = v
        .get("design")
        .or_else(|| v.get("modules").and_then(|m| m.get(format!("\\{top}"))))
        .ok_or_else(|| bad(format!("stat -json has no statistics for `{top}`")))?;
    let num = |key: &str| design.get(key).and_then(|x| x.as_u64()).unwrap_or(0);
    let mut cells_by_type = BTreeMap::new();
    if let Some(map) = design.get("num_cells_by_type").and_then(|m| m.as_object()) {
        for (k, n) in map {
            let n = n
                .as_u64()
                .ok_or_else(|| bad(format!("cell count of {k} is not a number")))?;
            cells_by_type.insert(k.clone(), n);
        }
    }
    let count = |pred: &dyn Fn(&str) -> bool| -> u64 {
        cells_by_type
            .iter()
            .filter(|(k, _)| pred(k.as_str()))
            .map(|(_, n)| *n)
            .sum()
    };
    let latches = count(&|k| {
        let k = k.to_ascii_uppercase();
        k.contains("DLATCH") || k.starts_with("$_SR_") || k == "$SR"
    });
    let flip_flops = count(&|k| k.to_ascii_uppercase().contains("DFF"));
    let memory_cells = count(&|k| k == "$mem" || k == "$mem_v2");
    Ok(SynthReport {
        top: top.to_string(),
        cells: num("num_cells"),
        cells_by_type,
        flip_flops,
        latches,
        memory_bits: num("num_memory_bits"),
        memory_cells,
        warnings: vec![],
        undriven: vec![],
    })
}

/// Lints `files` with `verilator --lint-only -Wall`, top module `top`, running in `work_dir`.
/// Warnings are reported, not errors; a run that fails without any message is an error.
pub fn lint(files: &[PathBuf], top: &str, work_dir: &Path) -> Result<LintReport, GenError> {
    let sources = absolute(files)?;
    let mut args = vec!["--lint-only", "-Wall", "--top-module", top];
    args.extend(sources.iter().map(String::as_str));
    let (out, ok) = run("verilator", &args, work_dir, true)?;
    let text = format!("{}{}", out.stdout, out.stderr);
    let messages = parse_lint(&text);
    if !ok && messages.is_empty() {
        return Err(GenError::ToolFailed {
            tool: "verilator".to_string(),
            status: "non-zero exit without messages".to_string(),
            output: text,
        });
    }
    Ok(LintReport {
        top: top.to_string(),
        messages,
    })
}

/// Parses `%Warning-CODE: file:line:col: text` and `%Error[-CODE]: ...` lines; the final
/// "Exiting due to N warning(s)" line is a summary, not a message.
fn parse_lint(text: &str) -> Vec<LintMessage> {
    let mut messages = Vec::new();
    for line in text.lines() {
        let Some(rest) = line.strip_prefix('%') else {
            continue;
        };
        let Some((head, body)) = rest.split_once(": ") else {
            continue;
        };
        let (severity, code) = match head.split_once('-') {
            Some((s, c)) => (s, c),
            None => (head, ""),
        };
        if !(severity == "Warning" || severity == "Error") {
            continue;
        }
        if body.starts_with("Exiting due to") {
            continue;
        }
        // The location is the first `: `-separated part when it looks like file:line.
        let (location, message) = match body.split_once(": ") {
            Some((loc, msg)) if loc.contains(':') && !loc.contains(' ') => {
                (loc.to_string(), msg.to_string())
            }
            _ => (String::new(), body.to_string()),
        };
        messages.push(LintMessage {
            severity: severity.to_string(),
            code: code.to_string(),
            location,
            message,
        });
    }
    messages
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_verilator_messages() {
        let text = "%Warning-UNUSEDSIGNAL: t.v:10:15: Signal is not used: 'mem'\n\
                    \x20  10 |     reg [7:0] mem [0:15];\n\
                    %Warning-LATCH: t.v:19:5: Latch inferred for signal 'l'\n\
                    %Error: t.v:3:1: syntax error, unexpected end\n\
                    %Error: Exiting due to 3 warning(s)\n";
        let m = parse_lint(text);
        assert_eq!(m.len(), 3);
        assert_eq!(m[0].code, "UNUSEDSIGNAL");
        assert_eq!(m[0].location, "t.v:10:15");
        assert_eq!(m[0].message, "Signal is not used: 'mem'");
        assert_eq!(m[1].code, "LATCH");
        assert_eq!(m[2].severity, "Error");
        assert_eq!(m[2].code, "");
    }

    #[test]
    fn parses_yosys_stat() {
        let json = r#"{"modules": {"\\t": {"num_cells": 9, "num_memory_bits": 0,
            "num_cells_by_type": {"$_DLATCH_P_": 4, "$_SDFFE_PP0P_": 4, "$_XOR_": 1}}}}"#;
        let r = parse_stat(json, "t").unwrap();
        assert_eq!(r.cells, 9);
        assert_eq!(r.latches, 4);
        assert_eq!(r.flip_flops, 4);
        assert!(!r.is_clean());
        assert!(parse_stat("{}", "t").is_err());
        assert!(parse_stat("not json", "t").is_err());
    }

    #[test]
    fn a_stray_hierarchy_line_in_yosys_stat_is_dropped() {
        let json =
            "{\n \"modules\": {},\n       bank            8\n \"design\": {\"num_cells\": 3,\n  \
                    \"num_cells_by_type\": {\"$mem_v2\": 2, \"$_XOR_\": 1}}\n}\n";
        let r = parse_stat(json, "t").unwrap();
        assert_eq!((r.cells, r.memory_cells), (3, 2));
    }
}
