//! The counters record (service.md 7, `docs/eeprom-image.md` "Counters"): two copies in
//! pages 510 and 511, one record of at most 64 bytes each, big-endian, saturating, CRC-16.
//!
//! As with the boot record, a write goes to the copy not holding the newest valid record,
//! with the next sequence number, so a power cut while writing it leaves the previous
//! record in force. This module is the record's bytes only; when it is written is the
//! tally's business (`service::counters`).
//!
//! The record holds one trip counter per fault code ([`TRIP_CODES`] follows the fault
//! table), so a new code needs a new record [`Format`]: [`FORMATS`] lists every format
//! this firmware reads, the last one is written. A record of an older format is read (its
//! missing counters are 0) and the next write replaces it with the newest. A compile-time
//! check refuses a fault table that the newest format does not hold.

use super::fault_log::CRC16;

use super::eeprom::PAGE_BYTES;
use super::layout::COUNTERS_ADDR;
use shared_protocol::fault::FaultCode;

/// A copy's size: one page.
pub const COUNTERS_BYTES: usize = PAGE_BYTES;
/// Largest value of a 3-byte field.
pub const U24_MAX: u32 = 0xFF_FFFF;
/// Fault codes with a trip counter: every code of the fault table.
pub const TRIP_CODES: usize = FaultCode::COUNT;
/// Application counters (Q60-Q63).
pub const APP_COUNTERS: usize = 4;

/// One layout of the record: magic, sequence, the fields of [`CounterValues`] with
/// `trips` counters, CRC-16 over everything before it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Format {
    /// The first bytes, which tell the formats apart.
    pub magic: &'static [u8],
    /// Bytes of the sequence number (compared modulo 2^(8 x this)).
    pub seq_bytes: usize,
    /// Trip counters it holds (codes 1..=trips).
    pub trips: usize,
}

impl Format {
    /// Bytes of a record in this format, CRC included.
    pub const fn bytes(&self) -> usize {
        self.magic.len() + self.seq_bytes + 4 * 3 + 2 + 2 * self.trips + 3 * APP_COUNTERS + 2
    }
}

/// `C1`: fault codes 1-16, 64 bytes.
pub const V1: Format = Format {
    magic: b"C1",
    seq_bytes: 2,
    trips: 16,
};

/// `0xC2`: fault codes 1-17, 64 bytes. One more trip counter than `C1` fits the page
/// only with a one-byte magic and a one-byte sequence (two copies alternate, so modulo
/// 2^8 tells the newer as well as 2^16 did).
pub const V2: Format = Format {
    magic: &[0xC2],
    seq_bytes: 1,
    trips: 17,
};

/// The formats read, oldest first; the last is the one written.
pub const FORMATS: [Format; 2] = [V1, V2];
const NEWEST: Format = V2;

const _: () = assert!(
    NEWEST.trips == TRIP_CODES,
    "the fault table changed: add a counters record format (docs/contributing/add-a-trip.md)"
);
const _: () = assert!(NEWEST.bytes() <= COUNTERS_BYTES, "a record is one page");

/// The counted values (the record without magic, sequence and CRC).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CounterValues {
    /// RUN starts (keypad, power-up, service), u24.
    pub run_starts: u32,
    /// Whole minutes in RUN, u24.
    pub run_minutes: u32,
    /// Whole minutes with the drive's PWM on, u24.
    pub pwm_minutes: u32,
    /// Link frames rejected plus link losses (PLC side), u24.
    pub link_errors: u32,
    /// Program saves (keypad and service).
    pub program_saves: u16,
    /// Trips per fault code (index 0 = code 1).
    pub trips: [u16; TRIP_CODES],
    /// Application counters 1-4 (Q60-Q63), u24.
    pub app: [u32; APP_COUNTERS],
}

/// Adds `n` to a 3-byte field, saturating.
pub fn add_u24(field: &mut u32, n: u32) {
    *field = field.saturating_add(n).min(U24_MAX);
}

/// Adds `n` to a 2-byte field, saturating.
pub fn add_u16(field: &mut u16, n: u16) {
    *field = field.saturating_add(n);
}

impl CounterValues {
    /// `self` plus `other`, field by field, saturating (counts made before the record was
    /// read at power-up are added to it).
    pub fn plus(&self, other: &CounterValues) -> CounterValues {
        let mut out = *self;
        add_u24(&mut out.run_starts, other.run_starts);
        add_u24(&mut out.run_minutes, other.run_minutes);
        add_u24(&mut out.pwm_minutes, other.pwm_minutes);
        add_u24(&mut out.link_errors, other.link_errors);
        add_u16(&mut out.program_saves, other.program_saves);
        for (a, b) in out.trips.iter_mut().zip(other.trips) {
            add_u16(a, b);
        }
        for (a, b) in out.app.iter_mut().zip(other.app) {
            add_u24(a, b);
        }
        out
    }

    /// The record in the newest format with sequence `seq` (its low bytes when the
    /// format's sequence is shorter), CRC included; bytes after it in the page are `FF`.
    pub fn to_bytes(&self, seq: u16) -> [u8; COUNTERS_BYTES] {
        self.to_bytes_as(&NEWEST, seq)
    }

    /// The record in `format` (the newest one, or an old one for the tests of reading).
    pub fn to_bytes_as(&self, format: &Format, seq: u16) -> [u8; COUNTERS_BYTES] {
        let mut w = Writer {
            buf: [0xFF; COUNTERS_BYTES],
            at: 0,
        };
        w.put(format.magic);
        let seq = seq.to_be_bytes();
        w.put(
            seq.get(2usize.saturating_sub(format.seq_bytes)..)
                .unwrap_or(&[]),
        );
        w.u24(self.run_starts);
        w.u24(self.run_minutes);
        w.u24(self.pwm_minutes);
        w.u24(self.link_errors);
        w.put(&self.program_saves.to_be_bytes());
        for i in 0..format.trips {
            w.put(&self.trips.get(i).copied().unwrap_or(0).to_be_bytes());
        }
        for a in self.app {
            w.u24(a);
        }
        let crc = CRC16.checksum(w.buf.get(..w.at).unwrap_or(&[]));
        w.put(&crc.to_be_bytes());
        w.buf
    }
}

struct Writer {
    buf: [u8; COUNTERS_BYTES],
    at: usize,
}

impl Writer {
    fn put(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(d) = self.buf.get_mut(self.at) {
                *d = b;
            }
            self.at += 1;
        }
    }

    fn u24(&mut self, v: u32) {
        let b = v.min(U24_MAX).to_be_bytes();
        self.put(b.get(1..).unwrap_or(&[]));
    }
}

struct Reader<'a> {
    buf: &'a [u8; COUNTERS_BYTES],
    at: usize,
}

impl Reader<'_> {
    fn byte(&mut self) -> u8 {
        let b = self.buf.get(self.at).copied().unwrap_or(0);
        self.at += 1;
        b
    }

    fn u16(&mut self) -> u16 {
        u16::from_be_bytes([self.byte(), self.byte()])
    }

    fn u24(&mut self) -> u32 {
        u32::from_be_bytes([0, self.byte(), self.byte(), self.byte()])
    }
}

/// Where a valid copy stands: its format (position in [`FORMATS`]) and sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    pub format: usize,
    pub seq: u16,
}

/// What one copy holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CopyState {
    /// Never written (all `FF`).
    Erased,
    /// Torn, overwritten or flipped: no known magic, or a wrong CRC.
    Bad,
    /// A valid record with its format and sequence.
    Valid(Stamp, CounterValues),
}

/// Reads one copy's bytes, in whichever of [`FORMATS`] its magic names.
pub fn parse(buf: &[u8; COUNTERS_BYTES]) -> CopyState {
    if buf.iter().all(|&b| b == 0xFF) {
        return CopyState::Erased;
    }
    let Some((format, f)) = FORMATS
        .iter()
        .enumerate()
        .find(|(_, f)| buf.starts_with(f.magic))
    else {
        return CopyState::Bad;
    };
    let len = f.bytes().min(COUNTERS_BYTES);
    let (body, crc) = buf.split_at(len - 2);
    let stored = u16::from_be_bytes([
        crc.first().copied().unwrap_or(0),
        crc.get(1).copied().unwrap_or(0),
    ]);
    if CRC16.checksum(body) != stored {
        return CopyState::Bad;
    }
    let mut r = Reader {
        buf,
        at: f.magic.len(),
    };
    let seq = if f.seq_bytes == 2 {
        r.u16()
    } else {
        u16::from(r.byte())
    };
    let mut v = CounterValues {
        run_starts: r.u24(),
        run_minutes: r.u24(),
        pwm_minutes: r.u24(),
        link_errors: r.u24(),
        program_saves: r.u16(),
        ..CounterValues::default()
    };
    for t in v.trips.iter_mut().take(f.trips) {
        *t = r.u16();
    }
    for a in v.app.iter_mut() {
        *a = r.u24();
    }
    CopyState::Valid(Stamp { format, seq }, v)
}

/// What the two copies give at power-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Found {
    /// The newest valid record (sequences compared modulo 2^16), or zeros.
    pub values: CounterValues,
    /// Where the next write goes (0: page 510, 1: page 511) and its sequence.
    pub next_copy: usize,
    pub next_seq: u16,
    /// Both copies bad (neither valid nor erased): the counters restart at 0 and the LCD
    /// says `COUNTERS RESET`. Erased copies (a new chip, or a first write that was cut
    /// beside one never written) restart them silently.
    pub reset: bool,
}

/// `a` is newer than `b`: a newer format always (an older one is never written again),
/// in the same format the sequence modulo 2^(8 x its bytes).
fn newer(a: Stamp, b: Stamp) -> bool {
    if a.format != b.format {
        return a.format > b.format;
    }
    let one_byte = FORMATS.get(a.format).is_some_and(|f| f.seq_bytes == 1);
    if one_byte {
        (a.seq.wrapping_sub(b.seq) as u8 as i8) > 0
    } else {
        (a.seq.wrapping_sub(b.seq) as i16) > 0
    }
}

/// The sequence after `s`, in its format's width.
fn next(s: Stamp) -> u16 {
    let n = s.seq.wrapping_add(1);
    match FORMATS.get(s.format) {
        Some(f) if f.seq_bytes == 1 => n & 0xFF,
        _ => n,
    }
}

/// The record in force from both copies (copy 0 = page 510, copy 1 = page 511).
pub fn choose(copies: [CopyState; 2]) -> Found {
    let [a, b] = copies;
    let newest = match (a, b) {
        (CopyState::Valid(sa, va), CopyState::Valid(sb, vb)) => {
            if newer(sb, sa) {
                Some((1, sb, vb))
            } else {
                Some((0, sa, va))
            }
        }
        (CopyState::Valid(s, v), _) => Some((0, s, v)),
        (_, CopyState::Valid(s, v)) => Some((1, s, v)),
        _ => None,
    };
    match newest {
        Some((copy, stamp, values)) => Found {
            values,
            next_copy: 1 - copy,
            next_seq: next(stamp),
            reset: false,
        },
        None => Found {
            values: CounterValues::default(),
            next_copy: 0,
            next_seq: 1,
            reset: a == CopyState::Bad && b == CopyState::Bad,
        },
    }
}

/// EEPROM address of copy `copy` (0; anything else is 1).
pub fn copy_addr(copy: usize) -> u16 {
    let [a, b] = COUNTERS_ADDR;
    if copy == 0 {
        a
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> CounterValues {
        CounterValues {
            run_starts: 3,
            run_minutes: 0x12_3456,
            pwm_minutes: 7,
            link_errors: U24_MAX,
            program_saves: 9,
            trips: core::array::from_fn(|i| i as u16 * 300),
            app: [1, 2, 0xAB_CDEF, 4],
        }
    }

    /// `v` as a record of `format` reads it: the counters of codes it has no room for
    /// are 0.
    fn as_read_from(format: &Format, mut v: CounterValues) -> CounterValues {
        for t in v.trips.iter_mut().skip(format.trips) {
            *t = 0;
        }
        v
    }

    #[test]
    fn the_record_has_the_layout_of_service_md_7() {
        let b = sample().to_bytes_as(&V1, 0x0102);
        assert_eq!(&b[0..4], b"C1\x01\x02");
        assert_eq!(&b[4..7], &[0, 0, 3]);
        assert_eq!(&b[7..10], &[0x12, 0x34, 0x56]);
        assert_eq!(&b[13..16], &[0xFF, 0xFF, 0xFF]);
        assert_eq!(&b[16..18], &[0, 9]);
        assert_eq!(&b[18..20], &[0, 0]);
        assert_eq!(&b[20..22], &[1, 44]);
        assert_eq!(&b[50..53], &[0, 0, 1]);
        assert_eq!(&b[56..59], &[0xAB, 0xCD, 0xEF]);
        assert_eq!(u16::from_be_bytes([b[62], b[63]]), CRC16.checksum(&b[..62]));
        assert_eq!(
            parse(&b),
            CopyState::Valid(
                Stamp {
                    format: 0,
                    seq: 0x0102
                },
                as_read_from(&V1, sample())
            )
        );
    }

    /// Every format this firmware knows is read, an older one loses against the newest
    /// whatever its sequence (a firmware update: the next write is the newest format, the
    /// old copy keeps its counts until then), and each fits one page.
    #[test]
    fn old_formats_still_read_and_the_newest_wins() {
        assert_eq!(FORMATS.last(), Some(&NEWEST));
        for (i, f) in FORMATS.iter().enumerate() {
            assert!(f.bytes() <= COUNTERS_BYTES, "{f:?}");
            let v = as_read_from(f, sample());
            let b = sample().to_bytes_as(f, 0x0107);
            let seq = if f.seq_bytes == 2 { 0x0107 } else { 0x07 };
            assert_eq!(
                parse(&b),
                CopyState::Valid(Stamp { format: i, seq }, v),
                "{f:?}"
            );
            let newest = CounterValues::default().to_bytes(3);
            let found = choose([parse(&b), parse(&newest)]);
            let want = if i + 1 == FORMATS.len() {
                v
            } else {
                Default::default()
            };
            assert_eq!(found.values, want, "{f:?}");
        }
        for w in FORMATS.windows(2) {
            assert!(w[0].trips < w[1].trips && w[0].magic != w[1].magic);
        }
    }

    #[test]
    fn fields_saturate() {
        let mut v = CounterValues {
            run_starts: U24_MAX - 1,
            program_saves: u16::MAX - 1,
            ..Default::default()
        };
        v = v.plus(&v);
        assert_eq!(v.run_starts, U24_MAX);
        assert_eq!(v.program_saves, u16::MAX);
        let mut x = U24_MAX + 5;
        add_u24(&mut x, 0);
        assert_eq!(x, U24_MAX);
    }

    #[test]
    fn any_flipped_bit_makes_a_copy_bad_and_the_other_counts() {
        let old = sample().to_bytes(7);
        let mut newer_values = sample();
        newer_values.run_starts += 1;
        let new = newer_values.to_bytes(8);
        for byte in 0..COUNTERS_BYTES {
            for bit in 0..8 {
                let mut b = new;
                b[byte] ^= 1 << bit;
                assert_eq!(parse(&b), CopyState::Bad, "{byte}.{bit}");
                let f = choose([parse(&old), parse(&b)]);
                assert_eq!((f.values, f.next_copy, f.next_seq), (sample(), 1, 8));
            }
        }
    }

    #[test]
    fn the_newer_sequence_counts_modulo_2_16() {
        let a = sample().to_bytes(0xFFFF);
        let b = CounterValues::default().to_bytes(0);
        let f = choose([parse(&a), parse(&b)]);
        assert_eq!(
            (f.values, f.next_copy, f.next_seq),
            (Default::default(), 0, 1)
        );
        let f = choose([parse(&b), parse(&a)]);
        assert_eq!(
            (f.values, f.next_copy, f.next_seq),
            (Default::default(), 1, 1)
        );
        let f = choose([parse(&a), CopyState::Erased]);
        assert_eq!((f.values, f.next_copy, f.next_seq), (sample(), 1, 0));
    }

    #[test]
    fn both_bad_restarts_at_zero_with_the_message_erased_silently() {
        let f = choose([CopyState::Bad, CopyState::Bad]);
        assert_eq!(
            (f.values, f.reset, f.next_copy),
            (Default::default(), true, 0)
        );
        assert!(!choose([CopyState::Erased, CopyState::Erased]).reset);
        assert!(!choose([CopyState::Bad, CopyState::Erased]).reset);
        assert_eq!(parse(&[0xFF; COUNTERS_BYTES]), CopyState::Erased);
        assert_eq!(parse(&[0; COUNTERS_BYTES]), CopyState::Bad);
    }
}
