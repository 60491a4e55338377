//! Starting and stopping: [`Server::bind`] resolves the stores, binds the address and runs
//! the routes on a tokio runtime in a thread of its own; [`RunningServer`] tells the bound
//! address and stops it.
//!
//! Stopping stops accepting connections and lets requests in flight finish for up to
//! [`GRACE`]; then the runtime is dropped, which closes what is left.

use crate::catalog::{Catalog, ServedStore};
use crate::config::ServeConfig;
use crate::error::ServeError;
use crate::listing::Listing;
use crate::respond::FileKind;
use crate::routes::{router, AppState};
use crate::viewer::ViewerFiles;
use axum::http::HeaderValue;
use std::future::IntoFuture;
use std::net::SocketAddr;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use tokio::sync::{watch, Semaphore};

/// How long requests in flight may go on once stopping began.
pub const GRACE: Duration = Duration::from_secs(5);

/// The entry point: see [`Server::bind`].
pub struct Server;

/// A server running on its own thread.
pub struct RunningServer {
    addr: SocketAddr,
    stores: Vec<ServedStore>,
    notes: Vec<String>,
    viewer: bool,
    stop: ShutdownHandle,
    thread: JoinHandle<Result<(), ServeError>>,
}

/// Stops a [`RunningServer`] from anywhere (a signal handler's thread, a test).
#[derive(Clone, Debug)]
pub struct ShutdownHandle(Arc<watch::Sender<bool>>);

impl ShutdownHandle {
    /// Asks the server to stop; returns at once.
    pub fn shutdown(&self) {
        self.0.send_replace(true);
    }
}

impl Server {
    /// Resolves and validates the stores (and the viewer folder), binds `config.bind` and
    /// starts serving. Errors name the argument or address at fault; once this returns `Ok`
    /// the address accepts connections.
    pub fn bind(config: ServeConfig) -> Result<RunningServer, ServeError> {
        let catalog = Catalog::resolve(&config.stores)?;
        let mut notes = catalog.notes().to_vec();
        let viewer = match &config.viewer_dir {
            Some(dir) => {
                let (files, viewer_notes) = ViewerFiles::scan(dir)?;
                notes.extend(viewer_notes);
                Some(files)
            }
            None => None,
        };
        let cache_control = match config.store_max_age {
            0 => "no-cache".to_string(),
            age => format!("public, max-age={age}"),
        };
        let store_kind = FileKind {
            content_type: crate::mime::content_type(crate::catalog::STORE_EXTENSION),
            cache_control: HeaderValue::from_str(&cache_control)
                .unwrap_or(HeaderValue::from_static("no-cache")),
        };
        let stores = catalog.stores().to_vec();
        let has_viewer = viewer.as_ref().is_some_and(|v| v.has_index());
        let state = Arc::new(AppState {
            listing: Listing::new(&catalog),
            catalog,
            viewer,
            streams: Arc::new(Semaphore::new(config.max_streams.max(1))),
            store_kind,
        });

        let listener =
            std::net::TcpListener::bind(config.bind).map_err(|cause| ServeError::Bind {
                addr: config.bind,
                cause,
            })?;
        let addr = listener.local_addr().map_err(|cause| ServeError::Bind {
            addr: config.bind,
            cause,
        })?;
        listener
            .set_nonblocking(true)
            .map_err(|cause| ServeError::Runtime {
                what: "configuring the listening socket",
                cause,
            })?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("pointlet-serve")
            .max_blocking_threads(64)
            .build()
            .map_err(|cause| ServeError::Runtime {
                what: "starting the async runtime",
                cause,
            })?;

        let (stop_tx, stop_rx) = watch::channel(false);
        let app = router(state);
        let thread = std::thread::Builder::new()
            .name("pointlet-serve-main".into())
            .spawn(move || {
                let result = runtime.block_on(run(listener, app, stop_rx));
                runtime.shutdown_timeout(Duration::from_secs(1));
                result
            })
            .map_err(|cause| ServeError::Runtime {
                what: "starting the server thread",
                cause,
            })?;
        Ok(RunningServer {
            addr,
            stores,
            notes,
            viewer: has_viewer,
            stop: ShutdownHandle(Arc::new(stop_tx)),
            thread,
        })
    }
}

/// Serves until asked to stop, then for at most [`GRACE`] more.
async fn run(
    listener: std::net::TcpListener,
    app: axum::Router,
    stop: watch::Receiver<bool>,
) -> Result<(), ServeError> {
    use axum::serve::ListenerExt;
    let listener = tokio::net::TcpListener::from_std(listener)
        .map_err(|cause| ServeError::Runtime {
            what: "registering the listening socket",
            cause,
        })?
        .tap_io(|tcp| {
            // Small answers (headers, 416s) go out at once; failing only costs latency.
            let _ = tcp.set_nodelay(true);
        });
    let graceful = axum::serve(listener, app)
        .with_graceful_shutdown(stopped(stop.clone()))
        .into_future();
    let deadline = async {
        stopped(stop).await;
        tokio::time::sleep(GRACE).await;
    };
    tokio::select! {
        served = graceful => served.map_err(|cause| ServeError::Runtime { what: "serving", cause }),
        () = deadline => Ok(()),
    }
}

/// Resolves once stopping was asked for (or every handle is gone).
async fn stopped(mut stop: watch::Receiver<bool>) {
    let _ = stop.wait_for(|&s| s).await;
}

impl RunningServer {
    /// The address the server listens on (the real port when port 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The served stores, sorted by name, as found at startup.
    pub fn stores(&self) -> &[ServedStore] {
        &self.stores
    }

    /// What was skipped in the given folders, one line each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Whether `/` serves a viewer (an `index.html` in the viewer folder).
    pub fn has_viewer(&self) -> bool {
        self.viewer
    }

    /// A handle that stops the server from another thread.
    pub fn shutdown_handle(&self) -> ShutdownHandle {
        self.stop.clone()
    }

    /// Stops the server and waits until it has stopped.
    pub fn shutdown(self) -> Result<(), ServeError> {
        self.stop.shutdown();
        self.wait()
    }

    /// Waits until the server stops (after a [`ShutdownHandle::shutdown`]).
    pub fn wait(self) -> Result<(), ServeError> {
        self.thread.join().map_err(|_| ServeError::ThreadPanicked)?
    }
}
