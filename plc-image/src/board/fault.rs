//! Panics and HardFault: the outputs Q0-Q5 go off before anything else, before any
//! logging, as on the drive (`drive-image/src/board/fault.rs`).
//!
//! * `core::panic!` (an `expect`, an embassy/PAC assertion) reaches [`panic`], this image's
//!   own `#[panic_handler]`: outputs off, then `panic` over defmt (no message or location:
//!   probe-rs's backtrace at the breakpoint has them), then [`halt`].
//! * `defmt::panic!`/`unwrap!` inside embassy log their message first and then reach
//!   [`defmt_panic`]: outputs off, [`halt`].
//! * A HardFault turns the outputs off in [`HardFault`], the NMI (a flash double-ECC or SRAM
//!   parity error) in [`NonMaskableInt`] and every exception without a handler of its own in
//!   [`DefaultHandler`], before anything else, then halt.
//! * Only the first fault path logs (`board_common::debug::first_fault`): a fault inside a
//!   defmt frame makes the log panic ("logger taken reentrantly"), and that nested panic
//!   goes straight to [`halt`].
//!
//! [`halt`] stops for a debugger (`bkpt`) or, without one, resets the MCU at once: it does
//! not wait for the watchdog, which may not have been started yet (a panic during
//! start-up). After the reset the outputs are inputs again (analog mode) until the
//! application drives them low.

use core::panic::PanicInfo;

use board_common::debug::{first_fault, halt};
use cortex_m_rt::{exception, ExceptionFrame};

use crate::pins;

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    pins::force_outputs_low();
    if first_fault() {
        board_common::debug::log_panic(info);
    }
    halt()
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    stop("HardFault")
}

/// A flash double-ECC or SRAM parity error: the program or its data cannot be trusted.
#[exception]
unsafe fn NonMaskableInt() {
    stop("NMI")
}

/// Every exception and interrupt without a handler of its own.
#[exception]
unsafe fn DefaultHandler(_irqn: i16) -> ! {
    stop("unexpected exception")
}

/// Outputs off, logged once, halt.
fn stop(what: &'static str) -> ! {
    cortex_m::interrupt::disable();
    pins::force_outputs_low();
    if first_fault() {
        defmt::error!("{=str}", what);
    }
    halt()
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    cortex_m::interrupt::disable();
    pins::force_outputs_low();
    halt()
}
