//! The lift of lift.md 4 (after seed 000): a car on a chain over a sprocket, driven through
//! a gearbox by the rig's motor, with a counterweight, a holding brake, two vane sensors
//! per floor, a door and final limits on the safety chain.
//!
//! The shaft side (gravity as an active torque, the reflected mass, the brake's torque and
//! the motor contactor) is [`LiftShaft`], which [`super::Plant`] integrates with the motor;
//! the rest (vanes, door, brake timing, limits, load sensor) is [`Lift`], stepped every
//! millisecond by the simulation with the PLC's outputs.

/// Standard gravity, m/s².
pub const G_M_S2: f64 = 9.81;
/// `at_floor` is k within this distance of floor k's level, mm (lift.md 4.4).
pub const AT_FLOOR_MM: f64 = 5.0;
/// D12 (door closed) reads 1 at or below this door position.
pub const DOOR_CLOSED_P: f64 = 0.02;

/// The lift's wiring to the PLC (lift.md 3.2): car buttons of floors 1-4.
pub const CAR_CALL_INPUTS: [u8; 4] = [0, 1, 2, 3];
/// Hall buttons by name (`hall = "2d"`).
pub const HALL_INPUTS: [(&str, u8); 6] = [
    ("1u", 4),
    ("2u", 5),
    ("2d", 6),
    ("3u", 7),
    ("3d", 8),
    ("4d", 9),
];
/// Left / right vane sensor, door closed, safety chain closed: driven by the plant.
pub const VANE_L_INPUT: u8 = 10;
pub const VANE_R_INPUT: u8 = 11;
pub const DOOR_CLOSED_INPUT: u8 = 12;
pub const CHAIN_INPUT: u8 = 15;
/// The load sensor's analog input (A00).
pub const LOAD_ANALOG: u8 = 0;
/// The outputs the plant reads: door open command, brake released.
pub const DOOR_OPEN_OUTPUT: u8 = 0;
pub const BRAKE_RELEASE_OUTPUT: u8 = 1;

/// The `[lift]` keys (lift.md 4.1), defaults as listed there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiftParams {
    pub floors: u8,
    pub floor_pitch_mm: f64,
    pub gear_ratio: f64,
    pub sprocket_d_mm: f64,
    pub unbalance_kg: f64,
    pub moving_mass_kg: f64,
    pub start_mm: f64,
    pub vane_long_mm: f64,
    pub vane_short_mm: f64,
    pub floor1_swapped: bool,
    pub door_stroke_s: f64,
    pub brake_delay_ms: f64,
    pub brake_torque_nm: f64,
    pub limit_low_mm: f64,
    /// `None`: z_N + 40 mm.
    pub limit_high_mm: Option<f64>,
    pub load_kg: f64,
    pub load_scale_kg: f64,
}

impl Default for LiftParams {
    fn default() -> Self {
        LiftParams {
            floors: 4,
            floor_pitch_mm: 300.0,
            gear_ratio: 25.0,
            sprocket_d_mm: 79.0,
            unbalance_kg: 2.0,
            moving_mass_kg: 10.0,
            start_mm: 450.0,
            vane_long_mm: 30.0,
            vane_short_mm: 2.0,
            floor1_swapped: true,
            door_stroke_s: 2.0,
            brake_delay_ms: 30.0,
            brake_torque_nm: 0.3,
            limit_low_mm: -40.0,
            limit_high_mm: None,
            load_kg: 0.0,
            load_scale_kg: 125.0,
        }
    }
}

impl LiftParams {
    /// Car travel per shaft radian, m: r / i.
    pub fn m_per_rad(&self) -> f64 {
        self.sprocket_d_mm / 2000.0 / self.gear_ratio
    }

    /// T_g = −unbalance · g · r / i: the active torque gravity puts on the motor shaft,
    /// N·m (negative: it pulls the car down, the drive's reverse direction).
    pub fn gravity_torque_nm(&self) -> f64 {
        -self.unbalance_kg * G_M_S2 * self.m_per_rad()
    }

    /// The moving mass reflected to the motor shaft, kg·m².
    pub fn reflected_inertia_kgm2(&self) -> f64 {
        self.moving_mass_kg * self.m_per_rad().powi(2)
    }

    /// z_k, mm: floor 1 at 0.
    pub fn level_mm(&self, floor: u8) -> f64 {
        f64::from(floor.saturating_sub(1)) * self.floor_pitch_mm
    }

    pub fn limit_high_mm(&self) -> f64 {
        self.limit_high_mm
            .unwrap_or(self.level_mm(self.floors) + 40.0)
    }

    /// The vane sensors at car position `x_mm` (left, right), before any `vane_fail`.
    /// Floors 2..N: the right sensor sees the long vane, the left the short one; floor 1
    /// (with `floor1_swapped`) the other way round, so "left on, right off" happens only
    /// at floor 1 going down.
    pub fn vanes(&self, x_mm: f64) -> (bool, bool) {
        let (mut left, mut right) = (false, false);
        for k in 1..=self.floors {
            let rel = (x_mm - self.level_mm(k)).abs();
            let long = rel <= self.vane_long_mm;
            let short = rel <= self.vane_short_mm;
            if k == 1 && self.floor1_swapped {
                left |= long;
                right |= short;
            } else {
                left |= short;
                right |= long;
            }
        }
        (left, right)
    }

    /// k when the car is within [`AT_FLOOR_MM`] of floor k's level, else 0.
    pub fn at_floor(&self, x_mm: f64) -> u8 {
        (1..=self.floors)
            .find(|&k| (x_mm - self.level_mm(k)).abs() <= AT_FLOOR_MM)
            .unwrap_or(0)
    }

    /// A00 = round(1023 · min(load, scale) / scale).
    pub fn load_counts(&self, load_kg: f64) -> u16 {
        let scale = self.load_scale_kg.max(1e-9);
        (1023.0 * load_kg.clamp(0.0, scale) / scale).round() as u16
    }

    /// The shaft side of the lift as the plant integrates it, brake released, contactor
    /// closed.
    pub fn shaft(&self) -> LiftShaft {
        LiftShaft {
            gravity_nm: self.gravity_torque_nm(),
            extra_inertia_kgm2: self.reflected_inertia_kgm2(),
            brake_torque_nm: self.brake_torque_nm,
            brake_engaged: false,
            contactor_open: false,
        }
    }
}

/// What the lift adds to the motor shaft (lift.md 4.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiftShaft {
    /// T_g: keeps its direction whether the shaft turns or not, and can drive it.
    pub gravity_nm: f64,
    pub extra_inertia_kgm2: f64,
    pub brake_torque_nm: f64,
    /// The holding brake is engaged: at rest it holds while |T_e + T_g| ≤ its torque,
    /// otherwise it brakes with its torque against the motion.
    pub brake_engaged: bool,
    /// A final limit opened the safety chain: the motor contactor is open (no stator
    /// current, no torque).
    pub contactor_open: bool,
}

/// A sensor `vane_fail` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Vane {
    Left,
    Right,
}

/// Scenario events on the lift (lift.md 4.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LiftEvent {
    LoadKg(f64),
    DoorBlock(bool),
    VaneFail(Option<Vane>),
}

/// What the lift drives into the PLC and shows in the record, after one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LiftSample {
    pub car_mm: f64,
    pub car_mms: f64,
    pub at_floor: u8,
    pub door: f64,
    pub brake_engaged: bool,
    pub vane_l: bool,
    pub vane_r: bool,
    /// D12: door closed and not blocked.
    pub door_closed: bool,
    /// D15: the safety chain is closed (the car between the final limits).
    pub chain_closed: bool,
    /// A00 counts.
    pub load_counts: u16,
}

/// The lift's own state besides the shaft.
#[derive(Debug, Clone)]
pub struct Lift {
    params: LiftParams,
    load_kg: f64,
    door_p: f64,
    door_block: bool,
    vane_fail: Option<Vane>,
    brake_engaged: bool,
    /// O01 level and how long it has been so, ms.
    o01: bool,
    o01_ms: f64,
    chain_closed: bool,
    last: LiftSample,
}

impl Lift {
    /// A lift at rest at `start_mm`, door closed, brake engaged.
    pub fn new(params: LiftParams) -> Self {
        let mut lift = Lift {
            params,
            load_kg: params.load_kg,
            door_p: 0.0,
            door_block: false,
            vane_fail: None,
            brake_engaged: true,
            o01: false,
            o01_ms: 0.0,
            chain_closed: true,
            last: LiftSample::default(),
        };
        lift.last = lift.observe(params.start_mm, 0.0);
        lift
    }

    pub fn params(&self) -> &LiftParams {
        &self.params
    }

    pub fn apply(&mut self, e: LiftEvent) {
        match e {
            LiftEvent::LoadKg(kg) => self.load_kg = kg.max(0.0),
            LiftEvent::DoorBlock(on) => self.door_block = on,
            LiftEvent::VaneFail(v) => self.vane_fail = v,
        }
    }

    /// Car position for a shaft angle (the plant's, 0 at t = 0), mm.
    pub fn car_mm(&self, angle_rad: f64) -> f64 {
        self.params.start_mm + angle_rad * self.params.m_per_rad() * 1000.0
    }

    /// One step of `dt_s` with the PLC's O00 (door open) and O01 (brake released), the
    /// car at `car_mm` moving at `car_mms`. Returns what the PLC's pins and the record see.
    pub fn step(
        &mut self,
        dt_s: f64,
        o00: bool,
        o01: bool,
        car_mm: f64,
        car_mms: f64,
    ) -> LiftSample {
        let p = self.params;
        // Door: toward open while O00, else toward closed; a blocked door cannot close.
        let rate = dt_s / p.door_stroke_s.max(1e-9);
        if o00 {
            self.door_p = (self.door_p + rate).min(1.0);
        } else if !self.door_block {
            self.door_p = (self.door_p - rate).max(0.0);
        }
        // Final limits: the chain is open while the car is outside them.
        self.chain_closed = (p.limit_low_mm..=p.limit_high_mm()).contains(&car_mm);
        // Brake: changes state once O01 has held its new level for the delay; engaged at
        // once while the chain is open.
        if o01 == self.o01 {
            self.o01_ms += dt_s * 1000.0;
        } else {
            self.o01 = o01;
            self.o01_ms = dt_s * 1000.0;
        }
        if self.o01_ms >= p.brake_delay_ms {
            self.brake_engaged = !self.o01;
        }
        if !self.chain_closed {
            self.brake_engaged = true;
        }
        self.last = self.observe(car_mm, car_mms);
        self.last
    }

    fn observe(&self, car_mm: f64, car_mms: f64) -> LiftSample {
        let p = &self.params;
        let (mut l, mut r) = p.vanes(car_mm);
        match self.vane_fail {
            Some(Vane::Left) => l = false,
            Some(Vane::Right) => r = false,
            None => {}
        }
        LiftSample {
            car_mm,
            car_mms,
            at_floor: p.at_floor(car_mm),
            door: self.door_p,
            brake_engaged: self.brake_engaged,
            vane_l: l,
            vane_r: r,
            door_closed: self.door_p <= DOOR_CLOSED_P && !self.door_block,
            chain_closed: self.chain_closed,
            load_counts: p.load_counts(self.load_kg),
        }
    }

    /// The last step's result.
    pub fn sample(&self) -> LiftSample {
        self.last
    }

    /// The shaft side now.
    pub fn shaft(&self) -> LiftShaft {
        LiftShaft {
            brake_engaged: self.brake_engaged,
            contactor_open: !self.chain_closed,
            ..self.params.shaft()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vanes_floor_one_swapped_first_sensor_slows_both_level() {
        let p = LiftParams::default();
        // Floor 2 at 300 mm: right (long) from 30 mm away, both within 2 mm.
        assert_eq!(p.vanes(300.0), (true, true));
        assert_eq!(p.vanes(331.0), (false, false));
        assert_eq!(p.vanes(329.0), (false, true));
        assert_eq!(p.vanes(271.0), (false, true));
        assert_eq!(p.vanes(301.9), (true, true));
        assert_eq!(p.vanes(302.5), (false, true));
        // Floor 1: the left sensor sees the long vane.
        assert_eq!(p.vanes(29.0), (true, false));
        assert_eq!(p.vanes(1.0), (true, true));
        // "Left on, right off" only near floor 1.
        for x in (-100..=1000).map(f64::from) {
            if p.vanes(x) == (true, false) {
                assert!(x.abs() <= 30.0, "{x}");
            }
        }
        let unswapped = LiftParams {
            floor1_swapped: false,
            ..p
        };
        assert_eq!(unswapped.vanes(29.0), (false, true));
    }

    #[test]
    fn geometry_and_levels() {
        let p = LiftParams::default();
        assert_eq!(p.level_mm(4), 900.0);
        assert_eq!(p.limit_high_mm(), 940.0);
        assert_eq!(p.at_floor(604.0), 3);
        assert_eq!(p.at_floor(606.0), 0);
        // 59.4 mm/s at 13.3 Hz with s = 0.10 (lift.md 3.1): v = ω r / i.
        let w = 2.0 * std::f64::consts::PI * 13.3 / 2.0 * 0.9;
        assert!((w * p.m_per_rad() * 1000.0 - 59.42).abs() < 0.05);
        // 2 kg need 0.031 N m on the shaft (lift.md 4.1).
        assert!((p.gravity_torque_nm() + 0.031).abs() < 0.0005);
        assert_eq!(p.load_counts(0.0), 0);
        assert_eq!(p.load_counts(110.0), 900);
        assert_eq!(p.load_counts(500.0), 1023);
    }

    #[test]
    fn brake_follows_o01_after_its_delay_and_the_chain_engages_it_at_once() {
        let mut l = Lift::new(LiftParams::default());
        assert!(l.sample().brake_engaged);
        for ms in 1..=40 {
            let s = l.step(0.001, false, true, 450.0, 0.0);
            assert_eq!(s.brake_engaged, ms < 30, "{ms} ms");
        }
        let s = l.step(0.001, false, true, -41.0, 0.0);
        assert!(s.brake_engaged && !s.chain_closed);
        assert!(l.shaft().contactor_open);
    }

    #[test]
    fn door_stroke_and_block() {
        let mut l = Lift::new(LiftParams::default());
        assert!(l.sample().door_closed);
        for _ in 0..1000 {
            l.step(0.001, true, false, 0.0, 0.0);
        }
        assert!((l.sample().door - 0.5).abs() < 1e-9 && !l.sample().door_closed);
        for _ in 0..1000 {
            l.step(0.001, false, false, 0.0, 0.0);
        }
        assert!(l.sample().door_closed);
        l.apply(LiftEvent::DoorBlock(true));
        let s = l.step(0.001, false, false, 0.0, 0.0);
        assert!(!s.door_closed, "a blocked door reads open at once");
        l.apply(LiftEvent::VaneFail(Some(Vane::Left)));
        let s = l.step(0.001, false, false, 0.0, 0.0);
        assert_eq!((s.vane_l, s.vane_r), (false, true));
    }
}
