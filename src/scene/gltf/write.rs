//! Writing a scene back: the input's JSON with only the members tspace changed spliced in, its
//! buffers' bytes passed through, and new data in new buffer views.
//!
//! The output has one binary buffer (the GLB's BIN chunk, or a `data:` URI for `.gltf`) holding
//! every input buffer that had data, then the new views. Buffers without data of their own
//! (`EXT_meshopt_compression` fallbacks) stay as they are. When a split replaced a primitive's
//! accessors and nothing else refers to the old ones, they and their views are dropped and the
//! kept views are copied one by one, so the file does not carry dead data; every index reference
//! is renumbered. That happens only when every extension in use is one whose references tspace
//! knows ([`super::refs::KNOWN_EXTENSIONS`]) and the file is not meshopt-compressed; otherwise
//! every byte and index stays where it was and the report says why.
//!
//! With `EXT_meshopt_compression` in or out ([`compress::Output`]), the views are copied one by
//! one instead: compressed views keep their compressed bytes (moved, never re-encoded) and get
//! a new place in the one fallback buffer; the views tspace writes are encoded
//! ([`compress::encode`]); with `compress=none` every compressed view is written out decoded.
//! Orphans are then dropped in meshopt files too.

pub mod compress;

use super::accessor::{self, ComponentType, Data, ElementType};
use super::created::{self, AccessorJson, Bounds, float_bound, integer_bound};
use super::glb;
use super::load::{Buffer, BufferSource, Container, Loaded, Resources};
use super::quantize::Snorm;
use super::refs::{self, Owner};
use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::options::Compression;
use crate::scene::pieces::{self, FloatBytes, Part};
use crate::scene::report::{Dropped, Notice, thousands};
use crate::scene::uri;
use crate::scene::{OutputFormat, index32};
use compress::{Encoded, Encoding, Output, Prefiltered, Shape};
use rayon::prelude::*;
use tspace_json::{self as json, Document, Editor, Node, Text};

/// An accessor in the output: one of the input's, or one this write adds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Ref {
    Old(usize),
    New(usize),
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

struct NewView {
    data: ViewData,
    target: Option<u32>,
    byte_stride: Option<usize>,
    /// What the data is, for the meshopt encoder.
    shape: Shape,
    /// For a copy of a filtered meshopt view: the input's pre-filter values, copied alike.
    prefiltered: Option<Prefiltered>,
}

/// A new view's bytes.
enum ViewData {
    Bytes(Vec<u8>),
    /// Float vectors moved in from the computation ([`FloatBytes`]).
    Floats(FloatBytes),
    /// Values still to come ([`Changes::fill_floats`]), this many bytes of them.
    Pending(usize),
}

impl ViewData {
    fn as_slice(&self) -> &[u8] {
        match self {
            ViewData::Bytes(bytes) => bytes,
            ViewData::Floats(floats) => floats.as_ref(),
            ViewData::Pending(_) => &[],
        }
    }

    fn len(&self) -> usize {
        match self {
            ViewData::Pending(len) => *len,
            data => data.as_slice().len(),
        }
    }

    /// The data as a piece of the output, taken out of the view.
    fn take_part(&mut self) -> Part {
        match std::mem::replace(self, ViewData::Bytes(Vec::new())) {
            ViewData::Bytes(bytes) => Part::Owned(bytes),
            ViewData::Floats(floats) => Part::Floats(floats),
            ViewData::Pending(_) => Part::Owned(Vec::new()),
        }
    }
}

/// A view of float vectors whose values come later: a job's tangents, which the primitives that
/// share the job may still read until the last of them is reported. It names its view, and is
/// used up by [`Changes::fill_floats`].
#[must_use]
pub struct PendingFloats {
    view: usize,
}

struct NewAccessor {
    view: usize,
    component_type: ComponentType,
    element_type: ElementType,
    normalized: bool,
    count: usize,
    min_max: Option<Bounds>,
}

/// The changes to one primitive: members to set (attribute name → accessor), and so on.
#[derive(Default, PartialEq)]
pub struct PrimitiveEdit {
    pub attributes: Vec<(Text, Ref)>,
    pub indices: Option<Ref>,
    /// Set `mode` to TRIANGLES (a strip or fan was unrolled).
    pub to_triangle_list: bool,
    /// Per morph target: members to set. Boxed to its length, and empty for most primitives.
    pub targets: Box<[Vec<(Text, Ref)>]>,
    /// Remove `KHR_draco_mesh_compression`: its compressed data no longer matches.
    pub remove_draco: bool,
    /// Point `material` at this one of [`Changes::materials`] (tspace adds one at most).
    pub material: Option<u32>,
}

/// The edited primitives' edits by `(mesh, primitive)`, in that order: a list, since edits come
/// in that order, without a map's room per entry (a scene may edit a hundred thousand). Keys in
/// 32 bits ([`index32`]).
///
/// A primitive names its edit by number, and an edit the same as the one before it is not
/// kept twice: primitives that share a geometry and a material get the same edit, and an
/// exporter that instances a mesh by reference writes such primitives by the hundred
/// thousand. Each edit held for each (80 bytes, and a list of attributes each) was 12.8 MB of
/// the writer's 94 MB peak on the `whole_path` bench's scene of 100,000 such primitives.
#[derive(Default)]
pub struct PrimitiveEdits {
    keys: Vec<((u32, u32), u32)>,
    edits: Vec<PrimitiveEdit>,
}

// One key per edited primitive; a change that grows it should be a decision.
const _: () = assert!(std::mem::size_of::<((u32, u32), u32)>() == 12);

impl PrimitiveEdits {
    fn position(&self, &(mesh, primitive): &(usize, usize)) -> Result<usize, usize> {
        let key = (index32(mesh), index32(primitive));
        self.keys.binary_search_by(|(k, _)| k.cmp(&key))
    }

    pub fn get(&self, key: &(usize, usize)) -> Option<&PrimitiveEdit> {
        let i = self.position(key).ok()?;
        let &(_, edit) = self.keys.get(i)?;
        self.edits.get(edit as usize)
    }

    pub fn contains_key(&self, key: &(usize, usize)) -> bool {
        self.position(key).is_ok()
    }

    /// Sets the edit of `key`, replacing any it had. (A replaced edit stays in the list,
    /// named by nothing: replacing is rare, and the list is read through its keys.)
    pub fn insert(&mut self, key: (usize, usize), edit: PrimitiveEdit) {
        if self.edits.last() != Some(&edit) {
            self.edits.push(edit);
        }
        let edit = index32(self.edits.len() - 1);
        let packed = (index32(key.0), index32(key.1));
        // Edits come in order: the usual one goes at the end without a search.
        if self.keys.last().is_none_or(|&(last, _)| last < packed) {
            self.keys.push((packed, edit));
            return;
        }
        match self.position(&key) {
            Ok(i) => {
                if let Some(slot) = self.keys.get_mut(i) {
                    slot.1 = edit;
                }
            }
            Err(i) => self.keys.insert(i, (packed, edit)),
        }
    }

    /// Room for `primitives` more keys. The edits themselves grow as they come: most scenes
    /// have one per primitive, and a scene of shared geometry has one for many.
    fn reserve(&mut self, primitives: usize) {
        self.keys.reserve_exact(primitives);
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Each primitive's edit, in order (a shared edit once for each of its primitives).
    pub fn values(&self) -> impl Iterator<Item = &PrimitiveEdit> {
        self.iter().map(|(_, edit)| edit)
    }

    pub fn iter(&self) -> impl Iterator<Item = ((usize, usize), &PrimitiveEdit)> {
        self.keys.iter().filter_map(|&((mesh, primitive), edit)| {
            let edit = self.edits.get(edit as usize)?;
            Some(((mesh as usize, primitive as usize), edit))
        })
    }
}

/// New accessors and views, and the changes to primitives, collected before anything is
/// written.
#[derive(Default)]
pub struct Changes {
    views: Vec<NewView>,
    accessors: Vec<NewAccessor>,
    pub primitives: PrimitiveEdits,
    /// Materials to append, as JSON text, in order.
    pub materials: Vec<String>,
    /// Extensions the added materials use: listed in `extensionsUsed` (not required: a viewer
    /// without them still shows the scene).
    pub extensions_used: Vec<&'static str>,
}

/// The bytes of `values` as glTF stores them, little-endian: where the machine is too, one copy
/// of their memory (a value at a time, a 2M-triangle mesh's tangents took a fifth longer).
fn little_endian_bytes<T: bytemuck::Pod>(values: &[T], to_le: fn(T) -> [u8; 4]) -> Vec<u8> {
    if cfg!(target_endian = "little") {
        bytemuck::cast_slice(values).to_vec()
    } else {
        values.iter().flat_map(|&v| to_le(v)).collect()
    }
}

impl Changes {
    /// Room for `views` more new views and accessors (as many as the jobs add) and
    /// `primitives` more edits, so that the lists are not grown by doubling (room no edit uses
    /// is never touched).
    pub fn reserve(&mut self, views: usize, primitives: usize) {
        self.views.reserve_exact(views);
        self.accessors.reserve_exact(views);
        self.primitives.reserve(primitives);
    }

    fn push_view(
        &mut self,
        data: Vec<u8>,
        target: Option<u32>,
        byte_stride: Option<usize>,
        shape: Shape,
    ) -> usize {
        self.push_view_data(ViewData::Bytes(data), target, byte_stride, shape)
    }

    fn push_view_data(
        &mut self,
        data: ViewData,
        target: Option<u32>,
        byte_stride: Option<usize>,
        shape: Shape,
    ) -> usize {
        self.views.push(NewView {
            data,
            target,
            byte_stride,
            shape,
            prefiltered: None,
        });
        self.views.len() - 1
    }

    fn push_accessor(&mut self, accessor: NewAccessor) -> Ref {
        self.accessors.push(accessor);
        Ref::New(self.accessors.len() - 1)
    }

    /// A float vertex attribute (TANGENT, NORMAL, a morph target's TANGENT deltas).
    pub fn add_floats<const N: usize>(&mut self, values: &[[f32; N]], with_min_max: bool) -> Ref {
        let data = little_endian_bytes(values.as_flattened(), f32::to_le_bytes);
        let min_max = with_min_max.then(|| {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in values {
                for i in 0..N {
                    if v[i].is_finite() {
                        lo[i] = lo[i].min(v[i]);
                        hi[i] = hi[i].max(v[i]);
                    }
                }
            }
            let list = |a: [f32; N]| a.iter().map(|&x| float_bound(x)).collect();
            (list(lo), list(hi))
        });
        self.push_float_attribute::<N>(ViewData::Bytes(data), values.len(), min_max)
    }

    /// A vec4 float vertex attribute (TANGENT) of `count` values still to come: they are given
    /// with [`Changes::fill_floats`], moved in rather than copied.
    pub fn add_floats_later(&mut self, count: usize) -> (Ref, PendingFloats) {
        let r = self.push_float_attribute::<4>(ViewData::Pending(count * 16), count, None);
        let view = self.views.len() - 1;
        (r, PendingFloats { view })
    }

    /// The view of `count` float vectors of `N` components, and their accessor.
    fn push_float_attribute<const N: usize>(
        &mut self,
        data: ViewData,
        count: usize,
        min_max: Option<Bounds>,
    ) -> Ref {
        let view = self.push_view_data(
            data,
            Some(ARRAY_BUFFER),
            None,
            Shape::Vertex { stride: N * 4 },
        );
        let element_type = match N {
            2 => ElementType::Vec2,
            3 => ElementType::Vec3,
            4 => ElementType::Vec4,
            _ => ElementType::Scalar,
        };
        self.push_accessor(NewAccessor {
            view,
            component_type: ComponentType::F32,
            element_type,
            normalized: false,
            count,
            min_max,
        })
    }

    /// Gives a view of [`Changes::add_floats_later`] its values, which must be as many as it
    /// was made for.
    pub fn fill_floats(
        &mut self,
        pending: PendingFloats,
        values: Vec<[f32; 4]>,
    ) -> Result<(), SceneError> {
        let PendingFloats { view } = pending;
        let Some(slot) = self.views.get_mut(view) else {
            return Err(SceneError::new(
                ProblemCode::Internal,
                format!("new view {view} to fill does not exist"),
            ));
        };
        let ViewData::Pending(len) = slot.data else {
            return Err(SceneError::new(
                ProblemCode::Internal,
                format!("new view {view} was filled twice"),
            ));
        };
        if values.len() * 16 != len {
            return Err(SceneError::new(
                ProblemCode::Internal,
                format!(
                    "new view {view} was made for {} values and given {}",
                    len / 16,
                    values.len()
                ),
            ));
        }
        slot.data = match FloatBytes::new(values) {
            Ok(floats) => ViewData::Floats(floats),
            Err(values) => {
                ViewData::Bytes(little_endian_bytes(values.as_flattened(), f32::to_le_bytes))
            }
        };
        Ok(())
    }

    /// Normalized signed integer vectors (quantized TANGENT or its morph deltas), already
    /// packed: `size` bytes per element, padded to `stride` when that differs.
    pub fn add_snorm(
        &mut self,
        bytes: Vec<u8>,
        count: usize,
        snorm: Snorm,
        element_type: ElementType,
    ) -> Ref {
        self.add_snorm_filtered(bytes, count, snorm, element_type, None)
    }

    /// [`Changes::add_snorm`], with the values a meshopt filter stores for them: compressed
    /// output then uses the filter (after checking that it decodes to `bytes` exactly).
    pub fn add_snorm_filtered(
        &mut self,
        bytes: Vec<u8>,
        count: usize,
        snorm: Snorm,
        element_type: ElementType,
        prefiltered: Option<Prefiltered>,
    ) -> Ref {
        let component_type = match snorm {
            Snorm::I8 => ComponentType::I8,
            Snorm::I16 => ComponentType::I16,
        };
        let size = component_type.size() * element_type.components();
        let stride = bytes.len().checked_div(count).unwrap_or(size);
        let view = self.push_view(
            bytes,
            Some(ARRAY_BUFFER),
            (stride != size).then_some(stride),
            Shape::Vertex { stride },
        );
        self.views[view].prefiltered = prefiltered;
        self.push_accessor(NewAccessor {
            view,
            component_type,
            element_type,
            normalized: true,
            count,
            min_max: None,
        })
    }

    /// An index list, as 16-bit indices when every vertex fits (65535 is the restart value,
    /// which glTF forbids), else 32-bit.
    pub fn add_indices(&mut self, indices: &[u32], vertex_count: usize) -> Ref {
        let (component_type, data) = if vertex_count <= 65535 {
            let mut data = Vec::with_capacity(indices.len() * 2);
            for &i in indices {
                data.extend_from_slice(&(i as u16).to_le_bytes());
            }
            (ComponentType::U16, data)
        } else {
            (
                ComponentType::U32,
                little_endian_bytes(indices, u32::to_le_bytes),
            )
        };
        let size = component_type.size();
        let view = self.push_view(
            data,
            Some(ELEMENT_ARRAY_BUFFER),
            None,
            Shape::Index {
                size,
                triangles: true,
            },
        );
        self.push_accessor(NewAccessor {
            view,
            component_type,
            element_type: ElementType::Scalar,
            normalized: false,
            count: indices.len(),
            min_max: None,
        })
    }

    /// Copies accessor `index` of the input, element `source[v]` for each new vertex `v`, into a
    /// new accessor of the same type. Vertex elements start on 4-byte boundaries, as glTF
    /// requires, so 3-byte or 6-byte elements get a stride.
    pub fn add_remapped(
        &mut self,
        root: &Node,
        data: Data<'_>,
        index: usize,
        source: &[u32],
        max_elements: usize,
        is_position: bool,
    ) -> Result<Ref, SceneError> {
        let data_source = data;
        let described = data
            .accessor(root, index)
            .map_err(super::compute::accessor_error)?;
        let raw =
            accessor::read_raw(&described, max_elements).map_err(super::compute::accessor_error)?;
        let size = raw.element_size;
        let stride = size.next_multiple_of(4);
        let mut data = vec![0u8; source.len() * stride];
        for (slot, &s) in data.chunks_exact_mut(stride).zip(source) {
            let element = raw.element(s as usize).ok_or_else(|| {
                SceneError::new(
                    ProblemCode::InvalidPrimitive,
                    format!(
                        "accessors[{index}] has {} elements but vertex {s} is used",
                        raw.len()
                    ),
                )
            })?;
            slot[..size].copy_from_slice(element);
        }
        let had_min_max = root
            .get("accessors")
            .and_then(|a| a.index(index))
            .is_some_and(|a| a.get("min").is_some() || a.get("max").is_some());
        let min_max = (had_min_max || is_position)
            .then(|| {
                min_max_of(
                    &data,
                    stride,
                    described.component_type,
                    described.element_type,
                )
            })
            .flatten();
        let view = self.push_view(
            data,
            Some(ARRAY_BUFFER),
            (stride != size).then_some(stride),
            Shape::Vertex { stride },
        );
        self.views[view].prefiltered =
            prefiltered_copy(root, data_source, index, source, size, stride);
        Ok(self.push_accessor(NewAccessor {
            view,
            component_type: described.component_type,
            element_type: described.element_type,
            normalized: described.normalized,
            count: source.len(),
            min_max,
        }))
    }
}

/// When accessor `index` reads a meshopt view stored with a filter (one element per stride, from
/// the view's start), its pre-filter values copied like the elements (`source`), padding zeroed:
/// encoding these with the same filter gives exactly the copied bytes, where the filter keeps
/// padding as stored (octahedral's fourth component). `None` in every other case.
fn prefiltered_copy(
    root: &Node,
    data: Data<'_>,
    index: usize,
    source: &[u32],
    size: usize,
    stride: usize,
) -> Option<Prefiltered> {
    let accessor = root.get("accessors")?.index(index)?;
    if accessor.get("sparse").is_some() || usize_of(accessor.get("byteOffset")) != 0 {
        return None;
    }
    let v = usize::try_from(accessor.get("bufferView")?.as_u64()?).ok()?;
    let (_, ext) = compress::extension(root.get("bufferViews")?.index(v)?)?;
    let filter = tspace_meshopt::Filter::from_name(ext.get("filter")?.as_str()?).ok()?;
    let mode = tspace_meshopt::Mode::from_name(ext.get("mode")?.as_str()?).ok()?;
    let count = usize_of(ext.get("count"));
    if filter == tspace_meshopt::Filter::None
        || mode != tspace_meshopt::Mode::Attributes
        || usize_of(ext.get("byteStride")) != stride
    {
        return None;
    }
    let (buffer, offset, length) = compress::compressed_range(ext)?;
    let compressed = data
        .buffers
        .get(buffer)?
        .get(offset..offset.checked_add(length)?)?;
    let pre = tspace_meshopt::decode(
        &tspace_meshopt::Compressed {
            data: compressed,
            count,
            byte_stride: stride,
            mode,
            filter: tspace_meshopt::Filter::None,
        },
        count.checked_mul(stride)?,
    )
    .ok()?;
    let mut bytes = vec![0u8; source.len() * stride];
    for (slot, &s) in bytes.chunks_exact_mut(stride).zip(source) {
        let at = (s as usize).checked_mul(stride)?;
        slot[..size].copy_from_slice(pre.get(at..at + size)?);
    }
    Some(Prefiltered { bytes, filter })
}

/// Per-component minimum and maximum of vector or scalar elements, in the component type's own
/// values (glTF's `min`/`max` ignore `normalized`). Matrices get none (they are optional there).
fn min_max_of(
    data: &[u8],
    stride: usize,
    component_type: ComponentType,
    element_type: ElementType,
) -> Option<Bounds> {
    let n = match element_type {
        ElementType::Scalar => 1,
        ElementType::Vec2 => 2,
        ElementType::Vec3 => 3,
        ElementType::Vec4 => 4,
        _ => return None,
    };
    let size = component_type.size();
    let value = |b: &[u8]| -> f64 {
        match (component_type, b) {
            (ComponentType::I8, [a, ..]) => f64::from(*a as i8),
            (ComponentType::U8, [a, ..]) => f64::from(*a),
            (ComponentType::I16, [a, b, ..]) => f64::from(i16::from_le_bytes([*a, *b])),
            (ComponentType::U16, [a, b, ..]) => f64::from(u16::from_le_bytes([*a, *b])),
            (ComponentType::U32, [a, b, c, d, ..]) => {
                f64::from(u32::from_le_bytes([*a, *b, *c, *d]))
            }
            (ComponentType::F32, [a, b, c, d, ..]) => {
                f64::from(f32::from_le_bytes([*a, *b, *c, *d]))
            }
            _ => 0.0,
        }
    };
    let mut lo = vec![f64::INFINITY; n];
    let mut hi = vec![f64::NEG_INFINITY; n];
    for element in data.chunks_exact(stride) {
        for i in 0..n {
            let v = element.get(i * size..).map_or(0.0, value);
            if v.is_finite() {
                lo[i] = lo[i].min(v);
                hi[i] = hi[i].max(v);
            }
        }
    }
    let bounds = |list: &[f64]| {
        list.iter()
            .map(|&v| {
                if !v.is_finite() {
                    integer_bound(0)
                } else if component_type == ComponentType::F32 {
                    float_bound(v as f32)
                } else {
                    integer_bound(v as i64)
                }
            })
            .collect()
    };
    Some((bounds(&lo), bounds(&hi)))
}

/// What [`write()`] produced.
pub struct Written {
    /// The file, unless it was written as [`Written::pieces`].
    pub bytes: Vec<u8>,
    /// The GLB as pieces, when asked for with the input they may refer to.
    pub pieces: Option<pieces::Pieces>,
    /// Bytes of external images the output now embeds.
    pub embedded_image_bytes: u64,
    pub dropped: Dropped,
    pub notices: Vec<Notice>,
}

fn edit_error(error: json::EditError) -> SceneError {
    // Edits are made from the document's own nodes; failing here is a bug, reported as such.
    SceneError::new(
        ProblemCode::InternalEdit,
        format!("tspace could not edit the document: {error}"),
    )
}

fn usize_of(node: Option<&Node>) -> usize {
    node.and_then(Node::as_u64)
        .and_then(|n| usize::try_from(n).ok())
        .unwrap_or(0)
}

fn align(offset: usize, to: usize) -> usize {
    offset.next_multiple_of(to)
}

/// The MIME type of an image from its first bytes (never decoded), if glTF knows it.
fn sniff_image(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        Some("image/webp")
    } else if bytes.starts_with(b"\xABKTX 20\xBB\r\n\x1a\n") {
        Some("image/ktx2")
    } else {
        None
    }
}

/// Writes the scene with `changes` applied: find what the edits leave unreferenced and whether
/// it may go, gather the images a GLB must carry, lay out the one output buffer, edit the JSON
/// to match it, and emit the container: as one vector, or with `pieces_of` (the input's bytes)
/// as [`pieces::Pieces`] that take the new views' data over from `changes` and refer to the
/// input where the output repeats it.
pub fn write(
    loaded: Loaded<'_>,
    mut changes: Changes,
    format: OutputFormat,
    compression: Compression,
    resources: &dyn Resources<'_>,
    pieces_of: Option<&[u8]>,
    release_freed_memory: Option<fn()>,
) -> Result<Written, SceneError> {
    let Loaded {
        container,
        doc,
        buffers,
        other_chunks,
    } = loaded;
    if let Some(view) = changes
        .views
        .iter()
        .position(|v| matches!(v.data, ViewData::Pending(_)))
    {
        return Err(SceneError::new(
            ProblemCode::Internal,
            format!("new view {view} never got its values"),
        ));
    }
    let (json, layout, mut images, mut written) =
        edit(&doc, &buffers, &mut changes, format, compression, resources)?;
    // The edited JSON refers to the input's text alone. The tree goes before the output is
    // assembled: in a scene of many small objects it is several times its text, and the
    // output's JSON about the size of that text again.
    let json_bytes = doc.source().len();
    drop(doc);
    if json_bytes >= RELEASE_FROM_JSON_BYTES
        && let Some(release) = release_freed_memory
    {
        release();
    }
    let other: &[glb::Chunk<'_>] = if container == Container::Glb {
        &other_chunks
    } else {
        &[]
    };
    match pieces_of {
        Some(input) if format == OutputFormat::Glb => {
            let pieces = emit_pieces(other, &json, layout, (&mut changes, &mut images), input)?;
            written.pieces = Some(pieces);
        }
        _ => written.bytes = emit(other, &json, &layout, format, (&changes, &images))?,
    }
    Ok(written)
}

/// From this much input JSON, [`write()`] offers the freed tree's memory back
/// ([`crate::scene::SceneOptions::release_freed_memory`]). The tree is then tens of megabytes,
/// all of it in small blocks, while the output's JSON is one block about the size of the text
/// (and the allocator maps blocks that large afresh): the service held both, and its peak on
/// the JSON-heavy scene without normals (27 MB) was 288 MB, 10.8 times the body; handing the
/// tree's memory back first (8–10 ms) made it 262 MB. A smaller tree is not worth the pages the
/// next request would fault in again.
const RELEASE_FROM_JSON_BYTES: usize = 4 << 20;

/// Everything [`write()`] does but emit the container: the edited JSON, the output buffer,
/// and what the report needs to know (with no bytes yet).
fn edit<'a, 'l>(
    doc: &Document<'a>,
    input_buffers: &'l [Buffer<'a>],
    changes: &mut Changes,
    format: OutputFormat,
    compression: Compression,
    resources: &dyn Resources<'_>,
) -> Result<(json::Rendered<'a>, Layout<'l>, Images, Written), SceneError> {
    let root = doc.root();
    let output = compress::resolve(compression, root);
    let mut warnings = Vec::new();
    let orphans = Orphans::find(root, changes);
    let (dropping, kept_because) = match may_drop_orphans(root, &orphans) {
        Ok(dropping) => (dropping, None),
        Err(why) => (false, Some(why)),
    };
    let numbering = Numbering::new(&orphans, dropping);
    let buffers = BufferMap::new(input_buffers);
    let images = match format {
        OutputFormat::Glb => embed_images(root, resources, &mut warnings),
        OutputFormat::GltfEmbedded => Images::default(),
    };
    let mut layout = match output {
        Output::Keep => lay_out_buffer(root, &buffers, &numbering, changes, &images, format)?,
        _ => {
            let recompress = compression == Compression::Meshopt;
            lay_out_packed(
                root, &buffers, &numbering, changes, &images, output, recompress,
            )?
        }
    };

    let mut editor = Editor::new(doc);
    drop_accessors(&mut editor, root, &numbering)?;
    renumber_view_refs(&mut editor, root, &numbering, changes)?;
    append_accessors(&mut editor, root, &numbering, changes)?;
    match &layout.packed {
        None => edit_buffer_views(&mut editor, root, &buffers, &numbering, &layout)?,
        Some(packed) => edit_buffer_views_packed(&mut editor, root, &numbering, packed)?,
    }
    append_buffer_views(&mut editor, root, changes, &images, &layout)?;
    renumber_accessor_refs(&mut editor, root, &numbering, changes)?;
    let first_new_material = append_materials(&mut editor, root, changes)?;
    edit_primitives(
        &mut editor,
        root,
        &numbering,
        changes,
        first_new_material,
        &mut warnings,
    )?;
    // In the editor now, and read by nothing after: one per edited primitive, they go before
    // the edited document is put together (in a scene of many small primitives, a tenth of
    // that step's peak).
    drop(std::mem::take(&mut changes.primitives));
    let changes = &*changes;
    point_images_at_views(
        &mut editor,
        root,
        &images,
        numbering.kept_views + changes.views.len(),
    )?;
    match &layout.packed {
        None => edit_buffers(
            &mut editor,
            doc,
            &buffers,
            &layout,
            (changes, &images),
            format,
            &mut warnings,
        )?,
        Some(packed) => {
            edit_buffers_packed(
                &mut editor,
                doc,
                &buffers,
                &layout,
                (changes, &images),
                format,
                &mut warnings,
            )?;
            list_meshopt(&mut editor, root, packed)?;
        }
    }
    list_material_extensions(&mut editor, root, changes)?;
    if let Some(packed) = &layout.packed {
        // Gone before the document is rendered: one entry per compressed view.
        let compressed_views = packed.compressed_views(&numbering);
        if !compressed_views.is_empty() {
            warnings.push(Notice::new(
                "output_compressed",
                describe_compression(&compressed_views, Some(packed)),
            ));
        }
    }
    let dropped = Dropped {
        accessors: (numbering.accessor_map.len() - numbering.kept_accessors) as u64,
        buffer_views: (numbering.view_map.len() - numbering.kept_views) as u64,
        kept_because,
    };
    // Rendering is the write's peak, beside the tree and the editor's records. What it does
    // not read goes first: the numbering and where each view went, an entry per view each (a
    // quarter of a million in a compressed scene of many small views).
    drop(numbering);
    layout.keep_bytes_only();
    let json = editor.into_rendered().map_err(edit_error)?;
    let written = Written {
        bytes: Vec::new(),
        pieces: None,
        embedded_image_bytes: images.external_bytes,
        dropped,
        notices: warnings,
    };
    Ok((json, layout, images, written))
}

/// The input's accessors and buffer views that something referred to and nothing will once
/// the edits are made (a split primitive's old attributes, and their views).
struct Orphans {
    accessors: Vec<bool>,
    views: Vec<bool>,
}

impl Orphans {
    // The references are visited where they sit in the tree rather than listed: a list held
    // 24 bytes for each, 7.6 MB of the writer's 94.6 MB peak on a scene of 100,000 primitives
    // sharing one geometry, and building it walked the tree twice (counting, then filling).
    fn find(root: &Node, changes: &Changes) -> Orphans {
        let accessors = orphan_accessors(root, changes);
        let views = orphan_views(root, changes, &accessors);
        Orphans { accessors, views }
    }

    fn count(&self) -> usize {
        self.accessors
            .iter()
            .chain(&self.views)
            .filter(|&&o| o)
            .count()
    }
}

fn is_edited(owner: Owner, changes: &Changes) -> bool {
    owner
        .primitive()
        .is_some_and(|key| changes.primitives.contains_key(&key))
}

/// Referenced before, and after the edits by neither an unedited owner nor an edited
/// primitive's final members.
fn orphan_accessors(root: &Node, changes: &Changes) -> Vec<bool> {
    let count = root
        .get("accessors")
        .and_then(Node::as_array)
        .map_or(0, <[Node]>::len);
    let mut referenced_before = vec![false; count];
    let mut referenced_after = vec![false; count];
    // A primitive's references come one after another: its edit is looked up once for them
    // all (a lookup per reference was a twelfth of a scene of 100,000 small primitives).
    let mut last: Option<(Owner, bool)> = None;
    refs::visit_accessor_refs(root, &mut |(owner, node)| {
        let i = refs::held(node);
        if let Some(r) = referenced_before.get_mut(i) {
            *r = true;
        }
        let edited = match last {
            Some((previous, edited)) if previous == owner => edited,
            _ => {
                let edited = is_edited(owner, changes);
                last = Some((owner, edited));
                edited
            }
        };
        if !edited && let Some(r) = referenced_after.get_mut(i) {
            *r = true;
        }
    });
    visit_final_primitive_accessors(root, changes, |r| {
        if let Ref::Old(i) = r
            && let Some(a) = referenced_after.get_mut(i)
        {
            *a = true;
        }
    });
    referenced_before
        .iter()
        .zip(&referenced_after)
        .map(|(b, a)| *b && !*a)
        .collect()
}

/// Referenced before, and after the edits only by orphan accessors or by the Draco extensions
/// the edits remove.
fn orphan_views(root: &Node, changes: &Changes, orphan_accessor: &[bool]) -> Vec<bool> {
    let count = root
        .get("bufferViews")
        .and_then(Node::as_array)
        .map_or(0, <[Node]>::len);
    // Usually nothing that refers to a view goes away (TANGENT is added beside what was
    // there), and then no view is orphaned. The walk below reads every view reference's node
    // again, scattered over the tree: 21 ms for the 200,000 of the JSON-heavy scene.
    let anything_dies =
        orphan_accessor.contains(&true) || changes.primitives.values().any(|e| e.remove_draco);
    if !anything_dies {
        return vec![false; count];
    }
    let mut view_before = vec![false; count];
    let mut view_after = vec![false; count];
    refs::visit_view_refs(root, &mut |(owner, node)| {
        let v = refs::held(node);
        if let Some(b) = view_before.get_mut(v) {
            *b = true;
        }
        if !reference_dies(owner, changes, orphan_accessor)
            && let Some(a) = view_after.get_mut(v)
        {
            *a = true;
        }
    });
    view_before
        .iter()
        .zip(&view_after)
        .map(|(b, a)| *b && !*a)
        .collect()
}

/// Whether a view reference goes away with its owner: an orphan accessor, or a primitive whose
/// Draco extension is removed.
fn reference_dies(owner: Owner, changes: &Changes, orphan_accessor: &[bool]) -> bool {
    match owner {
        Owner::Accessor(a) => orphan_accessor.get(a as usize).copied().unwrap_or(false),
        Owner::Primitive(m, p) => changes
            .primitives
            .get(&(m as usize, p as usize))
            .is_some_and(|e| e.remove_draco),
        _ => false,
    }
}

/// Whether the orphans may be dropped (`Ok(false)` when there are none). They stay, and the
/// error says why for the report, when an extension tspace does not know might refer to them.
fn may_drop_orphans(root: &Node, orphans: &Orphans) -> Result<bool, String> {
    if orphans.count() == 0 {
        return Ok(false);
    }
    // The meshopt extensions refer to buffers, never to accessors or views, and the packed
    // layout moves their compressed bytes and fallback ranges.
    let unknown: Vec<String> = refs::unknown_extensions(root)
        .into_iter()
        .filter(|e| e != compress::EXT && e != compress::KHR)
        .collect();
    if !unknown.is_empty() {
        return Err(format!(
            "the file uses {}, which may refer to accessors or buffer views in ways tspace does not know",
            unknown.join(", ")
        ));
    }
    Ok(true)
}

/// Where each input accessor and view lands in the output: kept ones are renumbered in order
/// when orphans are dropped, and new ones follow the kept ones.
struct Numbering {
    dropping: bool,
    /// Per input accessor: its output index, or `usize::MAX` when dropped.
    accessor_map: Vec<usize>,
    view_map: Vec<usize>,
    kept_accessors: usize,
    kept_views: usize,
}

impl Numbering {
    fn new(orphans: &Orphans, dropping: bool) -> Numbering {
        // Dropped entries are marked usize::MAX; the rest are numbered in order.
        let map = |orphan: &[bool]| -> (Vec<usize>, usize) {
            let mut next = 0;
            let map = orphan
                .iter()
                .map(|&o| {
                    if dropping && o {
                        usize::MAX
                    } else {
                        next += 1;
                        next - 1
                    }
                })
                .collect();
            (map, next)
        };
        let (accessor_map, kept_accessors) = map(&orphans.accessors);
        let (view_map, kept_views) = map(&orphans.views);
        Numbering {
            dropping,
            accessor_map,
            view_map,
            kept_accessors,
            kept_views,
        }
    }

    fn keeps_accessor(&self, i: usize) -> bool {
        self.accessor_map.get(i).is_none_or(|&n| n != usize::MAX)
    }

    fn keeps_view(&self, v: usize) -> bool {
        self.view_map.get(v).is_none_or(|&n| n != usize::MAX)
    }

    /// An accessor's index in the output.
    fn accessor(&self, r: Ref) -> usize {
        match r {
            Ref::Old(i) => self.accessor_map.get(i).copied().unwrap_or(i),
            Ref::New(k) => self.kept_accessors + k,
        }
    }

    /// An input view's index in the output (its own when it is out of range: a reference
    /// left as it was).
    fn view(&self, v: usize) -> usize {
        self.view_map.get(v).copied().unwrap_or(v)
    }
}

/// Where the input's buffers go: every buffer with data into output buffer 0; those without
/// (meshopt fallbacks) after it, in order.
struct BufferMap<'l> {
    buffers: &'l [Buffer<'l>],
    /// Per input buffer: its output index.
    map: Vec<usize>,
}

impl<'l> BufferMap<'l> {
    fn new(buffers: &'l [Buffer<'l>]) -> Self {
        let mut empty_count = 0;
        let map = buffers
            .iter()
            .map(|b| {
                if b.source == BufferSource::Empty {
                    empty_count += 1;
                    empty_count // after the merged buffer
                } else {
                    0
                }
            })
            .collect();
        BufferMap { buffers, map }
    }

    fn has_data(&self, b: usize) -> bool {
        self.buffers
            .get(b)
            .is_some_and(|b| b.source != BufferSource::Empty)
    }

    fn output_index(&self, b: usize) -> usize {
        self.map.get(b).copied().unwrap_or(0)
    }
}

/// The images a GLB embeds, as new views after the changes' own.
#[derive(Default)]
struct Images {
    /// `(image, index into data, MIME type)`.
    views: Vec<(usize, usize, &'static str)>,
    data: Vec<Vec<u8>>,
    /// Bytes of the embedded images that came from outside the file (not `data:` URIs), for
    /// the report's input size.
    external_bytes: u64,
}

/// A GLB must carry its images, so external ones (and `data:` URIs, which draw a validator
/// warning in a GLB) become buffer views. An image that was not supplied, or is not a format
/// glTF knows, stays a reference, with a warning.
fn embed_images(root: &Node, resources: &dyn Resources<'_>, warnings: &mut Vec<Notice>) -> Images {
    let mut images = Images::default();
    for (i, image) in root
        .get("images")
        .and_then(Node::as_array)
        .unwrap_or(&[])
        .iter()
        .enumerate()
    {
        let Some(u) = image.get("uri").and_then(Node::as_str) else {
            continue;
        };
        let (fetched, external) = match uri::decode_data_uri(u) {
            Some(Ok(data)) => (Ok(std::borrow::Cow::Owned(data.bytes)), false),
            Some(Err(_)) => continue,
            None => (resources.fetch(u), true),
        };
        let Ok(bytes) = fetched else {
            warnings.push(Notice::new("image_not_supplied", format!(
                "images[{i}] refers to {u:?}, which was not supplied; the GLB keeps the reference, so that file must travel with it"
            )));
            continue;
        };
        let declared = image
            .get("mimeType")
            .and_then(Node::as_str)
            .and_then(|m| match m {
                "image/png" => Some("image/png"),
                "image/jpeg" => Some("image/jpeg"),
                "image/webp" => Some("image/webp"),
                "image/ktx2" => Some("image/ktx2"),
                _ => None,
            });
        let Some(mime) = declared.or_else(|| sniff_image(&bytes)) else {
            warnings.push(Notice::new("image_format_unknown", format!(
                "images[{i}] ({u}) is not PNG, JPEG, WebP or KTX2 by its first bytes; it stays an external reference"
            )));
            continue;
        };
        if external {
            images.external_bytes += bytes.len() as u64;
        }
        images.views.push((i, images.data.len(), mime));
        images.data.push(bytes.into_owned());
    }
    images
}

/// For an analysis, which writes nothing: the images `embed_images` would warn were not
/// supplied, so that analysing a scene warns of what processing it would.
pub fn unsupplied_images(root: &Node, resources: &dyn Resources<'_>) -> Vec<Notice> {
    let images = root.get("images").and_then(Node::as_array).unwrap_or(&[]);
    images
        .iter()
        .enumerate()
        .filter_map(|(i, image)| Some((i, image.get("uri")?.as_str()?)))
        .filter(|(_, u)| uri::decode_data_uri(u).is_none() && !resources.has(u))
        .map(|(i, u)| Notice::new("image_not_supplied", format!(
            "images[{i}] refers to {u:?}, which was not supplied; a GLB written from this scene keeps the reference, so that file must travel with it"
        )))
        .collect()
}

/// The output buffer, laid out as the pieces it is made of: slices of the input's buffers, of
/// the new views and of the images, with the zeros that align them between. Nothing is copied
/// until the container is emitted, which copies each byte once, into the file: laying the
/// buffer out in a vector of its own first cost a copy of the whole buffer and the page faults
/// of a second allocation its size (a fifth of the time outside the core on a 2M-triangle
/// GLB).
#[derive(Default)]
struct BinPieces<'s> {
    parts: Vec<Piece<'s>>,
    len: usize,
}

enum Piece<'s> {
    /// Bytes of the input's buffers, or alignment zeros.
    Borrowed(&'s [u8]),
    /// A buffer built for the output (the packed layout's).
    Owned(Vec<u8>),
    /// The data of the changes' new view of this index.
    View(usize),
    /// The bytes of the embedded image of this index in [`Images::data`].
    Image(usize),
}

/// Alignment padding, borrowed: no padding is longer.
static ZEROS: [u8; 32] = [0; 32];

impl<'s> BinPieces<'s> {
    fn owned(bytes: Vec<u8>) -> BinPieces<'s> {
        BinPieces {
            len: bytes.len(),
            parts: vec![Piece::Owned(bytes)],
        }
    }

    fn len(&self) -> usize {
        self.len
    }

    fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends zeros up to `at` (at most 31 of them: callers align to 4 or 16, plus an offset
    /// below 16).
    fn pad_to(&mut self, at: usize) {
        let zeros = at.saturating_sub(self.len);
        let mut left = zeros;
        while left > 0 {
            let n = left.min(ZEROS.len());
            self.parts.push(Piece::Borrowed(&ZEROS[..n]));
            left -= n;
        }
        self.len += zeros;
    }

    fn push(&mut self, bytes: &'s [u8]) {
        self.len += bytes.len();
        self.parts.push(Piece::Borrowed(bytes));
    }

    /// Appends a piece of `len` bytes held elsewhere (a new view's or an image's).
    fn push_held(&mut self, piece: Piece<'s>, len: usize) {
        self.len += len;
        self.parts.push(piece);
    }

    fn slices<'a>(&'a self, changes: &'a Changes, images: &'a Images) -> Vec<&'a [u8]> {
        self.parts
            .iter()
            .map(|p| match p {
                Piece::Borrowed(b) => *b,
                Piece::Owned(v) => v.as_slice(),
                Piece::View(i) => changes.views.get(*i).map_or(&[][..], |v| v.data.as_slice()),
                Piece::Image(i) => images.data.get(*i).map_or(&[][..], Vec::as_slice),
            })
            .collect()
    }

    fn to_vec(&self, changes: &Changes, images: &Images) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.len);
        for slice in self.slices(changes, images) {
            out.extend_from_slice(slice);
        }
        out
    }
}

/// The output buffer's bytes and where every view lies in it.
struct Layout<'s> {
    bin: BinPieces<'s>,
    /// Per input view: its new byte offset, when its buffer has data.
    view_position: Vec<Option<usize>>,
    /// Per new view (the changes' own, then the images): its byte offset.
    new_view_offsets: Vec<usize>,
    /// Whether the output has a buffer with data (a GLB's BIN chunk).
    bin_needed: bool,
    /// With meshopt in or out: where each view went, view by view.
    packed: Option<Packed>,
}

impl Layout<'_> {
    /// Forgets where each view went, which only the edits read.
    fn keep_bytes_only(&mut self) {
        self.view_position = Vec::new();
        self.new_view_offsets = Vec::new();
        self.packed = None;
    }
}

/// Old data first (only the kept views when orphans are dropped, else every buffer whole),
/// then the new views, then the embedded images.
fn lay_out_buffer<'s>(
    root: &Node,
    buffers: &BufferMap<'s>,
    numbering: &Numbering,
    changes: &Changes,
    images: &Images,
    format: OutputFormat,
) -> Result<Layout<'s>, SceneError> {
    let old_views = root
        .get("bufferViews")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    let mut bin = BinPieces::default();
    let view_position = if numbering.dropping {
        copy_kept_views(&mut bin, old_views, buffers, numbering)?
    } else {
        copy_whole_buffers(&mut bin, old_views, buffers)
    };
    let mut new_view_offsets = Vec::with_capacity(changes.views.len() + images.data.len());
    let held = (changes.views.iter().enumerate())
        .map(|(i, v)| (Piece::View(i), v.data.len()))
        .chain((images.data.iter().enumerate()).map(|(i, data)| (Piece::Image(i), data.len())));
    for (piece, len) in held {
        let at = align(bin.len(), 4);
        bin.pad_to(at);
        new_view_offsets.push(at);
        bin.push_held(piece, len);
    }
    // In a GLB, a first buffer without a uri is the BIN chunk. When the only buffers are empty
    // ones (an EXT_meshopt_compression fallback, or a `.gltf` buffer with no uri), a BIN chunk
    // must still lead, or the first empty buffer would be read as it (found by fuzzing).
    let all = buffers.buffers;
    let bin_needed = (0..all.len()).any(|b| buffers.has_data(b))
        || !new_view_offsets.is_empty()
        || (format == OutputFormat::Glb && all.iter().any(|b| b.source == BufferSource::Empty));
    // Every buffer declares at least one byte, which its data must hold.
    if bin_needed && bin.is_empty() {
        bin.pad_to(1);
    }
    Ok(Layout {
        bin,
        view_position,
        new_view_offsets,
        bin_needed,
        packed: None,
    })
}

/// Copies the kept views one by one, so that dropped ones leave no dead bytes.
fn copy_kept_views<'s>(
    bin: &mut BinPieces<'s>,
    old_views: &[Node],
    buffers: &BufferMap<'s>,
    numbering: &Numbering,
) -> Result<Vec<Option<usize>>, SceneError> {
    let mut view_position = vec![None; old_views.len()];
    for (v, view) in old_views.iter().enumerate() {
        let b = usize_of(view.get("buffer"));
        if !numbering.keeps_view(v) || !buffers.has_data(b) {
            continue;
        }
        let offset = usize_of(view.get("byteOffset"));
        let length = usize_of(view.get("byteLength"));
        let Some(bytes) = buffers
            .buffers
            .get(b)
            .and_then(|b| b.bytes.get(offset..offset.saturating_add(length)))
        else {
            return Err(SceneError::new(
                ProblemCode::InvalidBufferView,
                format!("bufferViews[{v}] lies outside buffers[{b}]"),
            ));
        };
        // Keeping the offset modulo 16 keeps every alignment the input had.
        let at = align(bin.len(), 16) + offset % 16;
        bin.pad_to(at);
        bin.push(bytes);
        view_position[v] = Some(at);
    }
    Ok(view_position)
}

/// Copies every buffer with data whole, each on a 16-byte boundary; views move with theirs.
fn copy_whole_buffers<'s>(
    bin: &mut BinPieces<'s>,
    old_views: &[Node],
    buffers: &BufferMap<'s>,
) -> Vec<Option<usize>> {
    let mut base = vec![0usize; buffers.buffers.len()];
    for (b, buffer) in buffers.buffers.iter().enumerate() {
        if buffers.has_data(b) {
            let at = align(bin.len(), 16);
            bin.pad_to(at);
            base[b] = at;
            bin.push(&buffer.bytes);
        }
    }
    old_views
        .iter()
        .map(|view| {
            let b = usize_of(view.get("buffer"));
            buffers
                .has_data(b)
                .then(|| base.get(b).copied().unwrap_or(0) + usize_of(view.get("byteOffset")))
        })
        .collect()
}

fn drop_accessors<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    numbering: &Numbering,
) -> Result<(), SceneError> {
    if let Some(list) = root.get("accessors") {
        for a in (0..numbering.accessor_map.len()).filter(|&a| !numbering.keeps_accessor(a)) {
            editor.remove_element(list, a).map_err(edit_error)?;
        }
    }
    Ok(())
}

/// Every surviving reference to a buffer view, renumbered (references that die with their
/// owner are left to go with it).
fn renumber_view_refs<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    numbering: &Numbering,
    changes: &Changes,
) -> Result<(), SceneError> {
    if numbering.kept_views == numbering.view_map.len() {
        // No view is dropped: every view keeps its index.
        return Ok(());
    }
    let mut result = Ok(());
    refs::visit_view_refs(root, &mut |(owner, node)| {
        let v = refs::held(node);
        let alive = match owner {
            Owner::Accessor(a) => numbering.keeps_accessor(a as usize),
            Owner::Primitive(m, p) => !changes
                .primitives
                .get(&(m as usize, p as usize))
                .is_some_and(|e| e.remove_draco),
            _ => true,
        };
        let target = numbering.view(v);
        if result.is_ok() && alive && target != v {
            result = editor.replace(node, target.to_string());
        }
    });
    result.map_err(edit_error)
}

fn append_accessors<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    numbering: &Numbering,
    changes: &Changes,
) -> Result<(), SceneError> {
    for accessor in &changes.accessors {
        let text = created::accessor(&AccessorJson {
            view: numbering.kept_views + accessor.view,
            component_type: accessor.component_type,
            element_type: accessor.element_type,
            normalized: accessor.normalized,
            count: accessor.count,
            bounds: accessor.min_max.clone(),
        })?;
        editor
            .push_to_array_member(root, "accessors", text)
            .map_err(edit_error)?;
    }
    Ok(())
}

/// Drops the orphan views and points the kept ones at their place in the output buffer.
fn edit_buffer_views<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    buffers: &BufferMap<'_>,
    numbering: &Numbering,
    layout: &Layout<'_>,
) -> Result<(), SceneError> {
    let Some(list) = root.get("bufferViews") else {
        return Ok(());
    };
    for (v, view) in list.as_array().unwrap_or(&[]).iter().enumerate() {
        if !numbering.keeps_view(v) {
            editor.remove_element(list, v).map_err(edit_error)?;
            continue;
        }
        let b = usize_of(view.get("buffer"));
        let new_buffer = buffers.output_index(b);
        if new_buffer != b
            && let Some(node) = view.get("buffer")
        {
            editor
                .replace(node, new_buffer.to_string())
                .map_err(edit_error)?;
        }
        if let Some(at) = layout.view_position.get(v).copied().flatten()
            && at != usize_of(view.get("byteOffset"))
        {
            editor
                .set_member(view, "byteOffset", at.to_string())
                .map_err(edit_error)?;
        }
        // The meshopt extension names a buffer too.
        if let Some(node) = view
            .get("extensions")
            .and_then(|e| e.get("EXT_meshopt_compression"))
            .and_then(|e| e.get("buffer"))
        {
            let b = usize_of(Some(node));
            let new_buffer = buffers.output_index(b);
            if new_buffer != b {
                editor
                    .replace(node, new_buffer.to_string())
                    .map_err(edit_error)?;
            }
        }
    }
    Ok(())
}

/// The changes' views, then the embedded images', all in output buffer 0.
fn append_buffer_views<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    changes: &Changes,
    images: &Images,
    layout: &Layout<'_>,
) -> Result<(), SceneError> {
    let new_views = changes
        .views
        .iter()
        .map(|v| (v.data.len(), v.target, v.byte_stride))
        .chain(images.data.iter().map(|d| (d.len(), None, None)));
    for (i, ((length, target, stride), &offset)) in
        new_views.zip(&layout.new_view_offsets).enumerate()
    {
        let compressed = layout.packed.as_ref().and_then(|p| {
            let encoded = p.new_encoded.get(i)?.as_ref()?;
            Some((encoded, *p.new_fallback.get(i)?))
        });
        let text = match compressed {
            None => created::buffer_view(offset, length, stride, target)?,
            Some((encoded, fallback)) => {
                compressed_view_json(fallback, length, stride, target, encoded, offset)?
            }
        };
        editor
            .push_to_array_member(root, "bufferViews", text)
            .map_err(edit_error)?;
    }
    Ok(())
}

/// When accessors were dropped, every reference outside the edited primitives (skins,
/// animations, extensions tspace knows) follows the renumbering.
fn renumber_accessor_refs<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    numbering: &Numbering,
    changes: &Changes,
) -> Result<(), SceneError> {
    if !numbering.dropping {
        return Ok(());
    }
    let mut result = Ok(());
    refs::visit_accessor_refs(root, &mut |(owner, node)| {
        if result.is_err() || is_edited(owner, changes) {
            return;
        }
        let i = refs::held(node);
        let target = numbering.accessor(Ref::Old(i));
        if target != i {
            result = editor.replace(node, target.to_string());
        }
    });
    result.map_err(edit_error)
}

/// Appends the new materials; returns the index the first one gets.
fn append_materials<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    changes: &Changes,
) -> Result<usize, SceneError> {
    let first = root
        .get("materials")
        .and_then(Node::as_array)
        .map_or(0, <[Node]>::len);
    for material in &changes.materials {
        editor
            .push_to_array_member(root, "materials", material.clone())
            .map_err(edit_error)?;
    }
    Ok(first)
}

/// Lists the extensions the new materials use in `extensionsUsed`. Runs after every other
/// edit of the list: a list that loses its last name (Draco's) is removed as a member, and the
/// editor then starts a new one.
fn list_material_extensions<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    changes: &Changes,
) -> Result<(), SceneError> {
    let listed = root
        .get("extensionsUsed")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    for &name in &changes.extensions_used {
        if !listed.iter().any(|n| n.as_str() == Some(name)) {
            editor
                .push_to_array_member(root, "extensionsUsed", json::escape_str(name))
                .map_err(edit_error)?;
        }
    }
    Ok(())
}

/// Applies every primitive's edit; when no primitive keeps Draco data, the extension leaves
/// `extensionsUsed` too.
fn edit_primitives<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    numbering: &Numbering,
    changes: &Changes,
    first_new_material: usize,
    warnings: &mut Vec<Notice>,
) -> Result<(), SceneError> {
    let meshes = root.get("meshes").and_then(Node::as_array).unwrap_or(&[]);
    let mut draco_left = false;
    for (m, mesh) in meshes.iter().enumerate() {
        for (p, primitive) in mesh
            .get("primitives")
            .and_then(Node::as_array)
            .unwrap_or(&[])
            .iter()
            .enumerate()
        {
            let has_draco = primitive
                .get("extensions")
                .and_then(|e| e.get("KHR_draco_mesh_compression"))
                .is_some();
            let Some(edit) = changes.primitives.get(&(m, p)) else {
                draco_left |= has_draco;
                continue;
            };
            apply_primitive_edit(editor, primitive, edit, numbering)?;
            if let Some(material) = edit.material {
                editor
                    .set_member(
                        primitive,
                        "material",
                        (first_new_material + material as usize).to_string(),
                    )
                    .map_err(edit_error)?;
            }
            draco_left |= has_draco && !edit.remove_draco;
        }
    }
    if !draco_left {
        unlist_draco(editor, root, warnings)?;
    }
    Ok(())
}

fn unlist_draco<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    warnings: &mut Vec<Notice>,
) -> Result<(), SceneError> {
    let mut listed = false;
    for list in ["extensionsUsed", "extensionsRequired"] {
        listed |= unlist_extension(editor, root, list, "KHR_draco_mesh_compression")?;
    }
    if listed {
        warnings.push(Notice::new("draco_removed", "KHR_draco_mesh_compression was removed: every primitive that had it now carries tangents and is written uncompressed (encoding Draco again would quantize it again)"));
    }
    Ok(())
}

/// Removes `name` from the array member `list` of the root, and the member with its last name
/// (an empty list is invalid). Returns whether the name was there.
fn unlist_extension<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    list: &str,
    name: &str,
) -> Result<bool, SceneError> {
    let Some(array) = root.get(list) else {
        return Ok(false);
    };
    let names = array.as_array().unwrap_or(&[]);
    let Some(i) = names.iter().position(|n| n.as_str() == Some(name)) else {
        return Ok(false);
    };
    if names.len() == 1 {
        editor.remove_member(root, list).map_err(edit_error)?;
    } else {
        editor.remove_element(array, i).map_err(edit_error)?;
    }
    Ok(true)
}

/// Embedded images lose their URI and name their view (`first_view`: the first image view).
fn point_images_at_views<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    images: &Images,
    first_view: usize,
) -> Result<(), SceneError> {
    let list = root.get("images").and_then(Node::as_array).unwrap_or(&[]);
    for &(i, data_index, mime) in &images.views {
        let Some(image) = list.get(i) else { continue };
        editor.remove_member(image, "uri").map_err(edit_error)?;
        let view = first_view + data_index;
        editor
            .set_member(image, "bufferView", view.to_string())
            .map_err(edit_error)?;
        if image.get("mimeType").is_none() {
            editor
                .set_member(image, "mimeType", json::escape_str(mime))
                .map_err(edit_error)?;
        }
    }
    Ok(())
}

/// The buffers array: the merged buffer first, then the empty ones. The usual file, one buffer
/// with data, is edited in place, keeping its layout.
fn edit_buffers<'d>(
    editor: &mut Editor<'d, '_>,
    doc: &'d Document<'_>,
    buffers: &BufferMap<'_>,
    layout: &Layout<'_>,
    (changes, images): (&Changes, &Images),
    format: OutputFormat,
    warnings: &mut Vec<Notice>,
) -> Result<(), SceneError> {
    let root = doc.root();
    let count = buffers.buffers.len();
    let byte_length = layout.bin.len().max(1);
    let bin_uri = bin_uri(layout, format, changes, images);
    let single = count == 1 && buffers.has_data(0) && layout.bin_needed;
    match root.get("buffers") {
        Some(node) if single => {
            if let Some(buffer) = node.index(0) {
                point_buffer_at_bin(editor, buffer, byte_length, bin_uri.as_deref())?;
            }
            Ok(())
        }
        node => {
            let mut entries: Vec<String> = Vec::new();
            if layout.bin_needed {
                entries.push(merged_entry(doc, buffers, layout, bin_uri, warnings)?);
            }
            let list = root.get("buffers").and_then(Node::as_array).unwrap_or(&[]);
            for (b, original) in list.iter().enumerate() {
                if !buffers.has_data(b) {
                    entries.push(doc.text(original).to_owned());
                }
            }
            let text = format!("[{}]", entries.join(","));
            match node {
                Some(node) => editor.replace(node, text).map_err(edit_error),
                None if !entries.is_empty() => {
                    editor.set_member(root, "buffers", text).map_err(edit_error)
                }
                None => Ok(()),
            }
        }
    }
}

/// The output buffer's URI: none in a GLB (it is the BIN chunk), a `data:` URI in a `.gltf`.
fn bin_uri(
    layout: &Layout<'_>,
    format: OutputFormat,
    changes: &Changes,
    images: &Images,
) -> Option<String> {
    match format {
        OutputFormat::Glb => None,
        OutputFormat::GltfEmbedded => Some(format!(
            "data:application/octet-stream;base64,{}",
            base64(&layout.bin.to_vec(changes, images))
        )),
    }
}

/// The entry of the one buffer every input buffer with data is merged into, saying so when more
/// than one was.
fn merged_entry(
    doc: &Document<'_>,
    buffers: &BufferMap<'_>,
    layout: &Layout<'_>,
    bin_uri: Option<String>,
    warnings: &mut Vec<Notice>,
) -> Result<String, SceneError> {
    let byte_length = layout.bin.len().max(1);
    let entry = merged_buffer(doc, buffers, byte_length, bin_uri.as_deref())?;
    let merged_count = (0..buffers.buffers.len())
        .filter(|&b| buffers.has_data(b))
        .count();
    if merged_count > 1 {
        warnings.push(Notice::new("buffers_merged", format!(
            "{merged_count} buffers were merged into one; only the first one's name and extras are kept"
        )));
    }
    Ok(entry)
}

/// Sets a buffer's length and URI for the output buffer: no URI in a GLB (it is the BIN chunk),
/// a `data:` URI in a `.gltf`.
fn point_buffer_at_bin<'d>(
    editor: &mut Editor<'d, '_>,
    buffer: &'d Node,
    byte_length: usize,
    bin_uri: Option<&str>,
) -> Result<(), SceneError> {
    editor
        .set_member(buffer, "byteLength", byte_length.to_string())
        .map_err(edit_error)?;
    match bin_uri {
        None => {
            editor.remove_member(buffer, "uri").map_err(edit_error)?;
        }
        Some(uri) => editor
            .set_member(buffer, "uri", json::escape_str(uri))
            .map_err(edit_error)?,
    }
    Ok(())
}

/// The merged buffer's entry: the first buffer with data, edited (its name and extras kept),
/// or a new entry when none had data.
fn merged_buffer(
    doc: &Document<'_>,
    buffers: &BufferMap<'_>,
    byte_length: usize,
    bin_uri: Option<&str>,
) -> Result<String, SceneError> {
    let list = doc
        .root()
        .get("buffers")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    let first_data = (0..buffers.buffers.len()).find(|&b| buffers.has_data(b));
    match first_data.and_then(|b| list.get(b)) {
        Some(original) => {
            let text = doc.text(original);
            let sub = Document::parse(text.as_bytes()).map_err(|e| {
                SceneError::new(ProblemCode::MalformedJson, format!("buffers: {e}"))
            })?;
            let mut sub_editor = Editor::new(&sub);
            point_buffer_at_bin(&mut sub_editor, sub.root(), byte_length, bin_uri)?;
            sub_editor.render().map_err(edit_error)
        }
        None => created::buffer(byte_length, bin_uri),
    }
}

/// The container: a GLB (keeping the input GLB's chunks after BIN), or the `.gltf` JSON. The
/// edited JSON is written straight into it, never held as a text of its own besides.
fn emit(
    other: &[glb::Chunk<'_>],
    json: &json::Rendered<'_>,
    layout: &Layout<'_>,
    format: OutputFormat,
    (changes, images): (&Changes, &Images),
) -> Result<Vec<u8>, SceneError> {
    match format {
        OutputFormat::Glb => glb::write_with(
            json.len(),
            |out| json.for_each_part(|part| out.extend_from_slice(part.as_bytes())),
            layout
                .bin_needed
                .then(|| layout.bin.slices(changes, images))
                .as_deref(),
            other,
        )
        .map_err(|e| SceneError::new(ProblemCode::OutputTooLarge, format!("the output {e}"))),
        OutputFormat::GltfEmbedded => {
            let mut out = Vec::with_capacity(json.len());
            json.for_each_part(|part| out.extend_from_slice(part.as_bytes()));
            Ok(out)
        }
    }
}

/// The GLB as [`pieces::Pieces`]: its framing and JSON, then the BIN chunk's pieces, the new views' and
/// images' data moved out of `changes` and `images` rather than copied, and ranges of `input`
/// for what lies in it (the kept views of a GLB's BIN chunk, the chunks after BIN).
fn emit_pieces(
    other: &[glb::Chunk<'_>],
    json: &json::Rendered<'_>,
    layout: Layout<'_>,
    (changes, images): (&mut Changes, &mut Images),
    input: &[u8],
) -> Result<pieces::Pieces, SceneError> {
    let mut lengths = vec![(glb::CHUNK_JSON, json.len())];
    if layout.bin_needed {
        lengths.push((glb::CHUNK_BIN, layout.bin.len()));
    }
    lengths.extend(other.iter().map(|c| (c.kind, c.data.len())));
    let framing = glb::Framing::of(&lengths)
        .map_err(|e| SceneError::new(ProblemCode::OutputTooLarge, format!("the output {e}")))?;
    let mut chunks = framing.chunks.iter();
    let mut head = framing.header.to_vec();
    let json_at = match chunks.next() {
        Some(chunk) => {
            head.extend_from_slice(&chunk.header);
            let at = head.len();
            // The BIN chunk's header follows: room for it too, or its eight bytes would double
            // a buffer the size of the JSON.
            head.reserve_exact(json.len() + chunk.padding + glb::CHUNK_HEADER_LEN);
            json.for_each_part(|part| head.extend_from_slice(part.as_bytes()));
            if head.len() - at != json.len() {
                return Err(SceneError::new(
                    ProblemCode::Internal,
                    "the edited JSON's length was misjudged",
                ));
            }
            head.resize(head.len() + chunk.padding, chunk.pad_byte);
            at
        }
        None => head.len(),
    };
    let json_range = json_at..json_at + json.len();
    let bin_chunk = if layout.bin_needed {
        chunks.next()
    } else {
        None
    };
    if let Some(bin) = bin_chunk {
        head.extend_from_slice(&bin.header);
    }
    let mut pieces = pieces::Pieces::new(head, json_range);
    if let Some(bin) = bin_chunk {
        for piece in layout.bin.parts {
            pieces.push(match piece {
                Piece::Borrowed(bytes) => part_of(bytes, input),
                Piece::Owned(bytes) => Part::Owned(bytes),
                Piece::View(i) => changes
                    .views
                    .get_mut(i)
                    .map_or(Part::Owned(Vec::new()), |v| v.data.take_part()),
                Piece::Image(i) => Part::Owned(
                    images
                        .data
                        .get_mut(i)
                        .map(std::mem::take)
                        .unwrap_or_default(),
                ),
            });
        }
        pieces.push(Part::Owned(vec![bin.pad_byte; bin.padding]));
    }
    for (chunk, framing) in other.iter().zip(chunks) {
        pieces.push(Part::Owned(framing.header.to_vec()));
        pieces.push(part_of(chunk.data, input));
        pieces.push(Part::Owned(vec![framing.pad_byte; framing.padding]));
    }
    Ok(pieces)
}

/// `bytes` as a range of `input` when it lies there, else a copy.
fn part_of(bytes: &[u8], input: &[u8]) -> Part {
    let within = input.as_ptr_range();
    let start = bytes.as_ptr() as usize;
    let (low, high) = (within.start as usize, within.end as usize);
    if !bytes.is_empty() && start >= low && start + bytes.len() <= high {
        let at = start - low;
        Part::Input(at..at + bytes.len())
    } else {
        Part::Owned(bytes.to_vec())
    }
}

/// Each accessor an edited primitive refers to after the edit (its attributes, indices and
/// morph targets: those the edit sets, and the others it leaves), handed to `visit`.
fn visit_final_primitive_accessors(root: &Node, changes: &Changes, mut visit: impl FnMut(Ref)) {
    let meshes = root.get("meshes").and_then(Node::as_array).unwrap_or(&[]);
    for ((m, p), edit) in changes.primitives.iter() {
        let Some(primitive) = meshes
            .get(m)
            .and_then(|mesh| mesh.get("primitives"))
            .and_then(|ps| ps.index(p))
        else {
            continue;
        };
        let mut merged = |original: Option<&Node>, set: &[(Text, Ref)]| {
            for member in original.and_then(Node::as_object).unwrap_or(&[]) {
                if set.iter().any(|(k, _)| *k == member.key) {
                    continue;
                }
                if let Some(i) = member.value.as_u64().and_then(|i| usize::try_from(i).ok()) {
                    visit(Ref::Old(i));
                }
            }
            for &(_, r) in set {
                visit(r);
            }
        };
        merged(primitive.get("attributes"), &edit.attributes);
        let targets = primitive
            .get("targets")
            .and_then(Node::as_array)
            .unwrap_or(&[]);
        for (t, target) in targets.iter().enumerate() {
            let set = edit.targets.get(t).map_or(&[][..], Vec::as_slice);
            merged(Some(target), set);
        }
        match (
            edit.indices,
            primitive.get("indices").and_then(Node::as_u64),
        ) {
            (Some(r), _) => visit(r),
            (None, Some(i)) => visit(Ref::Old(i as usize)),
            _ => {}
        }
    }
}

/// Sets the members the edit names and, when accessors were dropped, renumbers the ones it
/// leaves alone.
fn apply_primitive_edit<'d>(
    editor: &mut Editor<'d, '_>,
    primitive: &'d Node,
    edit: &PrimitiveEdit,
    numbering: &Numbering,
) -> Result<(), SceneError> {
    let dropping = numbering.dropping;
    let final_accessor = |r: Ref| numbering.accessor(r);
    let set_all = |editor: &mut Editor<'d, '_>,
                   object: &'d Node,
                   set: &[(Text, Ref)]|
     -> Result<(), SceneError> {
        for (key, r) in set {
            editor
                .set_member(object, key, final_accessor(*r).to_string())
                .map_err(edit_error)?;
        }
        // Members left alone still need renumbering when accessors were dropped.
        if dropping {
            for member in object.as_object().unwrap_or(&[]) {
                if set.iter().any(|(k, _)| *k == member.key) {
                    continue;
                }
                if let Some(i) = member.value.as_u64().and_then(|i| usize::try_from(i).ok()) {
                    let target = final_accessor(Ref::Old(i));
                    if target != i {
                        editor
                            .replace(&member.value, target.to_string())
                            .map_err(edit_error)?;
                    }
                }
            }
        }
        Ok(())
    };
    if let Some(attributes) = primitive.get("attributes") {
        set_all(editor, attributes, &edit.attributes)?;
    }
    match (edit.indices, primitive.get("indices")) {
        (Some(r), _) => editor
            .set_member(primitive, "indices", final_accessor(r).to_string())
            .map_err(edit_error)?,
        (None, Some(node)) if dropping => {
            if let Some(i) = node.as_u64().and_then(|i| usize::try_from(i).ok()) {
                let target = final_accessor(Ref::Old(i));
                if target != i {
                    editor
                        .replace(node, target.to_string())
                        .map_err(edit_error)?;
                }
            }
        }
        _ => {}
    }
    if edit.to_triangle_list {
        editor
            .set_member(primitive, "mode", "4")
            .map_err(edit_error)?;
    }
    let targets = primitive
        .get("targets")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    for (t, target) in targets.iter().enumerate() {
        let set = edit.targets.get(t).map_or(&[][..], Vec::as_slice);
        set_all(editor, target, set)?;
    }
    if edit.remove_draco
        && let Some(extensions) = primitive.get("extensions")
    {
        let only = extensions.as_object().is_some_and(|m| m.len() == 1);
        if only {
            editor
                .remove_member(primitive, "extensions")
                .map_err(edit_error)?;
        } else {
            editor
                .remove_member(extensions, "KHR_draco_mesh_compression")
                .map_err(edit_error)?;
        }
    }
    Ok(())
}

/// Standard base64 with padding, for the embedded buffer's `data:` URI.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        let symbols = [(n >> 18) & 63, (n >> 12) & 63, (n >> 6) & 63, n & 63];
        for (i, s) in symbols.iter().enumerate() {
            if i <= chunk.len() {
                out.push(char::from(ALPHABET[*s as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_decoder() {
        for len in 0..40 {
            let bytes: Vec<u8> = (0..len).map(|i| (i * 37 + 11) as u8).collect();
            let text = base64(&bytes);
            assert_eq!(uri::decode_base64(text.as_bytes()).unwrap(), bytes);
        }
    }

    #[test]
    fn a_few_compressed_views_are_each_named_and_many_are_counted() {
        let few = [(0, "ATTRIBUTES", None), (1, "TRIANGLES", None)];
        let text = describe_compression(&few, None);
        assert!(
            text.contains("2 buffer views encoded with meshoptimizer's lossless codecs (bufferViews[0] ATTRIBUTES, bufferViews[1] TRIANGLES)"),
            "{text}"
        );
        let many: Vec<(usize, &'static str, Option<&'static str>)> = (0..5000)
            .map(|v| match v % 5 {
                4 => (v, "TRIANGLES", None),
                3 => (v, "ATTRIBUTES", Some("OCTAHEDRAL")),
                _ => (v, "ATTRIBUTES", None),
            })
            .collect();
        let text = describe_compression(&many, None);
        assert!(
            text.contains(
                "5,000 buffer views encoded with meshoptimizer's lossless codecs (3,000 ATTRIBUTES: \
                 bufferViews[0], bufferViews[1], bufferViews[2] and 2,997 more; 1,000 ATTRIBUTES \
                 with filter OCTAHEDRAL: bufferViews[3], bufferViews[8], bufferViews[13] and 997 \
                 more; 1,000 TRIANGLES: bufferViews[4], bufferViews[9], bufferViews[14] and 997 \
                 more); a filter only where"
            ),
            "{text}"
        );
        assert!(text.len() < 600, "{} bytes", text.len());
    }

    /// Float vectors given later are the bytes `add_floats` writes for them at once, and become
    /// the output's piece as they are; given in another number than the view was made for,
    /// they are refused.
    #[test]
    fn floats_given_later_are_the_bytes_of_floats_given_at_once() {
        let values = vec![[1.0f32, -0.5, 0.25, 1.0], [0.0, 1.0, -0.0, -1.0]];
        let mut at_once = Changes::default();
        at_once.add_floats(&values, false);
        let mut later = Changes::default();
        let (r, pending) = later.add_floats_later(values.len());
        assert_eq!(r, Ref::New(0));
        assert_eq!(later.views[0].data.len(), 32);
        later.fill_floats(pending, values.clone()).unwrap();
        assert_eq!(
            later.views[0].data.as_slice(),
            at_once.views[0].data.as_slice()
        );
        let (a, b) = (&later.accessors[0], &at_once.accessors[0]);
        assert_eq!(
            (
                a.view,
                a.component_type,
                a.element_type,
                a.normalized,
                a.count
            ),
            (
                b.view,
                b.component_type,
                b.element_type,
                b.normalized,
                b.count
            )
        );
        assert!(a.min_max.is_none());
        let part = later.views[0].data.take_part();
        if cfg!(target_endian = "little") {
            assert!(
                matches!(&part, Part::Floats(f) if f.as_ref() == at_once.views[0].data.as_slice())
            );
        }

        let mut wrong = Changes::default();
        let (_, pending) = wrong.add_floats_later(3);
        let refused = wrong.fill_floats(pending, values).unwrap_err();
        assert!(
            refused
                .to_string()
                .contains("made for 3 values and given 2"),
            "{refused}"
        );
    }

    /// A view whose floats never came fails the write, rather than writing an accessor over
    /// bytes that are not there.
    #[test]
    fn a_view_never_given_its_floats_fails_the_write() {
        let json = br#"{"asset":{"version":"2.0"},"meshes":[]}"#;
        let limits = super::super::load::LoadLimits {
            max_buffer_bytes: 1 << 20,
        };
        let loaded = super::super::load::load(json, &super::super::load::NoResources, &limits)
            .expect("a minimal glTF loads");
        let mut changes = Changes::default();
        let _never_filled = changes.add_floats_later(4);
        let result = write(
            loaded,
            changes,
            OutputFormat::Glb,
            Compression::Auto,
            &super::super::load::NoResources,
            None,
            None,
        );
        let error = result.err().expect("the write fails");
        assert!(
            error.to_string().contains("never got its values"),
            "{error}"
        );
    }

    #[test]
    fn min_max_in_component_values() {
        let data: Vec<u8> = [[1i16, -5, 3], [7, 2, -9]]
            .iter()
            .flat_map(|e| e.iter().flat_map(|c| c.to_le_bytes()).chain([0, 0]))
            .collect();
        let (min, max) = min_max_of(&data, 8, ComponentType::I16, ElementType::Vec3).unwrap();
        assert_eq!(
            (serde_json::json!(min), serde_json::json!(max)),
            (serde_json::json!([1, -5, -9]), serde_json::json!([7, 2, 3]))
        );
    }

    #[test]
    fn images_are_sniffed_not_decoded() {
        assert_eq!(sniff_image(b"\x89PNG\r\n\x1a\nrest"), Some("image/png"));
        assert_eq!(sniff_image(&[0xFF, 0xD8, 0xFF, 0xE0]), Some("image/jpeg"));
        assert_eq!(sniff_image(b"GIF89a"), None);
    }
}

/// Where one input view goes in a packed write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placed {
    /// Dropped (or, for a view in no buffer tspace knows, left as it is).
    Nowhere,
    /// Plain bytes at this offset of buffer 0; a meshopt extension it had is removed.
    Data(usize),
    /// Compressed: its own range at `fallback` in the fallback buffer, its compressed bytes at
    /// `data` in buffer 0; `fresh` when this write encoded it (an index into
    /// [`Packed::fresh`]), else its extension's bytes were copied as they were.
    Compressed {
        fallback: usize,
        data: usize,
        fresh: Option<usize>,
    },
}

/// The view-by-view layout used when meshopt compression is in the input or asked for.
struct Packed {
    output: Output,
    /// Per input view.
    old: Vec<Placed>,
    /// Input views this write compressed (`compress=meshopt` on plain views): `(view, encoding)`.
    fresh: Vec<(usize, Encoding)>,
    /// Per new view of the changes: its encoding, when compressed.
    new_encoded: Vec<Option<Encoding>>,
    /// Per new view: its range's offset in the fallback buffer (0 when not compressed).
    new_fallback: Vec<usize>,
    /// The fallback buffer's length; 0 when the output has none.
    fallback_length: usize,
}

impl Packed {
    /// The output buffer index of the fallback buffer (after the data buffer).
    const FALLBACK: usize = 1;

    fn compressed_views(
        &self,
        numbering: &Numbering,
    ) -> Vec<(usize, &'static str, Option<&'static str>)> {
        let entry = |view: usize, e: &Encoding| {
            let filter = (e.filter != tspace_meshopt::Filter::None).then(|| e.filter.name());
            (view, e.mode.name(), filter)
        };
        let mut list: Vec<_> = self
            .fresh
            .iter()
            .map(|(v, e)| entry(numbering.view(*v), e))
            .collect();
        list.extend(
            self.new_encoded
                .iter()
                .enumerate()
                .filter_map(|(i, e)| Some(entry(numbering.kept_views + i, e.as_ref()?))),
        );
        list
    }

    fn uses_extension(&self, root: &Node, name: &str) -> bool {
        let views = root
            .get("bufferViews")
            .and_then(Node::as_array)
            .unwrap_or(&[]);
        let kept = self.old.iter().enumerate().any(|(v, placed)| match placed {
            Placed::Compressed { fresh: None, .. } => views
                .get(v)
                .and_then(compress::extension)
                .is_some_and(|(n, _)| n == name),
            Placed::Compressed { fresh: Some(_), .. } => name == compress::EXT,
            _ => false,
        });
        kept || (name == compress::EXT && self.new_encoded.iter().any(Option::is_some))
    }
}

/// Who reads each of the input's views and accessors, found once for all views. Asked view by
/// view, each view went through every accessor and every reference of the document: 16 s for
/// 4,000 one-triangle primitives with `compress=meshopt`, and growing with the square.
struct Readers<'d> {
    /// `(view, accessor)` for every accessor with a `bufferView`, by view then accessor.
    of_view: Vec<(usize, usize)>,
    /// The views a sparse part names, ascending.
    sparse_parts: Vec<usize>,
    /// `(accessor, reference)` for every reference to an accessor, by accessor.
    of_accessor: Vec<(usize, refs::Ref<'d>)>,
}

impl<'d> Readers<'d> {
    fn of(root: &'d Node) -> Self {
        let accessors = root
            .get("accessors")
            .and_then(Node::as_array)
            .unwrap_or(&[]);
        let view_of = |n: Option<&Node>| n.and_then(Node::as_u64).map(|v| v as usize);
        let mut of_view: Vec<(usize, usize)> = accessors
            .iter()
            .enumerate()
            .filter_map(|(i, a)| Some((view_of(a.get("bufferView"))?, i)))
            .collect();
        of_view.sort_unstable();
        let mut sparse_parts: Vec<usize> = accessors
            .iter()
            .filter_map(|a| a.get("sparse"))
            .flat_map(|sparse| {
                ["indices", "values"]
                    .into_iter()
                    .filter_map(|part| view_of(sparse.get(part).and_then(|p| p.get("bufferView"))))
            })
            .collect();
        sparse_parts.sort_unstable();
        let mut of_accessor: Vec<(usize, refs::Ref<'d>)> = refs::accessor_refs(root)
            .into_iter()
            .map(|r| (refs::held(r.1), r))
            .collect();
        of_accessor.sort_by_key(|&(i, _)| i);
        Readers {
            of_view,
            sparse_parts,
            of_accessor,
        }
    }

    /// The entries of `list` whose key is `key`, in order.
    fn run<T>(list: &[(usize, T)], key: usize) -> &[(usize, T)] {
        let start = list.partition_point(|(k, _)| *k < key);
        let end = list.partition_point(|(k, _)| *k <= key);
        list.get(start..end).unwrap_or(&[])
    }
}

/// A view of the input that `compress=meshopt` may encode: vertex data read only by mesh
/// attributes (whole elements of a stride the codec takes) or indices read only as such.
fn plain_view_shape(root: &Node, found: &Readers<'_>, v: usize, view: &Node) -> Shape {
    if compress::extension(view).is_some() {
        return Shape::Other;
    }
    let accessors = root
        .get("accessors")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    let readers: Vec<usize> = Readers::run(&found.of_view, v)
        .iter()
        .map(|&(_, i)| i)
        .collect();
    // Sparse accessors, and views their sparse parts name, are left alone.
    let sparse_reads = found.sparse_parts.binary_search(&v).is_ok();
    if readers.is_empty()
        || sparse_reads
        || readers
            .iter()
            .any(|&i| accessors[i].get("sparse").is_some())
    {
        return Shape::Other;
    }
    let (mut vertex, mut index) = (Vec::new(), Vec::new());
    let mut other = false;
    let mut triangles = true;
    let references = readers
        .iter()
        .flat_map(|&i| Readers::run(&found.of_accessor, i));
    for &(_, (owner, node)) in references {
        let Some((m, p)) = owner.primitive() else {
            other = true;
            continue;
        };
        let primitive = root
            .get("meshes")
            .and_then(|ms| ms.index(m))
            .and_then(|mesh| mesh.get("primitives"))
            .and_then(|ps| ps.index(p));
        let is_indices = primitive
            .and_then(|p| p.get("indices"))
            .is_some_and(|i| std::ptr::eq(i, node));
        // Only a triangle list (mode 4, the default) may take the triangle codec.
        triangles &= primitive
            .and_then(|p| p.get("mode"))
            .is_none_or(|m| m.as_u64() == Some(4));
        if is_indices {
            index.push(node.as_u64().unwrap_or(0) as usize);
        } else {
            vertex.push(node.as_u64().unwrap_or(0) as usize);
        }
    }
    let length = usize_of(view.get("byteLength"));
    let element_size = |i: usize| -> Option<usize> {
        let a = accessors.get(i)?;
        let component = ComponentType::from_code(a.get("componentType")?.as_u64()?)?;
        let element = ElementType::from_name(a.get("type")?.as_str()?)?;
        Some(component.size() * element.components())
    };
    let all_read = |list: &[usize]| readers.iter().all(|r| list.contains(r));
    if other || (vertex.is_empty() == index.is_empty()) {
        return Shape::Other;
    }
    if !index.is_empty() && all_read(&index) && view.get("byteStride").is_none() {
        let sizes: Vec<Option<usize>> = readers.iter().map(|&i| element_size(i)).collect();
        return match sizes.first().copied().flatten() {
            Some(size @ (2 | 4))
                if sizes.iter().all(|s| *s == Some(size)) && length.is_multiple_of(size) =>
            {
                Shape::Index { size, triangles }
            }
            _ => Shape::Other,
        };
    }
    if all_read(&vertex) {
        let stride = match view.get("byteStride") {
            Some(s) => usize_of(Some(s)),
            None if readers.len() == 1 => element_size(readers[0]).unwrap_or(0),
            None => 0,
        };
        if stride != 0 && stride.is_multiple_of(4) && stride <= 256 && length.is_multiple_of(stride)
        {
            return Shape::Vertex { stride };
        }
    }
    Shape::Other
}

/// The bytes a view holds once decoded: its own buffer's (a fallback the loader filled, or real
/// data), or, when the loader did not decode it (`KHR_meshopt_compression`), decoded here.
fn decoded_view<'b>(
    buffers: &'b BufferMap<'_>,
    v: usize,
    view: &Node,
) -> Result<std::borrow::Cow<'b, [u8]>, SceneError> {
    let b = usize_of(view.get("buffer"));
    let offset = usize_of(view.get("byteOffset"));
    let length = usize_of(view.get("byteLength"));
    if let Some(bytes) = buffers
        .buffers
        .get(b)
        .and_then(|b| b.bytes.get(offset..offset.saturating_add(length)))
    {
        return Ok(std::borrow::Cow::Borrowed(bytes));
    }
    let outside = || {
        SceneError::new(
            ProblemCode::InvalidBufferView,
            format!("bufferViews[{v}] lies outside buffers[{b}]"),
        )
    };
    let (_, ext) = compress::extension(view).ok_or_else(outside)?;
    let (source, at, len) = compress::compressed_range(ext).ok_or_else(outside)?;
    let data = buffers
        .buffers
        .get(source)
        .and_then(|b| b.bytes.get(at..at.saturating_add(len)))
        .ok_or_else(outside)?;
    let name = |key: &str| ext.get(key).and_then(Node::as_str).unwrap_or("NONE");
    let malformed = |e: tspace_meshopt::MeshoptError| {
        SceneError::new(
            ProblemCode::MalformedMeshopt,
            format!("bufferViews[{v}]: {e}"),
        )
    };
    let decoded = tspace_meshopt::decode(
        &tspace_meshopt::Compressed {
            data,
            count: usize_of(ext.get("count")),
            byte_stride: usize_of(ext.get("byteStride")),
            mode: tspace_meshopt::Mode::from_name(name("mode")).map_err(malformed)?,
            filter: tspace_meshopt::Filter::from_name(name("filter")).map_err(malformed)?,
        },
        length,
    )
    .map_err(malformed)?;
    if decoded.len() != length {
        return Err(outside());
    }
    Ok(std::borrow::Cow::Owned(decoded))
}

/// Appends `bytes` to the data buffer at a multiple of `to` (plus `keep`, an offset modulo 16
/// to keep), returning where they start.
fn push_at(bin: &mut Vec<u8>, bytes: &[u8], to: usize, keep: usize) -> usize {
    let at = align(bin.len(), to) + keep;
    bin.resize(at, 0);
    bin.extend_from_slice(bytes);
    at
}

/// The packed layout: every kept view copied on its own (plain, or its compressed bytes and a
/// range of the fallback buffer), then the changes' views (encoded when the output is
/// compressed), then the embedded images.
fn lay_out_packed(
    root: &Node,
    buffers: &BufferMap<'_>,
    numbering: &Numbering,
    changes: &Changes,
    images: &Images,
    output: Output,
    recompress: bool,
) -> Result<Layout<'static>, SceneError> {
    let old_views = root
        .get("bufferViews")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    let meshopt = output == Output::Meshopt;
    // The encoding is the costly part: every view at once, in parallel.
    let fresh_candidates: Vec<(usize, Shape)> = if meshopt && recompress {
        let readers = Readers::of(root);
        old_views
            .iter()
            .enumerate()
            .filter(|(v, _)| numbering.keeps_view(*v))
            .map(|(v, view)| (v, plain_view_shape(root, &readers, v, view)))
            .filter(|(_, shape)| *shape != Shape::Other)
            .collect()
    } else {
        Vec::new()
    };
    let fresh: Vec<(usize, Encoded)> = fresh_candidates
        .par_iter()
        .filter_map(|&(v, shape)| {
            let view = old_views.get(v)?;
            let bytes = buffers
                .buffers
                .get(usize_of(view.get("buffer")))?
                .bytes
                .get(
                    usize_of(view.get("byteOffset"))
                        ..usize_of(view.get("byteOffset")) + usize_of(view.get("byteLength")),
                )?;
            Some((v, compress::encode(bytes, shape, None)?))
        })
        .collect();
    let new_encoded: Vec<Option<Encoded>> = if meshopt {
        changes
            .views
            .par_iter()
            .map(|view| {
                compress::encode(view.data.as_slice(), view.shape, view.prefiltered.as_ref())
            })
            .collect()
    } else {
        changes.views.iter().map(|_| None).collect()
    };

    let mut bin: Vec<u8> = Vec::new();
    let mut fallback_length = 0usize;
    let mut old = vec![Placed::Nowhere; old_views.len()];
    for (v, view) in old_views.iter().enumerate() {
        if !numbering.keeps_view(v) {
            continue;
        }
        let offset = usize_of(view.get("byteOffset"));
        let length = usize_of(view.get("byteLength"));
        // `fresh` is in view order (collected in order from the views in order): a search,
        // not a walk per view, which made a scene of many small views quadratic.
        let fresh_index = fresh.binary_search_by_key(&v, |&(f, _)| f).ok();
        let ext = compress::extension(view);
        old[v] = match (meshopt, ext, fresh_index) {
            (true, _, Some(k)) => {
                let data = push_at(&mut bin, &fresh[k].1.bytes, 4, 0);
                let fallback = align(fallback_length, 16) + offset % 16;
                fallback_length = fallback + length;
                Placed::Compressed {
                    fallback,
                    data,
                    fresh: Some(k),
                }
            }
            (true, Some((_, ext)), None) => {
                let (source, at, len) = compress::compressed_range(ext).ok_or_else(|| {
                    SceneError::new(
                        ProblemCode::MalformedMeshopt,
                        format!("bufferViews[{v}]: its meshopt extension names no data"),
                    )
                })?;
                let bytes = buffers
                    .buffers
                    .get(source)
                    .filter(|_| buffers.has_data(source))
                    .and_then(|b| b.bytes.get(at..at.saturating_add(len)))
                    .ok_or_else(|| {
                        SceneError::new(
                            ProblemCode::MalformedMeshopt,
                            format!(
                                "bufferViews[{v}]: the compressed bytes lie outside buffers[{source}]"
                            ),
                        )
                    })?;
                let data = push_at(&mut bin, bytes, 4, 0);
                let fallback = align(fallback_length, 16) + offset % 16;
                fallback_length = fallback + length;
                Placed::Compressed {
                    fallback,
                    data,
                    fresh: None,
                }
            }
            _ => {
                let b = usize_of(view.get("buffer"));
                if ext.is_none() && !buffers.has_data(b) {
                    // Not meshopt and in no buffer with data: left as it is.
                    Placed::Nowhere
                } else {
                    let bytes = decoded_view(buffers, v, view)?;
                    Placed::Data(push_at(&mut bin, &bytes, 16, offset % 16))
                }
            }
        };
    }
    let mut new_view_offsets = Vec::with_capacity(changes.views.len() + images.data.len());
    let mut new_fallback = Vec::with_capacity(changes.views.len());
    for (view, encoded) in changes.views.iter().zip(&new_encoded) {
        match encoded {
            Some(e) => {
                new_view_offsets.push(push_at(&mut bin, &e.bytes, 4, 0));
                let fallback = align(fallback_length, 4);
                fallback_length = fallback + view.data.len();
                new_fallback.push(fallback);
            }
            None => {
                new_view_offsets.push(push_at(&mut bin, view.data.as_slice(), 4, 0));
                new_fallback.push(0);
            }
        }
    }
    for data in &images.data {
        new_view_offsets.push(push_at(&mut bin, data, 4, 0));
    }
    // The fallback buffer is the second: a GLB's first buffer must be the BIN chunk.
    let bin_needed = !bin.is_empty() || fallback_length > 0;
    if bin_needed && bin.is_empty() {
        bin.push(0);
    }
    Ok(Layout {
        bin: BinPieces::owned(bin),
        view_position: Vec::new(),
        new_view_offsets,
        bin_needed,
        packed: Some(Packed {
            output,
            old,
            // The streams are in `bin` now.
            fresh: fresh.iter().map(|(v, e)| (*v, e.encoding())).collect(),
            new_encoded: new_encoded
                .iter()
                .map(|e| e.as_ref().map(Encoded::encoding))
                .collect(),
            new_fallback,
            fallback_length,
        }),
    })
}

/// A compressed view of the changes: its range in the fallback buffer, its data compressed in
/// buffer 0 at `data`.
fn compressed_view_json(
    fallback: usize,
    length: usize,
    stride: Option<usize>,
    target: Option<u32>,
    encoded: &Encoding,
    data: usize,
) -> Result<String, SceneError> {
    created::compressed_buffer_view(
        Packed::FALLBACK,
        (fallback, length),
        stride,
        target,
        &encoded.extension(data),
    )
}

/// Drops the orphan views and points each kept one at its place in the packed layout.
fn edit_buffer_views_packed<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    numbering: &Numbering,
    packed: &Packed,
) -> Result<(), SceneError> {
    let Some(list) = root.get("bufferViews") else {
        return Ok(());
    };
    let set_if = |editor: &mut Editor<'d, '_>, node: &'d Node, key: &str, value: usize| {
        if node.get(key).is_none_or(|n| usize_of(Some(n)) != value) {
            editor
                .set_member(node, key, value.to_string())
                .map_err(edit_error)?;
        }
        Ok::<(), SceneError>(())
    };
    for (v, view) in list.as_array().unwrap_or(&[]).iter().enumerate() {
        if !numbering.keeps_view(v) {
            editor.remove_element(list, v).map_err(edit_error)?;
            continue;
        }
        match packed.old.get(v).copied().unwrap_or(Placed::Nowhere) {
            Placed::Nowhere => {}
            Placed::Data(at) => {
                set_if(editor, view, "buffer", 0)?;
                set_if(editor, view, "byteOffset", at)?;
                if let Some((name, _)) = compress::extension(view)
                    && let Some(extensions) = view.get("extensions")
                {
                    if extensions.as_object().is_some_and(|m| m.len() == 1) {
                        editor
                            .remove_member(view, "extensions")
                            .map_err(edit_error)?;
                    } else {
                        editor.remove_member(extensions, name).map_err(edit_error)?;
                    }
                }
            }
            Placed::Compressed {
                fallback,
                data,
                fresh,
            } => {
                set_if(editor, view, "buffer", Packed::FALLBACK)?;
                set_if(editor, view, "byteOffset", fallback)?;
                match fresh {
                    None => {
                        if let Some((_, ext)) = compress::extension(view) {
                            set_if(editor, ext, "buffer", 0)?;
                            set_if(editor, ext, "byteOffset", data)?;
                        }
                    }
                    Some(k) => {
                        let extension = packed.fresh[k].1.extension(data);
                        match view.get("extensions") {
                            Some(extensions) if extensions.as_object().is_some() => {
                                let text = created::to_text(&extension).map_err(|e| {
                                    SceneError::new(ProblemCode::InternalEdit, e.to_string())
                                })?;
                                editor
                                    .set_member(extensions, compress::EXT, text)
                                    .map_err(edit_error)?
                            }
                            // Something other than an object (not valid glTF): replaced.
                            Some(_) => editor
                                .set_member(
                                    view,
                                    "extensions",
                                    created::meshopt_extensions(&extension)?,
                                )
                                .map_err(edit_error)?,
                            None => {
                                let later = MeshoptExtensions(packed.fresh[k].1, data);
                                editor
                                    .insert_member_deferred(view, "extensions", Box::new(later))
                                    .map_err(edit_error)?
                            }
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// A freshly compressed view's `extensions` object, `{"EXT_meshopt_compression": …}` for its
/// encoding with the compressed bytes at the given offset of the data buffer: written when the
/// output's JSON is made. Held as text, the objects of a scene of many small views (about 100
/// bytes each, for a quarter of a million views) were the editor's largest records.
#[derive(Debug)]
struct MeshoptExtensions(Encoding, usize);

impl json::DeferredValue for MeshoptExtensions {
    fn write(&self, out: &mut String) {
        // Nothing where it does not serialize (a bug): the editor refuses an empty text when
        // the edit is made, which reports it.
        let text = created::meshopt_extensions(&self.0.extension(self.1));
        out.push_str(text.as_deref().unwrap_or(""));
    }
}

/// The buffers of a packed write: the data buffer, then the fallback buffer when any view is
/// compressed (the input's own fallback entry, resized, or a new one).
fn edit_buffers_packed<'d>(
    editor: &mut Editor<'d, '_>,
    doc: &'d Document<'_>,
    buffers: &BufferMap<'_>,
    layout: &Layout<'_>,
    (changes, images): (&Changes, &Images),
    format: OutputFormat,
    warnings: &mut Vec<Notice>,
) -> Result<(), SceneError> {
    let root = doc.root();
    let Some(packed) = &layout.packed else {
        return Ok(());
    };
    let bin_uri = bin_uri(layout, format, changes, images);
    let mut entries: Vec<String> = Vec::new();
    if layout.bin_needed {
        entries.push(merged_entry(doc, buffers, layout, bin_uri, warnings)?);
    }
    if packed.fallback_length > 0 {
        entries.push(fallback_buffer(doc, buffers, packed.fallback_length)?);
    }
    let text = format!("[{}]", entries.join(","));
    match root.get("buffers") {
        Some(node) if !entries.is_empty() => editor.replace(node, text).map_err(edit_error),
        Some(_) => editor
            .remove_member(root, "buffers")
            .map(|_| ())
            .map_err(edit_error),
        None if !entries.is_empty() => editor.set_member(root, "buffers", text).map_err(edit_error),
        None => Ok(()),
    }
}

/// The fallback buffer's entry: the input's first buffer without data that is marked as a
/// meshopt fallback, with its new length (its name and extras kept), or a new one.
fn fallback_buffer(
    doc: &Document<'_>,
    buffers: &BufferMap<'_>,
    byte_length: usize,
) -> Result<String, SceneError> {
    let list = doc
        .root()
        .get("buffers")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    let marked = list.iter().enumerate().find(|(b, buffer)| {
        !buffers.has_data(*b)
            && buffer
                .get("extensions")
                .and_then(|e| e.get(compress::EXT))
                .is_some()
            && buffer.get("uri").is_none()
    });
    match marked {
        Some((_, original)) => {
            let text = doc.text(original);
            let sub = Document::parse(text.as_bytes()).map_err(|e| {
                SceneError::new(ProblemCode::MalformedJson, format!("buffers: {e}"))
            })?;
            let mut sub_editor = Editor::new(&sub);
            sub_editor
                .set_member(sub.root(), "byteLength", byte_length.to_string())
                .map_err(edit_error)?;
            sub_editor.render().map_err(edit_error)
        }
        None => created::fallback_buffer(byte_length),
    }
}

/// `extensionsUsed` and `extensionsRequired` after a packed write: `EXT_meshopt_compression`
/// in both when any view has it (the output holds no uncompressed copy), out of both when none
/// has; `KHR_meshopt_compression` leaves with its last view.
fn list_meshopt<'d>(
    editor: &mut Editor<'d, '_>,
    root: &'d Node,
    packed: &Packed,
) -> Result<(), SceneError> {
    for name in [compress::EXT, compress::KHR] {
        let used = packed.output == Output::Meshopt && packed.uses_extension(root, name);
        for list in ["extensionsUsed", "extensionsRequired"] {
            let listed = root
                .get(list)
                .and_then(Node::as_array)
                .unwrap_or(&[])
                .iter()
                .any(|n| n.as_str() == Some(name));
            if used && !listed {
                editor
                    .push_to_array_member(root, list, json::escape_str(name))
                    .map_err(edit_error)?;
            } else if !used && listed {
                unlist_extension(editor, root, list, name)?;
            }
        }
    }
    Ok(())
}

/// Up to this many compressed views, the notice names each with its encoding. Past it, a
/// scene of many small views would make the notice the largest part of the report (250,000
/// views: 7 MB, and a fifth of the write), and no one reads such a list: it counts the views
/// of each encoding and names the first few.
const VIEWS_NAMED: usize = 20;

/// `ATTRIBUTES`, or `ATTRIBUTES with filter OCTAHEDRAL`.
fn mode_and_filter(mode: &str, filter: Option<&str>) -> String {
    match filter {
        Some(f) => format!("{mode} with filter {f}"),
        None => mode.to_owned(),
    }
}

/// `200,000 ATTRIBUTES: bufferViews[0], bufferViews[1], bufferViews[2] and 199,997 more; ...`,
/// the encodings in the order they first appear.
fn views_by_encoding(views: &[(usize, &'static str, Option<&'static str>)]) -> String {
    const NAMED: usize = 3;
    struct Group {
        mode: &'static str,
        filter: Option<&'static str>,
        count: usize,
        first: Vec<usize>,
    }
    let mut groups: Vec<Group> = Vec::new();
    for &(v, mode, filter) in views {
        let index = match groups
            .iter()
            .position(|g| (g.mode, g.filter) == (mode, filter))
        {
            Some(i) => i,
            None => {
                groups.push(Group {
                    mode,
                    filter,
                    count: 0,
                    first: Vec::new(),
                });
                groups.len() - 1
            }
        };
        let group = &mut groups[index];
        group.count += 1;
        if group.first.len() < NAMED {
            group.first.push(v);
        }
    }
    let describe = |g: &Group| {
        let named: Vec<String> = g
            .first
            .iter()
            .map(|v| format!("bufferViews[{v}]"))
            .collect();
        let more = match g.count - g.first.len() {
            0 => String::new(),
            n => format!(" and {} more", thousands(n as u64)),
        };
        format!(
            "{} {}: {}{more}",
            thousands(g.count as u64),
            mode_and_filter(g.mode, g.filter),
            named.join(", ")
        )
    };
    groups.iter().map(describe).collect::<Vec<_>>().join("; ")
}

/// The report's line on what this write compressed: each view's mode, and its filter and why.
fn describe_compression(
    views: &[(usize, &'static str, Option<&'static str>)],
    packed: Option<&Packed>,
) -> String {
    let list = if views.len() <= VIEWS_NAMED {
        views
            .iter()
            .map(|&(v, mode, filter)| format!("bufferViews[{v}] {}", mode_and_filter(mode, filter)))
            .collect::<Vec<_>>()
            .join(", ")
    } else {
        views_by_encoding(views)
    };
    let filtered = views.iter().any(|(_, _, f)| f.is_some());
    let copied = packed.is_some_and(|p| {
        p.old
            .iter()
            .any(|placed| matches!(placed, Placed::Compressed { fresh: None, .. }))
    });
    format!(
        "EXT_meshopt_compression: {} buffer view{} encoded with meshoptimizer's lossless codecs ({}); {}{}",
        thousands(views.len() as u64),
        if views.len() == 1 { "" } else { "s" },
        list,
        if filtered {
            "a filter only where it decodes to exactly the values written (checked): views copied from input views stored with it, and TANGENT quantized to the octahedral representation its NORMAL has; none elsewhere, since filters are lossy"
        } else {
            "no filter, since filters are lossy"
        },
        if copied {
            "; the input's compressed views were copied as they were"
        } else {
            ""
        }
    )
}

#[cfg(test)]
mod primitive_edits_tests {
    use super::*;

    fn tangent_edit(accessor: usize) -> PrimitiveEdit {
        PrimitiveEdit {
            attributes: vec![("TANGENT".into(), Ref::New(accessor))],
            ..PrimitiveEdit::default()
        }
    }

    #[test]
    fn equal_edits_in_a_row_are_held_once_and_read_back_for_each_primitive() {
        let mut edits = PrimitiveEdits::default();
        edits.reserve(4);
        edits.insert((0, 0), tangent_edit(0));
        edits.insert((0, 1), tangent_edit(0));
        edits.insert((1, 0), tangent_edit(1));
        edits.insert((0, 2), tangent_edit(1));
        assert_eq!(
            edits.edits.len(),
            2,
            "the second and fourth repeat the edit before them"
        );
        let read: Vec<_> = edits
            .iter()
            .map(|(key, edit)| (key, edit.attributes[0].1))
            .collect();
        assert_eq!(
            read,
            [
                ((0, 0), Ref::New(0)),
                ((0, 1), Ref::New(0)),
                ((0, 2), Ref::New(1)),
                ((1, 0), Ref::New(1)),
            ]
        );
        assert_eq!(edits.values().count(), 4);
        assert!(edits.get(&(0, 1)) == Some(&tangent_edit(0)));
        assert!(edits.contains_key(&(1, 0)) && !edits.contains_key(&(1, 1)));
    }

    #[test]
    fn a_replaced_edit_is_read_no_more_and_leaves_its_twin_alone() {
        let mut edits = PrimitiveEdits::default();
        edits.insert((0, 0), tangent_edit(0));
        edits.insert((0, 1), tangent_edit(0));
        let mut moved = tangent_edit(0);
        moved.remove_draco = true;
        edits.insert((0, 0), moved);
        assert!(edits.get(&(0, 0)).is_some_and(|e| e.remove_draco));
        assert!(edits.get(&(0, 1)) == Some(&tangent_edit(0)));
        assert_eq!(edits.values().filter(|e| e.remove_draco).count(), 1);
        assert!(!edits.is_empty() && PrimitiveEdits::default().is_empty());
    }
}
