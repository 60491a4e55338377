//! A clone of the repository is all the tests and scripts have: nothing they read may live in
//! a sibling folder (the development checkout has one of shared data; a user's clone has not).

use std::path::{Path, PathBuf};

fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name();
        if name == "target" || name == "corpus" || name == "artifacts" {
            continue;
        }
        if p.is_dir() {
            files_under(&p, out);
        } else if p
            .extension()
            .and_then(|x| x.to_str())
            .is_some_and(|x| matches!(x, "rs" | "sh" | "toml"))
            || p.file_name().is_some_and(|n| n == "run")
        {
            out.push(p);
        }
    }
}

#[test]
fn no_test_or_script_reads_outside_the_repository() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut files = Vec::new();
    for dir in ["crates", "scripts", "fuzz", ".ci"] {
        files_under(&root.join(dir), &mut files);
    }
    assert!(files.len() > 50, "found only {} files", files.len());
    // Spelled in two halves so that this file does not find itself.
    let sibling = ["../", "shared"].concat();
    let offenders: Vec<String> = files
        .iter()
        .filter(|p| std::fs::read_to_string(p).is_ok_and(|text| text.contains(&sibling)))
        .map(|p| p.display().to_string())
        .collect();
    assert!(
        offenders.is_empty(),
        "these read a sibling folder of the clone: {offenders:?}"
    );
    for name in ["autzen_trim.laz", "simple.las", "plane.laz", "README.md"] {
        assert!(
            root.join("testdata").join(name).is_file(),
            "testdata/{name}"
        );
    }
}
