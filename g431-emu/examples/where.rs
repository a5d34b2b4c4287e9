//! Prints where an image spends its time: `cargo run -p g431-emu --example where --release
//! -- <elf> <from_ms> <to_ms> [step_us]`.
use g431_emu::mcu::Mcu;
use g431_emu::soc::BareBoard;
use g431_emu::time::CYCLES_PER_US;

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let from: u64 = a[2].parse()?;
    let to: u64 = a[3].parse()?;
    let step: u64 = a.get(4).map_or(Ok(1000), |s| s.parse())?;
    let mut mcu = Mcu::load("mcu", std::path::Path::new(&a[1]), Box::new(BareBoard))?;
    mcu.run_until(from * 1000 * CYCLES_PER_US);
    let mut t = from * 1000;
    while t < to * 1000 {
        t += step;
        mcu.run_until(t * CYCLES_PER_US);
        println!(
            "{t:>8} us {:?} {} pc={:#x} ipsr={}",
            mcu.state(),
            mcu.where_(),
            mcu.cpu().pc(),
            mcu.soc().ipsr
        );
    }
    for l in mcu.log() {
        println!("{l}");
    }
    Ok(())
}
