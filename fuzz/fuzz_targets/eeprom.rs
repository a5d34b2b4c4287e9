//! What the PLC reads from its EEPROM at power-up and on request: the boot record, the
//! program slots (two copies each: header, CRC-32, payload), the fault log and the
//! counters. The input is `[region, bytes...]`: `bytes` are XORed onto a valid image (a
//! program saved in slot 1 and run, five faults logged, a counters record) from the start
//! of the region `region` names (0 boot record, 1 fault log, 2 slot 1 copy A, 3 slot 1
//! copy B, 4 counters, else address 0), so that all-zero bytes leave the image valid and a
//! few set bits tear or flip exactly one record.
//!
//! Asserts: no panic; every program that loads (at power-up or from a slot) verifies; a
//! counters copy that parses re-encodes to the same bytes; the fault log reads at most its
//! 16 entries.
#![no_main]

use std::sync::OnceLock;

use firmware_plc::storage::counters::{self, CopyState, CounterValues, COUNTERS_BYTES, FORMATS};
use firmware_plc::storage::image::{program_image, ImageOptions};
use firmware_plc::storage::layout::{copy_addr, BOOT_ADDR, COUNTERS_ADDR, FAULT_LOG_ADDR};
use firmware_plc::storage::{MemEeprom, Storage, EEPROM_BYTES, FAULT_LOG_ENTRIES, SLOTS};
use libfuzzer_sys::fuzz_target;
use shared_protocol::program::{assemble_runnable, verify, Program};

const LIFT: &str = include_str!("../../shared-protocol/programs/lift.plc");

fn base() -> &'static [u8; EEPROM_BYTES] {
    static BASE: OnceLock<[u8; EEPROM_BYTES]> = OnceLock::new();
    BASE.get_or_init(|| {
        let program = assemble_runnable(LIFT).expect("the lift program assembles");
        let image = program_image(&program, &ImageOptions::default()).expect("saves");
        let mut storage = Storage::new(MemEeprom::from_image(&image));
        for (k, code) in [3u8, 7, 12, 3, 200].into_iter().enumerate() {
            storage.log_fault(code, 1000 * k as u64).expect("logs");
        }
        let mut image = *storage.into_eeprom().image();
        let values = CounterValues {
            run_starts: 12,
            run_minutes: 345,
            ..CounterValues::default()
        };
        let at = usize::from(COUNTERS_ADDR[0]);
        image[at..at + COUNTERS_BYTES].copy_from_slice(&values.to_bytes(7));
        image
    })
}

fn region_start(region: u8) -> usize {
    let addr = match region {
        0 => BOOT_ADDR[0],
        1 => FAULT_LOG_ADDR,
        2 => copy_addr(1, 0).unwrap_or(0),
        3 => copy_addr(1, 1).unwrap_or(0),
        4 => COUNTERS_ADDR[0],
        _ => 0,
    };
    usize::from(addr)
}

fn loads_verified(p: &Program) {
    assert!(
        verify(p).is_ok(),
        "a program loaded from the EEPROM does not verify"
    );
}

fuzz_target!(|data: &[u8]| {
    let Some((&region, bytes)) = data.split_first() else {
        return;
    };
    let mut image = *base();
    let start = region_start(region);
    for (d, s) in image[start..].iter_mut().zip(bytes) {
        *d ^= s;
    }

    let mut storage = Storage::new(MemEeprom::from_image(&image));
    let mut program = Program::default();
    if let Ok(up) = storage.power_up(&mut program) {
        if let Some(Ok(_)) = up.loaded {
            loads_verified(&program);
        }
    }
    for slot in 1..=SLOTS {
        let _ = storage.slot_info(slot);
        let mut p = Program::default();
        if storage.load(slot, &mut p).is_ok() {
            loads_verified(&p);
        }
    }
    let mut log = heapless::Vec::new();
    if storage.fault_log(&mut log).is_ok() {
        assert!(log.len() <= FAULT_LOG_ENTRIES);
    }
    let _ = storage.boot_record();

    let mut copies = [CopyState::Erased; 2];
    for (c, addr) in copies.iter_mut().zip(COUNTERS_ADDR) {
        let at = usize::from(addr);
        let mut buf = [0u8; COUNTERS_BYTES];
        buf.copy_from_slice(&image[at..at + COUNTERS_BYTES]);
        *c = counters::parse(&buf);
        if let CopyState::Valid(stamp, values) = *c {
            let format = &FORMATS[stamp.format];
            let again = values.to_bytes_as(format, stamp.seq);
            let len = format.bytes().min(COUNTERS_BYTES);
            assert_eq!(
                again[..len],
                buf[..len],
                "a valid counters copy re-encodes differently"
            );
        }
    }
    let _ = counters::choose(copies);
});
