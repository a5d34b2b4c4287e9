//! DMA1 and DMA2 of the G431 (6 channels each; the "bdma" register set of RM0440 §12), as a
//! pure state machine: the SoC performs each transfer as ordinary bus accesses, so that a
//! DMA read of a USART's RDR has the same side effects as a CPU read.
//!
//! The SoC's loop, whenever a peripheral's request lines may have changed:
//! 1. collect [`DmaRequests`] from every peripheral;
//! 2. `while let Some(t) = dma.next_transfer(&mux, &requests)`: read `t.src_size` bytes at
//!    `t.src`, write [`Transfer::value_to_write`] as `t.dst_size` bytes at `t.dst`, then
//!    [`Dma::complete`]`(&t)` (or [`Dma::bus_error`]`(t.channel)` if either access faulted),
//!    and collect the requests again (a read of RDR drops the USART's request).
//!
//! What is modelled (RM0440 §12.4):
//! * arbitration: among enabled channels with data left and their request active (the
//!   DMAMUX channel's request ID, or always with MEM2MEM), the highest PL wins, then the
//!   lowest channel number;
//! * the internal current addresses start at CPAR/CMAR when the channel is enabled after
//!   being programmed, advance by PSIZE/MSIZE with PINC/MINC, and are aligned down to the
//!   access size (RM0440 DMA_CPARx/CMARx: low address bits ignored); a narrower source is
//!   zero-extended, a wider one truncated (RM0440 table "Programmable data width");
//! * CNDTR counts down per transfer; HTIF sets when it reaches half the programmed count,
//!   TCIF when it reaches 0; in circular mode it then reloads the programmed count and the
//!   addresses restart (TCIF and the reload are simultaneous, so CNDTR never reads 0 —
//!   embassy's ring buffer computes its write position as `len - CNDTR`); in normal mode it
//!   stays 0 and the channel serves no more requests **but EN stays 1** (RM0440 DMA_CNDTRx:
//!   "If this register is zero, no transfer can be served whatever the channel status");
//! * a bus error sets TEIF and clears EN (RM0440 "Channel state and disabling a channel");
//! * while EN = 1, CNDTR, CPAR, CMAR and the CCR configuration fields are read-only (the IE
//!   bits and EN stay writable); a write that tries to change them is ignored and reported;
//! * ISR (GIFx = TCIFx | HTIFx | TEIFx), IFCR (write 1 to clear; CGIFx clears all three);
//! * one interrupt line per channel (DMA1_CHANNEL1..6), the level of
//!   TCIF·TCIE | HTIF·HTIE | TEIF·TEIE.
//!
//! Re-enabling a channel without reprogramming CNDTR, CPAR or CMAR ("suspend and resume")
//! is "not supported by the DMA hardware" (RM0440 "Channel state and disabling a channel"):
//! what the silicon then does is undefined, so the model reports it and **stops the
//! channel**: EN reads 1 but no request is served until the channel is disabled and CNDTR,
//! CPAR or CMAR is written again. embassy's `RingBufferedUartRx` does
//! exactly this after every RX error (`dma_bdma.rs` `request_pause` + `start`, which only
//! sets EN).
//!
//! Not modelled: transfer timing (a transfer takes no time), bus contention, the
//! peripheral-to-peripheral or memory-to-memory bandwidth.

use super::dmamux::Dmamux;
use super::reports::DistinctReports;
use super::{DmaRequests, IrqLines, Peripheral, Write};
use crate::names;
use crate::time::Cycles;

/// Channels per DMA controller on the G431.
pub const CHANNELS: usize = 6;

const ISR: u32 = 0x00;
const IFCR: u32 = 0x04;
const CH_BASE: u32 = 0x08;
const CH_STRIDE: u32 = 20;

const CCR_EN: u32 = 1 << 0;
const CCR_TCIE: u32 = 1 << 1;
const CCR_HTIE: u32 = 1 << 2;
const CCR_TEIE: u32 = 1 << 3;
const CCR_DIR: u32 = 1 << 4;
const CCR_CIRC: u32 = 1 << 5;
const CCR_PINC: u32 = 1 << 6;
const CCR_MINC: u32 = 1 << 7;
const CCR_MEM2MEM: u32 = 1 << 14;
const CCR_VALID: u32 = 0x7fff;
/// Fields that are read-only while EN = 1: DIR, CIRC, PINC, MINC, PSIZE, MSIZE, PL, MEM2MEM.
const CCR_LOCKED: u32 = 0x7ff0;

const FLAG_TC: u8 = 1 << 1;
const FLAG_HT: u8 = 1 << 2;
const FLAG_TE: u8 = 1 << 3;

/// DMA1 or DMA2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DmaInstance {
    Dma1,
    Dma2,
}

impl DmaInstance {
    pub fn name(self) -> &'static str {
        match self {
            DmaInstance::Dma1 => "DMA1",
            DmaInstance::Dma2 => "DMA2",
        }
    }
}

/// One data item to move: read `src_size` bytes at `src`, write `dst_size` bytes at `dst`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transfer {
    /// Channel number, 1-based as in RM0440 (`DMA1_CH1` is 1).
    pub channel: u8,
    pub src: u32,
    /// 1, 2 or 4.
    pub src_size: u8,
    pub dst: u32,
    /// 1, 2 or 4.
    pub dst_size: u8,
}

impl Transfer {
    /// The value to write for `read` (what the source access returned): zero-extended or
    /// truncated to the destination size.
    pub fn value_to_write(&self, read: u32) -> u32 {
        match self.dst_size {
            1 => read & 0xff,
            2 => read & 0xffff,
            _ => read,
        }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Channel {
    ccr: u32,
    cndtr: u16,
    /// The count last programmed into CNDTR (circular reload, half-transfer point).
    reload: u16,
    cpar: u32,
    cmar: u32,
    peri_cur: u32,
    mem_cur: u32,
    /// CNDTR, CPAR or CMAR written since the channel was last enabled.
    reprogrammed: bool,
    /// Re-enabled without reprogramming (undefined in RM0440): serves no request.
    stalled: bool,
    /// Configuration bits a write tried to change while it cleared EN (they were read-only
    /// at that moment); reported if the channel is enabled again without CCR having been
    /// rewritten while disabled.
    ignored_cfg: Option<u32>,
    /// TC/HT/TE flags (ISR bits 1..3 of this channel).
    flags: u8,
}

impl Channel {
    fn enabled(&self) -> bool {
        self.ccr & CCR_EN != 0
    }

    fn size(bits: u32) -> u8 {
        match bits & 3 {
            0 => 1,
            1 => 2,
            _ => 4,
        }
    }

    fn psize(&self) -> u8 {
        Self::size(self.ccr >> 8)
    }

    fn msize(&self) -> u8 {
        Self::size(self.ccr >> 10)
    }

    fn priority(&self) -> u32 {
        (self.ccr >> 12) & 3
    }

    fn irq_level(&self) -> bool {
        (self.flags & FLAG_TC != 0 && self.ccr & CCR_TCIE != 0)
            || (self.flags & FLAG_HT != 0 && self.ccr & CCR_HTIE != 0)
            || (self.flags & FLAG_TE != 0 && self.ccr & CCR_TEIE != 0)
    }
}

/// The register model of one DMA controller.
#[derive(Debug)]
pub struct Dma {
    instance: DmaInstance,
    ch: [Channel; CHANNELS],
    /// DMAMUX channel feeding each DMA channel (from the metadata).
    mux_channel: [Option<usize>; CHANNELS],
    irq: [Option<u16>; CHANNELS],
    reports: DistinctReports,
}

impl Dma {
    /// The controller at reset, with its interrupt lines and DMAMUX channels from the
    /// metadata.
    pub fn new(instance: DmaInstance) -> Self {
        let mut mux_channel = [None; CHANNELS];
        let mut irq = [None; CHANNELS];
        for (i, (m, q)) in mux_channel.iter_mut().zip(irq.iter_mut()).enumerate() {
            *m = names::chip()
                .dma_channels
                .iter()
                .find(|c| c.dma == instance.name() && c.channel as usize == i)
                .and_then(|c| c.dmamux_channel)
                .map(|c| c as usize);
            *q = names::irq(&format!("{}_CHANNEL{}", instance.name(), i + 1));
        }
        Dma {
            instance,
            ch: [Channel::default(); CHANNELS],
            mux_channel,
            irq,
            reports: DistinctReports::default(),
        }
    }

    /// The DMAMUX channel that feeds `channel` (1-based).
    pub fn mux_channel(&self, channel: u8) -> Option<usize> {
        self.mux_channel
            .get(usize::from(channel).wrapping_sub(1))
            .copied()
            .flatten()
    }

    /// The NVIC line of `channel` (1-based).
    pub fn irq(&self, channel: u8) -> Option<u16> {
        self.irq
            .get(usize::from(channel).wrapping_sub(1))
            .copied()
            .flatten()
    }

    /// The transfer the arbiter grants now, if any (RM0440 §12.4.2: software priority PL,
    /// then the lower channel number).
    pub fn next_transfer(&self, mux: &Dmamux, requests: &DmaRequests) -> Option<Transfer> {
        let mut best: Option<(usize, u32)> = None;
        for (i, c) in self.ch.iter().enumerate() {
            if !c.enabled() || c.cndtr == 0 || c.stalled {
                continue;
            }
            let requested = c.ccr & CCR_MEM2MEM != 0
                || self
                    .mux_channel
                    .get(i)
                    .copied()
                    .flatten()
                    .and_then(|m| mux.request_id(m))
                    .is_some_and(|id| requests.get(id));
            if !requested {
                continue;
            }
            // Strictly higher priority only: on a tie the lower channel number, found first,
            // keeps the grant.
            if best.is_none_or(|(_, pl)| c.priority() > pl) {
                best = Some((i, c.priority()));
            }
        }
        let (i, _) = best?;
        let c = self.ch.get(i)?;
        let align = |addr: u32, size: u8| addr & !(u32::from(size) - 1);
        let (psize, msize) = (c.psize(), c.msize());
        let peri = align(c.peri_cur, psize);
        let mem = align(c.mem_cur, msize);
        let channel = (i + 1) as u8;
        Some(if c.ccr & CCR_DIR != 0 {
            Transfer {
                channel,
                src: mem,
                src_size: msize,
                dst: peri,
                dst_size: psize,
            }
        } else {
            Transfer {
                channel,
                src: peri,
                src_size: psize,
                dst: mem,
                dst_size: msize,
            }
        })
    }

    /// `t` has been performed: advance the addresses and CNDTR, set HTIF/TCIF, reload in
    /// circular mode.
    pub fn complete(&mut self, t: &Transfer) {
        let Some(c) = self.ch.get_mut(usize::from(t.channel).wrapping_sub(1)) else {
            return;
        };
        if !c.enabled() || c.cndtr == 0 {
            return;
        }
        if c.ccr & CCR_PINC != 0 {
            c.peri_cur = c.peri_cur.wrapping_add(u32::from(c.psize()));
        }
        if c.ccr & CCR_MINC != 0 {
            c.mem_cur = c.mem_cur.wrapping_add(u32::from(c.msize()));
        }
        c.cndtr -= 1;
        if c.cndtr == c.reload / 2 {
            c.flags |= FLAG_HT;
        }
        if c.cndtr == 0 {
            c.flags |= FLAG_TC;
            if c.ccr & CCR_CIRC != 0 {
                c.cndtr = c.reload;
                c.peri_cur = c.cpar;
                c.mem_cur = c.cmar;
            }
        }
    }

    /// The SoC's access for a transfer of `channel` (1-based) faulted: TEIF sets and the
    /// channel is disabled by hardware.
    pub fn bus_error(&mut self, channel: u8) {
        if let Some(c) = self.ch.get_mut(usize::from(channel).wrapping_sub(1)) {
            c.flags |= FLAG_TE;
            c.ccr &= !CCR_EN;
        }
    }

    fn isr(&self) -> u32 {
        self.ch.iter().enumerate().fold(0, |acc, (i, c)| {
            let f = u32::from(c.flags & (FLAG_TC | FLAG_HT | FLAG_TE));
            let gif = u32::from(f != 0);
            acc | ((f | gif) << (4 * i))
        })
    }

    fn write_ccr(&mut self, i: usize, w: Write) {
        let name = format!("{}.CCR{}", self.instance.name(), i + 1);
        let Some(c) = self.ch.get(i).copied() else {
            return;
        };
        let old = c.ccr;
        let mut new = w.merge(old) & CCR_VALID;
        let mut msgs = Vec::new();
        let mut c = c;
        if old & CCR_EN == 0 {
            if new & CCR_EN == 0 {
                // Rewritten while disabled: whatever was ignored before is superseded.
                c.ignored_cfg = None;
            }
        } else if (old ^ new) & CCR_LOCKED != 0 {
            if new & CCR_EN == 0 {
                // embassy's request_reset writes TEIE | TCIE over an enabled channel: only EN
                // and the IE bits take effect. Harmless unless the channel is re-enabled
                // expecting the new configuration.
                c.ignored_cfg = Some(new & CCR_LOCKED);
            } else {
                msgs.push(format!(
                    "{name}: configuration bits {:#06x} written while EN = 1 (read-only): \
                     ignored",
                    (old ^ new) & CCR_LOCKED
                ));
            }
            new = (new & !CCR_LOCKED) | (old & CCR_LOCKED);
        }
        c.ccr = new;
        if old & CCR_EN == 0 && new & CCR_EN != 0 {
            if c.reprogrammed {
                c.peri_cur = c.cpar;
                c.mem_cur = c.cmar;
                c.stalled = false;
            } else if c.cndtr != 0 {
                c.stalled = true;
                msgs.push(format!(
                    "{name}: channel re-enabled without reprogramming CNDTR/CPAR/CMAR \
                     (RM0440: suspend/resume not supported by the hardware, undefined); the \
                     model stops the channel until it is reprogrammed"
                ));
            }
            c.reprogrammed = false;
            if let Some(cfg) = c.ignored_cfg.take() {
                if cfg != new & CCR_LOCKED {
                    msgs.push(format!(
                        "{name}: enabled with the configuration it had before a write that \
                         cleared EN tried to change it (bits {:#06x} were read-only then)",
                        cfg ^ (new & CCR_LOCKED)
                    ));
                }
            }
            if new & CCR_MEM2MEM != 0 && new & CCR_CIRC != 0 {
                msgs.push(format!("{name}: MEM2MEM with CIRC (RM0440: not allowed)"));
            }
            if (new >> 8) & 3 == 3 || (new >> 10) & 3 == 3 {
                msgs.push(format!(
                    "{name}: PSIZE/MSIZE = 11 is reserved (modelled as 32 bits)"
                ));
            }
        }
        if let Some(slot) = self.ch.get_mut(i) {
            *slot = c;
        }
        for m in msgs {
            self.reports.once(m);
        }
    }

    /// CNDTR, CPAR, CMAR: writable only while the channel is disabled.
    fn write_locked_reg(&mut self, i: usize, reg: u32, w: Write) {
        let Some(c) = self.ch.get(i).copied() else {
            return;
        };
        if c.enabled() {
            let name = ["CNDTR", "CPAR", "CMAR"]
                .get(reg as usize)
                .copied()
                .unwrap_or("?");
            self.reports.once(format!(
                "{}.{}{}: written while the channel is enabled (read-only): ignored",
                self.instance.name(),
                name,
                i + 1
            ));
            return;
        }
        let mut c = c;
        match reg {
            0 => {
                c.cndtr = (w.merge(u32::from(c.cndtr)) & 0xffff) as u16;
                c.reload = c.cndtr;
            }
            1 => c.cpar = w.merge(c.cpar),
            _ => c.cmar = w.merge(c.cmar),
        }
        c.reprogrammed = true;
        if let Some(slot) = self.ch.get_mut(i) {
            *slot = c;
        }
    }

    /// The channel register at `offset`: (channel index, register 0..=3 = CCR, CNDTR, CPAR,
    /// CMAR). The fifth word of each channel's block is reserved.
    fn channel_reg(offset: u32) -> Option<(usize, u32)> {
        let rel = offset.checked_sub(CH_BASE)?;
        let i = (rel / CH_STRIDE) as usize;
        let reg = (rel % CH_STRIDE) / 4;
        (i < CHANNELS && reg < 4).then_some((i, reg))
    }
}

impl Peripheral for Dma {
    /// Questionable or unmodelled uses, each reported once, since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        match offset {
            ISR => Some(self.isr()),
            // Write-only.
            IFCR => Some(0),
            o => {
                let (i, reg) = Self::channel_reg(o)?;
                let c = self.ch.get(i)?;
                Some(match reg {
                    0 => c.ccr,
                    1 => u32::from(c.cndtr),
                    2 => c.cpar,
                    _ => c.cmar,
                })
            }
        }
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        match w.offset {
            // Read-only.
            ISR => true,
            IFCR => {
                let v = w.value & w.mask;
                for (i, c) in self.ch.iter_mut().enumerate() {
                    let bits = (v >> (4 * i)) & 0xf;
                    if bits & 1 != 0 {
                        c.flags = 0;
                    }
                    c.flags &= !((bits & 0xe) as u8);
                }
                true
            }
            o => match Self::channel_reg(o) {
                Some((i, 0)) => {
                    self.write_ccr(i, w);
                    true
                }
                Some((i, reg)) => {
                    self.write_locked_reg(i, reg - 1, w);
                    true
                }
                None => false,
            },
        }
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        for (c, irq) in self.ch.iter().zip(self.irq.iter()) {
            if let (true, Some(irq)) = (c.irq_level(), irq) {
                lines.set(*irq);
            }
        }
    }

    fn reset(&mut self) {
        self.ch = [Channel::default(); CHANNELS];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::usart::{RxByte, TxFrame, Usart, UsartInstance};

    const CCR_PL_VERY_HIGH: u32 = 3 << 12;
    const CCR_SIZE32_P: u32 = 2 << 8;
    const CCR_SIZE16_M: u32 = 1 << 10;

    fn ch_off(ch: u8, reg: u32) -> u32 {
        CH_BASE + CH_STRIDE * u32::from(ch - 1) + 4 * reg
    }

    fn wr(d: &mut Dma, off: u32, v: u32) {
        assert!(d.write(Write::word(off, v), 0));
    }

    fn rd(d: &mut Dma, off: u32) -> u32 {
        d.read(off, 0).unwrap_or(0xdead_beef)
    }

    /// A memory-to-memory channel needs no request line.
    fn m2m(d: &mut Dma, ch: u8, pl: u32, n: u16) {
        wr(d, ch_off(ch, 2), 0x2000_0000);
        wr(d, ch_off(ch, 3), 0x2000_1000);
        wr(d, ch_off(ch, 1), u32::from(n));
        wr(
            d,
            ch_off(ch, 0),
            CCR_MEM2MEM | CCR_PINC | CCR_MINC | (pl << 12) | CCR_EN,
        );
    }

    fn irq(d: &Dma, ch: u8) -> bool {
        let mut l = IrqLines::default();
        d.irq_lines(&mut l);
        d.irq(ch).is_some_and(|n| l.get(n))
    }

    #[test]
    fn wiring_comes_from_the_metadata() {
        let d = Dma::new(DmaInstance::Dma1);
        assert_eq!(d.irq(1), Some(11));
        assert_eq!(d.irq(6), Some(16));
        assert_eq!(d.mux_channel(1), Some(0));
        assert_eq!(d.mux_channel(6), Some(5));
        let d2 = Dma::new(DmaInstance::Dma2);
        assert_eq!(d2.irq(1), crate::names::irq("DMA2_CHANNEL1"));
        assert_eq!(d2.mux_channel(1), Some(8));
        assert_eq!(d.irq(7), None);
    }

    #[test]
    fn register_map() {
        let mut d = Dma::new(DmaInstance::Dma1);
        for ch in 1..=6u8 {
            wr(&mut d, ch_off(ch, 1), 0x1_0000 + u32::from(ch));
            wr(&mut d, ch_off(ch, 2), 0x4000_0000 + u32::from(ch));
            wr(&mut d, ch_off(ch, 3), 0x2000_0000 + u32::from(ch));
            wr(&mut d, ch_off(ch, 0), 0xffff_fffe);
        }
        for ch in 1..=6u8 {
            assert_eq!(rd(&mut d, ch_off(ch, 1)), u32::from(ch), "CNDTR is 16 bits");
            assert_eq!(rd(&mut d, ch_off(ch, 2)), 0x4000_0000 + u32::from(ch));
            assert_eq!(rd(&mut d, ch_off(ch, 3)), 0x2000_0000 + u32::from(ch));
            assert_eq!(rd(&mut d, ch_off(ch, 0)), 0x7ffe, "CCR bits 15-31 reserved");
        }
        assert_eq!(d.read(ch_off(1, 4), 0), None, "reserved word of a channel");
        assert_eq!(d.read(ch_off(7, 0), 0), None, "no channel 7 on the G431");
        assert_eq!(rd(&mut d, ISR), 0);
    }

    #[test]
    fn configuration_is_read_only_while_enabled() {
        let mut d = Dma::new(DmaInstance::Dma1);
        m2m(&mut d, 2, 0, 4);
        let ccr = rd(&mut d, ch_off(2, 0));
        wr(&mut d, ch_off(2, 1), 9);
        wr(&mut d, ch_off(2, 2), 0x1234);
        wr(&mut d, ch_off(2, 3), 0x5678);
        // The IE bits stay writable, the rest of the configuration does not.
        wr(&mut d, ch_off(2, 0), CCR_EN | CCR_TCIE | CCR_CIRC);
        assert_eq!(rd(&mut d, ch_off(2, 1)), 4);
        assert_eq!(rd(&mut d, ch_off(2, 2)), 0x2000_0000);
        assert_eq!(rd(&mut d, ch_off(2, 3)), 0x2000_1000);
        assert_eq!(rd(&mut d, ch_off(2, 0)), ccr | CCR_TCIE);
        assert_eq!(d.take_reports().len(), 4);
        // embassy's request_reset: CCR = TEIE | TCIE clears EN (the locked fields keep
        // their value through that write); the next configure then writes them.
        wr(&mut d, ch_off(2, 0), CCR_TEIE | CCR_TCIE);
        assert_eq!(rd(&mut d, ch_off(2, 0)) & CCR_EN, 0);
        wr(&mut d, ch_off(2, 0), CCR_DIR);
        assert_eq!(rd(&mut d, ch_off(2, 0)), CCR_DIR);
        wr(&mut d, ch_off(2, 1), 9);
        assert_eq!(rd(&mut d, ch_off(2, 1)), 9);
        assert!(
            d.take_reports().is_empty(),
            "request_reset's write is not reported"
        );
        // A driver that clears EN and changes the configuration in one write, then enables
        // the channel, runs it with the old configuration: reported at the enable.
        wr(&mut d, ch_off(2, 0), CCR_DIR | CCR_EN);
        wr(&mut d, ch_off(2, 0), CCR_MINC);
        assert_eq!(rd(&mut d, ch_off(2, 0)), CCR_DIR);
        wr(&mut d, ch_off(2, 1), 3);
        wr(&mut d, ch_off(2, 0), CCR_DIR | CCR_EN);
        let r = d.take_reports();
        assert_eq!(r.len(), 1, "{r:?}");
        assert!(r[0].contains("before a write that cleared EN"));
    }

    #[test]
    fn arbitration_by_priority_then_channel_number() {
        let mut d = Dma::new(DmaInstance::Dma1);
        let mux = Dmamux::new();
        let none = DmaRequests::default();
        m2m(&mut d, 1, 0, 1);
        m2m(&mut d, 2, 0, 1);
        m2m(&mut d, 3, 2, 1);
        m2m(&mut d, 5, 2, 1);
        let mut order = Vec::new();
        while let Some(t) = d.next_transfer(&mux, &none) {
            order.push(t.channel);
            d.complete(&t);
        }
        assert_eq!(order, vec![3, 5, 1, 2]);
    }

    #[test]
    fn a_channel_serves_only_its_request_line() {
        let mut d = Dma::new(DmaInstance::Dma1);
        let mut mux = Dmamux::new();
        // DMA1 channel 4 hangs off DMAMUX channel 3.
        mux.write(Write::word(3 * 4, 26), 0);
        wr(&mut d, ch_off(4, 1), 2);
        wr(&mut d, ch_off(4, 0), CCR_EN);
        let mut r = DmaRequests::default();
        r.set(27);
        assert_eq!(d.next_transfer(&mux, &r), None);
        r.set(26);
        assert_eq!(d.next_transfer(&mux, &r).map(|t| t.channel), Some(4));
    }

    #[test]
    fn normal_mode_ends_with_tc_and_en_still_set() {
        let mut d = Dma::new(DmaInstance::Dma1);
        let mux = Dmamux::new();
        let none = DmaRequests::default();
        m2m(&mut d, 1, 0, 5);
        let ccr = rd(&mut d, ch_off(1, 0));
        wr(&mut d, ch_off(1, 0), ccr | CCR_HTIE | CCR_TCIE);
        let mut ndtr = Vec::new();
        let mut ht_at = None;
        while let Some(t) = d.next_transfer(&mux, &none) {
            d.complete(&t);
            ndtr.push(rd(&mut d, ch_off(1, 1)));
            if ht_at.is_none() && rd(&mut d, ISR) & 0b0100 != 0 {
                ht_at = Some(ndtr.len());
            }
        }
        assert_eq!(ndtr, vec![4, 3, 2, 1, 0]);
        assert_eq!(
            ht_at,
            Some(3),
            "HT when CNDTR reaches 5/2 = 2, after the 3rd item"
        );
        assert_eq!(rd(&mut d, ISR) & 0xf, 0b0111, "GIF, TCIF, HTIF");
        assert_ne!(rd(&mut d, ch_off(1, 0)) & CCR_EN, 0, "EN stays set");
        assert!(irq(&d, 1));
        // Re-enabling without reprogramming does nothing: CNDTR is 0.
        wr(&mut d, ch_off(1, 0), ccr & !CCR_EN);
        wr(&mut d, ch_off(1, 0), ccr);
        assert_eq!(d.next_transfer(&mux, &none), None);
        assert!(d.take_reports().is_empty());
    }

    #[test]
    fn ifcr_clears_what_is_written_as_one() {
        let mut d = Dma::new(DmaInstance::Dma1);
        let mux = Dmamux::new();
        let none = DmaRequests::default();
        for ch in [2u8, 5] {
            m2m(&mut d, ch, 0, 2);
        }
        while let Some(t) = d.next_transfer(&mux, &none) {
            d.complete(&t);
        }
        let both = (0b0111 << 4) | (0b0111 << 16);
        assert_eq!(rd(&mut d, ISR), both);
        wr(&mut d, IFCR, 0);
        assert_eq!(rd(&mut d, ISR), both);
        wr(&mut d, ISR, 0);
        assert_eq!(rd(&mut d, ISR), both, "ISR is read-only");
        // CTCIF2: channel 2 keeps HTIF (and so GIF).
        wr(&mut d, IFCR, 0b0010 << 4);
        assert_eq!(rd(&mut d, ISR), (0b0101 << 4) | (0b0111 << 16));
        // CGIF5 clears all of channel 5.
        wr(&mut d, IFCR, 0b0001 << 16);
        assert_eq!(rd(&mut d, ISR), 0b0101 << 4);
        wr(&mut d, IFCR, 0b0100 << 4);
        assert_eq!(rd(&mut d, ISR), 0);
        assert_eq!(rd(&mut d, IFCR), 0);
    }

    #[test]
    fn bus_error_sets_teif_and_disables_the_channel() {
        let mut d = Dma::new(DmaInstance::Dma1);
        let mux = Dmamux::new();
        let none = DmaRequests::default();
        m2m(&mut d, 3, 0, 4);
        let ccr = rd(&mut d, ch_off(3, 0));
        wr(&mut d, ch_off(3, 0), ccr | CCR_TEIE);
        let t = d
            .next_transfer(&mux, &none)
            .unwrap_or_else(|| panic!("transfer"));
        d.bus_error(t.channel);
        assert_eq!(rd(&mut d, ISR), 0b1001 << 8, "GIF3 | TEIF3");
        assert_eq!(rd(&mut d, ch_off(3, 0)) & CCR_EN, 0);
        assert_eq!(rd(&mut d, ch_off(3, 1)), 4, "nothing was counted");
        assert!(irq(&d, 3));
        assert_eq!(d.next_transfer(&mux, &none), None);
    }

    #[test]
    fn sizes_alignment_and_increments() {
        let mut d = Dma::new(DmaInstance::Dma1);
        let mux = Dmamux::new();
        let none = DmaRequests::default();
        // Peripheral (source) 32-bit at an unaligned CPAR, memory 16-bit, both incremented.
        wr(&mut d, ch_off(1, 2), 0x4000_0003);
        wr(&mut d, ch_off(1, 3), 0x2000_0001);
        wr(&mut d, ch_off(1, 1), 2);
        wr(
            &mut d,
            ch_off(1, 0),
            CCR_MEM2MEM | CCR_PINC | CCR_MINC | CCR_SIZE32_P | CCR_SIZE16_M | CCR_EN,
        );
        let t = d
            .next_transfer(&mux, &none)
            .unwrap_or_else(|| panic!("transfer"));
        assert_eq!(
            t,
            Transfer {
                channel: 1,
                src: 0x4000_0000,
                src_size: 4,
                dst: 0x2000_0000,
                dst_size: 2
            }
        );
        assert_eq!(
            t.value_to_write(0x1234_5678),
            0x5678,
            "truncated to 16 bits"
        );
        d.complete(&t);
        let t = d
            .next_transfer(&mux, &none)
            .unwrap_or_else(|| panic!("transfer"));
        assert_eq!((t.src, t.dst), (0x4000_0004, 0x2000_0002));
        // DIR = 1 swaps source and destination.
        let mut d = Dma::new(DmaInstance::Dma1);
        wr(&mut d, ch_off(1, 2), 0x4000_4428);
        wr(&mut d, ch_off(1, 3), 0x2000_0010);
        wr(&mut d, ch_off(1, 1), 1);
        wr(&mut d, ch_off(1, 0), CCR_MEM2MEM | CCR_DIR | CCR_EN);
        let t = d
            .next_transfer(&mux, &none)
            .unwrap_or_else(|| panic!("transfer"));
        assert_eq!(
            (t.src, t.src_size, t.dst, t.dst_size),
            (0x2000_0010, 1, 0x4000_4428, 1)
        );
    }

    // ---- A minimal SoC: CPU register accesses, the DMA service loop, RAM, interrupts. ----

    const RAM: u32 = 0x2000_0000;
    /// 8N1 at 115200 baud (BRR 1476): 10 bits of 1476 cycles.
    const FRAME: Cycles = 14_760;
    const TX_CH: u8 = 1;
    const RX_CH: u8 = 2;

    // USART registers used by the driver sequences.
    const U_CR1: u32 = 0x00;
    const U_CR2: u32 = 0x04;
    const U_CR3: u32 = 0x08;
    const U_BRR: u32 = 0x0c;
    const U_ISR: u32 = 0x1c;
    const U_ICR: u32 = 0x20;
    const U_RDR: u32 = 0x24;
    const U_TDR: u32 = 0x28;
    const U_PRESC: u32 = 0x2c;
    const UE: u32 = 1;
    const RE: u32 = 1 << 2;
    const TE: u32 = 1 << 3;
    const IDLEIE: u32 = 1 << 4;
    const RXNEIE: u32 = 1 << 5;
    const TCIE_U: u32 = 1 << 6;
    const PEIE: u32 = 1 << 8;
    const PCE: u32 = 1 << 10;
    const FIFOEN: u32 = 1 << 29;
    const EIE: u32 = 1;
    const DMAR: u32 = 1 << 6;
    const DMAT: u32 = 1 << 7;
    const ONEBIT: u32 = 1 << 11;
    const HDSEL: u32 = 1 << 3;
    const PE_F: u32 = 1;
    const FE_F: u32 = 2;
    const NE_F: u32 = 4;
    const ORE_F: u32 = 8;
    const IDLE_F: u32 = 0x10;
    const TC_F: u32 = 0x40;

    struct Bench {
        now: Cycles,
        usart: Usart,
        dma: Dma,
        mux: Dmamux,
        ram: Vec<u8>,
        ubase: u32,
        dbase: u32,
        mbase: u32,
        /// Set by the emulated DMA interrupt handler (embassy's `complete_count`).
        complete_count: [usize; CHANNELS],
        /// Whether the emulated NVIC runs the handlers.
        handlers: bool,
        /// A handler is running (the NVIC does not re-enter it; the DMA keeps working).
        in_handler: bool,
        wire: Vec<TxFrame>,
        /// (cycle, CNDTR of the RX channel) after each RX DMA transfer.
        rx_ndtr: Vec<(Cycles, u32)>,
    }

    impl Bench {
        fn new() -> Self {
            let base = |n: &str| crate::names::base(n).unwrap_or_else(|| panic!("{n}"));
            Bench {
                now: 0,
                usart: Usart::new(UsartInstance::Usart2),
                dma: Dma::new(DmaInstance::Dma1),
                mux: Dmamux::new(),
                ram: vec![0; 0x1000],
                ubase: base("USART2"),
                dbase: base("DMA1"),
                mbase: base("DMAMUX1"),
                complete_count: [0; CHANNELS],
                handlers: true,
                in_handler: false,
                wire: Vec::new(),
                rx_ndtr: Vec::new(),
            }
        }

        fn lane(addr: u32, size: u8) -> (u32, u32) {
            let shift = 8 * (addr & 3);
            let mask = match size {
                1 => 0xff,
                2 => 0xffff,
                _ => !0,
            };
            (shift, mask)
        }

        fn bus_read(&mut self, addr: u32, size: u8) -> Option<u32> {
            let now = self.now;
            let (shift, mask) = Self::lane(addr, size);
            let word = if addr >= RAM && addr < RAM + self.ram.len() as u32 {
                let i = (addr - RAM) as usize;
                let mut v = 0u32;
                for k in 0..usize::from(size) {
                    v |= u32::from(*self.ram.get(i + k)?) << (8 * k);
                }
                return Some(v);
            } else if addr >= self.ubase && addr < self.ubase + 0x400 {
                self.usart.advance(now);
                self.usart.read((addr - self.ubase) & !3, now)?
            } else if addr >= self.dbase && addr < self.dbase + 0x400 {
                self.dma.read((addr - self.dbase) & !3, now)?
            } else if addr >= self.mbase && addr < self.mbase + 0x400 {
                self.mux.read((addr - self.mbase) & !3, now)?
            } else {
                return None;
            };
            Some((word >> shift) & mask)
        }

        fn bus_write(&mut self, addr: u32, size: u8, value: u32) -> bool {
            let now = self.now;
            let (shift, mask) = Self::lane(addr, size);
            let w = |base: u32| Write {
                offset: (addr - base) & !3,
                value: (value & mask) << shift,
                mask: mask << shift,
            };
            if addr >= RAM && addr < RAM + self.ram.len() as u32 {
                let i = (addr - RAM) as usize;
                for k in 0..usize::from(size) {
                    match self.ram.get_mut(i + k) {
                        Some(b) => *b = (value >> (8 * k)) as u8,
                        None => return false,
                    }
                }
                true
            } else if addr >= self.ubase && addr < self.ubase + 0x400 {
                self.usart.advance(now);
                self.usart.write(w(self.ubase), now)
            } else if addr >= self.dbase && addr < self.dbase + 0x400 {
                self.dma.write(w(self.dbase), now)
            } else if addr >= self.mbase && addr < self.mbase + 0x400 {
                self.mux.write(w(self.mbase), now)
            } else {
                false
            }
        }

        /// After every access and event: DMA transfers while requests are pending, then
        /// the interrupt handlers while their lines are high.
        fn settle(&mut self) {
            for _ in 0..1000 {
                let mut req = DmaRequests::default();
                self.usart.dma_requests(&mut req);
                if let Some(t) = self.dma.next_transfer(&self.mux, &req) {
                    match self.bus_read(t.src, t.src_size) {
                        Some(v) if self.bus_write(t.dst, t.dst_size, t.value_to_write(v)) => {
                            self.dma.complete(&t);
                            if t.channel == RX_CH {
                                let n = self.dma.read(ch_off(RX_CH, 1), self.now).unwrap_or(0);
                                self.rx_ndtr.push((self.now, n));
                            }
                        }
                        _ => self.dma.bus_error(t.channel),
                    }
                    continue;
                }
                if !self.handlers || self.in_handler {
                    return;
                }
                let mut lines = IrqLines::default();
                self.usart.irq_lines(&mut lines);
                self.dma.irq_lines(&mut lines);
                if let Some(ch) =
                    (1..=CHANNELS as u8).find(|c| self.dma.irq(*c).is_some_and(|n| lines.get(n)))
                {
                    self.in_handler = true;
                    self.dma_on_irq(ch);
                    self.in_handler = false;
                    continue;
                }
                if self.usart.irq().is_some_and(|n| lines.get(n)) {
                    self.in_handler = true;
                    self.usart_on_interrupt();
                    self.in_handler = false;
                    continue;
                }
                return;
            }
            panic!("interrupt or DMA storm at cycle {}", self.now);
        }

        fn r(&mut self, addr: u32) -> u32 {
            let v = self
                .bus_read(addr, 4)
                .unwrap_or_else(|| panic!("read {addr:#x}"));
            self.settle();
            v
        }

        fn w(&mut self, addr: u32, v: u32) {
            assert!(self.bus_write(addr, 4, v), "write {addr:#x}");
            self.settle();
        }

        fn m(&mut self, addr: u32, f: impl FnOnce(u32) -> u32) {
            let v = self.r(addr);
            self.w(addr, f(v));
        }

        fn u(&self, off: u32) -> u32 {
            self.ubase + off
        }

        fn d(&self, off: u32) -> u32 {
            self.dbase + off
        }

        fn run_until(&mut self, t: Cycles) {
            while let Some(e) = self.usart.next_event().filter(|e| *e <= t) {
                self.now = self.now.max(e);
                self.usart.advance(self.now);
                self.wire
                    .extend(std::iter::from_fn(|| self.usart.take_tx()));
                self.settle();
            }
            self.now = t;
            self.usart.advance(t);
            self.wire
                .extend(std::iter::from_fn(|| self.usart.take_tx()));
            self.settle();
        }

        // ---- embassy-stm32 0.6, step by step ----

        /// `Uart::new` (usart/mod.rs `enable_and_configure` + `configure`), 8N1.
        fn uart_new(&mut self, brr: u32) {
            let (cr1, cr2, cr3, b, p) = (
                self.u(U_CR1),
                self.u(U_CR2),
                self.u(U_CR3),
                self.u(U_BRR),
                self.u(U_PRESC),
            );
            self.w(cr3, 0);
            self.m(cr1, |v| v & !UE);
            self.w(b, brr);
            self.w(p, 0);
            self.w(cr2, 0);
            self.m(cr3, |v| v & !(ONEBIT | HDSEL));
            self.w(cr1, UE | TE | RE | FIFOEN);
        }

        /// dma_bdma.rs `Channel::configure` for byte transfers with MINC.
        #[allow(clippy::too_many_arguments)]
        fn ch_configure(
            &mut self,
            ch: u8,
            request: u8,
            from_memory: bool,
            peri: u32,
            mem: u32,
            len: u16,
            circular: bool,
            half_transfer_ir: bool,
        ) {
            let mux_ch = self.dma.mux_channel(ch).unwrap_or_else(|| panic!("mux"));
            let ccr_mux = self.mbase + 4 * mux_ch as u32;
            self.w(ccr_mux, u32::from(request)); // NBREQ = 0, DMAREQ_ID
            self.m(ccr_mux, |v| v | (1 << 9)); // EGE
            self.complete_count[usize::from(ch - 1)] = 0;
            self.w(self.d(IFCR), 0b1110 << (4 * u32::from(ch - 1)));
            self.w(self.d(ch_off(ch, 2)), peri);
            self.w(self.d(ch_off(ch, 3)), mem);
            self.w(self.d(ch_off(ch, 1)), u32::from(len));
            let mut ccr = CCR_MINC | CCR_TEIE | CCR_TCIE | CCR_PL_VERY_HIGH;
            if from_memory {
                ccr |= CCR_DIR;
            }
            if half_transfer_ir {
                ccr |= CCR_HTIE;
            }
            if circular {
                ccr |= CCR_CIRC;
            }
            self.w(self.d(ch_off(ch, 0)), ccr);
        }

        fn ch_start(&mut self, ch: u8) {
            self.m(self.d(ch_off(ch, 0)), |v| v | CCR_EN);
        }

        fn ch_request_pause(&mut self, ch: u8) {
            self.m(self.d(ch_off(ch, 0)), |v| v & !CCR_EN);
        }

        /// `request_reset` then `while is_running() {}`.
        fn ch_request_reset(&mut self, ch: u8) {
            self.w(self.d(ch_off(ch, 0)), CCR_TEIE | CCR_TCIE);
            assert!(!self.ch_is_running(ch));
        }

        /// bdma `is_running`: EN && (CIRC || complete_count == 0).
        fn ch_is_running(&mut self, ch: u8) -> bool {
            let ccr = self.r(self.d(ch_off(ch, 0)));
            ccr & CCR_EN != 0
                && (ccr & CCR_CIRC != 0 || self.complete_count[usize::from(ch - 1)] == 0)
        }

        /// dma_bdma.rs `on_irq` for a bdma channel.
        fn dma_on_irq(&mut self, ch: u8) {
            let isr = self.r(self.d(ISR)) >> (4 * u32::from(ch - 1));
            let ccr = self.r(self.d(ch_off(ch, 0)));
            assert_eq!(isr & 0b1000, 0, "embassy panics on a DMA transfer error");
            if isr & 0b0100 != 0 && ccr & CCR_HTIE != 0 {
                self.w(self.d(IFCR), 0b0100 << (4 * u32::from(ch - 1)));
            } else if isr & 0b0010 != 0 && ccr & CCR_TCIE != 0 {
                self.w(self.d(IFCR), 0b0010 << (4 * u32::from(ch - 1)));
                self.complete_count[usize::from(ch - 1)] += 1;
            } else {
                panic!("DMA interrupt with nothing to acknowledge: the line would stay high");
            }
        }

        /// usart/mod.rs `on_interrupt`.
        fn usart_on_interrupt(&mut self) {
            let (isr, cr1, cr3) = (
                self.r(self.u(U_ISR)),
                self.r(self.u(U_CR1)),
                self.r(self.u(U_CR3)),
            );
            let has_errors = (isr & PE_F != 0 && cr1 & PEIE != 0)
                || (isr & (FE_F | NE_F | ORE_F) != 0 && cr3 & EIE != 0);
            if has_errors {
                self.m(self.u(U_CR1), |v| v & !(RXNEIE | PEIE | IDLEIE));
                self.m(self.u(U_CR3), |v| v & !(EIE | DMAR));
            } else if cr1 & IDLEIE != 0 && isr & IDLE_F != 0 {
                self.m(self.u(U_CR1), |v| v & !IDLEIE);
            } else if cr1 & TCIE_U != 0 && isr & TC_F != 0 {
                self.m(self.u(U_CR1), |v| v & !TCIE_U);
            } else {
                panic!("USART interrupt the handler cannot clear: ISR {isr:#x}");
            }
        }

        /// ringbuffered.rs `check_idle_and_errors`: Ok(idle) or Err(error flag).
        fn check_idle_and_errors(&mut self) -> Result<bool, u32> {
            let isr = self.r(self.u(U_ISR));
            self.w(self.u(U_ICR), isr);
            for e in [PE_F, FE_F, NE_F, ORE_F] {
                if isr & e != 0 {
                    return Err(e);
                }
            }
            self.m(self.u(U_CR1), |v| v | IDLEIE);
            Ok(isr & IDLE_F != 0)
        }

        /// ringbuffered.rs `start_uart` (eager_reads off).
        fn start_uart(&mut self) {
            self.ch_start(RX_CH);
            self.m(self.u(U_CR1), |v| {
                let peie = if v & PCE != 0 { PEIE } else { 0 };
                (v & !(RXNEIE | PEIE)) | peie | IDLEIE
            });
            self.m(self.u(U_CR3), |v| v | EIE | DMAR);
        }

        /// ringbuffered.rs `stop_uart`.
        fn stop_uart(&mut self) {
            self.ch_request_pause(RX_CH);
            self.m(self.u(U_CR1), |v| v & !(RXNEIE | PEIE | IDLEIE));
            self.m(self.u(U_CR3), |v| v & !(EIE | DMAR));
        }

        /// ringbuffered.rs `start_dma_or_check_errors`.
        fn start_dma_or_check_errors(&mut self) -> Result<(), u32> {
            self.check_idle_and_errors()?;
            if self.r(self.u(U_CR3)) & DMAR == 0 {
                self.start_uart();
            }
            Ok(())
        }

        /// `UartTx::write` up to the transfer's completion and drop.
        fn uart_write(&mut self, mem: u32, bytes: &[u8]) {
            for (k, b) in bytes.iter().enumerate() {
                self.ram[(mem - RAM) as usize + k] = *b;
            }
            self.m(self.u(U_CR3), |v| v | DMAT);
            let tdr = self.u(U_TDR);
            let req = self.usart.dma_request_ids().1.unwrap_or(0);
            self.ch_configure(TX_CH, req, true, tdr, mem, bytes.len() as u16, false, false);
            self.ch_start(TX_CH);
        }
    }

    /// embassy's ReadableDmaRingBuffer index bookkeeping (dma/ringbuffer/mod.rs), rewritten:
    /// the write position is `cap - CNDTR`, laps come from the TC interrupt count.
    struct RingReader {
        cap: usize,
        write: (usize, usize),
        read: (usize, usize),
    }

    impl RingReader {
        fn new(cap: usize) -> Self {
            RingReader {
                cap,
                write: (0, 0),
                read: (0, 0),
            }
        }

        fn sync(&mut self, b: &mut Bench) {
            let laps = std::mem::take(&mut b.complete_count[usize::from(RX_CH - 1)]);
            let ndtr = b.r(b.d(ch_off(RX_CH, 1))) as usize;
            let pos = self.cap - ndtr;
            self.write.1 = if pos < self.write.1 && laps == 0 {
                self.cap - 1
            } else {
                pos
            };
            self.write.0 += laps;
        }

        fn len(&self) -> isize {
            let w = (self.write.0 * self.cap + self.write.1) as isize;
            let r = (self.read.0 * self.cap + self.read.1) as isize;
            w - r
        }

        /// Everything available, or `Err` on an overrun or a desynchronised position.
        fn read(&mut self, b: &mut Bench, ring: u32) -> Result<Vec<u8>, isize> {
            self.sync(b);
            let n = self.len();
            if n < 0 || n > self.cap as isize {
                return Err(n);
            }
            let mut out = Vec::new();
            for _ in 0..n {
                out.push(b.ram[(ring - RAM) as usize + self.read.1]);
                self.read.1 += 1;
                if self.read.1 == self.cap {
                    self.read = (self.read.0 + 1, 0);
                }
            }
            Ok(out)
        }
    }

    #[test]
    fn uart_write_sends_hello_at_the_baud_rate() {
        let mut b = Bench::new();
        b.uart_new(1476);
        b.run_until(200_000);
        let t0 = b.now;
        b.uart_write(RAM + 0x100, b"hello");
        // FIFO mode (embassy sets FIFOEN): one word to the shift register, four into the
        // TXFIFO, all at once; the transfer is complete long before the line is.
        assert_eq!(b.complete_count[usize::from(TX_CH - 1)], 1);
        assert!(!b.ch_is_running(TX_CH));
        assert_ne!(b.r(b.d(ch_off(TX_CH, 0))) & CCR_EN, 0, "EN is still set");
        b.ch_request_reset(TX_CH);
        b.run_until(t0 + 5 * FRAME);
        let expect: Vec<TxFrame> = b"hello"
            .iter()
            .enumerate()
            .map(|(k, c)| TxFrame {
                start: t0 + k as u64 * FRAME,
                end: t0 + (k as u64 + 1) * FRAME,
                data: u16::from(*c),
            })
            .collect();
        assert_eq!(b.wire, expect);
        assert_ne!(b.r(b.u(U_ISR)) & TC_F, 0);
        // A second write reprograms the (disabled) channel: nothing is locked or reported.
        b.uart_write(RAM + 0x200, b"!");
        b.run_until(t0 + 6 * FRAME);
        assert_eq!(
            b.wire.last().map(|f| (f.start, f.data)),
            Some((t0 + 5 * FRAME, 0x21))
        );
        let r = b.dma.take_reports();
        assert!(r.is_empty(), "{r:?}");
        let r = b.usart.take_reports();
        assert!(r.is_empty(), "{r:?}");
    }

    #[test]
    fn without_fifo_the_dma_is_paced_by_txe() {
        let mut b = Bench::new();
        b.uart_new(1476);
        // FIFOEN off (UE must be 0 to change it).
        b.m(b.u(U_CR1), |v| v & !UE);
        b.m(b.u(U_CR1), |v| (v & !FIFOEN) | UE);
        b.run_until(200_000);
        let t0 = b.now;
        b.uart_write(RAM + 0x100, b"hello");
        let ndtr = |b: &mut Bench| b.r(b.d(ch_off(TX_CH, 1)));
        // One word in the shift register, one in TDR.
        assert_eq!(ndtr(&mut b), 3);
        for k in 1..=3u64 {
            b.run_until(t0 + k * FRAME - 1);
            assert_eq!(ndtr(&mut b), 3 - (k as u32 - 1), "before frame {k} ends");
            b.run_until(t0 + k * FRAME);
            assert_eq!(ndtr(&mut b), 3 - k as u32, "TXE at the end of frame {k}");
        }
        assert_eq!(b.complete_count[usize::from(TX_CH - 1)], 1);
        b.ch_request_reset(TX_CH);
        b.run_until(t0 + 5 * FRAME);
        let starts: Vec<Cycles> = b.wire.iter().map(|f| f.start - t0).collect();
        assert_eq!(starts, vec![0, FRAME, 2 * FRAME, 3 * FRAME, 4 * FRAME]);
        let data: Vec<u8> = b.wire.iter().map(|f| f.data as u8).collect();
        assert_eq!(data, b"hello");
    }

    /// RingBufferedUartRx: `into_ring_buffered` + the first `read`'s `start_uart`.
    fn ring_rx(b: &mut Bench, ring: u32, len: u16) {
        let rdr = b.u(U_RDR);
        let req = b.usart.dma_request_ids().0.unwrap_or(0);
        b.ch_configure(RX_CH, req, false, rdr, ring, len, true, true);
        b.start_dma_or_check_errors()
            .unwrap_or_else(|e| panic!("error flag {e:#x}"));
    }

    #[test]
    fn circular_rx_of_ten_bytes_into_an_eight_byte_ring() {
        let mut b = Bench::new();
        b.handlers = false;
        b.uart_new(1476);
        let ring = RAM + 0x400;
        ring_rx(&mut b, ring, 8);
        let t0 = 100_000;
        for k in 1..=10u64 {
            b.usart
                .push_rx(t0 + k * FRAME, RxByte::clean(0x30 + k as u16));
        }
        let isr = |b: &mut Bench| b.r(b.d(ISR)) >> (4 * u32::from(RX_CH - 1)) & 0xf;
        b.run_until(t0 + 4 * FRAME - 1);
        assert_eq!(isr(&mut b), 0);
        b.run_until(t0 + 4 * FRAME);
        assert_eq!(isr(&mut b), 0b0101, "GIF | HTIF as the 4th byte lands");
        b.w(b.d(IFCR), 0b0100 << 4);
        b.run_until(t0 + 8 * FRAME - 1);
        assert_eq!(isr(&mut b), 0);
        b.run_until(t0 + 8 * FRAME);
        assert_eq!(isr(&mut b), 0b0011, "GIF | TCIF as the 8th byte lands");
        b.run_until(t0 + 10 * FRAME);
        // CNDTR after each byte, at the cycle it arrived: never 0 (the reload is immediate).
        let expect: Vec<(Cycles, u32)> = (1..=10u64)
            .map(|k| (t0 + k * FRAME, 8 - (k as u32 % 8)))
            .map(|(t, n)| (t, if n == 0 { 8 } else { n }))
            .collect();
        assert_eq!(b.rx_ndtr, expect);
        assert_eq!(&b.ram[0x400..0x408], b"9:345678", "bytes 9 and 10 wrapped");
        assert_eq!(isr(&mut b), 0b0011, "HT not again before the 12th byte");
    }

    #[test]
    fn ring_buffered_reads_as_embassy_does() {
        let mut b = Bench::new();
        b.uart_new(1476);
        let ring = RAM + 0x400;
        ring_rx(&mut b, ring, 8);
        let mut reader = RingReader::new(8);
        let t0 = 100_000;
        for k in 1..=10u64 {
            b.usart.push_rx(
                t0 + k * FRAME,
                RxByte::clean(u16::from(b'a') + k as u16 - 1),
            );
        }
        b.run_until(t0 + 6 * FRAME);
        assert_eq!(reader.read(&mut b, ring), Ok(b"abcdef".to_vec()));
        b.run_until(t0 + 10 * FRAME);
        assert_eq!(
            b.complete_count[usize::from(RX_CH - 1)],
            1,
            "TC once, HT acknowledged"
        );
        assert_eq!(reader.read(&mut b, ring), Ok(b"ghij".to_vec()));
        // IDLE one frame later wakes the reader (USART interrupt, IDLEIE cleared by the
        // handler, IDLE reported by check_idle_and_errors).
        b.run_until(t0 + 11 * FRAME - 1);
        assert_eq!(b.r(b.u(U_CR1)) & IDLEIE, IDLEIE);
        b.run_until(t0 + 11 * FRAME);
        assert_eq!(b.r(b.u(U_CR1)) & IDLEIE, 0, "the handler ran");
        assert_eq!(b.check_idle_and_errors(), Ok(true));
        assert_eq!(b.check_idle_and_errors(), Ok(false), "ICR cleared IDLE");
        assert!(b.dma.take_reports().is_empty());
    }

    #[test]
    fn rx_error_stops_dma_and_the_restart_without_reprogramming_stays_stopped() {
        let mut b = Bench::new();
        b.uart_new(1476);
        let ring = RAM + 0x400;
        ring_rx(&mut b, ring, 8);
        let mut reader = RingReader::new(8);
        let t0 = 100_000;
        b.usart.push_rx(t0 + FRAME, RxByte::clean(u16::from(b'x')));
        b.usart.push_rx(
            t0 + 2 * FRAME,
            RxByte {
                data: 0,
                framing_error: true,
                noise: false,
            },
        );
        // Two more while DMA is stopped: they wait in RDR/RXFIFO.
        b.usart
            .push_rx(t0 + 3 * FRAME, RxByte::clean(u16::from(b'y')));
        b.usart
            .push_rx(t0 + 4 * FRAME, RxByte::clean(u16::from(b'z')));
        b.run_until(t0 + 2 * FRAME);
        // The FE interrupt (EIE) made the handler clear DMAR and EIE.
        assert_eq!(b.r(b.u(U_CR3)) & (DMAR | EIE), 0);
        assert_eq!(b.rx_ndtr.len(), 1, "the erroneous word was not transferred");
        // The pending read: data first, then the error from check_idle_and_errors.
        assert_eq!(reader.read(&mut b, ring), Ok(b"x".to_vec()));
        assert_eq!(b.check_idle_and_errors(), Err(FE_F));
        b.stop_uart();
        b.run_until(t0 + 4 * FRAME);
        assert_eq!(b.rx_ndtr.len(), 1);
        // The next read: flags clean, DMAR clear, so start_uart re-enables the channel
        // without reprogramming it: undefined in RM0440, reported, and the channel stops.
        b.start_dma_or_check_errors()
            .unwrap_or_else(|e| panic!("error flag {e:#x}"));
        let reports = b.dma.take_reports();
        assert_eq!(reports.len(), 1, "{reports:?}");
        assert!(reports[0].contains("DMA1.CCR2") && reports[0].contains("suspend/resume"));
        assert_ne!(b.r(b.d(ch_off(RX_CH, 0))) & CCR_EN, 0, "EN reads 1");
        assert_eq!(reader.read(&mut b, ring), Ok(Vec::new()), "nothing moves");
        b.usart
            .push_rx(t0 + 10 * FRAME, RxByte::clean(u16::from(b'!')));
        b.run_until(t0 + 10 * FRAME);
        assert_eq!(reader.read(&mut b, ring), Ok(Vec::new()));
        assert_eq!(b.rx_ndtr.len(), 1, "no transfer after the restart");
        // Reprogrammed with EN = 0 (CNDTR written), the channel serves requests again.
        b.ch_request_pause(RX_CH);
        b.w(b.d(ch_off(RX_CH, 1)), 8);
        b.m(b.d(ch_off(RX_CH, 0)), |v| v | CCR_EN);
        b.run_until(t0 + 11 * FRAME);
        assert!(b.rx_ndtr.len() > 1, "transfers again once reprogrammed");
    }

    #[test]
    fn rx_overrun_while_dma_is_stopped() {
        let mut b = Bench::new();
        b.uart_new(1476);
        let ring = RAM + 0x400;
        ring_rx(&mut b, ring, 8);
        b.stop_uart();
        // RDR + 8 in the RXFIFO hold 9 words; the 10th overruns, and the overrun
        // interrupt is off (EIE cleared), so only the next read sees it.
        let t0 = 100_000;
        for k in 1..=10u64 {
            b.usart.push_rx(t0 + k * FRAME, RxByte::clean(k as u16));
        }
        b.run_until(t0 + 11 * FRAME);
        // All flags are cleared at once (ICR = ISR), only the error is reported: the IDLE
        // that came one frame after the 10th word is lost, as ringbuffered.rs documents.
        assert_eq!(b.check_idle_and_errors(), Err(ORE_F));
        assert_eq!(b.check_idle_and_errors(), Ok(false));
        b.start_dma_or_check_errors()
            .unwrap_or_else(|e| panic!("error flag {e:#x}"));
        // The restart only sets EN (no reprogramming): the channel stays stopped and the
        // stored words stay in the USART.
        assert!(b.rx_ndtr.is_empty(), "{:?}", b.rx_ndtr);
        assert!(b
            .dma
            .take_reports()
            .iter()
            .any(|r| r.contains("suspend/resume")));
    }
}
