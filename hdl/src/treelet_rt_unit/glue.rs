//! The treelet RT unit's wiring registers ([`GlueRegs`]): who owns each warp-buffer slot, the
//! fills being built, the event FIFO for the controller, the tables' registered answers, the
//! free ray ids and the first fault; declared once with their trace signals ([`registers`]).

use std::fmt;

use super::TreeletRtUnitWidths;
use crate::bits::bits_for;
use crate::bounded::{BoundedDeque, BoundedVec};
use crate::config::HwConfig;
use crate::controller::FillKind;
use crate::queue_table::PopResult;
use crate::registers::RegTable;
use crate::rt_unit::RayRecord;

/// Who owns a warp-buffer slot, as the wiring sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotUse {
    /// Free for an SM warp or a controller fill (code 0).
    Free,
    /// An SM warp in its initial traversal phase, possibly terminated (code 1).
    Initial,
    /// A warp the controller filled (treelet or grouped), building or traversing (code 2).
    Controller,
    /// Its warp completed; enqueues and `warp_done` still to deliver (code 3).
    Closing,
}

impl SlotUse {
    /// The encoding.
    fn code(self) -> u64 {
        match self {
            SlotUse::Free => 0,
            SlotUse::Initial => 1,
            SlotUse::Controller => 2,
            SlotUse::Closing => 3,
        }
    }
}

/// A fill the controller is giving to a slot: its rays, and their records as they arrive,
/// each written into the lane it is issued to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Build {
    /// What the fill builds.
    pub kind: FillKind,
    /// Ray ids, in the order the controller gave them (at most `warp_size`; the fill's
    /// entries).
    pub rays: BoundedVec<u32>,
    /// Per entry: its record has arrived.
    pub arrived: BoundedVec<bool>,
    /// Per lane (`warp_size` of them): the record written there, `None` until one arrives.
    /// Entry `k` of a treelet or grouped fill goes to lane `k`; a repack's records go, in the
    /// order they arrive, to the lowest inactive lane of the held warp not yet written.
    pub records: Box<[Option<RayRecord>]>,
    /// Records not yet arrived.
    pub loading: u32,
    /// The controller closed the fill.
    pub last: bool,
}

/// Something the RT unit reports to the controller after a warp completes, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// A ray stopped at a treelet boundary: insert it into that treelet's queue.
    Enqueue {
        /// Ray id.
        ray: u32,
        /// The treelet it needs next.
        treelet: u32,
    },
    /// The slot's warp has sent all its rays.
    WarpDone(u32),
}

/// An inconsistency the wiring found (a modelling bug, reported rather than giving wrong
/// numbers).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GlueFault {
    /// A ray left the RT unit with an id that is not in use.
    UnknownRay(u32),
    /// A table raised its error output for an op.
    TableError(&'static str),
    /// A fill could not place all of its rays.
    Unplaced {
        /// The slot.
        slot: u32,
        /// Rays placed.
        placed: usize,
        /// Rays of the fill.
        rays: usize,
    },
    /// A ray record arrived for a fill that did not ask for it.
    UnexpectedRecord {
        /// The slot named.
        slot: u32,
        /// The ray.
        ray: u32,
    },
    /// A register array of the wiring was full (its depth is too small for the protocol).
    Full {
        /// The array.
        what: &'static str,
        /// Its depth.
        depth: usize,
    },
}

impl fmt::Display for GlueFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GlueFault::UnknownRay(id) => {
                write!(f, "ray id {id} left the RT unit but is not in use")
            }
            GlueFault::TableError(what) => write!(f, "{what}"),
            GlueFault::Unplaced { slot, placed, rays } => write!(
                f,
                "a fill of slot {slot} placed {placed} of its {rays} rays"
            ),
            GlueFault::UnexpectedRecord { slot, ray } => {
                write!(
                    f,
                    "a record of ray {ray} arrived for slot {slot}, which did not ask for it"
                )
            }
            GlueFault::Full { what, depth } => {
                write!(f, "the wiring's {what} ({depth} entries) overflowed")
            }
        }
    }
}

/// The ray-record slots of an SM (`max_rays` ray ids) as a bitmap of free ids; the lowest free
/// id is given first (a priority encoder).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdPool {
    free: Box<[u64]>,
    count: u32,
}

impl IdPool {
    /// Every id below `n` free.
    fn new(n: u32) -> Self {
        let mut free = vec![u64::MAX; (n as usize).div_ceil(64)];
        if !n.is_multiple_of(64) {
            *free.last_mut().expect("at least one word") = (1u64 << (n % 64)) - 1;
        }
        IdPool {
            free: free.into(),
            count: n,
        }
    }

    /// Free ids.
    pub fn len(&self) -> u32 {
        self.count
    }

    /// Whether no id is free.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Whether `id` is in use.
    pub(super) fn in_use(&self, id: u32) -> bool {
        self.free
            .get(id as usize / 64)
            .is_some_and(|w| w >> (id % 64) & 1 == 0)
    }

    /// Takes the lowest free id.
    pub(super) fn take(&mut self) -> Option<u32> {
        let (i, w) = self.free.iter_mut().enumerate().find(|(_, w)| **w != 0)?;
        let bit = w.trailing_zeros();
        *w &= !(1 << bit);
        self.count -= 1;
        Some(i as u32 * 64 + bit)
    }

    /// Frees `id`.
    pub(super) fn give(&mut self, id: u32) {
        if let Some(w) = self.free.get_mut(id as usize / 64) {
            if *w >> (id % 64) & 1 == 0 {
                *w |= 1 << (id % 64);
                self.count += 1;
            }
        }
    }
}

/// The wiring's registers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GlueRegs {
    /// Who owns each warp-buffer slot (`warp_buffer_size` entries).
    pub uses: Box<[SlotUse]>,
    /// The fill being built in each slot (`warp_buffer_size` entries).
    pub builds: Box<[Option<Build>]>,
    /// Events for the controller, oldest first: a FIFO of depth
    /// [`event_depth`]` = warp_buffer_size x (warp_size + 1)` (one enqueue per ray and one warp
    /// done per slot).
    pub events: BoundedDeque<Event>,
    /// The count table's eviction of the previous cycle.
    pub ct_evict: Option<u32>,
    /// The queue table's answer of the previous cycle.
    pub qt_done: Option<PopResult>,
    /// Free ray ids.
    pub ids: IdPool,
    /// The first inconsistency found (sticky).
    pub fault: Option<GlueFault>,
}

impl GlueRegs {
    /// The registers after reset.
    pub fn reset(cfg: &HwConfig) -> Self {
        let slots = cfg.warp_buffer_size as usize;
        GlueRegs {
            uses: vec![SlotUse::Free; slots].into(),
            builds: vec![None; slots].into(),
            events: BoundedDeque::new(event_depth(cfg)),
            ct_evict: None,
            qt_done: None,
            ids: IdPool::new(cfg.max_rays),
            fault: None,
        }
    }

    /// Records an inconsistency (the first one is kept).
    pub(super) fn set_fault(&mut self, fault: GlueFault) {
        self.fault.get_or_insert(fault);
    }

    /// Appends an event for the controller (a fault if the FIFO is full).
    pub(super) fn push_event(&mut self, event: Event) {
        if let Err(full) = self.events.push_back(event) {
            self.set_fault(GlueFault::Full {
                what: "event FIFO",
                depth: full.capacity,
            });
        }
    }
}

/// Depth of the wiring's event FIFO: one enqueue per ray and one warp done per warp-buffer
/// slot (`warp_buffer_size x (warp_size + 1)`).
pub fn event_depth(cfg: &HwConfig) -> usize {
    cfg.warp_buffer_size as usize * (cfg.warp_size as usize + 1)
}

/// The wiring's registers for `cfg` and widths `w`: their descriptions and trace signals,
/// declared once. Traced: the slots' owners, whether each slot has a fill and its records still
/// loading, and the event FIFO's and the id pool's occupancies; the fills' rays and records,
/// the events, the tables' registered answers and the free-id bitmap are described only.
pub(super) fn registers(cfg: &HwConfig, w: &TreeletRtUnitWidths) -> RegTable<'static, GlueRegs> {
    let slots = cfg.warp_buffer_size;
    let lanes = bits_for(cfg.warp_size as u64);
    let events = event_depth(cfg) as u32;
    let mut t = RegTable::new();
    t.bank(
        "slot_use",
        2,
        slots,
        "per slot: free / initial-phase SM warp / controller fill / closing",
        |g: &GlueRegs, i| g.uses[i].code(),
    )
    .bank(
        "build_valid",
        1,
        slots,
        "per slot: a fill is being built",
        |g, i| g.builds[i].is_some() as u64,
    )
    .untraced(
        "build_kind",
        FillKind::BITS,
        slots,
        "per slot: what the fill builds",
    )
    .untraced(
        "build_rays",
        w.ray,
        slots * cfg.warp_size,
        "per slot: the fill's ray ids",
    )
    .untraced(
        "build_records",
        w.record,
        slots * cfg.warp_size,
        "per slot and lane: the fill's loaded ray record issued to that lane",
    )
    .untraced(
        "build_filled",
        1,
        slots * cfg.warp_size,
        "per slot and lane: a record is written there",
    )
    .untraced(
        "build_arrived",
        1,
        slots * cfg.warp_size,
        "per slot: whether each of the fill's records (its entries) has arrived",
    )
    .untraced("build_count", lanes, slots, "per slot: the fill's rays")
    .bank(
        "build_loading",
        lanes,
        slots,
        "per slot: records not yet arrived",
        |g, i| g.builds[i].as_ref().map_or(0, |b| b.loading as u64),
    )
    .untraced("build_last", 1, slots, "per slot: the fill is closed")
    .untraced(
        "events",
        1 + w.ray + w.treelet,
        events,
        "events for the controller (FIFO): enqueue (ray, treelet) or warp done (slot)",
    )
    .one(
        "event_count",
        bits_for(events as u64),
        "valid entries of the event FIFO",
        |g| g.events.len() as u64,
    )
    .untraced(
        "last_ct_evict",
        1 + w.treelet,
        1,
        "the count table's eviction of the previous cycle",
    )
    .untraced(
        "last_qt_done",
        1 + w.treelet + lanes + w.ray * cfg.warp_size,
        1,
        "the queue table's answer of the previous cycle",
    )
    .untraced("free_ids", 1, cfg.max_rays, "free ray ids (lowest first)")
    .one(
        "free_count",
        bits_for(cfg.max_rays as u64),
        "free ray ids (the bitmap's population count)",
        |g| g.ids.len() as u64,
    )
    .untraced("fault", 1, 1, "an inconsistency was found (sticky)");
    t
}
