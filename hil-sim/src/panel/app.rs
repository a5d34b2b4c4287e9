//! The panel's state between frames: the co-simulated rig plus the PC-side input state.

use std::path::PathBuf;

use super::files::{program_text, write_atomically};
use super::keys::{Input, RigAction, TextKey, BANK_SIZE, PULSE_MS};
use super::sim_backend::{RigStatus, SimBackend};
use firmware_plc::editor::{Key, Screen};
use shared_protocol::program::DIGITAL_INPUTS;

/// A question the panel asks on its bottom line; keys answer it instead of reaching the
/// keypad.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Modal {
    /// Quit although work would be lost? `y` quits, `n` or Esc goes back.
    ConfirmQuit(QuitLoss),
    /// The file to export the program to, being typed; `overwrite` once Enter was
    /// pressed on an existing file (Enter again overwrites it).
    Export { name: String, overwrite: bool },
}

/// What quitting now would lose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QuitLoss {
    /// The program in RAM differs from the one last saved or loaded.
    UnsavedProgram,
    /// Programs saved to slots in this session: without `--eeprom FILE` the EEPROM lives
    /// only as long as the panel.
    SavedSlots,
    /// Both.
    Both,
}

/// The virtual front panel, independent of the terminal (drawn by [`super::ui`]).
pub struct PanelApp {
    backend: SimBackend,
    digital: u16,
    /// The bank the digital keys act on: 0 = D00-D07, 1 = D08-D15.
    bank: u8,
    analog: [u16; 4],
    /// Remaining push-button time per input, ms.
    pulses: [u32; DIGITAL_INPUTS as usize],
    /// Wall-clock time for the cursor blink, ms.
    pub blink_ms: u64,
    /// The last keypad key, highlighted on the drawn keypad.
    pub last_key: Option<Key>,
    /// The panel said goodbye.
    pub quit: bool,
    /// The question being asked, if any.
    pub modal: Option<Modal>,
    /// The panel's last message (export done, file errors), on its bottom line.
    pub notice: Option<String>,
    /// The name offered for an export.
    pub export_default: PathBuf,
    /// Esc came while keypad keys were still queued: decided once they are pressed.
    esc_deferred: bool,
}

impl PanelApp {
    pub fn new(backend: SimBackend) -> Self {
        let s = backend.status();
        PanelApp {
            backend,
            digital: s.digital_in,
            bank: 0,
            analog: s.analog,
            pulses: [0; DIGITAL_INPUTS as usize],
            blink_ms: 0,
            last_key: None,
            quit: false,
            modal: None,
            notice: None,
            export_default: PathBuf::from("program-panel.plc"),
            esc_deferred: false,
        }
    }

    /// Apply one input.
    pub fn input(&mut self, input: Input) {
        if self.modal.is_some() {
            // Keys answer the question (the event loop sends them as `TextKey`s).
            return;
        }
        match input {
            Input::Keypad(k) => {
                self.last_key = Some(k);
                self.backend.key(k);
            }
            Input::Bank => {
                self.bank = (self.bank + 1) % DIGITAL_INPUTS.div_ceil(BANK_SIZE);
            }
            Input::Toggle(n) => {
                let n = n + self.bank * BANK_SIZE;
                self.digital ^= 1 << n;
                self.backend.set_digital(n, self.digital & (1 << n) != 0);
            }
            Input::Pulse(n) => {
                let n = n + self.bank * BANK_SIZE;
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
            Input::Esc => {
                if self.backend.keys_idle() {
                    self.esc();
                } else {
                    self.esc_deferred = true;
                }
            }
            Input::Rig(a) => self.rig(a),
            Input::Quit => self.request_quit(),
            Input::Export => {
                self.modal = Some(Modal::Export {
                    name: self.export_default.display().to_string(),
                    overwrite: false,
                });
            }
        }
    }

    fn rig(&mut self, a: RigAction) {
        let b = &mut self.backend;
        match a {
            RigAction::SupplyV(dv) => b.adjust_supply(dv),
            RigAction::LoadNm(dt) => b.adjust_load(dt),
            RigAction::LockedRotor => b.toggle_locked_rotor(),
            RigAction::Link => b.toggle_link(),
            RigAction::CurrentSpike => b.current_spike(),
            RigAction::VoltageSpike => b.voltage_spike(),
            RigAction::SensorFault => b.toggle_sensor_fault(),
            RigAction::PowerCycleDrive => b.power_cycle_drive(),
            RigAction::WatchdogReset => b.watchdog_reset_drive(),
            RigAction::GarbleDownload => b.toggle_garble_download(),
        }
    }

    /// Esc with the keypad idle: `*` (cancel) when the editor waits for keys, else quit.
    fn esc(&mut self) {
        if self.backend.awaiting_keys() {
            self.input(Input::Keypad(Key::Star));
        } else {
            self.request_quit();
        }
    }

    /// Quit, asking first when the program is unsaved or saved slots would be lost.
    fn request_quit(&mut self) {
        let unsaved = self.backend.unsaved();
        let slots = self.backend.saved_slots_would_be_lost();
        self.modal = match (unsaved, slots) {
            (false, false) => return self.finish_quit(),
            (true, false) => Some(Modal::ConfirmQuit(QuitLoss::UnsavedProgram)),
            (false, true) => Some(Modal::ConfirmQuit(QuitLoss::SavedSlots)),
            (true, true) => Some(Modal::ConfirmQuit(QuitLoss::Both)),
        };
    }

    fn finish_quit(&mut self) {
        self.modal = None;
        match self.backend.flush() {
            Ok(()) => self.quit = true,
            // Keep the panel open: quitting now would lose the saved slots.
            Err(e) => self.notice = Some(format!("EEPROM file not written, not quitting: {e:#}")),
        }
    }

    /// A key while a question is asked.
    pub fn modal_key(&mut self, key: TextKey) {
        let Some(modal) = self.modal.take() else {
            return;
        };
        match modal {
            Modal::ConfirmQuit(loss) => match key {
                TextKey::Char('y' | 'Y') => self.finish_quit(),
                TextKey::Char('n' | 'N') | TextKey::Esc => {}
                _ => self.modal = Some(Modal::ConfirmQuit(loss)),
            },
            Modal::Export {
                mut name,
                overwrite,
            } => match key {
                TextKey::Esc => self.notice = Some("export cancelled".into()),
                TextKey::Enter => {
                    let path = PathBuf::from(name.trim());
                    if name.trim().is_empty() {
                        self.modal = Some(Modal::Export { name, overwrite });
                    } else if path.exists() && !overwrite {
                        self.modal = Some(Modal::Export {
                            name,
                            overwrite: true,
                        });
                    } else {
                        self.export(&path);
                    }
                }
                TextKey::Backspace => {
                    name.pop();
                    self.modal = Some(Modal::Export {
                        name,
                        overwrite: false,
                    });
                }
                TextKey::Char(c) => {
                    name.push(c);
                    self.modal = Some(Modal::Export {
                        name,
                        overwrite: false,
                    });
                }
            },
        }
    }

    /// Writes the program in RAM to `path` as `.plc` text.
    fn export(&mut self, path: &std::path::Path) {
        let program = self.backend.program();
        let lines = program.lines.iter().filter(|l| l.is_some()).count();
        let text = program_text(program);
        self.notice = Some(match write_atomically(path, text.as_bytes()) {
            Ok(()) => {
                let editing = if self.backend.editing() {
                    " (the field being edited is not in it: 5 first)"
                } else {
                    ""
                };
                format!("exported {lines} lines to {}{editing}", path.display())
            }
            Err(e) => format!("export failed: {e:#}"),
        });
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
            if self.esc_deferred && self.backend.keys_idle() {
                self.esc_deferred = false;
                self.esc();
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

    pub fn backend_mut(&mut self) -> &mut SimBackend {
        &mut self.backend
    }

    /// The bank the digital keys act on: 0 = D00-D07, 1 = D08-D15.
    pub fn bank(&self) -> u8 {
        self.bank
    }

    pub fn status(&self) -> RigStatus {
        let mut s = self.backend.status();
        s.digital_in = self.digital;
        s.analog = self.analog;
        s
    }
}
