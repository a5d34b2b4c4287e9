//! A debugger's halt of the core, and what DBGMCU freezes while it lasts.

use super::Soc;
use crate::periph::iwdg::Iwdg;
use crate::periph::tim_adv::TimAdv;
use crate::periph::tim_gp::TimGp;

impl Soc {
    /// Freezes what DBGMCU says while the core is halted by a debugger.
    pub fn debug_halt(&mut self, halted: bool) {
        let now = self.now;
        if self.dbgmcu().tim1_stop() {
            let k = self.wired.tim1;
            self.advance_slot(k, now);
            if let Some(t) = self.model_mut::<TimAdv>(k) {
                t.set_debug_halt(halted, now);
            }
            self.refresh(k);
            self.after_event(k, now);
        }
        if self.dbgmcu().tim4_stop() {
            let k = self.wired.tim_gp[2];
            self.advance_slot(k, now);
            if let Some(t) = self.model_mut::<TimGp>(k) {
                t.set_debug_halt(halted, now);
            }
            self.refresh(k);
        }
        if self.dbgmcu().iwdg_stop() {
            let k = self.iwdg;
            if let Some(w) = self.model_mut::<Iwdg>(k) {
                w.set_frozen(halted, now);
            }
            self.refresh(k);
        }
    }
}
