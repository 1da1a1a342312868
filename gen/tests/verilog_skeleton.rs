//! Skeleton Verilog from a hand-made block description: readable (snapshot), lint-clean under
//! `verilator --lint-only -Wall`, synthesizable by Yosys without latches or warnings, and
//! invalid descriptions are rejected with a reason.

mod common;

use common::{lints_clean, synthesizes_without_latches};
use std::path::PathBuf;
use vtq_gen::synth::{lint, synthesize};
use vtq_gen::tools::or_skip;
use vtq_gen::{emit_module, validate_desc, write_module, GenError};
use vtq_hdl::describe::{port, reg};
use vtq_hdl::{BlockDesc, Dir, FsmDesc, MemDesc};

/// A small treelet-count-table-like block exercising every kind of description item.
fn demo_desc() -> BlockDesc {
    BlockDesc {
        name: "demo_count_table".to_string(),
        doc: "A miniature treelet count table: counts rays per treelet and tracks the treelet \
              with the most rays (paper section 4.2)."
            .to_string(),
        params: vec![
            ("entries".to_string(), 8),
            ("treelet_addr_bits".to_string(), 19),
            ("count_bits".to_string(), 12),
        ],
        ports: vec![
            port(
                "op",
                Dir::In,
                2,
                "operation: 0 nop, 1 add rays, 2 remove rays",
            ),
            port("treelet", Dir::In, 19, "treelet address (upper 19 bits)"),
            port("n", Dir::In, 6, "number of rays added or removed"),
            port(
                "ready",
                Dir::Out,
                1,
                "the table accepts an operation this cycle",
            ),
            port("max_valid", Dir::Out, 1, "some treelet has rays"),
            port("max_treelet", Dir::Out, 19, "treelet with the most rays"),
            port("max_count", Dir::Out, 12, "its ray count minus one"),
        ],
        registers: vec![
            reg("occupancy", 4, 1, "valid entries"),
            reg("max_index", 3, 1, "entry holding the largest count"),
            reg("pending", 12, 4, "counts waiting to be written back"),
            reg(
                "max_valid",
                1,
                1,
                "registered output: some treelet has rays",
            ),
        ],
        memories: vec![MemDesc {
            name: "entries".to_string(),
            banks: 1,
            depth: 8,
            width: 32,
            read_ports: 1,
            write_ports: 1,
            read_latency: 0,
            fields: vec![
                ("valid".to_string(), 1),
                ("treelet".to_string(), 19),
                ("count".to_string(), 12),
            ],
            doc: "treelet count table entries".to_string(),
        }],
        fsms: vec![FsmDesc {
            name: "mode".to_string(),
            states: vec![
                "Idle".to_string(),
                "Scan".to_string(),
                "EvictSmallest".to_string(),
            ],
            width: 2,
        }],
        timing: vec!["one operation per cycle; the maximum is known in the same cycle".to_string()],
    }
}

fn work_dir(test: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-gen-{test}"))
}

#[test]
fn skeleton_snapshot() {
    let text = emit_module(&demo_desc()).unwrap();
    insta::assert_snapshot!("demo_count_table_skeleton", text);
}

#[test]
fn skeleton_mentions_every_item() {
    let d = demo_desc();
    let text = emit_module(&d).unwrap();
    for p in &d.ports {
        assert!(
            text.contains(&format!("{},", p.name)) || text.contains(&format!("{} ", p.name)),
            "port {} missing",
            p.name
        );
        assert!(text.contains(&p.doc), "doc of {} missing", p.name);
    }
    assert!(text.contains("localparam [1:0] MODE_EVICT_SMALLEST = 2'd2;"));
    assert!(text.contains("reg [31:0] entries [0:7];"));
    assert!(text.contains("reg [11:0] pending [0:3];"));
    assert!(text.contains("valid:1 | treelet:19 | count:12"));
    assert!(text.contains("treelet_addr_bits = 19"));
    assert!(text.contains("mode <= MODE_IDLE;"));
    assert!(text.contains("assign max_count = 12'd0;"));
    // The register named like an output port is that port.
    assert!(text.contains("output reg         max_valid,"));
    assert!(text.contains("max_valid <= 1'd0;"));
    assert!(!text.contains("assign max_valid"));
}

/// Lints and synthesizes `desc`'s skeleton; returns false when a tool is missing (skipped).
fn lint_and_synth(desc: &BlockDesc, test: &str) -> bool {
    let dir = work_dir(test);
    let files = [write_module(&dir, desc).unwrap()];
    if !lints_clean(&files, &desc.name, &dir, "verilator -Wall") {
        return false;
    }
    let Some(synth) = synthesizes_without_latches(&files, &desc.name, &dir, &desc.name) else {
        return false;
    };
    assert!(synth.undriven.is_empty(), "{synth:?}");
    true
}

#[test]
fn skeleton_is_lint_clean_and_synthesizes() {
    lint_and_synth(&demo_desc(), "skeleton-full");
}

#[test]
fn stateless_skeleton_is_lint_clean() {
    // No registers, memories or state machines: clk and rst are then unused too.
    let d = BlockDesc {
        name: "demo_comb".to_string(),
        registers: vec![],
        memories: vec![],
        fsms: vec![],
        params: vec![],
        timing: vec![],
        ..demo_desc()
    };
    lint_and_synth(&d, "skeleton-comb");
}

#[test]
fn lint_and_synth_report_problems() {
    // A latch and an undriven wire: both tools must say so.
    let dir = work_dir("bad-rtl");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.v");
    std::fs::write(
        &file,
        "module bad (input wire en, input wire [3:0] a, output reg [3:0] l, output wire u);\n\
         \x20   wire und;\n\
         \x20   always @(*) if (en) l = a;\n\
         \x20   assign u = und;\n\
         endmodule\n",
    )
    .unwrap();
    let files = [file];
    let Some(report) = or_skip(lint(&files, "bad", &dir)).unwrap() else {
        return;
    };
    let codes: Vec<&str> = report.messages.iter().map(|m| m.code.as_str()).collect();
    assert!(codes.contains(&"LATCH"), "{report}");
    assert!(codes.contains(&"UNDRIVEN"), "{report}");
    let Some(synth) = or_skip(synthesize(&files, "bad", &dir)).unwrap() else {
        return;
    };
    assert_eq!(synth.latches, 4, "{synth:?}");
    assert!(!synth.undriven.is_empty(), "{synth:?}");
    assert!(!synth.is_clean());
}

#[test]
fn syntax_errors_are_tool_failures() {
    let dir = work_dir("syntax-error");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("broken.v");
    std::fs::write(&file, "module broken (input wire a;\nendmodule\n").unwrap();
    let Some(result) = or_skip(match synthesize(&[file], "broken", &dir) {
        Err(GenError::ToolFailed { output, .. }) => Ok(output),
        Err(missing @ GenError::ToolMissing { .. }) => Err(missing),
        other => panic!("expected a yosys failure, got {other:?}"),
    })
    .unwrap() else {
        return;
    };
    assert!(result.contains("ERROR"), "{result}");
}

#[test]
fn invalid_descriptions_are_rejected() {
    let check = |d: BlockDesc, needle: &str| {
        let e = validate_desc(&d).unwrap_err().to_string();
        assert!(e.contains(needle), "`{e}` should mention `{needle}`");
        assert!(emit_module(&d).is_err());
    };
    let mut d = demo_desc();
    d.ports[1].name = "wire".to_string();
    check(d, "`wire` is not a legal");
    let mut d = demo_desc();
    d.ports[2].name = "treelet".to_string();
    check(d, "used twice");
    let mut d = demo_desc();
    d.ports[0].name = "clk".to_string();
    check(d, "clk");
    let mut d = demo_desc();
    d.registers[0].name = "treelet".to_string();
    check(d, "not a registered output");
    let mut d = demo_desc();
    d.registers[3].width = 2;
    check(d, "not a registered output");
    let mut d = demo_desc();
    d.registers[0].width = 0;
    check(d, "width 0");
    let mut d = demo_desc();
    d.memories[0].width = 31;
    check(d, "fields add up to 32");
    let mut d = demo_desc();
    d.fsms[0].states.push("A".to_string());
    d.fsms[0].states.push("B".to_string());
    check(d, "more than 2 bits");
    let mut d = demo_desc();
    d.fsms[0].states[1] = "idle".to_string();
    check(d, "MODE_IDLE");
    let mut d = demo_desc();
    d.ports.retain(|p| p.dir == Dir::In);
    check(d, "no output");
}
