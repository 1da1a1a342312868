//! Wavefront MTL material libraries: the reader and the mapping of MTL parameters to vtq's
//! [`Material`]s.
//!
//! The reader takes the text as [`super::text::logical_lines`] gives it (UTF-8 byte-order mark,
//! CRLF and `\` continuations accepted). It reads `newmtl` (the name is the rest of the line) and
//! the parameters the mapping uses: `Kd`, `Ks`, `Ke` (one number for grey or three; a fourth and
//! later are ignored), `Ns`, `Ni`, `d` (an optional `-halo` is skipped), `Tr`, `Pm`, `Pr` (one
//! number) and `illum` (an integer 0-255). Their values must be finite numbers: anything else is
//! an error naming the file and line, as is a first word that is not a keyword. Every other
//! statement (`Ka`, `Tf`, `map_*`, `bump`, `disp`, `refl`, `Pc`, `aniso`, ...) is not used by
//! vtq: it is skipped and counted by keyword; a parameter vtq uses that comes before any
//! `newmtl` is counted as `<keyword> (before newmtl)`.
//!
//! MTL to [`Material`] mapping, first rule that applies:
//! 1. `Ke` with a component > 0: `Light { emit: Ke }`.
//! 2. `illum` 4, 6, 7 or 9 (transparent models), or a dissolve `d < 1` together with `Ni`:
//!    `Dielectric { ior: Ni }` (1.5 when `Ni` is absent or not > 0). Without `d`, `Tr` gives the
//!    dissolve as `1 - Tr` (the two are alternative spellings in the MTL format).
//! 3. `Pm >= 0.5` (the PBR "metallic" extension Blender writes): `Metal { albedo: Kd }`.
//! 4. `illum` 3 or 5 (mirror models), or `Ks` non-zero with `Ns >= 900` (a nearly mirror-sharp
//!    highlight): `Metal { albedo: Ks }`.
//! 5. Otherwise `Lambertian { albedo: Kd }`.
//!
//! A missing `Kd` is 0.5 grey (and a missing `Ks` in rule 4 falls back to `Kd`). Metal fuzz is
//! `Pr` (Blender's roughness) when present, else `1 - sqrt(Ns / 1000)` (the inverse of Blender's
//! `Ns = 1000 (1 - roughness)^2`), else 0; clamped to `[0, 1]`. `Ks 0.5` with `illum 2` and no
//! `Ns`, as Blender writes for plain diffuse surfaces, therefore stays Lambertian.

use std::path::Path;

use glam::Vec3;

use super::text::{is_keyword, line_error, logical_lines, statement, StatementCounts};
use super::{Material, SceneError};

/// One `newmtl` block: its name and the parameters the mapping reads (`None` when absent).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MtlMaterial {
    /// The name after `newmtl`.
    pub name: String,
    /// Diffuse colour `Kd`.
    pub kd: Option<Vec3>,
    /// Specular colour `Ks`.
    pub ks: Option<Vec3>,
    /// Emission `Ke`.
    pub ke: Option<Vec3>,
    /// Specular exponent `Ns`.
    pub ns: Option<f32>,
    /// Index of refraction `Ni`.
    pub ni: Option<f32>,
    /// Dissolve (opacity) `d`.
    pub d: Option<f32>,
    /// Transparency `Tr` (`1 - d`).
    pub tr: Option<f32>,
    /// PBR metallic `Pm`.
    pub pm: Option<f32>,
    /// PBR roughness `Pr`.
    pub pr: Option<f32>,
    /// Illumination model `illum`.
    pub illum: Option<u8>,
}

/// A parsed material library.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MtlLibrary {
    /// The materials in file order (a repeated name is kept; the later one wins by name).
    pub materials: Vec<MtlMaterial>,
    /// Statements read but not used, by keyword.
    pub ignored: StatementCounts,
}

/// Parse MTL text; `path` names the file in errors.
///
/// Errors ([`SceneError::Parse`], naming the file and line): a first word that is not a
/// keyword, a parameter vtq uses with a missing, malformed or non-finite number, or a colour
/// given as `spectral` or `xyz`.
pub fn parse_mtl(text: &str, path: &Path) -> Result<MtlLibrary, SceneError> {
    let mut library = MtlLibrary::default();
    for (number, line) in logical_lines(text) {
        let at_line = line_error(path, number);
        let line = line.trim();
        let Some((keyword, mut words)) = statement(line) else {
            continue;
        };
        if !is_keyword(keyword) {
            return Err(at_line(format!(
                "'{}' is not an MTL statement",
                preview(keyword)
            )));
        }
        if keyword == "newmtl" {
            library.materials.push(MtlMaterial {
                name: line[keyword.len()..].trim().to_string(),
                ..MtlMaterial::default()
            });
            continue;
        }
        if !USED.contains(&keyword) {
            library.ignored.add(keyword, 1);
            continue;
        }
        let Some(material) = library.materials.last_mut() else {
            library
                .ignored
                .add(&format!("{keyword} (before newmtl)"), 1);
            continue;
        };
        let number_of = |words: &mut std::str::SplitWhitespace<'_>| -> Result<f32, SceneError> {
            let word = words
                .next()
                .ok_or_else(|| at_line(format!("{keyword} needs a number")))?;
            finite(word, keyword).map_err(&at_line)
        };
        match keyword {
            "Kd" | "Ks" | "Ke" => {
                let colour = Some(colour(keyword, &mut words).map_err(&at_line)?);
                match keyword {
                    "Kd" => material.kd = colour,
                    "Ks" => material.ks = colour,
                    _ => material.ke = colour,
                }
            }
            "Ns" => material.ns = Some(number_of(&mut words)?),
            "Ni" => material.ni = Some(number_of(&mut words)?),
            "Tr" => material.tr = Some(number_of(&mut words)?),
            "Pm" => material.pm = Some(number_of(&mut words)?),
            "Pr" => material.pr = Some(number_of(&mut words)?),
            "d" => {
                if words.clone().next() == Some("-halo") {
                    words.next();
                }
                material.d = Some(number_of(&mut words)?);
            }
            _ => {
                // illum
                let word = words.next().unwrap_or("");
                material.illum = Some(word.parse::<u8>().map_err(|_| {
                    at_line(format!(
                        "illum needs an illumination model number 0-255, found '{}'",
                        preview(word)
                    ))
                })?);
            }
        }
    }
    Ok(library)
}

/// The parameters vtq reads (besides `newmtl`).
const USED: [&str; 10] = ["Kd", "Ks", "Ke", "Ns", "Ni", "d", "Tr", "Pm", "Pr", "illum"];

/// A colour: one number (grey) or three (further words ignored), finite.
fn colour<'a>(keyword: &str, words: &mut impl Iterator<Item = &'a str>) -> Result<Vec3, String> {
    let values: Vec<&str> = words.take(3).collect();
    if let Some(&form @ ("spectral" | "xyz")) = values.first() {
        return Err(format!(
            "{keyword} {form} colours are not supported; give r g b numbers"
        ));
    }
    let numbers = values
        .iter()
        .map(|w| finite(w, keyword))
        .collect::<Result<Vec<f32>, String>>()?;
    match numbers[..] {
        [grey] => Ok(Vec3::splat(grey)),
        [r, g, b] => Ok(Vec3::new(r, g, b)),
        _ => Err(format!(
            "{keyword} needs 1 or 3 numbers, found {}",
            numbers.len()
        )),
    }
}

/// Parse a finite `f32`, naming `what` on failure.
fn finite(word: &str, what: &str) -> Result<f32, String> {
    match word.parse::<f32>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(_) => Err(format!("{what} value '{}' is not finite", preview(word))),
        Err(_) => Err(format!("'{}' is not a number ({what})", preview(word))),
    }
}

/// `word` shortened to at most 40 characters for a message.
pub(crate) fn preview(word: &str) -> String {
    if word.chars().count() <= 40 {
        word.to_string()
    } else {
        format!("{}...", word.chars().take(40).collect::<String>())
    }
}

/// The [`Material`] of an MTL material, by the mapping in this module's documentation.
pub fn material_from_mtl(m: &MtlMaterial) -> Material {
    let kd = m.kd.unwrap_or(Vec3::splat(0.5));
    let ks = m.ks.unwrap_or(Vec3::ZERO);
    let ke = m.ke.unwrap_or(Vec3::ZERO);
    let fuzz = || {
        let f = match (m.pr, m.ns) {
            (Some(roughness), _) => roughness,
            (None, Some(ns)) => 1.0 - (ns.clamp(0.0, 1000.0) / 1000.0).sqrt(),
            (None, None) => 0.0,
        };
        f.clamp(0.0, 1.0)
    };

    if ke.max_element() > 0.0 {
        return Material::Light { emit: ke };
    }
    let transparent_model = matches!(m.illum, Some(4 | 6 | 7 | 9));
    let dissolve = m.d.or(m.tr.map(|tr| 1.0 - tr));
    let see_through = dissolve.is_some_and(|d| d < 1.0) && m.ni.is_some();
    if transparent_model || see_through {
        let ior = m.ni.filter(|&n| n > 0.0).unwrap_or(1.5);
        return Material::Dielectric { ior };
    }
    if m.pm.is_some_and(|pm| pm >= 0.5) {
        return Material::Metal {
            albedo: kd,
            fuzz: fuzz(),
        };
    }
    let sharp_highlight = ks != Vec3::ZERO && m.ns.is_some_and(|ns| ns >= 900.0);
    if matches!(m.illum, Some(3 | 5)) || sharp_highlight {
        let albedo = if ks != Vec3::ZERO { ks } else { kd };
        return Material::Metal {
            albedo,
            fuzz: fuzz(),
        };
    }
    Material::Lambertian { albedo: kd }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<MtlLibrary, String> {
        parse_mtl(text, Path::new("lib.mtl")).map_err(|e| e.to_string())
    }

    #[test]
    fn unused_statements_are_counted_not_read() {
        let lib = parse(
            "\u{FEFF}# Blender MTL\r\nKa 1 1 1\r\nnewmtl a b\r\nKa spectral x.rfl\r\nKd 0.8\r\n\
             map_Kd tex.png\r\nbump -bm 2 n.png\r\nTf 1 1 1\r\nmap_Kd t2.png\r\nd -halo 0.5\r\n",
        )
        .unwrap();
        assert_eq!(lib.materials.len(), 1);
        let m = &lib.materials[0];
        assert_eq!(m.name, "a b");
        assert_eq!(m.kd, Some(Vec3::splat(0.8)));
        assert_eq!(m.d, Some(0.5));
        assert_eq!(lib.ignored.to_string(), "Ka x2, map_Kd x2, bump x1, Tf x1");
    }

    #[test]
    fn parameters_before_newmtl_are_counted_under_their_own_name() {
        let lib = parse("Kd 1 0 0\nnewmtl x\n").unwrap();
        assert_eq!(lib.ignored.get("Kd (before newmtl)"), 1);
        assert_eq!(lib.materials[0].kd, None);
    }

    #[test]
    fn malformed_parameters_name_the_line() {
        for (text, needle) in [
            ("newmtl a\nKd 0.5 0.5\n", "line 2: Kd needs 1 or 3 numbers"),
            ("newmtl a\nKs 1 x 1\n", "line 2: 'x' is not a number (Ks)"),
            (
                "newmtl a\n\nNs nan\n",
                "line 3: Ns value 'nan' is not finite",
            ),
            ("newmtl a\nKe\n", "line 2: Ke needs 1 or 3 numbers, found 0"),
            ("newmtl a\nNi\n", "line 2: Ni needs a number"),
            ("newmtl a\nillum two\n", "line 2: illum needs"),
            ("newmtl a\nKd xyz 1 1 1\n", "not supported"),
            (
                "newmtl a\n\u{FFFD}\n",
                "line 2: '\u{FFFD}' is not an MTL statement",
            ),
        ] {
            let err = parse(text).unwrap_err();
            assert!(err.contains("lib.mtl") && err.contains(needle), "{err}");
        }
    }

    #[test]
    fn tr_is_the_complement_of_d() {
        let glass = MtlMaterial {
            tr: Some(0.9),
            ni: Some(1.33),
            ..MtlMaterial::default()
        };
        assert_eq!(
            material_from_mtl(&glass),
            Material::Dielectric { ior: 1.33 }
        );
        let opaque = MtlMaterial {
            d: Some(1.0),
            ..glass.clone()
        };
        assert!(matches!(
            material_from_mtl(&opaque),
            Material::Lambertian { .. }
        ));
        let tr_zero = MtlMaterial {
            tr: Some(0.0),
            ..glass
        };
        assert!(matches!(
            material_from_mtl(&tr_zero),
            Material::Lambertian { .. }
        ));
    }
}
