//! What every CLI test needs: run the binary, a fresh folder, its error lines.

#![allow(dead_code)] // each test file uses its own part

use std::path::PathBuf;
use std::process::{Command, Output};

/// Runs `hitex` with `args`.
pub fn hitex(args: &[&str]) -> Output {
    match Command::new(env!("CARGO_BIN_EXE_hitex")).args(args).output() {
        Ok(o) => o,
        Err(e) => panic!("cannot run hitex: {e}"),
    }
}

/// An empty folder for test `name`, unique to this process.
pub fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hitex-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The error lines hitex printed (the GL driver may add noise lines of its own).
pub fn error_lines(o: &Output) -> Vec<String> {
    String::from_utf8_lossy(&o.stderr).lines().filter(|l| l.starts_with("hitex:")).map(str::to_string).collect()
}
