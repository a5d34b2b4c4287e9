//! The whole-EEPROM image of a program, for programming a 24C256 off-board
//! (`hil-sim asm -o image.bin`) and for reading one back (`hil-sim disasm image.bin`).
//!
//! The image is produced by running the firmware's own save code on a [`MemEeprom`], so
//! it is byte for byte what the PLC would have stored: the program in both copies of one
//! slot (generation 1), a boot record naming that slot (power-cycle count 0), an empty
//! fault log, and every other byte erased (`0xFF`).

use super::{MemEeprom, Storage, StorageError, EEPROM_BYTES, SLOTS};
use shared_protocol::program::Program;

/// How the image is laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageOptions {
    /// Slot (1..=4) the program goes in, and that is loaded at power-up.
    pub slot: u8,
    /// Start RUN at power-up without a key.
    pub run_at_power_up: bool,
}

impl Default for ImageOptions {
    /// Slot 1, run at power-up: an EEPROM programmed off-board runs its program when the
    /// PLC is switched on, as if the program had been saved and run on the keypad.
    fn default() -> Self {
        ImageOptions {
            slot: 1,
            run_at_power_up: true,
        }
    }
}

/// The exact 32 KiB the firmware would hold in its EEPROM after saving `program` into
/// `options.slot` and running it.
pub fn program_image(
    program: &Program,
    options: &ImageOptions,
) -> Result<[u8; EEPROM_BYTES], StorageError> {
    let mut storage = Storage::new(MemEeprom::new());
    storage.save(options.slot, program)?;
    storage.set_run_state(Some(options.slot), options.run_at_power_up)?;
    Ok(*storage.into_eeprom().image())
}

/// Whether `bytes` have the size of a whole-EEPROM image (a `.plc` text never does in
/// practice; callers may also look at the file name).
pub fn is_image(bytes: &[u8]) -> bool {
    bytes.len() == EEPROM_BYTES
}

/// The program the firmware would load at power-up from `image`: the boot record's slot,
/// or else the lowest-numbered slot holding a program. Shorter images are padded with
/// erased bytes.
pub fn program_from_image(image: &[u8]) -> Result<Program, StorageError> {
    if image.len() > EEPROM_BYTES {
        return Err(StorageError::Eeprom(super::EepromError::OutOfRange));
    }
    let mut storage = Storage::new(MemEeprom::from_image(image));
    let mut program = Program::default();
    let boot_slot = storage.boot_record()?.and_then(|r| r.last_run_slot);
    if let Some(slot) = boot_slot {
        storage.load(slot, &mut program)?;
        return Ok(program);
    }
    let mut first_err = StorageError::Empty(1);
    for slot in 1..=SLOTS {
        match storage.load(slot, &mut program) {
            Ok(_) => return Ok(program),
            Err(e) if slot == 1 => first_err = e,
            Err(_) => {}
        }
    }
    Err(first_err)
}

/// The program stored in one given slot of `image`.
pub fn program_from_image_slot(image: &[u8], slot: u8) -> Result<Program, StorageError> {
    if image.len() > EEPROM_BYTES {
        return Err(StorageError::Eeprom(super::EepromError::OutOfRange));
    }
    let mut storage = Storage::new(MemEeprom::from_image(image));
    let mut program = Program::default();
    storage.load(slot, &mut program)?;
    Ok(program)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_protocol::program::{Instruction, Mnemonic, Operand};

    #[test]
    fn image_round_trips_and_boots() {
        let mut p = Program::default();
        p.lines[150] = Some(Instruction {
            mnemonic: Mnemonic::Ld,
            operand: Some(Operand::D(0)),
            constant: 0,
        });
        p.lines[151] = Some(Instruction {
            mnemonic: Mnemonic::Wr,
            operand: Some(Operand::O(0)),
            constant: 0,
        });
        let opts = ImageOptions {
            slot: 3,
            run_at_power_up: true,
        };
        let img = program_image(&p, &opts).unwrap();
        assert!(is_image(&img));
        assert_eq!(program_from_image(&img).unwrap(), p);
        assert_eq!(program_from_image_slot(&img, 3).unwrap(), p);
        assert_eq!(
            program_from_image_slot(&img, 1),
            Err(StorageError::Empty(1))
        );
        // Deterministic: same program, same bytes.
        assert_eq!(program_image(&p, &opts).unwrap()[..], img[..]);
        // The firmware's power-up finds and runs it.
        let mut s = Storage::new(MemEeprom::from_image(&img));
        let mut q = Program::default();
        let up = s.power_up(&mut q).unwrap();
        assert!(up.run);
        assert_eq!(up.power_cycle, 1);
        assert_eq!(q, p);
    }
}
