//! `storage_decodes`: after every power cut of the PLC MCU, the EEPROM decodes through the
//! firmware's own decoders and holds nothing the firmware did not write (issue 32 item 2;
//! the guarantees are the storage's: `firmware-plc/src/storage/mod.rs` "a save writes the
//! stale copy completely first ... at every instant at least one copy holds either the
//! old or the new program in full", `storage/counters.rs` "a power cut while writing it
//! leaves the previous record in force", `docs/eeprom-image.md`):
//!
//! * each program slot loads (`Storage::load`: empty, or a copy whose CRC checks) and holds
//!   the program it held before, or the one a save in flight was writing;
//! * the fault log reads (`fault_log::read_all`) and keeps every entry it held, except the
//!   oldest of a full log (the ring slot the entry in flight overwrites); at most the one
//!   entry in flight is new;
//! * the counters record (`counters::choose` over both copies) is in force (never
//!   `COUNTERS RESET`) and no counter went back (they only count up, saturating).
//!
//! The state "before" is a snapshot of the EEPROM decoded at power-up, after every storage
//! job that ends and after every cut ([`StorageTrack::snapshot`]); the runner tells the
//! track which program a save in flight writes ([`StorageTrack::save_started`]).

use firmware_plc::storage::counters::{self, CopyState, CounterValues, COUNTERS_BYTES};
use firmware_plc::storage::{
    Eeprom, FaultEntry, MemEeprom, Storage, StorageError, FAULT_LOG_ENTRIES, SLOTS,
};
use shared_protocol::program::Program;

pub const NAME: &str = "storage_decodes";

/// What the EEPROM held, decoded.
#[derive(Clone)]
pub struct Decoded {
    /// Slot 1..=4 (index 0..=3): `None` empty.
    pub slots: Vec<Option<Program>>,
    /// Newest first.
    pub log: Vec<FaultEntry>,
    pub counters: CounterValues,
    /// Both counter copies bad.
    pub counters_reset: bool,
}

/// Decodes `e` through the firmware's decoders (on a copy: nothing is written).
pub fn decode(e: &MemEeprom) -> Result<Decoded, String> {
    let mut slots = Vec::new();
    for slot in 1..=SLOTS {
        let mut s = Storage::new(e.clone());
        let mut p = Program::default();
        match s.load(slot, &mut p) {
            Ok(_) => slots.push(Some(p)),
            Err(StorageError::Empty(_)) => slots.push(None),
            Err(x) => return Err(format!("slot {slot} does not load: {x}")),
        }
    }
    let mut s = Storage::new(e.clone());
    let mut log = heapless::Vec::<FaultEntry, FAULT_LOG_ENTRIES>::new();
    s.fault_log(&mut log)
        .map_err(|x| format!("the fault log does not read: {x}"))?;
    let mut e = e.clone();
    let mut copy = |i: usize| {
        let mut b = [0u8; COUNTERS_BYTES];
        e.read(counters::copy_addr(i), &mut b)
            .map(|_| counters::parse(&b))
            .unwrap_or(CopyState::Bad)
    };
    let found = counters::choose([copy(0), copy(1)]);
    Ok(Decoded {
        slots,
        log: log.to_vec(),
        counters: found.values,
        counters_reset: found.reset,
    })
}

/// The storage as the firmware left it, and what may change at a cut.
pub struct StorageTrack {
    before: Decoded,
    /// Per slot (index slot - 1): the program a save started since the snapshot writes.
    in_flight: Vec<Vec<Program>>,
    /// Power cuts checked.
    pub cuts: u64,
}

impl StorageTrack {
    /// The track of an EEPROM at power-up (it must decode).
    pub fn new(e: &MemEeprom) -> Result<Self, String> {
        Ok(StorageTrack {
            before: decode(e)?,
            in_flight: vec![Vec::new(); usize::from(SLOTS)],
            cuts: 0,
        })
    }

    /// A save of `program` into `slot` started.
    pub fn save_started(&mut self, slot: u8, program: &Program) {
        if let Some(v) = usize::from(slot)
            .checked_sub(1)
            .and_then(|i| self.in_flight.get_mut(i))
        {
            if !v.contains(program) {
                v.push(program.clone());
            }
        }
    }

    /// A storage job ended with the power on: what the EEPROM holds now is "before".
    pub fn snapshot(&mut self, e: &MemEeprom) {
        if let Ok(d) = decode(e) {
            self.before = d;
            self.in_flight.iter_mut().for_each(Vec::clear);
        }
    }

    /// The PLC lost its supply with `e` as it is: checks it, and takes it as "before".
    pub fn after_cut(&mut self, e: &MemEeprom) -> Option<String> {
        self.cuts += 1;
        let after = match decode(e) {
            Ok(d) => d,
            Err(m) => return Some(m),
        };
        let bad = self.compare(&after);
        self.before = after;
        self.in_flight.iter_mut().for_each(Vec::clear);
        bad
    }

    fn compare(&self, after: &Decoded) -> Option<String> {
        let b = &self.before;
        for (i, now) in after.slots.iter().enumerate() {
            let old = b.slots.get(i).cloned().flatten();
            let new = self.in_flight.get(i).map(Vec::as_slice).unwrap_or(&[]);
            let ok = *now == old || now.as_ref().is_some_and(|p| new.contains(p));
            if !ok {
                return Some(format!(
                    "slot {} holds {} program, neither its old one ({}) nor one being saved ({} in flight)",
                    i + 1,
                    if now.is_some() { "a" } else { "no" },
                    if old.is_some() { "a program" } else { "empty" },
                    new.len()
                ));
            }
        }
        let full = b.log.len() >= FAULT_LOG_ENTRIES;
        let may_go = if full { b.log.last() } else { None };
        if let Some(lost) = b
            .log
            .iter()
            .find(|x| Some(*x) != may_go && !after.log.contains(x))
        {
            return Some(format!(
                "the fault log lost entry code {} (power-up {}, {} s)",
                lost.code, lost.power_cycle, lost.uptime_s
            ));
        }
        let new = after.log.iter().filter(|x| !b.log.contains(x)).count();
        if new > 1 {
            return Some(format!(
                "the fault log gained {new} entries across the cut (one at most was in flight)"
            ));
        }
        if after.counters_reset {
            return Some("both counter copies are bad (COUNTERS RESET)".into());
        }
        if let Some(what) = went_back(&b.counters, &after.counters) {
            return Some(format!("the counters went back: {what}"));
        }
        None
    }
}

/// The first counter of `after` below its value in `before`.
fn went_back(before: &CounterValues, after: &CounterValues) -> Option<String> {
    let scalar = [
        ("run_starts", before.run_starts, after.run_starts),
        ("run_minutes", before.run_minutes, after.run_minutes),
        ("pwm_minutes", before.pwm_minutes, after.pwm_minutes),
        ("link_errors", before.link_errors, after.link_errors),
        (
            "program_saves",
            u32::from(before.program_saves),
            u32::from(after.program_saves),
        ),
    ];
    if let Some((n, b, a)) = scalar.iter().find(|(_, b, a)| a < b) {
        return Some(format!("{n} {b} -> {a}"));
    }
    let trips = before.trips.iter().zip(after.trips.iter()).enumerate();
    if let Some((i, (b, a))) = trips.clone().find(|(_, (b, a))| a < b) {
        return Some(format!("trips of code {} {b} -> {a}", i + 1));
    }
    let app = before.app.iter().zip(after.app.iter()).enumerate();
    app.clone()
        .find(|(_, (b, a))| a < b)
        .map(|(i, (b, a))| format!("application counter {} {b} -> {a}", i + 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_plc::storage::counters::CounterValues;

    fn program(text: &str) -> Program {
        crate::run::parse_program(text, "test").unwrap()
    }

    fn saved(slot: u8, p: &Program, e: MemEeprom) -> MemEeprom {
        let mut s = Storage::new(e);
        s.save(slot, p).unwrap();
        s.into_eeprom()
    }

    #[test]
    fn a_save_cut_at_any_byte_leaves_the_old_or_the_new_program() {
        let old = program("000 LD  K00 0001\n001 WR  Q01\n");
        let new = program("000 LD  K00 0002\n001 WR  Q01\n002 WR  Q02\n");
        let base = saved(2, &old, MemEeprom::new());
        let full = saved(2, &new, base.clone()).bytes_written() - base.bytes_written();
        for n in (0..full).step_by(7) {
            let mut t = StorageTrack::new(&base).unwrap();
            let mut s = Storage::new(base.clone());
            s.eeprom().cut_power_after(n);
            t.save_started(2, &new);
            assert!(s.save(2, &new).is_err(), "cut at {n}");
            let mut e = s.into_eeprom();
            e.restore_power();
            assert_eq!(t.after_cut(&e), None, "cut at byte {n}");
        }
    }

    #[test]
    fn fires_on_a_slot_holding_a_program_nobody_saved_there() {
        let old = program("000 LD  K00 0001\n001 WR  Q01\n");
        let other = program("000 LD  K00 0003\n001 WR  Q01\n");
        let base = saved(3, &old, MemEeprom::new());
        let mut t = StorageTrack::new(&base).unwrap();
        // A save of `old` was in flight, but the slot came back with `other`.
        t.save_started(3, &old);
        let m = t.after_cut(&saved(3, &other, base.clone())).unwrap();
        assert!(m.contains("slot 3") && m.contains("neither"), "{m}");
    }

    #[test]
    fn fires_on_a_slot_that_no_longer_loads() {
        let base = saved(
            1,
            &program("000 LD  K00 0001\n001 WR  Q01\n"),
            MemEeprom::new(),
        );
        let mut t = StorageTrack::new(&base).unwrap();
        let mut e = base.clone();
        // Both copies damaged (a byte of each header).
        let a = firmware_plc::storage::layout::copy_addr(1, 0).unwrap();
        let b = firmware_plc::storage::layout::copy_addr(1, 1).unwrap();
        e.flip_bit(a + 20, 3);
        e.flip_bit(b + 20, 3);
        let m = t.after_cut(&e).unwrap();
        assert!(m.contains("slot 1 does not load"), "{m}");
    }

    #[test]
    fn fires_on_a_lost_log_entry_and_on_counters_that_went_back() {
        let mut s = Storage::new(MemEeprom::new());
        s.log_fault(9, 1000).unwrap();
        s.log_fault(3, 2000).unwrap();
        let two = s.eeprom().clone();
        let mut t = StorageTrack::new(&two).unwrap();
        // One more entry (in flight) is fine.
        s.log_fault(5, 3000).unwrap();
        assert_eq!(t.after_cut(s.eeprom()), None);
        // Cleared: two entries that were there are gone.
        s.clear_fault_log().unwrap();
        let m = t.after_cut(s.eeprom()).unwrap();
        assert!(m.contains("lost entry"), "{m}");

        let counters = |v: &CounterValues, seq| {
            let mut e = MemEeprom::new();
            e.start_write(counters::copy_addr(0), &v.to_bytes(seq))
                .unwrap();
            e
        };
        let high = CounterValues {
            run_starts: 5,
            ..CounterValues::default()
        };
        let mut t = StorageTrack::new(&counters(&high, 1)).unwrap();
        let low = CounterValues {
            run_starts: 4,
            ..CounterValues::default()
        };
        let m = t.after_cut(&counters(&low, 2)).unwrap();
        assert!(m.contains("run_starts 5 -> 4"), "{m}");
        let mut bad = MemEeprom::new();
        bad.start_write(counters::copy_addr(0), &[0x55; 64])
            .unwrap();
        bad.start_write(counters::copy_addr(1), &[0x55; 64])
            .unwrap();
        let m = t.after_cut(&bad).unwrap();
        assert!(m.contains("COUNTERS RESET"), "{m}");
    }
}
