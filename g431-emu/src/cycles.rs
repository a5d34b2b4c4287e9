//! An approximate Cortex-M4 cycle model: what virtual time advances by.
//!
//! Each basic block Unicorn translates is decoded once ([`decode_block`]): its instructions'
//! costs from the Cortex-M4 Technical Reference Manual (ARM DDI 0439, r0p1, 3.3.1 "Processor
//! instruction timings", Table 3-1, and 7.2.3 for the FPU), summed into the block's *core*
//! cycles, with the 64-bit flash lines it is fetched from and the literal-pool words it loads.
//! At run time [`Timing::block`] adds what depends on the path and the flash interface: the
//! pipeline refill when the block was reached by a branch, and the wait states of every flash
//! line that is neither in the fetch buffer nor in the instruction cache (RM0440 3.3.3-3.3.4,
//! FLASH_ACR LATENCY/PRFTEN/ICEN/DCEN as the image programs them). Exceptions cost what the
//! TRM gives for entry, return and tail-chaining ([`ENTRY_CYCLES`] etc.).
//!
//! What the model does (TRM numbers at zero wait states):
//! * data processing, MOV/MOVW/MOVT, shifts, compares, IT, multiply and MLA/MLS, long
//!   multiplies (the M4's single-cycle MAC), saturation, bit-field, MRS/MSR, CPS, NOP: 1;
//! * SDIV/UDIV: 12, the TRM's upper bound (2-12 by operand size, not modelled: never kinder);
//! * LDR/LDRB/LDRH/LDRSx and LDREX/STREX: 2, but 1 when it follows a single load ("neighbouring
//!   load and store single instructions can pipeline their address and data phases"), and 1
//!   more when its address register was written by the instruction just before (no forwarding
//!   to the address generator); STR with an immediate offset: 1 (the data phase overlaps the
//!   next instruction), with a register offset 2; LDRD/STRD: 3; LDM/STM/PUSH/POP: 1 + N;
//! * taken branches: 1 + P, P = 1, or 2 when the target is a 32-bit instruction at an odd
//!   halfword (TRM: P is 1-3 "depending on the alignment and width of the target"); a
//!   conditional branch or CBZ that falls through: 1. Whether a branch was taken is known at
//!   the next block: a block not reached by falling through pays P. TBB/TBH: 2 + P;
//!   LDR PC/POP {PC}: as the load + P;
//! * FP: VADD/VSUB/VMUL/VABS/VNEG/VCMP/VCVT/VMOV: 1, VMLA/VMLS/VNMLA/VNMLS/VFMA/VFMS: 3,
//!   VDIV/VSQRT: 14, VLDR/VSTR: 2, VLDM/VSTM/VPUSH/VPOP: 1 + N words, VMRS/VMSR: 1;
//! * a peripheral access: loads 2 cycles and stores 1 more on the APB buses (the AHB-to-APB
//!   bridge), 1 more for a load on AHB (GPIO, ADC): charged by the CPU's MMIO hooks, see
//!   [`periph_access_cycles`].
//!
//! The flash interface (RM0440 3.3.3 "Read access latency", 3.3.4 "Adaptive real-time memory
//! accelerator"): a flash read returns 64 bits (four Thumb halfwords) after LATENCY + 1
//! cycles. Modelled per 64-bit line a block touches, in order:
//! * the line in the fetch buffer (the one just read): free;
//! * ICEN = 1 and the line in the instruction cache: free. The cache holds 1 KiB (RM0440: 32
//!   lines of 4 x 64 bits); modelled as 128 direct-mapped 64-bit entries filled on every
//!   flash read, which evicts more than the real replacement would (never kinder);
//! * PRFTEN = 1 and the line follows the previous one (sequential code): the prefetch
//!   started when the previous line was delivered, so it stalls LATENCY + 1 minus the cycles
//!   the previous line's instructions took (0 for most code at 4 wait states);
//! * otherwise (a branch to an uncached line, or sequential code without prefetch): LATENCY
//!   cycles, added to the refill.
//!
//! Literal-pool loads (`LDR Rt, [PC, #imm]`, LDRD/VLDR literal) in flash go through the
//! data cache (DCEN: RM0440 8 lines of 4 x 64 bits, modelled as 32 direct-mapped 64-bit
//! entries): a miss costs LATENCY. Other loads from flash (tables, strings through a
//! register) are charged as RAM loads: the address is not known when the block is decoded.
//! Code in RAM pays no wait states.
//!
//! Not modelled: the M4's own 3-word fetch queue beyond the above, IT folding, branch
//! speculation, bus contention with the DMA, lazy FP stacking (an FP-extended frame is
//! charged as if the handler used the FPU: never kinder). How far to trust the result is
//! in `docs/emulator.md` ("Time").

use crate::time::Cycles;

/// Exception entry: stacking and the vector fetch (TRM 3.3.1: "interrupt latency 12").
pub const ENTRY_CYCLES: Cycles = 12;
/// Exception return: unstacking and the refill (TRM: 10 for a basic frame).
pub const RETURN_CYCLES: Cycles = 10;
/// Tail-chaining from one handler into the next (TRM: 6, no unstack/restack).
pub const TAIL_CHAIN_CYCLES: Cycles = 6;
/// Stacking or unstacking the 18 words of an FP-extended frame (S0-S15, FPSCR, reserved):
/// 1 + N as for a VPUSH/VPOP of 17 words.
pub const FP_FRAME_CYCLES: Cycles = 18;

/// FLASH_ACR bits (RM0440 3.7.1).
pub mod acr {
    pub const LATENCY: u32 = 0xF;
    pub const PRFTEN: u32 = 1 << 8;
    pub const ICEN: u32 = 1 << 9;
    pub const DCEN: u32 = 1 << 10;
}

/// The flash interface's settings that change fetch timing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FlashTiming {
    /// Wait states (LATENCY).
    pub wait_states: u32,
    pub prefetch: bool,
    pub icache: bool,
    pub dcache: bool,
}

impl FlashTiming {
    /// From a FLASH_ACR value.
    pub fn from_acr(acr: u32) -> Self {
        FlashTiming {
            wait_states: acr & acr::LATENCY,
            prefetch: acr & acr::PRFTEN != 0,
            icache: acr & acr::ICEN != 0,
            dcache: acr & acr::DCEN != 0,
        }
    }
}

/// Extra cycles of a CPU access to a peripheral register at `addr` beyond the load/store's
/// own cost: the AHB-to-APB bridge (APB1 0x4000_0000, APB2 0x4001_0000) and the AHB
/// peripherals' bus (RM0440 2.1, figure 1). RM0440 gives no cycle count for the bridge; these
/// are conservative estimates (a load waits for the data, a store only when the bridge is
/// busy). The PPB (NVIC, SysTick, DWT) is the core's own and costs nothing more.
pub fn periph_access_cycles(addr: u32, write: bool) -> Cycles {
    match addr {
        0x4000_0000..=0x4001_FFFF => {
            if write {
                1
            } else {
                2
            }
        }
        0x4002_0000..=0x5FFF_FFFF => Cycles::from(!write),
        _ => 0,
    }
}

/// What a decoded block costs before the path and the flash interface are known.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BlockCost {
    /// Bytes Unicorn translated (a block with another size at the same address is decoded
    /// again).
    pub size: u32,
    /// Instructions in the block.
    pub instructions: u32,
    /// Core cycles at zero wait states, without the refill that reaching it may cost.
    pub core_cycles: u32,
    /// Pipeline refill when the block is a branch target (P).
    pub refill: u32,
    /// The 64-bit lines the block is fetched from, in order, each with the core cycles of
    /// the instructions that start in it.
    pub lines: Vec<(u32, u32)>,
    /// Literal-pool words the block loads (PC-relative addresses).
    pub literals: Vec<u32>,
}

/// One decoded instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Insn {
    cycles: u32,
    kind: Kind,
    /// A general register the instruction writes (data processing), for the address
    /// generator stall.
    writes: Option<u8>,
    /// Registers a load/store computes its address from.
    addr_regs: [Option<u8>; 2],
    /// A single load's destination (for pipelining the next access).
    load_rt: Option<u8>,
    literal: Option<u32>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Other,
    /// LDR/LDRB/LDRH/LDRSx/LDREX (single, pipelines with the next access).
    LoadSingle,
    /// STR with an immediate offset.
    StoreImm,
    /// STR with a register offset.
    StoreReg,
}

impl Insn {
    fn other(cycles: u32) -> Self {
        Insn {
            cycles,
            kind: Kind::Other,
            writes: None,
            addr_regs: [None, None],
            load_rt: None,
            literal: None,
        }
    }

    fn alu(rd: u32) -> Self {
        Insn {
            writes: Some((rd & 0xF) as u8),
            ..Insn::other(1)
        }
    }

    fn load(rt: u32, rn: u32, rm: Option<u32>) -> Self {
        Insn {
            cycles: 2,
            kind: Kind::LoadSingle,
            writes: None,
            addr_regs: [Some((rn & 0xF) as u8), rm.map(|r| (r & 0xF) as u8)],
            load_rt: Some((rt & 0xF) as u8),
            literal: None,
        }
    }

    fn store(rn: u32, rm: Option<u32>) -> Self {
        Insn {
            cycles: if rm.is_some() { 2 } else { 1 },
            kind: if rm.is_some() {
                Kind::StoreReg
            } else {
                Kind::StoreImm
            },
            writes: None,
            addr_regs: [Some((rn & 0xF) as u8), rm.map(|r| (r & 0xF) as u8)],
            load_rt: None,
            literal: None,
        }
    }
}

/// Literal address of a PC-relative access at `pc` with offset `off`.
fn literal(pc: u32, off: i64) -> u32 {
    let base = i64::from((pc + 4) & !3);
    (base + off) as u32
}

/// Decodes the 16-bit instruction `h` at `pc` (ARMv7-M ARM A5.2).
fn decode16(h: u32, pc: u32) -> Insn {
    let low3 = h & 7;
    match h >> 10 {
        // Shift/add/sub/mov/cmp (immediate) and add/sub (register): 1.
        0b000000..=0b000110 => Insn::alu(low3),
        0b000111 => Insn::alu(low3),
        0b001000..=0b001111 => {
            let op = (h >> 11) & 3;
            if op == 1 {
                Insn::other(1) // CMP
            } else {
                Insn::alu((h >> 8) & 7)
            }
        }
        // Data processing (register), MUL included: 1.
        0b010000 => {
            let op = (h >> 6) & 0xF;
            if matches!(op, 0b1000 | 0b1010 | 0b1011) {
                Insn::other(1) // TST, CMP, CMN
            } else {
                Insn::alu(low3)
            }
        }
        // Special data processing and BX/BLX.
        0b010001 => {
            let op = (h >> 8) & 3;
            let rd = ((h >> 4) & 8) | low3;
            match op {
                0b11 => Insn::other(1), // BX/BLX: P at the target
                0b01 => Insn::other(1), // CMP
                _ => Insn::alu(rd),
            }
        }
        // LDR (literal).
        0b010010 | 0b010011 => {
            let mut i = Insn::load((h >> 8) & 7, 15, None);
            i.literal = Some(literal(pc, i64::from((h & 0xFF) * 4)));
            i
        }
        // Load/store (register offset).
        0b010100..=0b010111 => {
            let opb = (h >> 9) & 7;
            let (rm, rn, rt) = ((h >> 6) & 7, (h >> 3) & 7, low3);
            if opb <= 0b010 {
                Insn::store(rn, Some(rm))
            } else {
                Insn::load(rt, rn, Some(rm))
            }
        }
        // Load/store word/byte/halfword (immediate), SP-relative.
        0b011000..=0b100111 => {
            let load = h & (1 << 11) != 0;
            let sp_rel = h >> 12 == 0b1001;
            let (rn, rt) = if sp_rel {
                (13, (h >> 8) & 7)
            } else {
                ((h >> 3) & 7, low3)
            };
            if load {
                Insn::load(rt, rn, None)
            } else {
                Insn::store(rn, None)
            }
        }
        // ADR, ADD (SP plus immediate).
        0b101000..=0b101011 => Insn::alu((h >> 8) & 7),
        // Miscellaneous.
        0b101100..=0b101111 => {
            if h & 0xFE00 == 0xB400 || h & 0xFE00 == 0xBC00 {
                // PUSH/POP: 1 + N (LR or PC in bit 8).
                let n = (h & 0x1FF).count_ones();
                Insn::other(1 + n)
            } else {
                // CBZ/CBNZ (1, P when taken), IT, hints, CPS, extend, REV, ADD/SUB SP, BKPT.
                Insn::other(1)
            }
        }
        // LDM/STM: 1 + N.
        0b110000..=0b110011 => Insn::other(1 + (h & 0xFF).count_ones()),
        // Conditional branch, UDF, SVC, B: 1 (+ P at the target).
        _ => Insn::other(1),
    }
}

/// Decodes the 32-bit instruction `h1:h2` at `pc` (ARMv7-M ARM A5.3).
fn decode32(h1: u32, h2: u32, pc: u32) -> Insn {
    let op1 = (h1 >> 11) & 3;
    let op2 = (h1 >> 4) & 0x7F;
    let rn = h1 & 0xF;
    let rd = (h2 >> 8) & 0xF;
    let rt = h2 >> 12;
    if h1 & 0xEC00 == 0xEC00 && (h2 >> 9) & 7 == 0b101 {
        return decode_fp(h1, h2, pc);
    }
    match op1 {
        0b01 => {
            if op2 & 0b110_0100 == 0 {
                // Load/store multiple (LDM/STM/PUSH.W/POP.W): 1 + N.
                Insn::other(1 + (h2 & 0xFFFF).count_ones())
            } else if op2 & 0b110_0100 == 0b000_0100 {
                // Load/store dual or exclusive, table branch.
                if h1 & 0xFFF0 == 0xE8D0 && h2 & 0xFFE0 == 0xF000 {
                    Insn::other(2) // TBB/TBH: 2 + P
                } else if h1 & 0xFFE0 == 0xE840 || h1 & 0xFFF0 == 0xE8C0 || h1 & 0xFFF0 == 0xE8D0 {
                    // LDREX/STREX (and byte/halfword forms): 2.
                    Insn::other(2)
                } else {
                    // LDRD/STRD: 1 + N, N = 2.
                    let mut i = Insn::other(3);
                    if rn == 15 && h1 & (1 << 4) != 0 {
                        let off = i64::from((h2 & 0xFF) * 4);
                        let off = if h1 & (1 << 7) != 0 { off } else { -off };
                        i.literal = Some(literal(pc, off));
                    }
                    i
                }
            } else if op2 & 0b110_0000 == 0b010_0000 {
                // Data processing (shifted register).
                if rd == 15 {
                    Insn::other(1) // TST/TEQ/CMP/CMN
                } else {
                    Insn::alu(rd)
                }
            } else {
                // Coprocessor other than the FPU.
                Insn::other(1)
            }
        }
        0b10 => {
            if h2 & 0x8000 == 0 {
                // Data processing (modified or plain immediate).
                if rd == 15 {
                    Insn::other(1)
                } else {
                    Insn::alu(rd)
                }
            } else if h1 & 0xFFF0 == 0xF3B0 && h2 & 0xFFF0 == 0x8F60 {
                // ISB: 1 + a refill.
                Insn::other(2)
            } else {
                // B.W, BL (1 + P at the target), MSR, MRS, hints, DMB/DSB: 1.
                Insn::other(1)
            }
        }
        _ => decode32_op1_11(h1, h2, pc, op2, rn, rd, rt),
    }
}

/// The `op1 = 0b11` space: single loads/stores, data processing (register), multiplies,
/// divides.
fn decode32_op1_11(h1: u32, h2: u32, pc: u32, op2: u32, rn: u32, rd: u32, rt: u32) -> Insn {
    if op2 & 0b111_0001 == 0b000_0000 {
        // Store single: register offset when h2[11] = 0 and h2[10:6] = 0 (T2).
        let reg = op2 & 0b000_1000 == 0 && h2 & 0x0FC0 == 0;
        return Insn::store(rn, reg.then_some(h2 & 0xF));
    }
    if op2 & 0b110_0000 == 0 {
        // Load byte/halfword/word (op2 = 00xx001, 00xx011, 00xx101).
        let reg = rn != 15 && op2 & 0b000_1000 == 0 && h2 & 0x0FC0 == 0;
        let mut i = Insn::load(rt, rn, reg.then_some(h2 & 0xF));
        if rn == 15 {
            let off = i64::from(h2 & 0xFFF);
            let off = if h1 & (1 << 7) != 0 { off } else { -off };
            i.literal = Some(literal(pc, off));
        }
        if rt == 15 && op2 & 0b110 != 0b100 {
            // PLD/PLI (a byte or halfword load to PC): a hint.
            return Insn::other(1);
        }
        if rt == 15 {
            // LDR PC: a blocking load, P at the target; no pipelining around it.
            i.kind = Kind::Other;
            i.load_rt = None;
        }
        return i;
    }
    if op2 & 0b111_0000 == 0b010_0000 {
        // Data processing (register): shifts, extends, parallel add/sub, REV, CLZ: 1.
        return Insn::alu(rd);
    }
    if op2 & 0b111_1000 == 0b011_0000 {
        // Multiply, multiply-accumulate, SMULxy etc.: 1 on the M4.
        return Insn::alu(rd);
    }
    if op2 & 0b111_1000 == 0b011_1000 {
        // Long multiply (1) and divide (2-12: 12).
        let op = (h1 >> 4) & 7;
        let op2b = (h2 >> 4) & 0xF;
        if (op == 0b001 || op == 0b011) && op2b == 0xF {
            return Insn {
                cycles: 12,
                ..Insn::alu(rd)
            };
        }
        return Insn::other(1);
    }
    Insn::other(1)
}

/// FPU instructions (coprocessor 10/11; TRM 7.2.3, Table 7-1).
fn decode_fp(h1: u32, h2: u32, pc: u32) -> Insn {
    if h1 & 0xEE00 == 0xEC00 {
        // Extension register load/store, 64-bit transfers.
        if h1 & 0xFFE0 == 0xEC40 {
            return Insn::other(2); // VMOV two core registers <-> D or two S
        }
        let imm8 = h2 & 0xFF;
        if h1 & 0xFF20 == 0xED00 {
            // VLDR/VSTR (P = 1, W = 0): 2.
            let load = h1 & (1 << 4) != 0;
            let mut i = Insn::other(2);
            if load && h1 & 0xF == 15 {
                let off = i64::from(imm8 * 4);
                let off = if h1 & (1 << 7) != 0 { off } else { -off };
                i.literal = Some(literal(pc, off));
            }
            return i;
        }
        // VLDM/VSTM/VPUSH/VPOP: 1 + N words.
        return Insn::other(1 + imm8);
    }
    if h2 & (1 << 4) != 0 {
        // VMOV core <-> S, VMRS/VMSR: 1.
        return Insn::other(1);
    }
    // Data processing: opc1 = h1[23:20] without D (bit 22).
    match h1 & 0x00B0 {
        0x0000 | 0x0010 | 0x0090 | 0x00A0 => Insn::other(3), // VMLA/VMLS/VNMLx/VFMx/VFNMx
        0x0080 => Insn::other(14),                           // VDIV
        0x00B0 if h1 & 0xF == 0b0001 && h2 & 0xC0 == 0xC0 => Insn::other(14), // VSQRT
        _ => Insn::other(1), // VADD/VSUB/VMUL/VNMUL, VMOV, VABS, VNEG, VCMP, VCVT
    }
}

/// True when the halfword `h` starts a 32-bit Thumb-2 instruction.
pub fn is_wide(h: u16) -> bool {
    h >> 11 >= 0b11101
}

/// Decodes the block of code `bytes` at `addr` once.
pub fn decode_block(addr: u32, bytes: &[u8]) -> BlockCost {
    let hw = |i: usize| -> u32 {
        bytes
            .get(i..i + 2)
            .map_or(0, |b| u32::from(u16::from_le_bytes([b[0], b[1]])))
    };
    let mut cost = BlockCost {
        size: bytes.len() as u32,
        refill: 1,
        ..BlockCost::default()
    };
    let mut prev: Option<Insn> = None;
    let mut i = 0;
    while i + 1 < bytes.len() {
        let pc = addr.wrapping_add(i as u32);
        let h1 = hw(i);
        let wide = is_wide(h1 as u16);
        let mut insn = if wide {
            decode32(h1, hw(i + 2), pc)
        } else {
            decode16(h1, pc)
        };
        if i == 0 && wide && addr & 2 != 0 {
            // A 32-bit target at an odd halfword takes two fetches.
            cost.refill = 2;
        }
        if insn.kind != Kind::Other {
            if let Some(p) = prev {
                let uses = |r: Option<u8>| r.is_some() && insn.addr_regs.contains(&r);
                if p.kind == Kind::LoadSingle && !uses(p.load_rt) {
                    // Pipelined behind the previous load: the address phase overlapped.
                    insn.cycles = insn.cycles.saturating_sub(1).max(1);
                } else if uses(p.writes) {
                    // No forwarding from the ALU to the address generator.
                    insn.cycles += 1;
                }
            }
        }
        if let Some(l) = insn.literal {
            cost.literals.push(l);
        }
        cost.instructions += 1;
        cost.core_cycles += insn.cycles;
        let line = pc & !7;
        match cost.lines.last_mut() {
            Some((l, c)) if *l == line => *c += insn.cycles,
            _ => cost.lines.push((line, insn.cycles)),
        }
        // A 32-bit instruction that straddles two lines needs both.
        if wide && (pc + 2) & !7 != line {
            cost.lines.push(((pc + 2) & !7, 0));
        }
        prev = Some(insn);
        i += if wide { 4 } else { 2 };
    }
    if cost.instructions == 0 {
        cost.instructions = 1;
        cost.core_cycles = 1;
    }
    cost
}

/// Where code and literal loads are fetched from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    /// Main flash (also through its alias at 0): wait states apply.
    Flash,
    /// SRAM, system memory: no wait states.
    Other,
}

const ICACHE_ENTRIES: usize = 128;
const DCACHE_ENTRIES: usize = 32;
const NO_LINE: u32 = 1;

/// The run-time state of the cycle model: the fetch buffer and the ART caches.
#[derive(Debug, Clone)]
pub struct Timing {
    /// The line address each instruction cache entry holds (`NO_LINE`: empty).
    icache: [u32; ICACHE_ENTRIES],
    dcache: [u32; DCACHE_ENTRIES],
    /// The 64-bit line in the fetch buffer.
    fetch_line: u32,
    /// Core cycles of the instructions of the last line fetched (prefetch overlap).
    fetch_line_cycles: u32,
    /// The address right after the last block: a block starting there fell through.
    next_pc: u32,
    /// The next block is a handler's first: its refill is part of the entry's cycles.
    entering: bool,
}

impl Default for Timing {
    fn default() -> Self {
        Timing {
            icache: [NO_LINE; ICACHE_ENTRIES],
            dcache: [NO_LINE; DCACHE_ENTRIES],
            fetch_line: NO_LINE,
            fetch_line_cycles: 0,
            next_pc: NO_LINE,
            entering: false,
        }
    }
}

/// Line addresses are multiples of 8, so `NO_LINE` (1) never matches one.
fn lookup(cache: &mut [u32], line: u32, fill: bool) -> bool {
    let k = (line as usize >> 3) % cache.len();
    match cache.get_mut(k) {
        Some(t) if *t == line => true,
        Some(t) => {
            if fill {
                *t = line;
            }
            false
        }
        None => false,
    }
}

impl Timing {
    /// Back to reset (caches invalid, nothing fetched).
    pub fn reset(&mut self) {
        *self = Timing::default();
    }

    /// Cycles of running the block `b` at `addr` fetched from `region`, with the flash
    /// interface set to `flash`.
    #[inline]
    pub fn block(&mut self, addr: u32, b: &BlockCost, region: Region, flash: FlashTiming) -> u64 {
        let mut c = u64::from(b.core_cycles);
        if addr != self.next_pc && !self.entering {
            c += u64::from(b.refill);
        }
        self.entering = false;
        self.next_pc = addr.wrapping_add(b.size);
        if region == Region::Flash && flash.wait_states > 0 {
            c += self.flash_stalls(b, flash);
        } else {
            self.fetch_line = NO_LINE;
        }
        c
    }

    fn flash_stalls(&mut self, b: &BlockCost, flash: FlashTiming) -> u64 {
        let ws = flash.wait_states;
        let mut stall = 0u32;
        for &(line, cycles) in &b.lines {
            let line = line & 0x07FF_FFFF; // the alias at 0 is the same flash
            if line != self.fetch_line {
                let sequential = line == self.fetch_line.wrapping_add(8);
                if flash.icache && lookup(&mut self.icache, line, false) {
                    // Served by the instruction cache.
                } else if flash.prefetch && sequential {
                    stall += (ws + 1).saturating_sub(self.fetch_line_cycles);
                    if flash.icache {
                        lookup(&mut self.icache, line, true);
                    }
                } else {
                    stall += ws;
                    if flash.icache {
                        lookup(&mut self.icache, line, true);
                    }
                }
                self.fetch_line = line;
                self.fetch_line_cycles = cycles;
            } else {
                self.fetch_line_cycles += cycles;
            }
        }
        // Literals are PC-relative: in flash, as the block is.
        for &lit in &b.literals {
            let line = lit & 0x07FF_FFF8;
            if !(flash.dcache && lookup(&mut self.dcache, line, true)) {
                stall += ws;
            }
        }
        u64::from(stall)
    }

    /// Cycles of an exception entry (or a tail-chain from the previous handler) whose
    /// vector is read at `vector_addr`, with an FP-extended frame or not.
    pub fn entry(
        &mut self,
        tail_chain: bool,
        fp_frame: bool,
        vector_addr: u32,
        flash: FlashTiming,
    ) -> Cycles {
        let mut c = if tail_chain {
            TAIL_CHAIN_CYCLES
        } else {
            ENTRY_CYCLES
        };
        if fp_frame && !tail_chain {
            c += FP_FRAME_CYCLES;
        }
        // The vector is read over the I-code bus, through the instruction cache.
        let line = vector_addr & 0x07FF_FFF8;
        if (vector_addr < 0x0010_0000 || (0x0800_0000..0x0810_0000).contains(&vector_addr))
            && flash.wait_states > 0
            && !(flash.icache && lookup(&mut self.icache, line, true))
        {
            c += Cycles::from(flash.wait_states);
        }
        self.entering = true;
        self.fetch_line = NO_LINE;
        c
    }

    /// Cycles of an exception return (unstacking and the refill at the return address).
    pub fn exit(&mut self, fp_frame: bool) -> Cycles {
        self.entering = true;
        self.fetch_line = NO_LINE;
        RETURN_CYCLES + if fp_frame { FP_FRAME_CYCLES - 1 } else { 0 }
    }
}

/// Flash as the code fetch sees it: the main array at 0x0800_0000 and its boot alias at 0.
const FLASH_BASE: u32 = 0x0800_0000;

/// The cycle model as the SoC holds it: each flash block decoded once, the run-time state,
/// and the instructions executed (for figures next to the cycles).
#[derive(Debug, Clone)]
pub struct CycleModel {
    /// Per flash halfword: 1 + the index in `costs` of the block starting there (0: none).
    index: Vec<u32>,
    costs: Vec<BlockCost>,
    pub timing: Timing,
    /// Instructions executed since power-on.
    pub instructions: u64,
    /// A FLASH_ACR the model applies instead of the image's (what-if figures, e.g. the
    /// same image with the prefetch on); `None`: the image's own.
    pub acr_override: Option<u32>,
}

impl CycleModel {
    /// For `flash_bytes` of main flash.
    pub fn new(flash_bytes: usize) -> Self {
        CycleModel {
            index: vec![0; flash_bytes / 2],
            costs: Vec::new(),
            timing: Timing::default(),
            instructions: 0,
            acr_override: None,
        }
    }

    /// A system reset: the caches are invalid (the decoded blocks stay: flash is unchanged).
    pub fn reset(&mut self) {
        self.timing.reset();
    }

    /// Cycles of the block of `size` bytes at `addr` about to run, with FLASH_ACR = `acr`.
    /// `flash` and `ram` are the memories (`ram_base` is where `ram` starts).
    #[inline]
    pub fn block(
        &mut self,
        addr: u32,
        size: u32,
        acr: u32,
        flash: &[u8],
        ram: &[u8],
        ram_base: u32,
    ) -> u64 {
        let flash_timing = FlashTiming::from_acr(acr);
        let off = if addr >= FLASH_BASE {
            addr - FLASH_BASE
        } else {
            addr
        };
        let in_flash = (off as usize) < flash.len() && (addr < 0x1000_0000);
        if in_flash {
            let k = off as usize / 2;
            let cached = self.index.get(k).copied().unwrap_or(0);
            let fresh = cached
                .checked_sub(1)
                .and_then(|i| self.costs.get(i as usize))
                .is_some_and(|c| c.size == size);
            let i = if fresh {
                cached - 1
            } else {
                let bytes = flash
                    .get(off as usize..(off + size) as usize)
                    .unwrap_or(&[]);
                let decoded = decode_block(addr, bytes);
                match cached
                    .checked_sub(1)
                    .and_then(|i| self.costs.get_mut(i as usize))
                {
                    // Unicorn translated the block again with another length.
                    Some(c) => {
                        *c = decoded;
                        cached - 1
                    }
                    None => {
                        self.costs.push(decoded);
                        let i = (self.costs.len() - 1) as u32;
                        if let Some(slot) = self.index.get_mut(k) {
                            *slot = i + 1;
                        }
                        i
                    }
                }
            };
            let Some(b) = self.costs.get(i as usize) else {
                return 1;
            };
            self.instructions += u64::from(b.instructions);
            return self.timing.block(addr, b, Region::Flash, flash_timing);
        }
        // RAM or system memory: decoded each time (the images run no code from RAM).
        let bytes = addr
            .checked_sub(ram_base)
            .and_then(|o| ram.get(o as usize..(o + size) as usize))
            .unwrap_or(&[]);
        let b = decode_block(addr, bytes);
        self.instructions += u64::from(b.instructions);
        self.timing.block(addr, &b, Region::Other, flash_timing)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn code(halfwords: &[u16]) -> Vec<u8> {
        halfwords.iter().flat_map(|h| h.to_le_bytes()).collect()
    }

    /// Core cycles of `halfwords` at `addr` (zero wait states), as a block reached by
    /// falling through.
    fn cycles(halfwords: &[u16]) -> u32 {
        decode_block(0x2000_0000, &code(halfwords)).core_cycles
    }

    #[test]
    fn data_processing_is_one_cycle_each() {
        // movs r0,#1; adds r1,r0,#2; lsls r2,r1,#3; mul r3,r2 (16-bit MULS); cmp r3,#4
        assert_eq!(cycles(&[0x2001, 0x1C81, 0x00CA, 0x4353, 0x2B04]), 5);
        // mla r0,r1,r2,r3 (T1): 1 on the M4; umull r0,r1,r2,r3: 1
        assert_eq!(cycles(&[0xFB01, 0x3002, 0xFBA2, 0x0103]), 2);
    }

    #[test]
    fn loads_pipeline_and_stores_overlap() {
        // TRM: "LDR R0,[R1]; LDR R1,[R2]: normally three cycles total".
        assert_eq!(cycles(&[0x6808, 0x6811]), 3);
        // LDR R0,[R1,R2]; STR R1,[R3,R2]: three cycles.
        assert_eq!(cycles(&[0x5888, 0x5099]), 3);
        // LDR R0,[R1,R5]; LDR R1,[R2]; LDR R2,[R3,#4]: four cycles.
        assert_eq!(cycles(&[0x5948, 0x6811, 0x685A]), 4);
        // A load whose address is the previous load's result does not pipeline:
        // ldr r0,[r1]; ldr r2,[r0] = 2 + 2.
        assert_eq!(cycles(&[0x6808, 0x6802]), 4);
        // STR with an immediate offset: one cycle; adds r1,#4 then str r0,[r1]: the address
        // depends on the ALU result: 1 + 2.
        assert_eq!(cycles(&[0x6008]), 1);
        assert_eq!(cycles(&[0x3104, 0x6008]), 3);
    }

    #[test]
    fn multiple_transfers_cost_one_plus_n() {
        // push {r4-r7,lr}: 1 + 5; pop {r4-r7,pc}: 1 + 5 (+ P at the target)
        assert_eq!(cycles(&[0xB5F0]), 6);
        assert_eq!(cycles(&[0xBDF0]), 6);
        // ldmia.w r0, {r1-r4}: 1 + 4; ldrd r0,r1,[r2]: 3
        assert_eq!(cycles(&[0xE890, 0x001E]), 5);
        assert_eq!(cycles(&[0xE9D2, 0x0100]), 3);
    }

    #[test]
    fn divide_and_fp_costs() {
        // udiv r0,r1,r2: 12 (the TRM's 2-12, worst case); sdiv: 12
        assert_eq!(cycles(&[0xFBB1, 0xF0F2]), 12);
        assert_eq!(cycles(&[0xFB91, 0xF0F2]), 12);
        // vadd.f32 s0,s1,s2: 1; vmul.f32 s0,s1,s2: 1; vmla.f32 s0,s1,s2: 3; vdiv.f32: 14
        assert_eq!(cycles(&[0xEE30, 0x0A81]), 1);
        assert_eq!(cycles(&[0xEE20, 0x0A81]), 1);
        assert_eq!(cycles(&[0xEE00, 0x0A81]), 3);
        assert_eq!(cycles(&[0xEE80, 0x0A81]), 14);
        // vsqrt.f32 s0,s1: 14; vldr s0,[r0]: 2; vpush {s16-s19}: 1 + 4
        assert_eq!(cycles(&[0xEEB1, 0x0AE0]), 14);
        assert_eq!(cycles(&[0xED90, 0x0A00]), 2);
        assert_eq!(cycles(&[0xED2D, 0x8A04]), 5);
    }

    #[test]
    fn taken_branches_pay_the_refill() {
        // A loop "subs r0,#1; bne loop" at zero wait states: 1 + 1 + P(1) = 3 per taken
        // iteration (compendium/TRM: a taken branch is 2 cycles), 2 when it falls through.
        let b = decode_block(0x2000_0000, &code(&[0x3801, 0xD1FD]));
        let mut t = Timing::default();
        let f = FlashTiming::default();
        t.block(0x1FFF_0000, &b, Region::Other, f); // first entry (a branch)
        assert_eq!(t.block(0x2000_0000, &b, Region::Other, f), 3);
        assert_eq!(t.block(0x2000_0000, &b, Region::Other, f), 3);
        // Falling through into the next block: no refill.
        let next = decode_block(0x2000_0004, &code(&[0x2001]));
        assert_eq!(t.block(0x2000_0004, &next, Region::Other, f), 1);
        // A 32-bit target at an odd halfword: P = 2.
        let odd = decode_block(0x2000_0102, &code(&[0xFB01, 0x3002]));
        assert_eq!(t.block(0x2000_0102, &odd, Region::Other, f), 3);
    }

    #[test]
    fn flash_wait_states_without_prefetch_or_cache() {
        // Eight movs (two 64-bit lines) from flash at 4 wait states, PRFTEN = ICEN = 0:
        // each line read costs 4 wait states; a branch to the block pays P as well.
        let b = decode_block(0x0800_0100, &code(&[0x2001; 8]));
        let f = FlashTiming::from_acr(4);
        let mut t = Timing::default();
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 8 + 1 + 2 * 4);
        // Again: nothing cached, the same cost.
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 8 + 1 + 2 * 4);
    }

    #[test]
    fn the_instruction_cache_hides_wait_states_of_a_loop() {
        let b = decode_block(0x0800_0100, &code(&[0x2001; 8]));
        let f = FlashTiming::from_acr(4 | acr::ICEN);
        let mut t = Timing::default();
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 8 + 1 + 8);
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 8 + 1);
        // ICEN cleared: the wait states are back.
        let off = FlashTiming::from_acr(4);
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, off), 8 + 1 + 8);
    }

    #[test]
    fn prefetch_overlaps_sequential_lines() {
        // With PRFTEN the second line was being read while the first ran 4 cycles: it
        // stalls 4 + 1 - 4 = 1. The first line (a branch target) pays the full latency.
        let b = decode_block(0x0800_0100, &code(&[0x2001; 8]));
        let f = FlashTiming::from_acr(4 | acr::PRFTEN);
        let mut t = Timing::default();
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 8 + 1 + 4 + 1);
    }

    #[test]
    fn literal_loads_from_flash_go_through_the_data_cache() {
        // ldr r0,[pc,#0] at 0x0800_0100 loads 0x0800_0104.
        let b = decode_block(0x0800_0100, &code(&[0x4800, 0x2001, 0x2001, 0x2001]));
        assert_eq!(b.literals, vec![0x0800_0104]);
        let f = FlashTiming::from_acr(4 | acr::ICEN | acr::DCEN);
        let mut t = Timing::default();
        // 2 + 3 core, P, one line and one literal miss.
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 5 + 1 + 4 + 4);
        assert_eq!(t.block(0x0800_0100, &b, Region::Flash, f), 5 + 1);
    }

    #[test]
    fn ram_code_pays_no_wait_states() {
        let b = decode_block(0x2000_0100, &code(&[0x2001; 8]));
        let mut t = Timing::default();
        let f = FlashTiming::from_acr(4);
        assert_eq!(t.block(0x2000_0100, &b, Region::Other, f), 8 + 1);
    }

    #[test]
    fn exceptions_cost_the_trm_latencies() {
        let mut t = Timing::default();
        let f = FlashTiming::from_acr(4 | acr::ICEN);
        // Vector read misses the cache once.
        assert_eq!(t.entry(false, false, 0x0800_00A4, f), 12 + 4);
        assert_eq!(t.entry(false, false, 0x0800_00A4, f), 12);
        assert_eq!(t.entry(true, false, 0x0800_00A4, f), 6);
        assert_eq!(t.entry(false, true, 0x0800_00A4, f), 12 + 18);
        assert_eq!(t.exit(false), 10);
        // The handler's first block: its refill is in the entry's 12 cycles.
        let b = decode_block(0x2000_0000, &code(&[0x2001]));
        t.entry(false, false, 0x2000_0000, f);
        assert_eq!(t.block(0x2000_0000, &b, Region::Other, f), 1);
    }

    #[test]
    fn periph_costs_by_bus() {
        assert_eq!(periph_access_cycles(0x4001_2C10, false), 2); // TIM1 on APB2
        assert_eq!(periph_access_cycles(0x4001_2C10, true), 1);
        assert_eq!(periph_access_cycles(0x4800_0010, false), 1); // GPIOA on AHB2
        assert_eq!(periph_access_cycles(0x4800_0018, true), 0);
        assert_eq!(periph_access_cycles(0xE000_1004, false), 0); // DWT
    }
}
