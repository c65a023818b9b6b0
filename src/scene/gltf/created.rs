//! The JSON members tspace adds to a document it edits (new accessors, buffer views, and the
//! one output buffer when the input had none), built as typed `gltf-json` values and serialized,
//! so that what tspace creates is well-formed and correctly named by construction.
//!
//! Only what tspace creates goes through here. The user's JSON is never parsed into these types:
//! it is edited in place by `tspace-json`'s splice editor, which is why everything tspace does not
//! change comes back byte for byte.
//!
//! Numbers: every float tspace creates is an `f32`, and is written with the shortest text that
//! reads back as the same `f32` (`0.1`, not the `0.10000000149011612` that its widening to `f64`
//! would print): [`to_text`] and its [`F32Spelling`] do that for this module and for the OBJ
//! conversion's whole document.

use super::accessor::{ComponentType, ElementType};
use crate::scene::error::{ProblemCode, SceneError};
use gltf_json::accessor::{self as json_accessor, GenericComponentType};
use gltf_json::buffer::{self as json_buffer, Stride};
use gltf_json::validation::{Checked, USize64};
use gltf_json::{Index, Value};

/// `min` and `max` of an accessor, one value per component.
pub type Bounds = (Vec<Value>, Vec<Value>);

/// A float bound (0 for a non-finite one, which glTF does not allow there).
pub fn float_bound(value: f32) -> Value {
    if value.is_finite() {
        Value::from(value)
    } else {
        Value::from(0)
    }
}

/// An integer component's bound.
pub fn integer_bound(value: i64) -> Value {
    Value::from(value)
}

/// A serde formatter for JSON whose floats are all `f32`s: `Value` holds each as the `f64` of
/// equal value, and this spells it as the shortest text of the `f32` instead of the `f64`'s.
/// Any other `f64` is written as usual.
pub(crate) struct F32Spelling;

impl serde_json::ser::Formatter for F32Spelling {
    fn write_f64<W: ?Sized + std::io::Write>(
        &mut self,
        writer: &mut W,
        value: f64,
    ) -> std::io::Result<()> {
        let narrow = value as f32;
        match tspace_json::f32_text(narrow) {
            Some(text) if f64::from(narrow) == value => writer.write_all(text.as_bytes()),
            _ => serde_json::ser::CompactFormatter.write_f64(writer, value),
        }
    }
}

/// Compact JSON text of `value`, floats spelled by [`F32Spelling`].
pub(crate) fn to_text(value: &impl serde::Serialize) -> Result<String, serde_json::Error> {
    let mut text = Vec::new();
    value.serialize(&mut serde_json::Serializer::with_formatter(
        &mut text,
        F32Spelling,
    ))?;
    // The serializer writes only UTF-8.
    Ok(String::from_utf8_lossy(&text).into_owned())
}

/// Serialized, or an internal error: a typed value that does not serialize is a bug here.
fn serialized(value: &impl serde::Serialize, what: &str) -> Result<String, SceneError> {
    to_text(value).map_err(|e| {
        SceneError::new(
            ProblemCode::InternalEdit,
            format!("tspace could not write a new {what}: {e}"),
        )
    })
}

fn index<T>(position: usize, what: &str) -> Result<Index<T>, SceneError> {
    u32::try_from(position).map(Index::new).map_err(|_| {
        SceneError::new(
            ProblemCode::TooLarge,
            format!("{what} {position} is past what a glTF index can hold"),
        )
    })
}

fn component_type(component_type: ComponentType) -> json_accessor::ComponentType {
    match component_type {
        ComponentType::I8 => json_accessor::ComponentType::I8,
        ComponentType::U8 => json_accessor::ComponentType::U8,
        ComponentType::I16 => json_accessor::ComponentType::I16,
        ComponentType::U16 => json_accessor::ComponentType::U16,
        ComponentType::U32 => json_accessor::ComponentType::U32,
        ComponentType::F32 => json_accessor::ComponentType::F32,
    }
}

fn element_type(element_type: ElementType) -> json_accessor::Type {
    match element_type {
        ElementType::Scalar => json_accessor::Type::Scalar,
        ElementType::Vec2 => json_accessor::Type::Vec2,
        ElementType::Vec3 => json_accessor::Type::Vec3,
        ElementType::Vec4 => json_accessor::Type::Vec4,
        ElementType::Mat2 => json_accessor::Type::Mat2,
        ElementType::Mat3 => json_accessor::Type::Mat3,
        ElementType::Mat4 => json_accessor::Type::Mat4,
    }
}

/// What one new accessor says.
pub struct AccessorJson {
    pub view: usize,
    pub component_type: ComponentType,
    pub element_type: ElementType,
    pub normalized: bool,
    pub count: usize,
    pub bounds: Option<Bounds>,
}

/// A new accessor of `count` tightly described elements in buffer view `view`.
pub fn accessor(new: &AccessorJson) -> Result<String, SceneError> {
    let (min, max) = match &new.bounds {
        Some((min, max)) => (
            Some(Value::from(min.clone())),
            Some(Value::from(max.clone())),
        ),
        None => (None, None),
    };
    let typed = gltf_json::Accessor {
        buffer_view: Some(index(new.view, "buffer view")?),
        byte_offset: None,
        count: USize64::from(new.count),
        component_type: Checked::Valid(GenericComponentType(component_type(new.component_type))),
        extensions: None,
        extras: Default::default(),
        type_: Checked::Valid(element_type(new.element_type)),
        min,
        max,
        name: None,
        normalized: new.normalized,
        sparse: None,
    };
    serialized(&typed, "accessor")
}

/// A new buffer view of `length` bytes at `offset` in buffer 0.
pub fn buffer_view(
    offset: usize,
    length: usize,
    stride: Option<usize>,
    target: Option<u32>,
) -> Result<String, SceneError> {
    serialized(
        &typed_view(0, offset, length, stride, target)?,
        "buffer view",
    )
}

fn typed_view(
    buffer: usize,
    offset: usize,
    length: usize,
    stride: Option<usize>,
    target: Option<u32>,
) -> Result<json_buffer::View, SceneError> {
    let target = match target {
        None => None,
        Some(34962) => Some(Checked::Valid(json_buffer::Target::ArrayBuffer)),
        Some(34963) => Some(Checked::Valid(json_buffer::Target::ElementArrayBuffer)),
        Some(other) => {
            return Err(SceneError::new(
                ProblemCode::InternalEdit,
                format!("tspace asked for a buffer view target {other}, which glTF does not have"),
            ));
        }
    };
    Ok(json_buffer::View {
        buffer: index(buffer, "buffer")?,
        byte_length: USize64::from(length),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: stride.map(Stride),
        name: None,
        target,
        extensions: None,
        extras: Default::default(),
    })
}

/// A buffer view whose data is meshopt-compressed: `length` bytes at `offset` of the fallback
/// buffer `buffer`, and `extension` (its `EXT_meshopt_compression` object) saying where the
/// compressed bytes are.
pub fn compressed_buffer_view(
    buffer: usize,
    (offset, length): (usize, usize),
    stride: Option<usize>,
    target: Option<u32>,
    extension: &impl serde::Serialize,
) -> Result<String, SceneError> {
    let mut typed = typed_view(buffer, offset, length, stride, target)?;
    typed.extensions = Some(gltf_json::extensions::buffer::View {
        others: meshopt_extension(extension)?,
    });
    serialized(&typed, "compressed buffer view")
}

/// `{"EXT_meshopt_compression": extension}`, as a buffer view's or buffer's `extensions`.
/// Serialized as it stands, not through a `Value` map: a compressed scene of many small views
/// writes one per view (250,000 in a scene of 50,000 one-triangle primitives), and the map's
/// allocations were a quarter of that write.
pub fn meshopt_extensions(extension: &impl serde::Serialize) -> Result<String, SceneError> {
    #[derive(serde::Serialize)]
    struct Extensions<'e, T> {
        #[serde(rename = "EXT_meshopt_compression")]
        meshopt: &'e T,
    }
    serialized(&Extensions { meshopt: extension }, "meshopt extension")
}

fn meshopt_extension(
    extension: &impl serde::Serialize,
) -> Result<serde_json::Map<String, Value>, SceneError> {
    let value = serde_json::to_value(extension).map_err(|e| internal(&e, "meshopt extension"))?;
    Ok(serde_json::Map::from_iter([(MESHOPT.to_owned(), value)]))
}

/// The buffer without data of its own that compressed views point into, as the extension asks.
pub fn fallback_buffer(byte_length: usize) -> Result<String, SceneError> {
    let typed = gltf_json::Buffer {
        byte_length: USize64::from(byte_length),
        name: None,
        uri: None,
        extensions: Some(gltf_json::extensions::buffer::Buffer {
            others: meshopt_extension(&serde_json::json!({"fallback": true}))?,
        }),
        extras: Default::default(),
    };
    serialized(&typed, "fallback buffer")
}

const MESHOPT: &str = "EXT_meshopt_compression";

fn internal(error: &serde_json::Error, what: &str) -> SceneError {
    SceneError::new(
        ProblemCode::Internal,
        format!("tspace could not build a {what}: {error}"),
    )
}

/// The output's one buffer, when no input buffer had data to keep its other members.
pub fn buffer(byte_length: usize, uri: Option<&str>) -> Result<String, SceneError> {
    let typed = gltf_json::Buffer {
        byte_length: USize64::from(byte_length),
        name: None,
        uri: uri.map(str::to_owned),
        extensions: None,
        extras: Default::default(),
    };
    serialized(&typed, "buffer")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_bounds_are_the_shortest_f32_text() {
        let text = |v: f32| to_text(&float_bound(v)).unwrap();
        assert_eq!(text(0.1), "0.1");
        assert_eq!(text(-2.5), "-2.5");
        assert_eq!(text(f32::NAN), "0");
        assert_eq!(text(1e-7), "1e-7");
    }

    #[test]
    fn an_accessor_says_what_it_describes() {
        let text = accessor(&AccessorJson {
            view: 7,
            component_type: ComponentType::F32,
            element_type: ElementType::Vec3,
            normalized: false,
            count: 24,
            bounds: Some((
                vec![float_bound(-1.0), float_bound(-0.5), float_bound(0.0)],
                vec![float_bound(1.0), float_bound(0.5), float_bound(0.25)],
            )),
        })
        .unwrap();
        let value: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            value,
            serde_json::json!({
                "bufferView": 7, "componentType": 5126, "count": 24, "type": "VEC3",
                // Whole floats are spelled as integers, as tspace-json's f32_text does.
                "min": [-1, -0.5, 0], "max": [1, 0.5, 0.25]
            })
        );
    }

    #[test]
    fn a_buffer_view_keeps_stride_and_target() {
        let text = buffer_view(64, 120, Some(8), Some(34962)).unwrap();
        let value: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            value,
            serde_json::json!({
                "buffer": 0, "byteOffset": 64, "byteLength": 120, "byteStride": 8, "target": 34962
            })
        );
        assert!(buffer_view(0, 4, None, Some(1)).is_err());
    }

    #[test]
    fn a_buffer_names_its_uri_only_when_it_has_one() {
        assert_eq!(buffer(16, None).unwrap(), r#"{"byteLength":16}"#);
        let with_uri: Value =
            serde_json::from_str(&buffer(16, Some("a \"b\".bin")).unwrap()).unwrap();
        assert_eq!(with_uri["uri"], "a \"b\".bin");
    }
}
