//! `command_fresh`: the drive never applies a corrupted, stale or duplicated Q write, and
//! after the link recovers it holds the PLC's last write (issue 32 item 2).
//!
//! The rules, from the link's contract (/work/shared/spec/link.md "Delivery": commands
//! "applied exactly once and in order (sequence numbers); the newest value of a Q wins";
//! "a corrupted frame is never acted on") and the repo's decisions
//! (shared-protocol/docs/link.md "Delivery": newest wins, writes kept for the next
//! handshake; "the drive's copy always equals the PLC's last write"), for every Q the
//! PLC section writes and the drive section does not (`firmware_plc::app::drive_written_q`:
//! a Q the drive's own `WR` changes is the drive's):
//!
//! * **in order, never corrupted**: each value the drive's copy takes is one the PLC's
//!   copy held, at or after the PLC value the drive held before (the drive's values are
//!   a subsequence of the PLC's). A value the PLC never held is corrupted; one it held
//!   only before is stale or a duplicate applied again. 0 is always allowed (the drive
//!   powers up and each RUN starts with its Q cleared: link.md "RUN starts with Q
//!   cleared"), and moves nothing;
//! * **fresh after recovery**: once the PLC runs, both ends of the link have been up, no
//!   fault of the link or of either supply is under way or has ended, and the PLC's
//!   value has not changed, for [`SETTLE_NS`], the drive's copy equals it. (While bit
//!   errors hit the wires the link may stay up with every other frame lost: a write
//!   may then take longer; the rule waits for the end of the fault.)

pub const NAME: &str = "command_fresh";

/// Long enough for a write and its retransmissions after the link came back (the link
/// timeout is 50 ms, a retransmission round a few ms at 115200 baud).
pub const SETTLE_NS: u64 = 100_000_000;

/// What the rig shows of one Q at one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QView {
    pub t_ns: u64,
    pub plc: i16,
    pub drive: i16,
    /// The PLC runs and both ends of the link are up.
    pub live: bool,
}

/// One Q's history.
#[derive(Default)]
pub struct QTrack {
    /// The PLC's values in order (consecutive repeats once).
    history: Vec<i16>,
    /// Index in `history` of the drive's newest non-zero value.
    at: usize,
    drive: i16,
    /// Since when the PLC's value and the liveness have been unchanged.
    steady_since: u64,
    live: bool,
    /// Non-zero values the drive took, each found in order.
    pub applied: u64,
    /// Steps at which the freshness rule applied.
    pub settled: u64,
}

impl QTrack {
    /// A fault of the link or of a supply disturbs it until `until_ns` (its end).
    pub fn disturbed(&mut self, until_ns: u64) {
        self.steady_since = self.steady_since.max(until_ns);
    }

    pub fn check(&mut self, n: u8, v: &QView) -> Option<String> {
        if self.history.last() != Some(&v.plc) {
            self.history.push(v.plc);
            self.steady_since = self.steady_since.max(v.t_ns);
        }
        if v.live != self.live {
            self.live = v.live;
            self.steady_since = self.steady_since.max(v.t_ns);
        }
        if v.drive != self.drive {
            self.drive = v.drive;
            if v.drive != 0 {
                let ahead = self.history.get(self.at..).unwrap_or(&[]);
                match ahead.iter().position(|x| *x == v.drive) {
                    Some(i) => {
                        self.at += i;
                        self.applied += 1;
                    }
                    None => {
                        let what = if self.history.contains(&v.drive) {
                            "stale (the PLC had written a newer value since) or a duplicate"
                        } else {
                            "corrupted (the PLC never held it)"
                        };
                        return Some(format!("the drive applied Q{n:02} = {}: {what}", v.drive));
                    }
                }
            }
        }
        let settled = v.live && v.t_ns >= self.steady_since + SETTLE_NS;
        self.settled += u64::from(settled);
        if settled && v.drive != v.plc {
            return Some(format!(
                "Q{n:02}: the drive holds {} but the PLC's last write, {:.0} ms steady with the link up, is {}",
                v.drive,
                (v.t_ns - self.steady_since) as f64 / 1e6,
                v.plc
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(t_ms: u64, plc: i16, drive: i16) -> QView {
        QView {
            t_ns: t_ms * 1_000_000,
            plc,
            drive,
            live: true,
        }
    }

    fn run(trace: &[QView]) -> Option<(u64, String)> {
        let mut q = QTrack::default();
        trace
            .iter()
            .find_map(|x| q.check(5, x).map(|m| (x.t_ns / 1_000_000, m)))
    }

    #[test]
    fn in_order_values_and_a_reset_to_zero_pass() {
        let t = [
            v(0, 0, 0),
            v(1, 10, 0),
            v(2, 20, 10),
            v(3, 30, 30),
            v(4, 30, 0),
            v(5, 30, 30),
            v(200, 30, 30),
        ];
        assert_eq!(run(&t), None);
    }

    #[test]
    fn fires_on_a_corrupted_a_stale_and_a_missing_value() {
        let corrupted = [v(0, 10, 0), v(1, 10, 11)];
        let (t, m) = run(&corrupted).unwrap();
        assert!(t == 1 && m.contains("corrupted"), "{m}");
        let stale = [v(0, 10, 0), v(1, 20, 20), v(2, 20, 10)];
        let (_, m) = run(&stale).unwrap();
        assert!(m.contains("stale"), "{m}");
        let missing = [v(0, 10, 0), v(50, 10, 0), v(101, 10, 0)];
        let (t, m) = run(&missing).unwrap();
        assert!(t == 101 && m.contains("last write"), "{m}");
    }

    #[test]
    fn a_link_down_or_a_disturbance_defers_the_freshness_rule() {
        let mut q = QTrack::default();
        let down = QView {
            live: false,
            ..v(0, 10, 0)
        };
        assert_eq!(q.check(1, &down), None);
        assert_eq!(q.check(1, &v(60, 10, 0)), None);
        // Bit errors from 100 ms to 150 ms: the rule waits until 250 ms.
        q.disturbed(150_000_000);
        assert_eq!(q.check(1, &v(159, 10, 0)), None);
        assert_eq!(q.check(1, &v(249, 10, 0)), None);
        assert!(q.check(1, &v(251, 10, 0)).is_some());
    }
}
