//! Writing a file atomically: the bytes go to a unique temporary file beside the target, which
//! is then renamed over it, so a reader (or a run killed mid-write) never sees a partial file.
//! Used by the BVH cache, the sweep result store and waveforms (`vtq sim --vcd`).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The marker in temporary file names: `<target file name>.tmp.<pid>.<counter>`.
pub const TEMP_MARKER: &str = ".tmp.";

/// A temporary path beside `path`, unique to this process and call (for a file written in a
/// stream and renamed to `path` when complete).
pub fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(
        "{TEMP_MARKER}{}.{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    path.with_file_name(name)
}

/// Writes `bytes` to `path` through a temporary file in the same folder (created if missing)
/// and a rename. On failure the temporary file is removed; the message names the file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    let tmp = temp_path(path);
    let result = std::fs::write(&tmp, bytes)
        .map_err(|e| format!("cannot write {}: {e}", tmp.display()))
        .and_then(|()| {
            std::fs::rename(&tmp, path)
                .map_err(|e| format!("cannot rename to {}: {e}", path.display()))
        });
    if result.is_err() {
        // Best effort: the temporary file may not exist.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_replaces_and_leaves_no_temporary_file() {
        let dir = std::env::temp_dir().join(format!("vtq-atomic-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("sub").join("a.json");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.json")]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_write_names_the_file() {
        let dir = std::env::temp_dir().join(format!("vtq-atomic-f-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("target.json")).unwrap();
        // Renaming a file over a non-empty directory fails.
        std::fs::write(dir.join("target.json").join("x"), b"").unwrap();
        let err = write_atomic(&dir.join("target.json"), b"x").unwrap_err();
        assert!(err.contains("target.json"), "{err}");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1, "the temporary file was removed");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
