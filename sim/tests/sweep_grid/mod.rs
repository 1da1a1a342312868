//! The sweep the sweep tests share: 12 points (2 scenes x 2 repack thresholds x 3 SM counts,
//! VTQ, 32x32), run locally, killed and resumed (cli_sweep.rs) and on Slurm (sweep_slurm.rs),
//! whose collected tables must agree.

use std::path::Path;

/// `vtq sweep` of the 12 points into `results` (BVH cache under `dir`), with `extra` options.
pub fn sweep_args(dir: &Path, results: &str, extra: &[&str]) -> Vec<String> {
    let vtq_toml = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/designs/vtq/config.toml");
    let mut args: Vec<String> = [
        "sweep",
        "--scene",
        "wknd",
        "--scene",
        "cornell",
        "--config",
        vtq_toml.to_str().unwrap(),
        "--grid",
        "hw.repack_threshold=16,28",
        "--grid",
        "gpu.sms=2,4,8",
        "--set",
        "width=32",
        "--set",
        "height=32",
        "--results",
        results,
        "--cache-dir",
        dir.join("bvh-cache").to_str().unwrap(),
    ]
    .map(String::from)
    .to_vec();
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}
