//! Quality report of the modulator: frequency accuracy, THD of the
//! PWM-period-averaged phase voltage next to the source's method, and host cost per call.
//!
//! `cargo bench -p firmware-drive --bench quality`

use std::f64::consts::TAU;
use std::hint::black_box;
use std::time::Instant;

use firmware_drive::{AdcSample, DriveCommand, DriveConfig, DriveCore, ResetCause};
use shared_protocol::program::assemble;

const PWM_HZ: u16 = 16_000;

/// Three-phase sine at f = Q01 (0.1 Hz), A = fjm (m = 1.0), PWF from Q00 (a K constant
/// has 4 digits, so 16 kHz comes from a Q).
const PROGRAM: &str = "000 PWF Q00\n001 LD Q01\n002 LD K01 0500\n003 LD K02 0000\n004 SN1\n\
    005 LD K03 1200\n006 SN2\n007 LD K04 2400\n008 SN3\n";

fn sample() -> AdcSample {
    AdcSample {
        u_dc: 2730,
        ..AdcSample::default()
    }
}

/// A core running the sine program at `f_dhz`, one 1 ms tick done.
fn running_core(f_dhz: i16) -> DriveCore {
    let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
    core.tick_1ms(&mut |_| {});
    let p = assemble(PROGRAM).expect("assembles").drive_section();
    core.load_program(&p).expect("verifies");
    core.command(DriveCommand::SetQ {
        addr: 0,
        value: PWM_HZ as i16,
    })
    .expect("q");
    core.command(DriveCommand::SetQ {
        addr: 1,
        value: f_dhz,
    })
    .expect("q");
    core.command(DriveCommand::Run).expect("run");
    core.tick_1ms(&mut |_| {});
    core
}

/// Seconds per PWM period as the timer really counts (perfect crystal).
fn t_pwm(core: &DriveCore) -> f64 {
    let t = core.pwm_timing();
    2.0 * f64::from(t.arr) * (f64::from(t.psc) + 1.0) / f64::from(core.config().timer_clock_hz)
}

fn frequency_accuracy() {
    println!("## Frequency accuracy over 10 s (16 kHz PWM, 170 MHz timer clock)");
    println!(
        "| f set | PWM periods | zero crossings | f from crossings | f from accumulated phase | relative error | source method |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for f_dhz in [5i16, 500, 800, 4000] {
        let mut core = running_core(f_dhz);
        let tp = t_pwm(&core);
        let periods = (10.0 / tp).round() as u64;
        let elapsed = periods as f64 * tp;
        let step = core.modulator().params().step;
        let n = core.pwm_timing().arr;
        let s = sample();
        // Upward zero crossings of phase 1, timed by linear interpolation between periods.
        let mut crossings: Vec<f64> = Vec::new();
        let mut prev = 0i32;
        for k in 0..periods {
            let c = core.pwm_period(&s);
            let v = 2 * i32::from(c.duty[0]) - i32::from(n);
            if prev < 0 && v >= 0 {
                let frac = f64::from(-prev) / f64::from(v - prev);
                crossings.push((k as f64 - 1.0 + frac) * tp);
            }
            prev = v;
        }
        let f_zc = match (crossings.first(), crossings.last()) {
            (Some(a), Some(b)) if crossings.len() > 1 => (crossings.len() - 1) as f64 / (b - a),
            _ => f64::NAN,
        };
        let cycles = step as f64 * periods as f64 / 2f64.powi(64);
        let f_meas = cycles / elapsed;
        let f_set = f64::from(f_dhz) / 10.0;
        // The source: pointer += f (0.1 Hz) at 800 Hz, wrapped at 7999 -> 800 f / 7999;
        // f limited to 0.1..80.0 Hz.
        let source = if f_dhz <= 800 {
            let f_src = 800.0 * f64::from(f_dhz) / 7999.0;
            format!("{f_src:.6} Hz ({:+.0} ppm)", (f_src / f_set - 1.0) * 1e6)
        } else {
            "n/a (max 80 Hz)".to_string()
        };
        println!(
            "| {f_set} Hz | {periods} | {} | {f_zc:.6} Hz | {f_meas:.9} Hz | {:+.1e} | {source} |",
            crossings.len(),
            f_meas / f_set - 1.0
        );
    }
    println!();
}

/// Amplitude of the component at `f` Hz in `x` sampled at `fs`, Hann window (sidelobes
/// 50 bins away are below -100 dB, so a record that is not a whole number of cycles does
/// not leak the fundamental into the harmonics).
fn amplitude(x: &[f64], fs: f64, f: f64) -> f64 {
    let n = x.len() as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let w = 0.5 - 0.5 * (TAU * k as f64 / n).cos();
        let a = TAU * f * k as f64 / fs;
        re += w * v * a.cos();
        im -= w * v * a.sin();
    }
    (re * re + im * im).sqrt() * 4.0 / n
}

/// THD (harmonics 2..=40) of `x` with fundamental `f1`.
fn thd(x: &[f64], fs: f64, f1: f64) -> (f64, f64) {
    let a1 = amplitude(x, fs, f1);
    let h: f64 = (2..=40)
        .map(|k| amplitude(x, fs, f1 * f64::from(k)).powi(2))
        .sum();
    (a1, h.sqrt() / a1)
}

fn thd_report() {
    println!("## THD of the PWM-period-averaged phase voltage, 50 Hz, m = 1.0, 16 kHz PWM, 1 s");
    // This project: the core end to end, duty/N per period (counts, after the clamp).
    let mut core = running_core(500);
    let tp = t_pwm(&core);
    let fs = 1.0 / tp;
    let n = f64::from(core.pwm_timing().arr);
    let f_out = core.modulator().params().step as f64 / 2f64.powi(64) * fs;
    let len = fs.round() as usize;
    let s = sample();
    let ours: Vec<f64> = (0..len)
        .map(|_| f64::from(core.pwm_period(&s).duty[0]) / n - 0.5)
        .collect();
    let (a1, t) = thd(&ours, fs, f_out);
    println!("| method | fundamental (of U_dc) | THD 2-40 |");
    println!("| --- | --- | --- |");
    println!(
        "| this core: 64-bit accumulator, 1024-pt table + interpolation, every PWM period, N = {n} | {a1:.5} | {:.4} % |",
        t * 100.0
    );
    // The source: 1000-entry table of one period, a pointer into an imaginary 8000-entry
    // table advanced by f (0.1 Hz) every 800 Hz interrupt, wrapped by subtracting 7999
    // (as the source text says), read at pointer/8; the PWM keeps the value until the next
    // interrupt (zero-order hold). Same duty quantisation (N counts) as above.
    let table: Vec<f64> = (0..1000).map(|i| (TAU * i as f64 / 1000.0).sin()).collect();
    let f_dhz = 500u32;
    let mut ptr = 0u32;
    let mut held = 0.0;
    let mut next_update = 0.0;
    let src: Vec<f64> = (0..len)
        .map(|k| {
            let t = k as f64 * tp;
            while t >= next_update {
                held = table[(ptr >> 3) as usize];
                ptr += f_dhz;
                if ptr > 7999 {
                    ptr -= 7999;
                }
                next_update += 1.0 / 800.0;
            }
            ((0.5 + 0.5 * held) * n).round() / n - 0.5
        })
        .collect();
    // Its real fundamental: 800 Hz * f / 7999 per pointer turn.
    let f_src = 800.0 * f64::from(f_dhz) / 7999.0;
    let (a1s, ts) = thd(&src, fs, f_src);
    println!(
        "| source: 1000-entry table, 800 Hz update, zero-order hold, 0.1 Hz steps ({f_src:.4} Hz) | {a1s:.5} | {:.3} % |",
        ts * 100.0
    );
    println!();
}

/// Three-phase sine at 50 Hz with amplitude A = Q02 against fjm 50.0 Hz: m = Q02 / 500.
const M_PROGRAM: &str = "000 PWF Q00\n001 LD K00 0500\n002 LD Q02\n003 LD K02 0000\n004 SN1\n\
    005 LD K03 1200\n006 SN2\n007 LD K04 2400\n008 SN3\n009 fjm K05 0500\n";

/// Fundamental of the PWM-period-averaged line voltage u_12 = (d1 - d2) / N * U_dc, in
/// units of U_dc, with the requested modulation index `m_permille` (end to end through
/// the core: program, tick, modulator, clipping, dead-time-safe clamp).
fn line_fundamental(m_permille: i16, injection: bool) -> f64 {
    let cfg = DriveConfig {
        min_max_injection: injection,
        ..DriveConfig::default()
    };
    let mut core = DriveCore::new(cfg, ResetCause::PowerOn);
    core.tick_1ms(&mut |_| {});
    let p = assemble(M_PROGRAM).expect("assembles").drive_section();
    core.load_program(&p).expect("verifies");
    for (addr, value) in [(0, PWM_HZ as i16), (2, m_permille / 2)] {
        core.command(DriveCommand::SetQ { addr, value }).expect("q");
    }
    core.command(DriveCommand::Run).expect("run");
    core.tick_1ms(&mut |_| {});
    let tp = t_pwm(&core);
    let fs = 1.0 / tp;
    let n = f64::from(core.pwm_timing().arr);
    let f_out = core.modulator().params().step as f64 / 2f64.powi(64) * fs;
    let s = sample();
    let x: Vec<f64> = (0..fs.round() as usize)
        .map(|_| {
            let d = core.pwm_period(&s).duty;
            (f64::from(d[0]) - f64::from(d[1])) / n
        })
        .collect();
    amplitude(&x, fs, f_out)
}

fn overmodulation_report() {
    println!("## Fundamental line voltage against the requested m (50 Hz, 16 kHz PWM, end to end)");
    println!("Line voltage fundamental (peak) in units of U_dc, and in V at U_dc = 30 V.");
    println!("Linear theory: sqrt(3)/2 m; six-step limit 2 sqrt(3)/pi = 1.1027 U_dc.");
    println!();
    println!("| m requested | sine PWM (of U_dc) | / value at m = 1.0 | at 30 V | min-max injection (of U_dc) | linear theory |");
    println!("| --- | --- | --- | --- | --- | --- |");
    let at_one = line_fundamental(1000, false);
    for k in 5..=15 {
        let m = k * 100;
        let sine = line_fundamental(m, false);
        let mm = line_fundamental(m, true);
        println!(
            "| {:.1} | {sine:.4} | {:.3} | {:.2} V | {mm:.4} | {:.4} |",
            f64::from(m) / 1000.0,
            sine / at_one,
            sine * 30.0,
            3f64.sqrt() / 2.0 * f64::from(m) / 1000.0
        );
    }
    // The motor example at 70 Hz: A = f = 700 against fjm 500 plus its IR boost
    // (Rs 1.95, Uc 30, Iz 0.50: dU = 67), m = 1.4 + 67/1023.
    let m70 = 1400 + (67_000 + 511) / 1023;
    let v70 = line_fundamental(m70 as i16, false);
    println!();
    println!(
        "Motor example at 70 Hz (m = {:.3}): {v70:.4} U_dc = {:.3} x the value at m = 1.0 \
         (the old cap at m = 1.0 gave 1.000 x); six-step would be {:.3} x.",
        f64::from(m70) / 1000.0,
        v70 / at_one,
        2.0 * 3f64.sqrt() / std::f64::consts::PI / at_one
    );
    println!();
}

fn cost_report() {
    println!("## Host cost per call (release build, this machine)");
    let mut core = running_core(500);
    let s = sample();
    let calls = 20_000_000u32;
    let start = Instant::now();
    let mut acc = 0u32;
    for _ in 0..calls {
        let c = core.pwm_period(black_box(&s));
        acc = acc.wrapping_add(u32::from(c.duty[0]));
    }
    let per = start.elapsed().as_secs_f64() * 1e9 / f64::from(calls);
    black_box(acc);
    println!("- DriveCore::pwm_period (trip checks + modulator): {per:.2} ns/call");
    let mut m = core.modulator().clone();
    let n = core.pwm_timing().arr;
    let start = Instant::now();
    for _ in 0..calls {
        let d = m.step(black_box(n));
        acc = acc.wrapping_add(u32::from(d[1]));
    }
    let per = start.elapsed().as_secs_f64() * 1e9 / f64::from(calls);
    black_box(acc);
    println!("- Modulator::step alone: {per:.2} ns/call");
    let start = Instant::now();
    let ticks = 200_000u32;
    for _ in 0..ticks {
        core.tick_1ms(&mut |e| {
            black_box(e);
        });
    }
    let per = start.elapsed().as_secs_f64() * 1e9 / f64::from(ticks);
    println!("- DriveCore::tick_1ms (9-line sine program): {per:.0} ns/call");
}

fn main() {
    // `cargo test --benches` runs this too: keep it quick there.
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    frequency_accuracy();
    thd_report();
    overmodulation_report();
    cost_report();
}
