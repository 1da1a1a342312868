//! Real traffic against the generated RTL: the input ports of one SM's treelet count table,
//! treelet queue table, treelet controller and RT unit, recorded cycle by cycle in a simulation
//! of the VTQ design (with tables small enough to evict and spill), replayed as a Verilog
//! testbench against the blocks' RTL: every output must match the Rust block's in every cycle.

mod common;

use common::{setup, small_config};
use vtq_gen::cosim::{
    datapath_tables, record, run_cosim, tests_and_hits, CosimOptions, RtUnitReplay,
};
use vtq_gen::rtl::{
    controller_verilog, count_table_verilog, queue_table_verilog, rt_unit_replay_verilog,
};
use vtq_gen::tools::or_skip;
use vtq_hdl::controller::TreeletController;
use vtq_hdl::count_table::{CountOp, CountTable};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{QueueOp, QueueTable};
use vtq_hdl::Block;
use vtq_sim::model::gpu::datapath::BvhDatapath;
use vtq_sim::model::gpu::{simulate, SimOptions};

#[test]
fn a_real_runs_table_traffic_matches_the_rtl() {
    let cfg = small_config(
        "queues",
        2,
        32,
        &[
            "mode.virtualization=true",
            "mode.grouping=true",
            "mode.preload=true",
            "hw.divergence_threshold=2",
            "hw.underpopulation_threshold=8",
            "hw.count_table_entries=2",
            "hw.queue_table_entries=2",
        ],
    );
    let (scene, bvh) = setup("cornell", &cfg);
    let options = SimOptions {
        record_tables: Some((0, 30_000)),
        ..SimOptions::default()
    };
    let out = simulate(&scene, &bvh, &cfg, options, None).expect("simulation runs");
    let log = out.table_log.expect("tables recorded");
    assert!(!log.count.is_empty());
    let adds = log
        .count
        .iter()
        .filter(|i| matches!(i.op, CountOp::Add { .. }))
        .count();
    let refills = log.queue.iter().filter(|i| i.refill_valid).count();
    let pops = log
        .queue
        .iter()
        .filter(|i| matches!(i.op, QueueOp::Pop { .. } | QueueOp::PopAny))
        .count();
    assert!(
        adds > 50 && pops > 5 && refills > 0,
        "{adds} adds, {pops} pops, {refills} refills"
    );
    // The controller's inputs from reset, every cycle; replayed on the Rust block they take it
    // through the treelet-stationary and final ray-stationary phases.
    assert_eq!(log.controller.len(), 30_000.min(out.stats.cycles as usize));
    let features = cfg.controller_features();
    let ctl = TreeletController::new(cfg.hw.clone(), features).unwrap();
    let mut regs = ctl.reset();
    let mut seen = [false; 4];
    for i in &log.controller {
        seen[ctl.step(&mut regs, i).mode as usize] = true;
    }
    assert!(
        seen[Mode::TreeletStationary as usize] && seen[Mode::FinalRayStationary as usize],
        "modes seen: {seen:?}"
    );
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-replay-rtl");
    let count = CountTable::new(&cfg.hw).unwrap();
    let queue = QueueTable::new(&cfg.hw).unwrap();
    let jobs = [
        (
            record(&count, log.count.iter().copied()).unwrap(),
            count_table_verilog(&cfg.hw).unwrap(),
        ),
        (
            record(&queue, log.queue.iter().copied()).unwrap(),
            queue_table_verilog(&cfg.hw).unwrap(),
        ),
        (
            record(&ctl, log.controller.iter().cloned()).unwrap(),
            controller_verilog(&cfg.hw, features).unwrap(),
        ),
    ];
    for (trace, verilog) in jobs {
        let work = dir.join(&trace.module);
        std::fs::create_dir_all(&work).unwrap();
        let source = work.join(format!("{}.v", trace.module));
        std::fs::write(&source, verilog).unwrap();
        let Some(result) =
            or_skip(run_cosim(&trace, &[source], &CosimOptions::icarus(&work))).unwrap()
        else {
            return;
        };
        assert_eq!(result.cycles, trace.cycles() as u64, "{}", trace.module);
        assert_eq!(
            result.mismatches, 0,
            "{}: {:?}",
            trace.module, result.reported
        );
    }
}

/// The RT unit's input ports on SM 0 of a VTQ run, from reset, replayed against its RTL with the
/// scene's datapath: the datapath's tests run once in Rust with the real BVH and are answered
/// from their results on both sides ([`RtUnitReplay`]); every output and status port must
/// match in every cycle. Short (Icarus runs a 32-lane RT unit at about 50 cycles a second);
/// `vtq cosim --block rt-unit --scene` replays longer runs, under Verilator.
#[test]
fn a_real_runs_rt_unit_traffic_matches_the_rtl() {
    const CYCLES: usize = 3000;
    let cfg = small_config(
        "queues",
        2,
        32,
        &[
            "mode.virtualization=true",
            "mode.grouping=true",
            "hw.divergence_threshold=2",
            "hw.underpopulation_threshold=8",
        ],
    );
    let (scene, bvh) = setup("cornell", &cfg);
    let options = SimOptions {
        record_tables: Some((0, CYCLES)),
        ..SimOptions::default()
    };
    let out = simulate(&scene, &bvh, &cfg, options, None).expect("simulation runs");
    let log = out.table_log.expect("inputs recorded");
    assert_eq!(log.rt_unit.len(), CYCLES);
    // The recorded inputs replayed on the Rust RT unit with the scene's datapath: warps run
    // and complete.
    let tables = datapath_tables(
        &cfg.hw,
        &log.rt_params,
        BvhDatapath::new(&bvh),
        &log.rt_unit,
    )
    .unwrap();
    let (tests, hits) = tests_and_hits(&tables);
    let issued = log.rt_unit.iter().filter(|i| i.issue.is_some()).count();
    eprintln!("{issued} warps issued, {tests} tests, {hits} hits in {CYCLES} cycles");
    assert!(
        issued >= 2 && tests > 200 && hits > 10,
        "{issued} warps, {tests} tests, {hits} hits"
    );
    let unit = RtUnitReplay::new(&cfg.hw, &log.rt_params).unwrap();
    let trace = record(&unit, unit.inputs(log.rt_unit, tables)).unwrap();
    assert_eq!(unit.misses(), 0);
    let work = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-replay-rt-unit");
    std::fs::create_dir_all(&work).unwrap();
    let mut files = Vec::new();
    for (module, text) in rt_unit_replay_verilog(&cfg.hw, &log.rt_params).unwrap() {
        let path = work.join(format!("{module}.v"));
        std::fs::write(&path, text).unwrap();
        files.push(path);
    }
    let Some(result) = or_skip(run_cosim(&trace, &files, &CosimOptions::icarus(&work))).unwrap()
    else {
        return;
    };
    assert_eq!(result.cycles, CYCLES as u64);
    assert_eq!(result.mismatches, 0, "{:?}", result.reported);
}
