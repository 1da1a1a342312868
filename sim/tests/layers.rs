//! The simulator crate's layers (sim/src/lib.rs): every module is in the folder of its layer,
//! and imports run only downwards — a module names, through `crate::`, only modules listed
//! before it in [`ORDER`] (itself included); only the command layer uses vtq-gen (the RTL
//! generator: co-simulation, the area report); and every command module stays under
//! [`COMMAND_LINES`] lines, its experiments living in the layers below.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Every module of the crate under its layer, bottom-up: a module may import the ones before
/// it. A new module must be added here (the test fails until it is).
const ORDER: &[(&str, &str)] = &[
    ("model", "splitmix"),
    ("model", "atomic_file"),
    ("model", "geometry"),
    ("model", "intersect"),
    ("model", "scene"),
    ("model", "bvh"),
    ("model", "traversal"),
    ("model", "workload"),
    ("model", "memory"),
    ("model", "config"),
    ("model", "designs"),
    ("model", "energy"),
    ("model", "gpu"),
    ("estimate", "figure5"),
    ("estimate", "sample"),
    ("experiment", "plot"),
    ("experiment", "sweep"),
    ("experiment", "perturb"),
    ("experiment", "compare"),
    ("experiment", "compare_report"),
    ("experiment", "cosim"),
    ("experiment", "accuracy"),
    ("experiment", "reproduce"),
    ("cli", "image"),
    ("cli", "time_series"),
    ("cli", "output"),
    ("cli", "fuzz"),
    ("cli", "cmd"),
];

/// The most lines a command module (`sim/src/cli/cmd/*.rs`) may have: a command parses its
/// arguments, calls the layers below and prints.
const COMMAND_LINES: usize = 500;

/// The rank of `layer::module` in [`ORDER`].
fn rank(layer: &str, module: &str) -> Option<usize> {
    ORDER.iter().position(|&(l, m)| l == layer && m == module)
}

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read a source folder") {
        let path = entry.expect("read a folder entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The crate's source folder and every `.rs` file under it, sorted.
fn sources() -> (PathBuf, Vec<PathBuf>) {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    (src, files)
}

/// The `(layer, module)` pairs named as `crate::layer::module` in `text`.
fn crate_paths(text: &str) -> BTreeSet<(String, String)> {
    let mut found = BTreeSet::new();
    let mut rest = text;
    while let Some(at) = rest.find("crate::") {
        let after = &rest[at + "crate::".len()..];
        let ident = |s: &str| -> String {
            s.chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect()
        };
        let layer = ident(after);
        let tail = &after[layer.len()..];
        if let Some(tail) = tail.strip_prefix("::") {
            let module = ident(tail);
            if !module.is_empty() {
                found.insert((layer, module));
            }
        }
        rest = after;
    }
    found
}

#[test]
fn every_module_sits_in_its_layer_and_imports_only_downwards() {
    let (src, files) = sources();
    let mut violations = Vec::new();
    let mut seen = BTreeSet::new();
    for file in &files {
        let relative = file.strip_prefix(&src).expect("under src");
        let parts: Vec<String> = relative
            .iter()
            .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
            .collect();
        // lib.rs, main.rs and the layers' mod.rs files only declare and re-export.
        if parts.len() < 2 || parts[1] == "mod" {
            continue;
        }
        let (layer, module) = (parts[0].as_str(), parts[1].as_str());
        let Some(own) = rank(layer, module) else {
            violations.push(format!(
                "{}: module {layer}::{module} is not in ORDER",
                relative.display()
            ));
            continue;
        };
        seen.insert(own);
        let text = std::fs::read_to_string(file).expect("read a source file");
        for (l, m) in crate_paths(&text) {
            match rank(&l, &m) {
                Some(r) if r <= own => {}
                Some(_) => violations.push(format!(
                    "{}: {layer}::{module} imports crate::{l}::{m}, a layer above it",
                    relative.display()
                )),
                None => violations.push(format!(
                    "{}: crate::{l}::{m} is not a module of ORDER",
                    relative.display()
                )),
            }
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
    // splitmix is a re-export of vtq-hdl's; every other module has files.
    let missing: Vec<_> = ORDER
        .iter()
        .enumerate()
        .filter(|&(i, &(_, m))| m != "splitmix" && !seen.contains(&i))
        .map(|(_, &(l, m))| format!("{l}::{m}"))
        .collect();
    assert!(
        missing.is_empty(),
        "modules in ORDER without files: {missing:?}"
    );
}

#[test]
fn an_upward_import_is_caught() {
    // The check itself: a scene module naming the GPU is found.
    let text = "use crate::model::gpu::engine::Engine;\nuse crate::model::geometry::Ray;";
    let paths = crate_paths(text);
    assert!(paths.contains(&("model".to_string(), "gpu".to_string())));
    let scene = rank("model", "scene").unwrap();
    assert!(rank("model", "gpu").unwrap() > scene);
    assert!(rank("model", "geometry").unwrap() < scene);
}

#[test]
fn only_the_command_layer_uses_the_rtl_generator_and_commands_stay_small() {
    let (src, files) = sources();
    let mut violations = Vec::new();
    for file in &files {
        let relative = file.strip_prefix(&src).expect("under src");
        let text = std::fs::read_to_string(file).expect("read a source file");
        let in_cli = relative.starts_with("cli") || relative.ends_with("main.rs");
        if !in_cli && text.contains("vtq_gen") {
            violations.push(format!(
                "{}: uses vtq_gen outside the command layer",
                relative.display()
            ));
        }
        let lines = text.lines().count();
        if relative.starts_with("cli/cmd") && lines > COMMAND_LINES {
            violations.push(format!(
                "{}: {lines} lines, more than the {COMMAND_LINES} a command module may have",
                relative.display()
            ));
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}
