//! The panel on the full co-simulation: both MCUs, the UART link and the motor rig.
//!
//! The panel's keys and switches reach the PLC board through [`PanelPlc`], a thin
//! wrapper that the simulator sees as the PLC MCU: queued keypad keys are pressed one
//! after the other, each held for [`KEY_HOLD_MS`] and released for as long (the board's
//! keypad debouncing needs 10 stable samples), and the scan reads the panel's switches and pots instead of the
//! (empty) scenario's. Everything else is the unchanged board.

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;

use firmware_plc::editor::{Key, Screen};
use firmware_plc::storage::image::{program_image, ImageOptions};
use firmware_plc::storage::MemEeprom;
use shared_protocol::link::pump::Pass;
use shared_protocol::link::LinkConfig;
use shared_protocol::program::Program;
use shared_protocol::units::Micros;

use super::backend::{Backend, RigStatus};
use crate::mcu::{DriveBoard, DriveMcu, Lcd, PlcBoard, PlcMcu, PlcPins};
use crate::scenario::Scenario;
use crate::sim::{RunOptions, Sample, Simulation};

/// How long a panel key is held down, and then left up before the next one, in ms: the
/// keypad debouncing's 10 samples each way (`firmware_plc::app::KEY_DEBOUNCE_SAMPLES`),
/// so the same key typed twice counts twice; 20 ms per key.
pub const KEY_HOLD_MS: u32 = firmware_plc::app::KEY_DEBOUNCE_SAMPLES as u32;

/// The PLC board with the panel's keypad and I/O attached.
pub struct PanelPlc {
    inner: PlcBoard,
    keys: RefCell<VecDeque<char>>,
    /// The key being pressed and the ticks left in its press (down, then up).
    pressing: Option<(char, u32)>,
    digital: Cell<u8>,
    analog: Cell<[u16; 4]>,
}

impl PanelPlc {
    pub fn new(inner: PlcBoard) -> Self {
        PanelPlc {
            inner,
            keys: RefCell::new(VecDeque::new()),
            pressing: None,
            digital: Cell::new(0),
            analog: Cell::new([0; 4]),
        }
    }

    pub fn board(&self) -> &PlcBoard {
        &self.inner
    }

    fn pins(&self) -> PlcPins {
        PlcPins {
            digital: self.digital.get(),
            analog: self.analog.get(),
        }
    }
}

impl PlcMcu for PanelPlc {
    fn tick_1ms(&mut self, now: Micros) {
        // Down for KEY_HOLD_MS ticks (samples), then up for as many.
        if self.pressing.is_none() {
            if let Some(c) = self.keys.borrow_mut().pop_front() {
                self.inner.key(c, true, now);
                self.pressing = Some((c, 2 * KEY_HOLD_MS));
            }
        }
        if let Some((c, KEY_HOLD_MS)) = self.pressing {
            self.inner.key(c, false, now);
        }
        self.inner.tick_1ms(now);
        self.pressing = self
            .pressing
            .and_then(|(c, left)| (left > 1).then_some((c, left - 1)));
    }
    fn scan(&mut self, _scenario_pins: &PlcPins, now: Micros) {
        let pins = self.pins();
        self.inner.scan(&pins, now);
    }
    fn key(&mut self, key: char, down: bool, now: Micros) {
        self.inner.key(key, down, now);
    }
    fn link_pass(&mut self, rx: &[u8], tx_room: usize, now: Micros) -> Pass {
        self.inner.link_pass(rx, tx_room, now)
    }
    fn link_tx(&self) -> &[u8] {
        self.inner.link_tx()
    }
    fn link_timeout(&self) -> Option<Micros> {
        self.inner.link_timeout()
    }
    fn outputs(&self) -> u8 {
        self.inner.outputs()
    }
    fn q(&self, n: u8) -> i16 {
        self.inner.q(n)
    }
    fn lcd_fields(&self) -> [Option<i16>; 4] {
        self.inner.lcd_fields()
    }
    fn lcd(&self) -> &Lcd {
        self.inner.lcd()
    }
    fn running(&self) -> bool {
        self.inner.running()
    }
    fn warnings(&self) -> crate::mcu::Warnings {
        self.inner.warnings()
    }
}

/// The co-simulated rig behind the panel, in virtual time that the panel advances.
pub struct SimBackend {
    sim: Simulation<DriveBoard, PanelPlc>,
    last: Option<Sample>,
}

impl SimBackend {
    /// Power up the rig with `program` (if any) stored in slot 1 of the PLC's EEPROM and
    /// loaded at power-up, but not running: RUN is the user's `A`.
    pub fn new(program: Option<&Program>) -> anyhow::Result<Self> {
        let eeprom = match program {
            Some(p) => {
                let image = program_image(
                    p,
                    &ImageOptions {
                        slot: 1,
                        run_at_power_up: false,
                    },
                )
                .map_err(|e| anyhow::anyhow!("cannot store the program in the EEPROM: {e:?}"))?;
                MemEeprom::from_image(&image)
            }
            None => MemEeprom::new(),
        };
        Ok(Self::with_eeprom(eeprom))
    }

    /// Power up the rig with `eeprom` in the PLC's socket.
    pub fn with_eeprom(eeprom: MemEeprom) -> Self {
        let scenario = Scenario::default();
        let link = LinkConfig::at_baud(scenario.baud);
        let plc = PanelPlc::new(PlcBoard::new(eeprom, link, Micros(0)));
        let drive = DriveBoard::new(link);
        let opts = RunOptions {
            // The side panel needs a few values per frame, not every millisecond.
            sample_ns: 20_000_000,
            ..RunOptions::default()
        };
        SimBackend {
            sim: Simulation::with_boards(drive, plc, scenario, opts),
            last: None,
        }
    }

    pub fn simulation(&self) -> &Simulation<DriveBoard, PanelPlc> {
        &self.sim
    }
}

impl Backend for SimBackend {
    fn key(&mut self, key: Key) {
        self.sim.plc().keys.borrow_mut().push_back(key.to_char());
    }

    fn advance(&mut self, dt_ms: u32) {
        let end = self.sim.now_ns() + u64::from(dt_ms) * 1_000_000;
        let mut last = None;
        self.sim.run_until(end, |s| last = Some(s.clone()));
        if last.is_some() {
            self.last = last;
        }
    }

    fn lcd(&self) -> Screen {
        // The board's LCD with its cursor, refreshed every 100 ms and after each key.
        self.sim.plc().board().screen().clone()
    }

    fn status(&self) -> RigStatus {
        let d = self.sim.drive().status();
        let mut st = RigStatus {
            t_s: self.sim.now_ns() as f64 * 1e-9,
            simulated: true,
            plc_running: self.sim.plc().running(),
            drive_state: format!("{:?}", d.state).to_uppercase(),
            fault: d.fault.map_or(0, |f| f.code()),
            reverse: d.reverse,
            digital_in: self.sim.plc().digital.get(),
            digital_out: self.sim.plc().outputs(),
            analog: self.sim.plc().analog.get(),
            ..RigStatus::default()
        };
        if let Some(s) = &self.last {
            st.f_hz = s.f_cmd_hz;
            st.speed_rpm = s.speed_rpm;
            st.u_dc_v = s.u_dc_v;
            st.i_max_a = s.i_abc_a.iter().fold(0.0f64, |m, i| m.max(i.abs()));
            st.brake = s.brake;
        }
        st
    }

    fn set_digital(&mut self, n: u8, on: bool) {
        let plc = self.sim.plc();
        let d = plc.digital.get();
        if n < 8 {
            plc.digital
                .set(if on { d | (1 << n) } else { d & !(1 << n) });
        }
    }

    fn set_analog(&mut self, n: u8, counts: u16) {
        let plc = self.sim.plc();
        let mut a = plc.analog.get();
        if let Some(v) = a.get_mut(usize::from(n)) {
            *v = counts.min(1023);
        }
        plc.analog.set(a);
    }
}
