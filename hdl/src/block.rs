//! The block framework: a hardware block is a configuration (immutable parameters), a register
//! bundle (all of its state), input and output port bundles, and one pure next-state function.
//!
//! In the manner of rhdl and Clash: `eval(&regs, &inputs) -> (outputs, next_regs)`. The
//! simulator calls [`Block::step`], which by default is `eval` followed by a register update;
//! a block may override `step` with an in-place version for speed, and must then have a test
//! showing both give the same outputs and registers.

use crate::describe::BlockDesc;

/// A named, fixed-width signal value, as recorded in traces and compared in co-simulation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Signal {
    /// Signal name (matches the port or register name in the block's description).
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// Value (only the low `width` bits are meaningful).
    pub value: u64,
}

impl Signal {
    /// Shorthand constructor.
    pub fn new(name: impl Into<String>, width: u32, value: u64) -> Self {
        Signal {
            name: name.into(),
            width,
            value,
        }
    }
}

/// A port bundle that can be flattened into signals for traces and co-simulation. Register
/// bundles are not `Signals`: they hold only registers, so the block, which knows their widths,
/// lists them ([`Block::reg_signals`]).
pub trait Signals {
    /// The bundle's signals in a fixed order (the same order every cycle).
    fn signals(&self) -> Vec<Signal>;
}

/// A synchronous hardware block with a pure next-state function.
pub trait Block {
    /// Input port bundle (what the block samples this cycle).
    type Inputs: Clone + Signals;
    /// Output port bundle (what the block drives this cycle).
    type Outputs: Clone + Signals;
    /// Register bundle: the only state of the block (registers only: no widths, statistics or
    /// simulation caches).
    type Regs: Clone;

    /// Register values after reset.
    fn reset(&self) -> Self::Regs;

    /// Outputs for this cycle and the register values for the next one; pure.
    fn eval(&self, regs: &Self::Regs, inputs: &Self::Inputs) -> (Self::Outputs, Self::Regs);

    /// One clock edge: evaluate and update the registers in place.
    fn step(&self, regs: &mut Self::Regs, inputs: &Self::Inputs) -> Self::Outputs {
        let (out, next) = self.eval(regs, inputs);
        *regs = next;
        out
    }

    /// The registers `regs` as trace signals, in a fixed order (the same names and widths every
    /// cycle; the widths come from the block's configuration).
    fn reg_signals(&self, regs: &Self::Regs) -> Vec<Signal>;

    /// The block's ports, registers, memories and state machines for this configuration.
    fn describe(&self) -> BlockDesc;
}
