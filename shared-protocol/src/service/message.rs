//! Every message of the service port, both directions (postcard + serde).
//!
//! The variant order of [`Request`] and [`Answer`] is the wire's message type: append new
//! variants at the end, never reorder. `Hello`/`HelloReply` are variant 0 and their fields
//! never change, so a host and a PLC of any two versions can always tell each other their
//! service version. The same holds for every enum inside a message (states, reasons):
//! append only.
//!
//! Every message fits the link's frame limit ([`crate::link::frame::MAX_RAW_FRAME`], 96
//! bytes before COBS) with every field at its largest value; `tests` checks that.

use heapless::{String, Vec};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{CHUNK_BYTES, LOG_ENTRIES_PER_ANSWER, MAX_SUBSCRIBED_Q};
use crate::fault::FaultCode;
use crate::link::DriveState;

/// PC to PLC. See service.md section 3 for what each request does; the doc of each variant
/// says what the PLC adds to it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Request {
    /// Variant 0, frozen: the host's service version. Answered by
    /// [`Answer::HelloReply`] whatever the version.
    Hello {
        version: u16,
    },
    Identify,
    GetStatus,
    GetScreen,
    /// `period_ms` 0 stops the samples; other values are clamped to
    /// [`super::SAMPLE_PERIOD_MIN_MS`]..=[`super::SAMPLE_PERIOD_MAX_MS`]. An empty `q`
    /// subscribes Q00-Q07; numbers above 63 read as 0.
    Subscribe {
        period_ms: u16,
        q: Vec<u8, MAX_SUBSCRIBED_Q>,
    },
    /// Entries newest first, starting at ring position `from`
    /// ([`super::LOG_FROM_NEWEST`] = the newest entry), at most `count` (and at most
    /// [`LOG_ENTRIES_PER_ANSWER`]); `count` 0 gives only `total` and `newest`.
    ReadFaultLog {
        from: u8,
        count: u8,
    },
    GetCounters,
    ListSlots,
    /// Slot 0 is the program in RAM, 1-4 the EEPROM slots; `offset` is a multiple of
    /// [`CHUNK_BYTES`] below the payload length (0 also for an empty program).
    ReadProgram {
        slot: u8,
        offset: u16,
    },
    /// Guarded, STOP only: a program write into slot 1-4 follows; `len` bytes of payload
    /// whose CRC-32C is `crc`.
    WriteBegin {
        slot: u8,
        len: u16,
        crc: u32,
    },
    /// Guarded: payload bytes at `offset` (a multiple of [`CHUNK_BYTES`]); every chunk but
    /// the last is [`CHUNK_BYTES`] long. The PLC stages them in the EEPROM (the slot's
    /// spare copy), so it refuses chunks in RUN too.
    WriteChunk {
        offset: u16,
        data: Vec<u8, CHUNK_BYTES>,
    },
    /// Guarded, STOP only: check, verify and save.
    WriteCommit,
    /// Guarded: slot 0 runs the program in RAM (as key `A`), 1-4 loads that slot first.
    Run {
        slot: u8,
    },
    /// Never guarded: STOP.
    Stop,
    /// Guarded: keys `*` `9`.
    Ack,
    /// Guarded, STOP only: erase the fault log (it then holds the event `LOGCLR`).
    ClearFaultLog,
    /// The PLC's time of day ([`Answer::Clock`]).
    GetClock,
    /// Never guarded (it writes no EEPROM and changes no output): set the PLC's clock to
    /// `seconds` since 2000-01-01 00:00:00 UTC ([`super::WALL_MAX_S`] at most, else
    /// `Refused(Transfer)`); answered with the clock as set ([`Answer::Clock`]).
    SetClock {
        seconds: u32,
    },
}

impl Request {
    /// Whether the request needs remote service enabled on the keypad (service.md 4); the
    /// PLC also keeps the answer of the last one for a repeat with the same id.
    pub fn is_guarded(&self) -> bool {
        matches!(
            self,
            Request::WriteBegin { .. }
                | Request::WriteChunk { .. }
                | Request::WriteCommit
                | Request::Run { .. }
                | Request::Ack
                | Request::ClearFaultLog
        )
    }

    /// Whether the PLC may take [`super::EEPROM_ANSWER_MS`] to answer (it writes the
    /// EEPROM before answering) and the host waits [`super::EEPROM_RETRY_MS`] before a
    /// resend (service.md 2): `WriteCommit` and `ClearFaultLog`.
    pub fn long_answer(&self) -> bool {
        matches!(self, Request::WriteCommit | Request::ClearFaultLog)
    }
}

/// PLC to PC: the answer to a request (same id), or a [`Sample`] (id 0).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Answer {
    /// Variant 0, frozen: the PLC's service version.
    HelloReply {
        version: u16,
    },
    Identity(Identity),
    Status(Status),
    Screen(Screen),
    /// The subscription in force (`period_ms` 0: none).
    Subscribed {
        period_ms: u16,
    },
    FaultLog(FaultLog),
    Counters(Counters),
    Slots(Slots),
    ProgramChunk(ProgramChunk),
    Done,
    Refused(RefuseReason),
    WriteResult(WriteResult),
    /// Sent with id 0, unasked, while subscribed.
    Sample(Sample),
    /// The PLC's time of day: seconds since 2000-01-01 00:00:00 UTC, `None` while its
    /// clock is unset (never set since its backup domain lost power).
    Clock {
        seconds: Option<u32>,
    },
}

/// Why a request was refused (service.md 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RefuseReason {
    /// No `Hello` with the PLC's version yet (or the PLC forgot the client).
    Hello,
    /// Remote service is off (keys `*` `7`).
    Locked,
    /// An EEPROM write while the PLC is not stopped.
    InRun,
    /// The program in RAM has unsaved edits.
    Unsaved,
    /// No such slot, or it is empty.
    Slot,
    /// Another EEPROM operation is under way (or the PLC is still reading the slot: ask
    /// again).
    Busy,
    /// The EEPROM failed.
    Storage,
    /// Addition: a chunk or commit without a `WriteBegin`, or a chunk offset, length or
    /// a read offset out of place.
    Transfer,
}

impl RefuseReason {
    /// A short explanation for the host's messages.
    pub const fn text(self) -> &'static str {
        match self {
            RefuseReason::Hello => "no Hello with the PLC's service version",
            RefuseReason::Locked => "remote service is off (keys * 7 on the PLC)",
            RefuseReason::InRun => "the PLC is in RUN (EEPROM writes only in STOP)",
            RefuseReason::Unsaved => "the program in RAM has unsaved edits",
            RefuseReason::Slot => "no such slot, or it is empty",
            RefuseReason::Busy => "another EEPROM operation is under way",
            RefuseReason::Storage => "EEPROM error",
            RefuseReason::Transfer => "transfer out of sequence or out of range",
        }
    }
}

/// `Identify`'s answer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    /// The firmware's crate version, e.g. `0.1.0`.
    pub firmware: String<16>,
    /// Short git hash of the build (`unknown` when it was not built from a git tree).
    pub git: String<12>,
    /// The MCU's 96-bit unique ID (the STM32's UID registers, lowest address first).
    pub uid: [u8; 12],
    /// This power-up's number (the boot record's count).
    pub power_ups: u32,
    pub uptime_ms: u64,
}

/// Where RUN stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlcState {
    Stop,
    /// RUN requested: waiting for the link or the drive's acceptance of its section.
    Starting,
    Run,
}

impl PlcState {
    pub const fn text(self) -> &'static str {
        match self {
            PlcState::Stop => "STOP",
            PlcState::Starting => "STARTING",
            PlcState::Run => "RUN",
        }
    }
}

/// The PLC-drive link as the PLC sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkView {
    Up,
    /// No valid frame from the drive (connecting).
    Lost,
    VersionMismatch {
        drive_version: u16,
    },
}

/// The drive's newest status as the PLC has it (only while the link is up).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DriveInfo {
    pub state: DriveState,
    /// Latched fault (`FLT`), 0 none.
    pub fault: u8,
    /// `FRQ`, 0.1 Hz.
    pub freq_dhz: i16,
    /// `DIR`: true = reverse.
    pub reverse: bool,
    /// `UDC`, 0.1 V.
    pub udc_dv: i16,
    /// `IMX`, 0.01 A.
    pub imax_ca: i16,
    /// `COM`, 10-bit counts.
    pub com: u16,
}

/// A run-time warning of the PLC's program.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunWarning {
    /// `DIV` by a `Q` holding 0 at this line.
    Div0 { line: u16 },
}

/// One fault-log entry with its ring position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LogEntry {
    /// Ring position 0-31.
    pub pos: u8,
    /// Fault code (drive.md) or event (240-254).
    pub code: u8,
    /// Power-up count when it happened, low 16 bits.
    pub power_up: u16,
    /// Seconds since that power-up (24 bits; saturates at [`super::UPTIME_LIMIT_S`]).
    pub uptime_s: u32,
    /// The PLC's time of day: seconds since 2000-01-01 00:00:00 UTC (`None`: the PLC's
    /// clock was not set, or the entry predates the entries that hold it).
    pub wall_s: Option<u32>,
    /// The two application values at the time (the program's first two `LCD` fields,
    /// e.g. the lift's floor and target; `None`: not written, or not in RUN).
    pub values: [Option<i16>; 2],
}

/// `GetStatus`'s answer (service.md 3 "Status").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Status {
    pub plc: PlcState,
    pub remote: bool,
    pub link: LinkView,
    /// `None` while the link is not up.
    pub drive: Option<DriveInfo>,
    /// D00-D15 as the last scan read them (bit n = Dn).
    pub d: u16,
    /// O00-O07 (bit n = On).
    pub o: u8,
    /// A00-A03, 10-bit counts.
    pub a: [u16; 4],
    /// The 4 `LCD` fields (`None`: not written by an `LCD` instruction).
    pub lcd: [Option<i16>; 4],
    pub warning: Option<RunWarning>,
    /// The newest fault-log entry (events included): ring position and code.
    pub newest_log: Option<(u8, u8)>,
    /// Time between the last two scans, and the longest since RUN started, µs.
    pub scan_last_us: u32,
    pub scan_max_us: u32,
    pub uptime_ms: u64,
    /// The slot the program in RAM came from or was saved to (`None`: a new program).
    pub slot: Option<u8>,
    /// The program in RAM has edits not saved to that slot.
    pub unsaved: bool,
}

/// `GetScreen`'s answer: the LCD's rows as shown (20 or 16 characters each; 2 or 4 rows).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Screen {
    pub rows: Vec<String<20>, 4>,
}

/// `ReadFaultLog`'s answer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultLog {
    /// Valid entries in the log.
    pub total: u8,
    /// Ring position of the newest entry (`None`: empty log).
    pub newest: Option<u8>,
    pub entries: Vec<LogEntry, LOG_ENTRIES_PER_ANSWER>,
}

/// The trip counters, one per fault code ([`FaultCode::COUNT`], code 1 first), carried as
/// big-endian byte pairs (a varint array could need 3 bytes a counter). The size follows
/// the fault table, so a new code changes this message: [`super::SERVICE_VERSION`] goes
/// up with it (`tests::the_service_version_names_its_trip_count`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Trips(pub [u16; FaultCode::COUNT]);

/// Bytes of [`Trips`] on the wire.
pub const TRIPS_BYTES: usize = 2 * FaultCode::COUNT;

impl Serialize for Trips {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = s.serialize_tuple(TRIPS_BYTES)?;
        for v in self.0 {
            for b in v.to_be_bytes() {
                t.serialize_element(&b)?;
            }
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Trips {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Pairs;
        impl<'de> serde::de::Visitor<'de> for Pairs {
            type Value = Trips;
            fn expecting(&self, f: &mut core::fmt::Formatter) -> core::fmt::Result {
                write!(f, "{TRIPS_BYTES} bytes of trip counters")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Trips, A::Error> {
                let mut t = [0u16; FaultCode::COUNT];
                for (i, v) in t.iter_mut().enumerate() {
                    let mut pair = [0u8; 2];
                    for (j, b) in pair.iter_mut().enumerate() {
                        *b = seq
                            .next_element()?
                            .ok_or_else(|| serde::de::Error::invalid_length(2 * i + j, &self))?;
                    }
                    *v = u16::from_be_bytes(pair);
                }
                Ok(Trips(t))
            }
        }
        d.deserialize_tuple(TRIPS_BYTES, Pairs)
    }
}

/// `GetCounters`'s answer: the RAM values (including counts not yet written), see
/// service.md 7 and `firmware-plc/docs/eeprom-image.md`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counters {
    pub run_starts: u32,
    pub run_minutes: u32,
    pub pwm_minutes: u32,
    pub link_errors: u32,
    pub program_saves: u16,
    /// Trips per fault code (index 0 = code 1).
    pub trips: Trips,
    /// Application counters 1-4 (Q60-Q63).
    pub app: [u32; 4],
    pub power_ups: u32,
    /// Seconds since the record was last written (`None`: not yet in this power-up).
    pub since_write_s: Option<u32>,
}

/// What a slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlotState {
    Empty,
    Valid,
    /// Both copies bad.
    Damaged,
}

/// One slot in `Slots`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct SlotSummary {
    pub state: SlotState,
    /// Of the copy a load would use (0 when not valid).
    pub generation: u32,
    pub lines: u16,
    /// Payload bytes.
    pub len: u16,
    /// CRC-32C of the payload (as `ReadProgram` and `WriteBegin`).
    pub crc: u32,
}

/// `ListSlots`' answer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Slots {
    /// Slots 1-4.
    pub slots: [SlotSummary; 4],
    /// The slot the program in RAM came from (`None`: a new program).
    pub ram_slot: Option<u8>,
    pub unsaved: bool,
    /// The slot RUN was last started from (loaded at power-up).
    pub last_run: Option<u8>,
}

/// `ReadProgram`'s answer: payload bytes `offset..offset + data.len()` of `len`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProgramChunk {
    pub slot: u8,
    /// The copy's generation (slot 0: 0).
    pub generation: u32,
    pub len: u16,
    /// CRC-32C of the whole payload.
    pub crc: u32,
    pub offset: u16,
    pub data: Vec<u8, CHUNK_BYTES>,
}

/// Why a written program was not saved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InvalidReason {
    /// The verifier refused the line: [`crate::link::message::verify_kind_code`].
    Verify(u8),
    /// The line's bytes are not an instruction.
    Decode,
    /// The runs of lines are not in ascending order, overlap or leave the program.
    Layout,
}

/// `WriteCommit`'s answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WriteResult {
    Saved {
        generation: u32,
    },
    Invalid {
        line: u16,
        reason: InvalidReason,
    },
    /// The staged bytes do not have `WriteBegin`'s CRC-32C.
    Crc,
    /// A chunk is missing (or the transfer was cut by a new `WriteBegin` or a keypad save).
    Incomplete,
}

/// The drive's part of a [`Sample`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DriveSample {
    pub freq_dhz: i16,
    pub reverse: bool,
    pub udc_dv: i16,
    pub imax_ca: i16,
    pub fault: u8,
}

/// One trend sample (service.md 3 "Sample").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sample {
    /// PLC uptime at the scan it follows, ms.
    pub uptime_ms: u64,
    pub plc: PlcState,
    /// `None` while the link is not up.
    pub drive: Option<DriveSample>,
    pub d: u16,
    pub o: u8,
    pub a: [u16; 4],
    pub lcd: [Option<i16>; 4],
    /// The subscribed Q values, in the order subscribed.
    pub q: Vec<i16, MAX_SUBSCRIBED_Q>,
    /// Samples dropped (transmitter busy) since the previous one sent.
    pub dropped: u32,
}
