//! Insert and remove in a `heapless::Vec` of small `Copy` elements by an element loop.
//!
//! `heapless::Vec::insert`/`remove` shift with `core::ptr::copy`, which links
//! `compiler_builtins`' `memmove` (1.5 KB of flash, its word-aligned paths) for queues of
//! a few dozen 4- or 8-byte elements: the PLC link's pending commands and the PLC's fault
//! log, where no time budget needs the faster copy. With these the PLC image has no
//! `memmove` at all (docs/size.md).

use heapless::Vec;

/// `v.insert(0, x)`: `Err(x)` when `v` is full.
pub fn insert_front<T: Copy, const N: usize>(v: &mut Vec<T, N>, x: T) -> Result<(), T> {
    v.push(x)?;
    for i in (1..v.len()).rev() {
        if let Some(&prev) = v.get(i - 1) {
            if let Some(e) = v.get_mut(i) {
                *e = prev;
            }
        }
    }
    if let Some(first) = v.first_mut() {
        *first = x;
    }
    Ok(())
}

/// `v.remove(i)`, `None` when `i` is not below the length.
pub fn remove_at<T: Copy, const N: usize>(v: &mut Vec<T, N>, i: usize) -> Option<T> {
    let x = *v.get(i)?;
    for j in i + 1..v.len() {
        if let Some(&next) = v.get(j) {
            if let Some(e) = v.get_mut(j - 1) {
                *e = next;
            }
        }
    }
    v.pop();
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn they_do_what_the_vec_methods_do() {
        for len in 0..=6usize {
            let full: Vec<u32, 6> = (0..len as u32).map(|n| n * 10 + 1).collect();
            let mut a = full.clone();
            let mut b = full.clone();
            assert_eq!(insert_front(&mut a, 99), b.insert(0, 99));
            assert_eq!(a, b);
            for i in 0..=len {
                let mut a = full.clone();
                let mut b = full.clone();
                let want = (i < len).then(|| b.remove(i));
                assert_eq!(remove_at(&mut a, i), want, "len {len} at {i}");
                assert_eq!(a, b);
            }
        }
    }
}
