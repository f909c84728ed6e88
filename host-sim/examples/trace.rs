//! Prints a run's per-tick rows as CSV: `cargo run --example trace -- <scenario> <pose> <seed>`.
use host_sim::{run, PoseMode, Scenario};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .map_or("host-sim/scenarios/seed-mat.toml", String::as_str);
    let mode: PoseMode = args.get(1).map_or(Ok(PoseMode::Tags), |s| s.parse())?;
    let seed = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let output = run(&Scenario::load(path.as_ref())?, mode, seed)?;
    println!("t_s,truth_x,truth_y,truth_h,est_x,est_y,est_h,error_cm,heading_error_deg,known_pct,out_of_place_pct,fix");
    for t in &output.record.ticks {
        println!(
            "{:.1},{:.1},{:.1},{:.2},{:.1},{:.1},{:.2},{:.2},{:.2},{:.1},{:.1},{}",
            t.t_s,
            t.truth_mm.0,
            t.truth_mm.1,
            t.truth_heading_deg,
            t.estimate_mm.0,
            t.estimate_mm.1,
            t.estimate_heading_deg,
            t.error_cm,
            t.heading_error_deg,
            t.known_pct,
            t.out_of_place_pct,
            u8::from(t.fix_taken)
        );
    }
    Ok(())
}
