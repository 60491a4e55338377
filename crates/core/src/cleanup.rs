//! Temporary files that must not outlive an interrupted process.
//!
//! Writers create their temporary outputs and run files through [`create`] and end them with
//! [`persist`] (renamed into place) or [`remove`]; a signal handler calls [`remove_all_and_exit`].
//! They take one lock (`remove` only to forget the file), and the exit path never releases it:
//! a file is either registered before the handler runs (and removed by it) or never created.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn temporaries() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic while holding the lock leaves the list itself intact.
    TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner())
}

/// Opens `path` with `options` and registers it as temporary.
pub fn create(path: &Path, options: &OpenOptions) -> std::io::Result<File> {
    let mut temps = temporaries();
    let file = options.open(path)?;
    temps.push(path.to_path_buf());
    Ok(file)
}

/// Renames a temporary file into place; it is no longer temporary.
pub fn persist(temporary: &Path, to: &Path) -> std::io::Result<()> {
    let mut temps = temporaries();
    std::fs::rename(temporary, to)?;
    temps.retain(|p| p != temporary);
    Ok(())
}

/// Removes a temporary file (if it still exists) and forgets it.
pub fn remove(temporary: &Path) {
    // Unlinked outside the lock: freeing a run file's pages takes milliseconds, and the 36 runs
    // of a 200 M-point build removed at once waited 1.2 thread-seconds for it (GPU machine).
    // Still registered while it is unlinked, so an interrupt meanwhile removes it too.
    let _ = std::fs::remove_file(temporary);
    temporaries().retain(|p| p != temporary);
}

/// The temporary files that exist now.
#[cfg(test)]
fn registered() -> Vec<PathBuf> {
    temporaries().clone()
}

/// Removes every registered temporary file and ends the process with `code`.
pub fn remove_all_and_exit(code: i32) -> ! {
    let temps = temporaries();
    for p in temps.iter() {
        let _ = std::fs::remove_file(p);
    }
    // Exiting with the lock held keeps other threads from creating new temporaries.
    std::process::exit(code)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn created_files_are_registered_until_persisted_or_removed() {
        let dir = std::env::temp_dir().join(format!("pointlet-cleanup-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b, out) = (dir.join("a.tmp"), dir.join("b.tmp"), dir.join("out"));
        let mut o = OpenOptions::new();
        o.write(true).create_new(true);
        create(&a, &o).unwrap();
        create(&b, &o).unwrap();
        assert!(registered().contains(&a) && registered().contains(&b));
        assert!(create(&a, &o).is_err(), "create_new on an existing file");
        persist(&a, &out).unwrap();
        remove(&b);
        assert!(!registered().contains(&a) && !registered().contains(&b));
        assert!(out.exists() && !b.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
