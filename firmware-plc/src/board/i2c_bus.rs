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

use core::cell::RefCell;

use embassy_stm32::gpio::{Level, OutputOpenDrain, Speed};
use embassy_stm32::i2c::{self, I2c, Master};
use embassy_stm32::mode::Blocking;
use embassy_stm32::time::Hertz;
use embassy_time::{block_for, Duration};
use firmware_plc::bus_recovery::{self, BusPins, Recovery};
use static_cell::StaticCell;

use crate::pins::Bus;

/// The shared bus.
pub type SharedI2c = &'static RefCell<I2c<'static, Blocking, Master>>;

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
    static BUS: StaticCell<RefCell<I2c<'static, Blocking, Master>>> = StaticCell::new();
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
    BUS.init(RefCell::new(I2c::new_blocking(b.i2c, b.scl, b.sda, config)))
}
