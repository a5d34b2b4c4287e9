//! One connection to the PLC's service port: request ids, resends and timeouts
//! (service.md 2), `Hello` and `Identify` first, trend samples set aside as they come.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use serialport::SerialPort;
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::service::{
    encode, Answer, Identity, Request, Sample, ServiceReader, ATTEMPTS, EEPROM_RETRY_MS, RETRY_MS,
    SERVICE_VERSION,
};

use crate::fail::{Fail, Result};

/// How long one read of the port may block.
const READ_SLICE: Duration = Duration::from_millis(10);

/// A connected PLC.
pub struct Client {
    port: Box<dyn SerialPort>,
    reader: ServiceReader,
    last_id: u8,
    /// Samples received and not yet taken (id 0).
    samples: VecDeque<Sample>,
    pub identity: Identity,
    /// When `Identify` was answered (the host's clock for the PLC's uptime).
    pub identified_at: chrono::DateTime<chrono::Utc>,
    /// When this PLC's power-ups began, as recorded at connections.
    pub power_ups: crate::clock::PowerUps,
}

/// Opens `path` at `baud` (8N1, raw), exit 2 when it cannot be opened.
fn open(path: &str, baud: u32) -> Result<Box<dyn SerialPort>> {
    let port = serialport::new(path, baud)
        .timeout(READ_SLICE)
        .open()
        .map_err(|e| Fail::NoDevice(format!("cannot open {path}: {e}")))?;
    // Whatever waited on the line belongs to nobody.
    let _ = port.clear(serialport::ClearBuffer::Input);
    Ok(port)
}

impl Client {
    /// Opens the port and says `Hello` and `Identify` (every command starts so).
    pub fn connect(path: &str, baud: u32) -> Result<Client> {
        let port = open(path, baud)?;
        let mut c = Client {
            port,
            reader: ServiceReader::new(),
            last_id: 0,
            samples: VecDeque::new(),
            identity: Identity {
                firmware: heapless::String::new(),
                git: heapless::String::new(),
                uid: [0; 12],
                power_ups: 0,
                uptime_ms: 0,
            },
            identified_at: chrono::Utc::now(),
            power_ups: crate::clock::PowerUps::default(),
        };
        match c.request(Request::Hello {
            version: SERVICE_VERSION,
        })? {
            Answer::HelloReply { version } if version == SERVICE_VERSION => {}
            Answer::HelloReply { version } => {
                return Err(Fail::Version {
                    host: SERVICE_VERSION,
                    plc: version,
                })
            }
            other => return Err(unexpected("Hello", &other)),
        }
        match c.request(Request::Identify)? {
            Answer::Identity(id) => {
                c.identified_at = chrono::Utc::now();
                c.power_ups = crate::clock::PowerUps::load(&id.uid);
                let start = crate::clock::power_up_start_ms(
                    c.identified_at.timestamp_millis(),
                    id.uptime_ms,
                );
                if let Some(start) = start {
                    c.power_ups.record(id.power_ups as u16, start);
                }
                c.identity = id;
            }
            other => return Err(unexpected("Identify", &other)),
        }
        Ok(c)
    }

    fn next_id(&mut self) -> u8 {
        self.last_id = self.last_id.wrapping_add(1).max(1);
        self.last_id
    }

    /// Sends `req` and returns its answer: resent with the same id after 300 ms (5 s for
    /// EEPROM writes; both times [`timeout_scale`]), 3 attempts, then exit 3. `Refused` is returned as an answer (the
    /// caller decides); [`Client::ask`] turns it into exit 5.
    pub fn request(&mut self, req: Request) -> Result<Answer> {
        let id = self.next_id();
        let retry = Duration::from_millis(if req.long_answer() {
            EEPROM_RETRY_MS
        } else {
            RETRY_MS
        })
        .saturating_mul(timeout_scale());
        let mut frame = [0u8; MAX_WIRE_FRAME];
        let n = encode(id, &req, &mut frame)
            .map_err(|e| Fail::Usage(anyhow::anyhow!("cannot encode {req:?}: {e:?}")))?;
        let frame = frame.get(..n).unwrap_or(&[]);
        for _ in 0..ATTEMPTS {
            self.port
                .write_all(frame)
                .map_err(|e| Fail::NoDevice(format!("write: {e}")))?;
            let deadline = Instant::now() + retry;
            while Instant::now() < deadline {
                if let Some(a) = self.receive_for(id)? {
                    return Ok(a);
                }
            }
        }
        Err(Fail::Timeout(format!(
            "no valid answer to {} after {ATTEMPTS} attempts",
            request_name(&req)
        )))
    }

    /// [`Client::request`] with `Refused` as exit 5.
    pub fn ask(&mut self, req: Request) -> Result<Answer> {
        match self.request(req)? {
            Answer::Refused(r) => Err(Fail::Refused(r)),
            a => Ok(a),
        }
    }

    /// Reads what has arrived (one read of at most [`READ_SLICE`]); the answer with
    /// `id` if it came, samples kept.
    fn receive_for(&mut self, id: u8) -> Result<Option<Answer>> {
        let mut buf = [0u8; 256];
        let n = match self.port.read(&mut buf) {
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => 0,
            Err(e) if e.kind() == ErrorKind::Interrupted => 0,
            Err(e) => return Err(Fail::NoDevice(format!("read: {e}"))),
        };
        let mut found = None;
        for &b in buf.get(..n).unwrap_or(&[]) {
            match self.reader.push::<Answer>(b) {
                Some(Ok((0, Answer::Sample(s)))) => self.samples.push_back(s),
                Some(Ok((i, a))) if i == id && id != 0 => found = Some(a),
                // Another id (a late answer to an earlier attempt) or a damaged frame.
                _ => {}
            }
        }
        if n == 0 && found.is_none() {
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(found)
    }

    /// Waits up to `wait` for samples; returns those received.
    pub fn samples(&mut self, wait: Duration) -> Result<Vec<Sample>> {
        let deadline = Instant::now() + wait;
        while self.samples.is_empty() && Instant::now() < deadline {
            self.receive_for(0)?;
        }
        Ok(self.samples.drain(..).collect())
    }
}

fn request_name(r: &Request) -> String {
    let s = format!("{r:?}");
    s.split([' ', '{', '('])
        .next()
        .unwrap_or("request")
        .to_string()
}

/// An answer of the wrong kind (a PLC that does not follow the protocol).
pub fn unexpected(what: &str, a: &Answer) -> Fail {
    Fail::Usage(anyhow::anyhow!("unexpected answer to {what}: {a:?}"))
}

/// `PLCCTL_TIMEOUT_SCALE` (a whole number, 1 to 100; default 1): multiplies the retry times,
/// for a PLC that runs slower than real time (the emulator's tests of the real image,
/// `hil-sim/tests/emu/service.rs`). Anything else is ignored.
pub fn timeout_scale() -> u32 {
    std::env::var("PLCCTL_TIMEOUT_SCALE")
        .ok()
        .and_then(|v| v.trim().parse::<u32>().ok())
        .filter(|k| (1..=100).contains(k))
        .unwrap_or(1)
}
