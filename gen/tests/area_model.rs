//! The area model against the paper's section 6.5 figures, CACTI 7 reference points, and
//! configuration scaling.

use vtq_gen::area::{
    area_report, format_kb, sram_area_mm2, AreaParams, AreaReport, Ports, StructureArea,
};
use vtq_hdl::HwConfig;

fn structure<'a>(r: &'a AreaReport, name: &str) -> &'a StructureArea {
    r.structures
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no structure {name}"))
}

fn default_report() -> AreaReport {
    area_report(&HwConfig::default(), &AreaParams::default()).unwrap()
}

#[test]
fn default_config_reproduces_section_6_5() {
    let r = default_report();
    // Section 6.5: 600 entries of a 19-bit treelet address and a 12-bit count.
    let ct = structure(&r, "treelet count table");
    assert_eq!(
        (ct.entries, ct.entry_bits, ct.bits),
        (600, 19 + 12, 600 * 31)
    );
    assert_eq!(ct.bytes, 600 * 31 / 8);
    assert_eq!(ct.size, "2.27 KB");
    // (19 + 32 x 12 bits) x 128 entries.
    let qt = structure(&r, "treelet queue table");
    assert_eq!((qt.entries, qt.entry_bits), (128, 19 + 32 * 12));
    assert_eq!(qt.size, "6.29 KB");
    // 4096 rays x 32 B.
    let rr = structure(&r, "ray records");
    assert_eq!(rr.bytes, 4096 * 32);
    assert_eq!(rr.size, "128 KB");
    let text = r.to_string();
    for figure in ["2.2 KB", "6.29 KB", "128 KB"] {
        assert!(text.contains(figure), "report lacks {figure}:\n{text}");
    }
}

#[test]
fn paper_figures_are_our_sizes_at_the_papers_precision() {
    // The paper truncates: 2325 B = 2.27 KB is "2.2 KB", 6448 B = 6.297 KB is "6.29 KB".
    let r = default_report();
    let mut quoted = 0;
    for s in &r.structures {
        let Some(paper) = &s.paper else { continue };
        quoted += 1;
        let number = paper.trim_end_matches(" KB");
        let decimals = number.split_once('.').map_or(0, |(_, f)| f.len() as u32);
        let scaled = s.bytes * 10u64.pow(decimals) / 1024;
        let ours = if decimals == 0 {
            scaled.to_string()
        } else {
            let p = 10u64.pow(decimals);
            format!("{}.{:0w$}", scaled / p, scaled % p, w = decimals as usize)
        };
        assert_eq!(ours, number, "{}", s.name);
    }
    assert_eq!(quoted, 3);
}

#[test]
fn bookkeeping_is_reported_separately() {
    let r = default_report();
    let qt = structure(&r, "treelet queue table");
    // valid + fill count (5 bits for 1..=32 rays) + link valid + link (7 bits for 128 entries).
    let per_entry: u32 = qt.bookkeeping.iter().map(|(_, b)| b).sum();
    assert_eq!(per_entry, 1 + 5 + 1 + 7);
    assert_eq!(qt.bookkeeping_bits, 128 * 14);
    assert_eq!(
        qt.bits,
        128 * 403,
        "bookkeeping must not change the paper's figure"
    );
    let ct = structure(&r, "treelet count table");
    assert_eq!(ct.bookkeeping_bits, 600);
}

#[test]
fn suspended_cta_state_follows_section_6_6() {
    let p = AreaParams::default();
    let r = default_report();
    let cta = structure(&r, "suspended CTA state");
    assert_eq!(r.suspended_ctas, 4096 / 64);
    assert_eq!(cta.entries, 64);
    // Per CTA: 64 threads x 10 registers x 32 bits, plus per warp (2 warps) and SIMT-stack
    // entry a 32-bit mask, a PC and a reconvergence PC.
    let warps = p.threads_per_cta.div_ceil(32) as u64;
    let expected = 64 * 10 * 32 + warps * p.simt_stack_depth as u64 * (32 + 2 * 32);
    assert_eq!(cta.entry_bits, expected);
    let deeper = area_report(
        &HwConfig::default(),
        &AreaParams {
            simt_stack_depth: p.simt_stack_depth + 1,
            ..p
        },
    )
    .unwrap();
    assert_eq!(
        structure(&deeper, "suspended CTA state").entry_bits,
        expected + warps * 96
    );
}

#[test]
fn scaling_changes_widths_and_sizes_consistently() {
    // 8192 rays and 32 KB treelets (half of a 64 KB L1); queue table sized for all rays.
    let cfg = HwConfig {
        max_rays: 8192,
        treelet_bytes: 32768,
        queue_table_entries: 256,
        ..HwConfig::default()
    };
    let r = area_report(&cfg, &AreaParams::default()).unwrap();
    assert_eq!(r.widths.ray_id, 13);
    assert_eq!(r.widths.treelet_addr, 17);
    assert_eq!(r.widths.ray_count, 13);
    assert_eq!(r.widths.queue_index, 8);
    let ct = structure(&r, "treelet count table");
    assert_eq!(ct.entry_bits, 17 + 13);
    assert_eq!(ct.paper, None, "not the paper's configuration");
    let qt = structure(&r, "treelet queue table");
    assert_eq!(qt.bits, 256 * (17 + 32 * 13));
    let rr = structure(&r, "ray records");
    assert_eq!(rr.size, "256 KB");
    assert_eq!(rr.paper, None);
    assert_eq!(r.suspended_ctas, 128);
    assert!(r.notes.is_empty(), "{:?}", r.notes);
    // Twice the rays and ray records: more area; wider ids: a larger queue table.
    let d = default_report();
    let area = |r: &AreaReport, n: &str| structure(r, n).area[0].sram_mm2;
    assert!(area(&r, "ray records") > 1.9 * area(&d, "ray records"));
    assert!(area(&r, "treelet queue table") > area(&d, "treelet queue table"));

    // The same rays with the paper's 128-entry queue table cannot queue every ray: noted.
    let small = HwConfig {
        queue_table_entries: 128,
        ..cfg
    };
    let r = area_report(&small, &AreaParams::default()).unwrap();
    assert_eq!(r.notes.len(), 1);
    assert!(r.notes[0].contains("256"), "{}", r.notes[0]);
}

#[test]
fn sram_model_is_near_cacti_7() {
    // CACTI 7 reference areas (mm^2) of 1RW arrays.
    let points = [
        (1, 45.0, 0.0040),
        (4, 45.0, 0.0150),
        (16, 45.0, 0.0549),
        (1, 22.0, 0.00097),
        (4, 22.0, 0.0040),
        (16, 22.0, 0.0136),
    ];
    for (kb, nm, cacti) in points {
        let model = sram_area_mm2(kb * 1024 * 8, nm, Ports::OneRw);
        let err = (model - cacti).abs() / cacti;
        assert!(
            err < 0.25,
            "{kb} KB at {nm} nm: model {model:.5} vs CACTI {cacti} ({:.0}%)",
            err * 100.0
        );
    }
}

#[test]
fn implementation_choices_order_as_expected() {
    let r = default_report();
    for s in &r.structures {
        let (a45, a22) = (&s.area[0], &s.area[1]);
        assert_eq!((a45.feature_nm, a22.feature_nm), (45.0, 22.0));
        assert!(
            a22.sram_mm2 < a45.sram_mm2 && a22.ff_mm2 < a45.ff_mm2,
            "{}",
            s.name
        );
        assert!(a45.ff_mm2 > 2.0 * a45.sram_mm2, "{}", s.name);
    }
    let bits = 18_600;
    let one = sram_area_mm2(bits, 45.0, Ports::OneRw);
    let two = sram_area_mm2(bits, 45.0, Ports::OneROneW);
    assert!((two / one - 2.0).abs() < 1e-9);
    assert_eq!(format_kb(0), "0 KB");
}

#[test]
fn report_serializes_to_json() {
    let r = default_report();
    let v = serde_json::to_value(&r).unwrap();
    assert_eq!(v["structures"][0]["name"], "treelet count table");
    assert_eq!(v["structures"][0]["bits"], 18_600);
    assert_eq!(v["structures"][1]["paper"], "6.29 KB");
    assert_eq!(v["config"]["max_rays"], 4096);
    assert_eq!(v["params"]["threads_per_cta"], 64);
    assert!(v["structures"][2]["area"][1]["sram_mm2"].as_f64().unwrap() > 0.0);
}

#[test]
fn default_report_snapshot() {
    insta::assert_snapshot!("area_report_default", default_report().to_string());
}
