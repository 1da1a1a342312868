//! The sampled tier (docs/accuracy.md): deterministic for a seed, exactly full detail when the
//! sample is the whole workload, skipping idle cycles equal to lockstep inside its replicates,
//! a paired speedup from the same CTA samples, stripe sampling where every CTA is resident, and
//! one-line errors for bad settings.

mod common;

use std::process::Command;

use common::{fresh_dir, setup, small_accuracy_args, small_config, SMALL_SAMPLED};
use vtq_sim::estimate::sample::stripes::ranked;
use vtq_sim::estimate::sample::{paired_speedup, simulate_sampled, Method, Profile, SampledStats};
use vtq_sim::model::config::{Cluster, SimConfig};
use vtq_sim::model::gpu::stats::comparable_json;
use vtq_sim::model::gpu::{simulate, SimOptions};

/// A sampled configuration: `mode` on 4 SMs, 24x24, `spec` (FRACTIONxREPLICATES).
fn sampled_config(mode: &str, spec: &str, extra: &[&str]) -> SimConfig {
    let mut cfg = small_config(mode, 4, 24, extra);
    cfg.sample.apply_spec(spec).unwrap();
    cfg.sample.validate(&cfg).unwrap();
    cfg
}

/// The estimates without host-dependent times, for comparing runs.
fn comparable(s: &SampledStats) -> serde_json::Value {
    common::comparable_sampled(s)
}

fn sampled(name: &str, cfg: &SimConfig, threads: usize) -> SampledStats {
    let (scene, bvh) = setup(name, cfg);
    let profile = Profile::new(&scene, &bvh, cfg).unwrap();
    simulate_sampled(&scene, &bvh, cfg, &profile, threads).unwrap()
}

#[test]
fn sampled_runs_are_deterministic_on_any_thread_count() {
    // Stratified samples (a 24x24 frame is all resident at once: stripes unless turned off).
    let cfg = sampled_config("baseline", "1/4x3", &["sample.stripes=false"]);
    let a = sampled("cornell", &cfg, 1);
    let b = sampled("cornell", &cfg, 2);
    assert_eq!(comparable(&a), comparable(&b));
    assert_eq!(a.method, Method::Strata);
    assert_eq!(a.replicate_runs.len(), 3);
    assert!(a.cycles.half_width.is_some());
    // Another seed draws other samples.
    let mut other = cfg.clone();
    other.sample.seed = 99;
    let c = sampled("cornell", &other, 1);
    assert_ne!(a.replicate_cycles(), c.replicate_cycles());
}

#[test]
fn the_whole_workload_is_exactly_full_detail() {
    for mode in ["baseline", "queues"] {
        let extra: &[&str] = if mode == "queues" {
            &[
                "mode.virtualization=true",
                "mode.grouping=true",
                "hw.max_rays=2048",
            ]
        } else {
            &[]
        };
        let cfg = sampled_config(mode, "1x1", extra);
        let (scene, bvh) = setup("cornell", &cfg);
        let full = simulate(&scene, &bvh, &cfg, SimOptions::default(), None).unwrap();
        let s = sampled("cornell", &cfg, 1);
        assert_eq!(s.scale_sms, 4);
        assert_eq!(s.cycles.value, full.stats.cycles as f64, "{mode}");
        assert_eq!(s.cycles.half_width, None);
        assert_eq!(
            comparable_json(&s.replicate_runs[0].stats),
            comparable_json(&full.stats),
            "{mode}"
        );
    }
}

#[test]
fn skipping_equals_lockstep_in_sampled_runs() {
    let cfg = sampled_config("prefetch", "1/4x2", &[]);
    let mut lock = cfg.clone();
    lock.sim.lockstep = true;
    let a = sampled("wknd", &cfg, 1);
    let b = sampled("wknd", &lock, 1);
    for (x, y) in a.replicate_runs.iter().zip(&b.replicate_runs) {
        let strip = |s: &vtq_sim::model::gpu::SimStats| {
            let mut v = comparable_json(s);
            v.as_object_mut().unwrap().remove("config");
            v
        };
        assert_eq!(strip(&x.stats), strip(&y.stats));
    }
    assert_eq!(a.cycles, b.cycles);
}

#[test]
fn speedups_pair_the_replicates() {
    let strata = ["sample.stripes=false"];
    let base = sampled("cornell", &sampled_config("baseline", "1/2x2", &strata), 1);
    let pre = sampled("cornell", &sampled_config("prefetch", "1/2x2", &strata), 1);
    let s = paired_speedup(&base, &pre);
    let pairs = || base.replicate_runs.iter().zip(&pre.replicate_runs);
    // Exactly the mean of the replicates' ratios of extrapolated cycles.
    let ratios: Vec<f64> = pairs().map(|(b, p)| b.cycles / p.cycles).collect();
    assert_eq!(s.value, (ratios[0] + ratios[1]) / 2.0);
    // Its interval: the ratios' Student-t half-width plus both designs' bias bounds.
    let t = vtq_sim::estimate::sample::Estimate::of(&ratios)
        .half_width
        .unwrap();
    let bias = s.value * (base.bias_bound + pre.bias_bound);
    assert!((s.half_width.unwrap() - (t + bias)).abs() < 1e-12);
    // Each replicate's cycles carry the same dispatch factor in both designs (the same CTAs,
    // the same CTAs per SM), so the ratio is that of the scale models' cycles, up to rounding.
    for ((b, p), r) in pairs().zip(&ratios) {
        let scale = b.stats.cycles as f64 / p.stats.cycles as f64;
        assert!((r - scale).abs() <= 1e-12 * scale, "{r} vs {scale}");
    }
    // The same CTAs ran on both designs: the same rays.
    for (b, p) in base.replicate_runs.iter().zip(&pre.replicate_runs) {
        assert_eq!(b.stats.rays, p.stats.rays);
        assert_eq!(b.ctas, p.ctas);
    }
}

/// Bad sample settings are one-line errors naming the problem.
#[test]
fn bad_sample_settings_are_one_line_errors() {
    let dir = fresh_dir("sampled-cli");
    let out = dir.join("s.json");
    // (--sample, one more --set, the key or words the one error names)
    for (spec, set, needle) in [
        ("0", "sample.cluster=1", "sample.fraction"),
        ("1.5", "sample.cluster=1", "sample.fraction"),
        ("32/16", "sample.cluster=1", "sample.fraction"),
        ("3/16", "sample.cluster=1", "whole number of SMs"),
        ("1/4x0", "sample.cluster=1", "sample.replicates"),
        ("1/4x2", "sample.cluster=0", "sample.cluster"),
        ("1/4x2", "sample.cluster=[1, 0]", "sample.cluster"),
        ("1/4x2", "sample.cluster=[]", "sample.cluster"),
        (
            "1/2x4",
            "sample.cluster=1",
            "need 32 stripes but the GPU has 16",
        ),
        ("quarter", "sample.cluster=1", "--sample `quarter`"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_vtq"))
            .args(["sim", "--scene", "cornell", "--sample", spec, "--out"])
            .arg(&out)
            .args(["--set", "width=8", "--set", "height=8", "--no-cache"])
            .args(["--set", set])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{spec}: {stderr}");
        assert!(!stderr.contains("panicked"), "{spec}: {stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{spec}: {stderr}");
        assert!(errors[0].contains(needle), "{spec}: {}", errors[0]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `vtq accuracy` measures every tier and writes the table, the summary and the plot.
#[test]
fn accuracy_command_measures_every_tier() {
    let dir = fresh_dir("accuracy-cli");
    let o = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(small_accuracy_args("cornell", None, dir.to_str().unwrap()))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for needle in ["sampled 1/2x2", "cyc err avg", "in 95%"] {
        assert!(stdout.contains(needle), "'{needle}' in {stdout}");
    }
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    // A header, then 3 designs x (full, one setting); the analytical tier is retired.
    assert_eq!(csv.lines().count(), 1 + 3 * 2, "{csv}");
    // 16x16 on 4 SMs: 4 CTAs, all resident: stripes, as the method column says.
    let methods: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(3).unwrap())
        .collect();
    assert_eq!(
        methods,
        ["", "stripes", "", "stripes", "", "stripes"],
        "{csv}"
    );
    // With the profile shared by the three designs a sampled row is faster than alone (its
    // profile's time divided by three); full detail has no profile.
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let (alone, shared): (f64, f64) = (f[5].parse().unwrap(), f[20].parse().unwrap());
        if f[2] == "full" {
            assert_eq!(alone, shared, "{line}");
        } else {
            assert!(shared > alone, "{line}");
        }
    }
    assert!(stdout.contains("x shared"), "{stdout}");
    assert!(!stdout.contains("analytical"), "{stdout}");
    assert!(
        csv.lines().skip(1).all(|l| l.starts_with("cornell,")),
        "{csv}"
    );
    // The design's own `[sample]` keys other than the setting's hold: stripes off.
    let off = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(["accuracy", "--scene", "cornell", "--settings", "1/2x2"])
        .args(["--designs", "baseline", "--set", "sample.stripes=false"])
        .args(SMALL_SAMPLED)
        .arg("--out")
        .arg(dir.join("off"))
        .output()
        .unwrap();
    assert!(
        off.status.success(),
        "{}",
        String::from_utf8_lossy(&off.stderr)
    );
    let off_csv = std::fs::read_to_string(dir.join("off/accuracy.csv")).unwrap();
    assert!(
        off_csv.lines().nth(2).unwrap().contains(",strata,"),
        "{off_csv}"
    );
    let png = std::fs::read(dir.join("accuracy.png")).unwrap();
    assert_eq!(&png[..4], b"\x89PNG");
    assert!(std::fs::read_to_string(dir.join("accuracy.svg"))
        .unwrap()
        .contains("<svg"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `vtq accuracy --perturb`: full detail also runs with the DRAM latency moved, and each row
/// gets the reference's mean and spread and its error against the mean.
#[test]
fn accuracy_with_perturbed_references() {
    let dir = fresh_dir("accuracy-pert");
    // With perturbations: full detail also runs with the DRAM latency moved by +1 and -1
    // cycles; each row gets the reference's mean and spread and its error against the mean.
    let pert = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(["accuracy", "--scene", "cornell", "--settings", "1/2x2"])
        .args(["--designs", "baseline,vtq", "--perturb", "2"])
        .args(SMALL_SAMPLED)
        .arg("--out")
        .arg(dir.clone())
        .output()
        .unwrap();
    let pert_out = String::from_utf8_lossy(&pert.stdout);
    assert!(pert.status.success(), "{pert_out}");
    assert!(
        pert_out.contains("against the mean of full detail's 3 runs"),
        "{pert_out}"
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("accuracy.json")).unwrap()).unwrap();
    for row in doc["rows"].as_array().unwrap() {
        let r = &row["reference"];
        let runs: Vec<f64> = r["cycles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect();
        assert_eq!(runs.len(), 3, "{row}");
        let mean = runs.iter().sum::<f64>() / 3.0;
        assert!((r["mean"].as_f64().unwrap() - mean).abs() < 1e-6, "{row}");
        let est = row["cycles"].as_f64().unwrap();
        assert!((r["cycles_error"].as_f64().unwrap() - (est / mean - 1.0)).abs() < 1e-9);
        // The unperturbed run is the reference's first, and full detail's own row.
        if row["tier"] == "Full" {
            assert_eq!(runs[0], est, "{row}");
        }
    }
    let pert_csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    assert!(pert_csv
        .lines()
        .next()
        .unwrap()
        .ends_with("speedup_covered_mean,time_speedup_shared"));
    for line in pert_csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 21, "{line}");
        assert!(f[14..17].iter().all(|v| !v.is_empty()), "{line}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `vtq compare --sample` labels its rows as estimates with intervals.
#[test]
fn sampled_compare_labels_estimates() {
    let o = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(["compare", "--scene", "cornell", "--sample", "1/2x2"])
        .args(SMALL_SAMPLED)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}");
    assert!(stdout.contains("compare (sampled)"), "{stdout}");
    assert!(stdout.contains(" ± "), "{stdout}");
    assert!(
        stdout.contains("estimates (sampled tier, not full detail)"),
        "{stdout}"
    );
}

#[test]
fn a_frame_whose_ctas_are_all_resident_at_once_is_flagged() {
    // 24x24: 9 CTAs, fewer than 4 SMs hold at once in any design.
    let small = sampled("cornell", &sampled_config("baseline", "1/4x2", &[]), 2);
    assert!(small.every_cta_resident);
    // 128x128: 256 CTAs; the baseline holds 4 x its CTA slots at once, VTQ with ray
    // virtualization as many as its ray budget covers (all of them with 4096 rays per SM).
    let base = sampled_config("baseline", "1/4x2", &["width=128", "height=128"]);
    assert!(!sampled("cornell", &base, 2).every_cta_resident);
    let mut vtq = common::small_vtq(4, 128, &[]);
    vtq.sample.apply_spec("1/4x2").unwrap();
    assert!(sampled("cornell", &vtq, 2).every_cta_resident);
    // With a ray budget of its CTA slots' rays (16 x 64), VTQ holds no more CTAs than they do.
    let mut tight = common::small_vtq(4, 128, &["hw.max_rays=1024"]);
    tight.sample.apply_spec("1/4x2").unwrap();
    assert!(!sampled("cornell", &tight, 2).every_cta_resident);
}

/// Where every CTA is resident, the replicates simulate the whole stripes the profile ranks
/// slowest, together in one scale model, and the estimate is the slowest stripe's cycles with
/// the validated bound as its interval; the same on any thread count.
#[test]
fn stripe_sampling_simulates_the_stripes_ranked_slowest() {
    // 128x128 on 4 SMs: 256 CTAs, all resident under VTQ with ray virtualization.
    let mut cfg = common::small_vtq(4, 128, &[]);
    cfg.sample.apply_spec("1/4x2").unwrap();
    let (scene, bvh) = setup("cornell", &cfg);
    let profile = Profile::new(&scene, &bvh, &cfg).unwrap();
    assert_eq!(profile.stripes.len(), 4);
    let s = simulate_sampled(&scene, &bvh, &cfg, &profile, 1).unwrap();
    assert_eq!(s.method, Method::Stripes);
    // The two replicates' stripes ran together: one scale model of 2 SMs.
    assert_eq!((s.replicates, s.scale_sms), (1, 2));
    let run = &s.replicate_runs[0];
    let mut first_two = ranked(&profile.stripes)[..2].to_vec();
    first_two.sort_unstable();
    assert_eq!(run.stripes, first_two);
    let stripe_ctas = (0..256u32).filter(|c| first_two.contains(&(c % 4))).count();
    assert_eq!(run.ctas, stripe_ctas);
    // Whole stripes need no carrying to the frame: the slowest stripe is the estimate.
    assert_eq!(s.cycles.value, run.stats.cycles as f64);
    assert_eq!(run.cycles, run.stats.cycles as f64);
    let h = s.cycles.half_width.unwrap();
    assert!((h - s.cycles.value * cfg.sample.stripe_bound).abs() < 1e-6);
    // Every ranked stripe's footprint and work come from the profile's CTAs.
    let fetches: u64 = profile.stripes.iter().map(|w| w.fetches).sum();
    assert_eq!(fetches, profile.work(None).fetches);
    assert!(profile.stripes.iter().all(|w| w.lines > 0));
    assert_eq!(
        comparable(&s),
        comparable(&simulate_sampled(&scene, &bvh, &cfg, &profile, 2).unwrap())
    );
    // Stripes turned off: stratified samples in two replicates.
    let mut strata = cfg.clone();
    strata.sample.stripes = false;
    let t = simulate_sampled(&scene, &bvh, &strata, &profile, 1).unwrap();
    assert_eq!((t.method, t.replicate_runs.len()), (Method::Strata, 2));
    assert!(t.replicate_runs.iter().all(|r| r.stripes.is_empty()));
    // A stripe run and a stratified one do not pair: the ratio of the estimates, with the sum
    // of their relative half-widths.
    let sp = paired_speedup(&t, &s);
    assert_eq!(sp.value, t.cycles.value / s.cycles.value);
    let rel = t.cycles.half_width.unwrap() / t.cycles.value + cfg.sample.stripe_bound;
    assert!((sp.half_width.unwrap() - sp.value * rel).abs() < 1e-9);
}

/// The footprint is computed only on frames some design could hold at once: a frame with
/// more CTAs than 4 SMs hold even under ray virtualization (64 each) has none.
#[test]
fn large_frames_have_no_stripes() {
    // 136x136: 17 x 17 = 289 CTAs of 8x8 pixels, above 4 x 64.
    let cfg = sampled_config("baseline", "1/4x2", &["width=136", "height=136"]);
    let (scene, bvh) = setup("cornell", &cfg);
    let profile = Profile::new(&scene, &bvh, &cfg).unwrap();
    assert!(profile.stripes.is_empty());
    let s = simulate_sampled(&scene, &bvh, &cfg, &profile, 1).unwrap();
    assert_eq!(s.method, Method::Strata);
    // The interval of cycles: the replicates' Student-t half-width plus the tail bound over
    // the frame's waves (289 CTAs over the 4 x 16 the baseline's SMs hold at once).
    let waves = 289.0 / 64.0;
    assert!((s.bias_bound - cfg.sample.tail_bound / waves).abs() < 1e-12);
    let t = vtq_sim::estimate::sample::Estimate::of(&s.replicate_cycles());
    let expected = t.half_width.unwrap() + s.bias_bound * t.value;
    assert!((s.cycles.half_width.unwrap() - expected).abs() < 1e-6);
    assert_eq!(s.cycles.value, t.value);
}

/// Stratified samples come in clumps of `sample.cluster` neighbouring CTAs (runs of
/// consecutive CTAs starting at a multiple of the clump), as a GPU SM's CTAs do; 1 draws single
/// CTAs; either way each replicate holds `fraction` of the frame's CTAs.
#[test]
fn stratified_samples_come_in_clumps_of_neighbours() {
    // 136x136: 289 CTAs, too many to be resident at once: stratified.
    for cluster in [1u32, 2, 4] {
        let c = format!("sample.cluster={cluster}");
        let cfg = sampled_config("baseline", "1/4x2", &["width=136", "height=136", &c]);
        let (scene, bvh) = setup("cornell", &cfg);
        let profile = Profile::new(&scene, &bvh, &cfg).unwrap();
        let samples = vtq_sim::estimate::sample::run::samples(&cfg, &profile).unwrap();
        assert_eq!(samples.len(), 2);
        for sample in &samples {
            let n = sample.len() as i64;
            assert!((n - 289 / 4).abs() <= cluster as i64, "{cluster}: {n}");
            // Every CTA's clump is whole in the sample (the last, CTA 288, is a clump alone).
            for &cta in sample {
                let start = cta - cta % cluster;
                let clump = (start..(start + cluster).min(289)).collect::<Vec<u32>>();
                assert!(clump.iter().all(|c| sample.contains(c)), "{cluster}: {cta}");
            }
        }
        assert_ne!(samples[0], samples[1]);
        if cluster == 1 {
            // Single CTAs: neighbours together only by chance (a clumped sample has half).
            let pairs = samples[0].windows(2).filter(|w| w[1] == w[0] + 1).count();
            assert!(pairs < samples[0].len() / 2, "{pairs}");
        }
    }
}

/// `sample.cluster = [1, 2]` gives each replicate its clump size in turn: replicate 0 draws
/// single CTAs and replicate 1 pairs, each exactly the sample its size gives that replicate on
/// its own (the same stream), replicate 2 single CTAs again.
#[test]
fn a_cluster_list_gives_each_replicate_its_size_in_turn() {
    let config = |cluster: &str| {
        let c = format!("sample.cluster={cluster}");
        sampled_config("baseline", "1/4x3", &["width=136", "height=136", &c])
    };
    let draw = |cluster: &str| {
        let cfg = config(cluster);
        let (scene, bvh) = setup("cornell", &cfg);
        let profile = Profile::new(&scene, &bvh, &cfg).unwrap();
        vtq_sim::estimate::sample::run::samples(&cfg, &profile).unwrap()
    };
    let (single, pairs, mixed) = (draw("1"), draw("2"), draw("[1, 2]"));
    assert_eq!(mixed.len(), 3);
    assert_eq!(mixed[0], single[0]);
    assert_eq!(mixed[1], pairs[1]);
    assert_eq!(mixed[2], single[2]);
    assert_ne!(mixed[1], single[1]);
    // A one-element list is the plain size.
    assert_eq!(draw("[2]"), pairs);
    // The replicates simulate samples of those sizes, and the estimates say which drew them.
    let s = sampled("cornell", &config("[1, 2]"), 2);
    assert_eq!(s.cluster, Cluster::PerReplicate(vec![1, 2]));
    let ctas: Vec<usize> = s.replicate_runs.iter().map(|r| r.ctas).collect();
    assert_eq!(ctas, mixed.iter().map(Vec::len).collect::<Vec<_>>());
}

/// A stratified replicate's cycles are carried to the whole frame by the dispatch model with
/// each CTA's cost as the design's RT unit pays it: the baseline's, which keeps a warp until
/// its slowest ray is done, its warps' lockstep fetches (between a warp's share of the CTA's
/// fetches and all of them, and above the share where a warp's rays differ); the treelet RT
/// unit's, which repacks rays, every fetch.
#[test]
fn the_dispatch_model_costs_ctas_as_the_design_pays_them() {
    use vtq_sim::estimate::sample::dispatch::{makespan_ratio, resident_ctas};
    for (mode, lockstep) in [("baseline", true), ("queues", false)] {
        // 136x136: 289 CTAs, more than any design's 4 SMs hold at once: strata.
        let size = ["width=136", "height=136"];
        let vtq = [
            &size[..],
            &["mode.grouping=true", "mode.virtualization=true"],
        ]
        .concat();
        let cfg = sampled_config(mode, "1/4x2", if lockstep { &size } else { &vtq });
        let (scene, bvh) = setup("cornell", &cfg);
        let profile = Profile::new(&scene, &bvh, &cfg).unwrap();
        let warp = u64::from(cfg.gpu.warp_size);
        for w in &profile.ctas {
            assert!(w.warp_fetches <= w.fetches && w.warp_fetches * warp >= w.fetches);
        }
        let (fetches, lockstep_fetches) = profile
            .ctas
            .iter()
            .fold((0, 0), |(f, l), w| (f + w.fetches, l + w.warp_fetches));
        assert!(lockstep_fetches * warp > fetches, "every ray alike?");
        let s = simulate_sampled(&scene, &bvh, &cfg, &profile, 1).unwrap();
        assert_eq!(s.method, Method::Strata);
        let cost = |c: u32| {
            let w = &profile.ctas[c as usize];
            (if lockstep { w.warp_fetches } else { w.fetches }) as f64
        };
        let full: Vec<f64> = (0..profile.ctas.len() as u32).map(cost).collect();
        let samples = vtq_sim::estimate::sample::run::samples(&cfg, &profile).unwrap();
        for (r, ctas) in s.replicate_runs.iter().zip(&samples) {
            let sample: Vec<f64> = ctas.iter().map(|&c| cost(c)).collect();
            let ratio = makespan_ratio(&full, 4, &sample, 1, resident_ctas(&cfg));
            let carried = r.stats.cycles as f64 * ratio;
            assert!(
                (r.cycles - carried).abs() <= 1e-9 * carried,
                "{mode}: {r:?}"
            );
        }
    }
}

/// A scale model starts with the BVH lines the GPU's other SMs would have fetched first in its
/// L2 (`sample.warm_l2`): more of its BVH reads hit there than from a cold L2, the same on any
/// thread count. (The whole GPU warms nothing: `the_whole_workload_is_exactly_full_detail`.)
#[test]
fn scale_models_start_with_the_other_sms_bvh_lines() {
    let warm = sampled_config("baseline", "1/4x2", &[]);
    let cold = sampled_config("baseline", "1/4x2", &["sample.warm_l2=false"]);
    assert!(warm.sample.warm_l2 && !cold.sample.warm_l2);
    let (w, c) = (sampled("cornell", &warm, 1), sampled("cornell", &cold, 1));
    for (rw, rc) in w.replicate_runs.iter().zip(&c.replicate_runs) {
        let (hw, hc) = (rw.stats.memory.bvh.l2_hits, rc.stats.memory.bvh.l2_hits);
        assert!(hw > hc, "warm {hw} vs cold {hc} BVH L2 hits");
        assert_eq!(
            rw.stats.memory.bvh.l2_accesses,
            rw.stats.memory.bvh.l2_hits
                + rw.stats.memory.bvh.l2_merges
                + rw.stats.memory.bvh.l2_misses
        );
    }
    assert_eq!(comparable(&w), comparable(&sampled("cornell", &warm, 2)));
}

/// Where the frame's BVH footprint is small (`sample.ghost_l2_footprint`), the profile records
/// each CTA's reads at the L2 and a scale model replays the left-out SMs' into its L2 as it
/// runs: more of its BVH reads hit there than without them (the lines other SMs keep
/// bringing), nothing of the replay is counted, and the results are the same on any thread
/// count; above the limit nothing is recorded and nothing changes.
#[test]
fn scale_models_see_the_other_sms_bvh_reads() {
    let with = sampled_config("baseline", "1/4x2", &["sample.warm_l2=false"]);
    let without = sampled_config(
        "baseline",
        "1/4x2",
        &["sample.warm_l2=false", "sample.ghost_l2_footprint=0"],
    );
    assert!(with.sample.ghost_l2_footprint > 0.0);
    let (scene, bvh) = setup("cornell", &with);
    let profile = Profile::new(&scene, &bvh, &with).unwrap();
    assert_eq!(profile.cta_streams.len(), profile.ctas.len());
    assert!(profile.footprint_bytes > 0);
    // Every CTA's reads at the L2 are among its fetches' sectors, at most one per 32 B read.
    let reads: usize = profile.cta_streams.iter().map(Vec::len).sum();
    assert!(reads > 0 && reads as u64 <= profile.work(None).fetches * 8);
    let (g, n) = (
        sampled("cornell", &with, 1),
        sampled("cornell", &without, 1),
    );
    for (rg, rn) in g.replicate_runs.iter().zip(&n.replicate_runs) {
        let (bg, bn) = (&rg.stats.memory.bvh, &rn.stats.memory.bvh);
        assert!(
            bg.l2_hits > bn.l2_hits,
            "{} vs {} BVH L2 hits",
            bg.l2_hits,
            bn.l2_hits
        );
        // The model's own reads only: as many reach the L2 as without the replay, give or take
        // what the L1 merges differently when timing moves.
        assert_eq!(bg.l2_accesses, bg.l2_hits + bg.l2_merges + bg.l2_misses);
        let ratio = bg.l2_accesses as f64 / bn.l2_accesses as f64;
        assert!((0.8..1.25).contains(&ratio), "L2 reads {ratio}");
    }
    assert_eq!(comparable(&g), comparable(&sampled("cornell", &with, 2)));
    // A limit below the footprint records nothing: the results are those without the replay.
    let tiny = sampled_config(
        "baseline",
        "1/4x2",
        &["sample.warm_l2=false", "sample.ghost_l2_footprint=0.000001"],
    );
    let (scene, bvh) = setup("cornell", &tiny);
    assert!(Profile::new(&scene, &bvh, &tiny)
        .unwrap()
        .cta_streams
        .is_empty());
    let t = sampled("cornell", &tiny, 1);
    assert_eq!(t.cycles, n.cycles);
    for (rt, rn) in t.replicate_runs.iter().zip(&n.replicate_runs) {
        assert_eq!(rt.stats.cycles, rn.stats.cycles);
        assert_eq!(rt.stats.memory, rn.stats.memory);
    }
}

/// Where the stripes' scale model runs CTAs of several stripes on one SM, the stripes are not
/// the GPU's fixed SM workloads (fox under VTQ at 256x256: its sky CTAs finish before the last
/// CTA is dispatched, and later CTAs go to whichever SM has room), so the tier falls back to
/// stratified samples and says so. Needs `../shared/scenes/fox`; says when it skips.
#[test]
fn stripes_whose_dispatch_is_not_static_fall_back_to_strata() {
    let Some(fox) = vtq_sim::model::scene::load::shared_scenes_dir()
        .map(|d| d.join("fox"))
        .filter(|d| d.is_dir())
    else {
        eprintln!("skipping: ../shared/scenes/fox not found");
        return;
    };
    let vtq =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/designs/vtq/config.toml");
    let mut cfg = SimConfig::load(Some(&vtq), &[]).expect("configs/designs/vtq/config.toml");
    cfg.sample.apply_spec("1/16x2").unwrap();
    let scene = vtq_sim::model::scene::load::load_scene(fox.to_str().unwrap()).expect("fox loads");
    let bvh = vtq_sim::model::bvh::HwBvh::build(&scene, &cfg.bvh_params()).expect("BVH");
    let profile = Profile::new(&scene, &bvh, &cfg).unwrap();
    assert_eq!(
        vtq_sim::estimate::sample::run::method(&cfg, &profile),
        Method::Stripes,
        "every CTA fits at once: stripes are tried"
    );
    let s = simulate_sampled(&scene, &bvh, &cfg, &profile, 2).unwrap();
    assert!(
        s.stripes_dynamic,
        "the stripes' dispatch was found not static"
    );
    assert_eq!(s.method, Method::Strata);
    assert_eq!(s.replicate_runs.len(), 2);
    assert!(s
        .replicate_runs
        .iter()
        .all(|r| !r.stripes_mixed && r.stripes.is_empty()));
    assert!(s.cycles.half_width.is_some());
}

/// `--sample` without a value runs the `default` named point (1/16x2, profile stride 4,
/// clusters [1, 2]), a name gives its settings, and a frame smaller than the point was
/// measured at gets a note saying so and what to use instead; `--help` lists the points with
/// their measured speed and error.
#[test]
fn named_sample_points_and_their_notes() {
    let dir = fresh_dir("sample-points");
    let run = |sample: &[&str]| {
        let out = dir.join("s.json");
        let o = Command::new(env!("CARGO_BIN_EXE_vtq"))
            .args(["sim", "--scene", "cornell", "--out"])
            .arg(&out)
            .args(["--set", "width=64", "--set", "height=64", "--no-cache"])
            // Stratified samples: stripe sampling reports its stripes' scale model instead.
            .args(["--set", "sample.stripes=false"])
            .args(sample)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        (stdout, json)
    };
    let (stdout, json) = run(&["--sample"]);
    assert_eq!(json["fraction"], 0.0625);
    assert_eq!(json["replicates"], 2);
    assert_eq!(json["cluster"], serde_json::json!([1, 2]));
    assert!(
        stdout.contains("note: the sample point `default` was measured at 1024x1024")
            && stdout.contains("prefer full detail"),
        "{stdout}"
    );
    let (_, named) = run(&["--sample", "default"]);
    assert_eq!(named["cycles"], json["cycles"], "no value is `default`");
    let (_, fast) = run(&["--sample", "fast"]);
    assert_eq!(fast["fraction"], 1.0 / 32.0);
    // The explicit form keeps the [sample] section's other settings, and prints no note.
    let (stdout, explicit) = run(&["--sample", "1/16x2"]);
    assert_eq!(explicit["cluster"], 1);
    assert!(!stdout.contains("note: the sample point"), "{stdout}");
    let help = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(["sim", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for point in vtq_sim::model::config::sample_points::POINTS {
        assert!(
            help.contains(&point.measured_line()) && help.contains(&point.settings()),
            "{}: {help}",
            point.name
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
