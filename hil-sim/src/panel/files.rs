//! The panel's files: the EEPROM image that keeps the saved slots between sessions
//! (`--eeprom FILE`) and programs exported as `.plc` text.
//!
//! Both are written to `<name>.tmp` and renamed over the target, so a crash or a full
//! disk while writing leaves the previous file whole: never a truncated image.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use firmware_plc::storage::EEPROM_BYTES;
use shared_protocol::program::{disassemble, Program};

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    if let Err(e) = std::fs::rename(&tmp, path) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("cannot replace {}", path.display()));
    }
    Ok(())
}

/// Reads the 24C256 image at `path`: `None` when there is no such file; an error when it
/// cannot be read or is not exactly 32 KiB (the file is left as it is).
pub fn read_eeprom_image(path: &Path) -> Result<Option<Vec<u8>>> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
    };
    if bytes.len() != EEPROM_BYTES {
        anyhow::bail!(
            "{}: {} bytes, not a 24C256 image ({} bytes, as `hil-sim asm -o` writes); \
             left unchanged",
            path.display(),
            bytes.len(),
            EEPROM_BYTES
        );
    }
    Ok(Some(bytes))
}

/// The program as `.plc` text (canonical form, `hil-sim disasm`'s), with a header line.
pub fn program_text(program: &Program) -> String {
    let mut text = String::from("; exported from the hil-sim panel\n");
    // Writing into a String cannot fail.
    let _ = disassemble(program, &mut text);
    text
}

/// A file name for an export that does not exist yet: `<stem>-panel.plc`, then
/// `<stem>-panel-2.plc`, ... in `dir`.
pub fn export_name(dir: &Path, stem: &str) -> PathBuf {
    let first = dir.join(format!("{stem}-panel.plc"));
    if !first.exists() {
        return first;
    }
    (2..1000)
        .map(|n| dir.join(format!("{stem}-panel-{n}.plc")))
        .find(|p| !p.exists())
        .unwrap_or(first)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_of_the_wrong_size_is_refused_and_left_alone() {
        let dir = std::env::temp_dir().join(format!("hil-sim-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("short.bin");
        std::fs::write(&path, b"not an eeprom").unwrap();
        let e = read_eeprom_image(&path).unwrap_err().to_string();
        assert!(
            e.contains("13 bytes, not a 24C256 image (32768 bytes"),
            "{e}"
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"not an eeprom");
        assert!(read_eeprom_image(&dir.join("absent.bin"))
            .unwrap()
            .is_none());
        write_atomically(&path, &[0xFF; EEPROM_BYTES]).unwrap();
        assert_eq!(
            read_eeprom_image(&path).unwrap().unwrap().len(),
            EEPROM_BYTES
        );
        assert!(!dir.join("short.bin.tmp").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
