//! Resolving a `.gltf`'s or `.obj`'s relative URIs against its own folder, for the command line.
//!
//! Only URIs that [`classify`] accepts as relative are read: no scheme, no absolute path, no `..`.
//! A symbolic link inside the folder that points out of it is refused too (the file's real path
//! must lie under the folder's real path). Files larger than the limit are refused before they
//! are read. The HTTP server never uses this: an upload's URIs resolve only to its own parts.

use super::gltf::load::Resources;
use super::uri::{LookedIn, PartSet, Refusal, UriError, UriKind, classify};
use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// A folder to resolve relative URIs in.
#[derive(Clone, Debug)]
pub struct Folder {
    base: PathBuf,
    max_file_bytes: u64,
}

impl Folder {
    /// `base` is the folder holding the main file.
    pub fn new(base: impl Into<PathBuf>, max_file_bytes: u64) -> Self {
        Folder {
            base: base.into(),
            max_file_bytes,
        }
    }

    /// The folder of `file` (the current folder for a bare file name).
    pub fn of_file(file: &Path, max_file_bytes: u64) -> Self {
        let base = match file.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        Self::new(base, max_file_bytes)
    }

    /// The bytes of the file `uri` names under the folder.
    pub fn read(&self, uri: &str) -> Result<Vec<u8>, UriError> {
        let refused = |reason| UriError::Refused {
            uri: uri.to_owned(),
            reason,
        };
        let missing = || UriError::MissingPart {
            uri: uri.to_owned(),
            looked_in: LookedIn::Folder,
        };
        let relative = match classify(uri) {
            UriKind::Relative(path) => path,
            UriKind::Data => return Err(refused(Refusal::NotAFile)),
            UriKind::Refused(reason) => return Err(refused(reason)),
        };
        let path = self.base.join(&relative);
        let (Ok(real), Ok(base)) = (path.canonicalize(), self.base.canonicalize()) else {
            return Err(missing());
        };
        if !real.starts_with(&base) {
            return Err(refused(Refusal::ParentSegment));
        }
        let metadata = std::fs::metadata(&real).map_err(|_| missing())?;
        if !metadata.is_file() {
            return Err(refused(Refusal::NotAFile));
        }
        if metadata.len() > self.max_file_bytes {
            return Err(UriError::FileTooLarge {
                uri: uri.to_owned(),
                limit: self.max_file_bytes,
            });
        }
        std::fs::read(&real).map_err(|_| missing())
    }

    /// Reads every file the URIs name that exists, as parts (for OBJ's MTL and images, whose
    /// names are known only after parsing). Names that cannot be read are left out; the scene
    /// layer then reports them as missing.
    pub fn read_all<'n>(&self, uris: impl IntoIterator<Item = &'n str>) -> Vec<(String, Vec<u8>)> {
        uris.into_iter()
            .filter_map(|u| self.read(u).ok().map(|bytes| (u.to_owned(), bytes)))
            .collect()
    }
}

impl<'a> Resources<'a> for Folder {
    fn fetch(&self, uri: &str) -> Result<Cow<'a, [u8]>, UriError> {
        self.read(uri).map(Cow::Owned)
    }

    /// Without reading it: an analysis asks only whether a texture is there.
    fn has(&self, uri: &str) -> bool {
        let UriKind::Relative(relative) = classify(uri) else {
            return false;
        };
        let (Ok(real), Ok(base)) = (
            self.base.join(relative).canonicalize(),
            self.base.canonicalize(),
        ) else {
            return false;
        };
        real.starts_with(&base) && real.is_file()
    }
}

/// Builds a [`PartSet`] over files already read.
pub fn parts_of(files: &[(String, Vec<u8>)]) -> PartSet<'_> {
    let mut parts = PartSet::new();
    for (name, bytes) in files {
        // Duplicate names cannot happen: the list comes from distinct URIs.
        let _ = parts.insert(name.clone(), bytes);
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixtures() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
    }

    #[test]
    fn reads_beside_the_file_and_refuses_escapes() {
        let folder = Folder::of_file(&fixtures().join("Avocado/Avocado.gltf"), 1 << 20);
        assert_eq!(folder.read("Avocado.bin").unwrap().len(), 23580);
        assert_eq!(folder.read("./Avocado.bin").unwrap().len(), 23580);
        for uri in [
            "../Box/Box.glb",
            "/etc/passwd",
            "file:///etc/passwd",
            "http://x/y.bin",
        ] {
            assert!(
                matches!(folder.read(uri), Err(UriError::Refused { .. })),
                "{uri}"
            );
        }
        assert!(matches!(
            folder.read("absent.bin"),
            Err(UriError::MissingPart { .. })
        ));
        let small = Folder::of_file(&fixtures().join("Avocado/Avocado.gltf"), 100);
        assert!(small.read("Avocado.bin").is_err());
        // `has` answers as `read` would, without reading.
        assert!(folder.has("./Avocado.bin"));
        assert!(!folder.has("absent.png"));
        assert!(!folder.has("../Box/Box.glb"));
        assert!(!folder.has("/etc/passwd"));
    }

    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_out_of_the_folder_is_refused() {
        let dir = std::env::temp_dir().join(format!("tspace-folder-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::os::unix::fs::symlink(fixtures().join("Box/Box.glb"), dir.join("link.bin")).unwrap();
        let folder = Folder::new(&dir, 1 << 20);
        let result = folder.read("link.bin");
        let _ = std::fs::remove_dir_all(&dir);
        assert!(
            matches!(result, Err(UriError::Refused { .. })),
            "{result:?}"
        );
    }
}
