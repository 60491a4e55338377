//! Primitives every Pointlet stage shares: f64 bounds, space-filling-curve keys,
//! seeded permutations, the point schema and the structure-of-arrays point batch.

pub mod aabb;
pub mod camera;
pub mod cleanup;
pub mod codes;
pub mod color;
pub mod crs;
pub mod density;
pub mod extra;
pub mod lod;
pub mod order;
pub mod partition;
pub mod parts;
pub mod path;
pub mod points;
pub mod progressive;
pub mod rows;
pub mod shuffle;
pub mod size;

pub use aabb::Aabb;
pub use camera::Camera;
pub use parts::{PartError, PartedSource};
pub use points::{
    flags, LasFields, PointBatch, PointLayout, Quantization, SourceMeta, Vlr, WAVEFORM_BYTES,
};
