//! Panics, fatal errors and HardFault: the power stage goes off before anything else,
//! before any logging (review D7).
//!
//! * `core::panic!` (an `expect`, an embassy/PAC assertion, an index out of range) reaches
//!   [`panic`], this image's own `#[panic_handler]`: outputs off, then `panic` over defmt
//!   (no message or location: probe-rs's backtrace at the breakpoint has them), then [`halt`].
//! * The board's own fatal checks call [`fatal`]: the same order.
//! * `defmt::panic!`/`unwrap!` inside embassy log their message first and then reach
//!   [`defmt_panic`]; with RTT in non-blocking mode (`disable-blocking-mode`, review D8)
//!   that log costs a few microseconds, never a wait for the probe.
//! * A HardFault turns the outputs off in [`HardFault`]. A lockup (a fault while the
//!   HardFault handler cannot run, e.g. a stack overflow) never reaches software: SYSCFG
//!   routes it to TIM1's break in hardware (`power_stage::route_system_faults_to_break`).
//!
//! [`halt`] then stops for a debugger (`bkpt`; TIM1 is frozen with its outputs disabled,
//! review D1) or, without one, resets the MCU at once: the reset cause reads as a software
//! reset and the core reports it. It does not wait for the watchdog, which may not have
//! been started yet (a panic during start-up).

use core::panic::PanicInfo;

use board_common::debug::halt;
use cortex_m_rt::{exception, ExceptionFrame};

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
    defmt::error!("fatal: {=str}", reason);
    halt()
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    safe_state();
    board_common::debug::log_panic(info);
    halt()
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    safe_state();
    defmt::error!("HardFault");
    halt()
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    cortex_m::interrupt::disable();
    safe_state();
    halt()
}
