//! Writes the lab figures of `hil-sim/docs/lab.md` (the source's Obr 5.1-5.7) into
//! `hil-sim/docs/lab/` and prints the measured values:
//!
//! ```text
//! cargo run --release -p hil-sim --example lab_figures
//! ```
//!
//! Each figure is the standard `hil-sim run --plot` plot of a window of the run (the ramp
//! and reversal figures sampled every 0.25-0.5 ms, the switching-frequency figures every
//! 2 us over two 50 Hz cycles).

use std::path::{Path, PathBuf};

use anyhow::Result;
use hil_sim::lab::{current_ripple, fine_window, first};
use hil_sim::run::{parse_program, run};
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Sample};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn read(rel: &str) -> Result<String> {
    Ok(std::fs::read_to_string(root().join(rel))?)
}

fn samples(program: &str, scenario: &str, duration_s: f64, sample_ms: f64) -> Result<Vec<Sample>> {
    let p = parse_program(&read(program)?, program)?;
    let s = Scenario::parse(&read(scenario)?)?;
    let opts = RunOptions {
        sample_ns: (sample_ms * 1e6).round() as u64,
        ..RunOptions::default()
    };
    Ok(run(
        &p,
        s,
        duration_s,
        opts,
        hil_sim::decimate::KeepSamples::All,
        |_| {},
        |_| {},
    )?
    .samples)
}

fn window(s: &[Sample], from_s: f64, to_s: f64) -> Vec<Sample> {
    s.iter()
        .filter(|x| (from_s..=to_s).contains(&(x.t_ns as f64 * 1e-9)))
        .cloned()
        .collect()
}

fn figure(name: &str, s: &[Sample], title: &str) -> Result<()> {
    let dir = root().join("hil-sim/docs/lab");
    std::fs::create_dir_all(&dir)?;
    let path = dir.join(name);
    hil_sim::plot::plot(&path, s, title, &hil_sim::plot::Marks::default())?;
    shrink(&path)
}

/// Re-encodes a plot as an 8-bit palette PNG with the best compression: the 256 most
/// frequent colours (lines, grid, background), every other pixel (anti-aliased text
/// edges) mapped to the nearest of them. The docs' figures shrink several times.
fn shrink(path: &Path) -> Result<()> {
    use std::collections::HashMap;
    let decoder = png::Decoder::new(std::fs::File::open(path)?);
    let mut reader = decoder.read_info()?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf)?;
    let bpp = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        _ => return Ok(()),
    };
    let px = &buf[..info.buffer_size()];
    let mut count: HashMap<[u8; 3], u32> = HashMap::new();
    for p in px.chunks(bpp) {
        *count.entry([p[0], p[1], p[2]]).or_default() += 1;
    }
    let mut by_freq: Vec<([u8; 3], u32)> = count.into_iter().collect();
    by_freq.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let palette: Vec<[u8; 3]> = by_freq.iter().take(256).map(|(c, _)| *c).collect();
    let mut map: HashMap<[u8; 3], u8> = HashMap::new();
    for (k, c) in palette.iter().enumerate() {
        map.insert(*c, k as u8);
    }
    let nearest = |c: [u8; 3]| -> u8 {
        let d = |p: &[u8; 3]| {
            (0..3)
                .map(|i| (i32::from(p[i]) - i32::from(c[i])).pow(2))
                .sum::<i32>()
        };
        (0..palette.len())
            .min_by_key(|&k| d(&palette[k]))
            .unwrap_or(0) as u8
    };
    let mut index = Vec::with_capacity(px.len() / bpp);
    for p in px.chunks(bpp) {
        let c = [p[0], p[1], p[2]];
        let k = match map.get(&c) {
            Some(k) => *k,
            None => {
                let k = nearest(c);
                map.insert(c, k);
                k
            }
        };
        index.push(k);
    }
    let mut enc = png::Encoder::new(
        std::io::BufWriter::new(std::fs::File::create(path)?),
        info.width,
        info.height,
    );
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(palette.concat());
    enc.set_compression(png::Compression::Best);
    enc.set_filter(png::FilterType::NoFilter);
    enc.write_header()?.write_image_data(&index)?;
    Ok(())
}

fn main() -> Result<()> {
    println!("| figure | source | measured |");
    println!("| --- | --- | --- |");

    let s = samples(
        "shared-protocol/programs/lab_5_1_runup.plc",
        "hil-sim/scenarios/lab_5_1_runup.toml",
        5.0,
        0.25,
    )?;
    let t6 = first(&s, 0.0, |x| x.pwm_on).unwrap_or(f64::NAN);
    let t20 = first(&s, t6, |x| x.f_cmd_hz >= 20.0).unwrap_or(f64::NAN);
    println!("| Obr 5.1 | run-up 6 -> 20 Hz in 2 s | {:.3} s |", t20 - t6);
    figure(
        "obr_5_1_runup.png",
        &window(&s, 0.5, 5.0),
        "Obr 5.1: run-up 6 -> 20 Hz in 2 s (lab_5_1_runup.plc)",
    )?;

    let s = samples(
        "shared-protocol/programs/motor.plc",
        "hil-sim/scenarios/lab_5_2_reversal.toml",
        22.0,
        0.5,
    )?;
    let flip = first(&s, 8.0, |x| x.dir == -1).unwrap_or(f64::NAN);
    println!("| Obr 5.2 | current and line voltage through a reversal | REV at 8.0 s, phases swapped at {flip:.3} s (turning point, outputs off below fmn), reversed run-up |");
    figure(
        "obr_5_2_reversal.png",
        &window(&s, 5.0, 22.0),
        "Obr 5.2: reversal, motor example at 30 Hz, REV at 8 s (motor.plc)",
    )?;
    figure(
        "obr_5_2_reversal_detail.png",
        &window(&s, 14.5, 17.5),
        "Obr 5.2: the turning point and the reversed start (motor.plc)",
    )?;

    let s = samples(
        "shared-protocol/programs/lab_5_3_rundown_runup.plc",
        "hil-sim/scenarios/lab_5_3_rundown_runup.toml",
        16.0,
        0.5,
    )?;
    let at20 = first(&s, 0.0, |x| x.f_cmd_hz >= 20.0).unwrap_or(f64::NAN);
    let down = first(&s, at20, |x| x.f_cmd_hz < 20.0).unwrap_or(f64::NAN);
    let at6 = first(&s, down, |x| x.f_cmd_hz <= 6.0).unwrap_or(f64::NAN);
    let up = first(&s, at6, |x| x.f_cmd_hz > 6.0).unwrap_or(f64::NAN);
    let at50 = first(&s, up, |x| x.f_cmd_hz >= 50.0).unwrap_or(f64::NAN);
    println!(
        "| Obr 5.3 | run-down 20 -> 6 Hz in 5 s | {:.3} s |",
        at6 - down
    );
    println!(
        "| Obr 5.3 | run-up 6 -> 50 Hz in 4 s | {:.3} s |",
        at50 - up
    );
    figure(
        "obr_5_3_rundown_runup.png",
        &window(&s, 4.5, 16.0),
        "Obr 5.3: run-down 20 -> 6 Hz in 5 s, run-up 6 -> 50 Hz in 4 s (lab_5_3_rundown_runup.plc)",
    )?;

    let prog = read("shared-protocol/programs/lab_5_4_switching.plc")?;
    let mut last: Option<(f64, f64)> = None;
    for (n, hz) in [(4, 9990.0), (5, 5000.0), (6, 2500.0), (7, 1250.0)] {
        let scen = read(&format!("hil-sim/scenarios/lab_5_4_switching_{hz}hz.toml"))?;
        let w = fine_window(&prog, &scen, 2.9, 0.04, 2.0)?;
        let r = current_ripple(&w, 0, hz);
        let ratio = last.map_or(String::from("-"), |(f_hi, rms_hi)| {
            format!(
                "{:.3} x the {f_hi} Hz value (1/f_sw: {:.3} x)",
                r.rms_a / rms_hi,
                f_hi / hz
            )
        });
        println!(
            "| Obr 5.{n} | current and voltage at f_sw = {hz} Hz | ripple {:.2} mA rms, {:.1} mA p-p per period; {ratio} |",
            r.rms_a * 1e3,
            r.pp_a * 1e3
        );
        last = Some((hz, r.rms_a));
        figure(
            &format!("obr_5_{n}_{hz}hz.png"),
            &w,
            &format!("Obr 5.{n}: 50 Hz, switching at {hz} Hz, two cycles (lab_5_4_switching.plc)"),
        )?;
    }
    Ok(())
}
