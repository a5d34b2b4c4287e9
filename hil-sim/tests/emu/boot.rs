//! Both images boot on their boards.

use g431_emu::cpu::CpuEvent;
use g431_emu::soc::Diagnostic;
use g431_emu::time::{cycles_to_ns, HCLK_HZ};
use shared_protocol::link::message::DriveState;

use crate::common::{emu, ns, MOTOR_PLC};

/// RUN is left to the keys (typed after the test ends): the PLC stays in STOP.
const STAY_STOPPED: &str = "[[event]]\nat_s = 10.0\nkeys = \"A\"\n";

#[test]
fn both_images_boot_to_idle_and_stop() {
    let mut sim = emu(MOTOR_PLC, STAY_STOPPED);
    sim.run_until(ns(0.5), |_| {});
    let tim1_up = sim.drive().cpu().irq_entries("TIM1_UP_TIM16");
    let mut outputs_seen_on = false;
    for k in 1..=50 {
        sim.run_until(ns(0.5 + 0.01 * f64::from(k)), |_| {});
        let g = sim.drive().soc().tim1().map(|t| t.gate());
        outputs_seen_on |= g.is_some_and(|g| g.outputs_enabled);
    }
    let tim1_up = sim.drive().cpu().irq_entries("TIM1_UP_TIM16") - tim1_up;

    // Boot lines, no fault, no extra reset.
    for (m, image) in [(sim.drive(), "firmware-drive"), (sim.plc(), "firmware-plc")] {
        let first = m
            .log()
            .first()
            .map(|l| l.message.clone())
            .unwrap_or_default();
        assert!(
            first.starts_with(image) && first.contains("boot: 170 MHz"),
            "{image} boot line: {first:?}"
        );
        assert!(
            m.events()
                .iter()
                .all(|e| matches!(e, CpuEvent::Reset { at: 0, .. })),
            "{image}: {:?}",
            m.events()
        );
        let bad: Vec<String> = m
            .diagnostics()
            .iter()
            .filter(|d| {
                matches!(
                    d,
                    Diagnostic::Unmodelled { .. }
                        | Diagnostic::Unclocked { .. }
                        | Diagnostic::Unmapped { .. }
                        | Diagnostic::StuckPoll { .. }
                )
            })
            .map(|d| d.to_string())
            .collect();
        assert!(bad.is_empty(), "{image}: {bad:?}");
        // The watchdog is fed, never with more than half its 100 ms timeout between feeds.
        let w = m.soc().iwdg();
        assert!(w.running() && w.feeds > 20, "{image}: {} feeds", w.feeds);
        let gap_ms = cycles_to_ns(w.longest_gap) as f64 * 1e-6;
        assert!(gap_ms < 50.0, "{image}: longest feed gap {gap_ms} ms");
    }

    // The drive is idle and reports it; its PWM interrupt runs at the programmed rate with
    // the outputs off.
    assert_eq!(sim.status().map(|s| s.state), Some(DriveState::Idle));
    assert!(!outputs_seen_on, "outputs enabled while idle");
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    let period_cycles = 2 * u64::from(g.arr) * g.cycles_per_count;
    let expected = 0.5 * HCLK_HZ as f64 / period_cycles as f64;
    let rate_err = (tim1_up as f64 - expected).abs() / expected;
    assert!(
        rate_err < 0.002,
        "{tim1_up} TIM1 updates in 0.5 s, expected {expected:.0} (ARR {})",
        g.arr
    );

    // The PLC shows the editor's listing of the loaded program, in STOP.
    let lcd = sim.lcd();
    let rows: Vec<String> = (0..4).map(|r| lcd.row(r)).collect();
    assert!(
        rows.first().is_some_and(|r| r.starts_with(">000 PWF  Q00")),
        "LCD: {rows:#?}\nPLC log {:#?}\nPLC diagnostics {:#?}",
        sim.plc()
            .log()
            .iter()
            .map(|l| &l.message)
            .collect::<Vec<_>>(),
        sim.plc().diagnostics()
    );
    // The LCD driver meets the HD44780's timing (RS and data stable before E
    // rises, held while it falls, nothing sent while the controller is busy).
    let lcd = sim.lcd_device();
    assert_eq!(
        (
            lcd.setup_violations(),
            lcd.hold_violations(),
            lcd.busy_violations()
        ),
        (0, 0, 0),
        "LCD timing violations (set-up, hold, busy)"
    );
}

/// The image users flash is for the bare B-G431B-ESC1. It puts OPAMP1-3 in
/// the VINM0-biased PGA mode (gain 16, VINP0 = PA1, PA7, PB0, VINM0 = PA3, PA5, PB2,
/// output to the ADC internally), the ADCs read the amplifier outputs (ADC1 IN13, ADC2
/// IN16), and with the plant at 0 A on the documented network the boot zero calibration
/// passes: IDLE, no `BOOT` fault.
#[test]
fn the_esc1_image_reads_its_shunt_amplifiers_and_boots_to_idle_at_zero_current() {
    use firmware_drive::comparators::B_G431B_ESC1;
    use g431_emu::periph::adc::AdcId;
    use g431_emu::periph::opamp::{OpampInput, OpampMode};

    let (drive, _) = crate::common::images();
    let image = g431_emu::elf::Image::load(drive).expect("drive image");
    let board = hil_sim::emu::boards::image_board(&image).expect("profile marker");
    if board != g431_emu::boards::DriveBoardId::Esc1 {
        // A `source-sensors` build (not what CI tests or users flash): its pins carry the
        // source's sensors, `both_images_boot_to_idle_and_stop` covers it.
        return;
    }
    let mut sim = emu(MOTOR_PLC, STAY_STOPPED);
    sim.run_until(ns(0.3), |_| {});
    assert_eq!(sim.rig().plant.params().board, &B_G431B_ESC1);
    assert!(
        sim.drive()
            .log()
            .iter()
            .any(|l| l.message.contains("board profile: B-G431B-ESC1")),
        "{:?}",
        sim.drive()
            .log()
            .iter()
            .map(|l| &l.message)
            .collect::<Vec<_>>()
    );
    let amps = sim.drive().soc().opamps().expect("OPAMP model");
    // UM2516 / the public ESC1 ports: each shunt's network on VINP (PA1, PA7, PB0) and its
    // foot on VINM0 (PA3, PA5, PB2), the PGA in the VINM0-biased mode.
    for (n, pin, foot) in [(1, "PA1", "PA3"), (2, "PA7", "PA5"), (3, "PB0", "PB2")] {
        let c = amps.config(n).expect("OPAMPn");
        assert!(c.enabled && c.internal_only && !c.calibrating, "{c:?}");
        assert_eq!(c.vinp, OpampInput::Pin(pin));
        assert_eq!(
            c.mode,
            OpampMode::PgaVinm0 {
                gain: 16,
                vinm0: foot,
                filter_vinm1: None
            }
        );
    }
    // At 0 A both ends of the network sit at its bias (3/7 of 3.3 V, 1.414 V): the PGA
    // output is the bias, about 1755 counts on both current channels (in the grounded
    // mode it rails at 4095).
    let adc = sim.drive().soc().adc12().expect("ADC model");
    for (id, what) in [(AdcId::Adc1, "i_a"), (AdcId::Adc2, "i_b")] {
        let c = adc.jdr(id, 1);
        assert!((1700..=1810).contains(&c), "{what}: {c} counts");
    }
    assert_eq!(sim.status().map(|s| s.state), Some(DriveState::Idle));
    assert!(sim.faults().is_empty(), "{:?}", sim.faults());
}

/// With a probe attached from power-up (DHCSR.C_DEBUGEN), a breakpoint that
/// holds both release images halted for 300 ms, three times the IWDG's 100 ms timeout,
/// resets neither: the image froze its IWDG for the halt (DBGMCU_APB1FZR1.DBG_IWDG_STOP).
/// Without a probe the core cannot halt, and the watchdog runs as before (every other
/// test's "no watchdog reset").
#[test]
fn under_a_probe_a_halt_longer_than_the_watchdog_timeout_resets_neither_image() {
    let mut sim = emu(MOTOR_PLC, STAY_STOPPED);
    sim.drive_mut().cpu_mut().set_debugger(true);
    sim.plc_mut().cpu_mut().set_debugger(true);
    sim.run_until(ns(0.5), |_| {});
    sim.drive_mut().cpu_mut().halt();
    sim.plc_mut().cpu_mut().halt();
    sim.run_until(ns(0.8), |_| {});
    sim.drive_mut().cpu_mut().resume();
    sim.plc_mut().cpu_mut().resume();
    sim.run_until(ns(1.2), |_| {});
    for (m, name) in [(sim.drive(), "drive"), (sim.plc(), "PLC")] {
        let resets: Vec<_> = m
            .events()
            .iter()
            .filter(|e| matches!(e, CpuEvent::Reset { at, .. } if *at > 0))
            .collect();
        assert!(
            resets.is_empty(),
            "{name}: reset during or after a 300 ms halt under a probe (IWDG frozen: {}): \
             {resets:?}",
            m.soc().dbgmcu().iwdg_stop()
        );
        assert!(m.soc().dbgmcu().iwdg_stop(), "{name}: DBG_IWDG_STOP");
    }
}
