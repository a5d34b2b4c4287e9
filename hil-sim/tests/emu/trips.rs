//! Protections of the real images.

use g431_emu::cpu::CpuEvent;
use g431_emu::periph::rcc::ResetKind;
use g431_emu::time::cycles_to_ns;

use firmware_drive::comparator_trim::TrimmedZeros;
use firmware_drive::comparators::{BoardProfile, HwThresholds, Signal};
use firmware_drive::measure::FrontEnd;
use hil_sim::plant::sensors;
use shared_protocol::units::{CentiAmps, Volts};

use crate::common::{emu, ns, MOTOR_PLC, START_50HZ};

/// The motor program with the hardware comparators' level `I>>` at 1.2 A, below the
/// software limit `I>` (2 A): the DAC values come from the downloaded section.
fn motor_with_low_hw_limit() -> String {
    MOTOR_PLC.replace("025 frv K20 0200", "025 frv K20 0200\n026 I>> K21 0120")
}

/// The phase current at which the image's phase-a comparator trips for `I>>` of
/// `oc_centiamps`, and the width of the band the trip may lie in below it: 0 for a
/// comparator counted from the ADC's zero (the emulated sensors have no offset), one DAC
/// step for one counted from its boot trim (the trim finds the zero to within a step,
/// `firmware_drive::comparator_trim`).
fn trip_level_a(board: &BoardProfile, oc_centiamps: i16) -> (f64, f64) {
    let t = HwThresholds {
        oc_hw: CentiAmps(oc_centiamps),
        ov_hw: Volts(30),
    };
    let fe = FrontEnd::new(board.scaling);
    let spec = board
        .comparators
        .iter()
        .find(|s| s.signal == Signal::CurrentA)
        .expect("phase a comparator");
    let zero = f64::from(board.scaling.current_zero_counts);
    let div = f64::from(spec.input_divider);
    let dac = f64::from(spec.dac_counts(t, &fe, &TrimmedZeros::default()));
    let signal_counts = zero + (dac - zero) * div;
    let level = sensors::counts_to_current_f(&board.scaling, signal_counts);
    let step = if spec.zero_trim {
        div * 1000.0 / f64::from(board.scaling.current_millicounts_per_amp.abs())
    } else {
        0.0
    };
    (level, step)
}

#[test]
fn a_comparator_break_latches_the_outputs_off_with_oc_hw() {
    let scen = format!("[plant]\nlocked_rotor = true\n{START_50HZ}");
    let mut sim = emu(&motor_with_low_hw_limit(), &scen);
    let mut samples = Vec::new();
    sim.run_until(ns(3.0), |s| samples.push(s.clone()));
    let codes: Vec<u8> = sim.faults().iter().map(|f| f.code).collect();
    assert_eq!(codes, vec![2], "faults {:?}", sim.faults());
    let t_trip = sim.faults()[0].t_ns;
    // Latched off: no switching after the trip, and the current dies out.
    let after: Vec<_> = samples
        .iter()
        .filter(|s| s.t_ns > t_trip + ns(0.005))
        .collect();
    assert!(!after.is_empty() && after.iter().all(|s| !s.pwm_on && s.fault == 2));
    assert!(after
        .iter()
        .filter(|s| s.t_ns > t_trip + ns(0.05))
        .all(|s| s.i_abc_a.iter().all(|i| i.abs() < 0.05)));
    // Before the trip no phase exceeded the level by more than what one PWM period of a
    // locked rotor adds (the comparators are sampled twice per period). The level is the
    // image's board's: on the bare ESC1 the comparators watch the PGA inputs, where the
    // DAC's step is 0.47 A; counted from the boot trim, the trip lies in the step that
    // holds 1.2 A.
    let (level, step) = trip_level_a(sim.rig().plant.params().board, 120);
    assert!(
        level - step <= 1.2 && level >= 1.2 && level < 1.2 + step + 0.01,
        "trip level {level} A, band {step} A"
    );
    let peak = samples
        .iter()
        .filter(|s| s.t_ns < t_trip)
        .flat_map(|s| s.i_abc_a)
        .fold(0.0f64, f64::max);
    assert!(
        peak > level - step - 0.1 && peak < level + 0.2,
        "peak before the trip {peak} A, level {level} A (band {step} A below it)"
    );
    let tim1 = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(!tim1.moe, "MOE set again after the break");
}

#[test]
fn a_link_cut_trips_link_within_50_ms() {
    let scen = format!("[link]\ncut_at_s = 2.0\n{START_50HZ}");
    let mut sim = emu(MOTOR_PLC, &scen);
    let mut samples = Vec::new();
    sim.run_until(ns(2.2), |s| samples.push(s.clone()));
    // The drive logs its fault; the outputs are off.
    let trip = sim
        .drive()
        .log()
        .iter()
        .find(|l| l.message.contains("fault Link"))
        .map(|l| cycles_to_ns(l.at))
        .expect("LINK fault logged");
    assert!(
        trip > ns(2.0) && trip <= ns(2.0) + ns(0.05) + ns(0.002),
        "LINK at {trip} ns"
    );
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(!g.outputs_enabled);
    // The record observes the drive image itself, not the PLC's view of it
    // (which the cut froze): the LINK trip is in the faults and the `fault` column from
    // the moment the image latched it, as in `hil-sim run`.
    let codes: Vec<(u64, u8)> = sim.faults().iter().map(|f| (f.t_ns, f.code)).collect();
    assert!(
        matches!(codes.as_slice(), [(t, 5)] if t.abs_diff(trip) <= ns(0.001)),
        "faults {codes:?}, the image logged LINK at {trip} ns"
    );
    let after: Vec<_> = samples
        .iter()
        .filter(|s| s.t_ns >= trip + ns(0.001))
        .collect();
    assert!(
        !after.is_empty() && after.iter().all(|s| s.fault == 5 && !s.pwm_on),
        "fault column after the trip: {:?}",
        after.iter().map(|s| s.fault).collect::<Vec<_>>()
    );
    // The PLC shows the lost link within 100 ms.
    let lcd = sim.lcd();
    assert!(
        (0..4).any(|r| lcd.row(r).contains("LINK LOST")),
        "LCD {:?}",
        (0..4).map(|r| lcd.row(r)).collect::<Vec<_>>()
    );
}

#[test]
fn a_late_watchdog_feed_resets_the_drive_and_the_plc_shows_wdg() {
    let scen = format!("[emu]\nexpect = [\"watchdog_reset\"]\n{START_50HZ}");
    let mut sim = emu(MOTOR_PLC, &scen);
    sim.run_until(ns(1.5), |_| {});
    // The core stops (as if stuck) for 150 ms: the independent watchdog (100 ms) resets it.
    sim.drive_mut().cpu_mut().halt();
    sim.run_until(ns(1.65), |_| {});
    sim.drive_mut().cpu_mut().resume();
    // The drive boots again, the link comes back and the drive reports WDG: the PLC's
    // status row shows it at once (a new alert replaces the power-up notice "LOADED SLOT
    // 1"), well within a second of the reset. Polled every 10 ms.
    let mut shown_at = None;
    let mut rows = Vec::new();
    for k in 1..=100u32 {
        let t = ns(1.65) + u64::from(k) * ns(0.01);
        sim.run_until(t, |_| {});
        let lcd = sim.lcd();
        rows = (0..4).map(|r| lcd.row(r)).collect::<Vec<_>>();
        if rows.iter().any(|r| r.contains("F7 watchdog")) {
            shown_at = Some(t);
            break;
        }
    }
    assert!(shown_at.is_some(), "LCD {rows:?}");
    assert!(
        sim.drive().events().iter().any(|e| matches!(
            e,
            CpuEvent::Reset {
                why: ResetKind::Watchdog,
                ..
            }
        )),
        "{:?}",
        sim.drive().events()
    );
    assert!(
        sim.faults().iter().any(|f| f.code == 7),
        "{:?}",
        sim.faults()
    );
}

/// The real image: TIM1's OC5 (CCR5 from the core every period) blanks
/// COMP1/2/4 in a window around the counter's valley that holds every switching edge. A
/// 0.8 us, +3 A spike on phase a's sense signal centred on the valley, in 20 periods,
/// trips nothing; the same spike centred on the peak, where the comparators stay live,
/// trips `OC_HW`. (A sustained overcurrent: `a_comparator_break_latches_the_outputs_off_with_oc_hw`,
/// with the window in place.) The running current is ~0.6 A on phase a here, well under
/// the trimmed I>> (1.50 A, trips in 1.41-1.88 A): without the spikes nothing trips. The
/// comparator sees the spike's end when it happens (`Board::next_input_change`), so its
/// output is low again ~37 us before the window closes, as on the silicon.
#[test]
fn a_spike_inside_the_blanking_window_does_not_trip_outside_it_trips_oc_hw() {
    use g431_emu::time::ns_to_cycles;
    use hil_sim::emu::boards::SenseSpikeAt;

    // I>> 1.50 A: above the start-up current on either board profile's steps.
    let program = MOTOR_PLC.replace("025 frv K20 0200", "025 frv K20 0200\n026 I>> K21 0150");
    let mut sim = emu(&program, START_50HZ);
    sim.run_until(ns(1.5), |_| {});
    assert!(sim.faults().is_empty(), "{:?}", sim.faults());
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(g.outputs_enabled, "the motor runs");
    // The comparators of the phases are blanked by TIM1_OC5, the DC link's is not.
    let comps = sim.drive().soc().comps().expect("COMP model");
    for n in 1..=4 {
        let c = comps.config(n).expect("COMPn");
        let tim1_oc5 = c.blanking == Some(g431_emu::periph::comp::BlankingSource::Tim1Oc5);
        assert_eq!(tim1_oc5, n != 3, "COMP{n}: {c:?}");
    }
    let origin = g.phase_origin.expect("counting");
    let count = g.cycles_per_count;
    let period = 2 * u64::from(g.arr) * count;
    // The next valley from now (in cycles), then a spike centred on it for 20 periods.
    let now = ns_to_cycles(sim.now_ns());
    let first = origin + (now.saturating_sub(origin) / period + 2) * period;
    let spike = |centre: u64| SenseSpikeAt {
        phase: 0,
        amps: 3.0,
        from_ns: cycles_to_ns(centre) - 400,
        to_ns: cycles_to_ns(centre) + 400,
    };
    {
        let mut rig = sim.rig_mut();
        for k in 0..20 {
            rig.sense_spikes.push(spike(first + k * period));
        }
    }
    // 50 ms more: a fault would have reached the PLC's status by then.
    sim.run_until(cycles_to_ns(first + 21 * period) + ns(0.05), |_| {});
    assert!(
        sim.faults().is_empty(),
        "tripped by blanked spikes: {:?}",
        sim.faults()
    );
    // The same spike at the next peak (half a period after a valley).
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    let origin = g.phase_origin.expect("counting");
    let now = ns_to_cycles(sim.now_ns());
    let valley = origin + (now.saturating_sub(origin) / period + 2) * period;
    sim.rig_mut().sense_spikes.push(spike(valley + period / 2));
    sim.run_until(cycles_to_ns(valley) + ns(0.05), |_| {});
    let codes: Vec<u8> = sim.faults().iter().map(|f| f.code).collect();
    assert_eq!(codes, vec![2], "faults {:?}", sim.faults());
}

/// `hil-sim emu`'s summary lists the drive's LINK trip after a link cut, read
/// from the drive image, as `hil-sim run` does (`2.045 s  5 LINK` there).
#[test]
fn the_emu_summary_shows_the_link_trip_after_a_cut() {
    let (drive, plc) = crate::common::images();
    let program = hil_sim::run::parse_program(MOTOR_PLC, "motor.plc").expect("assembles");
    let scen = format!("[link]\ncut_at_s = 2.0\n{START_50HZ}");
    let scenario = hil_sim::scenario::Scenario::parse(&scen).expect("parses");
    let report = hil_sim::emu::run::run(
        drive,
        plc,
        &program,
        scenario,
        2.2,
        hil_sim::sim::RunOptions::default(),
        hil_sim::decimate::KeepSamples::for_plot(false),
        |_| {},
        |_, _| {},
    )
    .expect("runs");
    let summary = report.summary();
    let line = summary
        .lines()
        .find(|l| l.contains("5 LINK"))
        .unwrap_or_else(|| panic!("no LINK trip in the summary:\n{summary}"));
    let t: f64 = line
        .split_whitespace()
        .next()
        .and_then(|t| t.parse().ok())
        .expect("a time");
    assert!(t > 2.0 && t <= 2.052, "{line}");
}

/// `OV` (code 17, `shared-protocol/docs/fault-codes.md`) on the real drive image: the
/// bare ESC1 (no chopper) on a 20 V supply with `U>` 22 V, which leaves the overvoltage
/// controller no room (its cap is 2 V below `U>`), stops on a ramp faster than the
/// example's (0.5 s): the DC link passes `U>` and the image trips `OV`, once, well below
/// `U>>` (32 V), and the PLC's LCD names it (hil-sim's twin:
/// `sim::trips::without_a_chopper_an_uncontrolled_stop_trips_ov_once`).
#[test]
fn the_drive_image_trips_ov_above_u_max_without_a_chopper() {
    use hil_sim::sim::Sample;
    use shared_protocol::fault::FaultCode;
    let program = MOTOR_PLC
        .replace("002 LD  K01 2333", "002 LD  K01 0500")
        .replace("014 U>  K09 0035", "014 U>  K09 0022")
        .replace("015 U<  K10 0025", "015 U<  K10 0015");
    assert!(program.contains("K01 0500") && program.contains("K09 0022"));
    let scen = format!(
        "[plant]\ndc_link_v = 20.0\n{START_50HZ}\n[[event]]\nat_s = 1.5\npress = \"D00\"\n"
    );
    let mut sim = emu(&program, &scen);
    let mut peak = 0.0f64;
    let mut last_on_ns = 0;
    let mut status_rows = Vec::new();
    for k in 1..=30 {
        sim.run_until(ns(0.1 * f64::from(k)), |s: &Sample| {
            peak = peak.max(s.u_dc_v);
            if s.pwm_on {
                last_on_ns = s.t_ns;
            }
        });
        status_rows.push(sim.lcd().row(3));
        if !sim.faults().is_empty() && status_rows.iter().any(|r| r.starts_with("F17 overvoltage"))
        {
            break;
        }
    }
    let codes: Vec<u8> = sim.faults().iter().map(|f| f.code).collect();
    assert_eq!(
        codes,
        vec![FaultCode::Ov.code()],
        "faults {:?}, DC link peak {peak:.2} V",
        sim.faults()
    );
    let t_trip = sim.faults()[0].t_ns as f64 * 1e-9;
    assert!(t_trip > 1.5, "OV at {t_trip:.3} s, before the stop");
    assert!(peak > 22.0 && peak < 32.0, "DC link peak {peak:.2} V");
    let last_on = last_on_ns as f64 * 1e-9;
    assert!(
        last_on < t_trip + 0.002,
        "switching at {last_on:.4} s, OV at {t_trip:.4} s"
    );
    assert!(
        status_rows.iter().any(|r| r.starts_with("F17 overvoltage")),
        "LCD status rows {status_rows:?}"
    );
}

/// `docs/contributing/add-a-trip.md` step 11: every code added after drive.md's 16 has an
/// emulator test on the real image (one of the emulator test files names it).
#[test]
fn every_added_trip_has_an_emulator_test() {
    use shared_protocol::fault::FaultCode;
    let sources = [
        include_str!("trips.rs"),
        include_str!("board_findings.rs"),
        include_str!("power_stage.rs"),
        include_str!("safety.rs"),
    ]
    .concat();
    for f in FaultCode::ALL.iter().filter(|f| f.code() > 16) {
        let name = format!("FaultCode::{f:?}.code()");
        let named = sources.matches(&name).count();
        assert!(
            named >= 1,
            "no emulator test names {name} (hil-sim/tests/emu/trips.rs)"
        );
    }
}
