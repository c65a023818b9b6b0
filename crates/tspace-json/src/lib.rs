//! A lossless JSON reader and splice editor for glTF documents.
//!
//! tspace adds tangents to a scene and must hand back everything else exactly as it came: number
//! spellings (`1.0`, `1e400`, `0.1000000000000000055511151231257827`), key order, whitespace and
//! extensions nobody here has heard of. A round trip through a generic JSON value respells numbers,
//! and a typed glTF model drops what it does not know. So the parser keeps the byte span of every
//! value, and the [`Editor`] rewrites only the spans it is asked to change; every other byte of the
//! output is copied from the input.
//!
//! The parser follows RFC 8259 strictly (no trailing commas, no comments, no leading zeros, no raw
//! control characters in strings) with these decisions for the corners the RFC leaves open:
//!
//! - **Byte order mark.** glTF requires UTF-8 without a BOM, and RFC 8259 lets a parser ignore one.
//!   A leading BOM is accepted and skipped (Windows tools add them), and never written back: the
//!   editor's output starts after it, because an exporter must not emit one.
//! - **Duplicate keys** in one object are an error. glTF requires unique keys, and readers disagree
//!   about which duplicate wins, so accepting them would let two tools see two different scenes.
//! - **Depth.** Arrays and objects nest at most [`MAX_DEPTH`] deep; deeper input is an error, so the
//!   recursive parser's stack use is bounded whatever the input.
//! - **Lone surrogates.** A `\uD800`-`\uDFFF` escape that is not part of a high-low pair decodes to
//!   U+FFFD in the decoded string (Rust strings cannot hold it; JavaScript's `JSON.stringify` does
//!   emit such escapes). The document text keeps the original escape, since untouched text is
//!   copied verbatim. Two keys that differ only in lone surrogates therefore count as duplicates:
//!   a rejection, never a misreading.
//! - Invalid UTF-8 anywhere is an error.
//!
//! Every container node consumes at least two bytes and every scalar at least one, so the tree's
//! size is bounded by the input's length.
//!
//! # Example
//!
//! Change one member of a glTF document; every other byte, odd number spellings and layout
//! included, comes back unchanged.
//!
//! ```
//! use tspace_json::{Document, escape_str};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let text = br#"{
//!   "asset": {"version": "2.0", "generator": "an exporter"},
//!   "accessors": [ {"count": 3, "max": [1.0, 1e0, 0.10]} ],
//!   "extensionsUsed": ["EXT_unknown_to_tspace"]
//! }"#;
//! let doc = Document::parse(text)?;
//! let asset = doc.root().get("asset").unwrap();
//! assert_eq!(asset.get("version").and_then(|v| v.as_str()), Some("2.0"));
//!
//! let mut editor = doc.editor();
//! editor.set_member(asset, "generator", escape_str("tspace"))?;
//! let out = editor.render()?;
//!
//! // Only the generator's value was rewritten.
//! let old = asset.get("generator").unwrap().span();
//! let new = "\"tspace\"";
//! let source = doc.source();
//! assert_eq!(&out[..old.start], &source[..old.start]);
//! assert_eq!(&out[old.start..old.start + new.len()], new);
//! assert_eq!(&out[old.start + new.len()..], &source[old.end..]);
//! assert!(out.contains("[1.0, 1e0, 0.10]"));
//! # Ok(())
//! # }
//! ```

#![warn(missing_docs)]

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;

/// How deeply arrays and objects may nest. glTF documents need fewer than 10 levels; `extras`
/// can hold anything, so the limit is generous.
pub const MAX_DEPTH: usize = 128;

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// A JSON value and where it sits in the source text.
///
/// Small, because a glTF document of many small objects is mostly nodes: 32 bytes, with
/// every short key, string and number held inside (see [`Text`]). The tree of a glTF of many
/// one-triangle primitives takes 3.6 times its JSON text; with a heap allocation per key and
/// number, and 48-byte nodes, it took over 7, and its allocations' overhead more.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Byte range of the value's text in the source, from its first to its last byte.
    /// Offsets are 32-bit: [`Document::parse`] refuses longer texts.
    start: u32,
    end: u32,
    /// What the value is; arrays and objects hold their children here.
    pub kind: Kind,
}

/// The type of a JSON value, with its contents.
#[derive(Clone, Debug, PartialEq)]
pub enum Kind {
    /// `null`.
    Null,
    /// `true` or `false`.
    Bool(bool),
    /// A number, kept as spelled in the source.
    Number(Number),
    /// The decoded string (escapes resolved).
    String(Text),
    /// Elements in source order.
    Array(Box<[Node]>),
    /// Members in source order. Keys are unique (the parser rejects duplicates).
    Object(Box<[Member]>),
}

/// One `"key": value` pair of an object. The key's own span is found from the value's when an
/// edit needs it ([`Document::key_span`]), rather than kept in every member.
#[derive(Clone, Debug, PartialEq)]
pub struct Member {
    /// The decoded key.
    pub key: Text,
    /// The member's value; its span covers the value only, not the key or colon.
    pub value: Node,
}

/// A number as spelled in the source, already checked against the JSON grammar.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Number(Text);

// What keeps a document of small objects at a few times its text; a change that grows these
// should be a decision.
const _: () = assert!(std::mem::size_of::<Text>() == 16);
const _: () = assert!(std::mem::size_of::<Node>() == 32);
const _: () = assert!(std::mem::size_of::<Member>() == 48);
// An editor may hold one of each per edited object, a quarter of a million of them (and a list
// of added members for most). An added member of 40 bytes takes the same 48-byte block of the
// allocator as one of 32 would.
const _: () = assert!(std::mem::size_of::<ObjectEdit<'static>>() == 24);
const _: () = assert!(std::mem::size_of::<(Text, NewValue)>() == 40);
const _: () = assert!(std::mem::size_of::<Replacement>() == 24);
const _: () = assert!(std::mem::size_of::<Piece>() == 16);

/// How many bytes of text a [`Text`] holds without an allocation of its own.
const INLINE: usize = 14;

/// A key's, string's or number's text, held inside the node when it is short (most of a glTF
/// document's keys and numbers are: `"componentType"`, `5126`) and on the heap otherwise. An
/// allocation per key and number would cost more than the text, and bookkeeping besides.
/// Reads as a `str` (it dereferences to one) and compares with `str` and `String`.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Text(Repr);

#[derive(Clone, PartialEq, Eq, Hash)]
enum Repr {
    /// `bytes[..len]` is the text and the rest zeros, so that equal texts are equal values.
    Inline { len: u8, bytes: [u8; INLINE] },
    /// Boxed twice: the thin pointer keeps a `Text` at 16 bytes. Only texts longer than
    /// [`INLINE`] bytes pay the second allocation.
    Heap(Box<Box<str>>),
}

impl Text {
    /// `s` as a text.
    pub fn new(s: &str) -> Text {
        if s.len() > INLINE {
            return Text(Repr::Heap(Box::new(s.into())));
        }
        let mut bytes = [0u8; INLINE];
        bytes[..s.len()].copy_from_slice(s.as_bytes());
        Text(Repr::Inline {
            len: s.len() as u8,
            bytes,
        })
    }

    /// The text as a `str`.
    pub fn as_str(&self) -> &str {
        match &self.0 {
            // Copied whole from a `str`, so always UTF-8.
            Repr::Inline { .. } => std::str::from_utf8(self.as_bytes()).unwrap_or(""),
            Repr::Heap(s) => s,
        }
    }

    /// The text's bytes: for comparisons, which [`Text::as_str`] would make check the text as
    /// UTF-8 first (this crate has no `unsafe` to skip that).
    pub fn as_bytes(&self) -> &[u8] {
        match &self.0 {
            Repr::Inline { len, bytes } => bytes.get(..usize::from(*len)).unwrap_or(&[]),
            Repr::Heap(s) => s.as_bytes(),
        }
    }
}

impl From<&str> for Text {
    fn from(s: &str) -> Text {
        Text::new(s)
    }
}

impl From<Cow<'_, str>> for Text {
    fn from(s: Cow<'_, str>) -> Text {
        match s {
            Cow::Borrowed(s) => Text::new(s),
            Cow::Owned(s) => Text::from(s),
        }
    }
}

impl From<String> for Text {
    fn from(s: String) -> Text {
        if s.len() > INLINE {
            Text(Repr::Heap(Box::new(s.into_boxed_str())))
        } else {
            Text::new(&s)
        }
    }
}

impl std::ops::Deref for Text {
    type Target = str;

    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl fmt::Debug for Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl fmt::Display for Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

// Byte comparisons: no UTF-8 check on the path of every `Node::get`.
impl PartialEq<str> for Text {
    fn eq(&self, other: &str) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<&str> for Text {
    fn eq(&self, other: &&str) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<String> for Text {
    fn eq(&self, other: &String) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<Text> for str {
    fn eq(&self, other: &Text) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<Text> for &str {
    fn eq(&self, other: &Text) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<Text> for String {
    fn eq(&self, other: &Text) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl Number {
    /// The number spelled `text`, for a reader that found it in a text already parsed (the
    /// caller's own output, read again without a tree): `None` unless `text` is a JSON number.
    pub fn from_text(text: &str) -> Option<Number> {
        let bytes = text.as_bytes();
        let mut parser = Parser::new(text, 0, None);
        (parser.check_number().is_ok() && parser.pos == bytes.len())
            .then(|| Number(Text::new(text)))
    }

    /// The source text, e.g. `-0`, `1e400`, `3.0`.
    pub fn raw(&self) -> &str {
        &self.0
    }

    /// The nearest `f64`; infinite when the magnitude is too large (`1e400`).
    pub fn as_f64(&self) -> Option<f64> {
        self.0.parse().ok()
    }

    /// The value as an unsigned integer, if it is one exactly. `3.0`, `3e2` and `-0` count (JSON
    /// Schema calls any number without a fractional part an integer). Decided on the decimal
    /// text, not through `f64`, which would round `9007199254740993` or `4503599627370495.6`.
    pub fn as_u64(&self) -> Option<u64> {
        match self.integer()? {
            (false, v) | (true, v @ 0) => Some(v),
            (true, _) => None,
        }
    }

    /// The value as a signed integer, if it is one exactly (see [`Number::as_u64`]).
    pub fn as_i64(&self) -> Option<i64> {
        match self.integer()? {
            (false, v) => i64::try_from(v).ok(),
            (true, v) => 0i64.checked_sub_unsigned(v),
        }
    }

    /// Sign and magnitude, if the number is an integer that fits in a `u64`.
    fn integer(&self) -> Option<(bool, u64)> {
        // The spelling nearly every index and count has, plain digits (19 always fit), is read
        // at once, from the bytes: the general path below copies the digits into a new string,
        // which on a scene of 200,000 accessors was a sixth of the whole run, and reading the
        // text as a `str` checks it as UTF-8 again, which on the JSON-heavy scene cost more
        // than the parse (7% of `tspace process`).
        let bytes = self.0.as_bytes();
        let (negative, digits) = match bytes.split_first() {
            Some((b'-', rest)) => (true, rest),
            _ => (false, bytes),
        };
        if (1..=19).contains(&digits.len()) && digits.iter().all(u8::is_ascii_digit) {
            let value = digits
                .iter()
                .fold(0u64, |value, &digit| 10 * value + u64::from(digit - b'0'));
            return Some((negative, value));
        }
        let (negative, unsigned) = match self.0.strip_prefix('-') {
            Some(rest) => (true, rest),
            None => (false, &*self.0),
        };
        let (mantissa, exponent) = match unsigned.find(['e', 'E']) {
            Some(i) => (unsigned.get(..i)?, unsigned.get(i + 1..)?),
            None => (unsigned, "0"),
        };
        let (int, frac) = mantissa.split_once('.').unwrap_or((mantissa, ""));
        let digits: String = [int, frac].concat();
        let significant = digits.trim_start_matches('0');
        if significant.is_empty() {
            return Some((negative, 0));
        }
        let trimmed = significant.trim_end_matches('0');
        // Exponents too long for i64 are far outside u64 either way.
        let exponent: i64 = exponent.parse().ok()?;
        let zeros = i64::try_from(significant.len() - trimmed.len()).ok()?;
        let frac_len = i64::try_from(frac.len()).ok()?;
        let scale = exponent.checked_add(zeros)?.checked_sub(frac_len)?;
        if !(0..=20).contains(&scale) {
            return None;
        }
        let base: u64 = trimmed.parse().ok()?;
        let v = 10u64
            .checked_pow(u32::try_from(scale).ok()?)?
            .checked_mul(base)?;
        Some((negative, v))
    }
}

impl Node {
    /// Byte range of the value's text in the source, from its first to its last byte.
    pub fn span(&self) -> Range<usize> {
        self.start as usize..self.end as usize
    }

    /// The value of member `key`, if this is an object that has it.
    pub fn get(&self, key: &str) -> Option<&Node> {
        self.member(key).map(|m| &m.value)
    }

    /// Member `key`, if this is an object that has it. Like [`Node::get`], for when the
    /// member itself matters ([`Document::key_span`]).
    pub fn member(&self, key: &str) -> Option<&Member> {
        self.as_object()?.iter().find(|m| m.key == key)
    }

    /// Element `i`, if this is an array that long.
    pub fn index(&self, i: usize) -> Option<&Node> {
        self.as_array()?.get(i)
    }

    /// The members in source order, if this is an object.
    pub fn as_object(&self) -> Option<&[Member]> {
        match &self.kind {
            Kind::Object(members) => Some(members),
            _ => None,
        }
    }

    /// The elements in source order, if this is an array.
    pub fn as_array(&self) -> Option<&[Node]> {
        match &self.kind {
            Kind::Array(elements) => Some(elements),
            _ => None,
        }
    }

    /// The decoded string (escapes resolved, lone surrogates as U+FFFD), if this is a string.
    pub fn as_str(&self) -> Option<&str> {
        match &self.kind {
            Kind::String(s) => Some(s.as_str()),
            _ => None,
        }
    }

    /// The value, if this is `true` or `false`.
    pub fn as_bool(&self) -> Option<bool> {
        match self.kind {
            Kind::Bool(b) => Some(b),
            _ => None,
        }
    }

    /// The number as spelled, if this is a number.
    pub fn as_number(&self) -> Option<&Number> {
        match &self.kind {
            Kind::Number(n) => Some(n),
            _ => None,
        }
    }

    /// [`Number::as_f64`] of this number; `None` if this is not a number.
    pub fn as_f64(&self) -> Option<f64> {
        self.as_number()?.as_f64()
    }

    /// [`Number::as_u64`] of this number: `None` if this is not a number, or not an integer
    /// that fits.
    pub fn as_u64(&self) -> Option<u64> {
        self.as_number()?.as_u64()
    }

    /// [`Number::as_i64`] of this number: `None` if this is not a number, or not an integer
    /// that fits.
    pub fn as_i64(&self) -> Option<i64> {
        self.as_number()?.as_i64()
    }

    /// Whether this is `null`. (An absent member is `None` from [`Node::get`], not null.)
    pub fn is_null(&self) -> bool {
        matches!(self.kind, Kind::Null)
    }

    /// "an object", "a number"…, for error messages.
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            Kind::Null => "null",
            Kind::Bool(_) => "a boolean",
            Kind::Number(_) => "a number",
            Kind::String(_) => "a string",
            Kind::Array(_) => "an array",
            Kind::Object(_) => "an object",
        }
    }
}

/// A parsed document: the source text and the tree of its values.
#[derive(Clone, Debug)]
pub struct Document<'a> {
    source: &'a str,
    /// Where the JSON text starts: 3 when a byte order mark was skipped, else 0.
    body_start: usize,
    root: Node,
}

impl<'a> Document<'a> {
    /// Parses `bytes` as one JSON text (see the module documentation for the exact rules).
    pub fn parse(bytes: &'a [u8]) -> Result<Self, ParseError> {
        let source = checked_source(bytes)?;
        let body_start = if bytes.starts_with(BOM) { BOM.len() } else { 0 };
        let root = Parser::new(source, body_start, None)
            .document()
            .map_err(|(at, kind)| ParseError::new(source, at, kind))?;
        Ok(Document {
            source,
            body_start,
            root,
        })
    }

    /// The top-level value. Its span excludes the surrounding whitespace and any byte order
    /// mark.
    pub fn root(&self) -> &Node {
        &self.root
    }

    /// The whole input, byte order mark included.
    pub fn source(&self) -> &'a str {
        self.source
    }

    /// Whether the input began with a byte order mark (which output never carries).
    pub fn had_bom(&self) -> bool {
        self.body_start > 0
    }

    /// The source text of `node`, exactly as written.
    pub fn text(&self, node: &Node) -> &'a str {
        self.source.get(node.span()).unwrap_or("")
    }

    /// The byte range of `member`'s key, quotes included: found by reading back from its value
    /// over the colon to the key's opening quote. `None` when what precedes the value here is no
    /// key and colon (a member of another document).
    pub fn key_span(&self, member: &Member) -> Option<Range<usize>> {
        let bytes = self.source.as_bytes();
        let ws = |b: &u8| matches!(b, b' ' | b'\t' | b'\n' | b'\r');
        let before_value = bytes.get(..member.value.span().start)?;
        let colon = before_value.iter().rposition(|b| !ws(b))?;
        let before_colon = bytes
            .get(..colon)
            .filter(|_| bytes.get(colon) == Some(&b':'))?;
        let close = before_colon.iter().rposition(|b| !ws(b))?;
        if bytes.get(close) != Some(&b'"') {
            return None;
        }
        // Inside a string every quote is escaped, that is preceded by an odd number of
        // backslashes; the opening quote follows no backslash at all.
        let mut at = close;
        loop {
            at = bytes.get(..at)?.iter().rposition(|&b| b == b'"')?;
            let backslashes = bytes
                .get(..at)?
                .iter()
                .rev()
                .take_while(|&&b| b == b'\\')
                .count();
            if backslashes % 2 == 0 {
                return Some(at..close + 1);
            }
        }
    }

    /// A new editor with no edits for this document (the same as [`Editor::new`]).
    pub fn editor(&self) -> Editor<'_, 'a> {
        Editor::new(self)
    }
}

/// Why a text is not JSON, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// Byte offset into the input (byte order mark included) where the problem is.
    pub offset: usize,
    /// 1-based line of `offset`, for people; lines end at `\n`.
    pub line: usize,
    /// 1-based column of `offset` within its line, counted in characters, not bytes.
    pub column: usize,
    /// What is wrong.
    pub kind: ParseErrorKind,
}

/// The kinds of [`ParseError`]. Each variant says where its error's `offset` points.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParseErrorKind {
    /// The input is not UTF-8. It is checked before any JSON, so this wins over syntax errors;
    /// `offset` is the first byte of the invalid sequence.
    InvalidUtf8,
    /// The text ended inside a value (or held no value at all); `offset` is the input's length.
    UnexpectedEnd,
    /// A character that cannot appear here; `offset` is at it.
    Unexpected {
        /// The offending character.
        found: char,
        /// What would have been valid here, as a phrase for messages (`"a value"`,
        /// `"',' or ']'"`).
        expected: &'static str,
    },
    /// A comma directly before `]` or `}`; `offset` is at the closing bracket.
    TrailingComma,
    /// A raw byte below 0x20 inside a string; JSON requires it escaped. `offset` is at it.
    ControlCharacter {
        /// The raw byte, 0x00 to 0x1F.
        byte: u8,
    },
    /// A backslash followed by something that starts no JSON escape; `offset` is at the
    /// backslash.
    InvalidEscape {
        /// The character after the backslash.
        found: char,
    },
    /// `\u` not followed by four hexadecimal digits, including when the text ends first;
    /// `offset` is at that escape's backslash.
    InvalidUnicodeEscape,
    /// A number with a superfluous leading zero (`01`, `-00`); `offset` is at the zero.
    LeadingZero,
    /// A number missing its digits: `-`, `1.`, `1e`. `offset` is where a digit was expected.
    MissingDigits,
    /// Arrays and objects nest deeper than allowed; `offset` is at the bracket that opens one
    /// level too many.
    TooDeep {
        /// The maximum nesting depth, [`MAX_DEPTH`].
        limit: usize,
    },
    /// A key appears twice in one object. `offset` is at the earliest key in the object that
    /// repeats an earlier one.
    DuplicateKey {
        /// The decoded key.
        key: String,
    },
    /// The text is longer than node offsets can say (4 GiB); `offset` is 0.
    TooLong {
        /// The most bytes a document may have.
        limit: usize,
    },
    /// Something other than whitespace after the top-level value; `offset` is at it.
    TrailingCharacters {
        /// The first such character.
        found: char,
    },
}

impl ParseError {
    fn new(source: &str, offset: usize, kind: ParseErrorKind) -> Self {
        let before = source.get(..offset).unwrap_or(source);
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
        let column = before.get(line_start..).map_or(0, |l| l.chars().count()) + 1;
        ParseError {
            offset,
            line,
            column,
            kind,
        }
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "invalid JSON at line {}, column {} (byte {}): ",
            self.line, self.column, self.offset
        )?;
        match &self.kind {
            ParseErrorKind::InvalidUtf8 => write!(f, "the text is not valid UTF-8"),
            ParseErrorKind::UnexpectedEnd => write!(f, "the text ends before the value does"),
            ParseErrorKind::Unexpected { found, expected } => {
                write!(f, "found {found:?} where {expected} was expected")
            }
            ParseErrorKind::TrailingComma => write!(f, "a comma is followed by a closing bracket"),
            ParseErrorKind::ControlCharacter { byte } => write!(
                f,
                "control character 0x{byte:02X} inside a string must be escaped"
            ),
            ParseErrorKind::InvalidEscape { found } => {
                write!(f, "\\{found} is not a JSON escape")
            }
            ParseErrorKind::InvalidUnicodeEscape => {
                write!(f, "\\u must be followed by four hexadecimal digits")
            }
            ParseErrorKind::LeadingZero => write!(f, "numbers must not have leading zeros"),
            ParseErrorKind::MissingDigits => write!(f, "a number is missing its digits"),
            ParseErrorKind::TooDeep { limit } => {
                write!(f, "arrays and objects nest more than {limit} levels deep")
            }
            ParseErrorKind::DuplicateKey { key } => {
                write!(f, "the key {key:?} appears twice in one object")
            }
            ParseErrorKind::TooLong { limit } => {
                write!(f, "the text is longer than {limit} bytes")
            }
            ParseErrorKind::TrailingCharacters { found } => {
                write!(f, "found {found:?} after the end of the top-level value")
            }
        }
    }
}

impl std::error::Error for ParseError {}

/// The text of `bytes`, when it is UTF-8 and short enough for 32-bit offsets.
fn checked_source(bytes: &[u8]) -> Result<&str, ParseError> {
    let source = std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        // The prefix before the bad byte is valid, so positions can be reported in it.
        let valid = bytes.get(..at).and_then(|b| std::str::from_utf8(b).ok());
        ParseError::new(valid.unwrap_or(""), at, ParseErrorKind::InvalidUtf8)
    })?;
    if u32::try_from(bytes.len()).is_err() {
        return Err(ParseError::new(
            "",
            0,
            ParseErrorKind::TooLong {
                limit: u32::MAX as usize,
            },
        ));
    }
    Ok(source)
}

/// Which object members a pruned parse keeps: called with the keys of the objects that enclose
/// the member, outermost first (arrays leave no step), and the member's own key.
pub type Keep<'k> = &'k dyn Fn(&[Text], &str) -> bool;

/// Parses `bytes` as [`Document::parse`] does, checking the whole text by the same rules
/// (duplicate keys included), but keeps only the object members `keep` accepts, and returns
/// the tree alone. For reading a few members of a large document: what is not kept is only
/// checked, never built, so the tree takes a fraction of a whole one and the parse less time
/// per byte than a whole one. There is no editor for it, since its objects do not hold all
/// their members.
///
/// ```
/// let text = br#"{"accessors": [{"bufferView": 0, "max": [1, 2, 3], "min": [0, 0, 0]}], "asset": {}}"#;
/// let root = tspace_json::parse_pruned(text, &|path, key| match path {
///     [] => key == "accessors",
///     [_] => key == "bufferView",
///     _ => false,
/// })?;
/// let accessor = &root.get("accessors").unwrap().as_array().unwrap()[0];
/// assert_eq!(accessor.get("bufferView").and_then(|v| v.as_u64()), Some(0));
/// assert!(accessor.get("max").is_none() && root.get("asset").is_none());
/// # Ok::<(), tspace_json::ParseError>(())
/// ```
pub fn parse_pruned(bytes: &[u8], keep: Keep<'_>) -> Result<Node, ParseError> {
    let source = checked_source(bytes)?;
    let body_start = if bytes.starts_with(BOM) { BOM.len() } else { 0 };
    Parser::new(source, body_start, Some(keep))
        .document()
        .map_err(|(at, kind)| ParseError::new(source, at, kind))
}

type Fail = (usize, ParseErrorKind);

struct Parser<'a> {
    text: &'a str,
    bytes: &'a [u8],
    pos: usize,
    depth: usize,
    /// The elements of the arrays being read, innermost last. A closing array takes its own
    /// off the end, in one allocation of exactly their number: no growth, no slack, one
    /// working list for the whole document.
    elements: Vec<Node>,
    /// The same for objects' members,
    members: Vec<Member>,
    /// and where each of their keys starts, for duplicate-key errors.
    key_starts: Vec<usize>,
    /// For a pruned parse: which members to keep,
    keep: Option<Keep<'a>>,
    /// the keys of the objects being read, outermost first,
    path: Vec<Text>,
    /// and the keys of the members left out, with where they start, until their objects' keys
    /// are compared (in every parse: inside a value that is only checked, every object's).
    /// Borrowed from the text unless they have escapes: making each a [`Text`], and reading it
    /// back as a `str` (checked as UTF-8 again), was a fifth of a pruned parse.
    left_out: Vec<(Cow<'a, str>, usize)>,
}

impl<'a> Parser<'a> {
    fn new(text: &'a str, body_start: usize, keep: Option<Keep<'a>>) -> Self {
        Parser {
            text,
            bytes: text.as_bytes(),
            pos: body_start,
            depth: 0,
            elements: Vec::new(),
            members: Vec::new(),
            key_starts: Vec::new(),
            keep,
            path: Vec::new(),
            left_out: Vec::new(),
        }
    }

    fn document(&mut self) -> Result<Node, Fail> {
        self.whole_text(Self::value)
    }

    /// The text as one value, read by `read`, with nothing but whitespace around it.
    fn whole_text<T>(
        &mut self,
        read: impl FnOnce(&mut Self) -> Result<T, Fail>,
    ) -> Result<T, Fail> {
        self.skip_ws();
        let root = read(self)?;
        self.skip_ws();
        if self.pos < self.bytes.len() {
            return Err((
                self.pos,
                ParseErrorKind::TrailingCharacters {
                    found: self.char_here(),
                },
            ));
        }
        Ok(root)
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    /// The character at `pos`, for messages. `pos` is always on a character boundary when this
    /// is called, because the parser only stops on ASCII bytes or at the start of a character.
    fn char_here(&self) -> char {
        self.text
            .get(self.pos..)
            .and_then(|s| s.chars().next())
            .unwrap_or('\u{FFFD}')
    }

    fn unexpected(&self, expected: &'static str) -> Fail {
        match self.peek() {
            None => (self.pos, ParseErrorKind::UnexpectedEnd),
            Some(_) => (
                self.pos,
                ParseErrorKind::Unexpected {
                    found: self.char_here(),
                    expected,
                },
            ),
        }
    }

    fn skip_ws(&mut self) {
        while let Some(b' ' | b'\t' | b'\n' | b'\r') = self.peek() {
            self.pos += 1;
        }
    }

    fn value(&mut self) -> Result<Node, Fail> {
        let start = self.pos;
        let kind = match self.peek() {
            Some(b'{') => self.object()?,
            Some(b'[') => self.array()?,
            Some(b'"') => Kind::String(self.string()?),
            Some(b'-' | b'0'..=b'9') => self.number()?,
            Some(b't') => self.literal(b"true", Kind::Bool(true))?,
            Some(b'f') => self.literal(b"false", Kind::Bool(false))?,
            Some(b'n') => self.literal(b"null", Kind::Null)?,
            _ => return Err(self.unexpected("a value")),
        };
        // `parse` refused texts whose offsets do not fit.
        Ok(Node {
            start: start as u32,
            end: self.pos as u32,
            kind,
        })
    }

    fn literal(&mut self, word: &[u8], kind: Kind) -> Result<Kind, Fail> {
        for &expected in word {
            if self.peek() != Some(expected) {
                return Err(self.unexpected("a value"));
            }
            self.pos += 1;
        }
        Ok(kind)
    }

    fn enter(&mut self) -> Result<(), Fail> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err((self.pos, ParseErrorKind::TooDeep { limit: MAX_DEPTH }));
        }
        Ok(())
    }

    /// Checks a value by [`Parser::value`]'s rules and in its order, so that a text fails at
    /// the same place with the same error, but keeps nothing of it: the members a pruned parse
    /// leaves out, and the texts edits insert, are only checked. Keys are still compared for
    /// repeats.
    fn skip_value(&mut self) -> Result<(), Fail> {
        match self.peek() {
            Some(b'{') => self.skip_object(),
            Some(b'[') => self.elements(Self::skip_value),
            Some(b'"') => self.string_runs(&mut None).map(drop),
            Some(b'-' | b'0'..=b'9') => self.check_number(),
            Some(b't') => self.literal(b"true", Kind::Null).map(drop),
            Some(b'f') => self.literal(b"false", Kind::Null).map(drop),
            Some(b'n') => self.literal(b"null", Kind::Null).map(drop),
            _ => Err(self.unexpected("a value")),
        }
    }

    fn array(&mut self) -> Result<Kind, Fail> {
        let base = self.elements.len();
        self.elements(|parser| {
            let element = parser.value()?;
            parser.elements.push(element);
            Ok(())
        })?;
        Ok(Kind::Array(self.elements.drain(base..).collect()))
    }

    /// Walks an array, `element` reading each of its elements.
    fn elements(
        &mut self,
        mut element: impl FnMut(&mut Self) -> Result<(), Fail>,
    ) -> Result<(), Fail> {
        self.enter()?;
        self.pos += 1; // '['
        self.skip_ws();
        if self.peek() == Some(b']') {
            self.pos += 1;
            self.depth -= 1;
            return Ok(());
        }
        loop {
            element(self)?;
            self.skip_ws();
            match self.peek() {
                Some(b',') => {
                    self.pos += 1;
                    self.skip_ws();
                    if self.peek() == Some(b']') {
                        return Err((self.pos, ParseErrorKind::TrailingComma));
                    }
                }
                Some(b']') => {
                    self.pos += 1;
                    self.depth -= 1;
                    return Ok(());
                }
                _ => return Err(self.unexpected("',' or ']'")),
            }
        }
    }

    fn object(&mut self) -> Result<Kind, Fail> {
        let base = self.members.len();
        let left_out_base = self.left_out.len();
        self.members_of_object(|parser, key, key_start| {
            let pruned = parser.keep.is_some();
            if parser.keep.is_some_and(|keep| !keep(&parser.path, &key)) {
                parser.skip_value()?;
                parser.left_out.push((key, key_start));
                return Ok(());
            }
            let key = Text::from(key);
            if pruned {
                parser.path.push(key.clone());
            }
            let value = parser.value()?;
            if pruned {
                parser.path.pop();
            }
            parser.members.push(Member { key, value });
            parser.key_starts.push(key_start);
            Ok(())
        })?;
        refuse_repeated_keys(
            self.members.get(base..).unwrap_or(&[]),
            self.key_starts.get(base..).unwrap_or(&[]),
            self.left_out.get(left_out_base..).unwrap_or(&[]),
        )?;
        self.key_starts.truncate(base);
        self.left_out.truncate(left_out_base);
        Ok(Kind::Object(self.members.drain(base..).collect()))
    }

    /// [`Parser::object`] keeping nothing: its keys are set aside only until they are compared.
    fn skip_object(&mut self) -> Result<(), Fail> {
        let base = self.left_out.len();
        self.members_of_object(|parser, key, key_start| {
            parser.skip_value()?;
            parser.left_out.push((key, key_start));
            Ok(())
        })?;
        refuse_repeated_keys(&[], &[], self.left_out.get(base..).unwrap_or(&[]))?;
        self.left_out.truncate(base);
        Ok(())
    }

    /// Walks an object, `member` reading each member's value given its key and where the key
    /// starts. Repeated keys are the caller's to find.
    fn members_of_object(
        &mut self,
        mut member: impl FnMut(&mut Self, Cow<'a, str>, usize) -> Result<(), Fail>,
    ) -> Result<(), Fail> {
        self.enter()?;
        self.pos += 1; // '{'
        self.skip_ws();
        if self.peek() == Some(b'}') {
            self.pos += 1;
            self.depth -= 1;
            return Ok(());
        }
        loop {
            if self.peek() != Some(b'"') {
                return Err(self.unexpected("a key (a string)"));
            }
            let key_start = self.pos;
            let key = self.decoded_string()?;
            self.skip_ws();
            if self.peek() != Some(b':') {
                return Err(self.unexpected("':'"));
            }
            self.pos += 1;
            self.skip_ws();
            member(self, key, key_start)?;
            self.skip_ws();
            match self.peek() {
                Some(b',') => {
                    self.pos += 1;
                    self.skip_ws();
                    if self.peek() == Some(b'}') {
                        return Err((self.pos, ParseErrorKind::TrailingComma));
                    }
                }
                Some(b'}') => {
                    self.pos += 1;
                    self.depth -= 1;
                    return Ok(());
                }
                _ => return Err(self.unexpected("',' or '}'")),
            }
        }
    }

    /// A string's decoded text. Most have no escapes and are taken from the source as they
    /// stand; the others are decoded into a buffer.
    fn string(&mut self) -> Result<Text, Fail> {
        self.decoded_string().map(Text::from)
    }

    /// A string's decoded text, borrowed from the source where it has no escapes.
    fn decoded_string(&mut self) -> Result<Cow<'a, str>, Fail> {
        let mut decoded = None;
        let last_run = self.string_runs(&mut decoded)?;
        Ok(match decoded {
            None => Cow::Borrowed(last_run),
            Some(mut decoded) => {
                decoded.push_str(last_run);
                Cow::Owned(decoded)
            }
        })
    }

    /// Reads a string up to its closing quote. Its text before the last escape is decoded into
    /// `decoded` (left `None` where it has no escape); the rest is returned as it stands.
    fn string_runs(&mut self, decoded: &mut Option<String>) -> Result<&'a str, Fail> {
        self.pos += 1; // opening quote
        loop {
            // Take the run of plain characters in one piece. It starts and ends next to ASCII
            // bytes (or the end), so both ends are character boundaries.
            let run_start = self.pos;
            while let Some(b) = self.peek() {
                if b == b'"' || b == b'\\' || b < 0x20 {
                    break;
                }
                self.pos += 1;
            }
            let run = self.text.get(run_start..self.pos).unwrap_or("");
            match self.peek() {
                None => return Err((self.pos, ParseErrorKind::UnexpectedEnd)),
                Some(b'"') => {
                    self.pos += 1;
                    return Ok(run);
                }
                Some(b'\\') => {
                    let decoded = decoded.get_or_insert_with(String::new);
                    decoded.push_str(run);
                    self.escape(decoded)?;
                }
                Some(byte) => return Err((self.pos, ParseErrorKind::ControlCharacter { byte })),
            }
        }
    }

    fn escape(&mut self, out: &mut String) -> Result<(), Fail> {
        let at = self.pos;
        self.pos += 1; // backslash
        let Some(b) = self.peek() else {
            return Err((self.pos, ParseErrorKind::UnexpectedEnd));
        };
        let c = match b {
            b'"' => '"',
            b'\\' => '\\',
            b'/' => '/',
            b'b' => '\u{8}',
            b'f' => '\u{c}',
            b'n' => '\n',
            b'r' => '\r',
            b't' => '\t',
            b'u' => {
                self.pos += 1;
                let unit = self.hex4(at)?;
                out.push(self.surrogate_pair(unit)?);
                return Ok(());
            }
            _ => {
                return Err((
                    at,
                    ParseErrorKind::InvalidEscape {
                        found: self.char_here(),
                    },
                ));
            }
        };
        self.pos += 1;
        out.push(c);
        Ok(())
    }

    /// Completes a `\u` escape whose first code unit has been read: joins a high surrogate with
    /// a following `\u` low surrogate, and turns lone surrogates into U+FFFD.
    fn surrogate_pair(&mut self, unit: u16) -> Result<char, Fail> {
        if !(0xD800..0xDC00).contains(&unit) {
            return Ok(char::from_u32(u32::from(unit)).unwrap_or('\u{FFFD}'));
        }
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        if rest.starts_with(b"\\u") {
            let save = self.pos;
            self.pos += 2;
            let low = self.hex4(save)?;
            if (0xDC00..0xE000).contains(&low) {
                let c = 0x10000 + ((u32::from(unit) - 0xD800) << 10) + (u32::from(low) - 0xDC00);
                return Ok(char::from_u32(c).unwrap_or('\u{FFFD}'));
            }
            // Not a low surrogate: the high one stands alone, and the next escape is read again
            // on its own.
            self.pos = save;
        }
        Ok('\u{FFFD}')
    }

    fn hex4(&mut self, escape_start: usize) -> Result<u16, Fail> {
        let mut v: u16 = 0;
        for _ in 0..4 {
            let digit = self
                .peek()
                .and_then(|b| (b as char).to_digit(16))
                .ok_or((escape_start, ParseErrorKind::InvalidUnicodeEscape))?;
            // Four hex digits fit in 16 bits exactly.
            v = (v << 4) | digit as u16;
            self.pos += 1;
        }
        Ok(v)
    }

    fn number(&mut self) -> Result<Kind, Fail> {
        let start = self.pos;
        self.check_number()?;
        let raw = self.text.get(start..self.pos).unwrap_or("0");
        Ok(Kind::Number(Number(Text::new(raw))))
    }

    /// Reads a number, checking it against the grammar.
    fn check_number(&mut self) -> Result<(), Fail> {
        if self.peek() == Some(b'-') {
            self.pos += 1;
        }
        match self.peek() {
            Some(b'0') => {
                self.pos += 1;
                if matches!(self.peek(), Some(b'0'..=b'9')) {
                    return Err((self.pos - 1, ParseErrorKind::LeadingZero));
                }
            }
            Some(b'1'..=b'9') => self.digits(),
            _ => return Err((self.pos, ParseErrorKind::MissingDigits)),
        }
        if self.peek() == Some(b'.') {
            self.pos += 1;
            self.required_digits()?;
        }
        if let Some(b'e' | b'E') = self.peek() {
            self.pos += 1;
            if let Some(b'+' | b'-') = self.peek() {
                self.pos += 1;
            }
            self.required_digits()?;
        }
        Ok(())
    }

    fn digits(&mut self) {
        while let Some(b'0'..=b'9') = self.peek() {
            self.pos += 1;
        }
    }

    fn required_digits(&mut self) -> Result<(), Fail> {
        let start = self.pos;
        self.digits();
        if self.pos == start {
            return Err((self.pos, ParseErrorKind::MissingDigits));
        }
        Ok(())
    }
}

/// Sorting beats hashing here: no hasher to seed against hostile keys, and no borrow of the
/// member list while it is built. `starts` holds where each member's key starts.
/// Fails on the first repeated key in the text, given each key with where it starts.
/// Whether an object's keys may repeat: false, at once and without allocating, for the
/// common small object whose keys all differ; [`check_unique_keys`] then has nothing to find.
/// Keys are compared as decoded bytes, as that check compares them.
fn may_repeat_keys(members: &[Member], left_out: &[(Cow<'_, str>, usize)]) -> bool {
    const COMPARED_PAIRWISE: usize = 16;
    let count = members.len() + left_out.len();
    if count > COMPARED_PAIRWISE {
        return true;
    }
    let mut keys = [&[][..]; COMPARED_PAIRWISE];
    let all = members
        .iter()
        .map(|m| m.key.as_bytes())
        .chain(left_out.iter().map(|(key, _)| key.as_bytes()));
    for (place, key) in keys.iter_mut().zip(all) {
        *place = key;
    }
    let keys = &keys[..count];
    keys.iter()
        .enumerate()
        .any(|(i, key)| keys[..i].contains(key))
}

/// Fails on the first repeated key of an object: its `members` kept (their keys starting at
/// `starts`) and its keys `left_out`.
fn refuse_repeated_keys(
    members: &[Member],
    starts: &[usize],
    left_out: &[(Cow<'_, str>, usize)],
) -> Result<(), Fail> {
    if members.len() + left_out.len() < 2 || !may_repeat_keys(members, left_out) {
        return Ok(());
    }
    let mut keys: Vec<(&str, usize)> = members
        .iter()
        .map(|m| m.key.as_str())
        .zip(starts.iter().copied())
        .chain(left_out.iter().map(|(key, start)| (key.as_ref(), *start)))
        .collect();
    check_unique_keys(&mut keys)
}

fn check_unique_keys(keys: &mut [(&str, usize)]) -> Result<(), Fail> {
    keys.sort_unstable();
    // Of all the repeats, report the one that comes first in the text.
    let repeat = keys
        .windows(2)
        .filter_map(|pair| match pair {
            [(a, _), (b, start)] if a == b => Some((*b, *start)),
            _ => None,
        })
        .min_by_key(|&(_, start)| start);
    match repeat {
        Some((key, start)) => Err((
            start,
            ParseErrorKind::DuplicateKey {
                key: key.to_owned(),
            },
        )),
        None => Ok(()),
    }
}

/// A member's value that its maker writes again when the edited text is made, rather than hand
/// the [`Editor`] a text to hold until then ([`Editor::insert_member_deferred`]): for a caller
/// that adds many values it can make again at will from less than their text (an extension
/// object for each of a quarter of a million buffer views).
pub trait DeferredValue: fmt::Debug + Send + Sync {
    /// Appends the value's text to `out`: one JSON value, the same on every call. The editor
    /// checks the first and counts on the others being equal to it.
    fn write(&self, out: &mut String);
}

/// `s` as a JSON string literal, quotes included.
pub fn escape_str(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    push_escaped(&mut out, s);
    out
}

/// Whether [`push_escaped`] writes anything of `s` other than `s` in quotes.
fn needs_escape(s: &str) -> bool {
    s.bytes().any(|b| b == b'"' || b == b'\\' || b < 0x20)
}

/// The length of what [`push_escaped`] writes for `s`, quotes included.
fn escaped_len(s: &str) -> usize {
    let escapes: usize = s
        .bytes()
        .map(|b| match b {
            b'"' | b'\\' | b'\n' | b'\r' | b'\t' => 1,
            b if b < 0x20 => 5,
            _ => 0,
        })
        .sum();
    s.len() + escapes + 2
}

/// Appends `s` to `out` as a JSON string literal, quotes included.
fn push_escaped(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
}

/// `v` as a JSON number that reads back as exactly `v` (shortest round-trip digits), or `None`
/// for NaN and infinities, which JSON cannot express.
///
/// Plain notation for ordinary magnitudes keeps files readable (`0.5`, `1`, `-0`); exponent
/// notation at the extremes avoids 40-digit spellings of `1e-40` or `f32::MAX`.
pub fn f32_text(v: f32) -> Option<String> {
    if !v.is_finite() {
        return None;
    }
    let magnitude = v.abs();
    if magnitude != 0.0 && !(1e-5..1e16).contains(&magnitude) {
        Some(format!("{v:e}"))
    } else {
        Some(format!("{v}"))
    }
}

/// A problem with a requested edit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EditError {
    /// The edit needs an object and the node is something else.
    NotAnObject {
        /// The node's span in the source.
        span: Range<usize>,
    },
    /// The edit needs an array and the node (or the member's value) is something else.
    NotAnArray {
        /// The span of the node that is not an array (for
        /// [`Editor::push_to_array_member`], the member's value).
        span: Range<usize>,
    },
    /// Adding the member would duplicate a key, or [`Editor::push_to_array_member`] names a
    /// member that this editor added with [`Editor::insert_member`] or [`Editor::set_member`].
    MemberExists {
        /// The key as the caller passed it.
        key: String,
    },
    /// The new text is not one JSON value (or starts with a byte order mark).
    InvalidText {
        /// The rejected text, in full.
        text: String,
        /// Why it does not parse; its offsets are into `text`.
        error: ParseError,
    },
    /// Two edits change overlapping text (for example a value and a member inside it).
    /// Reported by [`Editor::render`], not when the edits are made.
    Overlap {
        /// Byte range of the original text that one edit changes (an insertion is the empty
        /// range at its position). It starts no later than `second`.
        first: Range<usize>,
        /// Byte range of the original text that the other edit changes.
        second: Range<usize>,
    },
    /// An edit refers to text outside the document: its node came from another document.
    ForeignNode {
        /// The span the edit named, which is not within this document's JSON text.
        span: Range<usize>,
    },
}

impl fmt::Display for EditError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EditError::NotAnObject { span } => {
                write!(f, "the value at bytes {span:?} is not an object")
            }
            EditError::NotAnArray { span } => {
                write!(f, "the value at bytes {span:?} is not an array")
            }
            EditError::MemberExists { key } => {
                write!(f, "the object already has a member {key:?}")
            }
            EditError::InvalidText { text, error } => {
                let shown: String = text.chars().take(60).collect();
                write!(
                    f,
                    "replacement text {shown:?} is not one JSON value: {error}"
                )
            }
            EditError::Overlap { first, second } => write!(
                f,
                "two edits overlap: bytes {first:?} and bytes {second:?} of the original"
            ),
            EditError::ForeignNode { span } => write!(
                f,
                "an edit refers to bytes {span:?}, which are not a value of this document"
            ),
        }
    }
}

impl std::error::Error for EditError {}

/// Collects edits against a [`Document`] and renders the edited text.
///
/// Edits name nodes of the document they were made from (passing a node of another document is
/// a contract violation; it is caught as [`EditError::ForeignNode`] where it shows, never a panic).
/// Each edit is checked as it is made; edits that change overlapping text are reported by
/// [`Editor::render`] as [`EditError::Overlap`]. Members and elements added to one container
/// are written in the order they were added. Nothing outside the edited spans changes.
#[derive(Debug)]
pub struct Editor<'d, 'a> {
    doc: &'d Document<'a>,
    /// Each replaced span with its new text: a short text (most are numbers) held inside, so
    /// that an edit of every buffer view's offset and length costs no allocation of its own.
    replacements: Vec<Replacement>,
    objects: ObjectEdits<'d>,
    /// Keyed by the array's start offset, which is unique among containers (a document has few
    /// edited arrays: the lists tspace appends to).
    arrays: BTreeMap<usize, ArrayEdit>,
}

/// A replaced span of the source and its new text.
#[derive(Debug)]
struct Replacement {
    start: u32,
    end: u32,
    text: Text,
}

/// One object's edits. Nothing of the object is copied: where its members' keys lie is read
/// from its node when the edits are rendered (a scene may edit a hundred thousand objects, each
/// to add one member).
#[derive(Debug)]
struct ObjectEdit<'d> {
    object: &'d Node,
    /// Per original member, whether it is removed; empty while none is.
    removed: Thin<bool>,
    /// Its added members: a list of [`MemberLists`], or [`NO_MEMBERS`].
    added: u32,
}

/// An [`ObjectEdit`] that adds no member.
const NO_MEMBERS: u32 = u32::MAX;

#[derive(Debug)]
enum NewValue {
    /// A value's text of at most [`INLINE`] bytes, held inside.
    Short(Text),
    /// A longer value's text, in one allocation (a [`Text`] would take two).
    Long(Box<str>),
    /// A value its maker writes when the text is made, `len` bytes long.
    Deferred {
        len: u32,
        value: Box<dyn DeferredValue>,
    },
    /// An array member created by [`Editor::push_to_array_member`]; grows with each push.
    /// Boxed, so that a member with a short text value takes no more room than its text.
    Array(Box<NewArray>),
}

impl NewValue {
    /// A value that writes the same text, for a shared list of members that is about to change.
    fn duplicate(&self) -> NewValue {
        match self {
            NewValue::Short(text) => NewValue::Short(text.clone()),
            NewValue::Long(text) => NewValue::Long(text.clone()),
            NewValue::Deferred { value, .. } => {
                let mut text = String::new();
                value.write(&mut text);
                NewValue::text(text)
            }
            NewValue::Array(array) => NewValue::Array(Box::new(NewArray {
                items: array.items.clone(),
                count: array.count,
            })),
        }
    }

    fn text(text: String) -> NewValue {
        if text.len() <= INLINE {
            NewValue::Short(Text::new(&text))
        } else {
            NewValue::Long(text.into_boxed_str())
        }
    }

    /// The value's text when the editor holds it as one.
    fn as_text(&self) -> Option<&str> {
        match self {
            NewValue::Short(text) => Some(text),
            NewValue::Long(text) => Some(text),
            NewValue::Deferred { .. } | NewValue::Array(_) => None,
        }
    }
}

#[derive(Debug)]
struct NewArray {
    /// The elements' texts, separated by commas.
    items: String,
    count: usize,
}

/// A list held as one pointer, null while the list is empty: an edited object's or array's
/// removed flags, which nearly every one of a hundred thousand edited objects lacks.
#[derive(Debug)]
struct Thin<T>(Option<Box<Box<[T]>>>);

impl<T> Default for Thin<T> {
    fn default() -> Self {
        Thin(None)
    }
}

impl<T> Thin<T> {
    fn from_vec(items: Vec<T>) -> Self {
        Thin((!items.is_empty()).then(|| Box::new(items.into_boxed_slice())))
    }
}

impl<T> std::ops::Deref for Thin<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        self.0.as_deref().map_or(&[], |items| items)
    }
}

impl<T> std::ops::DerefMut for Thin<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        self.0.as_deref_mut().map_or(&mut [], |items| items)
    }
}

/// One array's edits.
#[derive(Debug)]
struct ArrayEdit {
    open: usize,
    /// Per original element: its span.
    elements: Box<[(u32, u32)]>,
    /// Per original element, whether it is removed; empty while none is.
    removed: Thin<bool>,
    /// The added elements' texts, each after the comma and whitespace that separate it from
    /// the one before, which rendering takes as they are.
    added: Chunks,
    /// How many elements were added.
    added_count: usize,
    /// The first added element's separator's length, left out when no original element is
    /// kept.
    first_separator: usize,
}

/// The edited objects' records, in the order of their objects' start offsets (which are unique
/// among containers). An editor is fed in text order, pass by pass, so a record whose object
/// starts after the last one's is appended to blocks of at most [`ObjectEdits::BLOCK`], with no
/// key beside it (the object's node holds its offset); a record made out of order goes to a
/// map. A map alone took about 78 bytes a record, its nodes half full when filled in order:
/// 7.8 MB for the 100,000 edited attribute objects of the `whole_path` bench's shared-geometry
/// scene, where the blocks take 3.2.
#[derive(Debug, Default)]
struct ObjectEdits<'d> {
    in_order: Vec<Vec<ObjectEdit<'d>>>,
    others: BTreeMap<u32, ObjectEdit<'d>>,
    lists: MemberLists,
}

impl<'d> ObjectEdits<'d> {
    /// Records per block (128 KiB): a block grows by doubling up to it, so an editor of a few
    /// edits takes a few records' room.
    const BLOCK: usize = 4096;

    /// Where in the ordered blocks the record of the object starting at `open` is.
    fn position(&self, open: u32) -> Option<(usize, usize)> {
        let after = self
            .in_order
            .partition_point(|block| block.first().is_some_and(|edit| edit.open() <= open));
        let block = after.checked_sub(1)?;
        let i = self
            .in_order
            .get(block)?
            .binary_search_by_key(&open, ObjectEdit::open)
            .ok()?;
        Some((block, i))
    }

    fn get(&self, open: u32) -> Option<&ObjectEdit<'d>> {
        match self.position(open) {
            Some((block, i)) => self.in_order.get(block)?.get(i),
            None => self.others.get(&open),
        }
    }

    fn get_mut(&mut self, open: u32) -> Option<&mut ObjectEdit<'d>> {
        match self.position(open) {
            Some((block, i)) => self.in_order.get_mut(block)?.get_mut(i),
            None => self.others.get_mut(&open),
        }
    }

    /// The members added to the object of `edit`.
    fn added(&self, edit: &ObjectEdit<'_>) -> &[(Text, NewValue)] {
        self.lists.get(edit.added)
    }

    /// Where member `key` is among those added to the object starting at `open`.
    fn added_position(&self, open: u32, key: &str) -> Option<usize> {
        let edit = self.get(open)?;
        self.added(edit).iter().position(|(k, _)| k == key)
    }

    /// Whether the object starting at `open` has member `key`: an original one not removed, or
    /// an added one.
    fn has_key(&self, open: u32, key: &str) -> bool {
        let Some(edit) = self.get(open) else {
            return false;
        };
        let members = edit.object.as_object().unwrap_or(&[]);
        let original = members
            .iter()
            .enumerate()
            .any(|(i, m)| m.key == key && !is_removed(&edit.removed, i));
        original || self.added(edit).iter().any(|(k, _)| k == key)
    }

    /// Changes the members added to the object starting at `open` (see [`MemberLists::change`]).
    fn change_added(&mut self, open: u32, change: impl FnOnce(&mut Vec<(Text, NewValue)>)) {
        let edit = match self.position(open) {
            Some((block, i)) => self.in_order.get_mut(block).and_then(|b| b.get_mut(i)),
            None => self.others.get_mut(&open),
        };
        if let Some(edit) = edit {
            self.lists.change(&mut edit.added, change);
        }
    }

    /// Adds the record of an object that has none.
    fn insert(&mut self, edit: ObjectEdit<'d>) {
        let open = edit.open();
        let last = self.in_order.last().and_then(|block| block.last());
        if last.is_some_and(|last| open <= last.open()) {
            self.others.insert(open, edit);
            return;
        }
        match self.in_order.last_mut() {
            Some(block) if block.len() < Self::BLOCK => block.push(edit),
            _ => self.in_order.push(vec![edit]),
        }
    }

    fn len(&self) -> usize {
        self.in_order.iter().map(Vec::len).sum::<usize>() + self.others.len()
    }

    /// The records in their objects' text order.
    fn values(&self) -> impl Iterator<Item = &ObjectEdit<'d>> {
        merged(
            self.in_order.iter().flatten(),
            self.others.values(),
            |edit: &&ObjectEdit<'d>| edit.open(),
        )
    }

    /// The records in their objects' text order, each block freed once it is read, and the
    /// lists of added members they name.
    #[allow(clippy::type_complexity)]
    fn into_parts(
        self,
    ) -> (
        impl Iterator<Item = ObjectEdit<'d>>,
        Vec<Box<[(Text, NewValue)]>>,
    ) {
        let records = merged(
            self.in_order.into_iter().flatten(),
            self.others.into_values(),
            ObjectEdit::open,
        );
        (records, self.lists.lists)
    }
}

/// The members the edited objects add, as lists their records name by index. A list equal to
/// the one made just before it is not made: it is the previous one, shared, and copied before
/// either object's members change. Primitives that share a geometry each gain the same
/// `"TANGENT": 4`, and a list each (48 bytes of the allocator) was 4.8 MB of the 100,000 such
/// primitives of the `whole_path` bench's shared-geometry scene, at the write's peak.
#[derive(Debug, Default)]
struct MemberLists {
    lists: Vec<Box<[(Text, NewValue)]>>,
    /// Per list, whether more than one record names it.
    shared: Vec<bool>,
}

impl MemberLists {
    fn get(&self, list: u32) -> &[(Text, NewValue)] {
        self.lists.get(list as usize).map_or(&[], |list| &list[..])
    }

    /// Changes the list `slot` names with `change`: in place when it is the slot's own, else
    /// (shared, or none yet) as a new list that the slot then names.
    fn change(&mut self, slot: &mut u32, change: impl FnOnce(&mut Vec<(Text, NewValue)>)) {
        let i = *slot as usize;
        let own = self.shared.get(i) == Some(&false);
        let mut members = match self.lists.get_mut(i) {
            Some(list) if own => std::mem::take(list).into_vec(),
            Some(list) => list
                .iter()
                .map(|(key, value)| (key.clone(), value.duplicate()))
                .collect(),
            None => Vec::new(),
        };
        change(&mut members);
        let members = members.into_boxed_slice();
        match self.lists.get_mut(i) {
            Some(list) if own => *list = members,
            _ => {
                self.lists.push(members);
                self.shared.push(false);
                *slot = index32(self.lists.len() - 1);
            }
        }
        self.share_with_previous(slot);
    }

    /// When the list `slot` names is the last one made and holds what the one before it holds,
    /// the slot names that one instead and the last goes.
    fn share_with_previous(&mut self, slot: &mut u32) {
        let i = *slot as usize;
        if i == 0 || i + 1 != self.lists.len() {
            return;
        }
        let same = match (self.lists.get(i - 1), self.lists.get(i)) {
            (Some(previous), Some(last)) => same_texts(previous, last),
            _ => false,
        };
        if same {
            self.lists.pop();
            self.shared.pop();
            if let Some(shared) = self.shared.get_mut(i - 1) {
                *shared = true;
            }
            *slot = index32(i - 1);
        }
    }
}

/// Whether two lists of members hold the same keys and the same texts. A value written when
/// the text is made, or an array that grows, is never taken for another.
fn same_texts(a: &[(Text, NewValue)], b: &[(Text, NewValue)]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|((ka, va), (kb, vb))| {
            ka == kb && va.as_text().is_some() && va.as_text() == vb.as_text()
        })
}

/// Adds member `key` at the end of `members`.
fn push_member(members: &mut Vec<(Text, NewValue)>, key: &str, value: NewValue) {
    // Room for one more: the list is boxed to its length again.
    members.reserve_exact(1);
    members.push((Text::new(key), value));
}

/// Two sequences, each in the order of `key`, as one in that order.
fn merged<T, K: Ord>(
    a: impl Iterator<Item = T>,
    b: impl Iterator<Item = T>,
    key: impl Fn(&T) -> K,
) -> impl Iterator<Item = T> {
    let (mut a, mut b) = (a.peekable(), b.peekable());
    std::iter::from_fn(move || match (a.peek(), b.peek()) {
        (Some(x), Some(y)) if key(y) < key(x) => b.next(),
        (Some(_), _) => a.next(),
        (None, _) => b.next(),
    })
}

/// A long text appended to in pieces, held in blocks of about [`Chunks::BLOCK`] bytes: an array
/// gaining a quarter of a million elements (every view of a large scene) made one text of tens
/// of megabytes, grown by doubling, so up to twice its length at the write's peak, and each
/// doubling copied it whole.
#[derive(Debug, Default)]
struct Chunks(Vec<String>);

impl Chunks {
    const BLOCK: usize = 256 << 10;

    /// Appends `parts`, joined, keeping them in one block.
    fn push(&mut self, parts: &[&str]) {
        let len: usize = parts.iter().map(|part| part.len()).sum();
        let fits = self
            .0
            .last()
            .is_some_and(|last| last.capacity() - last.len() >= len);
        if !fits {
            self.0.push(String::with_capacity(len.max(Self::BLOCK)));
        }
        if let Some(last) = self.0.last_mut() {
            parts.iter().for_each(|part| last.push_str(part));
        }
    }

    fn len(&self) -> usize {
        self.0.iter().map(String::len).sum()
    }

    /// The blocks, less the first `skip` bytes (which lie in the first block).
    fn parts(&self, skip: usize) -> impl Iterator<Item = &str> {
        self.0.iter().enumerate().map(move |(i, block)| match i {
            0 => block.get(skip..).unwrap_or(""),
            _ => block.as_str(),
        })
    }
}

/// Whether item `i` is removed, in a list that is empty while none is.
fn is_removed(removed: &[bool], i: usize) -> bool {
    removed.get(i).copied().unwrap_or(false)
}

/// Marks item `i` of `n` removed; false when there is no such item.
fn mark_removed(removed: &mut Thin<bool>, n: usize, i: usize) -> bool {
    if i >= n {
        return false;
    }
    if removed.is_empty() {
        *removed = Thin::from_vec(vec![false; n]);
    }
    if let Some(r) = removed.get_mut(i) {
        *r = true;
    }
    true
}

impl<'d, 'a> Editor<'d, 'a> {
    /// An editor for `doc` with no edits yet; rendering it gives `doc`'s text without any byte
    /// order mark.
    pub fn new(doc: &'d Document<'a>) -> Self {
        Editor {
            doc,
            replacements: Vec::new(),
            objects: ObjectEdits::default(),
            arrays: BTreeMap::new(),
        }
    }

    /// Replaces `node`'s text with `text`, which must be one JSON value.
    pub fn replace(&mut self, node: &Node, text: impl Into<String>) -> Result<(), EditError> {
        let text = checked_text(text.into())?;
        self.check_span(&node.span())?;
        self.push_replacement(node.span(), text)
    }

    fn push_replacement(&mut self, span: Range<usize>, text: String) -> Result<(), EditError> {
        let Piece { start, end, .. } = Piece::new(span, Insert::Nothing)?;
        let text = Text::from(text);
        self.replacements.push(Replacement { start, end, text });
        Ok(())
    }

    /// Adds member `key` at the end of `object`. Fails if the key is already there.
    pub fn insert_member(
        &mut self,
        object: &'d Node,
        key: &str,
        text: impl Into<String>,
    ) -> Result<(), EditError> {
        let text = checked_text(text.into())?;
        let open = self.object_edit(object)?.open();
        if self.objects.has_key(open, key) {
            return Err(EditError::MemberExists { key: key.into() });
        }
        let value = NewValue::text(text);
        self.objects
            .change_added(open, |members| push_member(members, key, value));
        Ok(())
    }

    /// Adds member `key` at the end of `object`, its value written by `value` when the text is
    /// made (see [`DeferredValue`]); the editor holds `value` instead of its text. Fails if the
    /// key is already there, or as [`Editor::insert_member`] does on what `value` writes.
    pub fn insert_member_deferred(
        &mut self,
        object: &'d Node,
        key: &str,
        value: Box<dyn DeferredValue>,
    ) -> Result<(), EditError> {
        let mut text = String::new();
        value.write(&mut text);
        let text = checked_text(text)?;
        let open = self.object_edit(object)?.open();
        if self.objects.has_key(open, key) {
            return Err(EditError::MemberExists { key: key.into() });
        }
        // A text past 4 GiB is held as it is.
        let new = match u32::try_from(text.len()) {
            Ok(len) => NewValue::Deferred { len, value },
            Err(_) => NewValue::text(text),
        };
        self.objects
            .change_added(open, |members| push_member(members, key, new));
        Ok(())
    }

    /// Replaces member `key`'s value, or adds the member if the object lacks it.
    pub fn set_member(
        &mut self,
        object: &'d Node,
        key: &str,
        text: impl Into<String>,
    ) -> Result<(), EditError> {
        let text = checked_text(text.into())?;
        let edit = self.object_edit(object)?;
        let open = edit.open();
        let existing = object
            .as_object()
            .and_then(|ms| ms.iter().enumerate().find(|(_, m)| m.key == key))
            .filter(|&(i, _)| !is_removed(&edit.removed, i));
        if let Some(i) = self.objects.added_position(open, key) {
            let value = NewValue::text(text);
            self.objects.change_added(open, |members| {
                if let Some((_, old)) = members.get_mut(i) {
                    *old = value;
                }
            });
            return Ok(());
        }
        match existing {
            Some((_, member)) => self.push_replacement(member.value.span(), text)?,
            None => {
                let value = NewValue::text(text);
                self.objects
                    .change_added(open, |members| push_member(members, key, value));
            }
        }
        Ok(())
    }

    /// Removes member `key` (with its comma) from `object`. Returns whether it was there.
    pub fn remove_member(&mut self, object: &'d Node, key: &str) -> Result<bool, EditError> {
        let open = self.object_edit(object)?.open();
        if let Some(i) = self.objects.added_position(open, key) {
            self.objects.change_added(open, |members| {
                members.remove(i);
            });
            return Ok(true);
        }
        let edit = self.object_edit(object)?;
        let members = object.as_object().unwrap_or(&[]);
        let found = (0..members.len()).find(|&i| {
            members.get(i).is_some_and(|m| m.key == key) && !is_removed(&edit.removed, i)
        });
        Ok(found.is_some_and(|i| mark_removed(&mut edit.removed, members.len(), i)))
    }

    /// Appends an element to `array` and returns its index in the edited array.
    pub fn append_element(
        &mut self,
        array: &Node,
        text: impl Into<String>,
    ) -> Result<usize, EditError> {
        let text = checked_text(text.into())?;
        self.append_checked_element(array, &text)
    }

    /// [`Editor::append_element`] with `text` already checked.
    fn append_checked_element(&mut self, array: &Node, text: &str) -> Result<usize, EditError> {
        let Some(elements) = array.as_array() else {
            return Err(EditError::NotAnArray { span: array.span() });
        };
        let source = self.doc.source;
        let edit = self.array_edit(array, elements)?;
        edit.add(source, text)?;
        Ok(edit.elements.len() + edit.added_count - 1)
    }

    /// Removes element `index` (with its comma) from `array`. Returns whether there was such an
    /// element. Indices are those of the original array; later elements move down, which the
    /// caller must reflect wherever they are referenced.
    pub fn remove_element(&mut self, array: &Node, index: usize) -> Result<bool, EditError> {
        let Some(elements) = array.as_array() else {
            return Err(EditError::NotAnArray { span: array.span() });
        };
        let edit = self.array_edit(array, elements)?;
        Ok(mark_removed(&mut edit.removed, edit.elements.len(), index))
    }

    fn array_edit(&mut self, array: &Node, elements: &[Node]) -> Result<&mut ArrayEdit, EditError> {
        self.check_span(&array.span())?;
        Ok(self
            .arrays
            .entry(array.span().start)
            .or_insert_with(|| ArrayEdit {
                open: array.span().start,
                elements: elements.iter().map(|e| (e.start, e.end)).collect(),
                removed: Thin::default(),
                added: Chunks::default(),
                added_count: 0,
                first_separator: 0,
            }))
    }

    /// Appends an element to the array in member `key` of `object`, creating the member (as a
    /// one-element array at the end of the object) when the object lacks it. Returns the new
    /// element's index. This is how a glTF document gains `accessors` or `bufferViews`.
    pub fn push_to_array_member(
        &mut self,
        object: &'d Node,
        key: &str,
        text: impl Into<String>,
    ) -> Result<usize, EditError> {
        let text = checked_text(text.into())?;
        let edit = self.object_edit(object)?;
        let open = edit.open();
        if let Some(i) = self.objects.added_position(open, key) {
            let is_array = self.objects.get(open).is_some_and(|edit| {
                matches!(
                    self.objects.added(edit).get(i),
                    Some((_, NewValue::Array(_)))
                )
            });
            if !is_array {
                return Err(EditError::MemberExists { key: key.into() });
            }
            let mut index = 0;
            self.objects.change_added(open, |members| {
                if let Some((_, NewValue::Array(array))) = members.get_mut(i) {
                    array.items.push(',');
                    array.items.push_str(&text);
                    array.count += 1;
                    index = array.count - 1;
                }
            });
            return Ok(index);
        }
        let edit = self.object_edit(object)?;
        let existing = object
            .as_object()
            .and_then(|ms| ms.iter().enumerate().find(|(_, m)| m.key == key));
        match existing {
            Some((i, member)) if !is_removed(&edit.removed, i) => {
                self.append_checked_element(&member.value, &text)
            }
            _ => {
                let items = NewValue::Array(Box::new(NewArray {
                    items: text,
                    count: 1,
                }));
                self.objects
                    .change_added(open, |members| push_member(members, key, items));
                Ok(0)
            }
        }
    }

    fn check_span(&self, span: &Range<usize>) -> Result<(), EditError> {
        let source = self.doc.source;
        if span.start < self.doc.body_start
            || span.start > span.end
            || source.get(span.clone()).is_none()
        {
            return Err(EditError::ForeignNode { span: span.clone() });
        }
        Ok(())
    }

    fn object_edit(&mut self, object: &'d Node) -> Result<&mut ObjectEdit<'d>, EditError> {
        let Some(members) = object.as_object() else {
            return Err(EditError::NotAnObject {
                span: object.span(),
            });
        };
        self.check_span(&object.span())?;
        let open = object.start;
        if self.objects.get_mut(open).is_none() {
            // A node of another document is refused here, where the edit is made, rather than
            // when the edits are rendered.
            for m in members {
                self.doc.key_span(m).ok_or(EditError::ForeignNode {
                    span: m.value.span(),
                })?;
            }
            let edit = ObjectEdit {
                object,
                removed: Thin::default(),
                added: NO_MEMBERS,
            };
            self.objects.insert(edit);
        }
        self.objects.get_mut(open).ok_or(EditError::ForeignNode {
            span: object.span(),
        })
    }

    /// The edited document. Fails only on overlapping edits or nodes from another document.
    pub fn render(&self) -> Result<String, EditError> {
        let plan = self.plan()?;
        let arrays: Vec<&ArrayEdit> = self.arrays.values().collect();
        let mut objects: Vec<&ObjectEdit<'d>> = Vec::with_capacity(self.objects.len());
        objects.extend(self.objects.values());
        let mut out = String::with_capacity(plan.len);
        let inserts = Inserts {
            replacement: |i: u32| {
                let text = self.replacements.get(i as usize);
                text.map_or("", |replacement| replacement.text.as_str())
            },
            elements: |i: u32| {
                let skip = plan.skips.get(i as usize).copied().unwrap_or(0) as usize;
                let added = arrays.get(i as usize).map(|edit| &edit.added);
                (skip, added)
            },
            members: |i: u32| {
                let layout = plan.layouts.get(i as usize).copied().unwrap_or_default();
                let added = objects
                    .get(i as usize)
                    .map_or(&[][..], |edit| self.objects.added(edit));
                (layout, added)
            },
        };
        let source = self.doc.source;
        write_parts(
            source,
            self.doc.body_start,
            &plan.pieces,
            &inserts,
            &mut |part| out.push_str(part),
        );
        Ok(out)
    }

    /// The edited document as the pieces it is made of, checked like [`Editor::render`]'s,
    /// for a caller that copies it once into a larger output (a GLB's JSON chunk) rather than
    /// hold a text of it besides. It borrows the source text alone, and takes the editor's
    /// texts rather than copy them: the editor's bookkeeping and the document's tree can go
    /// before the output is made.
    pub fn into_rendered(mut self) -> Result<Rendered<'a>, EditError> {
        let plan = self.plan()?;
        let Plan {
            pieces,
            skips,
            layouts,
            len,
        } = plan;
        let replacements = std::mem::take(&mut self.replacements)
            .into_iter()
            .map(|replacement| replacement.text)
            .collect();
        // Only the members are kept of each object's record (the plan has its layout).
        // Room for them all at once: the merged records do not say how many they are.
        let mut objects = Vec::with_capacity(self.objects.len());
        let (records, member_lists) = std::mem::take(&mut self.objects).into_parts();
        objects.extend(records.map(|edit| edit.added));
        let elements = std::mem::take(&mut self.arrays)
            .into_values()
            .map(|edit| edit.added)
            .collect();
        Ok(Rendered {
            source: self.doc.source,
            body_start: self.doc.body_start,
            pieces,
            replacements,
            elements,
            objects,
            member_lists,
            layouts,
            skips,
            len,
        })
    }

    /// Every edit as a piece of the text, sorted and checked, with what the pieces insert
    /// measured: replacements first, then arrays', then objects' (each in text order), so
    /// that the order in which they were added settles ties.
    fn plan(&self) -> Result<Plan, EditError> {
        let source = self.doc.source;
        // Counted first: a scene may make a million pieces, and a list grown by doubling
        // would hold up to twice that at the peak of the write.
        let arrays = self
            .arrays
            .values()
            .map(|edit| removal_runs(&edit.removed) + usize::from(edit.added_count > 0));
        let objects = self.objects.values().map(|edit| {
            removal_runs(&edit.removed) + usize::from(!self.objects.added(edit).is_empty())
        });
        let count = self.replacements.len() + arrays.sum::<usize>() + objects.sum::<usize>();
        let mut pieces = Vec::with_capacity(count);
        let mut inserted = 0usize;
        for (i, replacement) in self.replacements.iter().enumerate() {
            let (start, end) = (replacement.start, replacement.end);
            let insert = Insert::Replacement(index32(i));
            pieces.push(Piece { start, end, insert });
            inserted += replacement.text.len();
        }
        let mut skips = Vec::with_capacity(self.arrays.len());
        for (i, edit) in self.arrays.values().enumerate() {
            let mut skip = 0;
            if let Some((at, first_separator)) = edit.pieces(source, &mut pieces)? {
                pieces.push(Piece::new(at..at, Insert::Elements(index32(i)))?);
                skip = first_separator;
                inserted += edit.added.len().saturating_sub(skip);
            }
            skips.push(index32(skip));
        }
        let mut layouts = Vec::with_capacity(self.objects.len());
        for (i, edit) in self.objects.values().enumerate() {
            let added = self.objects.added(edit);
            let layout = edit.pieces(self.doc, (index32(i), !added.is_empty()), &mut pieces)?;
            inserted += members_len(source, layout, added);
            layouts.push(layout);
        }
        // An insertion at the start of a replaced span goes before it. Pieces with one span
        // (insertions at one offset) go in the order they were made, which is the order of
        // `Insert`: the sort needs no room of its own (a stable one took half the list again).
        pieces.sort_unstable_by_key(|piece| (piece.start, piece.end, piece.insert));

        let body_start = self.doc.body_start;
        let mut kept = source.len().saturating_sub(body_start);
        let mut cursor = body_start;
        let mut previous = cursor..cursor;
        for piece in &pieces {
            let range = piece.range();
            if range.start < cursor {
                return Err(EditError::Overlap {
                    first: previous,
                    second: range,
                });
            }
            if source.get(cursor..range.start).is_none() || source.get(range.clone()).is_none() {
                return Err(EditError::ForeignNode { span: range });
            }
            kept -= range.len();
            cursor = range.end;
            previous = range;
        }
        Ok(Plan {
            pieces,
            skips,
            layouts,
            len: kept + inserted,
        })
    }
}

/// The edits of an [`Editor`] as pieces of the text, sorted and checked; what the pieces
/// insert stays where the editor holds it.
struct Plan {
    pieces: Vec<Piece>,
    /// Per edited array, in text order: how much of its added text to leave out (the first
    /// separator, when no original element is kept).
    skips: Vec<u32>,
    /// Per edited object, in text order: where its added members go and the layout they copy.
    layouts: Vec<MemberLayout>,
    /// The edited text's length in bytes.
    len: usize,
}

/// One edit of the text: the source's bytes `start..end` give way to `insert`. Sixteen bytes,
/// where a range and a text were forty and the text often a copy: `compress=meshopt` on a
/// scene of many small views makes a million.
#[derive(Clone, Copy, Debug)]
struct Piece {
    start: u32,
    end: u32,
    insert: Insert,
}

/// What a [`Piece`] puts in place of its span: an index into the texts of its kind. Ordered
/// as [`Editor::plan`] makes them: replacements, then arrays' elements, then objects' members,
/// each kind by its index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Insert {
    /// Nothing: a removal.
    Nothing,
    /// Replacement `i`, in the order the replacements were made.
    Replacement(u32),
    /// The elements added to the `i`th edited array, in text order.
    Elements(u32),
    /// The members added to the `i`th edited object, in text order.
    Members(u32),
}

impl Piece {
    /// Offsets in a source [`Document::parse`] accepted fit in 32 bits; a range past them is
    /// no node of this document.
    fn new(range: Range<usize>, insert: Insert) -> Result<Piece, EditError> {
        match (u32::try_from(range.start), u32::try_from(range.end)) {
            (Ok(start), Ok(end)) => Ok(Piece { start, end, insert }),
            _ => Err(EditError::ForeignNode { span: range }),
        }
    }

    fn range(&self) -> Range<usize> {
        self.start as usize..self.end as usize
    }
}

/// A position in a list the editor holds, as 32 bits: the lists are bounded by the source's
/// length, which [`Document::parse`] keeps under 4 GiB.
fn index32(i: usize) -> u32 {
    u32::try_from(i).unwrap_or(u32::MAX)
}

/// Where an object's added members go, and the layout they copy from its last members: the
/// whitespace before a key and the spelling of the colon (spans of the source), and whether a
/// comma comes before the first (some original member is kept).
#[derive(Clone, Copy, Debug, Default)]
struct MemberLayout {
    lead: (u32, u32),
    colon: (u32, u32),
    comma: bool,
}

impl MemberLayout {
    fn lead<'s>(&self, source: &'s str) -> &'s str {
        source
            .get(self.lead.0 as usize..self.lead.1 as usize)
            .unwrap_or("")
    }

    /// The colon's spelling; a bare colon where there was no member to copy it from (the span
    /// of a real one holds at least the colon).
    fn colon<'s>(&self, source: &'s str) -> &'s str {
        match source.get(self.colon.0 as usize..self.colon.1 as usize) {
            Some(colon) if !colon.is_empty() => colon,
            _ => ":",
        }
    }
}

/// The texts [`Piece`]s insert, by kind and index.
struct Inserts<R, E, M> {
    replacement: R,
    elements: E,
    members: M,
}

/// Calls `f` with each part of the edited text in order: the source's kept runs and what
/// the pieces insert.
fn write_parts<'t, R, E, M>(
    source: &'t str,
    body_start: usize,
    pieces: &[Piece],
    inserts: &Inserts<R, E, M>,
    f: &mut impl FnMut(&str),
) where
    R: Fn(u32) -> &'t str,
    E: Fn(u32) -> (usize, Option<&'t Chunks>),
    M: Fn(u32) -> (MemberLayout, &'t [(Text, NewValue)]),
{
    let mut cursor = body_start;
    // Where deferred values are written, one after the other.
    let mut scratch = String::new();
    for piece in pieces {
        f(source.get(cursor..piece.start as usize).unwrap_or(""));
        match piece.insert {
            Insert::Nothing => {}
            Insert::Replacement(i) => f((inserts.replacement)(i)),
            Insert::Elements(i) => {
                let (skip, added) = (inserts.elements)(i);
                added
                    .into_iter()
                    .flat_map(|added| added.parts(skip))
                    .for_each(&mut *f);
            }
            Insert::Members(i) => {
                let (layout, members) = (inserts.members)(i);
                write_members(source, layout, members, &mut scratch, f);
            }
        }
        cursor = piece.end as usize;
    }
    f(source.get(cursor..).unwrap_or(""));
}

/// An object's added members as [`ObjectEdit`]'s layout writes them, part by part: written
/// where the text is made, rather than joined into a text of their own for each object.
fn write_members(
    source: &str,
    layout: MemberLayout,
    members: &[(Text, NewValue)],
    scratch: &mut String,
    f: &mut impl FnMut(&str),
) {
    let (lead, colon) = (layout.lead(source), layout.colon(source));
    let mut comma = layout.comma;
    for (key, value) in members {
        if comma {
            f(",");
            f(lead);
        }
        comma = true;
        if needs_escape(key) {
            let mut escaped = String::new();
            push_escaped(&mut escaped, key);
            f(&escaped);
        } else {
            f("\"");
            f(key);
            f("\"");
        }
        f(colon);
        match value {
            NewValue::Short(_) | NewValue::Long(_) => f(value.as_text().unwrap_or("null")),
            NewValue::Deferred { value, .. } => {
                scratch.clear();
                value.write(scratch);
                f(scratch);
            }
            NewValue::Array(array) => {
                f("[");
                f(&array.items);
                f("]");
            }
        }
    }
}

/// The length of what [`write_members`] writes.
fn members_len(source: &str, layout: MemberLayout, members: &[(Text, NewValue)]) -> usize {
    let separator = 1 + layout.lead(source).len();
    let colon = layout.colon(source).len();
    let mut comma = layout.comma;
    let mut len = 0;
    for (key, value) in members {
        if comma {
            len += separator;
        }
        comma = true;
        let value = match value {
            NewValue::Short(_) | NewValue::Long(_) => value.as_text().map_or(4, str::len),
            NewValue::Deferred { len, .. } => *len as usize,
            NewValue::Array(array) => array.items.len() + 2,
        };
        len += escaped_len(key) + colon + value;
    }
    len
}

/// An edited document in pieces: the source's kept runs and the edits' new text, in order
/// ([`Editor::into_rendered`]). Every piece was checked to lie in the source, after the one before.
#[derive(Debug)]
pub struct Rendered<'e> {
    source: &'e str,
    body_start: usize,
    pieces: Vec<Piece>,
    /// The editor's texts, taken from it: replacements in the order they were made, each
    /// edited array's added elements and each edited object's added members, in text order.
    replacements: Vec<Text>,
    elements: Vec<Chunks>,
    /// Per edited object, the list in `member_lists` of the members it adds.
    objects: Vec<u32>,
    member_lists: Vec<Box<[(Text, NewValue)]>>,
    /// Where each edited object's members go, and the layout they copy.
    layouts: Vec<MemberLayout>,
    /// How much of each edited array's added text to leave out.
    skips: Vec<u32>,
    len: usize,
}

impl Rendered<'_> {
    /// The length of the edited text in bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the edited text is empty (never, for a document: it holds a value).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Calls `f` with each part of the edited text in order; together they are
    /// [`Rendered::len`] bytes.
    pub fn for_each_part(&self, mut f: impl FnMut(&str)) {
        let inserts = Inserts {
            replacement: |i: u32| self.replacements.get(i as usize).map_or("", Text::as_str),
            elements: |i: u32| {
                let skip = self.skips.get(i as usize).copied().unwrap_or(0) as usize;
                (skip, self.elements.get(i as usize))
            },
            members: |i: u32| {
                let layout = self.layouts.get(i as usize).copied().unwrap_or_default();
                let list = self.objects.get(i as usize).copied();
                let added = list
                    .and_then(|list| self.member_lists.get(list as usize))
                    .map_or(&[][..], |added| &added[..]);
                (layout, added)
            },
        };
        write_parts(self.source, self.body_start, &self.pieces, &inserts, &mut f);
    }
}

/// Checks `bytes` as [`Document::parse`] does, and fails where it fails, building nothing;
/// whether it starts with a byte order mark when it passes.
fn check(bytes: &[u8]) -> Result<bool, ParseError> {
    let source = checked_source(bytes)?;
    let had_bom = bytes.starts_with(BOM);
    let body_start = if had_bom { BOM.len() } else { 0 };
    Parser::new(source, body_start, None)
        .whole_text(Parser::skip_value)
        .map_err(|(at, kind)| ParseError::new(source, at, kind))?;
    Ok(had_bom)
}

fn checked_text(text: String) -> Result<String, EditError> {
    // Checking each new fragment keeps the output valid JSON whatever the caller passes in, and
    // costs little next to the document itself.
    match check(text.as_bytes()) {
        Ok(false) => Ok(text),
        Ok(true) => Err(EditError::InvalidText {
            error: ParseError::new(
                &text,
                0,
                ParseErrorKind::Unexpected {
                    found: '\u{FEFF}',
                    expected: "a value",
                },
            ),
            text,
        }),
        Err(error) => Err(EditError::InvalidText { text, error }),
    }
}

fn slice(source: &str, range: Range<usize>) -> Result<&str, EditError> {
    source
        .get(range.clone())
        .ok_or(EditError::ForeignNode { span: range })
}

/// The whitespace that precedes an element, given the gap between it and the previous one
/// (`ws , ws`): the part after the comma.
fn lead_after_comma(gap: &str) -> &str {
    gap.find(',').map_or("", |i| gap.get(i + 1..).unwrap_or(""))
}

/// How many pieces [`removal_pieces`] makes: one per run of removed items.
fn removal_runs(removed: &[bool]) -> usize {
    let starts = removed
        .windows(2)
        .filter(|pair| !pair[0] && pair[1])
        .count();
    starts + usize::from(removed.first() == Some(&true))
}

/// The deletions for removed items (members or elements), given each item's start and end.
/// Removals go by runs of adjacent removed items, so that each comma is deleted once: a run
/// after a kept item takes the comma before it; a run at the start takes the comma after it; a
/// run that is everything takes no comma.
fn removal_pieces(
    n: usize,
    removed: impl Fn(usize) -> bool,
    start: impl Fn(usize) -> usize,
    end: impl Fn(usize) -> usize,
    source: &str,
    out: &mut Vec<Piece>,
) -> Result<(), EditError> {
    let mut i = 0;
    while i < n {
        if !removed(i) {
            i += 1;
            continue;
        }
        let first = i;
        while i < n && removed(i) {
            i += 1;
        }
        let last = i - 1;
        let range = if first > 0 {
            end(first - 1)..end(last)
        } else if i < n {
            start(first)..start(i)
        } else {
            start(first)..end(last)
        };
        slice(source, range.clone())?;
        out.push(Piece::new(range, Insert::Nothing)?);
    }
    Ok(())
}

impl ObjectEdit<'_> {
    /// The object's start offset, which keys its record.
    fn open(&self) -> u32 {
        self.object.start
    }

    /// The removals' pieces and the added members' (at the end of the object, `Members(index)`);
    /// returns the layout the added members copy.
    fn pieces(
        &self,
        doc: &Document<'_>,
        (index, adds): (u32, bool),
        out: &mut Vec<Piece>,
    ) -> Result<MemberLayout, EditError> {
        let source = doc.source;
        let members = self.object.as_object().unwrap_or(&[]);
        let n = members.len();
        let open = self.object.span().start;
        // Where member `i`'s key starts (what a removal cuts from), and where its value ends;
        // `object_edit` checked that every key is found.
        let key_span = |i: usize| members.get(i).and_then(|m| doc.key_span(m));
        let start = |i: usize| key_span(i).map_or(0, |key| key.start);
        let end = |i: usize| members.get(i).map_or(0, |m| m.value.span().end);
        let removed = |i: usize| is_removed(&self.removed, i);

        removal_pieces(n, removed, start, end, source, out)?;

        if !adds {
            return Ok(MemberLayout::default());
        }
        // New members copy the layout of the last existing ones: the whitespace before a key,
        // and the spelling of the colon.
        let (at, lead, colon) = match members.last() {
            None => (open + 1, open + 1..open + 1, None),
            Some(last) => {
                let lead = if n >= 2 {
                    let gap = end(n - 2)..start(n - 1);
                    let comma = slice(source, gap.clone())?.find(',');
                    comma.map_or(gap.end, |i| gap.start + i + 1)..gap.end
                } else {
                    open + 1..start(n - 1)
                };
                slice(source, lead.clone())?;
                let key_end = key_span(n - 1).map_or(0, |key| key.end);
                let colon = key_end..last.value.span().start;
                slice(source, colon.clone())?;
                (end(n - 1), lead, Some(colon))
            }
        };
        let span = |range: Range<usize>| -> Result<(u32, u32), EditError> {
            let piece = Piece::new(range, Insert::Nothing)?;
            Ok((piece.start, piece.end))
        };
        let layout = MemberLayout {
            lead: span(lead)?,
            // No member to copy: a bare colon (`MemberLayout::colon` reads an empty span so).
            colon: match colon {
                Some(colon) => span(colon)?,
                None => (0, 0),
            },
            comma: (0..n).any(|i| !removed(i)),
        };
        out.push(Piece::new(at..at, Insert::Members(index))?);
        Ok(layout)
    }
}

impl ArrayEdit {
    /// Appends an element's text, after the separator the array's own elements have: the
    /// whitespace after the comma between the last two, or before the only one.
    fn add(&mut self, source: &str, text: &str) -> Result<(), EditError> {
        let lead = match *self.elements {
            [] => "",
            [(start, _)] => slice(source, self.open + 1..start as usize)?,
            [.., (_, before_end), (last_start, _)] => {
                lead_after_comma(slice(source, before_end as usize..last_start as usize)?)
            }
        };
        if self.added_count == 0 {
            self.first_separator = 1 + lead.len();
        }
        self.added.push(&[",", lead, text]);
        self.added_count += 1;
        Ok(())
    }

    /// The removals' pieces, and where the added elements go with how much of their text to
    /// leave out (the first separator, when no original element is kept).
    fn pieces(
        &self,
        source: &str,
        out: &mut Vec<Piece>,
    ) -> Result<Option<(usize, usize)>, EditError> {
        let n = self.elements.len();
        let removed = |i: usize| is_removed(&self.removed, i);
        let start = |i: usize| self.elements.get(i).map_or(0, |e| e.0 as usize);
        let end = |i: usize| self.elements.get(i).map_or(0, |e| e.1 as usize);
        removal_pieces(n, removed, start, end, source, out)?;
        if self.added_count == 0 {
            return Ok(None);
        }
        let at = match n {
            0 => self.open + 1,
            _ => end(n - 1),
        };
        let kept = (0..n).any(|i| !removed(i));
        let skip = if kept { 0 } else { self.first_separator };
        Ok(Some((at, skip)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn parse(s: &str) -> Result<Document<'_>, ParseError> {
        Document::parse(s.as_bytes())
    }

    #[test]
    fn a_number_from_its_text_reads_as_the_parsed_one() {
        for text in [
            "3",
            "3.0",
            "3e2",
            "-0",
            "-7",
            "1.5",
            "18446744073709551616",
            "0.0e5",
        ] {
            let doc = Document::parse(text.as_bytes()).unwrap();
            let number = Number::from_text(text).unwrap();
            assert_eq!(number.as_u64(), doc.root().as_u64(), "{text}");
            assert_eq!(number.raw(), text);
        }
        for text in ["", "01", "3 ", " 3", "1.", "-", "+1", "0x10", "1e", "\"3\""] {
            assert!(Number::from_text(text).is_none(), "{text:?}");
        }
    }

    #[test]
    fn members_are_found_by_keys_short_and_long() {
        // Each key as the document spells it and as it reads back: around a `Text`'s inline
        // length, long, and with escapes.
        let keys = [
            ("", ""),
            ("a", "a"),
            ("POSITION", "POSITION"),
            ("thirteen-char", "thirteen-char"),
            ("fourteen-chars", "fourteen-chars"),
            ("fifteen-chars!!", "fifteen-chars!!"),
            ("KHR_materials_clearcoat", "KHR_materials_clearcoat"),
            ("tab\\there", "tab\there"),
            ("\\u00e9t\\u00e9", "\u{e9}t\u{e9}"),
        ];
        let text = format!(
            "{{{}}}",
            keys.iter()
                .enumerate()
                .map(|(i, (spelled, _))| format!("\"{spelled}\": {i}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        let doc = parse(&text).unwrap();
        let root = doc.root();
        let decoded = keys.map(|(_, decoded)| decoded);
        for (i, key) in decoded.iter().enumerate() {
            assert_eq!(
                root.get(key).and_then(Node::as_u64),
                Some(i as u64),
                "{key:?}"
            );
        }
        for absent in [
            "b",
            "POSITIO",
            "POSITION_",
            "fourteen-charz",
            "fifteen-chars!?",
        ] {
            assert!(root.get(absent).is_none(), "{absent:?}");
        }
    }

    fn kind_of(s: &str) -> ParseErrorKind {
        match parse(s) {
            Ok(_) => panic!("{s:?} parsed"),
            Err(e) => e.kind,
        }
    }

    fn edited(
        s: &str,
        f: impl for<'d, 'a> FnOnce(&'d Document<'a>, &mut Editor<'d, 'a>),
    ) -> String {
        let doc = parse(s).unwrap();
        let mut ed = doc.editor();
        f(&doc, &mut ed);
        let out = ed.render().unwrap();
        // Every edit must leave valid JSON behind.
        parse(&out).unwrap_or_else(|e| panic!("{out:?}: {e}"));
        // The pieces a GLB is written from say the same.
        let rendered = ed.into_rendered().unwrap();
        let mut joined = String::new();
        rendered.for_each_part(|part| joined.push_str(part));
        assert_eq!(joined, out);
        assert_eq!(rendered.len(), out.len());
        out
    }

    /// The text does not depend on the order in which objects are edited: nested objects (an
    /// outer object inserting right after an inner one that inserts too), empty ones, and
    /// removals and replacements beside.
    #[test]
    fn objects_edited_in_any_order_render_alike() {
        let s = r#"{"a":{"b":{},"c":{"d":1,"e":{}}},"f":{"g":2}}"#;
        let render = |order: &[usize]| {
            edited(s, |doc, ed| {
                let root = doc.root();
                let a = root.get("a").unwrap();
                let c = a.get("c").unwrap();
                let nodes = [
                    root,
                    a,
                    a.get("b").unwrap(),
                    c,
                    c.get("e").unwrap(),
                    root.get("f").unwrap(),
                ];
                for &i in order {
                    ed.insert_member(nodes[i], &format!("new{i}"), i.to_string())
                        .unwrap();
                }
                assert!(ed.remove_member(c, "d").unwrap());
                ed.set_member(root.get("f").unwrap(), "g", "3").unwrap();
            })
        };
        let forward = render(&[0, 1, 2, 3, 4, 5]);
        assert_eq!(
            forward,
            r#"{"a":{"b":{"new2":2},"c":{"e":{"new4":4},"new3":3},"new1":1},"f":{"g":3,"new5":5},"new0":0}"#
        );
        for order in [[5, 4, 3, 2, 1, 0], [2, 0, 4, 1, 5, 3], [4, 2, 1, 5, 0, 3]] {
            assert_eq!(render(&order), forward, "edited in the order {order:?}");
        }
    }

    #[test]
    fn records_past_a_block_and_out_of_order_are_found_and_rendered_in_text_order() {
        // More objects than a block of records holds, edited first every other one in text
        // order (the blocks), then the rest (the map), then each once more (found again).
        let n = 2 * ObjectEdits::BLOCK + 3;
        let s = format!("[{}]", vec!["{}"; n].join(","));
        let out = edited(&s, |doc, ed| {
            let items = doc.root().as_array().unwrap();
            for i in (0..n).step_by(2).chain((1..n).step_by(2)) {
                ed.insert_member(&items[i], "i", i.to_string()).unwrap();
            }
            for i in (0..n).rev() {
                ed.insert_member(&items[i], "j", "0").unwrap();
            }
            assert_eq!(ed.objects.len(), n);
            assert!(!ed.objects.others.is_empty() && ed.objects.in_order.len() > 1);
        });
        let expected: Vec<String> = (0..n).map(|i| format!(r#"{{"i":{i},"j":0}}"#)).collect();
        assert_eq!(out, format!("[{}]", expected.join(",")));
    }

    const ODD: &str = "\r\n\t {  \"a\" :[1 ,2.50,-0, 1e400 ,0.1000000000000000055511151231257827,\
        18446744073709551616],\n\"s\":\"\\u00e9\\ud83d\\ude00\\/\\\"x\\\\\", \"é\": {\"ext\" :{}},\
        \"n\":null ,\"t\":true,\"f\":false, \"e\":[ ] }\n\n";

    #[test]
    fn untouched_round_trip_is_byte_identical() {
        let doc = parse(ODD).unwrap();
        assert_eq!(doc.editor().render().unwrap(), ODD);
        let root = doc.root();
        assert_eq!(root.span(), 4..ODD.trim_end().len());
        let a = root.get("a").unwrap();
        assert_eq!(doc.text(a.index(1).unwrap()), "2.50");
        assert_eq!(a.index(2).unwrap().as_number().unwrap().raw(), "-0");
        assert_eq!(a.index(3).unwrap().as_f64(), Some(f64::INFINITY));
        assert_eq!(a.index(4).unwrap().as_f64(), Some(0.1));
        assert_eq!(a.index(5).unwrap().as_u64(), None);
        assert_eq!(root.get("s").unwrap().as_str(), Some("é😀/\"x\\"));
        assert!(root.get("é").unwrap().get("ext").is_some());
        assert!(root.get("n").unwrap().is_null());
        assert_eq!(root.get("t").unwrap().as_bool(), Some(true));
        assert_eq!(
            root.get("e").unwrap().as_array().map(<[Node]>::len),
            Some(0)
        );
        assert!(root.get("missing").is_none() && root.index(0).is_none());
    }

    #[test]
    fn texts_read_the_same_inline_and_on_the_heap() {
        // Either side of the inline limit, with a multi-byte character at the edge.
        for text in [
            "",
            "a",
            "componentType",
            "exactly14bytes",
            "fifteen bytes!!",
            "é2345678901é",
            "é23456789012é",
        ] {
            let t = Text::new(text);
            assert_eq!(t.as_str(), text);
            assert_eq!(t, *text);
            assert_eq!(t, Text::from(text.to_owned()));
            assert_eq!(format!("{t}"), text);
            assert_eq!(format!("{t:?}"), format!("{text:?}"));
        }
        assert_ne!(Text::new("ab"), Text::new("abc"));
        // Long keys, strings and numbers are found and compared like short ones.
        let doc = parse(r#"{"KHR_materials_emissive_strength": "a string longer than fourteen", "n": 0.1000000000000000055511151231257827}"#).unwrap();
        let root = doc.root();
        assert_eq!(
            root.get("KHR_materials_emissive_strength")
                .and_then(Node::as_str),
            Some("a string longer than fourteen")
        );
        let n = root.get("n").unwrap();
        assert_eq!(
            n.as_number().unwrap().raw(),
            "0.1000000000000000055511151231257827"
        );
        assert_eq!(doc.text(n), "0.1000000000000000055511151231257827");
    }

    #[test]
    fn key_spans_are_found_from_the_values() {
        let text = r#"{ "a" : 1,"b\"":[2] , "\\":{},
            "q\"\\\"" :null, "é\u00e9":"x"}"#;
        let doc = parse(text).unwrap();
        let spelled: Vec<&str> = doc
            .root()
            .as_object()
            .unwrap()
            .iter()
            .map(|m| &text[doc.key_span(m).unwrap()])
            .collect();
        assert_eq!(
            spelled,
            [
                r#""a""#,
                r#""b\"""#,
                r#""\\""#,
                r#""q\"\\\"""#,
                r#""é\u00e9""#
            ]
        );
        // A member of another document, whose value follows no key and colon here.
        let other = parse(r#"{"zzzzzzzzzzzzzzzzzzzzzzzzzzzzzz": 1}"#).unwrap();
        let foreign = &other.root().as_object().unwrap()[0];
        assert_eq!(doc.key_span(foreign), None);
    }

    #[test]
    fn fixtures_round_trip() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures");
        for name in [
            "Avocado/Avocado.gltf",
            "Lantern/Lantern.gltf",
            "BoxTextured_embedded/BoxTextured.gltf",
            "MultiUVTest/MultiUVTest.gltf",
        ] {
            let bytes = std::fs::read(format!("{dir}/{name}")).unwrap();
            let doc = Document::parse(&bytes).unwrap();
            assert_eq!(
                doc.editor().render().unwrap().as_bytes(),
                &bytes[..],
                "{name}"
            );
            assert!(doc.root().get("accessors").is_some(), "{name}");
        }
    }

    #[test]
    fn integer_accessors() {
        let doc = parse(
            "[3, 3.0, 3e2, -0, -7, 1.5, 9007199254740993.0, 18446744073709551615, -1e0, \
             4503599627370495.6, 1e400, 0e99999999999999999999, 12.3400e2, 1e-1, \
             -9223372036854775808, 9223372036854775808, 1844674407370955161.5e1]",
        )
        .unwrap();
        let v: Vec<_> = doc.root().as_array().unwrap().iter().collect();
        assert_eq!(v[0].as_u64(), Some(3));
        assert_eq!(v[1].as_u64(), Some(3));
        assert_eq!(v[2].as_u64(), Some(300));
        assert_eq!(v[3].as_u64(), Some(0));
        assert_eq!(v[4].as_u64(), None);
        assert_eq!(v[4].as_i64(), Some(-7));
        assert_eq!(v[5].as_u64(), None);
        assert_eq!(v[6].as_u64(), Some(9007199254740993), "exact beyond 2^53");
        assert_eq!(v[7].as_u64(), Some(u64::MAX));
        assert_eq!(v[8].as_i64(), Some(-1));
        assert_eq!(v[9].as_u64(), None, "f64 would round this to an integer");
        assert_eq!(v[10].as_u64(), None);
        assert_eq!(v[11].as_u64(), Some(0));
        assert_eq!(v[12].as_u64(), Some(1234));
        assert_eq!(v[13].as_u64(), None);
        assert_eq!(v[14].as_i64(), Some(i64::MIN));
        assert_eq!(v[15].as_i64(), None);
        assert_eq!(v[15].as_u64(), Some(1 << 63));
        assert_eq!(v[16].as_u64(), Some(18446744073709551615));
    }

    #[test]
    fn rejections() {
        use ParseErrorKind as K;
        assert_eq!(kind_of("[1,]"), K::TrailingComma);
        assert_eq!(kind_of("{\"a\":1,}"), K::TrailingComma);
        assert_eq!(kind_of("[01]"), K::LeadingZero);
        assert_eq!(kind_of("-01"), K::LeadingZero);
        assert_eq!(kind_of("1."), K::MissingDigits);
        assert_eq!(kind_of("1e+"), K::MissingDigits);
        assert_eq!(kind_of("-"), K::MissingDigits);
        assert!(matches!(kind_of("+1"), K::Unexpected { found: '+', .. }));
        assert!(matches!(kind_of(".5"), K::Unexpected { found: '.', .. }));
        assert_eq!(kind_of("\"a\tb\""), K::ControlCharacter { byte: 9 });
        assert_eq!(kind_of("\"\\x\""), K::InvalidEscape { found: 'x' });
        assert_eq!(kind_of("\"\\u12G4\""), K::InvalidUnicodeEscape);
        assert_eq!(kind_of("\"abc"), K::UnexpectedEnd);
        assert_eq!(kind_of(""), K::UnexpectedEnd);
        assert_eq!(kind_of("  "), K::UnexpectedEnd);
        assert_eq!(kind_of("[1] x"), K::TrailingCharacters { found: 'x' });
        assert_eq!(kind_of("{} {}"), K::TrailingCharacters { found: '{' });
        assert!(matches!(kind_of("{1:2}"), K::Unexpected { .. }));
        assert!(matches!(
            kind_of("{\"a\" 1}"),
            K::Unexpected { found: '1', .. }
        ));
        assert!(matches!(kind_of("[1 2]"), K::Unexpected { found: '2', .. }));
        assert!(matches!(kind_of("tru"), K::UnexpectedEnd));
        assert!(matches!(kind_of("nul1"), K::Unexpected { .. }));
        assert!(matches!(kind_of("NaN"), K::Unexpected { .. }));
        assert!(matches!(
            kind_of("[1]\u{a0}"),
            K::TrailingCharacters { found: '\u{a0}' }
        ));
        assert!(matches!(kind_of("// c\n{}"), K::Unexpected { .. }));
        assert_eq!(
            Document::parse(b"[\"\xff\"]").unwrap_err().kind,
            K::InvalidUtf8
        );
        let e = parse("{\"a\":1,\n \"b\":2, \"a\":3}").unwrap_err();
        assert_eq!(e.kind, K::DuplicateKey { key: "a".into() });
        assert_eq!((e.offset, e.line, e.column), (16, 2, 9));
        let msg = e.to_string();
        assert!(
            msg.contains("line 2, column 9") && msg.contains("\"a\" appears twice"),
            "{msg}"
        );
    }

    #[test]
    fn depth_limit() {
        let bomb = "[".repeat(100_000);
        assert_eq!(kind_of(&bomb), ParseErrorKind::TooDeep { limit: MAX_DEPTH });
        let objects = "{\"a\":".repeat(100_000);
        assert_eq!(
            kind_of(&objects),
            ParseErrorKind::TooDeep { limit: MAX_DEPTH }
        );
        let ok = format!("{}{}", "[".repeat(MAX_DEPTH), "]".repeat(MAX_DEPTH));
        assert!(parse(&ok).is_ok());
        let deep = format!("{}{}", "[".repeat(MAX_DEPTH + 1), "]".repeat(MAX_DEPTH + 1));
        assert_eq!(kind_of(&deep), ParseErrorKind::TooDeep { limit: MAX_DEPTH });
        // Depth is nesting, not the number of containers seen.
        let wide = format!("[{}]", vec!["[[]]"; 10_000].join(","));
        assert!(parse(&wide).is_ok());
    }

    #[test]
    fn surrogates() {
        let s = |t: &str| parse(t).unwrap().root().as_str().unwrap().to_owned();
        assert_eq!(s(r#""\ud83d\ude00""#), "😀");
        assert_eq!(s(r#""\uD83D\uDE00""#), "😀");
        assert_eq!(s(r#""\ud800""#), "\u{fffd}");
        assert_eq!(s(r#""\udc00x""#), "\u{fffd}x");
        assert_eq!(
            s(r#""\ud800\u0041""#),
            "\u{fffd}A",
            "high surrogate then a non-surrogate"
        );
        assert_eq!(s(r#""\ud800\ud800\udc00""#), "\u{fffd}\u{10000}");
        assert_eq!(
            kind_of(r#""\ud800\u00""#),
            ParseErrorKind::InvalidUnicodeEscape
        );
        // The text keeps the original escape.
        let text = r#"{"name":"\ud800"}"#;
        assert_eq!(parse(text).unwrap().editor().render().unwrap(), text);
        // Keys differing only in lone surrogates collide after decoding: refused, not guessed.
        assert!(matches!(
            kind_of(r#"{"\ud800":1,"\udbff":2}"#),
            ParseErrorKind::DuplicateKey { .. }
        ));
    }

    #[test]
    fn bom_is_skipped_and_not_written() {
        let text = "\u{feff}{\"a\": 1}";
        let doc = parse(text).unwrap();
        assert!(doc.had_bom());
        assert_eq!(doc.root().span(), 3..text.len());
        assert_eq!(doc.editor().render().unwrap(), "{\"a\": 1}");
        // Only at the very start.
        assert!(matches!(
            kind_of(" \u{feff}{}"),
            ParseErrorKind::Unexpected { .. }
        ));
    }

    #[test]
    fn replace_values() {
        let out = edited("{ \"a\" : [1, 2.0 ,3], \"b\":{\"c\":\"x\"} }", |doc, ed| {
            let root = doc.root();
            ed.replace(root.get("a").unwrap().index(1).unwrap(), "2.5")
                .unwrap();
            ed.replace(root.get("b").unwrap(), "null").unwrap();
        });
        assert_eq!(out, "{ \"a\" : [1, 2.5 ,3], \"b\":null }");
    }

    #[test]
    fn insert_members_keeps_layout() {
        let pretty = "{\n    \"asset\": {\n        \"version\": \"2.0\"\n    },\n    \"x\": 1\n}\n";
        let out = edited(pretty, |doc, ed| {
            ed.insert_member(doc.root(), "accessors", "[]").unwrap();
            ed.insert_member(doc.root(), "k\"ey", "2").unwrap();
            ed.insert_member(doc.root().get("asset").unwrap(), "generator", "\"tspace\"")
                .unwrap();
        });
        assert_eq!(
            out,
            "{\n    \"asset\": {\n        \"version\": \"2.0\",\n        \"generator\": \"tspace\"\n    },\
             \n    \"x\": 1,\n    \"accessors\": [],\n    \"k\\\"ey\": 2\n}\n"
        );
        let compact = edited("{\"a\":1,\"b\":2}", |doc, ed| {
            ed.insert_member(doc.root(), "c", "3").unwrap();
        });
        assert_eq!(compact, "{\"a\":1,\"b\":2,\"c\":3}");
        for (empty, expected) in [("{}", "{\"a\":1}"), ("{ \n }", "{\"a\":1 \n }")] {
            let out = edited(empty, |doc, ed| {
                ed.insert_member(doc.root(), "a", "1").unwrap()
            });
            assert_eq!(out, expected);
        }
        let doc = parse("{\"a\":1}").unwrap();
        let mut ed = doc.editor();
        assert_eq!(
            ed.insert_member(doc.root(), "a", "2"),
            Err(EditError::MemberExists { key: "a".into() })
        );
        assert!(matches!(
            ed.insert_member(doc.root().get("a").unwrap(), "b", "2"),
            Err(EditError::NotAnObject { .. })
        ));
        assert!(matches!(
            ed.insert_member(doc.root(), "b", "1,2"),
            Err(EditError::InvalidText { .. })
        ));
        assert!(matches!(
            ed.replace(doc.root(), "nan"),
            Err(EditError::InvalidText { .. })
        ));
    }

    #[test]
    fn set_member_replaces_or_adds() {
        let out = edited("{\"a\":1}", |doc, ed| {
            ed.set_member(doc.root(), "a", "10").unwrap();
            ed.set_member(doc.root(), "b", "20").unwrap();
            ed.set_member(doc.root(), "b", "21").unwrap();
        });
        assert_eq!(out, "{\"a\":10,\"b\":21}");
        // Values past a short text's room, added, replaced by a short one and back.
        let long = "\"longer than fourteen bytes\"";
        let out = edited("{\"a\":1}", |doc, ed| {
            ed.set_member(doc.root(), "a", long).unwrap();
            ed.set_member(doc.root(), "b", long).unwrap();
            ed.set_member(doc.root(), "c", long).unwrap();
            ed.set_member(doc.root(), "c", "3").unwrap();
            ed.set_member(doc.root(), "d", "4").unwrap();
            ed.set_member(doc.root(), "d", long).unwrap();
            assert!(ed.remove_member(doc.root(), "b").unwrap());
        });
        assert_eq!(out, format!("{{\"a\":{long},\"c\":3,\"d\":{long}}}"));
    }

    #[test]
    fn equal_added_members_are_shared_and_copied_before_either_changes() {
        let s = r#"[{"a":1},{"a":2},{"a":3},{"a":4},{},{}]"#;
        let out = edited(s, |doc, ed| {
            let items = doc.root().as_array().unwrap();
            for item in &items[..4] {
                ed.insert_member(item, "t", "9").unwrap();
            }
            assert_eq!(ed.objects.lists.lists.len(), 1, "four objects, one list");
            ed.set_member(&items[1], "t", "7").unwrap();
            ed.insert_member(&items[2], "u", "true").unwrap();
            assert!(ed.remove_member(&items[3], "t").unwrap());
            ed.push_to_array_member(&items[0], "v", "1").unwrap();
            assert_eq!(ed.push_to_array_member(&items[0], "v", "2"), Ok(1));
            // Values written when the text is made, and arrays, are each their own.
            for item in &items[4..] {
                ed.insert_member_deferred(item, "d", Box::new(Counted("n", 1)))
                    .unwrap();
                ed.push_to_array_member(item, "w", "0").unwrap();
            }
            ed.push_to_array_member(&items[5], "w", "5").unwrap();
            // The shared list (named by none now), the four copies, and the last two objects'.
            assert_eq!(ed.objects.lists.lists.len(), 7);
        });
        assert_eq!(
            out,
            r#"[{"a":1,"t":9,"v":[1,2]},{"a":2,"t":7},{"a":3,"t":9,"u":true},{"a":4},{"d":{"n":1},"w":[0]},{"d":{"n":1},"w":[0,5]}]"#
        );
    }

    /// A value written from a number when the text is made.
    #[derive(Debug)]
    struct Counted(&'static str, u32);

    impl DeferredValue for Counted {
        fn write(&self, out: &mut String) {
            out.push_str(&format!("{{\"{}\":{}}}", self.0, self.1));
        }
    }

    #[test]
    fn deferred_members_are_written_when_the_text_is_made() {
        let out = edited("[{\"a\":1},{}, {\"b\": 2, \"c\": 3}]", |doc, ed| {
            for (i, element) in doc.root().as_array().unwrap().iter().enumerate() {
                let value = Box::new(Counted("n", i as u32));
                ed.insert_member_deferred(element, "x", value).unwrap();
            }
            let first = &doc.root().as_array().unwrap()[0];
            ed.insert_member(first, "y", "\"after\"").unwrap();
        });
        assert_eq!(
            out,
            "[{\"a\":1,\"x\":{\"n\":0},\"y\":\"after\"},{\"x\":{\"n\":1}}, \
             {\"b\": 2, \"c\": 3, \"x\": {\"n\":2}}]"
        );
        let doc = parse("{\"x\":1}").unwrap();
        let mut ed = doc.editor();
        assert_eq!(
            ed.insert_member_deferred(doc.root(), "x", Box::new(Counted("n", 1))),
            Err(EditError::MemberExists { key: "x".into() })
        );
        assert!(matches!(
            ed.insert_member_deferred(doc.root(), "y", Box::new(Counted("\"", 1))),
            Err(EditError::InvalidText { .. })
        ));
        assert_eq!(ed.render().unwrap(), "{\"x\":1}");
    }

    #[test]
    fn append_elements() {
        let cases = [
            ("[]", "[7,8]"),
            ("[ ]", "[7,8 ]"),
            ("[1]", "[1,7,8]"),
            ("[\n  1\n]", "[\n  1,\n  7,\n  8\n]"),
            ("[1, 2]", "[1, 2, 7, 8]"),
            ("[1,\n\t2 ]", "[1,\n\t2,\n\t7,\n\t8 ]"),
        ];
        for (input, expected) in cases {
            let out = edited(input, |doc, ed| {
                let n = doc.root().as_array().unwrap().len();
                assert_eq!(ed.append_element(doc.root(), "7").unwrap(), n);
                assert_eq!(ed.append_element(doc.root(), "8").unwrap(), n + 1);
            });
            assert_eq!(out, expected, "{input:?}");
        }
        let doc = parse("{}").unwrap();
        assert!(matches!(
            doc.editor().append_element(doc.root(), "1"),
            Err(EditError::NotAnArray { .. })
        ));
    }

    /// More elements than one block of added text holds, after the originals are all removed
    /// (so the first separator is left out) and after some are kept.
    #[test]
    fn many_appended_elements_span_blocks() {
        let element = "{\"a\":12345678}";
        let count = 3 * Chunks::BLOCK / element.len();
        for (input, remove, expected_first) in [("[1, 2]", true, element), ("[1, 2]", false, "1")] {
            let out = edited(input, |doc, ed| {
                if remove {
                    assert!(ed.remove_element(doc.root(), 0).unwrap());
                    assert!(ed.remove_element(doc.root(), 1).unwrap());
                }
                for _ in 0..count {
                    ed.append_element(doc.root(), element).unwrap();
                }
            });
            let doc = parse(&out).unwrap();
            let elements = doc.root().as_array().unwrap();
            assert_eq!(elements.len(), count + if remove { 0 } else { 2 });
            assert_eq!(&out[elements[0].span()], expected_first);
            assert!(out.ends_with(&format!(", {element}]")));
        }
    }

    #[test]
    fn remove_elements_keeps_commas_right() {
        // (input, indices to remove, element to append or none, expected)
        let cases: [(&str, &[usize], Option<&str>, &str); 9] = [
            ("[1]", &[0], None, "[]"),
            ("[1, 2, 3]", &[1], None, "[1, 3]"),
            ("[1, 2, 3]", &[0], None, "[2, 3]"),
            ("[1, 2, 3]", &[2], None, "[1, 2]"),
            ("[1, 2, 3]", &[0, 2], None, "[2]"),
            ("[1, 2, 3]", &[0, 1, 2], None, "[]"),
            ("[1, 2, 3]", &[2], Some("9"), "[1, 2, 9]"),
            ("[1, 2, 3]", &[0, 1, 2], Some("9"), "[9]"),
            (
                "[\n  {\"a\": [1]},\n  2\n]",
                &[0],
                Some("3"),
                "[\n  2,\n  3\n]",
            ),
        ];
        for (input, remove, append, expected) in cases {
            let out = edited(input, |doc, ed| {
                for &i in remove {
                    assert!(ed.remove_element(doc.root(), i).unwrap());
                }
                if let Some(text) = append {
                    ed.append_element(doc.root(), text).unwrap();
                }
            });
            assert_eq!(out, expected, "{input:?} without {remove:?}");
            assert!(parse(&out).is_ok());
        }
        let doc = parse("[1]").unwrap();
        assert!(!doc.editor().remove_element(doc.root(), 1).unwrap());
    }

    #[test]
    fn push_to_array_member_creates_or_extends() {
        let out = edited("{\"accessors\":[{}], \"x\":1}", |doc, ed| {
            assert_eq!(
                ed.push_to_array_member(doc.root(), "accessors", "{\"a\":1}")
                    .unwrap(),
                1
            );
            assert_eq!(
                ed.push_to_array_member(doc.root(), "bufferViews", "{}")
                    .unwrap(),
                0
            );
            assert_eq!(
                ed.push_to_array_member(doc.root(), "bufferViews", "{}")
                    .unwrap(),
                1
            );
            assert!(matches!(
                ed.push_to_array_member(doc.root(), "x", "1"),
                Err(EditError::NotAnArray { .. })
            ));
        });
        assert_eq!(
            out,
            "{\"accessors\":[{},{\"a\":1}], \"x\":1, \"bufferViews\":[{},{}]}"
        );
    }

    #[test]
    fn remove_members() {
        let cases: &[(&str, &[&str], &str)] = &[
            ("{\"a\":1, \"b\":2, \"c\":3}", &["b"], "{\"a\":1, \"c\":3}"),
            ("{\"a\":1, \"b\":2, \"c\":3}", &["a"], "{\"b\":2, \"c\":3}"),
            ("{\"a\":1, \"b\":2, \"c\":3}", &["c"], "{\"a\":1, \"b\":2}"),
            ("{\"a\":1, \"b\":2, \"c\":3}", &["a", "b"], "{\"c\":3}"),
            ("{\"a\":1, \"b\":2, \"c\":3}", &["b", "c"], "{\"a\":1}"),
            ("{\"a\":1, \"b\":2, \"c\":3}", &["a", "c"], "{\"b\":2}"),
            ("{\"a\":1, \"b\":2, \"c\":3}", &["a", "b", "c"], "{}"),
            ("{ \"a\" : 1 }", &["a"], "{  }"),
            ("{\n  \"a\": 1,\n  \"b\": 2\n}", &["a"], "{\n  \"b\": 2\n}"),
        ];
        for &(input, keys, expected) in cases {
            let out = edited(input, |doc, ed| {
                for key in keys {
                    assert!(ed.remove_member(doc.root(), key).unwrap());
                }
                assert!(!ed.remove_member(doc.root(), "zz").unwrap());
            });
            assert_eq!(out, expected, "{input:?} without {keys:?}");
        }
    }

    #[test]
    fn remove_then_add() {
        let out = edited("{\"a\":1, \"b\":2}", |doc, ed| {
            ed.remove_member(doc.root(), "a").unwrap();
            ed.remove_member(doc.root(), "b").unwrap();
            ed.insert_member(doc.root(), "b", "3").unwrap();
            ed.insert_member(doc.root(), "c", "4").unwrap();
        });
        assert_eq!(out, "{\"b\":3, \"c\":4}");
        let out = edited("{\"a\":1, \"b\":2}", |doc, ed| {
            ed.remove_member(doc.root(), "b").unwrap();
            ed.set_member(doc.root(), "b", "5").unwrap();
            ed.replace(doc.root().get("a").unwrap(), "0").unwrap();
        });
        assert_eq!(out, "{\"a\":0, \"b\":5}");
        let out = edited("{\"a\":1}", |doc, ed| {
            ed.insert_member(doc.root(), "b", "2").unwrap();
            assert!(ed.remove_member(doc.root(), "b").unwrap());
        });
        assert_eq!(out, "{\"a\":1}");
        // Every element removed, before and after appending: the first added one takes no
        // comma, the next the array's own separator.
        let out = edited("[ 1,\n  2 ]", |doc, ed| {
            ed.append_element(doc.root(), "3").unwrap();
            ed.remove_element(doc.root(), 0).unwrap();
            ed.remove_element(doc.root(), 1).unwrap();
            ed.append_element(doc.root(), "4").unwrap();
        });
        assert_eq!(out, "[ 3,\n  4 ]");
    }

    #[test]
    fn overlapping_edits_are_refused() {
        let doc = parse("{\"a\":{\"b\":[1]}}").unwrap();
        let root = doc.root();
        let a = root.get("a").unwrap();
        let mut ed = doc.editor();
        ed.replace(a, "0").unwrap();
        ed.append_element(a.get("b").unwrap(), "2").unwrap();
        assert!(matches!(ed.render(), Err(EditError::Overlap { .. })));

        let mut ed = doc.editor();
        ed.replace(a.get("b").unwrap(), "0").unwrap();
        ed.remove_member(a, "b").unwrap();
        assert!(matches!(ed.render(), Err(EditError::Overlap { .. })));

        let mut ed = doc.editor();
        ed.replace(root, "1").unwrap();
        ed.replace(root, "2").unwrap();
        let err = ed.render().unwrap_err();
        assert!(err.to_string().contains("overlap"), "{err}");
    }

    #[test]
    fn foreign_nodes_are_caught() {
        let doc = parse("[1]").unwrap();
        let other = parse("[1, 2, 3, 4, 5]").unwrap();
        let mut ed = doc.editor();
        assert!(matches!(
            ed.replace(other.root(), "0"),
            Err(EditError::ForeignNode { .. })
        ));
        assert!(matches!(
            ed.append_element(other.root(), "0"),
            Err(EditError::ForeignNode { .. })
        ));
    }

    #[test]
    fn removal_runs_counts_the_pieces_removal_pieces_makes() {
        let source = "0123456789";
        for n in 0..=6 {
            for bits in 0u32..1 << n {
                let removed: Vec<bool> = (0..n).map(|i| bits & (1 << i) != 0).collect();
                let mut pieces = Vec::new();
                let (start, end) = (|i: usize| i, |i: usize| i + 1);
                removal_pieces(n, |i| removed[i], start, end, source, &mut pieces).unwrap();
                assert_eq!(removal_runs(&removed), pieces.len(), "{removed:?}");
            }
        }
    }

    #[test]
    fn escaping() {
        let tricky = "a\"b\\c\n\r\t\u{1}\u{1f}é😀/";
        let lit = escape_str(tricky);
        assert_eq!(lit, "\"a\\\"b\\\\c\\n\\r\\t\\u0001\\u001fé😀/\"");
        assert_eq!(parse(&lit).unwrap().root().as_str(), Some(tricky));
        // As an added member's key, in a text measured before it is written (see `edited`).
        let out = edited("{\"a\":1}", |doc, ed| {
            ed.insert_member(doc.root(), tricky, "2").unwrap();
        });
        assert_eq!(out, format!("{{\"a\":1,{lit}:2}}"));
    }

    #[test]
    fn f32_text_round_trips() {
        assert_eq!(f32_text(1.0).as_deref(), Some("1"));
        assert_eq!(f32_text(-0.0).as_deref(), Some("-0"));
        assert_eq!(f32_text(0.1).as_deref(), Some("0.1"));
        assert_eq!(f32_text(f32::NAN), None);
        assert_eq!(f32_text(f32::NEG_INFINITY), None);
        let specials = [
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            f32::EPSILON,
            1e-45,
            -1e-45,
            1e-5,
            9.99999e-6,
            1e16,
            9.999999e15,
            16777217.0,
            0.3,
        ];
        let mut state = 0x9E37_79B9_u32;
        let randoms = (0..200_000).map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            f32::from_bits(state)
        });
        for v in specials
            .into_iter()
            .chain(randoms)
            .filter(|v| v.is_finite())
        {
            let text = f32_text(v).unwrap();
            let doc = parse(&text).unwrap_or_else(|e| panic!("{text}: {e}"));
            let n = doc.root().as_number().unwrap();
            assert_eq!(
                n.raw().parse::<f32>().unwrap().to_bits(),
                v.to_bits(),
                "{text}"
            );
            // Readers that go through f64 first (JavaScript, serde_json) must agree too.
            assert_eq!(
                (n.as_f64().unwrap() as f32).to_bits(),
                v.to_bits(),
                "{text}"
            );
        }
    }

    /// What an edited object should read as: its members in order, each value's text (an
    /// array as its elements), and for an original member whether an edit changed its value.
    #[derive(Clone, Debug)]
    struct ModelMember {
        key: String,
        value: ModelValue,
        original: bool,
        changed: bool,
    }

    #[derive(Clone, Debug)]
    enum ModelValue {
        Text(String),
        Array(Vec<String>),
    }

    /// One edit of [`editor_matches_a_model`]: an operation, an object, a key and a value.
    type ModelEdit = (u8, usize, u8, u8);

    /// What the editor should do with an edit.
    #[derive(Debug, PartialEq)]
    enum Expected {
        Accept,
        Refuse,
        /// An edit of text an earlier edit of an original member changed (its value replaced
        /// or appended to): the editor reports the overlap when it renders, so such an edit is
        /// left out of the sequence.
        Overlaps,
    }

    fn model_key(key: u8) -> &'static str {
        ["a", "b", "c", "d"][key as usize % 4]
    }

    fn model_value(value: u8) -> &'static str {
        ["1", "22", "\"x\""][value as usize % 3]
    }

    /// Applies `edit` to the model of an object the way the editor documents it.
    fn apply_to_model(members: &mut Vec<ModelMember>, (op, _, key, value): ModelEdit) -> Expected {
        let (key, value) = (model_key(key).to_string(), model_value(value).to_string());
        let at = members.iter().position(|m| m.key == key);
        let found = at.map(|i| (i, members[i].original, members[i].changed));
        let new = |value| ModelMember {
            key: key.clone(),
            value,
            original: false,
            changed: false,
        };
        match op % 5 {
            // insert_member and insert_member_deferred
            0 | 1 => {
                if found.is_some() {
                    return Expected::Refuse;
                }
                members.push(new(ModelValue::Text(value)));
            }
            // set_member
            2 => match found {
                Some((_, true, true)) => return Expected::Overlaps,
                Some((i, original, _)) => {
                    members[i].value = ModelValue::Text(value);
                    members[i].changed = original;
                }
                None => members.push(new(ModelValue::Text(value))),
            },
            // remove_member
            3 => match found {
                Some((_, true, true)) => return Expected::Overlaps,
                Some((i, _, _)) => {
                    members.remove(i);
                }
                None => {}
            },
            // push_to_array_member
            _ => match found {
                Some((i, original, _)) => match &mut members[i].value {
                    ModelValue::Array(items) => {
                        items.push(value);
                        members[i].changed = original;
                    }
                    ModelValue::Text(_) if original => return Expected::Overlaps,
                    ModelValue::Text(_) => return Expected::Refuse,
                },
                None => members.push(new(ModelValue::Array(vec![value]))),
            },
        }
        Expected::Accept
    }

    fn render_model(objects: &[Vec<ModelMember>]) -> String {
        let object = |members: &Vec<ModelMember>| {
            let parts: Vec<String> = members
                .iter()
                .map(|m| match &m.value {
                    ModelValue::Text(text) => format!("\"{}\":{text}", m.key),
                    ModelValue::Array(items) => format!("\"{}\":[{}]", m.key, items.join(",")),
                })
                .collect();
            format!("{{{}}}", parts.join(","))
        };
        let objects: Vec<String> = objects.iter().map(object).collect();
        format!("[{}]", objects.join(","))
    }

    /// A deferred value that writes a fixed text.
    #[derive(Debug)]
    struct Fixed(String);

    impl DeferredValue for Fixed {
        fn write(&self, out: &mut String) {
            out.push_str(&self.0);
        }
    }

    proptest! {
        /// Any sequence of member edits on objects that start alike (so that their added
        /// members are shared, then copied as they part) reads as the same edits made on a
        /// plain list of members would.
        #[test]
        fn editor_matches_a_model(
            edits in proptest::collection::vec((0..5u8, 0..6usize, 0..4u8, 0..3u8), 0..60),
        ) {
            let start = r#"{"a":1,"b":[0]}"#;
            let source = format!("[{}]", [start; 6].join(","));
            let original = |key: &str, value| ModelMember {
                key: key.into(),
                value,
                original: true,
                changed: false,
            };
            let members = vec![
                original("a", ModelValue::Text("1".into())),
                original("b", ModelValue::Array(vec!["0".into()])),
            ];
            let mut model = vec![members; 6];
            let doc = parse(&source).unwrap();
            let mut ed = doc.editor();
            let objects = doc.root().as_array().unwrap();
            for &edit in &edits {
                let (op, object, key, value) = edit;
                let expected = apply_to_model(&mut model[object], edit);
                if expected == Expected::Overlaps {
                    continue;
                }
                let (node, key, value) = (&objects[object], model_key(key), model_value(value));
                let done = match op % 5 {
                    0 => ed.insert_member(node, key, value).is_ok(),
                    1 => ed
                        .insert_member_deferred(node, key, Box::new(Fixed(value.into())))
                        .is_ok(),
                    2 => ed.set_member(node, key, value).is_ok(),
                    3 => ed.remove_member(node, key).is_ok(),
                    _ => ed.push_to_array_member(node, key, value).is_ok(),
                };
                prop_assert_eq!(done, expected == Expected::Accept, "{:?}", edit);
            }
            let rendered = ed.render().unwrap();
            prop_assert_eq!(&rendered, &render_model(&model));
            let mut joined = String::new();
            ed.into_rendered().unwrap().for_each_part(|part| joined.push_str(part));
            prop_assert_eq!(joined, rendered);
        }

                /// An object's first key that repeats an earlier one is the error, however many keys
        /// it has (small objects are checked pairwise, large ones sorted), spelled with
        /// escapes or not, in a whole parse and a pruned one.
        #[test]
        fn the_first_repeated_key_is_reported(
            keys in proptest::collection::vec((0..24u8, any::<bool>()), 0..40),
        ) {
            let mut text = String::from("{");
            let mut starts = Vec::new();
            for (i, &(key, escaped)) in keys.iter().enumerate() {
                if i > 0 {
                    text.push(',');
                }
                starts.push(text.len());
                let letter = char::from(b'a' + key);
                if escaped {
                    text.push_str(&format!("\"\\u{:04x}\":{i}", u32::from(letter)));
                } else {
                    text.push_str(&format!("\"{letter}\":{i}"));
                }
            }
            text.push('}');
            let expected = keys
                .iter()
                .enumerate()
                .find(|&(i, (key, _))| keys[..i].iter().any(|(earlier, _)| earlier == key))
                .map(|(i, &(key, _))| (starts[i], char::from(b'a' + key).to_string()));
            let keep_all = |_: &[Text], _: &str| true;
            let keep_none = |_: &[Text], _: &str| false;
            for result in [
                Document::parse(text.as_bytes()).map(|_| ()),
                parse_pruned(text.as_bytes(), &keep_all).map(|_| ()),
                parse_pruned(text.as_bytes(), &keep_none).map(|_| ()),
            ] {
                match (&expected, result) {
                    (None, result) => prop_assert!(result.is_ok(), "{}", text),
                    (Some((offset, key)), Err(e)) => {
                        prop_assert_eq!(e.offset, *offset, "{}", text);
                        prop_assert_eq!(e.kind, ParseErrorKind::DuplicateKey { key: key.clone() });
                    }
                    (Some(_), Ok(())) => prop_assert!(false, "accepted {}", text),
                }
            }
        }

        /// Every spelling of an integer reads as that integer: plain digits (read at once) and
        /// the spellings with a fraction or an exponent (read by the general path) agree.
        #[test]
        fn integers_read_the_same_however_spelled(value in any::<u64>(), negative in any::<bool>()) {
            let sign = if negative { "-" } else { "" };
            let digits = value.to_string();
            let (head, tail) = digits.split_at(1);
            let spellings = [
                format!("{sign}{digits}"),
                format!("{sign}{digits}.0"),
                format!("{sign}{digits}e0"),
                format!("{sign}{head}.{tail}0E{}", tail.len()),
            ];
            let text = format!("[{}]", spellings.join(","));
            let doc = parse(&text).unwrap();
            let expected_i64 = if negative {
                0i64.checked_sub_unsigned(value)
            } else {
                i64::try_from(value).ok()
            };
            for (node, spelling) in doc.root().as_array().unwrap().iter().zip(&spellings) {
                let expected_u64 = (!negative || value == 0).then_some(value);
                prop_assert_eq!(node.as_u64(), expected_u64, "{}", spelling);
                prop_assert_eq!(node.as_i64(), expected_i64, "{}", spelling);
            }
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            if let Ok(doc) = Document::parse(&bytes) {
                let out = doc.editor().render().unwrap();
                prop_assert_eq!(out.as_bytes(), bytes.strip_prefix(BOM).unwrap_or(&bytes));
            }
        }

        #[test]
        fn json_like_text_never_panics(
            parts in proptest::collection::vec(
                prop::sample::select(vec![
                    "{", "}", "[", "]", ",", ":", " ", "\n", "\"a\"", "\"b\"", "\"\\u", "d800",
                    "\\", "1", "-", "0", ".", "e", "true", "null", "\"", "\u{feff}", "é",
                ]),
                0..64,
            )
        ) {
            let text: String = parts.concat();
            if let Ok(doc) = Document::parse(text.as_bytes()) {
                let mut ed = doc.editor();
                // Exercise every edit on whatever the root turned out to be.
                let root = doc.root();
                let _ = ed.insert_member(root, "new", "1");
                let _ = ed.push_to_array_member(root, "list", "2");
                let _ = ed.remove_member(root, "a");
                let _ = ed.append_element(root, "3");
                if let Some(first) = root.index(0) {
                    let _ = ed.replace(first, "4");
                }
                if let Ok(out) = ed.render() {
                    prop_assert!(Document::parse(out.as_bytes()).is_ok(), "{:?} -> {:?}", text, out);
                }
            }
        }

        #[test]
        fn a_pruned_parse_is_the_whole_parse_with_members_left_out(
            parts in proptest::collection::vec(
                prop::sample::select(vec![
                    "{", "}", "[", "]", ",", ":", " ", "\"a\"", "\"b\"", "\"c\"", "1", "0",
                    "true", "null", "\"", "\"\\u", "d800", "0061", "\\", "-", ".", "e",
                    "\u{1}", "fals", "é",
                ]),
                0..64,
            )
        ) {
            let text: String = parts.concat();
            let keep: Keep<'_> = &keep_a_and_b_under_a;
            let whole = Document::parse(text.as_bytes());
            // Checking alone fails where parsing does, with the same error.
            prop_assert_eq!(
                check(text.as_bytes()).map(|_| ()),
                whole.as_ref().map(|_| ()).map_err(Clone::clone)
            );
            match (whole, parse_pruned(text.as_bytes(), keep)) {
                (Ok(doc), Ok(pruned)) => {
                    prop_assert_eq!(pruned, pruned_copy(doc.root(), keep, &mut Vec::new()));
                }
                (Err(whole), Err(pruned)) => prop_assert_eq!(whole, pruned),
                (whole, pruned) => prop_assert!(false, "{:?}: {:?} against {:?}", text, whole.err(), pruned.err()),
            }
        }
    }

    /// Keeps `a` anywhere and `b` only inside an `a`.
    fn keep_a_and_b_under_a(path: &[Text], key: &str) -> bool {
        key == "a" || (key == "b" && path.last().is_some_and(|k| k.as_str() == "a"))
    }

    /// `node` with the members `keep` refuses taken out, as a pruned parse should give it.
    fn pruned_copy(node: &Node, keep: Keep<'_>, path: &mut Vec<Text>) -> Node {
        let kind = match &node.kind {
            Kind::Array(elements) => Kind::Array(
                elements
                    .iter()
                    .map(|e| pruned_copy(e, keep, path))
                    .collect(),
            ),
            Kind::Object(members) => {
                let mut kept = Vec::new();
                for m in members.iter() {
                    if keep(path, &m.key) {
                        path.push(m.key.clone());
                        let value = pruned_copy(&m.value, keep, path);
                        path.pop();
                        kept.push(Member {
                            key: m.key.clone(),
                            value,
                        });
                    }
                }
                Kind::Object(kept.into())
            }
            other => other.clone(),
        };
        Node { kind, ..*node }
    }

    #[test]
    fn a_pruned_parse_keeps_what_it_is_asked_for_and_checks_the_rest() {
        let keep: Keep<'_> = &keep_a_and_b_under_a;
        let text = br#"{"a": {"b": [1, {"a": 2, "b": 3}], "c": 4}, "b": {"a": 5}}"#;
        let root = parse_pruned(text, keep).unwrap();
        let a = root.get("a").unwrap();
        assert_eq!(a.get("b").unwrap().span(), 12..33);
        assert!(a.get("c").is_none() && root.get("b").is_none());
        let inner = a.get("b").unwrap().index(1).unwrap();
        assert_eq!(inner.get("a").and_then(Node::as_u64), Some(2));
        assert!(
            inner.get("b").is_none(),
            "a b under an array under b is not under an a"
        );
        // Errors inside members left out, and keys repeated among them, are still errors.
        for bad in [
            r#"{"c": [1,]}"#,
            r#"{"c": 1, "c": 2}"#,
            r#"{"a": 1, "c": 2, "a": 3}"#,
            r#"{"c": {"d": 1, "d": 2}}"#,
        ] {
            assert_eq!(
                parse_pruned(bad.as_bytes(), keep).unwrap_err(),
                parse(bad).unwrap_err(),
                "{bad}"
            );
        }
    }
}
