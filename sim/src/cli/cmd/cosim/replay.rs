//! `vtq cosim --scene`: the jobs of a replay of a real run's traffic, one per block, built
//! from SM `--sm`'s recorded inputs.

use std::path::Path;

use anyhow::{bail, Context};
use vtq_gen::cosim::{
    datapath_tables, record, record_with_registers, tests_and_hits, wiring_ports, write_rust_vcd,
    RtUnitReplay, TreeletRtUnitReplay, TreeletWiring,
};
use vtq_gen::rtl::{
    controller_verilog, count_table_verilog, queue_table_verilog, rt_unit_replay_verilog,
    treelet_rt_unit_replay_verilog, treelet_wiring_verilog,
};
use vtq_hdl::controller::{ControllerInputs, ControllerStats, TreeletController};
use vtq_hdl::count_table::{CountOp, CountTable};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{QueueOp, QueueTable};
use vtq_hdl::rt_unit::NoDatapath;
use vtq_hdl::treelet_rt_unit::{TableLog, TreeletRtUnit, WiringInputs};
use vtq_hdl::Block;

use super::super::options::{build_bvh, load_scene};
use super::{rust_vcd, CosimArgs, Job, RustVcd};
use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::datapath::BvhDatapath;
use crate::model::gpu::{simulate, SimOptions};

/// The jobs of a replay of real traffic: simulates `scene` and records SM `args.sm`'s table
/// inputs.
pub(super) fn replay_jobs(scene: &str, args: &CosimArgs) -> anyhow::Result<Vec<Job>> {
    let cfg = args.config.load()?;
    let scene = load_scene(scene)?;
    let bvh = build_bvh(&scene, &cfg.bvh_params(), &args.cache)?;
    let options = SimOptions {
        record_tables: Some((args.sm, args.cycles)),
        ..SimOptions::default()
    };
    let out = simulate(&scene, &bvh, &cfg, options, None)
        .with_context(|| format!("simulating scene '{}'", scene.name))?;
    let log = out
        .table_log
        .context("the simulation recorded no table inputs")?;
    let r = Replay {
        log: &log,
        cfg: &cfg,
        bvh: &bvh,
        args,
        run: format!("SM {} in scene {}", args.sm, scene.name),
        about: format!(
            "{}, {} cycles in all",
            cfg.mode.kind.name(),
            out.stats.cycles
        ),
    };
    let mut jobs = Vec::new();
    if args.block.count() {
        jobs.push(r.count_table()?);
    }
    if args.block.queue() {
        jobs.push(r.queue_table()?);
    }
    if args.block.controller() {
        jobs.push(r.controller()?);
    }
    if args.block.rt_unit() {
        jobs.push(r.rt_unit()?);
    }
    if args.block.wiring() {
        jobs.push(r.wiring()?);
    }
    if args.block.treelet_rt_unit() {
        jobs.push(r.treelet_rt_unit()?);
    }
    Ok(jobs)
}

/// A recorded run and what each block's replay job is built from.
struct Replay<'a> {
    /// SM `args.sm`'s recorded inputs.
    log: &'a TableLog,
    /// The run's configuration.
    cfg: &'a SimConfig,
    /// The scene's BVH (the RT unit's datapath).
    bvh: &'a HwBvh,
    /// The command's options.
    args: &'a CosimArgs,
    /// The run in words: SM and scene.
    run: String,
    /// The design and the run's cycles in words.
    about: String,
}

impl Replay<'_> {
    /// A table replay's coverage line: its window and `ops`.
    fn table_window(&self, ops: String) -> String {
        format!(
            "real traffic: cycles {}..{} of {} ({}; before, only nops from reset): {ops}",
            self.log.first_cycle,
            self.log.first_cycle + self.log.count.len() as u64,
            self.run,
            self.about
        )
    }

    /// The count table's job.
    fn count_table(&self) -> anyhow::Result<Job> {
        // Indexed by the op's `op_kind` code (Nop, Add, Remove, Clear).
        let mut n = [0u64; 4];
        for i in &self.log.count {
            n[i.op.kind_code() as usize] += 1;
        }
        let ops = format!(
            "{} adds, {} removes, {} clears, {} nop cycles",
            n[1], n[2], n[3], n[0]
        );
        let hw = &self.cfg.hw;
        let table = CountTable::new(hw)?;
        Ok(Job {
            rust_vcd: rust_vcd(&table, &self.log.count, self.args.vcd),
            trace: record(&table, self.log.count.iter().copied())?,
            coverage: self.table_window(ops),
            verilog: vec![(table.describe().name, count_table_verilog(hw)?)],
        })
    }

    /// The queue table's job.
    fn queue_table(&self) -> anyhow::Result<Job> {
        let mut n = [0u64; 6];
        let mut refills = 0;
        for i in &self.log.queue {
            n[i.op.kind_code() as usize] += 1;
            refills += u64::from(i.refill_valid);
        }
        let ops = format!(
            "{} inserts, {} pops, {} pop_any, {} refills ({} answered), {} nop cycles",
            n[1], n[2], n[3], n[5], refills, n[0]
        );
        let hw = &self.cfg.hw;
        let table = QueueTable::new(hw)?;
        Ok(Job {
            rust_vcd: rust_vcd(&table, &self.log.queue, self.args.vcd),
            trace: record(&table, self.log.queue.iter().copied())?,
            coverage: self.table_window(ops),
            verilog: vec![(table.describe().name, queue_table_verilog(hw)?)],
        })
    }

    /// The treelet controller's job.
    fn controller(&self) -> anyhow::Result<Job> {
        let hw = &self.cfg.hw;
        let features = self.cfg.controller_features();
        let ctl = TreeletController::new(hw.clone(), features)?;
        let summary = replay_summary(&ctl, &self.log.controller);
        Ok(Job {
            rust_vcd: rust_vcd(&ctl, &self.log.controller, self.args.vcd),
            trace: record(&ctl, self.log.controller.iter().cloned())?,
            coverage: format!(
                "real traffic: cycles 0..{} of {} ({}), from reset: {summary}",
                self.log.controller.len(),
                self.run,
                self.about
            ),
            verilog: vec![(ctl.describe().name, controller_verilog(hw, features)?)],
        })
    }

    /// The RT unit's job, its datapath answering from the run's recorded tests.
    fn rt_unit(&self) -> anyhow::Result<Job> {
        let (hw, log) = (&self.cfg.hw, self.log);
        let params = &log.params.rt;
        let tables = datapath_tables(hw, params, BvhDatapath::new(self.bvh), &log.rt_unit)?;
        let (tests, hits) = tests_and_hits(&tables);
        let unit = RtUnitReplay::new(hw, params)?;
        let inputs = unit.inputs(log.rt_unit.clone(), tables);
        let vcd = rust_vcd(&unit, &inputs, self.args.vcd);
        let trace = record_with_registers(&unit, inputs, unit.registers())?;
        if unit.misses() > 0 {
            bail!(
                "the RT unit's replay ran {} datapath tests its tables do not hold",
                unit.misses()
            );
        }
        let warps = log.rt_unit.iter().filter(|i| i.issue.is_some()).count();
        let occlusion = (log.rt_unit.iter())
            .filter_map(|i| i.issue.as_ref())
            .flat_map(|w| w.lanes.iter().flatten())
            .filter(|r| r.occlusion)
            .count();
        let responses: usize = log.rt_unit.iter().map(|i| i.responses.len()).sum();
        Ok(Job {
            rust_vcd: vcd,
            trace,
            coverage: format!(
                "real traffic with the scene's datapath: cycles 0..{} of {} ({}), from reset: \
                 {warps} warps issued ({occlusion} occlusion rays), {responses} memory \
                 responses, {tests} datapath tests ({hits} with a hit), answered from their \
                 recorded results on both sides",
                log.rt_unit.len(),
                self.run,
                self.about
            ),
            verilog: rt_unit_replay_verilog(hw, params)?,
        })
    }

    /// The treelet RT unit's wiring's job, alone on its ports in the recorded run.
    fn wiring(&self) -> anyhow::Result<Job> {
        let (hw, log) = (&self.cfg.hw, self.log);
        let datapath = BvhDatapath::new(self.bvh);
        let unit = TreeletRtUnit::new(hw.clone(), log.params.clone(), datapath)?;
        let ports = wiring_ports(&unit, log.treelet.iter().cloned());
        let sum = |f: &dyn Fn(&WiringInputs) -> usize| ports.iter().map(f).sum::<usize>();
        let done = sum(&|p| usize::from(p.rt.done.is_some()));
        let released = sum(&|p| usize::from(p.rt.released.is_some()));
        let fills = sum(&|p| usize::from(p.ctl.fill.is_some()));
        let records = sum(&|p| p.top.ray_records.len());
        let offered = sum(&|p| usize::from(p.top.sm_warp.is_some()));
        // The wiring's behaviour does not depend on the RT unit's datapath: the block whose
        // trace, RTL and waveform are taken owns a unit without one.
        let own = TreeletRtUnit::new(hw.clone(), log.params.clone(), NoDatapath)?;
        let vcd_ports = self.args.vcd.then(|| ports.clone());
        let trace = record(&TreeletWiring::new(&own), ports)?;
        let verilog = treelet_wiring_verilog(&own)?;
        let name = vtq_gen::compose::wiring_name(&own.describe());
        Ok(Job {
            rust_vcd: vcd_ports.map(|ports| {
                Box::new(move |path: &Path| {
                    write_rust_vcd(&TreeletWiring::new(&own), ports.iter().cloned(), path)
                }) as RustVcd
            }),
            trace,
            coverage: format!(
                "real traffic: the wiring's ports in cycles 0..{} of {} ({}), the block stepped by \
                 its definition from reset: {offered} cycles with an SM warp offered, {fills} \
                 fill commands, {records} ray records returned, {done} warps completed, \
                 {released} repacks released lanes",
                log.treelet.len(),
                self.run,
                self.about
            ),
            verilog: vec![(name, verilog)],
        })
    }

    /// The whole composed treelet RT unit's job, its datapath answering from the recorded tests.
    fn treelet_rt_unit(&self) -> anyhow::Result<Job> {
        let (hw, log) = (&self.cfg.hw, self.log);
        let datapath = BvhDatapath::new(self.bvh);
        let tables = datapath_tables(hw, &log.params.rt, datapath, &log.rt_unit)?;
        let (tests, hits) = tests_and_hits(&tables);
        let unit = TreeletRtUnitReplay::new(hw, &log.params)?;
        let inputs = unit.inputs(log.treelet.clone(), tables);
        let vcd = rust_vcd(&unit, &inputs, self.args.vcd);
        let trace = record_with_registers(&unit, inputs, unit.registers())?;
        if unit.misses() > 0 {
            bail!(
                "the treelet RT unit's replay ran {} datapath tests its tables do not hold",
                unit.misses()
            );
        }
        let offered = log.treelet.iter().filter(|i| i.sm_warp.is_some()).count();
        let records: usize = log.treelet.iter().map(|i| i.ray_records.len()).sum();
        let occlusion = (log.treelet.iter())
            .flat_map(|i| &i.ray_records)
            .filter(|r| r.record.occlusion)
            .count();
        Ok(Job {
            rust_vcd: vcd,
            trace,
            coverage: format!(
                "real traffic with the scene's datapath: the whole treelet RT unit's inputs in \
                 cycles 0..{} of {} ({}), from reset: {offered} cycles with an SM warp offered, \
                 {records} ray records returned ({occlusion} of occlusion rays), {tests} \
                 datapath tests ({hits} with a hit), answered from their recorded results on \
                 both sides",
                log.treelet.len(),
                self.run,
                self.about
            ),
            verilog: treelet_rt_unit_replay_verilog(hw, &log.params)?,
        })
    }
}

/// What a replayed controller stream does, in words: its cycles per mode and its actions,
/// counted by running the Rust block over it.
fn replay_summary(ctl: &TreeletController, inputs: &[ControllerInputs]) -> String {
    let mut regs = ctl.reset();
    let mut stats = ControllerStats::default();
    let mut modes = [0u64; 4];
    let mut pops = 0u64;
    let mut clears = 0u64;
    for i in inputs {
        let out = ctl.step(&mut regs, i);
        modes[out.mode as usize] += 1;
        pops += u64::from(matches!(out.qt_op, QueueOp::Pop { .. } | QueueOp::PopAny));
        clears += u64::from(out.ct_op == CountOp::Clear);
        stats.observe(i, &out);
    }
    let modes: Vec<String> = Mode::ALL
        .iter()
        .zip(modes)
        .map(|(m, c)| format!("{} {c}", m.name()))
        .collect();
    format!(
        "modes: {}; {} terminations, {} enqueues, {} claims, {} preloads, {} pops, {} treelet \
         warps, {} grouped warps, {} repacks, {} evictions, {} count-table clears",
        modes.join(", "),
        stats.terminated_warps,
        stats.enqueued_rays,
        stats.claims,
        stats.preloads,
        pops,
        stats.treelet_warps,
        stats.grouped_warps,
        stats.repacks,
        stats.evictions,
        clears
    )
}
