//! Logic area of synthesized RTL: NAND2-equivalent gates and area at 45 nm and 22 nm from the
//! cell counts of Yosys' generic synthesis ([`crate::synth::SynthReport`]).
//!
//! Yosys' `synth` maps a design to its internal gate library (`$_AND_`, `$_MUX_`,
//! `$_SDFFE_PP0P_`, ...), which has no area. Each internal cell type is given the area of the
//! NanGate FreePDK45 Open Cell Library cell (X1 drive strength, the `area` attribute of
//! `NangateOpenCellLibrary_typical.lib`) or cell combination that implements it
//! ([`cell_area_45nm`]); NAND2 equivalents are that area divided by NAND2_X1's 0.798 um^2
//! ([`NAND2_X1_45NM_UM2`]). NanGate45 cells sit on a 0.19 um x 1.4 um site (0.266 um^2): every
//! area below is a whole number of sites, which is how the figures were cross-checked.
//!
//! - Gates: `$_NOT_` INV_X1, `$_BUF_` BUF_X1, `$_NAND_` NAND2_X1, `$_NOR_` NOR2_X1, `$_AND_`
//!   AND2_X1, `$_OR_` OR2_X1, `$_XOR_` XOR2_X1, `$_XNOR_` XNOR2_X1, `$_MUX_` MUX2_X1, `$_AOI3_`
//!   AOI21_X1, `$_OAI3_` OAI21_X1, `$_AOI4_` AOI22_X1, `$_OAI4_` OAI22_X1. `$_ANDNOT_` (A & !B)
//!   and `$_ORNOT_` (A | !B) have no NanGate cell: INV_X1 + NOR2_X1 (!(!A | B)) and INV_X1 +
//!   NAND2_X1 (!(!A & B)); `$_NMUX_` is MUX2_X1 + INV_X1.
//! - Flip-flops: DFF_X1, or DFFR_X1 / DFFS_X1 / DFFRS_X1 with an asynchronous reset / set /
//!   both; plus MUX2_X1 for a clock enable (`E`: the output fed back), AND2_X1 for a synchronous
//!   reset and OR2_X1 for a synchronous set (`SDFF*`: the gate in front of D), and INV_X1 for a
//!   falling-edge clock. Enable and reset polarities are free (a MUX's inputs swap; the gate
//!   absorbs the inversion).
//!
//! A memory Yosys kept (`$mem_v2`: an SRAM array of [`crate::synth::synthesize_logic`]) is
//! storage, priced by [`crate::area`]'s SRAM model, not here. Any other unknown cell type (a
//! latch, a type this table lacks) gets no area and is listed in [`LogicArea::unpriced`]. The 22 nm figures scale the 45 nm areas by
//! (22 / 45)^2, the rule [`crate::area`] uses for flip-flops. docs/area.md lists the sources.

use crate::area::NODES_NM;
use crate::synth::SynthReport;
use serde::Serialize;
use std::collections::BTreeMap;

/// Area of the NanGate45 NAND2_X1 cell in um^2: one NAND2 equivalent at 45 nm.
pub const NAND2_X1_45NM_UM2: f64 = 0.798;
/// NanGate45 INV_X1 area in um^2.
pub const INV_X1_UM2: f64 = 0.532;
/// NanGate45 BUF_X1 area in um^2.
pub const BUF_X1_UM2: f64 = 0.798;
/// NanGate45 NOR2_X1 area in um^2.
pub const NOR2_X1_UM2: f64 = 0.798;
/// NanGate45 AND2_X1 and OR2_X1 area in um^2.
pub const AND2_X1_UM2: f64 = 1.064;
/// NanGate45 XOR2_X1 and XNOR2_X1 area in um^2.
pub const XOR2_X1_UM2: f64 = 1.596;
/// NanGate45 MUX2_X1 area in um^2.
pub const MUX2_X1_UM2: f64 = 1.862;
/// NanGate45 AOI21_X1 and OAI21_X1 area in um^2.
pub const AOI21_X1_UM2: f64 = 1.064;
/// NanGate45 AOI22_X1 and OAI22_X1 area in um^2.
pub const AOI22_X1_UM2: f64 = 1.330;
/// NanGate45 DFF_X1 area in um^2 (the flip-flop of [`crate::area::DFF_X1_45NM_UM2`]).
pub const DFF_X1_UM2: f64 = crate::area::DFF_X1_45NM_UM2;
/// NanGate45 DFFR_X1 and DFFS_X1 (asynchronous reset or set) area in um^2.
pub const DFFR_X1_UM2: f64 = 5.320;
/// NanGate45 DFFRS_X1 (asynchronous reset and set) area in um^2.
pub const DFFRS_X1_UM2: f64 = 6.384;

/// The 45 nm area in um^2 of one Yosys internal cell of type `cell` (see the module
/// documentation for the mapping), or `None` for a type without a price.
pub fn cell_area_45nm(cell: &str) -> Option<f64> {
    let gate = match cell {
        "$_NOT_" => Some(INV_X1_UM2),
        "$_BUF_" => Some(BUF_X1_UM2),
        "$_NAND_" => Some(NAND2_X1_45NM_UM2),
        "$_NOR_" => Some(NOR2_X1_UM2),
        "$_AND_" | "$_OR_" => Some(AND2_X1_UM2),
        "$_XOR_" | "$_XNOR_" => Some(XOR2_X1_UM2),
        "$_ANDNOT_" => Some(INV_X1_UM2 + NOR2_X1_UM2),
        "$_ORNOT_" => Some(INV_X1_UM2 + NAND2_X1_45NM_UM2),
        "$_MUX_" => Some(MUX2_X1_UM2),
        "$_NMUX_" => Some(MUX2_X1_UM2 + INV_X1_UM2),
        "$_AOI3_" | "$_OAI3_" => Some(AOI21_X1_UM2),
        "$_AOI4_" | "$_OAI4_" => Some(AOI22_X1_UM2),
        _ => None,
    };
    gate.or_else(|| flip_flop_area(cell))
}

/// The area of a fine-grained Yosys flip-flop type: `$_DFF_C_`, `$_DFF_CRV_` (asynchronous
/// reset to V), `$_DFFE_CE_`, `$_DFFE_CRVE_`, `$_SDFF_CRV_`, `$_SDFFE_CRVE_`, `$_SDFFCE_CRVE_`,
/// `$_DFFSR_CSR_`, `$_DFFSRE_CSRE_` (C, R, S, E polarity letters `P`/`N`, V the reset value).
fn flip_flop_area(cell: &str) -> Option<f64> {
    let body = cell.strip_prefix("$_")?.strip_suffix('_')?;
    let (kind, params) = body.split_once('_')?;
    let p: Vec<char> = params.chars().collect();
    let pol = |c: char| c == 'P' || c == 'N';
    let val = |c: char| c == '0' || c == '1';
    // (base cell, enable, sync reset/set) per kind, after checking the parameter letters.
    let (base, enable, sync) = match (kind, p.as_slice()) {
        ("DFF", [c]) if pol(*c) => (DFF_X1_UM2, false, None),
        ("DFF", [c, r, v]) if pol(*c) && pol(*r) && val(*v) => (DFFR_X1_UM2, false, None),
        ("DFFE", [c, e]) if pol(*c) && pol(*e) => (DFF_X1_UM2, true, None),
        ("DFFE", [c, r, v, e]) if pol(*c) && pol(*r) && val(*v) && pol(*e) => {
            (DFFR_X1_UM2, true, None)
        }
        ("SDFF", [c, r, v]) if pol(*c) && pol(*r) && val(*v) => (DFF_X1_UM2, false, Some(*v)),
        ("SDFFE" | "SDFFCE", [c, r, v, e]) if pol(*c) && pol(*r) && val(*v) && pol(*e) => {
            (DFF_X1_UM2, true, Some(*v))
        }
        ("DFFSR", [c, s, r]) if pol(*c) && pol(*s) && pol(*r) => (DFFRS_X1_UM2, false, None),
        ("DFFSRE", [c, s, r, e]) if pol(*c) && pol(*s) && pol(*r) && pol(*e) => {
            (DFFRS_X1_UM2, true, None)
        }
        _ => return None,
    };
    let mut area = base;
    if enable {
        area += MUX2_X1_UM2;
    }
    if sync.is_some() {
        // AND2 forces 0, OR2 forces 1: the same area.
        area += AND2_X1_UM2;
    }
    if p[0] == 'N' {
        area += INV_X1_UM2;
    }
    Some(area)
}

/// The logic area of one synthesized block.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogicArea {
    /// Top module.
    pub top: String,
    /// Cells after synthesis.
    pub cells: u64,
    /// Flip-flop bits.
    pub flip_flops: u64,
    /// NAND2 equivalents of every priced cell: 45 nm area / NAND2_X1 area.
    pub nand2_eq: f64,
    /// NAND2 equivalents of the flip-flops alone (with their enable and reset gates).
    pub flip_flop_nand2_eq: f64,
    /// Area at 45 nm in um^2: the priced cells' NanGate45 areas (cells only, no routing or
    /// placement utilization).
    pub area_45nm_um2: f64,
    /// Area per technology node of [`NODES_NM`] in mm^2: (node, area), scaled by (F / 45)^2.
    pub area_mm2: Vec<(f64, f64)>,
    /// Cell types without a price and their counts (none in a clean generic synthesis).
    pub unpriced: BTreeMap<String, u64>,
}

/// Prices `report`'s cells (see the module documentation).
pub fn logic_area(report: &SynthReport) -> LogicArea {
    let mut area = 0.0;
    let mut ff_area = 0.0;
    let mut unpriced = BTreeMap::new();
    for (cell, &n) in &report.cells_by_type {
        if cell == "$mem" || cell == "$mem_v2" {
            // An SRAM array: storage, priced by the storage model.
            continue;
        }
        match cell_area_45nm(cell) {
            Some(a) => {
                area += a * n as f64;
                if flip_flop_area(cell).is_some() {
                    ff_area += a * n as f64;
                }
            }
            None => {
                unpriced.insert(cell.clone(), n);
            }
        }
    }
    LogicArea {
        top: report.top.clone(),
        cells: report.cells,
        flip_flops: report.flip_flops,
        nand2_eq: area / NAND2_X1_45NM_UM2,
        flip_flop_nand2_eq: ff_area / NAND2_X1_45NM_UM2,
        area_45nm_um2: area,
        area_mm2: area_per_node(area),
        unpriced,
    }
}

/// An area of `um2_45nm` um^2 at 45 nm at every node of [`NODES_NM`] in mm^2: (node, area),
/// scaled by (F / 45)^2.
pub fn area_per_node(um2_45nm: f64) -> Vec<(f64, f64)> {
    NODES_NM
        .iter()
        .map(|&f| (f, um2_45nm * (f / 45.0).powi(2) / 1e6))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gates_are_priced_in_nand2_units() {
        let eq = |c: &str| cell_area_45nm(c).unwrap() / NAND2_X1_45NM_UM2;
        assert!((eq("$_NAND_") - 1.0).abs() < 1e-12);
        assert!((eq("$_NOT_") - 2.0 / 3.0).abs() < 1e-9);
        assert!((eq("$_MUX_") - 7.0 / 3.0).abs() < 1e-9);
        assert!((eq("$_DFF_P_") - 17.0 / 3.0).abs() < 1e-9);
        // Enable adds a MUX2, a synchronous reset an AND2, a falling clock an INV.
        assert!((eq("$_SDFFE_PP0P_") - (17.0 + 7.0 + 4.0) / 3.0).abs() < 1e-9);
        assert!((eq("$_DFFE_NP_") - (17.0 + 7.0 + 2.0) / 3.0).abs() < 1e-9);
        assert!((eq("$_DFF_PN0_") - 20.0 / 3.0).abs() < 1e-9);
        assert!((eq("$_DFFSRE_PPPP_") - (24.0 + 7.0) / 3.0).abs() < 1e-9);
        for bad in [
            "$_DLATCH_P_",
            "$mem_v2",
            "$_DFF_X_",
            "$_SDFF_PP2_",
            "$_AND3_",
        ] {
            assert!(cell_area_45nm(bad).is_none(), "{bad}");
        }
        // Every area is a whole number of 0.266 um^2 sites.
        for c in ["$_NOT_", "$_XOR_", "$_AOI4_", "$_ORNOT_", "$_SDFFCE_NN1N_"] {
            let sites = cell_area_45nm(c).unwrap() / 0.266;
            assert!((sites - sites.round()).abs() < 1e-9, "{c}: {sites}");
        }
    }

    #[test]
    fn sums_and_scales() {
        let mut by_type = BTreeMap::new();
        by_type.insert("$_NAND_".to_string(), 10);
        by_type.insert("$_DFF_P_".to_string(), 3);
        by_type.insert("$_DLATCH_P_".to_string(), 1);
        let r = SynthReport {
            top: "t".to_string(),
            cells: 14,
            cells_by_type: by_type,
            flip_flops: 3,
            latches: 1,
            memory_bits: 0,
            memory_cells: 0,
            warnings: vec![],
            undriven: vec![],
        };
        let a = logic_area(&r);
        assert!((a.nand2_eq - 27.0).abs() < 1e-9, "{}", a.nand2_eq);
        assert!((a.flip_flop_nand2_eq - 17.0).abs() < 1e-9);
        assert!((a.area_45nm_um2 - 27.0 * 0.798).abs() < 1e-9);
        let (nm, mm2) = a.area_mm2[1];
        assert_eq!(nm, 22.0);
        assert!((mm2 - 27.0 * 0.798 * (22.0f64 / 45.0).powi(2) / 1e6).abs() < 1e-15);
        assert_eq!(a.unpriced.get("$_DLATCH_P_"), Some(&1));
    }
}
