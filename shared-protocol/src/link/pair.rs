//! Both endpoints joined by two impaired [`Channel`]s, stepped in virtual time: the
//! harness of the link tests and benchmark (hil-sim runs the application-level version).

use super::channel::{Channel, Impairments};
use super::config::LinkConfig;
use super::drive::DriveLink;
use super::frame::MAX_WIRE_FRAME;
use super::plc::PlcLink;
use crate::units::Micros;

/// The longest step [`LinkPair::step`] takes: the endpoints' timers are polled at least
/// this often, as the firmware does from its 1 ms tick (finer here).
pub const MAX_STEP_US: u64 = 250;

pub struct LinkPair {
    pub plc: PlcLink,
    pub drive: DriveLink,
    /// PLC TX -> drive RX.
    pub to_drive: Channel,
    /// Drive TX -> PLC RX.
    pub to_plc: Channel,
    pub now: Micros,
}

impl LinkPair {
    /// Both directions with the same impairments (independent random streams).
    pub fn new(cfg: LinkConfig, imp: Impairments, seed: u64) -> Self {
        LinkPair {
            plc: PlcLink::new(cfg),
            drive: DriveLink::new(cfg),
            to_drive: Channel::new(cfg.baud, imp, seed),
            to_plc: Channel::new(cfg.baud, imp, seed.wrapping_mul(31).wrapping_add(17)),
            now: Micros(0),
        }
    }

    /// Deliver what has arrived by `now` and let each side send if its UART is idle.
    pub fn service(&mut self) {
        let now = self.now;
        let mut buf = [0u8; 64];
        loop {
            let n = self.to_drive.receive(now, &mut buf);
            if n == 0 {
                break;
            }
            self.drive.receive(buf.get(..n).unwrap_or(&[]), now);
        }
        loop {
            let n = self.to_plc.receive(now, &mut buf);
            if n == 0 {
                break;
            }
            self.plc.receive(buf.get(..n).unwrap_or(&[]), now);
        }
        let mut out = [0u8; MAX_WIRE_FRAME];
        if self.to_drive.is_idle(now) {
            let n = self.plc.poll_transmit(now, &mut out);
            if n > 0 {
                self.to_drive.send(out.get(..n).unwrap_or(&[]), now);
            }
        } else {
            self.plc.tick(now);
        }
        if self.to_plc.is_idle(now) {
            let n = self.drive.poll_transmit(now, &mut out);
            if n > 0 {
                self.to_plc.send(out.get(..n).unwrap_or(&[]), now);
            }
        } else {
            self.drive.tick(now);
        }
    }

    /// Advance to the next moment something happens (a byte arrives, a UART becomes
    /// idle) or by [`MAX_STEP_US`], but not beyond `until`; then [`Self::service`].
    pub fn step(&mut self, until: Micros) {
        let mut next = self.now.0 + MAX_STEP_US;
        for t in [
            self.to_drive.next_arrival(),
            self.to_plc.next_arrival(),
            Some(self.to_drive.free_at()),
            Some(self.to_plc.free_at()),
        ]
        .into_iter()
        .flatten()
        {
            if t.0 > self.now.0 {
                next = next.min(t.0);
            }
        }
        self.now = Micros(next.min(until.0).max(self.now.0));
        self.service();
    }

    /// Step until `until` (inclusive), calling `each` after every step.
    pub fn run_until(&mut self, until: Micros, mut each: impl FnMut(&mut LinkPair)) {
        while self.now < until {
            self.step(until);
            each(self);
        }
    }
}
