//! Property tests of the power-stage invariants (drive.md "Safety of the power stage",
//! program.md 4.3) over random programs, commands and measurements.

use firmware_drive::modulator::dead_time_safe;
use firmware_drive::restart::class_bit;
use firmware_drive::{
    AdcSample, DriveCommand, DriveConfig, DriveCore, DriveEvent, DriveState, FaultCode, HwBreak,
    PwmCommand, ResetCause,
};
use proptest::prelude::*;
use shared_protocol::program::{
    constant_range, mnemonics_for, operands_for, verify_drive, DriveSection, Instruction, Operand,
    Section,
};

#[path = "support/ramp_profile.rs"]
mod ramp_profile;
use ramp_profile::{ramp_profile, ramp_segments};

/// A valid drive line: mnemonic, operand and constant chosen from the verifier's own
/// tables; Q operands folded onto Q00-Q03 so that the random commands hit them.
fn instruction() -> impl Strategy<Value = Instruction> {
    let ms: Vec<_> = mnemonics_for(Section::Drive).collect();
    (0..ms.len(), any::<u16>(), any::<u16>()).prop_map(move |(mi, oi, c)| {
        let m = ms[mi];
        let ops: Vec<_> = operands_for(m, Section::Drive).collect();
        let operand = ops[usize::from(oi) % ops.len()].map(|o| match o {
            Operand::Q(n) => Operand::Q(n % 4),
            o => o,
        });
        let constant = match constant_range(m, Section::Drive, operand) {
            Some(r) => r.start() + c % (r.end() - r.start() + 1),
            None => 0,
        };
        Instruction {
            mnemonic: m,
            operand,
            constant,
        }
    })
}

/// A random section, often with a running three-phase sine on Q01 so that the outputs
/// are actually on in many cases.
fn program() -> impl Strategy<Value = DriveSection> {
    (
        prop::collection::vec((0u16..150, instruction()), 0..25),
        any::<bool>(),
    )
        .prop_map(|(lines, with_sine)| {
            let mut s = DriveSection::default();
            if with_sine {
                let text = "100 LD Q01\n101 LD Q01\n102 LD K00 0000\n103 SN1\n\
                    104 LD K01 1200\n105 SN2\n106 LD K02 2400\n107 SN3\n";
                let p = shared_protocol::program::assemble(text).unwrap();
                s = p.drive_section();
            }
            for (n, i) in lines {
                s.lines[usize::from(n)] = Some(i);
            }
            shared_protocol::program::testing::fix_drive_stack(&mut s.lines);
            shared_protocol::program::testing::fix_safety(&mut s.lines);
            assert!(verify_drive(&s).is_ok());
            s
        })
}

fn sample() -> impl Strategy<Value = AdcSample> {
    prop_oneof![
        // Nominal: small currents, 30 V.
        4 => (1900u16..2200, 1900u16..2200, 2600u16..2800, 0u16..4096),
        // Anything the ADC can return.
        1 => (0u16..4096, 0u16..4096, 0u16..4096, 0u16..4096),
    ]
    .prop_map(|(i_a, i_b, u_dc, aux)| AdcSample {
        i_a,
        i_b,
        u_dc,
        aux,
    })
}

#[derive(Debug, Clone)]
enum Op {
    Periods(u8, AdcSample),
    Tick,
    Cmd(DriveCommand),
    Trip(FaultCode),
    Break(HwBreak),
    Release(HwBreak),
    Load(Box<DriveSection>),
}

fn op() -> impl Strategy<Value = Op> {
    let cause = prop_oneof![Just(HwBreak::Overcurrent), Just(HwBreak::Overvoltage)];
    prop_oneof![
        20 => (1u8..40, sample()).prop_map(|(n, s)| Op::Periods(n, s)),
        20 => Just(Op::Tick),
        3 => Just(Op::Cmd(DriveCommand::Run)),
        1 => Just(Op::Cmd(DriveCommand::Stop)),
        2 => Just(Op::Cmd(DriveCommand::Ack)),
        4 => (0u8..4, -200i16..1200).prop_map(|(addr, value)| Op::Cmd(DriveCommand::SetQ { addr, value })),
        1 => any::<bool>().prop_map(|reverse| Op::Cmd(DriveCommand::Direction { reverse })),
        1 => prop_oneof![Just(FaultCode::Link), Just(FaultCode::Oc)].prop_map(Op::Trip),
        1 => cause.clone().prop_map(Op::Break),
        1 => cause.prop_map(Op::Release),
        1 => program().prop_map(|p| Op::Load(Box::new(p))),
    ]
}

/// The sine of `program()` with its protections, running at `f` from the start.
fn running_sine(f: i16) -> Vec<Op> {
    vec![
        Op::Cmd(DriveCommand::SetQ { addr: 1, value: f }),
        Op::Cmd(DriveCommand::Run),
        Op::Tick,
    ]
}

fn check_sequence(first: DriveSection, ops: Vec<Op>) -> Result<(), TestCaseError> {
    let cfg = DriveConfig::default();
    let min = cfg.min_pulse_counts;
    let mut core = DriveCore::new(cfg, ResetCause::PowerOn);
    let mut sink = |_e: DriveEvent| {};
    core.tick_1ms(&mut sink);
    let _ = core.load_program(&first);
    // A fault has latched since the last accepted RUN: outputs must stay off.
    let mut latched_since_run = false;
    let mut f_prev_tick = 0i16;
    // The PLC's latest direction request, and its value at the last tick that started at
    // standstill (f = 0 in the previous tick) until the outputs next come on.
    let mut requested = false;
    let mut start_dir: Option<bool> = None;
    let mut was_enabled = false;
    for op in ops {
        match op {
            Op::Periods(n, s) => {
                for _ in 0..n {
                    let before = core.state();
                    let settings = *core.vm().settings();
                    let c = core.pwm_period(&s);
                    let nn = c.period_counts;
                    prop_assert_eq!(nn, core.pwm_timing().arr);
                    for d in c.duty {
                        prop_assert!(d <= nn);
                        prop_assert!(
                            d == 0 || d == nn || (d > min && d < nn - min),
                            "{} of {}",
                            d,
                            nn
                        );
                    }
                    if !c.enable {
                        prop_assert_eq!(c.duty, [0; 3]);
                    }
                    // After any stop, the first period with the outputs on runs in the
                    // direction requested when the drive restarted from standstill.
                    if c.enable && !was_enabled {
                        if let Some(dir) = start_dir.take() {
                            prop_assert_eq!(core.modulator().params().swap_1_2, dir);
                        }
                    }
                    was_enabled = c.enable;
                    if core.fault().is_some() {
                        latched_since_run = true;
                    }
                    if c.enable {
                        prop_assert_eq!(core.state(), DriveState::Run);
                        prop_assert!(!latched_since_run);
                    }
                    // Trip conditions of this very sample.
                    let ia = (i32::from(s.i_a) - 2048).abs() * 1000;
                    let ib = (i32::from(s.i_b) - 2048).abs() * 1000;
                    let lim = i32::from(settings.i_max_centiamps) * 2048;
                    if before == DriveState::Run && settings.i_max_centiamps > 0 && ia.max(ib) > lim
                    {
                        prop_assert!(!c.enable);
                        prop_assert!(core.fault().is_some());
                    }
                    // 4095 counts / 45 V = 91 counts per volt exactly.
                    let uv_limit = 91 * u32::from(settings.u_min_volts);
                    if settings.u_min_volts > 0 && u32::from(s.u_dc) < uv_limit {
                        prop_assert!(!c.enable);
                    }
                }
            }
            Op::Tick => {
                let latched = core.fault().filter(|_| core.state() == DriveState::Fault);
                let classes = core.vm().settings().restart.classes;
                let mut reversed = None;
                core.tick_1ms(&mut |e| {
                    if let DriveEvent::Reversed(d) = e {
                        reversed = Some(d);
                    }
                });
                let restarted = latched.filter(|_| core.state() != DriveState::Fault);
                if let Some(code) = restarted {
                    // An automatic restart (a random section may set `arc`): only a
                    // class it names.
                    prop_assert!(class_bit(code) & classes != 0, "{:?} restarted", code);
                    latched_since_run = false;
                }
                let st = core.status();
                let f = st.f_command.0;
                let standstill = f_prev_tick == 0;
                if standstill {
                    // program.md 4.2 / lift.md 2.2: a pending request applies at once.
                    prop_assert_eq!(st.reverse, requested, "standstill, f now {}", f);
                    start_dir = Some(requested);
                } else {
                    start_dir = None;
                }
                if !standstill && reversed.is_some() {
                    let (frv, fmn) = (core.vm().settings().frv, core.vm().settings().fmn);
                    // Below frv, or below fmn where the outputs are off.
                    prop_assert!(f < frv || f < fmn, "reversed at f {} >= frv {}", f, frv);
                    // 002 4.2: only when the command rises again, at standstill or below fmn
                    // (outputs off); never above fmn at a steady speed or while it falls.
                    prop_assert!(
                        f == 0 || f > f_prev_tick || f < fmn,
                        "reversed while not rising {} -> {}",
                        f_prev_tick,
                        f
                    );
                }
                f_prev_tick = f;
                if restarted.is_some() {
                    // The RUN it returns to starts from standstill, as after a RUN.
                    f_prev_tick = 0;
                }
            }
            Op::Cmd(c) => {
                let before = core.state();
                let ok = core.command(c).is_ok();
                if c == DriveCommand::Run && ok && before != DriveState::Run {
                    // A RUN starts from standstill.
                    latched_since_run = false;
                    f_prev_tick = 0;
                }
                if let DriveCommand::Direction { reverse } = c {
                    requested = reverse;
                }
            }
            Op::Trip(f) => core.trip(f),
            Op::Break(b) => core.hardware_break(b),
            Op::Release(b) => core.hardware_break_released(b),
            Op::Load(p) => {
                let _ = core.load_program(&p);
            }
        }
        if core.fault().is_some() {
            latched_since_run = true;
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn outputs_stay_safe_for_any_program_commands_and_measurements(
        first in program(),
        ops in prop::collection::vec(op(), 1..300),
    ) {
        check_sequence(first, ops)?;
    }

    /// Same, starting with the outputs on (sine at 5..100 Hz with U<, I> set), so that most
    /// trips happen while switching.
    #[test]
    fn trips_while_switching_turn_the_outputs_off_in_the_same_period(
        f in 50i16..1000,
        ops in prop::collection::vec(op(), 1..200),
    ) {
        let text = "000 LD Q01\n001 LD Q01\n002 LD K00 0000\n003 SN1\n004 LD K01 1200\n005 SN2\n\
            006 LD K02 2400\n007 SN3\n008 U< K03 0025\n009 I> K04 0300\n010 U> K05 0038\n\
            011 fmn K06 0050\n012 frv K07 0200\n";
        let first = shared_protocol::program::assemble(text).unwrap().drive_section();
        let mut all = running_sine(f);
        all.extend(ops);
        check_sequence(first, all)?;
    }

    /// Complementary outputs of one leg with dead time, tick by tick over several
    /// centre-aligned periods whose duties change at every update event: the high and low
    /// switch are never on together, and no reference pulse is shorter than the minimum.
    #[test]
    fn complementary_outputs_never_shoot_through(
        n in 12u16..300,
        dead in 1u32..40,
        min in 0u16..6,
        raw in prop::collection::vec(0u16..320, 1..12),
    ) {
        let mut reference = Vec::new();
        for d in &raw {
            let duty = dead_time_safe(*d, n, min);
            prop_assert!(duty <= n);
            let cmd = PwmCommand {
                enable: true,
                leg_enable: [true; 3],
                duty: [duty; 3],
                period_counts: n,
                brake: false,
            };
            let ccr = u32::from(cmd.ccr()[0]);
            // Up-down counter 0..ARR..0 (2 * ARR ticks); PWM mode 1: active while
            // CNT < CCR, held active when CCR > ARR (RM0440).
            for t in 0..2 * u32::from(n) {
                let cnt = if t < u32::from(n) { t } else { 2 * u32::from(n) - t };
                reference.push(ccr > u32::from(n) || cnt < ccr);
            }
        }
        // Dead-time generator: a switch turns on `dead` ticks after its reference edge.
        let (mut hi_run, mut lo_run) = (0u32, 0u32);
        for r in &reference {
            if *r { hi_run += 1; lo_run = 0; } else { lo_run += 1; hi_run = 0; }
            let high_on = hi_run > dead;
            let low_on = lo_run > dead;
            prop_assert!(!(high_on && low_on));
        }
        // Pulse widths (runs not touching the ends of the record). A pulse inside one period
        // that does not touch an update event is a whole duty: at least 2 * min + 1 ticks (the clamp's rule). A pulse at an
        // update event joins the old duty's trailing half (CCR - 1 ticks) to the new duty's
        // leading half (CCR ticks), so a step from min + 1 to 0 leaves min ticks, half a
        // minimum pulse: the bound drive-core.md states for duty changes.
        let period = 2 * u32::from(n);
        let mut start = 0u32;
        for (i, w) in reference.windows(2).enumerate() {
            let end = i as u32 + 1; // first tick of the next run
            if w[0] == w[1] {
                continue;
            }
            if start > 0 {
                let len = end - start;
                // Touching an update event (the counter's valley, where a new CCR loads).
                let at_update = start.is_multiple_of(period)
                    || end.is_multiple_of(period)
                    || start / period != (end - 1) / period;
                let bound = if at_update { u32::from(min) } else { 2 * u32::from(min) + 1 };
                prop_assert!(
                    len >= bound,
                    "pulse of {} ticks at {} (at an update: {}) with min {}",
                    len, start, at_update, min
                );
            }
            start = end;
        }
    }
}

/// Any section of lines the per-line rules accept, stack use not fixed up.
fn raw_section() -> impl Strategy<Value = DriveSection> {
    prop::collection::vec(
        shared_protocol::program::testing::line_in(Section::Drive),
        0..40,
    )
    .prop_map(|lines| {
        let mut s = DriveSection::default();
        for (n, i) in lines {
            s.lines[usize::from(n)] = Some(i);
        }
        // A setting set twice is the other whole-section rule: not this test's.
        shared_protocol::program::testing::fix_safety(&mut s.lines);
        s
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// The verifier's stack count is what the VM does. A section the verifier
    /// accepts never runs an instruction with fewer values than it needs, and one it
    /// rejects for the stack does, at the line it names.
    #[test]
    fn no_accepted_section_underflows_at_run_time(s in raw_section()) {
        use firmware_drive::vm::DriveVm;
        use shared_protocol::program::VerifyErrorKind;
        let mut vm = DriveVm::new(16_000);
        vm.load(&s);
        for _ in 0..3 {
            vm.run(&s, &mut |_| {});
        }
        match verify_drive(&s) {
            Ok(()) => prop_assert_eq!(vm.stack_underflows(), 0),
            Err(e) => {
                prop_assert!(
                    matches!(e.kind, VerifyErrorKind::StackUnderflow { .. }),
                    "{:?}",
                    e
                );
                prop_assert!(vm.stack_underflows() >= 3);
                // The lines before the one named run without an underflow.
                let mut head = s.clone();
                for l in head.lines.iter_mut().skip(usize::from(e.line)) {
                    *l = None;
                }
                let mut vm = DriveVm::new(16_000);
                vm.run(&head, &mut |_| {});
                prop_assert_eq!(vm.stack_underflows(), 0);
            }
        }
        // The same lines made stack-valid (underflowing lines replaced by a load): the
        // verifier accepts them and they run without an underflow.
        let mut fixed = s.clone();
        shared_protocol::program::testing::fix_drive_stack(&mut fixed.lines);
        prop_assert_eq!(verify_drive(&fixed), Ok(()));
        let mut vm = DriveVm::new(16_000);
        vm.load(&fixed);
        for _ in 0..3 {
            vm.run(&fixed, &mut |_| {});
        }
        prop_assert_eq!(vm.stack_underflows(), 0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The automatic restart (`arc`, `art`, `arn` over their whole ranges): a latched class
    /// never leaves FAULT by itself, whatever the settings; a restartable class that `arc`
    /// names restarts after exactly `art`, at most `arn` times in a row, and the trip after
    /// the last one stays latched.
    #[test]
    fn latched_classes_never_restart_and_a_row_stops_at_arn(
        arc in 0u16..8,
        art in 0u16..20,
        arn in 0u16..4,
        code in prop::sample::select(FaultCode::ALL.to_vec()),
        trips in 1u16..6,
    ) {
        let text = format!(
            "000 LD Q01\n001 LD Q01\n002 LD K00 0000\n003 SN1\n004 LD K01 1200\n005 SN2\n\
             006 LD K02 2400\n007 SN3\n008 U< K03 0025\n009 I> K04 0300\n010 U> K05 0038\n\
             011 fmn K06 0050\n012 arc K07 {arc:04}\n013 art K08 {art:04}\n014 arn K09 {arn:04}\n"
        );
        let p = shared_protocol::program::assemble(&text).unwrap().drive_section();
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let mut sink = |_e: DriveEvent| {};
        let nominal = AdcSample { i_a: 2048, i_b: 2048, u_dc: 2730, aux: 0 };
        let _ = core.pwm_period(&nominal);
        core.tick_1ms(&mut sink);
        core.load_program(&p).unwrap();
        core.command(DriveCommand::Run).unwrap();
        let restartable = class_bit(code) & arc != 0;
        for n in 0..trips {
            prop_assert_eq!(core.state(), DriveState::Run);
            core.trip(code);
            let mut out_after = None;
            for ms in 1..=u32::from(art) * 100 + 50 {
                let _ = core.pwm_period(&nominal);
                core.tick_1ms(&mut sink);
                if core.state() != DriveState::Fault {
                    out_after = Some(ms);
                    break;
                }
            }
            if !restartable || n >= arn {
                prop_assert_eq!(out_after, None, "{:?} restarted (trip {})", code, n);
                return Ok(());
            }
            prop_assert_eq!(out_after, Some((u32::from(art) * 100).max(1)));
            prop_assert_eq!(core.fault(), None);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// 002 4.2 (`frv`) on the core, over random ramps of the commanded frequency (the PLC's
    /// Q01 every millisecond) and random times of the direction requests (before a
    /// ramp-down, during it, at a steady speed, at standstill), with random frv and fmn:
    /// the modulator's phase order never changes while the command is above fmn and not
    /// rising, nor at or above frv, except from standstill (the previous millisecond's
    /// command 0); a request is in effect whenever the command is 0, and one that was
    /// pending while the command fell is in effect at the first rise below frv.
    #[test]
    fn the_phase_order_changes_only_when_the_command_rises_below_frv_or_at_standstill(
        segs in ramp_segments(8),
        requests in prop::collection::vec(0u16..1000, 0..8),
        frv in 1i16..300,
        fmn in 0i16..100,
    ) {
        let text = format!(
            "000 LD Q01\n001 LD Q01\n002 LD K00 0000\n003 SN1\n004 LD K01 1200\n005 SN2\n\
             006 LD K02 2400\n007 SN3\n008 fmn K03 {fmn:04}\n009 frv K04 {frv:04}\n"
        );
        let section = shared_protocol::program::assemble(&text).unwrap().drive_section();
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let mut sink = |_e: DriveEvent| {};
        core.tick_1ms(&mut sink);
        prop_assert!(core.load_program(&section).is_ok());
        prop_assert!(core.command(DriveCommand::Run).is_ok());
        let fs = ramp_profile(&segs);
        let n = fs.len();
        let at: Vec<usize> = requests.iter().map(|r| usize::from(*r) * n / 1000).collect();
        let (mut prev, mut want, mut armed) = (0i16, false, false);
        let mut swapped = core.modulator().params().swap_1_2;
        for (k, &q) in fs.iter().enumerate() {
            for _ in at.iter().filter(|&&t| t == k) {
                want = !want;
                let dir = DriveCommand::Direction { reverse: want };
                prop_assert!(core.command(dir).is_ok());
            }
            let set = DriveCommand::SetQ { addr: 1, value: q };
            prop_assert!(core.command(set).is_ok());
            core.tick_1ms(&mut sink);
            prop_assert_eq!(core.state(), DriveState::Run);
            let f = core.status().f_command.0;
            prop_assert_eq!(f, q);
            let now = core.modulator().params().swap_1_2;
            if now != swapped {
                prop_assert!(
                    prev == 0 || f == 0 || f < fmn || (f > prev && f < frv),
                    "phase order changed at {} ms, command {} -> {} (fmn {}, frv {})",
                    k, prev, f, fmn, frv
                );
            }
            let pending = now != want;
            prop_assert!(f != 0 || !pending, "pending at standstill ({} ms)", k);
            if f > prev {
                prop_assert!(
                    !(armed && f < frv && pending),
                    "still pending at the turning point {} -> {} ({} ms, frv {})",
                    prev, f, k, frv
                );
                armed = false;
            }
            if f < prev {
                armed = pending;
            }
            armed &= pending;
            swapped = now;
            prev = f;
        }
    }
}

/// A line setting one of the limits the drive reports (`fmn`, `fjm`, `fmx`, `frv`, the
/// trips and the hardware levels), any constant the verifier allows.
fn limit_line() -> impl Strategy<Value = (u16, Instruction)> {
    use shared_protocol::program::Mnemonic as M;
    let ms = [
        M::Fmn,
        M::Fjm,
        M::Fmx,
        M::Frv,
        M::IMax,
        M::UMin,
        M::UMax,
        M::IMaxHw,
        M::UMaxHw,
    ];
    (0u16..150, 0..ms.len(), any::<u16>()).prop_map(move |(n, mi, c)| {
        let m = ms[mi];
        let r = constant_range(m, Section::Drive, Some(Operand::K(0))).unwrap();
        (
            n,
            Instruction {
                mnemonic: m,
                operand: Some(Operand::K(0)),
                constant: r.start() + c % (r.end() - r.start() + 1),
            },
        )
    })
}

/// Any stack-valid section, settings anywhere and as often as they fall (so that about
/// half of them set something twice), often with the sine of `program()` on Q01.
fn section_with_settings() -> impl Strategy<Value = DriveSection> {
    (
        prop::collection::vec(
            prop_oneof![3 => (0u16..150, instruction()), 2 => limit_line()],
            0..14,
        ),
        any::<bool>(),
    )
        .prop_map(|(lines, with_sine)| {
            let mut s = DriveSection::default();
            if with_sine {
                let text = "100 LD Q01\n101 LD Q01\n102 LD K00 0000\n103 SN1\n\
                    104 LD K01 1200\n105 SN2\n106 LD K02 2400\n107 SN3\n";
                s = shared_protocol::program::assemble(text)
                    .unwrap()
                    .drive_section();
            }
            for (n, i) in lines {
                s.lines[usize::from(n)] = Some(i);
            }
            shared_protocol::program::testing::fix_drive_stack(&mut s.lines);
            s
        })
}

/// The line of each parameter's first and second setting (`Mnemonic::drive_setting`), in
/// line order.
fn setting_lines(s: &DriveSection) -> Vec<(shared_protocol::program::Mnemonic, u16, Instruction)> {
    (0u16..)
        .zip(s.lines.iter())
        .filter_map(|(n, l)| l.and_then(|i| i.mnemonic.drive_setting().map(|p| (p, n, i))))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    /// Settings once per section (shared-protocol docs/program-format.md): a random
    /// section is either refused, at the second line of a parameter set twice and naming
    /// the first, or the drive reports, in every cycle, the `fmn`/`fjm`/`fmx`/`frv`, trip
    /// limits and hardware levels its lines set (the defaults for those it does not), and
    /// never commands or applies a frequency above the `fmx` it reports.
    #[test]
    fn the_settings_reported_are_the_settings_in_force(
        s in section_with_settings(),
        f in 0i16..2000,
        ticks in 1usize..12,
    ) {
        use firmware_drive::vm::{Settings, FJM_DEFAULT};
        use shared_protocol::program::{Mnemonic as M, VerifyErrorKind};
        let set = setting_lines(&s);
        let twice = set
            .iter()
            .enumerate()
            .find(|(k, (p, _, _))| set[..*k].iter().any(|(q, _, _)| q == p));
        let cfg = DriveConfig::default();
        let mut core = DriveCore::new(cfg, ResetCause::PowerOn);
        let mut sink = |_e: DriveEvent| {};
        core.tick_1ms(&mut sink);
        match (verify_drive(&s), twice) {
            (Err(e), Some((_, (p, second, i)))) => {
                let first = set.iter().find(|(q, _, _)| q == p).unwrap().1;
                prop_assert_eq!(e.line, *second);
                prop_assert_eq!(e.kind, VerifyErrorKind::SettingTwice { mnemonic: i.mnemonic, first });
                prop_assert_eq!(core.load_program(&s), Err(e));
                prop_assert_eq!(core.fault(), Some(FaultCode::Prog));
            }
            (Ok(()), None) => {
                // What each line sets, over the defaults.
                let mut want = Settings::new(cfg.default_pwm_hz);
                for (p, _, i) in &set {
                    let k = i.constant as i16;
                    match p {
                        M::Fmn => want.fmn = k,
                        M::Fjm => want.fjm = if k > 0 { k } else { FJM_DEFAULT },
                        M::Fmx => want.fmx = k,
                        M::Frv => want.frv = k,
                        M::IMax => want.i_max_centiamps = i.constant,
                        M::UMin => want.u_min_volts = i.constant,
                        M::UMax => want.u_max_volts = i.constant,
                        M::IMaxHw => want.oc_hw_centiamps = i.constant,
                        M::UMaxHw => want.ov_hw_volts = i.constant,
                        _ => {}
                    }
                }
                let limits = |s: &Settings| {
                    (s.fmn, s.fjm, s.fmx, s.frv, s.i_max_centiamps, s.u_min_volts,
                     s.u_max_volts, s.oc_hw_centiamps, s.ov_hw_volts)
                };
                prop_assert_eq!(core.load_program(&s), Ok(()));
                let hw = core.hw_thresholds();
                prop_assert_eq!(limits(core.vm().settings()), limits(&want));
                prop_assert_eq!(core.command(DriveCommand::SetQ { addr: 1, value: f }), Ok(()));
                let _ = core.command(DriveCommand::Run);
                let nominal = AdcSample { i_a: 2048, i_b: 2048, u_dc: 2700, aux: 0 };
                for _ in 0..ticks {
                    core.tick_1ms(&mut sink);
                    for _ in 0..3 {
                        let _ = core.pwm_period(&nominal);
                    }
                    let reported = *core.vm().settings();
                    prop_assert_eq!(limits(&reported), limits(&want));
                    prop_assert_eq!(core.hw_thresholds(), hw);
                    let st = core.status();
                    prop_assert!(core.vm().outputs().f <= reported.fmx);
                    prop_assert!(st.f_command.0 <= reported.fmx, "{:?}", st.f_command);
                    prop_assert!(st.f_applied.0 <= reported.fmx, "{:?}", st.f_applied);
                }
            }
            (v, t) => prop_assert!(false, "verifier {:?}, a parameter set twice {:?}", v, t),
        }
    }
}

/// The section of issue 35's item 7, as the drive receives it: refused, `PROG`.
#[test]
fn the_drive_refuses_a_section_that_sets_fmx_twice() {
    let s = shared_protocol::program::assemble(
        "000 FMX K00 0900\n001 LD K00 0800\n002 LD K00 0800\n003 LD K00 0000\n\
         004 SN1\n005 FMX K00 0500\n",
    )
    .unwrap()
    .drive_section();
    let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
    core.tick_1ms(&mut |_| {});
    let e = core.load_program(&s).unwrap_err();
    assert_eq!(e.to_string(), "line 005: fmx set twice (000)");
    assert_eq!(core.fault(), Some(FaultCode::Prog));
    assert_eq!(
        core.command(DriveCommand::Run),
        Err(firmware_drive::DriveRefusal::Faulted)
    );
}
