//! Every message of the link, in both directions (serialised with postcard).
//!
//! The variant order is the wire's message type byte: append new variants at the end,
//! never reorder. `Hello`/`HelloReply` are variant 0 and their fields must never change, so
//! that two firmware versions can always tell each other their protocol version.

use serde::{Deserialize, Serialize};

pub use crate::drive_state::DriveState;
pub use crate::fault::{fault_name, fault_text, FaultCode};

/// Protocol version stated in the handshake; bump on any incompatible wire change.
/// 2: the status carries the hardware thresholds and the drive's run-time warning.
/// 3: `DriveMsg::AckRefused` (why the drive refused an acknowledgement).
/// 4: the safety functions (safety.md 9): `PlcMsg::SafetyRequest`, the status's `sf_*`
/// and `sto_in_low` fields, fault codes 9-16.
/// 7: the status ends with `sf_turns` (the PLC's `SFP`).
pub const PROTOCOL_VERSION: u16 = 7;

/// Most Q writes carried by one frame (a scan that writes more sends several frames).
pub const MAX_Q_PER_FRAME: usize = 8;

/// Bytes of encoded program lines per download chunk (16 lines of 4 bytes).
pub const CHUNK_BYTES: usize = 64;

/// One Q variable's new value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QValue {
    /// Q00-Q63.
    #[serde(deserialize_with = "one_copy::de_u8")]
    pub addr: u8,
    pub value: i16,
}

/// PLC to drive.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum PlcMsg {
    /// Start of a handshake. `session` is chosen by the PLC and echoed by the drive.
    Hello {
        #[serde(deserialize_with = "one_copy::de_u16")]
        version: u16,
        #[serde(deserialize_with = "one_copy::de_u8")]
        session: u8,
    },
    /// Nothing to say: keeps the drive's supervision fed and carries the ack.
    Heartbeat,
    /// Reliable: new values of Q variables, applied in the listed order.
    QWrite(heapless::Vec<QValue, MAX_Q_PER_FRAME>),
    /// Reliable: start the drive section (drive.md: IDLE -> RUN).
    Run,
    /// Reliable: coast to stop (PWM off).
    Stop,
    /// Reliable: requested direction (level, not a toggle).
    Direction { reverse: bool },
    /// Reliable: acknowledge latched faults.
    AckFault,
    /// Reliable: a drive-section download follows; `crc` is the CRC-32C of all
    /// `DRIVE_LINES * LINE_BYTES` encoded slot bytes.
    DownloadBegin { crc: u32 },
    /// Reliable: encoded slots (`encode_slot`) of lines `first_line..`.
    DownloadChunk {
        #[serde(deserialize_with = "one_copy::de_u8")]
        first_line: u8,
        data: heapless::Vec<u8, CHUNK_BYTES>,
    },
    /// Reliable: all chunks sent; the drive checks, verifies and answers `DownloadResult`.
    DownloadEnd,
    /// Reliable, newest wins: the safety functions the PLC program requests (bit n set =
    /// function n requested, safety.md 2 and 9).
    SafetyRequest {
        #[serde(deserialize_with = "one_copy::de_u16")]
        requested: u16,
    },
}

impl PlcMsg {
    /// Whether this message is sequenced, acknowledged and retransmitted.
    pub fn is_reliable(&self) -> bool {
        !matches!(self, PlcMsg::Hello { .. } | PlcMsg::Heartbeat)
    }
}

/// The drive's periodic report. Units are in the field names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveStatus {
    pub state: DriveState,
    /// Latched fault (drive.md table). On the wire one byte, 0 = none, as before the
    /// type was typed: an undefined code makes the frame unparsable.
    #[serde(with = "crate::fault::wire_option")]
    pub fault: Option<FaultCode>,
    /// Output frequency being generated, 0.1 Hz.
    #[serde(serialize_with = "one_copy::i16")]
    pub freq_dhz: i16,
    /// Applied direction.
    #[serde(serialize_with = "one_copy::bool")]
    pub reverse: bool,
    /// DC-link voltage, 0.1 V.
    #[serde(serialize_with = "one_copy::i16")]
    pub udc_dv: i16,
    /// Largest |phase current| since the previous status, 0.01 A.
    #[serde(serialize_with = "one_copy::i16")]
    pub imax_ca: i16,
    /// Auxiliary ADC channel (`COM`), 10-bit counts.
    #[serde(serialize_with = "one_copy::u16")]
    pub com: u16,
    /// Hardware overcurrent threshold in effect (`I>>`, or the board's default), 0.01 A:
    /// the PLC's `IHW`.
    #[serde(serialize_with = "one_copy::i16")]
    pub oc_hw_ca: i16,
    /// Hardware overvoltage threshold in effect (`U>>`, or the board's default), V: the
    /// PLC's `UHW`.
    #[serde(serialize_with = "one_copy::i16")]
    pub ov_hw_v: i16,
    /// The drive's run-time warning while it lasts (none: `None`).
    pub warning: Option<DriveWarning>,
    /// Requested safety functions: the PLC's mask, plus bit 0 while `STO_IN` is low.
    #[serde(serialize_with = "one_copy::u16")]
    pub sf_requested: u16,
    /// Safety status bits (bit n = function n requested and in its safe state).
    #[serde(serialize_with = "one_copy::u16")]
    pub sf_status: u16,
    /// A ramp function is in its delay or ramp phase (`SDC`).
    #[serde(serialize_with = "one_copy::bool")]
    pub sf_sdc: bool,
    /// The safety stopwatch (`SFT`), 0.1 s.
    #[serde(serialize_with = "one_copy::u16")]
    pub sf_elapsed_ds: u16,
    /// The parameter signature of the drive section the drive accepted (safety.md 8).
    #[serde(serialize_with = "one_copy::u16")]
    pub sf_signature: u16,
    /// The hardware `STO_IN` input is low (STO requested).
    #[serde(serialize_with = "one_copy::bool")]
    pub sto_in_low: bool,
    /// The drive holds an accepted drive section. False after the drive's reset: a PLC in
    /// RUN that saw it true learns that the drive restarted and lost it.
    #[serde(serialize_with = "one_copy::bool")]
    pub program_loaded: bool,
    /// Whole commanded field turns since the safety request mask left 0 (`SFP`; 0 while
    /// nothing is requested).
    #[serde(serialize_with = "one_copy::i16")]
    pub sf_turns: i16,
}

impl DriveStatus {
    /// The fields whose change sends a status at once: state, fault and the safety
    /// request, status and input (safety.md 9).
    pub fn urgent_key(&self) -> (DriveState, Option<FaultCode>, u16, u16, bool, bool) {
        (
            self.state,
            self.fault,
            self.sf_requested,
            self.sf_status,
            self.sf_sdc,
            self.sto_in_low,
        )
    }
}

/// The drive's message fields serialised through one function per type, not each field's
/// varint or byte code inlined into `DriveMsg::serialize` (the drive image's flash, `docs/size.md`).
/// The wire bytes are postcard's as derived (`status_fields_keep_the_wire_bytes`).
pub(crate) mod one_copy {
    use serde::{Deserialize, Deserializer, Serializer};

    #[inline(never)]
    pub fn u16<S: Serializer>(v: &u16, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u16(*v)
    }

    #[inline(never)]
    pub fn i16<S: Serializer>(v: &i16, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_i16(*v)
    }

    #[inline(never)]
    pub fn bool<S: Serializer>(v: &bool, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bool(*v)
    }

    // The drive's received fields (`PlcMsg`, `Frame`), the same way. Only types with
    // several fields: a helper for one field costs more than it saves.

    #[inline(never)]
    pub fn de_u8<'de, D: Deserializer<'de>>(d: D) -> Result<u8, D::Error> {
        u8::deserialize(d)
    }

    #[inline(never)]
    pub fn de_u16<'de, D: Deserializer<'de>>(d: D) -> Result<u16, D::Error> {
        u16::deserialize(d)
    }
}

/// A run-time warning of the drive: nothing latched, the drive goes on. Sent in every
/// status while it lasts; the PLC shows it on the LCD status line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveWarning {
    /// `PWF Qxx` on drive line `line` asks for `requested` Hz, outside the drive's range
    /// (488..=20000 Hz): the drive switches at `applied_hz`.
    PwfClamped {
        line: u8,
        requested: i16,
        applied_hz: u16,
    },
}

impl DriveWarning {
    /// Short text for the LCD status line and hil-sim's `warn` column (at most 18
    /// characters: the status row adds `W:`), e.g. `PWF 488Hz @ 000`.
    pub fn short(&self) -> heapless::String<18> {
        use core::fmt::Write;
        let mut s = heapless::String::new();
        match *self {
            DriveWarning::PwfClamped {
                line, applied_hz, ..
            } => {
                let _ = write!(s, "PWF {applied_hz}Hz @ {line:03}");
            }
        }
        s
    }
}

impl core::fmt::Display for DriveWarning {
    /// The long form, e.g. `line 000: PWF asks for 0 Hz, outside 488..20000 Hz: switching at 488 Hz`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            DriveWarning::PwfClamped {
                line,
                requested,
                applied_hz,
            } => write!(
                f,
                "line {line:03}: PWF asks for {requested} Hz, outside 488..20000 Hz: switching at {applied_hz} Hz"
            ),
        }
    }
}

/// Why the drive refused a downloaded section.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RejectReason {
    /// The verifier refused the line; the code is [`verify_kind_code`] of its error.
    Verify(u8),
    /// The line's bytes are not an instruction.
    Decode,
    /// The whole-section CRC does not match.
    Crc,
    /// `DownloadEnd` before every line arrived, or a chunk out of place.
    Incomplete,
}

impl RejectReason {
    /// At most 16 characters, for the LCD status line.
    pub const fn short(self) -> &'static str {
        match self {
            RejectReason::Verify(_) => "invalid line",
            RejectReason::Decode => "bad line bytes",
            RejectReason::Crc => "section CRC",
            RejectReason::Incomplete => "incomplete",
        }
    }
}

/// A stable small code for a verifier error kind (the wire must not depend on the
/// verifier's enum layout). The PLC can re-run `verify_line` on its copy for the full text.
pub fn verify_kind_code(kind: &crate::program::VerifyErrorKind) -> u8 {
    use crate::program::VerifyErrorKind as K;
    match kind {
        K::LineOutOfRange => 1,
        K::WrongSection { .. } => 2,
        K::OperandMissing { .. } => 3,
        K::OperandNotAllowed { .. } => 4,
        K::OperandWrongKind { .. } => 5,
        K::LdcOnInt { .. } => 6,
        K::OperandOutOfRange { .. } => 7,
        K::ConstantOutOfRange { .. } => 8,
        K::ConstantWithoutK { .. } => 9,
        K::StackUnderflow { .. } => 10,
        K::SettingTwice { .. } => 11,
        K::SafetyNeeds { .. } => 12,
        K::SafetyNeedsSine { .. } => 13,
    }
}

/// The drive's answer to a download.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DownloadResult {
    Accepted,
    Rejected {
        #[serde(serialize_with = "one_copy::u16")]
        line: u16,
        reason: RejectReason,
    },
}

/// Drive to PLC.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum DriveMsg {
    /// Answer to `Hello`: the drive's version and the PLC's session.
    HelloReply {
        #[serde(serialize_with = "one_copy::u16")]
        version: u16,
        session: u8,
    },
    /// Nothing else to say: carries the ack.
    Ack,
    /// Periodic report (also sent at once when state or fault changes).
    Status(DriveStatus),
    /// Reliable: the answer to a download.
    Download(DownloadResult),
    /// Reliable: a trip, with the drive's millisecond clock at the trip.
    Fault { code: FaultCode, drive_time_ms: u32 },
    /// Reliable: an ACK the drive refused, and why (the fault stays latched).
    AckRefused(AckRefusal),
}

/// Why the drive refused to acknowledge its latched fault (`*` `9`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AckRefusal {
    /// The fault's cause is still present (e.g. the DC link still above `U>`).
    CauseActive(FaultCode),
    /// The drive section still commands a frequency at or above `fmn`: acknowledging
    /// would restart the motor at once. Lower the setpoint first.
    FrequencyNotBelowFmn,
}

impl AckRefusal {
    /// The PLC's status-row message (at most 20 characters).
    pub fn message(&self) -> &'static str {
        match self {
            AckRefusal::CauseActive(_) => "ACK REFUSED: CAUSE",
            AckRefusal::FrequencyNotBelowFmn => "ACK REFUSED: F>=FMN",
        }
    }
}

impl DriveMsg {
    /// Whether this message is sequenced, acknowledged and retransmitted.
    pub fn is_reliable(&self) -> bool {
        matches!(
            self,
            DriveMsg::Download(_) | DriveMsg::Fault { .. } | DriveMsg::AckRefused(_)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::frame::{decode_raw, encode_frame, Frame, FrameError, FrameReader};

    /// `DriveStatus` as it was before the fault became typed (`fault: u8`): the bytes must
    /// not change, or `PROTOCOL_VERSION` would have to.
    #[derive(Serialize)]
    struct UntypedStatus {
        state: DriveState,
        fault: u8,
        freq_dhz: i16,
        reverse: bool,
        udc_dv: i16,
        imax_ca: i16,
        com: u16,
        oc_hw_ca: i16,
        ov_hw_v: i16,
        warning: Option<DriveWarning>,
        sf_requested: u16,
        sf_status: u16,
        sf_sdc: bool,
        sf_elapsed_ds: u16,
        sf_signature: u16,
        sto_in_low: bool,
        program_loaded: bool,
        sf_turns: i16,
    }

    #[derive(Serialize)]
    enum UntypedDriveMsg {
        _HelloReply,
        _Ack,
        _Status,
        _Download,
        Fault { code: u8, drive_time_ms: u32 },
    }

    fn status(fault: Option<FaultCode>) -> DriveStatus {
        DriveStatus {
            state: DriveState::Fault,
            fault,
            freq_dhz: -123,
            udc_dv: 301,
            imax_ca: 250,
            com: 1023,
            oc_hw_ca: 900,
            ov_hw_v: 40,
            ..Default::default()
        }
    }

    /// A peer that does not know a code would refuse every frame carrying it (the link
    /// would look broken); a new fault code therefore raises `PROTOCOL_VERSION`, so that
    /// the handshake refuses the mismatched pair instead (`docs/contributing/add-a-trip.md`).
    #[test]
    fn the_protocol_version_names_its_fault_codes() {
        const CODES_PER_VERSION: [(u16, usize); 3] = [(5, 16), (6, 17), (7, 17)];
        let known = CODES_PER_VERSION
            .iter()
            .find(|(v, _)| *v == PROTOCOL_VERSION);
        assert_eq!(
            known.map(|(_, n)| *n),
            Some(FaultCode::COUNT),
            "PROTOCOL_VERSION {PROTOCOL_VERSION} does not carry {} fault codes: raise it and \
             add (version, count) to CODES_PER_VERSION",
            FaultCode::COUNT
        );
    }

    #[test]
    fn typed_fault_codes_keep_the_wire_bytes() {
        let mut typed = [0u8; 64];
        let mut untyped = [0u8; 64];
        for (fault, byte) in [(None, 0u8)]
            .into_iter()
            .chain(FaultCode::ALL.map(|f| (Some(f), f.code())))
        {
            let s = status(fault);
            let old = UntypedStatus {
                state: s.state,
                fault: byte,
                freq_dhz: s.freq_dhz,
                reverse: s.reverse,
                udc_dv: s.udc_dv,
                imax_ca: s.imax_ca,
                com: s.com,
                oc_hw_ca: s.oc_hw_ca,
                ov_hw_v: s.ov_hw_v,
                warning: s.warning,
                sf_requested: s.sf_requested,
                sf_status: s.sf_status,
                sf_sdc: s.sf_sdc,
                sf_elapsed_ds: s.sf_elapsed_ds,
                sf_signature: s.sf_signature,
                sto_in_low: s.sto_in_low,
                program_loaded: s.program_loaded,
                sf_turns: s.sf_turns,
            };
            assert_eq!(
                postcard::to_slice(&s, &mut typed).unwrap(),
                postcard::to_slice(&old, &mut untyped).unwrap()
            );
        }
        for f in FaultCode::ALL {
            let new = DriveMsg::Fault {
                code: f,
                drive_time_ms: 70_000,
            };
            let old = UntypedDriveMsg::Fault {
                code: f.code(),
                drive_time_ms: 70_000,
            };
            let n = postcard::to_slice(&new, &mut typed).unwrap().len();
            assert_eq!(typed[..n], *postcard::to_slice(&old, &mut untyped).unwrap());
            assert_eq!(postcard::from_bytes::<DriveMsg>(&typed[..n]), Ok(new));
        }
    }

    /// Every integer field at the edges of postcard's varint lengths: the same bytes as
    /// the plain derive, and back.
    #[test]
    fn status_fields_keep_the_wire_bytes() {
        let mut typed = [0u8; 64];
        let mut untyped = [0u8; 64];
        let edges_u = [0u16, 1, 127, 128, 16_383, 16_384, u16::MAX];
        let edges_i = [
            0i16,
            -1,
            1,
            -64,
            63,
            64,
            -65,
            8191,
            -8192,
            i16::MIN,
            i16::MAX,
        ];
        for k in 0..edges_u.len() * edges_i.len() {
            let u = |n: usize| edges_u[(k + n) % edges_u.len()];
            let i = |n: usize| edges_i[(k + n) % edges_i.len()];
            let s = DriveStatus {
                state: DriveState::Run,
                fault: None,
                freq_dhz: i(0),
                reverse: k % 2 == 0,
                udc_dv: i(1),
                imax_ca: i(2),
                com: u(0),
                oc_hw_ca: i(3),
                ov_hw_v: i(4),
                warning: None,
                sf_requested: u(1),
                sf_status: u(2),
                sf_sdc: k % 3 == 0,
                sf_elapsed_ds: u(3),
                sf_signature: u(4),
                sto_in_low: k % 5 == 0,
                program_loaded: k % 7 == 0,
                sf_turns: i(5),
            };
            let old = UntypedStatus {
                state: s.state,
                fault: 0,
                freq_dhz: s.freq_dhz,
                reverse: s.reverse,
                udc_dv: s.udc_dv,
                imax_ca: s.imax_ca,
                com: s.com,
                oc_hw_ca: s.oc_hw_ca,
                ov_hw_v: s.ov_hw_v,
                warning: s.warning,
                sf_requested: s.sf_requested,
                sf_status: s.sf_status,
                sf_sdc: s.sf_sdc,
                sf_elapsed_ds: s.sf_elapsed_ds,
                sf_signature: s.sf_signature,
                sto_in_low: s.sto_in_low,
                program_loaded: s.program_loaded,
                sf_turns: s.sf_turns,
            };
            let n = postcard::to_slice(&s, &mut typed).unwrap().len();
            assert_eq!(typed[..n], *postcard::to_slice(&old, &mut untyped).unwrap());
            assert_eq!(postcard::from_bytes::<DriveStatus>(&typed[..n]), Ok(s));
        }
    }

    /// The other fields serialised through `one_copy`: the derive's bytes.
    #[test]
    fn hello_and_download_keep_the_wire_bytes() {
        #[derive(Serialize)]
        enum Plain {
            HelloReply { version: u16, session: u8 },
            _Ack,
            _Status,
            Download(PlainResult),
        }
        #[derive(Serialize)]
        enum PlainResult {
            _Accepted,
            Rejected { line: u16, reason: RejectReason },
        }
        let mut typed = [0u8; 64];
        let mut plain = [0u8; 64];
        for v in [0u16, 127, 128, 16_384, u16::MAX] {
            let n = postcard::to_slice(
                &DriveMsg::HelloReply {
                    version: v,
                    session: v as u8,
                },
                &mut typed,
            )
            .unwrap()
            .len();
            let old = Plain::HelloReply {
                version: v,
                session: v as u8,
            };
            assert_eq!(typed[..n], *postcard::to_slice(&old, &mut plain).unwrap());
            let reason = RejectReason::Verify(v as u8);
            let n = postcard::to_slice(
                &DriveMsg::Download(DownloadResult::Rejected { line: v, reason }),
                &mut typed,
            )
            .unwrap()
            .len();
            let old = Plain::Download(PlainResult::Rejected { line: v, reason });
            assert_eq!(typed[..n], *postcard::to_slice(&old, &mut plain).unwrap());
        }
    }

    /// A frame (valid CRC) whose fault byte no `FaultCode` has: refused as a message
    /// that does not parse, counted by the receiver as a bad frame.
    #[test]
    fn an_undefined_fault_code_makes_the_frame_unparsable() {
        let mut wire = [0u8; 128];
        let undefined = FaultCode::COUNT as u8 + 1;
        for code in [0u8, undefined, 200] {
            let frame = Frame {
                seq: 0,
                ack: 0,
                msg: UntypedDriveMsg::Fault {
                    code,
                    drive_time_ms: 1,
                },
            };
            let n = encode_frame(&frame, false, &mut wire).unwrap();
            let mut r = FrameReader::new();
            let got = wire[..n].iter().find_map(|&b| r.push::<DriveMsg>(b));
            assert_eq!(got, Some(Err(FrameError::Message)), "code {code}");
        }
        // The status's 0 is "no fault"; an undefined code there is refused too.
        let mut raw = [0u8; 64];
        let ok = postcard::to_slice(
            &Frame {
                seq: 0,
                ack: 0,
                msg: DriveMsg::Status(status(None)),
            },
            &mut raw,
        )
        .unwrap()
        .len();
        let fault_at = 2 + 1 + 1; // seq, ack, message type, state
        assert_eq!(raw[fault_at], 0);
        raw[fault_at] = FaultCode::COUNT as u8 + 1;
        let crc = crate::link::frame::CRC.checksum(&raw[..ok]);
        raw[ok..ok + 4].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            decode_raw::<DriveMsg>(&raw[..ok + 4]),
            Err(FrameError::Message)
        );
        raw[fault_at] = 3;
        let crc = crate::link::frame::CRC.checksum(&raw[..ok]);
        raw[ok..ok + 4].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            decode_raw::<DriveMsg>(&raw[..ok + 4]).map(|f| f.msg),
            Ok(DriveMsg::Status(status(Some(FaultCode::OvHw))))
        );
    }
}
