//! OGC 3D Tiles point-cloud tilesets read into plain data: the tile tree in world space
//! ([`Tileset`], an arena of [`Tile`]s with bounding volumes, geometric errors, refinement and
//! content URIs) and each tile's points ([`TilePoints`]: f64 world positions, RGBA8 colours,
//! normals, named per-point attributes). No GPU, no streaming policy: those build on this.
//!
//! ```no_run
//! use pointlet_tiles::Tileset;
//! let (tileset, source) = Tileset::open("data/tileset.json".as_ref())?;
//! for leaf in tileset.leaves() {
//!     for points in tileset.read_tile(&source, leaf)? {
//!         println!("{}: {} points", points.uri, points.len());
//!     }
//! }
//! # Ok::<(), pointlet_tiles::TilesError>(())
//! ```
//!
//! Modules: [`tileset`] (tileset JSON, external tilesets, limits), [`volume`] (bounding
//! volumes), [`transform`] (f64 matrices), [`source`] (where bytes come from, URI resolution),
//! [`content`] (the output and the choice of decoder), [`pnts`] and its batch table, [`gltf`]
//! with `meshopt` decompression and `metadata` (EXT_mesh_features, EXT_structural_metadata),
//! [`error`].

mod batch_table;
mod bytes;
pub mod content;
pub mod error;
pub mod gltf;
mod meshopt;
mod metadata;
pub mod pnts;
pub mod points;
pub mod select;
pub mod source;
pub mod stream;
pub mod tileset;
pub mod transform;
pub mod volume;
pub mod write;

pub use content::{AttributeValues, ContentContext, PointAttribute, TilePoints, UpAxis};
pub use error::TilesError;
pub use select::{plan, screen_space_error, TilePlan, TileView, WantedTile};
pub use source::{resolve_uri, LocalSource, TileSource};
pub use stream::{TileData, TileStream, TileStreamConfig, TileStreamStats};
pub use tileset::{ContentRef, LoadLimits, Refine, Tile, Tileset, TilesetFile};
pub use transform::Transform;
pub use volume::{BoundingVolume, OrientedBox, Sphere};
