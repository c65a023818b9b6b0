//! Which primitives get tangents, from which texture-coordinate set, and which share work.
//!
//! A primitive gets tangents when it is made of triangles, its material uses a tangent frame
//! (`normalTexture`, `KHR_materials_clearcoat`'s `clearcoatNormalTexture`, or
//! `KHR_materials_anisotropy`), and it has no `TANGENT` yet. `all` drops the material test,
//! `overwrite` recomputes existing tangents. A primitive that keeps its tangents is audited
//! against MikkTSpace instead when its material uses them. Every other primitive is skipped with a
//! reason. Primitives with the same mode, indices, `POSITION`, `NORMAL`, texture coordinates and
//! morph targets are computed once.

use crate::scene::index32;
use crate::scene::report::{FrameUse, MeshName, Notes, SkipCode};
use tspace_json::Node;

/// How a primitive's triangles are laid out (`mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Topology {
    Triangles,
    Strip,
    Fan,
}

/// Why a primitive gets no tangents.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SkipReason {
    /// POINTS or LINES (or an unknown mode).
    NotTriangles {
        mode: u64,
    },
    /// No material, so the default material, which has no normal map.
    NoMaterial,
    /// Its material has no normal map, clearcoat normal map or anisotropy.
    NoNormalMap,
    /// It has TANGENT and `overwrite` was not asked for, and its material does not use it.
    HasTangents,
    NoPositions,
    /// The texture-coordinate set the material names (or 0) is not there. `normal_map` says
    /// whether a material asked for it (rather than `all`).
    NoTexcoords {
        set: u32,
        normal_map: bool,
    },
}

impl SkipReason {
    /// A stable code for reports.
    pub fn code(self) -> SkipCode {
        match self {
            SkipReason::NotTriangles { .. } => SkipCode::NotTriangles,
            SkipReason::NoMaterial => SkipCode::NoMaterial,
            SkipReason::NoNormalMap => SkipCode::NoNormalMap,
            SkipReason::HasTangents => SkipCode::HasTangents,
            SkipReason::NoPositions => SkipCode::NoPositions,
            SkipReason::NoTexcoords { .. } => SkipCode::NoTexcoords,
        }
    }

    pub fn message(self) -> String {
        match self {
            SkipReason::NotTriangles { mode } => format!(
                "mode {mode} is not TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN; points and lines have no tangent frame"
            ),
            SkipReason::NoMaterial => {
                "no material, so no normal map (use `all` to compute tangents anyway)".into()
            }
            SkipReason::NoNormalMap => "its material has no normal map, clearcoat normal map or anisotropy (use `all` to compute tangents anyway)".into(),
            SkipReason::HasTangents => {
                "it already has TANGENT and its material does not use it".into()
            }
            SkipReason::NoPositions => "it has no POSITION attribute".into(),
            SkipReason::NoTexcoords {
                set,
                normal_map: true,
            } => format!(
                "its normal map reads TEXCOORD_{set}, which the primitive does not have; ask for the axis method to get tangents without texture coordinates"
            ),
            SkipReason::NoTexcoords {
                set,
                normal_map: false,
            } => format!(
                "it has no TEXCOORD_{set}, which tangents follow; ask for the axis method to get tangents without texture coordinates"
            ),
        }
    }
}

/// What happens to one primitive.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Action {
    /// Compute tangents (replacing existing ones when `overwrite` is set).
    Generate,
    /// Keep the existing tangents and compare them with MikkTSpace.
    Audit,
    Skip(SkipReason),
}

/// The accessors a computation reads: primitives with equal keys share one result.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct GeometryKey {
    pub topology: Topology,
    pub indices: Option<usize>,
    pub position: usize,
    pub normal: Option<usize>,
    /// `None` only for the axis method.
    pub texcoord: Option<usize>,
    /// Per morph target: its POSITION and NORMAL accessors.
    pub targets: Vec<(Option<usize>, Option<usize>)>,
}

/// The decision for one primitive.
#[derive(Clone, Debug)]
pub struct PrimitivePlan {
    // Positions in 32 bits ([`index32`]): a scene may have a hundred thousand plans.
    pub mesh: u32,
    pub primitive: u32,
    /// Shared by the mesh's primitives (and their report entries).
    pub mesh_name: Option<MeshName>,
    pub material: Option<usize>,
    /// The texture-coordinate set the tangent frame follows.
    pub texcoord_set: u32,
    /// What in the material asked for a tangent frame (`normalTexture`…), if anything.
    pub uses: Option<FrameUse>,
    pub had_tangents: bool,
    pub action: Action,
    /// For [`Action::Generate`] and [`Action::Audit`]: the computation it joins, as the caller
    /// of [`plan`] numbered its geometry's key. The key itself is not kept: most primitives of
    /// a large scene share theirs, and the caller's list holds each once.
    job: Option<u32>,
    /// Notes for the report (a texture transform on the normal map, conflicting UV sets).
    pub notes: Notes,
}

// One per primitive, kept until the scene is written; a change that grows it should be a
// decision.
const _: () = assert!(std::mem::size_of::<PrimitivePlan>() == 72);

impl PrimitivePlan {
    /// `(mesh, primitive)`: where the primitive is in the document.
    pub fn at(&self) -> (usize, usize) {
        (self.mesh as usize, self.primitive as usize)
    }

    /// The computation it joins, for [`Action::Generate`] and [`Action::Audit`].
    pub fn job(&self) -> Option<usize> {
        self.job.map(|j| j as usize)
    }
}

/// Options that change the decisions.
#[derive(Clone, Copy, Debug, Default)]
pub struct PlanOptions {
    pub overwrite: bool,
    pub all: bool,
    /// The axis method needs no texture coordinates.
    pub axis: bool,
    /// Treat a primitive without a material as one that uses a normal map (a converted OBJ
    /// without MTL, where nothing else says what the sender wants).
    pub no_material_means_tangents: bool,
}

/// What a material says about tangents: whether it uses a frame, for which feature, on which
/// texture-coordinate set, and any notes.
struct MaterialUse {
    uses: Option<FrameUse>,
    set: u32,
    notes: Vec<String>,
}

fn texture_set(info: &Node) -> u32 {
    // KHR_texture_transform may override the set the texture reads.
    let overridden = info
        .get("extensions")
        .and_then(|e| e.get("KHR_texture_transform"))
        .and_then(|t| t.get("texCoord"))
        .and_then(Node::as_u64);
    let set = overridden.or_else(|| info.get("texCoord").and_then(Node::as_u64));
    set.and_then(|s| u32::try_from(s).ok()).unwrap_or(0)
}

fn material_use(material: Option<&Node>) -> MaterialUse {
    let mut out = MaterialUse {
        uses: None,
        set: 0,
        notes: Vec::new(),
    };
    let Some(material) = material else {
        return out;
    };
    let extension = |name: &str| material.get("extensions").and_then(|e| e.get(name));
    // At most three, looked at once per primitive: no list is allocated for them (a scene may
    // have a hundred thousand primitives).
    let normal = material
        .get("normalTexture")
        .map(|info| (FrameUse::NormalTexture, Some(info)));
    let clearcoat = extension("KHR_materials_clearcoat")
        .and_then(|clearcoat| clearcoat.get("clearcoatNormalTexture"))
        .map(|info| (FrameUse::ClearcoatNormalTexture, Some(info)));
    let anisotropy = extension("KHR_materials_anisotropy")
        .map(|anisotropy| (FrameUse::Anisotropy, anisotropy.get("anisotropyTexture")));
    let mut candidates = [normal, clearcoat, anisotropy].into_iter().flatten();
    // The normal map decides the set when there is one; the others follow it.
    let Some((first, first_info)) = candidates.next() else {
        return out;
    };
    out.uses = Some(first);
    out.set = first_info.map_or(0, texture_set);
    for (name, info) in candidates {
        if let Some(info) = info {
            let set = texture_set(info);
            if set != out.set {
                out.notes.push(format!(
                    "{name} reads TEXCOORD_{set} but {first} reads TEXCOORD_{}; tangents follow {first}",
                    out.set
                ));
            }
        }
    }
    if let Some(info) = first_info {
        let transform = info
            .get("extensions")
            .and_then(|e| e.get("KHR_texture_transform"));
        if let Some(transform) = transform {
            let rotated = transform
                .get("rotation")
                .and_then(Node::as_f64)
                .is_some_and(|r| r != 0.0);
            let scaled = transform
                .get("scale")
                .and_then(Node::as_array)
                .is_some_and(|s| s.iter().any(|v| v.as_f64().is_some_and(|v| v < 0.0)));
            if rotated || scaled {
                out.notes.push(format!(
                    "{first} has a KHR_texture_transform that rotates or mirrors it; tangents follow the untransformed texture coordinates, as bakers see them"
                ));
            }
        }
    }
    out
}

fn accessor_index(node: Option<&Node>) -> Option<usize> {
    node.and_then(Node::as_u64)
        .and_then(|n| usize::try_from(n).ok())
}

/// The array member `name` of `node`; a missing or malformed one holds nothing to plan.
fn array<'a>(node: &'a Node, name: &str) -> &'a [Node] {
    node.get(name).and_then(Node::as_array).unwrap_or(&[])
}

fn attribute(primitive: &Node, name: &str) -> Option<usize> {
    accessor_index(primitive.get("attributes").and_then(|a| a.get(name)))
}

/// The accessor of `TEXCOORD_<set>`, its name spelled on the stack rather than allocated once
/// per primitive.
fn texcoord_attribute(primitive: &Node, set: u32) -> Option<usize> {
    use std::io::Write;
    let mut name = [0u8; "TEXCOORD_4294967295".len()];
    let left = {
        let mut free = &mut name[..];
        // Always fits: the buffer is as long as the longest name.
        write!(free, "TEXCOORD_{set}").ok()?;
        free.len()
    };
    let len = name.len() - left;
    let name = std::str::from_utf8(name.get(..len)?).ok()?;
    attribute(primitive, name)
}

fn topology(mode: u64) -> Option<Topology> {
    match mode {
        4 => Some(Topology::Triangles),
        5 => Some(Topology::Strip),
        6 => Some(Topology::Fan),
        _ => None,
    }
}

/// What the primitive's material says about tangents. A material variant
/// (KHR_materials_variants) that uses a frame counts as well, since any variant may be shown.
fn frame_use(primitive: &Node, material: Option<usize>, materials: &[Node]) -> MaterialUse {
    let usage = material_use(material.and_then(|m| materials.get(m)));
    if usage.uses.is_some() {
        return usage;
    }
    let variants = primitive
        .get("extensions")
        .and_then(|e| e.get("KHR_materials_variants"))
        .map_or(&[][..], |v| array(v, "mappings"));
    variants
        .iter()
        .map(|mapping| {
            material_use(accessor_index(mapping.get("material")).and_then(|m| materials.get(m)))
        })
        .find(|candidate| candidate.uses.is_some())
        .unwrap_or(usage)
}

/// What the decision reads from one primitive.
struct Facts {
    mode: u64,
    topology: Option<Topology>,
    position: Option<usize>,
    /// The accessor of the texture-coordinate set the frame follows.
    texcoord: Option<usize>,
    material: Option<usize>,
    had_tangents: bool,
}

fn decide(facts: &Facts, usage: &MaterialUse, options: &PlanOptions) -> Action {
    let wants_frame = usage.uses.is_some()
        || options.all
        || (facts.material.is_none() && options.no_material_means_tangents);
    let keeps_tangents = facts.had_tangents && !options.overwrite;
    match (facts.topology, facts.position) {
        (None, _) => Action::Skip(SkipReason::NotTriangles { mode: facts.mode }),
        (_, None) => Action::Skip(SkipReason::NoPositions),
        _ if !wants_frame => {
            if keeps_tangents {
                Action::Skip(SkipReason::HasTangents)
            } else if facts.material.is_none() {
                Action::Skip(SkipReason::NoMaterial)
            } else {
                Action::Skip(SkipReason::NoNormalMap)
            }
        }
        // Kept tangents are audited against MikkTSpace, which needs the coordinates they follow.
        _ if keeps_tangents => match facts.texcoord {
            Some(_) => Action::Audit,
            None => Action::Skip(SkipReason::HasTangents),
        },
        _ if facts.texcoord.is_none() && !options.axis => Action::Skip(SkipReason::NoTexcoords {
            set: usage.set,
            normal_map: usage.uses.is_some(),
        }),
        _ => Action::Generate,
    }
}

/// Per morph target: its POSITION and NORMAL accessors.
fn morph_targets(primitive: &Node) -> Vec<(Option<usize>, Option<usize>)> {
    array(primitive, "targets")
        .iter()
        .map(|t| {
            (
                accessor_index(t.get("POSITION")),
                accessor_index(t.get("NORMAL")),
            )
        })
        .collect()
}

fn geometry_key(
    primitive: &Node,
    facts: &Facts,
    action: &Action,
    options: &PlanOptions,
) -> Option<GeometryKey> {
    let (Action::Generate | Action::Audit, Some(topology), Some(position)) =
        (action, facts.topology, facts.position)
    else {
        return None;
    };
    // Morph-target deltas are only written beside generated tangents; an audit compares the
    // base mesh alone.
    let targets = match action {
        Action::Generate => morph_targets(primitive),
        _ => Vec::new(),
    };
    Some(GeometryKey {
        topology,
        indices: accessor_index(primitive.get("indices")),
        position,
        normal: attribute(primitive, "NORMAL"),
        texcoord: if options.axis { None } else { facts.texcoord },
        targets,
    })
}

fn plan_primitive(
    (mesh, mesh_name): (usize, &Option<MeshName>),
    index: usize,
    primitive: &Node,
    materials: &[Node],
    options: &PlanOptions,
) -> (PrimitivePlan, Option<GeometryKey>) {
    let material = accessor_index(primitive.get("material"));
    let usage = frame_use(primitive, material, materials);
    let mode = primitive.get("mode").and_then(Node::as_u64).unwrap_or(4);
    let facts = Facts {
        mode,
        topology: topology(mode),
        position: attribute(primitive, "POSITION"),
        texcoord: texcoord_attribute(primitive, usage.set),
        material,
        had_tangents: attribute(primitive, "TANGENT").is_some(),
    };
    let action = decide(&facts, &usage, options);
    let key = geometry_key(primitive, &facts, &action, options);
    let plan = PrimitivePlan {
        mesh: index32(mesh),
        primitive: index32(index),
        mesh_name: mesh_name.clone(),
        material,
        texcoord_set: usage.set,
        uses: usage.uses,
        had_tangents: facts.had_tangents,
        action,
        job: None,
        notes: usage.notes.into(),
    };
    (plan, key)
}

/// Decides every primitive of the document. Each primitive that computes anything hands its
/// geometry's key to `job_of`, which says which computation it joins.
pub fn plan(
    root: &Node,
    options: &PlanOptions,
    mut job_of: impl FnMut(&PrimitivePlan, GeometryKey) -> usize,
) -> Vec<PrimitivePlan> {
    let materials = array(root, "materials");
    // One plan per primitive, allocated once: growing by doubling would leave up to as much
    // again unused, and the plans stay until the scene is written.
    let count = array(root, "meshes")
        .iter()
        .map(|mesh| array(mesh, "primitives").len())
        .sum();
    let mut plans = Vec::with_capacity(count);
    for (mesh_index, mesh) in array(root, "meshes").iter().enumerate() {
        let mesh_name = mesh.get("name").and_then(Node::as_str).map(MeshName::from);
        for (index, primitive) in array(mesh, "primitives").iter().enumerate() {
            let (mut plan, key) = plan_primitive(
                (mesh_index, &mesh_name),
                index,
                primitive,
                materials,
                options,
            );
            plan.job = key.map(|key| index32(job_of(&plan, key)));
            plans.push(plan);
        }
    }
    plans
}

#[cfg(test)]
mod tests {
    use super::*;
    use tspace_json::Document;

    /// The plans, and each one's key (`None` where it computes nothing).
    fn plans(json: &str, options: PlanOptions) -> Vec<(PrimitivePlan, Option<GeometryKey>)> {
        let doc = Document::parse(json.as_bytes()).unwrap();
        let mut keys = Vec::new();
        let plans = plan(doc.root(), &options, |_, key| {
            keys.push(key);
            keys.len() - 1
        });
        plans
            .into_iter()
            .map(|p| {
                let key = p.job().map(|j| keys[j].clone());
                (p, key)
            })
            .collect()
    }

    const SCENE: &str = r#"{
        "materials": [
            {"name": "plain"},
            {"normalTexture": {"index": 0, "texCoord": 1}},
            {"extensions": {"KHR_materials_clearcoat": {"clearcoatNormalTexture": {"index": 0}}}},
            {"extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 0.5}}},
            {"normalTexture": {"index": 0, "texCoord": 0,
                "extensions": {"KHR_texture_transform": {"texCoord": 1}}}}
        ],
        "meshes": [{"name": "m", "primitives": [
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2}, "material": 1},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 1},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 2, "mode": 5},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 3, "mode": 1},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TANGENT": 3}, "material": 3},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2}, "material": 4},
            {"attributes": {"TEXCOORD_0": 1}, "material": 3},
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "extensions": {"KHR_materials_variants":
                {"mappings": [{"material": 0, "variants": [0]}, {"material": 2, "variants": [1]}]}}}
        ]}]
    }"#;

    #[test]
    fn a_texcoord_set_is_found_by_its_whole_name() {
        let doc = Document::parse(
            br#"{"attributes": {"TEXCOORD_01": 0, "TEXCOORD_1": 1, "TEXCOORD_4294967295": 2}}"#,
        )
        .unwrap();
        let primitive = doc.root();
        assert_eq!(texcoord_attribute(primitive, 1), Some(1));
        assert_eq!(texcoord_attribute(primitive, u32::MAX), Some(2));
        assert_eq!(texcoord_attribute(primitive, 0), None);
        assert_eq!(texcoord_attribute(primitive, 10), None);
    }

    #[test]
    fn decisions_follow_the_material() {
        let p = plans(SCENE, PlanOptions::default());
        let actions: Vec<_> = p.iter().map(|(p, _)| p.action.clone()).collect();
        assert_eq!(
            actions,
            vec![
                Action::Skip(SkipReason::NoMaterial),
                Action::Skip(SkipReason::NoNormalMap),
                Action::Generate,
                Action::Skip(SkipReason::NoTexcoords {
                    set: 1,
                    normal_map: true
                }),
                Action::Generate,
                Action::Skip(SkipReason::NotTriangles { mode: 1 }),
                Action::Audit,
                Action::Generate,
                Action::Skip(SkipReason::NoPositions),
                Action::Generate,
            ]
        );
        assert_eq!(p[2].0.texcoord_set, 1);
        assert_eq!(p[2].1.as_ref().unwrap().texcoord, Some(2));
        assert_eq!(p[4].1.as_ref().unwrap().topology, Topology::Strip);
        assert_eq!(p[6].0.uses, Some(FrameUse::Anisotropy));
        // KHR_texture_transform's texCoord overrides the texture's own.
        assert_eq!(p[7].0.texcoord_set, 1);
        assert_eq!(p[9].0.uses, Some(FrameUse::ClearcoatNormalTexture));
        // Primitives 2 and 7 read the same accessors: one computation.
        assert_eq!(p[2].1, p[7].1);
        assert_ne!(p[2].1, p[4].1);
        // Only the primitives that compute anything have a key, and each its own number here.
        for (plan, key) in &p {
            let computes = matches!(plan.action, Action::Generate | Action::Audit);
            assert_eq!(plan.job().is_some(), computes);
            assert_eq!(key.is_some(), computes);
        }
    }

    #[test]
    fn options_widen_the_decisions() {
        let p = plans(
            SCENE,
            PlanOptions {
                overwrite: true,
                all: true,
                ..PlanOptions::default()
            },
        );
        assert_eq!(p[0].0.action, Action::Generate);
        assert_eq!(p[1].0.action, Action::Generate);
        assert_eq!(p[6].0.action, Action::Generate);
        let axis = plans(
            SCENE,
            PlanOptions {
                axis: true,
                ..PlanOptions::default()
            },
        );
        assert_eq!(axis[3].0.action, Action::Generate);
        assert_eq!(axis[3].1.as_ref().unwrap().texcoord, None);
    }
}
