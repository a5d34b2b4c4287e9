//! Bus faults the host injects: what a real bus does to a master now and
//! then, so that a driver's error and timeout paths run.
//!
//! A fault is armed for one device address and hits the **last byte of the next write chunk
//! without RELOAD** the master sends to that device, at the byte's acknowledge bit: the
//! second address byte of an EEPROM read (`blocking_write_read`'s write phase), the address
//! of an ACK poll, the last data byte of a page write. That is where embassy-stm32 0.6's
//! blocking master waits for TC (`wait_tc`) or TXIS. What each fault does follows RM0440's
//! "I2C master mode" and "I2C error conditions" sections:
//! * [`I2cFault::Nack`]: the device does not acknowledge the byte: NACKF, and the master
//!   sends STOP by itself (RM0440 "Master transmitter": "If a NACK is received: ... a STOP
//!   condition is automatically sent").
//! * [`I2cFault::Stretch`]: the device holds SCL low before the acknowledge bit for the given
//!   time (a slave may stretch SCL low at any bit; RM0440 "I2C timings"/clock
//!   synchronization): the byte, and TXIS/TC after it, come that much later. With
//!   TIMEOUTR.TIMOUTEN (TIDLE = 0) and a stretch longer than tTIMEOUT = (TIMEOUTA + 1) x
//!   2048 x tI2CCLK, the TIMEOUT flag sets at tTIMEOUT (RM0440 "Timeout error (TIMEOUT)");
//!   the model then also sends STOP once SCL is released, as RM0440 says the master does on
//!   a detected timeout ("a STOP condition is sent automatically" is the SMBus behaviour;
//!   see docs/models.md).
//! * [`I2cFault::ArbitrationLoss`]: another master drives SDA low while this one sends a 1
//!   (RM0440 "Arbitration lost (ARLO)"): ARLO, the master releases the bus and is no longer
//!   master; the other master's transfer is taken to end with its STOP at once (the
//!   addressed device sees a STOP).
//! * [`I2cFault::BusError`]: a misplaced STOP condition in the middle of the byte (RM0440
//!   "Bus error (BERR)": a START or STOP "not located after a multiple of 9 SCL clock
//!   pulses"): BERR. RM0440 does not say what a master does after it; the model abandons
//!   the transfer and releases the lines (as after ARLO), and the STOP ends BUSY.
//!
//! Each fault fires once. Hits are counted in [`super::I2cStats::injected_faults`].

use super::{I2c, Phase, ARLO, BERR, BUSY, CR2_RELOAD, CR2_START, TIMEOUT};
use crate::time::{ns_to_cycles, Cycles};

/// A fault of the bus (see the module documentation for where it hits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum I2cFault {
    /// The device does not acknowledge the byte.
    Nack,
    /// The device holds SCL low for this long before the acknowledge bit.
    Stretch { cycles: Cycles },
    /// Another master wins arbitration in the byte.
    ArbitrationLoss,
    /// A misplaced STOP condition in the byte.
    BusError,
}

impl I2cFault {
    /// A stretch of `ms` milliseconds.
    pub fn stretch_ms(ms: f64) -> Self {
        I2cFault::Stretch {
            cycles: ns_to_cycles((ms * 1e6).round().max(0.0) as u64),
        }
    }
}

/// A fault waiting for its byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Armed {
    fault: I2cFault,
    addr7: u8,
}

/// What the master does with the byte the fault hit.
pub(super) enum Hit {
    /// The byte is acknowledged (`true`) or not, at the slot's usual time.
    Ack(bool),
    /// As `Ack`, but the acknowledge bit ends `cycles` later.
    Stretched { ack: bool, cycles: Cycles },
    /// The transfer ends now with ARLO or BERR set.
    Abort { flag: u32 },
}

/// TIMEOUTR fields.
const TIMEOUTA: u32 = 0x0FFF;
const TIDLE: u32 = 1 << 12;
const TIMOUTEN: u32 = 1 << 15;

impl I2c {
    /// Arms `fault` for the device at 7-bit address `addr7`: it hits the last byte of the
    /// next write chunk without RELOAD to that device. Replaces a fault not yet fired.
    pub fn inject_fault(&mut self, fault: I2cFault, addr7: u8) {
        self.armed = Some(Armed { fault, addr7 });
    }

    /// A fault is armed and has not fired yet.
    pub fn fault_armed(&self) -> bool {
        self.armed.is_some()
    }

    /// Called when the eighth bit of a written data byte is on the wire (byte mode): the
    /// armed fault, if this byte is its target.
    pub(super) fn take_fault(&mut self) -> Option<I2cFault> {
        let a = self.armed?;
        let last_of_chunk = self.count.wrapping_add(1) >= self.nbytes;
        if self.read || a.addr7 != self.addr7 || !last_of_chunk || self.cr2 & CR2_RELOAD != 0 {
            return None;
        }
        self.armed = None;
        self.stats.injected_faults += 1;
        Some(a.fault)
    }

    /// What `fault` does to the byte `byte` whose slot started at `at`; `t` is now (the
    /// eighth bit).
    pub(super) fn apply_fault(&mut self, fault: I2cFault, byte: u8, t: Cycles) -> Hit {
        match fault {
            I2cFault::Nack => Hit::Ack(false),
            I2cFault::Stretch { cycles } => {
                let ack = self.bus.write(byte, t);
                if let Some(limit) = self.timeout_a_cycles() {
                    if cycles > limit {
                        self.timeout_at = Some(t + limit);
                    }
                }
                Hit::Stretched { ack, cycles }
            }
            I2cFault::ArbitrationLoss => Hit::Abort { flag: ARLO },
            I2cFault::BusError => Hit::Abort { flag: BERR },
        }
    }

    /// The transfer ends at `t` with `flag` (ARLO or BERR): the master releases the lines,
    /// the devices see a STOP (the other master's, or the misplaced one), BUSY ends.
    pub(super) fn abort_transfer(&mut self, flag: u32, t: Cycles) {
        self.isr |= flag;
        if flag == ARLO {
            self.stats.arbitration_losses += 1;
        }
        self.cr2 &= !CR2_START;
        self.bus.stop(t);
        self.isr &= !BUSY;
        self.phase = Phase::Idle;
        self.bit_mode = false;
    }

    /// tTIMEOUT in cycles when the SCL-low timeout detector is on (TIMOUTEN, TIDLE = 0).
    fn timeout_a_cycles(&self) -> Option<Cycles> {
        let r = self.timeoutr;
        if r & TIMOUTEN == 0 || r & TIDLE != 0 {
            return None;
        }
        Some((u64::from(r & TIMEOUTA) + 1) * 2048)
    }

    /// The SCL-low timeout fired at `t`: TIMEOUT, and STOP once SCL is released.
    pub(super) fn timeout_detected(&mut self, _t: Cycles) {
        self.timeout_at = None;
        self.isr |= TIMEOUT;
        self.cr2 |= super::CR2_STOP;
    }
}
