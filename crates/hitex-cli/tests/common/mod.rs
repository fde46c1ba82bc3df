//! What every CLI test needs: run the binary, a fresh folder, its error lines.

#![allow(dead_code)] // each test file uses its own part

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// Runs `hitex` with `args`.
pub fn hitex(args: &[&str]) -> Output {
    match Command::new(env!("CARGO_BIN_EXE_hitex")).args(args).output() {
        Ok(o) => o,
        Err(e) => panic!("cannot run hitex: {e}"),
    }
}

/// An empty folder for test `name`, unique to this process; removed when
/// the test ends, kept (for a look at what the command wrote) when it fails.
pub fn tmp(name: &str) -> TestDir {
    let d = std::env::temp_dir().join(format!("hitex-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TestDir(d)
}

/// A test's folder: a path, removed with everything in it when dropped
/// unless the thread is panicking (a failed test keeps its files).
pub struct TestDir(PathBuf);

impl std::ops::Deref for TestDir {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl AsRef<Path> for TestDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept {} for a look", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// The error lines hitex printed (the GL driver may add noise lines of its own).
pub fn error_lines(o: &Output) -> Vec<String> {
    // progress lines ("hitex: export: 15/144 images (10%)") are not messages
    String::from_utf8_lossy(&o.stderr)
        .lines()
        .filter(|l| l.starts_with("hitex:") && !l.ends_with("%)"))
        .map(str::to_string)
        .collect()
}

/// A small tmpfs mounted for one test, unmounted when dropped.
pub struct Tmpfs {
    /// Where it is mounted.
    pub dir: PathBuf,
    /// The test folder it is mounted in, removed after the unmount.
    _parent: Option<TestDir>,
}

impl Tmpfs {
    /// Mounts `kib` KiB at a fresh folder for `name`; `None` (and SKIPPED on
    /// stderr) where mounting is not allowed, a panic then if `HITEX_REQUIRE_FAULTS=1`.
    pub fn mount(name: &str, kib: u32) -> Option<Tmpfs> {
        let parent = tmp(name);
        let mut fs = Self::mount_at(&parent.join("mnt"), kib)?;
        fs._parent = Some(parent);
        Some(fs)
    }

    /// Like [`Tmpfs::mount`], at `dir`.
    pub fn mount_at(dir: &Path, kib: u32) -> Option<Tmpfs> {
        let name = dir.display();
        let dir = dir.to_path_buf();
        std::fs::create_dir_all(&dir).ok()?;
        let opt = format!("size={kib}k");
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &opt, "hitex-test", dir.to_str()?])
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            let msg = format!("SKIPPED {name}: cannot mount a tmpfs (needs root)");
            if std::env::var("HITEX_REQUIRE_FAULTS").is_ok_and(|v| v == "1") {
                panic!("{msg}, and HITEX_REQUIRE_FAULTS=1");
            }
            say_skipped(&msg);
            return None;
        }
        Some(Tmpfs { dir, _parent: None })
    }

    /// Fills the file system to the last byte.
    pub fn fill(&self) {
        use std::io::Write;
        let Ok(mut f) = std::fs::File::create(self.dir.join("filler")) else { return };
        let block = vec![0xa5u8; 4096];
        while f.write_all(&block).is_ok() {}
        let _ = f.write_all(&block[..1]);
        while f.write_all(&block[..1]).is_ok() {}
    }

    /// Remounts it read-only.
    pub fn read_only(&self) {
        let ok = Command::new("mount")
            .args(["-o", "remount,ro", self.dir.to_str().unwrap_or_default()])
            .status()
            .is_ok_and(|s| s.success());
        assert!(ok, "remount read-only failed");
    }

    /// Files other than `keep`, by name (temporary files would show up here).
    pub fn leftovers(&self, keep: &[&str]) -> Vec<String> {
        let mut v = Vec::new();
        walk(&self.dir, &mut v);
        v.retain(|n| !keep.iter().any(|k| n.ends_with(k)));
        v
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
    }
}

/// Every file below `dir`.
pub fn walk(dir: &Path, out: &mut Vec<String>) {
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else {
                out.push(p.to_string_lossy().into_owned());
            }
        }
    }
}

/// Prints a test's SKIPPED line to the process's standard error itself,
/// past the test harness's capture, so that a skip is seen in every log.
pub fn say_skipped(msg: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{msg}");
}
