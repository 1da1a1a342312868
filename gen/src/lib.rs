//! Verilog generation, co-simulation and area estimates for the vtq hardware blocks.
//!
//! - [`verilog`]: a readable Verilog-2005 module from a block's [`vtq_hdl::BlockDesc`]
//!   (header, ports, storage, state encodings and a lint-clean skeleton body).
//! - [`cosim`]: runs a Rust [`vtq_hdl::Block`] and its Verilog side by side, cycle by cycle.
//! - [`compose`]: the top module of a composed block (its children and a wiring module).
//! - [`area`]: the analytical storage and area model of the paper's section 6.5.
//! - [`datapath_area`]: the intersection datapath's area from a published datapath's units.
//! - [`synth_cache`]: reusing a synthesis whose RTL, script and Yosys did not change.
//! - [`logic_area`]: NAND2 equivalents and logic area of synthesized RTL (Yosys cell counts
//!   priced with NanGate45 cell areas); [`logic_report`]: the synthesized-logic table of
//!   `vtq area --synth` (every block with complete RTL beside the storage model).
//! - [`rtl`]: complete RTL of the treelet count table, treelet queue table, treelet controller
//!   and the RT unit's control.
//! - [`stimulus`]: seeded random stimulus and reactive test benches for the two tables and (its
//!   [`stimulus::controller`]) the treelet controller.
//! - [`synth`]: Yosys synthesis statistics and Verilator lint as structured results.
//! - [`emit`]: the Verilog text writer; [`tools`]: running the external tools;
//!   [`error`]: the crate's error type.

pub mod area;
pub mod compose;
pub mod cosim;
pub mod datapath_area;
pub mod emit;
pub mod error;
pub mod logic_area;
pub mod logic_report;
pub mod rtl;
pub mod stimulus;
pub mod synth;
pub mod synth_cache;
pub mod tools;
pub mod verilog;

pub use area::{area_report, AreaParams, AreaReport};
pub use cosim::{cosim_block, record, run_cosim, CosimOptions, CosimResult, Simulator, Trace};
pub use error::GenError;
pub use logic_area::{logic_area, LogicArea};
pub use logic_report::{logic_report, LogicReport};
pub use synth::{lint, synthesize, synthesize_logic, LintReport, SynthReport};
pub use verilog::{emit_module, validate_desc, write_module};
