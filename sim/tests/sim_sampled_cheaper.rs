//! The sampled tier's two ways of simulating less on large frames (docs/accuracy.md, "Less than
//! one SM and a cheaper profile"): a fraction below one SM (one SM running fewer CTAs than its
//! share, carried to the frame by the dispatch model), and a profile that traces one warp in
//! `sample.profile_stride` of each CTA (each CTA's work estimated from it, the samples' CTAs
//! traced in full). Both deterministic on any thread count.

mod common;

use common::{setup, small_config};
use vtq_sim::estimate::sample::{simulate_sampled, Method, Profile, SampledStats};
use vtq_sim::model::config::SimConfig;

/// `mode` on 4 SMs at `side` x `side` with sample setting `spec` and `extra` keys.
fn config(mode: &str, side: u32, spec: &str, extra: &[&str]) -> SimConfig {
    let mut cfg = small_config(mode, 4, side, extra);
    cfg.sample.apply_spec(spec).unwrap();
    cfg.sample.validate(&cfg).unwrap();
    cfg
}

/// The estimates without host-dependent times, for comparing runs.
fn comparable(s: &SampledStats) -> serde_json::Value {
    common::comparable_sampled(s)
}

/// Below one SM (1/8 of 4 SMs): each replicate is a scale model of one SM that runs an eighth
/// of the CTAs — half of 1/4's — with the same per-SM shares as 1/4's one SM; its cycles are
/// carried to the frame by the dispatch model. Stripe sampling, which runs whole stripes,
/// runs one stripe per replicate, each on its own SM (not two stripes on one).
#[test]
fn fractions_below_one_sm_run_fewer_ctas_on_one_sm() {
    // 128x128: 256 CTAs of 64 threads; the baseline holds 16 per SM.
    let quarter = config("baseline", 128, "1/4x2", &[]);
    let eighth = config("baseline", 128, "1/8x2", &[]);
    assert_eq!(eighth.sample.scale_sms(4), Some(1));
    let (e_model, q_model) = (
        eighth.sample.scale_model(&eighth),
        quarter.sample.scale_model(&quarter),
    );
    assert_eq!((e_model.gpu, e_model.memory), (q_model.gpu, q_model.memory));
    let (scene, bvh) = setup("cornell", &eighth);
    let profile = Profile::new(&scene, &bvh, &eighth).unwrap();
    let q = simulate_sampled(&scene, &bvh, &quarter, &profile, 1).unwrap();
    let e = simulate_sampled(&scene, &bvh, &eighth, &profile, 1).unwrap();
    assert_eq!((e.method, e.scale_sms), (Method::Strata, 1));
    for (rq, re) in q.replicate_runs.iter().zip(&e.replicate_runs) {
        assert_eq!((rq.ctas, re.ctas), (64, 32));
        // Half the CTAs on one SM finish sooner; the dispatch model carries them about twice
        // as far (exactly 2 for equal CTAs).
        assert!(re.stats.cycles < rq.stats.cycles);
        let carried = re.cycles / re.stats.cycles as f64;
        assert!(carried > 1.5 && carried < 3.0, "{carried}");
    }
    // The estimates agree within their intervals.
    let gap = (e.cycles.value - q.cycles.value).abs();
    assert!(
        gap <= e.cycles.half_width.unwrap() + q.cycles.half_width.unwrap(),
        "{:?} vs {:?}",
        e.cycles,
        q.cycles
    );
    assert_eq!(
        comparable(&e),
        comparable(&simulate_sampled(&scene, &bvh, &eighth, &profile, 2).unwrap())
    );

    // Stripes under VTQ (every CTA resident): 1/8x2 runs two replicates of one stripe each.
    let mut vtq = common::small_vtq(4, 128, &[]);
    vtq.sample.apply_spec("1/8x2").unwrap();
    let (scene, bvh) = setup("cornell", &vtq);
    let profile = Profile::new(&scene, &bvh, &vtq).unwrap();
    let s = simulate_sampled(&scene, &bvh, &vtq, &profile, 1).unwrap();
    assert_eq!(s.method, Method::Stripes);
    assert_eq!(s.replicate_runs.len(), 1, "two stripes together on two SMs");
    assert_eq!(s.scale_sms, 2);
    assert_eq!(s.replicate_runs[0].stripes.len(), 2);
    assert_eq!(s.replicate_runs[0].ctas, 128);
}

/// `sample.profile_stride` 2: the profile traces one of each CTA's two warps and doubles its
/// work (the frame's rays within a few percent of the exact profile's, flagged as estimated);
/// the samples' CTAs are traced in full, so their work equals the exact profile's; results
/// are deterministic on any thread count. Stride 1 is the exact profile. The other SMs' BVH
/// reads for the replay come from the traced warps too: the same work, fewer reads.
#[test]
fn a_strided_profile_estimates_the_frame_and_traces_the_samples_in_full() {
    let no_ghosts = "sample.ghost_l2_footprint=0";
    let exact_cfg = config("baseline", 128, "1/4x2", &[no_ghosts]);
    let strided_cfg = config(
        "baseline",
        128,
        "1/4x2",
        &["sample.profile_stride=2", no_ghosts],
    );
    let (scene, bvh) = setup("cornell", &exact_cfg);
    let exact = Profile::new(&scene, &bvh, &exact_cfg).unwrap();
    let strided = Profile::new(&scene, &bvh, &strided_cfg).unwrap();
    assert_eq!((exact.stride, strided.stride), (1, 2));
    let ghosts_cfg = config("baseline", 128, "1/4x2", &["sample.profile_stride=2"]);
    let ghosts = Profile::new(&scene, &bvh, &ghosts_cfg).unwrap();
    assert_eq!((ghosts.stride, &ghosts.ctas), (2, &strided.ctas));
    let all_ghosts = Profile::new(&scene, &bvh, &config("baseline", 128, "1/4x2", &[])).unwrap();
    assert_eq!(all_ghosts.ctas, exact.ctas);
    let reads = |p: &Profile| p.cta_streams.iter().map(Vec::len).sum::<usize>();
    assert!(
        0 < reads(&ghosts) && reads(&ghosts) < reads(&all_ghosts),
        "{} of {} reads",
        reads(&ghosts),
        reads(&all_ghosts)
    );
    assert_eq!(exact.ctas.len(), strided.ctas.len());
    assert_ne!(exact.ctas, strided.ctas, "half the warps traced");
    let (re, rs) = (exact.work(None).rays as f64, strided.work(None).rays as f64);
    assert!((rs / re - 1.0).abs() < 0.05, "{rs} vs {re}");
    // Traced in full, any CTA's work is the exact profile's.
    let some: Vec<u32> = vec![0, 17, 100, 255];
    let filled = strided
        .with_exact(&scene, &bvh, &strided_cfg, &some)
        .unwrap();
    for &c in &some {
        assert_eq!(filled[c as usize], exact.ctas[c as usize]);
    }
    // The exact profile fills nothing in.
    assert_eq!(
        exact.with_exact(&scene, &bvh, &exact_cfg, &some).unwrap(),
        exact.ctas
    );

    let a = simulate_sampled(&scene, &bvh, &strided_cfg, &strided, 1).unwrap();
    let b = simulate_sampled(&scene, &bvh, &strided_cfg, &strided, 2).unwrap();
    assert_eq!(comparable(&a), comparable(&b));
    assert!(a.rays_estimated);
    let full = simulate_sampled(&scene, &bvh, &exact_cfg, &exact, 1).unwrap();
    assert!(!full.rays_estimated);
    assert_eq!(full.rays, exact.work(None).rays);
    // A replicate's work share is its CTAs' exact fetches over the strided frame's share.
    for r in &a.replicate_runs {
        assert!((r.work_share - 1.0).abs() < 0.5, "{}", r.work_share);
    }
}

/// A stride out of range is the configuration's error naming the key.
#[test]
fn a_bad_profile_stride_names_its_key() {
    for bad in ["0", "65"] {
        let err = SimConfig::load(None, &[format!("sample.profile_stride={bad}")])
            .unwrap_err()
            .to_string();
        assert!(err.contains("sample.profile_stride"), "{err}");
    }
}

/// `sample.profile_stride` 4 on CTAs of two warps: one warp in four of the frame's, i.e. one
/// warp of every other CTA, in a checkerboard over the tiles. The traced CTAs' work is the
/// stride-2 profile's (the same warp traced and doubled), each other CTA's the mean of its
/// traced neighbours; only the traced CTAs record BVH reads for the replay; the frame's rays
/// stay an estimate close to the exact count, the samples' CTAs are traced in full, and the
/// results are the same on any thread count.
#[test]
fn a_profile_stride_beyond_the_warps_of_a_cta_traces_every_other_cta() {
    let cfg_of = |stride: u32| {
        config(
            "baseline",
            128,
            "1/4x2",
            &[&format!("sample.profile_stride={stride}")],
        )
    };
    let (exact_cfg, half_cfg, quarter_cfg) = (cfg_of(1), cfg_of(2), cfg_of(4));
    let (scene, bvh) = setup("cornell", &exact_cfg);
    let exact = Profile::new(&scene, &bvh, &exact_cfg).unwrap();
    let half = Profile::new(&scene, &bvh, &half_cfg).unwrap();
    let quarter = Profile::new(&scene, &bvh, &quarter_cfg).unwrap();
    assert_eq!(quarter.stride, 4);
    // 128x128 in 8x8 tiles: 16 tiles a row.
    let tiles_x = 16;
    let traced = |c: usize| (c % tiles_x + c / tiles_x).is_multiple_of(2);
    let n = quarter.ctas.len();
    assert_eq!(n, 256);
    let mut estimated = 0;
    for c in 0..n {
        if traced(c) {
            assert_eq!(
                quarter.ctas[c], half.ctas[c],
                "CTA {c} traced as at stride 2"
            );
            continue;
        }
        assert!(quarter.cta_streams[c].is_empty(), "CTA {c} recorded reads");
        let (x, y) = ((c % tiles_x) as i64, (c / tiles_x) as i64);
        let around: Vec<usize> = [(-1, 0), (1, 0), (0, -1), (0, 1)]
            .iter()
            .map(|(dx, dy)| (x + dx, y + dy))
            .filter(|&(x, y)| (0..16).contains(&x) && (0..16).contains(&y))
            .map(|(x, y)| (y * 16 + x) as usize)
            .collect();
        let mean =
            around.iter().map(|&k| half.ctas[k].rays).sum::<u64>() as f64 / around.len() as f64;
        assert_eq!(quarter.ctas[c].rays, mean.round() as u64, "CTA {c}");
        estimated += 1;
    }
    assert_eq!(estimated, n / 2);
    let (re, rq) = (exact.work(None).rays as f64, quarter.work(None).rays as f64);
    assert!((rq / re - 1.0).abs() < 0.05, "{rq} vs {re}");
    // An untraced CTA traced in full is the exact profile's.
    let some: Vec<u32> = vec![1, 16, 101, 254];
    assert!(some.iter().all(|&c| !traced(c as usize)));
    let filled = quarter
        .with_exact(&scene, &bvh, &quarter_cfg, &some)
        .unwrap();
    for &c in &some {
        assert_eq!(filled[c as usize], exact.ctas[c as usize]);
    }
    let a = simulate_sampled(&scene, &bvh, &quarter_cfg, &quarter, 1).unwrap();
    let b = simulate_sampled(&scene, &bvh, &quarter_cfg, &quarter, 2).unwrap();
    assert_eq!(comparable(&a), comparable(&b));
    assert!(a.rays_estimated);
}
