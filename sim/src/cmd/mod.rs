//! The `vtq` subcommands, one module each.

pub mod bench;
pub mod options;
pub mod render;
pub mod scenes;
pub mod trace;
