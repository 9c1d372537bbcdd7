//! The images' memory copy and clear, small: the ARM EABI entry points the compiler calls for
//! `copy_nonoverlapping` and for zeroing (`__aeabi_memcpy*`, `__aeabi_memclr*`,
//! `__aeabi_memset*`), in place of `compiler_builtins`' (weak symbols, so these win at link).
//!
//! `compiler_builtins` copies with unrolled, misalignment-shifting loops: 1 294 B of each image
//! for copies that are mostly a frame or a struct of a few dozen bytes, while the slave must
//! fit in 32 KiB. These move four words per `ldm`/`stm` pair where both addresses are
//! word-aligned (the `4` and `8` forms promise it), else words by unaligned `ldr`/`str`
//! (a third of the master's copies were at odd addresses, a byte at a time), then the last
//! bytes: 122 B in all. A 128 B SPI frame copied word-aligned is ~40 instructions
//! (a word at a time, as until the master's tasks were profiled relaying a play: ~165, a fifth
//! of the master's instructions; `compiler_builtins`: ~70), byte by byte ~520.
//!
//! In assembly, not Rust: LLVM turns a byte-copy loop back into a `memcpy` call, which here
//! would call itself. Included by `m3-bench`'s image too, so its counts are the boards'.

core::arch::global_asm!(
    ".pushsection .text.omnibench_mem,\"ax\",%progbits",
    ".syntax unified",
    ".thumb",
    ".p2align 2",
    // __aeabi_memcpy(dest r0, src r1, n r2): any alignment. Both word-aligned (most copies
    // the compiler could not prove so are), on to the four-word loop; else words by plain
    // LDR/STR, which the Cortex-M3 does at any address in memory (ARMv7-M A3.2.1: a split
    // access; CCR.UNALIGN_TRP, which would trap them, is left clear), then bytes.
    ".global __aeabi_memcpy",
    ".type __aeabi_memcpy, %function",
    ".thumb_func",
    "__aeabi_memcpy:",
    "orr r3, r0, r1",
    "lsls r3, r3, #30",
    "bne 1f",
    // Each entry's size ends where the next entry starts: code one falls into is counted once.
    ".size __aeabi_memcpy, . - __aeabi_memcpy",
    // __aeabi_memcpy4/8: both word-aligned. Words while four bytes are left, then the bytes.
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".type __aeabi_memcpy4, %function",
    ".thumb_func",
    "__aeabi_memcpy4:",
    // Four words at a time (r4, r5 saved: the EABI's callee-saved), then the rest.
    "subs r2, r2, #16",
    "bcc 21f",
    "push {{r4, r5}}",
    "20:",
    "ldmia r1!, {{r3, r4, r5, r12}}",
    "stmia r0!, {{r3, r4, r5, r12}}",
    "subs r2, r2, #16",
    "bcs 20b",
    "pop {{r4, r5}}",
    "21:",
    "adds r2, r2, #16",
    "1:",
    "subs r2, r2, #4",
    "bcc 2f",
    "ldr r3, [r1], #4",
    "str r3, [r0], #4",
    "b 1b",
    "2:",
    "adds r2, r2, #4",
    "cbz r2, 4f",
    "5:",
    "ldrb r3, [r1], #1",
    "strb r3, [r0], #1",
    "subs r2, r2, #1",
    "bne 5b",
    "4:",
    "bx lr",
    ".size __aeabi_memcpy4, . - __aeabi_memcpy4",
    ".thumb_set __aeabi_memcpy8, __aeabi_memcpy4",
    // __aeabi_memclr4/8(dest r0, n r1): word-aligned. Zero words, then bytes.
    ".global __aeabi_memclr4",
    ".global __aeabi_memclr8",
    ".type __aeabi_memclr4, %function",
    ".thumb_func",
    "__aeabi_memclr4:",
    "11:",
    "movs r2, #0",
    // Four words at a time (r4 saved), then the rest.
    "subs r1, r1, #16",
    "bcc 13f",
    "push {{r4}}",
    "movs r3, #0",
    "movs r4, #0",
    "mov r12, r2",
    "12:",
    "stmia r0!, {{r2, r3, r4, r12}}",
    "subs r1, r1, #16",
    "bcs 12b",
    "pop {{r4}}",
    "13:",
    "adds r1, r1, #16",
    "6:",
    "subs r1, r1, #4",
    "bcc 7f",
    "str r2, [r0], #4",
    "b 6b",
    "7:",
    "adds r1, r1, #4",
    "b 8f",
    ".size __aeabi_memclr4, . - __aeabi_memclr4",
    ".thumb_set __aeabi_memclr8, __aeabi_memclr4",
    // __aeabi_memclr(dest r0, n r1): any alignment (word-aligned, on to the four-word loop;
    // else words by plain STR, as in __aeabi_memcpy, then bytes).
    ".global __aeabi_memclr",
    ".type __aeabi_memclr, %function",
    ".thumb_func",
    "__aeabi_memclr:",
    "lsls r3, r0, #30",
    "beq 11b",
    "movs r2, #0",
    "b 6b",
    ".size __aeabi_memclr, . - __aeabi_memclr",
    // __aeabi_memset*(dest r0, n r1, byte r2) (the EABI's argument order, not C's): a byte
    // at a time (nothing on the boards sets more than a few bytes to anything but zero).
    ".global __aeabi_memset",
    ".global __aeabi_memset4",
    ".global __aeabi_memset8",
    ".type __aeabi_memset, %function",
    ".thumb_func",
    "__aeabi_memset:",
    "8:",
    "cbz r1, 10f",
    "9:",
    "strb r2, [r0], #1",
    "subs r1, r1, #1",
    "bne 9b",
    "10:",
    "bx lr",
    ".size __aeabi_memset, . - __aeabi_memset",
    ".thumb_set __aeabi_memset4, __aeabi_memset",
    ".thumb_set __aeabi_memset8, __aeabi_memset",
    ".popsection",
);
