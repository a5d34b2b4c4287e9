//! Devices on the boards' buses, modelled from their datasheets.

pub mod clt01_38sq7;
pub mod eeprom_24c256;
pub mod lcd_backpack;
pub mod vni8200xp;
