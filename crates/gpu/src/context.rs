//! The headless wgpu device: adapter choice, feature detection, limits.

use crate::GpuError;
use std::sync::{Arc, Mutex};

/// What the chosen adapter can do, decided once at start-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capabilities {
    /// 64-bit atomicMin/Max: the single-atomic closest-point rasterizers.
    pub int64_atomics: bool,
    /// 64-bit atomicAdd/Exchange: HQS1R.
    pub int64_atomic_add: bool,
    /// Subgroup operations: `reduce`, `reduce-early-z`, `dedup`.
    pub subgroups: bool,
    /// Timestamp queries on pass boundaries: GPU timings.
    pub timestamps: bool,
    /// Largest storage-buffer binding (point data beyond it is split over buffers).
    pub max_binding: u64,
    pub max_buffer: u64,
    /// Point memory made by Vulkan directly, off wgpu's allocator (a 2.5 GiB buffer in ~3
    /// instead of ~60 ms on the H100): whole buffers are made before the first frame.
    pub direct_memory: bool,
}

/// Which adapter to use: `None` picks the best (discrete GPU first, then integrated, virtual,
/// CPU; among equals the one with 64-bit atomics); `Some` matches an index of
/// [`GpuContext::adapters`] or a case-insensitive part of the adapter's name or backend.
#[derive(Clone, Debug, Default)]
pub struct AdapterRequest {
    pub name: Option<String>,
    /// Ask only for what a WebGPU browser offers (no 64-bit integers, no subgroups): exercises
    /// the fallback paths on any machine.
    pub webgpu_baseline: bool,
}

pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub caps: Capabilities,
    /// Errors raised outside an error scope, kept for the next [`GpuContext::checked`] call
    /// instead of wgpu's default handler, which panics.
    uncaptured: Arc<Mutex<Option<String>>>,
    /// Kept alive with the device: a browser destroys the device once the instance and
    /// adapter it came from are collected (buffer mappings then fail).
    instance: wgpu::Instance,
    adapter: wgpu::Adapter,
}

fn wanted_features() -> wgpu::Features {
    wgpu::Features::SHADER_INT64
        | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX
        | wgpu::Features::SHADER_INT64_ATOMIC_ALL_OPS
        | wgpu::Features::SUBGROUP
        | wgpu::Features::TIMESTAMP_QUERY
}

fn type_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

/// One line describing an adapter, e.g. `Vulkan, Cpu: llvmpipe (LLVM 15.0.6, 256 bits)`.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{:?}, {:?}: {}", info.backend, info.device_type, info.name)
}

impl GpuContext {
    /// Vulkan/Metal/DX12 unless WGPU_BACKEND says otherwise: probing GL on a headless machine
    /// only prints EGL warnings, and GL lacks the 64-bit atomics anyway.
    #[cfg(not(target_arch = "wasm32"))]
    fn instance() -> wgpu::Instance {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::PRIMARY;
        wgpu::Instance::new(desc.with_env())
    }

    /// In a browser: its WebGPU implementation, nothing else.
    #[cfg(target_arch = "wasm32")]
    fn instance() -> wgpu::Instance {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::BROWSER_WEBGPU;
        wgpu::Instance::new(desc)
    }

    /// The adapters to choose from: every one wgpu enumerates; in a browser, which cannot
    /// enumerate, the one it offers.
    async fn candidates(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
        if cfg!(target_arch = "wasm32") {
            let options = wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            };
            return instance
                .request_adapter(&options)
                .await
                .into_iter()
                .collect();
        }
        instance.enumerate_adapters(wgpu::Backends::all()).await
    }

    /// Every adapter wgpu finds, in enumeration order (the indices `--adapter` accepts).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn adapters() -> Vec<wgpu::AdapterInfo> {
        pollster::block_on(Self::candidates(&Self::instance()))
            .iter()
            .map(|a| a.get_info())
            .collect()
    }

    /// Opens the requested adapter with every useful feature it has.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn new(request: &AdapterRequest) -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async(request))
    }

    /// [`new`](Self::new) without blocking: a browser answers adapter and device requests
    /// through promises only.
    pub async fn new_async(request: &AdapterRequest) -> Result<Self, GpuError> {
        Self::open(&Self::instance(), request, None)
            .await
            .map(|(ctx, _)| ctx)
    }

    /// Like [`new`](Self::new), for drawing into a window: creates the surface of `window`,
    /// considers only adapters that can present to it, and returns what the surface supports
    /// on the chosen adapter (formats, present modes) for configuring it.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn for_surface<'w>(
        request: &AdapterRequest,
        window: impl Into<wgpu::SurfaceTarget<'w>>,
    ) -> Result<(Self, wgpu::Surface<'w>, wgpu::SurfaceCapabilities), GpuError> {
        let instance = Self::instance();
        let surface = instance
            .create_surface(window)
            .map_err(|e| GpuError::Device(format!("creating the window surface: {e}")))?;
        let (ctx, adapter) = pollster::block_on(Self::open(&instance, request, Some(&surface)))?;
        let caps = surface.get_capabilities(&adapter);
        Ok((ctx, surface, caps))
    }

    async fn open(
        instance: &wgpu::Instance,
        request: &AdapterRequest,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<(Self, wgpu::Adapter), GpuError> {
        let adapters = Self::candidates(instance).await;
        // An adapter that cannot present to the window is useless to it (e.g. a second GPU).
        let presents = |a: &wgpu::Adapter| surface.is_none_or(|s| a.is_surface_supported(s));
        let found: Vec<String> = adapters.iter().map(|a| describe(&a.get_info())).collect();
        let adapter = match &request.name {
            Some(want) => {
                let by_index = want
                    .parse::<usize>()
                    .ok()
                    .and_then(|i| adapters.get(i).cloned());
                by_index.or_else(|| {
                    let w = want.to_lowercase();
                    adapters
                        .iter()
                        .find(|a| describe(&a.get_info()).to_lowercase().contains(&w))
                        .cloned()
                })
            }
            None => adapters
                .iter()
                .filter(|a| presents(a))
                .min_by_key(|a| {
                    let f = a.features();
                    let atomics = f.contains(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX);
                    (type_rank(a.get_info().device_type), !atomics)
                })
                .cloned(),
        };
        let Some(adapter) = adapter else {
            return Err(GpuError::NoAdapter {
                wanted: request.name.clone(),
                found,
            });
        };
        let info = adapter.get_info();
        if !presents(&adapter) {
            return Err(GpuError::Unsupported {
                what: "presenting to the window".into(),
                why: "the adapter cannot draw into this window's surface".into(),
                adapter: describe(&info),
            });
        }
        let features = if request.webgpu_baseline {
            adapter.features() & wgpu::Features::TIMESTAMP_QUERY
        } else {
            adapter.features() & wanted_features()
        };
        // 64-bit atomics are only usable together with 64-bit integers in shaders.
        let int64 = features.contains(wgpu::Features::SHADER_INT64);
        // Ask for everything the adapter offers: large bindings decide how point data is split.
        let limits = adapter.limits();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("pointlet"),
                required_features: features,
                required_limits: limits,
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|e| GpuError::Device(format!("{}: {e}", describe(&info))))?;
        let caps = Capabilities {
            int64_atomics: int64 && features.contains(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX),
            int64_atomic_add: int64
                && features.contains(wgpu::Features::SHADER_INT64_ATOMIC_ALL_OPS),
            subgroups: features.contains(wgpu::Features::SUBGROUP),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            max_binding: device.limits().max_storage_buffer_binding_size,
            max_buffer: device.limits().max_buffer_size,
            // A browser makes memory its own way: the baseline keeps wgpu's path.
            direct_memory: !request.webgpu_baseline
                && crate::device_memory::DirectAllocator::new(&device).is_some(),
        };
        let uncaptured = Arc::new(Mutex::new(None));
        let sink = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert_with(|| e.to_string());
            }
        }));
        let ctx = Self {
            device,
            queue,
            info,
            caps,
            uncaptured,
            instance: instance.clone(),
            adapter: adapter.clone(),
        };
        Ok((ctx, adapter))
    }

    pub fn describe(&self) -> String {
        describe(&self.info)
    }

    /// The instance the device came from (a browser canvas's surface must come from it too).
    pub fn wgpu_instance(&self) -> &wgpu::Instance {
        &self.instance
    }

    pub fn adapter(&self) -> &wgpu::Adapter {
        &self.adapter
    }

    /// Blocks until the GPU finished everything submitted so far.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Device(format!("waiting for the GPU: {e}")))
    }

    /// What makes point memory directly, where the device allows
    /// ([`Capabilities::direct_memory`]).
    pub(crate) fn direct_allocator(&self) -> Option<crate::device_memory::DirectAllocator> {
        self.caps
            .direct_memory
            .then(|| crate::device_memory::DirectAllocator::new(&self.device))
            .flatten()
    }

    /// Runs `f` and returns the first validation or out-of-memory error it raised.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn checked<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = o {
            return Err(GpuError::OutOfMemory(format!("{what}: {e}")));
        }
        if let Some(e) = v {
            return Err(GpuError::Validation(format!("{what}: {e}")));
        }
        if let Some(e) = self.uncaptured.lock().ok().and_then(|mut s| s.take()) {
            return Err(GpuError::Validation(format!("{what}: {e}")));
        }
        Ok(out)
    }

    /// In a browser error scopes answer through promises, which cannot be waited for here:
    /// `f`'s errors surface through the uncaptured-error handler, at this or a later call.
    #[cfg(target_arch = "wasm32")]
    pub fn checked<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let out = f();
        if let Some(e) = self.uncaptured.lock().ok().and_then(|mut s| s.take()) {
            return Err(GpuError::Validation(format!("{what}: {e}")));
        }
        Ok(out)
    }
}
