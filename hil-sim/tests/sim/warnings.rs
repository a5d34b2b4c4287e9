//! Run-time warnings reach the user: the drive's clamped `PWF` and the
//! PLC's `DIV0 @ line` show on the LCD status line, in the run summary and in the CSV's
//! `warn` column.

use super::common::*;
use hil_sim::record::{header, row};

fn warn_col(s: &hil_sim::sim::Sample) -> String {
    let h = header();
    let k = h.split(',').position(|c| c == "warn").expect("warn column");
    row(s).split(',').nth(k).unwrap_or("").to_string()
}

#[test]
fn a_clamped_pwf_is_on_the_lcd_in_the_summary_and_in_the_csv() {
    // The motor example with the switching-frequency pot A00 at 0: PWF Q00 = 0 Hz. The
    // drive switches at its minimum, 488 Hz, and says so.
    let scen = "[[event]]\nat_s = 0.0\nset = { A00 = 0, A01 = 300 }\n\
                [[event]]\nat_s = 0.5\npress = \"D00\"\n\
                [[event]]\nat_s = 6.0\nset = { A00 = 500 }\n";
    let r = run_text(MOTOR_PLC, scen, 4.5);
    assert!(r.faults.is_empty());
    let s = at(&r.samples, 2.0);
    assert_eq!(
        s.lcd[1],
        Some(0),
        "the program's own field still shows A00 x 10"
    );
    assert_eq!(warn_col(s), "PWF 488Hz @ 000");
    let summary = r.summary();
    assert!(
        summary.contains("PWF 488Hz @ 000 (drive): line 000: PWF asks for 0 Hz, outside 488..20000 Hz: switching at 488 Hz"),
        "{summary}"
    );
    // The status row rotates the alert with the main hint every 2 s; the last redraw
    // (4.4 s) is an alert turn.
    assert_eq!(
        r.lcd.row(3).trim_end(),
        "W:PWF 488Hz @ 000",
        "{}",
        r.lcd.framed()
    );
    // Once the pot asks for 5000 Hz the warning is gone.
    let r = run_text(MOTOR_PLC, scen, 6.5);
    assert_eq!(warn_col(r.samples.last().unwrap()), "");
    assert_eq!(r.samples.last().unwrap().lcd[1], Some(5000));
}

#[test]
fn div0_is_in_the_summary_and_in_the_csv() {
    let prog = "150 LD  A00\n151 DIV Q10\n152 LCD\n";
    let r = run_text(prog, "[[event]]\nat_s = 0\nset = { A00 = 100 }\n", 0.5);
    let s = r.samples.last().unwrap();
    assert_eq!(s.lcd[0], Some(0));
    assert_eq!(warn_col(s), "DIV0 @ 151");
    assert!(r.summary().contains("DIV0 @ 151 (PLC)"), "{}", r.summary());
    // No warning anywhere: the summary says so.
    let r = run_text("150 LD A00\n151 LCD\n", "", 0.2);
    assert!(r.summary().contains("warnings: none"));
    assert_eq!(warn_col(r.samples.last().unwrap()), "");
}
