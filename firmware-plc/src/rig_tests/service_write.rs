//! Program writes over the service port (service.md 3 "Program transfer", 10): every
//! answer and refusal, a repeated commit executed once, the event `PGMSVC`, and the old
//! or the new program loadable, never a mix, whatever cuts the write: the power at every
//! byte, the cable at every chunk, a new `WriteBegin`, RUN on the keypad, a keypad save.

use super::service_support::*;
use crate::app::RunState;
use crate::editor::Key;
use crate::storage::{MemEeprom, Storage, StorageError};
use shared_protocol::link::message::verify_kind_code;
use shared_protocol::program::{encode_line, verify, Program};
use shared_protocol::service::{InvalidReason, WriteResult, EVENT_PROGRAM_WRITTEN};

/// Slot 1 holds SMALL (both copies), loaded into RAM; remote service on.
fn rig_with_small_in_slot_1() -> Rig {
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &assemble(SMALL).unwrap()).unwrap();
    let mut rig = Rig::with_eeprom(s.into_eeprom());
    rig.keys(&[Key::D, Key::Digit(1)]);
    rig.run_ms(300);
    assert_eq!(rig.plc.editor().loaded_slot(), Some(1));
    rig.hello_remote();
    rig
}

/// What a load of `slot` finds in the EEPROM as it is now (a fresh power-up's view).
fn stored(e: &MemEeprom, slot: u8) -> Result<Program, StorageError> {
    let mut e = e.clone();
    e.restore_power();
    let mut p = Program::default();
    Storage::new(e).load(slot, &mut p).map(|_| p)
}

fn events(rig: &Rig, code: u8) -> usize {
    rig.plc
        .fault_log()
        .iter()
        .filter(|e| e.code == code)
        .count()
}

#[test]
fn a_written_program_is_saved_loaded_logged_and_shown() {
    let mut rig = rig_with_small_in_slot_1();
    let motor = assemble(MOTOR).unwrap();
    let bytes = payload(&motor);
    assert_eq!(
        rig.push(1, &bytes),
        Answer::WriteResult(WriteResult::Saved { generation: 2 })
    );
    rig.run_ms(300);
    // RAM held slot 1 without edits: the new program is loaded.
    assert_eq!(rig.plc.program(), &motor);
    assert!(!rig.plc.editor().modified());
    assert!(
        rig.screen.to_string().contains("SLOT 1 WRITTEN (SVC)"),
        "{}",
        rig.screen
    );
    assert_eq!(events(&rig, EVENT_PROGRAM_WRITTEN), 1);
    // Both copies hold it: pull gives it back, a power-up loads it.
    let (data, _, generation) = pull(&mut rig, 1);
    assert_eq!((data, generation), (bytes.clone(), 2));
    assert_eq!(stored(rig.plc.storage().eeprom(), 1), Ok(motor.clone()));

    // Another slot, with edits in RAM: saved, RAM untouched.
    rig.plc.replace_program(&assemble(SMALL).unwrap());
    assert_eq!(
        rig.push(3, &bytes),
        Answer::WriteResult(WriteResult::Saved { generation: 1 })
    );
    rig.run_ms(300);
    assert_eq!(rig.plc.program(), &assemble(SMALL).unwrap());
    assert!(rig.screen.to_string().contains("SLOT 3 WRITTEN (SVC)"));
    assert_eq!(events(&rig, EVENT_PROGRAM_WRITTEN), 2);
    assert_eq!(stored(rig.plc.storage().eeprom(), 3), Ok(motor));

    // An empty program is a program too.
    assert_eq!(
        rig.push(4, &[]),
        Answer::WriteResult(WriteResult::Saved { generation: 1 })
    );
    assert_eq!(
        stored(rig.plc.storage().eeprom(), 4),
        Ok(Program::default())
    );
}

#[test]
fn every_refusal_of_a_write() {
    let mut rig = rig_with_small_in_slot_1();
    let small = payload(&assemble(SMALL).unwrap());
    let chunk = |offset: u16, data: &[u8]| Request::WriteChunk {
        offset,
        data: data.iter().copied().collect(),
    };
    let refused = |r| Answer::Refused(r);
    // Out of sequence.
    assert_eq!(rig.ask(chunk(0, &small)), refused(RefuseReason::Transfer));
    assert_eq!(
        rig.ask(Request::WriteCommit),
        refused(RefuseReason::Transfer)
    );
    // No such slot, too long.
    for slot in [0, 5] {
        let req = Request::WriteBegin {
            slot,
            len: 4,
            crc: 0,
        };
        assert_eq!(rig.ask_long(req), refused(RefuseReason::Slot));
    }
    let req = Request::WriteBegin {
        slot: 2,
        len: 4017,
        crc: 0,
    };
    assert_eq!(rig.ask_long(req), refused(RefuseReason::Transfer));
    // A 100-byte transfer: chunks at 0 (64 bytes) and 64 (36 bytes) only.
    let data: Vec<u8> = (0..100u8).collect();
    let req = Request::WriteBegin {
        slot: 2,
        len: 100,
        crc: 0,
    };
    assert_eq!(rig.ask_long(req), Answer::Done);
    assert_eq!(
        rig.ask(chunk(1, &data[..64])),
        refused(RefuseReason::Transfer)
    );
    assert_eq!(
        rig.ask(chunk(128, &data[..4])),
        refused(RefuseReason::Transfer)
    );
    assert_eq!(
        rig.ask(chunk(0, &data[..63])),
        refused(RefuseReason::Transfer)
    );
    assert_eq!(
        rig.ask(chunk(64, &data[64..99])),
        refused(RefuseReason::Transfer)
    );
    assert_eq!(rig.ask_long(chunk(64, &data[64..])), Answer::Done);
    // Chunk 0 missing.
    assert_eq!(
        rig.ask_long(Request::WriteCommit),
        Answer::WriteResult(WriteResult::Incomplete)
    );
    // Complete, but not the announced CRC.
    assert_eq!(rig.ask_long(chunk(0, &data[..64])), Answer::Done);
    assert_eq!(
        rig.ask_long(Request::WriteCommit),
        Answer::WriteResult(WriteResult::Crc)
    );
    assert_eq!(
        stored(rig.plc.storage().eeprom(), 2),
        Err(StorageError::Empty(2))
    );

    // The right CRC, but not a program: the runs' layout, an undecodable line, a line
    // the verifier refuses.
    let layout = [0x00, 0x05, 0x00]; // a run of 0 lines
    assert_eq!(
        rig.push(2, &layout),
        Answer::WriteResult(WriteResult::Invalid {
            line: 5,
            reason: InvalidReason::Layout
        })
    );
    let undecodable = [0x00, 0x96, 0x01, 0xFF, 0xFF, 0xFF, 0xFF];
    assert_eq!(
        rig.push(2, &undecodable),
        Answer::WriteResult(WriteResult::Invalid {
            line: 150,
            reason: InvalidReason::Decode
        })
    );
    // `ADD` as the drive section's first line (an empty stack): what RUN refuses.
    let mut bad = Program::default();
    bad.lines[0] = assemble("150 ADD K01 0001\n").unwrap().lines[150];
    let err = verify(&bad).unwrap_err();
    let mut bytes = vec![0x00, 0x00, 0x01];
    bytes.extend_from_slice(&encode_line(&bad.lines[0].unwrap()));
    assert_eq!(
        rig.push(2, &bytes),
        Answer::WriteResult(WriteResult::Invalid {
            line: err.line,
            reason: InvalidReason::Verify(verify_kind_code(&err.kind))
        })
    );
    assert_eq!(
        stored(rig.plc.storage().eeprom(), 2),
        Err(StorageError::Empty(2))
    );
    assert_eq!(events(&rig, EVENT_PROGRAM_WRITTEN), 0);

    // In RUN: begin, chunk and commit refused.
    let req = write_begin(2, &small);
    assert_eq!(rig.ask_long(req.clone()), Answer::Done);
    rig.keys(&[Key::A]);
    assert_ne!(rig.plc.run_state(), RunState::Stopped);
    assert_eq!(rig.ask_long(req), refused(RefuseReason::InRun));
    assert_eq!(rig.ask(chunk(0, &small)), refused(RefuseReason::InRun));
    assert_eq!(rig.ask(Request::WriteCommit), refused(RefuseReason::InRun));
    assert_eq!(rig.ask(Request::Stop), Answer::Done);
    // Remote service off: locked.
    rig.keys(&[Key::Star, Key::Digit(7)]);
    assert_eq!(rig.ask(Request::WriteCommit), refused(RefuseReason::Locked));
}

#[test]
fn a_repeated_commit_is_executed_once() {
    let mut rig = rig_with_small_in_slot_1();
    let bytes = payload(&assemble(MOTOR).unwrap());
    let begin = write_begin(2, &bytes);
    assert_eq!(rig.ask_long(begin), Answer::Done);
    for (k, c) in bytes.chunks(CHUNK_BYTES).enumerate() {
        let req = Request::WriteChunk {
            offset: (k * CHUNK_BYTES) as u16,
            data: c.iter().copied().collect(),
        };
        // A chunk sent twice (its answer lost) is simply written again.
        assert_eq!(rig.ask_long(req.clone()), Answer::Done);
        assert_eq!(rig.ask_long(req), Answer::Done);
    }
    let saved = Answer::WriteResult(WriteResult::Saved { generation: 1 });
    rig.send(77, &Request::WriteCommit);
    // Resent while it is being worked on: ignored, one answer.
    rig.run_ms(2);
    rig.send(77, &Request::WriteCommit);
    let got = rig.run_ms(2000);
    assert_eq!(got, vec![(77, saved.clone())]);
    // Resent after the answer (lost): the stored answer, nothing written again.
    let written = rig.plc.storage().eeprom().bytes_written();
    rig.send(77, &Request::WriteCommit);
    assert_eq!(rig.run_ms(100), vec![(77, saved)]);
    rig.run_ms(100);
    assert_eq!(rig.plc.storage().eeprom().bytes_written(), written);
    assert_eq!(events(&rig, EVENT_PROGRAM_WRITTEN), 1);
}

/// The power fails after every single byte the write stores (staging, the commit's two
/// copies, the event): afterwards slot 1 loads the old program or the new one.
#[test]
fn a_power_cut_at_any_byte_leaves_the_old_or_the_new_program() {
    let old = assemble(SMALL).unwrap();
    let new = assemble(MOTOR).unwrap();
    let bytes = payload(&new);
    let total = {
        let mut rig = rig_with_small_in_slot_1();
        let before = rig.plc.storage().eeprom().bytes_written();
        assert!(matches!(
            rig.push(1, &bytes),
            Answer::WriteResult(WriteResult::Saved { .. })
        ));
        rig.run_ms(300);
        rig.plc.storage().eeprom().bytes_written() - before
    };
    assert!(total as usize > 2 * bytes.len(), "{total}");
    let (mut saw_old, mut saw_new) = (0, 0);
    for cut in 0..=total {
        let mut rig = rig_with_small_in_slot_1();
        rig.plc.storage().eeprom().cut_power_after(cut);
        let answer = rig.push(1, &bytes);
        rig.run_ms(300);
        let e = rig.plc.storage().eeprom().clone();
        match stored(&e, 1) {
            Ok(p) if p == old => saw_old += 1,
            Ok(p) if p == new => {
                saw_new += 1;
            }
            other => panic!("cut after {cut} bytes: {other:?} (answer {answer:?})"),
        }
        // Only a complete save says so.
        if answer == Answer::WriteResult(WriteResult::Saved { generation: 2 }) {
            assert_eq!(stored(&e, 1), Ok(new.clone()), "cut after {cut}");
        }
    }
    assert!(saw_old > 0 && saw_new > 0, "{saw_old} {saw_new}");
}

/// The cable is cut after every chunk (the client stops talking): the old program stays;
/// a new `WriteBegin` then writes the new one. RUN on the keypad and a keypad save of the
/// slot in the middle of a transfer leave the old program too.
#[test]
fn a_cut_cable_a_new_begin_run_or_a_keypad_save_leave_the_old_program() {
    let old = assemble(SMALL).unwrap();
    let new = assemble(MOTOR).unwrap();
    let bytes = payload(&new);
    let chunks: Vec<&[u8]> = bytes.chunks(CHUNK_BYTES).collect();
    for sent in 0..=chunks.len() {
        let mut rig = rig_with_small_in_slot_1();
        let begin = write_begin(1, &bytes);
        assert_eq!(rig.ask_long(begin), Answer::Done);
        for (k, c) in chunks.iter().take(sent).enumerate() {
            let req = Request::WriteChunk {
                offset: (k * CHUNK_BYTES) as u16,
                data: c.iter().copied().collect(),
            };
            assert_eq!(rig.ask_long(req), Answer::Done);
        }
        // The cable is cut: the PLC forgets the client after 30 s.
        rig.run_ms(31_000);
        assert_eq!(
            stored(rig.plc.storage().eeprom(), 1),
            Ok(old.clone()),
            "{sent}"
        );
        // Reconnected: a new transfer from the start.
        rig.hello();
        assert_eq!(
            rig.push(1, &bytes),
            Answer::WriteResult(WriteResult::Saved { generation: 2 })
        );
        assert_eq!(stored(rig.plc.storage().eeprom(), 1), Ok(new.clone()));
    }

    // RUN on the keypad in the middle: the rest is refused, the old program stays.
    let mut rig = rig_with_small_in_slot_1();
    let begin = write_begin(1, &bytes);
    assert_eq!(rig.ask_long(begin.clone()), Answer::Done);
    let first = Request::WriteChunk {
        offset: 0,
        data: chunks[0].iter().copied().collect(),
    };
    assert_eq!(rig.ask_long(first.clone()), Answer::Done);
    rig.keys(&[Key::A]);
    assert_eq!(rig.ask(first.clone()), Answer::Refused(RefuseReason::InRun));
    assert_eq!(rig.ask(Request::Stop), Answer::Done);
    assert_eq!(rig.plc.run_state(), RunState::Stopped);
    assert_eq!(stored(rig.plc.storage().eeprom(), 1), Ok(old.clone()));

    // A keypad save of the slot in the middle voids the chunks staged so far.
    assert_eq!(rig.ask_long(begin), Answer::Done);
    assert_eq!(rig.ask_long(first), Answer::Done);
    rig.keys(&[Key::C, Key::Digit(1)]);
    rig.run_ms(500);
    for (k, c) in chunks.iter().enumerate().skip(1) {
        let req = Request::WriteChunk {
            offset: (k * CHUNK_BYTES) as u16,
            data: c.iter().copied().collect(),
        };
        assert_eq!(rig.ask_long(req), Answer::Done);
    }
    assert_eq!(
        rig.ask_long(Request::WriteCommit),
        Answer::WriteResult(WriteResult::Incomplete)
    );
    assert_eq!(stored(rig.plc.storage().eeprom(), 1), Ok(old));
}

/// A client that gives up a chunk half-written (one of its two page writes made) and asks
/// something else gets its answer: the abandoned chunk does not hold up the EEPROM reads.
#[test]
fn a_chunk_given_up_half_written_does_not_block_the_reads() {
    let bytes = payload(&assemble(MOTOR).unwrap());
    let mut rig = rig_with_small_in_slot_1();
    let begin = write_begin(1, &bytes);
    assert_eq!(rig.ask_long(begin), Answer::Done);
    rig.id += 1;
    let id = rig.id;
    rig.send(
        id,
        &Request::WriteChunk {
            offset: 0,
            data: bytes[..CHUNK_BYTES].iter().copied().collect(),
        },
    );
    // One pass: the chunk's first page write, no answer yet.
    assert!(rig.tick().is_empty());
    // ListSlots reads slots 2-4 from the EEPROM: answered within 100 ms.
    assert!(matches!(rig.ask(Request::ListSlots), Answer::Slots(_)));
}
