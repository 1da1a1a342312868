//! glTF materials mapped to vtq's [`Material`]s, first rule that applies:
//! 1. an emissive factor (times `KHR_materials_emissive_strength`) with a component > 0:
//!    `Light { emit }`;
//! 2. `KHR_materials_transmission` with a transmission factor >= 0.5: `Dielectric { ior }`, the
//!    index of refraction from `KHR_materials_ior` (1.5 when absent or not > 0);
//! 3. a metallic factor >= 0.5: `Metal { albedo: base colour, fuzz: roughness factor }`
//!    (roughness clamped to `[0, 1]`);
//! 4. otherwise `Lambertian { albedo: base colour }`,
//!
//! where the base colour is the RGB of `baseColorFactor` (its alpha is not used). The
//! thresholds are those of the MTL mapping (`Pm >= 0.5` is a metal). Primitives without a
//! material get vtq's default grey Lambertian, as OBJ faces without one do (glTF's own default
//! material is a rough white metal). Textures are not read: every texture a material names is
//! counted by its slot (`baseColorTexture`, `normalTexture`, ...), as are a non-opaque
//! `alphaMode` and a base colour alpha below 1.

use ::gltf::material::AlphaMode;
use glam::Vec3;

use crate::model::scene::text::StatementCounts;
use crate::model::scene::Material;

/// The [`Material`] of glTF material `m` by the mapping in this module's documentation, with
/// what it holds that vtq does not use counted in `ignored`. A non-finite factor (a number
/// beyond `f32` in the file) is an error naming the material.
pub fn material_from_gltf(
    m: &::gltf::Material<'_>,
    ignored: &mut StatementCounts,
) -> Result<Material, String> {
    let pbr = m.pbr_metallic_roughness();
    let textures = [
        ("baseColorTexture", pbr.base_color_texture().is_some()),
        (
            "metallicRoughnessTexture",
            pbr.metallic_roughness_texture().is_some(),
        ),
        ("normalTexture", m.normal_texture().is_some()),
        ("occlusionTexture", m.occlusion_texture().is_some()),
        ("emissiveTexture", m.emissive_texture().is_some()),
        (
            "transmissionTexture",
            m.transmission()
                .is_some_and(|t| t.transmission_texture().is_some()),
        ),
    ];
    for (slot, present) in textures {
        if present {
            ignored.add(slot, 1);
        }
    }
    match m.alpha_mode() {
        AlphaMode::Opaque => {}
        AlphaMode::Mask => ignored.add("alphaMode MASK", 1),
        AlphaMode::Blend => ignored.add("alphaMode BLEND", 1),
    }
    let [r, g, b, a] = pbr.base_color_factor();
    if a < 1.0 {
        ignored.add("baseColorFactor alpha", 1);
    }
    let base = Vec3::new(r, g, b);
    let emit = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
    let ior = m.ior().unwrap_or(1.5);
    let finite = base.is_finite()
        && emit.is_finite()
        && [transmission, metallic, roughness, ior]
            .iter()
            .all(|x| x.is_finite());
    if !finite {
        return Err(format!(
            "material {} has a factor that is not a finite number",
            m.index().map_or("(default)".into(), |i| i.to_string())
        ));
    }
    Ok(if emit.max_element() > 0.0 {
        Material::Light { emit }
    } else if transmission >= 0.5 {
        Material::Dielectric {
            ior: if ior > 0.0 { ior } else { 1.5 },
        }
    } else if metallic >= 0.5 {
        Material::Metal {
            albedo: base,
            fuzz: roughness.clamp(0.0, 1.0),
        }
    } else {
        Material::Lambertian { albedo: base }
    })
}
