//! Accessor decoding: typed attribute and index arrays out of glTF buffers.
//!
//! The `gltf` crate's typed readers assume float attributes and panic or return garbage on
//! quantized ones (KHR_mesh_quantization), so tspace decodes accessors itself, from a plain
//! [`Accessor`] description. [`accessor_from_json`] builds that description from a document;
//! errors there name the JSON path (`accessors[3].bufferView`).
//!
//! Everything the specification requires of an accessor's layout is checked before a byte is
//! read: strides, alignment, and that the accessor fits in its buffer view and the view in its
//! buffer (in 128-bit arithmetic, which cannot overflow on 64-bit counts). Output is therefore
//! bounded by the bytes present; an accessor without a buffer view, which is all zeros and may
//! claim any count, is bounded by the caller's `max_elements` instead (as is every read).
//!
//! Two leniencies, both harmless: the 4-byte alignment the specification asks of vertex
//! attributes is not enforced (only component alignment, which decoding depends on; quantized
//! exporters break the former, and the data still reads one way only), and an accessor
//! `byteOffset` without a `bufferView` is ignored.

use std::borrow::Cow;
use std::collections::HashMap;
use std::fmt;

use tspace_json::Node;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ComponentType {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl ComponentType {
    /// From the glTF `componentType` code (5120…5126; 5124, a 32-bit signed integer, is not one).
    pub fn from_code(code: u64) -> Option<Self> {
        Some(match code {
            5120 => ComponentType::I8,
            5121 => ComponentType::U8,
            5122 => ComponentType::I16,
            5123 => ComponentType::U16,
            5125 => ComponentType::U32,
            5126 => ComponentType::F32,
            _ => return None,
        })
    }

    pub fn code(self) -> u32 {
        match self {
            ComponentType::I8 => 5120,
            ComponentType::U8 => 5121,
            ComponentType::I16 => 5122,
            ComponentType::U16 => 5123,
            ComponentType::U32 => 5125,
            ComponentType::F32 => 5126,
        }
    }

    /// Size in bytes.
    pub fn size(self) -> usize {
        match self {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ComponentType::I8 => "BYTE (5120)",
            ComponentType::U8 => "UNSIGNED_BYTE (5121)",
            ComponentType::I16 => "SHORT (5122)",
            ComponentType::U16 => "UNSIGNED_SHORT (5123)",
            ComponentType::U32 => "UNSIGNED_INT (5125)",
            ComponentType::F32 => "FLOAT (5126)",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ElementType {
    Scalar,
    Vec2,
    Vec3,
    Vec4,
    Mat2,
    Mat3,
    Mat4,
}

impl ElementType {
    /// From the glTF `type` string (`"VEC3"`…).
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "SCALAR" => ElementType::Scalar,
            "VEC2" => ElementType::Vec2,
            "VEC3" => ElementType::Vec3,
            "VEC4" => ElementType::Vec4,
            "MAT2" => ElementType::Mat2,
            "MAT3" => ElementType::Mat3,
            "MAT4" => ElementType::Mat4,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            ElementType::Scalar => "SCALAR",
            ElementType::Vec2 => "VEC2",
            ElementType::Vec3 => "VEC3",
            ElementType::Vec4 => "VEC4",
            ElementType::Mat2 => "MAT2",
            ElementType::Mat3 => "MAT3",
            ElementType::Mat4 => "MAT4",
        }
    }

    /// Components per element (16 for MAT4).
    pub fn components(self) -> usize {
        let (rows, columns) = self.shape();
        rows * columns
    }

    /// Rows and columns; vectors are one column.
    fn shape(self) -> (usize, usize) {
        match self {
            ElementType::Scalar => (1, 1),
            ElementType::Vec2 => (2, 1),
            ElementType::Vec3 => (3, 1),
            ElementType::Vec4 => (4, 1),
            ElementType::Mat2 => (2, 2),
            ElementType::Mat3 => (3, 3),
            ElementType::Mat4 => (4, 4),
        }
    }
}

/// A glTF buffer view, resolved to the bytes of its buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferView<'a> {
    /// The whole buffer the view points into.
    pub buffer: &'a [u8],
    pub byte_offset: usize,
    pub byte_length: usize,
    pub byte_stride: Option<usize>,
}

/// The sparse substitution of an accessor: `count` indices and the values that replace the
/// elements at them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sparse<'a> {
    pub count: usize,
    pub indices_view: BufferView<'a>,
    pub indices_offset: usize,
    pub indices_type: ComponentType,
    pub values_view: BufferView<'a>,
    pub values_offset: usize,
}

/// Everything needed to decode one accessor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Accessor<'a> {
    pub component_type: ComponentType,
    pub normalized: bool,
    pub element_type: ElementType,
    pub count: usize,
    /// Offset into the buffer view; ignored without one.
    pub byte_offset: usize,
    /// `None`: every element is zero (before the sparse substitution).
    pub view: Option<BufferView<'a>>,
    pub sparse: Option<Sparse<'a>>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AccessorError {
    /// The caller asked for `[f32; requested]` elements from an accessor of another type.
    WrongComponentCount {
        element_type: ElementType,
        requested: usize,
    },
    ZeroCount,
    TooManyElements {
        count: usize,
        limit: usize,
    },
    /// `normalized` is only defined for integer components narrower than 32 bits.
    NormalizedNotAllowed {
        component_type: ComponentType,
    },
    NotIndices {
        component_type: ComponentType,
        element_type: ElementType,
        normalized: bool,
    },
    ViewOutOfBuffer {
        view_offset: usize,
        view_length: usize,
        buffer_length: usize,
    },
    InvalidStride {
        stride: usize,
        component_type: ComponentType,
    },
    StrideTooSmall {
        stride: usize,
        element_size: usize,
    },
    /// An offset (`what`) that is not a multiple of the component size.
    Misaligned {
        what: &'static str,
        offset: usize,
        component_size: usize,
    },
    /// The accessor, or a sparse part of it (`what`), needs bytes past the end of its view.
    OutOfView {
        what: &'static str,
        needed: u128,
        view_length: usize,
    },
    SparseCount {
        sparse_count: usize,
        count: usize,
    },
    SparseIndexType {
        component_type: ComponentType,
    },
    SparseViewHasStride {
        what: &'static str,
    },
    SparseIndexOutOfRange {
        position: usize,
        index: u32,
        count: usize,
    },
    SparseIndicesNotIncreasing {
        position: usize,
        index: u32,
        previous: u32,
    },
    /// A problem in the JSON description, at `path` (`accessors[3].bufferView`).
    Json {
        path: String,
        problem: String,
    },
    /// A decoding problem of the accessor at `path` (`accessors[3]`).
    In {
        path: String,
        error: Box<AccessorError>,
    },
}

impl fmt::Display for AccessorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use AccessorError as E;
        match self {
            E::WrongComponentCount {
                element_type,
                requested,
            } => write!(
                f,
                "a {} accessor has {} components per element, not {requested}",
                element_type.name(),
                element_type.components()
            ),
            E::ZeroCount => write!(f, "an accessor's count must be at least 1"),
            E::TooManyElements { count, limit } => write!(
                f,
                "the accessor has {count} elements, more than the limit of {limit}"
            ),
            E::NormalizedNotAllowed { component_type } => write!(
                f,
                "normalized is not allowed for component type {}",
                component_type.name()
            ),
            E::NotIndices {
                component_type,
                element_type,
                normalized,
            } => write!(
                f,
                "indices must be SCALAR, not normalized, and UNSIGNED_BYTE, UNSIGNED_SHORT or \
                 UNSIGNED_INT; this accessor is {}{} {}",
                if *normalized { "normalized " } else { "" },
                element_type.name(),
                component_type.name()
            ),
            E::ViewOutOfBuffer {
                view_offset,
                view_length,
                buffer_length,
            } => write!(
                f,
                "the buffer view (offset {view_offset}, length {view_length}) extends past the \
                 end of its {buffer_length}-byte buffer"
            ),
            E::InvalidStride {
                stride,
                component_type,
            } => write!(
                f,
                "byteStride {stride} must be between 4 and 252 and a multiple of the size of {}",
                component_type.name()
            ),
            E::StrideTooSmall {
                stride,
                element_size,
            } => write!(
                f,
                "byteStride {stride} is smaller than the {element_size}-byte elements"
            ),
            E::Misaligned {
                what,
                offset,
                component_size,
            } => write!(
                f,
                "{what} {offset} is not a multiple of the component size {component_size}"
            ),
            E::OutOfView {
                what,
                needed,
                view_length,
            } => write!(
                f,
                "the {what} need {needed} bytes of a {view_length}-byte buffer view"
            ),
            E::SparseCount {
                sparse_count,
                count,
            } => write!(
                f,
                "sparse.count {sparse_count} must be between 1 and the accessor's count {count}"
            ),
            E::SparseIndexType { component_type } => write!(
                f,
                "sparse indices must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT, not {}",
                component_type.name()
            ),
            E::SparseViewHasStride { what } => {
                write!(
                    f,
                    "the buffer view of the sparse {what} must not have a byteStride"
                )
            }
            E::SparseIndexOutOfRange {
                position,
                index,
                count,
            } => write!(
                f,
                "sparse index {index} (entry {position}) is out of range for {count} elements"
            ),
            E::SparseIndicesNotIncreasing {
                position,
                index,
                previous,
            } => write!(
                f,
                "sparse indices must strictly increase, but entry {position} is {index} after {previous}"
            ),
            E::Json { path, problem } => write!(f, "{path}: {problem}"),
            E::In { path, error } => write!(f, "{path}: {error}"),
        }
    }
}

impl std::error::Error for AccessorError {}

/// Reads a float attribute: one `[f32; N]` per element, N being the element type's component
/// count (column-major for matrices). Integer components convert as the glTF specification says:
/// normalized ones by its formulas (`max(c / 127, -1)` for BYTE, `c / 255` for UNSIGNED_BYTE…),
/// others by value. Float components are returned bit for bit, NaN and infinities included.
pub fn read_floats<const N: usize>(
    accessor: &Accessor<'_>,
    max_elements: usize,
) -> Result<Vec<[f32; N]>, AccessorError> {
    if accessor.element_type.components() != N {
        return Err(AccessorError::WrongComponentCount {
            element_type: accessor.element_type,
            requested: N,
        });
    }
    let normalized = accessor.normalized;
    match accessor.component_type {
        ComponentType::F32 | ComponentType::U32 if normalized => {
            Err(AccessorError::NormalizedNotAllowed {
                component_type: accessor.component_type,
            })
        }
        ComponentType::I8 if normalized => decode(accessor, max_elements, |b: [u8; 1]| {
            (f32::from(i8::from_le_bytes(b)) / 127.0).max(-1.0)
        }),
        ComponentType::I8 => decode(accessor, max_elements, |b: [u8; 1]| {
            f32::from(i8::from_le_bytes(b))
        }),
        ComponentType::U8 if normalized => {
            decode(accessor, max_elements, |b: [u8; 1]| f32::from(b[0]) / 255.0)
        }
        ComponentType::U8 => decode(accessor, max_elements, |b: [u8; 1]| f32::from(b[0])),
        ComponentType::I16 if normalized => decode(accessor, max_elements, |b: [u8; 2]| {
            (f32::from(i16::from_le_bytes(b)) / 32767.0).max(-1.0)
        }),
        ComponentType::I16 => decode(accessor, max_elements, |b: [u8; 2]| {
            f32::from(i16::from_le_bytes(b))
        }),
        ComponentType::U16 if normalized => decode(accessor, max_elements, |b: [u8; 2]| {
            f32::from(u16::from_le_bytes(b)) / 65535.0
        }),
        ComponentType::U16 => decode(accessor, max_elements, |b: [u8; 2]| {
            f32::from(u16::from_le_bytes(b))
        }),
        // Rounds above 2^24, as any u32-to-float conversion must.
        ComponentType::U32 => decode(accessor, max_elements, |b: [u8; 4]| {
            u32::from_le_bytes(b) as f32
        }),
        ComponentType::F32 => decode(accessor, max_elements, f32::from_le_bytes),
    }
}

/// Reads an index accessor: SCALAR, UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT, not
/// normalized. Whether the indices are in range for the vertices is the caller's question.
pub fn read_indices(
    accessor: &Accessor<'_>,
    max_elements: usize,
) -> Result<Vec<u32>, AccessorError> {
    let not_indices = AccessorError::NotIndices {
        component_type: accessor.component_type,
        element_type: accessor.element_type,
        normalized: accessor.normalized,
    };
    if accessor.element_type != ElementType::Scalar || accessor.normalized {
        return Err(not_indices);
    }
    let elements: Vec<[u32; 1]> = match accessor.component_type {
        ComponentType::U8 => decode(accessor, max_elements, |b: [u8; 1]| u32::from(b[0]))?,
        ComponentType::U16 => decode(accessor, max_elements, |b: [u8; 2]| {
            u32::from(u16::from_le_bytes(b))
        })?,
        ComponentType::U32 => decode(accessor, max_elements, u32::from_le_bytes)?,
        _ => return Err(not_indices),
    };
    Ok(elements.into_iter().map(|[i]| i).collect())
}

/// The elements of a float accessor where they lie, when they need no decoding: 32-bit floats,
/// not normalized, not sparse, tightly packed, and aligned in memory, on a little-endian
/// machine. Nearly every uncompressed mesh's positions, normals and UVs are so, and borrowing
/// them spares a copy of each and its page faults (on a 2M-triangle GLB, a tenth of the run).
/// `None` for anything else, which [`read_floats`] decodes (and refuses with its errors).
pub fn floats_in_place<'a, const N: usize>(
    accessor: &Accessor<'a>,
    max_elements: usize,
) -> Option<&'a [[f32; N]]> {
    if accessor.component_type != ComponentType::F32
        || accessor.normalized
        || accessor.element_type.components() != N
        || accessor.element_type.shape().1 != 1
    {
        return None;
    }
    bytemuck::try_cast_slice(in_place_bytes(accessor, 4 * N, max_elements)?).ok()
}

/// The indices of a 32-bit index accessor where they lie, under the conditions of
/// [`floats_in_place`]; `None` for anything else, which [`read_indices`] decodes.
pub fn indices_in_place<'a>(accessor: &Accessor<'a>, max_elements: usize) -> Option<&'a [u32]> {
    if accessor.component_type != ComponentType::U32
        || accessor.normalized
        || accessor.element_type != ElementType::Scalar
    {
        return None;
    }
    bytemuck::try_cast_slice(in_place_bytes(accessor, 4, max_elements)?).ok()
}

/// The bytes of an accessor of 4-byte components, `element_size` apart with no gaps, when they
/// can be read as they are: the checks [`decode`] makes (count, limit, stride, alignment of the
/// offsets, bounds) all pass, and there is no sparse substitution. Memory alignment is left to
/// the cast.
fn in_place_bytes<'a>(
    accessor: &Accessor<'a>,
    element_size: usize,
    max_elements: usize,
) -> Option<&'a [u8]> {
    if cfg!(target_endian = "big") || accessor.sparse.is_some() {
        return None;
    }
    let count = accessor.count;
    if count == 0 || count > max_elements {
        return None;
    }
    let view = accessor.view.as_ref()?;
    if view
        .byte_stride
        .is_some_and(|stride| stride != element_size)
        || !accessor.byte_offset.is_multiple_of(4)
        || !view.byte_offset.is_multiple_of(4)
    {
        return None;
    }
    let bytes = view_bytes(view).ok()?;
    let start = accessor.byte_offset;
    let end = start.checked_add(count.checked_mul(element_size)?)?;
    bytes.get(start..end)
}

/// The elements of any accessor as raw little-endian bytes, tightly packed (`element_size`
/// apart, matrix columns padded to 4 bytes as the specification lays them out), with the sparse
/// substitution applied. This is what copying an attribute into a new accessor of the same type
/// needs: no conversion, so integer and normalized data keep every bit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawElements {
    pub element_size: usize,
    pub bytes: Vec<u8>,
}

impl RawElements {
    /// The bytes of element `index`, if there is one.
    pub fn element(&self, index: usize) -> Option<&[u8]> {
        let start = index.checked_mul(self.element_size)?;
        self.bytes.get(start..start.checked_add(self.element_size)?)
    }

    pub fn len(&self) -> usize {
        self.bytes.len().checked_div(self.element_size).unwrap_or(0)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Reads every element of `accessor` as raw bytes; see [`RawElements`].
pub fn read_raw(
    accessor: &Accessor<'_>,
    max_elements: usize,
) -> Result<RawElements, AccessorError> {
    let layout = Layout::of(accessor.component_type, accessor.element_type);
    // One monomorphization per (component size, component count) pair, all going through the
    // same checked `decode` as the typed readers.
    macro_rules! raw {
        ($s:literal, $($n:literal),+) => {
            match accessor.element_type.components() {
                $($n => pack(&layout, decode::<[u8; $s], $s, $n>(accessor, max_elements, |b| b)?),)+
                _ => unreachable!("element types have 1, 2, 3, 4, 9 or 16 components"),
            }
        };
    }
    let bytes = match layout.component_size {
        1 => raw!(1, 1, 2, 3, 4, 9, 16),
        2 => raw!(2, 1, 2, 3, 4, 9, 16),
        _ => raw!(4, 1, 2, 3, 4, 9, 16),
    };
    Ok(RawElements {
        element_size: layout.element_size,
        bytes,
    })
}

/// Lays decoded components out as the specification stores them (columns padded to 4 bytes).
fn pack<const S: usize, const N: usize>(layout: &Layout, elements: Vec<[[u8; S]; N]>) -> Vec<u8> {
    let mut out = vec![0u8; elements.len() * layout.element_size];
    for (element, slot) in elements
        .iter()
        .zip(out.chunks_exact_mut(layout.element_size))
    {
        let mut components = element.iter();
        for column in 0..layout.columns {
            for row in 0..layout.rows {
                let at = column * layout.column_stride + row * S;
                if let (Some(component), Some(target)) =
                    (components.next(), slot.get_mut(at..at + S))
                {
                    target.copy_from_slice(component);
                }
            }
        }
    }
    out
}

/// Byte layout of one element. Matrix columns start on 4-byte boundaries, so a MAT2 of bytes or a
/// MAT3 of bytes or shorts has padding after each column.
#[derive(Clone, Copy, Debug)]
struct Layout {
    component_size: usize,
    rows: usize,
    columns: usize,
    column_stride: usize,
    element_size: usize,
}

impl Layout {
    fn of(component_type: ComponentType, element_type: ElementType) -> Self {
        let component_size = component_type.size();
        let (rows, columns) = element_type.shape();
        let column_stride = if columns > 1 {
            (rows * component_size).next_multiple_of(4)
        } else {
            rows * component_size
        };
        Layout {
            component_size,
            rows,
            columns,
            column_stride,
            element_size: columns * column_stride,
        }
    }

    /// Decodes the element that starts `bytes`. The caller has checked that `bytes` holds one.
    fn element<T: Copy + Default, const S: usize, const N: usize>(
        &self,
        bytes: &[u8],
        component: &impl Fn([u8; S]) -> T,
    ) -> [T; N] {
        let mut out = [T::default(); N];
        let mut slots = out.iter_mut();
        for column in 0..self.columns {
            for row in 0..self.rows {
                let at = column * self.column_stride + row * S;
                let raw = bytes
                    .get(at..at + S)
                    .and_then(|b| <[u8; S]>::try_from(b).ok())
                    .unwrap_or([0; S]);
                if let Some(slot) = slots.next() {
                    *slot = component(raw);
                }
            }
        }
        out
    }
}

/// The bytes of `view`, checked to lie inside its buffer.
fn view_bytes<'a>(view: &BufferView<'a>) -> Result<&'a [u8], AccessorError> {
    view.byte_offset
        .checked_add(view.byte_length)
        .and_then(|end| view.buffer.get(view.byte_offset..end))
        .ok_or(AccessorError::ViewOutOfBuffer {
            view_offset: view.byte_offset,
            view_length: view.byte_length,
            buffer_length: view.buffer.len(),
        })
}

/// `count` items of `size` bytes, `stride` apart, from `offset` into `bytes`: the slice that
/// holds them, checked to fit. `count` must be at least 1.
fn span<'a>(
    bytes: &'a [u8],
    offset: usize,
    stride: usize,
    count: usize,
    size: usize,
    what: &'static str,
) -> Result<&'a [u8], AccessorError> {
    // In u128 nothing here can overflow: each factor is below 2^64.
    let needed = offset as u128 + stride as u128 * (count as u128 - 1) + size as u128;
    let out_of_view = AccessorError::OutOfView {
        what,
        needed,
        view_length: bytes.len(),
    };
    let end = usize::try_from(needed).map_err(|_| out_of_view.clone())?;
    bytes.get(offset..end).ok_or(out_of_view)
}

/// Decodes every element into `[T; N]` with `component`, which turns the `S` bytes of one
/// component into a value, then applies the sparse substitution.
fn decode<T: Copy + Default, const S: usize, const N: usize>(
    accessor: &Accessor<'_>,
    max_elements: usize,
    component: impl Fn([u8; S]) -> T,
) -> Result<Vec<[T; N]>, AccessorError> {
    let layout = Layout::of(accessor.component_type, accessor.element_type);
    debug_assert_eq!(S, layout.component_size);
    let count = accessor.count;
    if count == 0 {
        return Err(AccessorError::ZeroCount);
    }
    if count > max_elements {
        return Err(AccessorError::TooManyElements {
            count,
            limit: max_elements,
        });
    }

    let mut out = match &accessor.view {
        None => vec![[T::default(); N]; count],
        Some(view) => {
            let bytes = view_bytes(view)?;
            let stride = match view.byte_stride {
                None => layout.element_size,
                Some(stride) => {
                    if !(4..=252).contains(&stride) || stride % S != 0 {
                        return Err(AccessorError::InvalidStride {
                            stride,
                            component_type: accessor.component_type,
                        });
                    }
                    if stride < layout.element_size {
                        return Err(AccessorError::StrideTooSmall {
                            stride,
                            element_size: layout.element_size,
                        });
                    }
                    stride
                }
            };
            for (what, offset) in [
                ("accessor byteOffset", accessor.byte_offset),
                ("buffer view byteOffset", view.byte_offset),
            ] {
                if offset % S != 0 {
                    return Err(AccessorError::Misaligned {
                        what,
                        offset,
                        component_size: S,
                    });
                }
            }
            let data = span(
                bytes,
                accessor.byte_offset,
                stride,
                count,
                layout.element_size,
                "accessor's elements",
            )?;
            // `span` checked that `count` elements fit, which also bounds this allocation by the
            // bytes present.
            let mut out = Vec::with_capacity(count);
            let mut rest = data;
            for _ in 0..count {
                out.push(layout.element(rest, &component));
                rest = rest.get(stride..).unwrap_or(&[]);
            }
            out
        }
    };

    if let Some(sparse) = &accessor.sparse {
        apply_sparse(&mut out, sparse, layout, &component)?;
    }
    Ok(out)
}

fn apply_sparse<T: Copy + Default, const S: usize, const N: usize>(
    out: &mut [[T; N]],
    sparse: &Sparse<'_>,
    layout: Layout,
    component: &impl Fn([u8; S]) -> T,
) -> Result<(), AccessorError> {
    let count = out.len();
    if sparse.count == 0 || sparse.count > count {
        return Err(AccessorError::SparseCount {
            sparse_count: sparse.count,
            count,
        });
    }
    let index_size = match sparse.indices_type {
        ComponentType::U8 | ComponentType::U16 | ComponentType::U32 => sparse.indices_type.size(),
        component_type => return Err(AccessorError::SparseIndexType { component_type }),
    };
    for (what, view) in [
        ("indices", &sparse.indices_view),
        ("values", &sparse.values_view),
    ] {
        if view.byte_stride.is_some() {
            return Err(AccessorError::SparseViewHasStride { what });
        }
    }
    let indices = span(
        view_bytes(&sparse.indices_view)?,
        sparse.indices_offset,
        index_size,
        sparse.count,
        index_size,
        "sparse indices",
    )?;
    let values = span(
        view_bytes(&sparse.values_view)?,
        sparse.values_offset,
        layout.element_size,
        sparse.count,
        layout.element_size,
        "sparse values",
    )?;

    let mut previous: Option<u32> = None;
    let entries = indices
        .chunks_exact(index_size)
        .zip(values.chunks_exact(layout.element_size));
    for (position, (index_bytes, value_bytes)) in entries.enumerate() {
        let index = match *index_bytes {
            [a] => u32::from(a),
            [a, b] => u32::from(u16::from_le_bytes([a, b])),
            [a, b, c, d] => u32::from_le_bytes([a, b, c, d]),
            _ => 0,
        };
        if let Some(previous) = previous.filter(|&p| index <= p) {
            return Err(AccessorError::SparseIndicesNotIncreasing {
                position,
                index,
                previous,
            });
        }
        previous = Some(index);
        let slot = usize::try_from(index)
            .ok()
            .and_then(|i| out.get_mut(i))
            .ok_or(AccessorError::SparseIndexOutOfRange {
                position,
                index,
                count,
            })?;
        *slot = layout.element(value_bytes, component);
    }
    Ok(())
}

/// One accessor's elements from somewhere other than its JSON: decoded from a compressed
/// primitive (`KHR_draco_mesh_compression`). `count` tightly packed elements of the accessor's
/// own component and element type.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DecodedAccessor {
    /// The decoder's count. For Draco this may exceed the accessor's declared `count`, which
    /// encoders write before the stream splits vertices along attribute seams; the decoded
    /// geometry is self-consistent and is what viewers show.
    pub count: usize,
    pub bytes: Vec<u8>,
}

/// Decoded accessors, by accessor index.
pub type DecodedAccessors = HashMap<usize, DecodedAccessor>;

/// Where accessors read their bytes: the loaded buffers, and the decoded accessors, whose data
/// replaces whatever their JSON points at.
#[derive(Clone, Copy)]
pub struct Data<'a> {
    pub buffers: &'a [&'a [u8]],
    pub decoded: &'a DecodedAccessors,
}

impl<'a> Data<'a> {
    /// [`accessor_from_json`], with a decoded accessor's data in place of its JSON's.
    pub fn accessor(&self, root: &Node, index: usize) -> Result<Accessor<'a>, AccessorError> {
        let mut accessor = accessor_from_json(root, index, self.buffers)?;
        if let Some(decoded) = self.decoded.get(&index) {
            accessor.count = decoded.count;
            accessor.byte_offset = 0;
            accessor.sparse = None;
            accessor.view = Some(BufferView {
                buffer: &decoded.bytes,
                byte_offset: 0,
                byte_length: decoded.bytes.len(),
                byte_stride: None,
            });
        }
        Ok(accessor)
    }

    /// [`Data::accessor`] then [`read_floats`], with decoding errors naming the accessor.
    pub fn floats<const N: usize>(
        &self,
        root: &Node,
        index: usize,
        max_elements: usize,
    ) -> Result<Vec<[f32; N]>, AccessorError> {
        let accessor = self.accessor(root, index)?;
        read_floats(&accessor, max_elements).map_err(|e| within(index, e))
    }

    /// [`Data::floats`], borrowed where they lie when they need no decoding
    /// ([`floats_in_place`]).
    pub fn floats_borrowed<const N: usize>(
        &self,
        root: &Node,
        index: usize,
        max_elements: usize,
    ) -> Result<Cow<'a, [[f32; N]]>, AccessorError> {
        let accessor = self.accessor(root, index)?;
        if let Some(floats) = floats_in_place(&accessor, max_elements) {
            return Ok(Cow::Borrowed(floats));
        }
        read_floats(&accessor, max_elements)
            .map(Cow::Owned)
            .map_err(|e| within(index, e))
    }

    /// [`Data::indices`], borrowed where they lie when they need no decoding
    /// ([`indices_in_place`]).
    pub fn indices_borrowed(
        &self,
        root: &Node,
        index: usize,
        max_elements: usize,
    ) -> Result<Cow<'a, [u32]>, AccessorError> {
        let accessor = self.accessor(root, index)?;
        if let Some(indices) = indices_in_place(&accessor, max_elements) {
            return Ok(Cow::Borrowed(indices));
        }
        read_indices(&accessor, max_elements)
            .map(Cow::Owned)
            .map_err(|e| within(index, e))
    }

    /// [`Data::accessor`] then [`read_indices`], with decoding errors naming the accessor.
    pub fn indices(
        &self,
        root: &Node,
        index: usize,
        max_elements: usize,
    ) -> Result<Vec<u32>, AccessorError> {
        let accessor = self.accessor(root, index)?;
        read_indices(&accessor, max_elements).map_err(|e| within(index, e))
    }
}

/// Builds the description of accessor `index` of a glTF document, resolving its buffer views
/// against `buffers` (the bytes of `buffers[i]`, already loaded: the GLB BIN chunk, a decoded
/// data URI or a file). A buffer longer than its declared `byteLength` (a BIN chunk's padding) is
/// cut to it, so views cannot reach past the declared end.
pub fn accessor_from_json<'a>(
    root: &Node,
    index: usize,
    buffers: &[&'a [u8]],
) -> Result<Accessor<'a>, AccessorError> {
    let path = Item("accessors", index);
    let accessor = array_item(root, "accessors", index)?;
    let Some(element_type) = ElementType::from_name(required_str(accessor, &path, "type")?) else {
        return Err(json_error(
            &path,
            "type",
            "must be SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4",
        ));
    };
    let component_type = required_component_type(accessor, &path, "componentType")?;
    let normalized = match accessor.get("normalized") {
        None => false,
        Some(v) => v.as_bool().ok_or_else(|| {
            json_error(
                &path,
                "normalized",
                &format!("must be a boolean, not {}", v.kind_name()),
            )
        })?,
    };
    let count = required_usize(accessor, &path, "count")?;
    let byte_offset = optional_usize(accessor, &path, "byteOffset")?.unwrap_or(0);
    let view = optional_usize(accessor, &path, "bufferView")?
        .map(|v| buffer_view(root, v, buffers, &Within(&path, "bufferView")))
        .transpose()?;

    let sparse = match accessor.get("sparse") {
        None => None,
        Some(sparse) => {
            let sparse_path = Within(&path, "sparse");
            let part = |key: &str| {
                sparse
                    .get(key)
                    .filter(|n| n.as_object().is_some())
                    .ok_or_else(|| json_error(&sparse_path, key, "must be an object"))
            };
            let (indices, values) = (part("indices")?, part("values")?);
            let indices_path = Within(&sparse_path, "indices");
            let values_path = Within(&sparse_path, "values");
            Some(Sparse {
                count: required_usize(sparse, &sparse_path, "count")?,
                indices_view: buffer_view(
                    root,
                    required_usize(indices, &indices_path, "bufferView")?,
                    buffers,
                    &Within(&indices_path, "bufferView"),
                )?,
                indices_offset: optional_usize(indices, &indices_path, "byteOffset")?.unwrap_or(0),
                indices_type: required_component_type(indices, &indices_path, "componentType")?,
                values_view: buffer_view(
                    root,
                    required_usize(values, &values_path, "bufferView")?,
                    buffers,
                    &Within(&values_path, "bufferView"),
                )?,
                values_offset: optional_usize(values, &values_path, "byteOffset")?.unwrap_or(0),
            })
        }
    };

    Ok(Accessor {
        component_type,
        normalized,
        element_type,
        count,
        byte_offset,
        view,
        sparse,
    })
}

/// [`accessor_from_json`] then [`read_floats`], with decoding errors naming the accessor.
pub fn read_floats_json<const N: usize>(
    root: &Node,
    index: usize,
    buffers: &[&[u8]],
    max_elements: usize,
) -> Result<Vec<[f32; N]>, AccessorError> {
    let accessor = accessor_from_json(root, index, buffers)?;
    read_floats(&accessor, max_elements).map_err(|e| within(index, e))
}

/// [`accessor_from_json`] then [`read_indices`], with decoding errors naming the accessor.
pub fn read_indices_json(
    root: &Node,
    index: usize,
    buffers: &[&[u8]],
    max_elements: usize,
) -> Result<Vec<u32>, AccessorError> {
    let accessor = accessor_from_json(root, index, buffers)?;
    read_indices(&accessor, max_elements).map_err(|e| within(index, e))
}

fn within(index: usize, error: AccessorError) -> AccessorError {
    AccessorError::In {
        path: Item("accessors", index).to_string(),
        error: Box::new(error),
    }
}

/// `name[index]`: a place in the document, spelled only when an error names it (reading an
/// accessor made three strings for its error messages, on a scene of 200,000 accessors read
/// twice each).
struct Item<'a>(&'a str, usize);

impl fmt::Display for Item<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}[{}]", self.0, self.1)
    }
}

/// `place.key`.
struct Within<'a>(&'a dyn fmt::Display, &'static str);

impl fmt::Display for Within<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.0, self.1)
    }
}

fn json_error(path: &dyn fmt::Display, key: &str, problem: &str) -> AccessorError {
    AccessorError::Json {
        path: format!("{path}.{key}"),
        problem: problem.into(),
    }
}

/// Element `index` of the top-level array `key`, which must be an object.
fn array_item<'n>(root: &'n Node, key: &str, index: usize) -> Result<&'n Node, AccessorError> {
    let Some(items) = root.get(key).and_then(Node::as_array) else {
        return Err(AccessorError::Json {
            path: key.into(),
            problem: format!("the document has no {key} array, so {key}[{index}] does not exist"),
        });
    };
    match items.get(index) {
        Some(item) if item.as_object().is_some() => Ok(item),
        Some(item) => Err(AccessorError::Json {
            path: Item(key, index).to_string(),
            problem: format!("must be an object, not {}", item.kind_name()),
        }),
        None => Err(AccessorError::Json {
            path: key.into(),
            problem: format!(
                "{key}[{index}] does not exist (there are {} {key})",
                items.len()
            ),
        }),
    }
}

fn buffer_view<'a>(
    root: &Node,
    index: usize,
    buffers: &[&'a [u8]],
    referenced_at: &dyn fmt::Display,
) -> Result<BufferView<'a>, AccessorError> {
    let view = match array_item(root, "bufferViews", index) {
        Err(AccessorError::Json { problem, .. }) if problem.contains("does not exist") => {
            return Err(AccessorError::Json {
                path: referenced_at.to_string(),
                problem: format!("bufferView {index} does not exist"),
            });
        }
        other => other?,
    };
    let path = Item("bufferViews", index);
    let buffer_index = required_usize(view, &path, "buffer")?;
    let Some(&data) = buffers.get(buffer_index) else {
        return Err(json_error(
            &path,
            "buffer",
            &format!(
                "buffer {buffer_index} does not exist ({} buffers are loaded)",
                buffers.len()
            ),
        ));
    };
    // Trust the smaller of the declared and the actual length.
    let declared = root
        .get("buffers")
        .and_then(|b| b.index(buffer_index))
        .and_then(|b| b.get("byteLength"))
        .and_then(Node::as_u64)
        .and_then(|n| usize::try_from(n).ok());
    let buffer = declared.and_then(|n| data.get(..n)).unwrap_or(data);
    Ok(BufferView {
        buffer,
        byte_offset: optional_usize(view, &path, "byteOffset")?.unwrap_or(0),
        byte_length: required_usize(view, &path, "byteLength")?,
        byte_stride: optional_usize(view, &path, "byteStride")?,
    })
}

fn optional_usize(
    object: &Node,
    path: &dyn fmt::Display,
    key: &str,
) -> Result<Option<usize>, AccessorError> {
    let Some(value) = object.get(key) else {
        return Ok(None);
    };
    match value.as_u64().map(usize::try_from) {
        Some(Ok(n)) => Ok(Some(n)),
        Some(Err(_)) => Err(json_error(path, key, "is too large")),
        None => {
            let found = match value.as_number() {
                Some(n) => n.raw().to_owned(),
                None => value.kind_name().to_owned(),
            };
            Err(json_error(
                path,
                key,
                &format!("must be a non-negative integer, not {found}"),
            ))
        }
    }
}

fn required_usize(
    object: &Node,
    path: &dyn fmt::Display,
    key: &str,
) -> Result<usize, AccessorError> {
    optional_usize(object, path, key)?.ok_or_else(|| json_error(path, key, "is missing"))
}

fn required_str<'n>(
    object: &'n Node,
    path: &dyn fmt::Display,
    key: &str,
) -> Result<&'n str, AccessorError> {
    match object.get(key) {
        None => Err(json_error(path, key, "is missing")),
        Some(value) => value.as_str().ok_or_else(|| {
            json_error(
                path,
                key,
                &format!("must be a string, not {}", value.kind_name()),
            )
        }),
    }
}

fn required_component_type(
    object: &Node,
    path: &dyn fmt::Display,
    key: &str,
) -> Result<ComponentType, AccessorError> {
    let code = required_usize(object, path, key)?;
    ComponentType::from_code(code as u64).ok_or_else(|| {
        json_error(
            path,
            key,
            &format!("{code} is not a glTF component type (5120, 5121, 5122, 5123, 5125, 5126)"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use tspace_json::Document;

    const MAX: usize = 1 << 20;

    fn view(buffer: &[u8], stride: Option<usize>) -> BufferView<'_> {
        BufferView {
            buffer,
            byte_offset: 0,
            byte_length: buffer.len(),
            byte_stride: stride,
        }
    }

    fn accessor<'a>(
        component_type: ComponentType,
        normalized: bool,
        element_type: ElementType,
        count: usize,
        view: Option<BufferView<'a>>,
    ) -> Accessor<'a> {
        Accessor {
            component_type,
            normalized,
            element_type,
            count,
            byte_offset: 0,
            view,
            sparse: None,
        }
    }

    fn scalars(acc: &Accessor<'_>) -> Result<Vec<f32>, AccessorError> {
        Ok(read_floats::<1>(acc, MAX)?
            .into_iter()
            .map(|[v]| v)
            .collect())
    }

    #[test]
    fn every_component_type_and_normalization() {
        use ComponentType::*;
        let i8s: Vec<u8> = [-128i8, -127, -1, 0, 1, 127]
            .iter()
            .map(|&v| v as u8)
            .collect();
        let u8s = [0u8, 1, 128, 255];
        let i16s: Vec<u8> = [-32768i16, -32767, -1, 0, 16384, 32767]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let u16s: Vec<u8> = [0u16, 1, 32768, 65535]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let u32s: Vec<u8> = [0u32, 1, 16777217, u32::MAX]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let f32s: Vec<u8> = [0.5f32, -0.0, f32::INFINITY, f32::from_bits(0x7FC0_0001)]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let cases: Vec<(ComponentType, bool, &[u8], Vec<f32>)> = vec![
            (I8, false, &i8s, vec![-128.0, -127.0, -1.0, 0.0, 1.0, 127.0]),
            (
                I8,
                true,
                &i8s,
                vec![-1.0, -1.0, -1.0 / 127.0, 0.0, 1.0 / 127.0, 1.0],
            ),
            (U8, false, &u8s, vec![0.0, 1.0, 128.0, 255.0]),
            (U8, true, &u8s, vec![0.0, 1.0 / 255.0, 128.0 / 255.0, 1.0]),
            (
                I16,
                false,
                &i16s,
                vec![-32768.0, -32767.0, -1.0, 0.0, 16384.0, 32767.0],
            ),
            (
                I16,
                true,
                &i16s,
                vec![-1.0, -1.0, -1.0 / 32767.0, 0.0, 16384.0 / 32767.0, 1.0],
            ),
            (U16, false, &u16s, vec![0.0, 1.0, 32768.0, 65535.0]),
            (
                U16,
                true,
                &u16s,
                vec![0.0, 1.0 / 65535.0, 32768.0 / 65535.0, 1.0],
            ),
            (U32, false, &u32s, vec![0.0, 1.0, 16777216.0, 4294967296.0]),
            (
                F32,
                false,
                &f32s,
                vec![0.5, -0.0, f32::INFINITY, f32::from_bits(0x7FC0_0001)],
            ),
        ];
        for (ct, normalized, bytes, expected) in cases {
            let count = bytes.len() / ct.size();
            let acc = accessor(
                ct,
                normalized,
                ElementType::Scalar,
                count,
                Some(view(bytes, None)),
            );
            let got = scalars(&acc).unwrap();
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&got),
                bits(&expected),
                "{ct:?} normalized={normalized}"
            );
        }
        for ct in [U32, F32] {
            let acc = accessor(ct, true, ElementType::Scalar, 1, Some(view(&u32s, None)));
            assert_eq!(
                scalars(&acc),
                Err(AccessorError::NormalizedNotAllowed { component_type: ct })
            );
        }
    }

    #[test]
    fn indices() {
        use ComponentType::*;
        let bytes: Vec<u8> = (0u8..16).collect();
        let read = |ct, normalized, et| {
            let count = 16 / ComponentType::size(ct);
            read_indices(
                &accessor(ct, normalized, et, count, Some(view(&bytes, None))),
                MAX,
            )
        };
        assert_eq!(
            read(U8, false, ElementType::Scalar).unwrap(),
            (0..16).collect::<Vec<u32>>()
        );
        assert_eq!(
            read(U16, false, ElementType::Scalar).unwrap()[..2],
            [0x0100, 0x0302]
        );
        assert_eq!(
            read(U32, false, ElementType::Scalar).unwrap()[1],
            0x0706_0504
        );
        for (ct, normalized, et) in [
            (I8, false, ElementType::Scalar),
            (I16, false, ElementType::Scalar),
            (F32, false, ElementType::Scalar),
            (U16, true, ElementType::Scalar),
            (U8, false, ElementType::Vec2),
        ] {
            let err = read(ct, normalized, et).unwrap_err();
            assert!(matches!(err, AccessorError::NotIndices { .. }), "{ct:?}");
            assert!(
                err.to_string().starts_with("indices must be SCALAR"),
                "{err}"
            );
        }
    }

    #[test]
    fn interleaved_with_stride_and_offset() {
        // Four vertices of position (3 f32) + uv (2 u16 normalized) + padding: 20 bytes each.
        let mut bytes = Vec::new();
        for v in 0..4u16 {
            for c in 0..3 {
                bytes.extend_from_slice(&(f32::from(v) * 10.0 + c as f32).to_le_bytes());
            }
            bytes.extend_from_slice(&(v * 1000).to_le_bytes());
            bytes.extend_from_slice(&65535u16.to_le_bytes());
            bytes.extend_from_slice(&[0xAA; 4]);
        }
        let mut buffer = vec![0xEE; 8];
        buffer.extend_from_slice(&bytes);
        let v = BufferView {
            buffer: &buffer,
            byte_offset: 8,
            byte_length: bytes.len(),
            byte_stride: Some(20),
        };
        let positions = accessor(ComponentType::F32, false, ElementType::Vec3, 4, Some(v));
        let got = read_floats::<3>(&positions, MAX).unwrap();
        assert_eq!(got[3], [30.0, 31.0, 32.0]);
        let mut uvs = accessor(ComponentType::U16, true, ElementType::Vec2, 4, Some(v));
        uvs.byte_offset = 12;
        let got = read_floats::<2>(&uvs, MAX).unwrap();
        assert_eq!(got[2], [2000.0 / 65535.0, 1.0]);
        // One element too many no longer fits.
        uvs.count = 5;
        assert!(matches!(
            read_floats::<2>(&uvs, MAX),
            Err(AccessorError::OutOfView { needed: 96, .. })
        ));
    }

    #[test]
    fn matrix_columns_are_padded() {
        use ComponentType::*;
        use ElementType::*;
        // MAT2 of bytes: columns of 2 bytes padded to 4.
        let bytes = [1u8, 2, 0xFF, 0xFF, 3, 4, 0xFF, 0xFF];
        let acc = accessor(U8, false, Mat2, 1, Some(view(&bytes, None)));
        assert_eq!(read_floats::<4>(&acc, MAX).unwrap(), [[1.0, 2.0, 3.0, 4.0]]);
        // MAT3 of bytes: columns of 3 padded to 4.
        let bytes = [1u8, 2, 3, 0xFF, 4, 5, 6, 0xFF, 7, 8, 9, 0xFF];
        let acc = accessor(I8, false, Mat3, 1, Some(view(&bytes, None)));
        let expected: [f32; 9] = std::array::from_fn(|i| i as f32 + 1.0);
        assert_eq!(read_floats::<9>(&acc, MAX).unwrap(), [expected]);
        // MAT3 of shorts: columns of 6 padded to 8; two elements back to back.
        let mut bytes = Vec::new();
        for m in 0..2i16 {
            for c in 0..3i16 {
                for r in 0..3i16 {
                    bytes.extend_from_slice(&(m * 100 + c * 3 + r).to_le_bytes());
                }
                bytes.extend_from_slice(&[0xFF, 0xFF]);
            }
        }
        let acc = accessor(I16, false, Mat3, 2, Some(view(&bytes, None)));
        let got = read_floats::<9>(&acc, MAX).unwrap();
        assert_eq!(got[1], std::array::from_fn(|i| 100.0 + i as f32));
        // MAT2 of shorts and MAT4 of floats need no padding.
        let bytes: Vec<u8> = (0..4u16).flat_map(|v| v.to_le_bytes()).collect();
        let acc = accessor(U16, false, Mat2, 1, Some(view(&bytes, None)));
        assert_eq!(read_floats::<4>(&acc, MAX).unwrap(), [[0.0, 1.0, 2.0, 3.0]]);
        let bytes: Vec<u8> = (0..16).flat_map(|v| (v as f32).to_le_bytes()).collect();
        let acc = accessor(F32, false, Mat4, 1, Some(view(&bytes, None)));
        assert_eq!(
            read_floats::<16>(&acc, MAX).unwrap(),
            [std::array::from_fn(|i| i as f32)]
        );
        // A padded MAT3 of bytes is 12 bytes: 9 bytes are not enough.
        let acc = accessor(I8, false, Mat3, 1, Some(view(&bytes[..9], None)));
        assert!(matches!(
            read_floats::<9>(&acc, MAX),
            Err(AccessorError::OutOfView { needed: 12, .. })
        ));
        assert_eq!(
            read_floats::<3>(&acc, MAX),
            Err(AccessorError::WrongComponentCount {
                element_type: Mat3,
                requested: 3
            })
        );
    }

    fn le16(values: &[u16]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    fn lef32(values: &[f32]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn sparse_substitution() {
        let base = lef32(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        let indices = le16(&[1, 4]);
        let values = lef32(&[20.0, 50.0]);
        let sparse = Sparse {
            count: 2,
            indices_view: view(&indices, None),
            indices_offset: 0,
            indices_type: ComponentType::U16,
            values_view: view(&values, None),
            values_offset: 0,
        };
        let mut acc = accessor(
            ComponentType::F32,
            false,
            ElementType::Scalar,
            5,
            Some(view(&base, None)),
        );
        acc.sparse = Some(sparse);
        assert_eq!(scalars(&acc).unwrap(), [1.0, 20.0, 3.0, 4.0, 50.0]);
        // Without a buffer view the base is zeros.
        acc.view = None;
        assert_eq!(scalars(&acc).unwrap(), [0.0, 20.0, 0.0, 0.0, 50.0]);
        // Offsets into the sparse views.
        let indices8 = [9u8, 9, 0, 3];
        let values_padded = lef32(&[-1.0, 7.0, 8.0]);
        acc.sparse = Some(Sparse {
            indices_view: view(&indices8, None),
            indices_offset: 2,
            indices_type: ComponentType::U8,
            values_view: view(&values_padded, None),
            values_offset: 4,
            ..sparse
        });
        assert_eq!(scalars(&acc).unwrap(), [7.0, 0.0, 0.0, 8.0, 0.0]);
    }

    #[test]
    fn sparse_errors() {
        let indices = le16(&[3, 1, 7, 0]);
        let values = lef32(&[1.0; 4]);
        let good = Sparse {
            count: 1,
            indices_view: view(&indices, None),
            indices_offset: 0,
            indices_type: ComponentType::U16,
            values_view: view(&values, None),
            values_offset: 0,
        };
        let run = |sparse: Sparse<'_>| {
            let mut acc = accessor(ComponentType::F32, false, ElementType::Scalar, 5, None);
            acc.sparse = Some(sparse);
            scalars(&acc)
        };
        assert!(run(good).is_ok());
        assert_eq!(
            run(Sparse { count: 2, ..good }),
            Err(AccessorError::SparseIndicesNotIncreasing {
                position: 1,
                index: 1,
                previous: 3
            })
        );
        assert_eq!(
            run(Sparse {
                count: 2,
                indices_offset: 2,
                ..good
            }),
            Err(AccessorError::SparseIndexOutOfRange {
                position: 1,
                index: 7,
                count: 5
            })
        );
        let repeated = le16(&[2, 2]);
        assert!(matches!(
            run(Sparse {
                count: 2,
                indices_view: view(&repeated, None),
                ..good
            }),
            Err(AccessorError::SparseIndicesNotIncreasing { .. })
        ));
        for count in [0, 6] {
            assert!(matches!(
                run(Sparse { count, ..good }),
                Err(AccessorError::SparseCount { .. })
            ));
        }
        assert!(matches!(
            run(Sparse {
                count: 4,
                values_offset: 4,
                ..good
            }),
            Err(AccessorError::OutOfView {
                what: "sparse values",
                ..
            })
        ));
        assert!(matches!(
            run(Sparse {
                indices_offset: 8,
                ..good
            }),
            Err(AccessorError::OutOfView {
                what: "sparse indices",
                ..
            })
        ));
        assert!(matches!(
            run(Sparse {
                indices_type: ComponentType::I16,
                ..good
            }),
            Err(AccessorError::SparseIndexType { .. })
        ));
        assert!(matches!(
            run(Sparse {
                values_view: view(&values, Some(4)),
                ..good
            }),
            Err(AccessorError::SparseViewHasStride { what: "values" })
        ));
    }

    #[test]
    fn layout_and_bounds_errors() {
        use AccessorError as E;
        let bytes = vec![0u8; 64];
        let f32_acc = |view| accessor(ComponentType::F32, false, ElementType::Vec3, 2, Some(view));
        let read = |acc: Accessor<'_>| read_floats::<3>(&acc, MAX).map(|_| ());
        assert!(read(f32_acc(view(&bytes, Some(12)))).is_ok());
        for stride in [0, 2, 6, 13, 256, 1 << 40] {
            assert!(
                matches!(
                    read(f32_acc(view(&bytes, Some(stride)))),
                    Err(E::InvalidStride { .. })
                ),
                "{stride}"
            );
        }
        assert_eq!(
            read(f32_acc(view(&bytes, Some(8)))),
            Err(E::StrideTooSmall {
                stride: 8,
                element_size: 12
            })
        );
        // Views that leave their buffer, including by overflowing.
        for (byte_offset, byte_length) in [(0, 65), (60, 8), (usize::MAX, 2), (1, usize::MAX)] {
            let v = BufferView {
                buffer: &bytes,
                byte_offset,
                byte_length,
                byte_stride: None,
            };
            assert!(matches!(read(f32_acc(v)), Err(E::ViewOutOfBuffer { .. })));
        }
        let mut acc = f32_acc(view(&bytes, None));
        acc.byte_offset = 2;
        assert_eq!(
            read(acc),
            Err(E::Misaligned {
                what: "accessor byteOffset",
                offset: 2,
                component_size: 4
            })
        );
        let shifted = BufferView {
            byte_offset: 1,
            byte_length: 24,
            ..view(&bytes, None)
        };
        assert!(matches!(read(f32_acc(shifted)), Err(E::Misaligned { .. })));
        // Counts that cannot fit, up to the largest, fail before allocating.
        for count in [6, 1 << 40, usize::MAX] {
            let mut acc = f32_acc(view(&bytes, Some(252)));
            acc.count = count;
            assert!(
                matches!(read_floats::<3>(&acc, usize::MAX), Err(E::OutOfView { .. })),
                "{count}"
            );
        }
        acc = f32_acc(view(&bytes, None));
        acc.byte_offset = usize::MAX - 3;
        assert!(matches!(read(acc), Err(E::OutOfView { .. })));
        acc.byte_offset = 0;
        acc.count = 0;
        assert_eq!(read(acc), Err(E::ZeroCount));
        // Without a view, only the limit bounds the count.
        let mut zeros = accessor(ComponentType::F32, false, ElementType::Vec3, 1000, None);
        assert_eq!(read_floats::<3>(&zeros, 1000).unwrap().len(), 1000);
        zeros.count = usize::MAX;
        assert_eq!(
            read_floats::<3>(&zeros, 1000),
            Err(E::TooManyElements {
                count: usize::MAX,
                limit: 1000
            })
        );
    }

    /// Decodes the base64 of a data URI (test-only; the real scene loader has its own).
    fn base64(text: &str) -> Vec<u8> {
        let value = |c: u8| match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        };
        let digits: Vec<u8> = text.bytes().filter(|&c| c != b'=').map(value).collect();
        let mut out = Vec::new();
        for chunk in digits.chunks(4) {
            let mut acc = 0u32;
            for (i, &d) in chunk.iter().enumerate() {
                acc |= u32::from(d) << (18 - 6 * i);
            }
            out.extend_from_slice(&acc.to_be_bytes()[1..chunk.len()]);
        }
        out
    }

    fn fixture(name: &str) -> Vec<u8> {
        let path = format!("{}/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    #[test]
    fn quantized_fixture() {
        let text = fixture("quantized_triangle/triangle_mesh_quantized.gltf");
        let doc = Document::parse(&text).unwrap();
        let uri = doc
            .root()
            .get("buffers")
            .unwrap()
            .index(0)
            .unwrap()
            .get("uri")
            .unwrap();
        let data = base64(uri.as_str().unwrap().split_once(',').unwrap().1);
        let buffers = [&data[..]];
        // SHORT positions, 6 bytes apart without a byteStride.
        let positions = read_floats_json::<3>(doc.root(), 0, &buffers, MAX).unwrap();
        assert_eq!(
            positions,
            [[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 100.0, 0.0]]
        );
        // Normalized BYTE normals (127 is 1.0) with a byteStride of 4.
        let normals = read_floats_json::<3>(doc.root(), 1, &buffers, MAX).unwrap();
        assert_eq!(normals, [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]);
    }

    /// Every float and index accessor of real files, against the `gltf` crate's reader.
    #[test]
    fn oracle_against_gltf_crate() {
        let files = [
            "Avocado/Avocado.gltf",
            "Lantern/Lantern.gltf",
            "WaterBottle/WaterBottle.gltf",
            "MultiUVTest/MultiUVTest.gltf",
            "NormalTangentMirrorTest/NormalTangentMirrorTest.gltf",
            "SimpleSparseAccessor/SimpleSparseAccessor.gltf",
        ];
        let mut compared = 0;
        for name in files {
            let text = fixture(name);
            let doc = Document::parse(&text).unwrap();
            let oracle = ::gltf::Gltf::from_slice(&text).unwrap();
            let dir = std::path::Path::new(name).parent().unwrap();
            let data: Vec<Vec<u8>> = oracle
                .buffers()
                .map(|b| match b.source() {
                    ::gltf::buffer::Source::Uri(uri) => fixture(dir.join(uri).to_str().unwrap()),
                    ::gltf::buffer::Source::Bin => unreachable!("no GLB here"),
                })
                .collect();
            let buffers: Vec<&[u8]> = data.iter().map(Vec::as_slice).collect();
            let get = |b: ::gltf::Buffer<'_>| Some(buffers[b.index()]);
            for acc in oracle.accessors() {
                use ::gltf::accessor::{DataType, Dimensions, Iter};
                let i = acc.index();
                match (acc.data_type(), acc.dimensions(), acc.normalized()) {
                    (DataType::F32, Dimensions::Vec2, false) => {
                        let ours = read_floats_json::<2>(doc.root(), i, &buffers, MAX).unwrap();
                        let theirs: Vec<[f32; 2]> = Iter::new(acc, get).unwrap().collect();
                        assert_eq!(bits(&ours), bits(&theirs), "{name} accessor {i}");
                    }
                    (DataType::F32, Dimensions::Vec3, false) => {
                        let ours = read_floats_json::<3>(doc.root(), i, &buffers, MAX).unwrap();
                        let theirs: Vec<[f32; 3]> = Iter::new(acc, get).unwrap().collect();
                        assert_eq!(bits(&ours), bits(&theirs), "{name} accessor {i}");
                    }
                    (DataType::F32, Dimensions::Vec4, false) => {
                        let ours = read_floats_json::<4>(doc.root(), i, &buffers, MAX).unwrap();
                        let theirs: Vec<[f32; 4]> = Iter::new(acc, get).unwrap().collect();
                        assert_eq!(bits(&ours), bits(&theirs), "{name} accessor {i}");
                    }
                    (DataType::U8, Dimensions::Scalar, false) => {
                        let ours = read_indices_json(doc.root(), i, &buffers, MAX).unwrap();
                        let theirs: Vec<u32> =
                            Iter::<u8>::new(acc, get).unwrap().map(u32::from).collect();
                        assert_eq!(ours, theirs, "{name} accessor {i}");
                    }
                    (DataType::U16, Dimensions::Scalar, false) => {
                        let ours = read_indices_json(doc.root(), i, &buffers, MAX).unwrap();
                        let theirs: Vec<u32> =
                            Iter::<u16>::new(acc, get).unwrap().map(u32::from).collect();
                        assert_eq!(ours, theirs, "{name} accessor {i}");
                    }
                    (DataType::U32, Dimensions::Scalar, false) => {
                        let ours = read_indices_json(doc.root(), i, &buffers, MAX).unwrap();
                        let theirs: Vec<u32> = Iter::<u32>::new(acc, get).unwrap().collect();
                        assert_eq!(ours, theirs, "{name} accessor {i}");
                    }
                    other => panic!("{name} accessor {i}: no oracle case for {other:?}"),
                }
                compared += 1;
            }
        }
        assert!(compared >= 30, "only {compared} accessors compared");
    }

    fn bits<const N: usize>(v: &[[f32; N]]) -> Vec<[u32; N]> {
        v.iter().map(|e| e.map(f32::to_bits)).collect()
    }

    #[test]
    fn sparse_fixture() {
        let text = fixture("SimpleSparseAccessor/SimpleSparseAccessor.gltf");
        let bin = fixture("SimpleSparseAccessor/SimpleSparseAccessor.bin");
        let doc = Document::parse(&text).unwrap();
        let positions = read_floats_json::<3>(doc.root(), 1, &[&bin], MAX).unwrap();
        assert_eq!(positions.len(), 14);
        // The three substituted vertices raise the middle of the top edge.
        assert_eq!(positions[8], [1.0, 2.0, 0.0]);
        assert_eq!(positions[10], [3.0, 3.0, 0.0]);
        assert_eq!(positions[12], [5.0, 4.0, 0.0]);
    }

    fn json_err(text: &str, index: usize, buffers: &[&[u8]]) -> String {
        let doc = Document::parse(text.as_bytes()).unwrap();
        accessor_from_json(doc.root(), index, buffers)
            .map(|_| ())
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn json_errors_name_the_path() {
        let buf = [0u8; 64];
        let b: &[&[u8]] = &[&buf];
        let doc = |accessor: &str, view: &str| {
            format!(
                r#"{{"buffers":[{{"byteLength":64}}],"bufferViews":[{view}],"accessors":[{{}},{accessor}]}}"#
            )
        };
        let good_view = r#"{"buffer":0,"byteLength":64}"#;
        let base = r#""componentType":5126,"type":"VEC3","count":2"#;
        let cases = [
            (
                doc(&format!(r#"{{{base},"bufferView":9}}"#), good_view),
                "accessors[1].bufferView: bufferView 9 does not exist",
            ),
            (
                doc(r#"{"componentType":5126,"type":"VEC3"}"#, good_view),
                "accessors[1].count: is missing",
            ),
            (
                doc(
                    r#"{"componentType":5126,"type":"VEC3","count":-2}"#,
                    good_view,
                ),
                "accessors[1].count: must be a non-negative integer, not -2",
            ),
            (
                doc(
                    r#"{"componentType":5126,"type":"VEC3","count":"2"}"#,
                    good_view,
                ),
                "accessors[1].count: must be a non-negative integer, not a string",
            ),
            (
                doc(
                    r#"{"componentType":5124,"type":"VEC3","count":2}"#,
                    good_view,
                ),
                "accessors[1].componentType: 5124 is not a glTF component type",
            ),
            (
                doc(
                    r#"{"componentType":5126,"type":"VEC5","count":2}"#,
                    good_view,
                ),
                "accessors[1].type: must be SCALAR",
            ),
            (
                doc(r#"{"componentType":5126,"type":3,"count":2}"#, good_view),
                "accessors[1].type: must be a string, not a number",
            ),
            (
                doc(&format!(r#"{{{base},"normalized":1}}"#), good_view),
                "accessors[1].normalized: must be a boolean, not a number",
            ),
            (
                doc(
                    &format!(r#"{{{base},"bufferView":0}}"#),
                    r#"{"buffer":3,"byteLength":4}"#,
                ),
                "bufferViews[0].buffer: buffer 3 does not exist (1 buffers are loaded)",
            ),
            (
                doc(&format!(r#"{{{base},"bufferView":0}}"#), r#"{"buffer":0}"#),
                "bufferViews[0].byteLength: is missing",
            ),
            (
                doc(&format!(r#"{{{base},"sparse":{{"count":1}}}}"#), good_view),
                "accessors[1].sparse.indices: must be an object",
            ),
            (
                doc(
                    &format!(
                        r#"{{{base},"sparse":{{"count":1,"indices":{{"bufferView":0}},"values":{{"bufferView":0}}}}}}"#
                    ),
                    good_view,
                ),
                "accessors[1].sparse.indices.componentType: is missing",
            ),
            (
                doc(
                    &format!(
                        r#"{{{base},"sparse":{{"count":1,"indices":{{"bufferView":0,"componentType":5123}},"values":{{"bufferView":4}}}}}}"#
                    ),
                    good_view,
                ),
                "accessors[1].sparse.values.bufferView: bufferView 4 does not exist",
            ),
            (
                doc("7", good_view),
                "accessors[1]: must be an object, not a number",
            ),
        ];
        for (text, expected) in &cases {
            let err = json_err(text, 1, b);
            assert!(err.starts_with(expected), "{err}\nexpected: {expected}");
        }
        assert_eq!(
            json_err("{}", 0, b),
            "accessors: the document has no accessors array, so accessors[0] does not exist"
        );
        assert_eq!(
            json_err(r#"{"accessors":[]}"#, 2, b),
            "accessors: accessors[2] does not exist (there are 0 accessors)"
        );
        // Decoding errors name the accessor too.
        let text = doc(
            &format!(r#"{{{base},"bufferView":0,"byteOffset":60}}"#),
            good_view,
        );
        let parsed = Document::parse(text.as_bytes()).unwrap();
        let err = read_floats_json::<3>(parsed.root(), 1, b, MAX).unwrap_err();
        assert_eq!(
            err.to_string(),
            "accessors[1]: the accessor's elements need 84 bytes of a 64-byte buffer view"
        );
    }

    #[test]
    fn declared_buffer_length_bounds_views() {
        // A GLB BIN chunk is padded; views must still end within the declared byteLength.
        let bin = [0u8; 16];
        let text = r#"{"buffers":[{"byteLength":12}],
            "bufferViews":[{"buffer":0,"byteLength":16}],
            "accessors":[{"bufferView":0,"componentType":5126,"type":"SCALAR","count":4}]}"#;
        let doc = Document::parse(text.as_bytes()).unwrap();
        let err = read_floats_json::<1>(doc.root(), 0, &[&bin], MAX).unwrap_err();
        assert!(err.to_string().contains("12-byte buffer"), "{err}");
    }

    fn arb_component() -> impl Strategy<Value = ComponentType> {
        prop::sample::select(vec![
            ComponentType::I8,
            ComponentType::U8,
            ComponentType::I16,
            ComponentType::U16,
            ComponentType::U32,
            ComponentType::F32,
        ])
    }

    fn arb_element() -> impl Strategy<Value = ElementType> {
        prop::sample::select(vec![
            ElementType::Scalar,
            ElementType::Vec2,
            ElementType::Vec3,
            ElementType::Vec4,
            ElementType::Mat2,
            ElementType::Mat3,
            ElementType::Mat4,
        ])
    }

    /// Mostly small numbers, sometimes huge ones.
    fn arb_size() -> impl Strategy<Value = usize> {
        prop_oneof![
            8 => 0usize..80,
            1 => Just(usize::MAX),
            1 => any::<usize>(),
        ]
    }

    fn read_any(acc: &Accessor<'_>) -> Result<usize, AccessorError> {
        let max = 4096;
        let _ = read_indices(acc, max);
        Ok(match acc.element_type.components() {
            1 => read_floats::<1>(acc, max)?.len(),
            2 => read_floats::<2>(acc, max)?.len(),
            3 => read_floats::<3>(acc, max)?.len(),
            4 => read_floats::<4>(acc, max)?.len(),
            9 => read_floats::<9>(acc, max)?.len(),
            _ => read_floats::<16>(acc, max)?.len(),
        })
    }

    proptest! {
        #[test]
        fn arbitrary_descriptions_never_panic(
            buffer in proptest::collection::vec(any::<u8>(), 0..300),
            component_type in arb_component(),
            indices_type in arb_component(),
            element_type in arb_element(),
            normalized in any::<bool>(),
            count in arb_size(),
            byte_offset in arb_size(),
            view_offset in arb_size(),
            view_length in arb_size(),
            stride in prop::option::of(arb_size()),
            has_view in any::<bool>(),
            sparse in prop::option::of((arb_size(), arb_size(), arb_size(), arb_size())),
        ) {
            let v = BufferView {
                buffer: &buffer,
                byte_offset: view_offset,
                byte_length: view_length,
                byte_stride: stride,
            };
            let acc = Accessor {
                component_type,
                normalized,
                element_type,
                count,
                byte_offset,
                view: has_view.then_some(v),
                sparse: sparse.map(|(count, indices_offset, values_offset, len)| Sparse {
                    count,
                    indices_view: BufferView { byte_length: len, byte_stride: None, ..v },
                    indices_offset,
                    indices_type,
                    values_view: BufferView { byte_offset: 0, byte_length: len, byte_stride: None, ..v },
                    values_offset,
                }),
            };
            if let Ok(n) = read_any(&acc) {
                prop_assert_eq!(n, count);
            }
        }

        #[test]
        fn arbitrary_json_descriptions_never_panic(
            values in proptest::collection::vec(
                prop::sample::select(vec![
                    "0", "1", "4", "12", "-1", "5126", "5121", "5123", "1e3", "2.5", "\"VEC3\"",
                    "\"SCALAR\"", "\"MAT3\"", "true", "null", "[]", "{}", "18446744073709551616",
                    "{\"count\":1,\"indices\":{\"bufferView\":0,\"componentType\":5121},\
                     \"values\":{\"bufferView\":1}}",
                ]),
                12,
            ),
            buffer in proptest::collection::vec(any::<u8>(), 0..64),
        ) {
            let text = format!(
                r#"{{"buffers":[{{"byteLength":{}}}],
                "bufferViews":[{{"buffer":{},"byteOffset":{},"byteLength":{},"byteStride":{}}},
                               {{"buffer":0,"byteLength":{}}}],
                "accessors":[{{"bufferView":{},"byteOffset":{},"componentType":{},"type":{},
                               "count":{},"sparse":{}}}]}}"#,
                values[0], values[1], values[2], values[3], values[4], values[5],
                values[6], values[7], values[8], values[9], values[10], values[11],
            );
            let doc = Document::parse(text.as_bytes()).unwrap();
            if let Ok(acc) = accessor_from_json(doc.root(), 0, &[&buffer]) {
                let _ = read_any(&acc);
            }
        }
    }
}
