//! The PLC's reaction to a drive fault report writes the EEPROM fault log: I2C transfers
//! and page write cycles on the board. Once that write ran inside the link pass that
//! received the report, the acknowledgement waited for it, the drive's 50 ms link timeout
//! expired first, and the drive delivered the unacknowledged report again in the next
//! session: logged again, again too slow, forever (seen in the emulator after a drive
//! watchdog reset: the PLC showed "LINK LOST" instead of the fault). Now the link pass
//! only queues a storage job; `PlcApp::tick_1ms` runs it one EEPROM page per tick, and
//! waits for the write cycle with non-blocking ready polls.
//!
//! Both applications on the co-simulation rig (`shared_protocol::link::pair::Pair`),
//! pumped as the boards run them (`board_common::link::run`: receive, transmit, write,
//! then the reaction; the application tasks every millisecond), with the EEPROM's bus
//! time modelled and the PLC's tasks (one executor) blocked for as long as its EEPROM
//! work takes.

use std::cell::Cell;
use std::rc::Rc;

use firmware_drive::app::DriveApp;
use firmware_drive::{DriveConfig, ResetCause};
use firmware_plc::app::{PlcApp, RawIo};
use firmware_plc::editor::Screen;
use firmware_plc::storage::{Eeprom, EepromError, MemEeprom};
use shared_protocol::link::channel::Impairments;
use shared_protocol::link::line::{Line, LinkTask, Pumped};
use shared_protocol::link::pair::Pair;
use shared_protocol::link::pump::{Pass, Pump, MAX_IDLE_US};
use shared_protocol::link::{LinkConfig, PlcLinkState};
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

/// The PLC's link task as `board_common::link::run` makes it (receive, transmit, write,
/// then the reaction), on the same executor as its application task: blocked for as long
/// as its EEPROM work takes. Bytes that arrive meanwhile wait in the UART's ring.
struct PlcTask {
    app: PlcApp<TimedEeprom>,
    pump: Pump,
    /// The PLC's tasks are blocked (EEPROM work) until then.
    busy_until: Micros,
    /// The longest single block of the PLC's tasks by its EEPROM work.
    longest_block_us: u64,
    spent: Rc<Cell<u64>>,
    clock: Rc<Cell<u64>>,
    ring: Vec<u8>,
    byte_us: u64,
}

impl PlcTask {
    /// EEPROM time spent since the last call (the task was blocked that long).
    fn take_spent(&mut self) -> u64 {
        let block = self.spent.replace(0);
        self.longest_block_us = self.longest_block_us.max(block);
        block
    }

    /// The application task's 1 ms pass, if the executor is free.
    fn tick_1ms(&mut self, now: Micros, screen: &mut Screen) {
        if now < self.busy_until {
            return;
        }
        self.clock.set(now.0);
        self.spent.set(0);
        let _ = self.app.tick_1ms(now, RawIo::default(), screen);
        let block = self.take_spent();
        self.busy_until = Micros(now.0 + block);
    }
}

impl LinkTask for PlcTask {
    fn pass(&mut self, rx: &[u8], room: usize, now: Micros) -> Pass {
        self.ring.extend_from_slice(rx);
        if now < self.busy_until {
            return Pass {
                tx_len: 0,
                wake_at: self.busy_until,
            };
        }
        self.clock.set(now.0);
        let rx = std::mem::take(&mut self.ring);
        self.spent.set(0);
        self.pump.receive(&mut self.app, &rx, now);
        let t = Micros(now.0 + self.take_spent());
        let pass = self.pump.transmit(&mut self.app, room, t);
        let mut t = Micros(t.0 + self.take_spent());
        // The board awaits the write.
        t = Micros(t.0 + pass.tx_len as u64 * self.byte_us);
        let wake = self.pump.service(&mut self.app, t);
        let block = self.take_spent();
        self.busy_until = Micros(t.0 + block);
        Pass {
            tx_len: pass.tx_len,
            wake_at: wake.max(self.busy_until),
        }
    }
    fn tx(&self) -> &[u8] {
        self.pump.tx()
    }
    fn timeout(&self) -> Option<Micros> {
        self.app.link().poll_timeout()
    }
}

/// The PLC's tasks and the drive application on the co-simulation rig.
struct Rig {
    pair: Pair<PlcTask, Pumped<DriveApp>>,
    screen: Screen,
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
        let plc = PlcTask {
            app: PlcApp::new(eeprom, cfg, 20, 4, Micros(0)),
            pump: Pump::new(MAX_IDLE_US),
            busy_until: Micros(0),
            longest_block_us: 0,
            spent,
            clock,
            ring: Vec::new(),
            byte_us: 10_000_000u64.div_ceil(u64::from(cfg.baud)),
        };
        // Restarted by its watchdog: it reports fault WDG once the link is up.
        let drive = DriveApp::new(DriveConfig::default(), ResetCause::Watchdog, cfg);
        Rig {
            pair: Pair::with_line(
                plc,
                Pumped::new(drive, MAX_IDLE_US),
                Line::new(cfg.baud, Impairments::default(), 1),
            ),
            screen: Screen::new(20, 4),
        }
    }

    /// The line's events as they come; every 1 ms both applications' tasks, which then
    /// kick their link tasks.
    fn run_for(&mut self, us: u64) {
        let end = self.pair.now.0 + us;
        while self.pair.now.0 < end {
            let next = ((self.pair.now.0 / 1000 + 1) * 1000).min(end);
            self.pair.run_until(Micros(next), |_| {});
            let now = self.pair.now;
            if now.0.is_multiple_of(1000) {
                self.pair.drive.tick_1ms(now);
                self.pair.plc.tick_1ms(now, &mut self.screen);
            }
            self.pair.kick();
        }
    }
}

#[test]
fn a_slow_fault_log_write_does_not_hold_back_the_acknowledgement() {
    let mut r = Rig::new();
    r.run_for(1_000_000);
    let log: Vec<u8> = r.pair.plc.app.fault_log().iter().map(|e| e.code).collect();
    assert_eq!(log, [7], "WDG logged once");
    // The EEPROM work is done in steps: no single block comes near the drive's link
    // timeout (one page transfer, a few ms at 100 kHz), however long the whole job is.
    assert!(
        r.pair.plc.longest_block_us < LinkConfig::default().drive_timeout_us / 4,
        "block {} us",
        r.pair.plc.longest_block_us
    );
    assert_eq!(r.pair.plc.app.link().state(), PlcLinkState::Up);
    // The report is acknowledged in the session that carried it: no session is lost.
    assert!(
        r.pair.drive.link().stats().link_losses == 0,
        "{:?}",
        r.pair.drive.link().stats()
    );
}
