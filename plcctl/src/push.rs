//! `push x.plc --slot n [--yes]` (service.md 8): assemble and verify the file, show a
//! unified diff of the canonical texts against what the slot holds, ask (unless `--yes`;
//! refused when stdin is not a terminal), write it (`WriteBegin`, chunks, `WriteCommit`),
//! then pull the slot back and compare byte for byte. Without remote service, or with the
//! PLC not in STOP, it stops before the diff (exit 5).

use std::io::{BufRead, IsTerminal, Write};
use std::path::Path;

use shared_protocol::link::frame::CRC as CRC32C;
use shared_protocol::program::payload::{for_each_payload_byte, program_from_payload};
use shared_protocol::program::{assemble_runnable, disassemble, Program};
use shared_protocol::service::{
    Answer, InvalidReason, PlcState, RefuseReason, Request, WriteResult, CHUNK_BYTES,
};

use crate::client::{unexpected, Client};
use crate::diff::unified;
use crate::fail::{Fail, Result};
use crate::program::read_payload;
use crate::usage;

fn canonical(p: &Program) -> Result<String> {
    let mut text = String::new();
    disassemble(p, &mut text).map_err(|_| usage("cannot format the program"))?;
    Ok(text)
}

/// The slot's program as canonical text (empty for an empty slot).
fn current_text(c: &mut Client, slot: u8) -> Result<String> {
    let payload = match read_payload(c, slot) {
        Ok(p) => p,
        Err(Fail::Refused(RefuseReason::Slot)) => return Ok(String::new()),
        Err(e) => return Err(e),
    };
    let mut p = Program::default();
    if !program_from_payload(&payload, &mut p) {
        return Err(usage(format!(
            "slot {slot}: the PLC sent a payload that does not decode"
        )));
    }
    canonical(&p)
}

/// Asks on the terminal; `false` unless the answer is yes.
fn confirm(question: &str) -> Result<bool> {
    let stdin = std::io::stdin();
    if !stdin.is_terminal() {
        return Err(usage(
            "confirmation refused: stdin is not a terminal (use --yes)",
        ));
    }
    print!("{question} [y/N] ");
    std::io::stdout().flush()?;
    let mut line = String::new();
    stdin.lock().read_line(&mut line)?;
    Ok(matches!(line.trim(), "y" | "Y" | "yes" | "YES"))
}

pub fn push(connect: impl Fn() -> Result<Client>, file: &Path, slot: u8, yes: bool) -> Result<()> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| usage(format!("cannot read {}: {e}", file.display())))?;
    let program = assemble_runnable(&text).map_err(|e| usage(format!("{}:{e}", file.display())))?;
    let mut payload = Vec::new();
    for_each_payload_byte(&program, |b| payload.push(b));

    let mut c = connect()?;
    // What the PLC would refuse is said before a diff the user would read for nothing
    // (the PLC checks again at `WriteBegin`).
    let status = match c.ask(Request::GetStatus)? {
        Answer::Status(s) => s,
        other => return Err(unexpected("GetStatus", &other)),
    };
    if !status.remote {
        return Err(Fail::Refused(RefuseReason::Locked));
    }
    if status.plc != PlcState::Stop {
        return Err(Fail::Refused(RefuseReason::InRun));
    }
    let old = current_text(&mut c, slot)?;
    let new = canonical(&program)?;
    let diff = unified(
        &format!("slot {slot} (PLC)"),
        &file.display().to_string(),
        &old,
        &new,
    );
    if diff.is_empty() {
        println!("slot {slot} already holds this program (written again)");
    } else {
        print!("{diff}");
    }
    if !yes && !confirm(&format!("write {} into slot {slot}?", file.display()))? {
        return Err(usage("confirmation refused"));
    }

    let begin = Request::WriteBegin {
        slot,
        len: payload.len() as u16,
        crc: CRC32C.checksum(&payload),
    };
    match c.ask(begin)? {
        Answer::Done => {}
        other => return Err(unexpected("WriteBegin", &other)),
    }
    for (k, chunk) in payload.chunks(CHUNK_BYTES).enumerate() {
        let req = Request::WriteChunk {
            offset: (k * CHUNK_BYTES) as u16,
            data: chunk.iter().copied().collect(),
        };
        match c.ask(req)? {
            Answer::Done => {}
            other => return Err(unexpected("WriteChunk", &other)),
        }
    }
    let generation = match c.ask(Request::WriteCommit)? {
        Answer::WriteResult(WriteResult::Saved { generation }) => generation,
        Answer::WriteResult(WriteResult::Invalid { line, reason }) => {
            return Err(usage(format!(
                "the PLC refused the program at line {line:03}: {}",
                invalid_text(reason)
            )))
        }
        // The PLC's own check of what arrived (CRC-32C, completeness) failed: what it
        // holds differs from what was sent, as a read-back that differs (exit 6).
        Answer::WriteResult(w) => {
            let why = match w {
                WriteResult::Crc => "its CRC-32C differs",
                _ => "a chunk is missing",
            };
            return Err(Fail::ReadBack(format!(
                "the PLC did not receive the program whole ({why}): nothing was written"
            )));
        }
        other => return Err(unexpected("WriteCommit", &other)),
    };
    let back = read_payload(&mut c, slot)?;
    if back != payload {
        return Err(Fail::ReadBack(format!(
            "slot {slot} reads back {} bytes that differ from the {} written",
            back.len(),
            payload.len()
        )));
    }
    println!("written into slot {slot} (generation {generation}), read back: identical");
    Ok(())
}

/// Why the PLC's verifier refused a line, in words.
fn invalid_text(r: InvalidReason) -> String {
    match r {
        InvalidReason::Verify(code) => {
            // `shared_protocol::link::message::verify_kind_code`'s numbers.
            let what = match code {
                1 => "line number out of range",
                2 => "instruction of the other section",
                3 => "operand missing",
                4 => "operand not allowed",
                5 => "operand of the wrong kind",
                6 => "LDC on an integer operand",
                7 => "operand out of range",
                8 => "constant out of range",
                9 => "constant without K",
                10 => "stack underflow",
                11 => "setting given twice",
                12 | 13 => "safety function without what it needs",
                _ => "refused by the verifier",
            };
            format!("{what} (verifier check {code})")
        }
        InvalidReason::Decode => "its bytes are not an instruction".into(),
        InvalidReason::Layout => "the program's lines are out of order or overlap".into(),
    }
}
