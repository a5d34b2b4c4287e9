//! Faults of the silicon on the real images:
//! the scenario's silicon keys (`vdd_v`, `flash_ecc_error`, `sram_parity_error`,
//! `i2c_fault`) drive g431-emu's models of the system break sources, the NMI and the I2C
//! bus.

use g431_emu::cpu::CpuEvent;
use g431_emu::periph::flash::{Flash, OPTR_FACTORY, OPTR_SRAM_PE};
use g431_emu::periph::rcc::ResetKind;
use hil_sim::emu::sim::EmuSim;

use crate::common::{emu, ns, outputs_enabled, MOTOR_PLC};

/// The motor program at 50 Hz (pot A01 = 500), switching at 9.8 kHz (A00 = 980), and the
/// silicon event `fault` at 1.5 s.
fn start_50hz_then(fault: &str) -> String {
    format!(
        r#"
[[event]]
at_s = 0.0
set = {{ A00 = 980, A01 = 500 }}

[[event]]
at_s = 0.3
press = "D00"

{fault}
"#
    )
}

/// Resets of the drive after power-up.
fn drive_resets(sim: &EmuSim) -> Vec<CpuEvent> {
    sim.drive()
        .events()
        .iter()
        .filter(|e| matches!(e, CpuEvent::Reset { at, .. } if *at > 0))
        .cloned()
        .collect()
}

/// What N4 asks of the drive after a system break at 1.5 s: the outputs open at once (in
/// hardware), and the image stays alive and reports a fault: no watchdog reset, no hang in
/// a handler, status frames still flowing with a fault code.
fn assert_system_break_handled(sim: &mut EmuSim, what: &str) {
    sim.run_until(ns(1.5) - 1_000, |_| {});
    assert!(outputs_enabled(sim), "{what}: running before the fault");
    sim.run_until(ns(1.5) + 1_000, |_| {});
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(
        !g.moe && !g.outputs_enabled,
        "{what}: the system break opened the outputs: {g:?}"
    );
    // Where the core is 50 ms later (2 = NMI, 16 + n = interrupt n).
    sim.run_until(ns(1.55), |_| {});
    let ipsr_50ms = sim.drive().soc().ipsr;
    let sbif = sim.drive().soc().system_break_sources();
    sim.run_until(ns(2.5), |_| {});
    let resets = drive_resets(sim);
    let wdg = resets.iter().any(|e| {
        matches!(
            e,
            CpuEvent::Reset {
                why: ResetKind::Watchdog,
                ..
            }
        )
    });
    let ipsr = sim.drive().soc().ipsr;
    let log: Vec<String> = sim
        .drive()
        .log()
        .iter()
        .rev()
        .take(8)
        .map(|l| l.message.clone())
        .collect();
    assert!(
        resets.is_empty(),
        "{what}: the drive was reset (watchdog: {wdg}) instead of reporting the fault: \
         {resets:?}; 50 ms after the fault the core was in exception {ipsr_50ms} with the \
         system break held by {sbif:?}; exception now {ipsr}; last log lines {log:?}"
    );
    assert!(
        !outputs_enabled(sim),
        "{what}: the outputs came back on by themselves"
    );
    let st = sim.status().expect("status frames from the drive");
    assert!(
        st.fault.is_some(),
        "{what}: the drive reports no fault after the system break: {st:?}; active \
         exception {ipsr}; faults {:?}",
        sim.faults()
    );
}

/// N4, PVD: the supply dips to 2.6 V (below the 2.75 V the image programs, PLS = 101) for
/// 50 ms. SYSCFG_CFGR2.PVDL routes PVDO to TIM1's system break: SBIF, not BIF (RM0440
/// TIMx_SR). The image's break handler reports SBIF as `BOOT` and masks it until re-armed.
#[test]
fn a_pvd_dip_while_running_opens_the_outputs_and_is_reported() {
    let mut sim = emu(
        MOTOR_PLC,
        &start_50hz_then(
            "[[event]]\nat_s = 1.5\nvdd_v = 2.6\n\n[[event]]\nat_s = 1.55\nvdd_v = 3.3\n",
        ),
    );
    assert_system_break_handled(&mut sim, "PVD");
}

/// N4, flash double ECC: an NMI (RM0440 FLASH_ECCR.ECCD) and, with ECCL, a system break.
#[test]
fn a_flash_double_ecc_error_while_running_opens_the_outputs_and_is_reported() {
    let mut sim = emu(
        MOTOR_PLC,
        &start_50hz_then("[[event]]\nat_s = 1.5\nflash_ecc_error = true\n"),
    );
    assert_system_break_handled(&mut sim, "flash ECC");
}

/// N4, SRAM parity, on the documented board: a factory-fresh G431 has the SRAM parity check
/// off (FLASH_OPTR.SRAM_PE = 1, RM0440 FLASH_OPTR; the factory value 0xFFEF_F8AA), and the
/// images do not program option bytes, so a parity error is never detected: no NMI, no
/// system break, the motor runs on. This part of N4 cannot happen on the board as shipped.
#[test]
fn with_factory_option_bytes_an_sram_parity_error_is_not_detected() {
    let mut sim = emu(
        MOTOR_PLC,
        &start_50hz_then("[[event]]\nat_s = 1.5\nsram_parity_error = true\n"),
    );
    sim.run_until(ns(2.0), |_| {});
    assert!(outputs_enabled(&sim), "the motor runs on");
    assert!(!sim.drive().soc().syscfg().parity_error(), "SPF stays 0");
    assert!(drive_resets(&sim).is_empty(), "{:?}", drive_resets(&sim));
    assert!(sim.faults().is_empty(), "{:?}", sim.faults());
}

/// N4, SRAM parity with the check enabled in the option bytes (SRAM_PE = 0, as a
/// production line could program them): an NMI and, with SPL, a system break.
#[test]
fn with_the_parity_check_on_an_sram_parity_error_opens_the_outputs_and_is_reported() {
    let mut sim = emu(
        MOTOR_PLC,
        &start_50hz_then("[[event]]\nat_s = 1.5\nsram_parity_error = true\n"),
    );
    let soc = sim.drive_mut().soc_mut();
    let k = soc.slot_of("FLASH").expect("FLASH");
    if let Some(f) = soc.model_mut::<Flash>(k) {
        *f = Flash::new(OPTR_FACTORY & !OPTR_SRAM_PE);
    }
    assert_system_break_handled(&mut sim, "SRAM parity");
}

/// RUN left to the keys; `C` `2` at 1 s saves the program into slot 2, and again at 3 s.
/// At 0.9 s the EEPROM is set to hold SCL low for 30 ms in the next write transfer to it
/// (the 64-byte page writes of the first save): longer than the image's 20 ms transaction
/// timeout (`i2c_bus::TRANSACTION_TIMEOUT_MS`).
const SAVE_WITH_A_STRETCH: &str = r#"
[[event]]
at_s = 30.0
keys = "A"

[[event]]
at_s = 0.9
i2c_fault = "stretch"
i2c_stretch_ms = 30.0

[[event]]
at_s = 1.0
keys = "C2"

[[event]]
at_s = 3.0
keys = "C2"
"#;

/// A short program for the saves.
const SMALL_PROGRAM: &str = "150 LD  D00\n151 WR  B00\n";

/// N12: embassy's blocking master returns `Timeout` from `wait_tc` without a STOP and
/// without resetting the peripheral, which keeps BUSY: every later transaction waits for
/// the bus and times out. After the timed-out save the bus must be usable again: the
/// second save reaches the EEPROM and the LCD shows it.
#[test]
fn an_i2c_timeout_in_a_save_leaves_the_bus_usable_for_the_next_save_and_the_lcd() {
    let mut sim = emu(SMALL_PROGRAM, SAVE_WITH_A_STRETCH);
    sim.run_until(ns(2.5), |_| {});
    let stats = sim.plc().soc().i2c(2).expect("I2C3").stats();
    assert_eq!(
        stats.injected_faults, 1,
        "the stretch hit a transfer: {stats:?}"
    );
    let writes_before = sim.eeprom().writes();
    sim.run_until(ns(6.0), |_| {});
    let lcd: Vec<String> = (0..4).map(|r| sim.lcd().row(r)).collect();
    let log: Vec<String> = sim
        .plc()
        .log()
        .iter()
        .map(|l| l.message.clone())
        .filter(|m| m.contains("storage") || m.contains("i2c") || m.contains("lcd"))
        .collect();
    let stats = sim.plc().soc().i2c(2).expect("I2C3").stats();
    assert!(
        sim.eeprom().writes() > writes_before,
        "the second save wrote nothing to the EEPROM; I2C3 {stats:?}; LCD {lcd:#?}; log \
         {log:#?}"
    );
    assert!(
        lcd.iter().any(|r| r.contains("SAVED")),
        "the LCD does not show the second save: {lcd:#?}; log {log:#?}"
    );
}

/// Both images: at 170 MHz RM0440 requires range 1 boost mode (PWR_CR5.R1MODE
/// = 0; range 1 normal mode allows 150 MHz at most, §6.1.5) and 4 flash wait states
/// (§3.3.3). `board-common/src/clocks.rs` asks embassy for boost, and embassy-stm32 0.6's
/// `rcc/g4.rs` writes `PWR.cr5().modify(|w| w.set_r1mode(false))`; but stm32-metapac 21
/// (generated from ST's SVD, like the `stm32g4` PAC) puts R1MODE at bit 0, where RM0440's
/// PWR_CR5 description and ST's CMSIS header (`PWR_CR5_R1MODE_Pos` = 8, reset value
/// 0x0000_0100) put it at bit 8. The write clears a reserved bit and leaves R1MODE at 1:
/// both images ran 170 MHz in range 1 normal mode, out of specification. The images now
/// use a vendored embassy-stm32 whose G4 set-up writes PWR_CR5 whole (and keeps the AHB /2
/// step across the switch, `vendor/README.md`). The model follows RM0440
/// (bit 8) and reports a switch above 150 MHz in normal mode.
#[test]
fn both_images_run_170_mhz_in_boost_mode_with_4_wait_states_and_the_prefetch() {
    use g431_emu::soc::Diagnostic;
    let mut sim = emu(MOTOR_PLC, "");
    sim.run_until(ns(0.3), |_| {});
    for m in [sim.drive(), sim.plc()] {
        let name = &m.name;
        let boost = m.soc().pwr().map(|p| p.boost());
        let clocks: Vec<String> = m
            .diagnostics()
            .iter()
            .filter_map(|d| match d {
                Diagnostic::Model(x)
                    if x.contains("HCLK") || x.contains("RCC_CFGR") || x.contains("LATENCY") =>
                {
                    Some(x.clone())
                }
                _ => None,
            })
            .collect();
        assert_eq!(m.soc().rcc().hclk_hz(), Some(170_000_000), "{name}");
        assert_eq!(
            m.soc().flash_if().map(|f| f.latency()),
            Some(4),
            "{name}: wait states"
        );
        // The prefetch on (FLASH_ACR.PRFTEN, bit 8; embassy never sets it).
        let acr = m.soc().flash_acr();
        assert!(
            acr & (1 << 8) != 0,
            "{name}: FLASH_ACR {acr:#x}, prefetch off"
        );
        assert!(
            clocks
                .iter()
                .all(|c| !c.contains("allows") && !c.contains("requires")),
            "{name}: boost mode {boost:?} (PWR_CR5.R1MODE, bit 8); {clocks:#?}"
        );
    }
}
