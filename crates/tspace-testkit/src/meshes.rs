//! Test-only mesh readers: glTF 2.0 (through the `gltf` crate) and a small Wavefront OBJ reader.
//!
//! These exist to feed the oracle tests with real meshes from `fixtures/` and the shared corpus.
//! They are meant for those known-good files only: the `gltf` crate panics on some malformed
//! input, and the OBJ reader does not try to be robust against hostile files either.
//!
//! Attributes are returned as stored: no UV flip, no normalization. A glTF texture coordinate
//! has its origin at the top left, an OBJ one at the bottom left.

use std::path::Path;

/// One triangle list read from a file: a glTF primitive, or a whole OBJ file.
#[derive(Clone, Debug)]
pub struct Primitive {
    /// Where it came from, for messages: `file.gltf mesh 0 primitive 1` or `file.obj`.
    pub name: String,
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    /// The texture coordinates the normal map reads (see [`Primitive::uv_set`]).
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Which `TEXCOORD_n` `uvs` holds: the material's `normalTexture.texCoord`, or 0 when the
    /// material has no normal texture. Always 0 for OBJ.
    pub uv_set: u32,
    /// Authored `TANGENT` (glTF only).
    pub tangents: Option<Vec<[f32; 4]>>,
    /// Three per triangle. Generated as `0..n` for non-indexed primitives; strips and fans are
    /// converted to lists.
    pub indices: Vec<u32>,
}

impl Primitive {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// Extensions a document may require and still be read correctly here: they change materials
/// or texture sampling, never the vertex data.
const READABLE_REQUIRED_EXTENSIONS: &[&str] = &["KHR_texture_transform", "KHR_materials_sheen"];

/// Reads every triangle primitive (triangles, strips and fans) of a `.gltf` or `.glb` file.
/// Points and lines are skipped.
pub fn load_gltf(path: &Path) -> Result<Vec<Primitive>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let gltf = parse_gltf(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    for ext in gltf.extensions_required() {
        if !READABLE_REQUIRED_EXTENSIONS.contains(&ext) {
            return Err(format!(
                "{}: requires {ext}, which this reader does not handle",
                path.display()
            ));
        }
    }
    let base = path.parent().unwrap_or_else(|| Path::new("."));
    let buffers = load_buffers(&gltf, base, gltf.blob.as_deref())
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();

    let mut out = Vec::new();
    for mesh in gltf.meshes() {
        for primitive in mesh.primitives() {
            let name = format!(
                "{file_name} mesh {} primitive {}",
                mesh.index(),
                primitive.index()
            );
            if let Some(p) = read_primitive(&primitive, &buffers, name)? {
                out.push(p);
            }
        }
    }
    Ok(out)
}

/// Parses and validates a document. The `gltf` crate refuses documents that *require* an
/// extension it was not built with (this build enables none); such documents are accepted when
/// that is the only complaint and every required extension is one this reader can ignore.
fn parse_gltf(bytes: &[u8]) -> Result<gltf::Gltf, String> {
    match gltf::Gltf::from_slice(bytes) {
        Ok(gltf) => Ok(gltf),
        Err(gltf::Error::Validation(errors))
            if errors.iter().all(|(path, error)| {
                *error == gltf::json::validation::Error::Unsupported
                    && path.as_str().starts_with("extensionsRequired[")
                    && READABLE_REQUIRED_EXTENSIONS
                        .iter()
                        .any(|ext| path.as_str().ends_with(&format!("\"{ext}\"")))
            }) =>
        {
            gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())
        }
        Err(e) => Err(e.to_string()),
    }
}

fn load_buffers(
    gltf: &gltf::Gltf,
    base: &Path,
    blob: Option<&[u8]>,
) -> Result<Vec<Vec<u8>>, String> {
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.ok_or("the BIN chunk is missing")?.to_vec(),
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let (_, payload) = rest.split_once(";base64,").ok_or_else(|| {
                        format!("unsupported data URI for buffer {}", buffer.index())
                    })?;
                    base64_decode(payload)?
                } else {
                    let file = base.join(percent_decode(uri));
                    std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?
                }
            }
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {} has {} bytes, {} expected",
                buffer.index(),
                data.len(),
                buffer.length()
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

fn read_primitive(
    primitive: &gltf::Primitive<'_>,
    buffers: &[Vec<u8>],
    name: String,
) -> Result<Option<Primitive>, String> {
    use gltf::accessor::DataType;
    use gltf::mesh::{Mode, Semantic};

    let mode = primitive.mode();
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(None);
    }
    // The util readers reinterpret bytes as the item type, so check the float attributes are
    // really floats (KHR_mesh_quantization would allow integers).
    for semantic in [Semantic::Positions, Semantic::Normals, Semantic::Tangents] {
        if let Some(accessor) = primitive.get(&semantic) {
            if accessor.data_type() != DataType::F32 {
                return Err(format!("{name}: {semantic:?} is not float"));
            }
        }
    }

    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let positions: Vec<[f32; 3]> = reader
        .read_positions()
        .ok_or_else(|| format!("{name}: no POSITION"))?
        .collect();
    let normals: Option<Vec<[f32; 3]>> = reader.read_normals().map(Iterator::collect);
    let uv_set = primitive
        .material()
        .normal_texture()
        .map_or(0, |t| t.tex_coord());
    let uvs: Option<Vec<[f32; 2]>> = reader
        .read_tex_coords(uv_set)
        .map(|t| t.into_f32().collect());
    let tangents: Option<Vec<[f32; 4]>> = reader.read_tangents().map(Iterator::collect);
    let stream: Vec<u32> = match reader.read_indices() {
        Some(indices) => indices.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };

    let n = positions.len();
    for (what, len) in [
        ("NORMAL", normals.as_ref().map(Vec::len)),
        ("TEXCOORD", uvs.as_ref().map(Vec::len)),
        ("TANGENT", tangents.as_ref().map(Vec::len)),
    ] {
        if len.is_some_and(|len| len != n) {
            return Err(format!("{name}: {what} count differs from POSITION"));
        }
    }
    if let Some(bad) = stream.iter().find(|&&i| i as usize >= n) {
        return Err(format!("{name}: index {bad} out of range ({n} vertices)"));
    }

    let indices = match mode {
        Mode::Triangles => {
            let whole = stream.len() - stream.len() % 3;
            stream[..whole].to_vec()
        }
        Mode::TriangleStrip => strip_to_list(&stream),
        Mode::TriangleFan => fan_to_list(&stream),
        _ => unreachable!(),
    };

    Ok(Some(Primitive {
        name,
        positions,
        normals,
        uvs,
        uv_set,
        tangents,
        indices,
    }))
}

/// glTF triangle strip: triangle i is (i, i+1, i+2) for even i, (i+1, i, i+2) for odd i.
fn strip_to_list(strip: &[u32]) -> Vec<u32> {
    let mut out = Vec::new();
    for i in 0..strip.len().saturating_sub(2) {
        if i % 2 == 0 {
            out.extend([strip[i], strip[i + 1], strip[i + 2]]);
        } else {
            out.extend([strip[i + 1], strip[i], strip[i + 2]]);
        }
    }
    out
}

/// glTF triangle fan: triangle i is (i+1, i+2, 0).
fn fan_to_list(fan: &[u32]) -> Vec<u32> {
    let mut out = Vec::new();
    for i in 0..fan.len().saturating_sub(2) {
        out.extend([fan[i + 1], fan[i + 2], fan[0]]);
    }
    out
}

fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let Some(v) = s
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
            {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn base64_decode(s: &str) -> Result<Vec<u8>, String> {
    fn value(c: u8) -> Option<u32> {
        match c {
            b'A'..=b'Z' => Some(u32::from(c - b'A')),
            b'a'..=b'z' => Some(u32::from(c - b'a') + 26),
            b'0'..=b'9' => Some(u32::from(c - b'0') + 52),
            b'+' | b'-' => Some(62),
            b'/' | b'_' => Some(63),
            _ => None,
        }
    }
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let mut acc = 0u32;
    let mut bits = 0;
    for &c in s.as_bytes() {
        if c == b'=' {
            break;
        }
        if c.is_ascii_whitespace() {
            continue;
        }
        let v = value(c).ok_or_else(|| format!("bad base64 character {:?}", c as char))?;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// Reads a Wavefront OBJ file into one indexed triangle list.
///
/// Understands `v`, `vt`, `vn` and `f` (with `v`, `v/vt`, `v//vn` and `v/vt/vn` corners,
/// negative indices counting back from the latest element). Polygons are split as fans from
/// their first corner. Every distinct (v, vt, vn) triple becomes one output vertex. UVs (or
/// normals) are returned only when every face corner has one. Everything else is ignored.
pub fn load_obj(path: &Path) -> Result<Primitive, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    parse_obj(&text, name)
}

/// See [`load_obj`].
pub fn parse_obj(text: &str, name: String) -> Result<Primitive, String> {
    let mut v: Vec<[f32; 3]> = Vec::new();
    let mut vt: Vec<[f32; 2]> = Vec::new();
    let mut vn: Vec<[f32; 3]> = Vec::new();
    // Output vertices as (v, vt, vn) triples, u32::MAX where absent.
    let mut triples: Vec<[u32; 3]> = Vec::new();
    let mut lookup = std::collections::HashMap::<[u32; 3], u32>::new();
    let mut indices = Vec::new();

    for (line_number, line) in text.lines().enumerate() {
        let line_number = line_number + 1;
        let err = |what: &str| format!("{name}:{line_number}: {what}");
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let floats = |words: std::str::SplitWhitespace<'_>| -> Result<Vec<f32>, String> {
            words
                .map(|w| {
                    w.parse::<f32>()
                        .map_err(|_| err(&format!("bad number {w:?}")))
                })
                .collect()
        };
        match keyword {
            "v" => {
                let f = floats(words)?;
                if f.len() < 3 {
                    return Err(err("v needs 3 coordinates"));
                }
                v.push([f[0], f[1], f[2]]);
            }
            "vt" => {
                let f = floats(words)?;
                if f.is_empty() {
                    return Err(err("vt needs a coordinate"));
                }
                vt.push([f[0], f.get(1).copied().unwrap_or(0.0)]);
            }
            "vn" => {
                let f = floats(words)?;
                if f.len() < 3 {
                    return Err(err("vn needs 3 coordinates"));
                }
                vn.push([f[0], f[1], f[2]]);
            }
            "f" => {
                let mut corners = Vec::new();
                for word in words {
                    let mut parts = word.split('/');
                    let resolve = |part: Option<&str>, len: usize| -> Result<u32, String> {
                        match part {
                            None | Some("") => Ok(u32::MAX),
                            Some(p) => {
                                let i: i64 =
                                    p.parse().map_err(|_| err(&format!("bad index {p:?}")))?;
                                let resolved = if i < 0 { len as i64 + i } else { i - 1 };
                                if i == 0 || resolved < 0 || resolved >= len as i64 {
                                    return Err(err(&format!("index {i} out of range")));
                                }
                                Ok(resolved as u32)
                            }
                        }
                    };
                    let iv = resolve(parts.next(), v.len())?;
                    if iv == u32::MAX {
                        return Err(err("face corner without a position"));
                    }
                    let it = resolve(parts.next(), vt.len())?;
                    let inn = resolve(parts.next(), vn.len())?;
                    let key = [iv, it, inn];
                    let out = *lookup.entry(key).or_insert_with(|| {
                        triples.push(key);
                        (triples.len() - 1) as u32
                    });
                    corners.push(out);
                }
                if corners.len() < 3 {
                    return Err(err("face with fewer than 3 corners"));
                }
                for k in 1..corners.len() - 1 {
                    indices.extend([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }

    let positions = triples.iter().map(|t| v[t[0] as usize]).collect();
    let uvs = triples
        .iter()
        .all(|t| t[1] != u32::MAX)
        .then(|| triples.iter().map(|t| vt[t[1] as usize]).collect());
    let normals = triples
        .iter()
        .all(|t| t[2] != u32::MAX)
        .then(|| triples.iter().map(|t| vn[t[2] as usize]).collect());
    Ok(Primitive {
        name,
        positions,
        normals,
        uvs,
        uv_set: 0,
        tangents: None,
        indices,
    })
}
