//! Wavefront OBJ and MTL, read from memory into plain arrays and triangle lists.
//!
//! OBJ is a line format with many dialects. The reader treats the input as ASCII tokens separated
//! by ASCII whitespace, so UTF-8 and Latin-1 files read alike; names (`o`, `g`, `usemtl`,
//! `mtllib`, texture paths) that are not UTF-8 are kept lossily (U+FFFD). A leading UTF-8 byte
//! order mark is skipped. Decisions where the format is loose:
//!
//! - **Comments** start at a `#` at the start of a line or after whitespace (`v 1 2 3 # note`);
//!   a `#` inside a token (`usemtl mat#2`) is part of it.
//! - **Line continuation**: a `\` ending a line (trailing whitespace aside) joins the next one;
//!   errors report the first physical line of the joined line.
//! - **Indices** are 1-based; negative ones count back from the number of elements defined so far
//!   (`-1` is the last). Both must refer to an element already defined: `0`, and anything out of
//!   range at that point, is an error with the line number. (The specification has references
//!   follow definitions; accepting forward references would cost a second pass and give no line.)
//! - **Faces with UVs or normals on some corners only** (`f 1/1 2 3/3`): the face keeps its
//!   positions and loses that attribute on every corner, counted in
//!   [`Warnings::faces_with_partial_uvs`] / [`Warnings::faces_with_partial_normals`]. Dropping is
//!   safer than guessing which UV a bare corner meant, and refusing the file would lose the mesh
//!   for a flaw the tangent core can work around (normals are generated, and a face without UVs
//!   gets no tangent from them). Different faces may freely differ in what they carry.
//! - **Vertex colours** (`v x y z r g b`, also with a 7th value, alpha, which is ignored): when
//!   any `v` has a colour, [`Obj::colors`] has one per position and positions without one are
//!   white, counted in [`Warnings::vertices_without_color`]. `v x y z w` (a rational weight) is
//!   read as `x y z`.
//! - **Polygons** become triangles by ear clipping in the polygon's best-fit plane (its Newell
//!   normal), so concave polygons come out right; a convex polygon gives exactly the fan from its
//!   first corner. A polygon with no usable plane (collinear, NaN) or one that is not simple
//!   becomes a fan, or partly one, and is counted in [`Warnings::polygons_fanned`]. So is a
//!   polygon whose ear search exceeds its work budget (proportional to its corner count), which
//!   keeps the total work linear in the input whatever it holds; in practice concave polygons of
//!   up to about 2000 corners triangulate exactly (the search is quadratic, without earcut's
//!   spatial index). The triangles of one face are
//!   consecutive and keep the face's winding. Faces with fewer than 3 corners are skipped and
//!   counted.
//! - **Ignored**: `l` and `p` (counted), free-form geometry and other statements tspace cannot use
//!   (counted in [`Warnings::unsupported_statements`], with the first few keywords named).
//!
//! Memory is bounded by the input's length and by [`Limits`]: each element, corner and triangle
//! comes from bytes actually present, and the counts are checked before anything is added.
//!
//! A file of 2 MiB or more is read in chunks of lines on the thread pool, to exactly the [`Obj`]
//! the sequential reader makes; on anything unusual the chunks give up and the file is read
//! sequentially (see the private `chunks` module).

use glam::DVec3;
use std::borrow::Cow;
use std::fmt;

mod chunks;

/// Caps on what one file may hold; exceeding one is an error, never a truncation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// The most `v`, `vt` or `vn` statements (each counted separately).
    pub max_vertices: usize,
    /// The most triangles, after triangulating polygons.
    pub max_triangles: usize,
    /// The most corners in one face.
    pub max_polygon_corners: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_vertices: 1 << 24,
            max_triangles: 1 << 24,
            max_polygon_corners: 1 << 16,
        }
    }
}

/// One triangle corner: 0-based indices into [`Obj`]'s arrays.
///
/// Twelve bytes: a texture coordinate or normal the corner lacks is held as the largest `u32`
/// rather than as an `Option` (eight bytes each), since a large OBJ holds millions of corners
/// and their array was nearly a third of the converter's peak. No index can be that value: the
/// readers refuse it as out of range.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Corner {
    pub position: u32,
    uv: u32,
    normal: u32,
}

/// What [`Corner`] holds for a texture coordinate or normal it lacks.
const NO_INDEX: u32 = u32::MAX;
const _: () = assert!(std::mem::size_of::<Corner>() == 12);

/// A 0-based index as a corner holds it, or `None` where no corner can: beyond `u32`, or
/// [`Corner`]'s mark of a missing index. Both readers refuse such an index through this.
fn corner_index(zero_based: impl TryInto<u32>) -> Option<u32> {
    zero_based.try_into().ok().filter(|&i| i != NO_INDEX)
}

impl Corner {
    /// A corner with these indices; `Some(NO_INDEX)` is taken as `None` (no reader makes it).
    pub fn new(position: u32, uv: Option<u32>, normal: Option<u32>) -> Corner {
        Corner {
            position,
            uv: uv.unwrap_or(NO_INDEX),
            normal: normal.unwrap_or(NO_INDEX),
        }
    }

    /// The texture coordinate's index, if the corner has one.
    pub fn uv(&self) -> Option<u32> {
        Some(self.uv).filter(|&i| i != NO_INDEX)
    }

    /// The normal's index, if the corner has one.
    pub fn normal(&self) -> Option<u32> {
        Some(self.normal).filter(|&i| i != NO_INDEX)
    }

    /// The same corner with texture coordinate `uv`.
    pub fn with_uv(self, uv: Option<u32>) -> Corner {
        Corner::new(self.position, uv, self.normal())
    }

    /// The same corner with normal `normal`.
    pub fn with_normal(self, normal: Option<u32>) -> Corner {
        Corner::new(self.position, self.uv(), normal)
    }
}

impl fmt::Debug for Corner {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Corner")
            .field("position", &self.position)
            .field("uv", &self.uv())
            .field("normal", &self.normal())
            .finish()
    }
}

/// A run of faces sharing object, groups and material, in file order. A change of any of them
/// starts a new run; runs are not merged, so a material used twice gives two runs. A file read
/// in chunks may have a run split where a chunk ended, continued by the next group with the
/// same object, groups and material (joining them would copy every triangle again). Smoothing
/// groups change too often to split runs (exporters switch them every few faces), so they are
/// kept per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaceGroup {
    /// The last `o` name before these faces.
    pub object: Option<String>,
    /// The names of the last `g` statement (it may name several).
    pub groups: Vec<String>,
    /// The last `usemtl` name.
    pub material: Option<String>,
    pub triangles: Vec<[Corner; 3]>,
    /// The smoothing group (`s`) of each triangle; 0 is `s off` (and the default).
    pub smoothing: Vec<u32>,
}

/// What the reader skipped or repaired. None of it stops the file from being read.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Warnings {
    pub unsupported_statements: usize,
    /// The first [`MAX_NAMED_KEYWORDS`] distinct unsupported keywords, for messages.
    pub unsupported_keywords: Vec<String>,
    pub faces_with_partial_uvs: usize,
    pub faces_with_partial_normals: usize,
    /// Faces with fewer than 3 corners, skipped.
    pub faces_too_few_corners: usize,
    /// Polygons triangulated wholly or partly as a fan (see the module documentation).
    pub polygons_fanned: usize,
    /// `l` statements, skipped.
    pub lines_skipped: usize,
    /// `p` statements, skipped.
    pub points_skipped: usize,
    /// Positions given the default white because other positions had a colour.
    pub vertices_without_color: usize,
    /// `v` statements with 5 or more than 7 values, read as their first 3.
    pub vertices_with_odd_value_count: usize,
}

/// How many distinct unsupported keywords [`Warnings`] names.
pub const MAX_NAMED_KEYWORDS: usize = 8;

impl Warnings {
    fn unsupported(&mut self, keyword: &[u8]) {
        self.unsupported_statements += 1;
        let keyword = String::from_utf8_lossy(keyword);
        if self.unsupported_keywords.len() < MAX_NAMED_KEYWORDS
            && !self.unsupported_keywords.iter().any(|k| *k == keyword)
        {
            self.unsupported_keywords.push(keyword.into_owned());
        }
    }
}

/// A parsed OBJ file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Obj {
    pub positions: Vec<[f32; 3]>,
    /// One linear RGB colour per position, if any `v` had one (see the module documentation).
    pub colors: Option<Vec<[f32; 3]>>,
    /// `vt` u and v (a third coordinate is dropped). OBJ's V axis points up (origin at the
    /// bottom left), the reverse of glTF's; the values are as written.
    pub uvs: Vec<[f32; 2]>,
    /// `vn`, as written (not normalized).
    pub normals: Vec<[f32; 3]>,
    pub groups: Vec<FaceGroup>,
    /// `mtllib` names, in order, as written.
    pub material_libraries: Vec<String>,
    /// Whether the file has an `s` statement at all: a file without one says nothing about
    /// smoothing (its faces are all in group 0, as the specification's default has it, but
    /// that is no modeller's choice), which the conversion's normals treat differently.
    pub smoothing_declared: bool,
    /// Statements read as OBJ ones (every keyword but those counted in
    /// [`Warnings::unsupported_statements`]). None at all, with lines that are not comments,
    /// means the text is not an OBJ (a README, a CSV).
    pub statements: usize,
    pub warnings: Warnings,
}

impl Obj {
    pub fn triangle_count(&self) -> usize {
        self.groups.iter().map(|g| g.triangles.len()).sum()
    }
}

/// An error, with the (first physical) line it was found on, counted from 1.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjError {
    pub line: usize,
    pub kind: ObjErrorKind,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ObjErrorKind {
    /// A value that should be a number is not.
    BadNumber { statement: String, token: String },
    TooFewValues {
        statement: String,
        expected: usize,
        found: usize,
    },
    /// A face corner that is not `v`, `v/vt`, `v//vn` or `v/vt/vn` with integer indices.
    BadCorner { token: String },
    /// Index 0, which OBJ's 1-based indices do not have.
    ZeroIndex { what: &'static str },
    /// An index outside the `count` elements defined so far.
    IndexOutOfRange {
        what: &'static str,
        index: i64,
        count: usize,
    },
    /// More `what` than [`Limits`] allows.
    LimitExceeded { what: &'static str, limit: usize },
}

impl fmt::Display for ObjErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ObjErrorKind::BadNumber { statement, token } => {
                write!(f, "{statement:?}: {token:?} is not a number")
            }
            ObjErrorKind::TooFewValues {
                statement,
                expected,
                found,
            } => write!(
                f,
                "{statement:?} needs at least {expected} value{}, found {found}",
                if *expected == 1 { "" } else { "s" }
            ),
            ObjErrorKind::BadCorner { token } => write!(
                f,
                "face corner {token:?} is not v, v/vt, v//vn or v/vt/vn with integer indices"
            ),
            ObjErrorKind::ZeroIndex { what } => {
                write!(
                    f,
                    "{what} index 0: OBJ indices start at 1 (or count back from -1)"
                )
            }
            ObjErrorKind::IndexOutOfRange { what, index, count } => write!(
                f,
                "{what} index {index} is out of range: {count} {what}{} defined so far",
                if *count == 1 { " is" } else { "s are" }
            ),
            ObjErrorKind::LimitExceeded { what, limit } => {
                write!(f, "more than {limit} {what}, the limit")
            }
        }
    }
}

impl fmt::Display for ObjError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.kind)
    }
}

impl std::error::Error for ObjError {}

fn error(line: usize, kind: ObjErrorKind) -> ObjError {
    ObjError { line, kind }
}

fn lossy(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Logical lines: physical lines with `\r\n` or `\n` endings, joined at continuations, comments
/// stripped, with the number of their first physical line.
struct Lines<'a> {
    rest: &'a [u8],
    next_line: usize,
}

impl<'a> Lines<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self::continuing(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes))
    }

    /// Lines of a piece of a file after its start, where a byte order mark is no such thing.
    fn continuing(bytes: &'a [u8]) -> Self {
        Lines {
            rest: bytes,
            next_line: 1,
        }
    }

    fn physical(&mut self) -> Option<&'a [u8]> {
        if self.rest.is_empty() {
            return None;
        }
        let (line, rest) = match memchr::memchr(b'\n', self.rest) {
            Some(i) => (&self.rest[..i], &self.rest[i + 1..]),
            None => (self.rest, &[][..]),
        };
        self.rest = rest;
        self.next_line += 1;
        Some(line.strip_suffix(b"\r").unwrap_or(line))
    }
}

/// `line` without a trailing `\` (and the whitespace after it), if it has one.
fn continued(line: &[u8]) -> Option<&[u8]> {
    line.trim_ascii_end().strip_suffix(b"\\")
}

/// `line` up to its comment, if any: the first `#` at its start or after whitespace. Found by
/// `memchr`, which skips the rest of the line in whole vectors (most lines hold no `#`).
fn strip_comment(line: &[u8]) -> &[u8] {
    for i in memchr::memchr_iter(b'#', line) {
        if i == 0 || line[i - 1].is_ascii_whitespace() {
            return &line[..i];
        }
    }
    line
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, Cow<'a, [u8]>);

    fn next(&mut self) -> Option<Self::Item> {
        let number = self.next_line;
        let first = self.physical()?;
        let Some(mut head) = continued(first) else {
            return Some((number, Cow::Borrowed(strip_comment(first))));
        };
        // Joined lines are at most the input's length.
        let mut joined = Vec::new();
        loop {
            joined.extend_from_slice(head);
            joined.push(b' ');
            let Some(next) = self.physical() else { break };
            match continued(next) {
                Some(h) => head = h,
                None => {
                    joined.extend_from_slice(next);
                    break;
                }
            }
        }
        let end = strip_comment(&joined).len();
        joined.truncate(end);
        Some((number, Cow::Owned(joined)))
    }
}

/// A statement: its keyword, its tokens, and the text after the keyword (for names with spaces).
struct Statement<'l> {
    keyword: &'l [u8],
    args: Args<'l>,
    rest: &'l [u8],
}

/// How many tokens a statement holds without allocating: every `v` (with a colour), `vt`, `vn`
/// and triangle or quad `f`, the statements a large file is made of.
const INLINE_ARGS: usize = 8;

/// A statement's tokens, read as a slice. Inline up to [`INLINE_ARGS`]: a vector per statement
/// was a tenth of the time of reading a million-triangle OBJ.
#[derive(Clone)]
enum Args<'l> {
    Inline {
        tokens: [&'l [u8]; INLINE_ARGS],
        len: usize,
    },
    Heap(Vec<&'l [u8]>),
}

impl<'l> Args<'l> {
    /// The whitespace-separated tokens of `text`.
    fn split(text: &'l [u8]) -> Self {
        let mut tokens = text.split(|&b| is_space(b)).filter(|t| !t.is_empty());
        let mut inline: [&'l [u8]; INLINE_ARGS] = [&[]; INLINE_ARGS];
        for len in 0..INLINE_ARGS {
            match tokens.next() {
                Some(token) => inline[len] = token,
                None => {
                    return Args::Inline {
                        tokens: inline,
                        len,
                    };
                }
            }
        }
        match tokens.next() {
            None => Args::Inline {
                tokens: inline,
                len: INLINE_ARGS,
            },
            Some(token) => {
                let mut all = inline.to_vec();
                all.push(token);
                all.extend(tokens);
                Args::Heap(all)
            }
        }
    }

    fn from_slice(tokens: &[&'l [u8]]) -> Self {
        if tokens.len() > INLINE_ARGS {
            return Args::Heap(tokens.to_vec());
        }
        let mut inline: [&'l [u8]; INLINE_ARGS] = [&[]; INLINE_ARGS];
        inline[..tokens.len()].copy_from_slice(tokens);
        Args::Inline {
            tokens: inline,
            len: tokens.len(),
        }
    }
}

impl<'l> std::ops::Deref for Args<'l> {
    type Target = [&'l [u8]];

    fn deref(&self) -> &[&'l [u8]] {
        match self {
            Args::Inline { tokens, len } => tokens.get(..*len).unwrap_or(tokens),
            Args::Heap(tokens) => tokens,
        }
    }
}

/// Exactly `N` numbers and nothing else on the line, or `None`; with them, the text after the
/// line (see [`line_end`]). Always inlined: called, it handed its numbers back through memory,
/// stored one float at a time and loaded as one 16-byte value, a load the CPU cannot forward
/// from those stores, which waited for them to reach the cache (a sixth of the samples of the
/// reader's loop, see docs/benchmarks.md).
#[inline(always)]
fn exact_numbers<const N: usize>(mut rest: &[u8]) -> Option<([f32; N], &[u8])> {
    let mut out = [0.0; N];
    for value in &mut out {
        *value = next_number(&mut rest)?;
    }
    Some((out, line_end(rest)?))
}

/// Moves `rest` past whitespace other than a line feed; whether anything is left. The
/// statements read in one pass are read straight from the file's text, where a line feed ends
/// the statement.
#[inline(always)]
fn skip_space(rest: &mut &[u8]) -> bool {
    while let [b, tail @ ..] = *rest {
        if !is_inline_space(*b) {
            return true;
        }
        *rest = tail;
    }
    false
}

/// [`is_space`] within a line: whitespace other than the line feed that ends it.
#[inline(always)]
fn is_inline_space(b: u8) -> bool {
    is_space(b) && b != b'\n'
}

/// After a statement's last token: the text after its line, where nothing but whitespace is
/// left on the line (a `#` comment or a `\` continuation is not read here).
#[inline(always)]
fn line_end(mut rest: &[u8]) -> Option<&[u8]> {
    skip_space(&mut rest);
    match rest {
        [] => Some(rest),
        [b'\n', tail @ ..] => Some(tail),
        _ => None,
    }
}

/// Whether `rest` starts where a token ends: at whitespace or the end of the line.
#[inline(always)]
fn at_token_end(rest: &[u8]) -> bool {
    rest.first().is_none_or(|&b| is_space(b))
}

/// The next token of `rest` as a number ([`parse_f32`]), moving past it. A plain decimal is
/// read as its bytes are met; only another spelling is first cut out as a token, so that most
/// numbers are read in one pass instead of two.
#[inline(always)]
fn next_number(rest: &mut &[u8]) -> Option<f32> {
    if !skip_space(rest) {
        return None;
    }
    let len = match short_decimal_prefix(rest) {
        Some((value, len)) if at_token_end(&rest[len..]) => {
            *rest = &rest[len..];
            return Some(value);
        }
        _ => rest.iter().position(|&b| is_space(b)).unwrap_or(rest.len()),
    };
    let token = &rest[..len];
    *rest = &rest[len..];
    parse_f32(token)
}

/// The next corner of `rest` in one of the four plain forms, `p`, `p/t`, `p//n` and `p/t/n`,
/// each index of one to nine digits and not zero, moving past it: its three 1-based indices (0
/// where absent) and whether it has a texture coordinate and a normal. `None` for anything else.
#[inline(always)]
fn next_plain_corner(rest: &mut &[u8]) -> Option<([u32; 3], (bool, bool))> {
    if !skip_space(rest) {
        return None;
    }
    let mut indices = [plain_index(rest)?, 0, 0];
    let mut shape = (false, false);
    if let [b'/', tail @ ..] = *rest {
        *rest = tail;
        if let [b'/', tail @ ..] = *rest {
            *rest = tail;
            indices[2] = plain_index(rest)?;
            shape = (false, true);
        } else {
            indices[1] = plain_index(rest)?;
            shape.0 = true;
            if let [b'/', tail @ ..] = *rest {
                *rest = tail;
                indices[2] = plain_index(rest)?;
                shape.1 = true;
            }
        }
    }
    at_token_end(rest).then_some((indices, shape))
}

/// One to nine digits at the start of `rest`, not all zero, moving past them.
#[inline(always)]
fn plain_index(rest: &mut &[u8]) -> Option<u32> {
    let mut value = 0u32;
    let mut digits = 0;
    while let Some(&b) = rest.get(digits) {
        let digit = b.wrapping_sub(b'0');
        if digit > 9 {
            break;
        }
        if digits == 9 {
            return None;
        }
        value = value * 10 + u32::from(digit);
        digits += 1;
    }
    *rest = &rest[digits..];
    (value != 0).then_some(value)
}

/// `u8::is_ascii_whitespace` (space, tab, line feed, form feed, carriage return) as one test of
/// a bit: the tokenizer asks it of every byte of the file.
#[inline(always)]
fn is_space(b: u8) -> bool {
    const SPACES: u64 = 1 << b' ' | 1 << b'\t' | 1 << b'\n' | 1 << 0x0C | 1 << b'\r';
    b <= b' ' && SPACES >> b & 1 != 0
}

fn split(line: &[u8]) -> Option<Statement<'_>> {
    let line = line.trim_ascii();
    let end = line.iter().position(|&b| is_space(b)).unwrap_or(line.len());
    if end == 0 {
        return None;
    }
    let rest = line[end..].trim_ascii();
    Some(Statement {
        keyword: &line[..end],
        args: Args::split(rest),
        rest,
    })
}

/// Parses a float: decimal and exponent forms, `inf`, `infinity` and `nan` in any case and with
/// either sign (real exporters write all of them; the tangent core copes with the values).
fn parse_f32(token: &[u8]) -> Option<f32> {
    if let Some(value) = short_decimal(token) {
        return Some(value);
    }
    let text = std::str::from_utf8(token).ok()?;
    if let Ok(v) = text.parse::<f32>() {
        return Some(v);
    }
    let unsigned = text.trim_start_matches(['+', '-']);
    (text.len() - unsigned.len() == 1 && unsigned.eq_ignore_ascii_case("nan")).then_some(f32::NAN)
}

/// The value of a plain decimal of at most about seven significant digits (`-0.123456`, `12`,
/// `.5`, `3.`), which is how exporters write nearly every number; `None` for anything else (an
/// exponent, more digits, `inf`), which the standard parser then reads.
///
/// Such a number is an integer mantissa below 2^24 and a power of ten up to 10^10, both exact
/// in `f32`, so one division (or multiplication) rounds it exactly as the standard parser does
/// (Clinger's fast path, which the standard parser takes for these numbers too). A million-
/// triangle OBJ holds millions of numbers; checking each token as UTF-8 and handing it to the
/// general parser was a sixth of the time spent reading it.
fn short_decimal(token: &[u8]) -> Option<f32> {
    short_decimal_prefix(token).and_then(|(value, len)| (len == token.len()).then_some(value))
}

/// [`short_decimal`] of the longest start of `bytes` made of a sign, digits and one point: its
/// value and length, or `None` where that start is not such a decimal. The caller checks what
/// follows it.
#[inline(always)]
fn short_decimal_prefix(bytes: &[u8]) -> Option<(f32, usize)> {
    const POWERS: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];
    let (negative, start) = match bytes.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let mut mantissa: u32 = 0;
    let mut seen_digit = false;
    let mut seen_point = false;
    let mut fraction_digits = 0usize;
    let mut end = start;
    while let Some(&b) = bytes.get(end) {
        match b {
            b'0'..=b'9' => {
                mantissa = mantissa.checked_mul(10)?.checked_add(u32::from(b - b'0'))?;
                if mantissa > 1 << 24 {
                    return None;
                }
                seen_digit = true;
                fraction_digits += usize::from(seen_point);
            }
            b'.' if !seen_point => seen_point = true,
            _ => break,
        }
        end += 1;
    }
    if !seen_digit {
        return None;
    }
    let magnitude = mantissa as f32 / *POWERS.get(fraction_digits)?;
    Some((if negative { -magnitude } else { magnitude }, end))
}

fn numbers<const N: usize>(
    statement: &Statement<'_>,
    line: usize,
    required: usize,
    defaults: [f32; N],
) -> Result<[f32; N], ObjError> {
    if statement.args.len() < required {
        return Err(error(
            line,
            ObjErrorKind::TooFewValues {
                statement: lossy(statement.keyword),
                expected: required,
                found: statement.args.len(),
            },
        ));
    }
    let mut out = defaults;
    for (slot, token) in out.iter_mut().zip(statement.args.iter()) {
        *slot = parse_f32(token).ok_or_else(|| {
            error(
                line,
                ObjErrorKind::BadNumber {
                    statement: lossy(statement.keyword),
                    token: lossy(token),
                },
            )
        })?;
    }
    Ok(out)
}

fn check_limit(
    count: usize,
    limit: usize,
    what: &'static str,
    line: usize,
) -> Result<(), ObjError> {
    if count >= limit {
        return Err(error(line, ObjErrorKind::LimitExceeded { what, limit }));
    }
    Ok(())
}

/// An integer as `i64`'s `FromStr` reads it (an optional sign, then decimal digits, nothing
/// else; `None` beyond the range), read from the bytes: a face's corners are most of a large
/// OBJ's numbers, and checking each as UTF-8 first cost as much as reading it.
fn parse_i64(token: &[u8]) -> Option<i64> {
    let (negative, digits) = match token.split_first()? {
        (b'-', rest) => (true, rest),
        (b'+', rest) => (false, rest),
        _ => (false, token),
    };
    if digits.is_empty() {
        return None;
    }
    let mut magnitude: u64 = 0;
    for &b in digits {
        if !b.is_ascii_digit() {
            return None;
        }
        magnitude = magnitude
            .checked_mul(10)?
            .checked_add(u64::from(b - b'0'))?;
    }
    if negative {
        0i64.checked_sub_unsigned(magnitude)
    } else {
        i64::try_from(magnitude).ok()
    }
}

/// Resolves a 1-based or negative OBJ index against the `count` elements defined so far.
fn resolve(token: &[u8], what: &'static str, count: usize, line: usize) -> Result<u32, ObjError> {
    let bad = || {
        error(
            line,
            ObjErrorKind::BadCorner {
                token: lossy(token),
            },
        )
    };
    let index = parse_i64(token).ok_or_else(bad)?;
    let out_of_range = || error(line, ObjErrorKind::IndexOutOfRange { what, index, count });
    let resolved = match index {
        0 => return Err(error(line, ObjErrorKind::ZeroIndex { what })),
        i if i > 0 => usize::try_from(i - 1).map_err(|_| out_of_range())?,
        i => count
            .checked_sub(usize::try_from(i.unsigned_abs()).map_err(|_| out_of_range())?)
            .ok_or_else(out_of_range)?,
    };
    if resolved >= count {
        return Err(out_of_range());
    }
    // Counts are capped by `Limits`, whose values could exceed u32 only by a caller's choice.
    corner_index(resolved).ok_or_else(out_of_range)
}

/// The state that decides which [`FaceGroup`] a face joins.
#[derive(Clone, Default, PartialEq)]
struct GroupKey {
    object: Option<String>,
    groups: Vec<String>,
    material: Option<String>,
}

struct Reader<'l> {
    limits: &'l Limits,
    obj: Obj,
    key: GroupKey,
    smoothing: u32,
    /// Whether the last group in `obj.groups` still matches `key`.
    group_current: bool,
    triangles: usize,
    // Scratch buffers reused across faces.
    corners: Vec<Corner>,
    has_uv: Vec<bool>,
    polygon: Vec<[f32; 3]>,
    local: Vec<[usize; 3]>,
    /// Set when reading one chunk of a file among others (see [`chunks`]): what the chunk
    /// cannot know of the file before it.
    chunk: Option<Box<chunks::ChunkState>>,
}

/// Reads an OBJ file (see the module documentation for the dialect and the decisions).
pub fn parse_obj(bytes: &[u8], limits: &Limits) -> Result<Obj, ObjError> {
    if let Some(obj) = chunks::parse_in_chunks(bytes, limits) {
        return Ok(obj);
    }
    parse_sequentially(bytes, limits)
}

/// [`parse_obj`]'s parallel reader on `bytes` cut into about `pieces` chunks, whatever its
/// size, with the runs it splits where chunks end joined again; `None` where it gives up (see
/// the `chunks` module). For the fuzz target, which checks it against the sequential reader on
/// inputs far smaller than those it is used for.
#[doc(hidden)]
pub fn parse_in_chunks_for_testing(bytes: &[u8], pieces: usize, limits: &Limits) -> Option<Obj> {
    let mut obj = chunks::read_pieces(&chunks::split_at_lines(bytes, pieces), limits)?;
    chunks::join_split_runs(&mut obj);
    Some(obj)
}

/// [`parse_obj`] on one thread, statement after statement: the reference for
/// [`chunks::parse_in_chunks`], and what gives every error its line.
fn parse_sequentially(bytes: &[u8], limits: &Limits) -> Result<Obj, ObjError> {
    let mut reader = Reader::new(limits, None);
    reader.read(Lines::new(bytes))?;
    let Reader { mut obj, .. } = reader;
    obj.groups.retain(|g| !g.triangles.is_empty());
    Ok(obj)
}

impl<'l> Reader<'l> {
    /// Every line of `lines`. A common statement is read straight from the text (see
    /// [`Reader::common_statement`]); any other line is cut out, joined at continuations and
    /// stripped of its comment first.
    fn read(&mut self, mut lines: Lines<'_>) -> Result<(), ObjError> {
        loop {
            if let Some(read) = self.common_statement(lines.rest) {
                lines.rest = &lines.rest[read..];
                lines.next_line += 1;
                continue;
            }
            let Some((line, text)) = lines.next() else {
                return Ok(());
            };
            self.line(&text, line)?;
        }
    }

    fn new(limits: &'l Limits, chunk: Option<Box<chunks::ChunkState>>) -> Self {
        Reader {
            limits,
            obj: Obj::default(),
            key: GroupKey::default(),
            smoothing: if chunk.is_some() {
                chunks::INHERITED
            } else {
                0
            },
            group_current: false,
            triangles: 0,
            corners: Vec::new(),
            has_uv: Vec::new(),
            polygon: Vec::new(),
            local: Vec::new(),
            chunk,
        }
    }

    /// One logical line. The statements a large file is made of are read in one pass over their
    /// bytes (see [`Reader::common_statement`]); anything else goes through [`split`] and
    /// [`Reader::statement`], which read it from the start.
    fn line(&mut self, text: &[u8], line: usize) -> Result<(), ObjError> {
        if self.common_statement(text).is_some() {
            return Ok(());
        }
        match split(text) {
            Some(statement) => self.statement(&statement, line),
            None => Ok(()),
        }
    }

    /// Reads the statement at the start of `text` if it is one of those exporters write
    /// millions of, in its plain form: `v`, `vt` or `vn` with exactly three, two or three
    /// numbers, or a triangle whose three corners are positive indices in range with the same
    /// attributes, alone on its line. Returns how many bytes it read: the line and its line
    /// feed, if any. Otherwise it has changed nothing, and the general path reads the line,
    /// finding any error and warning there; for the lines it reads, this does exactly what that
    /// path would. `text` is one logical line or the rest of the file. (Cutting every line out
    /// and tokenizing it into a slice of tokens, then each corner again at its slashes, was
    /// half of reading a million-triangle OBJ.)
    fn common_statement(&mut self, text: &[u8]) -> Option<usize> {
        let mut start = text;
        skip_space(&mut start);
        let max_vertices = self.limits.max_vertices;
        let after = match start {
            [b'f', space, rest @ ..] if is_inline_space(*space) => self.common_triangle(rest)?,
            [b'v', space, rest @ ..] if is_inline_space(*space) => {
                let (xyz, after) = exact_numbers::<3>(rest)?;
                if self.obj.positions.len() >= max_vertices {
                    return None;
                }
                let obj = &mut self.obj;
                if let Some(colors) = obj.colors.as_mut() {
                    colors.push([1.0; 3]);
                    obj.warnings.vertices_without_color += 1;
                }
                obj.positions.push(xyz);
                after
            }
            [b'v', b't', space, rest @ ..] if is_inline_space(*space) => {
                let (uv, after) = exact_numbers::<2>(rest)?;
                if self.obj.uvs.len() >= max_vertices {
                    return None;
                }
                self.obj.uvs.push(uv);
                after
            }
            [b'v', b'n', space, rest @ ..] if is_inline_space(*space) => {
                let (normal, after) = exact_numbers::<3>(rest)?;
                if self.obj.normals.len() >= max_vertices {
                    return None;
                }
                self.obj.normals.push(normal);
                after
            }
            _ => return None,
        };
        self.obj.statements += 1;
        Some(text.len() - after.len())
    }

    /// A triangle for [`Reader::common_statement`]: `rest` is the text after `f`. Returns the
    /// text after its line.
    fn common_triangle<'t>(&mut self, mut rest: &'t [u8]) -> Option<&'t [u8]> {
        if self.limits.max_polygon_corners < 3 || self.triangles >= self.limits.max_triangles {
            return None;
        }
        let mut corners = [Corner::new(0, None, None); 3];
        // The 1-based indices, to check against what is defined.
        let mut indices = [[0u32; 3]; 3];
        let mut shape = None;
        for (corner, index) in corners.iter_mut().zip(&mut indices) {
            let (read, this_shape) = next_plain_corner(&mut rest)?;
            if shape.is_some_and(|s| s != this_shape) {
                return None;
            }
            shape = Some(this_shape);
            *index = read;
            *corner = Corner::new(
                read[0] - 1,
                this_shape.0.then(|| read[1] - 1),
                this_shape.1.then(|| read[2] - 1),
            );
        }
        let after = line_end(rest)?;
        let (has_uv, has_normal) = shape?;
        let defined = [
            self.obj.positions.len(),
            if has_uv {
                self.obj.uvs.len()
            } else {
                usize::MAX
            },
            if has_normal {
                self.obj.normals.len()
            } else {
                usize::MAX
            },
        ];
        match self.chunk.as_deref_mut() {
            None => {
                let in_range = indices
                    .iter()
                    .all(|i| i.iter().zip(defined).all(|(&i, d)| i as usize <= d));
                if !in_range {
                    return None;
                }
            }
            Some(chunk) => {
                for i in &indices {
                    chunk.reach_to(
                        [
                            Some(i[0]),
                            has_uv.then_some(i[1]),
                            has_normal.then_some(i[2]),
                        ],
                        defined,
                    );
                }
            }
        }
        let smoothing = self.smoothing;
        let group = self.current_group();
        group.triangles.push(corners);
        group.smoothing.push(smoothing);
        self.triangles += 1;
        Some(after)
    }

    fn statement(&mut self, s: &Statement<'_>, line: usize) -> Result<(), ObjError> {
        let max_vertices = self.limits.max_vertices;
        match s.keyword {
            b"v" => {
                check_limit(self.obj.positions.len(), max_vertices, "vertices", line)?;
                let values = numbers(s, line, 3, [0.0; 3])?;
                self.vertex(values, s, line)?;
            }
            b"vt" => {
                check_limit(
                    self.obj.uvs.len(),
                    max_vertices,
                    "texture coordinates",
                    line,
                )?;
                let [u, v] = numbers(s, line, 1, [0.0; 2])?;
                self.obj.uvs.push([u, v]);
            }
            b"vn" => {
                check_limit(self.obj.normals.len(), max_vertices, "normals", line)?;
                self.obj.normals.push(numbers(s, line, 3, [0.0; 3])?);
            }
            b"f" | b"fo" => self.face(s, line)?,
            b"l" => self.obj.warnings.lines_skipped += 1,
            b"p" => self.obj.warnings.points_skipped += 1,
            b"o" => {
                self.set_key(chunks::OBJECT, |k| {
                    k.object = (!s.rest.is_empty()).then(|| lossy(s.rest));
                });
            }
            b"g" => {
                let groups = s.args.iter().map(|g| lossy(g)).collect();
                self.set_key(chunks::GROUPS, |k| k.groups = groups);
            }
            b"usemtl" => {
                self.set_key(chunks::MATERIAL, |k| {
                    k.material = (!s.rest.is_empty()).then(|| lossy(s.rest));
                });
            }
            b"s" => {
                let smoothing = match s.args.first() {
                    None => 0,
                    Some(t) if t.eq_ignore_ascii_case(b"off") => 0,
                    // Not in the specification, but some exporters write it (three.js reads it).
                    Some(t) if t.eq_ignore_ascii_case(b"on") => 1,
                    Some(t) => std::str::from_utf8(t)
                        .ok()
                        .and_then(|t| t.parse().ok())
                        .ok_or_else(|| {
                            error(
                                line,
                                ObjErrorKind::BadNumber {
                                    statement: "s".into(),
                                    token: lossy(t),
                                },
                            )
                        })?,
                };
                if self.chunk.is_some() && smoothing == chunks::INHERITED {
                    // The one value a chunk keeps for "as before the chunk": read in order.
                    return Err(chunks::unreadable(line));
                }
                self.smoothing = smoothing;
                self.obj.smoothing_declared = true;
            }
            b"mtllib" => self.mtllib(s),
            keyword => {
                self.obj.warnings.unsupported(keyword);
                return Ok(());
            }
        }
        self.obj.statements += 1;
        Ok(())
    }

    fn vertex(&mut self, xyz: [f32; 3], s: &Statement<'_>, line: usize) -> Result<(), ObjError> {
        let obj = &mut self.obj;
        let color = match s.args.len() {
            3 | 4 => None,
            6 | 7 => {
                let rest = Statement {
                    keyword: s.keyword,
                    args: Args::from_slice(&s.args[3..6]),
                    rest: s.rest,
                };
                Some(numbers(&rest, line, 3, [0.0; 3])?)
            }
            _ => {
                obj.warnings.vertices_with_odd_value_count += 1;
                None
            }
        };
        match (&mut obj.colors, color) {
            (Some(colors), color) => {
                if color.is_none() {
                    obj.warnings.vertices_without_color += 1;
                }
                colors.push(color.unwrap_or([1.0; 3]));
            }
            (None, Some(color)) => {
                // The first coloured vertex: the ones before it are white.
                let before = obj.positions.len();
                obj.warnings.vertices_without_color += before;
                let mut colors = vec![[1.0; 3]; before];
                colors.push(color);
                obj.colors = Some(colors);
            }
            (None, None) => {}
        }
        obj.positions.push(xyz);
        Ok(())
    }

    fn mtllib(&mut self, s: &Statement<'_>) {
        if s.rest.is_empty() {
            return;
        }
        // The specification separates several libraries by spaces, but exporters also write one
        // name containing spaces. Split only when every token is itself a `.mtl` name.
        let all_mtl = s.args.len() > 1
            && s.args
                .iter()
                .all(|t| t.len() > 4 && t[t.len() - 4..].eq_ignore_ascii_case(b".mtl"));
        if all_mtl {
            self.obj
                .material_libraries
                .extend(s.args.iter().map(|t| lossy(t)));
        } else {
            self.obj.material_libraries.push(lossy(s.rest));
        }
    }

    /// Changes one `field` of the key (a [`chunks`] bit naming it).
    fn set_key(&mut self, field: u8, change: impl FnOnce(&mut GroupKey)) {
        change(&mut self.key);
        self.group_current = false;
        if let Some(chunk) = self.chunk.as_deref_mut() {
            chunk.key_changed(field);
        }
    }

    fn current_group(&mut self) -> &mut FaceGroup {
        if let Some(chunk) = self.chunk.as_deref_mut() {
            return chunk.current_group(&self.key, &mut self.group_current);
        }
        let groups = &mut self.obj.groups;
        // Compared only after a statement changed the key, not for every face.
        let reusable = || {
            groups.last().is_some_and(|g| {
                g.object == self.key.object
                    && g.groups == self.key.groups
                    && g.material == self.key.material
            })
        };
        if !(self.group_current || reusable()) {
            let key = self.key.clone();
            groups.push(FaceGroup {
                object: key.object,
                groups: key.groups,
                material: key.material,
                triangles: Vec::new(),
                smoothing: Vec::new(),
            });
        }
        self.group_current = true;
        // Never empty here: a group was pushed above, or the last one was reused.
        let last = groups.len() - 1;
        &mut groups[last]
    }

    fn face(&mut self, s: &Statement<'_>, line: usize) -> Result<(), ObjError> {
        let limit = self.limits.max_polygon_corners;
        if s.args.len() > limit {
            return Err(error(
                line,
                ObjErrorKind::LimitExceeded {
                    what: "corners in one face",
                    limit,
                },
            ));
        }
        self.corners.clear();
        self.has_uv.clear();
        let (mut uvs, mut normals) = (0, 0);
        for token in s.args.iter() {
            let bad = || {
                error(
                    line,
                    ObjErrorKind::BadCorner {
                        token: lossy(token),
                    },
                )
            };
            let mut parts = token.split(|&b| b == b'/');
            let position = parts.next().filter(|p| !p.is_empty()).ok_or_else(bad)?;
            let uv = parts.next().filter(|p| !p.is_empty());
            let normal = parts.next().filter(|p| !p.is_empty());
            if parts.next().is_some() {
                return Err(bad());
            }
            let corner = match self.chunk.as_deref_mut() {
                None => Corner::new(
                    resolve(position, "position", self.obj.positions.len(), line)?,
                    uv.map(|t| resolve(t, "texture coordinate", self.obj.uvs.len(), line))
                        .transpose()?,
                    normal
                        .map(|t| resolve(t, "normal", self.obj.normals.len(), line))
                        .transpose()?,
                ),
                Some(chunk) => chunk.corner((position, uv, normal), &self.obj, line)?,
            };
            uvs += usize::from(corner.uv().is_some());
            normals += usize::from(corner.normal().is_some());
            self.corners.push(corner);
        }
        let n = self.corners.len();
        if n < 3 {
            self.obj.warnings.faces_too_few_corners += 1;
            return Ok(());
        }
        if uvs != 0 && uvs != n {
            self.obj.warnings.faces_with_partial_uvs += 1;
            self.corners.iter_mut().for_each(|c| *c = c.with_uv(None));
        }
        if normals != 0 && normals != n {
            self.obj.warnings.faces_with_partial_normals += 1;
            self.corners
                .iter_mut()
                .for_each(|c| *c = c.with_normal(None));
        }
        let added = n - 2;
        if self.triangles + added > self.limits.max_triangles {
            return Err(error(
                line,
                ObjErrorKind::LimitExceeded {
                    what: "triangles",
                    limit: self.limits.max_triangles,
                },
            ));
        }
        self.triangles += added;
        self.local.clear();
        if n > 3 && self.chunk.is_some() {
            // Its positions may lie in an earlier chunk: triangulated once all are known.
            let smoothing = self.smoothing;
            self.current_group();
            if let Some(chunk) = self.chunk.as_deref_mut() {
                chunk.defer_polygon(&self.corners, smoothing);
            }
            return Ok(());
        }
        if n == 3 {
            self.local.push([0, 1, 2]);
        } else {
            self.polygon.clear();
            let positions = &self.obj.positions;
            // Indices were resolved against `positions` above.
            self.polygon.extend(self.corners.iter().map(|c| {
                positions
                    .get(c.position as usize)
                    .copied()
                    .unwrap_or_default()
            }));
            if triangulate(&self.polygon, &mut self.local) == Triangulation::Fan {
                self.obj.warnings.polygons_fanned += 1;
            }
        }
        let corners = std::mem::take(&mut self.corners);
        let local = std::mem::take(&mut self.local);
        let smoothing = self.smoothing;
        let group = self.current_group();
        group
            .triangles
            .extend(local.iter().map(|t| t.map(|i| corners[i])));
        group
            .smoothing
            .extend(std::iter::repeat_n(smoothing, local.len()));
        self.corners = corners;
        self.local = local;
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Triangulation {
    /// Every triangle is an ear of a simple polygon.
    Ears,
    /// Some or all triangles come from the fallback.
    Fan,
}

/// Point-in-triangle tests per corner of a polygon that the ear search may spend before it falls
/// back to a fan. Enough for every convex polygon up to this many corners and for concave ones
/// well beyond it, while keeping a file's total work linear in its corner count.
const EAR_BUDGET_PER_CORNER: usize = 1024;

/// Twice the signed area of the triangle `a b c` (positive when counter-clockwise).
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// The polygon in its best-fit plane, counter-clockwise, or `None` when it has no plane.
fn project(polygon: &[[f32; 3]]) -> Option<Vec<[f64; 2]>> {
    let origin = DVec3::from(polygon.first()?.map(f64::from));
    let relative = |p: &[f32; 3]| DVec3::from(p.map(f64::from)) - origin;
    // Newell's normal: the sum of the edges' contributions to the projected areas.
    let mut normal = DVec3::ZERO;
    for (i, p) in polygon.iter().enumerate() {
        let a = relative(p);
        let b = relative(&polygon[(i + 1) % polygon.len()]);
        normal += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let length = normal.length();
    if !(length.is_finite() && length > 0.0) {
        return None;
    }
    let n = normal / length;
    // u: perpendicular to n and to the world axis least aligned with it; v = n × u, so that
    // (u, v, n) is right-handed and the polygon, wound counter-clockwise about n, stays so.
    let a = n.abs();
    let axis = if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let u = axis.cross(n);
    let u = u / u.length();
    let v = n.cross(u);
    Some(
        polygon
            .iter()
            .map(|p| {
                let r = relative(p);
                [r.dot(u), r.dot(v)]
            })
            .collect(),
    )
}

/// Appends triangles (as indices into `polygon`) covering the polygon, `polygon.len() - 2` of
/// them, each wound like the polygon. See the module documentation.
fn triangulate(polygon: &[[f32; 3]], out: &mut Vec<[usize; 3]>) -> Triangulation {
    let n = polygon.len();
    let fan = |from: usize, out: &mut Vec<[usize; 3]>| {
        out.extend((from + 1..n - 1).map(|i| [from, i, i + 1]));
    };
    if n < 3 {
        return Triangulation::Ears;
    }
    let Some(points) = project(polygon) else {
        fan(0, out);
        return Triangulation::Fan;
    };
    if points.iter().flatten().any(|c| !c.is_finite()) {
        fan(0, out);
        return Triangulation::Fan;
    }
    // A circular doubly linked list of the corners not yet clipped.
    let mut next: Vec<usize> = (1..=n).map(|i| i % n).collect();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut remaining = n;
    let mut budget = EAR_BUDGET_PER_CORNER.saturating_mul(n);
    let mut result = Triangulation::Ears;
    // Starting at corner 1 makes a convex polygon's ears exactly the fan from corner 0.
    let mut i = 1;
    let clip = |i: usize, next: &mut Vec<usize>, prev: &mut Vec<usize>, out: &mut Vec<_>| {
        let (a, c) = (prev[i], next[i]);
        out.push([a, i, c]);
        next[a] = c;
        prev[c] = a;
        c
    };
    while remaining > 3 {
        let mut found = None;
        let mut candidate = i;
        for _ in 0..remaining {
            let (a, c) = (prev[candidate], next[candidate]);
            let (pa, pb, pc) = (points[a], points[candidate], points[c]);
            if orient(pa, pb, pc) > 0.0 {
                let mut ear = true;
                let mut j = next[c];
                while j != a {
                    if budget == 0 {
                        break;
                    }
                    budget -= 1;
                    let p = points[j];
                    // Corners at a vertex of the triangle (a polygon's "bridge" to a hole
                    // visits two points twice) cannot be inside it.
                    if p != pa
                        && p != pb
                        && p != pc
                        && orient(pa, pb, p) >= 0.0
                        && orient(pb, pc, p) >= 0.0
                        && orient(pc, pa, p) >= 0.0
                    {
                        ear = false;
                        break;
                    }
                    j = next[j];
                }
                if ear && budget > 0 {
                    found = Some(candidate);
                    break;
                }
            }
            if budget == 0 {
                break;
            }
            candidate = next[candidate];
        }
        let ear = match found {
            Some(ear) => ear,
            None => {
                // Not simple, or out of budget: clip any convex corner, else fan what is left.
                result = Triangulation::Fan;
                let mut convex = None;
                let mut c = i;
                for _ in 0..remaining {
                    if orient(points[prev[c]], points[c], points[next[c]]) > 0.0 {
                        convex = Some(c);
                        break;
                    }
                    c = next[c];
                }
                match convex {
                    Some(c) if budget > 0 => c,
                    _ => {
                        let start = prev[i];
                        let mut a = i;
                        for _ in 0..remaining - 2 {
                            let b = next[a];
                            out.push([start, a, b]);
                            a = b;
                        }
                        return result;
                    }
                }
            }
        };
        i = clip(ear, &mut next, &mut prev, out);
        remaining -= 1;
    }
    out.push([prev[i], i, next[i]]);
    result
}

/// A texture reference from an MTL file: the path as written, with the options tspace uses.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Texture {
    /// The file name, exactly as written after the options (spaces kept).
    pub path: String,
    /// `-bm`: the bump multiplier (normal-map strength).
    pub bump_multiplier: Option<f32>,
    /// `-o u v w`: the texture offset (missing values are 0).
    pub offset: Option<[f32; 3]>,
    /// `-s u v w`: the texture scale (missing values are 1).
    pub scale: Option<[f32; 3]>,
}

/// One `newmtl` block. Colours are linear RGB as written; absent statements are `None`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Material {
    pub name: String,
    /// `Kd`.
    pub diffuse: Option<[f32; 3]>,
    /// `Ks`.
    pub specular: Option<[f32; 3]>,
    /// `Ns`.
    pub shininess: Option<f32>,
    /// `d`, or `1 - Tr`; the later statement wins.
    pub dissolve: Option<f32>,
    /// `Ke`.
    pub emissive: Option<[f32; 3]>,
    /// `Pr` (the PBR extension).
    pub roughness: Option<f32>,
    /// `Pm` (the PBR extension).
    pub metallic: Option<f32>,
    /// `map_Kd`.
    pub diffuse_map: Option<Texture>,
    /// `map_Ks`.
    pub specular_map: Option<Texture>,
    /// `map_d`.
    pub dissolve_map: Option<Texture>,
    /// `map_Bump`, `map_bump` or `bump`: in practice usually a tangent-space normal map.
    pub bump_map: Option<Texture>,
    /// `norm` (the PBR extension): a tangent-space normal map.
    pub normal_map: Option<Texture>,
}

/// What the MTL reader skipped.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MtlWarnings {
    pub unsupported_statements: usize,
    /// The first [`MAX_NAMED_KEYWORDS`] distinct unsupported keywords.
    pub unsupported_keywords: Vec<String>,
    /// Statements before the first `newmtl`, which belong to no material.
    pub outside_material: usize,
    /// Texture options tspace does not know, skipped (one token each).
    pub unknown_texture_options: usize,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mtl {
    pub materials: Vec<Material>,
    pub warnings: MtlWarnings,
}

impl Mtl {
    /// The last material of that name (a later `newmtl` of a name redefines it, as in most
    /// readers).
    pub fn get(&self, name: &str) -> Option<&Material> {
        self.materials.iter().rev().find(|m| m.name == name)
    }
}

/// Statements tspace reads past without a warning: common, and of no use to it.
const MTL_IGNORED: &[&[u8]] = &[
    b"Ka",
    b"Ni",
    b"Tf",
    b"illum",
    b"map_Ka",
    b"sharpness",
    b"map_Ns",
    b"map_Pr",
    b"map_Pm",
    b"map_Ke",
    b"Pc",
    b"Pcr",
    b"aniso",
    b"anisor",
    b"disp",
    b"decal",
    b"refl",
    b"map_aat",
];

/// How a texture option's values are read.
#[derive(Clone, Copy)]
enum OptionValues {
    /// One word (`-clamp on`, `-imfchan r`, `-type sphere`).
    Word,
    /// At least `min` and at most `max` numbers.
    Numbers { min: usize, max: usize },
}

fn texture_option(option: &[u8]) -> Option<OptionValues> {
    Some(match option {
        b"-blendu" | b"-blendv" | b"-cc" | b"-clamp" | b"-imfchan" | b"-type" => OptionValues::Word,
        b"-bm" | b"-boost" | b"-texres" => OptionValues::Numbers { min: 1, max: 1 },
        b"-mm" => OptionValues::Numbers { min: 2, max: 2 },
        b"-o" | b"-s" | b"-t" => OptionValues::Numbers { min: 1, max: 3 },
        _ => return None,
    })
}

/// The offset of `token` (a sub-slice of `rest`) within `rest`.
fn offset_in(rest: &[u8], token: &[u8]) -> usize {
    (token.as_ptr() as usize).saturating_sub(rest.as_ptr() as usize)
}

fn parse_texture(
    s: &Statement<'_>,
    line: usize,
    warnings: &mut MtlWarnings,
) -> Result<Texture, ObjError> {
    let mut texture = Texture::default();
    let mut k = 0;
    let bad_number = |token: &[u8]| {
        error(
            line,
            ObjErrorKind::BadNumber {
                statement: lossy(s.keyword),
                token: lossy(token),
            },
        )
    };
    while let Some(&token) = s.args.get(k) {
        if !token.starts_with(b"-") || token.len() < 2 {
            break;
        }
        let Some(kind) = texture_option(token) else {
            // Unknown: skip the option itself; its values, if any, cannot be told from a name.
            warnings.unknown_texture_options += 1;
            k += 1;
            continue;
        };
        let mut values = Vec::new();
        let mut j = k + 1;
        match kind {
            OptionValues::Word => j += 1,
            OptionValues::Numbers { min, max } => {
                // Optional values end at the first token that is not a number: the file name.
                while values.len() < max {
                    let Some(&value) = s.args.get(j) else { break };
                    match parse_f32(value) {
                        Some(v) => values.push(v),
                        None if values.len() < min => return Err(bad_number(value)),
                        None => break,
                    }
                    j += 1;
                }
                if values.len() < min {
                    return Err(error(
                        line,
                        ObjErrorKind::TooFewValues {
                            statement: lossy(token),
                            expected: min,
                            found: values.len(),
                        },
                    ));
                }
            }
        }
        let three = |default: f32| {
            let mut v = [default; 3];
            v.iter_mut().zip(&values).for_each(|(slot, &x)| *slot = x);
            v
        };
        match token {
            b"-bm" => texture.bump_multiplier = values.first().copied(),
            b"-o" => texture.offset = Some(three(0.0)),
            b"-s" => texture.scale = Some(three(1.0)),
            _ => {}
        }
        k = j;
    }
    let Some(&first) = s.args.get(k) else {
        return Err(error(
            line,
            ObjErrorKind::TooFewValues {
                statement: lossy(s.keyword),
                expected: k + 1,
                found: s.args.len(),
            },
        ));
    };
    texture.path = lossy(&s.rest[offset_in(s.rest, first).min(s.rest.len())..]);
    Ok(texture)
}

/// Reads an MTL file; the same line rules as [`parse_obj`].
pub fn parse_mtl(bytes: &[u8]) -> Result<Mtl, ObjError> {
    let mut mtl = Mtl::default();
    for (line, text) in Lines::new(bytes) {
        let Some(s) = split(&text) else { continue };
        if s.keyword == b"newmtl" {
            mtl.materials.push(Material {
                name: lossy(s.rest),
                ..Material::default()
            });
            continue;
        }
        if MTL_IGNORED.contains(&s.keyword) {
            continue;
        }
        let Some(material) = mtl.materials.last_mut() else {
            mtl.warnings.outside_material += 1;
            continue;
        };
        let color = |s: &Statement<'_>| -> Result<Option<[f32; 3]>, ObjError> {
            // `Kd spectral file` and `Kd xyz x y z` are colour spaces tspace does not convert.
            if matches!(s.args.first(), Some(&b"spectral" | &b"xyz")) {
                return Ok(None);
            }
            let [r, g, b] = numbers(s, line, 1, [f32::NAN; 3])?;
            // One value means grey.
            Ok(Some(if s.args.len() < 3 {
                [r, r, r]
            } else {
                [r, g, b]
            }))
        };
        let scalar = |s: &Statement<'_>| -> Result<f32, ObjError> {
            let [v] = numbers(s, line, 1, [0.0])?;
            Ok(v)
        };
        let warnings = &mut mtl.warnings;
        match s.keyword {
            b"Kd" => material.diffuse = color(&s)?.or(material.diffuse),
            b"Ks" => material.specular = color(&s)?.or(material.specular),
            b"Ke" => material.emissive = color(&s)?.or(material.emissive),
            b"Ns" => material.shininess = Some(scalar(&s)?),
            b"Pr" => material.roughness = Some(scalar(&s)?),
            b"Pm" => material.metallic = Some(scalar(&s)?),
            b"d" => {
                let args = match s.args.first() {
                    Some(&b"-halo") => Args::from_slice(&s.args[1..]),
                    _ => s.args.clone(),
                };
                let s = Statement {
                    keyword: s.keyword,
                    args,
                    rest: s.rest,
                };
                material.dissolve = Some(scalar(&s)?);
            }
            b"Tr" => material.dissolve = Some(1.0 - scalar(&s)?),
            b"map_Kd" => material.diffuse_map = Some(parse_texture(&s, line, warnings)?),
            b"map_Ks" => material.specular_map = Some(parse_texture(&s, line, warnings)?),
            b"map_d" => material.dissolve_map = Some(parse_texture(&s, line, warnings)?),
            b"map_Bump" | b"map_bump" | b"bump" => {
                material.bump_map = Some(parse_texture(&s, line, warnings)?)
            }
            b"norm" => material.normal_map = Some(parse_texture(&s, line, warnings)?),
            keyword => {
                warnings.unsupported_statements += 1;
                let keyword = String::from_utf8_lossy(keyword);
                if warnings.unsupported_keywords.len() < MAX_NAMED_KEYWORDS
                    && !warnings.unsupported_keywords.iter().any(|k| *k == keyword)
                {
                    warnings.unsupported_keywords.push(keyword.into_owned());
                }
            }
        }
    }
    Ok(mtl)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn parse(text: &str) -> Obj {
        parse_obj(text.as_bytes(), &Limits::default()).unwrap()
    }

    fn parse_err(text: &str) -> ObjError {
        parse_obj(text.as_bytes(), &Limits::default()).unwrap_err()
    }

    /// Every triangle's position indices, in order.
    fn position_triangles(obj: &Obj) -> Vec<[u32; 3]> {
        obj.groups
            .iter()
            .flat_map(|g| &g.triangles)
            .map(|t| t.map(|c| c.position))
            .collect()
    }

    fn corner(position: u32, uv: Option<u32>, normal: Option<u32>) -> Corner {
        Corner::new(position, uv, normal)
    }

    fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    /// Asserts that `triangles` tile the planar polygon: n - 2 of them, every one wound like the
    /// polygon (so none folds back over another), and their areas add up to the polygon's. For a
    /// fan of a concave polygon the second fails: some triangles wind the other way and their
    /// areas add up to more than the polygon's.
    fn assert_tiles(polygon: &[[f32; 3]], triangles: &[[usize; 3]]) {
        let p: Vec<[f64; 3]> = polygon.iter().map(|v| v.map(f64::from)).collect();
        let n = p.len();
        assert_eq!(triangles.len(), n - 2);
        let mut normal = [0.0; 3];
        for i in 0..n {
            let c = cross(p[i], p[(i + 1) % n]);
            normal = [normal[0] + c[0], normal[1] + c[1], normal[2] + c[2]];
        }
        let area = dot(normal, normal).sqrt() / 2.0;
        let unit = normal.map(|c| c / (2.0 * area));
        let mut sum = 0.0;
        for t in triangles {
            let c = cross(sub(p[t[1]], p[t[0]]), sub(p[t[2]], p[t[0]]));
            let signed = dot(c, unit) / 2.0;
            assert!(signed >= -1e-9 * area, "{t:?} winds backwards ({signed})");
            sum += signed.abs();
        }
        assert!((sum - area).abs() <= 1e-6 * area, "areas {sum} != {area}");
    }

    fn planar(points: &[[f32; 2]]) -> Vec<[f32; 3]> {
        points.iter().map(|&[x, y]| [x, y, 0.0]).collect()
    }

    const L_SHAPE: [[f32; 2]; 6] = [
        [0.0, 0.0],
        [2.0, 0.0],
        [2.0, 1.0],
        [1.0, 1.0],
        [1.0, 2.0],
        [0.0, 2.0],
    ];

    #[test]
    fn triangles_and_quads_keep_their_winding_and_fan_from_the_first_corner() {
        let obj = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 2 3 4\n");
        assert_eq!(position_triangles(&obj), [[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
        assert_eq!(obj.groups.len(), 1);
        assert_eq!(obj.groups[0].smoothing, [0, 0, 0]);
        assert_eq!(obj.warnings, Warnings::default());
        assert_eq!(obj.triangle_count(), 3);
    }

    #[test]
    fn convex_ngon_is_the_fan() {
        let mut text = String::new();
        for k in 0..7 {
            let a = k as f32 * std::f32::consts::TAU / 7.0;
            text += &format!("v {} {} 0.5\n", a.cos(), a.sin());
        }
        text += "f 1 2 3 4 5 6 7\n";
        let obj = parse(&text);
        let expected: Vec<[u32; 3]> = (1..6).map(|i| [0, i, i + 1]).collect();
        assert_eq!(position_triangles(&obj), expected);
    }

    #[test]
    fn concave_l_shape_gives_four_triangles_inside_the_l() {
        // Every rotation of the corner order, in both windings, tilted out of any axis plane.
        for reverse in [false, true] {
            for rotation in 0..6 {
                let mut points = L_SHAPE.to_vec();
                if reverse {
                    points.reverse();
                }
                points.rotate_left(rotation);
                let polygon: Vec<[f32; 3]> = points
                    .iter()
                    .map(|&[x, y]| [x, 0.6 * y, 0.8 * y + 0.25 * x])
                    .collect();
                let mut triangles = Vec::new();
                assert_eq!(triangulate(&polygon, &mut triangles), Triangulation::Ears);
                assert_tiles(&polygon, &triangles);
                // And no triangle's centroid lies outside the L (the square [1,2]x[1,2]).
                for t in &triangles {
                    let [x, y] = [0, 1].map(|k| t.iter().map(|&i| points[i][k]).sum::<f32>() / 3.0);
                    assert!(!(x > 1.0 && y > 1.0), "{t:?} at ({x}, {y})");
                }
            }
        }
        // Through the OBJ reader: the reflex corner (4) is first.
        let obj = parse("v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 4 5 6 1 2 3\n");
        let triangles = position_triangles(&obj);
        assert_eq!(triangles.len(), 4);
        let local: Vec<[usize; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| [3, 4, 5, 0, 1, 2].iter().position(|&p| p == i).unwrap()))
            .collect();
        let polygon = planar(&[
            L_SHAPE[3], L_SHAPE[4], L_SHAPE[5], L_SHAPE[0], L_SHAPE[1], L_SHAPE[2],
        ]);
        assert_tiles(&polygon, &local);
        assert_eq!(obj.warnings.polygons_fanned, 0);
    }

    #[test]
    fn dart_quad_is_split_along_the_inner_diagonal() {
        let dart = [[0.0, 0.0], [2.0, 1.0], [0.0, 2.0], [0.5, 1.0]];
        for rotation in 0..4 {
            let mut points = dart.to_vec();
            points.rotate_left(rotation);
            let polygon = planar(&points);
            let mut triangles = Vec::new();
            triangulate(&polygon, &mut triangles);
            assert_tiles(&polygon, &triangles);
        }
    }

    #[test]
    fn degenerate_polygons_fall_back_to_a_fan() {
        let obj = parse("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3 4\n");
        assert_eq!(position_triangles(&obj), [[0, 1, 2], [0, 2, 3]]);
        assert_eq!(obj.warnings.polygons_fanned, 1);
        let obj = parse("v nan 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
        assert_eq!(position_triangles(&obj), [[0, 1, 2], [0, 2, 3]]);
        // A bow tie: its two halves cancel in the Newell normal.
        let obj = parse("v 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 4\n");
        assert_eq!(obj.triangle_count(), 2);
        assert_eq!(obj.warnings.polygons_fanned, 1);
        // Collinear corners inside a polygon are fine.
        let mut triangles = Vec::new();
        let square = planar(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]);
        assert_eq!(triangulate(&square, &mut triangles), Triangulation::Ears);
        assert_tiles(&square, &triangles);
    }

    /// A comb: `teeth` reflex notches, so every ear test scans most of the polygon.
    fn comb(teeth: usize) -> Vec<[f32; 3]> {
        let mut points = Vec::new();
        for k in 0..teeth {
            let x = k as f32;
            points.extend([[x, 0.0], [x + 0.5, 10.0]]);
        }
        let end = teeth as f32;
        points.extend([[end, 0.0], [end, -1.0], [0.0, -1.0]]);
        planar(&points)
    }

    #[test]
    fn large_concave_polygons_tile_and_huge_ones_finish_within_their_budget() {
        let polygon = comb(400);
        let mut triangles = Vec::new();
        assert_eq!(triangulate(&polygon, &mut triangles), Triangulation::Ears);
        assert_tiles(&polygon, &triangles);
        // Past about 2000 corners the quadratic search outruns the linear budget: the polygon
        // still gets its n - 2 triangles, quickly, partly as a fan, and is counted.
        let polygon = comb(5000);
        let mut triangles = Vec::new();
        let started = std::time::Instant::now();
        assert_eq!(triangulate(&polygon, &mut triangles), Triangulation::Fan);
        assert!(started.elapsed().as_secs_f32() < 5.0);
        assert_eq!(triangles.len(), polygon.len() - 2);
    }

    #[test]
    fn self_intersecting_polygons_still_give_n_minus_2_triangles() {
        // A pentagram, drawn as one 5-corner polygon.
        let star: Vec<[f32; 2]> = (0..5)
            .map(|k| {
                let a = (k * 2 % 5) as f32 * std::f32::consts::TAU / 5.0;
                [a.cos(), a.sin()]
            })
            .collect();
        let mut triangles = Vec::new();
        triangulate(&planar(&star), &mut triangles);
        assert_eq!(triangles.len(), 3);
        assert!(triangles.iter().flatten().all(|&i| i < 5));
    }

    #[test]
    fn negative_indices_count_back_from_what_is_defined() {
        let obj = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n\
             f -3/-3/-1 -2/-2/-1 -1/-1/-1\nv 0 1 0\nf -4 -2 -1\n",
        );
        let t = &obj.groups[0].triangles;
        assert_eq!(
            t[0],
            [
                corner(0, Some(0), Some(0)),
                corner(1, Some(1), Some(0)),
                corner(2, Some(2), Some(0))
            ]
        );
        assert_eq!(
            t[1],
            [
                corner(0, None, None),
                corner(2, None, None),
                corner(3, None, None)
            ]
        );
    }

    #[test]
    fn every_corner_form() {
        let obj = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nvn 0 0 -1\n\
             f 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//2 3//1\nf 1/1/2 2/2/2 3/3/1\nf 1/ 2/ 3/\n",
        );
        let t = &obj.groups[0].triangles;
        assert_eq!(t[0][2], corner(2, None, None));
        assert_eq!(t[1][2], corner(2, Some(2), None));
        assert_eq!(t[2][1], corner(1, None, Some(1)));
        assert_eq!(t[3][0], corner(0, Some(0), Some(1)));
        assert_eq!(t[4][0], corner(0, None, None));
        assert_eq!(obj.warnings, Warnings::default());
    }

    #[test]
    fn partial_uvs_or_normals_are_dropped_for_the_face_and_counted() {
        let obj = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\n\
             f 1/1/1 2/1 3/1/1\nf 1//1 2 3\nf 1/1/1 2/1/1 3/1/1\n",
        );
        let t = &obj.groups[0].triangles;
        assert!(
            t[0].iter()
                .all(|c| c.uv() == Some(0) && c.normal().is_none())
        );
        assert!(
            t[1].iter()
                .all(|c| c.uv().is_none() && c.normal().is_none())
        );
        assert!(
            t[2].iter()
                .all(|c| c.uv() == Some(0) && c.normal() == Some(0))
        );
        assert_eq!(obj.warnings.faces_with_partial_uvs, 0);
        assert_eq!(obj.warnings.faces_with_partial_normals, 2);
        let obj = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2 3/1\n");
        assert!(obj.groups[0].triangles[0].iter().all(|c| c.uv().is_none()));
        assert_eq!(obj.warnings.faces_with_partial_uvs, 1);
    }

    #[test]
    fn objects_groups_materials_and_smoothing() {
        let obj = parse(
            "mtllib a.mtl b.mtl\nmtllib my materials.mtl\n\
             v 0 0 0\nv 1 0 0\nv 1 1 0\n\
             f 1 2 3\n\
             o Cube Object\ng left right\nusemtl red paint\ns 1\nf 1 2 3\ns off\nf 1 2 3\n\
             usemtl red paint\nf 1 2 3\n\
             usemtl blue\ng\n\
             o Other\nusemtl red paint\nf 1 2 3\n",
        );
        assert_eq!(
            obj.material_libraries,
            ["a.mtl", "b.mtl", "my materials.mtl"]
        );
        let summary: Vec<_> = obj
            .groups
            .iter()
            .map(|g| {
                (
                    g.object.as_deref(),
                    g.groups.clone(),
                    g.material.as_deref(),
                    g.smoothing.clone(),
                )
            })
            .collect();
        assert_eq!(
            summary,
            [
                (None, vec![], None, vec![0]),
                (
                    Some("Cube Object"),
                    vec!["left".to_string(), "right".to_string()],
                    Some("red paint"),
                    vec![1, 0, 0]
                ),
                (Some("Other"), vec![], Some("red paint"), vec![0]),
            ]
        );
        assert!(obj.smoothing_declared);
        assert_eq!(obj.statements, 20);
        assert!(!parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").smoothing_declared);
        let on = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\ns on\nf 1 2 3\ns 0\nf 1 2 3\n");
        assert_eq!(on.groups[0].smoothing, [1, 0]);
    }

    #[test]
    fn vertex_colors_default_to_white_when_some_are_missing() {
        let obj = parse("v 0 0 0\nv 1 0 0 1 0 0\nv 1 1 0 0 1 0 0.5\nv 0 1 0 1\n");
        assert_eq!(
            obj.colors.as_deref(),
            Some(
                &[
                    [1.0, 1.0, 1.0],
                    [1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [1.0, 1.0, 1.0]
                ][..]
            )
        );
        assert_eq!(obj.positions[3], [0.0, 1.0, 0.0]);
        assert_eq!(obj.warnings.vertices_without_color, 2);
        assert_eq!(parse("v 0 0 0\nv 1 1 1 1\n").colors, None);
        let obj = parse("v 0 0 0 1 1\nv 0 0 0 1 1 1 1 1\n");
        assert_eq!(obj.warnings.vertices_with_odd_value_count, 2);
        assert_eq!(obj.colors, None);
    }

    #[test]
    fn lines_comments_continuations_and_unknown_statements() {
        let obj = parse(
            "\u{feff}# a comment\r\nv 0 0 0 # trailing\r\nv 1 \\\r\n  0 0\r\nv 1 1 0\r\n\
             vt 0.5\nvt 0.25 0.75 0.1\n\
             f 1 2 \\\n3\nl 1 2\np 1\nvp 0.5\ncstype bezier\nvp 1\nusemtl mat#2\nf 1 2 3\n\n   \n\t\n",
        );
        assert_eq!(obj.positions, [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]);
        assert_eq!(obj.uvs, [[0.5, 0.0], [0.25, 0.75]]);
        assert_eq!(obj.triangle_count(), 2);
        assert_eq!(obj.groups[1].material.as_deref(), Some("mat#2"));
        assert_eq!(obj.warnings.lines_skipped, 1);
        assert_eq!(obj.warnings.points_skipped, 1);
        assert_eq!(obj.warnings.unsupported_statements, 3);
        assert_eq!(obj.warnings.unsupported_keywords, ["vp", "cstype"]);
        // Errors after a continuation report the first physical line.
        assert_eq!(parse_err("v 0 0 0\nv 1 \\\n x 0\n").line, 2);
        // A continuation at the end of the file just ends the line.
        assert_eq!(parse("v 1 2 3 \\").positions, [[1.0, 2.0, 3.0]]);
    }

    #[test]
    fn latin1_names_are_kept_lossily() {
        let obj = parse_obj(
            b"v 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl caf\xe9\nf 1 2 3\n",
            &Limits::default(),
        )
        .unwrap();
        assert_eq!(obj.groups[0].material.as_deref(), Some("caf\u{fffd}"));
    }

    #[test]
    fn special_float_spellings() {
        let obj = parse("v inf -Inf +INFINITY\nv nan -nan NaN\nv 1e3 -.5 2.\n");
        assert_eq!(
            obj.positions[0],
            [f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY]
        );
        assert!(obj.positions[1].iter().all(|v| v.is_nan()));
        assert_eq!(obj.positions[2], [1000.0, -0.5, 2.0]);
    }

    #[test]
    fn face_errors_name_the_line() {
        let head = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\n";
        let cases: [(&str, ObjErrorKind); 10] = [
            ("f 1 2 x", ObjErrorKind::BadCorner { token: "x".into() }),
            (
                "f 1 2 3/1/1/1",
                ObjErrorKind::BadCorner {
                    token: "3/1/1/1".into(),
                },
            ),
            ("f 1 2 /1", ObjErrorKind::BadCorner { token: "/1".into() }),
            (
                "f 1 2 1.5",
                ObjErrorKind::BadCorner {
                    token: "1.5".into(),
                },
            ),
            ("f 1 2 0", ObjErrorKind::ZeroIndex { what: "position" }),
            (
                "f 1/0 2/1 3/1",
                ObjErrorKind::ZeroIndex {
                    what: "texture coordinate",
                },
            ),
            (
                "f 1 2 4",
                ObjErrorKind::IndexOutOfRange {
                    what: "position",
                    index: 4,
                    count: 3,
                },
            ),
            (
                "f 1 2 -4",
                ObjErrorKind::IndexOutOfRange {
                    what: "position",
                    index: -4,
                    count: 3,
                },
            ),
            (
                "f 1//1 2//1 3//1",
                ObjErrorKind::IndexOutOfRange {
                    what: "normal",
                    index: 1,
                    count: 0,
                },
            ),
            (
                "f 1 2 99999999999999999999",
                ObjErrorKind::BadCorner {
                    token: "99999999999999999999".into(),
                },
            ),
        ];
        for (face, kind) in cases {
            let err = parse_err(&format!("{head}\n{face}\n"));
            assert_eq!(err, ObjError { line: 6, kind }, "{face}");
            assert!(err.to_string().starts_with("line 6: "), "{err}");
        }
        let err = parse_err(&format!("{head}f 1 2 -9223372036854775808\n"));
        assert!(
            matches!(err.kind, ObjErrorKind::IndexOutOfRange { .. }),
            "{err:?}"
        );
        // The one index whose 0-based form is `Corner`'s mark of a missing one.
        let err = parse_err(&format!("{head}f 1/4294967296 2/1 3/1\n"));
        assert!(
            matches!(
                err.kind,
                ObjErrorKind::IndexOutOfRange {
                    what: "texture coordinate",
                    index: 4294967296,
                    ..
                }
            ),
            "{err:?}"
        );
        // References must follow definitions.
        let err = parse_err("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 1 1 0\n");
        assert_eq!(err.line, 3);
    }

    #[test]
    fn value_errors_name_the_line() {
        assert_eq!(
            parse_err("v 1 2 abc\n"),
            ObjError {
                line: 1,
                kind: ObjErrorKind::BadNumber {
                    statement: "v".into(),
                    token: "abc".into()
                }
            }
        );
        assert_eq!(
            parse_err("\nvn 1 2\n"),
            ObjError {
                line: 2,
                kind: ObjErrorKind::TooFewValues {
                    statement: "vn".into(),
                    expected: 3,
                    found: 2
                }
            }
        );
        assert!(matches!(
            parse_err("vt\n").kind,
            ObjErrorKind::TooFewValues { .. }
        ));
        assert!(matches!(
            parse_err("v 1 2 3 red 0 0\n").kind,
            ObjErrorKind::BadNumber { .. }
        ));
        assert!(matches!(
            parse_err("s smooth\n").kind,
            ObjErrorKind::BadNumber { .. }
        ));
        assert!(matches!(
            parse_err("vt 1,5\n").kind,
            ObjErrorKind::BadNumber { .. }
        ));
        // Faces with fewer than three corners are skipped, not errors.
        let obj = parse("v 0 0 0\nf 1 1\nf\n");
        assert_eq!(obj.warnings.faces_too_few_corners, 2);
        assert!(obj.groups.is_empty());
    }

    #[test]
    fn limits_are_errors() {
        let limits = Limits {
            max_vertices: 3,
            max_triangles: 2,
            max_polygon_corners: 4,
        };
        let ok = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\nf 1 2 3 1\n";
        assert!(parse_obj(ok.as_bytes(), &limits).is_ok());
        for (text, what, line) in [
            ("v 0 0 0\nv 0 0 0\nv 0 0 0\nv 0 0 0\n", "vertices", 4),
            ("vt 0\nvt 0\nvt 0\nvt 0\n", "texture coordinates", 4),
            ("vn 0 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\n", "normals", 4),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3 1 2\n",
                "corners in one face",
                4,
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 3\nf 1 2 3\n",
                "triangles",
                6,
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 3 1\n",
                "triangles",
                5,
            ),
        ] {
            let err = parse_obj(text.as_bytes(), &limits).unwrap_err();
            let limit = match what {
                "corners in one face" => 4,
                "triangles" => 2,
                _ => 3,
            };
            assert_eq!(
                err,
                ObjError {
                    line,
                    kind: ObjErrorKind::LimitExceeded { what, limit }
                }
            );
        }
    }

    #[test]
    fn mtl_materials_and_texture_options() {
        let mtl = parse_mtl(
            b"# header\nKd 1 1 1\nnewmtl first\nKa 0.2 0.2 0.2\nKd 0.5 0.25 0.125\nKs 0.3\n\
              Ns 96.5\nd 0.75\nKe 1 0.5 0\nPr 0.4\nPm 1\nillum 2\nTf 1 1 1\nNi 1.45\n\
              map_Kd -s 2 2 -o 0.5 -clamp on textures/my diffuse.png\n\
              map_Bump -bm 0.8 -imfchan r normal.png\nmap_d -mm 0 1 alpha.png\n\
              map_Ks .\\spec.jpg\nnorm -o -0.25 0.5 0.75 -bm 2 n.png\nfoo 1\nbar\nfoo 2\n\
              newmtl second\nTr 0.25\nd -halo 0.5\nbump -blendu off -unknown b.png\nKd spectral x.rfl\n\
              newmtl first\nTr 0.1\nmap_bump -texres 512 -type sphere -cc off -boost 1.5 -t 0.1 0.2 c.png\n",
        )
        .unwrap();
        assert_eq!(mtl.materials.len(), 3);
        let m = &mtl.materials[0];
        assert_eq!(m.name, "first");
        assert_eq!(m.diffuse, Some([0.5, 0.25, 0.125]));
        assert_eq!(m.specular, Some([0.3; 3]));
        assert_eq!(m.shininess, Some(96.5));
        assert_eq!(m.dissolve, Some(0.75));
        assert_eq!(m.emissive, Some([1.0, 0.5, 0.0]));
        assert_eq!((m.roughness, m.metallic), (Some(0.4), Some(1.0)));
        assert_eq!(
            m.diffuse_map,
            Some(Texture {
                path: "textures/my diffuse.png".into(),
                bump_multiplier: None,
                offset: Some([0.5, 0.0, 0.0]),
                scale: Some([2.0, 2.0, 1.0]),
            })
        );
        let bump = m.bump_map.as_ref().unwrap();
        assert_eq!(
            (bump.path.as_str(), bump.bump_multiplier),
            ("normal.png", Some(0.8))
        );
        assert_eq!(m.dissolve_map.as_ref().unwrap().path, "alpha.png");
        assert_eq!(m.specular_map.as_ref().unwrap().path, ".\\spec.jpg");
        let norm = m.normal_map.as_ref().unwrap();
        assert_eq!(norm.path, "n.png");
        assert_eq!(norm.offset, Some([-0.25, 0.5, 0.75]));
        assert_eq!(norm.bump_multiplier, Some(2.0));
        let second = &mtl.materials[1];
        assert_eq!(second.dissolve, Some(0.5));
        assert_eq!(second.bump_map.as_ref().unwrap().path, "b.png");
        assert_eq!(second.diffuse, None);
        // A redefinition wins in lookups.
        let again = mtl.get("first").unwrap();
        assert!((again.dissolve.unwrap() - 0.9).abs() < 1e-6);
        assert_eq!(again.bump_map.as_ref().unwrap().path, "c.png");
        assert_eq!(mtl.get("second").unwrap().name, "second");
        assert!(mtl.get("third").is_none());
        assert_eq!(
            mtl.warnings,
            MtlWarnings {
                unsupported_statements: 3,
                unsupported_keywords: vec!["foo".into(), "bar".into()],
                outside_material: 1,
                unknown_texture_options: 1,
            }
        );
    }

    #[test]
    fn mtl_errors() {
        let err = parse_mtl(b"newmtl a\nKd 1 x 1\n").unwrap_err();
        assert_eq!(
            err,
            ObjError {
                line: 2,
                kind: ObjErrorKind::BadNumber {
                    statement: "Kd".into(),
                    token: "x".into()
                }
            }
        );
        assert_eq!(parse_mtl(b"newmtl a\nNs\n").unwrap_err().line, 2);
        assert!(matches!(
            parse_mtl(b"newmtl a\nmap_Kd -bm\n").unwrap_err().kind,
            ObjErrorKind::TooFewValues { .. }
        ));
        assert!(matches!(
            parse_mtl(b"newmtl a\nmap_Kd -bm x.png\n").unwrap_err().kind,
            ObjErrorKind::BadNumber { .. }
        ));
        assert!(matches!(
            parse_mtl(b"newmtl a\nmap_Kd -clamp on\n").unwrap_err().kind,
            ObjErrorKind::TooFewValues { .. }
        ));
        assert!(matches!(
            parse_mtl(b"newmtl a\nmap_Kd -mm 1 x.png\n")
                .unwrap_err()
                .kind,
            ObjErrorKind::BadNumber { .. }
        ));
    }

    fn fixture(path: &str) -> Option<Vec<u8>> {
        let full = format!("{}/fixtures/{path}", env!("CARGO_MANIFEST_DIR"));
        let bytes = std::fs::read(&full).ok();
        if bytes.is_none() {
            eprintln!("skipping: {full} is absent");
        }
        bytes
    }

    fn corpus(path: &str) -> Option<Vec<u8>> {
        let full = format!("{}/../shared/corpus/{path}", env!("CARGO_MANIFEST_DIR"));
        let bytes = std::fs::read(&full).ok();
        if bytes.is_none() {
            eprintln!("skipping: {full} is absent");
        }
        bytes
    }

    #[test]
    fn assimp_concave_polygon_with_a_hole_bridge_tiles_exactly() {
        let Some(bytes) = fixture("concave_polygon/concave_polygon.obj") else {
            return;
        };
        let obj = parse_obj(&bytes, &Limits::default()).unwrap();
        assert_eq!(obj.positions.len(), 64);
        assert_eq!(obj.triangle_count(), 64);
        assert_eq!(obj.warnings.polygons_fanned, 0);
        assert_eq!(obj.material_libraries, ["concave_polygon.mtl"]);
        let group = &obj.groups[0];
        assert_eq!(group.object.as_deref(), Some("concave_test.obj"));
        assert_eq!(group.groups, ["default"]);
        assert_eq!(group.material.as_deref(), Some("test"));
        assert_eq!(group.smoothing[0], 1);
        assert!(
            group
                .triangles
                .iter()
                .flatten()
                .all(|c| c.uv().is_none() && c.normal() == Some(0))
        );
        // Rebuild the face's corner list from the file to check the tiling against it.
        let text = String::from_utf8(bytes).unwrap();
        let face: Vec<u32> = text
            .lines()
            .find(|l| l.starts_with("f "))
            .unwrap()
            .split_whitespace()
            .skip(1)
            .map(|c| c.split('/').next().unwrap().parse::<u32>().unwrap() - 1)
            .collect();
        let polygon: Vec<[f32; 3]> = face.iter().map(|&i| obj.positions[i as usize]).collect();
        let mut local = Vec::new();
        triangulate(&polygon, &mut local);
        assert_tiles(&polygon, &local);
        let via_reader: Vec<[u32; 3]> = local.iter().map(|t| t.map(|i| face[i])).collect();
        assert_eq!(position_triangles(&obj), via_reader);
        // A fan of the same face would not tile it.
        let fan: Vec<[usize; 3]> = (1..face.len() - 1).map(|i| [0, i, i + 1]).collect();
        assert!(std::panic::catch_unwind(|| assert_tiles(&polygon, &fan)).is_err());

        let mtl = parse_mtl(&fixture("concave_polygon/concave_polygon.mtl").unwrap()).unwrap();
        assert_eq!(mtl.materials.len(), 1);
        assert_eq!(
            mtl.materials[0].diffuse,
            Some([0.141176, 0.184314, 0.411765])
        );
        assert_eq!(mtl.materials[0].shininess, Some(400.0));
        assert_eq!(mtl.materials[0].dissolve, Some(1.0));
        assert_eq!(mtl.warnings, MtlWarnings::default());
    }

    #[test]
    fn trimesh_negative_indices_cube() {
        let Some(bytes) = fixture("negative_indices/negative_indices.obj") else {
            return;
        };
        let obj = parse_obj(&bytes, &Limits::default()).unwrap();
        assert_eq!(
            (obj.positions.len(), obj.uvs.len(), obj.normals.len()),
            (8, 14, 6)
        );
        assert_eq!(obj.triangle_count(), 12);
        // `f -8/-13/-6 -4/-12/-6 -2/-12/-6 -6/-11/-6` with 8 v, 14 vt, 6 vn.
        let first = obj.groups[0].triangles[0];
        assert_eq!(
            first,
            [
                corner(0, Some(1), Some(0)),
                corner(4, Some(2), Some(0)),
                corner(6, Some(2), Some(0))
            ]
        );
        // A closed cube: every edge is used once in each direction.
        let mut edges: Vec<(u32, u32)> = position_triangles(&obj)
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .collect();
        edges.sort_unstable();
        for &(a, b) in &edges {
            assert!(
                edges.binary_search(&(b, a)).is_ok(),
                "edge {a}-{b} has no twin"
            );
        }
    }

    #[test]
    fn assimp_spider_with_its_materials() {
        let (Some(obj_bytes), Some(mtl_bytes)) =
            (fixture("spider/spider.obj"), fixture("spider/spider.mtl"))
        else {
            return;
        };
        let obj = parse_obj(&obj_bytes, &Limits::default()).unwrap();
        assert_eq!(
            (obj.positions.len(), obj.uvs.len(), obj.normals.len()),
            (762, 302, 747)
        );
        assert_eq!(obj.triangle_count(), 1368);
        assert_eq!(obj.groups.len(), 19);
        assert_eq!(obj.material_libraries, ["spider.mtl"]);
        assert!(
            obj.groups
                .iter()
                .flat_map(|g| &g.triangles)
                .flatten()
                .all(|c| c.uv().is_some() && c.normal().is_some())
        );
        let mtl = parse_mtl(&mtl_bytes).unwrap();
        assert_eq!(mtl.materials.len(), 5);
        for group in &obj.groups {
            let name = group.material.as_deref().unwrap();
            assert!(mtl.get(name).is_some(), "{name}");
        }
        assert_eq!(
            mtl.get("Skin").unwrap().diffuse_map.as_ref().unwrap().path,
            ".\\wal67ar_small.jpg"
        );
    }

    #[test]
    fn draco_edge_cases_from_the_corpus() {
        let dir = "obj_draco_edge_cases";
        if let Some(bytes) = corpus(&format!("{dir}/inf_nan.obj")) {
            let obj = parse_obj(&bytes, &Limits::default()).unwrap();
            assert_eq!(obj.positions[0][0], f32::INFINITY);
            assert!(obj.positions[1][0].is_nan() && obj.positions[1][2] == f32::NEG_INFINITY);
            assert_eq!(obj.triangle_count(), 1);
        }
        if let Some(bytes) = corpus(&format!("{dir}/octagon.obj")) {
            let obj = parse_obj(&bytes, &Limits::default()).unwrap();
            assert_eq!(obj.triangle_count(), 6);
            let polygon = obj.positions.clone();
            let local: Vec<[usize; 3]> = position_triangles(&obj)
                .iter()
                .map(|t| t.map(|i| i as usize))
                .collect();
            assert_tiles(&polygon, &local);
        }
        if let Some(bytes) = corpus(&format!("{dir}/deg_faces.obj")) {
            let obj = parse_obj(&bytes, &Limits::default()).unwrap();
            assert_eq!(position_triangles(&obj)[3], [0, 0, 2]);
        }
        for name in [
            "cube_att.obj",
            "cube_quads.obj",
            "triangle_with_degenerate_tex_coords.obj",
        ] {
            if let Some(bytes) = corpus(&format!("{dir}/{name}")) {
                let obj = parse_obj(&bytes, &Limits::default()).unwrap();
                assert!(obj.triangle_count() >= 1, "{name}");
                assert_eq!(obj.warnings, Warnings::default(), "{name}");
            }
        }
    }

    #[test]
    fn larger_corpus_files_read_cleanly() {
        for (path, triangles) in [
            ("obj_spot/spot_control_mesh.obj", None),
            ("obj_spot/spot_quadrangulated.obj", Some(5856)),
            ("obj_spot/spot_triangulated.obj", Some(5856)),
            ("obj_teapot_no_uv/teapot.obj", Some(6320)),
            ("obj_stanford_bunny_no_uv/stanford-bunny.obj", Some(69451)),
        ] {
            let Some(bytes) = corpus(path) else { continue };
            let obj = parse_obj(&bytes, &Limits::default()).unwrap();
            if let Some(t) = triangles {
                assert_eq!(obj.triangle_count(), t, "{path}");
            }
            assert_eq!(obj.warnings.polygons_fanned, 0, "{path}");
        }
    }

    #[test]
    fn the_tokenizers_whitespace_is_asciis() {
        for b in 0..=u8::MAX {
            assert_eq!(is_space(b), b.is_ascii_whitespace(), "{b:#04x}");
        }
    }

    /// Tokens made of the characters a number is spelled with, mostly decimals of a few digits
    /// (the fast paths' cases) and their edges: long mantissas, many fraction digits, signs
    /// alone, points alone, exponents, stray letters.
    fn number_tokens() -> impl Strategy<Value = String> {
        proptest::collection::vec(
            prop::sample::select(vec![
                "0",
                "1",
                "5",
                "9",
                "16777216",
                "16777217",
                "99999999",
                "000",
                ".",
                "-",
                "+",
                "e",
                "E",
                "e-3",
                "x",
                "00000000001",
            ]),
            0..6,
        )
        .prop_map(|parts| parts.concat())
    }

    /// What a line does to a reader that has read `before`, through [`Reader::line`] (with
    /// its one-pass reading of common statements) and through the general path alone.
    fn both_paths(before: &str, text: &str, chunk: bool) -> [String; 2] {
        let limits = Limits {
            max_vertices: 7,
            max_triangles: 2,
            ..Limits::default()
        };
        let run = |general_only: bool| {
            let state = chunk.then(Box::default);
            let mut reader = Reader::new(&limits, state);
            // The lines before through the general path in both runs, so that only `text`
            // can tell the two apart.
            for (line, before) in Lines::new(before.as_bytes()) {
                if let Some(statement) = split(&before) {
                    reader.statement(&statement, line).unwrap();
                }
            }
            let result = if general_only {
                match split(text.as_bytes()) {
                    Some(statement) => reader.statement(&statement, 7),
                    None => Ok(()),
                }
            } else {
                reader.line(text.as_bytes(), 7)
            };
            let reach = reader.chunk.as_deref().map(|c| c.reach_for_testing());
            format!("{result:?} {:?} {reach:?} {}", reader.obj, reader.triangles)
        };
        [run(false), run(true)]
    }

    /// The reader without its one-pass reading: every line cut out, joined, stripped of its
    /// comment and read by the general path.
    fn parse_generally(bytes: &[u8], limits: &Limits) -> Result<Obj, ObjError> {
        let mut reader = Reader::new(limits, None);
        for (line, text) in Lines::new(bytes) {
            if let Some(statement) = split(&text) {
                reader.statement(&statement, line)?;
            }
        }
        let Reader { mut obj, .. } = reader;
        obj.groups.retain(|g| !g.triangles.is_empty());
        Ok(obj)
    }

    #[test]
    fn a_statement_read_from_the_text_ends_at_its_line_feed() {
        let header = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
        for tail in [
            "v 0 0\n1\n",
            "v 0 0\n\n1\n",
            "vt 0.5\n1\n",
            "vn 0 0\n1\nf 1 2 3\n",
            "f 1 2\n3\n",
            "f 1/1 2/1\n3/1\n",
            "v 1 2 3\n\n\nf 1 2 9\n",
            "v 1 2 3 \r\n \r\nf 1 2 9\n",
            "f 1 2 3 \\\n4\n",
            "f 1 2 3 #\\\nf 1 2 9\n",
            "v 1 2 3\r\rf 1 2 3\n",
        ] {
            let text = format!("{header}{tail}");
            let limits = Limits::default();
            let read = parse_sequentially(text.as_bytes(), &limits);
            let general = parse_generally(text.as_bytes(), &limits);
            assert_eq!(format!("{read:?}"), format!("{general:?}"), "{text:?}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        /// Whole files, read with statements taken straight from the text where they can be,
        /// give what reading every line by the general path gives: the same `Obj`, or the same
        /// error on the same line.
        #[test]
        fn a_file_reads_as_the_general_path_reads_it(
            lines in proptest::collection::vec(
                (
                    prop::sample::select(vec!["", "", "", " ", "\t", "\r"]),
                    prop::sample::select(vec![
                        "v 0 0 0", "v 1 0 0", "v 0.5 -1.25 3", "v 1e3 2 3", "v 0 1 0 1 0 0",
                        "vt 0.5 1", "vt 1 1 0", "vt .5 2.", "vn 0 0 1", "vn 0 1 0", "f 1 2 3",
                        "f 1/1 2/2 3/1", "f 1//1 2//1 3//1", "f 1/1/1 2/1/1 3/1/1",
                        "f 1 2 3 4", "f 3 2 1", "f 1 2", "f -1 -2 -3", "f 1/1 2 3", "f 9 1 2",
                        "f 1 2 3x", "s 1", "s off", "usemtl a", "o x", "g g1", "", "#",
                        "# v 1 2 3", "l 1 2", "vp 1", "v", "f", "v\t1\t2\t3", "v 0 0",
                        "vt 0.5", "1", "0.5 1", "3/1/1",
                    ]),
                    prop::sample::select(vec![
                        "", "", "", " ", "\t", "\r", " # note", "#x", " \\", "\\", " \r",
                    ]),
                    prop::sample::select(vec!["\n", "\n", "\n", "\r\n", "\n\n"]),
                ),
                0..24,
            ),
            end_with_newline in any::<bool>(),
        ) {
            let mut text: String = lines
                .iter()
                .map(|(lead, statement, trail, end)| format!("{lead}{statement}{trail}{end}"))
                .collect();
            if !end_with_newline {
                text.truncate(text.trim_end_matches(['\r', '\n']).len());
            }
            let limits = Limits {
                max_vertices: 6,
                max_triangles: 5,
                ..Limits::default()
            };
            let read = parse_sequentially(text.as_bytes(), &limits);
            let general = parse_generally(text.as_bytes(), &limits);
            // Compared as printed, where NaN equals NaN.
            prop_assert_eq!(format!("{read:?}"), format!("{general:?}"), "{:?}", text);
        }
    }

    proptest! {
        // Many cases: the statements that tell the two paths apart (an index one past what is
        // defined, on the right count of elements) are a few percent of those drawn.
        #![proptest_config(ProptestConfig::with_cases(4096))]

        #[test]
        fn common_statements_read_as_the_general_path_reads_them(
            before in prop::sample::select(vec![
                "", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n",
                "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nv 2 2 2\nv 3 3 3\nvt 0 0\nvt 1 1\n",
                "vn 0 0 1\nvn 1 0 0\ns 3\nusemtl m\n",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 2 3\n",
                // Triangles at their limit of 2, then every kind of element at its limit of 7.
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 3 2 1\n",
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nv 2 2 2\nv 3 3 3\nv 4 4 4\n\
                 vt 0 0\nvt 1 1\nvt 0 1\nvt 1 0\nvt 2 2\nvt 3 3\nvt 4 4\n\
                 vn 0 0 1\nvn 1 0 0\nvn 0 1 0\nvn 1 1 0\nvn 0 1 1\nvn 1 0 1\nvn 1 1 1\n",
            ]),
            keyword in prop::sample::select(vec!["f", "v", "vt", "vn", " f", "fo", "f\t", "v\x0b"]),
            // Mostly three plain corners or numbers, the shape the one-pass reading takes.
            tokens in prop_oneof![
                proptest::collection::vec(
                    prop::sample::select(vec![
                        "1", "2", "3", "4", "6", "7", "1/1", "2/2", "1/3", "3/1", "4/2", "1//1",
                        "2//2", "4//1", "1//3", "1/1/1", "2/2/2", "3/1/2", "1/2/3", "0.5", "-2", "0", "1/0", "0//1",
                    ]),
                    3..=3,
                ),
                proptest::collection::vec(
                    prop::sample::select(vec![
                        "1", "2", "3", "4", "7", "0", "01", "+1", "-1", "1/1", "2/1", "1//1",
                        "3//2", "1/1/1", "2/2/1", "1/", "1//", "1/1/", "/1", "1/1/1/1", "1a",
                        "1234567890", "0.5", "-0.25", "1e3", "nan", "inf", "", " ", "#",
                        "1.2.3", "-", ".5", "3.", "-.5e1", "1.5x", "123456789.5", "+0.5",
                        "1/2/3x", "1//2/", "123456789/1", "1/0/1", "2/1//", "1//01",
                    ]),
                    0..6,
                ),
            ],
            chunk in any::<bool>(),
        ) {
            let text = format!("{keyword} {}", tokens.join(" "));
            let [fast, general] = both_paths(before, &text, chunk);
            prop_assert_eq!(fast, general, "{:?}", text);
        }
    }

    proptest! {
        /// Reading a number from bytes gives the standard parser's value, bit for bit (or, for
        /// an integer, the same refusal), for every spelling tried.
        #[test]
        fn numbers_read_from_bytes_are_the_standard_parsers_numbers(token in number_tokens()) {
            let standard = token.parse::<f32>().ok();
            if let Some(fast) = short_decimal(token.as_bytes()) {
                prop_assert_eq!(Some(fast.to_bits()), standard.map(f32::to_bits), "{}", token);
            }
            prop_assert_eq!(
                parse_f32(token.as_bytes()).map(f32::to_bits),
                standard.map(f32::to_bits),
                "{}", token
            );
            prop_assert_eq!(parse_i64(token.as_bytes()), token.parse::<i64>().ok(), "{}", token);
        }

        /// Decimals at random, up to four times the fast path's largest mantissa and two more
        /// fraction digits than it takes: within its bounds it answers, with the standard
        /// parser's rounding; beyond them it leaves the number to the standard parser.
        #[test]
        fn short_decimals_round_as_the_standard_parser_does(
            negative in any::<bool>(),
            mantissa in 0u32..1 << 26,
            fraction_digits in 0usize..=12,
        ) {
            let digits = format!("{mantissa:0>width$}", width = fraction_digits + 1);
            let (whole, fraction) = digits.split_at(digits.len() - fraction_digits);
            let token = format!("{}{whole}.{fraction}", if negative { "-" } else { "" });
            let standard = token.parse::<f32>().unwrap().to_bits();
            match short_decimal(token.as_bytes()) {
                Some(fast) => prop_assert_eq!(fast.to_bits(), standard, "{}", token),
                None => prop_assert!(mantissa > 1 << 24 || fraction_digits > 10, "{}", token),
            }
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let _ = parse_obj(&bytes, &Limits::default());
            let _ = parse_mtl(&bytes);
        }

        #[test]
        fn obj_like_text_never_panics_and_indices_stay_in_range(
            parts in proptest::collection::vec(
                prop::sample::select(vec![
                    "v ", "vt ", "vn ", "f ", "l ", "o x", "g a b", "usemtl m", "s 1", "\n", " ",
                    "\\\n", "#", "1", "-1", "2", "-3", "0", "/", "//", "0.5", "nan", "inf", "e", "-",
                    "map_Kd ", "-bm ", "-o ", "newmtl n\n", "Kd ", "d ", "Tr ", "\r\n",
                ]),
                0..80,
            )
        ) {
            let text: String = parts.concat();
            if let Ok(obj) = parse_obj(text.as_bytes(), &Limits::default()) {
                for c in obj.groups.iter().flat_map(|g| &g.triangles).flatten() {
                    prop_assert!((c.position as usize) < obj.positions.len());
                    prop_assert!(c.uv().is_none_or(|i| (i as usize) < obj.uvs.len()));
                    prop_assert!(c.normal().is_none_or(|i| (i as usize) < obj.normals.len()));
                }
                for g in &obj.groups {
                    prop_assert_eq!(g.triangles.len(), g.smoothing.len());
                }
            }
            let _ = parse_mtl(text.as_bytes());
        }

        #[test]
        fn random_polygons_triangulate_into_n_minus_2_triangles(
            points in proptest::collection::vec((-4i8..4, -4i8..4, -1i8..2), 3..12)
        ) {
            let polygon: Vec<[f32; 3]> =
                points.iter().map(|&(x, y, z)| [f32::from(x), f32::from(y), f32::from(z)]).collect();
            let mut triangles = Vec::new();
            triangulate(&polygon, &mut triangles);
            prop_assert_eq!(triangles.len(), polygon.len() - 2);
            prop_assert!(triangles.iter().flatten().all(|&i| i < polygon.len()));
            // Each corner of the polygon is used by some triangle.
            for i in 0..polygon.len() {
                prop_assert!(triangles.iter().flatten().any(|&j| j == i));
            }
        }

        #[test]
        fn star_shaped_polygons_tile(
            radii in proptest::collection::vec(0.2f32..2.0, 4..24),
            tilt in -1.0f32..1.0,
        ) {
            // Star-shaped about the origin, so simple, and concave wherever radii dip.
            let n = radii.len();
            let polygon: Vec<[f32; 3]> = radii
                .iter()
                .enumerate()
                .map(|(k, r)| {
                    let a = k as f32 * std::f32::consts::TAU / n as f32;
                    let (x, y) = (r * a.cos(), r * a.sin());
                    [x, y * tilt.cos(), y * tilt.sin()]
                })
                .collect();
            let mut triangles = Vec::new();
            prop_assert_eq!(triangulate(&polygon, &mut triangles), Triangulation::Ears);
            assert_tiles(&polygon, &triangles);
        }
    }
}
