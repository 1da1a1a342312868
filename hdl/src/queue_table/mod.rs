//! The hash-chained treelet queue table (paper section 4.2, Figure 9, section 6.5): which rays
//! wait for which treelet, in entries of up to one warp of ray ids.
//!
//! # Structure
//! - `heads`: a flip-flop array of `buckets` chain heads `{valid, idx}` (latency 0, 1R 1W).
//! - `meta`: an SRAM of `queue_table_entries` words `{treelet, count_m1, next_valid, next}`
//!   (latency 1, 1R 1W): the entry's treelet, fill count - 1 (1..=warp_size rays) and chain link.
//! - `rays`: an SRAM of the same depth holding `warp_size` ray ids per entry (latency 1, 1R 1W
//!   with a write enable per ray lane, so an insert writes one lane).
//! - `valid`: one flip-flop per entry; its complement is the free list, and a priority encoder
//!   picks the lowest free entry (allocation) or the lowest valid entry (PopAny).
//! - An FSM (`IDLE`, `WALK`, `ANY_META`, `POP_RAYS`, `REFILL_WAIT`) plus walk registers.
//!
//! A treelet hashes to bucket [`bucket_hash`]: the XOR of the treelet address cut into
//! `log2(buckets)`-bit groups from the least significant bit. New entries are linked at the head of
//! their bucket's chain, so along a chain entries appear newest first; a treelet has at most one
//! non-full entry (a new one is allocated only when all of its entries are full), and it is the
//! first of that treelet's entries in its chain.
//!
//! # Operations (`op_kind`: 0 Nop, 1 Insert, 2 Pop, 3 PopAny, 4 Count, 5 Refill)
//! An op is accepted when `ready` is high (only in `IDLE`); `done` pulses in the cycle its
//! result is on the outputs, and `ready` returns the cycle after. One walk step reads one `meta`
//! word per cycle. With `k` = position (1-based) of the first entry of the treelet in its chain
//! and `L` = chain length:
//! - **Insert** `{treelet, ray}`: 1 cycle into an empty bucket, else `1 + k` (or `1 + L` when the
//!   treelet has no entry). Appends to the treelet's first entry when it is not full, else
//!   allocates the lowest free entry at the chain head; with no free entry the ray **spills**:
//!   `spill_valid/spill_treelet/spill_ray` pulse with `done` and `spilled` counts it. The
//!   environment must store every spilled ray (a FIFO in memory).
//! - **Pop** `{treelet}`: unlinks the treelet's first entry and returns its rays on `pop_ray_*`
//!   with `pop_count`/`pop_treelet`: `2 + k` cycles; not found: `pop_count` = 0 after 1 cycle
//!   (empty bucket) or `1 + L`.
//! - **PopAny**: pops the lowest-index valid entry (to group underpopulated queues): `3 + k`
//!   cycles (read its treelet, then walk its chain to unlink it); empty table: 1 cycle.
//! - **Count** `{treelet}`: total rays of the treelet in the table on `count_result`: 1 cycle
//!   (empty bucket) or `1 + L`.
//! - **Refill**: brings one spilled ray back. With `spilled` = 0 it is done at once. Otherwise
//!   `refill_req` pulses and the table waits in `REFILL_WAIT` (ignoring ops) until the
//!   environment presents the oldest spilled ray on `refill_valid/refill_treelet/refill_ray`
//!   (exactly one answer per request, any number of cycles later); `spilled` then decrements and
//!   the ray is inserted as by Insert, starting in the answer cycle (it may spill again, so rays
//!   are never lost or duplicated). `refill_valid` outside `REFILL_WAIT` raises `error` and is
//!   ignored.

use crate::bits::{bits_for, clog2};
use crate::block::{Block, Signal};
use crate::bounded::BoundedVec;
use crate::config::{ConfigError, HwConfig};
use crate::describe::BlockDesc;
use crate::memory::{MemPorts, Memory};

mod desc;
mod walk;

use walk::Cycle;

/// Operation presented to the queue table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QueueOp {
    /// No operation (`op_kind` 0).
    Nop,
    /// Queue `ray` for `treelet` (`op_kind` 1).
    Insert {
        /// Treelet address.
        treelet: u64,
        /// Ray id.
        ray: u32,
    },
    /// Remove one entry (up to a warp of rays) of `treelet` (`op_kind` 2).
    Pop {
        /// Treelet address.
        treelet: u64,
    },
    /// Remove the lowest-index valid entry, whatever its treelet (`op_kind` 3).
    PopAny,
    /// Total rays of `treelet` in the table (`op_kind` 4).
    Count {
        /// Treelet address.
        treelet: u64,
    },
    /// Bring one spilled ray back from memory (`op_kind` 5).
    Refill,
}

impl QueueOp {
    /// The `op_kind` encoding: 0 Nop, 1 Insert, 2 Pop, 3 PopAny, 4 Count, 5 Refill.
    pub fn kind_code(&self) -> u64 {
        match self {
            QueueOp::Nop => 0,
            QueueOp::Insert { .. } => 1,
            QueueOp::Pop { .. } => 2,
            QueueOp::PopAny => 3,
            QueueOp::Count { .. } => 4,
            QueueOp::Refill => 5,
        }
    }
}

/// The bucket of a treelet: XOR of the treelet address's `bucket_bits`-wide groups, least
/// significant group first (`ceil(treelet_bits / bucket_bits)` groups; the top group is
/// zero-extended). With 19-bit addresses and 128 buckets: `t[6:0] ^ t[13:7] ^ t[18:14]`.
pub fn bucket_hash(treelet: u64, treelet_bits: u32, bucket_bits: u32) -> u32 {
    let mask = (1u64 << bucket_bits) - 1;
    let mut h = 0;
    let mut shift = 0;
    while shift < treelet_bits {
        h ^= (treelet >> shift) & mask;
        shift += bucket_bits;
    }
    h as u32
}

/// Bit widths of the queue table's signals, derived from the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QueueTableWidths {
    /// Treelet address bits (19 by default).
    pub treelet: u32,
    /// Ray id bits (12 by default).
    pub ray: u32,
    /// Rays per entry (warp size): the number of `pop_ray_*` ports and ray lanes.
    pub lanes: u32,
    /// Bits of an entry fill count - 1 (5 for 32 rays).
    pub count_m1: u32,
    /// Bits of `pop_count` (0..=warp_size).
    pub pop_count: u32,
    /// Bits of `count_result` (0..=entries x warp_size, the table's capacity).
    pub total: u32,
    /// Bits of `spilled` (0..=max_rays).
    pub spilled: u32,
    /// Bits of an entry index / chain link.
    pub index: u32,
    /// Bits of a number of entries 0..=queue_table_entries.
    pub entries: u32,
    /// Bits of a bucket index.
    pub bucket: u32,
}

crate::bundle! {
    /// Input ports of the queue table.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct QueueTableIn (In, w: QueueTableWidths, this) {
        /// This cycle's operation.
        pub op: QueueOp,
        /// The environment answers a `refill_req` with a spilled ray.
        pub refill_valid: bool,
        /// Treelet of the refilled ray.
        pub refill_treelet: u64,
        /// Id of the refilled ray.
        pub refill_ray: u32,
    }
    ports {
        /// operation: 0 Nop, 1 Insert, 2 Pop, 3 PopAny, 4 Count, 5 Refill
        sig op_kind (QueueOp::BITS) = this.op.kind_code();
        /// treelet address of Insert/Pop/Count
        sig op_treelet (w.treelet) = this.op.fields().0;
        /// ray id of Insert
        sig op_ray (w.ray) = this.op.fields().1 as u64;
        /// the spill store answers a refill request
        sig refill_valid (1) = this.refill_valid as u64;
        /// treelet of the refilled ray
        sig refill_treelet (w.treelet) = this.refill_treelet;
        /// id of the refilled ray
        sig refill_ray (w.ray) = this.refill_ray as u64;
    }
}

crate::bundle! {
    /// Output ports of the queue table.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct QueueTableOut (Out, w: QueueTableWidths, this) {
        /// An op presented this cycle is accepted.
        pub ready: bool,
        /// The current op finishes this cycle; its results are on the outputs.
        pub done: bool,
        /// Protocol violation or inconsistent table (unexpected `refill_valid`, PopAny entry
        /// not found in its chain).
        pub error: bool,
        /// Rays popped (0: nothing found); nonzero only with `done` of Pop/PopAny.
        pub pop_count: u32,
        /// Treelet of the popped entry.
        pub pop_treelet: u64,
        /// Popped ray ids in insertion order (`warp_size` lanes); lanes at or beyond
        /// `pop_count` are 0.
        pub pop_rays: Vec<u32>,
        /// Rays of the treelet in the table (with `done` of Count; 0 otherwise).
        pub count_result: u32,
        /// A ray spills to memory this cycle; the environment must store it.
        pub spill_valid: bool,
        /// Treelet of the spilled ray.
        pub spill_treelet: u64,
        /// Id of the spilled ray.
        pub spill_ray: u32,
        /// Request for one spilled ray (answer on `refill_*`).
        pub refill_req: bool,
        /// The table waits for the answer to its refill request (registers only).
        pub refill_waiting: bool,
        /// Free entries.
        pub free_entries: u32,
        /// Rays handed to the spill store and not yet refilled.
        pub spilled: u32,
        /// Entries read so far by the current op's chain walk, this cycle's read included (0 in
        /// a cycle without a walk step): a statistics event, whose maximum over a run (the
        /// longest chain walk) an observer keeps.
        pub walk_len: u32,
    }
    ports {
        /// an op is accepted this cycle (IDLE)
        sig ready (1) = this.ready as u64;
        /// the current op finishes; results are valid
        sig done (1) = this.done as u64;
        /// unexpected refill_valid or inconsistent chain
        sig error (1) = this.error as u64;
        /// rays popped (0 = none found)
        sig pop_count (w.pop_count) = this.pop_count as u64;
        /// treelet of the popped entry
        sig pop_treelet (w.treelet) = this.pop_treelet;
        /// popped ray id (0 beyond pop_count)
        each pop_ray (w.ray, w.lanes) = |i: usize| this.pop_rays.get(i).copied().unwrap_or(0) as u64;
        /// rays of the treelet in the table (Count)
        sig count_result (w.total) = this.count_result as u64;
        /// a ray spills to memory: the environment stores it
        sig spill_valid (1) = this.spill_valid as u64;
        /// treelet of the spilled ray
        sig spill_treelet (w.treelet) = this.spill_treelet;
        /// id of the spilled ray
        sig spill_ray (w.ray) = this.spill_ray as u64;
        /// request one spilled ray (answer on refill_*)
        sig refill_req (1) = this.refill_req as u64;
        /// waiting for the answer to a refill request (registers only)
        sig refill_waiting (1) = this.refill_waiting as u64;
        /// free table entries
        sig free_entries (w.entries) = this.free_entries as u64;
        /// rays spilled and not yet refilled
        sig spilled (w.spilled) = this.spilled as u64;
        /// entries read so far by this op's chain walk, this cycle's included (0 without a walk step; statistics event)
        sig walk_len (w.entries) = this.walk_len as u64;
    }
}

/// A bucket's chain head.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HeadWord {
    /// The chain is not empty.
    pub valid: bool,
    /// First entry of the chain.
    pub idx: u32,
}

/// An entry's metadata word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MetaWord {
    /// Treelet address.
    pub treelet: u64,
    /// Rays held - 1.
    pub count_m1: u32,
    /// Another entry follows in the chain.
    pub next_valid: bool,
    /// The next entry.
    pub next: u32,
}

/// FSM states of the queue table (encoding = discriminant).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum QueueState {
    /// Waiting for an op.
    #[default]
    Idle = 0,
    /// Walking a chain, one `meta` word per cycle.
    Walk = 1,
    /// PopAny: reading the chosen entry's treelet.
    AnyMeta = 2,
    /// Pop/PopAny: reading the popped entry's rays.
    PopRays = 3,
    /// Refill: waiting for the environment's answer.
    RefillWait = 4,
}

/// Which op a chain walk serves (encoding = discriminant).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WalkOp {
    /// Find an entry to append to.
    #[default]
    Insert = 0,
    /// Find and unlink the treelet's first entry.
    Pop = 1,
    /// Sum the treelet's entries.
    Count = 2,
    /// Find and unlink entry `target`.
    PopAny = 3,
}

/// The scalar registers of the queue table (all but the memories and valid bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QueueCtl {
    /// FSM state.
    pub state: QueueState,
    /// Op being walked for.
    pub walk_op: WalkOp,
    /// Treelet of the current op.
    pub key_treelet: u64,
    /// Ray of the current Insert/Refill.
    pub key_ray: u32,
    /// The bucket's head when the op started (a new entry links to it).
    pub head: HeadWord,
    /// Entry whose `meta` word arrives this cycle.
    pub cur: u32,
    /// An entry precedes `cur` in the chain.
    pub prev_valid: bool,
    /// That entry.
    pub prev: u32,
    /// Its treelet (to rewrite its word when unlinking `cur`).
    pub prev_treelet: u64,
    /// Its count - 1.
    pub prev_count_m1: u32,
    /// PopAny's entry.
    pub target: u32,
    /// Count's running sum.
    pub acc: u32,
    /// Entries read in this op's walk.
    pub walked: u32,
    /// Popped entry's count - 1.
    pub pop_count_m1: u32,
    /// Popped entry's treelet.
    pub pop_treelet: u64,
    /// Free entries.
    pub free_count: u32,
    /// Rays spilled and not refilled.
    pub spilled: u32,
}

/// Registers of the queue table.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QueueTableRegs {
    /// Bucket chain heads.
    pub heads: Memory<HeadWord>,
    /// Entry metadata.
    pub meta: Memory<MetaWord>,
    /// Entry ray ids (`warp_size` lanes per entry).
    pub rays: Memory<Box<[u32]>>,
    /// Entry valid bits (the free list is their complement).
    pub valid: Box<[bool]>,
    /// Scalar registers.
    pub ctl: QueueCtl,
}

/// The queue table's arrays, without its scalar registers: what [`QueueTable::cycle`] may
/// change in place.
struct QueueArrays<'a> {
    heads: &'a mut Memory<HeadWord>,
    meta: &'a mut Memory<MetaWord>,
    rays: &'a mut Memory<Box<[u32]>>,
    valid: &'a mut [bool],
}

impl<'a> QueueArrays<'a> {
    fn of(r: &'a mut QueueTableRegs) -> Self {
        QueueArrays {
            heads: &mut r.heads,
            meta: &mut r.meta,
            rays: &mut r.rays,
            valid: &mut r.valid,
        }
    }
}

/// The treelet queue table block (see the module documentation).
#[derive(Debug, Clone)]
pub struct QueueTable {
    cfg: HwConfig,
    buckets: u32,
    widths: QueueTableWidths,
}

impl QueueTable {
    /// A queue table for `cfg` with the largest power-of-two number of buckets not above the
    /// number of entries.
    pub fn new(cfg: &HwConfig) -> Result<Self, ConfigError> {
        let buckets = 1u32 << (31 - cfg.queue_table_entries.max(2).leading_zeros());
        Self::with_buckets(cfg, buckets)
    }

    /// A queue table for `cfg` with `buckets` hash buckets (a power of two, 2..=65536).
    pub fn with_buckets(cfg: &HwConfig, buckets: u32) -> Result<Self, ConfigError> {
        cfg.validate()?;
        if !buckets.is_power_of_two() || !(2..=65536).contains(&buckets) {
            return Err(ConfigError {
                key: "buckets",
                value: buckets as u64,
                reason: "must be a power of two in 2..=65536".into(),
            });
        }
        let e = cfg.queue_table_entries as u64;
        let widths = QueueTableWidths {
            treelet: cfg.treelet_addr_bits(),
            ray: cfg.ray_id_bits(),
            lanes: cfg.warp_size,
            count_m1: cfg.entry_count_bits(),
            pop_count: bits_for(cfg.warp_size as u64),
            total: bits_for(e * cfg.warp_size as u64),
            spilled: bits_for(cfg.max_rays as u64),
            index: cfg.queue_index_bits(),
            entries: bits_for(e),
            bucket: clog2(buckets as u64),
        };
        Ok(QueueTable {
            cfg: cfg.clone(),
            buckets,
            widths,
        })
    }

    /// Signal widths of this table.
    pub fn widths(&self) -> QueueTableWidths {
        self.widths
    }

    /// Number of hash buckets.
    pub fn buckets(&self) -> u32 {
        self.buckets
    }

    /// The bucket of a treelet ([`bucket_hash`] with this table's widths).
    pub fn bucket(&self, treelet: u64) -> usize {
        bucket_hash(treelet, self.widths.treelet, self.widths.bucket) as usize
    }

    /// An input bundle carrying `op` and no refill answer.
    pub fn input(&self, op: QueueOp) -> QueueTableIn {
        QueueTableIn {
            op,
            refill_valid: false,
            refill_treelet: 0,
            refill_ray: 0,
            widths: self.widths,
        }
    }

    /// An input bundle answering a refill request with `(treelet, ray)`, and no op.
    pub fn refill_answer(&self, treelet: u64, ray: u32) -> QueueTableIn {
        QueueTableIn {
            refill_valid: true,
            refill_treelet: treelet,
            refill_ray: ray,
            ..self.input(QueueOp::Nop)
        }
    }

    /// One cycle from the start-of-cycle scalar registers `c` and the table's arrays `mem`
    /// (memory reads see the start-of-cycle words; memory writes and valid-bit changes land at
    /// the edge): this cycle's outputs and the next scalar registers. The block's only
    /// definition of a cycle.
    fn cycle(
        &self,
        c: QueueCtl,
        mem: QueueArrays<'_>,
        inputs: &QueueTableIn,
    ) -> (QueueTableOut, QueueCtl) {
        let lanes = self.cfg.warp_size as usize;
        let mut cx = Cycle {
            heads: mem.heads.cycle(),
            meta: mem.meta.cycle(),
            rays: mem.rays.cycle(),
            first_free: mem.valid.iter().position(|&v| !v),
            first_valid: mem.valid.iter().position(|&v| v),
            nx: c,
            out: QueueTableOut {
                ready: c.state == QueueState::Idle,
                done: false,
                error: false,
                pop_count: 0,
                pop_treelet: 0,
                pop_rays: vec![0; lanes],
                count_result: 0,
                spill_valid: false,
                spill_treelet: 0,
                spill_ray: 0,
                refill_req: false,
                refill_waiting: c.state == QueueState::RefillWait,
                free_entries: c.free_count,
                spilled: c.spilled,
                walk_len: 0,
                widths: self.widths,
            },
            set_valid: None,
            clear_valid: None,
        };
        if inputs.refill_valid && c.state != QueueState::RefillWait {
            cx.out.error = true;
        }
        match c.state {
            QueueState::Idle => match inputs.op {
                QueueOp::Nop => {}
                QueueOp::Insert { treelet, ray } => self.start_insert(&mut cx, treelet, ray),
                QueueOp::Pop { treelet } => self.start_lookup(&mut cx, WalkOp::Pop, treelet),
                QueueOp::Count { treelet } => self.start_lookup(&mut cx, WalkOp::Count, treelet),
                QueueOp::PopAny => match cx.first_valid {
                    Some(f) => {
                        cx.meta.issue_read(0, f);
                        cx.nx.target = f as u32;
                        cx.nx.state = QueueState::AnyMeta;
                    }
                    None => self.finish(&mut cx),
                },
                QueueOp::Refill => {
                    if c.spilled == 0 {
                        self.finish(&mut cx);
                    } else {
                        cx.out.refill_req = true;
                        cx.nx.state = QueueState::RefillWait;
                    }
                }
            },
            QueueState::Walk => self.walk(&mut cx, &c),
            QueueState::AnyMeta => {
                let treelet = cx.meta.rdata(0).treelet;
                let hw = cx.heads.read(self.bucket(treelet));
                cx.nx.key_treelet = treelet;
                if hw.valid {
                    self.begin_walk(&mut cx, WalkOp::PopAny, hw.idx);
                } else {
                    cx.out.error = true;
                    self.finish(&mut cx);
                }
            }
            QueueState::PopRays => {
                let n = c.pop_count_m1 + 1;
                cx.out.pop_count = n;
                cx.out.pop_treelet = c.pop_treelet;
                cx.out.pop_rays[..n as usize].copy_from_slice(&cx.rays.rdata(0)[..n as usize]);
                self.finish(&mut cx);
            }
            QueueState::RefillWait => {
                if inputs.refill_valid {
                    cx.nx.spilled -= 1;
                    self.start_insert(&mut cx, inputs.refill_treelet, inputs.refill_ray);
                }
            }
        }
        let Cycle {
            heads,
            meta,
            rays,
            nx,
            out,
            set_valid,
            clear_valid,
            ..
        } = cx;
        drop((heads, meta, rays));
        if let Some(i) = set_valid {
            mem.valid[i] = true;
        }
        if let Some(i) = clear_valid {
            mem.valid[i] = false;
        }
        (out, nx)
    }

    fn entries(&self) -> usize {
        self.cfg.queue_table_entries as usize
    }
}

impl Block for QueueTable {
    type Inputs = QueueTableIn;
    type Outputs = QueueTableOut;
    type Regs = QueueTableRegs;

    fn reset(&self) -> QueueTableRegs {
        let e = self.entries();
        let sram = MemPorts {
            read: 1,
            write: 1,
            search: 0,
            read_latency: 1,
        };
        let flops = MemPorts {
            read: 1,
            write: 1,
            search: 0,
            read_latency: 0,
        };
        QueueTableRegs {
            heads: Memory::new(self.buckets as usize, HeadWord::default(), flops),
            meta: Memory::new(e, MetaWord::default(), sram),
            rays: Memory::new(e, vec![0; self.cfg.warp_size as usize].into(), sram),
            valid: vec![false; e].into(),
            ctl: QueueCtl {
                free_count: e as u32,
                ..QueueCtl::default()
            },
        }
    }

    /// A `Nop` with no refill.
    fn idle_inputs(&self) -> QueueTableIn {
        self.input(QueueOp::Nop)
    }

    /// The next-state function: the arrays copied into `next`'s storage, then
    /// [`QueueTable::cycle`] on them.
    fn next_into(
        &self,
        regs: &QueueTableRegs,
        inputs: &QueueTableIn,
        next: &mut QueueTableRegs,
    ) -> QueueTableOut {
        next.heads.copy_from(&regs.heads);
        next.meta.copy_from(&regs.meta);
        next.rays.copy_from(&regs.rays);
        next.valid.clone_from(&regs.valid);
        let (out, ctl) = self.cycle(regs.ctl, QueueArrays::of(next), inputs);
        next.ctl = ctl;
        out
    }

    /// In place: the same [`QueueTable::cycle`] on the registers' own arrays (memory writes
    /// and valid-bit changes land at the clock edge, after every read of the cycle).
    fn step(&self, r: &mut QueueTableRegs, inputs: &QueueTableIn) -> QueueTableOut {
        let (out, ctl) = self.cycle(r.ctl, QueueArrays::of(r), inputs);
        r.ctl = ctl;
        out
    }

    fn reg_signals(&self, r: &QueueTableRegs) -> Vec<Signal> {
        self.registers().signals(r)
    }

    fn describe(&self) -> BlockDesc {
        self.description()
    }

    /// A one-line summary of the registers, for a watchdog's dump.
    fn debug_state(&self, r: &QueueTableRegs) -> String {
        format!(
            "{:?} ({} free, {} spilled)",
            r.ctl.state, r.ctl.free_count, r.ctl.spilled
        )
    }
}

/// The queue table's register-only outputs: what a controller may read before it drives an op
/// in the same cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct QueueTableStatus {
    /// The table accepts an op this cycle (it is idle).
    pub ready: bool,
    /// Free table entries.
    pub free_entries: u32,
    /// Rays spilled to memory and not yet refilled.
    pub spilled: u32,
    /// The table waits for the answer to its refill request (the environment presents the spill
    /// FIFO's head on `refill_*`).
    pub refill_waiting: bool,
}

/// The answer to a `Pop`/`PopAny` (the popped entry), or the end of any other op.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct PopResult {
    /// Treelet address of the popped entry.
    pub treelet: u32,
    /// Ray ids of the entry (a list of depth warp_size; empty when the queue was empty or the op
    /// was not a pop).
    pub rays: BoundedVec<u32>,
}

crate::uncached!(QueueTable);

/// The `ready`, `free_entries`, `spilled` and `refill_waiting` ports.
impl crate::block::Moore for QueueTable {
    type Status = QueueTableStatus;
    type Select = ();

    fn status(&self, r: &QueueTableRegs, _: &(), _: ()) -> QueueTableStatus {
        QueueTableStatus {
            ready: r.ctl.state == QueueState::Idle,
            free_entries: r.ctl.free_count,
            spilled: r.ctl.spilled,
            refill_waiting: r.ctl.state == QueueState::RefillWait,
        }
    }
}

impl QueueTableOut {
    /// The register-only ports among these outputs ([`crate::block::Moore`]: what
    /// [`QueueTable`]'s `status` gives for the registers of the cycle).
    pub fn status(&self) -> QueueTableStatus {
        QueueTableStatus {
            ready: self.ready,
            free_entries: self.free_entries,
            spilled: self.spilled,
            refill_waiting: self.refill_waiting,
        }
    }

    /// The op that ends this cycle with its popped entry, if one ends.
    pub fn popped(&self) -> Option<PopResult> {
        let n = (self.pop_count as usize).min(self.pop_rays.len());
        self.done.then(|| PopResult {
            treelet: self.pop_treelet as u32,
            rays: BoundedVec::with(self.pop_rays.len(), self.pop_rays[..n].iter().copied())
                .unwrap_or_default(),
        })
    }
}

impl QueueOp {
    /// Width of the op-kind code.
    pub const BITS: u32 = 3;

    /// `(treelet, ray)` as driven on the wires (zeros where unused).
    pub fn fields(&self) -> (u64, u32) {
        match *self {
            QueueOp::Insert { treelet, ray } => (treelet, ray),
            QueueOp::Pop { treelet } | QueueOp::Count { treelet } => (treelet, 0),
            QueueOp::Nop | QueueOp::PopAny | QueueOp::Refill => (0, 0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> HwConfig {
        HwConfig {
            queue_table_entries: 4,
            max_rays: 64,
            warp_size: 4,
            repack_threshold: 2,
            divergence_threshold: 2,
            underpopulation_threshold: 8,
            ..HwConfig::default()
        }
    }

    /// Presents `op` until accepted, then runs until `done`; returns the done cycle's outputs
    /// and the cycles from acceptance to done (inclusive).
    fn run(t: &QueueTable, r: &mut QueueTableRegs, op: QueueOp) -> (QueueTableOut, u32) {
        let mut o = t.step(r, &t.input(op));
        assert!(o.ready);
        let mut cycles = 1;
        while !o.done {
            o = t.step(r, &t.input(QueueOp::Nop));
            cycles += 1;
            assert!(cycles < 100, "op never finished");
        }
        (o, cycles)
    }

    #[test]
    fn hash_folds_groups() {
        assert_eq!(
            bucket_hash(0b101_0000011_0000001, 19, 7),
            0b101 ^ 0b11 ^ 0b1
        );
        // All ones: two full groups cancel, the 5-bit top group remains.
        assert_eq!(bucket_hash(0x7ffff, 19, 7), 0x1f);
    }

    #[test]
    fn insert_pop_count_with_costs() {
        let t = QueueTable::with_buckets(&small(), 2).unwrap();
        let mut r = t.reset();
        let (_, cyc) = run(&t, &mut r, QueueOp::Insert { treelet: 2, ray: 7 });
        assert_eq!(cyc, 1, "insert into an empty bucket");
        let (_, cyc) = run(&t, &mut r, QueueOp::Insert { treelet: 2, ray: 8 });
        assert_eq!(cyc, 2, "append to the chain's first entry");
        let (o, cyc) = run(&t, &mut r, QueueOp::Count { treelet: 2 });
        assert_eq!((o.count_result, cyc), (2, 2));
        let (o, cyc) = run(&t, &mut r, QueueOp::Pop { treelet: 2 });
        assert_eq!((o.pop_count, o.pop_treelet, cyc), (2, 2, 3));
        assert_eq!(o.pop_rays, vec![7, 8, 0, 0]);
        assert_eq!(o.free_entries, 4);
        let (o, _) = run(&t, &mut r, QueueOp::Pop { treelet: 2 });
        assert_eq!(o.pop_count, 0);
    }

    #[test]
    fn full_table_spills_and_refills() {
        let t = QueueTable::with_buckets(&small(), 2).unwrap();
        let mut r = t.reset();
        for ray in 0..16 {
            let (o, _) = run(
                &t,
                &mut r,
                QueueOp::Insert {
                    treelet: ray as u64 % 4,
                    ray,
                },
            );
            assert!(!o.spill_valid);
        }
        let (o, _) = run(
            &t,
            &mut r,
            QueueOp::Insert {
                treelet: 1,
                ray: 16,
            },
        );
        assert_eq!((o.spill_valid, o.spill_treelet, o.spill_ray), (true, 1, 16));
        let (o, _) = run(&t, &mut r, QueueOp::PopAny);
        assert_eq!((o.pop_count, o.pop_treelet), (4, 0));
        assert_eq!(o.spilled, 1);
        // Refill: request, answer two cycles later, reinsert.
        let o = t.step(&mut r, &t.input(QueueOp::Refill));
        assert!(o.refill_req);
        let o = t.step(&mut r, &t.input(QueueOp::Nop));
        assert!(!o.ready && !o.done);
        let mut o = t.step(&mut r, &t.refill_answer(1, 16));
        while !o.done {
            o = t.step(&mut r, &t.input(QueueOp::Nop));
        }
        assert!(!o.spill_valid);
        assert_eq!(r.ctl.spilled, 0);
        let (o, _) = run(&t, &mut r, QueueOp::Count { treelet: 1 });
        assert_eq!(o.count_result, 5);
    }

    #[test]
    fn unexpected_refill_answer_is_an_error() {
        let t = QueueTable::new(&small()).unwrap();
        let mut r = t.reset();
        let before = r.clone();
        assert!(t.step(&mut r, &t.refill_answer(1, 2)).error);
        assert_eq!(r, before);
    }

    #[test]
    fn step_equals_eval() {
        let t = QueueTable::with_buckets(&small(), 2).unwrap();
        let mut r = t.reset();
        let ops = (0..12u32)
            .map(|i| QueueOp::Insert {
                treelet: (i % 3) as u64,
                ray: i,
            })
            .chain([
                QueueOp::Pop { treelet: 1 },
                QueueOp::PopAny,
                QueueOp::Count { treelet: 2 },
            ]);
        for op in ops {
            let mut i = t.input(op);
            loop {
                let (o, next) = t.eval(&r, &i);
                assert_eq!(t.step(&mut r, &i), o);
                assert_eq!(r, next);
                if o.done {
                    break;
                }
                i = t.input(QueueOp::Nop);
            }
        }
    }

    #[test]
    fn rejects_bad_buckets() {
        assert_eq!(
            QueueTable::with_buckets(&small(), 3).unwrap_err().key,
            "buckets"
        );
    }
}
