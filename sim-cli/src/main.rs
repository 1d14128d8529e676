//! `rlg-sim`: the simulated gyro with the firmware's own signal chain in the loop.
mod plot;

fn main() {
    let _ = plot::nice_ticks(0.0, 1.0, 5);
    eprintln!("rlg-sim: under construction");
    std::process::exit(2);
}
