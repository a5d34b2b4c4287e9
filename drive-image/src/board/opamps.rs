//! The on-chip amplifiers of the board profile's front end (`firmware_drive::front_end`):
//! each listed OPAMP in PGA mode, its output to the ADC internally. The table decides which
//! amplifier, input pin and gain; this module writes OPAMPx_CSR from it and decides nothing.
//!
//! Through the PAC, not embassy-stm32 0.6's `OpAmp::pga_int`: that driver takes the input
//! pin's type (the table's pin cannot select it), and its output token disables the
//! amplifier when dropped. [`apply`] runs after the ADCs' injected sequences are armed
//! ([`super::analog`]) and leaves the amplifiers on.
//!
//! The factory offset trim is kept (USERTRIM = 0): the boot zero calibration of the core
//! measures the whole chain's offset (bias network, amplifier, ADC) at 0 A.

use embassy_stm32::pac;
use embassy_stm32::pac::opamp::vals::{PgaGain, VmSel, VpSel};
use firmware_drive::front_end::FrontEndSpec;

/// Time allowed after OPAEN before TIM1 starts triggering conversions. The datasheet's
/// wake-up time is a bench item (`docs/bench-check.md`); a sample taken while an amplifier
/// still starts reads near 0 V, which the core's boot zero calibration rejects (`BOOT`)
/// rather than calibrating on it.
pub const STARTUP_US: u64 = 20;

/// Writes every amplifier of `fe` (VP_SEL from the table's pin, VM_SEL = PGA, PGA_GAIN,
/// high-speed mode, OPAINTOEN, OPAEN) and waits [`STARTUP_US`].
pub fn apply(fe: &FrontEndSpec) {
    for o in fe.opamps {
        let regs = match o.opamp {
            1 => pac::OPAMP1,
            2 => pac::OPAMP2,
            3 => pac::OPAMP3,
            _ => super::fault::fatal(super::fault::UNBINDABLE_PROFILE),
        };
        let (Some(vp), Some(gain)) = (o.vp_sel(), o.pga_gain_bits()) else {
            super::fault::fatal(super::fault::UNBINDABLE_PROFILE);
        };
        regs.csr().modify(|w| {
            w.set_vp_sel(VpSel::from_bits(vp));
            w.set_vm_sel(VmSel::PGA);
            w.set_pga_gain(PgaGain::from_bits(gain));
            w.set_opahsm(true);
            w.set_opaintoen(true);
            w.set_opampen(true);
        });
    }
    if !fe.opamps.is_empty() {
        embassy_time::block_for(embassy_time::Duration::from_micros(STARTUP_US));
    }
}
