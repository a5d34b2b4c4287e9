//! The scenario's faults of the silicon (`[silicon]`, the silicon keys of `[[event]]`,
//! `crate::scenario::silicon`) applied to the emulated MCUs.

use g431_emu::mcu::Mcu;
use g431_emu::periph::i2c::{I2c, I2cFault};

use crate::scenario::silicon::{I2cFaultKind, SiliconEvent};

/// The PLC's EEPROM and LCD bus: I2C3 (index 2 in `g431_emu::soc::Slots::i2c`).
const PLC_I2C: usize = 2;

/// `[silicon]` settings of one MCU, before it runs.
pub fn configure(mcu: &mut Mcu, lsi_hz: Option<f64>) {
    if let Some(hz) = lsi_hz {
        mcu.soc_mut().set_lsi_hz(hz.round() as u64);
    }
}

/// One silicon event on `mcu` now.
pub fn apply(mcu: &mut Mcu, ev: SiliconEvent) {
    let soc = mcu.soc_mut();
    match ev {
        SiliconEvent::VddMv(mv) => soc.set_vdd_mv(mv),
        SiliconEvent::SramParityError => {
            // Not detected with the factory option bytes (parity check off): nothing else.
            soc.inject_sram_parity_error();
        }
        SiliconEvent::FlashEccError => {
            // The double word the core is fetching from.
            let at = soc.block;
            soc.inject_flash_ecc_error(at);
        }
        SiliconEvent::I2c { fault, address } => {
            let f = match fault {
                I2cFaultKind::Nack => I2cFault::Nack,
                I2cFaultKind::Stretch { ms } => I2cFault::stretch_ms(ms),
                I2cFaultKind::ArbitrationLoss => I2cFault::ArbitrationLoss,
                I2cFaultKind::BusError => I2cFault::BusError,
            };
            let k = soc.wired.i2c[PLC_I2C];
            if let Some(i2c) = soc.model_mut::<I2c>(k) {
                i2c.inject_fault(f, address);
            }
            soc.refresh(k);
        }
    }
}
