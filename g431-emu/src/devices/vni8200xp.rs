//! VNI8200XP (ST, octal high-side smart power switch) in 16-bit SPI mode (SEL1 = SEL2 =
//! H), as the X-NUCLEO-PLC01A1 fits it. From the datasheet DocID15234 (Rev 6/9) section 10.2
//! and Table 17, sections 9.8-9.9, and ST's X-CUBE-PLC1 board driver for the answer's
//! bits the pages reached do not define: `firmware-plc/docs/field-io.md` lists each fact
//! with its source. Nothing here is taken from the firmware.
//!
//! * Command (MOSI, MSB first): `IN7..IN0 0000 P2 P1 P0 nP0`, P0 the XOR of IN0-IN7, P1 of
//!   IN1, IN3, IN5, IN7, P2 of IN0, IN2, IN4, IN6, nP0 = NOT P0. It is applied at the rise
//!   of SS when its parity is right and the clock count is 16; otherwise the outputs keep
//!   their state, the FAULT pin goes low and the next answer's PC bit is set (the datasheet:
//!   a parity fault or a clock count not a multiple of 8 keeps FAULT low; this model also
//!   refuses 8 or 24 clocks in 16-bit mode, the conservative reading).
//! * Answer (MISO, shifted out during the same window): `F7..F0 FB_OK TWARN PC PG` and
//!   `P2 P1 P0 nP0`, P0 over F7..F0, P1 over bits 15, 13, .., 5, P2 over bits 14, 12, .., 4
//!   (ST's driver). Fn = 1: channel n reached its thermal shutdown since the last window
//!   (latched, cleared at the rise of SS, set again while the channel stays hot). PG = 1:
//!   the supply is not good (ST's driver's polarity). FB_OK = 0 at the DC-DC's turn-on,
//!   1 once the feedback is up and a correct command was received.
//! * A channel drives its load when its command bit is set, OUT_EN is high, the supply is
//!   good and the channel is not in thermal shutdown.
//! * Supply lost ([`Vni8200xp::supply_ok`] false): PG = 1, FB_OK = 0, every channel off;
//!   the SPI side keeps answering (the datasheet pages reached say nothing else; the
//!   firmware's check of a MISO line stuck at 0 or 1 is tested with the CLT01-38SQ7).

/// The chip.
#[derive(Debug, Clone)]
pub struct Vni8200xp {
    /// The last applied command's channels (bit n = channel n on).
    applied: u8,
    /// OUT_EN's level (the board sets it from the MCU pin).
    pub out_enable: bool,
    /// The field supply is good.
    pub supply_ok: bool,
    /// Channels in thermal shutdown now (the host's fault injection).
    pub overheated: u8,
    /// The case temperature warning (TC > TCSD).
    pub case_warning: bool,
    latched_ovt: u8,
    parity_fail: bool,
    fb_ok: bool,
    refused: u64,
}

impl Default for Vni8200xp {
    fn default() -> Self {
        Vni8200xp {
            applied: 0,
            out_enable: false,
            supply_ok: true,
            overheated: 0,
            case_warning: false,
            latched_ovt: 0,
            parity_fail: false,
            fb_ok: false,
            refused: 0,
        }
    }
}

/// `P2 P1 P0 nP0` from the three groups' bits.
fn nibble(all: u16, odd: u16, even: u16) -> u16 {
    let p = |x: u16| u16::from(x.count_ones() % 2 == 1);
    let p0 = p(all);
    p(even) << 3 | p(odd) << 2 | p0 << 1 | (p0 ^ 1)
}

impl Vni8200xp {
    pub fn new() -> Self {
        Self::default()
    }

    /// Channel levels at the output pins (bit n = channel n drives its load).
    pub fn outputs(&self) -> u8 {
        if !self.out_enable || !self.supply_ok {
            return 0;
        }
        self.applied & !self.overheated
    }

    /// Commands refused for their parity or clock count.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The FAULT pin is low (active): a channel in thermal shutdown or the last command
    /// refused.
    pub fn fault_pin_low(&self) -> bool {
        self.overheated != 0 || self.parity_fail
    }

    /// One chip-select window: `mosi` clocked in over `bits` clocks (16 in this mode);
    /// returns the answer shifted out, then applies the command at the rise of SS.
    pub fn exchange(&mut self, mosi: u16, bits: u32) -> u16 {
        let answer = self.answer();
        self.latched_ovt = self.overheated;
        let data = (mosi >> 8) as u8;
        let w = u16::from(data) << 8;
        let good =
            bits == 16 && mosi & 0x00F0 == 0 && mosi & 0x000F == nibble(w, w & 0xAA00, w & 0x5500);
        if good {
            self.applied = data;
            self.parity_fail = false;
            self.fb_ok = self.supply_ok;
        } else {
            self.parity_fail = true;
            self.refused += 1;
        }
        if !self.supply_ok {
            self.fb_ok = false;
        }
        answer
    }

    /// The answer for the present state.
    pub fn answer(&self) -> u16 {
        let mut w = u16::from(self.latched_ovt | self.overheated) << 8;
        if self.fb_ok && self.supply_ok {
            w |= 1 << 7;
        }
        if self.case_warning {
            w |= 1 << 6;
        }
        if self.parity_fail {
            w |= 1 << 5;
        }
        if !self.supply_ok {
            w |= 1 << 4;
        }
        w | nibble(w & 0xFF00, w & 0xAAA0, w & 0x5550)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A command built bit by bit from the datasheet's formulas.
    fn command(outputs: u8) -> u16 {
        let bit = |n: u8| outputs >> n & 1;
        let p0 = (0..8).fold(0, |a, n| a ^ bit(n));
        let p1 = bit(1) ^ bit(3) ^ bit(5) ^ bit(7);
        let p2 = bit(0) ^ bit(2) ^ bit(4) ^ bit(6);
        u16::from(outputs) << 8
            | u16::from(p2) << 3
            | u16::from(p1) << 2
            | u16::from(p0) << 1
            | u16::from(p0 ^ 1)
    }

    #[test]
    fn a_good_command_drives_the_outputs_once_out_en_is_high() {
        let mut v = Vni8200xp::new();
        let first = v.exchange(command(0x05), 16);
        assert_eq!(first & 0x0080, 0, "FB_OK low at the DC-DC's turn-on");
        assert_eq!(v.outputs(), 0, "OUT_EN low");
        v.out_enable = true;
        assert_eq!(v.outputs(), 0x05);
        let next = v.exchange(command(0x05), 16);
        assert_eq!(next & 0x00F0, 0x0080, "FB_OK high, no TWARN, PC, PG");
    }

    #[test]
    fn a_command_with_bad_parity_or_clock_count_is_refused_and_reported() {
        let mut v = Vni8200xp::new();
        v.out_enable = true;
        let _ = v.exchange(command(0x01), 16);
        let _ = v.exchange(command(0x03) ^ 0x0002, 16);
        assert_eq!(v.outputs(), 0x01, "outputs kept");
        assert!(v.fault_pin_low());
        let _ = v.exchange(command(0x03), 8);
        assert_eq!(v.outputs(), 0x01);
        let answer = v.exchange(command(0x03), 16);
        assert_ne!(answer & 0x0020, 0, "PC reports the refused command");
        assert_eq!(v.outputs(), 0x03);
        assert_eq!(v.refused(), 2);
    }

    #[test]
    fn a_hot_channel_switches_off_and_its_fault_bit_is_latched_for_one_window() {
        let mut v = Vni8200xp::new();
        v.out_enable = true;
        let _ = v.exchange(command(0x06), 16);
        v.overheated = 0x04;
        assert_eq!(v.outputs(), 0x02);
        let a = v.exchange(command(0x06), 16);
        assert_eq!(a >> 8, 0x04);
        v.overheated = 0;
        let a = v.exchange(command(0x06), 16);
        assert_eq!(
            a >> 8,
            0x04,
            "latched at the occurrence, shifted out once more"
        );
        let a = v.exchange(command(0x06), 16);
        assert_eq!(a >> 8, 0);
    }

    #[test]
    fn a_lost_supply_sets_pg_clears_fb_ok_and_the_outputs() {
        let mut v = Vni8200xp::new();
        v.out_enable = true;
        let _ = v.exchange(command(0xFF), 16);
        v.supply_ok = false;
        assert_eq!(v.outputs(), 0);
        let a = v.answer();
        assert_eq!(a & 0x00F0, 0x0010);
    }

    #[test]
    fn every_answer_carries_its_check_bits() {
        let mut v = Vni8200xp::new();
        v.case_warning = true;
        v.overheated = 0x81;
        let a = v.answer();
        let hi = a & 0xFFF0;
        let odd = |x: u16| u16::from(x.count_ones() % 2 == 1);
        let p0 = odd(hi & 0xFF00);
        assert_eq!(
            a & 0xF,
            odd(hi & 0x5550) << 3 | odd(hi & 0xAAA0) << 2 | p0 << 1 | (p0 ^ 1)
        );
    }
}
