//! The `multipart/mixed` answer of `POST /v1/tangents`: the report, then the scene.
//!
//! A boundary must not occur in any part (RFC 2046 §5.1.1), and the scene is arbitrary bytes
//! from the client, so the boundary is chosen per answer: the fixed stem when no part contains
//! it (the usual case, which keeps answers as they always were), else the stem with the first
//! counter suffix that follows none of the stem's occurrences.

use std::collections::HashSet;

/// The boundary's stem, and the whole boundary when no part contains it.
const STEM: &str = "tspace-report-and-scene-7c1f3a";

/// The width of the suffix, `-` and eight hex digits: fixed, so that a suffix can only be
/// blocked by the bytes right after an occurrence of the stem, never by a longer one.
const SUFFIX_LEN: usize = 9;

/// The body and its `Content-Type`.
pub(super) struct Mixed {
    pub content_type: String,
    pub body: Vec<u8>,
}

/// The report (JSON) and the scene (`scene_type`, sent as `file_name`) as one answer.
pub(super) fn report_and_scene(
    report: &str,
    scene: &[u8],
    scene_type: &str,
    file_name: &str,
) -> Mixed {
    let boundary = boundary_for(&[report.as_bytes(), scene]);
    let mut body = Vec::with_capacity(scene.len() + report.len() + 512);
    body.extend_from_slice(
        format!(
            "--{boundary}\r\nContent-Type: application/json\r\nContent-Disposition: inline; name=\"report\"\r\n\r\n{report}\r\n--{boundary}\r\nContent-Type: {scene_type}\r\nContent-Disposition: attachment; name=\"scene\"; filename=\"{file_name}\"\r\n\r\n"
        )
        .as_bytes(),
    );
    body.extend_from_slice(scene);
    body.extend_from_slice(format!("\r\n--{boundary}--\r\n").as_bytes());
    Mixed {
        content_type: format!("multipart/mixed; boundary={boundary}"),
        body,
    }
}

/// A boundary that occurs in none of `parts`, in time linear in their length.
fn boundary_for(parts: &[&[u8]]) -> String {
    let stem = STEM.as_bytes();
    let mut blocked: HashSet<&[u8]> = HashSet::new();
    let mut found = false;
    for part in parts {
        for at in occurrences(part, stem) {
            found = true;
            if let Some(next) = part.get(at + stem.len()..at + stem.len() + SUFFIX_LEN) {
                blocked.insert(next);
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

    #[test]
    fn the_body_is_two_parts_around_the_scene() {
        let mixed = report_and_scene("{}", b"SCENE", "model/gltf-binary", "scene.glb");
        assert_eq!(
            mixed.content_type,
            format!("multipart/mixed; boundary={STEM}")
        );
        let text = String::from_utf8(mixed.body).unwrap();
        assert!(text.starts_with(&format!("--{STEM}\r\n")));
        assert!(text.ends_with(&format!("\r\n\r\nSCENE\r\n--{STEM}--\r\n")));
        assert_eq!(text.matches(&format!("--{STEM}")).count(), 3);
    }
}
