//! Devices on the boards' buses, modelled from their datasheets.
