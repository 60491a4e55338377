//! PNG files of the viewer (screenshots), written beside the target and renamed into place so
//! that no partial image is ever seen under the final name.

use crate::ViewerError;
use std::io::Write;
use std::path::Path;

pub fn check_png_path(path: &Path) -> Result<(), ViewerError> {
    let png = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png {
        Ok(())
    } else {
        Err(ViewerError::Config(format!(
            "screenshot {} must end in .png",
            path.display()
        )))
    }
}

/// Writes `rgba` (`width * height * 4` bytes, rows top down) to `path`.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), ViewerError> {
    let fail = |e: String| ViewerError::Write(format!("{}: {e}", path.display()));
    if rgba.len() as u64 != width as u64 * height as u64 * 4 {
        return Err(fail(format!(
            "{} bytes for a {width}×{height} image",
            rgba.len()
        )));
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| fail("the path names no file".into()))?;
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| -> Result<(), String> {
        let file = std::fs::File::create(&tmp).map_err(|e| e.to_string())?;
        let mut out = std::io::BufWriter::new(file);
        {
            let mut enc = png::Encoder::new(&mut out, width, height);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().map_err(|e| e.to_string())?;
            w.write_image_data(rgba).map_err(|e| e.to_string())?;
            w.finish().map_err(|e| e.to_string())?;
        }
        out.flush().map_err(|e| e.to_string())?;
        std::fs::rename(&tmp, path).map_err(|e| e.to_string())
    })();
    if result.is_err() {
        // Best effort: the temporary may not exist if creating it was what failed.
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(fail)
}
