//! A written scene as the pieces it is made of, for a caller that writes it out and still holds
//! the input ([`SceneOptions::in_pieces`](super::SceneOptions::in_pieces)): the GLB's framing
//! and JSON, the new data tspace made (moved, not copied), and ranges of the input where the
//! output repeats it. Written with vectored I/O, the output is never assembled in memory: on a
//! 2M-triangle GLB that assembly was a 72 MB copy into fresh memory, a sixth of the run.
//!
//! A scene made in the process (the GLB an OBJ is converted to) is not the caller's to hold:
//! the pieces then hold it themselves ([`Pieces::with_own_input`]), and every way of writing
//! them reads their ranges from it, whatever input the caller passes.

use std::io::{IoSlice, Write};
use std::ops::Range;

/// One piece of the output.
#[derive(Debug)]
pub enum Part {
    Owned(Vec<u8>),
    /// Float vectors tspace computed, whose memory is these bytes of the output.
    Floats(FloatBytes),
    /// These bytes of the input the scene was processed from.
    Input(Range<usize>),
}

/// Float vectors whose memory is their bytes as glTF stores them, little-endian: moved from the
/// computation into the output, where copying a 2M-triangle mesh's tangents into a vector of
/// bytes took 16 MB of fresh memory. Made only on a little-endian machine; elsewhere the values
/// are copied into bytes after all.
#[derive(Debug, Default)]
pub struct FloatBytes(Vec<[f32; 4]>);

impl FloatBytes {
    /// `values` as their bytes, or back where this machine's floats are not glTF's.
    pub fn new(values: Vec<[f32; 4]>) -> Result<FloatBytes, Vec<[f32; 4]>> {
        if cfg!(target_endian = "little") {
            Ok(FloatBytes(values))
        } else {
            Err(values)
        }
    }
}

impl AsRef<[u8]> for FloatBytes {
    fn as_ref(&self) -> &[u8] {
        bytemuck::cast_slice(&self.0)
    }
}

/// The output, piece by piece, in order.
#[derive(Debug, Default)]
pub struct Pieces {
    parts: Vec<Part>,
    len: usize,
    /// Where the JSON lies, in the first part.
    json: Range<usize>,
    /// The bytes [`Part::Input`] ranges refer to, where the pieces hold them.
    own_input: Option<Vec<u8>>,
}

/// How many slices one `write_vectored` call is given (Linux takes up to 1024).
const SLICES_PER_WRITE: usize = 1024;

impl Pieces {
    /// Pieces that start with `head` (the GLB header and the JSON chunk, whose text lies at
    /// `json` in it).
    pub fn new(head: Vec<u8>, json: Range<usize>) -> Pieces {
        Pieces {
            len: head.len(),
            parts: vec![Part::Owned(head)],
            json,
            own_input: None,
        }
    }

    /// The whole input, unchanged.
    pub fn whole_input(len: usize) -> Pieces {
        Pieces {
            parts: vec![Part::Input(0..len)],
            len,
            json: 0..0,
            own_input: None,
        }
    }

    /// The pieces, holding the input their ranges refer to: a scene made in the process, which
    /// its caller does not hold (an OBJ's GLB). Assembled from it instead, the 1M-triangle OBJ
    /// sphere's 36 MB output was copied into fresh memory once more.
    pub fn with_own_input(self, input: Vec<u8>) -> Pieces {
        Pieces {
            own_input: Some(input),
            ..self
        }
    }

    /// Whether the pieces hold the input their ranges refer to.
    pub fn hold_their_input(&self) -> bool {
        self.own_input.is_some()
    }

    pub fn push(&mut self, part: Part) {
        let len = match &part {
            Part::Owned(bytes) => bytes.len(),
            Part::Floats(floats) => floats.as_ref().len(),
            Part::Input(range) => range.len(),
        };
        if len > 0 {
            self.len += len;
            self.parts.push(part);
        }
    }

    /// The output's length in bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The JSON text, when the pieces were written (not the input passed through whole).
    pub fn json(&self) -> Option<&[u8]> {
        match self.parts.first() {
            Some(Part::Owned(head)) => head.get(self.json.clone()),
            _ => None,
        }
    }

    /// The slices to write, the ranges of `input` (or of the pieces' own input) resolved.
    fn slices<'a>(&'a self, input: &'a [u8]) -> impl Iterator<Item = &'a [u8]> {
        let input = self.own_input.as_deref().unwrap_or(input);
        self.parts.iter().map(move |part| match part {
            Part::Owned(bytes) => bytes.as_slice(),
            Part::Floats(floats) => floats.as_ref(),
            Part::Input(range) => input.get(range.clone()).unwrap_or_default(),
        })
    }

    /// The pieces, in order (for a caller that sends them as they are), and the input their
    /// ranges refer to where the pieces hold it (else the caller's).
    pub fn into_parts(self) -> (Vec<Part>, Option<Vec<u8>>) {
        (self.parts, self.own_input)
    }

    /// The output as one vector (for callers that need it whole). `input` is the one the
    /// scene was processed from, unless the pieces hold their own.
    pub fn to_vec(&self, input: &[u8]) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.len);
        for slice in self.slices(input) {
            out.extend_from_slice(slice);
        }
        out
    }

    /// Writes the output to `out`, a batch of slices per call, resuming after short writes.
    /// `input` as for [`Pieces::to_vec`].
    pub fn write_to(&self, input: &[u8], out: &mut dyn Write) -> std::io::Result<()> {
        let all: Vec<&[u8]> = self.slices(input).collect();
        for batch in all.chunks(SLICES_PER_WRITE) {
            let mut slices: Vec<IoSlice<'_>> = batch.iter().map(|s| IoSlice::new(s)).collect();
            let mut rest = &mut slices[..];
            while !rest.is_empty() {
                match out.write_vectored(rest) {
                    Ok(0) => return Err(std::io::ErrorKind::WriteZero.into()),
                    Ok(n) => IoSlice::advance_slices(&mut rest, n),
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e),
                }
            }
        }
        out.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer that takes at most 5 bytes a call, to exercise resuming.
    struct Trickle(Vec<u8>);

    impl Write for Trickle {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let n = buf.len().min(5);
            self.0.extend_from_slice(&buf[..n]);
            Ok(n)
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn pieces_write_in_order_through_short_writes() {
        let input = b"0123456789abcdef";
        let mut pieces = Pieces::new(b"HEAD{json}".to_vec(), 4..10);
        pieces.push(Part::Input(2..6));
        pieces.push(Part::Owned(Vec::new()));
        pieces.push(Part::Owned(b"new".to_vec()));
        pieces.push(Part::Input(10..16));
        let expected = b"HEAD{json}2345newabcdef".to_vec();
        assert_eq!(pieces.len(), expected.len());
        assert_eq!(pieces.json(), Some(&b"{json}"[..]));
        assert_eq!(pieces.to_vec(input), expected);
        let mut out = Trickle(Vec::new());
        pieces.write_to(input, &mut out).unwrap();
        assert_eq!(out.0, expected);
        // More slices than one call takes.
        let mut many = Pieces::new(Vec::new(), 0..0);
        for _ in 0..3000 {
            many.push(Part::Input(0..1));
        }
        let mut out = Vec::new();
        many.write_to(input, &mut out).unwrap();
        assert_eq!(out, vec![b'0'; 3000]);
        assert_eq!(Pieces::whole_input(16).to_vec(input), input.to_vec());
    }

    #[test]
    fn pieces_holding_their_input_read_it_whatever_they_are_given() {
        let own = b"0123456789".to_vec();
        let mut pieces = Pieces::new(b"HEAD".to_vec(), 0..0);
        pieces.push(Part::Input(2..5));
        pieces.push(Part::Owned(b"new".to_vec()));
        let pieces = pieces.with_own_input(own.clone());
        assert!(pieces.hold_their_input());
        let expected = b"HEAD234new".to_vec();
        assert_eq!(pieces.to_vec(b"some other input"), expected);
        assert_eq!(pieces.to_vec(&[]), expected);
        let mut out = Trickle(Vec::new());
        pieces.write_to(&[], &mut out).unwrap();
        assert_eq!(out.0, expected);
        let (parts, input) = pieces.into_parts();
        assert_eq!(input, Some(own));
        assert_eq!(parts.len(), 3);
    }
}
