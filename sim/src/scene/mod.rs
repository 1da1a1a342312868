//! Scenes: triangle meshes and procedural spheres with materials and a camera, from a built-in
//! name, one `.obj` file, or a scene folder (see `../shared/scenes/README.md`).

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
    #[error("unknown scene '{0}': not a built-in, a .obj file or a scene folder (run `vtq scenes`)")]
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
pub mod load;
pub mod manifest;
pub mod obj;
