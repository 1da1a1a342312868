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
//! the whole treelet RT unit, composed, [`vtq_gen::cosim::TreeletRtUnitReplay`]). The run is
//! recorded by [`crate::experiment::cosim`], the jobs are built by `vtq_gen::cosim`
//! ([`random_jobs`], [`replay_jobs`]); this module parses, runs them and prints the verdicts.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use vtq_gen::cosim::{
    random_jobs, replay_jobs, Blocks, Job, Recorded, Simulator, RESET_CYCLES, RTL_VCD_FILE,
    RUST_VCD_FILE,
};
use vtq_gen::GenError;
use vtq_hdl::rt_unit::RtUnitParams;

use super::options::{build_bvh, load_scene, CacheArgs, ConfigArgs};
use crate::experiment::cosim::record_sm;
use crate::model::config::SimConfig;
use crate::model::gpu::datapath::BvhDatapath;

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

/// The blocks `choice` names.
fn blocks(choice: BlockChoice) -> Blocks {
    Blocks {
        count: choice.count(),
        queue: choice.queue(),
        controller: choice.controller(),
        rt_unit: choice.rt_unit(),
        wiring: choice.wiring(),
        treelet_rt_unit: choice.treelet_rt_unit(),
    }
}

/// The jobs of `vtq cosim`: on random stimulus, or (`--scene`) replaying SM `--sm`'s recorded
/// inputs in a simulation of the scene.
fn jobs(args: &CosimArgs) -> anyhow::Result<Vec<Job>> {
    let Some(scene) = &args.scene else {
        if matches!(args.block, BlockChoice::Wiring | BlockChoice::TreeletRtUnit) {
            bail!("--block wiring and --block treelet-rt-unit replay a real run: give --scene");
        }
        let cfg = args.config.load_hardware()?;
        let features = cfg.hardware_controller_features();
        let (hw, params) = (&cfg.hw, rt_unit_params(&cfg));
        let run = (args.cycles, args.seed);
        return Ok(random_jobs(
            hw,
            features,
            &params,
            blocks(args.block),
            run,
            args.vcd,
        )?);
    };
    let cfg = args.config.load()?;
    let scene = load_scene(scene)?;
    let bvh = build_bvh(&scene, &cfg.bvh_params(), &args.cache)?;
    let rec = record_sm(&scene, &bvh, &cfg, args.sm, args.cycles)?;
    let recorded = Recorded {
        log: &rec.log,
        hw: &cfg.hw,
        datapath: BvhDatapath::new(&bvh),
        run: rec.run,
        about: rec.about,
        vcd: args.vcd,
    };
    Ok(replay_jobs(&recorded, blocks(args.block))?)
}

/// The RT unit's parameters of `cfg`, as `vtq verilog` generates it.
pub fn rt_unit_params(cfg: &SimConfig) -> RtUnitParams {
    cfg.rt_unit_params(0, None, RtUnitParams::default().stack_spill_chunks)
}

/// Run `vtq cosim`.
pub fn run(args: &CosimArgs) -> anyhow::Result<()> {
    if args.cycles == 0 {
        bail!("--cycles must be at least 1");
    }
    let jobs = jobs(args)?;
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
        let result = (job.run(&dir, simulator, args.vcd))
            .map_err(explain_missing)
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
