//! What `run --json` reports under `matching`: every tick's sweep used or refused by a
//! cause, and no `matching` at all in the modes that do not match.

use host_sim::{run, PoseMode};
use world::shipped::scenario;

/// On worlds with walls in reach, one sweep a tick is matched, and each is either used
/// or refused by one cause: the counts add up to the ticks, and most are used or pin
/// nothing (a wall or two seen along one direction), few fall on nothing the map knows.
#[test]
fn every_ticks_sweep_is_used_or_refused_by_a_cause() {
    for name in [
        "seed-mat-no-tags",
        "two-wall-room",
        "corridor",
        "tag-free-room",
    ] {
        let out = match run(&scenario(&format!("{name}.toml")), PoseMode::Slam, 1) {
            Ok(out) => out,
            Err(e) => panic!("{name}: {e}"),
        };
        let f = &out.figures;
        let Some(m) = f.matching else {
            panic!("{name}: no matching figures under slam");
        };
        let r = &m.refused;
        let refused = r.empty + r.too_few_points + r.no_fit + r.nothing_pinned + r.gate + r.other;
        assert_eq!(
            (m.used + refused) as usize,
            f.ticks,
            "{name}: {m:?} over {} ticks",
            f.ticks
        );
        assert!(m.used as usize * 3 > f.ticks, "{name}: {m:?}");
        assert!(r.no_fit as usize * 10 < f.ticks, "{name}: {m:?}");
        // The JSON names them as the struct does.
        let json = serde_json::to_value(f).expect("figures serialise");
        assert_eq!(json["matching"]["used"], m.used, "{name}");
        assert_eq!(
            json["matching"]["refused"]["nothing_pinned"], r.nothing_pinned,
            "{name}"
        );
        assert!(json["matching"]["wall_drives"]["taken"].is_u64(), "{name}");
    }
}

/// A drive straight at a wall close ahead measures the flow's scale: the seed mat without
/// tags has two on every seed tried, each taken by a filter that does not yet know it.
#[test]
fn drives_at_a_near_wall_are_counted() {
    for seed in 1..=3 {
        let out = match run(&scenario("seed-mat-no-tags.toml"), PoseMode::Slam, seed) {
            Ok(out) => out,
            Err(e) => panic!("seed {seed}: {e}"),
        };
        let Some(m) = out.figures.matching else {
            panic!("seed {seed}: no matching figures");
        };
        let w = m.wall_drives;
        assert!(w.taken >= 1, "seed {seed}: {w:?}");
        assert_eq!(w.refused, 0, "seed {seed}: {w:?}");
    }
}

/// Modes that do not match report no `matching` and no `match_truth`.
#[test]
fn modes_without_matching_report_none() {
    for mode in [
        PoseMode::Filter,
        PoseMode::DeadReckoning,
        PoseMode::Tags,
        PoseMode::Truth,
    ] {
        let out = match run(&scenario("seed-mat.toml"), mode, 1) {
            Ok(out) => out,
            Err(e) => panic!("{mode:?}: {e}"),
        };
        assert_eq!(out.figures.matching, None, "{mode:?}");
        assert_eq!(out.figures.match_truth, None, "{mode:?}");
        let json = serde_json::to_value(&out.figures).expect("figures serialise");
        assert!(json.get("matching").is_none(), "{mode:?}");
        assert!(json.get("match_truth").is_none(), "{mode:?}");
    }
}
