//! Boots an image on a bare board and prints what happened: `cargo run -p g431-emu --example
//! boot --release -- <elf> [ms]`.
use g431_emu::mcu::Mcu;
use g431_emu::soc::BareBoard;
use g431_emu::time::CYCLES_PER_US;

fn main() -> anyhow::Result<()> {
    let path = std::env::args().nth(1).expect("elf path");
    let ms: u64 = std::env::args()
        .nth(2)
        .map_or(10, |s| s.parse().unwrap_or(10));
    let mut mcu = Mcu::load("mcu", std::path::Path::new(&path), Box::new(BareBoard))?;
    let t0 = std::time::Instant::now();
    let mut shown = 0;
    for k in 1..=ms {
        mcu.run_until(k * 1000 * CYCLES_PER_US);
        for l in mcu.log_since(shown) {
            println!("{l}");
        }
        shown = mcu.log().len();
    }
    println!(
        "wall {:?} for {ms} ms; now in {} ({:?})",
        t0.elapsed(),
        mcu.where_(),
        mcu.state()
    );
    for e in mcu.events() {
        println!("event {e:?}");
    }
    for d in mcu.diagnostics() {
        println!("diag {d}");
    }
    Ok(())
}
