//! hil-sim runs the PLC board's task bodies (`firmware_plc::task`), at the board's cadence:
//! the pins sampled every millisecond whatever the scan period, the LCD written one cell
//! per application pass, and the service endpoint fed by every pass from power-up (it is
//! the board's, not the service line's).

use hil_sim::run::parse_program;
use hil_sim::scenario::Scenario;
use hil_sim::service::{line, ServiceLine};
use hil_sim::sim::{RunOptions, Simulation};
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::service::{
    encode, Answer, Request, ServiceReader, SERVICE_BAUD, SERVICE_VERSION,
};
use shared_protocol::units::Micros;

const MS: u64 = 1_000_000;

/// O00 follows D00.
const FOLLOW: &str = "150 LD D00\n151 WR O00\n";

fn sim(program: &str, scenario: &str) -> Simulation {
    let p = parse_program(program, "test.plc").unwrap();
    Simulation::new(
        &p,
        Scenario::parse(scenario).unwrap(),
        RunOptions::default(),
    )
    .unwrap()
}

#[test]
fn the_pins_are_sampled_every_millisecond_whatever_the_scan_period() {
    // Scans every 10 ms (at 1000, 1010, ... ms); a 7 ms pulse from 1002 to 1009 ms falls
    // between two scans. The board samples the pins every millisecond: the debounced input
    // is on from about 1006 to 1013 ms, and the scan at 1010 ms sees it.
    let scenario = "[plant]\nscan_time_ms = 10.0\n\
                    [[event]]\nat_s = 1.002\nset = { D00 = 1 }\n\
                    [[event]]\nat_s = 1.009\nset = { D00 = 0 }\n";
    let mut sim = sim(FOLLOW, scenario);
    sim.run_until(1000 * MS, |_| {});
    assert!(sim.plc().running(), "RUN at power-up");
    let mut on = Vec::new();
    for ms in 1001..=1040 {
        sim.run_until(ms * MS, |_| {});
        if sim.plc().outputs() & 1 != 0 {
            on.push(ms);
        }
    }
    assert!(
        !on.is_empty(),
        "the 7 ms pulse between two scans never reached O00"
    );
    assert!(on.iter().all(|&ms| (1010..1030).contains(&ms)), "{on:?}");
}

/// Cells of the LCD that are not blank.
fn lit_cells(sim: &Simulation) -> usize {
    (0..4)
        .map(|r| {
            sim.plc()
                .lcd()
                .row(r)
                .bytes()
                .filter(|&b| b != b' ')
                .count()
        })
        .sum()
}

#[test]
fn the_lcd_is_written_one_cell_per_application_pass() {
    let mut sim = sim(FOLLOW, "");
    let mut lit = Vec::new();
    for ms in 1..=5 {
        sim.run_until(ms * MS, |_| {});
        lit.push(lit_cells(&sim));
    }
    // The first pass draws the screen and writes its first cell; each later pass one
    // more (the screen at power-up has more than five characters).
    let steps: Vec<_> = lit.windows(2).map(|w| w[1] as i64 - w[0] as i64).collect();
    assert_eq!(steps, [1, 1, 1, 1], "lit cells at 1..5 ms: {lit:?}");
    // Within 80 passes (a full 20 x 4 screen) plus a redraw period, the LCD shows what the
    // application drew.
    sim.run_until(200 * MS, |_| {});
    let screen = sim.plc().screen().clone();
    for r in 0..4u8 {
        assert_eq!(
            sim.plc().lcd().row(usize::from(r)),
            screen.row(r),
            "row {r}"
        );
    }
}

/// Sends `req` on the line and steps the simulation 1 ms at a time until its answer.
fn ask(
    sim: &mut Simulation,
    line: &mut ServiceLine,
    reader: &mut ServiceReader,
    id: u8,
    req: Request,
) -> Answer {
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode(id, req, &mut out).unwrap();
    line.host_write(&out[..n]);
    for _ in 0..200 {
        let t = sim.now_ns() + MS;
        sim.run_until(t, |_| {});
        for b in line.step(sim.plc_mut(), Micros(t / 1000)) {
            if let Some(Ok((got, a))) = reader.push::<Answer>(b) {
                if got == id {
                    return a;
                }
            }
        }
    }
    panic!("no answer to request {id} within 200 ms");
}

#[test]
fn the_service_counts_a_run_started_before_a_client_plugged_in() {
    // The board's service endpoint sees every application pass from power-up: the RUN
    // started at power-up is counted though nobody was on the service port then.
    let mut sim = sim(FOLLOW, "");
    sim.run_until(1000 * MS, |_| {});
    assert!(sim.plc().running(), "RUN at power-up");
    let mut line = ServiceLine::new(line::build_info(1), SERVICE_BAUD, SERVICE_VERSION, None);
    let mut reader = ServiceReader::new();
    let hello = ask(
        &mut sim,
        &mut line,
        &mut reader,
        1,
        Request::Hello {
            version: SERVICE_VERSION,
        },
    );
    assert!(matches!(hello, Answer::HelloReply { .. }), "{hello:?}");
    match ask(&mut sim, &mut line, &mut reader, 2, Request::GetCounters) {
        Answer::Counters(c) => assert_eq!(c.run_starts, 1, "{c:?}"),
        a => panic!("{a:?}"),
    }
}
