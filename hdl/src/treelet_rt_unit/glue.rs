//! The treelet RT unit's wiring registers ([`GlueRegs`]): who owns each warp-buffer slot, the
//! fills being built, the event FIFO for the controller, the tables' registered answers, the
//! free ray ids and the first fault; declared once with their trace signals ([`registers`]).

use std::fmt;

use super::TreeletRtUnitWidths;
use crate::bits::bits_for;
use crate::bounded::{BoundedDeque, BoundedVec};
use crate::config::HwConfig;
use crate::controller::FillKind;
use crate::describe::MemDesc;
use crate::queue_table::PopResult;
use crate::registers::RegTable;

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

/// A fill the controller is giving to a slot: its rays, and which lanes their records were
/// written into as they arrived (the records themselves go straight into the RT unit's lanes,
/// [`crate::rt_unit::LaneWrite`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Build {
    /// What the fill builds.
    pub kind: FillKind,
    /// Ray ids, in the order the controller gave them (at most `warp_size`; the fill's
    /// entries).
    pub rays: BoundedVec<u32>,
    /// Per entry: its record has arrived.
    pub arrived: BoundedVec<bool>,
    /// Bit `l` set: lane `l` of the slot holds one of the fill's records. Entry `k` of a
    /// treelet or grouped fill goes to lane `k`; a repack's records go, in the order they
    /// arrive, to the lowest inactive lane of the held warp not yet written.
    pub filled: u64,
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
    /// Rays left the RT unit with more ids than were in use.
    IdsReturned {
        /// Ids given back in the cycle.
        returned: u32,
        /// Ids in use.
        in_use: u32,
    },
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
    /// Ray records of two slots arrived in one cycle (they share one lane-write port).
    MixedRecords {
        /// The slot of the cycle's first record.
        first: u32,
        /// The other slot.
        other: u32,
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
            GlueFault::IdsReturned { returned, in_use } => write!(
                f,
                "{returned} rays left the RT unit in one cycle but only {in_use} ray ids were in use"
            ),
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
            GlueFault::MixedRecords { first, other } => write!(
                f,
                "ray records for slots {first} and {other} arrived in one cycle; the RT unit \
                 writes one slot a cycle"
            ),
            GlueFault::Full { what, depth } => {
                write!(f, "the wiring's {what} ({depth} entries) overflowed")
            }
        }
    }
}

/// The free ray ids of an SM (`max_rays` ray-record slots) as a stack in SRAM, with the ids
/// never given out yet counted apart.
///
/// Hardware: the stack is [`id_banks`] SRAM banks of `max_rays / banks` words of a ray id each,
/// one read and one write port apiece (stack position `p` is word `p / banks` of bank
/// `p % banks`, so the `warp_size` positions an admission pops and the up to `2 x warp_size`
/// an unpacking pushes each meet a bank once). Registers: the stack's count, the first id
/// never given out (`fresh`: ids from it up are free without being on the stack, so reset needs
/// no initialisation sequence), and per bank a bypass (the id it was written in the previous
/// cycle, if any). Every cycle each bank reads the one position of the top `2 x warp_size` that
/// it holds; an id pushed in a cycle is read from its bank's bypass in the next. So the top
/// `warp_size` ids are always readable: there is no lag, and an id given back in a cycle can be
/// given out in the next.
///
/// An admitted warp's active lanes take, in lane order, ids popped from the top, then fresh
/// ones. Last in, first out keeps a reused id's ray-record and hit-record lines warm in the L2
/// (docs/hardware.md, "Free ray ids in an SRAM stack").
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdPool {
    /// The stack (`max_rays` positions); positions `0..count` hold free ids, the top last.
    stack: Box<[u32]>,
    /// Free ids on the stack.
    count: u32,
    /// Ids from `fresh` up to `max_rays` have never been given out.
    fresh: u32,
    /// Lanes of a warp (at most this many ids are popped in a cycle).
    lanes: u32,
}

/// Banks of the free-id stack: `2 x warp_size` (a warp popped and two pushed a cycle), at most
/// `max_rays`.
pub fn id_banks(cfg: &HwConfig) -> u32 {
    (2 * cfg.warp_size).min(cfg.max_rays)
}

impl IdPool {
    /// Every id free, none on the stack.
    fn new(cfg: &HwConfig) -> Self {
        IdPool {
            stack: vec![0; cfg.max_rays as usize].into(),
            count: 0,
            fresh: 0,
            lanes: cfg.warp_size,
        }
    }

    /// Free ids (on the stack or never given out).
    pub fn len(&self) -> u32 {
        self.count + self.stack.len() as u32 - self.fresh
    }

    /// Whether no id is free.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Ids an admission may take this cycle: the stack's top warp and the fresh ones.
    pub fn available(&self) -> u32 {
        self.count.min(self.lanes) + self.stack.len() as u32 - self.fresh
    }

    /// Ids given out and not given back.
    pub fn in_use(&self) -> u32 {
        self.fresh - self.count
    }

    /// Takes `need <= available()` ids, in order: popped from the top, then fresh ones.
    pub(super) fn take(&mut self, need: u32) -> impl Iterator<Item = u32> + '_ {
        debug_assert!(need <= self.available(), "take beyond the available ids");
        let popped = need.min(self.count).min(self.lanes);
        let (top, fresh) = (self.count, self.fresh);
        self.count -= popped;
        self.fresh += need - popped;
        let stack = &self.stack;
        (0..need).map(move |k| {
            if k < popped {
                stack[(top - 1 - k) as usize]
            } else {
                fresh + k - popped
            }
        })
    }

    /// Pushes `ids` in order (after the cycle's pops); more than are in use is an error (the
    /// in-use count) and gives nothing back.
    pub(super) fn give(&mut self, ids: impl ExactSizeIterator<Item = u32>) -> Result<(), u32> {
        let n = ids.len() as u32;
        if n > self.in_use() {
            return Err(self.in_use());
        }
        for (k, id) in ids.enumerate() {
            self.stack[(self.count + k as u32) as usize] = id;
        }
        self.count += n;
        Ok(())
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
            ids: IdPool::new(cfg),
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

/// The wiring's memories: the free-id stack's banks ([`IdPool`]).
pub(super) fn memories(cfg: &HwConfig, w: &TreeletRtUnitWidths) -> Vec<MemDesc> {
    let banks = id_banks(cfg);
    vec![MemDesc {
        name: "free_ids".into(),
        banks,
        depth: cfg.max_rays / banks,
        width: w.ray,
        read_ports: 1,
        write_ports: 1,
        read_latency: 1,
        fields: vec![("ray".into(), w.ray)],
        doc: format!(
            "the free-id stack: position p is word p / {banks} of bank p % {banks}; each cycle \
             every bank reads the position of the top {banks} that it holds and writes at most \
             one id given back"
        ),
    }]
}

/// The wiring's registers for `cfg` and widths `w`: their descriptions and trace signals,
/// declared once. Traced: the slots' owners, whether each slot has a fill and its records still
/// loading, and the event FIFO's and the id pool's occupancies; the fills' rays and records,
/// the events and the tables' registered answers are described only.
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
    .one(
        "id_count",
        bits_for(cfg.max_rays as u64),
        "free ids on the stack",
        |g| g.ids.count as u64,
    )
    .one(
        "id_fresh",
        bits_for(cfg.max_rays as u64),
        "the first id never given out",
        |g| g.ids.fresh as u64,
    )
    .untraced(
        "id_bypass",
        1 + w.ray,
        id_banks(cfg),
        "per free-id bank: the id written in the previous cycle (valid, id), read in place of \
         the bank's read data",
    )
    .untraced("fault", 1, 1, "an inconsistency was found (sticky)");
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pool(max_rays: u32, warp_size: u32) -> IdPool {
        IdPool::new(&HwConfig {
            max_rays,
            warp_size,
            ..HwConfig::default()
        })
    }

    /// One cycle: `need` ids taken, then `back` given back.
    fn cycle(p: &mut IdPool, need: u32, back: &[u32]) -> Vec<u32> {
        let got: Vec<u32> = p.take(need).collect();
        p.give(back.iter().copied()).expect("ids in use");
        got
    }

    #[test]
    fn fresh_ids_first_then_the_stack_last_in_first_out_from_the_next_cycle() {
        let mut p = pool(16, 4);
        assert_eq!((p.len(), p.available(), p.in_use()), (16, 16, 0));
        assert_eq!(cycle(&mut p, 4, &[]), [0, 1, 2, 3]);
        // Ids 2 and 0 come back; they can be given out from the next cycle.
        assert_eq!(cycle(&mut p, 3, &[2, 0]), [4, 5, 6]);
        assert_eq!((p.len(), p.available(), p.in_use()), (11, 11, 5));
        // The last id given back first, then the one before, then fresh.
        assert_eq!(cycle(&mut p, 3, &[5]), [0, 2, 7]);
        assert_eq!(cycle(&mut p, 1, &[]), [5]);
        assert_eq!((p.len(), p.in_use()), (8, 8));
    }

    #[test]
    fn a_cycle_pops_at_most_a_warp_of_the_stack() {
        let mut p = pool(8, 2);
        for _ in 0..4 {
            cycle(&mut p, 2, &[]);
        }
        assert_eq!((p.available(), p.in_use()), (0, 8));
        cycle(&mut p, 0, &[7, 6, 5, 4, 3]);
        assert_eq!(p.available(), 2, "a warp's worth of the stack's 5");
        // Pops come from the top; ids pushed in a cycle sit above what is left.
        assert_eq!(cycle(&mut p, 2, &[0, 1, 2]), [3, 4]);
        assert_eq!(cycle(&mut p, 2, &[]), [2, 1]);
        assert_eq!(cycle(&mut p, 2, &[]), [0, 5]);
        assert_eq!(cycle(&mut p, 2, &[]), [6, 7]);
        assert_eq!((p.len(), p.in_use()), (0, 8));
    }

    #[test]
    fn more_ids_back_than_in_use_is_refused_whole() {
        let mut p = pool(8, 2);
        cycle(&mut p, 2, &[]);
        assert_eq!(p.give([0, 1, 1].into_iter()), Err(2));
        assert_eq!((p.len(), p.in_use()), (6, 2), "nothing given back");
    }

    #[test]
    fn banks_cover_what_a_cycle_takes_and_gives() {
        let at = |max_rays, warp_size| {
            id_banks(&HwConfig {
                max_rays,
                warp_size,
                ..HwConfig::default()
            })
        };
        assert_eq!(at(4096, 32), 64);
        assert_eq!(at(32, 32), 32);
        assert_eq!(at(8, 2), 4);
    }
}
