//! Where the firmware images are: the ELFs `firmware-drive` and `firmware-plc` of the image
//! crates `drive-image` and `plc-image`, built with the workspace's `firmware` profile for
//! `thumbv7em-none-eabihf`, in the workspace's target directory: exactly what CI builds
//! and `probe-rs` flashes.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use anyhow::{bail, Context, Result};

/// The firmware target.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// The cargo profile the flashed images are built with (the workspace's `Cargo.toml`:
/// fat LTO, one codegen unit and the per-crate size choices, none of which host builds
/// pay for). Cargo puts its output in `target/<TARGET>/<PROFILE>/`.
pub const PROFILE: &str = "firmware";

/// The two images.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    Drive,
    Plc,
}

impl Firmware {
    /// The image's binary (its ELF's file name).
    pub fn bin_name(self) -> &'static str {
        match self {
            Firmware::Drive => "firmware-drive",
            Firmware::Plc => "firmware-plc",
        }
    }

    /// The crate that builds the image (target only).
    pub fn image_crate(self) -> &'static str {
        match self {
            Firmware::Drive => "drive-image",
            Firmware::Plc => "plc-image",
        }
    }
}

/// The workspace root (hil-sim's parent directory).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// The target directory cargo uses for this workspace (`CARGO_TARGET_DIR` or `target/`).
pub fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            if d.is_absolute() {
                d
            } else {
                workspace_root().join(d)
            }
        }
        None => workspace_root().join("target"),
    }
}

/// Path of the flashed ELF of `fw`.
pub fn release_elf(fw: Firmware) -> PathBuf {
    target_dir().join(TARGET).join(PROFILE).join(fw.bin_name())
}

/// The command that builds `fw`'s release image (each image alone: their embassy chip
/// features differ).
pub fn build_command(fw: Firmware) -> String {
    format!(
        "cargo build --profile {PROFILE} --target {TARGET} -p {} --bin {}",
        fw.image_crate(),
        fw.bin_name()
    )
}

/// The release ELF of `fw`, or an error that says how to build it.
pub fn existing(fw: Firmware) -> Result<PathBuf> {
    let p = release_elf(fw);
    if !p.is_file() {
        bail!(
            "{} is missing: build the image with `{}` (or pass its path with --{}-elf)",
            p.display(),
            build_command(fw),
            match fw {
                Firmware::Drive => "drive",
                Firmware::Plc => "plc",
            }
        );
    }
    Ok(p)
}

/// The step a machine without the firmware target must take (README "The two commands").
pub const TARGET_STEP: &str = "rustup target add thumbv7em-none-eabihf";

/// Whether the toolchain that builds the images has [`TARGET`]'s standard library: a
/// fresh machine that skipped the step gets one line naming it, instead of a page of
/// "can't find crate for `core`" per image.
fn target_installed() -> Result<()> {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let out = Command::new(&rustc)
        .current_dir(workspace_root())
        .args(["--print", "sysroot"])
        .output()
        .with_context(|| "cannot run `rustc --print sysroot`".to_string())?;
    let sysroot = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    target_in(&sysroot)
}

/// [`TARGET`]'s standard library is in `sysroot`, or the one-line error naming the step.
fn target_in(sysroot: &Path) -> Result<()> {
    if !sysroot.join("lib/rustlib").join(TARGET).is_dir() {
        bail!(
            "the firmware target {TARGET} is not installed in {}: run `{TARGET_STEP}` (or \
             `rustup toolchain install` in the workspace, which reads rust-toolchain.toml)",
            sysroot.display()
        );
    }
    Ok(())
}

/// Builds both release images (a no-op when they are up to date) and returns their paths
/// (drive, PLC). Used by the emulator tests so that `cargo test` alone exercises what is
/// flashed. Serialised within the process.
pub fn build_both() -> Result<(PathBuf, PathBuf)> {
    static LOCK: Mutex<()> = Mutex::new(());
    let _guard = LOCK
        .lock()
        .map_err(|_| anyhow::anyhow!("image build lock poisoned"))?;
    target_installed()?;
    for fw in [Firmware::Drive, Firmware::Plc] {
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let status = Command::new(cargo)
            .current_dir(workspace_root())
            .args([
                "build",
                "--profile",
                PROFILE,
                "--target",
                TARGET,
                "-p",
                fw.image_crate(),
                "--bin",
                fw.bin_name(),
            ])
            .status()
            .with_context(|| format!("cannot run `{}`", build_command(fw)))?;
        if !status.success() {
            bail!(
                "`{}` failed ({status}); a fresh machine needs the target and flip-link: \
                 `rustup target add {TARGET} && cargo install flip-link`",
                build_command(fw)
            );
        }
    }
    Ok((release_elf(Firmware::Drive), release_elf(Firmware::Plc)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sysroot_without_the_firmware_target_gives_one_line_naming_the_step() {
        let dir = std::env::temp_dir().join(format!("hil-sim-sysroot-{}", std::process::id()));
        let libs = dir.join("lib/rustlib");
        std::fs::create_dir_all(libs.join("x86_64-unknown-linux-gnu")).unwrap();
        let err = target_in(&dir).unwrap_err().to_string();
        assert!(err.contains(TARGET_STEP), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        std::fs::create_dir_all(libs.join(TARGET)).unwrap();
        assert!(target_in(&dir).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
