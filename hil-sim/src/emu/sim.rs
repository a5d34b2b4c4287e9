//! The co-simulation of the two real images: both emulated MCUs, joined by their USARTs
//! over a wire, with the drive's TIM1 driving hil-sim's plant and the plant feeding the
//! drive's ADC and comparators, in the same virtual time, under the same scenario and with
//! the same record as `hil-sim run`.
//!
//! Time advances in slices no longer than [`QUANTUM_NS`], shorter than one UART character
//! (86.8 µs at 115200 baud), so a character that starts on one side within a slice always
//! ends after it: each side can run its slice alone and the wire hands the character over
//! after the sender ran, before the receiver passes its end. A start bit also cancels the
//! receiver's idle-line detection when it falls inside the idle frame, so a receiver that
//! will detect an idle line inside a slice runs second, with the slice cut at that cycle;
//! otherwise the drive runs first. The plant is advanced inside the drive's run, at every
//! TIM1 event and ADC sample.
//!
//! The record observes each image directly, never through the other one: the drive's
//! outputs are its TIM1 (the gate state the board follows), its fault is what the drive
//! image itself logs (`drive: fault Link` latches code 5, leaving the `Fault` state clears
//! it) and its resets, faults and lockups; its frequency, direction and safety status are
//! decoded from the status frames at its own TX pin (so they stop changing when the image
//! stops sending, e.g. after a link timeout, while the fault column goes on). Q00-Q07 are
//! the values the PLC sent in its Q writes, the LCD fields are read off the LCD, and `m` is
//! derived from the three leg duties.
//!
//! The PLC's service port (LPUART1, PA2/PA3) has a host end ([`EmuSim::service_write`],
//! [`EmuSim::service_read`]): the host's bytes go onto PA3 back to back at the line rate
//! the image programmed, as the ST-LINK's USB bridge would send them, and what the image
//! sends on PA2 is collected for the host.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::path::Path;
use std::rc::Rc;

use anyhow::{Context, Result};
use g431_emu::boards::ExternalWire;
use g431_emu::cpu::{CpuEvent, CpuState};
use g431_emu::devices::eeprom_24c256::Eeprom24c256;
use g431_emu::devices::lcd_backpack::LcdBackpack;
use g431_emu::mcu::Mcu;
use g431_emu::periph::gpio::Mode;
use g431_emu::periph::rcc::ResetKind;
use g431_emu::periph::usart::{RxByte, UsartInstance};
use g431_emu::soc::{Soc, USARTS};
use g431_emu::time::{cycles_to_ns, ns_to_cycles};
use shared_protocol::fault::FaultCode;
use shared_protocol::link::channel::Noise;
use shared_protocol::link::message::{DriveMsg, DriveStatus, PlcMsg};
use shared_protocol::link::FrameReader;
use shared_protocol::program::Program;

use super::boards::{
    board_kind, drive_pins, image_board, pin_id, plc_pins, DriveBoard, PlcBoard, PlcIo, Rig,
};
use crate::mcu::SimLcd;
use crate::plant::Plant;
use crate::scenario::silicon::McuSide;
use crate::scenario::{Action, ImageTrouble, Input, Scenario};
use crate::sim::{FaultRecord, RunOptions, Sample};

/// Longest slice both MCUs run before the wire hands characters over.
pub const QUANTUM_NS: u64 = 50_000;

/// Fault-column codes for what happened to an image rather than to the drive core
/// (documented in `docs/emulator.md`): they never collide with drive.md's codes.
pub mod image_fault {
    /// The drive image took a HardFault (a panic ends there too).
    pub const HARD_FAULT: u8 = 90;
    /// The drive's core locked up.
    pub const LOCKUP: u8 = 91;
    /// The drive image was reset by its watchdog (until it reports again).
    pub const WATCHDOG: u8 = 92;
    /// BOOT0 was high at reset: the drive ran the ROM bootloader.
    pub const BOOT_ROM: u8 = 93;
}

/// One direction of the link: a UART wire with the scenario's bit errors and cut.
struct Wire {
    /// Characters handed over, and lost on the way (cut, or no USART on the far pin).
    delivered: u64,
    lost: u64,
    noise: Noise,
    ber: f64,
    /// The next this many characters arrive with a framing error (injected by a test).
    force_framing: u32,
    /// The next this many characters arrive with at least one data bit flipped.
    force_flip: u32,
    /// The frames on this wire, decoded for the record.
    reader: FrameReader,
}

impl Wire {
    fn new(seed: u64, ber: f64) -> Self {
        Wire {
            delivered: 0,
            lost: 0,
            noise: Noise::from_state(seed | 1),
            ber,
            force_framing: 0,
            force_flip: 0,
            reader: FrameReader::new(),
        }
    }

    /// The character as the receiver sees it: each of its 10 bits flips with the bit
    /// error rate; a flipped start or stop bit is a framing error.
    fn impair(&mut self, data: u16) -> RxByte {
        let mut b = RxByte::clean(data);
        if self.force_framing > 0 {
            self.force_framing -= 1;
            b.framing_error = true;
        }
        if self.force_flip > 0 {
            self.force_flip -= 1;
            // At least one bit, as the cores' `Channel::burst`.
            b.data ^= u16::from((self.noise.next_u64() as u8) | 1);
        }
        if self.ber <= 0.0 {
            return b;
        }
        for bit in 0..10 {
            if self.noise.chance(self.ber) {
                match bit {
                    0 | 9 => b.framing_error = true,
                    k => b.data ^= 1 << (k - 1),
                }
            }
        }
        b
    }
}

/// The USART whose `signal` ("TX"/"RX") is routed to pin `pin` by the GPIO configuration
/// (alternate function mode with that USART's AF number, per the STM32 metadata).
pub fn usart_on_pin(soc: &Soc, pin: &str, signal: &str) -> Option<UsartInstance> {
    let (port, n) = pin_id(pin)?;
    let g = soc.gpio(port)?;
    if g.mode(n) != Mode::Alternate {
        return None;
    }
    let af = g.af(n);
    USARTS.into_iter().find(|u| {
        g431_emu::names::peripheral(u.name()).is_some_and(|p| {
            p.pins
                .iter()
                .any(|pp| pp.pin == pin && pp.signal == signal && pp.af == Some(af))
        })
    })
}

/// Both images, the rig and the scenario.
pub struct EmuSim {
    now_ns: u64,
    drive: Mcu,
    plc: Mcu,
    rig: Rc<RefCell<Rig>>,
    io: Rc<RefCell<PlcIo>>,
    eeprom: Rc<RefCell<Eeprom24c256>>,
    lcd: Rc<RefCell<LcdBackpack>>,
    scenario: Scenario,
    next_action: usize,
    /// PLC → drive, drive → PLC.
    to_drive: Wire,
    to_plc: Wire,
    cut: bool,
    status: Option<DriveStatus>,
    q: [i16; 8],
    faults: Vec<FaultRecord>,
    last_fault: u8,
    /// The drive's fault latch as its own log and resets tell it.
    drive_latch: DriveLatch,
    next_sample_ns: u64,
    sample_ns: u64,
    service: ServiceHost,
    allowed: Vec<Allowance>,
}

/// A diagnostic a test lets pass ([`EmuSim::allow`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Allowance {
    /// Matched as a substring of `<image>: <diagnostic>`.
    pub pattern: String,
    /// Why it is not a failure: a model limit, or a finding in the image to be fixed.
    pub reason: String,
}

/// The [`ImageTrouble`] an image event is, if any (a power-on or pin reset is the host's
/// doing, not the image's).
pub fn trouble_of(e: &CpuEvent) -> Option<ImageTrouble> {
    Some(match e {
        CpuEvent::HardFault { .. } => ImageTrouble::HardFault,
        CpuEvent::Lockup { .. } => ImageTrouble::Lockup,
        CpuEvent::Reset {
            why: ResetKind::Watchdog,
            ..
        } => ImageTrouble::WatchdogReset,
        CpuEvent::Reset {
            why: ResetKind::Software,
            ..
        } => ImageTrouble::SoftwareReset,
        CpuEvent::Reset { .. } => return None,
        CpuEvent::BootRom { .. } => ImageTrouble::BootRom,
        CpuEvent::Unsupported { .. } => ImageTrouble::Unsupported,
    })
}

/// The host end of the PLC's service port.
#[derive(Default)]
struct ServiceHost {
    /// Bytes the host wrote, not yet on the wire.
    to_plc: VecDeque<u8>,
    /// When the wire to the PLC is free again (cycles): the end of the last character.
    free_at: u64,
    /// The end of the previous slice (cycles): bytes the host wrote since then start
    /// there at the earliest.
    slice_start: u64,
    /// Bytes the PLC sent, not yet read by the host.
    from_plc: Vec<u8>,
    /// Host bytes dropped: the PLC had no receiver on PA3.
    pub lost: u64,
    /// The next this many host characters arrive with a framing error.
    force_framing: u32,
}

impl EmuSim {
    /// The images at `drive_elf`/`plc_elf` with `program` in the PLC's EEPROM (slot 1, RUN
    /// at power-up unless the scenario types the RUN key), as `hil-sim run` sets it up.
    pub fn new(
        drive_elf: &Path,
        plc_elf: &Path,
        program: &Program,
        scenario: Scenario,
        opts: RunOptions,
    ) -> Result<Self> {
        if scenario.lift.is_some() {
            anyhow::bail!("the [lift] plant runs in `hil-sim run` and the panel, not the emulator");
        }
        let image = firmware_plc::storage::image::program_image(
            program,
            &firmware_plc::storage::image::ImageOptions {
                slot: 1,
                run_at_power_up: !scenario.keys_start_run,
            },
        )
        .map_err(|e| anyhow::anyhow!("cannot store the program in the EEPROM: {e:?}"))?;
        // The emulated board is the one the drive image was built for (its
        // `DRIVE_BOARD_PROFILE` marker), whatever the scenario's `[plant] board` says: an
        // image for the bare ESC1 reads its shunt amplifiers, one built with
        // `source-sensors` the source's sensors.
        let drive_image = g431_emu::elf::Image::load(drive_elf)
            .with_context(|| format!("drive image {}", drive_elf.display()))?;
        let mut scenario = scenario;
        let board = image_board(&drive_image).with_context(|| {
            format!(
                "drive image {} has no known DRIVE_BOARD_PROFILE marker",
                drive_elf.display()
            )
        })?;
        scenario.rig.board = board_kind(board).profile();
        let rig = Rc::new(RefCell::new(Rig::new(Plant::new(scenario.rig), board)));
        rig.borrow_mut().esc1_sense = scenario.esc1_amplifier_inputs;
        let mut drive = Mcu::new("drive", drive_image, Box::new(DriveBoard::new(rig.clone())))
            .with_context(|| format!("drive image {}", drive_elf.display()))?;
        // The drive MCU's analog errors (`[analog]`: the datasheet's typical part by default).
        drive.soc_mut().set_analog_errors(&scenario.analog.errors());
        let io = Rc::new(RefCell::new(PlcIo::default()));
        let mut plc = Mcu::load("plc", plc_elf, Box::new(PlcBoard::new(io.clone())))
            .with_context(|| format!("PLC image {}", plc_elf.display()))?;
        super::silicon::configure(&mut drive, scenario.silicon.drive_lsi_hz);
        super::silicon::configure(&mut plc, scenario.silicon.plc_lsi_hz);
        let eeprom = Rc::new(RefCell::new(Eeprom24c256::default()));
        eeprom
            .borrow_mut()
            .load(&image)
            .map_err(|e| anyhow::anyhow!("EEPROM image: {e}"))?;
        let lcd = Rc::new(RefCell::new(LcdBackpack::default()));
        // I2C3 (index 2) on PA8/PB5.
        plc.soc_mut()
            .attach_i2c(2, eeprom.clone(), plc_pins::I2C_SCL, plc_pins::I2C_SDA);
        plc.soc_mut()
            .attach_i2c(2, lcd.clone(), plc_pins::I2C_SCL, plc_pins::I2C_SDA);
        let seed = opts.seed;
        let mut sim = EmuSim {
            now_ns: 0,
            drive,
            plc,
            rig,
            io,
            eeprom,
            lcd,
            next_action: 0,
            to_drive: Wire::new(seed, scenario.bit_error_rate),
            to_plc: Wire::new(
                seed.wrapping_mul(31).wrapping_add(17),
                scenario.bit_error_rate,
            ),
            cut: false,
            status: None,
            q: [0; 8],
            faults: Vec::new(),
            last_fault: 0,
            drive_latch: DriveLatch::default(),
            next_sample_ns: 0,
            sample_ns: opts.sample_ns.max(1),
            service: ServiceHost::default(),
            allowed: Vec::new(),
            scenario,
        };
        // The STO wire is driven high (not requested) until a scenario sets it
        // (safety.md 11).
        sim.set_sto_wire(ExternalWire::DrivenHigh);
        Ok(sim)
    }

    /// The rig's STO wire: the level its net settles to (with the board's own driver on
    /// it, `Rig::sto_net`, and the image's pull on the pin) reaches the plant and TIM1's
    /// BKIN (PA15).
    pub fn set_sto_wire(&mut self, wire: ExternalWire) {
        let shdn = {
            let (p, n) = g431_emu::boards::b_g431b_esc1::CAN_SHDN;
            self.drive.soc().pin_drive(p, n)
        };
        let net = {
            let mut rig = self.rig.borrow_mut();
            rig.sto_wire = wire;
            rig.can_shdn = shdn;
            let net = rig.sto_net();
            if net.contention {
                rig.sto_contentions += 1;
            }
            net
        };
        let (p, n) = drive_pins::STO_IN;
        // A floating input without a pull is undefined: taken as high (STO not
        // requested), the reading that hides nothing from a test of the STO path.
        let high = self
            .drive
            .soc()
            .gpio(p)
            .and_then(|g| g.level(n, net.level))
            .unwrap_or(true);
        self.rig.borrow_mut().plant.set_sto_input(!high);
        let now = ns_to_cycles(self.now_ns);
        self.drive.soc_mut().set_tim1_bkin(high, now);
    }

    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    pub fn drive(&self) -> &Mcu {
        &self.drive
    }

    pub fn plc(&self) -> &Mcu {
        &self.plc
    }

    pub fn drive_mut(&mut self) -> &mut Mcu {
        &mut self.drive
    }

    pub fn plc_mut(&mut self) -> &mut Mcu {
        &mut self.plc
    }

    pub fn rig(&self) -> std::cell::Ref<'_, Rig> {
        self.rig.borrow()
    }

    pub fn rig_mut(&self) -> std::cell::RefMut<'_, Rig> {
        self.rig.borrow_mut()
    }

    pub fn eeprom(&self) -> std::cell::Ref<'_, Eeprom24c256> {
        self.eeprom.borrow()
    }

    pub fn lcd_device(&self) -> std::cell::Ref<'_, LcdBackpack> {
        self.lcd.borrow()
    }

    /// The LCD as the user sees it.
    pub fn lcd(&self) -> SimLcd {
        let mut l = SimLcd::default();
        for (r, text) in self.lcd.borrow().text().iter().enumerate() {
            l.set_row(r, text);
        }
        l
    }

    /// The drive's last status frame on the wire.
    pub fn status(&self) -> Option<DriveStatus> {
        self.status
    }

    /// Faults in the order they latched (from the status frames and the images' own
    /// resets and faults).
    pub fn faults(&self) -> &[FaultRecord] {
        &self.faults
    }

    /// Characters delivered and lost on (PLC → drive, drive → PLC).
    pub fn wire_counts(&self) -> [(u64, u64); 2] {
        [
            (self.to_drive.delivered, self.to_drive.lost),
            (self.to_plc.delivered, self.to_plc.lost),
        ]
    }

    /// The next `chars` characters from the PLC to the drive (`to_drive`) or back arrive
    /// with a framing error (a stop bit read low: noise on the line).
    pub fn inject_framing_errors(&mut self, to_drive: bool, chars: u32) {
        let wire = if to_drive {
            &mut self.to_drive
        } else {
            &mut self.to_plc
        };
        wire.force_framing = chars;
    }

    /// The next `chars` characters the host writes to the PLC's service port arrive with a
    /// framing error (a stop bit read low: a cable plugged in mid-character, noise).
    pub fn inject_service_framing_errors(&mut self, chars: u32) {
        self.service.force_framing = chars;
    }

    /// Bytes from the host to the PLC's service port: they go on the wire after what is
    /// queued, back to back at the line rate of the PLC's LPUART1.
    pub fn service_write(&mut self, bytes: &[u8]) {
        self.service.to_plc.extend(bytes);
    }

    /// What the PLC has sent on its service port since the last call.
    pub fn service_read(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.service.from_plc)
    }

    /// Host bytes lost because the PLC had no service receiver on PA3.
    pub fn service_lost(&self) -> u64 {
        self.service.lost
    }

    /// Both wires of the link flip each bit with `rate` from now on (the scenario's
    /// `bit_error_rate` at the start).
    pub fn set_link_bit_error_rate(&mut self, rate: f64) {
        self.to_drive.ber = rate;
        self.to_plc.ber = rate;
    }

    /// The next `chars` characters on one wire (to the drive, or back) each get at least
    /// one data bit flipped (a burst of noise, as the cores' `Channel::burst`).
    pub fn link_burst(&mut self, to_drive: bool, chars: u32) {
        let wire = if to_drive {
            &mut self.to_drive
        } else {
            &mut self.to_plc
        };
        wire.force_flip = chars;
    }

    /// Switches the drive board off and on again: the MCU restarts from power-on (TIM1
    /// and every peripheral to reset, the outputs open).
    pub fn power_cycle_drive(&mut self) {
        self.drive
            .cpu_mut()
            .reset(g431_emu::periph::rcc::ResetKind::PowerOn);
    }

    /// Cuts (or reconnects) both wires of the link.
    pub fn set_cut(&mut self, cut: bool) {
        self.cut = cut;
    }

    /// Switches the PLC board off and on again: the MCU restarts from power-on, the EEPROM
    /// loses a write cycle in progress, the LCD starts uninitialised.
    pub fn power_cycle_plc(&mut self) {
        let now = self.plc.now();
        self.eeprom.borrow_mut().power_cut(now);
        self.lcd.borrow_mut().power_on(now);
        self.plc
            .cpu_mut()
            .reset(g431_emu::periph::rcc::ResetKind::PowerOn);
    }

    /// Holds a keypad key down (or releases it).
    pub fn set_key(&mut self, key: char, down: bool) {
        let mut io = self.io.borrow_mut();
        if down {
            io.keys_down.insert(key);
        } else {
            io.keys_down.remove(&key);
        }
    }

    /// Runs until `end_ns`, calling `on_sample` at every sample time.
    pub fn run_until(&mut self, end_ns: u64, mut on_sample: impl FnMut(&Sample)) {
        while self.now_ns < end_ns {
            let mut t = (self.now_ns + QUANTUM_NS).min(end_ns);
            t = t.min(self.next_sample_ns.max(self.now_ns + 1));
            if let Some(a) = self.scenario.actions.get(self.next_action) {
                t = t.min(a.at_ns.max(self.now_ns + 1));
            }
            if !self.cut {
                t = t.min(self.scenario.cut_at_ns.max(self.now_ns + 1));
            }
            // Each side runs its slice alone; a character that starts in it reaches the
            // other side only after the sender ran. A receiver that will detect an idle
            // line inside the slice runs second, with the slice cut at that cycle, and
            // gets the sender's characters first: a start bit inside its idle frame then
            // cancels the detection, as on the line (RM0440 USART "IDLE").
            let (t, plc_first) = self.slice_order(t);
            let until = ns_to_cycles(t);
            let cut = self.cut || t >= self.scenario.cut_at_ns;
            if plc_first {
                self.plc.run_until(until);
                self.plc_to_drive(cut);
                self.drive.run_until(until);
            } else {
                self.drive.run_until(until);
                self.drive_to_plc(cut);
                self.plc.run_until(until);
            }
            self.rig.borrow_mut().advance_to(t);
            self.now_ns = t;
            self.exchange();
            self.apply_actions();
            self.track_faults();
            if t >= self.next_sample_ns {
                let s = self.sample(t);
                on_sample(&s);
                self.next_sample_ns += self.sample_ns;
            }
        }
    }

    /// The slice's end (`t`, or earlier) and whether the PLC runs first in it: the side
    /// whose link receiver has the first idle-line deadline before `t` runs second, and
    /// the slice ends at that deadline.
    fn slice_order(&mut self, t: u64) -> (u64, bool) {
        let now = ns_to_cycles(self.now_ns);
        let until = ns_to_cycles(t);
        let deadline = |m: &mut Mcu, pin| {
            usart_on_pin(m.soc(), pin, "RX")
                .and_then(|rx| m.soc_mut().usart_mut(rx).and_then(|u| u.idle_deadline()))
                .filter(|&d| d > now && d <= until)
        };
        let drive = deadline(&mut self.drive, drive_pins::LINK_RX);
        let plc = deadline(&mut self.plc, plc_pins::LINK_RX);
        // The first nanosecond whose first cycle is at or after the deadline.
        let end_at = |d: u64| (cycles_to_ns(d) + 1).min(t);
        match (drive, plc) {
            (Some(d), Some(p)) if p < d => (end_at(p), false),
            (Some(d), _) => (end_at(d), true),
            (None, Some(p)) => (end_at(p), false),
            (None, None) => (t, false),
        }
    }

    /// The PLC's link characters that started so far, to the drive.
    fn plc_to_drive(&mut self, cut: bool) {
        move_chars(
            &mut self.plc,
            plc_pins::LINK_TX,
            &mut self.drive,
            drive_pins::LINK_RX,
            &mut self.to_drive,
            cut,
            &mut |_m: PlcMsg| {},
            &mut self.q,
        );
    }

    /// The drive's link characters that started so far, to the PLC (decoding its status).
    fn drive_to_plc(&mut self, cut: bool) {
        let mut status = self.status;
        move_drive_chars(
            &mut self.drive,
            &mut self.plc,
            &mut self.to_plc,
            cut,
            &mut status,
        );
        self.status = status;
    }

    /// Hands the characters each side started sending in this slice (and not yet handed
    /// over) to the other side.
    fn exchange(&mut self) {
        let cut = self.cut || self.now_ns >= self.scenario.cut_at_ns;
        if cut && !self.cut {
            self.cut = true;
        }
        self.plc_to_drive(cut);
        self.drive_to_plc(cut);
        self.exchange_service();
    }

    /// The service port: the PLC's characters to the host, and the host's characters
    /// that start in this slice to the PLC (each pushed at its start with the cycle its
    /// stop bit ends, as the model wants).
    fn exchange_service(&mut self) {
        if let Some(tx) = usart_on_pin(self.plc.soc(), plc_pins::SERVICE_TX, "TX") {
            while let Some(f) = self.plc.soc_mut().usart_mut(tx).and_then(|u| u.take_tx()) {
                self.service.from_plc.push(f.data as u8);
            }
        }
        let now = ns_to_cycles(self.now_ns);
        let slice_start = std::mem::replace(&mut self.service.slice_start, now);
        if self.service.to_plc.is_empty() {
            return;
        }
        let Some(rx) = usart_on_pin(self.plc.soc(), plc_pins::SERVICE_RX, "RX") else {
            self.service.lost += self.service.to_plc.len() as u64;
            self.service.to_plc.clear();
            return;
        };
        let frame = self
            .plc
            .soc_mut()
            .usart_mut(rx)
            .and_then(|u| u.line_config())
            .map(|c| c.frame_cycles());
        let Some(frame) = frame else {
            self.service.lost += self.service.to_plc.len() as u64;
            self.service.to_plc.clear();
            return;
        };
        // Characters start back to back, the first when the previous one ended or when
        // the host wrote it (in this slice), whichever is later.
        let mut start = self.service.free_at.max(slice_start);
        while start <= now {
            let Some(b) = self.service.to_plc.pop_front() else {
                break;
            };
            let end = start + frame;
            let mut byte = RxByte::clean(u16::from(b));
            if self.service.force_framing > 0 {
                self.service.force_framing -= 1;
                byte.framing_error = true;
            }
            if let Some(u) = self.plc.soc_mut().usart_mut(rx) {
                u.push_rx(end, byte);
            }
            self.service.free_at = end;
            start = end;
        }
        self.plc.soc_mut().refresh_usart(rx);
    }

    fn apply_actions(&mut self) {
        while let Some(a) = self.scenario.actions.get(self.next_action) {
            if a.at_ns > self.now_ns {
                break;
            }
            let action = a.action.clone();
            self.next_action += 1;
            match action {
                Action::Set(Input::Digital(n), v) => {
                    let mut io = self.io.borrow_mut();
                    if v != 0 {
                        io.digital_in |= 1 << n;
                    } else {
                        io.digital_in &= !(1 << n);
                    }
                }
                Action::Set(Input::Analog(n), v) => {
                    if let Some(a) = self.io.borrow_mut().analog.get_mut(usize::from(n)) {
                        *a = v;
                    }
                }
                Action::Set(Input::Aux, v) => self.rig.borrow_mut().aux_counts = (v << 2).min(4095),
                // STO_IN = 0: the STO source pulls the wire to 0 V.
                Action::Set(Input::StoIn, v) => self.set_sto_wire(if v == 0 {
                    ExternalWire::DrivenLow
                } else {
                    ExternalWire::DrivenHigh
                }),
                Action::KeyDown(k) => self.set_key(k, true),
                Action::KeyUp(k) => self.set_key(k, false),
                Action::Plant(c) => c.apply(self.rig.borrow_mut().plant.params_mut()),
                // Refused in `new`: the lift is the host simulation's.
                Action::Lift(_) => {}
                Action::Silicon(side, ev) => {
                    let mcu = match side {
                        McuSide::Drive => &mut self.drive,
                        McuSide::Plc => &mut self.plc,
                    };
                    super::silicon::apply(mcu, ev);
                }
            }
        }
    }

    /// The image's own troubles go into the fault record too.
    fn image_fault(&self) -> Option<u8> {
        match self.drive.state() {
            CpuState::Lockup => return Some(image_fault::LOCKUP),
            CpuState::BootRom => return Some(image_fault::BOOT_ROM),
            _ => {}
        }
        if self.drive.soc().ipsr == 3 {
            return Some(image_fault::HARD_FAULT);
        }
        None
    }

    /// The drive's fault as the image itself has it now (see the module's docs).
    fn drive_fault(&self) -> u8 {
        self.image_fault().unwrap_or(self.drive_latch.code)
    }

    fn track_faults(&mut self) {
        let image = self.image_fault();
        let mut changes = self.drive_latch.update(&self.drive);
        changes.push((self.now_ns, self.drive_latch.code));
        for (t_ns, code) in changes {
            let f = image.unwrap_or(code);
            if f != 0 && f != self.last_fault {
                self.faults.push(FaultRecord { t_ns, code: f });
            }
            self.last_fault = f;
        }
    }

    /// One row of the record.
    fn sample(&self, t: u64) -> Sample {
        let rig = self.rig.borrow();
        let o = rig.plant.outputs();
        let st = self.status.unwrap_or_default();
        let duties = rig.duties();
        let m = modulation_index(&duties);
        let io = self.io.borrow();
        Sample {
            t_ns: t,
            f_cmd_hz: f64::from(st.freq_dhz) / 10.0,
            dir: if st.reverse { -1 } else { 1 },
            m,
            pwm_on: duties.iter().any(Option::is_some) && !o.hw_break,
            fault: self.drive_fault(),
            u_dc_v: o.u_dc_v,
            i_abc_a: o.i_abc_a,
            speed_rpm: o.speed_rad_s * 60.0 / (2.0 * std::f64::consts::PI),
            torque_nm: o.torque_nm,
            brake: o.brake_on,
            digital_in: io.digital_in,
            digital_out: io.outputs,
            q: self.q,
            lcd: lcd_fields(&self.lcd.borrow().text()),
            duty_abc: o.duty_abc,
            u_ab_v: o.u_ab_v,
            // The drive's warning is in its status; the PLC's own (DIV0) is not on the
            // wire and is not recorded by `emu`.
            warn: crate::mcu::Warnings {
                plc: None,
                drive: st.warning,
            },
            // From the drive's status on the wire; the turns are the drive core's own
            // (not on the wire): `emu` records 0.
            sf_req: st.sf_requested,
            sf_st: st.sf_status,
            sdc: st.sf_sdc,
            sft_ds: st.sf_elapsed_ds,
            turns_e4: 0,
            sf_turns: st.sf_turns,
            lift: None,
        }
    }

    /// The image events of both MCUs, with their names.
    pub fn cpu_events(&self) -> Vec<(String, CpuEvent)> {
        let mut v: Vec<(String, CpuEvent)> = Vec::new();
        for m in [&self.drive, &self.plc] {
            for e in m.events() {
                v.push((m.name.clone(), e.clone()));
            }
        }
        v
    }

    /// Lets the emulator diagnostics containing `pattern` pass [`EmuSim::problems`]: the
    /// pattern is matched against `<image>: <diagnostic>` (`"plc: input PA2 read while
    /// floating"`, or a register name such as `"TIM4.CCMR[1]"` for either image). `reason`
    /// says why it is not a failure; an allowance that matches nothing is a problem too,
    /// so that a list never outlives what it excuses.
    ///
    /// # Panics
    /// If `reason` is empty.
    pub fn allow(&mut self, pattern: &str, reason: &str) -> &mut Self {
        assert!(
            !pattern.trim().is_empty() && !reason.trim().is_empty(),
            "allow(\"{pattern}\", ...) needs a pattern and a reason"
        );
        self.allowed.push(Allowance {
            pattern: pattern.to_string(),
            reason: reason.to_string(),
        });
        self
    }

    /// Both images' emulator diagnostics so far, as `<image>: <diagnostic>`.
    pub fn diagnostics(&self) -> Vec<String> {
        let mut v = Vec::new();
        for m in [&self.drive, &self.plc] {
            for d in m.diagnostics() {
                v.push(format!("{}: {d}", m.name));
            }
        }
        v
    }

    /// The image events that are an [`ImageTrouble`], with the image's name, whether the
    /// scenario expects them (`[emu] expect`) and a line of text.
    pub fn image_troubles(&self) -> Vec<(String, ImageTrouble, bool, String)> {
        let mut v = Vec::new();
        for (name, e) in self.cpu_events() {
            if let Some(t) = trouble_of(&e) {
                let expected = self.scenario.expected_trouble.contains(&t);
                v.push((name, t, expected, super::run::event_text(&e)));
            }
        }
        v
    }

    /// Image troubles the scenario does not expect, as lines of text.
    pub fn unexpected_troubles(&self) -> Vec<String> {
        self.image_troubles()
            .into_iter()
            .filter(|(_, _, expected, _)| !expected)
            .map(|(name, t, _, text)| {
                format!(
                    "{name}: {text} (add \"{}\" to the scenario's [emu] expect if it is on purpose)",
                    t.key()
                )
            })
            .collect()
    }

    /// The scenario provokes `t` on purpose (`[emu] expect`).
    pub fn expects(&self, t: ImageTrouble) -> bool {
        self.scenario.expected_trouble.contains(&t)
    }

    /// Everything that must fail an emulator test: image troubles the scenario does not
    /// expect, diagnostics no [`EmuSim::allow`] covers, and allowances that matched nothing.
    pub fn problems(&self) -> Vec<String> {
        let diags = self.diagnostics();
        let mut v = self.unexpected_troubles();
        for d in &diags {
            if !self.allowed.iter().any(|a| d.contains(&a.pattern)) {
                v.push(format!(
                    "{d} (allow it by name with a reason, `sim.allow(\"{d}\", \"why\")`, only if it is not a defect)"
                ));
            }
        }
        for a in &self.allowed {
            if !diags.iter().any(|d| d.contains(&a.pattern)) {
                v.push(format!(
                    "allowance \"{}\" ({}) matched no diagnostic: remove it",
                    a.pattern, a.reason
                ));
            }
        }
        v
    }

    /// Simulated time in ns of cycle `c`.
    pub fn ns(c: u64) -> u64 {
        cycles_to_ns(c)
    }
}

/// The drive's fault latch, read from the drive image's own defmt log and resets (the
/// lines `drive-image/src/board/control.rs` writes for the core's events).
#[derive(Debug, Default)]
struct DriveLatch {
    /// The latched code (0: none; [`image_fault::WATCHDOG`] after a watchdog reset until
    /// the restarted image reports its own fault).
    code: u8,
    log_seen: usize,
    events_seen: usize,
}

impl DriveLatch {
    /// Reads what the image logged and did since the last call; returns the latch's
    /// changes in time order as (ns, code).
    fn update(&mut self, drive: &Mcu) -> Vec<(u64, u8)> {
        // (cycle, order, new code): resets before log lines of the same cycle.
        let mut steps: Vec<(u64, u8, u8)> = Vec::new();
        for e in drive.events().get(self.events_seen..).unwrap_or(&[]) {
            if let CpuEvent::Reset { at, why } = e {
                let code = match why {
                    ResetKind::Watchdog => image_fault::WATCHDOG,
                    _ => 0,
                };
                steps.push((*at, 0, code));
            }
        }
        self.events_seen = drive.events().len();
        for l in drive.log_since(self.log_seen) {
            if let Some(code) = logged_fault(&l.message) {
                steps.push((l.at, 1, code));
            } else if l.message.starts_with("drive: State { from: Fault,") {
                steps.push((l.at, 1, 0));
            }
        }
        self.log_seen = drive.log().len();
        steps.sort_by_key(|&(at, order, _)| (at, order));
        let mut changes = Vec::new();
        for (at, _, code) in steps {
            if code != self.code {
                self.code = code;
                changes.push((cycles_to_ns(at), code));
            }
        }
        changes
    }
}

/// The fault code of a `drive: fault <Name>` log line (the core's `FaultCode` as defmt
/// prints it).
pub fn logged_fault(message: &str) -> Option<u8> {
    let name = message.strip_prefix("drive: fault ")?.trim();
    (1..=u8::MAX).find_map(|c| {
        let f = FaultCode::try_from(c).ok()?;
        (format!("{f:?}") == name).then_some(c)
    })
}

/// Moves the PLC's transmitted characters to the drive, decoding them for the record.
#[allow(clippy::too_many_arguments)]
fn move_chars(
    from: &mut Mcu,
    from_pin: &str,
    to: &mut Mcu,
    to_pin: &str,
    wire: &mut Wire,
    cut: bool,
    _on_msg: &mut dyn FnMut(PlcMsg),
    q: &mut [i16; 8],
) {
    let Some(tx) = usart_on_pin(from.soc(), from_pin, "TX") else {
        return;
    };
    let rx = usart_on_pin(to.soc(), to_pin, "RX");
    while let Some(f) = from.soc_mut().usart_mut(tx).and_then(|u| u.take_tx()) {
        if let Some(Ok(frame)) = wire.reader.push::<PlcMsg>(f.data as u8) {
            if let PlcMsg::QWrite(values) = frame.msg {
                for v in values {
                    if let Some(slot) = q.get_mut(usize::from(v.addr)) {
                        *slot = v.value;
                    }
                }
            }
        }
        deliver(to, rx, f.end, f.data, wire, cut);
    }
    if let Some(rx) = rx {
        to.soc_mut().refresh_usart(rx);
    }
}

/// Moves the drive's characters to the PLC, decoding its status frames.
fn move_drive_chars(
    from: &mut Mcu,
    to: &mut Mcu,
    wire: &mut Wire,
    cut: bool,
    status: &mut Option<DriveStatus>,
) {
    let Some(tx) = usart_on_pin(from.soc(), drive_pins::LINK_TX, "TX") else {
        return;
    };
    let rx = usart_on_pin(to.soc(), plc_pins::LINK_RX, "RX");
    while let Some(f) = from.soc_mut().usart_mut(tx).and_then(|u| u.take_tx()) {
        if let Some(Ok(frame)) = wire.reader.push::<DriveMsg>(f.data as u8) {
            if let DriveMsg::Status(s) = frame.msg {
                *status = Some(s);
            }
        }
        deliver(to, rx, f.end, f.data, wire, cut);
    }
    if let Some(rx) = rx {
        to.soc_mut().refresh_usart(rx);
    }
}

fn deliver(
    to: &mut Mcu,
    rx: Option<UsartInstance>,
    end: u64,
    data: u16,
    wire: &mut Wire,
    cut: bool,
) {
    let Some(rx) = rx.filter(|_| !cut) else {
        wire.lost += 1;
        return;
    };
    let byte = wire.impair(data);
    if let Some(u) = to.soc_mut().usart_mut(rx) {
        u.push_rx(end, byte);
        wire.delivered += 1;
    }
}

/// The modulation index from three leg duties: for d_k = c + (m/2)·sin(θ + φ_k) the
/// deviations from their mean have Σ(d_k − mean)² = 3/2·(m/2)² (exact in the linear range;
/// an estimate when the duties clip).
pub fn modulation_index(duties: &[Option<f64>; 3]) -> f64 {
    let d: Vec<f64> = duties.iter().flatten().copied().collect();
    if d.len() != 3 {
        return 0.0;
    }
    let mean = d.iter().sum::<f64>() / 3.0;
    let ss: f64 = d.iter().map(|x| (x - mean).powi(2)).sum();
    2.0 * (ss * 2.0 / 3.0).sqrt()
}

/// The 4 `LCD` value fields read off the run screen ("1:   500   2:  9800"), if shown.
pub fn lcd_fields(rows: &[String; 4]) -> [Option<i16>; 4] {
    let mut out = [None; 4];
    for row in rows.iter().skip(1).take(2) {
        let mut rest = row.as_str();
        while let Some(colon) = rest.find(':') {
            let label = rest[..colon].trim_end().chars().last();
            let after = &rest[colon + 1..];
            let value: String = after
                .trim_start()
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '-')
                .collect();
            if let (Some(d), Ok(v)) = (label.and_then(|c| c.to_digit(10)), value.parse()) {
                if (1..=4).contains(&d) {
                    out[(d - 1) as usize] = Some(v);
                }
            }
            rest = after;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modulation_index_of_balanced_duties() {
        let m: f64 = 0.8;
        let th: f64 = 0.3;
        let duties = [0.0, 2.0, 4.0]
            .map(|k: f64| Some(0.5 + 0.5 * m * (th + k * std::f64::consts::PI / 3.0).sin()));
        assert!((modulation_index(&duties) - m).abs() < 1e-9);
        assert_eq!(modulation_index(&[None, Some(0.5), Some(0.5)]), 0.0);
    }

    #[test]
    fn faults_are_read_off_the_drive_log() {
        assert_eq!(logged_fault("drive: fault Link"), Some(5));
        assert_eq!(logged_fault("drive: fault OcHw"), Some(2));
        assert_eq!(logged_fault("drive: fault Sla"), Some(16));
        assert_eq!(logged_fault("drive: fault Nonsense"), None);
        assert_eq!(logged_fault("link: fault Link"), None);
    }

    #[test]
    fn lcd_fields_are_read_off_the_run_screen() {
        let rows = [
            "RUN  LINK OK  RUN".to_string(),
            "1:   500   2:  9800".to_string(),
            "3:    -7   4:      ".to_string(),
            String::new(),
        ];
        assert_eq!(lcd_fields(&rows), [Some(500), Some(9800), Some(-7), None]);
    }
}
