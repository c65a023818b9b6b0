//! Which files a `process` run reads, and where each output goes.

use super::stdio::is_dash;
use crate::scene::OutputFormat;
use std::collections::{HashMap, HashSet};
use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

/// One scene file to read.
#[derive(Clone, Debug)]
pub(crate) struct Input {
    /// The path as named on the command line or found under a directory.
    pub path: PathBuf,
    /// For a file found under a directory input: its path relative to that directory, which
    /// `--out-dir` mirrors.
    pub relative: Option<PathBuf>,
}

/// What the command-line inputs expand to, in order.
#[derive(Debug)]
pub(crate) enum Found {
    File(Input),
    /// A named input, or a folder under one, that cannot be read.
    Unreadable {
        path: PathBuf,
        message: String,
    },
}

/// Expands the inputs: files as they are, `-` (standard input) as it is, directories searched
/// recursively (see `collect_dir`), leaving out the folder `skip` (the output folder, whose
/// files are earlier outputs). A file named twice (or named and also found under a directory)
/// is read once.
pub(crate) fn collect(inputs: &[PathBuf], skip: Option<&Path>) -> Vec<Found> {
    let skip = skip.and_then(|p| p.canonicalize().ok());
    let mut found = Vec::new();
    for path in inputs {
        if is_dash(path) {
            found.push(Found::File(Input {
                path: path.clone(),
                relative: None,
            }));
            continue;
        }
        match std::fs::metadata(path) {
            Err(e) => found.push(Found::Unreadable {
                path: path.clone(),
                message: format!("cannot read it: {}", io_message(&e)),
            }),
            Ok(m) if m.is_dir() => collect_dir(path, path, skip.as_deref(), &mut found),
            Ok(_) => found.push(Found::File(Input {
                path: path.clone(),
                relative: None,
            })),
        }
    }
    let mut seen = HashSet::new();
    found.retain(|f| match f {
        Found::File(input) => seen.insert(identity(&input.path)),
        Found::Unreadable { .. } => true,
    });
    found
}

/// `.glb`, `.gltf` and `.obj` files under `dir`, in name order. Hidden entries, symbolic links to
/// folders (which could loop) and earlier outputs (`*.tspace.glb`, `*.tspace.gltf`) are skipped.
fn collect_dir(root: &Path, dir: &Path, skip: Option<&Path>, found: &mut Vec<Found>) {
    if skip.is_some() && dir.canonicalize().ok().as_deref() == skip {
        return;
    }
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) => {
            found.push(Found::Unreadable {
                path: dir.to_path_buf(),
                message: format!("cannot read the folder: {}", io_message(&e)),
            });
            return;
        }
    };
    let mut entries: Vec<_> = entries.filter_map(Result::ok).collect();
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let name = entry.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue;
        }
        let path = entry.path();
        let Ok(file_type) = entry.file_type() else {
            continue;
        };
        if file_type.is_dir() {
            collect_dir(root, &path, skip, found);
            continue;
        }
        let is_file = file_type.is_file()
            || (file_type.is_symlink() && std::fs::metadata(&path).is_ok_and(|m| m.is_file()));
        if is_file && is_scene_name(&name.to_string_lossy()) {
            let relative = path.strip_prefix(root).ok().map(Path::to_path_buf);
            found.push(Found::File(Input { path, relative }));
        }
    }
}

fn is_scene_name(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    let Some((stem, extension)) = lower.rsplit_once('.') else {
        return false;
    };
    match extension {
        // tspace's own outputs (of an earlier run beside the inputs) are not inputs.
        "glb" | "gltf" => !stem.ends_with(".tspace") && !stem.ends_with(".debug"),
        "obj" => true,
        _ => false,
    }
}

/// Where outputs go.
#[derive(Clone, Debug)]
pub(crate) enum Destination {
    /// `<stem>.tspace.glb` beside the input.
    Beside,
    /// `-o`: this file (one input).
    File(PathBuf),
    /// `--out-dir`: `<dir>/<relative folder>/<stem>.glb`.
    Dir(PathBuf),
}

pub(crate) fn extension(format: OutputFormat) -> &'static str {
    match format {
        OutputFormat::Glb => "glb",
        OutputFormat::GltfEmbedded => "gltf",
    }
}

/// The output path for `input`. A debug output (`--debug-colors`) is `<stem>.debug.<ext>`
/// beside the input or in the directory, so that it is never taken for the one to ship.
pub(crate) fn output_path(
    input: &Input,
    destination: &Destination,
    format: OutputFormat,
    debug: bool,
) -> PathBuf {
    let stem = input
        .path
        .file_stem()
        .map(OsString::from)
        .unwrap_or_else(|| OsString::from("scene"));
    let with_extension = |infix: &str| {
        let mut name = stem.clone();
        name.push(infix);
        name.push(extension(format));
        name
    };
    match destination {
        Destination::File(path) => path.clone(),
        Destination::Beside if debug => input.path.with_file_name(with_extension(".debug.")),
        Destination::Beside => input.path.with_file_name(with_extension(".tspace.")),
        Destination::Dir(dir) => {
            let folder = input
                .relative
                .as_deref()
                .and_then(Path::parent)
                .unwrap_or(Path::new(""));
            dir.join(folder)
                .join(with_extension(if debug { ".debug." } else { "." }))
        }
    }
}

/// Refuses a plan that would replace an input (or write the report over one), or write two
/// outputs to one path. Standard input and output (`-`) are no file and clash with none.
pub(crate) fn check(
    inputs: &[&Input],
    outputs: &[PathBuf],
    report: Option<&Path>,
) -> Result<(), String> {
    let input_ids: HashMap<PathBuf, &Path> = inputs
        .iter()
        .filter(|i| !is_dash(&i.path))
        .map(|i| (identity(&i.path), i.path.as_path()))
        .collect();
    let mut output_ids: HashMap<PathBuf, usize> = HashMap::new();
    for (i, output) in outputs.iter().enumerate() {
        if is_dash(output) {
            continue;
        }
        let id = identity(output);
        if let Some(input) = input_ids.get(&id) {
            return Err(format!(
                "the output {} would replace the input {}; choose another -o or --out-dir",
                output.display(),
                input.display()
            ));
        }
        if let Some(&first) = output_ids.get(&id) {
            return Err(format!(
                "{} and {} would both be written to {}; process them separately",
                inputs[first].path.display(),
                inputs[i].path.display(),
                output.display()
            ));
        }
        output_ids.insert(id, i);
    }
    if let Some(report) = report.filter(|r| !is_dash(r)) {
        let id = identity(report);
        if input_ids.contains_key(&id) || output_ids.contains_key(&id) {
            return Err(format!(
                "the report {} would replace an input or an output",
                report.display()
            ));
        }
    }
    Ok(())
}

/// A path to compare with others: the real path when it exists, else its real folder joined
/// with the name, else the path made absolute with `.` and `..` removed.
fn identity(path: &Path) -> PathBuf {
    if let Ok(real) = path.canonicalize() {
        return real;
    }
    if let (Some(parent), Some(name)) = (path.parent(), path.file_name()) {
        let parent = if parent.as_os_str().is_empty() {
            Path::new(".")
        } else {
            parent
        };
        if let Ok(real) = parent.canonicalize() {
            return real.join(name);
        }
    }
    let absolute = std::env::current_dir()
        .map(|d| d.join(path))
        .unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for component in absolute.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// An I/O error without Rust's "(os error 2)" suffix.
pub(crate) fn io_message(e: &std::io::Error) -> String {
    let text = e.to_string();
    match text.rfind(" (os error ") {
        Some(i) => text[..i].to_owned(),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_names() {
        assert!(is_scene_name("a.glb"));
        assert!(is_scene_name("a.GLTF"));
        assert!(is_scene_name("a.tspace.obj"));
        assert!(!is_scene_name("a.tspace.glb"));
        assert!(!is_scene_name("a.debug.gltf"));
        assert!(!is_scene_name("a.bin"));
        assert!(!is_scene_name("glb"));
    }

    #[test]
    fn outputs_beside_and_under_a_folder() {
        let input = Input {
            path: PathBuf::from("in/sub/x.obj"),
            relative: Some(PathBuf::from("sub/x.obj")),
        };
        assert_eq!(
            output_path(&input, &Destination::Beside, OutputFormat::Glb, false),
            PathBuf::from("in/sub/x.tspace.glb")
        );
        assert_eq!(
            output_path(
                &input,
                &Destination::Dir(PathBuf::from("out")),
                OutputFormat::GltfEmbedded,
                false
            ),
            PathBuf::from("out/sub/x.gltf")
        );
        assert_eq!(
            output_path(&input, &Destination::Beside, OutputFormat::Glb, true),
            PathBuf::from("in/sub/x.debug.glb")
        );
        assert_eq!(
            output_path(
                &input,
                &Destination::Dir(PathBuf::from("out")),
                OutputFormat::Glb,
                true
            ),
            PathBuf::from("out/sub/x.debug.glb")
        );
        let named = Input {
            path: PathBuf::from("x.glb"),
            relative: None,
        };
        assert_eq!(
            output_path(
                &named,
                &Destination::Dir(PathBuf::from("out")),
                OutputFormat::Glb,
                false
            ),
            PathBuf::from("out/x.glb")
        );
    }

    #[test]
    fn clashes_are_refused() {
        let a = Input {
            path: PathBuf::from("a/x.glb"),
            relative: None,
        };
        let b = Input {
            path: PathBuf::from("b/x.obj"),
            relative: None,
        };
        let out = vec![PathBuf::from("o/x.glb"), PathBuf::from("o/./x.glb")];
        assert!(check(&[&a, &b], &out, None).unwrap_err().contains("both"));
        assert!(check(&[&a], &[PathBuf::from("a/../a/x.glb")], None).is_err());
        assert!(check(&[&a, &b], &[out[0].clone(), PathBuf::from("o/y.glb")], None).is_ok());
    }
}
