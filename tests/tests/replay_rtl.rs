//! Real traffic against the generated RTL: the input ports of one SM's treelet count table,
//! treelet queue table, treelet controller and RT unit, recorded cycle by cycle in a simulation
//! of the VTQ design (with tables small enough to evict and spill), replayed as a Verilog
//! testbench against the blocks' RTL: every output must match the Rust block's in every cycle.
//! The whole treelet RT unit's recorded inputs replay the run on the Rust side, and its wiring's
//! ports in that run replay against the wiring's RTL.

// The simulator tests' helpers (a small GPU configuration, a built-in scene and its BVH).
#[path = "../../sim/tests/common/mod.rs"]
mod common;

use common::{setup, small_config};
use vtq_gen::cosim::{
    datapath_tables, record, record_with_registers, run_cosim, tests_and_hits, wiring_ports,
    CosimOptions, DatapathCall, RtUnitReplay, Trace, TreeletRtUnitReplay, TreeletWiring,
};
use vtq_gen::rtl::{
    controller_verilog, count_table_verilog, queue_table_verilog, rt_unit_replay_verilog,
    treelet_rt_unit_replay_verilog, treelet_wiring_verilog,
};
use vtq_gen::tools::or_skip;
use vtq_hdl::controller::TreeletController;
use vtq_hdl::count_table::{CountOp, CountTable};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{QueueOp, QueueTable};
use vtq_hdl::treelet_rt_unit::{TableLog, TreeletRtUnit};
use vtq_hdl::{Block, Cached};
use vtq_sim::model::bvh::HwBvh;
use vtq_sim::model::config::SimConfig;
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
    // Clears: waves of rays that ended with counts of grouped warps' rays in the table.
    let clears = log.count.iter().filter(|i| i.op == CountOp::Clear).count();
    assert!(
        adds > 50 && pops > 5 && refills > 0 && clears > 0,
        "{adds} adds, {pops} pops, {refills} refills, {clears} clears"
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

/// SM 0's recorded inputs of the first `cycles` cycles of a cornell VTQ run (32x32 pixels, two
/// SMs, a low divergence threshold), with its configuration, the scene's BVH and the datapath
/// tests of the RT unit's recorded inputs ([`datapath_tables`]).
fn recorded_vtq_run(cycles: usize) -> (SimConfig, HwBvh, TableLog, Vec<Vec<DatapathCall>>) {
    recorded_run(cycles, &[])
}

/// [`recorded_vtq_run`] with more settings `extra`.
fn recorded_run(
    cycles: usize,
    extra: &[&str],
) -> (SimConfig, HwBvh, TableLog, Vec<Vec<DatapathCall>>) {
    let mut settings = vec![
        "mode.virtualization=true",
        "mode.grouping=true",
        "hw.divergence_threshold=2",
        "hw.underpopulation_threshold=8",
    ];
    settings.extend_from_slice(extra);
    let cfg = small_config("queues", 2, 32, &settings);
    let (scene, bvh) = setup("cornell", &cfg);
    let options = SimOptions {
        record_tables: Some((0, cycles)),
        ..SimOptions::default()
    };
    let out = simulate(&scene, &bvh, &cfg, options, None).expect("simulation runs");
    let log = out.table_log.expect("inputs recorded");
    let datapath = BvhDatapath::new(&bvh);
    let tables = datapath_tables(&cfg.hw, &log.params.rt, datapath, &log.rt_unit).unwrap();
    (cfg, bvh, log, tables)
}

/// The RT unit's input ports on SM 0 of a VTQ run, from reset, replayed against its RTL with the
/// scene's datapath: the datapath's tests run once in Rust with the real BVH and are answered
/// from their results on both sides ([`RtUnitReplay`]); every output and status port, and
/// every register of the RT unit, must match in every cycle. Short (Icarus runs a 32-lane RT unit at about 50 cycles a second);
/// `vtq cosim --block rt-unit --scene` replays longer runs.
#[test]
fn a_real_runs_rt_unit_traffic_matches_the_rtl() {
    const CYCLES: usize = 3000;
    let (cfg, _, log, tables) = recorded_vtq_run(CYCLES);
    assert_eq!(log.rt_unit.len(), CYCLES);
    // The recorded inputs replayed on the Rust RT unit with the scene's datapath: warps run
    // and complete.
    let (tests, hits) = tests_and_hits(&tables);
    let issued = log.rt_unit.iter().filter(|i| i.issue.is_some()).count();
    eprintln!("{issued} warps issued, {tests} tests, {hits} hits in {CYCLES} cycles");
    assert!(
        issued >= 2 && tests > 200 && hits > 10,
        "{issued} warps, {tests} tests, {hits} hits"
    );
    let unit = RtUnitReplay::new(&cfg.hw, &log.params.rt).unwrap();
    let trace =
        record_with_registers(&unit, unit.inputs(log.rt_unit, tables), unit.registers()).unwrap();
    assert_eq!(unit.misses(), 0);
    assert!(trace.registers.len() > 50, "{}", trace.registers.len());
    let work = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-replay-rt-unit");
    std::fs::create_dir_all(&work).unwrap();
    let mut files = Vec::new();
    for (module, text) in rt_unit_replay_verilog(&cfg.hw, &log.params.rt).unwrap() {
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

/// The whole treelet RT unit's input ports on SM 0 of a VTQ run, from reset, replay the run:
/// stepped on a fresh block with the scene's datapath they reproduce the RT unit's and the
/// controller's recorded inputs cycle for cycle (skipped idle cycles recorded as idle inputs),
/// and the block whose RT unit answers from the datapath tables of the RT unit's recorded
/// inputs ([`TreeletRtUnitReplay`], what the composed RTL's co-simulation will run) gives the
/// outputs of the block with the real datapath in every cycle, every port encoded.
#[test]
fn a_real_runs_treelet_rt_unit_inputs_replay_the_run() {
    const CYCLES: usize = 10_000;
    let (cfg, bvh, log, tables) = recorded_vtq_run(CYCLES);
    assert_eq!(log.treelet.len(), CYCLES);
    let accepted = log.treelet.iter().filter(|i| i.sm_warp.is_some()).count();
    let responses: usize = log.treelet.iter().map(|i| i.responses.len()).sum();
    eprintln!("{accepted} warps offered, {responses} responses in {CYCLES} cycles");
    assert!(
        accepted >= 4 && responses > 100,
        "{accepted} warps offered, {responses} responses"
    );
    // Stepped again from reset, the block sees what it saw in the run.
    let unit =
        TreeletRtUnit::new(cfg.hw.clone(), log.params.clone(), BvhDatapath::new(&bvh)).unwrap();
    let mut regs = unit.reset();
    let mut cache = unit.cache(&regs);
    cache.record_tables(CYCLES, log.params.clone());
    for inputs in &log.treelet {
        unit.step_cached(&mut regs, &mut cache, inputs);
    }
    let again = cache.take_table_log().unwrap();
    assert!(again.rt_unit == log.rt_unit, "the RT unit's inputs differ");
    assert!(
        again.controller == log.controller,
        "the controller's inputs differ"
    );
    // The replay block answers from the RT unit's tables and gives the real datapath's outputs.
    let replay = TreeletRtUnitReplay::new(&cfg.hw, &log.params).unwrap();
    let trace = record(&replay, replay.inputs(log.treelet.clone(), tables)).unwrap();
    assert_eq!(replay.misses(), 0);
    let plain = record(&unit, log.treelet).unwrap();
    let outputs =
        |t: &Trace| -> Vec<Vec<u64>> { t.rows().map(|r| r[t.inputs.len()..].to_vec()).collect() };
    assert_eq!(trace.outputs, plain.outputs);
    let (a, b) = (outputs(&trace), outputs(&plain));
    assert_eq!(a.len(), CYCLES);
    assert!(
        a == b,
        "the replay's outputs differ from the real datapath's"
    );
    // The run did something the ports show: rays accepted, records stored, requests out.
    let column = |name: &str| {
        let k = trace.outputs.iter().position(|s| s.name == name).unwrap();
        a.iter().map(|r| r[k]).sum::<u64>()
    };
    assert!(column("sm_accept") >= 2 && column("ray_store_count") >= 32);
    assert!(column("mem_req_valid") > 100 && column("count_rt_tests_internal") > 100);
}

/// Settings of a run with 8-lane warps on a 16 x 16 image (beside [`recorded_run`]'s): small
/// treelets and a low divergence threshold, so one SM's first 26,000 cycles reach the final
/// phase's first repack.
const EIGHT_LANES: [&str; 8] = [
    "hw.treelet_bytes=1024",
    "hw.divergence_threshold=1",
    "hw.warp_size=8",
    "gpu.warp_size=8",
    "gpu.max_ctas_per_sm=4",
    "hw.repack_threshold=6",
    "width=16",
    "height=16",
];

/// The treelet RT unit's wiring against its RTL on a real run: the wiring's ports (the block's
/// inputs and its children's outputs in, the block's outputs and its children's inputs out)
/// in every cycle of the block's definition stepped over SM 0's recorded inputs, replayed
/// against `treelet_rt_unit_wiring` alone; every output must match in every cycle
/// (`TreeletWiring`, the wiring from its ports alone, records what the RTL must drive). A warp
/// of 8 lanes on a 16 x 16 image, so Icarus runs the 26,000 cycles (which reach the final
/// phase's first repack) in about two minutes. A deliberately broken line of the RTL must be
/// caught.
#[test]
fn a_real_runs_wiring_ports_match_the_wiring_rtl() {
    const CYCLES: usize = 26_000;
    // Two record ports (the composed block's replay below has the default one), so both
    // widths of the ray-record crossbar are co-simulated; records held on chip, so a fill's
    // records return together and use both; 256 ray ids (the fewest the CTA slots allow), so
    // admitted warps take ids given back through the free-id stack.
    let mut settings = EIGHT_LANES.to_vec();
    settings.extend([
        "hw.record_bytes_per_cycle=64",
        "rt.ray_record_latency=20",
        "hw.max_rays=256",
    ]);
    let (cfg, bvh, log, _) = recorded_run(CYCLES, &settings);
    assert_eq!(cfg.hw.record_ports(), 2);
    let unit =
        TreeletRtUnit::new(cfg.hw.clone(), log.params.clone(), BvhDatapath::new(&bvh)).unwrap();
    let ports = wiring_ports(&unit, log.treelet);
    let wiring = TreeletWiring::new(&unit);
    let trace = record(&wiring, ports.iter().cloned()).unwrap();
    // The run exercised the wiring: warps admitted, records loaded for fills, fills issued,
    // rays finished and parked, warps repacked.
    let column = |name: &str| {
        let k = (trace.inputs.iter().chain(&trace.outputs))
            .position(|s| s.name == name)
            .unwrap_or_else(|| panic!("no signal {name}"));
        trace.rows().map(|r| r[k]).sum::<u64>()
    };
    let seen: Vec<(&str, u64)> = [
        "sm_accept",
        "ray_load_count",
        "ray_count",
        "finished_count",
        "parked_count",
        "rt_issue_valid",
        "rt_write_valid",
        "rt_issue_written",
        "rt_released_valid",
        "ctl_repack_valid",
        "ctl_enq_valid",
        "ctl_warp_done_valid",
    ]
    .into_iter()
    .map(|name| (name, column(name)))
    .collect();
    eprintln!("{seen:?}");
    assert!(seen.iter().all(|&(_, n)| n > 0), "{seen:?}");
    let k = (trace.inputs.iter().position(|s| s.name == "ray_count")).expect("a ray_count port");
    let both = trace.rows().filter(|r| r[k] == 2).count();
    assert!(both > 0, "no cycle used both record ports");
    // Admitted warps' ids include ids given out before: popped from the free-id stack.
    let at = |name: &str| {
        (trace.inputs.iter().chain(&trace.outputs))
            .position(|s| s.name == name)
            .unwrap()
    };
    let (accept, active) = (at("sm_accept"), at("sm_active"));
    let ids: Vec<usize> = (0..8).map(|l| at(&format!("sm_ray_id_{l}"))).collect();
    let mut given = std::collections::HashSet::new();
    let mut again = 0;
    for r in trace.rows().filter(|r| r[accept] == 1) {
        for l in (0..8).filter(|l| r[active] >> l & 1 == 1) {
            again += usize::from(!given.insert(r[ids[l]]));
        }
    }
    assert!(again > 0, "no admitted ray took an id given back");
    let work = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-replay-wiring");
    std::fs::create_dir_all(&work).unwrap();
    let rtl = treelet_wiring_verilog(&unit).unwrap();
    let path = work.join("treelet_rt_unit_wiring.v");
    std::fs::write(&path, &rtl).unwrap();
    let Some(result) = or_skip(run_cosim(
        &trace,
        std::slice::from_ref(&path),
        &CosimOptions::icarus(&work),
    ))
    .unwrap() else {
        return;
    };
    assert_eq!(result.cycles, CYCLES as u64);
    assert_eq!(result.mismatches, 0, "{:?}", result.reported);
    // The check can fail: an admitted warp's fresh ids one too high.
    let line = "id_fresh = id_fresh32 + k - id_top;";
    assert!(rtl.contains(line));
    std::fs::write(&path, rtl.replace(line, &line.replace("+ k", "+ k + 1"))).unwrap();
    let short = record(&wiring, ports.iter().take(1000).cloned()).unwrap();
    let broken = run_cosim(
        &short,
        std::slice::from_ref(&path),
        &CosimOptions::icarus(&work),
    )
    .unwrap();
    assert!(broken.mismatches > 0, "a broken line went unnoticed");
    assert!(broken
        .reported
        .iter()
        .any(|m| m.signal.starts_with("sm_ray_id")));
    // The event FIFO drains as fast as the run fills it, so appends behind two or more events
    // are rare: the controller's `enq_ready` held low 60 cycles in every 120 of the run's first
    // 8,000 lets events pile up. The RTL matches on those ports too, and the appends placed as
    // if the count were 0 or 1 (the shift network's later stages skipped) are caught.
    let held: Vec<_> = ports
        .iter()
        .take(8_000)
        .enumerate()
        .map(|(i, p)| {
            let mut p = p.clone();
            p.ctl.enq_ready &= i % 120 < 60;
            p
        })
        .collect();
    let held = record(&wiring, held).unwrap();
    std::fs::write(&path, &rtl).unwrap();
    let good = run_cosim(
        &held,
        std::slice::from_ref(&path),
        &CosimOptions::icarus(&work),
    )
    .unwrap();
    assert_eq!(good.mismatches, 0, "{:?}", good.reported);
    let shift = "if (cnt[j]) begin";
    assert_eq!(rtl.matches(shift).count(), 1);
    std::fs::write(&path, rtl.replace(shift, "if (cnt[j] && j == 0) begin")).unwrap();
    let broken = run_cosim(&held, &[path], &CosimOptions::icarus(&work)).unwrap();
    assert!(
        broken.mismatches > 0,
        "a broken event-FIFO shift went unnoticed"
    );
}

/// The wiring against its RTL with two warp-buffer slots and two record ports: fills of both
/// slots load at once, their records written into the RT unit's lanes as they arrive (one
/// slot's a cycle).
#[test]
fn a_two_slot_runs_wiring_ports_match_the_wiring_rtl() {
    const CYCLES: usize = 12_000;
    let mut settings = EIGHT_LANES.to_vec();
    settings.extend(["hw.record_bytes_per_cycle=64", "hw.warp_buffer_size=2"]);
    let (cfg, bvh, log, _) = recorded_run(CYCLES, &settings);
    let unit =
        TreeletRtUnit::new(cfg.hw.clone(), log.params.clone(), BvhDatapath::new(&bvh)).unwrap();
    let ports = wiring_ports(&unit, log.treelet);
    let wiring = TreeletWiring::new(&unit);
    let trace = record(&wiring, ports.iter().cloned()).unwrap();
    let at = |name: &str| {
        (trace.inputs.iter().chain(&trace.outputs))
            .position(|s| s.name == name)
            .unwrap_or_else(|| panic!("no signal {name}"))
    };
    let (write, slot, written) = (
        at("rt_write_valid"),
        at("rt_write_slot"),
        at("rt_issue_written"),
    );
    let writes = |s: u64| {
        (trace.rows())
            .filter(|r| r[write] == 1 && r[slot] == s)
            .count()
    };
    let woken = trace.rows().filter(|r| r[written] != 0).count();
    eprintln!(
        "writes to slot 0 {}, to slot 1 {}, issues of written lanes {woken}",
        writes(0),
        writes(1)
    );
    assert!(writes(0) > 0 && writes(1) > 0 && woken > 0);
    let work = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-replay-wiring2");
    std::fs::create_dir_all(&work).unwrap();
    let path = work.join("treelet_rt_unit_wiring.v");
    std::fs::write(&path, treelet_wiring_verilog(&unit).unwrap()).unwrap();
    let Some(result) = or_skip(run_cosim(&trace, &[path], &CosimOptions::icarus(&work))).unwrap()
    else {
        return;
    };
    assert_eq!(result.cycles, CYCLES as u64);
    assert_eq!(result.mismatches, 0, "{:?}", result.reported);
}

/// The whole treelet RT unit against its composed RTL on a real run: SM 0's recorded input
/// ports replayed from reset against `treelet_rt_unit` (both tables, the controller, the RT
/// unit and the wiring, connected port by port) in the replay wrapper whose datapath answers
/// from the run's recorded tests ([`TreeletRtUnitReplay`] on the Rust side); every output of
/// the block and every register of its children and its wiring must match in every cycle.
#[test]
fn a_real_runs_treelet_rt_unit_matches_the_composed_rtl() {
    const CYCLES: usize = 26_000;
    let (cfg, _, log, tables) = recorded_run(CYCLES, &EIGHT_LANES);
    let replay = TreeletRtUnitReplay::new(&cfg.hw, &log.params).unwrap();
    let inputs = replay.inputs(log.treelet, tables);
    let trace = record_with_registers(&replay, inputs, replay.registers()).unwrap();
    assert_eq!(replay.misses(), 0);
    // Every child's registers and the wiring's.
    for prefix in ["rt_", "ctl_", "ct_", "qt_", "glue_"] {
        assert!(
            trace.registers.iter().any(|r| r.name.starts_with(prefix)),
            "no {prefix} register"
        );
    }
    let work = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vtq-replay-treelet");
    std::fs::create_dir_all(&work).unwrap();
    let mut files = Vec::new();
    for (module, text) in treelet_rt_unit_replay_verilog(&cfg.hw, &log.params).unwrap() {
        let path = work.join(format!("{module}.v"));
        std::fs::write(&path, text).unwrap();
        files.push(path);
    }
    let t = std::time::Instant::now();
    let Some(result) = or_skip(run_cosim(&trace, &files, &CosimOptions::icarus(&work))).unwrap()
    else {
        return;
    };
    eprintln!("icarus {:?}", t.elapsed());
    assert_eq!(result.cycles, CYCLES as u64);
    assert_eq!(result.mismatches, 0, "{:?}", result.reported);
}
