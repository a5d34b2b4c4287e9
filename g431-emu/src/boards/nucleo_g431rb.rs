//! The NUCLEO-G431RB (STM32G431RBT6), the PLC board.
//!
//! Sources: \[UM2505\] ST UM2505, "STM32G4 Nucleo-64 boards (MB1367)", default solder
//! bridges; the project's contract `shared/spec/lift.md` ("Pins", checked against UM2505)
//! and `service.md` 1.
//!
//! What sits on the NUCLEO itself is modelled here; what the rig wires to its pins (the
//! PLC's opto inputs and outputs, the keypad, the I2C modules) is the rig's, in hil-sim's
//! glue (`hil-sim/src/emu/boards.rs`, from the README's pin map).

/// The ST-LINK virtual COM port: LPUART1 TX on PA2, RX on PA3 \[UM2505\], `service.md` 1.
/// The bridge drives PA3 (idle high) while the ST-LINK is powered: hil-sim's host end.
pub const VCP_TX: &str = "PA2";
pub const VCP_RX: &str = "PA3";

/// User LED LD2 (green) on PA5 (Arduino D13) \[UM2505\]: an output load only.
pub const LD2: (u8, u8) = (0, 5);

/// User button B1 on PC13 \[UM2505\], `lift.md` ("PC13 (user button B1)"). Its level is not
/// modelled: no image reads PC13.
pub const B1: (u8, u8) = (2, 13);

/// The LSE crystal X2, 32.768 kHz on PC14/PC15 (OSC32_IN/OSC32_OUT), fitted by default
/// \[UM2505\] ("LSE clock" / OSC 32 kHz): the RTC's clock, the backup domain kept across
/// resets.
pub const LSE_HZ: u64 = 32_768;

/// Pins the board itself uses besides those above \[UM2505\], `lift.md`: SWD (PA13, PA14),
/// SWO (PB3), BOOT0 (PB8), the 32.768 kHz and 24 MHz crystals (PC14, PC15, PF0, PF1), NRST
/// (PG10). A rig wire on them would fight the board.
pub const TAKEN: [(u8, u8); 9] = [
    (0, 13),
    (0, 14),
    (1, 3),
    (1, 8),
    (2, 14),
    (2, 15),
    (5, 0),
    (5, 1),
    (6, 10),
];
