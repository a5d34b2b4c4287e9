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
//! COMP1/2/4 are blanked by TIM1's OC5 around the switching edges (
//! `firmware_drive::blanking`; the window is the core's, per period), COMP3 is not.
//!
//! The thresholds are the core's decision (`DriveCore::comparator_dacs`: the program's
//! `I>>`/`U>>` or the board's defaults, in ADC counts of the same signals); this module
//! only writes them to the DACs, at start-up and whenever the core's values change (a
//! download).
//!
//! Register level through the PAC (RM0440 "Digital-to-analog converter (DAC)",
//! "Comparator (COMP)"), with the values embassy-stm32 0.6's `Dac::new_internal` and
//! `Comp::new` wrote (~1.1 KiB of generic driver code, `docs/size.md`), except that the
//! comparators' NVIC lines (COMP1_2_3, COMP4) stay masked: `Comp::new` unmasked them for
//! its async edge waits, which the image never used (their EXTI lines stay masked, so they
//! never fired).

use embassy_stm32::pac::comp::vals::{Blanking, Hysteresis, Inm, Polarity};
use embassy_stm32::pac::dac::vals::Mode;
use embassy_stm32::peripherals::{COMP1, COMP2, COMP3, COMP4, DAC1, DAC3, PB0};
use embassy_stm32::{pac, Peri};
use firmware_drive::comparator_trim::{ComparatorTrim, TrimFailed, TrimmedZeros, SETTLE_US};
use firmware_drive::comparators::{BoardProfile, ComparatorSpec, DacChannel, DacValues};
use firmware_drive::power_port::ComparatorLevels;

use crate::pins::Protection;

/// The comparators, the threshold DACs and the comparators' input pins, owned so that
/// nothing else claims them; they run from [`init`] on.
pub struct HwProtection {
    _comps: (
        Peri<'static, COMP1>,
        Peri<'static, COMP2>,
        Peri<'static, COMP3>,
        Peri<'static, COMP4>,
    ),
    _dacs: (Peri<'static, DAC3>, Peri<'static, DAC1>),
    _pin_c: Peri<'static, PB0>,
}

/// The table entry of comparator `comp` (a profile without it is a build mistake; its
/// input pins are checked against RM0440 by the core's unit tests).
fn spec(board: &BoardProfile, comp: u8) -> ComparatorSpec {
    let Some(s) = board.comparators.iter().find(|s| s.comp == comp) else {
        super::fault::fatal("board profile lacks a comparator");
    };
    *s
}

/// COMPx_CSR from its table entry, enabled, not yet blanked: non-inverting input INP0 (the
/// pins [`init`] is given: PA1, PA7, PA0, PB0 are COMP1-4's INP0, RM0440 "COMP
/// non-inverting input"), inverting input (INMSEL 0b100 = DACA, 0b101 = DACB), hysteresis
/// (HYST: 10 mV steps), output polarity from the trip direction; the VREFINT scaler and
/// bridge off (no VREFINT input).
fn write_csr(regs: pac::comp::Comp, s: &ComparatorSpec) {
    let inmsel = match s.inmsel() {
        Some(code @ (0b100 | 0b101)) => Inm::from_bits(code),
        _ => super::fault::fatal("a comparator's DAC cannot reach it"),
    };
    let hyst = match s.hysteresis_mv {
        mv @ (0 | 10 | 20) => Hysteresis::from_bits(mv / 10),
        _ => super::fault::fatal(super::fault::UNBINDABLE_PROFILE),
    };
    regs.csr().modify(|w| {
        w.set_inpsel(false);
        w.set_inmsel(inmsel);
        w.set_hyst(hyst);
        w.set_polarity(if s.inverted() {
            Polarity::INVERTED
        } else {
            Polarity::NOT_INVERTED
        });
        w.set_blanksel(Blanking::NO_BLANKING);
        w.set_scalen(false);
        w.set_brgen(false);
        w.set_en(true);
    });
}

/// DAC `dac` reset and clocked, both channels in normal mode, internal output, buffer off
/// (MODE 011: PA5, the ESC1's OPAMP2 VINM0, is not driven), HFSEL for a 170 MHz AHB
/// (0b10: above 160 MHz, RM0440 "DAC_MCR"), then enabled.
fn dac_on(dac: pac::dac::Dac) {
    dac.mcr().modify(|w| {
        w.set_hfsel(0b10);
        w.set_mode(0, Mode::NORMAL_INT_BUFDIS);
        w.set_mode(1, Mode::NORMAL_INT_BUFDIS);
    });
    dac.cr().modify(|w| {
        w.set_en(0, true);
        w.set_en(1, true);
    });
}

/// Writes the DAC channels the core's values name (12-bit right-aligned).
pub fn write_dacs(v: DacValues) {
    for ch in DacChannel::ALL {
        if let Some(counts) = v.get(ch) {
            write_dac(ch, counts);
        }
    }
}

/// Writes `counts` to DAC channel `ch` (DHR12Rx).
fn write_dac(ch: DacChannel, counts: u16) {
    let (dac, idx) = match ch {
        DacChannel::Dac1Ch1 => (pac::DAC1, 0),
        DacChannel::Dac1Ch2 => (pac::DAC1, 1),
        DacChannel::Dac3Ch1 => (pac::DAC3, 0),
        DacChannel::Dac3Ch2 => (pac::DAC3, 1),
    };
    dac.dhr12r(idx).write(|w| w.set_dhr(counts));
}

/// Sets the thresholds `dacs`, enables the comparators of `board` (not yet routed to the
/// break input: [`super::power_stage::arm_break`] does that once TIM1 runs), trims those
/// the table marks at 0 A (the gates are still off) and then sets their blanking. The
/// trim's result goes to the core, whose thresholds then count from it.
pub fn init(
    p: Protection,
    board: &'static BoardProfile,
    dacs: DacValues,
) -> (HwProtection, Result<TrimmedZeros, TrimFailed>) {
    // DAC1 and DAC3 reset and clocked (AHB2), SYSCFG (the comparators' APB2 clock) on.
    pac::RCC.ahb2rstr().modify(|w| {
        w.set_dac1rst(true);
        w.set_dac3rst(true);
    });
    pac::RCC.ahb2enr().modify(|w| {
        w.set_dac1en(true);
        w.set_dac3en(true);
    });
    let _ = pac::RCC.ahb2enr().read();
    cortex_m::asm::dsb();
    pac::RCC.ahb2rstr().modify(|w| {
        w.set_dac1rst(false);
        w.set_dac3rst(false);
    });
    pac::RCC.apb2enr().modify(|w| w.set_syscfgen(true));
    dac_on(pac::DAC3);
    dac_on(pac::DAC1);
    // Before the trim, every channel the core does not name at full scale.
    for ch in DacChannel::ALL {
        write_dac(ch, dacs.get(ch).unwrap_or(4095));
    }
    super::analog_pins(&[
        (pac::GPIOA, 0),
        (pac::GPIOA, 1),
        (pac::GPIOA, 7),
        (pac::GPIOB, 0),
    ]);
    for (regs, n) in COMPS {
        write_csr(regs, &spec(board, n));
    }
    // The trim, unblanked: the core's search, one probe per DAC write.
    let mut trim = ComparatorTrim::new(board);
    while let Some(probe) = trim.probe() {
        write_dacs(probe);
        embassy_time::block_for(embassy_time::Duration::from_micros(SETTLE_US));
        trim.observe(levels());
    }
    let trimmed = trim.result();
    write_dacs(dacs);
    // BLANKSEL from the table (COMP4's TIM1_OC5 is 100). TIM1 does not run yet and the
    // break is not armed: no window and no trip depend on it before this write.
    for (regs, n) in COMPS {
        let Some(code) = spec(board, n).blanksel() else {
            super::fault::fatal(super::fault::UNBINDABLE_PROFILE);
        };
        regs.csr()
            .modify(|w| w.set_blanksel(Blanking::from_bits(code)));
    }
    (
        HwProtection {
            _comps: (p.comp_ia, p.comp_ib, p.comp_udc, p.comp_ic),
            _dacs: (p.dac_current, p.dac_voltage),
            _pin_c: p.current_c,
        },
        trimmed,
    )
}

/// COMP1-COMP4 with their numbers.
const COMPS: [(pac::comp::Comp, u8); 4] = [
    (pac::COMP1, 1),
    (pac::COMP2, 2),
    (pac::COMP3, 3),
    (pac::COMP4, 4),
];

/// TIM1 break-input comparator indices (AF2.BK2CMPxE break 2; 0-based) of the profile.
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
