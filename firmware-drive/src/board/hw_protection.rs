//! Hardware trips: COMP1/COMP2 compare the phase-current signals with DAC3's two channels
//! (`OC_HW`), COMP3 compares the DC-link divider with DAC1 CH1 (`OV_HW`). Their outputs are
//! ORed into TIM1's break input, which clears MOE within a few tens of nanoseconds without
//! software; automatic output enable is off, so the break latches until the core
//! acknowledges the fault and a new RUN sets MOE again.
//!
//! The comparators see the same pins as the ADC, so the thresholds are in ADC counts of the
//! same scale as the core's measurements (see `firmware_drive::measure`).

use embassy_stm32::comp::{self, Comp, Config, Hysteresis, InvertingInput, OutputPolarity};
use embassy_stm32::dac::{Dac, DacChannel, Value};
use embassy_stm32::mode::Blocking;
use embassy_stm32::peripherals::{COMP1, COMP2, COMP3, PA0, PA1, PA7};
use embassy_stm32::{bind_interrupts, pac, Peri};
use firmware_drive::measure::{
    udc_counts_at_volts, ADC_FULL_COUNTS, CURRENT_FULL_CENTIAMPS, CURRENT_ZERO_COUNTS,
};
use firmware_drive::protection::HwBreak;

use crate::pins::Protection;

/// Hardware overcurrent threshold (the source's trimmer; hil-sim's default rig), 0.01 A.
pub const OC_HW_CENTIAMPS: i32 = 300;
/// Hardware overvoltage threshold (the source's trimmer; hil-sim's default rig), V.
pub const OV_HW_VOLTS: u32 = 40;
/// TIM1 break-input comparator indices (AF1.BKCMPxE, 0-based) of COMP1..COMP3.
pub const BREAK_COMPARATORS: [usize; 3] = [0, 1, 2];

bind_interrupts!(struct Irqs {
    COMP1_2_3 => comp::InterruptHandler<COMP1>, comp::InterruptHandler<COMP2>, comp::InterruptHandler<COMP3>;
});

/// ADC counts of a phase current (the inverse of `measure::current_centiamps`), clamped to
/// the converter's range.
fn current_counts(centiamps: i32) -> u16 {
    let counts = CURRENT_ZERO_COUNTS + centiamps * CURRENT_ZERO_COUNTS / CURRENT_FULL_CENTIAMPS;
    counts.clamp(0, ADC_FULL_COUNTS as i32) as u16
}

/// The running comparators and threshold DACs.
pub struct HwProtection {
    _comps: (
        Comp<'static, COMP1>,
        Comp<'static, COMP2>,
        Comp<'static, COMP3>,
    ),
    _dac_current: (DacChannel<'static, Blocking>, DacChannel<'static, Blocking>),
    _dac_voltage: Dac<'static, Blocking>,
}

/// Sets the thresholds and enables the three comparators (not yet routed to the break
/// input: [`super::power_stage::arm_break`] does that once TIM1 runs).
pub fn init(
    p: Protection,
    ia: Peri<'_, PA1>,
    ib: Peri<'_, PA7>,
    udc: Peri<'_, PA0>,
) -> HwProtection {
    let oc = current_counts(OC_HW_CENTIAMPS);
    let ov = udc_counts_at_volts(OV_HW_VOLTS).min(ADC_FULL_COUNTS) as u16;
    let (mut dac_a, mut dac_b) = Dac::<Blocking>::new_internal(p.dac_current).split();
    dac_a.set(Value::Bit12Right(oc));
    dac_b.set(Value::Bit12Right(oc));
    dac_a.enable();
    dac_b.enable();
    let mut dac_v = Dac::<Blocking>::new_internal(p.dac_voltage);
    dac_v.ch1().set(Value::Bit12Right(ov));
    dac_v.ch1().enable();

    let config = |dac| Config {
        hysteresis: Hysteresis::Hyst20M,
        output_polarity: OutputPolarity::NotInverted,
        inverting_input: dac,
        ..Config::default()
    };
    // On COMP1/COMP2, DACA is DAC3 CH1/CH2; on COMP3, DACB is DAC1 CH1 (RM0440, COMP
    // inverting-input table).
    let mut c1 = Comp::new(p.comp_ia, ia, Irqs, config(InvertingInput::Dac1));
    let mut c2 = Comp::new(p.comp_ib, ib, Irqs, config(InvertingInput::Dac1));
    let mut c3 = Comp::new(p.comp_udc, udc, Irqs, config(InvertingInput::Dac2));
    c1.enable();
    c2.enable();
    c3.enable();
    defmt::info!(
        "hw trips: OC_HW {} counts ({} cA), OV_HW {} counts ({} V)",
        oc,
        OC_HW_CENTIAMPS,
        ov,
        OV_HW_VOLTS
    );
    HwProtection {
        _comps: (c1, c2, c3),
        _dac_current: (dac_a, dac_b),
        _dac_voltage: dac_v,
    }
}

/// Which hardware causes are present now (comparator outputs).
pub fn active() -> [(HwBreak, bool); 2] {
    let oc = pac::COMP1.csr().read().value() || pac::COMP2.csr().read().value();
    let ov = pac::COMP3.csr().read().value();
    [(HwBreak::Overcurrent, oc), (HwBreak::Overvoltage, ov)]
}
