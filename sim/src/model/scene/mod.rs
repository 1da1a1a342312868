//! Scenes: triangle meshes and procedural spheres with materials and a camera, from a built-in
//! name, one scene file (`.obj`, `.gltf`, `.glb`, `.ply`), or a scene folder (see
//! `../shared/scenes/README.md` and `docs/scenes.md`).

use glam::Vec3;

/// A scene could not be loaded: the message names the file (or scene) and the problem.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file or folder does not exist or cannot be read.
    #[error("{path}: {reason}")]
    Io {
        /// The path that failed.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// A file exists but its contents are malformed.
    #[error("{path}: {reason}")]
    Parse {
        /// The file.
        path: String,
        /// What is wrong with it (with a line number where known).
        reason: String,
    },
    /// A scene name matched no built-in and no folder.
    #[error(
        "unknown scene '{0}': not a built-in, a scene file or a scene folder (run `vtq scenes`)"
    )]
    Unknown(String),
}

/// How a surface scatters light (LumiBench's materials).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// Diffuse: scatter along normal + random point in the unit sphere.
    Lambertian {
        /// Reflectance.
        albedo: Vec3,
    },
    /// Mirror-like: reflect, perturbed by `fuzz` x random point in the unit sphere.
    Metal {
        /// Reflectance.
        albedo: Vec3,
        /// Roughness, 0..=1.
        fuzz: f32,
    },
    /// Glass: Schlick-weighted reflection or refraction.
    Dielectric {
        /// Index of refraction.
        ior: f32,
    },
    /// Emitter: emits `emit`, does not scatter.
    Light {
        /// Emitted radiance.
        emit: Vec3,
    },
}

impl Material {
    /// Grey Lambertian, the material of faces without one.
    pub const DEFAULT: Material = Material::Lambertian {
        albedo: Vec3::splat(0.5),
    };
}

/// A procedural sphere (intersected analytically, never tessellated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius (> 0).
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Up vector.
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
}

/// A loaded scene. Triangle ids are global in load order (files sorted by name, faces in order,
/// polygons as fans); sphere `i` has global primitive id `triangles.len() + i`.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Short name (built-in name, file stem or manifest name).
    pub name: String,
    /// Shared vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of each triangle.
    pub tri_material: Vec<u32>,
    /// Procedural spheres.
    pub spheres: Vec<Sphere>,
    /// Materials; index 0 is always [`Material::DEFAULT`].
    pub materials: Vec<Material>,
    /// The camera.
    pub camera: Camera,
    /// Whether rays that miss see a sky gradient (else black).
    pub sky: bool,
}

impl Scene {
    /// Number of primitives (triangles + spheres).
    pub fn prim_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    /// The three vertices of triangle `i`.
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The sphere with global primitive id `prim`, if `prim` is a sphere.
    pub fn sphere_of(&self, prim: u32) -> Option<&Sphere> {
        (prim as usize)
            .checked_sub(self.triangles.len())
            .and_then(|i| self.spheres.get(i))
    }

    /// The material of global primitive `prim`.
    pub fn material_of(&self, prim: u32) -> &Material {
        let idx = match self.sphere_of(prim) {
            Some(s) => s.material,
            None => self.tri_material[prim as usize],
        };
        &self.materials[idx as usize]
    }
}

pub mod builtin;
pub mod city;
mod content_hash;
pub use content_hash::hash_geometry;
pub mod geometry;
pub mod gltf;
pub mod load;
pub mod manifest;
pub mod mtl;
pub mod obj;
pub mod ply;
pub mod report;
pub mod text;

impl Camera {
    /// Check that the camera defines a usable view: finite vectors, `eye != look_at`, `up` not
    /// parallel to the view direction, and a field of view in `(0, 180)` degrees. The error is a
    /// one-line description of the first problem found.
    pub fn check(&self) -> Result<(), String> {
        if !(self.eye.is_finite() && self.look_at.is_finite() && self.up.is_finite()) {
            return Err("eye, look_at and up must be finite".into());
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(format!(
                "fov_y_deg must be in (0, 180) degrees, got {}",
                self.fov_y_deg
            ));
        }
        let view = self.look_at - self.eye;
        if view == Vec3::ZERO {
            return Err("eye and look_at are the same point".into());
        }
        if view.cross(self.up).length_squared() <= f32::MIN_POSITIVE {
            return Err("up is zero or parallel to the view direction".into());
        }
        Ok(())
    }

    /// A camera that frames the box `[min, max]`: looking along -Z at the box centre from a
    /// distance at which the box's bounding sphere fills the 45-degree vertical field of view,
    /// with +Y up. Used for a `.obj` file or a folder without a `scene.toml`. Bounds so large
    /// that the plain sums overflow (coordinates near 1e19 and beyond) are framed with scaled
    /// arithmetic, so the camera stays finite for boxes up to about 1e37.
    pub fn framing(min: Vec3, max: Vec3) -> Camera {
        let fov_y_deg = 45.0_f32;
        let mut center = (min + max) * 0.5;
        if !center.is_finite() {
            center = min * 0.5 + max * 0.5;
        }
        let mut radius = (max - min).length() * 0.5;
        if !radius.is_finite() {
            let half = max * 0.5 - min * 0.5;
            let scale = half.abs().max_element();
            radius = scale * (half / scale).length();
        }
        let radius = if radius > 0.0 { radius } else { 1.0 };
        let distance = radius / (fov_y_deg.to_radians() * 0.5).sin();
        Camera {
            eye: center + Vec3::Z * distance,
            look_at: center,
            up: Vec3::Y,
            fov_y_deg,
        }
    }
}

impl Scene {
    /// The axis-aligned bounding box `(min, max)` of every triangle vertex and sphere, or `None`
    /// for a scene without primitives.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut min = Vec3::splat(f32::INFINITY);
        let mut max = Vec3::splat(f32::NEG_INFINITY);
        for tri in &self.triangles {
            for &v in tri {
                let p = self.positions[v as usize];
                min = min.min(p);
                max = max.max(p);
            }
        }
        for s in &self.spheres {
            min = min.min(s.center - Vec3::splat(s.radius));
            max = max.max(s.center + Vec3::splat(s.radius));
        }
        (self.prim_count() > 0).then_some((min, max))
    }

    /// Check the scene's invariants: material 0 is [`Material::DEFAULT`]; every triangle index,
    /// triangle material and sphere material is in range; vertex positions, sphere centres and
    /// material parameters are finite; radii are positive; the camera passes [`Camera::check`].
    /// The error is a [`SceneError::Parse`] naming the scene and the first problem found.
    pub fn validate(&self) -> Result<(), SceneError> {
        let fail = |reason: String| SceneError::Parse {
            path: format!("scene '{}'", self.name),
            reason,
        };
        if self.materials.first() != Some(&Material::DEFAULT) {
            return Err(fail("material 0 is not the default grey Lambertian".into()));
        }
        for (i, m) in self.materials.iter().enumerate() {
            let finite = match *m {
                Material::Lambertian { albedo } => albedo.is_finite(),
                Material::Metal { albedo, fuzz } => albedo.is_finite() && fuzz.is_finite(),
                Material::Dielectric { ior } => ior.is_finite() && ior > 0.0,
                Material::Light { emit } => emit.is_finite(),
            };
            if !finite {
                return Err(fail(format!(
                    "material {i} has a non-finite parameter: {m:?}"
                )));
            }
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(fail(format!("vertex {i} is not finite")));
        }
        if self.tri_material.len() != self.triangles.len() {
            return Err(fail(format!(
                "{} triangles but {} triangle materials",
                self.triangles.len(),
                self.tri_material.len()
            )));
        }
        let n_pos = self.positions.len();
        let n_mat = self.materials.len();
        for (i, (tri, &m)) in self.triangles.iter().zip(&self.tri_material).enumerate() {
            if tri.iter().any(|&v| v as usize >= n_pos) {
                return Err(fail(format!(
                    "triangle {i} indexes a vertex out of range ({n_pos} vertices)"
                )));
            }
            if m as usize >= n_mat {
                return Err(fail(format!("triangle {i} has material {m} of {n_mat}")));
            }
        }
        for (i, s) in self.spheres.iter().enumerate() {
            if !(s.center.is_finite() && s.radius.is_finite() && s.radius > 0.0) {
                return Err(fail(format!(
                    "sphere {i} needs a finite centre and a finite radius > 0"
                )));
            }
            if s.material as usize >= n_mat {
                return Err(fail(format!(
                    "sphere {i} has material {} of {n_mat}",
                    s.material
                )));
            }
        }
        if u32::try_from(self.prim_count()).is_err() {
            return Err(fail("more primitives than fit in a 32-bit id".into()));
        }
        self.camera
            .check()
            .map_err(|reason| fail(format!("camera: {reason}")))
    }
}
