//! Text handling shared by the OBJ and MTL readers: decoding (UTF-8 with or without a byte-order
//! mark; UTF-16 refused with a clear error), logical lines (LF or CRLF endings, `\`
//! continuations), and the counts of statements read but not used.

use std::borrow::Cow;
use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use super::SceneError;

/// The longest keyword counted as an unused statement; a longer first word is not a statement.
const MAX_KEYWORD_LEN: usize = 32;

/// The text of a file's bytes: UTF-8 (invalid sequences replaced by U+FFFD) without a leading
/// byte-order mark. A UTF-16 byte-order mark is a [`SceneError::Parse`] naming the file.
pub fn decode<'a>(bytes: &'a [u8], path: &Path) -> Result<Cow<'a, str>, SceneError> {
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return Err(SceneError::Parse {
            path: path.display().to_string(),
            reason: "the file is UTF-16 text (byte-order mark at its start); save it as UTF-8 \
                     or ASCII"
                .into(),
        });
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    Ok(String::from_utf8_lossy(bytes))
}

/// The logical lines of `text` with the 1-based number of the physical line each starts on.
///
/// A leading byte-order mark (U+FEFF) is dropped; lines end at `\n`, and a `\r` before it is
/// dropped (CRLF files). A line whose last non-blank character is `\` continues on the next
/// line: the backslash becomes a space and the lines are joined.
pub fn logical_lines(text: &str) -> LogicalLines<'_> {
    let text = text.strip_prefix('\u{FEFF}').unwrap_or(text);
    LogicalLines {
        rest: Some(text).filter(|t| !t.is_empty()),
        line: 0,
    }
}

/// Iterator of [`logical_lines`].
#[derive(Debug, Clone)]
pub struct LogicalLines<'a> {
    /// The text not yet read (`None` at the end).
    rest: Option<&'a str>,
    /// Number of physical lines read so far.
    line: usize,
}

impl<'a> LogicalLines<'a> {
    /// The next physical line without its ending, or `None` at the end of the text.
    fn physical(&mut self) -> Option<&'a str> {
        let rest = self.rest?;
        let (line, tail) = match rest.split_once('\n') {
            Some((line, tail)) => (line, Some(tail)),
            None => (rest, None),
        };
        // A final newline does not start another (empty) line.
        self.rest = tail.filter(|t| !t.is_empty());
        self.line += 1;
        Some(line.strip_suffix('\r').unwrap_or(line))
    }
}

/// `line` without a final `\` continuation mark (and the blanks after it), if it has one.
fn continued(line: &str) -> Option<&str> {
    line.trim_end().strip_suffix('\\')
}

impl<'a> Iterator for LogicalLines<'a> {
    type Item = (usize, Cow<'a, str>);

    fn next(&mut self) -> Option<Self::Item> {
        let first = self.physical()?;
        let number = self.line;
        let Some(head) = continued(first) else {
            return Some((number, Cow::Borrowed(first)));
        };
        let mut joined = head.to_string();
        while let Some(next) = self.physical() {
            joined.push(' ');
            match continued(next) {
                Some(head) => joined.push_str(head),
                None => {
                    joined.push_str(next);
                    break;
                }
            }
        }
        Some((number, Cow::Owned(joined)))
    }
}

/// The error of line `number` of the file at `path`: `reason` after `line N: `, as a
/// [`SceneError::Parse`] naming the file (the OBJ and MTL readers' errors).
pub fn line_error(path: &Path, number: usize) -> impl Fn(String) -> SceneError + '_ {
    move |reason| SceneError::Parse {
        path: path.display().to_string(),
        reason: format!("line {number}: {reason}"),
    }
}

/// The first word of a trimmed logical line and the words after it, or `None` for a blank line
/// or a comment (a first word starting with `#`).
pub fn statement(line: &str) -> Option<(&str, std::str::SplitWhitespace<'_>)> {
    let mut words = line.split_whitespace();
    let keyword = words.next()?;
    (!keyword.starts_with('#')).then_some((keyword, words))
}

/// Whether `word` can be a statement keyword: 1 to 32 ASCII letters, digits or `_`, starting
/// with a letter.
pub fn is_keyword(word: &str) -> bool {
    word.len() <= MAX_KEYWORD_LEN
        && word.starts_with(|c: char| c.is_ascii_alphabetic())
        && word.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
}

/// How many statements of each kind were read but not used, in the order first met.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StatementCounts {
    /// `(keyword, count)` in the order first met.
    counts: Vec<(String, u64)>,
    /// Keyword to its index in `counts`.
    index: HashMap<String, usize>,
}

impl StatementCounts {
    /// Count `n` more statements of kind `keyword`.
    pub fn add(&mut self, keyword: &str, n: u64) {
        match self.index.get(keyword) {
            Some(&i) => self.counts[i].1 += n,
            None => {
                self.index.insert(keyword.to_string(), self.counts.len());
                self.counts.push((keyword.to_string(), n));
            }
        }
    }

    /// Add every count of `other` (keywords new here go last, in `other`'s order).
    pub fn merge(&mut self, other: &StatementCounts) {
        for (keyword, n) in &other.counts {
            self.add(keyword, *n);
        }
    }

    /// The count of `keyword` (0 when never met).
    pub fn get(&self, keyword: &str) -> u64 {
        self.index.get(keyword).map_or(0, |&i| self.counts[i].1)
    }

    /// Whether nothing was counted.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// Total number of statements counted.
    pub fn total(&self) -> u64 {
        self.counts.iter().map(|(_, n)| n).sum()
    }

    /// `(keyword, count)` pairs in the order first met.
    pub fn iter(&self) -> impl Iterator<Item = (&str, u64)> {
        self.counts.iter().map(|(k, n)| (k.as_str(), *n))
    }
}

/// `keyword xN` items joined by `, ` (at most 24; the rest summed as `and K more kinds xN`).
impl fmt::Display for StatementCounts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const SHOWN: usize = 24;
        let items: Vec<String> = self
            .counts
            .iter()
            .take(SHOWN)
            .map(|(k, n)| format!("{k} x{n}"))
            .collect();
        write!(f, "{}", items.join(", "))?;
        if self.counts.len() > SHOWN {
            let rest: u64 = self.counts[SHOWN..].iter().map(|(_, n)| n).sum();
            write!(f, ", and {} more kinds x{rest}", self.counts.len() - SHOWN)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(text: &str) -> Vec<(usize, String)> {
        logical_lines(text)
            .map(|(n, l)| (n, l.into_owned()))
            .collect()
    }

    #[test]
    fn crlf_bom_and_continuations() {
        assert_eq!(
            lines("\u{FEFF}v 1 2 3\r\nf 1 \\\r\n 2 \\  \n3\n\nx"),
            [
                (1, "v 1 2 3".to_string()),
                (2, "f 1   2  3".to_string()),
                (5, String::new()),
                (6, "x".to_string())
            ]
        );
        // A continuation on the last line simply ends there.
        assert_eq!(lines("a \\"), [(1, "a ".to_string())]);
        assert!(lines("").is_empty());
    }

    #[test]
    fn decoding_drops_a_utf8_bom_and_refuses_utf16() {
        let p = Path::new("x.obj");
        assert_eq!(decode(b"\xEF\xBB\xBFv 1 2 3", p).unwrap(), "v 1 2 3");
        assert_eq!(decode(b"v \xFF", p).unwrap(), "v \u{FFFD}");
        let err = decode(b"\xFF\xFEv\0", p).unwrap_err().to_string();
        assert!(err.contains("x.obj") && err.contains("UTF-16"), "{err}");
    }

    #[test]
    fn counts_keep_first_met_order_and_merge() {
        let mut a = StatementCounts::default();
        a.add("vt", 2);
        a.add("l", 1);
        a.add("vt", 1);
        let mut b = StatementCounts::default();
        b.add("map_Kd", 4);
        b.add("l", 2);
        a.merge(&b);
        assert_eq!(a.to_string(), "vt x3, l x3, map_Kd x4");
        assert_eq!((a.get("l"), a.get("nope"), a.total()), (3, 0, 10));
        let mut many = StatementCounts::default();
        for i in 0..30 {
            many.add(&format!("k{i}"), 1);
        }
        assert!(many.to_string().ends_with("k23 x1, and 6 more kinds x6"));
    }

    #[test]
    fn keywords_are_short_identifiers() {
        for ok in ["v", "map_Kd", "Ka", "curv2", "s"] {
            assert!(is_keyword(ok), "{ok}");
        }
        for bad in ["", "1", "_x", "é", "v\u{FEFF}", "@", &"k".repeat(33)] {
            assert!(!is_keyword(bad), "{bad}");
        }
    }
}
