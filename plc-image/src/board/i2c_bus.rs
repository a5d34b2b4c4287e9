//! I2C3 at 100 kHz (the PCF8574's rating) shared by the EEPROM and the LCD backpack.
//!
//! Both users run in the application task, so the bus is a `RefCell` borrowed for one
//! blocking transaction at a time and never across an `await`.
//!
//! Bus voltage: the usual PCF8574 LCD backpack and 24C256 module run at 5 V
//! with their 4.7-10 kΩ pull-ups to 5 V; PA8 and PB5 are 5 V tolerant (FT), which allows
//! this only with the pins' internal pull-up and pull-down **off** (datasheet: a pin
//! driven above VDD + 0.3 V). So the internal pull-ups stay off; a bus without external
//! pull-ups (a bare breadboard) needs 4.7 kΩ to 3.3 V fitted. See the README.
//!
//! Bus clear: a reset in the middle of an EEPROM read can leave the chip
//! holding SDA low, and a transaction that broke at run time (a device holding SCL low
//! past the timeout, a bus error) leaves embassy-stm32 0.6's blocking master as it was
//! (`i2c/v2.rs`: `wait_tc`'s timeout sends no STOP, BUSY stays set, a later `master_stop`
//! leaves CR2.STOP pending), after which every EEPROM and LCD transaction timed out while
//! the watchdog was fed. [`reset_and_clear`] is the one remedy, at boot and after each
//! transaction the core's rule ([`bus_recovery::after_failure`]) calls broken: I2C3 off
//! (RM0440 "I2C software reset"), the pins as open-drain GPIOs for the core's bus clear
//! ([`bus_recovery::recover`]: up to 9 clocks while SDA is low, then a STOP), the pins
//! back to I2C3, I2C3 on. Nothing here decides: the rule, the sequence and their host
//! tests are in [`firmware_plc::bus_recovery`].

use core::cell::RefCell;

use embassy_stm32::i2c::{self, Error, I2c, Master};
use embassy_stm32::mode::Blocking;
use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals::{Idr, Moder};
use embassy_stm32::time::Hertz;
use embassy_time::{block_for, Duration};
use firmware_plc::bus_recovery::{self, AfterFailure, BusPins, Failure, Recovery};
use static_cell::StaticCell;

use crate::pins::Bus;

/// The shared bus.
pub type SharedI2c = &'static RefCell<Recovering>;

/// A transaction that hangs (SCL held low, a dead bus) gives up after this long: well
/// under the 100 ms watchdog (embassy's default is 1 s). The longest legal transaction,
/// a 64-byte page read or write, takes about 7 ms at 100 kHz.
pub const TRANSACTION_TIMEOUT_MS: u64 = 20;

/// SCL (PA8) and SDA (PB5) in their GPIO ports, as [`Bus`] types them.
const SCL_PIN: usize = 8;
const SDA_PIN: usize = 5;

/// The blocking master, followed after each failed transaction by what
/// [`bus_recovery::after_failure`] asks for; the same calls as embassy's.
pub struct Recovering(I2c<'static, Blocking, Master>);

impl Recovering {
    pub fn blocking_write(&mut self, address: u8, write: &[u8]) -> Result<(), Error> {
        checked(self.0.blocking_write(address, write))
    }

    pub fn blocking_write_read(
        &mut self,
        address: u8,
        write: &[u8],
        read: &mut [u8],
    ) -> Result<(), Error> {
        checked(self.0.blocking_write_read(address, write, read))
    }

    pub fn blocking_write_vectored(&mut self, address: u8, write: &[&[u8]]) -> Result<(), Error> {
        checked(self.0.blocking_write_vectored(address, write))
    }
}

/// Passes `r` on, after the reset and bus clear if the core's rule asks for them.
#[inline(never)]
fn checked(r: Result<(), Error>) -> Result<(), Error> {
    if let Err(e) = r {
        let failure = match e {
            Error::Nack => Failure::Nack,
            Error::ZeroLengthTransfer => Failure::NotSent,
            _ => Failure::Broken,
        };
        if bus_recovery::after_failure(failure) == AfterFailure::ResetAndClear {
            let cleared = reset_and_clear();
            defmt::warn!("i2c: {}: reset, bus clear {}", e, cleared);
        }
    }
    r
}

/// I2C3 off (PE = 0; PE reads 0 once the reset has taken the 3 APB cycles RM0440 asks
/// for), the bus clear with the pins as open-drain GPIOs (the alternate function made
/// them open-drain without pulls), the pins back to I2C3, I2C3 on.
#[cold]
#[inline(never)]
fn reset_and_clear() -> Recovery {
    let i2c = pac::I2C3;
    i2c.cr1().modify(|w| w.set_pe(false));
    while i2c.cr1().read().pe() {}
    // Released (high) before they turn into outputs.
    RegisterBus.set_scl(true);
    RegisterBus.set_sda(true);
    set_mode(Moder::OUTPUT);
    let cleared = bus_recovery::recover(&mut RegisterBus);
    set_mode(Moder::ALTERNATE);
    i2c.cr1().modify(|w| w.set_pe(true));
    cleared
}

fn set_mode(m: Moder) {
    pac::GPIOA.moder().modify(|w| w.set_moder(SCL_PIN, m));
    pac::GPIOB.moder().modify(|w| w.set_moder(SDA_PIN, m));
}

/// The bus pins through their GPIO registers, while I2C3 keeps them claimed.
struct RegisterBus;

impl BusPins for RegisterBus {
    fn set_scl(&mut self, high: bool) {
        pac::GPIOA.bsrr().write(|w| {
            w.set_bs(SCL_PIN, high);
            w.set_br(SCL_PIN, !high);
        });
    }
    fn set_sda(&mut self, high: bool) {
        pac::GPIOB.bsrr().write(|w| {
            w.set_bs(SDA_PIN, high);
            w.set_br(SDA_PIN, !high);
        });
    }
    fn sda_high(&mut self) -> bool {
        pac::GPIOB.idr().read().idr(SDA_PIN) == Idr::HIGH
    }
    fn scl_high(&mut self) -> bool {
        pac::GPIOA.idr().read().idr(SCL_PIN) == Idr::HIGH
    }
    fn half_period(&mut self) {
        block_for(Duration::from_micros(5));
    }
}

/// Opens I2C3, then clears the bus (a device left in the middle of a byte by a reset).
pub fn open(b: Bus) -> SharedI2c {
    static BUS: StaticCell<RefCell<Recovering>> = StaticCell::new();
    let mut config = i2c::Config::default();
    config.frequency = Hertz::khz(100);
    config.sda_pullup = false;
    config.scl_pullup = false;
    config.timeout = Duration::from_millis(TRANSACTION_TIMEOUT_MS);
    let i2c = I2c::new_blocking(b.i2c, b.scl, b.sda, config);
    match reset_and_clear() {
        Recovery::Idle => {}
        Recovery::Freed { pulses } => {
            defmt::warn!("i2c: SDA held low, freed after {=u8} clocks", pulses)
        }
        Recovery::Stuck => defmt::warn!("i2c: bus stuck low (no pull-ups, or shorted)"),
    }
    BUS.init(RefCell::new(Recovering(i2c)))
}
