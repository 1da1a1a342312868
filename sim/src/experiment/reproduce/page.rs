//! The reproduction's page: `index.html` (the figures as SVG with their tables) and its Markdown
//! twin `index.md` (the same content, PNG images), plus one CSV per table in `tables/`.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;

use super::figures::{Figure, Table};
use crate::model::atomic_file::write_atomic;

/// Everything on the page.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    /// Title.
    pub title: String,
    /// Paragraphs before the figures (how it was made, how to rerun it).
    pub intro: Vec<String>,
    /// The figures, in order.
    pub figures: Vec<Figure>,
    /// Further tables: heading, text and table.
    pub tables: Vec<(String, String, Table)>,
}

/// Escapes text for HTML.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Turns `code` spans of the page's text into HTML (the text is escaped first).
fn inline_html(s: &str) -> String {
    let mut out = String::new();
    for (i, part) in esc(s).split('`').enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{part}</code>");
        } else {
            out.push_str(part);
        }
    }
    out
}

/// A table as HTML (nothing for a table without columns: a figure not drawn).
fn html_table(t: &Table) -> String {
    if t.header.is_empty() {
        return String::new();
    }
    let mut s = String::from("<table>\n<tr>");
    for h in &t.header {
        let _ = write!(s, "<th>{}</th>", esc(h));
    }
    s.push_str("</tr>\n");
    for row in &t.rows {
        s.push_str("<tr>");
        for c in row {
            let _ = write!(s, "<td>{}</td>", esc(c));
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</table>\n");
    s
}

/// A table as Markdown (nothing for a table without columns: a figure not drawn).
fn md_table(t: &Table) -> String {
    if t.header.is_empty() {
        return String::new();
    }
    let cell = |c: &str| c.replace('|', "\\|");
    let mut s = format!(
        "| {} |\n|{}\n",
        t.header
            .iter()
            .map(|h| cell(h))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(t.header.len())
    );
    for row in &t.rows {
        let _ = writeln!(
            s,
            "| {} |",
            row.iter().map(|c| cell(c)).collect::<Vec<_>>().join(" | ")
        );
    }
    s
}

/// A table as CSV.
fn csv_table(t: &Table) -> String {
    let field = |c: &str| {
        if c.contains([',', '"', '\n']) {
            format!("\"{}\"", c.replace('"', "\"\""))
        } else {
            c.to_string()
        }
    };
    let mut s = String::new();
    for row in std::iter::once(&t.header).chain(&t.rows) {
        let _ = writeln!(
            s,
            "{}",
            row.iter().map(|c| field(c)).collect::<Vec<_>>().join(",")
        );
    }
    s
}

impl Page {
    /// The page as HTML.
    pub fn html(&self) -> String {
        let mut s = format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
             <title>{}</title>\n<style>\n\
             body {{ font-family: sans-serif; max-width: 1100px; margin: 2em auto; \
             padding: 0 1em; color: #222; }}\n\
             img {{ max-width: 100%; border: 1px solid #ddd; margin: 0.5em 0; }}\n\
             table {{ border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.9em; }}\n\
             th, td {{ border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: right; }}\n\
             th {{ background: #eee; }}\n\
             td:first-child, th:first-child {{ text-align: left; }}\n\
             code {{ background: #f4f4f4; padding: 0 0.2em; }}\n\
             </style>\n</head>\n<body>\n<h1>{}</h1>\n",
            esc(&self.title),
            esc(&self.title)
        );
        for p in &self.intro {
            let _ = writeln!(s, "<p>{}</p>", inline_html(p));
        }
        s.push_str("<ul>\n");
        for f in &self.figures {
            let _ = writeln!(s, "<li><a href=\"#{}\">{}</a></li>", f.id, esc(&f.title));
        }
        for (i, (heading, _, _)) in self.tables.iter().enumerate() {
            let _ = writeln!(s, "<li><a href=\"#table{i}\">{}</a></li>", esc(heading));
        }
        s.push_str("</ul>\n");
        for f in &self.figures {
            let _ = writeln!(s, "<h2 id=\"{}\">{}</h2>", f.id, esc(&f.title));
            let _ = writeln!(s, "<p>{}</p>", inline_html(&f.caption));
            for img in &f.images {
                let _ = writeln!(
                    s,
                    "<a href=\"{img}.png\"><img src=\"{img}.svg\" alt=\"{}\"></a>",
                    esc(&f.title)
                );
            }
            s.push_str(&html_table(&f.table));
        }
        for (i, (heading, text, table)) in self.tables.iter().enumerate() {
            let _ = writeln!(s, "<h2 id=\"table{i}\">{}</h2>", esc(heading));
            let _ = writeln!(s, "<p>{}</p>", inline_html(text));
            s.push_str(&html_table(table));
        }
        s.push_str("</body>\n</html>\n");
        s
    }

    /// The page as Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!("# {}\n\n", self.title);
        for p in &self.intro {
            let _ = writeln!(s, "{p}\n");
        }
        for f in &self.figures {
            let _ = writeln!(s, "## {}\n\n{}\n", f.title, f.caption);
            for img in &f.images {
                let _ = writeln!(s, "![{}]({img}.png)\n", f.title);
            }
            s.push_str(&md_table(&f.table));
            s.push('\n');
        }
        for (heading, text, table) in &self.tables {
            let _ = writeln!(s, "## {heading}\n\n{text}\n");
            s.push_str(&md_table(table));
            s.push('\n');
        }
        s
    }

    /// Writes `index.html`, `index.md` and `tables/<id>.csv` into `out` (the figures' images
    /// are already there).
    pub fn write(&self, out: &Path) -> anyhow::Result<()> {
        let tables = out.join("tables");
        std::fs::create_dir_all(&tables)
            .with_context(|| format!("creating {}", tables.display()))?;
        for f in &self.figures {
            let path = tables.join(format!("{}.csv", f.id));
            write_atomic(&path, csv_table(&f.table).as_bytes()).map_err(anyhow::Error::msg)?;
        }
        for (i, (_, _, table)) in self.tables.iter().enumerate() {
            let path = tables.join(format!("table{i}.csv"));
            write_atomic(&path, csv_table(table).as_bytes()).map_err(anyhow::Error::msg)?;
        }
        write_atomic(&out.join("index.html"), self.html().as_bytes())
            .map_err(anyhow::Error::msg)?;
        write_atomic(&out.join("index.md"), self.markdown().as_bytes())
            .map_err(anyhow::Error::msg)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_escape_their_cells_in_every_format() {
        let t = Table {
            header: vec!["scene".into(), "a|b".into()],
            rows: vec![vec!["<x>".into(), "1,5".into()]],
        };
        assert!(html_table(&t).contains("<td>&lt;x&gt;</td>"));
        assert!(md_table(&t).contains("a\\|b"));
        assert_eq!(csv_table(&t), "scene,a|b\n<x>,\"1,5\"\n");
        assert_eq!(inline_html("use `a<b`"), "use <code>a&lt;b</code>");
    }
}
