//! The cycle-exact memory hierarchy of the simulated GPU: one sectored L1 per SM, a shared
//! sectored L2 in memory partitions and `dram_channels` DRAM channels (paper Table 1 and
//! Vulkan-Sim's RTX 3070; ray data bypasses the L1, paper 4.2 and 5).
//!
//! # Structure
//! - [`config`]: [`MemConfig`] (Table 1 defaults) and its validation.
//! - [`cache`]: [`SectorCache`], the tag store of one cache: lines of `line_bytes` (128) with
//!   valid bits per `sector_bytes` (32) sector, LRU, lines being filled never evicted.
//! - [`dram`]: [`Dram`], `dram_channels` interleaved [`DramChannel`]s, each a fixed latency plus
//!   a byte-exact share of the bandwidth.
//! - [`l1`]: [`L1Port`], one SM's L1, MSHRs and responses, whose L2 operations may be applied
//!   later in a fixed order ([`L2Op::key`]) so SMs can be simulated independently between
//!   synchronisation points.
//! - [`l2`]: [`L2Side`], the shared L2 and DRAM, in memory partitions ([`L2Partition`]) that
//!   share no state, one per DRAM channel where the address map allows.
//! - [`system`]: [`MemorySystem`], the ports and the L2 with every L2 operation applied as it
//!   is accepted.
//! - [`responses`]: [`ResponseQueue`], one SM's undelivered responses in delivery order.
//! - [`request`] and [`stats`]: requests, responses, stalls, errors and counters.
//!
//! # Timing rules
//! Every accepted access gets its completion cycle when it is accepted, and every cache and
//! DRAM state change is made then too, stamped with the cycle it takes effect. There is no
//! per-cycle work, so an engine may skip idle cycles: [`MemorySystem::next_event`] is the
//! earliest undelivered response. With `L1 = l1_latency`, `L2 = l2_latency`,
//! `D = dram_latency` and an access accepted at cycle `t`:
//!
//! | case | completion cycle |
//! |---|---|
//! | L1 hit (sector present at `t`) | `t + L1` |
//! | L1 merge (sector being filled, fill cycle `f`) | `f` (completes with the miss it joins) |
//! | L1 miss, L2 hit | `t + L1 + L2` |
//! | L1 miss, L2 merge (L2 sector being filled, fill cycle `f`) | `max(f, t + L1 + L2)` |
//! | L1 miss, L2 miss | `start + D`, `start` = DRAM start cycle for arrival `t + L1 + L2` |
//! | store (any case) | `t + L1 + L2` (acknowledged by the L2) |
//!
//! With Table 1 values an unloaded DRAM access takes 39 + 187 + 254 = 480 cycles: the L2
//! latency stands for the lookup on the way out and the DRAM latency for the trip back.
//!
//! - **Request path.** Every request, including L1 bypasses and stores, pays `L1` before it
//!   reaches the L2 at `t + L1`. Because that offset is the same for all requests, requests
//!   reach the L2 — and DRAM, at `t + L1 + L2` — in acceptance order, so the L2 state and the
//!   DRAM "next free" register are updated in the order the hardware would see them.
//! - **Fills at acceptance.** A miss installs its sector in the L1 (and, on an L2 miss, in
//!   the L2) immediately, marked valid from its completion cycle `f`. A later access to that
//!   sector before `f` is a *merge*: no new request, same completion cycle. From `f` on it is
//!   a hit. A line with a sector still being filled is never chosen as a victim.
//! - **MSHRs.** Each SM has `l1_mshrs` entries; an L1 miss (demand or prefetch) holds one from
//!   acceptance until its fill cycle (free again at `f`). Merges take none and are unlimited.
//!   With all entries busy, or every replaceable line of the set being filled, the access is
//!   refused with [`AccessError::Stall`], whose `retry_at` is the first cycle it can succeed.
//! - **DRAM.** One channel moving `dram_bytes_per_cycle` bytes per cycle (or `dram_channels`
//!   channels sharing it equally, addresses interleaved by `dram_interleave_bytes`), first come
//!   first served, one full sector per read or write (see [`dram`]); a read's data is back at
//!   `start + D` and is then in the L2 and the L1 at once.
//! - **Stores.** L1: write-through, no write-allocate (a store hit updates the sector and
//!   counts as a use for LRU; a miss leaves the L1 unchanged); no MSHR. L2: write-back and
//!   write-allocate without fetching (the written sector becomes valid and dirty from
//!   `t + L1`; partial-sector writes are treated like full ones). Dirty sectors of an evicted
//!   L2 line are written to DRAM, arriving at `t + L1 + L2` after the read that evicted them.
//! - **L1 bypass** (`bypass_l1`, ray records): the L1 is neither looked up nor changed and no
//!   MSHR is used; the L2 path is as above. With `l2_ray_ways > 0`, ray records allocate only
//!   in the reserved L2 ways and other classes only in the rest.
//! - **Prefetch** (`prefetch`, treelet preloads): a load that fills the L1 and delivers no
//!   response. Dropped if the sector is present or being filled; otherwise it takes an MSHR
//!   like a miss. A demand load that later hits or merges with a prefetched sector counts as a
//!   used prefetch; evicting it unused counts as evicted-unused. Prefetches are excluded from
//!   the L1 demand counters but counted at the L2.
//! - **L2 lines all being filled.** If an L2 miss finds every replaceable line of its set
//!   being filled, it is served without allocating in the L2 (counted as `l2_no_allocate`).
//! - **Delivery.** Responses of an SM come out of [`MemorySystem::pop_ready`] in completion
//!   cycle order, ties in acceptance order. Accesses must be offered in non-decreasing cycle
//!   order; within a cycle, call order is acceptance order, so the engine must call in a
//!   fixed order (e.g. by SM index) for determinism.

pub mod cache;
pub mod config;
pub mod dram;
pub mod ghosts;
pub mod l1;
pub mod l2;
pub mod partitions;
pub mod request;
pub mod responses;
pub mod stats;
pub mod system;

pub use cache::{SectorCache, SectorState};
pub use config::{MemConfig, MemConfigError};
pub use dram::{Dram, DramChannel};
pub use ghosts::GhostReads;
pub use l1::{Acceptance, L1Port};
pub use l2::{L2Op, L2Partition, L2Side};
pub use partitions::PartitionMap;
pub use request::{
    Accepted, AccessClass, AccessError, MemRequest, Response, Source, Stall, StallReason,
};
pub use responses::ResponseQueue;
pub use stats::{ClassStats, DramStats, MemStats, PrefetchStats};
pub use system::MemorySystem;
