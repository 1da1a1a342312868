//! RT-unit errors in words ([`RtFault`]): what the RT unit's first-error capture says, with the
//! SM warp, lane and pixel of the ray concerned.

use vtq_hdl::rt_unit::{ErrorKind, ErrorRecord};

/// An error the RT unit raised, with where its ray came from, so the message can name the SM
/// warp, lane and pixel rather than a flag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtFault {
    /// The RT unit's first-error capture.
    pub record: ErrorRecord,
    /// SM warp (virtual id) and lane of the ray concerned, when known.
    pub owner: Option<(usize, u32)>,
    /// Pixel `(x, y)` of that ray's thread, when known (filled in by the engine).
    pub pixel: Option<(u32, u32)>,
    /// `hw.address_bits`, which sizes the stack spill area.
    pub address_bits: u32,
}

impl std::fmt::Display for RtFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = &self.record;
        write!(f, "{}", r.kind.describe())?;
        let ray = match (self.owner, self.pixel) {
            (Some((w, l)), Some((x, y))) => {
                format!("ray {} (SM warp {w}, lane {l}, pixel ({x}, {y}))", r.ray_id)
            }
            (Some((w, l)), None) => format!("ray {} (SM warp {w}, lane {l})", r.ray_id),
            _ => format!("ray {}", r.ray_id),
        };
        let at = format!("warp-buffer slot {}, lane {}", r.slot, r.lane);
        match r.kind {
            ErrorKind::SpillAreaFull => write!(
                f,
                ": {ray} in {at} needs {} spilled 32 B chunks of one stack, but its spill area \
                 holds {} (the area is sized from the free address space: raise \
                 hw.address_bits, now {})",
                r.value, r.limit, self.address_bits
            ),
            ErrorKind::BadChild if r.limit == 0 => write!(
                f,
                ": {ray} in {at}: a child at address {:#x} is misaligned, of a bad size or \
                 outside the address space",
                r.value
            ),
            ErrorKind::BadChild => write!(
                f,
                ": {ray} in {at}: {} children, the stack room per node (max_children = \
                 bvh.width) is {}",
                r.value, r.limit
            ),
            ErrorKind::FifoOverflow => write!(
                f,
                ": {} responses offered in one cycle, at most {} accepted (a simulator bug)",
                r.value, r.limit
            ),
            ErrorKind::UnmatchedResponse => write!(
                f,
                ": the response for address {:#x} (tag: {at}) (a simulator bug)",
                r.value
            ),
            ErrorKind::IssueWhileFull | ErrorKind::BadIssue | ErrorKind::BadCommand => write!(
                f,
                ": {ray}, {at}, value {}, limit {} (a simulator bug)",
                r.value, r.limit
            ),
        }
    }
}
