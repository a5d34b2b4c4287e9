//! The bare B-G431B-ESC1 (STM32G431CBU6, L6387ED gate drivers, STL180N6F7 MOSFETs).
//!
//! Sources, cited at each constant as \[tag\]:
//! * \[UM2516\]: ST UM2516, "Electronic speed controller Discovery kit for drones with
//!   STM32G431CB", its pin assignment table (net names per MCU pin) and schematic
//!   (MB1419). The pin table was read through a transcription (a GitHub README quoting
//!   "Pin table from UM2516"); the schematic's resistor values were not reachable.
//! * \[NuttX\]: Apache NuttX `boards/arm/stm32/b-g431b-esc1/src/stm32_foc.c`
//!   (board parameters comment, OPAMP set-up), `b-g431b-esc1.h` (LED, button).
//! * \[duino\]: stm32duino `variants/STM32G4xx/G431C(6-8-B)U_G441CBU/variant_B_G431B_ESC1.h`
//!   (net alias per pin).
//! * \[SimpleFOC\]: SimpleFOC's ESC1 examples, `LowsideCurrentSense(0.003f, -64.0f/7.0f,
//!   A_OP1_OUT, A_OP2_OUT, A_OP3_OUT)`, and its `_configureOPAMP` (PGA x16,
//!   `OPAMP_PGA_CONNECT_INVERTINGINPUT_IO0_BIAS`).
//! * \[TCAN33x\]: TI SLLSEQ7 (TCAN330/332/334/337), pin functions: RXD "LOW for dominant and
//!   HIGH for recessive bus states, tri-state"; SHDN "drive high for shutdown mode.
//!   Internal pull-down".
//!
//! What it models: the three low-side shunts and the resistor network that brings each
//! shunt's two ends to its OPAMP's VINP and VINM0 pins (with the bias that network puts on
//! both), the DC-link divider, the potentiometer, the CAN transceiver's RX output on PA11
//! with its shutdown input on PC11, the `PWM` command pad on PA15, the BEMF divider enable
//! on PB5 and the user LED on PC6.
//! The board has no brake chopper: nothing on it dissipates regenerated energy.

use super::{ExternalWire, NetLevel, PowerStageQuantities, VDDA_VOLTS};
use crate::periph::gpio::{Drive, External};

/// Low-side shunt of each leg, ohm: 3 mOhm \[NuttX\] ("Current shunt resistance = 0.003"),
/// \[SimpleFOC\] (`0.003f`).
pub const SHUNT_OHMS: f64 = 0.003;

/// The gain the ports program in the on-chip amplifiers: PGA x16 with the inverting input
/// on VINM0 as bias (PGA_GAIN 0b01011) \[NuttX\] ("PGA mode, non-inverting configuration
/// with external bias on VINM0", `0b01011`), \[SimpleFOC\] (`OPAMP_PGA_GAIN_16_OR_MINUS_15`,
/// `..._IO0_BIAS`).
pub const PORTS_PGA_GAIN: f64 = 16.0;

/// Shunt volts to amplifier output volts with the ports' configuration, V/V: -64/7
/// \[SimpleFOC\] (`-64.0f/7.0f`), \[NuttX\] ("Current sense gain = -9.14 (inverted current)").
/// Negative: a current out of the leg into the motor flows up through the shunt while the
/// low switch conducts, so the shunt's leg side goes below ground.
pub const EQUIVALENT_GAIN: f64 = -64.0 / 7.0;

/// Fraction of a shunt end's voltage that reaches its amplifier pin: 4/7, i.e.
/// |[`EQUIVALENT_GAIN`]| / [`PORTS_PGA_GAIN`]. The network's resistor values are in
/// \[UM2516\]'s schematic, which we could not read: the network is reconstructed from what
/// the documents do say. Each shunt end goes to an amplifier pin (\[duino\] `CURRx_H` on
/// VINP, `CURRx_L` on VINM0; \[NuttX\] "Current U+ PA1, Current U- PA3") through a divider
/// whose other end is the 3V3 rail (the bias the VINM0-biased PGA mode needs), and the
/// ports' gain of 64/7 with the PGA's 16 leaves 4/7 for the divider.
pub const DIVIDER_SIGNAL_FRACTION: f64 = 4.0 / 7.0;

/// Fraction of VDDA on each amplifier pin with no current: 3/7 (the rest of the
/// two-resistor divider of [`DIVIDER_SIGNAL_FRACTION`]): 1.414 V on PA1/PA3, PA7/PA5,
/// PB0/PB2. Not in any document we reached (see above); what matters for the firmware is
/// that both pins sit far above 0 V, which holds for any bias that lets the VINM0-biased
/// PGA measure both current directions.
pub const DIVIDER_BIAS_FRACTION: f64 = 1.0 - DIVIDER_SIGNAL_FRACTION;

/// One leg's current sense: the amplifier pins its shunt reaches and the amplifier.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShuntSense {
    /// The shunt's leg side (`Curr_fdbkN_OPAmp+`, `CURRN_H`).
    pub vinp: &'static str,
    /// The shunt's ground side (`Curr_fdbkN_OPAmp-`, `CURRN_L`).
    pub vinm0: &'static str,
    /// OPAMP instance (1..=3) and its output pin (`OPN_OUT`).
    pub opamp: u8,
    pub output: &'static str,
}

/// Legs U, V, W \[UM2516\] pin table, \[duino\], \[NuttX\] OPAMP pins.
pub const SHUNTS: [ShuntSense; 3] = [
    ShuntSense {
        vinp: "PA1",
        vinm0: "PA3",
        opamp: 1,
        output: "PA2",
    },
    ShuntSense {
        vinp: "PA7",
        vinm0: "PA5",
        opamp: 2,
        output: "PA6",
    },
    ShuntSense {
        vinp: "PB0",
        vinm0: "PB2",
        opamp: 3,
        output: "PB1",
    },
];

/// DC-link divider, V/V: 0.0962 \[NuttX\] ("Vbus sense gain = 0.0962"), on PA0 (`VBUS`,
/// \[UM2516\], \[duino\]). Full scale 3.3 V / 0.0962 = 34.3 V.
pub const DC_LINK_DIVIDER: f64 = 0.0962;
pub const DC_LINK_PIN: &str = "PA0";

/// Highest DC-link voltage the board is specified for, V: 25 V \[NuttX\] ("Vbus max = 25V
/// (6S LiPo battery pack)"), the only figure among the documents we reached (the MOSFETs
/// are 60 V parts, the bulk capacitors' rating is in the unread schematic): the
/// conservative one.
pub const DC_LINK_MAX_VOLTS: f64 = 25.0;

/// The potentiometer's wiper, PB12 (`POTENTIOMETER` \[UM2516\], \[duino\]; ADC1_IN11 \[NuttX\]).
/// Its ends are not in the documents we reached; taken as 0 V..VDDA.
pub const POT_PIN: &str = "PB12";

/// The user LED, PC6 (`STATUS` \[UM2516\], `LED_BUILTIN` \[duino\], LD2 \[NuttX\]): an output
/// load only.
pub const LED: (u8, u8) = (2, 6);

/// PB5: `GPIO_BEMF` \[UM2516\], \[duino\]: it switches the BEMF dividers of the three phases
/// (to PA4, PC4, PB11: `BEMF1..3`). It drives nothing else on the board; in particular
/// there is no brake chopper on the ESC1.
pub const BEMF_ENABLE: (u8, u8) = (1, 5);

/// PA11: `CAN_RX` \[UM2516\], \[duino\]: the CAN transceiver's RXD output.
pub const CAN_RX: (u8, u8) = (0, 11);
/// PA15: `PWM` \[UM2516\], \[duino\] (`A_PWM`): the ESC's command input pad (a
/// servo-style PWM from a flight controller). No part on the net is named in the
/// documents we reached (a series or pull resistor would be in the unread schematic):
/// the pad's net is the external wire alone, and an open wire leaves the pin to the MCU's
/// own pull (the one reading the documents allow; bench-check.md measures it).
pub const PWM_INPUT: (u8, u8) = (0, 15);
/// PC11: `CAN_SHDN` \[UM2516\], \[duino\]: the transceiver's shutdown input.
pub const CAN_SHDN: (u8, u8) = (2, 11);

/// Volts on the amplifier pins of leg `leg` (VINP, VINM0) for its current `i_a` (out of
/// the leg into the motor, A), while the leg's low switch conducts.
pub fn shunt_pins_volts(i_a: f64) -> (f64, f64) {
    let leg_side = -SHUNT_OHMS * i_a;
    let ground_side = 0.0;
    let bias = DIVIDER_BIAS_FRACTION * VDDA_VOLTS;
    (
        (DIVIDER_SIGNAL_FRACTION * leg_side + bias).clamp(0.0, VDDA_VOLTS),
        (DIVIDER_SIGNAL_FRACTION * ground_side + bias).clamp(0.0, VDDA_VOLTS),
    )
}

/// Volts on PA0 for a DC link of `u` V.
pub fn dc_link_pin_volts(u: f64) -> f64 {
    (u * DC_LINK_DIVIDER).clamp(0.0, VDDA_VOLTS)
}

/// Volts on analog pin `pin` (`"PA1"`), or `None` for a pin the board does not drive.
/// `pot` is the potentiometer's position, 0..=1.
pub fn pin_volts(pin: &str, q: &PowerStageQuantities, pot: f64) -> Option<f64> {
    for (s, &i) in SHUNTS.iter().zip(q.phase_currents_a.iter()) {
        let (vinp, vinm0) = shunt_pins_volts(i);
        if pin == s.vinp {
            return Some(vinp);
        }
        if pin == s.vinm0 {
            return Some(vinm0);
        }
    }
    match pin {
        DC_LINK_PIN => Some(dc_link_pin_volts(q.dc_link_v)),
        POT_PIN => Some(pot.clamp(0.0, 1.0) * VDDA_VOLTS),
        _ => None,
    }
}

/// The CAN transceiver's mode from how the MCU drives its SHDN input: high = shutdown;
/// released or low = normal (SHDN's internal pull-down \[TCAN33x\]).
pub fn transceiver_shut_down(shdn: Drive) -> bool {
    match shdn {
        Drive::High => true,
        Drive::Low | Drive::Released { .. } | Drive::Alternate { .. } => false,
    }
}

/// What the transceiver's RXD drives onto PA11: HIGH in normal mode on an idle bus (no
/// other node: recessive), tri-state in shutdown \[TCAN33x\]. Which TCAN33x variant (or
/// other transceiver) the ESC1 carries is in the unread schematic; the net name `CAN_SHDN`
/// and the 8-pin family with a SHDN input fit this one, and an RXD that drives the pin in
/// normal mode is the case that hides an external signal on PA11 (the conservative one).
pub fn can_rxd(shdn: Drive) -> External {
    if transceiver_shut_down(shdn) {
        External::Floating
    } else {
        External::High
    }
}

/// The level of PA11's net with the transceiver's RXD on it and an external wire brought
/// to the pin: a wire pulled hard to 0 V wins (and fights a high RXD); an open wire leaves
/// the net to RXD; a wire driven high agrees with RXD or drives a tri-stated net.
pub fn can_rx_net(shdn: Drive, wire: Option<ExternalWire>) -> NetLevel {
    let rxd = can_rxd(shdn);
    match wire {
        None | Some(ExternalWire::Open) => NetLevel {
            level: rxd,
            contention: false,
        },
        Some(ExternalWire::DrivenLow) => NetLevel {
            level: External::Low,
            contention: rxd == External::High,
        },
        Some(ExternalWire::DrivenHigh) => NetLevel {
            level: External::High,
            contention: rxd == External::Low,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::gpio::Pull;

    #[test]
    fn the_network_gives_the_ports_gain_and_a_bias_on_both_pins() {
        let (p0, m0) = shunt_pins_volts(0.0);
        assert!((p0 - 1.4143).abs() < 1e-3, "{p0}");
        assert_eq!(p0, m0, "no current: both pins at the bias");
        // The VINM0-biased PGA x16: out = 16 VINP - 15 VINM0.
        let out = |i: f64| {
            let (p, m) = shunt_pins_volts(i);
            16.0 * p - 15.0 * m
        };
        let gain = (out(1.0) - out(0.0)) / SHUNT_OHMS;
        assert!((gain - EQUIVALENT_GAIN).abs() < 1e-9, "{gain}");
        // The grounded-input PGA x16 (16 VINP) sits at the rail at 0 A.
        assert!(16.0 * p0 > VDDA_VOLTS);
    }

    #[test]
    fn pins_and_divider() {
        let q = PowerStageQuantities {
            phase_currents_a: [1.0, -2.0, 0.0],
            dc_link_v: 24.0,
        };
        assert!((pin_volts("PA0", &q, 0.0).unwrap() - 2.3088).abs() < 1e-4);
        assert!(pin_volts("PA1", &q, 0.0).unwrap() < pin_volts("PA3", &q, 0.0).unwrap());
        assert!(pin_volts("PA7", &q, 0.0).unwrap() > pin_volts("PA5", &q, 0.0).unwrap());
        assert_eq!(pin_volts("PB12", &q, 0.5), Some(1.65));
        assert_eq!(pin_volts("PC4", &q, 0.0), None);
        assert_eq!(dc_link_pin_volts(40.0), VDDA_VOLTS);
    }

    #[test]
    fn pa11_is_the_transceivers_rxd() {
        let released = Drive::Released { pull: Pull::None };
        // PC11 left alone: normal mode, RXD recessive high; a broken wire changes nothing.
        assert_eq!(
            can_rx_net(released, Some(ExternalWire::Open)).level,
            External::High
        );
        // A wire pulled to 0 V wins, fighting RXD.
        let n = can_rx_net(released, Some(ExternalWire::DrivenLow));
        assert_eq!((n.level, n.contention), (External::Low, true));
        // SHDN high: RXD tri-stated, the pin floats (the MCU's pull decides).
        assert_eq!(can_rx_net(Drive::High, None).level, External::Floating);
        assert!(!can_rx_net(Drive::High, Some(ExternalWire::DrivenLow)).contention);
    }
}
