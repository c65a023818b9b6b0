//! Reading back what tspace wrote, through tspace's own loader and accessor reader, which
//! decode what the `gltf` crate's readers do not (meshopt views, quantized attributes), and
//! checking its tangents against the reference on the written geometry.

use crate::reference::{reference_is_valid, reference_tangents};
use crate::shapes::angle_degrees;
use tspace::scene::gltf::accessor::{self, ComponentType};
use tspace::scene::gltf::load::{self, LoadLimits, NoResources};
use tspace_json::Node;

/// One written triangle primitive, decoded.
pub struct WrittenPrimitive {
    /// Every attribute's elements as stored (one byte vector per element), by name.
    pub attributes: Vec<(String, Vec<Vec<u8>>)>,
    pub indices: Vec<u32>,
    pub positions: Vec<[f32; 3]>,
    /// Normalized (quantized normals are not unit when decoded).
    pub normals: Vec<[f32; 3]>,
    /// TEXCOORD_0.
    pub uvs: Vec<[f32; 2]>,
    pub tangents: Vec<[f32; 4]>,
    pub tangent_type: ComponentType,
}

/// Every primitive of a written GLB or `.gltf` (with only `data:` buffers); panics on anything
/// a primitive with tangents, normals, TEXCOORD_0 and indices would not have.
pub fn read_primitives(bytes: &[u8]) -> Vec<WrittenPrimitive> {
    const MAX: usize = 1 << 24;
    let limits = LoadLimits {
        max_buffer_bytes: 1 << 30,
    };
    let loaded = load::load(bytes, &NoResources, &limits).expect("the written scene loads");
    let root = loaded.doc.root();
    let buffers = loaded.buffer_slices();
    let index = |n: Option<&Node>| n.and_then(Node::as_u64).expect("an accessor index") as usize;
    let mut out = Vec::new();
    for mesh in root.get("meshes").and_then(Node::as_array).unwrap_or(&[]) {
        for primitive in mesh
            .get("primitives")
            .and_then(Node::as_array)
            .unwrap_or(&[])
        {
            let attributes = primitive.get("attributes").expect("attributes");
            let of = |key: &str| index(attributes.get(key));
            let raw = |i: usize| {
                let described = accessor::accessor_from_json(root, i, &buffers).unwrap();
                let raw = accessor::read_raw(&described, MAX).unwrap();
                (0..raw.len())
                    .map(|e| raw.element(e).unwrap().to_vec())
                    .collect::<Vec<_>>()
            };
            let mut normals = accessor::read_floats_json::<3>(root, of("NORMAL"), &buffers, MAX)
                .expect("NORMAL reads");
            for n in &mut normals {
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                *n = [n[0] / l, n[1] / l, n[2] / l];
            }
            let tangent = accessor::accessor_from_json(root, of("TANGENT"), &buffers).unwrap();
            out.push(WrittenPrimitive {
                attributes: attributes
                    .as_object()
                    .unwrap_or(&[])
                    .iter()
                    .map(|m| (m.key.to_string(), raw(index(Some(&m.value)))))
                    .collect(),
                indices: accessor::read_indices_json(
                    root,
                    index(primitive.get("indices")),
                    &buffers,
                    MAX,
                )
                .expect("indices read"),
                positions: accessor::read_floats_json::<3>(root, of("POSITION"), &buffers, MAX)
                    .expect("POSITION reads"),
                normals,
                uvs: accessor::read_floats_json::<2>(root, of("TEXCOORD_0"), &buffers, MAX)
                    .expect("TEXCOORD_0 reads"),
                tangents: accessor::read_floats::<4>(&tangent, MAX).expect("TANGENT reads"),
                tangent_type: tangent.component_type,
            });
        }
    }
    out
}

/// The largest angle, in degrees, between the written tangents and the reference run on the
/// written geometry; handedness must agree (glTF's UV origin: the reference's `w` negated)
/// wherever the reference's tangent is valid.
pub fn worst_angle_to_reference(p: &WrittenPrimitive) -> f64 {
    let reference = reference_tangents(&p.positions, &p.normals, &p.uvs, &p.indices);
    let mut worst = 0f64;
    for (corner, r) in reference.iter().enumerate() {
        let v = p.indices[corner] as usize;
        if !reference_is_valid(*r, p.normals[v]) {
            continue;
        }
        let (r, ours) = (r.expect("valid, so present"), p.tangents[v]);
        assert_eq!(ours[3], -r[3], "corner {corner}: handedness");
        worst = worst.max(angle_degrees(
            [r[0], r[1], r[2]],
            [ours[0], ours[1], ours[2]],
        ));
    }
    worst
}
