//! `vtq sweep --slurm --submit` against a real one-node Slurm cluster that the test starts on
//! localhost (Debian's `slurm-wlm` and `munge`): a generated munge key and `slurm.conf`,
//! `munged`, `slurmctld` and `slurmd` in the foreground as child processes, stopped when the
//! test ends however it ends. The sweep is submitted as a job array with a dependent collect
//! job; one array task is cancelled mid-way, the sweep is submitted again, and the collected
//! table must equal a local run's, the second array having skipped every finished run.
//!
//! Without the Slurm tools the test says "skipping: slurm-wlm not installed" and passes,
//! unless the `CI` environment variable is set: CI installs them (.ci/run), so there a
//! missing tool fails the test.

#![cfg(unix)]

mod common;

use std::io::Read;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use vtq_gen::tools::CI_ENV;

mod sweep_grid;
use sweep_grid::sweep_args;

/// The Slurm and munge programs the test runs.
const TOOLS: [&str; 8] = [
    "munged",
    "slurmctld",
    "slurmd",
    "sbatch",
    "squeue",
    "scancel",
    "sinfo",
    "scontrol",
];

/// How long the cluster may take to come up, and a job to finish.
const TIMEOUT: Duration = Duration::from_secs(60);

/// Job states after which a job does not change any more.
const FINAL_STATES: [&str; 9] = [
    "COMPLETED",
    "CANCELLED",
    "FAILED",
    "TIMEOUT",
    "NODE_FAIL",
    "PREEMPTED",
    "OUT_OF_MEMORY",
    "BOOT_FAIL",
    "DEADLINE",
];

/// The full path of `tool`: on PATH, or in the system folders daemons live in.
fn find_tool(tool: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/sbin", "/usr/bin", "/bin"].map(PathBuf::from))
        .map(|d| d.join(tool))
        .find(|p| p.is_file())
}

/// Whether the test can run: the tools are installed and we are root (slurmd needs it).
/// Otherwise it says why and skips, or fails under CI.
fn slurm_available() -> bool {
    let ci = std::env::var_os(CI_ENV).is_some();
    let missing: Vec<&str> = TOOLS
        .iter()
        .copied()
        .filter(|t| find_tool(t).is_none())
        .collect();
    if !missing.is_empty() {
        assert!(
            !ci,
            "CI is set but slurm-wlm/munge are not installed (missing {}): .ci/run installs them",
            missing.join(", ")
        );
        eprintln!(
            "skipping: slurm-wlm not installed (missing {})",
            missing.join(", ")
        );
        return false;
    }
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        assert!(!ci, "CI is set but the Slurm test is not running as root");
        eprintln!("skipping: the Slurm test starts slurmd, which needs root");
        return false;
    }
    true
}

/// A port nobody listens on now.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free local port")
        .port()
}

/// The last lines of a log file, for failure messages.
fn tail(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    format!(
        "--- {} ---\n{}",
        path.display(),
        lines[lines.len().saturating_sub(15)..].join("\n")
    )
}

/// A one-node Slurm cluster of child processes, stopped on drop.
struct Cluster {
    /// Its folder (configuration, keys, state, logs).
    dir: PathBuf,
    /// Its slurm.conf.
    conf: PathBuf,
    /// munged, slurmctld, slurmd (started in this order).
    daemons: Vec<(&'static str, Child)>,
}

impl Cluster {
    /// Starts munged, slurmctld and slurmd in `dir` and waits until the node is idle.
    fn start(dir: &Path) -> Cluster {
        let _ = std::fs::remove_dir_all(dir);
        for sub in ["munge", "state", "spool", "log"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        let tool = |t: &str| find_tool(t).unwrap();
        let mut cluster = Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
            daemons: Vec::new(),
        };

        // munge: a fresh 1024-byte key, readable by its owner only, and a private socket.
        use std::os::unix::fs::PermissionsExt;
        let munge = dir.join("munge");
        std::fs::set_permissions(&munge, std::fs::Permissions::from_mode(0o700)).unwrap();
        let mut key = vec![0u8; 1024];
        std::fs::File::open("/dev/urandom")
            .and_then(|mut f| f.read_exact(&mut key))
            .unwrap();
        let key_file = munge.join("munge.key");
        std::fs::write(&key_file, &key).unwrap();
        std::fs::set_permissions(&key_file, std::fs::Permissions::from_mode(0o400)).unwrap();
        let socket = munge.join("munge.socket");
        let mut munged = Command::new(tool("munged"));
        munged.args([
            "--foreground".into(),
            "--force".into(),
            format!("--socket={}", socket.display()),
            format!("--key-file={}", key_file.display()),
            format!("--log-file={}", dir.join("log/munged.log").display()),
            format!("--pid-file={}", munge.join("munged.pid").display()),
            format!("--seed-file={}", munge.join("munged.seed").display()),
        ]);
        cluster.spawn("munged", munged);
        cluster.wait_for("the munge socket", |_| socket.exists());

        // slurm.conf: this host as the one node, with the CPUs and memory slurmd finds.
        let probe = Command::new(tool("slurmd")).arg("-C").output().unwrap();
        let node_line = String::from_utf8_lossy(&probe.stdout)
            .lines()
            .next()
            .unwrap_or_default()
            .to_string();
        let node = node_line
            .split_whitespace()
            .find_map(|w| w.strip_prefix("NodeName="))
            .unwrap_or_else(|| panic!("slurmd -C printed no NodeName: {node_line}"))
            .to_string();
        let d = dir.display();
        let conf = format!(
            "ClusterName=vtqtest\n\
             SlurmctldHost={node}(127.0.0.1)\n\
             SlurmctldPort={ctld_port}\n\
             SlurmdPort={slurmd_port}\n\
             SlurmUser=root\n\
             SlurmdUser=root\n\
             AuthType=auth/munge\n\
             CredType=cred/munge\n\
             AuthInfo=socket={socket}\n\
             ProctrackType=proctrack/linuxproc\n\
             TaskPlugin=task/none\n\
             JobAcctGatherType=jobacct_gather/none\n\
             AccountingStorageType=accounting_storage/none\n\
             SchedulerType=sched/builtin\n\
             SchedulerParameters=sched_interval=1\n\
             SelectType=select/cons_tres\n\
             SelectTypeParameters=CR_CPU\n\
             ReturnToService=2\n\
             MpiDefault=none\n\
             StateSaveLocation={d}/state\n\
             SlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\n\
             SlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/log/slurmctld.log\n\
             SlurmdLogFile={d}/log/slurmd.log\n\
             {node_line} NodeAddr=127.0.0.1 State=UNKNOWN\n\
             PartitionName=test Nodes={node} Default=YES MaxTime=INFINITE State=UP\n",
            ctld_port = free_port(),
            slurmd_port = free_port(),
            socket = socket.display(),
        );
        std::fs::write(&cluster.conf, conf).unwrap();
        let mut ctld = Command::new(tool("slurmctld"));
        ctld.args(["-D", "-i"]);
        cluster.spawn("slurmctld", ctld);
        let mut slurmd = Command::new(tool("slurmd"));
        slurmd.args(["-D", "-N", &node]);
        cluster.spawn("slurmd", slurmd);
        cluster.wait_for("the node to be idle", |c| {
            let out = c.client("sinfo", &["-h", "-N", "-o", "%t"]);
            String::from_utf8_lossy(&out.stdout).trim() == "idle"
        });
        cluster
    }

    /// Starts a daemon with this cluster's configuration, its output in `log/<name>.out`.
    fn spawn(&mut self, name: &'static str, mut cmd: Command) {
        let log = std::fs::File::create(self.dir.join(format!("log/{name}.out"))).unwrap();
        let child = cmd
            .env("SLURM_CONF", &self.conf)
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name}: {e}"));
        self.daemons.push((name, child));
    }

    /// Every daemon's log tail.
    fn logs(&self) -> String {
        [
            "munged.out",
            "munged.log",
            "slurmctld.out",
            "slurmctld.log",
            "slurmd.out",
            "slurmd.log",
        ]
        .iter()
        .map(|f| tail(&self.dir.join("log").join(f)))
        .collect::<Vec<_>>()
        .join("\n")
    }

    /// Waits until `ready` holds, failing with the daemons' logs after [`TIMEOUT`] or when a
    /// daemon has exited.
    fn wait_for(&mut self, what: &str, mut ready: impl FnMut(&Cluster) -> bool) {
        let start = Instant::now();
        while !ready(self) {
            let exited = self
                .daemons
                .iter_mut()
                .find_map(|(name, child)| Some((*name, child.try_wait().ok()??)));
            if let Some((name, status)) = exited {
                panic!(
                    "{name} exited ({status}) while waiting for {what}\n{}",
                    self.logs()
                );
            }
            assert!(
                start.elapsed() < TIMEOUT,
                "timed out waiting for {what}\n{}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Runs a Slurm client command against this cluster.
    fn client(&self, tool: &str, args: &[&str]) -> Output {
        Command::new(find_tool(tool).unwrap())
            .args(args)
            .env("SLURM_CONF", &self.conf)
            .output()
            .unwrap()
    }

    /// (job, state) of every job or array task of `jobs`, finished ones included.
    fn states(&self, jobs: &[&str]) -> Vec<(String, String)> {
        let list = jobs.join(",");
        let out = self.client("squeue", &["-h", "-t", "all", "-j", &list, "-o", "%i %T"]);
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| l.split_once(' '))
            .map(|(j, s)| (j.to_string(), s.trim().to_string()))
            .collect()
    }

    /// Waits until every job and task of `jobs` is in a final state; returns the states.
    fn wait_finished(&mut self, jobs: &[&str]) -> Vec<(String, String)> {
        let mut last = Vec::new();
        self.wait_for(&format!("jobs {jobs:?} to finish"), |c| {
            last = c.states(jobs);
            !last.is_empty() && last.iter().all(|(_, s)| FINAL_STATES.contains(&s.as_str()))
        });
        last
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Cancel whatever still runs, then stop the daemons, newest first: SIGTERM, then
        // SIGKILL for one that has not exited after a few seconds.
        let out = self.client("squeue", &["-h", "-o", "%A"]);
        let jobs: Vec<String> = String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .map(String::from)
            .collect();
        if !jobs.is_empty() {
            let ids: Vec<&str> = jobs.iter().map(String::as_str).collect();
            let _ = self.client("scancel", &ids);
        }
        while let Some((_, mut child)) = self.daemons.pop() {
            // SAFETY: the pid is our own child's, not yet waited for.
            unsafe {
                libc::kill(child.id() as libc::pid_t, libc::SIGTERM);
            }
            let start = Instant::now();
            while matches!(child.try_wait(), Ok(None)) && start.elapsed() < Duration::from_secs(5) {
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A fresh temporary folder for the test.
fn temp_dir() -> PathBuf {
    common::fresh_dir("sweep-slurm")
}

/// Runs `vtq args` in `dir` with the cluster's configuration and checks it succeeded.
fn vtq_ok(dir: &Path, cluster: &Cluster, args: &[String]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(args)
        .current_dir(dir)
        .env("SLURM_CONF", &cluster.conf)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "vtq {args:?}\nstdout:\n{stdout}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The array and collect job ids of a `vtq sweep --submit` output.
fn submitted(stdout: &str) -> (String, String) {
    let line = stdout
        .lines()
        .find(|l| l.contains("submitted job array"))
        .unwrap_or_else(|| panic!("no submission line in:\n{stdout}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    // "sweep: submitted job array ID (N tasks) and collect job ID (runs after it); ..."
    let after = |a: &str, b: &str| {
        let i = words.windows(2).position(|w| w == [a, b]).unwrap();
        words[i + 2].to_string()
    };
    (after("job", "array"), after("collect", "job"))
}

/// Result files in `results/runs`.
fn result_count(results: &Path) -> usize {
    std::fs::read_dir(results.join("runs")).map_or(0, |entries| {
        entries
            .filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "json"))
            })
            .count()
    })
}

#[test]
fn a_sweep_runs_as_a_slurm_job_array_and_resumes_after_a_cancelled_task() {
    if !slurm_available() {
        return;
    }
    let start = Instant::now();
    let dir = temp_dir();
    let mut cluster = Cluster::start(&dir.join("cluster"));
    let up = start.elapsed();

    // The reference: the same sweep run locally.
    vtq_ok(&dir, &cluster, &sweep_args(&dir, "local", &["--jobs", "2"]));
    vtq_ok(
        &dir,
        &cluster,
        &["sweep", "--collect", "local", "--out", "local.csv"].map(String::from),
    );
    let expected = std::fs::read_to_string(dir.join("local.csv")).unwrap();
    assert_eq!(expected.lines().count(), 13);

    // Round 1: two array tasks of 6 points; task 1 is cancelled once it has finished a run.
    let slurm = ["--slurm", "job.sh", "--shards", "2", "--submit"];
    let round1_start = Instant::now();
    let (array, collect) = submitted(&vtq_ok(&dir, &cluster, &sweep_args(&dir, "res", &slurm)));
    let script = std::fs::read_to_string(dir.join("job.sh")).unwrap();
    assert!(script.contains("#SBATCH --array=0-1\n"), "{script}");
    let task_log = dir.join(format!("res/slurm/{array}_1.out"));
    cluster.wait_for("array task 1 to finish a run", |_| {
        std::fs::read_to_string(&task_log).is_ok_and(|t| t.contains("sweep: [1/"))
    });
    let task1 = format!("{array}_1");
    let out = cluster.client("scancel", &[&task1]);
    assert!(out.status.success(), "scancel: {out:?}");
    let states = cluster.wait_finished(&[&array, &collect]);
    let round1 = round1_start.elapsed();
    let state = |job: &str| {
        states
            .iter()
            .find(|(j, _)| j == job)
            .map(|(_, s)| s.clone())
            .unwrap_or_else(|| panic!("no job {job} in {states:?}"))
    };
    assert_eq!(state(&task1), "CANCELLED", "{states:?}");
    assert_eq!(state(&format!("{array}_0")), "COMPLETED", "{states:?}");
    assert_eq!(state(&collect), "COMPLETED", "{states:?}");
    let table1 = std::fs::read_to_string(dir.join("res/table.csv")).unwrap();
    let missing = table1.matches(",missing,").count();
    let done = result_count(&dir.join("res"));
    assert!(
        missing > 0 && done + missing == 12 && done >= 7,
        "task 1 was cancelled mid-way: {done} results, {missing} missing\n{table1}"
    );
    assert!(!table1.contains(",failed,"), "{table1}");

    // Round 2: the same submission again runs only the missing points.
    let round2_start = Instant::now();
    let (array2, collect2) = submitted(&vtq_ok(&dir, &cluster, &sweep_args(&dir, "res", &slurm)));
    let states = cluster.wait_finished(&[&array2, &collect2]);
    let round2 = round2_start.elapsed();
    assert!(
        states.iter().all(|(_, s)| s == "COMPLETED"),
        "{states:?}\n{}",
        cluster.logs()
    );
    let skipped: usize = (0..2)
        .map(|k| {
            let log =
                std::fs::read_to_string(dir.join(format!("res/slurm/{array2}_{k}.out"))).unwrap();
            let line = log.lines().find(|l| l.contains("sweep: ran")).unwrap();
            let rest = &line[line.find("skipped ").unwrap() + 8..];
            rest.split_whitespace()
                .next()
                .unwrap()
                .parse::<usize>()
                .unwrap()
        })
        .sum();
    assert_eq!(skipped, done, "the second array skipped every finished run");
    assert_eq!(result_count(&dir.join("res")), 12);
    let table2 = std::fs::read_to_string(dir.join("res/table.csv")).unwrap();
    assert_eq!(table2, expected, "the Slurm table equals the local one");
    eprintln!(
        "slurm: cluster up in {:.1} s; round 1 (task 1 cancelled after a run, {done} of 12 \
         done) {:.1} s; round 2 (skipped {skipped}) {:.1} s; total {:.1} s",
        up.as_secs_f64(),
        round1.as_secs_f64(),
        round2.as_secs_f64(),
        start.elapsed().as_secs_f64()
    );
    drop(cluster);
    let _ = std::fs::remove_dir_all(&dir);
}
