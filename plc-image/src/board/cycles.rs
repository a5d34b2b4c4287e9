//! `dwt-cycles`: DWT cycle counts of one pass of the application task (I/O sampling, PLC
//! scan, outputs, LCD) and of the link and service tasks' critical sections, logged once a second
//! (bring-up figures, 170 cycles = 1 us). The counters are `board_common::cycles`.

pub use board_common::cycles::now;
use board_common::cycles::{CycleStat, EverySecond, LINK_RX, LINK_TX, SERVICE_RX, SERVICE_TX};

static SCAN: CycleStat = CycleStat::new();
static SECOND: EverySecond = EverySecond::new();

/// Records one scan that started at `start`.
#[inline(always)]
pub fn record_scan(start: u32) {
    SCAN.record(start);
}

/// Called every millisecond; logs and resets the maxima once a second.
pub fn report_every_second() {
    SECOND.tick(|| {
        defmt::info!(
            "dwt: scan last {} max {} cycles; link rx max {} tx max {}; service rx max {} tx max {}",
            SCAN.last(),
            SCAN.take_max(),
            LINK_RX.take_max(),
            LINK_TX.take_max(),
            SERVICE_RX.take_max(),
            SERVICE_TX.take_max()
        )
    });
}
