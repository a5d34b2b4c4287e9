//! TIM1 as the three-phase power stage: centre-aligned complementary PWM on CH1-3/CH1N-3N,
//! hardware dead time, main output enable (MOE) as the single on/off switch, the break input
//! wired to the comparators (see `hw_protection`), and CH4 as the ADC trigger.
//!
//! Off state: MOE = 0 with OSSI = 1 and OIS = OISN = 0 drives all six outputs to their
//! inactive (low) level, so "off" is the same whether software cleared MOE, the break input
//! did, or the timer never started. Register-level programming goes through the PAC because
//! embassy-stm32 0.6's `ComplementaryPwm` rounds the centre-aligned period itself and takes
//! the dead time as raw ticks; it is used only to claim the pins and clock the timer.

use embassy_stm32::gpio::{OutputType, Pull, Speed};
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::{Bkp, Cms, Mms2, Ocm, Ossi, Ossr};
use embassy_stm32::peripherals::TIM1;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::complementary_pwm::{ComplementaryPwm, ComplementaryPwmPin};
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, PwmPinConfig};
use firmware_drive::timing::{decode_dtg, PwmTiming};

use crate::pins::PowerStage;

/// The timer, owned for the life of the firmware (dropping it would release the pins).
pub struct Tim1Pwm {
    _pwm: ComplementaryPwm<'static, TIM1>,
}

/// Fewest CK_INT periods of dead time the power stage accepts: `min_dead_time_ns` rounded up.
pub fn min_dead_time_counts(timer_clock_hz: u32, min_dead_time_ns: u32) -> u32 {
    let counts = (u64::from(min_dead_time_ns) * u64::from(timer_clock_hz)).div_ceil(1_000_000_000);
    u32::try_from(counts).unwrap_or(u32::MAX)
}

/// Claims the six pins (pulled down while the timer takes them over), clocks TIM1 and leaves
/// it counting with MOE = 0, all compares at 0 and the update interrupt enabled.
pub fn init(p: PowerStage, timing: PwmTiming, min_dead_counts: u32) -> Tim1Pwm {
    let cfg = PwmPinConfig {
        output_type: OutputType::PushPull,
        speed: Speed::VeryHigh,
        pull: Pull::Down,
    };
    let pwm = ComplementaryPwm::new(
        p.tim,
        Some(PwmPin::new_with_config(p.u_high, cfg)),
        Some(ComplementaryPwmPin::new_with_config(p.u_low, cfg)),
        Some(PwmPin::new_with_config(p.v_high, cfg)),
        Some(ComplementaryPwmPin::new_with_config(p.v_low, cfg)),
        Some(PwmPin::new_with_config(p.w_high, cfg)),
        Some(ComplementaryPwmPin::new_with_config(p.w_low, cfg)),
        None,
        None,
        Hertz(u32::from(firmware_drive::vm::PWF_MIN_HZ)),
        CountingMode::CenterAlignedDownInterrupts,
    );
    // `ComplementaryPwm::new` sets MOE; take it back before anything else.
    outputs_off();
    let t = pac::TIM1;
    t.cr1().modify(|w| w.set_cen(false));
    t.bdtr().modify(|w| {
        w.set_ossi(Ossi::IDLE_LEVEL);
        w.set_ossr(Ossr::IDLE_LEVEL);
        w.set_aoe(false);
        w.set_bke(0, false);
    });
    t.cr2().modify(|w| {
        for ch in 0..3 {
            w.set_ois(ch, false);
            w.set_oisn(ch, false);
        }
        // OC4REF (CH4 in PWM mode 2 just below the top) starts the injected ADC sequence
        // while the low-side switches conduct.
        w.set_mms2(Mms2::COMPARE_OC4);
    });
    for ch in 0..4 {
        t.ccmr_output(ch / 2).modify(|w| {
            w.set_ocm(
                ch % 2,
                if ch < 3 {
                    Ocm::PWM_MODE1
                } else {
                    Ocm::PWM_MODE2
                },
            );
            w.set_ocpe(ch % 2, true);
        });
    }
    t.ccer().modify(|w| {
        for ch in 0..3 {
            w.set_cce(ch, true);
            w.set_ccne(ch, true);
            w.set_ccp(ch, false);
            w.set_ccnp(ch, false);
        }
        // CH4 drives no pin: it only times the ADC trigger.
        w.set_cce(3, false);
    });
    t.cr1().modify(|w| {
        w.set_cms(Cms::CENTER_ALIGNED1);
        w.set_arpe(true);
    });
    // One update per PWM period, at the valley (counter = 0).
    t.rcr().write(|w| w.set_rep(1));
    apply_timing(&timing, min_dead_counts);
    for ch in 0..3 {
        t.ccr(ch).write(|w| w.set_ccr(0));
    }
    t.egr().write(|w| w.set_ug(true));
    t.sr().write(|w| w.0 = 0);
    t.dier().modify(|w| w.set_uie(true));
    t.cr1().modify(|w| w.set_cen(true));
    Tim1Pwm { _pwm: pwm }
}

/// Arms break input 1 (active high, fed by the comparators) with automatic output enable
/// off: a break clears MOE in hardware and it stays cleared until software sets it again.
pub fn arm_break(comparators: &[usize]) {
    let t = pac::TIM1;
    t.af1().modify(|w| {
        // Only the comparators: the BKIN pin (reset default on) is not wired.
        w.set_bkine(false);
        for &c in comparators {
            w.set_bkcmpe(c, true);
        }
    });
    t.bdtr().modify(|w| {
        w.set_bkp(0, Bkp::ACTIVE_HIGH);
        w.set_aoe(false);
        w.set_bke(0, true);
    });
    t.sr().modify(|w| w.set_bif(0, false));
    t.dier().modify(|w| w.set_bie(true));
}

/// Programs PSC, ARR, CH4's trigger point and the dead time for `timing`, after checking
/// that the dead time the DTG code really gives is at least the power stage's minimum.
/// A violation is a bug in the timing computation: it panics, and the panic path turns the
/// outputs off.
pub fn apply_timing(timing: &PwmTiming, min_dead_counts: u32) {
    let realised = u32::from(decode_dtg(timing.dtg));
    defmt::assert!(
        realised >= min_dead_counts && realised == u32::from(timing.dead_time_counts),
        "dead time {} counts (DTG {=u8:#x}) below the minimum {}",
        realised,
        timing.dtg,
        min_dead_counts
    );
    let t = pac::TIM1;
    t.psc().write_value(timing.psc);
    t.arr().write(|w| w.set_arr(timing.arr));
    t.ccr(3).write(|w| w.set_ccr(timing.arr.saturating_sub(1)));
    t.bdtr().modify(|w| w.set_dtg(timing.dtg));
}

/// Writes the three compare values (preloaded: they take effect at the next valley).
#[inline(always)]
pub fn write_duties(duty: [u16; 3]) {
    let t = pac::TIM1;
    for (ch, d) in duty.into_iter().enumerate() {
        t.ccr(ch).write(|w| w.set_ccr(d));
    }
}

/// Which legs switch (CCxE and CCxNE of CH1-3 together); the core turns a sine leg off
/// below `fmn` while a direct leg keeps switching. A leg that is off has both outputs
/// disabled: not driven by the timer, held low by the pins' pull-downs and the gate
/// driver's, so both of its switches are open. Written only when it changes.
#[inline(always)]
pub fn set_legs(on: [bool; 3]) {
    let t = pac::TIM1;
    let ccer = t.ccer().read();
    if (0..3)
        .zip(on)
        .any(|(ch, o)| ccer.cce(ch) != o || ccer.ccne(ch) != o)
    {
        t.ccer().modify(|w| {
            for (ch, o) in (0..3).zip(on) {
                w.set_cce(ch, o);
                w.set_ccne(ch, o);
            }
        });
    }
}

/// MOE on, unless a break is pending: the hardware refuses MOE while the break input is
/// active, and a break that has already ended must still reach the core (break interrupt)
/// before the outputs may come back.
#[inline(always)]
pub fn outputs_on() {
    let t = pac::TIM1;
    if !t.sr().read().bif(0) {
        t.bdtr().modify(|w| w.set_moe(true));
    }
}

/// MOE off: all six outputs to their inactive level after the dead time.
#[inline(always)]
pub fn outputs_off() {
    pac::TIM1.bdtr().modify(|w| w.set_moe(false));
}

/// Whether the update flag is set; clears it.
#[inline(always)]
pub fn take_update() -> bool {
    let t = pac::TIM1;
    let set = t.sr().read().uif();
    if set {
        t.sr().modify(|w| w.set_uif(false));
    }
    set
}

/// Whether the break flag is set; clears it and masks the break interrupt (the flag would
/// set again at once while the comparator stays high) until [`rearm_break_irq`].
pub fn take_break() -> bool {
    let t = pac::TIM1;
    let set = t.sr().read().bif(0);
    if set {
        t.dier().modify(|w| w.set_bie(false));
        t.sr().modify(|w| w.set_bif(0, false));
    }
    set
}

/// Unmasks the break interrupt again once no comparator is high.
pub fn rearm_break_irq() {
    let t = pac::TIM1;
    if !t.dier().read().bie() {
        t.sr().modify(|w| w.set_bif(0, false));
        t.dier().modify(|w| w.set_bie(true));
    }
}

/// The panic/HardFault path: MOE off through the PAC (a no-op if TIM1 was never clocked).
pub fn force_off() {
    outputs_off();
}
