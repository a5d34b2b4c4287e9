//! Faults and tolerances of the silicon (g431-emu's models; `hil-sim emu` only): the
//! `[silicon]` table and the silicon keys of an `[[event]]` (documented in
//! `docs/simulation.md` "Faults of the silicon").

use anyhow::{bail, Result};
use serde::Deserialize;

/// LSI frequency range of the STM32G431 over its operating conditions (DS12589, "LSI
/// oscillator characteristics": fLSI 29.5 kHz min, 34 kHz max; 32 kHz typical).
pub const LSI_MIN_HZ: f64 = 29_500.0;
pub const LSI_MAX_HZ: f64 = 34_000.0;

/// `[silicon]`: per-MCU settings for the whole run.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SiliconKeys {
    /// The drive MCU's LSI, Hz, or `"min"` / `"max"` for the datasheet extremes.
    pub drive_lsi: Option<LsiKey>,
    /// The PLC MCU's LSI.
    pub plc_lsi: Option<LsiKey>,
}

/// An LSI setting as written: a frequency in Hz or a datasheet extreme.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum LsiKey {
    Hz(f64),
    Named(String),
}

impl LsiKey {
    fn hz(&self, name: &str) -> Result<f64> {
        let hz = match self {
            LsiKey::Hz(h) => *h,
            LsiKey::Named(n) if n == "min" => LSI_MIN_HZ,
            LsiKey::Named(n) if n == "max" => LSI_MAX_HZ,
            LsiKey::Named(n) if n == "typ" => 32_000.0,
            LsiKey::Named(n) => {
                bail!("silicon.{name} = {n:?}: a frequency in Hz, \"min\", \"typ\" or \"max\"")
            }
        };
        if !(LSI_MIN_HZ..=LSI_MAX_HZ).contains(&hz) {
            bail!(
                "silicon.{name} = {hz} Hz is outside the datasheet's {LSI_MIN_HZ}-{LSI_MAX_HZ} Hz"
            );
        }
        Ok(hz)
    }
}

/// The validated `[silicon]` table.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SiliconParams {
    /// LSI of each MCU, Hz (`None`: the model's typical 32 kHz).
    pub drive_lsi_hz: Option<f64>,
    pub plc_lsi_hz: Option<f64>,
}

impl SiliconKeys {
    pub fn params(&self) -> Result<SiliconParams> {
        Ok(SiliconParams {
            drive_lsi_hz: self
                .drive_lsi
                .as_ref()
                .map(|k| k.hz("drive_lsi"))
                .transpose()?,
            plc_lsi_hz: self.plc_lsi.as_ref().map(|k| k.hz("plc_lsi")).transpose()?,
        })
    }
}

/// Which board's MCU a silicon event acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum McuSide {
    Drive,
    Plc,
}

/// An I2C fault on the PLC's bus (g431-emu `I2cFault`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum I2cFaultKind {
    Nack,
    Stretch { ms: f64 },
    ArbitrationLoss,
    BusError,
}

/// A fault of the silicon at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SiliconEvent {
    /// The MCU's supply is now this many millivolts (the PVD watches it).
    VddMv(u32),
    /// A read of SRAM finds a parity error (detected only with the parity option bit).
    SramParityError,
    /// A read of flash finds a double ECC error (NMI; a system break with ECCL).
    FlashEccError,
    /// The device at `address` on the PLC's I2C bus does `fault` in the next write to it.
    I2c { fault: I2cFaultKind, address: u8 },
}

/// The silicon keys of one `[[event]]`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EventSiliconKeys<'a> {
    pub mcu: Option<&'a str>,
    pub vdd_v: Option<f64>,
    pub sram_parity_error: Option<bool>,
    pub flash_ecc_error: Option<bool>,
    pub i2c_fault: Option<&'a str>,
    pub i2c_address: Option<u8>,
    pub i2c_stretch_ms: Option<f64>,
}

/// The EEPROM's address on the PLC's bus (24C256 with A2..A0 low).
pub const EEPROM_I2C_ADDRESS: u8 = 0x50;

impl EventSiliconKeys<'_> {
    /// The events these keys give (empty: none given).
    pub fn events(&self) -> Result<Vec<(McuSide, SiliconEvent)>> {
        let side = match self.mcu {
            None | Some("drive") => McuSide::Drive,
            Some("plc") => McuSide::Plc,
            Some(m) => bail!("mcu = {m:?}: \"drive\" or \"plc\""),
        };
        let mut out = Vec::new();
        if let Some(v) = self.vdd_v {
            if !(v.is_finite() && (0.0..=3.6).contains(&v)) {
                bail!("vdd_v = {v}: 0 to 3.6 V (the G431's absolute range)");
            }
            out.push((side, SiliconEvent::VddMv((v * 1000.0).round() as u32)));
        }
        if self.sram_parity_error == Some(true) {
            out.push((side, SiliconEvent::SramParityError));
        }
        if self.flash_ecc_error == Some(true) {
            out.push((side, SiliconEvent::FlashEccError));
        }
        match (self.i2c_fault, self.i2c_stretch_ms) {
            (Some(f), stretch) => {
                if self.mcu == Some("drive") {
                    bail!("i2c_fault: the I2C bus with devices is the PLC's (mcu = \"plc\")");
                }
                let fault = match (f, stretch) {
                    ("nack", None) => I2cFaultKind::Nack,
                    ("arbitration_loss", None) => I2cFaultKind::ArbitrationLoss,
                    ("bus_error", None) => I2cFaultKind::BusError,
                    ("stretch", Some(ms)) if ms.is_finite() && ms > 0.0 => {
                        I2cFaultKind::Stretch { ms }
                    }
                    ("stretch", _) => bail!("i2c_fault = \"stretch\" needs i2c_stretch_ms > 0"),
                    (_, Some(_)) => bail!("i2c_stretch_ms goes with i2c_fault = \"stretch\""),
                    (f, None) => bail!(
                        "i2c_fault = {f:?}: \"nack\", \"stretch\", \"arbitration_loss\" or \
                         \"bus_error\""
                    ),
                };
                let address = self.i2c_address.unwrap_or(EEPROM_I2C_ADDRESS);
                if address > 0x7F {
                    bail!("i2c_address = {address:#x}: a 7-bit address");
                }
                out.push((McuSide::Plc, SiliconEvent::I2c { fault, address }));
            }
            (None, Some(_)) => bail!("i2c_stretch_ms without i2c_fault = \"stretch\""),
            (None, None) if self.i2c_address.is_some() => bail!("i2c_address without i2c_fault"),
            (None, None) => {}
        }
        if out.is_empty() && self.mcu.is_some() {
            bail!(
                "mcu without a silicon key (vdd_v, sram_parity_error, flash_ecc_error, i2c_fault)"
            );
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lsi_extremes_and_range() {
        let k = SiliconKeys {
            drive_lsi: Some(LsiKey::Named("min".into())),
            plc_lsi: Some(LsiKey::Hz(33_000.0)),
        };
        let p = k.params().expect("valid");
        assert_eq!(p.drive_lsi_hz, Some(LSI_MIN_HZ));
        assert_eq!(p.plc_lsi_hz, Some(33_000.0));
        let bad = SiliconKeys {
            drive_lsi: Some(LsiKey::Hz(40_000.0)),
            plc_lsi: None,
        };
        assert!(bad.params().is_err());
    }

    #[test]
    fn event_keys() {
        let e = EventSiliconKeys {
            vdd_v: Some(2.5),
            flash_ecc_error: Some(true),
            ..Default::default()
        };
        assert_eq!(
            e.events().expect("valid"),
            vec![
                (McuSide::Drive, SiliconEvent::VddMv(2500)),
                (McuSide::Drive, SiliconEvent::FlashEccError)
            ]
        );
        let i = EventSiliconKeys {
            i2c_fault: Some("stretch"),
            i2c_stretch_ms: Some(30.0),
            ..Default::default()
        };
        assert_eq!(
            i.events().expect("valid"),
            vec![(
                McuSide::Plc,
                SiliconEvent::I2c {
                    fault: I2cFaultKind::Stretch { ms: 30.0 },
                    address: 0x50
                }
            )]
        );
        for bad in [
            EventSiliconKeys {
                i2c_fault: Some("stretch"),
                ..Default::default()
            },
            EventSiliconKeys {
                i2c_fault: Some("nack"),
                mcu: Some("drive"),
                ..Default::default()
            },
            EventSiliconKeys {
                vdd_v: Some(5.0),
                ..Default::default()
            },
            EventSiliconKeys {
                mcu: Some("plc"),
                ..Default::default()
            },
        ] {
            assert!(bad.events().is_err(), "{bad:?}");
        }
    }
}
