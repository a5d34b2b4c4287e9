#!/usr/bin/env python3
"""Flash use of a firmware image per crate and its largest symbols, from the ELF.

Usage: size-report.py <llvm-nm> <elf> [top]

Reads `llvm-nm --print-size --demangle` of the image (no rebuild, well under a second) and
prints:
  * flash per crate: every symbol in flash (text `t`/`T`, read-only data `r`/`R`), summed by
    the crate its name starts with (see `crate_of`); string and constant pools the compiler
    names `.Lanon.*` have no crate and count as `[anonymous constants]`;
  * the `top` (default 20) largest flash symbols, and the largest RAM symbols (`b`/`d`).
Symbol sizes do not add up to the section sizes exactly (alignment padding, the vector
table); `.ci/run`'s `sizes` step is the budget check, this is the map of where the bytes are.
How to read it: docs/size.md.
"""
import collections
import re
import subprocess
import sys

# Symbols without a crate path: where they come from.
PREFIXES = [
    ("__aeabi_", "compiler_builtins"),
    ("__", "compiler_builtins"),
    ("mem", "compiler_builtins"),
    ("_defmt_", "defmt_rtt"),
    ("_embassy_time", "embassy_time"),
    ("_ZN", "[mangled]"),
]
# Leading crates that name the trait or the container rather than the code's owner.
GENERIC = {"core", "alloc", "compiler_builtins"}
PRIMITIVES = {
    "u8", "u16", "u32", "u64", "u128", "usize", "i8", "i16", "i32", "i64", "i128", "isize",
    "f32", "f64", "bool", "char", "str",
}


def crate_of(name: str) -> str:
    """The crate a demangled symbol belongs to: the first `crate::` path in it that is not
    core's (so `core::ptr::drop_in_place<embassy_stm32::..>` is embassy_stm32's and
    `<usize as core::fmt::Display>::fmt` is core's); interrupt handlers and other
    unqualified symbols are the image's own (`[image: NAME]`) unless a known prefix says
    otherwise."""
    name = name.replace("$LT$", "<").replace("$GT$", ">").replace("$u20$", " ")
    name = name.replace("$RF$", "&").replace("..", "::").lstrip("_")
    # First segments of paths only (`core::fmt::Formatter`: core, not fmt).
    paths = re.findall(r"(?<![:A-Za-z0-9_])([A-Za-z_][A-Za-z0-9_]*)::", name)
    for p in paths:
        if p not in GENERIC and p not in PRIMITIVES and p not in ("impl", "_"):
            return p
    if paths:
        return paths[0]
    return ""


def main() -> int:
    nm, elf = sys.argv[1], sys.argv[2]
    top = int(sys.argv[3]) if len(sys.argv) > 3 else 20
    image = elf.rsplit("/", 1)[-1]
    out = subprocess.run(
        [nm, "--print-size", "--size-sort", "--demangle", elf],
        check=True, capture_output=True, text=True,
    ).stdout
    flash, ram = [], []
    for line in out.splitlines():
        parts = line.split(" ", 3)
        if len(parts) != 4:
            continue
        _addr, size, kind, name = parts
        size = int(size, 16)
        if kind in "tTrR":
            flash.append((size, name))
        elif kind in "bBdD":
            ram.append((size, name))
    per_crate = collections.Counter()
    for size, name in flash:
        if name.startswith(".Lanon") or name.startswith(".L"):
            per_crate["[anonymous constants]"] += size
            continue
        crate = crate_of(name)
        if not crate:
            crate = next((c for p, c in PREFIXES if name.startswith(p)), f"[image: {image}]")
        per_crate[crate] += size
    total = sum(per_crate.values())
    print(f"--- {image}: flash per crate (symbol sizes, total {total} B)")
    for crate, size in per_crate.most_common():
        print(f"{size:8} B {100 * size / total:5.1f} %  {crate}")
    print(f"--- {image}: {top} largest flash symbols")
    for size, name in sorted(flash, reverse=True)[:top]:
        print(f"{size:8} B  {name[:150]}")
    print(f"--- {image}: 5 largest RAM symbols")
    for size, name in sorted(ram, reverse=True)[:5]:
        print(f"{size:8} B  {name[:150]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
