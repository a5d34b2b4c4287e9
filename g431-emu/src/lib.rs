//! An emulator of the STM32G431 as the project's firmware images use it.
//!
//! It runs the exact release ELFs that CI builds and users flash: a Cortex-M4F on the Unicorn
//! engine with the ARMv7-M exception model added by this crate (Unicorn has none for
//! M-profile), and register models of the peripherals the images touch, written from RM0440.
//! A model must never be kinder than the silicon: flags that hardware sets late are set late,
//! rc_w0 flags are cleared only by a written 0, a write to a peripheral whose clock is off is
//! ignored and reported.
//!
//! * [`boards`]: the boards around the MCUs (B-G431B-ESC1, NUCLEO-G431RB), from their
//!   documents: physical quantities in, pin voltages and levels out.
//! * [`time`]: the one time base (CPU cycles at 170 MHz) and conversions.
//! * [`cycles`]: the approximate Cortex-M4 cycle model virtual time advances by.
//! * [`periph`]: the [`periph::Peripheral`] contract and one module per register model.
//! * [`devices`]: what sits on the board's buses (24C256 EEPROM, PCF8574 + HD44780 LCD).
//! * [`names`]: register, field and interrupt names from the STM32 metadata, so that an
//!   unmodelled access or a stuck busy-wait is reported as `RCC.CSR` rather than an address.
//!
//! How it works, what it models and what it cannot catch: `docs/emulator.md`.

pub mod boards;
pub mod cpu;
pub mod cycles;
pub mod devices;
pub mod elf;
pub mod log;
pub mod mcu;
pub mod names;
pub mod periph;
pub mod scs;
pub mod soc;
pub mod time;
