//! The block framework: a hardware block is a configuration (immutable parameters), a register
//! bundle (all of its state), input and output port bundles, and one pure next-state function.
//!
//! In the manner of rhdl and Clash: a block defines one next-state function,
//! [`Block::next_into`]`(&regs, &inputs, &mut next) -> outputs`, which reads the start-of-cycle
//! registers `regs` and the inputs and writes the next registers into `next`'s storage; the
//! framework gives `eval(&regs, &inputs) -> (outputs, next_regs)` and the clock edge
//! [`Block::step`] from it. A block may override `step` with an in-place version for speed
//! (the tables run the very same cycle function on their own storage, whose memory writes
//! land at the edge), and must then have a test showing both give the same outputs and
//! registers.

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

    /// The values of the bundle's bulk ports (data too wide to trace, such as whole ray
    /// records), as 64-bit words `<port>_<k>` (word 0 lowest; the last may be narrower), for
    /// co-simulation; none by default.
    fn bulk_signals(&self) -> Vec<Signal> {
        Vec::new()
    }
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

    /// Inputs with nothing happening this cycle (no op, no command, nothing arriving): what a
    /// composite drives a child with before its wiring has settled ([`crate::compose`]).
    fn idle_inputs(&self) -> Self::Inputs;

    /// The next-state function, the block's definition: this cycle's outputs, with the
    /// registers of the next cycle written into `next`. It reads the start-of-cycle registers
    /// `regs` and `inputs` only; `next` is storage to reuse (it may hold any earlier cycle's
    /// registers, and the result must not depend on them).
    fn next_into(
        &self,
        regs: &Self::Regs,
        inputs: &Self::Inputs,
        next: &mut Self::Regs,
    ) -> Self::Outputs;

    /// Outputs for this cycle and the register values for the next one; pure
    /// ([`Block::next_into`] into a copy of the registers).
    fn eval(&self, regs: &Self::Regs, inputs: &Self::Inputs) -> (Self::Outputs, Self::Regs) {
        let mut next = regs.clone();
        let out = self.next_into(regs, inputs, &mut next);
        (out, next)
    }

    /// One clock edge: the registers become the next cycle's.
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
