use hal_sim::gyro::Gyro;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
fn main() {
    let mut g = Gyro::new(GyroParams::default(), InputProfile::constant(13.888)).unwrap();
    println!("{}", g.advance_to(1.0));
}
