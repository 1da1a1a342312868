//! One co-simulation per block, ready to run: the Rust block's recorded [`Trace`], the RTL it
//! is compared with, a line saying what the stimulus covers and, on request, the Rust side's
//! waveform. [`random_jobs`] builds them on the seeded random stimulus of
//! [`crate::stimulus`]; [`replay_jobs`] on the real traffic of a recorded run (one SM's
//! [`TableLog`]). `vtq cosim` runs them ([`Job::run`]) and prints the verdicts.

use std::path::Path;

use vtq_hdl::controller::{
    ControllerFeatures, ControllerInputs, ControllerStats, TreeletController,
};
use vtq_hdl::count_table::{CountOp, CountTable};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{QueueOp, QueueTable};
use vtq_hdl::rt_unit::{NoDatapath, NodeDatapath, RtUnitParams};
use vtq_hdl::treelet_rt_unit::{TableLog, TreeletRtUnit, WiringInputs};
use vtq_hdl::{Block, HwConfig};

use super::{
    datapath_tables, record, record_with_registers, run_cosim, tests_and_hits, wiring_ports,
    write_rust_vcd, CosimOptions, CosimResult, RtUnitReplay, RtUnitWithStatus, Simulator, Trace,
    TreeletRtUnitReplay, TreeletWiring,
};
use crate::compose::wiring_name;
use crate::error::GenError;
use crate::rtl::{
    controller_verilog, count_table_verilog, queue_table_verilog, rt_unit_replay_verilog,
    rt_unit_verilog, toy_datapath_verilog, treelet_rt_unit_replay_verilog, treelet_wiring_verilog,
};
use crate::stimulus::controller::controller_inputs;
use crate::stimulus::rt_unit::rt_unit_inputs;
use crate::stimulus::{count_table_inputs, queue_table_inputs};
use crate::tools::{create_dir, write_file};

/// Which blocks to co-simulate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Blocks {
    /// The treelet count table.
    pub count: bool,
    /// The treelet queue table.
    pub queue: bool,
    /// The treelet controller.
    pub controller: bool,
    /// The RT unit's control.
    pub rt_unit: bool,
    /// The composed treelet RT unit's wiring, alone (a recorded run only).
    pub wiring: bool,
    /// The whole composed treelet RT unit (a recorded run only).
    pub treelet_rt_unit: bool,
}

/// Writes the Rust block's waveform of a job to a file; returns the cycles written.
pub type RustVcd = Box<dyn Fn(&Path) -> Result<u64, GenError>>;

/// One block's co-simulation, ready to run.
pub struct Job {
    /// The Rust block's run: inputs, outputs and registers per cycle.
    pub trace: Trace,
    /// What the stimulus covers, in words.
    pub coverage: String,
    /// The RTL: (module, source) of the block and everything it instantiates.
    pub verilog: Vec<(String, String)>,
    /// Writes the Rust block's waveform of the same run (when one was asked for).
    pub rust_vcd: Option<RustVcd>,
}

impl Job {
    /// The job of `block` over `inputs` (its described registers compared too), with the
    /// `coverage` line and the RTL `verilog`; the Rust waveform writer when `vcd`.
    fn of<B>(
        block: &B,
        inputs: Vec<B::Inputs>,
        coverage: String,
        verilog: Vec<(String, String)>,
        vcd: bool,
    ) -> Result<Job, GenError>
    where
        B: Block + Clone + 'static,
        B::Inputs: Clone + 'static,
    {
        Ok(Job {
            rust_vcd: rust_vcd(block, &inputs, vcd),
            trace: record(block, inputs)?,
            coverage,
            verilog,
        })
    }

    /// Writes the RTL into `dir` and runs the trace's testbench against it with `simulator`
    /// (the RTL's waveform too with `vcd`).
    pub fn run(
        &self,
        dir: &Path,
        simulator: Simulator,
        vcd: bool,
    ) -> Result<CosimResult, GenError> {
        create_dir(dir)?;
        let mut files = Vec::new();
        for (module, text) in &self.verilog {
            let source = dir.join(format!("{module}.v"));
            write_file(&source, text)?;
            files.push(source);
        }
        let opts = CosimOptions {
            simulator,
            vcd,
            ..CosimOptions::icarus(dir)
        };
        run_cosim(&self.trace, &files, &opts)
    }
}

/// The Rust waveform writer of `block` over `inputs`, when `wanted`.
fn rust_vcd<B>(block: &B, inputs: &[B::Inputs], wanted: bool) -> Option<RustVcd>
where
    B: Block + Clone + 'static,
    B::Inputs: Clone + 'static,
{
    wanted.then(|| {
        let (block, inputs) = (block.clone(), inputs.to_vec());
        Box::new(move |path: &Path| write_rust_vcd(&block, inputs.iter().cloned(), path)) as RustVcd
    })
}

/// The jobs of `blocks` (tables, controller, RT unit: the wiring and the composed block need a
/// recorded run) on `cycles` cycles of seeded random stimulus: the tables' on their own, the
/// controller with `features` and the RT unit with `params` in their reactive environments,
/// the RT unit with the toy node format's datapath on both sides. Each block's seed is `seed`
/// plus its position (0 count table, 1 queue table, 2 controller, 3 RT unit).
pub fn random_jobs(
    hw: &HwConfig,
    features: ControllerFeatures,
    params: &RtUnitParams,
    blocks: Blocks,
    (cycles, seed): (usize, u64),
    vcd: bool,
) -> Result<Vec<Job>, GenError> {
    let mut out = Vec::new();
    if blocks.count {
        let (table, inputs, coverage) = count_table_inputs(hw, cycles, seed)?;
        let verilog = vec![(table.describe().name, count_table_verilog(hw)?)];
        out.push(Job::of(&table, inputs, coverage.to_string(), verilog, vcd)?);
    }
    if blocks.queue {
        let (table, inputs, coverage) = queue_table_inputs(hw, cycles, seed.wrapping_add(1))?;
        let verilog = vec![(table.describe().name, queue_table_verilog(hw)?)];
        out.push(Job::of(&table, inputs, coverage.to_string(), verilog, vcd)?);
    }
    if blocks.controller {
        let (ctl, inputs, coverage) =
            controller_inputs(hw, features, cycles, seed.wrapping_add(2))?;
        let verilog = vec![(ctl.describe().name, controller_verilog(hw, features)?)];
        out.push(Job::of(&ctl, inputs, coverage.to_string(), verilog, vcd)?);
    }
    if blocks.rt_unit {
        let (unit, inputs, coverage) = rt_unit_inputs(hw, params, cycles, seed.wrapping_add(3))?;
        let unit = RtUnitWithStatus(unit);
        let verilog = vec![
            (unit.describe().name, rt_unit_verilog(hw, params)?),
            (
                "rt_datapath".to_string(),
                toy_datapath_verilog(hw.address_bits),
            ),
        ];
        let coverage = format!("random with the toy datapath: {coverage}");
        out.push(Job::of(&unit, inputs, coverage, verilog, vcd)?);
    }
    Ok(out)
}

/// A recorded run: one SM's inputs from reset and what the replays need around them.
pub struct Recorded<'a, D> {
    /// The SM's recorded inputs (with the run's treelet RT unit parameters).
    pub log: &'a TableLog,
    /// The run's hardware configuration.
    pub hw: &'a HwConfig,
    /// The run's datapath (the scene's BVH): the RT unit's tests are answered from what it
    /// returned in the run.
    pub datapath: D,
    /// The run in words: SM and scene.
    pub run: String,
    /// The design and the run's cycles in words.
    pub about: String,
    /// Write the Rust blocks' waveforms too.
    pub vcd: bool,
}

/// One block's replay job built from a recorded run (a method of [`Recorded`]).
type ReplayJob<'a, D> = fn(&Recorded<'a, D>) -> Result<Job, GenError>;

/// The jobs of `blocks` replaying the real traffic of the run `r`: each block's input ports in
/// the recorded cycles, from reset.
pub fn replay_jobs<'a, D: NodeDatapath + Copy>(
    r: &Recorded<'a, D>,
    blocks: Blocks,
) -> Result<Vec<Job>, GenError> {
    let jobs: [(bool, ReplayJob<'a, D>); 6] = [
        (blocks.count, Recorded::count_table),
        (blocks.queue, Recorded::queue_table),
        (blocks.controller, Recorded::controller),
        (blocks.rt_unit, Recorded::rt_unit),
        (blocks.wiring, Recorded::wiring),
        (blocks.treelet_rt_unit, Recorded::treelet_rt_unit),
    ];
    jobs.into_iter()
        .filter(|&(wanted, _)| wanted)
        .map(|(_, job)| job(r))
        .collect()
}

impl<D: NodeDatapath + Copy> Recorded<'_, D> {
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
    fn count_table(&self) -> Result<Job, GenError> {
        // Indexed by the op's `op_kind` code (Nop, Add, Remove, Clear).
        let mut n = [0u64; 4];
        for i in &self.log.count {
            n[i.op.kind_code() as usize] += 1;
        }
        let ops = format!(
            "{} adds, {} removes, {} clears, {} nop cycles",
            n[1], n[2], n[3], n[0]
        );
        let table = CountTable::new(self.hw)?;
        let verilog = vec![(table.describe().name, count_table_verilog(self.hw)?)];
        let coverage = self.table_window(ops);
        Job::of(&table, self.log.count.clone(), coverage, verilog, self.vcd)
    }

    /// The queue table's job.
    fn queue_table(&self) -> Result<Job, GenError> {
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
        let table = QueueTable::new(self.hw)?;
        let verilog = vec![(table.describe().name, queue_table_verilog(self.hw)?)];
        let coverage = self.table_window(ops);
        Job::of(&table, self.log.queue.clone(), coverage, verilog, self.vcd)
    }

    /// The treelet controller's job, with the run's features.
    fn controller(&self) -> Result<Job, GenError> {
        let features = self.log.params.features;
        let ctl = TreeletController::new(self.hw.clone(), features)?;
        let coverage = format!(
            "real traffic: cycles 0..{} of {} ({}), from reset: {}",
            self.log.controller.len(),
            self.run,
            self.about,
            replay_summary(&ctl, &self.log.controller)
        );
        let verilog = vec![(ctl.describe().name, controller_verilog(self.hw, features)?)];
        Job::of(
            &ctl,
            self.log.controller.clone(),
            coverage,
            verilog,
            self.vcd,
        )
    }

    /// The RT unit's job, its datapath answering from the run's recorded tests.
    fn rt_unit(&self) -> Result<Job, GenError> {
        let (hw, log) = (self.hw, self.log);
        let params = &log.params.rt;
        let tables = datapath_tables(hw, params, self.datapath, &log.rt_unit)?;
        let (tests, hits) = tests_and_hits(&tables);
        let unit = RtUnitReplay::new(hw, params)?;
        let inputs = unit.inputs(log.rt_unit.clone(), tables);
        let vcd = rust_vcd(&unit, &inputs, self.vcd);
        let trace = record_with_registers(&unit, inputs, unit.registers())?;
        unanswered(&trace, unit.misses(), "the RT unit's")?;
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
    fn wiring(&self) -> Result<Job, GenError> {
        let (hw, log) = (self.hw, self.log);
        let unit = TreeletRtUnit::new(hw.clone(), log.params.clone(), self.datapath)?;
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
        let vcd_ports = self.vcd.then(|| ports.clone());
        let trace = record(&TreeletWiring::new(&own), ports)?;
        let verilog = treelet_wiring_verilog(&own)?;
        let name = wiring_name(&own.describe());
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
    fn treelet_rt_unit(&self) -> Result<Job, GenError> {
        let (hw, log) = (self.hw, self.log);
        let tables = datapath_tables(hw, &log.params.rt, self.datapath, &log.rt_unit)?;
        let (tests, hits) = tests_and_hits(&tables);
        let unit = TreeletRtUnitReplay::new(hw, &log.params)?;
        let inputs = unit.inputs(log.treelet.clone(), tables);
        let vcd = rust_vcd(&unit, &inputs, self.vcd);
        let trace = record_with_registers(&unit, inputs, unit.registers())?;
        unanswered(&trace, unit.misses(), "the treelet RT unit's")?;
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

/// An error when a replay ran `misses` datapath tests its recorded tables do not hold.
fn unanswered(trace: &Trace, misses: u64, whose: &str) -> Result<(), GenError> {
    if misses == 0 {
        return Ok(());
    }
    Err(GenError::Cosim {
        block: trace.module.clone(),
        reason: format!("{whose} replay ran {misses} datapath tests its tables do not hold"),
    })
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
