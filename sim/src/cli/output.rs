//! Output files and folders of the commands: checked before the work, so that a path that
//! cannot be written fails in a moment with a one-line error naming it instead of after a long
//! run ([`check_file`], [`check_file_or_dirs`], [`check_dir`]); and written so that a failure
//! after the work keeps the result in a fallback file the error names ([`write_or_keep`]),
//! with the failures of several outputs reported together ([`Failures`]).
//!
//! The checks create nothing that stays: a probe file is created and removed again, and
//! missing folders are only checked to be creatable (their nearest existing ancestor is a
//! writable folder).

use std::fs::OpenOptions;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{anyhow, bail};

/// A probe file name in `dir`, unique to this process and call.
fn probe_path(dir: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    dir.join(format!(
        ".vtq-probe.{}.{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ))
}

/// `path` as shown in messages (`.` for the empty path of the current folder).
fn shown(path: &Path) -> String {
    if path.as_os_str().is_empty() {
        ".".into()
    } else {
        path.display().to_string()
    }
}

/// Checks that a file can be created in the existing folder `dir` (creates and removes a probe
/// file).
fn probe_dir(dir: &Path, what: &Path) -> anyhow::Result<()> {
    let folder = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let probe = probe_path(folder);
    match OpenOptions::new().write(true).create_new(true).open(&probe) {
        Ok(_) => {
            // Best effort: the probe is empty and uniquely named.
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => bail!(
            "cannot write {}: cannot create a file in {}: {e}",
            shown(what),
            shown(dir)
        ),
    }
}

/// Checks that the file `path` can be written by a writer that does not create folders: its
/// folder exists and takes a new file, `path` is not a folder, and an existing `path` opens
/// for writing (it is left unchanged). The error names the path.
pub fn check_file(path: &Path) -> anyhow::Result<()> {
    let parent = path.parent().unwrap_or(Path::new(""));
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => bail!("cannot write {}: it is a folder", shown(path)),
        Ok(_) => {
            OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| anyhow!("cannot write {}: {e}", shown(path)))?;
            Ok(())
        }
        Err(_) => {
            if !parent.as_os_str().is_empty() {
                match std::fs::metadata(parent) {
                    Ok(m) if m.is_dir() => {}
                    Ok(_) => bail!(
                        "cannot write {}: {} is not a folder",
                        shown(path),
                        shown(parent)
                    ),
                    Err(e) => bail!("cannot write {}: {}: {e}", shown(path), shown(parent)),
                }
            }
            probe_dir(parent, path)
        }
    }
}

/// Checks that the folder `dir` can be written, or created and then written: it is a folder
/// that takes a new file, or it is missing and its nearest existing ancestor is such a folder.
/// Creates nothing that stays. The error names the folder.
pub fn check_dir(dir: &Path) -> anyhow::Result<()> {
    let mut existing = dir;
    loop {
        match std::fs::metadata(if existing.as_os_str().is_empty() {
            Path::new(".")
        } else {
            existing
        }) {
            Ok(m) if m.is_dir() => return probe_dir(existing, dir),
            Ok(_) => bail!(
                "cannot create the folder {}: {} is not a folder",
                shown(dir),
                shown(existing)
            ),
            Err(e) if e.kind() == ErrorKind::NotFound => match existing.parent() {
                Some(parent) => existing = parent,
                None => bail!("cannot create the folder {}: {e}", shown(dir)),
            },
            Err(e) => bail!(
                "cannot create the folder {}: {}: {e}",
                shown(dir),
                shown(existing)
            ),
        }
    }
}

/// Checks the file `path` for a writer that creates its missing folders (as
/// [`write_atomic`](crate::model::atomic_file::write_atomic) does): `path` is not a folder, and its
/// folder can be written or created ([`check_dir`]).
pub fn check_file_or_dirs(path: &Path) -> anyhow::Result<()> {
    if path.is_dir() {
        bail!("cannot write {}: it is a folder", shown(path));
    }
    match path.parent() {
        Some(parent) => {
            check_dir(parent).map_err(|e| anyhow!("cannot write {}: {e:#}", shown(path)))
        }
        None => Ok(()),
    }
}

/// The places tried, in order, for a result that could not be written to `path`:
/// `vtq-kept-<pid>-<file name>` in the current folder, then in the system's temporary folder.
pub fn fallback_paths(path: &Path) -> Vec<PathBuf> {
    let name = path
        .file_name()
        .map_or_else(|| "result".into(), |n| n.to_string_lossy().into_owned());
    let kept = format!("vtq-kept-{}-{name}", std::process::id());
    let mut paths = vec![PathBuf::from(&kept)];
    let tmp = std::env::temp_dir().join(&kept);
    if std::path::absolute(&paths[0]).ok() != std::path::absolute(&tmp).ok() {
        paths.push(tmp);
    }
    paths
}

/// Writes an output with `write` (which is given the path to write): to `path`, or when that
/// fails, to the first of [`fallback_paths`] that works. Returns an error naming `path` (and
/// the fallback file that keeps the result, if any) when `path` could not be written, so the
/// command ends with a non-zero exit; the work is not lost.
pub fn write_or_keep<E: std::fmt::Display>(
    path: &Path,
    mut write: impl FnMut(&Path) -> Result<(), E>,
) -> anyhow::Result<()> {
    let err = match write(path) {
        Ok(()) => return Ok(()),
        Err(e) => e.to_string(),
    };
    for fallback in fallback_paths(path) {
        if write(&fallback).is_ok() {
            let shown_fallback = std::path::absolute(&fallback).unwrap_or(fallback);
            bail!(
                "cannot write {}: {err}; the result is kept in {}",
                shown(path),
                shown_fallback.display()
            );
        }
    }
    bail!(
        "cannot write {}: {err}; no fallback file could be written either",
        shown(path)
    )
}

/// Outputs that failed, reported together when the command ends so that one failure does not
/// stop the other outputs from being written.
#[derive(Debug, Default)]
pub struct Failures(Vec<String>);

impl Failures {
    /// Notes `result`'s error, if any; whether it was `Ok`.
    pub fn note(&mut self, result: anyhow::Result<()>) -> bool {
        match result {
            Ok(()) => true,
            Err(e) => {
                self.0.push(format!("{e:#}"));
                false
            }
        }
    }

    /// Whether nothing failed.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// `Ok` when nothing failed; else an error counting and repeating the failures.
    pub fn finish(self) -> anyhow::Result<()> {
        match self.0.len() {
            0 => Ok(()),
            1 => Err(anyhow!("{}", self.0[0])),
            n => Err(anyhow!("{n} outputs failed: {}", self.0.join("; "))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vtq-output-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> usize {
        std::fs::read_dir(dir).unwrap().count()
    }

    #[test]
    fn checks_pass_for_writable_places_and_leave_nothing() {
        let dir = scratch("ok");
        check_file(&dir.join("a.json")).unwrap();
        check_dir(&dir.join("new/deeper")).unwrap();
        check_dir(&dir).unwrap();
        check_file_or_dirs(&dir.join("new/b.csv")).unwrap();
        assert_eq!(entries(&dir), 0, "nothing is left behind");
        std::fs::write(dir.join("old.json"), b"keep").unwrap();
        check_file(&dir.join("old.json")).unwrap();
        assert_eq!(std::fs::read(dir.join("old.json")).unwrap(), b"keep");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn checks_fail_naming_the_path() {
        let dir = scratch("bad");
        let file = dir.join("plain");
        std::fs::write(&file, b"").unwrap();
        let under_file = file.join("x.json");
        for err in [
            check_file(&under_file).unwrap_err(),
            check_file(&dir.join("missing/x.json")).unwrap_err(),
            check_file(&dir).unwrap_err(),
            check_dir(&under_file).unwrap_err(),
            check_dir(&file).unwrap_err(),
            check_file_or_dirs(&file.join("a/b.csv")).unwrap_err(),
        ] {
            let text = format!("{err:#}");
            assert!(text.contains(&dir.display().to_string()), "{text}");
            assert!(!text.contains('\n'), "{text}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_write_keeps_the_result_in_a_named_fallback() {
        let dir = scratch("keep");
        let target = dir.join("plain").join("stats.json");
        std::fs::write(dir.join("plain"), b"").unwrap();
        let err = write_or_keep(&target, |p| std::fs::write(p, b"result")).unwrap_err();
        let text = format!("{err:#}");
        assert!(
            text.contains("stats.json") && text.contains("kept in"),
            "{text}"
        );
        let kept = fallback_paths(&target)
            .into_iter()
            .find(|p| p.exists())
            .expect("a fallback file was written");
        let absolute = std::path::absolute(&kept).unwrap();
        assert!(text.contains(&absolute.display().to_string()), "{text}");
        assert_eq!(std::fs::read(&kept).unwrap(), b"result");
        std::fs::remove_file(kept).unwrap();
        write_or_keep(&dir.join("ok.json"), |p| std::fs::write(p, b"1")).unwrap();
        assert_eq!(std::fs::read(dir.join("ok.json")).unwrap(), b"1");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn failures_are_collected() {
        let mut f = Failures::default();
        assert!(f.note(Ok(())));
        assert!(f.is_empty());
        assert!(!f.note(Err(anyhow!("one"))));
        assert!(!f.note(Err(anyhow!("two"))));
        let text = f.finish().unwrap_err().to_string();
        assert!(
            text.contains("2 outputs failed") && text.contains("two"),
            "{text}"
        );
    }
}
