//! The scenario's `[analog]` keys as the emulated drive MCU's analog errors: the part's
//! figures are g431-emu's (`g431-emu/docs/models.md` "Analog errors"), each key then
//! overrides one. The parser checked the keys' ranges (`scenario::AnalogKeys`).

use g431_emu::periph::analog_errors::AnalogErrors;

use crate::scenario::{AnalogKeys, AnalogPart};

impl AnalogKeys {
    /// The errors the drive MCU's comparators, DACs and OPAMPs get.
    pub fn errors(&self) -> AnalogErrors {
        let mut e = match self.part.unwrap_or(AnalogPart::Typical) {
            AnalogPart::Typical => AnalogErrors::TYPICAL,
            AnalogPart::Ideal => AnalogErrors::IDEAL,
            AnalogPart::WorstHigh => AnalogErrors::worst(1.0),
            AnalogPart::WorstLow => AnalogErrors::worst(-1.0),
        };
        for (val, slot) in [
            (self.comp_offset_v, &mut e.comp_offset_v),
            (self.comp_delay_ns, &mut e.comp_delay_ns),
            (self.dac_offset_v, &mut e.dac_offset_v),
            (self.opamp_offset_v, &mut e.opamp_offset_v),
        ] {
            if let Some(v) = val {
                *slot = v;
            }
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use crate::scenario::Scenario;

    use super::*;

    #[test]
    fn analog_errors_default_to_the_typical_part_and_each_key_overrides_one() {
        let errors = |text: &str| Scenario::parse(text).expect("parses").analog.errors();
        assert_eq!(errors(""), AnalogErrors::TYPICAL);
        let s = errors("[analog]\npart = \"worst_low\"\ncomp_offset_v = 0.004\n");
        let w = AnalogErrors::worst(-1.0);
        assert_eq!(s.comp_offset_v, 0.004);
        assert_eq!(
            (s.dac_offset_v, s.opamp_offset_v, s.comp_delay_ns),
            (w.dac_offset_v, w.opamp_offset_v, w.comp_delay_ns)
        );
        let s = errors("[analog]\npart = \"worst_high\"\ndac_offset_v = -0.01\n");
        assert_eq!(
            (s.comp_offset_v, s.dac_offset_v),
            (AnalogErrors::worst(1.0).comp_offset_v, -0.01)
        );
        let s = errors("[analog]\npart = \"ideal\"\ncomp_delay_ns = 50.0\n");
        assert_eq!(s.comp_delay_ns, 50.0);
        assert_eq!(s.dac_offset_v, 0.0);
        let s = errors("[analog]\nopamp_offset_v = 0.003\n");
        assert_eq!(
            s,
            AnalogErrors {
                opamp_offset_v: 0.003,
                ..AnalogErrors::TYPICAL
            }
        );
    }
}
