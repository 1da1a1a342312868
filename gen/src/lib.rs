//! Verilog generation, co-simulation and area estimates for the vtq hardware blocks.
