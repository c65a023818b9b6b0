//! The `multipart/mixed` answer of `POST /v1/tangents`: the report, then the scene.
//!
//! A boundary must not occur in any part (RFC 2046 §5.1.1), and the scene is arbitrary bytes
//! from the client, so the boundary is chosen per answer: the fixed stem when no part contains
//! it (the usual case, which keeps answers as they always were), else the stem with the first
//! counter suffix that follows none of the stem's occurrences.
//!
//! The scene comes as the pieces it was written in (slices of the upload and the new data), and
//! the answer is those pieces between a head and a tail: the scene is never put together in one
//! buffer, so the search for the boundary also looks across the seams between pieces.

use axum::body::Bytes;
use std::collections::HashSet;

/// The boundary's stem, and the whole boundary when no part contains it.
const STEM: &str = "tspace-report-and-scene-7c1f3a";

/// The width of the suffix, `-` and eight hex digits: fixed, so that a suffix can only be
/// blocked by the bytes right after an occurrence of the stem, never by a longer one.
const SUFFIX_LEN: usize = 9;

/// The stem and its suffix: what an occurrence blocks is read from this many bytes.
const WINDOW: usize = STEM.len() + SUFFIX_LEN;

/// The body, in parts to send in order, and its `Content-Type`.
pub(super) struct Mixed {
    pub content_type: String,
    pub parts: Vec<Bytes>,
}

/// The report (JSON) and the scene (`scene_type`, sent as `file_name`, in `scene` pieces) as
/// one answer.
pub(super) fn report_and_scene(
    report: &str,
    scene: Vec<Bytes>,
    scene_type: &str,
    file_name: &str,
) -> Mixed {
    let mut pieces: Vec<&[u8]> = vec![report.as_bytes()];
    pieces.extend(scene.iter().map(|p| &p[..]));
    let boundary = boundary_for(&pieces);
    let head = format!(
        "--{boundary}\r\nContent-Type: application/json\r\nContent-Disposition: inline; name=\"report\"\r\n\r\n{report}\r\n--{boundary}\r\nContent-Type: {scene_type}\r\nContent-Disposition: attachment; name=\"scene\"; filename=\"{file_name}\"\r\n\r\n"
    );
    let tail = format!("\r\n--{boundary}--\r\n");
    let mut parts = Vec::with_capacity(scene.len() + 2);
    parts.push(Bytes::from(head));
    parts.extend(scene);
    parts.push(Bytes::from(tail));
    Mixed {
        content_type: format!("multipart/mixed; boundary={boundary}"),
        parts,
    }
}

/// A boundary that occurs in none of `pieces`, in time linear in their length. The report is
/// the first piece and the scene the rest: the scene's pieces are one text, so an occurrence
/// may straddle the seam between two of them. (The report's seam with the scene is searched
/// too; at worst that moves the boundary off the stem for nothing.)
fn boundary_for(pieces: &[&[u8]]) -> String {
    let stem = STEM.as_bytes();
    let mut blocked: HashSet<Vec<u8>> = HashSet::new();
    let mut found = false;
    for piece in pieces {
        for at in occurrences(piece, stem) {
            found = true;
            if let Some(next) = piece.get(at + stem.len()..at + WINDOW) {
                blocked.insert(next.to_vec());
            }
        }
    }
    // Each seam: up to WINDOW - 1 bytes before it and WINDOW - 1 after (gathered across short
    // pieces), and the occurrences whose stem and suffix the seam cuts.
    for seam in 1..pieces.len() {
        let before = bytes_before(pieces, seam, WINDOW - 1);
        let after = bytes_after(pieces, seam, WINDOW - 1);
        let joined = [before.as_slice(), after.as_slice()].concat();
        for at in occurrences(&joined, stem).filter(|&at| at < before.len()) {
            found = true;
            if let Some(next) = joined.get(at + stem.len()..at + WINDOW) {
                blocked.insert(next.to_vec());
            }
        }
    }
    if !found {
        return STEM.to_owned();
    }
    // Each occurrence blocks at most one suffix, so this ends within `blocked.len() + 1` tries,
    // long before eight hex digits run out (that would take parts of over 100 GiB).
    let mut n: u64 = 0;
    loop {
        let suffix = format!("-{n:08x}");
        if !blocked.contains(suffix.as_bytes()) {
            return format!("{STEM}{suffix}");
        }
        n += 1;
    }
}

/// The last `n` bytes (or fewer, at the start) of the pieces before `seam`.
fn bytes_before(pieces: &[&[u8]], seam: usize, n: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(n);
    for piece in pieces[..seam].iter().rev() {
        let take = (n - out.len()).min(piece.len());
        out.splice(0..0, piece[piece.len() - take..].iter().copied());
        if out.len() == n {
            break;
        }
    }
    out
}

/// The first `n` bytes (or fewer, at the end) of the pieces from `seam` on.
fn bytes_after(pieces: &[&[u8]], seam: usize, n: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(n);
    for piece in &pieces[seam..] {
        let take = (n - out.len()).min(piece.len());
        out.extend_from_slice(&piece[..take]);
        if out.len() == n {
            break;
        }
    }
    out
}

/// Where `needle` starts in `haystack`. A window compare stops at the first differing byte, so
/// each costs at most the needle's length: linear in the haystack, for any bytes.
fn occurrences<'a>(haystack: &'a [u8], needle: &'a [u8]) -> impl Iterator<Item = usize> + 'a {
    haystack
        .windows(needle.len())
        .enumerate()
        .filter(move |(_, window)| *window == needle)
        .map(|(at, _)| at)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contains(haystack: &[u8], needle: &str) -> bool {
        occurrences(haystack, needle.as_bytes()).next().is_some()
    }

    #[test]
    fn the_stem_is_the_boundary_when_nothing_contains_it() {
        assert_eq!(boundary_for(&[b"{}", b"glTF\x02\0\0\0"]), STEM);
    }

    #[test]
    fn a_part_that_contains_the_boundary_gets_another() {
        let scene = format!("ab\r\n--{STEM}\r\ncd--{STEM}-00000000xx");
        let boundary = boundary_for(&[b"{}", scene.as_bytes()]);
        assert_eq!(boundary, format!("{STEM}-00000001"));
        assert!(!contains(scene.as_bytes(), &boundary));
        assert!(boundary.len() <= 70, "RFC 2046 allows 70 characters");
    }

    #[test]
    fn the_report_counts_too() {
        let report = format!("{{\"name\":\"{STEM}\"}}");
        let boundary = boundary_for(&[report.as_bytes(), b"glTF"]);
        assert_ne!(boundary, STEM);
        assert!(!contains(report.as_bytes(), &boundary));
    }

    #[test]
    fn many_blocked_suffixes_are_skipped() {
        let scene: String = (0..300u32).map(|n| format!("{STEM}-{n:08x}")).collect();
        let boundary = boundary_for(&[scene.as_bytes()]);
        assert_eq!(boundary, format!("{STEM}-0000012c"));
        assert!(!contains(scene.as_bytes(), &boundary));
    }

    /// A boundary found for the scene cut into pieces at every place.
    fn boundaries_of_every_cut(scene: &[u8]) -> HashSet<String> {
        let mut found = HashSet::new();
        for cut in 0..=scene.len() {
            for second in cut..=scene.len() {
                let (a, rest) = scene.split_at(cut);
                let (b, c) = rest.split_at(second - cut);
                found.insert(boundary_for(&[b"{}", a, b, c]));
            }
        }
        found
    }

    #[test]
    fn an_occurrence_across_a_seam_is_found() {
        // The stem and a suffix, cut anywhere into three pieces (some empty, some a byte long),
        // give the boundary the whole text gives.
        let scene = format!("xx--{STEM}-00000000yy");
        let whole = boundary_for(&[b"{}", scene.as_bytes()]);
        assert_eq!(whole, format!("{STEM}-00000001"));
        assert_eq!(
            boundaries_of_every_cut(scene.as_bytes()),
            HashSet::from([whole])
        );
        // Without the suffix the stem alone still moves the boundary off the stem.
        let bare = format!("ab{STEM}");
        assert_eq!(
            boundaries_of_every_cut(bare.as_bytes()),
            HashSet::from([format!("{STEM}-00000000")])
        );
    }

    fn body_of(mixed: Mixed) -> Vec<u8> {
        mixed.parts.concat()
    }

    #[test]
    fn the_body_is_two_parts_around_the_scene() {
        let scene = vec![Bytes::from_static(b"SC"), Bytes::from_static(b"ENE")];
        let mixed = report_and_scene("{}", scene, "model/gltf-binary", "scene.glb");
        assert_eq!(
            mixed.content_type,
            format!("multipart/mixed; boundary={STEM}")
        );
        assert_eq!(mixed.parts.len(), 4, "head, the scene's two pieces, tail");
        let text = String::from_utf8(body_of(mixed)).unwrap();
        assert!(text.starts_with(&format!("--{STEM}\r\n")));
        assert!(text.ends_with(&format!("\r\n\r\nSCENE\r\n--{STEM}--\r\n")));
        assert_eq!(text.matches(&format!("--{STEM}")).count(), 3);
    }
}
