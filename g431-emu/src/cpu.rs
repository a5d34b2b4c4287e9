//! The Cortex-M4F: Unicorn executes the instructions; this module adds what Unicorn lacks
//! for M-profile (ARMv7-M ARM B1.5): exception entry with basic or FP-extended frames and
//! 8-byte stack alignment, EXC_RETURN, tail-chaining, PRIMASK/BASEPRI/FAULTMASK gating,
//! WFE/WFI with the event register and SEV, fault escalation to HardFault, lockup, system
//! reset, and a debugger that can halt the core.
//!
//! Virtual time: CPU cycles from the approximate Cortex-M4 cycle model (`cycles.rs`). A
//! block hook adds each translated block's cycles (its instructions' TRM costs, the refill
//! when it was branched to, the flash wait states FLASH_ACR leaves) to [`Soc::now`], the
//! MMIO hooks add the bus cycles of each peripheral access, exception entry, return and
//! tail-chaining add the TRM's latencies. The block hook stops the CPU at the first block
//! boundary at or after the SoC's deadline (the next peripheral event), where the run loop
//! processes the event and takes interrupts. A polling loop on an unchanging register makes the SoC jump
//! the clock to the next event (see `soc`), and WFE/WFI skip idle time the same way.
//!
//! What Unicorn 2.1.5 does that this relies on (checked in its QEMU sources):
//! * WFE/YIELD and UDF reach the invalid-instruction hook (`arm_stop_interrupt`); the PC is
//!   after the WFE but at the UDF.
//! * A branch to EXC_RETURN in Handler mode raises EXCP_EXCEPTION_EXIT (interrupt 8) with
//!   the magic value in PC; in Thread mode (stale flags) it fetches from 0xFFFFFFxx, which
//!   is unmapped: both are handled as an exception return.
//! * SEV is a no-op: code hooks on every SEV site set the event register.
//! * The FPU is always enabled (`fp_exception_el` returns 0): CPACR is a plain register.
//! * Writing IPSR/CONTROL through the register API does not rebuild the cached CPU flags;
//!   writing APSR_NZCV does, so every entry and return ends with that write.

use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::rc::Rc;

use unicorn_engine::unicorn_const::{Arch, HookType, MemType, Mode, Prot};
pub use unicorn_engine::RegisterARM;
use unicorn_engine::{ArmCpuModel, Unicorn};

use crate::cycles::{periph_access_cycles, FlashTiming};
use crate::periph::rcc::ResetKind;
use crate::scs::{exc, fault};
use crate::soc::{
    Board, Soc, FLASH_BASE, FLASH_BYTES, RAM_BASE, RAM_BYTES, SYSMEM_BASE, SYSMEM_BYTES,
};
use crate::time::Cycles;

/// Interrupt numbers Unicorn's ARM target reports (QEMU `EXCP_*`).
mod excp {
    pub const UDEF: u32 = 1;
    pub const SWI: u32 = 2;
    pub const PREFETCH_ABORT: u32 = 3;
    pub const DATA_ABORT: u32 = 4;
    pub const BKPT: u32 = 7;
    pub const EXCEPTION_EXIT: u32 = 8;
    pub const NOCP: u32 = 17;
    pub const INVSTATE: u32 = 18;
}

/// What the core is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CpuState {
    Running,
    /// WFE or WFI: no instructions until a wake-up event.
    Sleeping {
        wfi: bool,
    },
    /// Halted by the debugger (a test's `halt`, or BKPT with a debugger attached).
    Halted,
    /// A fault at HardFault priority: the core stops (B1.5.15) until a reset.
    Lockup,
    /// BOOT0 was high at reset: the ROM bootloader runs instead of the image.
    BootRom,
}

/// Something the core did that a run reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CpuEvent {
    /// An exception escalated to HardFault (faulting PC, CFSR, HFSR).
    HardFault {
        at: Cycles,
        pc: u32,
        cfsr: u32,
        hfsr: u32,
    },
    /// The core locked up.
    Lockup { at: Cycles, pc: u32 },
    /// A reset and why.
    Reset { at: Cycles, why: ResetKind },
    /// BOOT0 high at reset: the image does not start.
    BootRom { at: Cycles },
    /// An instruction the emulator cannot execute (reported, then faulted).
    Unsupported { at: Cycles, pc: u32, what: String },
}

/// The event register and stop reasons the hooks leave for the run loop.
#[derive(Debug, Default)]
struct HookState {
    event: Cell<bool>,
    wfe: Cell<bool>,
    udf: Cell<bool>,
    intr: Cell<Option<u32>>,
    wfi: Cell<bool>,
    unmapped: Cell<Option<(u32, bool)>>,
    /// Masked stretches, kept by the hooks on CPSID/CPSIE/MSR.
    masks: RefCell<MaskTracker>,
}

/// A stretch of execution: how long, and where it started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stretch {
    /// Cycles from its start to its end (block granularity: see [`TimingReport`]).
    pub cycles: Cycles,
    /// Instructions executed in it.
    pub instructions: u64,
    /// The instruction that started it (CPSID, MSR, or a handler's first instruction).
    pub pc: u32,
    /// The cycle it started.
    pub at: Cycles,
}

impl Stretch {
    fn keep_longer(&mut self, other: Stretch) {
        if other.cycles > self.cycles {
            *self = other;
        }
    }
}

/// The longest stretches the core spent with interrupts masked and in each handler, in
/// cycles of the cycle model and in instructions: the emulator's view of what the
/// `dwt-cycles` image measures with DWT CYCCNT. Starts and ends are taken at the end of
/// the block holding the CPSID/CPSIE/MSR (virtual time advances a whole block at a time),
/// so a stretch is exact to within the cycles of those two blocks.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TimingReport {
    /// Longest with PRIMASK set (CPSID i .. CPSIE i, or MSR PRIMASK).
    pub primask: Stretch,
    /// The longest PRIMASK stretch per instruction that started it: each inlined critical
    /// section has its own CPSID, so this separates them (`examples/where.rs` names a PC).
    pub primask_by_site: BTreeMap<u32, Stretch>,
    /// Longest with BASEPRI non-zero.
    pub basepri: Stretch,
    /// Per exception number (16 + IRQ), the longest run from the handler's first instruction
    /// to its exception return, without the entry and return latencies, including any
    /// handler that preempted it.
    pub handlers: BTreeMap<u16, Stretch>,
}

impl TimingReport {
    /// The longest run of interrupt `name` (`"TIM1_UP_TIM16"`).
    pub fn irq(&self, name: &str) -> Option<Stretch> {
        let irq = crate::names::irq(name)?;
        self.handlers.get(&(exc::IRQ0 + irq)).copied()
    }
}

/// Open masked stretches and the longest closed ones.
#[derive(Debug, Default)]
struct MaskTracker {
    primask_since: Option<Stretch>,
    basepri_since: Option<Stretch>,
    report: TimingReport,
}

/// A core register by number (R0-R12, SP, LR, PC).
fn core_reg(n: u32) -> RegisterARM {
    [
        RegisterARM::R0,
        RegisterARM::R1,
        RegisterARM::R2,
        RegisterARM::R3,
        RegisterARM::R4,
        RegisterARM::R5,
        RegisterARM::R6,
        RegisterARM::R7,
        RegisterARM::R8,
        RegisterARM::R9,
        RegisterARM::R10,
        RegisterARM::R11,
        RegisterARM::R12,
        RegisterARM::SP,
        RegisterARM::LR,
        RegisterARM::PC,
    ][(n & 0xF) as usize]
}

/// Updates the masked stretches for the mask instruction `op` (first halfword) / `op2` at
/// `pc`, about to execute with the current PRIMASK/BASEPRI in `uc`.
fn track_mask(uc: &Unicorn<'_, Soc>, masks: &RefCell<MaskTracker>, pc: u32, op: u16, op2: u16) {
    let primask = uc.reg_read(RegisterARM::PRIMASK).unwrap_or(0) & 1 != 0;
    let basepri = uc.reg_read(RegisterARM::BASEPRI).unwrap_or(0) as u8;
    let (new_primask, new_basepri) = match op {
        0xB672 => (true, basepri),
        0xB662 => (false, basepri),
        _ if op & 0xFFF0 == 0xF380 => {
            let v = uc.reg_read(core_reg(u32::from(op & 0xF))).unwrap_or(0) as u32;
            match op2 & 0xFF {
                0x10 => (v & 1 != 0, basepri),
                0x11 => (primask, v as u8),
                0x12 if v as u8 != 0 && (basepri == 0 || (v as u8) < basepri) => (primask, v as u8),
                _ => (primask, basepri),
            }
        }
        _ => (primask, basepri),
    };
    let s = uc.get_data();
    let here = Stretch {
        cycles: 0,
        instructions: s.cycles.instructions,
        pc,
        at: s.now,
    };
    let close = |open: Stretch| Stretch {
        cycles: here.at.saturating_sub(open.at),
        instructions: here.instructions.saturating_sub(open.instructions),
        ..open
    };
    let mut m = masks.borrow_mut();
    if new_primask && !primask {
        m.primask_since = Some(here);
    } else if !new_primask && primask {
        if let Some(open) = m.primask_since.take() {
            let closed = close(open);
            m.report.primask.keep_longer(closed);
            m.report
                .primask_by_site
                .entry(open.pc)
                .or_default()
                .keep_longer(closed);
        }
    }
    if new_basepri != 0 && basepri == 0 {
        m.basepri_since = Some(here);
    } else if new_basepri == 0 && basepri != 0 {
        if let Some(open) = m.basepri_since.take() {
            m.report.basepri.keep_longer(close(open));
        }
    }
}

/// A Cortex-M4F with its SoC.
pub struct Cpu {
    uc: Unicorn<'static, Soc>,
    hooks: Rc<HookState>,
    state: CpuState,
    pc: u32,
    events: Vec<CpuEvent>,
    /// Instructions of the image that set the event register, sleep, or unmask interrupts.
    sev_sites: Vec<u32>,
    /// The image's vector table base in flash.
    vectors: u32,
    /// Exception entries, by exception number (16 + IRQ for interrupts).
    entries: Vec<u64>,
    /// Handlers running (exception number, when and at which instruction count their
    /// first instruction ran), innermost last.
    handler_stack: Vec<(u16, Cycles, u64)>,
    /// Cycles of the last exception return, not yet charged: a tail-chain replaces them.
    returning: Option<Cycles>,
}

fn rd(uc: &Unicorn<'static, Soc>, r: RegisterARM) -> u32 {
    uc.reg_read(r).unwrap_or(0) as u32
}

fn wr(uc: &mut Unicorn<'static, Soc>, r: RegisterARM, v: u32) {
    let _ = uc.reg_write(r, u64::from(v));
}

/// Registers a basic frame holds, in stack order.
const FRAME_REGS: [RegisterARM; 6] = [
    RegisterARM::R0,
    RegisterARM::R1,
    RegisterARM::R2,
    RegisterARM::R3,
    RegisterARM::R12,
    RegisterARM::LR,
];

const FP_REGS: [RegisterARM; 16] = [
    RegisterARM::S0,
    RegisterARM::S1,
    RegisterARM::S2,
    RegisterARM::S3,
    RegisterARM::S4,
    RegisterARM::S5,
    RegisterARM::S6,
    RegisterARM::S7,
    RegisterARM::S8,
    RegisterARM::S9,
    RegisterARM::S10,
    RegisterARM::S11,
    RegisterARM::S12,
    RegisterARM::S13,
    RegisterARM::S14,
    RegisterARM::S15,
];

/// CONTROL bits.
const CONTROL_SPSEL: u32 = 1 << 1;
const CONTROL_FPCA: u32 = 1 << 2;
/// xPSR bit 9: the frame was realigned by 4 bytes.
const XPSR_ALIGN: u32 = 1 << 9;
/// PC of a locked-up core.
const LOCKUP_PC: u32 = 0xEFFF_FFFE;

/// Halfword sites in `flash` that may be SEV, WFI, CPSIE/CPSID i or an MSR to a mask register.
fn scan_sites(flash: &[u8]) -> Vec<u32> {
    let hw = |i: usize| -> u16 {
        flash
            .get(i..i + 2)
            .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]))
    };
    let mut sites = Vec::new();
    let mut i = 0;
    while i + 1 < flash.len() {
        let h = hw(i);
        let is_sev = h == 0xBF40 || h == 0xBF30;
        let is_cpsie = h == 0xB662 || h == 0xB661 || h == 0xB672;
        let is_msr = h & 0xFFF0 == 0xF380 && {
            let h2 = hw(i + 2);
            h2 & 0xFF00 == 0x8800 && (0x10..=0x14).contains(&(h2 & 0xFF))
        };
        if is_sev || is_cpsie || is_msr {
            sites.push(FLASH_BASE + i as u32);
        }
        i += 2;
    }
    sites
}

impl Cpu {
    /// A G431 with `flash` (the image's flash contents from 0x0800_0000) on `board`, just
    /// after power-on.
    pub fn new(flash: Vec<u8>, board: Box<dyn Board>) -> anyhow::Result<Self> {
        let soc = Soc::new(flash, board);
        let mut uc = Unicorn::new_with_data(Arch::ARM, Mode::THUMB | Mode::MCLASS, soc)
            .map_err(|e| anyhow::anyhow!("unicorn: {e:?}"))?;
        uc.ctl_set_cpu_model(ArmCpuModel::CORTEX_M4 as i32)
            .map_err(|e| anyhow::anyhow!("unicorn cpu model: {e:?}"))?;
        let (flash_ptr, ram_ptr, sys_ptr) = {
            let s = uc.get_data_mut();
            (
                s.flash.as_mut_ptr(),
                s.ram.as_mut_ptr(),
                s.sysmem.as_mut_ptr(),
            )
        };
        // SAFETY: the buffers live in the SoC, which Unicorn owns for as long as the
        // mapping exists; they are never resized after `Soc::new`, so the pointers stay
        // valid, and the host only touches them while the CPU is stopped or from hooks on
        // this thread.
        unsafe {
            let m = |e| anyhow::anyhow!("unicorn map: {e:?}");
            uc.mem_map_ptr(
                u64::from(FLASH_BASE),
                FLASH_BYTES as u64,
                Prot::READ | Prot::EXEC,
                flash_ptr.cast(),
            )
            .map_err(m)?;
            // Boot from main flash: it is aliased at address 0.
            uc.mem_map_ptr(
                0,
                FLASH_BYTES as u64,
                Prot::READ | Prot::EXEC,
                flash_ptr.cast(),
            )
            .map_err(m)?;
            uc.mem_map_ptr(
                u64::from(RAM_BASE),
                RAM_BYTES as u64,
                Prot::ALL,
                ram_ptr.cast(),
            )
            .map_err(m)?;
            uc.mem_map_ptr(
                u64::from(SYSMEM_BASE),
                SYSMEM_BYTES as u64,
                Prot::READ,
                sys_ptr.cast(),
            )
            .map_err(m)?;
        }
        let hooks = Rc::new(HookState::default());
        Self::install_hooks(&mut uc, &hooks)?;
        let sites = scan_sites(&uc.get_data().flash);
        for &site in &sites {
            let h = hooks.clone();
            uc.add_code_hook(u64::from(site), u64::from(site), move |uc, addr, _| {
                let mut b = [0u8; 4];
                let _ = uc.mem_read(addr, &mut b);
                let op = u16::from_le_bytes([b[0], b[1]]);
                let op2 = u16::from_le_bytes([b[2], b[3]]);
                if op == 0xBF40 {
                    h.event.set(true);
                } else if op == 0xBF30 {
                    // WFI: Unicorn halts after it; the run loop then sleeps.
                    h.wfi.set(true);
                } else if op == 0xB672 {
                    // CPSID i: a masked stretch starts.
                    track_mask(uc, &h.masks, addr as u32, op, op2);
                } else {
                    track_mask(uc, &h.masks, addr as u32, op, op2);
                    // Unmasking: check for a pending interrupt once this block is done.
                    let s = uc.get_data_mut();
                    if s.scs.highest_pending().is_some() {
                        s.deadline = s.deadline.min(s.now);
                    }
                }
            })
            .map_err(|e| anyhow::anyhow!("unicorn hook: {e:?}"))?;
        }
        let mut cpu = Cpu {
            uc,
            hooks,
            state: CpuState::Running,
            pc: 0,
            events: Vec::new(),
            sev_sites: sites,
            vectors: FLASH_BASE,
            entries: vec![0; 16 + crate::scs::IRQ_COUNT as usize],
            handler_stack: Vec::new(),
            returning: None,
        };
        cpu.reset(ResetKind::PowerOn);
        Ok(cpu)
    }

    fn install_hooks(uc: &mut Unicorn<'static, Soc>, hooks: &Rc<HookState>) -> anyhow::Result<()> {
        let e = |e| anyhow::anyhow!("unicorn hook: {e:?}");
        uc.add_block_hook(1, 0, |uc, addr, size| {
            let s = uc.get_data_mut();
            if s.now >= s.deadline {
                // Stopping here leaves the PC at this block, not yet executed.
                let _ = uc.emu_stop();
                return;
            }
            let n = s.block_cycles(addr as u32, size);
            s.now += n;
            s.block = addr as u32;
        })
        .map_err(e)?;
        uc.mmio_map(
            0x4000_0000,
            0x2000_0000,
            Some(|uc: &mut Unicorn<'_, Soc>, off: u64, size: usize| {
                let s = uc.get_data_mut();
                let addr = 0x4000_0000 + off as u32;
                let v = s.bus_read(addr, size);
                s.now += periph_access_cycles(addr, false);
                u64::from(v)
            }),
            Some(
                |uc: &mut Unicorn<'_, Soc>, off: u64, size: usize, value: u64| {
                    let s = uc.get_data_mut();
                    let addr = 0x4000_0000 + off as u32;
                    s.bus_write(addr, size, value as u32);
                    s.now += periph_access_cycles(addr, true);
                    after_write(uc);
                },
            ),
        )
        .map_err(e)?;
        uc.mmio_map(
            0xE000_0000,
            0x10_0000,
            Some(|uc: &mut Unicorn<'_, Soc>, off: u64, size: usize| {
                u64::from(uc.get_data_mut().bus_read(0xE000_0000 + off as u32, size))
            }),
            Some(
                |uc: &mut Unicorn<'_, Soc>, off: u64, size: usize, value: u64| {
                    uc.get_data_mut()
                        .bus_write(0xE000_0000 + off as u32, size, value as u32);
                    after_write(uc);
                },
            ),
        )
        .map_err(e)?;
        let h = hooks.clone();
        uc.add_intr_hook(move |uc, intno| {
            h.intr.set(Some(intno));
            let _ = uc.emu_stop();
        })
        .map_err(e)?;
        let h = hooks.clone();
        uc.add_insn_invalid_hook(move |uc| {
            let pc = uc.reg_read(RegisterARM::PC).unwrap_or(0) as u32;
            let half = |a: u32| {
                let mut b = [0u8; 2];
                uc.mem_read(u64::from(a), &mut b)
                    .map(|_| u16::from_le_bytes(b))
            };
            let at = half(pc).unwrap_or(0);
            let udf16 = at & 0xFF00 == 0xDE00;
            let udf32 = at & 0xFFF0 == 0xF7F0 && half(pc + 2).is_ok_and(|h2| h2 & 0xF000 == 0xA000);
            if !udf16 && !udf32 && matches!(half(pc.wrapping_sub(2)), Ok(0xBF20 | 0xBF10)) {
                // WFE (or YIELD): PC is already past it.
                if half(pc.wrapping_sub(2)) == Ok(0xBF20) {
                    if h.event.get() {
                        h.event.set(false);
                    } else {
                        h.wfe.set(true);
                        let _ = uc.emu_stop();
                    }
                }
                return true;
            }
            h.udf.set(true);
            let _ = uc.emu_stop();
            true
        })
        .map_err(e)?;
        let h = hooks.clone();
        uc.add_mem_hook(
            HookType::MEM_UNMAPPED | HookType::MEM_FETCH_PROT | HookType::MEM_WRITE_PROT,
            1,
            0,
            move |_uc, t, addr, _size, _v| {
                let write = matches!(t, MemType::WRITE_UNMAPPED | MemType::WRITE_PROT);
                h.unmapped.set(Some((addr as u32, write)));
                false
            },
        )
        .map_err(e)?;
        Ok(())
    }

    /// The SoC.
    pub fn soc(&self) -> &Soc {
        self.uc.get_data()
    }

    /// The SoC, mutably (for wiring and tests; call [`Soc::refresh`] after changing a model).
    pub fn soc_mut(&mut self) -> &mut Soc {
        self.uc.get_data_mut()
    }

    /// Current cycle.
    pub fn now(&self) -> Cycles {
        self.soc().now
    }

    pub fn state(&self) -> CpuState {
        self.state
    }

    /// What the core did so far.
    pub fn events(&self) -> &[CpuEvent] {
        &self.events
    }

    /// Program counter (the next instruction).
    pub fn pc(&self) -> u32 {
        self.pc
    }

    /// Reads a core register.
    pub fn reg(&self, r: RegisterARM) -> u32 {
        rd(&self.uc, r)
    }

    /// Writes a core register as a debugger does (DCRSR/DCRDR) while the core is halted;
    /// `PC` sets where it resumes. Tests use it to put the core where the hardware can end
    /// up (a stack pointer past the bottom of RAM after an overflow, a jump into nowhere).
    /// Ignored while the core runs.
    pub fn write_reg(&mut self, r: RegisterARM, v: u32) {
        if self.state != CpuState::Halted {
            return;
        }
        if r == RegisterARM::PC {
            self.pc = v & !1;
        } else {
            wr(&mut self.uc, r, v);
        }
    }

    /// Sites of SEV/WFI/CPSIE/MSR the CPU watches (for tests).
    pub fn watched_sites(&self) -> usize {
        self.sev_sites.len()
    }

    /// Attaches (or detaches) a debugger: DHCSR.C_DEBUGEN reads 1 and BKPT halts the core
    /// instead of escalating to HardFault.
    pub fn set_debugger(&mut self, attached: bool) {
        self.soc_mut().scs.debugger = attached;
    }

    /// Halts the core as a debugger does (C_HALT). Peripherals go on unless DBGMCU freezes
    /// them.
    pub fn halt(&mut self) {
        if matches!(self.state, CpuState::Running | CpuState::Sleeping { .. }) {
            self.state = CpuState::Halted;
            self.soc_mut().debug_halt(true);
        }
    }

    /// Resumes a halted core.
    pub fn resume(&mut self) {
        if self.state == CpuState::Halted {
            self.state = CpuState::Running;
            self.soc_mut().debug_halt(false);
        }
    }

    /// A system reset of kind `why`: every peripheral to reset, the core restarts from the
    /// vector table (RAM keeps its contents, as on the chip).
    pub fn reset(&mut self, why: ResetKind) {
        let at = self.now();
        self.soc_mut().system_reset(why);
        self.events.push(CpuEvent::Reset { at, why });
        let sp = self.soc().mem_word(FLASH_BASE).unwrap_or(0);
        let pc = self.soc().mem_word(FLASH_BASE + 4).unwrap_or(0);
        for r in [
            RegisterARM::PRIMASK,
            RegisterARM::BASEPRI,
            RegisterARM::FAULTMASK,
            RegisterARM::CONTROL,
            RegisterARM::IPSR,
        ] {
            wr(&mut self.uc, r, 0);
        }
        wr(&mut self.uc, RegisterARM::LR, 0xFFFF_FFFF);
        wr(&mut self.uc, RegisterARM::SP, sp & !3);
        wr(&mut self.uc, RegisterARM::XPSR_NZCVQG, 1 << 24);
        self.rebuild_flags();
        self.pc = pc & !1;
        self.vectors = FLASH_BASE;
        self.hooks.event.set(false);
        self.handler_stack.clear();
        self.returning = None;
        {
            let mut m = self.hooks.masks.borrow_mut();
            m.primask_since = None;
            m.basepri_since = None;
        }
        self.state = CpuState::Running;
        if self.boot0_high() {
            self.state = CpuState::BootRom;
            self.events.push(CpuEvent::BootRom { at });
        }
    }

    /// BOOT0 as the chip samples it at reset: from the option bytes with nSWBOOT0 = 0,
    /// else from the PB8 pin (factory option bytes).
    fn boot0_high(&mut self) -> bool {
        use crate::periph::flash::{Flash, OPTR_NSWBOOT0};
        use crate::periph::gpio::{Drive, External, Pull};
        let s = self.soc_mut();
        let optr = s
            .slot_of("FLASH")
            .and_then(|k| s.model::<Flash>(k))
            .map_or(crate::periph::flash::OPTR_FACTORY, |f| f.optr());
        if optr & OPTR_NSWBOOT0 == 0 {
            // nBOOT0 (bit 27) = 0 selects system memory.
            return optr & (1 << 27) == 0;
        }
        // PB8 has a pull-down during reset (RM0440 §2.6: BOOT0 pin pulled down internally).
        let now = s.now;
        let drives = |_: u8, _: u8| Drive::Released { pull: Pull::None };
        s.board.external(1, 8, now, &drives) == External::High
    }

    /// Rebuilds Unicorn's cached CPU flags after IPSR/CONTROL changed (see module docs).
    fn rebuild_flags(&mut self) {
        let nzcv = rd(&self.uc, RegisterARM::APSR_NZCV);
        wr(&mut self.uc, RegisterARM::APSR_NZCV, nzcv);
    }

    fn exec_priority(&self) -> (bool, u8, bool) {
        (
            rd(&self.uc, RegisterARM::PRIMASK) & 1 != 0,
            rd(&self.uc, RegisterARM::BASEPRI) as u8,
            rd(&self.uc, RegisterARM::FAULTMASK) & 1 != 0,
        )
    }

    fn vector(&self, n: u16) -> u32 {
        let vtor = self.soc().scs.vtor();
        let base = if vtor == 0 { self.vectors } else { vtor };
        self.soc().mem_word(base + 4 * u32::from(n)).unwrap_or(0)
    }

    fn write_word(&mut self, addr: u32, v: u32) -> bool {
        self.soc_mut().set_ram_word(addr, v)
    }

    fn read_word(&self, addr: u32) -> Option<u32> {
        self.soc().mem_word(addr)
    }

    /// Exception entry (B1.5.6): stacks the frame, sets LR to EXC_RETURN, IPSR, and jumps
    /// to the vector. Returns false when stacking failed (a derived fault).
    fn enter(&mut self, n: u16) -> bool {
        let control = rd(&self.uc, RegisterARM::CONTROL);
        let handler = self.soc().ipsr != 0;
        let fpca = control & CONTROL_FPCA != 0 && self.soc().scs.aspen();
        let psp = !handler && control & CONTROL_SPSEL != 0;
        let sp = if psp {
            rd(&self.uc, RegisterARM::PSP)
        } else {
            rd(&self.uc, RegisterARM::SP)
        };
        let size = if fpca { 0x68 } else { 0x20 };
        let align = self.soc().scs.stkalign() && sp & 4 != 0;
        let frame = sp.wrapping_sub(size) & if self.soc().scs.stkalign() { !4 } else { !0 };
        let mut xpsr = rd(&self.uc, RegisterARM::XPSR);
        if align {
            xpsr |= XPSR_ALIGN;
        }
        let mut words: Vec<u32> = FRAME_REGS.iter().map(|r| rd(&self.uc, *r)).collect();
        words.push(self.pc);
        words.push(xpsr);
        if fpca {
            for r in FP_REGS {
                words.push(rd(&self.uc, r));
            }
            words.push(rd(&self.uc, RegisterARM::FPSCR));
            words.push(0);
        }
        let mut ok = true;
        for (k, w) in words.iter().enumerate() {
            ok &= self.write_word(frame + 4 * k as u32, *w);
        }
        if !ok {
            return false;
        }
        let mut exc_return = 0xFFFF_FFE1u32;
        if !handler {
            exc_return |= 0x8;
            if psp {
                exc_return |= 0x4;
            }
        }
        if !fpca {
            exc_return |= 0x10;
        }
        if psp {
            wr(&mut self.uc, RegisterARM::PSP, frame);
            // Handler mode runs on MSP.
            wr(
                &mut self.uc,
                RegisterARM::CONTROL,
                control & !CONTROL_SPSEL & !CONTROL_FPCA,
            );
        } else {
            wr(&mut self.uc, RegisterARM::SP, frame);
            wr(&mut self.uc, RegisterARM::CONTROL, control & !CONTROL_FPCA);
        }
        wr(&mut self.uc, RegisterARM::LR, exc_return);
        wr(
            &mut self.uc,
            RegisterARM::XPSR_NZCVQG,
            (1 << 24) | u32::from(n),
        );
        wr(&mut self.uc, RegisterARM::IPSR, u32::from(n));
        self.rebuild_flags();
        let s = self.soc_mut();
        s.scs.activate(n);
        s.ipsr = n;
        self.pc = self.vector(n) & !1;
        if let Some(c) = self.entries.get_mut(usize::from(n)) {
            *c += 1;
        }
        // A pending return's unstacking is skipped when the next handler tail-chains.
        let tail_chain = self.returning.take().is_some();
        let vtor = self.soc().scs.vtor();
        let base = if vtor == 0 { self.vectors } else { vtor };
        let s = self.soc_mut();
        let flash = FlashTiming::from_acr(s.flash_acr());
        let c = s
            .cycles
            .timing
            .entry(tail_chain, fpca, base + 4 * u32::from(n), flash);
        s.now += c;
        let (now, instructions) = (s.now, s.cycles.instructions);
        self.handler_stack.push((n, now, instructions));
        true
    }

    /// The longest masked stretches and handler runs since power-on or the last
    /// [`Cpu::clear_timing_report`].
    pub fn timing_report(&self) -> TimingReport {
        self.hooks.masks.borrow().report.clone()
    }

    /// Starts a new measurement window for [`Cpu::timing_report`] (e.g. after the boot).
    pub fn clear_timing_report(&mut self) {
        self.hooks.masks.borrow_mut().report = TimingReport::default();
    }

    /// How many times exception `n` (16 + IRQ for an interrupt) was entered.
    pub fn entries(&self, n: u16) -> u64 {
        self.entries.get(usize::from(n)).copied().unwrap_or(0)
    }

    /// How many times interrupt `name` (`"TIM1_UP_TIM16"`) was entered.
    pub fn irq_entries(&self, name: &str) -> u64 {
        crate::names::irq(name).map_or(0, |irq| self.entries(exc::IRQ0 + irq))
    }

    /// Exception return (B1.5.8) for the EXC_RETURN value `magic`.
    fn exit(&mut self, magic: u32) {
        let n = self.soc().ipsr;
        if let Some(k) = self.handler_stack.iter().rposition(|&(m, _, _)| m == n) {
            let (_, at, instructions) = self.handler_stack.remove(k);
            self.handler_stack.truncate(k);
            let s = self.soc();
            let run = Stretch {
                cycles: s.now.saturating_sub(at),
                instructions: s.cycles.instructions.saturating_sub(instructions),
                pc: self.vector(n) & !1,
                at,
            };
            self.hooks
                .masks
                .borrow_mut()
                .report
                .handlers
                .entry(n)
                .or_default()
                .keep_longer(run);
        }
        let extended_return = magic & 0x10 == 0;
        self.returning = Some(self.soc_mut().cycles.timing.exit(extended_return));
        let to_thread = magic & 0x8 != 0;
        let from_psp = magic & 0x4 != 0;
        let extended = magic & 0x10 == 0;
        self.soc_mut().scs.deactivate(n);
        let sp = if from_psp {
            rd(&self.uc, RegisterARM::PSP)
        } else {
            rd(&self.uc, RegisterARM::SP)
        };
        let count = if extended { 26 } else { 8 };
        let words: Vec<u32> = (0..count)
            .map(|k| self.read_word(sp + 4 * k).unwrap_or(0))
            .collect();
        for (r, v) in FRAME_REGS.iter().zip(&words) {
            wr(&mut self.uc, *r, *v);
        }
        let ret = words.get(6).copied().unwrap_or(0);
        let xpsr = words.get(7).copied().unwrap_or(0);
        if extended {
            for (k, r) in FP_REGS.iter().enumerate() {
                wr(&mut self.uc, *r, words.get(8 + k).copied().unwrap_or(0));
            }
            wr(
                &mut self.uc,
                RegisterARM::FPSCR,
                words.get(24).copied().unwrap_or(0),
            );
        }
        let mut new_sp = sp + 4 * count;
        if xpsr & XPSR_ALIGN != 0 {
            new_sp += 4;
        }
        let mut control = rd(&self.uc, RegisterARM::CONTROL) & !(CONTROL_FPCA | CONTROL_SPSEL);
        if extended {
            control |= CONTROL_FPCA;
        }
        if from_psp {
            wr(&mut self.uc, RegisterARM::PSP, new_sp);
            control |= CONTROL_SPSEL;
        } else {
            wr(&mut self.uc, RegisterARM::SP, new_sp);
        }
        let ipsr = if to_thread { 0 } else { (xpsr & 0x1FF) as u16 };
        wr(&mut self.uc, RegisterARM::CONTROL, control);
        wr(
            &mut self.uc,
            RegisterARM::XPSR_NZCVQG,
            (xpsr & !0x1FF & !XPSR_ALIGN) | u32::from(ipsr),
        );
        wr(&mut self.uc, RegisterARM::IPSR, u32::from(ipsr));
        self.rebuild_flags();
        self.soc_mut().ipsr = ipsr;
        self.pc = ret & !1;
        // An exception return sets the event register (B1.5.18).
        self.hooks.event.set(true);
    }

    /// A synchronous fault `n` (UsageFault/BusFault) at the current PC: taken as itself if
    /// enabled and possible, else escalated to HardFault, else lockup.
    fn fault(&mut self, n: u16, cfsr_bits: u32, bfar: Option<u32>) {
        let at = self.now();
        let pc = self.pc;
        {
            let s = self.soc_mut();
            s.scs.record_fault(cfsr_bits, bfar);
        }
        let (primask, basepri, faultmask) = self.exec_priority();
        let exec = self
            .soc()
            .scs
            .execution_priority(primask, basepri, faultmask);
        let target = if self.soc().scs.fault_enabled(n) && self.soc().scs.priority(n) < exec {
            n
        } else {
            self.soc_mut().scs.hfsr |= fault::FORCED;
            exc::HARD_FAULT
        };
        if target == exc::HARD_FAULT && exec <= -1 {
            self.lockup();
            return;
        }
        if target == exc::HARD_FAULT {
            let s = self.soc();
            let (cfsr, hfsr) = (s.scs.cfsr, s.scs.hfsr);
            self.events.push(CpuEvent::HardFault { at, pc, cfsr, hfsr });
        }
        self.soc_mut().scs.set_pending(target);
        if !self.enter(target) {
            // Stacking failed: a derived fault at HardFault priority.
            self.soc_mut().scs.record_fault(fault::STKERR, None);
            self.lockup();
        }
    }

    fn lockup(&mut self) {
        let at = self.now();
        self.events.push(CpuEvent::Lockup { at, pc: self.pc });
        self.state = CpuState::Lockup;
        self.pc = LOCKUP_PC;
        self.soc_mut().lockup(true);
    }

    /// Runs the core and its SoC up to cycle `until`.
    pub fn run_until(&mut self, until: Cycles) {
        self.run_loop(until);
        self.soc_mut().collect_reports();
    }

    fn run_loop(&mut self, until: Cycles) {
        loop {
            let now = self.now();
            self.soc_mut().advance_to(now);
            if self.soc().watchdog_expired() {
                self.reset(ResetKind::Watchdog);
                continue;
            }
            if self.soc().stop.system_reset {
                self.reset(ResetKind::Software);
                continue;
            }
            if self.now() >= until {
                break;
            }
            let (primask, basepri, faultmask) = self.exec_priority();
            match self.state {
                CpuState::Running => {}
                CpuState::Sleeping { wfi } => {
                    let s = self.soc();
                    let wake = s.scs.wakes(primask, basepri, faultmask, wfi)
                        || (!wfi && s.scs.sevonpend() && s.scs.highest_pending().is_some());
                    if wake {
                        self.state = CpuState::Running;
                    } else {
                        self.skip_to(until);
                        continue;
                    }
                }
                CpuState::Halted | CpuState::Lockup | CpuState::BootRom => {
                    self.skip_to(until);
                    continue;
                }
            }
            if let Some(n) = self.soc().scs.take(primask, basepri, faultmask) {
                if !self.enter(n) {
                    self.fault(exc::HARD_FAULT, fault::STKERR, None);
                }
                continue;
            }
            self.step(until);
        }
    }

    /// Idle until the next event or `until`, whichever is first.
    fn skip_to(&mut self, until: Cycles) {
        let next = self.soc().next_event().unwrap_or(Cycles::MAX);
        let t = next.min(until).max(self.now());
        self.soc_mut().now = t;
    }

    /// Executes instructions until the next event, `until`, or a stop.
    fn step(&mut self, until: Cycles) {
        if let Some(c) = self.returning.take() {
            self.soc_mut().now += c;
        }
        {
            let s = self.soc_mut();
            s.deadline = s.next_event().unwrap_or(Cycles::MAX).min(until);
            s.stop.irq = false;
        }
        self.hooks.wfe.set(false);
        self.hooks.wfi.set(false);
        self.hooks.udf.set(false);
        self.hooks.intr.set(None);
        self.hooks.unmapped.set(None);
        let start = self.pc;
        let r = self.uc.emu_start(u64::from(start | 1), 0, 0, 0);
        self.pc = rd(&self.uc, RegisterARM::PC);
        let at = self.now();
        if self.pc >= 0xF000_0000 && self.pc != LOCKUP_PC {
            // A branch to EXC_RETURN (Handler mode raised EXCEPTION_EXIT, or Thread-mode
            // flags fetched the magic address).
            let magic = self.pc | 1;
            self.hooks.unmapped.set(None);
            self.hooks.intr.set(None);
            if self.soc().ipsr != 0 {
                self.exit(magic);
            } else {
                self.fault(exc::USAGE_FAULT, fault::INVSTATE, None);
            }
            return;
        }
        if self.hooks.wfe.get() {
            self.state = CpuState::Sleeping { wfi: false };
            return;
        }
        if self.hooks.wfi.get() {
            self.state = CpuState::Sleeping { wfi: true };
            return;
        }
        if self.hooks.udf.get() {
            self.fault(exc::USAGE_FAULT, fault::UNDEFINSTR, None);
            return;
        }
        if let Some((addr, write)) = self.hooks.unmapped.get() {
            let _ = write;
            let bits = if self.pc == addr & !1 {
                fault::IBUSERR
            } else {
                fault::PRECISERR
            };
            self.fault(exc::BUS_FAULT, bits, Some(addr));
            return;
        }
        if let Some(intno) = self.hooks.intr.get() {
            match intno {
                excp::BKPT => {
                    if self.soc().scs.debugger {
                        self.state = CpuState::Halted;
                        self.soc_mut().debug_halt(true);
                    } else {
                        // No debugger: BKPT escalates to HardFault (DEBUGEVT).
                        self.soc_mut().scs.hfsr |= fault::DEBUGEVT;
                        self.fault(exc::HARD_FAULT, 0, None);
                    }
                }
                excp::SWI => {
                    self.soc_mut().scs.set_pending(exc::SVCALL);
                }
                excp::EXCEPTION_EXIT => {}
                excp::UDEF | excp::NOCP | excp::INVSTATE => {
                    self.fault(exc::USAGE_FAULT, fault::UNDEFINSTR, None)
                }
                excp::PREFETCH_ABORT | excp::DATA_ABORT => {
                    self.fault(exc::BUS_FAULT, fault::PRECISERR, None)
                }
                other => {
                    self.events.push(CpuEvent::Unsupported {
                        at,
                        pc: self.pc,
                        what: format!("Unicorn exception {other}"),
                    });
                    self.fault(exc::USAGE_FAULT, fault::UNDEFINSTR, None);
                }
            }
            return;
        }
        if r.is_err() {
            self.events.push(CpuEvent::Unsupported {
                at,
                pc: self.pc,
                what: format!("{r:?}"),
            });
            self.lockup();
        }
    }
}

/// After a register write: if an interrupt can now be taken or a reset was requested, the
/// CPU stops at the next block boundary. (Stopping inside an MMIO callback would make
/// Unicorn re-execute the store: it recompiles the block to end at the I/O instruction and
/// restarts there.)
fn after_write(uc: &mut Unicorn<'_, Soc>) {
    let stop = uc.get_data().stop;
    let mut now_please = stop.system_reset;
    if stop.irq {
        uc.get_data_mut().stop.irq = false;
        let primask = uc.reg_read(RegisterARM::PRIMASK).unwrap_or(0) & 1 != 0;
        let basepri = uc.reg_read(RegisterARM::BASEPRI).unwrap_or(0) as u8;
        let faultmask = uc.reg_read(RegisterARM::FAULTMASK).unwrap_or(0) & 1 != 0;
        now_please |= uc
            .get_data()
            .scs
            .take(primask, basepri, faultmask)
            .is_some();
    }
    if now_please {
        let s = uc.get_data_mut();
        s.deadline = s.deadline.min(s.now);
    }
}
