//! Every pin and peripheral instance the drive image uses, in one place
//! (B-G431B-ESC1, STM32G431CBUx).
//!
//! The board layer gets its hardware only through [`split`], so a port to another board
//! (e.g. NUCLEO-G431RB with a power shield) changes this file and nothing else. The README's
//! pin map mirrors this table.
//!
//! | signal | pin | peripheral | ESC1 net |
//! | --- | --- | --- | --- |
//! | PWM U high / low | PA8 / PC13 | TIM1_CH1 / TIM1_CH1N | UH / UL |
//! | PWM V high / low | PA9 / PA12 | TIM1_CH2 / TIM1_CH2N | VH / VL |
//! | PWM W high / low | PA10 / PB15 | TIM1_CH3 / TIM1_CH3N | WH / WL |
//! | phase current a | PA1 (+ PA3 = VINM0) | OPAMP1_VINP (PGA x16, foot on VINM0) -> ADC1_IN13 (injected); COMP1_INP vs DAC3_CH1 | Curr_fdbk1 +/- |
//! | phase current b | PA7 (+ PA5 = VINM0) | OPAMP2_VINP (PGA x16, foot on VINM0) -> ADC2_IN16 (injected); COMP2_INP vs DAC1_CH2 (internal) | Curr_fdbk2 +/- |
//! | phase current c (comparator only) | PB0 (+ PB2 = VINM0) | OPAMP3_VINP (PGA x16, foot on VINM0) -> ADC2_IN18 (not sampled); COMP4_INP vs DAC3_CH2 | Curr_fdbk3 +/- |
//! | DC link voltage | PA0 | ADC1_IN1 (injected), COMP3_INP vs DAC1_CH1 | VBUS |
//! | aux (`COM`, potentiometer) | PB12 | ADC1_IN11 (injected) | POT |
//! | brake chopper gate (`source-sensors` only; on the bare ESC1 not driven) | PB5 | GPIO out, active high | `GPIO_BEMF` (BEMF dividers' enable, UM2516) |
//! | link TX / RX | PB6 / PB7 | USART1 (AF7), DMA1 CH1 / CH2 | encoder/Hall H1 / H2 pads |
//! | heartbeat LED (toggles while the watchdog is fed) | PC6 | GPIO out | LED |
//! | `STO_IN` (safety.md 6, NOT RATED): active low, pull-down (a broken wire requests STO) | PA15 | TIM1_BKIN (AF9), break 1; read every 1 ms | `PWM`, the ESC's command input pad |
//!
//! `STO_IN`: UM2516's pin table and stm32duino's `variant_B_G431B_ESC1.h`
//! name PA11 `CAN_RX`, the CAN transceiver's RXD output, which drives the net (a broken
//! STO wire would read "not requested"); the only TIM1_BKIN2 pin of the STM32G431CBU6 is
//! PA11 (stm32-metapac 21, `STM32G431CB`: BKIN2 on PA11 AF12 only). PA15 is the ESC1's
//! `PWM` pad (the servo-style command input: stm32duino `A_PWM`, UM2516 pin table), unused
//! by this image, and TIM1_BKIN on AF9: the STO input is break 1 and the comparators
//! moved to break 2 (`board::power_stage`). Whether the board puts a resistor on the
//! `PWM` net is in UM2516's schematic, which we could not read: bench-check.md measures
//! the open pad.
//!
//! The current rows are the bare ESC1's front end (`firmware_drive::front_end::ESC1_PGAS`);
//! with the feature `source-sensors` the OPAMPs stay off and the ADC reads PA1 (ADC1_IN2)
//! and PA7 (ADC2_IN4) directly (`DIRECT_PINS`).

//!
//! The link is not on USART2 (PB3/PB4): those are the virtual COM port of the ST-LINK on the
//! ESC1's detachable daughterboard, whose TX drives PB4 push-pull while it is attached, so
//! the PLC could never pull that line low. PB6/PB7 are the encoder/Hall
//! inputs H1/H2, free without an encoder.

use embassy_stm32::{peripherals as p, Peri, Peripherals};

/// The six TIM1 outputs and the timer itself.
pub struct PowerStage {
    pub tim: Peri<'static, p::TIM1>,
    pub u_high: Peri<'static, p::PA8>,
    pub u_low: Peri<'static, p::PC13>,
    pub v_high: Peri<'static, p::PA9>,
    pub v_low: Peri<'static, p::PA12>,
    pub w_high: Peri<'static, p::PA10>,
    pub w_low: Peri<'static, p::PB15>,
    /// `STO_IN`: TIM1's break input 1 pin (BKIN).
    pub sto_in: Peri<'static, p::PA15>,
}

/// Analog front end: measurement pins and the converters behind them.
pub struct Analog {
    pub adc1: Peri<'static, p::ADC1>,
    pub adc2: Peri<'static, p::ADC2>,
    pub current_a: Peri<'static, p::PA1>,
    pub current_b: Peri<'static, p::PA7>,
    pub dc_link: Peri<'static, p::PA0>,
    pub aux: Peri<'static, p::PB12>,
    /// The shunt amplifiers (PGA mode when the profile lists them).
    pub opamp1: Peri<'static, p::OPAMP1>,
    pub opamp2: Peri<'static, p::OPAMP2>,
    pub opamp3: Peri<'static, p::OPAMP3>,
}

/// Hardware trip path: comparators and the DACs that set their thresholds (which one
/// watches what: `firmware_drive::comparators::B_G431B_ESC1`).
pub struct Protection {
    /// Phase current a against DAC3 CH1.
    pub comp_ia: Peri<'static, p::COMP1>,
    /// Phase current b against DAC1 CH2 (its own channel: the boot trim).
    pub comp_ib: Peri<'static, p::COMP2>,
    /// DC link against DAC1 CH1.
    pub comp_udc: Peri<'static, p::COMP3>,
    /// Phase current c against DAC3 CH2.
    pub comp_ic: Peri<'static, p::COMP4>,
    /// Phase current c's sense signal (the ESC1's third shunt; the core does not sample it).
    pub current_c: Peri<'static, p::PB0>,
    pub dac_current: Peri<'static, p::DAC3>,
    pub dac_voltage: Peri<'static, p::DAC1>,
}

/// The PLC link USART with its DMA channels.
pub type Link = board_common::link::LinkPins<Peri<'static, p::PB6>, Peri<'static, p::PB7>>;

/// Everything else the drive binds.
pub struct Misc {
    pub iwdg: Peri<'static, p::IWDG>,
    pub brake: Peri<'static, p::PB5>,
    pub led: Peri<'static, p::PC6>,
}

/// The drive board, grouped by job.
pub struct Board {
    pub power: PowerStage,
    pub analog: Analog,
    pub protection: Protection,
    pub link: Link,
    pub misc: Misc,
}

/// Hands each board module the peripherals it owns.
pub fn split(p: Peripherals) -> Board {
    Board {
        power: PowerStage {
            tim: p.TIM1,
            u_high: p.PA8,
            u_low: p.PC13,
            v_high: p.PA9,
            v_low: p.PA12,
            w_high: p.PA10,
            w_low: p.PB15,
            sto_in: p.PA15,
        },
        analog: Analog {
            adc1: p.ADC1,
            adc2: p.ADC2,
            current_a: p.PA1,
            current_b: p.PA7,
            dc_link: p.PA0,
            aux: p.PB12,
            opamp1: p.OPAMP1,
            opamp2: p.OPAMP2,
            opamp3: p.OPAMP3,
        },
        protection: Protection {
            comp_ia: p.COMP1,
            comp_ib: p.COMP2,
            comp_udc: p.COMP3,
            comp_ic: p.COMP4,
            current_c: p.PB0,
            dac_current: p.DAC3,
            dac_voltage: p.DAC1,
        },
        link: Link {
            usart: p.USART1,
            tx: p.PB6,
            rx: p.PB7,
            tx_dma: p.DMA1_CH1,
            rx_dma: p.DMA1_CH2,
        },
        misc: Misc {
            iwdg: p.IWDG,
            brake: p.PB5,
            led: p.PC6,
        },
    }
}

/// Forces the six gate signals and the brake gate to push-pull GPIO outputs driven low,
/// straight through the PAC, whatever TIM1 and the drivers are doing. Only for the panic and
/// HardFault paths: it takes no ownership and never returns an error.
pub fn force_power_outputs_low() {
    use embassy_stm32::pac;
    use embassy_stm32::pac::gpio::vals::Moder;
    let gates = [
        (pac::GPIOA, 8),  // U high
        (pac::GPIOC, 13), // U low
        (pac::GPIOA, 9),  // V high
        (pac::GPIOA, 12), // V low
        (pac::GPIOA, 10), // W high
        (pac::GPIOB, 15), // W low
    ];
    // The chopper's gate, on a board with one (on the ESC1 PB5 is `GPIO_BEMF`).
    let brake = firmware_drive::config::IMAGE_BOARD
        .brake_chopper
        .then_some((pac::GPIOB, 5));
    for (port, pin) in gates.into_iter().chain(brake) {
        port.bsrr().write(|w| w.set_br(pin, true));
        port.moder().modify(|w| w.set_moder(pin, Moder::OUTPUT));
    }
}
