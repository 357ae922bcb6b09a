//! How the materials of mesh files map to the renderer's four materials.
//!
//! **MTL** (`map_mtl`), in this order:
//! 1. `Ke` with any component > 0 → emissive, `emit = Ke`, one-sided;
//! 2. in the full mapping only: `d < 1` (or `Tr > 0`), or `illum` 4, 6 or 7 (the
//!    transparency/refraction illumination models) → dielectric with `ior = Ni` (1.5 if
//!    missing or ≤ 0);
//! 3. in the full mapping only: `illum` 3 (ray-traced reflection), or `Ks` brighter than `Kd`
//!    → metal with `albedo = Ks` and `fuzz = sqrt(2 / (Ns + 2))` (the roughness of a Blinn–Phong
//!    lobe of exponent `Ns`, Walter et al. 2007's conversion);
//! 4. otherwise Lambertian with `albedo = Kd` (0.7 grey when `Kd` is missing).
//!
//! The *reference* mapping (rules 1 and 4 only) is what `shared/reference` uses for its
//! `obj_mtl` objects, and what scene files get unless they ask for `"mtl_mapping": "full"`.
//!
//! **glTF** (`map_gltf`): emissive factor × strength > 0 → emissive; transmission ≥ 0.5 →
//! dielectric (`KHR_materials_ior`, 1.5 by default); metallic ≥ 0.5 → metal with `albedo` =
//! base colour and `fuzz` = roughness; otherwise Lambertian with `albedo` = base colour.

use crate::load::{GltfMaterial, MtlEntry, SourceMaterial};
use crate::material::Material;
use glam::Vec3;

/// Which MTL keys are honoured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MtlMapping {
    /// `Kd` and `Ke` only, as the reference renders do.
    #[default]
    Reference,
    /// Also `Ks`/`Ns` (metal), `Ni`/`d`/`illum` (dielectric).
    Full,
}

const DEFAULT_ALBEDO: Vec3 = Vec3::splat(0.7);

pub fn map_source_material(source: &SourceMaterial, mapping: MtlMapping) -> Material {
    match source {
        SourceMaterial::None => Material::Lambertian { albedo: DEFAULT_ALBEDO },
        SourceMaterial::Mtl(m) => map_mtl(m, mapping),
        SourceMaterial::Gltf(g) => map_gltf(g),
    }
}

pub fn map_mtl(m: &MtlEntry, mapping: MtlMapping) -> Material {
    let kd = m.kd.map(Vec3::from).unwrap_or(DEFAULT_ALBEDO);
    if let Some(ke) = m.ke.map(Vec3::from).filter(|ke| ke.max_element() > 0.0) {
        return Material::Emissive { emit: ke, two_sided: false };
    }
    if mapping == MtlMapping::Full {
        let illum = m.illum.unwrap_or(2);
        let transparent = m.d.is_some_and(|d| d < 1.0) || matches!(illum, 4 | 6 | 7);
        if transparent {
            let ior = m.ni.filter(|&n| n > 0.0).unwrap_or(1.5);
            return Material::Dielectric { ior };
        }
        let ks = m.ks.map(Vec3::from).unwrap_or(Vec3::ZERO);
        if illum == 3 || ks.max_element() > kd.max_element() {
            let ns = m.ns.unwrap_or(0.0).max(0.0);
            let fuzz = (2.0 / (ns + 2.0)).sqrt();
            return Material::Metal { albedo: ks, fuzz, fuzz_in_sphere: false };
        }
    }
    Material::Lambertian { albedo: kd }
}

pub fn map_gltf(g: &GltfMaterial) -> Material {
    let base = Vec3::from(g.base_color);
    let emit = Vec3::from(g.emissive);
    if emit.max_element() > 0.0 {
        Material::Emissive { emit, two_sided: false }
    } else if g.transmission >= 0.5 {
        Material::Dielectric { ior: g.ior }
    } else if g.metallic >= 0.5 {
        Material::Metal { albedo: base, fuzz: g.roughness.clamp(0.0, 1.0), fuzz_in_sphere: false }
    } else {
        Material::Lambertian { albedo: base }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mtl_rules() {
        let lamp = MtlEntry { kd: Some([0.5; 3]), ke: Some([17.0, 12.0, 4.0]), ..Default::default() };
        assert_eq!(
            map_mtl(&lamp, MtlMapping::Reference),
            Material::Emissive { emit: Vec3::new(17.0, 12.0, 4.0), two_sided: false }
        );
        let glass = MtlEntry { kd: Some([0.1; 3]), d: Some(0.3), ni: Some(1.33), ..Default::default() };
        assert_eq!(map_mtl(&glass, MtlMapping::Full), Material::Dielectric { ior: 1.33 });
        assert_eq!(map_mtl(&glass, MtlMapping::Reference), Material::Lambertian { albedo: Vec3::splat(0.1) });
        let shiny = MtlEntry { kd: Some([0.1; 3]), ks: Some([0.9; 3]), ns: Some(98.0), ..Default::default() };
        match map_mtl(&shiny, MtlMapping::Full) {
            Material::Metal { albedo, fuzz, .. } => {
                assert_eq!(albedo, Vec3::splat(0.9));
                assert!((fuzz - (0.02f32).sqrt()).abs() < 1e-6);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(map_mtl(&MtlEntry::default(), MtlMapping::Full), Material::Lambertian { albedo: DEFAULT_ALBEDO });
    }

    #[test]
    fn gltf_rules() {
        let base = GltfMaterial {
            base_color: [0.2, 0.3, 0.4],
            base_color_texture: None,
            metallic: 0.0,
            roughness: 0.5,
            emissive: [0.0; 3],
            transmission: 0.0,
            ior: 1.5,
            alpha_threshold: None,
        };
        assert_eq!(map_gltf(&base), Material::Lambertian { albedo: Vec3::new(0.2, 0.3, 0.4) });
        let metal = GltfMaterial { metallic: 1.0, ..base.clone() };
        assert!(matches!(map_gltf(&metal), Material::Metal { fuzz, .. } if fuzz == 0.5));
        let glass = GltfMaterial { transmission: 1.0, ior: 1.45, ..base.clone() };
        assert_eq!(map_gltf(&glass), Material::Dielectric { ior: 1.45 });
        let lamp = GltfMaterial { emissive: [2.0, 2.0, 2.0], ..base };
        assert!(map_gltf(&lamp).is_emissive());
    }
}
