//! The tileset: `tileset.json` of 3D Tiles 1.0 and 1.1 parsed (serde) and flattened into an
//! arena of [`Tile`]s in world space (3D Tiles 1.1 §"Tileset JSON", §"Tiles").
//!
//! Loading walks the tree depth first. Each tile gets its world transform (the parent's times
//! its own `transform`, 16 numbers column-major, in f64; refused when not finite, not affine
//! or singular, alone or accumulated), its bounding volume in world space ([`crate::volume`]),
//! its geometric error, its refinement (`ADD`/`REPLACE`, inherited from the parent when absent;
//! `REPLACE` for a root without one) and its content URIs (1.0 `content.uri` or the older
//! `content.url`; 1.1 `content` and `contents`), resolved against the URI of the tileset file.
//! A content URI ending in `.json` is an external tileset: it is loaded and its root becomes a
//! child of the tile that names it, its transform composed with that tile's world transform.
//! A chain of external tilesets that comes back to one of its own files is refused with the
//! chain of URIs; [`LoadLimits`] bound the depth, the tile count and the nesting of external
//! tilesets. Implicit tiling (1.1 `implicitTiling`) is reported as unsupported.

use crate::content::{ContentContext, TilePoints, UpAxis};
use crate::source::{resolve_uri, strip_query_and_fragment, TileSource};
use crate::transform::Transform;
use crate::volume::{BoundingVolume, VolumeSpec};
use crate::TilesError;
use serde::Deserialize;

/// How a tile's content relates to its children's (3D Tiles §"Refinement").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refine {
    /// Children add to the parent's content.
    Add,
    /// Children replace the parent's content.
    Replace,
}

/// Bounds that refuse absurd tilesets before they exhaust memory or the stack.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadLimits {
    /// Tile levels from the root, external tilesets included.
    pub max_depth: usize,
    /// Tiles in all, external tilesets included.
    pub max_tiles: usize,
    /// External tilesets nested in each other.
    pub max_external_depth: usize,
}

impl Default for LoadLimits {
    fn default() -> Self {
        LoadLimits {
            max_depth: 128,
            max_tiles: 2_000_000,
            max_external_depth: 32,
        }
    }
}

/// One content of a tile.
#[derive(Clone, Debug, PartialEq)]
pub struct ContentRef {
    /// The URI resolved against the tileset file's URI.
    pub uri: String,
    /// The content's own bounding volume in world space, when given.
    pub volume: Option<BoundingVolume>,
}

/// A tile in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    pub parent: Option<usize>,
    pub children: Vec<usize>,
    /// Levels below the root (0 for the root).
    pub depth: usize,
    /// The tile's path in its tileset file (`root.children[2].children[0]`).
    pub path: String,
    /// Index of the tileset file it came from in [`Tileset::files`].
    pub file: usize,
    pub volume: BoundingVolume,
    pub geometric_error: f64,
    pub refine: Refine,
    /// The tile's world transform (every ancestor's transform and its own).
    pub transform: Transform,
    /// Renderable contents (external tilesets are children instead).
    pub contents: Vec<ContentRef>,
}

/// One tileset JSON file of the tileset (the first is the root file).
#[derive(Clone, Debug, PartialEq)]
pub struct TilesetFile {
    pub uri: String,
    /// `asset.version`.
    pub version: String,
    /// The file's top-level `geometricError`.
    pub geometric_error: f64,
    /// `asset.gltfUpAxis` (Y unless stated).
    pub up_axis: UpAxis,
    /// The tile that references this file (`None` for the root file).
    pub referenced_by: Option<usize>,
    /// This file's root tile.
    pub root: usize,
}

/// A loaded tileset: tiles in an arena, the root first.
#[derive(Clone, Debug, PartialEq)]
pub struct Tileset {
    pub tiles: Vec<Tile>,
    pub files: Vec<TilesetFile>,
}

// The JSON shapes, as far as this crate reads them (unknown fields are ignored).

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct TilesetJson {
    asset: AssetJson,
    geometric_error: Option<f64>,
    root: TileJson,
    #[serde(default)]
    extensions_required: Vec<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct AssetJson {
    version: String,
    gltf_up_axis: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct TileJson {
    bounding_volume: Option<VolumeJson>,
    geometric_error: Option<f64>,
    refine: Option<String>,
    transform: Option<Vec<f64>>,
    content: Option<ContentJson>,
    contents: Option<Vec<ContentJson>>,
    #[serde(default)]
    children: Vec<TileJson>,
    implicit_tiling: Option<serde_json::Value>,
}

#[derive(Deserialize)]
struct VolumeJson {
    #[serde(rename = "box")]
    oriented_box: Option<Vec<f64>>,
    sphere: Option<Vec<f64>>,
    region: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct ContentJson {
    uri: Option<String>,
    url: Option<String>,
    bounding_volume: Option<VolumeJson>,
}

/// Tileset-level extensions that change nothing for reading points.
const HARMLESS_REQUIRED: &[&str] = &["3DTILES_content_gltf"];

impl Tileset {
    /// Loads the tileset at `uri` (and its external tilesets) from `source`.
    pub fn load(source: &dyn TileSource, uri: &str) -> Result<Tileset, TilesError> {
        Tileset::load_with(source, uri, &LoadLimits::default())
    }

    pub fn load_with(
        source: &dyn TileSource,
        uri: &str,
        limits: &LoadLimits,
    ) -> Result<Tileset, TilesError> {
        let mut loader = Loader {
            source,
            limits,
            tileset: Tileset {
                tiles: Vec::new(),
                files: Vec::new(),
            },
            chain: Vec::new(),
        };
        loader.load_file(uri, None, Transform::IDENTITY, None, 0)?;
        Ok(loader.tileset)
    }

    /// Opens a tileset file on disk: the source reads files next to it.
    pub fn open(path: &std::path::Path) -> Result<(Tileset, crate::LocalSource), TilesError> {
        let (source, uri) = crate::LocalSource::for_file(path);
        let tileset = Tileset::load(&source, &uri)?;
        Ok((tileset, source))
    }

    pub fn root(&self) -> &Tile {
        &self.tiles[0]
    }

    /// Tiles without children.
    pub fn leaves(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.tiles.len()).filter(|i| self.tiles[*i].children.is_empty())
    }

    /// Decodes content `content` of tile `tile` (errors name the tile and its file).
    pub fn read_content(
        &self,
        source: &dyn TileSource,
        tile: usize,
        content: usize,
    ) -> Result<TilePoints, TilesError> {
        let t = self
            .tiles
            .get(tile)
            .ok_or_else(|| TilesError::InvalidTile {
                uri: self.files.first().map_or(String::new(), |f| f.uri.clone()),
                tile: format!("#{tile}"),
                message: format!("no such tile: the tileset has {}", self.tiles.len()),
            })?;
        let file = &self.files[t.file];
        let wrap = |e: TilesError| TilesError::Tile {
            tileset: file.uri.clone(),
            tile: t.path.clone(),
            source: Box::new(e),
        };
        let c = t.contents.get(content).ok_or_else(|| {
            wrap(TilesError::tile(
                &file.uri,
                &t.path,
                format!("no content {content}: the tile has {}", t.contents.len()),
            ))
        })?;
        let bytes = source.read(&c.uri).map_err(wrap)?;
        let context = ContentContext {
            uri: &c.uri,
            world: t.transform,
            up_axis: file.up_axis,
            source: Some(source),
        };
        crate::content::decode(&bytes, &context).map_err(wrap)
    }

    /// Decodes every content of a tile, one [`TilePoints`] each.
    pub fn read_tile(
        &self,
        source: &dyn TileSource,
        tile: usize,
    ) -> Result<Vec<TilePoints>, TilesError> {
        let count = self.tiles.get(tile).map_or(0, |t| t.contents.len());
        (0..count)
            .map(|c| self.read_content(source, tile, c))
            .collect()
    }
}

struct Loader<'a> {
    source: &'a dyn TileSource,
    limits: &'a LoadLimits,
    tileset: Tileset,
    /// URIs of the tileset files from the root file down to the one being loaded.
    chain: Vec<String>,
}

/// What a tile inherits from the tile above it.
#[derive(Clone, Copy)]
struct Parent {
    index: Option<usize>,
    world: Transform,
    refine: Option<Refine>,
    depth: usize,
}

impl Loader<'_> {
    fn load_file(
        &mut self,
        uri: &str,
        referenced_by: Option<usize>,
        world: Transform,
        refine: Option<Refine>,
        depth: usize,
    ) -> Result<usize, TilesError> {
        let key = strip_query_and_fragment(uri).to_string();
        if self.chain.contains(&key) {
            let mut chain = self.chain.clone();
            chain.push(key);
            return Err(TilesError::Cycle { chain });
        }
        if self.chain.len() > self.limits.max_external_depth {
            return Err(TilesError::Limit {
                uri: uri.to_string(),
                message: format!(
                    "external tilesets nested more than {} deep (through {})",
                    self.limits.max_external_depth,
                    self.chain.join(" -> ")
                ),
            });
        }
        let bytes = self.source.read(uri)?;
        let json: TilesetJson =
            serde_json::from_slice(&bytes).map_err(|source| TilesError::Json {
                uri: uri.to_string(),
                source,
            })?;
        let major = json.asset.version.split('.').next().unwrap_or("");
        if !(major == "0" || major == "1") {
            return Err(TilesError::unsupported(
                uri,
                format!(
                    "3D Tiles version {} (1.0 and 1.1 are read)",
                    json.asset.version
                ),
            ));
        }
        let unknown: Vec<&String> = json
            .extensions_required
            .iter()
            .filter(|e| !HARMLESS_REQUIRED.contains(&e.as_str()))
            .collect();
        if !unknown.is_empty() {
            return Err(TilesError::unsupported(
                uri,
                format!("the tileset requires extensions {unknown:?}"),
            ));
        }
        let up_axis = match json.asset.gltf_up_axis.as_deref() {
            None | Some("Y") | Some("y") => UpAxis::Y,
            Some("Z") | Some("z") => UpAxis::Z,
            Some("X") | Some("x") => UpAxis::X,
            Some(other) => {
                return Err(TilesError::tile(
                    uri,
                    "asset",
                    format!("gltfUpAxis '{other}' is not X, Y or Z"),
                ))
            }
        };
        let file = self.tileset.files.len();
        self.tileset.files.push(TilesetFile {
            uri: uri.to_string(),
            version: json.asset.version.clone(),
            geometric_error: json.geometric_error.unwrap_or(0.0),
            up_axis,
            referenced_by,
            root: self.tileset.tiles.len(),
        });
        self.chain.push(key);
        let parent = Parent {
            index: referenced_by,
            world,
            refine,
            depth,
        };
        let root = self.add_tile(&json.root, file, uri, "root".to_string(), parent)?;
        self.chain.pop();
        Ok(root)
    }

    fn add_tile(
        &mut self,
        json: &TileJson,
        file: usize,
        file_uri: &str,
        path: String,
        parent: Parent,
    ) -> Result<usize, TilesError> {
        let fail = |message: String| TilesError::tile(file_uri, &path, message);
        if parent.depth > self.limits.max_depth {
            return Err(TilesError::Limit {
                uri: file_uri.to_string(),
                message: format!(
                    "tile {path} is more than {} levels deep",
                    self.limits.max_depth
                ),
            });
        }
        if self.tileset.tiles.len() >= self.limits.max_tiles {
            return Err(TilesError::Limit {
                uri: file_uri.to_string(),
                message: format!("more than {} tiles (at tile {path})", self.limits.max_tiles),
            });
        }
        if json.implicit_tiling.is_some() {
            return Err(TilesError::unsupported(
                file_uri,
                format!("tile {path} uses implicit tiling"),
            ));
        }
        let local = match &json.transform {
            None => Transform::IDENTITY,
            Some(v) => {
                let m: [f64; 16] =
                    v.as_slice()
                        .try_into()
                        .map_err(|_| TilesError::BadTransform {
                            uri: file_uri.to_string(),
                            tile: path.clone(),
                            message: format!("has {} numbers instead of 16", v.len()),
                        })?;
                Transform(m)
            }
        };
        let bad_transform = |message: String| TilesError::BadTransform {
            uri: file_uri.to_string(),
            tile: path.clone(),
            message,
        };
        if let Some(defect) = local.defect() {
            return Err(bad_transform(defect));
        }
        let world = parent.world.mul(&local);
        if let Some(defect) = world.defect() {
            return Err(bad_transform(format!("accumulated from the root {defect}")));
        }
        let volume = volume_spec(
            json.bounding_volume
                .as_ref()
                .ok_or_else(|| fail("has no boundingVolume".into()))?,
        )
        .map_err(&fail)?
        .to_world(&world);
        let geometric_error = json
            .geometric_error
            .ok_or_else(|| fail("has no geometricError".into()))?;
        if !(geometric_error >= 0.0 && geometric_error.is_finite()) {
            return Err(fail(format!(
                "geometricError {geometric_error} is negative or not finite"
            )));
        }
        let refine = match json.refine.as_deref() {
            None => parent.refine.unwrap_or(Refine::Replace),
            Some(r) if r.eq_ignore_ascii_case("ADD") => Refine::Add,
            Some(r) if r.eq_ignore_ascii_case("REPLACE") => Refine::Replace,
            Some(r) => return Err(fail(format!("refine '{r}' is neither ADD nor REPLACE"))),
        };

        let mut contents = Vec::new();
        let mut external = Vec::new();
        for content in json.content.iter().chain(json.contents.iter().flatten()) {
            let reference = content
                .uri
                .as_deref()
                .or(content.url.as_deref())
                .ok_or_else(|| fail("has a content without uri".into()))?;
            let resolved = resolve_uri(file_uri, reference);
            if is_tileset_uri(&resolved) {
                external.push(resolved);
                continue;
            }
            let volume = match &content.bounding_volume {
                None => None,
                Some(v) => Some(
                    volume_spec(v)
                        .map_err(|m| fail(format!("content {m}")))?
                        .to_world(&world),
                ),
            };
            contents.push(ContentRef {
                uri: resolved,
                volume,
            });
        }

        let index = self.tileset.tiles.len();
        self.tileset.tiles.push(Tile {
            parent: parent.index,
            children: Vec::new(),
            depth: parent.depth,
            path: path.clone(),
            file,
            volume,
            geometric_error,
            refine,
            transform: world,
            contents,
        });
        if let Some(p) = parent.index {
            self.tileset.tiles[p].children.push(index);
        }
        let below = Parent {
            index: Some(index),
            world,
            refine: Some(refine),
            depth: parent.depth + 1,
        };
        for (i, child) in json.children.iter().enumerate() {
            self.add_tile(
                child,
                file,
                file_uri,
                format!("{path}.children[{i}]"),
                below,
            )?;
        }
        for uri in external {
            self.load_file(&uri, Some(index), world, Some(refine), parent.depth + 1)?;
        }
        Ok(index)
    }
}

fn volume_spec(v: &VolumeJson) -> Result<VolumeSpec, String> {
    if let Some(b) = &v.oriented_box {
        VolumeSpec::from_box(b)
    } else if let Some(r) = &v.region {
        VolumeSpec::from_region(r)
    } else if let Some(s) = &v.sphere {
        VolumeSpec::from_sphere(s)
    } else {
        Err("boundingVolume has no box, region or sphere".into())
    }
}

/// True when a content URI names a tileset JSON file (an external tileset).
fn is_tileset_uri(uri: &str) -> bool {
    strip_query_and_fragment(uri)
        .to_ascii_lowercase()
        .ends_with(".json")
}
