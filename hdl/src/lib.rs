//! Hardware blocks of the treelet-queue RT unit (Chou & Aamodt, ASPLOS 2025), written as
//! synthesizable-style Rust: each block is registers + port bundles + a pure next-state function
//! ([`block::Block`]), with bit widths derived from [`config::HwConfig`]. This crate is the single
//! source of truth for the hardware: the simulator steps these blocks and `vtq-gen` describes them
//! in Verilog.

pub mod bits;
pub mod block;
pub mod bounded;
pub mod bundle;
pub mod compose;
pub mod config;
pub mod counters;
pub mod describe;

pub use bits::{bits_for, clog2, BitPacker, UBits, WidthError};
pub use block::{Block, Cached, Moore, Signal, Signals, Skip, Taps};
pub use config::{ConfigError, HwConfig};
pub use describe::{BlockDesc, Dir, FsmDesc, MemDesc, PortDesc, RegDesc};
pub mod controller;
pub mod count_table;
pub mod memory;
pub mod mode;
pub mod queue_table;
pub mod registers;
pub mod rt_unit;
pub mod splitmix;
pub mod trace;
pub mod treelet_rt_unit;
pub mod warp_repacking;
