//! The viewer as the page drives it: `open` fetches the store's metadata and a colour sample,
//! opens the GPU; `frame` (once per animation frame) turns LoD feedback into fetches, uploads
//! what arrived and draws. Fetches are async tasks on the page's event loop (the browser has
//! no threads to block); they hand their points back through an inbox the next frame drains.

use crate::params::{SizeParam, ViewParams};
use crate::ranges::{self, PointRange};
use crate::residency::{Load, Residency};
use crate::sparse::SparseBytes;
use crate::{colors, fetch, pick, view};
use pointlet_core::color::{
    classification_color, classification_name, default_color_of_parts, sample_indices, ColorMode,
    ColorScale,
};
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::{Camera, PointBatch};
use pointlet_gpu::{
    AdapterRequest, EdlSettings, GpuContext, PageWrite, PagedCloud, PagedView, PointEncoding,
    PointSize, PointletDesc, RasterVariant, RenderSettings, RenderTarget, Renderer, SplatSettings,
};
use pointlet_store::format::{metadata_extent, PREAMBLE_LEN};
use pointlet_store::{PointletEntry, Store, StoreHeader, StreamKind};
use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;
use std::sync::atomic::Ordering;
use wasm_bindgen::prelude::*;

/// Points per GPU page: `pointlet render`'s default `--pool-page-size`.
const PAGE_SIZE: u32 = 256;
/// GPU memory for the page pool, tables and framebuffers (the native default is 2 GiB; a
/// browser tab gets less).
const VRAM_BUDGET: u64 = 768 << 20;
/// Pointlets fetching at once, and per task (one task's ranges are joined into few requests).
const MAX_LOADS: usize = 512;
const LOADS_PER_TASK: usize = 64;
/// Frames submitted but not finished at most: a browser queues GPU work without pushing back,
/// and a slow adapter would fall ever further behind (feedback arriving ever later).
const MAX_FRAMES_IN_FLIGHT: u32 = 2;
/// Points in flight at most: bounds memory held by responses not yet uploaded.
const MAX_POINTS_IN_FLIGHT: u64 = 4 << 20;
/// First bytes fetched: the preamble and, for most stores, the whole metadata.
const FIRST_FETCH: u64 = 256 << 10;
/// Largest metadata a page accepts (header, pointlet table, checksums).
const MAX_METADATA: u64 = 512 << 20;
/// Pick radius in device pixels.
const PICK_RADIUS: f64 = 6.0;

/// Points of one fetch, decoded and coloured.
struct Arrival {
    epoch: u64,
    pointlet: usize,
    lo: u32,
    slots: Vec<u32>,
    positions: Vec<[i32; 3]>,
    colors: Vec<u32>,
}

enum Event {
    Arrived(Arrival),
    Failed {
        epoch: u64,
        pointlet: usize,
        message: String,
    },
}

type Inbox = Rc<RefCell<Vec<Event>>>;

/// What a fetch task needs, shared by all tasks of one store.
struct Source {
    url: String,
    header: StoreHeader,
    entries: Vec<PointletEntry>,
}

struct App {
    ctx: GpuContext,
    renderer: Renderer,
    target: RenderTarget,
    canvas: web_sys::HtmlCanvasElement,
    screen: Screen,
    source: Rc<Source>,
    paged: PagedCloud,
    residency: Residency,
    /// Quantized positions of each resident window (picking).
    positions: Vec<Vec<[i32; 3]>>,
    params: ViewParams,
    camera: Camera,
    settings: RenderSettings,
    scale: ColorScale,
    sample: Vec<PointBatch>,
    extras: ExtraAttributes,
    epoch: u64,
    inbox: Inbox,
    requested: Vec<u32>,
    drawn: Vec<u32>,
    feedback_frame: u64,
    last_view: Option<(Camera, RenderSettings, (u32, u32))>,
    still_frames: u32,
    still_since: Option<u64>,
    capped_since: Option<u64>,
    holds_store: bool,
    converged: bool,
    error: Option<String>,
    bytes_fetched: Rc<RefCell<u64>>,
    frames_drawn: u64,
    frames_in_flight: std::sync::Arc<std::sync::atomic::AtomicU32>,
}

fn js_err(e: impl std::fmt::Display) -> JsValue {
    JsValue::from_str(&e.to_string())
}

/// Opens the store the query names (`?store=NAME`, fetched from `BASE/stores/NAME.pointlet`)
/// on `canvas` (its `width`/`height` are the image size).
#[wasm_bindgen]
pub async fn open_viewer(
    canvas: web_sys::HtmlCanvasElement,
    query: String,
    base: String,
) -> Result<Viewer, JsValue> {
    std::panic::set_hook(Box::new(|info| {
        web_sys::console::error_1(&JsValue::from_str(&info.to_string()))
    }));
    let app = App::open(canvas, &query, &base).await.map_err(js_err)?;
    Ok(Viewer {
        app: Rc::new(RefCell::new(app)),
    })
}

/// Whether this browser exposes WebGPU at all (`navigator.gpu`).
#[wasm_bindgen]
pub fn has_webgpu() -> bool {
    web_sys::window()
        .and_then(|w| js_sys::Reflect::get(&w.navigator(), &JsValue::from_str("gpu")).ok())
        .is_some_and(|g| !g.is_undefined() && !g.is_null())
}

async fn fetch_store(url: &str) -> Result<(Store, SparseBytes), String> {
    let first = fetch::fetch_range(url, 0..FIRST_FETCH).await?;
    let total = first
        .total
        .ok_or_else(|| format!("{url}: the server did not say how long the store is"))?;
    let head = ranges::slice_of(&first.body, first.body_start, &(0..PREAMBLE_LEN))
        .and_then(|b| <[u8; PREAMBLE_LEN as usize]>::try_from(b).ok())
        .ok_or_else(|| format!("{url}: the store is shorter than its preamble"))?;
    let (_, data_offset) = metadata_extent(&head).map_err(|e| format!("{url}: {e}"))?;
    if data_offset > total.min(MAX_METADATA) {
        return Err(format!(
            "{url}: the metadata claims {data_offset} bytes (the store has {total})"
        ));
    }
    let sparse = SparseBytes::new(total);
    let mut metadata = first.body;
    metadata.truncate(data_offset.saturating_sub(first.body_start) as usize);
    let have = first.body_start + metadata.len() as u64;
    if first.body_start == 0 && have < data_offset {
        // One piece: the reader reads the table and checksums each in one read.
        let rest = fetch::fetch_range(url, have..data_offset).await?;
        let tail = ranges::slice_of(&rest.body, rest.body_start, &(have..data_offset))
            .ok_or_else(|| format!("{url}: the metadata response was short"))?;
        metadata.extend_from_slice(tail);
    }
    sparse.insert(first.body_start, metadata);
    let store =
        Store::from_source(Path::new(url), Box::new(sparse.clone())).map_err(|e| e.to_string())?;
    Ok((store, sparse))
}

/// Fetches every stream of the sample pointlets the colouring is fitted on.
async fn fetch_sample(url: &str, store: &Store, sparse: &SparseBytes) -> Result<(), String> {
    let h = store.header();
    let wanted: Vec<PointRange> = sample_indices(store.pointlets().len())
        .into_iter()
        .filter_map(|i| {
            store.pointlets().get(i).map(|e| PointRange {
                pointlet: i,
                points: 0..e.count,
            })
        })
        .collect();
    let kinds: Vec<StreamKind> = h.streams.iter().map(|s| s.kind).collect();
    let requests = ranges::plan(h, store.pointlets(), &wanted, &kinds);
    let bodies = futures::future::join_all(
        requests
            .iter()
            .map(|r| fetch::fetch_range(url, r.bytes.clone())),
    )
    .await;
    for b in bodies {
        let b = b?;
        sparse.insert(b.body_start, b.body);
    }
    Ok(())
}

/// Fetches `loads`, decodes and colours their points, and posts them to `inbox`.
async fn run_loads(
    source: Rc<Source>,
    kinds: Vec<StreamKind>,
    scale: ColorScale,
    epoch: u64,
    loads: Vec<Load>,
    inbox: Inbox,
    fetched: Rc<RefCell<u64>>,
) {
    let wanted: Vec<PointRange> = loads.iter().map(|l| l.range.clone()).collect();
    let requests = ranges::plan(&source.header, &source.entries, &wanted, &kinds);
    let bodies = futures::future::join_all(
        requests
            .iter()
            .map(|r| fetch::fetch_range(&source.url, r.bytes.clone())),
    )
    .await;
    let mut raws: Vec<Vec<Vec<u8>>> = vec![vec![Vec::new(); kinds.len()]; loads.len()];
    let mut error = None;
    for (req, body) in requests.iter().zip(bodies) {
        match body {
            Ok(b) => {
                *fetched.borrow_mut() += b.body.len() as u64;
                for (k, kind, bytes) in &req.pieces {
                    let slot = kinds.iter().position(|x| x == kind);
                    match (ranges::slice_of(&b.body, b.body_start, bytes), slot) {
                        (Some(s), Some(j)) => raws[*k][j] = s.to_vec(),
                        _ => error = Some(format!("{}: a response was short", source.url)),
                    }
                }
            }
            Err(e) => error = Some(e),
        }
    }
    let mut out = inbox.borrow_mut();
    for (load, raw) in loads.into_iter().zip(raws) {
        let pointlet = load.range.pointlet;
        if let Some(message) = &error {
            out.push(Event::Failed {
                epoch,
                pointlet,
                message: message.clone(),
            });
            continue;
        }
        let n = (load.range.points.end - load.range.points.start) as usize;
        let (positions, colors) = colors::decode(&source.header, &scale, &kinds, &raw, n);
        out.push(Event::Arrived(Arrival {
            epoch,
            pointlet,
            lo: load.range.points.start,
            slots: load.slots,
            positions,
            colors,
        }));
    }
}

fn canvas_size(canvas: &web_sys::HtmlCanvasElement) -> (u32, u32) {
    (canvas.width().max(1), canvas.height().max(1))
}

fn splats_for(size: SizeParam) -> SplatSettings {
    SplatSettings {
        size: match size {
            SizeParam::Pixels(n) => PointSize::Fixed(n),
            SizeParam::Adaptive => PointSize::adaptive(),
        },
        ..Default::default()
    }
}

impl App {
    async fn open(
        canvas: web_sys::HtmlCanvasElement,
        query: &str,
        base: &str,
    ) -> Result<App, String> {
        let params = ViewParams::parse(query).map_err(|e| e.to_string())?;
        let name = params
            .store
            .clone()
            .ok_or("no store named: add ?store=NAME to the address")?;
        let url = format!(
            "{base}stores/{}.pointlet",
            crate::params::encode_component(&name)
        );
        let (store, sparse) = fetch_store(&url).await?;
        fetch_sample(&url, &store, &sparse).await?;
        let header = store.header().clone();
        let n = store.pointlets().len();
        let sample: Vec<PointBatch> = sample_indices(n)
            .into_iter()
            .map(|i| store.read_pointlet(i))
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?;
        let extras =
            ExtraAttributes::from_vlrs(&header.vlrs, usize::from(header.layout.extra_bytes));
        let mode = match params.color {
            Some(m) if m.available_in(&header.layout) => m,
            _ => {
                default_color_of_parts(&header.layout, n, |i| store.read_pointlet(i))
                    .map_err(|e| e.to_string())?
                    .mode
            }
        };
        // The sample's bytes are decoded: keep only the metadata.
        let (_, data_offset) = {
            let mut pre = [0u8; PREAMBLE_LEN as usize];
            pointlet_store::ByteSource::read_exact_at(&sparse, &mut pre, 0)
                .map_err(|e| e.to_string())?;
            metadata_extent(&pre)?
        };
        sparse.forget_from(data_offset);
        let refs: Vec<&PointBatch> = sample.iter().collect();
        let z = [header.bounds.min[2], header.bounds.max[2]];
        let scale = ColorScale::fit_in(mode, &refs, z, &extras);

        let ctx = GpuContext::new_async(&AdapterRequest::default())
            .await
            .map_err(|e| e.to_string())?;
        let size = canvas_size(&canvas);
        let target = RenderTarget::new(&ctx, size.0, size.1).map_err(|e| e.to_string())?;

        let descs: Vec<PointletDesc> = store
            .pointlets()
            .iter()
            .map(|p| PointletDesc {
                aabb: p.aabb,
                count: p.count,
            })
            .collect();
        let encoding = PointEncoding::Full16;
        let fixed =
            PagedCloud::overhead_bytes(&descs, PAGE_SIZE) + RenderTarget::bytes_for(size.0, size.1);
        let per_slot = PagedCloud::slot_bytes(encoding, PAGE_SIZE);
        let store_pages: u64 = descs
            .iter()
            .map(|d| d.count.div_ceil(PAGE_SIZE) as u64)
            .sum();
        let slots = (VRAM_BUDGET.saturating_sub(fixed) / per_slot)
            .min(store_pages)
            .max(n as u64)
            .min(u32::MAX as u64 / 2) as u32;
        let paged =
            PagedCloud::new(&ctx, descs, encoding, PAGE_SIZE, slots).map_err(|e| e.to_string())?;
        let slots = paged.slots;
        let counts: Vec<u32> = store.pointlets().iter().map(|p| p.count).collect();
        let camera = view::camera_for(&params, &header.bounds).map_err(|e| e.to_string())?;
        let variant = RasterVariant::AtomicMin32.fallback(&ctx.caps);
        let mut settings = RenderSettings {
            variant,
            splats: splats_for(params.size),
            ..Default::default()
        };
        settings.screen.edl = params.edl.then(EdlSettings::default);
        let mut params = params;
        params.color = Some(mode).filter(|_| params.color.is_some());
        let renderer = Renderer::new(&ctx);
        let source = Rc::new(Source {
            url,
            header,
            entries: store.pointlets().to_vec(),
        });
        Ok(App {
            ctx,
            renderer,
            target,
            screen: Screen::new(&canvas)?,
            canvas,
            paged,
            residency: Residency::new(counts, slots, PAGE_SIZE),
            positions: vec![Vec::new(); n],
            params,
            camera,
            settings,
            scale,
            sample,
            extras,
            epoch: 0,
            inbox: Rc::default(),
            requested: vec![0; n],
            drawn: vec![0; n],
            feedback_frame: 0,
            last_view: None,
            still_frames: 0,
            still_since: None,
            capped_since: None,
            holds_store: slots as u64 == store_pages,
            converged: false,
            error: None,
            bytes_fetched: Rc::new(RefCell::new(0)),
            frames_drawn: 0,
            frames_in_flight: Default::default(),
            source,
        })
    }

    fn total_points(&self) -> u64 {
        self.source.header.points
    }

    /// The budget of a moving frame within what the pool holds (as the native scene).
    fn moving_bucket(&self) -> f64 {
        let budget = self.params.budget as f64;
        if self.holds_store {
            return budget;
        }
        let ps = PAGE_SIZE as f64;
        let pool = self.paged.slots as f64 * ps - 0.5 * ps * self.source.entries.len() as f64;
        budget.min(pool.max(ps))
    }

    /// The largest bucket whose requests fit the pool at once; None when it holds the store.
    fn single_pass_cap(&self) -> Option<f64> {
        if self.holds_store {
            return None;
        }
        let spare = self
            .paged
            .slots
            .saturating_sub(self.source.entries.len() as u32) as f64;
        Some((spare * PAGE_SIZE as f64).max(1.0))
    }

    fn publish(&mut self, i: usize) {
        let hi = self.residency.resident(i);
        let slots = self.residency.resident_slots(i).to_vec();
        self.paged.set_residency(i as u32, 0, hi, &slots);
    }

    fn receive(&mut self) {
        let events: Vec<Event> = std::mem::take(&mut *self.inbox.borrow_mut());
        let q = self.source.header.quantization;
        for event in events {
            match event {
                Event::Arrived(a) if a.epoch == self.epoch => {
                    let i = a.pointlet;
                    let mut writes = Vec::new();
                    let absolute: Vec<[f64; 3]> =
                        a.positions.iter().map(|p| q.dequantize(*p)).collect();
                    let n = absolute.len().min(a.colors.len());
                    let mut at = 0usize;
                    while at < n {
                        let point = a.lo + at as u32;
                        let page = (point / PAGE_SIZE - a.lo / PAGE_SIZE) as usize;
                        let end = (((point / PAGE_SIZE) + 1) * PAGE_SIZE - a.lo) as usize;
                        let end = end.min(n);
                        if let Some(slot) = a.slots.get(page) {
                            writes.push((*slot, point, at..end));
                        }
                        at = end;
                    }
                    let pages: Vec<PageWrite<'_>> = writes
                        .iter()
                        .map(|(slot, first, r)| PageWrite {
                            pointlet: i as u32,
                            slot: *slot,
                            first_point: *first,
                            positions: &absolute[r.clone()],
                            colors: &a.colors[r.clone()],
                        })
                        .collect();
                    self.paged.write_pages(&pages);
                    self.residency.arrived(i);
                    if let Some(p) = self.positions.get_mut(i) {
                        p.truncate(a.lo as usize);
                        p.extend_from_slice(&a.positions);
                    }
                    self.publish(i);
                }
                Event::Arrived(_) => {}
                Event::Failed {
                    epoch,
                    pointlet,
                    message,
                } => {
                    if epoch == self.epoch {
                        self.residency.failed(pointlet);
                        self.error = Some(message);
                    }
                }
            }
        }
    }

    fn request(&mut self) {
        let plan = self.residency.plan(
            &self.requested,
            self.feedback_frame,
            MAX_POINTS_IN_FLIGHT,
            MAX_LOADS,
        );
        for i in plan.shrunk {
            let keep = self.residency.resident(i) as usize;
            if let Some(p) = self.positions.get_mut(i) {
                p.truncate(keep);
            }
            self.publish(i);
        }
        let kinds = colors::fetch_streams(&self.source.header, self.scale.mode);
        // Neighbouring pointlets are neighbours in every stream: a task's ranges join into
        // a few large requests.
        let mut loads = plan.loads;
        loads.sort_by_key(|l| l.range.pointlet);
        for chunk in loads.chunks(LOADS_PER_TASK) {
            wasm_bindgen_futures::spawn_local(run_loads(
                Rc::clone(&self.source),
                kinds.clone(),
                self.scale,
                self.epoch,
                chunk.to_vec(),
                Rc::clone(&self.inbox),
                Rc::clone(&self.bytes_fetched),
            ));
        }
    }

    fn resize(&mut self) -> Result<(), String> {
        let size = canvas_size(&self.canvas);
        if size != (self.target.width, self.target.height) {
            self.target =
                RenderTarget::new(&self.ctx, size.0, size.1).map_err(|e| e.to_string())?;
        }
        Ok(())
    }

    /// One animation frame; idle once the still view converged.
    fn frame(&mut self) -> Result<(), String> {
        self.screen.show();
        if self.frames_in_flight.load(Ordering::Relaxed) >= MAX_FRAMES_IN_FLIGHT {
            return Ok(());
        }
        self.resize()?;
        let size = (self.target.width, self.target.height);
        let key = (self.camera, self.settings, size);
        let still = self.last_view.as_ref() == Some(&key);
        self.last_view = Some(key);
        if still {
            self.still_frames += 1;
            if self.still_since.is_none() {
                self.still_since = Some(self.paged.frames() + 1);
            }
        } else {
            self.still_frames = 0;
            self.still_since = None;
            self.converged = false;
        }
        let pool_cap = self.single_pass_cap();
        let bucket = if still {
            let growth = 2f64.powi(self.still_frames.min(60) as i32);
            let cap = pool_cap.unwrap_or(self.total_points() as f64 * 1048576.0);
            (self.params.budget as f64 * growth).min(cap)
        } else {
            self.moving_bucket()
        };
        if still && pool_cap.is_some_and(|cap| bucket >= cap) {
            self.capped_since.get_or_insert(self.paged.frames() + 1);
        } else {
            self.capped_since = None;
        }
        if let Some(fb) = self.paged.poll_feedback(&self.ctx) {
            self.requested = fb.requested;
            self.drawn = fb.drawn;
            self.feedback_frame = fb.frame;
            let current = self.still_since.is_some_and(|s| fb.frame >= s);
            let capped = self.capped_since.is_some_and(|s| fb.frame >= s);
            let counts = self.source.entries.iter().map(|e| e.count);
            let complete = self
                .requested
                .iter()
                .zip(&self.drawn)
                .zip(counts)
                .all(|((r, d), c)| *r == 0 || ((*r == c || capped) && d >= r));
            if current && complete {
                self.converged = true;
            }
        }
        self.receive();
        self.request();
        if self.converged && still {
            return Ok(());
        }
        let view = PagedView {
            bucket,
            accumulate: false,
        };
        self.renderer
            .render_paged(
                &self.ctx,
                &mut self.paged,
                &self.camera,
                &self.settings,
                &view,
                &mut self.target,
                None,
            )
            .map_err(|e| e.to_string())?;
        self.present();
        self.frames_in_flight.fetch_add(1, Ordering::Relaxed);
        let in_flight = std::sync::Arc::clone(&self.frames_in_flight);
        self.ctx.queue.on_submitted_work_done(move || {
            in_flight.fetch_sub(1, Ordering::Relaxed);
        });
        self.frames_drawn += 1;
        Ok(())
    }

    /// Starts copying the frame to the page (when the last copy is shown).
    fn present(&mut self) {
        self.screen.start(&self.ctx, &self.target);
    }

    /// Colours by `mode` from now on: every window is fetched again with the new colours.
    fn set_color(&mut self, mode: ColorMode) -> Result<(), String> {
        if !mode.available_in(&self.source.header.layout) {
            return Err(format!("the store has no {} attribute", mode.name()));
        }
        let refs: Vec<&PointBatch> = self.sample.iter().collect();
        let h = &self.source.header;
        self.scale = ColorScale::fit_in(
            mode,
            &refs,
            [h.bounds.min[2], h.bounds.max[2]],
            &self.extras,
        );
        self.params.color = Some(mode);
        self.epoch += 1;
        for i in self.residency.clear() {
            self.positions[i].clear();
            self.publish(i);
        }
        self.last_view = None;
        Ok(())
    }

    fn state(&self) -> &'static str {
        if self.error.is_some() {
            "error"
        } else if self.converged {
            "converged"
        } else {
            "refining"
        }
    }

    fn sync_params(&mut self) {
        self.params.eye = Some(self.camera.eye);
        self.params.target = Some(self.camera.target);
        self.params.fov = self.camera.fov_y_deg;
    }
}

/// Shows frames in the canvas through its 2D context: each frame is copied to a mappable
/// buffer and drawn with `putImageData` once mapped. Slower than a WebGPU canvas swap chain,
/// but that one loses the device in headless Chromium on SwiftShader (no shared-image backing
/// for it), where the tests run.
struct Screen {
    context: web_sys::CanvasRenderingContext2d,
    pending: Option<CanvasCopy>,
}

/// A frame on its way to the canvas.
struct CanvasCopy {
    buffer: wgpu::Buffer,
    size: (u32, u32),
    /// Bytes per row in the buffer (padded to 256).
    row: u32,
    /// Set by the mapping: whether it succeeded.
    mapped: Rc<RefCell<Option<bool>>>,
}

impl Screen {
    fn new(canvas: &web_sys::HtmlCanvasElement) -> Result<Self, String> {
        use wasm_bindgen::JsCast;
        let context = canvas
            .get_context("2d")
            .ok()
            .flatten()
            .and_then(|c| c.dyn_into::<web_sys::CanvasRenderingContext2d>().ok())
            .ok_or("the canvas has no 2D context")?;
        Ok(Self {
            context,
            pending: None,
        })
    }

    fn start(&mut self, ctx: &GpuContext, target: &RenderTarget) {
        if self.pending.is_some() {
            return;
        }
        let (w, h) = (target.width, target.height);
        let row = (w * 4).div_ceil(256) * 256;
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("canvas copy"),
            size: row as u64 * h as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        copy_out(&mut enc, target, &buffer, row);
        ctx.queue.submit([enc.finish()]);
        let done = Rc::new(RefCell::new(None));
        let flag = Rc::clone(&done);
        buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            *flag.borrow_mut() = Some(r.is_ok())
        });
        self.pending = Some(CanvasCopy {
            buffer,
            size: (w, h),
            row,
            mapped: done,
        });
    }

    /// Draws the copy in flight if it is mapped.
    fn show(&mut self) {
        let ready = self.pending.as_ref().and_then(|p| *p.mapped.borrow());
        let Some(ok) = ready else {
            return;
        };
        let Some(CanvasCopy {
            buffer,
            size: (w, h),
            row,
            ..
        }) = self.pending.take()
        else {
            return;
        };
        if !ok {
            return;
        }
        let mut rgba = Vec::with_capacity((w * h * 4) as usize);
        if let Ok(view) = buffer.slice(..).get_mapped_range() {
            for r in 0..h as usize {
                let start = r * row as usize;
                rgba.extend_from_slice(&view[start..start + (w * 4) as usize]);
            }
        }
        buffer.unmap();
        if let Ok(image) =
            web_sys::ImageData::new_with_u8_clamped_array_and_sh(wasm_bindgen::Clamped(&rgba), w, h)
        {
            let _ = self.context.put_image_data(&image, 0.0, 0.0);
        }
    }
}

/// Copies the target's image into `buffer` (rows of `row` bytes).
fn copy_out(
    enc: &mut wgpu::CommandEncoder,
    target: &RenderTarget,
    buffer: &wgpu::Buffer,
    row: u32,
) {
    enc.copy_texture_to_buffer(
        target.output().as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(target.height),
            },
        },
        wgpu::Extent3d {
            width: target.width,
            height: target.height,
            depth_or_array_layers: 1,
        },
    );
}

/// The handle the page holds.
#[wasm_bindgen]
pub struct Viewer {
    app: Rc<RefCell<App>>,
}

#[wasm_bindgen]
impl Viewer {
    /// Draws one frame (call from `requestAnimationFrame`).
    pub fn frame(&self) -> Result<(), JsValue> {
        self.app.borrow_mut().frame().map_err(js_err)
    }

    /// `refining`, `converged` (the still view shows every point) or `error`.
    pub fn state(&self) -> String {
        self.app.borrow().state().into()
    }

    /// The last fetch error, if any.
    pub fn error(&self) -> Option<String> {
        self.app.borrow().error.clone()
    }

    /// One line of numbers for the status bar.
    pub fn status(&self) -> String {
        let a = self.app.borrow();
        let requested: u64 = a.requested.iter().map(|v| *v as u64).sum();
        let drawn: u64 = a.drawn.iter().map(|v| *v as u64).sum();
        format!(
            "{} points · {} drawn of {} requested (frame {} of {}) · {} on GPU · {} fetches · {:.1} MB read · {} on {}",
            a.total_points(),
            drawn,
            requested,
            a.feedback_frame,
            a.paged.frames(),
            a.residency.resident_points(),
            a.residency.in_flight(),
            *a.bytes_fetched.borrow() as f64 / 1e6,
            a.settings.variant.name(),
            a.ctx.describe(),
        )
    }

    pub fn orbit(&self, dx: f64, dy: f64) {
        let mut a = self.app.borrow_mut();
        let b = a.source.header.bounds;
        view::orbit(&mut a.camera, dx * 0.005, dy * 0.005, &b);
        a.sync_params();
    }

    pub fn pan(&self, dx: f64, dy: f64) {
        let mut a = self.app.borrow_mut();
        let b = a.source.header.bounds;
        let h = a.target.height;
        view::pan(&mut a.camera, dx, dy, h, &b);
        a.sync_params();
    }

    pub fn zoom(&self, factor: f64) {
        let mut a = self.app.borrow_mut();
        let b = a.source.header.bounds;
        view::zoom(&mut a.camera, factor, &b);
        a.sync_params();
    }

    /// The view as a query string (`?store=…&eye=…`), for the address bar.
    pub fn query(&self) -> String {
        self.app.borrow().params.to_query()
    }

    /// Colourings the store can show.
    pub fn color_modes(&self) -> Vec<String> {
        let a = self.app.borrow();
        let layout = a.source.header.layout;
        ColorMode::ALL
            .iter()
            .filter(|m| m.available_in(&layout))
            .map(|m| m.name().to_string())
            .collect()
    }

    pub fn color(&self) -> String {
        self.app.borrow().scale.mode.name().into()
    }

    pub fn set_color(&self, name: &str) -> Result<(), JsValue> {
        let mode = ColorMode::parse(name).ok_or_else(|| js_err(format!("no colouring {name}")))?;
        self.app.borrow_mut().set_color(mode).map_err(js_err)
    }

    /// The classes of the colour sample: `class|name|#rrggbb` lines.
    pub fn legend(&self) -> Vec<String> {
        let a = self.app.borrow();
        let mut seen = [false; 256];
        for b in &a.sample {
            for c in &b.classification {
                seen[*c as usize] = true;
            }
        }
        (0..=255u8)
            .filter(|c| seen[*c as usize])
            .map(|c| {
                let [r, g, b] = classification_color(c);
                let hidden = if a.settings.class_hidden(c) {
                    "|hidden"
                } else {
                    ""
                };
                format!(
                    "{c}|{}|#{r:02x}{g:02x}{b:02x}{hidden}",
                    classification_name(c)
                )
            })
            .collect()
    }

    pub fn set_class_hidden(&self, class: u8, hidden: bool) {
        self.app
            .borrow_mut()
            .settings
            .set_class_hidden(class, hidden);
    }

    /// `1`–`32` pixels or `adaptive`.
    pub fn set_point_size(&self, size: &str) -> Result<(), JsValue> {
        let p = ViewParams::parse(&format!("size={size}")).map_err(js_err)?;
        let mut a = self.app.borrow_mut();
        a.params.size = p.size;
        a.settings.splats = splats_for(p.size);
        Ok(())
    }

    pub fn set_edl(&self, on: bool) {
        let mut a = self.app.borrow_mut();
        a.params.edl = on;
        a.settings.screen.edl = on.then(EdlSettings::default);
    }

    /// The moving camera's point budget.
    pub fn set_budget(&self, points: f64) {
        let mut a = self.app.borrow_mut();
        a.params.budget = points.clamp(1e3, 1e12) as u64;
        a.last_view = None;
    }

    pub fn budget(&self) -> f64 {
        self.app.borrow().params.budget as f64
    }

    /// `atomic-min-32` or `hqs` (the rasterizers WebGPU can run).
    pub fn set_raster(&self, name: &str) -> Result<(), JsValue> {
        let v =
            RasterVariant::parse(name).ok_or_else(|| js_err(format!("no rasterizer {name}")))?;
        let mut a = self.app.borrow_mut();
        if let Some(why) = v.unsupported_reason(&a.ctx.caps) {
            return Err(js_err(format!("{name}: {why}")));
        }
        a.settings.variant = v;
        Ok(())
    }

    /// The stored point nearest to the cursor at device pixel (x, y), `[x, y, z]`.
    pub fn pick(&self, x: f64, y: f64) -> Option<Vec<f64>> {
        let a = self.app.borrow();
        let size = (a.target.width, a.target.height);
        let q = a.source.header.quantization;
        pick::pick(
            &a.camera,
            size,
            [x, y],
            PICK_RADIUS,
            &q,
            a.positions.iter().map(|p| p.as_slice()),
        )
        .map(|p| p.to_vec())
    }

    /// Where a data point lands on the canvas, device pixels `[x, y]`.
    pub fn project(&self, x: f64, y: f64, z: f64) -> Option<Vec<f64>> {
        let a = self.app.borrow();
        view::project(&a.camera, (a.target.width, a.target.height), [x, y, z])
            .map(|(p, _)| p.to_vec())
    }

    /// The last image's RGBA8 pixels, rows top to bottom (screenshots and tests: the exact
    /// image, before the browser composites the canvas).
    pub fn read_pixels(&self) -> js_sys::Promise {
        let a = self.app.borrow();
        let (w, h) = (a.target.width, a.target.height);
        let row = (w * 4).div_ceil(256) * 256;
        let buffer = a.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("screenshot"),
            size: row as u64 * h as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut enc = a.ctx.device.create_command_encoder(&Default::default());
        copy_out(&mut enc, &a.target, &buffer, row);
        a.ctx.queue.submit([enc.finish()]);
        js_sys::Promise::new(&mut |resolve, reject| {
            let mapped = buffer.clone();
            buffer
                .slice(..)
                .map_async(wgpu::MapMode::Read, move |result| {
                    if let Err(e) = result {
                        let _ = reject.call1(&JsValue::NULL, &js_err(e));
                        return;
                    }
                    let mut out = Vec::with_capacity((w * h * 4) as usize);
                    if let Ok(view) = mapped.slice(..).get_mapped_range() {
                        for r in 0..h as usize {
                            let start = r * row as usize;
                            out.extend_from_slice(&view[start..start + (w * 4) as usize]);
                        }
                    }
                    mapped.unmap();
                    let array = js_sys::Uint8Array::from(out.as_slice());
                    let _ = resolve.call1(&JsValue::NULL, &array);
                });
        })
    }

    pub fn width(&self) -> u32 {
        self.app.borrow().target.width
    }

    pub fn height(&self) -> u32 {
        self.app.borrow().target.height
    }

    /// Frames drawn so far (idle frames of a converged view are not drawn).
    pub fn frames_drawn(&self) -> f64 {
        self.app.borrow().frames_drawn as f64
    }
}
