//! Running the external HDL tools (Icarus Verilog, Verilator, Yosys): a missing executable
//! becomes [`GenError::ToolMissing`], a failing run becomes [`GenError::ToolFailed`] with the
//! tool's output.

use crate::error::GenError;
use std::path::Path;
use std::process::{Command, Output};

/// Environment variable that, when set, makes a missing tool a test failure instead of a skip
/// (CI installs every tool).
pub const CI_ENV: &str = "CI";

/// Most characters of a failing tool's output kept in [`GenError::ToolFailed`].
const MAX_FAILURE_OUTPUT: usize = 8000;

/// The captured result of one tool run that exited successfully.
#[derive(Debug, Clone)]
pub struct ToolOutput {
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

/// Runs `tool args...` in `cwd` and returns its output; a non-zero exit is an error carrying
/// the output, unless `allow_failure` is set (linters exit non-zero when they warn).
pub fn run(
    tool: &str,
    args: &[&str],
    cwd: &Path,
    allow_failure: bool,
) -> Result<(ToolOutput, bool), GenError> {
    let output: Output = Command::new(tool)
        .args(args)
        .current_dir(cwd)
        .output()
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                GenError::ToolMissing {
                    tool: tool.to_string(),
                }
            } else {
                GenError::io(format!("starting `{tool}` in {}", cwd.display()), e)
            }
        })?;
    let out = ToolOutput {
        stdout: String::from_utf8_lossy(&output.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
    };
    let ok = output.status.success();
    if !ok && !allow_failure {
        return Err(GenError::ToolFailed {
            tool: tool.to_string(),
            status: output.status.to_string(),
            output: tail(&format!("{}{}", out.stdout, out.stderr), MAX_FAILURE_OUTPUT),
        });
    }
    Ok((out, ok))
}

/// The Debian package that provides the external tool `tool` (`iverilog` for Icarus Verilog's
/// `iverilog` and `vvp`; `gtkwave` for `vcd2fst`).
pub fn debian_package(tool: &str) -> &'static str {
    match tool {
        "verilator" | "./obj_dir/cosim" => "verilator",
        "yosys" => "yosys",
        "vcd2fst" | "gtkwave" => "gtkwave",
        "sbatch" | "srun" | "squeue" | "scancel" => "slurm-client",
        _ => "iverilog",
    }
}

/// Whether `tool` can be started (it answers `--version` or `-V`).
pub fn available(tool: &str) -> bool {
    ["--version", "-V"].iter().any(|flag| {
        Command::new(tool)
            .arg(flag)
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    })
}

/// For tests and optional checks: `Ok(Some(v))` on success; `Ok(None)` after printing
/// "skipping: TOOL not installed" when a tool is missing and the `CI` environment variable is
/// not set; the error otherwise (so under CI a missing tool fails).
pub fn or_skip<T>(result: Result<T, GenError>) -> Result<Option<T>, GenError> {
    match result {
        Ok(v) => Ok(Some(v)),
        Err(GenError::ToolMissing { tool }) if std::env::var_os(CI_ENV).is_none() => {
            eprintln!("skipping: {tool} not installed");
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// The last `max` characters of `s` (on a character boundary), marked when cut.
fn tail(s: &str, max: usize) -> String {
    if s.len() <= max {
        return s.to_string();
    }
    let mut start = s.len() - max;
    while !s.is_char_boundary(start) {
        start += 1;
    }
    format!("[... output cut ...]\n{}", &s[start..])
}

/// Writes `contents` to `path`, naming the file in the error.
pub(crate) fn write_file(path: &Path, contents: &str) -> Result<(), GenError> {
    std::fs::write(path, contents)
        .map_err(|e| GenError::io(format!("writing {}", path.display()), e))
}

/// Creates `dir` and its parents, naming the directory in the error.
pub(crate) fn create_dir(dir: &Path) -> Result<(), GenError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| GenError::io(format!("creating directory {}", dir.display()), e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_tool_is_reported_as_missing() {
        let err = run("vtq-no-such-tool-xyz", &[], Path::new("."), false).unwrap_err();
        assert!(err.is_tool_missing(), "{err}");
        assert!(!available("vtq-no-such-tool-xyz"));
    }

    #[test]
    fn missing_tool_skips_only_outside_ci() {
        let r = or_skip::<()>(Err(GenError::ToolMissing {
            tool: "x".to_string(),
        }));
        if std::env::var_os(CI_ENV).is_some() {
            assert!(r.unwrap_err().is_tool_missing());
        } else {
            assert!(matches!(r, Ok(None)));
        }
        let other = or_skip::<()>(Err(GenError::Parse {
            tool: "x".to_string(),
            reason: "y".to_string(),
        }));
        assert!(other.is_err());
        assert!(matches!(or_skip(Ok(3)), Ok(Some(3))));
    }

    #[test]
    fn tail_keeps_the_end() {
        assert_eq!(tail("abc", 5), "abc");
        let t = tail("0123456789", 4);
        assert!(t.ends_with("6789") && t.starts_with("[..."));
    }
}
