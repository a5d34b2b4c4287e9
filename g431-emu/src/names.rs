//! Names from the STM32 metadata (`stm32-metapac`, the same data embassy-stm32 is generated
//! from): which peripheral and register an address is, interrupt numbers, DMAMUX request
//! IDs. The G431CB (drive) and G431RB (PLC) are the same die; the RB's tables serve both.

use stm32_metapac::metadata::{ir, Metadata, Peripheral, METADATA};

/// The chip's metadata.
pub fn chip() -> &'static Metadata {
    &METADATA
}

/// The peripheral by name (`"TIM1"`).
pub fn peripheral(name: &str) -> Option<&'static Peripheral> {
    METADATA.peripherals.iter().find(|p| p.name == name)
}

/// Base address of a peripheral (`"USART2"` → 0x4000_4400).
pub fn base(name: &str) -> Option<u32> {
    peripheral(name).and_then(|p| u32::try_from(p.address).ok())
}

/// NVIC line of an interrupt (`"TIM1_UP_TIM16"` → 25).
pub fn irq(name: &str) -> Option<u16> {
    METADATA
        .interrupts
        .iter()
        .find(|i| i.name == name)
        .and_then(|i| u16::try_from(i.number).ok())
}

/// The interrupt's name, for reports.
pub fn irq_name(number: u16) -> Option<&'static str> {
    METADATA
        .interrupts
        .iter()
        .find(|i| i.number == u32::from(number))
        .map(|i| i.name)
}

/// DMAMUX request ID of a peripheral's DMA signal (`("USART1", "RX")` → 24).
pub fn dma_request(peripheral_name: &str, signal: &str) -> Option<u8> {
    peripheral(peripheral_name)?
        .dma_channels
        .iter()
        .find(|c| c.signal == signal)
        .and_then(|c| c.request)
        .and_then(|r| u8::try_from(r).ok())
}

/// The block named `name`: the metadata spells a peripheral's block `TIM_ADV` and the IR
/// spells it `TimAdv`.
fn find_block<'a>(ir: &'a ir::IR, name: &str) -> Option<&'a ir::Block> {
    let key = |s: &str| {
        s.chars()
            .filter(|c| *c != '_')
            .map(|c| c.to_ascii_lowercase())
            .collect::<String>()
    };
    let want = key(name);
    ir.blocks.iter().find(|b| key(b.name) == want)
}

/// Extent in bytes of a register block (its last register's end).
fn block_len(ir: &ir::IR, block: &str) -> u32 {
    let Some(b) = find_block(ir, block) else {
        return 0;
    };
    b.items
        .iter()
        .map(|i| {
            let count = match &i.array {
                Some(ir::Array::Regular(a)) => a.len.saturating_sub(1) * a.stride,
                Some(ir::Array::Cursed(a)) => a.offsets.iter().copied().max().unwrap_or(0),
                None => 0,
            };
            let size = match &i.inner {
                ir::BlockItemInner::Register(r) => r.bit_size / 8,
                ir::BlockItemInner::Block(inner) => block_len(ir, inner.block),
            };
            i.byte_offset + count + size.max(1)
        })
        .max()
        .unwrap_or(0)
}

/// The register at `offset` in `block`, as `NAME` or `NAME[i]`, descending into sub-blocks.
fn register_name(ir: &ir::IR, block: &str, offset: u32) -> Option<String> {
    let b = find_block(ir, block)?;
    for item in b.items {
        let starts: Vec<(Option<u32>, u32)> = match &item.array {
            None => vec![(None, item.byte_offset)],
            Some(ir::Array::Regular(a)) => (0..a.len)
                .map(|k| (Some(k), item.byte_offset + k * a.stride))
                .collect(),
            Some(ir::Array::Cursed(a)) => a
                .offsets
                .iter()
                .enumerate()
                .map(|(k, o)| (Some(k as u32), item.byte_offset + o))
                .collect(),
        };
        for (index, start) in starts {
            let label = match index {
                Some(k) => format!("{}[{k}]", item.name.to_uppercase()),
                None => item.name.to_uppercase(),
            };
            match &item.inner {
                ir::BlockItemInner::Register(r) => {
                    if offset >= start && offset < start + (r.bit_size / 8).max(1) {
                        return Some(label);
                    }
                }
                ir::BlockItemInner::Block(inner) => {
                    let len = block_len(ir, inner.block);
                    if offset >= start && offset < start + len {
                        let rest = register_name(ir, inner.block, offset - start)?;
                        return Some(format!("{label}.{rest}"));
                    }
                }
            }
        }
    }
    None
}

/// Bytes of a peripheral's register block (from its last register), rounded up to a word.
pub fn block_bytes(name: &str) -> Option<u32> {
    let regs = peripheral(name)?.registers.as_ref()?;
    let len = block_len(regs.ir, regs.block);
    (len > 0).then_some(len.div_ceil(4) * 4)
}

/// The peripheral whose register block holds `addr`, and the offset in it.
pub fn locate(addr: u32) -> Option<(&'static Peripheral, u32)> {
    METADATA
        .peripherals
        .iter()
        .filter_map(|p| {
            let regs = p.registers.as_ref()?;
            let base = u32::try_from(p.address).ok()?;
            let len = block_len(regs.ir, regs.block);
            // Blocks near the top of the address space (the core's) must not overflow.
            let off = addr.checked_sub(base).filter(|off| *off < len)?;
            Some((p, off))
        })
        // Overlapping blocks (COMP1..4 live inside SYSCFG's page): the nearest base wins.
        .min_by_key(|(_, off)| *off)
}

/// `"RCC.CSR"`, `"TIM1.CCR[2]"`, or `"0x40021058 (RCC+0x58)"` when the metadata has no
/// register there, or `"0x60000000"` outside every peripheral.
pub fn describe(addr: u32) -> String {
    match locate(addr) {
        Some((p, off)) => {
            let reg = p
                .registers
                .as_ref()
                .and_then(|r| register_name(r.ir, r.block, off & !3));
            match reg {
                Some(r) => format!("{}.{}", p.name, r),
                None => format!("{addr:#010x} ({}+{off:#x})", p.name),
            }
        }
        None => format!("{addr:#010x}"),
    }
}

/// Byte offset of register `reg` (`"APB2ENR"`) and bit of field `field` (`"TIM1EN"`) in the
/// RCC, from the metadata's register descriptions.
fn rcc_bit(reg: &str, field: &str) -> Option<(u32, u32)> {
    let rcc = peripheral("RCC")?.registers.as_ref()?;
    let block = find_block(rcc.ir, rcc.block)?;
    let item = block
        .items
        .iter()
        .find(|i| i.name.eq_ignore_ascii_case(reg))?;
    let ir::BlockItemInner::Register(r) = &item.inner else {
        return None;
    };
    let fs_name = r.fieldset?;
    let fs = rcc.ir.fieldsets.iter().find(|f| f.name == fs_name)?;
    let f = fs
        .fields
        .iter()
        .find(|f| f.name.eq_ignore_ascii_case(field))?;
    match &f.bit_offset {
        ir::BitOffset::Regular(o) => Some((item.byte_offset, o.offset)),
        ir::BitOffset::Cursed(_) => None,
    }
}

/// Where a peripheral's clock enable bit is: (RCC register offset, bit).
pub fn rcc_enable(peripheral_name: &str) -> Option<(u32, u32)> {
    let e = peripheral(peripheral_name)?.rcc.as_ref()?.enable.as_ref()?;
    rcc_bit(e.register, e.field)
}

/// Where a peripheral's reset bit is: (RCC register offset, bit).
pub fn rcc_reset(peripheral_name: &str) -> Option<(u32, u32)> {
    let e = peripheral(peripheral_name)?.rcc.as_ref()?.reset.as_ref()?;
    rcc_bit(e.register, e.field)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registers_are_named_from_the_metadata() {
        assert_eq!(describe(0x4002_1094), "RCC.CSR");
        assert_eq!(describe(0x4001_2c10), "TIM1.SR");
        assert_eq!(describe(0x4001_2c3c), "TIM1.CCR[2]");
        assert_eq!(describe(0x4000_4428), "USART2.TDR");
        assert_eq!(describe(0x4800_0414), "GPIOB.ODR");
    }

    #[test]
    fn interrupts_and_requests() {
        assert_eq!(irq("TIM1_UP_TIM16"), Some(25));
        assert_eq!(irq("TIM1_BRK_TIM15"), Some(24));
        assert_eq!(irq("USART2"), Some(38));
        assert_eq!(irq("LPUART1"), Some(91));
        assert_eq!(irq_name(30), Some("TIM4"));
        assert_eq!(dma_request("USART1", "RX"), Some(24));
        assert_eq!(dma_request("USART2", "TX"), Some(27));
        assert_eq!(base("DAC3"), Some(0x5000_1000));
    }

    #[test]
    fn rcc_bits_come_from_the_metadata() {
        // RM0440 7.4: APB2ENR (0x60) bit 11 TIM1EN; APB1ENR1 (0x58) bit 2 TIM4EN.
        assert_eq!(rcc_enable("TIM1"), Some((0x60, 11)));
        assert_eq!(rcc_reset("TIM1"), Some((0x40, 11)));
        assert_eq!(rcc_enable("TIM4"), Some((0x58, 2)));
        assert_eq!(rcc_enable("USART2"), Some((0x58, 17)));
        assert_eq!(rcc_enable("GPIOB"), Some((0x4c, 1)));
    }

    #[test]
    fn unknown_addresses_are_still_described() {
        assert_eq!(describe(0x6000_0000), "0x60000000");
    }
}
