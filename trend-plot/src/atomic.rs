//! A file that replaces its destination only when complete: written under a temporary
//! name in the destination's directory (same file system, so the rename is atomic) and
//! renamed by [`AtomicFile::commit`]. Dropped without a commit (an error, a port that
//! never opened), the temporary file is removed and whatever the user had under the
//! name is untouched. Shared by every output file option of hil-sim and plcctl (CSV,
//! EEPROM image, pulled program; the plot does the same through its own backends).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Result};

/// An output file being written.
pub struct AtomicFile {
    dest: PathBuf,
    tmp: PathBuf,
    file: Option<BufWriter<File>>,
}

/// `dir/.name.<pid>.partial`: next to the destination, hidden, never an existing file
/// (created with `create_new`).
fn temp_name(dest: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(".");
    name.push(dest.file_name().unwrap_or_default());
    name.push(format!(".{}.partial", std::process::id()));
    dest.with_file_name(name)
}

impl AtomicFile {
    /// Starts writing `dest`; fails (naming `dest`) when its directory is not writable
    /// or `dest` is a directory.
    pub fn create(dest: &Path) -> Result<AtomicFile> {
        if dest.file_name().is_none() || dest.is_dir() {
            return Err(anyhow!("cannot create {}: not a file name", dest.display()));
        }
        let tmp = temp_name(dest);
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| anyhow!("cannot create {}: {e}", dest.display()))?;
        Ok(AtomicFile {
            dest: dest.to_path_buf(),
            tmp,
            file: Some(BufWriter::new(file)),
        })
    }

    /// The destination's name (for messages).
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Flushes and renames the file to its destination.
    pub fn commit(mut self) -> Result<()> {
        let err = |e: &dyn std::fmt::Display| anyhow!("cannot write {}: {e}", self.dest.display());
        let Some(w) = self.file.take() else {
            return Err(err(&"already closed"));
        };
        let f = w.into_inner().map_err(|e| err(&e.error()))?;
        f.sync_all().map_err(|e| err(&e))?;
        drop(f);
        std::fs::rename(&self.tmp, &self.dest).map_err(|e| err(&e))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.file.as_mut() {
            Some(f) => f.write(buf),
            None => Err(std::io::ErrorKind::BrokenPipe.into()),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self.file.as_mut() {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        // Not committed (a commit takes the file): the temporary goes.
        if self.file.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes `bytes` to `path` through an [`AtomicFile`].
pub fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes)
        .map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
    f.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("atomic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn an_uncommitted_file_leaves_the_users_file_and_no_temporary() {
        let d = dir("drop");
        let keep = d.join("keep.csv");
        std::fs::write(&keep, "mine\n").unwrap();
        {
            let mut f = AtomicFile::create(&keep).unwrap();
            writeln!(f, "t_s,f_cmd_hz").unwrap();
            f.flush().unwrap();
            assert_eq!(std::fs::read_to_string(&keep).unwrap(), "mine\n");
        }
        assert_eq!(std::fs::read_to_string(&keep).unwrap(), "mine\n");
        assert_eq!(entries(&d), ["keep.csv"]);
    }

    #[test]
    fn a_commit_replaces_the_file_whole() {
        let d = dir("commit");
        let keep = d.join("keep.csv");
        std::fs::write(&keep, "mine\n").unwrap();
        let mut f = AtomicFile::create(&keep).unwrap();
        writeln!(f, "new").unwrap();
        f.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&keep).unwrap(), "new\n");
        assert_eq!(entries(&d), ["keep.csv"]);
        write(&d.join("b.bin"), &[1, 2]).unwrap();
        assert_eq!(std::fs::read(d.join("b.bin")).unwrap(), [1, 2]);
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_file() {
        let d = dir("missing");
        let e = AtomicFile::create(&d.join("no/such/x.csv")).err().unwrap();
        assert!(e.to_string().contains("x.csv"), "{e}");
        assert!(AtomicFile::create(&d).is_err());
    }
}
