//! The panel on the full co-simulation: both MCUs, the UART link and the motor rig.
//!
//! The panel's keys and switches reach the simulator's PLC board ([`crate::mcu::SimPlc`],
//! the firmware's `PlcApp` as the board runs it) the way a scenario's do: keypad keys
//! queue and are pressed one after the other, each held for [`KEY_HOLD_MS`] and released
//! for as long (the keypad debouncing needs 10 stable samples each way), and the
//! switches and pots are the PLC's input pins. No key handling of its own.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};

use firmware_plc::editor::{Key, Screen};
use firmware_plc::storage::image::{program_image, ImageOptions};
use firmware_plc::storage::MemEeprom;
use shared_protocol::link::LinkConfig;
use shared_protocol::program::{Program, DIGITAL_INPUTS};
use shared_protocol::units::Micros;

use crate::mcu::{PlcPins, SimDrive, SimPlc};
use crate::plant::{SenseSpike, UdcSenseSpike};
use crate::scenario::Scenario;
use crate::sim::{RunOptions, Sample, Simulation};
use firmware_drive::ResetCause;

use super::files::{read_eeprom_image, write_atomically};
use super::rms::RmsWindow;

/// How long a panel key is held down, and then left up before the next one, in ms: the
/// keypad debouncing's 10 samples each way (`firmware_plc::app::KEY_DEBOUNCE_SAMPLES`),
/// so the same key typed twice counts twice; 20 ms per key.
pub const KEY_HOLD_MS: u32 = firmware_plc::app::KEY_DEBOUNCE_SAMPLES as u32;

const MS_NS: u64 = 1_000_000;

/// The rig's state for the side panel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RigStatus {
    /// Simulated time, s.
    pub t_s: f64,
    pub plc_running: bool,
    pub drive_state: String,
    pub f_hz: f64,
    pub reverse: bool,
    pub speed_rpm: f64,
    pub u_dc_v: f64,
    pub i_max_a: f64,
    /// RMS phase current over whole periods ([`super::rms::RmsWindow`]), A.
    pub i_rms_a: f64,
    /// The drive section's frequency command (what the ramp heads for), Hz.
    pub f_set_hz: f64,
    /// Electromagnetic torque, N m.
    pub torque_nm: f64,
    /// The inverter outputs switch (enabled and no hardware break).
    pub pwm_on: bool,
    /// The rig's settings the panel changes: supply voltage, load torque, locked rotor,
    /// UART wires cut, phase-1 sensor offset (counts), next download garbled.
    pub supply_v: f64,
    pub load_nm: f64,
    pub locked_rotor: bool,
    pub link_cut: bool,
    pub sensor_offset: i16,
    pub garble_download: bool,
    /// The drive's limits in effect: `U<`, `U>`, `I>` (0 = off) and `U>>`, `I>>`.
    pub limits: Limits,
    pub fault: u8,
    pub brake: bool,
    /// D00..D15, bit n = Dn.
    pub digital_in: u16,
    /// O00..O07, bit n = On.
    pub digital_out: u8,
    /// A00..A03, 10-bit counts.
    pub analog: [u16; 4],
    /// The lift (`--lift`): car position, door, brake, vanes.
    pub lift: Option<crate::plant::lift::LiftSample>,
}

/// The drive's protection limits in effect (for the rig box: what a trip needs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Limits {
    pub u_min_v: f64,
    pub u_max_v: f64,
    pub i_max_a: f64,
    pub ov_hw_v: f64,
    pub oc_hw_a: f64,
}

/// The sensor offset the panel's sensor fault adds to phase 1's current, ADC counts: beyond
/// the drive's boot self-test tolerance on every board (the bare ESC1's is +-410 counts,
/// `firmware_drive::measure::ESC1_SCALING`).
pub const SENSOR_FAULT_COUNTS: i16 = 600;

/// The co-simulated rig behind the panel, in virtual time that the panel advances.
pub struct SimBackend {
    /// Boxed: ~90 KiB, and panels are built and moved on test threads with 2 MiB stacks.
    sim: Box<Simulation>,
    last: Option<Sample>,
    /// Keypad keys not yet pressed.
    keys: VecDeque<char>,
    /// The key being pressed and the milliseconds left in its press (down, then up).
    pressing: Option<(char, u32)>,
    pins: PlcPins,
    rms: RmsWindow,
    link_cut: bool,
    /// The file behind the EEPROM (`--eeprom`), and its write count when last written.
    eeprom_file: Option<PathBuf>,
    persisted_writes: u32,
    /// A hash of the program slots at power-up: without a file, quitting loses any
    /// save made since ([`SimBackend::saved_slots_would_be_lost`]).
    slots_at_start: u64,
    /// The last failure to write the EEPROM file (shown on the panel; retried).
    pub persist_error: Option<String>,
    /// The PLC's service port on a pty (`panel --service-pty`).
    service: Option<crate::service::Attached>,
}

/// The image of a fresh EEPROM with `program` (if any) in slot 1, loaded at power-up but
/// not run.
fn fresh_image(program: Option<&Program>) -> anyhow::Result<MemEeprom> {
    Ok(match program {
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
    })
}

impl SimBackend {
    /// Power up the rig with `program` (if any) stored in slot 1 of the PLC's EEPROM and
    /// loaded at power-up, but not running: RUN is the user's `A`.
    pub fn new(program: Option<&Program>) -> anyhow::Result<Self> {
        Ok(Self::with_eeprom(fresh_image(program)?))
    }

    /// Power up the rig with the EEPROM kept in `path` (`--eeprom`): the saved slots of
    /// earlier sessions, and every completed save written back to the file.
    ///
    /// * No such file: it is created, holding `program` in slot 1 (as [`Self::new`]).
    /// * The file exists: the PLC powers up from it (the boot record's slot, run if it
    ///   was running); then `program`, if given and different, replaces the program in
    ///   RAM as an unsaved program (no slot is overwritten). Not while the PLC runs at
    ///   power-up: the returned note says so.
    /// * A file that is not a 32 KiB image is refused and left unchanged.
    ///
    /// With `lift`, the lift of lift.md 4 is on the shaft ([`Self::with_lift`]).
    pub fn with_eeprom_file(
        program: Option<&Program>,
        path: &Path,
        lift: bool,
    ) -> anyhow::Result<(Self, Option<String>)> {
        let existing = read_eeprom_image(path)?;
        let created = existing.is_none();
        let eeprom = match &existing {
            Some(bytes) => MemEeprom::from_image(bytes),
            None => fresh_image(program)?,
        };
        let mut b = if lift {
            Self::with_lift(eeprom)
        } else {
            Self::with_eeprom(eeprom)
        };
        b.eeprom_file = Some(path.to_path_buf());
        let mut note = None;
        if created {
            b.write_eeprom_file()?;
            note = Some(format!("created {}", path.display()));
        } else if let Some(p) = program {
            let app = b.sim.plc_mut().app_mut();
            if app.program() != p {
                note = Some(if app.replace_program(p) {
                    format!(
                        "{}: slots kept; the program file is in RAM, unsaved (C n saves it)",
                        path.display()
                    )
                } else {
                    format!(
                        "{}: the PLC runs its saved program at power-up; the program file \
                         was not loaded",
                        path.display()
                    )
                });
            }
        }
        // The power-up wrote the boot record (power-cycle count): the file has it too.
        b.persist();
        if let Some(e) = b.persist_error.take() {
            anyhow::bail!(e);
        }
        Ok((b, note))
    }

    /// Power up the rig with `eeprom` in the PLC's socket.
    pub fn with_eeprom(eeprom: MemEeprom) -> Self {
        Self::with_scenario(eeprom, Scenario::default())
    }

    /// [`Self::new`] with the lift on the shaft ([`Self::with_lift`]).
    pub fn new_lift(program: Option<&Program>) -> anyhow::Result<Self> {
        Ok(Self::with_lift(fresh_image(program)?))
    }

    /// Power up the rig with `eeprom` and the lift of lift.md 4 on the shaft (default
    /// `[lift]` keys): `lift.plc` runs it; the car and hall buttons are D00-D09 (the
    /// digital keys, `` ` `` for D08/D09).
    pub fn with_lift(eeprom: MemEeprom) -> Self {
        Self::with_scenario(
            eeprom,
            Scenario {
                lift: Some(crate::plant::lift::LiftParams::default()),
                ..Scenario::default()
            },
        )
    }

    fn with_scenario(eeprom: MemEeprom, scenario: Scenario) -> Self {
        let link = LinkConfig::at_baud(scenario.baud);
        let plc = SimPlc::new(eeprom, link, Micros(0));
        // The drive core configured for the rig's board (as `run`): the plant's sensors
        // and the core's scaling must be the same board's.
        let drive = SimDrive::with_config(link, crate::sim::drive_config(&scenario.rig));
        let opts = RunOptions {
            // The RMS current needs a few samples per period of the output (70 Hz at
            // most): 2 kHz.
            sample_ns: 500_000,
            ..RunOptions::default()
        };
        let mut b = SimBackend {
            sim: Box::new(Simulation::with_boards(drive, plc, scenario, opts)),
            last: None,
            keys: VecDeque::new(),
            pressing: None,
            pins: PlcPins::default(),
            rms: RmsWindow::default(),
            link_cut: false,
            eeprom_file: None,
            persisted_writes: 0,
            slots_at_start: 0,
            persist_error: None,
            service: None,
        };
        b.slots_at_start = b.slots_hash();
        b
    }

    /// A hash of the EEPROM's program slots (both copies of every slot).
    fn slots_hash(&mut self) -> u64 {
        use firmware_plc::storage::layout::{copy_addr, COPIES, COPY_BYTES, SLOTS};
        use std::hash::{Hash, Hasher};
        let first = copy_addr(1, 0).map_or(0, usize::from);
        let end = copy_addr(SLOTS, COPIES - 1).map_or(0, |a| usize::from(a) + COPY_BYTES);
        let image = self.sim.plc_mut().app_mut().storage().eeprom().image();
        let mut h = std::collections::hash_map::DefaultHasher::new();
        image.get(first..end).hash(&mut h);
        h.finish()
    }

    /// A program was saved to a slot in this session and no `--eeprom` file keeps it:
    /// quitting loses it (the panel asks first).
    pub fn saved_slots_would_be_lost(&mut self) -> bool {
        self.eeprom_file.is_none() && self.slots_hash() != self.slots_at_start
    }

    /// The file behind the EEPROM, if any.
    pub fn eeprom_file(&self) -> Option<&Path> {
        self.eeprom_file.as_deref()
    }

    fn eeprom_writes(&mut self) -> u32 {
        self.sim
            .plc_mut()
            .app_mut()
            .storage()
            .eeprom()
            .bytes_written()
    }

    fn write_eeprom_file(&mut self) -> anyhow::Result<()> {
        let Some(path) = self.eeprom_file.clone() else {
            return Ok(());
        };
        let writes = self.eeprom_writes();
        let image = *self.sim.plc_mut().app_mut().storage().eeprom().image();
        write_atomically(&path, &image)?;
        self.persisted_writes = writes;
        Ok(())
    }

    /// Writes the EEPROM back to its file when it changed and no storage job is under
    /// way (a save is written to the file once it is complete, never half-done).
    fn persist(&mut self) {
        if self.eeprom_file.is_none() || self.sim.plc_mut().app_mut().storage().busy() {
            return;
        }
        if self.eeprom_writes() != self.persisted_writes {
            self.persist_error = self.write_eeprom_file().err().map(|e| format!("{e:#}"));
        }
    }

    /// Before quitting: a save under way is finished (at most 5 s of simulated time),
    /// then the EEPROM is written to its file.
    pub fn flush(&mut self) -> anyhow::Result<()> {
        for _ in 0..500 {
            if self.keys_idle() && !self.sim.plc_mut().app_mut().storage().busy() {
                break;
            }
            self.advance(10);
        }
        if self.eeprom_file.is_some() && self.eeprom_writes() != self.persisted_writes {
            self.write_eeprom_file()?;
        }
        Ok(())
    }

    /// No keypad key is queued or being pressed.
    pub fn keys_idle(&self) -> bool {
        self.keys.is_empty() && self.pressing.is_none()
    }

    /// The program in the PLC's RAM (what the editor shows and a save stores).
    pub fn program(&self) -> &Program {
        self.sim.plc().program()
    }

    /// The program differs from the one last saved or loaded, or a field is being
    /// edited: quitting would lose it.
    pub fn unsaved(&self) -> bool {
        let ed = self.sim.plc().editor();
        ed.modified() || ed.editing()
    }

    /// A field is being edited (its pending value is not in the program yet).
    pub fn editing(&self) -> bool {
        self.sim.plc().editor().editing()
    }

    /// The editor waits for keys to finish a command or an edit (`*` cancels it).
    pub fn awaiting_keys(&self) -> bool {
        self.sim.plc().editor().awaiting_keys()
    }

    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// A keypad key: pressed after the keys before it.
    pub fn key(&mut self, key: Key) {
        self.keys.push_back(key.to_char());
    }

    /// Let `dt_ms` of simulated time pass. While keys are being typed, in 1 ms steps:
    /// down for [`KEY_HOLD_MS`] PLC ticks, then up for as many.
    pub fn advance(&mut self, dt_ms: u32) {
        let mut left = dt_ms;
        while left > 0 {
            if self.pressing.is_none() {
                if let Some(c) = self.keys.pop_front() {
                    self.sim.key(c, true);
                    self.pressing = Some((c, 2 * KEY_HOLD_MS));
                }
            }
            let step = match self.pressing {
                Some((c, KEY_HOLD_MS)) => {
                    self.sim.key(c, false);
                    1
                }
                Some(_) => 1,
                None => left,
            };
            self.run(step);
            left -= step;
            self.pressing = self
                .pressing
                .and_then(|(c, n)| (n > 1).then_some((c, n - 1)));
        }
        self.persist();
    }

    fn run(&mut self, ms: u32) {
        let end = self.sim.now_ns() + u64::from(ms) * MS_NS;
        let mut last = None;
        let rms = &mut self.rms;
        let mut each = |s: &Sample| {
            rms.push(s.t_ns, s.i_abc_a);
            last = Some(s.clone());
        };
        match self.service.as_mut() {
            Some(svc) => svc.run_until(&mut self.sim, end, &mut each),
            None => self.sim.run_until(end, each),
        }
        if last.is_some() {
            self.last = last;
        }
    }

    /// Serve the PLC's service port through `service` from now on.
    pub fn attach_service(&mut self, service: crate::service::Attached) {
        self.service = Some(service);
    }

    /// The LCD as the PLC drives it now, with its cursor (the application pass writes
    /// one changed cell per millisecond, as on the board).
    pub fn lcd(&self) -> Screen {
        self.sim.plc().lcd().to_screen()
    }

    pub fn status(&self) -> RigStatus {
        let d = self.sim.drive().status();
        let mut st = RigStatus {
            t_s: self.sim.now_ns() as f64 * 1e-9,
            plc_running: self.sim.plc().running(),
            drive_state: d.state.name().to_string(),
            fault: d.fault.map_or(0, |f| f.code()),
            reverse: d.reverse,
            // The pins as the PLC reads them: the keys' toggles and, with the lift, the
            // plant's vanes, door switch, safety chain and load sensor.
            digital_in: self.sim.pins().digital,
            digital_out: self.sim.plc().outputs(),
            analog: self.sim.pins().analog,
            lift: self.sim.lift().map(|l| l.sample()),
            ..RigStatus::default()
        };
        if let Some(s) = &self.last {
            st.f_hz = s.f_cmd_hz;
            st.speed_rpm = s.speed_rpm;
            st.u_dc_v = s.u_dc_v;
            st.i_max_a = s.i_abc_a.iter().fold(0.0f64, |m, i| m.max(i.abs()));
            st.brake = s.brake;
            st.torque_nm = s.torque_nm;
            st.pwm_on = s.pwm_on;
        }
        st.i_rms_a = self.rms.rms_a(st.f_hz);
        st.f_set_hz = f64::from(d.f_command.0) / 10.0;
        let rig = self.sim.plant().params();
        st.supply_v = rig.supply_v;
        st.load_nm = rig.motor.load_torque_nm;
        st.locked_rotor = rig.motor.locked_rotor;
        st.link_cut = self.link_cut;
        st.sensor_offset = self.sim.current_sensor_offset();
        st.garble_download = self.sim.download_garbling();
        let settings = *self.sim.drive().core().vm().settings();
        st.limits = Limits {
            u_min_v: f64::from(settings.u_min_volts),
            u_max_v: f64::from(settings.u_max_volts),
            i_max_a: f64::from(settings.i_max_centiamps) / 100.0,
            ov_hw_v: f64::from(d.hw.ov_hw.0),
            oc_hw_a: f64::from(d.hw.oc_hw.0) / 100.0,
        };
        st
    }

    /// Changes the DC-link supply's open-circuit voltage by `dv` (0..60 V).
    pub fn adjust_supply(&mut self, dv: f64) {
        let p = self.sim.plant_mut().params_mut();
        p.supply_v = ((p.supply_v + dv).clamp(0.0, 60.0) * 10.0).round() / 10.0;
    }

    /// Changes the constant load torque by `dt` (0..1 N m).
    pub fn adjust_load(&mut self, dt: f64) {
        let m = &mut self.sim.plant_mut().params_mut().motor;
        m.load_torque_nm = ((m.load_torque_nm + dt).clamp(0.0, 1.0) * 1000.0).round() / 1000.0;
    }

    pub fn toggle_locked_rotor(&mut self) {
        let m = &mut self.sim.plant_mut().params_mut().motor;
        m.locked_rotor = !m.locked_rotor;
    }

    /// Cuts the UART wires, or restores them.
    pub fn toggle_link(&mut self) {
        self.link_cut = !self.link_cut;
        self.sim.set_link_cut(self.link_cut);
    }

    /// A spike's end "at the end of its period". Not the running period's length: the
    /// period the spike lands in is the next one, and periods differ by 1 ns (the timer's
    /// period is not a whole number of ns), so a spike ending at this period's length
    /// ended 1 ns before the break interrupt ran in every other period, and the drive
    /// blamed a voltage spike on overcurrent (`BreakMonitor::fired`'s rule for a pulse
    /// already gone).
    const UNTIL_PERIOD_END_NS: u64 = u64::MAX;

    /// A current spike on phase 1 that the overcurrent comparator sees for the last
    /// 30 % of the next PWM period (outside the blanking window around its middle, and
    /// still there when the break interrupt runs): 1 A above `I>>`.
    pub fn current_spike(&mut self) {
        let oc_hw = f64::from(self.sim.drive().status().hw.oc_hw.0) / 100.0;
        let i_now = self.last.as_ref().map_or(0.0, |s| s.i_abc_a[0].abs());
        let period = self.sim.plant().period_ns();
        self.sim.plant_mut().inject_sense_spike(SenseSpike {
            phase: 0,
            amps: oc_hw + i_now + 1.0,
            from_ns: 7 * period / 10,
            to_ns: Self::UNTIL_PERIOD_END_NS,
        });
    }

    /// A DC-link voltage spike that the overvoltage comparator sees for the last 30 % of
    /// the next PWM period: 5 V above `U>>`. (A pulse gone before the break interrupt
    /// runs is blamed on overcurrent by the drive, `BreakMonitor::fired`.)
    pub fn voltage_spike(&mut self) {
        let ov_hw = f64::from(self.sim.drive().status().hw.ov_hw.0);
        let u_now = self.sim.plant().outputs().u_dc_v;
        let period = self.sim.plant().period_ns();
        self.sim.plant_mut().inject_udc_sense_spike(UdcSenseSpike {
            volts: (ov_hw - u_now).max(0.0) + 5.0,
            from_ns: 7 * period / 10,
            to_ns: Self::UNTIL_PERIOD_END_NS,
        });
    }

    /// Cycles the drive board's supply: the drive restarts (boot self-test, handshake).
    pub fn power_cycle_drive(&mut self) {
        self.sim.restart_drive(ResetCause::PowerOn);
    }

    /// The drive's watchdog resets it (fault WDG after the restart).
    pub fn watchdog_reset_drive(&mut self) {
        self.sim.restart_drive(ResetCause::Watchdog);
    }

    /// Phase 1's current sensor gets (or loses) an offset of [`SENSOR_FAULT_COUNTS`].
    pub fn toggle_sensor_fault(&mut self) {
        let on = self.sim.current_sensor_offset() == 0;
        self.sim
            .set_current_sensor_offset(if on { SENSOR_FAULT_COUNTS } else { 0 });
    }

    /// Arms (or disarms) a garbled next download.
    pub fn toggle_garble_download(&mut self) {
        let on = !self.sim.download_garbling();
        self.sim.garble_next_download(on);
    }

    /// Set digital input `n` (0..16).
    pub fn set_digital(&mut self, n: u8, on: bool) {
        if n < DIGITAL_INPUTS {
            let d = self.pins.digital;
            self.pins.digital = if on { d | (1 << n) } else { d & !(1 << n) };
            self.sim.set_pins(self.pins);
        }
    }

    /// Set analog input `n` (0..4) to `counts` (0..1023).
    pub fn set_analog(&mut self, n: u8, counts: u16) {
        if let Some(v) = self.pins.analog.get_mut(usize::from(n)) {
            *v = counts.min(1023);
            self.sim.set_pins(self.pins);
        }
    }
}
