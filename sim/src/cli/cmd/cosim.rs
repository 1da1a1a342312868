//! `vtq cosim`: co-simulates the generated RTL of the treelet count table, the treelet queue
//! table, the treelet controller and the RT unit's control against the Rust blocks, cycle by
//! cycle, with Icarus Verilog or Verilator: on the seeded random stimulus of
//! [`vtq_gen::stimulus`] (for the controller and the RT unit, their reactive environments
//! [`vtq_gen::stimulus::controller`] and [`vtq_gen::stimulus::rt_unit`], the RT unit with the
//! toy node format's datapath on both sides), or (`--scene`) on the real traffic of a
//! simulation: the blocks' input ports of one SM's treelet RT unit, recorded cycle by cycle
//! from reset and replayed as the testbench's stimulus (the RT unit's with its datapath's tests
//! answered from their recorded results, [`vtq_gen::cosim::RtUnitReplay`]; the treelet RT
//! unit's wiring, alone, on its ports in the recorded run, [`vtq_gen::cosim::TreeletWiring`];
//! the whole treelet RT unit, composed, [`vtq_gen::cosim::TreeletRtUnitReplay`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use vtq_gen::cosim::{
    datapath_tables, record, record_with_registers, run_cosim, tests_and_hits, write_rust_vcd,
    CosimOptions, CosimResult, RtUnitReplay, RtUnitWithStatus, Simulator, Trace, RESET_CYCLES,
    RTL_VCD_FILE, RUST_VCD_FILE,
};
use vtq_gen::cosim::{wiring_ports, TreeletRtUnitReplay, TreeletWiring};
use vtq_gen::rtl::{
    controller_verilog, count_table_verilog, queue_table_verilog, rt_unit_replay_verilog,
    rt_unit_verilog, toy_datapath_verilog, treelet_rt_unit_replay_verilog, treelet_wiring_verilog,
};
use vtq_gen::stimulus::controller::controller_inputs;
use vtq_gen::stimulus::rt_unit::rt_unit_inputs;
use vtq_gen::stimulus::{count_table_inputs, queue_table_inputs};
use vtq_gen::GenError;
use vtq_hdl::controller::{ControllerInputs, ControllerStats, TreeletController};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::QueueOp;
use vtq_hdl::rt_unit::{NoDatapath, RtUnitParams};
use vtq_hdl::treelet_rt_unit::{TableLog, TreeletRtUnit, WiringInputs};
use vtq_hdl::Block;

use super::options::{build_bvh, load_scene, CacheArgs, ConfigArgs};
use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::datapath::BvhDatapath;
use crate::model::gpu::{simulate, SimOptions};
use vtq_hdl::count_table::{CountOp, CountTable};
use vtq_hdl::queue_table::QueueTable;

/// Which block(s) to co-simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BlockChoice {
    /// The treelet count table.
    Count,
    /// The treelet queue table.
    Queue,
    /// Both tables (the default).
    Tables,
    /// The treelet controller.
    Controller,
    /// The RT unit's control (random stimulus with the toy datapath; with `--scene`, the
    /// recorded traffic with the scene's datapath answering from its recorded results).
    RtUnit,
    /// The treelet RT unit's wiring, alone (with `--scene` only: its ports in the recorded run,
    /// the block stepped by its definition over SM `--sm`'s recorded inputs).
    Wiring,
    /// The whole treelet RT unit (both tables, the controller, the RT unit and the wiring,
    /// composed), with `--scene` only: SM `--sm`'s recorded inputs from reset, its datapath
    /// answering from the run's recorded tests.
    TreeletRtUnit,
    /// Both tables, the controller and the RT unit (and with `--scene`, the wiring and the
    /// whole treelet RT unit).
    All,
}

impl BlockChoice {
    fn count(self) -> bool {
        matches!(
            self,
            BlockChoice::Count | BlockChoice::Tables | BlockChoice::All
        )
    }
    fn queue(self) -> bool {
        matches!(
            self,
            BlockChoice::Queue | BlockChoice::Tables | BlockChoice::All
        )
    }
    fn controller(self) -> bool {
        matches!(self, BlockChoice::Controller | BlockChoice::All)
    }
    fn rt_unit(self) -> bool {
        matches!(self, BlockChoice::RtUnit | BlockChoice::All)
    }
    fn wiring(self) -> bool {
        matches!(self, BlockChoice::Wiring | BlockChoice::All)
    }
    fn treelet_rt_unit(self) -> bool {
        matches!(self, BlockChoice::TreeletRtUnit | BlockChoice::All)
    }
}

/// Which simulator runs the testbench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SimulatorChoice {
    /// Icarus Verilog (`iverilog` + `vvp`, Debian package `iverilog`).
    Icarus,
    /// Verilator (`verilator --binary`, Debian package `verilator`): slow to compile, fast to run.
    Verilator,
}

impl SimulatorChoice {
    fn simulator(self) -> Simulator {
        match self {
            SimulatorChoice::Icarus => Simulator::Icarus,
            SimulatorChoice::Verilator => Simulator::Verilator,
        }
    }
}

/// Options of `vtq cosim`.
#[derive(Debug, Args)]
pub struct CosimArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Block(s) to co-simulate.
    #[arg(long, value_enum, default_value_t = BlockChoice::Tables)]
    pub block: BlockChoice,
    /// Cycles of random stimulus per block; with `--scene`, cycles recorded (the tables' from
    /// their first op, the controller's from reset).
    #[arg(long, default_value_t = 100_000)]
    pub cycles: usize,
    /// Stimulus seed (the count table uses SEED, the queue table SEED + 1, the controller
    /// SEED + 2, the RT unit SEED + 3).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulator to run the testbench with.
    #[arg(long, value_enum, default_value_t = SimulatorChoice::Icarus)]
    pub simulator: SimulatorChoice,
    /// Directory for the RTL, testbench, vectors and simulator files, kept afterwards
    /// [default: a temporary directory, removed when every table matches].
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
    /// Replay real traffic instead of random stimulus: simulate this scene (with `--config`,
    /// which must be a queues design) and record the inputs of SM `--sm` for `--cycles` cycles:
    /// the tables' from the first op either table gets (before it they only get nops from
    /// reset), the controller's and the RT unit's from reset. The RT unit's datapath tests are
    /// run once in Rust with the scene's datapath, and both sides answer them from those
    /// results (`vtq_gen::cosim::RtUnitReplay`). With `--block all` every block is replayed.
    #[arg(long)]
    pub scene: Option<String>,
    /// The SM whose blocks are recorded with `--scene`.
    #[arg(long, default_value_t = 0)]
    pub sm: usize,
    /// Also write each block's waveforms, kept in its directory under the work directory:
    /// `rtl.vcd` (the RTL simulation's, dumped by the testbench) and `rust.vcd` (the Rust
    /// block's), with the same scopes and signal names for the ports and the registers the RTL
    /// names the same, and cycle k at 10 (k + 2) ns in both.
    #[arg(long)]
    pub vcd: bool,
    /// The BVH cache (with `--scene`).
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// The Debian/Ubuntu package that provides `tool`.
fn package_of(tool: &str) -> &'static str {
    match tool {
        "verilator" | "./obj_dir/cosim" => "verilator",
        "yosys" => "yosys",
        _ => "iverilog",
    }
}

/// A missing simulator becomes an error naming the tool and the package to install.
fn explain_missing(e: GenError) -> anyhow::Error {
    match &e {
        GenError::ToolMissing { tool } => anyhow::anyhow!(
            "{tool} is not installed (not found on PATH); install it with `apt-get install {}`",
            package_of(tool)
        ),
        _ => e.into(),
    }
}

/// Writes each `(module, text)` of `sources` as `<dir>/<module>.v` and co-simulates `trace`
/// against them in `dir`.
fn cosim_table(
    dir: &Path,
    trace: &Trace,
    sources: &[(String, String)],
    simulator: Simulator,
    vcd: bool,
) -> anyhow::Result<CosimResult> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut files = Vec::new();
    for (module, text) in sources {
        let source = dir.join(format!("{module}.v"));
        std::fs::write(&source, text).with_context(|| format!("writing {}", source.display()))?;
        files.push(source);
    }
    let opts = CosimOptions {
        simulator,
        vcd,
        ..CosimOptions::icarus(dir)
    };
    run_cosim(trace, &files, &opts).map_err(explain_missing)
}

/// Writes the Rust block's waveform of a job's run to a path (`vtq cosim --vcd`).
type RustVcd = Box<dyn Fn(&Path) -> Result<u64, GenError>>;

/// The [`RustVcd`] of `block` over `inputs` when `wanted`.
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

/// One table's stimulus, trace and RTL.
struct Job {
    trace: Trace,
    /// What the stimulus covered, in words.
    coverage: String,
    /// The RTL: `(module, Verilog text)`, the block's module first.
    verilog: Vec<(String, String)>,
    /// The Rust block's waveform writer, with `--vcd`.
    rust_vcd: Option<RustVcd>,
}

/// Builds the stimulus, records the Rust block and generates the RTL of each chosen block.
fn jobs(cfg: &SimConfig, args: &CosimArgs) -> anyhow::Result<Vec<Job>> {
    let hw = &cfg.hw;
    if matches!(args.block, BlockChoice::Wiring | BlockChoice::TreeletRtUnit) {
        bail!("--block wiring and --block treelet-rt-unit replay a real run: give --scene");
    }
    let mut out = Vec::new();
    if args.block.count() {
        let (table, inputs, coverage) = count_table_inputs(hw, args.cycles, args.seed)?;
        out.push(Job {
            rust_vcd: rust_vcd(&table, &inputs, args.vcd),
            trace: record(&table, inputs)?,
            coverage: coverage.to_string(),
            verilog: vec![(table.describe().name, count_table_verilog(hw)?)],
        });
    }
    if args.block.queue() {
        let seed = args.seed.wrapping_add(1);
        let (table, inputs, coverage) = queue_table_inputs(hw, args.cycles, seed)?;
        out.push(Job {
            rust_vcd: rust_vcd(&table, &inputs, args.vcd),
            trace: record(&table, inputs)?,
            coverage: coverage.to_string(),
            verilog: vec![(table.describe().name, queue_table_verilog(hw)?)],
        });
    }
    if args.block.controller() {
        let seed = args.seed.wrapping_add(2);
        let features = cfg.hardware_controller_features();
        let (ctl, inputs, coverage) = controller_inputs(hw, features, args.cycles, seed)?;
        out.push(Job {
            rust_vcd: rust_vcd(&ctl, &inputs, args.vcd),
            trace: record(&ctl, inputs)?,
            coverage: coverage.to_string(),
            verilog: vec![(ctl.describe().name, controller_verilog(hw, features)?)],
        });
    }
    if args.block.rt_unit() {
        let seed = args.seed.wrapping_add(3);
        let params = rt_unit_params(cfg);
        let (unit, inputs, coverage) = rt_unit_inputs(hw, &params, args.cycles, seed)?;
        let unit = RtUnitWithStatus(unit);
        out.push(Job {
            rust_vcd: rust_vcd(&unit, &inputs, args.vcd),
            trace: record(&unit, inputs)?,
            coverage: format!("random with the toy datapath: {coverage}"),
            verilog: vec![
                (unit.describe().name, rt_unit_verilog(hw, &params)?),
                (
                    "rt_datapath".to_string(),
                    toy_datapath_verilog(hw.address_bits),
                ),
            ],
        });
    }
    Ok(out)
}

/// The RT unit's parameters of `cfg`, as `vtq verilog` generates it.
pub fn rt_unit_params(cfg: &SimConfig) -> RtUnitParams {
    cfg.rt_unit_params(0, None, RtUnitParams::default().stack_spill_chunks)
}

/// The jobs of a replay of real traffic: simulates `scene` and records SM `args.sm`'s table
/// inputs.
fn replay_jobs(scene: &str, args: &CosimArgs) -> anyhow::Result<Vec<Job>> {
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

/// Run `vtq cosim`.
pub fn run(args: &CosimArgs) -> anyhow::Result<()> {
    if args.cycles == 0 {
        bail!("--cycles must be at least 1");
    }
    let jobs = match &args.scene {
        Some(scene) => replay_jobs(scene, args)?,
        None => jobs(&args.config.load_hardware()?, args)?,
    };
    let simulator = args.simulator.simulator();
    let (root, temporary) = match &args.work_dir {
        Some(dir) => (dir.clone(), false),
        None => (
            std::env::temp_dir().join(format!("vtq-cosim-{}", std::process::id())),
            true,
        ),
    };
    let mut failed = Vec::new();
    for job in jobs {
        let module = job.trace.module.clone();
        let start = Instant::now();
        let dir = root.join(&module);
        let result = cosim_table(&dir, &job.trace, &job.verilog, simulator, args.vcd)
            .with_context(|| format!("co-simulating {module}"))?;
        println!(
            "{module}: {} cycles compared, {} mismatches ({simulator:?}, {:.1} s)",
            result.cycles,
            result.mismatches,
            start.elapsed().as_secs_f64()
        );
        println!("  stimulus: {}", job.coverage);
        if let Some(write) = &job.rust_vcd {
            let rust = dir.join(RUST_VCD_FILE);
            write(&rust).with_context(|| format!("writing {}", rust.display()))?;
            println!(
                "  waveforms: {} (RTL), {} (Rust); cycle k at 10 (k + {RESET_CYCLES}) ns in both",
                dir.join(RTL_VCD_FILE).display(),
                rust.display()
            );
        }
        if let Some(m) = result.reported.first() {
            println!(
                "  first mismatch: cycle {} signal {} expected {} got {}",
                m.cycle, m.signal, m.expected, m.got
            );
        }
        if result.cycles != job.trace.cycles() as u64 {
            bail!(
                "{module}: the testbench compared {} cycles of the {} recorded",
                result.cycles,
                job.trace.cycles()
            );
        }
        if !result.passed() {
            failed.push(format!("{module} ({} mismatches)", result.mismatches));
        }
    }
    if !failed.is_empty() {
        bail!(
            "the RTL differs from the Rust model: {}; files kept in {}",
            failed.join(", "),
            root.display()
        );
    }
    if temporary && !args.vcd {
        // Best effort: the verdict is already printed.
        let _ = std::fs::remove_dir_all(&root);
    }
    Ok(())
}
