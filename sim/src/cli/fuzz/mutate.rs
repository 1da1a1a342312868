//! The fuzzer's random numbers and mutators: byte flips, interesting tokens (`nan`, `-0`,
//! `1e39`, huge indices, `\`, CR, byte-order marks, ...), deletion, duplication, repetition,
//! truncation, line edits and splicing with another seed.

use crate::model::splitmix::SplitMix64;

/// Inputs are cut to this many bytes after mutation, so that every case stays quick.
pub const MAX_INPUT: usize = 64 * 1024;

/// The fuzzer's random numbers: [`SplitMix64`], so a fuzz run is reproduced exactly by its seed.
#[derive(Debug, Clone)]
pub struct Rng(SplitMix64);

impl Rng {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng(SplitMix64::new(seed))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        self.0.below(n as u64) as usize
    }

    /// True with probability `percent` / 100.
    pub fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }

    /// A uniformly chosen element of `items` (which must not be empty).
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// A float for generated inputs: mostly small decimals, sometimes special values.
    pub fn float(&mut self) -> f32 {
        match self.below(20) {
            0 => *self.pick(&[0.0, -0.0, 1.0, -1.0, 0.5, 1e-30, 1e30]),
            _ => (self.below(20_001) as f32 - 10_000.0) / 1000.0,
        }
    }
}

/// Tokens that break parsers: special floats, integers at type limits, line and escape
/// characters, byte-order marks, TOML and CSV punctuation, replacement characters.
pub const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "infinity",
    "-0",
    "-0.0",
    "0",
    "1",
    "-1",
    "1e39",
    "-1e39",
    "1e-45",
    "3.4028235e38",
    "1e308",
    "1e400",
    "255",
    "256",
    "65536",
    "2147483647",
    "2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "18446744073709551616",
    "99999999999999999999999999",
    "0x10",
    "1_000",
    "+1",
    ".",
    "e",
    "\\",
    "\\\n",
    "\\\r\n",
    "\r",
    "\n",
    "\r\n",
    "\u{FEFF}",
    "\u{FFFD}",
    "\0",
    "\t",
    " ",
    "/",
    "//",
    "///",
    "#",
    "=",
    "==",
    "\"",
    "'",
    "\"\"\"",
    "'''",
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    ",",
    ",,",
    "é",
    "true",
    "false",
    "1979-05-27T07:32:00Z",
    "v",
    "f",
    "usemtl",
    "mtllib",
    "newmtl",
    "Kd",
];

/// Bytes worth writing over another byte.
const BYTES: &[u8] = b"\0\xFF\x7F\x80\n\r\\/#=\"'[],.-+e \t0123456789";

/// Mutate `input` with 1 to 8 random edits (one 60% of the time, so that most cases stay close
/// to valid and reach deep into the parser); `other` is a second seed for splicing.
pub fn mutate(rng: &mut Rng, input: &mut Vec<u8>, other: &[u8]) {
    let edits = match rng.below(100) {
        0..60 => 1,
        60..85 => 2 + rng.below(2),
        _ => 4 + rng.below(5),
    };
    for _ in 0..edits {
        edit(rng, input, other);
        input.truncate(MAX_INPUT);
    }
}

/// One random edit of `input`.
fn edit(rng: &mut Rng, input: &mut Vec<u8>, other: &[u8]) {
    let len = input.len();
    let at = rng.below(len + 1);
    match rng.below(15) {
        0 if len > 0 => {
            let i = rng.below(len);
            input[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            input[i] = *rng.pick(BYTES);
        }
        2 | 3 => {
            let token = rng.pick(TOKENS).as_bytes();
            input.splice(at..at, token.iter().copied());
        }
        4 => replace_number(rng, input),
        5 if len > 0 => {
            let (start, end) = range(rng, len, 16);
            input.drain(start..end);
        }
        6 if len > 0 => {
            let (start, end) = range(rng, len, 256);
            let copy = input[start..end].to_vec();
            input.splice(end..end, copy);
        }
        7 if len > 0 => {
            // Repetition: deep nesting, long lines, many statements.
            let (start, end) = range(rng, len, 16);
            let copy = input[start..end].to_vec();
            let times = 2 + rng.below(1000);
            let mut grown = Vec::new();
            for _ in 0..times {
                if grown.len() + copy.len() > MAX_INPUT / 2 {
                    break;
                }
                grown.extend_from_slice(&copy);
            }
            input.splice(end..end, grown);
        }
        8 => input.truncate(at),
        9 | 10 => line_edit(rng, input),
        11 if !other.is_empty() => {
            let cut = rng.below(other.len() + 1);
            input.truncate(at);
            input.extend_from_slice(&other[cut..]);
        }
        12 => {
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
            input.splice(at..at, bytes);
        }
        13 => match rng.below(3) {
            // The encoding and line-ending quirks of real files.
            0 => drop(input.splice(0..0, *b"\xEF\xBB\xBF")),
            1 => drop(input.splice(0..0, *b"\xFF\xFE")),
            _ => *input = crlf(input),
        },
        _ if len > 0 => {
            let token = rng.pick(TOKENS).as_bytes();
            let (start, end) = range(rng, len, 8);
            input.splice(start..end, token.iter().copied());
        }
        _ => input.extend_from_slice(rng.pick(TOKENS).as_bytes()),
    }
}

/// A random non-empty range `start..end` of at most `max` bytes within `0..len` (`len > 0`).
fn range(rng: &mut Rng, len: usize, max: usize) -> (usize, usize) {
    let start = rng.below(len);
    let n = 1 + rng.below(max.min(len - start));
    (start, start + n)
}

/// Replace one run of digits (a number or an index) with an interesting token.
fn replace_number(rng: &mut Rng, input: &mut Vec<u8>) {
    let runs: Vec<(usize, usize)> = {
        let mut runs = Vec::new();
        let mut i = 0;
        while i < input.len() {
            if input[i].is_ascii_digit() {
                let start = i;
                while i < input.len() && (input[i].is_ascii_digit() || input[i] == b'.') {
                    i += 1;
                }
                runs.push((start, i));
            } else {
                i += 1;
            }
        }
        runs
    };
    if runs.is_empty() {
        return;
    }
    let (start, end) = *rng.pick(&runs);
    let token = rng.pick(TOKENS).as_bytes();
    input.splice(start..end, token.iter().copied());
}

/// Delete, duplicate or swap whole lines.
fn line_edit(rng: &mut Rng, input: &mut Vec<u8>) {
    let mut lines: Vec<Vec<u8>> = input.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
    if lines.is_empty() {
        return;
    }
    let i = rng.below(lines.len());
    let j = rng.below(lines.len());
    match rng.below(3) {
        0 => {
            lines.remove(i);
        }
        1 => {
            let line = lines[i].clone();
            lines.insert(j, line);
        }
        _ => lines.swap(i, j),
    }
    *input = lines.join(&b'\n');
}

/// `input` with every LF turned into CRLF.
fn crlf(input: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(input.len() + input.len() / 16);
    for &b in input {
        if b == b'\n' {
            out.push(b'\r');
        }
        out.push(b);
    }
    out
}

/// Random bytes: printable ASCII with line ends half of the time, else any bytes.
pub fn random_bytes(rng: &mut Rng) -> Vec<u8> {
    let n = rng.below(512);
    if rng.chance(50) {
        const TEXT: &[u8] = b"abcdefgvtnlmpsoKdNe0123456789.-+ /#=[]\"\n\n\r\\";
        (0..n).map(|_| *rng.pick(TEXT)).collect()
    } else {
        (0..n).map(|_| rng.next_u64() as u8).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generator_is_determined_by_its_seed() {
        let draw = |seed| {
            let mut rng = Rng::new(seed);
            let mut input = b"v 1 2 3\nf 1 2 3\n".to_vec();
            mutate(&mut rng, &mut input, b"other seed");
            (input, random_bytes(&mut rng))
        };
        assert_eq!(draw(7), draw(7));
        assert_ne!(draw(7), draw(8));
        let mut rng = Rng::new(1);
        assert!((0..1000).all(|_| rng.below(10) < 10));
        assert_eq!(rng.below(0), 0);
    }

    #[test]
    fn mutations_stay_bounded_and_change_the_input() {
        let mut rng = Rng::new(3);
        let seed = b"[camera]\neye = [0, 0, 5]\n".to_vec();
        let mut changed = 0;
        for _ in 0..2000 {
            let mut input = seed.clone();
            mutate(&mut rng, &mut input, b"ox,oy\n1,2\n");
            assert!(input.len() <= MAX_INPUT);
            changed += usize::from(input != seed);
        }
        assert!(changed > 1900, "{changed} of 2000 inputs changed");
        assert_eq!(crlf(b"a\nb\n"), b"a\r\nb\r\n");
    }
}
