//! The system-on-chip around the CPU: memories, the bus that routes every access to the
//! register model at that address, clock gating and resets through the RCC, event
//! scheduling, interrupt lines into the NVIC, and the diagnostics a run reports
//! (unmodelled registers, accesses to unclocked peripherals, stuck busy-waits).
//!
//! The SoC is the data of the Unicorn instance ([`crate::cpu`]): the memory-mapped I/O
//! callbacks land in [`Soc::bus_read`] / [`Soc::bus_write`], and the CPU's run loop asks
//! [`Soc::next_event`] how far it may run.
//!
//! One module per job, each an `impl Soc` block over the state declared here:
//! * `registry`: the models, each mapped once, by address and by slot;
//! * `bus`: CPU and DMA accesses routed to memory, the PPB or a model;
//! * `scheduler`: model events in time order, block cycles, polling fast-forward;
//! * `wiring` (with `analog`): signals between models and between models and the board;
//! * `diagnostics`: what a run reports, once each;
//! * `debug_halt`: what DBGMCU freezes while a debugger halts the core;
//! * `clocks`, `faults`: the clock-tree checks and the system break sources.

use crate::periph::adc::Adc12;
use crate::periph::comp::CompBank;
use crate::periph::dac::{Dac, DacId};
use crate::periph::dma::{Dma, DmaInstance};
use crate::periph::dmamux::Dmamux;
use crate::periph::gpio::GpioPort;
use crate::periph::i2c::{I2c, I2cInstance};
use crate::periph::opamp::OpampBank;
use crate::periph::rtc::Rtc;
use crate::periph::tamp::Tamp;
use crate::periph::tim_adv::TimAdv;
use crate::periph::tim_gp::TimGp;
use crate::periph::usart::{Usart, UsartInstance};
use crate::periph::{
    dbgmcu::Dbgmcu, exti::Exti, flash::Flash, iwdg::Iwdg, pwr::Pwr, rcc::Rcc, syscfg::Syscfg,
};
use crate::scs::Scs;
use crate::time::Cycles;
use std::collections::BTreeMap;

mod analog;
mod backup;
mod board;
mod bus;
mod clocks;
mod debug_halt;
mod diagnostics;
mod faults;
mod registry;
mod scheduler;
mod wiring;

pub use board::{BareBoard, Board, BusPins, PinId, VREFINT_VOLTS};
pub use diagnostics::{Diagnostic, StackUse, STORED_ONLY};
pub use faults::SystemBreakSources;
use registry::{push_slot, slot};
pub use registry::{Model, Slot};
use scheduler::Poll;

/// Flash: 128 KiB at 0x0800_0000.
pub const FLASH_BASE: u32 = 0x0800_0000;
pub const FLASH_BYTES: usize = 128 * 1024;
/// SRAM1 + SRAM2 + CCM SRAM, contiguous at 0x2000_0000 on the G431 (32 KiB).
pub const RAM_BASE: u32 = 0x2000_0000;

pub const RAM_BYTES: usize = 32 * 1024;
/// System memory (bootloader ROM, unique ID, flash size), mapped read-only with the ID
/// values the HAL reads. RM0440's memory map (category 2 devices) ends it with the OTP
/// area and the option bytes at 0x1FFF_782F; the rest of the 0x1FFF_xxxx page is reserved
/// and faults. The map covers 0x1FFF_0000..0x1FFF_8000 (Unicorn maps whole 4 KiB pages),
/// so an access above it (a stack pointer run into 0x1FFF_FFF0) faults as on the silicon.
pub const SYSMEM_BASE: u32 = 0x1FFF_0000;
pub const SYSMEM_BYTES: usize = 0x8000;

/// Slot indices of the models the SoC wires to each other or to the host.
#[derive(Debug, Clone, Copy, Default)]
pub struct Slots {
    pub usart: [usize; 5],
    pub dma: [usize; 2],
    pub dmamux: usize,
    pub i2c: [usize; 3],
    pub tim_gp: [usize; 3],
    pub tim1: usize,
    pub tim8: usize,
    pub adc12: usize,
    pub dac: [usize; 2],
    pub comp: usize,
    pub opamp: usize,
    pub rtc: usize,
    pub tamp: usize,
}

/// The USART instances in [`Slots::usart`] order.
pub const USARTS: [UsartInstance; 5] = [
    UsartInstance::Usart1,
    UsartInstance::Usart2,
    UsartInstance::Usart3,
    UsartInstance::Uart4,
    UsartInstance::Lpuart1,
];

/// The I2C instances in [`Slots::i2c`] order.
pub const I2CS: [I2cInstance; 3] = [I2cInstance::I2c1, I2cInstance::I2c2, I2cInstance::I2c3];

/// Why the CPU must stop at the end of the current block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StopRequest {
    /// Interrupt state may have changed (an access raised a line, NVIC/priority write).
    pub irq: bool,
    /// AIRCR.SYSRESETREQ.
    pub system_reset: bool,
}

/// The SoC.
pub struct Soc {
    /// Cycle the CPU has reached (advanced by the CPU's block hook).
    pub now: Cycles,
    /// The CPU stops at the first block boundary at or after this cycle.
    pub deadline: Cycles,
    pub flash: Vec<u8>,
    pub ram: Box<[u8]>,
    pub sysmem: Vec<u8>,
    slots: Vec<Slot>,
    rcc: usize,
    gpio: [usize; 7],
    iwdg: usize,
    dbgmcu: usize,
    syscfg: usize,
    exti: usize,
    pub scs: Scs,
    /// Active exception number (IPSR), kept by the CPU.
    pub ipsr: u16,
    pub board: Box<dyn Board>,
    pub stop: StopRequest,
    diagnostics: Vec<Diagnostic>,
    seen: BTreeMap<(u32, bool, u8), ()>,
    poll: Poll,
    /// The cycle model: each flash block's cost decoded once, the fetch buffer and caches.
    pub cycles: crate::cycles::CycleModel,
    /// The FLASH slot (its ACR sets the wait states and caches the cycle model applies).
    flash_slot: usize,
    /// SysTick has been brought up to this cycle.
    systick_checked: Cycles,
    /// The board's input steps (`Board::next_input_change`) are sampled up to this cycle.
    inputs_checked: Cycles,
    /// Start address of the block the CPU is executing (set by the CPU's block hook).
    pub block: u32,
    /// Where the wired models are.
    pub wired: Slots,
    /// The board's I2C bus pins (SCL, SDA) as (port, pin), per I2C instance: the SoC drives
    /// the bus when the firmware bit-bangs those pins as GPIO (bus recovery).
    i2c_pins: [Option<BusPins>; 3],
    /// A DMA service is running (its register accesses must not start another).
    in_dma: bool,
    /// The timers' system break and its sources (`faults`).
    sys_faults: faults::SystemFaults,
}

/// Unique-ID, flash-size and package words in system memory (RM0440 §48).
fn sysmem_image() -> Vec<u8> {
    let mut m = vec![0xFFu8; SYSMEM_BYTES];
    let mut put = |addr: u32, v: u32| {
        let o = (addr - SYSMEM_BASE) as usize;
        if let Some(s) = m.get_mut(o..o + 4) {
            s.copy_from_slice(&v.to_le_bytes());
        }
    };
    put(0x1FFF_7590, 0x0031_0042); // UID (an arbitrary but fixed unit)
    put(0x1FFF_7594, 0x3131_5004);
    put(0x1FFF_7598, 0x3038_3338);
    put(0x1FFF_75E0, 0xFFFF_0080); // flash size: 128 KiB
    put(0x1FFF_7500, 0xFFFF_FFF4); // package
    put(0x1FFF_75A8, 0x0554_0000 | 0x0000_05F0); // TS/VREFINT calibration words
    m
}

impl Soc {
    /// A G431 with every modelled peripheral at reset, `flash` loaded, on `board`.
    pub fn new(flash: Vec<u8>, board: Box<dyn Board>) -> Self {
        let mut slots: Vec<Slot> = Vec::new();
        let mut add = |s: Slot| push_slot(&mut slots, s);
        let rcc = add(slot("RCC", Box::new(Rcc::default())));
        add(slot("PWR", Box::new(Pwr::new())));
        let flash_slot = add(slot("FLASH", Box::new(Flash::default())));
        let iwdg = add(slot("IWDG", Box::new(Iwdg::new())));
        let syscfg = {
            let mut s = slot("SYSCFG", Box::new(Syscfg::default()));
            // SYSCFG proper is 0x00-0x2F; VREFBUF, COMP and OPAMP follow in the same page.
            s.len = 0x30;
            add(s)
        };
        let exti = add(slot("EXTI", Box::new(Exti::new())));
        let gpio = [0u8, 1, 2, 3, 4, 5, 6].map(|k| {
            let name = [
                "GPIOA", "GPIOB", "GPIOC", "GPIOD", "GPIOE", "GPIOF", "GPIOG",
            ][usize::from(k)];
            add(slot(name, Box::new(GpioPort::new(k))))
        });
        let dbgmcu = {
            let mut s = slot("DBGMCU", Box::new(Dbgmcu::default()));
            s.enable = None;
            add(s)
        };
        let mut soc = Soc {
            now: 0,
            deadline: 0,
            flash,
            ram: vec![0u8; RAM_BYTES].into_boxed_slice(),
            sysmem: sysmem_image(),
            slots,
            rcc,
            gpio,
            iwdg,
            dbgmcu,
            syscfg,
            exti,
            scs: Scs::new(),
            ipsr: 0,
            board,
            stop: StopRequest::default(),
            diagnostics: Vec::new(),
            seen: BTreeMap::new(),
            poll: Poll::default(),
            cycles: crate::cycles::CycleModel::new(FLASH_BYTES),
            flash_slot: 0,
            systick_checked: 0,
            inputs_checked: 0,
            block: 0,
            wired: Slots::default(),
            i2c_pins: [None; 3],
            in_dma: false,
            sys_faults: faults::SystemFaults::default(),
        };
        soc.flash_slot = flash_slot;
        soc.add_wired_models();
        let lse = soc.board.lse_hz().is_some();
        let k = soc.rcc;
        if let Some(r) = soc.model_mut::<Rcc>(k) {
            r.set_lse_fitted(lse);
        }
        soc.flash.resize(FLASH_BYTES, 0xFF);
        soc
    }

    /// The models the helpers wrote, at their metadata addresses.
    fn add_wired_models(&mut self) {
        let mut idx = Slots::default();
        for (k, inst) in USARTS.into_iter().enumerate() {
            idx.usart[k] = self.add(inst.name(), Box::new(Usart::new(inst)));
        }
        idx.dma[0] = self.add("DMA1", Box::new(Dma::new(DmaInstance::Dma1)));
        idx.dma[1] = self.add("DMA2", Box::new(Dma::new(DmaInstance::Dma2)));
        idx.dmamux = self.add("DMAMUX1", Box::new(Dmamux::new()));
        for (k, inst) in I2CS.into_iter().enumerate() {
            idx.i2c[k] = self.add(["I2C1", "I2C2", "I2C3"][k], Box::new(I2c::new(inst)));
        }
        for (k, name) in ["TIM2", "TIM3", "TIM4"].into_iter().enumerate() {
            idx.tim_gp[k] = self.add(name, Box::new(TimGp::new(name)));
        }
        idx.tim1 = self.add("TIM1", Box::new(TimAdv::new("TIM1")));
        idx.tim8 = self.add("TIM8", Box::new(TimAdv::new("TIM8")));
        idx.adc12 = self.add_at(
            "ADC12",
            0x5000_0000,
            0x400,
            Some("ADC1"),
            Box::new(Adc12::new()),
        );
        idx.dac[0] = self.add("DAC1", Box::new(Dac::new(DacId::Dac1)));
        idx.dac[1] = self.add("DAC3", Box::new(Dac::new(DacId::Dac3)));
        idx.comp = self.add_at(
            "COMP",
            0x4001_0200,
            0x10,
            Some("SYSCFG"),
            Box::new(CompBank::new()),
        );
        idx.opamp = self.add_at(
            "OPAMP",
            0x4001_0300,
            0x24,
            Some("SYSCFG"),
            Box::new(OpampBank::new()),
        );
        idx.rtc = self.add("RTC", Box::new(Rtc::new()));
        idx.tamp = self.add("TAMP", Box::new(Tamp::new()));
        self.wired = idx;
    }

    /// The core locked up (or recovered by reset): with SYSCFG_CFGR2.CLL the LOCKUP signal
    /// is a system break of TIM1 and TIM8 (RM0440 Table 271; the other sources: `faults`).
    pub fn lockup(&mut self, locked: bool) {
        self.sys_faults.locked_up = locked;
        self.update_system_break();
    }

    /// The IWDG expired: the MCU must reset.
    pub fn watchdog_expired(&self) -> bool {
        self.iwdg().expired()
    }

    /// Every model back to reset (a system reset); the RCC records `why`.
    pub fn system_reset(&mut self, why: crate::periph::rcc::ResetKind) {
        for k in 0..self.slots.len() {
            if let Some(s) = self.slots.get_mut(k) {
                if k == self.rcc {
                    if let Some(r) = s.model.as_any_mut().downcast_mut::<Rcc>() {
                        r.system_reset(why);
                    }
                } else {
                    s.model.reset();
                }
            }
        }
        // The reset ends LOCKUP and clears SYSCFG_CFGR2's enables: the timers' system break
        // input falls (the comparator and BKIN inputs are the outside world's and stay).
        let now = self.now;
        for k in [self.wired.tim1, self.wired.tim8] {
            if let Some(tim) = self.model_mut::<TimAdv>(k) {
                tim.set_system_break(false, now);
            }
        }
        self.sys_faults = faults::SystemFaults::default();
        for k in 0..self.slots.len() {
            self.refresh(k);
        }
        let debugger = self.scs.debugger;
        self.scs = Scs::new();
        self.scs.debugger = debugger;
        self.ipsr = 0;
        self.poll = Poll::default();
        self.stop = StopRequest::default();
        let now = self.now;
        if why == crate::periph::rcc::ResetKind::PowerOn {
            self.backup_domain_power_on();
        }
        self.sync_backup_domain(now);
        self.cycles.reset();
    }
}
