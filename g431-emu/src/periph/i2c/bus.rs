//! The I2C bus: the devices on it ([`I2cDevice`]) and where each one is on the wire.
//!
//! While every device is in step with the master, the bus passes bytes (fast). When the
//! master goes away in the middle of a byte, each device is left where it was and is clocked
//! bit by bit from then on: falling SCL edges move a transmitter to its next bit, rising
//! edges sample SDA, SDA changes while SCL is high are START/STOP conditions. A device that
//! is shifting out a 0 or driving an ACK holds SDA low ([`I2cBus::sda_held_low`]).

use std::cell::RefCell;
use std::rc::Rc;

use crate::time::Cycles;

/// A device on an I2C bus, at byte level. The bus keeps every device's position on the wire
/// itself and only calls these at byte boundaries, also when it clocks a device bit by bit
/// (a stuck bus, GPIO bit-banging), so a device only models its protocol.
pub trait I2cDevice {
    /// The device's 7-bit address (for reports; the device decides itself in [`start`]).
    ///
    /// [`start`]: I2cDevice::start
    fn address(&self) -> u8;

    /// A START or repeated START followed by the address byte (`address` 7-bit, `read` the
    /// R/W bit). Every device sees every START (a START aborts whatever it was doing); it
    /// returns its ACK: `true` only if it is addressed and able to answer.
    fn start(&mut self, address: u8, read: bool, now: Cycles) -> bool;

    /// A byte written to the addressed device (after its eighth bit); returns the ACK.
    fn write(&mut self, byte: u8, now: Cycles) -> bool;

    /// The next byte the addressed device shifts out (asked for at its first bit).
    fn read(&mut self, now: Cycles) -> u8;

    /// A STOP condition on the bus (every device sees it).
    fn stop(&mut self, now: Cycles);

    /// A START condition whose address byte is still to come bit by bit (GPIO bit-banging,
    /// or a master that went away during the address): the device abandons what it was
    /// doing, as after any START; [`start`] follows if the address byte completes.
    ///
    /// [`start`]: I2cDevice::start
    fn start_condition(&mut self, _now: Cycles) {}

    /// Bumped by the device whenever it loses power: the bus then forgets where the device
    /// was on the wire (a powered-down device releases SDA).
    fn power_epoch(&self) -> u32 {
        0
    }
}

/// How the host shares a device with the bus: it keeps a clone of the `Rc` (typed, e.g.
/// `Rc<RefCell<Eeprom24c256>>`) and passes one coerced to this.
pub type SharedDevice = Rc<RefCell<dyn I2cDevice>>;

/// A bus condition made by GPIO edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusCondition {
    /// SDA fell while SCL was high.
    Start,
    /// SDA rose while SCL was high.
    Stop,
}

/// What a device does after the ACK slot it drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AfterAck {
    Receive,
    Send,
}

/// Where a device is on the wire.
///
/// Bit-level states keep this invariant: SCL is high and the device has seen the rising
/// edge of its current bit, so the next edge it expects is a falling one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Wire {
    /// Released; waits for a START (ignores clocks).
    Idle,
    /// Addressed by the byte-level master engine, in step with it.
    Selected { read: bool },
    /// Shifting bits in (the address byte if `address`): `bits` sampled so far.
    Receiving { address: bool, byte: u8, bits: u8 },
    /// Driving the ACK slot (SDA low if `ack`), then `next`.
    Acking { ack: bool, next: AfterAck },
    /// Shifting `byte` out: bit `bit` (0 = MSB) on SDA, 8 = released for the master's ACK,
    /// sampled into `master_ack`.
    Sending { byte: u8, bit: u8, master_ack: bool },
}

impl Wire {
    fn holds_sda_low(self) -> bool {
        match self {
            Wire::Acking { ack, .. } => ack,
            Wire::Sending { byte, bit, .. } => bit < 8 && (byte >> (7 - bit)) & 1 == 0,
            _ => false,
        }
    }
}

struct Attached {
    dev: SharedDevice,
    wire: Wire,
    epoch: u32,
    /// The device's ACK of the last byte-level address or data byte.
    last_ack: bool,
    /// The last byte this device shifted out at byte level.
    last_read: u8,
}

impl Attached {
    /// The wire state, forgetting it if the device lost power since.
    fn wire(&self) -> Wire {
        if self.dev.borrow().power_epoch() != self.epoch {
            Wire::Idle
        } else {
            self.wire
        }
    }

    fn sync_power(&mut self) {
        let e = self.dev.borrow().power_epoch();
        if e != self.epoch {
            self.epoch = e;
            self.wire = Wire::Idle;
        }
    }
}

/// Where the master was when it went away (MCU reset or PE=0) in the middle of a transfer.
#[derive(Debug, Clone, Copy)]
pub(super) enum Abandon {
    /// Master sending the address (`address`) or a data byte: `bits` bits (MSB first, 1..=8)
    /// sampled by the devices, the last one possibly the released level.
    MasterSending {
        address: bool,
        partial: u8,
        bits: u8,
    },
    /// In the ACK slot of a byte the master sent: the devices that ACKed drive SDA low.
    SlaveAcking { address: bool, read: bool },
    /// Master receiving: the addressed devices were at bit `bit` (8 = ACK slot) of their
    /// byte; `master_ack` the ACK they sampled.
    SlaveSending { bit: u8, master_ack: bool },
    /// Stretching after a write byte's ACK: the devices wait for the next byte's first bit
    /// (the release makes its rising edge, sampling a 1).
    BetweenWriteBytes,
    /// Stretching after a read byte the master ACKed: the devices have put the next byte's
    /// MSB on SDA.
    BetweenReadBytesAcked,
    /// After the master NACKed the last read byte: the devices released the bus.
    AfterNack,
}

/// The two wires and the devices on them.
#[derive(Default)]
pub struct I2cBus {
    devices: Vec<Attached>,
    gpio_scl_low: bool,
    gpio_sda_low: bool,
    gpio_scl_pulses: u64,
}

impl std::fmt::Debug for I2cBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("I2cBus")
            .field("devices", &self.devices.len())
            .field("scl", &self.scl())
            .field("sda", &self.sda())
            .finish()
    }
}

impl I2cBus {
    /// Attaches a device (the host keeps its own clone of the `Rc`).
    pub fn attach(&mut self, dev: SharedDevice) {
        let epoch = dev.borrow().power_epoch();
        self.devices.push(Attached {
            dev,
            wire: Wire::Idle,
            epoch,
            last_ack: false,
            last_read: 0xFF,
        });
    }

    /// Number of attached devices.
    pub fn device_count(&self) -> usize {
        self.devices.len()
    }

    /// A device holds SDA low (after an interrupted transfer): a master START is then not
    /// seen on the bus (D6).
    pub fn sda_held_low(&self) -> bool {
        self.devices.iter().any(|a| a.wire().holds_sda_low())
    }

    /// Whether device `index` (attach order) holds SDA low.
    pub fn device_holds_sda(&self, index: usize) -> bool {
        self.devices
            .get(index)
            .is_some_and(|a| a.wire().holds_sda_low())
    }

    /// Level of SCL (`true` = high) as the pins read it, outside master transfers.
    pub fn scl(&self) -> bool {
        !self.gpio_scl_low
    }

    /// Level of SDA (`true` = high) as the pins read it, outside master transfers.
    pub fn sda(&self) -> bool {
        !self.gpio_sda_low && !self.sda_held_low()
    }

    /// Rising SCL edges made by GPIO so far (recovery pulses).
    pub fn gpio_scl_pulses(&self) -> u64 {
        self.gpio_scl_pulses
    }

    /// The firmware drives SCL as an open-drain GPIO: `low` pulls it down, `false`
    /// releases it (also what the SoC passes when the pin leaves output mode). Edges clock
    /// the devices.
    pub fn drive_scl(&mut self, low: bool, now: Cycles) {
        let before = self.scl();
        self.gpio_scl_low = low;
        let after = self.scl();
        if before && !after {
            self.fall(now);
        } else if !before && after {
            self.gpio_scl_pulses += 1;
            let sda = self.sda();
            self.rise(sda, now);
        }
    }

    /// The firmware drives SDA as an open-drain GPIO. A change while SCL is high is a START
    /// or STOP condition, which every device sees; it is returned.
    pub fn drive_sda(&mut self, low: bool, now: Cycles) -> Option<BusCondition> {
        let before = self.sda();
        self.gpio_sda_low = low;
        let after = self.sda();
        if !self.scl() || before == after {
            return None;
        }
        if after {
            self.stop(now);
            Some(BusCondition::Stop)
        } else {
            self.bare_start(now);
            Some(BusCondition::Start)
        }
    }

    /// `n` GPIO pulses on SCL (low then released) at `now`, as a recovery loop makes them.
    pub fn pulse_scl(&mut self, n: u32, now: Cycles) {
        for _ in 0..n {
            self.drive_scl(true, now);
            self.drive_scl(false, now);
        }
    }

    /// A START seen with no byte-level address after it (GPIO): every device listens for
    /// the address bit by bit.
    fn bare_start(&mut self, now: Cycles) {
        for a in &mut self.devices {
            a.sync_power();
            a.dev.borrow_mut().start_condition(now);
            a.wire = Wire::Receiving {
                address: true,
                byte: 0,
                bits: 0,
            };
        }
    }

    /// SDA as the devices and GPIO leave it (the master released).
    pub(super) fn sda_free(&self) -> bool {
        self.sda()
    }

    // --- byte level (the master engine, every device in step) ---

    /// START + address at byte level; returns whether any device ACKed.
    pub(super) fn start(&mut self, address: u8, read: bool, now: Cycles) -> bool {
        let mut any = false;
        for a in &mut self.devices {
            a.sync_power();
            let ack = a.dev.borrow_mut().start(address, read, now);
            a.last_ack = ack;
            a.wire = if ack {
                Wire::Selected { read }
            } else {
                Wire::Idle
            };
            any |= ack;
        }
        any
    }

    pub(super) fn write(&mut self, byte: u8, now: Cycles) -> bool {
        let mut any = false;
        for a in &mut self.devices {
            a.sync_power();
            if a.wire == (Wire::Selected { read: false }) {
                let ack = a.dev.borrow_mut().write(byte, now);
                a.last_ack = ack;
                any |= ack;
            }
        }
        any
    }

    /// The byte on SDA: the wired AND of every addressed transmitter (0xFF if none).
    pub(super) fn read(&mut self, now: Cycles) -> u8 {
        let mut v = 0xFF;
        for a in &mut self.devices {
            a.sync_power();
            if a.wire == (Wire::Selected { read: true }) {
                let b = a.dev.borrow_mut().read(now);
                a.last_read = b;
                v &= b;
            }
        }
        v
    }

    /// A STOP condition seen on the bus.
    pub(super) fn stop(&mut self, now: Cycles) {
        for a in &mut self.devices {
            a.sync_power();
            a.dev.borrow_mut().stop(now);
            a.wire = Wire::Idle;
        }
    }

    // --- bit level ---

    fn fall(&mut self, now: Cycles) {
        for a in &mut self.devices {
            a.sync_power();
            a.wire = match a.wire {
                Wire::Receiving {
                    address,
                    byte,
                    bits: 8,
                } => {
                    let ack = if address {
                        a.dev.borrow_mut().start(byte >> 1, byte & 1 == 1, now)
                    } else {
                        a.dev.borrow_mut().write(byte, now)
                    };
                    let next = if address && byte & 1 == 1 {
                        AfterAck::Send
                    } else {
                        AfterAck::Receive
                    };
                    Wire::Acking { ack, next }
                }
                Wire::Acking { ack: false, .. } => Wire::Idle,
                Wire::Acking {
                    ack: true,
                    next: AfterAck::Receive,
                } => Wire::Receiving {
                    address: false,
                    byte: 0,
                    bits: 0,
                },
                Wire::Acking {
                    ack: true,
                    next: AfterAck::Send,
                } => Wire::Sending {
                    byte: a.dev.borrow_mut().read(now),
                    bit: 0,
                    master_ack: false,
                },
                Wire::Sending {
                    byte,
                    bit,
                    master_ack,
                } if bit < 8 => Wire::Sending {
                    byte,
                    bit: bit + 1,
                    master_ack,
                },
                Wire::Sending {
                    master_ack: true, ..
                } => Wire::Sending {
                    byte: a.dev.borrow_mut().read(now),
                    bit: 0,
                    master_ack: false,
                },
                Wire::Sending { .. } => Wire::Idle,
                w => w,
            };
        }
    }

    fn rise(&mut self, sda: bool, _now: Cycles) {
        for a in &mut self.devices {
            a.sync_power();
            a.wire = match a.wire {
                Wire::Receiving {
                    address,
                    byte,
                    bits,
                } if bits < 8 => Wire::Receiving {
                    address,
                    byte: (byte << 1) | u8::from(sda),
                    bits: bits + 1,
                },
                Wire::Sending { byte, bit: 8, .. } => Wire::Sending {
                    byte,
                    bit: 8,
                    master_ack: !sda,
                },
                w => w,
            };
        }
    }

    /// One SCL clock made by the master: falling edge, the master puts `master_sda` on SDA,
    /// rising edge. Returns SDA as sampled at the rising edge.
    pub(super) fn clock_bit(&mut self, master_sda: bool, now: Cycles) -> bool {
        self.fall(now);
        let line = master_sda && self.sda_free();
        self.rise(line, now);
        line
    }

    /// A byte sent by the master bit by bit: `Ok(ack)` or `Err(bit)` when arbitration is
    /// lost at `bit` (0 = MSB; the master then releases both lines).
    pub(super) fn clock_out(&mut self, byte: u8, now: Cycles) -> Result<bool, u8> {
        for k in 0..8u8 {
            let b = (byte >> (7 - k)) & 1 == 1;
            let line = self.clock_bit(b, now);
            if b && !line {
                return Err(k);
            }
        }
        Ok(!self.clock_bit(true, now))
    }

    /// A byte received by the master bit by bit (SDA released; whatever the devices drive).
    pub(super) fn clock_in(&mut self, now: Cycles) -> u8 {
        let mut v = 0u8;
        for _ in 0..8 {
            v = (v << 1) | u8::from(self.clock_bit(true, now));
        }
        v
    }

    /// Devices still selected by a byte-level transfer whose STOP was not seen (a bit-level
    /// peer held SDA) drop out when the master runs bit by bit.
    pub(super) fn deselect_all(&mut self) {
        for a in &mut self.devices {
            if matches!(a.wire, Wire::Selected { .. }) {
                a.wire = Wire::Idle;
            }
        }
    }

    /// The master went away mid-transfer: leave the devices where they are on the wire.
    pub(super) fn abandon(&mut self, at: Abandon, now: Cycles) {
        for a in &mut self.devices {
            a.sync_power();
            let selected = matches!(a.wire, Wire::Selected { .. });
            a.wire = match at {
                // Every device watches the address after a START.
                Abandon::MasterSending {
                    address: true,
                    partial,
                    bits,
                } => {
                    a.dev.borrow_mut().start_condition(now);
                    Wire::Receiving {
                        address: true,
                        byte: partial,
                        bits,
                    }
                }
                Abandon::MasterSending {
                    address: false,
                    partial,
                    bits,
                } if selected => Wire::Receiving {
                    address: false,
                    byte: partial,
                    bits,
                },
                Abandon::SlaveAcking { address, read } if selected => Wire::Acking {
                    ack: a.last_ack,
                    next: if address && read {
                        AfterAck::Send
                    } else {
                        AfterAck::Receive
                    },
                },
                Abandon::SlaveSending { bit, master_ack } if selected => Wire::Sending {
                    byte: a.last_read,
                    bit,
                    master_ack,
                },
                Abandon::BetweenWriteBytes if selected => Wire::Receiving {
                    address: false,
                    byte: 1,
                    bits: 1,
                },
                Abandon::BetweenReadBytesAcked if selected => {
                    let b = a.dev.borrow_mut().read(now);
                    a.last_read = b;
                    Wire::Sending {
                        byte: b,
                        bit: 0,
                        master_ack: false,
                    }
                }
                Abandon::AfterNack if selected => Wire::Idle,
                _ if selected => Wire::Idle,
                _ => a.wire,
            };
        }
    }
}
