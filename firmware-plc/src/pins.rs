//! Every pin and peripheral instance the PLC image uses, in one place (NUCLEO-G431RB,
//! STM32G431RBTx).
//!
//! The board layer gets its hardware only through [`split`], so a port to the real PLC board
//! changes this file and nothing else. The README's pin map mirrors this table.
//!
//! | signal | pin | peripheral | Nucleo connector |
//! | --- | --- | --- | --- |
//! | inputs I0..I7 (active high) | PC6, PC7, PC8, PC9, PC10, PC11, PC12, PD2 | GPIO in, pull-down | morpho |
//! | outputs Q0..Q5 (active high) | PB10, PB11, PB12, PB13, PB14, PB15 | GPIO out | morpho |
//! | analog A00, A01, A02, A03 | PA0, PA1, PB0, PC1 | ADC1_IN1, IN2, IN15, IN7 | Arduino A0, A1, A3, A4 |
//! | keypad rows R0..R3 (driven low one at a time) | PA6, PA7, PB6, PB7 | GPIO out, open drain | morpho |
//! | keypad columns C0..C3 | PC2, PC3, PC4, PC5 | GPIO in, pull-up | morpho |
//! | I2C SCL / SDA (24C256 at 0x50, PCF8574 LCD at 0x27) | PA8 / PB5 | I2C3 (AF2 / AF8) | Arduino D7 / D4 |
//! | link TX / RX | PA9 / PA10 | USART1 (AF7), DMA1 CH1 / CH2 | Arduino D8 / D2 |
//! | heartbeat LED (toggles while the watchdog is fed) | PA5 | GPIO out | LD2 |

//!
//! The I2C bus is not on PB8/PB9 (I2C1): PB8 is BOOT0 with the factory option bytes
//! (nSWBOOT0 = 1), and the bus's pull-ups would make every reset boot the ROM bootloader
//! (board review D2). PB8 must never be an input that can be high at reset.

use embassy_stm32::{peripherals as p, Peri, Peripherals};

/// The eight digital inputs I0..I7.
pub struct Inputs {
    pub i0: Peri<'static, p::PC6>,
    pub i1: Peri<'static, p::PC7>,
    pub i2: Peri<'static, p::PC8>,
    pub i3: Peri<'static, p::PC9>,
    pub i4: Peri<'static, p::PC10>,
    pub i5: Peri<'static, p::PC11>,
    pub i6: Peri<'static, p::PC12>,
    pub i7: Peri<'static, p::PD2>,
}

/// The six digital outputs Q0..Q5.
pub struct Outputs {
    pub q0: Peri<'static, p::PB10>,
    pub q1: Peri<'static, p::PB11>,
    pub q2: Peri<'static, p::PB12>,
    pub q3: Peri<'static, p::PB13>,
    pub q4: Peri<'static, p::PB14>,
    pub q5: Peri<'static, p::PB15>,
}

/// The four analog inputs A00..A03 on ADC1.
pub struct Analog {
    pub adc: Peri<'static, p::ADC1>,
    pub a00: Peri<'static, p::PA0>,
    pub a01: Peri<'static, p::PA1>,
    pub a02: Peri<'static, p::PB0>,
    pub a03: Peri<'static, p::PC1>,
}

/// The 4x4 keypad matrix.
pub struct Keypad {
    pub r0: Peri<'static, p::PA6>,
    pub r1: Peri<'static, p::PA7>,
    pub r2: Peri<'static, p::PB6>,
    pub r3: Peri<'static, p::PB7>,
    pub c0: Peri<'static, p::PC2>,
    pub c1: Peri<'static, p::PC3>,
    pub c2: Peri<'static, p::PC4>,
    pub c3: Peri<'static, p::PC5>,
}

/// The I2C bus with the EEPROM and the LCD backpack.
pub struct Bus {
    pub i2c: Peri<'static, p::I2C3>,
    pub scl: Peri<'static, p::PA8>,
    pub sda: Peri<'static, p::PB5>,
}

/// The drive link USART with its DMA channels.
pub type Link = board_common::link::LinkPins<Peri<'static, p::PA9>, Peri<'static, p::PA10>>;

/// Everything else the PLC binds.
pub struct Misc {
    pub iwdg: Peri<'static, p::IWDG>,
    pub led: Peri<'static, p::PA5>,
}

/// The PLC board, grouped by job.
pub struct Board {
    pub inputs: Inputs,
    pub outputs: Outputs,
    pub analog: Analog,
    pub keypad: Keypad,
    pub bus: Bus,
    pub link: Link,
    pub misc: Misc,
}

/// Hands each board module the peripherals it owns.
pub fn split(p: Peripherals) -> Board {
    Board {
        inputs: Inputs {
            i0: p.PC6,
            i1: p.PC7,
            i2: p.PC8,
            i3: p.PC9,
            i4: p.PC10,
            i5: p.PC11,
            i6: p.PC12,
            i7: p.PD2,
        },
        outputs: Outputs {
            q0: p.PB10,
            q1: p.PB11,
            q2: p.PB12,
            q3: p.PB13,
            q4: p.PB14,
            q5: p.PB15,
        },
        analog: Analog {
            adc: p.ADC1,
            a00: p.PA0,
            a01: p.PA1,
            a02: p.PB0,
            a03: p.PC1,
        },
        keypad: Keypad {
            r0: p.PA6,
            r1: p.PA7,
            r2: p.PB6,
            r3: p.PB7,
            c0: p.PC2,
            c1: p.PC3,
            c2: p.PC4,
            c3: p.PC5,
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
        misc: Misc {
            iwdg: p.IWDG,
            led: p.PA5,
        },
    }
}

/// Drives Q0..Q5 (PB10..PB15) low as push-pull outputs, straight through the PAC, whatever
/// the application is doing. Only for the panic and HardFault paths (`board::fault`): it
/// takes no ownership and never fails. BSRR first, then MODER: no high glitch.
pub fn force_outputs_low() {
    use embassy_stm32::pac;
    use embassy_stm32::pac::gpio::vals::Moder;
    for pin in 10..=15 {
        pac::GPIOB.bsrr().write(|w| w.set_br(pin, true));
        pac::GPIOB
            .moder()
            .modify(|w| w.set_moder(pin, Moder::OUTPUT));
    }
}
