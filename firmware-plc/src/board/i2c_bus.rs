//! I2C3 at 100 kHz (the PCF8574's rating) shared by the EEPROM and the LCD backpack.
//!
//! Both users run in the application task, so the bus is a `RefCell` borrowed for one
//! blocking transaction at a time and never across an `await`.

use core::cell::RefCell;

use embassy_stm32::i2c::{self, I2c, Master};
use embassy_stm32::mode::Blocking;
use embassy_stm32::time::Hertz;
use static_cell::StaticCell;

use crate::pins::Bus;

/// The shared bus.
pub type SharedI2c = &'static RefCell<I2c<'static, Blocking, Master>>;

/// Opens the bus (external pull-ups on the EEPROM/LCD boards; the internal ones help a
/// bare breadboard).
pub fn open(b: Bus) -> SharedI2c {
    static BUS: StaticCell<RefCell<I2c<'static, Blocking, Master>>> = StaticCell::new();
    let mut config = i2c::Config::default();
    config.frequency = Hertz::khz(100);
    config.sda_pullup = true;
    config.scl_pullup = true;
    BUS.init(RefCell::new(I2c::new_blocking(b.i2c, b.scl, b.sda, config)))
}
