//! Timing of the link. All times are microseconds of the caller's monotonic clock.

/// Timing parameters of one endpoint. Both ends should use the same values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkConfig {
    /// UART baud rate (8N1: 10 bit times per byte).
    pub baud: u32,
    /// The PLC sends a heartbeat when it has sent nothing for this long. Below the 10 ms
    /// the spec allows, leaving room for the caller's polling period and a frame in flight.
    pub heartbeat_us: u64,
    /// The drive's status period.
    pub status_us: u64,
    /// The drive declares the link lost after this long without a valid frame (link.md: 50 ms).
    pub drive_timeout_us: u64,
    /// The PLC declares the link lost after this long without a valid frame (4 status
    /// periods); with a redraw on the change (`PlcApp::alerts`) the LCD shows it well
    /// within the 100 ms link.md asks for, even with a slow I2C LCD.
    pub plc_timeout_us: u64,
    /// The PLC repeats `Hello` this often while connecting.
    pub hello_retry_us: u64,
    /// The PLC repeats `Hello` this often after a version mismatch (the drive may be
    /// reflashed; no need to flood it meanwhile).
    pub incompatible_retry_us: u64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self::at_baud(115_200)
    }
}

impl LinkConfig {
    /// The default timing at a given baud rate.
    pub const fn at_baud(baud: u32) -> Self {
        LinkConfig {
            baud,
            heartbeat_us: 8_000,
            status_us: 10_000,
            drive_timeout_us: 50_000,
            plc_timeout_us: 40_000,
            hello_retry_us: 20_000,
            incompatible_retry_us: 500_000,
        }
    }

    /// Nanoseconds per byte on the wire (start + 8 data + stop bits).
    pub const fn byte_time_ns(&self) -> u64 {
        let baud = if self.baud == 0 { 1 } else { self.baud as u64 };
        10_000_000_000 / baud
    }

    /// Retransmission timeout: the longest round trip on a clean link (a largest PLC
    /// frame, a drive status that was already on the wire, then the drive's ack frame:
    /// 160 byte times since the status carries the safety fields, protocol 4) plus 2 ms
    /// for the caller's polling and processing.
    pub const fn rto_us(&self) -> u64 {
        160 * self.byte_time_ns() / 1000 + 2_000
    }
}
