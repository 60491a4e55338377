//! Where tileset files and tile content come from: the [`TileSource`] trait and the local one.
//!
//! URIs are resolved by [`resolve_uri`] against the URI of the file that names them (3D Tiles
//! 1.1 §"URIs": relative URIs are relative to the referring tileset or glTF file), as plain
//! string operations following RFC 3986's merge and dot-segment removal, so that an HTTP source
//! can later take the same resolved URIs. [`LocalSource`] maps a resolved URI to a file: a URI
//! without a scheme is a path relative to its root folder (or absolute when it starts with `/`),
//! `file://` URIs are absolute paths; the query and fragment are dropped and `%XX` escapes
//! decoded. Every read is capped by a size limit checked before anything is allocated.

use crate::TilesError;
use std::io::Read;
use std::path::{Path, PathBuf};

/// A store of tileset files and tile content addressed by resolved URIs.
pub trait TileSource: Send + Sync {
    /// The whole file at `uri` (a URI already resolved by [`resolve_uri`]).
    fn read(&self, uri: &str) -> Result<Vec<u8>, TilesError>;
}

/// Files on the local file system, relative URIs under a root folder.
#[derive(Clone, Debug)]
pub struct LocalSource {
    root: PathBuf,
    max_bytes: u64,
}

/// The largest file [`LocalSource`] reads unless told otherwise (1 GiB).
pub const DEFAULT_MAX_FILE_BYTES: u64 = 1 << 30;

impl LocalSource {
    /// Relative URIs resolve under `root`.
    pub fn new(root: impl Into<PathBuf>) -> Self {
        LocalSource {
            root: root.into(),
            max_bytes: DEFAULT_MAX_FILE_BYTES,
        }
    }

    /// Refuses files larger than `max_bytes`.
    pub fn with_max_bytes(mut self, max_bytes: u64) -> Self {
        self.max_bytes = max_bytes;
        self
    }

    /// The source for a tileset file on disk and the URI of that file within it:
    /// `LocalSource::for_file("data/tileset.json")` reads under `data/` and names the tileset
    /// `tileset.json`.
    pub fn for_file(path: &Path) -> (LocalSource, String) {
        let root = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        (LocalSource::new(root), encode_path_segment(&name))
    }

    /// The file a resolved URI names.
    pub fn path_of(&self, uri: &str) -> PathBuf {
        let without_suffix = strip_query_and_fragment(uri);
        if let Some(rest) = without_suffix.strip_prefix("file://") {
            // file:///abs/path or file://host/path (the host is ignored).
            let path = match rest.find('/') {
                Some(i) => &rest[i..],
                None => rest,
            };
            return PathBuf::from(percent_decode(path));
        }
        let decoded = percent_decode(without_suffix);
        if decoded.starts_with('/') {
            PathBuf::from(decoded)
        } else {
            self.root.join(decoded)
        }
    }
}

impl TileSource for LocalSource {
    fn read(&self, uri: &str) -> Result<Vec<u8>, TilesError> {
        if has_scheme(uri) && !uri.starts_with("file:") {
            return Err(TilesError::unsupported(
                uri,
                "only local files can be read (no HTTP source yet)",
            ));
        }
        let path = self.path_of(uri);
        let error = |source| TilesError::Read {
            uri: uri.to_string(),
            location: path.display().to_string(),
            source,
        };
        let file = std::fs::File::open(&path).map_err(error)?;
        let len = file.metadata().map_err(error)?.len();
        if len > self.max_bytes {
            return Err(TilesError::Limit {
                uri: uri.to_string(),
                message: format!(
                    "file of {len} bytes is larger than the limit of {} bytes",
                    self.max_bytes
                ),
            });
        }
        let mut bytes = Vec::with_capacity(len as usize);
        // Read at most one byte past the limit: a file growing meanwhile is still capped.
        file.take(self.max_bytes + 1)
            .read_to_end(&mut bytes)
            .map_err(error)?;
        if bytes.len() as u64 > self.max_bytes {
            return Err(TilesError::Limit {
                uri: uri.to_string(),
                message: format!("file is larger than the limit of {} bytes", self.max_bytes),
            });
        }
        Ok(bytes)
    }
}

/// True when `uri` starts with a scheme (`http:`, `file:`, `data:`, ...). A one-letter
/// "scheme" is a Windows drive letter, not a scheme.
pub fn has_scheme(uri: &str) -> bool {
    match uri.find(':') {
        Some(i) if i > 1 => {
            let scheme = &uri[..i];
            scheme.starts_with(|c: char| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        _ => false,
    }
}

/// `reference` resolved against the URI of the file that contains it.
pub fn resolve_uri(base: &str, reference: &str) -> String {
    if has_scheme(reference) {
        return reference.to_string();
    }
    let base = strip_query_and_fragment(base);
    // scheme://authority of the base, kept in front of an absolute-path reference.
    let (prefix, base_path) = split_authority(base);
    if reference.starts_with("//") {
        let scheme = base.split_once(':').map(|(s, _)| s).unwrap_or("");
        return if scheme.is_empty() {
            reference.to_string()
        } else {
            format!("{scheme}:{reference}")
        };
    }
    if reference.starts_with('/') {
        return format!("{prefix}{}", remove_dot_segments(reference));
    }
    let directory = match base_path.rfind('/') {
        Some(i) => &base_path[..=i],
        None => "",
    };
    let (path, suffix) = split_suffix(reference);
    format!(
        "{prefix}{}{suffix}",
        remove_dot_segments(&format!("{directory}{path}"))
    )
}

/// The URI without `?query` and `#fragment`.
pub fn strip_query_and_fragment(uri: &str) -> &str {
    split_suffix(uri).0
}

fn split_suffix(uri: &str) -> (&str, &str) {
    match uri.find(['?', '#']) {
        Some(i) => (&uri[..i], &uri[i..]),
        None => (uri, ""),
    }
}

/// (`scheme://authority`, path) of a URI; both parts are plain strings.
fn split_authority(uri: &str) -> (&str, &str) {
    if let Some(i) = uri.find("://") {
        let after = i + 3;
        match uri[after..].find('/') {
            Some(j) => (&uri[..after + j], &uri[after + j..]),
            None => (uri, ""),
        }
    } else if has_scheme(uri) {
        let i = uri.find(':').unwrap_or(0) + 1;
        (&uri[..i], &uri[i..])
    } else {
        ("", uri)
    }
}

/// RFC 3986 §5.2.4 in spirit: `.` segments vanish, `..` removes the segment before it. A
/// relative path keeps the `..` segments that climb above its start.
fn remove_dot_segments(path: &str) -> String {
    let absolute = path.starts_with('/');
    let mut out: Vec<&str> = Vec::new();
    let segments: Vec<&str> = path.split('/').collect();
    let last = segments.len().saturating_sub(1);
    for (i, segment) in segments.iter().enumerate() {
        match *segment {
            "." => {}
            "" if i != last => {}
            ".." => {
                if matches!(out.last(), Some(s) if *s != "..") {
                    out.pop();
                } else if !absolute {
                    out.push("..");
                }
            }
            s => out.push(s),
        }
    }
    let joined = out.join("/");
    let trailing = if matches!(segments.last(), Some(&".") | Some(&"..")) && !joined.is_empty() {
        "/"
    } else {
        ""
    };
    if absolute {
        format!("/{joined}{trailing}")
    } else {
        format!("{joined}{trailing}")
    }
}

/// `%XX` escapes decoded (invalid escapes are kept as they are).
pub fn percent_decode(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = |b: u8| (b as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// A file name made safe as a relative URI (`%`, space, `?` and `#` escaped).
fn encode_path_segment(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for c in name.chars() {
        match c {
            '%' | ' ' | '?' | '#' => {
                let mut buf = [0u8; 4];
                for b in c.encode_utf8(&mut buf).bytes() {
                    out.push_str(&format!("%{b:02X}"));
                }
            }
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_relative_references_against_the_referring_file() {
        assert_eq!(
            resolve_uri("tileset.json", "points/r0.pnts"),
            "points/r0.pnts"
        );
        assert_eq!(
            resolve_uri("external/subtree.json", "../points/r0.pnts"),
            "points/r0.pnts"
        );
        assert_eq!(resolve_uri("a/b/c.json", "./d.pnts"), "a/b/d.pnts");
        assert_eq!(resolve_uri("a/c.json", "../../d.pnts"), "../d.pnts");
        assert_eq!(
            resolve_uri("https://h.org/t/tileset.json?v=1", "sub/x.glb"),
            "https://h.org/t/sub/x.glb"
        );
        assert_eq!(
            resolve_uri("https://h.org/t/tileset.json", "/y.glb"),
            "https://h.org/y.glb"
        );
        assert_eq!(
            resolve_uri("https://h.org/t/tileset.json", "//cdn.org/z.glb"),
            "https://cdn.org/z.glb"
        );
        assert_eq!(resolve_uri("t/tileset.json", "http://x/y"), "http://x/y");
        assert_eq!(resolve_uri("t/tileset.json", "x.pnts?v=2"), "t/x.pnts?v=2");
    }

    #[test]
    fn local_paths_drop_queries_and_decode_escapes() {
        let source = LocalSource::new("/data");
        assert_eq!(
            source.path_of("a%20b/c.pnts?x=1"),
            PathBuf::from("/data/a b/c.pnts")
        );
        assert_eq!(source.path_of("file:///t/x.glb"), PathBuf::from("/t/x.glb"));
        assert_eq!(percent_decode("%4"), "%4");
        assert_eq!(percent_decode("a%2"), "a%2");
    }
}
