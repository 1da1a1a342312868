//! The RTL co-simulation's waveform (`CosimOptions::vcd`) beside the Rust block's
//! (`write_rust_vcd`): the same scopes and signal names, and cycle `k` at the same time in both,
//! on the treelet count table, the treelet queue table and the treelet controller at a small
//! configuration.

use std::collections::BTreeMap;
use std::path::PathBuf;
use vtq_gen::cosim::{
    record, run_cosim, write_rust_vcd, CosimOptions, RESET_CYCLES, RTL_VCD_FILE, RUST_VCD_FILE,
};
use vtq_gen::rtl::rtl_modules;
use vtq_gen::stimulus::controller::controller_inputs;
use vtq_gen::stimulus::{count_table_inputs, queue_table_inputs};
use vtq_gen::tools::or_skip;
use vtq_hdl::controller::ControllerFeatures;
use vtq_hdl::HwConfig;

/// Cycles co-simulated per table.
const CYCLES: usize = 400;

fn small() -> HwConfig {
    HwConfig {
        count_table_entries: 5,
        queue_table_entries: 4,
        max_rays: 32,
        warp_size: 4,
        underpopulation_threshold: 3,
        repack_threshold: 2,
        divergence_threshold: 2,
        ..HwConfig::default()
    }
}

/// A VCD read into `name -> width` (names `scope.signal` below the top module, scopes of the
/// same top merged as Icarus writes them) and, per name, its value changes `(time, value)`
/// with values as binary strings without leading zeros (`x`/`z` kept).
struct Vcd {
    widths: BTreeMap<String, u32>,
    changes: BTreeMap<String, Vec<(u64, String)>>,
}

/// Appends a value change of `code` at `time` to every name the code stands for.
fn push_change(
    by_code: &BTreeMap<String, Vec<String>>,
    code: &str,
    value: &str,
    time: u64,
    changes: &mut BTreeMap<String, Vec<(u64, String)>>,
) {
    let v = value.trim_start_matches('0');
    let v = if v.is_empty() { "0" } else { v };
    for name in by_code.get(code).into_iter().flatten() {
        changes
            .entry(name.clone())
            .or_default()
            .push((time, v.to_string()));
    }
}

impl Vcd {
    fn read(path: &PathBuf) -> Vcd {
        let text =
            std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut widths = BTreeMap::new();
        let mut by_code: BTreeMap<String, Vec<String>> = BTreeMap::new();
        let mut scope: Vec<String> = Vec::new();
        let mut words = text.split_whitespace();
        let mut changes: BTreeMap<String, Vec<(u64, String)>> = BTreeMap::new();
        let mut time = 0u64;
        let mut defs: Vec<(String, String, u32)> = Vec::new();
        while let Some(w) = words.next() {
            match w {
                "$scope" => {
                    words.next();
                    scope.push(words.next().unwrap().to_string());
                }
                "$upscope" => {
                    scope.pop();
                }
                "$var" => {
                    words.next();
                    let width: u32 = words.next().unwrap().parse().unwrap();
                    let code = words.next().unwrap().to_string();
                    let name = words.next().unwrap();
                    let mut full = scope[1..].to_vec();
                    full.push(name.to_string());
                    defs.push((code, full.join("."), width));
                }
                "$enddefinitions" => {
                    for (code, name, width) in defs.drain(..) {
                        widths.insert(name.clone(), width);
                        by_code.entry(code).or_default().push(name);
                    }
                }
                _ if w.starts_with('#') => time = w[1..].parse().unwrap(),
                _ if w.starts_with('b') => {
                    let code = words.next().unwrap();
                    push_change(&by_code, code, &w[1..], time, &mut changes);
                }
                _ if w.len() >= 2 && "01xzXZ".contains(&w[..1]) && !w.starts_with('$') => {
                    push_change(&by_code, &w[1..], &w[..1], time, &mut changes);
                }
                _ => {}
            }
        }
        Vcd { widths, changes }
    }

    /// The value of `name` at `time`, after that time's changes.
    fn at(&self, name: &str, time: u64) -> Option<&str> {
        self.changes
            .get(name)?
            .iter()
            .take_while(|(t, _)| *t <= time)
            .last()
            .map(|(_, v)| v.as_str())
    }

    /// The names in the scopes `inputs`, `outputs` and `regs` with their widths.
    fn scoped(&self) -> BTreeMap<String, u32> {
        self.widths
            .iter()
            .filter(|(n, _)| {
                ["inputs.", "outputs.", "regs."]
                    .iter()
                    .any(|p| n.starts_with(p))
            })
            .map(|(n, w)| (n.clone(), *w))
            .collect()
    }
}

#[test]
fn rtl_waveform_carries_the_rust_trace_names_and_values() {
    let cfg = small();
    let modules: BTreeMap<String, String> = rtl_modules(&cfg, ControllerFeatures::FULL)
        .unwrap()
        .into_iter()
        .collect();
    for module in [
        "treelet_count_table",
        "treelet_queue_table",
        "treelet_controller",
    ] {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-vcd-{module}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let source = dir.join(format!("{module}.v"));
        std::fs::write(&source, &modules[module]).unwrap();
        let rust_vcd = dir.join(RUST_VCD_FILE);
        let (trace, written) = if module.contains("count") {
            let (b, inputs, _) = count_table_inputs(&cfg, CYCLES, 3).unwrap();
            let written = write_rust_vcd(&b, inputs.iter().copied(), &rust_vcd).unwrap();
            (record(&b, inputs).unwrap(), written)
        } else if module.contains("queue") {
            let (b, inputs, _) = queue_table_inputs(&cfg, CYCLES, 4).unwrap();
            let written = write_rust_vcd(&b, inputs.iter().copied(), &rust_vcd).unwrap();
            (record(&b, inputs).unwrap(), written)
        } else {
            let (b, inputs, _) =
                controller_inputs(&cfg, ControllerFeatures::FULL, CYCLES, 5).unwrap();
            let written = write_rust_vcd(&b, inputs.iter().cloned(), &rust_vcd).unwrap();
            (record(&b, inputs).unwrap(), written)
        };
        assert!(!trace.registers.is_empty(), "{module}");
        assert_eq!(written, CYCLES as u64);
        let opts = CosimOptions {
            vcd: true,
            ..CosimOptions::icarus(&dir)
        };
        let Some(result) = or_skip(run_cosim(&trace, &[source], &opts)).unwrap() else {
            return;
        };
        assert!(result.passed(), "{module}: {result}");
        let rtl_path = dir.join(RTL_VCD_FILE);
        assert!(rtl_path.is_file(), "{module}: no {}", rtl_path.display());
        let rtl = Vcd::read(&rtl_path);
        let rust = Vcd::read(&rust_vcd);

        // Every port signal of the Rust trace is in the RTL waveform under the same name and
        // width; the registers the RTL names the same are there too, and nothing else is in
        // those scopes.
        let (rtl_names, rust_names) = (rtl.scoped(), rust.scoped());
        for s in trace.inputs.iter().map(|s| ("inputs", s)) {
            let name = format!("{}.{}", s.0, s.1.name);
            assert_eq!(rtl_names.get(&name), Some(&s.1.width), "{module}: {name}");
        }
        for s in &trace.outputs {
            let name = format!("outputs.{}", s.name);
            assert_eq!(rtl_names.get(&name), Some(&s.width), "{module}: {name}");
        }
        // Every register the Rust trace shows is in the RTL waveform (a bank's members as
        // slices of the packed `<bank>_q`).
        let regs: Vec<&String> = rtl_names
            .keys()
            .filter(|n| n.starts_with("regs."))
            .collect();
        let rust_regs: Vec<&String> = rust_names
            .keys()
            .filter(|n| n.starts_with("regs."))
            .collect();
        assert_eq!(regs, rust_regs, "{module}");
        assert!(
            regs.len() >= 3,
            "{module}: registers in the RTL waveform: {regs:?}"
        );
        for (name, width) in &rtl_names {
            assert_eq!(rust_names.get(name), Some(width), "{module}: {name}");
        }
        assert!(
            rtl.widths.contains_key("dut.clk"),
            "{module}: the DUT scope"
        );

        // Cycle k starts at the same time in both: its inputs and the registers at its start
        // agree in every cycle (outputs settle 1 ns into the RTL's cycle; the testbench compared
        // them).
        // A register the RTL does not reset (a chain link of an empty entry) may be `x` where
        // the Rust block holds 0: no output depends on it; every determinate value must agree.
        let (mut compared, mut unknown) = (0u64, 0u64);
        for k in 0..CYCLES as u64 {
            let t = 10 * (k + RESET_CYCLES);
            for name in rtl_names.keys().filter(|n| !n.starts_with("outputs.")) {
                let (got, want) = (rtl.at(name, t), rust.at(name, t));
                assert!(
                    want.is_some(),
                    "{module}: {name} has no value in the Rust waveform"
                );
                if got.is_some_and(|v| v.contains(['x', 'z'])) {
                    assert!(
                        name.starts_with("regs."),
                        "{module}: {name} is x in cycle {k}"
                    );
                    unknown += 1;
                    continue;
                }
                compared += 1;
                assert_eq!(got, want, "{module}: {name} in cycle {k}");
            }
        }
        assert!(
            unknown * 20 < compared,
            "{module}: {unknown} x values, {compared} compared"
        );
    }
}
