//! The shield's policy over its two chips: what the board's 1 ms pass does with the
//! frames it exchanges. The board ([`SpiPort`]) only moves 16-bit frames with a chip
//! selected and drives OUT_EN; every decision is here.

use super::clt01;
use super::vni8200;
use super::FieldFault;

/// The shield's SPI bus and OUT_EN pin, as the board binds them.
pub trait SpiPort {
    /// One 16-bit frame with the CLT01-38SQ7 selected: what it shifted out.
    fn exchange_inputs(&mut self) -> u16;
    /// One 16-bit frame with the VNI8200XP selected: sends `command`, returns its answer.
    fn exchange_outputs(&mut self, command: u16) -> u16;
    /// Drives OUT_EN (high = the VNI8200XP's outputs follow its command).
    fn set_out_enable(&mut self, on: bool);
}

/// The VNI8200XP's FB_OK is low at its DC-DC's turn-on and rises after the feedback
/// reaches 90 % and a correct SPI exchange (`docs/field-io.md`). Its low level counts as
/// a supply fault only after this many good exchanges since power-up; no document gives
/// the DC-DC's start-up time, so this is the shortest that lets it rise (one good
/// exchange) with margin for the soft start, to be checked on the bench.
pub const FB_OK_GRACE_EXCHANGES: u8 = 10;

/// The shield's state: the latched trip and the one not yet reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Shield {
    latched: Option<FieldFault>,
    unreported: Option<FieldFault>,
    good_exchanges: u8,
}

impl Shield {
    /// At power-up: no trip, outputs off.
    pub const fn new() -> Self {
        Shield {
            latched: None,
            unreported: None,
            good_exchanges: 0,
        }
    }

    /// The latched trip, if any.
    pub fn latched(&self) -> Option<FieldFault> {
        self.latched
    }

    /// The trip not yet handed to the application (once per trip).
    pub fn take_trip(&mut self) -> Option<FieldFault> {
        self.unreported.take()
    }

    /// RUN was started again: the latch is cleared, the next exchanges check again.
    pub fn rearm(&mut self) {
        self.latched = None;
    }

    /// D00..D07 from the CLT01-38SQ7 (bit n = D0n). A frame that fails its check is read
    /// again once; a second failure trips. While a trip is latched (and on the read that
    /// trips) the inputs read 0: a failed frame never reaches the program.
    pub fn read_inputs<P: SpiPort>(&mut self, port: &mut P) -> u8 {
        if self.latched.is_some() {
            return 0;
        }
        let frame = match clt01::decode(port.exchange_inputs()) {
            Ok(f) => Ok(f),
            Err(_) => clt01::decode(port.exchange_inputs()),
        };
        let fault = match frame {
            Err(_) => FieldFault::FrameCheck,
            Ok(f) if f.under_voltage => FieldFault::SupplyLost,
            Ok(f) if f.over_temperature => FieldFault::InputOvertemp,
            Ok(f) => return f.inputs,
        };
        self.trip(fault, port);
        0
    }

    /// Writes the output image O00..O07 (bit n = On) to the VNI8200XP. OUT_EN goes low
    /// before the command when the image is all off or a trip is latched (then the command
    /// is all off, every pass), and high only
    /// after a command the chip confirmed. An answer that fails its check, or whose PC bit
    /// says the chip refused the previous command (the answer of an exchange is shifted
    /// out while its command comes in, so PC is about the exchange before), is exchanged
    /// again once; a second failure trips.
    pub fn write_outputs<P: SpiPort>(&mut self, image: u8, port: &mut P) {
        if self.latched.is_some() {
            port.set_out_enable(false);
            // The all-off command every pass, its answer unused: the chip's fault bits stay
            // latched until an exchange takes them, so without it the first answer after
            // RUN would report the heat of the trip, not of the pass before.
            let _ = port.exchange_outputs(vni8200::command(0));
            return;
        }
        if image == 0 {
            port.set_out_enable(false);
        }
        let command = vni8200::command(image);
        let answer = match exchange_checked(port, command) {
            Some(s) => s,
            None => match exchange_checked(port, command) {
                Some(s) => s,
                None => {
                    self.trip(FieldFault::FrameCheck, port);
                    return;
                }
            },
        };
        if answer.channel_overtemp != 0 || answer.temp_warning {
            self.trip(FieldFault::OutputOvertemp, port);
            return;
        }
        let fb_due = self.good_exchanges >= FB_OK_GRACE_EXCHANGES;
        if answer.power_fault || (fb_due && !answer.fb_ok) {
            self.trip(FieldFault::SupplyLost, port);
            return;
        }
        self.good_exchanges = self.good_exchanges.saturating_add(1);
        if image != 0 {
            port.set_out_enable(true);
        }
    }

    /// OUT_EN low first, then the all-off command (its answer is not needed); latched and
    /// reported once.
    fn trip<P: SpiPort>(&mut self, fault: FieldFault, port: &mut P) {
        port.set_out_enable(false);
        let _ = port.exchange_outputs(vni8200::command(0));
        if self.latched.is_none() {
            self.latched = Some(fault);
            self.unreported = Some(fault);
        }
    }
}

/// One command exchange; `None` when the answer fails its check or reports that the
/// chip refused the command.
fn exchange_checked<P: SpiPort>(port: &mut P, command: u16) -> Option<vni8200::Status> {
    match vni8200::decode_answer(port.exchange_outputs(command)) {
        Ok(s) if !s.parity_failed => Some(s),
        _ => None,
    }
}

#[cfg(test)]
mod tests;
