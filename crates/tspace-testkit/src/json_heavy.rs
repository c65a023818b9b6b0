//! A JSON-heavy scene: many one-triangle primitives, each with its own accessors and buffer
//! views, so that the document, not the geometry, is most of the file (issue 20's "50,000
//! one-triangle primitives, 18.9 MB"). What it measures is tspace's cost per primitive.
//!
//! The design decision: a GLB with all primitives in one mesh, under one node. Every primitive
//! has its own POSITION (with min/max), NORMAL, TEXCOORD_0 and u16 indices, each accessor in a
//! buffer view of its own, and shares the one normal-mapped material, so every primitive is a
//! computation of its own. One mesh, rather than a mesh and a node per primitive, keeps the
//! file to what the primitives themselves need: about 610 bytes of JSON and 104 of BIN each,
//! so 50,000 primitives make 35.7 MB. That is more than the 18.9 MB, whose file must
//! have shared buffer views or had fewer accessors per primitive: four accessors and four
//! views each cannot be written in 378 bytes. A `.gltf` with its `.bin` beside it would hold
//! the same bytes in two files, so GLB it is: one file to measure, and the body the service
//! receives.

use crate::glb_builder::{Builder, normal_mapped, texture_stub};
use serde_json::{Value, json};

/// Triangles per row of the layout, so that positions (and their min/max) differ.
const ROW: usize = 250;

/// The scene with `primitives` one-triangle primitives, as a GLB.
pub fn json_heavy(primitives: usize) -> Vec<u8> {
    scene(primitives, true)
}

/// [`json_heavy`] without NORMAL: tspace then adds a NORMAL accessor beside each TANGENT, so
/// the output's document grows the most per primitive.
pub fn json_heavy_without_normals(primitives: usize) -> Vec<u8> {
    scene(primitives, false)
}

/// The other kind of JSON-heavy scene: `primitives` primitives that all name the same accessors
/// (one triangle with POSITION, NORMAL, TEXCOORD_0 and indices), as an exporter writes a
/// mesh instanced by reference. There is one computation, so what it measures is the cost of
/// a primitive's entry in the document, the report and the edits alone: about 60 bytes of JSON
/// each, against the 610 of [`json_heavy`].
pub fn json_heavy_shared(primitives: usize) -> Vec<u8> {
    let mut b = Builder::default();
    let primitive = triangle(&mut b, 0, true);
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"name": "json-heavy-shared", "primitives": vec![primitive; primitives]}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    b.glb(doc)
}

fn scene(primitives: usize, normals: bool) -> Vec<u8> {
    let mut b = Builder::default();
    let list: Vec<Value> = (0..primitives)
        .map(|i| triangle(&mut b, i, normals))
        .collect();
    let mut doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"name": "json-heavy", "primitives": list}],
        "materials": normal_mapped(0),
    });
    texture_stub(&mut doc);
    b.glb(doc)
}

/// Primitive `i`: a right triangle at its own place in a grid, facing +Z.
fn triangle(b: &mut Builder, i: usize, normals: bool) -> Value {
    let (x, y) = ((i % ROW) as f32, (i / ROW) as f32);
    let position = b.floats(&[x, y, 0., x + 1., y, 0., x, y + 1., 0.], "VEC3", true);
    let mut attributes = json!({"POSITION": position});
    if normals {
        attributes["NORMAL"] = b
            .floats(&[0., 0., 1., 0., 0., 1., 0., 0., 1.], "VEC3", false)
            .into();
    }
    attributes["TEXCOORD_0"] = b.floats(&[0., 0., 1., 0., 0., 1.], "VEC2", false).into();
    let indices = b.indices(&[0, 1, 2]);
    json!({"attributes": attributes, "indices": indices, "material": 0})
}
