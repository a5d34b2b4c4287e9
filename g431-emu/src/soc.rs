//! The system-on-chip around the CPU: memories, the bus that routes every access to the
//! register model at that address, clock gating and resets through the RCC, event
//! scheduling, interrupt lines into the NVIC, and the diagnostics a run reports
//! (unmodelled registers, accesses to unclocked peripherals, stuck busy-waits).
//!
//! The SoC is the data of the Unicorn instance ([`crate::cpu`]): the memory-mapped I/O
//! callbacks land in [`Soc::bus_read`] / [`Soc::bus_write`], and the CPU's run loop asks
//! [`Soc::next_event`] how far it may run.

use std::any::Any;
use std::collections::BTreeMap;

use crate::names;
use crate::periph::adc::{Adc12, AdcId, AnalogSource, TriggerSignal};
use crate::periph::analog_errors::AnalogErrors;
use crate::periph::comp::{BlankingSource, CompBank, CompConfig, InvertingInput};
use crate::periph::dac::{Dac, DacId};
use crate::periph::dma::{Dma, DmaInstance, Transfer};
use crate::periph::dmamux::Dmamux;
use crate::periph::gpio::{Drive, GpioPort, PinReader};
use crate::periph::i2c::{I2c, I2cInstance, SharedDevice};
use crate::periph::opamp::{OpampBank, OpampConfig, OpampInput};
use crate::periph::tim_adv::{TimAdv, TimEvent};
use crate::periph::tim_gp::TimGp;
use crate::periph::usart::{Usart, UsartInstance};
use crate::periph::{
    dbgmcu::Dbgmcu, exti::Exti, flash::Flash, iwdg::Iwdg, pwr::Pwr, rcc::Rcc, syscfg::Syscfg,
};
use crate::periph::{DmaRequests, IrqLines, Peripheral, Write};
use crate::scs::Scs;
use crate::time::{Cycles, CYCLES_PER_US};

mod clocks;
mod faults;
pub use faults::SystemBreakSources;

/// Flash: 128 KiB at 0x0800_0000.
pub const FLASH_BASE: u32 = 0x0800_0000;
pub const FLASH_BYTES: usize = 128 * 1024;
/// SRAM1 + SRAM2 + CCM SRAM, contiguous at 0x2000_0000 on the G431 (32 KiB).
pub const RAM_BASE: u32 = 0x2000_0000;

/// How deep a flip-link stack has been ([`Soc::stack_high_water`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackUse {
    /// The whole stack: from the bottom of RAM to the initial stack pointer.
    pub size_bytes: u32,
    /// The deepest it has been.
    pub used_bytes: u32,
}
pub const RAM_BYTES: usize = 32 * 1024;
/// System memory (bootloader ROM, unique ID, flash size), mapped read-only with the ID
/// values the HAL reads. RM0440's memory map (category 2 devices) ends it with the OTP
/// area and the option bytes at 0x1FFF_782F; the rest of the 0x1FFF_xxxx page is reserved
/// and faults. The map covers 0x1FFF_0000..0x1FFF_8000 (Unicorn maps whole 4 KiB pages),
/// so an access above it (a stack pointer run into 0x1FFF_FFF0) faults as on the silicon.
pub const SYSMEM_BASE: u32 = 0x1FFF_0000;
pub const SYSMEM_BYTES: usize = 0x8000;

/// Registers of the RCC and PWR models that are plain storage: their value changes nothing
/// in the emulator, so the first change of each is reported (review E5: they were
/// accepted silently). (block, offset, what the silicon would do with it.)
pub const STORED_ONLY: &[(&str, u32, &str)] = &[
    (
        "PWR",
        0x08,
        "CR3: wake-up pins, standby pulls (APC), UCPD dead-battery pulls",
    ),
    ("PWR", 0x0C, "CR4: wake-up polarity, VBAT charging"),
    (
        "PWR",
        0x20,
        "PUCRA..PDCRG: pulls applied in Standby/Shutdown",
    ),
    ("RCC", 0x68, "AHB1SMENR: clocks kept in Sleep mode"),
    ("RCC", 0x6C, "AHB2SMENR"),
    ("RCC", 0x70, "AHB3SMENR"),
    ("RCC", 0x78, "APB1SMENR1"),
    ("RCC", 0x7C, "APB1SMENR2"),
    ("RCC", 0x80, "APB2SMENR"),
    ("RCC", 0x90, "BDCR: LSE, RTC clock, backup domain reset"),
    ("RCC", 0x9C, "CCIPR2: I2C4 and QUADSPI kernel clocks"),
];

/// Register `offset` of block `name` is plain storage ([`STORED_ONLY`]; PWR's PUCRx/PDCRx
/// are one entry for 0x20..0x5C).
fn is_stored_only(name: &str, offset: u32) -> bool {
    let offset = if name == "PWR" && (0x20..0x60).contains(&offset) {
        0x20
    } else {
        offset
    };
    STORED_ONLY
        .iter()
        .any(|(b, o, _)| *b == name && *o == offset)
}

/// DBGMCU, in the private peripheral bus (RM0440 §47.16).
const DBGMCU_BASE: u32 = 0xE004_2000;

/// A free-running counter read by a polling loop does not break its "nothing changes"
/// streak, but caps how far the clock may jump (the loop may be waiting for a time).
const COUNTER_POLL_JUMP: Cycles = 10 * CYCLES_PER_US;
/// Identical reads of one register, by the same block, in a row before it counts as a
/// polling loop. High enough that a bounded loop over pins or columns (a keypad scan reads
/// one IDR four times) is never taken for a poll: fast-forwarding it would stretch its time.
const POLL_STREAK: u32 = 64;

/// A register model together with what it implements for the SoC.
pub trait Model: Peripheral + Any {
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Peripheral + Any> Model for T {
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// One mapped register model.
pub struct Slot {
    pub name: &'static str,
    pub base: u32,
    pub len: u32,
    /// RCC enable bit (register offset, bit); `None` = always clocked.
    pub enable: Option<(u32, u32)>,
    /// RCC reset bit.
    pub reset_bit: Option<(u32, u32)>,
    pub model: Box<dyn Model>,
    next: Option<Cycles>,
    irqs: IrqLines,
    dma: DmaRequests,
}

/// Something a run found that a test or a user should see.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Diagnostic {
    /// A register no model implements, by name (first access only).
    Unmodelled { what: String, write: bool },
    /// An access to a peripheral whose RCC clock is off (reads 0, writes ignored, as on
    /// the chip).
    Unclocked { what: String, write: bool },
    /// An access to an address where nothing is mapped.
    Unmapped { addr: u32, write: bool },
    /// A polling loop on a register that nothing will ever change.
    StuckPoll { what: String, value: u32 },
    /// An input pin read while nothing drives it and no pull is on.
    FloatingInput { pin: String },
    /// A register the model only stores was changed (first change only): the silicon would
    /// act on the new value, the emulator does not ([`STORED_ONLY`]).
    StoredOnly { what: String, value: u32 },
    /// A model saw the software use something it does not model, or use it in a way the
    /// reference manual forbids.
    Model(String),
}

impl std::fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Diagnostic::Unmodelled { what, write } => {
                let rw = if *write { "write to" } else { "read of" };
                write!(f, "{rw} unmodelled register {what}")
            }
            Diagnostic::Unclocked { what, write } => {
                let rw = if *write { "write to" } else { "read of" };
                write!(f, "{rw} {what} while its clock is off")
            }
            Diagnostic::Unmapped { addr, write } => {
                let rw = if *write { "write to" } else { "read of" };
                write!(f, "{rw} unmapped address {addr:#010x}")
            }
            Diagnostic::StuckPoll { what, value } => write!(
                f,
                "busy-wait on {what} (reads {value:#010x}) that nothing will ever change"
            ),
            Diagnostic::FloatingInput { pin } => write!(f, "input {pin} read while floating"),
            Diagnostic::StoredOnly { what, value } => write!(
                f,
                "{what} set to {value:#010x}: stored only, its effect is not modelled"
            ),
            Diagnostic::Model(m) => write!(f, "{m}"),
        }
    }
}

/// The board around the MCU: pin levels, analog voltages, the power stage.
pub trait Board: PinReader {
    /// Output pins changed at `now`; `drives(port, pin)` is how the MCU drives each pin.
    fn outputs_changed(&mut self, _now: Cycles, _drives: &dyn Fn(u8, u8) -> Drive) {}

    /// Volts on pin `pin` ("PA1") at `at` (ADC sampling, comparator inputs, OPAMP inputs).
    fn pin_volts(&mut self, _pin: &str, _at: Cycles) -> f64 {
        0.0
    }

    /// TIM1 changed its outputs (an update with new compares, MOE, a break, the debug
    /// freeze): the power stage follows from `ev.at`.
    fn power_stage(&mut self, _ev: &TimEvent) {}

    /// Whether comparator `config.comp`'s non-inverting input is above `level` now: the level
    /// it must pass next (INM with the part's input offset and, while the comparator is high,
    /// its hysteresis below INM: `CompBank::threshold`). A board that knows of a crossing
    /// between two calls may report it (a short overcurrent between two samples trips the
    /// hardware). The default compares the pin's volts now.
    fn comparator_above(&mut self, config: &CompConfig, level: f64, at: Cycles) -> bool {
        self.pin_volts(config.inp, at) > level
    }

    /// The first cycle after `after` at which the board's analog inputs change by a step
    /// (a disturbance that starts or ends), `None` when none is known. The SoC samples the
    /// comparators there, as it does at TIM1's events: the silicon's comparator follows its
    /// input continuously, so a step between two TIM1 events reaches its output tD after
    /// the step, not at the next event (a spike that ended inside a blanking window does
    /// not show when the window closes).
    fn next_input_change(&self, _after: Cycles) -> Option<Cycles> {
        None
    }
}

/// VREFINT (DS12589 typical), for the comparators' scaled references and the ADC.
pub const VREFINT_VOLTS: f64 = 1.212;

/// A bare board: nothing connected.
pub struct BareBoard;

impl PinReader for BareBoard {
    fn external(
        &mut self,
        _: u8,
        _: u8,
        _: Cycles,
        _: &dyn Fn(u8, u8) -> Drive,
    ) -> crate::periph::gpio::External {
        crate::periph::gpio::External::Floating
    }
}

impl Board for BareBoard {}

/// A pin as (port, number): `(1, 8)` is PB8.
pub type PinId = (u8, u8);

/// An I2C bus's (SCL, SDA) pins on the board.
pub type BusPins = (PinId, PinId);

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

/// Tracks a possible polling loop: identical reads of one register.
#[derive(Debug, Clone, Copy, Default)]
struct Poll {
    block: u32,
    addr: u32,
    value: u32,
    streak: u32,
    /// A free-running counter was read in between.
    counter: bool,
    /// Reads of one counter from one block in a row with nothing else in between (a loop
    /// waiting for a time, e.g. `block_for`): (block, register, streak).
    counter_loop: (u32, u32, u32),
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

fn slot(name: &'static str, model: Box<dyn Model>) -> Slot {
    let base = names::base(name).unwrap_or(0);
    let len = names::block_bytes(name).unwrap_or(0x400);
    Slot {
        name,
        base,
        len,
        enable: names::rcc_enable(name),
        reset_bit: names::rcc_reset(name),
        model,
        next: None,
        irqs: IrqLines::default(),
        dma: DmaRequests::default(),
    }
}

/// Maps `s` after the blocks in `slots` and returns its index.
///
/// # Panics
/// If `s` is empty or overlaps a block already mapped: [`Soc::find`] returns the first
/// match, so a second model at the same addresses would never see the firmware's accesses
/// while the SoC's wiring (the debug freeze, the interrupt lines) might act on it (review
/// E13: TIM2-TIM4 were mapped twice and `debug_halt` froze a TIM4 copy nothing programmed).
fn push_slot(slots: &mut Vec<Slot>, s: Slot) -> usize {
    assert!(s.len > 0, "{}: an empty register block", s.name);
    let end = u64::from(s.base) + u64::from(s.len);
    if let Some(o) = slots.iter().find(|o| {
        u64::from(o.base) < end && u64::from(s.base) < u64::from(o.base) + u64::from(o.len)
    }) {
        panic!(
            "{} at {:#010x}..{:#010x} overlaps {} at {:#010x}..{:#010x}",
            s.name,
            s.base,
            end,
            o.name,
            o.base,
            u64::from(o.base) + u64::from(o.len)
        );
    }
    slots.push(s);
    slots.len() - 1
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
        soc.flash.resize(FLASH_BYTES, 0xFF);
        soc.sort_slots();
        soc
    }

    fn sort_slots(&mut self) {
        // Indices stored in fields refer to insertion order; keep that order and search
        // linearly (a few dozen slots, most accesses hit the first matches).
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
        self.wired = idx;
    }

    /// The USART `inst`, for the host's wires. Call [`Soc::refresh_usart`] after pushing RX.
    pub fn usart_mut(&mut self, inst: UsartInstance) -> Option<&mut Usart> {
        let k = USARTS.iter().position(|u| *u == inst)?;
        let slot = *self.wired.usart.get(k)?;
        self.model_mut::<Usart>(slot)
    }

    /// Re-reads the USART's lines after the host changed it (RX pushed).
    pub fn refresh_usart(&mut self, inst: UsartInstance) {
        if let Some(k) = USARTS.iter().position(|u| *u == inst) {
            if let Some(&slot) = self.wired.usart.get(k) {
                self.refresh(slot);
            }
        }
    }

    /// Attaches a device to the bus of I2C instance `k` (0 = I2C1) whose SCL/SDA are
    /// `scl`/`sda` on the board.
    pub fn attach_i2c(&mut self, k: usize, dev: SharedDevice, scl: PinId, sda: PinId) {
        if let Some(p) = self.i2c_pins.get_mut(k) {
            *p = Some((scl, sda));
        }
        let Some(&slot) = self.wired.i2c.get(k) else {
            return;
        };
        if let Some(i) = self.model_mut::<I2c>(slot) {
            i.attach(dev);
        }
    }

    /// The I2C instance `k`.
    pub fn i2c(&self, k: usize) -> Option<&I2c> {
        self.model::<I2c>(*self.wired.i2c.get(k)?)
    }

    /// The firmware drives a bus pin as GPIO: pass the level to the bus (D6 recovery).
    fn i2c_gpio(&mut self) {
        let now = self.now;
        for k in 0..3 {
            let Some((scl, sda)) = self.i2c_pins.get(k).copied().flatten() else {
                continue;
            };
            let level = |s: &Soc, (port, pin): PinId| -> Option<bool> {
                let g = s.gpio(port)?;
                (g.mode(pin) == crate::periph::gpio::Mode::Output).then(|| !g.odr_bit(pin))
            };
            let (scl_low, sda_low) = (level(self, scl), level(self, sda));
            let Some(&slot) = self.wired.i2c.get(k) else {
                continue;
            };
            if let Some(i) = self.model_mut::<I2c>(slot) {
                i.advance(now);
                i.gpio_scl(scl_low.unwrap_or(false), now);
                i.gpio_sda(sda_low.unwrap_or(false), now);
            }
            self.refresh(slot);
        }
    }

    /// Performs every DMA transfer the request lines call for now, as register accesses
    /// (so a DMA read of a data register has the CPU read's side effects).
    fn service_dma(&mut self) {
        if self.in_dma {
            return;
        }
        self.in_dma = true;
        for _ in 0..100_000 {
            let req = self.dma_requests();
            let mut next: Option<(usize, Transfer)> = None;
            for &d in &self.wired.dma {
                let (Some(dma), Some(mux)) = (
                    self.model::<Dma>(d),
                    self.model::<Dmamux>(self.wired.dmamux),
                ) else {
                    continue;
                };
                if let Some(t) = dma.next_transfer(mux, &req) {
                    next = Some((d, t));
                    break;
                }
            }
            let Some((d, t)) = next else {
                break;
            };
            let ok = match self.dma_read(t.src, t.src_size) {
                Some(v) => self.dma_write(t.dst, t.dst_size, t.value_to_write(v)),
                None => false,
            };
            if let Some(dma) = self.model_mut::<Dma>(d) {
                if ok {
                    dma.complete(&t);
                } else {
                    dma.bus_error(t.channel);
                }
            }
            self.refresh(d);
        }
        self.in_dma = false;
    }

    fn dma_read(&mut self, addr: u32, size: u8) -> Option<u32> {
        if (RAM_BASE..RAM_BASE + RAM_BYTES as u32).contains(&addr)
            || (FLASH_BASE..FLASH_BASE + FLASH_BYTES as u32).contains(&addr)
        {
            let aligned = addr & !3;
            let w = self.mem_word(aligned)?;
            let v = w >> (8 * (addr & 3));
            return Some(match size {
                1 => v & 0xFF,
                2 => v & 0xFFFF,
                _ => v,
            });
        }
        if (0x4000_0000..0x6000_0000).contains(&addr) {
            let aligned = addr & !3;
            let word = self.read_word(aligned);
            return Some(word >> (8 * (addr & 3)));
        }
        None
    }

    fn dma_write(&mut self, addr: u32, size: u8, value: u32) -> bool {
        if (RAM_BASE..RAM_BASE + RAM_BYTES as u32).contains(&addr) {
            let o = (addr - RAM_BASE) as usize;
            let bytes = value.to_le_bytes();
            let n = usize::from(size.clamp(1, 4));
            return match self.ram.get_mut(o..o + n) {
                Some(dst) => {
                    dst.copy_from_slice(&bytes[..n]);
                    true
                }
                None => false,
            };
        }
        if (0x4000_0000..0x6000_0000).contains(&addr) {
            self.write_raw(addr, usize::from(size), value);
            return true;
        }
        false
    }

    /// Collects what the models reported since the last call.
    pub fn collect_reports(&mut self) {
        let mut out: Vec<String> = self.silicon_reports();
        for s in self.slots.iter_mut() {
            let m = s.model.as_any_mut();
            if let Some(x) = m.downcast_mut::<Usart>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<Dma>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<Dmamux>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<TimGp>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<TimAdv>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<Adc12>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<Dac>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<CompBank>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<OpampBank>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<Dbgmcu>() {
                out.extend(x.take_reports());
            } else if let Some(x) = m.downcast_mut::<I2c>() {
                if let Some(u) = x.unsupported() {
                    out.push(format!("{}: {u}", x.name()));
                }
            }
        }
        for r in out {
            let key = {
                let mut h: u32 = 0x811C_9DC5;
                for b in r.bytes() {
                    h = (h ^ u32::from(b)).wrapping_mul(0x0100_0193);
                }
                h
            };
            self.report((key, false, 5), Diagnostic::Model(r));
        }
    }

    /// Adds a register model at `name`'s base address (helpers' models: TIM1, USART...).
    /// Returns its slot index.
    ///
    /// # Panics
    /// If the block overlaps one already mapped (two models at one address: the second
    /// would never be reached).
    pub fn add(&mut self, name: &'static str, model: Box<dyn Model>) -> usize {
        let k = push_slot(&mut self.slots, slot(name, model));
        self.refresh(k);
        k
    }

    /// Adds a model at an explicit base/length (blocks the metadata places inside another
    /// peripheral's page, e.g. COMP at SYSCFG+0x200), clocked with `clock_of`'s enable bit.
    pub fn add_at(
        &mut self,
        name: &'static str,
        base: u32,
        len: u32,
        clock_of: Option<&str>,
        model: Box<dyn Model>,
    ) -> usize {
        let mut s = slot(name, model);
        s.base = base;
        s.len = len;
        s.enable = clock_of.and_then(names::rcc_enable);
        s.reset_bit = clock_of.and_then(names::rcc_reset);
        let k = push_slot(&mut self.slots, s);
        self.refresh(k);
        k
    }

    /// The model in slot `k`, typed.
    pub fn model<T: 'static>(&self, k: usize) -> Option<&T> {
        self.slots.get(k)?.model.as_any().downcast_ref::<T>()
    }

    /// The model in slot `k`, typed, mutably. The caller must call [`Soc::refresh`] after
    /// changing its state from outside a register access.
    pub fn model_mut<T: 'static>(&mut self, k: usize) -> Option<&mut T> {
        self.slots
            .get_mut(k)?
            .model
            .as_any_mut()
            .downcast_mut::<T>()
    }

    /// Slot index of the model named `name`.
    pub fn slot_of(&self, name: &str) -> Option<usize> {
        self.slots.iter().position(|s| s.name == name)
    }

    pub fn rcc(&self) -> &Rcc {
        self.model::<Rcc>(self.rcc).expect("RCC is always present")
    }

    pub fn iwdg(&self) -> &Iwdg {
        self.model::<Iwdg>(self.iwdg)
            .expect("IWDG is always present")
    }

    pub fn dbgmcu(&self) -> &Dbgmcu {
        self.model::<Dbgmcu>(self.dbgmcu)
            .expect("DBGMCU is always present")
    }

    pub fn syscfg(&self) -> &Syscfg {
        self.model::<Syscfg>(self.syscfg)
            .expect("SYSCFG is always present")
    }

    pub fn exti_mut(&mut self) -> &mut Exti {
        let k = self.exti;
        self.model_mut::<Exti>(k).expect("EXTI is always present")
    }

    /// GPIO port `port` (0 = A).
    pub fn gpio(&self, port: u8) -> Option<&GpioPort> {
        let k = *self.gpio.get(usize::from(port))?;
        self.model::<GpioPort>(k)
    }

    /// How the MCU drives pin `pin` of `port`.
    pub fn pin_drive(&self, port: u8, pin: u8) -> Drive {
        self.gpio(port).map_or(
            Drive::Released {
                pull: crate::periph::gpio::Pull::None,
            },
            |g| g.drive(pin),
        )
    }

    /// What the run found so far.
    pub fn diagnostics(&self) -> &[Diagnostic] {
        &self.diagnostics
    }

    fn report(&mut self, key: (u32, bool, u8), d: Diagnostic) {
        if self.seen.insert(key, ()).is_none() {
            self.diagnostics.push(d);
        }
    }

    /// Re-reads slot `k`'s next event, interrupt and DMA lines after its state changed.
    pub fn refresh(&mut self, k: usize) {
        if let Some(s) = self.slots.get_mut(k) {
            s.next = s.model.next_event();
            if let Some(t) = s.next {
                // The CPU must stop there, even if the access made it sooner.
                self.deadline = self.deadline.min(t);
            }
            let mut l = IrqLines::default();
            s.model.irq_lines(&mut l);
            s.irqs = l;
            let mut d = DmaRequests::default();
            s.model.dma_requests(&mut d);
            s.dma = d;
        }
        self.sample_irqs();
    }

    /// NVIC sampling of the level-sensitive lines of every model.
    pub fn sample_irqs(&mut self) {
        let mut all = IrqLines::default();
        for s in &self.slots {
            for (a, b) in all.0.iter_mut().zip(s.irqs.0.iter()) {
                *a |= b;
            }
        }
        if all != self.scs.lines() {
            self.scs.sample_lines(&all);
            self.stop.irq = true;
        }
    }

    /// All DMA request lines asserted now.
    pub fn dma_requests(&self) -> DmaRequests {
        let mut all = DmaRequests::default();
        for s in &self.slots {
            for (a, b) in all.0.iter_mut().zip(s.dma.0.iter()) {
                *a |= b;
            }
        }
        all
    }

    /// The earliest event of any model.
    pub fn next_event(&self) -> Option<Cycles> {
        let slots = self.slots.iter().filter_map(|s| s.next).min();
        let input = self.board.next_input_change(self.inputs_checked);
        let models = match (slots, input) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let systick = self.scs.next_event(self.now);
        match (models, systick) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Processes every model event due up to `now`, in time order.
    pub fn advance_to(&mut self, now: Cycles) {
        loop {
            let due = self
                .slots
                .iter()
                .enumerate()
                .filter_map(|(k, s)| s.next.filter(|t| *t <= now).map(|t| (t, k)))
                .min();
            let input = self
                .board
                .next_input_change(self.inputs_checked)
                .filter(|t| *t <= now);
            if let Some(t) = input.filter(|t| due.is_none_or(|(d, _)| *t < d)) {
                self.inputs_checked = t;
                self.sample_comparators(t);
                continue;
            }
            let Some((t, k)) = due else {
                break;
            };
            self.advance_slot(k, t);
            self.refresh(k);
            self.after_event(k, t);
        }
        self.inputs_checked = self.inputs_checked.max(now);
        let last = self.systick_checked;
        self.scs.advance(now, last.min(now));
        self.systick_checked = now.max(last);
        if now > self.now {
            self.now = now;
        }
    }

    /// Cross-peripheral effects after slot `k` changed at `t` (overridden per model by the
    /// wiring in `crate::wiring` once all models exist).
    fn after_event(&mut self, k: usize, t: Cycles) {
        if k == self.rcc {
            self.apply_rcc_resets();
            self.sync_usart_clocks();
        }
        if k == self.wired.tim1 {
            self.tim1_events(t);
        }
        if k == self.wired.comp {
            self.comp_edges();
        }
        // A DAC output that moved is compared at once, as the silicon's comparator follows
        // its inputs continuously (a search over the DAC with TIM1 stopped, the drive's
        // boot trim, sees each step).
        if self.wired.dac.contains(&k) {
            self.sample_comparators(t);
        }
        if self.dma_related(k) {
            self.service_dma();
        }
        if self.is_system_fault_slot(k) {
            self.update_system_break();
        }
        self.clock_tree_changed(k, t);
    }

    /// Brings slot `k` to `t`; the ADC gets the board's analog values through an adapter.
    fn advance_slot(&mut self, k: usize, t: Cycles) {
        if k == self.wired.adc12 {
            let snap = self.analog_snapshot();
            let (slots, board) = (&mut self.slots, &mut self.board);
            if let Some(adc) = slots
                .get_mut(k)
                .and_then(|s| s.model.as_any_mut().downcast_mut::<Adc12>())
            {
                let mut src = AnalogAdapter {
                    board: board.as_mut(),
                    snap: &snap,
                };
                adc.advance_with(t, &mut src);
            }
            return;
        }
        if let Some(s) = self.slots.get_mut(k) {
            s.model.advance(t);
        }
    }

    /// What the analog adapter needs from other models (taken before the ADC is borrowed).
    fn analog_snapshot(&self) -> AnalogSnapshot {
        let opamp = self.model::<OpampBank>(self.wired.opamp);
        let opamps = [1, 2, 3].map(|n| opamp.and_then(|o| o.config(n)));
        let dac = |k: usize, ch: usize| {
            self.wired
                .dac
                .get(k)
                .and_then(|&d| self.model::<Dac>(d))
                .and_then(|d| d.output_volts(ch))
        };
        AnalogSnapshot {
            opamps,
            dac3: [dac(1, 0), dac(1, 1)],
            dac1: [dac(0, 0), dac(0, 1)],
        }
    }

    /// TIM1's events: TRGO2 to the ADCs, OC5 to the comparators' blanking, output changes
    /// to the board's power stage; then the comparators are sampled at that instant.
    fn tim1_events(&mut self, t: Cycles) {
        let k = self.wired.tim1;
        let events: Vec<TimEvent> = match self.model_mut::<TimAdv>(k) {
            Some(tim) => tim.take_events().collect(),
            None => return,
        };
        if events.is_empty() {
            return;
        }
        for ev in &events {
            match *ev {
                TimEvent::Trgo2 { at, level } => {
                    let a = self.wired.adc12;
                    self.advance_slot(a, at);
                    if let Some(adc) = self.model_mut::<Adc12>(a) {
                        adc.trigger_signal(TriggerSignal::Tim1Trgo2, level, at);
                    }
                    self.refresh(a);
                }
                TimEvent::Blanking { at, active } => {
                    // The comparators are sampled at TIM1's events and at the board's
                    // input steps (`Board::next_input_change`): take their inputs at the
                    // window's edge first, so that the window opens or closes on the
                    // input of that moment.
                    self.sample_comparators(at);
                    let c = self.wired.comp;
                    for n in 1..=4 {
                        let tim1_oc5 = self
                            .model::<CompBank>(c)
                            .and_then(|b| b.config(n))
                            .is_some_and(|cfg| cfg.blanking == Some(BlankingSource::Tim1Oc5));
                        if tim1_oc5 {
                            if let Some(b) = self.model_mut::<CompBank>(c) {
                                b.set_blanking(n, active, at);
                            }
                        }
                    }
                    self.refresh(c);
                    self.comp_edges();
                }
                TimEvent::Update { .. }
                | TimEvent::GateChanged { .. }
                | TimEvent::OutputsOff { .. }
                | TimEvent::OutputsOn { .. } => self.board.power_stage(ev),
                TimEvent::Trgo { .. } | TimEvent::Break { .. } => {}
            }
        }
        self.sample_comparators(t);
    }

    /// The comparators' inputs at `t`, from the board (the plant) and the thresholds the
    /// DACs / VREFINT give.
    fn sample_comparators(&mut self, t: Cycles) {
        let c = self.wired.comp;
        let snap = self.analog_snapshot();
        for n in 1..=4usize {
            let Some(cfg) = self.model::<CompBank>(c).and_then(|b| b.config(n)) else {
                continue;
            };
            if !cfg.enabled {
                continue;
            }
            let inm = match cfg.inm {
                InvertingInput::Vrefint { fraction, enabled } => {
                    if !enabled {
                        continue;
                    }
                    fraction * VREFINT_VOLTS
                }
                InvertingInput::Dac { dac, channel } => {
                    let v = match dac {
                        DacId::Dac1 => snap.dac1.get(channel).copied().flatten(),
                        DacId::Dac3 => snap.dac3.get(channel).copied().flatten(),
                    };
                    // A DAC that is off drives nothing: the input floats low.
                    v.unwrap_or(0.0)
                }
                InvertingInput::Pin(pin) => self.board.pin_volts(pin, t),
            };
            // The level INP must pass next: INM with the comparator's offset and, while its
            // output is high, its hysteresis below INM (`CompBank::threshold`).
            let Some(level) = self.model::<CompBank>(c).and_then(|b| b.threshold(n, inm)) else {
                continue;
            };
            // An OPAMP driving the comparator's INP pin (COMP1 INP1 = PB1 = OPAMP3 VOUT)
            // gives its output; any other input is the board's.
            let driven = snap.opamps.iter().any(|c| {
                c.is_some_and(|c| c.enabled && !c.internal_only && c.output_pin == cfg.inp)
            });
            let above = if driven {
                let mut src = AnalogAdapter {
                    board: self.board.as_mut(),
                    snap: &snap,
                };
                src.pin(cfg.inp, t) > level
            } else {
                self.board.comparator_above(&cfg, level, t)
            };
            if let Some(b) = self.model_mut::<CompBank>(c) {
                b.set_input(n, above, t);
            }
        }
        self.refresh(c);
        self.comp_edges();
    }

    /// Comparator output changes to TIM1's break inputs and the EXTI lines.
    fn comp_edges(&mut self) {
        let c = self.wired.comp;
        let edges = match self.model_mut::<CompBank>(c) {
            Some(b) => b.take_edges(),
            None => return,
        };
        if edges.is_empty() {
            return;
        }
        let t1 = self.wired.tim1;
        for e in &edges {
            if let Some(tim) = self.model_mut::<TimAdv>(t1) {
                tim.set_comparator(e.comp, e.level, e.at);
            }
            if let Some(&line) = crate::periph::exti::COMP_LINES.get(e.comp - 1) {
                self.exti_mut().set_line(line, e.level);
            }
        }
        self.refresh(t1);
        let x = self.exti;
        self.refresh(x);
    }

    /// The core locked up (or recovered by reset): with SYSCFG_CFGR2.CLL the LOCKUP signal
    /// is a system break of TIM1 and TIM8 (RM0440 Table 271; the other sources: `faults`).
    pub fn lockup(&mut self, locked: bool) {
        self.sys_faults.locked_up = locked;
        self.update_system_break();
    }

    /// The part's analog errors (comparator offset and delay, DAC offset, OPAMP offset):
    /// the datasheet's typical part until a host sets others (hil-sim's `[analog]` keys).
    pub fn set_analog_errors(&mut self, errors: &AnalogErrors) {
        let c = self.wired.comp;
        if let Some(b) = self.model_mut::<CompBank>(c) {
            b.set_errors(errors);
        }
        for k in self.wired.dac {
            if let Some(d) = self.model_mut::<Dac>(k) {
                d.set_errors(errors);
            }
        }
        let o = self.wired.opamp;
        if let Some(b) = self.model_mut::<OpampBank>(o) {
            b.set_errors(errors);
        }
    }

    /// The level of TIM1's BKIN pin (break input 1; on the drive board the hardware STO
    /// input on PA15, AF9). As [`Soc::set_tim1_bkin2`]: the host calls this when the net's
    /// level changes (the AF selection of the pin is not checked).
    pub fn set_tim1_bkin(&mut self, level: bool, now: Cycles) {
        let t1 = self.wired.tim1;
        if let Some(tim) = self.model_mut::<TimAdv>(t1) {
            tim.set_bkin(level, now);
        }
        self.refresh(t1);
    }

    /// The level of TIM1's BKIN2 pin (PA11, AF12, on the ESC1 the CAN transceiver's RXD).
    /// The board's net drives TIM1's break 2 directly: the host calls this
    /// when the level changes (the AF selection of the pin is not checked), and the pin's
    /// GPIO level (IDR) is the board's `PinReader::external` for the same pin.
    pub fn set_tim1_bkin2(&mut self, level: bool, now: Cycles) {
        let t1 = self.wired.tim1;
        if let Some(tim) = self.model_mut::<TimAdv>(t1) {
            tim.set_bkin2(level, now);
        }
        self.refresh(t1);
    }

    /// The TIM1 model (for the host's plant wiring and tests).
    pub fn tim1(&self) -> Option<&TimAdv> {
        self.model::<TimAdv>(self.wired.tim1)
    }

    /// The OPAMP1-3 model (for tests: the configuration the image wrote).
    pub fn opamps(&self) -> Option<&OpampBank> {
        self.model::<OpampBank>(self.wired.opamp)
    }

    /// The ADC1/ADC2 model (for tests: the latest conversions).
    pub fn adc12(&self) -> Option<&Adc12> {
        self.model::<Adc12>(self.wired.adc12)
    }

    /// The COMP1-4 model (for tests: configuration and outputs).
    pub fn comps(&self) -> Option<&CompBank> {
        self.model::<CompBank>(self.wired.comp)
    }

    /// Slot `k` can raise or drop a DMA request, or is a DMA controller.
    fn dma_related(&self, k: usize) -> bool {
        let w = &self.wired;
        w.usart.contains(&k)
            || w.dma.contains(&k)
            || w.dmamux == k
            || w.i2c.contains(&k)
            || w.adc12 == k
    }

    /// Gives each U(S)ART the kernel clock RCC selects for it now (after every RCC write:
    /// CCIPR, the APB prescalers, a peripheral reset).
    fn sync_usart_clocks(&mut self) {
        let clocks: Vec<_> = USARTS
            .into_iter()
            .map(|u| (u, self.rcc().usart_kernel_hz(u)))
            .collect();
        for (u, (hz, source)) in clocks {
            if let Some(m) = self.usart_mut(u) {
                if m.kernel_clock_hz() != hz {
                    m.set_kernel_clock_hz(hz, source);
                }
            }
        }
    }

    fn apply_rcc_resets(&mut self) {
        let resets = {
            let rcc = self.slots.get_mut(self.rcc);
            rcc.and_then(|s| s.model.as_any_mut().downcast_mut::<Rcc>())
                .map(|r| r.take_resets())
                .unwrap_or_default()
        };
        for bit in resets {
            let targets: Vec<usize> = self
                .slots
                .iter()
                .enumerate()
                .filter(|(_, s)| s.reset_bit == Some(bit))
                .map(|(k, _)| k)
                .collect();
            for k in targets {
                if let Some(s) = self.slots.get_mut(k) {
                    s.model.reset();
                }
                self.refresh(k);
            }
        }
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
        self.cycles.reset();
    }

    fn find(&self, addr: u32) -> Option<usize> {
        self.slots
            .iter()
            .position(|s| addr >= s.base && addr < s.base.saturating_add(s.len))
    }

    /// An access where no model is mapped: a peripheral of the chip without a model yet is
    /// reported by register name, anything else as an unmapped address.
    fn report_missing(&mut self, addr: u32, write: bool) {
        let d = match names::locate(addr) {
            Some(_) => Diagnostic::Unmodelled {
                what: names::describe(addr),
                write,
            },
            None => Diagnostic::Unmapped { addr, write },
        };
        self.report((addr, write, 0), d);
    }

    fn clocked(&self, k: usize) -> bool {
        let Some(s) = self.slots.get(k) else {
            return false;
        };
        match s.enable {
            None => true,
            Some((off, bit)) => self.rcc().enabled(off, bit),
        }
    }

    /// A free-running counter register (reading it is a clock read, not a state poll).
    fn is_counter(&self, addr: u32) -> bool {
        matches!(addr, 0xE000_1004 | 0xE000_E018)
            || (self
                .find(addr)
                .and_then(|k| self.slots.get(k))
                .is_some_and(|s| s.name.starts_with("TIM") && addr - s.base == 0x24))
    }

    /// A read of `size` bytes at `addr` by the CPU or the DMA.
    pub fn bus_read(&mut self, addr: u32, size: usize) -> u32 {
        let aligned = addr & !3;
        let shift = 8 * (addr & 3);
        let word = self.read_word(aligned);
        let v = word >> shift;
        let v = match size {
            1 => v & 0xFF,
            2 => v & 0xFFFF,
            _ => v,
        };
        self.track_poll(aligned, word);
        v
    }

    fn read_word(&mut self, addr: u32) -> u32 {
        if (0xE000_0000..0xE010_0000).contains(&addr) {
            return self.ppb_read(addr);
        }
        let Some(k) = self.find(addr) else {
            self.report_missing(addr, false);
            return 0;
        };
        if !self.clocked(k) {
            let what = names::describe(addr);
            self.report(
                (addr, false, 1),
                Diagnostic::Unclocked { what, write: false },
            );
            return 0;
        }
        let now = self.now;
        let Some(off) = self.slots.get(k).map(|s| addr - s.base) else {
            return 0;
        };
        self.advance_slot(k, now);
        let gpio_port = self.gpio.iter().position(|g| *g == k);
        let value = match gpio_port {
            Some(port) if off == 0x10 => self.read_idr(port as u8, k),
            _ => self.slots.get_mut(k).and_then(|s| s.model.read(off, now)),
        };
        self.refresh(k);
        if self.dma_related(k) {
            self.service_dma();
        }
        match value {
            Some(v) => v,
            None => {
                let what = names::describe(addr);
                self.report(
                    (addr, false, 2),
                    Diagnostic::Unmodelled { what, write: false },
                );
                0
            }
        }
    }

    fn read_idr(&mut self, port: u8, k: usize) -> Option<u32> {
        let now = self.now;
        // The board sees how every pin is driven at this instant.
        let snapshot: Vec<GpioPort> = self
            .gpio
            .iter()
            .filter_map(|g| self.model::<GpioPort>(*g).cloned())
            .collect();
        let drives = |p: u8, n: u8| {
            snapshot.get(usize::from(p)).map_or(
                Drive::Released {
                    pull: crate::periph::gpio::Pull::None,
                },
                |g| g.drive(n),
            )
        };
        // The I2C bus pins read the bus (its pull-ups, a device holding SDA low), not the
        // board.
        let mut bus_levels: Vec<(PinId, bool)> = Vec::new();
        for k2 in 0..3 {
            let (Some((scl, sda)), Some(i)) =
                (self.i2c_pins.get(k2).copied().flatten(), self.i2c(k2))
            else {
                continue;
            };
            bus_levels.push((scl, i.bus().scl()));
            bus_levels.push((sda, i.bus().sda()));
        }
        // Alternate-function outputs read the level their peripheral drives (RM0440
        // §9.3.12: the input buffer samples the pin whatever drives it).
        if let Some(g) = snapshot.get(usize::from(port)) {
            for n in 0..16u8 {
                if g.mode(n) != crate::periph::gpio::Mode::Alternate {
                    continue;
                }
                if let Some(level) = self.af_output_level(port, n, g.af(n)) {
                    bus_levels.push(((port, n), level));
                }
            }
        }
        let mut reader = BusOrBoard {
            bus: &bus_levels,
            board: self.board.as_mut(),
        };
        let s = self.slots.get_mut(k)?;
        let g = s.model.as_any_mut().downcast_mut::<GpioPort>()?;
        let v = g.idr(now, &mut reader, &drives);
        let floating = core::mem::take(&mut g.floating_reads);
        for n in 0..16u8 {
            if floating & (1 << n) != 0 {
                let pin = format!("P{}{}", char::from(b'A' + port), n);
                self.report(
                    (u32::from(port) << 8 | u32::from(n), false, 3),
                    Diagnostic::FloatingInput { pin },
                );
            }
        }
        Some(v)
    }

    /// The level a peripheral drives on pin `n` of `port` in alternate function `af`, if
    /// the function is an output this SoC models: a U(S)ART's TX (idle, high, while UE and
    /// TE are set: the bits of a character on the line are not modelled) and TIM1's
    /// CHx/CHxN outputs (their level at this cycle, `None` while the timer releases them).
    fn af_output_level(&mut self, port: u8, n: u8, af: u8) -> Option<bool> {
        const UE_TE: u32 = 1 | (1 << 3);
        let pin = format!("P{}{n}", char::from(b'A' + port));
        let (periph, signal) = af_signal(&pin, af)?;
        if signal == "TX" {
            let k = USARTS.iter().position(|u| u.name() == periph)?;
            let slot = *self.wired.usart.get(k)?;
            let now = self.now;
            let cr1 = self.slots.get_mut(slot)?.model.read(0, now)?;
            return (cr1 & UE_TE == UE_TE).then_some(true);
        }
        if periph == "TIM1" {
            let ch = signal.strip_prefix("CH")?;
            let (num, high) = match ch.strip_suffix('N') {
                Some(num) => (num, false),
                None => (ch, true),
            };
            let ch: usize = num.parse().ok()?;
            return self.tim1()?.gate().pin(ch.checked_sub(1)?, high, self.now);
        }
        None
    }

    /// A write of `size` bytes of `value` at `addr` by the CPU or the DMA.
    pub fn bus_write(&mut self, addr: u32, size: usize, value: u32) {
        self.poll = Poll::default();
        self.write_raw(addr, size, value);
    }

    /// A write by the CPU or the DMA (without the polling-loop bookkeeping).
    fn write_raw(&mut self, addr: u32, size: usize, value: u32) {
        let aligned = addr & !3;
        let shift = 8 * (addr & 3);
        let mask = match size {
            1 => 0xFFu32 << shift,
            2 => 0xFFFFu32 << shift,
            _ => !0,
        };
        let w = Write {
            offset: 0,
            value: value << shift,
            mask,
        };
        if (0xE000_0000..0xE010_0000).contains(&aligned) {
            self.ppb_write(aligned, w);
            return;
        }
        let Some(k) = self.find(aligned) else {
            self.report_missing(aligned, true);
            return;
        };
        if !self.clocked(k) {
            let what = names::describe(aligned);
            self.report(
                (aligned, true, 1),
                Diagnostic::Unclocked { what, write: true },
            );
            return;
        }
        let now = self.now;
        self.advance_slot(k, now);
        let stored_only = self
            .slots
            .get(k)
            .is_some_and(|s| is_stored_only(s.name, aligned - s.base));
        let before = match self.slots.get_mut(k) {
            Some(s) if stored_only => s.model.read(aligned - s.base, now),
            _ => None,
        };
        let ok = match self.slots.get_mut(k) {
            Some(s) => s.model.write(
                Write {
                    offset: aligned - s.base,
                    ..w
                },
                now,
            ),
            None => false,
        };
        if let Some(before) = before {
            let after = self
                .slots
                .get_mut(k)
                .and_then(|s| s.model.read(aligned - s.base, now));
            if after.is_some_and(|a| a != before) {
                self.report(
                    (aligned, true, 6),
                    Diagnostic::StoredOnly {
                        what: names::describe(aligned),
                        value: after.unwrap_or(0),
                    },
                );
            }
        }
        if !ok {
            let what = names::describe(aligned);
            self.report(
                (aligned, true, 2),
                Diagnostic::Unmodelled { what, write: true },
            );
        }
        self.refresh(k);
        self.after_event(k, now);
        if let Some(port) = self.gpio.iter().position(|g| *g == k) {
            self.gpio_changed(port);
            self.i2c_gpio();
        }
    }

    fn gpio_changed(&mut self, port: usize) {
        let k = self.gpio.get(port).copied();
        let changed = k
            .and_then(|k| self.model_mut::<GpioPort>(k))
            .is_some_and(|g| g.take_changed());
        if changed {
            let snapshot: Vec<GpioPort> = self
                .gpio
                .iter()
                .filter_map(|g| self.model::<GpioPort>(*g).cloned())
                .collect();
            let drives = |p: u8, n: u8| {
                snapshot.get(usize::from(p)).map_or(
                    Drive::Released {
                        pull: crate::periph::gpio::Pull::None,
                    },
                    |g| g.drive(n),
                )
            };
            let now = self.now;
            self.board.outputs_changed(now, &drives);
        }
    }

    /// A DBGMCU offset the model does not implement (PPB: the metadata does not name it).
    fn report_unmodelled_dbgmcu(&mut self, addr: u32, write: bool) {
        self.report(
            (addr, write, 2),
            Diagnostic::Unmodelled {
                what: format!("DBGMCU+{:#x}", addr - DBGMCU_BASE),
                write,
            },
        );
    }

    fn ppb_read(&mut self, addr: u32) -> u32 {
        if (DBGMCU_BASE..DBGMCU_BASE + 0x400).contains(&addr) {
            let k = self.dbgmcu;
            let now = self.now;
            let v = self
                .slots
                .get_mut(k)
                .and_then(|s| s.model.read(addr - DBGMCU_BASE, now));
            return v.unwrap_or_else(|| {
                self.report_unmodelled_dbgmcu(addr, false);
                0
            });
        }
        let (now, ipsr) = (self.now, self.ipsr);
        match self.scs.read(addr, now, ipsr) {
            Some(v) => v,
            None => {
                self.report(
                    (addr, false, 2),
                    Diagnostic::Unmodelled {
                        what: format!("{addr:#010x} (PPB)"),
                        write: false,
                    },
                );
                0
            }
        }
    }

    fn ppb_write(&mut self, addr: u32, w: Write) {
        if (DBGMCU_BASE..DBGMCU_BASE + 0x400).contains(&addr) {
            let k = self.dbgmcu;
            let now = self.now;
            let ok = self.slots.get_mut(k).is_some_and(|s| {
                s.model.write(
                    Write {
                        offset: addr - DBGMCU_BASE,
                        ..w
                    },
                    now,
                )
            });
            if !ok {
                self.report_unmodelled_dbgmcu(addr, true);
            }
            return;
        }
        let now = self.now;
        match self.scs.write(addr, w, now) {
            Some(fx) => {
                if fx.system_reset {
                    self.stop.system_reset = true;
                }
                self.stop.irq = true;
            }
            None => self.report(
                (addr, true, 2),
                Diagnostic::Unmodelled {
                    what: format!("{addr:#010x} (PPB)"),
                    write: true,
                },
            ),
        }
    }

    /// Polling-loop detection: the same register read repeatedly with the same value and
    /// nothing written in between. After [`POLL_STREAK`] such reads the clock jumps to the
    /// next event (the first moment anything can change), so that busy-waits cost no host
    /// time; a loop that also reads a free-running counter jumps at most
    /// [`COUNTER_POLL_JUMP`] at a time (it may be waiting for a time, not a flag).
    fn track_poll(&mut self, addr: u32, value: u32) {
        if self.is_counter(addr) {
            self.poll.counter = true;
            let (block, reg, n) = self.poll.counter_loop;
            let n = if block == self.block && reg == addr {
                n + 1
            } else {
                1
            };
            self.poll.counter_loop = (self.block, addr, n);
            if n >= POLL_STREAK && self.poll.streak == 0 {
                // Only the time is read, over and over: waiting for a time.
                self.jump(Some(self.now + COUNTER_POLL_JUMP));
            }
            return;
        }
        self.poll.counter_loop = (0, 0, 0);
        if self.poll.addr == addr
            && self.poll.value == value
            && self.poll.block == self.block
            && self.poll.streak > 0
        {
            self.poll.streak += 1;
        } else {
            self.poll = Poll {
                block: self.block,
                addr,
                value,
                streak: 1,
                counter: false,
                counter_loop: (0, 0, 0),
            };
            return;
        }
        if self.poll.streak < POLL_STREAK {
            return;
        }
        let limit = self.poll.counter.then_some(self.now + COUNTER_POLL_JUMP);
        if self.next_event().is_none() && !self.poll.counter && !self.iwdg().running() {
            let what = names::describe(addr);
            self.report((addr, false, 4), Diagnostic::StuckPoll { what, value });
        }
        self.jump(limit);
    }

    /// Moves the clock forward to the next event, the slice's deadline, or `limit`,
    /// whichever comes first: what a polling loop would spin through.
    fn jump(&mut self, limit: Option<Cycles>) {
        let next = self.next_event().unwrap_or(Cycles::MAX);
        let target = next.min(limit.unwrap_or(Cycles::MAX)).min(self.deadline);
        if target > self.now {
            self.now = target;
        }
    }

    /// Cycles of the block of `size` bytes starting at `addr` that the CPU is about to run
    /// (the cycle model of `cycles.rs`, with the flash interface as FLASH_ACR sets it now).
    #[inline]
    pub fn block_cycles(&mut self, addr: u32, size: u32) -> u64 {
        let acr = self.flash_acr();
        self.cycles
            .block(addr, size, acr, &self.flash, &self.ram, RAM_BASE)
    }

    /// FLASH_ACR as the cycle model applies it: the image's, unless a what-if overrides it.
    pub fn flash_acr(&self) -> u32 {
        match self.cycles.acr_override {
            Some(acr) => acr,
            None => self.model::<Flash>(self.flash_slot).map_or(0, |f| f.acr()),
        }
    }

    /// RAM as a slice (for the DMA, RTT and tests).
    pub fn ram(&self) -> &[u8] {
        &self.ram
    }

    /// The stack's high-water mark since power-on, for an image linked with flip-link
    /// (its initial stack pointer, word 0 of the vector table, is the top of a stack at
    /// the bottom of RAM, below every static). RAM powers up zeroed here (on silicon it
    /// holds noise), so the lowest non-zero byte below the initial stack pointer is the
    /// deepest the stack has been: an image that writes only zeros to its deepest words
    /// reads a few bytes shallower than it was. `None` when word 0 is not in RAM.
    pub fn stack_high_water(&self) -> Option<StackUse> {
        let top = self.mem_word(FLASH_BASE)?;
        let size = top
            .checked_sub(RAM_BASE)
            .filter(|&n| n as usize <= RAM_BYTES)?;
        let region = self.ram.get(..size as usize)?;
        let untouched = region.iter().take_while(|&&b| b == 0).count() as u32;
        Some(StackUse {
            size_bytes: size,
            used_bytes: size - untouched,
        })
    }

    /// Reads a little-endian word of RAM or flash (`None` elsewhere).
    pub fn mem_word(&self, addr: u32) -> Option<u32> {
        let (mem, base): (&[u8], u32) = if addr >= RAM_BASE {
            (&self.ram, RAM_BASE)
        } else {
            (&self.flash, FLASH_BASE)
        };
        let o = addr.checked_sub(base)? as usize;
        let b = mem.get(o..o + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// Writes a little-endian word of RAM.
    pub fn set_ram_word(&mut self, addr: u32, v: u32) -> bool {
        let Some(o) = addr.checked_sub(RAM_BASE) else {
            return false;
        };
        match self.ram.get_mut(o as usize..o as usize + 4) {
            Some(b) => {
                b.copy_from_slice(&v.to_le_bytes());
                true
            }
            None => false,
        }
    }

    /// Slot index of the IWDG (for the CPU's reset logic).
    pub fn iwdg_slot(&self) -> usize {
        self.iwdg
    }

    /// The IWDG expired: the MCU must reset.
    pub fn watchdog_expired(&self) -> bool {
        self.iwdg().expired()
    }

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

    /// Syscfg slot index.
    pub fn syscfg_slot(&self) -> usize {
        self.syscfg
    }
}

/// The (peripheral, signal) that alternate function `af` puts on `pin` ("PA9", 7 →
/// ("USART1", "TX")), from the metadata's pin table.
fn af_signal(pin: &str, af: u8) -> Option<(&'static str, &'static str)> {
    names::chip().peripherals.iter().find_map(|p| {
        p.pins
            .iter()
            .find(|pp| pp.pin == pin && pp.af == Some(af))
            .map(|pp| (p.name, pp.signal))
    })
}

/// Pin levels for an IDR read: the I2C bus lines from the bus, alternate-function outputs
/// from their peripheral, the rest from the board.
struct BusOrBoard<'a> {
    bus: &'a [(PinId, bool)],
    board: &'a mut dyn Board,
}

impl PinReader for BusOrBoard<'_> {
    fn external(
        &mut self,
        port: u8,
        pin: u8,
        now: Cycles,
        drives: &dyn Fn(u8, u8) -> Drive,
    ) -> crate::periph::gpio::External {
        use crate::periph::gpio::External;
        match self.bus.iter().find(|(p, _)| *p == (port, pin)) {
            Some((_, true)) => External::High,
            Some((_, false)) => External::Low,
            None => self.board.external(port, pin, now, drives),
        }
    }
}

/// The other models' state the ADC's analog adapter needs.
struct AnalogSnapshot {
    opamps: [Option<OpampConfig>; 3],
    dac1: [Option<f64>; 2],
    dac3: [Option<f64>; 2],
}

/// What the ADC converts: pins from the board, OPAMP outputs computed from their inputs,
/// the internal references.
struct AnalogAdapter<'a> {
    board: &'a mut dyn Board,
    snap: &'a AnalogSnapshot,
}

/// The pin of ADC `adc`'s external channel `ch` (from the metadata's pin table).
fn adc_pin(adc: AdcId, ch: u8) -> Option<&'static str> {
    let name = match adc {
        AdcId::Adc1 => "ADC1",
        AdcId::Adc2 => "ADC2",
    };
    let signal = format!("IN{ch}");
    names::peripheral(name)?
        .pins
        .iter()
        .find(|p| p.signal == signal)
        .map(|p| p.pin)
}

impl AnalogAdapter<'_> {
    fn opamp_out(&mut self, n: usize, at: Cycles) -> f64 {
        let Some(cfg) = self.snap.opamps.get(n).copied().flatten() else {
            return 0.0;
        };
        let vinp = match cfg.vinp {
            OpampInput::Pin(p) => self.board.pin_volts(p, at),
            OpampInput::Dac3(ch) => self.snap.dac3.get(ch).copied().flatten().unwrap_or(0.0),
            OpampInput::NotConnected => 0.0,
        };
        // The VINM0 pin's own volts when the feedback network's foot is on it.
        let vinm0 = cfg
            .vinm0_pin()
            .map_or(0.0, |pin| self.board.pin_volts(pin, at));
        cfg.output_volts(vinp, vinm0).unwrap_or(0.0)
    }
}

impl AnalogAdapter<'_> {
    /// OPAMPn's output on its internal ADC channel: only with OPAINTOEN = 1 (RM0440 §25.3:
    /// the output then goes to the ADC and not to the VOUT pin); otherwise the internal
    /// channel is not connected and reads 0 V.
    fn opamp_internal(&mut self, n: usize, at: Cycles) -> f64 {
        match self.snap.opamps.get(n).copied().flatten() {
            Some(cfg) if cfg.internal_only => self.opamp_out(n, at),
            _ => 0.0,
        }
    }

    /// Volts on `pin`: an enabled OPAMP's output while it drives its VOUT pin (OPAINTOEN =
    /// 0: PA2, PA6, PB1), else the board's.
    fn pin(&mut self, pin: &str, at: Cycles) -> f64 {
        let driver =
            self.snap.opamps.iter().position(|c| {
                c.is_some_and(|c| c.enabled && !c.internal_only && c.output_pin == pin)
            });
        match driver {
            Some(n) => self.opamp_out(n, at),
            None => self.board.pin_volts(pin, at),
        }
    }
}

impl AnalogSource for AnalogAdapter<'_> {
    fn volts(&mut self, adc: AdcId, channel: u8, at: Cycles) -> f64 {
        match (adc, channel) {
            (AdcId::Adc1, 13) => self.opamp_internal(0, at),
            (AdcId::Adc2, 16) => self.opamp_internal(1, at),
            (AdcId::Adc2, 18) => self.opamp_internal(2, at),
            // Temperature sensor at 30 °C (DS12589 V30), VBAT/3 at 3.3 V, VREFINT.
            (AdcId::Adc1, 16) => 0.76,
            (AdcId::Adc1, 17) => 3.3 / 3.0,
            (AdcId::Adc1, 18) => VREFINT_VOLTS,
            _ => match adc_pin(adc, channel) {
                Some(pin) => self.pin(pin, at),
                None => 0.0,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn soc() -> Soc {
        Soc::new(vec![0xFF; 16], Box::new(BareBoard))
    }

    #[test]
    fn stack_high_water_is_the_lowest_written_byte_below_the_initial_sp() {
        // Vector table word 0: a 0x2800-byte flip-link stack.
        let mut flash = vec![0xFF; 16];
        flash[..4].copy_from_slice(&(RAM_BASE + 0x2800).to_le_bytes());
        let mut s = Soc::new(flash, Box::new(BareBoard));
        let fresh = s.stack_high_water().unwrap();
        assert_eq!((fresh.size_bytes, fresh.used_bytes), (0x2800, 0));
        // A push 0x40 bytes below the top, then a deeper one; a static above the top
        // does not count.
        s.ram[0x2800 - 0x40] = 1;
        s.ram[0x2900] = 7;
        assert_eq!(s.stack_high_water().unwrap().used_bytes, 0x40);
        s.ram[0x1000] = 0xAA;
        s.ram[0x2800 - 0x40] = 0;
        assert_eq!(s.stack_high_water().unwrap().used_bytes, 0x1800);
        // Word 0 outside RAM (no flip-link stack): no figure.
        assert_eq!(soc().stack_high_water(), None);
    }

    /// A board with 0.1 V on the ESC1's PGA inputs and 1.0 V on PB1.
    struct AnalogBoard;

    impl PinReader for AnalogBoard {
        fn external(
            &mut self,
            _: u8,
            _: u8,
            _: Cycles,
            _: &dyn Fn(u8, u8) -> Drive,
        ) -> crate::periph::gpio::External {
            crate::periph::gpio::External::Floating
        }
    }

    impl Board for AnalogBoard {
        fn pin_volts(&mut self, pin: &str, _at: Cycles) -> f64 {
            match pin {
                "PA1" | "PA7" | "PB0" => 0.1,
                "PB1" => 1.0,
                _ => 0.0,
            }
        }
    }

    /// OPAMPn in PGA mode, gain 16, VINP0, enabled; `internal`: OPAINTOEN.
    fn pga16(bank: &mut OpampBank, n: u32, internal: bool) {
        let v = 1 | (2 << 5) | (3 << 14) | if internal { 1 << 8 } else { 0 };
        assert!(bank.write(crate::periph::Write::word(4 * (n - 1), v), 0));
    }

    fn snapshot(bank: &OpampBank) -> AnalogSnapshot {
        AnalogSnapshot {
            opamps: [1, 2, 3].map(|n| bank.config(n)),
            dac1: [None; 2],
            dac3: [None; 2],
        }
    }

    #[test]
    fn opamp_outputs_reach_the_adc_internally_only_with_opaintoen() {
        let mut bank = OpampBank::new();
        bank.set_errors(&AnalogErrors::IDEAL);
        pga16(&mut bank, 1, true);
        pga16(&mut bank, 2, true);
        pga16(&mut bank, 3, false);
        let snap = snapshot(&bank);
        let mut board = AnalogBoard;
        let mut a = AnalogAdapter {
            board: &mut board,
            snap: &snap,
        };
        // 16 x 0.1 V on ADC1 IN13 and ADC2 IN16 (the ESC1's phase currents at 0 A).
        assert!((a.volts(AdcId::Adc1, 13, 0) - 1.6).abs() < 1e-12);
        assert!((a.volts(AdcId::Adc2, 16, 0) - 1.6).abs() < 1e-12);
        // OPAMP3 drives its pin PB1 (ADC1 IN12), not ADC2 IN18.
        assert_eq!(a.volts(AdcId::Adc2, 18, 0), 0.0);
        assert!((a.volts(AdcId::Adc1, 12, 0) - 1.6).abs() < 1e-12);
        // The VINP pins themselves read the board's voltage (ADC1 IN2 = PA1).
        assert!((a.volts(AdcId::Adc1, 2, 0) - 0.1).abs() < 1e-12);
        // Output clamped to the rail: 16 x 0.25 V.
        struct High;
        impl PinReader for High {
            fn external(
                &mut self,
                _: u8,
                _: u8,
                _: Cycles,
                _: &dyn Fn(u8, u8) -> Drive,
            ) -> crate::periph::gpio::External {
                crate::periph::gpio::External::Floating
            }
        }
        impl Board for High {
            fn pin_volts(&mut self, _: &str, _: Cycles) -> f64 {
                0.25
            }
        }
        let mut high = High;
        let mut a = AnalogAdapter {
            board: &mut high,
            snap: &snap,
        };
        assert_eq!(a.volts(AdcId::Adc1, 13, 0), 3.3);
        // Disabled: nothing on the internal channel, and PB1 is the board's again.
        let off = AnalogSnapshot {
            opamps: [None; 3],
            ..snapshot(&bank)
        };
        let mut board = AnalogBoard;
        let mut a = AnalogAdapter {
            board: &mut board,
            snap: &off,
        };
        assert_eq!(a.volts(AdcId::Adc1, 13, 0), 0.0);
        assert!((a.volts(AdcId::Adc1, 12, 0) - 1.0).abs() < 1e-12);
    }

    /// Volts on OPAMP1's VINP0 (PA1) and VINM0 (PA3).
    struct ShuntPins {
        vinp: f64,
        vinm0: f64,
    }

    impl PinReader for ShuntPins {
        fn external(
            &mut self,
            _: u8,
            _: u8,
            _: Cycles,
            _: &dyn Fn(u8, u8) -> Drive,
        ) -> crate::periph::gpio::External {
            crate::periph::gpio::External::Floating
        }
    }

    impl Board for ShuntPins {
        fn pin_volts(&mut self, pin: &str, _at: Cycles) -> f64 {
            match pin {
                "PA1" => self.vinp,
                "PA3" => self.vinm0,
                _ => 0.0,
            }
        }
    }

    /// The ADC converts the amplifier's real output at the sampling instant: the VINM0-biased
    /// mode takes the VINM0 pin's volts, the grounded one does not, the part's input offset
    /// is amplified with the gain, the rails clamp.
    #[test]
    fn the_adc_converts_the_amplifiers_real_output() {
        let typ = AnalogErrors::TYPICAL.opamp_offset_v;
        let mut bank = OpampBank::new();
        let convert = |bank: &OpampBank, vinp: f64, vinm0: f64| {
            let snap = snapshot(bank);
            let mut board = ShuntPins { vinp, vinm0 };
            let mut a = AnalogAdapter {
                board: &mut board,
                snap: &snap,
            };
            a.volts(AdcId::Adc1, 13, 0)
        };
        // PGA x16, VINM0-biased (PGA_GAIN 01011), output to the ADC only.
        let biased = 1 | (2 << 5) | (0b01011 << 14) | (1 << 8);
        assert!(bank.write(crate::periph::Write::word(0, biased), 0));
        let v = convert(&bank, 0.12, 0.1);
        assert!(
            (v - (16.0 * (0.12 + typ) - 15.0 * 0.1)).abs() < 1e-12,
            "{v}"
        );
        // The same pins in the grounded mode (PGA_GAIN 00011): another output.
        assert!(bank.write(
            crate::periph::Write::word(0, 1 | (2 << 5) | (3 << 14) | (1 << 8)),
            1
        ));
        let g = convert(&bank, 0.12, 0.1);
        assert!((g - 16.0 * (0.12 + typ)).abs() < 1e-12, "{g}");
        // Below VSSA and above VDDA the output sits on the rails.
        assert!(bank.write(crate::periph::Write::word(0, biased), 2));
        assert_eq!(convert(&bank, 0.0, 0.5), 0.0);
        assert_eq!(convert(&bank, 1.0, 0.0), 3.3);
        // A negative offset lowers it by 16 x Vio.
        bank.set_errors(&AnalogErrors::worst(-1.0));
        let w = convert(&bank, 0.12, 0.1);
        let vio = AnalogErrors::worst(-1.0).opamp_offset_v;
        assert!((w - (16.0 * (0.12 + vio) - 1.5)).abs() < 1e-12, "{w}");
    }

    /// 1 V on PA1 (COMP1's INP) from `from` to `to` (cycles), 0 V otherwise.
    struct Pulse {
        from: Cycles,
        to: Cycles,
    }

    impl PinReader for Pulse {
        fn external(
            &mut self,
            _: u8,
            _: u8,
            _: Cycles,
            _: &dyn Fn(u8, u8) -> Drive,
        ) -> crate::periph::gpio::External {
            crate::periph::gpio::External::Floating
        }
    }

    impl Board for Pulse {
        fn pin_volts(&mut self, pin: &str, at: Cycles) -> f64 {
            if pin == "PA1" && (self.from..self.to).contains(&at) {
                1.0
            } else {
                0.0
            }
        }

        fn next_input_change(&self, after: Cycles) -> Option<Cycles> {
            [self.from, self.to]
                .into_iter()
                .filter(|&t| t > after)
                .min()
        }
    }

    /// With no TIM1 running (no TIM1 event to sample at), a pulse the board announces
    /// reaches COMP1's output when it starts and leaves it when it ends, as on the silicon
    /// whose comparator follows its input continuously.
    #[test]
    fn a_board_input_step_reaches_the_comparator_when_it_happens() {
        const APB2ENR: u32 = 0x4002_1060;
        const COMP1_CSR: u32 = 0x4001_0200;
        let mut s = Soc::new(
            vec![0xFF; 16],
            Box::new(Pulse {
                from: 10_000,
                to: 20_000,
            }),
        );
        // SYSCFGEN; COMP1: EN, INP PA1, INM 1/2 VREFINT (INMSEL 001, BRGEN, SCALEN).
        s.bus_write(APB2ENR, 4, 1);
        s.bus_write(COMP1_CSR, 4, 1 | (1 << 4) | (1 << 22) | (1 << 23));
        let out = |s: &Soc| s.comps().is_some_and(|b| b.output(1));
        s.advance_to(9_000);
        assert!(!out(&s), "0 V is below 0.6 V");
        s.advance_to(15_000);
        assert!(
            out(&s),
            "the pulse reached COMP1 within its propagation delay"
        );
        s.advance_to(30_000);
        assert!(!out(&s), "and its end did too");
    }

    #[test]
    fn unclocked_peripherals_read_zero_and_are_reported() {
        let mut s = soc();
        // GPIOB is not clocked out of reset: MODER reads 0, not its reset value.
        assert_eq!(s.bus_read(0x4800_0400, 4), 0);
        assert!(matches!(
            s.diagnostics().first(),
            Some(Diagnostic::Unclocked { what, .. }) if what == "GPIOB.MODER"
        ));
        // AHB2ENR bit 1: GPIOBEN.
        s.bus_write(0x4002_104C, 4, 1 << 1);
        assert_eq!(s.bus_read(0x4800_0400, 4), 0xFFFF_FEBF);
    }

    #[test]
    fn unmodelled_registers_are_named() {
        let mut s = soc();
        s.bus_read(0x4002_1024, 4);
        assert!(s.diagnostics().iter().any(|d| matches!(
            d, Diagnostic::Unmodelled { what, write: false } if what.starts_with("0x40021024")
        )));
    }

    #[test]
    fn byte_and_halfword_accesses_reach_the_right_bits() {
        let mut s = soc();
        s.bus_write(0x4002_104C, 4, 1);
        s.bus_write(0x4800_0014, 1, 0xA5);
        assert_eq!(s.bus_read(0x4800_0014, 4), 0xA5);
        s.bus_write(0x4800_0015, 1, 0x5A);
        assert_eq!(s.bus_read(0x4800_0014, 4), 0x5AA5);
        assert_eq!(s.bus_read(0x4800_0015, 1), 0x5A);
    }

    #[test]
    fn a_stuck_poll_jumps_to_the_next_event_and_is_named() {
        let mut s = soc();
        s.deadline = 1_000_000;
        // LSION: LSIRDY follows after the start-up time; polling CSR jumps there.
        s.bus_write(0x4002_1094, 4, 1);
        let ready_at = s.next_event().unwrap_or(0);
        for _ in 0..POLL_STREAK {
            s.bus_read(0x4002_1094, 4);
        }
        assert_eq!(s.now, ready_at);
        s.advance_to(s.now);
        assert_eq!(s.bus_read(0x4002_1094, 4) & 2, 2);
        // HSERDY with no crystal never sets: a stuck poll, reported by name.
        s.bus_write(0x4002_1000, 4, (1 << 16) | 0x500);
        s.advance_to(s.now + 10_000);
        // The run loop sets the deadline anew for each run slice.
        s.deadline = 1_000_000;
        for _ in 0..POLL_STREAK {
            s.bus_read(0x4002_1000, 4);
        }
        assert!(s
            .diagnostics()
            .iter()
            .any(|d| matches!(d, Diagnostic::StuckPoll { what, .. } if what == "RCC.CR")));
        assert_eq!(s.now, 1_000_000, "jumped to the deadline");
    }

    #[test]
    fn rcc_reset_bits_reset_the_model() {
        let mut s = soc();
        s.bus_write(0x4002_104C, 4, 1);
        s.bus_write(0x4800_0014, 4, 0xFF);
        // AHB2RSTR bit 0: GPIOARST.
        s.bus_write(0x4002_102C, 4, 1);
        s.bus_write(0x4002_102C, 4, 0);
        assert_eq!(s.bus_read(0x4800_0014, 4), 0);
    }

    #[test]
    fn lockup_breaks_tim1_only_until_the_reset() {
        const APB2ENR: u32 = 0x4002_1060;
        const TIM1_BDTR: u32 = 0x4001_2C44;
        const SYSCFG_CFGR2: u32 = 0x4001_001C;
        const BKE_MOE: u32 = (1 << 12) | (1 << 15);
        let mut s = soc();
        const BKP: u32 = 1 << 13;
        let start = |s: &mut Soc| {
            // SYSCFGEN, TIM1EN; BKIN (low, not wired) active high, i.e. inactive.
            s.bus_write(APB2ENR, 4, 1 | (1 << 11));
            s.bus_write(TIM1_BDTR, 4, BKE_MOE | BKP);
        };
        start(&mut s);
        assert_eq!(s.bus_read(TIM1_BDTR, 4) & BKE_MOE, BKE_MOE);
        // Without CLL the LOCKUP signal does not reach the timer.
        s.lockup(true);
        assert_eq!(s.bus_read(TIM1_BDTR, 4) & BKE_MOE, BKE_MOE);
        s.system_reset(crate::periph::rcc::ResetKind::Software);
        start(&mut s);
        s.bus_write(SYSCFG_CFGR2, 4, crate::periph::syscfg::cfgr2::CLL);
        s.lockup(true);
        assert_eq!(s.bus_read(TIM1_BDTR, 4) & BKE_MOE, 1 << 12, "MOE cleared");
        // The watchdog's reset ends the lockup: the restarted image can set MOE again.
        s.system_reset(crate::periph::rcc::ResetKind::Watchdog);
        start(&mut s);
        assert_eq!(s.bus_read(TIM1_BDTR, 4) & BKE_MOE, BKE_MOE);
    }

    #[test]
    fn every_register_block_is_mapped_once() {
        let s = soc();
        for (k, a) in s.slots.iter().enumerate() {
            for b in s.slots.iter().skip(k + 1) {
                assert!(
                    a.base + a.len <= b.base || b.base + b.len <= a.base,
                    "{} and {} overlap",
                    a.name,
                    b.name
                );
            }
        }
        // Review E13: the TIM4 the debug freeze acts on is the one the bus reaches.
        let tim4 = s.slot_of("TIM4").expect("TIM4");
        assert_eq!(s.wired.tim_gp[2], tim4);
        assert_eq!(s.find(0x4000_0800), Some(tim4));
    }

    #[test]
    #[should_panic(expected = "TIM4 at 0x40000800..0x40000be4 overlaps TIM4")]
    fn a_second_model_at_a_mapped_address_is_refused() {
        let mut s = soc();
        s.add("TIM4", Box::new(TimGp::new("TIM4")));
    }

    #[test]
    #[should_panic(expected = "overlaps SYSCFG")]
    fn a_block_inside_another_is_refused() {
        let mut s = soc();
        s.add_at("X", 0x4001_0010, 4, None, Box::new(Dbgmcu::default()));
    }

    #[test]
    fn a_usart_tx_pin_reads_its_idle_level_and_is_not_a_floating_input() {
        let mut s = soc();
        // GPIOAEN, USART1EN; PA9 in AF7 (USART1 TX), PA0 an input without pull.
        s.bus_write(0x4002_104C, 4, 1);
        s.bus_write(0x4002_1060, 4, 1 << 14);
        let moder = s.bus_read(0x4800_0000, 4);
        s.bus_write(0x4800_0000, 4, (moder & !(3 << 18) & !3) | (2 << 18));
        s.bus_write(0x4800_0024, 4, 7 << 4);
        assert_eq!(
            s.bus_read(0x4800_0010, 4) & (1 << 9),
            0,
            "USART off: not driven"
        );
        // UE | TE: the transmitter holds the line at its idle level.
        s.bus_write(0x4001_3800, 4, 1 | (1 << 3));
        assert_eq!(s.bus_read(0x4800_0010, 4) & (1 << 9), 1 << 9);
        let floating: Vec<_> = s
            .diagnostics()
            .iter()
            .filter_map(|d| match d {
                Diagnostic::FloatingInput { pin } => Some(pin.as_str()),
                _ => None,
            })
            .collect();
        assert_eq!(floating, ["PA0"], "only the input pin");
    }

    #[test]
    fn a_change_of_a_stored_only_register_is_reported_once() {
        let mut s = soc();
        // PWR is clocked by APB1ENR1.PWREN; CR4 (wake-up polarity) is stored, not applied.
        s.bus_write(0x4002_1058, 4, 1 << 28);
        s.bus_write(0x4000_700C, 4, 0); // no change: nothing to report
        assert!(s.diagnostics().is_empty(), "{:?}", s.diagnostics());
        s.bus_write(0x4000_700C, 4, 1);
        s.bus_write(0x4000_700C, 4, 3);
        let what: Vec<String> = s.diagnostics().iter().map(|d| d.to_string()).collect();
        assert_eq!(
            what,
            ["PWR.CR4 set to 0x00000001: stored only, its effect is not modelled"]
        );
        // CR1.VOS is modelled (VOSF): not a stored-only report.
        s.bus_write(0x4000_7000, 4, 0x400);
        let stored: Vec<String> = s
            .diagnostics()
            .iter()
            .map(|d| d.to_string())
            .filter(|d| d.contains("stored only"))
            .collect();
        assert_eq!(stored.len(), 1, "{:?}", s.diagnostics());
    }

    #[test]
    fn dbgmcu_offsets_without_a_register_are_reported() {
        let mut s = soc();
        assert_eq!(s.bus_read(DBGMCU_BASE, 4), crate::periph::dbgmcu::IDCODE);
        s.bus_write(DBGMCU_BASE + 0x10, 4, 1 << 11);
        assert!(s.dbgmcu().tim1_stop());
        assert!(s.diagnostics().is_empty(), "{:?}", s.diagnostics());
        s.bus_read(DBGMCU_BASE + 0x20, 4);
        s.bus_write(DBGMCU_BASE + 0x24, 4, 1);
        let what: Vec<String> = s.diagnostics().iter().map(|d| d.to_string()).collect();
        assert_eq!(
            what,
            [
                "read of unmodelled register DBGMCU+0x20",
                "write to unmodelled register DBGMCU+0x24"
            ]
        );
    }

    #[test]
    fn thumb_blocks_cost_cycles_with_the_programmed_wait_states() {
        let mut s = Soc::new(
            // movs r0,#1 (16) ; ldr.w r1,[r2] (32) ; bx lr (16)
            vec![0x01, 0x20, 0xD2, 0xF8, 0x00, 0x10, 0x70, 0x47],
            Box::new(BareBoard),
        );
        // At reset LATENCY = 0: 1 + 2 + 1 and the refill of a branch target.
        assert_eq!(s.block_cycles(FLASH_BASE, 8), 5);
        assert_eq!(s.cycles.instructions, 3);
        // 4 wait states, caches off: the one 64-bit line costs 4 more.
        s.bus_write(0x4002_2000, 4, 4);
        assert_eq!(s.block_cycles(FLASH_BASE, 8), 9);
    }
}
