//! The largest meshes of the shared test corpus, read with the test kit's glTF reader.
//!
//! Only geometry is read: all triangle primitives with normals and texture coordinates (the set
//! the normal map uses) are concatenated into one indexed mesh (node transforms are ignored,
//! they do not change the work).

use super::contenders::{BenchMesh, Family};
use std::path::Path;
/// Corpus files benchmarked, largest first, relative to the corpus folder.
pub const FILES: [(&str, &str); 4] = [
    ("SheenCloth", "gltf_SheenCloth_glb/SheenCloth.glb"),
    ("SciFiHelmet", "gltf_SciFiHelmet_no_images/SciFiHelmet.gltf"),
    (
        "DamagedHelmet",
        "gltf_DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
    ),
    (
        "NormalTangentTest",
        "gltf_NormalTangentTest/glTF-Binary/NormalTangentTest.glb",
    ),
];

/// Reads one file into a mesh; any problem is returned as text so the caller can skip it.
pub fn load(name: &str, path: &Path) -> Result<BenchMesh, String> {
    let mut mesh = BenchMesh {
        name: name.to_string(),
        family: Family::Corpus,
        nominal_triangles: None,
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
        exact_tangents: None,
    };
    for primitive in tspace_testkit::meshes::load_gltf(path)? {
        let (Some(normals), Some(uvs)) = (primitive.normals, primitive.uvs) else {
            continue;
        };
        let too_large = || format!("{}: more vertices than u32 indices", path.display());
        let base = u32::try_from(mesh.positions.len()).map_err(|_| too_large())?;
        mesh.positions.extend(primitive.positions);
        mesh.normals.extend(normals);
        mesh.uvs.extend(uvs);
        for i in primitive.indices {
            mesh.indices
                .push(i.checked_add(base).ok_or_else(too_large)?);
        }
    }
    if mesh.indices.is_empty() {
        return Err(format!(
            "{}: no triangle primitive with normals and texture coordinates",
            path.display()
        ));
    }
    Ok(mesh)
}
