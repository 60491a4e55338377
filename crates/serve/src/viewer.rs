//! The web viewer's files, from a folder listed once when the server starts.
//!
//! The folder is walked (at most [`MAX_DEPTH`] levels and [`MAX_FILES`] files): regular files
//! are recorded under their path relative to it (`index.html`, `pkg/viewer_bg.wasm`), hidden
//! entries (`.git`, …) are passed over, and symlinks are skipped with a note. A request's
//! path, percent-decoded, is looked up in that table and nothing else: `..`, encoded
//! separators, backslashes or absolute paths name no entry, and a folder is never listed
//! (`/` and paths ending in `/` mean their `index.html`).

use crate::error::ServeError;
use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

/// Folder levels walked below the viewer folder.
pub const MAX_DEPTH: usize = 16;
/// Files recorded at most.
pub const MAX_FILES: usize = 10_000;

/// The viewer's files by URL path (without the leading `/`).
#[derive(Debug, Default)]
pub struct ViewerFiles {
    files: HashMap<String, PathBuf>,
}

impl ViewerFiles {
    /// Lists `dir`; the notes say what was skipped.
    pub fn scan(dir: &Path) -> Result<(ViewerFiles, Vec<String>), ServeError> {
        let viewer_error = |message: String| ServeError::Viewer {
            path: dir.to_path_buf(),
            message,
        };
        let root = fs::canonicalize(dir).map_err(|e| viewer_error(e.to_string()))?;
        if !root.is_dir() {
            return Err(viewer_error("not a folder".into()));
        }
        let mut files = HashMap::new();
        let mut notes = Vec::new();
        let mut pending = vec![(root, String::new(), 0usize)];
        while let Some((folder, prefix, depth)) = pending.pop() {
            let listing = fs::read_dir(&folder)
                .map_err(|e| viewer_error(format!("listing {}: {e}", folder.display())))?;
            for entry in listing {
                let entry = entry.map_err(|e| viewer_error(e.to_string()))?;
                let Some(name) = entry.file_name().to_str().map(str::to_string) else {
                    notes.push(format!(
                        "viewer: skipped {}: the name is not UTF-8",
                        entry.path().display()
                    ));
                    continue;
                };
                if name.starts_with('.') {
                    continue;
                }
                let kind = entry.file_type().map_err(|e| viewer_error(e.to_string()))?;
                let key = format!("{prefix}{name}");
                if kind.is_symlink() {
                    notes.push(format!(
                        "viewer: skipped {}: symlinks are not followed",
                        entry.path().display()
                    ));
                } else if kind.is_dir() && depth < MAX_DEPTH {
                    pending.push((entry.path(), format!("{key}/"), depth + 1));
                } else if kind.is_file() {
                    if files.len() == MAX_FILES {
                        return Err(viewer_error(format!(
                            "more than {MAX_FILES} files (is this the viewer's folder?)"
                        )));
                    }
                    files.insert(key, entry.path());
                }
            }
        }
        Ok((ViewerFiles { files }, notes))
    }

    /// The file for a request path as it came (`/pkg/a.js`, percent-encoded).
    pub fn lookup(&self, url_path: &str) -> Option<(&str, &Path)> {
        let decoded = percent_encoding::percent_decode_str(url_path)
            .decode_utf8()
            .ok()?;
        let mut key = decoded.strip_prefix('/')?.to_string();
        if key.is_empty() || key.ends_with('/') {
            key.push_str("index.html");
        }
        self.files
            .get_key_value(&key)
            .map(|(k, p)| (k.as_str(), p.as_path()))
    }

    /// Whether the folder has an `index.html` (served at `/`).
    pub fn has_index(&self) -> bool {
        self.files.contains_key("index.html")
    }
}
