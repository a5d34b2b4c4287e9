//! The service UART as the simulation plays it: LPUART1 at the service baud, both
//! directions timed byte by byte by the link's [`Channel`] (no impairments: the ST-LINK's
//! USB bridge is not a noisy wire), the firmware's [`Service`] at the PLC's end.

use std::collections::VecDeque;

use firmware_plc::app::BuildInfo;
use firmware_plc::service::Service;
use shared_protocol::link::channel::{Channel, Impairments};
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::units::Micros;

use crate::mcu::PlcBoard;
use crate::sim::receive_all;

/// How often the service is stepped (the PLC's tick), ns.
pub const STEP_NS: u64 = 1_000_000;

/// One service UART with the PLC's endpoint.
pub struct ServiceLine {
    svc: Service,
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
        let mut svc = Service::new(build);
        svc.port().set_version(version);
        ServiceLine {
            svc,
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

    /// One step after the PLC's tick at `now`: the tick's sample and EEPROM step, the
    /// bytes that arrived at the PLC, at most one frame out when its transmitter is free.
    /// Returns the bytes that arrived at the host by `now`.
    pub fn step(&mut self, plc: &mut PlcBoard, now: Micros) -> Vec<u8> {
        if let Some(tick) = plc.take_tick() {
            self.svc.after_tick(plc.app(), &tick, now);
        }
        self.svc.eeprom_step(plc.app_mut());
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
        if !rx.is_empty() {
            self.svc.on_rx(&rx, now);
        }
        if self.to_host.is_idle(now) {
            let mut out = [0u8; MAX_WIRE_FRAME];
            let n = self.svc.poll_tx(plc.app_mut(), now, &mut out);
            if let Some(frame) = out.get(..n).filter(|f| !f.is_empty()) {
                self.to_host.send(frame, now);
                self.plc_bytes += n as u64;
            }
        }
        receive_all(&mut self.to_host, now)
    }

    /// The endpoint (figures, version).
    pub fn service(&mut self) -> &mut Service {
        &mut self.svc
    }
}
