//! The printed form of [`LogicReport`]: a table of the synthesized blocks, the memory macros,
//! the datapath, the totals per part of the RT unit and the overhead lines, then the notes.

use super::{add, BlockLogic, LogicReport, NodeAreas};
use crate::area::{sig3, NODES_NM};
use crate::logic_area::NAND2_X1_45NM_UM2;
use std::fmt;

/// The areas of `a`, one column per node.
fn areas(f: &mut fmt::Formatter<'_>, a: &NodeAreas) -> fmt::Result {
    for (_, x) in a {
        write!(f, " {:>11}", sig3(*x))?;
    }
    Ok(())
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
        areas(f, &self.logic.area_mm2)?;
        let sram = if self.sram_bits > 0 {
            format!("{} b", self.sram_bits)
        } else {
            "-".to_string()
        };
        let took = if self.reused {
            format!("{:.1}s (reused)", self.seconds)
        } else {
            format!("{:.1}s", self.seconds)
        };
        writeln!(f, " {sram:>9}  {took}")
    }
}

/// A total's line: its name and its areas.
fn total(f: &mut fmt::Formatter<'_>, name: &str, a: &NodeAreas) -> fmt::Result {
    write!(f, "  {name:<70}")?;
    areas(f, a)?;
    writeln!(f)
}

impl LogicReport {
    /// The table of the synthesized blocks.
    fn table(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
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
        writeln!(f, " {:>9}  yosys", "macros")?;
        for b in &self.blocks {
            b.row(f)?;
        }
        self.rt_unit_logic.row(f)?;
        writeln!(f)?;
        Ok(())
    }

    /// The memory macros and what is not a macro yet.
    fn macros(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Memory macros (SRAM arrays Yosys keeps; the storage model of docs/area.md with the \
             ports the block declares)"
        )?;
        let all = self.blocks.iter().chain([&self.rt_unit_logic]);
        for b in all.filter(|b| !b.macros.is_empty()) {
            for m in &b.macros {
                let shape = if m.banks > 1 {
                    format!("{} x {} x {}", m.banks, m.depth, m.width)
                } else {
                    format!("{} x {}", m.depth, m.width)
                };
                write!(
                    f,
                    "  {:<22} {:<8} {:>14} {}R {}W {:<6}",
                    b.synth.top,
                    m.name,
                    shape,
                    m.read_ports,
                    m.write_ports,
                    m.ports.label()
                )?;
                areas(f, &m.area_mm2)?;
                writeln!(f, " mm^2")?;
            }
        }
        writeln!(
            f,
            "  (not a macro: the count table's entries, a CAM searched every cycle)"
        )?;
        writeln!(f)?;
        Ok(())
    }

    /// The datapath line and the totals per part of the RT unit.
    fn totals(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.datapath;
        writeln!(
            f,
            "Datapath (estimate, a lower bound): {} x {:.0} NAND2 eq. = {:.0} NAND2 eq. ({} mm^2 \
             at 45 nm, {} at 22 nm): per datapath {} FP32 adds, {} multiply-adds, {} multiplies, \
             {} compares, {} mux bits; {}",
            d.units,
            d.unit_nand2_eq,
            d.nand2_eq,
            sig3(d.area_mm2[0].1),
            sig3(d.area_mm2[1].1),
            d.per_unit.adders,
            d.per_unit.mul_adds,
            d.per_unit.multipliers,
            d.per_unit.comparators(),
            d.per_unit.mux_bits(),
            d.source
        )?;
        writeln!(f)?;
        write!(f, "{:<72}", "Totals, logic + macros")?;
        for nm in NODES_NM {
            write!(f, " {:>11}", format!("mm^2 {nm}nm"))?;
        }
        writeln!(f)?;
        total(
            f,
            &format!(
                "treelet proposal: count table, queue table, controller ({:.0} NAND2 eq.)",
                self.proposal_nand2_eq
            ),
            &self.proposal_mm2,
        )?;
        total(
            f,
            "treelet RT unit's wiring (fills' lanes, id stack, events)",
            &self.wiring_mm2,
        )?;
        total(
            f,
            "RT unit's control (logic + SRAM: stack rings, node buffer)",
            &self.rt_unit_logic.total_mm2(),
        )?;
        total(
            f,
            "RT unit: control + datapath (without the treelet hardware)",
            &self.rt_unit_mm2,
        )?;
        let with = add(
            &add(&self.rt_unit_mm2, &self.proposal_mm2),
            &self.wiring_mm2,
        );
        total(
            f,
            "RT unit with the treelet hardware (proposal + wiring)",
            &with,
        )?;
        writeln!(f)?;
        Ok(())
    }
}

impl fmt::Display for LogicReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.table(f)?;
        self.macros(f)?;
        self.totals(f)?;
        writeln!(
            f,
            "treelet proposal over the whole RT unit: at most {:.1}% (the datapath is a lower bound); \
             with the wiring as modelled: {:.1}%",
            100.0 * self.proposal_over_rt_unit,
            100.0 * self.treelet_over_rt_unit
        )?;
        writeln!(
            f,
            "treelet proposal over an SM: at least {:.3}%; with the wiring as modelled: {:.2}% ({})",
            100.0 * self.proposal_over_sm,
            100.0 * self.treelet_over_sm,
            self.sm
        )?;
        writeln!(
            f,
            "treelet hardware's logic over the RT unit's control alone: {:.1}% ({:.0} / {:.0} NAND2 \
             eq.); the RT unit's other-treelet stacks are {} SRAM bits among its macros and {} \
             flip-flops in its logic (at least {:.0} NAND2 eq., {:.1}% of the control)",
            100.0 * self.overhead,
            self.total_nand2_eq,
            self.rt_unit_logic.logic.nand2_eq,
            self.other_stack_sram_bits,
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
             logic includes its storage; the wiring writes each returning ray record straight \
             into the RT unit's lane it issues to, keeping only which lanes a fill wrote, and \
             its free ray ids in a stack of SRAM banks, a macro above)"
        )?;
        for (name, a) in &self.storage_sram_mm2 {
            let list: Vec<String> = a
                .iter()
                .map(|(nm, x)| format!("{} mm^2 at {nm} nm", sig3(*x)))
                .collect();
            writeln!(
                f,
                "storage model, {name} as SRAM where the paper keeps it: {}",
                list.join(", ")
            )?;
        }
        writeln!(f, "{}", self.rt_unit)?;
        writeln!(f, "{}", self.paper)
    }
}
