//! The synthesized-logic report of `vtq area --synth`: the treelet hardware (the treelet count
//! table, the treelet queue table and the treelet controller, synthesized with
//! [`crate::synth::synthesize_logic`], and the composed treelet RT unit's wiring, synthesized
//! with [`crate::synth::synthesize_logic_hierarchy`]: its record crossbars and free-id words
//! once, counted per instance) and the RT unit's control (hierarchically too: its lane module
//! once, counted per lane; the intersection datapath a black box), priced with
//! [`crate::logic_area`], beside the storage model of [`crate::area`] and the paper's section
//! 6.5 figures; and the treelet hardware's logic over the RT unit control's.
//!
//! The blocks are synthesized in parallel (one Yosys process each).

use crate::area::{AreaReport, NODES_NM};
use crate::error::GenError;
use crate::logic_area::{logic_area, LogicArea, DFF_X1_UM2, NAND2_X1_45NM_UM2};
use crate::synth::{synthesize_logic, synthesize_logic_hierarchy, SynthReport};
use serde::Serialize;
use std::fmt;
use std::path::Path;
use std::time::Instant;
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::rt_unit::{NoDatapath, RtUnit, RtUnitParams};
use vtq_hdl::treelet_rt_unit::{TreeletRtUnit, TreeletRtUnitParams};
use vtq_hdl::{Block, BlockDesc, HwConfig};

/// What the report's RT-unit line covers.
pub const RT_UNIT_NOTE: &str = "rt_unit: the RT unit's control (warp buffer with its per-ray \
     stacks, memory scheduler, response FIFO, completion and the controller's commands) without \
     the box/triangle datapath, which vtq does not model (a black box here); the overhead is \
     the treelet hardware's logic over this control logic, so over a whole RT unit with its \
     datapath it is smaller. The RT unit's RTL serves both designs: its other-treelet stack, \
     part of the proposal, is counted in the RT unit";

/// The paper's own figures (section 6.5): storage sizes only; it gives no logic or mm^2 area.
pub const PAPER_NOTE: &str = "paper (section 6.5): treelet count table 2.2 KB (600 x (19 + 12) \
     b), treelet queue table 6.29 KB (128 x (19 + 32 x 12) b, in the L1), ray records 128 KB (in \
     the L2); it reports no logic area, gate count or mm^2";

/// One synthesized block.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockLogic {
    /// Yosys' statistics.
    pub synth: SynthReport,
    /// Its NAND2 equivalents and area.
    pub logic: LogicArea,
    /// Bits of the latency-1 memories (SRAM arrays) Yosys kept as memories: storage, in the
    /// storage model's table, not in the logic area.
    pub sram_bits: u64,
    /// The storage model's structure this block holds (`None` for the controller).
    pub structure: Option<String>,
    /// Seconds Yosys took.
    pub seconds: f64,
}

impl BlockLogic {
    /// Its row of the report's table.
    fn row(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:<22} {:>8} {:>10} {:>10.0} {:>9.0}",
            self.synth.top,
            self.synth.cells,
            self.synth.flip_flops,
            self.logic.nand2_eq,
            self.logic.flip_flop_nand2_eq
        )?;
        for (_, a) in &self.logic.area_mm2 {
            write!(f, " {:>11}", sig3(*a))?;
        }
        let sram = if self.sram_bits > 0 {
            format!("{} b", self.sram_bits)
        } else {
            "-".to_string()
        };
        writeln!(f, " {:>9} {:>5.1}s", sram, self.seconds)?;
        Ok(())
    }
}

/// The report: the blocks and their sum.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogicReport {
    /// Count table, queue table, controller, the treelet RT unit's wiring.
    pub blocks: Vec<BlockLogic>,
    /// Sum of the blocks' NAND2 equivalents.
    pub total_nand2_eq: f64,
    /// Sum of the blocks' areas per node of [`NODES_NM`]: (node, mm^2).
    pub total_mm2: Vec<(f64, f64)>,
    /// Storage-model area of each block's structure at each node as SRAM, (name, [(node,
    /// mm^2)]), from the [`AreaReport`] given.
    pub storage_sram_mm2: Vec<(String, Vec<(f64, f64)>)>,
    /// The RT unit's control, synthesized hierarchically without its datapath.
    pub rt_unit_logic: BlockLogic,
    /// The treelet hardware's NAND2 equivalents over the RT unit control's.
    pub overhead: f64,
    /// Bits of the RT unit's other-treelet stacks (a stack per ray, which treelet traversal
    /// adds to the baseline's one): inside `rt_unit_logic`, not in the treelet hardware.
    pub other_stack_bits: u64,
    /// Those bits' NAND2 equivalents as DFF_X1 cells alone (a lower bound: no enable or
    /// multiplexer).
    pub other_stack_nand2_eq: f64,
    /// [`RT_UNIT_NOTE`].
    pub rt_unit: String,
    /// [`PAPER_NOTE`].
    pub paper: String,
}

/// Bits of `desc`'s memories read with latency 1 or more (SRAM arrays).
fn sram_bits(desc: &BlockDesc) -> u64 {
    desc.memories
        .iter()
        .filter(|m| m.read_latency >= 1)
        .map(|m| m.depth as u64 * m.width as u64)
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

/// Synthesizes the three blocks of `cfg` (the controller with `features`) and the RT unit's
/// control (with `rt`) in `work_dir` (which must exist), one Yosys process each in parallel,
/// and prices them beside `storage`.
pub fn logic_report(
    cfg: &HwConfig,
    features: ControllerFeatures,
    rt: &RtUnitParams,
    storage: &AreaReport,
    work_dir: &Path,
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
    let modules = crate::rtl::rtl_modules(cfg, features)?;
    let mut files = Vec::new();
    for (name, text) in &modules {
        let path = work_dir.join(format!("{name}.v"));
        crate::tools::write_file(&path, text)?;
        files.push((name.clone(), path));
    }
    let wiring_file = work_dir.join("treelet_rt_unit_wiring.v");
    crate::tools::write_file(&wiring_file, &crate::rtl::treelet_wiring_verilog(&unit)?)?;
    let rt_files = [
        work_dir.join("rt_unit.v"),
        work_dir.join("rt_datapath_black_box.v"),
    ];
    crate::tools::write_file(&rt_files[0], &crate::rtl::rt_unit_verilog(cfg, rt)?)?;
    crate::tools::write_file(&rt_files[1], &crate::rtl::datapath_blackbox_verilog())?;
    let (results, rt_result): (Vec<Result<(SynthReport, f64), GenError>>, _) =
        std::thread::scope(|s| {
            let rt_unit = s.spawn(|| {
                let start = Instant::now();
                let r = synthesize_logic_hierarchy(&rt_files, "rt_unit", work_dir)?;
                Ok((
                    without_black_box(r, "rt_datapath"),
                    start.elapsed().as_secs_f64(),
                ))
            });
            let mut handles: Vec<_> = files
                .iter()
                .map(|(name, path)| {
                    s.spawn(move || {
                        let start = Instant::now();
                        let r = synthesize_logic(std::slice::from_ref(path), name, work_dir)?;
                        Ok((r, start.elapsed().as_secs_f64()))
                    })
                })
                .collect();
            let wiring = &wiring_file;
            handles.push(s.spawn(move || {
                let start = Instant::now();
                let top = "treelet_rt_unit_wiring";
                let r = synthesize_logic_hierarchy(std::slice::from_ref(wiring), top, work_dir)?;
                Ok((r, start.elapsed().as_secs_f64()))
            }));
            let blocks = handles
                .into_iter()
                .map(|h| h.join().expect("a synthesis thread panicked"))
                .collect();
            let rt: Result<(SynthReport, f64), GenError> =
                rt_unit.join().expect("a synthesis thread panicked");
            (blocks, rt)
        });
    let (rt_synth, rt_seconds) = rt_result?;
    let rt_unit_logic = BlockLogic {
        logic: logic_area(&rt_synth),
        synth: rt_synth,
        sram_bits: 0,
        structure: None,
        seconds: rt_seconds,
    };
    let mut blocks = Vec::new();
    for ((result, desc), structure) in results.into_iter().zip(&descs).zip(structures) {
        let (synth, seconds) = result?;
        let sram = if synth.memory_cells > 0 {
            sram_bits(desc)
        } else {
            0
        };
        blocks.push(BlockLogic {
            logic: logic_area(&synth),
            synth,
            sram_bits: sram,
            structure: structure.map(str::to_string),
            seconds,
        });
    }
    let total_nand2_eq: f64 = blocks.iter().map(|b| b.logic.nand2_eq).sum();
    let overhead = total_nand2_eq / rt_unit_logic.logic.nand2_eq;
    // The other-treelet stacks as the RT unit's description sizes them.
    let other_stack_bits = RtUnit::new(cfg.clone(), rt.clone(), NoDatapath)?
        .describe()
        .memories
        .iter()
        .filter(|m| m.name == "other_stack")
        .map(|m| u64::from(m.depth) * u64::from(m.width))
        .sum();
    let other_stack_nand2_eq = other_stack_bits as f64 * DFF_X1_UM2 / NAND2_X1_45NM_UM2;
    let total_mm2 = NODES_NM
        .iter()
        .enumerate()
        .map(|(i, &f)| (f, blocks.iter().map(|b| b.logic.area_mm2[i].1).sum()))
        .collect();
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
        blocks,
        total_nand2_eq,
        total_mm2,
        storage_sram_mm2,
        rt_unit_logic,
        overhead,
        other_stack_bits,
        other_stack_nand2_eq,
        rt_unit: RT_UNIT_NOTE.to_string(),
        paper: PAPER_NOTE.to_string(),
    })
}

/// `x` with three significant digits.
fn sig3(x: f64) -> String {
    if x == 0.0 {
        return "0".to_string();
    }
    let digits = 2 - x.abs().log10().floor() as i32;
    format!("{x:.prec$}", prec = digits.max(0) as usize)
}

impl fmt::Display for LogicReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Synthesized logic (Yosys generic synthesis, gen::synth::LOGIC_SCRIPT; NAND2 eq. = \
             NanGate45 cell area / NAND2_X1 {NAND2_X1_45NM_UM2} um^2; 22 nm = 45 nm x (22/45)^2; \
             cells only, no routing)"
        )?;
        write!(
            f,
            "{:<22} {:>8} {:>10} {:>10} {:>9}",
            "block", "cells", "flip-flops", "NAND2 eq.", "(of FFs)"
        )?;
        for nm in NODES_NM {
            write!(f, " {:>11}", format!("mm^2 {nm}nm"))?;
        }
        writeln!(f, " {:>9} {:>6}", "SRAM kept", "yosys")?;
        for b in &self.blocks {
            b.row(f)?;
        }
        write!(
            f,
            "{:<22} {:>8} {:>10} {:>10.0} {:>9}",
            "treelet hardware",
            self.blocks.iter().map(|b| b.synth.cells).sum::<u64>(),
            self.blocks.iter().map(|b| b.synth.flip_flops).sum::<u64>(),
            self.total_nand2_eq,
            ""
        )?;
        for (_, a) in &self.total_mm2 {
            write!(f, " {:>11}", sig3(*a))?;
        }
        writeln!(f)?;
        self.rt_unit_logic.row(f)?;
        writeln!(
            f,
            "treelet hardware over the RT unit's control: {:.1}% ({:.0} / {:.0} NAND2 eq.); \
             the RT unit's other-treelet stacks, in its figure, are {} flip-flops (at least {:.0} \
             NAND2 eq., {:.1}% of the control)",
            100.0 * self.overhead,
            self.total_nand2_eq,
            self.rt_unit_logic.logic.nand2_eq,
            self.other_stack_bits,
            self.other_stack_nand2_eq,
            100.0 * self.other_stack_nand2_eq / self.rt_unit_logic.logic.nand2_eq
        )?;
        for b in self.blocks.iter().chain([&self.rt_unit_logic]) {
            if !b.logic.unpriced.is_empty() {
                writeln!(
                    f,
                    "warning: {}: cells without a price: {:?}",
                    b.synth.top, b.logic.unpriced
                )?;
            }
            if !b.synth.is_clean() {
                writeln!(f, "warning: {}: Yosys warnings or latches", b.synth.top)?;
            }
        }
        writeln!(
            f,
            "(the count table's RTL keeps its entries in flip-flops, a CAM with scan ports: its \
             logic includes its storage; the queue table's SRAM arrays are storage, not logic; \
             the wiring keeps each slot's fill of whole ray records in flip-flops and moves \
             records through one-hot crossbars, up to a warp of them each way a cycle)"
        )?;
        for (name, areas) in &self.storage_sram_mm2 {
            let list: Vec<String> = areas
                .iter()
                .map(|(nm, a)| format!("{} mm^2 at {nm} nm", sig3(*a)))
                .collect();
            writeln!(f, "storage model, {name} as SRAM: {}", list.join(", "))?;
        }
        writeln!(f, "{}", self.rt_unit)?;
        writeln!(f, "{}", self.paper)
    }
}
