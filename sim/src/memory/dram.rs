//! [`DramChannel`]: DRAM as one channel with a fixed latency and a byte-exact bandwidth limit.
//!
//! The channel moves `bytes_per_cycle` bytes per core cycle. Its time is counted in byte slots
//! (`cycle * bytes_per_cycle + offset`), so bandwidths that are not a multiple of the transfer
//! size are exact rather than rounded up to whole cycles. A transfer of `b` bytes arriving at
//! cycle `a` occupies slots `[s, s + b)` with `s = max(a * bytes_per_cycle, next_free)`, and
//! `next_free` becomes `s + b` (a "next free" register: transfers are served in arrival order,
//! which the memory system guarantees is also call order). The transfer starts in cycle
//! `start = floor(s / bytes_per_cycle)` and its data is back at `start + latency`.
//!
//! When `bytes_per_cycle` divides `b` this is exactly a channel busy `b / bytes_per_cycle`
//! cycles per transfer with `start = max(arrival, next_free_cycle)`.

/// Start and completion cycles of one transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DramGrant {
    /// Cycle the transfer starts (arrival plus queueing).
    pub start: u64,
    /// Cycle its data is back (`start + latency`).
    pub done: u64,
}

/// One DRAM channel: fixed latency, bandwidth-limited, first come first served.
#[derive(Debug, Clone)]
pub struct DramChannel {
    latency: u64,
    /// Slots per cycle.
    bytes_per_cycle: u64,
    /// Slots per byte (a slot is `1 / slot_divisor` of a byte, so a share of the bandwidth
    /// stays exact).
    slot_divisor: u64,
    /// First free slot.
    next_free: u128,
}

impl DramChannel {
    /// An idle channel. `bytes_per_cycle` must be positive (checked by
    /// [`MemConfig::validate`](super::MemConfig::validate)).
    pub fn new(latency: u32, bytes_per_cycle: u32) -> Self {
        DramChannel::with_share(latency, bytes_per_cycle, [1, 1])
    }

    /// An idle channel of `bytes_per_cycle * share[0] / share[1]` bytes per cycle (`share`
    /// validated: `0 < share[0] <= share[1]`): time is counted in slots of `1 / share[1]` byte,
    /// `bytes_per_cycle * share[0]` of them per cycle.
    pub fn with_share(latency: u32, bytes_per_cycle: u32, share: [u32; 2]) -> Self {
        DramChannel {
            latency: u64::from(latency),
            bytes_per_cycle: u64::from(bytes_per_cycle.max(1)) * u64::from(share[0].max(1)),
            slot_divisor: u64::from(share[1].max(1)),
            next_free: 0,
        }
    }

    /// Queues a transfer of `bytes` arriving at cycle `arrival`; arrivals must not decrease
    /// from call to call.
    pub fn schedule(&mut self, arrival: u64, bytes: u32) -> DramGrant {
        let bpc = u128::from(self.bytes_per_cycle);
        let slot = (u128::from(arrival) * bpc).max(self.next_free);
        self.next_free = slot + u128::from(bytes) * u128::from(self.slot_divisor);
        // slot / bpc <= max(arrival, previous end / bpc): fits in u64 for any reachable cycle.
        let start = u64::try_from(slot / bpc).unwrap_or(u64::MAX);
        DramGrant {
            start,
            done: start.saturating_add(self.latency),
        }
    }

    /// First cycle in which a new transfer could start without queueing.
    pub fn next_free_cycle(&self) -> u64 {
        let bpc = u128::from(self.bytes_per_cycle);
        u64::try_from(self.next_free.div_ceil(bpc)).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_channel_adds_only_latency() {
        let mut d = DramChannel::new(254, 328);
        assert_eq!(
            d.schedule(1000, 32),
            DramGrant {
                start: 1000,
                done: 1254
            }
        );
        // 32 of 328 bytes of cycle 1000 are used; the next sector still starts in 1000.
        assert_eq!(d.schedule(1000, 32).start, 1000);
        assert_eq!(d.schedule(5000, 32).start, 5000);
    }

    #[test]
    fn whole_cycle_transfers_queue_back_to_back() {
        // 8 B/cycle: a 32 B sector keeps the channel busy 4 cycles.
        let mut d = DramChannel::new(10, 8);
        let starts: Vec<u64> = (0..5).map(|_| d.schedule(100, 32).start).collect();
        assert_eq!(starts, vec![100, 104, 108, 112, 116]);
        assert_eq!(d.next_free_cycle(), 120);
        // A later arrival after the queue drained starts on arrival.
        assert_eq!(
            d.schedule(130, 32),
            DramGrant {
                start: 130,
                done: 140
            }
        );
    }

    #[test]
    fn fractional_bandwidth_is_exact() {
        // 12 B/cycle: sector i starts in cycle floor(32 i / 12) after arrival.
        let mut d = DramChannel::new(1, 12);
        for i in 0..12u64 {
            assert_eq!(d.schedule(7, 32).start, 7 + 32 * i / 12);
        }
        // 12 sectors = 384 B = exactly 32 cycles of bandwidth.
        assert_eq!(d.next_free_cycle(), 7 + 32);
    }

    #[test]
    fn a_share_of_the_bandwidth_is_exact() {
        // 328 B/cycle, 1/16 of it: 20.5 B/cycle; sector i starts at floor(32 i / 20.5).
        let mut d = DramChannel::with_share(1, 328, [1, 16]);
        for i in 0..41u64 {
            assert_eq!(d.schedule(0, 32).start, 32 * 2 * i / 41);
        }
        // 41 sectors = 1312 B = exactly 64 cycles at 20.5 B/cycle.
        assert_eq!(d.next_free_cycle(), 64);
        // The whole share is the plain channel.
        let (mut a, mut b) = (
            DramChannel::new(5, 12),
            DramChannel::with_share(5, 12, [3, 3]),
        );
        for t in [0u64, 0, 3, 3, 3, 40, 41] {
            assert_eq!(a.schedule(t, 32), b.schedule(t, 32));
        }
    }
}
