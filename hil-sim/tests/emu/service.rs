//! The service port of the real PLC image (service.md 1, issue 18): `plcctl status`, the
//! host tool's binary, through a real pty whose other end is the emulated LPUART1 (PA2/PA3)
//! of the exact release PLC image, with the drive image on the link.
//!
//! plcctl is built here like the images (`cargo build --release -p plcctl`, a no-op when
//! it is up to date): `cargo test -p hil-sim --test emu` alone exercises what users run.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use hil_sim::emu::images::target_dir;
use hil_sim::service::pty::Pty;

use crate::common::{assert_stack_headroom, emu, ns, MOTOR_PLC, MOTOR_TOML};

/// The release plcctl of this workspace, built if needed.
fn plcctl() -> &'static PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
        let status = Command::new(cargo)
            .current_dir(&root)
            .args(["build", "--release", "-p", "plcctl", "--bin", "plcctl"])
            .status()
            .expect("cargo runs");
        assert!(status.success(), "cargo build --release -p plcctl failed");
        target_dir()
            .join("release")
            .join(format!("plcctl{}", std::env::consts::EXE_SUFFIX))
    })
}

#[test]
fn plcctl_status_answers_through_the_emulated_lpuart1() {
    let mut sim = emu(MOTOR_PLC, MOTOR_TOML);
    // Power-up, the program's download to the drive, RUN.
    sim.run_until(ns(1.0), |_| {});
    let mut pty = Pty::open().expect("a pty");
    let mut child = Command::new(plcctl())
        .env(
            "XDG_CACHE_HOME",
            std::env::temp_dir().join("emu-plcctl-cache"),
        )
        .args(["--port", pty.path().to_str().unwrap(), "status"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("plcctl starts");
    // The pty's bytes to and from the emulated LPUART1, virtual time never ahead of the
    // wall clock (plcctl's retries are wall-clock times).
    let wall0 = Instant::now();
    let virt0 = sim.now_ns();
    let deadline = wall0 + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "plcctl did not finish in 60 s");
        let bytes = pty.read_available();
        sim.service_write(&bytes);
        let end = sim.now_ns() + 500_000;
        sim.run_until(end, |_| {});
        pty.write(&sim.service_read());
        let ahead = Duration::from_nanos(sim.now_ns() - virt0).saturating_sub(wall0.elapsed());
        std::thread::sleep(ahead);
    };
    let mut out = String::new();
    let mut err = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(status.success(), "plcctl status: {status}\n{out}\n{err}");
    assert_eq!(sim.service_lost(), 0, "no host byte lost");
    // The image's own version and identity, the program's slot, RUN with the link up.
    let version = env!("CARGO_PKG_VERSION");
    assert!(
        out.starts_with(&format!("firmware {version} (")),
        "first line: {out}"
    );
    assert!(out.contains("PLC RUN"), "{out}");
    assert!(out.contains("link up"), "{out}");
    assert!(out.contains("slot 1"), "{out}");
    assert!(out.contains("drive RUN"), "{out}");
    assert_stack_headroom(&sim);
}
