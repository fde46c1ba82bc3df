//! Folders for the unit tests: removed when the test ends, kept when it
//! fails (for a look at what was written).

use std::path::{Path, PathBuf};

/// A test's folder under the system's temporary folder, unique to the
/// process; removed with everything in it when dropped unless the thread
/// is panicking.
pub(crate) struct TestDir(PathBuf);

impl TestDir {
    /// `hitex-NAME-PID`, emptied and not created (for writers that make
    /// their own folder).
    pub(crate) fn at(name: &str) -> Self {
        let d = std::env::temp_dir().join(format!("hitex-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        TestDir(d)
    }

    /// `hitex-NAME-PID`, empty.
    pub(crate) fn fresh(name: &str) -> Self {
        let d = Self::at(name);
        if let Err(e) = std::fs::create_dir_all(&d.0) {
            panic!("cannot make {}: {e}", d.0.display());
        }
        d
    }
}

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
