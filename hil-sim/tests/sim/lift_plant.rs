//! The `[lift]` plant wired to the PLC (lift.md 4): with the brake applied the car stays;
//! released with the motor off, gravity lowers it through floor 2's and floor 1's vanes
//! into the lower final limit, which opens the safety chain and engages the brake.

use super::common::*;

/// O01 (brake released) follows D00; the outputs are otherwise off. Needs no drive lines.
const BRAKE_ON_D00: &str = "150 LD  D00\n151 WR  O01\n";

#[test]
fn gravity_lowers_the_released_car_through_the_vanes_into_the_final_limit() {
    let r = run_text(
        BRAKE_ON_D00,
        "[lift]\n[[event]]\nat_s = 1.0\nset = { D00 = 1 }\n",
        6.0,
    );
    let s = &r.samples;
    let lift = |t: f64| at(s, t).lift.expect("lift columns");
    // Brake applied: the car does not move.
    assert_eq!(lift(0.9).car_mm, 450.0);
    assert!(lift(0.9).brake_engaged && lift(0.9).car_mms == 0.0);
    assert!(at(s, 0.9).digital_in & (1 << 12) != 0, "D12 door closed");
    assert!(at(s, 0.9).digital_in & (1 << 15) != 0, "D15 chain closed");
    // Released (O01 after the 5 ms debounce + scan, then the 30 ms brake delay): it falls.
    let first_move = s.iter().find(|x| x.lift.unwrap().car_mms != 0.0).unwrap();
    let dt = t_s(first_move) - 1.0;
    assert!((0.03..0.05).contains(&dt), "released {dt} s after D00");
    // Floor 2's zone: the right (long) vane first, both at level.
    let right_on = s.iter().find(|x| x.digital_in & (1 << 11) != 0).unwrap();
    let l = right_on.lift.unwrap();
    assert!(
        l.vane_r && !l.vane_l && (329.0..=331.0).contains(&l.car_mm),
        "{l:?}"
    );
    assert!(s.iter().any(|x| x.lift.unwrap().at_floor == 2));
    // Floor 1's zone from above: the left sensor leads.
    let f1 = s
        .iter()
        .find(|x| x.lift.unwrap().car_mm < 100.0 && x.digital_in & (3 << 10) != 0)
        .unwrap();
    assert_eq!((f1.digital_in >> 10) & 3, 0b01, "left on, right off");
    // The final limit at -40 mm: D15 = 0, brake engaged, the car stops below it.
    let open = s.iter().find(|x| x.digital_in & (1 << 15) == 0).unwrap();
    assert!(open.lift.unwrap().car_mm < -40.0 && open.lift.unwrap().car_mm > -42.0);
    let end = s.last().unwrap().lift.unwrap();
    assert!(end.brake_engaged && end.car_mms == 0.0, "{end:?}");
    // From about 0.4 m/s the brake (0.3 N m against 0.031 N m of gravity) needs ~50 mm.
    assert!(end.car_mm < -40.0 && end.car_mm > -150.0, "{end:?}");
    assert!(r.summary().contains("lift: car at"));
}
