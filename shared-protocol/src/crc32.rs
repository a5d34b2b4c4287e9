//! The CRC-32s of both images, one implementation: reflected CRC-32s (init and final XOR
//! `0xFFFF_FFFF`) with a table per polynomial, built at compile time.
//!
//! Two polynomials are in use, with different tables (they cannot share one):
//! * [`CASTAGNOLI`], CRC-32C (`crc::CRC_32_ISCSI`): the link's and the service port's
//!   frames, the drive-section download and the service's program payloads. A byte table
//!   (1 KiB): the drive checks frames and downloads inside its critical sections against the
//!   PWM interrupt (`firmware-drive/docs/critical-sections.md`), where one table look-up per
//!   byte matters (about 6 instructions per byte, against about 10 with the nibble table).
//!   The PLC image, which has no such interrupt, takes the nibble table (feature
//!   `crc32c-nibble-table`); the values are the same (a test checks both tables).
//! * [`ISO_HDLC`], CRC-32 (`crc::CRC_32_ISO_HDLC`): the PLC's stored program copies and
//!   boot records. A nibble table (64 B): it runs only in the PLC's storage steps, which
//!   have no such budget.

/// A reflected CRC-32 with a table of `N` entries: 256 (one look-up per byte) or 16 (two
/// per byte).
#[derive(Debug)]
pub struct Crc32<const N: usize> {
    table: [u32; N],
}

/// CRC-32C (Castagnoli, reflected polynomial `0x82F6_3B78`): a byte table, or a nibble
/// table with feature `crc32c-nibble-table` (the PLC image: no PWM interrupt to keep short,
/// and 960 B of flash back).
pub static CASTAGNOLI: Crc32<CASTAGNOLI_ENTRIES> = Crc32::new(0x82F6_3B78);
/// The entries of [`CASTAGNOLI`]'s table.
pub const CASTAGNOLI_ENTRIES: usize = if cfg!(feature = "crc32c-nibble-table") {
    16
} else {
    256
};
/// A running [`CASTAGNOLI`].
pub type CastagnoliDigest = Digest<CASTAGNOLI_ENTRIES>;
/// CRC-32 (ISO-HDLC, reflected polynomial `0xEDB8_8320`), nibble table.
pub static ISO_HDLC: Crc32<16> = Crc32::new(0xEDB8_8320);

impl<const N: usize> Crc32<N> {
    /// The table of `poly` (reflected) for `N` = 256 or 16 entries.
    #[allow(
        clippy::indexing_slicing,
        reason = "`i < N` indexes a table of N entries; `get_mut` is not usable in a const fn"
    )]
    pub const fn new(poly: u32) -> Self {
        let bits = if N == 256 { 8 } else { 4 };
        let mut table = [0u32; N];
        let mut i = 0;
        while i < N {
            let mut c = i as u32;
            let mut k = 0;
            while k < bits {
                c = if c & 1 != 0 { (c >> 1) ^ poly } else { c >> 1 };
                k += 1;
            }
            table[i] = c;
            i += 1;
        }
        Crc32 { table }
    }

    /// The CRC of `bytes`.
    pub fn checksum(&'static self, bytes: &[u8]) -> u32 {
        let mut d = self.digest();
        d.update(bytes);
        d.finalize()
    }

    /// A running CRC, fed piece by piece.
    pub const fn digest(&'static self) -> Digest<N> {
        Digest {
            crc: self,
            value: 0xFFFF_FFFF,
        }
    }

    /// One table step: the low `log2(N)` bits of `v` shifted out.
    #[inline(always)]
    fn step(&self, v: u32) -> u32 {
        let shift = if N == 256 { 8 } else { 4 };
        let i = (v as usize) & (N - 1);
        self.table.get(i).copied().unwrap_or(0) ^ (v >> shift)
    }

    #[inline(never)]
    fn update(&self, mut v: u32, bytes: &[u8]) -> u32 {
        for &b in bytes {
            v ^= u32::from(b);
            v = self.step(v);
            if N != 256 {
                v = self.step(v);
            }
        }
        v
    }
}

/// A CRC over bytes given in pieces.
#[derive(Debug, Clone)]
pub struct Digest<const N: usize> {
    crc: &'static Crc32<N>,
    value: u32,
}

impl<const N: usize> Digest<N> {
    pub fn update(&mut self, bytes: &[u8]) {
        self.value = self.crc.update(self.value, bytes);
    }

    pub fn finalize(self) -> u32 {
        self.value ^ 0xFFFF_FFFF
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crc::{Crc, CRC_32_ISCSI, CRC_32_ISO_HDLC};

    #[test]
    fn both_match_the_catalogue_and_the_crc_crate() {
        // The catalogue's check values (CRC of "123456789").
        assert_eq!(CASTAGNOLI.checksum(b"123456789"), 0xE306_9283);
        assert_eq!(ISO_HDLC.checksum(b"123456789"), 0xCBF4_3926);
        let c = Crc::<u32>::new(&CRC_32_ISCSI);
        let i = Crc::<u32>::new(&CRC_32_ISO_HDLC);
        let data: std::vec::Vec<u8> = (0..600u32).map(|n| (n * 7 + n / 13) as u8).collect();
        for len in [0, 1, 2, 15, 16, 17, 255, 600] {
            assert_eq!(CASTAGNOLI.checksum(&data[..len]), c.checksum(&data[..len]));
            assert_eq!(ISO_HDLC.checksum(&data[..len]), i.checksum(&data[..len]));
        }
    }

    /// The PLC image's CRC-32C (nibble table) equals the drive's (byte table).
    #[test]
    fn the_nibble_and_byte_tables_of_crc32c_agree() {
        static NIBBLE: Crc32<16> = Crc32::new(0x82F6_3B78);
        static BYTE: Crc32<256> = Crc32::new(0x82F6_3B78);
        let data: std::vec::Vec<u8> = (0..600u32).map(|n| (n * 31 + n / 7) as u8).collect();
        for len in [0, 1, 2, 15, 16, 17, 255, 600] {
            assert_eq!(NIBBLE.checksum(&data[..len]), BYTE.checksum(&data[..len]));
        }
    }

    #[test]
    fn pieces_give_the_crc_of_the_whole() {
        let data = [0xA5u8; 100];
        let mut d = ISO_HDLC.digest();
        for piece in data.chunks(7) {
            d.update(piece);
        }
        assert_eq!(d.clone().finalize(), ISO_HDLC.checksum(&data));
        let mut d = CASTAGNOLI.digest();
        d.update(&data[..50]);
        d.update(&data[50..]);
        assert_eq!(d.finalize(), CASTAGNOLI.checksum(&data));
    }
}
