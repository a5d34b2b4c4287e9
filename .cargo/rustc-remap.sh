#!/usr/bin/env bash
# rustc wrapper (`build.rustc-wrapper` in config.toml): for the firmware target only,
# strips this machine's cargo registry prefix (`$CARGO_HOME/registry/src/<index>/`) from
# the source paths rustc records, so that the images' panic locations read
# `embassy-stm32-0.6.0/src/..` instead of `/home/<user>/.cargo/registry/src/index.crates.io-
# <hash>/embassy-stm32-0.6.0/src/..`: ~1.1 KiB of flash per image, the same on every
# machine. Cargo's own `trim-paths` profile option does this but is not stable (cargo
# 1.95); `--remap-path-prefix` in `rustflags` needs the prefix literally. Bash, not sh:
# dash drops environment variables whose names are not identifiers, such as cargo's
# `CARGO_BIN_EXE_hil-sim` for integration tests. Host builds (no
# `--target thumbv7em-none-eabihf`) run rustc unchanged. docs/size.md.
rustc="$1"
shift
case " $* " in
*" --target thumbv7em-none-eabihf "*)
    for arg in "$@"; do
        case "$arg" in
        */registry/src/*/*.rs)
            # .../registry/src/<index>/<crate>-<version>/src/lib.rs -> .../registry/src/<index>/
            index="${arg%%/registry/src/*}/registry/src/"
            rest="${arg#"$index"}"
            exec "$rustc" "$@" "--remap-path-prefix=$index${rest%%/*}/="
            ;;
        esac
    done
    ;;
esac
exec "$rustc" "$@"
