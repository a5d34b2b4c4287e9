//! The CSV record (hil-sim.md "CSV columns"): the listed columns first, in that order.
//!
//! Numbers are written with a fixed number of decimals so that two runs give the same
//! bytes and the file stays small.

use std::io::{self, Write};

use shared_protocol::program::{DIGITAL_INPUTS, DIGITAL_OUTPUTS};

use crate::sim::Sample;

/// The header row.
pub fn header() -> String {
    let mut cols: Vec<String> = [
        "t_s",
        "f_cmd_hz",
        "dir",
        "m",
        "pwm_on",
        "fault",
        "u_dc_v",
        "i_a_a",
        "i_b_a",
        "i_c_a",
        "speed_rpm",
        "torque_nm",
        "brake",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    cols.extend((0..DIGITAL_INPUTS).map(|n| format!("D{n:02}")));
    cols.extend((0..DIGITAL_OUTPUTS).map(|n| format!("O{n:02}")));
    cols.extend((0..8).map(|n| format!("Q{n:02}")));
    cols.extend((0..4).map(|n| format!("lcd{n}")));
    cols.extend(
        ["duty_a", "duty_b", "duty_c", "u_ab_v", "warn"]
            .iter()
            .map(|s| s.to_string()),
    );
    // safety.md 11, appended.
    cols.extend(
        ["sf_req", "sf_st", "sdc", "sft_s", "turns"]
            .iter()
            .map(|s| s.to_string()),
    );
    cols.join(",")
}

/// One data row.
pub fn row(s: &Sample) -> String {
    let mut r = String::with_capacity(160);
    use std::fmt::Write as _;
    let _ = write!(
        r,
        "{},{},{},{},{},{},{},{},{},{},{},{},{}",
        num(s.t_ns as f64 * 1e-9, 6),
        num(s.f_cmd_hz, 1),
        s.dir,
        num(s.m, 3),
        u8::from(s.pwm_on),
        s.fault,
        num(s.u_dc_v, 3),
        num(s.i_abc_a[0], 4),
        num(s.i_abc_a[1], 4),
        num(s.i_abc_a[2], 4),
        num(s.speed_rpm, 2),
        num(s.torque_nm, 5),
        u8::from(s.brake),
    );
    for n in 0..DIGITAL_INPUTS {
        let _ = write!(r, ",{}", (s.digital_in >> n) & 1);
    }
    for n in 0..DIGITAL_OUTPUTS {
        let _ = write!(r, ",{}", (s.digital_out >> n) & 1);
    }
    for q in s.q {
        let _ = write!(r, ",{q}");
    }
    for f in s.lcd {
        match f {
            Some(v) => {
                let _ = write!(r, ",{v}");
            }
            None => r.push(','),
        }
    }
    for d in s.duty_abc {
        let _ = write!(r, ",{}", num(d, 4));
    }
    let _ = write!(r, ",{},{}", num(s.u_ab_v, 3), s.warn.short());
    let _ = write!(
        r,
        ",{},{},{},{}.{},{}",
        s.sf_req,
        s.sf_st,
        u8::from(s.sdc),
        s.sft_ds / 10,
        s.sft_ds % 10,
        turns(s.turns_e4)
    );
    if let Some(l) = &s.lift {
        let _ = write!(
            r,
            ",{},{},{},{},{},{},{}",
            num(l.car_mm, 2),
            num(l.car_mms, 2),
            l.at_floor,
            num(l.door, 3),
            u8::from(l.brake_engaged),
            u8::from(l.vane_l),
            u8::from(l.vane_r)
        );
    }
    r
}

/// 10⁻⁴ turn as turns with 4 decimals, exactly (no float).
fn turns(e4: i64) -> String {
    let sign = if e4 < 0 { "-" } else { "" };
    let a = e4.unsigned_abs();
    format!("{sign}{}.{:04}", a / 10_000, a % 10_000)
}

/// Fixed decimals; a value that rounds to zero is written without a sign.
fn num(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
        _ => s,
    }
}

/// The lift's columns (lift.md 4.4), after all others, only with `[lift]`.
pub const LIFT_COLUMNS: [&str; 7] = [
    "car_mm", "car_mms", "at_floor", "door", "mbrake", "vane_l", "vane_r",
];

/// The header row of a run with the lift.
pub fn header_with_lift() -> String {
    format!("{},{}", header(), LIFT_COLUMNS.join(","))
}

/// Streams rows to a writer. The header goes out with the first row (the lift's columns
/// when that row has the lift), or at `finish` when there was none.
pub struct CsvWriter<W: Write> {
    w: W,
    header_done: bool,
}

impl<W: Write> CsvWriter<W> {
    pub fn new(w: W) -> io::Result<Self> {
        Ok(CsvWriter {
            w,
            header_done: false,
        })
    }

    /// A writer whose file starts with `# <comment>` lines (one per line of `comment`)
    /// before the header row: what the run simulated (e.g. `board: B-G431B-ESC1`).
    pub fn with_comment(mut w: W, comment: &str) -> io::Result<Self> {
        for line in comment.lines() {
            writeln!(w, "# {line}")?;
        }
        Self::new(w)
    }

    pub fn write(&mut self, s: &Sample) -> io::Result<()> {
        if !self.header_done {
            let h = if s.lift.is_some() {
                header_with_lift()
            } else {
                header()
            };
            writeln!(self.w, "{h}")?;
            self.header_done = true;
        }
        writeln!(self.w, "{}", row(s))
    }

    pub fn finish(mut self) -> io::Result<W> {
        if !self.header_done {
            writeln!(self.w, "{}", header())?;
        }
        self.w.flush()?;
        Ok(self.w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_has_the_spec_columns_first() {
        let h = header();
        assert!(h.starts_with(
            "t_s,f_cmd_hz,dir,m,pwm_on,fault,u_dc_v,i_a_a,i_b_a,i_c_a,speed_rpm,torque_nm,brake,D00,"
        ));
        assert!(h.contains(",D15,O00,"));
        assert!(h.contains(",O07,Q00,"));
        assert!(h.ends_with(
            ",Q07,lcd0,lcd1,lcd2,lcd3,duty_a,duty_b,duty_c,u_ab_v,warn,sf_req,sf_st,sdc,sft_s,turns"
        ));
    }

    #[test]
    fn row_has_as_many_fields_as_the_header() {
        let s = Sample {
            t_ns: 1_500_000,
            f_cmd_hz: 12.3,
            dir: -1,
            m: 0.5,
            pwm_on: true,
            fault: 0,
            u_dc_v: 30.0,
            i_abc_a: [0.1, -0.05, -0.05],
            speed_rpm: 100.0,
            torque_nm: 0.01,
            brake: false,
            digital_in: 0b1000_0000_1000_0001,
            digital_out: 0b10,
            q: [1, 2, 3, 4, 5, 6, 7, 8],
            lcd: [Some(500), None, None, None],
            duty_abc: [0.5, 0.25, 1.0],
            u_ab_v: 7.5,
            warn: crate::mcu::Warnings {
                plc: Some(firmware_plc::vm::Warning::Div0 { line: 151 }),
                drive: Some(shared_protocol::link::DriveWarning::PwfClamped {
                    line: 0,
                    requested: 0,
                    applied_hz: 488,
                }),
            },
            sf_req: 2048 + 2,
            sf_st: 2,
            sdc: true,
            sft_ds: 150,
            turns_e4: -2_000_001,
            sf_turns: -200,
            lift: None,
        };
        let r = row(&s);
        assert_eq!(r.split(',').count(), header().split(',').count());
        assert!(r.starts_with("0.001500,12.3,-1,0.500,1,0,30.000,"));
        assert!(
            r.ends_with(
                ",1,2,3,4,5,6,7,8,500,,,,0.5000,0.2500,1.0000,7.500,DIV0 @ 151; PWF 488Hz @ 000,\
                 2050,2,1,15.0,-200.0001"
            ),
            "{r}"
        );
        let quiet = Sample {
            warn: crate::mcu::Warnings::default(),
            ..s
        };
        assert!(row(&quiet).ends_with(",7.500,,2050,2,1,15.0,-200.0001"));
        let lifted = Sample {
            lift: Some(crate::plant::lift::LiftSample {
                car_mm: 599.996,
                car_mms: -0.004,
                at_floor: 3,
                door: 0.5,
                brake_engaged: true,
                vane_l: true,
                vane_r: false,
                ..Default::default()
            }),
            ..quiet
        };
        let r = row(&lifted);
        assert!(r.ends_with(",-200.0001,600.00,0.00,3,0.500,1,1,0"), "{r}");
        assert_eq!(r.split(',').count(), header_with_lift().split(',').count());
        assert!(header_with_lift()
            .ends_with(",turns,car_mm,car_mms,at_floor,door,mbrake,vane_l,vane_r"));
    }

    #[test]
    fn negative_zero_has_no_sign() {
        assert_eq!(num(-0.00001, 4), "0.0000");
        assert_eq!(num(-0.5, 1), "-0.5");
    }
}
