//! Hardware trips, configured from the drive core's comparator table
//! (`firmware_drive::comparators`, the board profile of `DriveConfig::board`): on the
//! B-G431B-ESC1, COMP1/COMP2/COMP4 compare the phase-current signals of U, V, W with DAC3
//! CH1, DAC1 CH2 and DAC3 CH2 (`OC_HW`, positive half-wave: each phase pin reaches only one
//! comparator input, see the table's docs), COMP3 compares the DC-link divider with DAC1
//! CH1 (`OV_HW`). Before the break is armed, the comparators the table marks `zero_trim`
//! are trimmed at 0 A ([`init`] runs `firmware_drive::comparator_trim`'s search: the core
//! decides each probe, this module writes the DACs and reads the outputs). Their outputs are ORed into TIM1's break input, which clears MOE within a
//! few tens of nanoseconds without software; automatic output enable is off, so the break
//! latches until the core acknowledges the fault and a new RUN sets MOE again.
//!
//! COMP1/2/4 are blanked by TIM1's OC5 around the switching edges (review D10,
//! `firmware_drive::blanking`; the window is the core's, per period), COMP3 is not.
//!
//! The thresholds are the core's decision (`DriveCore::comparator_dacs`: the program's
//! `I>>`/`U>>` or the board's defaults, in ADC counts of the same signals); this module
//! only writes them to the DACs, at start-up and whenever the core's values change (a
//! download).

use embassy_stm32::comp::{self, Comp, Config, Hysteresis, InvertingInput, OutputPolarity};
use embassy_stm32::dac::{Dac, DacChannel as Channel, Value};
use embassy_stm32::mode::Blocking;
use embassy_stm32::peripherals::{COMP1, COMP2, COMP3, COMP4, PA0, PA1, PA7};
use embassy_stm32::{bind_interrupts, pac, Peri};
use firmware_drive::comparator_trim::{ComparatorTrim, TrimFailed, TrimmedZeros, SETTLE_US};
use firmware_drive::comparators::{BoardProfile, ComparatorSpec, DacChannel, DacValues};
use firmware_drive::power_port::ComparatorLevels;

use crate::pins::Protection;

bind_interrupts!(struct Irqs {
    COMP1_2_3 => comp::InterruptHandler<COMP1>, comp::InterruptHandler<COMP2>, comp::InterruptHandler<COMP3>;
    COMP4 => comp::InterruptHandler<COMP4>;
});

/// The running comparators and threshold DACs.
pub struct HwProtection {
    _comps: (
        Comp<'static, COMP1>,
        Comp<'static, COMP2>,
        Comp<'static, COMP3>,
        Comp<'static, COMP4>,
    ),
    _dac_current: (Channel<'static, Blocking>, Channel<'static, Blocking>),
    _dac_voltage: Dac<'static, Blocking>,
}

/// The table entry of comparator `comp` (a profile without it is a build mistake; its
/// input pins are checked against RM0440 by the core's unit tests).
fn spec(board: &BoardProfile, comp: u8) -> ComparatorSpec {
    let Some(s) = board.comparators.iter().find(|s| s.comp == comp) else {
        super::fault::fatal("board profile lacks a comparator");
    };
    *s
}

/// COMPx configuration from its table entry: inverting input (INMSEL 0b100 = DACA,
/// 0b101 = DACB), hysteresis, output polarity from the trip direction.
fn config(s: &ComparatorSpec) -> Config {
    let inverting_input = match s.inmsel() {
        Some(0b100) => InvertingInput::Dac1,
        Some(0b101) => InvertingInput::Dac2,
        _ => super::fault::fatal("a comparator's DAC cannot reach it"),
    };
    let hysteresis = match s.hysteresis_mv {
        0 => Hysteresis::None,
        10 => Hysteresis::Hyst10M,
        20 => Hysteresis::Hyst20M,
        _ => super::fault::fatal(super::fault::UNBINDABLE_PROFILE),
    };
    Config {
        hysteresis,
        output_polarity: if s.inverted() {
            OutputPolarity::Inverted
        } else {
            OutputPolarity::NotInverted
        },
        inverting_input,
        ..Config::default()
    }
}

/// Writes the DAC channels the core's values name (12-bit right-aligned).
pub fn write_dacs(v: DacValues) {
    for ch in DacChannel::ALL {
        let Some(counts) = v.get(ch) else { continue };
        let (dac, idx) = match ch {
            DacChannel::Dac1Ch1 => (pac::DAC1, 0),
            DacChannel::Dac1Ch2 => (pac::DAC1, 1),
            DacChannel::Dac3Ch1 => (pac::DAC3, 0),
            DacChannel::Dac3Ch2 => (pac::DAC3, 1),
        };
        dac.dhr12r(idx).write(|w| w.set_dhr(counts));
    }
}

/// Sets the thresholds `dacs`, enables the comparators of `board` (not yet routed to the
/// break input: [`super::power_stage::arm_break`] does that once TIM1 runs), trims those
/// the table marks at 0 A (the gates are still off) and then sets their blanking. The
/// trim's result goes to the core, whose thresholds then count from it.
pub fn init(
    p: Protection,
    board: &'static BoardProfile,
    pins: (Peri<'_, PA1>, Peri<'_, PA7>, Peri<'_, PA0>),
    dacs: DacValues,
) -> (HwProtection, Result<TrimmedZeros, TrimFailed>) {
    let (ia, ib, udc) = pins;
    let ic = p.current_c;
    let (mut dac_a, mut dac_b) = Dac::<Blocking>::new_internal(p.dac_current).split();
    let mut dac_v = Dac::<Blocking>::new_internal(p.dac_voltage);
    dac_a.set(Value::Bit12Right(
        dacs.get(DacChannel::Dac3Ch1).unwrap_or(4095),
    ));
    dac_b.set(Value::Bit12Right(
        dacs.get(DacChannel::Dac3Ch2).unwrap_or(4095),
    ));
    dac_v.ch1().set(Value::Bit12Right(
        dacs.get(DacChannel::Dac1Ch1).unwrap_or(4095),
    ));
    dac_v.ch2().set(Value::Bit12Right(
        dacs.get(DacChannel::Dac1Ch2).unwrap_or(4095),
    ));
    dac_a.enable();
    dac_b.enable();
    dac_v.ch1().enable();
    // Internal mode (embassy `new_internal`: MODE 011): PA5, the ESC1's OPAMP2 VINM0, is
    // not driven.
    dac_v.ch2().enable();

    let mut c1 = Comp::new(p.comp_ia, ia, Irqs, config(&spec(board, 1)));
    let mut c2 = Comp::new(p.comp_ib, ib, Irqs, config(&spec(board, 2)));
    let mut c3 = Comp::new(p.comp_udc, udc, Irqs, config(&spec(board, 3)));
    let mut c4 = Comp::new(p.comp_ic, ic, Irqs, config(&spec(board, 4)));
    c1.enable();
    c2.enable();
    c3.enable();
    c4.enable();
    // The trim, unblanked: the core's search, one probe per DAC write.
    let mut trim = ComparatorTrim::new(board);
    while let Some(probe) = trim.probe() {
        write_dacs(probe);
        embassy_time::block_for(embassy_time::Duration::from_micros(SETTLE_US));
        trim.observe(levels());
    }
    let trimmed = trim.result();
    write_dacs(dacs);
    // BLANKSEL from the table (embassy's `BlankingSource` stops at code 3; COMP4's
    // TIM1_OC5 is 100). TIM1 does not run yet and the break is not armed: no window and
    // no trip depend on it before this write.
    for (regs, n) in [
        (pac::COMP1, 1),
        (pac::COMP2, 2),
        (pac::COMP3, 3),
        (pac::COMP4, 4),
    ] {
        let Some(code) = spec(board, n).blanksel() else {
            super::fault::fatal(super::fault::UNBINDABLE_PROFILE);
        };
        regs.csr()
            .modify(|w| w.set_blanksel(pac::comp::vals::Blanking::from_bits(code)));
    }
    (
        HwProtection {
            _comps: (c1, c2, c3, c4),
            _dac_current: (dac_a, dac_b),
            _dac_voltage: dac_v,
        },
        trimmed,
    )
}

/// TIM1 break-input comparator indices (AF2.BK2CMPxE since issue 29: break 2; 0-based) of the profile.
pub fn break_comparators(board: &BoardProfile) -> heapless::Vec<usize, 7> {
    board
        .comparators
        .iter()
        .map(|s| usize::from(s.comp.saturating_sub(1)))
        .collect()
}

/// The comparator outputs now (COMPx_CSR.VALUE, after polarity), index = COMPx - 1.
pub fn levels() -> ComparatorLevels {
    let mut l = ComparatorLevels::default();
    for (out, regs) in
        l.0.iter_mut()
            .zip([pac::COMP1, pac::COMP2, pac::COMP3, pac::COMP4])
    {
        *out = regs.csr().read().value();
    }
    l
}
