//! The service bound to a UART the way the link is: [`OnApp`] makes the service, borrowed
//! together with the application for one call, a [`LinkEndpoint`], so that the board's
//! link pump task (`board_common::link::run_task`) moves its bytes, and [`after_scan`] is
//! the application task's share of the work. The board only moves bytes; what is decided
//! here:
//!
//! * **Who touches the EEPROM.** The reads a `ListSlots`, `ReadProgram` or `Run` of a slot
//!   wait for move one step per application pass, in the application task right after its
//!   scan ([`after_scan`]): the I2C bus is idle between scans and the application's own
//!   bus users (storage jobs, LCD) are in that task, so nothing else can be on the bus.
//!   The service task never touches the EEPROM: bytes arriving in a flood cannot turn
//!   into back-to-back page reads.
//! * **When the service task passes.** On received bytes, on its deadline, and when
//!   [`after_scan`] says so (a sample was taken, a request waits, a read step was made).
//!   While a request waits for EEPROM reads, the deadline is not "now": the task would
//!   otherwise pass again at once without yielding (embassy's timer completes a past
//!   deadline without a yield) and starve the application; the next pass comes with the
//!   next scan's [`after_scan`].
//! * **A busy transmitter.** The pump hands a short buffer while the line is busy: then
//!   only the port's timers run, so a request is never executed with nowhere to put its
//!   answer.

use shared_protocol::link::pump::{is_due, LinkEndpoint};
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::units::Micros;

use super::Service;
use crate::app::{PlcApp, Tick};
use crate::storage::Eeprom;

/// The service and the application, borrowed for one call of the pump.
pub struct OnApp<'a, E: Eeprom> {
    svc: &'a mut Service,
    app: &'a mut PlcApp<E>,
}

impl<'a, E: Eeprom> OnApp<'a, E> {
    pub fn new(svc: &'a mut Service, app: &'a mut PlcApp<E>) -> Self {
        OnApp { svc, app }
    }
}

impl<E: Eeprom> LinkEndpoint for OnApp<'_, E> {
    fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.svc.on_rx(bytes, now);
    }

    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        if out.len() < MAX_WIRE_FRAME {
            // The line is busy: timers only (an answer needs a whole frame's room).
            self.svc.port.tick(now);
            return 0;
        }
        self.svc.poll_tx(self.app, now, out)
    }

    fn poll_timeout(&self) -> Option<Micros> {
        if self.svc.reading() {
            // Paced by the scans: `after_scan` asks for the next pass.
            return self.svc.port.timeout();
        }
        // `Service::poll_timeout` gives `now` while something waits: any time not after
        // the present means now to the pump.
        self.svc.poll_timeout(Micros(0))
    }

    fn line_error(&mut self) {
        self.svc.on_line_error();
    }
}

/// The application task's part, after each [`PlcApp::tick_1ms`]: the tick's trend sample,
/// one step of the EEPROM reads a request waits for (the bus is idle between scans).
/// Returns whether the service task must pass now (a sample or an answer is ready, or a
/// request waits); the board then wakes it.
pub fn after_scan<E: Eeprom>(
    svc: &mut Service,
    app: &mut PlcApp<E>,
    tick: &Tick,
    now: Micros,
) -> bool {
    svc.after_tick(app, tick, now);
    svc.eeprom_step(app);
    is_due(svc.poll_timeout(now), now)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::{BuildInfo, RawIo};
    use crate::editor::Screen;
    use crate::storage::MemEeprom;
    use shared_protocol::link::pump::Pump;
    use shared_protocol::link::LinkConfig;
    use shared_protocol::program::assemble;
    use shared_protocol::service::{encode, Answer, Request, ServiceReader, SERVICE_VERSION};

    const BUILD: BuildInfo = BuildInfo {
        firmware: "0.1.0",
        git: "test",
        uid: [7; 12],
    };

    /// The board's two tasks around one PLC, with a host at the other end of the line.
    struct Board {
        app: PlcApp<MemEeprom>,
        svc: Service,
        pump: Pump,
        screen: Screen,
        now: Micros,
        reader: ServiceReader,
        /// Service task passes the application task asked for.
        kicks: u32,
    }

    impl Board {
        fn new() -> Board {
            let p = assemble("150 LD D00\n151 WR O00\n").unwrap();
            let image = crate::storage::image::program_image(
                &p,
                &crate::storage::image::ImageOptions {
                    slot: 1,
                    run_at_power_up: false,
                },
            )
            .unwrap();
            Board {
                app: PlcApp::new(
                    MemEeprom::from_image(&image),
                    LinkConfig::default(),
                    20,
                    4,
                    Micros(0),
                ),
                svc: Service::new(BUILD),
                pump: Pump::new(10_000),
                screen: Screen::new(20, 4),
                now: Micros(0),
                reader: ServiceReader::new(),
                kicks: 0,
            }
        }

        /// One service-task pass with `rx`; the answers the host decodes.
        fn pass(&mut self, rx: &[u8], room: usize) -> (Vec<(u8, Answer)>, Micros) {
            let mut ep = OnApp::new(&mut self.svc, &mut self.app);
            let p = self.pump.pass(&mut ep, rx, room, self.now);
            let mut got = Vec::new();
            for &b in self.pump.tx() {
                if let Some(Ok(a)) = self.reader.push::<Answer>(b) {
                    got.push(a);
                }
            }
            (got, p.wake_at)
        }

        /// One application pass (1 ms later); whether it asked for a service pass.
        fn scan(&mut self) -> bool {
            self.now = Micros(self.now.0 + 1000);
            let t = self
                .app
                .tick_1ms(self.now, RawIo::default(), &mut self.screen);
            let kick = after_scan(&mut self.svc, &mut self.app, &t, self.now);
            self.kicks += u32::from(kick);
            kick
        }
    }

    fn frame(id: u8, r: Request) -> Vec<u8> {
        let mut out = [0u8; MAX_WIRE_FRAME];
        let n = encode(id, r, &mut out).unwrap();
        out[..n].to_vec()
    }

    fn hello(b: &mut Board) {
        let (got, _) = b.pass(
            &frame(
                1,
                Request::Hello {
                    version: SERVICE_VERSION,
                },
            ),
            MAX_WIRE_FRAME,
        );
        assert_eq!(
            got,
            [(
                1,
                Answer::HelloReply {
                    version: SERVICE_VERSION
                }
            )]
        );
    }

    #[test]
    fn a_busy_line_never_swallows_an_answer() {
        let mut b = Board::new();
        hello(&mut b);
        let (got, wake) = b.pass(&frame(2, Request::GetStatus), 0);
        assert!(got.is_empty());
        assert_eq!(wake, b.now, "the request still waits: pass again at once");
        let (got, _) = b.pass(&[], MAX_WIRE_FRAME);
        assert!(
            matches!(got.as_slice(), [(2, Answer::Status(_))]),
            "{got:?}"
        );
    }

    #[test]
    fn eeprom_reads_are_paced_by_the_scans_not_by_the_service_task() {
        let mut b = Board::new();
        hello(&mut b);
        let (got, wake) = b.pass(&frame(2, Request::ListSlots), MAX_WIRE_FRAME);
        assert!(got.is_empty(), "the slot headers are read first: {got:?}");
        assert!(b.svc.reading());
        assert!(
            wake > b.now,
            "no pass at once while reads wait (it would never yield)"
        );
        // Passes of the service task alone (bytes arriving) make no progress...
        for _ in 0..50 {
            assert!(b.pass(&[], MAX_WIRE_FRAME).0.is_empty());
        }
        assert!(b.svc.reading());
        // ...the application's scans do, one step each, and ask for the pass that answers.
        let mut answer = None;
        for scan in 0..100 {
            if b.scan() {
                let (got, _) = b.pass(&[], MAX_WIRE_FRAME);
                if let Some(a) = got.into_iter().next() {
                    answer = Some((scan, a));
                    break;
                }
            }
        }
        let (scans, (id, a)) = answer.expect("ListSlots answered within 100 scans");
        assert_eq!(id, 2);
        assert!(matches!(a, Answer::Slots(_)), "{a:?}");
        assert!(scans >= 1, "at least one EEPROM step came first");
        assert!(!b.svc.reading());
    }

    #[test]
    fn an_idle_service_asks_for_no_pass_and_sleeps_until_the_client_is_forgotten() {
        let mut b = Board::new();
        for _ in 0..10 {
            assert!(!b.scan());
        }
        assert_eq!(b.kicks, 0);
        hello(&mut b);
        let t = b.now;
        assert!(!b.scan(), "nothing waits after the HelloReply");
        let ep = OnApp::new(&mut b.svc, &mut b.app);
        let deadline = ep.poll_timeout().unwrap();
        assert!(deadline.0 >= t.0 + 29_000_000, "{deadline:?}");
    }

    #[test]
    fn a_subscription_asks_for_a_pass_with_each_sample() {
        let mut b = Board::new();
        hello(&mut b);
        let sub = Request::Subscribe {
            period_ms: 10,
            q: heapless::Vec::new(),
        };
        let (got, _) = b.pass(&frame(2, sub), MAX_WIRE_FRAME);
        assert!(matches!(got.as_slice(), [(2, Answer::Subscribed { .. })]));
        let mut samples = 0;
        for _ in 0..100 {
            if b.scan() {
                let (got, _) = b.pass(&[], MAX_WIRE_FRAME);
                samples += got
                    .iter()
                    .filter(|(id, a)| *id == 0 && matches!(a, Answer::Sample(_)))
                    .count();
            }
        }
        assert!((9..=11).contains(&samples), "{samples} samples in 100 ms");
        assert_eq!(b.kicks as usize, samples, "one pass per sample, no more");
    }
}
