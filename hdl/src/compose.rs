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

#[cfg(test)]
mod tests {
    use super::*;

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
