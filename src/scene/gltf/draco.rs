//! `KHR_draco_mesh_compression`: a primitive's Draco stream decoded into the bytes its accessors
//! would have held, so that the rest of the scene layer reads them like any other accessor.
//!
//! The decoder is the `draco-gltf` crate (pure Rust, checked value for value against Google's
//! own decoder by `tests/draco_oracle.rs`). What this module adds is what tspace promises of
//! untrusted input: every count the stream declares is capped by the request's own limits
//! before anything is allocated, and each way a stream can disagree with its document gets its
//! own problem code and a message naming the JSON path.
//!
//! Values land in the accessor's declared component type, as Google's decoder delivers them
//! (`GetAttributeDataArrayForAllPoints` with the accessor's type). Only accessors without data
//! of their own are replaced: a file that keeps an uncompressed fallback is read from the
//! fallback, which holds the exporter's own values rather than Draco's quantized ones.

use super::accessor::{ComponentType, DecodedAccessor, ElementType};
use crate::scene::error::{ProblemCode, SceneError};
use draco_gltf::{DracoPrimitiveContract, DracoPrimitiveExtension, JsonValue, PackedGeometry};
use tspace_json::Node;

/// The extension's name, as files list it.
pub const EXTENSION: &str = "KHR_draco_mesh_compression";

/// Caps on one decode, from the request's limits.
#[derive(Clone, Copy, Debug)]
pub struct DracoLimits {
    pub max_vertices: usize,
    pub max_triangles: usize,
    /// Decoded attribute bytes of one stream.
    pub max_bytes: usize,
}

/// The primitive's Draco extension, if it has one.
pub fn extension(primitive: &Node) -> Option<&Node> {
    primitive.get("extensions")?.get(EXTENSION)
}

/// Whether the primitive needs its Draco stream decoded: it has the extension, and some
/// accessor the extension covers has no data of its own (no `bufferView`, no `sparse`).
pub fn needs_decoding(root: &Node, primitive: &Node) -> bool {
    let Some(ext) = extension(primitive) else {
        return false;
    };
    covered_accessors(primitive, ext)
        .iter()
        .any(|&(_, a)| !has_own_data(root, a))
}

fn has_own_data(root: &Node, accessor: usize) -> bool {
    root.get("accessors")
        .and_then(|a| a.index(accessor))
        .is_some_and(|a| a.get("bufferView").is_some() || a.get("sparse").is_some())
}

fn index_of(node: Option<&Node>) -> Option<usize> {
    node?.as_u64().and_then(|n| usize::try_from(n).ok())
}

/// The accessors the stream stands for: each attribute the extension names (semantic →
/// accessor), then the indices, named `"indices"`.
fn covered_accessors(primitive: &Node, ext: &Node) -> Vec<(String, usize)> {
    let attributes = primitive.get("attributes");
    let mut covered: Vec<(String, usize)> = ext
        .get("attributes")
        .and_then(Node::as_object)
        .unwrap_or(&[])
        .iter()
        .filter_map(|m| Some((m.key.to_string(), index_of(attributes?.get(&m.key))?)))
        .collect();
    if let Some(i) = index_of(primitive.get("indices")) {
        covered.push(("indices".into(), i));
    }
    covered
}

/// What the document says of one accessor.
struct Declared {
    component_type: ComponentType,
    element_type: ElementType,
    normalized: bool,
    count: usize,
}

fn declared(root: &Node, accessor: usize, path: &str) -> Result<Declared, SceneError> {
    let node = root
        .get("accessors")
        .and_then(|a| a.index(accessor))
        .ok_or_else(|| {
            SceneError::new(
                ProblemCode::InvalidPrimitive,
                format!("{path} names accessors[{accessor}], which does not exist"),
            )
        })?;
    let invalid = |what: &str| {
        SceneError::new(
            ProblemCode::InvalidAccessor,
            format!("accessors[{accessor}].{what}"),
        )
    };
    let component_type = node
        .get("componentType")
        .and_then(Node::as_u64)
        .and_then(ComponentType::from_code)
        .ok_or_else(|| invalid("componentType is missing or not a glTF component type"))?;
    let element_type = node
        .get("type")
        .and_then(Node::as_str)
        .and_then(ElementType::from_name)
        .ok_or_else(|| invalid("type is missing or not SCALAR, VEC2, VEC3, VEC4 or MATn"))?;
    let count = index_of(node.get("count"))
        .ok_or_else(|| invalid("count is missing or not a non-negative integer"))?;
    Ok(Declared {
        component_type,
        element_type,
        normalized: node.get("normalized").and_then(Node::as_bool) == Some(true),
        count,
    })
}

/// Decodes `meshes[mesh].primitives[primitive]`'s stream and returns the data of every
/// covered accessor that has none of its own.
pub fn decode_primitive(
    root: &Node,
    primitive: &Node,
    path: &str,
    buffers: &[&[u8]],
    limits: &DracoLimits,
) -> Result<Vec<(usize, DecodedAccessor)>, SceneError> {
    let ext_path = format!("{path}.extensions.{EXTENSION}");
    let Some(ext) = extension(primitive) else {
        return Ok(Vec::new());
    };
    let parsed = parse_extension(ext, &ext_path)?;
    let covered = covered_accessors(primitive, ext);
    check_semantics(primitive, &parsed, &ext_path)?;
    let mut declared_by_name = Vec::with_capacity(covered.len());
    for (name, accessor) in &covered {
        declared_by_name.push((
            name.as_str(),
            *accessor,
            declared(root, *accessor, &ext_path)?,
        ));
    }
    let payload = payload(root, &parsed, buffers, &ext_path)?;
    let geometry = decode_stream(&parsed, payload, &declared_by_name, limits, &ext_path)?;
    check_other_counts(root, primitive, &covered, geometry.vertex_count(), path)?;
    let mut decoded = Vec::with_capacity(covered.len());
    for (name, accessor, declared) in declared_by_name {
        if has_own_data(root, accessor) {
            continue;
        }
        let data = if name == "indices" {
            indices_bytes(&geometry, &declared, accessor, &ext_path)?
        } else {
            attribute_bytes(&geometry, name, &declared, accessor, &ext_path)?
        };
        decoded.push((accessor, data));
    }
    Ok(decoded)
}

fn parse_extension(ext: &Node, ext_path: &str) -> Result<DracoPrimitiveExtension, SceneError> {
    let invalid = |why: String| {
        SceneError::new(
            ProblemCode::InvalidDracoExtension,
            format!("{ext_path} {why}"),
        )
    };
    if index_of(ext.get("bufferView")).is_none() {
        return Err(invalid(
            "has no bufferView (a non-negative integer naming the view that holds the stream)"
                .into(),
        ));
    }
    let Some(attributes) = ext.get("attributes").and_then(Node::as_object) else {
        return Err(invalid(
            "has no attributes object (semantic → Draco attribute id)".into(),
        ));
    };
    // The Draco reader takes its own JSON: hand it just the two members it reads.
    let mut text = format!(
        "{{\"bufferView\":{},\"attributes\":{{",
        index_of(ext.get("bufferView")).unwrap_or(0)
    );
    for (i, member) in attributes.iter().enumerate() {
        let id = member
            .value
            .as_u64()
            .filter(|&id| id <= u64::from(u32::MAX))
            .ok_or_else(|| {
                invalid(format!(
                    "attributes.{} must be a Draco attribute id (an unsigned 32-bit integer)",
                    member.key
                ))
            })?;
        if i > 0 {
            text.push(',');
        }
        text.push_str(&tspace_json::escape_str(&member.key));
        text.push(':');
        text.push_str(&id.to_string());
    }
    text.push_str("}}");
    let json = JsonValue::parse(text.as_bytes())
        .map_err(|e| invalid(format!("is not valid JSON to the Draco reader: {e}")))?;
    DracoPrimitiveExtension::from_json(&json).map_err(|e| invalid(format!("is invalid: {e}")))
}

/// Every semantic the extension compresses must be one of the primitive's attributes: its
/// accessor is where the decoded values go.
fn check_semantics(
    primitive: &Node,
    parsed: &DracoPrimitiveExtension,
    ext_path: &str,
) -> Result<(), SceneError> {
    let attributes = primitive.get("attributes");
    for (semantic, _) in parsed.attributes() {
        if index_of(attributes.and_then(|a| a.get(semantic))).is_none() {
            return Err(SceneError::new(
                ProblemCode::InvalidDracoExtension,
                format!(
                    "{ext_path}.attributes names {semantic}, which the primitive's attributes do not have"
                ),
            ));
        }
    }
    Ok(())
}

/// The stream's bytes: the extension's buffer view, which must lie inside its buffer.
fn payload<'b>(
    root: &Node,
    parsed: &DracoPrimitiveExtension,
    buffers: &[&'b [u8]],
    ext_path: &str,
) -> Result<&'b [u8], SceneError> {
    let v = parsed.buffer_view();
    let bad = |why: String| {
        SceneError::new(
            ProblemCode::InvalidDracoExtension,
            format!("{ext_path}.bufferView {why}"),
        )
    };
    let view = root
        .get("bufferViews")
        .and_then(|views| views.index(v))
        .ok_or_else(|| bad(format!("names bufferViews[{v}], which does not exist")))?;
    let buffer = index_of(view.get("buffer"))
        .and_then(|b| buffers.get(b).copied())
        .ok_or_else(|| bad(format!("bufferViews[{v}] names no loaded buffer")))?;
    let offset = index_of(view.get("byteOffset")).unwrap_or(0);
    let length = index_of(view.get("byteLength"))
        .ok_or_else(|| bad(format!("bufferViews[{v}] has no byteLength")))?;
    offset
        .checked_add(length)
        .and_then(|end| buffer.get(offset..end))
        .ok_or_else(|| {
            bad(format!(
                "bufferViews[{v}] (bytes {offset}..+{length}) lies outside its buffer of {} bytes",
                buffer.len()
            ))
        })
}

/// Decodes under limits taken from the request, after checking what the document declares
/// against them (a declared count over the limit is refused before any decoding).
fn decode_stream(
    parsed: &DracoPrimitiveExtension,
    payload: &[u8],
    declared: &[(&str, usize, Declared)],
    limits: &DracoLimits,
    ext_path: &str,
) -> Result<PackedGeometry, SceneError> {
    // Draco checks points only for point clouds; a mesh's are bounded through its decoded
    // bytes: at most 16 (a float VEC4) per vertex and attribute, so no more vertices than the
    // limit can be decoded, whatever the stream claims.
    let per_vertex = 16u64.saturating_mul(parsed.attributes().len().max(1) as u64);
    let max_bytes = (limits.max_vertices as u64)
        .saturating_mul(per_vertex)
        .min(limits.max_bytes as u64);
    let mut contract = DracoPrimitiveContract::new().with_limits(
        draco_gltf::DecodeLimits::default()
            .with_max_points(limits.max_vertices as u64)
            .with_max_faces(limits.max_triangles as u64)
            .with_max_decoded_bytes(max_bytes),
    );
    for (name, _, d) in declared {
        if *name == "indices" {
            contract = contract.with_indices(d.count as u64);
        } else if parsed.unique_id(name).is_some() {
            contract = contract.with_attribute(*name, d.count as u64, d.normalized);
        }
    }
    let geometry = parsed
        .decode(payload, &contract)
        .map_err(|e| decode_error(e, ext_path))?;
    if geometry.vertex_count() > limits.max_vertices {
        return Err(SceneError::new(
            ProblemCode::DracoTooLarge,
            format!(
                "{ext_path}: the compressed stream decodes to {} vertices; the limit is {}",
                geometry.vertex_count(),
                limits.max_vertices
            ),
        ));
    }
    Ok(geometry)
}

fn decode_error(error: draco_gltf::Error, ext_path: &str) -> SceneError {
    use draco_gltf::{Error, GeometryError};
    let (code, why) = match &error {
        _ if error.is_decode_limit_exceeded() => (
            ProblemCode::DracoTooLarge,
            "decodes to more than this request allows",
        ),
        Error::Geometry(GeometryError::DracoAccessorCount { .. }) => (
            ProblemCode::DracoCountMismatch,
            "does not match its accessors",
        ),
        Error::Geometry(GeometryError::UnsupportedDraco(m)) if m.contains("is missing") => (
            ProblemCode::DracoAttributeMissing,
            "lacks an attribute the extension names",
        ),
        Error::Decode(_) => (ProblemCode::MalformedDraco, "is not a valid Draco stream"),
        _ => (
            ProblemCode::MalformedDraco,
            "decodes to geometry glTF cannot hold",
        ),
    };
    SceneError::new(
        code,
        format!("{ext_path}: the compressed stream {why}: {error}"),
    )
}

/// Accessors of the primitive the stream does not stand for (uncompressed attributes, morph
/// targets) are read as they are, so they must have one element per decoded point.
fn check_other_counts(
    root: &Node,
    primitive: &Node,
    covered: &[(String, usize)],
    points: usize,
    path: &str,
) -> Result<(), SceneError> {
    let is_covered = |a: usize| covered.iter().any(|&(_, c)| c == a);
    let mut others: Vec<(String, usize)> = Vec::new();
    let members = |object: Option<&Node>, prefix: &str, into: &mut Vec<(String, usize)>| {
        for m in object.and_then(Node::as_object).unwrap_or(&[]) {
            if let Some(a) = index_of(Some(&m.value)).filter(|&a| !is_covered(a)) {
                into.push((format!("{prefix}.{}", m.key), a));
            }
        }
    };
    members(primitive.get("attributes"), "attributes", &mut others);
    for (t, target) in primitive
        .get("targets")
        .and_then(Node::as_array)
        .unwrap_or(&[])
        .iter()
        .enumerate()
    {
        members(Some(target), &format!("targets[{t}]"), &mut others);
    }
    for (member, accessor) in others {
        let count = declared(root, accessor, path)?.count;
        if count != points {
            return Err(SceneError::new(
                ProblemCode::DracoCountMismatch,
                format!(
                    "{path}.{member} (accessors[{accessor}]) has {count} elements, but the primitive's Draco stream decodes to {points} vertices; an attribute or morph target outside the stream must match it vertex for vertex"
                ),
            ));
        }
    }
    Ok(())
}

fn attribute_bytes(
    geometry: &PackedGeometry,
    semantic: &str,
    declared: &Declared,
    accessor: usize,
    ext_path: &str,
) -> Result<DecodedAccessor, SceneError> {
    let attribute = geometry
        .attributes()
        .iter()
        .find(|a| a.semantic() == semantic)
        .ok_or_else(|| {
            SceneError::new(
                ProblemCode::DracoAttributeMissing,
                format!("{ext_path}: the decoded stream has no {semantic}"),
            )
        })?;
    let components = usize::from(attribute.components());
    if components != declared.element_type.components() {
        return Err(SceneError::new(
            ProblemCode::DracoTypeMismatch,
            format!(
                "{ext_path}: {semantic} decodes to {components} components per vertex, but accessors[{accessor}] is {}",
                declared.element_type.name()
            ),
        ));
    }
    let stored = Stored::of(attribute.component_type()).ok_or_else(|| {
        SceneError::new(
            ProblemCode::DracoTypeMismatch,
            format!(
                "{ext_path}: {semantic} decodes to {:?} values, which glTF accessors cannot hold",
                attribute.component_type()
            ),
        )
    })?;
    let bytes = convert(attribute.bytes(), stored, declared.component_type).ok_or_else(|| {
        SceneError::new(
            ProblemCode::DracoTypeMismatch,
            format!(
                "{ext_path}: {semantic} decodes to {stored:?} values that accessors[{accessor}]'s component type ({:?}) cannot hold",
                declared.component_type
            ),
        )
    })?;
    Ok(DecodedAccessor {
        count: attribute.count(),
        bytes,
    })
}

fn indices_bytes(
    geometry: &PackedGeometry,
    declared: &Declared,
    accessor: usize,
    ext_path: &str,
) -> Result<DecodedAccessor, SceneError> {
    if declared.element_type != ElementType::Scalar
        || !matches!(
            declared.component_type,
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32
        )
    {
        return Err(SceneError::new(
            ProblemCode::DracoTypeMismatch,
            format!(
                "{ext_path}: the indices accessor (accessors[{accessor}]) must be an unsigned SCALAR"
            ),
        ));
    }
    let indices = geometry.indices().ok_or_else(|| {
        SceneError::new(
            ProblemCode::DracoAttributeMissing,
            format!("{ext_path}: the decoded stream has no faces, but the primitive has indices"),
        )
    })?;
    let (count, bytes) = (indices.count(), indices.bytes());
    // An index the declared type cannot hold would silently wrap; refuse it instead.
    let largest = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .max()
        .unwrap_or(0);
    let fits = match declared.component_type {
        ComponentType::U8 => largest <= u32::from(u8::MAX),
        ComponentType::U16 => largest <= u32::from(u16::MAX),
        _ => true,
    };
    if !fits {
        return Err(SceneError::new(
            ProblemCode::DracoTypeMismatch,
            format!(
                "{ext_path}: the stream has vertex index {largest}, which accessors[{accessor}]'s component type cannot hold"
            ),
        ));
    }
    // Checked above: every index fits, so the conversion cannot fail.
    let bytes = convert(bytes, Stored::U32, declared.component_type).unwrap_or_default();
    Ok(DecodedAccessor { count, bytes })
}

/// The component types a decoded Draco attribute arrives in that glTF can also hold, plus
/// i32 (Draco's generic integer), which converts like the reference decoder converts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stored {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
}

impl Stored {
    fn of(component_type: draco_gltf::ComponentType) -> Option<Stored> {
        use draco_gltf::ComponentType as C;
        Some(match component_type {
            C::I8 => Stored::I8,
            C::U8 => Stored::U8,
            C::I16 => Stored::I16,
            C::U16 => Stored::U16,
            C::I32 => Stored::I32,
            C::U32 => Stored::U32,
            C::F32 => Stored::F32,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Stored::I8 | Stored::U8 => 1,
            Stored::I16 | Stored::U16 => 2,
            Stored::I32 | Stored::U32 | Stored::F32 => 4,
        }
    }

    fn read(self, b: &[u8]) -> f64 {
        let at = |i: usize| b.get(i).copied().unwrap_or(0);
        let four = [at(0), at(1), at(2), at(3)];
        match self {
            Stored::I8 => f64::from(at(0) as i8),
            Stored::U8 => f64::from(at(0)),
            Stored::I16 => f64::from(i16::from_le_bytes([at(0), at(1)])),
            Stored::U16 => f64::from(u16::from_le_bytes([at(0), at(1)])),
            Stored::I32 => f64::from(i32::from_le_bytes(four)),
            Stored::U32 => f64::from(u32::from_le_bytes(four)),
            Stored::F32 => f64::from(f32::from_le_bytes(four)),
        }
    }
}

/// Values of type `from` as type `to`: unchanged when the types agree, else converted value by
/// value; `None` when some value does not survive the conversion (a float stream under an
/// integer accessor, an integer too large for the declared type), which would mean the file's
/// accessor does not describe its stream.
fn convert(bytes: &[u8], from: Stored, to: ComponentType) -> Option<Vec<u8>> {
    let same = matches!(
        (from, to),
        (Stored::I8, ComponentType::I8)
            | (Stored::U8, ComponentType::U8)
            | (Stored::I16, ComponentType::I16)
            | (Stored::U16, ComponentType::U16)
            | (Stored::U32, ComponentType::U32)
            | (Stored::F32, ComponentType::F32)
    );
    if same {
        return Some(bytes.to_vec());
    }
    let mut out = Vec::with_capacity(bytes.len() / from.size() * to.size());
    for v in bytes.chunks_exact(from.size()).map(|b| from.read(b)) {
        let (lo, hi) = match to {
            ComponentType::I8 => (f64::from(i8::MIN), f64::from(i8::MAX)),
            ComponentType::U8 => (0.0, f64::from(u8::MAX)),
            ComponentType::I16 => (f64::from(i16::MIN), f64::from(i16::MAX)),
            ComponentType::U16 => (0.0, f64::from(u16::MAX)),
            ComponentType::U32 => (0.0, f64::from(u32::MAX)),
            ComponentType::F32 => (f64::NEG_INFINITY, f64::INFINITY),
        };
        let exact = if to == ComponentType::F32 {
            f64::from(v as f32) == v || v.is_nan()
        } else {
            v.fract() == 0.0 && (lo..=hi).contains(&v)
        };
        if !exact {
            return None;
        }
        match to {
            ComponentType::I8 => out.push(v as i8 as u8),
            ComponentType::U8 => out.push(v as u8),
            ComponentType::I16 => out.extend_from_slice(&(v as i16).to_le_bytes()),
            ComponentType::U16 => out.extend_from_slice(&(v as u16).to_le_bytes()),
            ComponentType::U32 => out.extend_from_slice(&(v as u32).to_le_bytes()),
            ComponentType::F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
        }
    }
    Some(out)
}
