//! Devices on the boards' buses, modelled from their datasheets.

pub mod eeprom_24c256;
pub mod lcd_backpack;
