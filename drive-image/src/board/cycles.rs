//! `dwt-cycles`: DWT cycle counts of the PWM interrupt, of the 1 ms task's critical
//! section and of the link task's (each delays the interrupt), logged once a second
//! (bring-up figures, 170 cycles = 1 us). The counters are `board_common::cycles`.

pub use board_common::cycles::now;
use board_common::cycles::{CycleStat, EverySecond, LINK_RX, LINK_TX};

static PWM: CycleStat = CycleStat::new();
static TICK: CycleStat = CycleStat::new();
static SECOND: EverySecond = EverySecond::new();

/// Records one PWM interrupt that started at `start`.
#[inline(always)]
pub fn record_pwm(start: u32) {
    PWM.record(start);
}

/// Records one 1 ms tick (critical section) that started at `start`.
#[inline(always)]
pub fn record_tick(start: u32) {
    TICK.record(start);
}

/// Called every millisecond; logs and resets the maxima once a second.
pub fn report_every_second() {
    SECOND.tick(|| {
        defmt::info!(
            "dwt: PWM isr last {} max {} cycles, 1 ms tick max {}, link rx max {} tx max {}",
            PWM.last(),
            PWM.take_max(),
            TICK.take_max(),
            LINK_RX.take_max(),
            LINK_TX.take_max()
        )
    });
}
