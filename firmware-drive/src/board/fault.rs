//! Panic and HardFault: the power stage goes off before anything else.
//!
//! panic-probe prints the panic message over defmt and then executes `udf`, which lands in
//! the HardFault handler below; `defmt::panic!`/`unwrap!`/`assert!` come through
//! [`defmt_panic`] first. Both force MOE off and the seven power outputs (six gates, brake)
//! low as plain GPIO through the PAC. The core then halts for a debugger, or spins until
//! the independent watchdog restarts the MCU, which the core reports as fault `WDG`.

use cortex_m_rt::{exception, ExceptionFrame};

use super::power_stage;
use crate::pins;

/// Everything that can switch power, off.
#[inline(always)]
fn safe_state() {
    power_stage::force_off();
    pins::force_power_outputs_low();
}

fn halt() -> ! {
    // C_DEBUGEN: a debugger is attached (probe-rs then prints the backtrace).
    const DHCSR: *const u32 = 0xE000_EDF0 as *const u32;
    // SAFETY: DHCSR is a read-only-safe core debug register, always mapped.
    let debugger = unsafe { core::ptr::read_volatile(DHCSR) } & 1 != 0;
    if debugger {
        cortex_m::asm::bkpt();
    }
    loop {
        cortex_m::asm::nop();
    }
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    safe_state();
    halt()
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    safe_state();
    panic_probe::hard_fault()
}
