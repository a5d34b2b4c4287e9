//! The service test rig: the PLC application (no drive: the link stays down) with a
//! service client on its port, stepped as a board does. Shared by the service tests.

#![allow(dead_code, unused_imports)]

pub use crate::app::{BuildInfo, PlcApp, RawIo, RunState};
pub use crate::editor::{Key, Screen};
pub use crate::service::Service;
pub use crate::storage::{MemEeprom, Storage};
pub use shared_protocol::link::frame::CRC as CRC32C;
pub use shared_protocol::link::{LinkConfig, MAX_WIRE_FRAME};
pub use shared_protocol::program::payload::for_each_payload_byte;
pub use shared_protocol::program::{assemble, Program};
pub use shared_protocol::service::{
    encode, Answer, LinkView, PlcState, RefuseReason, Request, Sample, ServiceReader, SlotState,
    CHUNK_BYTES, EVENT_LOG_CLEARED, LOG_FROM_NEWEST, REMOTE_TIMEOUT_MS, SERVICE_VERSION,
};
pub use shared_protocol::units::Micros;

pub const MOTOR: &str = include_str!("../../../shared-protocol/programs/motor.plc");
pub const SMALL: &str = "150 LD D00\n151 WR O00\n";

pub const BUILD: BuildInfo = BuildInfo {
    firmware: "0.1.0",
    git: "abcdef0",
    uid: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12],
};

/// The PLC (no drive: the link stays down) with a service client on its port.
pub struct Rig {
    pub plc: PlcApp<MemEeprom>,
    pub svc: Service,
    pub screen: Screen,
    pub now: Micros,
    pub id: u8,
    pub reader: ServiceReader,
    pub samples: Vec<Sample>,
    /// Poll the transmitter every tick (false: a busy UART, samples pile up).
    pub poll: bool,
}

impl Rig {
    pub fn with_eeprom(e: MemEeprom) -> Rig {
        Rig {
            plc: PlcApp::new(e, LinkConfig::default(), 20, 4, Micros(0)),
            svc: Service::new(BUILD),
            screen: Screen::new(20, 4),
            now: Micros(0),
            id: 0,
            reader: ServiceReader::new(),
            samples: Vec::new(),
            poll: true,
        }
    }

    pub fn new() -> Rig {
        Rig::with_eeprom(MemEeprom::new())
    }

    /// One board pass: the application's tick, the sample, the EEPROM step, the poll.
    pub fn tick(&mut self) -> Vec<(u8, Answer)> {
        self.now = Micros(self.now.0 + 1000);
        let now = self.now;
        let t = self.plc.tick_1ms(now, RawIo::default(), &mut self.screen);
        self.svc.after_tick(&self.plc, &t, now);
        self.svc.eeprom_step(&mut self.plc);
        let mut got = Vec::new();
        if !self.poll {
            return got;
        }
        let mut out = [0u8; MAX_WIRE_FRAME];
        let n = self.svc.poll_tx(&mut self.plc, now, &mut out);
        for &b in &out[..n] {
            match self.reader.push::<Answer>(b) {
                Some(Ok((0, Answer::Sample(s)))) => self.samples.push(s),
                Some(Ok(a)) => got.push(a),
                Some(Err(e)) => panic!("bad frame from the PLC: {e:?}"),
                None => {}
            }
        }
        got
    }

    pub fn run_ms(&mut self, ms: u64) -> Vec<(u8, Answer)> {
        (0..ms).flat_map(|_| self.tick()).collect()
    }

    pub fn send(&mut self, id: u8, req: &Request) {
        let mut out = [0u8; MAX_WIRE_FRAME];
        let n = encode(id, req.clone(), &mut out).unwrap();
        self.svc.on_rx(&out[..n], self.now);
    }

    /// Sends with `id` and returns the one answer, which must come within 100 ms.
    pub fn ask_id(&mut self, id: u8, req: Request) -> Answer {
        self.send(id, &req);
        for _ in 0..100 {
            let got = self.tick();
            if let Some((i, a)) = got.into_iter().next() {
                assert_eq!(i, id, "{req:?}");
                return a;
            }
        }
        panic!("no answer to {req:?} within 100 ms");
    }

    pub fn ask(&mut self, req: Request) -> Answer {
        self.id = self.id.wrapping_add(1).max(1);
        self.ask_id(self.id, req)
    }

    pub fn hello(&mut self) {
        assert_eq!(
            self.ask(Request::Hello {
                version: SERVICE_VERSION
            }),
            Answer::HelloReply {
                version: SERVICE_VERSION
            }
        );
    }

    pub fn keys(&mut self, keys: &[Key]) {
        for &k in keys {
            self.plc.key(k, self.now);
        }
    }
}

/// The `WriteBegin` that announces `bytes` for `slot`.
pub fn write_begin(slot: u8, bytes: &[u8]) -> Request {
    Request::WriteBegin {
        slot,
        len: bytes.len() as u16,
        crc: CRC32C.checksum(bytes),
    }
}

pub fn payload(p: &Program) -> Vec<u8> {
    let mut v = Vec::new();
    for_each_payload_byte(p, |b| v.push(b));
    v
}

/// Reads a whole program over the port, chunk by chunk.
pub fn pull(rig: &mut Rig, slot: u8) -> (Vec<u8>, u32, u32) {
    let mut data = Vec::new();
    let mut offset = 0u16;
    loop {
        let Answer::ProgramChunk(c) = rig.ask(Request::ReadProgram { slot, offset }) else {
            panic!("chunk");
        };
        assert_eq!((c.slot, c.offset), (slot, offset));
        data.extend_from_slice(&c.data);
        offset += c.data.len() as u16;
        if usize::from(offset) >= usize::from(c.len) {
            assert_eq!(data.len(), usize::from(c.len));
            return (data, c.crc, c.generation);
        }
    }
}

impl Rig {
    /// Sends and returns the one answer, which must come within 5 s (a request that
    /// writes the EEPROM: service.md 2).
    pub fn ask_long(&mut self, req: Request) -> Answer {
        self.id = self.id.wrapping_add(1).max(1);
        let id = self.id;
        self.send(id, &req);
        for _ in 0..5000 {
            if let Some((i, a)) = self.tick().into_iter().next() {
                assert_eq!(i, id, "{req:?}");
                return a;
            }
        }
        panic!("no answer to {req:?} within 5 s");
    }

    /// `Hello`, then remote service on (keys `*` `7`).
    pub fn hello_remote(&mut self) {
        self.hello();
        self.keys(&[Key::Star, Key::Digit(7)]);
    }

    /// Writes `bytes` into `slot` as `plcctl push` does: the commit's answer, or the
    /// first refusal on the way.
    pub fn push(&mut self, slot: u8, bytes: &[u8]) -> Answer {
        match self.ask_long(write_begin(slot, bytes)) {
            Answer::Done => {}
            other => return other,
        }
        for (k, chunk) in bytes.chunks(CHUNK_BYTES).enumerate() {
            let req = Request::WriteChunk {
                offset: (k * CHUNK_BYTES) as u16,
                data: chunk.iter().copied().collect(),
            };
            match self.ask_long(req) {
                Answer::Done => {}
                other => return other,
            }
        }
        self.ask_long(Request::WriteCommit)
    }
}
