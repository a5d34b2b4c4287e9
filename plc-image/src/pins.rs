//! Every pin and peripheral instance the PLC image uses, in one place (NUCLEO-G431RB,
//! STM32G431RBTx).
//!
//! The board layer gets its hardware only through [`split`], so a port to the real PLC board
//! changes this file and nothing else. The README's pin map mirrors this table.
//!
//! | signal | pin | peripheral | Nucleo connector |
//! | --- | --- | --- | --- |
//! | inputs D00..D07 (active high) | PC6, PC7, PC8, PC9, PC10, PC11, PC12, PD2 | GPIO in, pull-down | morpho |
//! | inputs D08..D15 (active high) | PA4, PA11, PA12, PA15, PB1, PB2, PB4, PC0 | GPIO in, pull-down | Arduino A2 (PA4), D5 (PB4), A5 (PC0); the rest morpho |
//! | outputs O00..O05 (active high) | PB10, PB11, PB12, PB13, PB14, PB15 | GPIO out | morpho |
//! | outputs O06, O07 (active high) | PB9, PB8 | GPIO out | Arduino D14, D15 |
//! | analog A00, A01, A02, A03 | PA0, PA1, PB0, PC1 | ADC1_IN1, IN2, IN15, IN7 | Arduino A0, A1, A3, A4 |
//! | keypad rows R0..R3 (driven low one at a time) | PA6, PA7, PB6, PB7 | GPIO out, open drain | morpho |
//! | keypad columns C0..C3 | PC2, PC3, PC4, PC5 | GPIO in, pull-up | morpho |
//! | I2C SCL / SDA (24C256 at 0x50, PCF8574 LCD at 0x27) | PA8 / PB5 | I2C3 (AF2 / AF8) | Arduino D7 / D4 |
//! | link TX / RX | PA9 / PA10 | USART1 (AF7), DMA1 CH1 / CH2 | Arduino D8 / D2 |
//! | service port TX / RX (service.md 1) | PA2 / PA3 | LPUART1 (AF12), DMA1 CH3 / CH4 | ST-LINK/V3E virtual COM port (USB cable) |
//! | heartbeat LED (toggles while the watchdog is fed) | PA5 | GPIO out | LD2 |
//!
//! The I2C bus is not on PB8/PB9 (I2C1): PB8 is BOOT0 with the factory option bytes
//! (nSWBOOT0 = 1), and the bus's pull-ups would make every reset boot the ROM bootloader.
//! PB8 must never be an input that can be high at reset.
//!
//! # D08-D15 and O06-O07 (lift.md 1)
//!
//! Besides the table above and what the NUCLEO-G431RB's own hardware takes with its default
//! solder bridges (UM2505: PA13/PA14 SWD, PB3 SWO, PA2/PA3 the ST-LINK virtual COM port =
//! LPUART1, the service port; PC13 button B1; PC14/PC15 and PF0/PF1 the crystals; PG10
//! NRST), lift.md 1 lists ten free pins: PA4, PA8, PA11, PA12, PA15, PB1, PB2, PB4, PB5,
//! PC0. PA8/PB5 became the I2C3 bus, which freed PB8/PB9. That leaves
//! PA4, PA11, PA12, PA15, PB1, PB2, PB4, PC0, PB8, PB9: ten again, 8 inputs + 2 outputs, so
//! no SPI shift registers are needed.
//!
//! * Outputs O06/O07 are PB9/PB8: both leave reset in analog mode (high impedance), so
//!   nothing drives a load before the firmware writes the image. PB8 is also BOOT0, sampled
//!   at reset; as an output it is safe as long as its load (an opto-coupler LED, a driver
//!   such as a ULN2803 with its own input pull-down) never pulls the pin high. An input
//!   there could be high at reset and boot the ROM bootloader, so PB8 is the output nobody
//!   needs: O07, the lift's spare (always 0).
//! * PA15 (JTDI) and PB4 (NJTRST) leave reset as JTAG pins with internal pull resistors:
//!   an output's load would switch on during reset, so they are inputs (D11, D14). The
//!   firmware configures every input with its pull-down before the first sample.
//! * PA11/PA12 (the G431's USB D-/D+) are plain GPIO: the NUCLEO's USB connector belongs to
//!   the ST-LINK, not to the target.
//!
//! The pin arrays are `[_; DIGITAL_INPUTS]` / `[_; DIGITAL_OUTPUTS]`
//! (`shared_protocol::program`): a table with one pin more or less does not compile.

use embassy_stm32::gpio::AnyPin;
use embassy_stm32::{peripherals as p, Peri, Peripherals};
use shared_protocol::program::DIGITAL_INPUTS;
#[cfg(not(feature = "shield-plc01a1"))]
use shared_protocol::program::DIGITAL_OUTPUTS;

/// The digital inputs read at GPIO pins, in order: D00..D15, or D08..D15 in the shield
/// profile (D00..D07 come from the shield's CLT01-38SQ7).
pub struct Inputs {
    pub pins: [Peri<'static, AnyPin>; GPIO_INPUTS],
}

/// Number of digital inputs at GPIO pins.
#[cfg(not(feature = "shield-plc01a1"))]
pub const GPIO_INPUTS: usize = DIGITAL_INPUTS as usize;
/// Number of digital inputs at GPIO pins (D08..D15).
#[cfg(feature = "shield-plc01a1")]
pub const GPIO_INPUTS: usize = DIGITAL_INPUTS as usize - 8;

/// The digital outputs O00..O07, in order.
#[cfg(not(feature = "shield-plc01a1"))]
pub struct Outputs {
    pub pins: [Peri<'static, AnyPin>; DIGITAL_OUTPUTS as usize],
}

/// The X-NUCLEO-PLC01A1 (`firmware-plc/docs/field-io.md`): SPI1 with SCK on D3 (PB3, tied
/// to D13 on the shield), MISO D12 (PA6), MOSI D11 (PA7); the CLT01-38SQ7's chip select
/// D10 (PB6), the VNI8200XP's D9 (PC7), its OUT_EN D6 (PB10).
#[cfg(feature = "shield-plc01a1")]
pub struct Shield {
    pub spi: Peri<'static, p::SPI1>,
    pub sck: Peri<'static, p::PB3>,
    pub miso: Peri<'static, p::PA6>,
    pub mosi: Peri<'static, p::PA7>,
    pub cs_inputs: Peri<'static, AnyPin>,
    pub cs_outputs: Peri<'static, AnyPin>,
    pub out_enable: Peri<'static, AnyPin>,
}

/// The four analog inputs A00..A03 on ADC1.
pub struct Analog {
    pub adc: Peri<'static, p::ADC1>,
    pub a00: Peri<'static, p::PA0>,
    pub a01: Peri<'static, p::PA1>,
    pub a02: Peri<'static, p::PB0>,
    pub a03: Peri<'static, p::PC1>,
}

/// The 4x4 keypad matrix: rows R0..R3, columns C0..C3.
pub struct Keypad {
    pub rows: [Peri<'static, AnyPin>; 4],
    pub cols: [Peri<'static, AnyPin>; 4],
}

/// The I2C bus with the EEPROM and the LCD backpack.
pub struct Bus {
    pub i2c: Peri<'static, p::I2C3>,
    pub scl: Peri<'static, p::PA8>,
    pub sda: Peri<'static, p::PB5>,
}

/// The drive link USART with its DMA channels.
pub type Link = board_common::link::LinkPins<Peri<'static, p::PA9>, Peri<'static, p::PA10>>;

/// The service port: LPUART1 on the ST-LINK's virtual COM port, with its DMA channels.
pub struct Service {
    pub lpuart: Peri<'static, p::LPUART1>,
    pub tx: Peri<'static, p::PA2>,
    pub rx: Peri<'static, p::PA3>,
    pub tx_dma: Peri<'static, p::DMA1_CH3>,
    pub rx_dma: Peri<'static, p::DMA1_CH4>,
}

/// Everything else the PLC binds.
pub struct Misc {
    pub iwdg: Peri<'static, p::IWDG>,
    /// The heartbeat LED (LD2 on PA5); in the shield profile a spare pin (LD2 is on the
    /// shield's SPI clock there).
    pub led: Peri<'static, AnyPin>,
}

/// The PLC board, grouped by job.
pub struct Board {
    pub inputs: Inputs,
    #[cfg(not(feature = "shield-plc01a1"))]
    pub outputs: Outputs,
    #[cfg(feature = "shield-plc01a1")]
    pub shield: Shield,
    pub analog: Analog,
    pub keypad: Keypad,
    pub bus: Bus,
    pub link: Link,
    pub service: Service,
    pub misc: Misc,
}

/// Hands each board module the peripherals it owns.
pub fn split(p: Peripherals) -> Board {
    Board {
        #[cfg(not(feature = "shield-plc01a1"))]
        inputs: Inputs {
            pins: [
                p.PC6.into(),  // D00
                p.PC7.into(),  // D01
                p.PC8.into(),  // D02
                p.PC9.into(),  // D03
                p.PC10.into(), // D04
                p.PC11.into(), // D05
                p.PC12.into(), // D06
                p.PD2.into(),  // D07
                p.PA4.into(),  // D08
                p.PA11.into(), // D09
                p.PA12.into(), // D10
                p.PA15.into(), // D11 (JTDI at reset: input only)
                p.PB1.into(),  // D12
                p.PB2.into(),  // D13
                p.PB4.into(),  // D14 (NJTRST at reset: input only)
                p.PC0.into(),  // D15
            ],
        },
        #[cfg(feature = "shield-plc01a1")]
        inputs: Inputs {
            pins: [
                p.PA4.into(),  // D08
                p.PA11.into(), // D09
                p.PA12.into(), // D10
                p.PA15.into(), // D11 (JTDI at reset: input only)
                p.PB1.into(),  // D12
                p.PB2.into(),  // D13
                p.PB4.into(),  // D14 (NJTRST at reset: input only)
                p.PC0.into(),  // D15
            ],
        },
        #[cfg(not(feature = "shield-plc01a1"))]
        outputs: Outputs {
            pins: [
                p.PB10.into(), // O00
                p.PB11.into(), // O01
                p.PB12.into(), // O02
                p.PB13.into(), // O03
                p.PB14.into(), // O04
                p.PB15.into(), // O05
                p.PB9.into(),  // O06
                p.PB8.into(),  // O07 (BOOT0: an output only)
            ],
        },
        #[cfg(feature = "shield-plc01a1")]
        shield: Shield {
            spi: p.SPI1,
            sck: p.PB3,
            miso: p.PA6,
            mosi: p.PA7,
            cs_inputs: p.PB6.into(),
            cs_outputs: p.PC7.into(),
            out_enable: p.PB10.into(),
        },
        analog: Analog {
            adc: p.ADC1,
            a00: p.PA0,
            a01: p.PA1,
            a02: p.PB0,
            a03: p.PC1,
        },
        #[cfg(not(feature = "shield-plc01a1"))]
        keypad: Keypad {
            rows: [p.PA6.into(), p.PA7.into(), p.PB6.into(), p.PB7.into()],
            cols: [p.PC2.into(), p.PC3.into(), p.PC4.into(), p.PC5.into()],
        },
        // R0..R2's pins are the shield's MISO, MOSI and CS; they move to morpho pins the
        // shield's GPIO inputs D00..D02 left free.
        #[cfg(feature = "shield-plc01a1")]
        keypad: Keypad {
            rows: [p.PC8.into(), p.PC9.into(), p.PC10.into(), p.PB7.into()],
            cols: [p.PC2.into(), p.PC3.into(), p.PC4.into(), p.PC5.into()],
        },
        bus: Bus {
            i2c: p.I2C3,
            scl: p.PA8,
            sda: p.PB5,
        },
        link: Link {
            usart: p.USART1,
            tx: p.PA9,
            rx: p.PA10,
            tx_dma: p.DMA1_CH1,
            rx_dma: p.DMA1_CH2,
        },
        service: Service {
            lpuart: p.LPUART1,
            tx: p.PA2,
            rx: p.PA3,
            tx_dma: p.DMA1_CH3,
            rx_dma: p.DMA1_CH4,
        },
        misc: Misc {
            iwdg: p.IWDG,
            #[cfg(not(feature = "shield-plc01a1"))]
            led: p.PA5.into(),
            // PA5 (LD2) is tied to the shield's SPI clock through D13-D3: never driven.
            // The heartbeat goes to PC6 (morpho CN10 pin 4, free in this profile).
            #[cfg(feature = "shield-plc01a1")]
            led: p.PC6.into(),
        },
    }
}

/// Drives O00..O07 (PB10..PB15, PB9, PB8) low as push-pull outputs, straight through the
/// PAC, whatever the application is doing. Only for the panic and HardFault paths
/// (`board::fault`): it takes no ownership and never fails. BSRR first, then MODER: no high
/// glitch.
pub fn force_outputs_low() {
    use embassy_stm32::pac;
    use embassy_stm32::pac::gpio::vals::Moder;
    for pin in 8..=15 {
        pac::GPIOB.bsrr().write(|w| w.set_br(pin, true));
        pac::GPIOB
            .moder()
            .modify(|w| w.set_moder(pin, Moder::OUTPUT));
    }
}
