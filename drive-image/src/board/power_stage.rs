//! TIM1 as the three-phase power stage: centre-aligned complementary PWM on CH1-3/CH1N-3N,
//! hardware dead time, main output enable (MOE) as the single on/off switch, the break input
//! wired to the comparators (see `hw_protection`), and CH4 as the ADC trigger.
//!
//! Off state: MOE = 0 with OSSI = 1 and OIS = OISN = 0 drives all six outputs to their
//! inactive (low) level, so "off" is the same whether software cleared MOE, the break input
//! did, or the timer never started. Register-level programming goes through the PAC because
//! embassy-stm32 0.6's `ComplementaryPwm` rounds the centre-aligned period itself and takes
//! the dead time as raw ticks. Embassy only clocks and resets the timer (`low_level::Timer`)
//! and claims the pins (`PwmPin`/`ComplementaryPwmPin`); `ComplementaryPwm::new` is not used:
//! it computed a period, counting mode and compare modes that [`init`] overwrote at once
//! (~0.5 KiB of start-up code, docs/size.md), and set MOE.

use core::sync::atomic::{AtomicU32, Ordering};
use embassy_stm32::gpio::{Level, Output};
use embassy_stm32::gpio::{OutputType, Pull, Speed};
use embassy_stm32::pac;
use embassy_stm32::pac::timer::regs::{BdtrAdv, SrAdv};
use embassy_stm32::pac::timer::vals::{Bkp, Cms, Mms2, Ocm, Ossi, Ossr};
use embassy_stm32::peripherals::TIM1;
use embassy_stm32::timer::complementary_pwm::ComplementaryPwmPin;
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::timer::simple_pwm::{PwmPin, PwmPinConfig};
use embassy_stm32::timer::{Ch1, Ch2, Ch3};
use firmware_drive::bodies::{BreakPort, PwmPort};
use firmware_drive::measure::AdcSample;
use firmware_drive::power_port::PowerPort;
use firmware_drive::power_port::{BreakSources, ComparatorLevels};
use firmware_drive::timing::PwmTiming;

use crate::pins::PowerStage;

/// The timer, owned for the life of the firmware (dropping it would release the pins).
pub struct Tim1Pwm {
    _tim: Timer<'static, TIM1>,
    _high: (
        PwmPin<'static, TIM1, Ch1>,
        PwmPin<'static, TIM1, Ch2>,
        PwmPin<'static, TIM1, Ch3>,
    ),
    _low: (
        ComplementaryPwmPin<'static, TIM1, Ch1>,
        ComplementaryPwmPin<'static, TIM1, Ch2>,
        ComplementaryPwmPin<'static, TIM1, Ch3>,
    ),
    /// `STO_IN` (PA15, TIM1_BKIN): held so that nothing else takes the pin; configured
    /// by [`arm_sto_input`].
    _sto_in: embassy_stm32::Peri<'static, embassy_stm32::peripherals::PA15>,
}

/// Claims the six pins (pulled down while the timer takes them over), clocks TIM1 and leaves
/// it counting with MOE = 0, all compares at 0 and the update interrupt enabled.
pub fn init(p: PowerStage, timing: PwmTiming) -> Tim1Pwm {
    let cfg = PwmPinConfig {
        output_type: OutputType::PushPull,
        speed: Speed::VeryHigh,
        pull: Pull::Down,
    };
    // TIM1's clock on and the timer reset (RCC APB2ENR/APB2RSTR): every register below
    // starts from its reset value, MOE = 0 and the counter stopped.
    let tim = Timer::new(p.tim);
    // The pins go to TIM1's alternate function while its outputs are disabled (CCxE = 0,
    // MOE = 0: the pull-downs hold the gate driver's inputs low).
    let high = (
        PwmPin::new_with_config(p.u_high, cfg),
        PwmPin::new_with_config(p.v_high, cfg),
        PwmPin::new_with_config(p.w_high, cfg),
    );
    let low = (
        ComplementaryPwmPin::new_with_config(p.u_low, cfg),
        ComplementaryPwmPin::new_with_config(p.v_low, cfg),
        ComplementaryPwmPin::new_with_config(p.w_low, cfg),
    );
    // MOE is 0 after the reset; cleared again so that this function owns the output
    // enable's start value (start-up: the configuration is not recorded yet, so this one
    // clear is a read-modify-write).
    let t = pac::TIM1;
    t.bdtr().modify(|w| w.set_moe(false));
    // A halted core (breakpoint, probe-rs halt) stops TIM1's counter, and a
    // stopped advanced timer disables its outputs as if MOE were cleared (RM0440 "Debug
    // mode"): no frozen duty cycle keeps driving DC into two windings.
    pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));
    // The dead time (BDTR.DTG) is preloaded and changes at the update event,
    // with PSC and ARR, never in mid-period (DTR2.DTPE, RM0440 29.4.28).
    t.dtr2().modify(|w| w.set_dtpe(true));
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
    // OC5 is the comparators' blanking window (COMP BLANKSEL = TIM1_OC5), PWM
    // mode 1 (active while CNT < CCR5: around the valley), preloaded like the compares;
    // CCR5 per period from the core (`PeriodAction::blanking`), 0 = no window. GC5Cx
    // stay 0: OC5 is not ANDed into the phase outputs.
    t.ccmr3().modify(|w| {
        w.set_ocm(0, Ocm::PWM_MODE1);
        w.set_ocpe(0, true);
    });
    t.ccr5().write(|w| w.set_ccr(0));
    t.ccer().modify(|w| {
        for ch in 0..3 {
            w.set_cce(ch, true);
            w.set_ccne(ch, true);
            w.set_ccp(ch, false);
            w.set_ccnp(ch, false);
        }
        // CH4 drives no pin: it only times the ADC trigger.
        w.set_cce(3, false);
        // OC5 is internal (no pin): enabled, active high, to the comparators.
        w.set_cce(4, true);
        w.set_ccp(4, false);
    });
    t.cr1().modify(|w| {
        w.set_cms(Cms::CENTER_ALIGNED1);
        w.set_arpe(true);
    });
    // One update per PWM period, at the valley (counter = 0).
    t.rcr().write(|w| w.set_rep(1));
    record_bdtr();
    apply_timing(&timing);
    for ch in 0..3 {
        t.ccr(ch).write(|w| w.set_ccr(0));
    }
    t.egr().write(|w| w.set_ug(true));
    t.sr().write_value(SrAdv(0));
    t.dier().modify(|w| w.set_uie(true));
    t.cr1().modify(|w| w.set_cen(true));
    Tim1Pwm {
        _tim: tim,
        _high: high,
        _low: low,
        _sto_in: p.sto_in,
    }
}

/// Arms break input 2 (active high, fed by the comparators; its BKIN2 pin, PA11, is the
/// ESC1's CAN_RX and not used) with automatic output enable off: a break clears MOE in
/// hardware and it stays cleared until software sets it again. Break 1 is `STO_IN`'s
/// ([`arm_sto_input`]): the only TIM1 break pin the ESC1 leaves free is a BKIN pin
/// (`pins`). MOE is 0 here (`init`), so the read-modify-write of BDTR cannot
/// set it.
pub fn arm_break(comparators: &[usize]) {
    let t = pac::TIM1;
    t.af2().modify(|w| {
        // Only the comparators: the BKIN2 pin (reset default on) is not wired.
        w.set_bk2ine(false);
        for &c in comparators {
            w.set_bk2cmpe(c, true);
        }
    });
    t.bdtr().modify(|w| {
        w.set_moe(false);
        w.set_bkp(1, Bkp::ACTIVE_HIGH);
        w.set_aoe(false);
        w.set_bke(1, true);
    });
    clear_flags(break_flags());
    t.dier().modify(|w| w.set_bie(true));
}

/// safety.md 6 (NOT RATED): `STO_IN` on PA15 as TIM1_BKIN (AF9; not BKIN2 as safety.md
/// says: the G431CBU6's only BKIN2 pin is PA11, the ESC1's CAN_RX), with a
/// pull-down so that a broken wire requests STO; break 1 armed active low (its only
/// source: the comparators are on break 2) with automatic output enable off: `STO_IN` low
/// clears MOE in hardware, with no software, and sets BIF, which stays set until the core
/// has seen it (`DriveApp::break_interrupt`); only the drive software sets MOE again (after ACK and a
/// new RUN). No filter (BKF = 0): a pulse of one timer clock (5.9 ns) breaks. No policy
/// here: the core latches the break and reads the level every tick
/// ([`sto_input_low`]). The pin stays reserved by `pins` (its `Peri` is kept by the
/// caller); MOE is 0 here (`init`). Break 1 also carries the system break (SBIF,
/// [`route_system_faults_to_break`]), which needs BKE = 1.
pub fn arm_sto_input() {
    let a = pac::GPIOA;
    a.pupdr()
        .modify(|w| w.set_pupdr(STO_PIN, pac::gpio::vals::Pupdr::PULL_DOWN));
    a.afr(STO_PIN / 8)
        .modify(|w| w.set_afr(STO_PIN % 8, STO_AF));
    a.moder()
        .modify(|w| w.set_moder(STO_PIN, pac::gpio::vals::Moder::ALTERNATE));
    let t = pac::TIM1;
    t.af1().modify(|w| {
        // The BKIN pin, not inverted; no comparator on break 1.
        w.set_bkine(true);
        w.set_bkinp(pac::timer::vals::Bkinp::NOT_INVERTED);
    });
    t.bdtr().modify(|w| {
        w.set_moe(false);
        w.set_bkp(0, Bkp::ACTIVE_LOW);
        w.set_aoe(false);
        w.set_bke(0, true);
    });
    clear_flags(break_flags());
}

/// PA15 (`STO_IN`).
const STO_PIN: usize = 15;
/// PA15's alternate function TIM1_BKIN.
const STO_AF: u8 = 9;

/// `STO_IN` is low (STO requested), as its input data register reads (the pin is in
/// alternate-function mode; IDR still reads its level).
pub fn sto_input_low() -> bool {
    pac::GPIOA.idr().read().idr(STO_PIN) == pac::gpio::vals::Idr::LOW
}

/// Routes the Cortex-M4 LOCKUP, the PVD, SRAM parity errors and flash double
/// ECC errors to TIM1's system break (SYSCFG_CFGR2 CLL/PVDL/SPL/ECCL, RM0440 Table
/// "TIMx break interconnect"): a stack overflow that locks the core up (flip-link puts the
/// stack at the bottom of RAM) opens every switch in hardware, without software. The PVD
/// is enabled first at 2.8 V falling (PWR_CR2 PLS = 101): a sagging 3.3 V supply opens the
/// switches before the logic misbehaves. The bits are write-once until reset.
pub fn route_system_faults_to_break() {
    pac::PWR.cr2().modify(|w| {
        w.set_pls(0b101);
        w.set_pvde(true);
    });
    pac::SYSCFG.cfgr2().modify(|w| {
        w.set_cll(true);
        w.set_pvdl(true);
        w.set_spl(true);
        w.set_eccl(true);
    });
}

/// Programs PSC, ARR, CH4's trigger point and the dead time for `timing` (all preloaded:
/// they take effect together at the next update). The dead-time floor is the core's
/// boot check (`PwmTiming::dead_time_meets`: below it the core latches `BOOT` and never
/// sets MOE). Called only with MOE = 0 ([`PowerPort::set_timing`]'s contract): BDTR is
/// written whole with MOE = 0 and the new DTG.
fn apply_timing(timing: &PwmTiming) {
    let t = pac::TIM1;
    t.psc().write_value(timing.psc);
    t.arr().write(|w| w.set_arr(timing.arr));
    t.ccr(3).write(|w| w.set_ccr(timing.arr.saturating_sub(1)));
    let mut v = bdtr_config();
    v.set_dtg(timing.dtg);
    BDTR_CONFIG.store(v.0, Ordering::Relaxed);
    t.bdtr().write_value(v);
}

/// TIM1_BDTR as the start-up configured it, with MOE = 0. After start-up BDTR
/// is never read: every write is this word whole, with MOE set ([`Tim1Port::outputs_on`])
/// or not, and a new DTG ([`apply_timing`]) is written into it. A read-modify-write
/// straddling a break pulse would write back the MOE = 1 it read after the break cleared
/// it (RM0440: software can set MOE again once the break input is inactive).
static BDTR_CONFIG: AtomicU32 = AtomicU32::new(0);

fn bdtr_config() -> BdtrAdv {
    BdtrAdv(BDTR_CONFIG.load(Ordering::Relaxed))
}

/// Records BDTR as the start-up code left it (MOE cleared). Start-up only: called before
/// the first timing write and, by the board, once every break is armed and before the PWM
/// interrupt runs ([`super::pwm_isr::enable`]), so that any start-up change of BDTR is in
/// the word the run writes.
pub fn record_bdtr() {
    let mut v = pac::TIM1.bdtr().read();
    v.set_moe(false);
    BDTR_CONFIG.store(v.0, Ordering::Relaxed);
}

/// The break flags: both break inputs (BIF: `STO_IN`, B2IF: the comparators) and the
/// system break (SBIF).
fn break_flags() -> SrAdv {
    let mut m = SrAdv(0);
    m.set_bif(0, true);
    m.set_bif(1, true);
    m.set_sbif(true);
    m
}

/// Clears the flags of `mask` and no other (TIM SR flags are rc_w0: writing 1 leaves a
/// flag as it is, a read-modify-write would clear flags set in between).
#[inline(always)]
fn clear_flags(mask: SrAdv) {
    pac::TIM1.sr().write_value(SrAdv(!mask.0));
}

/// TIM1, the ADC and the brake chopper's gate as the PWM interrupt's [`PwmPort`]: one
/// register access per method, no decisions (the order is `DriveApp::pwm_interrupt`'s and
/// `PeriodAction::apply`'s).
pub struct Tim1Port<'a> {
    /// `None` on a board without a chopper (the pin is not touched).
    pub brake: &'a mut Option<Output<'static>>,
}

impl PwmPort for Tim1Port<'_> {
    #[inline(always)]
    fn take_update(&mut self) -> bool {
        take_update()
    }

    #[inline(always)]
    fn sample(&mut self) -> AdcSample {
        super::analog::read()
    }
}

impl PowerPort for Tim1Port<'_> {
    #[inline(always)]
    fn outputs_off(&mut self) {
        outputs_off();
    }

    #[inline(always)]
    fn break_pending(&self) -> bool {
        pac::TIM1.sr().read().0 & break_flags().0 != 0
    }

    fn set_timing(&mut self, t: &PwmTiming) {
        apply_timing(t);
    }

    #[inline(always)]
    fn set_compares(&mut self, ccr: [u16; 3]) {
        // Written out per channel, as below: a loop stays a loop at opt-level "s", with the
        // register array's index check in it (every PWM period: docs/size.md).
        let t = pac::TIM1;
        let [c1, c2, c3] = ccr;
        t.ccr(0).write(|w| w.set_ccr(c1));
        t.ccr(1).write(|w| w.set_ccr(c2));
        t.ccr(2).write(|w| w.set_ccr(c3));
    }

    /// CCR5 alone (GC5C1-3 written 0: OC5 is not grouped with the outputs).
    #[inline(always)]
    fn set_blanking(&mut self, ccr5: u16) {
        pac::TIM1.ccr5().write(|w| w.set_ccr(ccr5));
    }

    /// CCxE and CCxNE of CH1-3 together. A leg that is off has both outputs disabled:
    /// with OSSR = 1 they sit at their inactive (low) level, so both switches are open.
    #[inline(always)]
    fn set_legs(&mut self, on: [bool; 3]) {
        let [on1, on2, on3] = on;
        pac::TIM1.ccer().modify(|w| {
            w.set_cce(0, on1);
            w.set_ccne(0, on1);
            w.set_cce(1, on2);
            w.set_ccne(1, on2);
            w.set_cce(2, on3);
            w.set_ccne(2, on3);
        });
    }

    /// The hardware ignores it while the break input is active (RM0440 29.3.18). BDTR
    /// written whole.
    #[inline(always)]
    fn outputs_on(&mut self) {
        let mut v = bdtr_config();
        v.set_moe(true);
        pac::TIM1.bdtr().write_value(v);
    }

    #[inline(always)]
    fn set_brake(&mut self, on: bool) {
        if let Some(b) = self.brake.as_mut() {
            b.set_level(Level::from(on));
        }
    }
}

/// MOE off: all six outputs to their inactive level after the dead time. BDTR written
/// whole with the recorded configuration; before start-up recorded it (a panic
/// during start-up) that word is 0, which is MOE off as well.
#[inline(always)]
pub fn outputs_off() {
    pac::TIM1.bdtr().write_value(bdtr_config());
}

/// Whether the update flag is set; clears it (and only it).
#[inline(always)]
pub fn take_update() -> bool {
    let set = pac::TIM1.sr().read().uif();
    if set {
        let mut m = SrAdv(0);
        m.set_uif(true);
        clear_flags(m);
    }
    set
}

/// TIM1's break registers and the comparators as the break interrupt's [`BreakPort`]:
/// which flag stands for which source is [`arm_break`]'s and [`arm_sto_input`]'s wiring.
pub struct Tim1Break;

impl BreakPort for Tim1Break {
    #[inline(always)]
    fn break_flags(&mut self) -> BreakSources {
        let sr = pac::TIM1.sr().read();
        BreakSources {
            sto: sr.bif(0),
            comparator: sr.bif(1),
            system: sr.sbif(),
        }
    }

    #[inline(always)]
    fn mask_break_irq(&mut self) {
        pac::TIM1.dier().modify(|w| w.set_bie(false));
    }

    #[inline(always)]
    fn outputs_off(&mut self) {
        outputs_off();
    }

    #[inline(always)]
    fn comparator_levels(&mut self) -> ComparatorLevels {
        super::hw_protection::levels()
    }

    /// The flags of `seen` and no other: a flag that set in between (another source)
    /// stays for the next entry.
    #[inline(always)]
    fn clear_break_flags(&mut self, seen: BreakSources) {
        let mut m = SrAdv(0);
        m.set_bif(0, seen.sto);
        m.set_bif(1, seen.comparator);
        m.set_sbif(seen.system);
        clear_flags(m);
    }
}

/// Unmasks the break interrupt (the core's `BreakReport::rearm`) without clearing any
/// flag: a break that came while the interrupt was masked (a comparator during an STO)
/// is then reported, delayed, not lost.
pub fn rearm_break_irq() {
    pac::TIM1.dier().modify(|w| w.set_bie(true));
}

/// The panic/HardFault path: MOE off through the PAC (a no-op if TIM1 was never clocked).
pub fn force_off() {
    outputs_off();
}
