//! The largest meshes of the shared test corpus, read with the `gltf` crate.
//!
//! Only geometry is read: all triangle primitives with NORMAL and TEXCOORD_0 are concatenated
//! into one indexed mesh (node transforms are ignored, they do not change the work).

use super::contenders::{BenchMesh, Family};
use std::fs;
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
    let bytes = fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    // Validation would reject files that *require* an extension this crate does not know
    // (SheenCloth requires KHR_texture_transform), which does not matter for geometry.
    let mut document = gltf::Gltf::from_slice_without_validation(&bytes)
        .map_err(|e| format!("cannot parse {}: {e}", path.display()))?;
    let mut blob = document.blob.take();
    let folder = path.parent().unwrap_or(Path::new("."));

    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in document.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob
                .take()
                .ok_or_else(|| format!("{}: GLB without a BIN chunk", path.display()))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                return Err(format!(
                    "{}: data-URI buffers are not read by the bench",
                    path.display()
                ));
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = folder.join(uri);
                fs::read(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))?
            }
        };
        buffers.push(data);
    }

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
    for primitive in document.meshes().flat_map(|m| m.primitives()) {
        if primitive.mode() != gltf::mesh::Mode::Triangles {
            continue;
        }
        let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let (Some(positions), Some(normals), Some(uvs)) = (
            reader.read_positions(),
            reader.read_normals(),
            reader.read_tex_coords(0),
        ) else {
            continue;
        };
        let base = mesh.positions.len();
        mesh.positions.extend(positions);
        mesh.normals.extend(normals);
        mesh.uvs.extend(uvs.into_f32());
        let end = mesh.positions.len();
        if mesh.normals.len() != end || mesh.uvs.len() != end {
            return Err(format!(
                "{}: attribute counts differ in a primitive",
                path.display()
            ));
        }
        let too_large = || format!("{}: more vertices than u32 indices", path.display());
        let base = u32::try_from(base).map_err(|_| too_large())?;
        let end = u32::try_from(end).map_err(|_| too_large())?;
        match reader.read_indices() {
            Some(indices) => {
                for i in indices.into_u32() {
                    mesh.indices
                        .push(i.checked_add(base).ok_or_else(too_large)?);
                }
            }
            None => mesh.indices.extend(base..end),
        }
    }
    if mesh.indices.is_empty() {
        return Err(format!(
            "{}: no triangle primitive with NORMAL and TEXCOORD_0",
            path.display()
        ));
    }
    Ok(mesh)
}
