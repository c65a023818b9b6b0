//! `EXT_meshopt_compression` output: which layout a write takes, and the encoding of one buffer
//! view with meshoptimizer's lossless codecs (the `meshopt` crate), checked by decoding it again
//! with tspace's own decoder before it is used.
//!
//! Vertex data takes the `ATTRIBUTES` codec (version 0, the only one `EXT_meshopt_compression`
//! allows), indices `TRIANGLES` (a triangle list) or `INDICES`. A filter is used only where it
//! is exact: a view copied from an input view that was stored with that filter is encoded from
//! the input's own pre-filter values, so that decoding gives back exactly the bytes the input
//! decoded to. Filters are lossy otherwise, and are not used.

use crate::scene::options::Compression;
use tspace_json::Node;
use tspace_meshopt::{Filter, Mode};

/// The extension tspace writes.
pub const EXT: &str = "EXT_meshopt_compression";
/// Its successor (draft), read and kept where the input has it.
pub const KHR: &str = "KHR_meshopt_compression";

/// The layout of a written scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// The input's own layout, as before compression was an option (no meshopt in or out).
    Keep,
    /// Everything uncompressed: the input's meshopt views written out as plain data.
    Plain,
    /// The views tspace writes compressed, and the input's compressed views kept so.
    Meshopt,
}

/// The layout `choice` gives for this input.
pub fn resolve(choice: Compression, root: &Node) -> Output {
    match (choice, uses_meshopt(root)) {
        (Compression::Meshopt, _) | (Compression::Auto, true) => Output::Meshopt,
        (Compression::None, true) => Output::Plain,
        (Compression::Auto | Compression::None, false) => Output::Keep,
    }
}

/// Whether the document declares or uses either meshopt extension.
pub fn uses_meshopt(root: &Node) -> bool {
    let listed = root
        .get("extensionsUsed")
        .and_then(Node::as_array)
        .unwrap_or(&[])
        .iter()
        .any(|e| matches!(e.as_str(), Some(EXT | KHR)));
    listed
        || root
            .get("bufferViews")
            .and_then(Node::as_array)
            .unwrap_or(&[])
            .iter()
            .any(|v| extension(v).is_some())
}

/// A view's meshopt extension object and its name.
pub fn extension(view: &Node) -> Option<(&'static str, &Node)> {
    let extensions = view.get("extensions")?;
    [EXT, KHR]
        .into_iter()
        .find_map(|name| Some((name, extensions.get(name)?)))
}

/// Where a meshopt extension's compressed bytes are: `(buffer, byteOffset, byteLength)`.
pub fn compressed_range(ext: &Node) -> Option<(usize, usize, usize)> {
    let member = |key: &str| {
        ext.get(key)
            .and_then(Node::as_u64)
            .and_then(|n| usize::try_from(n).ok())
    };
    Some((
        member("buffer")?,
        member("byteOffset").unwrap_or(0),
        member("byteLength")?,
    ))
}

/// What a new view holds, as the encoder needs to know it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// Vertex elements of `stride` bytes.
    Vertex { stride: usize },
    /// Little-endian indices of `size` (2 or 4) bytes; `triangles` when they are a triangle
    /// list and nothing else.
    Index { size: usize, triangles: bool },
    /// Anything else (images): never compressed.
    Other,
}

/// A vertex view's elements as the input stored them before its filter: decoding these with
/// `filter` gives the view's bytes.
pub struct Prefiltered {
    pub bytes: Vec<u8>,
    pub filter: Filter,
}

/// One view, encoded and checked.
pub struct Encoded {
    pub bytes: Vec<u8>,
    pub mode: Mode,
    pub filter: Filter,
    pub stride: usize,
    pub count: usize,
}

/// A buffer view's `EXT_meshopt_compression` object. Its members are in alphabetical order,
/// the order tspace's outputs have always had them in (they went through a `serde_json` map,
/// which sorts): every path that writes one serializes this struct as it stands.
#[derive(Clone, Debug, serde::Serialize)]
#[serde(rename_all = "camelCase")]
pub struct MeshoptView {
    pub buffer: usize,
    pub byte_length: usize,
    pub byte_offset: usize,
    pub byte_stride: usize,
    pub count: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub filter: Option<&'static str>,
    pub mode: &'static str,
}

/// What the output's JSON says of an encoded view, kept once its bytes are in the data buffer:
/// a scene of many small views would otherwise hold every stream twice while it is written.
#[derive(Clone, Copy, Debug)]
pub struct Encoding {
    pub mode: Mode,
    pub filter: Filter,
    pub stride: usize,
    pub count: usize,
    /// The compressed stream's length.
    pub length: usize,
}

impl Encoded {
    /// Everything but the bytes.
    pub fn encoding(&self) -> Encoding {
        Encoding {
            mode: self.mode,
            filter: self.filter,
            stride: self.stride,
            count: self.count,
            length: self.bytes.len(),
        }
    }
}

impl Encoding {
    /// The view's `EXT_meshopt_compression` object, its compressed bytes at `offset` of
    /// buffer 0.
    pub fn extension(&self, offset: usize) -> MeshoptView {
        MeshoptView {
            buffer: 0,
            byte_offset: offset,
            byte_length: self.length,
            byte_stride: self.stride,
            mode: self.mode.name(),
            filter: (self.filter != Filter::None).then(|| self.filter.name()),
            count: self.count,
        }
    }
}

/// Encodes `data` (a view of `shape`) with meshoptimizer, with `prefiltered`'s filter when that
/// decodes to exactly `data`. `None` when the view cannot be compressed (an `Other` shape, a
/// stride the codec does not take, no elements) or, which would be a bug in an encoder, does not
/// decode back to `data`: it is then written plain.
pub fn encode(data: &[u8], shape: Shape, prefiltered: Option<&Prefiltered>) -> Option<Encoded> {
    match shape {
        Shape::Vertex { stride } => {
            if data.is_empty() || stride == 0 || stride > 256 || !stride.is_multiple_of(4) {
                return None;
            }
            if !data.len().is_multiple_of(stride) {
                return None;
            }
            let count = data.len() / stride;
            if let Some(p) = prefiltered
                && p.bytes.len() == data.len()
                && let Some(bytes) = encode_vertex(&p.bytes, stride)
            {
                let encoded = Encoded {
                    bytes,
                    mode: Mode::Attributes,
                    filter: p.filter,
                    stride,
                    count,
                };
                if decodes_to(&encoded, data) {
                    return Some(encoded);
                }
            }
            let encoded = Encoded {
                bytes: encode_vertex(data, stride)?,
                mode: Mode::Attributes,
                filter: Filter::None,
                stride,
                count,
            };
            decodes_to(&encoded, data).then_some(encoded)
        }
        Shape::Index { size, triangles } => {
            let indices: Vec<u32> = match size {
                2 => data
                    .chunks_exact(2)
                    .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
                    .collect(),
                4 => data
                    .chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect(),
                _ => return None,
            };
            if indices.is_empty() || data.len() != indices.len() * size {
                return None;
            }
            let vertex_count = indices.iter().max().map_or(0, |&m| m as usize + 1);
            let (bytes, mode) = if triangles && indices.len().is_multiple_of(3) {
                let bytes = meshopt::encode_index_buffer(&indices, vertex_count).ok()?;
                (fitted(bytes), Mode::Triangles)
            } else {
                let bytes = meshopt::encode_index_sequence(&indices, vertex_count).ok()?;
                (fitted(bytes), Mode::Indices)
            };
            let encoded = Encoded {
                bytes,
                mode,
                filter: Filter::None,
                stride: size,
                count: indices.len(),
            };
            let exact = match mode {
                Mode::Triangles => decodes_to_triangles(&encoded, &indices),
                _ => decodes_to(&encoded, data),
            };
            exact.then_some(encoded)
        }
        Shape::Other => None,
    }
}

/// `bytes` without spare capacity. meshoptimizer's encoders return a vector of the worst case's
/// size, and the writer keeps every view's until the output is written: on 10,000 one-triangle
/// primitives that was 126 MB of capacity for 7 MB of streams.
fn fitted(mut bytes: Vec<u8>) -> Vec<u8> {
    bytes.shrink_to_fit();
    bytes
}

/// Whether tspace's decoder (which follows meshoptimizer's, and the WebAssembly one browsers
/// run) turns `encoded` back into exactly `expected`.
fn decodes_to(encoded: &Encoded, expected: &[u8]) -> bool {
    decode_encoded(encoded, expected.len()).is_some_and(|d| d == expected)
}

/// `encoded` decoded again by tspace's decoder, at most `max_bytes` of it.
fn decode_encoded(encoded: &Encoded, max_bytes: usize) -> Option<Vec<u8>> {
    let compressed = tspace_meshopt::Compressed {
        data: &encoded.bytes,
        count: encoded.count,
        byte_stride: encoded.stride,
        mode: encoded.mode,
        filter: encoded.filter,
    };
    tspace_meshopt::decode(&compressed, max_bytes).ok()
}

/// Whether a `TRIANGLES` stream decodes to exactly `expected`'s triangles, in order, each with
/// its winding: meshoptimizer's triangle codec may start a triangle at another of its corners
/// (it rotates them to match its edge FIFO), as every meshopt-compressed file does.
fn decodes_to_triangles(encoded: &Encoded, expected: &[u32]) -> bool {
    let Some(decoded) = decode_encoded(encoded, expected.len() * encoded.stride) else {
        return false;
    };
    let read = |c: &[u8]| match c {
        [a, b] => u32::from(u16::from_le_bytes([*a, *b])),
        [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]),
        _ => u32::MAX,
    };
    let got: Vec<u32> = decoded.chunks_exact(encoded.stride).map(read).collect();
    got.len() == expected.len()
        && got
            .chunks_exact(3)
            .zip(expected.chunks_exact(3))
            .all(|(g, e)| same_triangle(g, e))
}

/// The same corners in the same cyclic order.
pub fn same_triangle(a: &[u32], b: &[u32]) -> bool {
    matches!((a, b), ([a0, a1, a2], [b0, b1, b2])
        if (a0, a1, a2) == (b0, b1, b2)
            || (a0, a1, a2) == (b1, b2, b0)
            || (a0, a1, a2) == (b2, b0, b1))
}

/// The vertex codec, version 0 (`EXT_meshopt_compression` allows no other; meshoptimizer's
/// default is now version 1), on elements of `stride` bytes.
fn encode_vertex(data: &[u8], stride: usize) -> Option<Vec<u8>> {
    fn with<const S: usize>(data: &[u8]) -> Option<Vec<u8>> {
        let (elements, rest) = data.as_chunks::<S>();
        if !rest.is_empty() {
            return None;
        }
        meshopt::encode_vertex_buffer_level(elements, 2, Some(0))
            .ok()
            .map(fitted)
    }
    macro_rules! by_stride {
        ($($s:literal)*) => {
            match stride {
                $($s => with::<$s>(data),)*
                _ => None,
            }
        };
    }
    by_stride!(
        4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108 112
        116 120 124 128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196 200
        204 208 212 216 220 224 228 232 236 240 244 248 252 256
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_data_round_trips_in_version_0() {
        let data: Vec<u8> = (0..12 * 100).map(|i| (i * 7 % 251) as u8).collect();
        let encoded = encode(&data, Shape::Vertex { stride: 12 }, None).unwrap();
        assert_eq!(encoded.bytes[0], 0xa0);
        assert_eq!((encoded.count, encoded.filter), (100, Filter::None));
    }

    #[test]
    fn encoded_streams_keep_no_spare_room() {
        // One triangle's views, as in a scene of many small primitives: the encoders' worst
        // case is many times the stream, and every view's stream waits for the output.
        let positions: Vec<u8> = (0..36).map(|i| (i * 13 % 251) as u8).collect();
        let vertex = encode(&positions, Shape::Vertex { stride: 12 }, None).unwrap();
        let indices: Vec<u8> = [0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()).collect();
        let triangles = Shape::Index {
            size: 2,
            triangles: true,
        };
        let lines = Shape::Index {
            size: 2,
            triangles: false,
        };
        let index = encode(&indices, triangles, None).unwrap();
        let sequence = encode(&indices, lines, None).unwrap();
        for encoded in [vertex, index, sequence] {
            assert_eq!(
                encoded.bytes.capacity(),
                encoded.bytes.len(),
                "{:?}",
                encoded.mode
            );
        }
    }

    #[test]
    fn indices_take_the_triangle_or_sequence_codec() {
        let tri: Vec<u8> = [0u16, 1, 2, 2, 1, 3]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let encoded = encode(
            &tri,
            Shape::Index {
                size: 2,
                triangles: true,
            },
            None,
        )
        .unwrap();
        assert_eq!(encoded.mode, Mode::Triangles);
        // Lines are never read as triangles, even with a count that is a multiple of 3.
        let encoded = encode(
            &tri,
            Shape::Index {
                size: 2,
                triangles: false,
            },
            None,
        )
        .unwrap();
        assert_eq!(encoded.mode, Mode::Indices);
        let seq: Vec<u8> = [0u32, 1, 2, 3]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let encoded = encode(
            &seq,
            Shape::Index {
                size: 4,
                triangles: true,
            },
            None,
        )
        .unwrap();
        assert_eq!((encoded.mode, encoded.stride), (Mode::Indices, 4));
    }

    #[test]
    fn triangles_keep_their_corners_and_winding() {
        assert!(same_triangle(&[1, 2, 3], &[2, 3, 1]));
        assert!(same_triangle(&[1, 2, 3], &[3, 1, 2]));
        assert!(!same_triangle(&[1, 2, 3], &[1, 3, 2]));
    }

    #[test]
    fn strides_the_codec_cannot_take_stay_plain() {
        assert!(encode(&[0; 6], Shape::Vertex { stride: 6 }, None).is_none());
        assert!(encode(&[0; 520], Shape::Vertex { stride: 260 }, None).is_none());
        assert!(encode(&[1, 2, 3], Shape::Other, None).is_none());
    }

    #[test]
    fn a_filter_is_used_only_where_it_is_exact() {
        // Octahedral 8-bit: (x, y, one, w) stored; the filter gives the unit vector.
        let pre: Vec<u8> = [[127i8, 0, 127, 0], [0, 127, 127, 0]]
            .iter()
            .flat_map(|e| e.map(|c| c as u8))
            .collect();
        let mut decoded = pre.clone();
        let c = tspace_meshopt::Compressed {
            data: &encode_vertex(&pre, 4).unwrap(),
            count: 2,
            byte_stride: 4,
            mode: Mode::Attributes,
            filter: Filter::Octahedral,
        };
        decoded.copy_from_slice(&tspace_meshopt::decode(&c, 8).unwrap());
        let p = Prefiltered {
            bytes: pre,
            filter: Filter::Octahedral,
        };
        let exact = encode(&decoded, Shape::Vertex { stride: 4 }, Some(&p)).unwrap();
        assert_eq!(exact.filter, Filter::Octahedral);
        let mut other = decoded.clone();
        other[0] ^= 1;
        let plain = encode(&other, Shape::Vertex { stride: 4 }, Some(&p)).unwrap();
        assert_eq!(plain.filter, Filter::None);
    }
}
