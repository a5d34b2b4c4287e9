//! The simulated power stage and machine: DC-link supply, capacitor and brake resistor,
//! the inverter, the induction motor on its shaft, the sensors and the hardware comparators.
//!
//! The plant is advanced in virtual time with a fixed-step RK4 whose steps never cross a
//! switching edge (switching model) and are at most [`MAX_STEP_NS`] long. Inputs are held
//! constant over each step; a floating leg's diode is chosen from the current at the start
//! of the step.

pub mod inverter;
pub mod lift;
pub mod motor;
pub mod sensors;

pub use inverter::{GateCommand, Leg, PwmMode};
pub use motor::MotorParams;
pub use sensors::{AdcSample, ComparatorTable, Comparators, HwDefaults};

use firmware_drive::comparators::BoardProfile;
use firmware_drive::power_port::ComparatorLevels;

use inverter::Conn;

/// Longest integration step. 25 µs keeps RK4 far inside its stability region for every
/// time constant of the default rig (the fastest is the DC link's R·C = 0.5 ms) and gives
/// four steps per period at 10 kHz.
pub const MAX_STEP_NS: u64 = 25_000;

/// Below this stator current (A, peak of any phase) with all legs floating the diodes stop
/// conducting and the stator is treated as open.
pub const OPEN_CIRCUIT_A: f64 = 0.02;

/// Motor terminal driven by inverter leg k (legs = the drive's phases 1, 2, 3).
///
/// The source generates phase 2 at +120° and phase 3 at +240° (program.md section 4, the
/// motor example), i.e. the sequence 1-3-2. The rig's motor is wired 1→U, 2→W, 3→V so
/// that this sequence, the drive's "forward", turns the shaft forward (positive speed).
/// Currents, sensors and comparators are all on the inverter side (legs).
pub const WIRING: [usize; 3] = [0, 2, 1];

fn legs_to_motor(leg: [f64; 3]) -> [f64; 3] {
    let mut m = [0.0; 3];
    for (k, v) in leg.into_iter().enumerate() {
        m[WIRING[k]] = v;
    }
    m
}

fn motor_to_legs(m: [f64; 3]) -> [f64; 3] {
    WIRING.map(|w| m[w])
}

/// What the inverter feeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Load {
    /// The induction motor of [`RigParams::motor`] (the default rig).
    Motor,
    /// A star-connected resistive-inductive load, R and L per phase, star point floating:
    /// the rig variant for the source's examples that drive a single leg with a DC duty or
    /// start a full-voltage sine at once (`docs/rig.md`).
    Rl { r_ohm: f64, l_h: f64 },
}

impl Load {
    /// The RL variant's default resistance per phase.
    pub const RL_R_OHM: f64 = 10.0;
    /// The RL variant's default inductance per phase (with 10 ohm: 1.27 A peak at 50 Hz,
    /// m = 1, on the 30 V link; L/R = 2 ms).
    pub const RL_L_H: f64 = 0.02;
}

/// Every parameter of the rig (defaults: `docs/rig.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigParams {
    pub motor: MotorParams,
    /// The motor, or the RL load variant.
    pub load: Load,
    /// Open-circuit voltage of the rectified supply.
    pub supply_v: f64,
    /// Source resistance of the supply (transformer + rectifier).
    pub supply_r_ohm: f64,
    pub dc_capacitor_f: f64,
    pub brake_resistor_ohm: f64,
    /// The board's default hardware thresholds (the drive's, while the program sets no
    /// `I>>`/`U>>`).
    pub hw_defaults: HwDefaults,
    pub pwm_mode: PwmMode,
    /// The drive board: its sensors' scaling and its comparators (scenario `[plant]
    /// board = "esc1"` (default: the board the default drive image is built for) or
    /// `"source"`).
    pub board: &'static BoardProfile,
}

impl Default for RigParams {
    fn default() -> Self {
        RigParams {
            motor: MotorParams::DEFAULT_RIG,
            load: Load::Motor,
            supply_v: 30.0,
            supply_r_ohm: 0.5,
            dc_capacitor_f: 1000e-6,
            brake_resistor_ohm: 10.0,
            hw_defaults: HwDefaults {
                oc_hw_a: 3.0,
                ov_hw_v: 40.0,
            },
            pwm_mode: PwmMode::Averaged,
            board: &firmware_drive::comparators::B_G431B_ESC1,
        }
    }
}

/// Integrated state: ψs (2), ψr (2), shaft speed, DC-link voltage.
type State = [f64; 6];
const PSA: usize = 0;
const PSB: usize = 1;
const PRA: usize = 2;
const PRB: usize = 3;
const WM: usize = 4;
const UDC: usize = 5;

/// What is observable at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantOutputs {
    pub i_abc_a: [f64; 3],
    pub u_dc_v: f64,
    pub speed_rad_s: f64,
    pub torque_nm: f64,
    pub brake_on: bool,
    /// The break input has cleared MOE (outputs forced off) and software has not set it
    /// again.
    pub hw_break: bool,
    /// Leg voltages as fractions of the DC link, averaged over the last complete PWM
    /// period (a floating leg counts at the rail its diodes clamp it to).
    pub duty_abc: [f64; 3],
    /// Line voltage leg 1 - leg 2 averaged over the last complete PWM period, V.
    pub u_ab_v: f64,
}

/// A disturbance of one sensed phase current during part of a PWM period (a switching
/// spike or ringing on the shunt): what the comparators see, not the motor's current.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SenseSpike {
    /// Inverter leg 0..=2.
    pub phase: usize,
    /// Added to the sensed current, A.
    pub amps: f64,
    /// From/to this time into the period, ns (the valley of the counter is at half the
    /// period); `to_ns` = `u64::MAX`: to the period's end, whatever its length.
    pub from_ns: u64,
    pub to_ns: u64,
}

/// A disturbance of the sensed DC-link voltage during part of a PWM period (a transient
/// on the divider): what the overvoltage comparator sees, not the capacitor's voltage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UdcSenseSpike {
    /// Added to the sensed DC-link voltage, V.
    pub volts: f64,
    /// From/to this time into the period, ns; `to_ns` = `u64::MAX`: to the period's end.
    pub from_ns: u64,
    pub to_ns: u64,
}

/// Where the model is taken to have diverged: phase current 10 kA, speed 10^5 rad/s
/// (~955 000 rpm), DC link 100 kV: each 100x or more beyond the scenario ranges
/// (`scenario::physics`), so a valid run never comes near.
pub const DIVERGED: (f64, f64, f64) = (1e4, 1e5, 1e5);

/// The rig's state and the command it is under.
#[derive(Debug, Clone)]
pub struct Plant {
    params: RigParams,
    x: State,
    /// The stator is open: no leg driven and the diodes have stopped conducting.
    open: bool,
    cmd: GateCommand,
    brake_on: bool,
    period_ns: u64,
    /// Time into the current PWM period (switching model).
    tau_ns: u64,
    /// TIM1's break input cleared MOE: all legs float until software sets MOE again
    /// ([`Plant::release_break`]), which it cannot while a comparator is high.
    hw_break: bool,
    /// The drive board's `STO_IN` is low (safety.md 6): TIM1's break 1 (BKIN)
    /// holds MOE cleared without software, and sets BIF ([`Plant::sto_flag`]).
    sto_in_low: bool,
    /// TIM1_SR.B2IF (the comparators' break 2): set while a comparator is high, cleared
    /// by software only once none is.
    break_flag: bool,
    /// TIM1_SR.BIF (`STO_IN`'s break 1): set while `STO_IN` is low, cleared by software
    /// only once it is high.
    sto_flag: bool,
    /// The board's comparators (table and DAC values from the drive core).
    comparators: Comparators,
    /// Comparator outputs after the last step.
    comparator_levels: ComparatorLevels,
    /// TIM1's OC5 blanking window of this period: half its length either side of the
    /// counter's valley, ns (0: none). In this model's period the valley is at
    /// `period_ns / 2` (high switches on in the middle).
    blank_half_ns: u64,
    /// A disturbance of the sensed current in this period (armed for the next one).
    spike: Option<SenseSpike>,
    armed_spike: Option<SenseSpike>,
    udc_spike: Option<UdcSenseSpike>,
    armed_udc_spike: Option<UdcSenseSpike>,
    /// Mechanical angle, rad (for plots and tests of reversal).
    angle_rad: f64,
    /// Integrals over the running PWM period: leg fractions, line voltage a-b, time (s).
    period_acc: ([f64; 3], f64, f64),
    /// Averages of the last complete PWM period: leg fractions, line voltage a-b.
    period_avg: ([f64; 3], f64),
    brake_energy_j: f64,
    /// The lift on the shaft (`[lift]`), if any: gravity, reflected mass, holding brake,
    /// motor contactor.
    lift: Option<lift::LiftShaft>,
    /// The integration's constants for the present parameters, comparators and lift
    /// (`None`: to be computed at the next advance).
    coeffs: Option<Coeffs>,
}

impl Plant {
    pub fn new(params: RigParams) -> Self {
        let mut x = [0.0; 6];
        x[UDC] = params.supply_v;
        Plant {
            params,
            x,
            open: true,
            cmd: GateCommand::OFF,
            brake_on: false,
            period_ns: 100_000,
            tau_ns: 0,
            hw_break: false,
            sto_in_low: false,
            break_flag: false,
            sto_flag: false,
            comparators: Comparators::new(params.board, params.hw_defaults.thresholds()),
            comparator_levels: ComparatorLevels::default(),
            blank_half_ns: 0,
            spike: None,
            armed_spike: None,
            udc_spike: None,
            armed_udc_spike: None,
            angle_rad: 0.0,
            period_acc: ([0.0; 3], 0.0, 0.0),
            period_avg: ([0.0; 3], 0.0),
            brake_energy_j: 0.0,
            lift: None,
            coeffs: None,
        }
    }

    /// Attaches the lift's shaft side (or updates its brake and contactor).
    pub fn set_lift_shaft(&mut self, shaft: Option<lift::LiftShaft>) {
        self.lift = shaft;
        self.coeffs = None;
    }

    pub fn lift_shaft(&self) -> Option<lift::LiftShaft> {
        self.lift
    }

    pub fn params(&self) -> &RigParams {
        &self.params
    }

    /// Run-time parameter changes (scenario events). The state is kept.
    pub fn params_mut(&mut self) -> &mut RigParams {
        self.coeffs = None;
        &mut self.params
    }

    /// Starts a PWM period with a new gate command (the timer's preload taking effect).
    pub fn start_period(&mut self, period_ns: u64, cmd: GateCommand) {
        let (legs, u_ab, t) = self.period_acc;
        if t > 0.0 {
            self.period_avg = (legs.map(|x| x / t), u_ab / t);
        }
        self.period_acc = ([0.0; 3], 0.0, 0.0);
        self.period_ns = period_ns.max(1);
        self.tau_ns = 0;
        self.spike = self.armed_spike.take();
        self.udc_spike = self.armed_udc_spike.take();
        self.set_command(cmd);
    }

    /// The running PWM period, ns.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// TIM1's OC5 window for the period just started (RM0440: OC5REF in PWM mode 1 is
    /// active while CNT < CCR5; `firmware_drive::blanking`): `ccr5` of `arr` counts. While
    /// it is active the comparators the board profile marks `blanked` output 0.
    pub fn set_blanking(&mut self, ccr5: u16, arr: u16) {
        let half = self.period_ns / 2;
        self.blank_half_ns = (u64::from(ccr5.min(arr)) * half) / u64::from(arr.max(1));
    }

    /// The blanking window is active at `tau_ns` into the period.
    pub fn blanking_at(&self, tau_ns: u64) -> bool {
        self.blank_half_ns > 0 && tau_ns.abs_diff(self.period_ns / 2) < self.blank_half_ns
    }

    /// Adds `spike` to the sensed current of the next PWM period (the comparators see it;
    /// the motor does not: a switching spike or ringing on a shunt).
    pub fn inject_sense_spike(&mut self, spike: SenseSpike) {
        self.armed_spike = Some(spike);
    }

    /// Adds `spike` to the sensed DC-link voltage of the next PWM period (the overvoltage
    /// comparator sees it; the capacitor does not).
    pub fn inject_udc_sense_spike(&mut self, spike: UdcSenseSpike) {
        self.armed_udc_spike = Some(spike);
    }

    /// Changes the gate command now, inside the period (MOE or an output enable written).
    pub fn set_command(&mut self, cmd: GateCommand) {
        self.cmd = cmd;
    }

    /// The gate command in force (before a break, [`Plant::hw_break`], opens the legs).
    pub fn gate_command(&self) -> GateCommand {
        self.cmd
    }

    pub fn set_brake(&mut self, on: bool) {
        self.brake_on = on;
    }

    /// TIM1_SR.B2IF (a comparator broke).
    pub fn break_flag(&self) -> bool {
        self.break_flag
    }

    /// Software clears B2IF: it stays set while the break input is active (RM0440).
    pub fn clear_break_flag(&mut self) {
        self.break_flag = self.break_input_active();
    }

    /// TIM1_SR.BIF (`STO_IN` broke).
    pub fn sto_flag(&self) -> bool {
        self.sto_flag
    }

    /// Software clears BIF: it stays set while `STO_IN` is low (RM0440).
    pub fn clear_sto_flag(&mut self) {
        self.sto_flag = self.sto_in_low;
    }

    /// A comparator is high: the break input is active.
    pub fn break_input_active(&self) -> bool {
        self.comparator_levels.0.iter().any(|l| *l)
    }

    /// `STO_IN` (safety.md 6, 11): low opens the inverter at once (BKIN, like the
    /// comparators' break, in the same PWM period) and sets BIF, and MOE cannot be set
    /// while it is low.
    pub fn set_sto_input(&mut self, low: bool) {
        self.sto_in_low = low;
        if low {
            self.hw_break = true;
            self.sto_flag = true;
        }
    }

    /// `STO_IN` is low (BKIN active).
    pub fn sto_in_low(&self) -> bool {
        self.sto_in_low
    }

    /// Software set MOE with both break inputs inactive: the legs follow the gates again.
    pub fn release_break(&mut self) {
        if !self.break_input_active() && !self.sto_in_low {
            self.hw_break = false;
        }
    }

    /// Comparator outputs now, as COMPx_CSR.VALUE reads.
    pub fn comparator_levels(&self) -> ComparatorLevels {
        self.comparator_levels
    }

    /// The comparators and their DAC values (as the drive core last set them).
    pub fn comparators(&self) -> &Comparators {
        &self.comparators
    }

    /// The drive wrote its threshold DACs (board profile and values from the core).
    pub fn set_comparators(&mut self, c: Comparators) {
        if c != self.comparators {
            self.coeffs = None;
        }
        self.comparators = c;
    }

    /// The break input has cleared MOE.
    pub fn hw_break(&self) -> bool {
        self.hw_break
    }

    pub fn brake_energy_j(&self) -> f64 {
        self.brake_energy_j
    }

    pub fn angle_rad(&self) -> f64 {
        self.angle_rad
    }

    /// Forces the electrical and mechanical state (tests).
    pub fn set_speed_rad_s(&mut self, w: f64) {
        self.x[WM] = w;
    }

    pub fn outputs(&self) -> PlantOutputs {
        let m = &self.params.motor;
        let (i_s, psi_s) = self.stator(&self.x);
        let i_abc = motor_to_legs(motor::inverse_clarke(i_s));
        let torque_nm = match self.params.load {
            Load::Motor => motor::torque_nm(m, psi_s, i_s),
            Load::Rl { .. } => 0.0,
        };
        PlantOutputs {
            i_abc_a: i_abc,
            u_dc_v: self.x[UDC],
            speed_rad_s: self.x[WM],
            torque_nm,
            brake_on: self.brake_on,
            hw_break: self.hw_break,
            duty_abc: self.period_avg.0,
            u_ab_v: self.period_avg.1,
        }
    }

    /// Whether the model has left physics: a state that is not a finite number, or a
    /// phase current, speed or DC-link voltage beyond [`DIVERGED`] (far beyond anything
    /// a rig of this class can reach, so only a diverging integration gets there).
    pub fn diverged(&self) -> bool {
        let o = self.outputs();
        let (i_a, w_rad_s, u_v) = DIVERGED;
        // NaN is beyond every limit.
        let beyond = |v: f64, limit: f64| v.is_nan() || v.abs() >= limit;
        self.x.iter().any(|v| !v.is_finite())
            || o.i_abc_a.iter().any(|&i| beyond(i, i_a))
            || beyond(o.speed_rad_s, w_rad_s)
            || beyond(o.u_dc_v, u_v)
    }

    /// What the drive's ADC converts now.
    pub fn adc_sample(&self) -> AdcSample {
        let o = self.outputs();
        let sc = &self.params.board.scaling;
        AdcSample {
            i_a_counts: sensors::current_counts(sc, o.i_abc_a[0]),
            i_b_counts: sensors::current_counts(sc, o.i_abc_a[1]),
            u_dc_counts: sensors::udc_counts(sc, o.u_dc_v),
        }
    }

    /// The stator flux while the stator is open: the one the rotor induces (motor), none
    /// (RL load).
    fn open_flux(&self, x: &State) -> [f64; 2] {
        match self.params.load {
            Load::Motor => {
                let m = &self.params.motor;
                let k = m.lm_h / m.lr_h();
                [k * x[PRA], k * x[PRB]]
            }
            Load::Rl { .. } => [0.0, 0.0],
        }
    }

    fn stator(&self, x: &State) -> ([f64; 2], [f64; 2]) {
        if let Load::Rl { l_h, .. } = self.params.load {
            // The RL load's flux is L i per phase (alpha-beta).
            if self.open {
                return ([0.0, 0.0], [0.0, 0.0]);
            }
            let l = l_h.max(1e-9);
            return ([x[PSA] / l, x[PSB] / l], [x[PSA], x[PSB]]);
        }
        if self.open {
            let m = &self.params.motor;
            let k = m.lm_h / m.lr_h();
            ([0.0, 0.0], [k * x[PRA], k * x[PRB]])
        } else {
            let f = motor::Fluxes {
                psi_s: [x[PSA], x[PSB]],
                psi_r: [x[PRA], x[PRB]],
            };
            (f.currents(&self.params.motor).i_s, f.psi_s)
        }
    }

    /// Advances the plant by `dt_ns` under the present command.
    pub fn advance(&mut self, dt_ns: u64) {
        let c = match self.coeffs {
            Some(c) => c,
            None => {
                let c = Coeffs::new(&self.params, self.lift, &self.comparators);
                self.coeffs = Some(c);
                c
            }
        };
        // The stator current after the last step (nothing else changes the state
        // between the steps of one advance).
        let mut i_s = None;
        let mut left = dt_ns;
        while left > 0 {
            let seg_end = match self.params.pwm_mode {
                PwmMode::Averaged => self.tau_ns.saturating_add(left),
                PwmMode::Switching => {
                    if self.tau_ns >= self.period_ns {
                        // No new period was started (should not happen): wrap the carrier.
                        self.tau_ns %= self.period_ns;
                    }
                    inverter::next_edge_ns(&self.cmd, self.tau_ns, self.period_ns)
                        .min(self.tau_ns.saturating_add(left))
                }
            };
            let seg_end = seg_end.min(self.next_sense_boundary(self.tau_ns));
            let seg = seg_end.saturating_sub(self.tau_ns).max(1).min(left);
            let conns = self.conns();
            let n = seg.div_ceil(MAX_STEP_NS);
            let mut done = 0;
            for k in 0..n {
                let step = (seg * (k + 1)) / n - (seg * k) / n;
                i_s = Some(self.step(&c, i_s, step, conns, self.tau_ns + done + step));
                done += step;
                if self.hw_break && conns.iter().any(|c| matches!(c, Conn::Frac(_))) {
                    // The break forces every leg off at once: finish the segment floating.
                    break;
                }
            }
            self.tau_ns = self.tau_ns.saturating_add(done);
            left -= done;
        }
    }

    /// The next instant after `tau_ns` at which what the comparators see changes by
    /// itself (a blanking-window or sense-spike edge), so that a step ends there.
    fn next_sense_boundary(&self, tau_ns: u64) -> u64 {
        let mid = self.period_ns / 2;
        let mut edges = [u64::MAX; 6];
        if self.blank_half_ns > 0 {
            edges[0] = mid.saturating_sub(self.blank_half_ns);
            edges[1] = mid + self.blank_half_ns;
        }
        if let Some(s) = self.spike {
            edges[2] = s.from_ns;
            edges[3] = s.to_ns;
        }
        if let Some(s) = self.udc_spike {
            edges[4] = s.from_ns;
            edges[5] = s.to_ns;
        }
        edges
            .into_iter()
            .filter(|e| *e > tau_ns)
            .min()
            .unwrap_or(u64::MAX)
    }

    fn conns(&self) -> [Conn; 3] {
        if self.hw_break || self.lift.is_some_and(|l| l.contactor_open) {
            return [Conn::Float; 3];
        }
        match self.params.pwm_mode {
            PwmMode::Averaged => self.cmd.legs.map(inverter::averaged_conn),
            PwmMode::Switching => self.cmd.legs.map(|l| {
                inverter::switching_conn(l, self.tau_ns, self.period_ns, self.cmd.dead_time_ns)
            }),
        }
    }

    /// One RK4 step of `dt_ns` with the legs connected as given, from the stator current
    /// `i_s_start` (the previous step's result, or `None`: computed from the state).
    /// Returns the stator current at the step's end.
    fn step(
        &mut self,
        c: &Coeffs,
        i_s_start: Option<[f64; 2]>,
        dt_ns: u64,
        conns: [Conn; 3],
        tau_end_ns: u64,
    ) -> [f64; 2] {
        let h = dt_ns as f64 * 1e-9;
        let all_float = conns.iter().all(|c| matches!(c, Conn::Float));
        let i_s = i_s_start.unwrap_or_else(|| self.stator(&self.x).0);
        let i_abc = motor_to_legs(motor::inverse_clarke(i_s));
        let contactor_open = self.lift.is_some_and(|l| l.contactor_open);
        // The holding brake at rest: it holds while the torques it must resist stay below
        // its own (lift.md 4.2), decided on the torques at the start of the step.
        let brake_holds = self.lift.is_some_and(|l| {
            l.brake_engaged
                && self.x[WM] == 0.0
                && (self.outputs().torque_nm + l.gravity_nm).abs() <= l.brake_torque_nm
        });
        if all_float {
            if !self.open && (contactor_open || i_abc.iter().all(|i| i.abs() < OPEN_CIRCUIT_A)) {
                self.open = true;
            }
        } else if self.open {
            // Leaving the open state: the stator flux is the one the rotor induces (is = 0).
            let [a, b] = self.open_flux(&self.x);
            self.x[PSA] = a;
            self.x[PSB] = b;
            self.open = false;
        }
        let fracs = [
            conns[0].frac(i_abc[0]),
            conns[1].frac(i_abc[1]),
            conns[2].frac(i_abc[2]),
        ];
        let v_unit = unit_voltage(fracs);
        let x0 = self.x;
        let k1 = self.deriv(c, &x0, v_unit);
        let k2 = self.deriv(c, &axpy(&x0, h / 2.0, &k1), v_unit);
        let k3 = self.deriv(c, &axpy(&x0, h / 2.0, &k2), v_unit);
        let k4 = self.deriv(c, &axpy(&x0, h, &k3), v_unit);
        for i in 0..6 {
            self.x[i] = x0[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        if self.lift.is_some_and(|l| l.brake_engaged)
            && (brake_holds || (x0[WM] != 0.0 && x0[WM].signum() != self.x[WM].signum()))
        {
            // The brake's friction stops the shaft instead of reversing it, and holds it.
            self.x[WM] = 0.0;
        }
        if all_float && !self.open {
            // Freewheeling through the diodes against the DC link can only shrink the
            // current. If the step made it grow, a phase has crossed zero and the diodes
            // chatter around it: they have stopped conducting.
            let (i_after, _) = self.stator(&self.x);
            let grew = i_after[0].hypot(i_after[1]) > i_s[0].hypot(i_s[1]);
            if grew && i_s[0].hypot(i_s[1]) < 10.0 * OPEN_CIRCUIT_A {
                self.open = true;
            }
        }
        if self.open {
            let [a, b] = self.open_flux(&self.x);
            self.x[PSA] = a;
            self.x[PSB] = b;
        }
        self.angle_rad += h * 0.5 * (x0[WM] + self.x[WM]);
        let u = 0.5 * (x0[UDC] + self.x[UDC]);
        let acc = &mut self.period_acc;
        for (a, f) in acc.0.iter_mut().zip(fracs) {
            *a += h * f;
        }
        acc.1 += h * (fracs[0] - fracs[1]) * u;
        acc.2 += h;
        if self.brake_on {
            let u = 0.5 * (x0[UDC] + self.x[UDC]);
            self.brake_energy_j += u * u / self.params.brake_resistor_ohm * h;
        }
        let (i_s_end, _) = self.stator(&self.x);
        let mut sensed = motor_to_legs(motor::inverse_clarke(i_s_end));
        if let Some(sp) = self.spike {
            if (sp.from_ns..=sp.to_ns).contains(&tau_end_ns) {
                if let Some(i) = sensed.get_mut(sp.phase) {
                    *i += sp.amps;
                }
            }
        }
        let mut u_sensed = self.x[UDC];
        if let Some(sp) = self.udc_spike {
            if (sp.from_ns..=sp.to_ns).contains(&tau_end_ns) {
                u_sensed += sp.volts;
            }
        }
        let mut levels = c.comparators.levels(sensed, u_sensed);
        if self.blanking_at(tau_end_ns) {
            // RM0440: a blanked comparator's output (and VALUE) is 0 during the window.
            for spec in self
                .comparators
                .board
                .comparators
                .iter()
                .filter(|c| c.blanked)
            {
                if let Some(l) = levels.0.get_mut(usize::from(spec.comp.saturating_sub(1))) {
                    *l = false;
                }
            }
        }
        self.comparator_levels = levels;
        // The comparators are ORed into the break input (active high, level-sensitive):
        // while one is high, MOE is cleared and BIF set.
        if self.break_input_active() {
            self.hw_break = true;
            self.break_flag = true;
        }
        if self.sto_in_low {
            self.hw_break = true;
            self.sto_flag = true;
        }
        i_s_end
    }

    /// The derivative of the state, with the motor's alpha-beta voltage `v_unit` per volt
    /// of DC link ([`unit_voltage`] of the legs' fractions).
    fn deriv(&self, c: &Coeffs, x: &State, v_unit: [f64; 2]) -> State {
        let p = &self.params;
        let m = &p.motor;
        let udc = x[UDC];
        let wr = c.pole_pairs * x[WM];
        let mut dx = [0.0; 6];
        let (te, i_dc_inv) = if let Load::Rl { r_ohm, .. } = p.load {
            if self.open {
                (0.0, 0.0)
            } else {
                let (i_s, _) = self.stator(x);
                dx[PSA] = udc * v_unit[0] - r_ohm * i_s[0];
                dx[PSB] = udc * v_unit[1] - r_ohm * i_s[1];
                (0.0, dc_current(v_unit, i_s))
            }
        } else if self.open {
            // is = 0: ir = ψr / Lr.
            dx[PRA] = -c.rr_per_lr * x[PRA] - wr * x[PRB];
            dx[PRB] = -c.rr_per_lr * x[PRB] + wr * x[PRA];
            (0.0, 0.0)
        } else {
            let (sa, sb, ra, rb) = (x[PSA], x[PSB], x[PRA], x[PRB]);
            let i_s = [
                c.lr_per_det * sa - c.lm_per_det * ra,
                c.lr_per_det * sb - c.lm_per_det * rb,
            ];
            let i_r = [
                c.ls_per_det * ra - c.lm_per_det * sa,
                c.ls_per_det * rb - c.lm_per_det * sb,
            ];
            dx[PSA] = udc * v_unit[0] - m.rs_ohm * i_s[0];
            dx[PSB] = udc * v_unit[1] - m.rs_ohm * i_s[1];
            dx[PRA] = -m.rr_ohm * i_r[0] - wr * rb;
            dx[PRB] = -m.rr_ohm * i_r[1] + wr * ra;
            let te = c.torque_per_flux_current * (sa * i_s[1] - sb * i_s[0]);
            (te, dc_current(v_unit, i_s))
        };
        let load_nm =
            m.load_torque_nm * (x[WM] * c.per_load_band).clamp(-1.0, 1.0) + m.friction_nms * x[WM];
        dx[WM] = if m.locked_rotor || matches!(p.load, Load::Rl { .. }) {
            0.0
        } else if let Some(l) = self.lift {
            // J dω/dt = T_e + T_g − T_load(ω) − B ω − T_b (lift.md 4.2).
            let drive = te + l.gravity_nm;
            let t_b = if !l.brake_engaged {
                0.0
            } else if x[WM] != 0.0 {
                l.brake_torque_nm * x[WM].signum()
            } else {
                drive.clamp(-l.brake_torque_nm, l.brake_torque_nm)
            };
            (drive - load_nm - t_b) * c.per_inertia
        } else {
            (te - load_nm) * c.per_inertia
        };
        let i_src = ((p.supply_v - udc) * c.per_supply_r).max(0.0);
        let i_brake = if self.brake_on {
            udc * c.per_brake_r
        } else {
            0.0
        };
        dx[UDC] = (i_src - i_dc_inv - i_brake) * c.per_capacitance;
        dx
    }
}

/// The rig's constants as the derivative uses them: ratios and reciprocals of the
/// parameters, computed when the parameters, the comparators' DAC values or the lift
/// change (each only between advances), so that RK4's four derivative evaluations per
/// step multiply instead of dividing. The model is the same; the last bits of the results differ from dividing
/// at every evaluation (rounding of the reciprocal, ~1e-16 relative).
#[derive(Debug, Clone, Copy)]
struct Coeffs {
    /// Stator and rotor currents from the fluxes: is = (Lr ψs − Lm ψr)/D,
    /// ir = (Ls ψr − Lm ψs)/D, D = Ls Lr − Lm².
    lr_per_det: f64,
    ls_per_det: f64,
    lm_per_det: f64,
    /// Rotor time constant's reciprocal, for the open stator (ir = ψr/Lr).
    rr_per_lr: f64,
    pole_pairs: f64,
    /// Te = 3/2 p (ψsα isβ − ψsβ isα).
    torque_per_flux_current: f64,
    per_load_band: f64,
    /// 1/J of the shaft (with the lift's reflected inertia).
    per_inertia: f64,
    per_supply_r: f64,
    per_brake_r: f64,
    per_capacitance: f64,
    comparators: ComparatorTable,
}

impl Coeffs {
    fn new(p: &RigParams, lift: Option<lift::LiftShaft>, comparators: &Comparators) -> Self {
        let m = &p.motor;
        let d = m.det_h2();
        let pp = f64::from(m.pole_pairs);
        Coeffs {
            lr_per_det: m.lr_h() / d,
            ls_per_det: m.ls_h() / d,
            lm_per_det: m.lm_h / d,
            rr_per_lr: m.rr_ohm / m.lr_h(),
            pole_pairs: pp,
            torque_per_flux_current: 1.5 * pp,
            per_load_band: 1.0 / m.load_band_rad_s.max(1e-9),
            per_inertia: 1.0 / (m.inertia_kgm2 + lift.map_or(0.0, |l| l.extra_inertia_kgm2)),
            per_supply_r: 1.0 / p.supply_r_ohm,
            per_brake_r: 1.0 / p.brake_resistor_ohm,
            per_capacitance: 1.0 / p.dc_capacitor_f,
            comparators: ComparatorTable::new(comparators),
        }
    }
}

/// The alpha-beta voltage of the motor terminals per volt of DC link, with the inverter
/// legs at the fractions `fracs` of the link (constant over a step).
fn unit_voltage(fracs: [f64; 3]) -> [f64; 2] {
    motor::clarke(legs_to_motor(fracs))
}

/// The inverter's DC-link current: the power the legs deliver, 3/2 (vα iα + vβ iβ), per
/// volt of DC link (equal to Σ fraction × leg current for a star point that floats).
fn dc_current(v_unit: [f64; 2], i_s: [f64; 2]) -> f64 {
    1.5 * (v_unit[0] * i_s[0] + v_unit[1] * i_s[1])
}

fn axpy(x: &State, a: f64, k: &State) -> State {
    let mut y = *x;
    for i in 0..6 {
        y[i] += a * k[i];
    }
    y
}

#[cfg(test)]
mod tests;
