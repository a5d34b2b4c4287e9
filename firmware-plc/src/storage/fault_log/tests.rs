use super::super::MemEeprom;
use super::*;

fn entry(code: u8, power_cycle: u16, uptime_s: u32) -> FaultEntry {
    FaultEntry::new(code, power_cycle, uptime_s)
}

/// A format-2 entry with a time of day and values.
fn full(code: u8, power_cycle: u16, uptime_s: u32) -> FaultEntry {
    FaultEntry {
        wall_s: 848_000_000 + uptime_s,
        values: [code as i16 % 5, -(power_cycle as i16)],
        ..entry(code, power_cycle, uptime_s)
    }
}

fn all(e: &mut MemEeprom) -> heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES> {
    let mut v = heapless::Vec::new();
    read_all(e, &mut v).unwrap();
    v
}

#[test]
fn keeps_newest_16_newest_first() {
    let mut e = MemEeprom::new();
    assert!(all(&mut e).is_empty());
    for n in 0..40u32 {
        // Two faults per second, power cycle changing every 10 entries.
        append(&mut e, full(1 + (n % 7) as u8, (n / 10) as u16, n / 2)).unwrap();
    }
    let v = all(&mut e);
    let expect: heapless::Vec<FaultEntry, 16> = (24..40u32)
        .rev()
        .map(|n| full(1 + (n % 7) as u8, (n / 10) as u16, n / 2))
        .collect();
    assert_eq!(v, expect);
}

#[test]
fn an_entry_keeps_its_time_of_day_and_values() {
    let e = FaultEntry {
        wall_s: 0xFFFF_FFFE,
        values: [i16::MAX, -32767],
        ..entry(110, 65535, UPTIME_MAX_S)
    };
    let b = e.to_bytes();
    assert_eq!(FaultEntry::parse(&b), Some(e));
    assert_eq!(
        (e.wall(), e.value(0), e.value(1)),
        (Some(0xFFFF_FFFE), Some(i16::MAX), Some(-32767))
    );
    // Unset clock, no values.
    let none = entry(4, 1, 2);
    assert_eq!(FaultEntry::parse(&none.to_bytes()), Some(none));
    assert_eq!(
        (none.wall(), none.value(0), none.value(1)),
        (None, None, None)
    );
    // Uptime saturates at 24 bits.
    let long = FaultEntry::parse(&entry(4, 1, u32::MAX).to_bytes()).unwrap();
    assert_eq!(long.uptime_s, UPTIME_MAX_S);
    // Every single bit flipped is caught, as is an erased or zeroed slot.
    for bit in 0..8 * FAULT_ENTRY_BYTES {
        let mut x = b;
        x[bit / 8] ^= 1 << (bit % 8);
        assert_eq!(FaultEntry::parse(&x), None, "bit {bit}");
    }
    assert_eq!(FaultEntry::parse(&[0xFF; 16]), None);
    assert_eq!(FaultEntry::parse(&[0; 16]), None);
}

#[test]
fn torn_entry_loses_only_itself() {
    let mut e = MemEeprom::new();
    for n in 0..5u32 {
        append(&mut e, full(3, 1, n)).unwrap();
    }
    for cut in 1..FAULT_ENTRY_BYTES as u32 {
        let mut f = e.clone();
        f.cut_power_after(cut);
        assert!(append(&mut f, full(4, 2, 0)).is_err());
        f.restore_power();
        let v = all(&mut f);
        assert_eq!(v.len(), 5, "cut {cut}");
        assert_eq!(v[0], full(3, 1, 4));
        append(&mut f, full(5, 2, 1)).unwrap();
        assert_eq!(all(&mut f)[0], full(5, 2, 1));
    }
}

#[test]
fn power_cycle_wraps() {
    let mut e = MemEeprom::new();
    append(&mut e, entry(1, u16::MAX, 5)).unwrap();
    append(&mut e, entry(2, 0, 1)).unwrap();
    append(&mut e, entry(3, 1, 1)).unwrap();
    let codes: heapless::Vec<u8, 16> = all(&mut e).iter().map(|x| x.code).collect();
    assert_eq!(&codes[..], &[3, 2, 1]);
    clear(&mut e).unwrap();
    assert!(all(&mut e).is_empty());
}

/// Fault-log areas (pages 2-5) written by the format-1 firmware (`fault_log.rs` before
/// format 2, through its `append` and `clear` on a `MemEeprom`), one slot a line, and what
/// that firmware's `read_all` listed (code, power cycle, uptime; newest first).
struct V1Image {
    name: &'static str,
    hex: &'static str,
    list: &'static str,
}

const V1_IMAGES: [V1Image; 3] = [
    // 37 appends: the ring wrapped, the newest entry is the first half of its slot.
    V1Image {
        name: "wrapped_even",
        hex: include_str!("v1_wrapped_even.hex"),
        list: include_str!("v1_wrapped_even.list"),
    },
    // 40 appends, power cycles wrapping past 65535: the newest is a second half.
    V1Image {
        name: "wrapped_odd",
        hex: include_str!("v1_wrapped_odd.hex"),
        list: include_str!("v1_wrapped_odd.list"),
    },
    // Cleared, LOGCLR and 9 entries, then an append cut by a power loss.
    V1Image {
        name: "partial_torn",
        hex: include_str!("v1_partial_torn.hex"),
        list: include_str!("v1_partial_torn.list"),
    },
];

impl V1Image {
    fn eeprom(&self) -> MemEeprom {
        let mut image = [0xFFu8; super::super::EEPROM_BYTES];
        let bytes: std::vec::Vec<u8> = self
            .hex
            .split_whitespace()
            .flat_map(|line| {
                (0..line.len())
                    .step_by(2)
                    .map(move |i| u8::from_str_radix(&line[i..i + 2], 16).unwrap())
            })
            .collect();
        assert_eq!(bytes.len(), LOG_BYTES, "{}", self.name);
        let at = usize::from(FAULT_LOG_ADDR);
        image[at..at + LOG_BYTES].copy_from_slice(&bytes);
        MemEeprom::from_image(&image)
    }

    fn listed(&self) -> std::vec::Vec<FaultEntry> {
        self.list
            .lines()
            .map(|l| {
                let f: std::vec::Vec<u32> =
                    l.split_whitespace().map(|x| x.parse().unwrap()).collect();
                entry(f[0] as u8, f[1] as u16, f[2])
            })
            .collect()
    }
}

#[test]
fn a_format_1_log_reads_as_its_firmware_listed_it() {
    for img in &V1_IMAGES {
        let mut e = img.eeprom();
        let listed = img.listed();
        let v = all(&mut e);
        // The newest 16, in the same order, without time of day or values.
        let n = listed.len().min(FAULT_LOG_ENTRIES);
        assert_eq!(&v[..], &listed[..n], "{}", img.name);
        assert!(v.iter().all(|x| x.wall().is_none() && x.value(0).is_none()));
    }
}

/// After the update the log is never rewritten: each new entry replaces the oldest ones,
/// the newest-first list is the new entries, then what is left of the old ones in their
/// order, and the application's copy (insert in front, keep 16) stays equal to it.
#[test]
fn new_entries_replace_a_format_1_log_from_its_oldest() {
    for img in &V1_IMAGES {
        let mut e = img.eeprom();
        let old = img.listed();
        let mut ram: std::vec::Vec<FaultEntry> = all(&mut e).to_vec();
        let mut new: std::vec::Vec<FaultEntry> = std::vec::Vec::new();
        for k in 0..20u32 {
            let x = full(101 + k as u8, 2000, k);
            append(&mut e, x).unwrap();
            new.insert(0, x);
            ram.insert(0, x);
            ram.truncate(FAULT_LOG_ENTRIES);
            let v = all(&mut e);
            assert_eq!(&v[..], &ram[..], "{} after {} appends", img.name, k + 1);
            let n = new.len().min(FAULT_LOG_ENTRIES);
            assert_eq!(&v[..n], &new[..n], "{}", img.name);
            // The old entries left are the newest of the old list, in order.
            let rest = &v[n..];
            assert_eq!(
                rest,
                &old[..rest.len()],
                "{} after {} appends",
                img.name,
                k + 1
            );
        }
        assert!(all(&mut e).iter().all(|x| x.code > 100), "{}", img.name);
    }
}

#[test]
fn the_append_address_follows_the_newest_entry_of_either_format() {
    // Format 1 only: the slot after the newest half's.
    let img = &V1_IMAGES[0];
    let mut e = img.eeprom();
    let mut raw = [0u8; LOG_BYTES];
    e.read(FAULT_LOG_ADDR, &mut raw).unwrap();
    let mut f = RingFinder::default();
    f.push_bytes(&raw);
    // 37 appends: the newest is half 36 % 32 = 4, in slot 2.
    assert_eq!(f.heads(), (None, Some(4)));
    assert_eq!(f.append_addr(), FAULT_LOG_ADDR + 3 * 16);
    append(&mut e, full(7, 9, 9)).unwrap();
    e.read(FAULT_LOG_ADDR, &mut raw).unwrap();
    let mut f = RingFinder::default();
    f.push_bytes(&raw);
    assert_eq!(f.heads(), (Some(3), Some(4)));
    assert_eq!(f.append_addr(), FAULT_LOG_ADDR + 4 * 16);
    // Fed page by page (the job) as in one piece.
    let mut g = RingFinder::default();
    for page in raw.chunks(PAGE_BYTES) {
        g.push_bytes(page);
    }
    assert_eq!(g, f);
}

/// Module doc: a slot of format-1 entries (two valid ones, or a valid one and an erased
/// one) is never read as a format-2 entry, whatever the entries hold.
#[test]
fn format_1_slots_never_pass_as_format_2() {
    fn v1(code: u8, pc: u16, up: u32) -> [u8; 8] {
        let [p0, p1] = pc.to_be_bytes();
        let [_, u0, u1, u2] = up.to_be_bytes();
        let body = [code, p0, p1, u0, u1, u2];
        let [c0, c1] = CRC16.checksum(&body).to_be_bytes();
        [code, p0, p1, u0, u1, u2, c0, c1]
    }
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for _ in 0..200_000 {
        let r = next();
        let a = v1(
            1 + (r % 254) as u8,
            (r >> 8) as u16,
            (r >> 24) as u32 & UPTIME_MAX_S,
        );
        let r = next();
        let b = v1(
            1 + (r % 254) as u8,
            (r >> 8) as u16,
            (r >> 24) as u32 & UPTIME_MAX_S,
        );
        assert!(FaultEntry::parse(&a).is_some());
        let mut slot = [0xFFu8; 16];
        slot[..8].copy_from_slice(&a);
        assert_eq!(FaultEntry::parse(&slot), None, "{slot:02x?}");
        slot[8..].copy_from_slice(&b);
        assert_eq!(FaultEntry::parse(&slot), None, "{slot:02x?}");
    }
}
