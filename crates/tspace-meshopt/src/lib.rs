//! `EXT_meshopt_compression`: decoding of meshoptimizer-compressed buffer views.
//!
//! The extension (KhronosGroup/glTF, `extensions/2.0/Vendor/EXT_meshopt_compression`) stores a
//! buffer view's bytes compressed by one of three codecs, named by the view's `mode`:
//!
//! - `ATTRIBUTES`: vertex data. Elements of `byteStride` bytes are split into blocks of up to
//!   256, each byte position is delta-coded against the previous element and packed in groups
//!   of 16 with 0, 1, 2, 4 or 8 bits per delta (out-of-range deltas escape to a full byte).
//!   After decoding, an optional `filter` turns the stored integers back into the data the
//!   accessors describe: `OCTAHEDRAL` unit vectors, `QUATERNION` rotations, `EXPONENTIAL`
//!   floats, and `COLOR` (YCoCg) colours.
//! - `TRIANGLES`: triangle-list indices, one code byte per triangle referring to a 16-entry
//!   edge FIFO and vertex FIFO, with LEB128 deltas for indices the FIFOs cannot give.
//! - `INDICES`: any other index sequence, as LEB128 zigzag deltas against two baselines.
//!
//! tspace decodes compressed views only to read mesh data (positions, normals, UVs, indices) for
//! tangent generation; it never re-encodes. Output that tspace writes carries its own data.
//!
//! # Versions and the successor extension
//!
//! `KHR_meshopt_compression` (draft) uses the same modes with a superset bitstream, and this
//! decoder reads both: vertex streams of version 0 (header `0xa0`, the only one
//! `EXT_meshopt_compression` allows) and version 1 (`0xa1`: per-byte control modes, 1-bit
//! groups, and 16-bit delta or rotated 32-bit XOR channels; meshoptimizer 0.23+ writes it by
//! default), and the `COLOR` filter, which only the KHR specification lists. Index streams are
//! `0xe1` and `0xd1`; the format-version-0 headers `0xe0` and `0xd0` that meshoptimizer's own
//! decoder still reads are read too (`0xd0` is the same format as `0xd1`; `0xe0` lacks the
//! `last ± 1` codes). Any other header, including a later vertex version, is an error that says
//! so.
//!
//! Decoding follows meshoptimizer's reference decoder (`vertexcodec.cpp`, `indexcodec.cpp`):
//! it accepts the streams the reference accepts and produces the same bytes, except that it
//! rejects two things the specifications call invalid and the reference lets through: a
//! version-1 channel byte other than 0, 1 or `r << 4 | 2`, and a `TRIANGLES` lookup table with
//! a `0xf` nibble or non-zero last two bytes. The FIFOs start filled with `0xffffffff`, as the
//! reference encoder's and decoder's do (the encoder can refer to such an entry when an index
//! is `0xffffffff`).
//!
//! # Filters and exactness
//!
//! The specification defines filter results only to one unit in the last place (the
//! exponential filter exactly), and meshoptimizer's implementations differ from each other at
//! that level: the scalar one rounds halves away from zero, the SIMD ones to even, and the x86
//! SSE one computes the 8-bit octahedral and 8-bit colour scales with the approximate
//! `rsqrtps`/`rcpps` instructions, whose results vary between CPU vendors. This module computes
//! every filter with correctly rounded `f32` operations in the order meshoptimizer's SIMD code
//! uses (exactly its WebAssembly SIMD path, which browser loaders run where SIMD is available),
//! rounding to even and mapping NaN or out-of-range values as `cvtps2dq` does. The result is the same on every
//! platform, and equals the x86 SSE reference bit for bit for `EXPONENTIAL`, `QUATERNION`, and
//! the 16-bit `OCTAHEDRAL` and `COLOR` filters (on any input, valid or not); for the 8-bit
//! `OCTAHEDRAL` and `COLOR` filters it is within one unit of the SSE reference, and equal except
//! where `rsqrtps`/`rcpps` push a product across a rounding boundary. A NaN from the exponential
//! filter (only possible with exponent -128, outside the valid range) is stored as `0xffc00000`,
//! the value x86 produces.
//!
//! # Limits
//!
//! [`decode`] never panics, and allocates exactly one buffer, of `count * byteStride` bytes,
//! only after checking (with checked arithmetic) that this fits `max_output_bytes` *and* that
//! the compressed data is at least as long as the smallest encoding of that many elements can
//! be. Those minimum sizes (header, per-block overhead, tail) bound the expansion:
//!
//! | mode | smallest encoding | bytes out per byte in, at most |
//! | --- | --- | --- |
//! | `ATTRIBUTES` v0 | 1 + 2 header bits per 16 elements per byte position, per block + tail of `max(stride, 32)` | 64 (a block of 256 elements: 4 header bytes per byte position) |
//! | `ATTRIBUTES` v1 | 1 + `stride / 4` control bytes per block + tail of `max(stride * 5/4, 24)` | 1024 (a block of 256 all-zero-delta elements: one control byte per 4 byte positions) |
//! | `TRIANGLES` | 1 + one code byte per triangle + 16-byte table | 12 (3 indices of 4 bytes per code byte) |
//! | `INDICES` | 1 + one byte per index + 4-byte tail | 4 |
//!
//! Beyond the fixed header and tail, then, a compressed view of `n` bytes decodes to at most
//! `1024 * n` bytes (`64 * n` for the version `EXT_meshopt_compression` specifies), so the
//! caller's `max_output_bytes` is what bounds a hostile file's version-1 views. Decoding time is
//! linear in the output size.
//!
//! Structural rules that need the rest of the document (the parent view's `byteLength` equal to
//! `count * byteStride`, a matching parent `byteStride`, fallback buffers) are the caller's.
//!
//! # Example
//!
//! The index sequence 0, 1, 2, 2, 1, 3 as an `INDICES` stream: the header, then one LEB128
//! byte per index holding `zigzag(delta) << 1 | baseline` (here always baseline 0, starting
//! at 0), then the 4-byte tail.
//!
//! ```
//! use tspace_meshopt::{Compressed, Filter, Mode, decode};
//!
//! # fn main() -> Result<(), tspace_meshopt::MeshoptError> {
//! let data = [0xd1, 0, 4, 4, 0, 2, 8, 0, 0, 0, 0];
//! let view = Compressed {
//!     data: &data,
//!     count: 6,
//!     byte_stride: 2,
//!     mode: Mode::from_name("INDICES")?,
//!     filter: Filter::None,
//! };
//! let bytes = decode(&view, 1 << 20)?;
//! let indices: Vec<u16> = bytes
//!     .chunks_exact(2)
//!     .map(|b| u16::from_le_bytes([b[0], b[1]]))
//!     .collect();
//! assert_eq!(indices, [0, 1, 2, 2, 1, 3]);
//! # Ok(())
//! # }
//! ```

#![warn(missing_docs)]

use std::fmt;

/// Compression mode of a view: which bitstream its data is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Vertex codec (mode 0).
    Attributes,
    /// Triangle-list index codec (mode 1).
    Triangles,
    /// Index-sequence codec (mode 2).
    Indices,
}

impl Mode {
    /// From the extension's JSON `mode` string.
    pub fn from_name(name: &str) -> Result<Self, MeshoptError> {
        match name {
            "ATTRIBUTES" => Ok(Mode::Attributes),
            "TRIANGLES" => Ok(Mode::Triangles),
            "INDICES" => Ok(Mode::Indices),
            _ => Err(MeshoptError::UnknownMode(excerpt(name))),
        }
    }

    /// The JSON name.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Attributes => "ATTRIBUTES",
            Mode::Triangles => "TRIANGLES",
            Mode::Indices => "INDICES",
        }
    }

    fn expected_header(self) -> &'static str {
        match self {
            Mode::Attributes => "0xa0 or 0xa1",
            Mode::Triangles => "0xe1",
            Mode::Indices => "0xd1",
        }
    }

    /// The mode whose header family (high nibble) `byte` belongs to, if any.
    fn of_header(byte: u8) -> Option<Self> {
        match byte & 0xf0 {
            0xa0 => Some(Mode::Attributes),
            0xe0 => Some(Mode::Triangles),
            0xd0 => Some(Mode::Indices),
            _ => None,
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Post-decoding filter of an `ATTRIBUTES` view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Filter {
    /// Data is used as decoded (the default when the JSON has no `filter`).
    #[default]
    None,
    /// Octahedral unit vectors: 4 × 8-bit or 4 × 16-bit signed components.
    Octahedral,
    /// Unit quaternions with the largest component dropped: 4 × 16-bit.
    Quaternion,
    /// Floats as an 8-bit exponent and a 24-bit mantissa, per 32-bit word.
    Exponential,
    /// YCoCg colours with alpha (`KHR_meshopt_compression` only): 4 × 8-bit or 4 × 16-bit.
    Color,
}

impl Filter {
    /// From the extension's JSON `filter` string.
    pub fn from_name(name: &str) -> Result<Self, MeshoptError> {
        match name {
            "NONE" => Ok(Filter::None),
            "OCTAHEDRAL" => Ok(Filter::Octahedral),
            "QUATERNION" => Ok(Filter::Quaternion),
            "EXPONENTIAL" => Ok(Filter::Exponential),
            "COLOR" => Ok(Filter::Color),
            _ => Err(MeshoptError::UnknownFilter(excerpt(name))),
        }
    }

    /// The JSON name.
    pub fn name(self) -> &'static str {
        match self {
            Filter::None => "NONE",
            Filter::Octahedral => "OCTAHEDRAL",
            Filter::Quaternion => "QUATERNION",
            Filter::Exponential => "EXPONENTIAL",
            Filter::Color => "COLOR",
        }
    }

    /// Whether the filter can work on elements of `byte_stride` bytes.
    fn fits_stride(self, byte_stride: usize) -> bool {
        match self {
            Filter::None => true,
            Filter::Octahedral | Filter::Color => byte_stride == 4 || byte_stride == 8,
            Filter::Quaternion => byte_stride == 8,
            Filter::Exponential => byte_stride % 4 == 0,
        }
    }

    fn stride_rule(self) -> &'static str {
        match self {
            Filter::None => "any byteStride",
            Filter::Octahedral | Filter::Color => "byteStride 4 or 8",
            Filter::Quaternion => "byteStride 8",
            Filter::Exponential => "a byteStride that is a multiple of 4",
        }
    }
}

impl fmt::Display for Filter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One compressed buffer view, as its `EXT_meshopt_compression` object describes it.
#[derive(Clone, Copy, Debug)]
pub struct Compressed<'a> {
    /// The compressed bytes (`byteLength` bytes at `byteOffset` of the extension's `buffer`).
    pub data: &'a [u8],
    /// Number of elements (`count`).
    pub count: usize,
    /// Size of one element in bytes (`byteStride`).
    pub byte_stride: usize,
    /// Which codec the data is (`mode`).
    pub mode: Mode,
    /// What to apply after decoding (`filter`; [`Filter::None`] when the JSON has none). Only
    /// [`Mode::Attributes`] views may have another.
    pub filter: Filter,
}

/// Why a compressed view could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshoptError {
    /// The JSON `mode` is none of the three (the string, cut to 64 characters).
    UnknownMode(String),
    /// The JSON `filter` is none of the five (the string, cut to 64 characters).
    UnknownFilter(String),
    /// `byteStride` breaks the mode's rule: a multiple of 4 from 4 to 256 for `ATTRIBUTES`, 2
    /// or 4 for the index modes.
    InvalidStride {
        /// The view's mode.
        mode: Mode,
        /// The rejected `byteStride`.
        byte_stride: usize,
    },
    /// `TRIANGLES` with a count that is not a multiple of 3.
    TriangleCount {
        /// The view's `count`.
        count: usize,
    },
    /// A filter other than `NONE` on an index mode.
    FilterOnIndices {
        /// The view's mode, `TRIANGLES` or `INDICES`.
        mode: Mode,
        /// The filter it was given.
        filter: Filter,
    },
    /// `byteStride` does not suit the filter (`OCTAHEDRAL` and `COLOR` take 4 or 8,
    /// `QUATERNION` 8, `EXPONENTIAL` a multiple of 4).
    FilterStride {
        /// The view's filter.
        filter: Filter,
        /// The view's `byteStride`.
        byte_stride: usize,
    },
    /// `count * byteStride` overflows or exceeds the caller's limit.
    OutputTooLarge {
        /// The view's `count`.
        count: usize,
        /// The view's `byteStride`.
        byte_stride: usize,
        /// The `max_output_bytes` passed to [`decode`].
        limit: usize,
    },
    /// The data is shorter than any encoding of `count` elements can be.
    InputTooShort {
        /// The view's mode.
        mode: Mode,
        /// Length of the compressed data, in bytes.
        len: usize,
        /// Length of the shortest possible encoding, in bytes (`usize::MAX` if that
        /// overflows).
        needed: usize,
        /// The view's `count`.
        count: usize,
        /// The view's `byteStride`.
        byte_stride: usize,
    },
    /// The first byte is not a header of the view's mode.
    BadHeader {
        /// The view's mode.
        mode: Mode,
        /// The data's first byte (which may be another mode's header; the message says so).
        byte: u8,
    },
    /// A header of the right mode but a bitstream version this decoder does not read.
    UnsupportedVersion {
        /// The view's mode.
        mode: Mode,
        /// The header byte; its low nibble is the version.
        byte: u8,
    },
    /// The data ran out before every element was decoded.
    Truncated {
        /// The view's mode.
        mode: Mode,
    },
    /// Bytes were left between the decoded data and the tail.
    TrailingData {
        /// The view's mode.
        mode: Mode,
        /// How many bytes were left unread.
        extra: usize,
    },
    /// A version-1 vertex stream declares an invalid channel mode for bytes `4 * channel..`.
    InvalidChannel {
        /// Index of the 4-byte channel within an element (bytes `4 * channel` to
        /// `4 * channel + 3`).
        channel: usize,
        /// The channel's control byte from the stream's tail: valid ones are 0, 1 and
        /// `r << 4 | 2`.
        byte: u8,
    },
    /// The 16-byte lookup table at the end of a `TRIANGLES` stream breaks its rules.
    InvalidCodeTable,
}

impl fmt::Display for MeshoptError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("EXT_meshopt_compression: ")?;
        match self {
            MeshoptError::UnknownMode(name) => write!(
                f,
                "unknown mode \"{name}\" (expected ATTRIBUTES, TRIANGLES or INDICES)"
            ),
            MeshoptError::UnknownFilter(name) => write!(
                f,
                "unknown filter \"{name}\" (expected NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL or \
                 COLOR)"
            ),
            MeshoptError::InvalidStride {
                mode: Mode::Attributes,
                byte_stride,
            } => write!(
                f,
                "byteStride {byte_stride} is not valid for ATTRIBUTES (it must be a multiple of 4 \
                 from 4 to 256)"
            ),
            MeshoptError::InvalidStride { mode, byte_stride } => {
                write!(
                    f,
                    "byteStride {byte_stride} is not valid for {mode} (it must be 2 or 4)"
                )
            }
            MeshoptError::TriangleCount { count } => {
                write!(
                    f,
                    "count {count} is not a multiple of 3, which TRIANGLES requires"
                )
            }
            MeshoptError::FilterOnIndices { mode, filter } => write!(
                f,
                "filter {filter} cannot be used with mode {mode} (only ATTRIBUTES views take a \
                 filter)"
            ),
            MeshoptError::FilterStride {
                filter,
                byte_stride,
            } => write!(
                f,
                "filter {filter} needs {}, not {byte_stride}",
                filter.stride_rule()
            ),
            MeshoptError::OutputTooLarge {
                count,
                byte_stride,
                limit,
            } => write!(
                f,
                "{count} elements of {byte_stride} bytes would decode to more than the \
                 {limit}-byte limit"
            ),
            MeshoptError::InputTooShort {
                mode,
                len,
                needed,
                count,
                byte_stride,
            } => write!(
                f,
                "{len} bytes of {mode} data cannot encode {count} elements of {byte_stride} bytes \
                 (that takes at least {needed} bytes)"
            ),
            MeshoptError::BadHeader { mode, byte } => {
                write!(
                    f,
                    "{mode} data starts with 0x{byte:02x}, not a {mode} header ({})",
                    mode.expected_header()
                )?;
                match Mode::of_header(*byte) {
                    Some(other) if other != *mode => {
                        write!(f, "; it looks like {other} data")
                    }
                    _ => Ok(()),
                }
            }
            MeshoptError::UnsupportedVersion { mode, byte } => write!(
                f,
                "{mode} data is bitstream version {} (header 0x{byte:02x}), which this decoder \
                 does not read (it reads versions 0 and 1)",
                byte & 0x0f
            ),
            MeshoptError::Truncated { mode } => {
                write!(f, "{mode} data ends before all its elements are decoded")
            }
            MeshoptError::TrailingData { mode, extra } => write!(
                f,
                "{mode} data has {extra} unread bytes after its elements (the view's count, \
                 byteStride or byteLength is wrong, or the data is corrupt)"
            ),
            MeshoptError::InvalidChannel { channel, byte } => write!(
                f,
                "ATTRIBUTES data declares channel mode 0x{byte:02x} for bytes {}..{}, which is \
                 not a valid mode",
                channel * 4,
                channel * 4 + 3
            ),
            MeshoptError::InvalidCodeTable => f.write_str(
                "TRIANGLES data ends in an invalid lookup table (a 0xf nibble, or non-zero last \
                 two bytes)",
            ),
        }
    }
}

impl std::error::Error for MeshoptError {}

/// At most 64 characters of an untrusted name, for an error message.
fn excerpt(name: &str) -> String {
    name.chars().take(64).collect()
}

/// Decodes one compressed buffer view into `count * byte_stride` bytes, filter applied.
///
/// Fails, without allocating, if the description breaks the specification's rules for the
/// mode and filter, if the output would exceed `max_output_bytes`, or if the data is too short
/// to encode `count` elements; fails after decoding if the data is malformed. Never panics.
pub fn decode(c: &Compressed<'_>, max_output_bytes: usize) -> Result<Vec<u8>, MeshoptError> {
    let (mode, filter, count, stride) = (c.mode, c.filter, c.count, c.byte_stride);
    match mode {
        Mode::Attributes => {
            if stride == 0 || stride > 256 || stride % 4 != 0 {
                return Err(MeshoptError::InvalidStride {
                    mode,
                    byte_stride: stride,
                });
            }
            if !filter.fits_stride(stride) {
                return Err(MeshoptError::FilterStride {
                    filter,
                    byte_stride: stride,
                });
            }
        }
        Mode::Triangles | Mode::Indices => {
            if stride != 2 && stride != 4 {
                return Err(MeshoptError::InvalidStride {
                    mode,
                    byte_stride: stride,
                });
            }
            if mode == Mode::Triangles && count % 3 != 0 {
                return Err(MeshoptError::TriangleCount { count });
            }
            if filter != Filter::None {
                return Err(MeshoptError::FilterOnIndices { mode, filter });
            }
        }
    }

    let too_large = MeshoptError::OutputTooLarge {
        count,
        byte_stride: stride,
        limit: max_output_bytes,
    };
    let out_len = count.checked_mul(stride).ok_or(too_large.clone())?;
    if out_len > max_output_bytes {
        return Err(too_large);
    }

    let data = c.data;
    // An empty view is judged by the version `EXT_meshopt_compression` specifies.
    let version = match data.first() {
        Some(&byte) => header_version(mode, byte)?,
        None => 0,
    };
    let needed = match mode {
        Mode::Attributes => min_attributes_len(count, stride, version),
        Mode::Triangles => (count / 3).checked_add(1 + TRIANGLE_TABLE_LEN),
        Mode::Indices => count.checked_add(1 + SEQUENCE_TAIL_LEN),
    }
    .unwrap_or(usize::MAX);
    if data.len() < needed {
        return Err(MeshoptError::InputTooShort {
            mode,
            len: data.len(),
            needed,
            count,
            byte_stride: stride,
        });
    }

    // The checks above bound `out_len` by both the caller's limit and the input length.
    let mut out = vec![0u8; out_len];
    match mode {
        Mode::Attributes => decode_attributes(data, version, stride, &mut out)?,
        Mode::Triangles => decode_triangles(data, version, stride, &mut out)?,
        Mode::Indices => decode_sequence(data, stride, &mut out)?,
    }
    apply_filter(filter, stride, &mut out);
    Ok(out)
}

/// The bitstream version in a header byte of `mode`'s family (0 or 1).
fn header_version(mode: Mode, byte: u8) -> Result<u8, MeshoptError> {
    if Mode::of_header(byte) != Some(mode) {
        return Err(MeshoptError::BadHeader { mode, byte });
    }
    match byte & 0x0f {
        version @ (0 | 1) => Ok(version),
        _ => Err(MeshoptError::UnsupportedVersion { mode, byte }),
    }
}

/// Reads the compressed stream front to back; running out is `None`.
struct Reader<'a> {
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (head, tail) = self.rest.split_at_checked(n)?;
        self.rest = tail;
        Some(head)
    }

    fn byte(&mut self) -> Option<u8> {
        let (&first, tail) = self.rest.split_first()?;
        self.rest = tail;
        Some(first)
    }

    /// Unsigned LEB128 of up to 5 bytes, bits past 32 dropped. Like the reference decoder, a
    /// fifth byte ends the number whatever its high bit.
    fn varint(&mut self) -> Option<u32> {
        let lead = self.byte()?;
        let mut value = u32::from(lead & 0x7f);
        if lead & 0x80 != 0 {
            for shift in [7u32, 14, 21, 28] {
                let group = self.byte()?;
                value |= u32::from(group & 0x7f) << shift;
                if group & 0x80 == 0 {
                    break;
                }
            }
        }
        Some(value)
    }
}

// ---------------------------------------------------------------------------------------------
// ATTRIBUTES: the vertex codec

/// Elements are decoded in groups of this many.
const GROUP: usize = 16;
/// Most elements in one block.
const MAX_BLOCK: usize = 256;

/// Elements per block: as many as fit 8 KiB, in whole groups, at most 256 (32 to 256).
fn block_elements(stride: usize) -> usize {
    ((8192 / stride) & !(GROUP - 1)).min(MAX_BLOCK)
}

/// Bytes after the last block: zero padding, then the baseline element and (version 1) one
/// channel byte per 4 bytes of element.
fn vertex_tail(stride: usize, version: u8) -> (usize, usize) {
    let (tail, min) = if version == 0 {
        (stride, 32)
    } else {
        (stride + stride / 4, 24)
    };
    (tail, tail.max(min))
}

/// The shortest stream of `count` elements: every delta zero, which costs the group headers (2
/// bits per group per byte position) in version 0 and only the control bytes in version 1.
fn min_attributes_len(count: usize, stride: usize, version: u8) -> Option<usize> {
    let block = block_elements(stride);
    let per_block = |n: usize| {
        if version == 0 {
            stride * n.div_ceil(GROUP).div_ceil(4)
        } else {
            stride / 4
        }
    };
    let mut len = (count / block).checked_mul(per_block(block))?;
    if count % block != 0 {
        len = len.checked_add(per_block(count % block))?;
    }
    len.checked_add(1 + vertex_tail(stride, version).1)
}

/// How a 4-byte channel turns decoded deltas back into bytes (version 1 tail; version 0 is
/// always `Bytes`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Channel {
    /// Four zigzag 8-bit deltas.
    Bytes,
    /// Two zigzag 16-bit little-endian deltas.
    Shorts,
    /// One 32-bit XOR against the previous value, rotated right by the amount.
    Xor(u32),
}

fn decode_attributes(
    data: &[u8],
    version: u8,
    stride: usize,
    out: &mut [u8],
) -> Result<(), MeshoptError> {
    let mode = Mode::Attributes;
    let (tail_len, padded_tail_len) = vertex_tail(stride, version);
    // `decode` has checked `data.len() >= 1 + padded_tail_len`, so these do not fail.
    let body_end = data
        .len()
        .checked_sub(padded_tail_len)
        .ok_or(MeshoptError::Truncated { mode })?;
    let body = data
        .get(1..body_end)
        .ok_or(MeshoptError::Truncated { mode })?;
    let tail = data
        .get(data.len() - tail_len.min(data.len())..)
        .ok_or(MeshoptError::Truncated { mode })?;
    let (baseline, channel_bytes) = tail
        .split_at_checked(stride)
        .ok_or(MeshoptError::Truncated { mode })?;

    let mut channels = [Channel::Bytes; 64];
    for (index, (slot, &byte)) in channels.iter_mut().zip(channel_bytes).enumerate() {
        *slot = match (byte & 0x0f, byte >> 4) {
            (0, 0) => Channel::Bytes,
            (1, 0) => Channel::Shorts,
            (2, rotation) => Channel::Xor(u32::from(rotation)),
            _ => {
                return Err(MeshoptError::InvalidChannel {
                    channel: index,
                    byte,
                });
            }
        };
    }

    let mut last = [0u8; 256];
    let last = last
        .get_mut(..stride)
        .ok_or(MeshoptError::Truncated { mode })?;
    last.copy_from_slice(baseline);

    let mut reader = Reader { rest: body };
    for block in out.chunks_mut(block_elements(stride) * stride) {
        decode_block(&mut reader, block, stride, last, &channels, version)
            .ok_or(MeshoptError::Truncated { mode })?;
    }
    match reader.rest.len() {
        0 => Ok(()),
        extra => Err(MeshoptError::TrailingData { mode, extra }),
    }
}

/// Bit widths selected by a group's 2-bit header: version 0, and version 1 under control modes
/// 0 and 1.
const BITS_V0: [u8; 4] = [0, 2, 4, 8];
const BITS_V1_CONTROL0: [u8; 4] = [0, 1, 2, 4];
const BITS_V1_CONTROL1: [u8; 4] = [1, 2, 4, 8];

/// Decodes one block of `out.len() / stride` (1 to 256) elements, the previous element in
/// `last`, which it updates to the block's last.
fn decode_block(
    reader: &mut Reader<'_>,
    out: &mut [u8],
    stride: usize,
    last: &mut [u8],
    channels: &[Channel; 64],
    version: u8,
) -> Option<()> {
    let n = out.len() / stride;
    let aligned = n.next_multiple_of(GROUP);
    let control = if version == 0 {
        &[][..]
    } else {
        reader.take(stride / 4)?
    };

    for (c, &channel) in channels.iter().enumerate().take(stride / 4) {
        // Deltas for the channel's four byte positions, element by element.
        let mut deltas = [[0u8; MAX_BLOCK]; 4];
        let control_byte = control.get(c).copied().unwrap_or(0);
        for (j, stream) in deltas.iter_mut().enumerate() {
            let stream = stream.get_mut(..aligned)?;
            if version == 0 {
                decode_byte_stream(reader, stream, &BITS_V0)?;
            } else {
                match (control_byte >> (2 * j)) & 3 {
                    0 => decode_byte_stream(reader, stream, &BITS_V1_CONTROL0)?,
                    1 => decode_byte_stream(reader, stream, &BITS_V1_CONTROL1)?,
                    2 => {} // all deltas zero
                    _ => stream.get_mut(..n)?.copy_from_slice(reader.take(n)?), // literal
                }
            }
        }

        let k = 4 * c;
        let mut prev: [u8; 4] = last.get(k..k + 4)?.try_into().ok()?;
        for (i, element) in out.chunks_exact_mut(stride).enumerate() {
            // i < n <= 256, the length of each delta stream.
            let d = [deltas[0][i], deltas[1][i], deltas[2][i], deltas[3][i]];
            let value = match channel {
                Channel::Bytes => [
                    prev[0].wrapping_add(unzigzag8(d[0])),
                    prev[1].wrapping_add(unzigzag8(d[1])),
                    prev[2].wrapping_add(unzigzag8(d[2])),
                    prev[3].wrapping_add(unzigzag8(d[3])),
                ],
                Channel::Shorts => {
                    let lo = u16::from_le_bytes([prev[0], prev[1]])
                        .wrapping_add(unzigzag16(u16::from_le_bytes([d[0], d[1]])));
                    let hi = u16::from_le_bytes([prev[2], prev[3]])
                        .wrapping_add(unzigzag16(u16::from_le_bytes([d[2], d[3]])));
                    let [a, b] = lo.to_le_bytes();
                    let [c, e] = hi.to_le_bytes();
                    [a, b, c, e]
                }
                Channel::Xor(rotation) => (u32::from_le_bytes(d).rotate_right(rotation)
                    ^ u32::from_le_bytes(prev))
                .to_le_bytes(),
            };
            element.get_mut(k..k + 4)?.copy_from_slice(&value);
            prev = value;
        }
    }

    last.copy_from_slice(out.chunks_exact(stride).next_back()?);
    Some(())
}

/// Decodes the deltas of one byte position over a block (`stream.len()`, a multiple of 16):
/// 2 header bits per group of 16, then each group's packed deltas.
fn decode_byte_stream(reader: &mut Reader<'_>, stream: &mut [u8], bits: &[u8; 4]) -> Option<()> {
    let groups = stream.len() / GROUP;
    let header = reader.take(groups.div_ceil(4))?;
    for (g, group) in stream.chunks_exact_mut(GROUP).enumerate() {
        let selector = (header.get(g / 4)? >> ((g % 4) * 2)) & 3;
        decode_group(reader, bits[usize::from(selector)], group)?;
    }
    Some(())
}

/// Decodes 16 deltas of `bits` bits each. Widths 1, 2 and 4 are packed (1-bit values from the
/// least significant bit up, wider ones from the most significant down); a value with all bits
/// set is a sentinel whose real delta follows as a whole byte, after the packed bytes.
fn decode_group(reader: &mut Reader<'_>, bits: u8, group: &mut [u8]) -> Option<()> {
    match bits {
        0 => group.fill(0),
        8 => group.copy_from_slice(reader.take(GROUP)?),
        _ => {
            let packed = reader.take(2 * usize::from(bits))?;
            let sentinel = (1u8 << bits) - 1;
            let per_byte = usize::from(8 / bits);
            for (i, delta) in group.iter_mut().enumerate() {
                let byte = *packed.get(i / per_byte)?;
                let slot = (i % per_byte) as u8;
                let shift = if bits == 1 {
                    slot
                } else {
                    8 - bits * (slot + 1)
                };
                let value = (byte >> shift) & sentinel;
                *delta = if value == sentinel {
                    reader.byte()?
                } else {
                    value
                };
            }
        }
    }
    Some(())
}

fn unzigzag8(v: u8) -> u8 {
    (v >> 1) ^ 0u8.wrapping_sub(v & 1)
}

fn unzigzag16(v: u16) -> u16 {
    (v >> 1) ^ 0u16.wrapping_sub(v & 1)
}

// ---------------------------------------------------------------------------------------------
// TRIANGLES and INDICES: the index codecs

/// The `codeaux` lookup table closing a `TRIANGLES` stream.
const TRIANGLE_TABLE_LEN: usize = 16;
/// The zero padding closing an `INDICES` stream.
const SEQUENCE_TAIL_LEN: usize = 4;

/// Writes indices as `stride`-byte little-endian integers (2: truncated to 16 bits).
fn write_indices(out: &mut [u8], stride: usize, indices: &[u32]) {
    for (slot, &index) in out.chunks_exact_mut(stride).zip(indices) {
        if stride == 2 {
            slot.copy_from_slice(&(index as u16).to_le_bytes());
        } else {
            slot.copy_from_slice(&index.to_le_bytes());
        }
    }
}

/// The two FIFOs of the triangle codec. Entries not yet written hold `0xffffffff`, as in the
/// reference encoder and decoder.
struct Fifos {
    edges: [[u32; 2]; 16],
    edge_next: usize,
    vertices: [u32; 16],
    vertex_next: usize,
}

impl Fifos {
    /// The edge `back` entries before the most recent (0: the most recent).
    fn edge(&self, back: usize) -> (u32, u32) {
        let [a, b] = self.edges[self.edge_next.wrapping_sub(1 + back) & 15];
        (a, b)
    }

    fn push_edge(&mut self, a: u32, b: u32) {
        self.edges[self.edge_next & 15] = [a, b];
        self.edge_next = (self.edge_next + 1) & 15;
    }

    /// The vertex `back` entries before the most recent (0: the most recent).
    fn vertex(&self, back: usize) -> u32 {
        self.vertices[self.vertex_next.wrapping_sub(1 + back) & 15]
    }

    fn push_vertex(&mut self, v: u32) {
        self.vertices[self.vertex_next & 15] = v;
        self.vertex_next = (self.vertex_next + 1) & 15;
    }
}

fn decode_triangles(
    data: &[u8],
    version: u8,
    stride: usize,
    out: &mut [u8],
) -> Result<(), MeshoptError> {
    let mode = Mode::Triangles;
    let triangles = out.len() / (3 * stride);
    // `decode` has checked `data.len() >= 1 + triangles + 16`.
    let table_start = data
        .len()
        .checked_sub(TRIANGLE_TABLE_LEN)
        .ok_or(MeshoptError::Truncated { mode })?;
    let codes = data
        .get(1..1 + triangles)
        .ok_or(MeshoptError::Truncated { mode })?;
    let extra = data
        .get(1 + triangles..table_start)
        .ok_or(MeshoptError::Truncated { mode })?;
    let table: [u8; 16] = data
        .get(table_start..)
        .and_then(|t| t.try_into().ok())
        .ok_or(MeshoptError::Truncated { mode })?;
    if table[14] != 0 || table[15] != 0 || table.iter().any(|&b| b >> 4 == 0xf || b & 0xf == 0xf) {
        return Err(MeshoptError::InvalidCodeTable);
    }

    // Version 0 has no `last ± 1` codes: 0xXd and 0xXe read the vertex FIFO.
    let fifo_codes = if version == 0 { 15 } else { 13 };
    let mut fifos = Fifos {
        edges: [[u32::MAX; 2]; 16],
        edge_next: 0,
        vertices: [u32::MAX; 16],
        vertex_next: 0,
    };
    let mut next: u32 = 0;
    let mut last: u32 = 0;
    let mut reader = Reader { rest: extra };
    let truncated = MeshoptError::Truncated { mode };

    /// An explicit index: a zigzag delta from `last`, which it updates.
    fn read_index(reader: &mut Reader<'_>, last: &mut u32) -> Option<u32> {
        let v = reader.varint()?;
        *last = last.wrapping_add((v >> 1) ^ 0u32.wrapping_sub(v & 1));
        Some(*last)
    }

    for (&code, triangle) in codes.iter().zip(out.chunks_exact_mut(3 * stride)) {
        let (a, b, c);
        if code < 0xf0 {
            // A recent edge plus a third vertex.
            (a, b) = fifos.edge(usize::from(code >> 4));
            let third = code & 15;
            if third == 0 {
                c = next;
                next = next.wrapping_add(1);
                fifos.push_vertex(c);
            } else if third < fifo_codes {
                c = fifos.vertex(usize::from(third));
            } else {
                c = match third {
                    13 => last.wrapping_sub(1),
                    14 => last.wrapping_add(1),
                    _ => read_index(&mut reader, &mut last).ok_or(truncated.clone())?,
                };
                last = c;
                fifos.push_vertex(c);
            }
            fifos.push_edge(c, b);
            fifos.push_edge(a, c);
        } else {
            // A triangle of new, recent or explicit vertices; the second and third described by
            // a nibble each: 0 is `next`, 1..=14 the vertex FIFO, 15 an explicit index.
            let (explicit_first, aux) = if code < 0xfe {
                (false, table[usize::from(code & 15)])
            } else {
                let aux = reader.byte().ok_or(truncated.clone())?;
                if aux == 0 {
                    next = 0;
                }
                (code == 0xff, aux)
            };
            let (fb, fc) = (aux >> 4, aux & 15);
            let mut fresh = || {
                let v = next;
                next = next.wrapping_add(1);
                v
            };
            let first = if explicit_first { 0 } else { fresh() };
            let second = if fb == 0 {
                fresh()
            } else {
                fifos.vertex(usize::from(fb) - 1)
            };
            let third = if fc == 0 {
                fresh()
            } else {
                fifos.vertex(usize::from(fc) - 1)
            };
            a = if explicit_first {
                read_index(&mut reader, &mut last).ok_or(truncated.clone())?
            } else {
                first
            };
            b = if fb == 15 {
                read_index(&mut reader, &mut last).ok_or(truncated.clone())?
            } else {
                second
            };
            c = if fc == 15 {
                read_index(&mut reader, &mut last).ok_or(truncated.clone())?
            } else {
                third
            };
            fifos.push_vertex(a);
            if fb == 0 || fb == 15 {
                fifos.push_vertex(b);
            }
            if fc == 0 || fc == 15 {
                fifos.push_vertex(c);
            }
            fifos.push_edge(b, a);
            fifos.push_edge(c, b);
            fifos.push_edge(a, c);
        }
        write_indices(triangle, stride, &[a, b, c]);
    }

    match reader.rest.len() {
        0 => Ok(()),
        extra => Err(MeshoptError::TrailingData { mode, extra }),
    }
}

fn decode_sequence(data: &[u8], stride: usize, out: &mut [u8]) -> Result<(), MeshoptError> {
    let mode = Mode::Indices;
    // `decode` has checked `data.len() >= 1 + count + 4`.
    let body_end = data
        .len()
        .checked_sub(SEQUENCE_TAIL_LEN)
        .ok_or(MeshoptError::Truncated { mode })?;
    let body = data
        .get(1..body_end)
        .ok_or(MeshoptError::Truncated { mode })?;
    let mut reader = Reader { rest: body };
    let mut baselines = [0u32; 2];
    for slot in out.chunks_exact_mut(stride) {
        let v = reader.varint().ok_or(MeshoptError::Truncated { mode })?;
        let baseline = &mut baselines[(v & 1) as usize];
        let delta = v >> 1;
        *baseline = baseline.wrapping_add((delta >> 1) ^ 0u32.wrapping_sub(delta & 1));
        write_indices(slot, stride, &[*baseline]);
    }
    match reader.rest.len() {
        0 => Ok(()),
        extra => Err(MeshoptError::TrailingData { mode, extra }),
    }
}

// ---------------------------------------------------------------------------------------------
// Filters

/// The filter step of [`decode`] on its own: applies `filter` in place to elements of `stride`
/// bytes, turning stored (pre-filter) values into the ones a decoder delivers. For an encoder
/// that must know exactly what its filtered values decode to. Elements of a size the filter does
/// not take (see [`Filter`]) are left alone, as is a trailing partial element.
///
/// ```
/// use tspace_meshopt::{Filter, unfilter};
/// // Octahedral, 8-bit: x = 0, y = 0 and 1.0 stored as 127 decode to +z.
/// let mut element = [0u8, 0, 127, 127];
/// unfilter(Filter::Octahedral, 4, &mut element);
/// assert_eq!(element, [0, 0, 127, 127]);
/// ```
pub fn unfilter(filter: Filter, stride: usize, data: &mut [u8]) {
    apply_filter(filter, stride, data);
}

/// Applies `filter` in place to elements of `stride` bytes (`decode` has checked that the
/// filter suits the stride; elements of another size are left alone).
fn apply_filter(filter: Filter, stride: usize, data: &mut [u8]) {
    match (filter, stride) {
        (Filter::Octahedral, 4) => each::<4>(data, octahedral8),
        (Filter::Octahedral, 8) => each::<8>(data, octahedral16),
        (Filter::Quaternion, 8) => each::<8>(data, quaternion),
        (Filter::Exponential, _) => each::<4>(data, exponential),
        (Filter::Color, 4) => each::<4>(data, color8),
        (Filter::Color, 8) => each::<8>(data, color16),
        _ => {}
    }
}

fn each<const N: usize>(data: &mut [u8], f: fn(&mut [u8; N])) {
    for chunk in data.chunks_exact_mut(N) {
        if let Ok(element) = <&mut [u8; N]>::try_from(chunk) {
            f(element);
        }
    }
}

/// Float to integer as x86 `cvtps2dq` does under the default rounding mode: to nearest, ties
/// to even; NaN and values outside the `i32` range give `i32::MIN`. For the finite, in-range
/// products of valid data this is also what meshoptimizer's NEON and WebAssembly paths compute.
fn round_to_i32(v: f32) -> i32 {
    let r = v.round_ties_even();
    if (-2_147_483_648.0..2_147_483_648.0).contains(&r) {
        r as i32
    } else {
        i32::MIN
    }
}

/// The octahedral decode proper: `x`, `y` and the encoding of 1.0 in, components scaled to
/// `max` out (before truncation to the component width).
fn octahedral(x: f32, y: f32, one: f32, max: f32) -> [i32; 3] {
    let z = one - (x.abs() + y.abs());
    // Fold the lower hemisphere: move x and y towards zero by -z.
    let t = if z < 0.0 { z } else { 0.0 };
    let x = x + f32::from_bits(t.to_bits() ^ (x.to_bits() & 0x8000_0000));
    let y = y + f32::from_bits(t.to_bits() ^ (y.to_bits() & 0x8000_0000));
    let s = max / (x * x + (y * y + z * z)).sqrt();
    [
        round_to_i32(x * s),
        round_to_i32(y * s),
        round_to_i32(z * s),
    ]
}

fn octahedral8(e: &mut [u8; 4]) {
    let [x, y, z, _] = e.map(|b| f32::from(b as i8));
    let [x, y, z] = octahedral(x, y, z, 127.0);
    e[0] = x as u8;
    e[1] = y as u8;
    e[2] = z as u8;
}

fn octahedral16(e: &mut [u8; 8]) {
    let x = f32::from(i16::from_le_bytes([e[0], e[1]]));
    let y = f32::from(i16::from_le_bytes([e[2], e[3]]));
    // The encoding of 1.0 is read as a 15-bit unsigned value, as the reference's SIMD code does.
    let one = f32::from(u16::from_le_bytes([e[4], e[5]]) & 0x7fff);
    let [x, y, z] = octahedral(x, y, one, 32767.0);
    e[0..2].copy_from_slice(&(x as u16).to_le_bytes());
    e[2..4].copy_from_slice(&(y as u16).to_le_bytes());
    e[4..6].copy_from_slice(&(z as u16).to_le_bytes());
}

fn quaternion(e: &mut [u8; 8]) {
    let q = [
        i16::from_le_bytes([e[0], e[1]]),
        i16::from_le_bytes([e[2], e[3]]),
        i16::from_le_bytes([e[4], e[5]]),
        i16::from_le_bytes([e[6], e[7]]),
    ];
    // The fourth component is 1.0 in the same fixed point, its low two bits replaced by the
    // index of the dropped (largest) component.
    let s = f32::from(q[3] | 3);
    let [x, y, z] = [f32::from(q[0]), f32::from(q[1]), f32::from(q[2])];
    // Everything is unscaled here: components are stored times sqrt(2) in units of 1/s.
    let ww = s * (s + s) - (x * x + (y * y + z * z));
    let w = (if ww > 0.0 { ww } else { 0.0 }).sqrt();
    let scale = 32767.0f32 / 2.0f32.sqrt();
    let ss = scale / s;
    let values = [
        round_to_i32(x * ss),
        round_to_i32(y * ss),
        round_to_i32(z * ss),
        round_to_i32(w * ss),
    ];
    let dropped = (q[3] & 3) as usize;
    let mut out = [0u16; 4];
    for (offset, value) in [1, 2, 3, 0].into_iter().zip(values) {
        out[(dropped + offset) & 3] = value as u16;
    }
    for (bytes, value) in e.chunks_exact_mut(2).zip(out) {
        bytes.copy_from_slice(&value.to_le_bytes());
    }
}

fn exponential(e: &mut [u8; 4]) {
    let v = u32::from_le_bytes(*e);
    let exponent = (v as i32) >> 24;
    let mantissa = ((v << 8) as i32) >> 8;
    // 2^exponent built directly from bits, as the reference does; only -128 (outside the
    // specification's [-100, 100]) gives a non-finite factor.
    let factor = f32::from_bits(((exponent + 127) as u32) << 23);
    let value = factor * mantissa as f32;
    let bits = if value.is_nan() {
        0xffc0_0000
    } else {
        value.to_bits()
    };
    *e = bits.to_le_bytes();
}

/// The YCoCg decode: luma, signed chroma and alpha in, RGBA scaled to `max` out. `alpha` has
/// its top set bit at position K-1, which gives the bit depth K.
fn color(luma: i32, co: i32, cg: i32, alpha: i32, max: f32) -> [i32; 4] {
    let mut scale = alpha;
    scale |= scale >> 1;
    scale |= scale >> 2;
    scale |= scale >> 4;
    scale |= scale >> 8;
    let alpha = ((alpha << 1) & scale) | (alpha & 1);
    let ss = max / scale as f32;
    let r = luma + (co - cg);
    let g = luma + cg;
    let b = luma - (co + cg);
    [r, g, b, alpha].map(|v| round_to_i32(v as f32 * ss))
}

fn color8(e: &mut [u8; 4]) {
    let rgba = color(
        i32::from(e[0]),
        i32::from(e[1] as i8),
        i32::from(e[2] as i8),
        i32::from(e[3]),
        255.0,
    );
    *e = rgba.map(|v| v as u8);
}

fn color16(e: &mut [u8; 8]) {
    let rgba = color(
        i32::from(u16::from_le_bytes([e[0], e[1]])),
        i32::from(i16::from_le_bytes([e[2], e[3]])),
        i32::from(i16::from_le_bytes([e[4], e[5]])),
        i32::from(u16::from_le_bytes([e[6], e[7]])),
        65535.0,
    );
    for (bytes, value) in e.chunks_exact_mut(2).zip(rgba) {
        bytes.copy_from_slice(&(value as u16).to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    //! Oracle: meshoptimizer itself (the `meshopt` crate's vendored C++), for encoding and for
    //! the decoders and filters our output must equal.

    use super::*;
    use meshopt::ffi;
    use proptest::prelude::*;
    use std::ffi::c_void;
    use std::sync::Mutex;

    /// meshoptimizer's index encoder version is a global; encode under this lock.
    static INDEX_ENCODER: Mutex<()> = Mutex::new(());

    /// xorshift64*: deterministic test data without another dependency.
    struct Rng(u64);

    impl Rng {
        fn new(seed: u64) -> Self {
            Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
        }
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n.max(1)
        }
        fn unit(&mut self) -> f32 {
            (self.next() >> 40) as f32 / (1u64 << 24) as f32
        }
        fn signed(&mut self) -> f32 {
            self.unit() * 2.0 - 1.0
        }
        fn bytes(&mut self, n: usize) -> Vec<u8> {
            (0..n).map(|_| self.next() as u8).collect()
        }
    }

    const LIMIT: usize = 1 << 30;

    fn attributes(data: &[u8], count: usize, byte_stride: usize, filter: Filter) -> Compressed<'_> {
        Compressed {
            data,
            count,
            byte_stride,
            mode: Mode::Attributes,
            filter,
        }
    }

    fn encode_vertices(vertices: &[u8], stride: usize, level: i32, version: i32) -> Vec<u8> {
        let count = vertices.len() / stride;
        let mut out = vec![0u8; unsafe { ffi::meshopt_encodeVertexBufferBound(count, stride) }];
        let size = unsafe {
            ffi::meshopt_encodeVertexBufferLevel(
                out.as_mut_ptr(),
                out.len(),
                vertices.as_ptr().cast(),
                count,
                stride,
                level,
                version,
            )
        };
        assert!(size > 0, "meshoptimizer failed to encode");
        out.truncate(size);
        out
    }

    fn reference_vertices(encoded: &[u8], count: usize, stride: usize) -> Option<Vec<u8>> {
        let mut out = vec![0u8; count * stride];
        let rc = unsafe {
            ffi::meshopt_decodeVertexBuffer(
                out.as_mut_ptr().cast(),
                count,
                stride,
                encoded.as_ptr(),
                encoded.len(),
            )
        };
        (rc == 0).then_some(out)
    }

    fn encode_triangles(indices: &[u32], version: i32) -> Vec<u8> {
        let _lock = INDEX_ENCODER.lock().unwrap_or_else(|e| e.into_inner());
        let vertex_count = indices.iter().map(|&i| i as usize + 1).max().unwrap_or(0);
        let bound = unsafe { ffi::meshopt_encodeIndexBufferBound(indices.len(), vertex_count) };
        let mut out = vec![0u8; bound];
        let size = unsafe {
            ffi::meshopt_encodeIndexVersion(version);
            let size = ffi::meshopt_encodeIndexBuffer(
                out.as_mut_ptr(),
                out.len(),
                indices.as_ptr(),
                indices.len(),
            );
            ffi::meshopt_encodeIndexVersion(1);
            size
        };
        assert!(size > 0, "meshoptimizer failed to encode");
        out.truncate(size);
        out
    }

    fn encode_sequence(indices: &[u32]) -> Vec<u8> {
        let _lock = INDEX_ENCODER.lock().unwrap_or_else(|e| e.into_inner());
        let vertex_count = indices.iter().map(|&i| i as usize + 1).max().unwrap_or(0);
        let bound = unsafe { ffi::meshopt_encodeIndexSequenceBound(indices.len(), vertex_count) };
        let mut out = vec![0u8; bound];
        let size = unsafe {
            ffi::meshopt_encodeIndexSequence(
                out.as_mut_ptr(),
                out.len(),
                indices.as_ptr(),
                indices.len(),
            )
        };
        assert!(size > 0, "meshoptimizer failed to encode");
        out.truncate(size);
        out
    }

    fn reference_indices(
        mode: Mode,
        encoded: &[u8],
        count: usize,
        stride: usize,
    ) -> Option<Vec<u8>> {
        let mut out = vec![0u8; count * stride];
        let decoder = match mode {
            Mode::Triangles => ffi::meshopt_decodeIndexBuffer,
            _ => ffi::meshopt_decodeIndexSequence,
        };
        let rc = unsafe {
            decoder(
                out.as_mut_ptr().cast(),
                count,
                stride,
                encoded.as_ptr(),
                encoded.len(),
            )
        };
        (rc == 0).then_some(out)
    }

    fn index_bytes(indices: &[u32], stride: usize) -> Vec<u8> {
        let mut out = vec![0u8; indices.len() * stride];
        write_indices(&mut out, stride, indices);
        out
    }

    // -----------------------------------------------------------------------------------------
    // Vertex codec

    /// Vertex data of a kind: random bytes, smooth (floats, 16-bit and 32-bit counters, slow
    /// bytes: what version 1's channel modes are for), or one element repeated.
    fn vertex_data(kind: usize, count: usize, stride: usize, seed: u64) -> Vec<u8> {
        let mut rng = Rng::new(seed);
        match kind {
            0 => rng.bytes(count * stride),
            1 => {
                let mut out = Vec::with_capacity(count * stride);
                for i in 0..count {
                    for w in 0..stride / 4 {
                        let word: [u8; 4] = match w % 4 {
                            0 => ((i as f32 * 0.01 + w as f32).sin() * 10.0).to_le_bytes(),
                            1 => {
                                let a = (i * 3 + w) as u16;
                                let b = 40_000u16.wrapping_sub((i / 2) as u16);
                                let [a0, a1] = a.to_le_bytes();
                                let [b0, b1] = b.to_le_bytes();
                                [a0, a1, b0, b1]
                            }
                            2 => {
                                ((i as u32).wrapping_mul(7 + w as u32) ^ 0x5a5a_0000).to_le_bytes()
                            }
                            _ => [(i / 3) as u8, (i / 7) as u8, w as u8, (rng.below(3)) as u8],
                        };
                        out.extend_from_slice(&word);
                    }
                }
                out
            }
            _ => {
                let element = rng.bytes(stride);
                element.repeat(count)
            }
        }
    }

    #[test]
    fn vertex_round_trips_match_reference() {
        let counts = [0usize, 1, 15, 16, 17, 255, 256, 257, 10_000];
        // (level, version): version 0, then version 1 at every level (3 uses XOR channels).
        let encodings = [(2, 0), (0, 1), (1, 1), (2, 1), (3, 1)];
        let mut channel_modes = [0usize; 3];
        let mut streams = 0;
        for stride in [4usize, 8, 12, 16, 32, 64, 256] {
            for kind in 0..3 {
                for &count in &counts {
                    if stride == 256 && count > 257 {
                        continue;
                    }
                    let original = vertex_data(kind, count, stride, (stride * 31 + kind) as u64);
                    for (level, version) in encodings {
                        let encoded = encode_vertices(&original, stride, level, version);
                        assert_eq!(encoded[0], 0xa0 | version as u8);
                        let ours =
                            decode(&attributes(&encoded, count, stride, Filter::None), LIMIT)
                                .unwrap_or_else(|e| {
                                    panic!(
                                        "stride {stride} kind {kind} count {count} v{version}: {e}"
                                    )
                                });
                        assert!(
                            ours == original,
                            "stride {stride} kind {kind} count {count} level {level} v{version}"
                        );
                        assert_eq!(
                            reference_vertices(&encoded, count, stride).as_ref(),
                            Some(&original)
                        );
                        if version == 1 {
                            for &c in &encoded[encoded.len() - stride / 4..] {
                                channel_modes[usize::from(c & 3)] += 1;
                            }
                        }
                        streams += 1;
                    }
                }
            }
        }
        assert!(streams > 900);
        // The data exercises every version-1 channel mode.
        assert!(
            channel_modes.iter().all(|&n| n > 0),
            "channel modes seen: {channel_modes:?}"
        );
    }

    #[test]
    fn vertex_streams_with_every_block_size() {
        // Strides whose blocks hold 256, 128, 64 and 32 elements, with partial last blocks.
        for stride in [4usize, 36, 68, 128, 132, 252, 256] {
            for count in [31usize, 32, 33, 129, 511, 513] {
                let original = vertex_data(1, count, stride, count as u64);
                for (level, version) in [(2, 0), (3, 1)] {
                    let encoded = encode_vertices(&original, stride, level, version);
                    let ours =
                        decode(&attributes(&encoded, count, stride, Filter::None), LIMIT).unwrap();
                    assert!(ours == original, "stride {stride} count {count} v{version}");
                }
            }
        }
    }

    #[test]
    fn minimum_lengths_are_exact() {
        // All-zero data encodes to the smallest stream, which is what the bound assumes.
        for stride in [4usize, 8, 64, 256] {
            for count in [0usize, 1, 16, 17, 256, 257, 1000] {
                let zeros = vec![0u8; count * stride];
                for (level, version) in [(2, 0), (2, 1)] {
                    let encoded = encode_vertices(&zeros, stride, level, version);
                    assert_eq!(
                        Some(encoded.len()),
                        min_attributes_len(count, stride, version as u8),
                        "stride {stride} count {count} v{version}"
                    );
                }
            }
        }
        // The expansion ratios in the module documentation.
        let out = 256 * 4 * 1000;
        let v0 = min_attributes_len(256 * 1000, 4, 0).unwrap() - 1 - 32;
        let v1 = min_attributes_len(256 * 1000, 4, 1).unwrap() - 1 - 24;
        assert_eq!(out / v0, 64);
        assert_eq!(out / v1, 1024);
    }

    // -----------------------------------------------------------------------------------------
    // Index codecs

    fn grid(width: u32, height: u32) -> Vec<u32> {
        let mut out = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let i = y * (width + 1) + x;
                out.extend_from_slice(&[
                    i,
                    i + 1,
                    i + width + 1,
                    i + 1,
                    i + width + 2,
                    i + width + 1,
                ]);
            }
        }
        out
    }

    /// Triangle lists of several shapes, `triangles` long.
    fn triangle_lists(triangles: usize, seed: u64) -> Vec<(&'static str, Vec<u32>)> {
        let mut rng = Rng::new(seed);
        let n = triangles * 3;
        let mut lists = Vec::new();

        let mesh = grid(101, 101);
        let optimized = meshopt::optimize_vertex_cache(&mesh, 102 * 102);
        lists.push(("grid", mesh[..n.min(mesh.len())].to_vec()));
        lists.push((
            "optimized grid",
            optimized[..n.min(optimized.len())].to_vec(),
        ));

        // Two meshes one after the other, the second restarting at 0 (the reset code).
        let half = (triangles / 2) * 3;
        let mut two = optimized[..half.min(optimized.len())].to_vec();
        two.extend_from_slice(&optimized[..(n - two.len()).min(optimized.len())]);
        lists.push(("restarted", two));

        // A strip as a list: consecutive free indices (the last±1 codes).
        let strip: Vec<u32> = (0..triangles as u32)
            .flat_map(|t| {
                if t % 2 == 0 {
                    [t, t + 1, t + 2]
                } else {
                    [t + 1, t, t + 2]
                }
            })
            .map(|i| 1_000_000 - i)
            .collect();
        lists.push(("strip", strip));

        let small: Vec<u32> = (0..n).map(|_| rng.below(40) as u32).collect();
        lists.push(("random small", small));
        let large: Vec<u32> = (0..n).map(|_| rng.below(200_000) as u32).collect();
        lists.push(("random beyond 16 bits", large));
        // Full 32-bit range, with 0xffffffff (what the FIFOs start filled with) and repeats.
        let wide: Vec<u32> = (0..n)
            .map(|_| match rng.below(4) {
                0 => u32::MAX,
                1 => u32::MAX - rng.below(3) as u32,
                _ => rng.next() as u32,
            })
            .collect();
        lists.push(("full range", wide));
        for (_, list) in &mut lists {
            list.resize(n, 7);
        }
        lists
    }

    /// Equal triangle lists, up to a rotation of each triangle.
    fn same_triangles(decoded: &[u32], original: &[u32]) -> bool {
        decoded.len() == original.len()
            && decoded
                .chunks_exact(3)
                .zip(original.chunks_exact(3))
                .all(|(d, o)| {
                    (0..3).any(|r| d[0] == o[r] && d[1] == o[(r + 1) % 3] && d[2] == o[(r + 2) % 3])
                })
    }

    #[test]
    fn triangle_round_trips_match_reference() {
        for triangles in [0usize, 1, 15, 16, 17, 255, 256, 257, 10_000] {
            for (name, indices) in triangle_lists(triangles, triangles as u64) {
                for version in [1, 0] {
                    let encoded = encode_triangles(&indices, version);
                    assert_eq!(encoded[0], 0xe0 | version as u8);
                    let mut wide = Vec::new();
                    for stride in [4usize, 2] {
                        let compressed = Compressed {
                            data: &encoded,
                            count: indices.len(),
                            byte_stride: stride,
                            mode: Mode::Triangles,
                            filter: Filter::None,
                        };
                        let ours = decode(&compressed, LIMIT)
                            .unwrap_or_else(|e| panic!("{name} ×{triangles} v{version}: {e}"));
                        let reference =
                            reference_indices(Mode::Triangles, &encoded, indices.len(), stride);
                        assert!(
                            Some(&ours) == reference.as_ref(),
                            "{name} ×{triangles} v{version} stride {stride}"
                        );
                        if stride == 4 {
                            // The codec keeps each triangle's winding but may rotate it.
                            wide = ours
                                .chunks_exact(4)
                                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                                .collect();
                            assert!(same_triangles(&wide, &indices), "{name} ×{triangles}");
                        } else {
                            assert_eq!(
                                ours,
                                index_bytes(&wide, 2),
                                "16-bit: the 32-bit result truncated"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sequence_round_trips_match_reference() {
        for count in [0usize, 1, 15, 16, 17, 255, 256, 257, 10_000] {
            let mut rng = Rng::new(count as u64 + 5);
            let lists: Vec<Vec<u32>> = vec![
                (0..count as u32).collect(),
                (0..count).map(|_| rng.below(1000) as u32).collect(),
                // Two interleaved runs (the second baseline).
                (0..count as u32)
                    .map(|i| if i % 2 == 0 { i } else { 1_000_000 + i })
                    .collect(),
                (0..count).map(|_| rng.below(1 << 30) as u32).collect(),
                (0..count)
                    .map(|i| {
                        if i % 3 == 0 {
                            u32::MAX
                        } else {
                            i as u32 * 70_001
                        }
                    })
                    .collect(),
            ];
            // Jumps beyond the ±2^30 a delta can hold: lossy, so compared with the reference
            // decoder only.
            let lossy: Vec<u32> = (0..count).map(|_| rng.next() as u32).collect();
            for (exact, indices) in lists.into_iter().map(|l| (true, l)).chain([(false, lossy)]) {
                let encoded = encode_sequence(&indices);
                for stride in [2usize, 4] {
                    let compressed = Compressed {
                        data: &encoded,
                        count,
                        byte_stride: stride,
                        mode: Mode::Indices,
                        filter: Filter::None,
                    };
                    let ours = decode(&compressed, LIMIT).unwrap();
                    let reference = reference_indices(Mode::Indices, &encoded, count, stride);
                    assert_eq!(Some(&ours), reference.as_ref());
                    if exact {
                        assert_eq!(ours, index_bytes(&indices, stride));
                    }
                }
            }
        }
    }

    #[test]
    fn version_zero_index_headers_decode() {
        // 0xd0 is meshoptimizer's version-0 sequence header: the same format.
        let indices: Vec<u32> = (0..100).map(|i| i * 3 % 17).collect();
        let mut encoded = encode_sequence(&indices);
        encoded[0] = 0xd0;
        let compressed = Compressed {
            data: &encoded,
            count: indices.len(),
            byte_stride: 4,
            mode: Mode::Indices,
            filter: Filter::None,
        };
        assert_eq!(decode(&compressed, LIMIT), Ok(index_bytes(&indices, 4)));
    }

    // -----------------------------------------------------------------------------------------
    // Filters

    type RefFilter = unsafe extern "C" fn(*mut c_void, usize, usize);

    fn reference_filter(f: RefFilter, data: &[u8], stride: usize) -> Vec<u8> {
        let mut out = data.to_vec();
        unsafe { f(out.as_mut_ptr().cast(), data.len() / stride, stride) };
        out
    }

    fn ours_filter(filter: Filter, data: &[u8], stride: usize) -> Vec<u8> {
        let mut out = data.to_vec();
        apply_filter(filter, stride, &mut out);
        out
    }

    /// Largest difference between corresponding components, and how many differ.
    fn component_diff(a: &[u8], b: &[u8], width: usize, signed: bool) -> (i64, usize) {
        let value = |c: &[u8]| -> i64 {
            match (width, signed) {
                (1, true) => i64::from(c[0] as i8),
                (1, false) => i64::from(c[0]),
                (_, true) => i64::from(i16::from_le_bytes([c[0], c[1]])),
                (_, false) => i64::from(u16::from_le_bytes([c[0], c[1]])),
            }
        };
        let mut max = 0;
        let mut differing = 0;
        for (x, y) in a.chunks_exact(width).zip(b.chunks_exact(width)) {
            let d = (value(x) - value(y)).abs();
            max = max.max(d);
            differing += usize::from(d != 0);
        }
        (max, differing)
    }

    /// Unit vectors: random, axes, diagonals, and near the octahedron's folds.
    fn unit_vectors(count: usize, seed: u64) -> Vec<f32> {
        let mut rng = Rng::new(seed);
        let mut out = Vec::with_capacity(count * 4);
        let special: [[f32; 3]; 8] = [
            [1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.577, 0.577, -0.577],
            [-0.707, 0.707, 0.0],
            [0.6, -0.8, 1e-6],
            [0.0, 1e-7, -1.0],
        ];
        for i in 0..count {
            let v = if i < special.len() {
                special[i]
            } else {
                [rng.signed(), rng.signed(), rng.signed()]
            };
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-12);
            out.extend_from_slice(&[v[0] / len, v[1] / len, v[2] / len, rng.signed()]);
        }
        out
    }

    fn encode_filtered(
        encoder: unsafe extern "C" fn(*mut c_void, usize, usize, i32, *const f32),
        input: &[f32],
        stride: usize,
        bits: i32,
    ) -> Vec<u8> {
        let count = input.len() / 4;
        let mut out = vec![0u8; count * stride];
        unsafe { encoder(out.as_mut_ptr().cast(), count, stride, bits, input.as_ptr()) };
        out
    }

    #[test]
    fn octahedral_filter_matches_reference() {
        let input = unit_vectors(5000, 1);
        // 16-bit: bit for bit.
        for bits in 2..=16 {
            let encoded = encode_filtered(ffi::meshopt_encodeFilterOct, &input, 8, bits);
            let reference = reference_filter(ffi::meshopt_decodeFilterOct, &encoded, 8);
            assert!(
                ours_filter(Filter::Octahedral, &encoded, 8) == reference,
                "16-bit, K={bits}"
            );
        }
        // 8-bit: the SSE reference scales by rsqrtps, an approximation; within one unit.
        let (mut differing, mut total) = (0, 0);
        for bits in 2..=8 {
            let encoded = encode_filtered(ffi::meshopt_encodeFilterOct, &input, 4, bits);
            let reference = reference_filter(ffi::meshopt_decodeFilterOct, &encoded, 4);
            let ours = ours_filter(Filter::Octahedral, &encoded, 4);
            let (max, n) = component_diff(&ours, &reference, 1, true);
            assert!(max <= 1, "8-bit, K={bits}: off by {max}");
            for ((a, b), e) in ours
                .chunks_exact(4)
                .zip(reference.chunks_exact(4))
                .zip(encoded.chunks_exact(4))
            {
                assert_eq!(a[3], b[3], "w passes through");
                // Where we differ, ours is the nearer to the exact (f64) value.
                let [x, y, one] = [0, 1, 2].map(|i| f64::from(e[i] as i8));
                let z = one - x.abs() - y.abs();
                let t = z.min(0.0);
                let (x, y) = (
                    x + if x >= 0.0 { t } else { -t },
                    y + if y >= 0.0 { t } else { -t },
                );
                let len = (x * x + y * y + z * z).sqrt();
                for (i, exact) in [x, y, z].into_iter().enumerate() {
                    let exact = exact * 127.0 / len;
                    let (ours, theirs) = (f64::from(a[i] as i8), f64::from(b[i] as i8));
                    assert!(
                        (ours - exact).abs() <= (theirs - exact).abs() + 1e-3,
                        "{e:?}"
                    );
                }
            }
            differing += n;
            total += ours.len();
        }
        eprintln!("8-bit octahedral: {differing} of {total} components differ by 1 from SSE");
        assert!(differing * 100 < total, "{differing} of {total} differ");
    }

    #[test]
    fn quaternion_filter_matches_reference() {
        let mut rng = Rng::new(2);
        let mut input = Vec::new();
        for _ in 0..5000 {
            let q = [rng.signed(), rng.signed(), rng.signed(), rng.signed()];
            let len = q.iter().map(|c| c * c).sum::<f32>().sqrt().max(1e-12);
            input.extend(q.map(|c| c / len));
        }
        input.extend_from_slice(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.5, 0.5, 0.5, 0.5]);
        for bits in 4..=16 {
            let encoded = encode_filtered(ffi::meshopt_encodeFilterQuat, &input, 8, bits);
            let reference = reference_filter(ffi::meshopt_decodeFilterQuat, &encoded, 8);
            assert!(
                ours_filter(Filter::Quaternion, &encoded, 8) == reference,
                "K={bits}"
            );
        }
    }

    #[test]
    fn exponential_filter_matches_reference() {
        let mut rng = Rng::new(3);
        let mut input = Vec::new();
        for i in 0..4096 {
            let magnitude = 2f32.powi(rng.below(60) as i32 - 30);
            input.push(match i % 16 {
                0 => 0.0,
                1 => -0.0,
                2 => f32::MIN_POSITIVE,
                3 => 1e30,
                _ => rng.signed() * magnitude,
            });
        }
        for stride in [4usize, 8, 12, 16] {
            for bits in [1, 8, 15, 23, 24] {
                for mode in 0..4 {
                    let count = input.len() * 4 / stride;
                    let mut encoded = vec![0u8; count * stride];
                    unsafe {
                        ffi::meshopt_encodeFilterExp(
                            encoded.as_mut_ptr().cast(),
                            count,
                            stride,
                            bits,
                            input.as_ptr(),
                            mode,
                        )
                    };
                    let reference =
                        reference_filter(ffi::meshopt_decodeFilterExp, &encoded, stride);
                    assert!(
                        ours_filter(Filter::Exponential, &encoded, stride) == reference,
                        "stride {stride} K={bits} mode {mode}"
                    );
                }
            }
        }
    }

    #[test]
    fn color_filter_matches_reference() {
        let mut rng = Rng::new(4);
        let mut input: Vec<f32> = (0..4 * 5000).map(|_| rng.unit()).collect();
        input.extend_from_slice(&[0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.5, 0.25]);
        for bits in 2..=16 {
            let encoded = encode_filtered(ffi::meshopt_encodeFilterColor, &input, 8, bits);
            let reference = reference_filter(ffi::meshopt_decodeFilterColor, &encoded, 8);
            assert!(
                ours_filter(Filter::Color, &encoded, 8) == reference,
                "16-bit, K={bits}"
            );
        }
        // 8-bit: the SSE reference scales by rcpps, an approximation; within one unit.
        let (mut differing, mut total) = (0, 0);
        for bits in 2..=8 {
            let encoded = encode_filtered(ffi::meshopt_encodeFilterColor, &input, 4, bits);
            let reference = reference_filter(ffi::meshopt_decodeFilterColor, &encoded, 4);
            let ours = ours_filter(Filter::Color, &encoded, 4);
            let (max, n) = component_diff(&ours, &reference, 1, false);
            assert!(max <= 1, "8-bit, K={bits}: off by {max}");
            for ((a, b), e) in ours
                .chunks_exact(4)
                .zip(reference.chunks_exact(4))
                .zip(encoded.chunks_exact(4))
            {
                // Where we differ, ours is the nearer to the exact (f64) value.
                let (luma, co, cg) = (
                    f64::from(e[0]),
                    f64::from(e[1] as i8),
                    f64::from(e[2] as i8),
                );
                let scale = f64::from(
                    e[3] | e[3] >> 1
                        | e[3] >> 2
                        | e[3] >> 3
                        | e[3] >> 4
                        | e[3] >> 5
                        | e[3] >> 6
                        | e[3] >> 7,
                );
                let alpha = f64::from(((e[3] << 1) & scale as u8) | (e[3] & 1));
                let rgba = [luma + co - cg, luma + cg, luma - co - cg, alpha];
                for (i, exact) in rgba.into_iter().enumerate() {
                    let exact = exact * 255.0 / scale;
                    let (ours, theirs) = (f64::from(a[i]), f64::from(b[i]));
                    assert!(
                        (ours - exact).abs() <= (theirs - exact).abs() + 1e-3,
                        "{e:?}"
                    );
                }
            }
            differing += n;
            total += ours.len();
        }
        eprintln!("8-bit color: {differing} of {total} components differ by 1 from SSE");
        assert!(differing * 100 < total, "{differing} of {total} differ");
    }

    #[test]
    fn filters_match_reference_on_arbitrary_bytes() {
        // Where the SSE reference is exact, we equal it on any input, valid or not.
        let data = Rng::new(5).bytes(8 * 20_000);
        let cases: [(Filter, RefFilter, usize); 5] = [
            (Filter::Octahedral, ffi::meshopt_decodeFilterOct, 8),
            (Filter::Quaternion, ffi::meshopt_decodeFilterQuat, 8),
            (Filter::Exponential, ffi::meshopt_decodeFilterExp, 4),
            (Filter::Exponential, ffi::meshopt_decodeFilterExp, 8),
            (Filter::Color, ffi::meshopt_decodeFilterColor, 8),
        ];
        for (filter, reference, stride) in cases {
            let expected = reference_filter(reference, &data, stride);
            assert!(
                ours_filter(filter, &data, stride) == expected,
                "{filter} stride {stride}"
            );
        }
    }

    #[test]
    fn exponential_edge_words_match_reference() {
        // Exponents -128 (a -inf factor: NaN or infinities) and 127, zero and extreme mantissas.
        let words: [u32; 10] = [
            0x8000_0000,
            0x8000_0001,
            0x80ff_ffff,
            0x7f00_0000,
            0x7f7f_ffff,
            0x7f80_0000,
            0x0000_0000,
            0x0080_0000,
            0x8180_0000,
            0x9c00_0001,
        ];
        let data: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let expected = reference_filter(ffi::meshopt_decodeFilterExp, &data, 4);
        assert_eq!(ours_filter(Filter::Exponential, &data, 4), expected);
        assert_eq!(&expected[..4], &0xffc0_0000u32.to_le_bytes());
    }

    #[test]
    fn filtered_streams_decode_like_reference() {
        // The whole path: filter-encode, vertex-encode, then `decode` against meshoptimizer's
        // vertex decoder followed by its filter.
        let vectors = unit_vectors(3000, 6);
        let cases: [(Filter, RefFilter, usize, Vec<u8>); 3] = [
            (
                Filter::Octahedral,
                ffi::meshopt_decodeFilterOct,
                8,
                encode_filtered(ffi::meshopt_encodeFilterOct, &vectors, 8, 12),
            ),
            (
                Filter::Quaternion,
                ffi::meshopt_decodeFilterQuat,
                8,
                encode_filtered(ffi::meshopt_encodeFilterQuat, &vectors, 8, 12),
            ),
            (
                Filter::Color,
                ffi::meshopt_decodeFilterColor,
                8,
                encode_filtered(
                    ffi::meshopt_encodeFilterColor,
                    &vectors.iter().map(|v| v.abs()).collect::<Vec<_>>(),
                    8,
                    10,
                ),
            ),
        ];
        for (filter, reference, stride, filtered) in cases {
            let count = filtered.len() / stride;
            for version in [0, 1] {
                let encoded = encode_vertices(&filtered, stride, 2, version);
                let ours = decode(&attributes(&encoded, count, stride, filter), LIMIT).unwrap();
                let unpacked = reference_vertices(&encoded, count, stride).unwrap();
                assert!(
                    ours == reference_filter(reference, &unpacked, stride),
                    "{filter} v{version}"
                );
            }
        }
    }

    // -----------------------------------------------------------------------------------------
    // Validation and errors

    #[test]
    fn names_parse_and_errors_read() {
        for mode in [Mode::Attributes, Mode::Triangles, Mode::Indices] {
            assert_eq!(Mode::from_name(mode.name()), Ok(mode));
        }
        for filter in [
            Filter::None,
            Filter::Octahedral,
            Filter::Quaternion,
            Filter::Exponential,
            Filter::Color,
        ] {
            assert_eq!(Filter::from_name(filter.name()), Ok(filter));
        }
        let e = Mode::from_name("attributes").unwrap_err();
        assert_eq!(
            e.to_string(),
            "EXT_meshopt_compression: unknown mode \"attributes\" (expected ATTRIBUTES, \
             TRIANGLES or INDICES)"
        );
        let long = "X".repeat(10_000);
        assert!(Filter::from_name(&long).unwrap_err().to_string().len() < 200);
    }

    fn error(
        data: &[u8],
        count: usize,
        byte_stride: usize,
        mode: Mode,
        filter: Filter,
    ) -> MeshoptError {
        decode(
            &Compressed {
                data,
                count,
                byte_stride,
                mode,
                filter,
            },
            LIMIT,
        )
        .unwrap_err()
    }

    #[test]
    fn layout_rules_are_enforced() {
        use MeshoptError::*;
        let d = [0u8; 64];
        for stride in [0usize, 2, 6, 260, 1024] {
            assert!(matches!(
                error(&d, 1, stride, Mode::Attributes, Filter::None),
                InvalidStride { .. }
            ));
        }
        for stride in [0usize, 1, 3, 8] {
            assert!(matches!(
                error(&d, 3, stride, Mode::Triangles, Filter::None),
                InvalidStride { .. }
            ));
            assert!(matches!(
                error(&d, 3, stride, Mode::Indices, Filter::None),
                InvalidStride { .. }
            ));
        }
        assert_eq!(
            error(&d, 4, 2, Mode::Triangles, Filter::None),
            TriangleCount { count: 4 }
        );
        assert!(matches!(
            error(&d, 3, 4, Mode::Triangles, Filter::Exponential),
            FilterOnIndices { .. }
        ));
        for (filter, stride) in [
            (Filter::Octahedral, 12),
            (Filter::Octahedral, 16),
            (Filter::Quaternion, 4),
            (Filter::Color, 12),
        ] {
            assert!(matches!(
                error(&d, 1, stride, Mode::Attributes, filter),
                FilterStride { .. }
            ));
        }
        let e = error(&d, 1, 16, Mode::Attributes, Filter::Quaternion);
        assert_eq!(
            e.to_string(),
            "EXT_meshopt_compression: filter QUATERNION needs byteStride 8, not 16"
        );
    }

    #[test]
    fn oversized_outputs_are_refused_before_allocating() {
        use MeshoptError::*;
        let d = [0xa0u8; 64];
        // Overflowing and merely huge claims: allocating would abort the test.
        for (count, stride) in [(usize::MAX, 4usize), (usize::MAX / 2, 256), (1 << 40, 16)] {
            let c = attributes(&d, count, stride, Filter::None);
            assert!(matches!(
                decode(&c, usize::MAX),
                Err(OutputTooLarge { .. }) | Err(InputTooShort { .. })
            ));
            assert!(matches!(decode(&c, LIMIT), Err(OutputTooLarge { .. })));
        }
        let e = decode(&attributes(&d, 1000, 16, Filter::None), 15_999).unwrap_err();
        assert_eq!(
            e,
            OutputTooLarge {
                count: 1000,
                byte_stride: 16,
                limit: 15_999
            }
        );
        assert!(decode(&attributes(&[], 1000, 16, Filter::None), 16_000).is_err());

        // Within the limit but more than 49 bytes of version 0 can encode (1 + 4 header bytes
        // per 256 elements per byte position + 32; 257 elements take 1 + 16 + 4 + 32): refused
        // before decoding.
        let mut v0 = vec![0u8; 1 + 4 * 4 + 32];
        v0[0] = 0xa0;
        assert!(decode(&attributes(&v0, 256, 4, Filter::None), LIMIT).is_ok());
        assert!(matches!(
            decode(&attributes(&v0, 257, 4, Filter::None), LIMIT),
            Err(InputTooShort { needed: 53, .. })
        ));
        // Version 1: 1 control byte per 256 elements of 4 bytes; 10 bytes claim 1 KiB at most.
        let mut v1 = vec![0u8; 1 + 1 + 24];
        v1[0] = 0xa1;
        v1[1] = 0xaa; // every byte position: all deltas zero
        assert_eq!(
            decode(&attributes(&v1, 256, 4, Filter::None), LIMIT),
            Ok(vec![0; 1024])
        );
        assert!(matches!(
            decode(&attributes(&v1, 257, 4, Filter::None), LIMIT),
            Err(InputTooShort { .. })
        ));
        // Index modes: one code byte per triangle, one byte per index.
        let tri = [0xe1u8; 1 + 16];
        assert!(matches!(
            error(&tri, 3, 4, Mode::Triangles, Filter::None),
            InputTooShort { needed: 18, .. }
        ));
        let seq = [0xd1u8; 1 + 4];
        assert!(matches!(
            error(&seq, 1, 4, Mode::Indices, Filter::None),
            InputTooShort { needed: 6, .. }
        ));
    }

    #[test]
    fn malformed_streams_are_reported() {
        use MeshoptError::*;
        let original = vertex_data(1, 100, 16, 9);
        let encoded = encode_vertices(&original, 16, 3, 1);

        let mut wrong = encoded.clone();
        wrong[0] = 0xe1;
        let e = error(&wrong, 100, 16, Mode::Attributes, Filter::None);
        assert_eq!(
            e,
            BadHeader {
                mode: Mode::Attributes,
                byte: 0xe1
            }
        );
        assert!(
            e.to_string().ends_with("; it looks like TRIANGLES data"),
            "{e}"
        );

        wrong[0] = 0xa2;
        let e = error(&wrong, 100, 16, Mode::Attributes, Filter::None);
        assert_eq!(
            e,
            UnsupportedVersion {
                mode: Mode::Attributes,
                byte: 0xa2
            }
        );
        assert!(e.to_string().contains("version 2 (header 0xa2)"), "{e}");

        // Wrong count: too few elements leaves data unread, too many runs out.
        assert!(matches!(
            error(&encoded, 60, 16, Mode::Attributes, Filter::None),
            TrailingData { .. }
        ));
        assert!(matches!(
            error(&encoded, 101, 16, Mode::Attributes, Filter::None),
            Truncated { .. }
        ));

        // A channel byte with mode 3.
        let mut bad_channel = encoded.clone();
        let last = bad_channel.len() - 1;
        bad_channel[last] = 0x03;
        assert_eq!(
            error(&bad_channel, 100, 16, Mode::Attributes, Filter::None),
            InvalidChannel {
                channel: 3,
                byte: 0x03
            }
        );

        let indices = grid(10, 10);
        let mut tri = encode_triangles(&indices, 1);
        let n = tri.len();
        tri[n - 3] = 0x1f;
        assert_eq!(
            error(&tri, indices.len(), 4, Mode::Triangles, Filter::None),
            InvalidCodeTable
        );
    }

    // -----------------------------------------------------------------------------------------
    // Hostile input

    /// A valid stream of `mode` for `count` elements, from `seed`.
    fn valid_stream(mode: Mode, count: usize, stride: usize, seed: u64) -> (Vec<u8>, Vec<u8>) {
        match mode {
            Mode::Attributes => {
                let original = vertex_data((seed % 3) as usize, count, stride, seed);
                let version = (seed / 3 % 2) as i32;
                let level = (seed / 6 % 4) as i32;
                (encode_vertices(&original, stride, level, version), original)
            }
            Mode::Triangles => {
                let lists = triangle_lists(count / 3, seed);
                let (_, indices) = &lists[(seed as usize / 2) % lists.len()];
                let encoded = encode_triangles(indices, (seed % 2) as i32);
                // Triangles come back rotated: the reference decoder's output is the truth.
                let decoded = reference_indices(mode, &encoded, count, stride).unwrap();
                (encoded, decoded)
            }
            Mode::Indices => {
                let mut rng = Rng::new(seed);
                let indices: Vec<u32> = (0..count)
                    .map(|i| {
                        if seed % 2 == 0 {
                            rng.next() as u32
                        } else {
                            i as u32 / 2
                        }
                    })
                    .collect();
                let encoded = encode_sequence(&indices);
                // Random 32-bit jumps do not survive: the reference decoder's output is the truth.
                let decoded = reference_indices(mode, &encoded, count, stride).unwrap();
                (encoded, decoded)
            }
        }
    }

    fn any_mode() -> impl Strategy<Value = Mode> {
        prop_oneof![
            Just(Mode::Attributes),
            Just(Mode::Triangles),
            Just(Mode::Indices)
        ]
    }

    fn any_filter() -> impl Strategy<Value = Filter> {
        prop_oneof![
            Just(Filter::None),
            Just(Filter::Octahedral),
            Just(Filter::Quaternion),
            Just(Filter::Exponential),
            Just(Filter::Color),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        /// Arbitrary bytes (with a plausible header, most of the time) under arbitrary
        /// descriptions: an answer, never a panic; output exactly `count * stride`, within the
        /// limit.
        #[test]
        fn arbitrary_bytes_never_panic(
            mode in any_mode(),
            filter in any_filter(),
            stride in prop_oneof![Just(2usize), Just(4), Just(8), Just(12), Just(16), Just(64), Just(256), 0usize..300],
            count in prop_oneof![0usize..40, 0usize..3000, Just(usize::MAX), Just(usize::MAX / 3)],
            header in prop_oneof![Just(0xa0u8), Just(0xa1), Just(0xe0), Just(0xe1), Just(0xd0), Just(0xd1), any::<u8>()],
            body in prop::collection::vec(any::<u8>(), 0..4096),
            limit in prop_oneof![Just(LIMIT), 0usize..20_000],
        ) {
            let mut data = body;
            if let Some(first) = data.first_mut() {
                *first = header;
            }
            let c = Compressed { data: &data, count, byte_stride: stride, mode, filter };
            if let Ok(out) = decode(&c, limit) {
                prop_assert_eq!(Some(out.len()), count.checked_mul(stride));
                prop_assert!(out.len() <= limit);
            }
        }

        /// Valid streams, mutated: we accept only what meshoptimizer accepts, then produce the
        /// same bytes; what it accepts and we refuse is only what the specification calls
        /// invalid and it does not check.
        #[test]
        fn mutated_streams_agree_with_reference(
            mode in any_mode(),
            stride_pick in 0usize..6,
            count in prop_oneof![0usize..40, 0usize..1200],
            seed in any::<u64>(),
            flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
            cut in prop::option::weighted(0.15, any::<prop::sample::Index>()),
            append in prop_oneof![6 => Just(Vec::new()), 1 => prop::collection::vec(any::<u8>(), 1..3)],
        ) {
            let stride = match mode {
                Mode::Attributes => [4usize, 8, 12, 16, 64, 256][stride_pick],
                _ => [2usize, 4][stride_pick % 2],
            };
            let count = if mode == Mode::Triangles { count / 3 * 3 } else { count };
            let (mut data, original) = valid_stream(mode, count, stride, seed);
            let c = Compressed { data: &data, count, byte_stride: stride, mode, filter: Filter::None };
            prop_assert_eq!(decode(&c, LIMIT), Ok(original));

            for (at, value) in &flips {
                let i = at.index(data.len());
                data[i] ^= value;
            }
            if let Some(cut) = cut {
                data.truncate(cut.index(data.len() + 1));
            }
            data.extend_from_slice(&append);

            let reference = match mode {
                Mode::Attributes => reference_vertices(&data, count, stride),
                _ => reference_indices(mode, &data, count, stride),
            };
            let c = Compressed { data: &data, count, byte_stride: stride, mode, filter: Filter::None };
            match (decode(&c, LIMIT), reference) {
                (Ok(ours), Some(theirs)) => prop_assert!(ours == theirs),
                (Ok(_), None) => prop_assert!(false, "accepted a stream meshoptimizer refuses"),
                (Err(MeshoptError::InvalidChannel { .. } | MeshoptError::InvalidCodeTable), Some(_)) => {}
                (Err(e), Some(_)) => prop_assert!(false, "refused a stream meshoptimizer accepts: {}", e),
                (Err(_), None) => {}
            }
        }
    }
}
