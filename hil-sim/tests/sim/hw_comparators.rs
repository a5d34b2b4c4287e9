//! The hardware trip levels as drive settings (`I>>`, `U>>`, the source's trimmers) and the
//! board's comparators as they are: on the B-G431B-ESC1 the
//! positive half-wave of each phase and the DC link; a negative half-wave is the software
//! check's (`I>`).

use super::common::*;

const COM_MONITOR: &str = include_str!("../../../shared-protocol/programs/com_monitor.plc");

#[test]
fn the_trimmer_levels_are_settings_the_plc_reads() {
    // com_monitor sets I>> 2.50 A and U>> 38 V and shows COM, VLT, IHW, UHW.
    let r = run_text(
        COM_MONITOR,
        "[[event]]\nat_s = 0\nset = { AUX = 682 }\n",
        0.5,
    );
    assert!(r.faults.is_empty());
    let end = r.samples.last().unwrap();
    // U>> 38 V is beyond the bare ESC1's 34.3 V range: clamped to 34 V.
    assert_eq!(end.lcd, [Some(682), Some(300), Some(250), Some(34)]);
    assert!(
        r.lcd.row(2).contains("250") && r.lcd.row(2).contains("34"),
        "{}",
        r.lcd.framed()
    );
    // Without I>>/U>> the board's defaults are in effect: the rig's [plant] values.
    let plc_only: String = COM_MONITOR
        .lines()
        .filter(|l| !l.starts_with("00"))
        .collect::<Vec<_>>()
        .join("\n");
    // On the bare ESC1 the default U>> is at most the board's 32 V.
    let r = run_text(&plc_only, "", 0.5);
    assert_eq!(r.samples.last().unwrap().lcd[2..], [Some(300), Some(32)]);
    let r = run_text(&plc_only, "[plant]\noc_hw_a = 1.5\nov_hw_v = 31.0\n", 0.5);
    assert_eq!(r.samples.last().unwrap().lcd[2..], [Some(150), Some(31)]);
}

#[test]
fn i_hw_in_the_program_sets_the_comparator() {
    // The motor example with a 1.20 A hardware level: a locked rotor trips OC_HW (code 2),
    // below the software I> of 2.00 A, on the positive half-wave in the ESC1's 0.47 A step
    // that holds 1.2 A (0.94-1.41 A).
    let program = format!("{MOTOR_PLC}\n026 I>> K21 0120\n");
    let scen = "[plant]\nlocked_rotor = true\n[[event]]\nat_s = 0\nset = { A00 = 980, A01 = 500 }\n[[event]]\nat_s = 0.2\npress = \"D00\"\n";
    let r = run_text(&program, scen, 2.0);
    assert_eq!(r.faults.iter().map(|f| f.code).collect::<Vec<_>>(), vec![2]);
    let t = r.faults[0].t_ns;
    let before: Vec<_> = r.samples.iter().filter(|x| x.t_ns < t).collect();
    let peak_pos = before
        .iter()
        .flat_map(|x| x.i_abc_a)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(peak_pos < 1.5, "peak {peak_pos}");
}

/// Direct duties on the three legs (0.1 %), no software `I>` unless `i_max` is given.
fn direct(duty: [u16; 3], i_max: Option<u16>) -> String {
    let mut p = String::new();
    for (k, (d, pw)) in duty.iter().zip(["PW1", "PW3", "PW5"]).enumerate() {
        p += &format!(
            "{:03} LD K{:02} {d:04}\n{:03} WR {pw}\n",
            2 * k,
            k,
            2 * k + 1
        );
    }
    if let Some(i) = i_max {
        p += &format!("006 I> K05 {i:04}\n");
    }
    p
}

#[test]
fn a_positive_half_wave_on_the_unsampled_phase_c_trips_in_hardware() {
    // Leg 3 at 40 % against legs 1 and 2 low: +4.1 A in phase c, -2.05 A in a and b. The
    // software never sees phase c; COMP4 (PB0) does.
    let r = run_text(&direct([0, 0, 400], None), "", 0.5);
    assert_eq!(r.faults.iter().map(|f| f.code).collect::<Vec<_>>(), vec![2]);
    let t = r.faults[0].t_ns;
    let last = r.samples.iter().rev().find(|x| x.t_ns < t).unwrap();
    assert!(last.i_abc_a[2] > 2.5 && last.i_abc_a[0] < 0.0, "{last:?}");
}

#[test]
fn a_negative_half_wave_is_the_software_checks() {
    // Legs 2 and 3 at 40 % against leg 1 low: -4.1 A in phase a, +2.05 A in b and c. No
    // comparator sees it (the G431 has no window on phase a's pin).
    let r = run_text(&direct([0, 400, 400], None), "", 0.5);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let end = r.samples.last().unwrap();
    assert!(end.i_abc_a[0] < -3.5, "{end:?}");
    assert!(end.i_abc_a[1] < 3.0 && end.i_abc_a[2] < 3.0);
    // With I> 2.00 A the software check takes it (code 1, OC).
    let r = run_text(&direct([0, 400, 400], Some(200)), "", 0.5);
    assert_eq!(r.faults.iter().map(|f| f.code).collect::<Vec<_>>(), vec![1]);
}

/// The motor example on the bare B-G431B-ESC1 front end (`[plant] board = "esc1"`: shunts,
/// PGA gain 16, inverting; the comparators at the PGA inputs): the drive reads the same
/// currents and voltage as with the source's sensors, within the ESC1's 29 mA step.
#[test]
fn the_esc1_front_end_measures_what_the_source_sensors_do() {
    let scen = "[[event]]\nat_s = 0\nset = { A00 = 980, A01 = 500 }\n[[event]]\nat_s = 0.2\npress = \"D00\"\n";
    let src = run_text(MOTOR_PLC, scen, 1.5);
    let esc1 = run_text(
        MOTOR_PLC,
        &format!("[plant]\nboard = \"esc1\"\n{scen}"),
        1.5,
    );
    assert!(
        src.faults.is_empty() && esc1.faults.is_empty(),
        "{:?}",
        esc1.faults
    );
    let (a, b) = (src.samples.last().unwrap(), esc1.samples.last().unwrap());
    assert!(
        (a.speed_rpm - b.speed_rpm).abs() < 0.01 * a.speed_rpm.abs(),
        "{} {}",
        a.speed_rpm,
        b.speed_rpm
    );
    assert!(
        (a.u_dc_v - b.u_dc_v).abs() < 0.2,
        "{} {}",
        a.u_dc_v,
        b.u_dc_v
    );
    // IMX and UDC as the drive reports them (LCD via the status) agree too.
    assert_eq!(a.f_cmd_hz, b.f_cmd_hz);
}

/// On the ESC1 the hardware overcurrent acts at the PGA input, in steps of about 0.47 A,
/// counted from the trimmed zero so that the trip lies in the step that holds the setting:
/// `I>>` 1.20 A trips at 1.41 A on the host's ideal sensors (the step's top);
/// a locked rotor trips `OC_HW` on the positive half-wave, before the software `I>` (2 A).
#[test]
fn on_the_esc1_i_hw_trips_at_the_pga_input() {
    let program = format!("{MOTOR_PLC}\n026 I>> K21 0120\n");
    let scen = "[plant]\nboard = \"esc1\"\nlocked_rotor = true\n[[event]]\nat_s = 0\nset = { A00 = 980, A01 = 500 }\n[[event]]\nat_s = 0.2\npress = \"D00\"\n";
    let r = run_text(&program, scen, 2.0);
    assert_eq!(r.faults.iter().map(|f| f.code).collect::<Vec<_>>(), vec![2]);
    let t = r.faults[0].t_ns;
    let peak_pos = r
        .samples
        .iter()
        .filter(|x| x.t_ns < t)
        .flat_map(|x| x.i_abc_a)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(peak_pos > 1.2 && peak_pos < 1.6, "peak {peak_pos}");
}

/// The host cores: TIM1's OC5 window (CCR5 from the core, around the valley,
/// covering every switching edge plus dead time and ringing) blanks the phase-current
/// comparators (`I>>` 1.50 A: 1.88 A on the ESC1's steps, above the start-up current). A 0.8 us, +3 A disturbance of the sensed phase-a current at the valley
/// (inside the window) does not trip; the same disturbance next to the counter's peak,
/// where the comparators stay live, trips `OC_HW`; so does a sustained overcurrent.
#[test]
fn a_spike_inside_the_blanking_window_does_not_trip_outside_it_trips_oc_hw() {
    use hil_sim::plant::SenseSpike;
    use hil_sim::run::parse_program;
    use hil_sim::scenario::Scenario;
    use hil_sim::sim::{RunOptions, Simulation};

    for board in ["source", "esc1"] {
        let program = format!("{MOTOR_PLC}\n026 I>> K21 0150\n");
        let scen = format!(
            "[plant]\nboard = \"{board}\"\n[[event]]\nat_s = 0\nset = {{ A00 = 980, A01 = 500 }}\n[[event]]\nat_s = 0.2\npress = \"D00\"\n"
        );
        let p = parse_program(&program, "test.plc").expect("program");
        let s = Scenario::parse(&scen).expect("scenario");
        let mut sim = Simulation::new(&p, s, RunOptions::default()).expect("sim");
        sim.run_until(1_000_000_000, |_| {});
        assert!(sim.faults().is_empty(), "{board}: {:?}", sim.faults());
        let spike = |from_ns: u64| SenseSpike {
            phase: 0,
            amps: 3.0,
            from_ns,
            to_ns: from_ns + 800,
        };
        // Inside: centred on the valley, in each of 20 periods.
        let mut t = sim.now_ns();
        for _ in 0..20 {
            let half = sim.plant().period_ns() / 2;
            sim.plant_mut().inject_sense_spike(spike(half - 400));
            t += sim.plant().period_ns();
            sim.run_until(t, |_| {});
        }
        assert!(
            sim.faults().is_empty(),
            "{board}: tripped by a blanked spike"
        );
        // Outside: next to the peak (the period's start in the plant's time).
        sim.plant_mut().inject_sense_spike(spike(100));
        sim.run_until(t + 2_000_000, |_| {});
        let codes: Vec<u8> = sim.faults().iter().map(|f| f.code).collect();
        assert_eq!(codes, vec![2], "{board}");
    }
}
