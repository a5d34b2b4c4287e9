//! GPIO ports (RM0440 §9.4): MODER/OTYPER/OSPEEDR/PUPDR/IDR/ODR/BSRR/LCKR/AFR/BRR with the
//! documented reset values (every pin analog except the debug pins), and an input data
//! register *derived* from the pin's configuration and what the board drives onto it:
//!
//! | mode | IDR bit |
//! | --- | --- |
//! | analog | 0 (Schmitt trigger off) |
//! | output, push-pull | ODR (the pin drives it; a board driving the opposite level is a conflict) |
//! | output, open drain | 0 when ODR = 0, else the board's level, else the pull |
//! | input | the board's level, else the pull-up (1) / pull-down (0), else floating |
//! | alternate | the level the peripheral drives (the SoC passes it as the board's level for the outputs it models: USART TX, TIM1 CHx/CHxN, I2C), else as an input |
//!
//! A floating input reads 0 here and is reported once by the SoC: real silicon reads noise.
//! A pin in alternate-function mode is not reported: the software reads it through its
//! peripheral, and an IDR read of the port only samples it along with the pins it wants
//! (the PLC's USART TX pins were reported as floating inputs).
//! The board's side is asked through [`PinReader`] when IDR is read, so that a keypad matrix
//! (columns that follow the rows the same MCU drives) is evaluated at the instant of the read.

use crate::periph::{Peripheral, Write};
use crate::time::Cycles;

/// What the board does to one pin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum External {
    /// Nothing drives it (only the MCU's own pull, if any).
    Floating,
    /// Driven (or strongly pulled) high / low by the board.
    High,
    Low,
}

/// How the MCU itself drives a pin now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drive {
    /// Output driving high / low (push-pull, or open drain driving low).
    High,
    Low,
    /// Not driving (input, analog, alternate function, or open drain released); `pull` is
    /// the internal resistor.
    Released {
        pull: Pull,
    },
    /// Alternate function `af`: a peripheral drives or reads it.
    Alternate {
        af: u8,
    },
}

/// Internal pull resistor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pull {
    None,
    Up,
    Down,
}

/// Pin mode (MODER).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Input,
    Output,
    Alternate,
    Analog,
}

/// The board's side of the pins, asked at the moment the MCU reads them.
pub trait PinReader {
    /// The board's level on `pin` (0..16) of port `port` (0 = A) at `now`. `drives` tells
    /// how the MCU drives every pin of every port now (for wiring between the MCU's own
    /// pins, such as a keypad matrix). By default nothing is connected: every pin floats
    /// (a floating input that the MCU reads is reported as a diagnostic, so a board model
    /// that forgets a pin is seen).
    fn external(
        &mut self,
        port: u8,
        pin: u8,
        now: Cycles,
        drives: &dyn Fn(u8, u8) -> Drive,
    ) -> External {
        let _ = (port, pin, now, drives);
        External::Floating
    }
}

/// Reads every pin as floating (a bare MCU).
pub struct NoBoard;

impl PinReader for NoBoard {}

/// One GPIO port.
#[derive(Debug, Clone)]
pub struct GpioPort {
    /// 0 = A, 1 = B, ...
    pub port: u8,
    moder: u32,
    otyper: u32,
    ospeedr: u32,
    pupdr: u32,
    odr: u32,
    lckr: u32,
    afr: [u32; 2],
    /// ODR or MODER changed since the SoC last looked (it reports output changes to the
    /// board).
    changed: bool,
    /// Pins read while floating (bit per pin), for the SoC's report.
    pub floating_reads: u32,
}

impl GpioPort {
    /// Port `port` (0 = A) at reset.
    pub fn new(port: u8) -> Self {
        let (moder, ospeedr, pupdr) = match port {
            // PA13 SWDIO (AF, pull-up), PA14 SWCLK (AF, pull-down), PA15 JTDI (AF, pull-up).
            0 => (0xABFF_FFFF, 0x0C00_0000, 0x6400_0000),
            // PB3 SWO (AF), PB4 NJTRST (AF, pull-up).
            1 => (0xFFFF_FEBF, 0x0000_00C0, 0x0000_0100),
            _ => (0xFFFF_FFFF, 0, 0),
        };
        GpioPort {
            port,
            moder,
            otyper: 0,
            ospeedr,
            pupdr,
            odr: 0,
            lckr: 0,
            afr: [0; 2],
            changed: false,
            floating_reads: 0,
        }
    }

    /// Mode of pin `n`.
    pub fn mode(&self, n: u8) -> Mode {
        match (self.moder >> (2 * u32::from(n))) & 3 {
            0 => Mode::Input,
            1 => Mode::Output,
            2 => Mode::Alternate,
            _ => Mode::Analog,
        }
    }

    /// Internal pull of pin `n`.
    pub fn pull(&self, n: u8) -> Pull {
        match (self.pupdr >> (2 * u32::from(n))) & 3 {
            1 => Pull::Up,
            2 => Pull::Down,
            _ => Pull::None,
        }
    }

    /// Alternate function number of pin `n`.
    pub fn af(&self, n: u8) -> u8 {
        let reg = self.afr.get(usize::from(n / 8)).copied().unwrap_or(0);
        ((reg >> (4 * u32::from(n % 8))) & 0xF) as u8
    }

    /// Open-drain output type.
    pub fn open_drain(&self, n: u8) -> bool {
        self.otyper & (1 << n) != 0
    }

    /// The output data bit.
    pub fn odr_bit(&self, n: u8) -> bool {
        self.odr & (1 << n) != 0
    }

    /// How the MCU drives pin `n` now.
    pub fn drive(&self, n: u8) -> Drive {
        match self.mode(n) {
            Mode::Output => {
                if !self.odr_bit(n) {
                    Drive::Low
                } else if self.open_drain(n) {
                    Drive::Released { pull: self.pull(n) }
                } else {
                    Drive::High
                }
            }
            Mode::Alternate => Drive::Alternate { af: self.af(n) },
            Mode::Input => Drive::Released { pull: self.pull(n) },
            Mode::Analog => Drive::Released { pull: Pull::None },
        }
    }

    /// The level the pin settles to given the board's `ext` (None: floating).
    pub fn level(&self, n: u8, ext: External) -> Option<bool> {
        match self.drive(n) {
            Drive::High => Some(true),
            Drive::Low => Some(false),
            _ => match ext {
                External::High => Some(true),
                External::Low => Some(false),
                External::Floating => match self.pull(n) {
                    Pull::Up => Some(true),
                    Pull::Down => Some(false),
                    Pull::None => None,
                },
            },
        }
    }

    /// IDR at `now`, asking `board` for the external levels.
    pub fn idr(
        &mut self,
        now: Cycles,
        board: &mut dyn PinReader,
        drives: &dyn Fn(u8, u8) -> Drive,
    ) -> u32 {
        let mut v = 0;
        for n in 0..16u8 {
            if self.mode(n) == Mode::Analog {
                continue;
            }
            let ext = match self.drive(n) {
                Drive::High | Drive::Low => External::Floating,
                _ => board.external(self.port, n, now, drives),
            };
            match self.level(n, ext) {
                Some(true) => v |= 1 << n,
                Some(false) => {}
                None if self.mode(n) == Mode::Alternate => {}
                None => self.floating_reads |= 1 << n,
            }
        }
        v
    }

    /// Outputs changed since the last call (the SoC then tells the board).
    pub fn take_changed(&mut self) -> bool {
        core::mem::take(&mut self.changed)
    }

    fn locked(&self) -> u32 {
        if self.lckr & (1 << 16) != 0 {
            self.lckr & 0xFFFF
        } else {
            0
        }
    }

    /// Register write; IDR needs the board, so reads go through [`GpioPort::idr`] for
    /// offset 0x10 (the SoC does that); this handles every other register.
    fn write_reg(&mut self, w: Write) -> bool {
        let lock = self.locked();
        // A locked pin's configuration bits keep their value.
        let keep2 = |old: u32, new: u32| {
            let mut m = 0u32;
            for n in 0..16 {
                if lock & (1 << n) != 0 {
                    m |= 3 << (2 * n);
                }
            }
            (old & m) | (new & !m)
        };
        match w.offset {
            0x00 => {
                self.moder = keep2(self.moder, w.merge(self.moder));
                self.changed = true;
            }
            0x04 => {
                self.otyper = (self.otyper & lock) | (w.merge(self.otyper) & 0xFFFF & !lock);
                self.changed = true;
            }
            0x08 => self.ospeedr = keep2(self.ospeedr, w.merge(self.ospeedr)),
            0x0C => {
                self.pupdr = keep2(self.pupdr, w.merge(self.pupdr));
                self.changed = true;
            }
            0x10 => {} // IDR is read-only
            0x14 => {
                self.odr = w.merge(self.odr) & 0xFFFF;
                self.changed = true;
            }
            0x18 => {
                // BSRR: BR (upper half) first, BS wins when both are set.
                let v = w.value & w.mask;
                self.odr &= !(v >> 16);
                self.odr |= v & 0xFFFF;
                self.changed = true;
            }
            0x1C => {
                // LCKR: the key sequence is not checked; writing LCKK with the pins locks
                // them until reset (the images never lock).
                if self.lckr & (1 << 16) == 0 {
                    self.lckr = w.merge(self.lckr) & 0x1_FFFF;
                }
            }
            0x20 | 0x24 => {
                let k = ((w.offset - 0x20) / 4) as usize;
                if let Some(r) = self.afr.get_mut(k) {
                    let mut m = 0u32;
                    for n in 0..8 {
                        if lock & (1 << (n + 8 * k)) != 0 {
                            m |= 0xF << (4 * n);
                        }
                    }
                    *r = (*r & m) | (w.merge(*r) & !m);
                }
            }
            0x28 => {
                self.odr &= !(w.value & w.mask & 0xFFFF);
                self.changed = true;
            }
            _ => return false,
        }
        true
    }
}

impl Peripheral for GpioPort {
    /// Every register but IDR (0x10), which the SoC reads through [`GpioPort::idr`].
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00 => self.moder,
            0x04 => self.otyper,
            0x08 => self.ospeedr,
            0x0C => self.pupdr,
            0x14 => self.odr,
            0x18 | 0x28 => 0,
            0x1C => self.lckr,
            0x20 => self.afr[0],
            0x24 => self.afr[1],
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        self.write_reg(w)
    }

    fn reset(&mut self) {
        *self = GpioPort::new(self.port);
        self.changed = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Fixed(External);
    impl PinReader for Fixed {
        fn external(&mut self, _: u8, _: u8, _: Cycles, _: &dyn Fn(u8, u8) -> Drive) -> External {
            self.0
        }
    }

    fn idr(p: &mut GpioPort, ext: External) -> u32 {
        let q = p.clone();
        p.idr(0, &mut Fixed(ext), &|_, n| q.drive(n))
    }

    #[test]
    fn reset_state_is_analog_except_the_debug_pins() {
        let a = GpioPort::new(0);
        assert_eq!(a.mode(0), Mode::Analog);
        assert_eq!(a.mode(13), Mode::Alternate);
        assert_eq!(a.pull(13), Pull::Up);
        let mut c = GpioPort::new(2);
        assert_eq!(idr(&mut c, External::High), 0, "analog pins read 0");
    }

    #[test]
    fn pulled_up_input_reads_1_unless_the_board_pulls_it_low() {
        let mut p = GpioPort::new(2);
        // PC2 input with pull-up.
        p.write(Write::word(0x00, p.moder & !(3 << 4)), 0);
        p.write(Write::word(0x0C, 1 << 4), 0);
        assert_eq!(idr(&mut p, External::Floating) & (1 << 2), 1 << 2);
        assert_eq!(idr(&mut p, External::Low) & (1 << 2), 0);
        // Without pull and nothing driving: floating, reported.
        p.write(Write::word(0x0C, 0), 0);
        assert_eq!(idr(&mut p, External::Floating) & (1 << 2), 0);
        assert_ne!(p.floating_reads & (1 << 2), 0);
    }

    #[test]
    fn an_alternate_function_pin_reads_what_drives_it_and_is_not_reported_floating() {
        let mut p = GpioPort::new(0);
        // PA9 in AF7 (USART1 TX), no pull.
        p.write(Write::word(0x00, (p.moder & !(3 << 18)) | (2 << 18)), 0);
        p.write(Write::word(0x24, 7 << 4), 0);
        assert_eq!(p.drive(9), Drive::Alternate { af: 7 });
        // The SoC passes the peripheral's level as the pin's.
        assert_eq!(idr(&mut p, External::High) & (1 << 9), 1 << 9);
        assert_eq!(idr(&mut p, External::Low) & (1 << 9), 0);
        // Nothing drives it: 0, but no floating input report for an AF pin (PA13-15 too).
        p.floating_reads = 0;
        assert_eq!(idr(&mut p, External::Floating) & (1 << 9), 0);
        assert_eq!(p.floating_reads, 0);
    }

    #[test]
    fn open_drain_output_reads_the_bus() {
        let mut p = GpioPort::new(0);
        p.write(Write::word(0x00, (p.moder & !(3 << 12)) | (1 << 12)), 0);
        p.write(Write::word(0x04, 1 << 6), 0);
        p.write(Write::word(0x18, 1 << 6), 0);
        assert_eq!(p.drive(6), Drive::Released { pull: Pull::None });
        assert_eq!(idr(&mut p, External::Low) & (1 << 6), 0);
        assert_eq!(idr(&mut p, External::High) & (1 << 6), 1 << 6);
        p.write(Write::word(0x18, 1 << (6 + 16)), 0);
        assert_eq!(p.drive(6), Drive::Low);
    }

    #[test]
    fn bsrr_set_wins_and_brr_resets() {
        let mut p = GpioPort::new(1);
        p.write(Write::word(0x18, (1 << 5) | (1 << (5 + 16))), 0);
        assert!(p.odr_bit(5));
        p.write(Write::word(0x28, 1 << 5), 0);
        assert!(!p.odr_bit(5));
        // A halfword write to the upper half of BSRR resets.
        p.write(Write::word(0x18, 1 << 5), 0);
        p.write(
            Write {
                offset: 0x18,
                value: 1 << (5 + 16),
                mask: 0xFFFF_0000,
            },
            0,
        );
        assert!(!p.odr_bit(5));
    }
}
