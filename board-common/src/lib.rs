//! What the two STM32G431 board layers (`firmware-drive`, `firmware-plc`) share: register
//! and driver binding only. Every decision in here is core code with host tests, called
//! from these modules: the link pump (`shared_protocol::link::pump`), the watchdog's
//! feeding rule and the reset-cause decoding (`shared_protocol::supervision`), the log
//! rate limiter (`shared_protocol::rate_limit`).
//!
//! * `clocks`: the 170 MHz configuration both boards run at, boost mode and the flash
//!   prefetch.
//! * `reset_cause`: RCC_CSR read and cleared before embassy starts.
//! * `boot`: the boot sequence (reset cause, embassy at 170 MHz, interrupt priorities
//!   below the drive's TIM1, boot line).
//! * `banner`: the boot line.
//! * `debug`: what a halted core freezes (DBGMCU), and `halt` (debugger or reset), the end
//!   of both images' panic and fault handlers.
//! * `supervisor`: the task that feeds the IWDG while every task reports alive.
//! * `link`: the link USART (pull-up on RX, line-error recovery) and the pump task.
//! * `link_rx`: the link's receiver, a DMA ring that a line error never stops (N13).
//! * `cycles`: DWT cycle counters (feature `dwt-cycles`).
//! * `time`: the monotonic clock the cores take.
//! * `mem`: the EABI copy and fill helpers (`__aeabi_memcpy` ..), smaller than
//!   `compiler_builtins`' (linked into both images by being here; nothing calls it by name).
//!
//! Target only: on the host this crate is empty (so the module names above are plain text
//! in the host docs), and `cargo test --workspace` never builds embassy.
#![no_std]

#[cfg(target_os = "none")]
pub mod banner;
#[cfg(target_os = "none")]
pub mod boot;
#[cfg(target_os = "none")]
pub mod clocks;
#[cfg(all(target_os = "none", feature = "dwt-cycles"))]
pub mod cycles;
#[cfg(target_os = "none")]
pub mod debug;
#[cfg(target_os = "none")]
pub mod link;
#[cfg(target_os = "none")]
pub mod link_rx;
#[cfg(target_os = "none")]
mod mem;
#[cfg(target_os = "none")]
pub mod reset_cause;
#[cfg(target_os = "none")]
pub mod supervisor;
#[cfg(target_os = "none")]
pub mod time;
