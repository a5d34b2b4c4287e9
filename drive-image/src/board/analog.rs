//! Measurements: ADC1 and ADC2 injected sequences, both started by TIM1 TRGO2 (OC4REF, just
//! below the top of the centre-aligned count, while the low-side switches conduct). The
//! PWM interrupt runs at the next valley, half a period later, and reads the finished
//! conversions straight from the JDR registers.
//!
//! | ADC | rank | channel | signal |
//! | --- | --- | --- | --- |
//! | ADC1 | 1 | the profile's `current_a`: IN13 (OPAMP1, ESC1) or IN2 (PA1) | phase current a |
//! | ADC1 | 2 | IN1 (PA0) | DC link |
//! | ADC1 | 3 | IN11 (PB12) | aux `COM` |
//! | ADC2 | 1 | the profile's `current_b`: IN16 (OPAMP2, ESC1) or IN4 (PA7) | phase current b |
//!
//! Which channel carries the currents is the board profile's table
//! (`firmware_drive::front_end`); this module only binds it. The counts go to the core
//! unscaled ([`firmware_drive::measure::AdcSample`]).
//!
//! Register level through the PAC (RM0440 "Analog-to-digital converters (ADC)"), in the
//! order and with the values embassy-stm32 0.6's `Adc::new` and
//! `setup_injected_conversions` wrote: the generic driver was ~860 B of the start-up task
//! for two fixed sequences (`docs/size.md`).

use embassy_stm32::pac;
use embassy_stm32::pac::adc::vals::{Adcaldif, Exten, SampleTime};
use embassy_stm32::pac::adccommon::vals::Presc;
use embassy_stm32::peripherals::{ADC1, ADC2, OPAMP1, OPAMP2, OPAMP3, PA0, PA1, PA7, PB12};
use embassy_stm32::Peri;
use firmware_drive::front_end::{AdcInput, FrontEndSpec};
use firmware_drive::measure::AdcSample;

use crate::pins::Analog;

/// Sample time of every channel: 12.5 ADC clocks (0.3 us at 42.5 MHz) settles the
/// low-impedance sensor and amplifier outputs; the whole ADC1 sequence takes about 2 us.
const SAMPLE_TIME: SampleTime = SampleTime::CYCLES12_5;

/// ADC12's clock prescaler (ADC12_CCR.PRESC): the kernel clock is PLL P, 42.5 MHz
/// (`board_common::clocks`), below the ADC's 60 MHz: undivided.
const PRESC: Presc = Presc::DIV1;

/// JEXTSEL of TIM1_TRGO2 for ADC1/ADC2 injected conversions (RM0440 "ADC1/ADC2 -
/// External triggers for injected channels": `adc_jext_trg8`).
const JEXTSEL_TIM1_TRGO2: u8 = 8;

/// Regulator start-up time tADCVREG_STUP (20 us, RM0440 "ADC voltage regulator") and the
/// wait embassy-stm32 0.6 keeps after each calibration, in core cycles at 170 MHz.
const ADC_SETTLE_CYCLES: u32 = board_common::clocks::SYSCLK_HZ / 1_000_000 * 20;

/// The converters and the amplifiers, owned so that nothing else claims them; they run
/// from [`init`] on and are never stopped.
pub struct Converters {
    _adc: (Peri<'static, ADC1>, Peri<'static, ADC2>),
    _opamps: (
        Peri<'static, OPAMP1>,
        Peri<'static, OPAMP2>,
        Peri<'static, OPAMP3>,
    ),
    _pins: (
        Peri<'static, PA1>,
        Peri<'static, PA7>,
        Peri<'static, PA0>,
        Peri<'static, PB12>,
    ),
}

/// The ADC channel of the front end's input `input` on ADC `adc` (the table's choice; a
/// profile whose input is on the other ADC cannot be bound). A pin input's channel is the
/// bound pin's by the table (PA1 = ADC1_IN2, PA7 = ADC2_IN4: the core's
/// `direct_pins_read_the_sensor_pins`); checking it here again cost 64 B.
fn channel(fe: &FrontEndSpec, input: AdcInput, adc: u8) -> u8 {
    match fe.adc_channel(input) {
        Some((a, ch)) if a == adc => ch,
        _ => super::fault::fatal(super::fault::UNBINDABLE_PROFILE),
    }
}

/// Powers ADC `r` up and calibrates it (single-ended, then differential), then enables it
/// with regular conversions single and software-triggered: the register sequence of
/// embassy-stm32 0.6's `Adc::new` (RM0440 "ADC on-off control", "Calibration").
fn power_up(r: pac::adc::Adc) {
    r.cr().modify(|w| {
        w.set_deeppwd(false);
        w.set_advregen(true);
    });
    cortex_m::asm::delay(ADC_SETTLE_CYCLES);
    r.difsel().write_value(pac::adc::regs::Difsel(0));
    for dif in [Adcaldif::SINGLE_ENDED, Adcaldif::DIFFERENTIAL] {
        r.cr().modify(|w| w.set_adcaldif(dif));
        r.cr().modify(|w| w.set_adcal(true));
        while r.cr().read().adcal() {}
        cortex_m::asm::delay(ADC_SETTLE_CYCLES);
    }
    while r.cr().read().addis() {}
    if !r.cr().read().aden() {
        r.isr().modify(|w| w.set_adrdy(true));
        r.cr().modify(|w| w.set_aden(true));
        while !r.isr().read().adrdy() {}
    }
    r.cfgr().modify(|w| {
        w.set_cont(false);
        w.set_exten(Exten::DISABLED);
    });
}

/// Arms ADC `r`'s injected sequence `channels` (one rank each, [`SAMPLE_TIME`]) on the
/// rising edge of TIM1 TRGO2, without the end-of-sequence interrupt, and starts it.
fn arm_injected(r: pac::adc::Adc, channels: &[u8]) {
    let mut jsqr = pac::adc::regs::Jsqr(0);
    jsqr.set_jl(channels.len().saturating_sub(1) as u8);
    for (rank, &ch) in channels.iter().enumerate() {
        if ch <= 9 {
            r.smpr().modify(|w| w.set_smp(usize::from(ch), SAMPLE_TIME));
        } else {
            r.smpr2()
                .modify(|w| w.set_smp(usize::from(ch - 10), SAMPLE_TIME));
        }
        jsqr.set_jsq(rank, ch);
    }
    jsqr.set_jextsel(JEXTSEL_TIM1_TRGO2);
    jsqr.set_jexten(Exten::RISING_EDGE);
    r.cfgr().modify(|w| w.set_jdiscen(false));
    r.jsqr().write_value(jsqr);
    r.ier().modify(|w| w.set_jeosie(false));
    r.cr().modify(|w| w.set_jadstart(true));
}

/// Calibrates both ADCs, arms their injected sequences on TIM1 TRGO2 with the channels of
/// the front end `fe`, then enables its amplifiers ([`super::opamps::apply`]).
///
/// The comparators share the current and DC-link pins; they only need the pins in analog
/// mode, which is set here as well (PA0, PA1, PA7, PB12: they are analog from reset).
pub fn init(a: Analog, fe: &FrontEndSpec) -> Converters {
    let ch_a = channel(fe, fe.current_a, 1);
    let ch_b = channel(fe, fe.current_b, 2);
    // ADC12's clock on and the pair reset (AHB2: one enable and one reset bit for both).
    pac::RCC.ahb2rstr().modify(|w| w.set_adc12rst(true));
    pac::RCC.ahb2enr().modify(|w| w.set_adc12en(true));
    let _ = pac::RCC.ahb2enr().read();
    cortex_m::asm::dsb();
    pac::RCC.ahb2rstr().modify(|w| w.set_adc12rst(false));
    pac::ADC12_COMMON.ccr().modify(|w| w.set_presc(PRESC));
    power_up(pac::ADC1);
    power_up(pac::ADC2);
    super::analog_pins(&[
        (pac::GPIOA, 0),
        (pac::GPIOA, 1),
        (pac::GPIOA, 7),
        (pac::GPIOB, 12),
    ]);
    // Rank order: current a, DC link (IN1, PA0), aux (IN11, PB12).
    arm_injected(pac::ADC1, &[ch_a, 1, 11]);
    arm_injected(pac::ADC2, &[ch_b]);
    super::opamps::apply(fe);
    Converters {
        _adc: (a.adc1, a.adc2),
        _opamps: (a.opamp1, a.opamp2, a.opamp3),
        _pins: (a.current_a, a.current_b, a.dc_link, a.aux),
    }
}

/// The latest injected conversions of both ADCs.
#[inline(always)]
pub fn read() -> AdcSample {
    AdcSample {
        i_a: pac::ADC1.jdr(0).read().jdata(),
        u_dc: pac::ADC1.jdr(1).read().jdata(),
        aux: pac::ADC1.jdr(2).read().jdata(),
        i_b: pac::ADC2.jdr(0).read().jdata(),
    }
}
