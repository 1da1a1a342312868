//! Fuzzing every parser of user input: OBJ, MTL, glTF/GLB, PLY, `scene.toml`, configuration
//! TOML, `--set` overrides, rays CSV and BVH cache files (`vtq fuzz`, `docs/fuzzing.md`).
//!
//! Each parser gets cases made from its generated valid seeds ([`seeds`], [`mesh_seeds`]) by 1
//! to 8 random mutations ([`mutate`]), plus unchanged seeds and random bytes; cache files are
//! mostly resealed with a valid checksum after mutation so that the node validation behind the
//! checksum is reached, and GLB files get their chunk lengths repaired for the same reason. Each case runs on a worker thread under a time bound with panics caught
//! ([`harness`]); an input that panics or hangs is saved to a file for reproduction
//! (`vtq fuzz --replay FILE`). An accepted input must also keep its parser's invariants
//! ([`targets`]: round trips, counts, valid materials), checked by assertions that the harness
//! reports like any panic. Cases are determined by the seed: the same seed gives the same
//! inputs (the report's digest) on any machine.

pub mod harness;
pub mod mesh_seeds;
pub mod mutate;
pub mod seeds;
pub mod targets;

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use harness::{CaseEnd, Runner, Target};
use mutate::{mutate, random_bytes, Rng};
use targets::Outcome;

/// A parser under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Parser {
    /// Wavefront OBJ geometry (with an in-memory material library).
    Obj,
    /// Wavefront MTL material libraries.
    Mtl,
    /// glTF 2.0 files, JSON or GLB (with an in-memory external buffer).
    Gltf,
    /// PLY meshes, ASCII or binary.
    Ply,
    /// Scene folder manifests (`scene.toml`).
    SceneToml,
    /// Simulator configuration files.
    Config,
    /// `--set key=value` overrides (one a line).
    Set,
    /// Rays CSV files (`vtq trace --rays`).
    RaysCsv,
    /// Ray files in either form, binary or CSV (`[workload]` `rays_file`).
    RayFile,
    /// BVH cache files.
    BvhCache,
}

impl Parser {
    /// Every parser, in report order.
    pub const ALL: [Parser; 10] = [
        Parser::Obj,
        Parser::Mtl,
        Parser::Gltf,
        Parser::Ply,
        Parser::SceneToml,
        Parser::Config,
        Parser::Set,
        Parser::RaysCsv,
        Parser::RayFile,
        Parser::BvhCache,
    ];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Parser::Obj => "obj",
            Parser::Mtl => "mtl",
            Parser::Gltf => "gltf",
            Parser::Ply => "ply",
            Parser::SceneToml => "scene-toml",
            Parser::Config => "config",
            Parser::Set => "set",
            Parser::RaysCsv => "rays-csv",
            Parser::RayFile => "ray-file",
            Parser::BvhCache => "bvh-cache",
        }
    }

    /// The parser called `name`, if any.
    pub fn from_name(name: &str) -> Option<Parser> {
        Parser::ALL.into_iter().find(|p| p.name() == name)
    }

    /// File extension of saved inputs.
    fn extension(self) -> &'static str {
        match self {
            Parser::Obj => "obj",
            Parser::Mtl => "mtl",
            Parser::Gltf => "gltf",
            Parser::Ply => "ply",
            Parser::SceneToml | Parser::Config => "toml",
            Parser::Set => "txt",
            Parser::RaysCsv => "csv",
            Parser::RayFile => "bin",
            Parser::BvhCache => "vtqbvh",
        }
    }

    /// The parser as a fuzz target.
    pub fn target(self) -> Target {
        Arc::new(move |input: &[u8]| targets::run(self, input))
    }
}

impl fmt::Display for Parser {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Settings of a fuzz run.
#[derive(Debug, Clone)]
pub struct FuzzOptions {
    /// Cases per parser.
    pub cases: u64,
    /// Seed of the case generator.
    pub seed: u64,
    /// Time bound of one case.
    pub timeout: Duration,
    /// Folder for inputs that panic or hang (created when the first one is saved); `None`
    /// saves nothing.
    pub save_dir: Option<PathBuf>,
    /// Stop a parser after this many hangs (each abandons a busy worker thread).
    pub max_hangs: u64,
}

/// One input that panicked or hung.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    /// Index of the case in the run.
    pub case: u64,
    /// The panic message, or `hang (over N ms)`.
    pub message: String,
    /// Where the input was saved, if it was.
    pub saved: Option<PathBuf>,
}

/// The figures of one parser's run.
#[derive(Debug, Clone, PartialEq)]
pub struct ParserReport {
    /// The parser.
    pub parser: Parser,
    /// Cases run.
    pub cases: u64,
    /// Cases the parser accepted.
    pub accepted: u64,
    /// Cases the parser rejected with an error.
    pub rejected: u64,
    /// Cases that panicked.
    pub panics: Vec<Failure>,
    /// Cases that did not finish within the time bound.
    pub hangs: Vec<Failure>,
    /// The slowest case: its index and duration.
    pub slowest: (u64, Duration),
    /// Wall time of the run.
    pub wall: Duration,
    /// blake3 of every input in order (first 16 hex digits): equal for equal seeds.
    pub digest: String,
}

/// The input of case `case` for `parser`: random bytes (8%), an unchanged seed (4%), or a
/// mutated seed (for cache files, resealed with a valid checksum 3 times in 4; for GLB files,
/// their lengths repaired 3 times in 4).
fn make_case(parser: Parser, rng: &mut Rng, seeds: &[Vec<u8>]) -> Vec<u8> {
    let roll = rng.below(100);
    if roll < 8 {
        return random_bytes(rng);
    }
    let mut input = rng.pick(seeds).clone();
    if roll < 12 {
        return input;
    }
    let other = rng.pick(seeds).clone();
    mutate(rng, &mut input, &other);
    if parser == Parser::BvhCache && rng.chance(75) {
        reseal(&mut input);
    }
    if parser == Parser::Gltf && input.starts_with(b"glTF") && rng.chance(75) {
        mesh_seeds::reseal_glb(&mut input);
    }
    input
}

/// Replace the last 32 bytes of a cache file by the blake3 hash of the rest (the checksum a
/// valid file carries), so that mutations get past the checksum.
fn reseal(input: &mut [u8]) {
    if input.len() >= 64 {
        let (body, sum) = input.split_at_mut(input.len() - 32);
        sum.copy_from_slice(blake3::hash(body).as_bytes());
    }
}

/// Run `options.cases` cases of `parser` (see the module documentation).
pub fn fuzz_parser(parser: Parser, options: &FuzzOptions) -> ParserReport {
    fuzz_target(parser, parser.target(), None, options)
}

/// Run `options.cases` cases of `target` on inputs made for `parser` (or from `seeds` when
/// given), reporting panics, hangs and the slowest case. The inputs depend only on the parser
/// and `options.seed`.
pub fn fuzz_target(
    parser: Parser,
    target: Target,
    seeds: Option<Vec<Vec<u8>>>,
    options: &FuzzOptions,
) -> ParserReport {
    let start = Instant::now();
    let mut rng = Rng::new(options.seed ^ blake3_u64(parser.name()));
    let seeds = seeds.unwrap_or_else(|| seeds::seeds(parser, &mut rng));
    let mut runner = Runner::new(target, options.timeout);
    let mut digest = blake3::Hasher::new();
    let mut report = ParserReport {
        parser,
        cases: 0,
        accepted: 0,
        rejected: 0,
        panics: Vec::new(),
        hangs: Vec::new(),
        slowest: (0, Duration::ZERO),
        wall: Duration::ZERO,
        digest: String::new(),
    };
    for case in 0..options.cases {
        let input = make_case(parser, &mut rng, &seeds);
        digest.update(&(input.len() as u64).to_le_bytes());
        digest.update(&input);
        let (end, took) = runner.run(&input);
        report.cases += 1;
        if took > report.slowest.1 {
            report.slowest = (case, took);
        }
        let failure = |message: String| Failure {
            case,
            saved: save(options, parser, case, &message, &input),
            message,
        };
        match end {
            CaseEnd::Done(Outcome::Accepted) => report.accepted += 1,
            CaseEnd::Done(Outcome::Rejected) => report.rejected += 1,
            CaseEnd::Panic(message) => report.panics.push(failure(message)),
            CaseEnd::Hang => {
                let message = format!("hang (over {} ms)", options.timeout.as_millis());
                report.hangs.push(failure(message));
                if report.hangs.len() as u64 >= options.max_hangs {
                    break;
                }
            }
        }
    }
    report.wall = start.elapsed();
    report.digest = digest.finalize().to_hex()[..16].to_string();
    report
}

/// The first 8 bytes of the blake3 hash of `text`, as a number (to derive a parser's stream).
fn blake3_u64(text: &str) -> u64 {
    let hash = blake3::hash(text.as_bytes());
    u64::from_le_bytes(hash.as_bytes()[..8].try_into().expect("8 bytes"))
}

/// Save a failing input as `<parser>-<kind>-seed<S>-case<N>.<ext>` in the save folder; returns
/// the path, or `None` when saving is off or fails (the report still names the case).
fn save(
    options: &FuzzOptions,
    parser: Parser,
    case: u64,
    message: &str,
    input: &[u8],
) -> Option<PathBuf> {
    let dir = options.save_dir.as_deref()?;
    let kind = if message.starts_with("hang") {
        "hang"
    } else {
        "panic"
    };
    let path = dir.join(format!(
        "{}-{kind}-seed{}-case{case}.{}",
        parser.name(),
        options.seed,
        parser.extension()
    ));
    std::fs::create_dir_all(dir).ok()?;
    std::fs::write(&path, input).ok()?;
    Some(path)
}

/// Run one saved input through `parser` (under the same time bound and panic catching) and
/// describe how it ended.
pub fn replay(parser: Parser, path: &Path, timeout: Duration) -> std::io::Result<String> {
    let input = std::fs::read(path)?;
    let mut runner = Runner::new(parser.target(), timeout);
    let (end, took) = runner.run(&input);
    let ms = took.as_secs_f64() * 1000.0;
    Ok(match end {
        CaseEnd::Done(Outcome::Accepted) => format!("accepted in {ms:.3} ms"),
        CaseEnd::Done(Outcome::Rejected) => format!("rejected with an error in {ms:.3} ms"),
        CaseEnd::Panic(message) => format!("PANIC after {ms:.3} ms: {message}"),
        CaseEnd::Hang => format!("HANG: no answer within {} ms", timeout.as_millis()),
    })
}
