use hal_sim::params::GyroParams;
use rlg_sim::experiment::*;
use std::io::Write;
use std::ops::ControlFlow;
fn main() {
    let params = GyroParams::default();
    let noise: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(25.0);
    let secs: f64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(20.0);
    let setup = BoardSetup {
        drive: DitherDrive::ClosedLoop {
            noise_percent: noise,
        },
        ..BoardSetup::board(0.0, 1000.0)
    };
    let mut f = std::io::BufWriter::new(std::fs::File::create("/tmp/rec/noise.csv").unwrap());
    writeln!(f, "t_s,delta_angle_arcsec,valid").unwrap();
    let s = rlg_sim::record_run::record(&params, setup, 0.0, 0.5, secs, Default::default(), |r| {
        writeln!(f, "{},{},{}", r.t_s, r.delta_angle_arcsec, r.valid as u8).unwrap();
        ControlFlow::Continue(())
    })
    .unwrap();
    println!("{s:?}");
}
