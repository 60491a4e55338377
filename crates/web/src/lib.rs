//! The browser viewer: a store streamed over HTTP range requests and drawn on the browser's
//! WebGPU by the same GPU passes as the native renderer (LoD under a point budget, the page
//! pool, the two-pass 32-bit rasterizer, the screen passes).
//!
//! How it works: the page fetches the store's metadata (`0..data_offset`) and opens it with
//! the native validating reader over those bytes ([`sparse`]); every frame the GPU LoD's
//! feedback becomes fetches of the missing pages ([`residency`], [`ranges`]), several in
//! flight as async tasks where native builds use loader threads; arrived points are coloured
//! ([`colors`]) and uploaded with the next frame. A still camera grows the budget until every
//! visible point is drawn, then the page reports `converged`.
//!
//! Everything but the wasm glue (`app`, `fetch`) is plain logic with native tests.

pub mod colors;
pub mod params;
pub mod pick;
pub mod ranges;
pub mod residency;
pub mod sparse;
pub mod view;

#[cfg(target_arch = "wasm32")]
mod app;
#[cfg(target_arch = "wasm32")]
mod fetch;
