//! A parsed OBJ (and its MTL) turned into a glTF 2.0 document: JSON text plus one binary buffer,
//! so the rest of tspace can treat an OBJ exactly like a GLB. No tangents are made here; the
//! tangent step does that later, to the converted document. Normals are, for faces without
//! `vn`, because only the OBJ knows its smoothing groups (see [Normals](#normals)).
//!
//! # Structure
//!
//! - **Objects**: each run of faces under one `o` name becomes one node and one mesh carrying
//!   that name (faces before any `o` form an unnamed object). Two `o` blocks of the same name
//!   separated by another object stay two nodes, as two `o` statements made them.
//! - **Primitives**: one per (material, has UVs, has normals) signature within an object, in
//!   order of first use, merging every run of that signature across the object (faces given
//!   generated normals count as having normals). Each is indexed
//!   `TRIANGLES`; corners are deduplicated by their (position, uv, normal) index triple, so an
//!   OBJ vertex shared by faces stays shared. Indices are `u16` when the primitive has at most
//!   65535 vertices (the largest index is then 65534, never the 65535 primitive-restart value),
//!   `u32` otherwise.
//! - **Attributes**, each in its own tightly packed, 4-byte aligned buffer view: `POSITION`
//!   (with `min`/`max`), `NORMAL` (scaled to unit length; every primitive has it), `TEXCOORD_0`
//!   (`v` flipped to `1 - v`: OBJ's origin is the bottom left, glTF's the top left) and
//!   `COLOR_0` (float RGB, when the OBJ has vertex colours). `TEXCOORD_0` appears only on
//!   primitives whose faces had it.
//! - **Coordinates** are copied as they are: OBJ has no declared up axis or unit, and most
//!   exporters write glTF's (+Y up, metres or unknown). Winding is kept (both formats have
//!   counter-clockwise front faces).
//!
//! # Flawed values
//!
//! The Khronos glTF-Validator reports a non-unit normal (`ACCESSOR_VECTOR3_NON_UNIT`), a
//! non-finite value (`ACCESSOR_INVALID_FLOAT`) and a colour outside `[0, 1]`
//! (`ACCESSOR_NON_CLAMPED`) as errors, not warnings. So:
//!
//! - Normals are scaled to unit length. A triangle with a corner whose normal has zero length
//!   or a non-finite component gets generated normals, like the OBJ reader's faces with normals
//!   on some corners only and faces without `vn`. Likewise a triangle with a non-finite
//!   texture coordinate loses its texture coordinates. Both are counted in a warning.
//!
//! # Normals
//!
//! A face without `vn` gets normals made as [`NormalRequest`] says (the `normals` option), per
//! object, over all its faces without `vn` at once, so that smoothing crosses materials as it
//! does in the modeller; corners with `vn` keep theirs. `auto`, the default, does what
//! Blender's, Maya's and 3ds Max's importers do with smoothing groups: when the file has `s`
//! statements, faces of one group are smooth across every edge they share and faces of
//! `s off`/`s 0` are flat; when it has none (so nothing says how the modeller shaded it), faces
//! are smooth across edges flatter than [`DEFAULT_CREASE_DEGREES`] (or `normals_angle`) and
//! sharper edges stay hard, like an auto-smooth. `smooth` ignores the groups and smooths by
//! angle; `flat` gives each face its own normal. One warning says which, for how many
//! triangles, and how to choose otherwise. (Without this, the glTF path would make them flat,
//! as the glTF specification requires for primitives without `NORMAL`, and a smooth model
//! would come out faceted with several times the vertices.)
//! - Vertex colours are clamped to `[0, 1]` (a NaN component becomes 1), counted in a warning.
//! - A triangle with a NaN or infinite position is dropped, counted in a warning: it cannot be
//!   drawn, glTF's `POSITION` needs finite `min`/`max`, and the Khronos validator rejects
//!   non-finite accessor values, so keeping it would make the whole file invalid. An OBJ whose
//!   every triangle is dropped has nothing to draw: an error
//!   ([`ConvertError::NoFiniteTriangles`]), as an OBJ without faces is.
//!
//! # Materials (from the MTL; only those used, in order of first use)
//!
//! - Without an MTL no material is written and primitives have none (a warning says when the
//!   OBJ named materials). A `usemtl` name the MTL lacks gets a plain material of that name
//!   (white, non-metallic, fully rough) and a warning; faces without `usemtl` get no material.
//! - `baseColorFactor` is `Kd` (white when absent, so a `map_Kd` alone shows as it is) with
//!   alpha `d`; `alphaMode` is `BLEND` when `d < 1`. Colours and factors are clamped to
//!   `[0, 1]` as glTF requires (a warning names materials clamped or with non-finite values,
//!   which get the default).
//! - `metallicFactor` is `Pm`, else 0. `roughnessFactor` is `Pr`, else derived from the Phong
//!   exponent `Ns`: the usual Blinn-Phong-to-microfacet match gives the distribution width
//!   `alpha = sqrt(2 / (Ns + 2))`, and glTF's roughness is the *perceptual* roughness whose
//!   square is alpha, so `roughness = (2 / (Ns + 2))^(1/4)` (`Ns` 0 gives 1, 10 gives 0.64, 100
//!   gives 0.37, 1000 gives 0.21). A black `Ks` (no highlight at all) gives roughness 1
//!   whatever `Ns` says. Without `Ns`, roughness is 1. `Ks`'s colour is otherwise unused.
//! - `emissiveFactor` is `Ke`. When a component exceeds 1, the factor is `Ke` divided by its
//!   largest component and `KHR_materials_emissive_strength` carries that component, so
//!   nothing is lost.
//! - `map_Kd` becomes `baseColorTexture`; `norm`, else `map_Bump`/`bump`, becomes
//!   `normalTexture` with `scale` = its `-bm` value when given. (A `bump` map may be a height
//!   map; tspace cannot tell without decoding the image, and tangent-space normal maps are what
//!   exporters write there in practice.) `map_d` and `map_Ks` are not converted (warning).
//! - A texture's `-o` and `-s` become `KHR_texture_transform` on that texture reference. OBJ
//!   samples its image at `t = o + s * uv` with V up; with glTF's `v' = 1 - v` on both the
//!   coordinates and the image, `t'_v = 1 - (o_v + s_v (1 - v')) = (1 - o_v - s_v) + s_v v'`, so
//!   glTF's `scale` is `(s_u, s_v)` and its `offset` is `(o_u, 1 - o_v - s_v)`.
//! - A material with textures used by faces without texture coordinates gets a second copy
//!   without texture references for those faces (glTF forbids a texture the primitive has no
//!   coordinates for), with a warning.
//!
//! # Images
//!
//! Each distinct texture path becomes one image and one texture, all sharing one sampler
//! (`REPEAT` both ways). Paths are read as relative paths with `\` taken as `/` (Windows
//! exporters write `.\tex.jpg`); a path that is absolute, has a drive or scheme, or climbs out
//! with `..` keeps only its file name (warning). If the caller supplied the file (looked up as
//! written, as the cleaned path, then as the file name), it is embedded in the buffer with a
//! `mimeType` sniffed from its first bytes: PNG and JPEG as core glTF, WebP through
//! `EXT_texture_webp` (which is then required, as there is no fallback image). Anything else is
//! not embedded. Images that are not embedded keep a relative, percent-encoded `uri` and are
//! named in a warning. Images are never decoded.
//!
//! # Output
//!
//! Compact JSON with `asset`, `scene` 0, one scene of every node, and only non-empty arrays.
//! Buffer 0 has no `uri` and a `byteLength` equal to the (4-byte padded) binary buffer's
//! length: the caller decides between a GLB BIN chunk and a `data:` URI. Material members
//! equal to glTF's defaults are left out (except `metallicFactor`, and `roughnessFactor` of a
//! material from the MTL); every primitive states its `mode`; a primitive's attributes are
//! listed in the order above, which the tangent step keeps.
//!
//! # Phases
//!
//! [`obj_to_gltf`] plans the meshes, then the materials, then the images; lays out the buffer
//! and checks its size; writes it (attributes, indices, then images); builds the document as
//! `gltf-json`'s typed values; and writes that as JSON text. `gltf-json` is used here only
//! because tspace creates this document whole: it never reads input, and a user's glTF is
//! edited by `tspace-json`, byte for byte.
//!
//! Warnings here cover the conversion only; the OBJ and MTL readers' own are in
//! [`Obj::warnings`] and [`Mtl::warnings`]. Memory is proportional to the parsed OBJ (at most
//! three vertices per triangle) plus the embedded images, and the buffer's size is checked
//! against [`ConvertLimits`] before it is allocated.

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;

use super::gltf::glb;
use gltf_json as json;
use json::accessor::{ComponentType, GenericComponentType, Type};
use json::buffer::Target;
use json::extensions::material::{EmissiveStrength, EmissiveStrengthFactor};
use json::material::{
    AlphaMode, EmissiveFactor, NormalTexture, PbrBaseColorFactor, PbrMetallicRoughness,
    StrengthFactor,
};
use json::mesh::{Mode, Semantic};
use json::texture::WrappingMode;
use json::validation::{Checked, Checked::Valid, USize64};
use json::{Index, Root};
use serde_json::{Map, Value};

use super::gltf::created;
use super::obj::{Corner, FaceGroup, Material, Mtl, Obj, Texture};
use super::options::Normals;
use super::report::Notice;
use super::uri::PartSet;
use tspace_tangent::{CoreError, MeshInput, NormalMode, generate_normals};

/// glTF's `mode` for triangle lists, which every primitive here is.
const TRIANGLES: u32 = 4;

const TEXTURE_TRANSFORM: &str = "KHR_texture_transform";
const EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";
const TEXTURE_WEBP: &str = "EXT_texture_webp";

/// The most vertices a primitive may have for `u16` indices: its largest index is then 65534,
/// never 65535, which would be the primitive-restart value.
const MAX_U16_VERTICES: usize = 65535;

/// How many names a warning lists before it says how many more there are.
const NAMES_IN_WARNING: usize = 8;

/// Caps on the conversion's output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConvertLimits {
    /// The largest binary buffer (attributes, indices and embedded images) to build. The
    /// default is the largest multiple of 4 a GLB chunk length can hold.
    pub max_buffer_bytes: u64,
}

impl Default for ConvertLimits {
    fn default() -> Self {
        ConvertLimits {
            max_buffer_bytes: u64::from(u32::MAX) & !3,
        }
    }
}

/// What the conversion produced, in numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ConversionStats {
    /// Nodes, one mesh each.
    pub meshes: usize,
    pub primitives: usize,
    /// Vertices after deduplication, summed over the primitives.
    pub vertices: usize,
    pub triangles: usize,
    pub materials: usize,
    pub images_embedded: usize,
    /// Images written as a relative `uri`, because they were not supplied or not embeddable.
    pub images_referenced: usize,
}

/// A converted OBJ: a glTF 2.0 JSON document whose buffer 0 (without a `uri`) is `bin`.
#[derive(Clone, Debug, PartialEq)]
pub struct Converted {
    pub json: String,
    /// Buffer 0, padded with zeros to a multiple of 4 bytes.
    pub bin: Vec<u8>,
    /// What the conversion changed, dropped or could not find, one sentence each.
    pub notices: Vec<Notice>,
    pub stats: ConversionStats,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ConvertError {
    /// The OBJ has no faces (only points, lines, or nothing): there is no mesh to make.
    NoFaces,
    /// A corner refers past the end of one of the [`Obj`]'s arrays. [`super::obj::parse_obj`]
    /// never produces this; a hand-built [`Obj`] can.
    IndexOutOfRange {
        what: &'static str,
        index: u32,
        count: usize,
    },
    /// Every triangle has a NaN or infinite position, so none can be written.
    NoFiniteTriangles { triangles: usize },
    /// A count or size beyond what glTF (u32 lengths) or [`ConvertLimits`] allows.
    TooLarge {
        what: &'static str,
        value: u64,
        limit: u64,
    },
    /// Normals could not be generated for the triangles without them. Not expected (the core
    /// refuses only sizes, reported as [`ConvertError::TooLarge`]).
    Normals(String),
    /// The document could not be written as JSON. Not expected (every value written is finite
    /// and every key a string), so an error rather than a panic if it ever happens.
    Json(String),
}

impl fmt::Display for ConvertError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConvertError::NoFaces => write!(
                f,
                "the OBJ has no faces (f statements with 3 or more corners): nothing to convert"
            ),
            ConvertError::IndexOutOfRange { what, index, count } => write!(
                f,
                "a face refers to {what} {index} (counted from 0), but there are only {count}"
            ),
            ConvertError::NoFiniteTriangles { triangles: 1 } => write!(
                f,
                "the OBJ's only triangle has a NaN or infinite position: nothing can be drawn"
            ),
            ConvertError::NoFiniteTriangles { triangles } => write!(
                f,
                "every one of the OBJ's {triangles} triangles has a NaN or infinite position: \
                 nothing can be drawn"
            ),
            ConvertError::TooLarge { what, value, limit } => {
                write!(f, "{what} would be {value}, more than the limit of {limit}")
            }
            ConvertError::Normals(e) => {
                write!(
                    f,
                    "normals could not be generated for faces without vn: {e}"
                )
            }
            ConvertError::Json(e) => {
                write!(
                    f,
                    "the converted document could not be written as JSON: {e}"
                )
            }
        }
    }
}

impl std::error::Error for ConvertError {}

fn too_large(what: &'static str, value: impl TryInto<u64>, limit: u64) -> ConvertError {
    ConvertError::TooLarge {
        what,
        value: value.try_into().unwrap_or(u64::MAX),
        limit,
    }
}

fn to_u32(what: &'static str, value: usize) -> Result<u32, ConvertError> {
    u32::try_from(value).map_err(|_| too_large(what, value, u64::from(u32::MAX)))
}

// Planning the meshes.

/// Which primitive a triangle joins within its object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Signature<'o> {
    material: Option<&'o str>,
    uv: bool,
    normal: bool,
}

impl<'o> Signature<'o> {
    /// The primitive a triangle of `group` joins, by whether it keeps texture coordinates
    /// (every triangle has normals by then, its own or generated). Both of [`plan_mesh`]'s
    /// passes ask this, so that the triangles counted for a primitive are the ones it gets.
    fn of(group: &'o FaceGroup, uv: bool) -> Signature<'o> {
        Signature {
            material: group.material.as_deref(),
            uv,
            normal: true,
        }
    }
}

struct Primitive<'o> {
    signature: Signature<'o>,
    /// Unique corners, in order of first use: vertex `i` is `vertices[i]`.
    vertices: Vec<Corner>,
    indices: Vec<u32>,
}

struct Mesh<'o> {
    name: Option<&'o str>,
    primitives: Vec<Primitive<'o>>,
}

/// Builds a mesh's primitives, deduplicating corners per primitive.
struct MeshBuilder<'o, 'w> {
    name: Option<&'o str>,
    primitives: Vec<Primitive<'o>>,
    by_signature: HashMap<Signature<'o>, usize>,
    /// How many triangles each primitive will have, counted in [`plan_mesh`]'s first pass, so
    /// that its lists are made with room for them (see [`MeshBuilder::new`]).
    expected: HashMap<Signature<'o>, usize>,
    /// Which vertex each corner already has, across the mesh's primitives.
    welded: &'w mut CornerWeld,
}

/// Where each corner of a mesh became a vertex: for every position, the chain of vertices made
/// at it, in any primitive. Exporters give a position a handful of texture coordinates and
/// normals at most, so a lookup walks a short chain near the last one, where a hash map of
/// every corner missed the cache on most lookups and grew through a dozen rehashes (a sixth
/// of converting a million-triangle OBJ). A position with more than [`CHAIN_LIMIT`] vertices
/// (only a contrived file has one) keeps the rest in a hash map, so that no file makes the
/// lookups quadratic. One weld serves every object of a file in turn: its table is as long as
/// the file's positions, and only the places a mesh used are cleared after it.
struct CornerWeld {
    /// Per position, its latest vertex's entry, or [`NO_ENTRY`].
    heads: Vec<u32>,
    entries: Vec<WeldEntry>,
    /// Vertices beyond a full chain, by primitive and [`corner_key`].
    overflow: HashMap<(usize, u128), u32, SeededFold>,
}

struct WeldEntry {
    corner: Corner,
    primitive: u32,
    vertex: u32,
    /// The entry made before it at the same position, or [`NO_ENTRY`].
    next: u32,
}

const NO_ENTRY: u32 = u32::MAX;

/// The longest chain of vertices a position keeps (see [`CornerWeld`]).
const CHAIN_LIMIT: usize = 32;

impl CornerWeld {
    fn new(position_count: usize) -> CornerWeld {
        CornerWeld {
            heads: vec![NO_ENTRY; position_count],
            entries: Vec::new(),
            overflow: HashMap::with_hasher(SeededFold::new()),
        }
    }

    /// The vertex of `corner` in primitive `slot`, if it has one already, or else `new_vertex`,
    /// which it then becomes. `None` for a corner whose position has no place in the table.
    fn vertex(&mut self, slot: usize, corner: Corner, new_vertex: u32) -> Option<(u32, bool)> {
        let position = corner.position as usize;
        let head = *self.heads.get(position)?;
        let mut at = head;
        let mut walked = 0;
        while at != NO_ENTRY && walked < CHAIN_LIMIT {
            let entry = self.entries.get(at as usize)?;
            if entry.corner == corner && entry.primitive as usize == slot {
                return Some((entry.vertex, false));
            }
            at = entry.next;
            walked += 1;
        }
        if walked == CHAIN_LIMIT {
            return Some(match self.overflow.entry((slot, corner_key(&corner))) {
                Entry::Occupied(known) => (*known.get(), false),
                Entry::Vacant(new) => (*new.insert(new_vertex), true),
            });
        }
        // Entries are at most the corners of one mesh, which are counted in u32 elsewhere.
        let index = u32::try_from(self.entries.len()).ok()?;
        self.entries.push(WeldEntry {
            corner,
            primitive: u32::try_from(slot).ok()?,
            vertex: new_vertex,
            next: head,
        });
        self.heads[position] = index;
        Some((new_vertex, true))
    }

    /// Forgets the last mesh's vertices, clearing only the places it used.
    fn clear(&mut self) {
        for entry in self.entries.drain(..) {
            if let Some(head) = self.heads.get_mut(entry.corner.position as usize) {
                *head = NO_ENTRY;
            }
        }
        self.overflow.clear();
    }
}

/// A corner's three indices in one integer, each in bits of its own (absent ones as 0, present
/// ones plus one, in 33 bits), so that looking it up hashes one value instead of five fields.
fn corner_key(corner: &Corner) -> u128 {
    let present = |index: Option<u32>| index.map_or(0, |i| u128::from(i) + 1);
    u128::from(corner.position) | present(corner.uv()) << 32 | present(corner.normal()) << 65
}

/// The hash of the corner maps: one folded 128-bit multiplication of the key with a secret
/// seed (foldhash's step). The standard SipHash was a tenth of the time of converting a
/// million-triangle OBJ. The seed comes from the standard library's per-process random keys,
/// so a file cannot be made of corners that all collide, which a fixed hash would allow.
#[derive(Clone)]
struct SeededFold([u64; 2]);

impl SeededFold {
    fn new() -> SeededFold {
        use std::hash::{BuildHasher, Hasher};
        let mut seeds = std::collections::hash_map::RandomState::new().build_hasher();
        seeds.write_u8(1);
        let first = seeds.finish();
        seeds.write_u8(2);
        SeededFold([first, seeds.finish()])
    }
}

impl std::hash::BuildHasher for SeededFold {
    type Hasher = FoldHasher;

    fn build_hasher(&self) -> FoldHasher {
        FoldHasher {
            seeds: self.0,
            hash: 0,
        }
    }
}

struct FoldHasher {
    seeds: [u64; 2],
    hash: u64,
}

impl FoldHasher {
    fn fold(a: u64, b: u64) -> u64 {
        let product = u128::from(a) * u128::from(b);
        product as u64 ^ (product >> 64) as u64
    }
}

impl std::hash::Hasher for FoldHasher {
    fn write_u128(&mut self, key: u128) {
        let [low, high] = [key as u64, (key >> 64) as u64];
        self.hash = Self::fold(low ^ self.seeds[0], high ^ self.seeds[1] ^ self.hash);
    }

    /// Any other input, a byte at a time (the corner maps hash only `u128`s).
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u128(u128::from(b));
        }
    }

    fn finish(&self) -> u64 {
        self.hash
    }
}

impl<'o, 'w> MeshBuilder<'o, 'w> {
    /// A builder for a mesh whose primitives will have `expected` triangles. Each primitive's
    /// indices are made with room for all of its corners, and its vertices (and the weld's
    /// entries) for one a triangle: a smooth mesh has about half that, a faceted one up to
    /// three times. Grown from nothing, these lists were copied and faulted in again at every
    /// doubling: on the 1M-triangle sphere of `whole_path`, a fifth of the process's page
    /// faults (see docs/benchmarks.md). Room never touched costs no memory.
    fn new(
        name: Option<&'o str>,
        welded: &'w mut CornerWeld,
        expected: HashMap<Signature<'o>, usize>,
    ) -> Self {
        welded.clear();
        welded.entries.reserve(expected.values().sum());
        MeshBuilder {
            name,
            primitives: Vec::new(),
            by_signature: HashMap::new(),
            expected,
            welded,
        }
    }

    fn add(&mut self, signature: Signature<'o>, triangle: [Corner; 3]) -> Result<(), ConvertError> {
        // Consecutive triangles nearly always join the same primitive: asked first, that spares
        // hashing the material's name for every triangle.
        let last = self.primitives.len().checked_sub(1);
        let slot = match last.filter(|&l| self.primitives[l].signature == signature) {
            Some(last) => last,
            None => *self.by_signature.entry(signature).or_insert_with(|| {
                let triangles = self.expected.get(&signature).copied().unwrap_or(0);
                self.primitives.push(Primitive {
                    signature,
                    vertices: Vec::with_capacity(triangles),
                    indices: Vec::with_capacity(3 * triangles),
                });
                self.primitives.len() - 1
            }),
        };
        let Some(primitive) = self.primitives.get_mut(slot) else {
            return Ok(()); // Unreachable: `slot` was found or made above.
        };
        // By reference: iterated by value, the array was copied into the iterator a field at a
        // time and read back in wider loads, which waited for those stores (in a profile, the
        // samples of planning the meshes that sat on such a load went from 24% to 17%: the
        // rest wait on the triangle's own corners, made a field at a time in `plan_mesh`).
        for &corner in &triangle {
            let next = to_u32(
                "the vertex count of one primitive",
                primitive.vertices.len(),
            )?;
            let (index, new) =
                self.welded
                    .vertex(slot, corner, next)
                    .ok_or(ConvertError::IndexOutOfRange {
                        what: "position",
                        index: corner.position,
                        count: self.welded.heads.len(),
                    })?;
            if new {
                primitive.vertices.push(corner);
            }
            primitive.indices.push(index);
        }
        Ok(())
    }

    fn finish(self) -> Mesh<'o> {
        Mesh {
            name: self.name,
            primitives: self.primitives,
        }
    }
}

fn check_index(what: &'static str, index: Option<u32>, count: usize) -> Result<(), ConvertError> {
    match index {
        Some(i) if i as usize >= count => Err(ConvertError::IndexOutOfRange {
            what,
            index: i,
            count,
        }),
        _ => Ok(()),
    }
}

/// What [`plan_meshes`] dropped, in triangles.
#[derive(Default)]
struct Dropped {
    /// UVs or normals on some corners only (the OBJ reader never produces these).
    partial: usize,
    /// Normals of zero length or not finite on some corner.
    normals: usize,
    /// Texture coordinates not finite on some corner.
    uvs: usize,
    /// A position not finite on some corner: the whole triangle.
    positions: usize,
}

/// Whether every corner of `triangle` (whose indices [`check_corners`] has checked) has a
/// finite position.
fn finite_positions(obj: &Obj, triangle: &[Corner; 3]) -> bool {
    triangle.iter().all(|c| {
        obj.positions
            .get(c.position as usize)
            .is_some_and(|p| p.iter().all(|v| v.is_finite()))
    })
}

/// Whether a normal can be scaled to unit length.
fn usable_normal(n: [f32; 3]) -> bool {
    let v = n.map(f64::from);
    let length_squared = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    length_squared.is_finite() && length_squared > 0.0
}

/// Checks that every corner of `triangle` refers to values the OBJ has.
fn check_corners(obj: &Obj, triangle: &[Corner; 3]) -> Result<(), ConvertError> {
    for c in triangle {
        check_index("position", Some(c.position), obj.positions.len())?;
        check_index("texture coordinate", c.uv(), obj.uvs.len())?;
        check_index("normal", c.normal(), obj.normals.len())?;
        if let Some(colors) = &obj.colors {
            check_index("vertex colour", Some(c.position), colors.len())?;
        }
    }
    Ok(())
}

/// What a triangle keeps: whether its positions are finite (a triangle that is not is
/// dropped), and which of texture coordinates and normals it keeps, those present on all three
/// corners and usable (finite, and for normals of non-zero length); and what it drops, for
/// [`Dropped`]. Found once, in [`plan_mesh`]'s first pass, and read again in its second (a
/// byte a triangle), where finding it twice read every corner's values twice.
#[derive(Clone, Copy)]
struct Usable(u8);

impl Usable {
    const FINITE: u8 = 1;
    const UV: u8 = 2;
    const NORMAL: u8 = 4;
    const PARTIAL: u8 = 8;
    const UV_DROPPED: u8 = 16;
    const NORMAL_DROPPED: u8 = 32;

    fn of(obj: &Obj, triangle: &[Corner; 3]) -> Usable {
        if !finite_positions(obj, triangle) {
            return Usable(0);
        }
        let uvs = triangle.iter().filter(|c| c.uv().is_some()).count();
        let normals = triangle.iter().filter(|c| c.normal().is_some()).count();
        let mut flags = Self::FINITE;
        if uvs % 3 != 0 || normals % 3 != 0 {
            flags |= Self::PARTIAL;
        }
        let finite_uv = |c: &Corner| {
            c.uv()
                .and_then(|i| obj.uvs.get(i as usize))
                .is_some_and(|uv| uv.iter().all(|v| v.is_finite()))
        };
        let usable = |c: &Corner| {
            c.normal()
                .and_then(|i| obj.normals.get(i as usize))
                .is_some_and(|&n| usable_normal(n))
        };
        if uvs == 3 {
            flags |= if triangle.iter().all(finite_uv) {
                Self::UV
            } else {
                Self::UV_DROPPED
            };
        }
        if normals == 3 {
            flags |= if triangle.iter().all(usable) {
                Self::NORMAL
            } else {
                Self::NORMAL_DROPPED
            };
        }
        Usable(flags)
    }

    fn finite(self) -> bool {
        self.0 & Self::FINITE != 0
    }

    fn uv(self) -> bool {
        self.0 & Self::UV != 0
    }

    fn normal(self) -> bool {
        self.0 & Self::NORMAL != 0
    }

    /// Counts what a finite triangle drops.
    fn count(self, dropped: &mut Dropped) {
        let has = |flag: u8| usize::from(self.0 & flag != 0);
        dropped.partial += has(Self::PARTIAL);
        dropped.uvs += has(Self::UV_DROPPED);
        dropped.normals += has(Self::NORMAL_DROPPED);
    }

    /// `triangle` with only the attributes it keeps.
    fn keep(self, triangle: &[Corner; 3]) -> [Corner; 3] {
        triangle.map(|c| {
            c.with_uv(c.uv().filter(|_| self.uv()))
                .with_normal(c.normal().filter(|_| self.normal()))
        })
    }
}

/// Splits the OBJ's face groups into meshes and primitives, dropping from each triangle an
/// attribute that is missing or unusable on any of its corners, and giving normals to the
/// triangles left without (see the module documentation).
fn plan_meshes(
    obj: &Obj,
    request: NormalRequest,
) -> Result<(Vec<Mesh<'_>>, Dropped, GeneratedNormals), ConvertError> {
    let mut dropped = Dropped::default();
    let mut generated = GeneratedNormals::default();
    let mut welded = CornerWeld::new(obj.positions.len());
    let mut meshes = Vec::new();
    for (name, groups) in objects(obj) {
        meshes.push(plan_mesh(
            obj,
            name,
            &groups,
            request,
            &mut dropped,
            &mut generated,
            &mut welded,
        )?);
    }
    if meshes.is_empty() {
        return Err(ConvertError::NoFaces);
    }
    // An object whose every triangle was dropped has no mesh to write.
    meshes.retain(|m| !m.primitives.is_empty());
    if meshes.is_empty() {
        return Err(ConvertError::NoFiniteTriangles {
            triangles: dropped.positions,
        });
    }
    Ok((meshes, dropped, generated))
}

/// The OBJ's face groups that have faces, gathered by object in file order. A new `o` name
/// starts a new object, even one an earlier object had.
fn objects(obj: &Obj) -> Vec<(Option<&str>, Vec<&FaceGroup>)> {
    let mut objects: Vec<(Option<&str>, Vec<&FaceGroup>)> = Vec::new();
    for group in obj.groups.iter().filter(|g| !g.triangles.is_empty()) {
        let object = group.object.as_deref();
        match objects.last_mut() {
            Some((name, groups)) if *name == object => groups.push(group),
            _ => objects.push((object, vec![group])),
        }
    }
    objects
}

/// One object's mesh, in two passes over its faces, so that nothing per triangle is kept
/// between them but what each keeps ([`Usable`], a byte) and the generated normals' numbers:
/// the triangles left without normals get them, all at once, then every triangle joins its
/// primitive.
fn plan_mesh<'o>(
    obj: &'o Obj,
    name: Option<&'o str>,
    groups: &[&'o FaceGroup],
    request: NormalRequest,
    dropped: &mut Dropped,
    generated: &mut GeneratedNormals,
    welded: &mut CornerWeld,
) -> Result<Mesh<'o>, ConvertError> {
    let triangles = || {
        groups
            .iter()
            .flat_map(|g| g.triangles.iter().map(move |triangle| (*g, triangle)))
    };
    let mut without_normals = Vec::new();
    let mut usable = Vec::with_capacity(groups.iter().map(|g| g.triangles.len()).sum());
    // Each primitive's triangles, counted by group (a hash per group, not per triangle).
    let mut expected: HashMap<Signature<'o>, usize> = HashMap::new();
    for group in groups {
        let mut with_uv = [0usize; 2];
        for (t, triangle) in group.triangles.iter().enumerate() {
            check_corners(obj, triangle)?;
            let kept = Usable::of(obj, triangle);
            usable.push(kept);
            // A triangle whose positions are not finite is dropped, and counted, in the
            // second pass.
            if kept.finite() {
                with_uv[usize::from(kept.uv())] += 1;
                if !kept.normal() {
                    let smoothing = group.smoothing.get(t).copied().unwrap_or(0);
                    without_normals.push((kept.keep(triangle), smoothing));
                }
            }
        }
        for (uv, count) in [(false, with_uv[0]), (true, with_uv[1])] {
            if count > 0 {
                *expected.entry(Signature::of(group, uv)).or_default() += count;
            }
        }
    }
    let mut made = generate_missing_normals(obj, &without_normals, request, generated)?.into_iter();
    drop(without_normals);
    let mut builder = MeshBuilder::new(name, welded, expected);
    for ((group, triangle), &kept) in triangles().zip(&usable) {
        if !kept.finite() {
            dropped.positions += 1;
            continue;
        }
        kept.count(dropped);
        let mut triangle = kept.keep(triangle);
        if !kept.normal() {
            for corner in &mut triangle {
                *corner = corner.with_normal(made.next());
            }
        }
        builder.add(Signature::of(group, kept.uv()), triangle)?;
    }
    Ok(builder.finish())
}

/// How normals are made for the triangles of an OBJ without (usable) `vn`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalRequest {
    pub normals: Normals,
    /// The crease angle, in degrees, where normals are smoothed by angle.
    pub crease_degrees: f32,
}

impl Default for NormalRequest {
    fn default() -> Self {
        NormalRequest {
            normals: Normals::Auto,
            crease_degrees: DEFAULT_CREASE_DEGREES,
        }
    }
}

/// The crease angle of `normals=auto` and `normals=smooth` when none is given: edges sharper
/// than this stay hard. Between the 30° of Blender's auto smooth and the 89° some renderers
/// suggest: a cube stays a cube, a 6-sided cylinder's sides (60° apart) stay flat, anything
/// rounder is smooth.
pub const DEFAULT_CREASE_DEGREES: f32 = 60.0;

impl NormalRequest {
    /// The core's mode, and whether the OBJ's smoothing groups bound the smoothing.
    fn mode(self, smoothing_declared: bool) -> (NormalMode, bool) {
        let by_angle = NormalMode::SmoothByAngle {
            crease_degrees: self.crease_degrees,
        };
        match self.normals {
            Normals::Flat => (NormalMode::Flat, false),
            Normals::Smooth => (by_angle, false),
            // Within a smoothing group every edge is smooth, as in 3ds Max, Maya and Blender.
            Normals::Auto if smoothing_declared => (
                NormalMode::SmoothByAngle {
                    crease_degrees: 180.0,
                },
                true,
            ),
            Normals::Auto => (by_angle, false),
        }
    }
}

/// The normals made for triangles without `vn`, numbered after the OBJ's own.
#[derive(Default)]
struct GeneratedNormals {
    normals: Vec<[f32; 3]>,
    triangles: usize,
}

impl GeneratedNormals {
    /// The one sentence that says which normals were made and how to choose others.
    fn warn(&self, request: NormalRequest, smoothing_declared: bool, warnings: &mut Vec<Notice>) {
        if self.triangles == 0 {
            return;
        }
        let angle = request.crease_degrees;
        let how = match request.normals {
            Normals::Flat => "flat (faceted), as normals=flat asks".to_owned(),
            Normals::Smooth => format!(
                "smooth, with edges sharper than {angle}° kept hard, as normals=smooth asks \
                 (smoothing groups ignored)"
            ),
            Normals::Auto if smoothing_declared => "smooth within the OBJ's smoothing groups \
                 (s), flat where s is off; normals=smooth to smooth by angle instead, \
                 normals=flat for faceted"
                .to_owned(),
            Normals::Auto => format!(
                "smooth, with edges sharper than {angle}° kept hard (the OBJ has no smoothing \
                 groups); normals=flat for faceted, normals_angle to change the angle"
            ),
        };
        warnings.push(Notice::new(
            "normals_generated",
            format!(
                "normals generated for {} triangles without vn: {how}",
                self.triangles
            ),
        ));
    }
}

/// Generates normals for an object's triangles without (given with their smoothing group), all
/// in one call so that smoothing crosses primitives (materials) as it does in the modeller;
/// numbers them after the OBJ's `vn` and those made before, so that corners refer to them as
/// to any other normal; and returns each corner's number, triangle by triangle.
fn generate_missing_normals(
    obj: &Obj,
    triangles: &[([Corner; 3], u32)],
    request: NormalRequest,
    generated: &mut GeneratedNormals,
) -> Result<Vec<u32>, ConvertError> {
    if triangles.is_empty() {
        return Ok(Vec::new());
    }
    // Only the positions these triangles use, so that each object's work is its own size.
    let mut local_of: HashMap<u32, u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut indices = Vec::with_capacity(3 * triangles.len());
    for (triangle, _) in triangles {
        for c in triangle {
            let next = to_u32("the positions of one object", positions.len())?;
            let local = *local_of.entry(c.position).or_insert_with(|| {
                let p = obj.positions.get(c.position as usize);
                positions.push(p.copied().unwrap_or_default());
                next
            });
            indices.push(local);
        }
    }
    drop(local_of);
    let (mode, grouped) = request.mode(obj.smoothing_declared);
    let groups: Vec<u32> = triangles.iter().map(|(_, group)| *group).collect();
    let input = MeshInput {
        positions: &positions,
        normals: None,
        uvs: None,
        indices: Some(&indices),
    };
    let made =
        generate_normals(&input, mode, grouped.then_some(&groups[..])).map_err(|e| match e {
            CoreError::TooLarge { count } => too_large(
                "the corners without normals in one object",
                count,
                u64::from(u32::MAX / 2),
            ),
            other => ConvertError::Normals(other.to_string()),
        })?;
    let first = obj.normals.len() + generated.normals.len();
    to_u32("the number of normals", first + made.normals.len())?;
    generated.normals.extend(made.normals);
    generated.triangles += triangles.len();
    // In range: checked just above.
    Ok(made
        .indices
        .iter()
        .map(|&i| (first + i as usize) as u32)
        .collect())
}

// Planning the materials and images.

/// A material as written to the document.
struct MaterialPlan<'m> {
    name: &'m str,
    /// `None` for a `usemtl` name the MTL lacks.
    source: Option<&'m Material>,
    /// Whether texture references are written (false for the copy used by faces without UVs).
    textured: bool,
}

fn has_textures(m: &Material) -> bool {
    m.diffuse_map.is_some() || m.normal_map.is_some() || m.bump_map.is_some()
}

/// The texture `normalTexture` comes from: `norm`, else `map_Bump`/`bump`.
fn normal_source(m: &Material) -> Option<&Texture> {
    m.normal_map.as_ref().or(m.bump_map.as_ref())
}

/// `names` as a list for a warning: the first few quoted, then how many more.
fn name_list(names: &[String]) -> String {
    let quoted: Vec<String> = names
        .iter()
        .take(NAMES_IN_WARNING)
        .map(|n| format!("{n:?}"))
        .collect();
    item_list(&quoted, names.len())
}

/// The first few of `items` (of `total`), then how many more.
fn item_list(items: &[String], total: usize) -> String {
    let shown = items.len().min(NAMES_IN_WARNING);
    let mut out = items.get(..shown).unwrap_or_default().join(", ");
    if total > shown {
        out += &format!(" and {} more", total - shown);
    }
    out
}

/// A texture path read as a relative path: `\` taken as `/`, empty and `.` segments dropped.
/// When the path is absolute, has a drive or scheme, or has a `..` segment, only its file name
/// is kept (`reduced`). `None` when there is no file name at all.
struct CleanPath {
    path: String,
    file_name: String,
    reduced: bool,
}

fn clean_path(path: &str) -> Option<CleanPath> {
    let slashed = path.replace('\\', "/");
    if slashed.ends_with('/') {
        return None;
    }
    let segments: Vec<&str> = slashed
        .split('/')
        .filter(|s| !s.is_empty() && *s != ".")
        .collect();
    let last = *segments.last()?;
    if last == ".." {
        return None;
    }
    // A colon means a drive (`C:`) or a scheme (`file:`); the name is what follows the last one.
    let file_name = last.rsplit(':').next().unwrap_or(last);
    if file_name.is_empty() {
        return None;
    }
    let reduced = slashed.starts_with('/') || slashed.contains(':') || segments.contains(&"..");
    let path = if reduced {
        file_name.to_owned()
    } else {
        segments.join("/")
    };
    Some(CleanPath {
        path,
        file_name: file_name.to_owned(),
        reduced,
    })
}

/// `path` as a URI reference: every byte except RFC 3986's unreserved characters and `/`
/// percent-encoded (so spaces, `%`, `:`, `#`, `?` and non-ASCII are all escaped).
fn percent_encode_path(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    for &b in path.as_bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~' | b'/') {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ImageFormat {
    Png,
    Jpeg,
    Webp,
}

impl ImageFormat {
    fn sniff(bytes: &[u8]) -> Option<Self> {
        if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(ImageFormat::Png)
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Some(ImageFormat::Jpeg)
        } else if bytes.len() >= 12
            && bytes.starts_with(b"RIFF")
            && bytes.get(8..12) == Some(b"WEBP")
        {
            Some(ImageFormat::Webp)
        } else {
            None
        }
    }

    fn mime(self) -> &'static str {
        match self {
            ImageFormat::Png => "image/png",
            ImageFormat::Jpeg => "image/jpeg",
            ImageFormat::Webp => "image/webp",
        }
    }
}

struct ImagePlan<'p> {
    /// The file name, as the image's `name`.
    name: String,
    /// The relative path, for the `uri` when the image is not embedded.
    path: String,
    embedded: Option<(&'p [u8], ImageFormat)>,
}

/// The images and textures (one per image) the used materials need.
#[derive(Default)]
struct ImageTable<'p> {
    images: Vec<ImagePlan<'p>>,
    by_path: HashMap<String, usize>,
    /// Texture paths that had no file name at all (and the same as a set).
    unusable: Vec<String>,
    unusable_seen: HashSet<String>,
    /// Texture paths reduced to their file name.
    reduced: Vec<String>,
    /// Images not supplied.
    missing: Vec<String>,
    /// Images supplied in a format glTF cannot embed.
    unknown_format: Vec<String>,
}

impl<'p> ImageTable<'p> {
    /// The texture (and image) index for `texture`, adding it on first use; `None` when the
    /// path names no file.
    fn texture(&mut self, texture: &Texture, parts: &PartSet<'p>) -> Option<usize> {
        let Some(clean) = clean_path(&texture.path) else {
            if self.unusable_seen.insert(texture.path.clone()) {
                self.unusable.push(texture.path.clone());
            }
            return None;
        };
        if let Some(&index) = self.by_path.get(&clean.path) {
            return Some(index);
        }
        if clean.reduced {
            self.reduced.push(texture.path.clone());
        }
        let mut candidates = vec![texture.path.as_str(), clean.path.as_str()];
        candidates.push(clean.file_name.as_str());
        let bytes = candidates.iter().find_map(|c| parts.get(c).ok());
        let embedded = match bytes {
            None => {
                self.missing.push(clean.path.clone());
                None
            }
            Some(bytes) => match ImageFormat::sniff(bytes) {
                Some(format) => Some((bytes, format)),
                None => {
                    self.unknown_format.push(clean.path.clone());
                    None
                }
            },
        };
        let index = self.images.len();
        self.images.push(ImagePlan {
            name: clean.file_name,
            path: clean.path.clone(),
            embedded,
        });
        self.by_path.insert(clean.path, index);
        Some(index)
    }

    /// Warns about the paths that could not be used as they were written, and the images
    /// that could not be embedded.
    fn warn(&self, warnings: &mut Vec<Notice>) {
        if !self.reduced.is_empty() {
            warnings.push(Notice::new("texture_paths_reduced", format!(
                "texture paths that are absolute or climb out of their folder, kept as their file \
             name only: {}",
                name_list(&self.reduced)
            )));
        }
        if !self.unusable.is_empty() {
            warnings.push(Notice::new(
                "texture_paths_unusable",
                format!(
                    "texture paths without a file name, ignored: {}",
                    name_list(&self.unusable)
                ),
            ));
        }
        if !self.missing.is_empty() {
            warnings.push(Notice::new("textures_not_supplied", format!(
                "texture files not supplied, referenced by relative URI instead of embedded: {}",
                name_list(&self.missing)
            )));
        }
        if !self.unknown_format.is_empty() {
            warnings.push(Notice::new(
                "textures_not_embeddable",
                format!(
                    "texture files that are not PNG, JPEG or WebP, which glTF cannot embed; \
             referenced by relative URI: {}",
                    name_list(&self.unknown_format)
                ),
            ));
        }
    }
}

/// A `KHR_texture_transform` (rotation 0, texture coordinate set 0).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Transform {
    offset: [f32; 2],
    scale: [f32; 2],
}

/// A texture reference as written: the texture index and the `KHR_texture_transform`, if any.
struct TextureRef {
    index: usize,
    transform: Option<Transform>,
}

/// glTF's `(offset, scale)` for an OBJ texture's `-o` and `-s` (see the module documentation),
/// or `None` when they are absent, the identity, or not finite (`Err`).
fn texture_transform(t: &Texture) -> Result<Option<Transform>, ()> {
    if t.offset.is_none() && t.scale.is_none() {
        return Ok(None);
    }
    let [ou, ov, _] = t.offset.unwrap_or([0.0; 3]);
    let [su, sv, _] = t.scale.unwrap_or([1.0; 3]);
    let offset = [ou, 1.0 - ov - sv];
    let scale = [su, sv];
    if offset.iter().chain(&scale).any(|v| !v.is_finite()) {
        return Err(());
    }
    if offset == [0.0, 0.0] && scale == [1.0, 1.0] {
        return Ok(None);
    }
    Ok(Some(Transform { offset, scale }))
}

/// Material values as glTF wants them, plus whether anything had to be clamped or replaced.
struct Pbr {
    base_color: [f32; 4],
    metallic: f32,
    roughness: f32,
    emissive: [f32; 3],
    emissive_strength: Option<f32>,
    blend: bool,
    adjusted: bool,
}

/// Clamps to [0, 1]; a non-finite value becomes `default`. Sets `adjusted` on any change.
fn unit(v: f32, default: f32, adjusted: &mut bool) -> f32 {
    let out = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        default
    };
    if out.to_bits() != v.to_bits() {
        *adjusted = true;
    }
    out
}

/// `roughness = (2 / (Ns + 2))^(1/4)`; see the module documentation.
fn roughness_from_shininess(ns: f32) -> f32 {
    let ns = f64::from(ns.max(0.0));
    (2.0 / (ns + 2.0)).sqrt().sqrt() as f32
}

fn pbr(m: &Material) -> Pbr {
    let mut adjusted = false;
    let [r, g, b] = m.diffuse.unwrap_or([1.0; 3]);
    let alpha = unit(m.dissolve.unwrap_or(1.0), 1.0, &mut adjusted);
    let base_color = [
        unit(r, 1.0, &mut adjusted),
        unit(g, 1.0, &mut adjusted),
        unit(b, 1.0, &mut adjusted),
        alpha,
    ];
    let metallic = unit(m.metallic.unwrap_or(0.0), 0.0, &mut adjusted);
    let black_specular = m.specular.is_some_and(|s| s.iter().all(|&c| c == 0.0));
    let derived = match m.shininess {
        _ if black_specular => 1.0,
        Some(ns) if ns.is_finite() => roughness_from_shininess(ns),
        Some(_) => {
            adjusted = true;
            1.0
        }
        None => 1.0,
    };
    let roughness = unit(m.roughness.unwrap_or(derived), 1.0, &mut adjusted);
    let mut emissive = [0.0; 3];
    let mut emissive_strength = None;
    if let Some(ke) = m.emissive {
        if ke.iter().all(|c| c.is_finite()) {
            let ke = ke.map(|c| {
                if c < 0.0 {
                    adjusted = true;
                }
                c.max(0.0)
            });
            let peak = ke.iter().copied().fold(0.0f32, f32::max);
            if peak > 1.0 {
                emissive = ke.map(|c| (c / peak).min(1.0));
                emissive_strength = Some(peak);
            } else {
                emissive = ke;
            }
        } else {
            adjusted = true;
        }
    }
    Pbr {
        base_color,
        metallic,
        roughness,
        emissive,
        emissive_strength,
        blend: alpha < 1.0,
        adjusted,
    }
}

impl Dropped {
    fn warn(&self, warnings: &mut Vec<Notice>) {
        if self.positions > 0 {
            warnings.push(Notice::new(
                "non_finite_positions",
                format!(
                    "{} triangles have a NaN or infinite position and were dropped: they cannot \
                     be drawn, and glTF does not allow non-finite values",
                    self.positions
                ),
            ));
        }
        if self.partial > 0 {
            warnings.push(Notice::new(
                "obj_faces_repaired",
                format!(
                    "{} triangles had texture coordinates or normals on some corners only; those \
                 attributes were dropped from them",
                    self.partial
                ),
            ));
        }
        if self.normals > 0 {
            warnings.push(Notice::new(
                "invalid_normals_dropped",
                format!(
                    "{} triangles use a normal of zero length or not finite, which glTF does not \
                     allow; they were given generated normals, as faces without vn are",
                    self.normals
                ),
            ));
        }
        if self.uvs > 0 {
            warnings.push(Notice::new("invalid_texcoords_dropped", format!(
                "{} triangles use a texture coordinate that is NaN or infinite; they were written \
                 without texture coordinates",
                self.uvs
            )));
        }
    }
}

/// The materials to write, in order of first use, and each primitive's material (per mesh).
struct MaterialTable<'a> {
    materials: Vec<MaterialPlan<'a>>,
    per_primitive: Vec<Vec<Option<usize>>>,
}

fn plan_materials<'a>(
    meshes: &[Mesh<'a>],
    mtl: Option<&'a Mtl>,
    warnings: &mut Vec<Notice>,
) -> MaterialTable<'a> {
    let mut materials: Vec<MaterialPlan<'_>> = Vec::new();
    let mut material_slots: HashMap<(&str, bool), usize> = HashMap::new();
    let mut primitive_materials: Vec<Vec<Option<usize>>> = Vec::new();
    let mut missing_materials: Vec<String> = Vec::new();
    let mut untextured_copies: Vec<String> = Vec::new();
    let mut unnamed_without_mtl = false;
    for mesh in meshes {
        let mut slots = Vec::with_capacity(mesh.primitives.len());
        for primitive in &mesh.primitives {
            let (Some(name), Some(mtl)) = (primitive.signature.material, mtl) else {
                unnamed_without_mtl |= primitive.signature.material.is_some();
                slots.push(None);
                continue;
            };
            let source = mtl.get(name);
            let textured = source.is_some_and(has_textures) && primitive.signature.uv;
            let stripped = source.is_some_and(has_textures) && !primitive.signature.uv;
            let slot = *material_slots.entry((name, textured)).or_insert_with(|| {
                if source.is_none() {
                    missing_materials.push(name.to_owned());
                }
                if stripped {
                    untextured_copies.push(name.to_owned());
                }
                materials.push(MaterialPlan {
                    name,
                    source,
                    textured,
                });
                materials.len() - 1
            });
            slots.push(Some(slot));
        }
        primitive_materials.push(slots);
    }
    if unnamed_without_mtl {
        warnings.push(Notice::new(
            "materials_not_written",
            "the OBJ uses materials (usemtl) but no MTL was given: no materials were written"
                .to_owned(),
        ));
    }
    if !missing_materials.is_empty() {
        warnings.push(Notice::new(
            "materials_missing",
            format!(
                "materials not in the MTL, each given a plain white material of its name: {}",
                name_list(&missing_materials)
            ),
        ));
    }
    if !untextured_copies.is_empty() {
        warnings.push(Notice::new(
            "untextured_material_copies",
            format!(
                "materials with textures used by faces without texture coordinates; those faces \
             got a copy without textures: {}",
                name_list(&untextured_copies)
            ),
        ));
    }
    MaterialTable {
        materials,
        per_primitive: primitive_materials,
    }
}

/// A material's texture references.
struct MaterialTextures {
    base_color: Option<TextureRef>,
    normal: Option<TextureRef>,
}

/// The images and textures of the used materials, and each material's references to them.
/// Also warns about the maps glTF's core material has no place for.
fn plan_textures<'p>(
    materials: &[MaterialPlan<'_>],
    images: &PartSet<'p>,
    warnings: &mut Vec<Notice>,
) -> (ImageTable<'p>, Vec<MaterialTextures>) {
    let mut table = ImageTable::default();
    let mut material_textures = Vec::with_capacity(materials.len());
    let mut bad_transforms = Vec::new();
    let mut unconverted_maps = Vec::new();
    for plan in materials {
        let mut refs = MaterialTextures {
            base_color: None,
            normal: None,
        };
        if let Some(m) = plan.source {
            if plan.textured {
                let mut reference = |t: &Texture| {
                    let index = table.texture(t, images)?;
                    let transform = texture_transform(t).unwrap_or_else(|()| {
                        bad_transforms.push(t.path.clone());
                        None
                    });
                    Some(TextureRef { index, transform })
                };
                refs.base_color = m.diffuse_map.as_ref().and_then(&mut reference);
                refs.normal = normal_source(m).and_then(&mut reference);
            }
            for (what, map) in [("map_d", &m.dissolve_map), ("map_Ks", &m.specular_map)] {
                if let Some(t) = map {
                    unconverted_maps.push(format!("{what} {:?} of material {:?}", t.path, m.name));
                }
            }
        }
        material_textures.push(refs);
    }
    table.warn(warnings);
    if !bad_transforms.is_empty() {
        warnings.push(Notice::new(
            "texture_transforms_dropped",
            format!(
                "textures with a non-finite -o or -s, written without a transform: {}",
                name_list(&bad_transforms)
            ),
        ));
    }
    if !unconverted_maps.is_empty() {
        warnings.push(Notice::new(
            "texture_maps_not_converted",
            format!(
                "texture maps glTF's core material has no place for, not converted: {}",
                item_list(&unconverted_maps, unconverted_maps.len())
            ),
        ));
    }
    (table, material_textures)
}

// Laying out the buffer.

/// Bytes each vertex of `signature` takes in the buffer.
fn vertex_bytes(signature: &Signature<'_>, colors: bool) -> u64 {
    12 + 12 * u64::from(signature.normal) + 8 * u64::from(signature.uv) + 12 * u64::from(colors)
}

/// Whether a primitive of `vertices` vertices gets `u16` indices.
fn short_indices(vertices: usize) -> bool {
    vertices <= MAX_U16_VERTICES
}

/// The buffer's size in bytes: every primitive's attributes and padded indices, then the
/// embedded images. Saturating, so that no count can wrap it back under the limit.
fn buffer_size(meshes: &[Mesh<'_>], colors: bool, table: &ImageTable<'_>) -> u64 {
    let mut total: u64 = 0;
    for primitive in meshes.iter().flat_map(|m| &m.primitives) {
        let vertices = primitive.vertices.len() as u64;
        let index_size = if short_indices(primitive.vertices.len()) {
            2
        } else {
            4
        };
        let indices = primitive.indices.len() as u64;
        total = total
            .saturating_add(vertices.saturating_mul(vertex_bytes(&primitive.signature, colors)))
            .saturating_add(indices.saturating_mul(index_size).next_multiple_of(4));
    }
    for (bytes, _) in table.images.iter().filter_map(|i| i.embedded) {
        total = total.saturating_add((bytes.len() as u64).next_multiple_of(4));
    }
    total
}

/// An empty buffer with room for `total` bytes, once `total` is known to be within `limits`:
/// the size is checked before anything is allocated.
fn allocate_buffer(total: u64, limits: &ConvertLimits) -> Result<Bin, ConvertError> {
    const WHAT: &str = "the binary buffer's size in bytes";
    if total > limits.max_buffer_bytes {
        return Err(too_large(WHAT, total, limits.max_buffer_bytes));
    }
    let capacity = usize::try_from(total).map_err(|_| too_large(WHAT, total, usize::MAX as u64))?;
    Ok(Bin {
        // With room for the rest of the GLB it becomes (see `glb::write_around_bin`).
        bytes: Vec::with_capacity(capacity.saturating_add(glb::GLB_HEADROOM)),
        views: Vec::new(),
    })
}

// Writing the buffer.

/// `i` as a glTF index, which is a u32: a document cannot list more objects than that.
fn gltf_index<T>(what: &'static str, i: usize) -> Result<Index<T>, ConvertError> {
    Ok(Index::new(to_u32(what, i)?))
}

/// The buffer under construction, and its views as glTF lists them.
struct Bin {
    bytes: Vec<u8>,
    views: Vec<json::buffer::View>,
}

type ViewIndex = Index<json::buffer::View>;
type AccessorIndex = Index<json::Accessor>;

impl Bin {
    /// Ends the view that began at `offset`, padding the buffer with zeros to a multiple of 4
    /// so that the next view is aligned for any component type.
    fn end_view(
        &mut self,
        offset: usize,
        target: Option<Target>,
    ) -> Result<ViewIndex, ConvertError> {
        let length = self.bytes.len() - offset;
        self.bytes.resize(self.bytes.len().next_multiple_of(4), 0);
        let index = gltf_index("the buffer view count", self.views.len())?;
        self.views.push(json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64::from(length),
            // 0 is glTF's default, which tspace has always left unsaid.
            byte_offset: (offset > 0).then(|| USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        });
        Ok(index)
    }

    /// `data` in a view of its own (an image's, which has no target).
    fn view(&mut self, data: &[u8]) -> Result<ViewIndex, ConvertError> {
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.end_view(offset, None)
    }

    /// `values` as little-endian f32 in a view of their own.
    fn floats<const N: usize>(
        &mut self,
        values: impl Iterator<Item = [f32; N]>,
    ) -> Result<ViewIndex, ConvertError> {
        let offset = self.bytes.len();
        for v in values {
            for c in v {
                self.bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        self.end_view(offset, Some(Target::ArrayBuffer))
    }

    /// `indices` as little-endian `u16` when `short` (every index then fits), else `u32`.
    fn indices(&mut self, indices: &[u32], short: bool) -> Result<ViewIndex, ConvertError> {
        let offset = self.bytes.len();
        if short {
            for &i in indices {
                self.bytes.extend_from_slice(&(i as u16).to_le_bytes());
            }
        } else {
            for &i in indices {
                self.bytes.extend_from_slice(&i.to_le_bytes());
            }
        }
        self.end_view(offset, Some(Target::ElementArrayBuffer))
    }
}

/// Counts of flawed values, for warnings.
#[derive(Default)]
struct Flaws {
    colors_clamped: usize,
}

impl Flaws {
    fn warn(&self, warnings: &mut Vec<Notice>) {
        if self.colors_clamped > 0 {
            warnings.push(Notice::new(
                "colors_clamped",
                format!(
                    "{} vertex colours outside [0, 1] were clamped (a NaN component became 1)",
                    self.colors_clamped
                ),
            ));
        }
    }
}

/// The smallest and largest value on each axis (of finite positions: see [`plan_meshes`]).
fn bounds(positions: impl Iterator<Item = [f32; 3]>) -> ([f32; 3], [f32; 3]) {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    (min, max)
}

/// `n` scaled to unit length; `n` itself if it has none ([`plan_meshes`] keeps those out).
fn normalize(n: [f32; 3]) -> [f32; 3] {
    let v = n.map(f64::from);
    let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if length.is_finite() && length > 0.0 {
        v.map(|c| (c / length) as f32)
    } else {
        n
    }
}

/// `values` as a JSON array of numbers (finite here: serde_json makes a non-finite one null).
fn number_array(values: &[f32]) -> Value {
    Value::Array(values.iter().map(|&v| Value::from(v)).collect())
}

const FLOAT_VEC2: (ComponentType, Type) = (ComponentType::F32, Type::Vec2);
const FLOAT_VEC3: (ComponentType, Type) = (ComponentType::F32, Type::Vec3);

/// A primitive's accessors: its attributes by name, and its indices.
struct PrimitiveAccessors {
    attributes: BTreeMap<Checked<Semantic>, AccessorIndex>,
    indices: AccessorIndex,
}

/// Writes attributes, indices and images into the buffer, listing an accessor for each
/// attribute and index list.
struct Writer<'a> {
    obj: &'a Obj,
    /// Normals made for triangles without `vn`, numbered after the OBJ's own.
    generated_normals: &'a [[f32; 3]],
    bin: Bin,
    accessors: Vec<json::Accessor>,
    flaws: Flaws,
}

impl Writer<'_> {
    /// Lists an accessor of `count` elements over the whole of `view`.
    fn accessor(
        &mut self,
        view: ViewIndex,
        (component, kind): (ComponentType, Type),
        count: usize,
        bounds: Option<([f32; 3], [f32; 3])>,
    ) -> Result<AccessorIndex, ConvertError> {
        let index = gltf_index("the accessor count", self.accessors.len())?;
        self.accessors.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(kind),
            min: bounds.map(|(min, _)| number_array(&min)),
            max: bounds.map(|(_, max)| number_array(&max)),
            name: None,
            normalized: false,
            sparse: None,
        });
        Ok(index)
    }

    /// `POSITION`, with the `min` and `max` glTF requires ([`plan_meshes`] kept out the
    /// triangles with a position that is not finite).
    fn positions(&mut self, vertices: &[Corner]) -> Result<AccessorIndex, ConvertError> {
        let obj = self.obj;
        let position = |c: &Corner| {
            obj.positions
                .get(c.position as usize)
                .copied()
                .unwrap_or_default()
        };
        let bounds = bounds(vertices.iter().map(position));
        let view = self.bin.floats(vertices.iter().map(position))?;
        self.accessor(view, FLOAT_VEC3, vertices.len(), Some(bounds))
    }

    /// `NORMAL`, scaled to unit length ([`plan_meshes`] kept out normals that cannot be).
    fn normals(&mut self, vertices: &[Corner]) -> Result<AccessorIndex, ConvertError> {
        let (obj, generated) = (self.obj, self.generated_normals);
        let normal = |c: &Corner| {
            let n = c.normal().and_then(|i| {
                let i = i as usize;
                obj.normals
                    .get(i)
                    .or_else(|| generated.get(i - obj.normals.len()))
            });
            normalize(n.copied().unwrap_or_default())
        };
        let view = self.bin.floats(vertices.iter().map(normal))?;
        self.accessor(view, FLOAT_VEC3, vertices.len(), None)
    }

    /// `TEXCOORD_0`, with `v` flipped: OBJ's origin is the bottom left, glTF's the top left.
    fn uvs(&mut self, vertices: &[Corner]) -> Result<AccessorIndex, ConvertError> {
        let obj = self.obj;
        let uv = |c: &Corner| {
            let uv = c.uv().and_then(|i| obj.uvs.get(i as usize));
            let [u, v] = uv.copied().unwrap_or_default();
            [u, 1.0 - v]
        };
        let view = self.bin.floats(vertices.iter().map(uv))?;
        self.accessor(view, FLOAT_VEC2, vertices.len(), None)
    }

    /// `COLOR_0`, clamped to [0, 1] as glTF requires (counted for a warning).
    fn colors(
        &mut self,
        vertices: &[Corner],
        colors: &[[f32; 3]],
    ) -> Result<AccessorIndex, ConvertError> {
        let clamped_count = &mut self.flaws.colors_clamped;
        let color = |c: &Corner| {
            let color = colors.get(c.position as usize).copied().unwrap_or([1.0; 3]);
            let mut clamped = false;
            let color = color.map(|v| unit(v, 1.0, &mut clamped));
            *clamped_count += usize::from(clamped);
            color
        };
        let view = self.bin.floats(vertices.iter().map(color))?;
        self.accessor(view, FLOAT_VEC3, vertices.len(), None)
    }

    fn indices(&mut self, primitive: &Primitive<'_>) -> Result<AccessorIndex, ConvertError> {
        let short = short_indices(primitive.vertices.len());
        let view = self.bin.indices(&primitive.indices, short)?;
        let component = if short {
            ComponentType::U16
        } else {
            ComponentType::U32
        };
        let count = primitive.indices.len();
        self.accessor(view, (component, Type::Scalar), count, None)
    }

    /// One primitive: its attributes, each in its own view, then its indices.
    fn primitive(&mut self, primitive: &Primitive<'_>) -> Result<PrimitiveAccessors, ConvertError> {
        let vertices = &primitive.vertices;
        to_u32("the vertex count of one primitive", vertices.len())?;
        to_u32("the index count of one primitive", primitive.indices.len())?;
        let mut attributes = BTreeMap::new();
        attributes.insert(Valid(Semantic::Positions), self.positions(vertices)?);
        if primitive.signature.normal {
            attributes.insert(Valid(Semantic::Normals), self.normals(vertices)?);
        }
        if primitive.signature.uv {
            attributes.insert(Valid(Semantic::TexCoords(0)), self.uvs(vertices)?);
        }
        if let Some(colors) = self.obj.colors.as_deref() {
            attributes.insert(Valid(Semantic::Colors(0)), self.colors(vertices, colors)?);
        }
        let indices = self.indices(primitive)?;
        Ok(PrimitiveAccessors {
            attributes,
            indices,
        })
    }
}

/// The written buffer with its views and accessors.
struct Written {
    bytes: Vec<u8>,
    views: Vec<json::buffer::View>,
    accessors: Vec<json::Accessor>,
    /// Per mesh, per primitive.
    primitives: Vec<Vec<PrimitiveAccessors>>,
    /// Per image, its buffer view when embedded.
    image_views: Vec<Option<ViewIndex>>,
    flaws: Flaws,
}

/// Writes every primitive, mesh by mesh, then the embedded images after the geometry.
fn write_buffer(
    obj: &Obj,
    generated_normals: &[[f32; 3]],
    meshes: &[Mesh<'_>],
    table: &ImageTable<'_>,
    bin: Bin,
) -> Result<Written, ConvertError> {
    let mut writer = Writer {
        obj,
        generated_normals,
        bin,
        accessors: Vec::new(),
        flaws: Flaws::default(),
    };
    let mut primitives = Vec::with_capacity(meshes.len());
    for mesh in meshes {
        let written = mesh.primitives.iter().map(|p| writer.primitive(p));
        primitives.push(written.collect::<Result<Vec<_>, _>>()?);
    }
    let image_views = table
        .images
        .iter()
        .map(|image| {
            let embedded = image.embedded.map(|(bytes, _)| writer.bin.view(bytes));
            embedded.transpose()
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Written {
        bytes: writer.bin.bytes,
        views: writer.bin.views,
        accessors: writer.accessors,
        primitives,
        image_views,
        flaws: writer.flaws,
    })
}

/// The conversion's numbers, from its plan.
fn count(meshes: &[Mesh<'_>], materials: usize, table: &ImageTable<'_>) -> ConversionStats {
    let primitives = || meshes.iter().flat_map(|m| &m.primitives);
    let embedded = table.images.iter().filter(|i| i.embedded.is_some()).count();
    ConversionStats {
        meshes: meshes.len(),
        primitives: primitives().count(),
        vertices: primitives().map(|p| p.vertices.len()).sum(),
        triangles: primitives().map(|p| p.indices.len() / 3).sum(),
        materials,
        images_embedded: embedded,
        images_referenced: table.images.len() - embedded,
    }
}

// Building the document.

/// The glTF extensions the materials use.
#[derive(Default)]
struct Extensions {
    texture_transform: bool,
    emissive_strength: bool,
}

/// A texture reference's `KHR_texture_transform`, as plain JSON: gltf-json's typed one always
/// writes its `texCoord`, as `null` when unset, which glTF does not allow.
fn transform_extension(r: &TextureRef, uses: &mut Extensions) -> Option<Map<String, Value>> {
    let Transform { offset, scale } = r.transform?;
    uses.texture_transform = true;
    let mut transform = Map::new();
    transform.insert("offset".to_owned(), number_array(&offset));
    transform.insert("scale".to_owned(), number_array(&scale));
    let mut extensions = Map::new();
    extensions.insert(TEXTURE_TRANSFORM.to_owned(), Value::Object(transform));
    Some(extensions)
}

fn texture_info(
    r: &TextureRef,
    uses: &mut Extensions,
) -> Result<json::texture::Info, ConvertError> {
    // gltf-json's KHR_texture_transform feature, if any crate in the build turned it on, adds
    // a field here, which this leaves unset.
    #[allow(clippy::needless_update)]
    let extensions = transform_extension(r, uses).map(|others| json::extensions::texture::Info {
        others,
        ..Default::default()
    });
    Ok(json::texture::Info {
        index: gltf_index("the texture count", r.index)?,
        tex_coord: 0,
        extensions,
        extras: Default::default(),
    })
}

/// `normalTexture`, with `scale` from the map's `-bm` (glTF's default 1 when it has none, or
/// none that is finite).
fn normal_texture(
    r: &TextureRef,
    m: &Material,
    uses: &mut Extensions,
) -> Result<NormalTexture, ConvertError> {
    let scale = normal_source(m).and_then(|t| t.bump_multiplier);
    let extensions = transform_extension(r, uses)
        .map(|others| json::extensions::material::NormalTexture { others });
    Ok(NormalTexture {
        index: gltf_index("the texture count", r.index)?,
        scale: scale.filter(|s| s.is_finite()).unwrap_or(1.0),
        tex_coord: 0,
        extensions,
        extras: Default::default(),
    })
}

/// A material in glTF's terms (see the module documentation), and whether any of its values
/// had to be clamped or replaced.
fn gltf_material(
    plan: &MaterialPlan<'_>,
    refs: &MaterialTextures,
    uses: &mut Extensions,
) -> Result<(json::Material, bool), ConvertError> {
    let name = Some(plan.name.to_owned());
    let Some(m) = plan.source else {
        // A `usemtl` name the MTL lacks: white, non-metallic, fully rough.
        let pbr_metallic_roughness = PbrMetallicRoughness {
            metallic_factor: StrengthFactor(0.0),
            ..Default::default()
        };
        let material = json::Material {
            name,
            pbr_metallic_roughness,
            ..Default::default()
        };
        return Ok((material, false));
    };
    let values = pbr(m);
    let emissive_strength = values.emissive_strength.map(|strength| {
        uses.emissive_strength = true;
        json::extensions::material::Material {
            emissive_strength: Some(EmissiveStrength {
                emissive_strength: EmissiveStrengthFactor(strength),
            }),
            ..Default::default()
        }
    });
    let base_color_texture = refs.base_color.as_ref();
    let material = json::Material {
        name,
        alpha_mode: Valid(if values.blend {
            AlphaMode::Blend
        } else {
            AlphaMode::Opaque
        }),
        pbr_metallic_roughness: PbrMetallicRoughness {
            base_color_factor: PbrBaseColorFactor(values.base_color),
            base_color_texture: base_color_texture
                .map(|r| texture_info(r, uses))
                .transpose()?,
            metallic_factor: StrengthFactor(values.metallic),
            roughness_factor: StrengthFactor(values.roughness),
            ..Default::default()
        },
        normal_texture: (refs.normal.as_ref())
            .map(|r| normal_texture(r, m, uses))
            .transpose()?,
        emissive_factor: EmissiveFactor(values.emissive),
        extensions: emissive_strength,
        ..Default::default()
    };
    Ok((material, values.adjusted))
}

/// Every material in glTF's terms, warning about those whose values were clamped or replaced.
fn gltf_materials(
    materials: &[MaterialPlan<'_>],
    textures: &[MaterialTextures],
    uses: &mut Extensions,
    warnings: &mut Vec<Notice>,
) -> Result<Vec<json::Material>, ConvertError> {
    let mut adjusted = Vec::new();
    let mut adjusted_seen = HashSet::new();
    let mut out = Vec::with_capacity(materials.len());
    for (plan, refs) in materials.iter().zip(textures) {
        let (material, clamped) = gltf_material(plan, refs, uses)?;
        // A material and its untextured copy are one name in the warning.
        if clamped && adjusted_seen.insert(plan.name) {
            adjusted.push(plan.name.to_owned());
        }
        out.push(material);
    }
    if !adjusted.is_empty() {
        warnings.push(Notice::new(
            "material_values_adjusted",
            format!(
                "materials with values outside [0, 1] (clamped) or not finite (replaced by the \
             default): {}",
                name_list(&adjusted)
            ),
        ));
    }
    Ok(out)
}

/// One node and one mesh per planned mesh, each primitive with its accessors and material.
fn gltf_meshes(
    meshes: &[Mesh<'_>],
    accessors: Vec<Vec<PrimitiveAccessors>>,
    materials: &MaterialTable<'_>,
) -> Result<(Vec<json::Node>, Vec<json::Mesh>), ConvertError> {
    let mut nodes = Vec::with_capacity(meshes.len());
    let mut out = Vec::with_capacity(meshes.len());
    let per_mesh = meshes.iter().zip(accessors).zip(&materials.per_primitive);
    for (i, ((mesh, accessors), slots)) in per_mesh.enumerate() {
        let name = mesh.name.map(str::to_owned);
        nodes.push(json::Node {
            mesh: Some(gltf_index("the mesh count", i)?),
            name: name.clone(),
            ..Default::default()
        });
        let mut primitives = Vec::with_capacity(accessors.len());
        for (primitive, slot) in accessors.into_iter().zip(slots) {
            primitives.push(json::mesh::Primitive {
                attributes: primitive.attributes,
                indices: Some(primitive.indices),
                material: slot
                    .map(|m| gltf_index("the material count", m))
                    .transpose()?,
                mode: Valid(Mode::Triangles),
                targets: None,
                extensions: None,
                extras: Default::default(),
            });
        }
        out.push(json::Mesh {
            name,
            primitives,
            weights: None,
            extensions: None,
            extras: Default::default(),
        });
    }
    Ok((nodes, out))
}

/// A texture of image `source`. A WebP image is named through `EXT_texture_webp` only: core
/// glTF has no WebP, and there is no fallback image to name in `source`.
fn gltf_texture(source: usize, format: Option<ImageFormat>) -> Result<json::Texture, ConvertError> {
    let source = gltf_index("the image count", source)?;
    let webp = format == Some(ImageFormat::Webp);
    let extensions = webp.then(|| {
        let mut reference = Map::new();
        reference.insert("source".to_owned(), Value::from(source.value()));
        let mut others = Map::new();
        others.insert(TEXTURE_WEBP.to_owned(), Value::Object(reference));
        json::extensions::texture::Texture { others }
    });
    Ok(json::Texture {
        name: None,
        sampler: Some(Index::new(0)),
        // gltf-json's own mark for a texture without `source` (it reads one as this), which
        // it then leaves out.
        source: if webp { Index::new(u32::MAX) } else { source },
        extensions,
        extras: Default::default(),
    })
}

/// An image: in the buffer with its MIME type when embedded, else a relative URI.
fn gltf_image(image: &ImagePlan<'_>, view: Option<ViewIndex>) -> json::Image {
    let (buffer_view, mime_type, uri) = match (image.embedded, view) {
        (Some((_, format)), Some(view)) => {
            let mime = json::image::MimeType(format.mime().to_owned());
            (Some(view), Some(mime), None)
        }
        _ => (None, None, Some(percent_encode_path(&image.path))),
    };
    json::Image {
        name: Some(image.name.clone()),
        buffer_view,
        mime_type,
        uri,
        extensions: None,
        extras: Default::default(),
    }
}

/// The document's textures, samplers and images.
#[derive(Default)]
struct GltfImages {
    textures: Vec<json::Texture>,
    samplers: Vec<json::texture::Sampler>,
    images: Vec<json::Image>,
}

/// One texture per image, all sharing one sampler (`REPEAT` both ways, as OBJ viewers
/// sample), and the images; nothing at all without images.
fn gltf_images(
    table: &ImageTable<'_>,
    views: &[Option<ViewIndex>],
) -> Result<GltfImages, ConvertError> {
    if table.images.is_empty() {
        return Ok(GltfImages::default());
    }
    let mut textures = Vec::with_capacity(table.images.len());
    for (i, image) in table.images.iter().enumerate() {
        textures.push(gltf_texture(i, image.embedded.map(|(_, f)| f))?);
    }
    let images = table.images.iter().zip(views);
    let images = images.map(|(image, view)| gltf_image(image, *view));
    let repeat = json::texture::Sampler {
        wrap_s: Valid(WrappingMode::Repeat),
        wrap_t: Valid(WrappingMode::Repeat),
        ..Default::default()
    };
    Ok(GltfImages {
        textures,
        samplers: vec![repeat],
        images: images.collect(),
    })
}

/// The extensions the document uses and those it requires, in a fixed order.
fn extension_lists(uses: &Extensions, table: &ImageTable<'_>) -> (Vec<String>, Vec<String>) {
    let webp = table
        .images
        .iter()
        .any(|i| matches!(i.embedded, Some((_, ImageFormat::Webp))));
    let used = [
        (uses.emissive_strength, EMISSIVE_STRENGTH),
        (uses.texture_transform, TEXTURE_TRANSFORM),
        (webp, TEXTURE_WEBP),
    ];
    let used = used
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, n)| (*n).to_owned());
    // Without a fallback image, a reader that cannot decode WebP has nothing to show.
    let required = webp.then(|| TEXTURE_WEBP.to_owned());
    (used.collect(), required.into_iter().collect())
}

/// The materials in glTF's terms, and the extensions they use.
struct GltfMaterials {
    materials: Vec<json::Material>,
    uses: Extensions,
}

/// The whole document: one scene of every node, buffer 0 without a `uri`.
fn gltf_root(
    meshes: &[Mesh<'_>],
    material_table: &MaterialTable<'_>,
    materials: GltfMaterials,
    table: &ImageTable<'_>,
    written: Written,
) -> Result<(Root, Vec<u8>), ConvertError> {
    let (extensions_used, extensions_required) = extension_lists(&materials.uses, table);
    let (nodes, gltf_meshes) = gltf_meshes(meshes, written.primitives, material_table)?;
    let scene_nodes = (0..nodes.len()).map(|i| gltf_index("the node count", i));
    let scene = json::Scene {
        nodes: scene_nodes.collect::<Result<_, _>>()?,
        name: None,
        extensions: None,
        extras: Default::default(),
    };
    let images = gltf_images(table, &written.image_views)?;
    let buffer = json::Buffer {
        byte_length: USize64::from(written.bytes.len()),
        uri: None,
        name: None,
        extensions: None,
        extras: Default::default(),
    };
    let generator = format!("tspace {}", env!("CARGO_PKG_VERSION"));
    let root = Root {
        asset: json::Asset {
            generator: Some(generator),
            ..Default::default()
        },
        extensions_used,
        extensions_required,
        scene: Some(Index::new(0)),
        scenes: vec![scene],
        nodes,
        meshes: gltf_meshes,
        materials: materials.materials,
        textures: images.textures,
        samplers: images.samplers,
        images: images.images,
        accessors: written.accessors,
        buffer_views: written.views,
        buffers: vec![buffer],
        ..Default::default()
    };
    Ok((root, written.bytes))
}

// Writing the document.

fn json_error(e: impl fmt::Display) -> ConvertError {
    ConvertError::Json(e.to_string())
}

/// gltf-json writes some members whatever their value and leaves out a primitive's `mode`
/// when it is `TRIANGLES`. Converted documents have always left glTF's defaults unsaid in
/// materials (except `metallicFactor`, and `roughnessFactor` of a material from the MTL) and
/// always stated `mode`; this keeps them exactly what they were.
fn keep_members_as_before(doc: &mut Value, materials: &[MaterialPlan<'_>]) {
    let drop_if = |object: &mut Map<String, Value>, key: &str, default: Value| {
        if object.get(key) == Some(&default) {
            object.remove(key);
        }
    };
    let one = || Value::from(1.0f32);
    let zero = || Value::from(0.0f32);
    for primitive in members(doc, "meshes").flat_map(|m| members(m, "primitives")) {
        if let Some(primitive) = primitive.as_object_mut() {
            primitive.insert("mode".to_owned(), Value::from(TRIANGLES));
        }
    }
    let gltf_materials = members(doc, "materials").filter_map(Value::as_object_mut);
    for (material, plan) in gltf_materials.zip(materials) {
        drop_if(material, "alphaMode", Value::from("OPAQUE"));
        drop_if(material, "doubleSided", Value::from(false));
        drop_if(material, "emissiveFactor", Value::Array(vec![zero(); 3]));
        if let Some(Value::Object(normal)) = material.get_mut("normalTexture") {
            drop_if(normal, "scale", one());
            drop_if(normal, "texCoord", Value::from(0));
        }
        let Some(Value::Object(pbr)) = material.get_mut("pbrMetallicRoughness") else {
            continue;
        };
        drop_if(pbr, "baseColorFactor", Value::Array(vec![one(); 4]));
        if plan.source.is_none() {
            pbr.remove("roughnessFactor");
        }
        if let Some(Value::Object(base)) = pbr.get_mut("baseColorTexture") {
            drop_if(base, "texCoord", Value::from(0));
        }
    }
}

/// The elements of the array `key` of `value` (none when it has no such array).
fn members<'v>(value: &'v mut Value, key: &str) -> impl Iterator<Item = &'v mut Value> {
    let array = value.get_mut(key).and_then(Value::as_array_mut);
    array.into_iter().flatten()
}

/// A JSON value written with each primitive's `attributes` in the order of their accessors,
/// which is the order they were written in (`POSITION`, `NORMAL`, `TEXCOORD_0`, `COLOR_0`),
/// where `Value` would sort them by name. The tangent step takes a primitive's attributes in
/// document order, and so lays out what it writes in that order. Other members come in
/// `Value`'s order, which nothing depends on.
struct InOrder<'v> {
    value: &'v Value,
    by_accessor: bool,
}

impl serde::Serialize for InOrder<'_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self.value {
            Value::Object(members) => {
                let mut members: Vec<(&String, &Value)> = members.iter().collect();
                if self.by_accessor {
                    members.sort_by_key(|(_, accessor)| accessor.as_u64());
                }
                serializer.collect_map(members.into_iter().map(|(key, value)| {
                    let by_accessor = key == "attributes";
                    (key, InOrder { value, by_accessor })
                }))
            }
            Value::Array(items) => serializer.collect_seq(items.iter().map(|value| InOrder {
                value,
                by_accessor: false,
            })),
            other => other.serialize(serializer),
        }
    }
}

/// The document as JSON text.
fn to_json(root: &Root, materials: &[MaterialPlan<'_>]) -> Result<String, ConvertError> {
    let mut doc = serde_json::to_value(root).map_err(json_error)?;
    keep_members_as_before(&mut doc, materials);
    // Numbers read as they always have: every float here is an f32, spelled as one.
    let in_order = InOrder {
        value: &doc,
        by_accessor: false,
    };
    created::to_text(&in_order).map_err(json_error)
}

/// Converts a parsed OBJ (and its MTL, if any) to a glTF document; see the module
/// documentation. `images` supplies texture files by name; nothing is read from disk.
pub fn obj_to_gltf(
    obj: &Obj,
    mtl: Option<&Mtl>,
    images: &PartSet<'_>,
    normals: NormalRequest,
    limits: &ConvertLimits,
) -> Result<Converted, ConvertError> {
    let mut warnings = Vec::new();
    let (meshes, dropped, generated) = plan_meshes(obj, normals)?;
    dropped.warn(&mut warnings);
    generated.warn(normals, obj.smoothing_declared, &mut warnings);
    let material_table = plan_materials(&meshes, mtl, &mut warnings);
    let (table, textures) = plan_textures(&material_table.materials, images, &mut warnings);
    let total = buffer_size(&meshes, obj.colors.is_some(), &table);
    let bin = allocate_buffer(total, limits)?;
    let written = write_buffer(obj, &generated.normals, &meshes, &table, bin)?;
    debug_assert_eq!(written.bytes.len() as u64, total);
    written.flaws.warn(&mut warnings);
    let stats = count(&meshes, material_table.materials.len(), &table);
    let mut uses = Extensions::default();
    let materials = gltf_materials(
        &material_table.materials,
        &textures,
        &mut uses,
        &mut warnings,
    )?;
    let materials = GltfMaterials { materials, uses };
    let (root, bin) = gltf_root(&meshes, &material_table, materials, &table, written)?;
    let json = to_json(&root, &material_table.materials)?;
    Ok(Converted {
        json,
        bin,
        notices: warnings,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    impl Converted {
        fn messages(&self) -> Vec<String> {
            self.notices.iter().map(|n| n.message.clone()).collect()
        }
    }
    use crate::scene::gltf::glb;
    use crate::scene::obj::{FaceGroup, Limits, parse_mtl, parse_obj};
    use proptest::prelude::*;
    use std::collections::HashSet;
    use tspace_json::{Document, Node};

    /// Corners that differ in any index, or in having one, have different keys, at the
    /// extremes of every index too.
    #[test]
    fn corner_keys_tell_every_corner_apart() {
        // The largest u32 is no index (see `Corner`).
        let values = [
            None,
            Some(0),
            Some(1),
            Some(u32::MAX - 2),
            Some(u32::MAX - 1),
        ];
        let mut keys = HashSet::new();
        let mut corners = 0;
        for position in [0, 1, u32::MAX] {
            for uv in values {
                for normal in values {
                    keys.insert(corner_key(&Corner::new(position, uv, normal)));
                    corners += 1;
                }
            }
        }
        assert_eq!(keys.len(), corners);
    }

    const PNG: &[u8] = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR not really a png";
    const JPEG: &[u8] = b"\xFF\xD8\xFF\xE0\0\x10JFIF\0 not really a jpeg";
    const WEBP: &[u8] = b"RIFF\x1a\0\0\0WEBPVP8L not really a webp";

    fn obj(text: &str) -> Obj {
        parse_obj(text.as_bytes(), &Limits::default()).unwrap()
    }

    fn convert_with(
        obj_text: &str,
        mtl_text: Option<&str>,
        parts: &[(&str, &'static [u8])],
    ) -> Converted {
        let obj = obj(obj_text);
        let mtl = mtl_text.map(|m| parse_mtl(m.as_bytes()).unwrap());
        let mut set = PartSet::new();
        for &(name, bytes) in parts {
            set.insert(name, bytes).unwrap();
        }
        obj_to_gltf(
            &obj,
            mtl.as_ref(),
            &set,
            NormalRequest::default(),
            &ConvertLimits::default(),
        )
        .unwrap()
    }

    fn convert(obj_text: &str) -> Converted {
        convert_with(obj_text, None, &[])
    }

    /// A parsed OBJ with the default options and no MTL or textures.
    fn convert_obj(obj: &Obj) -> Result<Converted, ConvertError> {
        obj_to_gltf(
            obj,
            None,
            &PartSet::new(),
            NormalRequest::default(),
            &ConvertLimits::default(),
        )
    }

    /// The converted document read back by the `gltf` crate, from a GLB made of it.
    fn read(c: &Converted) -> gltf::Gltf {
        let glb = glb::write(c.json.as_bytes(), Some(&c.bin), &[]).unwrap();
        gltf::Gltf::from_slice(&glb).unwrap()
    }

    fn with_json<T>(c: &Converted, f: impl FnOnce(&Node) -> T) -> T {
        let doc = Document::parse(c.json.as_bytes()).unwrap();
        f(doc.root())
    }

    /// The `name` of each element of the top-level array `key` (the `gltf` crate is built
    /// without its `names` feature).
    fn names(c: &Converted, key: &str) -> Vec<Option<String>> {
        with_json(c, |root| {
            root.get(key)
                .map_or(&[][..], |a| a.as_array().unwrap())
                .iter()
                .map(|e| e.get("name").map(|n| n.as_str().unwrap().to_owned()))
                .collect()
        })
    }

    fn some(names: &[&str]) -> Vec<Option<String>> {
        names.iter().map(|n| Some((*n).to_owned())).collect()
    }

    fn f32s(node: &Node) -> Vec<f32> {
        node.as_array()
            .unwrap()
            .iter()
            .map(|n| n.as_f64().unwrap() as f32)
            .collect()
    }

    #[derive(Debug)]
    struct Prim {
        positions: Vec<[f32; 3]>,
        normals: Option<Vec<[f32; 3]>>,
        uvs: Option<Vec<[f32; 2]>>,
        colors: Option<Vec<[f32; 3]>>,
        indices: Vec<u32>,
        index_type: gltf::accessor::DataType,
        material: Option<usize>,
    }

    fn primitives(doc: &gltf::Gltf) -> Vec<Vec<Prim>> {
        let blob = doc.blob.as_deref();
        doc.meshes()
            .map(|mesh| {
                mesh.primitives()
                    .map(|p| {
                        assert_eq!(p.mode(), gltf::mesh::Mode::Triangles);
                        let r = p.reader(|b| (b.index() == 0).then_some(blob).flatten());
                        Prim {
                            positions: r.read_positions().unwrap().collect(),
                            normals: r.read_normals().map(Iterator::collect),
                            uvs: r.read_tex_coords(0).map(|t| t.into_f32().collect()),
                            colors: r.read_colors(0).map(|c| c.into_rgb_f32().collect()),
                            indices: r.read_indices().unwrap().into_u32().collect(),
                            index_type: p.indices().unwrap().data_type(),
                            material: p.material().index(),
                        }
                    })
                    .collect()
            })
            .collect()
    }

    /// Triangles as comparable bit patterns: position, uv, normal of each corner.
    type Key = Vec<(Vec<u32>, Option<Vec<u32>>, Option<Vec<u32>>)>;

    fn bits<const N: usize>(v: [f32; N]) -> Vec<u32> {
        v.iter().map(|c| c.to_bits()).collect()
    }

    fn unit(n: [f32; 3]) -> [f32; 3] {
        let v = n.map(f64::from);
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if l > 0.0 && l.is_finite() {
            v.map(|c| (c / l) as f32)
        } else {
            n
        }
    }

    /// The corners as the conversion should keep them: an attribute survives only when every
    /// corner has it, finite (and for normals, of non-zero length).
    fn kept(obj: &Obj, t: &[Corner; 3]) -> [Corner; 3] {
        let uv_ok = t.iter().all(|c| {
            c.uv()
                .is_some_and(|i| obj.uvs[i as usize].iter().all(|v| v.is_finite()))
        });
        let normal_ok = t.iter().all(|c| {
            c.normal().is_some_and(|i| {
                let n = obj.normals[i as usize];
                let l = n.iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>();
                l.is_finite() && l > 0.0
            })
        });
        t.map(|c| {
            Corner::new(
                c.position,
                c.uv().filter(|_| uv_ok),
                c.normal().filter(|_| normal_ok),
            )
        })
    }

    /// Every triangle of the OBJ, as the conversion should write it (V flipped, unit normals;
    /// those with a position that is not finite dropped).
    fn obj_triangles(obj: &Obj) -> Vec<Key> {
        let mut out: Vec<Key> = obj
            .groups
            .iter()
            .flat_map(|g| &g.triangles)
            .filter(|t| finite_positions(obj, t))
            .map(|t| {
                kept(obj, t)
                    .iter()
                    .map(|c| {
                        (
                            bits(obj.positions[c.position as usize]),
                            c.uv().map(|i| {
                                let [u, v] = obj.uvs[i as usize];
                                bits([u, 1.0 - v])
                            }),
                            c.normal().map(|i| bits(unit(obj.normals[i as usize]))),
                        )
                    })
                    .collect()
            })
            .collect();
        out.sort();
        out
    }

    fn gltf_triangles(prims: &[Vec<Prim>]) -> Vec<Key> {
        let mut out: Vec<Key> = Vec::new();
        for p in prims.iter().flatten() {
            for t in p.indices.chunks(3) {
                out.push(
                    t.iter()
                        .map(|&i| {
                            let i = i as usize;
                            (
                                bits(p.positions[i]),
                                p.uvs.as_ref().map(|u| bits(u[i])),
                                p.normals.as_ref().map(|n| bits(n[i])),
                            )
                        })
                        .collect(),
                );
            }
        }
        out.sort();
        out
    }

    /// The glTF holds exactly the OBJ's triangles, every primitive has as many vertices as it
    /// has distinct corners, and the POSITION bounds are exact.
    fn assert_faithful(obj: &Obj, c: &Converted) -> Vec<Vec<Prim>> {
        let doc = read(c);
        let prims = primitives(&doc);
        let (written, expected) = (gltf_triangles(&prims), obj_triangles(obj));
        let without_normals = |keys: &[Key]| {
            let mut keys: Vec<Key> = keys
                .iter()
                .map(|t| {
                    t.iter()
                        .map(|(p, uv, _)| (p.clone(), uv.clone(), None))
                        .collect()
                })
                .collect();
            keys.sort();
            keys
        };
        assert_eq!(without_normals(&written), without_normals(&expected));
        // The OBJ's own normals are kept as they are; the other triangles' were generated.
        let mut unclaimed: HashMap<&Key, usize> = HashMap::new();
        for t in &written {
            *unclaimed.entry(t).or_default() += 1;
        }
        for t in expected.iter().filter(|t| t.iter().all(|c| c.2.is_some())) {
            let left = unclaimed.get_mut(t).filter(|n| **n > 0);
            *left.unwrap_or_else(|| panic!("{t:?} lost its normals")) -= 1;
        }
        for p in prims.iter().flatten() {
            for n in p.normals.as_deref().expect("every primitive has NORMAL") {
                let length = n.iter().map(|c| c * c).sum::<f32>().sqrt();
                assert!((length - 1.0).abs() < 1e-5, "{n:?}");
            }
        }
        for (mesh, gmesh) in prims.iter().zip(doc.meshes()) {
            for (p, gp) in mesh.iter().zip(gmesh.primitives()) {
                assert!(p.indices.iter().all(|&i| (i as usize) < p.positions.len()));
                let used: HashSet<u32> = p.indices.iter().copied().collect();
                assert_eq!(used.len(), p.positions.len(), "unused vertices");
                let bounds = gp.bounding_box();
                for k in 0..3 {
                    let finite = p.positions.iter().map(|v| v[k]).filter(|v| v.is_finite());
                    let min = finite.clone().fold(f32::INFINITY, f32::min);
                    let max = finite.fold(f32::NEG_INFINITY, f32::max);
                    assert_eq!((bounds.min[k], bounds.max[k]), (min, max));
                }
                let expected = if p.positions.len() <= 65535 {
                    gltf::accessor::DataType::U16
                } else {
                    gltf::accessor::DataType::U32
                };
                assert_eq!(p.index_type, expected);
            }
        }
        let total: usize = prims.iter().flatten().map(|p| p.positions.len()).sum();
        assert_eq!(c.stats.vertices, total);
        assert_eq!(c.stats.triangles, expected.len());
        assert_eq!(c.bin.len() % 4, 0);
        prims
    }

    const QUAD: &str = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 -1\nvt 0 0\nvt 1 0\nvt 1 0.25\nvt 0 1\n\
                        vn 0 0 2\n";

    #[test]
    fn shared_vertices_stay_shared_uvs_flip_and_normals_become_unit() {
        let text = format!("{QUAD}f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n");
        let c = convert(&text);
        let prims = assert_faithful(&obj(&text), &c);
        assert_eq!(prims.len(), 1);
        let p = &prims[0][0];
        assert_eq!(p.positions.len(), 4);
        assert_eq!(p.indices, [0, 1, 2, 0, 2, 3]);
        assert_eq!(p.index_type, gltf::accessor::DataType::U16);
        assert_eq!(
            p.uvs.as_deref().unwrap(),
            [[0.0, 1.0], [1.0, 1.0], [1.0, 0.75], [0.0, 0.0]]
        );
        assert_eq!(p.normals.as_deref().unwrap(), [[0.0, 0.0, 1.0]; 4]);
        assert!(p.colors.is_none() && p.material.is_none());
        with_json(&c, |root| {
            let position = root.get("accessors").unwrap().index(0).unwrap();
            assert_eq!(f32s(position.get("min").unwrap()), [0.0, 0.0, -1.0]);
            assert_eq!(f32s(position.get("max").unwrap()), [2.0, 1.0, 0.0]);
            assert_eq!(root.get("scene").unwrap().as_u64(), Some(0));
            let asset = root.get("asset").unwrap();
            assert_eq!(asset.get("version").unwrap().as_str(), Some("2.0"));
            let generator = format!("tspace {}", env!("CARGO_PKG_VERSION"));
            assert_eq!(asset.get("generator").unwrap().as_str(), Some(&*generator));
            let buffers = root.get("buffers").unwrap().as_array().unwrap();
            assert_eq!(buffers.len(), 1);
            assert!(buffers[0].get("uri").is_none());
            assert_eq!(
                buffers[0].get("byteLength").unwrap().as_u64(),
                Some(c.bin.len() as u64)
            );
            for key in [
                "materials",
                "textures",
                "images",
                "samplers",
                "extensionsUsed",
            ] {
                assert!(root.get(key).is_none(), "{key}");
            }
            for view in root.get("bufferViews").unwrap().as_array().unwrap() {
                let offset = view.get("byteOffset").map_or(0, |o| o.as_u64().unwrap());
                assert_eq!(offset % 4, 0);
                assert!(view.get("byteStride").is_none());
            }
        });
        assert!(c.messages().is_empty(), "{:?}", c.messages());
        assert_eq!(
            c.stats,
            ConversionStats {
                meshes: 1,
                primitives: 1,
                vertices: 4,
                triangles: 2,
                ..ConversionStats::default()
            }
        );
    }

    /// What the conversion has always written and the tangent step relies on: attributes in
    /// the order of their accessors (it lays out a split primitive in document order),
    /// `mode` stated, glTF's defaults left out of materials, floats spelled as f32.
    #[test]
    fn the_document_keeps_its_attribute_order_mode_and_spelling() {
        let text = "mtllib m.mtl\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvt 0 0\nvt 1 0\n\
                    vt 0 1\nvn 0 0 1\nusemtl a\nf 1/1/1 2/2/1 3/3/1\nusemtl missing\nf 1 2 3\n";
        let mtl = "newmtl a\nKd 0.1 0.2 0.3\nNs 100\n";
        let c = convert_with(text, Some(mtl), &[]);
        with_json(&c, |root| {
            let meshes = root.get("meshes").unwrap();
            let primitives = meshes.index(0).unwrap().get("primitives").unwrap();
            let first = primitives.index(0).unwrap();
            let attributes = first.get("attributes").unwrap().as_object().unwrap();
            let keys: Vec<&str> = attributes.iter().map(|m| m.key.as_str()).collect();
            assert_eq!(keys, ["POSITION", "NORMAL", "TEXCOORD_0", "COLOR_0"]);
            for p in primitives.as_array().unwrap() {
                assert_eq!(p.get("mode").unwrap().as_u64(), Some(4));
            }
            let materials = root.get("materials").unwrap();
            let a = materials.index(0).unwrap();
            for key in ["alphaMode", "doubleSided", "emissiveFactor"] {
                assert!(a.get(key).is_none(), "{key}");
            }
            let pbr = a.get("pbrMetallicRoughness").unwrap();
            let factor = pbr.get("baseColorFactor").unwrap().as_array().unwrap();
            let spelled: Vec<&str> = factor
                .iter()
                .map(|n| n.as_number().unwrap().raw())
                .collect();
            assert_eq!(spelled, ["0.1", "0.2", "0.3", "1"]);
            assert!(pbr.get("roughnessFactor").is_some());
            let missing = materials
                .index(1)
                .unwrap()
                .get("pbrMetallicRoughness")
                .unwrap();
            let keys: Vec<&str> = missing
                .as_object()
                .unwrap()
                .iter()
                .map(|m| m.key.as_str())
                .collect();
            assert_eq!(keys, ["metallicFactor"]);
        });
    }

    #[test]
    fn mixed_vt_vn_faces_give_one_primitive_per_signature_merged_in_file_order() {
        let text = format!(
            "{QUAD}f 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//1 3//1\nf 1/1/1 2/2/1 3/3/1\nf 1 3 4\n\
             f 1/1/1 3/3/1 4/4/1\nf 1/1 2 3/3\n"
        );
        let c = convert(&text);
        let prims = assert_faithful(&obj(&text), &c);
        let p = &prims[0];
        assert_eq!(p.len(), 2);
        let shape: Vec<(bool, bool, usize)> = p
            .iter()
            .map(|p| (p.uvs.is_some(), p.normals.is_some(), p.indices.len() / 3))
            .collect();
        // Faces without vn got normals and joined those with, signature for signature; the
        // partial face (`f 1/1 2 3/3`) lost its UVs in the reader and joined the bare ones.
        assert_eq!(shape, [(false, true, 4), (true, true, 3)]);
        // The bare faces `f 1 2 3` (twice) and `f 1 3 4` share the edge 1-3 three times over:
        // not smoothed across (which two belong together is unknown), so `f 1 3 4` keeps its
        // own corners, and the twice-written face shares its three. The `vn` face's corners
        // keep the file's normal.
        assert_eq!(p[0].positions.len(), 9);
        assert_eq!(p[0].indices, [0, 1, 2, 3, 4, 5, 6, 7, 8, 0, 1, 2]);
    }

    #[test]
    fn one_node_and_mesh_per_object_in_file_order() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no first\nf 1 2 3\ng a\nf 3 2 1\n\
                    o second thing\nf 1 2 3\no first\nf 1 3 2\nl 1 2\n";
        let c = convert(text);
        assert_faithful(&obj(text), &c);
        let doc = read(&c);
        let expected = [None, Some("first"), Some("second thing"), Some("first")]
            .map(|n| n.map(str::to_owned));
        assert_eq!(names(&c, "nodes"), expected);
        assert_eq!(names(&c, "meshes"), expected);
        for (i, node) in doc.nodes().enumerate() {
            assert_eq!(node.mesh().unwrap().index(), i);
        }
        let scene = doc.default_scene().unwrap();
        assert_eq!(scene.nodes().count(), 4);
        let prims = primitives(&doc);
        // `g a` does not split the object: one primitive of two triangles.
        assert_eq!(prims[1].len(), 1);
        assert_eq!(prims[1][0].indices.len(), 6);
        assert_eq!(c.stats.meshes, 4);
    }

    #[test]
    fn vertex_colours_become_color_0() {
        let text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 2\nv 1 1 0\no b\nf 1 2 3\nf 2 4 3\n";
        let c = convert(text);
        let prims = assert_faithful(&obj(text), &c);
        let p = &prims[0][0];
        assert_eq!(
            p.colors.as_deref().unwrap(),
            [
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0]
            ]
        );
        assert_eq!(
            c.messages()[1..],
            ["1 vertex colours outside [0, 1] were clamped (a NaN component became 1)"]
        );
    }

    const MTL: &str = "newmtl plain\nKd 0.5 0.25 1\nNs 100\n\
        newmtl glass\nKd 0.1 0.2 0.3\nd 0.25\nPr 0.4\nPm 0.75\nKe 2 1 0.5\n\
        map_Kd -o 0.25 0.5 -s 2 3 textures/my diffuse.png\nnorm -bm 0.5 ..\\normals\\n.png\n\
        map_d alpha.png\n\
        newmtl dull\nKs 0 0 0\nNs 500\nKd 2 -1 nan\nKe 0.5 0 0\nmap_Bump -bm 2 bump.jpg\n\
        newmtl unused\nmap_Kd nothere.png\n";

    #[test]
    fn materials_map_to_pbr_with_textures_and_transforms() {
        let text = format!(
            "{QUAD}mtllib m.mtl\nusemtl glass\nf 1/1/1 2/2/1 3/3/1\nusemtl plain\nf 1/1 3/3 4/4\n\
             usemtl dull\nf 1/1/1 3/3/1 4/4/1\nusemtl glass\nf 1/1/1 3/3/1 4/4/1\n"
        );
        let c = convert_with(&text, Some(MTL), &[("my diffuse.png", PNG)]);
        let prims = assert_faithful(&obj(&text), &c);
        let materials: Vec<Option<usize>> = prims[0].iter().map(|p| p.material).collect();
        assert_eq!(materials, [Some(0), Some(1), Some(2)]);
        let doc = read(&c);
        assert_eq!(names(&c, "materials"), some(&["glass", "plain", "dull"]));

        let glass = doc.materials().next().unwrap();
        let pbr = glass.pbr_metallic_roughness();
        assert_eq!(pbr.base_color_factor(), [0.1, 0.2, 0.3, 0.25]);
        assert_eq!(glass.alpha_mode(), gltf::material::AlphaMode::Blend);
        assert_eq!((pbr.metallic_factor(), pbr.roughness_factor()), (0.75, 0.4));
        assert_eq!(glass.emissive_factor(), [1.0, 0.5, 0.25]);
        let base = pbr.base_color_texture().unwrap();
        let normal = glass.normal_texture().unwrap();
        assert_eq!(normal.scale(), 0.5);
        let source = |t: gltf::Texture<'_>| match t.source().source() {
            gltf::image::Source::View { view, mime_type } => {
                let start = view.offset();
                let bytes = &doc.blob.as_deref().unwrap()[start..start + view.length()];
                format!("embedded {mime_type} {}", bytes == PNG)
            }
            gltf::image::Source::Uri { uri, .. } => format!("uri {uri}"),
        };
        assert_eq!(source(base.texture()), "embedded image/png true");
        assert_eq!(source(normal.texture()), "uri n.png");

        let plain = doc.materials().nth(1).unwrap();
        let pbr = plain.pbr_metallic_roughness();
        assert_eq!(pbr.base_color_factor(), [0.5, 0.25, 1.0, 1.0]);
        assert_eq!(plain.alpha_mode(), gltf::material::AlphaMode::Opaque);
        assert_eq!(pbr.metallic_factor(), 0.0);
        assert!((pbr.roughness_factor() - (2.0f32 / 102.0).powf(0.25)).abs() < 1e-6);
        assert!(plain.normal_texture().is_none() && pbr.base_color_texture().is_none());

        let dull = doc.materials().nth(2).unwrap();
        let pbr = dull.pbr_metallic_roughness();
        // Kd 2 -1 nan: clamped, clamped, replaced by the default.
        assert_eq!(pbr.base_color_factor(), [1.0, 0.0, 1.0, 1.0]);
        // Black Ks: no highlight, so fully rough whatever Ns says.
        assert_eq!(pbr.roughness_factor(), 1.0);
        assert_eq!(dull.emissive_factor(), [0.5, 0.0, 0.0]);
        let bump = dull.normal_texture().unwrap();
        assert_eq!(bump.scale(), 2.0);
        assert_eq!(source(bump.texture()), "uri bump.jpg");

        assert_eq!(doc.textures().count(), 3);
        assert_eq!(doc.images().count(), 3);
        assert_eq!(doc.samplers().count(), 1);
        let sampler = doc.samplers().next().unwrap();
        assert_eq!(sampler.wrap_s(), gltf::texture::WrappingMode::Repeat);
        assert_eq!(sampler.wrap_t(), gltf::texture::WrappingMode::Repeat);
        assert_eq!((c.stats.images_embedded, c.stats.images_referenced), (1, 2));
        assert_eq!(c.stats.materials, 3);

        with_json(&c, |root| {
            let used: Vec<&str> = root
                .get("extensionsUsed")
                .unwrap()
                .as_array()
                .unwrap()
                .iter()
                .map(|n| n.as_str().unwrap())
                .collect();
            assert_eq!(used, [EMISSIVE_STRENGTH, TEXTURE_TRANSFORM]);
            assert!(root.get("extensionsRequired").is_none());
            let glass = root.get("materials").unwrap().index(0).unwrap();
            let strength = glass
                .get("extensions")
                .unwrap()
                .get(EMISSIVE_STRENGTH)
                .unwrap();
            assert_eq!(
                strength.get("emissiveStrength").unwrap().as_f64(),
                Some(2.0)
            );
            let transform = glass
                .get("pbrMetallicRoughness")
                .unwrap()
                .get("baseColorTexture")
                .unwrap()
                .get("extensions")
                .unwrap()
                .get(TEXTURE_TRANSFORM)
                .unwrap();
            // Offset (o_u, 1 - o_v - s_v) = (0.25, 1 - 0.5 - 3).
            assert_eq!(f32s(transform.get("offset").unwrap()), [0.25, -2.5]);
            assert_eq!(f32s(transform.get("scale").unwrap()), [2.0, 3.0]);
            assert!(
                glass
                    .get("normalTexture")
                    .unwrap()
                    .get("extensions")
                    .is_none()
            );
            let images = root.get("images").unwrap().as_array().unwrap();
            assert_eq!(
                images[0].get("name").unwrap().as_str(),
                Some("my diffuse.png")
            );
        });

        let joined = c.messages().join("\n");
        for expected in [
            "\"..\\\\normals\\\\n.png\"",
            "not supplied",
            "\"n.png\", \"bump.jpg\"",
            "map_d \"alpha.png\" of material \"glass\"",
            "\"dull\"",
        ] {
            assert!(joined.contains(expected), "{expected} not in {joined}");
        }
        assert!(
            !joined.contains("nothere"),
            "unused material's texture: {joined}"
        );
    }

    #[test]
    fn texture_transform_matches_obj_sampling_after_the_v_flip() {
        let cases = [
            (Some([0.25, 0.5, 0.0]), Some([2.0, 3.0, 1.0])),
            (Some([-0.5, 0.125, 0.0]), None),
            (None, Some([0.5, -2.0, 1.0])),
            (Some([0.0, 0.0, 0.0]), Some([1.0, 1.0, 1.0])),
        ];
        for (offset, scale) in cases {
            let t = Texture {
                path: "t.png".into(),
                bump_multiplier: None,
                offset,
                scale,
            };
            let transform = texture_transform(&t).unwrap();
            let (o, s) = (offset.unwrap_or([0.0; 3]), scale.unwrap_or([1.0; 3]));
            for (u, v) in [(0.0, 0.0), (1.0, 1.0), (0.3, 0.7), (-1.5, 2.25)] {
                // OBJ: the point `o + s * uv` of an image whose V axis points up; as a position
                // in the image from its top left, that is (x, 1 - y).
                let obj = [o[0] + s[0] * u, 1.0 - (o[1] + s[1] * v)];
                // glTF: v' = 1 - v, then offset + scale * uv' (rotation 0).
                let Transform {
                    offset: go,
                    scale: gs,
                } = transform.unwrap_or(Transform {
                    offset: [0.0; 2],
                    scale: [1.0; 2],
                });
                let gltf = [go[0] + gs[0] * u, go[1] + gs[1] * (1.0 - v)];
                for k in 0..2 {
                    assert!(
                        (obj[k] - gltf[k]).abs() < 1e-5,
                        "{offset:?} {scale:?} {u} {v}"
                    );
                }
            }
        }
        assert_eq!(
            texture_transform(&Texture {
                scale: Some([f32::NAN, 1.0, 1.0]),
                ..Texture::default()
            }),
            Err(())
        );
    }

    #[test]
    fn roughness_from_shininess_is_the_fourth_root_of_the_blinn_phong_alpha() {
        assert_eq!(roughness_from_shininess(0.0), 1.0);
        assert_eq!(roughness_from_shininess(-5.0), 1.0);
        for ns in [1.0f32, 10.0, 96.5, 400.0, 1000.0] {
            let alpha = (2.0 / (f64::from(ns) + 2.0)).sqrt();
            let r = f64::from(roughness_from_shininess(ns));
            assert!((r * r - alpha).abs() < 1e-6);
        }
        assert!((roughness_from_shininess(1000.0) - 0.2114).abs() < 1e-3);
    }

    #[test]
    fn missing_and_absent_materials() {
        let text =
            format!("{QUAD}usemtl nowhere\nf 1 2 3\nusemtl plain\nf 1 3 4\nusemtl\nf 2 3 4\n");
        let c = convert_with(&text, Some(MTL), &[]);
        let doc = read(&c);
        let prims = primitives(&doc);
        let materials: Vec<Option<usize>> = prims[0].iter().map(|p| p.material).collect();
        assert_eq!(materials, [Some(0), Some(1), None]);
        let nowhere = doc.materials().next().unwrap();
        assert_eq!(names(&c, "materials"), some(&["nowhere", "plain"]));
        assert_eq!(nowhere.pbr_metallic_roughness().metallic_factor(), 0.0);
        assert_eq!(
            nowhere.pbr_metallic_roughness().base_color_factor(),
            [1.0; 4]
        );
        assert!(
            c.messages()
                .iter()
                .any(|w| w.contains("not in the MTL") && w.contains("\"nowhere\""))
        );

        // Without an MTL: no materials at all, and a warning.
        let c = convert(&text);
        with_json(&c, |root| assert!(root.get("materials").is_none()));
        assert!(
            primitives(&read(&c))[0]
                .iter()
                .all(|p| p.material.is_none())
        );
        // The three usemtl runs are three primitives even without materials.
        assert_eq!(c.stats.primitives, 3);
        assert!(c.messages().iter().any(|w| w.contains("no MTL was given")));
    }

    #[test]
    fn textured_material_on_faces_without_uvs_gets_an_untextured_copy() {
        let text = format!("{QUAD}usemtl glass\nf 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 4//1\n");
        let c = convert_with(&text, Some(MTL), &[]);
        let doc = read(&c);
        let prims = primitives(&doc);
        assert_eq!(prims[0][0].material, Some(0));
        assert_eq!(prims[0][1].material, Some(1));
        let copy = doc.materials().nth(1).unwrap();
        assert_eq!(names(&c, "materials"), some(&["glass", "glass"]));
        assert!(copy.normal_texture().is_none());
        assert!(copy.pbr_metallic_roughness().base_color_texture().is_none());
        assert_eq!(
            copy.pbr_metallic_roughness().base_color_factor(),
            [0.1, 0.2, 0.3, 0.25]
        );
        assert!(
            c.messages()
                .iter()
                .any(|w| w.contains("got a copy without textures"))
        );
        // Only the UV-less use: no textures or images at all.
        let text = format!("{QUAD}usemtl glass\nf 1 3 4\n");
        let c = convert_with(&text, Some(MTL), &[]);
        with_json(&c, |root| {
            assert!(root.get("textures").is_none() && root.get("images").is_none());
            assert!(
                root.get("extensionsUsed")
                    .unwrap()
                    .as_array()
                    .unwrap()
                    .len()
                    == 1
            );
        });
    }

    #[test]
    fn images_embedded_when_supplied_referenced_when_not() {
        let mtl = "newmtl a\nmap_Kd .\\tex\\a.jpg\nnewmtl b\nmap_Kd C:\\Users\\me\\b 1%.png\n\
                   newmtl c\nmap_Kd /abs/c.webp\nnewmtl d\nmap_Kd tex/a.jpg\nnorm d.tga\n\
                   newmtl e\nmap_Kd sub/dir/é e#1.png\nnewmtl f\nmap_Kd textures/\n";
        let mut text = QUAD.to_owned();
        for m in ["a", "b", "c", "d", "e", "f"] {
            text += &format!("usemtl {m}\nf 1/1 2/2 3/3\n");
        }
        let c = convert_with(
            &text,
            Some(mtl),
            &[("a.jpg", JPEG), ("c.webp", WEBP), ("d.tga", b"TGA?")],
        );
        with_json(&c, |root| {
            let images = root.get("images").unwrap().as_array().unwrap();
            let summary: Vec<String> = images
                .iter()
                .map(|i| {
                    let name = i.get("name").unwrap().as_str().unwrap();
                    match i.get("uri") {
                        Some(uri) => format!("{name} uri {}", uri.as_str().unwrap()),
                        None => format!(
                            "{name} view {} {}",
                            i.get("bufferView").unwrap().as_u64().unwrap(),
                            i.get("mimeType").unwrap().as_str().unwrap()
                        ),
                    }
                })
                .collect();
            let views = root.get("bufferViews").unwrap().as_array().unwrap();
            let last = views.len() as u64;
            assert_eq!(
                summary,
                [
                    format!("a.jpg view {} image/jpeg", last - 2),
                    "b 1%.png uri b%201%25.png".to_owned(),
                    format!("c.webp view {} image/webp", last - 1),
                    "d.tga uri d.tga".to_owned(),
                    "é e#1.png uri sub/dir/%C3%A9%20e%231.png".to_owned(),
                ]
            );
            // `.\tex\a.jpg` and `tex/a.jpg` are one image.
            let textures = root.get("textures").unwrap().as_array().unwrap();
            assert_eq!(textures.len(), 5);
            let webp = &textures[2];
            assert!(webp.get("source").is_none());
            let ext = webp.get("extensions").unwrap().get(TEXTURE_WEBP).unwrap();
            assert_eq!(ext.get("source").unwrap().as_u64(), Some(2));
            for key in ["extensionsUsed", "extensionsRequired"] {
                let list = root.get(key).unwrap().as_array().unwrap();
                assert_eq!(list.len(), 1);
                assert_eq!(list[0].as_str(), Some(TEXTURE_WEBP));
            }
            let materials = root.get("materials").unwrap().as_array().unwrap();
            assert_eq!(materials.len(), 6);
            assert!(
                materials[5]
                    .get("pbrMetallicRoughness")
                    .unwrap()
                    .get("baseColorTexture")
                    .is_none()
            );
            for (view, bytes) in [(last - 2, JPEG), (last - 1, WEBP)] {
                let v = views[view as usize].clone();
                let offset = v.get("byteOffset").unwrap().as_u64().unwrap() as usize;
                let length = v.get("byteLength").unwrap().as_u64().unwrap() as usize;
                assert_eq!(offset % 4, 0);
                assert!(v.get("target").is_none());
                assert_eq!(&c.bin[offset..offset + length], bytes);
            }
        });
        assert_eq!((c.stats.images_embedded, c.stats.images_referenced), (2, 3));
        let joined = c.messages().join("\n");
        for expected in [
            "kept as their file name only: \"C:\\\\Users\\\\me\\\\b 1%.png\", \"/abs/c.webp\"",
            "not supplied, referenced by relative URI instead of embedded: \"b 1%.png\", \
             \"sub/dir/é e#1.png\"",
            "not PNG, JPEG or WebP, which glTF cannot embed; referenced by relative URI: \"d.tga\"",
            "without a file name, ignored: \"textures/\"",
        ] {
            assert!(joined.contains(expected), "{expected} not in {joined}");
        }
    }

    #[test]
    fn index_width_switches_to_u32_past_65535_vertices() {
        for vertices in [65535usize, 65536] {
            let mut obj = Obj {
                positions: (0..vertices)
                    .map(|i| [i as f32, (i % 7) as f32, 0.0])
                    .collect(),
                normals: vec![[0.0, 0.0, 1.0]],
                ..Obj::default()
            };
            let mut triangles: Vec<[Corner; 3]> = (0..vertices / 3)
                .map(|t| [0, 1, 2].map(|k| Corner::new((3 * t + k) as u32, None, Some(0))))
                .collect();
            if vertices % 3 != 0 {
                triangles.push([vertices - 1, 0, 1].map(|p| Corner::new(p as u32, None, Some(0))));
            }
            obj.groups.push(FaceGroup {
                smoothing: vec![0; triangles.len()],
                triangles,
                ..FaceGroup::default()
            });
            let c = convert_obj(&obj).unwrap();
            let prims = assert_faithful(&obj, &c);
            assert_eq!(prims[0][0].positions.len(), vertices);
            assert_eq!(
                *prims[0][0].indices.iter().max().unwrap() as usize,
                vertices - 1
            );
        }
    }

    /// A file read in chunks may come with a run split where a chunk ended (see `FaceGroup`):
    /// the conversion must not see the difference.
    #[test]
    fn a_run_split_into_groups_of_the_same_key_converts_as_one_run() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nvt 0 0\nvt 1 0\n\
                    vt 1 1\nvn 0 0 1\nvn 0 1 0\no a\nusemtl m\ns 1\nf 1/1/1 2/2/1 3/3/1\n\
                    f 1/1 3/3 4/2\ns off\nf 1 2 5\nf 2 6 5\nusemtl n\nf 1/1/2 2/2/2 6/3/2\n\
                    f 4 3 6 5\no b\nf 1 2 3\nf 3 4 1\nusemtl m\nf 1 5 6\n";
        let whole = obj(text);
        assert_eq!(whole.groups.len(), 4);
        let whole_converted = convert_obj(&whole).unwrap();
        // Every way of cutting each group at one place, and every group cut everywhere.
        let cut = |at: &dyn Fn(usize, usize) -> Vec<usize>| {
            let mut split = whole.clone();
            split.groups = whole
                .groups
                .iter()
                .enumerate()
                .flat_map(|(g, group)| {
                    let mut ends = at(g, group.triangles.len());
                    ends.push(group.triangles.len());
                    let mut start = 0;
                    ends.into_iter().map(move |end| {
                        let piece = FaceGroup {
                            triangles: group.triangles[start..end].to_vec(),
                            smoothing: group.smoothing[start..end].to_vec(),
                            ..group.clone()
                        };
                        start = end;
                        piece
                    })
                })
                .collect();
            split
        };
        let mut tried = 0;
        for g in 0..whole.groups.len() {
            for place in 0..=whole.groups[g].triangles.len() {
                let split = cut(&|group, _| if group == g { vec![place] } else { vec![] });
                assert_eq!(split.groups.len(), whole.groups.len() + 1);
                assert_eq!(
                    convert_obj(&split).unwrap(),
                    whole_converted,
                    "group {g} at {place}"
                );
                tried += 1;
            }
        }
        let everywhere = cut(&|_, len| (0..len).collect());
        assert!(everywhere.groups.len() > 2 * whole.groups.len());
        assert_eq!(convert_obj(&everywhere).unwrap(), whole_converted);
        assert!(tried > 8);
    }

    #[test]
    fn unusable_normals_and_uvs_are_dropped_per_triangle_and_bad_positions_drop_it() {
        // Triangle 1 has NaN and infinite positions: dropped. Triangle 2 has a NaN UV, 3 a
        // normal of zero length, 4 nothing but positions.
        let text = "v 0 0 0\nv 1 nan 0\nv 0 1 inf\nv 0 0 0\nv 1 1 1\nvt 0 nan\nvt 0.5 0.5\n\
                    vn 0 0 0\nvn 0 3 4\nf 1/2/2 2/2/2 3/2/2\nf 1/1/2 4/2/2 5/2/2\n\
                    f 1/2/1 4/2/2 5/2/2\nf 1 4 5\n";
        let c = convert(text);
        let doc = read(&c);
        let mesh = doc.meshes().next().unwrap();
        let counts: Vec<(bool, usize)> = mesh
            .primitives()
            .map(|p| {
                let uv = p.get(&gltf::Semantic::TexCoords(0)).is_some();
                (uv, p.indices().map_or(0, |i| i.count()) / 3)
            })
            .collect();
        // Triangles 2 and 4 share the primitive without UVs (first used by 2); 3 keeps its UVs.
        assert_eq!(counts, [(false, 2), (true, 1)]);
        for p in mesh.primitives() {
            let b = p.bounding_box();
            assert_eq!((b.min, b.max), ([0.0; 3], [1.0; 3]));
        }
        assert_eq!(
            c.messages(),
            [
                "1 triangles have a NaN or infinite position and were dropped: they cannot be \
                 drawn, and glTF does not allow non-finite values",
                "1 triangles use a normal of zero length or not finite, which glTF does not \
                 allow; they were given generated normals, as faces without vn are",
                "1 triangles use a texture coordinate that is NaN or infinite; they were written \
                 without texture coordinates",
                "normals generated for 2 triangles without vn: smooth, with edges sharper than \
                 60° kept hard (the OBJ has no smoothing groups); normals=flat for faceted, \
                 normals_angle to change the angle",
            ]
        );
        // Nothing left to draw: refused, as an OBJ without faces is.
        let o = obj("v 0 nan 0\nv 1 inf 0\nv 0 -inf 1\nf 1 2 3\n");
        let err = convert_obj(&o).unwrap_err();
        assert_eq!(err, ConvertError::NoFiniteTriangles { triangles: 1 });
        assert!(err.to_string().contains("NaN or infinite position"));
    }

    #[test]
    fn errors_are_clear() {
        let none = PartSet::new();
        let limits = ConvertLimits::default();
        for text in ["", "v 0 0 0\nv 1 0 0\nl 1 2\np 1\nf 1 2\n"] {
            let err = obj_to_gltf(&obj(text), None, &none, NormalRequest::default(), &limits)
                .unwrap_err();
            assert_eq!(err, ConvertError::NoFaces);
            assert!(err.to_string().contains("no faces"));
        }
        let mut bad = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let corner = &mut bad.groups[0].triangles[0][1];
        *corner = corner.with_normal(Some(5));
        assert_eq!(
            obj_to_gltf(&bad, None, &none, NormalRequest::default(), &limits).unwrap_err(),
            ConvertError::IndexOutOfRange {
                what: "normal",
                index: 5,
                count: 0
            }
        );
        let mut bad = obj("v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        bad.colors.as_mut().unwrap().truncate(1);
        assert!(matches!(
            obj_to_gltf(&bad, None, &none, NormalRequest::default(), &limits).unwrap_err(),
            ConvertError::IndexOutOfRange {
                what: "vertex colour",
                ..
            }
        ));
        let good = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        // 3 positions and 3 generated normals (36 bytes each) and 3 u16 indices (6, padded to 8).
        let tight = ConvertLimits {
            max_buffer_bytes: 80,
        };
        assert_eq!(
            obj_to_gltf(&good, None, &none, NormalRequest::default(), &tight)
                .unwrap()
                .bin
                .len(),
            80
        );
        let err = obj_to_gltf(
            &good,
            None,
            &none,
            NormalRequest::default(),
            &ConvertLimits {
                max_buffer_bytes: 79,
            },
        )
        .unwrap_err();
        assert!(matches!(
            err,
            ConvertError::TooLarge {
                value: 80,
                limit: 79,
                ..
            }
        ));
        assert!(err.to_string().contains("80"));
    }

    #[test]
    fn paths_and_uris() {
        let clean = |p: &str| clean_path(p).map(|c| (c.path, c.file_name, c.reduced));
        let s = |x: &str| x.to_owned();
        assert_eq!(clean(".\\a.jpg"), Some((s("a.jpg"), s("a.jpg"), false)));
        assert_eq!(
            clean("x//./y/b.png"),
            Some((s("x/y/b.png"), s("b.png"), false))
        );
        assert_eq!(clean("../b.png"), Some((s("b.png"), s("b.png"), true)));
        assert_eq!(clean("x/../b.png"), Some((s("b.png"), s("b.png"), true)));
        assert_eq!(clean("/b.png"), Some((s("b.png"), s("b.png"), true)));
        assert_eq!(
            clean("\\\\server\\share\\b.png"),
            Some((s("b.png"), s("b.png"), true))
        );
        assert_eq!(clean("C:b.png"), Some((s("b.png"), s("b.png"), true)));
        assert_eq!(
            clean("http://h/x.png"),
            Some((s("x.png"), s("x.png"), true))
        );
        for bad in ["", ".", "..", "a/", "a/..", "C:", "./"] {
            assert!(clean(bad).is_none(), "{bad}");
        }
        assert_eq!(
            percent_encode_path("a b/%20:?#~é.png"),
            "a%20b/%2520%3A%3F%23~%C3%A9.png"
        );
    }

    fn fixture(path: &str) -> Option<Vec<u8>> {
        let full = format!("{}/fixtures/{path}", env!("CARGO_MANIFEST_DIR"));
        let bytes = std::fs::read(&full).ok();
        if bytes.is_none() {
            eprintln!("skipping: {full} is absent");
        }
        bytes
    }

    /// For each (object, material, has uv, has normal), the distinct corner triples.
    fn distinct_corners(obj: &Obj) -> usize {
        type Key<'o> = (Option<&'o str>, Option<&'o str>, bool, bool, Corner);
        let mut seen: HashSet<Key<'_>> = HashSet::new();
        for g in &obj.groups {
            let drawn = g.triangles.iter().filter(|t| finite_positions(obj, t));
            for c in drawn.flat_map(|t| kept(obj, t)) {
                seen.insert((
                    g.object.as_deref(),
                    g.material.as_deref(),
                    c.uv().is_some(),
                    c.normal().is_some(),
                    c,
                ));
            }
        }
        seen.len()
    }

    #[test]
    fn spider_with_its_materials_and_one_supplied_texture() {
        let (Some(obj_bytes), Some(mtl_bytes)) =
            (fixture("spider/spider.obj"), fixture("spider/spider.mtl"))
        else {
            return;
        };
        let obj = parse_obj(&obj_bytes, &Limits::default()).unwrap();
        let mtl = parse_mtl(&mtl_bytes).unwrap();
        let mut parts = PartSet::new();
        parts.insert("SpiderTex.jpg", JPEG).unwrap();
        let c = obj_to_gltf(
            &obj,
            Some(&mtl),
            &parts,
            NormalRequest::default(),
            &ConvertLimits::default(),
        )
        .unwrap();
        let prims = assert_faithful(&obj, &c);
        assert!(c.stats.vertices >= distinct_corners(&obj));
        assert_eq!(prims.len(), 1);
        // 19 groups, 4 materials used, every face with UVs and normals, but one `vn 0 0 0`
        // (used by 32 corners): the 52 triangles using it get generated normals instead and
        // stay in their material's primitive.
        let shape: Vec<(Option<usize>, bool, bool, usize)> = prims[0]
            .iter()
            .map(|p| {
                (
                    p.material,
                    p.uvs.is_some(),
                    p.normals.is_some(),
                    p.indices.len() / 3,
                )
            })
            .collect();
        assert_eq!(
            shape,
            [
                (Some(0), true, true, 80),
                (Some(1), true, true, 260),
                (Some(2), true, true, 952),
                (Some(3), true, true, 76)
            ]
        );
        let doc = read(&c);
        assert_eq!(names(&c, "nodes"), [None]);
        assert_eq!(
            names(&c, "materials"),
            some(&["HLeibTex", "Skin", "BeinTex", "Augentex"])
        );
        let images: Vec<String> = doc
            .images()
            .map(|i| match i.source() {
                gltf::image::Source::View { mime_type, .. } => format!("embedded {mime_type}"),
                gltf::image::Source::Uri { uri, .. } => uri.to_owned(),
            })
            .collect();
        assert_eq!(
            images,
            [
                "embedded image/jpeg",
                "wal67ar_small.jpg",
                "drkwood2.jpg",
                "engineflare1.jpg"
            ]
        );
        for m in doc.materials() {
            let pbr = m.pbr_metallic_roughness();
            assert!(pbr.base_color_texture().is_some());
            // Ns 0 and a black Ks: fully rough, non-metallic.
            assert_eq!((pbr.metallic_factor(), pbr.roughness_factor()), (0.0, 1.0));
        }
        assert_eq!(c.stats.images_embedded, 1);
        assert_eq!(c.messages().len(), 3, "{:?}", c.messages());
        assert!(c.messages()[0].contains("use a normal of zero length"));
        // The spider has `s` statements: its smoothing groups are honoured.
        assert!(c.messages()[1].starts_with(
            "normals generated for 52 triangles without vn: smooth within the OBJ's smoothing \
             groups (s)"
        ));
        assert!(c.messages()[2].contains("\"wal67ar_small.jpg\", \"drkwood2.jpg\""));
    }

    #[test]
    fn concave_polygon_and_negative_indices() {
        if let (Some(obj_bytes), Some(mtl_bytes)) = (
            fixture("concave_polygon/concave_polygon.obj"),
            fixture("concave_polygon/concave_polygon.mtl"),
        ) {
            let obj = parse_obj(&obj_bytes, &Limits::default()).unwrap();
            let mtl = parse_mtl(&mtl_bytes).unwrap();
            let c = obj_to_gltf(
                &obj,
                Some(&mtl),
                &PartSet::new(),
                NormalRequest::default(),
                &ConvertLimits::default(),
            )
            .unwrap();
            let prims = assert_faithful(&obj, &c);
            assert_eq!(c.stats.vertices, distinct_corners(&obj));
            let p = &prims[0][0];
            assert_eq!((p.indices.len(), p.positions.len()), (192, 64));
            assert!(p.uvs.is_none() && p.normals.is_some());
            let doc = read(&c);
            assert_eq!(names(&c, "nodes"), some(&["concave_test.obj"]));
            assert_eq!(names(&c, "materials"), some(&["test"]));
            let m = doc.materials().next().unwrap();
            assert_eq!(
                m.pbr_metallic_roughness().base_color_factor(),
                [0.141176, 0.184314, 0.411765, 1.0]
            );
            assert!(c.messages().is_empty(), "{:?}", c.messages());
        }
        if let Some(bytes) = fixture("negative_indices/negative_indices.obj") {
            let obj = parse_obj(&bytes, &Limits::default()).unwrap();
            let c = convert_obj(&obj).unwrap();
            let prims = assert_faithful(&obj, &c);
            assert_eq!(c.stats.vertices, distinct_corners(&obj));
            assert_eq!(prims[0].len(), 1);
            assert_eq!(prims[0][0].indices.len(), 36);
            assert!(prims[0][0].uvs.is_some() && prims[0][0].normals.is_some());
        }
    }

    /// The vertices [`CornerWeld`] gives a sequence of (primitive, corner) lookups, against
    /// numbering each primitive's distinct corners by first use with a plain map.
    fn weld_against_a_map(weld: &mut CornerWeld, lookups: &[(usize, Corner)]) {
        let mut counts = [0u32; 3];
        let mut expected = HashMap::new();
        for &(slot, corner) in lookups {
            let next = counts[slot];
            let want = *expected.entry((slot, corner)).or_insert(next);
            let (got, new) = weld.vertex(slot, corner, next).unwrap();
            assert_eq!((got, new), (want, want == next), "{slot} {corner:?}");
            counts[slot] += u32::from(new);
        }
    }

    #[test]
    fn a_position_with_more_vertices_than_a_chain_holds_still_welds_exactly() {
        let mut weld = CornerWeld::new(2);
        // Three times a chain's length of texture coordinates at one position, in two
        // primitives, each asked for again in reverse order.
        let uvs = 0..3 * CHAIN_LIMIT as u32;
        let corner = |uv| Corner::new(1, Some(uv), None);
        let mut lookups: Vec<(usize, Corner)> = Vec::new();
        for slot in [0, 1] {
            lookups.extend(uvs.clone().map(|uv| (slot, corner(uv))));
        }
        let again: Vec<_> = lookups.iter().rev().copied().collect();
        lookups.extend(again);
        weld_against_a_map(&mut weld, &lookups);
        assert!(!weld.overflow.is_empty());
        // The next mesh starts from nothing, and a position the table lacks is refused.
        weld.clear();
        assert!(weld.heads.iter().all(|&h| h == NO_ENTRY) && weld.overflow.is_empty());
        weld_against_a_map(&mut weld, &lookups[..5]);
        assert_eq!(weld.vertex(0, Corner::new(2, Some(0), None), 0), None);
    }

    proptest! {
        #[test]
        fn the_corner_weld_numbers_corners_as_a_map_does(
            lookups in proptest::collection::vec(
                (0..3usize, 0..4u32, proptest::option::of(0..40u32), proptest::option::of(0..3u32)),
                0..400,
            )
        ) {
            let lookups: Vec<(usize, Corner)> = lookups
                .into_iter()
                .map(|(slot, position, uv, normal)| (slot, Corner::new(position, uv, normal)))
                .collect();
            weld_against_a_map(&mut CornerWeld::new(4), &lookups);
        }
    }

    proptest! {
        #[test]
        fn obj_like_text_converts_faithfully_or_fails_cleanly(
            parts in proptest::collection::vec(
                prop::sample::select(vec![
                    "v 0 0 0\n", "v 1 0 0\n", "v 0 1 0 0.5 0.5 0.5\n", "v 1 1 nan\n", "vt 0.5 1\n",
                    "vn 0 0 1\n", "vn 0 0 0\n", "f 1 2 3\n", "f -1 -2 -3 -4\n", "f 1/1 2/1 3/1\n",
                    "f 1//1 2//1 3//2\n", "f 1/1/1 2/1/1 3/1/1\n", "f 3/1/2 2/1/1 4/1/1\n",
                    "o a\n", "o b\n", "g x\n", "usemtl m\n", "usemtl n\n", "usemtl\n",
                ]),
                0..40,
            )
        ) {
            let text: String = parts.concat();
            let Ok(obj) = parse_obj(text.as_bytes(), &Limits::default()) else {
                return Ok(());
            };
            let mtl = parse_mtl(b"newmtl m\nKd 1 0 0\nmap_Kd m.png\nnorm -bm 2 -s 2 2 n.png\n")
                .unwrap();
            let mut set = PartSet::new();
            set.insert("m.png", PNG).unwrap();
            match obj_to_gltf(&obj, Some(&mtl), &set, NormalRequest::default(), &ConvertLimits::default()) {
                Ok(c) => {
                    assert_faithful(&obj, &c);
                    // Generated normals may split a corner, never merge two.
                    prop_assert!(c.stats.vertices >= distinct_corners(&obj));
                }
                Err(ConvertError::NoFaces) => prop_assert_eq!(obj.triangle_count(), 0),
                Err(ConvertError::NoFiniteTriangles { .. }) => {}
                Err(e) => prop_assert!(false, "{e}"),
            }
        }
    }
}
