//! Virtual-time co-simulation: the plant, both MCUs, the UART wires and the scenario,
//! scheduled in integer nanoseconds.
//!
//! Sources of events, each with its own next time: the drive's PWM period (from the timer
//! setup the firmware programs, exact to the timer tick, no drift), the drive's and the
//! PLC's 1 ms ticks, the PLC scan, bytes arriving on either UART wire, a UART becoming
//! free, scenario actions, the wire cut, and CSV samples. The plant is advanced to the time
//! of each event that reads or changes it (PWM period, drive tick, sample, scenario
//! action) before the event is handled, and to the end of every `run_until`. Events at
//! the same time run in a fixed order (scenario, cut, UART receive, PWM, drive tick, PLC
//! tick, scan, UART transmit, sample), so a run is a pure function of its inputs and the
//! seed.

use anyhow::{Context, Result};
use firmware_drive::{AdcSample, DriveConfig, ResetCause};
use firmware_plc::storage::image::{program_image, ImageOptions};
use firmware_plc::storage::MemEeprom;
use shared_protocol::link::channel::{Channel, Impairments};
use shared_protocol::link::line::{End, Line, LinkTask};
use shared_protocol::link::pump::Pass;
use shared_protocol::link::{LinkConfig, MAX_WIRE_FRAME};
use shared_protocol::program::Program;
use shared_protocol::units::Micros;

use crate::mcu::{PlcPins, SimDrive, SimPlc, Warnings};
use crate::plant::lift::{
    Lift, LiftSample, BRAKE_RELEASE_OUTPUT, CHAIN_INPUT, DOOR_CLOSED_INPUT, DOOR_OPEN_OUTPUT,
    LOAD_ANALOG, VANE_L_INPUT, VANE_R_INPUT,
};
use crate::plant::{GateCommand, Plant, PlantOutputs, RigParams};
use crate::scenario::{Action, Input, Scenario};
use crate::tim1::SimTim1;

const MS_NS: u64 = 1_000_000;

/// One row of the record (hil-sim.md "CSV columns").
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub t_ns: u64,
    pub f_cmd_hz: f64,
    pub dir: i8,
    pub m: f64,
    pub pwm_on: bool,
    pub fault: u8,
    pub u_dc_v: f64,
    pub i_abc_a: [f64; 3],
    pub speed_rpm: f64,
    pub torque_nm: f64,
    pub brake: bool,
    /// D00..D15 at the pins, bit n = Dn.
    pub digital_in: u16,
    /// O00..O07, bit n = On.
    pub digital_out: u8,
    pub q: [i16; 8],
    pub lcd: [Option<i16>; 4],
    /// Leg duties 0..1, averaged over the last complete PWM period.
    pub duty_abc: [f64; 3],
    /// Line voltage a-b averaged over the last complete PWM period, V.
    pub u_ab_v: f64,
    /// The run-time warnings the PLC shows (its own and the drive's).
    pub warn: Warnings,
    /// Safety (NOT RATED, safety.md 11): the requested mask (`sf_req`), the status bits
    /// (`sf_st`), SDC, the stopwatch (0.1 s), the commanded field turns since RUN start
    /// (10⁻⁴ turn) and the whole turns since the activation (`SFP`, from the status).
    pub sf_req: u16,
    pub sf_st: u16,
    pub sdc: bool,
    pub sft_ds: u16,
    pub turns_e4: i64,
    pub sf_turns: i16,
    /// The lift (`[lift]`), after its last 1 ms step.
    pub lift: Option<LiftSample>,
}

/// A drive fault as it was latched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultRecord {
    pub t_ns: u64,
    pub code: u8,
}

/// Settings of one run besides the scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunOptions {
    pub seed: u64,
    pub sample_ns: u64,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            seed: 1,
            sample_ns: MS_NS,
        }
    }
}

/// The whole rig in virtual time.
pub struct Simulation {
    now_ns: u64,
    plant: Plant,
    plant_ns: u64,
    drive: SimDrive,
    plc: SimPlc,
    scenario: Scenario,
    next_action: usize,
    pins: PlcPins,
    aux_counts: u16,
    /// The UART line between the two link tasks (`shared_protocol::link::line`, the
    /// co-simulation rig's line): its wires and when each task passes next.
    line: Line,
    cut: bool,
    // PWM timer.
    pwm_epoch_ns: u64,
    pwm_k: u64,
    pwm_key: (u16, u16),
    next_pwm_ns: u64,
    /// The drive's TIM1 registers (the firmware's power port writes them).
    tim1: SimTim1,
    next_drive_tick_ns: u64,
    next_plc_tick_ns: u64,
    next_sample_ns: u64,
    sample_ns: u64,
    faults: Vec<FaultRecord>,
    last_fault: u8,
    /// When the plant left physics ([`Plant::diverged`]): the run stops there.
    unstable_at_ns: Option<u64>,
    /// The drive's state changes (time, state name), for the run summary's RUN/ACK history.
    states: Vec<(u64, &'static str)>,
    /// Added to the drive's ADC reading of phase 1's current, counts (a sensor fault the
    /// panel injects: the drive's boot self-test measures the zero).
    i_a_offset_counts: i16,
    /// The next download's `DownloadBegin` goes out with a wrong section CRC (the
    /// panel's "garbled download": the drive rejects the section, fault PROG).
    garble_download: bool,
    /// The lift on the shaft (`[lift]`), stepped every millisecond.
    lift: Option<Lift>,
}

impl Simulation {
    /// The default boards with `program` in the PLC's EEPROM (slot 1, RUN at power-up
    /// unless the scenario types the RUN key).
    pub fn new(program: &Program, scenario: Scenario, opts: RunOptions) -> Result<Self> {
        if scenario
            .actions
            .iter()
            .any(|a| matches!(a.action, Action::Silicon(..)))
        {
            anyhow::bail!(
                "faults of the silicon (vdd_v, sram_parity_error, flash_ecc_error, i2c_fault) \
                 need the emulated MCUs: `hil-sim emu`"
            );
        }
        let image = program_image(
            program,
            &ImageOptions {
                slot: 1,
                run_at_power_up: !scenario.keys_start_run,
            },
        )
        .map_err(|e| anyhow::anyhow!("cannot store the program in the EEPROM: {e:?}"))
        .context("EEPROM image")?;
        let link = LinkConfig::at_baud(scenario.baud);
        let drive = SimDrive::with_config(link, drive_config(&scenario.rig));
        let mut plc = SimPlc::new(MemEeprom::from_image(&image), link, Micros(0));
        // The link's quiet window after each scan lasts until the next scan.
        plc.app_mut()
            .set_scan_period_us((scenario.scan_time_ns / 1000).max(1));
        Ok(Simulation::with_boards(drive, plc, scenario, opts))
    }
}

/// The drive's configuration on this rig: the board's default hardware thresholds are the
/// rig's (`[plant] oc_hw_a`, `ov_hw_v`), used while the program sets no `I>>`/`U>>`.
pub fn drive_config(rig: &RigParams) -> DriveConfig {
    let t = rig.hw_defaults.thresholds();
    DriveConfig {
        oc_hw_default_centiamps: t.oc_hw.0 as u16,
        ov_hw_default_volts: t.ov_hw.0 as u16,
        board: rig.board,
        ..DriveConfig::default()
    }
}

/// Every byte that has arrived on `wire` by `now`.
pub(crate) fn receive_all(wire: &mut Channel, now: Micros) -> Vec<u8> {
    let mut all = Vec::new();
    let mut buf = [0u8; 64];
    loop {
        let n = wire.receive(now, &mut buf);
        if n == 0 {
            return all;
        }
        all.extend_from_slice(buf.get(..n).unwrap_or(&[]));
    }
}

/// The wire frame `tx` with its section CRC flipped, if it is a `DownloadBegin`; the frame
/// CRC is made anew, so only the drive's check of the whole section sees the damage.
fn garble_download_begin(tx: &[u8]) -> Option<Vec<u8>> {
    use shared_protocol::link::frame::{encode_frame, FrameReader};
    use shared_protocol::link::PlcMsg;
    let mut reader = FrameReader::new();
    let mut frame = None;
    for &b in tx {
        if let Some(Ok(f)) = reader.push::<PlcMsg>(b) {
            frame = Some(f);
        }
    }
    let mut frame = frame?;
    let PlcMsg::DownloadBegin { crc } = frame.msg else {
        return None;
    };
    frame.msg = PlcMsg::DownloadBegin { crc: crc ^ 1 };
    let mut out = vec![0u8; MAX_WIRE_FRAME];
    let n = encode_frame(&frame, tx.first() == Some(&0), &mut out).ok()?;
    out.truncate(n);
    Some(out)
}

/// The PLC board's link task on the line; the panel's "garbled download" changes the
/// next `DownloadBegin` on its way to the wire.
struct PlcTask<'a> {
    board: &'a mut SimPlc,
    garble: &'a mut bool,
    garbled: Option<Vec<u8>>,
}

impl LinkTask for PlcTask<'_> {
    fn pass(&mut self, rx: &[u8], room: usize, now: Micros) -> Pass {
        let pass = self.board.link_pass(rx, room, now);
        self.garbled = None;
        if *self.garble {
            self.garbled = garble_download_begin(self.board.link_tx());
            if self.garbled.is_some() {
                *self.garble = false;
            }
        }
        pass
    }
    fn tx(&self) -> &[u8] {
        self.garbled
            .as_deref()
            .unwrap_or_else(|| self.board.link_tx())
    }
    fn timeout(&self) -> Option<Micros> {
        self.board.link_timeout()
    }
}

/// The drive board's link task on the line.
struct DriveTask<'a>(&'a mut SimDrive);

impl LinkTask for DriveTask<'_> {
    fn pass(&mut self, rx: &[u8], room: usize, now: Micros) -> Pass {
        self.0.link_pass(rx, room, now)
    }
    fn tx(&self) -> &[u8] {
        self.0.link_tx()
    }
    fn timeout(&self) -> Option<Micros> {
        self.0.link_timeout()
    }
}

fn timer_period_ns(epoch: u64, k: u64, ticks: u64, f_tim: u32) -> u64 {
    let f = u128::from(f_tim.max(1));
    epoch + ((u128::from(k) * u128::from(ticks) * 1_000_000_000) / f) as u64
}

impl Simulation {
    /// The given boards on the default models: [`Plant`] with the scenario's rig, and
    /// [`Channel`] wires with its link settings (bit errors seeded from `opts.seed`, the
    /// drive-to-PLC direction from a derived seed).
    pub fn with_boards(drive: SimDrive, plc: SimPlc, scenario: Scenario, opts: RunOptions) -> Self {
        let imp = Impairments {
            bit_error_rate: scenario.bit_error_rate,
            ..Impairments::default()
        };
        let seed = opts.seed;
        let to_drive = Channel::new(scenario.baud, imp, seed);
        let to_plc = Channel::new(scenario.baud, imp, seed.wrapping_mul(31).wrapping_add(17));
        let plant = Plant::new(scenario.rig);
        Simulation::with_parts(drive, plc, plant, to_drive, to_plc, scenario, opts)
    }

    /// The given boards, plant and wires. `to_drive` carries the PLC's transmissions,
    /// `to_plc` the drive's.
    pub fn with_parts(
        mut drive: SimDrive,
        plc: SimPlc,
        mut plant: Plant,
        to_drive: Channel,
        to_plc: Channel,
        scenario: Scenario,
        opts: RunOptions,
    ) -> Self {
        let timing = drive.pwm_timing();
        let tim1 = SimTim1::new(timing, drive.timer_clock_hz());
        drive.boot_dacs(&mut plant);
        let lift = scenario.lift.map(Lift::new);
        let mut pins = PlcPins::default();
        if let Some(l) = &lift {
            plant.set_lift_shaft(Some(l.shaft()));
            lift_pins(&mut pins, &l.sample());
        }
        Simulation {
            now_ns: 0,
            plant,
            plant_ns: 0,
            drive,
            plc,
            next_action: 0,
            pins,
            aux_counts: 0,
            line: Line::with_channels(to_drive, to_plc),
            cut: false,
            pwm_epoch_ns: 0,
            pwm_k: 0,
            pwm_key: (timing.arr, timing.psc),
            next_pwm_ns: 0,
            tim1,
            next_drive_tick_ns: MS_NS,
            next_plc_tick_ns: MS_NS,
            next_sample_ns: 0,
            sample_ns: opts.sample_ns.max(1),
            faults: Vec::new(),
            last_fault: 0,
            unstable_at_ns: None,
            states: Vec::new(),
            i_a_offset_counts: 0,
            garble_download: false,
            scenario,
            lift,
        }
    }

    /// Cuts (`true`) or restores the UART wires now, both directions (the panel's link
    /// switch). The scenario's `cut_at_s` no longer applies afterwards.
    pub fn set_link_cut(&mut self, cut: bool) {
        self.cut = true;
        self.scenario.cut_at_ns = u64::MAX;
        self.line.set_cut(cut);
    }

    /// Restarts the drive MCU now with reset cause `cause` (its supply cycled, or its
    /// watchdog): the board's firmware starts from scratch (boot self-test, link
    /// handshake), TIM1 is reset (outputs off), the plant and the PLC carry on.
    pub fn restart_drive(&mut self, cause: ResetCause) {
        let cfg = *self.drive.core().config();
        let link = LinkConfig::at_baud(self.scenario.baud);
        self.drive = SimDrive::with_reset(link, cfg, cause);
        let timing = self.drive.pwm_timing();
        self.tim1 = SimTim1::new(timing, self.drive.timer_clock_hz());
        self.drive.boot_dacs(&mut self.plant);
        self.pwm_key = (timing.arr, timing.psc);
        self.pwm_epoch_ns = self.now_ns;
        self.pwm_k = 0;
        self.next_pwm_ns = self.now_ns;
        self.plant.set_command(GateCommand::OFF);
        self.plant.set_brake(false);
        self.line.forget(End::Drive);
    }

    /// Restarts the PLC MCU now (its supply cycled): the board powers up from the EEPROM
    /// as it is (a page write in progress is lost or done whole, or stopped where an
    /// armed `MemEeprom::cut_power_after` stopped it; the chip is powered again), its
    /// link task starts again; the drive, the plant and the pins carry on.
    pub fn restart_plc(&mut self) {
        let mut eeprom = self.plc.app_mut().storage().eeprom().clone();
        eeprom.restore_power();
        let link = LinkConfig::at_baud(self.scenario.baud);
        let mut plc = SimPlc::new(eeprom, link, Micros(self.now_ns / 1000));
        plc.app_mut()
            .set_scan_period_us((self.scenario.scan_time_ns / 1000).max(1));
        self.plc = plc;
        self.line.forget(End::Plc);
    }

    /// The bit error rate of both wires from now on (the scenario's `bit_error_rate` is
    /// the rate at power-up).
    pub fn set_link_bit_error_rate(&mut self, rate: f64) {
        self.line.set_impairments(Impairments {
            bit_error_rate: rate,
            ..Impairments::default()
        });
    }

    /// A noise burst on one wire: the next `bytes` bytes sent toward the drive
    /// (`to_drive`) or toward the PLC each get at least one bit flipped.
    pub fn link_burst(&mut self, to_drive: bool, bytes: u32) {
        let end = if to_drive { End::Plc } else { End::Drive };
        self.line.outbox(end).burst(bytes);
    }

    /// The drive's TIM1 registers (what the gates are told).
    pub fn tim1(&self) -> &SimTim1 {
        &self.tim1
    }

    /// When the next event of the scheduler is due, ns (an observer steps event by
    /// event with `run_until(next_event_at_ns())`).
    pub fn next_event_at_ns(&self) -> u64 {
        self.next_event_ns()
    }

    /// A fault of the drive's phase-1 current sensor: `counts` added to its ADC reading
    /// (0: healthy). The drive measures the zero at boot only: a restart with an offset
    /// beyond its tolerance fails the self-test (fault BOOT).
    pub fn set_current_sensor_offset(&mut self, counts: i16) {
        self.i_a_offset_counts = counts;
    }

    pub fn current_sensor_offset(&self) -> i16 {
        self.i_a_offset_counts
    }

    /// Garbles the next program download (its section CRC), so that the drive rejects
    /// it (fault PROG), as a download corrupted past the frame CRC would be.
    pub fn garble_next_download(&mut self, on: bool) {
        self.garble_download = on;
    }

    pub fn download_garbling(&self) -> bool {
        self.garble_download
    }

    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, for tests that disturb it (e.g. `Plant::inject_sense_spike`).
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    pub fn drive(&self) -> &SimDrive {
        &self.drive
    }

    pub fn plc(&self) -> &SimPlc {
        &self.plc
    }

    /// The PLC board, for a host that reaches into it (the PC panel's EEPROM file).
    pub fn plc_mut(&mut self) -> &mut SimPlc {
        &mut self.plc
    }

    pub fn pins(&self) -> PlcPins {
        self.pins
    }

    /// Sets the PLC's input pins (the front panel's switches and pots; a scenario sets
    /// them with its actions). The PLC samples them at its next tick.
    /// The inputs the lift drives (with `[lift]`) stay the lift's.
    pub fn set_pins(&mut self, pins: PlcPins) {
        self.pins = pins;
        if let Some(l) = &self.lift {
            lift_pins(&mut self.pins, &l.sample());
        }
    }

    /// A keypad key goes down or up now (the front panel; a scenario presses keys with
    /// its actions).
    pub fn key(&mut self, key: char, down: bool) {
        self.plc.key(key, down, Micros(self.now_ns / 1000));
    }

    /// Changes the sampling period from the next sample on (e.g. fine samples of one
    /// window of a long run, for the current ripple of a PWM period).
    pub fn set_sample_ns(&mut self, sample_ns: u64) {
        self.sample_ns = sample_ns.max(1);
        self.next_sample_ns = self.next_sample_ns.min(self.now_ns + self.sample_ns);
    }

    /// Faults in the order they latched.
    pub fn faults(&self) -> &[FaultRecord] {
        &self.faults
    }

    /// The drive's state after each change (time in ns, `IDLE`/`RUN`/`FAULT`/...), from
    /// its first 1 ms tick: a FAULT -> IDLE change is an accepted ACK.
    pub fn drive_states(&self) -> &[(u64, &'static str)] {
        &self.states
    }

    /// No more scenario actions: the inputs stay as they are (hil-sim's service port
    /// serving its client after the run's duration, service.md 9).
    pub fn hold_inputs(&mut self) {
        self.next_action = self.scenario.actions.len();
    }

    /// Runs until `end_ns` (inclusive), calling `on_sample` at every sample time.
    /// A plant that diverged ([`Simulation::unstable_at_ns`]) is not stepped further:
    /// the clock jumps to `end_ns` and the caller reports the divergence.
    pub fn run_until(&mut self, end_ns: u64, mut on_sample: impl FnMut(&Sample)) {
        loop {
            if self.unstable_at_ns.is_some() {
                self.now_ns = self.now_ns.max(end_ns);
                return;
            }
            let t = self.next_event_ns();
            if t > end_ns {
                break;
            }
            if self.event_touches_plant(t) {
                self.advance_plant(t);
            }
            self.now_ns = t;
            self.handle_events(t, &mut on_sample);
        }
        self.advance_plant(end_ns);
        self.now_ns = self.now_ns.max(end_ns);
    }

    /// When the plant model left physics (NaN, or values no rig of this class reaches):
    /// checked every 1 ms, before the drive's tick, so that the divergence is never
    /// reported as a trip.
    pub fn unstable_at_ns(&self) -> Option<u64> {
        self.unstable_at_ns
    }

    /// Whether an event due at `t` reads or changes the plant: a PWM period, the drive's
    /// 1 ms tick (with the lift's step), a sample, a scenario action. The UART bytes and
    /// the PLC's tick alone do not (the link tasks see neither the timer nor the plant), so
    /// the plant is not integrated up to them: its steps do not depend on the link's
    /// traffic.
    fn event_touches_plant(&self, t: u64) -> bool {
        t >= self.next_pwm_ns
            || t >= self.next_drive_tick_ns
            || t >= self.next_sample_ns
            || self
                .scenario
                .actions
                .get(self.next_action)
                .is_some_and(|a| a.at_ns <= t)
    }

    fn advance_plant(&mut self, t: u64) {
        if t > self.plant_ns {
            self.plant.advance(t - self.plant_ns);
            self.plant_ns = t;
        }
    }

    fn next_event_ns(&self) -> u64 {
        let mut t = self
            .next_pwm_ns
            .min(self.next_drive_tick_ns)
            .min(self.next_plc_tick_ns)
            .min(self.next_sample_ns);
        if let Some(a) = self.scenario.actions.get(self.next_action) {
            t = t.min(a.at_ns);
        }
        if !self.cut {
            t = t.min(self.scenario.cut_at_ns);
        }
        if let Some(l) = self.line.next_event_ns() {
            t = t.min(l);
        }
        t
    }

    fn handle_events(&mut self, t: u64, on_sample: &mut impl FnMut(&Sample)) {
        let now = Micros(t / 1000);
        while let Some(a) = self.scenario.actions.get(self.next_action) {
            if a.at_ns > t {
                break;
            }
            let action = a.action.clone();
            self.next_action += 1;
            self.apply(&action, now);
        }
        if !self.cut && t >= self.scenario.cut_at_ns {
            self.cut = true;
            self.line.set_cut(true);
        }
        if t >= self.next_pwm_ns {
            self.pwm_event(t);
        }
        let mut app_ran = false;
        let mut drive_kick = false;
        if t >= self.next_drive_tick_ns && self.plant.diverged() {
            self.unstable_at_ns = Some(t);
            return;
        }
        if t >= self.next_drive_tick_ns {
            // The lift moves on with the outputs of the PLC's last scan.
            self.lift_step();
            // The board's 1 ms task: STO_IN (safety.md 6), the break monitor, the tick, the
            // threshold DACs, the link task's wake-up.
            drive_kick = self
                .drive
                .control_tick(&mut self.tim1, &mut self.plant, now);
            self.next_drive_tick_ns += MS_NS;
            let status = self.drive.status();
            let f = status.fault.map_or(0, |f| f.code());
            if f != 0 && f != self.last_fault {
                self.faults.push(FaultRecord { t_ns: t, code: f });
            }
            self.last_fault = f;
            let state = status.state.name();
            if self.states.last().is_none_or(|(_, s)| *s != state) {
                self.states.push((t, state));
            }
        }
        if t >= self.next_plc_tick_ns {
            // The application pass samples the pins as they are now (raw levels), every
            // millisecond as the board does; the scan cadence is the core's.
            self.plc.tick_1ms(&self.pins, now);
            self.next_plc_tick_ns += MS_NS;
            app_ran = true;
        }
        // A link task passes when bytes arrived (the boards' ring-buffered RX wakes on an
        // idle line or half a ring; bytes are handed over as they arrive here, which is
        // never later), at its pump's deadline (or when its line became free with a frame
        // due), or when the application task that just ran left something due (the
        // boards' tasks kick it then: `pump::is_due`).
        let mut plc = PlcTask {
            board: &mut self.plc,
            garble: &mut self.garble_download,
            garbled: None,
        };
        self.line.poll(End::Plc, &mut plc, t, app_ran);
        self.line
            .poll(End::Drive, &mut DriveTask(&mut self.drive), t, drive_kick);
        if t >= self.next_sample_ns {
            let s = self.sample(t);
            on_sample(&s);
            self.next_sample_ns += self.sample_ns;
        }
    }

    /// One millisecond of the lift: door, brake, limits and sensors from the car's
    /// position, then its inputs to the PLC's pins and its brake/contactor to the shaft.
    fn lift_step(&mut self) {
        let Some(lift) = self.lift.as_mut() else {
            return;
        };
        let out = self.plc.outputs();
        let o = self.plant.outputs();
        let m_per_rad = lift.params().m_per_rad();
        let car_mm = lift.car_mm(self.plant.angle_rad());
        let s = lift.step(
            1e-3,
            out & (1 << DOOR_OPEN_OUTPUT) != 0,
            out & (1 << BRAKE_RELEASE_OUTPUT) != 0,
            car_mm,
            o.speed_rad_s * m_per_rad * 1000.0,
        );
        self.plant.set_lift_shaft(Some(lift.shaft()));
        lift_pins(&mut self.pins, &s);
    }

    /// The lift, if the scenario has one.
    pub fn lift(&self) -> Option<&Lift> {
        self.lift.as_ref()
    }

    /// A lift event now (the panel's keys).
    pub fn lift_event(&mut self, e: crate::plant::lift::LiftEvent) {
        if let Some(l) = self.lift.as_mut() {
            l.apply(e);
        }
    }

    fn apply(&mut self, action: &Action, now: Micros) {
        match *action {
            Action::Set(Input::Digital(n), v) => {
                if v != 0 {
                    self.pins.digital |= 1 << n;
                } else {
                    self.pins.digital &= !(1 << n);
                }
            }
            Action::Set(Input::Analog(n), v) => {
                if let Some(a) = self.pins.analog.get_mut(usize::from(n)) {
                    *a = v;
                }
            }
            // 10-bit value on the drive's 12-bit converter.
            Action::Set(Input::Aux, v) => self.aux_counts = (v << 2).min(4095),
            // Low sets BIF: the break interrupt runs at the next event if unmasked.
            Action::Set(Input::StoIn, v) => self.plant.set_sto_input(v == 0),
            Action::KeyDown(k) => self.plc.key(k, true, now),
            Action::KeyUp(k) => self.plc.key(k, false, now),
            Action::Plant(c) => c.apply(self.plant.params_mut()),
            Action::Lift(e) => self.lift_event(e),
            // Refused in `new`: the silicon is the emulator's.
            Action::Silicon(..) => {}
        }
    }

    fn pwm_event(&mut self, t: u64) {
        // The break interrupt first (it outranks the update interrupt): the hardware has
        // already opened the switches.
        if self.tim1.break_irq_pending(&self.plant) {
            self.drive.break_interrupt(&mut self.tim1, &mut self.plant);
        }
        // The update event: the preloaded timing and compares take effect.
        self.tim1.update();
        let timing = *self.tim1.timing();
        let f_tim = self.tim1.timer_clock_hz();
        let key = (timing.arr, timing.psc);
        if key != self.pwm_key {
            // A new PSC/ARR: the new period starts at this update.
            self.pwm_key = key;
            self.pwm_epoch_ns = t;
            self.pwm_k = 0;
        }
        let ticks = 2 * u64::from(timing.arr.max(1)) * (u64::from(timing.psc) + 1);
        self.pwm_k += 1;
        self.next_pwm_ns = timer_period_ns(self.pwm_epoch_ns, self.pwm_k, ticks, f_tim);
        let period_ns = self.next_pwm_ns - t;
        self.plant.start_period(period_ns, self.tim1.gate());
        self.plant
            .set_blanking(self.tim1.blanking_ccr5(), timing.arr);
        let s = self.plant.adc_sample();
        let adc = AdcSample {
            i_a: s.i_a_counts.saturating_add_signed(self.i_a_offset_counts),
            i_b: s.i_b_counts,
            u_dc: s.u_dc_counts,
            aux: self.aux_counts,
        };
        // The update interrupt: the firmware's body over the simulator's TIM1.
        self.drive
            .pwm_interrupt(&mut self.tim1, &mut self.plant, adc);
    }

    fn sample(&self, t: u64) -> Sample {
        let o: PlantOutputs = self.plant.outputs();
        let st = self.drive.status();
        let mut q = [0i16; 8];
        for (n, v) in q.iter_mut().enumerate() {
            *v = self.plc.q(n as u8);
        }
        Sample {
            t_ns: t,
            f_cmd_hz: f64::from(st.f_applied.0) / 10.0,
            dir: if st.reverse { -1 } else { 1 },
            m: f64::from(st.modulation_permille) / 1000.0,
            pwm_on: self.tim1.moe() && !o.hw_break,
            fault: st.fault.map_or(0, |f| f.code()),
            u_dc_v: o.u_dc_v,
            i_abc_a: o.i_abc_a,
            speed_rpm: o.speed_rad_s * 60.0 / (2.0 * std::f64::consts::PI),
            torque_nm: o.torque_nm,
            brake: o.brake_on,
            digital_in: self.pins.digital,
            digital_out: self.plc.outputs(),
            q,
            lcd: self.plc.lcd_fields(),
            duty_abc: o.duty_abc,
            u_ab_v: o.u_ab_v,
            warn: self.plc.warnings(),
            sf_req: st.sf_requested,
            sf_st: st.sf_status,
            sdc: st.sf_sdc,
            sft_ds: st.sf_elapsed_ds,
            turns_e4: self.drive.turns_e4(),
            sf_turns: st.sf_turns,
            lift: self.lift.as_ref().map(|l| l.sample()),
        }
    }
}

/// The pins the lift drives (lift.md 3.2): vanes D10/D11, door closed D12, safety chain
/// D15, load sensor A00.
fn lift_pins(pins: &mut PlcPins, s: &LiftSample) {
    for (n, on) in [
        (VANE_L_INPUT, s.vane_l),
        (VANE_R_INPUT, s.vane_r),
        (DOOR_CLOSED_INPUT, s.door_closed),
        (CHAIN_INPUT, s.chain_closed),
    ] {
        if on {
            pins.digital |= 1 << n;
        } else {
            pins.digital &= !(1 << n);
        }
    }
    if let Some(a) = pins.analog.get_mut(usize::from(LOAD_ANALOG)) {
        *a = s.load_counts;
    }
}
