//! Loading a firmware ELF: the flash image from its loadable segments (by physical
//! address, so `.data`'s initial values land where the startup code copies them from),
//! and the symbols the emulator needs (RTT control block, function names for reports).

use std::path::Path;

use anyhow::{bail, Context, Result};
use object::read::elf::{ElfFile32, FileHeader, ProgramHeader};
use object::{Object, ObjectSymbol};

use crate::soc::{FLASH_BASE, FLASH_BYTES};

/// A loaded image.
pub struct Image {
    /// Flash contents from 0x0800_0000 (erased bytes 0xFF).
    pub flash: Vec<u8>,
    /// The raw ELF (for the defmt table).
    pub elf: Vec<u8>,
    /// Address of `_SEGGER_RTT`, if the image has RTT.
    pub rtt: Option<u32>,
    /// Function symbols sorted by address: (start, size, name).
    pub functions: Vec<(u32, u32, String)>,
}

impl Image {
    /// Reads and loads `path`.
    pub fn load(path: &Path) -> Result<Image> {
        let elf = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        Image::from_bytes(elf)
            .with_context(|| format!("{} is not a G431 firmware ELF", path.display()))
    }

    /// Loads an ELF held in memory.
    pub fn from_bytes(elf: Vec<u8>) -> Result<Image> {
        let file = ElfFile32::<object::Endianness>::parse(&*elf).context("not a 32-bit ELF")?;
        if file.architecture() != object::Architecture::Arm {
            bail!("not an ARM ELF");
        }
        let endian = file.endian();
        let mut flash = vec![0xFFu8; FLASH_BYTES];
        let mut loaded = 0usize;
        for ph in file.elf_header().program_headers(endian, &*elf)? {
            if ph.p_type(endian) != object::elf::PT_LOAD || ph.p_filesz(endian) == 0 {
                continue;
            }
            let paddr = ph.p_paddr(endian);
            let data = ph
                .data(endian, &*elf)
                .map_err(|()| anyhow::anyhow!("segment data out of the file"))?;
            let off = paddr
                .checked_sub(FLASH_BASE)
                .map(|o| o as usize)
                .filter(|o| o + data.len() <= FLASH_BYTES)
                .with_context(|| format!("segment at {paddr:#010x} is not in the 128 KiB flash"))?;
            flash
                .get_mut(off..off + data.len())
                .context("segment out of flash")?
                .copy_from_slice(data);
            loaded += data.len();
        }
        if loaded == 0 {
            bail!("no loadable segment");
        }
        let mut rtt = None;
        let mut functions = Vec::new();
        for sym in file.symbols() {
            let Ok(name) = sym.name() else { continue };
            if name == "_SEGGER_RTT" {
                rtt = Some(sym.address() as u32);
            }
            if sym.kind() == object::SymbolKind::Text && sym.size() > 0 {
                functions.push((
                    (sym.address() as u32) & !1,
                    sym.size() as u32,
                    name.to_string(),
                ));
            }
        }
        functions.sort();
        Ok(Image {
            flash,
            elf,
            rtt,
            functions,
        })
    }

    /// The flash bytes of the data symbol `name` (a `static` the image places in flash, e.g.
    /// a marker the host reads); `None` when the image has no such symbol or it is not in
    /// flash.
    pub fn flash_symbol(&self, name: &str) -> Option<&[u8]> {
        let file = ElfFile32::<object::Endianness>::parse(&*self.elf).ok()?;
        let sym = file.symbols().find(|s| s.name() == Ok(name))?;
        let start = (sym.address() as u32).checked_sub(FLASH_BASE)? as usize;
        self.flash.get(start..start + sym.size() as usize)
    }

    /// The function containing `pc`, demangled enough to read (`name+0x12`).
    pub fn symbolize(&self, pc: u32) -> String {
        let k = self.functions.partition_point(|(a, _, _)| *a <= pc);
        match k.checked_sub(1).and_then(|k| self.functions.get(k)) {
            Some((a, len, name)) if pc < a + len => format!("{}+{:#x}", demangle(name), pc - a),
            _ => format!("{pc:#010x}"),
        }
    }
}

/// Shortens a Rust v0/legacy mangled name to its path (no hash), without a demangler
/// dependency: `_ZN12embassy_stm323rcc2g44init17h..E` → `embassy_stm32::rcc::g4::init`.
fn demangle(name: &str) -> String {
    let Some(rest) = name.strip_prefix("_ZN") else {
        return name.to_string();
    };
    let b = rest.as_bytes();
    let mut i = 0;
    let mut parts = Vec::new();
    while i < b.len() && b[i].is_ascii_digit() {
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        let n: usize = rest[start..i].parse().unwrap_or(0);
        let part = rest.get(i..i + n).unwrap_or("");
        i += n;
        if !(part.len() == 17 && part.starts_with('h')) {
            parts.push(
                part.replace("$LT$", "<")
                    .replace("$GT$", ">")
                    .replace("$u20$", " ")
                    .replace("..", "::"),
            );
        }
    }
    if parts.is_empty() {
        name.to_string()
    } else {
        parts.join("::")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demangles_legacy_names() {
        assert_eq!(
            demangle("_ZN13embassy_stm323rcc2g44init17h0123456789abcdefE"),
            "embassy_stm32::rcc::g4::init"
        );
        assert_eq!(demangle("main"), "main");
    }

    #[test]
    fn rejects_what_is_not_an_elf() {
        assert!(Image::from_bytes(b"not an elf".to_vec()).is_err());
    }
}
