//! Reusing a synthesis whose inputs did not change: [`cached`] keys a Yosys run by the Yosys
//! version, the script, the top module and the text of every source file (BLAKE3), and keeps
//! the statistics and the seconds the run took in `<work dir>/synth-cache/<top>-<key>.json`.
//! A work directory kept between runs (`vtq area --synth --work-dir DIR`) then synthesizes only
//! the blocks whose RTL changed; a changed file, script or Yosys is a new key, never a stale
//! result.

use crate::error::GenError;
use crate::synth::SynthReport;
use crate::tools::run;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One synthesis, run now or reused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Synthesis {
    /// Yosys' statistics.
    pub report: SynthReport,
    /// Seconds Yosys took when it ran.
    pub seconds: f64,
    /// Whether this result was read from the cache instead of running Yosys.
    #[serde(skip)]
    pub reused: bool,
}

/// The cache key of synthesizing `files` with `script` and top `top` under `yosys_version`.
pub fn key(
    yosys_version: &str,
    script: &str,
    top: &str,
    files: &[PathBuf],
) -> Result<String, GenError> {
    let mut h = blake3::Hasher::new();
    for part in [yosys_version, script, top] {
        h.update(&(part.len() as u64).to_le_bytes());
        h.update(part.as_bytes());
    }
    for f in files {
        let text = std::fs::read(f)
            .map_err(|e| GenError::io(format!("reading Verilog source {}", f.display()), e))?;
        h.update(&(text.len() as u64).to_le_bytes());
        h.update(&text);
    }
    Ok(h.finalize().to_hex()[..16].to_string())
}

/// Yosys' version line (`yosys -V`).
pub fn yosys_version(work_dir: &Path) -> Result<String, GenError> {
    let (out, _) = run("yosys", &["-V"], work_dir, false)?;
    Ok(out.stdout.trim().to_string())
}

/// The synthesis of `files` with `script` (top `top`) in `work_dir`: read from the cache when
/// the same inputs were synthesized there before, else `synthesize()` timed and stored.
pub fn cached(
    work_dir: &Path,
    yosys: &str,
    script: &str,
    top: &str,
    files: &[PathBuf],
    synthesize: impl FnOnce() -> Result<SynthReport, GenError>,
) -> Result<Synthesis, GenError> {
    let dir = work_dir.join("synth-cache");
    let path = dir.join(format!("{top}-{}.json", key(yosys, script, top, files)?));
    if let Ok(text) = std::fs::read_to_string(&path) {
        // An unreadable entry (an older format, a torn write) is synthesized again.
        if let Ok(mut s) = serde_json::from_str::<Synthesis>(&text) {
            s.reused = true;
            return Ok(s);
        }
    }
    let start = Instant::now();
    let report = synthesize()?;
    let s = Synthesis {
        report,
        seconds: start.elapsed().as_secs_f64(),
        reused: false,
    };
    std::fs::create_dir_all(&dir)
        .map_err(|e| GenError::io(format!("creating {}", dir.display()), e))?;
    let json = serde_json::to_string_pretty(&s).expect("a synthesis serializes");
    // Written whole then renamed, so a killed run leaves no torn entry.
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, json)
        .and_then(|()| std::fs::rename(&tmp, &path))
        .map_err(|e| GenError::io(format!("writing {}", path.display()), e))?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn report(top: &str, cells: u64) -> SynthReport {
        SynthReport {
            top: top.to_string(),
            cells,
            cells_by_type: BTreeMap::from([("$_NAND_".to_string(), cells)]),
            flip_flops: 0,
            latches: 0,
            memory_bits: 0,
            memory_cells: 0,
            warnings: vec![],
            undriven: vec![],
        }
    }

    #[test]
    fn reuses_only_the_same_inputs() {
        let dir = std::env::temp_dir().join(format!("vtq-synth-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let src = dir.join("a.v");
        std::fs::write(&src, "module a; endmodule\n").unwrap();
        let files = [src.clone()];
        let runs = std::cell::Cell::new(0);
        let go = |yosys: &str, script: &str, cells: u64| {
            cached(&dir, yosys, script, "a", &files, || {
                runs.set(runs.get() + 1);
                Ok(report("a", cells))
            })
            .unwrap()
        };
        let first = go("Yosys 0.23", "synth", 7);
        assert!(!first.reused);
        let again = go("Yosys 0.23", "synth", 99);
        assert!(again.reused);
        assert_eq!(again.report, first.report);
        assert_eq!(again.seconds, first.seconds);
        // Another script or Yosys version is another key.
        assert!(!go("Yosys 0.23", "synth -flatten", 8).reused);
        assert!(!go("Yosys 0.40", "synth", 9).reused);
        // So is a changed source file.
        std::fs::write(&src, "module a; wire w; endmodule\n").unwrap();
        let changed = go("Yosys 0.23", "synth", 10);
        assert!(!changed.reused);
        assert_eq!(changed.report.cells, 10);
        assert_eq!(runs.get(), 4);
        // A torn entry is synthesized again, not an error.
        for e in std::fs::read_dir(dir.join("synth-cache")).unwrap() {
            std::fs::write(e.unwrap().path(), "{").unwrap();
        }
        assert!(!go("Yosys 0.23", "synth", 11).reused);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
