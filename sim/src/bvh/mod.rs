//! The hardware BVH: built with `obvhs`, collapsed to the configured width and laid out in a
//! byte-addressed memory image in the Intel/Vulkan-Sim style (see `layout`).

pub mod build;
pub mod cache;
pub mod layout;
