//! What goes into and comes out of the memory system: [`MemRequest`], [`Accepted`],
//! [`Response`], and why an access is refused ([`AccessError`], [`Stall`]).

use std::fmt;

use serde::{Deserialize, Serialize};

/// What a request carries, for statistics by class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum AccessClass {
    /// BVH nodes (demand fetches and treelet preloads).
    Bvh,
    /// 32 B ray records of virtualized rays (normally with `bypass_l1`).
    RayRecord,
    /// Saved and restored CTA state (registers, SIMT stacks) of suspended CTAs.
    CtaState,
    /// Hit records written by the RT unit.
    HitRecord,
    /// Traversal-stack entries the RT unit spills to and fills back from memory.
    Stack,
    /// Traversal stacks of rays waiting in treelet queues (`rt.queued_stack_traffic`).
    RayStack,
}

impl AccessClass {
    /// Every class, in statistics order.
    pub const ALL: [AccessClass; 6] = [
        AccessClass::Bvh,
        AccessClass::RayRecord,
        AccessClass::CtaState,
        AccessClass::HitRecord,
        AccessClass::Stack,
        AccessClass::RayStack,
    ];
}

/// One access of at most one sector, issued by an SM (or its RT unit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemRequest {
    /// Byte address.
    pub addr: u64,
    /// Bytes accessed, 1..=`sector_bytes`, not crossing a sector boundary.
    pub bytes: u32,
    /// What the data is.
    pub class: AccessClass,
    /// A store (write-through to the L2; acknowledged by a [`Response`] with `store` set).
    pub store: bool,
    /// Skip the L1 entirely (ray-record traffic, paper 4.2).
    pub bypass_l1: bool,
    /// A load that only fills the L1 (treelet preload): no response, own statistics.
    pub prefetch: bool,
    /// Requester's identifier, returned in the [`Response`].
    pub tag: u64,
}

impl MemRequest {
    /// A demand load.
    pub fn load(addr: u64, bytes: u32, class: AccessClass, tag: u64) -> Self {
        MemRequest {
            addr,
            bytes,
            class,
            store: false,
            bypass_l1: false,
            prefetch: false,
            tag,
        }
    }

    /// A store.
    pub fn store(addr: u64, bytes: u32, class: AccessClass, tag: u64) -> Self {
        MemRequest {
            store: true,
            ..MemRequest::load(addr, bytes, class, tag)
        }
    }

    /// A prefetch of the sector holding `addr` into the L1.
    pub fn prefetch(addr: u64, class: AccessClass) -> Self {
        MemRequest {
            prefetch: true,
            ..MemRequest::load(addr, 1, class, 0)
        }
    }

    /// The same request, bypassing the L1.
    pub fn bypassing_l1(self) -> Self {
        MemRequest {
            bypass_l1: true,
            ..self
        }
    }
}

/// Where an accepted access was served from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Source {
    /// The sector was in the L1.
    L1Hit,
    /// The sector was being filled into the L1: merged with that miss (MSHR hit).
    L1Merge,
    /// Present in the L2.
    L2Hit,
    /// Being filled into the L2 from DRAM: merged with that fill.
    L2Merge,
    /// Read from DRAM.
    Dram,
    /// A store, acknowledged by the L2.
    L2Write,
    /// A prefetch of a sector already in (or being filled into) the L1: nothing was done.
    AlreadyInL1,
}

/// An accepted access: when it completes and where it was served from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Accepted {
    /// Cycle its [`Response`] is delivered (for a prefetch: the L1 fill cycle, or the access
    /// cycle when dropped; no response is delivered).
    pub done: u64,
    /// Where it was served from.
    pub source: Source,
}

/// A completed access, delivered to its SM by
/// [`MemorySystem::pop_ready`](super::MemorySystem::pop_ready).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Response {
    /// The request's tag.
    pub tag: u64,
    /// The request's address.
    pub addr: u64,
    /// The request's class.
    pub class: AccessClass,
    /// Whether this acknowledges a store.
    pub store: bool,
    /// Completion cycle.
    pub cycle: u64,
}

/// Why an access had to be refused for now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum StallReason {
    /// Every L1 MSHR of the SM holds an outstanding miss.
    MshrsFull,
    /// Every line the L1 miss could replace is itself being filled.
    SetReserved,
}

/// A refused access: retry later. Nothing changed except the stall counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Stall {
    /// What is full.
    pub reason: StallReason,
    /// First cycle at which the same access can succeed (the earliest fill that frees the
    /// resource), unless other accesses of the same SM take the resource first.
    pub retry_at: u64,
}

impl fmt::Display for Stall {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self.reason {
            StallReason::MshrsFull => "all L1 MSHRs are busy",
            StallReason::SetReserved => "every replaceable L1 line is being filled",
        };
        write!(f, "{what}; retry at cycle {}", self.retry_at)
    }
}

/// Largest cycle accepted by [`MemorySystem::access`](super::MemorySystem::access), so
/// completion cycles never overflow.
pub const MAX_CYCLE: u64 = 1 << 60;

/// Why [`MemorySystem::access`](super::MemorySystem::access) did not accept a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AccessError {
    /// Back-pressure: retry the same request later (at the earliest at `retry_at`).
    #[error("memory access stalled: {0}")]
    Stall(Stall),
    /// The SM index is out of range.
    #[error("SM {sm} does not exist (the memory system has {num_sms} SMs)")]
    NoSuchSm {
        /// Requested SM.
        sm: usize,
        /// SMs in the memory system.
        num_sms: usize,
    },
    /// The request is empty, larger than a sector, or crosses a sector boundary.
    #[error(
        "request of {bytes} B at {addr:#x} must be 1..={sector_bytes} B within one {sector_bytes} B sector"
    )]
    BadSize {
        /// Request address.
        addr: u64,
        /// Request size.
        bytes: u32,
        /// Configured sector size.
        sector_bytes: u32,
    },
    /// A prefetch that is also a store or bypasses the L1 (a prefetch only fills the L1).
    #[error("a prefetch must be a load that does not bypass the L1 (request at {addr:#x})")]
    BadPrefetch {
        /// Request address.
        addr: u64,
    },
    /// Accesses must be made in non-decreasing cycle order.
    #[error("access at cycle {now} after an access at cycle {last}: time must not go backwards")]
    TimeWentBackwards {
        /// Cycle given.
        now: u64,
        /// Cycle of the previous access.
        last: u64,
    },
    /// The cycle is beyond [`MAX_CYCLE`].
    #[error("cycle {now} is beyond the supported maximum {MAX_CYCLE}")]
    CycleOutOfRange {
        /// Cycle given.
        now: u64,
    },
}

impl AccessError {
    /// The stall, when this is back-pressure rather than a bad request.
    pub fn stall(&self) -> Option<Stall> {
        match self {
            AccessError::Stall(s) => Some(*s),
            _ => None,
        }
    }
}
