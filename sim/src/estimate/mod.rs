//! The estimate tiers: faster answers than full detail, each with its error measured against
//! it (docs/accuracy.md).

pub mod figure5;
pub mod sample;
