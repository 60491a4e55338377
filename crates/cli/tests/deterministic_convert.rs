//! The same inputs and seed give byte-identical stores in memory and out of core, whatever the
//! number of threads (issue 15).

mod common;

use common::{ok, s};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Points in each case, together.
const POINTS: u64 = 300_000;
/// Small enough to force many spilled runs: the points take ~40 B each in memory.
const SPILLING_BUDGET: u64 = 2 << 20;
const _: () = assert!(POINTS * 40 > 4 * SPILLING_BUDGET);
const THREADS: [&str; 3] = ["1", "2", "4"];

/// Converts `inputs` on `threads` rayon threads (out of core when `budget` is given) and
/// returns the store's bytes.
fn convert(dir: &Path, inputs: &[&Path], threads: &str, budget: Option<u64>) -> Vec<u8> {
    let mode = if budget.is_some() { "ooc" } else { "mem" };
    let output = dir.join(format!("t{threads}-{mode}.pointlet"));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_pointlet"));
    cmd.env("RAYON_NUM_THREADS", threads)
        .arg("convert")
        .args(inputs)
        .arg("-o")
        .arg(&output)
        .args(["--seed", "7", "--pointlets", "300"]);
    if let Some(b) = budget {
        cmd.arg("--ram-budget")
            .arg(b.to_string())
            .arg("--tmp")
            .arg(dir);
    }
    let out = cmd.output().expect("running pointlet convert");
    assert!(
        out.status.success(),
        "convert on {threads} threads ({mode}) failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&output).expect("reading the store");
    std::fs::remove_file(&output).expect("removing the store");
    bytes
}

/// Every thread count, in memory and out of core, gives the same store as one thread in memory.
fn assert_deterministic(inputs: &[&Path]) {
    let dir = tempfile::tempdir().expect("tempdir");
    let reference = convert(dir.path(), inputs, "1", None);
    for threads in THREADS {
        for budget in [None, Some(SPILLING_BUDGET)] {
            if threads == "1" && budget.is_none() {
                continue;
            }
            let store = convert(dir.path(), inputs, threads, budget);
            assert!(
                store == reference,
                "{inputs:?} on {threads} threads with budget {budget:?} gave another store \
                 ({} bytes, not {})",
                store.len(),
                reference.len()
            );
        }
    }
    // The stores are removed as they are read: the runs must have gone too.
    assert_eq!(common::listing(dir.path()), Vec::<String>::new());
}

fn generate(dir: &Path, name: &str, points: u64, seed: u64) -> PathBuf {
    let path = dir.join(name);
    let (points, seed) = (points.to_string(), seed.to_string());
    ok(&[
        "generate",
        "--points",
        &points,
        "--seed",
        &seed,
        "-o",
        s(&path),
    ]);
    path
}

#[test]
fn a_las_gives_one_store_whatever_the_threads_and_budget() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = generate(dir.path(), "scene.las", POINTS, 3);
    assert_deterministic(&[&las]);
}

#[test]
fn a_laz_gives_one_store_whatever_the_threads_and_budget() {
    let dir = tempfile::tempdir().expect("tempdir");
    let laz = generate(dir.path(), "scene.laz", POINTS, 3);
    assert_deterministic(&[&laz]);
}

#[test]
fn merged_inputs_give_one_store_whatever_the_threads_and_budget() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = generate(dir.path(), "a.las", POINTS / 2, 4);
    let b = generate(dir.path(), "b.las", POINTS / 2, 5);
    assert_deterministic(&[&a, &b]);
}
