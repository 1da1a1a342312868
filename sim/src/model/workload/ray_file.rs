//! Ray files: the input of the `rays` workload (`[workload]` `rays_file`), in either of two
//! forms, told apart by their first bytes:
//!
//! - CSV, as `vtq trace` reads and `vtq render --rays-out` writes ([`super::rays_csv`]): header
//!   `ox,oy,oz,dx,dy,dz,tmin,tmax`, optionally `,occlusion`;
//! - binary, compact and exact: the magic `VTQRAYS1`, the ray count as a little-endian `u64`,
//!   then per ray 33 bytes: the eight `f32`s (origin xyz, direction xyz, tmin, tmax) little
//!   endian, then a flags byte whose bit 0 marks an occlusion ray (the other bits must be 0).
//!
//! Errors name the file and the line (CSV) or the ray and byte offset (binary).

use std::path::Path;

use glam::Vec3;

use crate::model::geometry::Ray;
use crate::model::workload::kind::TraceRay;
use crate::model::workload::rays_csv::{format_rays, parse_rays, CsvError};

/// The first bytes of a binary ray file.
pub const MAGIC: &[u8; 8] = b"VTQRAYS1";

/// Bytes of one ray in a binary ray file.
pub const RECORD_BYTES: usize = 33;

/// Bytes before the first ray of a binary ray file (magic and count).
const HEADER_BYTES: usize = 16;

/// A ray file could not be read or written; the message names the file and the place.
#[derive(Debug, thiserror::Error)]
pub enum RayFileError {
    /// The CSV form is malformed (or could not be read).
    #[error(transparent)]
    Csv(#[from] CsvError),
    /// The binary form is malformed.
    #[error("{path}: {reason}")]
    Binary {
        /// The file.
        path: String,
        /// What is wrong, with the ray and byte offset.
        reason: String,
    },
    /// Reading or writing the file failed.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        reason: String,
    },
}

/// A ray file as loaded for the `rays` workload: its path (as configured) and its rays in file
/// order. Two are equal when their paths and rays' bits are.
#[derive(Debug, Clone)]
pub struct RaySet {
    /// The file, as `workload.rays_file` names it.
    pub path: String,
    /// Its rays, in file order.
    pub rays: Vec<TraceRay>,
}

impl RaySet {
    /// Reads the ray file at `path`.
    pub fn read(path: &str) -> Result<RaySet, RayFileError> {
        Ok(RaySet {
            path: path.to_string(),
            rays: read_ray_file(Path::new(path))?,
        })
    }
}

impl PartialEq for RaySet {
    fn eq(&self, other: &Self) -> bool {
        let bits = |t: &TraceRay| (t.ray.bits(), t.occlusion);
        self.path == other.path
            && self.rays.len() == other.rays.len()
            && self
                .rays
                .iter()
                .zip(&other.rays)
                .all(|(a, b)| bits(a) == bits(b))
    }
}

/// Parses a binary ray file's bytes; `path` names it in errors.
pub fn parse_binary(path: &str, bytes: &[u8]) -> Result<Vec<TraceRay>, RayFileError> {
    let bad = |reason: String| RayFileError::Binary {
        path: path.to_string(),
        reason,
    };
    if bytes.len() < HEADER_BYTES || &bytes[..8] != MAGIC {
        return Err(bad(format!(
            "not a binary ray file: it must start with {:?} and an 8-byte ray count",
            std::str::from_utf8(MAGIC).unwrap_or_default()
        )));
    }
    let mut count = [0u8; 8];
    count.copy_from_slice(&bytes[8..HEADER_BYTES]);
    let count = u64::from_le_bytes(count);
    let body = (bytes.len() - HEADER_BYTES) as u64;
    let expected = count.checked_mul(RECORD_BYTES as u64);
    if expected != Some(body) {
        return Err(bad(format!(
            "the header declares {count} rays ({RECORD_BYTES} bytes each) but {body} bytes of \
             rays follow ({} whole rays{})",
            body / RECORD_BYTES as u64,
            if body.is_multiple_of(RECORD_BYTES as u64) {
                String::new()
            } else {
                format!(", {} bytes over", body % RECORD_BYTES as u64)
            }
        )));
    }
    let mut rays = Vec::with_capacity(count as usize);
    for (i, rec) in bytes[HEADER_BYTES..].chunks_exact(RECORD_BYTES).enumerate() {
        let f = |k: usize| {
            let mut w = [0u8; 4];
            w.copy_from_slice(&rec[4 * k..4 * k + 4]);
            f32::from_le_bytes(w)
        };
        let flags = rec[32];
        if flags & !1 != 0 {
            return Err(bad(format!(
                "ray {i} (byte {}): flags 0x{flags:02x} set bits other than bit 0 (occlusion)",
                HEADER_BYTES + i * RECORD_BYTES + 32
            )));
        }
        let ray = Ray {
            origin: Vec3::new(f(0), f(1), f(2)),
            dir: Vec3::new(f(3), f(4), f(5)),
            tmin: f(6),
            tmax: f(7),
        };
        rays.push(TraceRay {
            ray,
            occlusion: flags & 1 == 1,
        });
    }
    Ok(rays)
}

/// The binary form of `rays` (bit exact, NaN payloads included).
pub fn format_binary(rays: &[TraceRay]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_BYTES + rays.len() * RECORD_BYTES);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(rays.len() as u64).to_le_bytes());
    for TraceRay { ray, occlusion } in rays {
        for w in ray.bits() {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out.push(u8::from(*occlusion));
    }
    out
}

/// Parses a ray file's bytes in whichever form they are (binary when they start with
/// [`MAGIC`], CSV otherwise); `path` names it in errors.
pub fn parse_ray_file(path: &str, bytes: &[u8]) -> Result<Vec<TraceRay>, RayFileError> {
    if bytes.starts_with(MAGIC) {
        parse_binary(path, bytes)
    } else {
        Ok(parse_rays(path, bytes)?)
    }
}

/// Reads a ray file in either form.
pub fn read_ray_file(path: &Path) -> Result<Vec<TraceRay>, RayFileError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| RayFileError::Io {
        path: name.clone(),
        reason: e.to_string(),
    })?;
    parse_ray_file(&name, &bytes)
}

/// Writes `rays` to `path`: binary when its extension is `.bin`, CSV otherwise.
pub fn write_ray_file(path: &Path, rays: &[TraceRay]) -> Result<(), RayFileError> {
    let bytes = if path.extension().is_some_and(|e| e == "bin") {
        format_binary(rays)
    } else {
        let mut text = Vec::new();
        format_rays(&mut text, rays).expect("writing to memory");
        text
    };
    std::fs::write(path, bytes).map_err(|e| RayFileError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rays() -> Vec<TraceRay> {
        let ray = Ray::new(Vec3::new(0.5, -1.0, 2.0), Vec3::new(0.0, 0.0, -1.0));
        let odd = Ray {
            origin: Vec3::new(f32::from_bits(0x7fc0_1234), 0.0, 0.0),
            dir: Vec3::new(f32::INFINITY, 1.0, 0.0),
            tmin: -0.0,
            tmax: f32::INFINITY,
        };
        vec![
            TraceRay {
                ray,
                occlusion: false,
            },
            TraceRay {
                ray: odd,
                occlusion: true,
            },
        ]
    }

    fn bits(r: &[TraceRay]) -> Vec<([u32; 8], bool)> {
        r.iter().map(|t| (t.ray.bits(), t.occlusion)).collect()
    }

    #[test]
    fn binary_round_trips_bit_exactly_and_is_told_from_csv() {
        let bytes = format_binary(&rays());
        assert_eq!(bytes.len(), 16 + 2 * 33);
        assert_eq!(
            bits(&parse_ray_file("r.bin", &bytes).unwrap()),
            bits(&rays())
        );
        let mut text = Vec::new();
        format_rays(&mut text, &rays()[..1]).unwrap();
        let csv = parse_ray_file("r.csv", &text).unwrap();
        assert_eq!(bits(&csv), bits(&rays()[..1]));
    }

    #[test]
    fn malformed_binary_files_are_errors_naming_the_place() {
        let good = format_binary(&rays());
        let err = |bytes: &[u8]| parse_binary("r.bin", bytes).unwrap_err().to_string();
        assert!(
            err(&good[..20]).contains("declares 2 rays"),
            "{}",
            err(&good[..20])
        );
        assert!(err(b"VTQRAYS1").starts_with("r.bin: not a binary ray file"));
        let mut flags = good.clone();
        flags[16 + 33 + 32] = 0x81;
        assert_eq!(
            err(&flags),
            "r.bin: ray 1 (byte 81): flags 0x81 set bits other than bit 0 (occlusion)"
        );
        let mut long = good.clone();
        long.push(0);
        assert!(err(&long).contains("1 bytes over"), "{}", err(&long));
        let mut huge = good;
        huge[8..16].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(err(&huge).contains("declares 18446744073709551615 rays"));
    }
}
