//! The two MCUs as the simulator drives them.
//!
//! [`SimDrive`] and [`SimPlc`] are the seam between the simulated hardware and the
//! firmware's sans-IO applications: the simulator plays the peripherals (timer interrupt
//! with its ADC sample, 1 ms system tick, UART bytes, break input, GPIO, keypad, LCD,
//! EEPROM) and calls the same core code the firmware images run, as the boards' tasks
//! and interrupts call it. There is one of each (no trait: the front panel drives the
//! same `SimPlc` through the simulator). The PLC's side calls the firmware's task bodies
//! themselves (`firmware_plc::task`) over this crate's pin and LCD models.

pub mod drive_board;
pub mod lcd;
pub mod plc_board;

pub use drive_board::SimDrive;
pub use lcd::SimLcd;
pub use plc_board::SimPlc;

/// The PLC's inputs as its pins present them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PlcPins {
    /// D00..D15, bit n = Dn.
    pub digital: u16,
    /// A00..A03, 10-bit counts.
    pub analog: [u16; 4],
}

/// The run-time warnings the PLC knows of: its own (`DIV0 @ line`, kept until the next
/// RUN) and the drive's as its status reports it (while it lasts).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Warnings {
    pub plc: Option<firmware_plc::vm::Warning>,
    pub drive: Option<shared_protocol::link::DriveWarning>,
}

impl Warnings {
    pub fn is_empty(&self) -> bool {
        self.plc.is_none() && self.drive.is_none()
    }

    /// The LCD status line's texts, `; `-separated (the CSV's `warn`), e.g.
    /// `DIV0 @ 151` or `PWF 488Hz @ 000`; empty when none.
    pub fn short(&self) -> String {
        let mut parts = Vec::new();
        if let Some(w) = self.plc {
            parts.push(w.to_string());
        }
        if let Some(w) = self.drive {
            parts.push(w.short().to_string());
        }
        parts.join("; ")
    }

    /// Each warning as (status-line text, long text for the run summary).
    pub fn texts(&self) -> Vec<(String, String)> {
        let mut v = Vec::new();
        if let Some(w) = self.plc {
            match w {
                firmware_plc::vm::Warning::Div0 { line } => v.push((
                    w.to_string(),
                    format!("{w} (PLC): DIV by a Q holding 0 on line {line:03}, P set to 0"),
                )),
            }
        }
        if let Some(w) = self.drive {
            let short = w.short().to_string();
            v.push((short.clone(), format!("{short} (drive): {w}")));
        }
        v
    }
}
