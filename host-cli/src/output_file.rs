//! Output files, checked before a long run: a path that cannot be written is a usage error
//! (exit 2) at once, not after an hour of simulation or of a board's recording.
//!
//! Two checks, for two kinds of output:
//! - [`create`]: the file is created (truncated) now and its handle kept, for outputs written
//!   as the run goes or at its end (CSVs, SVGs of `sweep`, `record`, `stream`). A pipe or a
//!   device such as `/dev/stdout` works as well as a file.
//! - [`check_folder`]: only that the folder exists, for outputs of a command that must change
//!   nothing when its input turns out to be bad (`rlg-sim allan`).

use crate::Failure;
use std::fs::File;
use std::path::{Path, PathBuf};

/// An output file created before the run, with the path it was created at (for messages).
#[derive(Debug)]
pub struct Output {
    /// Where it is.
    pub path: PathBuf,
    /// The file, open for writing, empty.
    pub file: File,
}

/// Creates (truncates) `path`; a path that cannot be created is [`Failure::Usage`].
pub fn create(path: &Path) -> Result<Output, Failure> {
    File::create(path)
        .map(|file| Output {
            path: path.to_owned(),
            file,
        })
        .map_err(|e| Failure::Usage(format!("cannot create {}: {e}", path.display())))
}

/// [`create`] for an optional output.
pub fn create_optional(path: Option<&Path>) -> Result<Option<Output>, Failure> {
    path.map(create).transpose()
}

/// Checks that the folder `path` would be written in exists (creating nothing);
/// [`Failure::Usage`] if not.
pub fn check_folder(path: &Path) -> Result<(), Failure> {
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if folder.is_dir() {
        Ok(())
    } else {
        Err(Failure::Usage(format!(
            "cannot write {}: no folder {}",
            path.display(),
            folder.display()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file in a missing folder: both checks refuse it as usage (exit 2) and name it; a
    /// writable path is created empty by `create` and left alone by `check_folder`.
    #[test]
    fn a_path_in_a_missing_folder_is_a_usage_error() {
        let dir = std::env::temp_dir().join(format!("host-cli-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("no-such-folder").join("out.csv");
        for failure in [
            create(&missing).unwrap_err(),
            check_folder(&missing).unwrap_err(),
        ] {
            assert_eq!(failure.status(), 2);
            assert!(failure.message().unwrap().contains("no-such-folder"));
        }
        let fine = dir.join("out.csv");
        check_folder(&fine).unwrap();
        assert!(!fine.exists(), "check_folder creates nothing");
        std::fs::write(&fine, "old").unwrap();
        let out = create(&fine).unwrap();
        assert_eq!(
            (out.path.as_path(), std::fs::read(&fine).unwrap().len()),
            (fine.as_path(), 0)
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
