//! `cargo xtask firmware`: placeholder until the firmware lands.

pub fn run(_args: &[String]) -> Result<(), String> {
    Err("the firmware build is not written yet".into())
}
