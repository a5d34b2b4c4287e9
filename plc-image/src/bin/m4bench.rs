//! Cortex-M4 instruction count of the PLC scan, without a board (see
//! `/work/shared/tools/README.md` and `plc-vm/docs/vm.md`):
//!
//! ```text
//! cargo build --profile firmware --target thumbv7em-none-eabihf --bin m4bench -p plc-image
//! python3 ../shared/tools/m4count.py target/thumbv7em-none-eabihf/firmware/m4bench
//! ```
//!
//! Sections (each [`SCANS`] scans of a full 850-line PLC section): 1 = mixed program,
//! 2 = timers only, 3 = empty program (loop overhead), 4.. = one instruction kind on
//! every line (see `KINDS`). Section 0 is set-up between them. Divide by [`SCANS`] for
//! one scan, and by 850 for one executed instruction. The last section (12) is one
//! compile of the mixed program, what RUN costs once (`PlcVm::start_program`).
//! The service port (section 13 on): 13 = [`SERVICE_BYTES`] bytes of a random flood into
//! `Service::on_rx` (per received byte), 14 = one `GetStatus` request frame into `on_rx`
//! (the byte path plus the decode at its delimiter), 15 = encoding the largest `Status`
//! answer (the transmit side of a frame).
//! 16 = [`SCANS`] scans of `shared-protocol/programs/lift.plc` during its initialisation
//! run (safety chain and door closed, no vane, no call: the car travels down to floor 1),
//! from `data/lift.slots` (every line's 4 stored bytes; the host test
//! `m4bench_lift_slots_are_lift_plc` keeps the file equal to the program).
#![no_std]
#![no_main]

/// Scans per measured section.
const SCANS: u32 = 4;
/// Flood bytes in section 13.
const SERVICE_BYTES: usize = 1000;

mod target {
    use super::{SCANS, SERVICE_BYTES};
    use core::hint::black_box;
    use defmt_rtt as _;
    use embassy_stm32 as _; // vector table
    use panic_probe as _;

    use firmware_plc::vm::sample::{mixed_program, timer_program};
    use firmware_plc::vm::{PlcVm, ScanInputs, ScanOutputs};
    use shared_protocol::program::{Instruction, Mnemonic as M, Operand as X, Program};
    use shared_protocol::units::Millis;

    /// Sections 4..: `LD D`, `AND`, `LD A`, `ADD K`, `WR B`, `TON K`, `LCD`, `LET B`.
    const KINDS: [(M, Option<X>, u16); 8] = [
        (M::Ld, Some(X::D(1)), 0),
        (M::And, None, 0),
        (M::Ld, Some(X::A(1)), 0),
        (M::Add, Some(X::K(1)), 5),
        (M::Wr, Some(X::B(3)), 0),
        (M::Ton, Some(X::K(1)), 5),
        (M::Lcd, None, 0),
        (M::Let, Some(X::B(4)), 0),
    ];

    #[no_mangle]
    #[inline(never)]
    pub extern "C" fn bench_mark(id: u32) {
        black_box(id);
    }

    #[inline(never)]
    fn scans(vm: &mut PlcVm, program: &Program, out: &mut ScanOutputs, t0: u32) {
        let mut inputs = ScanInputs::default();
        for i in 0..SCANS {
            inputs.digital = black_box(i as u16 ^ 0xA55A);
            inputs.analog = [black_box(600), 200, 512, 3];
            vm.scan(black_box(program), &inputs, Millis(t0 + i * 10), out);
            black_box(&*out);
        }
    }

    fn program(id: u32) -> Program {
        match id {
            1 => mixed_program(),
            2 => timer_program(),
            3 => Program::default(),
            _ => {
                let mut p = Program::default();
                if let Some(&(mnemonic, operand, constant)) = KINDS.get(id as usize - 4) {
                    for line in p.lines.iter_mut().skip(150) {
                        *line = Some(Instruction {
                            mnemonic,
                            operand,
                            constant,
                        });
                    }
                }
                p
            }
        }
    }

    /// Section 16: scans of `lift.plc` in its initialisation run.
    #[inline(never)]
    fn lift(vm: &mut PlcVm, out: &mut ScanOutputs, program: &mut Program) {
        use shared_protocol::program::{decode_slot, LINE_BYTES};
        static SLOTS: &[u8] = include_bytes!("data/lift.slots");
        for (line, b) in program.lines.iter_mut().zip(SLOTS.chunks(LINE_BYTES)) {
            *line = decode_slot(b).ok().flatten();
        }
        // D12 door closed, D15 safety chain closed; the drive reports RUN, no fault.
        let mut inputs = ScanInputs {
            digital: (1 << 12) | (1 << 15),
            ..ScanInputs::default()
        };
        inputs.drive.ready = true;
        vm.start_program(program, Millis(0));
        for i in 0..50 {
            vm.scan(black_box(&*program), &inputs, Millis(i * 10), out);
        }
        bench_mark(16);
        for i in 50..50 + SCANS {
            vm.scan(
                black_box(&*program),
                black_box(&inputs),
                Millis(i * 10),
                out,
            );
            black_box(&*out);
        }
        bench_mark(0);
    }

    /// Sections 13-15: the service port's receive path per byte and per frame, and the
    /// encoding of its largest answer.
    #[inline(never)]
    fn service() {
        use firmware_plc::app::BuildInfo;
        use firmware_plc::service::Service;
        use shared_protocol::link::MAX_WIRE_FRAME;
        use shared_protocol::service::{
            encode, Answer, DriveInfo, LinkView, PlcState, Request, RunWarning, Status,
        };
        use shared_protocol::units::Micros;

        let mut svc = Service::new(BuildInfo {
            firmware: "0.1.0",
            git: "bench",
            uid: [0; 12],
        });
        let mut flood = [0u8; SERVICE_BYTES];
        let mut x = 0x2545_F491u32;
        for b in flood.iter_mut() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *b = x as u8;
        }
        bench_mark(13);
        svc.on_rx(black_box(&flood), Micros(1000));
        bench_mark(0);
        let mut frame = [0u8; MAX_WIRE_FRAME];
        let n = encode(7, Request::GetStatus, &mut frame).unwrap_or(0);
        bench_mark(14);
        svc.on_rx(black_box(frame.get(..n).unwrap_or(&[])), Micros(2000));
        bench_mark(0);
        black_box(&svc);
        let status = Status {
            plc: PlcState::Starting,
            remote: true,
            link: LinkView::VersionMismatch {
                drive_version: u16::MAX,
            },
            drive: Some(DriveInfo {
                state: shared_protocol::link::DriveState::Fault,
                fault: 255,
                freq_dhz: i16::MIN,
                reverse: true,
                udc_dv: i16::MIN,
                imax_ca: i16::MIN,
                com: u16::MAX,
            }),
            d: u16::MAX,
            o: u8::MAX,
            a: [u16::MAX; 4],
            lcd: [Some(i16::MIN); 4],
            warning: Some(RunWarning::Div0 { line: 999 }),
            newest_log: Some((31, 255)),
            scan_last_us: u32::MAX,
            scan_max_us: u32::MAX,
            uptime_ms: u64::MAX,
            slot: Some(4),
            unsaved: true,
        };
        let mut out = [0u8; MAX_WIRE_FRAME];
        bench_mark(15);
        let n = encode(7, Answer::Status(black_box(status)), &mut out).unwrap_or(0);
        bench_mark(0);
        black_box((n, &out));
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let mut vm = PlcVm::new();
        let mut out = ScanOutputs::default();
        for id in 1..=3 + KINDS.len() as u32 {
            let program = program(id);
            vm.start(Millis(0));
            // Scans outside the section first: the first scan takes the first-scan paths.
            scans(&mut vm, &program, &mut out, 0);
            bench_mark(id);
            scans(&mut vm, &program, &mut out, 1000);
            bench_mark(0);
        }
        let mut program = mixed_program();
        bench_mark(3 + KINDS.len() as u32 + 1);
        vm.start_program(black_box(&program), Millis(0));
        bench_mark(0);
        black_box(&vm);
        service();
        // The mixed program's storage is reused: a second `Program` (~8 KiB) on the stack
        // overflows the bench's RAM.
        lift(&mut vm, &mut out, &mut program);
        bench_mark(0xFFFF_FFFF);
        loop {
            cortex_m::asm::nop();
        }
    }
}
