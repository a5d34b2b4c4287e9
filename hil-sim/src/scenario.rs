//! Scenario files (hil-sim.md "Scenario file"): rig overrides, link settings and timed
//! events. Parsing is strict: an unknown key, a wrong type or an out-of-range value is an
//! error that names the key, so a typo never silently simulates something else.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::Deserialize;

use shared_protocol::program::DIGITAL_INPUTS;

use crate::plant::lift::{
    LiftEvent, LiftParams, Vane, CAR_CALL_INPUTS, CHAIN_INPUT, DOOR_CLOSED_INPUT, HALL_INPUTS,
    LOAD_ANALOG, VANE_L_INPUT, VANE_R_INPUT,
};
use crate::plant::{Load, PwmMode, RigParams};

pub mod physics;
pub mod silicon;
use silicon::{EventSiliconKeys, McuSide, SiliconEvent, SiliconKeys, SiliconParams};

/// Duration when neither `--duration` nor the scenario gives one.
pub const DEFAULT_DURATION_S: f64 = 10.0;
/// How long `press` holds an input when the event has no `hold_s`.
pub const DEFAULT_HOLD_S: f64 = 0.1;
/// Spacing of the keys of a `keys` event.
pub const KEY_SPACING_S: f64 = 0.1;
/// How long a key is held down.
pub const KEY_HOLD_S: f64 = 0.05;

/// A scenario file as written.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    pub duration_s: Option<f64>,
    #[serde(default)]
    pub plant: PlantKeys,
    #[serde(default)]
    pub link: LinkKeys,
    /// `[lift]` (lift.md 4): attaches the lift to the motor shaft.
    pub lift: Option<LiftKeys>,
    #[serde(default, rename = "event")]
    pub events: Vec<EventKeys>,
    #[serde(default)]
    pub service: ServiceKeys,
    /// `[analog]`: the emulated MCU's analog errors (`hil-sim emu` only).
    #[serde(default)]
    pub analog: AnalogKeys,
    #[serde(default)]
    pub emu: EmuKeys,
    /// `[silicon]`: tolerances of the emulated MCUs (`hil-sim emu` only).
    #[serde(default)]
    pub silicon: SiliconKeys,
}

/// `[analog]`: the drive MCU's analog errors in `hil-sim emu` (g431-emu `docs/models.md`
/// "Analog errors"): start from `part`, then each key overrides one figure.
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AnalogKeys {
    /// The part the figures start from (default `typical`).
    pub part: Option<AnalogPart>,
    /// COMP1-4 input offset, volts (INP must pass INM + offset).
    pub comp_offset_v: Option<f64>,
    /// COMP1-4 propagation delay, ns.
    pub comp_delay_ns: Option<f64>,
    /// DAC1/DAC3 output offset error, volts.
    pub dac_offset_v: Option<f64>,
    /// OPAMP1-3 input offset voltage, volts.
    pub opamp_offset_v: Option<f64>,
}

/// `[analog] part`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AnalogPart {
    /// The datasheet's typical figures (the default).
    Typical,
    /// No offsets, no comparator delay.
    Ideal,
    /// The datasheet's limits, every offset positive, the slowest comparator.
    WorstHigh,
    /// The datasheet's limits, every offset negative, the slowest comparator.
    WorstLow,
}

/// The largest offset a scenario may set (volts): ten times the datasheet limits.
const MAX_OFFSET_V: f64 = 0.2;
/// The longest comparator delay a scenario may set (ns).
const MAX_COMP_DELAY_NS: f64 = 1.0e6;

impl AnalogKeys {
    /// The keys, each checked against its range. Which figures the part and the keys give
    /// is the emulator's business (`emu::analog`): the parser needs none of its data.
    fn checked(self) -> Result<AnalogKeys> {
        for (name, val) in [
            ("analog.comp_offset_v", self.comp_offset_v),
            ("analog.dac_offset_v", self.dac_offset_v),
            ("analog.opamp_offset_v", self.opamp_offset_v),
        ] {
            if let Some(v) = val {
                if !v.is_finite() || v.abs() > MAX_OFFSET_V {
                    bail!("{name} must be within +-{MAX_OFFSET_V} V, got {v}");
                }
            }
        }
        if let Some(v) = non_negative("analog.comp_delay_ns", self.comp_delay_ns)? {
            if v > MAX_COMP_DELAY_NS {
                bail!("analog.comp_delay_ns must be at most {MAX_COMP_DELAY_NS}, got {v}");
            }
        }
        Ok(self)
    }
}

/// `[emu]`: what `hil-sim emu` (the real images in the emulator) must know; `run` ignores
/// it.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EmuKeys {
    /// What the scenario makes an image do on purpose: without it, `emu` exits with
    /// status 2 when an image takes a HardFault, locks up or is reset by its watchdog or
    /// by itself (a panic), and an emulator test fails.
    #[serde(default)]
    pub expect: Vec<ImageTrouble>,
    /// What the bare ESC1's amplifier input pins carry: `documented` (the default: the
    /// board's network) or `as_image_assumes` (what an earlier image assumed, not
    /// the board: a what-if, `docs/cli.md`).
    #[serde(default)]
    pub esc1_amplifier_inputs: Esc1Sense,
}

/// What the bare ESC1's amplifier input pins carry in `hil-sim emu` (scenario key
/// `[emu] esc1_amplifier_inputs`, `hil-sim/docs/cli.md`; the voltages are `emu::boards`').
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Esc1Sense {
    /// The board's documented network (`g431_emu::boards::b_g431b_esc1`): both amplifier
    /// pins of each leg at the network's bias.
    #[default]
    Documented,
    /// The voltages the drive image once assumed (0.103 V at 0 A on VINP,
    /// -1.714 mV/A, VINM0 pins at 0 V): **not the board**. A what-if only: the emulator
    /// tests ran on it while the image's amplifier mode was wrong for the documented board
    ///; since the fix they run on the documented network.
    AsImageAssumes,
}

/// What can go wrong with an image as a whole (`[emu] expect`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageTrouble {
    /// An exception escalated to HardFault.
    HardFault,
    /// The core locked up (a fault at HardFault priority).
    Lockup,
    /// The independent watchdog reset the MCU.
    WatchdogReset,
    /// The image reset itself (AIRCR.SYSRESETREQ: the end of its panic and fault
    /// handlers).
    SoftwareReset,
    /// BOOT0 was high at reset: the ROM bootloader ran instead of the image.
    BootRom,
    /// An instruction the emulator cannot execute.
    Unsupported,
}

impl ImageTrouble {
    /// The key as written in `[emu] expect`.
    pub fn key(self) -> &'static str {
        match self {
            ImageTrouble::HardFault => "hard_fault",
            ImageTrouble::Lockup => "lockup",
            ImageTrouble::WatchdogReset => "watchdog_reset",
            ImageTrouble::SoftwareReset => "software_reset",
            ImageTrouble::BootRom => "boot_rom",
            ImageTrouble::Unsupported => "unsupported",
        }
    }
}

/// `[service]`: the service port's test options (service.md 9).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceKeys {
    /// Seeded random bytes into the PLC's service receiver at line rate for the whole
    /// run (with `--service-pty` or the library's `service::Attached`).
    #[serde(default)]
    pub flood: bool,
}

/// `[lift]`: every key optional (lift.md 4.1).
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LiftKeys {
    pub floors: Option<u8>,
    pub floor_pitch_mm: Option<f64>,
    pub gear_ratio: Option<f64>,
    pub sprocket_d_mm: Option<f64>,
    pub unbalance_kg: Option<f64>,
    pub moving_mass_kg: Option<f64>,
    pub start_mm: Option<f64>,
    pub vane_long_mm: Option<f64>,
    pub vane_short_mm: Option<f64>,
    pub floor1_swapped: Option<bool>,
    pub door_stroke_s: Option<f64>,
    pub brake_delay_ms: Option<f64>,
    pub brake_torque_nm: Option<f64>,
    pub limit_low_mm: Option<f64>,
    pub limit_high_mm: Option<f64>,
    pub load_kg: Option<f64>,
    pub load_scale_kg: Option<f64>,
}

impl LiftKeys {
    fn params(&self) -> Result<LiftParams> {
        let mut p = LiftParams::default();
        if let Some(n) = self.floors {
            if !(2..=8).contains(&n) {
                bail!("lift.floors must be 2..=8, got {n}");
            }
            p.floors = n;
        }
        for (name, val, slot) in [
            (
                "lift.floor_pitch_mm",
                self.floor_pitch_mm,
                &mut p.floor_pitch_mm,
            ),
            ("lift.gear_ratio", self.gear_ratio, &mut p.gear_ratio),
            (
                "lift.sprocket_d_mm",
                self.sprocket_d_mm,
                &mut p.sprocket_d_mm,
            ),
            (
                "lift.moving_mass_kg",
                self.moving_mass_kg,
                &mut p.moving_mass_kg,
            ),
            ("lift.vane_long_mm", self.vane_long_mm, &mut p.vane_long_mm),
            (
                "lift.vane_short_mm",
                self.vane_short_mm,
                &mut p.vane_short_mm,
            ),
            (
                "lift.door_stroke_s",
                self.door_stroke_s,
                &mut p.door_stroke_s,
            ),
            (
                "lift.load_scale_kg",
                self.load_scale_kg,
                &mut p.load_scale_kg,
            ),
        ] {
            if let Some(v) = positive(name, val)? {
                *slot = v;
            }
        }
        for (name, val, slot) in [
            (
                "lift.brake_delay_ms",
                self.brake_delay_ms,
                &mut p.brake_delay_ms,
            ),
            (
                "lift.brake_torque_nm",
                self.brake_torque_nm,
                &mut p.brake_torque_nm,
            ),
            ("lift.load_kg", self.load_kg, &mut p.load_kg),
        ] {
            if let Some(v) = non_negative(name, val)? {
                *slot = v;
            }
        }
        for (name, val, slot) in [
            ("lift.unbalance_kg", self.unbalance_kg, &mut p.unbalance_kg),
            ("lift.start_mm", self.start_mm, &mut p.start_mm),
            ("lift.limit_low_mm", self.limit_low_mm, &mut p.limit_low_mm),
        ] {
            if let Some(v) = val {
                if !v.is_finite() {
                    bail!("{name} must be a number, got {v}");
                }
                *slot = v;
            }
        }
        if let Some(v) = self.limit_high_mm {
            p.limit_high_mm = Some(v);
        }
        if let Some(v) = self.floor1_swapped {
            p.floor1_swapped = v;
        }
        if p.vane_short_mm > p.vane_long_mm {
            bail!("lift.vane_short_mm must not exceed lift.vane_long_mm");
        }
        if p.limit_low_mm >= p.limit_high_mm() {
            bail!("lift.limit_low_mm must be below lift.limit_high_mm");
        }
        Ok(p)
    }
}

/// `[plant]`: every key optional; absent keys keep the default rig.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlantKeys {
    pub dc_link_v: Option<f64>,
    pub load_torque_nm: Option<f64>,
    pub inertia_kgm2: Option<f64>,
    pub oc_hw_a: Option<f64>,
    pub ov_hw_v: Option<f64>,
    pub dc_capacitor_uf: Option<f64>,
    pub brake_resistor_ohm: Option<f64>,
    pub scan_time_ms: Option<f64>,
    pub pwm_mode: Option<PwmMode>,
    // Additions (hil-sim docs): the rest of the rig.
    /// `"motor"` (default) or `"rl"`: a star RL load instead of the motor.
    pub load: Option<LoadKind>,
    /// `"esc1"` (default: the bare B-G431B-ESC1's shunts, PGA and divider, and its
    /// comparators: the board the default drive image is built for) or `"source"` (the
    /// source's sensors, +-10 A and 0-45 V, the image's `source-sensors` build).
    pub board: Option<BoardKind>,
    pub load_r_ohm: Option<f64>,
    pub load_l_h: Option<f64>,
    pub supply_r_ohm: Option<f64>,
    pub locked_rotor: Option<bool>,
    pub friction_nms: Option<f64>,
    pub rs_ohm: Option<f64>,
    pub rr_ohm: Option<f64>,
    pub lls_h: Option<f64>,
    pub llr_h: Option<f64>,
    pub lm_h: Option<f64>,
}

/// `[plant] load`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LoadKind {
    Motor,
    Rl,
}

/// `[plant] board`: the drive board's analog front end and comparators.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BoardKind {
    Source,
    Esc1,
}

impl BoardKind {
    /// The cores' scaling and comparators that `hil-sim run` uses for this board (`emu`
    /// takes the kind from the drive image's board, `emu::boards::board_kind`).
    pub fn profile(self) -> &'static firmware_drive::comparators::BoardProfile {
        match self {
            BoardKind::Source => &firmware_drive::comparators::SOURCE_SENSORS,
            BoardKind::Esc1 => &firmware_drive::comparators::B_G431B_ESC1,
        }
    }
}

/// `[link]`.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LinkKeys {
    pub baud: Option<u32>,
    pub bit_error_rate: Option<f64>,
    pub cut_at_s: Option<f64>,
}

/// One `[[event]]` as written.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EventKeys {
    pub at_s: f64,
    pub set: Option<BTreeMap<String, i64>>,
    pub press: Option<String>,
    pub hold_s: Option<f64>,
    pub keys: Option<String>,
    // Plant parameters changed at run time.
    pub dc_link_v: Option<f64>,
    pub load_torque_nm: Option<f64>,
    pub inertia_kgm2: Option<f64>,
    pub oc_hw_a: Option<f64>,
    pub ov_hw_v: Option<f64>,
    pub brake_resistor_ohm: Option<f64>,
    pub locked_rotor: Option<bool>,
    // The lift (lift.md 4.3; need `[lift]`).
    /// Press the car button of this floor (1-4) for `hold_s`.
    pub call: Option<u8>,
    /// Press a hall button: `1u`, `2u`, `2d`, `3u`, `3d`, `4d`.
    pub hall: Option<String>,
    pub load_kg: Option<f64>,
    pub door_block: Option<bool>,
    /// `"L"`, `"R"` or `"none"`.
    pub vane_fail: Option<String>,
    // Faults of the silicon (`hil-sim emu` only; `silicon`).
    /// Which MCU the silicon keys act on: `"drive"` (default) or `"plc"`.
    pub mcu: Option<String>,
    /// The MCU's supply voltage from now on, V (its PVD watches it).
    pub vdd_v: Option<f64>,
    /// An SRAM parity error is detected now.
    pub sram_parity_error: Option<bool>,
    /// A flash double ECC error is detected now.
    pub flash_ecc_error: Option<bool>,
    /// `"nack"`, `"stretch"`, `"arbitration_loss"` or `"bus_error"` on the PLC's I2C bus, in
    /// the next write to `i2c_address`.
    pub i2c_fault: Option<String>,
    /// The device the I2C fault hits (default 0x50, the EEPROM).
    pub i2c_address: Option<u8>,
    /// How long the device holds SCL low (`i2c_fault = "stretch"`), ms.
    pub i2c_stretch_ms: Option<f64>,
}

/// An input the scenario can set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Input {
    /// D00..D15.
    Digital(u8),
    /// A00..A03, 10-bit counts.
    Analog(u8),
    /// The drive's auxiliary channel (`COM`), 10-bit counts.
    Aux,
    /// The drive board's `STO_IN` (safety.md 11): 1 = high (default), 0 = STO requested.
    StoIn,
}

impl Input {
    pub fn parse(name: &str) -> Option<Input> {
        let upper = name.to_ascii_uppercase();
        if upper == "AUX" {
            return Some(Input::Aux);
        }
        if upper == "STO_IN" {
            return Some(Input::StoIn);
        }
        let (area, digits) = upper.split_at_checked(1)?;
        if digits.len() != 2 || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        let n: u8 = digits.parse().ok()?;
        match area {
            "D" if n < DIGITAL_INPUTS => Some(Input::Digital(n)),
            "A" if n < 4 => Some(Input::Analog(n)),
            _ => None,
        }
    }

    fn max(self) -> i64 {
        match self {
            Input::Digital(_) | Input::StoIn => 1,
            Input::Analog(_) | Input::Aux => 1023,
        }
    }
}

/// A plant parameter changed at run time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlantChange {
    DcLinkV(f64),
    LoadTorqueNm(f64),
    InertiaKgm2(f64),
    BrakeResistorOhm(f64),
    LockedRotor(bool),
}

impl PlantChange {
    pub fn apply(&self, rig: &mut RigParams) {
        match *self {
            PlantChange::DcLinkV(v) => rig.supply_v = v,
            PlantChange::LoadTorqueNm(v) => rig.motor.load_torque_nm = v,
            PlantChange::InertiaKgm2(v) => rig.motor.inertia_kgm2 = v,
            PlantChange::BrakeResistorOhm(v) => rig.brake_resistor_ohm = v,
            PlantChange::LockedRotor(v) => rig.motor.locked_rotor = v,
        }
    }
}

/// What happens at one instant (events are expanded: a press becomes a set and a release,
/// a key string becomes key-downs and key-ups).
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Set(Input, u16),
    KeyDown(char),
    KeyUp(char),
    Plant(PlantChange),
    Lift(LiftEvent),
    /// A fault of one MCU's silicon (`hil-sim emu` only).
    Silicon(McuSide, SiliconEvent),
}

/// A scheduled action in virtual time.
#[derive(Debug, Clone, PartialEq)]
pub struct TimedAction {
    pub at_ns: u64,
    pub action: Action,
}

/// A validated scenario, ready to simulate.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub duration_s: Option<f64>,
    pub rig: RigParams,
    pub scan_time_ns: u64,
    pub baud: u32,
    pub bit_error_rate: f64,
    /// When the UART wires are cut (never: `u64::MAX`).
    pub cut_at_ns: u64,
    /// Sorted by time; equal times keep file order.
    pub actions: Vec<TimedAction>,
    /// The scenario types the RUN key (`A`, firmware-plc/docs/keymap.md): then RUN is
    /// left to the keys instead of starting at power-up.
    pub keys_start_run: bool,
    /// `[lift]`: the lift on the shaft.
    pub lift: Option<LiftParams>,
    /// `[service] flood = true`.
    pub service_flood: bool,
    /// `[analog]`: the drive MCU's analog errors in the emulator, checked (the figures:
    /// `emu::analog`).
    pub analog: AnalogKeys,
    /// `[emu] expect`: image troubles the scenario provokes on purpose.
    pub expected_trouble: Vec<ImageTrouble>,
    /// `[emu] esc1_amplifier_inputs`.
    pub esc1_amplifier_inputs: Esc1Sense,
    /// `[silicon]`.
    pub silicon: SiliconParams,
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            duration_s: None,
            rig: RigParams::default(),
            scan_time_ns: 1_000_000,
            baud: 115_200,
            bit_error_rate: 0.0,
            cut_at_ns: u64::MAX,
            actions: Vec::new(),
            keys_start_run: false,
            lift: None,
            service_flood: false,
            analog: AnalogKeys::default(),
            expected_trouble: Vec::new(),
            esc1_amplifier_inputs: Esc1Sense::Documented,
            silicon: SiliconParams::default(),
        }
    }
}

/// The keypad's RUN / STOP key.
pub const RUN_KEY: char = 'A';

/// Keys of the 4 x 4 keypad (panel.md).
pub const KEYPAD_KEYS: &str = "0123456789ABCD*#";

fn secs_to_ns(s: f64) -> u64 {
    (s * 1e9).round() as u64
}

fn positive(name: &str, v: Option<f64>) -> Result<Option<f64>> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => {
            bail!("{name} must be a positive number, got {x}")
        }
        _ => Ok(v),
    }
}

fn non_negative(name: &str, v: Option<f64>) -> Result<Option<f64>> {
    match v {
        Some(x) if !(x.is_finite() && x >= 0.0) => bail!("{name} must be >= 0, got {x}"),
        _ => Ok(v),
    }
}

impl Scenario {
    pub fn load(path: &Path) -> Result<Scenario> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read scenario {}", path.display()))?;
        Scenario::parse(&text).with_context(|| format!("invalid scenario {}", path.display()))
    }

    pub fn parse(text: &str) -> Result<Scenario> {
        let file: ScenarioFile = toml::from_str(text)?;
        Scenario::from_file(file)
    }

    pub fn from_file(f: ScenarioFile) -> Result<Scenario> {
        let mut s = Scenario {
            duration_s: positive("duration_s", f.duration_s)?,
            service_flood: f.service.flood,
            analog: f.analog.checked()?,
            expected_trouble: f.emu.expect.clone(),
            esc1_amplifier_inputs: f.emu.esc1_amplifier_inputs,
            ..Scenario::default()
        };
        let p = &f.plant;
        for (key, v) in [
            ("dc_link_v", p.dc_link_v),
            ("load_torque_nm", p.load_torque_nm),
            ("inertia_kgm2", p.inertia_kgm2),
            ("oc_hw_a", p.oc_hw_a),
            ("ov_hw_v", p.ov_hw_v),
            ("dc_capacitor_uf", p.dc_capacitor_uf),
            ("brake_resistor_ohm", p.brake_resistor_ohm),
            ("supply_r_ohm", p.supply_r_ohm),
            ("friction_nms", p.friction_nms),
            ("rs_ohm", p.rs_ohm),
            ("rr_ohm", p.rr_ohm),
            ("lls_h", p.lls_h),
            ("llr_h", p.llr_h),
            ("lm_h", p.lm_h),
            ("load_r_ohm", p.load_r_ohm),
            ("load_l_h", p.load_l_h),
        ] {
            physics::check(physics::PLANT_RANGES, "plant", key, v)?;
        }
        if let Some(l) = &f.lift {
            for (key, v) in [
                ("unbalance_kg", l.unbalance_kg),
                ("load_kg", l.load_kg),
                ("moving_mass_kg", l.moving_mass_kg),
                ("start_mm", l.start_mm),
                ("limit_low_mm", l.limit_low_mm),
                ("limit_high_mm", l.limit_high_mm),
                ("floor_pitch_mm", l.floor_pitch_mm),
            ] {
                physics::check(physics::LIFT_RANGES, "lift", key, v)?;
            }
        }
        let rig = &mut s.rig;
        if let Some(v) = non_negative("plant.dc_link_v", p.dc_link_v)? {
            rig.supply_v = v;
        }
        if let Some(v) = non_negative("plant.load_torque_nm", p.load_torque_nm)? {
            rig.motor.load_torque_nm = v;
        }
        if let Some(v) = positive("plant.inertia_kgm2", p.inertia_kgm2)? {
            rig.motor.inertia_kgm2 = v;
        }
        if let Some(b) = p.board {
            rig.board = b.profile();
        }
        if let Some(v) = positive("plant.oc_hw_a", p.oc_hw_a)? {
            rig.hw_defaults.oc_hw_a = v;
        }
        if let Some(v) = positive("plant.ov_hw_v", p.ov_hw_v)? {
            rig.hw_defaults.ov_hw_v = v;
        }
        if let Some(v) = positive("plant.dc_capacitor_uf", p.dc_capacitor_uf)? {
            rig.dc_capacitor_f = v * 1e-6;
        }
        if let Some(v) = positive("plant.brake_resistor_ohm", p.brake_resistor_ohm)? {
            rig.brake_resistor_ohm = v;
        }
        if let Some(v) = positive("plant.supply_r_ohm", p.supply_r_ohm)? {
            rig.supply_r_ohm = v;
        }
        if let Some(v) = non_negative("plant.friction_nms", p.friction_nms)? {
            rig.motor.friction_nms = v;
        }
        for (name, val, slot) in [
            ("plant.rs_ohm", p.rs_ohm, &mut rig.motor.rs_ohm),
            ("plant.rr_ohm", p.rr_ohm, &mut rig.motor.rr_ohm),
            ("plant.lls_h", p.lls_h, &mut rig.motor.lls_h),
            ("plant.llr_h", p.llr_h, &mut rig.motor.llr_h),
            ("plant.lm_h", p.lm_h, &mut rig.motor.lm_h),
        ] {
            if let Some(v) = positive(name, val)? {
                *slot = v;
            }
        }
        if let Some(v) = p.locked_rotor {
            rig.motor.locked_rotor = v;
        }
        if let Some(m) = p.pwm_mode {
            rig.pwm_mode = m;
        }
        let r = positive("plant.load_r_ohm", p.load_r_ohm)?;
        let l = positive("plant.load_l_h", p.load_l_h)?;
        match p.load {
            Some(LoadKind::Rl) => {
                rig.load = Load::Rl {
                    r_ohm: r.unwrap_or(Load::RL_R_OHM),
                    l_h: l.unwrap_or(Load::RL_L_H),
                };
            }
            _ if r.is_some() || l.is_some() => {
                bail!("plant.load_r_ohm / load_l_h need plant.load = \"rl\"")
            }
            _ => {}
        }
        if let Some(v) = positive("plant.scan_time_ms", p.scan_time_ms)? {
            if v > 1000.0 {
                bail!("plant.scan_time_ms must be at most 1000, got {v}");
            }
            s.scan_time_ns = secs_to_ns(v * 1e-3).max(1);
        }
        let l = &f.link;
        if let Some(b) = l.baud {
            if !(1200..=10_000_000).contains(&b) {
                bail!("link.baud must be 1200..10000000, got {b}");
            }
            s.baud = b;
        }
        if let Some(r) = l.bit_error_rate {
            if !(0.0..=0.5).contains(&r) {
                bail!("link.bit_error_rate must be 0..0.5, got {r}");
            }
            s.bit_error_rate = r;
        }
        if let Some(c) = non_negative("link.cut_at_s", l.cut_at_s)? {
            s.cut_at_ns = if c >= 1e9 { u64::MAX } else { secs_to_ns(c) };
        }
        if let Some(l) = &f.lift {
            s.lift = Some(l.params()?);
        }
        s.silicon = f.silicon.params()?;
        for (n, e) in f.events.iter().enumerate() {
            s.add_event(e)
                .with_context(|| format!("event {} (at_s = {})", n + 1, e.at_s))?;
        }
        s.actions.sort_by_key(|a| a.at_ns);
        Ok(s)
    }

    fn push(&mut self, at_s: f64, action: Action) {
        self.actions.push(TimedAction {
            at_ns: secs_to_ns(at_s),
            action,
        });
    }

    fn add_event(&mut self, e: &EventKeys) -> Result<()> {
        if !(e.at_s.is_finite() && e.at_s >= 0.0) {
            bail!("at_s must be >= 0");
        }
        if e.oc_hw_a.is_some() || e.ov_hw_v.is_some() {
            bail!(
                "oc_hw_a / ov_hw_v cannot change at run time: the hardware thresholds are drive \
                 settings now (I>> and U>> in the program, written to the comparator DACs at \
                 download; [plant] oc_hw_a / ov_hw_v are the board's defaults)"
            );
        }
        let mut any = self.add_lift_event(e)?;
        if let Some(set) = &e.set {
            for (name, &v) in set {
                let input = Input::parse(name).with_context(|| {
                    format!(
                        "set: unknown input {name:?} (D00-D{:02}, A00-A03, AUX)",
                        DIGITAL_INPUTS - 1
                    )
                })?;
                if !(0..=input.max()).contains(&v) {
                    bail!("set: {name} = {v} out of range 0..{}", input.max());
                }
                self.check_not_lift_driven(name, input)?;
                self.push(e.at_s, Action::Set(input, v as u16));
                any = true;
            }
        }
        if let Some(name) = &e.press {
            let Some(input @ Input::Digital(_)) = Input::parse(name) else {
                bail!(
                    "press: {name:?} is not a digital input (D00-D{:02})",
                    DIGITAL_INPUTS - 1
                );
            };
            self.check_not_lift_driven(name, input)?;
            let hold = e.hold_s.unwrap_or(DEFAULT_HOLD_S);
            if !(hold.is_finite() && hold > 0.0) {
                bail!("hold_s must be > 0");
            }
            self.push(e.at_s, Action::Set(input, 1));
            self.push(e.at_s + hold, Action::Set(input, 0));
            any = true;
        } else if e.hold_s.is_some() && e.call.is_none() && e.hall.is_none() {
            bail!("hold_s without press");
        }
        if let Some(keys) = &e.keys {
            for (i, c) in keys.chars().filter(|c| !c.is_whitespace()).enumerate() {
                let k = c.to_ascii_uppercase();
                if !KEYPAD_KEYS.contains(k) {
                    bail!("keys: {c:?} is not a keypad key ({KEYPAD_KEYS})");
                }
                let t = e.at_s + i as f64 * KEY_SPACING_S;
                self.push(t, Action::KeyDown(k));
                self.push(t + KEY_HOLD_S, Action::KeyUp(k));
                if k == RUN_KEY {
                    self.keys_start_run = true;
                }
            }
            any = true;
        }
        for (key, v) in [
            ("dc_link_v", e.dc_link_v),
            ("load_torque_nm", e.load_torque_nm),
            ("inertia_kgm2", e.inertia_kgm2),
            ("brake_resistor_ohm", e.brake_resistor_ohm),
        ] {
            physics::check(physics::PLANT_RANGES, "event", key, v)?;
        }
        let changes = [
            non_negative("dc_link_v", e.dc_link_v)?.map(PlantChange::DcLinkV),
            non_negative("load_torque_nm", e.load_torque_nm)?.map(PlantChange::LoadTorqueNm),
            positive("inertia_kgm2", e.inertia_kgm2)?.map(PlantChange::InertiaKgm2),
            positive("brake_resistor_ohm", e.brake_resistor_ohm)?
                .map(PlantChange::BrakeResistorOhm),
            e.locked_rotor.map(PlantChange::LockedRotor),
        ];
        for c in changes.into_iter().flatten() {
            self.push(e.at_s, Action::Plant(c));
            any = true;
        }
        let silicon = EventSiliconKeys {
            mcu: e.mcu.as_deref(),
            vdd_v: e.vdd_v,
            sram_parity_error: e.sram_parity_error,
            flash_ecc_error: e.flash_ecc_error,
            i2c_fault: e.i2c_fault.as_deref(),
            i2c_address: e.i2c_address,
            i2c_stretch_ms: e.i2c_stretch_ms,
        };
        for (side, ev) in silicon.events()? {
            self.push(e.at_s, Action::Silicon(side, ev));
            any = true;
        }
        if !any {
            bail!(
                "the event does nothing (give set, press, keys, a plant parameter or a silicon \
                 fault)"
            );
        }
        Ok(())
    }

    /// With `[lift]` the plant drives D10, D11, D12, D15 and A00 (lift.md 4.3).
    fn check_not_lift_driven(&self, name: &str, input: Input) -> Result<()> {
        if self.lift.is_none() {
            return Ok(());
        }
        let driven = match input {
            Input::Digital(n) => {
                [VANE_L_INPUT, VANE_R_INPUT, DOOR_CLOSED_INPUT, CHAIN_INPUT].contains(&n)
            }
            Input::Analog(n) => n == LOAD_ANALOG,
            _ => false,
        };
        if driven {
            bail!("{name} is driven by the [lift] plant (vanes, door, safety chain, load sensor)");
        }
        Ok(())
    }

    /// The lift's events (`call`, `hall`, `load_kg`, `door_block`, `vane_fail`); whether
    /// the event had one.
    fn add_lift_event(&mut self, e: &EventKeys) -> Result<bool> {
        let any = e.call.is_some()
            || e.hall.is_some()
            || e.load_kg.is_some()
            || e.door_block.is_some()
            || e.vane_fail.is_some();
        if !any {
            return Ok(false);
        }
        if self.lift.is_none() {
            bail!("call / hall / load_kg / door_block / vane_fail need a [lift] table");
        }
        if e.press.is_some() && (e.call.is_some() || e.hall.is_some()) {
            bail!("one button per event: press, call or hall");
        }
        let hold = e.hold_s.unwrap_or(DEFAULT_HOLD_S);
        if !(hold.is_finite() && hold > 0.0) {
            bail!("hold_s must be > 0");
        }
        let mut buttons = Vec::new();
        if let Some(f) = e.call {
            let Some(&n) = CAR_CALL_INPUTS.get(usize::from(f.wrapping_sub(1))) else {
                bail!("call = {f}: the car has buttons for floors 1-4 (D00-D03)");
            };
            buttons.push(n);
        }
        if let Some(h) = &e.hall {
            let Some(&(_, n)) = HALL_INPUTS.iter().find(|(name, _)| name == h) else {
                bail!("hall = {h:?}: the hall buttons are 1u, 2u, 2d, 3u, 3d, 4d");
            };
            buttons.push(n);
        }
        for n in buttons {
            self.push(e.at_s, Action::Set(Input::Digital(n), 1));
            self.push(e.at_s + hold, Action::Set(Input::Digital(n), 0));
        }
        if let Some(kg) = non_negative("load_kg", e.load_kg)? {
            self.push(e.at_s, Action::Lift(LiftEvent::LoadKg(kg)));
        }
        if let Some(b) = e.door_block {
            self.push(e.at_s, Action::Lift(LiftEvent::DoorBlock(b)));
        }
        if let Some(v) = &e.vane_fail {
            let vane = match v.as_str() {
                "L" => Some(Vane::Left),
                "R" => Some(Vane::Right),
                "none" => None,
                _ => bail!("vane_fail = {v:?}: \"L\", \"R\" or \"none\""),
            };
            self.push(e.at_s, Action::Lift(LiftEvent::VaneFail(vane)));
        }
        Ok(true)
    }

    /// The run length: `--duration`, else the scenario's, else [`DEFAULT_DURATION_S`].
    pub fn duration_s(&self, cli: Option<f64>) -> f64 {
        cli.or(self.duration_s).unwrap_or(DEFAULT_DURATION_S)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn analog_keys_are_kept_as_written_and_each_checked_against_its_range() {
        assert_eq!(
            Scenario::parse("").expect("empty").analog,
            AnalogKeys::default()
        );
        let s = Scenario::parse("[analog]\npart = \"worst_low\"\ncomp_offset_v = 0.004\n")
            .expect("parses");
        assert_eq!(
            s.analog,
            AnalogKeys {
                part: Some(AnalogPart::WorstLow),
                comp_offset_v: Some(0.004),
                ..AnalogKeys::default()
            }
        );
        let s =
            Scenario::parse("[analog]\npart = \"ideal\"\ncomp_delay_ns = 50.0\n").expect("parses");
        assert_eq!(s.analog.comp_delay_ns, Some(50.0));
        for bad in [
            "[analog]\ncomp_offset_v = 0.5\n",
            "[analog]\ncomp_offset_v = nan\n",
            "[analog]\nopamp_offset_v = -0.3\n",
            "[analog]\ncomp_delay_ns = -1.0\n",
            "[analog]\ncomp_delay_ns = 2e6\n",
            "[analog]\npart = \"worst\"\n",
            "[analog]\ncomp_offset_mv = 2.0\n",
        ] {
            assert!(Scenario::parse(bad).is_err(), "{bad}");
        }
        let err = format!(
            "{:#}",
            Scenario::parse("[analog]\ndac_offset_v = 1.0\n").unwrap_err()
        );
        assert!(err.contains("analog.dac_offset_v"), "{err}");
    }

    #[test]
    fn the_default_drive_board_is_the_default_images_the_bare_esc1() {
        let esc1 = &firmware_drive::comparators::B_G431B_ESC1;
        assert_eq!(Scenario::default().rig.board, esc1);
        assert_eq!(Scenario::parse("").unwrap().rig.board, esc1);
        let s = Scenario::parse("[plant]\nboard = \"source\"\n").unwrap();
        assert_eq!(s.rig.board, &firmware_drive::comparators::SOURCE_SENSORS);
    }

    const SPEC_EXAMPLE: &str = r#"
duration_s = 20.0

[plant]
dc_link_v = 30.0
load_torque_nm = 0.0
inertia_kgm2 = 0.0005
oc_hw_a = 3.0
ov_hw_v = 40.0
dc_capacitor_uf = 1000.0
brake_resistor_ohm = 10.0
scan_time_ms = 1.0
pwm_mode = "averaged"

[link]
baud = 115200
bit_error_rate = 0.0
cut_at_s = 1e9

[[event]]
at_s = 0.0
set = { A00 = 500, A01 = 800 }

[[event]]
at_s = 1.0
press = "D00"
hold_s = 0.2

[[event]]
at_s = 2.0
set = { D03 = 1 }

[[event]]
at_s = 5.0
keys = "A"

[[event]]
at_s = 6.0
load_torque_nm = 0.05
"#;

    #[test]
    fn emu_expect_names_image_troubles() {
        let s = Scenario::parse("[emu]\nexpect = [\"watchdog_reset\", \"hard_fault\"]").unwrap();
        assert_eq!(
            s.expected_trouble,
            vec![ImageTrouble::WatchdogReset, ImageTrouble::HardFault]
        );
        assert!(Scenario::parse("").unwrap().expected_trouble.is_empty());
        let e = Scenario::parse("[emu]\nexpect = [\"reboot\"]").unwrap_err();
        assert!(format!("{e:#}").contains("watchdog_reset"), "{e:#}");
    }

    #[test]
    fn the_spec_example_parses() {
        let s = Scenario::parse(SPEC_EXAMPLE).unwrap();
        assert_eq!(s.duration_s, Some(20.0));
        assert_eq!(s.cut_at_ns, u64::MAX);
        assert!(s.keys_start_run);
        assert!(
            !Scenario::parse("[[event]]\nat_s = 1\nkeys = \"B\"")
                .unwrap()
                .keys_start_run
        );
        let at = |t: f64| -> Vec<&Action> {
            s.actions
                .iter()
                .filter(|a| a.at_ns == secs_to_ns(t))
                .map(|a| &a.action)
                .collect()
        };
        assert_eq!(
            at(0.0),
            vec![
                &Action::Set(Input::Analog(0), 500),
                &Action::Set(Input::Analog(1), 800)
            ]
        );
        assert_eq!(at(1.0), vec![&Action::Set(Input::Digital(0), 1)]);
        assert_eq!(at(1.2), vec![&Action::Set(Input::Digital(0), 0)]);
        assert_eq!(at(5.0), vec![&Action::KeyDown('A')]);
        assert_eq!(
            at(6.0),
            vec![&Action::Plant(PlantChange::LoadTorqueNm(0.05))]
        );
        assert!(s.actions.windows(2).all(|w| w[0].at_ns <= w[1].at_ns));
    }

    #[test]
    fn mistakes_are_named() {
        let err = |t: &str| format!("{:#}", Scenario::parse(t).unwrap_err());
        assert!(err("[plant]\ndc_link = 3").contains("dc_link"));
        assert!(err("[[event]]\nat_s = 1\nset = { D16 = 1 }").contains("D16"));
        assert!(Scenario::parse("[[event]]\nat_s = 1\nset = { D15 = 1 }").is_ok());
        assert!(err("[[event]]\nat_s = 1\nset = { A00 = 2000 }").contains("out of range"));
        assert!(err("[[event]]\nat_s = 1\npress = \"A00\"").contains("digital"));
        assert!(err("[[event]]\nat_s = 1\nkeys = \"X\"").contains("keypad"));
        assert!(err("[plant]\npwm_mode = \"fast\"").contains("pwm_mode"));
        assert!(err("[[event]]\nat_s = 1").contains("does nothing"));
        assert!(err("duration_s = -1").contains("duration_s"));
        assert!(err("[[event]]\nat_s = 1\noc_hw_a = 2.0").contains("I>>"));
        assert!(err("[plant]\nload_r_ohm = 5.0").contains("load = \"rl\""));
        assert!(err("[plant]\nload = \"lamp\"").contains("load"));
        let rl = Scenario::parse("[plant]\nload = \"rl\"\nload_l_h = 0.05").unwrap();
        assert_eq!(
            rl.rig.load,
            Load::Rl {
                r_ohm: 10.0,
                l_h: 0.05
            }
        );
    }

    #[test]
    fn duration_precedence() {
        let s = Scenario::parse("duration_s = 3.0").unwrap();
        assert_eq!(s.duration_s(Some(1.0)), 1.0);
        assert_eq!(s.duration_s(None), 3.0);
        assert_eq!(Scenario::default().duration_s(None), DEFAULT_DURATION_S);
    }

    fn lift_err(text: &str) -> String {
        format!("{:#}", Scenario::parse(text).unwrap_err())
    }

    #[test]
    fn lift_table_and_events() {
        let s = Scenario::parse(
            "[lift]\nstart_mm = 0.0\nunbalance_kg = 4.0\n\
             [[event]]\nat_s = 1\ncall = 3\n\
             [[event]]\nat_s = 2\nhall = \"3d\"\nhold_s = 0.3\n\
             [[event]]\nat_s = 3\nload_kg = 95.0\ndoor_block = true\nvane_fail = \"R\"\n",
        )
        .unwrap();
        let l = s.lift.unwrap();
        assert_eq!((l.start_mm, l.unbalance_kg, l.floors), (0.0, 4.0, 4));
        let at = |t: f64| -> Vec<&Action> {
            s.actions
                .iter()
                .filter(|a| a.at_ns == secs_to_ns(t))
                .map(|a| &a.action)
                .collect()
        };
        assert_eq!(at(1.0), vec![&Action::Set(Input::Digital(2), 1)]);
        assert_eq!(at(1.1), vec![&Action::Set(Input::Digital(2), 0)]);
        assert_eq!(at(2.0), vec![&Action::Set(Input::Digital(8), 1)]);
        assert_eq!(at(2.3), vec![&Action::Set(Input::Digital(8), 0)]);
        assert_eq!(
            at(3.0),
            vec![
                &Action::Lift(LiftEvent::LoadKg(95.0)),
                &Action::Lift(LiftEvent::DoorBlock(true)),
                &Action::Lift(LiftEvent::VaneFail(Some(Vane::Right)))
            ]
        );
    }

    #[test]
    fn lift_errors_name_the_key() {
        assert!(lift_err("[[event]]\nat_s = 1\ncall = 3").contains("[lift]"));
        assert!(lift_err("[lift]\n[[event]]\nat_s = 1\ncall = 5").contains("call = 5"));
        assert!(lift_err("[lift]\n[[event]]\nat_s = 1\nhall = \"1d\"").contains("1d"));
        assert!(lift_err("[lift]\n[[event]]\nat_s = 1\nvane_fail = \"X\"").contains("X"));
        assert!(lift_err("[lift]\n[[event]]\nat_s = 1\nset = { D10 = 1 }").contains("D10"));
        assert!(lift_err("[lift]\n[[event]]\nat_s = 1\npress = \"D12\"").contains("D12"));
        assert!(lift_err("[lift]\n[[event]]\nat_s = 1\nset = { A00 = 5 }").contains("A00"));
        assert!(lift_err("[lift]\nfloors = 9").contains("floors"));
        assert!(lift_err("[lift]\nbogus = 1").contains("bogus"));
        // Without [lift] those inputs stay free.
        assert!(Scenario::parse("[[event]]\nat_s = 1\nset = { D10 = 1 }").is_ok());
    }
}
