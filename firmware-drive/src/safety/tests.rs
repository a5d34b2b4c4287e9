//! The monitor on synthetic v(k) (safety.md 14): every boundary at ±1 tick, ±0.1 Hz and
//! ±10⁻⁴ turn, release and re-request, functions together, SLA, `asr`, and property tests.

use super::*;
use crate::state::DriveState;
use proptest::prelude::*;
use shared_protocol::safety::SafetySetting as S;
use shared_protocol::safety::SafetySetting;

const STO_B: u16 = 1 << 0;
const SS1_B: u16 = 1 << 1;
const SS2_B: u16 = 1 << 2;
const SOS_B: u16 = 1 << 3;
const SL1_B: u16 = 1 << 4;
const SL2_B: u16 = 1 << 5;
const SLI_B: u16 = 1 << 8;
const SDP_B: u16 = 1 << 9;
const SDN_B: u16 = 1 << 10;
const SLA_B: u16 = 1 << 11;

/// The lab's settings (safety.md 4, p = 2).
fn lab() -> SafetySettings {
    let mut s = SafetySettings::default();
    for (k, v) in [
        (S::Fss, 40),
        (S::Pss, 200),
        (S::Trd, 50),
        (S::Tel, 50),
        (S::Ts1, 100),
        (S::Ts2, 100),
        (S::Fl1, 160),
        (S::Fl2, 100),
        (S::Tl1, 100),
        (S::Tl2, 100),
        (S::Pli, 100),
        (S::Tli, 100),
        (S::Tdi, 0),
        (S::Aap, 2000),
        (S::Adp, 2000),
        (S::Aan, 2000),
        (S::Adn, 2000),
        (S::Tla, 0),
    ] {
        s.set(k, Some(v));
    }
    s
}

fn with(mut s: SafetySettings, changes: &[(S, Option<u16>)]) -> SafetySettings {
    for &(k, v) in changes {
        s.set(k, v);
    }
    s
}

fn monitor(s: &SafetySettings) -> Monitor {
    let mut m = Monitor::new(s);
    m.start_run();
    m
}

fn inp(requested: u16, f: i16) -> Input {
    Input {
        requested,
        f_dhz: f,
        fmn_dhz: 0,
        reverse: false,
    }
}

/// `n` ticks at the same input, each followed by [`Monitor::follow`] as the drive does;
/// the first tick that trips (index, code), if any.
fn run(m: &mut Monitor, n: u32, i: Input) -> Option<(u32, FaultCode)> {
    for t in 0..n {
        let trip = m.tick(i).trip;
        m.follow(i.requested);
        if let Some(c) = trip {
            return Some((t, c));
        }
    }
    None
}

#[test]
fn sto_trips_in_the_tick_of_the_request_and_stays_latched() {
    let mut m = monitor(&SafetySettings::default());
    assert_eq!(run(&mut m, 10, inp(0, 500)), None);
    let v = m.tick(inp(STO_B, 500));
    assert_eq!(
        v,
        Verdict {
            f_dhz: 0,
            trip: Some(FaultCode::Sto)
        }
    );
    assert_eq!(m.status() & STO_B, STO_B);
    // Latched: released or not, nothing is applied until a new RUN.
    assert_eq!(m.tick(inp(0, 500)).trip, Some(FaultCode::Sto));
    assert_eq!(m.latched(), Some(FaultCode::Sto));
    m.stop();
    assert_eq!(m.tick(inp(0, 500)).trip, Some(FaultCode::Sto));
    m.start_run();
    assert_eq!(
        m.tick(inp(0, 500)),
        Verdict {
            f_dhz: 500,
            trip: None
        }
    );
}

#[test]
fn ss1_lab_case_ends_at_delay_plus_ramp_time_to_the_tick() {
    let mut m = monitor(&lab());
    run(&mut m, 7, inp(0, 100));
    // Request at k_r; SDC on [k_r, k_r + 15000); code 10 at k_r + 15000.
    assert_eq!(run(&mut m, 15_000, inp(SS1_B, 100)), None);
    assert!(m.sdc());
    assert_eq!(m.status(), 0);
    assert_eq!(m.elapsed_ds(), 150); // 15000 ticks with SDC = 1
    let v = m.tick(inp(SS1_B, 100));
    assert_eq!(v.trip, Some(FaultCode::Ss1));
    assert_eq!(v.f_dhz, 0);
    assert!(!m.sdc());
    assert_eq!(m.status(), SS1_B);
    assert_eq!(m.elapsed_ds(), 150); // `sft_s` 15.0
}

#[test]
fn early_limit_counts_from_the_request_to_the_tick_and_to_0_1_hz() {
    // Stopped: the end comes tel = 5000 ticks after the request (not at trd + tel).
    let mut m = monitor(&lab());
    assert_eq!(run(&mut m, 5000, inp(SS1_B, 0)), None);
    assert_eq!(m.tick(inp(SS1_B, 0)).trip, Some(FaultCode::Ss1));
    // At fss + 0.1 Hz the run of samples restarts: 5000 ticks after the last one above.
    let mut m = monitor(&lab());
    assert_eq!(run(&mut m, 3000, inp(SS1_B, 41)), None);
    assert_eq!(run(&mut m, 5000, inp(SS1_B, 40)), None);
    assert_eq!(m.tick(inp(SS1_B, 40)).trip, Some(FaultCode::Ss1));
    // Off (tel absent): the full delay + ramp time even at standstill.
    let mut m = monitor(&with(lab(), &[(S::Tel, None)]));
    assert_eq!(run(&mut m, 15_000, inp(SS1_B, 0)), None);
    assert_eq!(m.tick(inp(SS1_B, 0)).trip, Some(FaultCode::Ss1));
}

#[test]
fn ss2_reaches_standstill_at_fss_and_misses_it_at_fss_plus_0_1_hz() {
    let s = with(lab(), &[(S::Tel, None)]);
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 15_000, inp(SS2_B, 140)), None);
    assert_eq!(m.tick(inp(SS2_B, 41)).trip, Some(FaultCode::Ramp));
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 15_000, inp(SS2_B, 140)), None);
    assert_eq!(m.tick(inp(SS2_B, 40)).trip, None);
    assert_eq!(m.status(), SS2_B);
    assert!(!m.sdc());
    // Standstill: fss holds, fss + 0.1 Hz is code 12.
    assert_eq!(run(&mut m, 100, inp(SS2_B, 40)), None);
    assert_eq!(m.tick(inp(SS2_B, 41)).trip, Some(FaultCode::Sos));
    assert_eq!(m.status(), 0);
}

#[test]
fn ss2_standstill_position_window_to_one_ten_thousandth_of_a_turn() {
    // pss 1 turn = 10000 units; at v = 0.1 Hz x grows by 1 unit per tick.
    let s = with(lab(), &[(S::Pss, Some(1)), (S::Tel, Some(1))]);
    let mut m = monitor(&s);
    // Early limit after 100 ticks at v = 1: the end tick is the first of STANDSTILL,
    // x0 = x(k − 1); x − x0 = 1 at that tick.
    assert_eq!(run(&mut m, 100, inp(SS2_B, 1)), None);
    assert!(m.sdc());
    // 10000 ticks keep |x − x0| ≤ 10000, the next one is 10001.
    assert_eq!(run(&mut m, 10_000, inp(SS2_B, 1)), None);
    assert_eq!(m.status(), SS2_B);
    assert_eq!(m.tick(inp(SS2_B, 1)).trip, Some(FaultCode::Sos));
}

#[test]
fn sls_limited_at_the_limit_and_the_lowest_requested_limit_governs() {
    let s = with(lab(), &[(S::Tel, None)]);
    // End of the ramp at 10.0 Hz: LIMITED; 10.1 Hz: code 11.
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 15_000, inp(SL2_B, 120)), None);
    assert_eq!(m.tick(inp(SL2_B, 101)).trip, Some(FaultCode::Ramp));
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 15_000, inp(SL2_B, 120)), None);
    assert_eq!(run(&mut m, 10, inp(SL2_B, 100)), None);
    assert_eq!(m.status(), SL2_B);
    assert_eq!(m.tick(inp(SL2_B, 101)).trip, Some(FaultCode::Sls));
    // SL1 (16.0 Hz) and SL2 (10.0 Hz) together: 10.1 Hz trips, as SL2.
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 15_001, inp(SL1_B | SL2_B, 100)), None);
    assert_eq!(m.status(), SL1_B | SL2_B);
    assert_eq!(m.tick(inp(SL1_B | SL2_B, 101)).trip, Some(FaultCode::Sls));
    // The early limit of SLk counts |v| within flk: 5000 ticks at 10.0 Hz.
    let mut m = monitor(&lab());
    assert_eq!(run(&mut m, 5000, inp(SL2_B, 100)), None);
    assert!(m.sdc());
    assert_eq!(m.tick(inp(SL2_B, 100)).trip, None);
    assert_eq!((m.status(), m.sdc()), (SL2_B, false));
}

#[test]
fn the_envelope_trips_one_tick_after_its_first_0_1_hz_step() {
    // ard 2.0 Hz/s from 10 Hz: env = 100 − ⌊20·n/1000⌋ falls to 99 at n = 50.
    let s = with(lab(), &[(S::Ard, Some(20))]);
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 5050, inp(SS1_B, 100)), None);
    assert_eq!(m.tick(inp(SS1_B, 100)).trip, Some(FaultCode::Ramp));
    // Following the envelope exactly never trips; 0.1 Hz above it does.
    let mut m = monitor(&s);
    for k in 0..9000u32 {
        let env = if k < 5000 {
            100
        } else {
            (100 - (20 * (k - 5000) / 1000) as i16).max(40)
        };
        assert_eq!(m.tick(inp(SS1_B, env)).trip, None, "{k}");
    }
    // At k_B + 4000 the envelope is at its floor, fss (4.0 Hz).
    assert_eq!(m.tick(inp(SS1_B, 41)).trip, Some(FaultCode::Ramp));
}

#[test]
fn sos_holds_within_fss_and_pss_to_the_last_unit() {
    let s = with(lab(), &[(S::Pss, Some(1))]);
    let mut m = monitor(&s);
    run(&mut m, 50, inp(0, 1));
    // x0 = x(k_r − 1); after j + 1 ticks at 1 unit x − x0 = j + 1.
    assert_eq!(run(&mut m, 10_000, inp(SOS_B, 1)), None);
    assert_eq!(m.status(), SOS_B);
    assert!(!m.sdc());
    assert_eq!(m.tick(inp(SOS_B, 1)).trip, Some(FaultCode::Sos));
    // Speed: 4.0 Hz holds, 4.1 Hz trips at once, also on the request tick.
    let mut m = monitor(&lab());
    assert_eq!(run(&mut m, 10, inp(SOS_B, 40)), None);
    assert_eq!(m.tick(inp(SOS_B, 41)).trip, Some(FaultCode::Sos));
    let mut m = monitor(&lab());
    assert_eq!(m.tick(inp(SOS_B, 41)).trip, Some(FaultCode::Sos));
    // Reverse counts the same.
    let mut m = monitor(&s);
    let rev = Input {
        reverse: true,
        ..inp(SOS_B, 1)
    };
    assert_eq!(run(&mut m, 10_000, rev), None);
    assert_eq!(m.turns_e4(), -10_000);
    assert_eq!(m.tick(rev).trip, Some(FaultCode::Sos));
}

#[test]
fn sli_checks_standstill_at_the_request_and_its_window_both_ways() {
    let mut m = monitor(&lab());
    assert_eq!(m.tick(inp(SLI_B, 41)).trip, Some(FaultCode::Sli));
    let mut m = monitor(&lab());
    assert_eq!(m.tick(inp(SLI_B, 40)).trip, None);
    assert_eq!(m.status(), SLI_B);
    // pli 1 turn: at v = 1 the window holds for 10000 units from x(k_r − 1).
    let s = with(lab(), &[(S::Pli, Some(1))]);
    for reverse in [false, true] {
        let mut m = monitor(&s);
        let i = Input {
            reverse,
            ..inp(SLI_B, 1)
        };
        assert_eq!(run(&mut m, 10_000, i), None);
        assert_eq!(m.tick(i).trip, Some(FaultCode::Sli));
    }
}

#[test]
fn sli_stays_active_for_its_disable_delay_and_toggling_keeps_x0() {
    let s = with(lab(), &[(S::Pli, Some(1)), (S::Tli, Some(1))]); // 100 ticks
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 10, inp(SLI_B, 0)), None);
    // Released: status 1 for exactly 100 ticks, then dropped.
    assert_eq!(run(&mut m, 100, inp(0, 0)), None);
    assert_eq!(m.status(), SLI_B);
    m.tick(inp(0, 0));
    assert_eq!(m.status(), 0);
    // Inside the delay the window still counts; a re-request keeps x0 and skips the
    // standstill check (v = 5.0 Hz > fss is no trip).
    let mut m = monitor(&s);
    run(&mut m, 10, inp(SLI_B, 0));
    assert_eq!(run(&mut m, 50, inp(0, 0)), None);
    assert_eq!(run(&mut m, 40, inp(0, 50)), None); // x = 2000
    assert_eq!(run(&mut m, 100, inp(SLI_B, 50)), None); // x = 7000
    assert_eq!(m.status(), SLI_B);
    assert_eq!(run(&mut m, 60, inp(SLI_B, 50)), None);
    // x = 10000 now: one more unit trips.
    assert_eq!(m.turns_e4(), 10_000);
    assert_eq!(m.tick(inp(SLI_B, 1)).trip, Some(FaultCode::Sli));
    // tli 0: dropped on the release tick.
    let mut m = monitor(&with(lab(), &[(S::Tli, None)]));
    m.tick(inp(SLI_B, 0));
    m.tick(inp(0, 0));
    assert_eq!(m.status(), 0);
}

#[test]
fn sdp_trails_its_reference_and_sdn_mirrors_it() {
    let s = with(lab(), &[(S::Pss, Some(1)), (S::Tdi, Some(1))]);
    let mut m = monitor(&s);
    // Inactive (status 0) for tdi = 100 ticks: backward travel is not counted yet.
    let back = Input {
        reverse: true,
        ..inp(SDP_B, 1)
    };
    assert_eq!(run(&mut m, 100, back), None);
    assert_eq!(m.status(), 0);
    // Active: x_ref = x(k_a − 1) = −100; 10000 units back hold, the next trips.
    assert_eq!(run(&mut m, 10_000, back), None);
    assert_eq!(m.status(), SDP_B);
    assert_eq!(m.tick(back).trip, Some(FaultCode::Sdi));
    // The reference trails the furthest forward point: 30000 forward, then back.
    let mut m = monitor(&with(lab(), &[(S::Pss, Some(1))]));
    assert_eq!(run(&mut m, 300, inp(SDP_B, 100)), None);
    let back = Input {
        reverse: true,
        ..inp(SDP_B, 100)
    };
    assert_eq!(run(&mut m, 100, back), None); // 10000 back from the maximum
    assert_eq!(m.tick(back).trip, Some(FaultCode::Sdi));
    // SDN: forward travel is the wrong direction.
    let mut m = monitor(&with(lab(), &[(S::Pss, Some(1))]));
    assert_eq!(run(&mut m, 10_000, inp(SDN_B, 1)), None);
    assert_eq!(m.tick(inp(SDN_B, 1)).trip, Some(FaultCode::Sdi));
}

#[test]
fn sla_uses_a_100_ms_window_and_the_quadrant_table() {
    let limits = |aap, adp, aan, adn| {
        with(
            lab(),
            &[
                (S::Aap, Some(aap)),
                (S::Adp, Some(adp)),
                (S::Aan, Some(aan)),
                (S::Adn, Some(adn)),
            ],
        )
    };
    // aap 10.0 Hz/s: +1.0 Hz per 100 ticks holds (a = 100), +1.1 Hz trips (a = 110).
    let s = limits(100, 9999, 9999, 9999);
    let mut m = monitor(&s);
    run(&mut m, 200, inp(0, 100));
    assert_eq!(run(&mut m, 100, inp(SLA_B, 110)), None);
    assert_eq!(m.status(), SLA_B);
    let mut m = monitor(&s);
    run(&mut m, 200, inp(0, 100));
    assert_eq!(m.tick(inp(SLA_B, 111)).trip, Some(FaultCode::Sla));
    // The same step in reverse accelerates the reverse way: aan (9999) applies.
    let mut m = monitor(&s);
    let r = |f| Input {
        reverse: true,
        ..inp(SLA_B, f)
    };
    run(
        &mut m,
        200,
        Input {
            requested: 0,
            ..r(100)
        },
    );
    assert_eq!(run(&mut m, 10, r(200)), None);
    // adp: decelerating forward.
    let s = limits(9999, 100, 9999, 9999);
    let mut m = monitor(&s);
    run(&mut m, 200, inp(0, 400));
    assert_eq!(m.tick(inp(SLA_B, 390)).trip, None);
    let mut m = monitor(&s);
    run(&mut m, 200, inp(0, 400));
    assert_eq!(m.tick(inp(SLA_B, 389)).trip, Some(FaultCode::Sla));
    // Within ±fss the stricter pair: accelerating up from standstill uses min(aap, adn).
    let l = Limits::from_settings(&limits(300, 200, 500, 100));
    assert_eq!(accel::limit(&l, 40, 1), 100);
    assert_eq!(accel::limit(&l, -40, -1), 200);
    assert_eq!(accel::limit(&l, 41, 1), 300);
    assert_eq!(accel::limit(&l, 41, -1), 200);
    assert_eq!(accel::limit(&l, -41, 1), 100);
    assert_eq!(accel::limit(&l, -41, -1), 500);
    // v = 0 before RUN: the outputs switching on at fmn is a step of fmn.
    let mut m = monitor(&limits(100, 9999, 9999, 9999));
    assert_eq!(m.tick(inp(SLA_B, 10)).trip, None); // a = 100
    let mut m = monitor(&limits(100, 9999, 9999, 9999));
    assert_eq!(m.tick(inp(SLA_B, 11)).trip, Some(FaultCode::Sla));
    // tla: inactive (status 0, no check) for its delay.
    let mut m = monitor(&with(limits(100, 9999, 9999, 9999), &[(S::Tla, Some(1))]));
    assert_eq!(run(&mut m, 99, inp(SLA_B, 0)), None);
    assert_eq!(m.tick(inp(SLA_B, 500)).trip, None); // k = 99: not active yet
    assert_eq!(m.status(), 0);
    assert_eq!(m.tick(inp(SLA_B, 500)).trip, Some(FaultCode::Sla));
}

#[test]
fn asr_caps_the_frequency_from_the_request_and_a_release_drops_the_cap() {
    let s = with(lab(), &[(S::Asr, Some(50))]);
    let mut m = monitor(&s);
    let fmn = |r, f| Input {
        fmn_dhz: 10,
        ..inp(r, f)
    };
    run(&mut m, 5, fmn(0, 100));
    // cap(k) = 100 − ⌊50·n/1000⌋: 40 at n = 1200 (not at 1199).
    for n in 0..1200u32 {
        let v = m.tick(fmn(SS1_B, 100));
        assert_eq!(v.f_dhz, 100 - (n / 20) as i16, "{n}");
    }
    assert_eq!(m.tick(fmn(SS1_B, 100)).f_dhz, 40);
    // The cap never raises f.
    assert_eq!(m.tick(fmn(SS1_B, 30)).f_dhz, 30);
    // Below fmn v = 0: the early limit ends SS1 tel after f first fell to fss.
    let mut m = monitor(&s);
    let mut end = None;
    for n in 0..10_000u32 {
        if m.tick(fmn(SS1_B, 100)).trip.is_some() {
            end = Some(n);
            break;
        }
    }
    assert_eq!(end, Some(1200 + 5000));
    // SS2 at standstill under the cap: the program's 6.0 Hz stays at 0, no trip.
    let mut m = monitor(&s);
    assert_eq!(run(&mut m, 8000, fmn(SS2_B, 100)), None);
    assert_eq!(m.status(), SS2_B);
    let v = m.tick(fmn(SS2_B, 60));
    assert_eq!((v.f_dhz, v.trip), (0, None));
    // A release drops the cap: the program's f at once.
    assert_eq!(m.tick(fmn(0, 60)).f_dhz, 60);
    // asr 0: no cap at all.
    let mut m = monitor(&lab());
    assert_eq!(m.tick(inp(SS1_B, 100)).f_dhz, 100);
    assert_eq!(run(&mut m, 2000, inp(SS1_B, 100)), None);
    assert_eq!(m.tick(inp(SS1_B, 100)).f_dhz, 100);
}

#[test]
fn a_release_before_the_end_drops_with_no_latch_and_a_new_request_starts_afresh() {
    for phase_ticks in [0u32, 4999, 5000, 14_999] {
        let mut m = monitor(&lab());
        assert_eq!(run(&mut m, phase_ticks, inp(SS1_B, 100)), None);
        assert_eq!(m.tick(inp(0, 100)).trip, None);
        assert!(!m.sdc());
        // Afresh: another full 15000 ticks.
        assert_eq!(run(&mut m, 15_000, inp(SS1_B, 100)), None, "{phase_ticks}");
        assert_eq!(m.tick(inp(SS1_B, 100)).trip, Some(FaultCode::Ss1));
    }
    // Released in the safe state (SS2 STANDSTILL, SOS, SDP): dropped, no trip after.
    for bit in [SS2_B, SOS_B, SDP_B, SL2_B] {
        let mut m = monitor(&lab());
        assert_eq!(run(&mut m, 16_000, inp(bit, 0)), None);
        assert_eq!(m.status(), bit);
        assert_eq!(run(&mut m, 10, inp(0, 500)), None);
        assert_eq!(m.status(), 0);
    }
}

#[test]
fn the_stopwatch_restarts_counts_reads_0_when_deselected_and_resets_at_run() {
    let mut m = monitor(&lab());
    run(&mut m, 2500, inp(SS2_B, 100));
    assert_eq!(m.elapsed_ds(), 25);
    // Released: 0 (001 4.2.4: `elapsedTime := 0` without an active ramp function).
    run(&mut m, 1, inp(0, 100));
    assert_eq!(m.elapsed_ds(), 0);
    // A non-ramp request leaves it at 0; a new ramp request counts from 0.
    run(&mut m, 1000, inp(SOS_B, 0));
    assert_eq!(m.elapsed_ds(), 0);
    run(&mut m, 100, inp(SOS_B | SL1_B, 0));
    assert_eq!(m.elapsed_ds(), 1);
    // The early end at 5000 ticks holds it at 5.0 s while SL1 stays requested, outside
    // RUN too; deselected there, 0.
    run(&mut m, 6000, inp(SL1_B, 0));
    assert_eq!(m.elapsed_ds(), 50);
    m.stop();
    m.follow(SL1_B);
    assert_eq!(m.elapsed_ds(), 50);
    m.follow(SOS_B);
    assert_eq!(m.elapsed_ds(), 0);
    run(&mut m, 100, inp(SL1_B, 0));
    m.start_run();
    assert_eq!(m.elapsed_ds(), 0);
}

#[test]
fn the_stopwatch_holds_at_15_s() {
    // SS1 with a 10 s delay and a 10 s ramp time: 15.0 s from tick 15000 to the end.
    let mut m = monitor(&with(lab(), &[(S::Trd, Some(100))]));
    assert_eq!(run(&mut m, 14_999, inp(SS1_B, 100)), None);
    assert_eq!(m.elapsed_ds(), 149);
    assert_eq!(run(&mut m, 5_001, inp(SS1_B, 100)), None);
    assert_eq!(m.elapsed_ds(), 150);
    assert_eq!(m.tick(inp(SS1_B, 100)).trip, Some(FaultCode::Ss1));
    assert_eq!(m.elapsed_ds(), 150);
}

#[test]
fn sfp_counts_whole_turns_since_the_activation_and_reads_0_when_deselected() {
    let mut m = monitor(&SafetySettings::default());
    let i = Input {
        requested: 0,
        f_dhz: 100,
        fmn_dhz: 0,
        reverse: false,
    };
    run(&mut m, 1000, i); // 10 turns with nothing requested
    assert_eq!(m.turns_e4(), 100_000);
    assert_eq!(m.turns_since_activation(), 0);
    // SDP (forward allowed): 999 ticks at 10 Hz are 9.99 turns, shown as 9.
    let sdp = Input {
        requested: SDP_B,
        ..i
    };
    run(&mut m, 999, sdp);
    assert_eq!(m.turns_since_activation(), 9);
    run(&mut m, 1, sdp);
    assert_eq!(m.turns_since_activation(), 10);
    // Another function added: still since the activation.
    run(
        &mut m,
        1000,
        Input {
            requested: SDP_B | SOS_B,
            f_dhz: 0,
            ..i
        },
    );
    assert_eq!(m.turns_since_activation(), 10);
    // Released: 0; SDN in reverse from there: negative, truncated toward 0.
    run(&mut m, 1, Input { requested: 0, ..i });
    assert_eq!(m.turns_since_activation(), 0);
    let sdn = Input {
        requested: SDN_B,
        reverse: true,
        ..i
    };
    run(&mut m, 1499, sdn);
    assert_eq!(m.turns_since_activation(), -14);
    // Outside RUN it holds while requested and reads 0 once released.
    m.stop();
    m.follow(SDN_B);
    assert_eq!(m.turns_since_activation(), -14);
    m.follow(0);
    assert_eq!(m.turns_since_activation(), 0);
    m.follow(SOS_B);
    assert_eq!(m.turns_since_activation(), 0);
    // Saturating at ±32767 turns.
    m.x = 400_000_000;
    assert_eq!(m.turns_since_activation(), 32767);
    m.x = -400_000_000;
    assert_eq!(m.turns_since_activation(), -32767);
    // A new RUN: 0, and the first request counts from x = 0.
    m.start_run();
    assert_eq!(m.turns_since_activation(), 0);
    run(&mut m, 2000, sdp);
    assert_eq!(m.turns_since_activation(), 20);
}

#[test]
fn x_integrates_the_applied_signed_command_in_ten_thousandths() {
    let mut m = monitor(&SafetySettings::default());
    let i = Input {
        requested: 0,
        f_dhz: 100,
        fmn_dhz: 50,
        reverse: false,
    };
    run(&mut m, 1000, i); // 10 Hz for 1 s: 10 turns
    assert_eq!(m.turns_e4(), 100_000);
    run(&mut m, 1000, Input { f_dhz: 49, ..i }); // below fmn: off, v = 0
    assert_eq!(m.turns_e4(), 100_000);
    run(&mut m, 500, Input { reverse: true, ..i });
    assert_eq!(m.turns_e4(), 50_000);
    m.start_run();
    assert_eq!(m.turns_e4(), 0);
}

#[test]
fn ack_rules_and_status_outside_run() {
    use FaultCode as F;
    assert_eq!(cause_gone(F::Sto, STO_B), Some(false));
    assert_eq!(cause_gone(F::Sto, SS1_B), Some(true));
    assert_eq!(cause_gone(F::Ss1, SS1_B), Some(false));
    assert_eq!(cause_gone(F::Ss1, STO_B), Some(true));
    for c in [F::Ramp, F::Sos, F::Sls, F::Sli, F::Sdi, F::Sla] {
        assert_eq!(cause_gone(c, 0xFFFF), Some(true));
    }
    assert_eq!(cause_gone(F::Oc, 0), None);
    let all = 0x0FFF;
    assert_eq!(status_outside_run(DriveState::Idle, 0xFFFF), all);
    assert_eq!(status_outside_run(DriveState::Fault, all), STO_B | SS1_B);
    assert_eq!(status_outside_run(DriveState::Boot, all), 0);
}

// ---- property tests -------------------------------------------------------------

/// Small random settings, so that every phase is reached within a few thousand ticks.
fn settings() -> impl Strategy<Value = SafetySettings> {
    prop::collection::vec(prop::option::weighted(0.9, 0u16..60), SETTINGS_N).prop_map(|v| {
        let mut s = SafetySettings::default();
        for (k, val) in shared_protocol::safety::SafetySetting::ALL
            .into_iter()
            .zip(v)
        {
            s.set(k, val);
        }
        s
    })
}
const SETTINGS_N: usize = shared_protocol::safety::SETTINGS;

/// Segments of (ticks, requested, f, reverse).
fn segments() -> impl Strategy<Value = Vec<(u32, u16, i16, bool)>> {
    prop::collection::vec(
        (
            1u32..400,
            prop::bits::u16::masked(0x0FFF),
            0i16..200,
            any::<bool>(),
        ),
        1..20,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Outputs never enabled while STO is requested or a code is latched (and off after
    /// one until a new RUN); no value beyond an active limit is ever applied; the cap
    /// never raises f.
    #[test]
    fn nothing_beyond_a_limit_is_ever_applied(
        s in settings(), segs in segments(), fmn in 0i16..30
    ) {
        let lim = Limits::from_settings(&s);
        let mut m = monitor(&s);
        let mut latched: Option<FaultCode> = None;
        let mut prev_req = 0u16;
        let mut sos_x0 = 0i64;
        let mut x = 0i64;
        let mut hist = std::collections::VecDeque::from(vec![0i32; 100]);
        for (n, req, f, reverse) in segs {
            for _ in 0..n {
                let v = m.tick(Input { requested: req, f_dhz: f, fmn_dhz: fmn, reverse });
                prop_assert!(v.f_dhz <= f.max(0));
                let speed = if v.f_dhz > 0 && v.f_dhz >= fmn { i32::from(v.f_dhz) } else { 0 };
                let sv = if reverse { -speed } else { speed };
                let x_prev = x;
                x += i64::from(sv);
                let old = hist.pop_front().unwrap_or(0);
                hist.push_back(sv);
                if req & SOS_B != 0 && prev_req & SOS_B == 0 {
                    sos_x0 = x_prev;
                }
                prev_req = req;
                if let Some(c) = latched {
                    prop_assert_eq!(v, Verdict { f_dhz: 0, trip: Some(c) });
                    continue;
                }
                if req & STO_B != 0 {
                    prop_assert_eq!(v.trip, Some(FaultCode::Sto));
                }
                if let Some(c) = v.trip {
                    prop_assert_eq!(v.f_dhz, 0);
                    latched = Some(c);
                    continue;
                }
                prop_assert_eq!(m.turns_e4(), x);
                let st = m.status();
                if req & SOS_B != 0 {
                    prop_assert!(speed <= lim.fss() && (x - sos_x0).abs() <= lim.pss());
                }
                if st & SS2_B != 0 {
                    prop_assert!(speed <= lim.fss());
                }
                for i in 0..4 {
                    if st & (SL1_B << i) != 0 {
                        prop_assert!(speed <= lim.speed(SafetySetting::ALL[S::Fl1.index() + i]));
                    }
                }
                if st & SLA_B != 0 {
                    let a = 10 * (sv - old);
                    prop_assert!(a.abs() <= accel::limit(&lim, sv, a));
                }
                // Status only for requested functions (SLI also in its disable delay).
                prop_assert_eq!(st & !req & !SLI_B, 0);
            }
        }
    }
}
