//! `pointlet serve`: serves stores over HTTP (byte ranges, ETags, CORS) for the web viewer
//! and remote readers, until Ctrl-C or SIGTERM. The server itself is `pointlet-serve`.

use anyhow::{Context, Result};
use pointlet_core::size::{format_bytes, format_count};
use pointlet_serve::{RunningServer, ServeConfig, Server};
use std::net::SocketAddr;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// `.pointlet` stores, or folders whose `.pointlet` files (directly inside) are served.
    /// Each is served as /stores/NAME.pointlet; symlinks inside a folder are not followed.
    #[arg(required = true, value_name = "STORE_OR_DIR")]
    pub stores: Vec<PathBuf>,
    /// Address to listen on: loopback only by default; 0.0.0.0:PORT serves the network too.
    #[arg(long, default_value_t = pointlet_serve::DEFAULT_BIND)]
    pub bind: SocketAddr,
}

pub fn run(args: Args) -> Result<()> {
    let mut config = ServeConfig::new(args.stores);
    config.bind = args.bind;
    let server = Server::bind(config)?;
    for note in server.notes() {
        eprintln!("note: {note}");
    }
    print_banner(&server);
    stop_on_signals(&server)?;
    server.wait()?;
    eprintln!("stopped");
    Ok(())
}

/// The URLs: the viewer's, the list's and each store's.
fn print_banner(server: &RunningServer) {
    let addr = server.local_addr();
    // An unspecified address listens everywhere; this machine reaches it on loopback.
    let host = if addr.ip().is_unspecified() {
        format!("localhost:{}", addr.port())
    } else {
        addr.to_string()
    };
    let base = format!("http://{host}");
    let stores = server.stores();
    let plural = if stores.len() == 1 { "" } else { "s" };
    println!("serving {} store{plural} on {base}/", stores.len());
    if server.has_viewer() {
        println!("  viewer       {base}/");
    } else {
        println!(
            "  viewer       {base}/  (the web viewer is not built yet: the page lists the stores)"
        );
    }
    println!("  stores.json  {base}/stores.json");
    let width = stores.iter().map(|s| s.name.len()).max().unwrap_or(0);
    for s in stores {
        println!(
            "  {:width$}  {base}{}  ({}, {} points)",
            s.name,
            pointlet_serve::listing::store_url(&s.name),
            format_bytes(s.validators.len),
            format_count(s.info.points),
        );
    }
    println!("press Ctrl-C to stop");
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
