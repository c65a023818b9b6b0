//! The project's files: `fixtures/`, the shared corpus beside the checkout, and GLB outputs.

use std::path::{Path, PathBuf};

/// The workspace root (the `tspace` package's folder), wherever the caller's crate sits.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The shared corpus (`../shared/corpus` beside the checkout), when it is there.
pub fn corpus_dir() -> Option<PathBuf> {
    let dir = workspace_root().join("../shared/corpus");
    dir.is_dir().then_some(dir)
}

/// The bytes of a file in `fixtures/`.
pub fn fixture(path: &str) -> Vec<u8> {
    let full = workspace_root().join("fixtures").join(path);
    std::fs::read(&full).unwrap_or_else(|e| panic!("fixture {path}: {e}"))
}

/// The JSON chunk of a GLB, parsed.
pub fn glb_json(bytes: &[u8]) -> serde_json::Value {
    let glb = tspace::scene::gltf::glb::parse(bytes).expect("a GLB");
    serde_json::from_slice(glb.json).expect("JSON")
}

/// Validates an output with the glTF-Validator (when installed) and asserts it has no errors
/// but the missing-image ones the fixtures cause on purpose (they ship without their images).
pub fn assert_valid_output(name: &str, bytes: &[u8]) -> Option<crate::validator::ValidatorReport> {
    let report = crate::validator::validate(name, bytes)?;
    eprintln!("validator, {name}: {}", report.summary());
    for m in &report.messages {
        eprintln!(
            "  {:?} {} {:?} {}",
            m.severity, m.code, m.pointer, m.message
        );
    }
    let errors: Vec<_> = report
        .messages_of(crate::validator::Severity::Error)
        .filter(|m| {
            !(m.code == "IO_ERROR"
                && m.pointer
                    .as_deref()
                    .is_some_and(|p| p.starts_with("/images/")))
        })
        .map(|m| format!("{} at {:?}: {}", m.code, m.pointer, m.message))
        .collect();
    assert!(errors.is_empty(), "{name}: validator errors {errors:#?}");
    Some(report)
}
