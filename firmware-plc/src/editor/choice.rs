//! Stepping a field through the values valid there. Every rule comes from
//! `shared_protocol::program` (`mnemonics_for`, `operands_for`, `constant_range`): the
//! editor never decides validity itself, so it can only produce lines the verifier accepts.

use shared_protocol::program::{
    constant_range, mnemonics_for, operands_for, Instruction, Mnemonic, Operand, Section,
};

/// Capacity for one mnemonic's operand list (PLC `LD` has 293).
const OPERANDS_MAX: usize = 320;

type OperandList = heapless::Vec<Option<Operand>, OPERANDS_MAX>;

fn operand_list(m: Mnemonic, section: Section) -> OperandList {
    // The list is shorter than the capacity for every mnemonic; extra ones would be cut.
    operands_for(m, section).take(OPERANDS_MAX).collect()
}

/// `(index + delta)` modulo `len` (0 for an empty list), in the index's width: an `i64`
/// `rem_euclid` linked the 64-bit signed division into the image.
fn wrap(index: usize, delta: i32, len: usize) -> usize {
    let (Some(at), Some(step)) = (
        index.checked_rem(len),
        (delta.unsigned_abs() as usize).checked_rem(len),
    ) else {
        return 0;
    };
    // Both below `len`: step forwards by `step`, or backwards (forwards by `len - step`).
    let forward = if delta < 0 && step != 0 {
        len - step
    } else {
        step
    };
    if at >= len - forward {
        at - (len - forward)
    } else {
        at + forward
    }
}

/// The line completed for mnemonic `m`: the operand kept when still valid, else the
/// first valid one; the constant clamped into the new range (0 without a `K`).
pub fn with_mnemonic(m: Mnemonic, section: Section, old: Option<&Instruction>) -> Instruction {
    let mut ops = operands_for(m, section);
    let old_op = old.and_then(|i| i.operand);
    let operand = if operands_for(m, section).any(|o| o == old_op) {
        old_op
    } else {
        ops.next().flatten()
    };
    with_operand(
        Instruction {
            mnemonic: m,
            operand,
            constant: old.map_or(0, |i| i.constant),
        },
        section,
    )
}

/// `i` with its constant forced into the range of its (mnemonic, operand).
fn with_operand(mut i: Instruction, section: Section) -> Instruction {
    i.constant = match constant_range(i.mnemonic, section, i.operand) {
        // Not `clamp`: it panics (its message formats both bounds with `core::fmt`) on an
        // empty range; this never panics and gives the same value on every real range.
        Some(r) => i.constant.max(*r.start()).min(*r.end()),
        None => 0,
    };
    i
}

/// Step the mnemonic by `delta` through [empty line, mnemonics of the section...].
pub fn step_mnemonic(
    current: Option<Instruction>,
    section: Section,
    delta: i32,
) -> Option<Instruction> {
    let count = mnemonics_for(section).count();
    let index = current
        .and_then(|i| mnemonics_for(section).position(|m| m == i.mnemonic))
        .map_or(0, |p| p + 1);
    let next = wrap(index, delta, count + 1);
    if next == 0 {
        return None;
    }
    let m = mnemonics_for(section).nth(next - 1)?;
    Some(with_mnemonic(m, section, current.as_ref()))
}

/// Step the operand by `delta` through the operands valid for the mnemonic.
pub fn step_operand(current: Instruction, section: Section, delta: i32) -> Instruction {
    let list = operand_list(current.mnemonic, section);
    let index = list.iter().position(|o| *o == current.operand).unwrap_or(0);
    let operand = list
        .get(wrap(index, delta, list.len()))
        .copied()
        .unwrap_or(current.operand);
    with_operand(Instruction { operand, ..current }, section)
}

/// Jump to the first operand of the next (`forward`) or previous operand area.
pub fn step_operand_class(current: Instruction, section: Section, forward: bool) -> Instruction {
    let list = operand_list(current.mnemonic, section);
    let len = list.len();
    let class_at = |i: usize| list.get(i).copied().flatten().map(|o| o.class());
    let Some(index) = list.iter().position(|o| *o == current.operand) else {
        return step_operand(current, section, 0);
    };
    let here = class_at(index);
    let target = if forward {
        (1..len)
            .map(|k| (index + k) % len)
            .find(|&i| class_at(i) != here)
    } else {
        // Back to the previous class, then to its first entry.
        let first_of_here = (0..len)
            .map(|k| (index + len - k) % len)
            .take_while(|&i| class_at(i) == here)
            .last()
            .unwrap_or(index);
        let prev_last = (first_of_here + len - 1) % len;
        let prev = class_at(prev_last);
        (0..len)
            .map(|k| (prev_last + len - k) % len)
            .take_while(|&i| class_at(i) == prev)
            .last()
    };
    let operand = target
        .and_then(|i| list.get(i).copied())
        .unwrap_or(current.operand);
    with_operand(Instruction { operand, ..current }, section)
}

/// Step digit `digit` (0 = thousands .. 3 = units) of the constant by one, skipping
/// values outside the valid range; unchanged when no other digit value is valid.
pub fn step_digit(current: Instruction, section: Section, digit: u8, up: bool) -> Instruction {
    let Some(range) = constant_range(current.mnemonic, section, current.operand) else {
        return current;
    };
    let pow = 10u16.pow(3u32.saturating_sub(u32::from(digit.min(3))));
    let c = current.constant;
    let d = (c / pow) % 10;
    for k in 1..10u16 {
        let nd = if up { (d + k) % 10 } else { (d + 10 - k) % 10 };
        let candidate = c - d * pow + nd * pow;
        if range.contains(&candidate) {
            return Instruction {
                constant: candidate,
                ..current
            };
        }
    }
    current
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_protocol::program::verify_line;

    #[test]
    fn wrap_is_the_euclidean_remainder() {
        let deltas = [
            0,
            1,
            -1,
            2,
            -2,
            9,
            -9,
            10,
            -10,
            319,
            -320,
            321,
            -641,
            i32::MAX,
            i32::MIN,
        ];
        for len in [0usize, 1, 2, 3, 10, 320, 321] {
            for index in [0, 1, 2, 9, 319, 320, 321, 1000].into_iter().chain(0..len) {
                for delta in deltas.into_iter().chain(-700..700) {
                    let want = if len == 0 {
                        0
                    } else {
                        (index as i64 + i64::from(delta)).rem_euclid(len as i64) as usize
                    };
                    assert_eq!(wrap(index, delta, len), want, "{index} {delta:+} mod {len}");
                }
            }
        }
    }

    #[test]
    fn mnemonic_cycle_covers_the_section_and_empty() {
        let mut cur = None;
        let mut seen = 0;
        loop {
            cur = step_mnemonic(cur, Section::Drive, 1);
            match cur {
                None => break,
                Some(i) => {
                    assert_eq!(verify_line(0, &i), Ok(()), "{i:?}");
                    seen += 1;
                }
            }
        }
        assert_eq!(seen, mnemonics_for(Section::Drive).count());
        // Backwards from empty: the last mnemonic.
        let last = step_mnemonic(None, Section::Plc, -1).unwrap();
        assert_eq!(Some(last.mnemonic), mnemonics_for(Section::Plc).last());
    }

    #[test]
    fn operand_steps_stay_valid_and_classes_jump() {
        let ld = with_mnemonic(Mnemonic::Ld, Section::Plc, None);
        assert_eq!(ld.operand, Some(Operand::D(0)));
        let o = step_operand_class(ld, Section::Plc, true);
        assert_eq!(o.operand, Some(Operand::O(0)));
        let b = step_operand_class(o, Section::Plc, true);
        assert_eq!(b.operand, Some(Operand::B(0)));
        let b10 = step_operand(b, Section::Plc, 10);
        assert_eq!(b10.operand, Some(Operand::B(10)));
        assert_eq!(
            step_operand_class(b10, Section::Plc, false).operand,
            Some(Operand::O(0))
        );
        // Backwards from the first class wraps to the last class's first entry.
        let last = step_operand_class(ld, Section::Plc, false);
        assert_eq!(last.operand, Some(Operand::Sfp));
        let mut i = ld;
        for _ in 0..400 {
            i = step_operand(i, Section::Plc, 1);
            assert_eq!(verify_line(150, &i), Ok(()), "{i:?}");
        }
    }

    #[test]
    fn constant_digits_skip_invalid_values() {
        // PWF K: 0488..=9999.
        let pwf = with_mnemonic(Mnemonic::Pwf, Section::Drive, None);
        assert_eq!(pwf.operand, Some(Operand::K(0)));
        assert_eq!(pwf.constant, 488);
        let down = step_digit(pwf, Section::Drive, 1, false);
        assert_eq!(down.constant, 988, "0388..0088 are invalid, wraps to 0988");
        // dU= K: 0000..=1023.
        let du = Instruction {
            constant: 1023,
            ..with_mnemonic(Mnemonic::DuSet, Section::Drive, None)
        };
        assert_eq!(step_digit(du, Section::Drive, 1, true).constant, 1023);
        assert_eq!(step_digit(du, Section::Drive, 0, true).constant, 23);
        // Changing the mnemonic clamps the constant into the new range.
        let big = Instruction {
            constant: 9000,
            ..with_mnemonic(Mnemonic::Fmn, Section::Drive, None)
        };
        assert_eq!(
            with_mnemonic(Mnemonic::DuSet, Section::Drive, Some(&big)).constant,
            1023
        );
    }
}
