//! The energy model (docs/energy.md): properties of the model itself (linear in every event
//! count, no events costs the time terms only, components add up to the total, runs differing
//! only in time differ only in the time terms) and its derivation from real runs' statistics
//! (the `energy` object equals an evaluation of the stored JSON, CTA-state traffic appears only
//! with ray virtualization, and the coefficient set is switched by `energy.coefficients`).

mod common;

use common::{run, setup, small_config, small_vtq};
use proptest::prelude::*;
use vtq_sim::model::config::{CoefficientSet, SimConfig};
use vtq_sim::model::energy::{
    evaluate, stats_config, Coefficients, EnergyEvents, EnergyReport, MemoryEvents, Relative,
    TimeInputs,
};

/// Memory events from 11 counts, in field order.
fn memory(v: &[f64]) -> MemoryEvents {
    MemoryEvents {
        l1_read_hits: v[0],
        l1_read_misses: v[1],
        l1_write_hits: v[2],
        l1_write_misses: v[3],
        l2_read_hits: v[4],
        l2_read_misses: v[5],
        l2_write_hits: v[6],
        l2_write_misses: v[7],
        flits: v[8],
        dram_reads: v[9],
        dram_writes: v[10],
    }
}

/// Events from 29 counts: 11 memory, 11 CTA-state, then tests and table accesses.
fn events(v: &[f64]) -> EnergyEvents {
    EnergyEvents {
        memory: memory(&v[0..11]),
        cta_state: memory(&v[11..22]),
        box_tests: v[22],
        triangle_tests: v[23],
        count_table_searches: v[24],
        count_table_writes: v[25],
        count_table_reads: v[26],
        queue_table_reads: v[27],
        queue_table_writes: v[28],
    }
}

/// Random event counts.
fn counts() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(0u32..1_000_000, 29).prop_map(|v| v.into_iter().map(f64::from).collect())
}

/// Random time inputs of a GPU of 1 to 80 SMs.
fn time() -> impl Strategy<Value = TimeInputs> {
    (1e-6f64..1e-1, 1u32..=80, 0.0f64..=1.0).prop_map(|(seconds, sms, active)| TimeInputs {
        seconds,
        sms: sms as f64,
        active_sm_fraction: active,
    })
}

/// A coefficient set.
fn set() -> impl Strategy<Value = Coefficients> {
    prop::sample::select(CoefficientSet::ALL.to_vec())
        .prop_map(|s| Coefficients::of(s, &SimConfig::default()))
}

/// Whether `a` and `b` agree to a relative 1e-9 (absolute 1e-15).
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()) + 1e-15
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn energy_is_linear_in_every_count(
        a in counts(), b in counts(), k in 0usize..29, scale in 0.0f64..8.0, t in time(), c in set()
    ) {
        let e0 = evaluate(&events(&[0.0; 29]), &t, 1, &c).total_mj;
        let e = |v: &[f64]| evaluate(&events(v), &t, 1, &c).total_mj - e0;
        let sum: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
        prop_assert!(close(e(&sum), e(&a) + e(&b)), "additive");
        let mut one = a.clone();
        one[k] *= scale;
        let mut unit = vec![0.0; 29];
        unit[k] = a[k] * (scale - 1.0);
        prop_assert!(close(e(&one), e(&a) + e(&unit)), "linear in count {k}");
    }

    #[test]
    fn no_events_costs_the_time_terms_only(t in time(), c in set()) {
        let r = evaluate(&EnergyEvents::default(), &t, 1, &c);
        let named = r.components.named();
        for (name, v) in &named[1..] {
            prop_assert_eq!(*v, 0.0, "{}", name);
        }
        prop_assert!(close(r.total_mj, r.components.time));
        prop_assert!(r.total_mj > 0.0);
        prop_assert!(close(r.time_share, 1.0));
    }

    #[test]
    fn components_sum_to_the_total(v in counts(), t in time(), c in set()) {
        let r = evaluate(&events(&v), &t, 1000, &c);
        let sum: f64 = r.components.named().iter().map(|(_, x)| x).sum();
        prop_assert!(close(sum, r.total_mj));
        let split = r.time_split;
        prop_assert!(close(split.constant + split.static_power + split.idle_sms, r.components.time));
        prop_assert!(close(r.nj_per_ray, r.total_mj * 1e6 / 1000.0));
        prop_assert!(close(r.edp_j_s, r.total_mj * 1e-3 * t.seconds));
    }

    #[test]
    fn runs_differing_only_in_time_differ_only_in_time_terms(
        v in counts(), t in time(), factor in 0.1f64..10.0, c in set()
    ) {
        let longer = TimeInputs { seconds: t.seconds * factor, ..t };
        let a = evaluate(&events(&v), &t, 1, &c);
        let b = evaluate(&events(&v), &longer, 1, &c);
        for ((name, x), (_, y)) in a.components.named()[1..].iter().zip(&b.components.named()[1..]) {
            prop_assert_eq!(x, y, "{}", name);
        }
        prop_assert!(close(b.components.time, a.components.time * factor));
        // The identity holds exactly when only time differs: E = f T + (1 - f) D with D = 1.
        let rel = Relative::of(&b, &a);
        prop_assert!(close(rel.time, factor));
        if a.total_mj > a.components.time {
            prop_assert!(close(rel.events, 1.0));
            prop_assert!(close(rel.identity, rel.energy));
        }
    }
}

/// A run's `energy` object and an evaluation of its statistics JSON under the configuration it
/// recorded.
fn report_and_reevaluated(cfg: &SimConfig) -> (serde_json::Value, EnergyReport, EnergyReport) {
    let (scene, bvh) = setup("wknd", cfg);
    let out = run(&scene, &bvh, cfg);
    let json = serde_json::to_value(&out.stats).unwrap();
    let stored = stats_config(&json).expect("the statistics record their configuration");
    let again = EnergyReport::of_stats(&json, &stored).unwrap();
    (json, out.stats.energy, again)
}

#[test]
fn real_runs_report_their_energy_and_cta_state_only_with_virtualization() {
    let base = small_config("baseline", 2, 16, &[]);
    let (json, report, again) = report_and_reevaluated(&base);
    assert_eq!(
        report, again,
        "the energy object is the evaluation of the statistics"
    );
    assert_eq!(report.coefficients, "accelwattch-ptx");
    assert!(report.total_mj > 0.0 && report.seconds > 0.0);
    assert!(json["energy"]["components"]["dram"].as_f64().unwrap() > 0.0);
    let sum: f64 = report.components.named().iter().map(|(_, x)| x).sum();
    assert!(close(sum, report.total_mj));
    assert_eq!(report.components.virtualization, 0.0);
    assert_eq!(report.components.treelet_tables, 0.0);
    assert!(!json["config"].as_str().unwrap().contains("[energy]"));

    let vtq = small_vtq(2, 16, &[]);
    let (json, report, again) = report_and_reevaluated(&vtq);
    assert_eq!(report, again);
    assert!(json["cta_suspends"].as_u64().unwrap() > 0);
    assert!(report.components.virtualization > 0.0);
    assert!(report.virtualization_share > 0.0 && report.virtualization_share < 1.0);
    // The PTX fit charges nothing for the tables; the physical set does.
    assert_eq!(report.components.treelet_tables, 0.0);
    let cfg = stats_config(&json).unwrap();
    let physical = EnergyReport::of_stats_with(
        &json,
        &cfg,
        &Coefficients::of(CoefficientSet::Physical, &cfg),
    )
    .unwrap();
    assert!(physical.components.treelet_tables > 0.0);
    assert!(physical.components.rt_tests > 0.0);

    let ideal = small_vtq(2, 16, &["virtualization.state_traffic=false"]);
    let (_, report, _) = report_and_reevaluated(&ideal);
    assert_eq!(report.components.virtualization, 0.0);
}

#[test]
fn the_coefficient_set_is_chosen_by_configuration_and_recorded() {
    let cfg = small_config("baseline", 2, 16, &["energy.coefficients=physical"]);
    let (json, report, again) = report_and_reevaluated(&cfg);
    assert_eq!(report.coefficients, "physical");
    assert_eq!(report, again);
    assert!(json["config"].as_str().unwrap().contains("[energy]"));
    let err = SimConfig::load(None, &["energy.coefficients=mcpat".into()]).unwrap_err();
    assert!(err.to_string().contains("energy.coefficients"), "{err}");
    let err = SimConfig::load(None, &["energy.clock_mhz=0".into()]).unwrap_err();
    assert!(err.to_string().contains("energy.clock_mhz"), "{err}");
}

#[test]
fn vtq_energy_evaluates_stored_statistics_under_every_set_and_varies_them() {
    let dir = common::fresh_dir("energy-cli");
    for (config, out) in [("baseline", "base.json"), ("vtq", "vtq.json")] {
        let mut args = vec!["sim", "--config", config, "--out", out];
        args.extend(common::TINY_CORNELL);
        let (ok, stdout, stderr) = common::vtq_cli(&dir, &args);
        assert!(ok, "{stderr}");
        assert!(stdout.contains("energy (accelwattch-ptx):"), "{stdout}");
    }
    let (ok, stdout, stderr) =
        common::vtq_cli(&dir, &["energy", "base.json", "vtq.json", "--vary"]);
    assert!(ok, "{stderr}");
    for set in CoefficientSet::ALL {
        assert!(stdout.contains(&format!("coefficients {set}")), "{stdout}");
    }
    // The first run is the reference: the baseline's row reads 1.000; VTQ's has CTA state.
    // (Rows of the energy tables have 10 cells, those of the component stacks 8.)
    let table_row = |l: &&str, who: &str| l.starts_with(who) && l.split_whitespace().count() == 10;
    let rows: Vec<&str> = stdout.lines().filter(|l| table_row(l, "base ")).collect();
    assert_eq!(rows.len(), 3, "{stdout}");
    assert!(rows
        .iter()
        .all(|r| r.split_whitespace().nth(4) == Some("1.000")));
    let stacks = stdout
        .lines()
        .filter(|l| l.starts_with("base ") && !table_row(l, "base "));
    assert_eq!(stacks.count(), 3, "one component stack per set:\n{stdout}");
    let vtq_row = stdout.lines().find(|l| table_row(l, "vtq ")).unwrap();
    let virt: f64 = vtq_row.split_whitespace().last().unwrap().parse().unwrap();
    assert!(virt > 0.0, "{vtq_row}");
    assert!(
        stdout.contains("sensitivity") && stdout.contains("dram_read"),
        "{stdout}"
    );
    // Bad input: clear errors, no panic.
    let (ok, _, stderr) =
        common::vtq_cli(&dir, &["energy", "base.json", "--coefficients", "mcpat"]);
    assert!(
        !ok && stderr.contains("unknown energy coefficient set `mcpat`"),
        "{stderr}"
    );
    std::fs::write(dir.join("empty.json"), "{}").unwrap();
    let (ok, _, stderr) = common::vtq_cli(&dir, &["energy", "empty.json"]);
    assert!(
        !ok && stderr.contains("no statistics") && !stderr.contains("panicked"),
        "{stderr}"
    );
}
