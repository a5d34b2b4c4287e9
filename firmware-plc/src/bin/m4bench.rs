//! Cortex-M4 instruction count of the PLC scan, without a board (see
//! `/work/shared/tools/README.md` and `docs/vm.md`):
//!
//! ```text
//! cargo build --release --target thumbv7em-none-eabihf --bin m4bench -p firmware-plc
//! python3 ../shared/tools/m4count.py target/thumbv7em-none-eabihf/release/m4bench
//! ```
//!
//! Sections (each [`SCANS`] scans): 1 = mixed 850-line program, 2 = 850 lines of timers,
//! 3 = empty program (loop overhead); section 0 is set-up between them. Divide by
//! [`SCANS`] for one scan.
//! On the host this binary is a stub.
#![cfg_attr(target_os = "none", no_std, no_main)]

/// Scans per measured section.
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
const SCANS: u32 = 4;

#[cfg(target_os = "none")]
mod target {
    use super::SCANS;
    use core::hint::black_box;
    use defmt_rtt as _;
    use embassy_stm32 as _; // vector table
    use panic_probe as _;

    use firmware_plc::vm::sample::{mixed_program, timer_program};
    use firmware_plc::vm::{PlcVm, ScanInputs, ScanOutputs};
    use shared_protocol::program::Program;
    use shared_protocol::units::Millis;

    #[no_mangle]
    #[inline(never)]
    pub extern "C" fn bench_mark(id: u32) {
        black_box(id);
    }

    #[inline(never)]
    fn scans(vm: &mut PlcVm, program: &Program, out: &mut ScanOutputs, t0: u32) {
        let mut inputs = ScanInputs::default();
        for i in 0..SCANS {
            inputs.digital = black_box(i as u8 ^ 0x5A);
            inputs.analog = [black_box(600), 200, 512, 3];
            vm.scan(black_box(program), &inputs, Millis(t0 + i * 10), out);
            black_box(&*out);
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let mut vm = PlcVm::new();
        let mut out = ScanOutputs::default();
        for id in 1..=3 {
            let program = match id {
                1 => mixed_program(),
                2 => timer_program(),
                _ => Program::default(),
            };
            vm.start(Millis(0));
            // Scans outside the section first: the first scan takes the first-scan paths.
            scans(&mut vm, &program, &mut out, 0);
            bench_mark(id);
            scans(&mut vm, &program, &mut out, 1000);
            // Section 0 is set-up, not reported in docs/vm.md.
            bench_mark(0);
        }
        bench_mark(0xFFFF_FFFF);
        loop {
            cortex_m::asm::nop();
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("m4bench runs on the target: see docs/vm.md");
}
