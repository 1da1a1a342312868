//! Ray and hit CSV files: the input and output of `vtq trace`, of `vtq render --rays-out` and of
//! the `rays` workload (`[workload]` `rays_file`).
//!
//! Rays: header `ox,oy,oz,dx,dy,dz,tmin,tmax`, one ray per line, or with a ninth column
//! `occlusion` (`0` a closest-hit ray, `1` an occlusion ray: terminate on first hit). Values
//! are decimal floats; `nan`, `inf` and `-inf` are accepted (such rays are invalid and
//! reported as misses). Blank lines are skipped. Hits: header `ray,hit,t,prim,u,v`; a miss is
//! written `i,0,inf,-1,0,0`.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};
use crate::model::workload::kind::TraceRay;

/// The header of a rays CSV file.
pub const RAYS_HEADER: &str = "ox,oy,oz,dx,dy,dz,tmin,tmax";
/// The header of a rays CSV file with the occlusion column.
pub const RAYS_OCCLUSION_HEADER: &str = "ox,oy,oz,dx,dy,dz,tmin,tmax,occlusion";
/// The header of a hits CSV file.
pub const HITS_HEADER: &str = "ray,hit,t,prim,u,v";

const COLUMNS: [&str; 9] = [
    "ox",
    "oy",
    "oz",
    "dx",
    "dy",
    "dz",
    "tmin",
    "tmax",
    "occlusion",
];

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
    #[error("{path}:1: expected header '{expected}' (or with ',occlusion'), found '{found}'")]
    Header {
        /// The file.
        path: String,
        /// The required header.
        expected: &'static str,
        /// The first line as read.
        found: String,
    },
    /// A row has the wrong number of fields.
    #[error("{path}:{line}: expected {expected} comma-separated values, found {found}")]
    FieldCount {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// Fields the header names.
        expected: usize,
        /// Fields found.
        found: usize,
    },
    /// An occlusion field is not `0` or `1`.
    #[error("{path}:{line}: column 9 (occlusion): '{value}' is not 0 or 1")]
    Occlusion {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// The offending text.
        value: String,
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

/// Parse rays CSV text (each ray with its occlusion flag, `false` without the column); `path`
/// is only used in error messages.
pub fn parse_rays(path: &str, reader: impl BufRead) -> Result<Vec<TraceRay>, CsvError> {
    let io = |e: std::io::Error| CsvError::Io {
        path: path.to_string(),
        reason: e.to_string(),
    };
    let mut lines = reader.lines();
    let header = lines.next().transpose().map_err(io)?.unwrap_or_default();
    let header_fields: Vec<&str> = header.trim().split(',').map(str::trim).collect();
    let columns = header_fields.len();
    if header_fields != COLUMNS[..columns.min(9)] || columns < 8 {
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
        if fields.len() != columns {
            return Err(CsvError::FieldCount {
                path: path.to_string(),
                line: line_no,
                expected: columns,
                found: fields.len(),
            });
        }
        let occlusion = match fields.get(8) {
            None | Some(&"0") => false,
            Some(&"1") => true,
            Some(other) => {
                return Err(CsvError::Occlusion {
                    path: path.to_string(),
                    line: line_no,
                    value: other.to_string(),
                })
            }
        };
        let mut v = [0.0f32; 8];
        for (c, text) in fields.iter().take(8).enumerate() {
            v[c] = text.parse::<f32>().map_err(|_| CsvError::Value {
                path: path.to_string(),
                line: line_no,
                column: c + 1,
                name: COLUMNS[c],
                value: text.to_string(),
            })?;
        }
        let ray = Ray {
            origin: Vec3::new(v[0], v[1], v[2]),
            dir: Vec3::new(v[3], v[4], v[5]),
            tmin: v[6],
            tmax: v[7],
        };
        rays.push(TraceRay { ray, occlusion });
    }
    Ok(rays)
}

/// Read a rays CSV file.
pub fn read_rays(path: &Path) -> Result<Vec<TraceRay>, CsvError> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|e| CsvError::Io {
        path: name.clone(),
        reason: e.to_string(),
    })?;
    parse_rays(&name, BufReader::new(file))
}

/// Write `rays` as CSV text (floats in shortest round-trip form, so reading gives the same bits;
/// a NaN is written `NaN` and reads back as a NaN, without its sign or payload), with the
/// occlusion column if any ray is an occlusion ray.
pub fn format_rays(out: &mut impl Write, rays: &[TraceRay]) -> std::io::Result<()> {
    let flags = rays.iter().any(|r| r.occlusion);
    let header = if flags {
        RAYS_OCCLUSION_HEADER
    } else {
        RAYS_HEADER
    };
    writeln!(out, "{header}")?;
    for TraceRay { ray: r, occlusion } in rays {
        write!(
            out,
            "{},{},{},{},{},{},{},{}",
            r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax
        )?;
        if flags {
            write!(out, ",{}", u8::from(*occlusion))?;
        }
        writeln!(out)?;
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
pub fn write_rays(path: &Path, rays: &[TraceRay]) -> Result<(), CsvError> {
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
        parse_rays("rays.csv", text.as_bytes()).map(|r| r.iter().map(|t| t.ray).collect())
    }

    fn closest(rays: &[Ray]) -> Vec<TraceRay> {
        rays.iter()
            .map(|&ray| TraceRay {
                ray,
                occlusion: false,
            })
            .collect()
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
        format_rays(&mut text, &closest(&rays)).unwrap();
        assert!(text.starts_with(b"ox,oy,oz,dx,dy,dz,tmin,tmax\n"));
        let back: Vec<Ray> = parse_rays("x", text.as_slice())
            .unwrap()
            .iter()
            .map(|t| t.ray)
            .collect();
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
        format_rays(&mut text, &closest(&rays)).unwrap();
        let back = parse_rays("x", text.as_slice()).unwrap()[0].ray;
        assert!(back.origin.x.is_nan() && !back.is_valid());
        assert_eq!(back.dir, rays[0].dir);
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
    fn the_occlusion_column_is_optional_and_round_trips() {
        let text = "ox,oy,oz,dx,dy,dz,tmin,tmax,occlusion\n0,0,0,0,0,-1,0,1,1\n0,0,0,1,0,0,0,2,0\n";
        let rays = parse_rays("r.csv", text.as_bytes()).unwrap();
        assert_eq!(
            rays.iter().map(|r| r.occlusion).collect::<Vec<_>>(),
            [true, false]
        );
        let mut out = Vec::new();
        format_rays(&mut out, &rays).unwrap();
        assert_eq!(String::from_utf8(out).unwrap(), text);
        let e = parse_rays(
            "r.csv",
            "ox,oy,oz,dx,dy,dz,tmin,tmax,occlusion\n0,0,0,0,0,-1,0,1,2\n".as_bytes(),
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "r.csv:2: column 9 (occlusion): '2' is not 0 or 1"
        );
        let e = parse_rays(
            "r.csv",
            "ox,oy,oz,dx,dy,dz,tmin,tmax,occlusion\n0,0,0,0,0,-1,0,1\n".as_bytes(),
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "r.csv:2: expected 9 comma-separated values, found 8"
        );
        let e = parse_rays("r.csv", "ox,oy,oz,dx,dy,dz,tmin,tmax,hit\n".as_bytes()).unwrap_err();
        assert!(matches!(e, CsvError::Header { .. }), "{e}");
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
