//! `trip_logged_once`: every drive trip the PLC learns of is in its fault log exactly
//! once, with its code (issue 32 item 2; service.md 6 "the fault log"; the PLC logs each
//! drive fault report as it receives it, `firmware-plc/src/app.rs` `PlcEvent::DriveFault`;
//! link.md: the drive's fault report is a reliable message, applied once).
//!
//! Two halves, both on what the rig shows:
//! * **learned**: a drive trip latched while both ends of the link are up, with no fault
//!   of the link, of either supply or inside an EEPROM write under way or starting in
//!   the next [`LEARN_NS`], makes the PLC queue a fault-log entry with that code within
//!   [`LEARN_NS`] (the report is one frame and its acknowledgement; the link's timeout is
//!   50 ms);
//! * **once**: whenever the PLC's storage has no log entry queued or in flight, every
//!   entry it ever queued is in the log exactly once. A PLC power cut may lose the
//!   entries queued or in flight at that moment (the queue is RAM; the page write in
//!   flight is torn and fails its CRC): each such entry may then be there once or not at
//!   all, never twice. While the log may have wrapped (more entries queued than it
//!   holds) the count is not checked.

use firmware_plc::storage::{FaultEntry, FAULT_LOG_ENTRIES};

pub const NAME: &str = "trip_logged_once";

/// How long the PLC has to learn of a trip and queue its log entry.
pub const LEARN_NS: u64 = 100_000_000;

/// An entry the log must hold: at least `min`, at most `max` times.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Expect {
    entry: FaultEntry,
    min: u32,
    max: u32,
}

#[derive(Default)]
pub struct TripLog {
    /// The log entries queued or in flight at the last step, queue order.
    queued: Vec<FaultEntry>,
    expected: Vec<Expect>,
    /// Entries ever queued (beyond [`FAULT_LOG_ENTRIES`] the log may have wrapped).
    total: usize,
    /// Drive trips the PLC must learn of: (latched at, code).
    learn: Vec<(u64, u8)>,
    /// Drive trips it had to learn of and did.
    pub learned: u64,
    /// No disturbance is under way from here on.
    quiet_from: u64,
}

impl TripLog {
    /// The drive latched `code` at `t_ns`; `link_up`: both ends of the link are up.
    pub fn drive_trip(&mut self, t_ns: u64, code: u8, link_up: bool) {
        if link_up && t_ns >= self.quiet_from {
            self.learn.push((t_ns, code));
        }
    }

    /// A fault of the link, a supply or an EEPROM write is under way until `until_ns`: a
    /// trip before that may legitimately never reach the PLC in time.
    pub fn disturbed(&mut self, until_ns: u64) {
        self.learn.clear();
        self.quiet_from = self.quiet_from.max(until_ns);
    }

    /// The log entries in the PLC's storage queue (the one in flight first) at `t_ns`.
    /// `Some(true)` when the queue has just drained of log entries (the runner then
    /// reads the log for [`TripLog::check_log`]); `Err` when a trip went unlearned.
    pub fn step(&mut self, t_ns: u64, queue: &[FaultEntry]) -> Result<bool, String> {
        let new = fifo_new(&self.queued, queue);
        for e in new {
            self.total += 1;
            if let Some(i) = self.learn.iter().position(|(_, c)| *c == e.code) {
                self.learn.remove(i);
                self.learned += 1;
            }
            match self.expected.iter_mut().find(|x| x.entry == *e) {
                Some(x) => {
                    x.min += 1;
                    x.max += 1;
                }
                None => self.expected.push(Expect {
                    entry: *e,
                    min: 1,
                    max: 1,
                }),
            }
        }
        let drained = !self.queued.is_empty() && queue.is_empty();
        self.queued = queue.to_vec();
        if let Some((t, code)) = self.learn.iter().find(|(t, _)| t_ns > t + LEARN_NS) {
            return Err(format!(
                "the drive tripped with code {code} at {:.6} s, the link up, and the PLC queued no log entry with that code within {} ms",
                *t as f64 / 1e9,
                LEARN_NS / 1_000_000
            ));
        }
        Ok(drained)
    }

    /// The PLC lost its supply: what it had queued may be lost.
    pub fn cut(&mut self) {
        for e in self.queued.drain(..) {
            if let Some(x) = self.expected.iter_mut().find(|x| x.entry == e) {
                x.min = x.min.saturating_sub(1);
            }
        }
    }

    /// The log as it reads now, with nothing queued: each entry as often as expected.
    pub fn check_log(&self, log: &[FaultEntry]) -> Option<String> {
        if self.total > FAULT_LOG_ENTRIES {
            return None;
        }
        for x in &self.expected {
            let n = log.iter().filter(|e| **e == x.entry).count() as u32;
            if n < x.min || n > x.max {
                let want = if x.min == x.max {
                    format!("{}", x.min)
                } else {
                    format!("{}-{}", x.min, x.max)
                };
                return Some(format!(
                    "fault-log entry code {} (power-up {}, {} s) is in the log {n} times, expected {want}",
                    x.entry.code, x.entry.power_cycle, x.entry.uptime_s
                ));
            }
        }
        None
    }
}

/// The entries of `now` that joined since `before` (a FIFO: entries leave at the front,
/// join at the back): the tail of `now` after the longest suffix of `before` it starts
/// with.
fn fifo_new<'a>(before: &[FaultEntry], now: &'a [FaultEntry]) -> &'a [FaultEntry] {
    for k in 0..=before.len() {
        let rest = &before[k..];
        if now.starts_with(rest) {
            return &now[rest.len()..];
        }
    }
    now
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(code: u8, s: u32) -> FaultEntry {
        FaultEntry::new(code, 1, s)
    }

    #[test]
    fn queue_diffs_find_the_joined_entries() {
        let (a, b, c) = (e(9, 1), e(3, 1), e(5, 2));
        assert_eq!(fifo_new(&[], &[a, b]), [a, b]);
        assert_eq!(fifo_new(&[a, b], &[b, c]), [c]);
        assert_eq!(fifo_new(&[a, b], &[b]), []);
        assert_eq!(fifo_new(&[a], &[c]), [c]);
    }

    #[test]
    fn fires_on_an_entry_lost_or_logged_twice_without_a_cut() {
        let mut t = TripLog::default();
        assert_eq!(t.step(0, &[e(9, 1)]), Ok(false));
        assert_eq!(t.step(1, &[]), Ok(true));
        assert_eq!(t.check_log(&[e(9, 1)]), None);
        let m = t.check_log(&[]).unwrap();
        assert!(m.contains("0 times, expected 1"), "{m}");
        let m = t.check_log(&[e(9, 1), e(9, 1)]).unwrap();
        assert!(m.contains("2 times"), "{m}");
    }

    #[test]
    fn a_cut_may_lose_the_entries_in_flight_but_never_doubles_them() {
        let mut t = TripLog::default();
        t.step(0, &[e(9, 1), e(3, 1)]).unwrap();
        t.cut();
        assert_eq!(t.check_log(&[]), None);
        assert_eq!(t.check_log(&[e(9, 1)]), None);
        assert!(t.check_log(&[e(3, 1), e(3, 1)]).is_some());
    }

    #[test]
    fn fires_on_a_trip_the_plc_never_logged() {
        let mut t = TripLog::default();
        t.drive_trip(1_000, 9, true);
        assert_eq!(t.step(50_000_000, &[]), Ok(false));
        let m = t.step(1_000 + LEARN_NS + 1, &[]).unwrap_err();
        assert!(m.contains("code 9"), "{m}");
        // Logged in time, or the link down, or disturbed: nothing.
        let mut t = TripLog::default();
        t.drive_trip(1_000, 9, true);
        t.drive_trip(1_000, 3, false);
        t.step(2_000, &[e(9, 0)]).unwrap();
        assert_eq!(t.step(LEARN_NS * 2, &[]), Ok(true));
        let mut t = TripLog::default();
        t.drive_trip(1_000, 9, true);
        t.disturbed(2_000);
        assert_eq!(t.step(LEARN_NS * 2, &[]), Ok(false));
        // A trip while bit errors still hit the wires (until 5 ms).
        let mut t = TripLog::default();
        t.disturbed(5_000_000);
        t.drive_trip(1_000_000, 9, true);
        assert_eq!(t.step(LEARN_NS * 2, &[]), Ok(false));
    }
}
