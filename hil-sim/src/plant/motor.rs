//! Induction motor in the stator-fixed αβ frame, fluxes as states.
//!
//! Fluxes (not currents) are the states because the flux equations need no matrix
//! inversion: currents are a fixed linear map of the fluxes. The Clarke transform is the
//! amplitude-invariant one (iα = ia), so torque carries the 3/2 factor.
//! See `docs/model.md` for the equations.

/// Electrical and mechanical parameters of the motor and its shaft load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorParams {
    /// Stator resistance per phase (star equivalent).
    pub rs_ohm: f64,
    /// Rotor resistance referred to the stator.
    pub rr_ohm: f64,
    /// Stator leakage inductance.
    pub lls_h: f64,
    /// Rotor leakage inductance referred to the stator.
    pub llr_h: f64,
    /// Magnetising inductance.
    pub lm_h: f64,
    /// Pole pairs (4 poles = 2).
    pub pole_pairs: u32,
    /// Total inertia on the shaft (motor + load).
    pub inertia_kgm2: f64,
    /// Viscous friction of the bearings and fan.
    pub friction_nms: f64,
    /// Magnitude of the load torque; it always opposes rotation (a brake/dynamometer).
    pub load_torque_nm: f64,
    /// Shaft speed below which the load torque is scaled down linearly, so that a stopped
    /// shaft with a load stays stopped instead of being driven backwards.
    pub load_band_rad_s: f64,
    /// Rotor held at standstill (locked-rotor test).
    pub locked_rotor: bool,
}

impl MotorParams {
    /// The default rig's motor: a small 4-pole 50 Hz motor for ~18 V line-to-line
    /// (a 30 V DC link with sine PWM). See `docs/rig.md` for how the values were chosen.
    pub const DEFAULT_RIG: MotorParams = MotorParams {
        rs_ohm: 1.95,
        rr_ohm: 1.6,
        lls_h: 0.008,
        llr_h: 0.008,
        lm_h: 0.062,
        pole_pairs: 2,
        inertia_kgm2: 0.0005,
        friction_nms: 1.0e-5,
        load_torque_nm: 0.0,
        load_band_rad_s: 1.0,
        locked_rotor: false,
    };

    pub fn ls_h(&self) -> f64 {
        self.lls_h + self.lm_h
    }

    pub fn lr_h(&self) -> f64 {
        self.llr_h + self.lm_h
    }

    /// Determinant of the inductance matrix, Ls·Lr − Lm².
    pub fn det_h2(&self) -> f64 {
        self.ls_h() * self.lr_h() - self.lm_h * self.lm_h
    }
}

/// Electrical state: stator and rotor flux linkages, αβ frame, in Wb.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Fluxes {
    pub psi_s: [f64; 2],
    pub psi_r: [f64; 2],
}

/// Stator and rotor currents belonging to a flux state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Currents {
    pub i_s: [f64; 2],
    pub i_r: [f64; 2],
}

impl Fluxes {
    pub fn currents(&self, p: &MotorParams) -> Currents {
        let d = p.det_h2();
        let (ls, lr, lm) = (p.ls_h(), p.lr_h(), p.lm_h);
        let [sa, sb] = self.psi_s;
        let [ra, rb] = self.psi_r;
        Currents {
            i_s: [(lr * sa - lm * ra) / d, (lr * sb - lm * rb) / d],
            i_r: [(ls * ra - lm * sa) / d, (ls * rb - lm * sb) / d],
        }
    }
}

/// Electromagnetic torque, N·m: 3/2 · p · (ψs × is).
pub fn torque_nm(p: &MotorParams, psi_s: [f64; 2], i_s: [f64; 2]) -> f64 {
    1.5 * f64::from(p.pole_pairs) * (psi_s[0] * i_s[1] - psi_s[1] * i_s[0])
}

/// Load torque seen by the shaft at speed `w_rad_s` (opposes rotation).
pub fn load_torque_nm(p: &MotorParams, w_rad_s: f64) -> f64 {
    let band = p.load_band_rad_s.max(1e-9);
    p.load_torque_nm * (w_rad_s / band).clamp(-1.0, 1.0) + p.friction_nms * w_rad_s
}

/// Amplitude-invariant Clarke transform of three phase values.
pub fn clarke(abc: [f64; 3]) -> [f64; 2] {
    [
        (2.0 * abc[0] - abc[1] - abc[2]) / 3.0,
        (abc[1] - abc[2]) / 3.0_f64.sqrt(),
    ]
}

/// Phase values of an αβ vector (zero-sequence free).
pub fn inverse_clarke(ab: [f64; 2]) -> [f64; 3] {
    let h = 3.0_f64.sqrt() / 2.0;
    [ab[0], -0.5 * ab[0] + h * ab[1], -0.5 * ab[0] - h * ab[1]]
}

/// Steady-state per-phase equivalent circuit (T circuit) of the same motor: the
/// reference the dynamic model is checked against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SteadyState {
    /// Stator current, rms per phase.
    pub i_s_rms_a: f64,
    /// Electromagnetic torque.
    pub torque_nm: f64,
}

/// Equivalent-circuit solution for a phase voltage `v_rms` at `f_hz` and slip `slip`.
pub fn equivalent_circuit(p: &MotorParams, v_rms: f64, f_hz: f64, slip: f64) -> SteadyState {
    // Complex arithmetic on (re, im) pairs; small enough not to need a crate.
    type C = (f64, f64);
    fn add(a: C, b: C) -> C {
        (a.0 + b.0, a.1 + b.1)
    }
    fn mul(a: C, b: C) -> C {
        (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
    }
    fn div(a: C, b: C) -> C {
        let n = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / n, (a.1 * b.0 - a.0 * b.1) / n)
    }
    fn abs(a: C) -> f64 {
        a.0.hypot(a.1)
    }
    let w = 2.0 * std::f64::consts::PI * f_hz;
    let zs = (p.rs_ohm, w * p.lls_h);
    let zr = (p.rr_ohm / slip, w * p.llr_h);
    let zm = (0.0, w * p.lm_h);
    let z_par = div(mul(zm, zr), add(zm, zr));
    let z = add(zs, z_par);
    let i_s = div((v_rms, 0.0), z);
    let i_r = div(mul(i_s, zm), add(zm, zr));
    let w_sync_mech = w / f64::from(p.pole_pairs);
    let torque = 3.0 * abs(i_r).powi(2) * p.rr_ohm / slip / w_sync_mech;
    SteadyState {
        i_s_rms_a: abs(i_s),
        torque_nm: torque,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clarke_round_trip_for_balanced_phases() {
        let abc = [1.0, -0.25, -0.75];
        let back = inverse_clarke(clarke(abc));
        for (a, b) in abc.iter().zip(back.iter()) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn currents_invert_the_flux_equations() {
        let p = MotorParams::DEFAULT_RIG;
        let f = Fluxes {
            psi_s: [0.03, -0.01],
            psi_r: [0.025, 0.004],
        };
        let c = f.currents(&p);
        // ψs = Ls·is + Lm·ir
        let psa = p.ls_h() * c.i_s[0] + p.lm_h * c.i_r[0];
        let prb = p.lr_h() * c.i_r[1] + p.lm_h * c.i_s[1];
        assert!((psa - f.psi_s[0]).abs() < 1e-12);
        assert!((prb - f.psi_r[1]).abs() < 1e-12);
    }

    #[test]
    fn load_opposes_rotation_and_vanishes_at_standstill() {
        let mut p = MotorParams::DEFAULT_RIG;
        p.load_torque_nm = 0.05;
        assert!(load_torque_nm(&p, 100.0) > 0.05);
        assert!(load_torque_nm(&p, -100.0) < -0.05);
        assert_eq!(load_torque_nm(&p, 0.0), 0.0);
    }
}
