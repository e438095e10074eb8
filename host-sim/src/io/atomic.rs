//! Output files that appear complete or not at all.
//!
//! An [`AtomicFile`] writes to a temporary file (tempfile's) beside the target and renames it
//! over the target on [`AtomicFile::commit`]; a rename within one directory is atomic, so
//! readers (and scripts that test for the file) never see a half-written output. Dropping an
//! uncommitted file removes the temporary, so a command that fails leaves nothing behind.

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

use super::{describe_io_error, OutputError};

/// A file being written to a temporary beside its target path.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    writer: BufWriter<NamedTempFile>,
}

impl AtomicFile {
    /// Starts writing `target`: creates the temporary in the target's directory.
    ///
    /// Fails now, before any work is done, when the target cannot be written: its directory is
    /// missing or read-only, or the target is a directory.
    pub fn create(target: &Path) -> Result<Self, OutputError> {
        let Some(name) = target.file_name() else {
            return Err(OutputError::new(target, "not a file name"));
        };
        if target.is_dir() {
            return Err(OutputError::new(target, "is a directory"));
        }
        let directory = match target.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        let mut prefix = std::ffi::OsString::from(".");
        prefix.push(name);
        prefix.push(".");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        // tempfile makes its files private (0600); outputs are ordinary files, readable by all
        // like those of `cp` under the usual umask.
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
        let temp = builder.tempfile_in(directory).map_err(|e| match e.kind() {
            // The temporary's name would only confuse: say what the user can fix.
            io::ErrorKind::NotFound => OutputError::new(
                target,
                format!(
                    "cannot write: directory {} does not exist",
                    directory.display()
                ),
            ),
            _ => OutputError::new(target, format!("cannot write: {}", describe_io_error(&e))),
        })?;
        Ok(Self {
            target: target.to_path_buf(),
            writer: BufWriter::new(temp),
        })
    }

    /// The path the file will have once committed.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Turns an error from writing this file into an [`OutputError`] naming the target.
    pub fn write_error(&self, error: &io::Error) -> OutputError {
        OutputError::new(
            &self.target,
            format!("cannot write: {}", describe_io_error(error)),
        )
    }

    /// Flushes the data to disk and renames the temporary over the target. On an error the
    /// temporary is removed (nothing useful is left in it).
    pub fn commit(self) -> Result<(), OutputError> {
        let target = self.target;
        let error = |e: &io::Error| {
            OutputError::new(&target, format!("cannot write: {}", describe_io_error(e)))
        };
        let temp = self.writer.into_inner().map_err(|e| error(e.error()))?;
        temp.as_file().sync_all().map_err(|e| error(&e))?;
        temp.persist(&target).map_err(|e| error(&e.error))?;
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }
}

/// Writes `contents` to `target` atomically.
pub fn write_atomically(target: &Path, contents: &[u8]) -> Result<(), OutputError> {
    let mut file = AtomicFile::create(target)?;
    file.write_all(contents).map_err(|e| file.write_error(&e))?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    fn scratch_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("host-sim-atomic-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn commit_replaces_the_target_and_leaves_no_temporary() {
        let dir = scratch_dir("commit");
        let target = dir.join("out.csv");
        fs::write(&target, "old").unwrap();
        write_atomically(&target, b"new").unwrap();
        assert_eq!(fs::read_to_string(&target).unwrap(), "new");
        assert_eq!(entries(&dir), ["out.csv"]);
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn dropping_without_commit_writes_nothing() {
        let dir = scratch_dir("drop");
        let target = dir.join("out.csv");
        {
            let mut file = AtomicFile::create(&target).unwrap();
            file.write_all(b"partial").unwrap();
        }
        assert!(entries(&dir).is_empty());
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn unwritable_targets_fail_at_creation() {
        let dir = scratch_dir("unwritable");
        let missing = dir.join("no-such-dir").join("out.csv");
        let error = AtomicFile::create(&missing).unwrap_err();
        assert!(
            error.to_string().ends_with("no-such-dir does not exist"),
            "{error}"
        );
        assert!(AtomicFile::create(&dir).is_err());
        fs::remove_dir_all(dir).unwrap();
    }
}
