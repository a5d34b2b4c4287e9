//! The scan loop over the compiled ops (`compile.rs`): S and P live in registers, every
//! operand is a cell index or an inline constant, and nothing is decoded at run time.

use shared_protocol::units::Millis;

use super::arith;
use super::cells::{Cells, CELLS};
use super::compile::{Op, Slot};
use super::io::{ScanOutputs, Warning};
use super::timer::{self, LineState};

/// What one scan reads besides the ops and cells.
pub struct Env {
    pub now: Millis,
    pub first_scan: bool,
}

/// Runs the ops once, in order. S and P start at 0. Returns the direction of the
/// section's `REV` (`None` when it has none).
#[inline(never)]
pub fn run(
    slots: &mut [Slot],
    cells: &mut Cells,
    env: &Env,
    out: &mut ScanOutputs,
) -> Option<bool> {
    // S: bit 0 = S0, 16 bits (a push drops bit 15). P: the accumulator.
    let mut s: u32 = 0;
    let mut p: i16 = 0;
    let mut rev = None;
    // `LET` sees no edge on the first scan: S0 is and-ed with this.
    let edges = if env.first_scan { !1 } else { !0 };
    let bits = &mut cells.bits;
    let ints = &mut cells.ints;
    macro_rules! bit {
        ($c:expr) => {
            bits.get(usize::from($c)).copied().unwrap_or(false)
        };
    }
    macro_rules! set_bit {
        ($c:expr, $v:expr) => {
            if let Some(b) = bits.get_mut(usize::from($c)) {
                *b = $v;
            }
        };
    }
    macro_rules! int {
        ($c:expr) => {
            ints.get(usize::from($c)).copied().unwrap_or(0)
        };
    }
    // Compiling keeps S below 2^16 (`PushDrop` where a push could carry a bit out).
    let push = |s: u32, b: bool| (s << 1) | u32::from(b);
    let top = |s: u32| s & 1 != 0;
    let set_top = |s: u32, b: bool| (s & !1) | u32::from(b);
    for slot in slots.iter_mut() {
        // Dispatch on a copy of the op (one word); timer and `ACK` ops update their flags
        // in place (`timer`).
        match slot.op {
            Op::Push(c) => s = push(s, bit!(c)),
            Op::PushNot(c) => s = push(s, !bit!(c)),
            Op::PushDrop(c) => s = push(s, bit!(c)) & 0xFFFF,
            Op::PushNotDrop(c) => s = push(s, !bit!(c)) & 0xFFFF,
            Op::Load(c) => p = int!(c),
            Op::LoadK(k) => p = k,
            Op::Vlt => p = arith::vlt(p),
            Op::Amp => p = arith::amp(p),
            Op::Store(c) => set_bit!(c, top(s)),
            Op::StoreNot(c) => set_bit!(c, !top(s)),
            Op::WriteQ(c) => {
                if top(s) {
                    write_q(ints, out, c, p);
                }
            }
            Op::WriteQNot(c) => {
                if !top(s) {
                    write_q(ints, out, c, p);
                }
            }
            Op::AndBit(c) => s &= u32::from(bit!(c)) | !1,
            Op::AndNotBit(c) => s &= !u32::from(bit!(c)),
            Op::OrBit(c) => s |= u32::from(bit!(c)),
            Op::OrNotBit(c) => s |= u32::from(!bit!(c)),
            Op::XorBit(c) => s ^= u32::from(bit!(c)),
            Op::XorNotBit(c) => s ^= u32::from(!bit!(c)),
            Op::Not => s ^= 1,
            // Pop t = S0, then S0 = S0 op t; in bit arithmetic on S with t = 0 or 1.
            Op::And => s = (s >> 1) & (s | !1),
            Op::Or => s = (s >> 1) | (s & 1),
            Op::Xor => s = (s >> 1) ^ (s & 1),
            Op::Anc => s = (s >> 1) & !(s & 1),
            Op::Orc => s = (s >> 1) | (!s & 1),
            Op::Let(c) => {
                // Branch-free: S0 = S0 & !B & !first_scan, B = S0.
                let before = u32::from(bit!(c));
                set_bit!(c, top(s));
                s &= !before & edges;
            }
            Op::Toggle(c) => {
                if top(s) {
                    let v = !bit!(c);
                    set_bit!(c, v);
                }
            }
            Op::Set(c) => {
                if top(s) {
                    set_bit!(c, true);
                }
            }
            Op::Reset(c) => {
                if top(s) {
                    set_bit!(c, false);
                }
            }
            Op::Eq(c) => s = set_top(s, p == int!(c)),
            Op::EqK(k) => s = set_top(s, p == k),
            Op::Gt(c) => s = set_top(s, p > int!(c)),
            Op::GtK(k) => s = set_top(s, p > k),
            Op::Lt(c) => s = set_top(s, p < int!(c)),
            Op::LtK(k) => s = set_top(s, p < k),
            Op::CountUp(c) => {
                let count = top(s);
                s >>= 1;
                if count {
                    count_by(ints, c, 1);
                }
            }
            Op::CountDown(c) => {
                let count = top(s);
                s >>= 1;
                if count {
                    count_by(ints, c, -1);
                }
            }
            Op::CountUpReset(c) => s = count_or_reset(ints, c, s, 1),
            Op::CountDownReset(c) => s = count_or_reset(ints, c, s, -1),
            Op::Ton { cell, .. } => {
                let preset = int!(cell);
                let q = timer(slot, |st| timer::on_delay(st, top(s), env.now, preset));
                s = set_top(s, q);
            }
            Op::TonK { preset, .. } => {
                let q = timer(slot, |st| timer::on_delay(st, top(s), env.now, preset));
                s = set_top(s, q);
            }
            Op::Tof { cell, .. } => {
                let preset = int!(cell);
                let q = timer(slot, |st| timer::off_delay(st, top(s), env.now, preset));
                s = set_top(s, q);
            }
            Op::TofK { preset, .. } => {
                let q = timer(slot, |st| timer::off_delay(st, top(s), env.now, preset));
                s = set_top(s, q);
            }
            Op::Imp { cell, .. } => {
                let preset = int!(cell);
                let q = timer(slot, |st| {
                    timer::pulse(st, top(s), env.now, preset, env.first_scan)
                });
                s = set_top(s, q);
            }
            Op::ImpK { preset, .. } => {
                let q = timer(slot, |st| {
                    timer::pulse(st, top(s), env.now, preset, env.first_scan)
                });
                s = set_top(s, q);
            }
            Op::Add(c) => p = arith::add(p, int!(c)),
            Op::AddK(k) => p = arith::add(p, k),
            Op::Sub(c) => p = arith::sub(p, int!(c)),
            Op::SubK(k) => p = arith::sub(p, k),
            Op::Mul(c) => p = arith::mul(p, int!(c)),
            Op::MulK(k) => p = arith::mul(p, k),
            Op::Div { cell, line } => {
                p = arith::div(p, int!(cell)).unwrap_or_else(|| {
                    out.warning.get_or_insert(Warning::Div0 { line });
                    0
                });
            }
            Op::DivK(k) => p = arith::div(p, k).unwrap_or(0),
            Op::DivZero { line } => {
                out.warning.get_or_insert(Warning::Div0 { line });
                p = 0;
            }
            Op::Lcd(field) => {
                if let Some(f) = out.lcd.get_mut(usize::from(field)) {
                    *f = Some(p);
                }
            }
            Op::Rev => rev = Some(top(s)),
            Op::Sfr(c) => set_bit!(c, !top(s)),
            Op::Ack { code, .. } => event(slot, code, top(s), env.first_scan, out),
        }
    }
    rev
}

/// Runs `f` on the state of a timer or `ACK` slot: the flags inside its op and its start
/// time. `false` for other ops (never: the caller matched the op).
#[inline(always)]
fn timer(slot: &mut Slot, f: impl FnOnce(LineState<'_>) -> bool) -> bool {
    let since = &mut slot.since;
    match &mut slot.op {
        Op::Ton { flags, .. }
        | Op::TonK { flags, .. }
        | Op::Tof { flags, .. }
        | Op::TofK { flags, .. }
        | Op::Imp { flags, .. }
        | Op::ImpK { flags, .. }
        | Op::Ack { flags, .. } => f(LineState { flags, since }),
        _ => false,
    }
}

/// `ACK` (code 0) or `ALM` (code K) on its slot. One alarm per scan: with one already
/// reported, an `ALM` line's edge is left for the next scan (its flags are not updated).
/// Out of line: in the scan's loop it cost every line ~0.9 instructions (m4bench), and
/// these lines are few.
#[inline(never)]
fn event(slot: &mut Slot, code: u8, input: bool, first_scan: bool, out: &mut ScanOutputs) {
    if code != 0 && out.alarm.is_some() {
        return;
    }
    if timer(slot, |st| timer::rising_edge(st.flags, input, first_scan)) {
        if code == 0 {
            out.ack_request = true;
        } else {
            out.alarm = Some(code);
        }
    }
}

/// `WR`/`WRC` to Qn (cell n): stores it and reports it for the drive.
fn write_q(ints: &mut [i16; CELLS], out: &mut ScanOutputs, n: u8, value: i16) {
    if let Some(q) = ints.get_mut(usize::from(n)) {
        *q = value;
        out.q_dirty |= 1u64 << (n & 63);
    }
}

/// `CTU`/`CTD` with a reset input: pops S0 = reset (Q = 0); else S1 = 1 counts. Returns
/// the new S.
fn count_or_reset(ints: &mut [i16; CELLS], cell: u8, s: u32, step: i16) -> u32 {
    let reset = s & 1 != 0;
    let s = s >> 1;
    if reset {
        if let Some(q) = ints.get_mut(usize::from(cell)) {
            *q = 0;
        }
    } else if s & 1 != 0 {
        count_by(ints, cell, step);
    }
    s
}

/// `CTU`/`CTD`: Q += step, saturating.
fn count_by(ints: &mut [i16; CELLS], cell: u8, step: i16) {
    if let Some(q) = ints.get_mut(usize::from(cell)) {
        *q = q.saturating_add(step);
    }
}
