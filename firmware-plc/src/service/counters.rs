//! The counters (service.md 7): counted in RAM from what each 1 ms tick shows, read from
//! and written to their EEPROM record (`storage::counters`, pages 510-511) a page at a
//! time between scans, like the service's other EEPROM work.
//!
//! The tally lives in the [`super::Service`] (its own static on the board), not in the
//! application: the application's builder frame must not grow (`board/`).
//!
//! Rules (the decisions are in `docs/eeprom-image.md` "Counters"):
//! * RUN starts: every change of the run state to RUN (both MCUs run), whoever asked.
//! * Minutes in RUN and minutes with PWM on (the drive reports RUN with a non-zero
//!   frequency): milliseconds summed tick by tick, a minute counted at each full 60 000.
//! * Link errors: the increase of the link's rejected frames plus link losses.
//! * Program saves: each keypad save and each service write that ends `Saved`.
//! * Trips: each drive fault report (fault-log entry) with code 1-16.
//! * Application counters: after each scan, every increase of Q60-Q63 since the previous
//!   scan; a decrease adds nothing.
//!
//! Cadence: when a value changed, the record is written when the PLC stops, and otherwise
//! 10 min after the previous write (or the power-up), never more often: one page write.

use shared_protocol::service::{Counters, Trips};
use shared_protocol::units::Micros;

use crate::storage::counters::{
    add_u16, add_u24, choose, copy_addr, parse, CopyState, CounterValues, APP_COUNTERS,
    COUNTERS_BYTES, TRIP_CODES,
};
use crate::storage::{Eeprom, Storage};

/// Time between two writes of the record while values change (service.md 7).
pub const WRITE_PERIOD_US: u64 = 10 * 60 * 1_000_000;
const MINUTE_MS: u32 = 60_000;
/// The first application counter's register: Q60.
pub const APP_FIRST_Q: u8 = 60;

/// What one tick showed, for [`Tally::observe`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Observation {
    /// The run state became RUN in this tick.
    pub run_started: bool,
    /// The run state became STOP in this tick.
    pub stopped: bool,
    /// The PLC is in RUN.
    pub running: bool,
    /// The drive reports RUN with a non-zero frequency.
    pub pwm_on: bool,
    /// The link's rejected frames plus link losses since power-up.
    pub link_errors_total: u32,
    /// A program save (keypad or service) ended `Saved`.
    pub saved: bool,
    /// A fault report with this code was logged.
    pub fault: Option<u8>,
    /// A scan ran: Q60-Q63 after it.
    pub q: Option<[i16; APP_COUNTERS]>,
}

/// Reading the record at power-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Load {
    /// Nothing read yet.
    Start,
    /// Page 510 read.
    First(CopyState),
    /// In force: the next write goes to `copy` with `seq`.
    Done { copy: usize, seq: u16 },
}

/// What [`Tally::eeprom_step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TallyStep {
    /// Nothing to do.
    Idle,
    /// Read or wrote a page.
    UsedBus,
    /// Read the second copy; both were bad: the counters restart at 0 (the LCD says
    /// `COUNTERS RESET`).
    Reset,
}

/// The counters in RAM and their record's state.
#[derive(Debug, Clone)]
pub struct Tally {
    /// Until the record is read: the counts made since power-up; then the values in force.
    values: CounterValues,
    load: Load,
    /// A value changed since the record was last written (or read).
    dirty: bool,
    /// The PLC stopped with values changed: write now.
    stop_pending: bool,
    /// When the record was last written in this power-up.
    written_at: Option<Micros>,
    /// Start of the current 10-minute period: the last write, or the record's read.
    period_from: Micros,
    /// The time of the last observation.
    now: Option<Micros>,
    run_ms: u32,
    pwm_ms: u32,
    link_errors_seen: u32,
    q_prev: [i16; APP_COUNTERS],
}

impl Default for Tally {
    fn default() -> Self {
        Self::new()
    }
}

impl Tally {
    pub const fn new() -> Self {
        Tally {
            values: CounterValues {
                run_starts: 0,
                run_minutes: 0,
                pwm_minutes: 0,
                link_errors: 0,
                program_saves: 0,
                trips: [0; TRIP_CODES],
                app: [0; APP_COUNTERS],
            },
            load: Load::Start,
            dirty: false,
            stop_pending: false,
            written_at: None,
            period_from: Micros(0),
            now: None,
            run_ms: 0,
            pwm_ms: 0,
            link_errors_seen: 0,
            q_prev: [0; APP_COUNTERS],
        }
    }

    /// The values in RAM (including counts not yet written).
    pub fn values(&self) -> &CounterValues {
        &self.values
    }

    /// Whether the record has been read (writes wait for it).
    pub fn loaded(&self) -> bool {
        matches!(self.load, Load::Done { .. })
    }

    /// Counts what a tick at `now` showed.
    pub fn observe(&mut self, o: &Observation, now: Micros) {
        let before = self.values;
        let dt_ms = self
            .now
            .map_or(0, |t| now.0.saturating_sub(t.0) / 1000)
            .min(u64::from(MINUTE_MS)) as u32;
        self.now = Some(now);
        let v = &mut self.values;
        if o.run_started {
            add_u24(&mut v.run_starts, 1);
        }
        for (on, ms, minutes) in [
            (o.running, &mut self.run_ms, &mut v.run_minutes),
            (o.pwm_on, &mut self.pwm_ms, &mut v.pwm_minutes),
        ] {
            if on {
                *ms += dt_ms;
                while *ms >= MINUTE_MS {
                    *ms -= MINUTE_MS;
                    add_u24(minutes, 1);
                }
            }
        }
        let errors = o.link_errors_total.wrapping_sub(self.link_errors_seen);
        self.link_errors_seen = o.link_errors_total;
        add_u24(&mut v.link_errors, errors);
        if o.saved {
            add_u16(&mut v.program_saves, 1);
        }
        if let Some(t) = o
            .fault
            .and_then(|c| usize::from(c).checked_sub(1))
            .and_then(|i| v.trips.get_mut(i))
        {
            add_u16(t, 1);
        }
        if let Some(q) = o.q {
            for ((prev, &now_q), counter) in self.q_prev.iter_mut().zip(&q).zip(&mut v.app) {
                let rise = i32::from(now_q) - i32::from(*prev);
                if rise > 0 {
                    add_u24(counter, rise as u32);
                }
                *prev = now_q;
            }
        }
        self.dirty |= self.values != before;
        if o.stopped && self.dirty {
            self.stop_pending = true;
        }
    }

    /// Whether the record is to be written now.
    pub fn write_due(&self) -> bool {
        let Some(now) = self.now else {
            return false;
        };
        self.loaded()
            && self.dirty
            && (self.stop_pending || now.0.saturating_sub(self.period_from.0) >= WRITE_PERIOD_US)
    }

    /// Reads the record (at power-up, one copy per call) or writes it when due (one page
    /// write), only while the EEPROM is free ([`Storage::idle`]).
    pub fn eeprom_step<E: Eeprom>(&mut self, storage: &mut Storage<E>) -> TallyStep {
        if !storage.idle() {
            return TallyStep::Idle;
        }
        let read = |storage: &mut Storage<E>, copy: usize| {
            let mut buf = [0u8; COUNTERS_BYTES];
            match storage.eeprom().read(copy_addr(copy), &mut buf) {
                Ok(()) => parse(&buf),
                // Unreadable counts as bad.
                Err(_) => CopyState::Bad,
            }
        };
        match self.load {
            Load::Start => {
                self.load = Load::First(read(storage, 0));
                TallyStep::UsedBus
            }
            Load::First(first) => {
                let found = choose([first, read(storage, 1)]);
                self.values = found.values.plus(&self.values);
                self.load = Load::Done {
                    copy: found.next_copy,
                    seq: found.next_seq,
                };
                self.period_from = self.now.unwrap_or(Micros(0));
                if found.reset {
                    // Write the restarted record soon (at the next STOP or in 10 min).
                    self.dirty = true;
                    TallyStep::Reset
                } else {
                    TallyStep::UsedBus
                }
            }
            Load::Done { copy, seq } => {
                if !self.write_due() {
                    return TallyStep::Idle;
                }
                let now = self.now.unwrap_or(Micros(0));
                let bytes = self.values.to_bytes(seq);
                self.period_from = now;
                if storage.write_outside_queue(copy_addr(copy), &bytes).is_ok() {
                    self.load = Load::Done {
                        copy: 1 - copy,
                        seq: seq.wrapping_add(1),
                    };
                    self.dirty = false;
                    self.stop_pending = false;
                    self.written_at = Some(now);
                }
                TallyStep::UsedBus
            }
        }
    }

    /// `GetCounters`'s answer at `now`.
    pub fn answer(&self, power_ups: u32, now: Micros) -> Counters {
        let v = &self.values;
        Counters {
            run_starts: v.run_starts,
            run_minutes: v.run_minutes,
            pwm_minutes: v.pwm_minutes,
            link_errors: v.link_errors,
            program_saves: v.program_saves,
            trips: Trips(v.trips),
            app: v.app,
            power_ups,
            since_write_s: self
                .written_at
                .map(|t| (now.0.saturating_sub(t.0) / 1_000_000) as u32),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::mem_eeprom::MemEeprom;
    use shared_protocol::fault::FaultCode;

    fn ms(n: u64) -> Micros {
        Micros(n * 1000)
    }

    /// A tally fed `n` ticks of 1 ms from `t` (ms) with `o`; returns the next `t`.
    fn ticks(t: &mut Tally, from: u64, n: u64, o: Observation) -> u64 {
        for k in 0..n {
            t.observe(&o, ms(from + k));
        }
        from + n
    }

    #[test]
    fn run_starts_minutes_saves_trips_and_link_errors() {
        let mut t = Tally::new();
        let run = Observation {
            running: true,
            ..Default::default()
        };
        t.observe(
            &Observation {
                run_started: true,
                ..run
            },
            ms(0),
        );
        // 59 999 ms in RUN: no minute yet; the next one counts it.
        let at = ticks(&mut t, 1, 59_999, run);
        assert_eq!(t.values().run_minutes, 0);
        let at = ticks(&mut t, at, 1, run);
        assert_eq!(t.values().run_minutes, 1);
        assert_eq!(t.values().pwm_minutes, 0);
        let pwm = Observation {
            pwm_on: true,
            ..run
        };
        let at = ticks(&mut t, at, 120_000, pwm);
        assert_eq!((t.values().run_minutes, t.values().pwm_minutes), (3, 2));
        // Stopped: minutes stand still.
        let at = ticks(&mut t, at, 120_000, Observation::default());
        assert_eq!(t.values().run_minutes, 3);
        t.observe(
            &Observation {
                saved: true,
                fault: Some(3),
                link_errors_total: 5,
                ..Default::default()
            },
            ms(at),
        );
        t.observe(
            &Observation {
                fault: Some(16),
                link_errors_total: 7,
                ..Default::default()
            },
            ms(at + 1),
        );
        // Events and undefined codes have no trip counter.
        for code in [FaultCode::COUNT as u8 + 1, 240, 241, 0] {
            t.observe(
                &Observation {
                    fault: Some(code),
                    link_errors_total: 7,
                    ..Default::default()
                },
                ms(at + 2),
            );
        }
        let v = t.values();
        assert_eq!(v.run_starts, 1);
        assert_eq!(v.program_saves, 1);
        assert_eq!(v.link_errors, 7);
        let mut trips = [0; TRIP_CODES];
        trips[2] = 1;
        trips[15] = 1;
        assert_eq!(v.trips, trips);
    }

    /// Every code of the fault table has its own trip counter, kept through a write and a
    /// read of the record (`docs/contributing/add-a-trip.md`, the PLC's counters).
    #[test]
    fn every_fault_code_counts_in_its_own_counter_and_survives_the_record() {
        let mut t = Tally::new();
        for (n, f) in FaultCode::ALL.into_iter().enumerate() {
            for _ in 0..=n {
                t.observe(
                    &Observation {
                        fault: Some(f.code()),
                        ..Default::default()
                    },
                    ms(0),
                );
            }
        }
        let v = t.values();
        let want: [u16; TRIP_CODES] = core::array::from_fn(|i| i as u16 + 1);
        assert_eq!(v.trips, want);
        let read = crate::storage::counters::parse(&v.to_bytes(1));
        assert!(
            matches!(read, CopyState::Valid(_, r) if r == *v),
            "{read:?}"
        );
    }

    #[test]
    fn application_counters_add_every_increase_and_no_decrease() {
        let mut t = Tally::new();
        let mut scan = |q: [i16; 4], at: u64| {
            t.observe(
                &Observation {
                    running: true,
                    q: Some(q),
                    ..Default::default()
                },
                ms(at),
            );
            t.values().app
        };
        assert_eq!(scan([1, 0, 0, 0], 0), [1, 0, 0, 0]);
        assert_eq!(scan([3, 5, 0, 0], 1), [3, 5, 0, 0]);
        // A reset (or the clear at RUN start) adds nothing; counting goes on from there.
        assert_eq!(scan([0, 5, 0, -4], 2), [3, 5, 0, 0]);
        assert_eq!(scan([2, 6, 0, -1], 3), [5, 6, 0, 3]);
        // A tick without a scan leaves them.
        t.observe(&Observation::default(), ms(4));
        assert_eq!(t.values().app, [5, 6, 0, 3]);
    }

    /// Reads the record as the next power-up does.
    fn power_up(e: MemEeprom) -> (Tally, Storage<MemEeprom>, TallyStep) {
        let mut s = Storage::new(e);
        let mut t = Tally::new();
        t.observe(&Observation::default(), ms(0));
        assert_eq!(t.eeprom_step(&mut s), TallyStep::UsedBus);
        let last = t.eeprom_step(&mut s);
        assert!(t.loaded());
        (t, s, last)
    }

    /// Lets the storage finish a write cycle.
    fn settle(s: &mut Storage<MemEeprom>, t: &mut u64) {
        let mut p = shared_protocol::program::Program::default();
        while !s.idle() {
            *t += 1;
            let _ = s.step(ms(*t), &mut p);
        }
    }

    #[test]
    fn written_at_stop_and_every_10_minutes_in_run_never_more_often() {
        let (mut t, mut s, _) = power_up(MemEeprom::new());
        let run = Observation {
            running: true,
            ..Default::default()
        };
        let mut at = 1;
        let mut writes = Vec::new();
        // 35 min in RUN: writes at 10, 20 and 30 min.
        t.observe(
            &Observation {
                run_started: true,
                ..run
            },
            ms(at),
        );
        while at < 35 * 60_000 {
            at += 1;
            t.observe(&run, ms(at));
            if t.eeprom_step(&mut s) == TallyStep::UsedBus {
                writes.push(at);
                settle(&mut s, &mut at);
            }
        }
        assert_eq!(writes.len(), 3, "{writes:?}");
        for (k, w) in writes.iter().enumerate() {
            let due = (k as u64 + 1) * 600_000;
            assert!((due..due + 20).contains(w), "{writes:?}");
        }
        // STOP: written at once.
        t.observe(
            &Observation {
                stopped: true,
                ..Default::default()
            },
            ms(at + 1),
        );
        assert_eq!(t.eeprom_step(&mut s), TallyStep::UsedBus);
        settle(&mut s, &mut at);
        // Nothing changed: no more writes, in STOP or in 10 min.
        for k in 0..700_000 {
            t.observe(&Observation::default(), ms(at + k));
            assert_eq!(t.eeprom_step(&mut s), TallyStep::Idle);
        }
        at += 700_000;
        // A change in STOP: written 10 min after the previous write, not before.
        t.observe(
            &Observation {
                saved: true,
                ..Default::default()
            },
            ms(at),
        );
        assert!(t.write_due());
        let since = t.answer(3, ms(at)).since_write_s;
        assert!(since.is_some_and(|s| (699..=701).contains(&s)), "{since:?}");
        // The next power-up finds everything.
        assert_eq!(t.eeprom_step(&mut s), TallyStep::UsedBus);
        settle(&mut s, &mut at);
        let want = *t.values();
        let (t2, _, last) = power_up(s.into_eeprom());
        assert_eq!(last, TallyStep::UsedBus);
        assert_eq!(*t2.values(), want);
        assert_eq!(want.run_minutes, 35);
        assert_eq!((want.run_starts, want.program_saves), (1, 1));
        assert_eq!(t2.answer(3, ms(5)).since_write_s, None);
    }

    /// The record's write is cut by the power after every byte: the next power-up finds
    /// the previous record or the new one, never a mix and never a reset.
    #[test]
    fn a_power_cut_at_any_byte_of_the_write_leaves_old_or_new() {
        // Two records written (both copies valid), then a third one cut.
        let (mut t, mut s, _) = power_up(MemEeprom::new());
        let mut at = 1;
        let write = |t: &mut Tally, s: &mut Storage<MemEeprom>, at: &mut u64, n: u8| {
            t.observe(
                &Observation {
                    fault: Some(n),
                    stopped: true,
                    ..Default::default()
                },
                ms(*at),
            );
            assert_eq!(t.eeprom_step(s), TallyStep::UsedBus);
            settle(s, at);
        };
        write(&mut t, &mut s, &mut at, 1);
        write(&mut t, &mut s, &mut at, 2);
        let old = *t.values();
        let image = s.into_eeprom();
        let mut seen = [0; 2];
        for cut in 0..=COUNTERS_BYTES as u32 {
            let (mut t, mut s, _) = power_up(image.clone());
            assert_eq!(*t.values(), old);
            s.eeprom().cut_power_after(cut);
            let mut at = 1;
            write(&mut t, &mut s, &mut at, 3);
            let new = *t.values();
            s.eeprom().restore_power();
            let (t2, _, last) = power_up(s.into_eeprom());
            assert_eq!(last, TallyStep::UsedBus, "cut after {cut}");
            match *t2.values() {
                v if v == old => seen[0] += 1,
                v if v == new => seen[1] += 1,
                v => panic!("cut after {cut}: {v:?}"),
            }
        }
        assert!(seen[0] > 0 && seen[1] > 0, "{seen:?}");
    }

    #[test]
    fn both_copies_bad_restart_at_zero_and_say_so() {
        let mut e = MemEeprom::new();
        for copy in 0..2 {
            e.start_write(copy_addr(copy), &[0x55; COUNTERS_BYTES])
                .unwrap();
            while !e.ready().unwrap() {}
        }
        let mut t = Tally::new();
        t.observe(
            &Observation {
                saved: true,
                ..Default::default()
            },
            ms(0),
        );
        let mut s = Storage::new(e);
        t.eeprom_step(&mut s);
        assert_eq!(t.eeprom_step(&mut s), TallyStep::Reset);
        // The count made before the read stays.
        assert_eq!(t.values().program_saves, 1);
        // A new chip restarts silently.
        let (_, _, last) = power_up(MemEeprom::new());
        assert_eq!(last, TallyStep::UsedBus);
    }
}
