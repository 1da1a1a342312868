//! The intersection datapath's area, which vtq does not build as RTL: a published RT datapath's
//! functional units (RayFlex's baseline ray-box/ray-triangle pipeline, Shen et al., "RayFlex:
//! An Open-Source RTL Implementation of the Hardware Ray Tracer Datapath", arXiv 2409.06000;
//! its unit counts per pipeline stage in `FU_summary.md` of github.com/purdue-aalp/raytracer)
//! priced with the FP32 units RayFlex is built from (Berkeley HardFloat, J. Hauser, Release 1,
//! the Verilog of github.com/bsg-external/HardFloat at aaf5736) synthesized by this crate's
//! flow: [`crate::synth::LOGIC_SCRIPT`] and [`crate::logic_area`]'s NanGate45 prices.
//!
//! RayFlex's baseline datapath tests one ray against one node a cycle: a 4-wide box node (24
//! subtractions, 24 multiplications as multiply-adds, then compare-and-swaps, min/max and two
//! 4-input sorts of the hit distances) or one triangle, both through one unified pipeline whose
//! stages share their units, so a stage has the larger of the two tests' counts
//! ([`RAYFLEX_UNITS`]). vtq's RT unit RTL instantiates one `rt_datapath` per lane index
//! (`warp_size` of them, each testing its lane's node when the node has arrived), so the report
//! prices that many units.
//!
//! What the figure leaves out, so it is a lower bound: the pipeline registers between RayFlex's
//! stages, the FP32 <-> recoded-format conversions at its ends, the node-decoding muxes and
//! wiring. A multiply-add is priced as a multiplier plus an adder (a fused unit's wider adder
//! costs more). docs/area.md gives the synthesis commands that reproduce the unit figures.

use crate::logic_area::{area_per_node, MUX2_X1_UM2, NAND2_X1_45NM_UM2};
use serde::Serialize;

/// NAND2 equivalents of HardFloat's `addRecFN #(8, 24)` (FP32 add, round-to-nearest-even
/// wired, exception flags kept): 1,614 Yosys cells.
pub const F32_ADD_NAND2: f64 = 2691.0;
/// NAND2 equivalents of HardFloat's `mulRecFN #(8, 24)` (FP32 multiply): 4,409 Yosys cells.
pub const F32_MUL_NAND2: f64 = 7062.0;
/// NAND2 equivalents of HardFloat's `compareRecFN #(8, 24)` (FP32 compare: lt, eq, gt,
/// unordered): 206 Yosys cells.
pub const F32_CMP_NAND2: f64 = 334.0;

/// Bits of one value moved by a compare-and-swap's or min/max's multiplexers: a recoded FP32
/// word (33 bits).
const RECODED_BITS: u32 = 33;
/// Bits of a sort's child index travelling with each distance (4 children).
const INDEX_BITS: u32 = 2;
/// Compare-and-swaps of one 4-input sorting network.
pub const SORT4_CAS: u32 = 5;

/// The functional units of one RayFlex baseline datapath, per pipeline stage the larger of the
/// ray-box and the ray-triangle test's needs (`FU_summary.md`, "FU usage summary for Baseline
/// Raytracer").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct DatapathUnits {
    /// FP32 adders (stages 3, 6, 8, 9: 24 + 3 + 2 + 2).
    pub adders: u32,
    /// FP32 multiply-adds (stage 4: the box test's 24 multiplications run as multiply-adds).
    pub mul_adds: u32,
    /// FP32 multipliers (stages 5 and 7: 6 + 3, the triangle test's).
    pub multipliers: u32,
    /// Compare-and-swap units (stage 10: 12, plus 2 sorts of 4 values with index).
    pub compare_swaps: u32,
    /// Min/max units (stage 10).
    pub min_max: u32,
    /// Plain compares (stage 10: the triangle test's 5).
    pub compares: u32,
    /// 4-input sorts of distances with their child index (stage 10), [`SORT4_CAS`] swaps each.
    pub sorts: u32,
}

/// One RayFlex baseline datapath's units.
pub const RAYFLEX_UNITS: DatapathUnits = DatapathUnits {
    adders: 24 + 3 + 2 + 2,
    mul_adds: 24,
    multipliers: 6 + 3,
    compare_swaps: 12,
    min_max: 8,
    compares: 5,
    sorts: 2,
};

impl DatapathUnits {
    /// FP32 comparators: one per compare-and-swap (the sorts' included), min/max and compare.
    pub fn comparators(&self) -> u32 {
        self.compare_swaps + self.sorts * SORT4_CAS + self.min_max + self.compares
    }

    /// Two-input multiplexer bits: a compare-and-swap moves two values, a sort's swaps carry
    /// the child index too, a min/max picks one value.
    pub fn mux_bits(&self) -> u32 {
        self.compare_swaps * 2 * RECODED_BITS
            + self.sorts * SORT4_CAS * 2 * (RECODED_BITS + INDEX_BITS)
            + self.min_max * RECODED_BITS
    }

    /// NAND2 equivalents of the units (see the module documentation for what is left out).
    pub fn nand2_eq(&self) -> f64 {
        f64::from(self.adders) * F32_ADD_NAND2
            + f64::from(self.mul_adds) * (F32_MUL_NAND2 + F32_ADD_NAND2)
            + f64::from(self.multipliers) * F32_MUL_NAND2
            + f64::from(self.comparators()) * F32_CMP_NAND2
            + f64::from(self.mux_bits()) * MUX2_X1_UM2 / NAND2_X1_45NM_UM2
    }
}

/// The datapath of an RT unit: `units` RayFlex datapaths.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DatapathArea {
    /// Datapaths priced (the RT unit RTL's `rt_datapath` instances).
    pub units: u32,
    /// One datapath's functional units.
    pub per_unit: DatapathUnits,
    /// NAND2 equivalents of one datapath's functional units.
    pub unit_nand2_eq: f64,
    /// NAND2 equivalents of all `units` (a lower bound, see the module documentation).
    pub nand2_eq: f64,
    /// Area per technology node of [`crate::area::NODES_NM`] in mm^2: (node, area), scaled by (F / 45)^2
    /// like [`crate::logic_area::LogicArea::area_mm2`].
    pub area_mm2: Vec<(f64, f64)>,
    /// Where the figures come from.
    pub source: String,
}

/// What [`DatapathArea::source`] says.
pub const DATAPATH_SOURCE: &str = "RayFlex baseline datapath (Shen et al., arXiv 2409.06000; \
     FU counts of purdue-aalp/raytracer FU_summary.md) priced with Berkeley HardFloat's FP32 \
     add/mul/compare (bsg-external/HardFloat aaf5736) synthesized by gen::synth::LOGIC_SCRIPT; \
     functional units only: no pipeline registers, format conversions or node decoding, so a \
     lower bound";

/// The datapath area of `units` RayFlex datapaths.
pub fn datapath_area(units: u32) -> DatapathArea {
    let unit = RAYFLEX_UNITS.nand2_eq();
    let nand2_eq = unit * f64::from(units);
    DatapathArea {
        units,
        per_unit: RAYFLEX_UNITS,
        unit_nand2_eq: unit,
        nand2_eq,
        area_mm2: area_per_node(nand2_eq * NAND2_X1_45NM_UM2),
        source: DATAPATH_SOURCE.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::area::NODES_NM;

    #[test]
    fn rayflex_counts_add_up() {
        let u = RAYFLEX_UNITS;
        assert_eq!(u.adders, 31);
        assert_eq!(u.comparators(), 12 + 10 + 8 + 5);
        assert_eq!(u.mux_bits(), 12 * 66 + 2 * 5 * 70 + 8 * 33);
        // Arithmetic dominates: 31 adds, 24 multiply-adds, 9 multiplies.
        let arith =
            31.0 * F32_ADD_NAND2 + 24.0 * (F32_MUL_NAND2 + F32_ADD_NAND2) + 9.0 * F32_MUL_NAND2;
        let n = u.nand2_eq();
        assert!(n > arith && n < arith * 1.1, "{n} vs {arith}");
    }

    #[test]
    fn area_scales_with_units_and_node() {
        let one = datapath_area(1);
        let many = datapath_area(32);
        assert!((many.nand2_eq - 32.0 * one.nand2_eq).abs() < 1e-6);
        assert_eq!(one.area_mm2.len(), NODES_NM.len());
        let (nm45, a45) = one.area_mm2[0];
        assert_eq!(nm45, 45.0);
        assert!((a45 - one.nand2_eq * 0.798 / 1e6).abs() < 1e-12);
        assert!(one.area_mm2[1].1 < a45 / 4.0);
        assert_eq!(datapath_area(0).nand2_eq, 0.0);
    }
}
