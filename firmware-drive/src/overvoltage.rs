//! The overvoltage controller of a board without a brake chopper:
//! what industrial drives call the Vdc-max controller. A motor that decelerates faster
//! than its losses allow returns energy to the DC link; without a chopper (the bare
//! B-G431B-ESC1) and on a supply that cannot take energy back (a lab supply, a diode
//! rectifier) that energy can only lift the DC link, by volts per millisecond on a small
//! capacitor. Once the DC link passes its level during a deceleration, the controller
//! takes the applied frequency over from the command, a PI controller on the DC link: it
//! integrates the link's distance from the level ([`GAIN_CENTI_DHZ_PER_MS_PER_VOLT`]),
//! falling while the link is below the level and rising while it is above (a frequency
//! back above the rotor's speed makes the motor draw energy again), plus
//! [`PROPORTIONAL_CENTI_DHZ_PER_VOLT`] per volt above the level; never below the command
//! and at most [`RAISE_LIMIT_DHZ`] above the frequency at which it took over. It hands
//! back when the command is at or above the applied frequency: the stop takes as long as
//! the motor's losses need and ends at 0 Hz instead of in `OV_HW`.
//!
//! The level follows the supply, as SINAMICS' automatic "Vdc_max on level" does:
//! [`LEVEL_MARGIN_VOLTS`] above the supply, never above the cap ([`CAP_BELOW_OV_HW_VOLTS`]
//! below the lower of `U>` and `U>>`, the software trip `OV` and the hardware `OV_HW`). A supply within
//! [`MIN_HEADROOM_DECIVOLTS`] of the cap leaves no room to regulate: the controller is
//! then off and `U>>` protects alone (`docs/drive-core.md`, "Overvoltage without a
//! chopper"). The supply is the DC link with the outputs off; while they switch, the
//! estimate follows the link down at once and up by one count (11 mV) every
//! [`SUPPLY_RISE_TICKS`] ticks while the frequency is not falling (0.7 V/s: a supply
//! turned up is followed, a link pumped up by a deceleration is not).
//!
//! Sans-IO: the DC link in canonical counts and the frequencies in 0.1 Hz in, the
//! frequency to apply out, once per 1 ms tick.

use crate::measure::udc_counts_at_volts;

/// The level sits this far above the supply's DC link, V.
pub const LEVEL_MARGIN_VOLTS: u32 = 1;
/// The level's cap is at least this far below `U>` (`OV`) and `U>>` (`OV_HW`), V:
/// regulation starts before either trip.
pub const CAP_BELOW_OV_HW_VOLTS: u16 = 2;
/// The controller is off when the level is less than this above the supply, 0.1 V.
pub const MIN_HEADROOM_DECIVOLTS: u32 = 5;
/// Integral gain: the applied frequency changes this much per millisecond for each volt
/// between the DC link and the level, 0.01 x 0.1 Hz (0.01 Hz/ms per V: 10 Hz/s per V).
pub const GAIN_CENTI_DHZ_PER_MS_PER_VOLT: i32 = 10;
/// Proportional gain: the applied frequency is raised this much per volt above the level
/// for as long as the link is above it, 0.01 x 0.1 Hz (0.1 Hz per V).
pub const PROPORTIONAL_CENTI_DHZ_PER_VOLT: i32 = 100;
/// Fastest change the controller's integral makes, 0.01 x 0.1 Hz per ms (0.1 Hz/ms).
pub const MAX_STEP_CENTI_DHZ: i32 = 100;
/// The controller raises the frequency at most this far above the one at which it took
/// over, 0.1 Hz (the slip of a small motor is a few hertz).
pub const RAISE_LIMIT_DHZ: i32 = 100;
/// While switching, the supply estimate rises one count per this many ticks.
pub const SUPPLY_RISE_TICKS: u8 = 16;

/// The controller's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OvController {
    /// The highest level, canonical counts; `None`: off (a board with a chopper).
    cap: Option<u32>,
    /// The supply's DC link: the last reading while the motor took energy, counts.
    supply: u32,
    /// The frequency applied in the last tick, 0.01 x 0.1 Hz.
    f_prev: i32,
    /// The controller has taken the frequency over, since it was at this one (0.1 Hz).
    active_from: Option<i16>,
    /// Ticks since the supply estimate last rose.
    rise_ticks: u8,
}

impl OvController {
    /// The cap of the level, V (`None`: no controller).
    pub fn set_cap_volts(&mut self, volts: Option<u16>) {
        self.cap = volts.map(|v| udc_counts_at_volts(u32::from(v)));
    }

    /// The level in effect, canonical counts (`None`: no controller, or no headroom above
    /// the supply).
    pub fn level_counts(&self) -> Option<u32> {
        let margin = udc_counts_at_volts(LEVEL_MARGIN_VOLTS);
        let headroom = MIN_HEADROOM_DECIVOLTS * udc_counts_at_volts(1) / 10;
        self.cap
            .map(|cap| (self.supply + margin).min(cap))
            .filter(|on| *on >= self.supply + headroom)
    }

    /// The controller sets the frequency now (it took over during a deceleration).
    pub fn holding(&self) -> bool {
        self.active_from.is_some()
    }

    /// The frequency to apply (0.1 Hz, >= 0) for the command `f_cmd` with the DC link at
    /// `u_dc` (canonical counts); `switching`: the sine legs switch (otherwise the motor
    /// returns nothing and the controller only measures the supply).
    pub fn step(&mut self, f_cmd: i16, u_dc: u16, switching: bool) -> i16 {
        let f_cmd = f_cmd.max(0);
        let u = u32::from(u_dc);
        let prev = (self.f_prev / 100) as i16;
        let level = self.level_counts();
        let take_over = level.is_some_and(|on| u > on) && f_cmd <= prev;
        let regulate = switching && f_cmd < prev && (self.active_from.is_some() || take_over);
        let (Some(on), true) = (level, regulate) else {
            // Nothing to regulate: the command; the supply estimate follows the link.
            self.rise_ticks = self.rise_ticks.saturating_add(1);
            if !switching || u < self.supply {
                self.supply = u;
            } else if u > self.supply && f_cmd >= prev && self.rise_ticks >= SUPPLY_RISE_TICKS {
                self.supply += 1;
                self.rise_ticks = 0;
            }
            self.active_from = None;
            self.f_prev = i32::from(f_cmd) * 100;
            return f_cmd;
        };
        let from = *self.active_from.get_or_insert(prev);
        // Counts to volts: 91 counts per volt (4095 / 45 V).
        let per_volt = udc_counts_at_volts(1) as i32;
        let below = on as i32 - u as i32;
        let step = (below * GAIN_CENTI_DHZ_PER_MS_PER_VOLT / per_volt)
            .clamp(-MAX_STEP_CENTI_DHZ, MAX_STEP_CENTI_DHZ);
        // At most RAISE_LIMIT_DHZ above where it took over (the rotor runs above the applied
        // frequency by its slip; the motor draws energy again once the frequency is above
        // it), never below the command.
        let top = (i32::from(from) + RAISE_LIMIT_DHZ) * 100;
        let floor = i32::from(f_cmd) * 100;
        let f_i = (self.f_prev - step).min(top).max(floor);
        self.f_prev = f_i;
        if f_i <= floor {
            self.active_from = None;
        }
        // The proportional part acts on this tick only (it damps the loop).
        let p = (-below).max(0) * PROPORTIONAL_CENTI_DHZ_PER_VOLT / per_volt;
        ((f_i + p).min(top) / 100) as i16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counts(v: u32) -> u16 {
        udc_counts_at_volts(v) as u16
    }

    fn ctl(cap: u16, supply_v: u32, f: i16) -> OvController {
        let mut c = OvController::default();
        c.set_cap_volts(Some(cap));
        // Idle on the supply, then running at f.
        assert_eq!(c.step(0, counts(supply_v), false), 0);
        assert_eq!(c.step(f, counts(supply_v), true), f);
        c
    }

    #[test]
    fn off_without_a_cap() {
        let mut c = OvController::default();
        assert_eq!(c.step(500, counts(20), true), 500);
        assert_eq!(c.step(100, counts(40), true), 100);
        assert_eq!(c.level_counts(), None);
    }

    #[test]
    fn the_level_follows_the_supply_under_the_cap() {
        let c = ctl(26, 20, 500);
        assert_eq!(c.level_counts(), Some(udc_counts_at_volts(21)));
        let c = ctl(26, 25, 500);
        assert_eq!(c.level_counts(), Some(udc_counts_at_volts(26)));
        // Within 0.5 V of the cap, or above it: off.
        let c = ctl(26, 26, 500);
        assert_eq!(c.level_counts(), None);
    }

    #[test]
    fn a_deceleration_below_the_level_is_the_commands() {
        let mut c = ctl(26, 20, 500);
        assert_eq!(c.step(300, counts(21), true), 300);
        assert!(!c.holding());
    }

    #[test]
    fn above_the_level_the_frequency_rises_below_it_falls_within_its_bounds() {
        let mut c = ctl(26, 20, 500);
        assert_eq!(c.step(490, counts(20), true), 490);
        // The link passes 21 V: taken over at 49.0 Hz, raised while above.
        let a = c.step(400, counts(22), true);
        assert!(a > 490 && c.holding(), "{a}");
        // Below the level it falls.
        let b = c.step(100, counts(19), true);
        assert!(b < a, "{a} {b}");
        // Far above: at most 10 Hz above where it took over.
        for _ in 0..2000 {
            c.step(100, counts(30), true);
        }
        assert_eq!(c.step(100, counts(30), true), 590);
        // Far below: never below the command, and then the command's again.
        for _ in 0..2000 {
            c.step(560, counts(5), true);
        }
        assert_eq!(c.step(560, counts(5), true), 560);
        assert!(!c.holding(), "caught up with the command");
    }

    #[test]
    fn the_command_rising_above_the_applied_frequency_ends_it() {
        let mut c = ctl(26, 20, 500);
        assert!(c.step(400, counts(22), true) > 500);
        assert_eq!(c.step(600, counts(22), true), 600);
        assert!(!c.holding());
    }

    #[test]
    fn outputs_off_reset_it() {
        let mut c = ctl(26, 20, 500);
        assert!(c.step(100, counts(24), true) > 500);
        assert_eq!(c.step(0, counts(24), false), 0);
        assert!(!c.holding());
    }

    #[test]
    fn the_supply_estimate_follows_down_at_once_and_up_slowly() {
        let mut c = ctl(26, 20, 500);
        // Steady at 50 Hz, the link at 18 V: followed at once.
        assert_eq!(c.step(500, counts(18), true), 500);
        assert_eq!(c.level_counts(), Some(udc_counts_at_volts(19)));
        // Back at 20 V: one count per 16 ticks.
        for _ in 0..32 {
            c.step(500, counts(20), true);
        }
        assert_eq!(c.level_counts(), Some(udc_counts_at_volts(19) + 2));
    }
}
