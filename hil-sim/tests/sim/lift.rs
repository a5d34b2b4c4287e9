//! The lift's acceptance scenarios L1-L10 (lift.md 5) with `lift.plc` on the default rig and
//! the `[lift]` plant; the scenario files are `scenarios/lift/`.

use hil_sim::plant::lift::LiftSample;
use hil_sim::sim::Sample;

use super::common::*;

const LIFT: &str = include_str!("../../../shared-protocol/programs/lift.plc");

fn scenario(name: &str) -> String {
    let path = format!("{}/scenarios/lift/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn run_lift(name: &str, duration_s: f64) -> Vec<Sample> {
    run_text(LIFT, &scenario(name), duration_s).samples
}

fn lift(s: &Sample) -> LiftSample {
    s.lift.expect("lift columns")
}

fn out(s: &Sample, n: u8) -> bool {
    s.digital_out & (1 << n) != 0
}

fn input(s: &Sample, n: u8) -> bool {
    s.digital_in & (1 << n) != 0
}

/// The first sample at or after `from_s` that satisfies `f`.
fn first(s: &[Sample], from_s: f64, f: impl Fn(&Sample) -> bool) -> &Sample {
    s.iter()
        .find(|x| t_s(x) >= from_s && f(x))
        .unwrap_or_else(|| panic!("nothing after {from_s} s"))
}

/// Where the car comes to rest after the level stop at `from_s` (brake engaged, speed 0).
fn rest_after(s: &[Sample], from_s: f64) -> LiftSample {
    lift(first(s, from_s, |x| {
        lift(x).brake_engaged && lift(x).car_mms == 0.0
    }))
}

/// lift.md 5 L1's checks of an initialisation ending level at floor 1, from `t0`.
fn check_init_level(s: &[Sample], t0: f64, within_s: f64) -> f64 {
    let both = first(s, t0, |x| {
        input(x, 10) && input(x, 11) && x.q[7] == 1 && lift(x).car_mm < 100.0
    });
    let t_both = t_s(both);
    let stop = first(s, t_both, |x| x.q[2] == 0 && x.q[3] == 0 && !out(x, 1));
    assert!(
        t_s(stop) - t_both <= 0.010,
        "stop {} s after both vanes",
        t_s(stop) - t_both
    );
    let off = first(s, t_both, |x| !x.pwm_on);
    assert!(t_s(off) - t_both <= 0.012);
    let rest = rest_after(s, t_s(stop));
    assert!(rest.car_mm.abs() <= 5.0, "level error {} mm", rest.car_mm);
    let idle = first(s, t_s(stop), |x| x.q[7] == 2);
    assert_eq!((idle.q[4], idle.q[5], idle.lcd[0]), (1, 1, Some(1)));
    assert!(t_s(idle) <= within_s, "idle at {} s", t_s(idle));
    t_s(idle)
}

#[test]
fn l1_initialisation_from_between_floors() {
    let s = run_lift("l1_init", 12.0);
    let first_on = first(&s, 0.0, |x| x.pwm_on);
    assert_eq!(first_on.dir, -1, "down before the first PWM period");
    let run = first(&s, 0.0, |x| x.q[7] != 0);
    assert_eq!(run.q[2], 154);
    assert!(out(run, 3), "down arrow from the first scan");
    // Floor 2's zone passed at 15.4 Hz.
    for x in s.iter().filter(|x| lift(x).at_floor == 2) {
        assert_eq!(x.q[2], 154);
    }
    // Floor 1's left-vane edge: creep within 10 ms.
    let edge = first(&s, 0.0, |x| lift(x).car_mm < 100.0 && input(x, 10));
    let creep = first(&s, t_s(edge), |x| x.q[2] == 46);
    assert!(t_s(creep) - t_s(edge) <= 0.010);
    check_init_level(&s, 0.0, 12.0);
    for x in &s {
        assert!(!out(x, 0), "no door cycle at initialisation");
        assert!(lift(x).car_mm >= -10.0 && input(x, 15));
    }
}

#[test]
fn l1b_initialisation_from_floor_one_clears_the_zone_first() {
    let s = run_lift("l1b_zone_start", 15.0);
    let first_on = first(&s, 0.0, |x| x.pwm_on);
    assert_eq!((first_on.dir, first_on.q[2]), (1, 46));
    let clear = first(&s, 0.0, |x| !input(x, 10) && !input(x, 11));
    assert!(s
        .iter()
        .filter(|x| t_s(x) < t_s(clear) && x.pwm_on)
        .all(|x| x.q[2] == 46));
    let stopped = first(&s, t_s(clear), |x| x.q[2] == 0);
    let rerun = first(&s, t_s(stopped), |x| x.q[2] == 154);
    assert!(t_s(rerun) - t_s(stopped) >= 0.5);
    check_init_level(&s, t_s(rerun), 15.0);
    assert!(s.iter().all(|x| (-10.0..=45.0).contains(&lift(x).car_mm)));
}

#[test]
fn l2_call_up_to_floor_three() {
    let s = run_lift("l2_call_up", 26.0);
    let press = first(&s, 7.0, |x| input(x, 2));
    let go = first(&s, t_s(press), |x| x.q[2] == 133 && out(x, 1));
    assert!(
        t_s(go) - t_s(press) <= 0.010,
        "departure {} s after the press",
        t_s(go) - t_s(press)
    );
    assert_eq!(first(&s, t_s(go), |x| x.pwm_on).dir, 1);
    assert!(
        s.iter()
            .filter(|x| t_s(x) >= 7.0)
            .all(|x| lift(x).car_mm >= -2.0),
        "roll-back"
    );
    let steady = first(&s, 10.0, |_| true);
    assert_eq!(steady.f_cmd_hz, 13.3);
    let v = lift(steady).car_mms;
    assert!((0.6 * 59.4..=1.5 * 59.4).contains(&v), "{v} mm/s");
    let f2 = first(&s, 7.0, |x| x.q[4] == 2);
    assert!((lift(f2).car_mm - 270.0).abs() < 2.0 && f2.q[2] == 133);
    let vane3 = first(&s, 7.0, |x| {
        lift(x).car_mm > 500.0 && (input(x, 10) || input(x, 11))
    });
    let creep = first(&s, t_s(vane3), |x| x.q[2] == 46);
    assert!(t_s(creep) - t_s(vane3) <= 0.010);
    let both = first(&s, t_s(vane3), |x| input(x, 10) && input(x, 11));
    let stop = first(&s, t_s(both), |x| x.q[2] == 0 && !out(x, 1));
    assert!(t_s(stop) - t_s(both) <= 0.010);
    let rest = rest_after(&s, t_s(stop));
    assert!(
        (rest.car_mm - 600.0).abs() <= 5.0,
        "level error {}",
        rest.car_mm - 600.0
    );
    let door = first(&s, t_s(stop), |x| out(x, 0));
    assert!(t_s(door) - t_s(stop) <= 0.010);
    let closed = first(&s, t_s(door), |x| !out(x, 0));
    assert!(
        (t_s(closed) - t_s(door) - 5.0).abs() <= 0.0011,
        "O00 for {} s",
        t_s(closed) - t_s(door)
    );
    let held: Vec<f64> = s
        .iter()
        .filter(|x| t_s(x) > t_s(stop) && lift(x).brake_engaged)
        .map(|x| lift(x).car_mm)
        .collect();
    // lift.md 5 L2: within +-1 mm of where the brake caught it.
    let caught = held
        .first()
        .copied()
        .expect("the brake holds the car after the stop");
    let worst = held.iter().map(|x| (x - caught).abs()).fold(0.0, f64::max);
    assert!(worst <= 1.0, "car moved {worst} mm on the brake");
}

/// The level stops after `from_s`: (floor, time).
fn stops(s: &[Sample], from_s: f64) -> Vec<(i16, f64)> {
    let mut v = Vec::new();
    // A door already open at `from_s` is not a new stop.
    let mut was = out(first(s, from_s, |_| true), 0);
    for x in s.iter().filter(|x| t_s(x) >= from_s) {
        let now = out(x, 0);
        if now && !was {
            v.push((x.q[4], t_s(x)));
        }
        was = now;
    }
    v
}

#[test]
fn l3_calls_are_served_in_press_order() {
    let s = run_lift("l3_press_order", 50.0);
    let st = stops(&s, 18.5);
    assert_eq!(st.iter().map(|x| x.0).collect::<Vec<_>>(), vec![4, 2]);
    // 4 -> 2 passes floor 3 at 13.3 Hz.
    for x in s
        .iter()
        .filter(|x| t_s(x) > st[0].1 && t_s(x) < st[1].1 && lift(x).at_floor == 3)
    {
        assert_eq!(x.q[2], 133);
    }
    let floors: Vec<i16> = s
        .iter()
        .filter(|x| t_s(x) > st[0].1 && t_s(x) <= st[1].1)
        .map(|x| x.q[4])
        .fold(Vec::new(), |mut v, f| {
            if v.last() != Some(&f) {
                v.push(f);
            }
            v
        });
    assert_eq!(floors, vec![4, 3, 2]);
}

#[test]
fn l3b_car_calls_before_hall_calls() {
    let s = run_lift("l3b_car_first", 50.0);
    let st = stops(&s, 6.5);
    assert_eq!(st.iter().map(|x| x.0).collect::<Vec<_>>(), vec![1, 4, 2]);
    // Floor 2 passed without creep on the way to 4.
    for x in s
        .iter()
        .filter(|x| t_s(x) < st[1].1 && lift(x).at_floor == 2)
    {
        assert_ne!(x.q[2], 46);
    }
}

#[test]
fn l4_overloaded_and_full_cars() {
    let s = run_lift("l4_load", 100.0);
    for x in s.iter().filter(|x| (7.6..12.9).contains(&t_s(x))) {
        assert!(
            !out(x, 1) && out(x, 5) && x.q[7] == 7 && x.lcd[3] == Some(3),
            "t {}",
            t_s(x)
        );
    }
    let go = first(&s, 13.0, |x| out(x, 1));
    assert!(t_s(go) - 13.0 <= 1.0 && !out(go, 5));
    // Full at floor 1: the hall call for 3 waits, the car call for 4 goes first.
    for x in s.iter().filter(|x| (52.6..57.9).contains(&t_s(x))) {
        assert!(!out(x, 1), "a full car ignores hall calls (t {})", t_s(x));
    }
    let st = stops(&s, 52.0);
    assert_eq!(st.iter().map(|x| x.0).collect::<Vec<_>>(), vec![4, 3]);
    assert!(st[1].1 > 82.0, "the hall call after the load fell");
}

#[test]
fn l5_in_car_stop_creeps_to_the_next_floor() {
    let s = run_lift("l5_in_car_stop", 50.0);
    let press = first(&s, 14.2, |x| input(x, 13));
    assert!(
        (lift(press).car_mm - 400.0).abs() < 10.0,
        "{}",
        lift(press).car_mm
    );
    let creep = first(&s, t_s(press), |x| x.q[2] == 46);
    assert!(t_s(creep) - t_s(press) <= 0.010);
    let st = stops(&s, t_s(press));
    assert_eq!(st[0].0, 3);
    let rest = rest_after(&s, st[0].1);
    assert!((rest.car_mm - 600.0).abs() <= 5.0);
    assert_eq!(first(&s, st[0].1, |_| true).q[7], 8);
    // The hall call at 28 s does nothing for 10 s; the car call at 39 s departs.
    assert!(s
        .iter()
        .filter(|x| (28.0..38.0).contains(&t_s(x)))
        .all(|x| !out(x, 1) && x.q[7] == 8));
    let go = first(&s, 39.0, |x| out(x, 1));
    assert!(t_s(go) - 39.0 < 0.1);
}

#[test]
fn l6_door_open_in_travel_is_a_latched_fault() {
    use hil_sim::run::parse_program;
    use hil_sim::scenario::Scenario;
    use hil_sim::sim::{RunOptions, Simulation};
    let p = parse_program(LIFT, "lift.plc").unwrap();
    let sc = Scenario::parse(&scenario("l6_door_in_travel")).unwrap();
    let mut sim = Simulation::new(&p, sc, RunOptions::default()).unwrap();
    let mut s: Vec<Sample> = Vec::new();
    sim.run_until(28_000_000_000, |x| s.push(x.clone()));
    let block = first(&s, 14.22, |_| true);
    assert!((lift(block).car_mm - 400.0).abs() < 10.0);
    let fault = first(&s, 14.22, |x| x.q[7] == 10);
    assert!(t_s(fault) - 14.22 <= 0.25);
    assert!(fault.q[2] == 0 && !out(fault, 1) && out(fault, 5));
    let off = first(&s, 14.22, |x| !x.pwm_on);
    assert!(t_s(off) - 14.22 <= 0.25);
    let rest = rest_after(&s, t_s(fault));
    assert!(rest.car_mm - lift(block).car_mm <= 20.0);
    for x in s.iter().filter(|x| (16.0..26.0).contains(&t_s(x))) {
        assert!(lift(x).car_mms == 0.0 && x.q[7] == 10, "t {}", t_s(x));
    }
    // The fault is in the PLC's fault log once (004 §2.3.3): application fault 10 (code
    // 110) with the floor (2: floor 2's zone was the last entered) and the target (3);
    // no time of day, the simulated PLC's clock is not set.
    type Logged = (u8, Option<i16>, Option<i16>, Option<u32>);
    let logged = |sim: &Simulation| -> Vec<Logged> {
        let log = sim.plc().app().fault_log();
        log.iter()
            .map(|e| (e.code, e.value(0), e.value(1), e.wall()))
            .collect()
    };
    assert_eq!(logged(&sim), [(110, Some(2), Some(3), None)]);
    // STOP, RUN: a new initialisation run (down at 15.4 Hz).
    for (k, t) in [(true, 28.0), (false, 28.1), (true, 28.5), (false, 28.6)] {
        sim.run_until((t * 1e9) as u64, |x| s.push(x.clone()));
        sim.key('A', k);
    }
    sim.run_until(31_000_000_000, |x| s.push(x.clone()));
    let init = first(&s, 28.5, |x| x.q[7] == 1 && x.q[2] == 154);
    assert!(t_s(init) < 29.0 && out(init, 3));
    // Once per occurrence: the latched fault and the new RUN add nothing.
    assert_eq!(logged(&sim).len(), 1);
}

#[test]
fn l7_a_drive_trip_applies_the_brake() {
    let s = run_lift("l7_drive_trip", 22.0);
    let trip = first(&s, 13.0, |x| x.fault != 0);
    assert_eq!(trip.fault, 4);
    let brake = first(&s, t_s(trip), |x| !out(x, 1));
    assert!(t_s(brake) - t_s(trip) <= 0.010);
    assert_eq!(first(&s, t_s(brake), |x| x.q[7] == 11).q[7], 11);
    let rest = rest_after(&s, t_s(trip));
    assert!((rest.car_mm - lift(trip).car_mm).abs() <= 10.0);
    let end = lift(s.last().unwrap());
    assert!((end.car_mm - rest.car_mm).abs() <= 1.0);
}

/// L7b (firmware-drive/docs/drive-core.md "Automatic restart"): L7's supply dip, but the
/// supply is back after 0.5 s. The drive restarts by itself after UV (`lift.plc`'s `arc`,
/// `art` 1.0 s), the lift waits in state 9 with the brake applied and then finishes its
/// trip: level at floor 3, the door opening only at rest, the motor never switching
/// before the program commands it again.
#[test]
fn l7b_the_lift_rides_through_a_supply_dip() {
    let s = run_lift("l7b_supply_dip", 30.0);
    let trip = first(&s, 13.0, |x| x.fault != 0);
    assert_eq!(trip.fault, 4);
    let brake = first(&s, t_s(trip), |x| !out(x, 1));
    assert!(t_s(brake) - t_s(trip) <= 0.010);
    let end = s.last().unwrap();
    let arrival = s
        .iter()
        .find(|x| t_s(x) > t_s(trip) && out(x, 0))
        .unwrap_or_else(|| {
            panic!(
                "the lift never reached floor 3 after the dip: state {}, fault {}, car at {:.1} mm",
                end.q[7],
                end.fault,
                lift(end).car_mm
            )
        });
    assert_eq!(arrival.q[4], 3);
    let rest = rest_after(&s, t_s(arrival) - 0.010);
    assert!(
        (rest.car_mm - 600.0).abs() <= 5.0,
        "level error {}",
        rest.car_mm - 600.0
    );
    // The drive restarted by itself, `art` after the supply came back (14.72 s).
    let restart = first(&s, t_s(trip), |x| x.fault == 0);
    assert!(t_s(restart) >= 15.72, "restart at {} s", t_s(restart));
    // Waiting in 9 (never a fault state), the motor off until the program resumes.
    let resume = first(&s, t_s(restart), |x| out(x, 1));
    assert!(matches!(resume.q[7], 3 | 5), "resumed in {}", resume.q[7]);
    for x in s.iter().filter(|x| t_s(x) > t_s(trip)) {
        assert!(x.q[7] < 10, "fault state {} at {} s", x.q[7], t_s(x));
        if t_s(x) < t_s(resume) {
            assert!(
                (!x.pwm_on && x.q[7] == 9) || t_s(x) < t_s(brake) + 0.02,
                "t {}",
                t_s(x)
            );
        }
    }
    // No motion with the door open (the door starts to open at the level stop while the
    // brake catches the creeping car: 10 % open is 0.2 s after O00); no roll-back after
    // the dip.
    for x in &s {
        assert!(
            lift(x).door <= 0.1 || lift(x).car_mms == 0.0,
            "t {}: door {}, car {} mm/s",
            t_s(x),
            lift(x).door,
            lift(x).car_mms
        );
    }
    let mut top = lift(trip).car_mm;
    for x in s
        .iter()
        .filter(|x| t_s(x) > t_s(trip) && t_s(x) < t_s(arrival))
    {
        assert!(lift(x).car_mm >= top - 1.0, "roll-back at {} s", t_s(x));
        top = top.max(lift(x).car_mm);
    }
}

#[test]
fn l8_overhauling_init_run_is_held_by_the_chopper() {
    let s = run_lift("l8_overhauling", 20.0);
    assert!(s.iter().all(|x| x.u_dc_v <= 38.0 && x.fault == 0));
    assert!(s.iter().any(|x| x.q[2] == 154 && lift(x).at_floor == 2));
    let idle = check_init_level(&s, 0.0, 20.0);
    assert!(idle > 5.0);
}

#[test]
fn l9_reversal_after_arriving_upwards() {
    let s = run_lift("l9_reversal", 40.0);
    let call = first(&s, 19.0, |x| input(x, 0));
    let stand = lift(call).car_mm;
    let first_on = first(&s, t_s(call), |x| x.pwm_on);
    assert_eq!(first_on.dir, -1);
    for x in s.iter().filter(|x| t_s(x) >= t_s(call)) {
        assert!(
            x.speed_rpm <= 5.0 && lift(x).car_mm <= stand + 1.0,
            "t {}",
            t_s(x)
        );
    }
    let st = stops(&s, t_s(call));
    assert_eq!(st[0].0, 1);
    assert!(rest_after(&s, st[0].1).car_mm.abs() <= 5.0);
}

fn check_vane_failure(name: &str) {
    let s = run_lift(name, 25.0);
    assert!(s.iter().any(|x| x.q[4] == 2), "floor 2 counted");
    let vane3 = first(&s, 7.0, |x| {
        lift(x).car_mm > 500.0 && (input(x, 10) || input(x, 11))
    });
    let fault = first(&s, t_s(vane3), |x| x.q[7] == 12);
    assert!(
        t_s(fault) - t_s(vane3) <= 4.010,
        "{} s",
        t_s(fault) - t_s(vane3)
    );
    assert!(fault.q[2] == 0 && !out(fault, 1) && out(fault, 5));
    let rest = rest_after(&s, t_s(fault));
    assert!((570.0..=700.0).contains(&rest.car_mm), "{}", rest.car_mm);
    assert!(s.iter().all(|x| input(x, 15)));
}

#[test]
fn l10_left_vane_failure_stops_on_the_travel_time() {
    check_vane_failure("l10_vane_fail_left");
}

#[test]
fn l10_right_vane_failure_stops_on_the_travel_time() {
    check_vane_failure("l10_vane_fail_right");
}
