//! The PLC's reaction to a drive fault report writes the EEPROM fault log: tens of ms of
//! blocking I2C and write cycles on the board. The link pump runs that reaction after the
//! pass's frame (the report's acknowledgement) went out. Before, the reaction ran while
//! the bytes were received, the acknowledgement waited for it, the drive's 50 ms link
//! timeout expired first, and the drive delivered the unacknowledged report again in the
//! next session: logged again, again too slow, forever (seen in the emulator after a
//! drive watchdog reset: the PLC showed "LINK LOST" instead of the fault).
//!
//! Both applications pumped as the boards run them (`board_common::link::run`: receive,
//! transmit, write, then the reaction), with the EEPROM's time modelled and the PLC's
//! link task blocked for as long as its EEPROM work takes.

use std::cell::Cell;
use std::rc::Rc;

use firmware_drive::app::DriveApp;
use firmware_drive::{DriveConfig, ResetCause};
use firmware_plc::app::PlcApp;
use firmware_plc::storage::{Eeprom, EepromError, MemEeprom};
use shared_protocol::link::channel::{Channel, Impairments};
use shared_protocol::link::pump::{Pump, MAX_IDLE_US};
use shared_protocol::link::{LinkConfig, PlcLinkState, MAX_WIRE_FRAME};
use shared_protocol::units::Micros;

/// I2C at 100 kHz: 9 bit times per byte.
const BYTE_US: u64 = 90;
/// Address phase of a transaction (device and word address).
const TRANSACTION_US: u64 = 300;
/// A 24C256 page write cycle.
const WRITE_CYCLE_US: u64 = 5_000;

/// A `MemEeprom` that adds what each access costs on the board to `spent`.
struct TimedEeprom {
    mem: MemEeprom,
    spent: Rc<Cell<u64>>,
}

impl Eeprom for TimedEeprom {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        self.spent
            .set(self.spent.get() + TRANSACTION_US + BYTE_US * buf.len() as u64);
        self.mem.read(addr, buf)
    }
    fn write_page(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        self.spent
            .set(self.spent.get() + TRANSACTION_US + BYTE_US * data.len() as u64 + WRITE_CYCLE_US);
        self.mem.write_page(addr, data)
    }
}

struct Rig {
    plc: PlcApp<TimedEeprom>,
    plc_pump: Pump,
    /// The PLC's link task is blocked (EEPROM work) until then.
    plc_busy_until: Micros,
    plc_wake: Micros,
    /// The longest single block of the PLC's link task by its EEPROM work.
    longest_block_us: u64,
    spent: Rc<Cell<u64>>,
    drive: DriveApp,
    drive_pump: Pump,
    to_drive: Channel,
    to_plc: Channel,
    now: Micros,
}

impl Rig {
    fn new() -> Rig {
        let cfg = LinkConfig::default();
        let spent = Rc::new(Cell::new(0));
        let eeprom = TimedEeprom {
            mem: MemEeprom::new(),
            spent: spent.clone(),
        };
        Rig {
            plc: PlcApp::new(eeprom, cfg, 20, 4, Micros(0)),
            plc_pump: Pump::new(MAX_IDLE_US),
            plc_busy_until: Micros(0),
            plc_wake: Micros(0),
            longest_block_us: 0,
            spent,
            // Restarted by its watchdog: it reports fault WDG once the link is up.
            drive: DriveApp::new(DriveConfig::default(), ResetCause::Watchdog, cfg),
            drive_pump: Pump::new(MAX_IDLE_US),
            to_drive: Channel::new(cfg.baud, Impairments::default(), 1),
            to_plc: Channel::new(cfg.baud, Impairments::default(), 2),
            now: Micros(0),
        }
    }

    /// EEPROM time spent since the last call (the link task was blocked that long).
    fn take_spent(&mut self) -> u64 {
        let block = self.spent.replace(0);
        self.longest_block_us = self.longest_block_us.max(block);
        block
    }

    /// One pass of the PLC's link task at `now`, as `board_common::link::run` makes it.
    fn plc_pass(&mut self, now: Micros) {
        let mut buf = [0u8; 512];
        let n = self.to_plc.receive(now, &mut buf);
        self.spent.set(0);
        self.plc_pump.receive(&mut self.plc, &buf[..n], now);
        let t = Micros(now.0 + self.take_spent());
        let room = if self.to_drive.is_idle(t) {
            MAX_WIRE_FRAME
        } else {
            0
        };
        let pass = self.plc_pump.transmit(&mut self.plc, room, t);
        let mut t = Micros(t.0 + self.take_spent());
        if pass.tx_len > 0 {
            self.to_drive.send(self.plc_pump.tx(), t);
            // The board awaits the write.
            t = self.to_drive.free_at();
        }
        let wake = self.plc_pump.service(&mut self.plc, t);
        let block = self.take_spent();
        self.plc_busy_until = Micros(t.0 + block);
        self.plc_wake = wake;
    }

    fn run_for(&mut self, us: u64) {
        let end = self.now.0 + us;
        let mut buf = [0u8; 512];
        while self.now.0 < end {
            self.now = Micros(self.now.0 + 10);
            let now = self.now;
            if now.0.is_multiple_of(1000) {
                self.drive.tick_1ms(now);
            }
            let n = self.to_drive.receive(now, &mut buf);
            let room = if self.to_plc.is_idle(now) {
                MAX_WIRE_FRAME
            } else {
                0
            };
            self.drive_pump.pass(&mut self.drive, &buf[..n], room, now);
            if !self.drive_pump.tx().is_empty() {
                self.to_plc.send(self.drive_pump.tx(), now);
            }
            let arrived = self.to_plc.next_arrival().is_some_and(|a| a <= now);
            if now >= self.plc_busy_until && (arrived || now >= self.plc_wake) {
                self.plc_pass(now);
            }
        }
    }
}

#[test]
fn a_slow_fault_log_write_does_not_hold_back_the_acknowledgement() {
    let mut r = Rig::new();
    r.run_for(1_000_000);
    let log: Vec<u8> = r.plc.fault_log().iter().map(|e| e.code).collect();
    assert_eq!(log, [7], "WDG logged once");
    // The model is slow enough to matter: one fault's EEPROM work blocks the PLC's link
    // task longer than the drive's link timeout (as on the board).
    assert!(
        r.longest_block_us > LinkConfig::default().drive_timeout_us,
        "block {} us",
        r.longest_block_us
    );
    assert_eq!(r.plc.link().state(), PlcLinkState::Up);
    // The block costs the drive one session at most; the report is not delivered again.
    assert!(
        r.drive.link().stats().link_losses <= 1,
        "{:?}",
        r.drive.link().stats()
    );
}
