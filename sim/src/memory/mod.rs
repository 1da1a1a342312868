//! Memory hierarchy model (being written).
