//! Builds the design registry: every folder of `configs/designs/` is a design named after the
//! folder, holding its configuration (`config.toml`) and its documentation (`README.md`, whose
//! first line is `# NAME: SUMMARY`). The registry (`BUILT_INS` of `sim/src/model/designs.rs`)
//! is generated from the folders, so adding a design is adding its folder.

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let root = Path::new(&manifest).join("..");
    let dir = root.join("configs/designs");
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot read the design folder {}: {e}", dir.display()))
        .map(|e| e.expect("a readable design folder entry"))
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut code = format!(
        "/// Every built-in design: the folders of `configs/designs/`, by name.\n\
         pub const BUILT_INS: [BuiltIn; {}] = [\n",
        names.len()
    );
    for name in &names {
        let folder = dir.join(name);
        let config = folder.join("config.toml");
        let readme = folder.join("README.md");
        for f in [&config, &readme] {
            assert!(f.is_file(), "design `{name}` has no {}", f.display());
        }
        let doc = std::fs::read_to_string(&readme)
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", readme.display()));
        let heading = doc.lines().next().unwrap_or_default();
        let summary = heading
            .strip_prefix(&format!("# {name}: "))
            .filter(|s| !s.trim().is_empty())
            .unwrap_or_else(|| {
                panic!(
                    "{}: the first line must be `# {name}: SUMMARY`, found `{heading}`",
                    readme.display()
                )
            });
        writeln!(
            code,
            "    BuiltIn {{\n        name: {name:?},\n        path: {path:?},\n        \
             toml: include_str!({config:?}),\n        doc: include_str!({readme:?}),\n        \
             summary: {summary:?},\n    }},",
            path = format!("configs/designs/{name}/config.toml"),
            config = config.display().to_string(),
            readme = readme.display().to_string(),
        )
        .expect("writing to a String");
    }
    code.push_str("];\n");
    let out = Path::new(&std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("designs.rs");
    std::fs::write(&out, code).unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
}
