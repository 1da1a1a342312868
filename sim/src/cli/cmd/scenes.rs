//! `vtq scenes`: a table of the built-in scenes and the scene folders of `../shared/scenes`.

use clap::Args;

use crate::model::scene::load::{
    list_scenes, shared_scenes_dir, CountSource, SceneInfo, SceneKind,
};

/// Options of `vtq scenes` (none).
#[derive(Debug, Args)]
pub struct ScenesArgs {}

/// A count for the table: `?` when unknown, `~` marking a count read from a manifest.
fn count(info: &SceneInfo, n: Option<usize>) -> String {
    match (n, info.counted) {
        (None, _) | (_, CountSource::Unknown) => "?".into(),
        (Some(n), CountSource::Manifest) => format!("{n}~"),
        (Some(n), CountSource::Loaded) => n.to_string(),
    }
}

/// The table as text, one scene per line after a header.
pub fn table(scenes: &[SceneInfo]) -> String {
    let rows: Vec<[String; 7]> = scenes
        .iter()
        .map(|s| {
            let source = match &s.kind {
                SceneKind::BuiltIn => "built-in".to_string(),
                SceneKind::Folder(dir) => dir.display().to_string(),
            };
            let complete = match s.complete {
                Some(true) => "yes",
                Some(false) => "no",
                None => "?",
            };
            let mut title = s.title.clone();
            if let Some(p) = &s.problem {
                title = if title.is_empty() {
                    format!("[{p}]")
                } else {
                    format!("{title} [{p}]")
                };
            }
            [
                s.name.clone(),
                s.label.clone(),
                count(s, s.triangles),
                s.spheres.to_string(),
                count(s, s.prims()),
                complete.to_string(),
                format!("{title} ({source})"),
            ]
        })
        .collect();
    let header = [
        "scene",
        "label",
        "triangles",
        "spheres",
        "primitives",
        "complete",
        "description (source)",
    ];
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in &rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.len());
        }
    }
    let line = |cells: Vec<&str>| {
        let mut out = String::new();
        for (i, (cell, w)) in cells.iter().zip(&widths).enumerate() {
            match i {
                0 | 1 | 5 => out.push_str(&format!("{cell:<w$}  ")),
                6 => out.push_str(cell),
                _ => out.push_str(&format!("{cell:>w$}  ")),
            }
        }
        out.trim_end().to_string() + "\n"
    };
    let mut out = line(header.to_vec());
    for row in &rows {
        out.push_str(&line(row.iter().map(String::as_str).collect()));
    }
    out
}

/// Run `vtq scenes`.
pub fn run(_args: &ScenesArgs) -> anyhow::Result<()> {
    print!("{}", table(&list_scenes()));
    match shared_scenes_dir() {
        Some(dir) => println!(
            "~ = count from the folder's scene.toml; scene folders from {}",
            dir.display()
        ),
        None => println!("(no ../shared/scenes folder found: built-in scenes only)"),
    }
    Ok(())
}
