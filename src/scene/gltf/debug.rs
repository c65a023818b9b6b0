//! Debug colours (`debug=colors`): the written scene painted by what tspace found in each
//! triangle, so that any glTF viewer shows where the problems are.
//!
//! A vertex has one colour, and a vertex shared by triangles of two classes needs two. So the
//! job's split plan is refined until every vertex's triangles share one class: the first class
//! a vertex meets keeps it in place, each other class gets a copy appended at the end. Tangents,
//! generated normals and morph deltas follow the refined plan, so every corner keeps exactly
//! the tangent it had; the writer then carries the other attributes over as it does for any
//! split. COLOR_0 holds the class colours in linear RGB (glTF's colour space for vertex
//! colours), converted from the sRGB the UV-layout picture uses, so a viewer shows the
//! picture's colours. A primitive's material becomes one unlit material that shows COLOR_0 as
//! it is (`KHR_materials_unlit`; viewers without it light the same colours).

use super::compute::Computed;
use std::collections::HashMap;
use tspace_tangent::{Marks, TriangleMarks};

/// What a triangle is painted as, in order of precedence (a degenerate triangle with mirrored
/// UVs is painted degenerate).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Class {
    Ordinary = 0,
    Mirrored = 1,
    Repaired = 2,
    ZeroUvArea = 3,
    Degenerate = 4,
}

impl Class {
    /// Every class, in the order the report lists them.
    pub const ALL: [Class; 5] = [
        Class::Ordinary,
        Class::Mirrored,
        Class::Repaired,
        Class::ZeroUvArea,
        Class::Degenerate,
    ];

    /// The highest class `marks` has.
    pub fn of(marks: TriangleMarks) -> Class {
        if marks.is_degenerate() {
            Class::Degenerate
        } else if marks.has(TriangleMarks::ZERO_UV_AREA) {
            Class::ZeroUvArea
        } else if marks.has(TriangleMarks::REPAIRED) {
            Class::Repaired
        } else if marks.has(TriangleMarks::MIRRORED_UV) {
            Class::Mirrored
        } else {
            Class::Ordinary
        }
    }

    /// The report's name for the class.
    pub fn name(self) -> &'static str {
        match self {
            Class::Ordinary => "ordinary",
            Class::Mirrored => "mirrored_uv",
            Class::Repaired => "repaired_tangent",
            Class::ZeroUvArea => "zero_uv_area",
            Class::Degenerate => "degenerate",
        }
    }

    /// The colour in sRGB: the UV-layout picture's (Okabe–Ito, told apart with the common
    /// colour-vision deficiencies), ordinary a light grey that the others stand out from.
    pub fn srgb(self) -> [u8; 3] {
        match self {
            Class::Ordinary => [0xc9, 0xc9, 0xc9],
            Class::Mirrored => [0x56, 0xb4, 0xe9],
            Class::Repaired => [0xcc, 0x79, 0xa7],
            Class::ZeroUvArea => [0xe6, 0x9f, 0x00],
            Class::Degenerate => [0xd5, 0x5e, 0x00],
        }
    }

    /// `#rrggbb`, for the report.
    pub fn hex(self) -> String {
        let [r, g, b] = self.srgb();
        format!("#{r:02x}{g:02x}{b:02x}")
    }

    /// The colour as COLOR_0 stores it: linear RGB.
    pub fn linear(self) -> [f32; 3] {
        self.srgb().map(srgb_to_linear)
    }
}

/// The sRGB transfer function, inverted.
fn srgb_to_linear(value: u8) -> f32 {
    let c = f32::from(value) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// One job, painted: a colour per vertex of its refined plan, and what was painted.
#[derive(Clone, Debug, Default)]
pub struct Painted {
    /// COLOR_0: one per vertex of the refined plan.
    pub colors: Vec<[f32; 3]>,
    /// Triangles per class, indexed by `Class as usize`.
    pub triangles: [u64; 5],
    /// Vertices the refinement added beyond the tangents' own split.
    pub vertices_added: u64,
}

/// Refines `computed`'s plan so that each vertex's triangles share one class of `marks` (one
/// entry per triangle, as `tspace_tangent::marks` gives them for this computation) and returns
/// the colours of the refined vertices. Every corner's tangent is unchanged.
pub fn paint(computed: &mut Computed, marks: &Marks) -> Painted {
    let tangents = &mut computed.tangents;
    let split = &mut tangents.split;
    let kept = split.source_vertex.len();
    // The class a kept vertex was first painted, and the copies made for its other classes.
    let mut class_of: Vec<Option<Class>> = vec![None; kept];
    let mut copies: HashMap<(u32, Class), u32> = HashMap::new();
    let mut appended: Vec<(u32, Class)> = Vec::new();
    let mut triangles = [0u64; 5];
    // Refining may give corners other vertices: the plan's own indices, if it had none.
    let indices = split.indices_mut(computed.geometry.indices.as_deref());
    for (t, corners) in indices.chunks_exact_mut(3).enumerate() {
        let class = marks
            .triangles
            .get(t)
            .map_or(Class::Ordinary, |&m| Class::of(m));
        triangles[class as usize] += 1;
        for corner in corners {
            let vertex = *corner;
            let Some(slot) = class_of.get_mut(vertex as usize) else {
                continue;
            };
            match slot {
                None => *slot = Some(class),
                Some(first) if *first == class => {}
                Some(_) => {
                    *corner = *copies.entry((vertex, class)).or_insert_with(|| {
                        appended.push((vertex, class));
                        (kept + appended.len() - 1) as u32
                    });
                }
            }
        }
    }
    let copied = || appended.iter().map(|&(v, _)| v as usize);
    let sources: Vec<u32> = copied().map(|v| split.source_vertex[v]).collect();
    split.source_vertex.extend(sources);
    let copied_tangents: Vec<[f32; 4]> = copied().map(|v| split.vertex_tangents[v]).collect();
    split.vertex_tangents.extend(copied_tangents);
    if let Some(normals) = &mut tangents.normals {
        let copied_normals: Vec<[f32; 3]> = copied().map(|v| normals[v]).collect();
        normals.extend(copied_normals);
    }
    for deltas in computed.target_deltas.iter_mut().flatten() {
        let copied_deltas: Vec<[f32; 3]> = copied().map(|v| deltas[v]).collect();
        deltas.extend(copied_deltas);
    }
    let colors = class_of
        .iter()
        .map(|class| class.unwrap_or(Class::Ordinary).linear())
        .chain(appended.iter().map(|&(_, class)| class.linear()))
        .collect();
    Painted {
        colors,
        triangles,
        vertices_added: appended.len() as u64,
    }
}

/// The material every painted primitive gets: unlit, white, so COLOR_0 shows as it is, and
/// double-sided, so a triangle facing away still shows its class.
pub const MATERIAL_JSON: &str = r#"{"name":"tspace debug colours","pbrMetallicRoughness":{"baseColorFactor":[1,1,1,1],"metallicFactor":0,"roughnessFactor":1},"doubleSided":true,"extensions":{"KHR_materials_unlit":{}}}"#;

/// The extension the material uses.
pub const UNLIT: &str = "KHR_materials_unlit";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gltf::compute::Geometry;
    use std::borrow::Cow;
    use tspace_tangent::{Options, generate};

    /// Two triangles sharing an edge, the second mirrored in UV.
    fn mirrored_pair() -> Computed<'static> {
        let geometry = Geometry {
            positions: Cow::Owned(vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
            ]),
            normals: Some(Cow::Owned(vec![[0.0, 0.0, 1.0]; 4])),
            uvs: Some(Cow::Owned(vec![
                [0.0, 0.0],
                [1.0, 0.0],
                [0.0, 1.0],
                [1.0, 1.0],
            ])),
            indices: Some(Cow::Owned(vec![0, 1, 2, 2, 1, 3])),
        };
        let tangents = match generate(&geometry.input(), &Options::default()) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        Computed {
            geometry,
            tangents,
            target_deltas: Vec::new(),
            morph_handedness_changes: 0,
        }
    }

    #[test]
    fn shared_vertices_are_copied_per_class_and_corners_keep_their_tangents() {
        let mut computed = mirrored_pair();
        let indices = computed.geometry.indices.clone();
        let before = computed.tangents.corner_tangents(indices.as_deref());
        let marks = Marks {
            triangles: vec![
                TriangleMarks::default(),
                TriangleMarks::from_bits(TriangleMarks::MIRRORED_UV),
            ],
            flip_vertices: Vec::new(),
        };
        let kept = computed.tangents.split.source_vertex.len();
        let painted = paint(&mut computed, &marks);
        let split = &computed.tangents.split;
        // Vertices 1 and 2 are shared across the classes: one copy each.
        assert_eq!(painted.vertices_added, 2);
        assert_eq!(split.source_vertex.len(), kept + 2);
        assert_eq!(painted.colors.len(), kept + 2);
        assert_eq!(painted.triangles, [1, 1, 0, 0, 0]);
        assert_eq!(
            computed.tangents.corner_tangents(indices.as_deref()),
            before
        );
        // Every vertex is used by triangles of one class only, and coloured as that class.
        let refined = split.indices.as_deref().expect("refined indices");
        for (t, corners) in refined.chunks_exact(3).enumerate() {
            let class = if t == 0 {
                Class::Ordinary
            } else {
                Class::Mirrored
            };
            for &v in corners {
                assert_eq!(painted.colors[v as usize], class.linear());
            }
        }
        // The copies come from the same input vertices.
        assert_eq!(&split.source_vertex[kept..], &[2, 1]);
    }

    #[test]
    fn one_class_adds_nothing() {
        let mut computed = mirrored_pair();
        let marks = Marks {
            triangles: vec![TriangleMarks::default(); 2],
            flip_vertices: Vec::new(),
        };
        let painted = paint(&mut computed, &marks);
        assert_eq!(painted.vertices_added, 0);
        assert!(
            painted
                .colors
                .iter()
                .all(|c| *c == Class::Ordinary.linear())
        );
    }

    #[test]
    fn precedence_and_colours() {
        let degenerate_mirrored = TriangleMarks::from_bits(
            TriangleMarks::ZERO_AREA | TriangleMarks::MIRRORED_UV | TriangleMarks::REPAIRED,
        );
        assert_eq!(Class::of(degenerate_mirrored), Class::Degenerate);
        let repaired_mirrored =
            TriangleMarks::from_bits(TriangleMarks::REPAIRED | TriangleMarks::MIRRORED_UV);
        assert_eq!(Class::of(repaired_mirrored), Class::Repaired);
        assert_eq!(Class::Mirrored.hex(), "#56b4e9");
        // sRGB 0xc9 is about 0.584 linear.
        let [r, ..] = Class::Ordinary.linear();
        assert!((r - 0.5840).abs() < 1e-3, "{r}");
        assert_eq!(srgb_to_linear(255), 1.0);
        assert_eq!(srgb_to_linear(0), 0.0);
    }
}
