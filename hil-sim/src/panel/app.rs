//! The panel's state between frames: the co-simulated rig plus the PC-side input state.

use super::keys::{Input, PULSE_MS};
use super::sim_backend::{RigStatus, SimBackend};
use firmware_plc::editor::{Key, Screen};

/// The virtual front panel, independent of the terminal (drawn by [`super::ui`]).
pub struct PanelApp {
    backend: SimBackend,
    digital: u8,
    analog: [u16; 4],
    /// Remaining push-button time per input, ms.
    pulses: [u32; 8],
    /// Wall-clock time for the cursor blink, ms.
    pub blink_ms: u64,
    /// The last keypad key, highlighted on the drawn keypad.
    pub last_key: Option<Key>,
    /// The panel said goodbye.
    pub quit: bool,
}

impl PanelApp {
    pub fn new(backend: SimBackend) -> Self {
        let s = backend.status();
        PanelApp {
            backend,
            digital: s.digital_in,
            analog: s.analog,
            pulses: [0; 8],
            blink_ms: 0,
            last_key: None,
            quit: false,
        }
    }

    /// Apply one input.
    pub fn input(&mut self, input: Input) {
        match input {
            Input::Keypad(k) => {
                self.last_key = Some(k);
                self.backend.key(k);
            }
            Input::Toggle(n) => {
                self.digital ^= 1 << n;
                self.backend.set_digital(n, self.digital & (1 << n) != 0);
            }
            Input::Pulse(n) => {
                self.digital |= 1 << n;
                self.backend.set_digital(n, true);
                if let Some(p) = self.pulses.get_mut(usize::from(n)) {
                    *p = PULSE_MS;
                }
            }
            Input::Analog(n, delta) => {
                if let Some(a) = self.analog.get_mut(usize::from(n)) {
                    *a = (i32::from(*a) + i32::from(delta)).clamp(0, 1023) as u16;
                    self.backend.set_analog(n, *a);
                }
            }
            Input::Quit => self.quit = true,
        }
    }

    /// Let `dt_ms` pass (simulated time and the blink clock), in 1..=10 ms steps so
    /// that push-button releases land on time.
    pub fn advance(&mut self, dt_ms: u32) {
        self.blink_ms += u64::from(dt_ms);
        let mut left = dt_ms;
        while left > 0 {
            let next_release = self
                .pulses
                .iter()
                .filter(|&&p| p > 0)
                .min()
                .copied()
                .unwrap_or(u32::MAX);
            let step = left.min(next_release).clamp(1, 10);
            self.backend.advance(step);
            left -= step;
            for (n, p) in self.pulses.iter_mut().enumerate() {
                if *p > 0 {
                    *p = p.saturating_sub(step);
                    if *p == 0 {
                        self.digital &= !(1 << n);
                        self.backend.set_digital(n as u8, false);
                    }
                }
            }
        }
    }

    pub fn lcd(&self) -> Screen {
        self.backend.lcd()
    }

    /// The rig behind the panel.
    pub fn backend(&self) -> &SimBackend {
        &self.backend
    }

    pub fn status(&self) -> RigStatus {
        let mut s = self.backend.status();
        s.digital_in = self.digital;
        s.analog = self.analog;
        s
    }
}
