//! Panics, fatal errors and HardFault: the power stage goes off before anything else,
//! before any logging.
//!
//! * `core::panic!` (an `expect`, an embassy/PAC assertion, an index out of range) reaches
//!   [`panic`], this image's own `#[panic_handler]`: outputs off, then `panic` over defmt
//!   (no message or location: probe-rs's backtrace at the breakpoint has them), then [`halt`].
//! * The board's own fatal checks call [`fatal`]: the same order.
//! * `defmt::panic!`/`unwrap!` inside embassy log their message first and then reach
//!   [`defmt_panic`]; with RTT in non-blocking mode (`disable-blocking-mode`)
//!   that log costs a few microseconds, never a wait for the probe.
//! * A HardFault turns the outputs off in [`HardFault`]; the NMI in [`NonMaskableInt`] and every
//!   exception without a handler of its own in [`DefaultHandler`], before anything else.
//!   A flash double-ECC error or an SRAM parity error (the NMI's sources on
//!   this image) also reach TIM1's system break (`power_stage::route_system_faults_to_break`):
//!   the NMI clears its flag and returns, and the break interrupt has the core latch
//!   `BOOT` and report it; any other NMI halts.
//! * Only the first fault path logs (`board_common::debug::first_fault`): a fault inside a
//!   defmt frame makes the log panic ("logger taken reentrantly"), and that nested panic
//!   goes straight to [`halt`].
//! * A lockup (a fault while the
//!   HardFault handler cannot run, e.g. a stack overflow) never reaches software: SYSCFG
//!   routes it to TIM1's break in hardware (`power_stage::route_system_faults_to_break`).
//!
//! [`halt`] then stops for a debugger (`bkpt`; TIM1 is frozen with its outputs disabled)
//! or, without one, resets the MCU at once: the reset cause reads as a software
//! reset and the core reports it. It does not wait for the watchdog, which may not have
//! been started yet (a panic during start-up).

use core::panic::PanicInfo;

use board_common::debug::{first_fault, halt};
use cortex_m_rt::{exception, ExceptionFrame};
use embassy_stm32::pac;

use super::power_stage;
use crate::pins;

/// Everything that can switch power, off.
#[inline(always)]
fn safe_state() {
    power_stage::force_off();
    pins::force_power_outputs_low();
}

/// The one reason for every board-profile table entry the board cannot bind (an OPAMP,
/// pin, gain, ADC input or blanking source the G431 or this board lacks): one string in
/// flash instead of one per check. The core's unit tests keep the tables bindable.
pub const UNBINDABLE_PROFILE: &str = "board profile entry not bindable";

/// A check of the board layer failed: outputs off, the reason logged, halt.
pub fn fatal(reason: &'static str) -> ! {
    cortex_m::interrupt::disable();
    safe_state();
    if first_fault() {
        defmt::error!("fatal: {=str}", reason);
    }
    halt()
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    safe_state();
    if first_fault() {
        board_common::debug::log_panic(info);
    }
    halt()
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    safe_state();
    if first_fault() {
        defmt::error!("HardFault");
    }
    halt()
}

/// Outputs off first. A flash double-ECC error (FLASH_ECCR.ECCD) or an SRAM parity error
/// (SYSCFG_CFGR2.SPF) has also set TIM1's system break (ECCL/SPL): its flag is cleared
/// (rc_w1) so that the NMI does not repeat, and the break interrupt reports the fault
/// (`BOOT`) over the link. An NMI with neither flag (nothing else raises it here) halts.
#[exception]
unsafe fn NonMaskableInt() {
    safe_state();
    let flash = pac::FLASH.eccr().read();
    let syscfg = pac::SYSCFG.cfgr2().read();
    if flash.eccd() {
        pac::FLASH.eccr().write_value(flash);
    }
    if syscfg.spf() {
        pac::SYSCFG.cfgr2().write_value(syscfg);
    }
    if !flash.eccd() && !syscfg.spf() {
        unknown_exception("NMI")
    }
}

/// Every exception and interrupt without a handler of its own.
#[exception]
unsafe fn DefaultHandler(_irqn: i16) -> ! {
    unknown_exception("unexpected exception")
}

/// Outputs off, logged once, halt.
fn unknown_exception(what: &'static str) -> ! {
    cortex_m::interrupt::disable();
    safe_state();
    if first_fault() {
        defmt::error!("{=str}", what);
    }
    halt()
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    cortex_m::interrupt::disable();
    safe_state();
    halt()
}
