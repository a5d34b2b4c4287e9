//! `hil-sim emu` as a process: its exit status when an image fails.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::images;

fn repo(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(p)
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hil-sim-emu-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

/// The release drive image with its reset and HardFault vectors pointing at unmapped
/// memory: the first instruction fetch faults, the HardFault entry faults again, and the
/// core locks up (the watchdog has not been started).
fn locking_drive_image() -> PathBuf {
    let (drive, _) = images();
    let mut elf = std::fs::read(drive).expect("drive ELF");
    let image = g431_emu::elf::Image::from_bytes(elf.clone()).expect("parses");
    // The vector table's first 64 bytes occur once in the file: where it is stored.
    let table = &image.flash[..64];
    let at = elf
        .windows(table.len())
        .position(|w| w == table)
        .expect("the vector table is in the file");
    const UNMAPPED: u32 = 0x0900_0001;
    for word in [1, 3] {
        let o = at + 4 * word;
        elf[o..o + 4].copy_from_slice(&UNMAPPED.to_le_bytes());
    }
    let path = tmp("locking-drive.elf");
    std::fs::write(&path, elf).expect("write the patched image");
    path
}

fn emu(drive: &Path, name: &str, scenario: &str) -> Output {
    let (_, plc) = images();
    let scen = tmp(&format!("{name}.toml"));
    std::fs::write(&scen, scenario).expect("scenario");
    Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .arg("emu")
        .arg(repo("shared-protocol/programs/motor.plc"))
        .arg("--scenario")
        .arg(&scen)
        .args(["--duration", "0.05"])
        .arg("--drive-elf")
        .arg(drive)
        .arg("--plc-elf")
        .arg(plc)
        .output()
        .expect("hil-sim runs")
}

/// `emu` exits with status 2 when an image locks up (or takes a HardFault, or is
/// reset by its watchdog or by itself) unless the scenario expects it; the summary is
/// printed either way.
#[test]
fn emu_exits_2_when_an_image_fails_unless_the_scenario_expects_it() {
    let drive = locking_drive_image();
    let out = emu(&drive, "plain", "duration_s = 0.05\n");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(2),
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    assert!(stdout.contains("LOCKUP"), "{stdout}");
    assert!(
        stderr.contains("drive:") && stderr.contains("\"lockup\""),
        "{stderr}"
    );

    let out = emu(
        &drive,
        "expecting",
        "[emu]\nexpect = [\"hard_fault\", \"lockup\"]\n",
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
