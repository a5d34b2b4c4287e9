//! Cortex-M4 instruction count of `DriveCore::pwm_period` (the PWM interrupt's core part)
//! and of `tick_1ms`, for `../shared/tools/m4count.py`. No peripheral is initialised; the
//! HAL is linked only for its vector table.
//!
//! ```text
//! cargo build --profile firmware --target thumbv7em-none-eabihf --bin drive-m4bench -p drive-image
//! python3 ../shared/tools/m4count.py target/thumbv7em-none-eabihf/firmware/drive-m4bench
//! ```
//! Sections (m4count prints the instructions between `bench_mark(k)` and the next mark):
//! 1 = 1000 x pwm_period, motor program running (outputs on, OC/UV/brake checks active);
//! 3 = 1000 x pwm_period with the outputs off (IDLE); 5 = 10 x tick_1ms of the motor
//! program (lines 000-025); 7 = 1000 x `PeriodAction::from_command` of a running period
//! (the compare clamp and the blanking window's CCR5). A mark 0x10 after section 1 confirms
//! the outputs were on.
//! The end of a download, part by part (`docs/critical-sections.md`): 20 = the
//! section CRC, 21 = decoding 150 slots, 22 = `verify_drive`, 23 = `DriveCore::load_program`
//! (verifies again; the link path uses `load_verified`).
//! 30 = 1000 x `safety::Monitor::tick` with every function but STO requested (mask 0x0FFE,
//! the lab's settings, 2.0 Hz forward: every function evaluates, none trips; a mark 0x31
//! after it confirms no trip, 0x32 that one did); 33 = one tick with STO requested too
//! (0x0FFF: the trip).
#![no_std]
#![no_main]

mod target {
    use core::hint::black_box;

    use defmt_rtt as _;
    use embassy_stm32 as _;

    /// The bench never panics; m4count stops at the fault if it did.
    #[panic_handler]
    fn panic(_: &core::panic::PanicInfo) -> ! {
        cortex_m::asm::udf()
    }

    use firmware_drive::power_port::PeriodAction;
    use firmware_drive::safety::{Input as SafetyInput, Monitor};
    use firmware_drive::{AdcSample, DriveCommand, DriveConfig, DriveCore, ResetCause};
    use shared_protocol::link::plc::section_crc;
    use shared_protocol::program::Program;
    use shared_protocol::program::{
        assemble_into, decode_slot, encode_slot, verify_drive, DRIVE_LINES, LINE_BYTES,
    };
    use shared_protocol::safety::{SafetySetting as S, SafetySettings};
    use static_cell::StaticCell;

    pub const CALLS: u32 = 1000;

    const MOTOR: &str = "000 PWF Q00\n001 LD K00 0000\n002 LD K01 2333\n003 LD Q01\n\
        004 LD Q02\n005 PI K02 1000\n006 WR Q01\n007 Rs= K03 0195\n008 Uc= K04 0030\n\
        009 Iz= K05 0050\n010 =dU\n011 fmn K06 0050\n012 fjm K07 0500\n013 fmx K08 0700\n\
        014 U> K09 0035\n015 U< K10 0025\n016 I> K11 0200\n017 LD Q01\n018 LD Q01\n\
        019 LD K12 0000\n020 SN1\n021 LD K13 1200\n022 SN2\n023 LD K14 2400\n024 SN3\n\
        025 frv K20 0200\n";

    #[no_mangle]
    #[inline(never)]
    pub extern "C" fn bench_mark(id: u32) {
        black_box(id);
    }

    static PROGRAM: StaticCell<Program> = StaticCell::new();
    static MONITOR: StaticCell<Monitor> = StaticCell::new();
    static CORE: StaticCell<DriveCore> = StaticCell::new();

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let program = PROGRAM.init(Program::default());
        let _ = assemble_into(MOTOR, program);
        let core = CORE.init(DriveCore::new(DriveConfig::default(), ResetCause::PowerOn));
        core.tick_1ms(&mut |_| {});
        let _ = core.load_program(&program.drive_section());
        let _ = core.command(DriveCommand::SetQ {
            addr: 0,
            value: 16000,
        });
        let _ = core.command(DriveCommand::SetQ {
            addr: 1,
            value: 400,
        });
        let _ = core.command(DriveCommand::SetQ {
            addr: 2,
            value: 400,
        });
        let _ = core.command(DriveCommand::Run);
        // 0.4 s: the 2.333 s lag has passed fmn (5 Hz), the outputs are on.
        for _ in 0..400 {
            core.tick_1ms(&mut |_| {});
        }
        // The interrupt reaches the core through a pointer it loads (`Shared`'s
        // `&'static mut DriveApp`), not through an address known at link time: without this
        // the compiler rematerialises the static's address (movw/movt) at each field access
        // in the loops, which the image never does (+40 instructions per call, depending on
        // what else `main` holds).
        let core: &mut DriveCore = black_box(core);
        let s = AdcSample {
            i_a: 2100,
            i_b: 2000,
            u_dc: 2730,
            aux: 1234,
        };
        let mut acc = 0u32;
        let mut enabled = 0u32;
        bench_mark(1);
        for _ in 0..CALLS {
            let c = core.pwm_period(black_box(&s));
            acc = acc.wrapping_add(u32::from(c.duty[0]));
            enabled += u32::from(c.enable);
        }
        bench_mark(2);
        black_box(acc);
        // Section 0x10 = every call had the outputs on (0x11 = not: the figure is void).
        bench_mark(if enabled == CALLS { 0x10 } else { 0x11 });
        let _ = core.command(DriveCommand::Stop);
        core.tick_1ms(&mut |_| {});
        bench_mark(3);
        for _ in 0..CALLS {
            let c = core.pwm_period(black_box(&s));
            acc = acc.wrapping_add(u32::from(c.duty[0]));
        }
        bench_mark(4);
        let _ = core.command(DriveCommand::Run);
        bench_mark(5);
        for _ in 0..10 {
            core.tick_1ms(&mut |e| {
                black_box(e);
            });
        }
        bench_mark(6);
        black_box(acc);
        // Section 7: 1000 x the period's action from a running command (compares clamped,
        // the blanking window's CCR5), as `DriveApp::pwm_period` builds it after the core.
        let _ = core.command(DriveCommand::Run);
        let t = core.pwm_timing();
        let c = core.pwm_period(&s);
        let mut blank = 0u32;
        bench_mark(7);
        for _ in 0..CALLS {
            let a = PeriodAction::from_command(black_box(&c), black_box(&t), black_box(&t));
            let a = black_box(a);
            blank = blank.wrapping_add(u32::from(a.blanking) + u32::from(a.ccr[2]));
        }
        bench_mark(8);
        black_box(blank);
        // The end of a download, part by part: the section CRC, the slot
        // decoding, the verifier, the core's load (which verifies again).
        let section = program.drive_section();
        let mut bytes = [0u8; DRIVE_LINES * LINE_BYTES];
        for (dst, line) in bytes.chunks_exact_mut(LINE_BYTES).zip(section.lines.iter()) {
            dst.copy_from_slice(&encode_slot(line.as_ref()));
        }
        bench_mark(20);
        black_box(section_crc(black_box(&bytes)));
        bench_mark(21);
        let mut decoded = 0u32;
        for b in bytes.chunks_exact(LINE_BYTES) {
            decoded += u32::from(matches!(decode_slot(black_box(b)), Ok(Some(_))));
        }
        black_box(decoded);
        bench_mark(22);
        black_box(verify_drive(black_box(&section)).is_ok());
        bench_mark(23);
        let _ = core.command(DriveCommand::Stop);
        black_box(core.load_program(black_box(&section)).is_ok());
        bench_mark(24);
        // The safety monitor: every function requested but STO.
        let mut settings = SafetySettings::default();
        for (k, v) in [
            (S::Fss, 40u16),
            (S::Pss, 200),
            (S::Trd, 50),
            (S::Tel, 50),
            (S::Ts1, 100),
            (S::Ts2, 100),
            (S::Fl1, 160),
            (S::Fl2, 100),
            (S::Fl3, 100),
            (S::Fl4, 100),
            (S::Tl1, 100),
            (S::Tl2, 100),
            (S::Tl3, 100),
            (S::Tl4, 100),
            (S::Pli, 100),
            (S::Tli, 100),
            (S::Ard, 20),
            (S::Aap, 2000),
            (S::Adp, 2000),
            (S::Aan, 2000),
            (S::Adn, 2000),
            (S::Asr, 50),
        ] {
            settings.set(k, Some(v));
        }
        let monitor = MONITOR.init(Monitor::new(&settings));
        monitor.start_run();
        let input = SafetyInput {
            requested: 0x0FFE,
            f_dhz: 20,
            fmn_dhz: 10,
            reverse: false,
        };
        let mut trips = 0u32;
        bench_mark(30);
        for _ in 0..CALLS {
            trips += u32::from(monitor.tick(black_box(input)).trip.is_some());
        }
        bench_mark(31 + u32::from(trips > 0));
        bench_mark(33);
        black_box(monitor.tick(black_box(SafetyInput {
            requested: 0x0FFF,
            ..input
        })));
        bench_mark(34);
        bench_mark(0xFFFF_FFFF);
        loop {
            cortex_m::asm::nop();
        }
    }
}
