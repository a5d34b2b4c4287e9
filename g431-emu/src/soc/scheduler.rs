//! Time: the earliest event of any model, bringing every model to a cycle in time order,
//! the cycle cost of the blocks the CPU runs, and the fast-forward of polling loops.

use super::analog::AnalogAdapter;
use super::{Diagnostic, Soc, RAM_BASE};
use crate::names;
use crate::periph::adc::Adc12;
use crate::periph::flash::Flash;
use crate::time::{Cycles, CYCLES_PER_US};

/// A free-running counter read by a polling loop does not break its "nothing changes"
/// streak, but caps how far the clock may jump (the loop may be waiting for a time).
pub(super) const COUNTER_POLL_JUMP: Cycles = 10 * CYCLES_PER_US;
/// Identical reads of one register, by the same block, in a row before it counts as a
/// polling loop. High enough that a bounded loop over pins or columns (a keypad scan reads
/// one IDR four times) is never taken for a poll: fast-forwarding it would stretch its time.
pub(super) const POLL_STREAK: u32 = 64;

/// Tracks a possible polling loop: identical reads of one register.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Poll {
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

impl Soc {
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

    /// Brings slot `k` to `t`; the ADC gets the board's analog values through an adapter.
    pub(super) fn advance_slot(&mut self, k: usize, t: Cycles) {
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

    /// A free-running counter register (reading it is a clock read, not a state poll).
    pub(super) fn is_counter(&self, addr: u32) -> bool {
        matches!(addr, 0xE000_1004 | 0xE000_E018)
            || (self
                .find(addr)
                .and_then(|k| self.slots.get(k))
                .is_some_and(|s| s.name.starts_with("TIM") && addr - s.base == 0x24))
    }

    /// Polling-loop detection: the same register read repeatedly with the same value and
    /// nothing written in between. After [`POLL_STREAK`] such reads the clock jumps to the
    /// next event (the first moment anything can change), so that busy-waits cost no host
    /// time; a loop that also reads a free-running counter jumps at most
    /// [`COUNTER_POLL_JUMP`] at a time (it may be waiting for a time, not a flag).
    pub(super) fn track_poll(&mut self, addr: u32, value: u32) {
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
    pub(super) fn jump(&mut self, limit: Option<Cycles>) {
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
}

#[cfg(test)]
mod tests {
    use super::super::{BareBoard, FLASH_BASE};
    use super::*;

    fn soc() -> Soc {
        Soc::new(vec![0xFF; 16], Box::new(BareBoard))
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
