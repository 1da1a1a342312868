//! [`Scene::content_hash`]: a blake3 hash of everything a simulation reads from a scene, the
//! scene's part of a sweep result's key.

use glam::Vec3;

use super::{Material, Scene};

/// Version of what [`Scene::content_hash`] covers; bump it when a field is added.
const CONTENT_HASH_VERSION: u32 = 1;

/// Feeds the bit patterns of `v`'s components into `h`.
fn hash_vec3(h: &mut blake3::Hasher, v: Vec3) {
    for x in v.to_array() {
        h.update(&x.to_le_bytes());
    }
}

impl Scene {
    /// A blake3 hash of the scene's content: its name, the geometry (hashed as the BVH cache
    /// hashes it, [`hash_geometry`]), the triangles' and spheres' materials, the material
    /// table, the camera and the sky switch. Two scenes with the same hash render and simulate
    /// identically, so sweep results keyed by it are never stale after a scene file changes.
    pub fn content_hash(&self) -> blake3::Hash {
        let mut h = blake3::Hasher::new();
        h.update(b"vtq-scene-content");
        h.update(&CONTENT_HASH_VERSION.to_le_bytes());
        h.update(&(self.name.len() as u64).to_le_bytes());
        h.update(self.name.as_bytes());
        hash_geometry(&mut h, self);
        h.update(&(self.tri_material.len() as u64).to_le_bytes());
        for m in &self.tri_material {
            h.update(&m.to_le_bytes());
        }
        for s in &self.spheres {
            h.update(&s.material.to_le_bytes());
        }
        h.update(&(self.materials.len() as u64).to_le_bytes());
        for m in &self.materials {
            match *m {
                Material::Lambertian { albedo } => {
                    h.update(&[0]);
                    hash_vec3(&mut h, albedo);
                }
                Material::Metal { albedo, fuzz } => {
                    h.update(&[1]);
                    hash_vec3(&mut h, albedo);
                    h.update(&fuzz.to_le_bytes());
                }
                Material::Dielectric { ior } => {
                    h.update(&[2]);
                    h.update(&ior.to_le_bytes());
                }
                Material::Light { emit } => {
                    h.update(&[3]);
                    hash_vec3(&mut h, emit);
                }
            }
        }
        let c = &self.camera;
        for v in [c.eye, c.look_at, c.up] {
            hash_vec3(&mut h, v);
        }
        h.update(&c.fov_y_deg.to_le_bytes());
        h.update(&[u8::from(self.sky)]);
        h.finalize()
    }
}

/// Feeds the scene geometry a BVH is built from into `h`: vertex positions, triangles and
/// spheres (centres and radii), each list preceded by its length. Shared by the BVH cache key
/// (`bvh::cache`) and the scene content hash of the sweep result store.
pub fn hash_geometry(h: &mut blake3::Hasher, scene: &Scene) {
    h.update(&(scene.positions.len() as u64).to_le_bytes());
    for p in &scene.positions {
        for x in p.to_array() {
            h.update(&x.to_le_bytes());
        }
    }
    h.update(&(scene.triangles.len() as u64).to_le_bytes());
    for t in &scene.triangles {
        for i in t {
            h.update(&i.to_le_bytes());
        }
    }
    h.update(&(scene.spheres.len() as u64).to_le_bytes());
    for s in &scene.spheres {
        for x in s.center.to_array() {
            h.update(&x.to_le_bytes());
        }
        h.update(&s.radius.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use crate::model::scene::builtin::{cornell, wknd};
    use crate::model::scene::Material;

    #[test]
    fn equal_scenes_hash_equal_and_every_part_counts() {
        let base = cornell();
        let h = base.content_hash();
        assert_eq!(cornell().content_hash(), h);
        assert_ne!(wknd().content_hash(), h);
        let mut s = cornell();
        s.name = "other".into();
        assert_ne!(s.content_hash(), h, "name");
        let mut s = cornell();
        s.positions[0].x += 1e-3;
        assert_ne!(s.content_hash(), h, "geometry");
        let mut s = cornell();
        s.tri_material[0] += 1;
        assert_ne!(s.content_hash(), h, "triangle material");
        let mut s = cornell();
        s.materials[0] = Material::Dielectric { ior: 1.5 };
        assert_ne!(s.content_hash(), h, "material table");
        let mut s = cornell();
        s.camera.fov_y_deg += 1.0;
        assert_ne!(s.content_hash(), h, "camera");
        let mut s = cornell();
        s.sky = !s.sky;
        assert_ne!(s.content_hash(), h, "sky");
    }
}
