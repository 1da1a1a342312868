//! The placement of returning ray records ([`super::place_records`]).

use super::*;
use crate::config::HwConfig;
use crate::rt_unit::{SlotStatus, SlotSummary, Widths};

/// A 4-lane, 2-slot unit with `ports` record ports.
fn config(ports: u32) -> HwConfig {
    HwConfig {
        warp_size: 4,
        max_rays: 16,
        warp_buffer_size: 2,
        record_bytes_per_cycle: 32 * ports,
        ..HwConfig::default()
    }
}

/// Wiring registers of [`config`]'s unit with a fill of `kind` for rays 7, 8 and 9 in slot 1,
/// none of their records in yet.
fn with_fill(kind: FillKind) -> GlueRegs {
    let mut g = GlueRegs::reset(&config(1));
    g.builds[1] = Some(Build {
        kind,
        rays: BoundedVec::with(4, [7, 8, 9]).unwrap(),
        arrived: BoundedVec::with(4, [false; 3]).unwrap(),
        filled: 0,
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
        issue_ready: true,
        resp_free: 0,
    }
}

fn load(ray: u32) -> RayLoad {
    load_for(1, ray)
}

fn load_for(slot: u32, ray: u32) -> RayLoad {
    RayLoad {
        slot,
        ray,
        record: RayRecord::default(),
    }
}

/// Lanes of slot 1 written so far, as ray ids: [`place_records`]'s lane writes, cycle by cycle.
#[derive(Default)]
struct Written([Option<u32>; 4]);

impl Written {
    /// One cycle: the records `arrived` on `ports` record ports, with the held warp's
    /// `inactive` lanes; the lanes written must be in slot 1 and not written before.
    fn place(&mut self, g: &mut GlueRegs, inactive: u64, arrived: &[RayLoad], ports: u32) {
        let Some(w) = place_records(&config(ports), g, &status(inactive), arrived) else {
            return;
        };
        assert_eq!(w.slot, 1);
        for (l, r) in w.lanes.iter().enumerate() {
            if let Some(r) = r {
                assert_eq!(self.0[l], None, "lane {l} written twice");
                self.0[l] = Some(r.ray_id);
            }
        }
        let filled = g.builds[1].as_ref().unwrap().filled;
        let lanes = self.0.iter().enumerate();
        let mask = lanes.fold(0, |m, (l, r)| m | (u64::from(r.is_some()) << l));
        assert_eq!(filled, mask, "the fill's lanes and the lanes written");
    }
}

#[test]
fn a_treelet_fills_records_go_to_their_entries_lanes_one_port_a_cycle() {
    let mut g = with_fill(FillKind::Treelet);
    let mut w = Written::default();
    w.place(&mut g, 0, &[load(9)], 1);
    w.place(&mut g, 0, &[load(7)], 1);
    assert_eq!(w.0, [Some(7), None, Some(9), None]);
    assert_eq!(g.builds[1].as_ref().unwrap().loading, 1);
    assert_eq!(g.fault, None);
    // Two records on one port: a fault, and the second is not taken.
    w.place(&mut g, 0, &[load(8), load(8)], 1);
    assert_eq!(w.0, [Some(7), Some(8), Some(9), None]);
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
    let mut w = Written::default();
    // Lanes 1 and 3 are inactive; records arrive 9, then 7 and 8 on two ports.
    w.place(&mut g, 0b1010, &[load(9)], 2);
    w.place(&mut g, 0b1010, &[load(7), load(8)], 2);
    assert_eq!(w.0, [None, Some(9), None, Some(7)]);
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
    let mut w = Written::default();
    w.place(&mut g, 0, &[load(5)], 1);
    assert_eq!(
        g.fault,
        Some(GlueFault::UnexpectedRecord { slot: 1, ray: 5 })
    );
    assert_eq!(w.0, [None; 4]);
}

#[test]
fn records_of_two_slots_in_one_cycle_are_a_fault_and_the_second_slots_are_not_taken() {
    // The RT unit takes one slot's lane write a cycle.
    let mut g = with_fill(FillKind::Treelet);
    let mut w = Written::default();
    w.place(&mut g, 0, &[load(7), load_for(0, 3)], 2);
    assert_eq!(w.0, [Some(7), None, None, None]);
    assert_eq!(
        g.fault,
        Some(GlueFault::MixedRecords { first: 1, other: 0 })
    );
}
