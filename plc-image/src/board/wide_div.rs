//! The 64-bit division helper `compiler_builtins`' `__aeabi_uldivmod` calls, by shift and
//! subtract (`firmware_plc::wide_div`): ~650 B less flash than its `u64_div_rem`. Its
//! definitions are weak, this strong one replaces it and the linker pulls no `u64_div_rem`
//! (docs/size.md). Nothing calls it by name. The image has no signed 64-bit division
//! (`__aeabi_ldivmod` would link `u64_div_rem` again: `llvm-nm` shows it).

use firmware_plc::wide_div::udivmod;

/// `n / d`, and `n % d` into `rem` when given.
#[no_mangle]
extern "C" fn __udivmoddi4(n: u64, d: u64, rem: Option<&mut u64>) -> u64 {
    let (q, r) = udivmod(n, d);
    if let Some(rem) = rem {
        *rem = r;
    }
    q
}
