//! The PLC's service port (service.md part A): a PC (`plcctl`) reads status, trends, the
//! fault log and counters, pulls and pushes programs and, with the keypad's consent, runs,
//! stops and acknowledges. Full description: `docs/service.md` in this crate.
//!
//! ```text
//! wire:  0x00  COBS( id | 0 | postcard(message) | CRC-32C ) 0x00
//! ```
//!
//! The frame codec is the PLC-drive link's ([`crate::link::frame`]): the link's `seq`
//! byte carries the request id, its `ack` byte is always 0. This module holds the
//! messages ([`message`]), the protocol's constants and the two helpers both ends use to
//! put messages on the wire and take them off ([`encode`], [`ServiceReader`]).

pub mod message;

pub use message::*;

use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::link::frame::{encode_frame, Frame, FrameError, FrameReader};

/// EEPROM program slots, numbered 1..=SLOTS on the keypad, the LCD and in the requests
/// (slot 0 is the program in RAM).
pub const SLOTS: u8 = 4;
/// The service protocol's version (`Hello`), independent of the link's: 3 since a
/// fault-log entry holds the time of day and two application values, and the PC reads and
/// sets the PLC's clock (docs/service.md).
pub const SERVICE_VERSION: u16 = 3;
/// Default line rate (a firmware constant; `plcctl --baud` must match).
pub const SERVICE_BAUD: u32 = 115_200;
/// The PLC answers a request within this time...
pub const ANSWER_MS: u64 = 100;
/// ...or this one for `WriteCommit` and `ClearFaultLog` (EEPROM writes).
pub const EEPROM_ANSWER_MS: u64 = 3_000;
/// The host sends the same frame again after this time without an answer...
pub const RETRY_MS: u64 = 300;
/// ...or this one for requests that write the EEPROM.
pub const EEPROM_RETRY_MS: u64 = 5_000;
/// Attempts before the host reports a timeout.
pub const ATTEMPTS: u32 = 3;
/// Without a valid frame for this long the PLC forgets its client (a new `Hello` is due).
pub const FORGET_CLIENT_MS: u64 = 30_000;
/// Remote service switches itself off this long after enabling or after the last guarded
/// request, whichever is later (service.md 4).
pub const REMOTE_TIMEOUT_MS: u64 = 30 * 60 * 1000;
/// Program bytes per `ReadProgram` answer and `WriteChunk`.
pub const CHUNK_BYTES: usize = 64;
/// Most Q variables in one subscription.
pub const MAX_SUBSCRIBED_Q: usize = 8;
/// Shortest and longest sample period.
pub const SAMPLE_PERIOD_MIN_MS: u16 = 10;
pub const SAMPLE_PERIOD_MAX_MS: u16 = 100;
/// Most fault-log entries per answer (a fourth at its largest would not fit a frame).
pub const LOG_ENTRIES_PER_ANSWER: usize = 3;
/// Ring positions of fault-log entries (`LogEntry::pos`, `FaultLog::newest`) count
/// modulo this: the entry `k` places before the newest is at `newest - k`.
pub const LOG_POSITIONS: u8 = 32;
/// `ReadFaultLog { from }` value meaning "the newest entry".
pub const LOG_FROM_NEWEST: u8 = 0xFF;
/// Largest program payload (eeprom-image.md: one copy's 63 pages minus its header).
pub const PROGRAM_MAX_BYTES: u16 = 4016;
/// The last second the PLC's clock holds, 2099-12-31 23:59:59 UTC, in seconds since
/// 2000-01-01 00:00:00 UTC: the RTC counts two-digit years (RM0440 RTC_DR) and stops there.
pub const WALL_MAX_S: u32 = 36_525 * 86_400 - 1;
/// Unix time of 2000-01-01 00:00:00 UTC, the epoch of the PLC's clock.
pub const WALL_EPOCH_UNIX_S: i64 = 946_684_800;

/// A log entry's uptime at this value means "this long or longer" (24 bits of seconds).
pub const UPTIME_LIMIT_S: u32 = 0x00FF_FFFF;

/// Fault-log event: the log was cleared (keypad `*` `0` or service); the first entry of
/// the emptied log.
pub const EVENT_LOG_CLEARED: u8 = 240;
/// Fault-log event: a program was written over the service port.
pub const EVENT_PROGRAM_WRITTEN: u8 = 241;

/// Fault-log codes 101-199: application faults 1-99, logged by the PLC program's `ALM`
/// (program-format.md), between the drive's codes and the events.
pub const APP_FAULT_BASE: u8 = 100;

/// The fault-log code of application fault `n` (`ALM K00 00nn`, 1..=99).
pub const fn app_fault_code(n: u8) -> u8 {
    APP_FAULT_BASE.saturating_add(n)
}

/// The application fault (1..=99) a fault-log code holds, if it is one.
pub const fn app_fault_of(code: u8) -> Option<u8> {
    match code {
        101..=199 => Some(code - APP_FAULT_BASE),
        _ => None,
    }
}

/// Fault-log codes 200-203: the field I/O of the X-NUCLEO-PLC01A1 shield profile
/// (`firmware-plc/docs/field-io.md`), between the application faults and the events.
/// An output channel in over-temperature, or the output chip's case warning.
pub const FIELD_FAULT_OVT: u8 = 200;
/// The 24 V field supply lost or low.
pub const FIELD_FAULT_24V: u8 = 201;
/// The input chip in over-temperature.
pub const FIELD_FAULT_INT: u8 = 202;
/// A field I/O frame failed its check twice in a row.
pub const FIELD_FAULT_SPI: u8 = 203;

/// Short name of a field I/O fault-log code (200-203).
pub const fn field_fault_name(code: u8) -> Option<&'static str> {
    match code {
        FIELD_FAULT_OVT => Some("FIO_OVT"),
        FIELD_FAULT_24V => Some("FIO_24V"),
        FIELD_FAULT_INT => Some("FIO_INT"),
        FIELD_FAULT_SPI => Some("FIO_SPI"),
        _ => None,
    }
}

/// Text of a field I/O fault-log code (200-203).
pub const fn field_fault_text(code: u8) -> Option<&'static str> {
    match code {
        FIELD_FAULT_OVT => Some("field output overtemperature"),
        FIELD_FAULT_24V => Some("field 24 V supply lost"),
        FIELD_FAULT_INT => Some("field input overtemperature"),
        FIELD_FAULT_SPI => Some("field I/O frame check failed"),
        _ => None,
    }
}

/// Whether a fault-log code is an event (240-254): listed, never counted as a trip nor
/// shown as the newest fault.
pub const fn is_event(code: u8) -> bool {
    code >= 240 && code <= 254
}

/// Short name of a fault-log code: drive.md's for faults, service.md 6's for events,
/// `?` otherwise.
pub const fn log_name(code: u8) -> &'static str {
    match code {
        EVENT_LOG_CLEARED => "LOGCLR",
        EVENT_PROGRAM_WRITTEN => "PGMSVC",
        101..=199 => "ALM",
        c => crate::link::fault_name(c),
    }
}

/// The text of a fault-log code (service.md 6): drive faults from the shared
/// [`crate::link::fault_text`], events from service.md's table, anything else `code N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogText(pub u8);

impl core::fmt::Display for LogText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            EVENT_LOG_CLEARED => f.write_str("fault log cleared"),
            EVENT_PROGRAM_WRITTEN => f.write_str("program written over the service port"),
            c if field_fault_text(c).is_some() => f.write_str(field_fault_text(c).unwrap_or("")),
            c if app_fault_of(c).is_some() => {
                write!(f, "application fault {}", c.saturating_sub(APP_FAULT_BASE))
            }
            c if crate::link::fault_name(c).as_bytes() != b"?" && c != 0 => {
                f.write_str(crate::link::fault_text(c))
            }
            c => write!(f, "code {c}"),
        }
    }
}

/// Encode `msg` with request id `id` (0 for samples) into `out`, with the leading
/// delimiter; returns the wire length. `out` of [`crate::link::MAX_WIRE_FRAME`] always
/// suffices.
pub fn encode<M: Serialize>(id: u8, msg: M, out: &mut [u8]) -> Result<usize, FrameError> {
    encode_frame(
        &Frame {
            seq: id,
            ack: 0,
            msg,
        },
        true,
        out,
    )
}

/// Cuts a received byte stream into `(id, message)` pairs: the link's [`FrameReader`]
/// (fixed memory, bounded work per byte) plus the service's header rule (second byte 0).
#[derive(Debug, Clone, Default)]
pub struct ServiceReader {
    frames: FrameReader,
}

impl ServiceReader {
    pub const fn new() -> Self {
        ServiceReader {
            frames: FrameReader::new(),
        }
    }

    /// Forget a partial frame.
    pub fn reset(&mut self) {
        self.frames.reset();
    }

    /// Feed one byte; at a delimiter ending a non-empty frame, its result.
    pub fn push<M: DeserializeOwned>(&mut self, byte: u8) -> Option<Result<(u8, M), FrameError>> {
        let r = self.frames.push::<M>(byte)?;
        Some(r.and_then(|f| {
            if f.ack == 0 {
                Ok((f.seq, f.msg))
            } else {
                Err(FrameError::Message)
            }
        }))
    }
}

#[cfg(test)]
mod tests;
