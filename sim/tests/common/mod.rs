//! Helpers shared by the simulator's end-to-end tests (`sim_baseline.rs`, `sim_prefetch.rs`):
//! a small GPU configuration, running a simulation, and the checks every design must pass —
//! closest hits and the image equal the functional tracer's, and skipping idle cycles equals
//! stepping every cycle; small meshes made in code ([`meshes`]). The cross-crate tests
//! (`tests/tests/replay_rtl.rs`) include this module too.

// Each test binary compiles this module on its own and uses only part of it.
#![allow(dead_code)]

pub mod meshes;

use vtq_sim::model::bvh::HwBvh;
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::geometry::Hit;
use vtq_sim::model::gpu::stats::comparable_json;
use vtq_sim::model::gpu::{simulate, SimOptions, SimOutput};
use vtq_sim::model::scene::load::load_scene;
use vtq_sim::model::scene::Scene;
use vtq_sim::model::traversal::{trace, Order};
use vtq_sim::model::workload::pathtracer::render;

/// A small GPU in `mode` (`baseline` or `prefetch`): `sms` SMs, a `side` x `side` image, 4 KB
/// L1s, 16 KB L2, 2 KB treelets cut breadth-first (one slot each: the small scenes' packed
/// treelets would fit in a few slots and leave the treelet hardware nothing to do), then the
/// `extra` overrides.
pub fn small_config(mode: &str, sms: u32, side: u32, extra: &[&str]) -> SimConfig {
    let mut sets: Vec<String> = [
        format!("mode.kind={mode}"),
        format!("gpu.sms={sms}"),
        format!("width={side}"),
        format!("height={side}"),
        "memory.l1_bytes=4096".into(),
        "memory.l2_bytes=16384".into(),
        "hw.treelet_bytes=2048".into(),
        "bvh.treelet_formation=breadth_first".into(),
        "sim.sample_interval=500".into(),
    ]
    .into();
    sets.extend(extra.iter().map(|s| s.to_string()));
    SimConfig::load(None, &sets).expect("valid test configuration")
}

/// The full design (ray virtualization, grouping, preloading, repacking below 22) on a small GPU
/// (`small_config`), with thresholds low enough that small images reach the treelet phase, then
/// the `extra` overrides.
pub fn small_vtq(sms: u32, side: u32, extra: &[&str]) -> SimConfig {
    let mut sets = vec![
        "mode.virtualization=true",
        "mode.grouping=true",
        "mode.preload=true",
        "hw.repack_threshold=22",
        "hw.divergence_threshold=2",
        "hw.underpopulation_threshold=8",
    ];
    sets.extend_from_slice(extra);
    small_config("queues", sms, side, &sets)
}

/// A built-in scene and its BVH for `cfg`.
pub fn setup(name: &str, cfg: &SimConfig) -> (Scene, HwBvh) {
    let scene = load_scene(name).expect("built-in scene");
    let bvh = HwBvh::build(&scene, &cfg.bvh_params()).expect("BVH builds");
    (scene, bvh)
}

/// A simulation that records every ray and its hit.
pub fn run(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> SimOutput {
    run_threads(scene, bvh, cfg, 1)
}

/// [`run`] on `threads` threads.
pub fn run_threads(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig, threads: usize) -> SimOutput {
    simulate(
        scene,
        bvh,
        cfg,
        SimOptions {
            record_rays: true,
            threads,
            ..SimOptions::default()
        },
        None,
    )
    .expect("simulation runs")
}

/// Thread counts every design is checked with: one, the machine's two cores, an odd count and
/// more threads than SMs.
pub const THREAD_COUNTS: [usize; 4] = [1, 2, 3, 16];

/// A hit as bits, so comparisons are exact (and NaN-proof).
pub fn hit_bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
}

/// An image as bits, so comparisons are exact.
pub fn image_bits(img: &[glam::Vec3]) -> Vec<[u32; 3]> {
    img.iter().map(|c| c.to_array().map(f32::to_bits)).collect()
}

/// Simulates scene `name` with `cfg` and checks it against the functional renderer: every
/// ray's closest hit equals `traversal::trace`'s, every pixel traced the renderer's rays in the
/// same order, rays issued = completed, and the image is bit-identical. Returns the output
/// for the design's own checks.
pub fn check_against_functional(name: &str, cfg: &SimConfig) -> SimOutput {
    let (scene, bvh) = setup(name, cfg);
    check_scene_against_functional(&scene, &bvh, cfg)
}

/// [`check_against_functional`] for a scene built in the test, with its BVH.
pub fn check_scene_against_functional(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> SimOutput {
    let name = &scene.name;
    let out = run(scene, bvh, cfg);
    let reference = render(scene, bvh, &cfg.render_settings(), None).unwrap();

    assert_eq!(out.ray_log.len(), reference.rays.len(), "{name}: ray count");
    assert_eq!(out.stats.rays, reference.rays.len() as u64);
    assert_eq!(out.stats.rays_issued, out.stats.rays_completed);
    let mut per_pixel: Vec<Vec<_>> = vec![Vec::new(); reference.image.len()];
    for r in &out.ray_log {
        let closest = trace(bvh, &r.ray, Order::RayStationary);
        if r.occlusion {
            // Whether it hits is the answer; the hit it reports lies in the ray's interval.
            assert_eq!(
                r.hit.is_some(),
                closest.is_some(),
                "{name}: occlusion {:?}",
                r.ray
            );
            assert!(r.hit.is_none_or(|h| h.t >= r.ray.tmin && h.t <= r.ray.tmax));
        } else {
            assert_eq!(
                hit_bits(r.hit),
                hit_bits(closest),
                "{name}: closest hit of {:?}",
                r.ray
            );
        }
        per_pixel[r.pixel as usize].push(r.ray);
    }
    for (p, rays) in per_pixel.iter().enumerate() {
        assert_eq!(
            rays.as_slice(),
            reference.pixel_rays(p),
            "{name}: rays of pixel {p}"
        );
    }
    assert_eq!(
        image_bits(&out.image),
        image_bits(&reference.image),
        "{name}: image"
    );
    out
}

/// Runs the cornell box twice with `cfg` on one thread, then on each of [`THREAD_COUNTS`], and
/// checks every run gives identical statistics (but for host-dependent keys), time series, ray
/// logs and images. Returns the first run.
pub fn check_deterministic(cfg: &SimConfig) -> SimOutput {
    let (scene, bvh) = setup("cornell", cfg);
    let a = run(&scene, &bvh, cfg);
    for threads in [1].into_iter().chain(THREAD_COUNTS) {
        let b = run_threads(&scene, &bvh, cfg, threads);
        check_identical(&a, &b, &format!("{threads} thread(s)"));
    }
    a
}

/// Checks two runs gave identical statistics (but for host-dependent keys), time series, ray
/// logs and images.
pub fn check_identical(a: &SimOutput, b: &SimOutput, what: &str) {
    assert_eq!(
        comparable_json(&a.stats),
        comparable_json(&b.stats),
        "statistics, {what}"
    );
    assert_eq!(a.time_series, b.time_series, "time series, {what}");
    assert!(a.ray_log == b.ray_log, "ray log, {what}");
    assert_eq!(image_bits(&a.image), image_bits(&b.image), "image, {what}");
}

/// Checks that two runs of one workload on different designs (or timing settings) traced the
/// same rays with the same hits, in whatever order, and rendered the same image.
pub fn check_same_results(a: &SimOutput, b: &SimOutput) {
    assert_eq!(a.stats.rays, b.stats.rays);
    assert_eq!(a.stats.rays_hit, b.stats.rays_hit);
    assert_eq!(image_bits(&a.image), image_bits(&b.image));
    let sorted = |o: &SimOutput| {
        let mut v: Vec<_> = o
            .ray_log
            .iter()
            .map(|r| (r.pixel, hit_bits(r.hit)))
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(sorted(a), sorted(b));
}

/// Memory so slow (one MSHR, one DRAM byte per cycle) that the RT unit waits longer than a
/// watchdog of 8 cycles allows.
pub const STARVED_MEMORY: [&str; 6] = [
    "memory.l1_latency=1",
    "memory.l2_latency=1",
    "memory.dram_latency=1",
    "memory.dram_bytes_per_cycle=1",
    "memory.l1_mshrs=1",
    "sim.watchdog_cycles=8",
];

/// Statistics without host-dependent keys and the configuration text (which names lockstep).
pub fn strip(o: &SimOutput) -> serde_json::Value {
    let mut v = comparable_json(&o.stats);
    v.as_object_mut().unwrap().remove("config");
    v
}

/// Simulates wknd with `cfg` skipping idle cycles and in lockstep, and checks both give the same
/// statistics and time series and that the skipping run really skipped cycles. Returns
/// (skipping run, lockstep run).
pub fn check_skip_matches_lockstep(cfg: &SimConfig) -> (SimOutput, SimOutput) {
    let (scene, bvh) = setup("wknd", cfg);
    check_scene_skip_matches_lockstep(&scene, &bvh, cfg)
}

/// [`check_skip_matches_lockstep`] for a scene built in the test, with its BVH.
pub fn check_scene_skip_matches_lockstep(
    scene: &Scene,
    bvh: &HwBvh,
    cfg: &SimConfig,
) -> (SimOutput, SimOutput) {
    let skip = run(scene, bvh, cfg);
    let mut lock_cfg = cfg.clone();
    lock_cfg.sim.lockstep = true;
    let lock = run(scene, bvh, &lock_cfg);
    assert_eq!(strip(&skip), strip(&lock));
    assert_eq!(skip.time_series, lock.time_series);
    assert!(!skip.time_series.is_empty());
    assert!(
        lock.stats.sm_visits >= lock.stats.cycles,
        "lockstep visits every cycle"
    );
    assert!(
        skip.stats.sm_visits < lock.stats.sm_visits,
        "idle cycles were skipped"
    );
    (skip, lock)
}

/// A sampled tier's estimates without host-dependent times (profile and simulation seconds,
/// the replicates' wall-clock statistics), for comparing runs.
pub fn comparable_sampled(s: &vtq_sim::estimate::sample::SampledStats) -> serde_json::Value {
    let mut v = serde_json::to_value(s).unwrap();
    let o = v.as_object_mut().unwrap();
    o.remove("profile_seconds");
    o.remove("sim_seconds");
    for r in o["replicate_runs"].as_array_mut().unwrap() {
        let stats = r["stats"].as_object_mut().unwrap();
        for k in vtq_sim::model::gpu::HOST_DEPENDENT_KEYS {
            stats.remove(k);
        }
    }
    v
}

/// The `vtq` binary as a command with `args`, to run in `dir`.
// Not `env!`: the cross-crate tests (tests/tests/replay_rtl.rs) include this module, and Cargo
// builds the binary for vtq-sim's own tests only.
#[allow(clippy::option_env_unwrap)]
fn vtq_command(dir: &std::path::Path, args: &[&str]) -> std::process::Command {
    let mut cmd = std::process::Command::new(
        option_env!("CARGO_BIN_EXE_vtq").expect("the vtq binary: a test of vtq-sim"),
    );
    cmd.current_dir(dir).args(args);
    cmd
}

/// Runs `cmd` (a `vtq` command); returns (success, stdout, stderr).
fn run_vtq(mut cmd: std::process::Command) -> (bool, String, String) {
    let out = cmd.output().expect("the vtq binary runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs the `vtq` binary with `args` in `dir`; returns (success, stdout, stderr).
pub fn vtq_cli(dir: &std::path::Path, args: &[&str]) -> (bool, String, String) {
    run_vtq(vtq_command(dir, args))
}

/// [`vtq_cli`] with fontconfig pointed at an empty configuration written into `dir` (no
/// fonts: the text of vtq's charts must come from the font embedded in vtq).
pub fn vtq_cli_without_fonts(dir: &std::path::Path, args: &[&str]) -> (bool, String, String) {
    let fonts_conf = dir.join("empty-fonts.conf");
    std::fs::write(&fonts_conf, "<?xml version=\"1.0\"?>\n<fontconfig/>\n").unwrap();
    let mut cmd = vtq_command(dir, args);
    cmd.env("FONTCONFIG_FILE", &fonts_conf)
        .env("FONTCONFIG_PATH", dir);
    run_vtq(cmd)
}

/// The stdout of `run`, a [`vtq_cli`] result of `args` that must have succeeded (the failure
/// shows both outputs).
pub fn ok_stdout(args: &[&str], run: (bool, String, String)) -> String {
    let (ok, stdout, stderr) = run;
    assert!(ok, "vtq {args:?}: {stdout}\n{stderr}");
    stdout
}

/// Runs `vtq args` in `dir`, which must succeed; returns its stdout.
pub fn vtq_ok_in(dir: &std::path::Path, args: &[&str]) -> String {
    ok_stdout(args, vtq_cli(dir, args))
}

/// A fresh, empty folder `vtq-<name>-<process id>` in the system's temporary folder, for one
/// test's files.
pub fn fresh_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("vtq-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a fresh temporary folder");
    dir
}

/// Pixels darker than mid grey in rows `rows` of the PNG at `path`: whether a chart drew its
/// text there.
pub fn dark_pixels(path: &std::path::Path, rows: std::ops::Range<usize>) -> usize {
    let file = std::fs::File::open(path).unwrap();
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let (channels, width) = (info.color_type.samples(), info.width as usize);
    rows.flat_map(|y| (0..width).map(move |x| (y * width + x) * channels))
        .filter(|&i| buf[i..i + 3].iter().map(|&c| u32::from(c)).sum::<u32>() < 3 * 128)
        .count()
}

/// A 16x16 frame of cornell, as `vtq` options: a tiny workload for commands that run the
/// simulator.
pub const TINY_CORNELL: [&str; 6] = [
    "--scene",
    "cornell",
    "--set",
    "width=16",
    "--set",
    "height=16",
];

/// A 16x16 frame on 4 SMs without the BVH cache, as `vtq` options: the small runs of the
/// sampled tier's commands.
pub const SMALL_SAMPLED: [&str; 7] = [
    "--set",
    "width=16",
    "--set",
    "height=16",
    "--set",
    "gpu.sms=4",
    "--no-cache",
];

/// The arguments of `vtq accuracy` on `scene` for `designs` (all when `None`) with one sampled
/// setting (1/2x2) on two threads, on [`SMALL_SAMPLED`]'s frame, writing into `out`.
pub fn small_accuracy_args<'a>(
    scene: &'a str,
    designs: Option<&'a str>,
    out: &'a str,
) -> Vec<&'a str> {
    let mut args = vec!["accuracy", "--scene", scene];
    if let Some(designs) = designs {
        args.extend(["--designs", designs]);
    }
    args.extend(["--settings", "1/2x2", "--threads", "2"]);
    args.extend(SMALL_SAMPLED);
    args.extend(["--out", out]);
    args
}
