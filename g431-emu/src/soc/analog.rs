//! What the ADC converts and the comparators compare: pins from the board, OPAMP outputs
//! computed from their inputs and the part's errors, the DACs' outputs, the internal
//! references.

use super::{Board, VREFINT_VOLTS};
use crate::names;
use crate::periph::adc::{AdcId, AnalogSource};
use crate::periph::opamp::{OpampConfig, OpampInput};
use crate::time::Cycles;

/// The other models' state the ADC's analog adapter needs.
pub(super) struct AnalogSnapshot {
    pub(super) opamps: [Option<OpampConfig>; 3],
    pub(super) dac1: [Option<f64>; 2],
    pub(super) dac3: [Option<f64>; 2],
}

/// What the ADC converts: pins from the board, OPAMP outputs computed from their inputs,
/// the internal references.
pub(super) struct AnalogAdapter<'a> {
    pub(super) board: &'a mut dyn Board,
    pub(super) snap: &'a AnalogSnapshot,
}

/// The pin of ADC `adc`'s external channel `ch` (from the metadata's pin table).
fn adc_pin(adc: AdcId, ch: u8) -> Option<&'static str> {
    let name = match adc {
        AdcId::Adc1 => "ADC1",
        AdcId::Adc2 => "ADC2",
    };
    let signal = format!("IN{ch}");
    names::peripheral(name)?
        .pins
        .iter()
        .find(|p| p.signal == signal)
        .map(|p| p.pin)
}

impl AnalogAdapter<'_> {
    fn opamp_out(&mut self, n: usize, at: Cycles) -> f64 {
        let Some(cfg) = self.snap.opamps.get(n).copied().flatten() else {
            return 0.0;
        };
        let vinp = match cfg.vinp {
            OpampInput::Pin(p) => self.board.pin_volts(p, at),
            OpampInput::Dac3(ch) => self.snap.dac3.get(ch).copied().flatten().unwrap_or(0.0),
            OpampInput::NotConnected => 0.0,
        };
        // The VINM0 pin's own volts when the feedback network's foot is on it.
        let vinm0 = cfg
            .vinm0_pin()
            .map_or(0.0, |pin| self.board.pin_volts(pin, at));
        cfg.output_volts(vinp, vinm0).unwrap_or(0.0)
    }
}

impl AnalogAdapter<'_> {
    /// OPAMPn's output on its internal ADC channel: only with OPAINTOEN = 1 (RM0440 §25.3:
    /// the output then goes to the ADC and not to the VOUT pin); otherwise the internal
    /// channel is not connected and reads 0 V.
    fn opamp_internal(&mut self, n: usize, at: Cycles) -> f64 {
        match self.snap.opamps.get(n).copied().flatten() {
            Some(cfg) if cfg.internal_only => self.opamp_out(n, at),
            _ => 0.0,
        }
    }

    /// Volts on `pin`: an enabled OPAMP's output while it drives its VOUT pin (OPAINTOEN =
    /// 0: PA2, PA6, PB1), else the board's.
    pub(super) fn pin(&mut self, pin: &str, at: Cycles) -> f64 {
        let driver =
            self.snap.opamps.iter().position(|c| {
                c.is_some_and(|c| c.enabled && !c.internal_only && c.output_pin == pin)
            });
        match driver {
            Some(n) => self.opamp_out(n, at),
            None => self.board.pin_volts(pin, at),
        }
    }
}

impl AnalogSource for AnalogAdapter<'_> {
    fn volts(&mut self, adc: AdcId, channel: u8, at: Cycles) -> f64 {
        match (adc, channel) {
            (AdcId::Adc1, 13) => self.opamp_internal(0, at),
            (AdcId::Adc2, 16) => self.opamp_internal(1, at),
            (AdcId::Adc2, 18) => self.opamp_internal(2, at),
            // Temperature sensor at 30 °C (DS12589 V30), VBAT/3 at 3.3 V, VREFINT.
            (AdcId::Adc1, 16) => 0.76,
            (AdcId::Adc1, 17) => 3.3 / 3.0,
            (AdcId::Adc1, 18) => VREFINT_VOLTS,
            _ => match adc_pin(adc, channel) {
                Some(pin) => self.pin(pin, at),
                None => 0.0,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::analog_errors::AnalogErrors;
    use crate::periph::gpio::{Drive, PinReader};
    use crate::periph::opamp::OpampBank;
    use crate::periph::Peripheral;

    /// A board with 0.1 V on the ESC1's PGA inputs and 1.0 V on PB1.
    struct AnalogBoard;

    impl PinReader for AnalogBoard {}

    impl Board for AnalogBoard {
        fn pin_volts(&mut self, pin: &str, _at: Cycles) -> f64 {
            match pin {
                "PA1" | "PA7" | "PB0" => 0.1,
                "PB1" => 1.0,
                _ => 0.0,
            }
        }
    }

    /// OPAMPn in PGA mode, gain 16, VINP0, enabled; `internal`: OPAINTOEN.
    fn pga16(bank: &mut OpampBank, n: u32, internal: bool) {
        let v = 1 | (2 << 5) | (3 << 14) | if internal { 1 << 8 } else { 0 };
        assert!(bank.write(crate::periph::Write::word(4 * (n - 1), v), 0));
    }

    fn snapshot(bank: &OpampBank) -> AnalogSnapshot {
        AnalogSnapshot {
            opamps: [1, 2, 3].map(|n| bank.config(n)),
            dac1: [None; 2],
            dac3: [None; 2],
        }
    }

    #[test]
    fn opamp_outputs_reach_the_adc_internally_only_with_opaintoen() {
        let mut bank = OpampBank::new();
        bank.set_errors(&AnalogErrors::IDEAL);
        pga16(&mut bank, 1, true);
        pga16(&mut bank, 2, true);
        pga16(&mut bank, 3, false);
        let snap = snapshot(&bank);
        let mut board = AnalogBoard;
        let mut a = AnalogAdapter {
            board: &mut board,
            snap: &snap,
        };
        // 16 x 0.1 V on ADC1 IN13 and ADC2 IN16 (the ESC1's phase currents at 0 A).
        assert!((a.volts(AdcId::Adc1, 13, 0) - 1.6).abs() < 1e-12);
        assert!((a.volts(AdcId::Adc2, 16, 0) - 1.6).abs() < 1e-12);
        // OPAMP3 drives its pin PB1 (ADC1 IN12), not ADC2 IN18.
        assert_eq!(a.volts(AdcId::Adc2, 18, 0), 0.0);
        assert!((a.volts(AdcId::Adc1, 12, 0) - 1.6).abs() < 1e-12);
        // The VINP pins themselves read the board's voltage (ADC1 IN2 = PA1).
        assert!((a.volts(AdcId::Adc1, 2, 0) - 0.1).abs() < 1e-12);
        // Output clamped to the rail: 16 x 0.25 V.
        struct High;
        impl PinReader for High {
            fn external(
                &mut self,
                _: u8,
                _: u8,
                _: Cycles,
                _: &dyn Fn(u8, u8) -> Drive,
            ) -> crate::periph::gpio::External {
                crate::periph::gpio::External::Floating
            }
        }
        impl Board for High {
            fn pin_volts(&mut self, _: &str, _: Cycles) -> f64 {
                0.25
            }
        }
        let mut high = High;
        let mut a = AnalogAdapter {
            board: &mut high,
            snap: &snap,
        };
        assert_eq!(a.volts(AdcId::Adc1, 13, 0), 3.3);
        // Disabled: nothing on the internal channel, and PB1 is the board's again.
        let off = AnalogSnapshot {
            opamps: [None; 3],
            ..snapshot(&bank)
        };
        let mut board = AnalogBoard;
        let mut a = AnalogAdapter {
            board: &mut board,
            snap: &off,
        };
        assert_eq!(a.volts(AdcId::Adc1, 13, 0), 0.0);
        assert!((a.volts(AdcId::Adc1, 12, 0) - 1.0).abs() < 1e-12);
    }

    /// Volts on OPAMP1's VINP0 (PA1) and VINM0 (PA3).
    struct ShuntPins {
        vinp: f64,
        vinm0: f64,
    }

    impl PinReader for ShuntPins {}

    impl Board for ShuntPins {
        fn pin_volts(&mut self, pin: &str, _at: Cycles) -> f64 {
            match pin {
                "PA1" => self.vinp,
                "PA3" => self.vinm0,
                _ => 0.0,
            }
        }
    }

    /// The ADC converts the amplifier's real output at the sampling instant: the VINM0-biased
    /// mode takes the VINM0 pin's volts, the grounded one does not, the part's input offset
    /// is amplified with the gain, the rails clamp.
    #[test]
    fn the_adc_converts_the_amplifiers_real_output() {
        let typ = AnalogErrors::TYPICAL.opamp_offset_v;
        let mut bank = OpampBank::new();
        let convert = |bank: &OpampBank, vinp: f64, vinm0: f64| {
            let snap = snapshot(bank);
            let mut board = ShuntPins { vinp, vinm0 };
            let mut a = AnalogAdapter {
                board: &mut board,
                snap: &snap,
            };
            a.volts(AdcId::Adc1, 13, 0)
        };
        // PGA x16, VINM0-biased (PGA_GAIN 01011), output to the ADC only.
        let biased = 1 | (2 << 5) | (0b01011 << 14) | (1 << 8);
        assert!(bank.write(crate::periph::Write::word(0, biased), 0));
        let v = convert(&bank, 0.12, 0.1);
        assert!(
            (v - (16.0 * (0.12 + typ) - 15.0 * 0.1)).abs() < 1e-12,
            "{v}"
        );
        // The same pins in the grounded mode (PGA_GAIN 00011): another output.
        assert!(bank.write(
            crate::periph::Write::word(0, 1 | (2 << 5) | (3 << 14) | (1 << 8)),
            1
        ));
        let g = convert(&bank, 0.12, 0.1);
        assert!((g - 16.0 * (0.12 + typ)).abs() < 1e-12, "{g}");
        // Below VSSA and above VDDA the output sits on the rails.
        assert!(bank.write(crate::periph::Write::word(0, biased), 2));
        assert_eq!(convert(&bank, 0.0, 0.5), 0.0);
        assert_eq!(convert(&bank, 1.0, 0.0), 3.3);
        // A negative offset lowers it by 16 x Vio.
        bank.set_errors(&AnalogErrors::worst(-1.0));
        let w = convert(&bank, 0.12, 0.1);
        let vio = AnalogErrors::worst(-1.0).opamp_offset_v;
        assert!((w - (16.0 * (0.12 + vio) - 1.5)).abs() < 1e-12, "{w}");
    }
}
