//! Why a command failed, and its exit code (service.md 8).

use shared_protocol::service::RefuseReason;

/// A failure with its exit code.
#[derive(Debug)]
pub enum Fail {
    /// 1: usage, bad file, assembler or verifier error, confirmation refused.
    Usage(anyhow::Error),
    /// 2: no device found, several candidates, or the port cannot be opened.
    NoDevice(String),
    /// 3: no valid answer after 3 attempts.
    Timeout(String),
    /// 4: service version mismatch.
    Version { host: u16, plc: u16 },
    /// 5: refused by the PLC.
    Refused(RefuseReason),
    /// 6: `push` read back something else than it wrote.
    ReadBack(String),
}

impl Fail {
    pub fn exit_code(&self) -> u8 {
        match self {
            Fail::Usage(_) => 1,
            Fail::NoDevice(_) => 2,
            Fail::Timeout(_) => 3,
            Fail::Version { .. } => 4,
            Fail::Refused(_) => 5,
            Fail::ReadBack(_) => 6,
        }
    }
}

impl std::fmt::Display for Fail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Fail::Usage(e) => write!(f, "{e:#}"),
            Fail::NoDevice(m) => write!(f, "no device: {m}"),
            Fail::Timeout(m) => write!(f, "timeout: {m}"),
            Fail::Version { host, plc } => write!(
                f,
                "service version mismatch: plcctl speaks {host}, the PLC {plc}"
            ),
            Fail::Refused(r) => write!(f, "refused by the PLC: {}", r.text()),
            Fail::ReadBack(m) => write!(f, "read-back differs: {m}"),
        }
    }
}

impl From<anyhow::Error> for Fail {
    fn from(e: anyhow::Error) -> Self {
        Fail::Usage(e)
    }
}

impl From<std::io::Error> for Fail {
    fn from(e: std::io::Error) -> Self {
        Fail::Usage(e.into())
    }
}

pub type Result<T> = std::result::Result<T, Fail>;
