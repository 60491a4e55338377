//! `pointlet bench-alloc`: the GPU buffer suballocator against one `create_buffer` per
//! allocation, as the WebGPU-engine paper measures it (§3.5, Tables 2–3): 10 000 vertex
//! buffers of 128 KB to 1 MB, allocated, then freed, per page size.

use anyhow::{Context, Result};
use pointlet_gpu::suballoc::{benchmark_sizes, time_direct, time_suballocator, AllocTimes};
use serde::Serialize;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Allocations per run.
    #[arg(long, default_value_t = 10_000)]
    pub allocations: usize,
    /// Page sizes of the suballocator.
    #[arg(long, value_delimiter = ',', default_value = "16MiB,32MiB,64MiB,128MiB",
          value_parser = crate::parse_bytes_arg)]
    pub page_sizes: Vec<u64>,
    /// Runs of each configuration (alternated); the median is reported.
    #[arg(long, default_value_t = 3)]
    pub rounds: usize,
    #[arg(long)]
    pub adapter: Option<String>,
    /// Write the measurements as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

#[derive(Serialize)]
struct Row {
    method: String,
    page_mib: Option<u64>,
    pages: usize,
    alloc_us: f64,
    free_ns: f64,
    alloc_speedup: Option<f64>,
    free_speedup: Option<f64>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

pub fn run(args: Args) -> Result<()> {
    if args.allocations == 0 || args.rounds == 0 {
        anyhow::bail!("--allocations and --rounds must be at least 1");
    }
    let ctx = crate::render_cmd::open_adapter(&args.adapter)?;
    let sizes = benchmark_sizes(args.allocations, 1);
    let mut direct = Vec::new();
    let mut paged: Vec<Vec<AllocTimes>> = vec![Vec::new(); args.page_sizes.len()];
    for _ in 0..args.rounds {
        direct.push(time_direct(&ctx, &sizes).context("direct allocation")?);
        for (k, page) in args.page_sizes.iter().enumerate() {
            paged[k].push(time_suballocator(&ctx, &sizes, *page).context("suballocation")?);
        }
    }
    let med = |t: &[AllocTimes]| {
        (
            median(t.iter().map(|x| x.alloc_us).collect()),
            median(t.iter().map(|x| x.free_ns).collect()),
        )
    };
    let (d_alloc, d_free) = med(&direct);
    println!(
        "{}: {} allocations of 128 KiB–1 MiB, median of {} rounds",
        ctx.describe(),
        args.allocations,
        args.rounds
    );
    println!("direct create_buffer: alloc {d_alloc:.2} µs, free {d_free:.1} ns");
    let mut rows = vec![Row {
        method: "direct".into(),
        page_mib: None,
        pages: 0,
        alloc_us: d_alloc,
        free_ns: d_free,
        alloc_speedup: None,
        free_speedup: None,
    }];
    for (k, page) in args.page_sizes.iter().enumerate() {
        let (a, f) = med(&paged[k]);
        let pages = paged[k].first().map_or(0, |t| t.pages);
        println!(
            "suballocator, {:>4} MiB pages ({pages:>4} pages): alloc {a:.2} µs ({:.1}× direct), free {f:.1} ns ({:.1}× direct)",
            page >> 20,
            d_alloc / a,
            d_free / f
        );
        rows.push(Row {
            method: "suballocator".into(),
            page_mib: Some(page >> 20),
            pages,
            alloc_us: a,
            free_ns: f,
            alloc_speedup: Some(d_alloc / a),
            free_speedup: Some(d_free / f),
        });
    }
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}
