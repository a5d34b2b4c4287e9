//! The drive-section interpreter (program.md 4.1-4.2): lines 000-149, in order, once per
//! millisecond. It only computes *what* to output (frequency, amplitude, phase offsets,
//! leg modes, switching frequency, protection limits); [`crate::drive`] turns that into
//! modulator parameters and the interrupt does the rest.
//!
//! Decisions where program.md is silent (also in `docs/drive-core.md`):
//! * Popping (only `PI` pops) shifts the stack up and fills element 4 with 0.
//! * Settings (`Rs=` .. `frv`, `PRx`, `PWF` from K) are sticky. The verifier lets each
//!   parameter be set by one line only (`Mnemonic::drive_setting`), so the value is the
//!   same on every line and in every cycle. They are also applied once when a program is
//!   loaded, so protection limits and the brake chopper work before the first RUN.
//! * Instructions the verifier would reject (wrong section or operand) do nothing.
//! * `SN1` clamps f to 0..=fmx and A to >= 0.
//! * `=dU` with `Uc=` unset (0) leaves dU unchanged; `fjm` 0 keeps 50.0 Hz.
//! * `PI` with T <= 0 (lift.md 2.1, the rule): the line's integral is reset to 0, not
//!   frozen, and stays 0 while T <= 0; y = clamp(trunc(Kp (w - x) / 100), 0, limit), so
//!   Kp = 0 gives y = 0 in the same millisecond (a ramp stops at once). When T > 0 again
//!   the integral restarts from 0. The integral is kept in Q16 so that a 2333 ms time
//!   constant integrates steps far below 1 count per millisecond.

use shared_protocol::program::{
    drive_stack_step, DriveSection, Instruction, Mnemonic, Operand, DRIVE_LINES,
};

use crate::modulator::LegMode;
use crate::restart::RestartPolicy;

/// Depth of the int stack.
pub const STACK_DEPTH: usize = 5;
/// Number of Q variables (shared with the PLC and the link).
pub use shared_protocol::program::Q_COUNT;
/// `PWF` range, Hz (program.md 4.2): the source's 488 Hz minimum.
pub const PWF_MIN_HZ: u16 = 488;
pub const PWF_MAX_HZ: u16 = 20_000;
/// `fjm` when the program has none: 50.0 Hz.
pub const FJM_DEFAULT: i16 = 500;
/// `frv` when the program has none: 0.1 Hz, i.e. reverse only at standstill.
pub const FRV_DEFAULT: i16 = 1;

/// The program's drive parameters (units as in program.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Settings {
    /// `Rs=`, 0.01 ohm.
    pub rs_centiohm: u16,
    /// `Uc=`, V.
    pub uc_volts: u16,
    /// `Iz=`, 0.01 A.
    pub iz_centiamps: u16,
    /// IR boost, 0..=1023 (`=dU`, `dU=`).
    pub du: u16,
    /// `U>`, V (0 = none).
    pub u_max_volts: u16,
    /// `U<`, V (0 = none).
    pub u_min_volts: u16,
    /// `I>`, 0.01 A (0 = none).
    pub i_max_centiamps: u16,
    /// `fmn`, `fjm`, `fmx`, `frv`: 0.1 Hz.
    pub fmn: i16,
    pub fjm: i16,
    pub fmx: i16,
    pub frv: i16,
    /// `PWF`, Hz (488..=20000).
    pub pwf_hz: u16,
    /// `PR0`/`PR1`/`PR2`: 4/16/64; 1 when none ran.
    pub prescaler: u16,
    /// `I>>`: hardware overcurrent threshold, 0.01 A (0 = none: the board's default).
    pub oc_hw_centiamps: u16,
    /// `U>>`: hardware overvoltage threshold, V (0 = none: the board's default).
    pub ov_hw_volts: u16,
    /// `arc`, `art`, `arn`: the automatic restart (`crate::restart`).
    pub restart: RestartPolicy,
}

impl Settings {
    pub fn new(default_pwm_hz: u16) -> Self {
        Settings {
            rs_centiohm: 0,
            uc_volts: 0,
            iz_centiamps: 0,
            du: 0,
            u_max_volts: 0,
            u_min_volts: 0,
            i_max_centiamps: 0,
            fmn: 0,
            fjm: FJM_DEFAULT,
            fmx: i16::MAX,
            frv: FRV_DEFAULT,
            pwf_hz: default_pwm_hz.clamp(PWF_MIN_HZ, PWF_MAX_HZ),
            prescaler: 1,
            oc_hw_centiamps: 0,
            ov_hw_volts: 0,
            restart: RestartPolicy::OFF,
        }
    }

    /// `=dU`: round(1023 * Rs * Iz / (Uc / 2)), 0..=1023.
    fn calc_du(&mut self) {
        if self.uc_volts == 0 {
            return;
        }
        // Rs [0.01 ohm] * Iz [0.01 A] / 10^4 = volts; / (Uc/2) = 2 * .. / Uc.
        let num = 1023u64 * u64::from(self.rs_centiohm) * u64::from(self.iz_centiamps) * 2;
        let den = 10_000u64 * u64::from(self.uc_volts);
        self.du = ((num + den / 2) / den).min(1023) as u16;
    }
}

/// What the section commands, read by the core after each cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Outputs {
    /// Commanded frequency f from `SN1`, 0.1 Hz, already clamped to 0..=fmx.
    pub f: i16,
    /// Amplitude A from `SN1` (0.1 Hz units: A = f is nominal V/f), >= 0.
    pub a: i16,
    /// Phase offsets of phases 1-3, 0.1 degree.
    pub phase_decideg: [i16; 3],
    pub legs: [LegMode; 3],
}

/// Run-time warnings of the drive section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum VmWarning {
    /// `PWF Qxx` outside 488..=20000 Hz: `applied` is the clamped value. Reported when the
    /// clamping starts, not every millisecond.
    PwfClamped {
        line: u16,
        requested: i16,
        applied: u16,
    },
}

#[derive(Debug, Clone)]
pub struct DriveVm {
    settings: Settings,
    default_pwm_hz: u16,
    stack: [i16; STACK_DEPTH],
    /// Integral of each `PI` line, Q16.
    pi: [i32; DRIVE_LINES],
    q: [i16; Q_COUNT],
    out: Outputs,
    pwf_clamped: bool,
    /// The warning of the last full cycle while its cause lasts (PWF clamped).
    active: Option<VmWarning>,
    /// Values loaded in the running cycle (the verifier's count, program.md 4.1).
    depth: u8,
    /// Instructions that found fewer values than they need since the last load: 0 for
    /// every section the verifier accepts (property-tested).
    underflows: u32,
}

impl DriveVm {
    pub fn new(default_pwm_hz: u16) -> Self {
        DriveVm {
            settings: Settings::new(default_pwm_hz),
            default_pwm_hz,
            stack: [0; STACK_DEPTH],
            pi: [0; DRIVE_LINES],
            q: [0; Q_COUNT],
            out: Outputs::default(),
            pwf_clamped: false,
            active: None,
            depth: 0,
            underflows: 0,
        }
    }

    /// Instructions that ran with fewer values loaded in their cycle than they need
    /// (the verifier's stack rule), since the program was loaded.
    pub fn stack_underflows(&self) -> u32 {
        self.underflows
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    pub fn outputs(&self) -> &Outputs {
        &self.out
    }

    /// The run-time warning whose cause lasts (the `PWF` of the last cycle clamped), for
    /// the status the PLC shows.
    pub fn active_warning(&self) -> Option<VmWarning> {
        self.active
    }

    pub fn stack(&self) -> &[i16; STACK_DEPTH] {
        &self.stack
    }

    /// The drive's copy of Qn (0 for n out of range).
    pub fn q(&self, n: u8) -> i16 {
        self.q.get(usize::from(n)).copied().unwrap_or(0)
    }

    /// Set the drive's copy of Qn; false when n is out of range.
    pub fn set_q(&mut self, n: u8, value: i16) -> bool {
        match self.q.get_mut(usize::from(n)) {
            Some(slot) => {
                *slot = value;
                true
            }
            None => false,
        }
    }

    /// A new program: settings back to defaults, then its settings applied; Q cleared
    /// (the PLC clears its Q at RUN, which is when it downloads).
    pub fn load(&mut self, s: &DriveSection) {
        self.settings = Settings::new(self.default_pwm_hz);
        self.q = [0; Q_COUNT];
        self.underflows = 0;
        self.start_run();
        for (line, ins) in lines(s) {
            if ins.mnemonic == Mnemonic::Pwf {
                if matches!(ins.operand, Some(Operand::K(_))) {
                    self.exec(line, ins, &mut |_| {});
                }
            } else {
                self.setting(ins);
            }
        }
    }

    /// State at the start of a RUN: empty stack, PI integrals 0, no outputs.
    pub fn start_run(&mut self) {
        self.stack = [0; STACK_DEPTH];
        self.pi = [0; DRIVE_LINES];
        self.out = Outputs::default();
        self.pwf_clamped = false;
        self.active = None;
    }

    /// Stop generating: f and the leg modes back to none (the PI states are kept until
    /// the next RUN).
    pub fn stop_outputs(&mut self) {
        self.out = Outputs::default();
        self.active = None;
    }

    /// One 1 ms cycle: every line of the section, in order.
    pub fn run(&mut self, s: &DriveSection, warn: &mut impl FnMut(VmWarning)) {
        self.depth = 0;
        self.active = None;
        for (line, ins) in lines(s) {
            self.depth = match drive_stack_step(self.depth, ins.mnemonic) {
                Ok(d) => d,
                Err(d) => {
                    self.underflows = self.underflows.saturating_add(1);
                    d
                }
            };
            self.exec(line, ins, warn);
        }
    }

    fn push(&mut self, v: i16) {
        self.stack.copy_within(0..STACK_DEPTH - 1, 1);
        self.stack[0] = v;
    }

    fn pop(&mut self) -> i16 {
        let v = self.stack[0];
        self.stack.copy_within(1..STACK_DEPTH, 0);
        self.stack[STACK_DEPTH - 1] = 0;
        v
    }

    fn value(&self, ins: &Instruction) -> Option<i16> {
        match ins.operand {
            Some(Operand::K(_)) => Some(ins.constant.min(i16::MAX as u16) as i16),
            Some(Operand::Q(n)) => self.q.get(usize::from(n)).copied(),
            _ => None,
        }
    }

    fn exec(&mut self, line: u16, ins: &Instruction, warn: &mut impl FnMut(VmWarning)) {
        let k = ins.constant;
        match ins.mnemonic {
            Mnemonic::Ld => {
                if let Some(v) = self.value(ins) {
                    self.push(v);
                }
            }
            Mnemonic::Wr => {
                let e0 = self.stack[0];
                let leg = match ins.operand {
                    Some(Operand::Q(n)) => {
                        self.set_q(n, e0);
                        None
                    }
                    Some(Operand::Pw1) => Some(0),
                    Some(Operand::Pw3) => Some(1),
                    Some(Operand::Pw5) => Some(2),
                    _ => None,
                };
                if let Some(slot) = leg.and_then(|l| self.out.legs.get_mut(l)) {
                    *slot = LegMode::Direct {
                        permille: e0.clamp(0, 1000) as u16,
                    };
                }
            }
            Mnemonic::Pwf => {
                if let Some(v) = self.value(ins) {
                    let applied = v.clamp(PWF_MIN_HZ as i16, PWF_MAX_HZ as i16) as u16;
                    let clamped = applied as i16 != v;
                    if matches!(ins.operand, Some(Operand::Q(_))) && clamped {
                        let w = VmWarning::PwfClamped {
                            line,
                            requested: v,
                            applied,
                        };
                        if !self.pwf_clamped {
                            warn(w);
                        }
                        self.active = Some(w);
                    }
                    self.pwf_clamped = clamped;
                    self.settings.pwf_hz = applied;
                }
            }
            Mnemonic::Pi => self.pi(line, k),
            Mnemonic::Sn1 => {
                let [phase, a, f, ..] = self.stack;
                self.out.f = f.clamp(0, self.settings.fmx.max(0));
                self.out.a = a.max(0);
                self.out.phase_decideg[0] = phase;
                self.out.legs[0] = LegMode::Sine;
            }
            Mnemonic::Sn2 => {
                self.out.phase_decideg[1] = self.stack[0];
                self.out.legs[1] = LegMode::Sine;
            }
            Mnemonic::Sn3 => {
                self.out.phase_decideg[2] = self.stack[0];
                self.out.legs[2] = LegMode::Sine;
            }
            _ => self.setting(ins),
        }
    }

    /// The instructions that only set a parameter from their constant (with `PWF K`, the
    /// ones a load applies; anything else does nothing here). One copy for the cycle and the load (flash:
    /// `docs/size.md`).
    #[inline(never)]
    fn setting(&mut self, ins: &Instruction) {
        let k = ins.constant;
        let ki = k.min(i16::MAX as u16) as i16;
        match ins.mnemonic {
            Mnemonic::Pr0 => self.settings.prescaler = 4,
            Mnemonic::Pr1 => self.settings.prescaler = 16,
            Mnemonic::Pr2 => self.settings.prescaler = 64,
            Mnemonic::RsSet => self.settings.rs_centiohm = k,
            Mnemonic::UcSet => self.settings.uc_volts = k,
            Mnemonic::IzSet => self.settings.iz_centiamps = k,
            Mnemonic::CalcDu => self.settings.calc_du(),
            Mnemonic::DuSet => self.settings.du = k.min(1023),
            Mnemonic::UMax => self.settings.u_max_volts = k,
            Mnemonic::UMin => self.settings.u_min_volts = k,
            Mnemonic::IMax => self.settings.i_max_centiamps = k,
            Mnemonic::IMaxHw => self.settings.oc_hw_centiamps = k,
            Mnemonic::UMaxHw => self.settings.ov_hw_volts = k,
            Mnemonic::Fmn => self.settings.fmn = ki,
            Mnemonic::Fjm if ki > 0 => self.settings.fjm = ki,
            Mnemonic::Fmx => self.settings.fmx = ki,
            Mnemonic::Frv => self.settings.frv = ki,
            Mnemonic::Arc => self.settings.restart.classes = k,
            Mnemonic::Art => self.settings.restart.delay_ds = k,
            Mnemonic::Arn => self.settings.restart.limit = k,
            // `fjm 0` keeps the default (the verifier refuses it anyway); the safety
            // settings are read by `safety_settings`, not here; the rest are executed by
            // `exec` (not settings) or are PLC-section mnemonics the verifier keeps out.
            // Listed one by one, so that a new mnemonic is a compile error here until it
            // is given its effect or listed.
            Mnemonic::Fjm
            | Mnemonic::Fss
            | Mnemonic::Pss
            | Mnemonic::Trd
            | Mnemonic::Ard
            | Mnemonic::Tel
            | Mnemonic::Ts1
            | Mnemonic::Ts2
            | Mnemonic::Fl1
            | Mnemonic::Fl2
            | Mnemonic::Fl3
            | Mnemonic::Fl4
            | Mnemonic::Tl1
            | Mnemonic::Tl2
            | Mnemonic::Tl3
            | Mnemonic::Tl4
            | Mnemonic::Pli
            | Mnemonic::Tli
            | Mnemonic::Tdi
            | Mnemonic::Aap
            | Mnemonic::Adp
            | Mnemonic::Aan
            | Mnemonic::Adn
            | Mnemonic::Tla
            | Mnemonic::Asr
            | Mnemonic::Ld
            | Mnemonic::Wr
            | Mnemonic::Pwf
            | Mnemonic::Pi
            | Mnemonic::Sn1
            | Mnemonic::Sn2
            | Mnemonic::Sn3
            | Mnemonic::Ldc
            | Mnemonic::Wrc
            | Mnemonic::Not
            | Mnemonic::And
            | Mnemonic::Or
            | Mnemonic::Xor
            | Mnemonic::Anc
            | Mnemonic::Orc
            | Mnemonic::Let
            | Mnemonic::Io
            | Mnemonic::Set
            | Mnemonic::Res
            | Mnemonic::Eq
            | Mnemonic::Gt
            | Mnemonic::Lt
            | Mnemonic::Ctu
            | Mnemonic::Ctd
            | Mnemonic::Ton
            | Mnemonic::Tof
            | Mnemonic::Imp
            | Mnemonic::Add
            | Mnemonic::Sub
            | Mnemonic::Mul
            | Mnemonic::Div
            | Mnemonic::Lcd
            | Mnemonic::Rev
            | Mnemonic::Ack
            | Mnemonic::Alm
            | Mnemonic::Sfr => {}
        }
    }

    /// `PI K limit`: pops w, x, T, Kp; pushes y (program.md 4.2).
    fn pi(&mut self, line: u16, limit: u16) {
        let w = self.pop();
        let x = self.pop();
        let t = self.pop();
        let kp = self.pop();
        let lim = i64::from(limit.min(i16::MAX as u16));
        let e = i64::from(w) - i64::from(x);
        let y = match self.pi.get_mut(usize::from(line)) {
            Some(integral) => {
                let i = if t > 0 {
                    // dt = 1 ms: I += e / T, rounded half away from zero.
                    let t = i64::from(t);
                    let num = e << 16;
                    let inc = (num + num.signum() * (t / 2)) / t;
                    (i64::from(*integral) + inc).clamp(0, lim << 16)
                } else {
                    0
                };
                *integral = i as i32;
                let p = i64::from(kp) * e / 100;
                (p + (i >> 16)).clamp(0, lim)
            }
            None => 0,
        };
        self.push(y as i16);
    }
}

/// The non-empty lines of a drive section.
fn lines(s: &DriveSection) -> impl Iterator<Item = (u16, &Instruction)> {
    s.lines
        .iter()
        .enumerate()
        .filter_map(|(n, l)| l.as_ref().map(|i| (n as u16, i)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ins(mnemonic: Mnemonic, operand: Option<Operand>, constant: u16) -> Instruction {
        Instruction {
            mnemonic,
            operand,
            constant,
        }
    }

    fn section(lines: &[(u16, Instruction)]) -> DriveSection {
        let mut s = DriveSection::default();
        for (n, i) in lines {
            s.lines[*n as usize] = Some(*i);
        }
        s
    }

    fn k(v: u16) -> Option<Operand> {
        Some(Operand::K((v % 100) as u8))
    }

    #[test]
    fn ld_pushes_and_drops_the_fifth() {
        let mut vm = DriveVm::new(16000);
        let s = section(
            &(0..6)
                .map(|n| (n, ins(Mnemonic::Ld, k(n + 1), n + 1)))
                .collect::<Vec<_>>(),
        );
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.stack(), &[6, 5, 4, 3, 2]);
    }

    #[test]
    fn wr_q_keeps_the_stack() {
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::Ld, k(7), 7)),
            (1, ins(Mnemonic::Wr, Some(Operand::Q(5)), 0)),
            (2, ins(Mnemonic::Ld, Some(Operand::Q(5)), 0)),
        ]);
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.q(5), 7);
        assert_eq!(&vm.stack()[..2], &[7, 7]);
    }

    #[test]
    fn pi_pure_gain_and_limit() {
        // Kp = 2.00, T = 0: y = 2 * (w - x), limited to 0..=300.
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::Ld, k(200), 200)),
            (1, ins(Mnemonic::Ld, k(0), 0)),
            (2, ins(Mnemonic::Ld, Some(Operand::Q(0)), 0)),
            (3, ins(Mnemonic::Ld, Some(Operand::Q(1)), 0)),
            (4, ins(Mnemonic::Pi, k(300), 300)),
            (5, ins(Mnemonic::Wr, Some(Operand::Q(2)), 0)),
        ]);
        vm.set_q(1, 100);
        vm.set_q(0, 40);
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.q(2), 120);
        // The four operands are popped, y pushed, element 4 filled with 0.
        assert_eq!(vm.stack(), &[120, 0, 0, 0, 0]);
        vm.set_q(1, 1000);
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.q(2), 300);
        vm.set_q(1, 0);
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.q(2), 0);
    }

    /// lift.md 2.1: T <= 0 resets the integral (not frozen) and stops a lag at once; a
    /// positive T restarts it from 0; the limit is min(K, 32767).
    #[test]
    fn pi_with_t_at_or_below_zero_resets_the_integral_and_stops_at_once() {
        // The lift's lag: Kp = 0, T = Q03, x = Q01 (fed back), w = Q02, limit 250.
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::Ld, k(0), 0)),
            (1, ins(Mnemonic::Ld, Some(Operand::Q(3)), 0)),
            (2, ins(Mnemonic::Ld, Some(Operand::Q(1)), 0)),
            (3, ins(Mnemonic::Ld, Some(Operand::Q(2)), 0)),
            (4, ins(Mnemonic::Pi, k(250), 250)),
            (5, ins(Mnemonic::Wr, Some(Operand::Q(1)), 0)),
        ]);
        vm.set_q(2, 133);
        vm.set_q(3, 300);
        for _ in 0..2000 {
            vm.run(&s, &mut |_| {});
        }
        assert_eq!(vm.q(1), 133, "settled on w");
        // T = 0: y = 0 in the same millisecond, and stays 0 (w still 133).
        for t in [0, -5] {
            vm.set_q(3, t);
            for _ in 0..3 {
                vm.run(&s, &mut |_| {});
                assert_eq!(vm.q(1), 0, "T = {t}");
            }
        }
        // T > 0 again: the integral restarts from 0 (not from the old 133): after 1 ms
        // y = 133 / 300 of a count, truncated to 0, and it rises from there.
        vm.set_q(3, 300);
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.q(1), 0);
        for _ in 0..299 {
            vm.run(&s, &mut |_| {});
        }
        let after_t = vm.q(1);
        assert!(
            (80..=90).contains(&after_t),
            "1 - 1/e of 133 after T: {after_t}"
        );
        // With Kp > 0 and T <= 0, y is the P part alone, truncated and clamped to the
        // limit: Kp = 1.50, e = 33 -> 49.5 -> 49.
        let p = section(&[
            (0, ins(Mnemonic::Ld, k(150), 150)),
            (1, ins(Mnemonic::Ld, k(0), 0)),
            (2, ins(Mnemonic::Ld, k(100), 100)),
            (3, ins(Mnemonic::Ld, Some(Operand::Q(2)), 0)),
            (4, ins(Mnemonic::Pi, k(9999), 9999)),
            (5, ins(Mnemonic::Wr, Some(Operand::Q(4)), 0)),
        ]);
        vm.set_q(2, 133);
        vm.run(&p, &mut |_| {});
        assert_eq!(vm.q(4), 49);
        vm.set_q(2, i16::MAX);
        vm.run(&p, &mut |_| {});
        assert_eq!(vm.q(4), 9999, "limit K");
    }

    #[test]
    fn pi_integral_is_anti_windup_clamped() {
        // Kp = 0, T = 10 ms, x = 0, w = 1000, limit 100: I saturates at 100 and comes
        // back down at once when the error reverses (no wound-up integral).
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::Ld, k(0), 0)),
            (1, ins(Mnemonic::Ld, k(10), 10)),
            (2, ins(Mnemonic::Ld, k(0), 0)),
            (3, ins(Mnemonic::Ld, Some(Operand::Q(1)), 0)),
            (4, ins(Mnemonic::Pi, k(100), 100)),
            (5, ins(Mnemonic::Wr, Some(Operand::Q(2)), 0)),
        ]);
        vm.set_q(1, 1000);
        for _ in 0..1000 {
            vm.run(&s, &mut |_| {});
        }
        assert_eq!(vm.q(2), 100);
        vm.set_q(1, -1000);
        vm.run(&s, &mut |_| {});
        assert_eq!(vm.q(2), 0);
    }

    #[test]
    fn pwf_from_q_is_clamped_with_one_warning() {
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::Pwf, Some(Operand::Q(0)), 0)),
            (1, ins(Mnemonic::Pr1, None, 0)),
        ]);
        let mut warnings = Vec::new();
        vm.set_q(0, 100);
        for _ in 0..3 {
            vm.run(&s, &mut |w| warnings.push(w));
        }
        assert_eq!(vm.settings().pwf_hz, 488);
        assert_eq!(vm.settings().prescaler, 16);
        assert_eq!(
            warnings,
            vec![VmWarning::PwfClamped {
                line: 0,
                requested: 100,
                applied: 488
            }]
        );
        vm.set_q(0, 9800);
        vm.run(&s, &mut |w| warnings.push(w));
        assert_eq!(vm.settings().pwf_hz, 9800);
        vm.set_q(0, 30000);
        vm.run(&s, &mut |w| warnings.push(w));
        assert_eq!(vm.settings().pwf_hz, 20000);
        assert_eq!(warnings.len(), 2);
    }

    #[test]
    fn du_from_the_source_example() {
        // Rs = 1.95 ohm, Uc = 30 V, Iz = 0.6 A: 1023 * 1.17 / 15 = 79.8 -> 80.
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::RsSet, k(195), 195)),
            (1, ins(Mnemonic::UcSet, k(30), 30)),
            (2, ins(Mnemonic::IzSet, k(60), 60)),
            (3, ins(Mnemonic::CalcDu, None, 0)),
        ]);
        vm.load(&s);
        assert_eq!(vm.settings().du, 80);
        let s = section(&[(0, ins(Mnemonic::DuSet, k(512), 512))]);
        vm.load(&s);
        assert_eq!(vm.settings().du, 512);
    }

    #[test]
    fn sn1_reads_phase_amplitude_frequency_and_clamps_to_fmx() {
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::Fmx, k(700), 700)),
            (1, ins(Mnemonic::Ld, k(900), 900)),
            (2, ins(Mnemonic::Ld, k(450), 450)),
            (3, ins(Mnemonic::Ld, k(100), 100)),
            (4, ins(Mnemonic::Sn1, None, 0)),
            (5, ins(Mnemonic::Ld, k(1200), 1200)),
            (6, ins(Mnemonic::Sn2, None, 0)),
        ]);
        vm.run(&s, &mut |_| {});
        let o = vm.outputs();
        assert_eq!((o.f, o.a, o.phase_decideg), (700, 450, [100, 1200, 0]));
        assert_eq!(o.legs, [LegMode::Sine, LegMode::Sine, LegMode::Unused]);
        assert_eq!(vm.stack(), &[1200, 100, 450, 900, 0]);
    }

    #[test]
    fn settings_apply_at_load_without_running() {
        let mut vm = DriveVm::new(16000);
        let s = section(&[
            (0, ins(Mnemonic::UMax, k(35), 35)),
            (1, ins(Mnemonic::Pwf, k(5620), 5620)),
            (2, ins(Mnemonic::Ld, k(1), 1)),
        ]);
        vm.load(&s);
        assert_eq!(vm.settings().u_max_volts, 35);
        assert_eq!(vm.settings().pwf_hz, 5620);
        assert_eq!(vm.stack(), &[0; 5]);
    }
}
