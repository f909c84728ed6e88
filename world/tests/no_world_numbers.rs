//! No world's numbers are written by hand in `slam-core/src` or `firmware/src`: the grid,
//! the tags, the start and the route come from a scenario file (through this crate). This
//! scans their code outside `#[cfg(test)]` items for the shapes such numbers take, so a
//! seed constant or a hand-sized grid that comes back fails here.

use std::path::{Path, PathBuf};

/// Names the seed's hand-written world went by.
const SEED_NAMES: [&str; 5] = [
    "seed_mat",
    "SEED_TAGS",
    "SEED_START",
    "SEED_ROUTE",
    "SeedSlam",
];

/// Text that, followed by a number, writes a world's number by hand: a grid's size, a
/// grid's place, a tag's or start's place, a route's leg.
const BEFORE_A_NUMBER: [&str; 11] = [
    "Slam<",
    "Slam::<",
    "GridMap<",
    "GridMap::<",
    "cell_mm: ",
    "origin_x_mm: ",
    "origin_y_mm: ",
    "x_mm: ",
    "y_mm: ",
    "Pose::from_mm_mdeg(",
    "mdeg: ",
];

/// The lines of `text` outside `#[cfg(test)]` items, with their line numbers.
fn code_lines(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut skipping = false;
    let (mut depth, mut opened) = (0i64, false);
    for (i, line) in text.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        if !skipping && line.trim() == "#[cfg(test)]" {
            (skipping, depth, opened) = (true, 0, false);
            continue;
        }
        if skipping {
            depth += code.matches('{').count() as i64 - code.matches('}').count() as i64;
            opened |= code.contains('{');
            if (opened && depth <= 0) || (!opened && code.trim_end().ends_with(';')) {
                skipping = false;
            }
            continue;
        }
        out.push((i + 1, code));
    }
    out
}

/// What in `text` looks like a world's number written by hand: (line, what).
fn world_numbers(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, code) in code_lines(text) {
        for name in SEED_NAMES {
            if code.contains(name) {
                found.push((n, format!("`{name}`")));
            }
        }
        if code.contains("KnownTag {") && !code.contains("struct KnownTag {") {
            found.push((n, "a tag written out (`KnownTag { .. }`)".into()));
        }
        for before in BEFORE_A_NUMBER {
            for (at, _) in code.match_indices(before) {
                // The whole name, not the end of a longer one (`heading_mdeg: ` is tuning).
                let joined = code[..at]
                    .chars()
                    .next_back()
                    .is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
                if joined {
                    continue;
                }
                let rest = code[at + before.len()..].trim_start();
                if rest.starts_with(|c: char| c.is_ascii_digit() || c == '-') {
                    found.push((n, format!("a number after `{before}`")));
                }
            }
        }
    }
    found
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn no_world_numbers_in_the_core_or_the_firmware() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for dir in ["slam-core/src", "firmware/src"] {
        let before = files.len();
        rust_files(&root.join(dir), &mut files);
        assert!(files.len() > before, "no Rust files under {dir}");
    }
    let mut found = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap_or_default();
        for (line, what) in world_numbers(&text) {
            found.push(format!("{}:{line}: {what}", file.display()));
        }
    }
    assert!(
        found.is_empty(),
        "world numbers written by hand (they belong in a scenario file, read through the \
         world crate):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_scan_finds_what_it_looks_for_and_skips_tests() {
    let bad = "pub const START: Pose = SlamConfig::SEED_START;\n\
               type S = Slam<46, 46>;\n\
               const T: KnownTag = KnownTag { id: 11, x_mm: 700, y_mm: 1950 };\n\
               let g = GridGeometry { cell_mm: 50, origin_x_mm: -150, origin_y_mm: -150 };\n\
               let leg = Leg::Turn { mdeg: 360_000, rate_mdps: 1 };\n";
    let found = world_numbers(bad);
    let lines: Vec<usize> = found.iter().map(|f| f.0).collect();
    for line in 1..=5 {
        assert!(lines.contains(&line), "line {line} not caught: {found:?}");
    }
    let fine = "pub struct KnownTag {\n    pub x_mm: i32,\n}\n\
                type S = Slam<GRID_COLUMNS, GRID_ROWS>;\n\
                #[cfg(test)]\nmod tests {\n    const T: KnownTag = KnownTag { id: 1, x_mm: 2, y_mm: 3 };\n}\n\
                #[cfg(test)]\nconst G: usize = 46;\n\
                let n = Slam::<W, H>::new(config, start); // Slam<46, 46> in a comment\n\
                const E: EstimatorConfig = EstimatorConfig { initial_heading_mdeg: 2000 };\n";
    assert_eq!(world_numbers(fine), Vec::<(usize, String)>::new());
}
