//! Self-descriptions of hardware blocks: ports, registers, memories and state machines with their
//! widths for the configured sizes. The Verilog and area generator (`vtq-gen`) works from these.

use serde::Serialize;

/// Direction of a port, seen from the block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Dir {
    /// Driven from outside, read by the block.
    In,
    /// Driven by the block.
    Out,
}

/// One port of a block.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct PortDesc {
    /// Signal name (snake_case, a legal Verilog identifier).
    pub name: String,
    /// Direction.
    pub dir: Dir,
    /// Width in bits.
    pub width: u32,
    /// What the signal means, in the paper's terms.
    pub doc: String,
}

/// One register (or a bank of `count` identical registers) of a block.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RegDesc {
    /// Register name.
    pub name: String,
    /// Width of one register in bits.
    pub width: u32,
    /// How many of them (1 for a plain register).
    pub count: u32,
    /// What it holds.
    pub doc: String,
}

/// A memory array (register file or SRAM) of a block.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct MemDesc {
    /// Memory name.
    pub name: String,
    /// Identical arrays of this shape, each with the ports below (1: one array).
    pub banks: u32,
    /// Number of words (of one bank).
    pub depth: u32,
    /// Bits per word.
    pub width: u32,
    /// Read ports.
    pub read_ports: u32,
    /// Write ports.
    pub write_ports: u32,
    /// Cycles from presenting a read address to data out (0 = combinational read).
    pub read_latency: u32,
    /// Which bits of a word hold what (name, width), most significant first.
    pub fields: Vec<(String, u32)>,
    /// What it holds.
    pub doc: String,
}

/// A finite state machine of a block with its state encoding.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FsmDesc {
    /// Name of the state register.
    pub name: String,
    /// State names in encoding order (state i is encoded as i).
    pub states: Vec<String>,
    /// Width of the state register.
    pub width: u32,
}

/// Everything a generator needs to know about a block for one configuration.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BlockDesc {
    /// Module name.
    pub name: String,
    /// One-paragraph summary tying the block to the paper.
    pub doc: String,
    /// Configuration parameters that shaped this block (name, value).
    pub params: Vec<(String, u64)>,
    /// Ports (clock and reset are implicit).
    pub ports: Vec<PortDesc>,
    /// Registers outside memories.
    pub registers: Vec<RegDesc>,
    /// Memory arrays.
    pub memories: Vec<MemDesc>,
    /// State machines.
    pub fsms: Vec<FsmDesc>,
    /// How many operations the block accepts per cycle and what its searches cost, in words.
    pub timing: Vec<String>,
}

impl BlockDesc {
    /// Storage bits held in registers (outside memories).
    pub fn register_bits(&self) -> u64 {
        self.registers
            .iter()
            .map(|r| r.width as u64 * r.count as u64)
            .sum()
    }

    /// Storage bits held in memory arrays.
    pub fn memory_bits(&self) -> u64 {
        self.memories
            .iter()
            .map(|m| m.width as u64 * m.depth as u64)
            .sum()
    }

    /// Total storage bits: registers plus memories.
    pub fn storage_bits(&self) -> u64 {
        self.register_bits() + self.memory_bits()
    }

    /// The port with the given name, if any.
    pub fn port(&self, name: &str) -> Option<&PortDesc> {
        self.ports.iter().find(|p| p.name == name)
    }
}

/// Shorthand for building a [`PortDesc`].
pub fn port(name: &str, dir: Dir, width: u32, doc: &str) -> PortDesc {
    PortDesc {
        name: name.to_string(),
        dir,
        width,
        doc: doc.to_string(),
    }
}

/// Shorthand for building a [`RegDesc`].
pub fn reg(name: &str, width: u32, count: u32, doc: &str) -> RegDesc {
    RegDesc {
        name: name.to_string(),
        width,
        count,
        doc: doc.to_string(),
    }
}

/// Builds a [`BlockDesc`]'s `params` list, in the order given (the order of the generated Verilog
/// parameters): `block_params!(cfg; field, name = value, ...)`. A bare `field` is the
/// configuration field `cfg.field` under its own name; `name = value` is any other value
/// (`u32`, `u64` or `bool`, widened with `u64::from`).
macro_rules! block_params {
    ($cfg:expr; $($entries:tt)*) => {
        $crate::describe::block_params!(@acc $cfg; []; $($entries)*)
    };
    (@acc $cfg:expr; [$($out:expr),*]; $name:ident = $value:expr $(, $($rest:tt)*)?) => {
        $crate::describe::block_params!(@acc $cfg;
            [$($out,)* (stringify!($name).to_string(), u64::from($value))]; $($($rest)*)?)
    };
    (@acc $cfg:expr; [$($out:expr),*]; $name:ident $(, $($rest:tt)*)?) => {
        $crate::describe::block_params!(@acc $cfg;
            [$($out,)* (stringify!($name).to_string(), u64::from($cfg.$name))]; $($($rest)*)?)
    };
    (@acc $cfg:expr; [$($out:expr),*];) => {
        vec![$($out),*]
    };
}
pub(crate) use block_params;
