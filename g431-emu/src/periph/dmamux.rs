//! DMAMUX1: routes a peripheral's DMA request line (request ID, RM0440 §13.3 table
//! "DMAMUX: assignment of multiplexer inputs to resources") to a DMA channel (RM0440 §13).
//!
//! Modelled: the request line multiplexer (DMAMUX_CxCR.DMAREQ_ID; request ID 0 is "no
//! request"), which is all embassy-stm32 uses (`dma/dmamux.rs`: DMAREQ_ID, NBREQ = 0, then
//! EGE). EGE only drives event outputs that feed the synchronisation and generator inputs
//! below, so it has no effect here. Not modelled, and reported when turned on: synchronisation
//! (SE, SOIE), and the four request generators (RGxCR.GE, OIE). Their status registers read 0
//! (no overrun ever happens), so the DMAMUX_OVR interrupt never rises.
//!
//! The DMA asks [`Dmamux::request_id`] which request feeds a multiplexer channel; which
//! multiplexer channel a DMA channel hangs off comes from the metadata (see `dma.rs`).

use super::reports::DistinctReports;
use super::{Peripheral, Write};
use crate::time::Cycles;

/// Multiplexer channels with a CxCR register (the G4's DMAMUX block; the G431 connects
/// 0-5 to DMA1 and 8-13 to DMA2 per the metadata).
pub const MUX_CHANNELS: usize = 16;
/// Request generator channels.
const GENERATORS: usize = 4;

const CCR_DMAREQ_ID: u32 = 0x7f;
const CCR_SOIE: u32 = 1 << 8;
const CCR_EGE: u32 = 1 << 9;
const CCR_SE: u32 = 1 << 16;
const CCR_NBREQ: u32 = 0x1f << 19;
const CCR_VALID: u32 = 0x1fff_037f;

const CSR: u32 = 0x80;
const CFR: u32 = 0x84;
const RGCR0: u32 = 0x100;
const RGSR: u32 = 0x140;
const RGCFR: u32 = 0x144;

const RGCR_OIE: u32 = 1 << 8;
const RGCR_GE: u32 = 1 << 16;
const RGCR_GNBREQ: u32 = 0x1f << 19;
const RGCR_VALID: u32 = 0x00ff_011f;

/// The DMAMUX1 register model.
#[derive(Debug, Default)]
pub struct Dmamux {
    ccr: [u32; MUX_CHANNELS],
    rgcr: [u32; GENERATORS],
    reports: DistinctReports,
}

impl Dmamux {
    pub fn new() -> Self {
        Self::default()
    }

    /// The request ID routed to multiplexer channel `mux_channel`, or `None` for ID 0 (no
    /// request) or a channel that does not exist.
    pub fn request_id(&self, mux_channel: usize) -> Option<u8> {
        self.ccr
            .get(mux_channel)
            .map(|c| (c & CCR_DMAREQ_ID) as u8)
            .filter(|id| *id != 0)
    }
}

impl Peripheral for Dmamux {
    /// Uses of the synchronisation and request generator features, each reported once.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        let idx = (offset / 4) as usize;
        match offset {
            o if o < 4 * MUX_CHANNELS as u32 => self.ccr.get(idx).copied(),
            // No synchronisation overrun or trigger overrun ever happens; the clear
            // registers are write-only.
            CSR | CFR | RGSR | RGCFR => Some(0),
            o if (RGCR0..RGCR0 + 4 * GENERATORS as u32).contains(&o) => {
                self.rgcr.get(((o - RGCR0) / 4) as usize).copied()
            }
            _ => None,
        }
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        match w.offset {
            o if o < 4 * MUX_CHANNELS as u32 => {
                let idx = (o / 4) as usize;
                let Some(old) = self.ccr.get(idx).copied() else {
                    return false;
                };
                let mut new = w.merge(old) & CCR_VALID;
                // NBREQ can only be written while SE and EGE are both 0.
                if old & (CCR_SE | CCR_EGE) != 0 {
                    new = (new & !CCR_NBREQ) | (old & CCR_NBREQ);
                }
                if let Some(c) = self.ccr.get_mut(idx) {
                    *c = new;
                }
                if new & (CCR_SE | CCR_SOIE) != 0 {
                    self.reports.once(format!(
                        "DMAMUX1.C{idx}CR: request synchronisation (SE/SOIE) is not modelled; \
                         requests are forwarded unsynchronised"
                    ));
                }
            }
            // Clear flags of events that never happen.
            CFR | RGCFR => {}
            CSR | RGSR => {}
            o if (RGCR0..RGCR0 + 4 * GENERATORS as u32).contains(&o) => {
                let idx = ((o - RGCR0) / 4) as usize;
                let Some(old) = self.rgcr.get(idx).copied() else {
                    return false;
                };
                let mut new = w.merge(old) & RGCR_VALID;
                // GNBREQ can only be written while GE is 0.
                if old & RGCR_GE != 0 {
                    new = (new & !RGCR_GNBREQ) | (old & RGCR_GNBREQ);
                }
                if let Some(r) = self.rgcr.get_mut(idx) {
                    *r = new;
                }
                if new & (RGCR_GE | RGCR_OIE) != 0 {
                    self.reports.once(format!(
                        "DMAMUX1.RG{idx}CR: request generator is not modelled; it generates \
                         no request"
                    ));
                }
            }
            _ => return false,
        }
        true
    }

    fn reset(&mut self) {
        self.ccr = [0; MUX_CHANNELS];
        self.rgcr = [0; GENERATORS];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embassy_configure_sequence_routes_the_request() {
        // dma/dmamux.rs configure_dmamux: write(NBREQ = 0, DMAREQ_ID), then modify(EGE).
        let mut m = Dmamux::new();
        let usart2_rx = crate::names::dma_request("USART2", "RX").unwrap_or(0);
        assert!(m.write(Write::word(4, u32::from(usart2_rx)), 0));
        let v = m.read(4, 0).unwrap_or(0);
        assert!(m.write(Write::word(4, v | CCR_EGE), 0));
        assert_eq!(m.request_id(1), Some(usart2_rx));
        assert_eq!(m.request_id(0), None, "ID 0 is no request");
        assert!(m.take_reports().is_empty(), "EGE alone is not reported");
    }

    #[test]
    fn nbreq_is_locked_while_ege_is_set() {
        let mut m = Dmamux::new();
        m.write(Write::word(0, CCR_EGE | (3 << 19) | 5), 0);
        assert_eq!(m.read(0, 0), Some(CCR_EGE | (3 << 19) | 5));
        // With EGE set, NBREQ keeps its value; the other fields change.
        m.write(Write::word(0, 7), 0);
        assert_eq!(m.read(0, 0), Some((3 << 19) | 7));
    }

    #[test]
    fn synchronisation_and_generators_are_reported() {
        let mut m = Dmamux::new();
        m.write(Write::word(8, CCR_SE | 3), 0);
        m.write(Write::word(RGCR0 + 4, RGCR_GE), 0);
        let r = m.take_reports();
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(r[0].contains("C2CR") && r[1].contains("RG1CR"));
        // Reported once.
        m.write(Write::word(8, CCR_SE | 4), 0);
        assert!(m.take_reports().is_empty());
        assert_eq!(m.read(CSR, 0), Some(0));
        assert_eq!(m.read(0x90, 0), None, "no register there");
    }
}
