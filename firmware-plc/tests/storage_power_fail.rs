//! Power-fail safety and corruption handling of program storage (panel.md "Storage").

use firmware_plc::storage::{MemEeprom, OtherCopy, SlotCopy, Storage, StorageError, EEPROM_BYTES};
use proptest::prelude::*;
use shared_protocol::program::{Instruction, Mnemonic, Operand, Program, LINES};

fn ins(mnemonic: Mnemonic, operand: Option<Operand>, constant: u16) -> Instruction {
    Instruction {
        mnemonic,
        operand,
        constant,
    }
}

/// A program with several runs of lines in both sections; `seed` varies the content.
fn program(seed: u16, lines: &[usize]) -> Program {
    let mut p = Program::default();
    for (k, &n) in lines.iter().enumerate() {
        let v = (seed as usize * 31 + k * 7) % 100;
        p.lines[n] = Some(if n < 150 {
            ins(
                Mnemonic::Ld,
                Some(Operand::K(v as u8)),
                (seed + k as u16) % 10_000,
            )
        } else {
            ins(Mnemonic::Wr, Some(Operand::B(v as u8)), 0)
        });
    }
    p
}

fn old_program() -> Program {
    program(1, &[0, 1, 2, 3, 20, 150, 151, 152, 153, 154, 300, 301, 999])
}

fn new_program() -> Program {
    let mut v: Vec<usize> = (0..30).collect();
    v.extend(150..200);
    v.push(700);
    program(2, &v)
}

/// Bytes written by one complete save of `p` into `slot` of `e`.
fn save_bytes(e: &MemEeprom, slot: u8, p: &Program) -> u32 {
    let mut s = Storage::new(e.clone());
    let before = s.eeprom().bytes_written();
    s.save(slot, p).unwrap();
    s.eeprom().bytes_written() - before
}

/// Cut the power after every possible number of bytes of a save, reboot, load: the slot
/// must hold the old program up to some byte and the new one from then on, never
/// anything else.
fn cut_everywhere(start: &MemEeprom, slot: u8, old: Option<&Program>, new: &Program) -> u32 {
    let total = save_bytes(start, slot, new);
    let mut switched_at = None;
    for cut in 0..=total {
        let mut s = Storage::new(start.clone());
        s.eeprom().cut_power_after(cut);
        let r = s.save(slot, new);
        assert_eq!(r.is_ok(), cut == total, "cut {cut}: {r:?}");
        s.eeprom().restore_power();
        // Reboot: a fresh Storage over what the chip holds.
        let mut s = Storage::new(s.into_eeprom());
        let mut got = Program::default();
        match (s.load(slot, &mut got), old) {
            (Ok(_), _) if &got == new => {
                switched_at.get_or_insert(cut);
            }
            (Ok(_), Some(o)) if &got == o => {
                assert!(
                    switched_at.is_none(),
                    "old program again after new at {cut}"
                );
            }
            (Err(StorageError::Empty(_)), None) => {
                assert!(switched_at.is_none(), "slot empty again at {cut}");
            }
            (r, _) => panic!("cut {cut}: neither old nor new: {r:?} {got:?}"),
        }
        // And the slot still takes a save afterwards.
        if cut % 97 == 0 {
            s.save(slot, new).unwrap();
            let mut again = Program::default();
            s.load(slot, &mut again).unwrap();
            assert_eq!(&again, new);
        }
    }
    assert!(switched_at.is_some());
    total
}

#[test]
fn power_cut_at_every_byte_of_a_save_leaves_old_or_new() {
    let mut s = Storage::new(MemEeprom::new());
    // First save into an empty slot: empty or new.
    let empty = s.eeprom().clone();
    let n0 = cut_everywhere(&empty, 2, None, &old_program());
    s.save(2, &old_program()).unwrap();
    // Old -> new (both copies at the same generation beforehand).
    let n1 = cut_everywhere(s.eeprom(), 2, Some(&old_program()), &new_program());
    // After a save that was cut between the copies (copies at different generations).
    let total = save_bytes(s.eeprom(), 2, &new_program());
    let mut half = Storage::new(s.eeprom().clone());
    half.eeprom().cut_power_after(total / 2 + 3);
    assert!(half.save(2, &new_program()).is_err());
    half.eeprom().restore_power();
    let e = half.into_eeprom();
    let n2 = cut_everywhere(&e, 2, Some(&new_program()), &old_program());
    assert!(n0 > 0 && n1 > n0 && n2 > 0);
    println!("power cut after every byte: {n0} + {n1} + {n2} cut points, all old-or-new");
}

#[test]
fn other_slots_are_untouched_by_a_cut_save() {
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &old_program()).unwrap();
    s.save(3, &new_program()).unwrap();
    let total = save_bytes(s.eeprom(), 2, &new_program());
    for cut in (0..total).step_by(17) {
        let mut t = Storage::new(s.eeprom().clone());
        t.eeprom().cut_power_after(cut);
        let _ = t.save(2, &new_program());
        t.eeprom().restore_power();
        let mut p = Program::default();
        t.load(1, &mut p).unwrap();
        assert_eq!(p, old_program());
        t.load(3, &mut p).unwrap();
        assert_eq!(p, new_program());
    }
}

/// Address range of the used part of one copy, found from the image difference.
fn copy_bytes(slot: u8, copy: u8, p: &Program) -> std::ops::Range<u16> {
    let mut s = Storage::new(MemEeprom::new());
    s.save(slot, p).unwrap();
    let img = s.eeprom().image();
    let used: Vec<usize> = (0..EEPROM_BYTES).filter(|&i| img[i] != 0xFF).collect();
    // Copies A and B are contiguous runs; A comes first.
    let split = used.windows(2).position(|w| w[1] - w[0] > 64).unwrap();
    let (a, b) = used.split_at(split + 1);
    let r = if copy == 0 { a } else { b };
    r[0] as u16..(*r.last().unwrap() + 1) as u16
}

#[test]
fn bit_flip_in_one_copy_falls_back_to_the_other_and_says_so() {
    let p = new_program();
    for copy in 0..2u8 {
        let range = copy_bytes(2, copy, &p);
        for addr in range.clone().step_by(5) {
            let mut s = Storage::new(MemEeprom::new());
            s.save(2, &p).unwrap();
            s.eeprom().flip_bit(addr, (addr % 8) as u8);
            let mut got = Program::default();
            let report = s.load(2, &mut got).unwrap();
            assert_eq!(got, p, "flip at {addr}");
            let expect_used = if copy == 0 { SlotCopy::B } else { SlotCopy::A };
            assert_eq!(report.used, expect_used);
            assert!(matches!(report.other, OtherCopy::Bad(_)), "{report:?}");
            // The next save repairs both copies.
            s.save(2, &p).unwrap();
            assert_eq!(s.load(2, &mut got).unwrap().other, OtherCopy::Same);
        }
    }
}

#[test]
fn bit_flips_in_both_copies_are_an_error_not_garbage() {
    let p = new_program();
    let a = copy_bytes(1, 0, &p);
    let b = copy_bytes(1, 1, &p);
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &p).unwrap();
    s.eeprom().flip_bit(a.start + 40, 3);
    s.eeprom().flip_bit(b.start + 100, 0);
    let mut got = old_program();
    assert_eq!(s.load(1, &mut got), Err(StorageError::Damaged(1)));
    assert_eq!(
        got,
        old_program(),
        "a failed load leaves the program as it was"
    );
}

#[test]
fn last_run_slot_loads_and_runs_at_power_up() {
    let mut s = Storage::new(MemEeprom::new());
    let mut p = Program::default();
    let up = s.power_up(&mut p).unwrap();
    assert_eq!((up.power_cycle, up.loaded, up.run), (1, None, false));
    s.save(3, &new_program()).unwrap();
    s.set_run_state(Some(3), true).unwrap();
    // Power cycle.
    let mut s = Storage::new(s.into_eeprom());
    let mut p = Program::default();
    let up = s.power_up(&mut p).unwrap();
    assert_eq!(up.power_cycle, 2);
    assert!(up.run);
    assert!(matches!(up.loaded, Some(Ok(r)) if r.slot == 3));
    assert_eq!(p, new_program());
    // STOP by the user: loaded at the next power-up, but not run.
    s.set_run_state(None, false).unwrap();
    let mut s = Storage::new(s.into_eeprom());
    let up = s.power_up(&mut p).unwrap();
    assert_eq!(up.power_cycle, 3);
    assert!(!up.run);
    assert!(matches!(up.loaded, Some(Ok(r)) if r.slot == 3));
}

#[test]
fn fault_log_survives_power_cycles() {
    let mut s = Storage::new(MemEeprom::new());
    let mut p = Program::default();
    s.power_up(&mut p).unwrap();
    s.log_fault(1, 12_345).unwrap();
    s.log_fault(5, 60_000).unwrap();
    let mut s = Storage::new(s.into_eeprom());
    s.power_up(&mut p).unwrap();
    s.log_fault(4, 2_000).unwrap();
    let mut log = heapless::Vec::new();
    s.fault_log(&mut log).unwrap();
    let got: Vec<(u8, u16, u32)> = log
        .iter()
        .map(|e| (e.code, e.power_cycle, e.uptime_s))
        .collect();
    assert_eq!(got, vec![(4, 2, 2), (5, 1, 60), (1, 1, 12)]);
}

fn arb_instruction() -> impl Strategy<Value = Instruction> {
    let ops = prop_oneof![
        Just(None),
        (0u8..8).prop_map(|i| Some(Operand::D(i))),
        (0u8..100).prop_map(|i| Some(Operand::B(i))),
        (0u8..100).prop_map(|i| Some(Operand::K(i))),
        (0u8..64).prop_map(|i| Some(Operand::Q(i))),
        Just(Some(Operand::Com)),
        Just(Some(Operand::Flb)),
    ];
    (0..Mnemonic::ALL.len(), ops, 0u16..10_000).prop_map(|(m, operand, c)| Instruction {
        mnemonic: Mnemonic::ALL[m],
        operand,
        constant: if matches!(operand, Some(Operand::K(_))) {
            c
        } else {
            0
        },
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn any_program_round_trips(lines in proptest::collection::vec((0..LINES, arb_instruction()), 0..400), slot in 1u8..=4) {
        let mut p = Program::default();
        for (n, i) in lines {
            p.lines[n] = Some(i);
        }
        let mut s = Storage::new(MemEeprom::new());
        s.save(slot, &p).unwrap();
        let mut q = Program::default();
        s.load(slot, &mut q).unwrap();
        prop_assert_eq!(p, q);
    }
}

#[test]
fn motor_program_save_costs_eight_page_writes() {
    let text = include_str!("../../shared-protocol/programs/motor.plc");
    let p = shared_protocol::program::assemble(text).unwrap();
    assert_eq!(
        shared_protocol::program::payload::payload_size(&p),
        (2 * 3 + 52 * 4, 52),
        "two runs of 26 lines (docs/eeprom-image.md)"
    );
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &p).unwrap();
    // 230 bytes per copy = 4 pages, two copies: 8 page writes, at most 40 ms on a 24C256.
    assert_eq!(s.eeprom().pages_written(), 8);
    assert_eq!(s.eeprom().bytes_written(), 2 * 230);
    // Overwriting it with another program, cut at every byte.
    let n = cut_everywhere(s.eeprom(), 1, Some(&p), &old_program());
    // And back.
    let mut t = Storage::new(s.eeprom().clone());
    t.save(1, &old_program()).unwrap();
    let m = cut_everywhere(t.eeprom(), 1, Some(&old_program()), &p);
    assert_eq!(m, 2 * 230);
    println!("motor program: {n} + {m} cut points, all old-or-new");
}

#[test]
fn an_unsaved_program_is_never_replaced_by_an_older_one_at_power_up() {
    let mut s = Storage::new(MemEeprom::new());
    s.save(2, &old_program()).unwrap();
    s.set_run_state(Some(2), true).unwrap();
    // The user edits and runs without saving.
    s.set_run_state(None, true).unwrap();
    let mut s = Storage::new(s.into_eeprom());
    let mut p = Program::default();
    let up = s.power_up(&mut p).unwrap();
    assert!(
        !up.run,
        "the running program was not stored: do not start slot 2"
    );
    assert_eq!(p, old_program(), "but slot 2 is loaded for editing");
}
