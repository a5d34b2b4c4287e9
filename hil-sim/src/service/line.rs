//! The service UART as the simulation plays it: LPUART1 at the service baud, both
//! directions timed byte by byte by the link's [`Channel`] (no impairments: the ST-LINK's
//! USB bridge is not a noisy wire). At the PLC's end the board's service task: the
//! PLC's service pump over `OnApp` ([`SimPlc::service_pass`]), passing when bytes
//! arrived, at its deadline, or when the application pass asked for it, as on the board.

use std::collections::VecDeque;

use firmware_plc::app::BuildInfo;
use firmware_plc::service::PortStats;
use shared_protocol::link::channel::{Channel, Impairments};
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::units::Micros;

use crate::mcu::SimPlc;
use crate::sim::receive_all;

/// How often the service is stepped (the PLC's tick), ns.
pub const STEP_NS: u64 = 1_000_000;

/// One service UART to the PLC.
pub struct ServiceLine {
    /// The identity the PLC's endpoint takes when the line is plugged in (first step).
    identity: Option<(BuildInfo, u16)>,
    /// The service task's next deadline (its pump's).
    wake: Option<Micros>,
    /// The PLC endpoint's receive figures at the last step.
    stats: PortStats,
    /// Host -> PLC.
    to_plc: Channel,
    /// PLC -> host.
    to_host: Channel,
    /// Host bytes not yet on the line (the line takes them at its own pace).
    host_queue: VecDeque<u8>,
    /// `[service] flood`: xorshift state of the garbage written at line rate.
    flood: Option<u64>,
    /// Bytes the host wrote, the flood wrote and the PLC sent, for the figures.
    pub host_bytes: u64,
    flood_bytes: u64,
    pub plc_bytes: u64,
}

/// The simulated PLC's identity: this build's version, `sim` as git hash, a unique ID
/// derived from the seed (service.md 9).
pub fn build_info(seed: u64) -> BuildInfo {
    let mut uid = [0u8; 12];
    uid[..8].copy_from_slice(&seed.to_le_bytes());
    uid[8..].copy_from_slice(b"HSIM");
    BuildInfo {
        firmware: env!("CARGO_PKG_VERSION"),
        git: "sim",
        uid,
    }
}

impl ServiceLine {
    /// A line at `baud`; `version`: the service version the PLC announces (tests give
    /// another); `flood`: the seed of garbage written into the PLC's receiver at line
    /// rate for the whole run.
    pub fn new(build: BuildInfo, baud: u32, version: u16, flood: Option<u64>) -> Self {
        ServiceLine {
            identity: Some((build, version)),
            wake: None,
            stats: PortStats::default(),
            to_plc: Channel::new(baud, Impairments::default(), 0),
            to_host: Channel::new(baud, Impairments::default(), 0),
            host_queue: VecDeque::new(),
            flood: flood.map(|s| s | 1),
            host_bytes: 0,
            flood_bytes: 0,
            plc_bytes: 0,
        }
    }

    /// Bytes the host wrote (they go on the line after what is queued).
    pub fn host_write(&mut self, bytes: &[u8]) {
        self.host_queue.extend(bytes);
        self.host_bytes += bytes.len() as u64;
    }

    fn flood_byte(&mut self) -> Option<u8> {
        let x = self.flood.as_mut()?;
        *x ^= *x >> 12;
        *x ^= *x << 25;
        *x ^= *x >> 27;
        let b = (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 56) as u8;
        self.flood_bytes += 1;
        Some(b)
    }

    /// Garbage bytes the flood has written so far.
    pub fn flooded_bytes(&self) -> u64 {
        self.flood_bytes
    }

    /// One step after the PLC's tick at `now`: the bytes that arrived at the PLC, and a
    /// pass of its service task when they did, at its deadline or when the application
    /// pass asked for one (a frame out when its transmitter is free). Returns the bytes
    /// that arrived at the host by `now`.
    pub fn step(&mut self, plc: &mut SimPlc, now: Micros) -> Vec<u8> {
        if let Some((build, version)) = self.identity.take() {
            plc.set_service_identity(build, version);
        }
        // Keep the host's line busy until the next step: host bytes first, else flood.
        let horizon = Micros(now.0 + STEP_NS / 1000);
        while self.to_plc.free_at() < horizon {
            let b = match self.host_queue.pop_front() {
                Some(b) => b,
                None => match self.flood_byte() {
                    Some(b) => b,
                    None => break,
                },
            };
            self.to_plc.send(&[b], now);
        }
        let rx = receive_all(&mut self.to_plc, now);
        let kicked = plc.take_service_due();
        if !rx.is_empty() || kicked || self.wake.is_some_and(|w| w <= now) {
            let room = if self.to_host.is_idle(now) {
                MAX_WIRE_FRAME
            } else {
                0
            };
            let pass = plc.service_pass(&rx, room, now);
            let tx = plc.service_tx();
            if !tx.is_empty() {
                self.to_host.send(tx, now);
                self.plc_bytes += tx.len() as u64;
            }
            // A frame due while the line is busy goes when the line is free.
            self.wake = Some(if pass.wake_at <= now && !self.to_host.is_idle(now) {
                self.to_host.free_at()
            } else {
                pass.wake_at
            });
        }
        self.stats = plc.service().port().stats();
        receive_all(&mut self.to_host, now)
    }

    /// The PLC endpoint's receive figures at the last step.
    pub fn port_stats(&self) -> PortStats {
        self.stats
    }
}
