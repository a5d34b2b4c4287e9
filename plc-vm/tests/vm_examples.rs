//! The PLC examples of the source's section 4.1 (seed lines 500-900), each run on its own
//! program text and checked against what its prose says.

mod vm_support;

use vm_support::Rig;

/// Source: "RS flip-flop with output on O01": D00 sets, D01 resets.
const RS_FLIP_FLOP: &str = include_str!("../../shared-protocol/programs/rs_flipflop.plc");

#[test]
fn rs_flip_flop() {
    let mut r = Rig::new(RS_FLIP_FLOP);
    assert!(!r.step(10).output(1));
    r.d(0, true);
    assert!(r.step(10).output(1), "set");
    r.d(0, false);
    assert!(r.step(10).output(1), "holds after set released");
    r.d(1, true);
    assert!(!r.step(10).output(1), "reset");
    r.d(1, false);
    assert!(!r.step(10).output(1), "holds after reset released");
    // Both pressed: reset comes last in the program and wins.
    r.d(0, true);
    r.d(1, true);
    assert!(!r.step(10).output(1));
}

/// Source: "T flip-flop: first press on, second press off".
const T_FLIP_FLOP: &str = include_str!("../../shared-protocol/programs/t_flipflop.plc");

#[test]
fn t_flip_flop() {
    let mut r = Rig::new(T_FLIP_FLOP);
    assert!(!r.step(10).output(0));
    // First press switches on; holding the button does not toggle again.
    r.d(0, true);
    for _ in 0..5 {
        assert!(r.step(10).output(0));
    }
    r.d(0, false);
    assert!(r.step(10).output(0), "stays on after release");
    let (down, up) = r.press(0, 10);
    assert!(
        !down.output(0) && !up.output(0),
        "second press switches off"
    );
    let (down, up) = r.press(0, 10);
    assert!(down.output(0) && up.output(0), "third press on again");
}

#[test]
fn t_flip_flop_button_held_at_run_start_does_not_toggle() {
    let mut r = Rig::new(T_FLIP_FLOP);
    r.d(0, true);
    assert!(!r.scan_at(0).output(0));
    assert!(!r.step(10).output(0));
}

/// Source: "O01 = (D00 & D01) | (D02 & D03)".
const AND_OR: &str = include_str!("../../shared-protocol/programs/and_or.plc");

#[test]
fn and_or_expression_all_inputs() {
    let mut r = Rig::new(AND_OR);
    for d in 0u16..16 {
        r.inputs.digital = d;
        let bit = |i: u16| d & (1 << i) != 0;
        let expect = (bit(0) && bit(1)) || (bit(2) && bit(3));
        assert_eq!(r.step(10).output(1), expect, "D = {d:04b}");
        assert_eq!(r.out.outputs & !0b10, 0, "no other output");
    }
}

/// Source: "counts up on the falling edge of D00; at 100 it resets and stops counting".
const COUNTER_TO_100: &str = include_str!("../../shared-protocol/programs/counter100.plc");

#[test]
fn counter_to_100_with_let() {
    let mut r = Rig::new(COUNTER_TO_100);
    r.step(10);
    for i in 1..=99 {
        // Only the falling edge counts, once per press.
        r.d(0, true);
        r.step(10);
        r.step(10);
        assert_eq!(r.vm.q(5), i - 1, "press {i}: no count while held");
        r.d(0, false);
        r.step(10);
        assert_eq!(r.vm.q(5), i, "release {i} counts");
        r.step(10);
        assert_eq!(r.vm.q(5), i, "one count per release");
    }
    assert!(!r.vm.b(1));
    r.press(0, 10);
    // The 100th count sets B01 in the same scan.
    assert_eq!(r.vm.q(5), 100);
    assert!(r.vm.b(1));
    r.step(10);
    assert_eq!(r.vm.q(5), 0, "reset at 100");
    for _ in 0..10 {
        r.press(0, 10);
        assert_eq!(r.vm.q(5), 0, "stopped");
    }
}

/// Source: "on-delay of 10 s".
const ON_DELAY_10S: &str = include_str!("../../shared-protocol/programs/on_delay_10s.plc");

#[test]
fn on_delay_10_s() {
    let mut r = Rig::new(ON_DELAY_10S);
    r.scan_at(0);
    r.d(0, true);
    let t0 = 1234;
    assert!(!r.scan_at(t0).output(4));
    let mut t = t0;
    while t < t0 + 10_000 {
        assert!(!r.scan_at(t).output(4), "early at {t}");
        t += 7;
    }
    assert!(r.scan_at(t).output(4), "on at the first scan after 10 s");
    assert!(r.scan_at(t + 60_000).output(4), "stays on");
    r.d(0, false);
    assert!(!r.step(1).output(4), "off with the input");
    // Interrupted input: the delay starts again.
    r.d(0, true);
    let t1 = r.now + 5;
    r.scan_at(t1);
    r.scan_at(t1 + 9_000);
    r.d(0, false);
    r.scan_at(t1 + 9_001);
    r.d(0, true);
    assert!(!r.scan_at(t1 + 10_500).output(4));
    assert!(!r.scan_at(t1 + 19_500).output(4));
    assert!(r.scan_at(t1 + 20_500).output(4));
}

/// Source: "loads A01, adds 10 and multiplies by three" (the project copy follows the
/// prose: MUL; the listing's DIV is covered by `div_*` tests). `LCD` shows P.
const ARITHMETIC: &str = include_str!("../../shared-protocol/programs/arithmetic.plc");

#[test]
fn arithmetic() {
    let mut r = Rig::new(ARITHMETIC);
    for a in [0u16, 1, 2, 5, 500, 1023] {
        r.inputs.analog[1] = a;
        let expect = (i16::try_from(a).unwrap() + 10) * 3;
        assert_eq!(r.step(10).lcd[0], Some(expect), "A01 = {a}");
        assert_eq!(r.out.warning, None);
    }
}

/// Source: "shows A02 and the counted Q02 on the LCD" (the project copy is the listing).
const LCD: &str = include_str!("../../shared-protocol/programs/lcd.plc");

/// The source's own LCD listing: only the edge is on the stack before `CTU`.
const LCD_SOURCE_LISTING: &str = "
150 LD  A02
151 LCD
152 LD  D00
153 LET B00
154 CTU Q02
155 LD  Q02
156 LCD
";

fn check_lcd_counts_presses(text: &str) {
    let mut r = Rig::new(text);
    r.inputs.analog[2] = 321;
    assert_eq!(r.step(10).lcd, [Some(321), Some(0), None, None]);
    // Rising edges of D00 are counted, once per press.
    for i in 1..=3 {
        r.d(0, true);
        assert_eq!(r.step(10).lcd[1], Some(i), "press {i}");
        assert_eq!(r.step(10).lcd[1], Some(i), "held {i}");
        r.d(0, false);
        assert_eq!(r.step(10).lcd[1], Some(i));
    }
    r.inputs.analog[2] = 1000;
    assert_eq!(r.step(10).lcd, [Some(1000), Some(3), None, None]);
}

#[test]
fn lcd_shows_a02_and_counter() {
    check_lcd_counts_presses(LCD);
}

#[test]
fn lcd_source_listing_counts_with_the_lone_bit_rule() {
    // One bit loaded before CTU: it is the count input (docs/vm.md).
    check_lcd_counts_presses(LCD_SOURCE_LISTING);
}

/// Source REV example: D01 requests reverse, D02 forward, B00 holds the request.
const REV_BUTTONS: &str = include_str!("../../shared-protocol/programs/rev_buttons.plc");

#[test]
fn rev_buttons_send_only_changes() {
    let mut r = Rig::new(REV_BUTTONS);
    assert_eq!(
        r.step(10).rev_request,
        Some(false),
        "first REV syncs the drive"
    );
    assert_eq!(r.step(10).rev_request, None);
    let (down, up) = r.press(1, 10);
    assert_eq!(down.rev_request, Some(true));
    assert_eq!(up.rev_request, None);
    let (down, _) = r.press(1, 10);
    assert_eq!(down.rev_request, None, "already reverse");
    let (down, up) = r.press(2, 10);
    assert_eq!(down.rev_request, Some(false));
    assert_eq!(up.rev_request, None);
}

/// Source WR example: "only when D00 = 1 is K00 written to Q01 and sent to the drive".
const CONDITIONAL_WRITE: &str =
    include_str!("../../shared-protocol/programs/conditional_write.plc");

#[test]
fn conditional_write_sends_q() {
    let mut r = Rig::new(CONDITIONAL_WRITE);
    let out = r.step(10);
    assert_eq!(out.q_dirty, 0);
    assert_eq!(r.vm.q(1), 0);
    r.d(0, true);
    let out = r.step(10);
    assert_eq!(out.dirty_q().collect::<Vec<_>>(), vec![1]);
    assert_eq!(r.vm.q(1), 100);
}

/// Source's commissioning example: COM raw and as volts (VLT), and the hardware trip
/// levels (its trimmers) as the drive reports them (IHW, UHW).
const COM_MONITOR: &str = include_str!("../../shared-protocol/programs/com_monitor.plc");

#[test]
fn com_vlt_and_the_trimmers() {
    let mut r = Rig::new(COM_MONITOR);
    r.inputs.drive.com = 682;
    r.inputs.drive.ihw = shared_protocol::units::CentiAmps(250);
    r.inputs.drive.uhw = shared_protocol::units::Volts(38);
    // 682 * 450 / 1023 = 300.0 (30.0 V).
    assert_eq!(r.step(10).lcd, [Some(682), Some(300), Some(250), Some(38)]);
}

#[test]
fn amp_converts_com_to_tenths_of_an_amp() {
    // The source's third display: a current trimmer on COM, LD AMP.
    let mut r = Rig::new("150 LD COM\n151 LD AMP\n152 LCD\n");
    r.inputs.drive.com = 682;
    // (682 - 512) * 100 / 512 = 33.2 (3.3 A).
    assert_eq!(r.step(10).lcd[0], Some(33));
}

#[test]
fn div_by_zero_q_warns_with_line_and_goes_on() {
    let mut r = Rig::new(
        "
150 LD  A00
151 DIV Q10
152 LCD
153 LDC B00
154 WR  O00
",
    );
    r.inputs.analog[0] = 100;
    let out = r.step(10);
    assert_eq!(out.lcd[0], Some(0));
    assert_eq!(out.warning, Some(plc_vm::Warning::Div0 { line: 151 }));
    assert!(out.output(0));
}
