//! The drive MCU on the host: [`DriveCore`] and the link endpoint [`DriveLink`], joined as
//! the firmware joins them.

use firmware_drive::link::{DriveEvent as LinkEvent, DriveLink};
use firmware_drive::{
    AdcSample, DriveCommand, DriveConfig, DriveCore, DriveEvent, DriveState, DriveStatus,
    FaultCode, HwBreak, PwmCommand, PwmTiming, ResetCause,
};
use shared_protocol::link::message::{DriveState as WireState, DriveStatus as WireStatus};
use shared_protocol::link::LinkConfig;
use shared_protocol::units::Micros;

use super::DriveMcu;

/// The drive board.
pub struct DriveBoard {
    core: DriveCore,
    link: DriveLink,
    /// A fault to report that did not fit the link's queue yet.
    unreported: Option<u8>,
}

impl DriveBoard {
    pub fn new(link_cfg: LinkConfig) -> Self {
        DriveBoard {
            core: DriveCore::new(DriveConfig::default(), ResetCause::PowerOn),
            link: DriveLink::new(link_cfg),
            unreported: None,
        }
    }

    pub fn core(&self) -> &DriveCore {
        &self.core
    }

    pub fn link(&self) -> &DriveLink {
        &self.link
    }

    fn drain_link(&mut self, now: Micros) {
        while let Some(e) = self.link.poll_event() {
            // A refused command (e.g. RUN while faulted) is the PLC's to notice from the
            // status; the core has already said no.
            let _ = match e {
                LinkEvent::Connected | LinkEvent::VersionMismatch { .. } => Ok(()),
                LinkEvent::LinkLost => {
                    if self.core.state() == DriveState::Run {
                        self.core.trip(FaultCode::Link);
                    }
                    Ok(())
                }
                LinkEvent::QWrite { addr, value } => {
                    self.core.command(DriveCommand::SetQ { addr, value })
                }
                LinkEvent::Run => self.core.command(DriveCommand::Run),
                LinkEvent::Stop => self.core.command(DriveCommand::Stop),
                LinkEvent::Direction { reverse } => {
                    self.core.command(DriveCommand::Direction { reverse })
                }
                LinkEvent::AckFault => self.core.command(DriveCommand::Ack),
                LinkEvent::ProgramAccepted => {
                    if let Some(p) = self.link.take_program() {
                        // The link verified it already; the core verifies again.
                        let _ = self.core.load_program(&p);
                    }
                    Ok(())
                }
                LinkEvent::ProgramRejected { .. } => {
                    self.core.trip(FaultCode::Prog);
                    Ok(())
                }
            };
        }
        let _ = now;
    }

    fn publish_status(&mut self) {
        let s = self.core.status();
        self.link.set_status(WireStatus {
            state: match s.state {
                DriveState::Boot => WireState::Boot,
                DriveState::Idle => WireState::Idle,
                DriveState::Run => WireState::Run,
                DriveState::Fault => WireState::Fault,
            },
            fault: s.fault.map_or(0, |f| f.code()),
            freq_dhz: s.f_applied.0,
            reverse: s.reverse,
            udc_dv: s.u_dc.0,
            imax_ca: s.i_peak.0,
            com: s.com,
        });
    }
}

impl DriveMcu for DriveBoard {
    fn pwm_isr(&mut self, adc: &AdcSample) -> PwmCommand {
        self.core.pwm_period(adc)
    }

    fn tick_1ms(&mut self, now: Micros) {
        self.link.tick(now);
        self.drain_link(now);
        let mut faults: Vec<u8> = Vec::new();
        self.core.tick_1ms(&mut |e| {
            if let DriveEvent::Fault(f) = e {
                faults.push(f.code());
            }
        });
        let ms = (now.0 / 1000) as u32;
        if let Some(code) = self.unreported {
            if self.link.report_fault(code, ms) {
                self.unreported = None;
            }
        }
        for code in faults {
            if !self.link.report_fault(code, ms) {
                self.unreported = Some(code);
            }
        }
        self.publish_status();
    }

    fn break_input(&mut self, cause: HwBreak, active: bool) {
        if active {
            self.core.hardware_break(cause);
        } else {
            self.core.hardware_break_released(cause);
        }
    }

    fn uart_rx(&mut self, bytes: &[u8], now: Micros) {
        self.link.receive(bytes, now);
        self.drain_link(now);
    }

    fn uart_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let n = self.link.poll_transmit(now, out);
        self.drain_link(now);
        n
    }

    fn pwm_timing(&self) -> PwmTiming {
        self.core.pwm_timing()
    }

    fn timer_clock_hz(&self) -> u32 {
        self.core.config().timer_clock_hz
    }

    fn status(&self) -> DriveStatus {
        self.core.status()
    }
}
