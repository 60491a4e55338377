//! `pointlet serve`: an HTTP/1.1 server of pointlet stores for the web viewer and for remote
//! readers.
//!
//! [`Server::bind`] takes a [`ServeConfig`] (store files and folders, the address, an optional
//! viewer folder), resolves what will be served once ([`catalog`]), and serves on a tokio
//! runtime of its own:
//! - `GET /stores.json`: the stores, with size, point count, bounds and ETag ([`listing`]);
//! - `GET|HEAD /stores/NAME.pointlet`: the store's bytes, with one byte range per request
//!   ([`ranges`]), strong ETags and the conditional headers ([`conditional`]),
//!   `Cache-Control`, `Last-Modified` ([`respond`]), read in chunks by positioned reads
//!   ([`files`]);
//! - `/` and the viewer's files from the viewer folder ([`viewer`]), or a placeholder page;
//! - CORS for any origin, preflights answered ([`routes`]).
//!
//! Requests name stores and viewer files only through tables built at startup, so no path
//! outside them can be reached.

pub mod catalog;
pub mod conditional;
pub mod config;
mod error;
pub mod files;
pub mod listing;
pub mod mime;
pub mod ranges;
pub mod respond;
mod routes;
mod server;
pub mod viewer;

pub use catalog::{ServedStore, StoreInfo};
pub use config::{ServeConfig, DEFAULT_BIND};
pub use error::ServeError;
pub use server::{RunningServer, Server, ShutdownHandle, GRACE};
