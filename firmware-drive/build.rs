//! Build script.
//!
//! Generates the modulator's quarter-period sine table into `OUT_DIR/sine_table.rs`: the
//! firmware never evaluates trigonometry at run time, and a table computed here in `f64` is
//! exact to the last bit of its Q15 format. (Linking the image is `drive-image`'s.)
use std::{env, fmt::Write as _, fs, path::PathBuf};

/// Points per full sine period; must match `sine::TABLE_BITS` (2^10). The table holds the
/// first quarter of them (the rest follows by symmetry, `sine::sin_q15`).
const SINE_POINTS: usize = 1024;

/// Q15 sine of point `k` of `SINE_POINTS` per period, rounded half away from zero.
fn sine_point(k: usize) -> i16 {
    let x = (2.0 * std::f64::consts::PI * k as f64 / SINE_POINTS as f64).sin();
    (32767.0 * x).round() as i16
}

fn sine_table() -> String {
    let quarter = SINE_POINTS / 4;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/// round(32767 * sin(2*pi*k/{SINE_POINTS})) for k = 0..={}: the first quarter period,\n\
         /// its end point (sin = 1) and the point past it, so that interpolation from the end\n\
         /// point (a zero step, `sine::sin_q15`) never leaves the table.\n\
         pub static SINE_Q15_QUARTER: [i16; {}] = [",
        quarter + 1,
        quarter + 2
    );
    for k in 0..=quarter + 1 {
        let _ = write!(s, "{},", sine_point(k));
        if k % 16 == 15 {
            s.push('\n');
        }
    }
    s.push_str("];\n");
    s
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("sine_table.rs"), sine_table()).expect("write OUT_DIR/sine_table.rs");
}
