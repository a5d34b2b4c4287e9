//! I2C3 at 100 kHz (the PCF8574's rating) shared by the EEPROM and the LCD backpack.
//!
//! Both users run in the application task, so the bus is a `RefCell` borrowed for one
//! blocking transaction at a time and never across an `await`.
//!
//! Bus voltage (review D16): the usual PCF8574 LCD backpack and 24C256 module run at 5 V
//! with their 4.7-10 kΩ pull-ups to 5 V; PA8 and PB5 are 5 V tolerant (FT), which allows
//! this only with the pins' internal pull-up and pull-down **off** (datasheet: a pin
//! driven above VDD + 0.3 V). So the internal pull-ups stay off; a bus without external
//! pull-ups (a bare breadboard) needs 4.7 kΩ to 3.3 V fitted. See the README.
//!
//! Before the peripheral takes the pins, the bus is cleared (review D6): a reset in the
//! middle of an EEPROM read can leave the chip holding SDA low
//! ([`firmware_plc::bus_recovery`], the sequence and its host tests).
//!
//! At run time too (review N12): after a transaction that failed other than by a NACK (a
//! timeout while a device held SCL low, a bus error, a lost arbitration), embassy-stm32
//! 0.6's blocking master returns with the peripheral as it was (`i2c/v2.rs`: `wait_tc`'s
//! timeout sends no STOP, `master_stop` after a timeout leaves CR2.STOP pending, BUSY
//! stays), and every later transaction of the EEPROM and the LCD times out while the
//! watchdog is fed. [`Recovering`] then resets the peripheral (RM0440 "I2C software
//! reset": PE = 0 releases both lines and clears the state machine and CR2.START/STOP) and
//! clears the bus from the pins with the boot's sequence (up to 9 clocks, then a STOP), so
//! the next transaction starts on an idle bus. A NACK needs none of it: the peripheral
//! sent the STOP itself, and the EEPROM's ready poll lives on NACKs.

use core::cell::RefCell;

use embassy_stm32::gpio::{Level, OutputOpenDrain, Speed};
use embassy_stm32::i2c::{self, Error, I2c, Master};
use embassy_stm32::mode::Blocking;
use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals::Moder;
use embassy_stm32::time::Hertz;
use embassy_time::{block_for, Duration};
use firmware_plc::bus_recovery::{self, BusPins, Recovery};
use static_cell::StaticCell;

use crate::pins::Bus;

/// The shared bus.
pub type SharedI2c = &'static RefCell<Recovering>;

/// The blocking master with the run-time recovery of review N12 (module docs) after each
/// failed transaction; the same calls as embassy's.
pub struct Recovering(I2c<'static, Blocking, Master>);

impl Recovering {
    pub fn blocking_write(&mut self, address: u8, write: &[u8]) -> Result<(), Error> {
        recover_after(self.0.blocking_write(address, write))
    }

    pub fn blocking_write_read(
        &mut self,
        address: u8,
        write: &[u8],
        read: &mut [u8],
    ) -> Result<(), Error> {
        recover_after(self.0.blocking_write_read(address, write, read))
    }

    pub fn blocking_write_vectored(&mut self, address: u8, write: &[&[u8]]) -> Result<(), Error> {
        recover_after(self.0.blocking_write_vectored(address, write))
    }
}

/// Passes `r` on, after resetting I2C3 and clearing the bus if it failed other than by a
/// NACK (or a call with nothing to send, which never touched the bus).
fn recover_after<T>(r: Result<T, Error>) -> Result<T, Error> {
    if let Err(e) = &r {
        if !matches!(e, Error::Nack | Error::ZeroLengthTransfer) {
            let cleared = reset_and_clear();
            defmt::warn!("i2c: {}: peripheral reset, bus clear {}", e, cleared);
        }
    }
    r
}

/// SCL (PA8) and SDA (PB5) in their GPIO ports, as `pins::Bus` assigns them.
const SCL_PIN: usize = 8;
const SDA_PIN: usize = 5;

/// I2C3 off (PE = 0 for the software reset; PE reads 0 only once the reset has taken the
/// 3 APB cycles RM0440 asks for), the bus clear with the pins as open-drain GPIOs (the
/// alternate function already made them open-drain), the pins back to I2C3, I2C3 on.
fn reset_and_clear() -> Recovery {
    let i2c = pac::I2C3;
    i2c.cr1().modify(|w| w.set_pe(false));
    while i2c.cr1().read().pe() {}
    let (scl_port, sda_port) = (pac::GPIOA, pac::GPIOB);
    // Released (high) before they turn into outputs.
    scl_port.bsrr().write(|w| w.set_bs(SCL_PIN, true));
    sda_port.bsrr().write(|w| w.set_bs(SDA_PIN, true));
    scl_port
        .moder()
        .modify(|w| w.set_moder(SCL_PIN, Moder::OUTPUT));
    sda_port
        .moder()
        .modify(|w| w.set_moder(SDA_PIN, Moder::OUTPUT));
    let cleared = bus_recovery::recover(&mut RegisterBus);
    scl_port
        .moder()
        .modify(|w| w.set_moder(SCL_PIN, Moder::ALTERNATE));
    sda_port
        .moder()
        .modify(|w| w.set_moder(SDA_PIN, Moder::ALTERNATE));
    i2c.cr1().modify(|w| w.set_pe(true));
    cleared
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
        pac::GPIOB.idr().read().idr(SDA_PIN) == pac::gpio::vals::Idr::HIGH
    }
    fn scl_high(&mut self) -> bool {
        pac::GPIOA.idr().read().idr(SCL_PIN) == pac::gpio::vals::Idr::HIGH
    }
    fn half_period(&mut self) {
        block_for(Duration::from_micros(5));
    }
}

/// A transaction that hangs (SCL held low, a dead bus) gives up after this long: well
/// under the 100 ms watchdog (embassy's default is 1 s). The longest legal transaction,
/// a 64-byte page read, takes about 6 ms at 100 kHz.
pub const TRANSACTION_TIMEOUT_MS: u64 = 20;

/// The bus pins as open-drain GPIOs for the bus clear.
struct GpioBus<'a> {
    scl: OutputOpenDrain<'a>,
    sda: OutputOpenDrain<'a>,
}

impl BusPins for GpioBus<'_> {
    fn set_scl(&mut self, high: bool) {
        self.scl.set_level(Level::from(high));
    }
    fn set_sda(&mut self, high: bool) {
        self.sda.set_level(Level::from(high));
    }
    fn sda_high(&mut self) -> bool {
        self.sda.is_high()
    }
    fn scl_high(&mut self) -> bool {
        self.scl.is_high()
    }
    fn half_period(&mut self) {
        block_for(Duration::from_micros(5));
    }
}

/// Clears the bus, then opens it.
pub fn open(mut b: Bus) -> SharedI2c {
    static BUS: StaticCell<RefCell<Recovering>> = StaticCell::new();
    let recovery = {
        let mut pins = GpioBus {
            scl: OutputOpenDrain::new(b.scl.reborrow(), Level::High, Speed::Low),
            sda: OutputOpenDrain::new(b.sda.reborrow(), Level::High, Speed::Low),
        };
        bus_recovery::recover(&mut pins)
    };
    match recovery {
        Recovery::Idle => {}
        Recovery::Freed { pulses } => {
            defmt::warn!("i2c: SDA held low, freed after {=u8} clocks", pulses)
        }
        Recovery::Stuck => defmt::warn!("i2c: bus stuck low (no pull-ups, or shorted)"),
    }
    let mut config = i2c::Config::default();
    config.frequency = Hertz::khz(100);
    config.sda_pullup = false;
    config.scl_pullup = false;
    config.timeout = Duration::from_millis(TRANSACTION_TIMEOUT_MS);
    BUS.init(RefCell::new(Recovering(I2c::new_blocking(
        b.i2c, b.scl, b.sda, config,
    ))))
}
