//! The PLC lines 150-175 of the source's full motor program (program.md section 5),
//! checked against what its prose says: START toggles run, the speed setpoint Q02 follows
//! A01 while running, REV stops, flips the direction and restarts after 7 s, the
//! switching frequency Q00 = A00 x 10 is written every scan, and nothing starts at RUN.

mod vm_support;

use vm_support::Rig;

const MOTOR: &str = include_str!("../../shared-protocol/programs/motor.plc");

const START: u8 = 0;
const REV: u8 = 1;
/// Scan period used by these tests (ms).
const SCAN: u32 = 10;

fn rig() -> Rig {
    let mut r = Rig::new(MOTOR);
    r.inputs.analog[0] = 562; // switching frequency 5620 Hz
    r.inputs.analog[1] = 700; // speed setpoint
    r
}

fn running(r: &Rig) -> bool {
    r.vm.b(1)
}

#[test]
fn nothing_starts_on_the_first_scan_or_later_without_start() {
    let mut r = rig();
    let out = r.scan_at(0);
    assert!(
        !running(&r),
        "LET B04 must not see an edge on the first scan"
    );
    assert_eq!(r.vm.q(2), 0);
    assert_eq!(out.rev_request, Some(false), "first scan syncs forward");
    for _ in 0..2000 {
        let out = r.step(SCAN);
        assert!(!running(&r));
        assert_eq!(r.vm.q(2), 0, "setpoint stays 0 without START");
        assert_eq!(out.rev_request, None);
    }
}

#[test]
fn buttons_held_at_power_up_start_nothing() {
    let mut r = rig();
    r.d(START, true);
    r.d(REV, true);
    r.scan_at(0);
    for _ in 0..1000 {
        r.step(SCAN);
        assert!(!running(&r));
        assert_eq!(r.vm.q(2), 0);
    }
}

#[test]
fn switching_frequency_written_every_scan_and_lcd_fields() {
    let mut r = rig();
    for a0 in [0u16, 49, 562, 999] {
        r.inputs.analog[0] = a0;
        let out = r.step(SCAN);
        assert_ne!(out.q_dirty & 1, 0, "Q00 written every scan");
        assert_eq!(r.vm.q(0), i16::try_from(a0).unwrap() * 10);
        assert_eq!(out.lcd, [Some(700), Some(r.vm.q(0)), None, None]);
    }
}

#[test]
fn start_toggles_run_and_q02_follows_a01() {
    let mut r = rig();
    r.scan_at(0);
    let (down, _) = r.press(START, SCAN);
    assert!(running(&r));
    assert_ne!(down.q_dirty & (1 << 2), 0);
    assert_eq!(r.vm.q(2), 700);
    for a1 in [0u16, 300, 1023] {
        r.inputs.analog[1] = a1;
        let out = r.step(SCAN);
        assert_ne!(
            out.q_dirty & (1 << 2),
            0,
            "written every scan while running"
        );
        assert_eq!(r.vm.q(2), i16::try_from(a1).unwrap());
    }
    r.press(START, SCAN);
    assert!(!running(&r));
    assert_eq!(r.vm.q(2), 0, "STOP writes setpoint 0");
    r.inputs.analog[1] = 800;
    r.step(SCAN);
    assert_eq!(r.vm.q(2), 0);
}

#[test]
fn rev_stops_flips_direction_and_restarts_after_7_s() {
    let mut r = rig();
    r.scan_at(0);
    r.press(START, SCAN);
    assert!(running(&r));

    // REV pressed: direction request reverse, setpoint to 0, 7 s pulse starts.
    r.d(REV, true);
    let t_rev = r.now + SCAN;
    let out = r.scan_at(t_rev);
    assert_eq!(out.rev_request, Some(true));
    assert!(!running(&r));
    r.d(REV, false);
    let out = r.step(SCAN);
    assert_eq!(out.rev_request, None, "sent once");
    assert_eq!(r.vm.q(2), 0, "setpoint 0 while the motor ramps down");

    // Held at 0 until 7 s after REV, restarted on the first scan at or after it.
    let mut t = r.now;
    while t + SCAN < t_rev + 7000 {
        t += SCAN;
        r.scan_at(t);
        assert!(!running(&r), "restart early at {} ms", t - t_rev);
        assert_eq!(r.vm.q(2), 0);
    }
    r.scan_at(t_rev + 7000);
    assert!(running(&r), "restart 7 s after REV");
    r.step(SCAN);
    assert_eq!(r.vm.q(2), 700, "setpoint returns");

    // REV again: back to forward, same cycle.
    let (down, up) = r.press(REV, SCAN);
    assert_eq!(down.rev_request, Some(false));
    assert_eq!(up.rev_request, None);
    assert!(!running(&r));
}

#[test]
fn rev_while_stopped_flips_direction_and_starts_after_7_s() {
    // As listed, REV also starts a stopped motor 7 s later (line 170 sets B01).
    let mut r = rig();
    r.scan_at(0);
    r.step(SCAN);
    r.d(REV, true);
    let out = r.scan_at(100);
    assert_eq!(out.rev_request, Some(true));
    r.d(REV, false);
    r.scan_at(7099);
    assert!(!running(&r));
    r.scan_at(7100);
    assert!(running(&r));
}

#[test]
fn scan_timing_jitter_never_restarts_early() {
    for period in [1u32, 3, 7, 20, 49, 100, 333] {
        let mut r = rig();
        r.scan_at(0);
        r.press(START, period);
        r.d(REV, true);
        let t_rev = r.now + period;
        r.scan_at(t_rev);
        r.d(REV, false);
        let mut t = t_rev;
        loop {
            t += period;
            r.scan_at(t);
            if running(&r) {
                break;
            }
        }
        let late = t - (t_rev + 7000);
        assert!(t >= t_rev + 7000, "period {period}: early");
        assert!(late < period, "period {period}: {late} ms late");
    }
}
