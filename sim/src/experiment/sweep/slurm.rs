//! Running a sweep on a Slurm cluster: a job-array script whose task `k` runs shard `k/N` of
//! the sweep (written to a sweep file beside the script, so every task sees the same point
//! list), and a collect script, submitted to run after the array (`afterany`: also when tasks
//! failed or were cancelled; points without a result then show as `missing` in the table).
//! Submitting the same sweep again runs only what is not done yet.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context};

use super::spec::SweepSpec;

/// The file name of the collected table in the results folder.
pub const TABLE_FILE: &str = "table.csv";

/// The folder of the jobs' output files in the results folder.
pub const LOG_DIR: &str = "slurm";

/// A sweep as Slurm jobs.
#[derive(Debug, Clone)]
pub struct SlurmJob {
    /// The job-array script.
    pub script: PathBuf,
    /// The collect job's script (`<script stem>.collect.sh` beside it).
    pub collect_script: PathBuf,
    /// The sweep file the tasks read (`<script stem>.sweep.toml` beside it).
    pub spec_file: PathBuf,
    /// The results folder (absolute).
    pub results: PathBuf,
    /// Array tasks (shards).
    pub shards: usize,
    /// The vtq executable the jobs run (absolute).
    pub vtq: PathBuf,
    /// The folder the jobs run in (relative scene paths resolve there).
    pub workdir: PathBuf,
    /// Further `vtq sweep` options of the shard runs (the BVH cache, `--retry-failed`).
    pub vtq_args: Vec<String>,
    /// Extra `#SBATCH` options of both jobs (partition, time limit, account, ...).
    pub sbatch_args: Vec<String>,
}

/// `s` quoted for a POSIX shell.
fn sh_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// A path quoted for a POSIX shell.
fn sh_path(p: &Path) -> String {
    sh_quote(&p.display().to_string())
}

/// The job id in `sbatch --parsable` output (`ID` or `ID;CLUSTER`).
fn parse_job_id(stdout: &str) -> anyhow::Result<String> {
    let id = stdout.trim().split(';').next().unwrap_or("").trim();
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        bail!("sbatch printed `{}`, not a job id", stdout.trim());
    }
    Ok(id.to_string())
}

/// Runs `sbatch --parsable ARGS SCRIPT` and returns the job id.
fn sbatch(args: &[String], script: &Path) -> anyhow::Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .arg(script)
        .output()
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                anyhow::anyhow!(
                    "cannot run sbatch: not found on PATH (Slurm's client, Debian package \
                     `slurm-client`)"
                )
            } else {
                anyhow::anyhow!("cannot run sbatch: {e}")
            }
        })?;
    if !out.status.success() {
        bail!(
            "sbatch {} failed ({}): {}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    parse_job_id(&String::from_utf8_lossy(&out.stdout))
        .with_context(|| format!("submitting {}", script.display()))
}

impl SlurmJob {
    /// The collect script and sweep file that go beside `script`.
    pub fn companions(script: &Path) -> (PathBuf, PathBuf) {
        let stem = script
            .file_stem()
            .map_or_else(|| "sweep".into(), |s| s.to_string_lossy().into_owned());
        (
            script.with_file_name(format!("{stem}.collect.sh")),
            script.with_file_name(format!("{stem}.sweep.toml")),
        )
    }

    /// The folder of the jobs' output files.
    pub fn log_dir(&self) -> PathBuf {
        self.results.join(LOG_DIR)
    }

    /// The lines both scripts share after their job's name and array: one task on one CPU, the
    /// output file `log`, the extra `#SBATCH` options, then the shell's settings and the move to
    /// the working folder.
    fn common_lines(&self, log: &Path) -> String {
        let extra: String = self
            .sbatch_args
            .iter()
            .map(|a| format!("#SBATCH {a}\n"))
            .collect();
        format!(
            "#SBATCH --ntasks=1\n\
             #SBATCH --cpus-per-task=1\n\
             #SBATCH --output={log}\n\
             {extra}\
             set -euo pipefail\n\
             cd {workdir}\n",
            log = log.display(),
            workdir = sh_path(&self.workdir),
        )
    }

    /// The job-array script.
    pub fn array_script(&self) -> String {
        let n = self.shards;
        let log = self.log_dir().join("%A_%a.out");
        let mut cmd = vec![
            sh_path(&self.vtq),
            "sweep".into(),
            "--spec".into(),
            sh_path(&self.spec_file),
            "--results".into(),
            sh_path(&self.results),
            "--shard".into(),
            format!("\"${{SLURM_ARRAY_TASK_ID}}/{n}\""),
            "--jobs".into(),
            "1".into(),
        ];
        cmd.extend(self.vtq_args.iter().map(|a| sh_quote(a)));
        format!(
            "#!/bin/bash\n\
             # vtq sweep as a Slurm job array (written by `vtq sweep --slurm`): task k runs\n\
             # shard k/{n} of the sweep in {spec}, storing one result file per run in\n\
             # {runs}. Finished runs are skipped, so submitting again resumes.\n\
             # Submit it, then the table:\n\
             #   sbatch {script}\n\
             #   sbatch --dependency=afterany:<array job id> {collect}\n\
             #SBATCH --job-name=vtq-sweep\n\
             #SBATCH --array=0-{last}\n\
             {common}\
             exec {cmd}\n",
            spec = self.spec_file.display(),
            runs = self.results.join(super::store::RUNS_DIR).display(),
            script = sh_path(&self.script),
            collect = sh_path(&self.collect_script),
            last = n - 1,
            common = self.common_lines(&log),
            cmd = cmd.join(" "),
        )
    }

    /// The collect job's script: the table of the sweep's points, `missing` for points
    /// without a result.
    pub fn collect_script_text(&self) -> String {
        format!(
            "#!/bin/bash\n\
             # Collects the table of the vtq sweep in {spec} (written by `vtq sweep --slurm`);\n\
             # submitted to run after the job array of {script}.\n\
             #SBATCH --job-name=vtq-sweep-collect\n\
             {common}\
             exec {vtq} sweep --collect {results} --spec {spec_q} --out {table}\n",
            spec = self.spec_file.display(),
            script = self.script.display(),
            common = self.common_lines(&self.log_dir().join("collect_%j.out")),
            vtq = sh_path(&self.vtq),
            results = sh_path(&self.results),
            spec_q = sh_path(&self.spec_file),
            table = sh_path(&self.results.join(TABLE_FILE)),
        )
    }

    /// Writes the sweep file, both scripts (executable) and the log folder. `#SBATCH` lines
    /// cannot quote, so a results path with white space is an error.
    pub fn write(&self, spec: &SweepSpec) -> anyhow::Result<()> {
        if self.shards == 0 {
            bail!("a Slurm sweep needs at least one shard");
        }
        if self
            .log_dir()
            .display()
            .to_string()
            .contains(char::is_whitespace)
        {
            bail!(
                "the results folder {} contains white space, which #SBATCH --output cannot hold",
                self.results.display()
            );
        }
        std::fs::create_dir_all(self.log_dir())
            .with_context(|| format!("cannot create {}", self.log_dir().display()))?;
        let files = [
            (&self.spec_file, spec.to_toml()?),
            (&self.script, self.array_script()),
            (&self.collect_script, self.collect_script_text()),
        ];
        for (path, text) in files {
            crate::model::atomic_file::write_atomic(path, text.as_bytes())
                .map_err(anyhow::Error::msg)?;
        }
        #[cfg(unix)]
        for path in [&self.script, &self.collect_script] {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755))
                .with_context(|| format!("cannot make {} executable", path.display()))?;
        }
        Ok(())
    }

    /// Submits the array, then the collect job depending on it (`afterany`); returns both job
    /// ids.
    pub fn submit(&self) -> anyhow::Result<(String, String)> {
        let array = sbatch(&[], &self.script)?;
        let collect = sbatch(
            &[format!("--dependency=afterany:{array}")],
            &self.collect_script,
        )?;
        Ok((array, collect))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job() -> SlurmJob {
        let (collect_script, spec_file) = SlurmJob::companions(Path::new("/w/run/s.sh"));
        SlurmJob {
            script: "/w/run/s.sh".into(),
            collect_script,
            spec_file,
            results: "/w/res".into(),
            shards: 3,
            vtq: "/opt/it's/vtq".into(),
            workdir: "/w".into(),
            vtq_args: vec!["--no-cache".into()],
            sbatch_args: vec!["--partition=short".into()],
        }
    }

    #[test]
    fn scripts_run_the_shards_and_the_collect() {
        let j = job();
        assert_eq!(j.collect_script, Path::new("/w/run/s.collect.sh"));
        assert_eq!(j.spec_file, Path::new("/w/run/s.sweep.toml"));
        let a = j.array_script();
        assert!(a.starts_with("#!/bin/bash\n"), "{a}");
        assert!(a.contains("#SBATCH --array=0-2\n"), "{a}");
        assert!(a.contains("#SBATCH --partition=short\n"), "{a}");
        assert!(
            a.contains("#SBATCH --output=/w/res/slurm/%A_%a.out\n"),
            "{a}"
        );
        assert!(
            a.contains(
                "exec '/opt/it'\\''s/vtq' sweep --spec '/w/run/s.sweep.toml' --results \
                 '/w/res' --shard \"${SLURM_ARRAY_TASK_ID}/3\" --jobs 1 '--no-cache'\n"
            ),
            "{a}"
        );
        let c = j.collect_script_text();
        assert!(
            c.contains(
                "sweep --collect '/w/res' --spec '/w/run/s.sweep.toml' --out '/w/res/table.csv'"
            ),
            "{c}"
        );
        assert!(!c.contains("--array"), "{c}");
    }

    #[test]
    fn job_ids_are_parsed() {
        assert_eq!(parse_job_id("42\n").unwrap(), "42");
        assert_eq!(parse_job_id("42;cluster\n").unwrap(), "42");
        assert!(parse_job_id("Submitted batch job 42").is_err());
        assert!(parse_job_id("").is_err());
    }
}
