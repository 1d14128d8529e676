//! `rlg-sim`: the simulated gyro with the firmware's own signal chain in the loop.
#![allow(dead_code)] // wired up once the simulator board lands
mod args;
mod plot;
mod report;

fn main() {
    eprintln!("rlg-sim: under construction");
    std::process::exit(2);
}
