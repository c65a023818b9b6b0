//! Mesh bytes: what a scene's geometry takes in its file, per primitive and in all, and how it is
//! compressed, so that the report can say what tspace did to a pipeline's sizes.
//!
//! A primitive's bytes are those of every buffer view its accessors (attributes, indices, morph
//! targets, sparse parts) and its Draco stream read, each view once; a meshopt-compressed view
//! counts at its compressed size, which is what the file holds. The scene's total counts each
//! view once, however many primitives share it. Images, animations and skins are not mesh bytes.

use super::draco;
use tspace_json::{Node, Text};

/// How a primitive's geometry is stored: the report's own type.
pub use crate::scene::report::MeshCompression as Compression;

/// One primitive's storage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveSize {
    pub compression: Compression,
    pub bytes: u64,
}

/// A document's mesh storage.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MeshSizes {
    /// Every primitive's, mesh by mesh in order: one flat list, since it is kept while the
    /// scene is written and a scene may have a hundred thousand primitives (a map took three
    /// times the room).
    primitives: Vec<PrimitiveSize>,
    /// Where each mesh's primitives start in `primitives`, and one past the last.
    mesh_starts: Vec<usize>,
    pub total: u64,
}

impl MeshSizes {
    /// Primitive `primitive` of mesh `mesh`.
    pub fn primitive(&self, (mesh, primitive): (usize, usize)) -> Option<&PrimitiveSize> {
        let start = *self.mesh_starts.get(mesh)?;
        let end = *self.mesh_starts.get(mesh + 1)?;
        self.primitives.get(start..end)?.get(primitive)
    }
}

/// Measures the mesh storage a document declares (lengths from the JSON; no bytes are read).
pub fn measure(root: &Node) -> MeshSizes {
    let views = array(root.get("bufferViews"));
    let accessors = array(root.get("accessors"));
    let meshes = array(root.get("meshes"));
    let count = meshes
        .iter()
        .map(|mesh| array(mesh.get("primitives")).len())
        .sum();
    let mut sizes = MeshSizes {
        primitives: Vec::with_capacity(count),
        mesh_starts: Vec::with_capacity(meshes.len() + 1),
        total: 0,
    };
    // Per view: whether some primitive reads it. A scene of 50,000 primitives measured each
    // one's views in sets and maps; flat lists do the same without the allocations.
    let mut read = vec![false; views.len()];
    let mut used = Vec::new();
    for mesh in meshes {
        sizes.mesh_starts.push(sizes.primitives.len());
        for primitive in array(mesh.get("primitives")) {
            primitive_views(accessors, primitive, &mut used);
            let meshopt = used.iter().any(|&v| meshopt_length(views.get(v)).is_some());
            let compression = if draco::extension(primitive).is_some() {
                Compression::Draco
            } else if meshopt {
                Compression::Meshopt
            } else {
                Compression::None
            };
            let bytes = used.iter().map(|&v| view_bytes(views.get(v))).sum();
            sizes.primitives.push(PrimitiveSize { compression, bytes });
            for &v in &used {
                if let Some(read) = read.get_mut(v) {
                    *read = true;
                }
            }
        }
    }
    sizes.mesh_starts.push(sizes.primitives.len());
    sizes.total = (views.iter().zip(&read))
        .filter(|&(_, &read)| read)
        .map(|(view, _)| view_bytes(Some(view)))
        .sum();
    sizes
}

/// The members [`measure`] reads, for [`tspace_json::parse_pruned`]: a document read only to be
/// measured (tspace's own output) then takes a fraction of its whole tree.
pub fn read_by_measure(path: &[Text], key: &str) -> bool {
    const MESHOPT: [&[u8]; 2] = [b"EXT_meshopt_compression", b"KHR_meshopt_compression"];
    const DRACO: &[u8] = draco::EXTENSION.as_bytes();
    // Steps as bytes: this is asked of every member of the output's kept objects, and reading
    // each step as a `str` checked it as UTF-8 again, a tenth of the parse.
    let mut steps: [&[u8]; 4] = [b""; 4];
    for (step, text) in steps.iter_mut().zip(path) {
        *step = text.as_bytes();
    }
    let key = key.as_bytes();
    match (path.len(), steps) {
        (0, _) => matches!(key, b"meshes" | b"accessors" | b"bufferViews"),
        (1, [b"meshes", ..]) => key == b"primitives",
        (2, [b"meshes", b"primitives", ..]) => {
            matches!(key, b"attributes" | b"targets" | b"indices" | b"extensions")
        }
        (3, [b"meshes", b"primitives", b"attributes" | b"targets", _]) => true,
        (3, [b"meshes", b"primitives", b"extensions", _]) => key == DRACO,
        (4, [b"meshes", b"primitives", b"extensions", name]) => {
            name == DRACO && key == b"bufferView"
        }
        (1, [b"accessors", ..]) => matches!(key, b"bufferView" | b"sparse"),
        (2, [b"accessors", b"sparse", ..]) => matches!(key, b"indices" | b"values"),
        (3, [b"accessors", b"sparse", b"indices" | b"values", _]) => key == b"bufferView",
        (1, [b"bufferViews", ..]) => matches!(key, b"byteLength" | b"extensions"),
        (2, [b"bufferViews", b"extensions", ..]) => MESHOPT.contains(&key),
        (3, [b"bufferViews", b"extensions", name, _]) => {
            MESHOPT.contains(&name) && key == b"byteLength"
        }
        _ => false,
    }
}

fn array(node: Option<&Node>) -> &[Node] {
    node.and_then(Node::as_array).unwrap_or(&[])
}

fn index(node: Option<&Node>) -> Option<usize> {
    node?.as_u64().and_then(|i| usize::try_from(i).ok())
}

/// The views a primitive reads, each once, into `views`: its accessors' (and their sparse
/// parts'), and its Draco stream's.
fn primitive_views(accessors: &[Node], primitive: &Node, views: &mut Vec<usize>) {
    views.clear();
    let mut add_accessor = |accessor: Option<&Node>| {
        let Some(accessor) = accessor else {
            return;
        };
        views.extend(index(accessor.get("bufferView")));
        if let Some(sparse) = accessor.get("sparse") {
            for part in ["indices", "values"] {
                views.extend(index(sparse.get(part).and_then(|p| p.get("bufferView"))));
            }
        }
    };
    let mut add_object = |object: Option<&Node>| {
        for member in object.and_then(Node::as_object).unwrap_or(&[]) {
            add_accessor(index(Some(&member.value)).and_then(|a| accessors.get(a)));
        }
    };
    add_object(primitive.get("attributes"));
    for target in array(primitive.get("targets")) {
        add_object(Some(target));
    }
    add_accessor(index(primitive.get("indices")).and_then(|a| accessors.get(a)));
    views.extend(index(
        draco::extension(primitive).and_then(|e| e.get("bufferView")),
    ));
    views.sort_unstable();
    views.dedup();
}

/// A meshopt-compressed view's compressed length.
fn meshopt_length(view: Option<&Node>) -> Option<u64> {
    let extensions = view?.get("extensions")?;
    ["EXT_meshopt_compression", "KHR_meshopt_compression"]
        .iter()
        .find_map(|name| extensions.get(name)?.get("byteLength")?.as_u64())
}

/// What a view takes in the file: its compressed length when meshopt-compressed.
fn view_bytes(view: Option<&Node>) -> u64 {
    meshopt_length(view)
        .or_else(|| view?.get("byteLength")?.as_u64())
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tspace_json::Document;

    #[test]
    fn shared_views_count_once_in_the_total_and_compressed_views_at_their_compressed_size() {
        let text = br#"{
            "bufferViews": [
                {"buffer": 0, "byteLength": 100},
                {"buffer": 1, "byteLength": 400, "extensions": {"EXT_meshopt_compression":
                    {"buffer": 0, "byteLength": 40, "byteStride": 4, "count": 100, "mode": "ATTRIBUTES"}}},
                {"buffer": 0, "byteLength": 7},
                {"buffer": 0, "byteLength": 1000},
                {"buffer": 0, "byteLength": 1},
                {"buffer": 0, "byteLength": 5}
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5126, "count": 1, "type": "VEC3"},
                {"componentType": 5126, "count": 1, "type": "VEC3"},
                {"componentType": 5126, "count": 1, "type": "VEC3", "sparse": {"count": 1,
                    "indices": {"bufferView": 4, "componentType": 5121},
                    "values": {"bufferView": 5}}}
            ],
            "meshes": [{"name": "m", "primitives": [
                {"attributes": {"POSITION": 0}, "material": 0},
                {"attributes": {"POSITION": 0, "NORMAL": 1}},
                {"attributes": {"POSITION": 2},
                 "extensions": {"KHR_draco_mesh_compression": {"bufferView": 2, "attributes": {"POSITION": 0}}}},
                {"attributes": {"POSITION": 0}, "targets": [{"POSITION": 3}], "indices": 2}
            ]}]
        }"#;
        let doc = Document::parse(text).unwrap();
        let sizes = measure(doc.root());
        let at = |p| *sizes.primitive((0, p)).unwrap();
        assert_eq!((at(0).compression, at(0).bytes), (Compression::None, 100));
        assert_eq!(
            (at(1).compression, at(1).bytes),
            (Compression::Meshopt, 140)
        );
        assert_eq!((at(2).compression, at(2).bytes), (Compression::Draco, 7));
        assert_eq!((at(3).compression, at(3).bytes), (Compression::None, 106));
        assert_eq!(sizes.primitive((0, 4)), None);
        assert_eq!(sizes.primitive((1, 0)), None);
        // View 3 is no mesh's.
        assert_eq!(sizes.total, 153);
        // Read with only the members it needs, the document measures the same.
        let pruned = tspace_json::parse_pruned(text, &read_by_measure).unwrap();
        assert_eq!(measure(&pruned), sizes);
        assert!(
            pruned
                .get("meshes")
                .unwrap()
                .index(0)
                .unwrap()
                .get("name")
                .is_none()
        );
    }

    #[test]
    fn each_mesh_finds_its_own_primitives() {
        let text = br#"{
            "bufferViews": [{"byteLength": 10}, {"byteLength": 20}, {"byteLength": 40}],
            "accessors": [{"bufferView": 0}, {"bufferView": 1}, {"bufferView": 2}],
            "meshes": [
                {"primitives": [{"attributes": {"POSITION": 0}}]},
                {"primitives": []},
                {"primitives": [{"attributes": {"POSITION": 1}}, {"attributes": {"POSITION": 2}}]}
            ]
        }"#;
        let doc = Document::parse(text).unwrap();
        let sizes = measure(doc.root());
        let bytes = |key| sizes.primitive(key).map(|p| p.bytes);
        assert_eq!(bytes((0, 0)), Some(10));
        assert_eq!(bytes((0, 1)), None);
        assert_eq!(bytes((1, 0)), None);
        assert_eq!(bytes((2, 0)), Some(20));
        assert_eq!(bytes((2, 1)), Some(40));
        assert_eq!(bytes((2, 2)), None);
        assert_eq!(bytes((3, 0)), None);
        assert_eq!(sizes.total, 70);
    }
}
