//! A VCD trace of a short queue-table run is written, parses back, and holds the values the
//! block produced.

use std::io::BufReader;
use vtq_hdl::queue_table::{QueueOp, QueueTable};
use vtq_hdl::trace::{read_vcd, TraceError, Tracer, CYCLE_NS};
use vtq_hdl::{Block, HwConfig, Signals};

#[test]
fn queue_table_trace_round_trips() {
    let table = QueueTable::new(&HwConfig::default()).unwrap();
    let mut regs = table.reset();
    let mut tracer = Tracer::new("treelet_queue_table");
    let treelet = 0x5_a5a5;
    let mut ops = vec![
        QueueOp::Insert { treelet, ray: 7 },
        QueueOp::Insert { treelet, ray: 4095 },
        QueueOp::Nop,
        QueueOp::Nop,
        QueueOp::Count { treelet },
        QueueOp::Nop,
        QueueOp::Pop { treelet },
    ];
    ops.extend([QueueOp::Nop; 3]);
    let mut outputs = Vec::new();
    for op in ops {
        outputs.push(tracer.step(&table, &mut regs, &table.input(op)).unwrap());
    }
    assert_eq!(tracer.cycles(), 10);

    let dir = std::env::temp_dir().join(format!("vtq-vcd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("queue_table.vcd");
    tracer.write_vcd_file(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("$timescale"), "VCD header");
    let trace = read_vcd(BufReader::new(std::fs::File::open(&path).unwrap())).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();

    assert_eq!(trace.cycles(), 10);
    // Every recorded signal of every cycle reads back unchanged.
    for (cycle, o) in outputs.iter().enumerate() {
        for s in o.signals() {
            assert_eq!(
                trace.value(&format!("outputs.{}", s.name), cycle),
                Some(s.value),
                "{} @ {cycle}",
                s.name
            );
        }
    }
    let width = |name: &str| trace.signals.iter().find(|s| s.0 == name).map(|s| s.1);
    assert_eq!(width("inputs.op_treelet"), Some(19));
    assert_eq!(width("outputs.pop_ray_31"), Some(12));
    assert_eq!(trace.value("inputs.op_kind", 0), Some(1));
    assert_eq!(trace.value("inputs.op_treelet", 1), Some(treelet));
    assert_eq!(trace.value("inputs.op_ray", 1), Some(4095));
    assert_eq!(
        trace.value("clk", 3),
        Some(1),
        "clk is high in the sampled half"
    );
    // Count walks one entry: done in cycle 5 with 2 rays; Pop is done two cycles after issue.
    assert_eq!(trace.value("outputs.count_result", 5), Some(2));
    assert_eq!(trace.value("outputs.done", 8), Some(1));
    assert_eq!(trace.value("outputs.pop_count", 8), Some(2));
    assert_eq!(trace.value("outputs.pop_ray_1", 8), Some(4095));
    // The Pop's walk step (cycle 7) frees the entry at its clock edge.
    assert_eq!(trace.value("regs.free_count", 8), Some(128));
    assert_eq!(
        trace.value("regs.free_count", 7),
        Some(127),
        "registers are recorded before the edge"
    );
    assert_eq!(CYCLE_NS, 10);
}

#[test]
fn layout_change_is_an_error() {
    let table = QueueTable::new(&HwConfig::default()).unwrap();
    let small = QueueTable::new(&HwConfig {
        warp_size: 16,
        repack_threshold: 8,
        ..HwConfig::default()
    })
    .unwrap();
    let mut tracer = Tracer::new("t");
    let mut regs = table.reset();
    tracer
        .step(&table, &mut regs, &table.input(QueueOp::Nop))
        .unwrap();
    let mut regs = small.reset();
    let err = tracer
        .step(&small, &mut regs, &small.input(QueueOp::Nop))
        .unwrap_err();
    assert!(matches!(err, TraceError::Layout { cycle: 1, .. }), "{err}");
}

#[test]
fn malformed_vcd_is_an_error() {
    let err = read_vcd(
        &b"$scope module a $end $var wire 1 ! x $end $upscope $end $enddefinitions $end #0 q!"[..],
    )
    .unwrap_err();
    assert!(matches!(err, TraceError::Read(_)), "{err}");
}
