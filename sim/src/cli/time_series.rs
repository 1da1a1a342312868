//! Writing a simulation's time series ([`Sample`]s, `sim.sample_interval`) as CSV.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use crate::model::gpu::stats::Sample;

/// Writes the time series as CSV with a header line.
pub fn write_time_series(path: &Path, samples: &[Sample]) -> std::io::Result<()> {
    let mut out =
        String::from("cycle,bvh_l1_accesses,bvh_l1_misses,bvh_l1_miss_rate,active_rays\n");
    for s in samples {
        let _ = writeln!(
            out,
            "{},{},{},{},{}",
            s.cycle, s.bvh_l1_accesses, s.bvh_l1_misses, s.bvh_l1_miss_rate, s.active_rays
        );
    }
    std::fs::File::create(path)?.write_all(out.as_bytes())
}
