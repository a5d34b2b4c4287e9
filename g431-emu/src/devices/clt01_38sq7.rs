//! CLT01-38SQ7 (ST, octal digital input current limiter with SPI output), as the
//! X-NUCLEO-PLC01A1 fits it, in 16-bit mode. From the datasheet (DocID028182 Rev 1: "8
//! inputs - 8-bit SPI output", "Optional: 16-bit mode with parity check, temperature and
//! voltage alarms", 6.25 MHz SPI) and ST's X-CUBE-PLC1 board driver for the frame's bit
//! order (the datasheet's frame table was not reachable): `firmware-plc/docs/field-io.md`
//! lists each fact with its source. Nothing here is taken from the firmware.
//!
//! The frame shifted out on MISO, MSB first, during one chip-select window:
//! `IN8..IN1 /UVA /OTA PC1 PC2 PC3 PC4 0 1`, where INn = 1 is an energised input, /UVA and
//! /OTA are active low, and PCk are inverted parities of the inputs: PC1 over IN1-IN8,
//! PC2 over IN5-IN8, PC3 over IN1-IN4, PC4 over IN3-IN6. MOSI is ignored.
//!
//! The field supply ([`FieldSupply`]): `Low` raises the under-voltage alarm and the inputs
//! read off (an input needs the field supply's current to switch on); `Off` leaves MISO
//! undriven: this model reads it as all zeros (no document says what the shield's
//! isolators then give; all zeros fails the frame's check like any stuck line).

/// The 24 V field supply as the chip sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FieldSupply {
    #[default]
    Ok,
    /// Below the under-voltage threshold: /UVA low, inputs off.
    Low,
    /// No supply: MISO undriven.
    Off,
}

/// The chip.
#[derive(Debug, Clone, Default)]
pub struct Clt01_38sq7 {
    /// Field levels of IN1..IN8 (bit n = IN(n+1)), set by the host.
    pub inputs: u8,
    pub supply: FieldSupply,
    /// The chip's over-temperature alarm.
    pub over_temperature: bool,
    frames: u64,
}

impl Clt01_38sq7 {
    pub fn new() -> Self {
        Self::default()
    }

    /// Frames shifted out so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// One chip-select window of `bits` clocks: what MISO carried, MSB first, in the low
    /// `bits` bits (a window longer than 16 clocks shifts zeros after the frame; this
    /// model keeps the first 16).
    pub fn exchange(&mut self, bits: u32) -> u16 {
        self.frames += 1;
        let word = self.frame();
        match bits {
            0 => 0,
            1..=15 => word >> (16 - bits),
            _ => word,
        }
    }

    /// The 16-bit frame for the present state.
    pub fn frame(&self) -> u16 {
        let inputs = match self.supply {
            FieldSupply::Ok => self.inputs,
            FieldSupply::Low => 0,
            FieldSupply::Off => return 0,
        };
        let even = |mask: u8| (inputs & mask).count_ones().is_multiple_of(2);
        let mut w = u16::from(inputs) << 8;
        if self.supply == FieldSupply::Ok {
            w |= 1 << 7; // /UVA high: no alarm
        }
        if !self.over_temperature {
            w |= 1 << 6; // /OTA high: no alarm
        }
        for (bit, mask) in [(5, 0xFFu8), (4, 0xF0), (3, 0x0F), (2, 0x3C)] {
            if even(mask) {
                w |= 1 << bit;
            }
        }
        w | 0b01
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_healthy_chip_with_no_input_on_sends_the_alarm_free_frame() {
        let c = Clt01_38sq7::new();
        assert_eq!(c.frame(), 0b0000_0000_1111_1101);
    }

    #[test]
    fn in1_and_in8_on_keep_the_total_parity_even() {
        let c = Clt01_38sq7 {
            inputs: 0x81,
            ..Clt01_38sq7::new()
        };
        // PC1 (all eight): two ones, even -> 1. PC2 (IN5-IN8): one -> 0. PC3 (IN1-IN4):
        // one -> 0. PC4 (IN3-IN6): none -> 1.
        assert_eq!(c.frame(), 0x8100 | 0b1100_0000 | 0b0010_0100 | 0b01);
    }

    #[test]
    fn a_low_field_supply_raises_uva_and_drops_the_inputs() {
        let mut c = Clt01_38sq7 {
            inputs: 0xFF,
            supply: FieldSupply::Low,
            ..Clt01_38sq7::new()
        };
        assert_eq!(c.frame() & 0xFF80, 0, "inputs off, /UVA low");
        c.supply = FieldSupply::Off;
        assert_eq!(c.exchange(16), 0);
        assert_eq!(c.frames(), 1);
    }

    #[test]
    fn over_temperature_pulls_ota_low() {
        let c = Clt01_38sq7 {
            over_temperature: true,
            ..Clt01_38sq7::new()
        };
        assert_eq!(c.frame() & 0xC0, 0x80);
    }
}
