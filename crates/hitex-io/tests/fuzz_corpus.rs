//! Replays every checked-in fuzz input (the seeds and the minimised crashes
//! under `fuzz/`) through the same entry points the libFuzzer targets call.
//! A crash found by `scripts/fuzz` lands in `fuzz/regressions/TARGET/` and is
//! replayed here on every test run.

use hitex_io::fuzz::{Target, run};
use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(rd) => rd.filter_map(|e| e.ok()).map(|e| e.path()).filter(|p| p.is_file()).collect(),
        Err(_) => Vec::new(),
    };
    v.sort();
    v
}

#[test]
fn every_target_has_a_fuzz_binary_and_seeds() {
    for t in Target::ALL {
        let bin = fuzz_dir().join("fuzz_targets").join(format!("{}.rs", t.name()));
        assert!(bin.is_file(), "no fuzz target {}", bin.display());
        assert!(!files(&fuzz_dir().join("seeds").join(t.name())).is_empty(), "no seeds for {}", t.name());
    }
    // and no fuzz binary without an entry point
    for f in files(&fuzz_dir().join("fuzz_targets")) {
        let stem = f.file_stem().and_then(|s| s.to_str()).unwrap_or_default().to_string();
        assert!(Target::from_name(&stem).is_some(), "fuzz target {stem} has no hitex_io::fuzz::Target");
    }
}

#[test]
fn seeds_and_regressions_replay_without_panic() {
    let mut replayed = 0;
    for t in Target::ALL {
        let mut accepted = 0;
        let seeds = files(&fuzz_dir().join("seeds").join(t.name()));
        for f in &seeds {
            let data = std::fs::read(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            accepted += run(t, &data) as usize;
            replayed += 1;
        }
        // the seeds are valid files: a reader that refuses all of them has broken
        assert!(accepted > 0, "{}: no seed was accepted", t.name());
        for f in files(&fuzz_dir().join("regressions").join(t.name())) {
            let data = std::fs::read(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            run(t, &data);
            replayed += 1;
        }
    }
    println!("replayed {replayed} fuzz inputs");
}
