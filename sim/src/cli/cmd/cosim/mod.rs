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

mod replay;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use vtq_gen::cosim::{
    record, run_cosim, write_rust_vcd, CosimOptions, CosimResult, RtUnitWithStatus, Simulator,
    Trace, RESET_CYCLES, RTL_VCD_FILE, RUST_VCD_FILE,
};
use vtq_gen::rtl::{
    controller_verilog, count_table_verilog, queue_table_verilog, rt_unit_verilog,
    toy_datapath_verilog,
};
use vtq_gen::stimulus::controller::controller_inputs;
use vtq_gen::stimulus::rt_unit::rt_unit_inputs;
use vtq_gen::stimulus::{count_table_inputs, queue_table_inputs};
use vtq_gen::GenError;
use vtq_hdl::rt_unit::RtUnitParams;
use vtq_hdl::Block;

use super::options::{CacheArgs, ConfigArgs};
use crate::model::config::SimConfig;
use replay::replay_jobs;

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
