//! The generated RTL of the treelet count table and the treelet queue table against the Rust
//! blocks: cycle-by-cycle co-simulation of long random operation streams (Icarus Verilog, and
//! Verilator on a shorter stream), `verilator --lint-only -Wall` and Yosys synthesis without
//! latches or undriven wires, at the paper's configuration and a small one, plus snapshots of
//! the small configuration's Verilog.
//!
//! The stimulus is played by a test bench that steps its own copy of the Rust block, so it can
//! react like the real environment: it holds a count-table Add while `ready` is low, presents
//! queue-table ops only when `ready` is high (and junk, which must be ignored, while busy),
//! stores spilled rays in a FIFO and answers each refill request after a random latency with
//! the oldest one, as `hdl/tests/queue_table_props.rs` does.

use std::collections::{BTreeSet, VecDeque};
use std::path::{Path, PathBuf};
use std::time::Instant;
use vtq_gen::cosim::{record, run_cosim, CosimOptions, Simulator, Trace};
use vtq_gen::rtl::{count_table_verilog, queue_table_verilog, table_modules};
use vtq_gen::synth::{lint, synthesize};
use vtq_gen::tools::or_skip;
use vtq_hdl::count_table::{CountOp, CountTable, CountTableIn, CountTableRegs};
use vtq_hdl::queue_table::{QueueOp, QueueTable, QueueTableIn, QueueTableRegs};
use vtq_hdl::{Block, HwConfig};

/// Cycles of every Icarus co-simulation.
const ICARUS_CYCLES: usize = 100_000;
/// Cycles of the Verilator co-simulations.
const VERILATOR_CYCLES: usize = 20_000;

/// A small deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }

    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in 0..n (n > 0).
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    /// True with probability `percent` / 100.
    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
}

/// The small configuration: 20 count-table entries (3 scan windows, the last one partial),
/// 8 queue-table entries in 8 buckets, 4-ray warps, 64 rays.
fn small() -> HwConfig {
    HwConfig {
        count_table_entries: 20,
        queue_table_entries: 8,
        max_rays: 64,
        warp_size: 4,
        underpopulation_threshold: 5,
        repack_threshold: 2,
        divergence_threshold: 2,
        ..HwConfig::default()
    }
}

fn configs() -> [(&'static str, HwConfig); 2] {
    [("default", HwConfig::default()), ("small", small())]
}

/// `n` distinct treelet addresses of `bits` bits: a few small ones (which share hash buckets)
/// and random ones.
fn treelet_pool(rng: &mut Rng, n: usize, bits: u32) -> Vec<u64> {
    let mut set = BTreeSet::new();
    let mut pool = Vec::new();
    for attempt in 0u64.. {
        if pool.len() == n {
            break;
        }
        let t = if attempt % 4 == 0 {
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

/// How often the count table's scan engine started, restarted and published during a run.
#[derive(Debug, Default)]
struct ScanStats {
    started: u32,
    restarted: u32,
    published: u32,
}

/// Count-table stimulus: Adds (some with an invalid n, some to the smallest entry), Removes
/// (of part or all of an entry, of the largest entry, of unknown treelets, invalid n) and Nops;
/// an Add is held while `ready` is low.
fn count_inputs(
    t: &CountTable,
    cfg: &HwConfig,
    cycles: usize,
    seed: u64,
) -> (Vec<CountTableIn>, ScanStats) {
    let mut stats = ScanStats::default();
    let mut rng = Rng::new(seed);
    let pool = treelet_pool(&mut rng, cfg.count_table_entries as usize * 3 / 2, 19);
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
                    treelet: pool[rng.below(pool.len() as u64) as usize],
                    n: 1 + rng.below(warp) as u32,
                },
                45..=47 => CountOp::Add {
                    treelet: pool[rng.below(pool.len() as u64) as usize],
                    n: if rng.chance(50) { 0 } else { warp as u32 + 1 },
                },
                48..=52 if regs.min.valid => CountOp::Add {
                    treelet: regs.min.treelet,
                    n: 1 + rng.below(warp) as u32,
                },
                53..=57 if regs.max.valid => CountOp::Remove {
                    treelet: regs.max.treelet,
                    n: 1 + rng.below(warp.min(regs.max.count_m1 as u64 + 1)) as u32,
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
                    treelet: pool[rng.below(pool.len() as u64) as usize],
                    n: rng.below(warp + 2) as u32,
                },
                _ => CountOp::Nop,
            }
        });
        let input = t.input(op);
        let was_scanning = regs.scanning;
        let o = t.step(&mut regs, &input);
        match (was_scanning, regs.scanning) {
            (false, true) => stats.started += 1,
            (true, true) if regs.scan_pos == 0 => stats.restarted += 1,
            (true, false) => stats.published += 1,
            _ => {}
        }
        if !o.ready {
            held = Some(op);
        }
        out.push(input);
    }
    (out, stats)
}

/// Queue-table stimulus: Insert (fresh ray ids only), Pop, PopAny, Count and Refill when
/// `ready`; junk ops while busy; the spill store answers refill requests after 0..4 cycles;
/// rarely an unexpected refill answer (an error the table must ignore).
fn queue_inputs(t: &QueueTable, cfg: &HwConfig, cycles: usize, seed: u64) -> Vec<QueueTableIn> {
    let mut rng = Rng::new(seed);
    let bits = cfg.treelet_addr_bits();
    let pool = treelet_pool(&mut rng, cfg.queue_table_entries as usize * 2 + 4, bits);
    let mut regs: QueueTableRegs = t.reset();
    let mut free_ids: Vec<u32> = (0..cfg.max_rays).rev().collect();
    let mut spill: VecDeque<(u64, u32)> = VecDeque::new();
    // Cycles until the spill store answers the outstanding refill request.
    let mut refill_wait: Option<u64> = None;
    let mut ready = true;
    let mut out = Vec::with_capacity(cycles);
    for _ in 0..cycles {
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
                let (treelet, ray) = spill.pop_front().expect("a refill request with spills");
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
        ready = regs.ctl.state == vtq_hdl::queue_table::QueueState::Idle;
        out.push(input);
    }
    out
}

fn work_dir(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-gen-table-rtl-{name}"))
}

/// Writes `text` as `<dir>/<module>.v`.
fn write_verilog(dir: &Path, module: &str, text: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{module}.v"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Co-simulates `trace` against `source` and asserts zero mismatches; false when the
/// simulator is not installed (outside CI).
fn cosim(trace: &Trace, source: &Path, sim: Simulator, tag: &str) -> bool {
    let opts = CosimOptions {
        simulator: sim,
        ..CosimOptions::icarus(work_dir(&format!("{tag}-{sim:?}")))
    };
    let start = Instant::now();
    let Some(result) = or_skip(run_cosim(trace, &[source.to_path_buf()], &opts)).unwrap() else {
        return false;
    };
    eprintln!("{tag}: {result}  ({:.1} s)", start.elapsed().as_secs_f64());
    assert!(result.passed(), "{tag}:\n{result}");
    assert_eq!(result.cycles, trace.cycles() as u64, "{tag}");
    true
}

#[test]
fn count_table_matches_rust_cycle_by_cycle() {
    for (tag, cfg) in configs() {
        let t = CountTable::new(&cfg).unwrap();
        let (inputs, scans) = count_inputs(&t, &cfg, ICARUS_CYCLES, 1);
        eprintln!("count table ({tag}): {scans:?}");
        assert!(
            scans.started > 100 && scans.restarted > 10 && scans.published > 100,
            "{tag}: {scans:?}"
        );
        let trace = record(&t, inputs).unwrap();
        // The stream exercises every behaviour of the table.
        let (mut evicts, mut stalls, mut errors) = (0, 0, 0);
        let names: Vec<&str> = trace.outputs.iter().map(|s| s.name.as_str()).collect();
        let col = |n: &str| names.iter().position(|x| *x == n).unwrap();
        let (c_ev, c_rdy, c_err) = (col("evict_valid"), col("ready"), col("error"));
        for c in 0..trace.cycles() {
            let o = trace.output_values(c);
            evicts += o[c_ev];
            stalls += 1 - o[c_rdy];
            errors += o[c_err];
        }
        eprintln!(
            "count table ({tag}): {evicts} evictions, {stalls} stall cycles, {errors} errors"
        );
        assert!(evicts > 100 && stalls > 100 && errors > 100, "{tag}");
        let text = count_table_verilog(&cfg).unwrap();
        let file = write_verilog(
            &work_dir(&format!("count-{tag}")),
            &t.describe().name,
            &text,
        );
        if !cosim(&trace, &file, Simulator::Icarus, &format!("count-{tag}")) {
            return;
        }
    }
}

#[test]
fn generated_tables_lint_clean() {
    for (tag, cfg) in configs() {
        for (module, text) in table_modules(&cfg).unwrap() {
            assert!(
                !text.contains("${"),
                "{module} ({tag}): unfilled template variable"
            );
            let dir = work_dir(&format!("lint-{tag}"));
            let file = write_verilog(&dir, &module, &text);
            let Some(report) = or_skip(lint(&[file], &module, &dir)).unwrap() else {
                return;
            };
            assert!(report.is_clean(), "{module} ({tag}):\n{report}");
        }
    }
}

#[test]
fn queue_table_matches_rust_cycle_by_cycle() {
    for (tag, cfg) in configs() {
        let t = QueueTable::new(&cfg).unwrap();
        let trace = record(&t, queue_inputs(&t, &cfg, ICARUS_CYCLES, 2)).unwrap();
        let names: Vec<&str> = trace.outputs.iter().map(|s| s.name.as_str()).collect();
        let col = |n: &str| names.iter().position(|x| *x == n).unwrap();
        let [spills, refills, pops, counts, errors, done] = [
            "spill_valid",
            "refill_req",
            "pop_count",
            "count_result",
            "error",
            "done",
        ]
        .map(|n| {
            let c = col(n);
            (0..trace.cycles())
                .filter(|&k| trace.output_values(k)[c] != 0)
                .count()
        });
        let chain = trace.output_values(trace.cycles() - 1)[col("max_chain")];
        eprintln!(
            "queue table ({tag}): {done} ops done, {spills} spills, {refills} refill requests, \
             {pops} pops, {counts} nonzero counts, {errors} errors, longest walk {chain}"
        );
        assert!(
            spills > 100 && refills > 100 && pops > 1000 && counts > 500 && errors > 100,
            "{tag}"
        );
        assert!(chain >= 3, "{tag}: chains too short to test the walk");
        let text = queue_table_verilog(&cfg).unwrap();
        let file = write_verilog(
            &work_dir(&format!("queue-{tag}")),
            &t.describe().name,
            &text,
        );
        if !cosim(&trace, &file, Simulator::Icarus, &format!("queue-{tag}")) {
            return;
        }
    }
}

/// The same kind of streams, shorter, under Verilator (two-state, its own scheduling).
#[test]
fn tables_match_rust_under_verilator() {
    for (tag, cfg) in configs() {
        let ct = CountTable::new(&cfg).unwrap();
        let (inputs, _) = count_inputs(&ct, &cfg, VERILATOR_CYCLES, 3);
        let trace = record(&ct, inputs).unwrap();
        let dir = work_dir(&format!("verilator-{tag}"));
        let file = write_verilog(
            &dir,
            &ct.describe().name,
            &count_table_verilog(&cfg).unwrap(),
        );
        if !cosim(&trace, &file, Simulator::Verilator, &format!("count-{tag}")) {
            return;
        }
        let qt = QueueTable::new(&cfg).unwrap();
        let trace = record(&qt, queue_inputs(&qt, &cfg, VERILATOR_CYCLES, 4)).unwrap();
        let file = write_verilog(
            &dir,
            &qt.describe().name,
            &queue_table_verilog(&cfg).unwrap(),
        );
        cosim(&trace, &file, Simulator::Verilator, &format!("queue-{tag}"));
    }
}

/// Yosys' generic synthesis of the small configuration: no latches, no undriven wires, no
/// warnings, and the flip-flops the storage needs (the default configuration takes minutes
/// and is measured separately; see docs/hardware.md).
#[test]
fn small_tables_synthesize_without_latches() {
    let cfg = small();
    for (module, text) in table_modules(&cfg).unwrap() {
        let dir = work_dir(&format!("synth-{module}"));
        let file = write_verilog(&dir, &module, &text);
        let Some(r) = or_skip(synthesize(&[file], &module, &dir)).unwrap() else {
            return;
        };
        eprintln!(
            "{module} (small): {} cells, {} flip-flops",
            r.cells, r.flip_flops
        );
        assert_eq!(r.latches, 0, "{module}: {r:?}");
        assert!(r.undriven.is_empty(), "{module}: {:?}", r.undriven);
        assert!(r.warnings.is_empty(), "{module}: {:?}", r.warnings);
        // Every memory bit is a flip-flop (generic synthesis maps the SRAMs to flip-flops too);
        // Yosys may drop register bits that are constant (the scan position's low bits).
        let desc = if module.contains("count") {
            CountTable::new(&cfg).unwrap().describe()
        } else {
            QueueTable::new(&cfg).unwrap().describe()
        };
        let mem_bits: u64 = desc
            .memories
            .iter()
            .map(|m| (m.width * m.depth) as u64)
            .sum();
        assert!(
            r.flip_flops >= mem_bits,
            "{module}: {} < {mem_bits}",
            r.flip_flops
        );
    }
}

#[test]
fn small_table_snapshots() {
    let cfg = small();
    insta::assert_snapshot!("count_table_small", count_table_verilog(&cfg).unwrap());
    insta::assert_snapshot!("queue_table_small", queue_table_verilog(&cfg).unwrap());
}

#[test]
fn generated_modules_follow_the_configuration() {
    let modules = table_modules(&HwConfig::default()).unwrap();
    let names: Vec<&str> = modules.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["treelet_count_table", "treelet_queue_table"]);
    let (count, queue) = (&modules[0].1, &modules[1].1);
    // The paper's sizes: 600 x {valid, 19-bit treelet, 12-bit count - 1}; 128 x 32 ray ids.
    assert!(count.contains("reg [599:0] entries_valid;"));
    assert!(count.contains("reg [30:0] entries [0:599];"));
    assert!(queue.contains("reg [383:0] rays [0:127];"));
    assert!(queue.contains("t[6:0] ^ t[13:7] ^ {2'd0, t[18:14]}"));
    for text in [count, queue] {
        assert!(!text.contains("initial"), "no initial blocks in RTL");
        assert!(text.contains("always @(posedge clk)"));
    }
    // An invalid configuration is an error naming the offending key, not a panic.
    let bad = HwConfig {
        count_table_entries: 1,
        ..HwConfig::default()
    };
    let err = count_table_verilog(&bad).unwrap_err().to_string();
    assert!(err.contains("count_table_entries"), "{err}");
    let bad = HwConfig {
        warp_size: 3,
        ..HwConfig::default()
    };
    let err = queue_table_verilog(&bad).unwrap_err().to_string();
    assert!(err.contains("warp_size"), "{err}");
}
