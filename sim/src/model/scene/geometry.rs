//! The accumulation of scene files (OBJ, glTF, PLY) into one world space: shared vertices,
//! triangles with their materials, and the counts of what the files held but vtq does not use.
//!
//! Each reader turns a file into a [`MeshPart`] (its own vertex numbering and material slots);
//! [`SceneGeometry::add_part`] appends it. Vertices are shared: every distinct position
//! (bit-exact) is stored once across all parts, in the order triangles first use them, and
//! vertices no kept triangle uses are not stored. Triangles with a non-finite corner are left
//! out and counted; degenerate (zero-area) triangles are kept (the BVH build leaves them out and
//! counts them). Materials are stored once per distinct value, material 0 being
//! [`Material::DEFAULT`].

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::text::StatementCounts;
use super::{Material, SceneError};

/// The material slot of a triangle without a material (it gets [`Material::DEFAULT`]).
pub const NO_MATERIAL: u32 = u32::MAX;

/// The triangles of one file in its own vertex numbering, ready to be appended to a
/// [`SceneGeometry`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshPart {
    /// Vertex positions, possibly non-finite.
    pub vertices: Vec<Vec3>,
    /// Triangles as indices into `vertices` (every index must be in range).
    pub triangles: Vec<[u32; 3]>,
    /// Material slot of each triangle: an index into `materials`, or [`NO_MATERIAL`].
    pub tri_slot: Vec<u32>,
    /// The file's materials, used or not.
    pub materials: Vec<Material>,
    /// Number of vertices whose position is not finite.
    pub nonfinite_vertices: u64,
}

/// Triangles, shared vertices and materials accumulated from scene files into one world space,
/// with the counts of what was read but not used or left out.
#[derive(Debug, Clone)]
pub struct SceneGeometry {
    /// Shared vertex positions: each distinct position once, only positions a triangle uses.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`, in load order.
    pub triangles: Vec<[u32; 3]>,
    /// Material index (into `materials`) of each triangle.
    pub tri_material: Vec<u32>,
    /// Distinct materials; index 0 is [`Material::DEFAULT`].
    pub materials: Vec<Material>,
    /// Material libraries named by `mtllib` that do not exist, once each, in the order met
    /// (their faces use the default material). Loading does not print; the caller decides how
    /// to warn.
    pub missing_mtl: Vec<PathBuf>,
    /// Names that `usemtl` selected but no loaded library defined, once each, in order met.
    pub undefined_materials: Vec<String>,
    /// OBJ statements read but not used, by keyword.
    pub ignored: StatementCounts,
    /// MTL statements read but not used, by keyword (each library file counted once).
    pub mtl_ignored: StatementCounts,
    /// glTF content read but not used (textures, other primitive modes, ...), by kind.
    pub gltf_ignored: StatementCounts,
    /// PLY properties and elements read but not used (colours, normals, ...), by kind.
    pub ply_ignored: StatementCounts,
    /// Vertices whose position is not finite.
    pub nonfinite_vertices: u64,
    /// Triangles left out because a corner's position is not finite.
    pub nonfinite_triangles: u64,
    /// Position bit patterns to vertex ids, for sharing.
    vertex_ids: HashMap<[u32; 3], u32>,
    /// Material values (see [`material_key`]) to their index in `materials`.
    material_ids: HashMap<[u32; 5], u32>,
    /// The entries of `missing_mtl` and `undefined_materials`, for finding them fast.
    reported: (HashSet<PathBuf>, HashSet<String>),
}

impl Default for SceneGeometry {
    fn default() -> Self {
        SceneGeometry::new()
    }
}

impl SceneGeometry {
    /// Empty geometry with only the default material.
    pub fn new() -> Self {
        SceneGeometry {
            positions: Vec::new(),
            triangles: Vec::new(),
            tri_material: Vec::new(),
            materials: vec![Material::DEFAULT],
            missing_mtl: Vec::new(),
            undefined_materials: Vec::new(),
            ignored: StatementCounts::default(),
            mtl_ignored: StatementCounts::default(),
            gltf_ignored: StatementCounts::default(),
            ply_ignored: StatementCounts::default(),
            nonfinite_vertices: 0,
            nonfinite_triangles: 0,
            vertex_ids: HashMap::new(),
            material_ids: HashMap::from([(material_key(&Material::DEFAULT), 0)]),
            reported: (HashSet::new(), HashSet::new()),
        }
    }

    /// Append `part`, read from the file `origin` (named in errors), and return the number of
    /// triangles it added. Triangles with a non-finite corner are left out and counted, as are
    /// the part's non-finite vertices. On error (more than 2^32 distinct vertices, or a triangle
    /// indexing a vertex out of range) nothing is appended.
    pub fn add_part(&mut self, part: &MeshPart, origin: &Path) -> Result<usize, SceneError> {
        let mark = (
            self.positions.len(),
            self.triangles.len(),
            self.materials.len(),
        );
        match self.add_geometry(part, origin) {
            Ok(left_out) => {
                self.nonfinite_triangles += left_out;
                self.nonfinite_vertices += part.nonfinite_vertices;
                Ok(self.triangles.len() - mark.1)
            }
            Err(err) => {
                for p in self.positions.drain(mark.0..) {
                    self.vertex_ids
                        .remove(&[p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]);
                }
                self.triangles.truncate(mark.1);
                self.tri_material.truncate(mark.1);
                for m in self.materials.drain(mark.2..) {
                    self.material_ids.remove(&material_key(&m));
                }
                Err(err)
            }
        }
    }

    /// Record a material library that does not exist (once per path).
    pub fn note_missing_library(&mut self, path: PathBuf) {
        if self.reported.0.insert(path.clone()) {
            self.missing_mtl.push(path);
        }
    }

    /// Record a material name that no library defines (once per name).
    pub fn note_undefined_material(&mut self, name: String) {
        if self.reported.1.insert(name.clone()) {
            self.undefined_materials.push(name);
        }
    }

    /// Append the materials and the finite triangles of `part`; returns how many triangles
    /// were left out for a non-finite corner.
    fn add_geometry(&mut self, part: &MeshPart, origin: &Path) -> Result<u64, SceneError> {
        let fail = |reason: String| SceneError::Parse {
            path: origin.display().to_string(),
            reason,
        };
        let material_ids: Vec<u32> = part
            .materials
            .iter()
            .map(|&m| self.intern_material(m))
            .collect();
        let mut left_out = 0;
        self.triangles.reserve(part.triangles.len());
        self.tri_material.reserve(part.triangles.len());
        for (tri, &slot) in part.triangles.iter().zip(&part.tri_slot) {
            let mut corners = [Vec3::ZERO; 3];
            for (corner, &v) in corners.iter_mut().zip(tri) {
                *corner = *part.vertices.get(v as usize).ok_or_else(|| {
                    fail(format!(
                        "a triangle indexes vertex {v} of {}",
                        part.vertices.len()
                    ))
                })?;
            }
            if !corners.iter().all(|p| p.is_finite()) {
                left_out += 1;
                continue;
            }
            let mut ids = [0; 3];
            for (id, p) in ids.iter_mut().zip(corners) {
                *id = self
                    .vertex_id(p)
                    .ok_or_else(|| fail("more than 2^32 distinct vertices".into()))?;
            }
            self.triangles.push(ids);
            self.tri_material
                .push(material_ids.get(slot as usize).copied().unwrap_or(0));
        }
        Ok(left_out)
    }

    /// The id of `p`, adding it if it is new (`None` when there are 2^32 already).
    fn vertex_id(&mut self, p: Vec3) -> Option<u32> {
        let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        if let Some(&id) = self.vertex_ids.get(&key) {
            return Some(id);
        }
        let id = u32::try_from(self.positions.len()).ok()?;
        self.positions.push(p);
        self.vertex_ids.insert(key, id);
        Some(id)
    }

    /// The index of `m` in `materials`, adding it if it is new.
    fn intern_material(&mut self, m: Material) -> u32 {
        let next = self.materials.len() as u32;
        let id = *self.material_ids.entry(material_key(&m)).or_insert(next);
        if id == next {
            self.materials.push(m);
        }
        id
    }
}

/// A material's kind and parameters as bits, equal exactly when the materials compare equal
/// (`-0` counts as `0`; parameters are finite).
fn material_key(m: &Material) -> [u32; 5] {
    let bits = |x: f32| (x + 0.0).to_bits();
    match *m {
        Material::Lambertian { albedo } => [0, bits(albedo.x), bits(albedo.y), bits(albedo.z), 0],
        Material::Metal { albedo, fuzz } => [
            1,
            bits(albedo.x),
            bits(albedo.y),
            bits(albedo.z),
            bits(fuzz),
        ],
        Material::Dielectric { ior } => [2, bits(ior), 0, 0, 0],
        Material::Light { emit } => [3, bits(emit.x), bits(emit.y), bits(emit.z), 0],
    }
}

/// The bytes of the regular file at `path` ([`SceneError::Io`] if it cannot be read or is not a
/// regular file: a device or pipe would never end).
pub fn read_regular_file(path: &Path) -> Result<Vec<u8>, SceneError> {
    let io = |reason: String| SceneError::Io {
        path: path.display().to_string(),
        reason,
    };
    let meta = std::fs::metadata(path).map_err(|e| io(e.to_string()))?;
    if !meta.is_file() {
        return Err(io("not a regular file".into()));
    }
    std::fs::read(path).map_err(|e| io(e.to_string()))
}
