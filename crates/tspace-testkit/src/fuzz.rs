//! The bodies of the fuzz targets (`fuzz/fuzz_targets/*.rs` are two-line wrappers around these),
//! kept in the library so that `tests/fuzz_replay.rs` replays the saved corpus through exactly the
//! code the fuzzers ran, on stable and in the normal test suite.
//!
//! Every function takes arbitrary bytes and returns nothing: errors are the expected outcome for
//! most inputs and are simply dropped. A panic (an `assert!` included) is the bug signal.
//!
//! - [`glb()`]: the GLB container (split, rewritten byte for byte), then the whole scene path.
//! - [`gltf()`]: the JSON parser, the storage report's reading of a text without a tree against
//!   the tree's, every accessor decoded, then the whole scene path, for GLB and `.gltf` input
//!   alike, with no external resources.
//! - [`obj()`]: OBJ text and an MTL (`a.mtl`), split at the first `0xFF` byte; the parallel
//!   reader is checked against the sequential one on the text cut into a few chunks.
//! - [`parts`]: a multipart upload, as length-prefixed records (see [`parts`]).
//! - [`draco()`]: a Draco stream under a declared layout, decoded on its own and then through
//!   the whole scene path.
//! - [`core()`]: arbitrary geometry straight into [`tspace_tangent::generate`], with the core's
//!   invariants checked on every successful result.
//!
//! The scene options (method, overwrite, all, output format, normal mode, write) of [`glb`],
//! [`gltf()`] and [`parts`] come from a cheap hash of the input, so that every mutation may also
//! change them and the replay stays deterministic.

use crate::invariants;
use tspace::scene::gltf::accessor::{self, ElementType};
use tspace::scene::gltf::draco;
use tspace::scene::gltf::glb as glb_container;
use tspace::scene::gltf::load::{self, LoadLimits, NoResources};
use tspace::scene::gltf::sizes;
use tspace::scene::input::{self, InputKind};
use tspace::scene::obj;
use tspace::scene::uri::PartSet;
use tspace::scene::{Normals, OutputFormat, SceneLimits, SceneOptions, TangentType};
use tspace_tangent::{
    self as tangent, CoreError, MeshInput, Method, NormalMode, Options, UvOrigin, Weighting,
};

/// Small enough that one input stays fast, large enough for every fixture-sized seed.
const LIMITS: SceneLimits = SceneLimits {
    max_triangles: 1 << 16,
    max_vertices: 1 << 16,
    max_buffer_bytes: 1 << 20,
};

/// Elements decoded per accessor by [`gltf`].
const MAX_ELEMENTS: usize = 1 << 16;

fn hash(data: &[u8]) -> u32 {
    // FNV-1a: any single-byte change moves it.
    data.iter().fold(0x811C_9DC5u32, |h, &b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}

/// Scene options chosen by the input's hash.
fn scene_options(data: &[u8]) -> SceneOptions {
    let h = hash(data);
    SceneOptions {
        method: match h % 3 {
            0 => Method::MikkTSpace,
            1 => Method::Fast,
            _ => Method::Axis,
        },
        overwrite: h & 0x10 != 0,
        all: h & 0x20 != 0,
        format: if h & 0x40 != 0 {
            OutputFormat::GltfEmbedded
        } else {
            OutputFormat::Glb
        },
        normal_mode: if h & 0x80 != 0 {
            NormalMode::SmoothByAngle {
                crease_degrees: 60.0,
            }
        } else {
            NormalMode::Flat
        },
        // Mostly written, sometimes only analysed.
        write: h & 0x300 != 0x300,
        tangents: if h & 0x400 != 0 {
            TangentType::Float
        } else {
            TangentType::Auto
        },
        compress: Default::default(),
        // Sometimes painted by finding (the debug scene must load again too).
        debug: if h & 0x1000 != 0 {
            tspace::scene::options::Debug::Colors
        } else {
            tspace::scene::options::Debug::None
        },
        // OBJ only: the OBJ target chooses its own.
        normals: Default::default(),
        normals_angle: 60.0,
        limits: LIMITS,
        cancel: Default::default(),
        // Sometimes the UV-layout picture too (drawn in check_processed).
        layouts: h & 0x800 != 0,
        // Sometimes written in pieces (put together again in run_scene).
        in_pieces: h & 0x2000 != 0,
        // The service's hand-back of freed memory changes no output, and inputs that reach
        // its threshold (megabytes of JSON) are not what a fuzzer makes.
        release_freed_memory: None,
    }
}

/// What every successful scene run must give: a written scene that loads again.
fn check_processed(processed: &tspace::scene::Processed) {
    if let Some(bytes) = &processed.bytes {
        if let Err(e) = load::load(
            bytes,
            &NoResources,
            &LoadLimits {
                max_buffer_bytes: usize::MAX,
            },
        ) {
            panic!("the written scene does not load again: {e:?}");
        }
    }
    if !processed.layouts.is_empty() {
        let svg = tspace::scene::pictures::svg(
            &tspace::scene::pictures::Subject { file: "fuzz" },
            &processed.layouts,
        );
        assert!(svg.ends_with("</svg>\n"), "the picture is not a whole SVG");
    }
}

fn run_scene<'a>(
    kind: InputKind,
    main: &'a [u8],
    resources: &dyn load::Resources<'a>,
    options: &SceneOptions,
) {
    if let Ok(mut processed) = input::process(kind, main, resources, options) {
        if let Some(pieces) = processed.pieces.take() {
            processed.bytes = Some(pieces.to_vec(main));
        }
        check_processed(&processed);
    }
}

/// The GLB container: a file that splits must be rewritten byte for byte from its chunks (the
/// chunks of a valid GLB are already padded, so the writer adds nothing); then the whole scene
/// path, as a GLB.
pub fn glb(data: &[u8]) {
    if let Ok(parsed) = glb_container::parse(data) {
        let rewritten = glb_container::write(parsed.json, parsed.bin, &parsed.other_chunks)
            .expect("a parsed GLB fits in a GLB");
        assert!(
            rewritten == data,
            "a parsed GLB is not rewritten byte for byte"
        );
    }
    run_scene(InputKind::Glb, data, &NoResources, &scene_options(data));
}

/// The JSON parser and every accessor (up to 64) decoded in every way that applies, then the
/// whole scene path with no resources; GLB (by its magic) and `.gltf` input alike. Any JSON the
/// parser accepts is also measured from its text (`sizes::measure_text`, which the storage
/// report runs on tspace's own output) and from its tree: the two must agree.
pub fn gltf(data: &[u8]) {
    let json = match glb_container::parse(data) {
        Ok(glb) => glb.json,
        Err(_) => data,
    };
    if let Ok(doc) = tspace_json::Document::parse(json) {
        assert_eq!(
            sizes::measure_text(json),
            Some(sizes::measure(doc.root())),
            "the text and the tree measure differently"
        );
    }
    if let Ok(loaded) = load::load(
        data,
        &NoResources,
        &LoadLimits {
            max_buffer_bytes: LIMITS.max_buffer_bytes,
        },
    ) {
        let root = loaded.doc.root();
        let buffers = loaded.buffer_slices();
        let count = root
            .get("accessors")
            .and_then(|a| a.as_array())
            .map_or(0, <[_]>::len);
        for index in 0..count.min(64) {
            let Ok(described) = accessor::accessor_from_json(root, index, &buffers) else {
                continue;
            };
            let _ = accessor::read_raw(&described, MAX_ELEMENTS);
            match described.element_type {
                ElementType::Scalar => {
                    let _ = accessor::read_floats::<1>(&described, MAX_ELEMENTS);
                    let _ = accessor::read_indices(&described, MAX_ELEMENTS);
                }
                ElementType::Vec2 => {
                    let _ = accessor::read_floats::<2>(&described, MAX_ELEMENTS);
                }
                ElementType::Vec3 => {
                    let _ = accessor::read_floats::<3>(&described, MAX_ELEMENTS);
                }
                ElementType::Vec4 | ElementType::Mat2 => {
                    let _ = accessor::read_floats::<4>(&described, MAX_ELEMENTS);
                }
                _ => {}
            }
            // A mismatched component count is an error, never a panic.
            let _ = accessor::read_floats::<3>(&described, MAX_ELEMENTS);
        }
    }
    let kind = if glb_container::is_glb(data) {
        InputKind::Glb
    } else {
        InputKind::Gltf
    };
    run_scene(kind, data, &NoResources, &scene_options(data));
}

/// OBJ text, then after the first `0xFF` byte (never in UTF-8) an MTL supplied as `a.mtl`; run
/// with the default options and with the axis method (which needs no UVs), the latter with
/// smooth or flat normals and a crease angle chosen by the input's hash.
pub fn obj(data: &[u8]) {
    let (text, mtl) = match data.iter().position(|&b| b == 0xFF) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    let mut parts = PartSet::new();
    if parts.insert("a.mtl", mtl).is_err() {
        return;
    }
    let options = SceneOptions {
        limits: LIMITS,
        ..SceneOptions::default()
    };
    run_scene(InputKind::Obj, text, &parts, &options);
    // Every primitive gets tangents, with the other ways of making normals.
    let h = hash(data);
    let axis = SceneOptions {
        method: Method::Axis,
        all: true,
        format: OutputFormat::GltfEmbedded,
        normals: if h & 1 == 0 {
            Normals::Smooth
        } else {
            Normals::Flat
        },
        normals_angle: (h >> 1 & 0xFF) as f32 * (180.0 / 255.0),
        ..options
    };
    run_scene(InputKind::Obj, text, &parts, &axis);
    // The parallel reader, on the text cut where lines end, gives up or reads the same file.
    let pieces = (h >> 9 & 15) as usize + 1;
    let limits = obj::Limits::default();
    if let Some(chunked) = obj::parse_in_chunks_for_testing(text, pieces, &limits) {
        // Compared as printed, where NaN equals NaN.
        let sequential = obj::parse_obj(text, &limits).map(|o| format!("{o:?}"));
        assert_eq!(
            Ok(format!("{chunked:?}")),
            sequential.map_err(|e| e.to_string())
        );
    }
}

/// One field of a multipart upload.
struct Field<'a> {
    name: &'a [u8],
    file_name: Option<&'a [u8]>,
    bytes: &'a [u8],
}

/// Reads `len` bytes at `*at`, or what is left.
fn take<'a>(data: &'a [u8], at: &mut usize, len: usize) -> &'a [u8] {
    let start = (*at).min(data.len());
    let end = start.saturating_add(len).min(data.len());
    *at = end;
    &data[start..end]
}

/// Splits the input into multipart fields. Each record is: a name length (1 byte) and the field
/// name; a file-name length (1 byte, `0xFF` for no file name) and the file name; the data length
/// (4 bytes, little-endian, cut to what is left) and the data. At most 16 records.
fn fields(data: &[u8]) -> Vec<Field<'_>> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < data.len() && out.len() < 16 {
        let name_len = take(data, &mut at, 1)[0] as usize;
        let name = take(data, &mut at, name_len);
        let file_name = match take(data, &mut at, 1).first() {
            None | Some(0xFF) => None,
            Some(&len) => Some(take(data, &mut at, len as usize)),
        };
        let len = take(data, &mut at, 4);
        let mut word = [0u8; 4];
        word[..len.len()].copy_from_slice(len);
        let bytes = take(data, &mut at, u32::from_le_bytes(word) as usize);
        out.push(Field {
            name,
            file_name,
            bytes,
        });
    }
    out
}

/// Encodes fields in the format [`parts`] reads (for making seeds).
pub fn encode_parts(fields: &[(&str, Option<&str>, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    for (name, file_name, bytes) in fields {
        out.push(name.len() as u8);
        out.extend_from_slice(name.as_bytes());
        match file_name {
            Some(f) => {
                out.push(f.len() as u8);
                out.extend_from_slice(f.as_bytes());
            }
            None => out.push(0xFF),
        }
        out.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    out
}

/// A multipart upload (see `fields` for the format), assembled as the server does: the scene
/// is the field named file, scene or model, else the first whose file name has a scene
/// extension, else the first; every other field is a part named by its file name, else its field
/// name; two parts with one name are an error. The kind comes from the main file's name, else
/// from its bytes.
pub fn parts(data: &[u8]) {
    let mut fields = fields(data);
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    let main = fields
        .iter()
        .position(|f| matches!(f.name, b"file" | b"scene" | b"model"))
        .or_else(|| {
            fields.iter().position(|f| {
                f.file_name
                    .is_some_and(|n| InputKind::from_file_name(&text(n)).is_some())
            })
        })
        .or(if fields.is_empty() { None } else { Some(0) });
    let Some(main) = main else { return };
    let main = fields.remove(main);
    let Some(kind) = main
        .file_name
        .and_then(|n| InputKind::from_file_name(&text(n)))
        .or_else(|| InputKind::sniff(main.bytes))
    else {
        return;
    };
    let mut set = PartSet::new();
    for field in &fields {
        if set
            .insert(text(field.file_name.unwrap_or(field.name)), field.bytes)
            .is_err()
        {
            return;
        }
    }
    run_scene(kind, main.bytes, &set, &scene_options(data));
}

// ---------------------------------------------------------------------------------------------
// The tangent core.

/// One float from one byte, for the compact encoding: the special values, else a small multiple
/// of 1/8 (so that positions coincide and triangles degenerate often).
fn compact_float(b: u8) -> f32 {
    match b {
        0x80 => f32::NAN,
        0x81 => f32::INFINITY,
        0x82 => f32::NEG_INFINITY,
        0x83 => f32::from_bits(1), // the smallest subnormal
        0x84 => -0.0,
        0x85 => f32::MAX,
        0x86 => f32::MIN_POSITIVE,
        0x87 => 1e-30,
        _ => f32::from(b as i8) / 8.0,
    }
}

/// A mesh decoded from bytes.
struct CoreMesh {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
    options: Options,
    has_uvs: bool,
}

/// The layout: byte 0 the vertex count (at most what the data holds); byte 1 flags (bit 0: each
/// float is one byte, see [`compact_float`], else 4 bytes of raw `f32` bits; bit 1: UV origin
/// bottom left; bit 2: area weighting; bit 3: smooth generated normals, with the crease angle
/// from byte 2 as degrees (255: NaN); bit 4: no UVs; bit 5: keep an index count that is not a
/// multiple of 3). Then per vertex 8 floats (position, normal, UV); then one index per byte: the
/// byte modulo the vertex count, except 0xFF, which is out of range.
fn core_mesh(data: &[u8]) -> Option<CoreMesh> {
    let [count, flags, crease, rest @ ..] = data else {
        return None;
    };
    let compact = flags & 1 != 0;
    let float_size = if compact { 1 } else { 4 };
    let vertex_size = 8 * float_size;
    let n = (*count as usize).min(rest.len() / vertex_size);
    let (vertex_bytes, index_bytes) = rest.split_at(n * vertex_size);
    let floats: Vec<f32> = if compact {
        vertex_bytes.iter().map(|&b| compact_float(b)).collect()
    } else {
        vertex_bytes
            .chunks_exact(4)
            .map(|w| f32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect()
    };
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    let mut uvs = Vec::with_capacity(n);
    for v in floats.chunks_exact(8) {
        positions.push([v[0], v[1], v[2]]);
        normals.push([v[3], v[4], v[5]]);
        uvs.push([v[6], v[7]]);
    }
    let mut indices: Vec<u32> = index_bytes
        .iter()
        .map(|&b| match b {
            0xFF => n as u32,
            _ if n == 0 => 0,
            _ => u32::from(b) % n as u32,
        })
        .collect();
    if flags & 0x20 == 0 {
        indices.truncate(indices.len() / 3 * 3);
    }
    let normal_mode = if flags & 8 != 0 {
        NormalMode::SmoothByAngle {
            crease_degrees: if *crease == 255 {
                f32::NAN
            } else {
                f32::from(*crease)
            },
        }
    } else {
        NormalMode::Flat
    };
    Some(CoreMesh {
        positions,
        normals,
        uvs,
        indices,
        options: Options {
            method: Method::MikkTSpace,
            uv_origin: if flags & 2 != 0 {
                UvOrigin::BottomLeft
            } else {
                UvOrigin::TopLeft
            },
            weighting: if flags & 4 != 0 {
                Weighting::Area
            } else {
                Weighting::Angle
            },
            normal_mode,
            parallel: false,
        },
        has_uvs: flags & 0x10 == 0,
    })
}

/// Arbitrary geometry (see `core_mesh` for the layout) through every method, with and
/// without normals, indexed and not; every result checked with [`invariants::check_core`], every error
/// explained by the input.
pub fn core(data: &[u8]) {
    let Some(mesh) = core_mesh(data) else { return };
    let vertex_count = mesh.positions.len();
    let out_of_range = mesh.indices.iter().any(|&i| i as usize >= vertex_count);
    for method in [Method::MikkTSpace, Method::Fast, Method::Axis] {
        for with_normals in [true, false] {
            for indexed in [true, false] {
                let input = MeshInput {
                    positions: &mesh.positions,
                    normals: with_normals.then_some(&mesh.normals[..]),
                    uvs: mesh.has_uvs.then_some(&mesh.uvs[..]),
                    indices: indexed.then_some(&mesh.indices[..]),
                };
                let options = Options {
                    method,
                    ..mesh.options
                };
                let corners = if indexed {
                    mesh.indices.len()
                } else {
                    vertex_count
                };
                match tangent::generate(&input, &options) {
                    Ok(out) => {
                        if let Err(broken) = invariants::check_core(&input, &options, &out) {
                            panic!("{broken}");
                        }
                    }
                    Err(e) => {
                        let explained = match e {
                            CoreError::MissingUvs { .. } => !mesh.has_uvs && method != Method::Axis,
                            CoreError::NotTriangles { count } => {
                                count == corners && corners % 3 != 0
                            }
                            CoreError::IndexOutOfRange { .. } => indexed && out_of_range,
                            _ => false,
                        };
                        assert!(explained, "unexplained error {e:?} for {options:?}");
                    }
                }
            }
        }
    }
}

/// The Draco header of [`draco`]: the declared layout a stream is decoded under.
const DRACO_HEADER: usize = 9;

/// A `KHR_draco_mesh_compression` stream under a document the first `DRACO_HEADER` (9) bytes
/// declare: the Draco ids of POSITION, NORMAL and TEXCOORD_0 (`0xFF`: absent; POSITION always
/// present), the TEXCOORD_0 component type (by its low two bits: float, normalized u16, normalized
/// u8, i16), the declared vertex count (u16, little-endian), flags (bit 0: indices, bit 1: u32
/// rather than u16 indices, bit 2: NORMAL as normalized i8) and the declared triangle count
/// (u16). The rest is the stream.
///
/// The stream is decoded on its own ([`draco::decode_primitive`]); whatever decodes must fill
/// each accessor exactly (count × element size). Then the same document and stream, with a
/// normal map, take the whole scene path as a GLB.
pub fn draco(data: &[u8]) {
    let Some((header, stream)) = data.split_first_chunk::<DRACO_HEADER>() else {
        return;
    };
    let text =
        serde_json::to_vec(&draco_document(header, stream.len())).expect("a JSON value serializes");
    let _ = decode_draco_input(&text, stream);
    let glb = glb_container::write(&text, Some(stream), &[]).expect("a small GLB fits");
    run_scene(InputKind::Glb, &glb, &NoResources, &scene_options(data));
}

/// How many accessors a [`draco()`] input decodes to, or why it does not: lets a test check that
/// the seeds reach the decoder's far side.
pub fn draco_decoded_accessors(data: &[u8]) -> Result<usize, String> {
    let (header, stream) = data
        .split_first_chunk::<DRACO_HEADER>()
        .ok_or("shorter than the header")?;
    let text =
        serde_json::to_vec(&draco_document(header, stream.len())).expect("a JSON value serializes");
    decode_draco_input(&text, stream)
}

fn decode_draco_input(text: &[u8], stream: &[u8]) -> Result<usize, String> {
    let Ok(parsed) = tspace_json::Document::parse(text) else {
        panic!("the fuzz document does not parse");
    };
    let root = parsed.root();
    let primitive = root
        .get("meshes")
        .and_then(|m| m.index(0))
        .and_then(|m| m.get("primitives"))
        .and_then(|p| p.index(0))
        .expect("the fuzz document has its primitive");
    let limits = draco::DracoLimits {
        max_vertices: LIMITS.max_vertices,
        max_triangles: LIMITS.max_triangles,
        max_bytes: LIMITS.max_buffer_bytes,
    };
    let decoded = draco::decode_primitive(root, primitive, "fuzz", &[stream], &limits)
        .map_err(|e| e.to_string())?;
    for (index, accessor) in &decoded {
        let described = accessor::accessor_from_json(root, *index, &[])
            .expect("a decoded accessor is described by the document");
        let element = described.component_type.size() * described.element_type.components();
        assert_eq!(
            accessor.bytes.len(),
            accessor.count * element,
            "accessors[{index}] is not filled exactly"
        );
        assert!(accessor.count <= LIMITS.max_vertices.max(LIMITS.max_triangles * 3));
    }
    Ok(decoded.len())
}

fn draco_document(header: &[u8; DRACO_HEADER], stream_len: usize) -> serde_json::Value {
    use serde_json::json;
    let [
        position_id,
        normal_id,
        uv_id,
        uv_type,
        count_lo,
        count_hi,
        flags,
        tri_lo,
        tri_hi,
    ] = *header;
    let count = u16::from_le_bytes([count_lo, count_hi]);
    let mut accessors = vec![json!({"componentType": 5126, "count": count, "type": "VEC3"})];
    let mut attributes = serde_json::Map::new();
    let mut ids = serde_json::Map::new();
    attributes.insert("POSITION".into(), json!(0));
    ids.insert("POSITION".into(), json!(position_id));
    if normal_id != 0xFF {
        let normal = if flags & 4 != 0 {
            json!({"componentType": 5120, "normalized": true, "count": count, "type": "VEC3"})
        } else {
            json!({"componentType": 5126, "count": count, "type": "VEC3"})
        };
        attributes.insert("NORMAL".into(), json!(accessors.len()));
        ids.insert("NORMAL".into(), json!(normal_id));
        accessors.push(normal);
    }
    if uv_id != 0xFF {
        let (component_type, normalized) = match uv_type & 3 {
            0 => (5126, false),
            1 => (5123, true),
            2 => (5121, true),
            _ => (5122, false),
        };
        attributes.insert("TEXCOORD_0".into(), json!(accessors.len()));
        ids.insert("TEXCOORD_0".into(), json!(uv_id));
        accessors.push(
            json!({"componentType": component_type, "normalized": normalized,
            "count": count, "type": "VEC2"}),
        );
    }
    let mut primitive = json!({"attributes": attributes, "material": 0,
        "extensions": {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": ids}}});
    if flags & 1 != 0 {
        let component_type = if flags & 2 != 0 { 5125 } else { 5123 };
        primitive["indices"] = json!(accessors.len());
        accessors.push(json!({"componentType": component_type,
            "count": u32::from(u16::from_le_bytes([tri_lo, tri_hi])) * 3, "type": "SCALAR"}));
    }
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"],
        "buffers": [{"byteLength": stream_len}],
        "bufferViews": [{"buffer": 0, "byteLength": stream_len}],
        "accessors": accessors,
        "meshes": [{"primitives": [primitive]}],
        "materials": [{"normalTexture": {"index": 0}}],
        "textures": [{"source": 0}],
        "images": [{"mimeType": "image/png", "bufferView": 0}],
    })
}
