//! The analytical storage and area model of the paper's section 6.5 (and the suspended-CTA state
//! of section 6.6), derived from a [`HwConfig`] and a few [`AreaParams`].
//!
//! For each storage structure the model gives the paper's bit count (entries x payload bits per
//! entry), the bookkeeping bits an implementation adds (valid bits, fill counts, chain links),
//! the size in KB (1 KB = 1024 B, printed to three significant digits, truncated, as the paper
//! prints 6448 B as "6.29 KB"), and the area at 45 nm and 22 nm as SRAM and as flip-flops.
//!
//! SRAM area = bits x cell area / array efficiency x port factor, with the cell area CACTI's
//! 146 F^2 cell and an array efficiency that grows with the array size (fitted to CACTI 7's 1, 4
//! and 16 KB points, which it reproduces within 11%). Flip-flop area = bits x one NanGate45
//! DFF_X1, scaled by (F / 45 nm)^2: storage cells only, without read multiplexers or
//! placement utilization, so a lower bound. docs/area.md lists every constant with its source.

use crate::error::GenError;
use serde::{Deserialize, Serialize};
use std::fmt;
use vtq_hdl::HwConfig;

/// Area of one SRAM bit cell in units of F^2 (CACTI's cell; 0.296 um^2 at 45 nm).
pub const SRAM_CELL_F2: f64 = 146.0;
/// Area of a NanGate45 DFF_X1 flip-flop in um^2 (NanGate FreePDK45 Open Cell Library).
pub const DFF_X1_45NM_UM2: f64 = 4.522;
/// Array efficiency (cell area / array area) of a 1 KB SRAM array.
pub const EFFICIENCY_AT_1KB: f64 = 0.60;
/// Increase of the array efficiency per doubling of the array size.
pub const EFFICIENCY_PER_DOUBLING: f64 = 0.025;
/// Lowest array efficiency the model uses (tiny arrays).
pub const EFFICIENCY_MIN: f64 = 0.50;
/// Highest array efficiency the model uses (large arrays).
pub const EFFICIENCY_MAX: f64 = 0.80;
/// Technology nodes the report covers, in nm.
pub const NODES_NM: [f64; 2] = [45.0, 22.0];

/// How many ports an SRAM array has; more ports need larger cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Ports {
    /// One shared read/write port.
    OneRw,
    /// One read port and one write port (about twice the area of 1RW).
    OneROneW,
}

impl Ports {
    /// Area relative to a 1RW array of the same capacity.
    pub fn factor(self) -> f64 {
        match self {
            Ports::OneRw => 1.0,
            Ports::OneROneW => 2.0,
        }
    }

    /// Its name in tables: `1RW`, `1R+1W`.
    pub fn label(self) -> &'static str {
        match self {
            Ports::OneRw => "1RW",
            Ports::OneROneW => "1R+1W",
        }
    }
}

/// SRAM bit-cell area at a feature size, in um^2 (146 F^2).
pub fn sram_cell_um2(feature_nm: f64) -> f64 {
    SRAM_CELL_F2 * (feature_nm / 1000.0).powi(2)
}

/// Flip-flop area at a feature size, in um^2 (DFF_X1 scaled by (F / 45 nm)^2).
pub fn dff_um2(feature_nm: f64) -> f64 {
    DFF_X1_45NM_UM2 * (feature_nm / 45.0).powi(2)
}

/// Fraction of an SRAM array's area taken by bit cells, for an array of `bytes` bytes.
pub fn array_efficiency(bytes: f64) -> f64 {
    (EFFICIENCY_AT_1KB + EFFICIENCY_PER_DOUBLING * (bytes / 1024.0).log2())
        .clamp(EFFICIENCY_MIN, EFFICIENCY_MAX)
}

/// Area in mm^2 of an SRAM array holding `bits` bits at `feature_nm`.
pub fn sram_area_mm2(bits: u64, feature_nm: f64, ports: Ports) -> f64 {
    if bits == 0 {
        return 0.0;
    }
    let cells_um2 = bits as f64 * sram_cell_um2(feature_nm);
    cells_um2 / array_efficiency(bits as f64 / 8.0) * ports.factor() / 1e6
}

/// Area in mm^2 of `bits` flip-flops at `feature_nm` (cells only).
pub fn ff_area_mm2(bits: u64, feature_nm: f64) -> f64 {
    bits as f64 * dff_um2(feature_nm) / 1e6
}

/// Area-model parameters that the hardware configuration does not hold (section 6.6's
/// suspended-CTA state and the ray record size).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AreaParams {
    /// Bytes per ray record in memory: origin, direction, tmin, tmax (32 in the paper).
    pub ray_record_bytes: u32,
    /// Threads per CTA of the raygen shader. Default 64 (2 warps): an 8x8 pixel tile per CTA;
    /// the paper does not state the CTA size, so this is an assumption.
    pub threads_per_cta: u32,
    /// Saved 32-bit-or-narrower registers per thread (10 for LumiBench's raygen, per ptxas).
    pub regs_per_thread: u32,
    /// Bits per saved register.
    pub reg_bits: u32,
    /// Bits of a program counter and of a reconvergence PC (32, as Vulkan-Sim's addresses).
    pub pc_bits: u32,
    /// Saved SIMT-stack entries per warp (each: active mask, PC, reconvergence PC). Default 2,
    /// the simulator's `gpu.simt_stack_entries` (the bounce loop's reconvergence entry and the
    /// current one); an assumption: the paper saves "per SIMT stack depth" without the depth.
    pub simt_stack_depth: u32,
}

impl Default for AreaParams {
    fn default() -> Self {
        AreaParams {
            ray_record_bytes: 32,
            threads_per_cta: 64,
            regs_per_thread: 10,
            reg_bits: 32,
            pc_bits: 32,
            simt_stack_depth: 2,
        }
    }
}

impl AreaParams {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), GenError> {
        let check = |key: &'static str, value: u32, lo: u32, hi: u32| {
            if (lo..=hi).contains(&value) {
                Ok(())
            } else {
                Err(GenError::AreaParam {
                    key,
                    value: value as u64,
                    reason: format!("must be {lo}..={hi}"),
                })
            }
        };
        check("ray_record_bytes", self.ray_record_bytes, 1, 4096)?;
        check("threads_per_cta", self.threads_per_cta, 1, 1024)?;
        check("regs_per_thread", self.regs_per_thread, 0, 255)?;
        check("reg_bits", self.reg_bits, 1, 64)?;
        check("pc_bits", self.pc_bits, 1, 64)?;
        check("simt_stack_depth", self.simt_stack_depth, 1, 64)
    }
}

/// The paper's size figures (section 6.5) with the dimensions they were computed for: a
/// structure whose entries and bits per entry match shows the paper's figure beside its own.
const PAPER_FIGURES: [(&str, u64, u64, &str); 3] = [
    ("treelet count table", 600, 19 + 12, "2.2 KB"),
    ("treelet queue table", 128, 19 + 32 * 12, "6.29 KB"),
    ("ray records", 4096, 32 * 8, "128 KB"),
];

/// Area of one structure at one technology node.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NodeArea {
    /// Feature size in nm.
    pub feature_nm: f64,
    /// As an SRAM array with the structure's ports, in mm^2.
    pub sram_mm2: f64,
    /// As flip-flops (cells only), in mm^2.
    pub ff_mm2: f64,
}

/// Size and area of one storage structure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureArea {
    /// Structure name in the paper's terms.
    pub name: String,
    /// Where the paper keeps it.
    pub location: String,
    /// Entries (rows).
    pub entries: u64,
    /// Payload bits per entry, as the paper counts them.
    pub entry_bits: u64,
    /// How the payload bits per entry are made up.
    pub entry_formula: String,
    /// Bookkeeping fields per entry an implementation adds (name, bits); not in the paper.
    pub bookkeeping: Vec<(String, u32)>,
    /// Payload bits: entries x entry_bits.
    pub bits: u64,
    /// Payload bytes (bits / 8, rounded up).
    pub bytes: u64,
    /// Payload size as printed (three significant digits of KB, truncated).
    pub size: String,
    /// The paper's figure for this structure when its dimensions match the paper's.
    pub paper: Option<String>,
    /// Bookkeeping bits in total: entries x the bookkeeping fields.
    pub bookkeeping_bits: u64,
    /// Ports assumed for the SRAM area.
    pub ports: Ports,
    /// Area of payload plus bookkeeping at each node.
    pub area: Vec<NodeArea>,
}

/// Widths derived from the configuration that the structures use.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Widths {
    /// Treelet address bits.
    pub treelet_addr: u32,
    /// Ray id bits.
    pub ray_id: u32,
    /// Per-treelet ray count bits.
    pub ray_count: u32,
    /// Queue-entry fill count bits.
    pub entry_count: u32,
    /// Queue-table index (chain link) bits.
    pub queue_index: u32,
}

/// The area report for one configuration: printable as a table, serializable as JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AreaReport {
    /// The hardware configuration.
    pub config: HwConfig,
    /// The extra parameters.
    pub params: AreaParams,
    /// Derived widths.
    pub widths: Widths,
    /// CTAs that can be suspended at once: max_rays / threads_per_cta, rounded up.
    pub suspended_ctas: u64,
    /// The structures, in the paper's order.
    pub structures: Vec<StructureArea>,
    /// Remarks on the configuration (for example a queue table too small to hold every ray).
    pub notes: Vec<String>,
}

/// KB (1024 B) to three significant digits, truncated: 2325 B -> "2.27 KB", 6448 B ->
/// "6.29 KB", 131072 B -> "128 KB", 512 B -> "0.5 KB".
pub fn format_kb(bytes: u64) -> String {
    // Decimals so that three significant digits remain: 100+ KB none, 10+ one, else two
    // (three below 1 KB).
    let decimals: u32 = match bytes {
        b if b >= 100 * 1024 => 0,
        b if b >= 10 * 1024 => 1,
        b if b >= 1024 => 2,
        _ => 3,
    };
    let scale = 10u64.pow(decimals);
    let scaled = bytes as u128 * scale as u128 / 1024;
    let whole = scaled / scale as u128;
    let frac = scaled % scale as u128;
    let mut s = if decimals == 0 {
        whole.to_string()
    } else {
        format!("{whole}.{frac:0width$}", width = decimals as usize)
    };
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    format!("{s} KB")
}

/// Builds one structure row.
#[allow(clippy::too_many_arguments)]
fn structure(
    name: &str,
    location: &str,
    entries: u64,
    entry_bits: u64,
    entry_formula: String,
    bookkeeping: Vec<(String, u32)>,
    ports: Ports,
) -> StructureArea {
    let bits = entries * entry_bits;
    let bytes = bits.div_ceil(8);
    let per_entry_bookkeeping: u64 = bookkeeping.iter().map(|(_, b)| *b as u64).sum();
    let bookkeeping_bits = entries * per_entry_bookkeeping;
    let stored = bits + bookkeeping_bits;
    let paper = PAPER_FIGURES
        .iter()
        .find(|(n, e, b, _)| *n == name && *e == entries && *b == entry_bits)
        .map(|(_, _, _, quote)| quote.to_string());
    StructureArea {
        name: name.to_string(),
        location: location.to_string(),
        entries,
        entry_bits,
        entry_formula,
        bookkeeping,
        bits,
        bytes,
        size: format_kb(bytes),
        paper,
        bookkeeping_bits,
        ports,
        area: NODES_NM
            .iter()
            .map(|&f| NodeArea {
                feature_nm: f,
                sram_mm2: sram_area_mm2(stored, f, ports),
                ff_mm2: ff_area_mm2(stored, f),
            })
            .collect(),
    }
}

/// The storage and area report for `cfg` (validated first) and `params`.
pub fn area_report(cfg: &HwConfig, params: &AreaParams) -> Result<AreaReport, GenError> {
    cfg.validate()?;
    params.validate()?;
    let widths = Widths {
        treelet_addr: cfg.treelet_addr_bits(),
        ray_id: cfg.ray_id_bits(),
        ray_count: cfg.count_bits(),
        entry_count: cfg.entry_count_bits(),
        queue_index: cfg.queue_index_bits(),
    };
    let warp = cfg.warp_size as u64;
    let mut structures = vec![
        structure(
            "treelet count table",
            "RT unit, dedicated SRAM",
            cfg.count_table_entries as u64,
            (widths.treelet_addr + widths.ray_count) as u64,
            format!(
                "{} treelet address + {} ray count",
                widths.treelet_addr, widths.ray_count
            ),
            vec![("valid".to_string(), 1)],
            Ports::OneROneW,
        ),
        structure(
            "treelet queue table",
            "L1 cache, reserved lines",
            cfg.queue_table_entries as u64,
            widths.treelet_addr as u64 + warp * widths.ray_id as u64,
            format!(
                "{} treelet address + {warp} x {} ray id",
                widths.treelet_addr, widths.ray_id
            ),
            vec![
                ("valid".to_string(), 1),
                ("fill count".to_string(), widths.entry_count),
                ("link valid".to_string(), 1),
                ("chain link".to_string(), widths.queue_index),
            ],
            Ports::OneRw,
        ),
        structure(
            "ray records",
            "L2 cache, reserved section",
            cfg.max_rays as u64,
            params.ray_record_bytes as u64 * 8,
            format!(
                "{} B: origin, direction, tmin, tmax",
                params.ray_record_bytes
            ),
            vec![],
            Ports::OneRw,
        ),
    ];
    let suspended_ctas = (cfg.max_rays as u64).div_ceil(params.threads_per_cta as u64);
    let warps_per_cta = (params.threads_per_cta as u64).div_ceil(warp);
    let per_cta =
        params.threads_per_cta as u64 * params.regs_per_thread as u64 * params.reg_bits as u64
            + warps_per_cta * params.simt_stack_depth as u64 * (warp + 2 * params.pc_bits as u64);
    structures.push(structure(
        "suspended CTA state",
        "memory, cached in L2",
        suspended_ctas,
        per_cta,
        format!(
            "{} threads x {} x {} b registers + {warps_per_cta} warps x {} SIMT entries x \
             ({warp} mask + {} PC + {} reconvergence PC)",
            params.threads_per_cta,
            params.regs_per_thread,
            params.reg_bits,
            params.simt_stack_depth,
            params.pc_bits,
            params.pc_bits
        ),
        vec![],
        Ports::OneRw,
    ));
    let mut notes = Vec::new();
    let warps_of_rays = (cfg.max_rays as u64).div_ceil(warp);
    if (cfg.queue_table_entries as u64) < warps_of_rays {
        notes.push(format!(
            "the treelet queue table has {} entries but max_rays / warp_size = {warps_of_rays}: \
             it cannot hold every ray at once (the paper sizes it so that it can)",
            cfg.queue_table_entries
        ));
    }
    Ok(AreaReport {
        config: cfg.clone(),
        params: params.clone(),
        widths,
        suspended_ctas,
        structures,
        notes,
    })
}

/// `x` with three significant digits (areas in mm^2).
pub(crate) fn sig3(x: f64) -> String {
    if x == 0.0 {
        return "0".to_string();
    }
    let digits = 2 - x.abs().log10().floor() as i32;
    format!("{x:.prec$}", prec = digits.max(0) as usize)
}

impl fmt::Display for AreaReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.config;
        let w = &self.widths;
        let p = &self.params;
        writeln!(f, "Storage and area (paper sections 6.5 and 6.6)")?;
        writeln!(
            f,
            "Configuration: max_rays {}, warp_size {}, address_bits {}, treelet_bytes {}, \
             count_table_entries {}, queue_table_entries {}",
            c.max_rays,
            c.warp_size,
            c.address_bits,
            c.treelet_bytes,
            c.count_table_entries,
            c.queue_table_entries
        )?;
        writeln!(
            f,
            "Widths: treelet address {} b, ray id {} b, ray count {} b, queue fill count {} b, \
             queue link {} b",
            w.treelet_addr, w.ray_id, w.ray_count, w.entry_count, w.queue_index
        )?;
        writeln!(
            f,
            "CTA state: {} threads/CTA, {} x {} b registers/thread, {} b PCs, SIMT stack depth \
             {}: {} suspended CTAs",
            p.threads_per_cta,
            p.regs_per_thread,
            p.reg_bits,
            p.pc_bits,
            p.simt_stack_depth,
            self.suspended_ctas
        )?;
        writeln!(f)?;
        writeln!(
            f,
            "{:<20} {:<27} {:>7} {:>10} {:>10} {:>8}  bookkeeping (not in paper)",
            "structure", "where", "entries", "bits/entry", "size", "paper"
        )?;
        for s in &self.structures {
            let bookkeeping = if s.bookkeeping.is_empty() {
                "-".to_string()
            } else {
                let fields = s
                    .bookkeeping
                    .iter()
                    .map(|(n, b)| format!("{n} {b}"))
                    .collect::<Vec<_>>()
                    .join(" + ");
                format!("{fields} b/entry: {} B", s.bookkeeping_bits.div_ceil(8))
            };
            writeln!(
                f,
                "{:<20} {:<27} {:>7} {:>10} {:>10} {:>8}  {}",
                s.name,
                s.location,
                s.entries,
                s.entry_bits,
                s.size,
                s.paper.as_deref().unwrap_or("-"),
                bookkeeping
            )?;
        }
        writeln!(f)?;
        writeln!(f, "Bits per entry:")?;
        for s in &self.structures {
            writeln!(f, "  {:<20} {}", s.name, s.entry_formula)?;
        }
        writeln!(f)?;
        write!(f, "{:<20} {:>6}", "area (mm^2)", "ports")?;
        for nm in NODES_NM {
            write!(
                f,
                " {:>10} {:>10}",
                format!("SRAM {nm}nm"),
                format!("FF {nm}nm")
            )?;
        }
        writeln!(f)?;
        for s in &self.structures {
            write!(f, "{:<20} {:>6}", s.name, s.ports.label())?;
            for a in &s.area {
                write!(f, " {:>10} {:>10}", sig3(a.sram_mm2), sig3(a.ff_mm2))?;
            }
            writeln!(f)?;
        }
        writeln!(
            f,
            "(areas include bookkeeping bits; SRAM = 146 F^2 cells / array efficiency x port \
             factor; FF = DFF_X1 cells only)"
        )?;
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kb_formatting_truncates_to_three_digits() {
        assert_eq!(format_kb(2325), "2.27 KB");
        assert_eq!(format_kb(6448), "6.29 KB");
        assert_eq!(format_kb(131072), "128 KB");
        assert_eq!(format_kb(512), "0.5 KB");
        assert_eq!(format_kb(1024), "1 KB");
        assert_eq!(format_kb(10 * 1024 + 1023), "10.9 KB");
    }

    #[test]
    fn cells_match_anchors() {
        // 146 F^2 at 45 nm is the ~0.30 um^2 cell; DFF_X1 is ~15 SRAM cells.
        assert!((sram_cell_um2(45.0) - 0.2957).abs() < 1e-3);
        let ratio = dff_um2(45.0) / sram_cell_um2(45.0);
        assert!((14.0..17.0).contains(&ratio), "{ratio}");
        assert!((Ports::OneROneW.factor() / Ports::OneRw.factor() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_params() {
        let p = AreaParams {
            threads_per_cta: 0,
            ..AreaParams::default()
        };
        let e = area_report(&HwConfig::default(), &p).unwrap_err();
        assert!(e.to_string().contains("threads_per_cta"), "{e}");
        let c = HwConfig {
            max_rays: 3000,
            ..HwConfig::default()
        };
        assert!(area_report(&c, &AreaParams::default()).is_err());
    }
}
