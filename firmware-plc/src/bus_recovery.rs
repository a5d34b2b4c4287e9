//! I2C bus clear, at boot and after a broken transaction.
//!
//! A reset (watchdog, debugger, NRST) in the middle of an EEPROM read can leave the 24C256
//! shifting out a 0 bit: it holds SDA low until it sees more SCL clocks, and every master
//! transaction after boot fails. The I2C peripheral has no bus clear, so the board drives
//! the pins as open-drain GPIOs and this sequence (the usual one, as in the I2C
//! specification's "bus clear") frees the bus: up to 9 SCL pulses while SDA reads low,
//! then a STOP (SDA low to high while SCL is high).
//!
//! At run time a transaction can break the same way, or leave the peripheral itself in
//! the middle of a transfer (a device holding SCL low past the board's transaction
//! timeout, a bus error). [`after_failure`] is the rule for what the board does then:
//! reset the peripheral and run this bus clear, for anything but a NACK.

/// The bus pins as open-drain GPIOs, and a half-period delay. `true` = released (pulled
/// up), `false` = driven low.
pub trait BusPins {
    fn set_scl(&mut self, high: bool);
    fn set_sda(&mut self, high: bool);
    /// SDA's level as read at the pin.
    fn sda_high(&mut self) -> bool;
    /// SCL's level as read at the pin (low while a device stretches the clock).
    fn scl_high(&mut self) -> bool;
    /// Half an SCL period (5 µs at 100 kHz).
    fn half_period(&mut self);
}

/// SCL pulses at most: a slave's byte is 8 bits plus the ACK.
pub const MAX_PULSES: u8 = 9;

/// What the bus clear found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Recovery {
    /// SDA was high: only the STOP was sent.
    Idle,
    /// SDA was held low and was released after this many pulses.
    Freed { pulses: u8 },
    /// SDA still low after [`MAX_PULSES`] pulses, or SCL held low: a shorted or dead bus.
    Stuck,
}

/// Clears the bus (see the module docs). Leaves both lines released.
pub fn recover(p: &mut impl BusPins) -> Recovery {
    p.set_sda(true);
    p.set_scl(true);
    p.half_period();
    if !p.scl_high() {
        return Recovery::Stuck;
    }
    let mut pulses = 0u8;
    while !p.sda_high() {
        if pulses == MAX_PULSES {
            return Recovery::Stuck;
        }
        p.set_scl(false);
        p.half_period();
        p.set_scl(true);
        p.half_period();
        pulses += 1;
    }
    // STOP: SDA low while SCL is low, SCL high, then SDA high.
    p.set_scl(false);
    p.half_period();
    p.set_sda(false);
    p.half_period();
    p.set_scl(true);
    p.half_period();
    p.set_sda(true);
    p.half_period();
    if pulses == 0 {
        Recovery::Idle
    } else {
        Recovery::Freed { pulses }
    }
}

/// How a transaction on the bus failed, as the board's I2C driver reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    /// The addressed device did not acknowledge: the 24C256 during its write cycle (its
    /// ready poll lives on these), an absent LCD backpack. The peripheral ended the
    /// transfer with a STOP by itself (RM0440 "I2C master mode": NACKF, automatic STOP).
    Nack,
    /// Nothing was sent (an empty transfer).
    NotSent,
    /// Anything else: a timeout (a device held SCL low, the bus never went idle), a bus
    /// error, a lost arbitration. The peripheral may be left in the middle of a transfer
    /// (embassy-stm32 0.6 returns a timeout without a STOP, with BUSY set and CR2.STOP
    /// pending) and a device in the middle of a byte.
    Broken,
}

/// What the board does after a failed transaction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AfterFailure {
    /// Nothing: the bus is idle and the peripheral ready.
    Nothing,
    /// Reset the peripheral (RM0440 "I2C software reset": PE = 0, read back 0, which
    /// covers the 3 APB cycles, then PE = 1) and clear the bus from the pins with
    /// [`recover`] in between, so that the next transaction starts on an idle bus.
    ResetAndClear,
}

/// The run-time rule: a broken transaction resets the peripheral and clears the bus; a
/// NACK never does (the EEPROM's write-cycle polls are NACKs, a reset per poll would
/// clear the bus every millisecond of a save). The transaction is not repeated: the
/// caller gets its error (a storage job fails with `EepromError::Bus` and says so; the
/// LCD is initialised again by its retry timer), and its next transaction finds the bus
/// idle.
pub fn after_failure(f: Failure) -> AfterFailure {
    match f {
        Failure::Broken => AfterFailure::ResetAndClear,
        Failure::Nack | Failure::NotSent => AfterFailure::Nothing,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 24C256 left in the middle of a read: it drives SDA with the bits of `byte`
    /// (MSB first) from `bit`, one per SCL falling edge, then releases SDA for the ACK
    /// slot (the master's, not driven) and stops.
    struct Slave {
        scl: bool,
        sda_master: bool,
        byte: u8,
        bit: u8,
        done: bool,
        edges: Vec<(bool, bool)>,
        stuck_scl: bool,
    }

    impl Slave {
        fn new(byte: u8, bit: u8) -> Self {
            Slave {
                scl: true,
                sda_master: true,
                byte,
                bit,
                done: false,
                edges: vec![],
                stuck_scl: false,
            }
        }
        fn slave_sda(&self) -> bool {
            self.done || self.bit >= 8 || self.byte & (0x80 >> self.bit) != 0
        }
    }

    impl BusPins for Slave {
        fn set_scl(&mut self, high: bool) {
            if self.scl && !high && !self.done {
                // Falling edge: the slave moves to its next bit.
                self.bit += 1;
                if self.bit > 8 {
                    self.done = true;
                }
            }
            self.scl = high;
            let e = (self.scl, self.sda_high());
            self.edges.push(e);
        }
        fn set_sda(&mut self, high: bool) {
            if self.scl && self.sda_master && !high {
                // START while the slave is not driving: it resets its state machine.
                if self.slave_sda() {
                    self.done = true;
                }
            }
            self.sda_master = high;
            let e = (self.scl, self.sda_high());
            self.edges.push(e);
        }
        fn sda_high(&mut self) -> bool {
            self.sda_master && self.slave_sda()
        }
        fn scl_high(&mut self) -> bool {
            self.scl && !self.stuck_scl
        }
        fn half_period(&mut self) {}
    }

    #[test]
    fn only_a_broken_transaction_resets_the_peripheral_and_clears_the_bus() {
        assert_eq!(after_failure(Failure::Broken), AfterFailure::ResetAndClear);
        assert_eq!(after_failure(Failure::NotSent), AfterFailure::Nothing);
        // A save polls the busy 24C256 about every millisecond of each 5 ms write cycle;
        // each poll is a NACK and must leave the bus alone.
        assert_eq!(after_failure(Failure::Nack), AfterFailure::Nothing);
    }

    #[test]
    fn an_idle_bus_gets_a_stop_only() {
        let mut s = Slave::new(0xFF, 8);
        s.done = true;
        assert_eq!(recover(&mut s), Recovery::Idle);
        // The last two edges: SCL high with SDA low, then SDA high (STOP).
        let n = s.edges.len();
        assert_eq!(s.edges[n - 2..], [(true, false), (true, true)]);
    }

    #[test]
    fn a_slave_holding_sda_low_is_clocked_free_at_every_bit_position() {
        for byte in [0x00u8, 0x7F, 0x3C, 0x01] {
            for bit in 0..8u8 {
                let mut s = Slave::new(byte, bit);
                if s.slave_sda() {
                    continue;
                }
                match recover(&mut s) {
                    Recovery::Freed { pulses } => assert!(pulses <= MAX_PULSES),
                    other => panic!("byte {byte:#x} bit {bit}: {other:?}"),
                }
                assert!(s.sda_high() && s.scl_high());
                let n = s.edges.len();
                assert_eq!(s.edges[n - 1], (true, true));
            }
        }
    }

    #[test]
    fn a_shorted_bus_is_reported_stuck() {
        struct Short;
        impl BusPins for Short {
            fn set_scl(&mut self, _: bool) {}
            fn set_sda(&mut self, _: bool) {}
            fn sda_high(&mut self) -> bool {
                false
            }
            fn scl_high(&mut self) -> bool {
                true
            }
            fn half_period(&mut self) {}
        }
        assert_eq!(recover(&mut Short), Recovery::Stuck);
        let mut s = Slave::new(0, 0);
        s.stuck_scl = true;
        assert_eq!(recover(&mut s), Recovery::Stuck);
    }
}
