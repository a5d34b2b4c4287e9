//! The first PLC VM, kept as the test oracle of the compiled form (`cfg(test)`, and
//! feature `reference` for the differential fuzz target: the image does not carry it). It interprets the stored [`Program`] lines directly, exactly
//! as the first VM did, before the compiled form (the code below is that interpreter, renamed
//! `ReferenceVm`, with its timer functions below as they were); `differential.rs` runs
//! random programs on both and compares everything a scan produces. It shares only the
//! saturating arithmetic (`arith.rs`) and the input/output types with the VM.

use super::io::{ScanInputs, ScanOutputs, Warning, INPUTS, OUTPUTS, OUTPUT_MASK};
use super::{arith, B_COUNT, PLC_LINES, Q_COUNT};
use shared_protocol::program::{Instruction, Mnemonic, Operand, Program, PLC_FIRST_LINE};
use shared_protocol::units::Millis;
use timer::LineState;

/// Largest value of the 10-bit analog operands (A, COM).
const ADC_MAX: u16 = 1023;

/// The PLC's data memory: what RUN clears and the program reads and writes.
#[derive(Clone)]
struct Memory {
    b: [bool; B_COUNT],
    q: [i16; Q_COUNT],
    /// Output image O00-O07 (bit n = On); kept between scans.
    o: u8,
}

/// The working registers of one scan.
struct Regs {
    /// Bit stack, bit 0 = S0 (top).
    s: u16,
    /// Accumulator ("pomkonst").
    p: i16,
    /// How many bits loaded in this scan are still on S (0..=16); lets `CTU`/`CTD` tell
    /// a lone count input from a count + reset pair.
    depth: u8,
}

impl Regs {
    fn top(&self) -> bool {
        self.s & 1 != 0
    }
    fn push(&mut self, bit: bool) {
        self.s = (self.s << 1) | u16::from(bit);
        self.depth = (self.depth + 1).min(16);
    }
    fn pop(&mut self) {
        self.s >>= 1;
        self.depth = self.depth.saturating_sub(1);
    }
    fn set_top(&mut self, bit: bool) {
        self.s = (self.s & !1) | u16::from(bit);
    }
    /// Pops t = S0 and combines the new S0 with it.
    fn combine(&mut self, op: impl Fn(bool, bool) -> bool) {
        let t = self.top();
        self.pop();
        self.depth = self.depth.max(1);
        let s0 = self.top();
        self.set_top(op(s0, t));
    }
}

/// Read-only context of one scan.
struct Env<'a> {
    inputs: &'a ScanInputs,
    now: Millis,
    first_scan: bool,
}

/// The PLC VM: data memory, per-line timer/edge state, the first-scan flag and the last
/// direction request. About 4.6 KiB, all inline (no allocation). `Clone` gives a
/// snapshot (e.g. for hil-sim).
#[derive(Clone)]
pub struct ReferenceVm {
    mem: Memory,
    /// Per PLC line (index = line - 150): timer/edge flags, see `timer`.
    flags: [u8; PLC_LINES],
    /// Per PLC line: when its timer started.
    since: [Millis; PLC_LINES],
    first_scan: bool,
    /// Direction set by the last `REV` executed in this RUN (`true` = reverse).
    rev_state: Option<bool>,
    /// Direction last reported in [`ScanOutputs::rev_request`]; `None` at RUN start, so
    /// the first `REV` always reports (the drive may hold an earlier RUN's direction).
    rev_reported: Option<bool>,
    /// The safety request mask (`SFR`: bit n set = function n requested) and the one last
    /// reported.
    sf_requested: u16,
    sf_reported: u16,
}

impl Default for ReferenceVm {
    fn default() -> Self {
        Self::new()
    }
}

impl ReferenceVm {
    /// A VM in the state RUN starts from (as after [`ReferenceVm::start`]).
    pub const fn new() -> Self {
        ReferenceVm {
            mem: Memory {
                b: [false; B_COUNT],
                q: [0; Q_COUNT],
                o: 0,
            },
            flags: [0; PLC_LINES],
            since: [Millis(0); PLC_LINES],
            first_scan: true,
            rev_state: None,
            rev_reported: None,
            sf_requested: 0,
            sf_reported: 0,
        }
    }

    /// RUN starts: clears B, Q, the output image and every line's timer/edge state, and
    /// arms the first-scan rule. The first `REV` executed after it reports its direction.
    pub fn start(&mut self, now: Millis) {
        *self = Self::new();
        self.since = [now; PLC_LINES];
    }

    /// The PLC's copy of Qn (0 for n out of range).
    pub fn q(&self, addr: u8) -> i16 {
        self.mem.q.get(usize::from(addr)).copied().unwrap_or(0)
    }

    /// Bit memory Bn (false for n out of range).
    pub fn b(&self, addr: u8) -> bool {
        self.mem.b.get(usize::from(addr)).copied().unwrap_or(false)
    }

    /// Output image On as the last scan left it.
    pub fn output(&self, n: u8) -> bool {
        n < OUTPUTS && self.mem.o & (1 << n) != 0
    }

    /// `true` until the first scan after [`ReferenceVm::start`] has run.
    pub fn is_first_scan(&self) -> bool {
        self.first_scan
    }

    /// One scan: executes lines 150-999 in order with the inputs sampled by the caller at
    /// the start of the scan and `now` from the monotonic ms clock; overwrites `out`.
    ///
    /// S and P start every scan at 0.
    pub fn scan(
        &mut self,
        program: &Program,
        inputs: &ScanInputs,
        now: Millis,
        out: &mut ScanOutputs,
    ) {
        *out = ScanOutputs::default();
        let env = Env {
            inputs,
            now,
            first_scan: self.first_scan,
        };
        let mut regs = Regs {
            s: 0,
            p: 0,
            depth: 0,
        };
        let mut lcd_used = 0usize;
        let plc = program
            .lines
            .get(usize::from(PLC_FIRST_LINE)..)
            .unwrap_or(&[]);
        // A plain index loop keeps S, P and the line pointer in registers on the M4.
        for (idx, slot) in plc.iter().enumerate() {
            if let Some(ins) = slot {
                self.exec(&mut regs, &env, out, &mut lcd_used, ins, idx);
            }
        }
        if self.rev_state.is_some() && self.rev_state != self.rev_reported {
            self.rev_reported = self.rev_state;
            out.rev_request = self.rev_state;
        }
        if self.sf_requested != self.sf_reported {
            self.sf_reported = self.sf_requested;
            out.sf_request = Some(self.sf_requested);
        }
        out.outputs = self.mem.o & OUTPUT_MASK;
        self.first_scan = false;
    }
}

impl ReferenceVm {
    /// Executes one instruction of PLC line `PLC_FIRST_LINE + idx`.
    #[inline(always)]
    fn exec(
        &mut self,
        regs: &mut Regs,
        env: &Env<'_>,
        out: &mut ScanOutputs,
        lcd_used: &mut usize,
        ins: &Instruction,
        idx: usize,
    ) {
        use Mnemonic as M;
        let mem = &mut self.mem;
        let x = ins.operand;
        let k = ins.constant;
        match ins.mnemonic {
            M::Ld => match x {
                Some(Operand::Vlt) => regs.p = arith::vlt(regs.p),
                Some(Operand::Amp) => regs.p = arith::amp(regs.p),
                Some(op) => {
                    if let Some(bit) = read_bit(mem, env, op) {
                        regs.push(bit);
                    } else if let Some(v) = read_int(mem, env, op, k) {
                        regs.p = v;
                    }
                }
                None => {}
            },
            M::Ldc => {
                if let Some(bit) = x.and_then(|op| read_bit(mem, env, op)) {
                    regs.push(!bit);
                }
            }
            M::Wr | M::Wrc => {
                // WR stores S0, WRC its complement; to Q only when that is 1.
                let value = regs.top() == (ins.mnemonic == M::Wr);
                match x {
                    Some(Operand::Q(n)) if value => write_q(mem, out, n, regs.p),
                    // write_bit ignores Q (the condition was false) and non-bit operands.
                    Some(op) => write_bit(mem, op, value),
                    None => {}
                }
            }
            M::Not => regs.s ^= 1,
            M::And => regs.combine(|s, t| s & t),
            M::Or => regs.combine(|s, t| s | t),
            M::Xor => regs.combine(|s, t| s ^ t),
            M::Anc => regs.combine(|s, t| s & !t),
            M::Orc => regs.combine(|s, t| s | !t),
            M::Let => {
                if let Some(Operand::B(n)) = x {
                    if let Some(b) = mem.b.get_mut(usize::from(n)) {
                        let s0 = regs.top();
                        let edge = s0 && !*b && !env.first_scan;
                        *b = s0;
                        regs.set_top(edge);
                    }
                }
            }
            M::Io | M::Set | M::Res => {
                if let Some(op) = x.filter(|_| regs.top()) {
                    let value = match ins.mnemonic {
                        M::Set => Some(true),
                        M::Res => Some(false),
                        _ => read_bit(mem, env, op).map(|v| !v),
                    };
                    if let Some(v) = value {
                        write_bit(mem, op, v);
                    }
                }
            }
            M::Eq | M::Gt | M::Lt => {
                if let Some(v) = x.and_then(|op| read_int(mem, env, op, k)) {
                    let p = regs.p;
                    regs.set_top(match ins.mnemonic {
                        M::Eq => p == v,
                        M::Gt => p > v,
                        _ => p < v,
                    });
                }
            }
            M::Ctu | M::Ctd => {
                if let Some(Operand::Q(n)) = x {
                    if let Some(q) = mem.q.get_mut(usize::from(n)) {
                        // With fewer than two bits loaded in this scan there is no reset
                        // input: S0 is the count input (docs/vm.md).
                        let pair = regs.depth >= 2;
                        let s0 = regs.top();
                        regs.pop();
                        let (reset, count) = if pair {
                            (s0, !s0 && regs.top())
                        } else {
                            (false, s0)
                        };
                        if reset {
                            *q = 0;
                        } else if count {
                            *q = if ins.mnemonic == M::Ctu {
                                q.saturating_add(1)
                            } else {
                                q.saturating_sub(1)
                            };
                        }
                    }
                }
            }
            M::Ton | M::Tof | M::Imp => {
                let v = x.and_then(|op| read_int(mem, env, op, k));
                if let (Some(v), Some(flags), Some(since)) =
                    (v, self.flags.get_mut(idx), self.since.get_mut(idx))
                {
                    let st = LineState { flags, since };
                    let preset = timer::preset_ms(v);
                    let input = regs.top();
                    regs.set_top(match ins.mnemonic {
                        M::Ton => timer::on_delay(st, input, env.now, preset),
                        M::Tof => timer::off_delay(st, input, env.now, preset),
                        _ => timer::pulse(st, input, env.now, preset, env.first_scan),
                    });
                }
            }
            M::Add | M::Sub | M::Mul | M::Div => {
                if let Some(v) = x.and_then(|op| read_int(mem, env, op, k)) {
                    let p = regs.p;
                    regs.p = match ins.mnemonic {
                        M::Add => arith::add(p, v),
                        M::Sub => arith::sub(p, v),
                        M::Mul => arith::mul(p, v),
                        _ => arith::div(p, v).unwrap_or_else(|| {
                            let line = PLC_FIRST_LINE.saturating_add(idx as u16);
                            out.warning.get_or_insert(Warning::Div0 { line });
                            0
                        }),
                    };
                }
            }
            M::Lcd => {
                if let Some(field) = out.lcd.get_mut(*lcd_used) {
                    *field = Some(regs.p);
                    *lcd_used += 1;
                }
            }
            M::Rev => self.rev_state = Some(regs.top()),
            M::Ack => {
                if let Some(flags) = self.flags.get_mut(idx) {
                    if timer::rising_edge(flags, regs.top(), env.first_scan) {
                        out.ack_request = true;
                    }
                }
            }
            M::Alm => {
                if let (Some(Operand::K(_)), Ok(code @ 1..)) = (x, u8::try_from(ins.constant)) {
                    if out.alarm.is_none() {
                        if let Some(flags) = self.flags.get_mut(idx) {
                            if timer::rising_edge(flags, regs.top(), env.first_scan) {
                                out.alarm = Some(code);
                            }
                        }
                    }
                }
            }
            M::Sfr => {
                if let Some(Operand::Sf(f)) = x {
                    if regs.top() {
                        self.sf_requested &= !f.mask();
                    } else {
                        self.sf_requested |= f.mask();
                    }
                }
            }
            // Drive-section mnemonics: the verifier keeps them out of lines 150-999.
            drive_mnemonics!() => {}
        }
    }
}

/// A bit operand's value; `None` if `op` is not a (valid) bit operand.
fn read_bit(mem: &Memory, env: &Env<'_>, op: Operand) -> Option<bool> {
    let inputs = env.inputs;
    match op {
        Operand::D(n) if n < INPUTS => Some(inputs.digital & (1 << n) != 0),
        Operand::O(n) if n < OUTPUTS => Some(mem.o & (1 << n) != 0),
        Operand::B(n) => mem.b.get(usize::from(n)).copied(),
        Operand::Rdy => Some(inputs.drive.ready),
        Operand::Flb => Some(inputs.drive.fault_latched),
        Operand::Sf(f) => Some(inputs.drive.sf_status & f.mask() != 0),
        Operand::Sdc => Some(inputs.drive.sf_sdc),
        _ => None,
    }
}

/// An int operand's value; `None` if `op` is not a (valid) int operand.
fn read_int(mem: &Memory, env: &Env<'_>, op: Operand, constant: u16) -> Option<i16> {
    let d = &env.inputs.drive;
    let adc = |v: u16| v.min(ADC_MAX) as i16;
    match op {
        Operand::A(n) => env.inputs.analog.get(usize::from(n)).map(|&v| adc(v)),
        Operand::K(_) => Some(i16::try_from(constant).unwrap_or(i16::MAX)),
        Operand::Q(n) => mem.q.get(usize::from(n)).copied(),
        Operand::Com => Some(adc(d.com)),
        Operand::Frq => Some(d.frq.0),
        Operand::Udc => Some(d.udc.0),
        Operand::Imx => Some(d.imx.0),
        Operand::Ihw => Some(d.ihw.0),
        Operand::Uhw => Some(d.uhw.0),
        Operand::Flt => Some(i16::from(d.flt)),
        Operand::Dir => Some(i16::from(d.dir_reverse)),
        Operand::Sft => Some(d.sf_elapsed_ds.min(i16::MAX as u16) as i16),
        Operand::Sfp => Some(d.sf_turns),
        _ => None,
    }
}

/// Writes a bit operand (O, B); anything else is ignored.
fn write_bit(mem: &mut Memory, op: Operand, value: bool) {
    match op {
        Operand::O(n) if n < OUTPUTS => {
            let mask = 1u8 << n;
            mem.o = if value { mem.o | mask } else { mem.o & !mask };
        }
        Operand::B(n) => {
            if let Some(b) = mem.b.get_mut(usize::from(n)) {
                *b = value;
            }
        }
        _ => {}
    }
}

/// `WR`/`WRC` to Qn: stores it and reports it for the drive.
fn write_q(mem: &mut Memory, out: &mut ScanOutputs, n: u8, value: i16) {
    if let Some(q) = mem.q.get_mut(usize::from(n)) {
        *q = value;
        out.q_dirty |= 1u64 << n;
    }
}

/// The interpreter's timer and edge functions, as they were (`timer.rs` before the compiled form).
mod timer {
    use shared_protocol::units::Millis;

    /// Input was 1 on the previous scan (TOF, IMP, ACK edge memory).
    pub const PREV: u8 = 1 << 0;
    /// Timing is under way (TON delay, TOF off-delay, IMP pulse).
    pub const RUNNING: u8 = 1 << 1;
    /// TON delay elapsed: latched so that a 49-day wrap of the clock cannot drop the output.
    pub const DONE: u8 = 1 << 2;

    /// Per-line state: `flags` of the constants above, `since` = when timing started.
    pub struct LineState<'a> {
        pub flags: &'a mut u8,
        pub since: &'a mut Millis,
    }

    /// Preset operand value (0.1 s) to ms; negative presets (from Q) count as 0.
    pub fn preset_ms(preset_ds: i16) -> u32 {
        u32::try_from(preset_ds).unwrap_or(0) * 100
    }

    /// On-delay: output 1 once the input has been 1 continuously for `preset` ms, measured
    /// from the first scan that saw it 1.
    pub fn on_delay(st: LineState<'_>, input: bool, now: Millis, preset: u32) -> bool {
        if !input {
            *st.flags = 0;
            return false;
        }
        if *st.flags & DONE != 0 {
            return true;
        }
        if *st.flags & RUNNING == 0 {
            *st.flags = RUNNING;
            *st.since = now;
        }
        if now.since(*st.since) >= preset {
            *st.flags = DONE;
            true
        } else {
            false
        }
    }

    /// Off-delay: output 1 while the input is 1 and until `preset` ms after the first scan
    /// that saw it 0 again. An input that is 0 from RUN on never starts the delay.
    pub fn off_delay(st: LineState<'_>, input: bool, now: Millis, preset: u32) -> bool {
        if input {
            *st.flags = PREV;
            return true;
        }
        if *st.flags & PREV != 0 {
            *st.flags = RUNNING;
            *st.since = now;
        }
        if *st.flags & RUNNING == 0 {
            return false;
        }
        if now.since(*st.since) >= preset {
            *st.flags = 0;
            false
        } else {
            true
        }
    }

    /// Pulse: a rising edge of the input (not on the first scan) starts a `preset` ms pulse;
    /// edges while it runs are ignored. A preset of 0 gives no pulse.
    pub fn pulse(
        st: LineState<'_>,
        input: bool,
        now: Millis,
        preset: u32,
        first_scan: bool,
    ) -> bool {
        let edge = input && *st.flags & PREV == 0 && !first_scan;
        let mut running = *st.flags & RUNNING != 0;
        if running && now.since(*st.since) >= preset {
            running = false;
        }
        if edge && !running {
            running = true;
            *st.since = now;
        }
        if running && now.since(*st.since) >= preset {
            running = false;
        }
        *st.flags = if input { PREV } else { 0 } | if running { RUNNING } else { 0 };
        running
    }

    /// Rising edge of the input since the previous scan (never on the first scan).
    pub fn rising_edge(flags: &mut u8, input: bool, first_scan: bool) -> bool {
        let edge = input && *flags & PREV == 0 && !first_scan;
        *flags = if input { PREV } else { 0 };
        edge
    }
}
