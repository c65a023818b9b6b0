//! The GLB container (glTF 2.0 binary): a 12-byte header, then chunks of `length, type, data`.
//!
//! The first chunk must be JSON and the second, if any, the BIN buffer. Chunks of other types may
//! follow them; a reader must ignore them, and tspace keeps them, in order, so that writing the
//! file back loses nothing an extension put there.
//!
//! Parsing is strict about what the specification makes structural: the header's total length
//! must equal the bytes given, every chunk must lie inside them, and every chunk length must be a
//! multiple of 4 (chunks start and end on 4-byte boundaries). A reader that guessed at a file
//! breaking these would be guessing where the JSON ends. Nothing is copied: the parsed [`Glb`]
//! borrows the input.

use std::fmt;

/// `glTF` in ASCII, read as a little-endian u32.
pub const MAGIC: u32 = 0x4654_6C67;
pub const VERSION: u32 = 2;
/// `JSON` as a little-endian u32.
pub const CHUNK_JSON: u32 = 0x4E4F_534A;
/// `BIN\0` as a little-endian u32.
pub const CHUNK_BIN: u32 = 0x004E_4942;

const HEADER_LEN: usize = 12;
pub const CHUNK_HEADER_LEN: usize = 8;

/// A parsed GLB, borrowing the input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Glb<'a> {
    /// The JSON chunk's data, padding included (trailing spaces, which JSON ignores).
    pub json: &'a [u8],
    /// The BIN chunk's data, padding included: the buffer is its first `buffers[0].byteLength`
    /// bytes, and up to 3 zero bytes may follow.
    pub bin: Option<&'a [u8]>,
    /// Chunks of other types, in file order.
    pub other_chunks: Vec<Chunk<'a>>,
}

/// A chunk of a type tspace does not interpret.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chunk<'a> {
    pub kind: u32,
    pub data: &'a [u8],
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GlbError {
    /// Fewer than 12 bytes: not even a header.
    TooShort {
        len: usize,
    },
    BadMagic {
        found: [u8; 4],
    },
    UnsupportedVersion {
        version: u32,
    },
    /// The header's total length disagrees with the number of bytes given.
    LengthMismatch {
        header: u32,
        actual: usize,
    },
    /// A chunk header does not fit in what is left of the file.
    TruncatedChunkHeader {
        index: usize,
        offset: usize,
    },
    /// A chunk's data runs past the end of the file.
    ChunkOverrun {
        index: usize,
        offset: usize,
        length: u32,
        available: usize,
    },
    /// A chunk length that is not a multiple of 4.
    UnalignedChunk {
        index: usize,
        length: u32,
    },
    /// The file has no chunks, or its first chunk is not JSON.
    MissingJson {
        first_kind: Option<u32>,
    },
    /// A JSON chunk after the first, or a BIN chunk anywhere but second.
    MisplacedChunk {
        index: usize,
        kind: u32,
    },
    /// The output would not fit the format's 32-bit lengths.
    TooLarge {
        bytes: u64,
    },
}

/// A chunk type for messages: its four bytes as text when printable, else hex.
struct Kind(u32);

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let bytes = self.0.to_le_bytes();
        if bytes.iter().all(|&b| b == 0 || b.is_ascii_graphic()) {
            let text: String = bytes
                .iter()
                .filter(|&&b| b != 0)
                .map(|&b| b as char)
                .collect();
            write!(f, "{text:?}")
        } else {
            write!(f, "0x{:08X}", self.0)
        }
    }
}

impl fmt::Display for GlbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GlbError::TooShort { len } => {
                write!(f, "a GLB file needs a 12-byte header; got {len} bytes")
            }
            GlbError::BadMagic { found } => write!(
                f,
                "not a GLB file: it starts with {found:02X?} instead of \"glTF\""
            ),
            GlbError::UnsupportedVersion { version } => write!(
                f,
                "GLB version {version} is not supported (only glTF 2.0, version 2)"
            ),
            GlbError::LengthMismatch { header, actual } => write!(
                f,
                "the GLB header says the file is {header} bytes long, but it is {actual}"
            ),
            GlbError::TruncatedChunkHeader { index, offset } => write!(
                f,
                "GLB chunk {index} at byte {offset}: the file ends inside its 8-byte header"
            ),
            GlbError::ChunkOverrun {
                index,
                offset,
                length,
                available,
            } => write!(
                f,
                "GLB chunk {index} at byte {offset} claims {length} bytes, but only {available} remain"
            ),
            GlbError::UnalignedChunk { index, length } => write!(
                f,
                "GLB chunk {index} is {length} bytes long, which is not a multiple of 4"
            ),
            GlbError::MissingJson { first_kind: None } => {
                write!(f, "the GLB file has no chunks; it needs a JSON chunk first")
            }
            GlbError::MissingJson {
                first_kind: Some(kind),
            } => write!(
                f,
                "the first GLB chunk must be JSON, but it is of type {}",
                Kind(*kind)
            ),
            GlbError::MisplacedChunk { index, kind } => write!(
                f,
                "GLB chunk {index} is of type {}, which may only appear {}",
                Kind(*kind),
                if *kind == CHUNK_JSON {
                    "first"
                } else {
                    "second"
                }
            ),
            GlbError::TooLarge { bytes } => write!(
                f,
                "a GLB file of {bytes} bytes exceeds the format's 4 GiB limit"
            ),
        }
    }
}

impl std::error::Error for GlbError {}

fn u32_at(bytes: &[u8], offset: usize) -> Option<u32> {
    let end = offset.checked_add(4)?;
    let word: [u8; 4] = bytes.get(offset..end)?.try_into().ok()?;
    Some(u32::from_le_bytes(word))
}

/// Whether `bytes` starts like a GLB file (for choosing between GLB and JSON input).
pub fn is_glb(bytes: &[u8]) -> bool {
    u32_at(bytes, 0) == Some(MAGIC)
}

/// Splits a GLB file into its chunks (see the module documentation for what is checked).
pub fn parse(bytes: &[u8]) -> Result<Glb<'_>, GlbError> {
    let (Some(magic), Some(version), Some(length)) =
        (u32_at(bytes, 0), u32_at(bytes, 4), u32_at(bytes, 8))
    else {
        return Err(GlbError::TooShort { len: bytes.len() });
    };
    if magic != MAGIC {
        let mut found = [0; 4];
        found.copy_from_slice(bytes.get(..4).unwrap_or(&[0; 4]));
        return Err(GlbError::BadMagic { found });
    }
    if version != VERSION {
        return Err(GlbError::UnsupportedVersion { version });
    }
    if usize::try_from(length).ok() != Some(bytes.len()) {
        return Err(GlbError::LengthMismatch {
            header: length,
            actual: bytes.len(),
        });
    }

    let mut json = None;
    let mut bin = None;
    let mut other_chunks = Vec::new();
    let mut offset = HEADER_LEN;
    let mut index = 0;
    while offset < bytes.len() {
        let (Some(length), Some(kind)) = (u32_at(bytes, offset), u32_at(bytes, offset + 4)) else {
            return Err(GlbError::TruncatedChunkHeader { index, offset });
        };
        let start = offset + CHUNK_HEADER_LEN;
        let available = bytes.len() - start;
        let data = usize::try_from(length)
            .ok()
            .and_then(|len| bytes.get(start..start.checked_add(len)?))
            .ok_or(GlbError::ChunkOverrun {
                index,
                offset,
                length,
                available,
            })?;
        if length % 4 != 0 {
            return Err(GlbError::UnalignedChunk { index, length });
        }
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(data),
            (0, other) => {
                return Err(GlbError::MissingJson {
                    first_kind: Some(other),
                });
            }
            (1, CHUNK_BIN) => bin = Some(data),
            (_, CHUNK_JSON | CHUNK_BIN) => return Err(GlbError::MisplacedChunk { index, kind }),
            (_, kind) => other_chunks.push(Chunk { kind, data }),
        }
        offset = start + data.len();
        index += 1;
    }
    let json = json.ok_or(GlbError::MissingJson { first_kind: None })?;
    Ok(Glb {
        json,
        bin,
        other_chunks,
    })
}

/// Assembles a GLB file: the JSON chunk padded with spaces, the BIN chunk (if any) padded with
/// zeros, then `other_chunks` in order, each padded with zeros to a multiple of 4 bytes.
pub fn write(
    json: &[u8],
    bin: Option<&[u8]>,
    other_chunks: &[Chunk<'_>],
) -> Result<Vec<u8>, GlbError> {
    write_with(
        json.len(),
        |out| out.extend_from_slice(json),
        bin.as_ref().map(std::slice::from_ref),
        other_chunks,
    )
}

/// [`write()`] of a JSON chunk and a BIN chunk, made in the BIN chunk's own memory: the chunk
/// is moved up within it and the header and JSON written before it, rather than both copied
/// into a second buffer as large. For a converted OBJ of a million triangles that is 28 MB
/// less to allocate, touch and hold at once. The move is within the allocation when it has
/// room for the rest of the file (see [`GLB_HEADROOM`]), else the allocation grows first.
pub fn write_around_bin(json: &[u8], mut bin: Vec<u8>) -> Result<Vec<u8>, GlbError> {
    let framing = Framing::of(&[(CHUNK_JSON, json.len()), (CHUNK_BIN, bin.len())])?;
    let (Some(json_chunk), Some(bin_chunk)) = (framing.chunks.first(), framing.chunks.get(1))
    else {
        // Unreachable: the framing has a chunk per length given.
        return write(json, Some(&bin), &[]);
    };
    let json_start = HEADER_LEN + CHUNK_HEADER_LEN;
    let json_end = json_start + json.len() + json_chunk.padding;
    let bin_start = json_end + CHUNK_HEADER_LEN;
    let bin_len = bin.len();
    bin.resize(framing.total, bin_chunk.pad_byte);
    bin.copy_within(..bin_len, bin_start);
    bin[bin_start + bin_len..].fill(bin_chunk.pad_byte);
    bin[..HEADER_LEN].copy_from_slice(&framing.header);
    bin[HEADER_LEN..json_start].copy_from_slice(&json_chunk.header);
    bin[json_start..json_start + json.len()].copy_from_slice(json);
    bin[json_start + json.len()..json_end].fill(json_chunk.pad_byte);
    bin[json_end..bin_start].copy_from_slice(&bin_chunk.header);
    Ok(bin)
}

/// Room to leave after a BIN chunk that [`write_around_bin`] will frame: the GLB's header, the
/// two chunk headers and a JSON document of up to 64 KiB, padding included.
pub const GLB_HEADROOM: usize = HEADER_LEN + 2 * CHUNK_HEADER_LEN + (64 << 10) + 3;

/// [`write()`], with the BIN chunk given as the pieces it is made of, in order: each byte is
/// copied once, into the file, however the chunk was laid out.
pub fn write_pieces(
    json: &[u8],
    bin: Option<&[&[u8]]>,
    other_chunks: &[Chunk<'_>],
) -> Result<Vec<u8>, GlbError> {
    write_with(
        json.len(),
        |out| out.extend_from_slice(json),
        bin,
        other_chunks,
    )
}

/// [`write_pieces`], with the JSON written into the file by `json` (which appends about
/// `json_len` bytes) rather than copied from a text of its own: an edited document goes
/// straight into its chunk. The lengths in the headers are those of what was written.
pub fn write_with(
    json_len: usize,
    json: impl FnOnce(&mut Vec<u8>),
    bin: Option<&[&[u8]]>,
    other_chunks: &[Chunk<'_>],
) -> Result<Vec<u8>, GlbError> {
    let after_json: Vec<(u32, &[&[u8]])> = bin
        .map(|b| (CHUNK_BIN, b))
        .into_iter()
        .chain(
            other_chunks
                .iter()
                .map(|c| (c.kind, std::slice::from_ref(&c.data))),
        )
        .collect();
    let lengths = |json_len: usize| -> Vec<(u32, usize)> {
        std::iter::once((CHUNK_JSON, json_len))
            .chain(
                after_json
                    .iter()
                    .map(|(kind, pieces)| (*kind, pieces.iter().map(|p| p.len()).sum())),
            )
            .collect()
    };
    let mut framing = Framing::of(&lengths(json_len))?;
    let mut out = Vec::with_capacity(framing.total);
    out.extend_from_slice(&framing.header);
    out.extend_from_slice(&[0; CHUNK_HEADER_LEN]);
    let json_start = out.len();
    json(&mut out);
    let written = out.len() - json_start;
    if written != json_len {
        framing = Framing::of(&lengths(written))?;
        out[..HEADER_LEN].copy_from_slice(&framing.header);
    }
    let mut chunks = framing.chunks.iter();
    if let Some(chunk) = chunks.next() {
        out[HEADER_LEN..json_start].copy_from_slice(&chunk.header);
        out.resize(out.len() + chunk.padding, chunk.pad_byte);
    }
    for ((_, pieces), chunk) in after_json.iter().zip(chunks) {
        out.extend_from_slice(&chunk.header);
        for piece in *pieces {
            out.extend_from_slice(piece);
        }
        out.resize(out.len() + chunk.padding, chunk.pad_byte);
    }
    Ok(out)
}

/// The bytes a GLB puts around its chunks: the file header, and per chunk its header and the
/// padding after it (spaces after JSON, zeros after the others).
pub struct Framing {
    pub header: [u8; HEADER_LEN],
    pub chunks: Vec<ChunkFraming>,
    /// The file's length.
    pub total: usize,
}

pub struct ChunkFraming {
    pub header: [u8; CHUNK_HEADER_LEN],
    pub padding: usize,
    pub pad_byte: u8,
}

impl Framing {
    /// The framing of chunks of these kinds and lengths, in order; fails when the file would
    /// pass the format's 4 GiB.
    pub fn of(chunks: &[(u32, usize)]) -> Result<Framing, GlbError> {
        // Lengths come from slices that exist, so u64 cannot overflow; the format's u32 can.
        let total: u64 = HEADER_LEN as u64
            + chunks
                .iter()
                .map(|&(_, len)| CHUNK_HEADER_LEN as u64 + padded_len(len as u64))
                .sum::<u64>();
        let too_large = GlbError::TooLarge { bytes: total };
        let total_u32 = u32::try_from(total).map_err(|_| too_large.clone())?;
        let total = usize::try_from(total).map_err(|_| too_large)?;
        let mut header = [0u8; HEADER_LEN];
        header[0..4].copy_from_slice(&MAGIC.to_le_bytes());
        header[4..8].copy_from_slice(&VERSION.to_le_bytes());
        header[8..12].copy_from_slice(&total_u32.to_le_bytes());
        let chunks = chunks
            .iter()
            .map(|&(kind, len)| {
                // Each padded length is at most the total, which fits in u32.
                let padded = padded_len(len as u64) as u32;
                let mut header = [0u8; CHUNK_HEADER_LEN];
                header[0..4].copy_from_slice(&padded.to_le_bytes());
                header[4..8].copy_from_slice(&kind.to_le_bytes());
                ChunkFraming {
                    header,
                    padding: padded as usize - len,
                    pad_byte: if kind == CHUNK_JSON { b' ' } else { 0 },
                }
            })
            .collect();
        Ok(Framing {
            header,
            chunks,
            total,
        })
    }
}

fn padded_len(len: u64) -> u64 {
    len.div_ceil(4) * 4
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(name: &str) -> Vec<u8> {
        let path = format!("{}/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    #[test]
    fn a_glb_made_around_its_bin_chunk_is_the_glb_written_from_copies() {
        for json_len in 0..9 {
            for bin_len in [0, 1, 4, 5, 7, 8, 100] {
                let json: Vec<u8> = (0..json_len).map(|i| b'a' + i as u8).collect();
                let bin: Vec<u8> = (0..bin_len).map(|i| (i * 7 + 1) as u8).collect();
                let expected = write(&json, Some(&bin), &[]).unwrap();
                // With room already there, and with none (the allocation grows).
                let mut roomy = Vec::with_capacity(bin_len + GLB_HEADROOM);
                roomy.extend_from_slice(&bin);
                let made = write_around_bin(&json, roomy).unwrap();
                assert_eq!(made, expected, "{json_len} {bin_len}");
                assert_eq!(write_around_bin(&json, bin.clone()).unwrap(), expected);
                assert!(parse(&made).is_ok());
            }
        }
    }

    /// A GLB built by hand, so each test can break exactly one thing.
    fn build(chunks: &[(u32, u32, &[u8])]) -> Vec<u8> {
        let mut body = Vec::new();
        for &(len, kind, data) in chunks {
            body.extend_from_slice(&len.to_le_bytes());
            body.extend_from_slice(&kind.to_le_bytes());
            body.extend_from_slice(data);
        }
        let mut out = b"glTF".to_vec();
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(12 + body.len() as u32).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }

    const J: &[u8] = b"{}  ";

    #[test]
    fn fixture_round_trips() {
        let bytes = fixture("Box/Box.glb");
        assert!(is_glb(&bytes));
        let glb = parse(&bytes).unwrap();
        assert!(glb.json.starts_with(b"{\"asset\""));
        assert_eq!(glb.bin.map(<[u8]>::len), Some(648));
        assert!(glb.other_chunks.is_empty());
        assert_eq!(write(glb.json, glb.bin, &glb.other_chunks).unwrap(), bytes);
        tspace_json::Document::parse(glb.json).unwrap();
    }

    #[test]
    fn edited_json_round_trips_through_glb() {
        use tspace_json::Document;
        let bytes = fixture("Box/Box.glb");
        let glb = parse(&bytes).unwrap();
        let doc = Document::parse(glb.json).unwrap();
        let mut editor = doc.editor();
        let asset = doc.root().get("asset").unwrap();
        editor.set_member(asset, "generator", "\"tspace\"").unwrap();
        let json = editor.render().unwrap();
        let out = write(json.as_bytes(), glb.bin, &glb.other_chunks).unwrap();
        let again = parse(&out).unwrap();
        assert_eq!(again.bin, glb.bin);
        let doc = Document::parse(again.json).unwrap();
        let generator = doc.root().get("asset").and_then(|a| a.get("generator"));
        assert_eq!(generator.and_then(|g| g.as_str()), Some("tspace"));
        assert!(again.json.ends_with(b"}") || again.json.ends_with(b" "));
    }

    #[test]
    fn corpus_round_trips() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/corpus");
        let files = [
            "gltf_SheenCloth_glb/SheenCloth.glb",
            "gltf_draco_Box/Box_Draco.glb",
            "gltf_assimp_invalid_inputs/BoxBadNormals.glb",
            "gltf_assimp_invalid_inputs/BoxWithInfinites.glb",
        ];
        for name in files {
            let Ok(bytes) = std::fs::read(format!("{dir}/{name}")) else {
                eprintln!("skipping {name}: the shared corpus is not present");
                continue;
            };
            let glb = parse(&bytes).unwrap();
            assert_eq!(
                write(glb.json, glb.bin, &glb.other_chunks).unwrap(),
                bytes,
                "{name}"
            );
        }
    }

    #[test]
    fn unknown_chunks_are_kept_in_order() {
        let bytes = build(&[
            (4, CHUNK_JSON, J),
            (4, CHUNK_BIN, &[1, 2, 3, 4]),
            (4, 0x5458_4558, b"abcd"),
            (0, 0x0000_0001, b""),
        ]);
        let glb = parse(&bytes).unwrap();
        assert_eq!(glb.bin, Some(&[1u8, 2, 3, 4][..]));
        assert_eq!(
            glb.other_chunks,
            [
                Chunk {
                    kind: 0x5458_4558,
                    data: b"abcd"
                },
                Chunk { kind: 1, data: b"" }
            ]
        );
        assert_eq!(write(glb.json, glb.bin, &glb.other_chunks).unwrap(), bytes);
        // An unknown chunk may also come second, with no BIN chunk at all.
        let bytes = build(&[(4, CHUNK_JSON, J), (4, 7, b"abcd")]);
        let glb = parse(&bytes).unwrap();
        assert_eq!((glb.bin, glb.other_chunks.len()), (None, 1));
        assert_eq!(write(glb.json, glb.bin, &glb.other_chunks).unwrap(), bytes);
    }

    #[test]
    fn write_pads() {
        let out = write(
            b"{\"a\":1}",
            Some(&[9]),
            &[Chunk {
                kind: 5,
                data: b"xy",
            }],
        )
        .unwrap();
        let glb = parse(&out).unwrap();
        assert_eq!(glb.json, b"{\"a\":1} ");
        assert_eq!(glb.bin, Some(&[9u8, 0, 0, 0][..]));
        assert_eq!(glb.other_chunks[0].data, b"xy\0\0");
        assert_eq!(out.len(), 12 + 8 + 8 + 8 + 4 + 8 + 4);
        let json_only = write(b"{}", None, &[]).unwrap();
        assert_eq!(&json_only[12..], b"\x04\0\0\0JSON{}  ");
    }

    #[test]
    fn header_errors() {
        let good = build(&[(4, CHUNK_JSON, J)]);
        for len in 0..12 {
            assert_eq!(parse(&good[..len]), Err(GlbError::TooShort { len }));
        }
        let mut bad = good.clone();
        bad[0] = b'G';
        assert!(matches!(parse(&bad), Err(GlbError::BadMagic { .. })));
        assert!(!is_glb(&bad));
        let mut v1 = good.clone();
        v1[4] = 1;
        assert_eq!(parse(&v1), Err(GlbError::UnsupportedVersion { version: 1 }));
        // The header's length must match the bytes given, in both directions.
        assert_eq!(
            parse(&good[..good.len() - 4]),
            Err(GlbError::LengthMismatch {
                header: 24,
                actual: 20
            })
        );
        let mut longer = good.clone();
        longer.extend_from_slice(&[0; 4]);
        assert!(matches!(
            parse(&longer),
            Err(GlbError::LengthMismatch { .. })
        ));
        let mut huge = good.clone();
        huge[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(parse(&huge), Err(GlbError::LengthMismatch { .. })));
        // A header alone has no JSON chunk.
        let header_only = build(&[]);
        assert_eq!(
            parse(&header_only),
            Err(GlbError::MissingJson { first_kind: None })
        );
    }

    #[test]
    fn chunk_errors() {
        // Lying chunk lengths: past the end, and so large that offset arithmetic would overflow.
        for lie in [8, 9, 1 << 20, u32::MAX - 3, u32::MAX] {
            let bytes = build(&[(lie, CHUNK_JSON, J)]);
            assert!(
                matches!(parse(&bytes), Err(GlbError::ChunkOverrun { index: 0, .. })),
                "{lie}"
            );
        }
        let bytes = build(&[(4, CHUNK_JSON, J), (u32::MAX, CHUNK_BIN, b"")]);
        assert!(matches!(
            parse(&bytes),
            Err(GlbError::ChunkOverrun { index: 1, .. })
        ));
        // The file ends inside a chunk header.
        let mut bytes = build(&[(4, CHUNK_JSON, J), (0, CHUNK_BIN, b"")]);
        bytes.truncate(bytes.len() - 4);
        let len = bytes.len() as u32;
        bytes[8..12].copy_from_slice(&len.to_le_bytes());
        assert_eq!(
            parse(&bytes),
            Err(GlbError::TruncatedChunkHeader {
                index: 1,
                offset: 24
            })
        );
        let bytes = build(&[(3, CHUNK_JSON, b"{} "), (0, 9, b"\0")]);
        assert!(matches!(
            parse(&bytes),
            Err(GlbError::UnalignedChunk { .. })
        ));
        let bytes = build(&[(4, CHUNK_BIN, b"abcd")]);
        assert_eq!(
            parse(&bytes),
            Err(GlbError::MissingJson {
                first_kind: Some(CHUNK_BIN)
            })
        );
        for (chunks, index, kind) in [
            (vec![(4, CHUNK_JSON, J), (4, CHUNK_JSON, J)], 1, CHUNK_JSON),
            (
                vec![
                    (4, CHUNK_JSON, J),
                    (0, CHUNK_BIN, &b""[..]),
                    (0, CHUNK_BIN, b""),
                ],
                2,
                CHUNK_BIN,
            ),
            (
                vec![(4, CHUNK_JSON, J), (0, 7, b""), (0, CHUNK_BIN, b"")],
                2,
                CHUNK_BIN,
            ),
        ] {
            let err = parse(&build(&chunks)).unwrap_err();
            assert_eq!(err, GlbError::MisplacedChunk { index, kind });
            assert!(err.to_string().contains("may only appear"), "{err}");
        }
    }

    #[test]
    fn messages_are_readable() {
        let err = parse(&build(&[(4, 0x1234_5678, J)])).unwrap_err();
        assert_eq!(
            err.to_string(),
            "the first GLB chunk must be JSON, but it is of type 0x12345678"
        );
        let err = parse(&build(&[(4, CHUNK_BIN, J)])).unwrap_err();
        assert_eq!(
            err.to_string(),
            "the first GLB chunk must be JSON, but it is of type \"BIN\""
        );
        assert!(
            GlbError::TooLarge { bytes: 1 << 33 }
                .to_string()
                .contains("4 GiB")
        );
    }

    #[test]
    fn arbitrary_bytes_never_panic() {
        // Every prefix and single-byte corruption of a real file.
        let bytes = fixture("Box/Box.glb");
        for len in 0..bytes.len() {
            let _ = parse(&bytes[..len]);
        }
        for i in 0..64.min(bytes.len()) {
            for v in [0u8, 1, 3, 0x7F, 0xFF] {
                let mut b = bytes.clone();
                b[i] = v;
                if let Ok(glb) = parse(&b) {
                    let out = write(glb.json, glb.bin, &glb.other_chunks).unwrap();
                    assert_eq!(out, b);
                }
            }
        }
    }
}
