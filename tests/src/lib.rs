//! vtq's cross-crate tests: where the simulator (`vtq-sim`) meets the hardware blocks
//! (`vtq-hdl`) and their RTL (`vtq-gen`) through their libraries, e.g. a recorded simulation
//! replayed into the blocks and co-simulated against their Verilog (`tests/replay_rtl.rs`),
//! and the check that the composed block and the simulator read the blocks only through the
//! block framework (`tests/one_face.rs`, over `vtq-hdl`'s and `vtq-sim`'s sources).
//! The tests are in `tests/`; this library is empty. Where each kind of test lives:
//! docs/architecture.md, "Where the tests are".
