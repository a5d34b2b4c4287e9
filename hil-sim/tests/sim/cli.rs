//! The command line as users script it (hil-sim.md "Commands").

use std::path::PathBuf;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hil-sim"))
}

fn repo(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(p)
}

/// `hil-sim run` of the source's motor program under `scenarios/motor.toml`.
fn run_motor(duration_s: &str, sample_ms: &str) -> Command {
    let mut c = bin();
    c.arg("run")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .arg("--scenario")
        .arg(repo("hil-sim/scenarios/motor.toml"))
        .args(["--duration", duration_s, "--sample-ms", sample_ms]);
    c
}

/// Exit 0, else the command's stderr.
fn assert_success(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hil-sim-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn run_writes_csv_and_plot_and_prints_a_summary() {
    let csv = tmp("motor.csv");
    let png = tmp("motor.png");
    let out = run_motor("2", "10")
        .arg("--csv")
        .arg(&csv)
        .arg("--plot")
        .arg(&png)
        .output()
        .unwrap();
    assert_success(&out);
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("simulated 2.000 s"), "{stdout}");
    assert!(stdout.contains("faults: none"), "{stdout}");
    // The board it simulated: motor.toml asks for the source's rig (the default is the
    // bare ESC1).
    assert!(
        stdout.contains("drive board: source sensors on B-G431B-ESC1 pins\n"),
        "{stdout}"
    );
    assert!(stdout.contains("|1:   500   2:  9800 |"), "{stdout}");
    // No progress on stderr when it is not a terminal.
    assert!(out.stderr.is_empty());
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().count(), 2 + 201);
    assert!(text.starts_with(
        "# board: source sensors on B-G431B-ESC1 pins\nt_s,f_cmd_hz,dir,m,pwm_on,fault,u_dc_v,"
    ));
    let png = std::fs::read(&png).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn a_trip_still_exits_zero() {
    let scen = tmp("locked.toml");
    std::fs::write(
        &scen,
        "[plant]\nlocked_rotor = true\noc_hw_a = 1.0\n[[event]]\nat_s = 0\nset = { A01 = 500, A00 = 980 }\n[[event]]\nat_s = 0.1\npress = \"D00\"\n",
    )
    .unwrap();
    let out = bin()
        .arg("run")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .arg("--scenario")
        .arg(&scen)
        .args(["--duration", "2"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("2 OC_HW"), "{stdout}");
}

#[test]
fn invalid_program_or_scenario_fails_before_simulating() {
    let bad_prog = tmp("bad.plc");
    std::fs::write(&bad_prog, "150 LD D16\n").unwrap();
    let csv = tmp("never.csv");
    let out = bin()
        .arg("run")
        .arg(&bad_prog)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("bad.plc:1:"), "{err}");
    assert!(err.contains("D16"), "{err}");
    assert!(!csv.exists());

    let bad_scen = tmp("bad.toml");
    std::fs::write(&bad_scen, "[plant]\ndc_link = 30\n").unwrap();
    let out = bin()
        .arg("run")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .arg("--scenario")
        .arg(&bad_scen)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("dc_link"), "{err}");
    assert!(out.stdout.is_empty());
}

#[test]
fn asm_writes_the_eeprom_image_and_disasm_reads_it_back() {
    let img = tmp("motor.bin");
    let out = bin()
        .arg("asm")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .arg("-o")
        .arg(&img)
        .output()
        .unwrap();
    assert_success(&out);
    assert_eq!(std::fs::metadata(&img).unwrap().len(), 32768);
    let from_text = bin()
        .arg("disasm")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .output()
        .unwrap();
    let from_image = bin().arg("disasm").arg(&img).output().unwrap();
    assert!(from_text.status.success() && from_image.status.success());
    assert_eq!(from_text.stdout, from_image.stdout);
    let text = String::from_utf8(from_text.stdout).unwrap();
    assert!(text.contains("025 FRV K20 0200"), "{text}");

    let bad = tmp("bad2.plc");
    std::fs::write(&bad, "000 LD D00\n").unwrap();
    let out = bin().arg("asm").arg(&bad).output().unwrap();
    assert!(!out.status.success());
}

#[test]
fn a_drive_stack_underflow_is_refused_with_its_text_line() {
    // SN1 needs frequency, amplitude and phase: with two values the motor would never
    // turn.
    let bad = tmp("sn1.plc");
    std::fs::write(
        &bad,
        "; two values only\n000 LD K00 0500\n001 LD K01 0000\n002 SN1\n",
    )
    .unwrap();
    for cmd in ["run", "asm"] {
        let out = bin().arg(cmd).arg(&bad).output().unwrap();
        assert!(!out.status.success(), "{cmd}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(
            err.contains("sn1.plc:4:5: SN1 needs 3 values on the stack, only 2 loaded"),
            "{err}"
        );
    }
    // disasm prints it (to fix it), but says that the PLC would refuse it.
    let out = bin().arg("disasm").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("002 SN1"));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the PLC would refuse this program"));
}

/// Without a terminal (piped stdin, CI, ssh without -t) the panel exits 1 with
/// one clear line instead of panicking inside ratatui (exit 101).
#[test]
fn the_panel_without_a_terminal_exits_1_with_one_line() {
    let out = bin()
        .arg("panel")
        .stdin(std::process::Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("interactive terminal"), "{err}");
}

/// `panel --eeprom FILE` refuses a file that is not a 32 KiB 24C256 image with
/// one line and exit 1, before anything else, and leaves the file as it was.
#[test]
fn the_panel_refuses_an_eeprom_file_of_the_wrong_size_and_leaves_it_alone() {
    let f = tmp("short-eeprom.bin");
    std::fs::write(&f, [0u8; 1000]).unwrap();
    let out = bin()
        .arg("panel")
        .arg("--eeprom")
        .arg(&f)
        .stdin(std::process::Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("1000 bytes, not a 24C256 image (32768 bytes"),
        "{err}"
    );
    assert_eq!(std::fs::read(&f).unwrap(), vec![0u8; 1000]);
}

/// A sampling period below the simulation's 1 us step is refused before the run
/// (0.0001 ms once wrote 1.18 GB for one simulated second), and so is a plot format that
/// cannot be written; neither leaves a file behind.
#[test]
fn a_too_fine_sampling_or_an_unknown_plot_format_is_refused_before_the_run() {
    let csv = tmp("fine.csv");
    let out = bin()
        .arg("run")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .args(["--duration", "1", "--sample-ms", "0.0001"])
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("--sample-ms must be at least 0.001"), "{err}");
    assert!(!csv.exists());

    let jpg = tmp("motor.jpg");
    let out = bin()
        .arg("run")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .args(["--duration", "1"])
        .arg("--plot")
        .arg(&jpg)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("use a .png or .svg"), "{err}");
    assert!(!jpg.exists());
    assert!(out.stdout.is_empty(), "nothing simulated");
}

/// `--plot x.svg` writes an SVG, complete (no `.partial` left), and the summary.
#[test]
fn an_svg_plot_is_written_complete_with_the_summary() {
    let svg = tmp("motor.svg");
    let out = run_motor("1", "5")
        .arg("--plot")
        .arg(&svg)
        .output()
        .unwrap();
    assert_success(&out);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        text.starts_with("<svg") || text.starts_with("<?xml"),
        "{}",
        &text[..80.min(text.len())]
    );
    assert!(text.trim_end().ends_with("</svg>"));
    assert!(
        text.contains("phase currents [A]: i_a (red)"),
        "captions name the traces"
    );
    assert!(!tmp("motor.partial.svg").exists());
    // Limits, events and the zoom.
    let has = |a: &str, b: &str| text.contains(a) || text.contains(b);
    assert!(
        has("dashed: I&gt; 2.0, OC_HW", "dashed: I> 2.0, OC_HW"),
        "current limits"
    );
    assert!(has("U&gt; 35.0", "U> 35.0"), "DC-link limits");
    assert!(text.contains("D00=1"), "START marked");
    assert!(text.contains("zoom "), "phase-current zoom");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("simulated"), "{stdout}");
    assert!(stdout.contains("peaks: phase current"), "{stdout}");
    assert!(
        stdout.contains("drive states: ") && stdout.contains(" RUN"),
        "{stdout}"
    );
}

/// An EEPROM image that the PLC would refuse (a PLC instruction in the
/// drive section) is refused by `run` and `asm`, and `disasm` prints it but says so and
/// exits non-zero.
#[test]
fn an_image_the_plc_would_refuse_is_reported_by_every_command() {
    use shared_protocol::program::{Instruction, Mnemonic, Program};
    let mut p = Program::default();
    p.lines[0] = Some(Instruction {
        mnemonic: Mnemonic::Not,
        operand: None,
        constant: 0,
    });
    let img = tmp("refused.bin");
    std::fs::write(&img, hil_sim::image_bytes(&p).unwrap()).unwrap();
    for cmd in ["run", "asm", "disasm"] {
        let out = bin().arg(cmd).arg(&img).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("NOT") && err.contains("drive section"),
            "{cmd}: {err}"
        );
    }
    // disasm still shows the program, so that it can be fixed.
    let out = bin().arg("disasm").arg(&img).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("000 NOT"));
}

/// NaN, infinity and huge numbers are refused with a message naming the option
/// (exit 1), never a panic (`--service-linger 1e20` panicked converting to a Duration).
#[test]
fn bad_numbers_on_the_command_line_are_refused_without_a_panic() {
    let motor = repo("shared-protocol/programs/motor.plc");
    for args in [
        &["--service-pty", "--service-linger", "1e20"][..],
        &["--service-pty", "--service-linger", "nan"],
        &["--duration", "nan"],
        &["--duration", "inf"],
        &["--duration", "1e20"],
        &["--zoom-at", "nan"],
        &["--sample-ms", "1e9"],
        &["--sample-ms", "nan"],
    ] {
        let out = bin().arg("run").arg(&motor).args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("invalid value") && err.contains(args[args.len() - 2]),
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// Plant values outside physics are refused, naming the key and its
/// range, before anything runs; a failed run leaves the user's CSV as it was.
#[test]
fn scenario_values_outside_physics_are_refused_and_the_csv_is_kept() {
    let csv = tmp("keep.csv");
    std::fs::write(&csv, "mine\n").unwrap();
    for (toml, key) in [
        ("[plant]\nfriction_nms = 100.0\n", "plant.friction_nms"),
        ("[plant]\ndc_link_v = 1e8\n", "plant.dc_link_v"),
        ("[lift]\nlimit_high_mm = inf\n", "lift.limit_high_mm"),
        ("[lift]\nunbalance_kg = 1e30\n", "lift.unbalance_kg"),
    ] {
        let scen = tmp("physics.toml");
        std::fs::write(&scen, toml).unwrap();
        let out = bin()
            .arg("run")
            .arg(repo("shared-protocol/programs/motor.plc"))
            .arg("--scenario")
            .arg(&scen)
            .arg("--csv")
            .arg(&csv)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{toml}: {err}");
        assert!(err.contains(key) && err.contains("physical range"), "{err}");
        assert_eq!(std::fs::read_to_string(&csv).unwrap(), "mine\n");
    }
}

/// A plant that diverges stops the simulation at the first 1 ms check
/// (`model unstable`), before the drive's tick could latch a trip from it.
#[test]
fn a_diverging_plant_is_caught_before_any_trip() {
    use hil_sim::scenario::Scenario;
    use hil_sim::sim::{RunOptions, Simulation};
    let program = hil_sim::run::load_program(&repo("shared-protocol/programs/motor.plc")).unwrap();
    let scen =
        Scenario::parse(&std::fs::read_to_string(repo("hil-sim/scenarios/motor.toml")).unwrap())
            .unwrap();
    let mut sim = Simulation::new(&program, scen, RunOptions::default()).unwrap();
    sim.run_until(500_000_000, |_| {});
    assert_eq!(sim.unstable_at_ns(), None, "a valid run stays in physics");
    // What the scenario's ranges now refuse: the explicit integrator cannot follow it.
    sim.plant_mut().params_mut().motor.friction_nms = 100.0;
    sim.plant_mut().params_mut().supply_v = 1e8;
    let faults_before = sim.faults().len();
    sim.run_until(2_000_000_000, |_| {});
    let at = sim.unstable_at_ns().expect("model unstable");
    assert!(at > 500_000_000 && at <= 2_000_000_000, "{at}");
    assert_eq!(
        sim.faults().len(),
        faults_before,
        "the divergence was reported as a trip"
    );
}
