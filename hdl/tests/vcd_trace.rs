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

/// A streamed trace of two blocks in nested scopes, starting at cycle 1000, parses back with one
/// value per cycle for every signal (held values included) and its timestamps from cycle 1000.
#[test]
fn streamed_scopes_round_trip_from_any_cycle() {
    use vtq_hdl::count_table::{CountOp, CountTable};
    use vtq_hdl::trace::{BlockCycle, VcdStream};
    let cfg = HwConfig::default();
    let (qt, ct) = (
        QueueTable::new(&cfg).unwrap(),
        CountTable::new(&cfg).unwrap(),
    );
    let (mut qr, mut cr) = (qt.reset(), ct.reset());
    let dir = std::env::temp_dir().join(format!("vtq-vcd-stream-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("two.vcd");
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut stream =
        VcdStream::new(file, "sm3", 1000).with_comment("two tables, cycles 1000..1006");
    let mut free = Vec::new();
    for k in 0..6u32 {
        let op = if k < 2 {
            QueueOp::Insert {
                treelet: 9,
                ray: k + 1,
            }
        } else {
            QueueOp::Nop
        };
        let (qi, ci) = (qt.input(op), ct.input(CountOp::Nop));
        let (qo, qn) = qt.eval(&qr, &qi);
        let (co, cn) = ct.eval(&cr, &ci);
        let mut scopes = Vec::new();
        BlockCycle::new(&qi, &qo, qt.reg_signals(&qr)).push_scopes("unit.qt", &mut scopes);
        BlockCycle::new(&ci, &co, ct.reg_signals(&cr)).push_scopes("unit.ct", &mut scopes);
        free.push(
            qt.reg_signals(&qr)
                .iter()
                .find(|s| s.name == "free_count")
                .unwrap()
                .value,
        );
        stream.record(&scopes).unwrap();
        (qr, cr) = (qn, cn);
    }
    assert_eq!(stream.cycles(), 6);
    stream.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("two tables, cycles 1000..1006"),
        "header comment"
    );
    assert!(text.contains("#10000\n"), "first cycle at 10 x 1000 ns");
    assert!(text.contains("#10060\n"), "end of the last cycle");
    let trace = read_vcd(BufReader::new(std::fs::File::open(&path).unwrap())).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!((trace.start, trace.cycles()), (1000, 6));
    assert!(trace.values.iter().all(|v| v.len() == trace.signals.len()));
    for (k, f) in free.iter().enumerate() {
        assert_eq!(trace.value("unit.qt.regs.free_count", 1000 + k), Some(*f));
    }
    assert!(free[5] < free[0], "the inserts took an entry: {free:?}");
    assert_eq!(trace.value("unit.qt.inputs.op_ray", 1001), Some(2));
    // Held after the last insert: the op fields stay as they were written last.
    assert_eq!(trace.value("unit.qt.inputs.op_kind", 1005), Some(0));
    assert!(trace.value("unit.ct.outputs.ready", 1003).is_some());
    assert_eq!(
        trace.value("clk", 999),
        None,
        "nothing before the first cycle"
    );
    assert_eq!(
        trace.value("clk", 1006),
        None,
        "nothing after the last cycle"
    );
}

/// A streamed cycle whose scopes differ from the first cycle's is an error naming the cycle.
#[test]
fn streamed_layout_change_is_an_error() {
    use vtq_hdl::trace::VcdStream;
    use vtq_hdl::Signal;
    let mut stream = VcdStream::new(Vec::new(), "t", 0);
    stream
        .record(&[("a".into(), vec![Signal::new("x", 4, 3)])])
        .unwrap();
    let err = stream
        .record(&[("b".into(), vec![Signal::new("x", 4, 3)])])
        .unwrap_err();
    assert!(matches!(err, TraceError::Layout { cycle: 1, .. }), "{err}");
    let err = stream
        .record(&[("a".into(), vec![Signal::new("x", 4, 16)])])
        .unwrap_err();
    assert!(matches!(err, TraceError::Width { cycle: 1, .. }), "{err}");
}
