//! The registry of register models: each model mapped once at its address range with its
//! RCC enable and reset bits, looked up by address for the bus and by slot index for the
//! wiring; the cached next event, interrupt and DMA request lines of every slot.

use std::any::Any;

use super::Soc;
use crate::names;
use crate::periph::dbgmcu::Dbgmcu;
use crate::periph::exti::Exti;
use crate::periph::gpio::{Drive, GpioPort};
use crate::periph::iwdg::Iwdg;
use crate::periph::rcc::Rcc;
use crate::periph::syscfg::Syscfg;
use crate::periph::{DmaRequests, IrqLines, Peripheral};
use crate::time::Cycles;

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
    pub(super) next: Option<Cycles>,
    pub(super) irqs: IrqLines,
    pub(super) dma: DmaRequests,
}

pub(super) fn slot(name: &'static str, model: Box<dyn Model>) -> Slot {
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
pub(super) fn push_slot(slots: &mut Vec<Slot>, s: Slot) -> usize {
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

impl Soc {
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

    /// The slot mapped at `addr`: a linear search in insertion order (a few dozen slots,
    /// the busiest first), so the slot indices kept in `Soc` and `Slots` stay valid.
    pub(super) fn find(&self, addr: u32) -> Option<usize> {
        self.slots
            .iter()
            .position(|s| addr >= s.base && addr < s.base.saturating_add(s.len))
    }

    pub(super) fn clocked(&self, k: usize) -> bool {
        let Some(s) = self.slots.get(k) else {
            return false;
        };
        match s.enable {
            None => true,
            Some((off, bit)) => self.rcc().enabled(off, bit),
        }
    }

    pub(super) fn apply_rcc_resets(&mut self) {
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

    /// Slot index of the IWDG (for the CPU's reset logic).
    pub fn iwdg_slot(&self) -> usize {
        self.iwdg
    }

    /// Syscfg slot index.
    pub fn syscfg_slot(&self) -> usize {
        self.syscfg
    }
}

#[cfg(test)]
mod tests {
    use super::super::BareBoard;
    use super::*;
    use crate::periph::tim_gp::TimGp;

    fn soc() -> Soc {
        Soc::new(vec![0xFF; 16], Box::new(BareBoard))
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
        // The TIM4 the debug freeze acts on is the one the bus reaches.
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

    /// The address map `docs/models.md` gives ("Address map"), as the registry has it.
    fn address_map(s: &Soc) -> String {
        let mut out = String::from("| block | base | bytes |\n| --- | --- | --- |\n");
        for slot in &s.slots {
            out += &format!(
                "| {} | {:#010x} | {:#x} |\n",
                slot.name, slot.base, slot.len
            );
        }
        out
    }

    /// A model added to the SoC without its row in `docs/models.md` (the recipe's step
    /// "document it") fails here, with the table to paste.
    #[test]
    fn every_registered_model_is_listed_in_models_md() {
        let doc = include_str!("../../docs/models.md");
        let map = address_map(&soc());
        assert!(
            doc.contains(&map),
            "docs/models.md's \"Address map\" differs from the registry; it should read:\n{map}"
        );
    }
}
