//! Ray and hit CSV files: the input and output of `vtq trace` and of `vtq render --rays-out`.
//!
//! Rays: header `ox,oy,oz,dx,dy,dz,tmin,tmax`, one ray per line. Values are decimal floats;
//! `nan`, `inf` and `-inf` are accepted (such rays are invalid and reported as misses). Blank
//! lines are skipped. Hits: header `ray,hit,t,prim,u,v`; a miss is written `i,0,inf,-1,0,0`.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};

/// The header of a rays CSV file.
pub const RAYS_HEADER: &str = "ox,oy,oz,dx,dy,dz,tmin,tmax";
/// The header of a hits CSV file.
pub const HITS_HEADER: &str = "ray,hit,t,prim,u,v";

const COLUMNS: [&str; 8] = ["ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax"];

/// A CSV file could not be read or written; the message names the file (and line and column).
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    /// Opening, reading or writing the file failed.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        reason: String,
    },
    /// The first line is not the expected header.
    #[error("{path}:1: expected header '{expected}', found '{found}'")]
    Header {
        /// The file.
        path: String,
        /// The required header.
        expected: &'static str,
        /// The first line as read.
        found: String,
    },
    /// A row has the wrong number of fields.
    #[error("{path}:{line}: expected 8 comma-separated values, found {found}")]
    FieldCount {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// Fields found.
        found: usize,
    },
    /// A field is not a number.
    #[error("{path}:{line}: column {column} ({name}): '{value}' is not a number")]
    Value {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// 1-based column number.
        column: usize,
        /// Column name from the header.
        name: &'static str,
        /// The offending text.
        value: String,
    },
}

/// Parse rays CSV text; `path` is only used in error messages.
pub fn parse_rays(path: &str, reader: impl BufRead) -> Result<Vec<Ray>, CsvError> {
    let io = |e: std::io::Error| CsvError::Io {
        path: path.to_string(),
        reason: e.to_string(),
    };
    let mut lines = reader.lines();
    let header = lines.next().transpose().map_err(io)?.unwrap_or_default();
    let header_fields: Vec<&str> = header.trim().split(',').map(str::trim).collect();
    if header_fields != COLUMNS {
        return Err(CsvError::Header {
            path: path.to_string(),
            expected: RAYS_HEADER,
            found: header.trim().to_string(),
        });
    }
    let mut rays = Vec::new();
    for (i, line) in lines.enumerate() {
        let line = line.map_err(io)?;
        let line_no = i + 2;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != COLUMNS.len() {
            return Err(CsvError::FieldCount {
                path: path.to_string(),
                line: line_no,
                found: fields.len(),
            });
        }
        let mut v = [0.0f32; 8];
        for (c, text) in fields.iter().enumerate() {
            v[c] = text.parse::<f32>().map_err(|_| CsvError::Value {
                path: path.to_string(),
                line: line_no,
                column: c + 1,
                name: COLUMNS[c],
                value: text.to_string(),
            })?;
        }
        rays.push(Ray {
            origin: Vec3::new(v[0], v[1], v[2]),
            dir: Vec3::new(v[3], v[4], v[5]),
            tmin: v[6],
            tmax: v[7],
        });
    }
    Ok(rays)
}

/// Read a rays CSV file.
pub fn read_rays(path: &Path) -> Result<Vec<Ray>, CsvError> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|e| CsvError::Io {
        path: name.clone(),
        reason: e.to_string(),
    })?;
    parse_rays(&name, BufReader::new(file))
}

/// Write `rays` as CSV text (floats in shortest round-trip form, so reading gives the same bits;
/// a NaN is written `NaN` and reads back as a NaN, without its sign or payload).
pub fn format_rays(out: &mut impl Write, rays: &[Ray]) -> std::io::Result<()> {
    writeln!(out, "{RAYS_HEADER}")?;
    for r in rays {
        writeln!(
            out,
            "{},{},{},{},{},{},{},{}",
            r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax
        )?;
    }
    Ok(())
}

/// Write `hits` (one per ray, in ray order) as CSV text.
pub fn format_hits(out: &mut impl Write, hits: &[Option<Hit>]) -> std::io::Result<()> {
    writeln!(out, "{HITS_HEADER}")?;
    for (i, h) in hits.iter().enumerate() {
        match h {
            Some(h) => writeln!(out, "{i},1,{},{},{},{}", h.t, h.prim, h.u, h.v)?,
            None => writeln!(out, "{i},0,inf,-1,0,0")?,
        }
    }
    Ok(())
}

/// Create `path` and fill it with `write`, mapping I/O errors to [`CsvError::Io`].
fn write_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), CsvError> {
    let io = |e: std::io::Error| CsvError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    };
    let mut out = BufWriter::new(File::create(path).map_err(io)?);
    write(&mut out).map_err(io)?;
    out.flush().map_err(io)
}

/// Write a rays CSV file.
pub fn write_rays(path: &Path, rays: &[Ray]) -> Result<(), CsvError> {
    write_file(path, |out| format_rays(out, rays))
}

/// Write a hits CSV file.
pub fn write_hits(path: &Path, hits: &[Option<Hit>]) -> Result<(), CsvError> {
    write_file(path, |out| format_hits(out, hits))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Ray>, CsvError> {
        parse_rays("rays.csv", text.as_bytes())
    }

    #[test]
    fn rays_round_trip_bit_exactly() {
        let rays = vec![
            Ray::new(Vec3::new(0.1, -2.5, 1e-7), Vec3::new(1.0 / 3.0, 0.0, -1.0)),
            Ray {
                origin: Vec3::new(f32::NAN, 0.0, 0.0),
                dir: Vec3::new(f32::INFINITY, 1.0, f32::NEG_INFINITY),
                tmin: 0.0,
                tmax: f32::INFINITY,
            },
        ];
        let mut text = Vec::new();
        format_rays(&mut text, &rays).unwrap();
        let back = parse_rays("x", text.as_slice()).unwrap();
        assert_eq!(back[0], rays[0]);
        assert!(back[1].origin.x.is_nan());
        assert_eq!(back[1].dir.x, f32::INFINITY);
        assert_eq!(back[1].dir.z, f32::NEG_INFINITY);
        assert_eq!(back[1].tmax, f32::INFINITY);
        assert!(!back[1].is_valid());
    }

    #[test]
    fn negative_nan_reads_back_as_nan() {
        // Found by `vtq fuzz`: `-nan` parses to a NaN with the sign bit set, written as `NaN`.
        let rays = parse("ox,oy,oz,dx,dy,dz,tmin,tmax\n-nan,0,0,0,0,-1,0,1\n").unwrap();
        assert!(rays[0].origin.x.is_nan() && rays[0].origin.x.is_sign_negative());
        let mut text = Vec::new();
        format_rays(&mut text, &rays).unwrap();
        let back = parse_rays("x", text.as_slice()).unwrap();
        assert!(back[0].origin.x.is_nan() && !back[0].is_valid());
        assert_eq!(back[0].dir, rays[0].dir);
    }

    #[test]
    fn blank_lines_and_spaces_are_tolerated() {
        let rays = parse("ox, oy,oz,dx,dy,dz,tmin,tmax\n\n 0,0,0, 0,0,-1,0.001,1e4\n\n").unwrap();
        assert_eq!(rays.len(), 1);
        assert_eq!(rays[0].dir, Vec3::NEG_Z);
        assert_eq!(rays[0].tmax, 1e4);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let e =
            parse("ox,oy,oz,dx,dy,dz,tmin,tmax\n0,0,0,0,0,-1,0,1\n0,0,0,0,x,-1,0,1\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "rays.csv:3: column 5 (dy): 'x' is not a number"
        );
        let e = parse("ox,oy,oz,dx,dy,dz,tmin,tmax\n0,0,0,0,0,-1,0\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "rays.csv:2: expected 8 comma-separated values, found 7"
        );
        let e = parse("x,y,z\n").unwrap_err();
        assert!(e.to_string().starts_with("rays.csv:1: expected header"));
        assert!(matches!(parse(""), Err(CsvError::Header { .. })));
    }

    #[test]
    fn hits_format() {
        let mut text = Vec::new();
        let hit = Hit {
            t: 2.5,
            prim: 7,
            u: 0.25,
            v: 0.5,
        };
        format_hits(&mut text, &[Some(hit), None]).unwrap();
        assert_eq!(
            String::from_utf8(text).unwrap(),
            "ray,hit,t,prim,u,v\n0,1,2.5,7,0.25,0.5\n1,0,inf,-1,0,0\n"
        );
    }
}
