//! The placement of returning ray records ([`super::place_records`]).

use super::*;
use crate::config::HwConfig;
use crate::rt_unit::{SlotStatus, SlotSummary, Widths};

/// Wiring registers of a 4-lane, 2-slot unit with a fill of `kind` for rays 7, 8 and 9 in
/// slot 1, none of their records in yet.
fn with_fill(kind: FillKind) -> GlueRegs {
    let cfg = HwConfig {
        warp_size: 4,
        max_rays: 16,
        warp_buffer_size: 2,
        ..HwConfig::default()
    };
    let mut g = GlueRegs::reset(&cfg);
    g.builds[1] = Some(Build {
        kind,
        rays: BoundedVec::with(4, [7, 8, 9]).unwrap(),
        arrived: BoundedVec::with(4, [false; 3]).unwrap(),
        records: vec![None; 4].into(),
        loading: 3,
        last: true,
    });
    g
}

/// RT-unit status ports with slot 1 holding a warp whose `inactive` lanes hold no ray.
fn status(inactive: u64) -> RtUnitStatus {
    let slot = SlotStatus {
        order: TraversalOrder::RayStationary,
        held: true,
        summary: SlotSummary::default(),
        inactive,
    };
    RtUnitStatus {
        widths: Widths::default(),
        slots: vec![None, Some(slot)],
    }
}

fn load(ray: u32) -> RayLoad {
    RayLoad {
        slot: 1,
        ray,
        record: RayRecord::default(),
    }
}

/// The lanes of slot 1's fill that hold a record, as ray ids.
fn lanes(g: &GlueRegs) -> Vec<Option<u32>> {
    let b = g.builds[1].as_ref().expect("a fill");
    b.records
        .iter()
        .map(|r| r.as_ref().map(|r| r.ray_id))
        .collect()
}

#[test]
fn a_treelet_fills_records_go_to_their_entries_lanes_one_port_a_cycle() {
    let mut g = with_fill(FillKind::Treelet);
    place_records(&mut g, &status(0), &[load(9)], 1);
    place_records(&mut g, &status(0), &[load(7)], 1);
    assert_eq!(lanes(&g), [Some(7), None, Some(9), None]);
    assert_eq!(g.builds[1].as_ref().unwrap().loading, 1);
    assert_eq!(g.fault, None);
    // Two records on one port: a fault, and the second is not taken.
    place_records(&mut g, &status(0), &[load(8), load(8)], 1);
    assert_eq!(lanes(&g), [Some(7), Some(8), Some(9), None]);
    assert_eq!(
        g.fault,
        Some(GlueFault::Full {
            what: "ray-record ports",
            depth: 1
        })
    );
}

#[test]
fn a_repacks_records_go_to_the_held_warps_lowest_inactive_lanes_in_arrival_order() {
    let mut g = with_fill(FillKind::Repack);
    // Lanes 1 and 3 are inactive; records arrive 9, then 7 and 8 on two ports.
    place_records(&mut g, &status(0b1010), &[load(9)], 2);
    place_records(&mut g, &status(0b1010), &[load(7), load(8)], 2);
    assert_eq!(lanes(&g), [None, Some(9), None, Some(7)]);
    // The third record finds no inactive lane left: unplaced, named.
    assert_eq!(
        g.fault,
        Some(GlueFault::Unplaced {
            slot: 1,
            placed: 2,
            rays: 3
        })
    );
    assert_eq!(g.builds[1].as_ref().unwrap().loading, 0);
}

#[test]
fn a_record_no_fill_asked_for_is_a_fault() {
    let mut g = with_fill(FillKind::Grouped);
    place_records(&mut g, &status(0), &[load(5)], 1);
    assert_eq!(
        g.fault,
        Some(GlueFault::UnexpectedRecord { slot: 1, ray: 5 })
    );
    assert_eq!(lanes(&g), [None; 4]);
}
