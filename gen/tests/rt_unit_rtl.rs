//! The generated RTL of the RT unit's control against the Rust block: cycle-by-cycle
//! co-simulation (Icarus Verilog, and Verilator on the replay's shorter stream) of the reactive
//! random environment of [`vtq_gen::stimulus::rt_unit`] with the toy datapath on both sides, at the
//! small configuration (three slots of four lanes, four-entry stacks that spill), a medium one
//! and the paper's; every output including the status ports and the ray records of completed
//! warps compared every cycle; broken RTL lines that the co-simulation must catch;
//! `verilator --lint-only -Wall`; the replay of recorded traffic whose datapath answers from
//! tables.

mod common;

use common::{cosim_timed, write_verilog};
use std::path::PathBuf;
use vtq_gen::cosim::{
    datapath_tables, record, tests_and_hits, CosimResult, DatapathCall, RtUnitReplay,
    RtUnitWithStatus, Simulator, Trace,
};
use vtq_gen::rtl::{rt_unit_replay_verilog, rt_unit_verilog, toy_datapath_verilog};
use vtq_gen::stimulus::rt_unit::{rt_unit_inputs, small_config, ToyDatapath};
use vtq_gen::synth::lint;
use vtq_gen::tools::or_skip;
use vtq_hdl::rt_unit::RtUnitParams;
use vtq_hdl::HwConfig;

/// The work directory of test `name`.
fn work_dir(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-gen-rt-unit-rtl-{name}"))
}

/// The RTL and the toy datapath of `cfg` and `params` written to the work directory of `tag`.
fn sources(tag: &str, cfg: &HwConfig, params: &RtUnitParams, rtl: Option<String>) -> Vec<PathBuf> {
    let dir = work_dir(tag);
    let rtl = rtl.unwrap_or_else(|| rt_unit_verilog(cfg, params).unwrap());
    vec![
        write_verilog(&dir, "rt_unit", &rtl),
        write_verilog(&dir, "rt_datapath", &toy_datapath_verilog(cfg.address_bits)),
    ]
}

/// The stimulus of `cfg`, recorded on the Rust block with its status ports.
fn trace_of(cfg: &HwConfig, params: &RtUnitParams, cycles: usize, seed: u64) -> Trace {
    let (unit, inputs, cov) = rt_unit_inputs(cfg, params, cycles, seed).unwrap();
    eprintln!("rt unit stimulus: {cov}");
    record(&RtUnitWithStatus(unit), inputs).unwrap()
}

/// Co-simulates `trace` against `files`; `None` when the simulator is not installed.
fn cosim(trace: &Trace, files: &[PathBuf], sim: Simulator, tag: &str) -> Option<CosimResult> {
    cosim_timed(trace, files, sim, work_dir(&format!("{tag}-{sim:?}")), tag)
}

/// Three seeds of 12,000 cycles at the small configuration under Icarus.
#[test]
fn rt_unit_matches_rust_cycle_by_cycle() {
    let (cfg, params) = small_config();
    for seed in 1..=3 {
        let trace = trace_of(&cfg, &params, 12_000, seed);
        let files = sources("small", &cfg, &params, None);
        if let Some(r) = cosim(&trace, &files, Simulator::Icarus, &format!("small-{seed}")) {
            assert!(r.passed(), "{r}");
        }
    }
}

/// `verilator --lint-only -Wall` finds nothing in the RT unit and the toy datapath, at the
/// small configuration and the paper's (64-lane warps for the widest vectors).
#[test]
fn lints_clean() {
    let wide = HwConfig {
        warp_size: 64,
        max_rays: 4096,
        warp_buffer_size: 2,
        ..HwConfig::default()
    };
    for (tag, (cfg, params)) in [
        ("lint-small", small_config()),
        ("lint-wide", (wide, RtUnitParams::default())),
    ] {
        let files = sources(tag, &cfg, &params, None);
        let Some(report) = or_skip(lint(&files, "rt_unit", &work_dir(tag))).unwrap() else {
            return;
        };
        for m in &report.messages {
            eprintln!("{tag}: {m:?}");
        }
        assert!(
            report.messages.is_empty(),
            "{tag}: {} lint messages",
            report.messages.len()
        );
    }
}

/// Wider fields: the paper's 32-lane warps, 32-entry stacks and 32-bit addresses with the
/// default RT-unit parameters, and a medium configuration of two slots.
#[test]
fn rt_unit_matches_rust_at_wider_configurations() {
    let (medium, medium_params) = medium_config();
    for (tag, cfg, params, cycles) in [
        ("medium", medium, medium_params, 6000),
        (
            "default",
            HwConfig::default(),
            RtUnitParams::default(),
            2000,
        ),
    ] {
        let trace = trace_of(&cfg, &params, cycles, 7);
        let files = sources(tag, &cfg, &params, None);
        if let Some(r) = cosim(&trace, &files, Simulator::Icarus, tag) {
            assert!(r.passed(), "{r}");
        }
    }
}

/// A medium configuration of two slots whose records carry 4 of the 8 entries of a stack
/// (`record_stack_entries` below `stack_depth`: parked lanes spill before their warp completes).
fn medium_config() -> (HwConfig, RtUnitParams) {
    let medium = HwConfig {
        warp_size: 8,
        warp_buffer_size: 2,
        stack_depth: 8,
        record_stack_entries: 4,
        max_rays: 64,
        address_bits: 24,
        treelet_bytes: 256,
        ..small_config().0
    };
    let params = RtUnitParams {
        max_children: 4,
        resp_fifo_depth: 5,
        resp_ports: 3,
        stack_spill_chunks: 3,
        ..Default::default()
    };
    (medium, params)
}

/// A parked lane that keeps its whole stack instead of spilling it down to what a record
/// carries is caught (in the medium configuration, where records carry half a stack).
#[test]
fn a_parked_lane_that_does_not_spill_is_caught() {
    let (cfg, params) = medium_config();
    let trace = trace_of(&cfg, &params, 6000, 7);
    let good = rt_unit_verilog(&cfg, &params).unwrap();
    // (The shared functions are in the top module and in the lane module.)
    let from = "dl == {DW{1'b0}} && osp > RD_SPW) begin";
    assert!(good.contains(from), "`{from}` not found");
    let files = sources(
        "broken-park",
        &cfg,
        &params,
        Some(good.replace(from, "dl == {DW{1'b0}} && 1'b0) begin")),
    );
    if let Some(r) = cosim(&trace, &files, Simulator::Icarus, "broken-park") {
        assert!(!r.passed() && r.mismatches > 0, "not caught: {r}");
    }
}

/// The stacks' SRAM rings are exercised: at the paper's sizes a pop that reloads the top from
/// the wrong ring position, and in the medium configuration a spill whose refill of the window
/// is not taken from the ring's read data, make the co-simulation fail.
#[test]
fn a_broken_stack_ring_is_caught() {
    let (medium, medium_params) = medium_config();
    let cases = [
        (
            "ring-top",
            HwConfig::default(),
            RtUnitParams::default(),
            2000,
            "{{(32-SPW){1'b0}}, cur_sp_q - ONE_SPW}))*E +: E];",
            "{{(32-SPW){1'b0}}, cur_sp_q}))*E +: E];",
        ),
        (
            "ring-refill",
            medium,
            medium_params,
            6000,
            "cur_pend_a[j] = 1'b1;",
            "cur_pend_a[j] = 1'b0;",
        ),
    ];
    for (tag, cfg, params, cycles, from, to) in cases {
        let trace = trace_of(&cfg, &params, cycles, 7);
        let good = rt_unit_verilog(&cfg, &params).unwrap();
        assert_eq!(
            good.matches(from).count(),
            1,
            "{tag}: `{from}` not found once"
        );
        let files = sources(tag, &cfg, &params, Some(good.replacen(from, to, 1)));
        if let Some(r) = cosim(&trace, &files, Simulator::Icarus, tag) {
            assert!(!r.passed() && r.mismatches > 0, "{tag} not caught: {r}");
        }
    }
}

/// Deliberately broken lines of the RTL: each must make the co-simulation fail.
#[test]
fn a_broken_rtl_line_is_caught() {
    let (cfg, params) = small_config();
    let trace = trace_of(&cfg, &params, 5000, 3);
    let good = rt_unit_verilog(&cfg, &params).unwrap();
    let mutations = [
        // Lanes of a warp merge their requests whatever node they fetch.
        (
            "if (merge && a_act == ACT_FETCH && a_node == lead_node) begin",
            "if (merge && a_act == ACT_FETCH) begin",
        ),
        // A tie in t goes to the larger hit id.
        ("h[63:32] < b[63:32]", "h[63:32] > b[63:32]"),
        // A warp completes while its last test's latency is still counting down.
        (
            "|| delay_q != {DW{1'b0}} || store_pending_q;",
            "|| store_pending_q;",
        ),
        // An append may overwrite an occupied lane.
        (
            "&& (issue_active & ~lane_empty[s*N +: N]) == {N{1'b0}})",
            ")",
        ),
        // A lane write does not mark the lane written, so the issue naming it is refused.
        ("written_d = write_here;", "written_d = 1'b0;"),
        // An issue leaves the lanes it names written inactive.
        ("wake[s*N+l] = issue_written[l];", "wake[s*N+l] = 1'b0;"),
        // An occlusion ray goes on traversing after its first accepted hit.
        ("if (accepted && occlusion_t) begin", "if (1'b0) begin"),
        // The node buffer's read misses last cycle's write (no forwarding).
        (
            "else if (node_write_valid_q && node_write_chunk_q",
            "else if (1'b0 && node_write_chunk_q",
        ),
        // The node buffer reads the word of the response popping now, not of the next one.
        (
            "nb_raddr = node_index(next_tag[TGW-1:LB], next_tag[LB-1:0]);",
            "nb_raddr = nb_index;",
        ),
    ];
    for (i, (from, to)) in mutations.iter().enumerate() {
        assert_eq!(
            good.matches(from).count(),
            1,
            "mutation {i}: `{from}` not found once"
        );
        let tag = format!("broken-{i}");
        let files = sources(&tag, &cfg, &params, Some(good.replacen(from, to, 1)));
        let Some(r) = cosim(&trace, &files, Simulator::Icarus, &tag) else {
            return;
        };
        assert!(
            !r.passed() && r.mismatches > 0,
            "mutation {i} was not caught: {r}"
        );
    }
}

/// The replay of recorded traffic that `vtq cosim --block rt-unit --scene` runs with a real
/// scene's datapath, here with the toy one: its tests recorded in a first pass
/// ([`datapath_tables`]) and answered from the cycle's table on both sides (the Rust
/// [`RtUnitReplay`], the RTL's replay `rt_datapath`). The replay's outputs are the plain run's;
/// the RTL matches them under Icarus and Verilator (the RT unit's one Verilator run: two-state,
/// its own scheduling); and tables that say no node hits anything change the outputs on both
/// sides alike (the table, not the toy format, decides).
#[test]
fn a_replay_answering_from_datapath_tables_matches() {
    let (cfg, params) = small_config();
    let (unit, inputs, _) = rt_unit_inputs(&cfg, &params, 5000, 4).unwrap();
    let tables = datapath_tables(&cfg, &params, ToyDatapath, &inputs).unwrap();
    let (tests, hits) = tests_and_hits(&tables);
    assert!(tests > 1000 && hits > 100, "{tests} tests, {hits} hits");
    let block = RtUnitReplay::new(&cfg, &params).unwrap();
    let trace = record(&block, block.inputs(inputs.clone(), tables.clone())).unwrap();
    assert_eq!(block.misses(), 0);
    let plain = record(&RtUnitWithStatus(unit), inputs.clone()).unwrap();
    let outputs =
        |t: &Trace| -> Vec<Vec<u64>> { t.rows().map(|r| r[t.inputs.len()..].to_vec()).collect() };
    assert_eq!(trace.outputs, plain.outputs);
    assert_eq!(outputs(&trace), outputs(&plain));
    let dir = work_dir("replay");
    let files: Vec<PathBuf> = rt_unit_replay_verilog(&cfg, &params)
        .unwrap()
        .iter()
        .map(|(m, v)| write_verilog(&dir, m, v))
        .collect();
    for sim in [Simulator::Icarus, Simulator::Verilator] {
        if let Some(r) = cosim(&trace, &files, sim, "replay") {
            assert!(r.passed(), "{r}");
        }
    }
    let missless: Vec<Vec<DatapathCall>> = tables
        .into_iter()
        .map(|calls| {
            calls
                .into_iter()
                .map(|mut c| {
                    c.result.hit = None;
                    c
                })
                .collect()
        })
        .collect();
    let blind = record(&block, block.inputs(inputs, missless)).unwrap();
    assert_ne!(outputs(&blind), outputs(&trace));
    if let Some(r) = cosim(&blind, &files, Simulator::Icarus, "replay-no-hits") {
        assert!(r.passed(), "{r}");
    }
}
