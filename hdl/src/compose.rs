//! Composition: a block built from child blocks and a pure wiring kernel, in the manner of rhdl.
//!
//! A composite's registers are its children's registers plus the wiring's own (a few registered
//! answers and bookkeeping). Each cycle its kernel maps the composite's inputs, the wiring's
//! registers and the children's outputs to the composite's outputs, the children's inputs and
//! the wiring's next registers. The children's outputs in a cycle depend on their inputs, which
//! the kernel computes from their outputs, so [`settle`] solves the cycle as rhdl does: it
//! evaluates the kernel on the children's outputs of the previous round and the children on the
//! kernel's child inputs, starting from the children's outputs for idle inputs, until those
//! outputs stop changing. A wiring without a combinational cycle settles in at most one round
//! more than the longest chain of children driving children in one cycle.
//!
//! Children's register-only outputs (what a parent may read before it drives their inputs, such
//! as a table's status) are read from their registers and are inputs to the kernel like the
//! composite's own inputs. [`settle`] with pure `eval`s of the children is the composite's
//! definition; a composite may step faster in place by evaluating the kernel's stages in
//! dependency order, and must then be tested against the settled result.

/// A composite's cycle did not settle: the wiring has a combinational cycle (or needs more
/// rounds than allowed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the composite's wiring did not settle in {rounds} rounds (a combinational cycle?)")]
pub struct SettleError {
    /// Rounds evaluated.
    pub rounds: usize,
}

/// Solves one cycle of a composite: `kernel(q)` gives the children's inputs `d` and the rest of
/// the kernel's results `k` (composite outputs, the wiring's next registers) for children's
/// outputs `q`; `children(d)` evaluates the children on `d` and gives their outputs and next
/// registers `(q, r)`. Starting from `q0` (the children's outputs for idle inputs), the two are
/// evaluated alternately until `q` repeats; returns the settled `(d, k, q, r)`.
pub fn settle<Q: PartialEq, D, K, R>(
    q0: Q,
    max_rounds: usize,
    kernel: impl Fn(&Q) -> (D, K),
    children: impl Fn(&D) -> (Q, R),
) -> Result<(D, K, Q, R), SettleError> {
    let mut q = q0;
    for _ in 0..max_rounds {
        let (d, k) = kernel(&q);
        let (next_q, r) = children(&d);
        if next_q == q {
            return Ok((d, k, next_q, r));
        }
        q = next_q;
    }
    Err(SettleError { rounds: max_rounds })
}

/// Declares a composite's parts once — its children (instance name, block, and the block's
/// register, input and output bundles) and the wiring's registers — and generates what follows
/// from them:
///
/// - the composite's register bundle (one public field per child, named by its instance, then
///   the wiring's field);
/// - the children's inputs, outputs and next registers of one settle round, as structs with the
///   same field names;
/// - on the composite (whose fields of the same names hold the children): `children_reset`
///   (every child's [`Block::reset`](crate::block::Block::reset) with the given wiring
///   registers), `children_idle_inputs`, `eval_children` (every child's pure `eval`),
///   `settle_children` ([`settle`] of a kernel with those, started from the children's outputs
///   for idle inputs), `children_reg_signals` (each child's register signals prefixed with its
///   instance name, then the wiring's prefixed with its field name) and the public `children`
///   (instance names and descriptions, for a Verilog top that instantiates them).
///
/// So adding, removing or renaming a child is one line here; the block's `reset`,
/// `next_into`, `reg_signals` and description take the lists from these functions.
#[macro_export]
macro_rules! composite {
    (
        $(#[$rdoc:meta])*
        pub struct $regs:ident;
        child_inputs $cin:ident;
        child_outputs $cout:ident;
        child_regs $cregs:ident;
        parent $parent:ident < $g:ident : $bound:path >;
        children {
            $( $(#[$cdoc:meta])* $name:ident : $block:ty => ($r:ty, $i:ty, $o:ty) ),+ $(,)?
        }
        $(#[$gdoc:meta])*
        glue $gname:ident : $gty:ty;
    ) => {
        $(#[$rdoc])*
        #[derive(Debug, Clone, PartialEq, Eq)]
        pub struct $regs {
            $( $(#[$cdoc])* pub $name: $r, )+
            $(#[$gdoc])*
            pub $gname: $gty,
        }

        /// The children's inputs in one settle round of a cycle.
        #[derive(Debug, Clone, PartialEq)]
        pub(crate) struct $cin {
            $( pub(crate) $name: $i, )+
        }

        /// The children's outputs in one settle round of a cycle (compared to find the fixed
        /// point).
        #[derive(Debug, Clone, PartialEq)]
        pub(crate) struct $cout {
            $( pub(crate) $name: $o, )+
        }

        /// The children's next registers.
        #[derive(Debug, Clone, PartialEq)]
        pub(crate) struct $cregs {
            $( pub(crate) $name: $r, )+
        }

        impl $cregs {
            /// The composite's next registers: these with the wiring's.
            pub(crate) fn with_glue(self, $gname: $gty) -> $regs {
                $regs { $( $name: self.$name, )+ $gname }
            }
        }

        impl<$g: $bound> $parent<$g> {
            /// Every child's reset registers, with the wiring's `glue`.
            fn children_reset(&self, glue: $gty) -> $regs {
                $regs { $( $name: $crate::block::Block::reset(&self.$name), )+ $gname: glue }
            }

            /// Every child's idle inputs.
            fn children_idle_inputs(&self) -> $cin {
                $cin { $( $name: $crate::block::Block::idle_inputs(&self.$name), )+ }
            }

            /// The children evaluated on `d` (pure): their outputs and next registers.
            pub(crate) fn eval_children(&self, regs: &$regs, d: &$cin) -> ($cout, $cregs) {
                $( let $name = $crate::block::Block::eval(&self.$name, &regs.$name, &d.$name); )+
                ($cout { $( $name: $name.0, )+ }, $cregs { $( $name: $name.1, )+ })
            }

            /// One cycle of the composite solved by [`settle`]: the children's settled inputs,
            /// the kernel's results, the children's settled outputs and their next registers,
            /// from the children's outputs for idle inputs.
            fn settle_children<K>(
                &self,
                regs: &$regs,
                max_rounds: usize,
                kernel: impl Fn(&$cout) -> ($cin, K),
            ) -> Result<($cin, K, $cout, $cregs), $crate::compose::SettleError> {
                let q0 = self.eval_children(regs, &self.children_idle_inputs()).0;
                $crate::compose::settle(q0, max_rounds, kernel, |d| self.eval_children(regs, d))
            }

            /// Every child's register signals prefixed with its instance name (`rt_...`), then
            /// the wiring's `glue` signals prefixed with its field name.
            fn children_reg_signals(
                &self,
                regs: &$regs,
                glue: Vec<$crate::block::Signal>,
            ) -> Vec<$crate::block::Signal> {
                let parts = [
                    $( (stringify!($name),
                        $crate::block::Block::reg_signals(&self.$name, &regs.$name)), )+
                    (stringify!($gname), glue),
                ];
                parts
                    .into_iter()
                    .flat_map(|(prefix, signals)| {
                        signals.into_iter().map(move |sig| $crate::block::Signal {
                            name: format!("{prefix}_{}", sig.name),
                            ..sig
                        })
                    })
                    .collect()
            }

            /// The children's instance names and descriptions, for a Verilog top module that
            /// instantiates them.
            pub fn children(&self) -> Vec<(&'static str, $crate::describe::BlockDesc)> {
                vec![ $( (stringify!($name), $crate::block::Block::describe(&self.$name)), )+ ]
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block::Signal;

    /// Two children in a chain: child A outputs its input + 1, child B outputs A's output x 2;
    /// the kernel feeds A from the composite's input and B from A. Settles in three rounds.
    #[test]
    fn a_chain_settles_to_the_combinational_result() {
        let input = 5u32;
        let kernel = |q: &(u32, u32)| ((input, q.0), q.1);
        let children = |d: &(u32, u32)| ((d.0 + 1, d.1 * 2), ());
        let (d, k, q, ()) = settle((0, 0), 4, kernel, children).unwrap();
        assert_eq!(q, (6, 12));
        assert_eq!(d, (5, 6));
        assert_eq!(k, 12);
    }

    /// An accumulator: its output is its register, which adds its input each cycle.
    pub(crate) struct Acc;

    #[derive(Debug, Clone, PartialEq)]
    pub(crate) struct AccIn(u64);

    #[derive(Debug, Clone, PartialEq)]
    pub(crate) struct AccOut(u64);

    impl crate::block::Signals for AccIn {
        fn signals(&self) -> Vec<crate::block::Signal> {
            vec![crate::block::Signal::new("add", 8, self.0)]
        }
    }

    impl crate::block::Signals for AccOut {
        fn signals(&self) -> Vec<crate::block::Signal> {
            vec![crate::block::Signal::new("sum", 8, self.0)]
        }
    }

    impl crate::block::Block for Acc {
        type Inputs = AccIn;
        type Outputs = AccOut;
        type Regs = u64;
        fn reset(&self) -> u64 {
            0
        }
        fn idle_inputs(&self) -> AccIn {
            AccIn(0)
        }
        fn next_into(&self, regs: &u64, inputs: &AccIn, next: &mut u64) -> AccOut {
            *next = (regs + inputs.0) & 0xff;
            AccOut(*regs)
        }
        fn reg_signals(&self, regs: &u64) -> Vec<crate::block::Signal> {
            vec![crate::block::Signal::new("sum", 8, *regs)]
        }
        fn describe(&self) -> crate::describe::BlockDesc {
            crate::describe::BlockDesc {
                name: "acc".into(),
                doc: String::new(),
                params: vec![],
                ports: vec![],
                registers: vec![],
                memories: vec![],
                fsms: vec![],
                timing: vec![],
            }
        }
    }

    /// Two accumulators in a chain: `first` adds the composite's input, `second` adds
    /// `first`'s output; the wiring counts cycles.
    pub(crate) struct Chain<G> {
        first: Acc,
        second: Acc,
        _g: std::marker::PhantomData<G>,
    }

    crate::composite! {
        /// The chain's registers.
        pub struct ChainRegs;
        child_inputs ChainIns;
        child_outputs ChainOuts;
        child_regs ChainNext;
        parent Chain<G: Copy>;
        children {
            /// The first accumulator's.
            first: Acc => (u64, AccIn, AccOut),
            /// The second's.
            second: Acc => (u64, AccIn, AccOut),
        }
        /// The wiring's cycle count.
        glue cycles: u64;
    }

    /// The macro's functions give the composite's reset, settled cycle, prefixed register
    /// signals and children from the one declaration.
    #[test]
    fn a_declared_composite_resets_settles_and_names_its_children() {
        let c = Chain::<u8> {
            first: Acc,
            second: Acc,
            _g: std::marker::PhantomData,
        };
        let mut regs = c.children_reset(7);
        assert_eq!((regs.first, regs.second, regs.cycles), (0, 0, 7));
        for _ in 0..3 {
            let (_, (), _, next) = c
                .settle_children(&regs, 4, |q: &ChainOuts| {
                    let d = ChainIns {
                        first: AccIn(5),
                        second: AccIn(q.first.0),
                    };
                    (d, ())
                })
                .unwrap();
            regs = next.with_glue(regs.cycles + 1);
        }
        // first: 0, 5, 10 -> 15; second adds first's output each cycle: 0 + 0 + 5 + 10.
        assert_eq!((regs.first, regs.second, regs.cycles), (15, 15, 10));
        let names: Vec<String> = c
            .children_reg_signals(&regs, vec![Signal::new("n", 4, regs.cycles)])
            .into_iter()
            .map(|s| format!("{}={}", s.name, s.value))
            .collect();
        assert_eq!(names, ["first_sum=15", "second_sum=15", "cycles_n=10"]);
        let children: Vec<&str> = c.children().into_iter().map(|(n, _)| n).collect();
        assert_eq!(children, ["first", "second"]);
    }

    /// A child whose input is its own output inverted never settles.
    #[test]
    fn a_combinational_loop_is_an_error() {
        let kernel = |q: &bool| (!*q, ());
        let children = |d: &bool| (*d, ());
        assert_eq!(
            settle(false, 8, kernel, children).unwrap_err(),
            SettleError { rounds: 8 }
        );
    }
}
