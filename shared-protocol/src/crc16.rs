//! CRC-16/IBM-3740 (poly 0x1021, init 0xFFFF, not reflected, xorout 0; check 0x29B1), the
//! safety settings' signature (safety.md 8) and the PLC's fault log and counters records:
//! one definition, so that an image links one implementation.
//!
//! The `crc` crate's byte table (512 B) by default: the drive checks a new section's
//! signature inside a critical section against the PWM interrupt, where a bitwise CRC of
//! the 48 bytes costs ~2 300 instructions (the emulated link section reached 9 872
//! cycles, over its 8 500 budget). The PLC image, which has no such interrupt, computes it
//! bit by bit ([`Bitwise`], feature `crc16-bitwise`: no table, one short loop); the values
//! are the same (a test checks both).

/// CRC-16/IBM-3740 with the `crc` crate's 256-entry table.
#[cfg(not(feature = "crc16-bitwise"))]
pub static IBM_3740: crc::Crc<u16, crc::Table<1>> =
    crc::Crc::<u16, crc::Table<1>>::new(&crc::CRC_16_IBM_3740);
/// CRC-16/IBM-3740 bit by bit.
#[cfg(feature = "crc16-bitwise")]
pub static IBM_3740: Bitwise = Bitwise;

/// CRC-16/IBM-3740 bit by bit, with the `crc` crate's `checksum`/`digest` calls.
#[derive(Debug, Clone, Copy)]
pub struct Bitwise;

impl Bitwise {
    /// The CRC of `bytes`.
    pub fn checksum(&self, bytes: &[u8]) -> u16 {
        let mut d = self.digest();
        d.update(bytes);
        d.finalize()
    }

    /// A CRC over bytes given in parts.
    pub fn digest(&self) -> BitwiseDigest {
        BitwiseDigest(0xFFFF)
    }
}

/// A running [`Bitwise`] CRC.
#[derive(Debug, Clone, Copy)]
pub struct BitwiseDigest(u16);

impl BitwiseDigest {
    /// Adds `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = shift(self.0 ^ (u16::from(b) << 8), 8);
        }
    }

    /// The CRC of the bytes added.
    pub fn finalize(self) -> u16 {
        self.0
    }
}

/// `crc` shifted `bits` times through the polynomial, most significant bit first. Out of
/// line and with a run-time count: one short loop in the image (a constant count is
/// unrolled at the crate's opt-level 3).
#[inline(never)]
fn shift(mut crc: u16, bits: u32) -> u16 {
    for _ in 0..bits {
        crc = (crc << 1) ^ ((crc >> 15) * 0x1021);
    }
    crc
}

/// CRC-16/IBM-3740 over each word's two bytes, big-endian (the safety signature).
#[cfg(not(feature = "crc16-bitwise"))]
pub fn of_be_words(words: &[u16]) -> u16 {
    let mut d = IBM_3740.digest();
    for r in words {
        d.update(&r.to_be_bytes());
    }
    d.finalize()
}

/// CRC-16/IBM-3740 over each word's two bytes, big-endian (the safety signature): the
/// word's 16 bits at once, which is the same as its high byte then its low byte.
#[cfg(feature = "crc16-bitwise")]
#[inline(never)]
pub fn of_be_words(words: &[u16]) -> u16 {
    words.iter().fold(0xFFFF, |crc, &w| shift(crc ^ w, 16))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn check_values() {
        assert_eq!(IBM_3740.checksum(b"123456789"), 0x29B1);
        assert_eq!(Bitwise.checksum(b"123456789"), 0x29B1);
        assert_eq!(Bitwise.checksum(b""), 0xFFFF);
    }

    proptest! {
        #[test]
        fn the_table_and_the_bitwise_crc_agree(
            bytes in proptest::collection::vec(any::<u8>(), 0..80),
            cut in 0usize..80,
        ) {
            let table = crc::Crc::<u16, crc::Table<1>>::new(&crc::CRC_16_IBM_3740);
            prop_assert_eq!(Bitwise.checksum(&bytes), table.checksum(&bytes));
            let (a, b) = bytes.split_at(cut.min(bytes.len()));
            let mut d = Bitwise.digest();
            d.update(a);
            d.update(b);
            prop_assert_eq!(d.finalize(), table.checksum(&bytes));
            prop_assert_eq!(IBM_3740.checksum(&bytes), table.checksum(&bytes));
        }

        #[test]
        fn words_are_their_big_endian_bytes(words in proptest::collection::vec(any::<u16>(), 0..30)) {
            let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
            let table = crc::Crc::<u16, crc::Table<1>>::new(&crc::CRC_16_IBM_3740);
            prop_assert_eq!(of_be_words(&words), table.checksum(&bytes));
            prop_assert_eq!(
                words.iter().fold(0xFFFF, |crc, &w| shift(crc ^ w, 16)),
                table.checksum(&bytes)
            );
        }
    }
}
