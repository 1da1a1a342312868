//! Blocks have one face: a parent (the treelet RT unit over its children) and the simulator
//! (over the RT hardware beside each SM) call only the block framework's functions of a block
//! — `eval`, `next_into`, `step` and the rest of `Block`, the register-only outputs
//! (`Moore`), the cached step (`Cached`), clock gating (`Skip`) and observer probes (`Taps`) —
//! plus the block's configuration accessors and one observer tap of the treelet RT unit,
//! listed here with why each is not a way around the framework. Everything else of a block's state is read from its outputs.
//!
//! The test reads the sources: every method called on a child (`u.rt.`, `self.ct.`, ...) in
//! the composite's files and on the unit (`self.unit.`, `unit.`) in the simulator's RT
//! hardware must be in the lists below.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The block framework's functions (`vtq_hdl::block`).
const FRAMEWORK: &[&str] = &[
    // Block
    "reset",
    "idle_inputs",
    "next_into",
    "eval",
    "step",
    "reg_signals",
    "describe",
    "debug_state",
    // Cached
    "cache",
    "step_cached",
    "step_cached_into",
    // Moore
    "status",
    "status_into",
    // Skip
    "idle_cycles",
    "skip",
    "gated",
    // Taps: observer probes, not ports (nothing in the hardware reads them; they change no
    // state): per slot the rays traversing, their sum, every traversing ray's next node address
    "slot_lanes",
    "traversing_rays",
    "next_addresses",
];

/// Configuration accessors and constructors: they read parameters fixed at construction, not
/// state.
const CONFIGURATION: &[&str] = &[
    "new",
    "config",
    "params",
    "features",
    "widths",
    "treelet_of",
    "rt_unit",
    "empty_outputs",
    "check_issue",
];

/// The one observer tap outside the framework's `Taps`, the treelet RT unit's alone: the kind
/// of warp a fill builds (what the warp-cost attribution charges a ray-record load to). It is
/// not a port and changes no state.
const TAPS: &[&str] = &["fill_kind"];

/// The workspace root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate sits in the workspace")
        .to_path_buf()
}

/// The `.rs` files under `dir` (recursively), test modules (`tests.rs`) left out.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let path = entry.expect("a directory entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs")
                && path.file_name().is_some_and(|n| n != "tests.rs")
            {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// Every method called on a receiver ending in one of `receivers` (`.rt`, `unit`, ...) in
/// `text`, outside comments, with its line: `(method, line)`. A call split over lines
/// (`self\n    .unit\n    .status(`) counts too: the text is read with whitespace before a
/// `.` removed.
fn calls(text: &str, receivers: &[&str]) -> Vec<(String, usize)> {
    let code: Vec<&str> = text
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect();
    // Joined with line breaks kept as markers, whitespace before a '.' dropped.
    let mut joined = String::new();
    let mut line_of = Vec::new();
    for (n, l) in code.iter().enumerate() {
        for c in l.chars().chain(std::iter::once('\n')) {
            joined.push(c);
            line_of.push(n + 1);
        }
    }
    let bytes: Vec<char> = joined.chars().collect();
    let mut found = Vec::new();
    for recv in receivers {
        let pat: Vec<char> = recv.chars().collect();
        let mut i = 0;
        while i + pat.len() <= bytes.len() {
            if bytes[i..i + pat.len()] == pat[..]
                && (i == 0 || !(bytes[i - 1].is_alphanumeric() || bytes[i - 1] == '_'))
            {
                // After the receiver: optional whitespace, '.', a name, '('.
                let mut j = i + pat.len();
                while j < bytes.len() && bytes[j].is_whitespace() {
                    j += 1;
                }
                if j < bytes.len() && bytes[j] == '.' {
                    let start = j + 1;
                    let mut k = start;
                    while k < bytes.len() && (bytes[k].is_alphanumeric() || bytes[k] == '_') {
                        k += 1;
                    }
                    if k > start && k < bytes.len() && bytes[k] == '(' {
                        let name: String = bytes[start..k].iter().collect();
                        found.push((name, line_of[i]));
                    }
                }
                i += pat.len();
            } else {
                i += 1;
            }
        }
    }
    found
}

/// The calls in the files under `dir` on `receivers` that are not in the allowed lists, as
/// `file:line method`, and how many calls were checked.
fn outside_framework(dir: &Path, receivers: &[&str]) -> (Vec<String>, usize) {
    let allowed =
        |m: &str| FRAMEWORK.contains(&m) || CONFIGURATION.contains(&m) || TAPS.contains(&m);
    let mut bad = Vec::new();
    let mut checked = 0;
    for file in sources(dir) {
        let text = std::fs::read_to_string(&file).expect("a readable source");
        // Unit-test modules inline in a file are left out with the file's test module.
        let text = text.split("#[cfg(test)]").next().unwrap_or("");
        for (method, line) in calls(text, receivers) {
            checked += 1;
            if !allowed(&method) {
                bad.push(format!("{}:{line} {method}", file.display()));
            }
        }
    }
    (bad, checked)
}

/// Asserts that the files under `dir` (from the workspace root) call only allowed functions on
/// `receivers`, after checking at least `at_least` calls (so a broken scan cannot pass).
fn assert_framework_only(dir: &str, receivers: &[&str], at_least: usize) {
    let (bad, checked) = outside_framework(&root().join(dir), receivers);
    assert!(
        checked >= at_least,
        "only {checked} calls found in {dir}: the scan is broken"
    );
    assert!(
        bad.is_empty(),
        "calls outside the framework:\n{}",
        bad.join("\n")
    );
}

/// The composite calls only the framework's functions of its children (and their
/// configuration and taps).
#[test]
fn the_composite_reads_its_children_only_through_the_framework() {
    let children = [
        "u.rt", "u.ctl", "u.ct", "u.qt", "self.rt", "self.ctl", "self.ct", "self.qt",
    ];
    assert_framework_only("hdl/src/treelet_rt_unit", &children, 30);
}

/// The simulator calls only the framework's functions of the RT hardware beside an SM (and its
/// configuration and taps).
#[test]
fn the_simulator_reads_the_rt_hardware_only_through_the_framework() {
    assert_framework_only("sim/src/model/gpu/rt", &["unit"], 20);
}

/// The scan finds calls split over lines and flags a method outside the lists (what the two
/// tests above would report if a parent read a child's registers another way).
#[test]
fn the_scan_flags_a_register_reading_call() {
    let text = "fn f() {\n    let a = u.ct.busy(&regs.ct); // u.ct.comment(\n    let b = self\n        .unit\n        .status(&r, &c, false);\n}\n";
    let found: BTreeMap<String, usize> = calls(text, &["u.ct", "self.unit", "unit"])
        .into_iter()
        .collect();
    assert_eq!(found.get("busy"), Some(&2));
    assert_eq!(found.get("status"), Some(&4));
    assert!(!found.contains_key("comment"));
    assert!(
        !FRAMEWORK.contains(&"busy") && !CONFIGURATION.contains(&"busy") && !TAPS.contains(&"busy")
    );
}
