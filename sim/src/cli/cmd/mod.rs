//! The `vtq` subcommands, one module each.

pub mod accuracy;
pub mod area;
pub mod bench;
pub mod compare;
pub mod cosim;
pub mod designs;
pub mod energy;
pub mod figure5;
pub mod fuzz;
pub mod options;
pub mod render;
pub mod reproduce;
pub mod runner;
pub mod scenes;
pub mod sim;
pub mod sweep;
pub mod trace;
pub mod verilog;
