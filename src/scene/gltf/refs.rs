//! Where a glTF document refers to accessors, buffer views and buffers by index.
//!
//! The writer needs every such place to tell which accessors a change left unreferenced and to
//! renumber the rest once those are dropped. The list covers the core specification and the
//! extensions in [`KNOWN_EXTENSIONS`]; when a document uses any other extension, one of its
//! members might hold an index this list does not know, so the writer then drops nothing.

use crate::scene::index32;
use tspace_json::Node;

/// Extensions whose every index reference is listed here (most have none at all).
pub const KNOWN_EXTENSIONS: &[&str] = &[
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_dispersion",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_variants",
    "KHR_materials_volume",
    "KHR_mesh_quantization",
    "KHR_texture_basisu",
    "KHR_texture_transform",
    "KHR_lights_punctual",
    "KHR_xmp_json_ld",
    "KHR_animation_pointer",
    "KHR_draco_mesh_compression",
    "EXT_mesh_gpu_instancing",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "EXT_lights_image_based",
];

/// Who holds a reference. Positions in 32 bits ([`index32`]): a scene of many small
/// primitives holds several references each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Owner {
    /// `meshes[mesh].primitives[primitive]` (attributes, indices, targets, extensions).
    Primitive(u32, u32),
    Accessor(u32),
    Image(u32),
    Other,
}

impl Owner {
    /// For a primitive, its `(mesh, primitive)`, as the edits are keyed.
    pub fn primitive(self) -> Option<(usize, usize)> {
        match self {
            Owner::Primitive(m, p) => Some((m as usize, p as usize)),
            _ => None,
        }
    }
}

fn items(node: Option<&Node>) -> &[Node] {
    node.and_then(Node::as_array).unwrap_or(&[])
}

fn values(node: Option<&Node>) -> impl Iterator<Item = &Node> {
    node.and_then(Node::as_object)
        .unwrap_or(&[])
        .iter()
        .map(|m| &m.value)
}

/// The value node of an index reference, if it is a non-negative integer.
fn index(node: Option<&Node>) -> Option<(&Node, usize)> {
    let node = node?;
    let i = usize::try_from(node.as_u64()?).ok()?;
    Some((node, i))
}

/// A reference: its owner and the number's node. The index it holds is read from the node when
/// needed ([`held`]) rather than kept beside it.
pub type Ref<'d> = (Owner, &'d Node);

/// The index a reference's node holds; every listed node holds one.
pub fn held(node: &Node) -> usize {
    index(Some(node)).map_or(usize::MAX, |(_, i)| i)
}

/// The references `visit` reports, in a list of exactly their number: a scene of many small
/// primitives has several each, and a list grown by doubling held up to twice the room, at
/// the writer's peak.
fn counted<'d>(visit: impl Fn(&mut dyn FnMut(Ref<'d>))) -> Vec<Ref<'d>> {
    let mut count = 0;
    visit(&mut |_| count += 1);
    let mut out = Vec::with_capacity(count);
    visit(&mut |r| out.push(r));
    out
}

/// Every accessor reference: `(owner, the number's node, the accessor index)`.
pub fn accessor_refs(root: &Node) -> Vec<Ref<'_>> {
    counted(|out| visit_accessor_refs(root, out))
}

/// Calls `out` with every accessor reference, as [`accessor_refs`] lists them.
pub fn visit_accessor_refs<'d>(root: &'d Node, out: &mut dyn FnMut(Ref<'d>)) {
    for (m, mesh) in items(root.get("meshes")).iter().enumerate() {
        for (p, primitive) in items(mesh.get("primitives")).iter().enumerate() {
            let owner = Owner::Primitive(index32(m), index32(p));
            let nodes = values(primitive.get("attributes"))
                .map(Some)
                .chain(std::iter::once(primitive.get("indices")))
                .chain(
                    items(primitive.get("targets"))
                        .iter()
                        .flat_map(|t| values(Some(t)).map(Some)),
                );
            for node in nodes {
                if let Some((n, _)) = index(node) {
                    out((owner, n));
                }
            }
        }
    }
    for skin in items(root.get("skins")) {
        if let Some((n, _)) = index(skin.get("inverseBindMatrices")) {
            out((Owner::Other, n));
        }
    }
    for animation in items(root.get("animations")) {
        for sampler in items(animation.get("samplers")) {
            for key in ["input", "output"] {
                if let Some((n, _)) = index(sampler.get(key)) {
                    out((Owner::Other, n));
                }
            }
        }
    }
    for node in items(root.get("nodes")) {
        let instancing = node
            .get("extensions")
            .and_then(|e| e.get("EXT_mesh_gpu_instancing"))
            .and_then(|e| e.get("attributes"));
        for v in values(instancing) {
            if let Some((n, _)) = index(Some(v)) {
                out((Owner::Other, n));
            }
        }
    }
}

/// Every buffer-view reference: `(owner, the number's node, the view index)`.
pub fn view_refs(root: &Node) -> Vec<Ref<'_>> {
    counted(|out| visit_view_refs(root, out))
}

/// Calls `out` with every buffer-view reference, as [`view_refs`] lists them.
pub fn visit_view_refs<'d>(root: &'d Node, out: &mut dyn FnMut(Ref<'d>)) {
    for (a, accessor) in items(root.get("accessors")).iter().enumerate() {
        let owner = Owner::Accessor(index32(a));
        if let Some((n, _)) = index(accessor.get("bufferView")) {
            out((owner, n));
        }
        if let Some(sparse) = accessor.get("sparse") {
            for part in ["indices", "values"] {
                if let Some((n, _)) = index(sparse.get(part).and_then(|p| p.get("bufferView"))) {
                    out((owner, n));
                }
            }
        }
    }
    for (i, image) in items(root.get("images")).iter().enumerate() {
        if let Some((n, _)) = index(image.get("bufferView")) {
            out((Owner::Image(index32(i)), n));
        }
    }
    for (m, mesh) in items(root.get("meshes")).iter().enumerate() {
        for (p, primitive) in items(mesh.get("primitives")).iter().enumerate() {
            let draco = primitive
                .get("extensions")
                .and_then(|e| e.get("KHR_draco_mesh_compression"));
            if let Some((n, _)) = index(draco.and_then(|d| d.get("bufferView"))) {
                out((Owner::Primitive(index32(m), index32(p)), n));
            }
        }
    }
}

/// The extensions a document declares that are not in [`KNOWN_EXTENSIONS`].
pub fn unknown_extensions(root: &Node) -> Vec<String> {
    items(root.get("extensionsUsed"))
        .iter()
        .filter_map(Node::as_str)
        .filter(|name| !KNOWN_EXTENSIONS.contains(name))
        .map(str::to_owned)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use tspace_json::Document;

    #[test]
    fn finds_every_kind_of_reference() {
        let doc = Document::parse(
            br#"{
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2,
                "targets": [{"POSITION": 3}],
                "extensions": {"KHR_draco_mesh_compression": {"bufferView": 4, "attributes": {"POSITION": 0}}}}]}],
            "skins": [{"inverseBindMatrices": 5, "joints": [0]}],
            "animations": [{"samplers": [{"input": 6, "output": 7}], "channels": []}],
            "nodes": [{"extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 8}}}}],
            "accessors": [{"bufferView": 0}, {"sparse": {"indices": {"bufferView": 1}, "values": {"bufferView": 2}}}],
            "images": [{"bufferView": 3}],
            "extensionsUsed": ["KHR_draco_mesh_compression", "EXT_structural_metadata"]
        }"#,
        )
        .unwrap();
        let found = accessor_refs(doc.root());
        assert_eq!(found.capacity(), found.len());
        let accessors: Vec<usize> = found.iter().map(|r| held(r.1)).collect();
        assert_eq!(accessors, vec![0, 1, 2, 3, 5, 6, 7, 8]);
        let views: Vec<(Owner, usize)> = view_refs(doc.root())
            .iter()
            .map(|r| (r.0, held(r.1)))
            .collect();
        assert_eq!(
            views,
            vec![
                (Owner::Accessor(0), 0),
                (Owner::Accessor(1), 1),
                (Owner::Accessor(1), 2),
                (Owner::Image(0), 3),
                (Owner::Primitive(0, 0), 4)
            ]
        );
        assert_eq!(
            unknown_extensions(doc.root()),
            vec!["EXT_structural_metadata"]
        );
    }
}
