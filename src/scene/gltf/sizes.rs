//! Mesh bytes: what a scene's geometry takes in its file, per primitive and in all, and how it is
//! compressed, so that the report can say what tspace did to a pipeline's sizes.
//!
//! A primitive's bytes are those of every buffer view its accessors (attributes, indices, morph
//! targets, sparse parts) and its Draco stream read, each view once; a meshopt-compressed view
//! counts at its compressed size, which is what the file holds. The scene's total counts each
//! view once, however many primitives share it. Images, animations and skins are not mesh bytes.

use super::draco;
use crate::scene::index32;
use std::borrow::Cow;
use tspace_json::{Node, Number};

/// How a primitive's geometry is stored: the report's own type.
pub use crate::scene::report::MeshCompression as Compression;

/// One primitive's storage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveSize {
    pub compression: Compression,
    pub bytes: u64,
}

/// A document's mesh storage.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MeshSizes {
    /// Every primitive's, mesh by mesh in order: one flat list, since it is kept while the
    /// scene is written and a scene may have a hundred thousand primitives (a map took three
    /// times the room).
    primitives: Vec<PrimitiveSize>,
    /// Where each mesh's primitives start in `primitives`, and one past the last.
    mesh_starts: Vec<usize>,
    pub total: u64,
}

impl MeshSizes {
    /// Primitive `primitive` of mesh `mesh`.
    pub fn primitive(&self, (mesh, primitive): (usize, usize)) -> Option<&PrimitiveSize> {
        let start = *self.mesh_starts.get(mesh)?;
        let end = *self.mesh_starts.get(mesh + 1)?;
        self.primitives.get(start..end)?.get(primitive)
    }
}

/// Measures the mesh storage a document declares (lengths from the JSON; no bytes are read).
pub fn measure(root: &Node) -> MeshSizes {
    Facts::of_tree(root).measure()
}

/// [`measure`] on a document's text, read without a tree: for tspace's own output, which the
/// report measures after writing it. A tree of it, even of only the members measuring reads,
/// cost a fifth of processing a scene of many small primitives (165 ms of 730 on the
/// JSON-heavy scene). `None` when the text is not the JSON object it should be.
pub fn measure_text(json: &[u8]) -> Option<MeshSizes> {
    Some(Facts::of_text(json)?.measure())
}

/// What measuring reads of a document, in flat lists.
#[derive(Debug, Default, PartialEq, Eq)]
struct Facts {
    /// Per buffer view: what it takes in the file, and whether that is meshopt-compressed.
    views: Vec<(u64, bool)>,
    /// Per accessor: the views it reads (its own, its sparse indices', its sparse values').
    accessors: Vec<[Option<u32>; 3]>,
    /// Per primitive, mesh by mesh: where its accessors end in `primitive_accessors`, and its
    /// Draco stream (whether it has the extension, and the extension's view).
    primitives: Vec<(u32, bool, Option<u32>)>,
    /// The accessors of each primitive's attributes, targets and indices, in turn. Positions
    /// are 32-bit ([`index32`]): the output's lists are measured beside the output and the
    /// report, and a scene of 100,000 primitives holds half a million of them.
    primitive_accessors: Vec<u32>,
    /// Where each mesh's primitives start in `primitives`.
    mesh_starts: Vec<usize>,
}

impl Facts {
    fn of_tree(root: &Node) -> Facts {
        let mut facts = Facts {
            views: array(root.get("bufferViews"))
                .iter()
                .map(|view| (view_bytes(Some(view)), meshopt_length(Some(view)).is_some()))
                .collect(),
            accessors: array(root.get("accessors"))
                .iter()
                .map(|accessor| {
                    let sparse = |part| index(accessor.get("sparse")?.get(part)?.get("bufferView"));
                    [
                        index(accessor.get("bufferView")),
                        sparse("indices"),
                        sparse("values"),
                    ]
                })
                .collect(),
            ..Facts::default()
        };
        for mesh in array(root.get("meshes")) {
            facts.mesh_starts.push(facts.primitives.len());
            for primitive in array(mesh.get("primitives")) {
                let mut add_object = |object: Option<&Node>| {
                    for member in object.and_then(Node::as_object).unwrap_or(&[]) {
                        facts.primitive_accessors.extend(index(Some(&member.value)));
                    }
                };
                add_object(primitive.get("attributes"));
                for target in array(primitive.get("targets")) {
                    add_object(Some(target));
                }
                facts
                    .primitive_accessors
                    .extend(index(primitive.get("indices")));
                let draco = draco::extension(primitive);
                facts.primitives.push((
                    index32(facts.primitive_accessors.len()),
                    draco.is_some(),
                    index(draco.and_then(|e| e.get("bufferView"))),
                ));
            }
        }
        facts
    }

    fn of_text(json: &[u8]) -> Option<Facts> {
        let mut facts = Facts::default();
        let mut text = Scanner::new(json);
        let is_object = text.members(|text, key| match key.as_ref() {
            b"bufferViews" => text.elements(|text| {
                let view = text.view()?;
                facts.views.push(view);
                Some(())
            }),
            b"accessors" => text.elements(|text| {
                let accessor = text.accessor()?;
                facts.accessors.push(accessor);
                Some(())
            }),
            b"meshes" => text.elements(|text| {
                facts.mesh_starts.push(facts.primitives.len());
                text.members(|text, key| match key.as_ref() {
                    b"primitives" => text.elements(|text| text.primitive(&mut facts)),
                    _ => text.skip(),
                })
                .map(drop)
            }),
            _ => text.skip(),
        })?;
        (is_object && text.at_end()).then_some(facts)
    }

    fn measure(&self) -> MeshSizes {
        let mut sizes = MeshSizes {
            primitives: Vec::with_capacity(self.primitives.len()),
            mesh_starts: Vec::with_capacity(self.mesh_starts.len() + 1),
            total: 0,
        };
        sizes.mesh_starts.extend(&self.mesh_starts);
        sizes.mesh_starts.push(self.primitives.len());
        // Per view: whether some primitive reads it. A scene of 50,000 primitives measured each
        // one's views in sets and maps; flat lists do the same without the allocations.
        let mut read = vec![false; self.views.len()];
        let mut used: Vec<usize> = Vec::new();
        let mut accessors_start = 0;
        let at = |i: u32| usize::try_from(i).unwrap_or(usize::MAX);
        for &(accessors_end, draco, draco_view) in &self.primitives {
            used.clear();
            let accessors_end = at(accessors_end);
            let accessors = self
                .primitive_accessors
                .get(accessors_start..accessors_end)
                .unwrap_or(&[]);
            accessors_start = accessors_end;
            for &a in accessors {
                let views = self.accessors.get(at(a)).into_iter().flatten().flatten();
                used.extend(views.map(|&v| at(v)));
            }
            used.extend(draco_view.map(at));
            used.sort_unstable();
            used.dedup();
            let meshopt = used.iter().any(|&v| self.views.get(v).is_some_and(|v| v.1));
            let compression = if draco {
                Compression::Draco
            } else if meshopt {
                Compression::Meshopt
            } else {
                Compression::None
            };
            let bytes = used
                .iter()
                .map(|&v| self.views.get(v).map_or(0, |v| v.0))
                .sum();
            sizes.primitives.push(PrimitiveSize { compression, bytes });
            for &v in &used {
                if let Some(read) = read.get_mut(v) {
                    *read = true;
                }
            }
        }
        sizes.total = (self.views.iter().zip(&read))
            .filter(|&(_, &read)| read)
            .map(|(view, _)| view.0)
            .sum();
        sizes
    }
}

fn array(node: Option<&Node>) -> &[Node] {
    node.and_then(Node::as_array).unwrap_or(&[])
}

/// An index into one of the document's arrays; one past 32 bits is past every array's end.
fn index(node: Option<&Node>) -> Option<u32> {
    node?.as_u64().and_then(|i| u32::try_from(i).ok())
}

/// A meshopt-compressed view's compressed length.
fn meshopt_length(view: Option<&Node>) -> Option<u64> {
    let extensions = view?.get("extensions")?;
    MESHOPT
        .iter()
        .find_map(|name| extensions.get(name)?.get("byteLength")?.as_u64())
}

/// What a view takes in the file: its compressed length when meshopt-compressed.
fn view_bytes(view: Option<&Node>) -> u64 {
    meshopt_length(view)
        .or_else(|| view?.get("byteLength")?.as_u64())
        .unwrap_or(0)
}

const MESHOPT: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// The bytes that start or end a string or a container: what [`Scanner::skip`] stops at.
const STRUCTURAL: [bool; 256] = {
    let mut table = [false; 256];
    let mut i = 0;
    let bytes = *b"\"{}[]";
    while i < bytes.len() {
        table[bytes[i] as usize] = true;
        i += 1;
    }
    table
};

/// A reader of a JSON text that was parsed and checked before (tspace's own output): it walks
/// the members measuring reads and skips the rest by their brackets, allocating nothing but
/// what it keeps. It reads numbers and keys as the parser does ([`Number::from_text`], escapes
/// decoded), so that it finds what [`Facts::of_tree`] finds; every method consumes exactly one
/// value, and `None` means the text is not JSON after all.
struct Scanner<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Scanner<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        let bom = b"\xEF\xBB\xBF";
        let mut scanner = Scanner {
            bytes,
            pos: if bytes.starts_with(bom) { bom.len() } else { 0 },
        };
        scanner.skip_ws();
        scanner
    }

    fn skip_ws(&mut self) {
        while let Some(b' ' | b'\t' | b'\n' | b'\r') = self.bytes.get(self.pos) {
            self.pos += 1;
        }
    }

    fn at_end(&mut self) -> bool {
        self.skip_ws();
        self.pos == self.bytes.len()
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn eat(&mut self, byte: u8) -> Option<()> {
        self.skip_ws();
        (self.peek()? == byte).then(|| self.pos += 1)
    }

    /// A string's text between its quotes, escapes as written; and whether it has any.
    fn raw_string(&mut self) -> Option<(&'a [u8], bool)> {
        self.eat(b'"')?;
        let start = self.pos;
        let mut escaped = false;
        loop {
            match *self.bytes.get(self.pos)? {
                b'"' => break,
                b'\\' => {
                    escaped = true;
                    self.pos += 2;
                }
                _ => self.pos += 1,
            }
        }
        let text = self.bytes.get(start..self.pos)?;
        self.pos += 1;
        Some((text, escaped))
    }

    /// A key, decoded when it has escapes (`"by\u0074eLength"` is `byteLength`).
    fn key(&mut self) -> Option<Cow<'a, [u8]>> {
        let start = self.pos;
        let (raw, escaped) = self.raw_string()?;
        if !escaped {
            return Some(Cow::Borrowed(raw));
        }
        let quoted = self.bytes.get(start..self.pos)?;
        let decoded: String = serde_json::from_slice(quoted).ok()?;
        Some(Cow::Owned(decoded.into_bytes()))
    }

    /// Calls `each` with every member's key, `each` reading its value. `Some(false)` (and the
    /// value skipped) when the value is not an object.
    fn members(
        &mut self,
        mut each: impl FnMut(&mut Self, Cow<'a, [u8]>) -> Option<()>,
    ) -> Option<bool> {
        self.skip_ws();
        if self.peek()? != b'{' {
            self.skip()?;
            return Some(false);
        }
        self.pos += 1;
        self.skip_ws();
        if self.peek()? == b'}' {
            self.pos += 1;
            return Some(true);
        }
        loop {
            self.skip_ws();
            let key = self.key()?;
            self.eat(b':')?;
            each(self, key)?;
            self.skip_ws();
            match self.peek()? {
                b',' => self.pos += 1,
                b'}' => {
                    self.pos += 1;
                    return Some(true);
                }
                _ => return None,
            }
        }
    }

    /// Calls `each` to read every element. `Some(false)` (and the value skipped) when the
    /// value is not an array.
    fn elements(&mut self, mut each: impl FnMut(&mut Self) -> Option<()>) -> Option<()> {
        self.skip_ws();
        if self.peek()? != b'[' {
            return self.skip();
        }
        self.pos += 1;
        self.skip_ws();
        if self.peek()? == b']' {
            self.pos += 1;
            return Some(());
        }
        loop {
            each(self)?;
            self.skip_ws();
            match self.peek()? {
                b',' => self.pos += 1,
                b']' => {
                    self.pos += 1;
                    return Some(());
                }
                _ => return None,
            }
        }
    }

    /// Any value, read past.
    fn skip(&mut self) -> Option<()> {
        self.skip_ws();
        match self.peek()? {
            b'"' => self.raw_string().map(drop),
            b'{' | b'[' => {
                let bytes = self.bytes;
                let mut depth = 0usize;
                loop {
                    // Numbers, commas, colons and spaces, most of what is skipped, a byte a
                    // step with one test each.
                    while bytes
                        .get(self.pos)
                        .is_some_and(|&b| !STRUCTURAL[usize::from(b)])
                    {
                        self.pos += 1;
                    }
                    match *bytes.get(self.pos)? {
                        b'"' => {
                            self.raw_string()?;
                            continue;
                        }
                        b'{' | b'[' => depth += 1,
                        _ => {
                            depth -= 1;
                            if depth == 0 {
                                self.pos += 1;
                                return Some(());
                            }
                        }
                    }
                    self.pos += 1;
                }
            }
            _ => self.scalar().map(drop),
        }
    }

    /// A number's, `true`'s, `false`'s or `null`'s text.
    fn scalar(&mut self) -> Option<&'a [u8]> {
        let start = self.pos;
        while let Some(byte) = self.peek() {
            if matches!(byte, b',' | b'}' | b']' | b' ' | b'\t' | b'\n' | b'\r') {
                break;
            }
            self.pos += 1;
        }
        (self.pos > start)
            .then(|| self.bytes.get(start..self.pos))
            .flatten()
    }

    /// A value read as [`Node::as_u64`] reads it: a number that is an integer, else `None`
    /// (and the value skipped).
    fn length(&mut self) -> Option<Option<u64>> {
        self.skip_ws();
        if !matches!(self.peek()?, b'-' | b'0'..=b'9') {
            self.skip()?;
            return Some(None);
        }
        let text = self.scalar()?;
        // Plain digits, as nearly every index and length is spelled, read at once; the text
        // was checked, so they are a JSON number (19 always fit).
        if text.len() <= 19 && text.iter().all(u8::is_ascii_digit) {
            return Some(Some(
                text.iter()
                    .fold(0u64, |value, &digit| 10 * value + u64::from(digit - b'0')),
            ));
        }
        Some(Number::from_text(std::str::from_utf8(text).ok()?)?.as_u64())
    }

    /// A value read as [`index`] reads it.
    fn index(&mut self) -> Option<Option<u32>> {
        Some(self.length()?.and_then(|i| u32::try_from(i).ok()))
    }

    /// A buffer view's entry in [`Facts::views`].
    fn view(&mut self) -> Option<(u64, bool)> {
        let (mut length, mut compressed) = (None, [None, None]);
        self.members(|text, key| match key.as_ref() {
            b"byteLength" => {
                length = text.length()?;
                Some(())
            }
            b"extensions" => text
                .members(|text, key| {
                    match MESHOPT
                        .iter()
                        .position(|name| name.as_bytes() == key.as_ref())
                    {
                        Some(which) => text
                            .members(|text, key| match key.as_ref() {
                                b"byteLength" => {
                                    compressed[which] = text.length()?;
                                    Some(())
                                }
                                _ => text.skip(),
                            })
                            .map(drop),
                        None => text.skip(),
                    }
                })
                .map(drop),
            _ => text.skip(),
        })?;
        let compressed = compressed[0].or(compressed[1]);
        Some((compressed.or(length).unwrap_or(0), compressed.is_some()))
    }

    /// An accessor's entry in [`Facts::accessors`].
    fn accessor(&mut self) -> Option<[Option<u32>; 3]> {
        let mut views = [None; 3];
        self.members(|text, key| match key.as_ref() {
            b"bufferView" => {
                views[0] = text.index()?;
                Some(())
            }
            b"sparse" => text
                .members(|text, key| {
                    let part = match key.as_ref() {
                        b"indices" => 1,
                        b"values" => 2,
                        _ => return text.skip(),
                    };
                    views[part] = text.buffer_view()?;
                    Some(())
                })
                .map(drop),
            _ => text.skip(),
        })?;
        Some(views)
    }

    /// An object's `bufferView`, read as [`index`] reads it; the rest of the object skipped.
    fn buffer_view(&mut self) -> Option<Option<u32>> {
        let mut view = None;
        self.members(|text, key| match key.as_ref() {
            b"bufferView" => {
                view = text.index()?;
                Some(())
            }
            _ => text.skip(),
        })?;
        Some(view)
    }

    /// A primitive's entries in [`Facts::primitives`] and [`Facts::primitive_accessors`].
    fn primitive(&mut self, facts: &mut Facts) -> Option<()> {
        // Read in the order of the text, kept in the order of [`Facts::of_tree`].
        let (mut attributes, mut targets, mut indices) = (Vec::new(), Vec::new(), None);
        let (mut draco, mut draco_view) = (false, None);
        let accessors_of = |text: &mut Self, into: &mut Vec<u32>| {
            text.members(|text, _| {
                into.extend(text.index()?);
                Some(())
            })
            .map(drop)
        };
        self.members(|text, key| match key.as_ref() {
            b"attributes" => accessors_of(text, &mut attributes),
            b"targets" => text.elements(|text| accessors_of(text, &mut targets)),
            b"indices" => {
                indices = text.index()?;
                Some(())
            }
            b"extensions" => text
                .members(|text, key| {
                    if key.as_ref() != draco::EXTENSION.as_bytes() {
                        return text.skip();
                    }
                    draco = true;
                    draco_view = text.buffer_view()?;
                    Some(())
                })
                .map(drop),
            _ => text.skip(),
        })?;
        facts.primitive_accessors.extend(attributes);
        facts.primitive_accessors.extend(targets);
        facts.primitive_accessors.extend(indices);
        facts
            .primitives
            .push((index32(facts.primitive_accessors.len()), draco, draco_view));
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use tspace_json::Document;

    /// Numbers as JSON may spell them, integers or not, and past 32 and 64 bits.
    fn number() -> BoxedStrategy<String> {
        let spellings = vec![
            "0",
            "1",
            "2",
            "3",
            "4",
            "3.0",
            "1e1",
            "2E0",
            "-0",
            "-3",
            "1.5",
            "0.0e5",
            "4294967296",
            "18446744073709551616",
        ];
        prop::sample::select(spellings)
            .prop_map(String::from)
            .boxed()
    }

    /// Values of the wrong kind, strings with brackets and escapes among them.
    fn junk() -> BoxedStrategy<String> {
        let values = vec![
            "null",
            "true",
            "false",
            "\"s\"",
            r#""a]}\"[{""#,
            "[]",
            "{}",
            r#"[1, [2, {"x": 3}]]"#,
            r#""\u0041""#,
            r#"{"bufferView": 1}"#,
        ];
        prop::sample::select(values).prop_map(String::from).boxed()
    }

    fn or_junk(value: BoxedStrategy<String>) -> BoxedStrategy<String> {
        prop_oneof![6 => value, 1 => junk()].boxed()
    }

    fn index() -> BoxedStrategy<String> {
        or_junk(number())
    }

    /// `"key"`, or with one of its characters escaped.
    fn key(key: &'static str) -> BoxedStrategy<String> {
        (any::<bool>(), 0..key.len())
            .prop_map(move |(escaped, at)| {
                if !escaped {
                    return format!("\"{key}\"");
                }
                let (before, rest) = key.split_at(at);
                let mut chars = rest.chars();
                let c = chars.next().unwrap_or('x');
                format!("\"{before}\\u{:04x}{}\"", u32::from(c), chars.as_str())
            })
            .boxed()
    }

    /// An object with some of `members`, and a member measuring skips.
    fn object(members: Vec<(&'static str, BoxedStrategy<String>)>) -> BoxedStrategy<String> {
        let mut parts: Vec<BoxedStrategy<Option<String>>> = members
            .into_iter()
            .map(|(name, value)| {
                prop::option::weighted(0.8, (key(name), value))
                    .prop_map(|m| m.map(|(k, v)| format!("{k}: {v}")))
                    .boxed()
            })
            .collect();
        parts.push(
            prop::option::of(junk())
                .prop_map(|v| v.map(|v| format!("\"extras\":{v}")))
                .boxed(),
        );
        parts
            .prop_map(|members| {
                let members: Vec<String> = members.into_iter().flatten().collect();
                format!("{{ {} }}", members.join(",\n"))
            })
            .boxed()
    }

    fn array(element: BoxedStrategy<String>) -> BoxedStrategy<String> {
        prop::collection::vec(element, 0..4)
            .prop_map(|elements| format!("[{}]", elements.join(", ")))
            .boxed()
    }

    fn document() -> BoxedStrategy<String> {
        let compressed = || or_junk(object(vec![("byteLength", index())]));
        let extensions = or_junk(object(vec![
            ("EXT_meshopt_compression", compressed()),
            ("KHR_meshopt_compression", compressed()),
        ]));
        let view = or_junk(object(vec![
            ("byteLength", index()),
            ("extensions", extensions),
        ]));
        let part = || or_junk(object(vec![("bufferView", index())]));
        let sparse = or_junk(object(vec![("indices", part()), ("values", part())]));
        let accessor = or_junk(object(vec![("bufferView", index()), ("sparse", sparse)]));
        let attributes = || or_junk(object(vec![("POSITION", index()), ("NORMAL", index())]));
        let draco = or_junk(object(vec![(draco::EXTENSION, part())]));
        let primitive = or_junk(object(vec![
            ("attributes", attributes()),
            ("targets", or_junk(array(attributes()))),
            ("indices", index()),
            ("extensions", draco),
        ]));
        let mesh = or_junk(object(vec![("primitives", or_junk(array(primitive)))]));
        object(vec![
            ("bufferViews", or_junk(array(view))),
            ("accessors", or_junk(array(accessor))),
            ("meshes", or_junk(array(mesh))),
        ])
    }

    proptest! {
        #[test]
        fn the_text_is_measured_as_its_tree_is(text in document()) {
            // Only what the parser accepts is ever read from its text.
            if let Ok(doc) = Document::parse(text.as_bytes()) {
                let from_tree = Facts::of_tree(doc.root());
                prop_assert_eq!(Facts::of_text(text.as_bytes()), Some(from_tree), "{}", text);
            }
        }
    }

    #[test]
    fn shared_views_count_once_in_the_total_and_compressed_views_at_their_compressed_size() {
        let text = br#"{
            "bufferViews": [
                {"buffer": 0, "byteLength": 100},
                {"buffer": 1, "byteLength": 400, "extensions": {"EXT_meshopt_compression":
                    {"buffer": 0, "byteLength": 40, "byteStride": 4, "count": 100, "mode": "ATTRIBUTES"}}},
                {"buffer": 0, "byteLength": 7},
                {"buffer": 0, "byteLength": 1000},
                {"buffer": 0, "byteLength": 1},
                {"buffer": 0, "byteLength": 5}
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5126, "count": 1, "type": "VEC3"},
                {"componentType": 5126, "count": 1, "type": "VEC3"},
                {"componentType": 5126, "count": 1, "type": "VEC3", "sparse": {"count": 1,
                    "indices": {"bufferView": 4, "componentType": 5121},
                    "values": {"bufferView": 5}}}
            ],
            "meshes": [{"name": "m", "primitives": [
                {"attributes": {"POSITION": 0}, "material": 0},
                {"attributes": {"POSITION": 0, "NORMAL": 1}},
                {"attributes": {"POSITION": 2},
                 "extensions": {"KHR_draco_mesh_compression": {"bufferView": 2, "attributes": {"POSITION": 0}}}},
                {"attributes": {"POSITION": 0}, "targets": [{"POSITION": 3}], "indices": 2}
            ]}]
        }"#;
        let doc = Document::parse(text).unwrap();
        let sizes = measure(doc.root());
        let at = |p| *sizes.primitive((0, p)).unwrap();
        assert_eq!((at(0).compression, at(0).bytes), (Compression::None, 100));
        assert_eq!(
            (at(1).compression, at(1).bytes),
            (Compression::Meshopt, 140)
        );
        assert_eq!((at(2).compression, at(2).bytes), (Compression::Draco, 7));
        assert_eq!((at(3).compression, at(3).bytes), (Compression::None, 106));
        assert_eq!(sizes.primitive((0, 4)), None);
        assert_eq!(sizes.primitive((1, 0)), None);
        // View 3 is no mesh's.
        assert_eq!(sizes.total, 153);
        // Read from the text without a tree, the document measures the same.
        assert_eq!(Facts::of_text(text), Some(Facts::of_tree(doc.root())));
        assert_eq!(measure_text(text), Some(sizes));
    }

    #[test]
    fn the_text_and_the_tree_find_the_same_in_every_fixture() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
        let mut files = vec![root];
        let mut measured = 0;
        while let Some(path) = files.pop() {
            if path.is_dir() {
                files.extend(std::fs::read_dir(&path).unwrap().map(|e| e.unwrap().path()));
                continue;
            }
            let bytes = std::fs::read(&path).unwrap();
            let json = match path.extension().and_then(|e| e.to_str()) {
                Some("glb") => match super::super::glb::parse(&bytes) {
                    Ok(glb) => glb.json.to_vec(),
                    Err(_) => continue,
                },
                Some("gltf") => bytes,
                _ => continue,
            };
            let Ok(doc) = Document::parse(&json) else {
                continue;
            };
            let from_tree = Facts::of_tree(doc.root());
            assert_eq!(Facts::of_text(&json), Some(from_tree), "{}", path.display());
            measured += 1;
        }
        assert!(measured >= 20, "{measured} fixtures measured");
    }

    #[test]
    fn the_text_is_read_as_the_parser_reads_it() {
        // Escaped keys, integers spelled as floats, values of the wrong kind, a BOM, and
        // members measuring skips holding brackets in strings.
        let text = "\u{feff} {\"extras\": {\"a]\": \"}{\\\"[\"}, \"bufferViews\": [
            {\"by\\u0074eLength\": 1.0e2, \"extensions\": {\"KHR_meshopt_compression\":
                {\"byteLength\": 30}, \"EXT_meshopt_compression\": {\"byteLength\": \"40\"}}},
            {\"byteLength\": -0}, {\"byteLength\": 1.5}, 7, {\"byteLength\": 18446744073709551616}],
            \"accessors\": [{\"bufferView\": 0, \"sparse\": {\"indices\": {\"bufferView\": 1},
                \"values\": {\"bufferView\": 2e0}}}, [], {\"bufferView\": null}],
            \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0, \"X\": \"1\"},
                \"targets\": [{\"POSITION\": 2}, 5], \"indices\": 1.0,
                \"extensions\": {\"KHR_draco_mesh_compression\": {\"bufferView\": 3}}},
                {}, 4]}, {\"primitives\": {}}, 3, {}]}";
        let doc = Document::parse(text.as_bytes()).unwrap();
        let from_tree = Facts::of_tree(doc.root());
        assert_eq!(from_tree.views[0], (30, true));
        assert_eq!(Facts::of_text(text.as_bytes()), Some(from_tree));
        assert_eq!(Facts::of_text(b"[1, 2]"), None);
        assert_eq!(Facts::of_text(b"{\"meshes\": [} "), None);
        assert_eq!(Facts::of_text(b"{} {}"), None);
    }

    #[test]
    fn each_mesh_finds_its_own_primitives() {
        let text = br#"{
            "bufferViews": [{"byteLength": 10}, {"byteLength": 20}, {"byteLength": 40}],
            "accessors": [{"bufferView": 0}, {"bufferView": 1}, {"bufferView": 2}],
            "meshes": [
                {"primitives": [{"attributes": {"POSITION": 0}}]},
                {"primitives": []},
                {"primitives": [{"attributes": {"POSITION": 1}}, {"attributes": {"POSITION": 2}}]}
            ]
        }"#;
        let doc = Document::parse(text).unwrap();
        let sizes = measure(doc.root());
        let bytes = |key| sizes.primitive(key).map(|p| p.bytes);
        assert_eq!(bytes((0, 0)), Some(10));
        assert_eq!(bytes((0, 1)), None);
        assert_eq!(bytes((1, 0)), None);
        assert_eq!(bytes((2, 0)), Some(20));
        assert_eq!(bytes((2, 1)), Some(40));
        assert_eq!(bytes((2, 2)), None);
        assert_eq!(bytes((3, 0)), None);
        assert_eq!(sizes.total, 70);
    }
}
