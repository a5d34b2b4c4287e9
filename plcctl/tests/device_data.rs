//! `plcctl` against a fake PLC on a pty that sends absurd but well-formed data: no
//! command may panic on what a device says (`faults` panicked with
//! `DateTime + TimeDelta overflowed` on a huge `uptime_ms`).

use std::io::{Read, Write};
use std::os::fd::OwnedFd;
use std::process::{Command, Output};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use nix::fcntl::{fcntl, FcntlArg, OFlag};
use nix::pty::openpty;
use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::service::{
    encode, Answer, FaultLog, Identity, LogEntry, RefuseReason, Request, ServiceReader,
    SERVICE_VERSION,
};

const PLCCTL: &str = env!("CARGO_BIN_EXE_plcctl");

/// A PLC that answers `Hello`, `Identify` (with `uptime_ms`) and `ReadFaultLog` (one
/// entry of the current power-up, 5 s in) and refuses the rest, until dropped.
struct FakePlc {
    path: String,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl FakePlc {
    fn start(uptime_ms: u64) -> FakePlc {
        let pair = openpty(None, None).unwrap();
        let path = nix::unistd::ttyname(&pair.slave)
            .unwrap()
            .display()
            .to_string();
        let mut t = tcgetattr(&pair.slave).unwrap();
        cfmakeraw(&mut t);
        tcsetattr(&pair.slave, SetArg::TCSANOW, &t).unwrap();
        let master: OwnedFd = pair.master;
        let flags = fcntl(&master, FcntlArg::F_GETFL).unwrap();
        fcntl(
            &master,
            FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
        )
        .unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        // The slave stays open here, so that the master never reads a hang-up between
        // clients.
        let slave = pair.slave;
        let thread = std::thread::spawn(move || {
            let _slave = slave;
            let mut master = std::fs::File::from(master);
            let mut reader = ServiceReader::new();
            let mut buf = [0u8; 256];
            while !s.load(Ordering::Relaxed) {
                // WouldBlock (nothing yet) reads as nothing.
                let n: usize = master.read(&mut buf).unwrap_or_default();
                if n == 0 {
                    std::thread::sleep(Duration::from_millis(1));
                }
                for &b in &buf[..n] {
                    let Some(Ok((id, req))) = reader.push::<Request>(b) else {
                        continue;
                    };
                    let answer = answer(&req, uptime_ms);
                    let mut out = [0u8; MAX_WIRE_FRAME];
                    let len = encode(id, &answer, &mut out).unwrap();
                    let _ = master.write_all(&out[..len]);
                }
            }
        });
        FakePlc {
            path,
            stop,
            thread: Some(thread),
        }
    }

    fn plcctl(&self, args: &[&str]) -> Output {
        let cache = std::env::temp_dir().join(format!("plcctl-fake-{}", std::process::id()));
        Command::new(PLCCTL)
            .env("XDG_CACHE_HOME", cache)
            .args(["--port", &self.path])
            .args(args)
            .output()
            .unwrap()
    }
}

impl Drop for FakePlc {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn answer(req: &Request, uptime_ms: u64) -> Answer {
    match req {
        Request::Hello { .. } => Answer::HelloReply {
            version: SERVICE_VERSION,
        },
        Request::Identify => Answer::Identity(Identity {
            firmware: heapless::String::try_from("0.1.0").unwrap(),
            git: heapless::String::try_from("fake").unwrap(),
            uid: [0xFA; 12],
            power_ups: 1,
            uptime_ms,
        }),
        Request::ReadFaultLog { .. } => {
            let mut entries = heapless::Vec::new();
            entries
                .push(LogEntry {
                    pos: 0,
                    code: 1,
                    power_up: 1,
                    uptime_s: 5,
                    wall_s: None,
                    values: [None, None],
                })
                .unwrap();
            Answer::FaultLog(FaultLog {
                total: 1,
                newest: Some(0),
                entries,
            })
        }
        _ => Answer::Refused(RefuseReason::Locked),
    }
}

#[test]
fn faults_with_an_absurd_uptime_print_the_power_up_time_instead_of_panicking() {
    for uptime_ms in [u64::MAX, i64::MAX as u64, 1 << 62] {
        let plc = FakePlc::start(uptime_ms);
        for args in [&["faults"][..], &["faults", "--json"], &["faults", "--csv"]] {
            let o = plc.plcctl(args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(0), "{args:?} at {uptime_ms}: {err}");
            assert!(!err.contains("panicked"), "{err}");
            let out = String::from_utf8_lossy(&o.stdout);
            assert!(out.contains("power-up #1 + 00:00:05"), "{args:?}: {out}");
        }
    }
}
