//! The drive's operating states (drive.md "States").

/// BOOT -> IDLE <-> RUN; any state -> FAULT on a trip; FAULT -> IDLE on an accepted ACK.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum DriveState {
    /// After reset, until the first 1 ms tick has run the self-test.
    Boot,
    /// Ready; PWM off; the drive section does not run.
    Idle,
    /// The drive section runs every 1 ms; PWM on while f >= fmn.
    Run,
    /// A fault is latched; PWM off until ACK (then IDLE, then a new RUN).
    Fault,
}

impl DriveState {
    pub const fn name(self) -> &'static str {
        match self {
            DriveState::Boot => "BOOT",
            DriveState::Idle => "IDLE",
            DriveState::Run => "RUN",
            DriveState::Fault => "FAULT",
        }
    }
}
