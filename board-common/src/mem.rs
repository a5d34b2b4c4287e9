//! The ARM EABI memory helpers the compiler calls for copies and fills
//! (`__aeabi_memcpy{,4,8}`, `__aeabi_memset{,4,8}`, `__aeabi_memclr{,4,8}`), as two short
//! loops: bytes up to a word boundary, two words per step, the last bytes.
//!
//! Why: `compiler_builtins` (prebuilt at opt-level 3 in the standard library) links its
//! unrolled versions, about 1.7 KiB per image for these entry points and the `memcpy` they
//! share. Its definitions are weak, so these strong ones replace them in both images (the
//! linker then pulls none of them: docs/size.md). Nothing time-critical copies through them:
//! the drive's PWM interrupt and the PLC's scan (`plc-vm`) call none (`llvm-objdump -d` of
//! `TIM1_UP_TIM16` and of the scan), and the drive's critical sections that do (the 1 ms
//! tick, the link's receive and transmit) are measured by the emulator's timing test
//! (`firmware-drive/docs/critical-sections.md`).
//!
//! Written in assembly: a loop of loads and stores in Rust is the pattern LLVM turns back
//! into a call to these very functions. Word accesses only at word-aligned addresses
//! (`ldm`/`stm`/`strd` require it; the `4`/`8` entry points guarantee it): a copy whose
//! source and destination differ in their low two address bits goes byte by byte. The
//! EABI lets them clobber r0-r3 and r12 and return nothing.

core::arch::global_asm!(
    ".section .text.__aeabi_memcpy,\"ax\",%progbits",
    ".global __aeabi_memcpy",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".type __aeabi_memcpy,%function",
    ".type __aeabi_memcpy4,%function",
    ".type __aeabi_memcpy8,%function",
    // r0 = destination, r1 = source, r2 = bytes.
    ".thumb_func",
    "__aeabi_memcpy:",
    "    eor r3, r0, r1",
    "    lsls r3, r3, #30",
    "    bne 3f",
    "0:  lsls r3, r0, #30",
    "    beq 1f",
    "    cbz r2, 4f",
    "    ldrb r3, [r1], #1",
    "    strb r3, [r0], #1",
    "    subs r2, #1",
    "    b 0b",
    ".thumb_func",
    "__aeabi_memcpy4:",
    ".thumb_func",
    "__aeabi_memcpy8:",
    "1:  subs r2, #8",
    "    blo 2f",
    "    ldmia r1!, {{r3, r12}}",
    "    stmia r0!, {{r3, r12}}",
    "    b 1b",
    "2:  adds r2, #8",
    "3:  cbz r2, 4f",
    "    ldrb r3, [r1], #1",
    "    strb r3, [r0], #1",
    "    subs r2, #1",
    "    b 3b",
    "4:  bx lr",
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
    "0:  mov r3, r2",
    "1:  lsls r12, r0, #30",
    "    beq 2f",
    "    cbz r1, 5f",
    "    strb r2, [r0], #1",
    "    subs r1, #1",
    "    b 1b",
    "2:  subs r1, #8",
    "    blo 3f",
    "    strd r2, r3, [r0], #8",
    "    b 2b",
    "3:  adds r1, #8",
    "4:  cbz r1, 5f",
    "    strb r2, [r0], #1",
    "    subs r1, #1",
    "    b 4b",
    "5:  bx lr",
    ".size __aeabi_memset, . - __aeabi_memset",
);
