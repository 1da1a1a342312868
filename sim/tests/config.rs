//! Tests of the simulator configuration: the paper's defaults, the shipped configs, `--set`
//! overrides, error messages that name the key, and the to_toml round trip.

use std::path::{Path, PathBuf};

use vtq_sim::model::config::{ConfigError, ModeKind, SimConfig, TreeletPrefetch};

/// The workspace's design folders, `configs/designs/`.
fn designs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("configs/designs")
}

/// One shipped design's configuration file, `NAME.toml` naming design NAME.
fn shipped(name: &str) -> PathBuf {
    designs_dir()
        .join(name.trim_end_matches(".toml"))
        .join("config.toml")
}

/// A fresh temporary file holding `text`.
fn temp_file(test: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vtq-config-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("config.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn sets(overrides: &[&str]) -> Vec<String> {
    overrides.iter().map(|s| s.to_string()).collect()
}

/// Loads with overrides only (on the defaults).
fn load_set(overrides: &[&str]) -> Result<SimConfig, ConfigError> {
    SimConfig::load(None, &sets(overrides))
}

/// Loads a shipped config with overrides.
fn load_shipped(name: &str, overrides: &[&str]) -> Result<SimConfig, ConfigError> {
    SimConfig::load(Some(&shipped(name)), &sets(overrides))
}

/// Asserts `result` is an error about `key` whose message names the key.
fn assert_key_error(result: Result<SimConfig, ConfigError>, key: &str) -> ConfigError {
    let e = result.expect_err(&format!("expected an error about {key}"));
    assert_eq!(e.key(), Some(key), "wrong key in: {e}");
    assert!(
        e.to_string().contains(key),
        "message should name {key}: {e}"
    );
    e
}

#[test]
fn defaults_are_the_papers_table_1_baseline() {
    let c = SimConfig::default();
    c.validate().unwrap();
    // Table 1.
    assert_eq!(c.gpu.sms, 16);
    assert_eq!(c.gpu.max_warps_per_sm, 32);
    assert_eq!(c.gpu.warp_size, 32);
    assert_eq!(c.gpu.max_ctas_per_sm, 16);
    assert_eq!(c.gpu.registers_per_sm, 32768);
    assert_eq!((c.memory.l1_bytes, c.memory.l1_ways), (16 * 1024, 0)); // fully associative
    assert_eq!(c.memory.l1_latency, 39);
    assert_eq!((c.memory.l2_bytes, c.memory.l2_ways), (128 * 1024, 16));
    assert_eq!(c.memory.l2_latency, 187);
    assert_eq!(c.hw.warp_buffer_size, 1);
    // Vulkan-Sim: DRAM latency (RTX 3070 config), intersection latencies, 6-wide BVH; paper
    // section 6.6: ptxas registers; Chou et al.'s treelet-prefetching code: prefetcher.
    assert_eq!(c.memory.dram_latency, 254);
    assert_eq!(c.gpu.raygen_regs_per_thread, 10);
    let l = c.rt.latencies;
    assert_eq!(
        [
            l.header,
            l.internal,
            l.instance_leaf,
            l.primitive_descriptor,
            l.triangle_leaf,
            l.triangle_hit,
            l.procedural
        ],
        [2, 4, 4, 2, 4, 4, 4]
    );
    assert_eq!(c.bvh.width, 6);
    assert_eq!(c.mode.prefetch_threshold, 0.75);
    // Section 5: 4096 rays per SM, treelets half the L1; workload 256x256, 1 spp, 3 bounces.
    assert_eq!(c.hw.max_rays, 4096);
    assert_eq!(c.hw.treelet_bytes, c.memory.l1_bytes / 2);
    assert_eq!(c.bvh_params().treelet_bytes, 8192);
    let r = c.render_settings();
    assert_eq!((r.width, r.height, r.spp, r.bounces), (256, 256, 1, 3));
    // The default is the baseline GPU: no virtualization, no queue features.
    assert_eq!(c.mode.kind, ModeKind::Baseline);
    assert!(!c.mode.virtualization && !c.mode.grouping && !c.mode.preload);
    // 16 CTAs of 64 threads fill the 32 warps of 32 threads exactly.
    assert_eq!(c.warps_per_cta(), 2);
    assert_eq!(
        c.gpu.max_ctas_per_sm * c.gpu.threads_per_cta,
        c.gpu.max_warps_per_sm * c.gpu.warp_size
    );
    // A suspended CTA: 64 threads x 10 registers x 4 B, plus 2 warps x 2 SIMT entries x
    // (mask, PC, reconvergence PC) x 4 B.
    assert_eq!(c.cta_state_bytes(), 64 * 10 * 4 + 2 * 2 * 3 * 4);
}

#[test]
fn empty_load_is_the_default() {
    assert_eq!(SimConfig::load(None, &[]).unwrap(), SimConfig::default());
    let empty = temp_file("empty", "# nothing\n");
    assert_eq!(
        SimConfig::load(Some(&empty), &[]).unwrap(),
        SimConfig::default()
    );
}

#[test]
fn every_shipped_config_loads_and_validates() {
    let mut names: Vec<String> = std::fs::read_dir(designs_dir())
        .unwrap()
        .map(|e| format!("{}.toml", e.unwrap().file_name().to_string_lossy()))
        .collect();
    names.sort();
    for expected in [
        "baseline.toml",
        "prefetch.toml",
        "vtq.toml",
        "queues-naive.toml",
        "queues-grouping.toml",
        "queues-repack16.toml",
        "vtq-prefetch.toml",
    ] {
        assert!(names.iter().any(|n| n == expected), "missing {expected}");
    }
    for name in &names {
        let c = load_shipped(name, &[]).unwrap_or_else(|e| panic!("{name}: {e}"));
        c.validate().unwrap();
    }
}

#[test]
fn shipped_configs_select_the_papers_designs() {
    let base = load_shipped("baseline.toml", &[]).unwrap();
    assert_eq!(base, SimConfig::default());

    let pf = load_shipped("prefetch.toml", &[]).unwrap();
    assert_eq!(pf.mode.kind, ModeKind::Prefetch);
    assert_eq!(pf.mode.prefetch_threshold, 0.75);

    // (grouping, repack threshold) of the ablation ladder: naive, + grouping, + repack 16, VTQ.
    let ladder = [
        ("queues-naive.toml", false, 0),
        ("queues-grouping.toml", true, 0),
        ("queues-repack16.toml", true, 16),
        ("vtq.toml", true, 22),
    ];
    for (name, grouping, repack) in ladder {
        let c = load_shipped(name, &[]).unwrap();
        assert_eq!(c.mode.kind, ModeKind::Queues, "{name}");
        assert!(c.mode.virtualization && c.mode.preload, "{name}");
        assert_eq!(c.mode.grouping, grouping, "{name}");
        assert_eq!(c.hw.repack_threshold, repack, "{name}");
        assert_eq!(c.hw.underpopulation_threshold, 128, "{name}");
        assert_eq!(c.controller_features().group_underpopulated, grouping);
        // Only the mode and the queue hardware differ from the baseline GPU.
        assert_eq!(c.gpu, base.gpu, "{name}");
        assert_eq!(c.memory, base.memory, "{name}");
        assert_eq!(c.workload, base.workload, "{name}");
    }
}

/// VTQ with treelet prefetching is VTQ plus the prefetcher's switches, and the switch means
/// something only beside the treelet RT unit.
#[test]
fn vtq_prefetch_is_vtq_with_the_prefetcher_watching_its_rays() {
    let vtq = load_shipped("vtq.toml", &[]).unwrap();
    let both = load_shipped("vtq-prefetch.toml", &[]).unwrap();
    assert_eq!(both.mode.treelet_prefetch, TreeletPrefetch::RayStationary);
    assert_eq!(both.mode.prefetch_threshold, 0.75);
    assert!(both.mode.prefetcher() && both.mode.treelet_queues());
    assert!(both.mode.units().contains(&"prefetcher"));
    assert!(!vtq.mode.units().contains(&"prefetcher"));
    let mut same = both.clone();
    same.mode.treelet_prefetch = TreeletPrefetch::Off;
    assert_eq!(same, vtq, "only the switch differs");
    let all = load_shipped("vtq-prefetch.toml", &["mode.treelet_prefetch=all"]).unwrap();
    assert_eq!(all.mode.treelet_prefetch, TreeletPrefetch::All);
    // Not beside the plain RT unit: the prefetch design's prefetcher always runs.
    for kind in ["baseline", "prefetch"] {
        let e = assert_key_error(
            load_set(&[
                &format!("mode.kind={kind}"),
                "mode.treelet_prefetch=ray_stationary",
            ]),
            "mode.treelet_prefetch",
        );
        assert!(e.to_string().contains("only treelet queues use it"), "{e}");
    }
    // The threshold needs a prefetcher that uses it.
    let e = assert_key_error(
        load_shipped("vtq.toml", &["mode.prefetch_threshold=0.5"]),
        "mode.prefetch_threshold",
    );
    assert!(
        e.to_string().contains("mode.treelet_prefetch = \"off\""),
        "{e}"
    );
    let c = load_shipped("vtq-prefetch.toml", &["mode.prefetch_threshold=0.5"]).unwrap();
    assert_eq!(c.mode.prefetch_threshold, 0.5);
    assert!(load_set(&["mode.kind=queues", "mode.treelet_prefetch=sometimes"]).is_err());
}

#[test]
fn dotted_and_bare_overrides() {
    let c = load_shipped(
        "vtq.toml",
        &[
            "hw.repack_threshold=16",
            "memory.l1_bytes=65536",
            "width=64",
            "height = 32",
            "workload.spp=2",
            "bounces=0",
            "rt.latencies.internal=8",
            "sim.lockstep=true",
        ],
    )
    .unwrap();
    assert_eq!(c.hw.repack_threshold, 16);
    assert_eq!(c.memory.l1_bytes, 65536);
    assert_eq!((c.workload.width, c.workload.height), (64, 32));
    assert_eq!((c.workload.spp, c.workload.bounces), (2, 0));
    assert_eq!(c.rt.latencies.internal, 8);
    assert_eq!(c.rt_unit_params(0, None, 16).latencies.internal, 8);
    assert!(c.sim.lockstep);
    // Untouched keys keep the file's values.
    assert!(c.mode.grouping);
}

#[test]
fn override_values_are_toml_or_bare_strings() {
    let quoted = load_set(&[
        "mode.kind=\"queues\"",
        "mode.virtualization=true",
        "hw.repack_threshold=0",
    ])
    .unwrap();
    assert_eq!(quoted.mode.kind, ModeKind::Queues);
    assert!(quoted.mode.virtualization);
    let bare = load_set(&[
        "mode.kind=queues",
        "mode.virtualization=true",
        "hw.repack_threshold=0",
    ])
    .unwrap();
    assert_eq!(bare, quoted);
    let float = load_set(&["mode.kind=prefetch", "mode.prefetch_threshold=0.5"]).unwrap();
    assert_eq!(float.mode.prefetch_threshold, 0.5);
    // TOML integer syntax: underscores and hexadecimal.
    let ints = load_set(&["sim.watchdog_cycles=1_000_000", "sim.sample_interval=0x100"]).unwrap();
    assert_eq!(ints.sim.watchdog_cycles, 1_000_000);
    assert_eq!(ints.sim.sample_interval, 256);
}

#[test]
fn overrides_apply_in_order_over_the_file() {
    let file = temp_file("order", "[workload]\nwidth = 100\nheight = 50\n");
    let c = SimConfig::load(Some(&file), &sets(&["width=20", "workload.width=30"])).unwrap();
    assert_eq!(c.workload.width, 30);
    assert_eq!(c.workload.height, 50);
}

#[test]
fn partial_file_fills_defaults() {
    let file = temp_file("partial", "[gpu]\nsms = 4\n\n[rt.latencies]\nheader = 3\n");
    let c = SimConfig::load(Some(&file), &[]).unwrap();
    assert_eq!(c.gpu.sms, 4);
    assert_eq!(c.gpu.max_warps_per_sm, 32);
    assert_eq!(c.rt.latencies.header, 3);
    assert_eq!(c.rt.latencies.internal, 4);
}

#[test]
fn unknown_key_in_file_names_key_file_and_valid_keys() {
    let file = temp_file("unknown", "[gpu]\nsms = 4\nsmz = 8\n");
    let e = assert_key_error(SimConfig::load(Some(&file), &[]), "gpu.smz");
    let msg = e.to_string();
    assert!(msg.contains(&file.display().to_string()), "{msg}");
    for valid in [
        "sms",
        "max_warps_per_sm",
        "threads_per_cta",
        "raygen_cycles",
    ] {
        assert!(msg.contains(valid), "should list {valid}: {msg}");
    }
    let section = temp_file("unknown-section", "[gpus]\nsms = 4\n");
    let e = assert_key_error(SimConfig::load(Some(&section), &[]), "gpus");
    assert!(e.to_string().contains("memory"), "{e}");
}

#[test]
fn unknown_key_in_set_names_key_and_suggests() {
    let e = assert_key_error(load_set(&["gpu.smz=8"]), "gpu.smz");
    assert!(e.to_string().contains("--set `gpu.smz=8`"), "{e}");
    // A key that lives in another section is pointed to.
    let e = assert_key_error(load_set(&["bvh.treelet_bytes=4096"]), "bvh.treelet_bytes");
    assert!(e.to_string().contains("hw.treelet_bytes"), "{e}");
    let e = assert_key_error(load_set(&["repack_threshold=16"]), "repack_threshold");
    assert!(e.to_string().contains("hw.repack_threshold"), "{e}");
    let e = assert_key_error(load_set(&["rt.latencies.box=2"]), "rt.latencies.box");
    assert!(e.to_string().contains("triangle_hit"), "{e}");
}

#[test]
fn type_mismatch_names_key_and_expected_type() {
    let e = assert_key_error(
        load_set(&["hw.repack_threshold=abc"]),
        "hw.repack_threshold",
    );
    assert!(matches!(e, ConfigError::Type { .. }), "{e}");
    assert!(e.to_string().contains("u32"), "{e}");
    let e = assert_key_error(load_set(&["gpu.sms=-1"]), "gpu.sms");
    assert!(matches!(e, ConfigError::Type { .. }), "{e}");
    let e = assert_key_error(load_set(&["mode.kind=fast"]), "mode.kind");
    assert!(
        e.to_string().contains("queues"),
        "should list the kinds: {e}"
    );
    let e = assert_key_error(load_set(&["sim.lockstep=1"]), "sim.lockstep");
    assert!(e.to_string().contains("bool"), "{e}");
    let file = temp_file("type", "[mode]\nvirtualization = \"yes\"\n");
    let e = assert_key_error(SimConfig::load(Some(&file), &[]), "mode.virtualization");
    assert!(e.to_string().contains(&file.display().to_string()), "{e}");
    // A section is not a value.
    assert_key_error(load_set(&["gpu=3"]), "gpu");
}

#[test]
fn malformed_override_is_rejected() {
    for text in [
        "hw.repack_threshold",
        "=3",
        "hw..repack_threshold=3",
        "sim.watchdog_cycles=99999999999999999999",
        "mode.kind=\"queues",
    ] {
        let e = load_set(&[text]).unwrap_err();
        assert!(matches!(e, ConfigError::Override { .. }), "{text}: {e}");
        assert!(e.to_string().contains(text), "{e}");
    }
}

#[test]
fn bad_toml_and_missing_file_name_the_file() {
    let file = temp_file("syntax", "[gpu\nsms = \n");
    let e = SimConfig::load(Some(&file), &[]).unwrap_err();
    assert!(matches!(e, ConfigError::Syntax { .. }), "{e}");
    assert!(e.to_string().contains(&file.display().to_string()), "{e}");
    let missing = designs_dir().join("no-such-config.toml");
    let e = SimConfig::load(Some(&missing), &[]).unwrap_err();
    assert!(matches!(e, ConfigError::Read { .. }), "{e}");
    assert!(e.to_string().contains("no-such-config.toml"), "{e}");
}

/// Bad configurations: (config file, overrides, offending key, value shown).
const BAD_CONFIGS: &[(&str, &[&str], &str, &str)] = &[
    (
        "vtq.toml",
        &["hw.repack_threshold=33"],
        "hw.repack_threshold",
        "33",
    ),
    (
        "vtq.toml",
        &["hw.record_bytes_per_cycle=48"],
        "hw.record_bytes_per_cycle",
        "48",
    ),
    (
        "vtq.toml",
        &["hw.record_bytes_per_cycle=2048"],
        "hw.record_bytes_per_cycle",
        "2048",
    ),
    (
        "baseline.toml",
        &["hw.record_bytes_per_cycle=64"],
        "hw.record_bytes_per_cycle",
        "64",
    ),
    (
        "baseline.toml",
        &["memory.l1_bytes=0"],
        "memory.l1_bytes",
        "0",
    ),
    (
        "baseline.toml",
        &["memory.l1_bytes=12288"],
        "memory.l1_bytes",
        "12288",
    ),
    (
        "baseline.toml",
        &["gpu.warp_size=16"],
        "gpu.warp_size",
        "16",
    ),
    (
        "baseline.toml",
        &["gpu.threads_per_cta=48"],
        "gpu.threads_per_cta",
        "48",
    ),
    (
        "baseline.toml",
        &["gpu.max_ctas_per_sm=32"],
        "gpu.max_ctas_per_sm",
        "32",
    ),
    (
        "baseline.toml",
        &["gpu.registers_per_sm=8192"],
        "gpu.registers_per_sm",
        "8192",
    ),
    ("baseline.toml", &["gpu.sms=0"], "gpu.sms", "0"),
    (
        "baseline.toml",
        &["mode.grouping=true"],
        "mode.grouping",
        "true",
    ),
    (
        "baseline.toml",
        &["mode.preload=true"],
        "mode.preload",
        "true",
    ),
    (
        "baseline.toml",
        &["hw.repack_threshold=16"],
        "hw.repack_threshold",
        "16",
    ),
    (
        "vtq.toml",
        &["mode.prefetch_threshold=0.5"],
        "mode.prefetch_threshold",
        "0.5",
    ),
    (
        "prefetch.toml",
        &["mode.prefetch_threshold=1.5"],
        "mode.prefetch_threshold",
        "1.5",
    ),
    (
        "queues-naive.toml",
        &["hw.repack_threshold=22"],
        "hw.repack_threshold",
        "22",
    ),
    (
        "vtq.toml",
        &["mode.virtualization=false"],
        "hw.repack_threshold",
        "22",
    ),
    (
        "vtq.toml",
        &["hw.max_resident_treelets=1"],
        "hw.max_resident_treelets",
        "1",
    ),
    (
        "vtq.toml",
        &["hw.max_resident_treelets=4"],
        "hw.max_resident_treelets",
        "4",
    ),
    ("vtq.toml", &["hw.max_rays=512"], "hw.max_rays", "512"),
    (
        "baseline.toml",
        &["hw.treelet_bytes=32768"],
        "hw.treelet_bytes",
        "32768",
    ),
    (
        "baseline.toml",
        &["hw.treelet_bytes=256"],
        "hw.treelet_bytes",
        "256",
    ),
    ("baseline.toml", &["bvh.width=9"], "bvh.width", "9"),
    ("baseline.toml", &["bvh.width=1"], "bvh.width", "1"),
    ("baseline.toml", &["width=0"], "workload.width", "0"),
    (
        "baseline.toml",
        &["height=100000"],
        "workload.height",
        "100000",
    ),
    ("baseline.toml", &["spp=0"], "workload.spp", "0"),
    (
        "baseline.toml",
        &["bounces=1000"],
        "workload.bounces",
        "1000",
    ),
    (
        "baseline.toml",
        &["rt.latencies.internal=0"],
        "rt.latencies.internal",
        "0",
    ),
    (
        "baseline.toml",
        &["rt.resp_fifo_depth=0"],
        "rt.resp_fifo_depth",
        "0",
    ),
    (
        "baseline.toml",
        &["sim.watchdog_cycles=100"],
        "sim.watchdog_cycles",
        "100",
    ),
];

#[test]
fn validation_errors_name_key_and_value() {
    let cases = BAD_CONFIGS;
    for (file, overrides, key, value) in cases {
        let e = assert_key_error(load_shipped(file, overrides), key);
        assert!(
            matches!(e, ConfigError::Invalid { .. }),
            "{file} {overrides:?}: {e}"
        );
        assert!(
            e.to_string().contains(&format!("{key} = {value}")),
            "{file} {overrides:?}: {e}"
        );
    }
}

#[test]
fn repack_threshold_above_warp_size_says_why() {
    let e = assert_key_error(
        load_shipped("vtq.toml", &["hw.repack_threshold=33"]),
        "hw.repack_threshold",
    );
    assert!(e.to_string().contains("warp_size"), "{e}");
}

#[test]
fn warp_size_mismatch_names_both_keys() {
    let e = assert_key_error(load_set(&["hw.warp_size=16"]), "gpu.warp_size");
    assert!(e.to_string().contains("hw.warp_size (16)"), "{e}");
}

#[test]
fn to_toml_round_trips() {
    let mut configs = vec![
        SimConfig::default(),
        load_set(&[
            "mode.kind=prefetch",
            "mode.prefetch_threshold=0.3",
            "rt.latencies.triangle_hit=9",
            "sim.lockstep=true",
            "width=17",
            "energy.coefficients=physical",
            "energy.clock_mhz=1000",
        ])
        .unwrap(),
    ];
    for name in [
        "baseline.toml",
        "prefetch.toml",
        "vtq.toml",
        "queues-naive.toml",
    ] {
        configs.push(load_shipped(name, &[]).unwrap());
    }
    for (i, c) in configs.iter().enumerate() {
        let text = c.to_toml().unwrap();
        let file = temp_file(&format!("round-{i}"), &text);
        assert_eq!(&SimConfig::load(Some(&file), &[]).unwrap(), c, "{text}");
        // The serde derive reads it back too.
        assert_eq!(&toml::from_str::<SimConfig>(&text).unwrap(), c);
    }
}

#[test]
fn serde_rejects_unknown_keys_and_fills_defaults() {
    assert!(toml::from_str::<SimConfig>("[gpu]\nsmz = 1\n").is_err());
    assert!(toml::from_str::<SimConfig>("[nope]\n").is_err());
    let c: SimConfig = toml::from_str("[workload]\nwidth = 8\n").unwrap();
    assert_eq!(c.workload.width, 8);
    assert_eq!(c.gpu, SimConfig::default().gpu);
}
