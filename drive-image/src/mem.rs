//! The ARM EABI memory helpers the compiler calls for copies and fills
//! (`__aeabi_memcpy{,4,8}`, `__aeabi_memset{,4,8}`, `__aeabi_memclr{,4,8}`), as two short
//! word-then-byte loops.
//!
//! Why: `compiler_builtins` (prebuilt at opt-level 3 in the standard library) links its
//! unrolled versions, about 1.5 KiB for these seven entry points and the `memcpy` they
//! share. Its definitions are weak, so these strong ones replace them in this image (the
//! linker then pulls none of them: docs/size.md). Nothing time-critical copies through them:
//! the PWM interrupt calls none (`llvm-objdump -d` of `TIM1_UP_TIM16`), and the critical
//! sections that do (the 1 ms tick, the link's receive and transmit) are measured by the
//! emulator's timing test (`firmware-drive/docs/critical-sections.md`).
//!
//! Written in assembly: a loop of loads and stores in Rust is the pattern LLVM turns back
//! into a call to these very functions. Word accesses only when the addresses are
//! word-aligned (the `4`/`8` entry points guarantee it); the rest byte by byte. The EABI
//! lets them clobber r0-r3 and r12 and return nothing.

core::arch::global_asm!(
    ".section .text.__aeabi_memcpy,\"ax\",%progbits",
    ".global __aeabi_memcpy",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".type __aeabi_memcpy,%function",
    ".type __aeabi_memcpy4,%function",
    ".type __aeabi_memcpy8,%function",
    ".thumb_func",
    // r0 = destination, r1 = source, r2 = bytes.
    "__aeabi_memcpy:",
    "    orr r3, r0, r1",
    "    lsls r3, r3, #30",
    "    bne 2f",
    ".thumb_func",
    "__aeabi_memcpy4:",
    ".thumb_func",
    "__aeabi_memcpy8:",
    "1:  cmp r2, #4",
    "    blo 2f",
    "    ldr r3, [r1], #4",
    "    str r3, [r0], #4",
    "    subs r2, #4",
    "    b 1b",
    "2:  cbz r2, 3f",
    "    ldrb r3, [r1], #1",
    "    strb r3, [r0], #1",
    "    subs r2, #1",
    "    b 2b",
    "3:  bx lr",
    ".size __aeabi_memcpy, . - __aeabi_memcpy",
    "",
    ".section .text.__aeabi_memset,\"ax\",%progbits",
    ".global __aeabi_memset",
    ".global __aeabi_memset4",
    ".global __aeabi_memset8",
    ".global __aeabi_memclr",
    ".global __aeabi_memclr4",
    ".global __aeabi_memclr8",
    ".type __aeabi_memset,%function",
    ".type __aeabi_memset4,%function",
    ".type __aeabi_memset8,%function",
    ".type __aeabi_memclr,%function",
    ".type __aeabi_memclr4,%function",
    ".type __aeabi_memclr8,%function",
    // memset: r0 = destination, r1 = bytes, r2 = value (its low byte).
    ".thumb_func",
    "__aeabi_memset:",
    ".thumb_func",
    "__aeabi_memset4:",
    ".thumb_func",
    "__aeabi_memset8:",
    "    uxtb r2, r2",
    "    orr r2, r2, r2, lsl #8",
    "    orr r2, r2, r2, lsl #16",
    "    b 0f",
    // memclr: r0 = destination, r1 = bytes.
    ".thumb_func",
    "__aeabi_memclr:",
    ".thumb_func",
    "__aeabi_memclr4:",
    ".thumb_func",
    "__aeabi_memclr8:",
    "    movs r2, #0",
    "0:  lsls r3, r0, #30",
    "    bne 2f",
    "1:  cmp r1, #4",
    "    blo 2f",
    "    str r2, [r0], #4",
    "    subs r1, #4",
    "    b 1b",
    "2:  cbz r1, 3f",
    "    strb r2, [r0], #1",
    "    subs r1, #1",
    "    b 2b",
    "3:  bx lr",
    ".size __aeabi_memset, . - __aeabi_memset",
);
