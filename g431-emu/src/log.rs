//! The images' defmt logs: the emulator drains the RTT up-buffer as a probe does (reads
//! WrOff, copies the bytes, writes RdOff back), and decodes the frames with the ELF's defmt
//! table. Each line gets the virtual time at which it was drained (at most one run slice
//! after the firmware wrote it) next to the firmware's own timestamp.

use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

use defmt_decoder::{DecodeError, StreamDecoder, Table};

use crate::soc::{Soc, RAM_BASE};
use crate::time::{cycles_to_ns, Cycles};

/// One decoded log line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogLine {
    /// Virtual time at which the emulator read it.
    pub at: Cycles,
    /// `INFO`, `WARN`, ... (empty for println-style frames).
    pub level: String,
    /// The firmware's timestamp, as defmt formats it (embassy uptime).
    pub timestamp: String,
    pub message: String,
}

impl std::fmt::Display for LogLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ns = cycles_to_ns(self.at);
        write!(
            f,
            "{:>4}.{:06} {:<5} {}",
            ns / 1_000_000_000,
            (ns / 1000) % 1_000_000,
            self.level,
            self.message
        )
    }
}

/// Tables parsed once per distinct ELF and kept for the life of the process (a decoder
/// borrows its table).
fn table_for(elf: &[u8]) -> Option<&'static Table> {
    static TABLES: OnceLock<Mutex<HashMap<u64, &'static Table>>> = OnceLock::new();
    let key = {
        // FNV-1a over the ELF: cheap and stable.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in elf {
            h = (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3);
        }
        h
    };
    let map = TABLES.get_or_init(|| Mutex::new(HashMap::new()));
    let mut map = map.lock().ok()?;
    if let Some(t) = map.get(&key) {
        return Some(t);
    }
    let table = Table::parse(elf).ok().flatten()?;
    let leaked: &'static Table = Box::leak(Box::new(table));
    map.insert(key, leaked);
    Some(leaked)
}

/// The RTT channel 0 of one image and its decoder.
pub struct DefmtLog {
    rtt: Option<u32>,
    decoder: Option<Box<dyn StreamDecoder + Send + Sync + 'static>>,
    lines: Vec<LogLine>,
    /// Bytes the decoder could not make sense of (a corrupted stream).
    pub malformed: usize,
}

impl DefmtLog {
    /// For an image whose `_SEGGER_RTT` is at `rtt`, with `elf` for the table.
    pub fn new(elf: &[u8], rtt: Option<u32>) -> Self {
        DefmtLog {
            rtt,
            decoder: table_for(elf).map(|t| t.new_stream_decoder()),
            lines: Vec::new(),
            malformed: 0,
        }
    }

    /// Reads what the firmware wrote since the last call and decodes it.
    pub fn drain(&mut self, soc: &mut Soc) {
        let Some(cb) = self.rtt else {
            return;
        };
        // Control block: "SEGGER RTT\0..." (16), MaxNumUpBuffers, MaxNumDownBuffers, then
        // up-buffer 0: name, pBuffer, SizeOfBuffer, WrOff, RdOff, Flags.
        let up = cb + 24;
        let (Some(buf), Some(size), Some(wr), Some(rd)) = (
            soc.mem_word(up + 4),
            soc.mem_word(up + 8),
            soc.mem_word(up + 12),
            soc.mem_word(up + 16),
        ) else {
            return;
        };
        if size == 0 || wr == rd || wr >= size || rd >= size || buf < RAM_BASE {
            return;
        }
        let mut bytes = Vec::new();
        let mut r = rd;
        while r != wr {
            let o = (buf + r - RAM_BASE) as usize;
            if let Some(b) = soc.ram.get(o) {
                bytes.push(*b);
            }
            r = (r + 1) % size;
        }
        soc.set_ram_word(up + 16, wr);
        let at = soc.now;
        let Some(dec) = self.decoder.as_mut() else {
            return;
        };
        dec.received(&bytes);
        loop {
            match dec.decode() {
                Ok(frame) => self.lines.push(LogLine {
                    at,
                    level: frame
                        .level()
                        .map(|l| format!("{l:?}").to_uppercase())
                        .unwrap_or_default(),
                    timestamp: frame
                        .display_timestamp()
                        .map(|t| t.to_string())
                        .unwrap_or_default(),
                    message: frame.display_message().to_string(),
                }),
                Err(DecodeError::UnexpectedEof) => break,
                Err(DecodeError::Malformed) => {
                    self.malformed += 1;
                    break;
                }
            }
        }
    }

    /// Every line so far.
    pub fn lines(&self) -> &[LogLine] {
        &self.lines
    }

    /// Lines from index `from` on (for printing as they come).
    pub fn since(&self, from: usize) -> &[LogLine] {
        self.lines.get(from..).unwrap_or(&[])
    }
}
