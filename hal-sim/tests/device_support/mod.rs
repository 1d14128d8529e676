//! Shared by the tests that talk to the simulated board over its serial protocol
//! (`protocol_device`, `output_stream`): the fixture key, power-up with it, one exchange of
//! bytes for the answer, and a field of an answer.

use firmware::protocol::execute::Identity;
use firmware::protocol::key::Key;
use hal_sim::device::{SimDevice, SIM_IDENTITY};
use hal_sim::flash::CalibrationFlash;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;

/// The key these tests give their simulated board (a fixture: the simulator has no fixed key).
pub const KEY: &str = "3a7c5e91b2d4f60819e3c5a7b9d1f2e4";

/// Powers up the simulated board with [`KEY`] at a constant input rate.
pub fn boot_with_key(
    params: GyroParams,
    rate_deg_h: f64,
    flash: CalibrationFlash,
    boot_count: u32,
) -> SimDevice {
    SimDevice::boot(
        params,
        InputProfile::constant(rate_deg_h),
        Identity {
            key: Key::parse_hex(KEY),
            ..SIM_IDENTITY
        },
        flash,
        boot_count,
    )
    .unwrap()
}

/// Sends `bytes` and runs the board until it answers (up to 3 simulated seconds: a `store`
/// answers when its flash stall is over); the answer as text, without the 0x00 delimiters an
/// answer has when a stream is on before or after its line.
pub fn exchange(dev: &mut SimDevice, bytes: &[u8]) -> String {
    dev.receive(bytes);
    let mut out = dev.take_output();
    let sent_s = dev.time_s();
    while out.is_empty() && dev.time_s() - sent_s < 3.0 {
        dev.run_for(0.001);
        out = dev.take_output();
    }
    String::from_utf8(out)
        .expect("text answer")
        .trim_matches('\0')
        .to_owned()
}

/// The value of `key=` in an answer.
pub fn field<'a>(answer: &'a str, key: &str) -> &'a str {
    answer
        .split(' ')
        .find_map(|w| w.strip_prefix(key).and_then(|w| w.strip_prefix('=')))
        .unwrap_or_else(|| panic!("{key} in {answer}"))
        .trim_end()
}
