//! What the engine's GPU tests share: the adapter (lavapipe on CI; a test never skips without
//! one) and stores built from generated scenes.

#![allow(dead_code)]

use pointlet_gpu::{AdapterRequest, GpuContext};
use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::PointReader;
use pointlet_store::{BuildConfig, StoreBuilder};
use std::path::Path;

pub fn context() -> GpuContext {
    GpuContext::new(&AdapterRequest::default()).unwrap_or_else(|e| {
        panic!("GPU tests need a Vulkan adapter (CI installs mesa-vulkan-drivers): {e}")
    })
}

/// A store of the generated scene of `points` points and `seed`, in about `pointlets`
/// pointlets.
pub fn build_store(path: &Path, points: u64, seed: u64, pointlets: u64) {
    let generator = SceneGenerator::new(SceneConfig { points, seed });
    let meta = generator.meta();
    let config = BuildConfig {
        target_pointlets: pointlets,
        ..Default::default()
    };
    let mut builder =
        StoreBuilder::create(path, config, &meta, vec!["test".into()]).expect("builder");
    let mut reader = generator.reader();
    while let Some(b) = reader.read_batch(1 << 16).expect("generate") {
        builder.push(&b).expect("push");
    }
    builder.finish().expect("finish");
}
