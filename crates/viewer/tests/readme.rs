//! The README's controls table lists every key the help window shows, and its screenshot exists.

use pointlet_viewer::ui::CONTROLS;

#[test]
fn readme_lists_every_control() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let readme = std::fs::read_to_string(format!("{root}/README.md")).expect("README.md");
    for (key, _) in CONTROLS {
        assert!(
            readme.contains(&format!("| {key} |")),
            "README.md's viewer controls lack '{key}'"
        );
    }
    assert!(readme.contains("docs/viewer.png"));
    assert!(std::path::Path::new(&format!("{root}/docs/viewer.png")).is_file());
}
