//! One entry point for every input: GLB, `.gltf` or OBJ bytes, with the parts (buffers, images,
//! MTL files) that came with them. The HTTP server and the CLI both call [`process`], so they
//! cannot drift apart.
//!
//! An OBJ is converted to a glTF document first ([`super::obj_gltf`]) and then goes through the
//! glTF path like any other scene. OBJ groups whose material has a normal map get tangents; so do
//! faces with no material at all, since an OBJ sent to a tangent tool without an MTL gives no
//! other way to say what it wants. Groups whose MTL material has no normal map are skipped, as in
//! glTF, unless `all` is set.

use super::error::{ProblemCode, SceneError};
use super::gltf::load::{NoResources, Resources};
use super::gltf::{self, glb};
use super::obj::{self, ObjErrorKind};
use super::obj_gltf::{self, ConvertError, ConvertLimits, NormalRequest};
use super::options::Timings;
use super::report::Notice;
use super::uri::PartSet;
use super::{Processed, SceneOptions};

/// What kind of file the main input is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    Glb,
    Gltf,
    Obj,
}

impl InputKind {
    /// Tells the kind from the bytes: the GLB magic, a JSON object, or else text, read as OBJ.
    /// Binary data that is none of these is `None`.
    pub fn sniff(bytes: &[u8]) -> Option<InputKind> {
        if glb::is_glb(bytes) {
            return Some(InputKind::Glb);
        }
        let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        match text.iter().find(|b| !b.is_ascii_whitespace()) {
            Some(b'{') => Some(InputKind::Gltf),
            // OBJ is text; a NUL in the first kilobyte means it is not.
            _ if !text.iter().take(1024).any(|&b| b == 0) => Some(InputKind::Obj),
            _ => None,
        }
    }

    /// From a media type (`model/gltf-binary`, `model/gltf+json`, `model/obj`), parameters
    /// ignored.
    pub fn from_media_type(media_type: &str) -> Option<InputKind> {
        let essence = media_type.split(';').next().unwrap_or("").trim();
        match essence.to_ascii_lowercase().as_str() {
            "model/gltf-binary" => Some(InputKind::Glb),
            "model/gltf+json" => Some(InputKind::Gltf),
            "model/obj" | "text/x-obj" | "application/x-tgif" => Some(InputKind::Obj),
            _ => None,
        }
    }

    /// From a file name's extension.
    pub fn from_file_name(name: &str) -> Option<InputKind> {
        let extension = name.rsplit_once('.')?.1.to_ascii_lowercase();
        match extension.as_str() {
            "glb" => Some(InputKind::Glb),
            "gltf" => Some(InputKind::Gltf),
            "obj" => Some(InputKind::Obj),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            InputKind::Glb => "glb",
            InputKind::Gltf => "gltf",
            InputKind::Obj => "obj",
        }
    }
}

/// Processes one scene. `resources` supplies what the main file refers to by name: an upload's
/// parts ([`PartSet`]), or on the command line the file's folder ([`super::folder::Folder`]).
pub fn process<'a>(
    kind: InputKind,
    main: &'a [u8],
    resources: &dyn Resources<'a>,
    options: &SceneOptions,
) -> Result<Processed, SceneError> {
    match kind {
        InputKind::Glb | InputKind::Gltf => {
            if kind == InputKind::Gltf && glb::is_glb(main) {
                return Err(SceneError::new(
                    ProblemCode::MalformedGltf,
                    "the input was declared .gltf (JSON) but is a GLB",
                ));
            }
            if kind == InputKind::Glb && !glb::is_glb(main) {
                return Err(SceneError::new(
                    ProblemCode::MalformedGlb,
                    "the input was declared GLB but does not start with the GLB magic 'glTF'",
                ));
            }
            gltf::process(main, resources, options)
        }
        InputKind::Obj => process_read_obj(read_obj(main, options)?, resources, options),
    }
}

fn obj_error(error: obj::ObjError) -> SceneError {
    match &error.kind {
        ObjErrorKind::LimitExceeded { what, .. } => {
            let code = if what.contains("triangle") {
                ProblemCode::TooManyTriangles
            } else {
                ProblemCode::TooManyVertices
            };
            SceneError::new(code, format!("OBJ {error}"))
        }
        _ => SceneError::new(ProblemCode::MalformedObj, format!("OBJ {error}")),
    }
}

/// An OBJ read from its text by [`read_obj`]: all [`process_read_obj`] needs, without the text.
pub struct ReadObj {
    parsed: obj::Obj,
    /// The text's length, for the report.
    text_bytes: u64,
    timings: Timings,
}

/// Reads an OBJ's text, the first half of [`process`] for an OBJ. Unlike a glTF's output, which
/// repeats its input's bytes, nothing [`process_read_obj`] makes refers to the text, so a
/// caller holding it in memory of its own (a request's body) can free it before the second
/// half, whose conversion needs memory of its size again.
pub fn read_obj(main: &[u8], options: &SceneOptions) -> Result<ReadObj, SceneError> {
    let mut timings = Timings::start();
    let parsed = parse_obj(main, options)?;
    timings.lap("parse OBJ");
    SceneError::check(&options.cancel)?;
    check_reads_as_obj(&parsed)?;
    Ok(ReadObj {
        parsed,
        text_bytes: main.len() as u64,
        timings,
    })
}

/// The rest of [`process`] for an OBJ [`read_obj`] read: read its MTL files and the textures
/// they name, convert it to a GLB, and process that like any glTF; the report then describes
/// the OBJ.
pub fn process_read_obj<'a>(
    read: ReadObj,
    resources: &dyn Resources<'a>,
    options: &SceneOptions,
) -> Result<Processed, SceneError> {
    let ReadObj {
        parsed,
        text_bytes,
        mut timings,
    } = read;
    let mut supplied = Supplied::default();
    let mtl = read_material_libraries(&parsed, resources, &mut supplied)?;
    supplied.notices.extend(parse_notices(&parsed.warnings));
    fetch_textures(mtl.as_ref(), resources, &mut supplied);
    let glb_bytes = convert_to_glb(&parsed, mtl.as_ref(), &mut supplied, options)?;
    drop(parsed);
    timings.lap("convert OBJ to GLB");
    SceneError::check(&options.cancel)?;
    let mut processed = gltf::process_with(
        &glb_bytes,
        &NoResources,
        options,
        &gltf::Internal {
            no_material_means_tangents: true,
        },
    )?;
    // The OBJ's steps, then the glTF path's.
    timings.steps.append(&mut processed.timings.steps);
    // The pieces refer to the GLB made here, which the caller does not hold: they keep it.
    if let Some(pieces) = processed.pieces.take() {
        processed.pieces = Some(pieces.with_own_input(glb_bytes));
    }
    processed.timings.steps = timings.steps;
    let report = &mut processed.report;
    report.input_format = "obj";
    report.input_bytes = text_bytes + supplied.bytes;
    // The OBJ's own notices come first, then the glTF path's. The conversion already named
    // the textures that were not supplied (textures_not_supplied); the glTF path would name
    // each again as an image.
    report.notices.retain(|n| n.code != "image_not_supplied");
    supplied.notices.append(&mut report.notices);
    report.notices = supplied.notices;
    report.finish();
    Ok(processed)
}

/// Refuses text in which not one line is an OBJ statement (a README or CSV sent as a scene, or
/// named `.obj`), which would otherwise be "an OBJ without faces".
fn check_reads_as_obj(parsed: &obj::Obj) -> Result<(), SceneError> {
    let w = &parsed.warnings;
    if parsed.statements > 0 || w.unsupported_statements == 0 {
        return Ok(());
    }
    let shown: Vec<String> = w
        .unsupported_keywords
        .iter()
        .take(3)
        .map(|k| format!("{:?}", k.chars().take(24).collect::<String>()))
        .collect();
    Err(SceneError::new(
        ProblemCode::UnsupportedMediaType,
        format!(
            "not a GLB, glTF or OBJ: nothing in it reads as an OBJ statement (v, vt, vn, f, ...); \
             its lines begin with {}",
            shown.join(", ")
        ),
    ))
}

/// What came with the OBJ: the textures to embed, the bytes read beside it (MTL files and
/// textures, for the report's input size), and warnings about what was missing or skipped.
#[derive(Default)]
struct Supplied<'a> {
    images: Vec<(String, std::borrow::Cow<'a, [u8]>)>,
    bytes: u64,
    notices: Vec<Notice>,
}

fn parse_obj(main: &[u8], options: &SceneOptions) -> Result<obj::Obj, SceneError> {
    let limits = obj::Limits {
        max_vertices: options.limits.max_vertices,
        max_triangles: options.limits.max_triangles,
        ..obj::Limits::default()
    };
    obj::parse_obj(main, &limits).map_err(obj_error)
}

/// Every `mtllib` the OBJ names, merged into one library. A missing file is a warning (its
/// faces get default materials); a malformed one is an error.
fn read_material_libraries<'a>(
    parsed: &obj::Obj,
    resources: &dyn Resources<'a>,
    supplied: &mut Supplied<'a>,
) -> Result<Option<obj::Mtl>, SceneError> {
    let mut mtl: Option<obj::Mtl> = None;
    for name in &parsed.material_libraries {
        let Ok(bytes) = resources.fetch(name) else {
            supplied.notices.push(Notice::new(
                "mtl_not_supplied",
                format!(
                    "the OBJ names the material library {name:?}, which was not supplied; its faces get default materials"
                ),
            ));
            continue;
        };
        supplied.bytes += bytes.len() as u64;
        let library = obj::parse_mtl(&bytes).map_err(|e| {
            SceneError::new(ProblemCode::MalformedMtl, format!("MTL {name:?}: {e}"))
        })?;
        match &mut mtl {
            None => mtl = Some(library),
            Some(all) => all.materials.extend(library.materials),
        }
    }
    Ok(mtl)
}

/// What the OBJ parser skipped or repaired, one sentence each.
fn parse_notices(w: &obj::Warnings) -> Vec<Notice> {
    let mut notices = Vec::new();
    if w.unsupported_statements > 0 {
        notices.push(Notice::new(
            "obj_statements_skipped",
            format!(
                "{} OBJ statements were skipped ({})",
                w.unsupported_statements,
                w.unsupported_keywords.join(", ")
            ),
        ));
    }
    for (code, count, what) in [
        (
            "obj_faces_repaired",
            w.faces_with_partial_uvs,
            "faces had texture coordinates on only some corners; they were dropped for those faces",
        ),
        (
            "obj_faces_repaired",
            w.faces_with_partial_normals,
            "faces had normals on only some corners; they were dropped for those faces",
        ),
        (
            "obj_faces_repaired",
            w.faces_too_few_corners,
            "faces had fewer than 3 corners and were skipped",
        ),
        (
            "obj_faces_repaired",
            w.polygons_fanned,
            "polygons could not be ear-clipped and were triangulated as fans",
        ),
        (
            "obj_statements_skipped",
            w.lines_skipped,
            "line statements were skipped",
        ),
        (
            "obj_statements_skipped",
            w.points_skipped,
            "point statements were skipped",
        ),
    ] {
        if count > 0 {
            notices.push(Notice::new(code, format!("{count} {what}")));
        }
    }
    notices
}

/// The textures the conversion embeds, fetched under the path the MTL wrote. MTL files from
/// Windows tools write `.\name.jpg`; the slash form and the bare file name are tried too. One
/// that is not found stays a reference (the conversion says so).
fn fetch_textures<'a>(
    mtl: Option<&obj::Mtl>,
    resources: &dyn Resources<'a>,
    supplied: &mut Supplied<'a>,
) {
    for material in mtl.iter().flat_map(|m| &m.materials) {
        for texture in [
            &material.diffuse_map,
            &material.normal_map,
            &material.bump_map,
        ]
        .into_iter()
        .flatten()
        {
            if supplied.images.iter().any(|(n, _)| *n == texture.path) {
                continue;
            }
            let slashed = texture.path.replace('\\', "/");
            let file_name = slashed.rsplit('/').next().unwrap_or("").to_owned();
            let found = [texture.path.as_str(), slashed.as_str(), file_name.as_str()]
                .into_iter()
                .filter(|c| !c.is_empty())
                .find_map(|c| resources.fetch(c).ok());
            if let Some(bytes) = found {
                supplied.bytes += bytes.len() as u64;
                supplied.images.push((texture.path.clone(), bytes));
            }
        }
    }
}

/// The OBJ as a GLB with its textures embedded; the conversion's warnings join the rest.
fn convert_to_glb(
    parsed: &obj::Obj,
    mtl: Option<&obj::Mtl>,
    supplied: &mut Supplied<'_>,
    options: &SceneOptions,
) -> Result<Vec<u8>, SceneError> {
    let mut image_parts = PartSet::new();
    for (name, bytes) in &supplied.images {
        // Names are distinct by construction.
        let _ = image_parts.insert(name.clone(), bytes);
    }
    let normals = NormalRequest {
        normals: options.normals,
        crease_degrees: options.normals_angle,
    };
    let converted = obj_gltf::obj_to_gltf(
        parsed,
        mtl,
        &image_parts,
        normals,
        &ConvertLimits::default(),
    )
    .map_err(|e| match e {
        ConvertError::TooLarge { .. } => SceneError::new(ProblemCode::TooLarge, e.to_string()),
        // The document tspace built would not serialize: a bug here, not the file's fault.
        ConvertError::Json(_) => SceneError::new(ProblemCode::Internal, e.to_string()),
        _ => SceneError::new(ProblemCode::ObjNotConvertible, e.to_string()),
    })?;
    supplied.notices.extend(converted.notices);
    glb::write_around_bin(converted.json.as_bytes(), converted.bin)
        .map_err(|e| SceneError::new(ProblemCode::TooLarge, format!("the converted OBJ {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_are_told_apart() {
        assert_eq!(InputKind::sniff(b"glTF\x02\0\0\0"), Some(InputKind::Glb));
        assert_eq!(
            InputKind::sniff(b"\xEF\xBB\xBF  {\"asset\":{}}"),
            Some(InputKind::Gltf)
        );
        assert_eq!(
            InputKind::sniff(b"# comment\nv 0 0 0\n"),
            Some(InputKind::Obj)
        );
        assert_eq!(InputKind::sniff(b"\x89PNG\r\n\x1a\n\0\0"), None);
        assert_eq!(
            InputKind::from_media_type("model/gltf+json; charset=utf-8"),
            Some(InputKind::Gltf)
        );
        assert_eq!(InputKind::from_file_name("a.b.GLB"), Some(InputKind::Glb));
        assert_eq!(InputKind::from_file_name("noextension"), None);
    }
}
