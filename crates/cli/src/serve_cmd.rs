//! `pointlet serve`: serves stores over HTTP (byte ranges, ETags, CORS) for the web viewer
//! and remote readers, until Ctrl-C or SIGTERM. The server itself is `pointlet-serve`.

use anyhow::{Context, Result};
use pointlet_core::size::{format_bytes, format_count};
use pointlet_serve::{RunningServer, ServeConfig, Server};
use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// `.pointlet` stores, or folders whose `.pointlet` files (directly inside) are served.
    /// Each is served as /stores/NAME.pointlet; symlinks inside a folder are not followed.
    #[arg(required = true, value_name = "STORE_OR_DIR")]
    pub stores: Vec<PathBuf>,
    /// Address to listen on: loopback only by default; 0.0.0.0:PORT serves the network too;
    /// port 0 picks a free port (the first line printed says which).
    #[arg(long, default_value_t = pointlet_serve::DEFAULT_BIND)]
    pub bind: SocketAddr,
    /// The web viewer's built files, served from /. Default: $POINTLET_WEB_DIR, else the
    /// target/web that `bash scripts/build-web.sh` writes; without one, / says how to build it.
    #[arg(long, value_name = "DIR")]
    pub web_dir: Option<PathBuf>,
}

/// The variable naming the web viewer's folder when `--web-dir` is not given.
const WEB_DIR_VAR: &str = "POINTLET_WEB_DIR";

pub fn run(args: Args) -> Result<()> {
    let mut config = ServeConfig::new(args.stores);
    config.bind = args.bind;
    config.viewer_dir = web_dir(args.web_dir);
    let server = Server::bind(config)?;
    for note in server.notes() {
        eprintln!("note: {note}");
    }
    print_banner(&server).context("printing the server's address")?;
    stop_on_signals(&server)?;
    server.wait()?;
    eprintln!("stopped");
    Ok(())
}

/// The viewer's folder: the one named by `--web-dir` or `POINTLET_WEB_DIR` (an error later if
/// it cannot be served), else a built `target/web` found beside this executable's target
/// folder or in the source tree it was built from.
fn web_dir(given: Option<PathBuf>) -> Option<PathBuf> {
    if let Some(dir) = given {
        return Some(dir);
    }
    if let Some(dir) = std::env::var_os(WEB_DIR_VAR).filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(dir));
    }
    // The executable is target/PROFILE/pointlet (or target/PROFILE/deps/… for tests).
    let beside_exe = std::env::current_exe()
        .ok()
        .and_then(|exe| {
            exe.ancestors()
                .find(|a| a.ends_with("target"))
                .map(Path::to_path_buf)
        })
        .map(|target| target.join("web"));
    let in_source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/web");
    beside_exe
        .into_iter()
        .chain([in_source])
        .find(|dir| dir.join("index.html").is_file())
}

/// The URLs: the viewer's, the list's and each store's. The first line, `serving N stores at
/// http://HOST:PORT/`, is what scripts and tests read the address from.
fn print_banner(server: &RunningServer) -> std::io::Result<()> {
    let addr = server.local_addr();
    // An unspecified address listens everywhere; this machine reaches it on loopback.
    let host = if addr.ip().is_unspecified() {
        format!("localhost:{}", addr.port())
    } else {
        addr.to_string()
    };
    let base = format!("http://{host}");
    let stores = server.stores();
    let mut out = std::io::stdout().lock();
    writeln!(out, "serving {} stores at {base}/", stores.len())?;
    if server.has_viewer() {
        writeln!(out, "  viewer       {base}/")?;
    } else {
        writeln!(
            out,
            "  viewer       {base}/  (not built: `bash scripts/build-web.sh`, or --web-dir DIR)"
        )?;
    }
    writeln!(out, "  stores.json  {base}/stores.json")?;
    let width = stores.iter().map(|s| s.name.len()).max().unwrap_or(0);
    for s in stores {
        writeln!(
            out,
            "  {:width$}  {base}{}  ({}, {} points)",
            s.name,
            pointlet_serve::listing::store_url(&s.name),
            format_bytes(s.validators.len),
            format_count(s.info.points),
        )?;
    }
    writeln!(out, "press Ctrl-C to stop")?;
    // Piped stdout is read by scripts waiting for the address: send it now.
    out.flush()
}

/// Ctrl-C, SIGTERM and SIGHUP stop the server (requests in flight may finish first, for up to
/// `pointlet_serve::GRACE`); a second signal ends the process at once.
#[cfg(unix)]
fn stop_on_signals(server: &RunningServer) -> Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .context("installing the signal handlers")?;
    let handle = server.shutdown_handle();
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            let mut signals = signals.forever();
            if signals.next().is_some() {
                eprintln!("\nstopping (Ctrl-C again to stop at once)");
                handle.shutdown();
            }
            if let Some(signal) = signals.next() {
                std::process::exit(128 + signal);
            }
        })
        .context("starting the signal thread")?;
    Ok(())
}

#[cfg(not(unix))]
fn stop_on_signals(_server: &RunningServer) -> Result<()> {
    Ok(())
}
