//! `pull`: a program read chunk by chunk (service.md 3 "Program transfer") and printed as
//! canonical text, byte for byte what `hil-sim disasm` prints.

use std::path::Path;

use shared_protocol::link::frame::CRC as CRC32C;
use shared_protocol::program::payload::program_from_payload;
use shared_protocol::program::{disassemble, Program};
use shared_protocol::service::{Answer, Request, CHUNK_BYTES};

use crate::client::{unexpected, Client};
use crate::fail::Result;
use crate::usage;

/// Restarts allowed when the program changes under the reader.
const RESTARTS: usize = 3;

/// The payload of `slot` (0: RAM), its CRC checked; restarted when the generation or the
/// CRC changes between chunks.
pub fn read_payload(c: &mut Client, slot: u8) -> Result<Vec<u8>> {
    'again: for _ in 0..RESTARTS {
        let mut bytes = Vec::new();
        let mut first: Option<(u32, u32, u16)> = None;
        loop {
            let offset = bytes.len() as u16;
            let chunk = match c.ask(Request::ReadProgram { slot, offset })? {
                Answer::ProgramChunk(ch) => ch,
                other => return Err(unexpected("ReadProgram", &other)),
            };
            let key = (chunk.generation, chunk.crc, chunk.len);
            if *first.get_or_insert(key) != key || chunk.offset != offset {
                continue 'again;
            }
            bytes.extend_from_slice(&chunk.data);
            if bytes.len() >= usize::from(chunk.len) || chunk.data.len() < CHUNK_BYTES {
                bytes.truncate(usize::from(chunk.len));
                if CRC32C.checksum(&bytes) != chunk.crc {
                    continue 'again;
                }
                return Ok(bytes);
            }
        }
    }
    Err(usage(format!(
        "slot {slot} kept changing while it was read ({RESTARTS} attempts)"
    )))
}

pub fn pull(c: &mut Client, slot: u8, output: Option<&Path>) -> Result<()> {
    let payload = read_payload(c, slot)?;
    let mut program = Program::default();
    if !program_from_payload(&payload, &mut program) {
        return Err(usage(format!(
            "slot {slot}: the PLC sent a payload that does not decode"
        )));
    }
    let mut text = String::new();
    disassemble(&program, &mut text).map_err(|_| usage("cannot format the program"))?;
    match output {
        // Under a temporary name, renamed when whole: a failed write keeps the user's file.
        Some(p) => trend_plot::atomic::write(p, text.as_bytes()).map_err(usage)?,
        None => print!("{text}"),
    }
    Ok(())
}
