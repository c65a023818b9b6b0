//! Every glTF and GLB of the shared corpus (`../shared/corpus`, skipped when absent), processed
//! with the default options and with `overwrite` + `all`: where the Khronos glTF-Validator accepts
//! the input, it must accept the output with no new errors or warnings; where it does not, tspace
//! must still answer with a result or a clean error, never a panic.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tspace::scene::SceneOptions;
use tspace::scene::gltf::process;
use tspace::scene::uri::PartSet;
#[allow(unused_imports)]
use tspace_testkit::validator::{self, Severity, ValidatorReport};

fn corpus() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    dir.is_dir().then_some(dir)
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            files(&path, out);
        } else if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("gltf" | "glb")
        ) {
            out.push(path);
        }
    }
}

fn codes(report: &ValidatorReport, severity: Severity) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    for m in report.messages_of(severity) {
        *out.entry(m.code.clone()).or_insert(0) += 1;
    }
    out
}

/// Codes that may appear in the output but not the input, and why.
const DOCUMENTED_NEW_WARNINGS: &[(&str, &str)] = &[];

#[test]
fn corpus_files_come_back_valid() {
    let Some(dir) = corpus() else {
        eprintln!("corpus_roundtrip: ../shared/corpus not found, skipping");
        return;
    };
    let mut paths = Vec::new();
    files(&dir, &mut paths);
    let mut problems = Vec::new();
    let mut checked = 0;
    for path in &paths {
        let bytes = std::fs::read(path).unwrap();
        // Every file beside it is a part, as an upload would carry them.
        let folder = path.parent().unwrap();
        let siblings: Vec<(String, Vec<u8>)> = std::fs::read_dir(folder)
            .unwrap()
            .flatten()
            .filter(|e| e.path().is_file() && e.path() != *path)
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into_owned(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        let mut parts = PartSet::new();
        for (name, data) in &siblings {
            parts.insert(name.clone(), data).unwrap();
        }
        let name = path.strip_prefix(&dir).unwrap().display().to_string();
        let input_report = validator::validate_file(path);
        let input_ok = input_report.as_ref().is_some_and(|r| r.num_errors == 0);
        for (label, options) in [
            ("default", SceneOptions::default()),
            (
                "overwrite+all",
                SceneOptions {
                    overwrite: true,
                    all: true,
                    ..SceneOptions::default()
                },
            ),
        ] {
            let result = std::panic::catch_unwind(|| process(&bytes, &parts, &options));
            let processed = match result {
                Err(_) => {
                    problems.push(format!("{name} ({label}): panicked"));
                    continue;
                }
                Ok(Err(error)) => {
                    if input_ok {
                        problems.push(format!("{name} ({label}): refused a valid file: {error}"));
                    } else {
                        eprintln!("{name} ({label}): refused ({}): {error}", error.code);
                    }
                    continue;
                }
                Ok(Ok(p)) => p,
            };
            let summary = &processed.report.summary;
            eprintln!(
                "{name} ({label}): {} generated, {} audited, {} skipped, {} -> {} bytes",
                summary.generated,
                summary.audited,
                summary.skipped,
                processed.report.input_bytes,
                processed.report.output_bytes.unwrap_or(0)
            );
            for p in &processed.report.primitives {
                if let Some(audit) = &p.audit {
                    eprintln!(
                        "  audit mesh {} primitive {}: {} ({} of {} corners disagree in w; angle median {:.3}°, p99 {:.3}°, max {:.3}°)",
                        p.mesh,
                        p.primitive,
                        audit.verdict,
                        audit.w_disagreements.count,
                        audit.corners,
                        audit.angle_median_degrees,
                        audit.angle_p99_degrees,
                        audit.angle_max_degrees
                    );
                }
            }
            let (Some(input_report), Some(bytes)) = (&input_report, processed.bytes) else {
                continue;
            };
            if !input_ok {
                continue;
            }
            let Some(output_report) = validator::validate(&format!("{name}.glb"), &bytes) else {
                continue;
            };
            checked += 1;
            if output_report.num_errors > 0 {
                problems.push(format!(
                    "{name} ({label}): output has errors {:?}",
                    output_report.error_codes()
                ));
            }
            let before = codes(input_report, Severity::Warning);
            for (code, count) in codes(&output_report, Severity::Warning) {
                let documented = DOCUMENTED_NEW_WARNINGS.iter().any(|(c, _)| *c == code);
                if count > before.get(&code).copied().unwrap_or(0) && !documented {
                    problems.push(format!("{name} ({label}): new warning {code} x{count}"));
                }
            }
        }
    }
    eprintln!("corpus_roundtrip: {checked} outputs validated");
    assert!(problems.is_empty(), "{problems:#?}");
}
