//! Compressed transfers: request bodies sent with `Content-Encoding: gzip` or `zstd`, and the
//! answers' compression.
//!
//! A request body is decoded as it streams in, and the body limit counts decoded bytes: the
//! limit exists to bound what a request makes the server hold, and a scene is held decoded. So a
//! gzip bomb (a gigabyte of zeros in a megabyte) is refused at the limit, having cost the limit
//! and never the gigabyte. Errors are told apart by their type: a stream that does not decode is
//! the client's mistake (400), a body over the limit is a 413, and a connection that broke is
//! neither.
//!
//! Answers are compressed by tower-http when the client's `Accept-Encoding` asks for gzip or
//! zstd, at the fastest level: the CPU it costs is taken from the same two cores the workers use,
//! and scene data is mostly floats that a higher level barely shrinks further.

use crate::scene::error::ProblemCode;
use crate::server::problem::Problem;
use async_compression::tokio::bufread::{GzipDecoder, ZstdDecoder};
use axum::extract::Request;
use axum::http::{HeaderMap, header};
use futures_util::TryStreamExt;
use std::fmt;
use tokio_util::io::{ReaderStream, StreamReader};
use tower_http::compression::{CompressionLayer, CompressionLevel};

/// The codings a request body may arrive in, as the 415 lists them in `Accept-Encoding`.
pub const ACCEPTED: &str = "gzip, zstd";

/// Decoded bytes are handed on in pieces of this size.
const CHUNK: usize = 64 << 10;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Coding {
    Gzip,
    Zstd,
}

/// A request body's compressed stream could not be decoded.
#[derive(Debug)]
pub struct DecodeError {
    coding: Coding,
    cause: std::io::Error,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self.coding {
            Coding::Gzip => "gzip",
            Coding::Zstd => "zstd",
        };
        write!(f, "the body is not valid {name}: {}", self.cause)
    }
}

impl std::error::Error for DecodeError {}

/// The connection failed while a compressed body was being read; not the encoding's fault.
#[derive(Debug)]
struct ReadError(axum::Error);

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "reading the body failed: {}", self.0)
    }
}

impl std::error::Error for ReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.0)
    }
}

/// The content coding `headers` declare: none for an absent header or `identity`, else exactly
/// one of gzip (or its old name x-gzip) and zstd. Stacked codings are refused rather than
/// half-supported: no client library sends them.
fn coding_of(headers: &HeaderMap) -> Result<Option<Coding>, Problem> {
    let mut codings = Vec::new();
    for value in headers.get_all(header::CONTENT_ENCODING) {
        let value = value.to_str().unwrap_or("\u{fffd}");
        codings.extend(
            value
                .split(',')
                .map(|c| c.trim().to_ascii_lowercase())
                .filter(|c| !c.is_empty() && c != "identity"),
        );
    }
    match codings.as_slice() {
        [] => Ok(None),
        [one] if one == "gzip" || one == "x-gzip" => Ok(Some(Coding::Gzip)),
        [one] if one == "zstd" => Ok(Some(Coding::Zstd)),
        [one] => Err(unsupported(format!(
            "the body's Content-Encoding is {one}; tspace decodes {ACCEPTED}, or an unencoded body"
        ))),
        many => Err(unsupported(format!(
            "the body's Content-Encoding stacks {}; tspace decodes one of {ACCEPTED}",
            many.join(", ")
        ))),
    }
}

fn unsupported(detail: String) -> Problem {
    Problem::new(ProblemCode::UnsupportedEncoding, detail)
}

/// `request` with its body decoded as it is read, when it declares gzip or zstd. The encoding
/// headers go: `Content-Length` counted the compressed bytes, and what follows sees a plain
/// body.
pub fn decode_request(request: Request) -> Result<Request, Problem> {
    let Some(coding) = coding_of(request.headers())? else {
        return Ok(request);
    };
    let (mut parts, body) = request.into_parts();
    parts.headers.remove(header::CONTENT_ENCODING);
    parts.headers.remove(header::CONTENT_LENGTH);
    let compressed = StreamReader::new(
        body.into_data_stream()
            .map_err(|e| std::io::Error::other(ReadError(e))),
    );
    let decoded: Box<dyn tokio::io::AsyncRead + Send + Unpin> = match coding {
        Coding::Gzip => {
            let mut decoder = GzipDecoder::new(compressed);
            // `cat a.gz b.gz` is a valid gzip file, and `gzip -d` reads both members.
            decoder.multiple_members(true);
            Box::new(decoder)
        }
        Coding::Zstd => {
            let mut decoder = ZstdDecoder::new(compressed);
            decoder.multiple_members(true);
            Box::new(decoder)
        }
    };
    let stream = ReaderStream::with_capacity(decoded, CHUNK).map_err(move |cause| {
        // A failure of the connection comes back through the decoder as it went in.
        match cause
            .get_ref()
            .is_some_and(|inner| inner.downcast_ref::<ReadError>().is_some())
        {
            true => axum::Error::new(cause),
            false => axum::Error::new(DecodeError { coding, cause }),
        }
    });
    Ok(Request::from_parts(
        parts,
        axum::body::Body::from_stream(stream),
    ))
}

/// Why reading a body failed, found by walking the error's causes.
#[derive(Debug, PartialEq, Eq)]
pub enum BodyFailure {
    /// More (decoded) bytes than the body limit.
    TooLarge,
    /// The compressed stream is corrupt or truncated; the message says how.
    Undecodable(String),
    /// Anything else: the connection broke, or the multipart framing is wrong.
    Other,
}

pub fn body_failure(error: &(dyn std::error::Error + 'static)) -> BodyFailure {
    let mut cause = Some(error);
    while let Some(error) = cause {
        if error.is::<http_body_util::LengthLimitError>() {
            return BodyFailure::TooLarge;
        }
        if let Some(decode) = error.downcast_ref::<DecodeError>() {
            return BodyFailure::Undecodable(decode.to_string());
        }
        cause = error.source();
    }
    BodyFailure::Other
}

/// Compresses answers for clients that ask for gzip or zstd.
pub fn compression() -> CompressionLayer {
    CompressionLayer::new().quality(CompressionLevel::Fastest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(values: &[&str]) -> HeaderMap {
        let mut map = HeaderMap::new();
        for v in values {
            map.append(header::CONTENT_ENCODING, HeaderValue::from_str(v).unwrap());
        }
        map
    }

    #[test]
    fn codings_are_read_as_http_spells_them() {
        assert_eq!(coding_of(&headers(&[])).unwrap(), None);
        assert_eq!(coding_of(&headers(&["identity"])).unwrap(), None);
        assert_eq!(coding_of(&headers(&["GZIP"])).unwrap(), Some(Coding::Gzip));
        assert_eq!(
            coding_of(&headers(&["x-gzip"])).unwrap(),
            Some(Coding::Gzip)
        );
        assert_eq!(
            coding_of(&headers(&["identity, zstd"])).unwrap(),
            Some(Coding::Zstd)
        );
        for refused in [
            &["br"][..],
            &["gzip, zstd"],
            &["gzip", "gzip"],
            &["deflate"],
        ] {
            let problem = coding_of(&headers(refused)).unwrap_err();
            assert_eq!(
                problem.code,
                ProblemCode::UnsupportedEncoding,
                "{refused:?}"
            );
        }
    }
}
