//! The two MCUs as the simulator drives them.
//!
//! Each trait is the seam between the simulated hardware and the firmware's sans-IO
//! application: the simulator plays the peripherals (timer interrupt with its ADC sample,
//! 1 ms system tick, UART bytes, break input, GPIO, keypad, LCD, EEPROM) and calls the
//! same core code the firmware images run. The implementations in [`drive_board`] and
//! [`plc_board`] are the host counterparts of the boards' `main.rs`.

pub mod drive_board;
pub mod lcd;
pub mod plc_board;

use firmware_drive::comparators::{BoardProfile, DacValues};
use firmware_drive::power_port::{BreakReport, ComparatorLevels, PeriodAction};
use firmware_drive::{AdcSample, DriveStatus, PwmTiming};
use shared_protocol::units::Micros;

pub use drive_board::DriveBoard;
pub use lcd::Lcd;
pub use plc_board::PlcBoard;

/// The drive MCU.
pub trait DriveMcu {
    /// TIM1 update interrupt: the ADC conversion of this period in, what the power stage
    /// does out (performed over the simulator's TIM1, [`crate::tim1::SimTim1`]).
    fn pwm_isr(&mut self, adc: &AdcSample) -> PeriodAction;
    /// The 1 ms system tick (drive section, state machine, link timers).
    fn tick_1ms(&mut self, now: Micros);
    /// TIM1 break interrupt with the comparators at `levels`.
    fn break_fired(&mut self, levels: ComparatorLevels) -> BreakReport;
    /// Every 1 ms before the tick: the comparators at `levels` (release, re-arm).
    fn break_poll(&mut self, levels: ComparatorLevels) -> BreakReport;
    /// Bytes the UART received.
    fn uart_rx(&mut self, bytes: &[u8], now: Micros);
    /// The UART can take a frame: the next one to send (length, 0 = none).
    fn uart_tx(&mut self, now: Micros, out: &mut [u8]) -> usize;
    /// TIM1 setup the board's init programs (later changes come as [`PeriodAction`]s).
    fn pwm_timing(&self) -> PwmTiming;
    /// The timer's kernel clock.
    fn timer_clock_hz(&self) -> u32;
    fn status(&self) -> DriveStatus;
    /// The board's comparators (which signal, direction and DAC each one has). Default:
    /// the drive core's default profile.
    fn board(&self) -> &'static BoardProfile {
        firmware_drive::DriveConfig::default().board
    }
    /// What the firmware writes to the comparator threshold DACs now. Default: the
    /// drive core's default levels (a board model that reads its DAC registers overrides
    /// this).
    fn comparator_dacs(&self) -> DacValues {
        let c = firmware_drive::DriveConfig::default();
        let t = firmware_drive::comparators::HwThresholds {
            oc_hw: shared_protocol::units::CentiAmps(c.oc_hw_default_centiamps as i16),
            ov_hw: shared_protocol::units::Volts(c.ov_hw_default_volts as i16),
        };
        firmware_drive::comparators::dac_values(self.board(), t)
    }
}

/// The PLC's inputs as its pins present them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PlcPins {
    /// D00..D07, bit n = Dn.
    pub digital: u8,
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

/// The PLC MCU.
pub trait PlcMcu {
    /// The 1 ms system tick (link timers, keypad debouncing, LCD refresh).
    fn tick_1ms(&mut self, now: Micros);
    /// One PLC scan with the pins as they are now.
    fn scan(&mut self, pins: &PlcPins, now: Micros);
    /// A keypad key went down or up.
    fn key(&mut self, key: char, down: bool, now: Micros);
    fn uart_rx(&mut self, bytes: &[u8], now: Micros);
    fn uart_tx(&mut self, now: Micros, out: &mut [u8]) -> usize;
    /// Output pins O00..O05, bit n = On.
    fn outputs(&self) -> u8;
    /// The PLC's copy of Qn.
    fn q(&self, n: u8) -> i16;
    /// The run screen's 4 value fields.
    fn lcd_fields(&self) -> [Option<i16>; 4];
    /// The LCD as the user sees it.
    fn lcd(&self) -> &Lcd;
    /// The user program is running.
    fn running(&self) -> bool;
    /// The run-time warnings the PLC shows on its status line (default: none known).
    fn warnings(&self) -> Warnings {
        Warnings::default()
    }
}
