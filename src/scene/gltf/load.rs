//! A glTF or GLB in memory: the JSON document and the bytes of every buffer.
//!
//! Buffers come from the GLB's BIN chunk, from `data:` URIs, or from [`Resources`] the caller
//! supplies (an upload's named parts, or on the command line the file's own folder). Nothing
//! here opens a file or a connection: a URI reaches the outside only through the caller's
//! `Resources`, and an upload's resources are the parts it carried.

use super::glb::{self, Chunk};
use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::uri::{self, LookedIn, PartSet, UriError};
use std::borrow::Cow;
use tspace_json::{Document, Node};

/// Where the bytes a relative URI names come from.
pub trait Resources<'a> {
    /// The bytes `uri` (as written in the file, not a `data:` URI) names.
    fn fetch(&self, uri: &str) -> Result<Cow<'a, [u8]>, UriError>;

    /// Whether [`Resources::fetch`] would find `uri`, for an analysis that reads no images.
    fn has(&self, uri: &str) -> bool {
        self.fetch(uri).is_ok()
    }
}

impl<'a> Resources<'a> for PartSet<'a> {
    fn fetch(&self, uri: &str) -> Result<Cow<'a, [u8]>, UriError> {
        self.get(uri).map(Cow::Borrowed)
    }
}

/// No resources at all: every URI that is not `data:` is missing.
pub struct NoResources;

impl<'a> Resources<'a> for NoResources {
    fn fetch(&self, uri: &str) -> Result<Cow<'a, [u8]>, UriError> {
        Err(UriError::MissingPart {
            uri: uri.to_owned(),
            looked_in: LookedIn::Nothing,
        })
    }
}

/// The container the scene arrived in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Container {
    Glb,
    /// A `.gltf` JSON file.
    Json,
}

/// Where one buffer's bytes came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BufferSource {
    GlbBin,
    DataUri,
    /// A relative URI, resolved through [`Resources`].
    External(String),
    /// No `uri` and not the GLB's BIN: a buffer that holds no data of its own (an
    /// `EXT_meshopt_compression` fallback buffer, filled in by decoding).
    Empty,
}

/// One buffer: its bytes (cut to its declared `byteLength`) and where they came from.
#[derive(Clone, Debug)]
pub struct Buffer<'a> {
    pub bytes: Cow<'a, [u8]>,
    pub source: BufferSource,
}

/// A parsed scene: the document, its buffers and, for a GLB, the chunks after BIN.
pub struct Loaded<'a> {
    pub container: Container,
    pub doc: Document<'a>,
    pub buffers: Vec<Buffer<'a>>,
    pub other_chunks: Vec<Chunk<'a>>,
}

impl<'a> Loaded<'a> {
    /// Every buffer's bytes, indexed like `buffers`, as the accessor reader takes them.
    pub fn buffer_slices(&self) -> Vec<&[u8]> {
        self.buffers.iter().map(|b| b.bytes.as_ref()).collect()
    }
}

/// Limits on what loading may allocate.
#[derive(Clone, Copy, Debug)]
pub struct LoadLimits {
    /// The most bytes one buffer may declare (its data must also really be there, except for a
    /// buffer that is filled by decoding).
    pub max_buffer_bytes: usize,
}

/// Parses a GLB or `.gltf` (told apart by the GLB magic) and loads its buffers.
pub fn load<'a>(
    bytes: &'a [u8],
    resources: &dyn Resources<'a>,
    limits: &LoadLimits,
) -> Result<Loaded<'a>, SceneError> {
    let (container, json, bin, other_chunks) = if glb::is_glb(bytes) {
        let parsed = glb::parse(bytes).map_err(|e| {
            SceneError::new(ProblemCode::MalformedGlb, format!("not a valid GLB: {e}"))
        })?;
        (Container::Glb, parsed.json, parsed.bin, parsed.other_chunks)
    } else {
        (Container::Json, bytes, None, Vec::new())
    };
    let doc = Document::parse(json).map_err(|e| {
        SceneError::new(ProblemCode::MalformedJson, format!("the glTF JSON is {e}"))
    })?;
    check_asset(doc.root())?;
    let mut buffers = load_buffers(doc.root(), container, bin, resources, limits)?;
    decode_meshopt(doc.root(), &mut buffers, limits)?;
    Ok(Loaded {
        container,
        doc,
        buffers,
        other_chunks,
    })
}

fn check_asset(root: &Node) -> Result<(), SceneError> {
    if root.as_object().is_none() {
        return Err(SceneError::new(
            ProblemCode::MalformedGltf,
            format!("a glTF document is a JSON object, not {}", root.kind_name()),
        ));
    }
    let version = root
        .get("asset")
        .and_then(|a| a.get("version"))
        .and_then(Node::as_str);
    match version {
        None => Err(SceneError::new(
            ProblemCode::MalformedGltf,
            "asset.version is missing: this is not a glTF 2.0 document",
        )),
        Some(v) if v == "2.0" || v.starts_with("2.") => Ok(()),
        Some(v) => Err(SceneError::new(
            ProblemCode::UnsupportedVersion,
            format!("asset.version is {v:?}; tspace reads glTF 2.x"),
        )),
    }
}

fn load_buffers<'a>(
    root: &Node,
    container: Container,
    bin: Option<&'a [u8]>,
    resources: &dyn Resources<'a>,
    limits: &LoadLimits,
) -> Result<Vec<Buffer<'a>>, SceneError> {
    let Some(list) = root.get("buffers") else {
        return Ok(Vec::new());
    };
    let list = list.as_array().ok_or_else(|| {
        SceneError::new(
            ProblemCode::MalformedGltf,
            "buffers must be an array of objects",
        )
    })?;
    let mut buffers = Vec::with_capacity(list.len());
    for (index, buffer) in list.iter().enumerate() {
        let path = format!("buffers[{index}]");
        let declared = buffer
            .get("byteLength")
            .and_then(Node::as_u64)
            .and_then(|n| usize::try_from(n).ok())
            .filter(|&n| n >= 1)
            .ok_or_else(|| {
                SceneError::new(
                    ProblemCode::MalformedGltf,
                    format!("{path}.byteLength must be an integer of at least 1"),
                )
            })?;
        if declared > limits.max_buffer_bytes {
            return Err(SceneError::new(
                ProblemCode::BufferTooLarge,
                format!(
                    "{path} declares {declared} bytes; the limit is {}",
                    limits.max_buffer_bytes
                ),
            ));
        }
        let uri = match buffer.get("uri") {
            None => None,
            Some(u) => Some(u.as_str().ok_or_else(|| {
                SceneError::new(
                    ProblemCode::MalformedGltf,
                    format!("{path}.uri must be a string"),
                )
            })?),
        };
        let (bytes, source): (Cow<'a, [u8]>, BufferSource) = match uri {
            None if index == 0 && container == Container::Glb => {
                let bin = bin.ok_or_else(|| {
                    SceneError::new(
                        ProblemCode::MalformedGlb,
                        "buffers[0] has no uri, so it is the GLB's BIN chunk, but the file has none",
                    )
                })?;
                (Cow::Borrowed(bin), BufferSource::GlbBin)
            }
            None => (Cow::Borrowed(&[][..]), BufferSource::Empty),
            Some(text) => match uri::decode_data_uri(text) {
                Some(data) => {
                    let data = data.map_err(|e| {
                        SceneError::new(ProblemCode::MalformedUri, format!("{path}.uri: {e}"))
                    })?;
                    (Cow::Owned(data.bytes), BufferSource::DataUri)
                }
                None => {
                    let bytes = resources
                        .fetch(text)
                        .map_err(|e| resource_error(&path, e))?;
                    (bytes, BufferSource::External(text.to_owned()))
                }
            },
        };
        let bytes = match source {
            BufferSource::Empty => bytes,
            _ if bytes.len() < declared => {
                return Err(SceneError::new(
                    ProblemCode::BufferTooShort,
                    format!(
                        "{path} declares {declared} bytes but its data has only {}",
                        bytes.len()
                    ),
                ));
            }
            // Padding (a BIN chunk's) or trailing bytes are not part of the buffer.
            _ => match bytes {
                Cow::Borrowed(b) => Cow::Borrowed(&b[..declared]),
                Cow::Owned(mut v) => {
                    v.truncate(declared);
                    Cow::Owned(v)
                }
            },
        };
        buffers.push(Buffer { bytes, source });
    }
    Ok(buffers)
}

fn usize_member(node: &Node, key: &str, path: &str) -> Result<Option<usize>, SceneError> {
    match node.get(key) {
        None => Ok(None),
        Some(value) => value
            .as_u64()
            .and_then(|n| usize::try_from(n).ok())
            .map(Some)
            .ok_or_else(|| {
                SceneError::new(
                    ProblemCode::MalformedGltf,
                    format!("{path}.{key} must be a non-negative integer"),
                )
            }),
    }
}

/// Decodes every `EXT_meshopt_compression` buffer view whose own buffer holds no data (the
/// fallback buffer of a file that requires the extension) into that buffer, so that accessors
/// read it like any other. Views whose fallback has real data are read as they are.
///
/// A fallback buffer is allocated only as far as its decoded views reach, and at most
/// `max_buffer_bytes`; each view's decoded size is bounded by the decoder against its
/// compressed size, so the allocation follows from bytes actually present.
fn decode_meshopt(
    root: &Node,
    buffers: &mut [Buffer<'_>],
    limits: &LoadLimits,
) -> Result<(), SceneError> {
    let views = root
        .get("bufferViews")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    let mut decoded: Vec<(usize, usize, Vec<u8>)> = Vec::new();
    for (v, view) in views.iter().enumerate() {
        let Some(ext) = view
            .get("extensions")
            .and_then(|e| e.get("EXT_meshopt_compression"))
        else {
            continue;
        };
        let path = format!("bufferViews[{v}]");
        let ext_path = format!("{path}.extensions.EXT_meshopt_compression");
        let target = usize_member(view, "buffer", &path)?.unwrap_or(usize::MAX);
        if buffers
            .get(target)
            .is_none_or(|b| b.source != BufferSource::Empty)
        {
            continue;
        }
        let required = |key: &str| -> Result<usize, SceneError> {
            usize_member(ext, key, &ext_path)?.ok_or_else(|| {
                SceneError::new(
                    ProblemCode::MalformedGltf,
                    format!("{ext_path}.{key} is missing"),
                )
            })
        };
        let source = required("buffer")?;
        let offset = usize_member(ext, "byteOffset", &ext_path)?.unwrap_or(0);
        let length = required("byteLength")?;
        let stride = required("byteStride")?;
        let count = required("count")?;
        let name = |key: &str| ext.get(key).and_then(Node::as_str);
        let mode = tspace_meshopt::Mode::from_name(name("mode").unwrap_or("")).map_err(|e| {
            SceneError::new(ProblemCode::MalformedMeshopt, format!("{ext_path}: {e}"))
        })?;
        let filter = match name("filter") {
            None => tspace_meshopt::Filter::None,
            Some(f) => tspace_meshopt::Filter::from_name(f).map_err(|e| {
                SceneError::new(ProblemCode::MalformedMeshopt, format!("{ext_path}: {e}"))
            })?,
        };
        let data = buffers
            .get(source)
            .filter(|b| b.source != BufferSource::Empty)
            .and_then(|b| b.bytes.get(offset..offset.checked_add(length)?))
            .ok_or_else(|| {
                SceneError::new(
                    ProblemCode::MalformedMeshopt,
                    format!("{ext_path}: the compressed bytes lie outside buffers[{source}]"),
                )
            })?;
        let bytes = tspace_meshopt::decode(
            &tspace_meshopt::Compressed {
                data,
                count,
                byte_stride: stride,
                mode,
                filter,
            },
            limits.max_buffer_bytes,
        )
        .map_err(|e| SceneError::new(ProblemCode::MalformedMeshopt, format!("{ext_path}: {e}")))?;
        let at = usize_member(view, "byteOffset", &path)?.unwrap_or(0);
        decoded.push((target, at, bytes));
    }
    // Exporters pack a fallback buffer's views end to end; a gap far larger than the data would
    // be an allocation the file's bytes do not justify.
    let total: usize = decoded.iter().map(|(_, _, b)| b.len()).sum();
    let reach = total.saturating_mul(2).saturating_add(1 << 16);
    for (target, at, bytes) in decoded {
        let end = at
            .checked_add(bytes.len())
            .filter(|&end| end <= limits.max_buffer_bytes && end <= reach)
            .ok_or_else(|| {
                SceneError::new(
                    ProblemCode::BufferTooLarge,
                    format!("a decoded EXT_meshopt_compression view of buffers[{target}] ends past the limit"),
                )
            })?;
        let Some(buffer) = buffers.get_mut(target) else {
            continue;
        };
        let data = buffer.bytes.to_mut();
        if data.len() < end {
            data.resize(end, 0);
        }
        data[at..end].copy_from_slice(&bytes);
    }
    Ok(())
}

/// The error for a URI that could not be resolved: missing or refused is the caller's omission
/// (422), a malformed URI is a malformed file (400).
pub fn resource_error(path: &str, error: UriError) -> SceneError {
    match error {
        UriError::MissingPart { .. } => {
            SceneError::new(ProblemCode::MissingResource, format!("{path}.uri: {error}"))
        }
        UriError::Refused { .. } => {
            SceneError::new(ProblemCode::RefusedUri, format!("{path}.uri: {error}"))
        }
        UriError::FileTooLarge { .. } => {
            SceneError::new(ProblemCode::BufferTooLarge, format!("{path}.uri: {error}"))
        }
        _ => SceneError::new(ProblemCode::MalformedUri, format!("{path}.uri: {error}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: LoadLimits = LoadLimits {
        max_buffer_bytes: 1 << 20,
    };

    fn fixture(path: &str) -> Vec<u8> {
        let full = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/");
        std::fs::read(format!("{full}{path}")).expect("fixture")
    }

    #[test]
    fn glb_buffer_is_the_bin_chunk_cut_to_its_length() {
        let bytes = fixture("Box/Box.glb");
        let loaded = load(&bytes, &NoResources, &LIMITS).unwrap();
        assert_eq!(loaded.container, Container::Glb);
        assert_eq!(loaded.buffers.len(), 1);
        assert_eq!(loaded.buffers[0].source, BufferSource::GlbBin);
        assert_eq!(loaded.buffers[0].bytes.len(), 648);
    }

    #[test]
    fn external_buffers_come_from_parts_and_missing_ones_are_named() {
        let gltf = fixture("Avocado/Avocado.gltf");
        let bin = fixture("Avocado/Avocado.bin");
        let error = load(&gltf, &NoResources, &LIMITS).err().unwrap();
        assert_eq!(error.code, "missing-resource");
        assert!(error.message.contains("Avocado.bin"), "{}", error.message);

        let mut parts = PartSet::new();
        parts.insert("Avocado.bin", &bin).unwrap();
        let loaded = load(&gltf, &parts, &LIMITS).unwrap();
        assert_eq!(
            loaded.buffers[0].source,
            BufferSource::External("Avocado.bin".into())
        );
        assert_eq!(loaded.buffers[0].bytes.len(), bin.len());
    }

    #[test]
    fn data_uri_buffers_decode_and_short_data_is_refused() {
        let gltf = fixture("BoxTextured_embedded/BoxTextured.gltf");
        let loaded = load(&gltf, &NoResources, &LIMITS).unwrap();
        assert_eq!(loaded.buffers[0].source, BufferSource::DataUri);

        let short = br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":8,"uri":"data:application/octet-stream;base64,AAAA"}]}"#;
        let error = load(short, &NoResources, &LIMITS).err().unwrap();
        assert_eq!(error.code, "buffer-too-short");
    }

    #[test]
    fn bad_documents_are_refused_with_reasons() {
        let cases: [(&[u8], &str); 5] = [
            (b"{", "malformed-json"),
            (b"[]", "malformed-gltf"),
            (br#"{"asset":{}}"#, "malformed-gltf"),
            (br#"{"asset":{"version":"1.0"}}"#, "unsupported-version"),
            (
                br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":1e30}]}"#,
                "malformed-gltf",
            ),
        ];
        for (bytes, code) in cases {
            let error = load(bytes, &NoResources, &LIMITS).err().unwrap();
            assert_eq!(error.code, code, "{}", String::from_utf8_lossy(bytes));
        }
        let huge = br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":2000000}]}"#;
        let error = load(huge, &NoResources, &LIMITS).err().unwrap();
        assert_eq!(error.code, "buffer-too-large");
    }
}
