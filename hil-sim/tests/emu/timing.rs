//! The drive's time budget in cycles: no critical section and no PWM
//! interrupt may take longer than one PWM period at the highest switching frequency, or a
//! period is skipped. Measured by the emulator's cycle model (`g431-emu/src/cycles.rs`) on
//! the real image, through the motor example's download, start and run.

use g431_emu::cpu::Stretch;

use crate::common::{emu, ns, MOTOR_PLC, MOTOR_TOML};

/// One PWM period at the highest switching frequency `PWF` accepts (spec `program.md`:
/// 488..20000 Hz) at the 170 MHz core clock: 170e6 / 20e3.
const PWM_PERIOD_CYCLES: u64 = 8_500;

/// The PWM interrupt's own budget: a quarter of that period (`firmware-drive/docs/drive-core.md`,
/// "2125-cycle budget of the whole PWM interrupt"), so that the tasks keep 75 % of the core.
const PWM_ISR_BUDGET_CYCLES: u64 = PWM_PERIOD_CYCLES / 4;

/// FLASH_ACR with 4 wait states and both caches on, the prefetch off (RM0440 3.7.1): what
/// embassy leaves.
const ACR_4WS_CACHES: u32 = 4 | 1 << 9 | 1 << 10;

/// The longest PWM interrupt and PRIMASK section of the motor example's first 2.2 s after
/// the boot, with the image's FLASH_ACR or `acr` in its place, and their description.
fn measure(acr: Option<u32>) -> (Stretch, Stretch, String) {
    let mut sim = emu(MOTOR_PLC, MOTOR_TOML);
    // Past the boot (its one-off set-up is not a running critical section), then the
    // download (~0.24 s), RUN and a second of running.
    sim.run_until(ns(0.1), |_| {});
    let cpu = sim.drive_mut().cpu_mut();
    cpu.clear_timing_report();
    cpu.soc_mut().cycles.acr_override = acr;
    sim.run_until(ns(2.2), |_| {});
    let r = sim.drive().cpu().timing_report();
    let pwm = r.irq("TIM1_UP_TIM16").expect("the PWM interrupt ran");
    let acr_used = sim.drive().soc().flash_acr();
    let report = format!(
        "FLASH_ACR {acr_used:#x}: PWM interrupt: {} cycles ({} instructions); longest PRIMASK section: {} cycles ({} instructions) from {:#010x} at {:.4} s; BASEPRI: {} cycles",
        pwm.cycles,
        pwm.instructions,
        r.primask.cycles,
        r.primask.instructions,
        r.primask.pc,
        r.primask.at as f64 / 170e6,
        r.basepri.cycles
    );
    eprintln!("{report}");
    let mut sites: Vec<_> = r.primask_by_site.values().collect();
    sites.sort_by_key(|s| std::cmp::Reverse(s.cycles));
    for s in sites.iter().take(6) {
        eprintln!(
            "  PRIMASK from {:#010x}: {} cycles, {} instructions",
            s.pc, s.cycles, s.instructions
        );
    }
    assert!(pwm.cycles > 0 && r.primask.cycles > 0, "{report}");
    (pwm, r.primask, report)
}

#[test]
fn no_critical_section_or_pwm_interrupt_is_longer_than_a_pwm_period() {
    let (pwm, section, report) = measure(None);
    assert!(
        section.cycles <= PWM_PERIOD_CYCLES,
        "a critical section over one PWM period ({PWM_PERIOD_CYCLES} cycles at 20 kHz): {report}"
    );
    assert!(
        pwm.cycles <= PWM_ISR_BUDGET_CYCLES,
        "the PWM interrupt over its budget ({PWM_ISR_BUDGET_CYCLES} cycles): {report}"
    );
}

/// The same image with FLASH_ACR.PRFTEN cleared, as embassy leaves it (a what-if of the
/// cycle model: an earlier image set the prefetch): the PWM interrupt
/// and the sections are longer.
#[test]
#[ignore = "Emulated boards built from the boards' documents, not from the firmware's assumptions: a what-if figure (the image with PRFTEN cleared), not the image's behaviour"]
fn without_the_prefetch_the_sections_would_be_longer() {
    let (pwm_on, section_on, _) = measure(None);
    let (pwm_off, section_off, report) = measure(Some(ACR_4WS_CACHES));
    assert!(
        pwm_on.cycles < pwm_off.cycles && section_on.cycles < section_off.cycles,
        "{report}"
    );
}
