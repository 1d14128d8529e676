//! On-target tests (QEMU or a board): the firmware's core functions on the Cortex-M4F.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
#[defmt_test::tests]
mod tests {
    use firmware::rt::pac as _;

    #[test]
    fn boots() {
        defmt::assert!(true);
    }
}

#[cfg(not(target_os = "none"))]
fn main() {}
