//! `TON`, `TOF`, `IMP` and the `ACK` edge: per-line state machines driven by the scan's
//! monotonic millisecond time (never by counting scans).
//!
//! Each line owns one flag byte and one start time. A timer's output changes at the first
//! scan whose time is at least the preset after the scan that started it, so it never ends
//! early and ends at most one scan late.

use shared_protocol::units::Millis;

/// Input was 1 on the previous scan (TOF, IMP, ACK edge memory).
pub const PREV: u8 = 1 << 0;
/// Timing is under way (TON delay, TOF off-delay, IMP pulse).
pub const RUNNING: u8 = 1 << 1;
/// TON delay elapsed: latched so that a 49-day wrap of the clock cannot drop the output.
pub const DONE: u8 = 1 << 2;

/// Per-line state: `flags` of the constants above, `since` = when timing started.
pub struct LineState<'a> {
    pub flags: &'a mut u8,
    pub since: &'a mut Millis,
}

/// Preset operand value (0.1 s) to ms; negative presets (from Q) count as 0.
pub fn preset_ms(preset_ds: i16) -> u32 {
    u32::try_from(preset_ds).unwrap_or(0) * 100
}

/// Whether `preset_ds` (0.1 s) has elapsed at `now` since `since`.
fn elapsed(now: Millis, since: Millis, preset_ds: i16) -> bool {
    now.since(since) >= preset_ms(preset_ds)
}

/// On-delay: output 1 once the input has been 1 continuously for `preset_ds` (0.1 s),
/// measured from the first scan that saw it 1.
#[inline(always)]
pub fn on_delay(st: LineState<'_>, input: bool, now: Millis, preset_ds: i16) -> bool {
    if !input {
        *st.flags = 0;
        return false;
    }
    if *st.flags & DONE != 0 {
        return true;
    }
    if *st.flags & RUNNING == 0 {
        *st.flags = RUNNING;
        *st.since = now;
    }
    if elapsed(now, *st.since, preset_ds) {
        *st.flags = DONE;
        true
    } else {
        false
    }
}

/// Off-delay: output 1 while the input is 1 and until `preset_ds` (0.1 s) after the first
/// scan that saw it 0 again. An input that is 0 from RUN on never starts the delay.
#[inline(always)]
pub fn off_delay(st: LineState<'_>, input: bool, now: Millis, preset_ds: i16) -> bool {
    if input {
        *st.flags = PREV;
        return true;
    }
    if *st.flags & PREV != 0 {
        *st.flags = RUNNING;
        *st.since = now;
    }
    if *st.flags & RUNNING == 0 {
        return false;
    }
    if elapsed(now, *st.since, preset_ds) {
        *st.flags = 0;
        false
    } else {
        true
    }
}

/// Pulse: a rising edge of the input (not on the first scan) starts a `preset_ds` (0.1 s)
/// pulse; edges while it runs are ignored. A preset of 0 gives no pulse.
#[inline(always)]
pub fn pulse(
    st: LineState<'_>,
    input: bool,
    now: Millis,
    preset_ds: i16,
    first_scan: bool,
) -> bool {
    let edge = input && *st.flags & PREV == 0 && !first_scan;
    let mut running = *st.flags & RUNNING != 0;
    if running && elapsed(now, *st.since, preset_ds) {
        running = false;
    }
    if edge && !running {
        *st.since = now;
        // A preset of 0 ends the pulse at once.
        running = preset_ds > 0;
    }
    *st.flags = if input { PREV } else { 0 } | if running { RUNNING } else { 0 };
    running
}

/// Rising edge of the input since the previous scan (never on the first scan).
#[inline(always)]
pub fn rising_edge(flags: &mut u8, input: bool, first_scan: bool) -> bool {
    let edge = input && *flags & PREV == 0 && !first_scan;
    *flags = if input { PREV } else { 0 };
    edge
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Slot {
        flags: u8,
        since: Millis,
    }

    impl Slot {
        fn new() -> Self {
            Slot {
                flags: 0,
                since: Millis(0),
            }
        }
        fn st(&mut self) -> LineState<'_> {
            LineState {
                flags: &mut self.flags,
                since: &mut self.since,
            }
        }
    }

    #[test]
    fn preset_is_tenths_of_a_second_and_negative_is_zero() {
        assert_eq!(preset_ms(100), 10_000);
        assert_eq!(preset_ms(9999), 999_900);
        assert_eq!(preset_ms(-5), 0);
        assert_eq!(preset_ms(i16::MAX), 3_276_700);
    }

    #[test]
    fn on_delay_counts_from_first_scan_with_input() {
        let mut s = Slot::new();
        assert!(!on_delay(s.st(), false, Millis(0), 10));
        assert!(!on_delay(s.st(), true, Millis(10), 10));
        assert!(!on_delay(s.st(), true, Millis(1009), 10));
        assert!(on_delay(s.st(), true, Millis(1010), 10));
        assert!(on_delay(s.st(), true, Millis(5000), 10));
        // Input drop resets; a new delay starts from scratch.
        assert!(!on_delay(s.st(), false, Millis(5001), 10));
        assert!(!on_delay(s.st(), true, Millis(5002), 10));
        assert!(!on_delay(s.st(), true, Millis(6001), 10));
        assert!(on_delay(s.st(), true, Millis(6002), 10));
    }

    #[test]
    fn on_delay_stays_on_across_clock_wrap() {
        let mut s = Slot::new();
        let t0 = Millis(u32::MAX - 100);
        assert!(!on_delay(s.st(), true, t0, 5));
        assert!(!on_delay(s.st(), true, t0.add(499), 5));
        assert!(on_delay(s.st(), true, t0.add(500), 5));
        // A full wrap later the latched output is still on.
        assert!(on_delay(s.st(), true, t0.add(200), 5));
    }

    #[test]
    fn on_delay_preset_zero_follows_input() {
        let mut s = Slot::new();
        assert!(on_delay(s.st(), true, Millis(3), 0));
        assert!(!on_delay(s.st(), false, Millis(4), 0));
    }

    #[test]
    fn off_delay_holds_after_fall() {
        let mut s = Slot::new();
        assert!(!off_delay(s.st(), false, Millis(0), 10));
        assert!(off_delay(s.st(), true, Millis(10), 10));
        assert!(off_delay(s.st(), false, Millis(20), 10));
        assert!(off_delay(s.st(), false, Millis(1019), 10));
        assert!(!off_delay(s.st(), false, Millis(1020), 10));
        assert!(!off_delay(s.st(), false, Millis(3000), 10));
        // Input back during the delay: output stays 1 and the delay restarts on the fall.
        assert!(off_delay(s.st(), true, Millis(4000), 10));
        assert!(off_delay(s.st(), false, Millis(4100), 10));
        assert!(off_delay(s.st(), true, Millis(4500), 10));
        assert!(off_delay(s.st(), false, Millis(4600), 10));
        assert!(off_delay(s.st(), false, Millis(5599), 10));
        assert!(!off_delay(s.st(), false, Millis(5600), 10));
    }

    #[test]
    fn off_delay_preset_zero_follows_input() {
        let mut s = Slot::new();
        assert!(off_delay(s.st(), true, Millis(0), 0));
        assert!(!off_delay(s.st(), false, Millis(1), 0));
    }

    #[test]
    fn pulse_has_preset_length_and_is_not_retriggered() {
        let mut s = Slot::new();
        assert!(!pulse(s.st(), false, Millis(0), 7, true));
        assert!(pulse(s.st(), true, Millis(100), 7, false));
        assert!(pulse(s.st(), false, Millis(200), 7, false));
        // A new edge during the pulse does not extend it.
        assert!(pulse(s.st(), true, Millis(300), 7, false));
        assert!(pulse(s.st(), true, Millis(799), 7, false));
        assert!(!pulse(s.st(), true, Millis(800), 7, false));
        // Input still high: no new pulse without a new edge.
        assert!(!pulse(s.st(), true, Millis(2000), 7, false));
        assert!(!pulse(s.st(), false, Millis(2100), 7, false));
        assert!(pulse(s.st(), true, Millis(2200), 7, false));
    }

    #[test]
    fn pulse_sees_no_edge_on_first_scan() {
        let mut s = Slot::new();
        assert!(!pulse(s.st(), true, Millis(0), 7, true));
        assert!(!pulse(s.st(), true, Millis(10), 7, false));
    }

    #[test]
    fn pulse_preset_zero_gives_nothing() {
        let mut s = Slot::new();
        assert!(!pulse(s.st(), false, Millis(0), 0, false));
        assert!(!pulse(s.st(), true, Millis(1), 0, false));
        assert!(!pulse(s.st(), true, Millis(2), 0, false));
    }

    #[test]
    fn edge_needs_a_previous_scan() {
        let mut f = 0;
        assert!(!rising_edge(&mut f, true, true));
        assert!(!rising_edge(&mut f, true, false));
        assert!(!rising_edge(&mut f, false, false));
        assert!(rising_edge(&mut f, true, false));
    }
}
