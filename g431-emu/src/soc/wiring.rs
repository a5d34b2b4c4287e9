//! The wiring between models, and between models and the board: TIM1's events to the ADC,
//! the comparators' blanking and the power stage; comparator edges to TIM1's break and the
//! EXTI; DMA requests served as bus accesses; the U(S)ARTs' kernel clocks; I2C buses and
//! their pins; GPIO levels to and from the board.

use super::analog::{AnalogAdapter, AnalogSnapshot};
use super::{Board, Diagnostic, PinId, Soc, USARTS, VREFINT_VOLTS};
use crate::names;
use crate::periph::adc::{Adc12, TriggerSignal};
use crate::periph::analog_errors::AnalogErrors;
use crate::periph::comp::{BlankingSource, CompBank, InvertingInput};
use crate::periph::dac::{Dac, DacId};
use crate::periph::dma::{Dma, Transfer};
use crate::periph::dmamux::Dmamux;
use crate::periph::gpio::{Drive, GpioPort, PinReader};
use crate::periph::i2c::{I2c, SharedDevice};
use crate::periph::opamp::OpampBank;
use crate::periph::tim_adv::{TimAdv, TimEvent};
use crate::periph::usart::{Usart, UsartInstance};
use crate::periph::{Peripheral, Signal};
use crate::time::Cycles;

impl Soc {
    /// The output signals slot `k` raised since the last call.
    fn take_signals(&mut self, k: usize) -> Vec<Signal> {
        let mut out = Vec::new();
        if let Some(s) = self.slots.get_mut(k) {
            s.model.take_signals(&mut out);
        }
        out
    }

    /// Cross-peripheral effects after slot `k` changed at `t` (overridden per model by the
    /// wiring in `crate::wiring` once all models exist).
    pub(super) fn after_event(&mut self, k: usize, t: Cycles) {
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
        if k == self.rcc || self.pwr_slot() == Some(k) {
            self.sync_backup_domain(t);
        }
    }

    /// Slot `k` can raise or drop a DMA request, or is a DMA controller.
    pub(super) fn dma_related(&self, k: usize) -> bool {
        let w = &self.wired;
        w.usart.contains(&k)
            || w.dma.contains(&k)
            || w.dmamux == k
            || w.i2c.contains(&k)
            || w.adc12 == k
    }

    /// Performs every DMA transfer the request lines call for now, as register accesses
    /// (so a DMA read of a data register has the CPU read's side effects).
    pub(super) fn service_dma(&mut self) {
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

    /// Gives each U(S)ART the kernel clock RCC selects for it now (after every RCC write:
    /// CCIPR, the APB prescalers, a peripheral reset).
    pub(super) fn sync_usart_clocks(&mut self) {
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
    pub(super) fn i2c_gpio(&mut self) {
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

    /// What the analog adapter needs from other models (taken before the ADC is borrowed).
    pub(super) fn analog_snapshot(&self) -> AnalogSnapshot {
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
    pub(super) fn tim1_events(&mut self, t: Cycles) {
        let k = self.wired.tim1;
        let events = self.take_signals(k);
        if events.is_empty() {
            return;
        }
        for signal in &events {
            let Signal::Timer(ev) = signal else {
                continue;
            };
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
    pub(super) fn sample_comparators(&mut self, t: Cycles) {
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
    pub(super) fn comp_edges(&mut self) {
        let c = self.wired.comp;
        let edges = self.take_signals(c);
        if edges.is_empty() {
            return;
        }
        let t1 = self.wired.tim1;
        for signal in &edges {
            let Signal::Comparator(e) = signal else {
                continue;
            };
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

    pub(super) fn read_idr(&mut self, port: u8, k: usize) -> Option<u32> {
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
    pub(super) fn af_output_level(&mut self, port: u8, n: u8, af: u8) -> Option<bool> {
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

    pub(super) fn gpio_changed(&mut self, port: usize) {
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

#[cfg(test)]
mod tests {
    use super::super::BareBoard;
    use super::*;

    fn soc() -> Soc {
        Soc::new(vec![0xFF; 16], Box::new(BareBoard))
    }

    /// 1 V on PA1 (COMP1's INP) from `from` to `to` (cycles), 0 V otherwise.
    struct Pulse {
        from: Cycles,
        to: Cycles,
    }

    impl PinReader for Pulse {}

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
}
