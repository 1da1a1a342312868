//! Real traffic against the generated RTL: the input ports of one SM's treelet count table,
//! treelet queue table and treelet controller, recorded cycle by cycle in a simulation of the VTQ
//! design (with tables small enough to evict and spill), replayed as a Verilog testbench against
//! the blocks' RTL: every output must match the Rust block's in every cycle.

mod common;

use common::{setup, small_config};
use vtq_gen::cosim::{record, run_cosim, CosimOptions};
use vtq_gen::rtl::{controller_verilog, count_table_verilog, queue_table_verilog};
use vtq_gen::tools::or_skip;
use vtq_hdl::controller::TreeletController;
use vtq_hdl::count_table::{CountOp, CountTable};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{QueueOp, QueueTable};
use vtq_hdl::Block;
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
