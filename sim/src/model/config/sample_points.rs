//! The sampled tier's named operating points (`--sample default`, `--sample fast`): the
//! settings each name stands for and what they were last measured to give against full
//! detail. One table ([`POINTS`]) feeds the command line, its help, the notes a run prints
//! when it is outside the conditions a point was measured in, and the docs test that checks
//! docs/accuracy.md's reference table.

use super::{Cluster, SampleConfig, SimConfig, WorkloadKindName};

/// What an operating point gave against full detail in the run that measured it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// Frame width and height it was measured at (square frames).
    pub frame: u32,
    /// Host threads of both tiers in the benchmark.
    pub threads: u32,
    /// Scene-design pairs of the benchmark.
    pub pairs: u32,
    /// Mean speed-up over full detail (wall time), each design profiling on its own.
    pub faster: f64,
    /// Smallest and largest speed-up over the pairs.
    pub faster_range: (f64, f64),
    /// Mean speed-up with the functional profile shared by a scene's designs (as `vtq compare
    /// --sample`, `vtq sweep --sample` and `vtq reproduce --sample` run them).
    pub faster_shared: f64,
    /// Mean and worst absolute error of cycles, percent.
    pub cycles_error: (f64, f64),
    /// Mean and worst absolute error of speedups over the baseline, percent.
    pub speedup_error: (f64, f64),
    /// Share of 95% intervals that held full detail's value, percent.
    pub coverage: f64,
    /// Where the run is recorded (a section of docs/log/accuracy-log.md).
    pub recorded: &'static str,
}

/// A named operating point: `FRACTIONxREPLICATES` with a profile stride and cluster sizes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// Its name on the command line.
    pub name: &'static str,
    /// What it is for, in a few words.
    pub purpose: &'static str,
    /// The fraction as `(1, d)`: `1/d` of the GPU and of the frame.
    pub one_in: u32,
    /// Replicates.
    pub replicates: u32,
    /// `sample.profile_stride`.
    pub profile_stride: u32,
    /// `sample.cluster`, one size per replicate in turn.
    pub cluster: &'static [u32],
    /// Its last measurement at the frame size it is meant for.
    pub measured: Measured,
}

/// The section of the accuracy log both points were last measured in.
const NAMED_POINTS: &str = "The named points, measured by name (2026-12-02)";

/// The named points, the default first.
pub const POINTS: [OperatingPoint; 2] = [
    OperatingPoint {
        name: "default",
        purpose: "the benchmarked point: every error target met on the benchmark's seed",
        one_in: 16,
        replicates: 2,
        profile_stride: 4,
        cluster: &[1, 2],
        measured: Measured {
            frame: 1024,
            threads: 2,
            pairs: 33,
            faster: 7.1,
            faster_range: (5.3, 10.4),
            faster_shared: 8.0,
            cycles_error: (1.38, 4.63),
            speedup_error: (1.62, 4.63),
            coverage: 98.0,
            recorded: NAMED_POINTS,
        },
    },
    OperatingPoint {
        name: "fast",
        purpose: "faster, with larger worst errors (below one SM)",
        one_in: 32,
        replicates: 2,
        profile_stride: 4,
        cluster: &[1, 2],
        measured: Measured {
            frame: 1024,
            threads: 2,
            pairs: 33,
            faster: 12.0,
            faster_range: (7.9, 18.0),
            faster_shared: 14.8,
            cycles_error: (1.93, 8.30),
            speedup_error: (2.48, 8.91),
            coverage: 96.0,
            recorded: NAMED_POINTS,
        },
    },
];

/// The name `--sample` takes without a value.
pub const DEFAULT_POINT: &str = "default";

/// The name that keeps the `[sample]` section's settings as configured.
pub const CONFIG_POINT: &str = "config";

/// The named point `name`, if there is one.
pub fn point(name: &str) -> Option<&'static OperatingPoint> {
    POINTS.iter().find(|p| p.name == name)
}

impl OperatingPoint {
    /// The point's settings written into `s` (fraction, replicates, profile stride, cluster);
    /// the section's other keys (seed, stripes, bounds, L2 warming) stay as configured.
    pub fn apply(&self, s: &mut SampleConfig) {
        s.fraction = 1.0 / f64::from(self.one_in);
        s.replicates = self.replicates;
        s.profile_stride = self.profile_stride;
        s.cluster = Cluster::PerReplicate(self.cluster.to_vec());
    }

    /// `1/16x2, profile_stride 4, cluster [1, 2]`.
    pub fn settings(&self) -> String {
        let sizes: Vec<String> = self.cluster.iter().map(u32::to_string).collect();
        format!(
            "1/{}x{}, profile_stride {}, cluster [{}]",
            self.one_in,
            self.replicates,
            self.profile_stride,
            sizes.join(", ")
        )
    }

    /// One line of what it gave: `7.1x faster (5.3-10.4x; 8.0x shared), cycles 1.38% mean /
    /// 4.63% worst, speedups 1.62% / 4.63%, 98% of intervals holding (1024x1024, 2 threads,
    /// 33 pairs)`.
    pub fn measured_line(&self) -> String {
        let m = &self.measured;
        format!(
            "{:.1}x faster ({:.1}-{:.1}x; {:.1}x shared), cycles error {:.2}% mean / {:.2}% worst, speedups \
             {:.2}% / {:.2}%, {:.0}% of 95% intervals holding ({f}x{f}, {} threads, {} \
             scene-design pairs)",
            m.faster,
            m.faster_range.0,
            m.faster_range.1,
            m.faster_shared,
            m.cycles_error.0,
            m.cycles_error.1,
            m.speedup_error.0,
            m.speedup_error.1,
            m.coverage,
            m.threads,
            m.pairs,
            f = m.frame,
        )
    }

    /// Notes for running this point on `cfg` outside the conditions it was measured in, each
    /// saying what to use instead: a smaller frame than it was measured at.
    pub fn notes(&self, cfg: &SimConfig) -> Vec<String> {
        let mut notes = Vec::new();
        let m = &self.measured;
        let pixels = u64::from(cfg.workload.width) * u64::from(cfg.workload.height);
        let measured = u64::from(m.frame) * u64::from(m.frame);
        if pixels < measured {
            notes.push(format!(
                "the sample point `{}` was measured at {f}x{f} ({}); this frame is {}x{}, \
                 where a sample holds fewer CTAs and errors grow (at 256x256, 1/16x2 with the \
                 [sample] defaults was 3.5x faster at 3.2% mean, 14% worst error of cycles; \
                 docs/accuracy.md): for small frames prefer full detail (no --sample, with \
                 --threads), which is exact",
                self.name,
                self.measured_line(),
                cfg.workload.width,
                cfg.workload.height,
                f = m.frame,
            ));
        }
        let kind = cfg.workload.kind;
        if kind != WorkloadKindName::Path {
            notes.push(format!(
                "the sample point `{}` was measured on the path tracer; its error on the `{}` \
                 workload is not measured (the 95% intervals still hold their meaning): check a \
                 result against full detail (no --sample) before relying on it",
                self.name,
                kind.name(),
            ));
        }
        notes
    }
}

/// The notes of `spec` (a `--sample` value) for `cfg` when it names a point
/// ([`OperatingPoint::notes`]); none for other values.
pub fn notes(spec: Option<&str>, cfg: &SimConfig) -> Vec<String> {
    spec.and_then(|s| point(s.trim()))
        .map_or_else(Vec::new, |p| p.notes(cfg))
}

/// The notes of `spec` for every configuration of a sweep or reproduce run, each distinct note
/// once, in the order first met.
pub fn notes_of_all<'a>(
    spec: Option<&str>,
    cfgs: impl IntoIterator<Item = &'a SimConfig>,
) -> Vec<String> {
    let mut all: Vec<String> = Vec::new();
    for cfg in cfgs {
        for note in notes(spec, cfg) {
            if !all.contains(&note) {
                all.push(note);
            }
        }
    }
    all
}

/// The named points as a table for `--help` and listings: name, settings, purpose and what
/// each was last measured to give.
pub fn points_help() -> String {
    let mut s = String::from(
        "The sampled tier instead of full detail: estimates with 95% intervals from scale \
         models running samples of the frame (docs/accuracy.md). POINT is a named point, \
         `FRACTION[xREPLICATES]` (e.g. `1/16x4`, with the [sample] section's other settings) or \
         `config` (the [sample] section as configured); without a value, `default`. A named \
         point sets sample.fraction, replicates, profile_stride and cluster (a --set of those \
         keys is overridden: use the explicit form to vary them).\n\nNamed points:",
    );
    for p in &POINTS {
        s.push_str(&format!(
            "\n  {:<8} {} — {}\n           measured: {}",
            p.name,
            p.settings(),
            p.purpose,
            p.measured_line()
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_valid_and_named_once() {
        let cfg = SimConfig::default();
        for p in &POINTS {
            let mut s = SampleConfig::default();
            p.apply(&mut s);
            s.validate(&cfg)
                .unwrap_or_else(|e| panic!("{}: {e}", p.name));
            assert_eq!(POINTS.iter().filter(|q| q.name == p.name).count(), 1);
            assert!(p.name != CONFIG_POINT && point(p.name) == Some(p));
        }
        assert!(point(DEFAULT_POINT).is_some() && point("nope").is_none());
    }

    /// docs/accuracy.md's reference table gives each named point's settings and figures as
    /// this table does, and names the run that recorded them.
    #[test]
    fn the_docs_reference_table_is_this_table() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/accuracy.md");
        let doc = std::fs::read_to_string(path).unwrap();
        for p in &POINTS {
            let m = &p.measured;
            let row = doc
                .lines()
                .find(|l| l.starts_with(&format!("| `{}`", p.name)))
                .unwrap_or_else(|| panic!("docs/accuracy.md has no row for `{}`", p.name));
            let sizes: Vec<String> = p.cluster.iter().map(u32::to_string).collect();
            for expected in [
                format!("`1/{}x{}`", p.one_in, p.replicates),
                format!("`profile_stride = {}`", p.profile_stride),
                format!("`cluster = [{}]`", sizes.join(", ")),
                format!(
                    "{:.1}x ({:.1}-{:.1}x; {:.1}x)",
                    m.faster, m.faster_range.0, m.faster_range.1, m.faster_shared
                ),
                format!("{:.2}% / {:.2}%", m.cycles_error.0, m.cycles_error.1),
                format!("{:.2}% / {:.2}%", m.speedup_error.0, m.speedup_error.1),
                format!("| {:.0}% |", m.coverage),
                format!("[{}]", m.recorded),
            ] {
                assert!(
                    row.contains(&expected),
                    "`{}`: no {expected} in {row}",
                    p.name
                );
            }
            let log = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/log/accuracy-log.md");
            let log = std::fs::read_to_string(log).unwrap();
            assert!(
                log.contains(&format!("## {}", m.recorded)),
                "{}",
                m.recorded
            );
        }
    }

    #[test]
    fn small_frames_get_a_note_naming_what_to_use() {
        let p = point(DEFAULT_POINT).unwrap();
        let mut cfg = SimConfig::default();
        cfg.workload.width = 256;
        cfg.workload.height = 256;
        let notes = p.notes(&cfg);
        assert_eq!(notes.len(), 1);
        assert!(notes[0].contains("256x256") && notes[0].contains("full detail"));
        cfg.workload.width = 1024;
        cfg.workload.height = 1024;
        assert!(p.notes(&cfg).is_empty());
    }
}
