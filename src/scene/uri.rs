//! glTF URIs: `data:` URIs decoded in memory, percent-decoding, and the decision of which
//! relative URIs a caller may resolve at all.
//!
//! tspace never opens a file or a connection because an upload names it. A `.gltf` gets its
//! buffers and images from `data:` URIs or from parts the caller supplied with it ([`PartSet`]).
//! Only the command line resolves relative URIs against the file's own folder, and only those
//! [`classify`] returns as [`UriKind::Relative`]: no scheme, no absolute or drive path, no `..`.
//!
//! Decisions:
//!
//! - **Base64** is the standard alphabet (`+`, `/`), as RFC 2397 and the glTF specification use.
//!   Padding is optional but must be consistent: either none, or exactly enough `=` to make the
//!   length a multiple of 4, and only at the end. Whitespace is **rejected**: it is not allowed in
//!   a URI (RFC 3986), a JSON string cannot hold a raw line break, and no exporter writes it, so
//!   its presence means the text is not what it claims to be. Non-zero bits left over in the last
//!   character are ignored (every encoder writes zeros; rejecting them would only refuse files
//!   that read one way only). Percent-escapes in the data are decoded before the base64.
//! - **Media type**: [`DataUri::mime`] is the `type/subtype` part, lower-cased, without
//!   parameters; `text/plain` when absent (RFC 2397's default).
//! - **Percent-decoding** turns `%XX` into the byte and leaves every other character as it is (in
//!   particular `+` is not a space: that is form encoding, not URI syntax). A `%` not followed by
//!   two hex digits is an error, as is a name that is not UTF-8 once decoded.
//! - Every decoded size is at most the input's length, and buffers are allocated only after that
//!   is known, so no size comes from the input's say-so.

use std::borrow::Cow;
use std::fmt;

/// A decoded `data:` URI.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DataUri {
    /// `type/subtype`, lower-cased (`application/octet-stream`, `image/png`).
    pub mime: String,
    pub bytes: Vec<u8>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UriError {
    /// A `%` at byte `offset` not followed by two hex digits.
    BadPercentEscape { offset: usize },
    /// The percent-decoded text is not UTF-8.
    NotUtf8,
    /// A `data:` URI without the `,` that separates the media type from the data.
    DataUriWithoutComma,
    /// A byte outside the base64 alphabet (whitespace included) at `offset` in the data.
    BadBase64Byte { offset: usize, byte: u8 },
    /// `=` padding that is incomplete, too long, or followed by data; or a length that cannot
    /// be base64 (one character left over).
    BadBase64Length { length: usize },
    /// Nothing supplied matches this URI.
    MissingPart { uri: String, looked_in: LookedIn },
    /// The file a URI names is larger than one input file may be.
    FileTooLarge { uri: String, limit: u64 },
    /// Two caller-supplied parts with one name.
    DuplicatePart { name: String },
    /// The URI may not be resolved (see [`Refusal`]).
    Refused { uri: String, reason: Refusal },
}

impl fmt::Display for UriError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UriError::BadPercentEscape { offset } => write!(
                f,
                "malformed percent-escape at byte {offset}: '%' must be followed by two hex digits"
            ),
            UriError::NotUtf8 => write!(f, "the percent-decoded URI is not valid UTF-8"),
            UriError::DataUriWithoutComma => {
                write!(
                    f,
                    "a data: URI needs a ',' between its media type and its data"
                )
            }
            UriError::BadBase64Byte { offset, byte } => write!(
                f,
                "byte {offset} of the base64 data is 0x{byte:02X}, which is not in the base64 \
                 alphabet (A-Z, a-z, 0-9, '+', '/', with '=' only as final padding)"
            ),
            UriError::BadBase64Length { length } => write!(
                f,
                "{length} characters of base64 data cannot be decoded: the padding is incomplete \
                 or misplaced, or one character is left over"
            ),
            UriError::MissingPart { uri, looked_in } => {
                write!(f, "the file refers to {uri:?}, ")?;
                match looked_in {
                    LookedIn::Nothing => write!(
                        f,
                        "which was not supplied (the scene came with no files beside it)"
                    ),
                    LookedIn::Folder => write!(f, "which is not a file in the scene's folder"),
                    LookedIn::Parts(names) if names.is_empty() => write!(
                        f,
                        "which was not supplied: the upload has no part but the scene; send \
                         multipart/form-data with a part whose file name is {uri:?}"
                    ),
                    LookedIn::Parts(names) => {
                        write!(
                            f,
                            "which was not supplied: the other parts are named {} (a part's \
                             file name, else its field name, must be the URI, percent-decoded)",
                            quoted_list(names)
                        )?;
                        match names.iter().find(|n| n.eq_ignore_ascii_case(uri)) {
                            Some(near) => write!(f, "; {near:?} differs only in case"),
                            None => Ok(()),
                        }
                    }
                }
            }
            UriError::FileTooLarge { uri, limit } => write!(
                f,
                "the file refers to {uri:?}, which is larger than the {limit} byte limit for one file"
            ),
            UriError::DuplicatePart { name } => {
                write!(f, "two supplied parts are both named {name:?}")
            }
            UriError::Refused { uri, reason } => {
                write!(f, "the URI {uri:?} is refused: {reason}")
            }
        }
    }
}

impl std::error::Error for UriError {}

/// Where a missing URI was looked for, so the message can say what was there instead.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LookedIn {
    /// Nowhere: the scene has nothing beside it (converted, or read from stdin).
    Nothing,
    /// The scene file's folder (the command line).
    Folder,
    /// An upload's parts other than the scene, by name.
    Parts(Vec<String>),
}

/// `"a", "b", "c" and 4 more`: enough names to spot a typo without flooding one line.
fn quoted_list(names: &[String]) -> String {
    const SHOWN: usize = 5;
    let mut list = names
        .iter()
        .take(SHOWN)
        .map(|n| format!("{n:?}"))
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > SHOWN {
        list.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    list
}

/// Why [`classify`] will not let a URI be resolved against a folder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Refusal {
    Empty,
    /// `http:`, `file:`, … (a `data:` URI is not refused; it is [`UriKind::Data`]).
    Scheme(String),
    /// `/x`, or `//host/x` (a network-path reference).
    Absolute,
    /// `C:\x`, `C:x`, or any other colon once decoded (Windows drive or stream syntax).
    Colon,
    Backslash,
    /// NUL or another control character, once decoded.
    ControlCharacter,
    /// A `..` segment, once decoded (`%2e%2e` too).
    ParentSegment,
    /// `?` or `#`: a query or fragment has no meaning for a file.
    QueryOrFragment,
    /// Ends in `/`, or has no segments left once `.` and empty ones are dropped.
    NotAFile,
    /// The percent-encoding is malformed or not UTF-8.
    BadEncoding(Box<UriError>),
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Empty => write!(f, "it is empty"),
            Refusal::Scheme(scheme) => write!(
                f,
                "it has the scheme {scheme:?}; only data: URIs and relative paths are read"
            ),
            Refusal::Absolute => write!(f, "it is an absolute path; only relative paths are read"),
            Refusal::Colon => write!(
                f,
                "it contains ':', which would name a drive or a stream on Windows"
            ),
            Refusal::Backslash => write!(
                f,
                "it contains '\\'; URIs separate folders with '/' (a backslash would be a Windows \
                 path)"
            ),
            Refusal::ControlCharacter => write!(f, "it contains a control character"),
            Refusal::ParentSegment => write!(
                f,
                "it contains a '..' segment, which could leave the file's folder"
            ),
            Refusal::QueryOrFragment => {
                write!(
                    f,
                    "it has a query ('?') or fragment ('#'), which files do not"
                )
            }
            Refusal::NotAFile => write!(f, "it names a folder, not a file"),
            Refusal::BadEncoding(error) => write!(f, "{error}"),
        }
    }
}

/// What a glTF URI is, for a caller about to resolve it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UriKind {
    /// A `data:` URI: decode it with [`decode_data_uri`].
    Data,
    /// A relative path, percent-decoded, with `.` and empty segments dropped and segments joined
    /// by `/`. It has no `..`, no colon, no backslash and no control character, so joining it to
    /// a folder cannot leave that folder (symbolic links inside the folder aside).
    Relative(String),
    Refused(Refusal),
}

/// Whether `uri` starts with the `data:` scheme (case-insensitive, as schemes are).
fn is_data_uri(uri: &str) -> bool {
    uri.as_bytes()
        .get(..5)
        .is_some_and(|p| p.eq_ignore_ascii_case(b"data:"))
}

/// The scheme of `uri`, if it has one: RFC 3986's `ALPHA *( ALPHA / DIGIT / "+" / "-" / "." )`
/// followed by `:` before any `/`, `?` or `#`.
fn scheme(uri: &str) -> Option<&str> {
    let colon = uri.find(':')?;
    let candidate = &uri[..colon];
    let mut bytes = candidate.bytes();
    let first = bytes.next()?;
    (first.is_ascii_alphabetic()
        && bytes.all(|b| b.is_ascii_alphanumeric() || matches!(b, b'+' | b'-' | b'.')))
    .then_some(candidate)
}

/// Classifies a glTF URI (see [`UriKind`] and [`Refusal`]). Checks run on the raw text and
/// again on the decoded text, so an escape cannot smuggle in what the raw form would be refused
/// for.
pub fn classify(uri: &str) -> UriKind {
    if is_data_uri(uri) {
        return UriKind::Data;
    }
    match relative_path(uri) {
        Ok(path) => UriKind::Relative(path),
        Err(reason) => UriKind::Refused(reason),
    }
}

fn relative_path(uri: &str) -> Result<String, Refusal> {
    if uri.is_empty() {
        return Err(Refusal::Empty);
    }
    // A one-letter scheme is a Windows drive (`C:\x`, `C:/x`): the colon reason reads better.
    if let Some(s) = scheme(uri).filter(|s| s.len() > 1) {
        return Err(Refusal::Scheme(s.to_owned()));
    }
    if uri.contains(['?', '#']) {
        return Err(Refusal::QueryOrFragment);
    }
    let decoded = percent_decode(uri).map_err(|e| Refusal::BadEncoding(Box::new(e)))?;
    // Every check on the decoded text covers the raw text too: decoding only adds characters
    // that were escaped, it never removes one that was there.
    if decoded.contains(':') {
        return Err(Refusal::Colon);
    }
    if decoded.contains('\\') {
        return Err(Refusal::Backslash);
    }
    if decoded.chars().any(char::is_control) {
        return Err(Refusal::ControlCharacter);
    }
    if decoded.starts_with('/') {
        return Err(Refusal::Absolute);
    }
    if decoded.ends_with('/') {
        return Err(Refusal::NotAFile);
    }
    let mut segments = Vec::new();
    for segment in decoded.split('/') {
        match segment {
            "" | "." => {}
            ".." => return Err(Refusal::ParentSegment),
            s => segments.push(s),
        }
    }
    if segments.is_empty() || decoded.ends_with("/.") || decoded == "." {
        return Err(Refusal::NotAFile);
    }
    Ok(segments.join("/"))
}

/// Percent-decodes `text` to bytes; see the module documentation.
fn percent_decode_bytes(text: &[u8]) -> Result<Vec<u8>, UriError> {
    // Decoding only shrinks, so the input's length bounds the output.
    let mut out = Vec::with_capacity(text.len());
    let mut i = 0;
    while let Some(&b) = text.get(i) {
        if b == b'%' {
            let hex = |j: usize| text.get(j).and_then(|&c| (c as char).to_digit(16));
            let (Some(hi), Some(lo)) = (hex(i + 1), hex(i + 2)) else {
                return Err(UriError::BadPercentEscape { offset: i });
            };
            out.push((hi * 16 + lo) as u8);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    Ok(out)
}

/// Percent-decodes a URI or a name; the result must be UTF-8.
pub fn percent_decode(text: &str) -> Result<String, UriError> {
    if !text.contains('%') {
        return Ok(text.to_owned());
    }
    String::from_utf8(percent_decode_bytes(text.as_bytes())?).map_err(|_| UriError::NotUtf8)
}

/// Decodes a `data:` URI (RFC 2397): `data:[<media type>][;base64],<data>`. `None` when `uri`
/// is not a `data:` URI at all.
pub fn decode_data_uri(uri: &str) -> Option<Result<DataUri, UriError>> {
    if !is_data_uri(uri) {
        return None;
    }
    Some(decode_data(&uri[5..]))
}

fn decode_data(rest: &str) -> Result<DataUri, UriError> {
    let (header, data) = rest.split_once(',').ok_or(UriError::DataUriWithoutComma)?;
    let mut params = header.split(';');
    let media_type = params.next().unwrap_or("").trim();
    let mut base64 = false;
    for param in params {
        // RFC 2397 puts `;base64` last; accepting it anywhere changes nothing a valid URI means.
        if param.trim().eq_ignore_ascii_case("base64") {
            base64 = true;
        }
    }
    let mime = if media_type.is_empty() {
        "text/plain".to_owned()
    } else {
        media_type.to_ascii_lowercase()
    };
    let raw = percent_decode_bytes(data.as_bytes())?;
    let bytes = if base64 { decode_base64(&raw)? } else { raw };
    Ok(DataUri { mime, bytes })
}

fn base64_value(b: u8) -> Option<u8> {
    Some(match b {
        b'A'..=b'Z' => b - b'A',
        b'a'..=b'z' => b - b'a' + 26,
        b'0'..=b'9' => b - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => return None,
    })
}

/// Standard-alphabet base64, padding optional but consistent, no whitespace (see the module
/// documentation).
pub fn decode_base64(text: &[u8]) -> Result<Vec<u8>, UriError> {
    let padding = text.iter().rev().take_while(|&&b| b == b'=').count();
    let body = &text[..text.len() - padding];
    // 3 bytes per 4 characters, rounded down: never more than the input's length.
    let mut out = Vec::with_capacity(body.len() / 4 * 3 + 2);
    let mut word: u32 = 0;
    let mut bits = 0;
    for (offset, &b) in body.iter().enumerate() {
        let value = base64_value(b).ok_or(UriError::BadBase64Byte { offset, byte: b })?;
        word = (word << 6) | u32::from(value);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((word >> bits) as u8);
            word &= (1 << bits) - 1;
        }
    }
    // Checked after the alphabet, so a stray byte is reported as itself, not as a bad length.
    let bad_length = UriError::BadBase64Length { length: text.len() };
    // With padding, the whole must be a multiple of 4 and the padding exactly what completes it.
    if padding > 0
        && (!text.len().is_multiple_of(4) || padding > 2 || padding != (4 - body.len() % 4) % 4)
    {
        return Err(bad_length);
    }
    if body.len() % 4 == 1 {
        return Err(bad_length);
    }
    Ok(out)
}

/// Buffers and images the caller supplied beside a `.gltf`, by name (an HTTP upload's multipart
/// filenames). Lookups never touch a disk.
///
/// A URI matches a part named, in this order of preference: the URI exactly as written; the URI
/// percent-decoded (`my%20file.bin` finds `my file.bin`); the decoded relative path with `.` and
/// empty segments dropped (`./a.bin` finds `a.bin`); and, since browsers and `curl -F` send only
/// a file's last path segment, that segment alone (`textures/a.png` finds `a.png`), provided the
/// part's own name has no `/`.
#[derive(Clone, Debug, Default)]
pub struct PartSet<'a> {
    parts: Vec<(String, &'a [u8])>,
}

impl<'a> PartSet<'a> {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a part; a second part with the same name is an error, since either choice would be
    /// a guess.
    pub fn insert(&mut self, name: impl Into<String>, bytes: &'a [u8]) -> Result<(), UriError> {
        let name = name.into();
        if self.parts.iter().any(|(n, _)| *n == name) {
            return Err(UriError::DuplicatePart { name });
        }
        self.parts.push((name, bytes));
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.parts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// The part names, in insertion order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.parts.iter().map(|(n, _)| n.as_str())
    }

    fn find(&self, name: &str) -> Option<&'a [u8]> {
        self.parts
            .iter()
            .find(|(n, _)| n == name)
            .map(|&(_, bytes)| bytes)
    }

    /// The part a (non-`data:`) URI names; see the type's documentation for the matching.
    pub fn get(&self, uri: &str) -> Result<&'a [u8], UriError> {
        if let Some(bytes) = self.find(uri) {
            return Ok(bytes);
        }
        let missing = || UriError::MissingPart {
            uri: uri.to_owned(),
            looked_in: LookedIn::Parts(self.parts.iter().map(|(n, _)| n.clone()).collect()),
        };
        let Ok(decoded) = percent_decode(uri) else {
            return Err(missing());
        };
        if let Some(bytes) = self.find(&decoded) {
            return Ok(bytes);
        }
        if let UriKind::Relative(path) = classify(uri) {
            if let Some(bytes) = self.find(&path) {
                return Ok(bytes);
            }
            if let Some((_, last)) = path.rsplit_once('/')
                && let Some(bytes) = self.find(last)
            {
                return Ok(bytes);
            }
        }
        Err(missing())
    }

    /// The bytes a glTF URI stands for: a `data:` URI decoded, anything else looked up with
    /// [`PartSet::get`].
    pub fn resolve(&self, uri: &str) -> Result<Cow<'a, [u8]>, UriError> {
        match decode_data_uri(uri) {
            Some(data) => Ok(Cow::Owned(data?.bytes)),
            None => self.get(uri).map(Cow::Borrowed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn data(uri: &str) -> Result<DataUri, UriError> {
        decode_data_uri(uri).expect("a data: URI")
    }

    fn refused(uri: &str) -> Refusal {
        match classify(uri) {
            UriKind::Refused(reason) => reason,
            other => panic!("{uri:?} was not refused: {other:?}"),
        }
    }

    #[test]
    fn base64_known_vectors() {
        // RFC 4648 section 10, padded and unpadded.
        let vectors: [(&str, &str); 7] = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in vectors {
            assert_eq!(decode_base64(encoded.as_bytes()).unwrap(), plain.as_bytes());
            let unpadded = encoded.trim_end_matches('=');
            assert_eq!(
                decode_base64(unpadded.as_bytes()).unwrap(),
                plain.as_bytes()
            );
        }
        assert_eq!(decode_base64(b"+/+/").unwrap(), [0xFB, 0xFF, 0xBF]);
    }

    #[test]
    fn base64_rejects_inconsistent_padding_and_stray_bytes() {
        for bad in [
            "Zg=", "Zg===", "Z===", "Zm8==", "Zm9v=", "=", "Zg==Zg==", "Z", "Zm9vY",
        ] {
            let err = decode_base64(bad.as_bytes()).unwrap_err();
            assert!(
                matches!(
                    err,
                    UriError::BadBase64Length { .. } | UriError::BadBase64Byte { .. }
                ),
                "{bad}: {err:?}"
            );
        }
        // Padding in the middle is a stray '=' byte.
        assert_eq!(
            decode_base64(b"Zg==Zm8="),
            Err(UriError::BadBase64Byte {
                offset: 2,
                byte: b'='
            })
        );
        // Whitespace is rejected, not skipped.
        assert_eq!(
            decode_base64(b"Zm9v\nYmFy"),
            Err(UriError::BadBase64Byte {
                offset: 4,
                byte: b'\n'
            })
        );
        // URL-safe alphabet is not the standard one.
        assert!(matches!(
            decode_base64(b"Zm-_"),
            Err(UriError::BadBase64Byte { offset: 2, .. })
        ));
    }

    #[test]
    fn data_uris() {
        assert_eq!(decode_data_uri("buffer.bin"), None);
        assert_eq!(decode_data_uri("dat:x"), None);
        let d = data("data:application/octet-stream;base64,AAECAw==").unwrap();
        assert_eq!(d.mime, "application/octet-stream");
        assert_eq!(d.bytes, [0, 1, 2, 3]);
        // Scheme and the base64 marker are case-insensitive; the mime is lower-cased.
        let d = data("DATA:Image/PNG;BASE64,AAEC").unwrap();
        assert_eq!(
            (d.mime.as_str(), d.bytes.as_slice()),
            ("image/png", &[0, 1, 2][..])
        );
        // Parameters are dropped from the mime; the default type is text/plain.
        let d = data("data:text/plain;charset=utf-8,a%20b%00").unwrap();
        assert_eq!(
            (d.mime.as_str(), d.bytes.as_slice()),
            ("text/plain", &b"a b\0"[..])
        );
        let d = data("data:,Hello%2C%20World!").unwrap();
        assert_eq!(
            (d.mime.as_str(), d.bytes.as_slice()),
            ("text/plain", &b"Hello, World!"[..])
        );
        // Non-UTF-8 bytes are fine in data; they are bytes.
        assert_eq!(data("data:,%FF%fe").unwrap().bytes, [0xFF, 0xFE]);
        // Escapes inside base64 data decode first.
        assert_eq!(
            data("data:;base64,Zm9v%3D").unwrap_err(),
            UriError::BadBase64Length { length: 5 }
        );
        assert_eq!(data("data:;base64,Zg%3D%3D").unwrap().bytes, b"f");
        assert_eq!(data("data:;base64,").unwrap().bytes, b"");
        assert_eq!(
            data("data:application/octet-stream;base64"),
            Err(UriError::DataUriWithoutComma)
        );
        assert_eq!(
            data("data:,%4"),
            Err(UriError::BadPercentEscape { offset: 0 })
        );
    }

    #[test]
    fn embedded_fixture_buffer_decodes_to_its_byte_length() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/fixtures/BoxTextured_embedded/BoxTextured.gltf"
        );
        let Ok(text) = std::fs::read_to_string(path) else {
            eprintln!("skipping: {path} is absent");
            return;
        };
        let doc = tspace_json::Document::parse(text.as_bytes()).unwrap();
        let buffer = doc.root().get("buffers").unwrap().index(0).unwrap();
        let uri = buffer.get("uri").unwrap().as_str().unwrap();
        let length = buffer.get("byteLength").unwrap().as_f64().unwrap() as usize;
        let d = data(uri).unwrap();
        assert_eq!(d.bytes.len(), length);
        let image = doc.root().get("images").unwrap().index(0).unwrap();
        let d = data(image.get("uri").unwrap().as_str().unwrap()).unwrap();
        assert_eq!(d.mime, "image/png");
        assert_eq!(&d.bytes[..8], b"\x89PNG\r\n\x1a\n");
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b+c").unwrap(), "a b+c");
        assert_eq!(percent_decode("caf%C3%A9").unwrap(), "café");
        assert_eq!(percent_decode("%e2%82%ac").unwrap(), "€");
        assert_eq!(percent_decode("plain é").unwrap(), "plain é");
        assert_eq!(percent_decode("%FF"), Err(UriError::NotUtf8));
        assert_eq!(percent_decode("%C3"), Err(UriError::NotUtf8));
        for (bad, offset) in [
            ("%", 0),
            ("a%2", 1),
            ("%zz", 0),
            ("ab%g0", 2),
            ("%%41", 0),
            ("%é1", 0),
        ] {
            assert_eq!(
                percent_decode(bad),
                Err(UriError::BadPercentEscape { offset }),
                "{bad}"
            );
        }
    }

    #[test]
    fn relative_paths_are_decoded_and_normalized() {
        let ok = |uri: &str, path: &str| {
            assert_eq!(classify(uri), UriKind::Relative(path.into()), "{uri}")
        };
        ok("buffer.bin", "buffer.bin");
        ok("my%20model.bin", "my model.bin");
        ok("./textures/a.png", "textures/a.png");
        ok("textures//./a.png", "textures/a.png");
        ok("t%C3%A9xture.png", "téxture.png");
        ok("a..b/c...d", "a..b/c...d");
        ok(".hidden", ".hidden");
        assert_eq!(classify("data:,x"), UriKind::Data);
        assert_eq!(
            classify("Data:application/octet-stream;base64,"),
            UriKind::Data
        );
    }

    #[test]
    fn escaping_uris_are_refused_with_a_reason() {
        assert_eq!(refused(""), Refusal::Empty);
        assert_eq!(
            refused("http://example.com/a.bin"),
            Refusal::Scheme("http".into())
        );
        assert_eq!(
            refused("file:///etc/passwd"),
            Refusal::Scheme("file".into())
        );
        assert_eq!(refused("HTTPS://x/y"), Refusal::Scheme("HTTPS".into()));
        assert_eq!(
            refused("s3+x.y-z:bucket"),
            Refusal::Scheme("s3+x.y-z".into())
        );
        assert_eq!(refused("/etc/passwd"), Refusal::Absolute);
        assert_eq!(refused("//server/share/a.bin"), Refusal::Absolute);
        assert_eq!(refused("%2Fetc%2Fpasswd"), Refusal::Absolute);
        assert_eq!(refused("C:\\x.bin"), Refusal::Colon);
        assert_eq!(refused("C:/x.bin"), Refusal::Colon);
        assert_eq!(refused("c:x.bin"), Refusal::Colon);
        // RFC 3986 reads this as the scheme `a.bin`; refused either way.
        assert_eq!(refused("a.bin:stream"), Refusal::Scheme("a.bin".into()));
        assert_eq!(refused("dir/a.bin:stream"), Refusal::Colon);
        assert_eq!(refused("dir%3Aa.bin"), Refusal::Colon);
        assert_eq!(refused("\\\\server\\share\\a.bin"), Refusal::Backslash);
        assert_eq!(refused("a\\..\\b"), Refusal::Backslash);
        assert_eq!(refused("a%5Cb"), Refusal::Backslash);
        assert_eq!(refused("a%00.bin"), Refusal::ControlCharacter);
        assert_eq!(refused("a\0.bin"), Refusal::ControlCharacter);
        assert_eq!(refused("a%0A.bin"), Refusal::ControlCharacter);
        assert_eq!(refused(".."), Refusal::ParentSegment);
        assert_eq!(refused("../a.bin"), Refusal::ParentSegment);
        assert_eq!(refused("a/../../b"), Refusal::ParentSegment);
        assert_eq!(refused("a/.."), Refusal::ParentSegment);
        assert_eq!(refused("%2e%2e/a.bin"), Refusal::ParentSegment);
        assert_eq!(refused("%2E%2E%2Fa.bin"), Refusal::ParentSegment);
        assert_eq!(refused(".%2e/a.bin"), Refusal::ParentSegment);
        assert_eq!(refused("a.bin?x=1"), Refusal::QueryOrFragment);
        assert_eq!(refused("a.bin#frag"), Refusal::QueryOrFragment);
        assert_eq!(refused("textures/"), Refusal::NotAFile);
        assert_eq!(refused("."), Refusal::NotAFile);
        assert_eq!(refused("a/."), Refusal::NotAFile);
        assert_eq!(refused("./"), Refusal::NotAFile);
        assert!(matches!(refused("a%zz"), Refusal::BadEncoding(_)));
        assert!(matches!(refused("a%FF"), Refusal::BadEncoding(_)));
        // Every refusal has a message.
        let message = UriError::Refused {
            uri: "../a.bin".into(),
            reason: refused("../a.bin"),
        }
        .to_string();
        assert!(
            message.contains("\"../a.bin\"") && message.contains(".."),
            "{message}"
        );
    }

    #[test]
    fn parts_match_raw_decoded_normalized_and_last_segment() {
        let mut parts = PartSet::new();
        parts.insert("my file.bin", b"decoded").unwrap();
        parts.insert("my%20raw.bin", b"raw").unwrap();
        parts.insert("tex/a.png", b"nested").unwrap();
        parts.insert("b.png", b"basename").unwrap();
        assert_eq!(parts.len(), 4);
        assert_eq!(parts.get("my%20file.bin").unwrap(), b"decoded");
        assert_eq!(parts.get("my file.bin").unwrap(), b"decoded");
        assert_eq!(parts.get("my%20raw.bin").unwrap(), b"raw");
        assert_eq!(parts.get("./tex/a.png").unwrap(), b"nested");
        assert_eq!(parts.get("tex/a.png").unwrap(), b"nested");
        assert_eq!(parts.get("images/b.png").unwrap(), b"basename");
        // The last segment only matches part names without a folder.
        assert!(parts.get("other/a.png").is_err());
        // A refused URI can still match a part by its exact name, since nothing is opened.
        let mut odd = PartSet::new();
        odd.insert("../x.bin", b"x").unwrap();
        assert_eq!(odd.get("../x.bin").unwrap(), b"x");
        let err = parts.get("missing%20one.bin").unwrap_err();
        assert_eq!(
            err,
            UriError::MissingPart {
                uri: "missing%20one.bin".into(),
                looked_in: LookedIn::Parts(parts.names().map(str::to_owned).collect()),
            }
        );
        assert!(err.to_string().contains("\"missing%20one.bin\""), "{err}");
        assert!(parts.get("bad%zz").is_err());
        assert_eq!(
            parts.insert("b.png", b"again"),
            Err(UriError::DuplicatePart {
                name: "b.png".into()
            })
        );
        assert_eq!(&*parts.resolve("data:,hi").unwrap(), b"hi");
        assert_eq!(&*parts.resolve("b.png").unwrap(), b"basename");
        assert!(parts.resolve("data:;base64,%").is_err());
        assert!(PartSet::new().is_empty());
    }

    fn encode(bytes: &[u8], pad: bool) -> String {
        const ALPHABET: &[u8; 64] =
            b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for chunk in bytes.chunks(3) {
            let word = chunk
                .iter()
                .enumerate()
                .fold(0u32, |w, (i, &b)| w | u32::from(b) << (16 - 8 * i));
            for i in 0..=chunk.len() {
                out.push(ALPHABET[(word >> (18 - 6 * i) & 63) as usize] as char);
            }
            if pad {
                out.extend(std::iter::repeat_n('=', 3 - chunk.len()));
            }
        }
        out
    }

    proptest! {
        #[test]
        fn base64_round_trips(bytes in proptest::collection::vec(any::<u8>(), 0..64), pad: bool) {
            let text = encode(&bytes, pad);
            prop_assert_eq!(decode_base64(text.as_bytes()).unwrap(), bytes);
        }

        #[test]
        fn arbitrary_text_never_panics(text in "\\PC{0,24}|[%./\\\\:a-z0-9=]{0,24}") {
            let _ = percent_decode(&text);
            if let UriKind::Relative(path) = classify(&text) {
                prop_assert!(!path.split('/').any(|s| s == ".." || s.is_empty()));
                prop_assert!(!path.contains(['\\', ':', '\0']) && !path.starts_with('/'));
            }
            let uri = format!("data:{text}");
            if let Some(Ok(d)) = decode_data_uri(&uri) {
                prop_assert!(d.bytes.len() <= uri.len());
            }
            let _ = decode_base64(text.as_bytes());
        }
    }

    #[test]
    fn a_missing_file_says_where_it_was_looked_for_and_what_was_there() {
        let missing = |looked_in| {
            UriError::MissingPart {
                uri: "Avocado.bin".into(),
                looked_in,
            }
            .to_string()
        };
        assert!(missing(LookedIn::Folder).ends_with("which is not a file in the scene's folder"));
        assert!(missing(LookedIn::Nothing).contains("no files beside it"));
        assert!(missing(LookedIn::Parts(vec![])).contains("has no part but the scene"));
        let names: Vec<String> = (0..7).map(|i| format!("part{i}.bin")).collect();
        let many = missing(LookedIn::Parts(names));
        assert!(many.contains("\"part4.bin\" and 2 more"), "{many}");
        assert!(!many.contains("part5"), "{many}");
        let near = missing(LookedIn::Parts(vec!["AVOCADO.BIN".into()]));
        assert!(
            near.ends_with("; \"AVOCADO.BIN\" differs only in case"),
            "{near}"
        );
    }
}
