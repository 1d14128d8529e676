//! The simulator and the firmware meet at `firmware::sample`: this checks they link together.
#[test]
fn firmware_and_simulator_link() {
    let k = firmware::sample::TurnaroundKind::Plus;
    assert_ne!(k, firmware::sample::TurnaroundKind::Minus);
}
