//! The synthesized-logic report of `vtq area --synth`: the treelet hardware (the treelet count
//! table, the treelet queue table and the treelet controller, synthesized with
//! [`crate::synth::synthesize_logic`], and the composed treelet RT unit's wiring, synthesized
//! with [`crate::synth::synthesize_logic_hierarchy`]: its record crossbars and free-id words
//! once, counted per instance) and the RT unit's control (hierarchically too: its lane module
//! once, counted per lane; the intersection datapath a black box, priced instead from a
//! published datapath by [`crate::datapath_area`]), priced with [`crate::logic_area`]; the
//! SRAM arrays Yosys keeps as memory macros, priced by [`crate::area`]'s SRAM model with the
//! ports the block declares; the totals per block and the overheads of the treelet hardware
//! over the whole RT unit and an SM ([`SM_SOURCE`]), beside the paper's section 6.5 figures
//! (`display.rs` prints it).
//!
//! The blocks are synthesized in parallel (one Yosys process each); a block whose RTL, script
//! and Yosys are unchanged since a run in the same work directory is read back from
//! [`crate::synth_cache`] instead.

mod display;

use crate::area::{sram_area_mm2, AreaReport, Ports, NODES_NM};
use crate::datapath_area::{datapath_area, DatapathArea};
use crate::error::GenError;
use crate::logic_area::{logic_area, LogicArea, DFF_X1_UM2, NAND2_X1_45NM_UM2};
use crate::synth::{
    synthesize_logic, synthesize_logic_hierarchy, SynthReport, HIERARCHY_LOGIC_SCRIPT, LOGIC_SCRIPT,
};
use crate::synth_cache::{cached, yosys_version, Synthesis};
use serde::Serialize;
use std::path::{Path, PathBuf};
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::rt_unit::{NoDatapath, RtUnit, RtUnitParams};
use vtq_hdl::treelet_rt_unit::{TreeletRtUnit, TreeletRtUnitParams};
use vtq_hdl::{Block, BlockDesc, HwConfig, MemDesc};

/// What the report's RT-unit line covers.
pub const RT_UNIT_NOTE: &str = "rt_unit: the RT unit's control (warp buffer with its per-ray \
     stacks, memory scheduler, response FIFO, completion and the controller's commands); its \
     box/triangle datapath is a black box in the RTL, priced from a published datapath (the \
     datapath line). The RT unit's RTL serves both designs: its other-treelet stack, part of \
     the proposal, is counted in the RT unit";

/// The paper's own figures (section 6.5): storage sizes only; it gives no logic or mm^2 area.
pub const PAPER_NOTE: &str = "paper (section 6.5): treelet count table 2.2 KB (600 x (19 + 12) \
     b), treelet queue table 6.29 KB (128 x (19 + 32 x 12) b, in the L1), ray records 128 KB (in \
     the L2); it reports no logic area, gate count or mm^2";

/// The SM whose area the overhead is set against: NVIDIA's Turing architecture whitepaper
/// (2018) gives TU106 (the RTX 2060's die) as 445 mm^2 with 36 SMs in TSMC 12 nm FFN.
pub const SM_SOURCE: &str = "SM: TU106 die area / SMs, 445 mm^2 / 36 = 12.4 mm^2 at TSMC 12 nm \
     (NVIDIA Turing architecture whitepaper, 2018), an upper bound on an SM (the die's L2, \
     memory interfaces and I/O are shared out); the treelet hardware scaled from 45 nm by \
     (12/45)^2, more than FinFET nodes shrink logic; so the share is a lower bound";

/// TU106's die area in mm^2 ([`SM_SOURCE`]).
pub const SM_DIE_MM2: f64 = 445.0;
/// TU106's SMs ([`SM_SOURCE`]).
pub const SM_COUNT: u32 = 36;
/// The node of [`SM_DIE_MM2`] in nm.
pub const SM_NODE_NM: f64 = 12.0;

/// One memory macro: an SRAM array Yosys kept, priced by the storage model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MacroArea {
    /// The array's name in the block's description.
    pub name: String,
    /// Identical arrays (banks) of this shape; the area is theirs together.
    pub banks: u32,
    /// Words (of one bank).
    pub depth: u32,
    /// Bits per word.
    pub width: u32,
    /// Read ports, as the block declares them.
    pub read_ports: u32,
    /// Write ports, as the block declares them.
    pub write_ports: u32,
    /// The storage model's port kind for those counts.
    pub ports: Ports,
    /// Area per node of [`NODES_NM`] in mm^2: (node, area).
    pub area_mm2: Vec<(f64, f64)>,
}

/// One synthesized block.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockLogic {
    /// Yosys' statistics.
    pub synth: SynthReport,
    /// Its NAND2 equivalents and area.
    pub logic: LogicArea,
    /// Bits of the latency-1 memories (SRAM arrays) Yosys kept as memories: storage, in
    /// [`BlockLogic::macros`], not in the logic area.
    pub sram_bits: u64,
    /// Those arrays as memory macros.
    pub macros: Vec<MacroArea>,
    /// The storage model's structure this block holds (`None` for the controller).
    pub structure: Option<String>,
    /// Seconds Yosys took.
    pub seconds: f64,
    /// Whether the synthesis was read back from the work directory's cache.
    pub reused: bool,
}

impl BlockLogic {
    /// Logic plus macros per node of [`NODES_NM`] in mm^2.
    pub fn total_mm2(&self) -> Vec<(f64, f64)> {
        self.logic
            .area_mm2
            .iter()
            .enumerate()
            .map(|(i, &(nm, a))| {
                (
                    nm,
                    a + self.macros.iter().map(|m| m.area_mm2[i].1).sum::<f64>(),
                )
            })
            .collect()
    }
}

/// Areas per node of [`NODES_NM`]: (node, mm^2).
pub type NodeAreas = Vec<(f64, f64)>;

/// The report: the blocks, the datapath and the overheads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogicReport {
    /// Count table, queue table, controller, the treelet RT unit's wiring.
    pub blocks: Vec<BlockLogic>,
    /// Sum of the blocks' NAND2 equivalents (logic only).
    pub total_nand2_eq: f64,
    /// Sum of the blocks' logic areas per node of [`NODES_NM`].
    pub total_mm2: NodeAreas,
    /// The paper's three blocks (count table, queue table, controller): logic plus macros.
    pub proposal_mm2: NodeAreas,
    /// The proposal's logic in NAND2 equivalents.
    pub proposal_nand2_eq: f64,
    /// The composed block's wiring: logic (it keeps no macros).
    pub wiring_mm2: NodeAreas,
    /// Storage-model area of each block's structure at each node as SRAM, (name, [(node,
    /// mm^2)]), from the [`AreaReport`] given.
    pub storage_sram_mm2: Vec<(String, NodeAreas)>,
    /// The RT unit's control, synthesized hierarchically without its datapath.
    pub rt_unit_logic: BlockLogic,
    /// The RT unit's datapath: one RayFlex datapath per `rt_datapath` instance (a lower bound).
    pub datapath: DatapathArea,
    /// The whole RT unit without the treelet hardware: control plus datapath.
    pub rt_unit_mm2: NodeAreas,
    /// The treelet hardware's logic NAND2 equivalents over the RT unit control's.
    pub overhead: f64,
    /// The proposal's area over the whole RT unit's (at 45 nm): an upper bound, the datapath
    /// being a lower bound.
    pub proposal_over_rt_unit: f64,
    /// The proposal and the wiring over the whole RT unit (at 45 nm).
    pub treelet_over_rt_unit: f64,
    /// The proposal's area over an SM's ([`SM_SOURCE`]): a lower bound.
    pub proposal_over_sm: f64,
    /// The proposal and the wiring over an SM's.
    pub treelet_over_sm: f64,
    /// Flip-flop bits of the RT unit's other-treelet stacks (a stack per ray, which treelet
    /// traversal adds to the baseline's one; each lane's window and top copy): inside
    /// `rt_unit_logic`, not in the treelet hardware.
    pub other_stack_bits: u64,
    /// SRAM bits of the RT unit's other-treelet stacks (their rings, among `rt_unit_logic`'s
    /// macros).
    pub other_stack_sram_bits: u64,
    /// Those bits' NAND2 equivalents as DFF_X1 cells alone (a lower bound: no enable or
    /// multiplexer).
    pub other_stack_nand2_eq: f64,
    /// [`RT_UNIT_NOTE`].
    pub rt_unit: String,
    /// [`SM_SOURCE`].
    pub sm: String,
    /// [`PAPER_NOTE`].
    pub paper: String,
}

/// The storage model's port kind for `r` read and `w` write ports: `None` for an array without
/// a port or with more than one of either (the model has no multi-ported array).
pub fn macro_ports(r: u32, w: u32) -> Option<Ports> {
    match (r, w) {
        (1, 0) | (0, 1) => Some(Ports::OneRw),
        (1, 1) => Some(Ports::OneROneW),
        _ => None,
    }
}

/// The latency-1 memories of `desc` (the SRAM arrays Yosys keeps) as macros.
fn macros(desc: &BlockDesc) -> Result<Vec<MacroArea>, GenError> {
    desc.memories
        .iter()
        .filter(|m| m.read_latency >= 1)
        .map(|m: &MemDesc| {
            let ports =
                macro_ports(m.read_ports, m.write_ports).ok_or_else(|| GenError::InvalidDesc {
                    block: desc.name.clone(),
                    reason: format!(
                        "memory `{}` has {} read and {} write ports; the SRAM model prices 1RW \
                         and 1R+1W arrays only",
                        m.name, m.read_ports, m.write_ports
                    ),
                })?;
            let bits = u64::from(m.depth) * u64::from(m.width);
            Ok(MacroArea {
                name: m.name.clone(),
                banks: m.banks,
                depth: m.depth,
                width: m.width,
                read_ports: m.read_ports,
                write_ports: m.write_ports,
                ports,
                area_mm2: NODES_NM
                    .iter()
                    .map(|&f| (f, f64::from(m.banks) * sram_area_mm2(bits, f, ports)))
                    .collect(),
            })
        })
        .collect()
}

/// Bits held by `macros`.
fn macro_bits(macros: &[MacroArea]) -> u64 {
    macros
        .iter()
        .map(|m| u64::from(m.banks) * u64::from(m.depth) * u64::from(m.width))
        .sum()
}

/// `report` without the cells of black-box module `module` (instances of it, whatever their
/// parameters).
fn without_black_box(mut report: SynthReport, module: &str) -> SynthReport {
    let boxes: Vec<String> = report
        .cells_by_type
        .keys()
        .filter(|k| k.contains(module))
        .cloned()
        .collect();
    for k in boxes {
        report.cells -= report.cells_by_type.remove(&k).unwrap_or(0);
    }
    report
}

/// Sums per node.
fn add(a: &[(f64, f64)], b: &[(f64, f64)]) -> NodeAreas {
    a.iter()
        .zip(b)
        .map(|(&(nm, x), &(_, y))| (nm, x + y))
        .collect()
}

/// One block's synthesis job: files, top, whether hierarchical.
struct Job {
    files: Vec<PathBuf>,
    top: String,
    hierarchy: bool,
}

impl Job {
    /// Runs (or reuses) the job's synthesis in `work_dir` under Yosys `yosys`.
    fn run(&self, work_dir: &Path, yosys: &str) -> Result<Synthesis, GenError> {
        let script = if self.hierarchy {
            HIERARCHY_LOGIC_SCRIPT
        } else {
            LOGIC_SCRIPT
        }
        .replace("{top}", &self.top);
        cached(work_dir, yosys, &script, &self.top, &self.files, || {
            if self.hierarchy {
                synthesize_logic_hierarchy(&self.files, &self.top, work_dir)
            } else {
                synthesize_logic(&self.files, &self.top, work_dir)
            }
        })
    }
}

/// Synthesizes the three blocks of `cfg` (the controller with `features`), the composed
/// block's wiring and the RT unit's control (with `rt`) in `work_dir` (which must exist), one
/// Yosys process each in parallel (or read back from the work directory's cache), and prices
/// them beside `storage`, the datapath and an SM.
pub fn logic_report(
    cfg: &HwConfig,
    features: ControllerFeatures,
    rt: &RtUnitParams,
    storage: &AreaReport,
    work_dir: &Path,
) -> Result<LogicReport, GenError> {
    logic_report_with(cfg, features, rt, storage, work_dir, &|_, _| {})
}

/// Called with a block's top module and its synthesis as each one finishes (from the thread
/// that ran it).
pub type Progress<'a> = &'a (dyn Fn(&str, &Synthesis) + Sync);

/// [`logic_report`], telling `progress` as each block's synthesis finishes.
pub fn logic_report_with(
    cfg: &HwConfig,
    features: ControllerFeatures,
    rt: &RtUnitParams,
    storage: &AreaReport,
    work_dir: &Path,
    progress: Progress<'_>,
) -> Result<LogicReport, GenError> {
    let unit = TreeletRtUnit::new(
        cfg.clone(),
        TreeletRtUnitParams {
            rt: rt.clone(),
            features,
            ray_base: 0,
        },
        NoDatapath,
    )?;
    let descs = [
        CountTable::new(cfg)?.describe(),
        QueueTable::new(cfg)?.describe(),
        TreeletController::new(cfg.clone(), features)?.describe(),
        crate::rtl::treelet_wiring_desc(&unit),
    ];
    let structures = [
        Some("treelet count table"),
        Some("treelet queue table"),
        None,
        None,
    ];
    let jobs = write_jobs(cfg, features, rt, &unit, work_dir)?;
    let mut results = run_jobs(&jobs, work_dir, progress)?;
    let rt_synthesis = results.pop().expect("the RT unit's job")?;
    let rt_synth = without_black_box(rt_synthesis.report, "rt_datapath");
    let rt_desc = RtUnit::new(cfg.clone(), rt.clone(), NoDatapath)?.describe();
    let rt_macros = if rt_synth.memory_cells > 0 {
        macros(&rt_desc)?
    } else {
        Vec::new()
    };
    let rt_unit_logic = BlockLogic {
        logic: logic_area(&rt_synth),
        synth: rt_synth,
        sram_bits: macro_bits(&rt_macros),
        macros: rt_macros,
        structure: None,
        seconds: rt_synthesis.seconds,
        reused: rt_synthesis.reused,
    };
    let mut blocks = Vec::new();
    for ((result, desc), structure) in results.into_iter().zip(&descs).zip(structures) {
        let Synthesis {
            report: synth,
            seconds,
            reused,
        } = result?;
        let kept = if synth.memory_cells > 0 {
            macros(desc)?
        } else {
            Vec::new()
        };
        blocks.push(BlockLogic {
            logic: logic_area(&synth),
            synth,
            sram_bits: macro_bits(&kept),
            macros: kept,
            structure: structure.map(str::to_string),
            seconds,
            reused,
        });
    }
    let total_nand2_eq: f64 = blocks.iter().map(|b| b.logic.nand2_eq).sum();
    let overhead = total_nand2_eq / rt_unit_logic.logic.nand2_eq;
    // The other-treelet stacks as the RT unit's description sizes them: flip-flops (each
    // lane's window and top copy) and the SRAM ring.
    let other_stack_bits = rt_desc
        .registers
        .iter()
        .filter(|r| r.name == "lane_other_window" || r.name == "lane_other_top")
        .map(|r| u64::from(r.count) * u64::from(r.width))
        .sum();
    let other_stack_sram_bits = rt_desc
        .memories
        .iter()
        .filter(|m| m.name == "other_stack")
        .map(|m| u64::from(m.banks) * u64::from(m.depth) * u64::from(m.width))
        .sum();
    let other_stack_nand2_eq = other_stack_bits as f64 * DFF_X1_UM2 / NAND2_X1_45NM_UM2;
    let per_node = |pick: &dyn Fn(&BlockLogic) -> Vec<(f64, f64)>, which: &[BlockLogic]| {
        NODES_NM
            .iter()
            .enumerate()
            .map(|(i, &f)| (f, which.iter().map(|b| pick(b)[i].1).sum()))
            .collect::<NodeAreas>()
    };
    let total_mm2 = per_node(&|b| b.logic.area_mm2.clone(), &blocks);
    let (proposal, wiring) = blocks.split_at(3);
    let proposal_mm2 = per_node(&|b| b.total_mm2(), proposal);
    let proposal_nand2_eq = proposal.iter().map(|b| b.logic.nand2_eq).sum();
    let wiring_mm2 = per_node(&|b| b.total_mm2(), wiring);
    // One RayFlex datapath per `rt_datapath` instance: one per lane index.
    let datapath = datapath_area(cfg.warp_size);
    let rt_unit_mm2 = add(&rt_unit_logic.total_mm2(), &datapath.area_mm2);
    let at45 = |a: &NodeAreas| a[0].1;
    let sm_mm2 = SM_DIE_MM2 / f64::from(SM_COUNT);
    let to_sm_node = (SM_NODE_NM / NODES_NM[0]).powi(2);
    let treelet_45 = at45(&proposal_mm2) + at45(&wiring_mm2);
    let storage_sram_mm2 = storage
        .structures
        .iter()
        .filter(|s| structures.contains(&Some(s.name.as_str())))
        .map(|s| {
            (
                s.name.clone(),
                s.area.iter().map(|a| (a.feature_nm, a.sram_mm2)).collect(),
            )
        })
        .collect();
    Ok(LogicReport {
        total_nand2_eq,
        total_mm2,
        proposal_over_rt_unit: at45(&proposal_mm2) / at45(&rt_unit_mm2),
        treelet_over_rt_unit: treelet_45 / at45(&rt_unit_mm2),
        proposal_over_sm: at45(&proposal_mm2) * to_sm_node / sm_mm2,
        treelet_over_sm: treelet_45 * to_sm_node / sm_mm2,
        proposal_mm2,
        proposal_nand2_eq,
        wiring_mm2,
        blocks,
        storage_sram_mm2,
        rt_unit_logic,
        datapath,
        rt_unit_mm2,
        overhead,
        other_stack_bits,
        other_stack_sram_bits,
        other_stack_nand2_eq,
        rt_unit: RT_UNIT_NOTE.to_string(),
        sm: SM_SOURCE.to_string(),
        paper: PAPER_NOTE.to_string(),
    })
}

/// Writes the RTL of the five synthesized blocks into `work_dir`: the three of
/// [`crate::rtl::rtl_modules`], the composed block's wiring and the RT unit's control (with its
/// datapath as a black box), in the report's order.
fn write_jobs<D: vtq_hdl::rt_unit::NodeDatapath>(
    cfg: &HwConfig,
    features: ControllerFeatures,
    rt: &RtUnitParams,
    unit: &TreeletRtUnit<D>,
    work_dir: &Path,
) -> Result<Vec<Job>, GenError> {
    let mut jobs = Vec::new();
    for (name, text) in crate::rtl::rtl_modules(cfg, features)? {
        let path = work_dir.join(format!("{name}.v"));
        crate::tools::write_file(&path, &text)?;
        jobs.push(Job {
            files: vec![path],
            top: name,
            hierarchy: false,
        });
    }
    let wiring_file = work_dir.join("treelet_rt_unit_wiring.v");
    crate::tools::write_file(&wiring_file, &crate::rtl::treelet_wiring_verilog(unit)?)?;
    jobs.push(Job {
        files: vec![wiring_file],
        top: "treelet_rt_unit_wiring".to_string(),
        hierarchy: true,
    });
    let rt_files = vec![
        work_dir.join("rt_unit.v"),
        work_dir.join("rt_datapath_black_box.v"),
    ];
    crate::tools::write_file(&rt_files[0], &crate::rtl::rt_unit_verilog(cfg, rt)?)?;
    crate::tools::write_file(&rt_files[1], &crate::rtl::datapath_blackbox_verilog())?;
    jobs.push(Job {
        files: rt_files,
        top: "rt_unit".to_string(),
        hierarchy: true,
    });
    Ok(jobs)
}

/// Runs `jobs` in parallel, one thread (and Yosys process) each, telling `progress`.
fn run_jobs(
    jobs: &[Job],
    work_dir: &Path,
    progress: Progress<'_>,
) -> Result<Vec<Result<Synthesis, GenError>>, GenError> {
    let yosys = yosys_version(work_dir)?;
    Ok(std::thread::scope(|s| {
        let handles: Vec<_> = jobs
            .iter()
            .map(|job| {
                s.spawn(|| {
                    let r = job.run(work_dir, &yosys);
                    if let Ok(done) = &r {
                        progress(&job.top, done);
                    }
                    r
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a synthesis thread panicked"))
            .collect()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn macro_ports_follow_the_declared_ports() {
        assert_eq!(macro_ports(1, 0), Some(Ports::OneRw));
        assert_eq!(macro_ports(0, 1), Some(Ports::OneRw));
        assert_eq!(macro_ports(1, 1), Some(Ports::OneROneW));
        assert_eq!(macro_ports(0, 0), None);
        assert_eq!(macro_ports(2, 1), None);
        assert_eq!(macro_ports(1, 2), None);
    }
}
