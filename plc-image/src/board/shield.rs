//! The X-NUCLEO-PLC01A1's SPI bus and OUT_EN (`firmware-plc/docs/field-io.md`): moves
//! 16-bit frames with one chip selected and drives the pins; what the frames mean, the
//! retries and the trips are the core's (`firmware_plc::field_io::Shield`).
//!
//! SPI1 master, mode 0, MSB first, 16-bit frames at 170 MHz / 64 = 2.66 MHz (below the
//! CLT01-38SQ7's 6.25 MHz; the VNI8200XP's limit was not in the pages reached), blocking:
//! two frames of 6 µs per 1 ms pass, less than a DMA set-up would cost.

use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::mode::Blocking;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use firmware_plc::field_io::{Shield, SpiPort};

use crate::pins;

/// The SPI clock asked for: embassy takes the fastest prescaler at or below it (/64).
const SPI_HZ: u32 = 3_000_000;

/// The shield's bus and pins with the core's state.
pub struct ShieldIo {
    bus: Bus,
    core: Shield,
}

struct Bus {
    spi: Spi<'static, Blocking, spi::mode::Master>,
    cs_inputs: Output<'static>,
    cs_outputs: Output<'static>,
    out_enable: Output<'static>,
}

impl ShieldIo {
    /// OUT_EN low (outputs off) first, both chip selects high, then the bus.
    pub fn new(p: pins::Shield) -> Self {
        let out_enable = Output::new(p.out_enable, Level::Low, Speed::Low);
        let cs_inputs = Output::new(p.cs_inputs, Level::High, Speed::Low);
        let cs_outputs = Output::new(p.cs_outputs, Level::High, Speed::Low);
        let mut config = spi::Config::default();
        config.mode = spi::MODE_0;
        config.bit_order = spi::BitOrder::MsbFirst;
        config.frequency = Hertz(SPI_HZ);
        let spi = Spi::new_blocking(p.spi, p.sck, p.mosi, p.miso, config);
        ShieldIo {
            bus: Bus {
                spi,
                cs_inputs,
                cs_outputs,
                out_enable,
            },
            core: Shield::new(),
        }
    }

    /// D00..D07 (bit n = D0n).
    pub fn read_inputs(&mut self) -> u8 {
        self.core.read_inputs(&mut self.bus)
    }

    /// O00..O07.
    pub fn write_outputs(&mut self, image: u8) {
        self.core.write_outputs(image, &mut self.bus);
    }

    /// A new trip's fault-log code.
    pub fn take_trip(&mut self) -> Option<u8> {
        let code = self.core.take_trip()?.code();
        defmt::error!("field i/o: trip {=u8}, outputs off", code);
        Some(code)
    }

    /// RUN started: the latch is cleared.
    pub fn rearm(&mut self) {
        self.core.rearm();
    }
}

impl Bus {
    /// One 16-bit frame with `cs` low. A bus error (none is possible in master mode
    /// without CRC) reads as 0, which fails both chips' checks.
    fn frame(
        spi: &mut Spi<'static, Blocking, spi::mode::Master>,
        cs: &mut Output<'static>,
        word: u16,
    ) -> u16 {
        let mut w = [word];
        cs.set_low();
        let ok = spi.blocking_transfer_in_place(&mut w).is_ok();
        cs.set_high();
        if ok {
            w[0]
        } else {
            0
        }
    }
}

impl SpiPort for Bus {
    fn exchange_inputs(&mut self) -> u16 {
        Bus::frame(&mut self.spi, &mut self.cs_inputs, 0)
    }

    fn exchange_outputs(&mut self, command: u16) -> u16 {
        Bus::frame(&mut self.spi, &mut self.cs_outputs, command)
    }

    fn set_out_enable(&mut self, on: bool) {
        self.out_enable.set_level(Level::from(on));
    }
}
