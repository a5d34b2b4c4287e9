//! The PLC's reaction to a drive fault report writes the EEPROM fault log: I2C transfers
//! and page write cycles on the board. Once that write ran inside the link pass that
//! received the report, the acknowledgement waited for it, the drive's 50 ms link timeout
//! expired first, and the drive delivered the unacknowledged report again in the next
//! session: logged again, again too slow, forever (seen in the emulator after a drive
//! watchdog reset: the PLC showed "LINK LOST" instead of the fault). Now the link pass
//! only queues a storage job; `PlcApp::tick_1ms` runs it one EEPROM page per tick, and
//! waits for the write cycle with non-blocking ready polls.
//!
//! Both applications pumped as the boards run them (`board_common::link::run`: receive,
//! transmit, write, then the reaction; the PLC's application task every millisecond),
//! with the EEPROM's bus time modelled and the PLC's tasks (one executor) blocked for as
//! long as its EEPROM work takes.

use std::cell::Cell;
use std::rc::Rc;

use firmware_drive::app::DriveApp;
use firmware_drive::{DriveConfig, ResetCause};
use firmware_plc::app::{PlcApp, RawIo};
use firmware_plc::editor::Screen;
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
/// An address-only poll (start, address byte, NACK or ACK, stop).
const POLL_US: u64 = 100;

/// A `MemEeprom` that adds what each access costs on the board to `spent`, and answers
/// "busy" for a write cycle's time after a write.
struct TimedEeprom {
    mem: MemEeprom,
    spent: Rc<Cell<u64>>,
    /// The board's clock as the rig runs it (write cycles end in real time).
    clock: Rc<Cell<u64>>,
    busy_until: u64,
}

impl TimedEeprom {
    fn charge(&self, us: u64) {
        self.spent.set(self.spent.get() + us);
    }
}

impl Eeprom for TimedEeprom {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        self.charge(TRANSACTION_US + BYTE_US * buf.len() as u64);
        self.mem.read(addr, buf)
    }
    fn start_write(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        self.charge(TRANSACTION_US + BYTE_US * data.len() as u64);
        self.busy_until = self.clock.get() + WRITE_CYCLE_US;
        self.mem.start_write(addr, data)
    }
    fn ready(&mut self) -> Result<bool, EepromError> {
        self.charge(POLL_US);
        Ok(self.clock.get() >= self.busy_until && self.mem.ready()?)
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
    clock: Rc<Cell<u64>>,
    screen: Screen,
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
        let clock = Rc::new(Cell::new(0));
        let eeprom = TimedEeprom {
            mem: MemEeprom::new(),
            spent: spent.clone(),
            clock: clock.clone(),
            busy_until: 0,
        };
        Rig {
            plc: PlcApp::new(eeprom, cfg, 20, 4, Micros(0)),
            plc_pump: Pump::new(MAX_IDLE_US),
            plc_busy_until: Micros(0),
            plc_wake: Micros(0),
            longest_block_us: 0,
            spent,
            clock,
            screen: Screen::new(20, 4),
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
            self.clock.set(now.0);
            if now.0.is_multiple_of(1000) {
                self.drive.tick_1ms(now);
                if now >= self.plc_busy_until {
                    // The PLC's application task (same executor as its link task).
                    self.spent.set(0);
                    let _ = self.plc.tick_1ms(now, RawIo::default(), &mut self.screen);
                    let block = self.take_spent();
                    self.plc_busy_until = Micros(now.0 + block);
                }
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
    // The EEPROM work is done in steps: no single block comes near the drive's link
    // timeout (one page transfer, a few ms at 100 kHz), however long the whole job is.
    assert!(
        r.longest_block_us < LinkConfig::default().drive_timeout_us / 4,
        "block {} us",
        r.longest_block_us
    );
    assert_eq!(r.plc.link().state(), PlcLinkState::Up);
    // The report is acknowledged in the session that carried it: no session is lost.
    assert!(
        r.drive.link().stats().link_losses == 0,
        "{:?}",
        r.drive.link().stats()
    );
}
