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

    /// A summary of the registers `regs` for a watchdog's dump (by default every register
    /// signal as `name=value`; blocks with large state summarize).
    fn debug_state(&self, regs: &Self::Regs) -> String {
        self.reg_signals(regs)
            .iter()
            .map(|s| format!("{}={}", s.name, s.value))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// A simulation cache of a block's registers (not hardware): what the block's fast functions
/// read beside the registers so they need not scan them ([`Moore`], [`Skip`]); `()` for a
/// block without one. It is a function of the registers: whoever steps the block keeps it up to
/// date through the block's own cached step.
pub trait Cached: Block {
    /// The cache (`()` for none).
    type Cache;

    /// The cache of registers `regs`.
    fn cache(&self, regs: &Self::Regs) -> Self::Cache;

    /// One clock edge in place with `cache` kept up to date (a simulator's fast path): the
    /// same outputs and next registers as [`Block::eval`] (each block with a cache has a test).
    /// By default [`Block::step`]: a block with a cache overrides it.
    fn step_cached(
        &self,
        regs: &mut Self::Regs,
        cache: &mut Self::Cache,
        inputs: &Self::Inputs,
    ) -> Self::Outputs {
        let _ = cache;
        self.step(regs, inputs)
    }

    /// [`Cached::step_cached`] writing the outputs into `out` (whatever it held before): a
    /// block whose outputs hold lists overrides it to reuse their storage, so a simulator that
    /// keeps one bundle allocates nothing per cycle.
    fn step_cached_into(
        &self,
        regs: &mut Self::Regs,
        cache: &mut Self::Cache,
        inputs: &Self::Inputs,
        out: &mut Self::Outputs,
    ) {
        *out = self.step_cached(regs, cache, inputs);
    }
}

/// Implements [`Cached`] for a block that needs no cache (`Cache = ()`; its cached step is
/// [`Block::step`]).
#[macro_export]
macro_rules! uncached {
    ($block:ty) => {
        impl $crate::block::Cached for $block {
            type Cache = ();

            fn cache(&self, _: &<$block as $crate::block::Block>::Regs) {}
        }
    };
}

/// A block's register-only (Moore) outputs, as one bundle: the ports that depend on the
/// registers alone (a table's status, the controller's mode register, the RT unit's status
/// ports), which a parent reads before it drives the block's inputs in the same cycle.
///
/// They are outputs like any other: every output bundle `next_into` returns for registers
/// `regs` carries the same values (each block has a test), so a composite's definition reads
/// them from its children's settled outputs. `status` gives them from the registers alone, as
/// the combinational logic behind those ports would, for a parent that steps its children in
/// dependency order (a fast path): it is the only register-reading function a parent calls.
pub trait Moore: Cached {
    /// The register-only outputs.
    type Status;
    /// Which costly fields of the status to compute (`()` when none is costly): a field left
    /// out reads 0. The simulator leaves out what no reader looks at this cycle (the RT unit's
    /// distinct-treelet counts); hardware computes them always.
    type Select: Copy;

    /// The register-only outputs of registers `regs` (with their cache `cache`).
    fn status(&self, regs: &Self::Regs, cache: &Self::Cache, select: Self::Select) -> Self::Status;

    /// [`Moore::status`] written into `status` (a block with list-valued status ports reuses
    /// their storage).
    fn status_into(
        &self,
        regs: &Self::Regs,
        cache: &Self::Cache,
        select: Self::Select,
        status: &mut Self::Status,
    ) {
        *status = self.status(regs, cache, select);
    }
}

/// Clock gating, as a simulator uses it: cycles in which a block given idle inputs changes
/// nothing a parent sees but its statistics and internal progress (delays counting down, a
/// scan advancing), which a simulator jumps over instead of stepping. Hardware would gate the
/// clock of such a block and count the cycles; [`Skip::skip`] is exactly that many steps with
/// idle inputs (each block has a test), so a run that skips equals one that steps every cycle.
pub trait Skip: Cached {
    /// The statistics increments of skipped cycles.
    type Counts;

    /// Cycles from now, with idle inputs, before the block does anything a parent sees (a
    /// request, a completion, an output changing); `u64::MAX` when it waits only for inputs,
    /// and then idle inputs change none of its registers (its clock may stay gated). Derived
    /// from its registers and outputs the way a clock-gating condition would be.
    fn idle_cycles(&self, regs: &Self::Regs, cache: &Self::Cache) -> u64;

    /// Advances `n <= idle_cycles` cycles with idle inputs, as `n` steps would; returns the
    /// statistics of those cycles.
    fn skip(&self, regs: &mut Self::Regs, cache: &mut Self::Cache, n: u64) -> Self::Counts;

    /// Idle inputs change none of the registers: the block need not be stepped in a cycle
    /// whose inputs are idle ([`Skip::idle_cycles`] is `u64::MAX`).
    fn gated(&self, regs: &Self::Regs, cache: &Self::Cache) -> bool {
        self.idle_cycles(regs, cache) == u64::MAX
    }
}

/// Observer taps: what a simulator's statistics observers and a treelet prefetcher watch of a
/// block's lanes, as a logic analyzer's probes would. They are not ports (nothing in the
/// hardware reads them) and change no state.
pub trait Taps: Cached {
    /// Per warp-buffer slot, the rays traversing in it (`None`: the slot holds no warp): for
    /// observers that follow each warp (SIMT efficiency, resident lanes).
    fn slot_lanes<'a>(
        &self,
        regs: &'a Self::Regs,
        cache: &'a Self::Cache,
    ) -> impl Iterator<Item = Option<u32>> + 'a;

    /// The next node address of every traversing ray whose next node is on chip, slot by slot
    /// and lane by lane (the per-lane next-access wires a treelet prefetcher taps).
    fn next_addresses<'a>(
        &self,
        regs: &'a Self::Regs,
        cache: &'a Self::Cache,
    ) -> impl Iterator<Item = u64> + 'a;

    /// Rays traversing in the warp buffer (the sum of [`Taps::slot_lanes`]).
    fn traversing_rays(&self, regs: &Self::Regs, cache: &Self::Cache) -> u64 {
        self.slot_lanes(regs, cache).flatten().map(u64::from).sum()
    }
}
