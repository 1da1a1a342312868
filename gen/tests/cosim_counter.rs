//! End-to-end test of the co-simulation harness on a tiny block: a 4-bit counter with enable,
//! load and a combinational (Mealy) wrap output, its hand-written Verilog, and a deliberately
//! broken Verilog variant whose mismatches must be found and reported at the right cycle.

use std::path::PathBuf;
use vtq_gen::cosim::{cosim_block, record, run_cosim, write_testbench, CosimOptions, Simulator};
use vtq_gen::synth::lint;
use vtq_gen::tools::or_skip;
use vtq_gen::GenError;
use vtq_hdl::splitmix::SplitMix64;
use vtq_hdl::{Block, BlockDesc, RegDesc, Signal};

/// The counter: `count` is the register (a Moore output); `wrap` is high in a cycle where the
/// counter is enabled at 15 (a Mealy output, combinational in the inputs). `load` wins over
/// `en`. With `skip_ten` set the model is wrong on purpose: it jumps from 9 to 11, like the
/// broken Verilog below, so the test can predict the first mismatch independently.
struct Counter {
    skip_ten: bool,
}

vtq_hdl::bundle! {
    /// The counter's inputs.
    #[derive(Clone)]
    struct CounterIn (In, w: (), this) {
        en: bool,
        load: bool,
        value: u64,
    }
    /// The counter's outputs.
    #[derive(Clone)]
    struct CounterOut (Out, w: (), this) {
        count: u64,
        wrap: bool,
    }
    ports {
        /// count up
        In sig en (1) = this.en as u64;
        /// load value
        In sig load (1) = this.load as u64;
        /// value to load
        In sig value (4) = this.value;
        /// current count
        Out sig count (4) = this.count;
        /// counting up from 15 this cycle
        Out sig wrap (1) = this.wrap as u64;
    }
}

#[derive(Clone)]
struct CounterRegs {
    count: u64,
}

impl Block for Counter {
    type Inputs = CounterIn;
    type Outputs = CounterOut;
    type Regs = CounterRegs;

    fn reset(&self) -> CounterRegs {
        CounterRegs { count: 0 }
    }

    fn idle_inputs(&self) -> CounterIn {
        CounterIn {
            widths: (),
            en: false,
            load: false,
            value: 0,
        }
    }

    fn next_into(&self, regs: &CounterRegs, i: &CounterIn, n: &mut CounterRegs) -> CounterOut {
        let out = CounterOut {
            widths: (),
            count: regs.count,
            wrap: i.en && regs.count == 15,
        };
        let next = if i.load {
            i.value
        } else if i.en {
            if self.skip_ten && regs.count == 9 {
                11
            } else {
                (regs.count + 1) % 16
            }
        } else {
            regs.count
        };
        n.count = next;
        out
    }

    fn reg_signals(&self, regs: &CounterRegs) -> Vec<Signal> {
        vec![Signal::new("count", 4, regs.count)]
    }

    fn describe(&self) -> BlockDesc {
        BlockDesc {
            name: "counter4".to_string(),
            doc: "4-bit counter for testing the co-simulation harness".to_string(),
            params: vec![],
            ports: CounterIn::block_ports(&()),
            registers: vec![],
            memories: vec![],
            fsms: vec![],
            timing: vec![],
        }
    }
}

const COUNTER_V: &str = "\
module counter4 (
    input  wire       clk,
    input  wire       rst,
    input  wire       en,
    input  wire       load,
    input  wire [3:0] value,
    output wire [3:0] count,
    output wire       wrap
);
    reg [3:0] count_q;
    always @(posedge clk) begin
        if (rst) count_q <= 4'd0;
        else if (load) count_q <= value;
        else if (en) count_q <= NEXT;
    end
    assign count = count_q;
    assign wrap = en && (count_q == 4'd15);
endmodule
";

fn counter_v(broken: bool) -> String {
    let next = if broken {
        "(count_q == 4'd9) ? 4'd11 : count_q + 4'd1"
    } else {
        "count_q + 4'd1"
    };
    COUNTER_V.replace("NEXT", next)
}

/// Deterministic pseudo-random inputs (the workspace's SplitMix64): enable most of the time,
/// load rarely.
fn inputs(cycles: usize, seed: u64) -> Vec<CounterIn> {
    let mut rng = SplitMix64::new(seed);
    (0..cycles)
        .map(|_| {
            let r = rng.next_u64();
            CounterIn {
                widths: (),
                en: r & 7 != 0,
                load: (r >> 3) & 31 == 0,
                value: (r >> 8) & 15,
            }
        })
        .collect()
}

fn work_dir(test: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-gen-{test}"))
}

fn write_dut(dir: &PathBuf, broken: bool) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("counter4.v");
    std::fs::write(&path, counter_v(broken)).unwrap();
    path
}

#[test]
fn handwritten_counter_is_lint_clean() {
    let dir = work_dir("counter-lint");
    let dut = write_dut(&dir, false);
    let Some(report) = or_skip(lint(&[dut], "counter4", &dir)).unwrap() else {
        return;
    };
    assert!(report.is_clean(), "{report}");
}

#[test]
fn counter_matches_over_100k_random_cycles() {
    let dir = work_dir("counter-icarus");
    let dut = write_dut(&dir, false);
    let block = Counter { skip_ten: false };
    let trace = record(&block, inputs(100_000, 0x9e37_79b9_7f4a_7c15)).unwrap();
    assert_eq!(trace.cycles(), 100_000);
    // The random inputs do exercise the Mealy output and the load path.
    let n_in = trace.inputs.len();
    assert!(trace.rows().any(|r| r[n_in + 1] == 1));
    let Some(result) = or_skip(run_cosim(&trace, &[dut], &CosimOptions::icarus(&dir))).unwrap()
    else {
        return;
    };
    assert_eq!(result.cycles, 100_000, "{result}");
    assert!(result.passed(), "{result}");
    assert!(result.reported.is_empty());
}

#[test]
fn broken_counter_mismatch_is_found_at_the_right_cycle() {
    let dir = work_dir("counter-broken");
    let dut = write_dut(&dir, true);
    let stimulus = inputs(5_000, 42);
    let good = record(&Counter { skip_ten: false }, stimulus.clone()).unwrap();
    let bad = record(&Counter { skip_ten: true }, stimulus).unwrap();
    // The first cycle where the broken model's outputs differ is where the broken Verilog
    // must first disagree with the correct Rust block.
    let n_in = good.inputs.len();
    let (first_cycle, first_signal) = good
        .rows()
        .zip(bad.rows())
        .enumerate()
        .find_map(|(c, (g, b))| {
            (n_in..g.len())
                .find(|&i| g[i] != b[i])
                .map(|i| (c as u64, good.outputs[i - n_in].name.clone()))
        })
        .expect("the stimulus never reaches 10 by counting");
    let Some(result) = or_skip(run_cosim(&good, &[dut], &CosimOptions::icarus(&dir))).unwrap()
    else {
        return;
    };
    assert!(!result.passed(), "{result}");
    assert_eq!(result.cycles, 5_000);
    let m = &result.reported[0];
    assert_eq!(
        (m.cycle, m.signal.as_str()),
        (first_cycle, first_signal.as_str()),
        "{result}"
    );
    assert_eq!(m.expected.trim_start_matches('0'), "a", "{result}");
    assert_eq!(m.got.trim_start_matches('0'), "b", "{result}");
    assert!(result.reported.len() <= 10);
    // Every cycle where the broken model differs is counted.
    let differing = good
        .rows()
        .zip(bad.rows())
        .map(|(g, b)| (n_in..g.len()).filter(|&i| g[i] != b[i]).count() as u64)
        .sum::<u64>();
    assert_eq!(result.mismatches, differing, "{result}");
}

#[test]
fn counter_matches_under_verilator() {
    let dir = work_dir("counter-verilator");
    let dut = write_dut(&dir, false);
    let opts = CosimOptions {
        simulator: Simulator::Verilator,
        ..CosimOptions::icarus(&dir)
    };
    let block = Counter { skip_ten: false };
    let Some(result) = or_skip(cosim_block(&block, inputs(2_000, 7), &[dut], &opts)).unwrap()
    else {
        return;
    };
    assert_eq!(result.cycles, 2_000, "{result}");
    assert!(result.passed(), "{result}");
}

#[test]
fn testbench_follows_the_timing_convention() {
    let trace = record(&Counter { skip_ten: false }, inputs(3, 1)).unwrap();
    let tb = write_testbench(&trace, 10);
    // Inputs are applied (the cycle's changes read from the vectors), then outputs compared
    // after 1 ns, then the rising edge.
    assert!(tb.contains("i_value = value["), "{tb}");
    let apply = tb.find("apply(v_index, v_value);").unwrap();
    let settle = tb.find("#1;").unwrap();
    let compare = tb.find("check(cycle, \"count\"").unwrap();
    let edge = tb.find("#4 clk = 1'b1;").unwrap();
    assert!(apply < settle && settle < compare && compare < edge);
    assert!(tb.contains("cosim: %0d cycles compared, %0d mismatches"));
    // The vectors hold each cycle's changes and an end-of-cycle line per cycle.
    let vectors = vtq_gen::cosim::vectors(&trace);
    let end = format!("{:x} 0", trace.inputs.len() + trace.outputs.len());
    assert_eq!(
        vectors.lines().filter(|l| *l == end).count(),
        3,
        "{vectors}"
    );
}

#[test]
fn record_rejects_signals_that_do_not_match_the_ports() {
    struct Renamed;
    impl Block for Renamed {
        type Inputs = CounterIn;
        type Outputs = CounterOut;
        type Regs = CounterRegs;
        fn reset(&self) -> CounterRegs {
            Counter { skip_ten: false }.reset()
        }
        fn idle_inputs(&self) -> CounterIn {
            Counter { skip_ten: false }.idle_inputs()
        }
        fn next_into(&self, r: &CounterRegs, i: &CounterIn, n: &mut CounterRegs) -> CounterOut {
            Counter { skip_ten: false }.next_into(r, i, n)
        }
        fn reg_signals(&self, r: &CounterRegs) -> Vec<Signal> {
            Counter { skip_ten: false }.reg_signals(r)
        }
        fn describe(&self) -> BlockDesc {
            let mut d = Counter { skip_ten: false }.describe();
            d.ports[2].width = 5;
            d
        }
    }
    let e = record(&Renamed, inputs(3, 1)).unwrap_err();
    assert!(matches!(e, GenError::Cosim { .. }), "{e}");
    assert!(e.to_string().contains("`value`"), "{e}");
    let e = record(&Counter { skip_ten: false }, Vec::new()).unwrap_err();
    assert!(e.to_string().contains("no input cycles"), "{e}");
}

/// The counter with its register described (`count`, the RTL's `count_q`), so the testbench
/// compares it every cycle.
struct DescribedCounter(Counter);

impl Block for DescribedCounter {
    type Inputs = CounterIn;
    type Outputs = CounterOut;
    type Regs = CounterRegs;

    fn reset(&self) -> CounterRegs {
        self.0.reset()
    }

    fn idle_inputs(&self) -> CounterIn {
        self.0.idle_inputs()
    }

    fn next_into(&self, regs: &CounterRegs, i: &CounterIn, n: &mut CounterRegs) -> CounterOut {
        self.0.next_into(regs, i, n)
    }

    fn reg_signals(&self, regs: &CounterRegs) -> Vec<Signal> {
        self.0.reg_signals(regs)
    }

    fn describe(&self) -> BlockDesc {
        let mut d = self.0.describe();
        d.registers.push(RegDesc {
            name: "count".to_string(),
            width: 4,
            count: 1,
            doc: "the count".to_string(),
        });
        d
    }
}

/// RTL whose outputs come from a correct counter `good_q` while the described register
/// `count_q` runs one ahead after every counting step: only the register comparison sees it.
/// Its ports are the counter's.
fn hidden_v() -> String {
    let ports = COUNTER_V.split_inclusive(");\n").next().unwrap();
    format!(
        "{ports}\
    reg [3:0] good_q;
    reg [3:0] count_q;
    always @(posedge clk) begin
        if (rst) begin
            good_q <= 4'd0;
            count_q <= 4'd0;
        end else if (load) begin
            good_q <= value;
            count_q <= value;
        end else if (en) begin
            good_q <= good_q + 4'd1;
            count_q <= good_q + 4'd2;
        end
    end
    assign count = good_q;
    assign wrap = en && (good_q == 4'd15);
endmodule
"
    )
}

/// The registers of the block's description are compared every cycle, with the Rust block's
/// values at the cycle's start: the correct RTL matches them, and a register that differs
/// while every output matches is reported as `regs.count`.
#[test]
fn a_described_register_is_compared_every_cycle() {
    let block = DescribedCounter(Counter { skip_ten: false });
    let trace = record(&block, inputs(3_000, 5)).unwrap();
    assert_eq!(trace.registers.len(), 1);
    let dir = work_dir("counter-registers");
    let dut = write_dut(&dir, false);
    let Some(good) = or_skip(run_cosim(&trace, &[dut], &CosimOptions::icarus(&dir))).unwrap()
    else {
        return;
    };
    assert!(good.passed(), "{good}");
    let tb = std::fs::read_to_string(dir.join(vtq_gen::cosim::TESTBENCH_FILE)).unwrap();
    assert!(tb.contains("check_reg(cycle, \"regs.count\""), "{tb}");
    let hidden = dir.join("hidden.v");
    std::fs::write(&hidden, hidden_v()).unwrap();
    let bad = run_cosim(&trace, &[hidden], &CosimOptions::icarus(&dir)).unwrap();
    assert!(bad.mismatches > 100, "{bad}");
    assert!(
        bad.reported.iter().all(|m| m.signal == "regs.count"),
        "{bad}"
    );
}
