//! The stores being served, resolved once when the server starts.
//!
//! Each argument is a `NAME.pointlet` file or a folder. A path given on the command line is
//! followed wherever it points (symlinks included): naming it is the permission to serve it.
//! Inside a given folder only regular files named `NAME.pointlet` are taken, directly inside
//! (no recursion); hidden files (the builder's temporaries) are passed over silently, and
//! symlinks are skipped with a note, whatever they point to. Every store is opened and
//! validated here, and its resolved path (no symlink left in it) is all a request can ever
//! reach: requests look stores up by name, never build a path from the URL.

use crate::error::ServeError;
use crate::files::Validators;
use pointlet_core::Aabb;
use pointlet_store::Store;
use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

/// The extension of a store's file name.
pub const STORE_EXTENSION: &str = ".pointlet";

/// One store being served.
#[derive(Clone, Debug)]
pub struct ServedStore {
    /// The file name without `.pointlet`; the store is served at `/stores/NAME.pointlet`.
    pub name: String,
    /// The path as the user gave it (or the folder joined with the file name), for messages.
    pub given: PathBuf,
    /// The resolved path that requests read.
    pub path: PathBuf,
    /// The store's header facts when the server started.
    pub info: StoreInfo,
    /// The file's validators when the server started.
    pub validators: Validators,
}

/// What `stores.json` tells of a store's contents.
#[derive(Clone, Debug, PartialEq)]
pub struct StoreInfo {
    pub points: u64,
    pub pointlets: u64,
    pub bounds: Aabb,
}

impl StoreInfo {
    /// Opens the store at `path` and reads its header facts.
    pub fn read(path: &Path) -> Result<StoreInfo, pointlet_store::StoreError> {
        let store = Store::open(path)?;
        let h = store.header();
        Ok(StoreInfo {
            points: h.points,
            pointlets: h.pointlets,
            bounds: h.bounds,
        })
    }
}

/// The served stores, sorted by name, and what was passed over on the way.
#[derive(Debug, Default)]
pub struct Catalog {
    stores: Vec<ServedStore>,
    by_name: HashMap<String, usize>,
    notes: Vec<String>,
}

impl Catalog {
    /// Resolves every argument; any argument that cannot be served is an error.
    pub fn resolve(args: &[PathBuf]) -> Result<Catalog, ServeError> {
        if args.is_empty() {
            return Err(ServeError::NothingGiven);
        }
        let mut catalog = Catalog::default();
        for arg in args {
            let meta = fs::metadata(arg).map_err(|e| ServeError::io(arg, "cannot read", e))?;
            if meta.is_dir() {
                catalog.add_folder(arg)?;
            } else if meta.is_file() {
                let name = store_name(arg).ok_or_else(|| {
                    ServeError::not_servable(
                        arg,
                        "not a store: only NAME.pointlet files are served",
                    )
                })?;
                let path = fs::canonicalize(arg)
                    .map_err(|e| ServeError::io(arg, "resolving the path", e))?;
                catalog.add(name, arg.clone(), path)?;
            } else {
                return Err(ServeError::not_servable(arg, "neither a file nor a folder"));
            }
        }
        catalog.stores.sort_by(|a, b| a.name.cmp(&b.name));
        catalog.by_name = (catalog.stores.iter().enumerate())
            .map(|(i, s)| (s.name.clone(), i))
            .collect();
        Ok(catalog)
    }

    /// The stores, sorted by name.
    pub fn stores(&self) -> &[ServedStore] {
        &self.stores
    }

    /// The store served as `NAME.pointlet`.
    pub fn get(&self, name: &str) -> Option<&ServedStore> {
        self.by_name.get(name).map(|&i| &self.stores[i])
    }

    /// Entries of the given folders that were skipped, one line each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    fn add_folder(&mut self, arg: &Path) -> Result<(), ServeError> {
        let dir =
            fs::canonicalize(arg).map_err(|e| ServeError::io(arg, "resolving the path", e))?;
        let mut entries = Vec::new();
        let listing =
            fs::read_dir(&dir).map_err(|e| ServeError::io(arg, "listing the folder", e))?;
        for entry in listing {
            let entry = entry.map_err(|e| ServeError::io(arg, "listing the folder", e))?;
            entries.push(entry);
        }
        entries.sort_by_key(|e| e.file_name());
        let before = self.stores.len();
        for entry in entries {
            let given = arg.join(entry.file_name());
            let Some(name) = store_name(&given) else {
                continue;
            };
            if name.starts_with('.') {
                continue;
            }
            let kind = entry
                .file_type()
                .map_err(|e| ServeError::io(&given, "reading the file type", e))?;
            if kind.is_symlink() {
                self.notes.push(format!(
                    "{}: skipped: symlinks inside a folder are not followed (give the file itself to serve it)",
                    given.display()
                ));
            } else if kind.is_file() {
                self.add(name, given, dir.join(entry.file_name()))?;
            } else {
                self.notes
                    .push(format!("{}: skipped: not a regular file", given.display()));
            }
        }
        if self.stores.len() == before
            && !self
                .stores
                .iter()
                .any(|s| s.path.parent() == Some(dir.as_path()))
        {
            return Err(ServeError::EmptyFolder {
                path: arg.to_path_buf(),
            });
        }
        Ok(())
    }

    fn add(&mut self, name: String, given: PathBuf, path: PathBuf) -> Result<(), ServeError> {
        if let Some(other) = self.stores.iter().find(|s| s.name == name) {
            if other.path == path {
                return Ok(());
            }
            return Err(ServeError::DuplicateName {
                name,
                first: other.given.clone(),
                second: given,
            });
        }
        let meta = fs::metadata(&path).map_err(|e| ServeError::io(&given, "cannot read", e))?;
        let validators = Validators::of(&meta);
        let info = StoreInfo::read(&path)?;
        self.stores.push(ServedStore {
            name,
            given,
            path,
            info,
            validators,
        });
        Ok(())
    }
}

/// `NAME` of a path whose file name is `NAME.pointlet` (valid UTF-8, NAME not empty).
fn store_name(path: &Path) -> Option<String> {
    let file_name = path.file_name()?.to_str()?;
    let name = file_name.strip_suffix(STORE_EXTENSION)?;
    (!name.is_empty()).then(|| name.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_come_from_the_file_name() {
        assert_eq!(
            store_name(Path::new("a/city.pointlet")).as_deref(),
            Some("city")
        );
        assert_eq!(
            store_name(Path::new("a.b.pointlet")).as_deref(),
            Some("a.b")
        );
        assert_eq!(store_name(Path::new(".pointlet")), None);
        assert_eq!(store_name(Path::new("city.laz")), None);
        assert_eq!(store_name(Path::new("city.pointlet/..")), None);
    }
}
