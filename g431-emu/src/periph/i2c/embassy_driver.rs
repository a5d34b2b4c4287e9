//! Test driver: the register sequences of embassy-stm32 0.6's blocking I2C v2 master
//! (`src/i2c/v2.rs`: `init`, `blocking_write`, `blocking_write_read`,
//! `blocking_write_vectored`, their `master_write`/`master_read`/`reload`/`wait_*`/
//! `error_occurred`/`flush_txdr`/`soft_reset` helpers), replayed access by access against
//! the model, so the tests drive it exactly as the PLC image does. Each register access
//! costs [`Embassy::access_cycles`] of virtual time; timeouts (embassy-time, 1 s by
//! default) are checked on that clock.

use super::*;

/// embassy's `i2c::Error` (the variants the blocking master returns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Error {
    Bus,
    Arbitration,
    Nack,
    Timeout,
    Overrun,
}

/// embassy's TIMINGR for 100 kHz at 170 MHz (`Timings::new`): PRESC 3, SCLL = SCLH = 211,
/// SDADEL 21 and SCLDEL 84 truncated to their 4-bit fields (5 and 4).
pub(crate) const TIMINGR_100K: u32 = (3 << 28) | (4 << 20) | (5 << 16) | (211 << 8) | 211;

/// The driver: the model, a virtual clock and the timeout.
pub(crate) struct Embassy<'a> {
    pub i2c: &'a mut I2c,
    pub now: Cycles,
    pub access_cycles: Cycles,
    pub timeout: Cycles,
}

impl<'a> Embassy<'a> {
    pub fn new(i2c: &'a mut I2c, now: Cycles) -> Self {
        Embassy {
            i2c,
            now,
            access_cycles: 30,
            // embassy-stm32 `i2c::Config::default().timeout` = 1000 ms.
            timeout: 170_000_000,
        }
    }

    pub fn rd(&mut self, off: u32) -> u32 {
        self.now += self.access_cycles;
        self.i2c.advance(self.now);
        self.i2c.read(off, self.now).expect("modelled register")
    }

    pub fn wr(&mut self, off: u32, v: u32) {
        self.now += self.access_cycles;
        self.i2c.advance(self.now);
        assert!(self.i2c.write(Write::word(off, v), self.now));
    }

    pub fn modify(&mut self, off: u32, f: impl FnOnce(u32) -> u32) {
        let v = self.rd(off);
        self.wr(off, f(v));
    }

    /// Lets virtual time pass (the firmware doing something else, e.g. `block_for`).
    pub fn wait(&mut self, cycles: Cycles) {
        self.now += cycles;
        self.i2c.advance(self.now);
    }

    fn deadline(&self) -> Cycles {
        self.now + self.timeout
    }

    fn check(&self, deadline: Cycles) -> Result<(), Error> {
        if self.now > deadline {
            Err(Error::Timeout)
        } else {
            Ok(())
        }
    }

    /// `init`: PE off with the analog filter on, TIMINGR, PE on.
    pub fn init(&mut self, timingr: u32) {
        self.modify(CR1, |v| v & !(CR1_PE | CR1_ANFOFF));
        self.wr(TIMINGR, timingr);
        self.modify(CR1, |v| v | CR1_PE);
    }

    fn master_stop(&mut self) {
        self.wr(CR2, CR2_STOP);
    }

    fn soft_reset(&mut self) {
        self.modify(CR1, |v| v & !CR1_PE);
        while self.rd(CR1) & CR1_PE != 0 {}
        self.modify(CR1, |v| v | CR1_PE);
    }

    fn cr2_transfer(
        v: u32,
        address: u8,
        read: bool,
        len: usize,
        autoend: bool,
        reload: bool,
    ) -> u32 {
        let mut v =
            v & !(CR2_SADD | CR2_RD_WRN | CR2_ADD10 | CR2_NBYTES | CR2_AUTOEND | CR2_RELOAD);
        v |= u32::from(address) << 1;
        if read {
            v |= CR2_RD_WRN;
        }
        v |= (len as u32) << CR2_NBYTES_SHIFT;
        v |= CR2_START;
        if autoend {
            v |= CR2_AUTOEND;
        }
        if reload {
            v |= CR2_RELOAD;
        }
        v
    }

    fn master_read(
        &mut self,
        address: u8,
        len: usize,
        autoend: bool,
        reload: bool,
        restart: bool,
        dl: Cycles,
    ) -> Result<(), Error> {
        assert!(len < 256);
        if !restart {
            while self.rd(CR2) & CR2_START != 0 {
                self.check(dl)?;
            }
        }
        self.modify(CR2, |v| {
            Self::cr2_transfer(v, address, true, len, autoend, reload)
        });
        Ok(())
    }

    fn master_write(
        &mut self,
        address: u8,
        len: usize,
        autoend: bool,
        reload: bool,
        restart: bool,
        dl: Cycles,
    ) -> Result<(), Error> {
        assert!(len < 256);
        if !restart {
            while self.rd(CR2) & CR2_START != 0 {
                self.check(dl)?;
            }
            while self.rd(ISR) & BUSY != 0 {
                self.check(dl)?;
            }
        }
        self.modify(CR2, |v| {
            Self::cr2_transfer(v, address, false, len, autoend, reload)
        });
        Ok(())
    }

    fn reload(
        &mut self,
        len: usize,
        will_reload: bool,
        autoend: bool,
        dl: Cycles,
    ) -> Result<(), Error> {
        assert!(len < 256 && len > 0);
        loop {
            let isr = self.rd(ISR);
            if isr & (TCR | TC) != 0 {
                break;
            }
            self.check(dl)?;
        }
        self.modify(CR2, |v| {
            let mut v = v & !(CR2_NBYTES | CR2_RELOAD | CR2_AUTOEND);
            v |= (len as u32) << CR2_NBYTES_SHIFT;
            if will_reload {
                v |= CR2_RELOAD;
            }
            if autoend {
                v |= CR2_AUTOEND;
            }
            v
        });
        Ok(())
    }

    fn flush_txdr(&mut self) {
        if self.rd(ISR) & TXIS != 0 {
            self.modify(TXDR, |v| v & !0xFF);
        }
        if self.rd(ISR) & TXE == 0 {
            self.modify(ISR, |v| v | TXE);
        }
    }

    fn error_occurred(&mut self, isr: u32, dl: Cycles) -> Result<(), Error> {
        if isr & NACKF != 0 {
            self.modify(ICR, |v| v | NACKF);
            if self.wait_stop(dl).is_ok() {
                self.modify(ICR, |v| v | STOPF);
            }
            self.flush_txdr();
            return Err(Error::Nack);
        } else if isr & BERR != 0 {
            self.modify(ICR, |v| v | BERR);
            self.flush_txdr();
            self.soft_reset();
            return Err(Error::Bus);
        } else if isr & ARLO != 0 {
            self.modify(ICR, |v| v | ARLO);
            self.flush_txdr();
            self.soft_reset();
            return Err(Error::Arbitration);
        } else if isr & OVR != 0 {
            self.modify(ICR, |v| v | OVR);
            return Err(Error::Overrun);
        }
        Ok(())
    }

    fn wait_txis(&mut self, dl: Cycles) -> Result<(), Error> {
        loop {
            let isr = self.rd(ISR);
            self.error_occurred(isr, dl)?;
            if isr & TXIS != 0 {
                return Ok(());
            }
            self.check(dl)?;
        }
    }

    fn wait_stop(&mut self, dl: Cycles) -> Result<(), Error> {
        loop {
            if self.rd(ISR) & STOPF != 0 {
                self.modify(ICR, |v| v | STOPF);
                return Ok(());
            }
            self.check(dl)?;
        }
    }

    fn wait_rxne(&mut self, dl: Cycles) -> Result<(), Error> {
        loop {
            let isr = self.rd(ISR);
            self.error_occurred(isr, dl)?;
            // STOPF (DataAvailable or StopReceived), RXNE, ADDR (NewStart): embassy returns
            // and the caller reads RXDR in every case.
            if isr & (STOPF | RXNE | ADDR) != 0 {
                return Ok(());
            }
            self.check(dl)?;
        }
    }

    fn wait_tc(&mut self, dl: Cycles) -> Result<(), Error> {
        loop {
            let isr = self.rd(ISR);
            self.error_occurred(isr, dl)?;
            if isr & (TC | TCR) != 0 {
                return Ok(());
            }
            self.check(dl)?;
        }
    }

    fn read_internal(
        &mut self,
        address: u8,
        read: &mut [u8],
        restart: bool,
        dl: Cycles,
    ) -> Result<(), Error> {
        let completed_chunks = read.len() / 255;
        let total_chunks = if completed_chunks * 255 == read.len() {
            completed_chunks
        } else {
            completed_chunks + 1
        };
        let last_chunk_idx = total_chunks.saturating_sub(1);
        self.master_read(
            address,
            read.len().min(255),
            true,
            last_chunk_idx != 0,
            restart,
            dl,
        )?;
        for (number, chunk) in read.chunks_mut(255).enumerate() {
            if number != 0 {
                self.reload(chunk.len(), number != last_chunk_idx, true, dl)?;
            }
            for byte in chunk {
                self.wait_rxne(dl)?;
                *byte = self.rd(RXDR) as u8;
            }
        }
        self.wait_stop(dl)?;
        Ok(())
    }

    fn write_internal(
        &mut self,
        address: u8,
        write: &[u8],
        send_stop: bool,
        dl: Cycles,
    ) -> Result<(), Error> {
        let completed_chunks = write.len() / 255;
        let total_chunks = if completed_chunks * 255 == write.len() {
            completed_chunks
        } else {
            completed_chunks + 1
        };
        let last_chunk_idx = total_chunks.saturating_sub(1);
        if let Err(err) = self.master_write(
            address,
            write.len().min(255),
            false,
            last_chunk_idx != 0,
            false,
            dl,
        ) {
            if send_stop {
                self.master_stop();
            }
            return Err(err);
        }
        for (number, chunk) in write.chunks(255).enumerate() {
            if number != 0 {
                self.reload(chunk.len(), number != last_chunk_idx, false, dl)?;
            }
            for byte in chunk {
                if let Err(err) = self.wait_txis(dl) {
                    if send_stop && err != Error::Nack {
                        self.master_stop();
                    }
                    return Err(err);
                }
                self.wr(TXDR, u32::from(*byte));
            }
        }
        self.wait_tc(dl)?;
        if send_stop {
            self.master_stop();
            self.wait_stop(dl)?;
        }
        Ok(())
    }

    pub fn blocking_write(&mut self, address: u8, write: &[u8]) -> Result<(), Error> {
        let dl = self.deadline();
        self.write_internal(address, write, true, dl)
    }

    pub fn blocking_read(&mut self, address: u8, read: &mut [u8]) -> Result<(), Error> {
        let dl = self.deadline();
        self.read_internal(address, read, false, dl)
    }

    pub fn blocking_write_read(
        &mut self,
        address: u8,
        write: &[u8],
        read: &mut [u8],
    ) -> Result<(), Error> {
        let dl = self.deadline();
        self.write_internal(address, write, false, dl)?;
        self.read_internal(address, read, true, dl)
    }

    pub fn blocking_write_vectored(&mut self, address: u8, write: &[&[u8]]) -> Result<(), Error> {
        assert!(!write.is_empty());
        let dl = self.deadline();
        let first_length = write[0].len();
        let last_slice_index = write.len() - 1;
        if let Err(err) = self.master_write(
            address,
            first_length.min(255),
            false,
            (first_length > 255) || (last_slice_index != 0),
            false,
            dl,
        ) {
            self.master_stop();
            return Err(err);
        }
        for (idx, slice) in write.iter().enumerate() {
            let slice_len = slice.len();
            let completed_chunks = slice_len / 255;
            let total_chunks = if completed_chunks * 255 == slice_len {
                completed_chunks
            } else {
                completed_chunks + 1
            };
            let last_chunk_idx = total_chunks.saturating_sub(1);
            if idx != 0 {
                if let Err(err) = self.reload(
                    slice_len.min(255),
                    (idx != last_slice_index) || (slice_len > 255),
                    false,
                    dl,
                ) {
                    if err != Error::Nack {
                        self.master_stop();
                    }
                    return Err(err);
                }
            }
            for (number, chunk) in slice.chunks(255).enumerate() {
                if number != 0 {
                    if let Err(err) = self.reload(
                        chunk.len(),
                        (number != last_chunk_idx) || (idx != last_slice_index),
                        false,
                        dl,
                    ) {
                        if err != Error::Nack {
                            self.master_stop();
                        }
                        return Err(err);
                    }
                }
                for byte in chunk {
                    if let Err(err) = self.wait_txis(dl) {
                        if err != Error::Nack {
                            self.master_stop();
                        }
                        return Err(err);
                    }
                    self.wr(TXDR, u32::from(*byte));
                }
            }
        }
        self.wait_tc(dl)?;
        self.master_stop();
        self.wait_stop(dl)?;
        Ok(())
    }
}
