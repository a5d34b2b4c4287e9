//! Tests of the I2C v2 model: register semantics, timing in cycles, and embassy's exact
//! register sequences against the board's devices.

use std::cell::RefCell;
use std::rc::Rc;

use super::embassy_driver::{Embassy, Error, TIMINGR_100K};
use super::*;
use crate::devices::eeprom_24c256::{Eeprom24c256, DEFAULT_WRITE_CYCLE};
use crate::devices::lcd_backpack::LcdBackpack;

type Shared<T> = Rc<RefCell<T>>;

/// I2C1 with the PLC board's bus: the 24C256 at 0x50 and the LCD backpack at 0x27.
fn board() -> (I2c, Shared<Eeprom24c256>, Shared<LcdBackpack>) {
    let mut i2c = I2c::new(I2cInstance::I2c1);
    let eeprom = Rc::new(RefCell::new(Eeprom24c256::default()));
    let lcd = Rc::new(RefCell::new(LcdBackpack::default()));
    i2c.attach(eeprom.clone());
    i2c.attach(lcd.clone());
    (i2c, eeprom, lcd)
}

fn rd(i2c: &mut I2c, off: u32, now: Cycles) -> u32 {
    i2c.advance(now);
    i2c.read(off, now).unwrap()
}

fn wr(i2c: &mut I2c, off: u32, v: u32, now: Cycles) {
    i2c.advance(now);
    assert!(i2c.write(Write::word(off, v), now));
}

/// PE=1 with embassy's 100 kHz timing, at cycle 0.
fn enabled(i2c: &mut I2c) {
    wr(i2c, TIMINGR, TIMINGR_100K, 0);
    wr(i2c, CR1, CR1_PE, 0);
}

fn cr2(addr: u8, read: bool, n: u8, autoend: bool, reload: bool) -> u32 {
    (u32::from(addr) << 1)
        | if read { CR2_RD_WRN } else { 0 }
        | (u32::from(n) << CR2_NBYTES_SHIFT)
        | CR2_START
        | if autoend { CR2_AUTOEND } else { 0 }
        | if reload { CR2_RELOAD } else { 0 }
}

#[test]
fn reset_values_and_unmodelled_registers() {
    let (mut i2c, ..) = board();
    for (off, v) in [
        (CR1, 0),
        (CR2, 0),
        (OAR1, 0),
        (OAR2, 0),
        (TIMINGR, 0),
        (TIMEOUTR, 0),
        (ISR, TXE),
        (ICR, 0),
        (RXDR, 0),
        (TXDR, 0),
    ] {
        assert_eq!(i2c.read(off, 0), Some(v), "offset {off:#x}");
    }
    // PEC is not modelled: the SoC reports the access.
    assert_eq!(i2c.read(PECR, 0), None);
    assert_eq!(i2c.read(0x2C, 0), None);
    assert!(!i2c.write(Write::word(0x2C, 1), 0));
    // Reserved CR1 bit 13 reads 0.
    wr(&mut i2c, CR1, 0xFFFF_FFFF, 0);
    assert_eq!(rd(&mut i2c, CR1, 0), CR1_MASK);
}

#[test]
fn timingr_decodes_into_the_scl_period() {
    let (mut i2c, ..) = board();
    wr(&mut i2c, TIMINGR, TIMINGR_100K, 0);
    // (SCLL + 1) x (PRESC + 1) = 212 x 4 = 848 cycles each half, plus the analog filter
    // (260 ns = 45 cycles rounded up) and 3 cycles of synchronisation per edge.
    let sync = ns_to_cycles(260) + 3;
    assert_eq!(sync, 48);
    assert_eq!(i2c.scl_low_high(), (848 + sync, 848 + sync));
    assert_eq!(i2c.scl_period(), 1792);
    // ~94.9 kHz: a 9-bit byte is 16128 cycles (94.9 us).
    assert_eq!(9 * i2c.scl_period(), 16_128);

    // Digital filter and no analog filter (configured with PE=0).
    wr(&mut i2c, CR1, CR1_ANFOFF | (2 << CR1_DNF_SHIFT), 0);
    assert_eq!(i2c.scl_low_high(), (848 + 5, 848 + 5));
    // SDADEL + SCLDEL longer than SCLL lengthens the low period.
    wr(&mut i2c, TIMINGR, (15 << 20) | (15 << 16) | (1 << 8) | 1, 0);
    assert_eq!(i2c.scl_low_high(), (31 + 5, 2 + 5));
    // The board's rise time adds to the high period.
    i2c.set_rise_time_ns(1000);
    assert_eq!(i2c.scl_low_high(), (31 + 5, 2 + 5 + 170));
}

#[test]
fn filters_are_locked_while_enabled() {
    let (mut i2c, ..) = board();
    wr(&mut i2c, CR1, CR1_PE, 0);
    wr(&mut i2c, CR1, CR1_PE | CR1_ANFOFF | (3 << CR1_DNF_SHIFT), 0);
    assert_eq!(rd(&mut i2c, CR1, 0), CR1_PE);
    // Writable in the same write that clears PE (embassy's init does PE=0, ANFOFF=0).
    wr(&mut i2c, CR1, CR1_ANFOFF, 0);
    assert_eq!(rd(&mut i2c, CR1, 0), CR1_ANFOFF);
}

#[test]
fn write_to_an_acking_device_flag_timing() {
    let (mut i2c, _, lcd) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    let t0 = 1000;
    wr(&mut i2c, CR2, cr2(0x27, false, 2, false, false), t0);
    assert_ne!(rd(&mut i2c, ISR, t0) & BUSY, 0, "BUSY from the START on");
    assert_ne!(rd(&mut i2c, CR2, t0) & CR2_START, 0);
    // START (1 T) + address (9 T): TXIS not a cycle earlier.
    let txis = t0 + t + 9 * t;
    assert_eq!(i2c.next_event(), Some(t0 + t));
    assert_eq!(rd(&mut i2c, ISR, txis - 1) & TXIS, 0);
    assert_eq!(rd(&mut i2c, CR2, txis - 1) & CR2_START, CR2_START);
    assert_eq!(rd(&mut i2c, ISR, txis) & (TXIS | TXE), TXIS | TXE);
    assert_eq!(
        rd(&mut i2c, CR2, txis) & CR2_START,
        0,
        "START cleared after the address"
    );
    // SCL is stretched while TXDR is empty: nothing is due.
    assert_eq!(i2c.next_event(), None);
    let w1 = txis + 5000;
    wr(&mut i2c, TXDR, 0x3C, w1);
    assert_eq!(
        rd(&mut i2c, ISR, w1) & (TXIS | TXE),
        TXE,
        "copied to the shift register"
    );
    // The device gets the byte after its eighth bit.
    i2c.advance(w1 + 8 * t - 1);
    assert_eq!(lcd.borrow().latch(), 0xFF);
    i2c.advance(w1 + 8 * t);
    assert_eq!(lcd.borrow().latch(), 0x3C);
    assert_eq!(rd(&mut i2c, ISR, w1 + 9 * t - 1) & TXIS, 0);
    assert_ne!(rd(&mut i2c, ISR, w1 + 9 * t) & TXIS, 0);
    let w2 = w1 + 9 * t + 100;
    wr(&mut i2c, TXDR, 0x38, w2);
    // Last byte: TC (AUTOEND=0), SCL stretched until STOP.
    assert_eq!(rd(&mut i2c, ISR, w2 + 9 * t - 1) & TC, 0);
    assert_ne!(rd(&mut i2c, ISR, w2 + 9 * t) & TC, 0);
    assert_eq!(i2c.next_event(), None);
    let s = w2 + 9 * t + 300;
    wr(&mut i2c, CR2, CR2_STOP, s);
    let isr = rd(&mut i2c, ISR, s);
    assert_eq!(isr & TC, 0, "TC cleared by setting STOP");
    assert_ne!(isr & BUSY, 0);
    assert_eq!(rd(&mut i2c, ISR, s + t - 1) & STOPF, 0);
    let isr = rd(&mut i2c, ISR, s + t);
    assert_ne!(isr & STOPF, 0);
    assert_eq!(isr & BUSY, 0);
    assert_eq!(
        rd(&mut i2c, CR2, s + t) & CR2_STOP,
        0,
        "STOP cleared by the STOP condition"
    );
    assert_eq!(lcd.borrow().latch(), 0x38);
    let st = i2c.stats();
    assert_eq!(
        (st.starts, st.stops, st.bytes_written, st.nacks),
        (1, 1, 2, 0)
    );
}

#[test]
fn preloaded_txdr_goes_out_without_txis() {
    let (mut i2c, _, lcd) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, TXDR, 0x55, 10);
    assert_eq!(rd(&mut i2c, ISR, 10) & TXE, 0);
    wr(&mut i2c, CR2, cr2(0x27, false, 1, true, false), 10);
    let after_addr = 10 + 10 * t;
    assert_eq!(rd(&mut i2c, ISR, after_addr) & (TXIS | TXE), TXE);
    // AUTOEND: STOP right after the byte.
    assert_ne!(rd(&mut i2c, ISR, after_addr + 9 * t + t) & STOPF, 0);
    assert_eq!(lcd.borrow().latch(), 0x55);
}

#[test]
fn txdr_write_ignored_while_full() {
    let (mut i2c, ..) = board();
    enabled(&mut i2c);
    wr(&mut i2c, TXDR, 0x11, 0);
    wr(&mut i2c, TXDR, 0x22, 0);
    assert_eq!(rd(&mut i2c, TXDR, 0), 0x11);
}

#[test]
fn nack_of_an_absent_address() {
    let (mut i2c, ..) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    let t0 = 500;
    wr(&mut i2c, CR2, cr2(0x42, false, 1, false, false), t0);
    assert_eq!(rd(&mut i2c, ISR, t0 + 10 * t - 1) & NACKF, 0);
    let isr = rd(&mut i2c, ISR, t0 + 10 * t);
    assert_eq!(isr & (NACKF | TXIS), NACKF, "no TXIS after a NACK");
    // The master sends STOP by itself.
    let isr = rd(&mut i2c, ISR, t0 + 11 * t);
    assert_eq!(isr & (STOPF | BUSY), STOPF);
    assert_eq!(i2c.stats().nacks, 1);
    wr(&mut i2c, ICR, NACKF | STOPF, t0 + 11 * t);

    // The same through embassy's blocking_write: Err(Nack), flags cleared by the driver.
    let mut e = Embassy::new(&mut i2c, 100_000);
    assert_eq!(e.blocking_write(0x42, &[1, 2]), Err(Error::Nack));
    assert_eq!(e.rd(ISR) & (NACKF | STOPF | BUSY | TXIS), 0);
    assert_eq!(e.rd(ISR) & TXE, TXE);
}

#[test]
fn icr_clears_only_written_flags_and_isr_writes_only_flush() {
    let (mut i2c, ..) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, CR2, cr2(0x42, false, 1, false, false), 0);
    i2c.advance(20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t) & (NACKF | STOPF), NACKF | STOPF);
    // Writing ISR cannot clear flags; writing 0 to ICR clears nothing.
    wr(&mut i2c, ISR, 0, 20 * t);
    wr(&mut i2c, ICR, 0, 20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t) & (NACKF | STOPF), NACKF | STOPF);
    wr(&mut i2c, ICR, STOPF, 20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t) & (NACKF | STOPF), NACKF);
    wr(&mut i2c, ICR, NACKF, 20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t) & (NACKF | STOPF), 0);
    // ISR: TXE=1 flushes TXDR; TXIS is writable only with NOSTRETCH.
    wr(&mut i2c, TXDR, 0x12, 20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t) & TXE, 0);
    wr(&mut i2c, ISR, TXE | TXIS | STOPF, 20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t), TXE);
    wr(&mut i2c, CR1, CR1_PE | CR1_NOSTRETCH, 20 * t);
    wr(&mut i2c, ISR, TXIS, 20 * t);
    assert_eq!(rd(&mut i2c, ISR, 20 * t), TXE | TXIS);
}

#[test]
fn clearing_pe_resets_the_state_machine() {
    let (mut i2c, _, lcd) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, OAR1, 0x8042, 0);
    wr(&mut i2c, CR2, cr2(0x27, false, 3, false, false), 0);
    wr(&mut i2c, TXDR, 0x10, 0);
    i2c.advance(12 * t);
    assert_ne!(rd(&mut i2c, ISR, 12 * t) & BUSY, 0);
    // PE=0 in the middle of the first data byte.
    wr(&mut i2c, CR1, 0, 12 * t);
    assert_eq!(rd(&mut i2c, CR1, 12 * t) & CR1_PE, 0, "PE reads 0 at once");
    assert_eq!(rd(&mut i2c, ISR, 12 * t), TXE);
    let c2 = rd(&mut i2c, CR2, 12 * t);
    assert_eq!(c2 & (CR2_START | CR2_STOP | CR2_NACK), 0);
    assert_eq!(
        c2 & CR2_NBYTES,
        3 << CR2_NBYTES_SHIFT,
        "other CR2 bits keep their value"
    );
    assert_eq!(rd(&mut i2c, TIMINGR, 12 * t), TIMINGR_100K);
    assert_eq!(rd(&mut i2c, OAR1, 12 * t), 0x8042);
    assert_eq!(i2c.next_event(), None);
    assert_eq!(i2c.stats().abandoned, 1);
    // The byte never completed: the backpack kept its pins.
    i2c.advance(100 * t);
    assert_eq!(lcd.borrow().latch(), 0xFF);
    // START is ignored while PE=0.
    wr(&mut i2c, CR2, cr2(0x27, false, 1, false, false), 100 * t);
    assert_eq!(rd(&mut i2c, CR2, 100 * t) & CR2_START, 0);
    // PE low for less than 3 APB cycles is counted.
    wr(&mut i2c, CR1, CR1_PE, 100 * t);
    assert_eq!(i2c.stats().short_pe_resets, 0);
    wr(&mut i2c, CR1, 0, 100 * t + 10);
    wr(&mut i2c, CR1, CR1_PE, 100 * t + 12);
    assert_eq!(i2c.stats().short_pe_resets, 1);
    // A new transfer works.
    let mut e = Embassy::new(&mut i2c, 200 * t);
    assert_eq!(e.blocking_write(0x27, &[0x08]), Ok(()));
    assert_eq!(lcd.borrow().latch(), 0x08);
}

#[test]
fn reload_sets_tcr_and_stretches_until_nbytes_is_written() {
    let (mut i2c, _, lcd) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, CR2, cr2(0x27, false, 1, false, true), 0);
    wr(&mut i2c, TXDR, 0xA0, 0);
    let tcr = 10 * t + 9 * t;
    assert_eq!(rd(&mut i2c, ISR, tcr - 1) & TCR, 0);
    let isr = rd(&mut i2c, ISR, tcr);
    assert_eq!(isr & (TCR | TC | TXIS), TCR, "TCR, not TC nor TXIS");
    assert_eq!(i2c.next_event(), None, "SCL stretched while TCR is set");
    // Writing NBYTES=0 does not clear it.
    let v = rd(&mut i2c, CR2, tcr) & !CR2_NBYTES;
    wr(&mut i2c, CR2, v, tcr + 10);
    assert_ne!(rd(&mut i2c, ISR, tcr + 10) & TCR, 0);
    // NBYTES=1, RELOAD=0: TCR cleared, next byte needed.
    let v = (rd(&mut i2c, CR2, tcr + 20) & !(CR2_NBYTES | CR2_RELOAD)) | (1 << CR2_NBYTES_SHIFT);
    wr(&mut i2c, CR2, v, tcr + 20);
    assert_eq!(rd(&mut i2c, ISR, tcr + 20) & (TCR | TXIS), TXIS);
    wr(&mut i2c, TXDR, 0xA4, tcr + 30);
    assert_ne!(rd(&mut i2c, ISR, tcr + 30 + 9 * t) & TC, 0);
    assert_eq!(lcd.borrow().latch(), 0xA4);
}

#[test]
fn receiver_stretches_while_rxdr_is_full() {
    let (mut i2c, eeprom, _) = board();
    let mut img = vec![0u8; 32 * 1024];
    img[0..3].copy_from_slice(&[0x11, 0x22, 0x33]);
    eeprom.borrow_mut().load(&img).unwrap();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    // Current-address read of 3 bytes, AUTOEND.
    wr(&mut i2c, CR2, cr2(0x50, true, 3, true, false), 0);
    let b0 = 10 * t;
    assert_eq!(rd(&mut i2c, ISR, b0 + 8 * t - 1) & RXNE, 0);
    assert_ne!(
        rd(&mut i2c, ISR, b0 + 8 * t) & RXNE,
        0,
        "RXNE after the eighth bit"
    );
    // Byte 1 arrives at b0 + 17 T but RXDR is full: the master stretches before its ACK.
    i2c.advance(b0 + 100 * t);
    assert_eq!(i2c.next_event(), None);
    assert_eq!(rd(&mut i2c, RXDR, b0 + 100 * t), 0x11);
    // Reading RXDR lets the held byte in at once.
    let r = b0 + 100 * t;
    assert_ne!(rd(&mut i2c, ISR, r) & RXNE, 0);
    assert_eq!(rd(&mut i2c, RXDR, r), 0x22);
    // The last byte: eight bits after the ACK bit of byte 1, then NACK + STOP.
    let b2 = r + t;
    assert_eq!(rd(&mut i2c, ISR, b2 + 8 * t - 1) & RXNE, 0);
    assert_eq!(rd(&mut i2c, RXDR, b2 + 8 * t), 0x33);
    assert_eq!(rd(&mut i2c, ISR, b2 + 10 * t - 1) & STOPF, 0);
    assert_ne!(rd(&mut i2c, ISR, b2 + 10 * t) & STOPF, 0);
    assert_eq!(i2c.stats().bytes_read, 3);
    assert_eq!(eeprom.borrow().pointer(), 3);
}

#[test]
fn interrupt_lines_and_dma_requests() {
    let (mut i2c, ..) = board();
    let ev = names::irq("I2C1_EV").unwrap();
    let er = names::irq("I2C1_ER").unwrap();
    assert_eq!((ev, er), (31, 32));
    assert_eq!(I2c::new(I2cInstance::I2c3).ev_irq, Some(92));
    let tx = names::dma_request("I2C1", "TX").unwrap();
    let rx = names::dma_request("I2C1", "RX").unwrap();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(
        &mut i2c,
        CR1,
        CR1_PE | CR1_TXIE | CR1_TXDMAEN | CR1_ERRIE | CR1_NACKIE,
        0,
    );
    wr(&mut i2c, CR2, cr2(0x27, false, 1, false, false), 0);
    let lines = |i: &I2c| {
        let mut l = IrqLines::default();
        i.irq_lines(&mut l);
        let mut d = DmaRequests::default();
        i.dma_requests(&mut d);
        (l.get(ev), l.get(er), d.get(tx), d.get(rx))
    };
    assert_eq!(lines(&i2c), (false, false, false, false));
    i2c.advance(10 * t);
    assert_eq!(
        lines(&i2c),
        (true, false, true, false),
        "TXIS: event line and TX request"
    );
    wr(&mut i2c, TXDR, 0, 10 * t);
    assert_eq!(lines(&i2c), (false, false, false, false));
    // A NACK with NACKIE: event line.
    wr(&mut i2c, CR2, cr2(0x42, false, 1, false, false), 30 * t);
    i2c.advance(45 * t);
    assert!(lines(&i2c).0);
    wr(&mut i2c, ICR, ICR_MASK, 45 * t);
    assert_eq!(lines(&i2c), (false, false, false, false));
}

#[test]
fn ten_bit_addressing_is_reported() {
    let (mut i2c, ..) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(
        &mut i2c,
        CR2,
        cr2(0x27, false, 1, false, false) | CR2_ADD10,
        0,
    );
    assert_ne!(rd(&mut i2c, ISR, 10 * t) & NACKF, 0);
    assert!(i2c.unsupported().unwrap().contains("10-bit"));
}

#[test]
fn timeoutr_and_oar_fields_are_locked_while_enabled() {
    let (mut i2c, ..) = board();
    wr(&mut i2c, TIMEOUTR, 0x8000_00C3 | TIMEOUTR_TIMOUTEN, 0);
    wr(
        &mut i2c,
        TIMEOUTR,
        0x8000_0000 | TIMEOUTR_TIMOUTEN | 0x0055 | (0x66 << 16),
        0,
    );
    // TIMEOUTA locked by TIMOUTEN, TIMEOUTB by TEXTEN.
    assert_eq!(rd(&mut i2c, TIMEOUTR, 0), 0x8000_80C3);
    wr(&mut i2c, OAR1, 0x8042, 0);
    wr(&mut i2c, OAR1, 0x8010, 0);
    assert_eq!(rd(&mut i2c, OAR1, 0), 0x8042);
    wr(&mut i2c, OAR1, 0x0010, 0);
    assert_eq!(
        rd(&mut i2c, OAR1, 0),
        0x0042,
        "OA1EN cleared, OA1 still locked in this write"
    );
}

/// The image's `I2cEeprom::write_page` then `read`: embassy's `blocking_write_vectored`
/// (address + data with RELOAD), ACK polling with `blocking_write` of the address, then
/// `blocking_write_read`.
#[test]
fn eeprom_page_write_ack_polling_and_read_back_through_embassy() {
    let (mut i2c, eeprom, _) = board();
    let t;
    {
        let mut e = Embassy::new(&mut i2c, 0);
        e.init(TIMINGR_100K);
        t = e.i2c.scl_period();
        let data: Vec<u8> = (0..64u8).map(|i| i.wrapping_mul(7) ^ 0x5A).collect();
        let addr: u16 = 0x0140;
        let t0 = e.now;
        assert_eq!(
            e.blocking_write_vectored(0x50, &[&addr.to_be_bytes(), &data]),
            Ok(())
        );
        let t_stop = e.now;
        // START, address, 2 + 64 bytes, STOP: 1 + 9 x 67 + 1 SCL periods, plus the
        // driver's register accesses (a few per byte).
        let wire = (1 + 9 * 67 + 1) * t;
        assert!(t_stop - t0 >= wire, "{} < {wire}", t_stop - t0);
        assert!(t_stop - t0 < wire + 67 * 20 * 30, "{}", t_stop - t0);
        assert_eq!(eeprom.borrow().writes(), 1);
        let cycle_end = eeprom.borrow().write_cycle_end().unwrap();
        // tWR starts at the STOP condition, which ends just before the driver sees STOPF.
        let stop_condition = cycle_end - DEFAULT_WRITE_CYCLE;
        assert!(stop_condition <= t_stop && stop_condition + t > t_stop);

        // ACK polling as `write_page` does it.
        let mut nacks = 0;
        let ok_at = loop {
            match e.blocking_write(0x50, &addr.to_be_bytes()) {
                Ok(()) => break e.now,
                Err(Error::Nack) => nacks += 1,
                Err(other) => panic!("{other:?}"),
            }
            assert!(e.now < t_stop + 2 * DEFAULT_WRITE_CYCLE);
        };
        // Each NACKed poll is START + address + STOP (11 T) plus the driver's accesses.
        assert!(nacks >= 20, "{nacks}");
        assert_eq!(eeprom.borrow().nacked_polls(), nacks);
        assert!(ok_at > cycle_end, "the chip ACKs only after tWR");
        assert!(ok_at < cycle_end + 40 * t, "first poll after tWR succeeds");
        assert_eq!(eeprom.borrow().writes(), 1, "the polls wrote nothing");

        let mut back = [0u8; 64];
        assert_eq!(
            e.blocking_write_read(0x50, &addr.to_be_bytes(), &mut back),
            Ok(())
        );
        assert_eq!(back.to_vec(), data);
        assert_eq!(&eeprom.borrow().contents()[0x140..0x180], &data[..]);
        // A current-address read (`blocking_read`) continues after the last byte read.
        let mut next = [0u8; 2];
        assert_eq!(e.blocking_read(0x50, &mut next), Ok(()));
        assert_eq!(next, [0xFF, 0xFF]);
        assert_eq!(eeprom.borrow().pointer(), 0x182);
        assert_eq!(e.rd(ISR) & (BUSY | STOPF | NACKF | TC | TCR), 0);
    }
    let st = i2c.stats();
    assert_eq!(st.arbitration_losses, 0);
    assert_eq!(st.stuck_starts, 0);
}

/// The MCU resets while the 24C256 shifts out a 0 bit of a read: it keeps SDA low. The
/// image's next transaction (the LCD's first nibble) loses arbitration; 9 SCL pulses and a
/// STOP made with the pins as GPIO free the bus.
#[test]
fn stuck_sda_after_a_reset_mid_read_and_its_recovery() {
    let (mut i2c, eeprom, lcd) = board();
    // 0x0F at 0x0200: bits 7..4 are 0.
    let mut img = vec![0xFFu8; 32 * 1024];
    img[0x200] = 0x0F;
    img[0x201] = 0x0F;
    eeprom.borrow_mut().load(&img).unwrap();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    // The image's read: address 0x0200 (write, TC), repeated START, read 2 with AUTOEND.
    wr(&mut i2c, CR2, cr2(0x50, false, 2, false, false), 0);
    wr(&mut i2c, TXDR, 0x02, 10 * t);
    wr(&mut i2c, TXDR, 0x00, 19 * t);
    assert_ne!(rd(&mut i2c, ISR, 28 * t) & TC, 0);
    wr(&mut i2c, CR2, cr2(0x50, true, 2, true, false), 28 * t);
    // Repeated START at 28 T, address 29..38 T, data from 38 T; reset 1.5 bits in.
    let reset_at = 38 * t + t + t / 2;
    i2c.advance(reset_at);
    assert!(!i2c.sda_held_low());
    i2c.reset();
    assert!(i2c.sda_held_low(), "the EEPROM drives bit 1 (a 0) of 0x0F");
    assert!(!i2c.bus().sda());

    // After the reset, embassy's init and the LCD's first nibble.
    let mut e = Embassy::new(&mut i2c, reset_at + 1000);
    e.init(TIMINGR_100K);
    assert_eq!(
        e.blocking_write(0x27, &[0x3C, 0x38]),
        Err(Error::Arbitration)
    );
    assert_eq!(lcd.borrow().writes(), 0, "the LCD never saw its address");
    let st = e.i2c.stats();
    assert_eq!((st.stuck_starts, st.arbitration_losses), (1, 1));
    // embassy's error path soft-reset the peripheral, then set CR2.STOP (`master_stop` for
    // any error but a NACK) while not master: the bit stays set. The bus is still stuck
    // (the two clocks moved the chip to bit 3 of 0x0F, another 0).
    assert_ne!(e.rd(CR2) & CR2_STOP, 0);
    assert!(e.i2c.sda_held_low());

    // The fixed boot: after the next reset, 9 SCL pulses at most (GPIO, until SDA is high)
    // and a STOP, before the I2C is initialised.
    let now = e.now;
    e.i2c.reset();
    let mut pulses = 0;
    while e.i2c.sda_held_low() && pulses < 9 {
        let now = e.now;
        e.i2c.gpio_scl(true, now + 850);
        e.i2c.gpio_scl(false, now + 1700);
        e.now += 1700;
        pulses += 1;
    }
    assert!(!e.i2c.sda_held_low(), "released within 9 pulses");
    assert_eq!(pulses, 1, "bit 4 of 0x0F is a 1");
    let now2 = e.now.max(now);
    e.i2c.gpio_scl(true, now2);
    e.i2c.gpio_sda(true, now2 + 100);
    e.i2c.gpio_scl(false, now2 + 900);
    e.i2c.gpio_sda(false, now2 + 1800);
    e.now = now2 + 1800;
    assert!(e.i2c.bus().sda() && e.i2c.bus().scl());
    assert_eq!(e.i2c.bus().gpio_scl_pulses(), pulses + 1);
    e.init(TIMINGR_100K);

    // Both devices answer again.
    assert_eq!(e.blocking_write(0x27, &[0x3C, 0x38]), Ok(()));
    assert_eq!(lcd.borrow().latch(), 0x38);
    let mut back = [0u8; 2];
    assert_eq!(
        e.blocking_write_read(0x50, &[0x02, 0x00], &mut back),
        Ok(())
    );
    assert_eq!(back, [0x0F, 0x0F]);
    assert_eq!(eeprom.borrow().writes(), 0, "the recovery wrote nothing");
}

/// embassy-stm32 0.6 sets CR2.STOP after an arbitration loss, when the peripheral is no
/// longer master: the bit stays set, so the next transfer sends its address and a STOP,
/// never TXIS, and times out after 1 s, setting STOP again (the same mechanism as
/// embassy PR #4634 fixed for NACKs). Even with the bus free, every later `blocking_write`
/// fails until the peripheral is reset.
#[test]
fn stale_stop_after_an_arbitration_loss_makes_later_writes_time_out() {
    let (mut i2c, eeprom, lcd) = board();
    eeprom.borrow_mut().load(&vec![0x00u8; 32 * 1024]).unwrap();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, CR2, cr2(0x50, true, 4, true, false), 0);
    i2c.advance(10 * t + 3 * t);
    i2c.reset();
    let mut e = Embassy::new(&mut i2c, 20 * t);
    e.init(TIMINGR_100K);
    assert_eq!(e.blocking_write(0x27, &[0x08]), Err(Error::Arbitration));
    assert_ne!(e.rd(CR2) & CR2_STOP, 0);
    // Free the bus for good (9 pulses + STOP): the stale STOP alone now breaks the write.
    let now = e.now;
    e.i2c.gpio_pulse_scl(9, now);
    e.i2c.gpio_sda(true, now);
    e.i2c.gpio_sda(false, now);
    assert!(!e.i2c.sda_held_low());
    let t0 = e.now;
    assert_eq!(e.blocking_write(0x27, &[0x08]), Err(Error::Timeout));
    assert!(e.now - t0 > 170_000_000, "the 1 s default timeout");
    assert_eq!(lcd.borrow().writes(), 0, "address, then STOP: no data byte");
    assert_ne!(e.rd(CR2) & CR2_STOP, 0, "set again by the timeout path");
    // A peripheral reset (RCC) clears it.
    e.i2c.reset();
    e.init(TIMINGR_100K);
    assert_eq!(e.blocking_write(0x27, &[0x08]), Ok(()));
}

/// Without recovery, the failed attempts clock the stuck chip along: its byte ends, it
/// sees no ACK and lets go, so a later attempt gets through (the intermittent D6 symptom).
#[test]
fn failed_attempts_eventually_clock_the_stuck_device_free() {
    let (mut i2c, eeprom, lcd) = board();
    eeprom.borrow_mut().load(&vec![0x00u8; 32 * 1024]).unwrap();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, CR2, cr2(0x50, true, 4, true, false), 0);
    i2c.advance(10 * t + 3 * t);
    i2c.reset();
    assert!(i2c.sda_held_low());
    let mut e = Embassy::new(&mut i2c, 20 * t);
    e.init(TIMINGR_100K);
    let mut failures = 0;
    while e.blocking_write(0x27, &[0x08]).is_err() {
        failures += 1;
        assert!(failures < 20);
    }
    assert!(failures >= 2);
    assert_eq!(lcd.borrow().latch(), 0x08);
    // Each failure is a lost arbitration or, once the chip lets go mid-address, a NACK
    // (nobody saw the START).
    let st = e.i2c.stats();
    assert!(st.arbitration_losses >= 1);
    assert_eq!(st.arbitration_losses + st.nacks, failures);
    assert_eq!(st.stuck_starts, failures);
}

/// A reset while the addressed device drives the ACK of a written byte: SDA stays low until
/// the next SCL clock, which a single GPIO pulse provides.
#[test]
fn reset_during_a_device_ack_holds_sda_until_the_next_clock() {
    let (mut i2c, _, lcd) = board();
    enabled(&mut i2c);
    let t = i2c.scl_period();
    wr(&mut i2c, CR2, cr2(0x27, false, 1, false, false), 0);
    wr(&mut i2c, TXDR, 0x40, 0);
    // Data byte 10..19 T: its ACK slot is 18..19 T.
    i2c.advance(18 * t + t / 2);
    i2c.reset();
    assert!(i2c.sda_held_low());
    assert_eq!(lcd.borrow().latch(), 0x40, "the byte was complete");
    i2c.gpio_pulse_scl(1, 19 * t);
    assert!(!i2c.sda_held_low());
}

/// GPIO bit-banging drives the devices too: START, address, a data byte, STOP.
#[test]
fn gpio_bit_banged_write_reaches_the_backpack() {
    /// One GPIO step 500 cycles after the previous: SCL then SDA (`Some(true)` = low).
    fn step(i2c: &mut I2c, now: &mut Cycles, scl_low: Option<bool>, sda_low: Option<bool>) {
        *now += 500;
        if let Some(l) = sda_low {
            i2c.gpio_sda(l, *now);
        }
        if let Some(l) = scl_low {
            i2c.gpio_scl(l, *now);
        }
    }
    fn byte(i2c: &mut I2c, now: &mut Cycles, b: u8) -> bool {
        for k in (0..8).rev() {
            step(i2c, now, Some(true), None);
            step(i2c, now, None, Some(b >> k & 1 == 0));
            step(i2c, now, Some(false), None);
        }
        // ACK slot: SDA released; the device pulls it low while SCL is high.
        step(i2c, now, Some(true), None);
        step(i2c, now, None, Some(false));
        step(i2c, now, Some(false), None);
        let acked = !i2c.bus().sda();
        step(i2c, now, Some(true), None);
        acked
    }
    let (mut i2c, _, lcd) = board();
    let mut now = 0;
    step(&mut i2c, &mut now, None, Some(true)); // START
    assert!(byte(&mut i2c, &mut now, 0x27 << 1));
    assert!(byte(&mut i2c, &mut now, 0x9A));
    step(&mut i2c, &mut now, None, Some(true));
    step(&mut i2c, &mut now, Some(false), None);
    step(&mut i2c, &mut now, None, Some(false)); // STOP
    assert_eq!(lcd.borrow().latch(), 0x9A);
    assert!(i2c.bus().sda());
    // Nobody answers another address.
    step(&mut i2c, &mut now, None, Some(true));
    assert!(!byte(&mut i2c, &mut now, 0x33 << 1));
}

/// The MCU resets in the middle of a page write (third data byte, bit 3). Nothing holds SDA,
/// but the 24C256 still has two complete bytes in its page buffer and half a byte in its
/// shift register. How the recovery ends decides what gets written: a STOP (after no or
/// after 9 pulses) starts the write cycle of what the chip latched — with 9 pulses including
/// a ghost byte the pulses clocked in (0x33's first four bits, then released 1s: 0x3F) —
/// while a START before the STOP (the EEPROM makers' "memory reset": clocks, then START)
/// aborts the page write. The model writes the complete bytes latched at a STOP; the
/// datasheets do not say what a STOP in the middle of a byte does.
#[test]
fn reset_during_a_page_write_then_recovery_endings() {
    fn interrupted_write() -> (I2c, Shared<Eeprom24c256>, Cycles) {
        let (mut i2c, eeprom, _) = board();
        enabled(&mut i2c);
        let t = i2c.scl_period();
        wr(&mut i2c, CR2, cr2(0x50, false, 5, false, false), 0);
        for (k, b) in [0x01u8, 0x00, 0x11, 0x22, 0x33].iter().enumerate() {
            wr(&mut i2c, TXDR, u32::from(*b), (10 + 9 * k as u64) * t);
        }
        let at = 46 * t + 3 * t + t / 2;
        i2c.advance(at);
        i2c.reset();
        assert!(!i2c.sda_held_low());
        (i2c, eeprom, at + 1000)
    }
    fn stop(i2c: &mut I2c, now: Cycles) {
        i2c.gpio_scl(true, now);
        i2c.gpio_sda(true, now + 100);
        i2c.gpio_scl(false, now + 900);
        i2c.gpio_sda(false, now + 1800);
    }

    // (a) "pulse while SDA is low" does nothing here, then STOP: bytes 1 and 2 written.
    let (mut i2c, eeprom, now) = interrupted_write();
    stop(&mut i2c, now);
    assert_eq!(eeprom.borrow().writes(), 1);
    assert_eq!(
        &eeprom.borrow().contents()[0x100..0x103],
        &[0x11, 0x22, 0xFF]
    );

    // (b) always 9 pulses, then STOP: the ghost byte 0x3F is written too.
    let (mut i2c, eeprom, now) = interrupted_write();
    i2c.gpio_pulse_scl(9, now);
    stop(&mut i2c, now + 100);
    assert_eq!(eeprom.borrow().writes(), 1);
    assert_eq!(
        &eeprom.borrow().contents()[0x100..0x103],
        &[0x11, 0x22, 0x3F]
    );

    // (c) 9 pulses, START, STOP: the page write is aborted, nothing written.
    let (mut i2c, eeprom, now) = interrupted_write();
    i2c.gpio_pulse_scl(9, now);
    i2c.gpio_sda(true, now + 100); // SDA falls while SCL is high: START
    i2c.gpio_sda(false, now + 200); // and rises: STOP
    assert_eq!(eeprom.borrow().writes(), 0);
    assert_eq!(eeprom.borrow().aborted_writes(), 1);
    assert_eq!(
        &eeprom.borrow().contents()[0x100..0x103],
        &[0xFF, 0xFF, 0xFF]
    );
    assert!(i2c.bus().sda() && !i2c.sda_held_low());
}

// ---------------------------------------------------------------------------------------
// Injected faults

/// The PLC image's bus: embassy with the 20 ms transaction timeout (`i2c_bus.rs`).
fn plc_driver(i2c: &mut I2c) -> Embassy<'_> {
    let mut e = Embassy::new(i2c, 0);
    e.timeout = 20 * 170_000;
    e.init(TIMINGR_100K);
    e
}

/// A 30 ms stretch at the end of `blocking_write_read`'s write phase: embassy times out in
/// `wait_tc` and returns without STOP. When the device lets go the master completes the
/// chunk and holds the bus (TC, BUSY): every later `blocking_write` waits for BUSY and
/// times out too, until the peripheral is reset and a STOP is sent.
#[test]
fn a_stretch_in_the_write_phase_times_out_and_leaves_the_bus_busy() {
    let (mut i2c, eeprom, lcd) = board();
    eeprom.borrow_mut().load(&vec![0x42u8; 32 * 1024]).unwrap();
    i2c.inject_fault(I2cFault::stretch_ms(30.0), 0x50);
    let mut e = plc_driver(&mut i2c);
    let mut buf = [0u8; 4];
    assert_eq!(
        e.blocking_write_read(0x50, &[0x01, 0x00], &mut buf),
        Err(Error::Timeout)
    );
    assert!(!e.i2c.fault_armed());
    e.wait(20 * 170_000);
    let isr = e.rd(ISR);
    assert_ne!(isr & BUSY, 0, "the master still owns the bus: {isr:#x}");
    assert_ne!(
        isr & TC,
        0,
        "the chunk completed after the stretch: {isr:#x}"
    );
    assert_eq!(e.blocking_write(0x27, &[0x08]), Err(Error::Timeout));
    assert_eq!(lcd.borrow().writes(), 0, "nothing reached the LCD");
    // A driver that recovers: STOP, then the next transfer works.
    e.wr(CR2, CR2_STOP);
    e.wait(3 * e.i2c.scl_period());
    assert_eq!(e.rd(ISR) & BUSY, 0);
    e.wr(ICR, STOPF);
    assert_eq!(e.blocking_write(0x27, &[0x08]), Ok(()));
    assert_eq!(e.i2c.stats().injected_faults, 1);
}

/// A stretch shorter than the timeout only delays the transfer.
#[test]
fn a_short_stretch_only_delays_the_transfer() {
    let (mut i2c, eeprom, _) = board();
    eeprom.borrow_mut().load(&vec![0x42u8; 32 * 1024]).unwrap();
    i2c.inject_fault(I2cFault::stretch_ms(5.0), 0x50);
    let mut e = plc_driver(&mut i2c);
    let t0 = e.now;
    let mut buf = [0u8; 4];
    assert_eq!(e.blocking_write_read(0x50, &[0x01, 0x00], &mut buf), Ok(()));
    assert_eq!(buf, [0x42; 4]);
    assert!(e.now - t0 > 5 * 170_000, "the stretch took its time");
}

/// A NACK of the last address byte: NACKF, automatic STOP, `Error::Nack`; the bus is free.
#[test]
fn an_injected_nack_ends_with_stop_and_leaves_the_bus_free() {
    let (mut i2c, eeprom, lcd) = board();
    eeprom.borrow_mut().load(&vec![0x42u8; 32 * 1024]).unwrap();
    i2c.inject_fault(I2cFault::Nack, 0x50);
    let mut e = plc_driver(&mut i2c);
    let mut buf = [0u8; 2];
    assert_eq!(
        e.blocking_write_read(0x50, &[0x00, 0x10], &mut buf),
        Err(Error::Nack)
    );
    assert_eq!(e.rd(ISR) & BUSY, 0);
    assert_eq!(e.blocking_write(0x27, &[0x08]), Ok(()));
    assert_eq!(lcd.borrow().writes(), 1);
    assert_eq!(e.i2c.stats().nacks, 1);
}

/// Arbitration loss and bus error: ARLO / BERR, embassy resets the peripheral (PE toggle),
/// and the next transfer works.
#[test]
fn arbitration_loss_and_bus_error_are_flagged_and_recoverable() {
    for (fault, err, flag) in [
        (I2cFault::ArbitrationLoss, Error::Arbitration, ARLO),
        (I2cFault::BusError, Error::Bus, BERR),
    ] {
        let (mut i2c, eeprom, lcd) = board();
        eeprom.borrow_mut().load(&vec![0x42u8; 32 * 1024]).unwrap();
        enabled(&mut i2c);
        i2c.inject_fault(fault, 0x27);
        // Register level: the flag and the end of the transfer.
        let t = i2c.scl_period();
        wr(&mut i2c, CR2, cr2(0x27, false, 1, false, false), 0);
        wr(&mut i2c, TXDR, 0x08, 10);
        let isr = rd(&mut i2c, ISR, 30 * t);
        assert_eq!(isr & (flag | BUSY | TC), flag, "{fault:?}: {isr:#x}");
        assert_eq!(rd(&mut i2c, CR2, 30 * t) & CR2_START, 0);
        wr(&mut i2c, ICR, flag, 30 * t);
        // Through embassy: the error, then a working transfer.
        i2c.inject_fault(fault, 0x27);
        let mut e = Embassy::new(&mut i2c, 40 * t);
        e.timeout = 20 * 170_000;
        assert_eq!(e.blocking_write(0x27, &[0x08]), Err(err), "{fault:?}");
        assert_eq!(e.blocking_write(0x27, &[0x0C]), Ok(()), "{fault:?}");
        assert_eq!(lcd.borrow().writes(), 1, "{fault:?}");
    }
}

/// TIMEOUTR.TIMOUTEN (TIDLE = 0): a stretch longer than tTIMEOUT sets TIMEOUT at
/// tTIMEOUT, and the master stops once SCL is released.
#[test]
fn scl_low_timeout_detector_flags_a_long_stretch() {
    let (mut i2c, _, lcd) = board();
    enabled(&mut i2c);
    // TIMEOUTA = 0x61: (0x61 + 1) x 2048 cycles = 200 704 cycles (1.18 ms).
    wr(&mut i2c, TIMEOUTR, (1 << 15) | 0x61, 0);
    let t_timeout = (0x61 + 1) * 2048;
    i2c.inject_fault(I2cFault::stretch_ms(5.0), 0x27);
    let t = i2c.scl_period();
    wr(&mut i2c, CR2, cr2(0x27, false, 1, false, false), 1);
    wr(&mut i2c, TXDR, 0x08, 2);
    // The eighth bit of the data byte ends at START + address + 8 bits.
    let eighth = 1 + t + 9 * t + 8 * t;
    assert_eq!(rd(&mut i2c, ISR, eighth + t_timeout - 10) & TIMEOUT, 0);
    assert_ne!(rd(&mut i2c, ISR, eighth + t_timeout + 10) & TIMEOUT, 0);
    // After the stretch: STOP instead of TC.
    let isr = rd(&mut i2c, ISR, eighth + 850_000 + 5 * t);
    assert_eq!(isr & (TC | BUSY | STOPF), STOPF, "{isr:#x}");
    assert_eq!(lcd.borrow().writes(), 1);
}
