//! Unit tests of every PLC instruction on small programs built in code.

use super::*;
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts};
use Mnemonic as M;
use Operand as X;

type Line = (Mnemonic, Option<Operand>, u16);

fn l(m: Mnemonic, x: Operand) -> Line {
    (m, Some(x), 0)
}
fn k(m: Mnemonic, label: u8, value: u16) -> Line {
    (m, Some(X::K(label)), value)
}
fn n(m: Mnemonic) -> Line {
    (m, None, 0)
}

/// Appends lines that copy S0..S(depth-1) into B80.. (pop with `CTU Q63`).
fn dump_stack(lines: &mut Vec<Line>, depth: u8) {
    for i in 0..depth {
        lines.push(l(M::Wr, X::B(80 + i)));
        lines.push(l(M::Ctu, X::Q(63)));
    }
}

struct Rig {
    vm: PlcVm,
    prog: Program,
    inputs: ScanInputs,
    now: u32,
    out: ScanOutputs,
}

impl Rig {
    fn new(lines: &[Line]) -> Rig {
        let mut prog = Program::default();
        for (i, &(mnemonic, operand, constant)) in lines.iter().enumerate() {
            prog.lines[150 + i] = Some(Instruction {
                mnemonic,
                operand,
                constant,
            });
        }
        let mut vm = PlcVm::new();
        vm.start(Millis(0));
        Rig {
            vm,
            prog,
            inputs: ScanInputs::default(),
            now: 0,
            out: ScanOutputs::default(),
        }
    }
    fn scan(&mut self) -> ScanOutputs {
        self.vm
            .scan(&self.prog, &self.inputs, Millis(self.now), &mut self.out);
        self.out
    }
    fn scan_at(&mut self, t: u32) -> ScanOutputs {
        self.now = t;
        self.scan()
    }
    fn d(&mut self, i: u8, v: bool) {
        if v {
            self.inputs.digital |= 1 << i;
        } else {
            self.inputs.digital &= !(1 << i);
        }
    }
    fn stack(&self, depth: u8) -> Vec<bool> {
        (0..depth).map(|i| self.vm.b(80 + i)).collect()
    }
}

#[test]
fn ld_bit_pushes_and_drops_bit_15() {
    // Push D00=1 first, then 16 zeros: the 1 falls off the 16-bit stack.
    let mut lines = vec![l(M::Ld, X::D(0))];
    for _ in 0..15 {
        lines.push(l(M::Ld, X::B(0)));
    }
    // After 16 pushes the 1 is S15; one more drops it.
    let mut lines_kept = lines.clone();
    dump_stack(&mut lines_kept, 16);
    let mut r = Rig::new(&lines_kept);
    r.d(0, true);
    r.scan();
    let s = r.stack(16);
    assert!(s[15], "the first push is S15 after 16 pushes");
    assert!(s[..15].iter().all(|b| !b));

    lines.push(l(M::Ld, X::B(0)));
    dump_stack(&mut lines, 16);
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan();
    assert!(
        r.stack(16).iter().all(|b| !b),
        "bit 15 is lost on the 17th push"
    );
}

#[test]
fn ld_reads_every_bit_operand() {
    let mut lines = vec![
        l(M::Ld, X::D(7)),
        l(M::Ld, X::B(5)),
        l(M::Ld, X::Rdy),
        l(M::Ld, X::Flb),
        l(M::Ld, X::O(2)),
    ];
    dump_stack(&mut lines, 5);
    lines.push(l(M::Ldc, X::B(99)));
    lines.push(l(M::Wr, X::O(2)));
    lines.push(l(M::Wr, X::B(5)));
    let mut r = Rig::new(&lines);
    r.d(7, true);
    r.inputs.drive.ready = true;
    r.inputs.drive.fault_latched = false;
    r.scan();
    // Top first: O02 (0 on the first scan), FLB 0, RDY 1, B05 0, D07 1.
    assert_eq!(r.stack(5), vec![false, false, true, false, true]);
    // Second scan sees O02 and B05 as the first scan left them.
    r.inputs.drive.ready = false;
    r.inputs.drive.fault_latched = true;
    r.scan();
    assert_eq!(r.stack(5), vec![true, true, false, true, true]);
}

#[test]
fn ldc_pushes_complement() {
    let mut lines = vec![l(M::Ldc, X::D(1)), l(M::Ldc, X::D(2))];
    dump_stack(&mut lines, 2);
    let mut r = Rig::new(&lines);
    r.d(1, true);
    r.scan();
    assert_eq!(r.stack(2), vec![true, false]);
}

#[test]
fn ld_int_operands_replace_p_without_touching_s() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Ld, X::A(3)),
        n(M::Lcd),
        k(M::Ld, 7, 9999),
        n(M::Lcd),
        l(M::Ld, X::Com),
        n(M::Lcd),
        l(M::Ld, X::Frq),
        n(M::Lcd),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.inputs.analog = [1, 2, 3, 4000];
    r.inputs.drive.com = 512;
    r.inputs.drive.frq = Decihertz(-250);
    let out = r.scan();
    assert_eq!(out.lcd, [Some(1023), Some(9999), Some(512), Some(-250)]);
    assert!(out.output(0), "int loads leave S0 alone");
}

#[test]
fn ld_extension_int_operands() {
    let lines = vec![
        l(M::Ld, X::Udc),
        n(M::Lcd),
        l(M::Ld, X::Imx),
        n(M::Lcd),
        l(M::Ld, X::Flt),
        n(M::Lcd),
        l(M::Ld, X::Dir),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    r.inputs.drive.udc = Decivolts(321);
    r.inputs.drive.imx = CentiAmps(150);
    r.inputs.drive.flt = 4;
    r.inputs.drive.dir_reverse = true;
    assert_eq!(r.scan().lcd, [Some(321), Some(150), Some(4), Some(1)]);
}

#[test]
fn ld_hardware_thresholds() {
    // The source's commissioning display of its trimmers, without DIP switches.
    let lines = vec![l(M::Ld, X::Ihw), n(M::Lcd), l(M::Ld, X::Uhw), n(M::Lcd)];
    let mut r = Rig::new(&lines);
    r.inputs.drive.ihw = CentiAmps(300);
    r.inputs.drive.uhw = shared_protocol::units::Volts(40);
    assert_eq!(r.scan().lcd, [Some(300), Some(40), None, None]);
}

#[test]
fn ld_q_reads_the_plc_copy() {
    let lines = vec![
        l(M::Ldc, X::B(0)),
        k(M::Ld, 0, 1234),
        l(M::Wr, X::Q(9)),
        k(M::Ld, 1, 0),
        l(M::Ld, X::Q(9)),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    assert_eq!(r.scan().lcd[0], Some(1234));
    assert_eq!(r.vm.q(9), 1234);
}

#[test]
fn ld_vlt_and_amp_convert_p() {
    let lines = vec![
        l(M::Ld, X::Com),
        l(M::Ld, X::Vlt),
        n(M::Lcd),
        l(M::Ld, X::Com),
        l(M::Ld, X::Amp),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    r.inputs.drive.com = 1023;
    assert_eq!(r.scan().lcd[..2], [Some(450), Some(99)]);
    r.inputs.drive.com = 0;
    assert_eq!(r.scan().lcd[..2], [Some(0), Some(-100)]);
}

#[test]
fn wr_and_wrc_on_bits() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Wr, X::O(1)),
        l(M::Wrc, X::O(2)),
        l(M::Wr, X::B(10)),
        l(M::Wrc, X::B(11)),
    ];
    let mut r = Rig::new(&lines);
    let out = r.scan();
    assert_eq!(out.outputs, 0b100);
    assert!(!r.vm.b(10) && r.vm.b(11));
    r.d(0, true);
    let out = r.scan();
    assert_eq!(out.outputs, 0b010);
    assert!(r.vm.b(10) && !r.vm.b(11));
}

#[test]
fn wr_q_is_conditional_and_reported() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        k(M::Ld, 0, 100),
        l(M::Wr, X::Q(1)),
        k(M::Ld, 1, 200),
        l(M::Wrc, X::Q(2)),
    ];
    let mut r = Rig::new(&lines);
    let out = r.scan();
    assert_eq!(out.q_dirty, 1 << 2);
    assert_eq!((r.vm.q(1), r.vm.q(2)), (0, 200));
    assert_eq!(out.dirty_q().collect::<Vec<_>>(), vec![2]);
    r.d(0, true);
    let out = r.scan();
    assert_eq!(out.q_dirty, 1 << 1);
    assert_eq!((r.vm.q(1), r.vm.q(2)), (100, 200));
}

#[test]
fn q_written_twice_reports_newest_value() {
    let lines = vec![
        l(M::Ldc, X::B(0)),
        k(M::Ld, 0, 5),
        l(M::Wr, X::Q(63)),
        k(M::Ld, 1, 6),
        l(M::Wr, X::Q(63)),
    ];
    let mut r = Rig::new(&lines);
    let out = r.scan();
    assert_eq!(out.q_dirty, 1 << 63);
    assert_eq!(r.vm.q(63), 6);
}

#[test]
fn not_flips_only_s0() {
    let mut lines = vec![l(M::Ld, X::D(0)), l(M::Ld, X::D(1)), n(M::Not)];
    dump_stack(&mut lines, 2);
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan();
    assert_eq!(r.stack(2), vec![true, true]);
}

#[test]
fn binary_logic_truth_tables() {
    // S1 = D00 (s), S0 = D01 (t); result on O00, and the stack below must move up.
    type Truth = fn(bool, bool) -> bool;
    let cases: [(Mnemonic, Truth); 5] = [
        (M::And, |s, t| s & t),
        (M::Or, |s, t| s | t),
        (M::Xor, |s, t| s ^ t),
        (M::Anc, |s, t| s & !t),
        (M::Orc, |s, t| s | !t),
    ];
    for (m, f) in cases {
        let mut lines = vec![
            l(M::Ld, X::D(2)),
            l(M::Ld, X::D(0)),
            l(M::Ld, X::D(1)),
            n(m),
        ];
        dump_stack(&mut lines, 3);
        let mut r = Rig::new(&lines);
        r.d(2, true);
        for s in [false, true] {
            for t in [false, true] {
                r.d(0, s);
                r.d(1, t);
                r.scan();
                assert_eq!(r.stack(3), vec![f(s, t), true, false], "{m:?} s={s} t={t}");
            }
        }
    }
}

#[test]
fn let_detects_rising_edges_but_not_on_first_scan() {
    let lines = vec![l(M::Ld, X::D(0)), l(M::Let, X::B(0)), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    assert!(!r.scan().output(0), "no edge on the first scan");
    assert!(r.vm.b(0), "first scan stores S0");
    assert!(!r.scan().output(0));
    r.d(0, false);
    assert!(!r.scan().output(0));
    r.d(0, true);
    assert!(r.scan().output(0), "rising edge");
    assert!(!r.scan().output(0), "one scan only");
}

#[test]
fn let_after_ldc_detects_falling_edges() {
    let lines = vec![l(M::Ldc, X::D(0)), l(M::Let, X::B(0)), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    assert!(!r.scan().output(0));
    r.d(0, false);
    assert!(r.scan().output(0));
    assert!(!r.scan().output(0));
}

#[test]
fn let_first_scan_with_input_low_then_high_is_an_edge() {
    let lines = vec![l(M::Ld, X::D(0)), l(M::Let, X::B(0)), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    assert!(!r.scan().output(0));
    r.d(0, true);
    assert!(r.scan().output(0));
}

#[test]
fn io_toggles_when_s0_set() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Io, X::B(1)),
        l(M::Io, X::O(3)),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.scan();
    assert!(!r.vm.b(1));
    r.d(0, true);
    let out = r.scan();
    assert!(r.vm.b(1) && out.output(3));
    assert!(out.output(0), "S unchanged by I/O");
    let out = r.scan();
    assert!(!r.vm.b(1) && !out.output(3));
}

#[test]
fn set_and_res() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Set, X::B(3)),
        l(M::Set, X::O(4)),
        l(M::Ld, X::D(1)),
        l(M::Res, X::B(3)),
        l(M::Res, X::O(4)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    assert!(r.scan().output(4) && r.vm.b(3));
    r.d(0, false);
    assert!(r.scan().output(4) && r.vm.b(3), "kept without input");
    r.d(1, true);
    assert!(!r.scan().output(4) && !r.vm.b(3));
}

#[test]
fn compare_overwrites_s0_without_push() {
    for (m, expect) in [
        (M::Eq, [false, true, false]),
        (M::Gt, [false, false, true]),
        (M::Lt, [true, false, false]),
    ] {
        let mut lines = vec![
            l(M::Ldc, X::B(0)),
            l(M::Ld, X::D(0)),
            l(M::Ld, X::A(0)),
            k(m, 1, 500),
        ];
        dump_stack(&mut lines, 2);
        let mut r = Rig::new(&lines);
        for (a, e) in [499, 500, 501].into_iter().zip(expect) {
            r.inputs.analog[0] = a;
            r.scan();
            assert_eq!(r.stack(2), vec![e, true], "{m:?} {a}");
        }
    }
}

#[test]
fn compare_with_q() {
    let lines = vec![
        l(M::Ldc, X::B(0)),
        l(M::Ld, X::A(0)),
        l(M::Wr, X::Q(4)),
        k(M::Ld, 0, 7),
        l(M::Gt, X::Q(4)),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.inputs.analog[0] = 6;
    assert!(r.scan().output(0));
    r.inputs.analog[0] = 7;
    assert!(!r.scan().output(0));
}

#[test]
fn ctu_counts_level_and_resets() {
    let mut lines = vec![
        l(M::Ld, X::B(50)),
        l(M::Ld, X::D(0)),
        l(M::Ld, X::D(1)),
        l(M::Ctu, X::Q(5)),
    ];
    dump_stack(&mut lines, 2);
    let mut r = Rig::new(&lines);
    r.d(0, true);
    for i in 1..=3 {
        let out = r.scan();
        assert_eq!(r.vm.q(5), i);
        assert_eq!(
            out.q_dirty & (1 << 5),
            0,
            "counters change the PLC copy only"
        );
    }
    // After the pop, S0 is the count input and S1 what lay below it.
    assert_eq!(r.stack(2), vec![true, false]);
    r.d(0, false);
    r.scan();
    assert_eq!(r.vm.q(5), 3);
    r.d(1, true);
    r.d(0, true);
    r.scan();
    assert_eq!(r.vm.q(5), 0, "reset wins");
}

#[test]
fn ctd_counts_down_and_saturates() {
    let lines = vec![
        l(M::Ldc, X::B(0)),
        k(M::Ld, 0, 0),
        l(M::Sub, X::Q(60)), // P = -Q60 ... build -32767 below
        k(M::Sub, 1, 9999),
        k(M::Sub, 2, 9999),
        k(M::Sub, 3, 9999),
        k(M::Sub, 4, 2770),
        l(M::Ld, X::D(0)),
        l(M::Wr, X::Q(7)),
        l(M::Ldc, X::B(0)),
        l(M::Ld, X::B(0)),
        l(M::Ctd, X::Q(7)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan();
    // Q7 = -32767 then counted down once to -32768.
    assert_eq!(r.vm.q(7), -32768);
    r.d(0, false);
    r.scan();
    assert_eq!(r.vm.q(7), -32768, "saturates");
}

#[test]
fn ctu_saturates_at_max() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        k(M::Ld, 0, 9999),
        k(M::Mul, 1, 9),
        l(M::Wr, X::Q(8)),
        l(M::Ldc, X::B(0)),
        l(M::Ld, X::B(0)),
        l(M::Ctu, X::Q(8)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan();
    assert_eq!(r.vm.q(8), i16::MAX);
}

#[test]
fn ctu_with_one_bit_loaded_counts_it() {
    // A lone bit (the source's LCD example) is the count input, not a reset.
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Ctu, X::Q(1)),
        l(M::Ld, X::D(0)),
        l(M::Ld, X::D(1)),
        n(M::And),
        l(M::Ctd, X::Q(2)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan();
    r.scan();
    assert_eq!(r.vm.q(1), 2);
    assert_eq!(r.vm.q(2), 0, "AND result 0: no count");
    r.d(1, true);
    r.scan();
    assert_eq!(r.vm.q(1), 3);
    assert_eq!(r.vm.q(2), -1, "an AND result is one bit: counted");
}

#[test]
fn ctu_with_two_bits_loaded_uses_s0_as_reset() {
    let lines = vec![
        l(M::Ld, X::D(1)),
        l(M::Ld, X::D(0)),
        l(M::Ctu, X::Q(1)),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.d(1, true);
    r.scan();
    assert_eq!(r.vm.q(1), 1);
    r.d(0, true);
    let out = r.scan();
    assert_eq!(r.vm.q(1), 0);
    assert!(out.output(0), "after the pop S0 is the count input");
}

#[test]
fn ton_with_k_preset() {
    let lines = vec![l(M::Ld, X::D(0)), k(M::Ton, 1, 100), l(M::Wr, X::O(4))];
    let mut r = Rig::new(&lines);
    assert!(!r.scan_at(0).output(4));
    r.d(0, true);
    assert!(!r.scan_at(5).output(4));
    assert!(!r.scan_at(10_004).output(4));
    assert!(r.scan_at(10_005).output(4));
    r.d(0, false);
    assert!(!r.scan_at(10_006).output(4));
}

#[test]
fn timer_preset_from_q_is_read_each_scan() {
    let lines = vec![
        l(M::Ldc, X::B(0)),
        l(M::Ld, X::A(0)),
        l(M::Wr, X::Q(3)),
        l(M::Ld, X::D(0)),
        l(M::Ton, X::Q(3)),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.inputs.analog[0] = 50; // 5 s
    r.d(0, true);
    assert!(!r.scan_at(0).output(0));
    assert!(!r.scan_at(3000).output(0));
    r.inputs.analog[0] = 20; // 2 s: already elapsed
    assert!(r.scan_at(3001).output(0));
}

#[test]
fn tof_with_k_preset() {
    let lines = vec![l(M::Ld, X::D(0)), k(M::Tof, 1, 10), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    assert!(!r.scan_at(0).output(0));
    r.d(0, true);
    assert!(r.scan_at(10).output(0));
    r.d(0, false);
    assert!(r.scan_at(20).output(0));
    assert!(r.scan_at(1019).output(0));
    assert!(!r.scan_at(1020).output(0));
}

#[test]
fn imp_pulse_and_first_scan() {
    let lines = vec![l(M::Ld, X::D(0)), k(M::Imp, 1, 70), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    assert!(!r.scan_at(0).output(0), "no edge on the first scan");
    r.d(0, false);
    assert!(!r.scan_at(10).output(0));
    r.d(0, true);
    assert!(r.scan_at(20).output(0));
    r.d(0, false);
    assert!(r.scan_at(7019).output(0));
    assert!(!r.scan_at(7020).output(0));
}

#[test]
fn each_timer_line_has_its_own_state() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        k(M::Ton, 1, 10),
        l(M::Wr, X::O(0)),
        l(M::Ld, X::D(1)),
        k(M::Ton, 2, 10),
        l(M::Wr, X::O(1)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan_at(0);
    r.d(1, true);
    r.scan_at(500);
    let out = r.scan_at(1000);
    assert!(out.output(0) && !out.output(1));
    assert!(r.scan_at(1500).output(1));
}

#[test]
fn arithmetic_saturates() {
    let lines = vec![
        k(M::Ld, 0, 9999),
        k(M::Mul, 1, 9999),
        n(M::Lcd),
        k(M::Add, 2, 1),
        n(M::Lcd),
        k(M::Ld, 3, 0),
        k(M::Sub, 4, 9999),
        k(M::Mul, 5, 9999),
        n(M::Lcd),
        k(M::Sub, 6, 5),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    assert_eq!(
        r.scan().lcd,
        [Some(32767), Some(32767), Some(-32768), Some(-32768)]
    );
}

#[test]
fn arithmetic_with_q_operand() {
    let lines = vec![
        l(M::Ldc, X::B(0)),
        k(M::Ld, 0, 7),
        l(M::Wr, X::Q(0)),
        k(M::Ld, 1, 100),
        l(M::Add, X::Q(0)),
        n(M::Lcd),
        l(M::Sub, X::Q(0)),
        l(M::Sub, X::Q(0)),
        n(M::Lcd),
        l(M::Mul, X::Q(0)),
        n(M::Lcd),
        l(M::Div, X::Q(0)),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    assert_eq!(r.scan().lcd, [Some(107), Some(93), Some(651), Some(93)]);
}

#[test]
fn div_truncates_and_div0_warns_and_goes_on() {
    let lines = vec![
        k(M::Ld, 0, 0),
        k(M::Sub, 1, 7),
        k(M::Div, 2, 2),
        n(M::Lcd),
        k(M::Div, 3, 0),
        n(M::Lcd),
        k(M::Ld, 4, 9),
        k(M::Div, 5, 0),
        k(M::Add, 6, 3),
        n(M::Lcd),
        l(M::Ldc, X::B(0)),
        l(M::Wr, X::O(5)),
    ];
    let mut r = Rig::new(&lines);
    let out = r.scan();
    assert_eq!(out.lcd[..3], [Some(-3), Some(0), Some(3)]);
    assert_eq!(out.warning, Some(Warning::Div0 { line: 154 }), "first one");
    assert!(out.output(5), "the scan went on");
}

#[test]
fn lcd_fills_four_fields_and_ignores_a_fifth() {
    let mut lines = vec![];
    for i in 0..5u8 {
        lines.push(k(M::Ld, i, u16::from(i) + 10));
        lines.push(n(M::Lcd));
    }
    let mut r = Rig::new(&lines);
    assert_eq!(r.scan().lcd, [Some(10), Some(11), Some(12), Some(13)]);
    let mut r = Rig::new(&lines[..4]);
    assert_eq!(r.scan().lcd, [Some(10), Some(11), None, None]);
}

#[test]
fn rev_reports_first_request_then_only_changes() {
    let lines = vec![l(M::Ld, X::D(0)), n(M::Rev)];
    let mut r = Rig::new(&lines);
    assert_eq!(
        r.scan().rev_request,
        Some(false),
        "the first REV after RUN syncs the drive"
    );
    assert_eq!(r.scan().rev_request, None);
    r.d(0, true);
    assert_eq!(r.scan().rev_request, Some(true));
    assert_eq!(r.scan().rev_request, None);
    r.d(0, false);
    assert_eq!(r.scan().rev_request, Some(false));
    assert_eq!(r.scan().rev_request, None);
}

#[test]
fn rev_reports_again_after_a_new_run() {
    let lines = vec![l(M::Ldc, X::B(0)), n(M::Rev)];
    let mut r = Rig::new(&lines);
    assert_eq!(r.scan().rev_request, Some(true));
    assert_eq!(r.scan().rev_request, None);
    r.vm.start(Millis(5));
    assert_eq!(r.scan().rev_request, Some(true), "a new RUN reports again");
}

#[test]
fn rev_last_in_scan_wins_and_no_rev_reports_nothing() {
    // Two REV lines disagreeing in one scan: the last one is the request.
    let lines = vec![l(M::Ldc, X::B(0)), n(M::Rev), l(M::Ld, X::B(0)), n(M::Rev)];
    let mut r = Rig::new(&lines);
    assert_eq!(r.scan().rev_request, Some(false));
    assert_eq!(r.scan().rev_request, None);
    // A REV that is not reached (empty program) reports nothing.
    let mut r = Rig::new(&[l(M::Ld, X::D(0))]);
    assert_eq!(r.scan().rev_request, None);
}

#[test]
fn ack_on_rising_edge_only() {
    let lines = vec![l(M::Ld, X::D(0)), n(M::Ack), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    let out = r.scan();
    assert!(!out.ack_request, "no edge on the first scan");
    assert!(out.output(0), "S unchanged");
    r.d(0, false);
    assert!(!r.scan().ack_request);
    r.d(0, true);
    assert!(r.scan().ack_request);
    assert!(!r.scan().ack_request);
}

#[test]
fn alm_reports_its_code_on_a_rising_edge_only() {
    let lines = vec![l(M::Ld, X::D(0)), k(M::Alm, 0, 12), l(M::Wr, X::O(0))];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    let out = r.scan();
    assert_eq!(out.alarm, None, "no edge on the first scan");
    assert!(out.output(0), "S unchanged");
    r.d(0, false);
    assert_eq!(r.scan().alarm, None);
    r.d(0, true);
    assert_eq!(r.scan().alarm, Some(12));
    assert_eq!(r.scan().alarm, None, "held: one report per edge");
}

#[test]
fn a_second_alm_edge_in_the_same_scan_is_reported_in_the_next() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        k(M::Alm, 0, 12),
        k(M::Alm, 1, 13),
        l(M::Ld, X::D(1)),
        k(M::Alm, 2, 14),
    ];
    let mut r = Rig::new(&lines);
    r.scan();
    r.d(0, true);
    assert_eq!(r.scan().alarm, Some(12));
    assert_eq!(r.scan().alarm, Some(13), "its edge was kept");
    assert_eq!(r.scan().alarm, None);
    // An edge that is gone by the next scan is not reported.
    r.d(0, false);
    r.scan();
    r.d(0, true);
    r.d(1, true);
    assert_eq!(r.scan().alarm, Some(12));
    r.d(0, false);
    r.d(1, false);
    assert_eq!(r.scan().alarm, None);
}

#[test]
fn start_clears_memory_and_timers() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Set, X::B(7)),
        l(M::Set, X::O(5)),
        k(M::Ld, 0, 42),
        l(M::Wr, X::Q(42)),
        k(M::Ton, 1, 10),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    r.scan_at(0);
    assert!(r.scan_at(1000).output(0));
    assert!(r.vm.b(7) && r.vm.q(42) == 42 && r.vm.output(5));
    r.vm.start(Millis(2000));
    assert!(r.vm.is_first_scan());
    assert!(!r.vm.b(7) && r.vm.q(42) == 0 && !r.vm.output(5));
    r.d(0, false);
    r.scan_at(2000);
    assert!(!r.vm.is_first_scan());
    r.d(0, true);
    assert!(!r.scan_at(2001).output(0), "timer restarted");
}

#[test]
fn s_and_p_start_every_scan_at_zero() {
    let lines = vec![
        k(M::Add, 0, 5),
        n(M::Lcd),
        l(M::Wr, X::O(0)),
        l(M::Ldc, X::B(0)),
    ];
    let mut r = Rig::new(&lines);
    r.scan();
    let out = r.scan();
    assert_eq!(out.lcd[0], Some(5));
    assert!(!out.output(0));
}

#[test]
fn drive_lines_and_drive_mnemonics_do_nothing_in_the_plc() {
    let mut r = Rig::new(&[k(M::Pwf, 0, 1000), n(M::Sn1), l(M::Wr, X::Pw1)]);
    r.prog.lines[10] = Some(Instruction {
        mnemonic: M::Ldc,
        operand: Some(X::B(0)),
        constant: 0,
    });
    r.prog.lines[11] = Some(Instruction {
        mnemonic: M::Wr,
        operand: Some(X::O(0)),
        constant: 0,
    });
    let out = r.scan();
    assert_eq!(out, ScanOutputs::default());
}

#[test]
fn out_of_range_operands_are_ignored() {
    let lines = vec![
        l(M::Ldc, X::D(16)),
        l(M::Ldc, X::B(200)),
        l(M::Wr, X::O(8)),
        l(M::Wr, X::Q(64)),
        l(M::Ld, X::A(4)),
        l(M::Ctu, X::Q(99)),
        l(M::Let, X::B(100)),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    let out = r.scan();
    assert_eq!(out.outputs, 0);
    assert_eq!(out.q_dirty, 0);
    assert_eq!(out.lcd[0], Some(0));
}

// ---- safety functions (safety.md 5) ------------------------------------------------

use shared_protocol::safety::SafetyFunction as F;

#[test]
fn sfr_requests_while_its_control_bit_is_0_and_reports_changes_only() {
    // D00 = curtain clear (1 = not requested): LD D00 / SFR SS1, S unchanged after it.
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Sfr, X::Sf(F::Ss1)),
        l(M::Wr, X::O(0)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    let out = r.scan();
    assert_eq!(
        out.sf_request, None,
        "all 1 = nothing requested, as at RUN start"
    );
    assert!(out.output(0), "S unchanged");
    r.d(0, false);
    assert_eq!(r.scan().sf_request, Some(F::Ss1.mask()));
    assert_eq!(r.scan().sf_request, None);
    r.d(0, true);
    assert_eq!(r.scan().sf_request, Some(0));
    // A broken wire reads 0: requested (closed-circuit principle).
    r.d(0, false);
    assert_eq!(r.scan().sf_request, Some(F::Ss1.mask()));
    // A new RUN: every control bit back to 1; the first scan reports the request again.
    r.vm.start(Millis(10));
    assert_eq!(r.scan().sf_request, Some(F::Ss1.mask()));
}

#[test]
fn the_last_sfr_of_a_function_wins_and_functions_are_independent() {
    let lines = vec![
        l(M::Ld, X::D(0)),
        l(M::Sfr, X::Sf(F::Sto)),
        l(M::Sfr, X::Sf(F::Sla)),
        l(M::Ldc, X::D(0)),
        l(M::Sfr, X::Sf(F::Sto)),
    ];
    let mut r = Rig::new(&lines);
    r.d(0, true);
    // STO: the second SFR (S0 = !D00 = 0) requests it; SLA follows D00 (not requested).
    assert_eq!(r.scan().sf_request, Some(F::Sto.mask()));
    r.d(0, false);
    assert_eq!(r.scan().sf_request, Some(F::Sla.mask()));
}

#[test]
fn status_bits_sdc_the_stopwatch_and_the_position_are_read_only_operands() {
    let lines = vec![
        l(M::Ld, X::Sf(F::Sos)),
        l(M::Wr, X::O(0)),
        l(M::Ldc, X::Sf(F::Sl2)),
        l(M::Wr, X::O(1)),
        l(M::Ld, X::Sdc),
        l(M::Wr, X::O(2)),
        l(M::Ld, X::Sft),
        n(M::Lcd),
        l(M::Ld, X::Sfp),
        n(M::Lcd),
    ];
    let mut r = Rig::new(&lines);
    r.inputs.drive.sf_status = F::Sos.mask() | F::Sl2.mask();
    r.inputs.drive.sf_sdc = true;
    r.inputs.drive.sf_elapsed_ds = 150;
    r.inputs.drive.sf_turns = -99;
    let out = r.scan();
    assert_eq!(out.outputs & 0b111, 0b101);
    assert_eq!(out.lcd[0], Some(150));
    assert_eq!(out.lcd[1], Some(-99));
    r.inputs.drive = DriveView {
        sf_elapsed_ds: u16::MAX,
        ..DriveView::default()
    };
    let out = r.scan();
    assert_eq!(out.outputs & 0b111, 0b010);
    assert_eq!(out.lcd[0], Some(i16::MAX), "saturates");
}
