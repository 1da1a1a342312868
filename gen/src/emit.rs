//! A small writer for readable Verilog text: indentation, wrapped `//` comments, bit ranges,
//! sized literals and identifier checks.

/// Column at which `//` comment paragraphs are wrapped.
const WRAP: usize = 96;

/// Verilog-2005 (IEEE 1364-2005, annex B) reserved words, plus the SystemVerilog words that
/// Verilator and Yosys also reserve; a signal must not be named like one of these.
const KEYWORDS: &[&str] = &[
    "always",
    "and",
    "assign",
    "automatic",
    "begin",
    "buf",
    "bufif0",
    "bufif1",
    "case",
    "casex",
    "casez",
    "cell",
    "cmos",
    "config",
    "deassign",
    "default",
    "defparam",
    "design",
    "disable",
    "edge",
    "else",
    "end",
    "endcase",
    "endconfig",
    "endfunction",
    "endgenerate",
    "endmodule",
    "endprimitive",
    "endspecify",
    "endtable",
    "endtask",
    "event",
    "for",
    "force",
    "forever",
    "fork",
    "function",
    "generate",
    "genvar",
    "highz0",
    "highz1",
    "if",
    "ifnone",
    "incdir",
    "include",
    "initial",
    "inout",
    "input",
    "instance",
    "integer",
    "join",
    "large",
    "liblist",
    "library",
    "localparam",
    "macromodule",
    "medium",
    "module",
    "nand",
    "negedge",
    "nmos",
    "nor",
    "noshowcancelled",
    "not",
    "notif0",
    "notif1",
    "or",
    "output",
    "parameter",
    "pmos",
    "posedge",
    "primitive",
    "pull0",
    "pull1",
    "pulldown",
    "pullup",
    "pulsestyle_ondetect",
    "pulsestyle_onevent",
    "rcmos",
    "real",
    "realtime",
    "reg",
    "release",
    "repeat",
    "rnmos",
    "rpmos",
    "rtran",
    "rtranif0",
    "rtranif1",
    "scalared",
    "showcancelled",
    "signed",
    "small",
    "specify",
    "specparam",
    "strong0",
    "strong1",
    "supply0",
    "supply1",
    "table",
    "task",
    "time",
    "tran",
    "tranif0",
    "tranif1",
    "tri",
    "tri0",
    "tri1",
    "triand",
    "trior",
    "trireg",
    "unsigned",
    "use",
    "uwire",
    "vectored",
    "wait",
    "wand",
    "weak0",
    "weak1",
    "while",
    "wire",
    "wor",
    "xnor",
    "xor",
    "bit",
    "logic",
    "byte",
    "int",
    "shortint",
    "longint",
    "enum",
    "struct",
    "union",
    "typedef",
    "interface",
    "package",
    "import",
    "export",
    "class",
    "return",
    "break",
    "continue",
    "do",
    "final",
    "priority",
    "unique",
    "string",
    "void",
    "type",
    "const",
];

/// Whether `name` is a legal, non-reserved Verilog identifier (letters, digits, `_`, `$`; not
/// starting with a digit or `$`).
pub fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    let Some(first) = chars.next() else {
        return false;
    };
    (first.is_ascii_alphabetic() || first == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '$')
        && !KEYWORDS.contains(&name)
}

/// The packed range of a `width`-bit signal with a trailing space (`"[11:0] "`), or nothing
/// for a single bit.
pub fn range(width: u32) -> String {
    if width <= 1 {
        String::new()
    } else {
        format!("[{}:0] ", width - 1)
    }
}

/// Widest sized literal [`dec`] writes as one number: Verilator 5.006 rejects wider ones
/// ("Width of number exceeds implementation limit"), which IEEE 1364-2005 permits for sizes
/// above 65,536 bits, and warns about replications wider than 8 Kbit.
pub const MAX_LITERAL_WIDTH: u32 = 1 << 16;

/// A sized decimal literal (`12'd0`); above [`MAX_LITERAL_WIDTH`] bits a concatenation of
/// literals of at most that width, the value in the last one (`{10240'd0, 65536'd5}`).
pub fn dec(width: u32, value: u64) -> String {
    if width <= MAX_LITERAL_WIDTH {
        return format!("{width}'d{value}");
    }
    let mut parts = Vec::new();
    let mut rest = width - MAX_LITERAL_WIDTH;
    while rest > 0 {
        let w = rest.min(MAX_LITERAL_WIDTH);
        parts.push(format!("{w}'d0"));
        rest -= w;
    }
    parts.reverse();
    parts.push(format!("{MAX_LITERAL_WIDTH}'d{value}"));
    format!("{{{}}}", parts.join(", "))
}

/// `CamelCase`, `snake_case` or `kebab-case` text as `SCREAMING_SNAKE_CASE` (for localparams).
pub fn screaming_snake(name: &str) -> String {
    let mut out = String::new();
    let mut prev_lower = false;
    for c in name.chars() {
        if c.is_ascii_uppercase() && prev_lower {
            out.push('_');
        }
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_uppercase());
        } else if !out.ends_with('_') {
            out.push('_');
        }
        prev_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
    }
    out
}

/// Accumulates Verilog source line by line with indentation.
#[derive(Debug, Default)]
pub struct VerilogWriter {
    out: String,
    indent: usize,
}

impl VerilogWriter {
    /// An empty writer at indentation level 0.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes one line at the current indentation (an empty `text` writes an empty line).
    pub fn line(&mut self, text: impl AsRef<str>) {
        let text = text.as_ref();
        if !text.is_empty() {
            for _ in 0..self.indent {
                self.out.push_str("    ");
            }
            self.out.push_str(text);
        }
        self.out.push('\n');
    }

    /// Writes `text` as `//` comment lines, wrapped at word boundaries; embedded newlines
    /// start new comment lines, and a line indented with spaces (a list item) keeps its
    /// indentation, its continuation lines two more.
    pub fn comment(&mut self, text: &str) {
        let width = WRAP.saturating_sub(4 * self.indent + 3).max(20);
        for paragraph in text.lines() {
            if paragraph.trim().is_empty() {
                self.line("//");
                continue;
            }
            let lead: String = paragraph.chars().take_while(|c| *c == ' ').collect();
            let continuation = if lead.is_empty() {
                String::new()
            } else {
                format!("{lead}  ")
            };
            let mut current = lead.clone();
            let mut empty = true;
            for word in paragraph.split_whitespace() {
                if !empty && current.len() + 1 + word.len() > width {
                    self.line(format!("// {current}"));
                    current = continuation.clone();
                    empty = true;
                }
                if !empty {
                    current.push(' ');
                }
                current.push_str(word);
                empty = false;
            }
            self.line(format!("// {current}"));
        }
    }

    /// Increases the indentation by one level (four spaces).
    pub fn indent(&mut self) {
        self.indent += 1;
    }

    /// Decreases the indentation by one level.
    pub fn dedent(&mut self) {
        self.indent = self.indent.saturating_sub(1);
    }

    /// The text written so far.
    pub fn finish(self) -> String {
        self.out
    }
}

/// One line of text as a comment-safe string (no newlines, no `*/`), for trailing `//` comments.
pub fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers() {
        assert!(is_identifier("max_count"));
        assert!(is_identifier("_x1$"));
        assert!(!is_identifier("1x"));
        assert!(!is_identifier("wire"));
        assert!(!is_identifier("logic"));
        assert!(!is_identifier("a-b"));
        assert!(!is_identifier(""));
    }

    #[test]
    fn ranges_and_names() {
        assert_eq!(range(1), "");
        assert_eq!(range(12), "[11:0] ");
        assert_eq!(dec(7, 5), "7'd5");
        assert_eq!(dec(MAX_LITERAL_WIDTH, 0), "65536'd0");
        assert_eq!(dec(75776, 5), "{10240'd0, 65536'd5}");
        assert_eq!(dec(3 << 16, 0), "{65536'd0, 65536'd0, 65536'd0}");
        assert_eq!(screaming_snake("RayStationary"), "RAY_STATIONARY");
        assert_eq!(screaming_snake("treelet_stationary"), "TREELET_STATIONARY");
        assert_eq!(screaming_snake("Phase2Done"), "PHASE2_DONE");
    }

    #[test]
    fn comments_wrap() {
        let mut w = VerilogWriter::new();
        w.indent();
        let long = "word ".repeat(40);
        w.comment(&long);
        let text = w.finish();
        assert!(text.lines().count() > 1);
        assert!(text
            .lines()
            .all(|l| l.len() <= WRAP && l.starts_with("    // ")));
    }
}
