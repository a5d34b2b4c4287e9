//! The Cortex-M4's System Control Space as the images use it: NVIC, SCB, SysTick, the FPU's
//! control registers, DWT's cycle counter and the debug registers (ARMv7-M ARM B3).
//!
//! Unicorn has none of this for M-profile. [`Scs`] holds the exception state (pending,
//! active, priorities) and decides what the CPU takes next; the CPU module
//! ([`crate::cpu`]) performs entry and return. Priorities follow B1.5.4: 4 implemented
//! bits (the upper nibble of each 8-bit field), group priority split by AIRCR.PRIGROUP,
//! Reset -3, NMI -2, HardFault -1, ties broken by the lower exception number.

use crate::periph::{IrqLines, Write};
use crate::time::Cycles;

/// Base address of the System Control Space.
pub const SCS_BASE: u32 = 0xE000_E000;

/// Interrupt lines the G431's NVIC implements (102: IRQ 0..=101).
pub const IRQ_COUNT: u16 = 102;

/// Exception numbers (B1.5.2).
pub mod exc {
    pub const RESET: u16 = 1;
    pub const NMI: u16 = 2;
    pub const HARD_FAULT: u16 = 3;
    pub const MEM_MANAGE: u16 = 4;
    pub const BUS_FAULT: u16 = 5;
    pub const USAGE_FAULT: u16 = 6;
    pub const SVCALL: u16 = 11;
    pub const DEBUG_MONITOR: u16 = 12;
    pub const PENDSV: u16 = 14;
    pub const SYSTICK: u16 = 15;
    /// Exception number of IRQ 0.
    pub const IRQ0: u16 = 16;
}

/// Priority of "no exception active, nothing masked".
pub const THREAD_PRIORITY: i16 = 256;

/// Implemented priority bits (the G431 has 4).
const PRIO_MASK: u8 = 0xF0;

/// Bits of CFSR and HFSR the CPU module sets when it escalates a fault.
pub mod fault {
    /// UFSR.UNDEFINSTR (CFSR bit 16).
    pub const UNDEFINSTR: u32 = 1 << 16;
    /// UFSR.INVSTATE (CFSR bit 17).
    pub const INVSTATE: u32 = 1 << 17;
    /// BFSR.PRECISERR (CFSR bit 9).
    pub const PRECISERR: u32 = 1 << 9;
    /// BFSR.IBUSERR (CFSR bit 8).
    pub const IBUSERR: u32 = 1 << 8;
    /// BFSR.STKERR (CFSR bit 12).
    pub const STKERR: u32 = 1 << 12;
    /// HFSR.FORCED: a configurable fault escalated to HardFault.
    pub const FORCED: u32 = 1 << 30;
    /// HFSR.DEBUGEVT: a BKPT without a debugger.
    pub const DEBUGEVT: u32 = 1 << 31;
}

/// What a write to the SCS asks the CPU/SoC to do besides changing registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ScsEffects {
    /// AIRCR.SYSRESETREQ written with the right key: a system reset.
    pub system_reset: bool,
}

/// The System Control Space.
#[derive(Debug, Clone)]
pub struct Scs {
    enabled: [u32; 4],
    pending: [u32; 4],
    active: [u32; 4],
    /// Asserted peripheral lines (level-sensitive), as last sampled.
    lines: IrqLines,
    irq_prio: [u8; IRQ_COUNT as usize],
    /// Pending/active system exceptions, bit = exception number (1..=15).
    sys_pending: u16,
    sys_active: u16,
    /// SHPR1-3: priorities of exceptions 4..=15, index = exception number.
    sys_prio: [u8; 16],
    prigroup: u8,
    vtor: u32,
    scr: u32,
    ccr: u32,
    shcsr_enables: u32,
    /// Configurable fault status (CFSR) and HardFault status (HFSR).
    pub cfsr: u32,
    pub hfsr: u32,
    mmfar: u32,
    bfar: u32,
    cpacr: u32,
    fpccr: u32,
    fpcar: u32,
    fpdscr: u32,
    // SysTick.
    st_ctrl: u32,
    st_reload: u32,
    /// Cycle at which the SysTick counter was last loaded with `st_loaded`.
    st_epoch: Cycles,
    st_loaded: u32,
    st_countflag: bool,
    // DWT / DCB.
    dwt_ctrl: u32,
    /// CYCCNT = cycle - dwt_epoch while counting.
    dwt_epoch: Cycles,
    dwt_frozen: u32,
    demcr: u32,
    /// A debugger is attached (DHCSR.C_DEBUGEN reads 1): BKPT halts instead of faulting.
    pub debugger: bool,
}

impl Default for Scs {
    fn default() -> Self {
        Scs::new()
    }
}

fn bit_get(set: &[u32; 4], n: u16) -> bool {
    set.get(usize::from(n / 32))
        .is_some_and(|w| w & (1 << (n % 32)) != 0)
}

fn bit_put(set: &mut [u32; 4], n: u16, v: bool) {
    if let Some(w) = set.get_mut(usize::from(n / 32)) {
        if v {
            *w |= 1 << (n % 32);
        } else {
            *w &= !(1 << (n % 32));
        }
    }
}

impl Scs {
    /// Reset state (B3.2: everything disabled, priorities 0, VTOR 0).
    pub fn new() -> Self {
        Scs {
            enabled: [0; 4],
            pending: [0; 4],
            active: [0; 4],
            lines: IrqLines::default(),
            irq_prio: [0; IRQ_COUNT as usize],
            sys_pending: 0,
            sys_active: 0,
            sys_prio: [0; 16],
            prigroup: 0,
            vtor: 0,
            scr: 0,
            // STKALIGN resets to 1 on the Cortex-M4.
            ccr: 1 << 9,
            shcsr_enables: 0,
            cfsr: 0,
            hfsr: 0,
            mmfar: 0,
            bfar: 0,
            cpacr: 0,
            // ASPEN | LSPEN (reset value on the M4 with FPU).
            fpccr: 0xC000_0000,
            fpcar: 0,
            fpdscr: 0,
            st_ctrl: 0,
            st_reload: 0,
            st_epoch: 0,
            st_loaded: 0,
            st_countflag: false,
            dwt_ctrl: 0,
            dwt_epoch: 0,
            dwt_frozen: 0,
            demcr: 0,
            debugger: false,
        }
    }

    /// Vector table base.
    pub fn vtor(&self) -> u32 {
        self.vtor
    }

    /// SCR.SEVONPEND: a pending interrupt wakes WFE even when it cannot be taken.
    pub fn sevonpend(&self) -> bool {
        self.scr & (1 << 4) != 0
    }

    /// CCR.STKALIGN: exception frames are 8-byte aligned.
    pub fn stkalign(&self) -> bool {
        self.ccr & (1 << 9) != 0
    }

    /// FPCCR.ASPEN: the FP context is stacked automatically when CONTROL.FPCA is set.
    pub fn aspen(&self) -> bool {
        self.fpccr & (1 << 31) != 0
    }

    /// The group priority of an 8-bit priority field (B1.5.4, with 4 implemented bits).
    fn group(&self, field: u8) -> i16 {
        let field = field & PRIO_MASK;
        // PRIGROUP n: bits [7:n+1] are the group priority.
        let shift = u32::from(self.prigroup) + 1;
        let group = if shift >= 8 {
            0
        } else {
            (field >> shift) << shift
        };
        i16::from(group)
    }

    /// Priority of exception `n` (its group priority; fixed for Reset/NMI/HardFault).
    pub fn priority(&self, n: u16) -> i16 {
        match n {
            exc::RESET => -3,
            exc::NMI => -2,
            exc::HARD_FAULT => -1,
            4..=15 => self.group(self.sys_prio.get(usize::from(n)).copied().unwrap_or(0)),
            _ => {
                let irq = n.saturating_sub(exc::IRQ0);
                self.group(self.irq_prio.get(usize::from(irq)).copied().unwrap_or(0))
            }
        }
    }

    fn is_active(&self, n: u16) -> bool {
        if n < exc::IRQ0 {
            self.sys_active & (1 << n) != 0
        } else {
            bit_get(&self.active, n - exc::IRQ0)
        }
    }

    fn is_pending(&self, n: u16) -> bool {
        if n < exc::IRQ0 {
            self.sys_pending & (1 << n) != 0
        } else {
            bit_get(&self.pending, n - exc::IRQ0)
        }
    }

    /// Any exception active (the CPU is in Handler mode).
    pub fn any_active(&self) -> bool {
        self.sys_active != 0 || self.active.iter().any(|w| *w != 0)
    }

    /// The execution priority (B1.5.4): the highest (lowest-valued) priority of the active
    /// exceptions, boosted by PRIMASK (0), BASEPRI (its group) and FAULTMASK (-1).
    pub fn execution_priority(&self, primask: bool, basepri: u8, faultmask: bool) -> i16 {
        let mut p = THREAD_PRIORITY;
        for n in 2..exc::IRQ0 {
            if self.sys_active & (1 << n) != 0 {
                p = p.min(self.priority(n));
            }
        }
        for irq in 0..IRQ_COUNT {
            if bit_get(&self.active, irq) {
                p = p.min(self.priority(exc::IRQ0 + irq));
            }
        }
        if basepri & PRIO_MASK != 0 {
            p = p.min(self.group(basepri));
        }
        if primask {
            p = p.min(0);
        }
        if faultmask {
            p = p.min(-1);
        }
        p
    }

    /// The pending exception that would be taken first (enabled, highest priority, lowest
    /// number on a tie), whatever the masks.
    pub fn highest_pending(&self) -> Option<(u16, i16)> {
        let mut best: Option<(u16, i16)> = None;
        let mut consider = |n: u16, p: i16| {
            if best.is_none_or(|(_, bp)| p < bp) {
                best = Some((n, p));
            }
        };
        for n in 2..exc::IRQ0 {
            if self.sys_pending & (1 << n) != 0 && self.sys_enabled(n) {
                consider(n, self.priority(n));
            }
        }
        for irq in 0..IRQ_COUNT {
            if bit_get(&self.pending, irq) && bit_get(&self.enabled, irq) {
                consider(exc::IRQ0 + irq, self.priority(exc::IRQ0 + irq));
            }
        }
        best
    }

    /// A configurable fault handler is enabled in SHCSR (otherwise it escalates).
    fn sys_enabled(&self, n: u16) -> bool {
        match n {
            exc::MEM_MANAGE => self.shcsr_enables & (1 << 16) != 0,
            exc::BUS_FAULT => self.shcsr_enables & (1 << 17) != 0,
            exc::USAGE_FAULT => self.shcsr_enables & (1 << 18) != 0,
            _ => true,
        }
    }

    /// The exception the CPU must take now, if any: the highest pending one whose priority
    /// is higher than the execution priority.
    pub fn take(&self, primask: bool, basepri: u8, faultmask: bool) -> Option<u16> {
        let (n, p) = self.highest_pending()?;
        (p < self.execution_priority(primask, basepri, faultmask)).then_some(n)
    }

    /// Whether something pending would wake a WFE/WFI: an exception that can be taken, or
    /// any pending interrupt with SEVONPEND (WFE) / regardless of PRIMASK (WFI, B1.5.19).
    pub fn wakes(&self, primask: bool, basepri: u8, faultmask: bool, wfi: bool) -> bool {
        if self.take(primask, basepri, faultmask).is_some() {
            return true;
        }
        if wfi {
            // WFI wakes on an interrupt that would be taken if PRIMASK were clear.
            return self.take(false, basepri, faultmask).is_some();
        }
        false
    }

    /// Entry bookkeeping: `n` becomes active and stops pending.
    pub fn activate(&mut self, n: u16) {
        if n < exc::IRQ0 {
            self.sys_active |= 1 << n;
            self.sys_pending &= !(1 << n);
        } else {
            bit_put(&mut self.active, n - exc::IRQ0, true);
            bit_put(&mut self.pending, n - exc::IRQ0, false);
        }
    }

    /// Return bookkeeping: `n` is no longer active; a level-sensitive line still asserted
    /// pends it again.
    pub fn deactivate(&mut self, n: u16) {
        if n < exc::IRQ0 {
            self.sys_active &= !(1 << n);
        } else {
            let irq = n - exc::IRQ0;
            bit_put(&mut self.active, irq, false);
            if self.lines.get(irq) {
                bit_put(&mut self.pending, irq, true);
            }
        }
    }

    /// Sets exception `n` pending (a fault, SVC, or a pulse).
    pub fn set_pending(&mut self, n: u16) {
        if n < exc::IRQ0 {
            self.sys_pending |= 1 << n;
        } else {
            bit_put(&mut self.pending, n - exc::IRQ0, true);
        }
    }

    /// Is exception `n` active (for the fault escalation rules).
    pub fn active(&self, n: u16) -> bool {
        self.is_active(n)
    }

    /// Is exception `n` pending.
    pub fn pending(&self, n: u16) -> bool {
        self.is_pending(n)
    }

    /// The peripheral lines as last sampled.
    pub fn lines(&self) -> IrqLines {
        self.lines
    }

    /// Samples the peripherals' lines (level-sensitive): an asserted line that is not
    /// active becomes pending (B3.4.1).
    pub fn sample_lines(&mut self, lines: &IrqLines) {
        self.lines = *lines;
        for (k, (p, a)) in self.pending.iter_mut().zip(self.active.iter()).enumerate() {
            let l = lines.0.get(k).copied().unwrap_or(0);
            *p |= l & !a;
        }
    }

    /// The configurable fault `n` (MemManage/BusFault/UsageFault) can be taken as itself;
    /// otherwise it escalates to HardFault (B1.5.8).
    pub fn fault_enabled(&self, n: u16) -> bool {
        self.sys_enabled(n)
    }

    // ---- SysTick (B3.3) -------------------------------------------------------------

    fn st_enabled(&self) -> bool {
        self.st_ctrl & 1 != 0
    }

    /// Current value of the SysTick counter at `now`.
    fn st_value(&self, now: Cycles) -> u32 {
        if !self.st_enabled() {
            return self.st_loaded;
        }
        let elapsed = now.saturating_sub(self.st_epoch);
        let loaded = u64::from(self.st_loaded);
        if elapsed <= loaded {
            return (loaded - elapsed) as u32;
        }
        let period = u64::from(self.st_reload) + 1;
        if self.st_reload == 0 {
            return 0;
        }
        // After reaching 0 the counter reloads with RVR on the next clock.
        let after = (elapsed - loaded - 1) % period;
        (u64::from(self.st_reload) - after) as u32
    }

    /// The next cycle at which SysTick counts down to 0.
    pub fn next_event(&self, now: Cycles) -> Option<Cycles> {
        if !self.st_enabled() || (self.st_reload == 0 && self.st_loaded == 0) {
            return None;
        }
        let v = u64::from(self.st_value(now));
        if v == 0 {
            // Wraps to RVR next clock, reaches 0 again RVR clocks later.
            return Some(now + u64::from(self.st_reload) + 1);
        }
        Some(now + v)
    }

    /// Brings SysTick to `now`: a count to 0 sets COUNTFLAG and, with TICKINT, pends
    /// exception 15.
    pub fn advance(&mut self, now: Cycles, last: Cycles) {
        if !self.st_enabled() {
            return;
        }
        let Some(zero) = self.next_event(last) else {
            return;
        };
        if zero <= now {
            self.st_countflag = true;
            if self.st_ctrl & 2 != 0 {
                self.set_pending(exc::SYSTICK);
            }
        }
    }

    // ---- Register access ------------------------------------------------------------

    /// CYCCNT at `now`.
    fn cyccnt(&self, now: Cycles) -> u32 {
        if self.dwt_ctrl & 1 != 0 {
            (now.wrapping_sub(self.dwt_epoch)) as u32
        } else {
            self.dwt_frozen
        }
    }

    /// Reads the PPB register at `addr` (0xE000_0000..0xE010_0000). `ipsr` is the active
    /// exception number (for ICSR.VECTACTIVE). `None`: not modelled.
    pub fn read(&mut self, addr: u32, now: Cycles, ipsr: u16) -> Option<u32> {
        let v = match addr {
            // DWT
            0xE000_1000 => self.dwt_ctrl | (4 << 28), // NUMCOMP = 4
            0xE000_1004 => self.cyccnt(now),
            // ICTR: 4 x 32 interrupt lines
            0xE000_E004 => 3,
            0xE000_E008 => 0, // ACTLR
            0xE000_E010 => {
                let flag = u32::from(self.st_countflag) << 16;
                // COUNTFLAG clears on read.
                self.st_countflag = false;
                self.st_ctrl | flag | (1 << 2)
            }
            0xE000_E014 => self.st_reload,
            0xE000_E018 => self.st_value(now),
            0xE000_E01C => 0, // CALIB: no reference clock, no TENMS
            0xE000_E100..=0xE000_E10C => self.word(&self.enabled, addr - 0xE000_E100),
            0xE000_E180..=0xE000_E18C => self.word(&self.enabled, addr - 0xE000_E180),
            0xE000_E200..=0xE000_E20C => self.word(&self.pending, addr - 0xE000_E200),
            0xE000_E280..=0xE000_E28C => self.word(&self.pending, addr - 0xE000_E280),
            0xE000_E300..=0xE000_E30C => self.word(&self.active, addr - 0xE000_E300),
            0xE000_E400..=0xE000_E464 => {
                let base = (addr - 0xE000_E400) as usize;
                let mut v = 0u32;
                for k in 0..4 {
                    v |= u32::from(self.irq_prio.get(base + k).copied().unwrap_or(0)) << (8 * k);
                }
                v
            }
            0xE000_ED00 => 0x410F_C241, // CPUID: Cortex-M4 r0p1
            0xE000_ED04 => self.icsr(ipsr),
            0xE000_ED08 => self.vtor,
            0xE000_ED0C => 0xFA05_0000 | (u32::from(self.prigroup) << 8),
            0xE000_ED10 => self.scr,
            0xE000_ED14 => self.ccr,
            0xE000_ED18..=0xE000_ED20 => {
                let base = (addr - 0xE000_ED18) as usize + 4;
                let mut v = 0u32;
                for k in 0..4 {
                    v |= u32::from(self.sys_prio.get(base + k).copied().unwrap_or(0)) << (8 * k);
                }
                v
            }
            0xE000_ED24 => self.shcsr(),
            0xE000_ED28 => self.cfsr,
            0xE000_ED2C => self.hfsr,
            0xE000_ED30 => 0, // DFSR
            0xE000_ED34 => self.mmfar,
            0xE000_ED38 => self.bfar,
            0xE000_ED3C => 0, // AFSR
            0xE000_ED88 => self.cpacr,
            // DHCSR: C_DEBUGEN only while a debugger is attached.
            0xE000_EDF0 => u32::from(self.debugger),
            0xE000_EDFC => self.demcr,
            0xE000_EF34 => self.fpccr,
            0xE000_EF38 => self.fpcar,
            0xE000_EF3C => self.fpdscr,
            // ID registers of the ROM table / peripheral IDs some crates probe.
            0xE000_EF40 => 0x1011_0021, // MVFR0
            0xE000_EF44 => 0x1100_0011, // MVFR1
            _ => return None,
        };
        Some(v)
    }

    fn word(&self, set: &[u32; 4], off: u32) -> u32 {
        set.get((off / 4) as usize).copied().unwrap_or(0)
    }

    fn icsr(&self, ipsr: u16) -> u32 {
        let pending = self.highest_pending().map_or(0, |(n, _)| u32::from(n));
        let isrpending = self.pending.iter().any(|w| *w != 0);
        let mut v = u32::from(ipsr & 0x1FF) | (pending << 12) | (u32::from(isrpending) << 22);
        if self.sys_pending & (1 << exc::SYSTICK) != 0 {
            v |= 1 << 26;
        }
        if self.sys_pending & (1 << exc::PENDSV) != 0 {
            v |= 1 << 28;
        }
        if self.sys_pending & (1 << exc::NMI) != 0 {
            v |= 1 << 31;
        }
        // RETTOBASE: only one exception active.
        let active_count =
            self.sys_active.count_ones() + self.active.iter().map(|w| w.count_ones()).sum::<u32>();
        if active_count <= 1 {
            v |= 1 << 11;
        }
        v
    }

    fn shcsr(&self) -> u32 {
        let mut v = self.shcsr_enables;
        let act = |n: u16| u32::from(self.sys_active & (1 << n) != 0);
        let pend = |n: u16| u32::from(self.sys_pending & (1 << n) != 0);
        v |= act(exc::MEM_MANAGE)
            | (act(exc::BUS_FAULT) << 1)
            | (act(exc::USAGE_FAULT) << 3)
            | (act(exc::SVCALL) << 7)
            | (act(exc::DEBUG_MONITOR) << 8)
            | (act(exc::PENDSV) << 10)
            | (act(exc::SYSTICK) << 11)
            | (pend(exc::USAGE_FAULT) << 12)
            | (pend(exc::MEM_MANAGE) << 13)
            | (pend(exc::BUS_FAULT) << 14)
            | (pend(exc::SVCALL) << 15);
        v
    }

    /// Writes the PPB register `w.offset` (an absolute address here). `false`: not
    /// modelled.
    pub fn write(&mut self, addr: u32, w: Write, now: Cycles) -> Option<ScsEffects> {
        let mut fx = ScsEffects::default();
        let v = w.value & w.mask;
        match addr {
            0xE000_1000 => {
                let was = self.dwt_ctrl & 1 != 0;
                self.dwt_ctrl = w.merge(self.dwt_ctrl) & 0x0FFF_FFFF;
                let is = self.dwt_ctrl & 1 != 0;
                if was && !is {
                    self.dwt_frozen = (now.wrapping_sub(self.dwt_epoch)) as u32;
                } else if !was && is {
                    self.dwt_epoch = now.wrapping_sub(u64::from(self.dwt_frozen));
                }
            }
            0xE000_1004 => {
                let c = w.merge(self.cyccnt(now));
                self.dwt_frozen = c;
                self.dwt_epoch = now.wrapping_sub(u64::from(c));
            }
            0xE000_E008 => {}
            0xE000_E010 => {
                let was = self.st_enabled();
                let cur = self.st_value(now);
                self.st_ctrl = w.merge(self.st_ctrl) & 0x7;
                if !was && self.st_enabled() {
                    self.st_loaded = cur;
                    self.st_epoch = now;
                } else if was && !self.st_enabled() {
                    self.st_loaded = cur;
                }
            }
            0xE000_E014 => self.st_reload = w.merge(self.st_reload) & 0x00FF_FFFF,
            0xE000_E018 => {
                // Any write clears the counter and COUNTFLAG.
                self.st_loaded = 0;
                self.st_epoch = now;
                self.st_countflag = false;
            }
            0xE000_E100..=0xE000_E10C => self.set_bits(Set::Enabled, addr - 0xE000_E100, v, true),
            0xE000_E180..=0xE000_E18C => self.set_bits(Set::Enabled, addr - 0xE000_E180, v, false),
            0xE000_E200..=0xE000_E20C => self.set_bits(Set::Pending, addr - 0xE000_E200, v, true),
            0xE000_E280..=0xE000_E28C => {
                self.set_bits(Set::Pending, addr - 0xE000_E280, v, false);
                // A still-asserted line pends again at once (level-sensitive).
                let lines = self.lines;
                self.sample_lines(&lines);
            }
            0xE000_E400..=0xE000_E464 => {
                let base = (addr - 0xE000_E400) as usize;
                for k in 0..4 {
                    if w.mask & (0xFF << (8 * k)) != 0 {
                        if let Some(p) = self.irq_prio.get_mut(base + k) {
                            *p = ((w.value >> (8 * k)) as u8) & PRIO_MASK;
                        }
                    }
                }
            }
            0xE000_ED04 => {
                // ICSR: PENDSVSET/CLR, PENDSTSET/CLR, NMIPENDSET.
                if v & (1 << 28) != 0 {
                    self.sys_pending |= 1 << exc::PENDSV;
                }
                if v & (1 << 27) != 0 {
                    self.sys_pending &= !(1 << exc::PENDSV);
                }
                if v & (1 << 26) != 0 {
                    self.sys_pending |= 1 << exc::SYSTICK;
                }
                if v & (1 << 25) != 0 {
                    self.sys_pending &= !(1 << exc::SYSTICK);
                }
                if v & (1 << 31) != 0 {
                    self.sys_pending |= 1 << exc::NMI;
                }
            }
            0xE000_ED08 => self.vtor = w.merge(self.vtor) & 0xFFFF_FF80,
            0xE000_ED0C => {
                // Writes need VECTKEY 0x05FA in the upper half.
                let full = w.merge(0xFA05_0000 | (u32::from(self.prigroup) << 8));
                if full >> 16 == 0x05FA {
                    self.prigroup = ((full >> 8) & 7) as u8;
                    if full & (1 << 2) != 0 {
                        fx.system_reset = true;
                    }
                    if full & (1 << 1) != 0 {
                        // VECTCLRACTIVE (debug only): clear active state.
                        self.sys_active = 0;
                        self.active = [0; 4];
                    }
                }
            }
            0xE000_ED10 => self.scr = w.merge(self.scr) & 0x16,
            0xE000_ED14 => self.ccr = w.merge(self.ccr) & 0x31B,
            0xE000_ED18..=0xE000_ED20 => {
                let base = (addr - 0xE000_ED18) as usize + 4;
                for k in 0..4 {
                    if w.mask & (0xFF << (8 * k)) != 0 {
                        if let Some(p) = self.sys_prio.get_mut(base + k) {
                            *p = ((w.value >> (8 * k)) as u8) & PRIO_MASK;
                        }
                    }
                }
            }
            0xE000_ED24 => self.shcsr_enables = w.merge(self.shcsr_enables) & (7 << 16),
            0xE000_ED28 => self.cfsr &= !v,
            0xE000_ED2C => self.hfsr &= !v,
            0xE000_ED34 => self.mmfar = w.merge(self.mmfar),
            0xE000_ED38 => self.bfar = w.merge(self.bfar),
            0xE000_ED88 => self.cpacr = w.merge(self.cpacr) & 0x00F0_0000,
            0xE000_EDF0 => {
                // DHCSR writes need DBGKEY 0xA05F; halting from software is not modelled.
            }
            0xE000_EDFC => self.demcr = w.merge(self.demcr) & 0x010F_07F1,
            0xE000_EF00 => {
                // STIR: software-triggered interrupt.
                let irq = (v & 0x1FF) as u16;
                if irq < IRQ_COUNT {
                    bit_put(&mut self.pending, irq, true);
                }
            }
            0xE000_EF34 => self.fpccr = w.merge(self.fpccr) & 0xC000_01FB,
            0xE000_EF38 => self.fpcar = w.merge(self.fpcar) & !7,
            0xE000_EF3C => self.fpdscr = w.merge(self.fpdscr) & 0x07C0_0000,
            _ => return None,
        }
        Some(fx)
    }

    fn set_bits(&mut self, which: Set, off: u32, v: u32, set: bool) {
        let k = (off / 4) as usize;
        // Lines beyond IRQ_COUNT are not implemented (RAZ/WI).
        let implemented = match k {
            0..=2 => !0u32,
            3 => (1u32 << (IRQ_COUNT - 96)) - 1,
            _ => 0,
        };
        let target = match which {
            Set::Enabled => &mut self.enabled,
            Set::Pending => &mut self.pending,
        };
        if let Some(word) = target.get_mut(k) {
            if set {
                *word |= v & implemented;
            } else {
                *word &= !v;
            }
        }
    }

    /// Records a fault's status bits (CFSR) and, for a BusFault, its address.
    pub fn record_fault(&mut self, cfsr_bits: u32, bfar: Option<u32>) {
        self.cfsr |= cfsr_bits;
        if let Some(a) = bfar {
            self.bfar = a;
            // BFARVALID
            self.cfsr |= 1 << 15;
        }
    }
}

enum Set {
    Enabled,
    Pending,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn enable(s: &mut Scs, irq: u16) {
        let reg = 0xE000_E100 + u32::from(irq / 32) * 4;
        s.write(reg, Write::word(0, 1 << (irq % 32)), 0);
    }

    fn set_prio(s: &mut Scs, irq: u16, prio: u8) {
        let reg = 0xE000_E400 + u32::from(irq & !3);
        let shift = 8 * u32::from(irq % 4);
        s.write(
            reg,
            Write {
                offset: 0,
                value: u32::from(prio) << shift,
                mask: 0xFF << shift,
            },
            0,
        );
    }

    #[test]
    fn a_pending_enabled_irq_is_taken_in_thread_mode() {
        let mut s = Scs::new();
        let mut l = IrqLines::default();
        l.set(25);
        s.sample_lines(&l);
        assert_eq!(s.take(false, 0, false), None, "disabled: not taken");
        enable(&mut s, 25);
        assert_eq!(s.take(false, 0, false), Some(exc::IRQ0 + 25));
        assert_eq!(s.take(true, 0, false), None, "PRIMASK masks it");
    }

    #[test]
    fn priorities_use_the_upper_nibble_and_lower_number_wins_a_tie() {
        let mut s = Scs::new();
        for irq in [24, 25, 38] {
            enable(&mut s, irq);
            s.set_pending(exc::IRQ0 + irq);
        }
        set_prio(&mut s, 38, 0x20);
        set_prio(&mut s, 24, 0x10);
        set_prio(&mut s, 25, 0x1F); // low nibble not implemented: same as 0x10
        assert_eq!(s.priority(exc::IRQ0 + 25), 0x10);
        assert_eq!(s.highest_pending(), Some((exc::IRQ0 + 24, 0x10)));
    }

    #[test]
    fn an_active_handler_is_preempted_only_by_a_higher_priority() {
        let mut s = Scs::new();
        enable(&mut s, 25);
        enable(&mut s, 38);
        set_prio(&mut s, 25, 0x00);
        set_prio(&mut s, 38, 0x20);
        s.set_pending(exc::IRQ0 + 38);
        s.activate(exc::IRQ0 + 38);
        s.set_pending(exc::IRQ0 + 38);
        assert_eq!(
            s.take(false, 0, false),
            None,
            "same priority does not preempt"
        );
        s.set_pending(exc::IRQ0 + 25);
        assert_eq!(s.take(false, 0, false), Some(exc::IRQ0 + 25));
        // BASEPRI 0x10 masks priority 0x20 and below, not 0x00.
        s.deactivate(exc::IRQ0 + 38);
        assert_eq!(s.take(false, 0x10, false), Some(exc::IRQ0 + 25));
        s.activate(exc::IRQ0 + 25);
        assert_eq!(s.take(false, 0x10, false), None);
    }

    #[test]
    fn level_lines_pend_again_after_return_while_asserted() {
        let mut s = Scs::new();
        enable(&mut s, 30);
        let mut l = IrqLines::default();
        l.set(30);
        s.sample_lines(&l);
        s.activate(exc::IRQ0 + 30);
        s.sample_lines(&l);
        assert!(!s.pending(exc::IRQ0 + 30), "not pended while active");
        s.deactivate(exc::IRQ0 + 30);
        assert!(s.pending(exc::IRQ0 + 30), "still asserted: pending again");
        // The handler cleared the flag before returning: no re-pend.
        s.activate(exc::IRQ0 + 30);
        s.sample_lines(&IrqLines::default());
        s.deactivate(exc::IRQ0 + 30);
        assert!(!s.pending(exc::IRQ0 + 30));
    }

    #[test]
    fn clear_pending_of_an_asserted_line_pends_it_again() {
        let mut s = Scs::new();
        let mut l = IrqLines::default();
        l.set(3);
        s.sample_lines(&l);
        s.write(0xE000_E280, Write::word(0, 1 << 3), 0);
        assert!(s.pending(exc::IRQ0 + 3));
    }

    #[test]
    fn aircr_needs_its_key() {
        let mut s = Scs::new();
        let fx = s
            .write(0xE000_ED0C, Write::word(0, 1 << 2), 0)
            .unwrap_or_default();
        assert!(!fx.system_reset);
        let fx = s
            .write(0xE000_ED0C, Write::word(0, 0x05FA_0004), 0)
            .unwrap_or_default();
        assert!(fx.system_reset);
    }

    #[test]
    fn systick_counts_down_and_pends() {
        let mut s = Scs::new();
        s.write(0xE000_E014, Write::word(0, 99), 0);
        s.write(0xE000_E018, Write::word(0, 0), 0);
        s.write(0xE000_E010, Write::word(0, 0b111), 10);
        // Loaded with 0: reaches 0 at once, reloads 99 on the next clock.
        assert_eq!(s.read(0xE000_E018, 11, 0), Some(99));
        assert_eq!(s.read(0xE000_E018, 20, 0), Some(90));
        let next = s.next_event(20);
        assert_eq!(next, Some(110));
        s.advance(110, 20);
        assert!(s.pending(exc::SYSTICK));
        let ctrl = s.read(0xE000_E010, 110, 0).unwrap_or(0);
        assert!(ctrl & (1 << 16) != 0, "COUNTFLAG set");
        let ctrl = s.read(0xE000_E010, 111, 0).unwrap_or(0);
        assert!(ctrl & (1 << 16) == 0, "COUNTFLAG clears on read");
    }

    #[test]
    fn cyccnt_counts_cycles_while_enabled() {
        let mut s = Scs::new();
        s.write(0xE000_1004, Write::word(0, 0), 100);
        s.write(0xE000_1000, Write::word(0, 1), 100);
        assert_eq!(s.read(0xE000_1004, 1100, 0), Some(1000));
        s.write(0xE000_1000, Write::word(0, 0), 1100);
        assert_eq!(s.read(0xE000_1004, 5000, 0), Some(1000));
    }

    #[test]
    fn faults_escalate_unless_enabled() {
        let mut s = Scs::new();
        assert!(!s.fault_enabled(exc::USAGE_FAULT));
        s.write(0xE000_ED24, Write::word(0, 1 << 18), 0);
        assert!(s.fault_enabled(exc::USAGE_FAULT));
    }
}
