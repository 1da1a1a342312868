//! Shared helpers for the cross-crate tests (small in-code meshes, scene paths).
