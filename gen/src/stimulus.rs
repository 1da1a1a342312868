//! Seeded random stimulus for the treelet count table and the treelet queue table, played by
//! reactive test benches, for co-simulating the generated RTL against the Rust blocks.
//!
//! Each bench steps its own copy of the Rust block so it can react like the real environment:
//! the count-table bench holds an Add while `ready` is low; the queue-table bench presents ops
//! only while the table is idle (and junk, which must be ignored, while it is busy), inserts
//! only ray ids that are not in the table, stores spilled rays in a FIFO and answers each
//! refill request 0–3 cycles later with the oldest one, and rarely sends an unexpected refill
//! answer (a protocol error the table must ignore). The same configuration, length and seed
//! always give the same inputs.
//!
//! Besides the inputs, each generator returns a [`Coverage`]: how often the interesting
//! behaviours (evictions, scans, stalls, spills, refills, pops, errors) happened, so a test can
//! check that a stream exercises the whole table.
//!
//! The treelet controller's stimulus is in [`controller`]: a reactive environment of the real
//! Rust tables and a model of the RT unit, with its own [`controller::ControllerCoverage`].
//! The RT unit's is in [`rt_unit`]: a toy BVH in a memory model answering its requests out of
//! order, a toy intersection datapath, and a treelet controller issuing, stopping, repacking
//! and refilling its warps, with its own [`rt_unit::RtUnitCoverage`].

pub mod controller;
pub mod rt_unit;

use crate::error::GenError;
use serde::Serialize;
use std::collections::{BTreeSet, VecDeque};
use vtq_hdl::count_table::{CountOp, CountTable, CountTableIn, CountTableRegs};
use vtq_hdl::queue_table::{QueueOp, QueueState, QueueTable, QueueTableIn, QueueTableRegs};
use vtq_hdl::splitmix::SplitMix64;
use vtq_hdl::{Block, HwConfig};

/// The named coverage counters that stayed below `n`, each as "name (count < n)": the misses a
/// coverage check reports.
fn counters_below<'a>(counters: impl IntoIterator<Item = (&'a str, u64)>, n: u64) -> Vec<String> {
    counters
        .into_iter()
        .filter(|&(_, c)| c < n)
        .map(|(name, c)| format!("{name} ({c} < {n})"))
        .collect()
}

/// A coverage check's verdict: Ok when nothing is `missing`, else an error listing the misses
/// next to the whole `coverage`.
fn coverage_verdict(missing: &[String], coverage: &dyn std::fmt::Display) -> Result<(), String> {
    if missing.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "not covered: {}; coverage: {coverage}",
            missing.join(", ")
        ))
    }
}

/// What a stimulus stream exercised, counted on the Rust block's outputs. Fields that do not
/// apply to a table stay 0 (the count table has no spills, the queue table no scans).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Coverage {
    /// Cycles simulated.
    pub cycles: u64,
    /// Cycles with `ready` low (the presented op was not accepted).
    pub stalls: u64,
    /// Cycles with `error` high (an invalid op or protocol violation was ignored).
    pub errors: u64,
    /// Count table: entries evicted (`evict_valid`).
    pub evictions: u64,
    /// Count table: scans of the entry array started from idle.
    pub scans_started: u64,
    /// Count table: scans restarted from the first entry by an update during the scan.
    pub scans_restarted: u64,
    /// Count table: scans that finished and published new extreme pointers.
    pub scans_published: u64,
    /// Count table: Clear ops (each empties the table).
    pub clears: u64,
    /// Queue table: ops finished (`done`).
    pub ops_done: u64,
    /// Queue table: rays spilled to memory (`spill_valid`).
    pub spills: u64,
    /// Queue table: refill requests (`refill_req`).
    pub refills: u64,
    /// Queue table: pops that returned rays (`pop_count` > 0).
    pub pops: u64,
    /// Queue table: Count ops that found rays (`count_result` > 0).
    pub counts: u64,
    /// Queue table: the longest chain walk of the run (the largest `walk_len`).
    pub max_chain: u64,
}

impl std::fmt::Display for Coverage {
    /// The nonzero counters, e.g. `evictions 2120, stalls 310, errors 812`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let fields = [
            ("evictions", self.evictions),
            ("scans started", self.scans_started),
            ("scans restarted", self.scans_restarted),
            ("scans published", self.scans_published),
            ("clears", self.clears),
            ("ops done", self.ops_done),
            ("spills", self.spills),
            ("refill requests", self.refills),
            ("pops", self.pops),
            ("nonzero counts", self.counts),
            ("longest chain walk", self.max_chain),
            ("stall cycles", self.stalls),
            ("errors", self.errors),
        ];
        let text: Vec<String> = fields
            .iter()
            .filter(|(_, v)| *v != 0)
            .map(|(name, v)| format!("{name} {v}"))
            .collect();
        write!(f, "{}", text.join(", "))
    }
}

/// The workspace's seeded generator with the draws the stimulus needs.
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }

    /// Uniform in 0..n (n > 0).
    fn below(&mut self, n: u64) -> u64 {
        self.0.below_exact(n)
    }

    /// True with probability `percent` / 100.
    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
}

/// `n` distinct treelet addresses of `bits` bits (fewer if there are not that many): a few
/// small ones (which share hash buckets) and random ones.
fn treelet_pool(rng: &mut Rng, n: usize, bits: u32) -> Vec<u64> {
    let n = n.min(1usize << bits.min(usize::BITS - 1));
    let mut set = BTreeSet::new();
    let mut pool = Vec::new();
    for attempt in 0u64.. {
        if pool.len() == n {
            break;
        }
        let t = if attempt % 4 == 0 && attempt >> bits == 0 {
            attempt
        } else {
            rng.below(1 << bits)
        };
        if set.insert(t) {
            pool.push(t);
        }
    }
    pool
}

/// The count table for `cfg` and `cycles` cycles of its inputs from `seed`: Adds (to entries in
/// the table, to a pool of mostly absent treelets, to the smallest entry, some with an invalid
/// n), Removes (of part or all of an entry, of the largest entry, of absent treelets, some of
/// too many rays), now and then a Clear of a full table, and Nops; an Add is held while
/// `ready` is low.
pub fn count_table_inputs(
    cfg: &HwConfig,
    cycles: usize,
    seed: u64,
) -> Result<(CountTable, Vec<CountTableIn>, Coverage), GenError> {
    let t = CountTable::new(cfg)?;
    let mut cov = Coverage::default();
    let mut rng = Rng::new(seed);
    let pool = treelet_pool(
        &mut rng,
        cfg.count_table_entries as usize * 3 / 2,
        cfg.treelet_addr_bits(),
    );
    let warp = cfg.warp_size as u64;
    let mut regs: CountTableRegs = t.reset();
    let mut held: Option<CountOp> = None;
    let mut out = Vec::with_capacity(cycles);
    for _ in 0..cycles {
        let op = held.take().unwrap_or_else(|| {
            let entry = |rng: &mut Rng| {
                let words = regs.entries.words();
                let e = words[rng.below(words.len() as u64) as usize];
                e.valid.then_some((e.treelet, e.count_m1 as u64 + 1))
            };
            let from_pool = |rng: &mut Rng| pool[rng.below(pool.len() as u64) as usize];
            match rng.below(100) {
                // Adds to treelets in the table (hits) and from the pool (mostly misses).
                0..=34 => match entry(&mut rng) {
                    Some((treelet, _)) => CountOp::Add {
                        treelet,
                        n: 1 + rng.below(warp) as u32,
                    },
                    None => CountOp::Nop,
                },
                35..=44 => CountOp::Add {
                    treelet: from_pool(&mut rng),
                    n: 1 + rng.below(warp) as u32,
                },
                45..=47 => CountOp::Add {
                    treelet: from_pool(&mut rng),
                    n: if rng.chance(50) { 0 } else { warp as u32 + 1 },
                },
                48..=52 if regs.ctl.min.valid => CountOp::Add {
                    treelet: regs.ctl.min.treelet,
                    n: 1 + rng.below(warp) as u32,
                },
                53..=57 if regs.ctl.max.valid => CountOp::Remove {
                    treelet: regs.ctl.max.treelet,
                    n: 1 + rng.below(warp.min(regs.ctl.max.count_m1 as u64 + 1)) as u32,
                },
                58..=84 => match entry(&mut rng) {
                    // Mostly within the count (sometimes all of it), sometimes too many.
                    Some((treelet, c)) => CountOp::Remove {
                        treelet,
                        n: if rng.chance(90) {
                            1 + rng.below(warp.min(c)) as u32
                        } else {
                            1 + rng.below(warp) as u32
                        },
                    },
                    None => CountOp::Nop,
                },
                85..=89 => CountOp::Remove {
                    treelet: from_pool(&mut rng),
                    n: rng.below(warp + 2) as u32,
                },
                // Now and then a full table is emptied (as the controller does after a wave).
                90 if regs.ctl.occupancy == cfg.count_table_entries && rng.below(20) == 0 => {
                    CountOp::Clear
                }
                _ => CountOp::Nop,
            }
        });
        cov.clears += u64::from(op == CountOp::Clear);
        let input = t.input(op);
        let was_scanning = regs.ctl.scanning;
        let o = t.step(&mut regs, &input);
        match (was_scanning, regs.ctl.scanning) {
            (false, true) => cov.scans_started += 1,
            (true, true) if regs.ctl.scan_pos == 0 => cov.scans_restarted += 1,
            (true, false) => cov.scans_published += 1,
            _ => {}
        }
        cov.cycles += 1;
        cov.evictions += o.evict_valid as u64;
        cov.stalls += !o.ready as u64;
        cov.errors += o.error as u64;
        if !o.ready {
            held = Some(op);
        }
        out.push(input);
    }
    Ok((t, out, cov))
}

/// The queue table for `cfg` and `cycles` cycles of its inputs from `seed`: Insert (of ray ids
/// not in the table), Pop, PopAny, Count and Refill while the table is idle, junk ops while it
/// is busy; the spill store answers refill requests after 0–3 cycles, and about once in a
/// hundred cycles an unexpected refill answer arrives (an error the table must ignore).
pub fn queue_table_inputs(
    cfg: &HwConfig,
    cycles: usize,
    seed: u64,
) -> Result<(QueueTable, Vec<QueueTableIn>, Coverage), GenError> {
    let t = QueueTable::new(cfg)?;
    let mut cov = Coverage::default();
    let mut rng = Rng::new(seed);
    let pool = treelet_pool(
        &mut rng,
        cfg.queue_table_entries as usize * 2 + 4,
        cfg.treelet_addr_bits(),
    );
    let mut regs: QueueTableRegs = t.reset();
    let mut free_ids: Vec<u32> = (0..cfg.max_rays).rev().collect();
    let mut spill: VecDeque<(u64, u32)> = VecDeque::new();
    // Cycles until the spill store answers the outstanding refill request.
    let mut refill_wait: Option<u64> = None;
    let mut ready = true;
    let mut out = Vec::with_capacity(cycles);
    for cycle in 0..cycles {
        let pick = |rng: &mut Rng| pool[rng.below(pool.len() as u64) as usize];
        let random_op = |rng: &mut Rng, free_ids: &mut Vec<u32>, real: bool| match rng.below(100) {
            0..=49 if !free_ids.is_empty() => {
                let i = rng.below(free_ids.len() as u64) as usize;
                let ray = if real {
                    free_ids.swap_remove(i)
                } else {
                    free_ids[i]
                };
                QueueOp::Insert {
                    treelet: pick(rng),
                    ray,
                }
            }
            0..=69 => QueueOp::Pop { treelet: pick(rng) },
            70..=79 => QueueOp::PopAny,
            80..=89 => QueueOp::Count { treelet: pick(rng) },
            90..=96 => QueueOp::Refill,
            _ => QueueOp::Nop,
        };
        let input = match refill_wait {
            Some(0) => {
                refill_wait = None;
                let (treelet, ray) = spill.pop_front().ok_or_else(|| GenError::Cosim {
                    block: t.describe().name,
                    reason: format!(
                        "the Rust queue table requested a refill with no spilled ray \
                         outstanding (answered at cycle {cycle})"
                    ),
                })?;
                t.refill_answer(treelet, ray)
            }
            _ => {
                if let Some(c) = refill_wait.as_mut() {
                    *c -= 1;
                }
                let op = random_op(&mut rng, &mut free_ids, ready);
                let mut input = t.input(op);
                if refill_wait.is_none() && rng.chance(1) {
                    input.refill_valid = true;
                    input.refill_treelet = pick(&mut rng);
                    input.refill_ray = rng.below(cfg.max_rays as u64) as u32;
                }
                input
            }
        };
        let o = t.step(&mut regs, &input);
        if o.spill_valid {
            spill.push_back((o.spill_treelet, o.spill_ray));
        }
        if o.refill_req {
            refill_wait = Some(rng.below(4));
        }
        free_ids.extend(&o.pop_rays[..o.pop_count as usize]);
        ready = regs.ctl.state == QueueState::Idle;
        cov.cycles += 1;
        cov.stalls += !o.ready as u64;
        cov.errors += o.error as u64;
        cov.ops_done += o.done as u64;
        cov.spills += o.spill_valid as u64;
        cov.refills += o.refill_req as u64;
        cov.pops += (o.pop_count != 0) as u64;
        cov.counts += (o.count_result != 0) as u64;
        cov.max_chain = cov.max_chain.max(o.walk_len as u64);
        out.push(input);
    }
    Ok((t, out, cov))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> HwConfig {
        HwConfig {
            count_table_entries: 16,
            queue_table_entries: 8,
            max_rays: 64,
            underpopulation_threshold: 8,
            ..HwConfig::default()
        }
    }

    #[test]
    fn same_seed_same_stream_other_seed_other_stream() {
        let cfg = small();
        let (_, a, ca) = count_table_inputs(&cfg, 2000, 7).unwrap();
        let (_, b, cb) = count_table_inputs(&cfg, 2000, 7).unwrap();
        let (_, c, _) = count_table_inputs(&cfg, 2000, 8).unwrap();
        assert_eq!(a, b);
        assert_eq!(ca, cb);
        assert_ne!(a, c);
        assert_eq!(ca.cycles, 2000);
        let (_, a, _) = queue_table_inputs(&cfg, 2000, 7).unwrap();
        let (_, b, _) = queue_table_inputs(&cfg, 2000, 7).unwrap();
        let (_, c, cov) = queue_table_inputs(&cfg, 2000, 8).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(cov.spills > 0 && cov.ops_done > 0, "{cov}");
    }

    #[test]
    fn invalid_configuration_is_an_error() {
        let bad = HwConfig {
            queue_table_entries: 1,
            ..HwConfig::default()
        };
        let err = queue_table_inputs(&bad, 10, 1).unwrap_err().to_string();
        assert!(err.contains("queue_table_entries"), "{err}");
    }
}
