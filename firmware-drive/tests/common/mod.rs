//! A minimal bench around `DriveCore`: PWM periods at the timer's real rate, the 1 ms
//! tick, and a fixed ADC sample (no motor model: hil-sim has that).
#![allow(dead_code)]

use firmware_drive::{
    AdcSample, DriveCommand, DriveConfig, DriveCore, DriveEvent, PwmCommand, ResetCause,
};
use shared_protocol::program::assemble;

pub struct Rig {
    pub core: DriveCore,
    pub sample: AdcSample,
    /// Milliseconds since RUN (or since the rig started).
    pub ms: u64,
    acc_millihertz: u64,
    pub events: Vec<(u64, DriveEvent)>,
}

impl Rig {
    /// Booted, program loaded, 30 V on the DC link, zero current; not yet running.
    pub fn new(text: &str) -> Rig {
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let sample = AdcSample {
            u_dc: 2730,
            ..AdcSample::default()
        };
        // The boot period only runs the self-test; its (off) command is not needed.
        let _ = core.pwm_period(&sample);
        let mut rig = Rig {
            core,
            sample,
            ms: 0,
            acc_millihertz: 0,
            events: Vec::new(),
        };
        rig.step_ms(|_| {});
        let p = assemble(text).expect("example assembles").drive_section();
        rig.core.load_program(&p).expect("example verifies");
        rig
    }

    pub fn cmd(&mut self, c: DriveCommand) {
        self.core.command(c).expect("command accepted");
    }

    /// One millisecond: the PWM periods that fit in it, then the tick.
    pub fn step_ms(&mut self, mut on_period: impl FnMut(&PwmCommand)) {
        self.acc_millihertz += u64::from(self.core.pwm_timing().pwm_millihertz);
        let n = self.acc_millihertz / 1_000_000;
        self.acc_millihertz %= 1_000_000;
        for _ in 0..n {
            let c = self.core.pwm_period(&self.sample);
            on_period(&c);
        }
        let ms = self.ms;
        let events = &mut self.events;
        self.core.tick_1ms(&mut |e| events.push((ms, e)));
        self.ms += 1;
    }

    pub fn run_ms(&mut self, ms: u64) {
        for _ in 0..ms {
            self.step_ms(|_| {});
        }
    }
}

/// Amplitude and phase (rad) of the component at `cycles` per record of `x`.
pub fn dft_bin(x: &[f64], cycles: f64) -> (f64, f64) {
    let n = x.len() as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let a = std::f64::consts::TAU * cycles * k as f64 / n;
        re += v * a.cos();
        im -= v * a.sin();
    }
    ((re * re + im * im).sqrt() * 2.0 / n, im.atan2(re))
}
