//! Timers are exact to the scan (program.md 3.2): measured with the monotonic ms clock
//! from the scan that first saw the input, they never end early and end at most one scan
//! late, whatever the scan periods, presets, input patterns and clock wrap.

use plc_vm::{PlcVm, ScanInputs, ScanOutputs};
use proptest::prelude::*;
use shared_protocol::program::assemble;
use shared_protocol::units::Millis;

/// One scan of the history: how long after the previous one it runs, and D00.
#[derive(Debug, Clone, Copy)]
struct Scan {
    dt_ms: u32,
    input: bool,
}

fn scans() -> impl Strategy<Value = Vec<Scan>> {
    // Runs of equal input so that timers get the chance to elapse.
    prop::collection::vec((1u32..400, any::<bool>(), 1usize..40), 1..30).prop_map(|runs| {
        runs.into_iter()
            .flat_map(|(dt, input, n)| {
                (0..n).map(move |i| Scan {
                    dt_ms: dt + (i as u32 * 37) % 50,
                    input,
                })
            })
            .collect()
    })
}

/// Runs the three timers on D00 and returns (time since start in ms, input, TON, TOF, IMP)
/// per scan. The VM sees the wrapped u32 clock starting at `t0`.
fn run(t0: u32, presets: [u16; 3], history: &[Scan]) -> Vec<(u64, bool, bool, bool, bool)> {
    let text = format!(
        "150 LD D00\n151 TON K01 {:04}\n152 WR O00\n\
         153 LD D00\n154 TOF K02 {:04}\n155 WR O01\n\
         156 LD D00\n157 IMP K03 {:04}\n158 WR O02\n",
        presets[0], presets[1], presets[2]
    );
    let prog = assemble(&text).unwrap();
    let mut vm = PlcVm::new();
    vm.start(Millis(t0));
    let mut out = ScanOutputs::default();
    let mut t = 0u64;
    let mut rows = vec![];
    for (k, s) in history.iter().enumerate() {
        if k > 0 {
            t += u64::from(s.dt_ms);
        }
        let inputs = ScanInputs {
            digital: u16::from(s.input),
            ..ScanInputs::default()
        };
        vm.scan(&prog, &inputs, Millis(t0.wrapping_add(t as u32)), &mut out);
        rows.push((t, s.input, out.output(0), out.output(1), out.output(2)));
    }
    rows
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn ton_never_early_at_most_one_scan_late(
        t0 in prop_oneof![any::<u32>(), (u32::MAX - 5000)..=u32::MAX],
        preset in 0u16..=60,
        history in scans(),
    ) {
        let preset_ms = u64::from(preset) * 100;
        let rows = run(t0, [preset, 0, 0], &history);
        let mut since: Option<u64> = None; // first scan of the current run of 1s
        for (k, &(t, input, on, _, _)) in rows.iter().enumerate() {
            since = if input { Some(since.unwrap_or(t)) } else { None };
            match since {
                None => prop_assert!(!on, "scan {k}: on without input"),
                Some(t_in) => {
                    let elapsed = t - t_in;
                    // Never early.
                    prop_assert!(!on || elapsed >= preset_ms, "scan {k}: early ({elapsed} ms)");
                    // At most one scan late: on at the first scan at or after the preset.
                    prop_assert!(on || elapsed < preset_ms, "scan {k}: late ({elapsed} ms)");
                }
            }
        }
    }

    #[test]
    fn tof_holds_exactly_the_preset_after_the_fall(
        t0 in prop_oneof![any::<u32>(), (u32::MAX - 5000)..=u32::MAX],
        preset in 0u16..=60,
        history in scans(),
    ) {
        let preset_ms = u64::from(preset) * 100;
        let rows = run(t0, [0, preset, 0], &history);
        let mut fell: Option<u64> = None; // scan that first saw the input 0 after a 1
        let mut prev = false;
        for (k, &(t, input, _, on, _)) in rows.iter().enumerate() {
            if input {
                fell = None;
                prop_assert!(on, "scan {k}: off while the input is on");
            } else {
                if prev {
                    fell = Some(t);
                }
                match fell {
                    None => prop_assert!(!on, "scan {k}: on without a preceding input"),
                    Some(t_fall) => {
                        let elapsed = t - t_fall;
                        prop_assert!(on || elapsed >= preset_ms, "scan {k}: ended early");
                        prop_assert!(!on || elapsed < preset_ms, "scan {k}: ended late");
                    }
                }
            }
            prev = input;
        }
    }

    #[test]
    fn imp_pulses_exactly_the_preset_not_retriggered(
        t0 in prop_oneof![any::<u32>(), (u32::MAX - 5000)..=u32::MAX],
        preset in 0u16..=60,
        history in scans(),
    ) {
        let preset_ms = u64::from(preset) * 100;
        let rows = run(t0, [0, 0, preset], &history);
        let mut pulse: Option<u64> = None; // start of the running pulse
        let mut prev = false;
        for (k, &(t, input, _, _, on)) in rows.iter().enumerate() {
            if pulse.is_some_and(|t_p| t - t_p >= preset_ms) {
                pulse = None;
            }
            let edge = k > 0 && input && !prev;
            if edge && pulse.is_none() && preset_ms > 0 {
                pulse = Some(t);
            }
            prop_assert_eq!(on, pulse.is_some(), "scan {}: t = {}", k, t);
            if on {
                prop_assert!(t - pulse.unwrap() < preset_ms, "never longer than the preset");
            }
            prev = input;
        }
    }
}

#[test]
fn pulse_length_equals_preset_at_1_ms_scans() {
    let rows = run(
        u32::MAX - 3000,
        [0, 0, 70],
        &(0..10_000)
            .map(|i| Scan {
                dt_ms: 1,
                input: (5..20).contains(&i),
            })
            .collect::<Vec<_>>(),
    );
    let on: Vec<u64> = rows.iter().filter(|r| r.4).map(|r| r.0).collect();
    assert_eq!(on.len(), 7000, "exactly 7 s of 1 ms scans");
    assert_eq!(on[0], 5);
}
