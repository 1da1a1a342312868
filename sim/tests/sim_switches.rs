//! The modelling switches of docs/fidelity.md, each checked to change what it models and
//! nothing else: every switched run traces the same rays with the same closest hits and renders
//! the same image as the default, repeats exactly on any number of threads, and gives the same
//! statistics skipping idle cycles as in lockstep; then each switch's own effect is asserted.
//! Also the statistics added with them (DRAM queueing by class, CTA suspend timing, SM finish
//! cycles, miss-rate deciles, BVH summary).

mod common;

use common::{
    check_against_functional, check_deterministic, check_same_results, check_skip_matches_lockstep,
    run, setup, small_config, small_vtq,
};
use vtq_sim::model::bvh::TreeletFormation;
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::gpu::SimOutput;
use vtq_sim::model::memory::AccessClass;

/// The baseline with ray virtualization on one SM with two CTA slots and room for 16 CTAs'
/// rays, a `side` x `side` image, then `extra`: CTAs wait for slots to resume.
fn scarce_slots(side: u32, extra: &[&str]) -> SimConfig {
    let mut sets = vec![
        "mode.virtualization=true",
        "gpu.max_ctas_per_sm=2",
        "hw.max_rays=1024",
    ];
    sets.extend_from_slice(extra);
    small_config("baseline", 1, side, &sets)
}

/// The full design on `sms` SMs, a `side` x `side` image, then `extra`.
fn vtq(sms: u32, side: u32, extra: &[&str]) -> SimConfig {
    small_vtq(sms, side, extra)
}

/// Runs `a` and `b` on scene `name` and checks they traced the same rays with the same hits
/// and rendered the same image; returns both outputs.
fn same_results(name: &str, a: &SimConfig, b: &SimConfig) -> (SimOutput, SimOutput) {
    let (scene, bvh) = setup(name, a);
    let x = run(&scene, &bvh, a);
    let y = if a.bvh_params() == b.bvh_params() {
        run(&scene, &bvh, b)
    } else {
        let (scene, bvh) = setup(name, b);
        run(&scene, &bvh, b)
    };
    check_same_results(&x, &y);
    (x, y)
}

/// Without state traffic, CTAs still suspend and resume, but no CTA state moves and no cycle
/// is spent saving or restoring it.
#[test]
fn free_cta_state_moves_nothing_and_changes_only_timing() {
    let on = scarce_slots(48, &[]);
    let off = scarce_slots(48, &["virtualization.state_traffic=false"]);
    let (a, b) = same_results("wknd", &on, &off);
    assert!(a.stats.memory.cta_state.l1_bypasses > 0);
    assert!(a.stats.virtualization.save_cycles > 0);
    assert!(a.stats.virtualization.restore_cycles > 0);
    let s = &b.stats;
    assert!(s.cta_suspends > 0 && s.cta_suspends == s.cta_resumes);
    assert_eq!(s.memory.cta_state, Default::default());
    assert_eq!(
        (
            s.virtualization.save_cycles,
            s.virtualization.restore_cycles
        ),
        (0, 0)
    );
    assert_ne!(a.stats.cycles, s.cycles);
    check_skip_matches_lockstep(&off);
}

/// Restoring when ready loads the same state (same accesses per suspend and resume) but a CTA
/// that waited for a slot finds its state back: less restore latency while holding a slot. Long
/// shaders keep the two slots busy, so ready CTAs wait for them.
#[test]
fn restore_on_ready_overlaps_the_wait_for_a_slot() {
    let long = ["gpu.raygen_cycles=3000", "gpu.closest_hit_cycles=2000"];
    let slot = scarce_slots(48, &long);
    let ready = scarce_slots(48, &[long[0], long[1], "virtualization.restore=on_ready"]);
    let (a, b) = same_results("wknd", &slot, &ready);
    let per_cta = slot.cta_state_bytes().div_ceil(32);
    for o in [&a, &b] {
        let s = &o.stats;
        assert_eq!(
            s.memory.cta_state.l1_bypasses,
            (s.cta_suspends + s.cta_resumes) * per_cta
        );
    }
    assert!(
        a.stats.virtualization.resume_wait_cycles > 0,
        "CTAs waited for slots"
    );
    assert!(
        b.stats.virtualization.restore_cycles < a.stats.virtualization.restore_cycles,
        "on_ready {:?} against on_slot {:?}",
        b.stats.virtualization,
        a.stats.virtualization
    );
    check_skip_matches_lockstep(&ready);
}

/// Suspending on demand suspends only while a slot is wanted: fewer suspends (none once no CTA
/// is pending), each still saved and restored whole.
#[test]
fn on_demand_suspends_fewer_ctas() {
    let eager = scarce_slots(48, &[]);
    let demand = scarce_slots(48, &["virtualization.suspend=on_demand"]);
    let (a, b) = same_results("wknd", &eager, &demand);
    let s = &b.stats;
    assert!(s.cta_suspends > 0 && s.cta_suspends == s.cta_resumes);
    assert!(
        s.cta_suspends < a.stats.cta_suspends,
        "on_demand {} against eager {}",
        s.cta_suspends,
        a.stats.cta_suspends
    );
    let per_cta = demand.cta_state_bytes().div_ceil(32);
    assert_eq!(
        s.memory.cta_state.l1_bypasses,
        (s.cta_suspends + s.cta_resumes) * per_cta
    );
    check_skip_matches_lockstep(&demand);
}

/// The suspend and restore switches give the same results on any number of threads (the
/// on-demand policy reads the CTA scheduler's pending count, which the engine serves in cycle
/// order).
#[test]
fn virtualization_switches_are_deterministic_on_any_threads() {
    for extra in [
        "virtualization.suspend=on_demand",
        "virtualization.restore=on_ready",
    ] {
        let cfg = small_config(
            "baseline",
            3,
            32,
            &[
                "mode.virtualization=true",
                "gpu.max_ctas_per_sm=2",
                "hw.max_rays=1024",
                extra,
            ],
        );
        let out = check_deterministic(&cfg);
        assert!(out.stats.cta_suspends > 0, "{extra}");
    }
}

/// The virtualization switches are rejected without virtualization.
#[test]
fn virtualization_switches_need_virtualization() {
    for set in [
        "virtualization.suspend=on_demand",
        "virtualization.restore=on_ready",
        "virtualization.state_traffic=false",
    ] {
        let e = SimConfig::load(None, &[set.to_string()]).unwrap_err();
        assert!(e.to_string().contains("mode.virtualization"), "{set}: {e}");
    }
}

/// Queued rays' stacks moved through memory: the same rays and hits, every parked chunk stored
/// and loaded back (bypassing the L1), more bytes; nothing else of the design changes.
#[test]
fn queued_stack_traffic_adds_bytes_not_results() {
    let free = vtq(1, 32, &[]);
    let moved = vtq(1, 32, &["rt.queued_stack_traffic=true"]);
    check_against_functional("wknd", &moved);
    let (a, b) = same_results("wknd", &free, &moved);
    assert_eq!(a.stats.memory.ray_stack, Default::default());
    let st = &b.stats.memory.ray_stack;
    assert!(st.l1_bypasses > 0, "no queued stack moved");
    assert_eq!((st.l1_loads, st.l1_stores), (0, 0), "stacks bypass the L1");
    assert_eq!(st.l2_accesses, st.l1_bypasses);
    assert!(b.stats.queues.counts.ctl.enqueued_rays > 0);
    assert_eq!(
        st.l1_bypasses,
        b.stats.queues.stack_stores + b.stats.queues.stack_loads
    );
    assert_eq!(
        (a.stats.queues.stack_stores, a.stats.queues.stack_loads),
        (0, 0)
    );
    assert_ne!(a.stats.cycles, b.stats.cycles);
    check_skip_matches_lockstep(&vtq(1, 32, &["rt.queued_stack_traffic=true"]));
    // Only treelet queues park rays.
    let e = SimConfig::load(None, &["rt.queued_stack_traffic=true".to_string()]).unwrap_err();
    assert!(e.to_string().contains("rt.queued_stack_traffic"), "{e}");
}

/// Every chunk a parked ray stores is loaded once when the ray is taken out of its queue, so
/// at the end of a run the queued-stack stores and loads balance; on any number of threads.
#[test]
fn queued_stack_stores_and_loads_balance() {
    let cfg = vtq(2, 32, &["rt.queued_stack_traffic=true"]);
    let out = check_deterministic(&cfg);
    let q = &out.stats.queues;
    assert!(q.stack_stores > 0);
    assert_eq!(q.stack_stores, q.stack_loads);
    assert_eq!(q.counts.ray_loads, q.counts.ctl.enqueued_rays);
}

/// Packed treelets: fewer, fuller treelets; the same hits and image in every design.
#[test]
fn packed_treelets_are_fuller_and_change_no_result() {
    for mode in ["baseline", "vtq"] {
        let (bf, packed) = if mode == "vtq" {
            (
                vtq(1, 32, &[]),
                vtq(1, 32, &["bvh.treelet_formation=packed"]),
            )
        } else {
            (
                small_config("baseline", 1, 32, &[]),
                small_config("baseline", 1, 32, &["bvh.treelet_formation=packed"]),
            )
        };
        assert_eq!(packed.bvh_params().formation, TreeletFormation::Packed);
        check_against_functional("wknd", &packed);
        let (a, b) = same_results("wknd", &bf, &packed);
        if mode == "vtq" {
            // Treelet preloads are prefetches: counted, they change the miss rate.
            let m = &a.stats.memory.prefetch;
            assert!(m.requests > 0);
            let s = &a.stats;
            let with =
                (s.bvh_l1_misses + m.issued) as f64 / (s.bvh_l1_accesses + m.requests) as f64;
            assert_eq!(s.bvh_l1_miss_rate_with_prefetches, with);
            assert_eq!(s.bvh_l1_miss_rate_deciles_with_prefetches.len(), 10);
        }
        assert!(b.stats.bvh.treelets < a.stats.bvh.treelets, "{mode}");
        assert!(
            b.stats.bvh.treelet_fill > a.stats.bvh.treelet_fill,
            "{mode}"
        );
        assert_eq!(b.stats.bvh.bvh_bytes, a.stats.bvh.bvh_bytes, "{mode}");
    }
    check_skip_matches_lockstep(&vtq(1, 32, &["bvh.treelet_formation=packed"]));
}

/// DRAM channels change when transfers start, not what is transferred: the same results, the
/// traffic equal up to what the changed timing changes second hand (which accesses merge with a
/// fill still in flight), different queueing.
#[test]
fn dram_channels_change_queueing_not_traffic() {
    let starved = ["memory.dram_bytes_per_cycle=16", "memory.l2_bytes=4096"];
    let one = small_config("baseline", 2, 32, &starved);
    let mut sets = starved.to_vec();
    sets.push("memory.dram_channels=4");
    let four = small_config("baseline", 2, 32, &sets);
    let (a, b) = same_results("wknd", &one, &four);
    let (x, y) = (a.stats.dram_bytes as f64, b.stats.dram_bytes as f64);
    assert!((x - y).abs() <= 0.02 * x, "DRAM bytes {x} and {y}");
    assert_ne!(
        a.stats.memory.dram.queue_cycles,
        b.stats.memory.dram.queue_cycles
    );
    check_skip_matches_lockstep(&four);
}

/// The statistics added for docs/fidelity.md are consistent with the others.
#[test]
fn fidelity_statistics_are_consistent() {
    let cfg = scarce_slots(
        48,
        &["memory.dram_bytes_per_cycle=16", "memory.l2_bytes=4096"],
    );
    let (scene, bvh) = setup("wknd", &cfg);
    let out = run(&scene, &bvh, &cfg);
    let s = &out.stats;
    // DRAM queueing: the reads' by class plus the writes' make the total.
    let reads: u64 = AccessClass::ALL
        .iter()
        .map(|&c| s.memory.class(c).dram_queue_cycles)
        .sum();
    assert_eq!(
        reads + s.memory.dram.write_queue_cycles,
        s.memory.dram.queue_cycles
    );
    assert!(s.memory.dram.queue_cycles > 0);
    // Saving a CTA's 82 accesses takes at least 81 cycles after the first one.
    let per_cta = cfg.cta_state_bytes().div_ceil(32);
    assert!(s.virtualization.save_cycles >= s.cta_suspends * (per_cta - 1));
    // The last SM to finish ends the run.
    assert_eq!(s.sm_finish_cycles.len(), cfg.gpu.sms as usize);
    assert_eq!(s.sm_finish_cycles.iter().max(), Some(&s.cycles));
    // The deciles aggregate the time series.
    assert_eq!(s.bvh_l1_miss_rate_deciles.len(), 10);
    let n = out.time_series.len();
    let first_decile: Vec<_> = out
        .time_series
        .iter()
        .filter(|t| (t.cycle - 500) * 10 < s.cycles)
        .collect();
    assert!(!first_decile.is_empty() && first_decile.len() < n);
    let (m, a) = first_decile.iter().fold((0, 0), |(m, a), t| {
        (m + t.bvh_l1_misses, a + t.bvh_l1_accesses)
    });
    assert_eq!(s.bvh_l1_miss_rate_deciles[0], m as f64 / a as f64);
    // Without prefetches, counting them changes nothing.
    assert_eq!(s.bvh_l1_miss_rate_with_prefetches, s.bvh_l1_miss_rate);
    assert_eq!(
        s.bvh_l1_miss_rate_deciles_with_prefetches,
        s.bvh_l1_miss_rate_deciles
    );
    // The BVH summary is the BVH's.
    assert_eq!(s.bvh, bvh.stats());
    // Without a time series there are no deciles; without virtualization no suspend timing.
    let plain = small_config("baseline", 1, 16, &["sim.sample_interval=0"]);
    let (scene, bvh) = setup("wknd", &plain);
    let out = run(&scene, &bvh, &plain);
    assert!(out.stats.bvh_l1_miss_rate_deciles.is_empty());
    assert_eq!(out.stats.virtualization, Default::default());
}

/// SM warps kept out of the treelet-stationary mode (`mode.admit_in_treelet_stationary =
/// false`): the same rays, hits and image; in that mode the RT unit then tests fewer nodes for
/// warps other than treelet warps; exact skipping idle cycles and on any threads; only treelet
/// queues take the switch.
#[test]
fn sm_warps_kept_out_of_treelet_mode_change_only_timing() {
    let admit = vtq(1, 32, &[]);
    let keep_out = vtq(1, 32, &["mode.admit_in_treelet_stationary=false"]);
    check_against_functional("wknd", &keep_out);
    let (a, b) = same_results("wknd", &admit, &keep_out);
    // Tests made in treelet-stationary mode by warps not in treelet-stop order.
    let others = |o: &SimOutput| {
        let ts = o.stats.phases.treelet_stationary.intersection_tests;
        ts.saturating_sub(o.stats.rt.treelet_order_tests)
    };
    assert!(a.stats.rt.treelet_order_tests > 0);
    assert!(
        others(&b) < others(&a),
        "keeping SM warps out leaves fewer other warps' tests in treelet-stationary mode"
    );
    assert_ne!(a.stats.cycles, b.stats.cycles);
    check_skip_matches_lockstep(&keep_out);
    check_deterministic(&vtq(2, 32, &["mode.admit_in_treelet_stationary=false"]));
    let e = SimConfig::load(
        None,
        &["mode.admit_in_treelet_stationary=false".to_string()],
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("mode.admit_in_treelet_stationary"),
        "{e}"
    );
}

/// The tail after the last CTA dispatch: it starts at the first sample boundary at or after
/// the last CTA's dispatch (its first trace less launch and raygen), counts part of the RT
/// units' warp cycles, and is the same skipping idle cycles as in lockstep and on any threads;
/// without samples it counts nothing.
#[test]
fn the_tail_after_the_last_dispatch_is_counted_from_the_samples() {
    // One SM with two CTA slots: CTAs are dispatched one after another over the run.
    let cfg = small_config(
        "baseline",
        1,
        32,
        &["gpu.max_ctas_per_sm=2", "sim.sample_interval=100"],
    );
    let (scene, bvh) = setup("wknd", &cfg);
    let out = run(&scene, &bvh, &cfg);
    let (s, t) = (&out.stats, &out.stats.tail);
    let lead = cfg.gpu.cta_launch_cycles as u64;
    let last_start = out.cta_spans[0].iter().map(|c| c.start).max().unwrap();
    assert!(t.last_dispatch > 0 && t.last_dispatch + lead <= last_start);
    assert_eq!(t.from_cycle, t.last_dispatch.div_ceil(100) * 100);
    assert_eq!(t.cycles, s.cycles - t.from_cycle);
    assert!(t.warp_cycles > 0 && t.warp_cycles < s.rt.warp_cycles);
    assert!(t.active_thread_cycles <= t.warp_cycles * cfg.hw.warp_size as u64);
    check_skip_matches_lockstep(&cfg);
    check_deterministic(&cfg);
    let none = small_config(
        "baseline",
        1,
        32,
        &["gpu.max_ctas_per_sm=2", "sim.sample_interval=0"],
    );
    let (scene, bvh) = setup("wknd", &none);
    let t = run(&scene, &bvh, &none).stats.tail;
    assert_eq!((t.cycles, t.warp_cycles, t.from_cycle), (0, 0, s.cycles));
}

/// Ray records held on chip (`rt.ray_record_latency`): the same rays, hits and image; no ray
/// record reaches the memory system, every queued ray is still loaded once; records nearer than
/// the L2 make the fills and the run shorter here; exact skipping idle cycles and on any
/// threads; only treelet queues take the key.
#[test]
fn on_chip_ray_records_move_no_memory_and_change_only_timing() {
    let memory = vtq(1, 32, &[]);
    let on_chip = vtq(1, 32, &["rt.ray_record_latency=4"]);
    check_against_functional("wknd", &on_chip);
    let (a, b) = same_results("wknd", &memory, &on_chip);
    assert!(a.stats.memory.ray_record.l1_bypasses > 0);
    assert_eq!(b.stats.memory.ray_record, Default::default());
    let q = &b.stats.queues.counts;
    assert!(q.ray_loads > 0);
    assert_eq!(
        q.ray_loads, q.ctl.enqueued_rays,
        "every queued ray is loaded once"
    );
    assert!(
        b.stats.cycles < a.stats.cycles,
        "records 4 cycles away fill warps sooner"
    );
    check_skip_matches_lockstep(&on_chip);
    check_deterministic(&vtq(2, 32, &["rt.ray_record_latency=4"]));
    let e = SimConfig::load(None, &["rt.ray_record_latency=4".to_string()]).unwrap_err();
    assert!(e.to_string().contains("rt.ray_record_latency"), "{e}");
}

/// The per-phase, per-warp-kind costs (`warp_costs`) partition the RT units' counters: the
/// cells' tests, warp cycles and BVH loads add up to the run's; treelet warps appear only in
/// treelet-stationary mode and grouped warps only in the final phase; a design without treelet
/// queues has none; skipping idle cycles counts them as lockstep does.
#[test]
fn warp_costs_partition_the_rt_units_work() {
    let out = check_deterministic(&vtq(2, 32, &[]));
    let s = &out.stats;
    let w = s
        .warp_costs
        .as_ref()
        .expect("queues mode reports warp costs");
    let phases = [&w.initial, &w.treelet_stationary, &w.ray_stationary];
    let cells: Vec<_> = phases
        .iter()
        .flat_map(|p| [p.sm, p.treelet, p.grouped])
        .collect();
    let sum = |f: &dyn Fn(&vtq_sim::model::gpu::rt::warp_costs::CostReport) -> u64| {
        cells.iter().map(f).sum::<u64>()
    };
    assert_eq!(sum(&|c| c.intersection_tests), s.rt.total_tests());
    assert_eq!(sum(&|c| c.warp_cycles), s.rt.warp_cycles);
    assert_eq!(sum(&|c| c.bvh_l1_accesses), s.bvh_l1_accesses);
    assert_eq!(sum(&|c| c.ray_record_loads), s.queues.counts.ray_loads);
    assert_eq!(
        sum(&|c| c.rays_in),
        s.rays_issued + s.queues.counts.ray_loads,
        "every SM ray and every loaded ray enters a warp once"
    );
    for p in [&w.initial, &w.ray_stationary] {
        assert_eq!(
            p.treelet.warp_cycles, 0,
            "treelet warps only in treelet mode"
        );
    }
    for p in [&w.initial, &w.treelet_stationary] {
        assert_eq!(
            p.grouped.warp_cycles, 0,
            "grouped warps only in the final phase"
        );
    }
    assert!(w.treelet_stationary.treelet.intersection_tests > 0);
    assert!(w.ray_stationary.grouped.intersection_tests > 0);
    assert!(w.treelet_stationary.treelet.queue_wait_cycles_per_ray > 0.0);
    let cfg = small_config("baseline", 1, 16, &[]);
    let (scene, bvh) = setup("wknd", &cfg);
    assert!(run(&scene, &bvh, &cfg).stats.warp_costs.is_none());
}
